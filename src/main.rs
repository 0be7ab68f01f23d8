//! The `lumis` command-line program.

mod interrupt;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lumis::image_io;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

#[derive(Parser)]
#[command(
    name = "lumis",
    version,
    about = "A physically based renderer for multiple importance sampling research"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to an EXR (colour and AOV layers) and a PNG preview beside it.
    Render(RenderArgs),
    /// Measure the speed/accuracy trade of integrators on scenes: K runs each give sampling and
    /// estimator variance, error against a reference, time and efficiency, written as
    /// results.csv, results.md, plots and image panels in --out as each row finishes.
    Study(Box<StudyArgs>),
    /// Merge the shards of a render (`lumis render --shard i/n`, all n of them, in any order)
    /// into the EXR and previews the one-process render writes, bit for bit.
    Merge {
        /// The shard files.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// Output EXR (the PNG previews are written beside it). Default: the scene's output.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// No summary line.
        #[arg(short, long)]
        quiet: bool,
    },
    /// Write a MERL-format measured BRDF file tabulating any BSDF (e.g. to test `measured`).
    Merl {
        /// The BSDF to tabulate, as in a scene file: '(type: "glossy", roughness: 0.2)'.
        #[arg(long)]
        bsdf: String,
        /// The .binary file to write.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Convert a Mitsuba 3 XML scene to a lumis RON scene, naming (with its line) every element
    /// it cannot convert; nothing is written unless all of it converts (or --partial).
    Import {
        /// The Mitsuba 3 scene (XML).
        scene: PathBuf,
        /// The RON scene to write.
        #[arg(short, long)]
        output: PathBuf,
        /// Override a <default> parameter, as `mitsuba -D name=value` (repeatable).
        #[arg(short = 'D', long = "define", value_name = "NAME=VALUE")]
        defines: Vec<String>,
        /// Write the scene without the elements that cannot be converted (they are listed).
        #[arg(long)]
        partial: bool,
    },
    /// List the built-in plugins with their parameters.
    Plugins {
        /// Print the reference as Markdown (docs/plugins.md is generated this way).
        #[arg(long)]
        markdown: bool,
    },
}

#[derive(clap::Args)]
struct RenderArgs {
    /// The scene file (RON).
    scene: PathBuf,
    /// Output EXR; the PNG preview is written beside it with the extension .png.
    /// Default: the film's `output`, or the scene's name + .exr in the current directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Camera samples per pixel (overrides sampler.spp).
    #[arg(long)]
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
    /// Override any scene value by its path, e.g. --set integrator.type=balance
    /// --set integrator.samples=64 --set film.width=128 (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    overrides: Vec<String>,
    /// Exposure of the PNG preview in stops (overrides film.exposure).
    #[arg(long)]
    exposure: Option<f32>,
    /// No progress bar and no summary line. (When stderr is not a terminal, progress is a plain
    /// line `progress: K of N pixels` at each tenth of the image.)
    #[arg(short, long)]
    quiet: bool,
    /// Render only shard I of N (0 ≤ I < N): every Nth tile, with the seeds of the whole render,
    /// written as sums (--output, default NAME.shard-I-of-N.lshard beside the EXR) for
    /// `lumis merge`.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
}

#[derive(clap::Args)]
struct StudyArgs {
    /// The scene files (RON).
    #[arg(required_unless_present_any = ["cell", "collect"])]
    scenes: Vec<PathBuf>,
    /// Do not run the study: write its manifest of cells to DIR (docs/distributed.md), to run
    /// them with --cell (e.g. as a SLURM array) and collect them with --collect.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["cell", "collect"])]
    plan: Option<PathBuf>,
    /// With --plan: also write DIR/slurm.sh, which submits the cells as a SLURM job array and
    /// the collect step as a job that depends on it, and print it.
    #[arg(long, requires = "plan")]
    slurm: bool,
    /// With --slurm: at most this many cells run at once (the array's %throttle).
    #[arg(long, default_value_t = 64, requires = "slurm")]
    slurm_throttle: u32,
    /// Run one cell of the study planned in DIR and write its result there. INDEX defaults to
    /// $SLURM_ARRAY_TASK_ID, else $JOB_COMPLETION_INDEX (Kubernetes indexed jobs).
    #[arg(long, num_args = 1..=2, value_names = ["DIR", "INDEX"], conflicts_with = "collect")]
    cell: Option<Vec<String>>,
    /// Collect the cells of the study planned in DIR into the report a local run writes
    /// (to the plan's --out); names the missing and failed cells.
    #[arg(long, value_name = "DIR")]
    collect: Option<PathBuf>,
    /// Integrators, comma-separated, each NAME[:key=value]... (e.g. alpha:mode=preprocessed);
    /// any registered integrator with a `samples` parameter. Must include balance.
    #[arg(long, default_value = lumis::study::DEFAULT_INTEGRATORS)]
    integrators: String,
    /// The ladder of budgets N (samples per light per camera sample), comma-separated.
    #[arg(long, default_value = lumis::study::DEFAULT_BUDGETS)]
    budgets: String,
    /// The budget whose balance error is the target error and whose time is the equal-time
    /// point (default: the middle of the ladder).
    #[arg(long)]
    target_budget: Option<u32>,
    /// K₀: runs (seeds) of every configuration in the first round, at least 3.
    #[arg(long, default_value_t = 4)]
    runs: u32,
    /// The cap of K: the curves' runs double until the headline ratio's 95 % interval is within
    /// ±--precision, up to this.
    #[arg(long, default_value_t = 16)]
    max_runs: u32,
    /// Relative half-width the K rule aims at (0.05: ±5 %).
    #[arg(long, default_value_t = 0.05)]
    precision: f64,
    /// A reference image (EXR) for a single scene, instead of rendering one.
    #[arg(long, conflicts_with = "reference_samples")]
    reference: Option<PathBuf>,
    /// Samples per light per pixel of the rendered reference (balance heuristic, 16 shards).
    #[arg(long, default_value_t = 4096)]
    reference_samples: u32,
    /// Where rendered references are cached (default: OUT/cache).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Also run the paper's preprocessed α (M = 4096) at N = 256 with K₀ runs (costly: its pilot
    /// is 17 times its budget).
    #[arg(long)]
    paper_pilots: bool,
    /// Sweeps of α's parameters, comma-separated: clamp (Figure 2), m (Figure 7), n (Figures 3,
    /// 4), all, none.
    #[arg(long, default_value = "none")]
    sweeps: String,
    /// The budget of the sweeps (default: the target budget).
    #[arg(long)]
    sweep_budget: Option<u32>,
    /// Edge of the pixel blocks of the jackknife, pixels.
    #[arg(long, default_value_t = 16)]
    block: u32,
    /// ε of the relative errors as a fraction of the reference's mean luminance:
    /// V / (ref² + (fraction · mean)²).
    #[arg(long, default_value_t = 0.01)]
    epsilon: f64,
    /// Override scene values for every scene (repeatable), e.g. --set film.width=64.
    #[arg(long = "set", value_name = "PATH=VALUE")]
    overrides: Vec<String>,
    /// Worker threads (default: one per core; at most the machine's hardware threads).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Seed of the runs (run k uses seed + k).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output directory.
    #[arg(short, long, default_value = "study")]
    out: PathBuf,
    /// Where to write the Markdown report (default: OUT/results.md); links are relative to it.
    #[arg(long)]
    report: Option<PathBuf>,
    /// A Markdown file (a reading of the results, written by hand) inserted after the summary.
    #[arg(long)]
    notes: Option<PathBuf>,
    /// No progress bar and no progress lines.
    #[arg(short, long)]
    quiet: bool,
}

fn main() {
    let cli = Cli::parse();
    lumis::link_plugins();
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::Study(args) => study(*args),
        Command::Merge {
            shards,
            output,
            quiet,
        } => merge(&shards, output.as_deref(), quiet),
        Command::Merl { bsdf, output } => merl(&bsdf, &output),
        Command::Import {
            scene,
            output,
            defines,
            partial,
        } => lumis::import::run(&scene, &output, &defines, partial),
        Command::Plugins { markdown } => {
            print!(
                "{}",
                if markdown {
                    lumis::registry::plugins_markdown()
                } else {
                    lumis::registry::plugins_text()
                }
            );
            Ok(())
        }
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        let interrupted = e.downcast_ref::<lumis::study::Interrupted>().is_some();
        std::process::exit(if interrupted {
            interrupt::exit_code()
        } else {
            1
        });
    }
}

/// The worker thread count to use for `--threads requested` (0: one per core). A render is
/// CPU-bound: threads beyond the hardware threads only add switching (10 000 of them made a
/// 0.02 s render take minutes), so a larger request is reduced, with a warning.
fn worker_threads(requested: usize) -> usize {
    let available = std::thread::available_parallelism().map_or(1, |n| n.get());
    if requested > available {
        eprintln!(
            "warning: --threads {requested} is more than the {available} hardware threads of this machine; using {available}"
        );
        return available;
    }
    requested
}

/// The study's configuration from its arguments.
fn study_config(args: StudyArgs) -> Result<lumis::study::StudyConfig> {
    use lumis::study::config::{parse_budgets, parse_integrators};
    use lumis::study::{ReferenceSource, StudyConfig, Sweeps};
    let mut config = StudyConfig::new(args.scenes, args.out)?;
    config.integrators = parse_integrators(&args.integrators)?;
    config.budgets = parse_budgets(&args.budgets)?;
    config.target_budget = args.target_budget;
    config.runs = args.runs;
    config.max_runs = args.max_runs;
    config.precision = args.precision;
    config.reference = match args.reference {
        Some(file) => ReferenceSource::File(file),
        None => ReferenceSource::Samples(args.reference_samples),
    };
    config.cache_dir = args.cache_dir;
    config.paper_pilots = args.paper_pilots;
    config.sweeps = Sweeps::parse(&args.sweeps)?;
    config.sweep_budget = args.sweep_budget;
    config.block = args.block;
    config.epsilon = args.epsilon;
    config.overrides = args.overrides;
    config.threads = worker_threads(args.threads);
    config.seed = args.seed;
    config.report = args.report;
    config.notes = args.notes;
    Ok(config)
}

/// The arguments after `lumis study`, without the options that plan, run or collect cells:
/// the arguments of the same study run locally.
fn study_arguments() -> Vec<String> {
    let mut arguments = Vec::new();
    let mut args = std::env::args().skip(2);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--plan" | "--slurm-throttle" => {
                args.next();
            }
            "--slurm" => {}
            a if a.starts_with("--plan=") || a.starts_with("--slurm-throttle=") => {}
            _ => arguments.push(arg),
        }
    }
    arguments
}

/// The configuration of the study planned in `dir`, whose directory becomes the current one
/// (the plan's paths are relative to it); `dir` is returned absolute.
fn planned_study(
    dir: &std::path::Path,
    threads: usize,
) -> Result<(lumis::study::StudyConfig, PathBuf)> {
    let dir =
        std::path::absolute(dir).with_context(|| format!("cannot resolve `{}`", dir.display()))?;
    let manifest = lumis::study::store::Manifest::read(&dir)?;
    let arguments = std::iter::once("lumis".to_string())
        .chain(std::iter::once("study".to_string()))
        .chain(manifest.arguments.iter().cloned());
    let Command::Study(args) = Cli::try_parse_from(arguments)
        .with_context(|| format!("the arguments in `{}`", dir.join("manifest.ron").display()))?
        .command
    else {
        anyhow::bail!("the manifest of `{}` is not a study's", dir.display());
    };
    std::env::set_current_dir(&manifest.directory).with_context(|| {
        format!(
            "cannot enter the study's directory `{}`",
            manifest.directory.display()
        )
    })?;
    let mut config = study_config(*args)?;
    if threads != 0 {
        config.threads = worker_threads(threads);
    }
    config.command = Some(format!("lumis study {}", manifest.arguments.join(" ")));
    Ok((config, dir))
}

/// The index of the cell to run: given, else from the array job's environment.
fn cell_index(given: Option<&String>) -> Result<usize> {
    if let Some(text) = given {
        return text
            .parse()
            .with_context(|| format!("cell index `{text}` is not a number"));
    }
    for variable in ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"] {
        if let Ok(text) = std::env::var(variable) {
            return text
                .parse()
                .with_context(|| format!("{variable}=`{text}` is not a cell index"));
        }
    }
    anyhow::bail!(
        "--cell DIR needs a cell index: give it (--cell DIR INDEX), or run in a SLURM array job (SLURM_ARRAY_TASK_ID) or a Kubernetes indexed job (JOB_COMPLETION_INDEX)"
    )
}

fn study(args: StudyArgs) -> Result<()> {
    use lumis::study::Progress;
    let quiet = args.quiet;
    if let Some(cell) = &args.cell {
        let index = cell_index(cell.get(1))?;
        let (config, dir) = planned_study(std::path::Path::new(&cell[0]), args.threads)?;
        let cancel = interrupt::install().context("cannot install the Ctrl-C handler")?;
        let start = std::time::Instant::now();
        let result = lumis::study::run_planned_cell(&config, &dir, index, &cancel)?;
        if !quiet {
            eprintln!(
                "cell {index} ({:?}, seed {}) done in {:.2} s ({:.2} s of CPU) -> {}",
                result.cell.role,
                result.cell.seed,
                start.elapsed().as_secs_f64(),
                result.cpu_time,
                lumis::study::store::cell_path(&dir, index).display()
            );
        }
        return Ok(());
    }
    if let Some(dir) = &args.collect {
        let (config, dir) = planned_study(dir, args.threads)?;
        let progress = Progress {
            bar: ProgressBar::hidden(),
            lines: !quiet,
        };
        let start = std::time::Instant::now();
        lumis::study::collect(&config, &dir, &progress)?;
        if !quiet {
            eprintln!(
                "collected {} in {:.1} s -> {}",
                dir.display(),
                start.elapsed().as_secs_f64(),
                config.report_path().display()
            );
        }
        return Ok(());
    }
    let plan = args.plan.clone();
    let (slurm, throttle) = (args.slurm, args.slurm_throttle);
    let mut config = study_config(args)?;
    config.command = Some(
        std::iter::once("lumis".to_string())
            .chain(std::env::args().skip(1))
            .collect::<Vec<_>>()
            .join(" "),
    );
    if let Some(dir) = plan {
        let dir = std::path::absolute(&dir)
            .with_context(|| format!("cannot resolve `{}`", dir.display()))?;
        let program = std::env::current_exe()
            .context("cannot find this program's path")?
            .display()
            .to_string();
        let directory = std::env::current_dir().context("cannot read the current directory")?;
        let manifest = lumis::study::plan(&config, &dir, study_arguments(), directory, &program)?;
        if slurm {
            let script = lumis::study::slurm_script(&manifest, &dir, &program, throttle);
            let path = dir.join("slurm.sh");
            image_io::write_atomically(&path, |file| {
                use std::io::Write;
                file.write_all(script.as_bytes()).map_err(|e| e.to_string())
            })?;
            print!("{script}");
        }
        if !quiet {
            eprintln!(
                "planned {} cells in {}: run each with `{}`, then `{} study --collect {}`",
                manifest.cells.len(),
                dir.display(),
                manifest.command,
                program,
                dir.display()
            );
        }
        return Ok(());
    }
    let terminal = std::io::stderr().is_terminal();
    let bar = if quiet || !terminal {
        ProgressBar::hidden()
    } else {
        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {wide_bar} {percent}% (eta {eta}) {msg}",
            )
            .context("progress bar template")?,
        );
        bar.enable_steady_tick(std::time::Duration::from_millis(200));
        bar
    };
    let progress = Progress { bar, lines: !quiet };
    // Ctrl-C stops at the next packet of camera samples; every finished scene is already written, and the
    // current one is written with its complete runs.
    let cancel = interrupt::install().context("cannot install the Ctrl-C handler")?;
    let start = std::time::Instant::now();
    lumis::study::run(&config, &progress, &cancel)?;
    if !quiet {
        eprintln!(
            "study of {} scene(s) finished in {:.1} s -> {}",
            config.scenes.len(),
            start.elapsed().as_secs_f64(),
            config.report_path().display()
        );
    }
    Ok(())
}

fn merge(shards: &[PathBuf], output: Option<&std::path::Path>, quiet: bool) -> Result<()> {
    let start = std::time::Instant::now();
    let written = lumis::shards::merge(shards, output)?;
    if !quiet {
        eprintln!(
            "merged {} shards in {:.3} s -> {}",
            shards.len(),
            start.elapsed().as_secs_f64(),
            written
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    Ok(())
}

fn merl(spec: &str, output: &std::path::Path) -> Result<()> {
    let spec: lumis::scene::description::PluginSpec = ron::from_str(spec)
        .with_context(|| format!("--bsdf `{spec}` is not a plugin description"))?;
    let plugin = lumis::registry::find::<lumis::registry::BsdfPlugin>(&spec.kind)
        .map_err(anyhow::Error::msg)?;
    let mut params =
        lumis::params::Params::new(format!("bsdf ({})", spec.kind), plugin.params, spec.params)?;
    let bsdf = (plugin.create)(&mut params)?;
    params.finish()?;
    let front = lumis::bsdf::BsdfContext::FRONT;
    lumis::bsdfs::measured::write_merl(output, |wi, wo| bsdf.eval(&front, wo, wi) / wi.z)
        .map_err(anyhow::Error::msg)?;
    eprintln!("wrote {}", output.display());
    Ok(())
}

fn render(args: RenderArgs) -> Result<()> {
    let mut overrides = args.overrides.clone();
    if let Some(spp) = args.spp {
        overrides.push(format!("sampler.spp={spp}"));
    }
    if let Some(seed) = args.seed {
        overrides.push(format!("sampler.seed={seed}"));
    }
    if let Some(limit) = &args.memory_limit {
        lumis::limits::set_memory_limit(limit, "--memory-limit").map_err(anyhow::Error::msg)?;
    }
    let shard = args
        .shard
        .as_deref()
        .map(lumis::render::Shard::parse)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let threads = worker_threads(args.threads);
    let load_start = std::time::Instant::now();
    let mut loaded = lumis::scene::load::load_scene(&args.scene, &overrides)?;
    let load_time = load_start.elapsed();
    for warning in &loaded.warnings {
        eprintln!("warning: {}: {warning}", args.scene.display());
    }
    if let Some(shard) = shard {
        return render_shard(&args, overrides, loaded, shard, threads);
    }
    let exr_path = args.output.unwrap_or_else(|| loaded.scene.output.clone());
    lumis::render_files::check_exr_path(&exr_path).map_err(anyhow::Error::msg)?;
    let exposure = args.exposure.unwrap_or(loaded.scene.exposure);
    // Every output is checked before the render, not found unwritable after it.
    let preview_paths: Vec<PathBuf> = loaded
        .integrator
        .aovs(&loaded.scene)
        .iter()
        .filter(|a| a.preview)
        .map(|a| exr_path.with_extension(format!("{}.png", a.name)))
        .collect();
    let png_path = exr_path.with_extension("png");
    for path in [&exr_path, &png_path].into_iter().chain(&preview_paths) {
        image_io::check_writable(path)?;
    }

    loaded.integrator.preprocess(&loaded.scene);
    let window = loaded.scene.window;
    let pixels = window.width as u64 * window.height as u64;
    let terminal = std::io::stderr().is_terminal();
    let bar = if args.quiet || !terminal {
        ProgressBar::hidden()
    } else {
        let bar = ProgressBar::with_draw_target(Some(pixels), ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {wide_bar} {percent}% (eta {eta})",
            )
            .context("progress bar template")?,
        );
        bar
    };
    // Ctrl-C (or SIGTERM) stops the render; what is finished is written, marked partial.
    let cancel = interrupt::install().context("cannot install the Ctrl-C handler")?;
    // Without a terminal there is no progress bar: a line when the render starts and at each
    // tenth, for logs (and for tests that interrupt a render once it runs).
    let log_progress = !args.quiet && !terminal;
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
    let metadata = lumis::render_files::metadata(
        &args.scene.display().to_string(),
        integrator,
        loaded.scene.spp,
        loaded.scene.seed,
        &stats,
    );
    let written = lumis::render_files::write(&film, &exr_path, exposure, &metadata)?;

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
            written
                .all()
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    Ok(())
}

/// `lumis render --shard`: renders the shard's tiles and writes their sums.
fn render_shard(
    args: &RenderArgs,
    overrides: Vec<String>,
    mut loaded: lumis::scene::load::LoadedScene,
    shard: lumis::render::Shard,
    threads: usize,
) -> Result<()> {
    let path = args
        .output
        .clone()
        .unwrap_or_else(|| lumis::shards::default_path(&loaded.scene.output, shard));
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
    {
        anyhow::bail!(
            "a shard holds sums for `lumis merge`, not an image: name it .lshard, not `{}`",
            path.display()
        );
    }
    image_io::check_writable(&path)?;
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
    let file = lumis::shards::ShardFile {
        scene_name: args.scene.display().to_string(),
        scene_hash: lumis::shards::file_hash(&scene_path)?,
        scene_path,
        overrides,
        exposure: args.exposure.unwrap_or(loaded.scene.exposure),
        shard,
        stats,
        sums,
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
