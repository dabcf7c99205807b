//! Ray and point queries of trees and scene trees. One generic body per query
//! ([`Target`] is what a tree and a scene tree both answer); the `extern "C"` functions only
//! name their arguments.

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

fn tree_hit(h: Option<Hit>) -> sahkd_hit {
    h.map_or(MISS, |h| sahkd_hit {
        t: h.t,
        u: h.u,
        v: h.v,
        prim: h.prim,
        geometry: 0,
    })
}

fn scene_hit(h: Option<SceneHit>) -> sahkd_hit {
    h.map_or(MISS, |h| sahkd_hit {
        t: h.t,
        u: h.u,
        v: h.v,
        prim: h.prim,
        geometry: h.geometry,
    })
}

fn tree_closest(c: Option<ClosestPoint>) -> sahkd_closest {
    c.map_or(NOWHERE, |c| sahkd_closest {
        point: c.point,
        distance: c.distance,
        barycentrics: c.barycentrics,
        prim: c.prim,
        geometry: 0,
    })
}

fn scene_closest(c: Option<SceneClosestPoint>) -> sahkd_closest {
    c.map_or(NOWHERE, |c| sahkd_closest {
        point: c.point,
        distance: c.distance,
        barycentrics: c.barycentrics,
        prim: c.prim,
        geometry: c.geometry,
    })
}

/// What a tree and a scene tree both answer, for one ray or point and for arrays of them
/// (`parallel`: on every core; else on the calling thread).
pub(crate) trait Target: Sync {
    fn closest(&self, ray: &Ray) -> sahkd_hit;
    fn any(&self, ray: &Ray) -> bool;
    fn closest_many(&self, rays: &[Ray], parallel: bool) -> Vec<sahkd_hit>;
    fn any_many(&self, rays: &[Ray], parallel: bool) -> Vec<bool>;
    fn nearest(&self, p: Vec3) -> sahkd_closest;
    fn nearest_many(&self, points: &[Vec3]) -> Vec<sahkd_closest>;
    fn distance(&self, p: Vec3) -> f64;
    fn distance_many(&self, points: &[Vec3]) -> Vec<f64>;
    fn signed_distance(&self, p: Vec3, test: InsideTest) -> f64;
    fn signed_distance_many(&self, points: &[Vec3], test: InsideTest) -> Vec<f64>;
    fn contains(&self, p: Vec3, test: InsideTest) -> bool;
    fn contains_many(&self, points: &[Vec3], test: InsideTest) -> Vec<bool>;
}

impl Target for sahkd_tree {
    fn closest(&self, ray: &Ray) -> sahkd_hit {
        tree_hit(self.tree.intersect(ray))
    }
    fn any(&self, ray: &Ray) -> bool {
        self.tree.occluded(ray)
    }
    fn closest_many(&self, rays: &[Ray], parallel: bool) -> Vec<sahkd_hit> {
        let hits = if parallel {
            self.tree.intersect_batch(rays)
        } else {
            let mut out = vec![None; rays.len()];
            self.tree.intersect_into(rays, &mut out);
            out
        };
        hits.into_iter().map(tree_hit).collect()
    }
    fn any_many(&self, rays: &[Ray], parallel: bool) -> Vec<bool> {
        if parallel {
            self.tree.occluded_batch(rays)
        } else {
            let mut out = vec![false; rays.len()];
            self.tree.occluded_into(rays, &mut out);
            out
        }
    }
    fn nearest(&self, p: Vec3) -> sahkd_closest {
        tree_closest(self.tree.closest_point(p))
    }
    fn nearest_many(&self, points: &[Vec3]) -> Vec<sahkd_closest> {
        let found = self.tree.closest_point_batch(points);
        found.into_iter().map(tree_closest).collect()
    }
    fn distance(&self, p: Vec3) -> f64 {
        self.tree.distance(p)
    }
    fn distance_many(&self, points: &[Vec3]) -> Vec<f64> {
        self.tree.distance_batch(points)
    }
    fn signed_distance(&self, p: Vec3, test: InsideTest) -> f64 {
        self.tree.signed_distance(p, test)
    }
    fn signed_distance_many(&self, points: &[Vec3], test: InsideTest) -> Vec<f64> {
        self.tree.signed_distance_batch(points, test)
    }
    fn contains(&self, p: Vec3, test: InsideTest) -> bool {
        self.tree.contains(p, test)
    }
    fn contains_many(&self, points: &[Vec3], test: InsideTest) -> Vec<bool> {
        self.tree.contains_batch(points, test)
    }
}

impl Target for sahkd_scene_tree {
    fn closest(&self, ray: &Ray) -> sahkd_hit {
        scene_hit(self.scene.intersect(ray))
    }
    fn any(&self, ray: &Ray) -> bool {
        self.scene.occluded(ray)
    }
    fn closest_many(&self, rays: &[Ray], parallel: bool) -> Vec<sahkd_hit> {
        let hits = if parallel {
            self.scene.intersect_batch(rays)
        } else {
            rays.iter().map(|r| self.scene.intersect(r)).collect()
        };
        hits.into_iter().map(scene_hit).collect()
    }
    fn any_many(&self, rays: &[Ray], parallel: bool) -> Vec<bool> {
        if parallel {
            self.scene.occluded_batch(rays)
        } else {
            rays.iter().map(|r| self.scene.occluded(r)).collect()
        }
    }
    fn nearest(&self, p: Vec3) -> sahkd_closest {
        scene_closest(self.scene.closest_point(p))
    }
    fn nearest_many(&self, points: &[Vec3]) -> Vec<sahkd_closest> {
        let found = self.scene.closest_point_batch(points);
        found.into_iter().map(scene_closest).collect()
    }
    fn distance(&self, p: Vec3) -> f64 {
        self.scene.distance(p)
    }
    fn distance_many(&self, points: &[Vec3]) -> Vec<f64> {
        self.scene.distance_batch(points)
    }
    fn signed_distance(&self, p: Vec3, test: InsideTest) -> f64 {
        self.scene.signed_distance(p, test)
    }
    fn signed_distance_many(&self, points: &[Vec3], test: InsideTest) -> Vec<f64> {
        self.scene.signed_distance_batch(points, test)
    }
    fn contains(&self, p: Vec3, test: InsideTest) -> bool {
        self.scene.contains(p, test)
    }
    fn contains_many(&self, points: &[Vec3], test: InsideTest) -> Vec<bool> {
        self.scene.contains_batch(points, test)
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

unsafe fn intersect_one(t: &impl Target, ray: *const sahkd_ray, hit: *mut sahkd_hit) -> Result<()> {
    let ray = one_ray(ray)?;
    put(hit, t.closest(&ray), "hit")
}

unsafe fn occluded_one(t: &impl Target, ray: *const sahkd_ray, out: *mut bool) -> Result<()> {
    let ray = one_ray(ray)?;
    put(out, t.any(&ray), "occluded")
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

/// Point queries share their reading, flag and writing; `single` answers one point (the
/// serial path), `many` an array on every core.
#[allow(clippy::too_many_arguments)]
unsafe fn point_query<T: Copy + Send>(
    p: *const f32,
    count: usize,
    stride: usize,
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

// ---- Trees -------------------------------------------------------------------------------

/// The closest hit of one ray.
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_intersect(
    tree: *const sahkd_tree,
    ray: *const sahkd_ray,
    hit: *mut sahkd_hit,
) -> sahkd_status {
    guard(|| intersect_one(get(tree, "tree")?, ray, hit))
}

/// Whether one ray hits anything in [t_min, t_max] (stops at the first hit found).
#[no_mangle]
pub unsafe extern "C" fn sahkd_tree_occluded(
    tree: *const sahkd_tree,
    ray: *const sahkd_ray,
    occluded: *mut bool,
) -> sahkd_status {
    guard(|| occluded_one(get(tree, "tree")?, ray, occluded))
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
    guard(|| {
        intersect_aos(
            get(tree, "tree")?,
            rays,
            count,
            ray_stride,
            hits,
            hit_stride,
            flags,
        )
    })
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
    guard(|| intersect_soa(get(tree, "tree")?, rays, count, hits, flags))
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
    guard(|| {
        let t = get(tree, "tree")?;
        occluded_many(
            t,
            aos_rays(rays, count, ray_stride)?,
            occluded,
            occluded_stride,
            flags,
        )
    })
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
    guard(|| {
        let t = get(tree, "tree")?;
        occluded_many(t, soa_rays(rays, count)?, occluded, occluded_stride, flags)
    })
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
        let fits = found.len().min(capacity);
        let all = found.len();
        write_all(
            hits,
            0,
            found
                .into_iter()
                .take(fits)
                .map(|h| tree_hit(Some(h)))
                .collect(),
            "hits",
        )?;
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
    t: &KdTree,
    rays: Vec<Ray>,
    counts: *mut u32,
    counts_stride: usize,
    parallel: bool,
) -> Result<()> {
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
    guard(|| {
        let t = &get(tree, "tree")?.tree;
        let parallel = parallel(flags)?;
        let rays = aos_rays(rays, count, ray_stride)?;
        count_hits_many(t, rays, counts, counts_stride, parallel)
    })
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
    guard(|| {
        let t = &get(tree, "tree")?.tree;
        let parallel = parallel(flags)?;
        let rays = soa_rays(rays, count)?;
        count_hits_many(t, rays, counts, counts_stride, parallel)
    })
}

/// Every hit of `rays`, flattened with offsets (shared by the array-of-structures and the
/// structure-of-arrays call).
#[allow(clippy::too_many_arguments)]
unsafe fn all_hits_many(
    t: &KdTree,
    rays: Vec<Ray>,
    hits: *mut sahkd_hit,
    capacity: usize,
    offsets: *mut usize,
    total: *mut usize,
    parallel: bool,
) -> Result<()> {
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
    let flat = found
        .into_iter()
        .flatten()
        .map(|h| tree_hit(Some(h)))
        .collect();
    write_all(hits, 0, flat, "hits")
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
    guard(|| {
        put(total, 0, "total")?;
        let t = &get(tree, "tree")?.tree;
        let parallel = parallel(flags)?;
        let rays = aos_rays(rays, count, ray_stride)?;
        all_hits_many(t, rays, hits, capacity, offsets, total, parallel)
    })
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
    guard(|| {
        put(total, 0, "total")?;
        let t = &get(tree, "tree")?.tree;
        let parallel = parallel(flags)?;
        let rays = soa_rays(rays, count)?;
        all_hits_many(t, rays, hits, capacity, offsets, total, parallel)
    })
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
    guard(|| {
        closest_point(
            get(tree, "tree")?,
            points,
            count,
            point_stride,
            out,
            out_stride,
            flags,
        )
    })
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
    guard(|| {
        distance(
            get(tree, "tree")?,
            points,
            count,
            point_stride,
            out,
            out_stride,
            flags,
        )
    })
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
    guard(|| {
        let t = get(tree, "tree")?;
        signed_distance(
            t,
            points,
            count,
            point_stride,
            inside_test,
            out,
            out_stride,
            flags,
        )
    })
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
    guard(|| {
        let t = get(tree, "tree")?;
        contains(
            t,
            points,
            count,
            point_stride,
            inside_test,
            out,
            out_stride,
            flags,
        )
    })
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
    guard(|| {
        let t = &get(tree, "tree")?.tree;
        let single = |p| t.winding_number(p);
        let many = |ps: &[Vec3]| t.winding_number_batch(ps);
        point_query(
            points,
            count,
            point_stride,
            out,
            out_stride,
            flags,
            single,
            many,
        )
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
    guard(|| intersect_one(get(scene, "scene")?, ray, hit))
}

/// Whether one ray hits any geometry of the scene.
#[no_mangle]
pub unsafe extern "C" fn sahkd_scene_tree_occluded(
    scene: *const sahkd_scene_tree,
    ray: *const sahkd_ray,
    occluded: *mut bool,
) -> sahkd_status {
    guard(|| occluded_one(get(scene, "scene")?, ray, occluded))
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
    guard(|| {
        intersect_aos(
            get(scene, "scene")?,
            rays,
            count,
            ray_stride,
            hits,
            hit_stride,
            flags,
        )
    })
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
    guard(|| intersect_soa(get(scene, "scene")?, rays, count, hits, flags))
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
    guard(|| {
        let s = get(scene, "scene")?;
        occluded_many(
            s,
            aos_rays(rays, count, ray_stride)?,
            occluded,
            occluded_stride,
            flags,
        )
    })
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
    guard(|| {
        let s = get(scene, "scene")?;
        occluded_many(s, soa_rays(rays, count)?, occluded, occluded_stride, flags)
    })
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
    guard(|| {
        closest_point(
            get(scene, "scene")?,
            points,
            count,
            point_stride,
            out,
            out_stride,
            flags,
        )
    })
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
    guard(|| {
        distance(
            get(scene, "scene")?,
            points,
            count,
            point_stride,
            out,
            out_stride,
            flags,
        )
    })
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
    guard(|| {
        let s = get(scene, "scene")?;
        signed_distance(
            s,
            points,
            count,
            point_stride,
            inside_test,
            out,
            out_stride,
            flags,
        )
    })
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
    guard(|| {
        let s = get(scene, "scene")?;
        contains(
            s,
            points,
            count,
            point_stride,
            inside_test,
            out,
            out_stride,
            flags,
        )
    })
}

// ---- The bodies both share ---------------------------------------------------------------

unsafe fn intersect_aos(
    t: &impl Target,
    rays: *const sahkd_ray,
    count: usize,
    ray_stride: usize,
    hits: *mut sahkd_hit,
    hit_stride: usize,
    flags: u32,
) -> Result<()> {
    let parallel = parallel(flags)?;
    let rays = aos_rays(rays, count, ray_stride)?;
    check_out(hits, count, hit_stride, "hits")?;
    write_all(hits, hit_stride, t.closest_many(&rays, parallel), "hits")
}

unsafe fn intersect_soa(
    t: &impl Target,
    rays: *const sahkd_rays_soa,
    count: usize,
    hits: *const sahkd_hits_soa,
    flags: u32,
) -> Result<()> {
    let parallel = parallel(flags)?;
    let rays = soa_rays(rays, count)?;
    get(hits, "hits")?;
    write_hits_soa(hits, t.closest_many(&rays, parallel))
}

unsafe fn occluded_many(
    t: &impl Target,
    rays: Vec<Ray>,
    out: *mut bool,
    stride: usize,
    flags: u32,
) -> Result<()> {
    let parallel = parallel(flags)?;
    check_out(out, rays.len(), stride, "occluded")?;
    write_all(out, stride, t.any_many(&rays, parallel), "occluded")
}

unsafe fn closest_point(
    t: &impl Target,
    p: *const f32,
    count: usize,
    stride: usize,
    out: *mut sahkd_closest,
    out_stride: usize,
    flags: u32,
) -> Result<()> {
    let (single, many) = (|p| t.nearest(p), |ps: &[Vec3]| t.nearest_many(ps));
    point_query(p, count, stride, out, out_stride, flags, single, many)
}

unsafe fn distance(
    t: &impl Target,
    p: *const f32,
    count: usize,
    stride: usize,
    out: *mut f64,
    out_stride: usize,
    flags: u32,
) -> Result<()> {
    let (single, many) = (|p| t.distance(p), |ps: &[Vec3]| t.distance_many(ps));
    point_query(p, count, stride, out, out_stride, flags, single, many)
}

#[allow(clippy::too_many_arguments)]
unsafe fn signed_distance(
    t: &impl Target,
    p: *const f32,
    count: usize,
    stride: usize,
    test: u32,
    out: *mut f64,
    out_stride: usize,
    flags: u32,
) -> Result<()> {
    let test = inside(test)?;
    let single = |p| t.signed_distance(p, test);
    let many = |ps: &[Vec3]| t.signed_distance_many(ps, test);
    point_query(p, count, stride, out, out_stride, flags, single, many)
}

#[allow(clippy::too_many_arguments)]
unsafe fn contains(
    t: &impl Target,
    p: *const f32,
    count: usize,
    stride: usize,
    test: u32,
    out: *mut bool,
    out_stride: usize,
    flags: u32,
) -> Result<()> {
    let test = inside(test)?;
    let single = |p| t.contains(p, test);
    let many = |ps: &[Vec3]| t.contains_many(ps, test);
    point_query(p, count, stride, out, out_stride, flags, single, many)
}
