//! Collect: everything a scene's report says, as a pure function of its plan, its reference and
//! its cells' results. A [`Collector`] takes the results in any order (reducing each to a
//! [`RunSummary`] at once, so that a study never holds more than one image per run), and
//! [`Collector::analyse`] computes the statistics, their ratios to the balance heuristic, the
//! curves of error against CPU time, the time to reach the scene's target error, the Pareto
//! front, the paper's like-for-like rows and the sweeps, each with its 95 % interval.
//!
//! The number of runs K is chosen here too: of the rounds K₀, 2K₀, … that all the curves'
//! configurations have complete, the first at which the headline ratio (integrated α over
//! balance, relative variance at the target budget) is known to ±precision, or else the
//! largest. A study that stops growing K as soon as the rule is met, and one that ran every
//! round up to the cap, report the same K and so the same numbers.
//!
//! Why one file of over 600 lines: the study's statistics are one pure function of a plan and its
//! results, kept in one place so that a report can be recomputed from results.csv; with its tests.

use super::cell::CellResult;
use super::config::StudyConfig;
use super::paper;
use super::plan::{Role, ScenePlan, Sweep};
use super::stats::{Estimate, Jack, Reach, reach};
use super::summary::{ConfigurationStats, Context, RunSummary, median_variance_ratio};
use anyhow::{Result, bail};
use lumis_core::math::Rgb;
use serde::Serialize;
use std::collections::HashMap;

/// Accumulates a scene's run summaries.
pub struct Collector {
    pub plan: ScenePlan,
    pub context: Context,
    /// `runs[configuration][k − 1]`.
    runs: Vec<Vec<Option<RunSummary>>>,
    rounds: Vec<u32>,
    precision: f64,
}

/// Ratios of a configuration's statistics to the balance heuristic's at the same budget (and
/// the same runs), with 95 % intervals.
#[derive(Clone, Debug, Serialize)]
pub struct Ratios {
    pub relative_variance: Estimate,
    pub median_variance: Estimate,
    pub variance: Estimate,
    pub relative_mse: Estimate,
    pub delta_e: Estimate,
    pub sampling_variance: Option<Estimate>,
    pub sampling_variance_estimate: Option<Estimate>,
    pub cpu_time: Estimate,
    pub efficiency: Estimate,
    /// The paper's efficiency, 1 / (V[L₁] × time), V[L₁] on the estimate basis.
    pub paper_efficiency: Option<Estimate>,
}

/// One configuration's measurements.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub configuration: usize,
    pub label: String,
    pub kind: String,
    pub samples: u32,
    pub runs: usize,
    pub cpu_time: Estimate,
    pub wall_time: f64,
    pub relative_variance: Estimate,
    pub variance: Estimate,
    pub relative_variance_top: f64,
    pub variance_top: f64,
    pub relative_mse: Estimate,
    pub delta_e: Estimate,
    pub sampling_variance: Option<Estimate>,
    pub sampling_variance_estimate: Option<Estimate>,
    pub sampling_variance_median: Option<Estimate>,
    pub bsdf_fraction: Option<Estimate>,
    pub alpha_median: Option<Estimate>,
    pub efficiency: Estimate,
    pub z: f64,
    pub ratios: Ratios,
}

/// A quantity read off a curve: between its measured times, extrapolated by up to a factor
/// of two in time beyond them, or further (then only a bound is reported).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum Extent {
    Within,
    Extrapolated,
    /// Below the least measured time ÷ 2 (`false`) or above the greatest × 2 (`true`).
    Beyond {
        above: bool,
    },
}

impl Extent {
    /// Where a reading at `log_time` lies against a curve's measured times (`log_times`, in
    /// budget order). Against the least and the greatest of them, not the first and the last:
    /// at small budgets a larger budget can be measured faster, and the curve, piecewise linear
    /// through its points, is read between two measured points anywhere in that range.
    pub fn of(log_times: &[f64], log_time: f64) -> Extent {
        let (least, greatest) = log_times
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
                (lo.min(t), hi.max(t))
            });
        let margin = std::f64::consts::LN_2;
        if log_time < least - margin {
            Extent::Beyond { above: false }
        } else if log_time > greatest + margin {
            Extent::Beyond { above: true }
        } else if log_time < least || log_time > greatest {
            Extent::Extrapolated
        } else {
            Extent::Within
        }
    }

    /// The less reliable of two extents (a value read off two curves is as far out as the
    /// farther of its two readings).
    fn farther(self, other: Extent) -> Extent {
        let rank = |e: Extent| match e {
            Extent::Within => 0,
            Extent::Extrapolated => 1,
            Extent::Beyond { .. } => 2,
        };
        if rank(other) > rank(self) {
            other
        } else {
            self
        }
    }
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct Reading {
    pub estimate: Estimate,
    pub extent: Extent,
}

/// What one integrator's curve says about the trade.
#[derive(Clone, Debug, Serialize)]
pub struct Trade {
    pub integrator: usize,
    pub label: String,
    /// CPU time to reach the target error, seconds.
    pub time_to_target: Option<Reading>,
    /// The balance heuristic's time to the target over this integrator's: > 1 is faster.
    pub speedup: Option<Reading>,
    /// The headline α's time to the same target over this integrator's: > 1 is faster than α.
    pub speedup_over_headline: Option<Reading>,
    /// This integrator's relative variance at the balance heuristic's target-budget time,
    /// over balance's there: < 1 is better at equal time.
    pub equal_time_ratio: Option<Reading>,
}

/// One integrator's curve: per budget, CPU time and errors.
#[derive(Clone, Debug, Serialize)]
pub struct Curve {
    pub label: String,
    pub points: Vec<CurvePoint>,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct CurvePoint {
    pub samples: u32,
    pub cpu_time: Estimate,
    pub relative_variance: Estimate,
    pub relative_mse: Estimate,
}

/// A stretch of CPU time over which one integrator has the lowest error of all (point
/// estimates, between measured budgets).
#[derive(Clone, Debug, Serialize)]
pub struct FrontSegment {
    pub label: String,
    pub from: f64,
    pub to: f64,
}

/// A sweep point against the balance heuristic at its budget.
#[derive(Clone, Debug, Serialize)]
pub struct SweepRow {
    pub sweep: Sweep,
    pub x: f64,
    pub row: Row,
}

/// A row compared with the paper's tables (N = 256).
#[derive(Clone, Debug, Serialize)]
pub struct PaperRow {
    pub row: Row,
    /// The paper's ratios to its balance heuristic for the same method, when it is the same
    /// quantity: V[L₁] (Table 1, integrated α from Table 2), ΔE (Table 2), time, efficiency.
    pub sampling_variance: Option<f64>,
    pub delta_e: Option<f64>,
    pub time: Option<f64>,
    pub efficiency: Option<f64>,
}

/// The images of the panel: the first run of balance and of the headline α at the target budget.
#[derive(Clone, Debug)]
pub struct PanelImages {
    pub samples: u32,
    pub balance: Vec<Rgb>,
    pub alpha: Option<(String, Vec<Rgb>, Option<Vec<f32>>)>,
}

/// Everything the report says about one scene.
#[derive(Clone, Debug, Serialize)]
pub struct SceneAnalysis {
    pub name: String,
    pub path: std::path::PathBuf,
    pub width: u32,
    pub height: u32,
    /// K of the curves, and K₀ of the paper's rows and the sweeps.
    pub runs: usize,
    pub base_runs: usize,
    /// The headline ratio at K and whether it met the precision (None without a headline).
    pub headline: Option<(String, Estimate, bool)>,
    pub interrupted: bool,
    pub epsilon: f64,
    pub block: u32,
    pub blocks: usize,
    pub reference_samples: Option<u32>,
    pub reference_cpu_time: Option<f64>,
    pub reference_cached: bool,
    pub reference_path: std::path::PathBuf,
    /// The reference image (not serialised: the analysis's numbers are, its images are in the
    /// report's panels).
    #[serde(skip)]
    pub reference_pixels: Vec<Rgb>,
    /// The reference's own relative variance over balance's at the largest budget.
    pub reference_share: f64,
    pub budgets: Vec<u32>,
    pub target_budget: u32,
    /// The target error (balance's relative variance at the target budget) and the equal-time
    /// point (its CPU time there).
    pub target_error: f64,
    pub target_time: f64,
    /// `rows[i][j]`: integrator i at budget j.
    pub rows: Vec<Vec<Row>>,
    pub balance: usize,
    pub curves: Vec<Curve>,
    pub trade: Vec<Trade>,
    pub front: Vec<FrontSegment>,
    pub paper: Vec<PaperRow>,
    pub sweeps: Vec<SweepRow>,
    #[serde(skip)]
    pub panel: Option<PanelImages>,
    pub exposure_scale: f32,
}

impl Collector {
    pub fn new(plan: ScenePlan, context: Context, config: &StudyConfig) -> Self {
        let configurations = plan.configurations.len();
        Collector {
            plan,
            context,
            runs: vec![Vec::new(); configurations],
            rounds: config.rounds(),
            precision: config.precision,
        }
    }

    /// Adds a run's result (a reference shard is not one).
    pub fn add(&mut self, result: &CellResult) -> Result<()> {
        let Role::Run { configuration, run } = result.cell.role else {
            bail!("a reference shard is not a run");
        };
        if (result.width, result.height) != (self.context.width, self.context.height) {
            bail!(
                "a cell of {}×{} pixels in a study of {}×{}",
                result.width,
                result.height,
                self.context.width,
                self.context.height
            );
        }
        let keep = run == 1 && self.plan.panel.contains(&configuration);
        let summary = RunSummary::new(result, run, &self.context, keep);
        let slots = &mut self.runs[configuration];
        let index = run as usize - 1;
        if slots.len() <= index {
            slots.resize(index + 1, None);
        }
        slots[index] = Some(summary);
        Ok(())
    }

    /// The largest k such that runs 1 … k of `configuration` are all here.
    fn complete(&self, configuration: usize) -> usize {
        self.runs[configuration]
            .iter()
            .position(Option::is_none)
            .unwrap_or(self.runs[configuration].len())
    }

    /// Complete runs common to the configurations that grow (`grows`) or to all.
    fn available(&self, grows_only: bool) -> usize {
        (0..self.runs.len())
            .filter(|&c| !grows_only || self.plan.configurations[c].grows)
            .map(|c| self.complete(c))
            .min()
            .unwrap_or(0)
    }

    fn runs_of(&self, configuration: usize, k: usize) -> Vec<&RunSummary> {
        self.runs[configuration][..k]
            .iter()
            .map(|r| r.as_ref().expect("complete runs"))
            .collect()
    }

    /// The headline ratio (relative variance of integrated α over balance's at the target
    /// budget) with `k` runs.
    pub fn headline_ratio(&self, k: usize) -> Option<Estimate> {
        let h = self.plan.headline?;
        let t = self.plan.target;
        let a = ConfigurationStats::new(&self.runs_of(self.plan.curves[h][t], k), &self.context);
        let b = ConfigurationStats::new(
            &self.runs_of(self.plan.curves[self.plan.balance][t], k),
            &self.context,
        );
        Some(
            a.relative_variance
                .ratio(&b.relative_variance)
                .log_interval(),
        )
    }

    /// Whether the headline ratio is known to ±precision with `k` runs (true without a
    /// headline: nothing to grow for).
    pub fn precise_enough(&self, k: usize) -> bool {
        self.headline_ratio(k)
            .is_none_or(|e| e.relative_half_width() <= self.precision)
    }

    /// K of the curves by the rule, and K₀ of the rest, from the runs here; `None` if fewer
    /// than 3 runs of everything are complete.
    pub fn chosen_runs(&self) -> Option<(usize, usize)> {
        let base = self.available(false).min(self.rounds[0] as usize);
        if base < 3 {
            return None;
        }
        let growing = self.available(true);
        let mut k = base;
        for &r in &self.rounds {
            let r = r as usize;
            if r > growing {
                break;
            }
            k = r;
            if self.precise_enough(r) {
                break;
            }
        }
        Some((k.max(base), base))
    }

    /// The scene's analysis from the runs here (`None` if fewer than 3 complete runs).
    pub fn analyse(&self, interrupted: bool) -> Option<SceneAnalysis> {
        let (k, k0) = self.chosen_runs()?;
        let plan = &self.plan;
        let context = &self.context;
        // Every configuration's statistics at the K of its group: the curves at K, the paper's
        // rows and the sweeps (with the balance rows they are compared with) at K₀.
        let mut needed: Vec<(usize, usize)> =
            plan.curves.iter().flatten().map(|&c| (c, k)).collect();
        let paper_balance =
            plan.paper.iter().copied().find(|&c| {
                plan.configurations[c].choice.spec.kind == lumis_integrators::balance::NAME
            });
        if paper_balance.is_some() {
            needed.extend(plan.paper.iter().map(|&c| (c, k0)));
        }
        needed.extend(
            plan.sweeps
                .iter()
                .flat_map(|p| [(p.configuration, k0), (p.balance, k0)]),
        );
        let mut stats: HashMap<(usize, usize), ConfigurationStats> = HashMap::new();
        for key in needed {
            stats
                .entry(key)
                .or_insert_with(|| ConfigurationStats::new(&self.runs_of(key.0, key.1), context));
        }
        let stats_of = |c: usize, k: usize| &stats[&(c, k)];
        let row = |c: usize, base: usize, k: usize| {
            self.row(c, k, stats_of(c, k), base, stats_of(base, k))
        };
        let rows: Vec<Vec<Row>> = plan
            .curves
            .iter()
            .map(|curve| {
                curve
                    .iter()
                    .zip(&plan.curves[plan.balance])
                    .map(|(&c, &base)| row(c, base, k))
                    .collect()
            })
            .collect();

        // The target: balance's error and time at the target budget.
        let t = plan.target;
        let balance_stats = stats_of(plan.curves[plan.balance][t], k);
        let target_error = balance_stats.relative_variance.value;
        let target_time = balance_stats.cpu_time.value;
        let curve_stats: Vec<Vec<&ConfigurationStats>> = plan
            .curves
            .iter()
            .map(|curve| curve.iter().map(|&c| stats_of(c, k)).collect())
            .collect();
        let trade = plan
            .integrators
            .iter()
            .enumerate()
            .map(|(i, choice)| {
                trade(
                    i,
                    &choice.label,
                    &curve_stats[i],
                    &curve_stats[plan.balance],
                    plan.headline.map(|h| curve_stats[h].as_slice()),
                    target_error,
                    target_time,
                )
            })
            .collect();
        let curves: Vec<Curve> = plan
            .integrators
            .iter()
            .zip(&rows)
            .map(|(choice, rows)| Curve {
                label: choice.label.clone(),
                points: rows
                    .iter()
                    .map(|r| CurvePoint {
                        samples: r.samples,
                        cpu_time: r.cpu_time,
                        relative_variance: r.relative_variance,
                        relative_mse: r.relative_mse,
                    })
                    .collect(),
            })
            .collect();
        let front = pareto_front(&curves);

        // The paper's rows, against balance at N = 256 with K₀ runs.
        let paper_scene = paper::scene(&plan.path);
        let paper = match paper_balance {
            Some(base) => plan
                .paper
                .iter()
                .map(|&c| {
                    let row = row(c, base, k0);
                    let configuration = &plan.configurations[c];
                    let method = paper::method(&configuration.choice, configuration.samples);
                    let of = |table: &paper::PerMethod| {
                        let (kind, mode) = method?;
                        table.ratio(kind, mode)
                    };
                    PaperRow {
                        sampling_variance: paper_scene.and_then(|p| of(&p.sampling_variance)),
                        delta_e: paper_scene.and_then(|p| of(&p.lab_error)),
                        time: paper_scene.and_then(|p| of(&p.time)),
                        efficiency: paper_scene.and_then(|p| {
                            let (kind, mode) = method?;
                            Some(
                                paper::efficiency(p, kind, mode)?
                                    / paper::efficiency(p, lumis_integrators::balance::NAME, None)?,
                            )
                        }),
                        row,
                    }
                })
                .collect(),
            None => Vec::new(),
        };
        let sweeps = plan
            .sweeps
            .iter()
            .map(|point| SweepRow {
                sweep: point.sweep,
                x: point.x,
                row: row(point.configuration, point.balance, k0),
            })
            .collect();

        let top = plan.budgets.len() - 1;
        let balance_top = stats_of(plan.curves[plan.balance][top], k);
        let reference_share = context
            .reference
            .variance
            .iter()
            .zip(&context.weights)
            .map(|(v, w)| v * w)
            .sum::<f64>()
            / context.pixels() as f64
            / balance_top.relative_variance.value;

        let headline = plan.headline.and_then(|h| {
            let e = self.headline_ratio(k)?;
            Some((
                plan.integrators[h].label.clone(),
                e,
                e.relative_half_width() <= self.precision,
            ))
        });
        Some(SceneAnalysis {
            name: plan.name.clone(),
            path: plan.path.clone(),
            width: context.width,
            height: context.height,
            runs: k,
            base_runs: k0,
            headline,
            interrupted,
            epsilon: context.epsilon,
            block: context.blocks.edge,
            blocks: context.blocks.count,
            reference_samples: context.reference.samples,
            reference_cpu_time: context.reference.cpu_time,
            reference_cached: context.reference.cached,
            reference_path: context.reference.path.clone(),
            reference_pixels: context.reference.pixels.clone(),
            reference_share,
            budgets: plan.budgets.clone(),
            target_budget: plan.budgets[t],
            target_error,
            target_time,
            rows,
            balance: plan.balance,
            curves,
            trade,
            front,
            paper,
            sweeps,
            panel: self.panel(),
            exposure_scale: context.exposure_scale,
        })
    }

    fn row(
        &self,
        c: usize,
        k: usize,
        s: &ConfigurationStats,
        base: usize,
        b: &ConfigurationStats,
    ) -> Row {
        let configuration = &self.plan.configurations[c];
        let ratio = |x: &Jack, y: &Jack| x.ratio(y).log_interval();
        let optional = |x: &Option<Jack>, y: &Option<Jack>| match (x, y) {
            (Some(x), Some(y)) => Some(ratio(x, y)),
            _ => None,
        };
        let paper_efficiency = match (&s.sampling_variance_estimate, &b.sampling_variance_estimate)
        {
            (Some(x), Some(y)) => {
                let inputs = [y, &b.cpu_time, x, &s.cpu_time];
                Some(Jack::combine(&inputs, |v| (v[0] * v[1]) / (v[2] * v[3])).log_interval())
            }
            _ => None,
        };
        let median_variance =
            median_variance_ratio(&self.runs_of(c, k), &self.runs_of(base, k), s, b).log_interval();
        let interval = |j: &Option<Jack>| j.as_ref().map(Jack::interval);
        Row {
            configuration: c,
            label: configuration.label.clone(),
            kind: configuration.choice.spec.kind.clone(),
            samples: configuration.samples,
            runs: k,
            cpu_time: s.cpu_time.interval(),
            wall_time: s.wall_time,
            relative_variance: s.relative_variance.log_interval(),
            variance: s.variance.log_interval(),
            relative_variance_top: s.relative_variance_top,
            variance_top: s.variance_top,
            relative_mse: s.relative_mse.interval(),
            delta_e: s.delta_e.interval(),
            sampling_variance: s.sampling_variance.as_ref().map(Jack::log_interval),
            sampling_variance_estimate: s
                .sampling_variance_estimate
                .as_ref()
                .map(Jack::log_interval),
            sampling_variance_median: interval(&s.sampling_variance_median),
            bsdf_fraction: interval(&s.bsdf_fraction),
            alpha_median: interval(&s.alpha_median),
            efficiency: s.efficiency().log_interval(),
            z: s.z(&self.context),
            ratios: Ratios {
                relative_variance: ratio(&s.relative_variance, &b.relative_variance),
                median_variance,
                variance: ratio(&s.variance, &b.variance),
                relative_mse: ratio(&s.relative_mse, &b.relative_mse),
                delta_e: ratio(&s.delta_e, &b.delta_e),
                sampling_variance: optional(&s.sampling_variance, &b.sampling_variance),
                sampling_variance_estimate: optional(
                    &s.sampling_variance_estimate,
                    &b.sampling_variance_estimate,
                ),
                cpu_time: ratio(&s.cpu_time, &b.cpu_time),
                efficiency: ratio(&s.efficiency(), &b.efficiency()),
                paper_efficiency,
            },
        }
    }

    fn panel(&self) -> Option<PanelImages> {
        let plan = &self.plan;
        let first = |c: usize| self.runs[c].first()?.as_ref();
        let balance_configuration = *plan.panel.first()?;
        let balance = first(balance_configuration)?.image.clone()?;
        let alpha = plan.panel.get(1).and_then(|&c| {
            let run = first(c)?;
            Some((
                plan.configurations[c].label.clone(),
                run.image.clone()?,
                run.alpha.clone(),
            ))
        });
        Some(PanelImages {
            samples: plan.configurations[balance_configuration].samples,
            balance,
            alpha,
        })
    }
}

/// Reads one integrator's curve against the balance heuristic's: time to the target error,
/// speed-up there, and the error ratio at the target time, each a function of both curves'
/// statistics (so their intervals carry the noise of both); and the speed-up over the headline
/// α's curve at the same target, from all three.
fn trade(
    integrator: usize,
    label: &str,
    curve: &[&ConfigurationStats],
    balance: &[&ConfigurationStats],
    headline: Option<&[&ConfigurationStats]>,
    target_error: f64,
    target_time: f64,
) -> Trade {
    let n = curve.len();
    // Inputs: ln t and ln e at each budget, this curve's, then balance's, then the headline's.
    let logs: Vec<Jack> = curve
        .iter()
        .chain(balance)
        .chain(headline.unwrap_or_default())
        .flat_map(|s| [s.cpu_time.map(f64::ln), s.relative_variance.map(f64::ln)])
        .collect();
    let inputs: Vec<&Jack> = logs.iter().collect();
    // (ln t, ln e) of curve `which` (0: this one, 1: balance) from the inputs' values `v`.
    let points = |v: &[f64], which: usize| -> Vec<(f64, f64)> {
        (0..n)
            .map(|j| (v[(which * n + j) * 2], v[(which * n + j) * 2 + 1]))
            .collect()
    };
    let (ln_error, ln_time) = (target_error.ln(), target_time.ln());
    let log_or_nan = |r: Option<Reach>| r.map_or(f64::NAN, Reach::log);
    // The log time at which curve `which` reaches the target error.
    let time_at = |v: &[f64], which: usize| log_or_nan(reach(&points(v, which), ln_error));
    // The log error of curve `which` at the target time.
    let error_at = |v: &[f64], which: usize| {
        let swapped: Vec<(f64, f64)> = points(v, which).into_iter().map(|(t, e)| (e, t)).collect();
        log_or_nan(reach(&swapped, ln_time))
    };
    let values: Vec<f64> = logs.iter().map(|j| j.value).collect();
    // Where `log_time` lies against the measured times of curve `which`.
    let extent = |which: usize, log_time: f64| -> Extent {
        let log_times: Vec<f64> = (0..n).map(|j| values[2 * (which * n + j)]).collect();
        Extent::of(&log_times, log_time)
    };
    let reading = |log_time: f64, f: &dyn Fn(&[f64]) -> f64| {
        log_time.is_finite().then(|| Reading {
            estimate: Jack::combine(&inputs, f).log_interval(),
            extent: extent(0, log_time),
        })
    };
    let own = time_at(&values, 0);
    let has_target = error_at(&values, 0);
    // Over the headline: read where both curves reach the target, as far out as the farther.
    let speedup_over_headline = headline.and_then(|_| {
        let headline_time = time_at(&values, 2);
        if !headline_time.is_finite() {
            return None;
        }
        match extent(2, headline_time) {
            // Where α's own time is only a bound, so is the ratio: none is given.
            Extent::Beyond { .. } => None,
            headline_extent => {
                reading(own, &|v| (time_at(v, 2) - time_at(v, 0)).exp()).map(|r| Reading {
                    extent: r.extent.farther(headline_extent),
                    ..r
                })
            }
        }
    });
    Trade {
        integrator,
        label: label.to_string(),
        time_to_target: reading(own, &|v| time_at(v, 0).exp()),
        speedup: reading(own, &|v| (time_at(v, 1) - time_at(v, 0)).exp()),
        speedup_over_headline,
        equal_time_ratio: if has_target.is_finite() {
            reading(ln_time, &|v| (error_at(v, 0) - error_at(v, 1)).exp())
        } else {
            None
        },
    }
}

/// The lower envelope of the curves' point estimates in log-log, as stretches of CPU time
/// each owned by one integrator.
fn pareto_front(curves: &[Curve]) -> Vec<FrontSegment> {
    let logs: Vec<Vec<(f64, f64)>> = curves
        .iter()
        .map(|c| {
            c.points
                .iter()
                .map(|p| (p.cpu_time.value.ln(), p.relative_variance.value.ln()))
                .filter(|p| p.0.is_finite() && p.1.is_finite())
                .collect()
        })
        .collect();
    let (lo, hi) = logs
        .iter()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.0), b.max(p.0))
        });
    if lo.partial_cmp(&hi) != Some(std::cmp::Ordering::Less) {
        return Vec::new();
    }
    // Error of a curve at log time x: interpolated within its measured times, and beyond its
    // largest its lowest measured error (what that much time buys at least), so that a curve
    // whose ladder ends early is not left out of the front where slower ones continue.
    let at = |points: &[(f64, f64)], x: f64| -> Option<f64> {
        let last = points.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
        if x > last {
            return points.iter().map(|p| p.1).min_by(f64::total_cmp);
        }
        points.windows(2).find_map(|w| {
            let ((x0, y0), (x1, y1)) = (w[0], w[1]);
            let (a, b) = (x0.min(x1), x0.max(x1));
            (a <= x && x <= b).then(|| {
                if x1 == x0 {
                    y0.min(y1)
                } else {
                    y0 + (x - x0) * (y1 - y0) / (x1 - x0)
                }
            })
        })
    };
    const STEPS: usize = 400;
    let mut front: Vec<FrontSegment> = Vec::new();
    for s in 0..=STEPS {
        let x = lo + (hi - lo) * s as f64 / STEPS as f64;
        let best = logs
            .iter()
            .enumerate()
            .filter_map(|(i, p)| Some((i, at(p, x)?)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((i, _)) = best else { continue };
        let t = x.exp();
        match front.last_mut() {
            Some(last) if last.label == curves[i].label => last.to = t,
            _ => front.push(FrontSegment {
                label: curves[i].label.clone(),
                from: t,
                to: t,
            }),
        }
    }
    front
}
