//! `lumis render`: a plain render of the scene's samples, a render in passes (to a target error,
//! within a time, in fixed passes, replayed, resumed), or a shard of either.
//!
//! Over 600 lines: the options, their checks and the three ways of rendering share the
//! argument struct and the summary and state-file helpers.

use crate::interrupt;
use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lumis::budgets::Budgets;
use lumis::error_estimate::Metric;
use lumis::passes::{self, Settings, Stop, Stopping};
use lumis::progressive::{Control, Ending, RenderState, Scope};
use lumis::render::Shard;
use lumis::render_files::{self, error_text};
use lumis::shards::{BUDGETS_KEY, ShardFile};
use lumis::{image_io, limits};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

#[derive(clap::Args)]
pub struct RenderArgs {
    /// The scene file (RON).
    scene: PathBuf,
    /// Output EXR; the PNG preview is written beside it with the extension .png.
    /// Default: the film's `output`, or the scene's name + .exr in the current directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Camera samples per pixel (overrides sampler.spp).
    #[arg(long, conflicts_with_all = ["target_error", "time"])]
    spp: Option<u32>,
    /// Random seed (overrides sampler.seed).
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads (default: one per core; more than the machine's hardware threads are
    /// reduced to that number, which a CPU-bound render cannot exceed usefully).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Memory the render may use, e.g. 8G or 512M, or `none` (default: the memory available,
    /// MemAvailable in /proc/meminfo; or the LUMIS_MEMORY_LIMIT environment variable). A scene
    /// estimated to need more is refused before anything large is allocated.
    #[arg(long, value_name = "SIZE")]
    memory_limit: Option<String>,
    /// The widest SIMD lanes of the batch kernels: 4, 8 [default] or 16. Eight need AVX2 and
    /// sixteen AVX-512; a processor without them runs the widest it has. The image is the
    /// same, bit for bit, at every width; only the time differs.
    #[arg(long, value_name = "W", value_parser = parse_lanes)]
    lanes: Option<usize>,
    /// Override any scene value by its path, e.g. --set integrator.type=balance
    /// --set integrator.samples=64 --set film.width=128 (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    overrides: Vec<String>,
    /// Exposure of the PNG preview in stops (overrides film.exposure).
    #[arg(long)]
    exposure: Option<f32>,
    /// No progress bar and no summary line. (When stderr is not a terminal, progress is a plain
    /// line `progress: K of N pixels` at each tenth of the image, or a line per pass.)
    #[arg(short, long)]
    quiet: bool,
    /// Render only shard I of N (0 ≤ I < N): every Nth tile, with the seeds of the whole render,
    /// written as sums (--output, default NAME.shard-I-of-N.lshard beside the EXR) for
    /// `lumis merge`. A render in passes renders one pass per shard and merge; the shards of
    /// the next pass --resume from the merged state.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Render in passes until the image's estimated error is below E with the --confidence, or
    /// until a cap: --max-spp (default 4096 samples per pixel) or --max-time. The error is
    /// --metric's, estimated from two half-images (even and odd samples) and stated with its
    /// interval; the last pass is sized before it runs, so that the image is unbiased, and the
    /// render ends with at least 128 samples per pixel (fewer only at a cap). An estimated error of 0 (no sample has found any light) is
    /// unknown, not zero: such a render runs to its cap.
    #[arg(long, allow_negative_numbers = true, value_name = "E", conflicts_with_all = ["time", "passes", "replay"])]
    target_error: Option<f64>,
    /// The error a render in passes estimates (and --target-error is in): `relmse`, the
    /// luminance's squared error over (Y² + ε) averaged over the pixels, ε = (0.01 × the mean
    /// luminance)² [default]; or `mse`, the squared error averaged over the pixels.
    #[arg(long)]
    metric: Option<String>,
    /// Confidence of the stated error interval and of a --target-error stop [default: 0.95].
    #[arg(long, allow_negative_numbers = true)]
    confidence: Option<f64>,
    /// With --target-error or --time: at most S camera samples per pixel (with --target-error
    /// the default is 4096).
    #[arg(long, value_name = "S")]
    max_spp: Option<u32>,
    /// With --target-error: stop after T seconds of rendering (the passes are then recorded for
    /// --replay).
    #[arg(long, allow_negative_numbers = true, value_name = "T")]
    max_time: Option<f64>,
    /// Render in passes the best image T seconds allow; the passes are recorded in the EXR, so
    /// that --replay renders the same image.
    #[arg(long, allow_negative_numbers = true, value_name = "T", conflicts_with_all = ["passes", "replay", "max_time"])]
    time: Option<f64>,
    /// Render the --spp samples in K passes (a preview after each; resumable after an
    /// interrupt): the image is the one-pass render's, bit for bit.
    #[arg(long, value_name = "K", conflicts_with = "replay")]
    passes: Option<u32>,
    /// Render the passes recorded in the metadata of EXR (a --time or --target-error render)
    /// again: the same image, bit for bit, on any machine and thread count.
    #[arg(long, value_name = "EXR")]
    replay: Option<PathBuf>,
    /// Continue the render in passes saved in FILE (written beside the EXR, NAME.lshard, when
    /// one is interrupted; or merged from shards): give the same scene, overrides and settings.
    #[arg(long, value_name = "FILE")]
    resume: Option<PathBuf>,
    /// With a render in passes: also write an error heat map, NAME.error.png, after each pass
    /// (each pixel's error over its 3 × 3 neighbourhood relative to the image's, log scale:
    /// black 1/100, red 1, white 100 times the image's).
    #[arg(long)]
    heat_map: bool,
    /// How a render in passes spreads each pass's samples over the pixels: `uniform` (the same
    /// for all) [default], or `per-pixel`: in proportion to the square root of each pixel's
    /// variance per sample (relative for --metric relmse) measured on the passes before, with a
    /// floor and a dilation; still unbiased (docs/integrators.md, "Per-pixel budgets"). Needs
    /// passes of even sizes; an interrupt drops the pass cut short (so that --resume continues
    /// into the uninterrupted image); --replay reads it from the EXR.
    #[arg(long, value_name = "B")]
    budgets: Option<String>,
}

impl RenderArgs {
    /// The worker threads asked for (0: one per core).
    pub fn threads(&self) -> usize {
        self.threads
    }
}

/// The settings of a render in passes from the arguments; `None` for a plain render.
fn settings(args: &RenderArgs, spp: u32) -> Result<Option<Settings>> {
    let request = passes::Request {
        target_error: args.target_error,
        time: args.time,
        passes: args.passes,
        replay: args.replay.as_deref().map(replayed_passes).transpose()?,
        metric: args
            .metric
            .as_deref()
            .map(Metric::parse)
            .transpose()
            .map_err(anyhow::Error::msg)?,
        confidence: args.confidence,
        max_spp: args.max_spp,
        max_time: args.max_time,
    };
    let settings = request
        .settings(spp, |key| format!("--{}", key.replace('_', "-")))
        .map_err(anyhow::Error::msg)?;
    if settings.is_none() && args.heat_map {
        bail!(
            "--heat-map applies to a render in passes (--target-error, --time, --passes, --replay)"
        );
    }
    Ok(settings)
}

/// The budgets asked for, checked against the render: per-pixel budgets read the half-images of
/// the passes before (so every pass has an even number of samples).
fn budgets(args: &RenderArgs, settings: Option<&Settings>) -> Result<Budgets> {
    let asked = args
        .budgets
        .as_deref()
        .map(Budgets::parse)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    // A replay renders the recorded passes with the budgets recorded beside them.
    let recorded = args.replay.as_deref().map(replayed_budgets).transpose()?;
    if let (Some(asked), Some(recorded), Some(exr)) = (asked, recorded, &args.replay)
        && asked != recorded
    {
        bail!(
            "cannot replay `{}`: it was rendered with --budgets {}, this render asks for {}",
            exr.display(),
            recorded.name(),
            asked.name()
        );
    }
    let budgets = asked.or(recorded).unwrap_or_default();
    let name = budgets.name();
    if budgets == Budgets::Uniform {
        return Ok(budgets);
    }
    let Some(settings) = settings else {
        bail!(
            "--budgets {name} applies to a render in passes (--target-error, --time, --passes, --replay)"
        );
    };
    if !settings.estimates_error() {
        bail!(
            "--budgets {name} needs passes of even sizes (it reads the half-images of the passes before): give --passes K with an even --spp of at least 2K"
        );
    }
    Ok(budgets)
}

/// The budgets the EXR at `path` was rendered with (uniform if it records none).
fn replayed_budgets(path: &Path) -> Result<Budgets> {
    let metadata = image_io::read_exr_metadata(path).map_err(anyhow::Error::msg)?;
    let Some((_, name)) = metadata.iter().find(|(k, _)| k == BUDGETS_KEY) else {
        return Ok(Budgets::Uniform);
    };
    Budgets::parse(name).map_err(|e| anyhow::anyhow!("cannot replay `{}`: {e}", path.display()))
}

/// The passes recorded in the EXR at `path`.
fn replayed_passes(path: &Path) -> Result<Vec<passes::PlannedPass>> {
    let metadata = image_io::read_exr_metadata(path).map_err(anyhow::Error::msg)?;
    render_files::recorded_passes(&metadata)
        .map_err(|e| anyhow::anyhow!("cannot replay `{}`: {e}", path.display()))
}

/// The replayed EXR's seed and integrator (with its parameters) must be the render's: the
/// passes replay that render.
fn check_replay(
    path: &Path,
    seed: u64,
    integrator: &lumis::scene::description::PluginSpec,
) -> Result<()> {
    let theirs = image_io::read_exr_metadata(path).map_err(anyhow::Error::msg)?;
    let ours = render_files::metadata("", integrator, 0, seed, &empty_stats());
    let relevant = |m: &image_io::Metadata| -> std::collections::BTreeMap<String, String> {
        m.iter()
            .filter(|(k, _)| k == "seed" || k == "integrator" || k.starts_with("integrator."))
            .cloned()
            .collect()
    };
    let (ours, theirs) = (relevant(&ours), relevant(&theirs));
    for key in ours.keys().chain(theirs.keys()) {
        let (a, b) = (ours.get(key), theirs.get(key));
        if a != b {
            bail!(
                "cannot replay `{}`: it was rendered with {key} {}, this render has {}",
                path.display(),
                b.map_or("unset", String::as_str),
                a.map_or("unset", String::as_str)
            );
        }
    }
    Ok(())
}

fn empty_stats() -> lumis::render::RenderStats {
    lumis::render::RenderStats {
        wall_time: std::time::Duration::ZERO,
        camera_samples: 0,
        rays: 0,
        threads: 0,
        pixels_done: 0,
        pixels_total: 0,
        tiles_done: 0,
        tiles_total: 0,
    }
}

/// The settings as options of `lumis render`, for messages.
fn settings_text(settings: &Settings) -> String {
    let stopping = match &settings.stopping {
        Stopping::Samples { spp, passes } => format!("--spp {spp} --passes {passes}"),
        Stopping::Target {
            error,
            max_spp,
            max_time,
        } => format!(
            "--target-error {error} --max-spp {max_spp}{}",
            max_time.map_or(String::new(), |t| format!(" --max-time {t}"))
        ),
        Stopping::Time { seconds, max_spp } => format!("--time {seconds} --max-spp {max_spp}"),
        Stopping::Replay(passes) => format!("--replay ({} passes)", passes.len()),
    };
    format!(
        "{stopping} --metric {} --confidence {}",
        settings.metric.name(),
        settings.confidence
    )
}

/// A render's saved state, checked to be this render's: the same scene file (unchanged), the
/// same overrides, settings and budgets; a whole render (not one shard of it).
fn resumed_state(
    path: &Path,
    scene: &Path,
    overrides: &[String],
    settings: &Settings,
    budgets: Budgets,
) -> Result<RenderState> {
    let file = ShardFile::read(path)?;
    let scene = std::path::absolute(scene)
        .with_context(|| format!("cannot resolve `{}`", scene.display()))?;
    if file.scene_path != scene {
        bail!(
            "`{}` is a render of `{}`, not of `{}`",
            path.display(),
            file.scene_path.display(),
            scene.display()
        );
    }
    if lumis::shards::file_hash(&scene)? != file.scene_hash {
        bail!(
            "the scene `{}` has changed since `{}` was saved: its render cannot continue",
            scene.display(),
            path.display()
        );
    }
    if file.overrides != overrides {
        bail!(
            "`{}` was rendered with the overrides [{}], this render has [{}] (--set, --spp and --seed)",
            path.display(),
            file.overrides.join(" "),
            overrides.join(" ")
        );
    }
    if file.settings != *settings {
        bail!(
            "`{}` is a render with {}; this one asks for {}",
            path.display(),
            settings_text(&file.settings),
            settings_text(settings)
        );
    }
    if file.budgets != budgets {
        bail!(
            "`{}` is a render with --budgets {}; this one asks for --budgets {}",
            path.display(),
            file.budgets.name(),
            budgets.name()
        );
    }
    // An interrupt drops the pass cut short of a render with per-pixel budgets (each pass is
    // decided from the whole image's sums before it), or of one that learns beyond the sums,
    // so its state has none.
    if !file.state.learned.is_empty() && file.state.current.is_some() {
        bail!(
            "`{}` holds part of a pass of a render whose integrator learns from its passes: it cannot be resumed. Render it again",
            path.display()
        );
    }
    if file.budgets != Budgets::Uniform && file.state.current.is_some() {
        bail!(
            "`{}` holds part of a pass of a render with --budgets {}, whose passes are decided from the whole image's sums before them: it cannot be resumed. Render it again",
            path.display(),
            file.budgets.name()
        );
    }
    if file.shard != Shard::WHOLE {
        bail!(
            "`{}` is shard {} of a render: merge its shards (`lumis merge`) and resume from the merged state",
            path.display(),
            file.shard
        );
    }
    Ok(file.state)
}

/// Gives the integrator back what it learned in the passes of `state`, resumed from `file`.
fn restore_learned(
    loaded: &mut lumis::scene::load::LoadedScene,
    state: &RenderState,
    file: Option<&Path>,
) -> Result<()> {
    loaded
        .integrator
        .restore_learned_state(&state.learned)
        .map_err(|e| {
            anyhow::anyhow!(
                "`{}` cannot continue: {e}",
                file.map_or("the state".into(), |f| f.display().to_string())
            )
        })
}

/// The command that resumes this render from `state`: the arguments given, with `--resume`.
fn resume_command(state: &Path) -> String {
    let mut args: Vec<String> = Vec::new();
    let mut given = std::env::args().skip(1);
    while let Some(arg) = given.next() {
        if arg == "--resume" {
            given.next();
        } else if !arg.starts_with("--resume=") {
            args.push(arg);
        }
    }
    format!("lumis {} --resume {}", args.join(" "), state.display())
}

/// `--lanes`: 4, 8 or 16.
fn parse_lanes(text: &str) -> Result<usize, String> {
    match text.parse() {
        Ok(width @ (4 | 8 | 16)) => Ok(width),
        _ => Err(format!("{text:?} is not a lane width: 4, 8 or 16")),
    }
}

pub fn render(args: RenderArgs, threads: usize) -> Result<()> {
    let mut overrides = args.overrides.clone();
    if let Some(spp) = args.spp {
        overrides.push(format!("sampler.spp={spp}"));
    }
    if let Some(seed) = args.seed {
        overrides.push(format!("sampler.seed={seed}"));
    }
    if let Some(width) = args.lanes {
        lumis::math::lanes::limit_width(width);
    }
    if let Some(limit) = &args.memory_limit {
        limits::set_memory_limit(limit, "--memory-limit").map_err(anyhow::Error::msg)?;
    }
    let shard = args
        .shard
        .as_deref()
        .map(Shard::parse)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let load_start = std::time::Instant::now();
    let loaded = lumis::scene::load::load_scene(&args.scene, &overrides)?;
    let load_time = load_start.elapsed();
    for warning in &loaded.warnings {
        eprintln!("warning: {}: {warning}", args.scene.display());
    }
    let settings = settings(&args, loaded.scene.spp)?;
    let budgets = budgets(&args, settings.as_ref())?;
    if let Some(exr) = &args.replay {
        check_replay(exr, loaded.scene.seed, &loaded.description.integrator)?;
    }
    if args.resume.is_some() && settings.is_none() {
        bail!(
            "--resume continues a render in passes: give its settings again (--target-error, --time, --passes or --replay)"
        );
    }
    match (shard, settings) {
        (Some(shard), None) => render_shard(&args, overrides, loaded, shard, threads),
        (Some(shard), Some(settings)) => render_shard_pass(
            &args,
            overrides,
            loaded,
            (&settings, budgets),
            shard,
            threads,
        ),
        (None, Some(settings)) => {
            let scope = Scope::whole(threads).with_budgets(budgets);
            render_in_passes(&args, &overrides, loaded, &settings, scope, load_time)
        }
        (None, None) => render_plain(&args, loaded, threads, load_time),
    }
}

/// The EXR's path, checked, and every file written beside it checked writable before the
/// render (not found unwritable after it): the PNG, the AOV previews, `extra`.
fn outputs(
    args: &RenderArgs,
    loaded: &lumis::scene::load::LoadedScene,
    extra: &[PathBuf],
) -> Result<PathBuf> {
    let exr_path = args
        .output
        .clone()
        .unwrap_or_else(|| loaded.scene.output.clone());
    render_files::check_exr_path(&exr_path).map_err(anyhow::Error::msg)?;
    let preview_paths: Vec<PathBuf> = loaded
        .integrator
        .aovs(&loaded.scene)
        .iter()
        .filter(|a| a.preview)
        .map(|a| exr_path.with_extension(format!("{}.png", a.name)))
        .collect();
    let png_path = exr_path.with_extension("png");
    for path in [&exr_path, &png_path]
        .into_iter()
        .chain(&preview_paths)
        .chain(extra)
    {
        image_io::check_writable(path)?;
    }
    Ok(exr_path)
}

/// A progress bar of `pixels` on a terminal, else hidden.
fn progress_bar(quiet: bool, pixels: u64) -> Result<ProgressBar> {
    if quiet || !std::io::stderr().is_terminal() {
        return Ok(ProgressBar::hidden());
    }
    let bar = ProgressBar::with_draw_target(Some(pixels), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {wide_bar} {percent}% (eta {eta}) {msg}",
        )
        .context("progress bar template")?,
    );
    Ok(bar)
}

/// Prints a line above the progress bar, or to stderr when there is no bar.
fn say(bar: &ProgressBar, line: String) {
    if bar.is_hidden() {
        eprintln!("{line}");
    } else {
        bar.println(line);
    }
}

fn file_list(files: &[&Path]) -> String {
    files
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

/// A plain render: the scene's samples in one pass.
fn render_plain(
    args: &RenderArgs,
    mut loaded: lumis::scene::load::LoadedScene,
    threads: usize,
    load_time: std::time::Duration,
) -> Result<()> {
    let exr_path = outputs(args, &loaded, &[])?;
    let exposure = args.exposure.unwrap_or(loaded.scene.exposure);
    loaded.integrator.preprocess(&loaded.scene);
    let window = loaded.scene.window;
    let pixels = window.width as u64 * window.height as u64;
    let bar = progress_bar(args.quiet, pixels)?;
    // Ctrl-C (or SIGTERM) stops the render; what is finished is written, marked partial.
    let cancel = interrupt::install().context("cannot install the Ctrl-C handler")?;
    // Without a terminal there is no progress bar: a line when the render starts and at each
    // tenth, for logs (and for tests that interrupt a render once it runs).
    let log_progress = !args.quiet && !std::io::stderr().is_terminal();
    if log_progress {
        eprintln!(
            "rendering {} ({}x{}, {} spp)",
            args.scene.display(),
            window.width,
            window.height,
            loaded.scene.spp
        );
    }
    let pixels_done = AtomicU64::new(0);
    let on_tile = |n: u64| {
        bar.inc(n);
        if log_progress {
            let before = pixels_done.fetch_add(n, Ordering::Relaxed);
            let tenth = (before + n) * 10 / pixels.max(1);
            if tenth > before * 10 / pixels.max(1) && tenth < 10 {
                eprintln!("rendered {}%", tenth * 10);
            }
        }
    };
    let (film, stats) = lumis::render::render_cancellable(
        &loaded.scene,
        loaded.integrator.as_ref(),
        threads,
        &on_tile,
        &cancel,
    )
    .context("cannot start the render threads")?;
    bar.finish_and_clear();

    let integrator = &loaded.description.integrator;
    let metadata = render_files::metadata(
        &args.scene.display().to_string(),
        integrator,
        loaded.scene.spp,
        loaded.scene.seed,
        &stats,
    );
    let written = render_files::write(&film, &exr_path, exposure, &metadata)?;

    if stats.partial() {
        eprintln!(
            "interrupted: wrote a partial image ({} of {} pixels) to {} after {}",
            stats.pixels_done,
            stats.pixels_total,
            exr_path.display(),
            interrupt::signal_name()
        );
        std::process::exit(interrupt::exit_code());
    }
    if !args.quiet {
        let secs = stats.wall_time.as_secs_f64();
        eprintln!(
            "{} ({}x{}, {} spp, {}, {} threads): loaded in {:.3} s, rendered in {:.3} s, {:.3} M samples/s, {:.2} M rays/s -> {}",
            args.scene.display(),
            window.width,
            window.height,
            loaded.scene.spp,
            integrator.kind,
            stats.threads,
            load_time.as_secs_f64(),
            secs,
            stats.camera_samples as f64 / secs / 1e6,
            stats.rays as f64 / secs / 1e6,
            file_list(&written.all())
        );
    }
    Ok(())
}

/// Refuses a render whose sums would not fit in memory (the film's own estimate is checked
/// when the scene loads).
fn check_sums_memory(loaded: &lumis::scene::load::LoadedScene, halves: bool) -> Result<()> {
    let mut estimate = limits::MemoryEstimate::default();
    lumis::scene::budget::add_film_sums(
        &mut estimate,
        &loaded.scene.window,
        loaded.integrator.pixel_sums(&loaded.scene) as u64,
        halves,
    );
    estimate
        .check(&limits::memory_limit().map_err(anyhow::Error::msg)?)
        .map_err(anyhow::Error::msg)
}

/// What the render was asked for, for its first line.
fn asked(settings: &Settings) -> String {
    match &settings.stopping {
        Stopping::Samples { spp, passes } => format!("{spp} spp in {passes} passes"),
        Stopping::Target {
            error,
            max_spp,
            max_time,
        } => format!(
            "to a {} of {} at {} % confidence, at most {max_spp} spp{}",
            settings.metric.name(),
            number(*error),
            settings.confidence * 100.0,
            max_time.map_or(String::new(), |t| format!(" and {t} s"))
        ),
        Stopping::Time { seconds, .. } => format!("for {seconds} s"),
        Stopping::Replay(passes) => format!("{} replayed passes", passes.len()),
    }
}

/// A number as the user reads it: `1e-20` rather than twenty decimals.
fn number(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// Why the passes ended, for the summary line.
fn ending_text(settings: &Settings, state: &RenderState) -> String {
    let history = &state.history;
    let met = |target: f64| match history.error() {
        Some(e) if e.high <= target => format!("below the target {}", number(target)),
        Some(_) => format!(
            "the target {} not confirmed by the interval",
            number(target)
        ),
        None => String::new(),
    };
    match (history.stopped, &settings.stopping) {
        (Some(Stop::Target), Stopping::Target { error, .. }) => met(*error),
        (Some(Stop::MaxSpp), Stopping::Target { error, max_spp, .. }) => format!(
            "stopped at the cap of {max_spp} spp ({})",
            if history.error().is_some_and(|e| e.high <= *error) {
                met(*error)
            } else {
                format!("the target {} not reached", number(*error))
            }
        ),
        (
            Some(Stop::MaxTime),
            Stopping::Target {
                error, max_time, ..
            },
        ) => format!(
            "stopped at the cap of {} s ({})",
            max_time.unwrap_or_default(),
            if history.error().is_some_and(|e| e.high <= *error) {
                met(*error)
            } else {
                format!("the target {} not reached", number(*error))
            }
        ),
        (Some(Stop::MaxSpp), Stopping::Time { max_spp, .. }) => {
            format!("stopped at the cap of {max_spp} spp")
        }
        (Some(Stop::Time), Stopping::Time { seconds, .. }) if history.elapsed > *seconds => {
            format!("the time {seconds} s exceeded (the last pass must run)")
        }
        _ => String::new(),
    }
}

/// The line after each pass: its index, the samples and time so far, the error.
fn pass_line(state: &RenderState) -> String {
    let history = &state.history;
    format!(
        "pass {}: {} spp, {:.3} s{}",
        history.passes.len(),
        history.samples(),
        history.elapsed,
        history
            .error()
            .map_or(String::new(), |e| format!(", error {}", error_text(&e)))
    )
}

/// A render in passes in one process.
fn render_in_passes(
    args: &RenderArgs,
    overrides: &[String],
    mut loaded: lumis::scene::load::LoadedScene,
    settings: &Settings,
    scope: Scope,
    load_time: std::time::Duration,
) -> Result<()> {
    let heat_map = args.heat_map.then_some(settings.metric);
    let exr_for_heat = args
        .output
        .clone()
        .unwrap_or_else(|| loaded.scene.output.clone());
    let extra: Vec<PathBuf> = heat_map
        .map(|_| render_files::heat_map_path(&exr_for_heat))
        .into_iter()
        .chain([lumis::shards::state_path(&exr_for_heat)])
        .collect();
    let exr_path = outputs(args, &loaded, &extra)?;
    check_sums_memory(&loaded, settings.estimates_error())?;
    if let Stopping::Target { error, .. } = settings.stopping
        && error > 0.0
        && error < 1e-13
    {
        eprintln!(
            "warning: --target-error {} is below what f32 pixels resolve (a relative error of about 1e-14): the render stops at its cap",
            number(error)
        );
    }
    let exposure = args.exposure.unwrap_or(loaded.scene.exposure);
    let mut state = match &args.resume {
        Some(path) => {
            let state = resumed_state(path, &args.scene, overrides, settings, scope.budgets)?;
            let fresh = RenderState::new(&loaded.scene, loaded.integrator.as_ref(), settings);
            if (
                state.sums.window,
                state.sums.stride,
                state.sums.halves.len(),
            ) != (
                fresh.sums.window,
                fresh.sums.stride,
                fresh.sums.halves.len(),
            ) {
                bail!(
                    "`{}` holds sums of another film or integrator than this scene's",
                    path.display()
                );
            }
            if state.history.complete() {
                bail!(
                    "`{}` is a complete render: nothing to continue",
                    path.display()
                );
            }
            state
        }
        None => RenderState::new(&loaded.scene, loaded.integrator.as_ref(), settings),
    };
    loaded.integrator.preprocess(&loaded.scene);
    restore_learned(&mut loaded, &state, args.resume.as_deref())?;
    let window = loaded.scene.window;
    let pixels = window.width as u64 * window.height as u64;
    let bar = progress_bar(args.quiet, pixels)?;
    let cancel = interrupt::install().context("cannot install the Ctrl-C handler")?;
    if !args.quiet {
        say(
            &bar,
            format!(
                "rendering {} ({}x{}) in passes, {}{}",
                args.scene.display(),
                window.width,
                window.height,
                asked(settings),
                if state.history.passes.is_empty() {
                    String::new()
                } else {
                    format!(", resumed after {}", pass_line(&state))
                }
            ),
        );
    }
    let mut preview_error = None;
    let mut on_pass = |state: &RenderState| {
        bar.reset();
        if !args.quiet {
            say(&bar, pass_line(state));
        }
        match render_files::write_previews(&state.sums, &exr_path, exposure, heat_map) {
            Ok(()) => Control::Continue,
            Err(e) => {
                preview_error = Some(e);
                Control::Stop
            }
        }
    };
    let outcome = lumis::progressive::run(
        &loaded.scene,
        loaded.integrator.as_mut(),
        settings,
        &mut state,
        scope,
        &cancel,
        &|n| bar.inc(n),
        &mut on_pass,
    )
    .context("cannot start the render threads")?;
    bar.finish_and_clear();
    if let Some(e) = preview_error {
        return Err(e.into());
    }
    let integrator = &loaded.description.integrator;
    let film = state
        .sums
        .resolve(&loaded.scene, loaded.integrator.as_ref());
    let mut metadata = render_files::passes_metadata(
        &args.scene.display().to_string(),
        integrator,
        loaded.scene.seed,
        &outcome.stats,
        settings,
        &state.history,
    );
    // `--replay` reads it: the passes' per-pixel samples are decided again as they were.
    if scope.budgets != Budgets::Uniform {
        metadata.push((BUDGETS_KEY.to_string(), scope.budgets.name().to_string()));
    }
    let written = render_files::write(&film, &exr_path, exposure, &metadata)?;
    if let Some(metric) = heat_map {
        image_io::write_atomically(
            &render_files::heat_map_path(&exr_path),
            render_files::heat_map_writer(&state.sums, metric),
        )?;
    }
    if outcome.ending != Ending::Complete {
        let saved = lumis::shards::state_path(&exr_path);
        let scene_path = std::path::absolute(&args.scene)
            .with_context(|| format!("cannot resolve `{}`", args.scene.display()))?;
        ShardFile {
            scene_name: args.scene.display().to_string(),
            scene_hash: lumis::shards::file_hash(&scene_path)?,
            scene_path,
            overrides: overrides.to_vec(),
            exposure,
            shard: Shard::WHOLE,
            stats: outcome.stats,
            settings: settings.clone(),
            budgets: scope.budgets,
            state: state.clone(),
        }
        .write(&saved)?;
        let next = format!("continue it with `{}`", resume_command(&saved));
        eprintln!(
            "interrupted: wrote a partial image ({} of its passes{}) to {} after {}; {next}",
            state.history.passes.len(),
            match (
                state.current.is_some(),
                scope.budgets,
                state.learned.is_empty()
            ) {
                (true, _, _) => " and part of the next",
                (false, Budgets::Uniform, true) => "",
                (false, Budgets::Uniform, false) => {
                    "; an integrator that learns from its passes drops a pass cut short, which taught it already"
                }
                (false, _, _) => {
                    "; per-pixel budgets drop a pass cut short, as they decide each pass from the whole image"
                }
            },
            exr_path.display(),
            interrupt::signal_name(),
        );
        std::process::exit(interrupt::exit_code());
    }
    // A finished render leaves no state behind: a state file of an earlier interrupt is done.
    if args.resume.is_some() {
        let saved = lumis::shards::state_path(&exr_path);
        if args.resume.as_deref() == Some(saved.as_path()) {
            std::fs::remove_file(&saved)
                .with_context(|| format!("cannot remove `{}`", saved.display()))?;
        }
    }
    if !args.quiet {
        let history = &state.history;
        let secs = outcome.stats.wall_time.as_secs_f64();
        let mut files = written.all();
        let heat = render_files::heat_map_path(&exr_path);
        if heat_map.is_some() {
            files.push(&heat);
        }
        let ending = ending_text(settings, &state);
        eprintln!(
            "{} ({}x{}, {} spp in {} passes, {}, {} threads): loaded in {:.3} s, rendered in {:.3} s{}{}, {:.3} M samples/s, {:.2} M rays/s -> {}",
            args.scene.display(),
            window.width,
            window.height,
            history.samples(),
            history.passes.len(),
            integrator.kind,
            outcome.stats.threads,
            load_time.as_secs_f64(),
            history.elapsed,
            history
                .error()
                .map_or(String::new(), |e| format!(", error {}", error_text(&e))),
            if ending.is_empty() {
                ending
            } else {
                format!(": {ending}")
            },
            outcome.stats.camera_samples as f64 / secs / 1e6,
            outcome.stats.rays as f64 / secs / 1e6,
            file_list(&files)
        );
    }
    Ok(())
}

/// The shard file's path: --output, else beside the EXR.
fn shard_path(
    args: &RenderArgs,
    loaded: &lumis::scene::load::LoadedScene,
    shard: Shard,
) -> Result<PathBuf> {
    let path = args
        .output
        .clone()
        .unwrap_or_else(|| lumis::shards::default_path(&loaded.scene.output, shard));
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
    {
        bail!(
            "a shard holds sums for `lumis merge`, not an image: name it .lshard, not `{}`",
            path.display()
        );
    }
    image_io::check_writable(&path)?;
    Ok(path)
}

/// `lumis render --shard`: renders the shard's tiles and writes their sums.
fn render_shard(
    args: &RenderArgs,
    overrides: Vec<String>,
    mut loaded: lumis::scene::load::LoadedScene,
    shard: Shard,
    threads: usize,
) -> Result<()> {
    let path = shard_path(args, &loaded, shard)?;
    let scene_path = std::path::absolute(&args.scene)
        .with_context(|| format!("cannot resolve `{}`", args.scene.display()))?;
    loaded.integrator.preprocess(&loaded.scene);
    let cancel = interrupt::install().context("cannot install the Ctrl-C handler")?;
    let (sums, stats) = lumis::render::render_shard(
        &loaded.scene,
        loaded.integrator.as_ref(),
        threads,
        shard,
        &|_| {},
        &cancel,
    )
    .context("cannot start the render threads")?;
    if stats.partial() {
        eprintln!(
            "interrupted after {}: shard {shard} not written",
            interrupt::signal_name()
        );
        std::process::exit(interrupt::exit_code());
    }
    let spp = loaded.scene.spp;
    let pass = passes::PlannedPass {
        end: spp,
        planned: u64::from(spp),
    };
    let file = ShardFile {
        scene_name: args.scene.display().to_string(),
        scene_hash: lumis::shards::file_hash(&scene_path)?,
        scene_path,
        overrides,
        exposure: args.exposure.unwrap_or(loaded.scene.exposure),
        shard,
        stats,
        settings: Settings::samples(spp),
        budgets: Budgets::Uniform,
        state: RenderState {
            sums,
            history: passes::History {
                mass: f64::from(spp),
                passes: vec![passes::PassRecord {
                    pass,
                    seconds: stats.wall_time.as_secs_f64(),
                    error: None,
                }],
                elapsed: stats.wall_time.as_secs_f64(),
                stopped: Some(Stop::Samples),
            },
            current: None,
            learned: Vec::new(),
        },
    };
    file.write(&path)?;
    if !args.quiet {
        eprintln!(
            "{} shard {shard} ({} tiles, {} pixels): rendered in {:.3} s -> {}",
            args.scene.display(),
            stats.tiles_total,
            stats.pixels_total,
            stats.wall_time.as_secs_f64(),
            path.display()
        );
    }
    Ok(())
}

/// `lumis render --shard` of a render in passes: the next pass of the shard's tiles, planned
/// from the merged state of the passes before (`--resume`; none before the first pass).
fn render_shard_pass(
    args: &RenderArgs,
    overrides: Vec<String>,
    mut loaded: lumis::scene::load::LoadedScene,
    (settings, budgets): (&Settings, Budgets),
    shard: Shard,
    threads: usize,
) -> Result<()> {
    if settings.timed() {
        bail!(
            "--time and --max-time cannot be combined with --shard: passes decided by the clock need one clock. Render with --time in one process, then --replay its EXR across shards"
        );
    }
    let path = shard_path(args, &loaded, shard)?;
    let mut state = match &args.resume {
        Some(resume) => {
            let state = resumed_state(resume, &args.scene, &overrides, settings, budgets)?;
            if state.history.complete() {
                bail!(
                    "`{}` is a complete render: `lumis merge` wrote its image; nothing to render",
                    resume.display()
                );
            }
            state
        }
        None => RenderState::new(&loaded.scene, loaded.integrator.as_ref(), settings),
    };
    loaded.integrator.preprocess(&loaded.scene);
    restore_learned(&mut loaded, &state, args.resume.as_deref())?;
    let cancel = interrupt::install().context("cannot install the Ctrl-C handler")?;
    let outcome = lumis::progressive::run(
        &loaded.scene,
        loaded.integrator.as_mut(),
        settings,
        &mut state,
        Scope {
            threads,
            shard,
            max_passes: Some(1),
            budgets,
        },
        &cancel,
        &|_| {},
        &mut |_| Control::Continue,
    )
    .context("cannot start the render threads")?;
    if outcome.ending == Ending::Interrupted {
        eprintln!(
            "interrupted after {}: shard {shard} not written",
            interrupt::signal_name()
        );
        std::process::exit(interrupt::exit_code());
    }
    state.sums.retain_tiles(|t| shard.has(t));
    let scene_path = std::path::absolute(&args.scene)
        .with_context(|| format!("cannot resolve `{}`", args.scene.display()))?;
    ShardFile {
        scene_name: args.scene.display().to_string(),
        scene_hash: lumis::shards::file_hash(&scene_path)?,
        scene_path,
        overrides,
        exposure: args.exposure.unwrap_or(loaded.scene.exposure),
        shard,
        stats: outcome.stats,
        settings: settings.clone(),
        budgets,
        state: state.clone(),
    }
    .write(&path)?;
    if !args.quiet {
        eprintln!(
            "{} shard {shard}, pass {} ({} spp{}): rendered in {:.3} s -> {}",
            args.scene.display(),
            state.history.passes.len(),
            state.history.samples(),
            if state.history.complete() {
                ", the last"
            } else {
                ""
            },
            outcome.stats.wall_time.as_secs_f64(),
            path.display()
        );
    }
    Ok(())
}
