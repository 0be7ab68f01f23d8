//! Running one cell: one render of a configuration (or a reference shard) with one seed, and
//! its raw result. The result is a plain value (serialisable): the image, the AOV channels the
//! study reads, and the CPU and wall time; everything the study reports is computed from such
//! results (and the reference) by [`super::collect`].

use super::config::InPasses;
use super::plan::{Cell, ScenePlan};
use anyhow::{Context, Result};
use lumis_core::film::Film;
use lumis_core::integrator::Integrator;
use lumis_core::passes::{Settings, Stopping};
use lumis_core::progressive::{self, Control, Ending, RenderState, Scope};
use lumis_core::scene::Scene;
use lumis_core::scene::load::build_integrator;
use lumis_integrators::aovs;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::atomic::AtomicBool;

/// The AOV channels a cell keeps: `(layer, channel)`.
pub const CHANNELS: [(&str, &str); 5] = [
    (aovs::SAMPLING_VARIANCE, aovs::Y),
    (aovs::SAMPLING_VARIANCE, aovs::ESTIMATE),
    (aovs::ALPHA, aovs::COMBINED),
    (aovs::SAMPLE_COUNTS, aovs::BSDF),
    (aovs::SAMPLE_COUNTS, aovs::LIGHT),
];

/// One AOV channel of a cell's render, per pixel in row order.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Channel {
    /// `layer.channel`, as in the EXR.
    pub name: String,
    pub values: Vec<f32>,
}

/// What one render measured.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CellResult {
    pub cell: Cell,
    pub width: u32,
    pub height: u32,
    /// Linear RGB per pixel, row order.
    pub color: Vec<[f32; 3]>,
    /// The channels of [`CHANNELS`] the integrator declared.
    pub channels: Vec<Channel>,
    /// CPU time of all threads (`CLOCK_PROCESS_CPUTIME_ID`) and wall time of `preprocess` and
    /// the render, seconds.
    pub cpu_time: f64,
    pub wall_time: f64,
}

impl CellResult {
    /// The values of AOV channel `channel` of layer `layer`, if the integrator declared it.
    pub fn channel(&self, layer: &str, channel: &str) -> Option<&[f32]> {
        let name = format!("{layer}.{channel}");
        self.channels
            .iter()
            .find(|c| c.name == name)
            .map(|c| c.values.as_slice())
    }
}

/// A render stopped by the user (Ctrl-C); the study exits with status 130.
#[derive(Debug, thiserror::Error)]
#[error("interrupted: the finished scenes' results are in `{}`", .0.display())]
pub struct Interrupted(pub std::path::PathBuf);

/// Renders `cell` of `plan` on `scene` (loaded from the plan's scene file, jitter off); `base`
/// is the scene's directory, for plugin files.
pub fn run_cell(
    plan: &ScenePlan,
    cell: &Cell,
    scene: &mut Scene,
    base: &Path,
    threads: usize,
    cancel: &AtomicBool,
    out: &Path,
) -> Result<CellResult> {
    let spec = plan.spec(cell);
    let mut integrator = build_integrator(spec, base)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("integrator `{}`", spec.kind))?;
    scene.seed = cell.seed;
    let cpu_start = process_cpu_time();
    let wall_start = std::time::Instant::now();
    let scene_spp = scene.spp;
    let film = render(plan, cell, scene, integrator.as_mut(), threads, cancel);
    scene.spp = scene_spp;
    let film = film?.ok_or_else(|| Interrupted(out.to_path_buf()))?;
    let wall_time = wall_start.elapsed().as_secs_f64();
    let cpu = process_cpu_time() - cpu_start;
    Ok(CellResult {
        cell: *cell,
        width: film.window.width,
        height: film.window.height,
        color: film.color.iter().map(|c| c.to_array()).collect(),
        channels: channels(&film),
        cpu_time: if cpu.is_finite() { cpu } else { wall_time },
        wall_time,
    })
}

/// Renders `cell` (preprocess included) at its camera samples per pixel, at once or in passes;
/// `None` if `cancel` stopped it. Leaves `scene.spp` at the cell's.
fn render(
    plan: &ScenePlan,
    cell: &Cell,
    scene: &mut Scene,
    integrator: &mut dyn Integrator,
    threads: usize,
    cancel: &AtomicBool,
) -> Result<Option<Film>> {
    let camera_samples = plan.camera_samples(cell);
    if let Some(spp) = camera_samples {
        scene.spp = spp;
    }
    integrator.preprocess(scene);
    match plan.in_passes(cell) {
        None => {
            let (film, stats) =
                lumis_core::render::render_cancellable(scene, integrator, threads, &|_| {}, cancel)
                    .context("cannot start the render threads")?;
            Ok((!stats.partial()).then_some(film))
        }
        Some(in_passes) => {
            // A `path` row's camera samples are its budget, in as many passes as it asks
            // (at most one a camera sample); a direct row's are the passes'.
            let in_passes = match camera_samples {
                Some(spp) => InPasses {
                    passes: in_passes.passes.min(spp),
                    ..in_passes
                },
                None => {
                    scene.spp = in_passes.spp();
                    in_passes
                }
            };
            render_in_passes(scene, integrator, in_passes, threads, cancel)
        }
    }
}

/// A render of `scene`'s samples in the passes of `in_passes`; `None` if `cancel` stopped it.
fn render_in_passes(
    scene: &Scene,
    integrator: &mut dyn Integrator,
    in_passes: InPasses,
    threads: usize,
    cancel: &AtomicBool,
) -> Result<Option<Film>> {
    let settings = Settings {
        stopping: Stopping::Samples {
            spp: scene.spp,
            passes: in_passes.passes,
        },
        ..Settings::samples(scene.spp)
    };
    let mut state = RenderState::new(scene, integrator, &settings);
    let outcome = progressive::run(
        scene,
        integrator,
        &settings,
        &mut state,
        Scope::whole(threads).with_budgets(in_passes.budgets),
        cancel,
        &|_| {},
        &mut |_| Control::Continue,
    )
    .context("cannot start the render threads")?;
    Ok((outcome.ending == Ending::Complete).then(|| state.sums.resolve(scene, integrator)))
}

fn channels(film: &Film) -> Vec<Channel> {
    CHANNELS
        .iter()
        .filter_map(|&(layer, channel)| {
            Some(Channel {
                name: format!("{layer}.{channel}"),
                values: film.aov(layer)?.channel(channel)?,
            })
        })
        .collect()
}

/// CPU seconds used by this process so far (all threads), or NaN where it cannot be read.
fn process_cpu_time() -> f64 {
    #[cfg(unix)]
    {
        let mut t = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes one timespec through a valid pointer.
        if unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) } == 0 {
            return t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9;
        }
    }
    f64::NAN
}
