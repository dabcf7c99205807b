//! table1.md: the paper's Table 1 with this machine's numbers beside it, then every
//! measurement of the run (all builds, ray throughput, Fig. 1 and Fig. 2 as numbers).

use super::{Results, SceneResult, Spread};
use crate::format;
use crate::gpu::GpuReport;
use sahkd::render::RayCounts;
use std::fmt::Write;

/// Table 1's builder columns, in the paper's order, then sahkd's default builder (not in
/// the paper).
pub const COLUMNS: [(&str, &str); 5] = [
    ("median", "[14] (median)"),
    ("sweep", "Wald [2] (sweep, serial)"),
    ("naive", "naive"),
    ("level", "ours (level)"),
    ("hybrid", "sahkd default (hybrid)"),
];

/// `median (min–max)` with as many decimals as the size needs.
pub fn spread(s: &Spread) -> String {
    format!("{} ({}–{})", number(s.median), number(s.min), number(s.max))
}

fn number(x: f64) -> String {
    if x >= 100.0 {
        format!("{x:.0}")
    } else if x >= 10.0 {
        format!("{x:.1}")
    } else {
        format!("{x:.2}")
    }
}

fn ratio(a: Option<f64>, b: Option<f64>) -> String {
    match (a, b) {
        (Some(a), Some(b)) if b > 0.0 => format!("{:.2}", a / b),
        _ => "—".into(),
    }
}

/// The median build time of `algorithm` at its Table 1 thread count.
pub fn table_ms(results: &Results, scene: &SceneResult, algorithm: &str) -> Option<f64> {
    let threads = results.settings.table_threads(algorithm);
    scene
        .build(algorithm, threads)
        .and_then(|b| b.measured.as_ref())
        .map(|m| m.build_ms.median)
}

pub fn markdown(results: &Results) -> String {
    let mut md = String::new();
    let s = &results.settings;
    let m = &results.machine;
    let o = &s.build_options;
    let _ = writeln!(md, "# Table 1, the paper's and this machine's\n");
    let _ = writeln!(md, "Command: `{}`\n", results.command);
    let _ = writeln!(
        md,
        "Machine: {}, {} hardware threads, {} memory, {}; load average (1, 5, 15 min) {} before \
         and {} after the run, which took {:.0} s.\n",
        m.cpu, m.cores, m.memory, m.os, m.load_before, m.load_after, results.seconds
    );
    let _ = writeln!(
        md,
        "Settings: every build with the same options ({} axes, {} counting, clip {}, \
         K_T = {}, K_I = {}, empty bonus {}, leaf size {}, depth limit {}); one warm-up build, \
         then {} timed builds, median (min–max) in ms; threads {:?} (the serial sweep at {} only); \
         naive only up to {} triangles.\n",
        o.axes.name(),
        o.counting.name(),
        if o.clip { "on" } else { "off" },
        o.cost.traversal,
        o.cost.intersection,
        o.cost.empty_bonus,
        o.cost.leaf_size,
        o.cost
            .max_depth
            .map_or("auto (8 + 1.3 log2 N)".to_string(), |d| d.to_string()),
        s.repeat,
        s.threads,
        s.threads[0],
        format::count(s.naive_cap as u64),
    );
    let _ = writeln!(md, "{}\n", device_note(results));

    let _ = writeln!(
        md,
        "Build time in ms. **paper**: Table 1 of Li, Tan & Liao, parallel builders at 64 threads \
         on a GTX 750 Ti, Wald's serial builder on a four-core Intel E3. **sahkd**: this run, \
         parallel builders at {} threads, the sweep at {}. The last three columns are the \
         speed-ups of the level builder (time of the other builder / time of ours). The hybrid \
         column is sahkd's default builder (binned SAH at the top by default, sweep subtrees below; \
         the sweep's tree with the same bins), at the parallel builders' thread count.\n",
        s.table_threads("level"),
        s.table_threads("sweep"),
    );
    let _ = write!(md, "| scene | triangles | measured by |");
    for (_, title) in COLUMNS {
        let _ = write!(md, " {title} |");
    }
    let _ = writeln!(md, " sweep / ours | median / ours | naive / ours |");
    let _ = writeln!(
        md,
        "|---|---|---{}",
        "|---:".repeat(COLUMNS.len() + 3) + "|"
    );
    for scene in &results.scenes {
        if let Some(p) = &scene.paper {
            let _ = write!(md, "| {} | {} | paper |", p.name, p.triangles);
            for (a, _) in COLUMNS {
                // As the paper prints them: whole milliseconds.
                match p.ms(a) {
                    Some(ms) => write!(md, " {ms:.0} |"),
                    None => write!(md, " — |"),
                }
                .ok();
            }
            let _ = writeln!(
                md,
                " {} | {} | {} |",
                ratio(Some(p.sweep_ms), Some(p.level_ms)),
                ratio(Some(p.median_ms), Some(p.level_ms)),
                ratio(Some(p.naive_ms), Some(p.level_ms)),
            );
        }
        let first = if scene.paper.is_some() {
            ""
        } else {
            &scene.label
        };
        let _ = write!(
            md,
            "| {first} | {} ({}) | sahkd |",
            format::count(scene.triangles as u64),
            file_name(&scene.source)
        );
        for (a, _) in COLUMNS {
            let threads = s.table_threads(a);
            let cell = match scene.build(a, threads) {
                Some(b) => match (&b.measured, &b.skipped) {
                    (Some(m), _) => spread(&m.build_ms),
                    (None, Some(why)) => why.clone(),
                    (None, None) => "—".into(),
                },
                None => "not run".into(),
            };
            let _ = write!(md, " {cell} |");
        }
        let level = table_ms(results, scene, "level");
        let _ = writeln!(
            md,
            " {} | {} | {} |",
            ratio(table_ms(results, scene, "sweep"), level),
            ratio(table_ms(results, scene, "median"), level),
            ratio(table_ms(results, scene, "naive"), level),
        );
    }
    let stand_ins: Vec<_> = results
        .scenes
        .iter()
        .filter_map(|sc| sc.paper.map(|p| (p, &sc.source)))
        .collect();
    if !stand_ins.is_empty() {
        let _ = writeln!(md, "\nStand-ins for the paper's scenes:\n");
        for (p, source) in stand_ins {
            let _ = writeln!(
                md,
                "- {} ({}) -> `{}`: {}.",
                p.name,
                p.triangles,
                file_name(source),
                p.note
            );
        }
    }

    all_builds(&mut md, results);
    gpu_builds(&mut md, results);
    rays(&mut md, results);
    levels(&mut md, results);
    speedups(&mut md, results);
    md
}

fn file_name(source: &str) -> String {
    std::path::Path::new(source)
        .file_name()
        .map_or(source.to_string(), |f| f.to_string_lossy().into_owned())
}

fn all_builds(md: &mut String, results: &Results) {
    let _ = writeln!(md, "\n## Every build\n");
    let _ = writeln!(
        md,
        "Times in ms, median (min–max) of {} builds after a warm-up. SAH cost under the cost \
         model above, normalised by the root's surface area. Tree memory: nodes, references and \
         triangle data; working memory: the builder's arrays at their peak.\n",
        results.settings.repeat
    );
    let _ = writeln!(
        md,
        "| scene | builder | threads | build ms | pre-sort ms | SAH cost | nodes | leaves | \
         references | depth | tree memory | peak working memory |"
    );
    let _ = writeln!(
        md,
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for scene in &results.scenes {
        for b in &scene.builds {
            match (&b.measured, &b.skipped) {
                (Some(m), _) => {
                    let _ = writeln!(
                        md,
                        "| {} | {} | {} | {} | {} | {:.3} | {} | {} | {} | {} | {} | {} |",
                        scene.label,
                        b.algorithm,
                        b.threads,
                        spread(&m.build_ms),
                        spread(&m.presort_ms),
                        m.sah_cost,
                        format::count(m.nodes as u64),
                        format::count(m.leaves as u64),
                        format::count(m.references as u64),
                        m.depth,
                        format::bytes(m.tree_bytes as u64),
                        format::bytes(m.peak_working_bytes as u64),
                    );
                }
                (None, why) => {
                    let _ = writeln!(
                        md,
                        "| {} | {} | {} | {} | | | | | | | | |",
                        scene.label,
                        b.algorithm,
                        b.threads,
                        why.as_deref().unwrap_or("—")
                    );
                }
            }
        }
    }
}

/// Where the builds ran, and on which GPU adapter(s).
fn device_note(results: &Results) -> String {
    if results.settings.device != "gpu" {
        return "Device: every build on the CPU.".into();
    }
    let mut adapters: Vec<&str> = gpu_rows(results)
        .map(|(_, _, gpu)| gpu.adapter.as_str())
        .collect();
    adapters.sort_unstable();
    adapters.dedup();
    format!(
        "Device: the level builder's trees built on the GPU ({}; --device gpu), every other \
         builder and all rays on the CPU.",
        if adapters.is_empty() {
            "no level build ran".to_string()
        } else {
            adapters.join(", ")
        }
    )
}

/// Every measured build that ran on a GPU: scene label, threads and its report.
fn gpu_rows(results: &Results) -> impl Iterator<Item = (&str, usize, &GpuReport)> {
    results.scenes.iter().flat_map(|scene| {
        scene.builds.iter().filter_map(move |b| {
            let gpu = b.measured.as_ref()?.gpu.as_ref()?;
            Some((scene.label.as_str(), b.threads, gpu))
        })
    })
}

fn gpu_builds(md: &mut String, results: &Results) {
    let Some((_, _, first)) = gpu_rows(results).next() else {
        return;
    };
    let _ = writeln!(md, "\n## GPU builds\n");
    let _ = writeln!(
        md,
        "The level builder on the GPU, the last timed build of each row above: ms of the \
         upload, of each phase summed over the levels, and of the download; host round trips \
         (reads of GPU results by the host) per build and per level. The host's pre-sort is the \
         pre-sort column above (serial: the thread count does not change a GPU build).\n"
    );
    let _ = write!(md, "| scene | threads | adapter | upload |");
    for (name, _) in &first.phases_ms {
        let _ = write!(md, " {name} |");
    }
    let _ = writeln!(md, " download | levels | round trips | per level |");
    let _ = writeln!(
        md,
        "|---|---:|---|---:|{}---:|---:|---:|---:|",
        "---:|".repeat(first.phases_ms.len())
    );
    for (label, threads, gpu) in gpu_rows(results) {
        let _ = write!(
            md,
            "| {label} | {threads} | {} | {} |",
            gpu.adapter,
            number(gpu.upload_ms)
        );
        for (_, ms) in &gpu.phases_ms {
            let _ = write!(md, " {} |", number(*ms));
        }
        let _ = writeln!(
            md,
            " {} | {} | {} | {:.1} |",
            number(gpu.download_ms),
            gpu.levels,
            gpu.round_trips,
            gpu.round_trips_per_level
        );
    }
}

fn rays(md: &mut String, results: &Results) {
    let r = &results.settings.rays;
    let _ = writeln!(md, "\n## Ray throughput\n");
    let _ = writeln!(
        md,
        "Camera {}. Primary rays: one per pixel of a {} x {} picture; from each of their hits one \
         shadow ray to a point light (any hit) and one cosine-weighted bounce ray (closest hit), \
         traced as batches (`sahkd::render::RaySets`). Ambient occlusion: a {} x {} picture, {} \
         rays per hit, reaching 0.1 scene diagonal. {} threads; each ray type timed on its own; \
         Mrays/s median (min–max) of {} runs after a warm-up; nodes visited and triangles tested \
         per ray (in brackets) are means over every 7th ray or pixel.\n",
        r.camera,
        r.width,
        r.height,
        r.ao_size,
        r.ao_size,
        r.ao_samples,
        r.threads,
        results.settings.repeat
    );
    let _ = writeln!(
        md,
        "| scene | tree of | primary rays | primary Mrays/s | shadow rays | shadow Mrays/s | \
         bounce Mrays/s | AO rays | AO Mrays/s |"
    );
    let _ = writeln!(md, "|---|---|---:|---:|---:|---:|---:|---:|---:|");
    let cell = |s: &Spread, c: &RayCounts| {
        format!(
            "{} ({:.1}, {:.1})",
            spread(s),
            c.nodes_per_ray,
            c.triangles_per_ray
        )
    };
    for scene in &results.scenes {
        for row in &scene.rays {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                scene.label,
                row.algorithm,
                format::count(row.primary.rays),
                cell(&row.primary_mrays, &row.primary),
                format::count(row.shadow.rays),
                cell(&row.shadow_mrays, &row.shadow),
                cell(&row.bounce_mrays, &row.bounce),
                format::count(row.ao.rays),
                cell(&row.ao_mrays, &row.ao),
            );
        }
    }
}

fn levels(md: &mut String, results: &Results) {
    let Some(first) = results.levels.first() else {
        return;
    };
    let _ = writeln!(
        md,
        "\n## Fig. 1: time of the first n levels ({})\n",
        first.scene
    );
    let _ = writeln!(
        md,
        "T_n: build time with the depth limited to n (the same builder and options; for the \
         depth-first sweep this is the only way to stop after n levels, and the level builder is \
         measured the same way). T_sort: the pre-sort part of those builds. \
         P_n = median(T_n - T_sort) / median(T_1 - T_sort), the differences taken build by \
         build.\n"
    );
    let _ = write!(md, "| n |");
    for c in &results.levels {
        let _ = write!(
            md,
            " {0} T_n ms ({1} thr.) | {0} T_sort ms | {0} T_n - T_sort ms | {0} P_n |",
            c.algorithm, c.threads
        );
    }
    let _ = writeln!(md);
    let _ = writeln!(
        md,
        "|---:|{}",
        "---:|---:|---:|---:|".repeat(results.levels.len())
    );
    for (i, point) in first.points.iter().enumerate() {
        let _ = write!(md, "| {} |", point.level);
        for c in &results.levels {
            let p = &c.points[i];
            let _ = write!(
                md,
                " {} | {} | {} | {:.2} |",
                spread(&p.t_ms),
                number(p.presort_ms.median),
                spread(&p.after_sort_ms),
                p.p
            );
        }
        let _ = writeln!(md);
    }
}

/// Speed-up of each parallel builder against its smallest thread count, per scene.
pub fn speedup(scene: &SceneResult, algorithm: &str, base: usize, threads: usize) -> Option<f64> {
    let ms = |t| {
        scene
            .build(algorithm, t)
            .and_then(|b| b.measured.as_ref())
            .map(|m| m.build_ms.median)
    };
    Some(ms(base)? / ms(threads)?)
}

fn speedups(md: &mut String, results: &Results) {
    let s = &results.settings;
    let base = s.threads[0];
    let _ = writeln!(
        md,
        "\n## Fig. 2: speed-up against {base} thread{}\n",
        if base == 1 { "" } else { "s" }
    );
    let _ = writeln!(
        md,
        "Median build time at {base} / median at n threads. This machine has {} hardware \
         threads: more threads than that share them and cannot speed anything up.\n",
        results.machine.cores
    );
    let _ = write!(md, "| scene | builder |");
    for t in &s.threads {
        let _ = write!(md, " {t} |");
    }
    let _ = writeln!(md);
    let _ = writeln!(md, "|---|---|{}", "---:|".repeat(s.threads.len()));
    for scene in &results.scenes {
        for &a in s.algorithms.iter().filter(|&&a| a != "sweep") {
            if speedup(scene, a, base, base).is_none() {
                continue;
            }
            let _ = write!(md, "| {} | {a} |", scene.label);
            for &t in &s.threads {
                let cell = speedup(scene, a, base, t).map_or("—".into(), |x| format!("{x:.2}"));
                let _ = write!(md, " {cell} |");
            }
            let _ = writeln!(md);
        }
    }
}
