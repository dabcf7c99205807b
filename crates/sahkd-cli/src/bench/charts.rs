//! The PNG charts of `sahkd bench`: Table 1 as grouped bars, Fig. 1 (P_n by level) and
//! Fig. 2 (speed-up by thread count). Text uses the embedded DejaVu Sans, so no system font
//! is needed.

use super::table::{speedup, table_ms, COLUMNS};
use super::Results;
use anyhow::{anyhow, Result};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use std::ops::Range;
use std::path::Path;
use std::sync::Once;

const SIZE: (u32, u32) = (1400, 800);
const FONT: &str = "sans-serif";

fn register_fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TTF shipped by the dejavu crate; a failure would only leave
        // the text out of the charts.
        let _ = register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
        let _ = register_font(FONT, FontStyle::Bold, dejavu::sans::bold());
    });
}

/// The RGB pixels of a chart before it is drawn.
fn blank() -> Vec<u8> {
    vec![0; SIZE.0 as usize * SIZE.1 as usize * 3]
}

/// A chart's pixels as a PNG file's bytes. Charts are drawn in memory and written by the
/// caller, so a failure to write (a full disk) is a plain I/O error naming the file rather
/// than the plotting backend's.
fn png(pixels: Vec<u8>) -> Result<Vec<u8>> {
    let image = image::RgbImage::from_raw(SIZE.0, SIZE.1, pixels)
        .ok_or_else(|| anyhow!("a chart's pixels do not fill {}x{}", SIZE.0, SIZE.1))?;
    let mut bytes = Vec::new();
    image.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )?;
    Ok(bytes)
}

/// Table 1's chart as PNG bytes (`path` names it in errors).
pub fn table1(path: &Path, results: &Results) -> Result<Vec<u8>> {
    let mut buffer = blank();
    draw_table1(&mut buffer, path, results)?;
    png(buffer)
}

/// Fig. 1's chart as PNG bytes.
pub fn fig1(path: &Path, results: &Results) -> Result<Vec<u8>> {
    let mut buffer = blank();
    draw_fig1(&mut buffer, path, results)?;
    png(buffer)
}

/// Fig. 2's chart as PNG bytes.
pub fn fig2(path: &Path, results: &Results) -> Result<Vec<u8>> {
    let mut buffer = blank();
    draw_fig2(&mut buffer, path, results)?;
    png(buffer)
}

fn failed(path: &Path) -> impl Fn(&dyn std::fmt::Display) -> anyhow::Error + '_ {
    move |e| anyhow!("cannot draw {}: {e}", path.display())
}

/// Turns plotters' error into ours, naming the file.
macro_rules! draw {
    ($path:expr, $e:expr) => {
        $e.map_err(|e| failed($path)(&e))?
    };
}

/// The legend every chart shares: upper left, on a white box with a black border.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    path: &Path,
    chart: &mut ChartContext<'a, DB, CT>,
    font_size: u32,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    draw!(
        path,
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((FONT, font_size))
            .draw()
    );
    Ok(())
}

/// How Fig. 2 draws a builder, as its legend says.
fn builder_style(algorithm: &str) -> &'static str {
    match algorithm {
        "level" => "level (solid, circles)",
        "median" => "median (dashed, triangles)",
        "hybrid" => "hybrid (long dashes, rings)",
        _ => "naive (dotted, crosses)",
    }
}

fn colour(i: usize) -> RGBColor {
    const COLOURS: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
    ];
    COLOURS[i % COLOURS.len()]
}

/// Table 1 as grouped bars on a log scale: the paper's times on the left, this run's on the
/// right, the same axis on both.
fn draw_table1(buffer: &mut [u8], path: &Path, results: &Results) -> Result<()> {
    register_fonts();
    let scenes = &results.scenes;
    let paper: Vec<Vec<Option<f64>>> = scenes
        .iter()
        .map(|s| {
            COLUMNS
                .iter()
                .map(|(a, _)| s.paper.and_then(|p| p.ms(a)))
                .collect()
        })
        .collect();
    let ours: Vec<Vec<Option<f64>>> = scenes
        .iter()
        .map(|s| {
            COLUMNS
                .iter()
                .map(|(a, _)| table_ms(results, s, a))
                .collect()
        })
        .collect();
    let all = paper.iter().chain(&ours).flatten().flatten().copied();
    let (lo, hi) = all.fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)));
    let (lo, hi) = if lo <= hi {
        (lo / 2.0, hi * 2.0)
    } else {
        (1.0, 10.0)
    };
    let labels: Vec<String> = scenes
        .iter()
        .map(|s| match &s.paper {
            Some(p) => format!("{} {}", p.name, p.triangles),
            None => s.label.clone(),
        })
        .collect();

    let root = BitMapBackend::with_buffer(buffer, SIZE).into_drawing_area();
    draw!(path, root.fill(&WHITE));
    let root = draw!(
        path,
        root.titled(
            "Table 1: build time of each builder (lower is better)",
            (FONT, 30).into_font().style(FontStyle::Bold)
        )
    );
    let (left, right) = root.split_horizontally(SIZE.0 / 2);
    let s = &results.settings;
    let panels = [
        (
            left,
            "paper: GTX 750 Ti, 64 threads (Wald serial on CPU)".to_string(),
            &paper,
        ),
        (
            right,
            format!(
                "sahkd: this machine, {} threads (sweep {}), median of {}",
                s.table_threads("level"),
                s.table_threads("sweep"),
                s.repeat
            ),
            &ours,
        ),
    ];
    for (area, caption, values) in panels {
        let mut chart = draw!(
            path,
            ChartBuilder::on(&area)
                .caption(caption, (FONT, 20))
                .margin(15)
                .x_label_area_size(45)
                .y_label_area_size(80)
                .build_cartesian_2d(-0.5f64..scenes.len() as f64 - 0.5, (lo..hi).log_scale())
        );
        let names = labels.clone();
        draw!(
            path,
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_labels(2 * scenes.len() + 1)
                .x_label_formatter(&move |x| {
                    let i = x.round();
                    if (x - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < names.len() {
                        names[i as usize].clone()
                    } else {
                        String::new()
                    }
                })
                .x_desc("scene")
                .y_desc("build time (ms, log scale)")
                .label_style((FONT, 16))
                .axis_desc_style((FONT, 18))
                .draw()
        );
        let width = 0.8 / COLUMNS.len() as f64;
        for (k, (_, title)) in COLUMNS.iter().enumerate() {
            let c = colour(k);
            let bars = values.iter().enumerate().filter_map(|(i, row)| {
                row[k].map(|v| {
                    let x0 = i as f64 - 0.4 + k as f64 * width;
                    Rectangle::new([(x0, lo), (x0 + width * 0.9, v)], c.filled())
                })
            });
            draw!(path, chart.draw_series(bars))
                .label(*title)
                .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 14, y + 6)], c.filled()));
        }
        draw_legend(path, &mut chart, 16)?;
    }
    draw!(path, root.present());
    Ok(())
}

/// Fig. 1: P_n = (T_n - T_sort) / (T_1 - T_sort) for n = 1 .. 7 on the largest scene.
/// What a figure's axes say, and the room for its y labels.
struct Axes {
    x_desc: &'static str,
    y_desc: &'static str,
    y_area: u32,
}

const FIG1: Axes = Axes {
    x_desc: "levels built, n (tree depth limited to n)",
    y_desc: "P_n = median(T_n - T_sort) / median(T_1 - T_sort)",
    y_area: 90,
};

const FIG2: Axes = Axes {
    x_desc: "worker threads",
    y_desc: "speed-up (median time at base / median time at n threads)",
    y_area: 80,
};

/// A figure's chart over its whole picture: a bold caption, linear axes over the ranges
/// `x` and `y` described by `axes`, and `x_labels` whole-number ticks along x.
fn figure<'a, 'b>(
    path: &Path,
    root: &'a DrawingArea<BitMapBackend<'b>, Shift>,
    caption: String,
    axes: &Axes,
    (x, y): (Range<f64>, Range<f64>),
    x_labels: usize,
) -> Result<ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>> {
    let mut chart = draw!(
        path,
        ChartBuilder::on(root)
            .caption(caption, (FONT, 28).into_font().style(FontStyle::Bold))
            .margin(20)
            .x_label_area_size(55)
            .y_label_area_size(axes.y_area)
            .build_cartesian_2d(x, y)
    );
    draw!(
        path,
        chart
            .configure_mesh()
            .x_labels(x_labels)
            .x_label_formatter(&|x| format!("{x:.0}"))
            .x_desc(axes.x_desc)
            .y_desc(axes.y_desc)
            .label_style((FONT, 18))
            .axis_desc_style((FONT, 20))
            .draw()
    );
    Ok(chart)
}

fn draw_fig1(buffer: &mut [u8], path: &Path, results: &Results) -> Result<()> {
    register_fonts();
    let root = BitMapBackend::with_buffer(buffer, SIZE).into_drawing_area();
    draw!(path, root.fill(&WHITE));
    let scene = results.levels.first().map_or("", |c| c.scene.as_str());
    let levels = results.settings.fig1_levels as f64;
    let top = results
        .levels
        .iter()
        .flat_map(|c| c.points.iter().map(|p| p.p))
        .filter(|p| p.is_finite())
        .fold(1.0f64, f64::max)
        * 1.1;
    let caption =
        format!("Fig. 1: time to build the first n levels, {scene}, relative to one level");
    let ranges = (0.5f64..levels + 0.5, 0f64..top);
    let ticks = results.settings.fig1_levels as usize;
    let mut chart = figure(path, &root, caption, &FIG1, ranges, ticks)?;
    for curve in &results.levels {
        let c = colour(if curve.algorithm == "level" { 3 } else { 1 });
        let points: Vec<(f64, f64)> = curve
            .points
            .iter()
            .filter(|p| p.p.is_finite())
            .map(|p| (p.level as f64, p.p))
            .collect();
        draw!(
            path,
            chart.draw_series(LineSeries::new(points.clone(), c.stroke_width(3)))
        )
        .label(format!(
            "{} ({} thread{})",
            if curve.algorithm == "level" {
                "ours (level)"
            } else {
                "Wald (sweep, serial)"
            },
            curve.threads,
            if curve.threads == 1 { "" } else { "s" }
        ))
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 24, y)], c.stroke_width(3)));
        draw!(
            path,
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 5, c.filled())))
        );
    }
    draw_legend(path, &mut chart, 18)?;
    draw!(path, root.present());
    Ok(())
}

/// Fig. 2: speed-up of each parallel builder on each scene against the smallest thread count,
/// with the ideal line and the machine's core count marked.
fn draw_fig2(buffer: &mut [u8], path: &Path, results: &Results) -> Result<()> {
    register_fonts();
    let s = &results.settings;
    let base = s.threads[0];
    let max_threads = *s.threads.last().unwrap_or(&1) as f64;
    let cores = results.machine.cores as f64;
    // (scene index, builder, points): colour by scene, line and marker by builder.
    let mut series = Vec::new();
    for (i, scene) in results.scenes.iter().enumerate() {
        for &a in s.algorithms.iter().filter(|&&a| a != "sweep") {
            let points: Vec<(f64, f64)> = s
                .threads
                .iter()
                .filter_map(|&t| speedup(scene, a, base, t).map(|x| (t as f64, x)))
                .collect();
            if !points.is_empty() {
                series.push((i, scene.label.as_str(), a, points));
            }
        }
    }
    let top = series
        .iter()
        .flat_map(|(_, _, _, p)| p.iter().map(|&(_, y)| y))
        .fold(max_threads / base as f64, f64::max)
        * 1.1;

    let root = BitMapBackend::with_buffer(buffer, SIZE).into_drawing_area();
    draw!(path, root.fill(&WHITE));
    let plural = if base == 1 { "" } else { "s" };
    let caption = format!("Fig. 2: build speed-up against {base} thread{plural}");
    let ranges = (0f64..max_threads + 0.5, 0f64..top);
    let mut chart = figure(
        path,
        &root,
        caption,
        &FIG2,
        ranges,
        max_threads as usize + 1,
    )?;
    // Threads beyond the cores share them: shade that part and say so.
    if cores < max_threads + 0.5 {
        draw!(
            path,
            chart.draw_series(std::iter::once(Rectangle::new(
                [(cores, 0.0), (max_threads + 0.5, top)],
                RGBColor(230, 230, 230).filled(),
            )))
        );
        draw!(
            path,
            chart.draw_series(std::iter::once(PathElement::new(
                [(cores, 0.0), (cores, top)],
                BLACK.stroke_width(2),
            )))
        )
        .label(format!(
            "{} hardware threads on this machine: beyond, threads are oversubscribed",
            results.machine.cores
        ))
        .legend(|(x, y)| PathElement::new([(x, y), (x + 24, y)], BLACK.stroke_width(2)));
    }
    let ideal = [(base as f64, 1.0), (max_threads, max_threads / base as f64)];
    draw!(
        path,
        chart.draw_series(LineSeries::new(
            ideal,
            RGBColor(160, 160, 160).stroke_width(2)
        ))
    )
    .label("ideal (speed-up = threads / base)")
    .legend(|(x, y)| {
        PathElement::new(
            [(x, y), (x + 24, y)],
            RGBColor(160, 160, 160).stroke_width(2),
        )
    });
    for (i, scene, algorithm, points) in series {
        let c = colour(i);
        let (line, marker) = (c.stroke_width(3), c.filled());
        let label = format!("{scene}: {}", builder_style(algorithm));
        let anno = match algorithm {
            "level" => draw!(
                path,
                chart.draw_series(LineSeries::new(points.clone(), line))
            ),
            "median" => draw!(
                path,
                chart.draw_series(DashedLineSeries::new(points.clone(), 14, 8, line))
            ),
            "hybrid" => draw!(
                path,
                chart.draw_series(DashedLineSeries::new(points.clone(), 28, 6, line))
            ),
            _ => draw!(
                path,
                chart.draw_series(DashedLineSeries::new(points.clone(), 4, 6, line))
            ),
        };
        anno.label(label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 24, y)], line));
        match algorithm {
            "level" => draw!(
                path,
                chart.draw_series(points.iter().map(|&p| Circle::new(p, 6, marker)))
            ),
            "median" => draw!(
                path,
                chart.draw_series(points.iter().map(|&p| TriangleMarker::new(p, 7, marker)))
            ),
            "hybrid" => draw!(
                path,
                chart.draw_series(points.iter().map(|&p| Circle::new(p, 7, line)))
            ),
            _ => draw!(
                path,
                chart.draw_series(points.iter().map(|&p| Cross::new(p, 6, line)))
            ),
        };
    }
    draw_legend(path, &mut chart, 17)?;
    draw!(path, root.present());
    Ok(())
}
