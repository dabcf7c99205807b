//! The rays a renderer casts, made from one camera: primary rays, and from every primary hit
//! a shadow ray, ambient-occlusion rays and a bounce ray. They are the yardstick of
//! `sahkd bench` and `examples/trace_throughput.rs`, and the sets
//! `scripts/embree_throughput.py` replays against Embree.
//!
//! Every set is a pure function of the tree, the camera and the picture size: the random
//! numbers are hashes of (primary ray index, dimension), as in [`render`](super::render).

use super::sampling::{cosine_direction, SampleRng};
use super::shading::surface_origin;
use super::{Camera, OFFSET_SCALE};
use crate::geometry::Vec3;
use crate::trace::Ray;
use crate::tree::KdTree;

/// Ambient-occlusion rays per primary hit.
pub const AO_RAYS: u32 = 8;
/// How far ambient-occlusion rays reach, times the scene diagonal.
const AO_REACH: f32 = 0.1;

/// What a set of rays asks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Query {
    /// The closest hit (`KdTree::intersect`).
    Closest,
    /// Whether anything is hit (`KdTree::occluded`).
    Any,
}

impl Query {
    pub fn name(self) -> &'static str {
        match self {
            Query::Closest => "closest",
            Query::Any => "any",
        }
    }
}

/// One named set of rays and the query it is traced with.
#[derive(Clone, Debug)]
pub struct RaySet {
    pub name: &'static str,
    pub query: Query,
    pub rays: Vec<Ray>,
}

/// The four ray sets of one camera's picture.
#[derive(Clone, Debug)]
pub struct RaySets {
    pub camera: Camera,
    /// The point light the shadow rays aim at.
    pub light: Vec3,
    /// Whether the camera stands inside the scene's box (a building seen from inside).
    pub inside: bool,
    /// `primary` (closest hit): one ray per pixel centre, row by row. From every primary hit,
    /// moved off the surface as `render` does: `shadow` (any hit), one ray to the light,
    /// stopping just short of it; `ao` (any hit), `AO_RAYS` cosine-weighted rays reaching a
    /// tenth of the scene diagonal; `bounce` (closest hit), one cosine-weighted ray.
    pub sets: [RaySet; 4],
}

impl RaySets {
    /// The sets of a `width` x `height` picture of `tree` through `camera`. Traces the
    /// primary rays (in the current rayon pool) to find their hits.
    pub fn new(tree: &KdTree, camera: Camera, width: u32, height: u32) -> RaySets {
        let bounds = tree.bounds();
        let inside = (0..3).all(|a| camera.eye[a] > bounds.lo[a] && camera.eye[a] < bounds.hi[a]);
        // Above and to the front left of the scene; for a camera inside the box, high up in
        // the middle of the box.
        let light = if inside {
            bounds.centre() + Vec3::new(0.0, 0.3 * bounds.extent()[1], 0.0)
        } else {
            bounds.centre() + Vec3::new(-0.3, 0.6, 0.4) * bounds.diagonal()
        };
        let primary: Vec<Ray> = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| camera.primary_ray(width, height, x as f32 + 0.5, y as f32 + 0.5))
            .collect();
        let hits = tree.intersect_batch(&primary);
        let offset = OFFSET_SCALE * bounds.diagonal();
        let ao_reach = AO_REACH * bounds.diagonal();
        let (mut shadow, mut ao, mut bounce) = (Vec::new(), Vec::new(), Vec::new());
        for (i, (ray, hit)) in primary.iter().zip(&hits).enumerate() {
            let Some(hit) = hit else { continue };
            let tri = &tree.triangles()[hit.prim as usize];
            let (p, n) = surface_origin(tri, ray, hit, offset);
            // The light sits in empty space: stop just short of it.
            shadow.push(Ray::new(p, light - p).with_range(0.0, 1.0 - 1e-4));
            let rng = SampleRng::new(i as u64, 0);
            let direction =
                |k: u32| cosine_direction(n, rng.get(2 * k as u64), rng.get(2 * k as u64 + 1));
            ao.extend((0..AO_RAYS).map(|k| Ray::new(p, direction(k)).with_range(0.0, ao_reach)));
            bounce.push(Ray::new(p, direction(AO_RAYS)));
        }
        let set = |name, query, rays| RaySet { name, query, rays };
        RaySets {
            camera,
            light,
            inside,
            sets: [
                set("primary", Query::Closest, primary),
                set("shadow", Query::Any, shadow),
                set("ao", Query::Any, ao),
                set("bounce", Query::Closest, bounce),
            ],
        }
    }

    /// The set called `name`.
    pub fn get(&self, name: &str) -> Option<&RaySet> {
        self.sets.iter().find(|s| s.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::facing_normal;
    use crate::{build_triangles, BuildOptions};

    /// A floor under a box: the camera sees both, so every set has rays.
    fn scene() -> KdTree {
        let q = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| [[a, b, c], [a, c, d]];
        let v = Vec3::new;
        let mut tris = Vec::new();
        tris.extend(q(
            v(-4., 0., -4.),
            v(4., 0., -4.),
            v(4., 0., 4.),
            v(-4., 0., 4.),
        ));
        tris.extend(q(
            v(-1., 1., 1.),
            v(1., 1., 1.),
            v(1., 1., -1.),
            v(-1., 1., -1.),
        ));
        tris.extend(q(
            v(-1., 0., 1.),
            v(1., 0., 1.),
            v(1., 1., 1.),
            v(-1., 1., 1.),
        ));
        build_triangles(tris, &BuildOptions::default())
            .unwrap()
            .tree
    }

    #[test]
    fn secondary_rays_leave_every_primary_hit_and_stay_in_their_hemisphere() {
        let tree = scene();
        let camera = Camera::near(tree.bounds());
        let sets = RaySets::new(&tree, camera, 32, 24);
        let primary = &sets.get("primary").unwrap().rays;
        assert_eq!(primary.len(), 32 * 24);
        let hits = primary.iter().filter_map(|r| tree.intersect(r)).count();
        assert!(
            hits > 0 && hits < primary.len(),
            "{hits} of {}",
            primary.len()
        );
        let [_, shadow, ao, bounce] = &sets.sets;
        assert_eq!(shadow.rays.len(), hits);
        assert_eq!(bounce.rays.len(), hits);
        assert_eq!(ao.rays.len(), AO_RAYS as usize * hits);
        let hit_rays = primary
            .iter()
            .filter_map(|r| tree.intersect(r).map(|h| (r, h)));
        for (k, (ray, hit)) in hit_rays.enumerate() {
            let normal = facing_normal(&tree.triangles()[hit.prim as usize], ray);
            let s = &shadow.rays[k];
            // The shadow ray ends just short of the light.
            let end = s.origin + s.direction * 1.0;
            assert!((end - sets.light).length() < 1e-4, "{end:?}");
            // It starts on the camera's side of the hit point, just off the surface.
            let point = ray.origin + ray.direction * hit.t;
            assert!((s.origin - point).dot(normal) > 0.0);
            assert!((s.origin - point).length() < 1e-3);
            // AO and bounce rays start there too, into the hemisphere around the normal.
            let group = &ao.rays[AO_RAYS as usize * k..AO_RAYS as usize * (k + 1)];
            for r in group.iter().chain([&bounce.rays[k]]) {
                assert_eq!(r.origin, s.origin);
                assert!((r.direction.length() - 1.0).abs() < 1e-5);
                assert!(r.direction.dot(normal) >= -1e-6, "{:?}", r.direction);
            }
            let reach = 0.1 * tree.bounds().diagonal();
            assert!(group.iter().all(|r| r.t_max == reach));
        }
    }

    #[test]
    fn the_same_sets_on_every_thread_count() {
        let tree = scene();
        let camera = Camera::near(tree.bounds());
        let make = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| RaySets::new(&tree, camera, 20, 20))
        };
        let (a, b) = (make(1), make(3));
        for (x, y) in a.sets.iter().zip(&b.sets) {
            assert_eq!(x.rays.len(), y.rays.len());
            for (r, s) in x.rays.iter().zip(&y.rays) {
                assert_eq!(
                    (r.origin, r.direction, r.t_max),
                    (s.origin, s.direction, s.t_max)
                );
            }
        }
    }
}
