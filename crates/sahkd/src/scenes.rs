//! Procedural scenes (placeholder: a tessellated sphere until the generators land).

use crate::mesh::Mesh;

/// The scene used when no mesh file is given.
pub const DEFAULT_SCENE: &str = "spd:sphere:10000";

/// Makes the scene named by a spec such as `spd:sphere:10000` (kind and approximate
/// triangle count).
pub fn generate(spec: &str) -> Result<Mesh, String> {
    let parts: Vec<&str> = spec.split(':').collect();
    if parts.len() != 3 || parts[0] != "spd" {
        return Err(format!(
            "{spec}: expected a scene spec like {DEFAULT_SCENE}"
        ));
    }
    let n: usize = parts[2]
        .parse()
        .map_err(|_| format!("{spec}: '{}' is not a triangle count", parts[2]))?;
    Ok(sphere(((n / 2) as f64).sqrt().max(2.0) as usize))
}

/// A UV sphere of radius 1 with `k` stacks and `k` slices (about 2k^2 triangles).
fn sphere(k: usize) -> Mesh {
    let mut m = Mesh::default();
    for i in 0..=k {
        let theta = std::f32::consts::PI * i as f32 / k as f32;
        for j in 0..k {
            let phi = 2.0 * std::f32::consts::PI * j as f32 / k as f32;
            m.vertices.push([
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ]);
        }
    }
    for i in 0..k {
        for j in 0..k {
            let a = (i * k + j) as u32;
            let b = (i * k + (j + 1) % k) as u32;
            let (c, d) = (a + k as u32, b + k as u32);
            m.triangles.push([a, c, b]);
            m.triangles.push([b, c, d]);
        }
    }
    m
}
