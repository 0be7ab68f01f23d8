//! The study's tables: `results.csv` and `sweeps.csv` (one line per measured configuration),
//! and `results.md` (a table per scene with the paper's ratios beside ours). All are rewritten
//! atomically after every finished row.

use super::{Measurement, SceneResults, StudyConfig, paper};
use anyhow::Result;
use lumis_core::image_io::write_atomically;
use lumis_integrators::{alpha, balance};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// One integrator on one scene at one budget.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub scene: String,
    pub integrator: String,
    pub kind: String,
    pub mode: String,
    /// "equal samples" or "equal time".
    pub budget: String,
    /// N, samples per light per camera sample.
    pub samples: u32,
    pub runs: u32,
    pub width: u32,
    pub height: u32,
    /// V[L_{1,α}] averaged over pixels and runs.
    pub sampling_variance: f64,
    /// Its median over pixels (the mean is heavy-tailed).
    pub sampling_variance_median: f64,
    /// V[L_{N,α}]: each pixel's variance across runs, averaged over pixels.
    pub estimator_variance: f64,
    pub rel_mse: f64,
    /// Mean CIE76 ΔE*ab against the reference after the paper's tone map.
    pub lab_error: f64,
    /// Median wall time of a run, seconds.
    pub time: f64,
    /// Median CPU time of a run (all threads), seconds: robust to other load on the machine.
    pub cpu_time: f64,
    /// 1 / (V[L_{N,α}] × CPU time).
    pub efficiency: f64,
    /// Mean luminance of the image, averaged over runs, and its standard error (with the
    /// reference's).
    pub mean: f64,
    pub mean_sigma: f64,
    pub reference_mean: f64,
    /// (mean − reference mean) / σ.
    pub z: f64,
}

/// One point of a sweep.
#[derive(Clone, Debug, Serialize)]
pub struct SweepPoint {
    pub scene: String,
    /// "clamp" (x = interval size), "m" (x = M) or "n" (x = N, M fixed).
    pub sweep: String,
    pub integrator: String,
    pub x: f64,
    pub samples: u32,
    pub sampling_variance: f64,
    pub estimator_variance: f64,
    pub time: f64,
    pub cpu_time: f64,
}

impl SweepPoint {
    pub(super) fn new(scene: &str, sweep: &str, integrator: &str, x: f64, m: &Measurement) -> Self {
        Self {
            scene: scene.into(),
            sweep: sweep.into(),
            integrator: integrator.into(),
            x,
            samples: m.samples,
            sampling_variance: m.sampling_variance,
            estimator_variance: m.runs.estimator_variance(),
            time: m.time,
            cpu_time: m.cpu_time,
        }
    }
}

fn write_records<T: Serialize>(path: &Path, records: impl Iterator<Item = T>) -> Result<()> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    for record in records {
        writer.serialize(record)?;
    }
    let bytes = writer.into_inner()?;
    write_atomically(path, |file| {
        std::io::Write::write_all(file, &bytes).map_err(|e| e.to_string())
    })?;
    Ok(())
}

pub fn write_csv(out: &Path, scenes: &[SceneResults]) -> Result<()> {
    write_records(
        &out.join("results.csv"),
        scenes.iter().flat_map(|s| s.rows.iter()),
    )
}

pub fn write_sweeps_csv(out: &Path, scenes: &[SceneResults]) -> Result<()> {
    write_records(
        &out.join("sweeps.csv"),
        scenes.iter().flat_map(|s| s.sweeps.iter()),
    )
}

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

fn ratio(v: Option<f64>) -> String {
    v.filter(|v| v.is_finite())
        .map_or_else(|| "–".into(), |v| format!("{v:.2}"))
}

/// The balance heuristic's row at the same budget.
fn balance<'a>(rows: &'a [Row], budget: &str) -> Option<&'a Row> {
    rows.iter()
        .find(|r| r.kind == balance::NAME && r.budget == budget)
}

fn mode(row: &Row) -> Option<&str> {
    (!row.mode.is_empty()).then_some(row.mode.as_str())
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

pub fn write_markdown(config: &StudyConfig, scenes: &[SceneResults]) -> Result<()> {
    let mut md = String::new();
    let prefix = link_prefix(config);
    let scene_list: Vec<String> = config
        .scenes
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    writeln!(md, "# lumis study\n")?;
    if let Some(command) = &config.command {
        writeln!(md, "Made by `{command}`.\n")?;
    }
    writeln!(
        md,
        "Scenes: {}. N = {} samples per light, K = {} runs (seeds {}–{}){}.\n",
        scene_list.join(", "),
        config.samples,
        config.runs,
        config.seed + 1,
        config.seed + config.runs as u64,
        if config.overrides.is_empty() {
            String::new()
        } else {
            format!(", overrides `{}`", config.overrides.join(" "))
        }
    )?;
    writeln!(
        md,
        "V[L₁]: sampling variance of the one-sample estimator (mean over pixels); V[L_N]: \
         variance of the image across runs (mean over pixels); rel. MSE and ΔE*ab (mean CIE76 \
         after gamma 2.2 and clamping, as the paper) against the reference; time: median wall \
         time of a run; CPU: its CPU time, all threads (other programs on the machine do not \
         count in it); efficiency: 1 / (V[L_N] × CPU time); z: the image's mean luminance against \
         the reference's, in standard errors. Ratios are to the balance heuristic at the same \
         budget; *paper* columns are the paper's ratios for its scene of the same number \
         (Tables 1 and 2; its efficiency uses V[L₁]).\n"
    )?;
    summary(&mut md, scenes)?;
    if let Some(notes) = &config.notes {
        let text = std::fs::read_to_string(notes)?;
        writeln!(md, "{}\n", text.trim_end())?;
    }
    for (file, caption) in [
        (
            "plots/clamp.png",
            "Clamping α (paper Figure 2): V[L_N] of integrated α against the size of the interval around ½ that α is clamped to, relative to the best size, per scene",
        ),
        (
            "plots/m.png",
            "Samples M that estimate α (paper Figure 7): V[L_N] at fixed N against M, relative to the best M, per scene",
        ),
        (
            "plots/convergence-l1.png",
            "Integrated α with M = N/4 of the study fixed (paper Figure 3): V[L₁] against N, relative to the preprocessed α of the table",
        ),
        (
            "plots/convergence-ln.png",
            "Convergence in N with M fixed (paper Figure 4): V[L_N] of integrated α and of the balance heuristic, relative to α's at N = M",
        ),
    ] {
        if config.out.join(file).exists() {
            writeln!(md, "![{caption}]({prefix}{file})\n\n*{caption}.*\n")?;
        }
    }
    for results in scenes {
        scene_section(&mut md, config, results, &prefix)?;
    }
    let bytes = md.into_bytes();
    write_atomically(&config.report_path(), |file| {
        std::io::Write::write_all(file, &bytes).map_err(|e| e.to_string())
    })?;
    Ok(())
}

/// Integrated and preprocessed α against balance, ours beside the paper's, one line a scene.
fn summary(md: &mut String, scenes: &[SceneResults]) -> Result<()> {
    writeln!(md, "## Summary: α against the balance heuristic\n")?;
    writeln!(
        md,
        "| scene | α V[L₁] ratio | paper | α V[L_N] ratio | α ΔE ratio | paper | α efficiency ratio | paper | preprocessed α V[L₁] ratio | paper |"
    )?;
    writeln!(md, "|---|---|---|---|---|---|---|---|---|---|")?;
    for s in scenes {
        let budget = "equal samples";
        let Some(b) = balance(&s.rows, budget) else {
            continue;
        };
        let find = |pre: bool| {
            s.rows.iter().find(|r| {
                r.kind == alpha::NAME
                    && r.budget == budget
                    && (r.mode == alpha::PREPROCESSED) == pre
            })
        };
        let p = paper::scene(&s.path);
        let alpha = find(false);
        let pre = find(true);
        writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            s.name,
            ratio(alpha.map(|a| a.sampling_variance / b.sampling_variance)),
            ratio(p.and_then(|p| p.sampling_variance.ratio(alpha::NAME, None))),
            ratio(alpha.map(|a| a.estimator_variance / b.estimator_variance)),
            ratio(alpha.map(|a| a.lab_error / b.lab_error)),
            ratio(p.and_then(|p| p.lab_error.ratio(alpha::NAME, None))),
            ratio(alpha.map(|a| a.efficiency / b.efficiency)),
            ratio(p.and_then(|p| Some(
                paper::efficiency(p, alpha::NAME, None)?
                    / paper::efficiency(p, balance::NAME, None)?
            ))),
            ratio(pre.map(|a| a.sampling_variance / b.sampling_variance)),
            ratio(p.and_then(|p| {
                p.sampling_variance
                    .ratio(alpha::NAME, Some(alpha::PREPROCESSED))
            })),
        )?;
    }
    writeln!(md)?;
    Ok(())
}

fn scene_section(
    md: &mut String,
    config: &StudyConfig,
    s: &SceneResults,
    prefix: &str,
) -> Result<()> {
    writeln!(
        md,
        "## {} — `{}` ({}×{})\n",
        s.name,
        s.path.display(),
        s.width,
        s.height
    )?;
    let r = &s.reference;
    let mut reference = format!("Reference: `{}`", r.path.display());
    if let Some(n) = r.samples {
        write!(
            reference,
            ", balance heuristic, {n} samples per light per pixel"
        )?;
    }
    if let Some(t) = r.time {
        write!(reference, ", rendered in {t:.1} s")?;
    }
    if r.cached {
        write!(reference, " (cached)")?;
    }
    // The reference's own error, next to what it measures: negligible when this is small.
    if let (Some(v), Some(b)) = (r.variance(), balance(&s.rows, "equal samples")) {
        write!(
            reference,
            "; its own variance is {:.2} % of the balance heuristic's V[L_N], so it adds that \
             much to each MSE",
            100.0 * v / b.estimator_variance
        )?;
    }
    writeln!(md, "{reference}.\n")?;
    let p = paper::scene(&s.path);
    for budget in ["equal samples", "equal time"] {
        let rows: Vec<&Row> = s.rows.iter().filter(|r| r.budget == budget).collect();
        if rows.is_empty() {
            continue;
        }
        let b = balance(&s.rows, budget);
        let heading = if budget == "equal samples" {
            format!("Equal samples (N = {})", config.samples)
        } else {
            "Equal time (N chosen to match `alpha`'s CPU time)".into()
        };
        writeln!(md, "### {heading}\n")?;
        writeln!(
            md,
            "| integrator | N | V[L₁] | ratio | paper | median V[L₁] | V[L_N] | ratio | rel. MSE | ΔE*ab | ratio | paper | time (s) | CPU (s) | efficiency | ratio | z |"
        )?;
        writeln!(
            md,
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
        )?;
        for row in rows {
            let of_balance = |f: fn(&Row) -> f64| b.map(|b| f(row) / f(b));
            let paper_v = p.and_then(|p| p.sampling_variance.ratio(&row.kind, mode(row)));
            let paper_lab = p.and_then(|p| p.lab_error.ratio(&row.kind, mode(row)));
            writeln!(
                md,
                "| `{}` | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.2} |",
                row.integrator,
                row.samples,
                sig(row.sampling_variance),
                ratio(of_balance(|r| r.sampling_variance)),
                if budget == "equal samples" {
                    ratio(paper_v)
                } else {
                    "–".into()
                },
                sig(row.sampling_variance_median),
                sig(row.estimator_variance),
                ratio(of_balance(|r| r.estimator_variance)),
                sig(row.rel_mse),
                sig(row.lab_error),
                ratio(of_balance(|r| r.lab_error)),
                if budget == "equal samples" {
                    ratio(paper_lab)
                } else {
                    "–".into()
                },
                sig(row.time),
                sig(row.cpu_time),
                sig(row.efficiency),
                ratio(of_balance(|r| r.efficiency)),
                row.z,
            )?;
        }
        writeln!(md)?;
    }
    let name = &s.name;
    let exists = |file: &str| config.out.join(file).exists();
    for (file, caption) in [
        (
            format!("plots/{name}-time.png"),
            "Variance and error against CPU time (log-log): each integrator at equal samples and equal time",
        ),
        (
            format!("panels/{name}.png"),
            "Top: reference, balance, α (equal time when measured), α map (red: light sampling, green: BSDF sampling, yellow: ½). Bottom: ΔE*ab of balance and of α (0 … 10: black, red, yellow, white), and the quarter of the image where balance errs most, ×2, for balance and α",
        ),
    ] {
        if exists(&file) {
            writeln!(md, "![{caption}]({prefix}{file})\n\n*{caption}.*\n")?;
        }
    }
    Ok(())
}
