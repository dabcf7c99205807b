//! Renders a procedural scene to a binary PPM file.
//!
//! ```text
//! cargo run --release -p sahkd --example render_ppm -- [OUT.ppm] [SCENE] [normal|ao|diffuse] [auto|front]
//! ```
//! Defaults: `render.ppm`, the default scene, normal shading, the automatic camera;
//! 320 x 240 pixels.

use sahkd::render::{render, Camera, RenderOptions, Shading};
use std::io::Write;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args.first().map_or("render.ppm", String::as_str);
    let spec = args
        .get(1)
        .map_or(sahkd::scenes::DEFAULT_SCENE, String::as_str);
    let shading: Shading = args.get(2).map_or(Ok(Shading::Normal), |s| s.parse())?;
    let mesh = sahkd::scenes::generate(spec)?;
    let tree = sahkd::build(&mesh, &sahkd::BuildOptions::default())?.tree;
    let camera = match args.get(3).map(String::as_str) {
        Some("front") => Camera::front(tree.bounds()),
        _ => Camera::auto(tree.bounds()),
    };
    let options = RenderOptions {
        shading,
        ..RenderOptions::new(320, 240, camera)
    };
    options.validate()?;
    let (image, report) = render(&tree, &options, &|_, _| {});
    let mut file = std::io::BufWriter::new(std::fs::File::create(out)?);
    write!(file, "P6\n{} {}\n255\n", image.width, image.height)?;
    file.write_all(&image.rgb)?;
    file.flush()?;
    println!(
        "{spec}: {} triangles -> {out}\n{}",
        mesh.triangles.len(),
        serde_json::to_string_pretty(&report)?
    );
    Ok(())
}
