//! A render in passes: the loop that plans each pass from the passes before it
//! ([`passes::next_pass`]), lets the integrator read those passes ([`Integrator::begin_pass`]),
//! renders the pass on the film's sums ([`render::render_pass`]), estimates the image's error
//! ([`error_estimate::estimate`]) and reports to the caller, who may stop it.
//!
//! The state between passes ([`RenderState`]: the sums, the passes so far, a pass cut short and
//! what the integrator learned beyond the sums) is all a render is: saved after an interrupt, it
//! resumes into the image the render would have given without one; saved by shards after each
//! pass, it merges into the one-process state (docs/distributed.md).

use crate::budgets::{self, Budgets};
use crate::error_estimate;
use crate::integrator::Integrator;
pub use crate::passes::PassContext;
use crate::passes::{self, Decision, History, PassRecord, PlannedPass, Settings, Stop};
use crate::render::{self, FilmSums, RenderStats, Shard};
use crate::scene::Scene;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// A render in passes between two passes: everything needed to continue it.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderState {
    pub sums: FilmSums,
    pub history: History,
    /// The pass being rendered when the render was interrupted, and whether it was planned as
    /// the last: finished first when the render resumes (its pixels already done skip it).
    pub current: Option<(PlannedPass, Option<Stop>)>,
    /// What the integrator learned that the sums do not hold, as of the last finished pass
    /// ([`Integrator::learned_state`]; empty when it learns nothing, or before [`run`] first
    /// sees it). A render that continues this state with a new integrator gives it back with
    /// [`Integrator::restore_learned_state`] after `preprocess`.
    pub learned: Vec<u8>,
}

impl RenderState {
    /// A render of `scene` by `integrator` with `settings` that has not started.
    pub fn new(scene: &Scene, integrator: &dyn Integrator, settings: &Settings) -> Self {
        RenderState {
            sums: FilmSums::new(
                scene,
                integrator.pixel_sums(scene),
                settings.estimates_error(),
            ),
            history: History::default(),
            current: None,
            learned: Vec::new(),
        }
    }
}

/// The caller's answer after a pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Control {
    Continue,
    /// Stop now: the image is the passes so far, their weights made to sum to one (an
    /// unplanned stop: consistent, not unbiased), marked partial; the state can resume.
    Stop,
}

/// How a call of [`run`] ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ending {
    /// The pass planned as the last is done.
    Complete,
    /// `cancel` was raised: the pass in progress is in the state's `current`, its finished
    /// pixels in the sums; with per-pixel budgets, or an integrator that learns beyond the sums
    /// ([`Integrator::learned_state`]), the pass is dropped instead (the state, and what the
    /// integrator learned, are the ones before it; `current` empty).
    Interrupted,
    /// The caller answered [`Control::Stop`].
    Stopped,
    /// The number of passes asked for were rendered (a shard renders one pass at a time).
    Passes,
}

/// What [`run`] did.
#[derive(Clone, Copy, Debug)]
pub struct Outcome {
    pub ending: Ending,
    /// Render time, camera samples and rays of this call's passes; pixels and tiles of the
    /// latest pass.
    pub stats: RenderStats,
}

/// Where and how much of a render [`run`] renders.
#[derive(Clone, Copy, Debug)]
pub struct Scope {
    pub threads: usize,
    /// The tiles rendered; a shard renders one pass per call and estimates no error (its sums
    /// hold only its tiles' latest pass), the merge of the shards does.
    pub shard: Shard,
    /// At most this many passes.
    pub max_passes: Option<usize>,
    /// How each pass's samples are spread over the pixels ([`crate::budgets`]).
    pub budgets: Budgets,
}

impl Scope {
    /// The whole render on `threads` threads (0: one per core).
    pub fn whole(threads: usize) -> Self {
        Scope {
            threads,
            shard: Shard::WHOLE,
            max_passes: None,
            budgets: Budgets::Uniform,
        }
    }

    /// This scope with each pass's samples spread over the pixels by `budgets`.
    pub fn with_budgets(self, budgets: Budgets) -> Self {
        Scope { budgets, ..self }
    }
}

/// Renders the passes of `state` that `settings` plan, until the render is complete, `cancel`
/// is raised, `on_pass` says stop or `scope.max_passes` passes are done. `on_pass` is called
/// after each pass with the state (the pass's record last in its history); `on_tile` after
/// each tile with the pixels that have their pass. An integrator that learns beyond the sums
/// must hold the state's `learned` (restored by the caller, or left by an earlier `run`).
#[allow(clippy::too_many_arguments)]
pub fn run(
    scene: &Scene,
    integrator: &mut dyn Integrator,
    settings: &Settings,
    state: &mut RenderState,
    scope: Scope,
    cancel: &AtomicBool,
    on_tile: &(dyn Fn(u64) + Sync),
    on_pass: &mut dyn FnMut(&RenderState) -> Control,
) -> Result<Outcome, rayon::ThreadPoolBuildError> {
    let pool = render::thread_pool(scope.threads)?;
    let session = Instant::now();
    let elapsed_before = state.history.elapsed;
    let mut stats = RenderStats {
        wall_time: Duration::ZERO,
        camera_samples: 0,
        rays: 0,
        threads: pool.current_num_threads(),
        pixels_done: state.sums.pixels_with_samples(),
        pixels_total: state.sums.samples.len() as u64,
        tiles_done: 0,
        tiles_total: 0,
    };
    let mut rendered = 0;
    // Per-pixel budgets decide each pass from the whole image's sums: a pass cut short would
    // leave sums that no decision was made from (the pixels done would differ from those an
    // uninterrupted render gives them). An integrator that learns beyond the sums has learned
    // from samples of tiles cut short, which are rendered again when the pass is. So the sums
    // from before each pass are kept to return to: twice the sums' memory, in these cases only.
    let mut before_pass: Option<FilmSums> = None;
    // What the integrator has learned as of the last finished pass: the state's, which the
    // caller restored, or else the integrator's own from before its first pass (empty for one
    // that learns nothing). Exported once per pass, after it; an interrupted pass restores it.
    if state.learned.is_empty() {
        state.learned = integrator.learned_state();
    }
    let learns = !state.learned.is_empty();
    let ending = loop {
        state.history.elapsed = elapsed_before + session.elapsed().as_secs_f64();
        if cancel.load(Ordering::Relaxed) {
            break Ending::Interrupted;
        }
        if scope.max_passes.is_some_and(|m| rendered >= m) {
            break Ending::Passes;
        }
        let (pass, stop) = match state.current.take() {
            Some(current) => current,
            None => match passes::next_pass(settings, &state.history) {
                Decision::Done => break Ending::Complete,
                Decision::Pass(pass, stop) => (pass, stop),
            },
        };
        if state.history.passes.is_empty() {
            state.history.mass = pass.planned as f64;
        }
        if scope.budgets != Budgets::Uniform || learns {
            match &mut before_pass {
                Some(sums) => sums.clone_from(&state.sums),
                None => before_pass = Some(state.sums.clone()),
            }
        }
        let budget = budgets::budget(
            scope.budgets,
            settings.metric,
            &state.history,
            &state.sums,
            pass,
        );
        integrator.begin_pass(
            scene,
            &PassContext {
                index: state.history.passes.len(),
                budget: &budget,
                history: &state.history,
                sums: &state.sums,
            },
        );
        let pass_stats = render::render_pass(
            scene,
            &*integrator,
            &pool,
            scope.shard,
            &mut state.sums,
            &budget,
            on_tile,
            cancel,
        );
        stats.wall_time += pass_stats.wall_time;
        stats.camera_samples += pass_stats.camera_samples;
        stats.rays += pass_stats.rays;
        stats.pixels_done = pass_stats.pixels_done;
        stats.pixels_total = pass_stats.pixels_total;
        stats.tiles_done = pass_stats.tiles_done;
        stats.tiles_total = pass_stats.tiles_total;
        rendered += 1;
        if pass_stats.pixels_done < pass_stats.pixels_total {
            if let Some(sums) = before_pass.take() {
                state.sums = sums;
                integrator
                    .restore_learned_state(&state.learned)
                    .expect("an integrator takes back the state it saved");
                stats.pixels_done = state.sums.pixels_with_samples();
                stats.tiles_done = 0;
                state.history.elapsed = elapsed_before + session.elapsed().as_secs_f64();
                break Ending::Interrupted;
            }
            state.current = Some((pass, stop));
            state.history.elapsed = elapsed_before + session.elapsed().as_secs_f64();
            break Ending::Interrupted;
        }
        let error = (scope.shard == Shard::WHOLE && settings.estimates_error())
            .then(|| error_estimate::estimate(&state.sums, settings.metric, settings.confidence))
            .flatten();
        state.history.passes.push(PassRecord {
            pass,
            seconds: pass_stats.wall_time.as_secs_f64(),
            error,
        });
        state.history.stopped = stop;
        state.history.elapsed = elapsed_before + session.elapsed().as_secs_f64();
        if learns {
            state.learned = integrator.learned_state();
        }
        if on_pass(state) == Control::Stop {
            break Ending::Stopped;
        }
    };
    Ok(Outcome { ending, stats })
}
