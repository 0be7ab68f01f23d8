//! The study's plots (plotters, drawn into memory and written as PNG atomically): per scene, the
//! curves of error against CPU time with their 95 % bands and the Pareto front; over all
//! scenes, the speed-up over balance at equal error (the summary figure) and the sweeps of α's
//! clamping interval (paper Figure 2), pilot count M (Figure 7) and N with M fixed (Figures 3
//! and 4). Log axes carry round ticks (1, 2, 5 × 10^k, or powers of two for budgets), and every
//! figure has a legend.
//!
//! Why one file of over 600 lines: each plot of the study is one function over the same collected
//! statistics and drawing helpers.

use super::collect::{Extent, SceneAnalysis, SweepRow};
use super::plan::Sweep;
use anyhow::{Result, anyhow};
use lumis_core::image_io::write_rgb8_png;
use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::prelude::*;
use std::ops::Range;
use std::path::Path;

/// A linear range (of mapped values: log10 on log axes) whose key points are given ticks.
#[derive(Clone)]
struct Ticked {
    range: Range<f64>,
    ticks: Vec<f64>,
}

impl Ranged for Ticked {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let t = (value - self.range.start) / (self.range.end - self.range.start);
        let v = limit.0 as f64 + t * (limit.1 - limit.0) as f64;
        if v.is_finite() {
            v.round().clamp(-1e6, 1e6) as i32
        } else {
            limit.0
        }
    }

    fn key_points<Hint: KeyPointHint>(&self, _hint: Hint) -> Vec<f64> {
        self.ticks.clone()
    }

    fn range(&self) -> Range<f64> {
        self.range.clone()
    }
}

/// DejaVu Sans (Bitstream Vera licence, `fonts/LICENSE-DejaVu`): plots must not depend on the
/// fonts a machine happens to have.
const FONT: &[u8] = include_bytes!("fonts/DejaVuSans.ttf");

pub fn register_font() -> Result<()> {
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| anyhow!("the embedded plot font is invalid"))
}

/// Twenty distinguishable colours (Tableau 10, then their lighter or darker companions).
const COLORS: [RGBColor; 20] = [
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
    RGBColor(0, 0, 128),
    RGBColor(170, 110, 40),
    RGBColor(0, 128, 128),
    RGBColor(128, 0, 0),
    RGBColor(60, 180, 75),
    RGBColor(145, 30, 180),
    RGBColor(240, 50, 230),
    RGBColor(70, 70, 70),
    RGBColor(210, 160, 0),
    RGBColor(0, 90, 40),
];

pub fn color(i: usize) -> RGBColor {
    COLORS[i % COLORS.len()]
}

/// How an axis maps and labels its values.
#[derive(Clone, Copy, PartialEq)]
pub enum Scale {
    /// Linear, with round ticks.
    Linear,
    /// Log scale with ticks at 1, 2, 5 × 10^k.
    Log,
    /// Log scale with ticks at powers of two (budgets).
    Log2,
}

impl Scale {
    fn map(self, v: f64) -> Option<f64> {
        match self {
            Scale::Linear => v.is_finite().then_some(v),
            Scale::Log | Scale::Log2 => (v.is_finite() && v > 0.0).then(|| v.log10()),
        }
    }

    fn unmap(self, v: f64) -> f64 {
        match self {
            Scale::Linear => v,
            Scale::Log | Scale::Log2 => 10f64.powf(v),
        }
    }

    /// Round tick values (in data units) covering [lo, hi] (data units).
    pub fn ticks(self, lo: f64, hi: f64) -> Vec<f64> {
        match self {
            Scale::Linear => linear_ticks(lo, hi),
            Scale::Log => log_ticks(lo, hi),
            Scale::Log2 => {
                let (a, b) = (lo.log2().ceil() as i32, hi.log2().floor() as i32);
                let mut ticks: Vec<f64> = (a..=b).map(|e| 2f64.powi(e)).collect();
                while ticks.len() > 10 {
                    ticks = ticks.into_iter().step_by(2).collect();
                }
                if ticks.len() < 2 {
                    log_ticks(lo, hi)
                } else {
                    ticks
                }
            }
        }
    }
}

/// Ticks at 1, 2, 5 × 10^k (or only powers of ten when there are too many).
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let (a, b) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    for mantissas in [&[1.0, 2.0, 5.0][..], &[1.0][..]] {
        let ticks: Vec<f64> = (a..=b)
            .flat_map(|e| mantissas.iter().map(move |m| m * 10f64.powi(e)))
            .filter(|&t| t >= lo * (1.0 - 1e-9) && t <= hi * (1.0 + 1e-9))
            .collect();
        if ticks.len() <= 9 && ticks.len() >= 2 {
            return ticks;
        }
        if ticks.len() < 2 {
            // Less than a factor of two: ticks at 1 … 9 × 10^k.
            let fine: Vec<f64> = (a - 1..=b)
                .flat_map(|e| (1..10).map(move |m| m as f64 * 10f64.powi(e)))
                .filter(|&t| t >= lo && t <= hi)
                .collect();
            if fine.len() >= 2 {
                return fine;
            }
            return vec![lo, hi];
        }
    }
    let step = ((b - a) as f64 / 6.0).ceil().max(1.0) as usize;
    (a..=b)
        .step_by(step)
        .map(|e| 10f64.powi(e))
        .filter(|&t| t >= lo && t <= hi)
        .collect()
}

fn linear_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = hi - lo;
    if span.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return vec![lo];
    }
    let raw = span / 6.0;
    let magnitude = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * magnitude)
        .find(|s| span / s <= 7.0)
        .unwrap_or(10.0 * magnitude);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|i| i as f64 * step).collect()
}

/// A tick label: "16", "0.25", "2×10⁻³", "10⁵".
pub fn tick_label(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-2..1e4).contains(&a) {
        let s = format!("{v:.3}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        return s.to_string();
    }
    let exponent = a.log10().floor() as i32;
    let mantissa = v / 10f64.powi(exponent);
    let sup: String = exponent
        .to_string()
        .chars()
        .map(|c| match c {
            '-' => '⁻',
            d => ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'][d as usize - '0' as usize],
        })
        .collect();
    if (mantissa - 1.0).abs() < 1e-9 {
        format!("10{sup}")
    } else {
        let m = format!("{mantissa:.1}");
        format!("{}×10{sup}", m.trim_end_matches('0').trim_end_matches('.'))
    }
}

/// One series: a line through points, optionally with a shaded band or error bars.
struct Series {
    name: String,
    color: RGBColor,
    points: Vec<(f64, f64)>,
    /// (x, lo, hi) of a shaded band.
    band: Vec<(f64, f64, f64)>,
    /// (x, lo, hi) of vertical error bars.
    bars: Vec<(f64, f64, f64)>,
    /// Markers only, or a dashed line.
    line: Line,
    /// Points (data coordinates) of ratios whose interval contains 1: drawn hollow (n.s.).
    not_significant: Vec<(f64, f64)>,
}

#[derive(Clone, Copy, PartialEq)]
enum Line {
    Solid,
    Dashed,
    None,
}

impl Series {
    fn new(name: impl Into<String>, color: RGBColor, points: Vec<(f64, f64)>) -> Self {
        Series {
            name: name.into(),
            color,
            points,
            band: Vec::new(),
            bars: Vec::new(),
            not_significant: Vec::new(),
            line: Line::Solid,
        }
    }
}

struct Axes<'a> {
    title: &'a str,
    x: (&'a str, Scale),
    y: (&'a str, Scale),
    /// Dotted reference lines at these x and y values.
    x_marks: Vec<f64>,
    y_marks: Vec<f64>,
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Draws series on one area; points that cannot be shown on the axes' scales (non-finite, or
/// not positive on a log scale) are left out.
fn chart(area: &Area, axes: &Axes, series: &[Series]) -> Result<()> {
    let (xs, ys) = (axes.x.1, axes.y.1);
    let map = |(x, y): (f64, f64)| Some((xs.map(x)?, ys.map(y)?));
    // The extent of everything drawn, in mapped coordinates.
    let mut extent = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    let mut grow = |p: Option<(f64, f64)>| {
        if let Some((x, y)) = p {
            extent = (
                extent.0.min(x),
                extent.1.max(x),
                extent.2.min(y),
                extent.3.max(y),
            );
        }
    };
    for s in series {
        s.points.iter().for_each(|&p| grow(map(p)));
        for &(x, lo, hi) in s.band.iter().chain(&s.bars) {
            grow(map((x, lo)));
            grow(map((x, hi)));
        }
    }
    for &x in &axes.x_marks {
        if let Some(x) = xs.map(x) {
            extent.0 = extent.0.min(x);
            extent.1 = extent.1.max(x);
        }
    }
    for &y in &axes.y_marks {
        if let Some(y) = ys.map(y) {
            extent.2 = extent.2.min(y);
            extent.3 = extent.3.max(y);
        }
    }
    let (mut x0, mut x1, mut y0, mut y1) = extent;
    if x0 > x1 || y0 > y1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    let pad = |a: f64, b: f64| {
        let d = if b > a { 0.06 * (b - a) } else { 0.3 };
        (a - d, b + d)
    };
    let ((x0, x1), (y0, y1)) = (pad(x0, x1), pad(y0, y1));
    let key_points = |scale: Scale, lo: f64, hi: f64| -> Vec<f64> {
        scale
            .ticks(scale.unmap(lo), scale.unmap(hi))
            .into_iter()
            .filter_map(|t| scale.map(t))
            .collect()
    };
    let mut chart = ChartBuilder::on(area)
        .caption(axes.title, ("sans-serif", 17))
        .margin(10)
        .x_label_area_size(42)
        .y_label_area_size(72)
        .build_cartesian_2d(
            Ticked {
                range: x0..x1,
                ticks: key_points(xs, x0, x1),
            },
            Ticked {
                range: y0..y1,
                ticks: key_points(ys, y0, y1),
            },
        )?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .bold_line_style(RGBColor(225, 225, 225))
        .x_desc(axes.x.0)
        .y_desc(axes.y.0)
        .x_label_formatter(&|v| tick_label(xs.unmap(*v)))
        .y_label_formatter(&|v| tick_label(ys.unmap(*v)))
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .draw()?;
    let dotted = BLACK.mix(0.55).stroke_width(1);
    for &x in &axes.x_marks {
        if let Some(x) = xs.map(x) {
            chart.draw_series(DashedLineSeries::new(vec![(x, y0), (x, y1)], 3, 4, dotted))?;
        }
    }
    for &y in &axes.y_marks {
        if let Some(y) = ys.map(y) {
            chart.draw_series(DashedLineSeries::new(vec![(x0, y), (x1, y)], 3, 4, dotted))?;
        }
    }
    for s in series {
        let band: Vec<(f64, f64, f64)> = s
            .band
            .iter()
            .filter_map(|&(x, lo, hi)| Some((xs.map(x)?, ys.map(lo)?, ys.map(hi)?)))
            .collect();
        if band.len() >= 2 {
            let outline: Vec<(f64, f64)> = band
                .iter()
                .map(|&(x, lo, _)| (x, lo))
                .chain(band.iter().rev().map(|&(x, _, hi)| (x, hi)))
                .collect();
            chart.draw_series(std::iter::once(Polygon::new(outline, s.color.mix(0.15))))?;
        }
        let points: Vec<(f64, f64)> = s.points.iter().filter_map(|&p| map(p)).collect();
        let style = s.color.stroke_width(2);
        match s.line {
            Line::Solid => {
                chart.draw_series(LineSeries::new(points.clone(), style))?;
            }
            Line::Dashed => {
                chart.draw_series(DashedLineSeries::new(points.clone(), 8, 5, style))?;
            }
            Line::None => {}
        }
        if s.line != Line::Dashed {
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, s.color.filled())))?;
            let hollow: Vec<(f64, f64)> =
                s.not_significant.iter().filter_map(|&p| map(p)).collect();
            chart.draw_series(hollow.iter().map(|&p| Circle::new(p, 3, WHITE.filled())))?;
            chart.draw_series(
                hollow
                    .iter()
                    .map(|&p| Circle::new(p, 3, s.color.stroke_width(2))),
            )?;
        }
        for &(x, lo, hi) in &s.bars {
            if let (Some(x), Some(lo), Some(hi)) = (xs.map(x), ys.map(lo), ys.map(hi)) {
                chart.draw_series(std::iter::once(PathElement::new(
                    vec![(x, lo), (x, hi)],
                    s.color.stroke_width(2),
                )))?;
            }
        }
    }
    Ok(())
}

/// A legend: one line per series, its colour and line style beside its name.
fn legend(area: &Area, title: &str, series: &[Series]) -> Result<()> {
    let text = ("sans-serif", 13).into_font();
    area.draw_text(title, &("sans-serif", 14).into_font().into(), (8, 40))?;
    for (i, s) in series.iter().enumerate() {
        let y = 66 + 20 * i as i32;
        let style = s.color.stroke_width(3);
        match s.line {
            Line::Dashed => {
                for k in 0..3 {
                    area.draw(&PathElement::new(
                        vec![(8 + 9 * k, y), (14 + 9 * k, y)],
                        style,
                    ))?;
                }
            }
            _ => {
                area.draw(&PathElement::new(vec![(8, y), (32, y)], style))?;
                area.draw(&Circle::new((20, y), 3, s.color.filled()))?;
            }
        }
        area.draw_text(&s.name, &text.clone().into(), (40, y - 7))?;
    }
    Ok(())
}

/// Draws into an in-memory bitmap with `draw` and writes it as a PNG.
fn png(path: &Path, size: (u32, u32), draw: impl FnOnce(&Area) -> Result<()>) -> Result<()> {
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

/// Width of the legend column, from its longest label.
fn legend_width(series: &[Series]) -> u32 {
    let longest = series
        .iter()
        .map(|s| s.name.chars().count())
        .max()
        .unwrap_or(0);
    (60 + 8 * longest as u32).clamp(160, 420)
}

/// `plots/NAME-curves.png`: relative variance and rel. MSE against CPU time, each integrator
/// through its budgets with its 95 % band; the Pareto front, the target error and the
/// equal-time point.
pub fn scene_curves(out: &Path, s: &SceneAnalysis) -> Result<()> {
    let series =
        |error: &dyn Fn(&super::collect::CurvePoint) -> super::stats::Estimate| -> Vec<Series> {
            s.curves
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let mut series = Series::new(c.label.clone(), color(i), Vec::new());
                    for p in &c.points {
                        let e = error(p);
                        let t = p.cpu_time.value;
                        series.points.push((t, e.value));
                        series.band.push((t, e.lo, e.hi));
                    }
                    series
                })
                .collect()
        };
    let mut variance = series(&|p| p.relative_variance);
    let error = series(&|p| p.relative_mse);
    // The front: each segment along its owner's curve.
    let mut front = Series::new("Pareto front", BLACK, Vec::new());
    front.line = Line::Dashed;
    for segment in &s.front {
        let Some(curve) = s.curves.iter().find(|c| c.label == segment.label) else {
            continue;
        };
        let points: Vec<(f64, f64)> = curve
            .points
            .iter()
            .map(|p| (p.cpu_time.value, p.relative_variance.value))
            .collect();
        // Beyond its largest budget a curve's front is its lowest error (collect's rule).
        let last = points.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
        let lowest = points.iter().map(|p| p.1).min_by(f64::total_cmp);
        // The segment's ends and its owner's measured points between them.
        let inside = points
            .iter()
            .map(|p| p.0)
            .filter(|&t| segment.from < t && t < segment.to);
        let times: Vec<f64> = std::iter::once(segment.from)
            .chain(inside)
            .chain(std::iter::once(segment.to))
            .collect();
        for t in times {
            let beyond = if t > last { lowest } else { None };
            if let Some(e) = interpolate_log(&points, t).or(beyond) {
                front.points.push((t, e));
            }
        }
    }
    variance.push(front);
    let legend_series: Vec<Series> = variance
        .iter()
        .map(|v| {
            let mut l = Series::new(v.name.clone(), v.color, Vec::new());
            l.line = v.line;
            l
        })
        .collect();
    let legend_w = legend_width(&legend_series);
    let size = (2 * 620 + legend_w, 540);
    let title_v = format!("{}: relative variance against CPU time", s.name);
    let title_e = format!("{}: rel. MSE against CPU time", s.name);
    png(
        &out.join("plots").join(format!("{}-curves.png", s.name)),
        size,
        |root| {
            let (charts, key) = root.split_horizontally(2 * 620);
            let halves = charts.split_evenly((1, 2));
            chart(
                &halves[0],
                &Axes {
                    title: &title_v,
                    x: ("CPU time per run (s)", Scale::Log),
                    y: ("relative variance", Scale::Log),
                    x_marks: vec![s.target_time],
                    y_marks: vec![s.target_error],
                },
                &variance,
            )?;
            chart(
                &halves[1],
                &Axes {
                    title: &title_e,
                    x: ("CPU time per run (s)", Scale::Log),
                    y: ("rel. MSE", Scale::Log),
                    x_marks: vec![s.target_time],
                    y_marks: Vec::new(),
                },
                &error,
            )?;
            legend(&key, "integrators (N = budgets)", &legend_series)
        },
    )
}

/// y of a log-log polyline at x (within its range).
fn interpolate_log(points: &[(f64, f64)], x: f64) -> Option<f64> {
    let lx = x.ln();
    points.windows(2).find_map(|w| {
        let ((x0, y0), (x1, y1)) = ((w[0].0.ln(), w[0].1.ln()), (w[1].0.ln(), w[1].1.ln()));
        let (a, b) = (x0.min(x1), x0.max(x1));
        (a <= lx && lx <= b).then(|| {
            if x1 == x0 {
                y0.min(y1).exp()
            } else {
                (y0 + (lx - x0) * (y1 - y0) / (x1 - x0)).exp()
            }
        })
    })
}

/// `plots/summary.png`: every integrator's speed-up over balance at equal error, per scene,
/// with its 95 % interval (hollow: extrapolated beyond the ladder).
pub fn summary(out: &Path, scenes: &[SceneAnalysis], labels: &[String]) -> Result<()> {
    if scenes.is_empty() {
        return Ok(());
    }
    let n = scenes.len();
    let rows = labels.len().max(1) as f64;
    let mut series: Vec<Series> = labels
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let mut s = Series::new(l.clone(), color(i), Vec::new());
            s.line = Line::None;
            s
        })
        .collect();
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for (row, scene) in scenes.iter().enumerate() {
        for t in &scene.trade {
            let Some(i) = labels.iter().position(|l| *l == t.label) else {
                continue;
            };
            let Some(r) = t.speedup else { continue };
            if matches!(r.extent, Extent::Beyond { .. })
                || r.estimate.value.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
            {
                continue;
            }
            // Each integrator a little below the last within the scene's row.
            let y = (n - 1 - row) as f64 + 0.8 * (0.5 - (i as f64 + 0.5) / rows);
            series[i].points.push((r.estimate.value, y));
            // Balance against itself is 1 by definition, not a finding.
            if r.estimate.not_significant() && i != scene.balance {
                series[i].not_significant.push((r.estimate.value, y));
            }
            if r.estimate.lo.is_finite() && r.estimate.hi.is_finite() {
                series[i].band.push((y, r.estimate.lo, r.estimate.hi));
                lo = lo.min(r.estimate.lo);
                hi = hi.max(r.estimate.hi);
            }
            lo = lo.min(r.estimate.value);
            hi = hi.max(r.estimate.value);
        }
    }
    if lo > hi {
        return Ok(());
    }
    let (lo, hi) = ((lo.min(1.0) / 1.15).log10(), (hi.max(1.0) * 1.15).log10());
    let legend_w = legend_width(&series);
    let height = (120 + 46 * n as u32).max(360);
    let names: Vec<String> = scenes.iter().map(|s| s.name.clone()).collect();
    png(
        &out.join("plots/summary.png"),
        (760 + legend_w, height),
        |root| {
            let (area, key) = root.split_horizontally(760);
            let ticks: Vec<f64> = log_ticks(10f64.powf(lo), 10f64.powf(hi))
                .into_iter()
                .map(f64::log10)
                .collect();
            let rows: Vec<f64> = (0..n).map(|i| i as f64).collect();
            let mut chart = ChartBuilder::on(&area)
                .caption(
                    "Speed-up over balance at equal error (95 % intervals; hollow: n.s.)",
                    ("sans-serif", 17),
                )
                .margin(10)
                .x_label_area_size(42)
                .y_label_area_size(64)
                .build_cartesian_2d(
                    Ticked {
                        range: lo..hi,
                        ticks,
                    },
                    Ticked {
                        range: -0.6..n as f64 - 0.4,
                        ticks: rows,
                    },
                )?;
            chart
                .configure_mesh()
                .light_line_style(WHITE)
                .bold_line_style(RGBColor(225, 225, 225))
                .x_desc("speed-up (balance's CPU time to the target error / the integrator's)")
                .y_desc("scene")
                .x_label_formatter(&|v| tick_label(10f64.powf(*v)))
                .y_label_formatter(&|v| {
                    let i = v.round() as i64;
                    if (v - i as f64).abs() < 1e-6 && i >= 0 && (i as usize) < names.len() {
                        names[names.len() - 1 - i as usize].clone()
                    } else {
                        String::new()
                    }
                })
                .label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 14))
                .draw()?;
            chart.draw_series(DashedLineSeries::new(
                vec![(0.0, -0.6), (0.0, n as f64 - 0.4)],
                3,
                4,
                BLACK.mix(0.6).stroke_width(1),
            ))?;
            for s in &series {
                for &(y, a, b) in &s.band {
                    chart.draw_series(std::iter::once(PathElement::new(
                        vec![(a.log10(), y), (b.log10(), y)],
                        s.color.stroke_width(2),
                    )))?;
                }
                chart.draw_series(
                    s.points
                        .iter()
                        .map(|&(x, y)| Circle::new((x.log10(), y), 4, s.color.filled())),
                )?;
                // A speed-up whose interval contains 1: hollow, and marked.
                for &(x, y) in &s.not_significant {
                    chart.draw_series([
                        Circle::new((x.log10(), y), 4, WHITE.filled()),
                        Circle::new((x.log10(), y), 4, s.color.stroke_width(2)),
                    ])?;
                }
            }
            legend(&key, "integrators", &series)
        },
    )
}

/// The sweep plots over all scenes: `plots/clamp.png`, `plots/m.png`, `plots/convergence.png`.
pub fn sweeps(out: &Path, scenes: &[SceneAnalysis]) -> Result<()> {
    let of = |s: &SceneAnalysis, sweep: Sweep| -> Vec<SweepRow> {
        s.sweeps
            .iter()
            .filter(|p| p.sweep == sweep)
            .cloned()
            .collect()
    };
    let series = |sweep: Sweep,
                  value: &dyn Fn(&SweepRow) -> Option<super::stats::Estimate>|
     -> Vec<Series> {
        scenes
            .iter()
            .enumerate()
            .filter(|(_, s)| s.sweeps.iter().any(|p| p.sweep == sweep))
            .map(|(i, s)| {
                let mut series = Series::new(s.name.clone(), color(i), Vec::new());
                for p in of(s, sweep) {
                    if let Some(e) = value(&p) {
                        series.points.push((p.x, e.value));
                        if e.not_significant() {
                            series.not_significant.push((p.x, e.value));
                        }
                        series.bars.push((p.x, e.lo, e.hi));
                    }
                }
                series
            })
            .collect()
    };
    let relative = |p: &SweepRow| Some(p.row.ratios.relative_variance);
    for (sweep, file, title, x) in [
        (
            Sweep::Clamp,
            "clamp.png",
            "Clamping α to [½ − s/2, ½ + s/2] (paper Figure 2)",
            ("interval size s (0: balance heuristic)", Scale::Linear),
        ),
        (
            Sweep::AlphaSamples,
            "m.png",
            "Pilot samples M that estimate α, N fixed (paper Figure 7)",
            ("M", Scale::Log2),
        ),
    ] {
        let s = series(sweep, &relative);
        if s.is_empty() {
            continue;
        }
        let w = legend_width(&s);
        png(&out.join("plots").join(file), (800 + w, 520), |root| {
            let (area, key) = root.split_horizontally(800);
            chart(
                &area,
                &Axes {
                    title,
                    x,
                    y: ("relative variance / balance's (hollow: n.s.)", Scale::Log),
                    x_marks: Vec::new(),
                    y_marks: vec![1.0],
                },
                &s,
            )?;
            legend(&key, "scenes", &s)
        })?;
    }
    let l1 = series(Sweep::Convergence, &|p| {
        p.row.ratios.sampling_variance_estimate
    });
    let ln = series(Sweep::Convergence, &relative);
    if !ln.is_empty() {
        let w = legend_width(&ln);
        png(
            &out.join("plots/convergence.png"),
            (2 * 620 + w, 520),
            |root| {
                let (charts, key) = root.split_horizontally(2 * 620);
                let halves = charts.split_evenly((1, 2));
                chart(
                    &halves[0],
                    &Axes {
                        title: "V[L₁] (estimate basis), M fixed (paper Figure 3)",
                        x: ("N", Scale::Log2),
                        y: ("V[L₁] / balance's (hollow: n.s.)", Scale::Log),
                        x_marks: Vec::new(),
                        y_marks: vec![1.0],
                    },
                    &l1,
                )?;
                chart(
                    &halves[1],
                    &Axes {
                        title: "Relative variance, M fixed (paper Figure 4)",
                        x: ("N", Scale::Log2),
                        y: ("relative variance / balance's (hollow: n.s.)", Scale::Log),
                        x_marks: Vec::new(),
                        y_marks: vec![1.0],
                    },
                    &ln,
                )?;
                legend(&key, "scenes", &ln)
            },
        )?;
    }
    Ok(())
}
