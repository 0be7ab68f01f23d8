//! The `lumis` command-line program.

mod interrupt;
mod render_command;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lumis::image_io;
use std::io::IsTerminal;
use std::path::PathBuf;

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
    Render(Box<render_command::RenderArgs>),
    /// Measure the speed/accuracy trade of integrators on scenes: K runs each give sampling and
    /// estimator variance, error against a reference, time and efficiency, written as
    /// results.csv, results.md, plots and image panels in --out as each row finishes.
    Study(Box<StudyArgs>),
    /// Merge the shards of a render (`lumis render --shard i/n`, all n of them, in any order)
    /// into the EXR and previews the one-process render writes, bit for bit. The shards of a
    /// render in passes merge after each pass: until the last, the merged state is written too,
    /// and the next pass's shards resume from it.
    Merge {
        /// The shard files.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// Output EXR (the PNG previews are written beside it). Default: the scene's output.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Where the merged state of a render in passes with more passes to go is written
        /// (default: beside the EXR, NAME.lshard).
        #[arg(long, value_name = "FILE")]
        state: Option<PathBuf>,
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
    /// any registered integrator with a `samples` parameter. Must include balance, the baseline
    /// of every ratio; or all `path` rows, then including path:weighting=balance, the baseline,
    /// and budgets are camera samples per pixel (docs/study.md). Mixed lists are refused.
    #[arg(long, default_value = lumis::study::DEFAULT_INTEGRATORS)]
    integrators: String,
    /// The ladder of budgets N (samples per light per camera sample; camera samples per pixel
    /// for `path` rows), comma-separated.
    #[arg(long, default_value = lumis::study::DEFAULT_BUDGETS)]
    budgets: String,
    /// The budget whose baseline error is the target error and whose time is the equal-time
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
    /// Samples per light per pixel of the rendered reference (the baseline, 16 shards; camera
    /// samples per pixel for `path`).
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
        Command::Render(args) => {
            let threads = worker_threads(args.threads());
            render_command::render(*args, threads)
        }
        Command::Study(args) => study(*args),
        Command::Merge {
            shards,
            output,
            state,
            quiet,
        } => merge(&shards, output.as_deref(), state.as_deref(), quiet),
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
pub(crate) fn worker_threads(requested: usize) -> usize {
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

fn merge(
    shards: &[PathBuf],
    output: Option<&std::path::Path>,
    state: Option<&std::path::Path>,
    quiet: bool,
) -> Result<()> {
    let start = std::time::Instant::now();
    let merged = lumis::shards::merge(shards, output, state)?;
    if !quiet {
        let files = merged
            .files
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ");
        let error = merged.history.error().map_or(String::new(), |e| {
            format!(", error {}", lumis::render_files::error_text(&e))
        });
        match &merged.state {
            None => eprintln!(
                "merged {} shards in {:.3} s{error} -> {files}",
                shards.len(),
                start.elapsed().as_secs_f64(),
            ),
            Some(state) => eprintln!(
                "merged {} shards of pass {} ({} spp{error}) in {:.3} s -> {files}, {}; render the next pass's shards with --resume {}",
                shards.len(),
                merged.history.passes.len(),
                merged.history.samples(),
                start.elapsed().as_secs_f64(),
                state.display(),
                state.display()
            ),
        }
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
