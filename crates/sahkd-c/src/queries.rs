//! Ray and point queries of trees and scene trees. One generic body per query, over a
//! [`Target`] (what a tree and a scene tree both answer); each `extern "C"` function only
//! hands its arguments to its body. The functions themselves are written out, tree and scene
//! each, because cbindgen reads the sources without expanding macros: a function a macro made
//! would be missing from include/sahkd.h.

use crate::checked::{get, put, Strided};
use crate::mesh::sahkd_tree;
use crate::scene::sahkd_scene_tree;
use crate::{error, guard, invalid, sahkd_status, Result};
use rayon::prelude::*;
use sahkd::{ClosestPoint, Hit, InsideTest, KdTree, Ray, SceneClosestPoint, SceneHit, Vec3};

/// `prim` and `geometry` of a miss, and of a point query on an empty mesh.
pub const SAHKD_INVALID_ID: u32 = u32::MAX;
/// Query flag: answer an array on every core (the calling thread joins the library's
/// worker pool). Without it an array is answered on the calling thread only, for callers
/// that run their own threads.
pub const SAHKD_QUERY_PARALLEL: u32 = 1;
/// Inside test: crossing parity of one ray (three voting near an edge); for closed meshes.
pub const SAHKD_INSIDE_PARITY: u32 = 0;
/// Inside test: generalized winding number; robust to holes, O(triangles) per point.
pub const SAHKD_INSIDE_WINDING: u32 = 1;

/// A ray origin + t * direction for t in [t_min, t_max] (t_max = INFINITY: unbounded).
/// The library's rule for rays given as input: every coordinate and t_min finite, t_max not
/// NaN; a call given a ray that breaks it fails with SAHKD_ERROR_INVALID_ARGUMENT naming the
/// ray and the part. A zero direction or t_min > t_max is a ray that hits nothing.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct sahkd_ray {
    pub origin: [f32; 3],
    pub t_min: f32,
    pub direction: [f32; 3],
    pub t_max: f32,
}

/// The closest hit of a ray: distance, barycentrics (u, v) of corners 1 and 2, the triangle
/// (in its mesh) and the geometry (0 for a tree; the scene's id for a scene tree). A miss
/// has t = INFINITY, u = v = 0 and prim = geometry = SAHKD_INVALID_ID.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct sahkd_hit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    pub prim: u32,
    pub geometry: u32,
}

/// Rays as separate arrays (structure of arrays), each element `stride` bytes after the
/// previous (0: packed floats). `t_min` NULL means 0 for every ray, `t_max` NULL INFINITY.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sahkd_rays_soa {
    pub origin_x: *const f32,
    pub origin_y: *const f32,
    pub origin_z: *const f32,
    pub direction_x: *const f32,
    pub direction_y: *const f32,
    pub direction_z: *const f32,
    pub t_min: *const f32,
    pub t_max: *const f32,
    pub stride: usize,
}

/// Where closest hits go, as separate arrays with one `stride` (0: packed); any of them may
/// be NULL to skip it.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sahkd_hits_soa {
    pub t: *mut f32,
    pub u: *mut f32,
    pub v: *mut f32,
    pub prim: *mut u32,
    pub geometry: *mut u32,
    pub stride: usize,
}

/// The closest point of a mesh (or scene) to a query point, in f64: the point, its
/// distance, the corners' weights, the triangle (the lowest index among equally near ones)
/// and the geometry (0 for a tree). On an empty mesh: NaN point, infinite distance, ids
/// SAHKD_INVALID_ID.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct sahkd_closest {
    pub point: [f64; 3],
    pub distance: f64,
    pub barycentrics: [f64; 3],
    pub prim: u32,
    pub geometry: u32,
}

const MISS: sahkd_hit = sahkd_hit {
    t: f32::INFINITY,
    u: 0.0,
    v: 0.0,
    prim: SAHKD_INVALID_ID,
    geometry: SAHKD_INVALID_ID,
};

const NOWHERE: sahkd_closest = sahkd_closest {
    point: [f64::NAN; 3],
    distance: f64::INFINITY,
    barycentrics: [f64::NAN; 3],
    prim: SAHKD_INVALID_ID,
    geometry: SAHKD_INVALID_ID,
};

/// The library's hits and closest points of one kind (tree or scene: the same fields but for
/// the geometry id) as the C API reports them; `$geometry` is the answer's geometry id.
macro_rules! answers {
    ($hit:ty, $closest:ty, |$a:ident| $geometry:expr) => {
        impl From<$hit> for sahkd_hit {
            fn from($a: $hit) -> sahkd_hit {
                let (t, u, v, prim) = ($a.t, $a.u, $a.v, $a.prim);
                let geometry = $geometry;
                sahkd_hit {
                    t,
                    u,
                    v,
                    prim,
                    geometry,
                }
            }
        }

        impl From<$closest> for sahkd_closest {
            fn from($a: $closest) -> sahkd_closest {
                let (point, distance, barycentrics) = ($a.point, $a.distance, $a.barycentrics);
                let (prim, geometry) = ($a.prim, $geometry);
                sahkd_closest {
                    point,
                    distance,
                    barycentrics,
                    prim,
                    geometry,
                }
            }
        }
    };
}

answers!(Hit, ClosestPoint, |a| 0);
answers!(SceneHit, SceneClosestPoint, |a| a.geometry);

/// The point queries a handle forwards to the library: `KdTree` and `SceneTree` name them
/// alike (a scene judges inside each geometry alone, so these are not the tree's answers).
macro_rules! point_queries {
    ($field:ident) => {
        fn nearest(&self, p: Vec3) -> sahkd_closest {
            self.$field.closest_point(p).map_or(NOWHERE, Into::into)
        }
        fn nearest_many(&self, points: &[Vec3]) -> Vec<sahkd_closest> {
            let found = self.$field.closest_point_batch(points);
            found
                .into_iter()
                .map(|c| c.map_or(NOWHERE, Into::into))
                .collect()
        }
        fn signed_distance(&self, p: Vec3, test: InsideTest) -> f64 {
            self.$field.signed_distance(p, test)
        }
        fn signed_distance_many(&self, points: &[Vec3], test: InsideTest) -> Vec<f64> {
            self.$field.signed_distance_batch(points, test)
        }
        fn contains(&self, p: Vec3, test: InsideTest) -> bool {
            self.$field.contains(p, test)
        }
        fn contains_many(&self, points: &[Vec3], test: InsideTest) -> Vec<bool> {
            self.$field.contains_batch(points, test)
        }
    };
}

/// What a tree and a scene tree both answer. Rays walk the one tree either holds (a scene's
/// hits only renamed afterwards), so the ray queries and distances are written once, below;
/// the point queries that differ (geometry ids, inside) come from the library's own methods.
pub(crate) trait Target: Sync {
    /// What the handle is called in messages ("tree" or "scene").
    const NAME: &'static str;
    /// The tree rays and distances walk.
    fn tree(&self) -> &KdTree;
    /// A hit of that tree as this handle reports it.
    fn hit(&self, h: Hit) -> sahkd_hit;
    fn nearest(&self, p: Vec3) -> sahkd_closest;
    fn nearest_many(&self, points: &[Vec3]) -> Vec<sahkd_closest>;
    fn signed_distance(&self, p: Vec3, test: InsideTest) -> f64;
    fn signed_distance_many(&self, points: &[Vec3], test: InsideTest) -> Vec<f64>;
    fn contains(&self, p: Vec3, test: InsideTest) -> bool;
    fn contains_many(&self, points: &[Vec3], test: InsideTest) -> Vec<bool>;

    /// The closest hit of one ray.
    fn closest(&self, ray: &Ray) -> sahkd_hit {
        self.tree().intersect(ray).map_or(MISS, |h| self.hit(h))
    }
    /// Whether one ray hits anything.
    fn any(&self, ray: &Ray) -> bool {
        self.tree().occluded(ray)
    }
}

impl Target for sahkd_tree {
    const NAME: &'static str = "tree";
    fn tree(&self) -> &KdTree {
        &self.tree
    }
    fn hit(&self, h: Hit) -> sahkd_hit {
        h.into()
    }
    point_queries!(tree);
}

impl Target for sahkd_scene_tree {
    const NAME: &'static str = "scene";
    fn tree(&self) -> &KdTree {
        self.scene.tree()
    }
    fn hit(&self, h: Hit) -> sahkd_hit {
        self.scene.scene_hit(h).into()
    }
    point_queries!(scene);
}

/// Closest hits of `rays` (`parallel`: on every core; else on the calling thread).
fn closest_many(t: &impl Target, rays: &[Ray], parallel: bool) -> Vec<sahkd_hit> {
    let answer = |h: Option<Hit>| h.map_or(MISS, |h| t.hit(h));
    if parallel {
        let hits = t.tree().intersect_batch(rays);
        hits.into_par_iter()
            .with_min_len(1024)
            .map(answer)
            .collect()
    } else {
        let mut out = vec![None; rays.len()];
        t.tree().intersect_into(rays, &mut out);
        out.into_iter().map(answer).collect()
    }
}

/// Any-hit answers of `rays`, as [`closest_many`].
fn any_many(t: &impl Target, rays: &[Ray], parallel: bool) -> Vec<bool> {
    if parallel {
        t.tree().occluded_batch(rays)
    } else {
        let mut out = vec![false; rays.len()];
        t.tree().occluded_into(rays, &mut out);
        out
    }
}

fn parallel(flags: u32) -> Result<bool> {
    if flags & !SAHKD_QUERY_PARALLEL != 0 {
        return invalid(format!(
            "unknown query flags {:#x}: the only flag is SAHKD_QUERY_PARALLEL (1)",
            flags & !SAHKD_QUERY_PARALLEL
        ));
    }
    Ok(flags & SAHKD_QUERY_PARALLEL != 0)
}

fn inside(test: u32) -> Result<InsideTest> {
    match test {
        SAHKD_INSIDE_PARITY => Ok(InsideTest::Parity),
        SAHKD_INSIDE_WINDING => Ok(InsideTest::Winding),
        _ => invalid(format!(
            "inside test {test} is out of range: SAHKD_INSIDE_PARITY (0) or SAHKD_INSIDE_WINDING (1)"
        )),
    }
}

/// Runs one call on a tree or scene handle (checked, then borrowed), as [`guard`] does.
unsafe fn on<T: Target>(handle: *const T, f: impl FnOnce(&T) -> Result<()>) -> sahkd_status {
    guard(|| f(get(handle, T::NAME)?))
}

fn ray_of(r: &sahkd_ray) -> Ray {
    Ray::new(Vec3(r.origin), Vec3(r.direction)).with_range(r.t_min, r.t_max)
}

/// `ray` if the library's rule for input rays takes it, else an error naming it and the part.
fn checked(ray: Ray, what: impl FnOnce() -> String) -> Result<Ray> {
    match ray.input_problem() {
        None => Ok(ray),
        Some((part, why)) => invalid(format!("{}: {} is {why}", what(), part.name())),
    }
}

unsafe fn one_ray(ray: *const sahkd_ray) -> Result<Ray> {
    checked(ray_of(get(ray, "ray")?), || "ray".into())
}

/// An array of rays as a call received it: structures `stride` bytes apart (0: packed), or
/// separate arrays; read (and every ray checked) by [`Rays::read`].
#[derive(Clone, Copy)]
enum Rays {
    Aos(*const sahkd_ray, usize, usize),
    Soa(*const sahkd_rays_soa, usize),
}

impl Rays {
    unsafe fn read(self) -> Result<Vec<Ray>> {
        match self {
            Rays::Aos(rays, count, stride) => aos_rays(rays, count, stride),
            Rays::Soa(soa, count) => soa_rays(soa, count),
        }
    }
}

unsafe fn aos_rays(rays: *const sahkd_ray, count: usize, stride: usize) -> Result<Vec<Ray>> {
    let rays = Strided::new(rays, count, stride, "rays")?;
    (0..count)
        .map(|i| checked(ray_of(&rays.read(i)), || format!("rays[{i}]")))
        .collect()
}

unsafe fn soa_rays(soa: *const sahkd_rays_soa, count: usize) -> Result<Vec<Ray>> {
    let s = get(soa, "rays")?;
    let column = |p, what| Strided::new(p, count, s.stride, what);
    let o = [
        column(s.origin_x, "rays->origin_x")?,
        column(s.origin_y, "rays->origin_y")?,
        column(s.origin_z, "rays->origin_z")?,
    ];
    let d = [
        column(s.direction_x, "rays->direction_x")?,
        column(s.direction_y, "rays->direction_y")?,
        column(s.direction_z, "rays->direction_z")?,
    ];
    let t_min = Strided::optional(s.t_min, count, s.stride, "rays->t_min")?;
    let t_max = Strided::optional(s.t_max, count, s.stride, "rays->t_max")?;
    (0..count)
        .map(|i| {
            let xyz = |c: &[Strided<f32>; 3]| Vec3([c[0].read(i), c[1].read(i), c[2].read(i)]);
            let ray = Ray::new(xyz(&o), xyz(&d)).with_range(
                t_min.map_or(0.0, |t| t.read(i)),
                t_max.map_or(f32::INFINITY, |t| t.read(i)),
            );
            checked(ray, || format!("rays[{i}]"))
        })
        .collect()
}

/// Query points: every coordinate must be finite, as for rays.
unsafe fn points(p: *const f32, count: usize, stride: usize) -> Result<Vec<Vec3>> {
    let p = Strided::new(p.cast::<[f32; 3]>(), count, stride, "points")?;
    (0..count)
        .map(|i| match Vec3(p.read(i)) {
            v if v.is_finite() => Ok(v),
            v => invalid(format!(
                "points[{i}] = ({}, {}, {}) is not finite",
                v[0], v[1], v[2]
            )),
        })
        .collect()
}

/// Writes `values` to a strided output array.
unsafe fn write_all<T: Copy>(out: *mut T, stride: usize, values: Vec<T>, what: &str) -> Result<()> {
    let out = Strided::new(out, values.len(), stride, what)?;
    for (i, v) in values.into_iter().enumerate() {
        out.write(i, v);
    }
    Ok(())
}

/// Checks an output array before any work, so a bad one costs no query.
unsafe fn check_out<T: Copy>(out: *mut T, count: usize, stride: usize, what: &str) -> Result<()> {
    Strided::new(out, count, stride, what).map(|_| ())
}

unsafe fn write_hits_soa(hits: *const sahkd_hits_soa, found: Vec<sahkd_hit>) -> Result<()> {
    let h = get(hits, "hits")?;
    let n = found.len();
    let t = Strided::optional(h.t, n, h.stride, "hits->t")?;
    let u = Strided::optional(h.u, n, h.stride, "hits->u")?;
    let v = Strided::optional(h.v, n, h.stride, "hits->v")?;
    let prim = Strided::optional(h.prim, n, h.stride, "hits->prim")?;
    let geometry = Strided::optional(h.geometry, n, h.stride, "hits->geometry")?;
    let floats = [(t, 0), (u, 1), (v, 2)];
    let ids = [(prim, 0), (geometry, 1)];
    for (i, hit) in found.into_iter().enumerate() {
        for (column, k) in floats {
            if let Some(c) = column {
                c.write(i, [hit.t, hit.u, hit.v][k]);
            }
        }
        for (column, k) in ids {
            if let Some(c) = column {
                c.write(i, [hit.prim, hit.geometry][k]);
            }
        }
    }
    Ok(())
}

/// Query points as a call received them: `count` points of 3 floats, `stride` bytes apart
/// (0: packed).
#[derive(Clone, Copy)]
struct Points(*const f32, usize, usize);

/// Point queries share their reading, flag and writing; `single` answers one point (the
/// serial path), `many` an array on every core.
unsafe fn point_query<T: Copy + Send>(
    Points(p, count, stride): Points,
    out: *mut T,
    out_stride: usize,
    flags: u32,
    single: impl Fn(Vec3) -> T + Sync,
    many: impl FnOnce(&[Vec3]) -> Vec<T>,
) -> Result<()> {
    let parallel = parallel(flags)?;
    let points = points(p, count, stride)?;
    check_out(out, count, out_stride, "out")?;
    let values = if parallel {
        many(&points)
    } else {
        points.iter().map(|&p| single(p)).collect()
    };
    write_all(out, out_stride, values, "out")
}

// ---- The bodies trees and scene trees share ----------------------------------------------

/// A query of one ray, `answer`, written to `out`.
unsafe fn one_ray_query<T: Target, V>(
    handle: *const T,
    ray: *const sahkd_ray,
    out: *mut V,
    what: &str,
    answer: impl FnOnce(&T, &Ray) -> V,
) -> sahkd_status {
    on(handle, |t| {
        let ray = one_ray(ray)?;
        put(out, answer(t, &ray), what)
    })
}

/// Where an array query's answers go: `stride` bytes apart (0: packed), and its name for
/// messages.
struct Out<V>(*mut V, usize, &'static str);

/// A query of an array of rays, `answer` (`closest_many` or `any_many`), written to `out`.
unsafe fn rays_query<T: Target, V: Copy>(
    handle: *const T,
    rays: Rays,
    Out(out, stride, what): Out<V>,
    flags: u32,
    answer: impl FnOnce(&T, &[Ray], bool) -> Vec<V>,
) -> sahkd_status {
    on(handle, |t| {
        let parallel = parallel(flags)?;
        let rays = rays.read()?;
        check_out(out, rays.len(), stride, what)?;
        write_all(out, stride, answer(t, &rays, parallel), what)
    })
}

unsafe fn intersect_soa<T: Target>(
    handle: *const T,
    rays: *const sahkd_rays_soa,
    count: usize,
    hits: *const sahkd_hits_soa,
    flags: u32,
) -> sahkd_status {
    on(handle, |t| {
        let parallel = parallel(flags)?;
        let rays = soa_rays(rays, count)?;
        get(hits, "hits")?;
        write_hits_soa(hits, closest_many(t, &rays, parallel))
    })
}

unsafe fn closest_point<T: Target>(
    handle: *const T,
    points: Points,
    out: *mut sahkd_closest,
    out_stride: usize,
    flags: u32,
) -> sahkd_status {
    on(handle, |t| {
        let (single, many) = (|p| t.nearest(p), |ps: &[Vec3]| t.nearest_many(ps));
        point_query(points, out, out_stride, flags, single, many)
    })
}

unsafe fn distance<T: Target>(
    handle: *const T,
    points: Points,
    out: *mut f64,
    out_stride: usize,
    flags: u32,
) -> sahkd_status {
    on(handle, |t| {
        let tree = t.tree();
        let (single, many) = (|p| tree.distance(p), |ps: &[Vec3]| tree.distance_batch(ps));
        point_query(points, out, out_stride, flags, single, many)
    })
}

/// A query by an inside test, signed distance or containment: `by` is its pair of
/// [`Target`] methods (one point, an array on every core).
unsafe fn inside_query<T: Target, V: Copy + Send, S, M>(
    handle: *const T,
    points: Points,
    test: u32,
    out: *mut V,
    out_stride: usize,
    flags: u32,
    by: (S, M),
) -> sahkd_status
where
    S: Fn(&T, Vec3, InsideTest) -> V + Sync,
    M: FnOnce(&T, &[Vec3], InsideTest) -> Vec<V>,
{
    on(handle, |t| {
        let test = inside(test)?;
        let single = |p| by.0(t, p, test);
        let many = |ps: &[Vec3]| by.1(t, ps, test);
        point_query(points, out, out_stride, flags, single, many)
    })
}

// ---- Trees -------------------------------------------------------------------------------

/// The closest hit of one ray.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_intersect(
    tree: *const sahkd_tree,
    ray: *const sahkd_ray,
    hit: *mut sahkd_hit,
) -> sahkd_status {
    one_ray_query(tree, ray, hit, "hit", Target::closest)
}

/// Whether one ray hits anything in [t_min, t_max] (stops at the first hit found).
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_occluded(
    tree: *const sahkd_tree,
    ray: *const sahkd_ray,
    occluded: *mut bool,
) -> sahkd_status {
    one_ray_query(tree, ray, occluded, "occluded", Target::any)
}

/// Closest hits of `count` rays, `ray_stride` bytes apart (0: packed), into `hits`,
/// `hit_stride` bytes apart (0: packed). Each answer is sahkd_tree_intersect's bit for bit.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_intersect_aos(
    tree: *const sahkd_tree,
    rays: *const sahkd_ray,
    count: usize,
    ray_stride: usize,
    hits: *mut sahkd_hit,
    hit_stride: usize,
    flags: u32,
) -> sahkd_status {
    let rays = Rays::Aos(rays, count, ray_stride);
    let out = Out(hits, hit_stride, "hits");
    rays_query(tree, rays, out, flags, closest_many)
}

/// sahkd_tree_intersect_aos with rays and hits as separate arrays.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_intersect_soa(
    tree: *const sahkd_tree,
    rays: *const sahkd_rays_soa,
    count: usize,
    hits: *const sahkd_hits_soa,
    flags: u32,
) -> sahkd_status {
    intersect_soa(tree, rays, count, hits, flags)
}

/// Any-hit answers of `count` rays into `occluded`, `occluded_stride` bytes apart (0: packed).
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_occluded_aos(
    tree: *const sahkd_tree,
    rays: *const sahkd_ray,
    count: usize,
    ray_stride: usize,
    occluded: *mut bool,
    occluded_stride: usize,
    flags: u32,
) -> sahkd_status {
    let rays = Rays::Aos(rays, count, ray_stride);
    let out = Out(occluded, occluded_stride, "occluded");
    rays_query(tree, rays, out, flags, any_many)
}

/// sahkd_tree_occluded_aos with the rays as separate arrays.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_occluded_soa(
    tree: *const sahkd_tree,
    rays: *const sahkd_rays_soa,
    count: usize,
    occluded: *mut bool,
    occluded_stride: usize,
    flags: u32,
) -> sahkd_status {
    let rays = Rays::Soa(rays, count);
    let out = Out(occluded, occluded_stride, "occluded");
    rays_query(tree, rays, out, flags, any_many)
}

/// Every triangle one ray hits in [t_min, t_max], each once, nearest first (ties to the
/// lower index). `*count` is set to how many there are; the nearest `capacity` of them are
/// written to `hits`, and SAHKD_ERROR_BUFFER_TOO_SMALL says when some did not fit.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_all_hits(
    tree: *const sahkd_tree,
    ray: *const sahkd_ray,
    hits: *mut sahkd_hit,
    capacity: usize,
    count: *mut usize,
) -> sahkd_status {
    guard(|| {
        put(count, 0, "count")?;
        let t = get(tree, "tree")?;
        let ray = one_ray(ray)?;
        check_out(hits, capacity, 0, "hits")?;
        let found = t.tree.all_hits(&ray);
        *count = found.len();
        let all = found.len();
        let fits = found.into_iter().take(capacity).map(Into::into).collect();
        write_all(hits, 0, fits, "hits")?;
        if all > capacity {
            return error(
                sahkd_status::SAHKD_ERROR_BUFFER_TOO_SMALL,
                format!("the ray hits {all} triangles; hits holds {capacity}"),
            );
        }
        Ok(())
    })
}

/// How many triangles one ray hits in [t_min, t_max], each once.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_count_hits(
    tree: *const sahkd_tree,
    ray: *const sahkd_ray,
    count: *mut u32,
) -> sahkd_status {
    guard(|| {
        put(count, 0, "count")?;
        let t = get(tree, "tree")?;
        let ray = one_ray(ray)?;
        put(count, t.tree.all_hits(&ray).len() as u32, "count")
    })
}

/// Hit counts of `rays` into `counts` (shared by the array-of-structures and the
/// structure-of-arrays call).
unsafe fn count_hits_many(
    tree: *const sahkd_tree,
    rays: Rays,
    counts: *mut u32,
    counts_stride: usize,
    flags: u32,
) -> sahkd_status {
    on(tree, |t| {
        let t = &t.tree;
        let parallel = parallel(flags)?;
        let rays = rays.read()?;
        check_out(counts, rays.len(), counts_stride, "counts")?;
        // One hit buffer per worker, reused from ray to ray, as Python's count_hits does.
        let one = |buf: &mut Vec<Hit>, r: &Ray| {
            t.all_hits_into(r, buf);
            buf.len() as u32
        };
        let found = if parallel {
            rays.par_iter().map_init(Vec::new, one).collect()
        } else {
            let mut buf = Vec::new();
            rays.iter().map(|r| one(&mut buf, r)).collect()
        };
        write_all(counts, counts_stride, found, "counts")
    })
}

/// sahkd_tree_count_hits for `count` rays, into `counts`, `counts_stride` bytes apart.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_count_hits_aos(
    tree: *const sahkd_tree,
    rays: *const sahkd_ray,
    count: usize,
    ray_stride: usize,
    counts: *mut u32,
    counts_stride: usize,
    flags: u32,
) -> sahkd_status {
    let rays = Rays::Aos(rays, count, ray_stride);
    count_hits_many(tree, rays, counts, counts_stride, flags)
}

/// sahkd_tree_count_hits_aos with the rays as separate arrays.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_count_hits_soa(
    tree: *const sahkd_tree,
    rays: *const sahkd_rays_soa,
    count: usize,
    counts: *mut u32,
    counts_stride: usize,
    flags: u32,
) -> sahkd_status {
    count_hits_many(tree, Rays::Soa(rays, count), counts, counts_stride, flags)
}

/// Every hit of `rays`, flattened with offsets (shared by the array-of-structures and the
/// structure-of-arrays call).
#[allow(clippy::too_many_arguments)]
unsafe fn all_hits_many(
    tree: *const sahkd_tree,
    rays: Rays,
    hits: *mut sahkd_hit,
    capacity: usize,
    offsets: *mut usize,
    total: *mut usize,
    flags: u32,
) -> sahkd_status {
    guard(|| {
        put(total, 0, "total")?;
        let t = &get(tree, "tree")?.tree;
        let parallel = parallel(flags)?;
        let rays = rays.read()?;
        let count = rays.len();
        let Some(ends) = count.checked_add(1) else {
            return invalid("count + 1 offsets overflow");
        };
        check_out(offsets, ends, 0, "offsets")?;
        check_out(hits, capacity, 0, "hits")?;
        let found: Vec<Vec<Hit>> = if parallel {
            rays.par_iter().map(|r| t.all_hits(r)).collect()
        } else {
            rays.iter().map(|r| t.all_hits(r)).collect()
        };
        let mut at = 0usize;
        let mut ends = Vec::with_capacity(count + 1);
        ends.push(0);
        for f in &found {
            at += f.len();
            ends.push(at);
        }
        write_all(offsets, 0, ends, "offsets")?;
        *total = at;
        if at > capacity {
            return error(
                sahkd_status::SAHKD_ERROR_BUFFER_TOO_SMALL,
                format!("the rays hit {at} triangles in all; hits holds {capacity}"),
            );
        }
        let flat = found.into_iter().flatten().map(Into::into).collect();
        write_all(hits, 0, flat, "hits")
    })
}

/// Every hit of `count` rays: the hits of ray i are hits[offsets[i]] up to
/// hits[offsets[i + 1]], each ray's as sahkd_tree_all_hits gives them. `offsets` holds
/// count + 1 entries and `*total` the number of hits; when it exceeds `capacity`, offsets
/// and total are written, hits is not, and the call returns SAHKD_ERROR_BUFFER_TOO_SMALL.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_all_hits_aos(
    tree: *const sahkd_tree,
    rays: *const sahkd_ray,
    count: usize,
    ray_stride: usize,
    hits: *mut sahkd_hit,
    capacity: usize,
    offsets: *mut usize,
    total: *mut usize,
    flags: u32,
) -> sahkd_status {
    let rays = Rays::Aos(rays, count, ray_stride);
    all_hits_many(tree, rays, hits, capacity, offsets, total, flags)
}

/// sahkd_tree_all_hits_aos with the rays as separate arrays.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_all_hits_soa(
    tree: *const sahkd_tree,
    rays: *const sahkd_rays_soa,
    count: usize,
    hits: *mut sahkd_hit,
    capacity: usize,
    offsets: *mut usize,
    total: *mut usize,
    flags: u32,
) -> sahkd_status {
    let rays = Rays::Soa(rays, count);
    all_hits_many(tree, rays, hits, capacity, offsets, total, flags)
}

/// Closest points of the mesh to `count` points (3 floats each, `point_stride` bytes apart,
/// 0: packed) into `out`, `out_stride` bytes apart. One point: count 1.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_closest_point(
    tree: *const sahkd_tree,
    points: *const f32,
    count: usize,
    point_stride: usize,
    out: *mut sahkd_closest,
    out_stride: usize,
    flags: u32,
) -> sahkd_status {
    let points = Points(points, count, point_stride);
    closest_point(tree, points, out, out_stride, flags)
}

/// Distances from `count` points to the mesh (infinite for an empty mesh).
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_distance(
    tree: *const sahkd_tree,
    points: *const f32,
    count: usize,
    point_stride: usize,
    out: *mut f64,
    out_stride: usize,
    flags: u32,
) -> sahkd_status {
    let points = Points(points, count, point_stride);
    distance(tree, points, out, out_stride, flags)
}

/// Distances, negative inside, by the inside test SAHKD_INSIDE_PARITY or
/// SAHKD_INSIDE_WINDING.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_signed_distance(
    tree: *const sahkd_tree,
    points: *const f32,
    count: usize,
    point_stride: usize,
    inside_test: u32,
    out: *mut f64,
    out_stride: usize,
    flags: u32,
) -> sahkd_status {
    let points = Points(points, count, point_stride);
    let by = (Target::signed_distance, Target::signed_distance_many);
    inside_query(tree, points, inside_test, out, out_stride, flags, by)
}

/// Whether each point is inside the mesh, by the inside test given.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_contains(
    tree: *const sahkd_tree,
    points: *const f32,
    count: usize,
    point_stride: usize,
    inside_test: u32,
    out: *mut bool,
    out_stride: usize,
    flags: u32,
) -> sahkd_status {
    let points = Points(points, count, point_stride);
    let by = (Target::contains, Target::contains_many);
    inside_query(tree, points, inside_test, out, out_stride, flags, by)
}

/// The generalized winding number of the mesh around each point (1 inside, 0 outside a
/// closed mesh wound outwards); O(triangles) per point.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_winding_number(
    tree: *const sahkd_tree,
    points: *const f32,
    count: usize,
    point_stride: usize,
    out: *mut f64,
    out_stride: usize,
    flags: u32,
) -> sahkd_status {
    on(tree, |t| {
        let t = &t.tree;
        let (single, many) = (
            |p| t.winding_number(p),
            |ps: &[Vec3]| t.winding_number_batch(ps),
        );
        let points = Points(points, count, point_stride);
        point_query(points, out, out_stride, flags, single, many)
    })
}

// ---- Scene trees (the same queries, with the geometry id) --------------------------------

/// The closest hit of one ray in a scene, with its geometry id.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_intersect(
    scene: *const sahkd_scene_tree,
    ray: *const sahkd_ray,
    hit: *mut sahkd_hit,
) -> sahkd_status {
    one_ray_query(scene, ray, hit, "hit", Target::closest)
}

/// Whether one ray hits any geometry of the scene.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_occluded(
    scene: *const sahkd_scene_tree,
    ray: *const sahkd_ray,
    occluded: *mut bool,
) -> sahkd_status {
    one_ray_query(scene, ray, occluded, "occluded", Target::any)
}

/// sahkd_tree_intersect_aos for a scene.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_intersect_aos(
    scene: *const sahkd_scene_tree,
    rays: *const sahkd_ray,
    count: usize,
    ray_stride: usize,
    hits: *mut sahkd_hit,
    hit_stride: usize,
    flags: u32,
) -> sahkd_status {
    let rays = Rays::Aos(rays, count, ray_stride);
    let out = Out(hits, hit_stride, "hits");
    rays_query(scene, rays, out, flags, closest_many)
}

/// sahkd_tree_intersect_soa for a scene.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_intersect_soa(
    scene: *const sahkd_scene_tree,
    rays: *const sahkd_rays_soa,
    count: usize,
    hits: *const sahkd_hits_soa,
    flags: u32,
) -> sahkd_status {
    intersect_soa(scene, rays, count, hits, flags)
}

/// sahkd_tree_occluded_aos for a scene.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_occluded_aos(
    scene: *const sahkd_scene_tree,
    rays: *const sahkd_ray,
    count: usize,
    ray_stride: usize,
    occluded: *mut bool,
    occluded_stride: usize,
    flags: u32,
) -> sahkd_status {
    let rays = Rays::Aos(rays, count, ray_stride);
    let out = Out(occluded, occluded_stride, "occluded");
    rays_query(scene, rays, out, flags, any_many)
}

/// sahkd_tree_occluded_soa for a scene.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_occluded_soa(
    scene: *const sahkd_scene_tree,
    rays: *const sahkd_rays_soa,
    count: usize,
    occluded: *mut bool,
    occluded_stride: usize,
    flags: u32,
) -> sahkd_status {
    let rays = Rays::Soa(rays, count);
    let out = Out(occluded, occluded_stride, "occluded");
    rays_query(scene, rays, out, flags, any_many)
}

/// sahkd_tree_closest_point over every geometry (ties to the lower geometry id).
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_closest_point(
    scene: *const sahkd_scene_tree,
    points: *const f32,
    count: usize,
    point_stride: usize,
    out: *mut sahkd_closest,
    out_stride: usize,
    flags: u32,
) -> sahkd_status {
    let points = Points(points, count, point_stride);
    closest_point(scene, points, out, out_stride, flags)
}

/// Distances from each point to the nearest geometry.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_distance(
    scene: *const sahkd_scene_tree,
    points: *const f32,
    count: usize,
    point_stride: usize,
    out: *mut f64,
    out_stride: usize,
    flags: u32,
) -> sahkd_status {
    let points = Points(points, count, point_stride);
    distance(scene, points, out, out_stride, flags)
}

/// Distances, negative inside any geometry (each judged alone).
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_signed_distance(
    scene: *const sahkd_scene_tree,
    points: *const f32,
    count: usize,
    point_stride: usize,
    inside_test: u32,
    out: *mut f64,
    out_stride: usize,
    flags: u32,
) -> sahkd_status {
    let points = Points(points, count, point_stride);
    let by = (Target::signed_distance, Target::signed_distance_many);
    inside_query(scene, points, inside_test, out, out_stride, flags, by)
}

/// Whether each point is inside any geometry.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_contains(
    scene: *const sahkd_scene_tree,
    points: *const f32,
    count: usize,
    point_stride: usize,
    inside_test: u32,
    out: *mut bool,
    out_stride: usize,
    flags: u32,
) -> sahkd_status {
    let points = Points(points, count, point_stride);
    let by = (Target::contains, Target::contains_many);
    inside_query(scene, points, inside_test, out, out_stride, flags, by)
}
