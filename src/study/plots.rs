//! The study's plots (plotters, drawn into memory and written as PNG atomically): per scene,
//! variance and error against time; over all scenes, the clamping sweep (paper Figure 2), the
//! M sweep (Figure 7) and convergence in N for a fixed M (Figures 3 and 4).

use super::SceneResults;
use super::report::{Row, SweepPoint, sig};
use anyhow::{Result, anyhow};
use lumis_core::image_io::write_rgb8_png;
use lumis_integrators::{alpha, balance};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// DejaVu Sans (Bitstream Vera licence, `fonts/LICENSE-DejaVu`): plots must not depend on the
/// fonts a machine happens to have.
const FONT: &[u8] = include_bytes!("fonts/DejaVuSans.ttf");

pub fn register_font() -> Result<()> {
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| anyhow!("the embedded plot font is invalid"))
}

#[derive(Clone, Copy, PartialEq)]
enum Scale {
    Linear,
    Log,
}

impl Scale {
    fn map(self, v: f64) -> Option<f64> {
        match self {
            Scale::Linear => v.is_finite().then_some(v),
            Scale::Log => (v.is_finite() && v > 0.0).then(|| v.log10()),
        }
    }

    fn label(self, v: f64) -> String {
        match self {
            Scale::Linear => sig(v),
            Scale::Log => format!("{:.2}", 10f64.powf(v))
                .trim_end_matches('0')
                .trim_end_matches('.')
                .to_string(),
        }
    }
}

struct Series {
    name: String,
    points: Vec<(f64, f64)>,
}

struct Axes<'a> {
    title: &'a str,
    x: (&'a str, Scale),
    y: (&'a str, Scale),
}

const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Draws line-and-marker series on one area; series and points that cannot be shown on the
/// axes' scales (non-finite, or not positive on a log scale) are left out.
fn chart(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    axes: &Axes,
    series: &[Series],
) -> Result<()> {
    // Each series with its colour index, in the axes' (log or linear) coordinates.
    let mapped: Vec<(usize, Series)> = series
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let points: Vec<(f64, f64)> = s
                .points
                .iter()
                .filter_map(|&(x, y)| Some((axes.x.1.map(x)?, axes.y.1.map(y)?)))
                .collect();
            let name = s.name.clone();
            (i, Series { name, points })
        })
        .filter(|(_, s)| !s.points.is_empty())
        .collect();
    let all = mapped.iter().flat_map(|(_, s)| s.points.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in all {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    let pad = |a: f64, b: f64| {
        let d = if b > a { 0.05 * (b - a) } else { 0.5 };
        (a - d, b + d)
    };
    let ((x0, x1), (y0, y1)) = (pad(x0, x1), pad(y0, y1));
    let mut chart = ChartBuilder::on(area)
        .caption(axes.title, ("sans-serif", 18))
        .margin(8)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    let (xs, ys) = (axes.x.1, axes.y.1);
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_labels(7)
        .y_labels(7)
        .x_desc(axes.x.0)
        .y_desc(axes.y.0)
        .x_label_formatter(&|v| xs.label(*v))
        .y_label_formatter(&|v| ys.label(*v))
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 14))
        .draw()?;
    for (i, Series { name, points }) in mapped {
        let color = COLORS[i % COLORS.len()];
        chart
            .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?
            .label(name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2))
            });
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 12))
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}

/// Draws into an in-memory bitmap with `draw` and writes it as a PNG.
fn png(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
) -> Result<()> {
    let mut buffer = vec![0u8; (size.0 * size.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, size).into_drawing_area();
        root.fill(&WHITE)?;
        draw(&root)?;
        root.present()?;
    }
    write_rgb8_png(path, size.0, size.1, buffer)?;
    Ok(())
}

/// One chart in a PNG of its own, if there is anything to draw.
fn one_chart(path: &Path, axes: &Axes, series: &[Series]) -> Result<()> {
    if series.is_empty() {
        return Ok(());
    }
    png(path, (800, 520), |root| chart(root, axes, series))
}

/// `plots/NAME-time.png`: V[L_N] and relative MSE against time, each integrator a line through
/// its equal-samples and equal-time points.
pub fn scene_plots(out: &Path, results: &SceneResults) -> Result<()> {
    let mut labels: Vec<&str> = Vec::new();
    for row in &results.rows {
        if !labels.contains(&row.integrator.as_str()) {
            labels.push(&row.integrator);
        }
    }
    let series = |value: fn(&Row) -> f64| -> Vec<Series> {
        labels
            .iter()
            .map(|label| {
                let mut points: Vec<(f64, f64)> = results
                    .rows
                    .iter()
                    .filter(|r| r.integrator == *label)
                    .map(|r| (r.cpu_time, value(r)))
                    .collect();
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                points.dedup();
                Series {
                    name: label.to_string(),
                    points,
                }
            })
            .collect()
    };
    let variance = series(|r| r.estimator_variance);
    let error = series(|r| r.rel_mse);
    let title_v = format!("{}: V[L_N] against CPU time", results.name);
    let title_e = format!("{}: relative MSE against CPU time", results.name);
    png(
        &out.join("plots").join(format!("{}-time.png", results.name)),
        (1200, 480),
        |root| {
            let halves = root.split_evenly((1, 2));
            let log = Scale::Log;
            chart(
                &halves[0],
                &Axes {
                    title: &title_v,
                    x: ("CPU time (s)", log),
                    y: ("V[L_N]", log),
                },
                &variance,
            )?;
            chart(
                &halves[1],
                &Axes {
                    title: &title_e,
                    x: ("CPU time (s)", log),
                    y: ("relative MSE", log),
                },
                &error,
            )
        },
    )
}

fn points(
    scene: &SceneResults,
    sweep: &str,
    integrator: &str,
    value: fn(&SweepPoint) -> f64,
) -> Vec<(f64, f64)> {
    scene
        .sweeps
        .iter()
        .filter(|p| p.sweep == sweep && p.integrator == integrator)
        .map(|p| (p.x, value(p)))
        .collect()
}

/// Divides every y by the smallest (positive) one.
fn relative_to_best(points: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    let best = points
        .iter()
        .map(|p| p.1)
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold(f64::INFINITY, f64::min);
    points.into_iter().map(|(x, y)| (x, y / best)).collect()
}

/// The plots over all scenes studied so far: `plots/clamp.png`, `plots/m.png`,
/// `plots/convergence-l1.png` and `plots/convergence-ln.png` (only those with data).
pub fn study_plots(out: &Path, scenes: &[SceneResults]) -> Result<()> {
    let plots = out.join("plots");
    let per_scene = |sweep: &str, f: &dyn Fn(&SceneResults) -> Vec<(f64, f64)>| -> Vec<Series> {
        scenes
            .iter()
            .filter(|s| s.sweeps.iter().any(|p| p.sweep == sweep))
            .map(|s| Series {
                name: s.name.clone(),
                points: f(s),
            })
            .collect()
    };
    let clamp = per_scene("clamp", &|s| {
        relative_to_best(points(s, "clamp", alpha::NAME, |p| p.estimator_variance))
    });
    one_chart(
        &plots.join("clamp.png"),
        &Axes {
            title: "Clamping α to [½ − s/2, ½ + s/2] (Figure 2)",
            x: ("interval size s (0: balance heuristic)", Scale::Linear),
            y: ("V[L_N] / best", Scale::Log),
        },
        &clamp,
    )?;
    let m = per_scene("m", &|s| {
        relative_to_best(points(s, "m", alpha::NAME, |p| p.estimator_variance))
    });
    one_chart(
        &plots.join("m.png"),
        &Axes {
            title: "Samples M that estimate α, N fixed (Figure 7)",
            x: ("M", Scale::Log),
            y: ("V[L_N] / best", Scale::Log),
        },
        &m,
    )?;
    // Figure 3: V[L₁] of integrated α (M fixed) over that of the preprocessed α of the table.
    let l1 = per_scene("n", &|s| {
        let preprocessed = s
            .rows
            .iter()
            .find(|r| {
                r.kind == alpha::NAME
                    && r.mode == alpha::PREPROCESSED
                    && r.budget == "equal samples"
            })
            .map_or(f64::NAN, |r| r.sampling_variance);
        points(s, "n", alpha::NAME, |p| p.sampling_variance)
            .into_iter()
            .map(|(x, y)| (x, y / preprocessed))
            .collect()
    });
    if l1.iter().any(|s| s.points.iter().any(|p| p.1.is_finite())) {
        one_chart(
            &plots.join("convergence-l1.png"),
            &Axes {
                title: "V[L₁] of integrated α with M fixed, over preprocessed α's (Figure 3)",
                x: ("N", Scale::Log),
                y: ("V[L₁] / V[L₁] preprocessed", Scale::Linear),
            },
            &l1,
        )?;
    }
    // Figure 4: V[L_N] of α and balance over α's at N = M, one small chart per scene.
    let with_n: Vec<&SceneResults> = scenes
        .iter()
        .filter(|s| s.sweeps.iter().any(|p| p.sweep == "n"))
        .collect();
    if !with_n.is_empty() {
        let cols = with_n.len().min(4);
        let rows = with_n.len().div_ceil(cols);
        png(
            &plots.join("convergence-ln.png"),
            (360 * cols as u32, 300 * rows as u32),
            |root| {
                let cells = root.split_evenly((rows, cols));
                for (scene, cell) in with_n.iter().zip(&cells) {
                    let alpha = points(scene, "n", alpha::NAME, |p| p.estimator_variance);
                    let first = alpha.first().map_or(f64::NAN, |p| p.1);
                    let norm =
                        |v: Vec<(f64, f64)>| v.into_iter().map(|(x, y)| (x, y / first)).collect();
                    let series = [
                        Series {
                            name: "α (integrated)".into(),
                            points: norm(alpha.clone()),
                        },
                        Series {
                            name: "balance".into(),
                            points: norm(points(scene, "n", balance::NAME, |p| {
                                p.estimator_variance
                            })),
                        },
                    ];
                    let title = format!("{} (Figure 4)", scene.name);
                    chart(
                        cell,
                        &Axes {
                            title: &title,
                            x: ("N", Scale::Log),
                            y: ("V[L_N] / α's at N = M", Scale::Log),
                        },
                        &series,
                    )?;
                }
                Ok(())
            },
        )?;
    }
    Ok(())
}
