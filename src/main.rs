//! The `lumis` command-line program.

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use lumis::image_io::{self, Metadata};
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
    /// Write a MERL-format measured BRDF file tabulating any BSDF (e.g. to test `measured`).
    Merl {
        /// The BSDF to tabulate, as in a scene file: '(type: "glossy", roughness: 0.2)'.
        #[arg(long)]
        bsdf: String,
        /// The .binary file to write.
        #[arg(short, long)]
        output: PathBuf,
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

fn main() {
    let cli = Cli::parse();
    lumis::link_plugins();
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::Merl { bsdf, output } => merl(&bsdf, &output),
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
        std::process::exit(1);
    }
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
    if exr_path
        .extension()
        .is_none_or(|e| !e.eq_ignore_ascii_case("exr"))
    {
        bail!(
            "the output `{}` must end in .exr (the PNG preview is written beside it)",
            exr_path.display()
        );
    }
    let png_path = exr_path.with_extension("png");
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
    // Ctrl-C stops the render at the next tile; what is finished is written, marked partial.
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
    let mut metadata: Metadata = vec![
        ("scene".into(), args.scene.display().to_string()),
        ("integrator".into(), integrator.kind.clone()),
        ("spp".into(), loaded.scene.spp.to_string()),
        ("seed".into(), loaded.scene.seed.to_string()),
        ("partial".into(), stats.partial().to_string()),
        (
            "tiles".into(),
            format!("{} of {}", stats.tiles_done, stats.tiles_total),
        ),
    ];
    metadata.extend(integrator.params.iter().map(|(k, v)| {
        (
            format!("integrator.{k}"),
            ron::to_string(v).unwrap_or_default(),
        )
    }));
    image_io::write_exr(&film, &exr_path, &metadata)?;
    image_io::write_png(&film, &png_path, exposure)?;
    let mut previews = Vec::new();
    for (i, aov) in film.aovs.iter().enumerate().filter(|(_, a)| a.preview) {
        let path = exr_path.with_extension(format!("{}.png", aov.name));
        image_io::write_aov_png(&film, i, &path)?;
        previews.push(path.display().to_string());
    }

    if stats.partial() {
        eprintln!(
            "interrupted: wrote a partial image ({} of {} tiles) to {}",
            stats.tiles_done,
            stats.tiles_total,
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
            [
                vec![
                    exr_path.display().to_string(),
                    png_path.display().to_string()
                ],
                previews
            ]
            .concat()
            .join(", ")
        );
    }
    Ok(())
}
