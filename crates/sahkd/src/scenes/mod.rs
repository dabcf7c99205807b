//! Procedural scenes after Eric Haines' Standard Procedural Databases (SPD), any size.
//!
//! A scene is named by a spec `spd:KIND:N`, where N is the approximate triangle count. Every
//! generator is deterministic: the same spec gives the same mesh, bit for bit, whatever the
//! number of threads (randomness comes from hashes of coordinates, see `random`). The exact
//! count rules are in [`KINDS`] and in each kind's module:
//!
//! | kind          | triangles                                   | within          |
//! |---------------|---------------------------------------------|-----------------|
//! | `sphere`      | `2 m (s - 1)` (s stacks, m slices)          | 1.2x for N >= 6 |
//! | `sphereflake` | `(9^(L+1) - 1) / 8` spheres of `2 m (s - 1)` | 1.2x for N >= 6 |
//! | `mount`       | `2 g^2` (a g x g height field)              | 1.5x for N >= 8 |
//! | `tetra`       | `4^(d+1) k^2` (depth d, faces cut k x k)    | 1.25x for N >= 64 |
//! | `toys`        | 32 (ground) + the sum over the objects      | 1.25x for N >= 500 |

mod memory;
mod mount;
pub(crate) mod random;
mod shapes;
mod sphere;
mod sphereflake;
mod tetra;
mod toys;

use crate::mesh::Mesh;

pub use memory::{available_bytes, check_available};

/// The scene used when no mesh file is given.
pub const DEFAULT_SCENE: &str = "spd:toys:100000";

/// The largest triangle count a spec may ask for (the mesh would need tens of GB beyond it).
/// Below it, [`generate`] also checks the mesh against the memory available.
pub const MAX_TRIANGLES: u64 = 500_000_000;

/// An upper bound on a generated mesh's bytes per requested triangle: up to 1.5x the
/// triangles of N (the count rules above), 12 bytes each, and at most 3 vertices of 12
/// bytes per triangle.
const MESH_BYTES_PER_TRIANGLE: u64 = 72;

/// A kind of procedural scene and how its size follows from N.
#[derive(Clone, Copy, Debug)]
pub struct SceneKind {
    pub name: &'static str,
    pub description: &'static str,
    generate: fn(u64) -> Mesh,
}

/// Every kind `generate` knows, in the order error messages list them.
pub const KINDS: &[SceneKind] = &[
    SceneKind {
        name: "sphereflake",
        description: "a sphere with 9 children of a third its radius, recursively; depth L is \
                      the largest with 40 triangles per sphere, each sphere a UV sphere of \
                      N / spheres triangles",
        generate: sphereflake::generate,
    },
    SceneKind {
        name: "mount",
        description: "a fractal mountain: midpoint-displacement height field of g x g cells, \
                      g the integer nearest sqrt(N / 2), 2 g^2 triangles",
        generate: mount::generate,
    },
    SceneKind {
        name: "tetra",
        description: "a Sierpinski tetrahedron of depth d with faces cut into k x k, \
                      4^(d+1) k^2 triangles, d as deep as a k within 1.25x of N allows",
        generate: tetra::generate,
    },
    SceneKind {
        name: "toys",
        description: "spheres, tori, boxes and long thin cylinders of very different sizes on \
                      a large ground plane; N shared by the objects in proportion to the root \
                      of their areas",
        generate: toys::generate,
    },
    SceneKind {
        name: "sphere",
        description: "one UV sphere of 2 m (s - 1) triangles, m = 2 s slices",
        generate: sphere::generate,
    },
];

fn kind_names() -> String {
    KINDS.iter().map(|k| k.name).collect::<Vec<_>>().join(", ")
}

fn usage(spec: &str, problem: &str) -> String {
    format!(
        "scene spec '{spec}': {problem}; expected spd:KIND:N, where KIND is one of {} and N \
         the approximate number of triangles (for example {DEFAULT_SCENE})",
        kind_names()
    )
}

/// Makes the scene named by a spec such as `spd:toys:100000` (kind and approximate
/// triangle count; see the module documentation for the exact counts).
pub fn generate(spec: &str) -> Result<Mesh, String> {
    let parts: Vec<&str> = spec.trim().split(':').collect();
    if parts[0] != "spd" {
        return Err(usage(spec, "it does not start with 'spd:'"));
    }
    let kind_name = match parts.get(1) {
        Some(k) if !k.is_empty() => *k,
        _ => return Err(usage(spec, "the scene kind is missing")),
    };
    let kind = KINDS
        .iter()
        .find(|k| k.name == kind_name)
        .ok_or_else(|| usage(spec, &format!("unknown scene kind '{kind_name}'")))?;
    let count = match parts.get(2) {
        Some(n) if !n.is_empty() => *n,
        _ => return Err(usage(spec, "the triangle count N is missing")),
    };
    if parts.len() > 3 {
        return Err(usage(spec, "too many ':'-separated parts"));
    }
    let n: u64 = count.replace('_', "").parse().map_err(|_| {
        usage(
            spec,
            &format!("'{count}' is not a whole number of triangles"),
        )
    })?;
    if n == 0 {
        return Err(usage(spec, "the triangle count must be at least 1"));
    }
    if n > MAX_TRIANGLES {
        return Err(usage(
            spec,
            &format!("{n} triangles is more than the {MAX_TRIANGLES} a scene may have"),
        ));
    }
    check_available(
        n.saturating_mul(MESH_BYTES_PER_TRIANGLE),
        &format!("the scene {spec}"),
    )?;
    Ok((kind.generate)(n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_memory_bound_holds_for_every_kind() {
        for kind in KINDS {
            for n in [1_000, 5_000, 60_000] {
                let mesh = (kind.generate)(n);
                let bytes = 12 * (mesh.vertices.len() + mesh.triangles.len()) as u64;
                assert!(
                    bytes <= n * MESH_BYTES_PER_TRIANGLE,
                    "{} of {n}: {bytes} bytes",
                    kind.name
                );
            }
        }
    }
}
