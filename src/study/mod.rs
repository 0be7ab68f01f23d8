//! `lumis study`: measures the speed/accuracy trade of integrators on scenes (docs/study.md).
//!
//! A study is **planned**, **run** and **collected**:
//!
//! - [`plan`]: per scene, the integrator configurations (each integrator at each budget of the
//!   ladder, the paper's configurations, the sweeps' points) and the *cells* that measure them,
//!   one render each (a configuration and a seed, or a shard of the reference), in a
//!   deterministic order;
//! - [`cell`]: running a cell gives a plain, serialisable [`CellResult`];
//! - [`collect`]: the report is a pure function of the plan, the reference and the results,
//!   including the choice of K by the rule that grows it (so a study whose cells ran anywhere,
//!   in any order, collects to the same numbers).
//!
//! [`run`] runs the three in one process: per scene, the reference (cached, [`reference`]),
//! then rounds of runs (K₀, 2K₀, … until the headline ratio is precise enough), then the
//! scene's tables ([`report`]), plots and panel, written as each scene finishes. Statistics and
//! their intervals are in [`stats`] and [`summary`].
//!
//! [`plan`], [`run_planned_cell`] and [`collect`] (in `distributed.rs`) do the same in separate
//! processes, through a directory ([`store`]): the plan lists every cell of every round up to
//! the cap of K (which cannot be known before the cells run), each cell runs anywhere (a SLURM
//! array task) and writes its result, and collect applies the K rule to the results, so that it
//! reports the K and the numbers of the local run (docs/distributed.md).

pub mod cell;
pub mod collect;
pub mod config;
mod distributed;
pub mod metrics;
/// The panels of images: renders, their error maps and α.
pub mod panel;
pub mod paper;
pub mod plan;
/// The plots of error against time and budget, and their axes.
pub mod plots;
pub mod reference;
pub mod report;
pub mod stats;
pub mod store;
pub mod summary;

pub use cell::{CellResult, Interrupted};
pub use config::{
    Choice, DEFAULT_BUDGETS, DEFAULT_INTEGRATORS, ReferenceSource, StudyConfig, Sweeps,
};
pub use distributed::{collect, plan, run_planned_cell, slurm_script};

use anyhow::{Context as _, Result};
use collect::Collector;
pub use collect::SceneAnalysis;
use indicatif::ProgressBar;
use lumis_core::output::Window;
use lumis_core::scene::load::load_scene;
use plan::{Cell, ScenePlan, plan_scene};
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// How a study tells its progress: a bar on a terminal, and a line per finished run and scene
/// (above the bar, or alone when stderr is not a terminal) unless quiet.
pub struct Progress {
    pub bar: ProgressBar,
    pub lines: bool,
}

impl Progress {
    /// No progress at all.
    pub fn quiet() -> Self {
        Progress {
            bar: ProgressBar::hidden(),
            lines: false,
        }
    }

    fn line(&self, text: String) {
        if !self.lines {
            return;
        }
        if self.bar.is_hidden() {
            eprintln!("{text}");
        } else {
            self.bar.println(text);
        }
    }
}

/// Runs a study: every scene's reference, rounds of runs and report, and returns the finished
/// scenes' analyses (whose tables are [`report::results_table`] and [`report::trade_table`]);
/// stops at the next packet of camera samples once `cancel` is set, after writing what it has (the
/// finished scenes, and the current one with its complete runs).
pub fn run(
    config: &StudyConfig,
    progress: &Progress,
    cancel: &AtomicBool,
) -> Result<Vec<SceneAnalysis>> {
    let (plans, _) = plan_study(config)?;
    plots::register_font()?;
    std::fs::create_dir_all(&config.out)
        .with_context(|| format!("cannot create `{}`", config.out.display()))?;
    // Progress in samples per light per pixel: the references and the first round (later
    // rounds are added when they start).
    let first_round: u64 = plans
        .iter()
        .map(|p| {
            let cells = p
                .reference_cells()
                .into_iter()
                .chain(p.cells(1..=config.runs, true));
            cells.map(|c| p.cost(&c)).sum::<u64>()
        })
        .sum();
    progress.bar.set_length(first_round);
    let start = Instant::now();
    let mut finished: Vec<SceneAnalysis> = Vec::new();
    for plan in plans {
        let result = study_scene(config, plan, progress, cancel, &mut finished);
        if let Err(e) = result {
            if e.downcast_ref::<Interrupted>().is_some() {
                write_study(config, &finished)?;
            }
            return Err(e);
        }
        write_study(config, &finished)?;
        progress.line(format!(
            "study: {} of {} scenes done in {:.0} s",
            finished.len(),
            config.scenes.len(),
            start.elapsed().as_secs_f64()
        ));
    }
    progress.bar.finish_and_clear();
    Ok(finished)
}

/// Renders one scene's reference and runs, and adds its analysis to `finished`.
fn study_scene(
    config: &StudyConfig,
    plan: ScenePlan,
    progress: &Progress,
    cancel: &AtomicBool,
    finished: &mut Vec<SceneAnalysis>,
) -> Result<()> {
    let name = plan.name.clone();
    progress.bar.set_message(format!("{name}: loading"));
    let mut loaded = load_study_scene(config, &plan)?;
    let base = plan.path.parent().unwrap_or(Path::new("")).to_path_buf();
    let window = loaded.scene.window;
    let scene = &mut loaded.scene;
    let run = |plan: &ScenePlan, cell: &Cell, scene: &mut lumis_core::scene::Scene| {
        cell::run_cell(
            plan,
            cell,
            scene,
            &base,
            config.threads,
            cancel,
            &config.out,
        )
    };

    let reference = match &config.reference {
        ReferenceSource::File(file) => reference::read_file(file, window)?,
        ReferenceSource::Samples(_) => {
            let (reference_plan, entry) = reference_cache_entry(config, &plan, window)?;
            let cells = plan.reference_cells();
            let cost: u64 = cells.iter().map(|c| plan.cost(c)).sum();
            match reference::cached(&entry, window, reference_plan) {
                Some(reference) => {
                    progress.bar.inc(cost);
                    reference
                }
                None => {
                    let mut shards = Vec::new();
                    for (j, cell) in cells.iter().enumerate() {
                        progress.bar.set_message(format!(
                            "{name}: reference shard {}/{}",
                            j + 1,
                            cells.len()
                        ));
                        shards.push(run(&plan, cell, scene)?);
                        progress.bar.inc(plan.cost(cell));
                    }
                    let reference =
                        reference::merge(&shards, reference_plan, &entry, &plan.path, window)?;
                    let unit = if reference_plan.camera_samples.is_some() {
                        "camera samples"
                    } else {
                        "samples per light"
                    };
                    progress.line(format!(
                        "{name}: reference, {} {unit} per pixel, {:.1} s of CPU -> {}",
                        reference_plan.total_samples(),
                        reference.cpu_time.unwrap_or(f64::NAN),
                        entry.file.display()
                    ));
                    reference
                }
            }
        }
    };
    let mut collector = Collector::new(plan, context(config, scene, reference), config);
    let rounds = config.rounds();
    let mut done = 0;
    for (round, &k) in rounds.iter().enumerate() {
        let cells = collector.plan.cells(done + 1..=k, round == 0);
        if round > 0 {
            progress
                .bar
                .inc_length(cells.iter().map(|c| collector.plan.cost(c)).sum());
        }
        let mut cpu = 0.0;
        for (i, cell) in cells.iter().enumerate() {
            let plan::Role::Run {
                configuration,
                run: r,
            } = cell.role
            else {
                continue;
            };
            progress.bar.set_message(format!(
                "{name}: run {r}/{k}, {} N={}",
                collector.plan.configurations[configuration].label,
                collector.plan.configurations[configuration].samples
            ));
            let result = match run(&collector.plan, cell, scene) {
                Ok(result) => result,
                Err(e) => {
                    if e.downcast_ref::<Interrupted>().is_some()
                        && let Some(analysis) = collector.analyse(true)
                    {
                        write_scene(config, &analysis)?;
                        finished.push(analysis);
                    }
                    return Err(e);
                }
            };
            cpu += result.cpu_time;
            collector.add(&result)?;
            progress.bar.inc(collector.plan.cost(cell));
            let last_of_run = cells.get(i + 1).is_none_or(|next| match next.role {
                plan::Role::Run { run, .. } => run != r,
                plan::Role::Shard(_) => true,
            });
            if last_of_run {
                progress.line(format!(
                    "{name}: run {r} of {k} done ({} configurations, {cpu:.1} s of CPU)",
                    cells
                        .iter()
                        .filter(|c| matches!(c.role, plan::Role::Run { run, .. } if run == r))
                        .count()
                ));
                cpu = 0.0;
            }
        }
        done = k;
        if collector.precise_enough(k as usize) {
            break;
        }
    }
    finished.push(finish_scene(config, &collector, progress)?);
    Ok(())
}

/// A scene of a study, loaded with the study's overrides.
fn load_study_scene(
    config: &StudyConfig,
    plan: &ScenePlan,
) -> Result<lumis_core::scene::load::LoadedScene> {
    let mut loaded = load_scene(&plan.path, &config.overrides)?;
    // Rays through pixel centres: runs then differ only in the light and BSDF samples that
    // MIS is about, not in where the pixel is shaded (antialiasing noise no strategy changes).
    loaded.scene.jitter = false;
    Ok(loaded)
}

/// What a scene's statistics are computed against.
fn context(
    config: &StudyConfig,
    scene: &lumis_core::scene::Scene,
    reference: reference::Reference,
) -> summary::Context {
    summary::Context::new(
        reference,
        config.epsilon,
        config.block,
        scene.exposure.exp2(),
        scene.window.width,
        scene.window.height,
    )
}

/// The analysis of a scene whose runs are all in `collector`, its progress line, its plots and
/// panel.
fn finish_scene(
    config: &StudyConfig,
    collector: &Collector,
    progress: &Progress,
) -> Result<SceneAnalysis> {
    let name = &collector.plan.name;
    let analysis = collector
        .analyse(false)
        .with_context(|| format!("{name}: fewer than 3 complete runs"))?;
    if let Some((label, e, met)) = &analysis.headline {
        progress.line(format!(
            "{name}: K = {}: `{label}` / balance relative variance at N = {}: {} [{:.3}, {:.3}]{}",
            analysis.runs,
            analysis.target_budget,
            report::sig(e.value),
            e.lo,
            e.hi,
            if *met {
                ""
            } else {
                " (not within the precision: the cap)"
            }
        ));
    }
    write_scene(config, &analysis)?;
    Ok(analysis)
}

/// Every cell of a scene in index order: the reference's shards (when rendered), then the runs
/// of every round up to the cap of K, run-major (the runs of K₀ of every configuration, then
/// the further runs of the configurations that grow).
fn scene_cells(config: &StudyConfig, plan: &ScenePlan) -> Vec<Cell> {
    let mut cells = plan.reference_cells();
    let mut done = 0;
    for (round, &k) in config.rounds().iter().enumerate() {
        cells.extend(plan.cells(done + 1..=k, round == 0));
        done = k;
    }
    cells
}

/// The plans of a study's scenes and all their cells, in index order.
fn plan_study(config: &StudyConfig) -> Result<(Vec<ScenePlan>, Vec<Cell>)> {
    config.validate()?;
    let plans: Vec<ScenePlan> = config
        .scenes
        .iter()
        .enumerate()
        .map(|(i, path)| plan_scene(config, i, path.clone()))
        .collect::<Result<_>>()?;
    let cells = plans.iter().flat_map(|p| scene_cells(config, p)).collect();
    Ok((plans, cells))
}

/// A scene's rendered reference: its plan and where the study caches it.
fn reference_cache_entry<'a>(
    config: &StudyConfig,
    plan: &'a ScenePlan,
    window: Window,
) -> Result<(&'a plan::ReferencePlan, reference::CacheEntry)> {
    let reference_plan = plan.reference.as_ref().context("a rendered reference")?;
    let entry = reference::cache_entry(
        &config.cache_dir(),
        &plan.path,
        &plan.name,
        window,
        &config.overrides,
        reference_plan,
    )?;
    Ok((reference_plan, entry))
}

/// The outputs of one finished scene: its plots and panel.
fn write_scene(config: &StudyConfig, analysis: &SceneAnalysis) -> Result<()> {
    plots::scene_curves(&config.out, analysis)?;
    panel::write(&config.out, analysis)?;
    Ok(())
}

/// The outputs over all finished scenes: the tables and the plots across scenes.
fn write_study(config: &StudyConfig, scenes: &[SceneAnalysis]) -> Result<()> {
    let labels: Vec<String> = config.integrators.iter().map(|c| c.label.clone()).collect();
    plots::summary(&config.out, scenes, &labels)?;
    plots::sweeps(&config.out, scenes)?;
    report::write_csvs(&config.out, scenes)?;
    report::write_markdown(config, scenes)
}
