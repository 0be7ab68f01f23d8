//! Renders split over processes, and renders saved to continue: `lumis render SCENE --shard i/n`
//! writes the sums of its tiles (a [`ShardFile`]), and `lumis merge` adds the shards' sums and
//! resolves them into the image the one-process render writes, bit for bit
//! (docs/distributed.md); an interrupted render in passes saves its whole state in the same
//! format (shard 0 of 1), which `lumis render --resume` continues.
//!
//! A file holds the render's state ([`RenderState`]: per pixel of the window the camera samples
//! summed, Σ u·colour, Σ u and the half-images (f64), the integrator's own sums (f64); the passes
//! so far and a pass cut short; what the integrator learned beyond the sums, as its bytes), what
//! the render was asked for ([`Settings`]) and what is needed to rebuild the integrator that
//! resolves it: the scene file and the overrides of the render.

use crate::binary::{Reader, Writer};
use anyhow::{Context, Result, bail};
use glam::DVec3;
use lumis_core::budgets::Budgets;
use lumis_core::error_estimate::{ErrorEstimate, Metric};
use lumis_core::output::Window;
use lumis_core::passes::{History, PassRecord, PlannedPass, Settings, Stop, Stopping};
use lumis_core::progressive::RenderState;
use lumis_core::render::{FilmSums, RenderStats, Shard};
use std::path::{Path, PathBuf};
use std::time::Duration;

const MAGIC: &[u8; 8] = b"LUMISSHD";
const VERSION: u32 = 4;
const WHAT: &str = "render shard";

/// One shard of a render, or a whole render's state, as written by `lumis render --shard` and
/// by an interrupted render in passes.
#[derive(Clone, Debug)]
pub struct ShardFile {
    /// The scene file as the user named it (for the EXR's metadata) and its absolute path (to
    /// load it again).
    pub scene_name: String,
    pub scene_path: PathBuf,
    /// FNV-1a of the scene file's bytes when the shard was rendered: shards of different
    /// versions of a scene are not one render.
    pub scene_hash: u64,
    /// The render's overrides, `--spp` and `--seed` included.
    pub overrides: Vec<String>,
    /// Exposure of the PNG preview, stops.
    pub exposure: f32,
    pub shard: Shard,
    pub stats: RenderStats,
    pub settings: Settings,
    /// How the render's passes spread their samples over the pixels (a shard's are uniform).
    pub budgets: Budgets,
    pub state: RenderState,
}

fn write_pass(w: &mut Writer, pass: &PlannedPass) {
    w.u32(pass.end);
    w.u64(pass.planned);
}

fn read_pass(r: &mut Reader) -> Result<PlannedPass> {
    Ok(PlannedPass {
        end: r.u32("a pass's samples")?,
        planned: r.u64("a pass's planned samples")?,
    })
}

fn metric_code(metric: Metric) -> u32 {
    match metric {
        Metric::RelMse => 0,
        Metric::Mse => 1,
    }
}

fn read_metric(r: &mut Reader) -> Result<Metric> {
    match r.u32("the error metric")? {
        0 => Ok(Metric::RelMse),
        1 => Ok(Metric::Mse),
        other => Err(r.problem(format!("an unknown error metric {other}"))),
    }
}

/// Stops are written as their names (an empty name: none).
fn write_stop(w: &mut Writer, stop: Option<Stop>) {
    w.str(stop.map_or("", Stop::name));
}

fn read_stop(r: &mut Reader) -> Result<Option<Stop>> {
    let name = r.str("a stop")?;
    if name.is_empty() {
        return Ok(None);
    }
    Stop::parse(&name)
        .map(Some)
        .ok_or_else(|| r.problem(format!("an unknown stop `{name}`")))
}

fn write_settings(w: &mut Writer, settings: &Settings) {
    match &settings.stopping {
        Stopping::Samples { spp, passes } => {
            w.u32(0);
            w.u32(*spp);
            w.u32(*passes);
        }
        Stopping::Target {
            error,
            max_spp,
            max_time,
        } => {
            w.u32(1);
            w.f64(*error);
            w.u32(*max_spp);
            w.f64(max_time.unwrap_or(f64::NAN));
        }
        Stopping::Time { seconds, max_spp } => {
            w.u32(2);
            w.f64(*seconds);
            w.u32(*max_spp);
        }
        Stopping::Replay(passes) => {
            w.u32(3);
            w.u64(passes.len() as u64);
            passes.iter().for_each(|p| write_pass(w, p));
        }
    }
    w.u32(metric_code(settings.metric));
    w.f64(settings.confidence);
}

fn read_settings(r: &mut Reader) -> Result<Settings> {
    let stopping = match r.u32("the kind of render")? {
        0 => Stopping::Samples {
            spp: r.u32("the samples")?,
            passes: r.u32("the passes")?,
        },
        1 => Stopping::Target {
            error: r.f64("the target error")?,
            max_spp: r.u32("the cap on samples")?,
            max_time: Some(r.f64("the cap on time")?).filter(|t| !t.is_nan()),
        },
        2 => Stopping::Time {
            seconds: r.f64("the time")?,
            max_spp: r.u32("the cap on samples")?,
        },
        3 => {
            let n = r.u64("the replayed passes")?;
            if n > u64::from(u32::MAX) {
                return Err(r.problem(format!("{n} replayed passes")));
            }
            Stopping::Replay((0..n).map(|_| read_pass(r)).collect::<Result<_>>()?)
        }
        other => return Err(r.problem(format!("an unknown kind of render {other}"))),
    };
    Ok(Settings {
        stopping,
        metric: read_metric(r)?,
        confidence: r.f64("the confidence")?,
    })
}

fn write_error(w: &mut Writer, error: &Option<ErrorEstimate>) {
    let Some(e) = error else {
        w.u32(0);
        return;
    };
    w.u32(1);
    w.u32(metric_code(e.metric));
    for v in [e.confidence, e.value, e.low, e.high, e.variance] {
        w.f64(v);
    }
    w.u64(e.pixels);
}

fn read_error(r: &mut Reader) -> Result<Option<ErrorEstimate>> {
    if r.u32("whether a pass has an error estimate")? == 0 {
        return Ok(None);
    }
    Ok(Some(ErrorEstimate {
        metric: read_metric(r)?,
        confidence: r.f64("a confidence")?,
        value: r.f64("an error")?,
        low: r.f64("an error's lower bound")?,
        high: r.f64("an error's upper bound")?,
        variance: r.f64("an error's variance")?,
        pixels: r.u64("an error's pixels")?,
    }))
}

impl ShardFile {
    pub fn write(&self, path: &Path) -> Result<()> {
        let mut w = Writer::new(MAGIC, VERSION);
        w.str(&self.scene_name);
        w.str(&self.scene_path.to_string_lossy());
        w.u64(self.scene_hash);
        w.u64(self.overrides.len() as u64);
        self.overrides.iter().for_each(|o| w.str(o));
        w.f32(self.exposure);
        w.u32(self.shard.index);
        w.u32(self.shard.count);
        let s = &self.stats;
        w.f64(s.wall_time.as_secs_f64());
        w.u64(s.camera_samples);
        w.u64(s.rays);
        w.u64(s.threads as u64);
        w.u64(s.pixels_done);
        w.u64(s.pixels_total);
        w.u32(s.tiles_done);
        w.u32(s.tiles_total);
        write_settings(&mut w, &self.settings);
        w.u32(match self.budgets {
            Budgets::Uniform => 0,
            Budgets::PerPixel => 1,
        });
        let f = &self.state.sums;
        for v in [
            f.full_width,
            f.full_height,
            f.window.x,
            f.window.y,
            f.window.width,
            f.window.height,
        ] {
            w.u32(v);
        }
        w.u64(f.stride as u64);
        w.u32s(&f.samples);
        let color: Vec<f64> = f.color.iter().flat_map(|c| c.to_array()).collect();
        w.f64s(&color);
        w.f64s(&f.weight);
        let halves: Vec<f64> = f.halves.iter().flatten().copied().collect();
        w.f64s(&halves);
        w.f64s(&f.sums);
        let h = &self.state.history;
        w.f64(h.mass);
        w.f64(h.elapsed);
        write_stop(&mut w, h.stopped);
        w.u64(h.passes.len() as u64);
        for record in &h.passes {
            write_pass(&mut w, &record.pass);
            w.f64(record.seconds);
            write_error(&mut w, &record.error);
        }
        match &self.state.current {
            Some((pass, stop)) => {
                w.u32(1);
                write_pass(&mut w, pass);
                write_stop(&mut w, *stop);
            }
            None => w.u32(0),
        }
        w.bytes(&self.state.learned);
        w.write(path)
            .with_context(|| format!("cannot write the shard `{}`", path.display()))
    }

    pub fn read(path: &Path) -> Result<Self> {
        let mut r = Reader::open(path, MAGIC, VERSION, WHAT)?;
        let scene_name = r.str("the scene's name")?;
        let scene_path = PathBuf::from(r.str("the scene's path")?);
        let scene_hash = r.u64("the scene's hash")?;
        let overrides = r.u64("the override count")?;
        let overrides = (0..overrides)
            .map(|_| r.str("an override"))
            .collect::<Result<Vec<_>>>()?;
        let exposure = f32::from_bits(r.u32("the exposure")?);
        let (index, count) = (r.u32("the shard index")?, r.u32("the shard count")?);
        if index >= count {
            return Err(r.problem(format!("shard {index} of {count}")));
        }
        let wall = r.f64("the wall time")?;
        let stats = RenderStats {
            wall_time: Duration::try_from_secs_f64(wall)
                .map_err(|_| r.problem(format!("a wall time of {wall} s")))?,
            camera_samples: r.u64("the camera samples")?,
            rays: r.u64("the rays")?,
            threads: r.u64("the threads")? as usize,
            pixels_done: r.u64("the pixels done")?,
            pixels_total: r.u64("the pixels")?,
            tiles_done: r.u32("the tiles done")?,
            tiles_total: r.u32("the tiles")?,
        };
        let settings = read_settings(&mut r)?;
        let budgets = match r.u32("the budgets")? {
            0 => Budgets::Uniform,
            1 => Budgets::PerPixel,
            code => return Err(r.problem(format!("budgets of code {code}"))),
        };
        let mut size = [0u32; 6];
        for v in &mut size {
            *v = r.u32("the film's size")?;
        }
        let [full_width, full_height, x, y, width, height] = size;
        let window = Window {
            x,
            y,
            width,
            height,
        };
        if u64::from(x) + u64::from(width) > u64::from(full_width)
            || u64::from(y) + u64::from(height) > u64::from(full_height)
            || width == 0
            || height == 0
        {
            return Err(r.problem(format!(
                "a {width}×{height} window at ({x}, {y}) outside its {full_width}×{full_height} film"
            )));
        }
        let stride = r.u64("the sums per pixel")? as usize;
        let pixels = width as usize * height as usize;
        let samples = r.u32s("the sample counts")?;
        let color = r.f64s("the colour sums")?;
        let weight = r.f64s("the weights")?;
        let halves = r.f64s("the half-images")?;
        let sums = r.f64s("the integrator's sums")?;
        if samples.len() != pixels
            || color.len() != 3 * pixels
            || weight.len() != pixels
            || (!halves.is_empty() && halves.len() != 2 * pixels)
            || Some(sums.len()) != pixels.checked_mul(stride)
        {
            return Err(r.problem(format!(
                "{} counts, {} colour sums, {} weights, {} half-image sums and {} integrator sums for {pixels} pixels with {stride} sums each",
                samples.len(),
                color.len(),
                weight.len(),
                halves.len(),
                sums.len()
            )));
        }
        let mass = r.f64("the weight mass")?;
        let elapsed = r.f64("the time")?;
        let stopped = read_stop(&mut r)?;
        let passes = r.u64("the pass count")?;
        let mut records = Vec::new();
        for _ in 0..passes {
            let pass = read_pass(&mut r)?;
            let seconds = r.f64("a pass's time")?;
            let error = read_error(&mut r)?;
            records.push(PassRecord {
                pass,
                seconds,
                error,
            });
        }
        let current = if r.u32("whether a pass was cut short")? == 1 {
            Some((read_pass(&mut r)?, read_stop(&mut r)?))
        } else {
            None
        };
        let learned = r.bytes("what the integrator learned")?;
        r.finish()?;
        Ok(ShardFile {
            scene_name,
            scene_path,
            scene_hash,
            overrides,
            exposure,
            shard: Shard { index, count },
            stats,
            settings,
            budgets,
            state: RenderState {
                sums: FilmSums {
                    full_width,
                    full_height,
                    window,
                    samples,
                    color: color
                        .chunks_exact(3)
                        .map(|c| DVec3::new(c[0], c[1], c[2]))
                        .collect(),
                    weight,
                    halves: halves.chunks_exact(2).map(|h| [h[0], h[1]]).collect(),
                    sums,
                    stride,
                },
                history: History {
                    mass,
                    passes: records,
                    elapsed,
                    stopped,
                },
                current,
                learned,
            },
        })
    }
}

/// FNV-1a (64 bits) of the file at `path`: a fingerprint stable across builds and machines.
pub fn file_hash(path: &Path) -> Result<u64> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read `{}`", path.display()))?;
    Ok(bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    }))
}

/// The shard file a render writes by default: beside its EXR, `NAME.shard-I-of-N.lshard`.
pub fn default_path(exr: &Path, shard: Shard) -> PathBuf {
    exr.with_extension(format!("shard-{}-of-{}.lshard", shard.index, shard.count))
}

/// The file a render's state is saved to (after an interrupt, or merged from shards between
/// passes): beside its EXR, `NAME.lshard`.
pub fn state_path(exr: &Path) -> PathBuf {
    exr.with_extension("lshard")
}

/// What [`merge`] did.
#[derive(Debug)]
pub struct Merged {
    /// The EXR and previews written.
    pub files: Vec<PathBuf>,
    /// The passes so far (complete when the pass planned as the last is done).
    pub history: History,
    /// Where the merged state was saved, when the render has more passes: the shards of the
    /// next pass resume from it.
    pub state: Option<PathBuf>,
}

/// A short description of a file's passes, for messages.
fn passes_text(history: &History, current: &Option<(PlannedPass, Option<Stop>)>) -> String {
    let ends: Vec<String> = history
        .passes
        .iter()
        .map(|p| p.pass.end.to_string())
        .collect();
    format!(
        "passes ending at [{}] samples{}",
        ends.join(", "),
        if current.is_some() {
            " and one cut short"
        } else {
            ""
        }
    )
}

/// The EXR metadata key of a render's budgets, written when they are not uniform (`--replay`
/// reads it).
pub const BUDGETS_KEY: &str = "budgets";

/// Merges the shards at `paths` (all the shards of one render, after the same pass, in any
/// order) and writes the render's EXR and previews to `output` (default: the scene's output);
/// when the render has more passes, also its merged state, to `state` (default:
/// [`state_path`] of the EXR), from which the shards of the next pass resume.
pub fn merge(paths: &[PathBuf], output: Option<&Path>, state: Option<&Path>) -> Result<Merged> {
    let Some(first_path) = paths.first() else {
        bail!("nothing to merge: name the shard files");
    };
    let shards = paths
        .iter()
        .map(|p| ShardFile::read(p))
        .collect::<Result<Vec<_>>>()?;
    let first = &shards[0];
    let count = first.shard.count;
    let mut seen: Vec<Option<&Path>> = vec![None; count as usize];
    for (shard, path) in shards.iter().zip(paths) {
        if (
            &shard.scene_path,
            shard.scene_hash,
            &shard.overrides,
            shard.shard.count,
            &shard.settings,
            shard.budgets,
        ) != (
            &first.scene_path,
            first.scene_hash,
            &first.overrides,
            count,
            &first.settings,
            first.budgets,
        ) {
            bail!(
                "`{}` is shard {} of a render of `{}` with overrides [{}]; `{}` is shard {} of `{}` with [{}]: not the same render (or the scene file or the render's settings changed between them)",
                path.display(),
                shard.shard,
                shard.scene_path.display(),
                shard.overrides.join(" "),
                first_path.display(),
                first.shard,
                first.scene_path.display(),
                first.overrides.join(" ")
            );
        }
        let plan = |f: &ShardFile| -> Vec<PlannedPass> {
            f.state.history.passes.iter().map(|p| p.pass).collect()
        };
        if plan(shard) != plan(first) || shard.state.current.is_some() {
            bail!(
                "`{}` has {}; `{}` has {}: shards merge after the same pass",
                path.display(),
                passes_text(&shard.state.history, &shard.state.current),
                first_path.display(),
                passes_text(&first.state.history, &first.state.current)
            );
        }
        let slot = &mut seen[shard.shard.index as usize];
        if let Some(other) = slot {
            bail!(
                "`{}` and `{}` are both shard {}",
                other.display(),
                path.display(),
                shard.shard
            );
        }
        *slot = Some(path);
    }
    let missing: Vec<String> = (0..count)
        .filter(|&i| seen[i as usize].is_none())
        .map(|i| format!("{i}/{count}"))
        .collect();
    if !missing.is_empty() {
        bail!(
            "shard{} {} of the render of `{}` missing (render {} with --shard)",
            if missing.len() > 1 { "s" } else { "" },
            missing.join(", "),
            first.scene_path.display(),
            if missing.len() > 1 { "them" } else { "it" }
        );
    }

    if file_hash(&first.scene_path)? != first.scene_hash {
        bail!(
            "the scene `{}` has changed since its shards were rendered: render them again",
            first.scene_path.display()
        );
    }
    let mut merged = first.state.clone();
    for (shard, path) in shards.iter().zip(paths).skip(1) {
        merged
            .sums
            .add(&shard.state.sums)
            .map_err(|e| anyhow::anyhow!("`{}`: {e}", path.display()))?;
    }
    let settings = &first.settings;
    if settings.estimates_error()
        && let Some(last) = merged.history.passes.last_mut()
    {
        last.error = lumis_core::error_estimate::estimate(
            &merged.sums,
            settings.metric,
            settings.confidence,
        );
    }
    merged.history.elapsed = shards
        .iter()
        .map(|s| s.state.history.elapsed)
        .fold(0.0, f64::max);
    let loaded = lumis_core::scene::load::load_scene(&first.scene_path, &first.overrides)
        .with_context(|| "the shards' scene, to resolve their sums")?;
    let scene = &loaded.scene;
    let integrator = loaded.integrator.as_ref();
    let sums = &merged.sums;
    if (
        scene.width,
        scene.height,
        scene.window,
        integrator.pixel_sums(scene),
    ) != (sums.full_width, sums.full_height, sums.window, sums.stride)
    {
        bail!(
            "the scene `{}` has changed since the shards were rendered (its film or integrator differs)",
            first.scene_path.display()
        );
    }
    // The cache of a learned α and the like: what every shard learned in the pass, added to
    // what they learned from the passes before (the same in every shard).
    for (shard, path) in shards.iter().zip(paths).skip(1) {
        merged.learned = integrator
            .merge_learned_states(&merged.learned, &shard.state.learned)
            .map_err(|e| {
                anyhow::anyhow!("`{}` and `{}`: {e}", first_path.display(), path.display())
            })?;
    }
    let film = sums.resolve(scene, integrator);
    let total = |f: fn(&RenderStats) -> u64| shards.iter().map(|s| f(&s.stats)).sum::<u64>();
    let stats = RenderStats {
        wall_time: shards.iter().map(|s| s.stats.wall_time).sum(),
        camera_samples: total(|s| s.camera_samples),
        rays: total(|s| s.rays),
        threads: shards.iter().map(|s| s.stats.threads).max().unwrap_or(1),
        pixels_done: total(|s| s.pixels_done),
        pixels_total: total(|s| s.pixels_total),
        tiles_done: shards.iter().map(|s| s.stats.tiles_done).sum(),
        tiles_total: shards.iter().map(|s| s.stats.tiles_total).sum(),
    };
    let exr = output.map_or_else(|| scene.output.clone(), Path::to_path_buf);
    let mut metadata = if *settings == Settings::samples(scene.spp) {
        lumis_core::render_files::metadata(
            &first.scene_name,
            &loaded.description.integrator,
            scene.spp,
            scene.seed,
            &stats,
        )
    } else {
        lumis_core::render_files::passes_metadata(
            &first.scene_name,
            &loaded.description.integrator,
            scene.seed,
            &stats,
            settings,
            &merged.history,
        )
    };
    if first.budgets != Budgets::Uniform {
        metadata.push((BUDGETS_KEY.to_string(), first.budgets.name().to_string()));
    }
    let written = lumis_core::render_files::write(&film, &exr, first.exposure, &metadata)?;
    let state = if merged.history.complete() {
        None
    } else {
        let path = state.map_or_else(|| state_path(&exr), Path::to_path_buf);
        ShardFile {
            shard: Shard::WHOLE,
            stats,
            state: merged.clone(),
            ..first.clone()
        }
        .write(&path)?;
        Some(path)
    };
    Ok(Merged {
        files: written.all().into_iter().map(Path::to_path_buf).collect(),
        history: merged.history,
        state,
    })
}
