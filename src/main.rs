//! The `lumis` command-line program.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

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
    Study(StudyArgs),
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
    /// Worker threads (default: one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Override any scene value by its path, e.g. --set integrator.type=balance
    /// --set integrator.samples=64 --set film.width=128 (repeatable).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    overrides: Vec<String>,
    /// Exposure of the PNG preview in stops (overrides film.exposure).
    #[arg(long)]
    exposure: Option<f32>,
    /// No progress bar and no summary line.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(clap::Args)]
struct StudyArgs {
    /// The scene files (RON).
    #[arg(required = true)]
    scenes: Vec<PathBuf>,
    /// Integrators, comma-separated, each NAME[:key=value]... (e.g. alpha:mode=preprocessed).
    #[arg(long, default_value = lumis::study::DEFAULT_INTEGRATORS)]
    integrators: String,
    /// N: samples per light per camera sample.
    #[arg(long, default_value_t = 64)]
    samples: u32,
    /// K: independent runs (seeds) per configuration, at least 2.
    #[arg(long, default_value_t = 4)]
    runs: u32,
    /// A reference image (EXR) for a single scene, instead of rendering one.
    #[arg(long, conflicts_with = "reference_samples")]
    reference: Option<PathBuf>,
    /// Samples per light per pixel of the rendered reference (balance heuristic), cached next
    /// to the scene as NAME.reference-WxH-S.exr with the parameters that made it.
    #[arg(long, default_value_t = 4096)]
    reference_samples: u32,
    /// Also run every integrator with the N that matches `alpha`'s time.
    #[arg(long)]
    equal_time: bool,
    /// Sweeps to run, comma-separated: clamp (Figure 2), m (Figure 7), n (Figures 3, 4), all, none.
    #[arg(long, default_value = "all")]
    sweeps: String,
    /// Override scene values for every scene (repeatable), e.g. --set film.width=64.
    #[arg(long = "set", value_name = "PATH=VALUE")]
    overrides: Vec<String>,
    /// Worker threads (default: one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Seed of the first run (runs use seed + 1 ... seed + K).
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
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

fn main() {
    let cli = Cli::parse();
    lumis::link_plugins();
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::Study(args) => study(args),
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
        std::process::exit(if interrupted { 130 } else { 1 });
    }
}

/// Splits a comma-separated list at the commas outside parentheses and brackets.
fn split_list(list: &str) -> Vec<&str> {
    let (mut depth, mut start, mut items) = (0i32, 0, Vec::new());
    for (i, c) in list.char_indices() {
        match c {
            '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&list[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items.push(&list[start..]);
    items
        .into_iter()
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect()
}

fn study(args: StudyArgs) -> Result<()> {
    use lumis::study::{Choice, ReferenceSource, StudyConfig, Sweeps};
    let config = StudyConfig {
        scenes: args.scenes,
        integrators: split_list(&args.integrators)
            .into_iter()
            .map(Choice::parse)
            .collect::<Result<_>>()?,
        samples: args.samples,
        runs: args.runs,
        reference: match args.reference {
            Some(file) => ReferenceSource::File(file),
            None => ReferenceSource::Samples(args.reference_samples),
        },
        equal_time: args.equal_time,
        sweeps: Sweeps::parse(&args.sweeps)?,
        overrides: args.overrides,
        threads: args.threads,
        seed: args.seed,
        out: args.out,
        report: args.report,
        notes: args.notes,
        command: Some(
            std::iter::once("lumis".to_string())
                .chain(std::env::args().skip(1))
                .collect::<Vec<_>>()
                .join(" "),
        ),
    };
    let bar = if args.quiet || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} renders (eta {eta}) {msg}",
            )
            .context("progress bar template")?,
        );
        bar.enable_steady_tick(std::time::Duration::from_millis(200));
        bar
    };
    // Ctrl-C stops at the next tile; every finished row is already written.
    let cancel = Arc::new(AtomicBool::new(false));
    let flag = cancel.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed))
        .context("cannot install the Ctrl-C handler")?;
    let start = std::time::Instant::now();
    lumis::study::run(&config, &bar, &cancel)?;
    if !args.quiet {
        eprintln!(
            "study of {} scene(s) finished in {:.1} s -> {}",
            config.scenes.len(),
            start.elapsed().as_secs_f64(),
            config.report_path().display()
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
    lumis::bsdfs::measured::write_merl(output, |wi, wo| bsdf.eval(wo, wi) / wi.z)
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
    let load_start = std::time::Instant::now();
    let mut loaded = lumis::scene::load_scene(&args.scene, &overrides)?;
    let load_time = load_start.elapsed();
    let exr_path = args.output.unwrap_or_else(|| loaded.scene.output.clone());
    lumis::render_files::check_exr_path(&exr_path).map_err(anyhow::Error::msg)?;
    let exposure = args.exposure.unwrap_or(loaded.scene.exposure);

    loaded.integrator.preprocess(&loaded.scene);
    let window = loaded.scene.window;
    let pixels = window.width as u64 * window.height as u64;
    let bar = if args.quiet || !std::io::stderr().is_terminal() {
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
    // Ctrl-C stops the render at the next camera sample; the finished pixels are written, marked
    // partial.
    let cancel = Arc::new(AtomicBool::new(false));
    let flag = cancel.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed))
        .context("cannot install the Ctrl-C handler")?;
    let (film, stats) = lumis::render::render_cancellable(
        &loaded.scene,
        loaded.integrator.as_ref(),
        args.threads,
        &|n| bar.inc(n),
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
            "interrupted: wrote a partial image ({} of {} pixels) to {}",
            stats.pixels_done,
            stats.pixels_total,
            exr_path.display()
        );
        std::process::exit(130);
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
