//! The files of one render, as `lumis render` writes them: the EXR (colour, every AOV layer and
//! the run's metadata), the sRGB PNG preview beside it and a PNG per previewable AOV; between the
//! passes of a render in passes, the preview and the error heat map. The CLI and the Python
//! binding both write through here, so their files are the same bit for bit.

use crate::error_estimate::{self, ErrorEstimate};
use crate::film::Film;
use crate::image_io::{self, FileWriter, Metadata, OutputError};
use crate::passes::{History, PlannedPass, Settings, Stopping};
use crate::render::{FilmSums, RenderStats};
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

/// The metadata of a render in passes: [`metadata`] with `spp` the samples per pixel reached
/// and `partial` whether the render is incomplete (interrupted or stopped before the pass
/// planned as its last), then what was asked (`target_error`, `max_spp`, `max_time`, `time`,
/// `error_metric`, `confidence`), the passes (`passes`, `pass_samples`: each pass's samples per
/// pixel after it; `pass_planned`: the samples each planned from its start, which with the
/// samples replay the render exactly), why they ended (`stopped`), the render's wall time
/// (`render_time`, seconds) and the image's estimated error (`error`, `error_low`,
/// `error_high`).
pub fn passes_metadata(
    scene: &str,
    integrator: &PluginSpec,
    seed: u64,
    stats: &RenderStats,
    settings: &Settings,
    history: &History,
) -> Metadata {
    let mut metadata = metadata(scene, integrator, history.samples(), seed, stats);
    let partial = !history.complete() || stats.partial();
    for (key, value) in metadata.iter_mut() {
        if key == "partial" {
            *value = partial.to_string();
        }
    }
    let mut add = |key: &str, value: String| metadata.push((key.to_string(), value));
    match &settings.stopping {
        Stopping::Samples { .. } | Stopping::Replay(_) => {}
        Stopping::Target {
            error,
            max_spp,
            max_time,
        } => {
            add("target_error", error.to_string());
            add("max_spp", max_spp.to_string());
            if let Some(t) = max_time {
                add("max_time", t.to_string());
            }
        }
        Stopping::Time { seconds, max_spp } => {
            add("time", seconds.to_string());
            add("max_spp", max_spp.to_string());
        }
    }
    add("error_metric", settings.metric.name().to_string());
    add("confidence", settings.confidence.to_string());
    let list = |f: &dyn Fn(&PlannedPass) -> String| -> String {
        history
            .passes
            .iter()
            .map(|p| f(&p.pass))
            .collect::<Vec<_>>()
            .join(",")
    };
    add("passes", history.passes.len().to_string());
    add("pass_samples", list(&|p| p.end.to_string()));
    add("pass_planned", list(&|p| p.planned.to_string()));
    add(
        "stopped",
        history.stopped.map_or("none", |s| s.name()).to_string(),
    );
    add("render_time", history.elapsed.to_string());
    if let Some(e) = history.error() {
        add("error", e.value.to_string());
        add("error_low", e.low.to_string());
        add("error_high", e.high.to_string());
    }
    metadata
}

/// The passes recorded by [`passes_metadata`] in an EXR's metadata, to render them again.
pub fn recorded_passes(metadata: &Metadata) -> Result<Vec<PlannedPass>, String> {
    let get = |key: &str| {
        metadata
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
            .ok_or_else(|| format!("its metadata has no `{key}` (not a render in passes)"))
    };
    let numbers = |key: &str| -> Result<Vec<u64>, String> {
        get(key)?
            .split(',')
            .map(|n| {
                n.parse::<u64>()
                    .map_err(|_| format!("`{key}` holds `{n}`, not a number"))
            })
            .collect()
    };
    let (ends, planned) = (numbers("pass_samples")?, numbers("pass_planned")?);
    if ends.len() != planned.len() {
        return Err("`pass_samples` and `pass_planned` list different numbers of passes".into());
    }
    let mut passes = Vec::new();
    let mut done = 0;
    for (&end, &planned) in ends.iter().zip(&planned) {
        let end = u32::try_from(end).map_err(|_| format!("a pass ends at {end} samples"))?;
        if end <= done || planned < u64::from(end - done) {
            return Err(format!(
                "a pass from {done} to {end} samples planned for {planned}: not a valid sequence of passes"
            ));
        }
        passes.push(PlannedPass { end, planned });
        done = end;
    }
    if passes.is_empty() {
        return Err("it records no pass".into());
    }
    Ok(passes)
}

/// The text of an error estimate: `0.0123 [0.0110, 0.0136] (relmse, 95 %)`.
pub fn error_text(e: &ErrorEstimate) -> String {
    format!(
        "{} [{}, {}] ({}, {} %)",
        significant(e.value),
        significant(e.low),
        significant(e.high),
        e.metric.name(),
        e.confidence * 100.0
    )
}

/// Three significant digits.
fn significant(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let digits = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    if v.abs() < 1e-4 {
        format!("{v:.2e}")
    } else {
        format!("{v:.digits$}")
    }
}

/// The error heat map of a render in passes: `<exr stem>.error.png`.
pub fn heat_map_path(exr: &Path) -> PathBuf {
    exr.with_extension("error.png")
}

/// The heat map of the error of the image `sums` resolve to: each pixel's term of the error
/// estimate, averaged over its 3 × 3 neighbourhood (one pixel's term alone is mostly noise),
/// relative to the image's error, on a log scale from 1/100 of it (black) through the image's
/// error (red) to 100 times it (white); pixels without samples are black.
pub fn heat_map_writer(sums: &FilmSums, metric: error_estimate::Metric) -> FileWriter<'_> {
    Box::new(move |file| {
        let (w, h) = (sums.window.width as usize, sums.window.height as usize);
        let map = error_estimate::error_map(sums, metric);
        let mean = map.iter().sum::<f64>() / map.len().max(1) as f64;
        let mut bytes = Vec::with_capacity(w * h * 3);
        for y in 0..h {
            for x in 0..w {
                let (mut total, mut count) = (0.0, 0.0);
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        total += map[yy * w + xx];
                        count += 1.0;
                    }
                }
                let t = if mean > 0.0 && total > 0.0 {
                    ((total / count / mean).log10() / 4.0 + 0.5).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                bytes.extend(heat(t));
            }
        }
        image_io::encode_png(file, w as u32, h as u32, bytes)
    })
}

/// A black–red–yellow–white colour ramp at `t` in [0, 1].
fn heat(t: f64) -> [u8; 3] {
    let ramp = |a: f64| (a.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [ramp(3.0 * t), ramp(3.0 * t - 1.0), ramp(3.0 * t - 2.0)]
}

/// Writes the preview PNG beside `exr` (scaled by 2^`exposure`) and, if `heat_map`, the error
/// heat map, atomically: what a render in passes shows after each pass.
pub fn write_previews(
    sums: &FilmSums,
    exr: &Path,
    exposure: f32,
    heat_map: Option<error_estimate::Metric>,
) -> Result<(), OutputError> {
    let (width, height) = (sums.window.width, sums.window.height);
    let bytes = sums.preview_bytes(exposure.exp2());
    let png = exr.with_extension("png");
    let heat = heat_map_path(exr);
    let mut outputs: Vec<(&Path, FileWriter<'_>)> = vec![(
        &png,
        Box::new(move |file| image_io::encode_png(file, width, height, bytes)),
    )];
    if let Some(metric) = heat_map {
        outputs.push((&heat, heat_map_writer(sums, metric)));
    }
    image_io::write_all_atomically(outputs)
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
