//! A small ray tracer over a [`KdTree`]: pictures for looking at a scene, and ray throughput
//! for measuring a tree.
//!
//! The picture is cut into 16 x 16 tiles rendered on every core of the current rayon pool.
//! Every random number is a hash of (pixel, sample, dimension), so the picture is the same
//! whatever the number of threads.
//!
//! Each tile runs in passes, so that each ray type is timed on its own and the plain
//! (uncounted) queries are what is timed:
//! 1. all primary rays of the tile (`KdTree::intersect`, walked in packets of neighbouring
//!    rays: the same answers), timed;
//! 2. all occlusion rays the hits need (`KdTree::occluded`: shadow rays for diffuse shading,
//!    AO rays for ambient occlusion; none for normal shading), timed;
//! 3. shading (untimed);
//! 4. counting: the rays of every `COUNT_STRIDE`-th pixel (row-major pixel index) are traced
//!    again with `intersect_counted` / `occluded_counted`, untimed, for the nodes visited and
//!    triangles tested per ray.
//!
//! `RayCounts::seconds` is the time spent in a ray type's pass summed over all tiles (that is,
//! over all threads) divided by the number of threads: the wall-clock share of that ray type
//! when the threads are kept busy. `mrays_per_s` is rays / seconds / 10^6, the throughput of
//! the whole pool.

mod camera;
mod ray_sets;
mod sampling;
mod shading;

pub use camera::Camera;
pub use ray_sets::{Query, RaySet, RaySets, AO_RAYS};
pub use shading::{
    background, facing_normal, normal_colour, surface_origin, to_rgb8, Shading, SUN_DIRECTION,
};

use crate::geometry::{Triangle, Vec3};
use crate::trace::{Hit, Ray, TraceStats};
use crate::tree::KdTree;
use camera::Projection;
use rayon::prelude::*;
use sampling::{cosine_direction, SampleRng};
use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Side of the square tiles the picture is rendered in.
pub const TILE: u32 = 16;
/// One pixel in this many (by row-major index) has its rays traced again with counters.
pub const COUNT_STRIDE: u64 = 7;
/// Occlusion rays start this far (times the scene diagonal) off the surface, along the normal.
pub const OFFSET_SCALE: f32 = 1e-5;

/// Everything that decides a picture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    pub width: u32,
    pub height: u32,
    pub camera: Camera,
    pub shading: Shading,
    /// Samples per pixel: 1 shoots through the pixel centre; more are jittered in the pixel
    /// and averaged.
    pub spp: u32,
    /// Occlusion rays per hit for `Shading::Ao`.
    pub ao_samples: u32,
    /// Reach of the AO rays; `None` is 0.1 x the scene diagonal.
    pub ao_distance: Option<f32>,
}

impl RenderOptions {
    /// Normal shading, one sample per pixel, 16 AO samples when AO is asked for.
    pub fn new(width: u32, height: u32, camera: Camera) -> RenderOptions {
        RenderOptions {
            width,
            height,
            camera,
            shading: Shading::Normal,
            spp: 1,
            ao_samples: 16,
            ao_distance: None,
        }
    }

    /// Checks the options; `render` itself never fails (it treats 0 samples as 1 and renders
    /// a broken camera as background), so call this to report user mistakes.
    pub fn validate(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!(
                "image size {}x{} has no pixels",
                self.width, self.height
            ));
        }
        if self.width as u64 * self.height as u64 > 1 << 28 {
            return Err(format!(
                "image size {}x{} is too large",
                self.width, self.height
            ));
        }
        if self.spp == 0 {
            return Err("samples per pixel must be at least 1".into());
        }
        if self.shading == Shading::Ao && self.ao_samples == 0 {
            return Err("ambient occlusion needs at least 1 sample per hit".into());
        }
        if let Some(d) = self.ao_distance {
            if !(d > 0.0 && d.is_finite()) {
                return Err(format!("AO distance must be a positive number, not {d}"));
            }
        }
        let c = &self.camera;
        if !(c.fov_y_degrees > 0.0 && c.fov_y_degrees < 180.0) {
            return Err(format!(
                "camera field of view must be between 0 and 180 degrees, not {}",
                c.fov_y_degrees
            ));
        }
        let forward = c.look_at - c.eye;
        if !(c.eye.is_finite() && c.look_at.is_finite() && c.up.is_finite()) {
            return Err("camera position, target and up must be finite".into());
        }
        if forward.length() == 0.0 {
            return Err("camera looks at its own position".into());
        }
        if forward.normalized().cross(c.up).length() < 1e-6 {
            return Err("camera up is parallel to the view direction".into());
        }
        Ok(())
    }
}

/// A picture: row-major from the top-left, 3 bytes (red, green, blue) per pixel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

impl Image {
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }
}

/// Throughput of one ray type.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct RayCounts {
    /// Rays traced (all of them, in the timed pass).
    pub rays: u64,
    /// Wall-clock share of this ray type (see the module documentation).
    pub seconds: f64,
    pub mrays_per_s: f64,
    /// Mean over the counted subset of rays (every `COUNT_STRIDE`-th pixel).
    pub nodes_per_ray: f64,
    pub triangles_per_ray: f64,
}

/// Throughput of the primary rays and of the occlusion (shadow or AO) rays of a render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct RenderReport {
    pub primary: RayCounts,
    pub occlusion: RayCounts,
}

/// Renders the tree's triangles as `options` say. `progress(done, total)` is called after
/// each tile with the number of pixels finished so far (from any thread; the counts of
/// concurrent calls may arrive out of order).
pub fn render(
    tree: &KdTree,
    options: &RenderOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> (Image, RenderReport) {
    let (width, height) = (options.width, options.height);
    let mut image = Image {
        width,
        height,
        rgb: vec![0; 3 * width as usize * height as usize],
    };
    if width == 0 || height == 0 {
        return (image, RenderReport::default());
    }
    let context = Context::new(tree, options);
    let tiles: Vec<(u32, u32)> = (0..height.div_ceil(TILE))
        .flat_map(|ty| (0..width.div_ceil(TILE)).map(move |tx| (tx * TILE, ty * TILE)))
        .collect();
    let total = width as u64 * height as u64;
    let done = AtomicU64::new(0);
    let results: Vec<TileResult> = tiles
        .par_iter()
        .map(|&(x0, y0)| {
            let r = context.tile(x0, y0);
            let finished = done.fetch_add(r.pixels.len() as u64, Ordering::Relaxed);
            progress(finished + r.pixels.len() as u64, total);
            r
        })
        .collect();

    let mut sums = TileResult::default();
    for (&(x0, y0), r) in tiles.iter().zip(&results) {
        let w = (width - x0).min(TILE);
        for (k, rgb) in r.pixels.iter().enumerate() {
            let (x, y) = (x0 + k as u32 % w, y0 + k as u32 / w);
            let i = 3 * (y as usize * width as usize + x as usize);
            image.rgb[i..i + 3].copy_from_slice(rgb);
        }
        sums.add(r);
    }
    let threads = rayon::current_num_threads().max(1) as f64;
    let report = RenderReport {
        primary: counts(
            sums.primary_rays,
            sums.primary_seconds / threads,
            &sums.primary_stats,
        ),
        occlusion: counts(
            sums.occlusion_rays,
            sums.occlusion_seconds / threads,
            &sums.occlusion_stats,
        ),
    };
    (image, report)
}

fn counts(rays: u64, seconds: f64, stats: &TraceStats) -> RayCounts {
    let per_ray = |x: u64| {
        if stats.rays == 0 {
            0.0
        } else {
            x as f64 / stats.rays as f64
        }
    };
    RayCounts {
        rays,
        seconds,
        mrays_per_s: if seconds > 0.0 {
            rays as f64 / seconds / 1e6
        } else {
            0.0
        },
        nodes_per_ray: per_ray(stats.nodes),
        triangles_per_ray: per_ray(stats.triangles),
    }
}

/// One tile's pixels (row-major within the tile) and measurements.
#[derive(Default)]
struct TileResult {
    pixels: Vec<[u8; 3]>,
    primary_rays: u64,
    primary_seconds: f64,
    primary_stats: TraceStats,
    occlusion_rays: u64,
    occlusion_seconds: f64,
    occlusion_stats: TraceStats,
}

impl TileResult {
    fn add(&mut self, o: &TileResult) {
        self.primary_rays += o.primary_rays;
        self.primary_seconds += o.primary_seconds;
        self.primary_stats += o.primary_stats;
        self.occlusion_rays += o.occlusion_rays;
        self.occlusion_seconds += o.occlusion_seconds;
        self.occlusion_stats += o.occlusion_stats;
    }
}

/// What shading a hit needs once its occlusion rays are answered.
#[derive(Clone, Copy)]
enum Pending {
    Colour([f32; 3]),
    /// Diffuse: normal, cosine to the sun (0 when facing away: no shadow ray then).
    Diffuse {
        normal: Vec3,
        sun_cosine: f32,
    },
    /// AO: fraction of free rays is the intensity.
    Ao,
}

/// Per-render constants.
struct Context<'a> {
    tree: &'a KdTree,
    options: &'a RenderOptions,
    projection: Projection,
    spp: u32,
    ao_samples: u32,
    ao_distance: f32,
    offset: f32,
}

impl<'a> Context<'a> {
    fn new(tree: &'a KdTree, options: &'a RenderOptions) -> Context<'a> {
        let b = tree.bounds();
        let diagonal = if b.is_empty() { 1.0 } else { b.diagonal() };
        Context {
            tree,
            options,
            projection: Projection::new(&options.camera, options.width, options.height),
            spp: options.spp.max(1),
            ao_samples: options.ao_samples.max(1),
            ao_distance: options.ao_distance.unwrap_or(0.1 * diagonal),
            offset: OFFSET_SCALE * diagonal,
        }
    }

    fn triangle(&self, hit: &Hit) -> &Triangle {
        &self.tree.triangles()[hit.prim as usize]
    }

    /// The primary ray of one sample: the pixel centre for 1 sample per pixel, a jittered
    /// point in the pixel otherwise.
    fn primary(&self, x: u32, y: u32, sample: u32) -> Ray {
        let (jx, jy) = if self.spp == 1 {
            (0.5, 0.5)
        } else {
            let rng = SampleRng::new(self.pixel_index(x, y), sample);
            (rng.get(0), rng.get(1))
        };
        self.projection.ray(x as f32 + jx, y as f32 + jy)
    }

    fn pixel_index(&self, x: u32, y: u32) -> u64 {
        y as u64 * self.options.width as u64 + x as u64
    }

    /// How to shade a hit, and its occlusion rays appended to `rays`.
    fn prepare(&self, ray: &Ray, hit: &Hit, rng: SampleRng, rays: &mut Vec<Ray>) -> Pending {
        let tri = self.triangle(hit);
        let (origin, normal) = surface_origin(tri, ray, hit, self.offset);
        match self.options.shading {
            Shading::Normal => Pending::Colour(normal_colour(tri, ray)),
            Shading::Diffuse => {
                let sun_cosine = normal.dot(SUN_DIRECTION).max(0.0);
                if sun_cosine > 0.0 {
                    rays.push(Ray::new(origin, SUN_DIRECTION));
                }
                Pending::Diffuse { normal, sun_cosine }
            }
            Shading::Ao => {
                for k in 0..self.ao_samples as u64 {
                    let d = cosine_direction(normal, rng.get(2 + 2 * k), rng.get(3 + 2 * k));
                    rays.push(Ray::new(origin, d).with_range(0.0, self.ao_distance));
                }
                Pending::Ao
            }
        }
    }

    fn finish(&self, ray: &Ray, pending: Pending, blocked: &[bool]) -> [f32; 3] {
        match pending {
            Pending::Colour(c) => c,
            Pending::Diffuse { normal, sun_cosine } => {
                let sunlit = sun_cosine > 0.0 && !blocked[0];
                shading::lit(shading::diffuse_intensity(normal, ray, sun_cosine, sunlit))
            }
            Pending::Ao => {
                let free = blocked.iter().filter(|&&b| !b).count();
                shading::lit(free as f32 / blocked.len() as f32)
            }
        }
    }

    fn tile(&self, x0: u32, y0: u32) -> TileResult {
        let x1 = (x0 + TILE).min(self.options.width);
        let y1 = (y0 + TILE).min(self.options.height);
        let pixels: Vec<(u32, u32)> = (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .collect();
        let spp = self.spp as usize;
        let primaries: Vec<Ray> = pixels
            .iter()
            .flat_map(|&(x, y)| (0..self.spp).map(move |s| self.primary(x, y, s)))
            .collect();

        // Pass 1: primary rays.
        let start = Instant::now();
        let hits = self.tree.intersect_serial(&primaries);
        let primary_seconds = start.elapsed().as_secs_f64();

        // Occlusion rays of every hit; sample i owns occlusion[ranges[i]..ranges[i + 1]].
        let mut occlusion = Vec::new();
        let mut ranges = Vec::with_capacity(hits.len() + 1);
        ranges.push(0);
        let pending: Vec<Pending> = (0..hits.len())
            .map(|i| {
                let ray = &primaries[i];
                let p = match &hits[i] {
                    None => Pending::Colour(background(ray)),
                    Some(hit) => {
                        let (x, y) = pixels[i / spp];
                        let rng = SampleRng::new(self.pixel_index(x, y), (i % spp) as u32);
                        self.prepare(ray, hit, rng, &mut occlusion)
                    }
                };
                ranges.push(occlusion.len());
                p
            })
            .collect();

        // Pass 2: occlusion rays.
        let start = Instant::now();
        let blocked = self.tree.occluded_serial(&occlusion);
        let occlusion_seconds = start.elapsed().as_secs_f64();

        let colours: Vec<[u8; 3]> = (0..pixels.len())
            .map(|k| {
                let mut sum = [0f32; 3];
                for i in k * spp..(k + 1) * spp {
                    let c = self.finish(
                        &primaries[i],
                        pending[i],
                        &blocked[ranges[i]..ranges[i + 1]],
                    );
                    (0..3).for_each(|j| sum[j] += c[j]);
                }
                to_rgb8(sum.map(|s| s / spp as f32))
            })
            .collect();

        // Counting pass over a fixed subset of pixels.
        let (mut primary_stats, mut occlusion_stats) =
            (TraceStats::default(), TraceStats::default());
        for (k, &(x, y)) in pixels.iter().enumerate() {
            if self.pixel_index(x, y) % COUNT_STRIDE != 0 {
                continue;
            }
            for i in k * spp..(k + 1) * spp {
                primary_stats.rays += 1;
                self.tree
                    .intersect_counted(&primaries[i], &mut primary_stats);
                for r in &occlusion[ranges[i]..ranges[i + 1]] {
                    occlusion_stats.rays += 1;
                    self.tree.occluded_counted(r, &mut occlusion_stats);
                }
            }
        }

        TileResult {
            pixels: colours,
            primary_rays: primaries.len() as u64,
            primary_seconds,
            primary_stats,
            occlusion_rays: occlusion.len() as u64,
            occlusion_seconds,
            occlusion_stats,
        }
    }
}
