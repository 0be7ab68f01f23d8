//! A study in separate processes, through a directory (docs/distributed.md): [`plan`] writes
//! the manifest of every cell, [`run_planned_cell`] runs one cell anywhere and writes its
//! result, [`collect`] reads them all and writes the report a local run writes;
//! [`slurm_script`] submits the cells and the collect step as SLURM jobs.

use super::collect::Collector;
use super::plan::Cell;
use super::store::{self, Manifest};
use super::{
    CellResult, Interrupted, Progress, ReferenceSource, SceneAnalysis, StudyConfig, cell, context,
    finish_scene, load_study_scene, plan_study, plots, reference, reference_cache_entry,
    scene_cells, write_study,
};
use anyhow::{Context as _, Result};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// `lumis study … --plan DIR`: writes the manifest of the study's cells to `dir` (the cells'
/// results go to `dir/cells`). `arguments` are the study's arguments without `--plan` (they
/// plan the same cells again in `directory`); `program` is the executable that runs a cell.
pub fn plan(
    config: &StudyConfig,
    dir: &Path,
    arguments: Vec<String>,
    directory: PathBuf,
    program: &str,
) -> Result<Manifest> {
    let (_, cells) = plan_study(config)?;
    std::fs::create_dir_all(dir.join("cells"))
        .with_context(|| format!("cannot create `{}`", dir.join("cells").display()))?;
    let manifest = Manifest {
        format: store::MANIFEST_FORMAT,
        arguments,
        directory,
        command: format!("{program} study --cell {} INDEX", dir.display()),
        cells,
    };
    manifest.write(dir)?;
    Ok(manifest)
}

/// `lumis study --cell DIR INDEX`: runs cell `index` of the study planned in `dir` (whose
/// arguments gave `config`) and writes its result, or its error beside it.
pub fn run_planned_cell(
    config: &StudyConfig,
    dir: &Path,
    index: usize,
    cancel: &AtomicBool,
) -> Result<CellResult> {
    let manifest = Manifest::read(dir)?;
    let Some(&cell) = manifest.cells.get(index) else {
        anyhow::bail!(
            "cell {index} is not in the plan `{}`: it has cells 0 to {}",
            dir.display(),
            manifest.cells.len().saturating_sub(1)
        );
    };
    let result = run_checked_cell(config, &manifest, dir, index, cell, cancel);
    let error = store::error_path(dir, index);
    match &result {
        Ok(_) => {
            if error.exists() {
                std::fs::remove_file(&error)
                    .with_context(|| format!("cannot remove `{}`", error.display()))?;
            }
        }
        Err(e) if e.downcast_ref::<Interrupted>().is_none() => {
            let text = format!("{e:#}\n");
            lumis_core::image_io::write_atomically(&error, |file| {
                std::io::Write::write_all(file, text.as_bytes()).map_err(|e| e.to_string())
            })?;
        }
        Err(_) => {}
    }
    result
}

fn run_checked_cell(
    config: &StudyConfig,
    manifest: &Manifest,
    dir: &Path,
    index: usize,
    cell: Cell,
    cancel: &AtomicBool,
) -> Result<CellResult> {
    let (plans, cells) = plan_study(config)?;
    if cells != manifest.cells {
        anyhow::bail!(
            "the arguments of `{}` no longer plan its cells (the scenes or the program changed?): plan the study again",
            dir.display()
        );
    }
    let plan = &plans[cell.scene];
    let mut loaded = load_study_scene(config, plan)?;
    let base = plan.path.parent().unwrap_or(Path::new("")).to_path_buf();
    let result = cell::run_cell(
        plan,
        &cell,
        &mut loaded.scene,
        &base,
        config.threads,
        cancel,
        dir,
    )?;
    store::write_cell(&store::cell_path(dir, index), &result)?;
    Ok(result)
}

/// `lumis study --collect DIR`: reads every cell's result of the study planned in `dir`, writes
/// the report the local run writes, and returns the scenes' analyses. Names the missing and the
/// failed cells by index if any.
pub fn collect(
    config: &StudyConfig,
    dir: &Path,
    progress: &Progress,
) -> Result<Vec<SceneAnalysis>> {
    let manifest = Manifest::read(dir)?;
    let (plans, cells) = plan_study(config)?;
    if cells != manifest.cells {
        anyhow::bail!(
            "the arguments of `{}` no longer plan its cells (the scenes or the program changed?)",
            dir.display()
        );
    }
    let (mut missing, mut failed) = (Vec::new(), Vec::new());
    for index in 0..cells.len() {
        if !store::cell_path(dir, index).is_file() {
            if store::error_path(dir, index).is_file() {
                failed.push(index);
            } else {
                missing.push(index);
            }
        }
    }
    if !missing.is_empty() || !failed.is_empty() {
        let mut text = format!(
            "{} of {} cells are not done:",
            missing.len() + failed.len(),
            cells.len()
        );
        if !failed.is_empty() {
            text += &format!(
                " failed: {} (their errors: {}/cells/NNNNNN.error);",
                store::ranges(&failed),
                dir.display()
            );
        }
        if !missing.is_empty() {
            text += &format!(" missing: {};", store::ranges(&missing));
        }
        text += &format!(" run each with `{}`", manifest.command);
        anyhow::bail!(text);
    }
    plots::register_font()?;
    std::fs::create_dir_all(&config.out)
        .with_context(|| format!("cannot create `{}`", config.out.display()))?;
    let mut finished = Vec::new();
    let mut next = 0;
    for plan in plans {
        let count = scene_cells(config, &plan).len();
        let indices = next..next + count;
        next += count;
        let loaded = load_study_scene(config, &plan)?;
        let scene = &loaded.scene;
        let window = scene.window;
        let read = |i: usize| store::read_cell(&store::cell_path(dir, i), &cells[i]);
        let shards = plan.reference_cells().len();
        let reference = match &config.reference {
            ReferenceSource::File(file) => reference::read_file(file, window)?,
            ReferenceSource::Samples(_) => {
                let (reference_plan, entry) = reference_cache_entry(config, &plan, window)?;
                let results = indices
                    .clone()
                    .take(shards)
                    .map(read)
                    .collect::<Result<Vec<_>>>()?;
                reference::merge(&results, reference_plan, &entry, &plan.path, window)?
            }
        };
        let mut collector = Collector::new(plan, context(config, scene, reference), config);
        for i in indices.skip(shards) {
            collector.add(&read(i)?)?;
        }
        finished.push(finish_scene(config, &collector, progress)?);
    }
    write_study(config, &finished)?;
    Ok(finished)
}

/// A shell word: `text` in single quotes.
fn shell_quote(text: &str) -> String {
    format!("'{}'", text.replace('\'', r"'\''"))
}

/// The script `--plan DIR --slurm` writes to `DIR/slurm.sh`: it submits the cells as one job
/// array (at most `throttle` running at once), and the collect step as a job that starts only
/// once every cell has succeeded (`--dependency=afterok`). sbatch's own environment variables
/// (SBATCH_PARTITION, SBATCH_TIMELIMIT, SBATCH_ACCOUNT, …) apply to both.
pub fn slurm_script(manifest: &Manifest, dir: &Path, program: &str, throttle: u32) -> String {
    let last = manifest.cells.len().saturating_sub(1);
    let dir = shell_quote(&dir.display().to_string());
    let program = shell_quote(program);
    format!(
        r#"#!/bin/sh
# Runs the study planned in {dir} on SLURM: its {cells} cells as a job array (at most
# {throttle} at once, LUMIS_CPUS_PER_CELL cores each, default 1), then the collect step once every
# cell has succeeded. A failed cell is named by `lumis study --collect`; re-run it alone with
# `sbatch --array=INDEX ...` (the cells line below) and submit the collect line again.
# Made by `lumis study ... --plan DIR --slurm`.
set -eu
dir={dir}
cpus="${{LUMIS_CPUS_PER_CELL:-1}}"
mkdir -p "$dir/logs"
cells=$(sbatch --parsable --job-name=lumis-cells --array=0-{last}%{throttle} \
    --cpus-per-task="$cpus" --output="$dir/logs/cell-%a.out" \
    --wrap="{program} study --quiet --cell {dir} --threads $cpus")
cells="${{cells%%;*}}"
collect=$(sbatch --parsable --job-name=lumis-collect --dependency=afterok:"$cells" \
    --output="$dir/logs/collect.out" --wrap="{program} study --collect {dir}")
echo "cells: job $cells; collect: job ${{collect%%;*}}"
"#,
        cells = manifest.cells.len(),
    )
}
