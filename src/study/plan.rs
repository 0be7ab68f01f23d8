//! The plan of a study: per scene, the integrator configurations it measures (each integrator at
//! each budget of the ladder, the paper's configurations, the sweeps' points) and the *cells*
//! that measure them. A cell is one render: a configuration (or a reference shard) with one
//! seed. The plan is a pure function of the configuration; its cells come in a deterministic
//! order, so that a study split across processes (each running some cells) and merged gives
//! the same results as one process running them all.
//!
//! Runs are seed-major: the cells of run k of every configuration come before those of run
//! k + 1, so slow drifts of the machine's speed hit every configuration alike, and a study
//! interrupted after k runs has k complete runs of everything.

use super::config::{
    Choice, InPasses, PAPER_BUDGET, PAPER_PREPROCESSED_PILOT, ReferenceSource, StudyConfig,
};
use anyhow::Result;
use lumis_core::scene::description::PluginSpec;
use lumis_integrators::{alpha, balance};
use ron::Value;
use serde::{Deserialize, Serialize};
use std::ops::RangeInclusive;
use std::path::PathBuf;

/// Independent runs whose mean is a rendered reference: their spread gives each reference
/// pixel's own variance.
pub const REFERENCE_SHARDS: u32 = 16;
/// Seeds of the reference's shards start here (above any run's seed).
const REFERENCE_SEED_OFFSET: u64 = 1_000_003;
/// Sizes s of the clamping interval [½ − s/2, ½ + s/2] in the clamp sweep (paper Figure 2).
pub const CLAMP_SIZES: [f64; 8] = [0.0, 0.2, 0.4, 0.6, 0.8, 0.9, 0.95, 1.0];
/// M as fractions of N in the M sweep (paper Figure 7).
pub const ALPHA_SAMPLE_FRACTIONS: [f64; 6] = [1.0 / 32.0, 1.0 / 16.0, 0.125, 0.25, 0.5, 0.75];
/// N as multiples of M = N/4 in the convergence sweep (paper Figures 3 and 4).
pub const CONVERGENCE_MULTIPLES: [u32; 4] = [1, 2, 4, 8];

/// One integrator configuration at one budget.
#[derive(Clone, Debug)]
pub struct Configuration {
    /// The row's label: the integrator as the user wrote it, or a sweep point's.
    pub label: String,
    pub choice: Choice,
    /// The budget: N, samples per light per camera sample, or for a `path` row the camera
    /// samples per pixel.
    pub samples: u32,
    /// Camera samples per pixel, when the study sets them (`path` rows: the budget).
    pub camera_samples: Option<u32>,
    /// The plugin spec rendered: `samples` and the study's AOV layers set.
    pub spec: PluginSpec,
    /// Part of the curves: its runs grow with the K rule (the others keep K₀).
    pub grows: bool,
}

impl Configuration {
    fn key(&self) -> String {
        format!(
            "{}{}{:?}{:?}",
            self.spec.kind,
            ron::to_string(&self.spec.params).unwrap_or_default(),
            self.choice.in_passes,
            self.camera_samples
        )
    }
}

/// The sweeps of α's parameters (paper Figures 2, 7, 3 and 4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Sweep {
    Clamp,
    #[serde(rename = "m")]
    AlphaSamples,
    #[serde(rename = "n")]
    Convergence,
}

impl Sweep {
    pub fn name(self) -> &'static str {
        match self {
            Sweep::Clamp => "clamp",
            Sweep::AlphaSamples => "m",
            Sweep::Convergence => "n",
        }
    }
}

/// One point of a sweep: a configuration and the balance heuristic's at the same budget.
#[derive(Clone, Debug)]
pub struct SweepPoint {
    pub sweep: Sweep,
    /// The swept value: the clamping interval's size, M, or N.
    pub x: f64,
    pub configuration: usize,
    pub balance: usize,
}

/// What a cell renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Role {
    /// Shard j of the reference (the baseline, its own seed).
    Shard(u32),
    /// Run k ≥ 1 of a configuration.
    Run { configuration: usize, run: u32 },
}

/// One render of a study.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Cell {
    /// Index of the scene in the study's list.
    pub scene: usize,
    pub role: Role,
    /// The scene's seed for this render.
    pub seed: u64,
}

/// How a scene's reference is rendered: `shards` runs of the baseline with
/// `samples_per_shard` samples per light per pixel each (camera samples per pixel for `path`).
#[derive(Clone, Debug)]
pub struct ReferencePlan {
    pub shards: u32,
    pub samples_per_shard: u32,
    pub spec: PluginSpec,
    /// Camera samples per pixel of a shard, when the study sets them (`path`).
    pub camera_samples: Option<u32>,
}

impl ReferencePlan {
    pub fn total_samples(&self) -> u32 {
        self.shards * self.samples_per_shard
    }
}

/// Everything measured on one scene.
#[derive(Clone, Debug)]
pub struct ScenePlan {
    pub index: usize,
    pub path: PathBuf,
    /// The scene's file stem: its name in tables and file names.
    pub name: String,
    pub configurations: Vec<Configuration>,
    /// The integrators of the curves, in the order given.
    pub integrators: Vec<Choice>,
    pub budgets: Vec<u32>,
    /// `curves[i][j]`: the configuration of integrator i at budget j.
    pub curves: Vec<Vec<usize>>,
    /// Index of the baseline among the integrators ([`StudyConfig::baseline`]): `balance`, or
    /// `path:weighting=balance`.
    pub balance: usize,
    /// Index of the integrator the K rule watches ([`StudyConfig::headline`]), if any.
    pub headline: Option<usize>,
    /// Index of the target budget in `budgets`.
    pub target: usize,
    /// Configurations at the paper's budget (N = 256) compared with its tables.
    pub paper: Vec<usize>,
    pub sweeps: Vec<SweepPoint>,
    /// Configurations whose first run's image the panel shows: balance and the headline α at
    /// the target budget.
    pub panel: Vec<usize>,
    /// `None` when the reference is a file.
    pub reference: Option<ReferencePlan>,
    /// The first run's seed is `seed + 1`.
    pub seed: u64,
}

/// Plans one scene of a study.
pub fn plan_scene(config: &StudyConfig, index: usize, path: PathBuf) -> Result<ScenePlan> {
    let name = path.file_stem().map_or_else(
        || path.display().to_string(),
        |s| s.to_string_lossy().into(),
    );
    let baseline = config.baseline()?;
    // The reference is the baseline's image, rendered at once rather than in passes.
    let reference_choice = Choice {
        in_passes: None,
        ..config.integrators[baseline].clone()
    };
    let mut plan = ScenePlan {
        index,
        path,
        name,
        configurations: Vec::new(),
        integrators: config.integrators.clone(),
        budgets: config.budgets.clone(),
        curves: Vec::new(),
        balance: baseline,
        headline: config.headline_index(),
        target: config
            .budgets
            .iter()
            .position(|&b| b == config.target_budget())
            .unwrap_or(0),
        paper: Vec::new(),
        sweeps: Vec::new(),
        panel: Vec::new(),
        reference: match config.reference {
            ReferenceSource::File(_) => None,
            ReferenceSource::Samples(s) => {
                let samples_per_shard = s.div_ceil(REFERENCE_SHARDS).max(2);
                Some(ReferencePlan {
                    shards: REFERENCE_SHARDS,
                    samples_per_shard,
                    spec: reference_choice
                        .spec_at(samples_per_shard)
                        .map(|mut spec| {
                            // The reference needs its colours only.
                            spec.params.remove(lumis_integrators::mis::AOVS);
                            spec
                        })?,
                    camera_samples: reference_choice.camera_samples(samples_per_shard),
                })
            }
        },
        seed: config.seed,
    };
    for choice in &config.integrators {
        let row = config
            .budgets
            .iter()
            .map(|&n| plan.add(choice.clone(), choice.label.clone(), n, true))
            .collect::<Result<Vec<_>>>()?;
        plan.curves.push(row);
    }
    let target = config.target_budget();
    plan.panel.push(plan.curves[plan.balance][plan.target]);
    if let Some(h) = plan.headline {
        plan.panel.push(plan.curves[h][plan.target]);
    }
    if let Some(j) = config.budgets.iter().position(|&b| b == PAPER_BUDGET) {
        plan.paper = plan.curves.iter().map(|row| row[j]).collect();
    }
    if config.paper_pilots {
        let label = format!("alpha:mode=preprocessed:alpha_samples={PAPER_PREPROCESSED_PILOT}");
        let choice = Choice::parse(&label)?;
        let paper = plan.add(choice, label, PAPER_BUDGET, false)?;
        if !plan.paper.contains(&paper) {
            plan.paper.push(paper);
        }
    }
    plan_sweeps(config, &mut plan)?;
    debug_assert!(plan.budgets.contains(&target));
    Ok(plan)
}

fn plan_sweeps(config: &StudyConfig, plan: &mut ScenePlan) -> Result<()> {
    let n = config.sweep_budget();
    let number = |v: f64| Value::Number(v.into());
    let count = |m: u32| Value::Number(u64::from(m).into());
    let balance = Choice::parse(balance::NAME)?;
    if config.sweeps.clamp {
        let base = plan.add(balance.clone(), balance::NAME.into(), n, false)?;
        for size in CLAMP_SIZES {
            let (lo, hi) = (0.5 - size / 2.0, 0.5 + size / 2.0);
            let clamp = Value::Seq(vec![number(lo), number(hi)]);
            let label = format!("alpha:clamp=({lo},{hi})");
            let choice = Choice::with_params(label.clone(), alpha::NAME, &[(alpha::CLAMP, clamp)]);
            let configuration = plan.add(choice, label, n, false)?;
            plan.sweeps.push(SweepPoint {
                sweep: Sweep::Clamp,
                x: size,
                configuration,
                balance: base,
            });
        }
    }
    if config.sweeps.alpha_samples {
        let base = plan.add(balance.clone(), balance::NAME.into(), n, false)?;
        let mut counts: Vec<u32> = ALPHA_SAMPLE_FRACTIONS
            .iter()
            .map(|f| ((n as f64 * f).round() as u32).max(2))
            .filter(|&m| m < n)
            .collect();
        counts.dedup();
        for m in counts {
            let label = format!("alpha:alpha_samples={m}");
            let choice = Choice::with_params(
                label.clone(),
                alpha::NAME,
                &[(alpha::ALPHA_SAMPLES, count(m))],
            );
            let configuration = plan.add(choice, label, n, false)?;
            plan.sweeps.push(SweepPoint {
                sweep: Sweep::AlphaSamples,
                x: m as f64,
                configuration,
                balance: base,
            });
        }
    }
    if config.sweeps.convergence {
        let m = (n / 4).max(1);
        for multiple in CONVERGENCE_MULTIPLES {
            let samples = m * multiple;
            let label = format!("alpha:alpha_samples={m}");
            let choice = Choice::with_params(
                label.clone(),
                alpha::NAME,
                &[(alpha::ALPHA_SAMPLES, count(m))],
            );
            let configuration = plan.add(choice, label, samples, false)?;
            let base = plan.add(balance.clone(), balance::NAME.into(), samples, false)?;
            plan.sweeps.push(SweepPoint {
                sweep: Sweep::Convergence,
                x: samples as f64,
                configuration,
                balance: base,
            });
        }
    }
    Ok(())
}

impl ScenePlan {
    /// Adds a configuration, or finds the identical one already planned (its label and
    /// growth are kept, growth widened if this one grows).
    fn add(&mut self, choice: Choice, label: String, samples: u32, grows: bool) -> Result<usize> {
        let spec = choice.spec_at(samples)?;
        let configuration = Configuration {
            label,
            camera_samples: choice.camera_samples(samples),
            choice,
            samples,
            spec,
            grows,
        };
        let key = configuration.key();
        if let Some(i) = self.configurations.iter().position(|c| c.key() == key) {
            self.configurations[i].grows |= grows;
            return Ok(i);
        }
        self.configurations.push(configuration);
        Ok(self.configurations.len() - 1)
    }

    /// The cells of runs `runs` (1-based, inclusive): of every configuration if `all`, of the
    /// growing ones (the curves) otherwise; run-major.
    pub fn cells(&self, runs: RangeInclusive<u32>, all: bool) -> Vec<Cell> {
        let mut cells = Vec::new();
        for run in runs {
            for (configuration, c) in self.configurations.iter().enumerate() {
                if all || c.grows {
                    cells.push(Cell {
                        scene: self.index,
                        role: Role::Run { configuration, run },
                        seed: self.seed + u64::from(run),
                    });
                }
            }
        }
        cells
    }

    /// The cells of the reference's shards (none when the reference is a file).
    pub fn reference_cells(&self) -> Vec<Cell> {
        let shards = self.reference.as_ref().map_or(0, |r| r.shards);
        (0..shards)
            .map(|j| Cell {
                scene: self.index,
                role: Role::Shard(j),
                seed: self.seed + REFERENCE_SEED_OFFSET + u64::from(j),
            })
            .collect()
    }

    /// How `cell` is rendered in passes, if it is.
    pub fn in_passes(&self, cell: &Cell) -> Option<InPasses> {
        match cell.role {
            Role::Run { configuration, .. } => self.configurations[configuration].choice.in_passes,
            Role::Shard(_) => None,
        }
    }

    /// Camera samples per pixel of `cell`, when the study sets them (`None`: the scene's own,
    /// or the passes' for a render in passes).
    pub fn camera_samples(&self, cell: &Cell) -> Option<u32> {
        match cell.role {
            Role::Run { configuration, .. } => self.configurations[configuration].camera_samples,
            Role::Shard(_) => self.reference.as_ref().and_then(|r| r.camera_samples),
        }
    }

    /// The plugin spec a cell renders.
    pub fn spec(&self, cell: &Cell) -> &PluginSpec {
        match cell.role {
            Role::Run { configuration, .. } => &self.configurations[configuration].spec,
            Role::Shard(_) => {
                &self
                    .reference
                    .as_ref()
                    .expect("shards only for rendered references")
                    .spec
            }
        }
    }

    /// The cost of a cell in samples per light per pixel (the pilot included), to weigh
    /// progress.
    pub fn cost(&self, cell: &Cell) -> u64 {
        match cell.role {
            Role::Shard(_) => self.reference.as_ref().map_or(0, |r| r.samples_per_shard) as u64,
            Role::Run { configuration, .. } => {
                let c = &self.configurations[configuration];
                let pilot = match c.choice.string_param(alpha::MODE) {
                    Some(alpha::PREPROCESSED) if c.choice.spec.kind == alpha::NAME => c
                        .choice
                        .int_param(alpha::ALPHA_SAMPLES)
                        .unwrap_or(PAPER_PREPROCESSED_PILOT as u64),
                    _ => 0,
                };
                c.samples as u64 + pilot
            }
        }
    }
}
