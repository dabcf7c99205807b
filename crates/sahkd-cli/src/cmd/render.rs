//! `sahkd render`: build a mesh's tree, render a picture of it through the tree, write it as
//! PNG, and report the build and the ray throughput of each ray type.

use super::build::{Built, Report as BuildReport};
use super::Context;
use crate::format;
use crate::input::{MeshArg, Source};
use crate::options::BuilderArgs;
use crate::output;
use crate::progress::Progress;
use anyhow::{bail, Result};
use clap::ValueEnum;
use image::{ExtendedColorType, ImageEncoder};
use sahkd::render::{render, Camera, Image, RayCounts, RenderOptions, Shading};
use sahkd::{KdTree, Vec3};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub mesh: MeshArg,

    /// Where to write the picture (PNG)
    #[arg(long, short, value_name = "IMAGE.png", default_value = "sahkd.png")]
    pub output: PathBuf,

    /// Picture width in pixels
    #[arg(long, value_name = "PIXELS", allow_negative_numbers = true, default_value_t = 1024,
          value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub width: u32,

    /// Picture height in pixels
    #[arg(long, value_name = "PIXELS", allow_negative_numbers = true, default_value_t = 768,
          value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub height: u32,

    /// Camera placement: `auto` frames the whole scene from above and to the side (or looks
    /// from inside a scene that surrounds its centre, such as a courtyard), `front` is the
    /// fixed benchmark view from +z; --eye, --look-at, --up and --fov override its parts
    #[arg(long, value_enum, value_name = "VIEW", default_value_t = CameraArg::Auto)]
    pub camera: CameraArg,

    /// Camera position
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = parse_vector)]
    pub eye: Option<Vec3>,

    /// The point the camera looks at
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = parse_vector)]
    pub look_at: Option<Vec3>,

    /// The camera's up direction (need not be perpendicular to the view)
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = parse_vector)]
    pub up: Option<Vec3>,

    /// Vertical field of view in degrees, in (0, 180)
    #[arg(long, value_name = "DEGREES", allow_negative_numbers = true, value_parser = parse_fov)]
    pub fov: Option<f32>,

    /// How hits are coloured: the surface normal (primary rays only), ambient occlusion,
    /// or diffuse light from a sun with shadow rays
    #[arg(long, value_enum, value_name = "MODE", default_value_t = ShadingArg::Diffuse)]
    pub shading: ShadingArg,

    /// Samples (primary rays) per pixel, jittered and averaged when more than 1
    #[arg(long, value_name = "N", allow_negative_numbers = true, default_value_t = 1,
          value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub spp: u32,

    /// Ambient occlusion rays per hit
    #[arg(long, value_name = "N", allow_negative_numbers = true, default_value_t = 16,
          value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub ao_samples: u32,

    /// Print one JSON object on stdout instead of text
    #[arg(long)]
    pub json: bool,

    // Last: the heading of its flattened options would carry over to any argument after it.
    #[command(flatten)]
    pub builder: BuilderArgs,
}

/// The camera presets of `sahkd::render::Camera`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CameraArg {
    /// Three-quarter view from above that frames the whole scene, or a view from inside
    Auto,
    /// Fixed view from +z, two scene diagonals away (the benchmark camera)
    Front,
}

/// `sahkd::render::Shading` as a command-line value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ShadingArg {
    /// The geometric normal as colour
    Normal,
    /// Ambient occlusion
    Ao,
    /// Sun with shadows plus a headlight
    Diffuse,
}

impl From<ShadingArg> for Shading {
    fn from(s: ShadingArg) -> Shading {
        match s {
            ShadingArg::Normal => Shading::Normal,
            ShadingArg::Ao => Shading::Ao,
            ShadingArg::Diffuse => Shading::Diffuse,
        }
    }
}

impl Args {
    /// The preset camera for a scene box, with the parts given on the command line replaced.
    fn camera(&self, tree: &KdTree) -> Camera {
        let preset = match self.camera {
            CameraArg::Auto => Camera::framing(tree),
            CameraArg::Front => Camera::front(tree.bounds()),
        };
        Camera {
            eye: self.eye.unwrap_or(preset.eye),
            look_at: self.look_at.unwrap_or(preset.look_at),
            up: self.up.unwrap_or(preset.up),
            fov_y_degrees: self.fov.unwrap_or(preset.fov_y_degrees),
        }
    }

    fn render_options(&self, tree: &KdTree) -> RenderOptions {
        self.render_options_with(self.camera(tree))
    }

    fn render_options_with(&self, camera: Camera) -> RenderOptions {
        RenderOptions {
            shading: self.shading.into(),
            spp: self.spp,
            ao_samples: self.ao_samples,
            ..RenderOptions::new(self.width, self.height, camera)
        }
    }
}

#[derive(Serialize)]
struct CameraReport {
    eye: [f32; 3],
    look_at: [f32; 3],
    up: [f32; 3],
    fov_y_degrees: f32,
}

/// The JSON report: the build's, then the picture's.
#[derive(Serialize)]
struct Report<'a> {
    build: BuildReport<'a>,
    output: String,
    width: u32,
    height: u32,
    shading: &'static str,
    spp: u32,
    ao_samples: u32,
    camera: CameraReport,
    /// Making the tree's trace layout, done once before the picture (not part of `render_ms`
    /// nor of the rays' times).
    layout_ms: f64,
    render_ms: f64,
    primary: RayCounts,
    occlusion: RayCounts,
}

pub fn run(args: Args, context: &Context) -> Result<()> {
    let progress = Progress::new(context.quiet, args.json);
    // Everything the user can get wrong is checked before the long steps; the picture goes
    // to a temporary file beside the output, renamed over it only once it is complete.
    check_output(&args.output, &args.mesh)?;
    let mut builder = args.builder.builder()?;
    // The picture's own limits (size, samples) need no tree: checked with a stand-in camera.
    if let Err(e) = args.render_options_with(standin_camera()).validate() {
        bail!("cannot render: {e}");
    }
    let built = Built::new(&args.mesh, &mut builder, &context.builder_flags, &progress)?;
    let options = args.render_options(&built.build.tree);
    if let Err(e) = options.validate() {
        bail!("cannot render: {e}");
    }

    let start = Instant::now();
    builder.install(|| built.build.tree.prepare_trace());
    let layout_ms = start.elapsed().as_secs_f64() * 1e3;

    let bar = progress.bar(
        u64::from(options.width) * u64::from(options.height),
        "rendering",
    );
    let shown = AtomicU64::new(0);
    let on_tile = |done: u64, _total: u64| {
        // Tiles finish out of order; keep the bar from stepping back.
        if shown.fetch_max(done, Ordering::Relaxed) < done {
            bar.set_position(done);
        }
    };
    let start = Instant::now();
    let (image, rays) = builder.install(|| render(&built.build.tree, &options, &on_tile));
    let render_ms = start.elapsed().as_secs_f64() * 1e3;
    bar.finish_and_clear();

    let spinner = progress.spinner(format!("writing {}", args.output.display()));
    let written = write_png(&args.output, &image);
    spinner.finish_and_clear();
    written?;

    let camera = &options.camera;
    if args.json {
        format::print_json(&Report {
            build: built.report(&builder, None),
            output: args.output.display().to_string(),
            width: options.width,
            height: options.height,
            shading: options.shading.name(),
            spp: options.spp,
            ao_samples: options.ao_samples,
            camera: CameraReport {
                eye: array(camera.eye),
                look_at: array(camera.look_at),
                up: array(camera.up),
                fov_y_degrees: camera.fov_y_degrees,
            },
            layout_ms,
            render_ms,
            primary: rays.primary,
            occlusion: rays.occlusion,
        })?;
    } else {
        let mut t = built.table(&builder);
        t.row(
            "picture",
            format!(
                "{} x {}, {} shading, {} per pixel",
                options.width,
                options.height,
                options.shading.name(),
                plural(u64::from(options.spp), "sample")
            ),
        )
        .row(
            "camera",
            format!(
                "eye {}, looking at {}, up {}, {} degree field of view",
                vector(camera.eye),
                vector(camera.look_at),
                vector(camera.up),
                camera.fov_y_degrees
            ),
        )
        .row("trace layout", format::ms(layout_ms))
        .row("render time", format::ms(render_ms))
        .row("primary rays", ray_counts(&rays.primary, "camera"))
        .row(
            "occlusion rays",
            ray_counts(
                &rays.occlusion,
                match options.shading {
                    Shading::Ao => "AO",
                    Shading::Normal | Shading::Diffuse => "shadow",
                },
            ),
        )
        .row("picture written to", args.output.display().to_string());
        format::print_text(&t.render())?;
    }
    Ok(())
}

/// `rays, Mrays/s, nodes and triangles per ray`, or `none` when there were none.
fn ray_counts(c: &RayCounts, kind: &str) -> String {
    if c.rays == 0 {
        return "none".to_string();
    }
    format!(
        "{} {kind} rays, {:.2} Mrays/s, {:.1} nodes visited and {:.2} triangles tested per ray",
        format::count(c.rays),
        c.mrays_per_s,
        c.nodes_per_ray,
        c.triangles_per_ray
    )
}

fn plural(n: u64, what: &str) -> String {
    if n == 1 {
        format!("1 {what}")
    } else {
        format!("{} {what}s", format::count(n))
    }
}

fn array(v: Vec3) -> [f32; 3] {
    [v[0], v[1], v[2]]
}

fn vector(v: Vec3) -> String {
    format!("({:.4}, {:.4}, {:.4})", v[0], v[1], v[2])
}

/// `x,y,z`: three finite numbers separated by commas (spaces allowed).
fn parse_vector(s: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let numbers: Vec<f32> = parts
        .iter()
        .filter_map(|p| p.parse::<f32>().ok().filter(|x| x.is_finite()))
        .collect();
    match numbers[..] {
        [x, y, z] if parts.len() == 3 => Ok(Vec3::new(x, y, z)),
        _ => Err(format!(
            "expected three finite numbers separated by commas, such as 1,2.5,-3; found `{s}`"
        )),
    }
}

fn parse_fov(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(x) if x > 0.0 && x < 180.0 => Ok(x),
        Ok(_) => Err(format!(
            "the field of view must be between 0 and 180 degrees, found {s}"
        )),
        Err(_) => Err(format!("expected a number of degrees, found `{s}`")),
    }
}

/// A valid camera for checking the picture's options before the tree exists.
fn standin_camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 0.0, 1.0),
        look_at: Vec3::new(0.0, 0.0, 0.0),
        up: Vec3::new(0.0, 1.0, 0.0),
        fov_y_degrees: 45.0,
    }
}

/// Checks that the output is a `.png` that can be written and is not the mesh file.
fn check_output(path: &Path, mesh: &MeshArg) -> Result<()> {
    let extension = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    if !extension.eq_ignore_ascii_case("png") {
        bail!(
            "{}: cannot write {} pictures; the output must end in .png",
            path.display(),
            if extension.is_empty() {
                "extensionless".to_string()
            } else {
                format!(".{extension}")
            }
        );
    }
    let source = Source::resolve(&mesh.mesh);
    output::check(path, &source.file().into_iter().collect::<Vec<_>>())
}

/// Encodes the picture and writes it whole to `path`.
fn write_png(path: &Path, image: &Image) -> Result<()> {
    output::write(path, |writer| {
        image::codecs::png::PngEncoder::new(writer)
            .write_image(
                &image.rgb,
                image.width,
                image.height,
                ExtendedColorType::Rgb8,
            )
            .map_err(std::io::Error::other)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors_are_three_finite_numbers() {
        assert_eq!(
            parse_vector("1, -2.5,3e1").unwrap(),
            Vec3::new(1.0, -2.5, 30.0)
        );
        for bad in ["", "1,2", "1,2,3,4", "1,,3", "a,b,c", "1,2,inf", "1;2;3"] {
            assert!(parse_vector(bad).is_err(), "{bad:?} was accepted");
        }
    }

    #[test]
    fn the_field_of_view_is_between_0_and_180_degrees() {
        assert_eq!(parse_fov("45").unwrap(), 45.0);
        for bad in ["0", "180", "-10", "nan", "wide"] {
            assert!(parse_fov(bad).is_err(), "{bad:?} was accepted");
        }
    }
}
