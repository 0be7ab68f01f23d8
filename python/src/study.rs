//! `lumis.study`: the CLI's `lumis study` run from Python, returning its tables as values.
//!
//! The study runs on a Rust thread with the GIL released ([`crate::beside_python`]), exactly as
//! `lumis study` runs (same configuration, same output directory and files); the calling thread
//! handles Python signals (Ctrl-C stops the study at the next camera sample) and reports progress. The tables are
//! [`report::results_table`] and [`report::trade_table`], the ones `results.csv` and
//! `trade.csv` print, so the returned values and the files cannot disagree.

use crate::{LumisError, beside_python, convert, scene_error};
use lumis::study::report::{self, Field, Table};
use lumis::study::{
    Interrupted, Progress, ReferenceSource, SceneAnalysis, StudyConfig, Sweeps, config,
};
use pyo3::exceptions::{PyKeyboardInterrupt, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};
use std::path::PathBuf;

/// A comma-separated string or a sequence of strings (`"balance,alpha"` or `["balance", "alpha"]`).
fn list_text(object: &Bound<'_, PyAny>, name: &str) -> PyResult<String> {
    if object.is_instance_of::<PyString>() {
        return object.extract();
    }
    let items: Vec<Bound<'_, PyAny>> = object
        .try_iter()
        .map_err(|_| PyTypeError::new_err(format!("{name}: a string or a list of strings")))?
        .collect::<PyResult<_>>()?;
    let texts = items
        .iter()
        .map(|item| item.str().map(|s| s.to_string()))
        .collect::<PyResult<Vec<_>>>()?;
    Ok(texts.join(","))
}

fn value_error(e: anyhow::Error) -> PyErr {
    PyValueError::new_err(format!("{e:#}"))
}

/// Runs a study as `lumis study` does (docs/study.md) and returns its tables.
///
/// Writes the same files into `out` (results.csv, trade.csv, results.md, plots, panels, the
/// reference cache). Arguments are the CLI's options in snake_case; lists may be Python lists
/// or comma-separated strings. progress: called as progress(done, total, message) as the study
/// advances (done and total count samples per light per pixel). Ctrl-C stops the study at the
/// next camera sample and raises KeyboardInterrupt (the finished scenes are written). Returns a
/// dict with "results", "trade" and "curves" (each a list of dicts, one per record), "out" and
/// "report" (paths); `lumis.study` wraps it in a `lumis.Study`.
#[pyfunction(name = "_study")]
#[pyo3(signature = (
    scenes, out, *, integrators=None, budgets=None, target_budget=None, runs=None,
    max_runs=None, precision=None, reference=None, reference_samples=None, cache_dir=None,
    paper_pilots=false, sweeps=None, sweep_budget=None, block=None, epsilon=None,
    overrides=None, threads=None, seed=None, report=None, notes=None, progress=None,
))]
#[allow(clippy::too_many_arguments)]
pub fn study<'py>(
    py: Python<'py>,
    scenes: Vec<PathBuf>,
    out: PathBuf,
    integrators: Option<&Bound<'py, PyAny>>,
    budgets: Option<&Bound<'py, PyAny>>,
    target_budget: Option<u32>,
    runs: Option<u32>,
    max_runs: Option<u32>,
    precision: Option<f64>,
    reference: Option<PathBuf>,
    reference_samples: Option<u32>,
    cache_dir: Option<PathBuf>,
    paper_pilots: bool,
    sweeps: Option<&Bound<'py, PyAny>>,
    sweep_budget: Option<u32>,
    block: Option<u32>,
    epsilon: Option<f64>,
    overrides: Option<&Bound<'py, PyAny>>,
    threads: Option<usize>,
    seed: Option<u64>,
    report: Option<PathBuf>,
    notes: Option<PathBuf>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    crate::guarded(|| {
        if scenes.is_empty() {
            return Err(PyValueError::new_err(
                "scenes: give at least one scene file",
            ));
        }
        let mut config = StudyConfig::new(scenes, out).map_err(value_error)?;
        if let Some(list) = integrators {
            config.integrators =
                config::parse_integrators(&list_text(list, "integrators")?).map_err(value_error)?;
        }
        if let Some(list) = budgets {
            config.budgets =
                config::parse_budgets(&list_text(list, "budgets")?).map_err(value_error)?;
        }
        config.target_budget = target_budget;
        config.runs = runs.unwrap_or(config.runs);
        config.max_runs = max_runs.unwrap_or(config.max_runs.max(config.runs));
        config.precision = precision.unwrap_or(config.precision);
        config.reference = match (reference, reference_samples) {
            (Some(_), Some(_)) => {
                return Err(PyValueError::new_err(
                    "give reference (an image) or reference_samples (a rendered reference), not both",
                ));
            }
            (Some(file), None) => ReferenceSource::File(file),
            (None, Some(samples)) => ReferenceSource::Samples(samples),
            (None, None) => config.reference.clone(),
        };
        config.cache_dir = cache_dir;
        config.paper_pilots = paper_pilots;
        if let Some(list) = sweeps {
            config.sweeps = Sweeps::parse(&list_text(list, "sweeps")?).map_err(value_error)?;
        }
        config.sweep_budget = sweep_budget;
        config.block = block.unwrap_or(config.block);
        config.epsilon = epsilon.unwrap_or(config.epsilon);
        if let Some(o) = overrides {
            config.overrides = convert::overrides(o)?;
        }
        config.threads = threads.unwrap_or(0);
        config.seed = seed.unwrap_or(config.seed);
        config.report = report;
        config.notes = notes;
        config.command = Some("lumis.study(...) from Python".into());
        // Checked here, before the thread starts, so that mistakes raise at once.
        config.validate().map_err(value_error)?;

        let analyses = run(py, config.clone(), progress.as_ref())?;
        let result = PyDict::new(py);
        result.set_item("results", records(py, &report::results_table(&analyses))?)?;
        result.set_item("trade", records(py, &report::trade_table(&analyses))?)?;
        result.set_item("curves", curves(py, &analyses)?)?;
        result.set_item("out", config.out.clone())?;
        result.set_item("report", config.report_path())?;
        Ok(result)
    })
}

/// Runs the study on its own thread, reporting progress meanwhile.
fn run(
    py: Python<'_>,
    config: StudyConfig,
    callback: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<SceneAnalysis>> {
    // A hidden bar still counts: the calling thread reads its position for `callback`.
    let bar = indicatif::ProgressBar::hidden();
    let progress = Progress {
        bar: bar.clone(),
        lines: false,
    };
    let mut reported = None;
    let mut report = || -> PyResult<()> {
        let Some(callback) = callback else {
            return Ok(());
        };
        let now = (bar.position(), bar.length().unwrap_or(0), bar.message());
        if reported.as_ref() != Some(&now) {
            callback.call1(now.clone())?;
            reported = Some(now);
        }
        Ok(())
    };
    let outcome = beside_python(
        py,
        "lumis-study",
        move |cancel, _| lumis::study::run(&config, &progress, cancel),
        &mut report,
        |_| Ok(true),
    )?;
    match outcome {
        Ok(analyses) => {
            // The last state too, so that a finished study always reports done == total.
            report()?;
            Ok(analyses)
        }
        Err(e) if e.downcast_ref::<Interrupted>().is_some() => {
            Err(PyKeyboardInterrupt::new_err(e.to_string()))
        }
        Err(e) => match e.downcast_ref::<lumis::error::SceneError>() {
            Some(scene) => Err(scene_error(py, scene)),
            None => Err(LumisError::new_err(format!("{e:#}"))),
        },
    }
}

fn field<'py>(py: Python<'py>, field: &Field) -> PyResult<Bound<'py, PyAny>> {
    Ok(match field {
        Field::Text(text) => text.into_pyobject(py)?.into_any(),
        Field::Count(n) => n.into_pyobject(py)?.into_any(),
        Field::Number(v) | Field::Fixed(v, _) | Field::Decimal(v) => {
            v.into_pyobject(py)?.into_any()
        }
        Field::Missing => py.None().into_bound(py),
    })
}

/// A table as a list of dicts, one per record, keyed by column.
fn records<'py>(py: Python<'py>, table: &Table) -> PyResult<Bound<'py, PyList>> {
    let list = PyList::empty(py);
    for record in &table.records {
        let dict = PyDict::new(py);
        for (column, value) in table.columns.iter().zip(record) {
            dict.set_item(column, field(py, value)?)?;
        }
        list.append(dict)?;
    }
    Ok(list)
}

/// Every integrator's curve: per scene, integrator and budget, CPU time and errors with their
/// 95 % intervals (the points the study's `*_curves.png` plot).
fn curves<'py>(py: Python<'py>, analyses: &[SceneAnalysis]) -> PyResult<Bound<'py, PyList>> {
    let list = PyList::empty(py);
    for analysis in analyses {
        for curve in &analysis.curves {
            for point in &curve.points {
                let dict = PyDict::new(py);
                dict.set_item("scene", &analysis.name)?;
                dict.set_item("integrator", &curve.label)?;
                dict.set_item("samples", point.samples)?;
                for (name, e) in [
                    ("cpu_time", &point.cpu_time),
                    ("relative_variance", &point.relative_variance),
                    ("relative_mse", &point.relative_mse),
                ] {
                    dict.set_item(name, e.value)?;
                    dict.set_item(format!("{name}_lo"), e.lo)?;
                    dict.set_item(format!("{name}_hi"), e.hi)?;
                }
                list.append(dict)?;
            }
        }
    }
    Ok(list)
}
