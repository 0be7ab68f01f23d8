//! A planned study on disk (docs/distributed.md): `DIR/manifest.ron` lists the cells and the
//! arguments that plan them again, `DIR/cells/NNNNNN.cell` is cell N's raw result (binary,
//! written atomically) and `DIR/cells/NNNNNN.error` the error of a cell that failed.
//!
//! A cell file holds the run's image and AOV channels as the local study reads them (f32 per
//! pixel, as the film resolves them), not per-pixel Σx and Σx² over its camera samples: the
//! study's statistics are across runs (each run is one draw of every pixel's estimator, and the
//! jackknife leaves runs out), so a run's own sums of squares would be unused, and the f32
//! values are what makes `--collect` give the local report exactly (32 bytes a pixel with every
//! channel, against 56 for a count and f64 sums of colour and its square).

use super::cell::{CellResult, Channel};
use super::plan::{Cell, Role};
use crate::binary::{Reader, Writer};
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The manifest's format; a manifest of another is refused.
pub const MANIFEST_FORMAT: u32 = 1;
const MANIFEST: &str = "manifest.ron";
const CELL_MAGIC: &[u8; 8] = b"LUMISCEL";
const CELL_VERSION: u32 = 1;

/// What `--plan` writes: enough to run any cell and collect them, from any machine that sees
/// the same files.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Manifest {
    pub format: u32,
    /// The study's arguments after `lumis study`, without `--plan` and `--slurm`: parsed
    /// again (in `directory`) by `--cell` and `--collect`, they plan the same cells.
    pub arguments: Vec<String>,
    /// The working directory of the plan, against which the arguments' paths are read.
    pub directory: PathBuf,
    /// The command that runs cell INDEX (the index may instead come from the environment).
    pub command: String,
    /// The cells in index order.
    pub cells: Vec<Cell>,
}

impl Manifest {
    pub fn write(&self, dir: &Path) -> Result<()> {
        let text = ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::default())
            .context("cannot serialise the manifest")?;
        let path = dir.join(MANIFEST);
        lumis_core::image_io::write_atomically(&path, |file| {
            std::io::Write::write_all(file, text.as_bytes()).map_err(|e| e.to_string())
        })?;
        Ok(())
    }

    pub fn read(dir: &Path) -> Result<Self> {
        let path = dir.join(MANIFEST);
        let text = std::fs::read_to_string(&path).with_context(|| {
            format!(
                "cannot read `{}` (is `{}` a study planned with --plan?)",
                path.display(),
                dir.display()
            )
        })?;
        let manifest: Manifest = ron::from_str(&text)
            .map_err(|e| anyhow::anyhow!("`{}`: not a study manifest: {e}", path.display()))?;
        if manifest.format != MANIFEST_FORMAT {
            bail!(
                "`{}` is a manifest of format {}; this lumis reads format {MANIFEST_FORMAT}",
                path.display(),
                manifest.format
            );
        }
        Ok(manifest)
    }
}

/// Where cell `index`'s result goes.
pub fn cell_path(dir: &Path, index: usize) -> PathBuf {
    dir.join("cells").join(format!("{index:06}.cell"))
}

/// Where cell `index`'s error goes when it fails.
pub fn error_path(dir: &Path, index: usize) -> PathBuf {
    dir.join("cells").join(format!("{index:06}.error"))
}

/// Writes a cell's result.
pub fn write_cell(path: &Path, result: &CellResult) -> Result<()> {
    let mut w = Writer::new(CELL_MAGIC, CELL_VERSION);
    let cell = &result.cell;
    w.u64(cell.scene as u64);
    match cell.role {
        Role::Shard(j) => {
            w.u32(0);
            w.u32(j);
        }
        Role::Run { configuration, run } => {
            w.u32(1);
            w.u64(configuration as u64);
            w.u32(run);
        }
    }
    w.u64(cell.seed);
    w.u32(result.width);
    w.u32(result.height);
    w.f64(result.cpu_time);
    w.f64(result.wall_time);
    let color: Vec<f32> = result.color.iter().flatten().copied().collect();
    w.f32s(&color);
    w.u64(result.channels.len() as u64);
    for channel in &result.channels {
        w.str(&channel.name);
        w.f32s(&channel.values);
    }
    w.write(path)
        .with_context(|| format!("cannot write the cell `{}`", path.display()))
}

/// Reads a cell's result and checks it is `expected`'s.
pub fn read_cell(path: &Path, expected: &Cell) -> Result<CellResult> {
    let mut r = Reader::open(path, CELL_MAGIC, CELL_VERSION, "study cell")?;
    let scene = r.u64("the scene index")? as usize;
    let role = match r.u32("the cell's kind")? {
        0 => Role::Shard(r.u32("the shard")?),
        1 => Role::Run {
            configuration: r.u64("the configuration")? as usize,
            run: r.u32("the run")?,
        },
        other => return Err(r.problem(format!("unknown cell kind {other}"))),
    };
    let cell = Cell {
        scene,
        role,
        seed: r.u64("the seed")?,
    };
    if cell != *expected {
        return Err(r.problem(format!(
            "holds {cell:?}, the plan's cell here is {expected:?} (a result of another plan?)"
        )));
    }
    let (width, height) = (r.u32("the width")?, r.u32("the height")?);
    let cpu_time = r.f64("the CPU time")?;
    let wall_time = r.f64("the wall time")?;
    let pixels = width as usize * height as usize;
    let color = r.f32s("the image")?;
    if color.len() != 3 * pixels {
        return Err(r.problem(format!(
            "{} colour values for {width}×{height} pixels",
            color.len()
        )));
    }
    let count = r.u64("the channel count")?;
    let mut channels = Vec::new();
    for _ in 0..count {
        let name = r.str("a channel's name")?;
        let values = r.f32s("a channel's values")?;
        if values.len() != pixels {
            return Err(r.problem(format!(
                "channel `{name}` has {} values for {pixels} pixels",
                values.len()
            )));
        }
        channels.push(Channel { name, values });
    }
    r.finish()?;
    Ok(CellResult {
        cell,
        width,
        height,
        color: color.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        channels,
        cpu_time,
        wall_time,
    })
}

/// Cell indices as short ranges: `0-3, 7, 9-10`.
pub fn ranges(indices: &[usize]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < indices.len() {
        let mut j = i;
        while j + 1 < indices.len() && indices[j + 1] == indices[j] + 1 {
            j += 1;
        }
        parts.push(if i == j {
            indices[i].to_string()
        } else {
            format!("{}-{}", indices[i], indices[j])
        });
        i = j + 1;
    }
    parts.join(", ")
}
