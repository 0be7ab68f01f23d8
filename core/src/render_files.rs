//! The files of one render, as `lumis render` writes them: the EXR (colour, every AOV layer and
//! the run's metadata), the sRGB PNG preview beside it and a PNG per previewable AOV. The CLI and
//! the Python binding both write through here, so their files are the same bit for bit.

use crate::film::Film;
use crate::image_io::{self, FileWriter, Metadata, OutputError};
use crate::render::RenderStats;
use crate::scene::description::PluginSpec;
use std::path::{Path, PathBuf};

/// The files [`write`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct WrittenFiles {
    pub exr: PathBuf,
    pub png: PathBuf,
    /// `<exr stem>.<aov>.png`, one per AOV layer with a preview.
    pub previews: Vec<PathBuf>,
}

impl WrittenFiles {
    /// Every file, the EXR first.
    pub fn all(&self) -> Vec<&Path> {
        [self.exr.as_path(), self.png.as_path()]
            .into_iter()
            .chain(self.previews.iter().map(PathBuf::as_path))
            .collect()
    }
}

/// Refuses an output path that does not end in `.exr` (the previews are named after it).
pub fn check_exr_path(path: &Path) -> Result<(), String> {
    if path
        .extension()
        .is_none_or(|e| !e.eq_ignore_ascii_case("exr"))
    {
        return Err(format!(
            "the output `{}` must end in .exr (the PNG preview is written beside it)",
            path.display()
        ));
    }
    Ok(())
}

/// The EXR header's `lumis` metadata: the scene as named by the user, the integrator and its
/// parameters, the sampling settings and how much of the image was finished.
pub fn metadata(
    scene: &str,
    integrator: &PluginSpec,
    spp: u32,
    seed: u64,
    stats: &RenderStats,
) -> Metadata {
    let mut metadata: Metadata = vec![
        ("scene".into(), scene.to_string()),
        ("integrator".into(), integrator.kind.clone()),
        ("spp".into(), spp.to_string()),
        ("seed".into(), seed.to_string()),
        ("partial".into(), stats.partial().to_string()),
        (
            "pixels".into(),
            format!("{} of {}", stats.pixels_done, stats.pixels_total),
        ),
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
    metadata
}

/// Writes the EXR at `exr` (which must end in `.exr`), the preview PNG beside it scaled by
/// 2^`exposure`, and the AOV previews; each file atomically.
pub fn write(
    film: &Film,
    exr: &Path,
    exposure: f32,
    metadata: &Metadata,
) -> Result<WrittenFiles, OutputError> {
    check_exr_path(exr).map_err(|reason| OutputError {
        path: exr.to_path_buf(),
        reason,
    })?;
    let png = exr.with_extension("png");
    let previews: Vec<(usize, PathBuf)> = film
        .aovs
        .iter()
        .enumerate()
        .filter(|(_, a)| a.preview)
        .map(|(i, a)| (i, exr.with_extension(format!("{}.png", a.name))))
        .collect();
    // All files or none: the EXR is not left behind when its PNG cannot be written.
    let mut outputs: Vec<(&Path, FileWriter<'_>)> = vec![
        (exr, image_io::exr_writer(film, metadata)),
        (&png, image_io::png_writer(film, exposure)),
    ];
    for (i, path) in &previews {
        outputs.push((path, image_io::aov_png_writer(film, *i)));
    }
    image_io::write_all_atomically(outputs)?;
    Ok(WrittenFiles {
        exr: exr.to_path_buf(),
        png,
        previews: previews.into_iter().map(|(_, path)| path).collect(),
    })
}
