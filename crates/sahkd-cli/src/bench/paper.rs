//! The paper's Table 1 (Li, Tan & Liao, section 3): its four scenes, their sizes, the build
//! times it reports, and the real meshes that stand in for them here.

use serde::Serialize;

/// One row of the paper's Table 1. Times in milliseconds, parallel builders at 64 threads on
/// a GTX 750 Ti, Wald's serial builder on the CPU (a four-core Intel E3).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PaperScene {
    /// The paper's name for the scene.
    pub name: &'static str,
    /// Its size as the paper prints it.
    pub triangles: &'static str,
    /// Reference [14], the Zhou-style builder (our `median`).
    pub median_ms: f64,
    /// Wald [2], serial (our `sweep`).
    pub sweep_ms: f64,
    /// The paper's builder without space trees (our `naive`).
    pub naive_ms: f64,
    /// The paper's builder (our `level`).
    pub level_ms: f64,
    /// The file in the scenes directory that stands in for it.
    pub stand_in: &'static str,
    /// Procedural stand-in when there is no scenes directory.
    pub procedural: &'static str,
    /// How the stand-in differs from the paper's scene.
    pub note: &'static str,
}

/// Table 1, in the paper's order.
pub const TABLE_1: [PaperScene; 4] = [
    PaperScene {
        name: "Toys",
        triangles: "11 k",
        median_ms: 31.0,
        sweep_ms: 37.0,
        naive_ms: 27.0,
        level_ms: 28.0,
        stand_in: "dragon_res4.ply",
        procedural: "spd:toys:11000",
        note: "Toys is not available; dragon_res4 has the same size (11k)",
    },
    PaperScene {
        name: "Bunny",
        triangles: "69 k",
        median_ms: 87.0,
        sweep_ms: 233.0,
        naive_ms: 240.0,
        level_ms: 54.0,
        stand_in: "bunny.ply",
        procedural: "spd:toys:69000",
        note: "the same Stanford Bunny (69,451 triangles)",
    },
    PaperScene {
        name: "Dragon",
        triangles: "252 k",
        median_ms: 193.0,
        sweep_ms: 641.0,
        naive_ms: 810.0,
        level_ms: 110.0,
        stand_in: "dragon_res2.ply",
        procedural: "spd:toys:252000",
        note: "no 252k Dragon exists; dragon_res2 (202k) is the nearest",
    },
    PaperScene {
        name: "Buddha",
        triangles: "1 M",
        median_ms: 790.0,
        sweep_ms: 2554.0,
        naive_ms: 2840.0,
        level_ms: 410.0,
        stand_in: "dragon.ply",
        procedural: "spd:toys:1000000",
        note: "the 1M Buddha is not available; the 871k Dragon stands in",
    },
];

impl PaperScene {
    /// The paper's time for one of our builders, by its command-line name.
    pub fn ms(&self, algorithm: &str) -> Option<f64> {
        match algorithm {
            "median" => Some(self.median_ms),
            "sweep" => Some(self.sweep_ms),
            "naive" => Some(self.naive_ms),
            "level" => Some(self.level_ms),
            _ => None,
        }
    }
}
