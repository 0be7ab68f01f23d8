//! Renders split over processes: `lumis render SCENE --shard i/n` writes the sums of its tiles
//! (a [`ShardFile`]), and `lumis merge` adds the shards' sums and resolves them into the image
//! the one-process render writes, bit for bit (docs/distributed.md).
//!
//! A shard file holds, per pixel of the window, the camera samples summed, Σ colour (f64) and
//! the integrator's own sums (f64), plus what is needed to rebuild the integrator that resolves
//! them: the scene file and the overrides of the render.

use crate::binary::{Reader, Writer};
use anyhow::{Context, Result, bail};
use glam::DVec3;
use lumis_core::output::Window;
use lumis_core::render::{FilmSums, RenderStats, Shard};
use std::path::{Path, PathBuf};
use std::time::Duration;

const MAGIC: &[u8; 8] = b"LUMISSHD";
const VERSION: u32 = 1;
const WHAT: &str = "render shard";

/// One shard of a render, as written by `lumis render --shard`.
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
    pub sums: FilmSums,
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
        let f = &self.sums;
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
        w.f64s(&f.sums);
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
        {
            return Err(r.problem(format!(
                "a {width}×{height} window at ({x}, {y}) outside its {full_width}×{full_height} film"
            )));
        }
        let stride = r.u64("the sums per pixel")? as usize;
        let pixels = width as usize * height as usize;
        let samples = r.u32s("the sample counts")?;
        let color = r.f64s("the colour sums")?;
        let sums = r.f64s("the integrator's sums")?;
        if samples.len() != pixels
            || color.len() != 3 * pixels
            || Some(sums.len()) != pixels.checked_mul(stride)
        {
            return Err(r.problem(format!(
                "{} counts, {} colour sums and {} integrator sums for {pixels} pixels with {stride} sums each",
                samples.len(),
                color.len(),
                sums.len()
            )));
        }
        r.finish()?;
        Ok(ShardFile {
            scene_name,
            scene_path,
            scene_hash,
            overrides,
            exposure,
            shard: Shard { index, count },
            stats,
            sums: FilmSums {
                full_width,
                full_height,
                window,
                samples,
                color: color
                    .chunks_exact(3)
                    .map(|c| DVec3::new(c[0], c[1], c[2]))
                    .collect(),
                sums,
                stride,
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

/// Merges the shards at `paths` (all the shards of one render, in any order) and writes the
/// render's EXR and previews to `output` (default: the scene's output); returns the files
/// written.
pub fn merge(paths: &[PathBuf], output: Option<&Path>) -> Result<Vec<PathBuf>> {
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
        ) != (&first.scene_path, first.scene_hash, &first.overrides, count)
        {
            bail!(
                "`{}` is shard {} of a render of `{}` with overrides [{}]; `{}` is shard {} of `{}` with [{}]: not the same render (or the scene file changed between them)",
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
    let mut sums = first.sums.clone();
    for (shard, path) in shards.iter().zip(paths).skip(1) {
        sums.add(&shard.sums)
            .map_err(|e| anyhow::anyhow!("`{}`: {e}", path.display()))?;
    }
    let loaded = lumis_core::scene::load::load_scene(&first.scene_path, &first.overrides)
        .with_context(|| "the shards' scene, to resolve their sums")?;
    let scene = &loaded.scene;
    let integrator = loaded.integrator.as_ref();
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
    let metadata = lumis_core::render_files::metadata(
        &first.scene_name,
        &loaded.description.integrator,
        scene.spp,
        scene.seed,
        &stats,
    );
    let written = lumis_core::render_files::write(&film, &exr, first.exposure, &metadata)?;
    Ok(written.all().into_iter().map(Path::to_path_buf).collect())
}
