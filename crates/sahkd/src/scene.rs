//! Several meshes in one scene, each placed once or many times (instancing), with a geometry
//! id in every answer.
//!
//! ```
//! use sahkd::scene::{Scene, Transform};
//! use sahkd::{BuildOptions, InsideTest, Mesh, Ray, Vec3};
//!
//! // A unit square in the plane z = 1, and a copy of it moved to z = 3.
//! let square = Mesh {
//!     vertices: vec![[0., 0., 1.], [1., 0., 1.], [1., 1., 1.], [0., 1., 1.]],
//!     triangles: vec![[0, 1, 2], [0, 2, 3]],
//! };
//! let mut scene = Scene::new();
//! let a = scene.add_mesh(&square).unwrap();
//! let b = scene.add_instance(a, Transform::translation([0., 0., 2.])).unwrap();
//! assert!(scene.add_instance(7, Transform::IDENTITY).is_err()); // no mesh 7
//! let tree = scene.build(&BuildOptions::default()).unwrap();
//!
//! let up = Ray::new(Vec3::new(0.25, 0.5, 2.), Vec3::new(0., 0., 1.));
//! let hit = tree.intersect(&up).unwrap();
//! assert_eq!((hit.t, hit.geometry, hit.prim), (1.0, b, 1));
//! let near = tree.closest_point(Vec3::new(0.5, 0.5, 0.)).unwrap();
//! assert_eq!((near.geometry, near.distance), (a, 1.0));
//! assert!(!tree.contains(Vec3::new(5., 5., 2.), InsideTest::Parity));
//! ```
//!
//! # Design: one tree over every placed triangle
//!
//! [`Scene::build`] bakes every placement into world space (corners transformed in f64,
//! rounded to f32 once) and builds one kd-tree over all of them with [`crate::build()`]. The
//! tree's triangles are laid out geometry after geometry, each in its mesh's order, so a tree
//! triangle index maps to (geometry, primitive) by a binary search in the geometries' start
//! offsets (4 bytes per geometry, nothing per triangle), and the tree's tie rule (lower
//! triangle index) becomes "lower geometry id, then lower primitive".
//!
//! The alternative, a small top tree over instance boxes with one tree per mesh, stores each
//! mesh once; it is the better choice for many copies of big meshes. We did not take it
//! because:
//! - point queries do not survive a non-rigid transform: under scaling or shear the nearest
//!   point in the mesh's own frame is not the nearest in the world, so closest point and
//!   distance would need a different search per instance, not the existing one;
//! - rays would be transformed into each instance's frame (another rounding, and the
//!   watertight test no longer watertight where instances touch) and walk two trees;
//! - one tree lets the SAH see where instances overlap, and every query here is the tuned
//!   walk of [`KdTree`] unchanged, answers checked against the same brute force.
//!
//! The price is memory and build time proportional to the placed triangles (instances times
//! mesh size). `examples/scene_instances.rs` compares the two on copies of one mesh: the one
//! tree stores and builds every copy's triangles, while its rays find the same hits at about
//! the rate of a tree per mesh. So a scene of many copies of a big mesh pays the instance
//! count in build time and memory here: that is the case for adding the top tree beside this one (for rigid placements,
//! where the point queries survive too), not instead of it.
//!
//! # Mirrors
//!
//! A transform with a negative determinant turns a mesh inside out (it reverses the winding of
//! its triangles). Baking swaps such a triangle's corners 1 and 2 so the placed mesh keeps its
//! orientation: its normals point out where the mesh's did, and the winding-number test still
//! counts +1 inside. The answers report barycentrics in the mesh's own corner order.
//!
//! # Inside
//!
//! [`SceneTree::contains`] is the union: a point is inside when it is inside any geometry,
//! each judged by itself (crossings counted per geometry, or one winding number per geometry),
//! so overlapping instances do not cancel each other out as a whole-scene parity would.
//! [`SceneTree::signed_distance`] is the distance to the nearest surface of any geometry,
//! negative inside any geometry.

use crate::builders::{build_triangles, BuildError, BuildOptions, BuildReport};
use crate::geometry::{Triangle, Vec3};
use crate::mesh::{Mesh, MeshError};
use crate::query::{winding_number, ClosestPoint, InsideTest, PARITY_DIRECTIONS};
use crate::trace::{Hit, Hit64, Ray, Ray64};
use crate::tree::KdTree;
use rayon::prelude::*;
use std::fmt;
use std::sync::Arc;

/// Items handed to a worker at a time by the batches.
const MIN_BATCH: usize = 64;

/// An affine transform: the rows of a 3x4 matrix `[A | t]`, mapping `p` to `A p + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform(pub [[f64; 4]; 3]);

impl Transform {
    pub const IDENTITY: Transform =
        Transform([[1., 0., 0., 0.], [0., 1., 0., 0.], [0., 0., 1., 0.]]);

    /// A translation by `t`.
    pub fn translation(t: [f64; 3]) -> Transform {
        let mut m = Self::IDENTITY.0;
        for (row, t) in m.iter_mut().zip(t) {
            row[3] = t;
        }
        Transform(m)
    }

    /// From the rows of a 4x4 matrix, whose last row must be `[0, 0, 0, 1]` (no projection).
    pub fn from_4x4(m: [[f64; 4]; 4]) -> Result<Transform, SceneError> {
        if m[3] != [0., 0., 0., 1.] {
            return Err(SceneError::BadTransform(format!(
                "the last row of a 4x4 transform must be [0, 0, 0, 1], got {:?}",
                m[3]
            )));
        }
        Ok(Transform([m[0], m[1], m[2]]))
    }

    /// `A p + t`.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        self.0
            .map(|r| r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + r[3])
    }

    /// The determinant of the linear part `A`.
    pub fn determinant(&self) -> f64 {
        let a = &self.0;
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    }

    /// Finite, and `A` invertible in float32 terms: every row of `A` long enough that the
    /// placed coordinates do not underflow float32 (at least its smallest normal number), and
    /// `A` with its rows scaled to length 1 well conditioned (condition number below
    /// `1 / f32::EPSILON`). Rows are the placed coordinates: a row nearly a combination of
    /// the others, or one that scales to nothing, leaves that coordinate without the mesh's
    /// shape once rounded to float32, flat within rounding. Scaling rows apart (different
    /// units per axis) loses nothing in float32 and is accepted.
    pub fn validate(&self) -> Result<(), SceneError> {
        if let Some((i, j)) = (0..3)
            .flat_map(|i| (0..4).map(move |j| (i, j)))
            .find(|&(i, j)| !self.0[i][j].is_finite())
        {
            return Err(SceneError::BadTransform(format!(
                "entry [{i}][{j}] is {} (every entry must be finite)",
                self.0[i][j]
            )));
        }
        // Lengths without overflow: scaled by the row's largest entry first.
        let lengths = self.0.map(|r| {
            let m = r[0].abs().max(r[1].abs()).max(r[2].abs());
            if m == 0.0 {
                return 0.0;
            }
            m * ((r[0] / m).powi(2) + (r[1] / m).powi(2) + (r[2] / m).powi(2)).sqrt()
        });
        if let Some(i) = lengths
            .iter()
            .position(|&l| !(l >= f32::MIN_POSITIVE as f64))
        {
            return Err(SceneError::BadTransform(format!(
                "the 3x3 part is singular in float32: row {i} has length {:e}, below float32's \
                 smallest normal number {:e}; it would flatten the mesh",
                lengths[i],
                f32::MIN_POSITIVE
            )));
        }
        let unit = Transform([0, 1, 2].map(|i| {
            let r = self.0[i];
            [r[0] / lengths[i], r[1] / lengths[i], r[2] / lengths[i], 0.0]
        }));
        let condition = unit.condition();
        if !(condition < 1.0 / f32::EPSILON as f64) {
            return Err(SceneError::BadTransform(format!(
                "the 3x3 part is singular or too nearly so for float32 (condition number \
                 {condition:.1e} with its rows scaled to length 1, at most {:.1e}): it would \
                 flatten the mesh",
                1.0 / f32::EPSILON as f64
            )));
        }
        Ok(())
    }

    /// The condition number of `A` in the Frobenius norm, `|A| |A^-1|`; infinite when `A`
    /// is singular.
    fn condition(&self) -> f64 {
        let a = &self.0;
        let det = self.determinant();
        if det == 0.0 {
            return f64::INFINITY;
        }
        // The adjugate's entries, each a 2x2 minor; A^-1 is the adjugate over det.
        let minor = |r0: usize, r1: usize, c0: usize, c1: usize| {
            a[r0][c0] * a[r1][c1] - a[r0][c1] * a[r1][c0]
        };
        let mut adjugate = 0.0;
        for (r0, r1) in [(1, 2), (0, 2), (0, 1)] {
            for (c0, c1) in [(1, 2), (0, 2), (0, 1)] {
                adjugate += minor(r0, r1, c0, c1).powi(2);
            }
        }
        let norm: f64 = a
            .iter()
            .map(|r| r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
            .sum();
        (norm * adjugate).sqrt() / det.abs()
    }
}

/// Why a scene could not be put together or built.
#[derive(Debug)]
pub enum SceneError {
    /// `add_instance` named an id that is not a mesh added with `add_mesh`.
    UnknownMesh {
        id: u32,
        meshes: usize,
    },
    /// Not finite, singular, or projective.
    BadTransform(String),
    /// A mesh given to `add_mesh` is invalid.
    InvalidMesh(MeshError),
    /// A triangle given to `add_triangles` has a non-finite corner.
    NonFiniteCorner {
        prim: usize,
    },
    /// A placed corner is beyond the float32 range.
    OutOfRange {
        geometry: u32,
        prim: usize,
    },
    Build(BuildError),
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SceneError::UnknownMesh { id, meshes } => write!(
                f,
                "no mesh with id {id}: instances place meshes added with add_mesh ({meshes} so far), not instances"
            ),
            SceneError::BadTransform(m) => write!(f, "bad transform: {m}"),
            SceneError::InvalidMesh(e) => write!(f, "invalid mesh: {e}"),
            SceneError::NonFiniteCorner { prim } => {
                write!(f, "invalid mesh: triangle {prim} has a non-finite corner")
            }
            SceneError::OutOfRange { geometry, prim } => write!(
                f,
                "geometry {geometry}: triangle {prim} placed beyond the float32 range"
            ),
            SceneError::Build(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for SceneError {}

/// One placement: which mesh, where.
#[derive(Clone)]
struct Placement {
    mesh: usize,
    transform: Option<Transform>,
}

/// Meshes and their placements, before the tree is built. Geometry ids count from 0 in the
/// order of `add_mesh` and `add_instance` calls together.
#[derive(Clone, Default)]
pub struct Scene {
    meshes: Vec<Arc<Vec<Triangle>>>,
    /// Per geometry id: the mesh it places, in the mesh's own frame or transformed.
    placements: Vec<Placement>,
    /// Per mesh, its geometry id (what `add_instance` takes).
    mesh_ids: Vec<u32>,
}

impl Scene {
    pub fn new() -> Scene {
        Scene::default()
    }

    /// Adds a mesh (validated) placed as it is; returns its geometry id, which
    /// [`add_instance`](Self::add_instance) takes to place it again.
    pub fn add_mesh(&mut self, mesh: &Mesh) -> Result<u32, SceneError> {
        mesh.validate().map_err(SceneError::InvalidMesh)?;
        self.add_triangles(mesh.corner_triangles())
    }

    /// [`add_mesh`](Self::add_mesh) for a triangle list; every corner must be finite.
    pub fn add_triangles(&mut self, triangles: Vec<Triangle>) -> Result<u32, SceneError> {
        if let Some(i) = triangles
            .iter()
            .position(|t| !t.iter().all(|v| v.is_finite()))
        {
            return Err(SceneError::NonFiniteCorner { prim: i });
        }
        let id = self.next_id()?;
        self.mesh_ids.push(id);
        self.meshes.push(Arc::new(triangles));
        self.placements.push(Placement {
            mesh: self.meshes.len() - 1,
            transform: None,
        });
        Ok(id)
    }

    /// Places the mesh whose geometry id is `mesh_id` again, transformed; returns the new
    /// geometry id.
    pub fn add_instance(&mut self, mesh_id: u32, transform: Transform) -> Result<u32, SceneError> {
        let mesh =
            self.mesh_ids
                .iter()
                .position(|&m| m == mesh_id)
                .ok_or(SceneError::UnknownMesh {
                    id: mesh_id,
                    meshes: self.meshes.len(),
                })?;
        transform.validate()?;
        let id = self.next_id()?;
        self.placements.push(Placement {
            mesh,
            transform: Some(transform),
        });
        Ok(id)
    }

    /// Number of geometries (meshes and instances).
    pub fn len(&self) -> usize {
        self.placements.len()
    }

    pub fn is_empty(&self) -> bool {
        self.placements.is_empty()
    }

    fn next_id(&self) -> Result<u32, SceneError> {
        u32::try_from(self.placements.len()).map_err(|_| {
            SceneError::Build(BuildError::InvalidOptions(
                "more than 2^32 geometries".into(),
            ))
        })
    }

    /// Bakes every placement into world space and builds one tree over all of them.
    pub fn build(&self, options: &BuildOptions) -> Result<SceneTree, SceneError> {
        let mut starts = Vec::with_capacity(self.placements.len() + 1);
        let mut mirrored = Vec::with_capacity(self.placements.len());
        let mut total = 0usize;
        for p in &self.placements {
            starts.push(u32::try_from(total).unwrap_or(u32::MAX));
            total += self.meshes[p.mesh].len();
            mirrored.push(p.transform.is_some_and(|t| t.determinant() < 0.0));
        }
        starts.push(u32::try_from(total).unwrap_or(u32::MAX));
        if total > crate::tree::Node::MAX_INDEX as usize {
            return Err(SceneError::Build(BuildError::InvalidOptions(format!(
                "{total} placed triangles is more than the {} a tree can hold",
                crate::tree::Node::MAX_INDEX
            ))));
        }
        let mut triangles = Vec::with_capacity(total);
        for (g, p) in self.placements.iter().enumerate() {
            let mesh = &self.meshes[p.mesh];
            let Some(t) = p.transform else {
                triangles.extend_from_slice(mesh);
                continue;
            };
            let placed: Vec<Triangle> = mesh
                .par_iter()
                .with_min_len(4096)
                .map(|tri| {
                    let mut out = tri.map(|c| {
                        let w = t.apply(c.0.map(f64::from));
                        Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32)
                    });
                    if mirrored[g] {
                        out.swap(1, 2);
                    }
                    out
                })
                .collect();
            if let Some(prim) = placed.iter().position(|t| !t.iter().all(|v| v.is_finite())) {
                return Err(SceneError::OutOfRange {
                    geometry: g as u32,
                    prim,
                });
            }
            triangles.extend(placed);
        }
        let built = build_triangles(triangles, options).map_err(SceneError::Build)?;
        Ok(SceneTree {
            tree: built.tree,
            report: built.report,
            starts,
            mirrored,
        })
    }
}

/// A ray's hit: distance, which geometry and which of its mesh's triangles, and the
/// barycentrics `(u, v)` of that triangle's corners 1 and 2 (in the mesh's corner order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneHit {
    pub t: f32,
    pub geometry: u32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

/// [`SceneHit`] of the f64 walk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneHit64 {
    pub t: f64,
    pub geometry: u32,
    pub prim: u32,
    pub u: f64,
    pub v: f64,
}

/// The closest point of the scene to a query point, in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneClosestPoint {
    pub point: [f64; 3],
    pub distance: f64,
    pub geometry: u32,
    pub prim: u32,
    /// Weights of the mesh triangle's corners 0, 1, 2.
    pub barycentrics: [f64; 3],
}

/// The tree of a [`Scene`], with the map from its triangles back to geometries.
pub struct SceneTree {
    tree: KdTree,
    report: BuildReport,
    /// Tree index of each geometry's first triangle, and the total at the end.
    starts: Vec<u32>,
    /// Per geometry: placed by a mirror, so its corners 1 and 2 were swapped.
    mirrored: Vec<bool>,
}

impl SceneTree {
    /// The tree over every placed triangle (world space, geometry after geometry).
    pub fn tree(&self) -> &KdTree {
        &self.tree
    }

    pub fn report(&self) -> &BuildReport {
        &self.report
    }

    /// Number of geometries.
    pub fn geometries(&self) -> usize {
        self.mirrored.len()
    }

    /// The geometry and primitive of a tree triangle.
    pub fn locate(&self, index: u32) -> (u32, u32) {
        // The last geometry starting at or before `index`: empty geometries share their start
        // with the next one, and are passed over.
        let g = self.starts.partition_point(|&s| s <= index) - 1;
        (g as u32, index - self.starts[g])
    }

    /// The tree index of a geometry's primitive; `None` when there is no such one.
    pub fn index_of(&self, geometry: u32, prim: u32) -> Option<u32> {
        let g = geometry as usize;
        let (start, end) = (*self.starts.get(g)?, *self.starts.get(g + 1)?);
        (prim < end - start).then_some(start + prim)
    }

    /// The placed corners of a geometry's primitive (world space, mesh corner order).
    pub fn triangle(&self, geometry: u32, prim: u32) -> Option<Triangle> {
        let mut t = self.tree.triangles()[self.index_of(geometry, prim)? as usize];
        if self.mirrored[geometry as usize] {
            t.swap(1, 2);
        }
        Some(t)
    }

    /// The unit geometric normal of a placed primitive, the way its mesh's winding points
    /// (outwards for an outward-wound mesh, mirrored or not); zero for a degenerate triangle.
    pub fn normal(&self, geometry: u32, prim: u32) -> Option<[f64; 3]> {
        let i = self.index_of(geometry, prim)?;
        // The tree's copy keeps the orientation (mirrors had their corners swapped).
        let t = self.tree.triangles()[i as usize].map(|c| c.0.map(f64::from));
        let e1 = [0, 1, 2].map(|k| t[1][k] - t[0][k]);
        let e2 = [0, 1, 2].map(|k| t[2][k] - t[0][k]);
        let n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        Some(if len > 0.0 {
            n.map(|c| c / len)
        } else {
            [0.0; 3]
        })
    }

    /// A hit of the scene's tree ([`tree`](Self::tree)) as the scene names it: the geometry,
    /// the primitive within it and the barycentrics in the geometry's own corner order.
    pub fn scene_hit(&self, h: Hit) -> SceneHit {
        let (geometry, prim) = self.locate(h.prim);
        let (u, v) = if self.mirrored[geometry as usize] {
            (h.v, h.u)
        } else {
            (h.u, h.v)
        };
        SceneHit {
            t: h.t,
            geometry,
            prim,
            u,
            v,
        }
    }

    fn hit64(&self, h: Hit64) -> SceneHit64 {
        let (geometry, prim) = self.locate(h.prim);
        let (u, v) = if self.mirrored[geometry as usize] {
            (h.v, h.u)
        } else {
            (h.u, h.v)
        };
        SceneHit64 {
            t: h.t,
            geometry,
            prim,
            u,
            v,
        }
    }

    fn closest(&self, c: ClosestPoint) -> SceneClosestPoint {
        let (geometry, prim) = self.locate(c.prim);
        let [a, b, w] = c.barycentrics;
        SceneClosestPoint {
            point: c.point,
            distance: c.distance,
            geometry,
            prim,
            barycentrics: if self.mirrored[geometry as usize] {
                [a, w, b]
            } else {
                [a, b, w]
            },
        }
    }

    /// The closest hit; ties in t go to the lower geometry id, then the lower primitive.
    pub fn intersect(&self, ray: &Ray) -> Option<SceneHit> {
        self.tree.intersect(ray).map(|h| self.scene_hit(h))
    }

    /// Whether anything is hit in `[ray.t_min, ray.t_max]`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.tree.occluded(ray)
    }

    /// Every hit, each (geometry, primitive) once, nearest first (ties as in `intersect`).
    pub fn all_hits(&self, ray: &Ray) -> Vec<SceneHit> {
        let hits = self.tree.all_hits(ray);
        hits.into_iter().map(|h| self.scene_hit(h)).collect()
    }

    /// [`intersect`](Self::intersect) in f64 (see [`KdTree::intersect_f64`]).
    pub fn intersect_f64(&self, ray: &Ray64) -> Option<SceneHit64> {
        self.tree.intersect_f64(ray).map(|h| self.hit64(h))
    }

    /// [`occluded`](Self::occluded) in f64.
    pub fn occluded_f64(&self, ray: &Ray64) -> bool {
        self.tree.occluded_f64(ray)
    }

    /// [`intersect`](Self::intersect) of every ray, on every core of the current rayon pool.
    pub fn intersect_batch(&self, rays: &[Ray]) -> Vec<Option<SceneHit>> {
        let hits = self.tree.intersect_batch(rays);
        hits.into_par_iter()
            .with_min_len(1024)
            .map(|h| h.map(|h| self.scene_hit(h)))
            .collect()
    }

    /// [`occluded`](Self::occluded) of every ray, on every core.
    pub fn occluded_batch(&self, rays: &[Ray]) -> Vec<bool> {
        self.tree.occluded_batch(rays)
    }

    /// [`all_hits`](Self::all_hits) of every ray, on every core.
    pub fn all_hits_batch(&self, rays: &[Ray]) -> Vec<Vec<SceneHit>> {
        rays.par_iter()
            .with_min_len(MIN_BATCH)
            .map(|r| self.all_hits(r))
            .collect()
    }

    /// [`intersect_f64`](Self::intersect_f64) of every ray, on every core.
    pub fn intersect_batch_f64(&self, rays: &[Ray64]) -> Vec<Option<SceneHit64>> {
        let hits = self.tree.intersect_batch_f64(rays);
        hits.into_par_iter()
            .with_min_len(1024)
            .map(|h| h.map(|h| self.hit64(h)))
            .collect()
    }

    /// [`occluded_f64`](Self::occluded_f64) of every ray, on every core.
    pub fn occluded_batch_f64(&self, rays: &[Ray64]) -> Vec<bool> {
        self.tree.occluded_batch_f64(rays)
    }

    /// The closest point of any geometry (ties to the lower geometry, then primitive);
    /// `None` for an empty scene or a non-finite point.
    pub fn closest_point(&self, p: Vec3) -> Option<SceneClosestPoint> {
        self.tree.closest_point(p).map(|c| self.closest(c))
    }

    /// Distance to the nearest geometry: infinite for an empty scene, NaN for a non-finite
    /// point.
    pub fn distance(&self, p: Vec3) -> f64 {
        self.tree.distance(p)
    }

    /// Whether `p` is inside any geometry, each judged alone under `test`; false for a
    /// non-finite point.
    pub fn contains(&self, p: Vec3, test: InsideTest) -> bool {
        self.contains_with(p, test, &mut Scratch::default())
    }

    /// The distance, negative inside any geometry; 0 on a surface.
    pub fn signed_distance(&self, p: Vec3, test: InsideTest) -> f64 {
        self.signed_with(p, test, &mut Scratch::default())
    }

    /// [`closest_point`](Self::closest_point) of every point, on every core.
    pub fn closest_point_batch(&self, points: &[Vec3]) -> Vec<Option<SceneClosestPoint>> {
        let found = self.tree.closest_point_batch(points);
        found
            .into_par_iter()
            .map(|c| c.map(|c| self.closest(c)))
            .collect()
    }

    /// [`distance`](Self::distance) of every point, on every core.
    pub fn distance_batch(&self, points: &[Vec3]) -> Vec<f64> {
        self.tree.distance_batch(points)
    }

    /// [`contains`](Self::contains) of every point, on every core.
    pub fn contains_batch(&self, points: &[Vec3], test: InsideTest) -> Vec<bool> {
        points
            .par_iter()
            .with_min_len(MIN_BATCH)
            .map_init(Scratch::default, |s, &p| self.contains_with(p, test, s))
            .collect()
    }

    /// [`signed_distance`](Self::signed_distance) of every point, on every core.
    pub fn signed_distance_batch(&self, points: &[Vec3], test: InsideTest) -> Vec<f64> {
        let distances = self.tree.distance_batch(points);
        points
            .par_iter()
            .zip(distances)
            .with_min_len(MIN_BATCH)
            .map_init(Scratch::default, |s, (&p, d)| self.signed(p, d, test, s))
            .collect()
    }

    fn signed_with(&self, p: Vec3, test: InsideTest, s: &mut Scratch) -> f64 {
        self.signed(p, self.tree.distance(p), test, s)
    }

    /// The distance `d` of `p`, negated when `p` lies inside a geometry.
    fn signed(&self, p: Vec3, d: f64, test: InsideTest, s: &mut Scratch) -> f64 {
        if d == 0.0 || !d.is_finite() {
            return d;
        }
        if self.contains_with(p, test, s) {
            -d
        } else {
            d
        }
    }

    fn contains_with(&self, p: Vec3, test: InsideTest, s: &mut Scratch) -> bool {
        if !p.is_finite() {
            return false;
        }
        match test {
            InsideTest::Winding => (0..self.geometries()).any(|g| {
                let tris =
                    &self.tree.triangles()[self.starts[g] as usize..self.starts[g + 1] as usize];
                !tris.is_empty() && winding_number(tris, p).abs() > 0.5
            }),
            InsideTest::Parity => {
                // The library's vote (two rays, a third on disagreement), per geometry.
                self.odd_geometries(p, PARITY_DIRECTIONS[0], &mut s.hits, &mut s.a);
                self.odd_geometries(p, PARITY_DIRECTIONS[1], &mut s.hits, &mut s.b);
                if s.a.iter().any(|g| s.b.binary_search(g).is_ok()) {
                    return true;
                }
                // Geometries odd along exactly one of the two rays: the third ray decides.
                let undecided =
                    s.a.iter()
                        .filter(|g| s.b.binary_search(g).is_err())
                        .chain(s.b.iter().filter(|g| s.a.binary_search(g).is_err()));
                s.c.clear();
                s.c.extend(undecided);
                if s.c.is_empty() {
                    return false;
                }
                let mut third = Vec::new();
                self.odd_geometries(p, PARITY_DIRECTIONS[2], &mut s.hits, &mut third);
                s.c.iter().any(|g| third.binary_search(g).is_ok())
            }
        }
    }

    /// The geometries (sorted) whose distinct triangles the ray from `p` along `d` crosses an
    /// odd number of times.
    fn odd_geometries(&self, p: Vec3, d: Vec3, hits: &mut Vec<u32>, odd: &mut Vec<u32>) {
        hits.clear();
        self.tree
            .for_each_hit(&Ray::new(p, d), |h| hits.push(h.prim));
        hits.sort_unstable();
        hits.dedup();
        odd.clear();
        // Sorted tree indices come geometry by geometry: count each run.
        let mut i = 0;
        while i < hits.len() {
            let (g, _) = self.locate(hits[i]);
            let end = self.starts[g as usize + 1];
            let run = hits[i..].partition_point(|&h| h < end);
            if run % 2 == 1 {
                odd.push(g);
            }
            i += run;
        }
    }
}

/// Per-worker buffers of the inside test.
#[derive(Default)]
struct Scratch {
    hits: Vec<u32>,
    a: Vec<u32>,
    b: Vec<u32>,
    c: Vec<u32>,
}
