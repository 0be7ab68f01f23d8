//! Renders in passes, measured (docs/study.md, "Renders to a target error"):
//!
//! ```text
//! cargo bench --bench passes -- coverage [--renders R] [--size WxH] [--samples N]
//!     [--target E] [--metric relmse|mse] [--confidence C] [--reference-spp S] SCENE...
//! cargo bench --bench passes -- bias [--renders R] [--size WxH] [--samples N] [--target E]
//!     [--spp S] SCENE...
//! cargo bench --bench passes -- cost [--runs K] [--size WxH] [--samples N] [--spp S]
//!     [--passes P[,P…]] [--raw FILE] SCENE...
//! cargo bench --bench passes -- dump [--renders R] [--size WxH] [--samples N] [--spp S] SCENE...
//! ```
//!
//! `coverage`: per scene, a converged reference (S samples per pixel in 16 renders of
//! independent seeds: its per-pixel mean and the variance of that mean), then R renders to the
//! target error E (seeds 0 … R − 1). For each render the true error e against the reference
//! (the reference's own variance taken out), the stated estimate and interval; over the renders
//! the fraction with e < E (*honest stopping*: at least the confidence) and the fraction whose
//! stated interval holds e (*coverage*: the nominal two-sided confidence), each with its 95 %
//! Wilson interval, the samples and passes used and why the renders stopped; on stderr one line
//! per render (its samples, e, the stated estimate, interval and ν, why it stopped).
//!
//! `bias`: per scene, R renders to the target error (planned weights), R renders of the same
//! target by the biased rule (equal weights, stopped after the first pass whose own estimate is
//! below the target: `Control::Stop`), R renders by a second biased rule (equal weights, each
//! pixel keeping its value from the first pass where its own estimate is below the target), R
//! plain one-pass renders of `--spp` samples compared with, and R more plain renders as the pilot
//! of the pixel weights; seeds disjoint. Each rule against the plain renders: the relative
//! difference of the images' mean luminance with its standard error (Welch) and z; then the
//! suite's per-pixel same-mean comparison (`lumis::same_mean`, as tests/integrators.rs): the
//! weighted relative bias δ̂ over the whole image, its standard error from the renders' weighted
//! sums (a stop couples the pixels of a render), t, Welch–Satterthwaite ν, Student's t limit at
//! half the suite's false-alarm rate (Šidák over the rules), the bias it detects with probability
//! 0.9, and over the blocks of 6² pixels (the other half, Šidák over rules and blocks) the worst
//! block's t against its limit and how many blocks exceed theirs.
//!
//! `cost`: a render of S samples per pixel in P uniform passes (with everything a target render
//! does between passes: the error estimate, a preview resolved and encoded as PNG) against the
//! one-pass render of the same samples, for each P listed, in K interleaved rounds on one thread
//! (each round renders the one-pass render and every P once, in an order that changes from
//! round to round); the images are the same bit for bit. Prints, per P, the ratio of the medians
//! of CPU time, the mean of the rounds' log ratios with its normal 95 % interval, and the
//! Hodges–Lehmann estimate (the median of the log ratios' Walsh averages) with its Wilcoxon
//! signed-rank 95 % interval, which a few rounds slowed by other tenants of the machine move
//! less than they move the mean. `--raw FILE` writes every round's CPU times as CSV.
//!
//! `dump`: R renders of S spp in passes of 2, each pixel's half-images written after 8, 16, …
//! spp (`dump`'s comment says where), for trying error estimators offline against the reference.

use lumis::error_estimate::Metric;
use lumis::passes::{Settings, Stopping};
use lumis::progressive::{Control, RenderState, Scope};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

struct Options {
    mode: String,
    renders: usize,
    width: u32,
    height: u32,
    samples: u32,
    target: f64,
    metric: Metric,
    confidence: f64,
    reference_spp: u32,
    spp: u32,
    passes: Vec<u32>,
    raw: Option<PathBuf>,
    scenes: Vec<PathBuf>,
}

fn from_repository(path: &str) -> PathBuf {
    let p = Path::new(path);
    if p.exists() {
        p.to_path_buf()
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(p)
    }
}

fn options() -> Result<Options, String> {
    let mut o = Options {
        mode: String::new(),
        renders: 200,
        width: 40,
        height: 30,
        samples: 8,
        target: 0.01,
        metric: Metric::RelMse,
        confidence: 0.95,
        reference_spp: 16384,
        spp: 64,
        passes: vec![8],
        raw: None,
        scenes: Vec::new(),
    };
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = |name: &str| -> Result<String, String> {
            args.next().ok_or_else(|| format!("{name} needs a value"))
        };
        let number = |name: &str, text: String| -> Result<f64, String> {
            text.parse::<f64>()
                .map_err(|_| format!("{name}: `{text}` is not a number"))
        };
        match arg.as_str() {
            "--bench" => {}
            "--renders" | "--runs" => o.renders = number(&arg, value(&arg)?)? as usize,
            "--size" => {
                let text = value("--size")?;
                let (w, h) = text.split_once('x').ok_or("--size is WxH, e.g. 40x30")?;
                o.width = number("--size", w.into())? as u32;
                o.height = number("--size", h.into())? as u32;
            }
            "--samples" => o.samples = number(&arg, value(&arg)?)? as u32,
            "--target" => o.target = number(&arg, value(&arg)?)?,
            "--metric" => o.metric = Metric::parse(&value(&arg)?)?,
            "--confidence" => o.confidence = number(&arg, value(&arg)?)?,
            "--reference-spp" => o.reference_spp = number(&arg, value(&arg)?)? as u32,
            "--spp" => o.spp = number(&arg, value(&arg)?)? as u32,
            "--passes" => {
                o.passes = value(&arg)?
                    .split(',')
                    .map(|p| number("--passes", p.into()).map(|p| p as u32))
                    .collect::<Result<_, _>>()?
            }
            "--raw" => o.raw = Some(PathBuf::from(value(&arg)?)),
            flag if flag.starts_with("--") => return Err(format!("unknown option {flag}")),
            word if o.mode.is_empty() => o.mode = word.to_string(),
            scene => o.scenes.push(from_repository(scene)),
        }
    }
    if !["coverage", "cost", "calibration", "bias", "dump"].contains(&o.mode.as_str())
        || o.scenes.is_empty()
    {
        return Err("usage: passes coverage|calibration|bias|cost|dump [options] SCENE...".into());
    }
    Ok(o)
}

fn cpu_time() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer.
    if unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) } == 0 {
        t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
    } else {
        f64::NAN
    }
}

fn load(o: &Options, scene: &Path, extra: &[String]) -> lumis::scene::load::LoadedScene {
    let mut overrides = vec![
        format!("film.width={}", o.width),
        format!("film.height={}", o.height),
        format!("integrator.samples={}", o.samples),
        "integrator.aovs=[]".to_string(),
    ];
    overrides.extend(extra.iter().cloned());
    lumis::scene::load::load_scene(scene, &overrides)
        .unwrap_or_else(|e| panic!("{}: {e}", scene.display()))
}

fn luminance(film: &lumis::film::Film) -> Vec<f64> {
    film.color
        .iter()
        .map(|c| lumis::math::luminance(*c) as f64)
        .collect()
}

/// The reference's per-pixel mean luminance and the variance of that mean, from 16 renders;
/// cached in the temporary directory by scene, size, samples and spp.
fn reference(o: &Options, scene: &Path) -> (Vec<f64>, Vec<f64>) {
    const PARTS: u32 = 16;
    let cache = std::env::temp_dir().join(format!(
        "lumis-passes-reference-{}-{}x{}-{}-{}.txt",
        scene.file_stem().unwrap().to_string_lossy(),
        o.width,
        o.height,
        o.samples,
        o.reference_spp
    ));
    if let Ok(text) = std::fs::read_to_string(&cache) {
        let values: Vec<f64> = text
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect();
        let n = values.len() / 2;
        return (values[..n].to_vec(), values[n..].to_vec());
    }
    let mut loaded = load(
        o,
        scene,
        &[format!("sampler.spp={}", (o.reference_spp / PARTS).max(1))],
    );
    let mut images = Vec::new();
    for part in 0..PARTS {
        loaded.scene.seed = 1_000_000 + u64::from(part);
        loaded.integrator.preprocess(&loaded.scene);
        let (film, _) =
            lumis::render::render(&loaded.scene, loaded.integrator.as_ref(), 0, &|_| {})
                .expect("render");
        images.push(luminance(&film));
    }
    let n = f64::from(PARTS);
    let pixels = images[0].len();
    let mean: Vec<f64> = (0..pixels)
        .map(|p| images.iter().map(|i| i[p]).sum::<f64>() / n)
        .collect();
    let variance: Vec<f64> = (0..pixels)
        .map(|p| images.iter().map(|i| (i[p] - mean[p]).powi(2)).sum::<f64>() / (n - 1.0) / n)
        .collect();
    let text: Vec<String> = mean
        .iter()
        .chain(&variance)
        .map(|v| format!("{v:e}"))
        .collect();
    std::fs::write(&cache, text.join(" ")).expect("the reference cache");
    (mean, variance)
}

/// The true error of `image` against the reference, its own variance taken out.
fn true_error(image: &[f64], reference: &(Vec<f64>, Vec<f64>), metric: Metric) -> f64 {
    let (mean, variance) = reference;
    let epsilon = match metric {
        Metric::RelMse => (0.01 * mean.iter().sum::<f64>() / mean.len() as f64).powi(2),
        Metric::Mse => 0.0,
    };
    image
        .iter()
        .zip(mean.iter().zip(variance))
        .map(|(y, (m, v))| {
            let d = match metric {
                Metric::RelMse => m * m + epsilon,
                Metric::Mse => 1.0,
            };
            if d > 0.0 {
                ((y - m).powi(2) - v) / d
            } else {
                0.0
            }
        })
        .sum::<f64>()
        / image.len() as f64
}

/// The 95 % Wilson interval of `k` successes in `n` trials.
fn wilson(k: usize, n: usize) -> (f64, f64) {
    let (k, n, z) = (k as f64, n as f64, 1.959_964);
    let centre = (k + z * z / 2.0) / (n + z * z);
    let half = z / (n + z * z) * (k * (n - k) / n + z * z / 4.0).sqrt();
    (centre - half, centre + half)
}

fn coverage(o: &Options, scene: &Path) {
    let reference = reference(o, scene);
    let settings = Settings {
        stopping: Stopping::Target {
            error: o.target,
            max_spp: lumis::passes::DEFAULT_MAX_SPP,
            max_time: None,
        },
        metric: o.metric,
        confidence: o.confidence,
    };
    let mut loaded = load(o, scene, &[]);
    let (mut below, mut covered, mut above_high, mut spp, mut passes) = (0, 0, 0, Vec::new(), 0);
    let (mut ratio, mut stops) = (0.0, std::collections::BTreeMap::new());
    // N Q / M²: the image's variance relative to equal weights over the same samples.
    let mut weights_cost = Vec::new();
    for seed in 0..o.renders {
        loaded.scene.seed = seed as u64;
        loaded.integrator.preprocess(&loaded.scene);
        let mut state = RenderState::new(&loaded.scene, loaded.integrator.as_ref(), &settings);
        run_passes(&mut loaded, &settings, &mut state, 0, &mut |_| {
            Control::Continue
        });
        let film = state
            .sums
            .resolve(&loaded.scene, loaded.integrator.as_ref());
        let e = true_error(&luminance(&film), &reference, o.metric);
        let stated = state.history.error().expect("an error estimate");
        // One line per render on stderr, for looking at the misses.
        eprintln!(
            "{} seed {seed}: {} spp, e {e:.5}, stated {:.5} [{:.5}, {:.5}], nu {:.1}, {}",
            scene.file_stem().unwrap().to_string_lossy(),
            state.history.samples(),
            stated.value,
            stated.low,
            stated.high,
            stated.degrees_of_freedom().unwrap_or(f64::NAN),
            state.history.stopped.map_or("none", |s| s.name())
        );
        below += usize::from(e < o.target);
        covered += usize::from(stated.low <= e && e <= stated.high);
        above_high += usize::from(e > stated.high);
        ratio += stated.value / e;
        spp.push(state.history.samples());
        let (given, squares) = state.history.given();
        weights_cost.push(f64::from(state.history.samples()) * squares / (given * given));
        passes += state.history.passes.len();
        *stops
            .entry(state.history.stopped.map_or("none", |s| s.name()))
            .or_insert(0) += 1;
    }
    let n = o.renders;
    let (b_lo, b_hi) = wilson(below, n);
    let (c_lo, c_hi) = wilson(covered, n);
    spp.sort_unstable();
    let cost_mean = weights_cost.iter().sum::<f64>() / n as f64;
    let cost_max = weights_cost.iter().copied().fold(0.0, f64::max);
    println!(
        "| {} | {} | {} | {:.3} [{:.3}, {:.3}] | {:.3} [{:.3}, {:.3}] | {:.3} | {:.3} | {} [{}, {}] | {:.1} | {:.3} (max {:.3}) | {:?} |",
        scene.file_stem().unwrap().to_string_lossy(),
        o.target,
        n,
        below as f64 / n as f64,
        b_lo,
        b_hi,
        covered as f64 / n as f64,
        c_lo,
        c_hi,
        above_high as f64 / n as f64,
        ratio / n as f64,
        spp[n / 2],
        spp[0],
        spp[n - 1],
        passes as f64 / n as f64,
        cost_mean,
        cost_max,
        stops
    );
}

/// The error estimates at fixed samples (two passes of half the samples each) against the true
/// error: the half-image estimate itself and the stated one (raised for its small-sample bias
/// from the two passes), the mean of each over the true error's and how often their intervals
/// hold it.
fn calibration(o: &Options, scene: &Path) {
    let reference = reference(o, scene);
    let mut loaded = load(o, scene, &[]);
    for spp in [4u32, 8, 16, 32, 64, 128, 256, 512, 1024] {
        if spp > o.spp {
            break;
        }
        let settings = Settings {
            stopping: Stopping::Samples { spp, passes: 2 },
            metric: o.metric,
            confidence: o.confidence,
        };
        let (mut truth, mut raw, mut stated, mut raw_covered, mut covered) = (0.0, 0.0, 0.0, 0, 0);
        for seed in 0..o.renders {
            loaded.scene.seed = seed as u64;
            loaded.scene.spp = spp;
            loaded.integrator.preprocess(&loaded.scene);
            let mut state = RenderState::new(&loaded.scene, loaded.integrator.as_ref(), &settings);
            run_passes(&mut loaded, &settings, &mut state, 0, &mut |_| {
                Control::Continue
            });
            let film = state
                .sums
                .resolve(&loaded.scene, loaded.integrator.as_ref());
            let e = true_error(&luminance(&film), &reference, o.metric);
            let (r, s) = (
                state.history.raw_error().expect("an estimate"),
                state.history.error().expect("an estimate"),
            );
            truth += e;
            raw += r.value;
            stated += s.value;
            raw_covered += usize::from(r.low <= e && e <= r.high);
            covered += usize::from(s.low <= e && e <= s.high);
        }
        let r = o.renders as f64;
        println!(
            "| {} | {spp} | {:.3e} | {:.3} | {:.3} | {:.3} | {:.3} |",
            scene.file_stem().unwrap().to_string_lossy(),
            truth / r,
            raw / truth,
            stated / truth,
            raw_covered as f64 / r,
            covered as f64 / r
        );
    }
}

/// The image's luminance (row order) after a render of `settings` from seed `seed`;
/// `stop_below`: stop after the first pass whose own error estimate is below it (the biased rule).
fn render_luminance(
    loaded: &mut lumis::scene::load::LoadedScene,
    settings: &Settings,
    seed: u64,
    stop_below: Option<f64>,
) -> Vec<f64> {
    loaded.scene.seed = seed;
    loaded.integrator.preprocess(&loaded.scene);
    let mut state = RenderState::new(&loaded.scene, loaded.integrator.as_ref(), settings);
    let mut stop = |state: &RenderState| match (stop_below, state.history.raw_error()) {
        (Some(target), Some(e)) if e.value < target => Control::Stop,
        _ => Control::Continue,
    };
    run_passes(loaded, settings, &mut state, 0, &mut stop);
    luminance(
        &state
            .sums
            .resolve(&loaded.scene, loaded.integrator.as_ref()),
    )
}

/// The second biased rule, pixel by pixel: a render in passes of `settings` (equal weights) from
/// seed `seed` in which each pixel keeps the luminance it had after the first pass where its own
/// relative error estimate, (A − B)² / (A + B)² from its half-images, is below `target` (or its
/// last, if none is); the render stops once every pixel has.
fn render_luminance_per_pixel_stop(
    loaded: &mut lumis::scene::load::LoadedScene,
    settings: &Settings,
    seed: u64,
    target: f64,
) -> Vec<f64> {
    loaded.scene.seed = seed;
    loaded.integrator.preprocess(&loaded.scene);
    let mut state = RenderState::new(&loaded.scene, loaded.integrator.as_ref(), settings);
    let mut kept: Vec<Option<f64>> = Vec::new();
    let mut last = Vec::new();
    run_passes(loaded, settings, &mut state, 0, &mut |state| {
        let sums = &state.sums;
        last = luminance(&sums.resolve_color());
        kept.resize(last.len(), None);
        for p in (0..sums.samples.len()).filter(|&p| sums.samples[p] > 0) {
            let r = sums.row_index(p);
            let [a, b] = sums.halves[p];
            let estimate = if a + b > 0.0 {
                ((a - b) / (a + b)).powi(2)
            } else {
                0.0
            };
            if kept[r].is_none() && estimate < target {
                kept[r] = Some(last[r]);
            }
        }
        if kept.iter().all(Option::is_some) {
            Control::Stop
        } else {
            Control::Continue
        }
    });
    kept.iter()
        .zip(&last)
        .map(|(k, l)| k.unwrap_or(*l))
        .collect()
}

/// The samples per pixel of the per-pixel biased rule's passes (of 2 each): pixels whose own
/// estimate never falls below the target keep their value at this count.
const PER_PIXEL_CAP: u32 = 1024;

fn bias(o: &Options, scene: &Path) {
    use lumis::chi2::{FAMILY_FALSE_ALARM, mean_and_standard_error, sidak};
    use lumis::same_mean::{Comparison, PixelMeans, Z_POWER_90, blocks, t_limit, weights};
    let mut loaded = load(o, scene, &[format!("sampler.spp={}", o.spp)]);
    let cap = lumis::passes::DEFAULT_MAX_SPP;
    let planned = Settings {
        stopping: Stopping::Target {
            error: o.target,
            max_spp: cap,
            max_time: None,
        },
        metric: o.metric,
        confidence: o.confidence,
    };
    // Passes of 2 samples with every weight one (each planned for what remains of the cap).
    let equal = |cap: u32| Settings {
        stopping: Stopping::Samples {
            spp: cap,
            passes: cap / 2,
        },
        metric: o.metric,
        confidence: o.confidence,
    };
    let plain = Settings::samples(o.spp);
    let r = o.renders as u64;
    let mut runs =
        |render: &mut dyn FnMut(&mut lumis::scene::load::LoadedScene, u64) -> Vec<f64>,
         first: u64| {
            PixelMeans::new((first..first + r).map(|s| render(&mut loaded, s)).collect())
        };
    // The pilot (for the pixel weights) and the plain renders compared with, seeds disjoint from
    // each other and from every rule's.
    let pilot = runs(&mut |l, s| render_luminance(l, &plain, s, None), 3_000_000);
    let reference = runs(&mut |l, s| render_luminance(l, &plain, s, None), 2_000_000);
    let rules = [
        (
            "planned weights",
            runs(&mut |l, s| render_luminance(l, &planned, s, None), 0),
        ),
        (
            "equal weights, image stopped after seeing",
            runs(
                &mut |l, s| render_luminance(l, &equal(cap), s, Some(o.target)),
                1_000_000,
            ),
        ),
        (
            "equal weights, pixels stopped after seeing",
            runs(
                &mut |l, s| render_luminance_per_pixel_stop(l, &equal(PER_PIXEL_CAP), s, o.target),
                4_000_000,
            ),
        ),
    ];
    // A rule's render spends its samples evenly over the pixels, so its per-pixel variance is
    // the plain render's scaled by one factor for the whole image: the plain pilot's relative
    // variances give weights proportional to the rule's own (the scale cancels in δ̂).
    let weights = weights(&pilot, &pilot, r, r);
    let blocks = blocks(o.width as usize, o.height as usize);
    let whole_alpha = sidak(FAMILY_FALSE_ALARM / 2.0, rules.len());
    let block_alpha = sidak(FAMILY_FALSE_ALARM / 2.0, rules.len() * blocks.len());
    let image_mean = |images: &PixelMeans| -> Vec<f64> {
        images
            .images
            .iter()
            .map(|y| y.iter().sum::<f64>() / y.len() as f64)
            .collect()
    };
    let (m0, se0) = mean_and_standard_error(&image_mean(&reference));
    for (rule, tested) in &rules {
        // Every rule's stop is one decision for the whole image (or couples its pixels through
        // the passes' common plan): its pixels are compared as coupled, by the runs' weighted
        // sums, with runs − 1 degrees of freedom.
        let comparison = |pixels: &mut dyn Iterator<Item = usize>| {
            Comparison::new(tested, &reference, &weights, &pilot.mean, pixels, true)
        };
        let whole = comparison(&mut (0..tested.mean.len()));
        let limit = t_limit(whole_alpha, whole.degrees_of_freedom);
        let (mut worst, mut worst_limit, mut over) = (0.0f64, f64::NAN, 0);
        for block in &blocks {
            let c = comparison(&mut block.iter().copied());
            if c.standard_error.is_nan() {
                continue; // no pixel of positive variance
            }
            let block_limit = t_limit(block_alpha, c.degrees_of_freedom);
            over += usize::from(c.t().abs() >= block_limit);
            if c.t().abs() > worst.abs() || worst_limit.is_nan() {
                (worst, worst_limit) = (c.t(), block_limit);
            }
        }
        let (m, se) = mean_and_standard_error(&image_mean(tested));
        let image_se = se.hypot(se0) / m0;
        println!(
            "| {} | {} | {rule} | {} | {:+.4} ± {:.4} (z {:+.2}) | {:+.4} | {:.4} | {:+.2} | {:.0} | {:.2} | {:.2} % | {:+.2} / {:.2} | {over} of {} |",
            scene.file_stem().unwrap().to_string_lossy(),
            o.target,
            o.renders,
            m / m0 - 1.0,
            image_se,
            (m / m0 - 1.0) / image_se,
            whole.relative_bias,
            whole.standard_error,
            whole.t(),
            whole.degrees_of_freedom,
            limit,
            100.0 * (limit + Z_POWER_90) * whole.standard_error,
            worst,
            worst_limit,
            blocks.len()
        );
    }
}

fn cost(o: &Options, scene: &Path) {
    let mut loaded = load(o, scene, &[format!("sampler.spp={}", o.spp)]);
    loaded.integrator.preprocess(&loaded.scene);
    let dir = tempfile::tempdir().expect("a temporary directory");
    let preview = dir.path().join("preview.exr");
    // Contender 0 is the one-pass render, contender k the render in `o.passes[k - 1]` passes.
    let contenders = o.passes.len() + 1;
    let mut times = vec![Vec::with_capacity(o.renders); contenders];
    let mut order: Vec<usize> = (0..contenders).collect();
    for run in 0..o.renders {
        // Each round in the next rotation of the contenders, reversed every other round, so
        // that none is always first or always after the same one.
        order.rotate_left(1);
        let mut round = order.clone();
        if run % 2 == 1 {
            round.reverse();
        }
        for &which in &round {
            let start = cpu_time();
            let film = if which == 0 {
                lumis::render::render(&loaded.scene, loaded.integrator.as_ref(), 1, &|_| {})
                    .expect("render")
                    .0
            } else {
                let settings = Settings {
                    stopping: Stopping::Samples {
                        spp: o.spp,
                        passes: o.passes[which - 1],
                    },
                    ..Settings::samples(o.spp)
                };
                let mut state =
                    RenderState::new(&loaded.scene, loaded.integrator.as_ref(), &settings);
                run_passes(&mut loaded, &settings, &mut state, 1, &mut |state| {
                    lumis::render_files::write_previews(&state.sums, &preview, 0.0, None)
                        .expect("preview");
                    Control::Continue
                });
                state
                    .sums
                    .resolve(&loaded.scene, loaded.integrator.as_ref())
            };
            times[which].push(cpu_time() - start);
            std::hint::black_box(film);
        }
    }
    if let Some(raw) = &o.raw {
        let mut csv = String::from("round,one_pass");
        for p in &o.passes {
            csv += &format!(",passes_{p}");
        }
        for run in 0..o.renders {
            csv += &format!("\n{run}");
            for t in &times {
                csv += &format!(",{:.6}", t[run]);
            }
        }
        std::fs::write(raw, csv + "\n").expect("the raw times written");
    }
    let median = |v: &[f64]| {
        let mut v = v.to_vec();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    for (k, passes) in o.passes.iter().enumerate() {
        let logs: Vec<f64> = times[k + 1]
            .iter()
            .zip(&times[0])
            .map(|(p, one)| (p / one).ln())
            .collect();
        let n = logs.len() as f64;
        let mean = logs.iter().sum::<f64>() / n;
        let sd = (logs.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let (low, high) = (mean - 1.96 * sd / n.sqrt(), mean + 1.96 * sd / n.sqrt());
        let (hl, hl_low, hl_high) = hodges_lehmann(&logs);
        println!(
            "{}: {} spp in {passes} passes against one pass, {} rounds on one thread: medians {:.4} s and {:.4} s, ratio of the medians {:.4}; mean log ratio {:.4} [{:.4}, {:.4}]; Hodges-Lehmann {:.4} [{:.4}, {:.4}]",
            scene.display(),
            o.spp,
            o.renders,
            median(&times[k + 1]),
            median(&times[0]),
            median(&times[k + 1]) / median(&times[0]),
            mean.exp(),
            low.exp(),
            high.exp(),
            hl.exp(),
            hl_low.exp(),
            hl_high.exp(),
        );
    }
}

/// The Hodges–Lehmann estimate of the centre of `x` (the median of the Walsh averages
/// (x_i + x_j)/2, i ≤ j) with the 95 % interval that inverts Wilcoxon's signed-rank test (normal
/// approximation to its critical rank, fine from a few dozen values on): (estimate, low, high).
fn hodges_lehmann(x: &[f64]) -> (f64, f64, f64) {
    let n = x.len();
    let mut walsh = Vec::with_capacity(n * (n + 1) / 2);
    for i in 0..n {
        for j in i..n {
            walsh.push(0.5 * (x[i] + x[j]));
        }
    }
    walsh.sort_by(f64::total_cmp);
    let m = walsh.len();
    let nf = n as f64;
    let spread = (nf * (nf + 1.0) * (2.0 * nf + 1.0) / 24.0).sqrt();
    let k = ((nf * (nf + 1.0) / 4.0 - 1.959_964 * spread)
        .floor()
        .max(0.0) as usize)
        .min(m - 1);
    let centre = if m % 2 == 1 {
        walsh[m / 2]
    } else {
        0.5 * (walsh[m / 2 - 1] + walsh[m / 2])
    };
    (centre, walsh[k], walsh[m - 1 - k])
}

/// Per seed, after each pass ending at a power of two from 8 spp on (passes of 2 samples, every
/// weight one): per pixel in row order the half-images A and B, as little-endian f64 to
/// $TMPDIR/lumis-passes-dump-SCENE.bin (seed-major, then spp, then A, then B), beside the
/// reference's cache: what an error estimator can be tried on offline.
fn dump(o: &Options, scene: &Path) {
    use std::io::Write;
    let _ = reference(o, scene);
    let mut loaded = load(o, scene, &[]);
    let settings = Settings {
        stopping: Stopping::Samples {
            spp: o.spp,
            passes: o.spp / 2,
        },
        metric: o.metric,
        confidence: o.confidence,
    };
    let path = std::env::temp_dir().join(format!(
        "lumis-passes-dump-{}.bin",
        scene.file_stem().unwrap().to_string_lossy()
    ));
    let mut out = std::io::BufWriter::new(std::fs::File::create(&path).expect("dump"));
    for seed in 0..o.renders {
        loaded.scene.seed = seed as u64;
        loaded.integrator.preprocess(&loaded.scene);
        let mut state = RenderState::new(&loaded.scene, loaded.integrator.as_ref(), &settings);
        let mut frames: Vec<Vec<f64>> = Vec::new();
        run_passes(&mut loaded, &settings, &mut state, 0, &mut |state| {
            let end = state.history.samples();
            if end >= 8 && end.is_power_of_two() {
                let sums = &state.sums;
                let n = sums.samples.len();
                let mut a = vec![0.0; n];
                let mut b = vec![0.0; n];
                for p in 0..n {
                    let half = sums.weight[p] / 2.0;
                    let r = sums.row_index(p);
                    a[r] = sums.halves[p][0] / half;
                    b[r] = sums.halves[p][1] / half;
                }
                frames.push(a);
                frames.push(b);
            }
            Control::Continue
        });
        for f in &frames {
            for v in f {
                out.write_all(&v.to_le_bytes()).unwrap();
            }
        }
    }
    eprintln!("{}", path.display());
}

/// Renders the passes `settings` plan on `loaded` from `state` (to its end) on `threads` threads
/// (0: one per core), calling `on_pass` after each pass.
fn run_passes(
    loaded: &mut lumis::scene::load::LoadedScene,
    settings: &Settings,
    state: &mut RenderState,
    threads: usize,
    on_pass: &mut dyn FnMut(&RenderState) -> Control,
) {
    lumis::progressive::run(
        &loaded.scene,
        loaded.integrator.as_mut(),
        settings,
        state,
        Scope::whole(threads),
        &AtomicBool::new(false),
        &|_| {},
        on_pass,
    )
    .expect("render");
}

fn main() {
    lumis::link_plugins();
    let o = match options() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    };
    if o.mode == "coverage" {
        println!(
            "| scene | target | renders | e < E | interval holds e | e above interval | mean ê/e | spp median [min, max] | passes | N·Σu²n/M² | stops |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
    }
    if o.mode == "calibration" {
        println!(
            "| scene | spp | mean e | half-image ê / e | stated ê / e | coverage (half-image) | coverage (stated) |"
        );
        println!("|---|---|---|---|---|---|---|");
    }
    if o.mode == "bias" {
        println!(
            "| scene | target | rule | renders | image mean: relative bias ± se (z) | δ̂ | standard error | t | ν | limit | detected with probability 0.9 | worst block t / limit | blocks over their limit |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    }
    for scene in &o.scenes {
        match o.mode.as_str() {
            "coverage" => coverage(&o, scene),
            "bias" => bias(&o, scene),
            "calibration" => calibration(&o, scene),
            "dump" => dump(&o, scene),
            _ => cost(&o, scene),
        }
    }
}
