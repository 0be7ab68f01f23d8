//! Image output (multi-layer OpenEXR and an sRGB PNG preview) and EXR input.
//!
//! Outputs are written to a temporary file in the target directory and renamed into place,
//! so an interrupted run never leaves a truncated image.

use crate::film::Film;
use crate::math::Rgb;
use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image, IntegerBounds, Layer,
    LayerAttributes, ReadChannels, ReadLayers, Text, Vec2, WritableImage,
    read_all_flat_layers_from_file,
};
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// An output file could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write `{path}`: {reason}")]
pub struct OutputError {
    pub path: PathBuf,
    pub reason: String,
}

fn output_error(path: &Path, reason: impl ToString) -> OutputError {
    OutputError {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

/// Writes through `write` into a temporary file beside `path`, then renames it to `path`
/// (creating the directory if needed).
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::fs::File) -> Result<(), String>,
) -> Result<(), OutputError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir).map_err(|e| output_error(path, e))?;
    let mut tmp = tempfile::Builder::new()
        .prefix(".lumis-")
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|e| output_error(path, e))?;
    // The temporary file is private (0600); the output should be as readable as any file.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))
            .map_err(|e| output_error(path, e))?;
    }
    write(tmp.as_file_mut()).map_err(|e| output_error(path, e))?;
    tmp.as_file_mut()
        .flush()
        .map_err(|e| output_error(path, e))?;
    tmp.persist(path).map_err(|e| output_error(path, e.error))?;
    Ok(())
}

/// Key–value pairs stored in the EXR header as the text attribute `lumis`, one `key=value` a line
/// (the scene, the integrator and its settings).
pub type Metadata = Vec<(String, String)>;

/// Writes colour as channels R, G, B and each AOV as `aov.channel`, in one EXR part whose data
/// window is the rendered window of the full film.
pub fn write_exr(film: &Film, path: &Path, metadata: &Metadata) -> Result<(), OutputError> {
    let size = (film.window.width as usize, film.window.height as usize);
    let mut channels: Vec<AnyChannel<FlatSamples>> = ["R", "G", "B"]
        .iter()
        .enumerate()
        .map(|(i, name)| {
            AnyChannel::new(
                *name,
                FlatSamples::F32(film.color.iter().map(|c| c[i]).collect()),
            )
        })
        .collect();
    for (a, aov) in film.aovs.iter().enumerate() {
        for (c, channel) in aov.channels.iter().enumerate() {
            let name = format!("{}.{}", aov.name, channel);
            channels.push(AnyChannel::new(
                name.as_str(),
                FlatSamples::F32(film.aov_channel(a, c).collect()),
            ));
        }
    }
    let mut attributes = LayerAttributes {
        layer_position: Vec2(film.window.x as i32, film.window.y as i32),
        ..LayerAttributes::default()
    };
    // One attribute holding every entry: exr keeps attributes in a HashMap, whose order (and so
    // the file's bytes) would change from run to run with several.
    if !metadata.is_empty() {
        let text: String = metadata.iter().map(|(k, v)| format!("{k}={v}\n")).collect();
        attributes.other.insert(
            Text::from("lumis"),
            AttributeValue::Text(Text::from(text.as_str())),
        );
    }
    let layer = Layer::new(
        size,
        attributes,
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let mut image = Image::from_layer(layer);
    image.attributes.display_window = IntegerBounds::new(
        (0, 0),
        (film.full_width as usize, film.full_height as usize),
    );
    write_atomically(path, |file| {
        image
            .write()
            .to_buffered(std::io::BufWriter::new(file))
            .map_err(|e| e.to_string())
    })
}

/// Writes 8-bit RGB pixels (row-major) as a PNG, atomically.
pub fn write_rgb8_png(
    path: &Path,
    width: u32,
    height: u32,
    bytes: Vec<u8>,
) -> Result<(), OutputError> {
    let image = image::RgbImage::from_raw(width, height, bytes)
        .ok_or_else(|| output_error(path, "bad image size"))?;
    write_atomically(path, |file| {
        image
            .write_to(&mut std::io::BufWriter::new(file), image::ImageFormat::Png)
            .map_err(|e| e.to_string())
    })
}

/// The sRGB transfer function.
pub fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Writes the colour as an 8-bit sRGB PNG, scaled by 2^exposure and clamped.
pub fn write_png(film: &Film, path: &Path, exposure: f32) -> Result<(), OutputError> {
    let (w, h) = (film.window.width, film.window.height);
    let scale = exposure.exp2();
    let bytes: Vec<u8> = film
        .color
        .iter()
        .flat_map(|c| c.to_array())
        .map(|v| {
            let v = if v.is_finite() { v * scale } else { 0.0 };
            (linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0 + 0.5) as u8
        })
        .collect();
    write_rgb8_png(path, w, h, bytes)
}

fn exr_error(path: &Path, e: exr::error::Error) -> String {
    match e {
        exr::error::Error::Io(io) => format!("cannot read EXR file `{}`: {io}", path.display()),
        other => format!("`{}` is not a valid EXR file: {other}", path.display()),
    }
}

/// Writes the first three channels of AOV `aov` as an 8-bit PNG of display colours in [0, 1]
/// (no tone mapping: such AOVs already hold colours, e.g. the α map).
pub fn write_aov_png(film: &Film, aov: usize, path: &Path) -> Result<(), OutputError> {
    let (w, h) = (film.window.width, film.window.height);
    let channels: Vec<Vec<f32>> = (0..3).map(|c| film.aov_channel(aov, c).collect()).collect();
    let bytes: Vec<u8> = (0..(w * h) as usize)
        .flat_map(|i| channels.iter().map(move |ch| ch[i]))
        .map(|v| {
            (if v.is_finite() {
                v.clamp(0.0, 1.0)
            } else {
                0.0
            } * 255.0
                + 0.5) as u8
        })
        .collect();
    write_rgb8_png(path, w, h, bytes)
}

/// An RGB image read from an EXR file, in row order.
#[derive(Clone, Debug)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<Rgb>,
}

/// Reads the first RGB(A) layer of an EXR file; the error names the path and the reason.
pub fn read_exr_rgb(path: &Path) -> Result<RgbImage, String> {
    let bytes = std::fs::read(path).map_err(|e| exr_error(path, exr::error::Error::Io(e)))?;
    decode_exr_rgb(&bytes).map_err(|e| exr_error(path, e))
}

/// The largest image (in pixels) an EXR may declare: 2²⁷, a 16384 × 8192 environment map. The
/// header's size is checked before any pixel memory is allocated (a corrupt header asked for
/// terabytes; found by fuzzing).
pub const MAX_EXR_PIXELS: usize = 1 << 27;

/// Decodes the first RGB(A) layer of EXR data held in memory; never panics on bad data.
pub fn decode_exr_rgb(bytes: &[u8]) -> Result<RgbImage, exr::error::Error> {
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)?;
    for header in &meta.headers {
        let size = header.layer_size;
        if size
            .width()
            .checked_mul(size.height())
            .is_none_or(|area| area > MAX_EXR_PIXELS)
        {
            return Err(exr::error::Error::NotSupported(std::borrow::Cow::Owned(
                format!(
                    "{}x{} pixels is more than lumis reads ({MAX_EXR_PIXELS})",
                    size.width(),
                    size.height()
                ),
            )));
        }
    }
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |resolution, _| RgbImage {
                width: resolution.width(),
                height: resolution.height(),
                pixels: vec![Rgb::ZERO; resolution.area()],
            },
            |img: &mut RgbImage, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                img.pixels[pos.y() * img.width + pos.x()] = Rgb::new(r, g, b);
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))?;
    Ok(image.layer_data.channel_data.pixels)
}

/// Every channel of the first layer of an EXR file, by name, as f32 (for tests and tools).
pub fn read_exr_channels(path: &Path) -> Result<Vec<(String, Vec<f32>)>, String> {
    let image = read_all_flat_layers_from_file(path).map_err(|e| exr_error(path, e))?;
    let layer = image.layer_data.first().ok_or("the file has no layer")?;
    Ok(layer
        .channel_data
        .list
        .iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
        .collect())
}

/// The `lumis` metadata that [`write_exr`] stored in an EXR header (empty if there is none).
pub fn read_exr_metadata(path: &Path) -> Result<Metadata, String> {
    let file = std::fs::File::open(path).map_err(|e| exr_error(path, exr::error::Error::Io(e)))?;
    let meta = exr::meta::MetaData::read_from_buffered(std::io::BufReader::new(file), false)
        .map_err(|e| exr_error(path, e))?;
    let text =
        meta.headers
            .iter()
            .find_map(|h| match h.own_attributes.other.get(&Text::from("lumis")) {
                Some(AttributeValue::Text(text)) => Some(text.to_string()),
                _ => None,
            });
    Ok(text
        .unwrap_or_default()
        .lines()
        .filter_map(|line| line.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect())
}
