//! The study's tables: `results.csv` (one line per measured configuration, every statistic
//! and ratio with its 95 % interval), `trade.csv` (per scene and integrator: time to the target
//! error, speed-up over balance, error ratio at equal time) and `results.md`. All are rewritten
//! atomically after every finished scene.
//!
//! Why one file of over 600 lines: every table of the study (results.csv, trade.csv, results.md)
//! formats the same collected statistics with the same interval conventions.

use super::collect::{Extent, Reading, Row, SceneAnalysis, Trade};
use super::config::StudyConfig;
use super::plan::Sweep;
use super::stats::Estimate;
use anyhow::Result;
use lumis_core::image_io::write_atomically;
use std::fmt::Write as _;
use std::path::Path;

/// A number with four significant digits, in plain or scientific notation as fits.
pub fn sig(v: f64) -> String {
    if !v.is_finite() {
        return "–".into();
    }
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) {
        format!("{v:.3e}")
    } else if a >= 100.0 {
        format!("{v:.1}")
    } else if a >= 1.0 {
        format!("{v:.3}")
    } else {
        format!("{v:.4}")
    }
}

/// A number with three significant digits (for intervals).
pub fn short(v: f64) -> String {
    if !v.is_finite() {
        return "–".into();
    }
    let a = v.abs();
    if a != 0.0 && !(1e-2..1e4).contains(&a) {
        format!("{v:.2e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        format!("{v:.1}")
    } else if a >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

/// A value and its interval: `1.23e-3 [1.10e-3, 1.37e-3]`.
fn value(e: &Estimate) -> String {
    if e.lo.is_finite() && e.hi.is_finite() {
        format!("{} [{}, {}]", short(e.value), short(e.lo), short(e.hi))
    } else {
        short(e.value)
    }
}

/// A ratio and its interval, marked "n.s." when the interval contains 1.
pub fn ratio(e: &Estimate) -> String {
    let mark = if e.not_significant() { " n.s." } else { "" };
    format!("{}{mark}", value(e))
}

fn optional(e: &Option<Estimate>, f: fn(&Estimate) -> String) -> String {
    e.as_ref().map_or_else(|| "–".into(), f)
}

fn paper(v: Option<f64>) -> String {
    v.filter(|v| v.is_finite())
        .map_or_else(|| "–".into(), |v| format!("{v:.2}"))
}

/// A reading off a curve, with its extent: extrapolated values are marked "ext.", and beyond
/// twice the ladder's times only the bound is given.
fn reading(r: &Option<Reading>, bound: impl Fn(bool) -> String) -> String {
    match r {
        None => "–".into(),
        Some(Reading {
            extent: Extent::Beyond { above },
            ..
        }) => bound(*above),
        Some(Reading {
            estimate,
            extent: Extent::Extrapolated,
        }) => format!("{} ext.", ratio(estimate)),
        Some(Reading { estimate, .. }) => ratio(estimate),
    }
}

/// Whether an integrator beats balance at equal time: from the interval of its error ratio.
fn verdict(r: &Option<Reading>) -> &'static str {
    match r {
        Some(Reading {
            estimate,
            extent: Extent::Within | Extent::Extrapolated,
        }) => {
            if estimate.hi < 1.0 {
                "yes"
            } else if estimate.lo > 1.0 {
                "no, worse"
            } else {
                "not significant"
            }
        }
        _ => "–",
    }
}

fn estimate_columns(name: &str) -> [String; 3] {
    [name.to_string(), format!("{name}_lo"), format!("{name}_hi")]
}

/// One field of a table: what `results.csv` and `trade.csv` print, and what the Python package
/// returns as a value (`lumis.study`), so that the two cannot disagree.
#[derive(Clone, Debug, PartialEq)]
pub enum Field {
    Text(String),
    Count(u64),
    /// Printed in scientific notation, shortest round-trip digits.
    Number(f64),
    /// Printed with this many decimals.
    Fixed(f64, usize),
    /// Printed as the shortest decimal that reads back to it (a sweep's x).
    Decimal(f64),
    /// No value (an empty CSV field).
    Missing,
}

impl std::fmt::Display for Field {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Field::Text(s) => f.write_str(s),
            Field::Count(n) => write!(f, "{n}"),
            Field::Number(v) => write!(f, "{v:e}"),
            Field::Fixed(v, decimals) => write!(f, "{v:.decimals$}"),
            Field::Decimal(v) => write!(f, "{v}"),
            Field::Missing => Ok(()),
        }
    }
}

/// A table with named columns; every record has one field per column.
#[derive(Clone, Debug)]
pub struct Table {
    pub columns: Vec<String>,
    pub records: Vec<Vec<Field>>,
}

fn estimate_fields(e: Option<&Estimate>) -> [Field; 3] {
    e.map_or_else(
        || [Field::Missing, Field::Missing, Field::Missing],
        |e| [e.value, e.lo, e.hi].map(Field::Number),
    )
}

fn write_csv(path: &Path, table: &Table) -> Result<()> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(&table.columns)?;
    for record in &table.records {
        writer.write_record(record.iter().map(Field::to_string))?;
    }
    let bytes = writer.into_inner()?;
    write_atomically(path, |file| {
        std::io::Write::write_all(file, &bytes).map_err(|e| e.to_string())
    })?;
    Ok(())
}

/// The columns of a row in `results.csv`: its statistics, then its ratios to balance.
fn row_columns() -> Vec<String> {
    let mut header: Vec<String> = [
        "scene",
        "group",
        "x",
        "integrator",
        "kind",
        "samples",
        "runs",
        "width",
        "height",
        "wall_time",
        "z",
        "relative_variance_top_share",
        "variance_top_share",
    ]
    .map(String::from)
    .to_vec();
    for name in [
        "cpu_time",
        "relative_variance",
        "variance",
        "relative_mse",
        "delta_e",
        "sampling_variance",
        "sampling_variance_estimate",
        "sampling_variance_median",
        "bsdf_fraction",
        "alpha_median",
        "efficiency",
        "ratio_relative_variance",
        "ratio_median_variance",
        "ratio_variance",
        "ratio_relative_mse",
        "ratio_delta_e",
        "ratio_sampling_variance",
        "ratio_sampling_variance_estimate",
        "ratio_cpu_time",
        "ratio_efficiency",
        "ratio_paper_efficiency",
    ] {
        header.extend(estimate_columns(name));
    }
    header
}

fn row_record(s: &SceneAnalysis, group: &str, x: f64, r: &Row) -> Vec<Field> {
    let mut record = vec![
        Field::Text(s.name.clone()),
        Field::Text(group.to_string()),
        if x.is_finite() {
            Field::Decimal(x)
        } else {
            Field::Missing
        },
        Field::Text(r.label.clone()),
        Field::Text(r.kind.clone()),
        Field::Count(r.samples.into()),
        Field::Count(r.runs as u64),
        Field::Count(s.width.into()),
        Field::Count(s.height.into()),
        Field::Number(r.wall_time),
        Field::Fixed(r.z, 3),
        Field::Fixed(r.relative_variance_top, 4),
        Field::Fixed(r.variance_top, 4),
    ];
    let q = &r.ratios;
    for e in [
        Some(&r.cpu_time),
        Some(&r.relative_variance),
        Some(&r.variance),
        Some(&r.relative_mse),
        Some(&r.delta_e),
        r.sampling_variance.as_ref(),
        r.sampling_variance_estimate.as_ref(),
        r.sampling_variance_median.as_ref(),
        r.bsdf_fraction.as_ref(),
        r.alpha_median.as_ref(),
        Some(&r.efficiency),
        Some(&q.relative_variance),
        Some(&q.median_variance),
        Some(&q.variance),
        Some(&q.relative_mse),
        Some(&q.delta_e),
        q.sampling_variance.as_ref(),
        q.sampling_variance_estimate.as_ref(),
        Some(&q.cpu_time),
        Some(&q.efficiency),
        q.paper_efficiency.as_ref(),
    ] {
        record.extend(estimate_fields(e));
    }
    record
}

/// `results.csv`: one record per measured configuration (the curves' budgets, the paper's rows,
/// the sweeps' points).
pub fn results_table(scenes: &[SceneAnalysis]) -> Table {
    let mut records = Vec::new();
    for s in scenes {
        for r in s.rows.iter().flatten() {
            records.push(row_record(s, "curve", f64::NAN, r));
        }
        for p in &s.paper {
            records.push(row_record(s, "paper", f64::NAN, &p.row));
        }
        for p in &s.sweeps {
            let group = format!("sweep {}", p.sweep.name());
            records.push(row_record(s, &group, p.x, &p.row));
        }
    }
    Table {
        columns: row_columns(),
        records,
    }
}

/// `trade.csv`: per scene and integrator, what its curve says about the trade.
pub fn trade_table(scenes: &[SceneAnalysis]) -> Table {
    let mut columns: Vec<String> = [
        "scene",
        "integrator",
        "runs",
        "target_budget",
        "target_error",
        "target_time",
    ]
    .map(String::from)
    .to_vec();
    for name in [
        "time_to_target",
        "speedup",
        "equal_time_ratio",
        "speedup_over_headline",
    ] {
        columns.extend(estimate_columns(name));
        columns.push(format!("{name}_extent"));
    }
    let mut records = Vec::new();
    for s in scenes {
        for t in &s.trade {
            let mut record = vec![
                Field::Text(s.name.clone()),
                Field::Text(t.label.clone()),
                Field::Count(s.runs as u64),
                Field::Count(s.target_budget.into()),
                Field::Number(s.target_error),
                Field::Number(s.target_time),
            ];
            for r in [
                &t.time_to_target,
                &t.speedup,
                &t.equal_time_ratio,
                &t.speedup_over_headline,
            ] {
                record.extend(estimate_fields(r.as_ref().map(|r| &r.estimate)));
                record.push(match r.map(|r| r.extent) {
                    None => Field::Missing,
                    Some(Extent::Within) => Field::Text("within".into()),
                    Some(Extent::Extrapolated) => Field::Text("extrapolated".into()),
                    Some(Extent::Beyond { above: true }) => Field::Text("above".into()),
                    Some(Extent::Beyond { above: false }) => Field::Text("below".into()),
                });
            }
            records.push(record);
        }
    }
    Table { columns, records }
}

/// `results.csv` and `trade.csv`.
pub fn write_csvs(out: &Path, scenes: &[SceneAnalysis]) -> Result<()> {
    write_csv(&out.join("results.csv"), &results_table(scenes))?;
    write_csv(&out.join("trade.csv"), &trade_table(scenes))
}

/// The prefix that makes a path inside the output directory relative to the report's directory.
fn link_prefix(config: &StudyConfig) -> String {
    let report = config.report_path();
    let report_dir = report.parent().unwrap_or(Path::new(""));
    match config.out.strip_prefix(report_dir) {
        Ok(rel) if rel.as_os_str().is_empty() => String::new(),
        Ok(rel) => format!("{}/", rel.display()),
        Err(_) => match std::path::absolute(&config.out) {
            Ok(abs) => format!("{}/", abs.display()),
            Err(_) => format!("{}/", config.out.display()),
        },
    }
}

fn table_head(md: &mut String, columns: &[&str]) -> Result<()> {
    writeln!(md, "| {} |", columns.join(" | "))?;
    writeln!(md, "|{}", "---|".repeat(columns.len()))?;
    Ok(())
}

fn table_row(md: &mut String, cells: &[String]) -> Result<()> {
    writeln!(md, "| {} |", cells.join(" | "))?;
    Ok(())
}

fn figure(
    md: &mut String,
    config: &StudyConfig,
    prefix: &str,
    file: &str,
    caption: &str,
) -> Result<()> {
    if config.out.join(file).exists() {
        writeln!(md, "![{caption}]({prefix}{file})\n\n*{caption}.*\n")?;
    }
    Ok(())
}

pub fn write_markdown(config: &StudyConfig, scenes: &[SceneAnalysis]) -> Result<()> {
    let mut md = String::new();
    let prefix = link_prefix(config);
    writeln!(md, "# lumis study\n")?;
    if let Some(command) = &config.command {
        writeln!(md, "Made by `{command}`.\n")?;
    }
    let scene_list: Vec<String> = config
        .scenes
        .iter()
        .map(|p| format!("`{}`", p.display()))
        .collect();
    let integrators: Vec<String> = config
        .integrators
        .iter()
        .map(|c| format!("`{}`", c.label))
        .collect();
    let budgets: Vec<String> = config.budgets.iter().map(u32::to_string).collect();
    let (unit, headline) = if config.is_path_study() {
        (
            "camera samples per pixel (each row's `samples` per light at the first vertex)",
            "the first integrated α's, or else the first row's, relative variance over \
             `path:weighting=balance`'s at the target budget",
        )
    } else {
        (
            "samples per light per camera sample",
            "the first integrated α's relative variance over balance's at the target budget",
        )
    };
    writeln!(
        md,
        "Scenes {}; integrators {}; budgets N = {} {unit}; \
         K₀ = {} runs (seeds {} + 1, 2, …), doubled up to {} until the headline ratio \
         ({headline}) is within ±{} %; \
         the paper's rows and the sweeps keep K₀{}.\n",
        scene_list.join(", "),
        integrators.join(", "),
        budgets.join(", "),
        config.runs,
        config.seed,
        config.max_runs,
        config.precision * 100.0,
        if config.overrides.is_empty() {
            String::new()
        } else {
            format!("; overrides `{}`", config.overrides.join(" "))
        }
    )?;
    writeln!(
        md,
        "Errors are relative to the reference per pixel: *relative variance* is the mean over \
         pixels of V_p / (ref_p² + ε), V_p the variance of pixel p across the K runs, with \
         ε = ({} × the reference's mean luminance)²; *rel. MSE* the mean of ((Y − ref)² − the \
         reference's own variance) / (ref² + ε); ΔE*ab the paper's Lab error. Every interval is \
         95 %, from a jackknife over runs stratified by {}×{}-pixel blocks (runs pair across \
         integrators: the same seeds); a ratio marked *n.s.* has an interval containing 1. \
         `docs/study.md` defines every quantity.\n",
        config.epsilon, config.block, config.block
    )?;
    summary(&mut md, config, scenes, &prefix)?;
    if let Some(notes) = &config.notes {
        let text = std::fs::read_to_string(notes)?;
        writeln!(md, "{}\n", text.trim_end())?;
    }
    sweeps(&mut md, config, scenes, &prefix)?;
    for s in scenes {
        scene_section(&mut md, config, s, &prefix)?;
    }
    let bytes = md.into_bytes();
    write_atomically(&config.report_path(), |file| {
        std::io::Write::write_all(file, &bytes).map_err(|e| e.to_string())
    })?;
    Ok(())
}

fn summary(
    md: &mut String,
    config: &StudyConfig,
    scenes: &[SceneAnalysis],
    prefix: &str,
) -> Result<()> {
    writeln!(md, "## Summary: the trade against the balance heuristic\n")?;
    writeln!(
        md,
        "Per scene, the *target error* is balance's relative variance at the target budget and \
         the *equal-time point* balance's CPU time there. *Speed-up*: balance's CPU time to reach \
         the target error over the integrator's (> 1: faster), read off the curves by \
         interpolating log time against log error between budgets; *error at equal time*: the \
         integrator's relative variance at the equal-time point over balance's (< 1: better). \
         \"ext.\" marks values extrapolated beyond the ladder (by up to a factor 2 in time); \
         beyond that only a bound is given.\n"
    )?;
    let headline = config.headline().map(|c| c.label.clone());
    if let Some(h) = &headline {
        table_head(
            md,
            &[
                "scene",
                "K",
                &format!("`{h}` / balance rel. variance at the target budget"),
                "speed-up at equal error",
                "error ratio at equal time",
                "beats balance at equal time (95 %)?",
            ],
        )?;
        for s in scenes {
            let Some(t) = s.trade.iter().find(|t| &t.label == h) else {
                continue;
            };
            let at_target = s.rows[t.integrator]
                .iter()
                .find(|r| r.samples == s.target_budget)
                .map(|r| format!("{} (N = {})", ratio(&r.ratios.relative_variance), r.samples))
                .unwrap_or_default();
            table_row(
                md,
                &[
                    s.name.clone(),
                    format!(
                        "{}{}",
                        s.runs,
                        if s.interrupted { " (interrupted)" } else { "" }
                    ),
                    at_target,
                    speedup_text(&t.speedup),
                    reading(&t.equal_time_ratio, |_| "beyond the ladder".into()),
                    verdict(&t.equal_time_ratio).to_string(),
                ],
            )?;
        }
        writeln!(md)?;
    }
    // Every integrator's speed-up, scene by scene, over balance and over the headline α.
    let labels: Vec<&str> = config
        .integrators
        .iter()
        .map(|c| c.label.as_str())
        .collect();
    writeln!(
        md,
        "Speed-up over balance at equal error, every integrator:\n"
    )?;
    speedup_table(md, scenes, &labels, |t| &t.speedup)?;
    if let Some(h) = &headline {
        writeln!(
            md,
            "Speed-up over `{h}` at equal error (the same target error: balance's at the target \
             budget), every integrator:\n"
        )?;
        speedup_table(md, scenes, &labels, |t| &t.speedup_over_headline)?;
    }
    across_scenes(md, scenes, &labels, headline.as_deref())?;
    figure(
        md,
        config,
        prefix,
        "plots/summary.png",
        "Speed-up over the balance heuristic at equal error, per scene and integrator, with 95 % intervals (log scale; right of 1 is faster)",
    )
}

/// How a speed-up known only as a bound (its time more than a factor 2 beyond the ladder's)
/// is shown: slower or faster than any value the ladder can measure.
pub const SLOWER_THAN_BOUND: &str = "< bound";
/// See [`SLOWER_THAN_BOUND`].
pub const FASTER_THAN_BOUND: &str = "> bound";

/// A speed-up and its interval, or its bound.
fn speedup_text(r: &Option<Reading>) -> String {
    reading(r, |above| {
        if above {
            SLOWER_THAN_BOUND
        } else {
            FASTER_THAN_BOUND
        }
        .into()
    })
}

/// One row per scene, one column per integrator: the speed-up that `pick` reads.
fn speedup_table(
    md: &mut String,
    scenes: &[SceneAnalysis],
    labels: &[&str],
    pick: fn(&Trade) -> &Option<Reading>,
) -> Result<()> {
    let mut columns = vec!["scene".to_string()];
    columns.extend(labels.iter().map(|l| format!("`{l}`")));
    let columns: Vec<&str> = columns.iter().map(String::as_str).collect();
    table_head(md, &columns)?;
    for s in scenes {
        let mut cells = vec![s.name.clone()];
        cells.extend(s.trade.iter().map(|t| speedup_text(pick(t))));
        table_row(md, &cells)?;
    }
    writeln!(md)?;
    Ok(())
}

/// How a speed-up's 95 % interval places it against 1.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Side {
    Faster,
    NotSignificant,
    Slower,
}

fn side(r: &Reading) -> Side {
    match r.extent {
        // Beyond the ladder by more than a factor 2 in time: the bound decides.
        Extent::Beyond { above } => {
            if above {
                Side::Slower
            } else {
                Side::Faster
            }
        }
        Extent::Within | Extent::Extrapolated => {
            if r.estimate.lo > 1.0 {
                Side::Faster
            } else if r.estimate.hi < 1.0 {
                Side::Slower
            } else {
                Side::NotSignificant
            }
        }
    }
}

/// The median of the point estimates and the count of scenes on each side of 1. A speed-up
/// known only as a bound beyond the ladder ranks as 0 (slower) or ∞ (faster): if the median
/// falls on one, only its bound is given.
pub fn tally(readings: &[Reading]) -> [String; 2] {
    let mut values: Vec<f64> = readings
        .iter()
        .map(|r| match r.extent {
            Extent::Beyond { above: true } => 0.0,
            Extent::Beyond { above: false } => f64::INFINITY,
            Extent::Within | Extent::Extrapolated => r.estimate.value,
        })
        .collect();
    values.sort_by(f64::total_cmp);
    let shown = |v: f64| match v {
        0.0 => SLOWER_THAN_BOUND.to_string(),
        f64::INFINITY => FASTER_THAN_BOUND.to_string(),
        v => short(v),
    };
    let median = match values.len() {
        0 => "–".to_string(),
        n if n % 2 == 1 => shown(values[n / 2]),
        n => shown((values[n / 2 - 1] * values[n / 2]).sqrt()),
    };
    let count = |which| readings.iter().filter(|r| side(r) == which).count();
    [
        median,
        format!(
            "{} / {} / {}",
            count(Side::Faster),
            count(Side::NotSignificant),
            count(Side::Slower)
        ),
    ]
}

/// Per integrator, across the scenes: the median speed-up over balance (and over the headline
/// α) and on how many scenes it is faster, not significantly different, or slower (95 %).
fn across_scenes(
    md: &mut String,
    scenes: &[SceneAnalysis],
    labels: &[&str],
    headline: Option<&str>,
) -> Result<()> {
    writeln!(
        md,
        "Across the {} scenes: the median of the per-scene speed-ups at equal error (point \
         estimates; a geometric mean of the middle two for an even count), and the number of \
         scenes where the 95 % interval lies above 1 (faster) / contains 1 (not significant) / \
         lies below 1 (slower). A speed-up known only as a bound (its time more than a factor 2 \
         beyond the ladder's) counts on the side of its bound and ranks there in the median.\n",
        scenes.len()
    )?;
    let mut columns = vec![
        "integrator".to_string(),
        "median speed-up over balance".to_string(),
        "faster / n.s. / slower than balance".to_string(),
    ];
    if let Some(h) = headline {
        columns.push(format!("median speed-up over `{h}`"));
        columns.push(format!("faster / n.s. / slower than `{h}`"));
    }
    let columns: Vec<&str> = columns.iter().map(String::as_str).collect();
    table_head(md, &columns)?;
    for (i, label) in labels.iter().enumerate() {
        let of = |pick: fn(&Trade) -> &Option<Reading>| -> Vec<Reading> {
            scenes
                .iter()
                .filter_map(|s| s.trade.get(i).and_then(|t| *pick(t)))
                .collect()
        };
        let mut cells = vec![format!("`{label}`")];
        cells.extend(tally(&of(|t| &t.speedup)));
        if headline.is_some() {
            cells.extend(tally(&of(|t| &t.speedup_over_headline)));
        }
        table_row(md, &cells)?;
    }
    writeln!(md)?;
    Ok(())
}

fn sweeps(
    md: &mut String,
    config: &StudyConfig,
    scenes: &[SceneAnalysis],
    prefix: &str,
) -> Result<()> {
    let any = |sweep: Sweep| {
        scenes
            .iter()
            .any(|s| s.sweeps.iter().any(|p| p.sweep == sweep))
    };
    if !scenes.iter().any(|s| !s.sweeps.is_empty()) {
        return Ok(());
    }
    writeln!(md, "## Sweeps of α's parameters\n")?;
    writeln!(
        md,
        "Integrated α at N = {} (K₀ runs), each point's relative variance over balance's at the \
         same N; the convergence sweep (N with M = N/4 of the sweep budget fixed) also gives \
         V[L₁] on the estimate basis (pilot included) over balance's.\n",
        config.sweep_budget()
    )?;
    for (sweep, what, file, caption) in [
        (
            Sweep::Clamp,
            "interval size s",
            "plots/clamp.png",
            "Clamping α to [½ − s/2, ½ + s/2] (paper Figure 2): relative variance over balance's, 95 % intervals",
        ),
        (
            Sweep::AlphaSamples,
            "M",
            "plots/m.png",
            "Pilot samples M that estimate α at fixed N (paper Figure 7): relative variance over balance's, 95 % intervals",
        ),
        (
            Sweep::Convergence,
            "N",
            "plots/convergence.png",
            "N with M fixed (paper Figures 3 and 4): V[L₁] (estimate basis) and relative variance of integrated α over balance's at the same N, 95 % intervals",
        ),
    ] {
        if !any(sweep) {
            continue;
        }
        writeln!(md, "### {} sweep\n", sweep.name())?;
        let xs: Vec<f64> = {
            let mut xs: Vec<f64> = scenes
                .iter()
                .flat_map(|s| s.sweeps.iter().filter(|p| p.sweep == sweep).map(|p| p.x))
                .collect();
            xs.sort_by(f64::total_cmp);
            xs.dedup();
            xs
        };
        let mut columns = vec!["scene".to_string()];
        columns.extend(xs.iter().map(|x| format!("{what} = {x}")));
        let columns: Vec<&str> = columns.iter().map(String::as_str).collect();
        table_head(md, &columns)?;
        for s in scenes {
            let mut cells = vec![s.name.clone()];
            for x in &xs {
                cells.push(
                    s.sweeps
                        .iter()
                        .find(|p| p.sweep == sweep && p.x == *x)
                        .map_or_else(|| "–".into(), |p| ratio(&p.row.ratios.relative_variance)),
                );
            }
            table_row(md, &cells)?;
        }
        writeln!(md)?;
        figure(md, config, prefix, file, caption)?;
    }
    Ok(())
}

fn scene_section(
    md: &mut String,
    config: &StudyConfig,
    s: &SceneAnalysis,
    prefix: &str,
) -> Result<()> {
    writeln!(
        md,
        "## {} — `{}` ({}×{}, K = {}{})\n",
        s.name,
        s.path.display(),
        s.width,
        s.height,
        s.runs,
        if s.interrupted { ", interrupted" } else { "" }
    )?;
    let mut reference = format!("Reference: `{}`", s.reference_path.display());
    if let Some(n) = s.reference_samples {
        if config.is_path_study() {
            let baseline = s.rows[s.balance].first().map_or("", |r| r.label.as_str());
            write!(
                reference,
                ", `{baseline}`, {n} camera samples per pixel in 16 shards"
            )?;
        } else {
            write!(
                reference,
                ", balance heuristic, {n} samples per light per pixel in 16 shards"
            )?;
        }
    }
    if let Some(t) = s.reference_cpu_time {
        write!(reference, ", {t:.1} s of CPU")?;
    }
    if s.reference_cached {
        write!(reference, " (cached)")?;
    }
    write!(
        reference,
        "; its own relative variance is {:.2} % of balance's at N = {} (removed from every rel. MSE)",
        100.0 * s.reference_share,
        s.budgets.last().copied().unwrap_or(0)
    )?;
    writeln!(md, "{reference}.\n")?;
    if let Some((label, e, met)) = &s.headline {
        writeln!(
            md,
            "K rule: `{label}` / balance relative variance at N = {} is {} with K = {} ({}).\n",
            s.target_budget,
            ratio(e),
            s.runs,
            if *met {
                format!("within ±{} %", config.precision * 100.0)
            } else {
                format!(
                    "not within ±{} %: the cap, or an interrupted study",
                    config.precision * 100.0
                )
            }
        )?;
    }
    writeln!(
        md,
        "Target error: relative variance {} (balance at N = {}); equal-time point: {} s of CPU.\n",
        sig(s.target_error),
        s.target_budget,
        sig(s.target_time)
    )?;
    writeln!(md, "### The trade\n")?;
    table_head(
        md,
        &[
            "integrator",
            "CPU time to the target (s)",
            "speed-up over balance",
            "error ratio at equal time",
            "beats balance at equal time?",
        ],
    )?;
    for t in &s.trade {
        table_row(
            md,
            &[
                format!("`{}`", t.label),
                reading(&t.time_to_target, |above| {
                    let times = &s.curves[t.integrator].points;
                    if above {
                        format!(
                            "> {}",
                            short(2.0 * times.last().map_or(f64::NAN, |p| p.cpu_time.value))
                        )
                    } else {
                        format!(
                            "< {}",
                            short(0.5 * times.first().map_or(f64::NAN, |p| p.cpu_time.value))
                        )
                    }
                }),
                speedup_text(&t.speedup),
                reading(&t.equal_time_ratio, |_| "beyond the ladder".into()),
                verdict(&t.equal_time_ratio).to_string(),
            ],
        )?;
    }
    writeln!(md)?;
    if !s.front.is_empty() {
        let front: Vec<String> = s
            .front
            .iter()
            .map(|f| {
                format!(
                    "`{}` from {} s to {} s",
                    f.label,
                    short(f.from),
                    short(f.to)
                )
            })
            .collect();
        writeln!(
            md,
            "Pareto front (lowest relative variance at each CPU time, point estimates): {}.\n",
            front.join("; ")
        )?;
    }
    figure(
        md,
        config,
        prefix,
        &format!("plots/{}-curves.png", s.name),
        "Relative variance and rel. MSE against CPU time (log-log), each integrator through its budgets with its 95 % band; dashed: the Pareto front; dotted: the target error and the equal-time point",
    )?;

    writeln!(md, "### Relative variance over balance's, per budget\n")?;
    let mut columns = vec!["integrator".to_string()];
    columns.extend(s.budgets.iter().map(|n| format!("N = {n}")));
    let columns: Vec<&str> = columns.iter().map(String::as_str).collect();
    table_head(md, &columns)?;
    for (i, rows) in s.rows.iter().enumerate() {
        if i == s.balance {
            continue;
        }
        let mut cells = vec![format!("`{}`", rows[0].label)];
        cells.extend(rows.iter().map(|r| ratio(&r.ratios.relative_variance)));
        table_row(md, &cells)?;
    }
    let mut cells = vec!["balance: CPU s per run".to_string()];
    cells.extend(s.rows[s.balance].iter().map(|r| value(&r.cpu_time)));
    table_row(md, &cells)?;
    writeln!(md)?;

    writeln!(
        md,
        "### At the target budget (N = {}): robust statistics and α\n",
        s.target_budget
    )?;
    writeln!(
        md,
        "Ratios to balance. *median V ratio*: the median over pixels of V_p / V_p(balance); \
         *V[L_N]*: the plain mean of V_p, which a few bright pixels dominate (*top 0.1 %*: the \
         share of balance's V[L_N] and of its relative variance held by its largest 0.1 % of \
         pixels); *z*: the image's mean luminance against the reference's, in standard errors.\n"
    )?;
    table_head(
        md,
        &[
            "integrator",
            "rel. variance",
            "median V ratio",
            "rel. MSE",
            "V[L_N]",
            "ΔE*ab",
            "CPU time",
            "efficiency",
            "BSDF samples",
            "median α̂",
            "z",
        ],
    )?;
    for rows in &s.rows {
        let Some(r) = rows.iter().find(|r| r.samples == s.target_budget) else {
            continue;
        };
        let q = &r.ratios;
        table_row(
            md,
            &[
                format!("`{}`", r.label),
                ratio(&q.relative_variance),
                ratio(&q.median_variance),
                ratio(&q.relative_mse),
                ratio(&q.variance),
                ratio(&q.delta_e),
                ratio(&q.cpu_time),
                ratio(&q.efficiency),
                optional(&r.bsdf_fraction, value),
                optional(&r.alpha_median, value),
                format!("{:.2}", r.z),
            ],
        )?;
    }
    if let Some(b) = s.rows[s.balance]
        .iter()
        .find(|r| r.samples == s.target_budget)
    {
        writeln!(
            md,
            "\nBalance's largest 0.1 % of pixels hold {:.0} % of its V[L_N] and {:.0} % of its relative variance.",
            100.0 * b.variance_top,
            100.0 * b.relative_variance_top
        )?;
    }
    writeln!(md)?;

    if !s.paper.is_empty() {
        writeln!(
            md,
            "### Like for like with the paper (N = 256, K₀ = {} runs)\n",
            s.base_runs
        )?;
        writeln!(
            md,
            "Ratios to balance. V[L₁] is the variance of the one-sample estimator: *estimate \
             basis* over every sample of the estimate (for integrated α the pilot's M = N/2 \
             too, as the paper's Table 2), *settled split* over the samples at the split the \
             method settled on (for integrated α the N − M samples at α̂ only). The *paper* \
             columns are its ratios for the same method and pilot size (Table 1's V[L₁], \
             Table 2's ΔE and time, efficiency 1/(V[L₁] × time)); \"–\" where the quantity is \
             not the same.\n"
        )?;
        table_head(
            md,
            &[
                "integrator",
                "V[L₁] estimate basis",
                "paper",
                "V[L₁] settled split",
                "ΔE*ab",
                "paper",
                "CPU time",
                "paper",
                "efficiency 1/(V[L₁]·t)",
                "paper",
            ],
        )?;
        for p in &s.paper {
            let q = &p.row.ratios;
            table_row(
                md,
                &[
                    format!("`{}`", p.row.label),
                    optional(&q.sampling_variance_estimate, ratio),
                    self::paper(p.sampling_variance),
                    optional(&q.sampling_variance, ratio),
                    ratio(&q.delta_e),
                    self::paper(p.delta_e),
                    ratio(&q.cpu_time),
                    self::paper(p.time),
                    optional(&q.paper_efficiency, ratio),
                    self::paper(p.efficiency),
                ],
            )?;
        }
        writeln!(md)?;
    }
    let alpha_label = s
        .panel
        .as_ref()
        .and_then(|p| p.alpha.as_ref().map(|a| a.0.clone()))
        .unwrap_or_else(|| "α".into());
    figure(
        md,
        config,
        prefix,
        &format!("panels/{}.png", s.name),
        &format!(
            "Top: reference, balance and `{alpha_label}` (first run, N = {}), α map (red: light sampling, green: BSDF sampling). Bottom: ΔE*ab of balance and of α (scale below them), and the quarter of the image where balance errs most, ×2",
            s.target_budget
        ),
    )?;
    Ok(())
}
