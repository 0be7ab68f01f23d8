//! A render as a sequence of passes, and how a pixel's passes combine without bias
//! (docs/integrators.md, "Passes").
//!
//! Pass k gives each pixel camera samples with indices from the pixel's count so far up to the
//! pass's `end`, each weighted by u_k. With n_k the pass's samples, P_k the samples *planned* for
//! the pixel from the start of pass k to the end of the render (decided, like n_k, before pass k
//! runs), T the render's weight mass (P_0) and M_k = Σ_{i<k} u_i n_i the mass given so far,
//!
//! ```text
//! u_k = (T − M_k) / P_k,
//! ```
//!
//! the remaining mass spread over the planned samples. A pixel's image is Σ_k u_k S_k / Σ_k u_k n_k
//! (S_k the sum of its pass-k colours): the pass weights w_k = u_k n_k / T depend on earlier
//! passes only, and the pass planned to be the last (P_k = n_k) brings Σ_k w_k to one. So the
//! image is unbiased for any data-dependent plan, as long as every decision about pass k (its
//! samples, its plan, whether it runs) is taken before it runs. When every plan holds (each P_k is
//! what remains), every u_k is one and the image is the plain mean of the samples, bit for bit
//! the single-pass render of as many samples.
//!
//! Over 600 lines: about half is the planner's tests, which drive its private functions.

use crate::error_estimate::{ErrorEstimate, Metric};
use crate::film_sums::FilmSums;

/// Samples per pixel of a target or time render's first pass, planned with no data: its weight
/// is 2/T, so that it costs at most its own samples when the render needs few.
pub const FIRST_PASS: u32 = 2;

/// The cap of a target-error render that names no cap (`--max-spp`).
pub const DEFAULT_MAX_SPP: u32 = 4096;

/// The samples per pixel a time-limited render may reach when it names no `--max-spp`.
pub const TIME_MAX_SPP: u32 = 1 << 24;

/// A pass is at most as large as the passes before it together (the samples double): the
/// estimates that plan the last pass are then made on at least half of the render's samples.
const GROWTH: u32 = 1;

/// The fraction of the remaining time a time-limited render plans to fill, for the variations of
/// its throughput.
const TIME_SAFETY: f64 = 0.95;

/// A pass that is not the last is planned for this much more than the estimates say the render
/// needs: a plan found short later leaves the earlier passes weighted too much for good (the
/// variance that costs has no bound), one found long only gives the last pass a little more
/// than its share.
const PLAN_MARGIN: f64 = 1.25;

/// The last pass is planned only when the per-sample error estimated after the last two passes
/// agrees within this fraction (docs/integrators.md, "Passes"): a half-image estimate is low
/// while rare bright samples are still unseen, and rises towards the error as they appear.
const SETTLED: f64 = 0.15;

/// No last pass is planned before every pixel has this many samples: a light that a few samples
/// per pixel miss shows no error yet (docs/integrators.md, "Passes"). One packet of camera
/// samples ([`PACKET_SIZE`](crate::geometry::PACKET_SIZE)): the passes before it are the only
/// ones that leave lanes empty.
pub const MIN_SAMPLES_BEFORE_STOP: u32 = 16;

/// A render to a target error ends with at least this many samples per pixel (fewer only at a
/// cap): the last pass is sized to reach it. Below it the half-image estimate of the relative
/// MSE reads low where rare bright samples dominate a pixel (a half that caught one raises its
/// own denominator), and a stop planned from it misses the target far more often than the
/// confidence allows (docs/study.md, "Renders to a target error": the environment map at 0.1).
pub const MIN_SAMPLES_AT_STOP: u32 = 128;

/// The confidence a last pass planned after the pass ending at `done` samples is sized with:
/// every pass from [`MIN_SAMPLES_BEFORE_STOP`] on is a look at which a low estimate could plan
/// the stop, so the render's 1 − `confidence` is spent over the looks, half at the first, a
/// quarter at the second, …: the chance that any planned stop misses is at most the sum,
/// 1 − `confidence`, however many looks the render takes (Bonferroni). Looks are counted by
/// samples (they double), so the confidence is a function of `done` alone.
pub fn stop_confidence(confidence: f64, done: u32) -> f64 {
    let mut look = 1;
    let mut samples = MIN_SAMPLES_BEFORE_STOP;
    while samples < done {
        samples = samples.saturating_mul(2);
        look += 1;
    }
    1.0 - (1.0 - confidence) / 2f64.powi(look)
}

/// A pass as decided before it runs, for every pixel alike.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlannedPass {
    /// The pixel's camera samples after the pass (its indices continue the earlier passes').
    pub end: u32,
    /// P_k: the samples planned from the start of this pass to the end of the render, the pass's
    /// own included; equal to the pass's samples for the last pass.
    pub planned: u64,
}

/// What a pass gives the pixels, decided before it runs.
#[derive(Clone, Debug, PartialEq)]
pub struct Budget {
    /// T: the render's weight mass (its first pass's planned samples).
    pub mass: f64,
    pub pixels: PixelPasses,
}

/// Each pixel's pass: the same for all (what the planners decide), or each pixel its own (in
/// the order of [`FilmSums`](crate::render::FilmSums)), decided from earlier passes as well.
#[derive(Clone, Debug, PartialEq)]
pub enum PixelPasses {
    Uniform(PlannedPass),
    PerPixel(Vec<PlannedPass>),
}

impl Budget {
    /// The same pass for every pixel of a render of mass `mass`.
    pub fn uniform(mass: f64, pass: PlannedPass) -> Self {
        Budget {
            mass,
            pixels: PixelPasses::Uniform(pass),
        }
    }

    /// Pixel `p`'s pass (`p` in the sums' order).
    #[inline]
    pub fn pixel(&self, p: usize) -> PlannedPass {
        match &self.pixels {
            PixelPasses::Uniform(pass) => *pass,
            PixelPasses::PerPixel(passes) => passes[p],
        }
    }
}

/// What the integrator is shown before a pass ([`Integrator::begin_pass`](crate::integrator::Integrator::begin_pass)).
pub struct PassContext<'a> {
    /// The pass's index (0 for the first).
    pub index: usize,
    /// What each pixel gets in the pass.
    pub budget: &'a Budget,
    /// The passes before it and their sums: everything a decision about the pass may read.
    pub history: &'a History,
    pub sums: &'a FilmSums,
}

/// u_k: a pixel's weight per camera sample in a pass, from the render's mass, the mass the pixel
/// has been given and the samples planned for it.
#[inline]
pub fn sample_weight(mass: f64, given: f64, planned: u64) -> f64 {
    (mass - given) / planned as f64
}

/// The mass a pixel has been given after `samples` more samples at weight `u`.
#[inline]
pub fn give(given: f64, u: f64, samples: u32) -> f64 {
    given + u * samples as f64
}

/// When a render stops.
#[derive(Clone, Debug, PartialEq)]
pub enum Stopping {
    /// `spp` samples in `passes` passes as equal as possible (even where they can be): one pass
    /// is the plain render.
    Samples { spp: u32, passes: u32 },
    /// When the error is below `error` with the settings' confidence, or at a cap.
    Target {
        error: f64,
        max_spp: u32,
        max_time: Option<f64>,
    },
    /// The best image in `seconds` of rendering.
    Time { seconds: f64, max_spp: u32 },
    /// The passes of an earlier render, as recorded.
    Replay(Vec<PlannedPass>),
}

/// What a render was asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub stopping: Stopping,
    /// The error the render estimates and reports (and a target is in).
    pub metric: Metric,
    /// The confidence of the reported interval and of a target's stop.
    pub confidence: f64,
}

impl Settings {
    /// A plain render of `spp` samples in one pass.
    pub fn samples(spp: u32) -> Self {
        Settings {
            stopping: Stopping::Samples { spp, passes: 1 },
            metric: Metric::RelMse,
            confidence: 0.95,
        }
    }

    /// Whether the render keeps the half-images its error is estimated from: a render in passes
    /// whose every pass has an even number of samples (a plain one-pass render estimates none).
    pub fn estimates_error(&self) -> bool {
        match &self.stopping {
            Stopping::Samples { spp, passes } => {
                *passes > 1
                    && fixed_passes(*spp, *passes)
                        .iter()
                        .all(|p| p.samples % 2 == 0)
            }
            Stopping::Target { .. } | Stopping::Time { .. } => true,
            Stopping::Replay(passes) => {
                let mut end = 0;
                passes.iter().all(|p| {
                    let even = (p.end - end) % 2 == 0;
                    end = p.end;
                    even
                })
            }
        }
    }

    /// Whether the decisions may depend on the clock (then the render is reproduced by
    /// replaying its recorded passes).
    pub fn timed(&self) -> bool {
        matches!(
            self.stopping,
            Stopping::Time { .. }
                | Stopping::Target {
                    max_time: Some(_),
                    ..
                }
        )
    }
}

/// What a caller asks of a render, unchecked: the options of `lumis render` and of Python's
/// `Scene.render` (each named after its option there).
#[derive(Clone, Debug, Default)]
pub struct Request {
    pub target_error: Option<f64>,
    pub time: Option<f64>,
    pub passes: Option<u32>,
    pub replay: Option<Vec<PlannedPass>>,
    pub metric: Option<Metric>,
    pub confidence: Option<f64>,
    pub max_spp: Option<u32>,
    pub max_time: Option<f64>,
}

impl Request {
    /// The settings of the render in passes asked for, `None` for a plain render of the scene's
    /// `spp`, or what is wrong, each option named by `name` (e.g. `target_error` →
    /// `--target-error`).
    pub fn settings(
        &self,
        spp: u32,
        name: impl Fn(&str) -> String,
    ) -> Result<Option<Settings>, String> {
        let given: Vec<&str> = [
            ("target_error", self.target_error.is_some()),
            ("time", self.time.is_some()),
            ("passes", self.passes.is_some()),
            ("replay", self.replay.is_some()),
        ]
        .into_iter()
        .filter_map(|(n, g)| g.then_some(n))
        .collect();
        if given.len() > 1 {
            return Err(format!(
                "{} and {} ask for different renders: give one",
                name(given[0]),
                name(given[1])
            ));
        }
        if let Some(c) = self.confidence
            && !(c > 0.0 && c < 1.0)
        {
            return Err(format!(
                "{} {c} must lie between 0 and 1 (e.g. 0.95)",
                name("confidence")
            ));
        }
        for (key, value) in [("max_time", self.max_time), ("time", self.time)] {
            if let Some(v) = value
                && !(v.is_finite() && v > 0.0)
            {
                return Err(format!(
                    "{} {v} must be a positive number of seconds",
                    name(key)
                ));
            }
        }
        if let Some(s) = self.max_spp
            && s < 2
        {
            return Err(format!(
                "{} {s}: a render in passes needs at least 2 samples per pixel",
                name("max_spp")
            ));
        }
        let caps_only = |what: &str| {
            Err(format!(
                "{} caps a render to {}{}",
                name(what),
                name("target_error"),
                if what == "max_spp" {
                    format!(" or {}", name("time"))
                } else {
                    String::new()
                }
            ))
        };
        let stopping = if let Some(error) = self.target_error {
            if !(error.is_finite() && error >= 0.0) {
                return Err(format!(
                    "{} {error} must be a number ≥ 0 (0 renders to the cap)",
                    name("target_error")
                ));
            }
            Stopping::Target {
                error,
                max_spp: self.max_spp.unwrap_or(DEFAULT_MAX_SPP),
                max_time: self.max_time,
            }
        } else {
            if self.max_time.is_some() {
                return caps_only("max_time");
            }
            if let Some(seconds) = self.time {
                Stopping::Time {
                    seconds,
                    max_spp: self.max_spp.unwrap_or(TIME_MAX_SPP),
                }
            } else if self.max_spp.is_some() {
                return caps_only("max_spp");
            } else if let Some(k) = self.passes {
                if k == 0 || k > spp {
                    return Err(format!(
                        "{} {k}: between 1 and the {spp} samples per pixel",
                        name("passes")
                    ));
                }
                Stopping::Samples { spp, passes: k }
            } else if let Some(passes) = &self.replay {
                Stopping::Replay(passes.clone())
            } else {
                if self.metric.is_some() || self.confidence.is_some() {
                    return Err(format!(
                        "{} and {} apply to a render in passes ({}, {}, {}, {})",
                        name("metric"),
                        name("confidence"),
                        name("target_error"),
                        name("time"),
                        name("passes"),
                        name("replay")
                    ));
                }
                return Ok(None);
            }
        };
        Ok(Some(Settings {
            stopping,
            metric: self.metric.unwrap_or(Metric::RelMse),
            confidence: self.confidence.unwrap_or(0.95),
        }))
    }
}

/// Why a render's passes ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// The fixed samples were rendered.
    Samples,
    /// The last pass was sized to bring the error below the target.
    Target,
    /// The cap on samples per pixel.
    MaxSpp,
    /// The cap on time.
    MaxTime,
    /// The time asked for.
    Time,
    /// The recorded passes were replayed.
    Replayed,
}

impl Stop {
    pub fn name(self) -> &'static str {
        match self {
            Stop::Samples => "samples",
            Stop::Target => "target",
            Stop::MaxSpp => "max-spp",
            Stop::MaxTime => "max-time",
            Stop::Time => "time",
            Stop::Replayed => "replay",
        }
    }

    pub fn parse(text: &str) -> Option<Stop> {
        [
            Stop::Samples,
            Stop::Target,
            Stop::MaxSpp,
            Stop::MaxTime,
            Stop::Time,
            Stop::Replayed,
        ]
        .into_iter()
        .find(|s| s.name() == text)
    }
}

/// A finished pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassRecord {
    pub pass: PlannedPass,
    /// Wall time of its rendering, seconds.
    pub seconds: f64,
    /// The image's error after it, if the render estimates it.
    pub error: Option<ErrorEstimate>,
}

/// The passes of a render so far.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct History {
    /// T: the first pass's planned samples.
    pub mass: f64,
    pub passes: Vec<PassRecord>,
    /// Wall time since the first pass started, all sessions of a resumed render together.
    pub elapsed: f64,
    /// Set when the last pass planned as the last is done.
    pub stopped: Option<Stop>,
}

impl History {
    /// Samples per pixel so far.
    pub fn samples(&self) -> u32 {
        self.passes.last().map_or(0, |p| p.pass.end)
    }

    /// Whether the weights are complete: the pass planned to be the last has run.
    pub fn complete(&self) -> bool {
        self.stopped.is_some()
    }

    /// The weight mass given to every pixel so far, M, and Σ u² n, Q (with M² / Q the effective
    /// samples of the image), computed as a pixel computes its M.
    pub fn given(&self) -> (f64, f64) {
        let (mut given, mut squares, mut end) = (0.0, 0.0, 0);
        for record in &self.passes {
            let u = sample_weight(self.mass, given, record.pass.planned);
            let n = record.pass.end - end;
            given = give(given, u, n);
            squares += u * u * n as f64;
            end = record.pass.end;
        }
        (given, squares)
    }

    /// The effective samples per pixel of the image after each pass, M²/Q (the samples whose
    /// plain mean would have the image's variance).
    fn effective_samples(&self) -> Vec<f64> {
        let (mut given, mut squares, mut end) = (0.0, 0.0, 0);
        self.passes
            .iter()
            .map(|record| {
                let u = sample_weight(self.mass, given, record.pass.planned);
                let n = record.pass.end - end;
                given = give(given, u, n);
                squares += u * u * n as f64;
                end = record.pass.end;
                given * given / squares
            })
            .collect()
    }

    /// The per-sample error (the estimate times the effective samples) after the last two
    /// passes that have an estimate, with those samples: `None` before two.
    fn per_sample_errors(&self) -> Option<[(f64, f64); 2]> {
        let samples = self.effective_samples();
        let mut estimated = self
            .passes
            .iter()
            .zip(samples)
            .rev()
            .filter_map(|(p, n)| p.error.map(|e| (e.value * n, n)));
        let last = estimated.next()?;
        let before = estimated.next()?;
        Some([before, last])
    }

    /// Whether the per-sample error estimated after the last two passes agrees within
    /// [`SETTLED`] (or is zero both times).
    pub fn settled(&self) -> bool {
        self.per_sample_errors()
            .is_some_and(|[(before, _), (last, _)]| last <= before * (1.0 + SETTLED))
    }

    /// The factor by which the latest half-image estimate is raised for its small-sample bias:
    /// a Richardson step under the model v̂(N) = v / (1 + κ/N) of the per-sample error estimated
    /// from N effective samples, κ from the last two passes, v = v̂₂ (1 + κ/N₂); one when the
    /// estimate did not rise, at most N₂/N₁ (an estimate that grew as fast as the samples).
    fn small_sample_factor(&self) -> f64 {
        let Some([(v1, n1), (v2, n2)]) = self.per_sample_errors() else {
            return 1.0;
        };
        if !(v2 > v1 && n2 > n1) {
            return 1.0;
        }
        let slope = v1 / n1 - v2 / n2;
        if slope > 0.0 {
            (1.0 + (v2 - v1) / slope / n2).min(n2 / n1)
        } else {
            n2 / n1
        }
    }

    /// The image's error after the last pass, as the render states it: the half-image estimate
    /// and its interval's high end raised for its small-sample bias, the low end not (a raise
    /// for bright samples not yet seen says nothing of how low the error may be);
    /// [`History::raw_error`] is the estimate itself.
    pub fn error(&self) -> Option<ErrorEstimate> {
        let raw = self.raw_error()?;
        let f = self.small_sample_factor();
        Some(ErrorEstimate {
            value: raw.value * f,
            low: raw.low,
            high: raw.high * f,
            variance: raw.variance * f * f,
            ..raw
        })
    }

    /// The half-image estimate of the image's error after the last pass.
    pub fn raw_error(&self) -> Option<ErrorEstimate> {
        self.passes.last().and_then(|p| p.error)
    }
}

/// The next step of a render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Decision {
    /// Render this pass; `Some(stop)` if it is planned as the last, and why.
    Pass(PlannedPass, Option<Stop>),
    /// The render is complete.
    Done,
}

/// The passes of `spp` samples in `passes` parts: even sizes when `spp` is even and there are at
/// most spp/2 passes, else sizes differing by at most one.
fn fixed_passes(spp: u32, passes: u32) -> Vec<Sized> {
    let passes = passes.clamp(1, spp.max(1));
    let unit = if spp.is_multiple_of(2) && passes <= spp / 2 {
        2
    } else {
        1
    };
    let units = spp / unit;
    (0..passes)
        .map(|k| Sized {
            samples: unit * (units / passes + u32::from(k < units % passes)),
        })
        .collect()
}

struct Sized {
    samples: u32,
}

/// `n` rounded up to an even number of samples, at least 2 (∞ stays ∞).
fn even_up(n: f64) -> f64 {
    if n.is_finite() {
        (2.0 * (n / 2.0).ceil()).max(2.0)
    } else {
        n
    }
}

/// `n` rounded down to an even number.
fn even_down(n: u64) -> u64 {
    n - n % 2
}

/// The samples a last pass needs so that the image's error is below `target`, predicted from
/// `upper`, a bound of the error of the image so far that holds for the image after the last
/// pass once scaled ([`ErrorEstimate::upper_bound`]) (∞ if no last pass can: the earlier
/// passes' share of the error is already above the target).
///
/// With M, Q the mass and Σ u² n so far, the image's error per unit of per-sample error is Q/M²
/// now and (Q + (T − M)²/n)/T² after a last pass of n samples; the ratio q(n) of the two scales
/// the bound, and the last pass is the smallest n with q(n)·upper ≤ target.
pub fn samples_for_target(target: f64, upper: f64, mass: f64, given: f64, squares: f64) -> f64 {
    if upper <= 0.0 {
        return 0.0;
    }
    if target <= 0.0 || given <= 0.0 {
        return f64::INFINITY;
    }
    let now = squares / (given * given);
    let room = mass * mass * (target / upper) * now - squares;
    if room > 0.0 {
        (mass - given).powi(2) / room
    } else {
        f64::INFINITY
    }
}

/// The samples per pixel that fit in the time left, from the latest pass's throughput and the
/// time spent between passes so far.
fn samples_in_time(history: &History, seconds: f64) -> u64 {
    let Some(last) = history.passes.last() else {
        return u64::MAX;
    };
    let previous = history.passes.iter().rev().nth(1).map_or(0, |p| p.pass.end);
    let per_second = (last.pass.end - previous) as f64 / last.seconds.max(1e-9);
    let rendering: f64 = history.passes.iter().map(|p| p.seconds).sum();
    let between = (history.elapsed - rendering).max(0.0) / history.passes.len() as f64;
    let left = (seconds - history.elapsed - between).max(0.0);
    let fit = per_second * left * TIME_SAFETY;
    if fit >= u32::MAX as f64 {
        u64::from(u32::MAX)
    } else {
        fit as u64
    }
}

/// The next pass of a render with `settings`, from its `history` (whose `elapsed` is up to
/// date): a function of the passes so far only, so that every decision about a pass is taken
/// before it runs.
pub fn next_pass(settings: &Settings, history: &History) -> Decision {
    if history.complete() {
        return Decision::Done;
    }
    let done = history.samples();
    let index = history.passes.len();
    match &settings.stopping {
        Stopping::Samples { spp, passes } => {
            let sizes = fixed_passes(*spp, *passes);
            let end: u32 = sizes[..=index.min(sizes.len() - 1)]
                .iter()
                .map(|s| s.samples)
                .sum();
            let last = index + 1 >= sizes.len();
            Decision::Pass(
                PlannedPass {
                    end,
                    planned: u64::from(spp - done),
                },
                last.then_some(Stop::Samples),
            )
        }
        Stopping::Replay(passes) => match passes.get(index) {
            Some(pass) => {
                let last = pass.planned == u64::from(pass.end - done);
                Decision::Pass(*pass, last.then_some(Stop::Replayed))
            }
            None => Decision::Done,
        },
        Stopping::Target {
            error,
            max_spp,
            max_time,
        } => plan(
            history,
            *max_spp,
            max_time.map(|t| (t, Stop::MaxTime)),
            Some(*error),
            settings.confidence,
        ),
        Stopping::Time { seconds, max_spp } => plan(
            history,
            *max_spp,
            Some((*seconds, Stop::Time)),
            None,
            settings.confidence,
        ),
    }
}

/// The next pass of a target or time render (docs/integrators.md, "Passes"): the first pass of
/// [`FIRST_PASS`] samples planned with the cap (no data yet); then the samples double, each
/// pass planned for what the latest estimates say the render needs, until a last pass no larger
/// than the samples so far reaches the target, or the cap or the time is reached.
fn plan(
    history: &History,
    max_spp: u32,
    time: Option<(f64, Stop)>,
    target: Option<f64>,
    confidence: f64,
) -> Decision {
    let done = history.samples();
    let cap = even_down(u64::from(max_spp));
    if history.passes.is_empty() {
        let samples = u64::from(FIRST_PASS).min(cap);
        let last = samples >= cap;
        return Decision::Pass(
            PlannedPass {
                end: samples as u32,
                planned: cap,
            },
            last.then_some(Stop::MaxSpp),
        );
    }
    let (mut limit, mut limit_stop) = (cap - u64::from(done), Stop::MaxSpp);
    if let Some((seconds, stop)) = time {
        let fit = even_down(samples_in_time(history, seconds)).max(2);
        if fit < limit {
            (limit, limit_stop) = (fit, stop);
        }
    }
    // An estimate of 0 is an unknown error (no sample has shown any), never a reason to stop.
    let (mut needed, mut reachable) = (f64::INFINITY, false);
    if let (Some(target), Some(estimate)) = (target, history.error())
        && let Some(upper) = estimate.upper_bound(stop_confidence(confidence, done))
    {
        let (given, squares) = history.given();
        needed = even_up(samples_for_target(
            target,
            upper,
            history.mass,
            given,
            squares,
        ))
        .max(f64::from(MIN_SAMPLES_AT_STOP.saturating_sub(done)));
        // The per-sample error over the cap: the error of an image of the cap's samples.
        reachable = upper * given * given / squares / cap as f64 <= target;
    }
    let growth = even_down(u64::from(GROWTH * done)).max(2);
    let settled = target.is_none() || (done >= MIN_SAMPLES_BEFORE_STOP && history.settled());
    let pass = |samples: u64, planned: u64, stop: Option<Stop>| {
        Decision::Pass(
            PlannedPass {
                end: done + samples as u32,
                planned,
            },
            stop,
        )
    };
    if settled && needed <= limit as f64 && needed <= growth as f64 {
        let samples = needed as u64;
        return pass(samples, samples, Some(Stop::Target));
    }
    if limit <= growth {
        return pass(limit, limit, Some(limit_stop));
    }
    if settled
        && needed.is_infinite()
        && reachable
        && u64::from(done) + growth >= u64::from(MIN_SAMPLES_AT_STOP)
    {
        // The passes so far hold too much of the weight for any last pass to reach the target
        // (their plans were found short), though the cap would with weights in proportion:
        // close with a pass as large as the samples so far.
        return pass(growth, growth, Some(Stop::Target));
    }
    // A pass that leaves room for a last one; planned, with a margin, for what the render is
    // expected to need.
    let samples = growth.min(limit - 2);
    let planned = if needed.is_finite() {
        ((needed * PLAN_MARGIN) as u64).clamp(samples + 2, limit)
    } else {
        limit
    };
    pass(samples, planned, None)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(value: f64, variance: f64) -> ErrorEstimate {
        ErrorEstimate {
            metric: Metric::RelMse,
            confidence: 0.95,
            value,
            low: value,
            high: value,
            variance,
            pixels: 1000,
        }
    }

    /// Runs the planner with an error that falls as 1/samples from `per_sample`, returning the
    /// passes; checks the weights' mass at the end.
    fn run(settings: &Settings, per_sample: f64) -> History {
        let mut history = History::default();
        loop {
            match next_pass(settings, &history) {
                Decision::Done => break,
                Decision::Pass(pass, stop) => {
                    if history.passes.is_empty() {
                        history.mass = pass.planned as f64;
                    }
                    assert!(pass.end > history.samples(), "{pass:?} adds nothing");
                    assert!(pass.planned >= u64::from(pass.end - history.samples()));
                    let (given, squares) = history.given();
                    let u = sample_weight(history.mass, given, pass.planned);
                    let n = (pass.end - history.samples()) as f64;
                    // The error of the image W/M: per-sample error × Σu²n / M².
                    let after = per_sample * (squares + u * u * n) / (given + u * n).powi(2);
                    history.passes.push(PassRecord {
                        pass,
                        seconds: 1.0,
                        error: Some(estimate(after, (after * 0.01).powi(2))),
                    });
                    history.stopped = stop;
                }
            }
            assert!(history.passes.len() < 64, "too many passes");
        }
        history
    }

    fn target(error: f64, max_spp: u32) -> Settings {
        Settings {
            stopping: Stopping::Target {
                error,
                max_spp,
                max_time: None,
            },
            metric: Metric::RelMse,
            confidence: 0.95,
        }
    }

    #[test]
    fn the_weights_of_a_finished_render_sum_to_one() {
        for (error, cap) in [
            (0.01, 4096),
            (1e-3, 4096),
            (0.5, 4096),
            (0.0, 64),
            (1e-9, 30),
        ] {
            let history = run(&target(error, cap), 1.0);
            assert!(history.complete());
            let (given, _) = history.given();
            assert!(
                (given - history.mass).abs() <= 1e-12 * history.mass,
                "{error}, {cap}: {given} of {}",
                history.mass
            );
        }
    }

    /// Samples double until the last pass, which brings the predicted error under the target
    /// (with its margin); the first pass weighs 2/T, the rest of the passes are weighted alike
    /// when the plan holds.
    #[test]
    fn a_target_is_reached_in_doubling_passes() {
        let history = run(&target(0.01, 4096), 1.0);
        let ends: Vec<u32> = history.passes.iter().map(|p| p.pass.end).collect();
        assert_eq!(history.stopped, Some(Stop::Target));
        assert_eq!(&ends[..4], &[2, 4, 8, 16]);
        let last = history.error().unwrap().value;
        assert!(last < 0.01, "{last}");
        // About 100 samples are needed (1/0.01), plus the margin, plus the first pass.
        assert!((100..140).contains(&history.samples()), "{ends:?}");
    }

    #[test]
    fn unreachable_targets_stop_at_the_cap() {
        for error in [0.0, 1e-20] {
            let history = run(&target(error, 64), 1.0);
            assert_eq!(history.stopped, Some(Stop::MaxSpp));
            assert_eq!(history.samples(), 64);
        }
        // An odd cap is reached to its even part.
        assert_eq!(run(&target(0.0, 31), 1.0).samples(), 30);
    }

    /// A target met after the first pass still ends at the minimum samples: the passes double
    /// up to half of it and a last pass as large as the samples so far reaches it.
    #[test]
    fn a_target_met_at_once_ends_at_the_minimum_samples() {
        let history = run(&target(0.5, 4096), 0.1);
        let ends: Vec<u32> = history.passes.iter().map(|p| p.pass.end).collect();
        assert_eq!(ends, [2, 4, 8, 16, 32, 64, MIN_SAMPLES_AT_STOP]);
        assert_eq!(history.stopped, Some(Stop::Target));
        // A black image: no sample has shown an error, which is unknown, not zero: the cap.
        let history = run(&target(0.01, 256), 0.0);
        assert_eq!(history.stopped, Some(Stop::MaxSpp));
        assert_eq!(history.samples(), 256);
    }

    /// The stated error is the half-image estimate raised by the Richardson step: exact under
    /// the model v̂(N) = v/(1 + κ/N), one when the estimate does not rise, bounded by N₂/N₁.
    #[test]
    fn the_small_sample_bias_is_extrapolated() {
        let history = |v1: f64, v2: f64| History {
            mass: 4.0,
            passes: vec![
                PassRecord {
                    pass: PlannedPass { end: 2, planned: 4 },
                    seconds: 0.0,
                    error: Some(estimate(v1 / 2.0, 0.0)),
                },
                PassRecord {
                    pass: PlannedPass { end: 4, planned: 2 },
                    seconds: 0.0,
                    error: Some(estimate(v2 / 4.0, 0.0)),
                },
            ],
            ..History::default()
        };
        // v = 1, κ = 2: v̂(2) = 1/2, v̂(4) = 2/3; the stated error is v/4.
        let h = history(0.5, 2.0 / 3.0);
        assert!((h.error().unwrap().value - 0.25).abs() < 1e-12);
        assert!(!h.settled());
        assert_eq!(history(0.7, 0.6).error().unwrap().value, 0.15);
        assert!(history(0.7, 0.6).settled());
        // Twice the per-sample error from twice the samples: at most a factor 2.
        assert_eq!(history(0.1, 0.2).error().unwrap().value, 0.1);
    }

    #[test]
    fn fixed_passes_split_the_samples() {
        let sizes =
            |spp, k| -> Vec<u32> { fixed_passes(spp, k).iter().map(|s| s.samples).collect() };
        assert_eq!(sizes(64, 8), vec![8; 8]);
        assert_eq!(sizes(10, 3), vec![4, 4, 2]);
        assert_eq!(sizes(7, 3), vec![3, 2, 2]);
        assert_eq!(sizes(5, 9), vec![1; 5]);
        let settings = Settings {
            stopping: Stopping::Samples { spp: 10, passes: 3 },
            ..Settings::samples(10)
        };
        assert!(settings.estimates_error());
        let history = run(&settings, 1.0);
        assert_eq!(history.stopped, Some(Stop::Samples));
        // Every plan holds: every weight is one.
        let (given, squares) = history.given();
        assert_eq!((given, squares), (10.0, 10.0));
        assert!(!Settings::samples(8).estimates_error());
    }

    #[test]
    fn replays_repeat_the_recorded_passes() {
        let history = run(&target(0.02, 4096), 1.0);
        let replay = Settings {
            stopping: Stopping::Replay(history.passes.iter().map(|p| p.pass).collect()),
            ..target(0.02, 4096)
        };
        let again = run(&replay, 1.0);
        assert_eq!(again.stopped, Some(Stop::Replayed));
        assert_eq!(
            again.passes.iter().map(|p| p.pass).collect::<Vec<_>>(),
            history.passes.iter().map(|p| p.pass).collect::<Vec<_>>()
        );
    }

    /// A time render plans its passes from its throughput: here one sample per pixel per
    /// second, 100 s: about 95 samples, the last pass filling what is left.
    #[test]
    fn a_time_render_fills_its_time() {
        let settings = Settings {
            stopping: Stopping::Time {
                seconds: 100.0,
                max_spp: TIME_MAX_SPP,
            },
            ..Settings::samples(1)
        };
        let mut history = History::default();
        while let Decision::Pass(pass, stop) = next_pass(&settings, &history) {
            if history.passes.is_empty() {
                history.mass = pass.planned as f64;
            }
            let n = pass.end - history.samples();
            history.elapsed += n as f64;
            history.passes.push(PassRecord {
                pass,
                seconds: n as f64,
                error: None,
            });
            history.stopped = stop;
        }
        assert_eq!(history.stopped, Some(Stop::Time));
        assert!((90..=100).contains(&history.samples()), "{history:?}");
        // Out of time after the first pass: a last pass of 2 samples.
        let mut late = History {
            mass: f64::from(TIME_MAX_SPP),
            elapsed: 200.0,
            ..History::default()
        };
        late.passes.push(PassRecord {
            pass: PlannedPass {
                end: 2,
                planned: u64::from(TIME_MAX_SPP),
            },
            seconds: 200.0,
            error: None,
        });
        assert_eq!(
            next_pass(&settings, &late),
            Decision::Pass(PlannedPass { end: 4, planned: 2 }, Some(Stop::Time))
        );
    }

    /// The combination rule, tested where a stop that sees the data would be biased: each
    /// replicate is one pixel whose samples are heavy-tailed (a bright value in 2 % of them
    /// carries three quarters of the mean, so the noise the decisions see predicts the
    /// estimate), rendered to a relative error of 1 % by the planner ([`next_pass`], doubling
    /// passes, the last one sized from the passes before it) and combined by the rule
    /// ([`sample_weight`], [`give`]). Its mean over the replicates is the samples' mean within
    /// the suite's false-alarm limit. The same samples averaged with equal weights, stopped after
    /// the first pass whose own estimate is below the target, are biased low, caught by the
    /// same limit. Also prints what the rule's unequal weights cost: the mean over replicates
    /// of N Σ w²/n, the variance of the image relative to equal weights at the same samples.
    #[test]
    fn planned_weights_are_unbiased_where_a_stop_after_seeing_is_not() {
        use crate::chi2::{FAMILY_FALSE_ALARM, mean_and_standard_error, test_sampler, z_limit};
        let (p, bright, dim) = (0.02, 40.0, 0.5);
        let mean = p * bright + (1.0 - p) * dim / 2.0;
        let (goal, cap, replicates) = (0.01, 512, 20_000);
        let settings = target(goal, cap);
        let mut sampler = test_sampler(46);
        let mut draw = || {
            if sampler.next_1d() < p as f32 {
                bright
            } else {
                dim * f64::from(sampler.next_1d())
            }
        };
        let (mut planned, mut seen, mut cost) = (Vec::new(), Vec::new(), 0.0);
        let mut samples = Vec::with_capacity(cap as usize);
        for _ in 0..replicates {
            samples.clear();
            // The planned rule.
            let mut history = History::default();
            let (mut weighted, mut total, mut squares) = (0.0, 0.0, 0.0);
            while let Decision::Pass(pass, stop) = next_pass(&settings, &history) {
                if history.passes.is_empty() {
                    history.mass = pass.planned as f64;
                }
                let (given, _) = history.given();
                let u = sample_weight(history.mass, given, pass.planned);
                while samples.len() < pass.end as usize {
                    let x = draw();
                    samples.push(x);
                    weighted += u * x;
                    total += x;
                    squares += x * x;
                }
                let n = samples.len() as f64;
                let (given, q) = {
                    history.passes.push(PassRecord {
                        pass,
                        seconds: 0.0,
                        error: None,
                    });
                    history.given()
                };
                // The relative error of the image so far, from every sample so far (the
                // decisions of the next pass may read them all).
                let image = weighted / given;
                let variance = (squares - total * total / n) / (n - 1.0);
                let error = if image > 0.0 {
                    variance * q / (given * given) / (image * image)
                } else {
                    0.0
                };
                // A sample variance of n − 1 degrees of freedom: Var ê = 2ê²/(n − 1).
                history.passes.last_mut().unwrap().error =
                    Some(estimate(error, 2.0 * error * error / (n - 1.0)));
                history.stopped = stop;
            }
            let (given, q) = history.given();
            assert!((given - history.mass).abs() < 1e-9 * history.mass);
            planned.push(weighted / given);
            cost += samples.len() as f64 * q / (given * given);
            // Equal weights, stopped after seeing a pass below the target: the same samples.
            let mut end = 2;
            let estimate = loop {
                let xs = &samples[..end.min(samples.len())];
                let n = xs.len() as f64;
                let m = xs.iter().sum::<f64>() / n;
                let v = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
                if (m > 0.0 && v / n / (m * m) < goal) || xs.len() == samples.len() {
                    break m;
                }
                end *= 2;
            };
            seen.push(estimate);
        }
        let z = |estimates: &[f64]| {
            let (m, se) = mean_and_standard_error(estimates);
            ((m - mean) / se, m / mean - 1.0)
        };
        let limit = z_limit(FAMILY_FALSE_ALARM / 2.0);
        let ((z_planned, bias_planned), (z_seen, bias_seen)) = (z(&planned), z(&seen));
        eprintln!(
            "planned weights: relative bias {bias_planned:+.4} (z = {z_planned:+.2}); equal \
             weights after seeing: {bias_seen:+.4} (z = {z_seen:+.2}); limit {limit:.2}; \
             variance of the planned image over equal weights' at its samples: {:.3}",
            cost / replicates as f64
        );
        assert!(
            z_planned.abs() < limit,
            "the planned rule is biased: z = {z_planned}"
        );
        assert!(
            z_seen.abs() > limit,
            "the biased rule is not caught: z = {z_seen}"
        );
    }

    #[test]
    fn the_prediction_scales_the_bound() {
        // After 2 plain samples (T = M = 2 ... a render planned for 2 more at weight one).
        // Exactly proportional weights: q(n) = 2/(2 + n), bound 0.1, target 0.01 → n = 18.
        let n = samples_for_target(0.01, 0.1, 20.0, 2.0, 2.0);
        assert!((n - 18.0).abs() < 1e-9, "{n}");
        assert!(samples_for_target(0.01, 0.2, 20.0, 2.0, 2.0) > 18.0);
        assert_eq!(samples_for_target(0.0, 0.1, 20.0, 2.0, 2.0), f64::INFINITY);
        // An estimate of 0 bounds nothing: the planner takes it as unknown.
        assert_eq!(estimate(0.0, 0.0).upper_bound(0.95), None);
    }

    /// The looks spend 1 − confidence: half at 16 samples, a quarter at 32, … (any `done` in
    /// between counts as the next look), and the confidences' misses sum to less than 1 − c.
    #[test]
    fn the_stop_confidence_spends_its_error_over_the_looks() {
        let c = 0.95;
        assert!((stop_confidence(c, 16) - 0.975).abs() < 1e-12);
        assert!((stop_confidence(c, 17) - 0.9875).abs() < 1e-12);
        assert!((stop_confidence(c, 32) - 0.9875).abs() < 1e-12);
        let misses: f64 = (0..28).map(|k| 1.0 - stop_confidence(c, 16 << k)).sum();
        assert!(misses < 1.0 - c, "{misses}");
    }
}
