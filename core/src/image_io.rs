//! Image output (multi-layer OpenEXR and an sRGB PNG preview) and EXR input.
//!
//! Outputs are written to a temporary file in the target directory and renamed into place,
//! so an interrupted run never leaves a truncated image.
//!
//! Why one file of over 600 lines: EXR output, EXR input and the PNG preview share the atomic
//! writing and the layer layout; with its tests.

use crate::film::Film;
use crate::math::Rgb;
use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image, IntegerBounds, Layer,
    LayerAttributes, LineOrder, ReadChannels, ReadLayers, Text, Vec2, WritableImage,
    read_all_flat_layers_from_file,
};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

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

/// Temporary files being written, so that an exit that skips destructors (a second Ctrl-C)
/// can remove them first ([`exit_removing_temporaries`]). A temporary file is created with
/// this lock held, so that none exists unlisted.
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn temporaries() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    // The list stays valid if a writer panicked while holding it.
    TEMPORARIES
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A new temporary file in `dir`, listed in [`TEMPORARIES`] from its creation on.
fn listed_temporary(dir: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    let mut list = temporaries();
    let tmp = tempfile::Builder::new()
        .prefix(".lumis-")
        .suffix(".tmp")
        .tempfile_in(dir)?;
    list.push(tmp.path().to_path_buf());
    Ok(tmp)
}

fn forget_temporary(path: &Path) {
    temporaries().retain(|p| p != path);
}

/// Removes every temporary output file still being written and exits with `code`, without
/// running destructors. The list stays locked until the exit, so that no other thread creates
/// a temporary file after the removal (one file of several being written, e.g. the PNG after
/// the EXR).
pub fn exit_removing_temporaries(code: i32) -> ! {
    let list = temporaries();
    for path in list.iter() {
        let _ = std::fs::remove_file(path);
    }
    std::process::exit(code)
}

/// The directory an output file goes to.
fn output_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Checks, before a long computation, that `path` can be written: it is not a directory, and
/// its directory exists (or is created) and accepts a new file.
pub fn check_writable(path: &Path) -> Result<(), OutputError> {
    if path.is_dir() {
        return Err(output_error(path, "it is a directory"));
    }
    let dir = output_dir(path);
    std::fs::create_dir_all(dir).map_err(|e| output_error(path, e))?;
    let tmp = listed_temporary(dir).map_err(|e| output_error(path, e))?;
    // Removed before it leaves the list: an exit in between finds it gone, not unlisted.
    let temporary = tmp.path().to_path_buf();
    drop(tmp);
    forget_temporary(&temporary);
    Ok(())
}

/// Writes what a closure writes to a file.
pub type FileWriter<'a> = Box<dyn FnOnce(&mut std::fs::File) -> Result<(), String> + 'a>;

/// Writes several files as one: each into a temporary file beside its target (creating the
/// directory if needed); only when every one is complete are they renamed into place. A failure
/// before the renames leaves every target as it was and no temporary behind (an EXR is never
/// left without its PNG because the PNG's path was a directory).
pub fn write_all_atomically(files: Vec<(&Path, FileWriter<'_>)>) -> Result<(), OutputError> {
    for (path, _) in &files {
        if path.is_dir() {
            return Err(output_error(path, "it is a directory"));
        }
    }
    let mut written = Vec::new();
    for (path, write) in files {
        let dir = output_dir(path);
        std::fs::create_dir_all(dir).map_err(|e| output_error(path, e))?;
        let mut tmp = listed_temporary(dir).map_err(|e| output_error(path, e))?;
        let result = write_temporary(&mut tmp, write).map_err(|e| output_error(path, e));
        if let Err(e) = result {
            let temporary = tmp.path().to_path_buf();
            drop(tmp);
            forget_temporary(&temporary);
            return Err(e);
        }
        written.push((path, tmp));
    }
    for (path, tmp) in written {
        let temporary = tmp.path().to_path_buf();
        let result = tmp.persist(path).map_err(|e| output_error(path, e.error));
        forget_temporary(&temporary);
        result?;
    }
    Ok(())
}

fn write_temporary(tmp: &mut tempfile::NamedTempFile, write: FileWriter<'_>) -> Result<(), String> {
    // The temporary file is private (0600); the output should be as readable as any file.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))
            .map_err(|e| e.to_string())?;
    }
    write(tmp.as_file_mut())?;
    tmp.as_file_mut().flush().map_err(|e| e.to_string())
}

/// Writes through `write` into a temporary file beside `path`, then renames it to `path`
/// (creating the directory if needed).
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::fs::File) -> Result<(), String>,
) -> Result<(), OutputError> {
    write_all_atomically(vec![(path, Box::new(write))])
}

/// Key–value pairs stored in the EXR header as the text attribute `lumis`, one `key=value` a line
/// (the scene, the integrator and its settings).
pub type Metadata = Vec<(String, String)>;

/// Writes colour as channels R, G, B and each AOV as `aov.channel`, in one EXR part whose data
/// window is the rendered window of the full film.
pub fn write_exr(film: &Film, path: &Path, metadata: &Metadata) -> Result<(), OutputError> {
    write_atomically(path, exr_writer(film, metadata))
}

/// What [`write_exr`] writes, for [`write_all_atomically`].
pub fn exr_writer<'a>(film: &'a Film, metadata: &'a Metadata) -> FileWriter<'a> {
    Box::new(move |file| {
        exr_image(film, metadata)
            .write()
            .to_buffered(std::io::BufWriter::new(file))
            .map_err(|e| e.to_string())
    })
}

fn exr_image(film: &Film, metadata: &Metadata) -> Image<Layer<AnyChannels<FlatSamples>>> {
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
    // Blocks are compressed in parallel and written in increasing order: with the crate's
    // default (unspecified order) they are written as they finish, so the chunk table, and the
    // file's bytes, would depend on the threads' timing.
    let encoding = Encoding {
        line_order: LineOrder::Increasing,
        ..Encoding::FAST_LOSSLESS
    };
    let layer = Layer::new(
        size,
        attributes,
        encoding,
        AnyChannels::sort(channels.into()),
    );
    let mut image = Image::from_layer(layer);
    image.attributes.display_window = IntegerBounds::new(
        (0, 0),
        (film.full_width as usize, film.full_height as usize),
    );
    image
}

/// Writes 8-bit RGB pixels (row-major) as a PNG, atomically.
pub fn write_rgb8_png(
    path: &Path,
    width: u32,
    height: u32,
    bytes: Vec<u8>,
) -> Result<(), OutputError> {
    write_atomically(path, move |file: &mut std::fs::File| {
        encode_png(file, width, height, bytes)
    })
}

/// Encodes 8-bit RGB pixels (row-major) as a PNG: adaptive filters and fast compression (a
/// preview is written at every render; its size matters less).
pub fn encode_png(
    file: &mut std::fs::File,
    width: u32,
    height: u32,
    bytes: Vec<u8>,
) -> Result<(), String> {
    if bytes.len() != width as usize * height as usize * 3 {
        return Err(format!(
            "{} bytes for a {width}×{height} RGB image",
            bytes.len()
        ));
    }
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    encoder.set_filter(png::Filter::Adaptive);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(&bytes).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())
}

/// The sRGB transfer function.
pub fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Bins of the linear range [0, 1] for [`srgb_byte`]: in each, the byte steps up at most once,
/// since the curve's steepest part (12.92 × 255 bytes per unit, at 0) is less than a byte per
/// bin.
const SRGB_BINS: usize = 4096;

/// One bin of [`srgb_byte`]'s table: the byte at its lower edge, and the value in it (or above
/// it) where the byte steps up.
#[derive(Clone, Copy)]
struct SrgbBin {
    byte: u8,
    step: f32,
}

/// The 8-bit sRGB value of a linear value, clamped to [0, 1] (NaN is 0):
/// `(linear_to_srgb(v) * 255 + 0.5) as u8`, looked up rather than computed, because one `powf`
/// per channel was the largest part of writing a render's preview after each pass. The value's
/// bin of [0, 1] gives the byte at the bin's lower edge and where in the bin it steps up: one
/// comparison (the table is built from the 255 values where the byte steps up).
pub fn srgb_byte(v: f32) -> u8 {
    static TABLE: OnceLock<Box<[SrgbBin]>> = OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let steps: Vec<f32> = (0..255u8).map(least_with_byte_above).collect();
        let mut byte = 0;
        (0..=SRGB_BINS)
            .map(|bin| {
                let edge = bin as f32 / SRGB_BINS as f32;
                while steps.get(byte).is_some_and(|&step| step <= edge) {
                    byte += 1;
                }
                SrgbBin {
                    byte: byte as u8,
                    step: steps.get(byte).copied().unwrap_or(f32::INFINITY),
                }
            })
            .collect()
    });
    // NaN fails the comparison and is 0; v × SRGB_BINS is exact (a power of two), so the bin's
    // lower edge is at most v; 1 has a bin of its own, the last.
    let v = if v >= 0.0 { v.min(1.0) } else { 0.0 };
    let bin = table[(v * SRGB_BINS as f32) as usize];
    bin.byte + u8::from(v >= bin.step)
}

/// The least value in [0, 1] whose sRGB byte is above `k` (`k` < 255): a bisection over the
/// bits of the non-negative floats, which order as their values do. The bytes rise with the
/// value (the transfer function is increasing), so below it every byte is at most `k`.
fn least_with_byte_above(k: u8) -> f32 {
    let byte = |bits: u32| (linear_to_srgb(f32::from_bits(bits)) * 255.0 + 0.5) as u8;
    // byte(low) <= k < byte(high) throughout.
    let (mut low, mut high) = (0.0f32.to_bits(), 1.0f32.to_bits());
    while high - low > 1 {
        let middle = low + (high - low) / 2;
        if byte(middle) > k {
            high = middle;
        } else {
            low = middle;
        }
    }
    f32::from_bits(high)
}

/// Writes the colour as an 8-bit sRGB PNG, scaled by 2^exposure and clamped.
pub fn write_png(film: &Film, path: &Path, exposure: f32) -> Result<(), OutputError> {
    write_atomically(path, png_writer(film, exposure))
}

/// What [`write_png`] writes, for [`write_all_atomically`].
pub fn png_writer(film: &Film, exposure: f32) -> FileWriter<'_> {
    Box::new(move |file| {
        let (w, h) = (film.window.width, film.window.height);
        let scale = exposure.exp2();
        let mut bytes = vec![0; film.color.len() * 3];
        for (pixel, color) in bytes.chunks_exact_mut(3).zip(&film.color) {
            pixel.copy_from_slice(&display_bytes(*color, scale));
        }
        encode_png(file, w, h, bytes)
    })
}

/// A linear colour's 8-bit sRGB bytes in the preview PNG, scaled by `scale` (2^exposure) and
/// clamped; a non-finite channel is black.
#[inline]
pub fn display_bytes(color: Rgb, scale: f32) -> [u8; 3] {
    let byte = |v: f32| srgb_byte(if v.is_finite() { v * scale } else { 0.0 });
    [byte(color.x), byte(color.y), byte(color.z)]
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
    write_atomically(path, aov_png_writer(film, aov))
}

/// What [`write_aov_png`] writes, for [`write_all_atomically`].
pub fn aov_png_writer(film: &Film, aov: usize) -> FileWriter<'_> {
    Box::new(move |file| {
        let (w, h) = (film.window.width, film.window.height);
        let channels: Vec<Vec<f32>> = (0..3).map(|c| film.aov_channel(aov, c).collect()).collect();
        let bytes: Vec<u8> = (0..(w as usize * h as usize))
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
        encode_png(file, w, h, bytes)
    })
}

/// An RGB image read from an EXR file, in row order.
#[derive(Clone, Debug)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<Rgb>,
}

/// Reads the first RGB(A) layer of an EXR radiance map; the error names the path and the
/// reason. Values above [`MAX_EMISSION`](crate::limits::MAX_EMISSION) are refused (negative
/// and non-finite values are left to the caller, which reads them as no light).
pub fn read_exr_rgb(path: &Path) -> Result<RgbImage, String> {
    let bytes = std::fs::read(path).map_err(|e| exr_error(path, exr::error::Error::Io(e)))?;
    let image = decode_exr_rgb(&bytes).map_err(|e| match e {
        DecodeError::Exr(e) => exr_error(path, e),
        DecodeError::Unusable(why) => format!("`{}` cannot be used: {why}", path.display()),
    })?;
    let max = crate::limits::MAX_EMISSION;
    if let Some((i, c)) = image.pixels.iter().enumerate().find_map(|(i, p)| {
        p.to_array()
            .into_iter()
            .find(|&c| c.is_finite() && c > max)
            .map(|c| (i, c))
    }) {
        return Err(format!(
            "`{}`: pixel ({}, {}) holds {}, above the largest radiance lumis accepts, {}",
            path.display(),
            i % image.width.max(1),
            i / image.width.max(1),
            crate::limits::fmt_f32(c),
            crate::limits::fmt_f32(max)
        ));
    }
    Ok(image)
}

/// Why EXR data gave no RGB image.
#[derive(Debug)]
pub enum DecodeError {
    /// Not a valid EXR (the decoder's reason).
    Exr(exr::error::Error),
    /// A valid EXR lumis cannot use: no R, G and B channels, or more pixels than it reads.
    Unusable(String),
}

impl From<exr::error::Error> for DecodeError {
    fn from(e: exr::error::Error) -> Self {
        DecodeError::Exr(e)
    }
}

/// The largest image (in pixels) an EXR may declare: 2²⁷, a 16384 × 8192 environment map. The
/// header's size is checked before any pixel memory is allocated (a corrupt header asked for
/// terabytes; found by fuzzing).
pub const MAX_EXR_PIXELS: usize = 1 << 27;

/// Decodes the first RGB(A) layer of EXR data held in memory; never panics on bad data.
pub fn decode_exr_rgb(bytes: &[u8]) -> Result<RgbImage, DecodeError> {
    let mut headers_read = std::io::Cursor::new(bytes);
    let meta = exr::meta::MetaData::read_from_buffered(&mut headers_read, false)?;
    let has_rgb = |h: &exr::meta::header::Header| {
        ["R", "G", "B"].iter().all(|name| {
            h.channels
                .list
                .iter()
                .any(|c| c.name.eq_case_insensitive(name))
        })
    };
    if !meta.headers.iter().any(has_rgb) {
        let found: Vec<String> = meta
            .headers
            .iter()
            .flat_map(|h| h.channels.list.iter().map(|c| c.name.to_string()))
            .collect();
        return Err(DecodeError::Unusable(format!(
            "an RGB image needs channels R, G and B; this one has {}",
            if found.is_empty() {
                "none".to_string()
            } else {
                found.join(", ")
            }
        )));
    }
    for header in &meta.headers {
        let size = header.layer_size;
        if size
            .width()
            .checked_mul(size.height())
            .is_none_or(|area| area > MAX_EXR_PIXELS)
        {
            return Err(DecodeError::Unusable(format!(
                "{}x{} pixels is more than lumis reads ({MAX_EXR_PIXELS})",
                size.width(),
                size.height()
            )));
        }
    }
    // The header reader has consumed exactly the headers (the last byte it peeks at is their
    // terminator), so the offset tables start here.
    check_chunks_fit(bytes, &meta, headers_read.position())?;
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |resolution, _| RgbImage {
                width: resolution.width(),
                height: resolution.height(),
                // Allocated zeroed, not written: the pages are touched only as pixels are
                // decoded. `vec![Rgb::ZERO; n]` wrote them all at once, 400 MB for a 457-byte
                // corpus file declaring 33 554 435 pixels whose data then proved corrupt.
                pixels: bytemuck::zeroed_vec(resolution.area()),
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

/// Checks that every chunk of a flat part lies inside `bytes` with the byte count it declares,
/// the offset tables starting at `tables_start`. The decoder sizes a chunk's buffer from its
/// declared count, up to the largest block the header allows, and zeroes it before reading: a
/// 584-byte file of the fuzz corpus declared a 3 GB chunk and made it fill 3 GB of memory, in
/// 9 s. The layout is the OpenEXR file layout's: a part number in multi-part files, the scan
/// line's y or the tile's four coordinates, then the data's byte count. Deep parts are not read
/// (no RGB layer is taken from them), so only their offset tables are passed over.
fn check_chunks_fit(
    bytes: &[u8],
    meta: &exr::meta::MetaData,
    tables_start: u64,
) -> Result<(), DecodeError> {
    let invalid = |why: String| DecodeError::Exr(exr::error::Error::Invalid(why.into()));
    let end = bytes.len() as u64;
    let read_le = |at: u64, width: u64| -> Option<u64> {
        let start = usize::try_from(at).ok()?;
        let field = bytes.get(start..start.checked_add(width as usize)?)?;
        Some(field.iter().rev().fold(0, |v, &b| v << 8 | u64::from(b)))
    };
    let part_number = if meta.requirements.has_multiple_layers {
        4
    } else {
        0
    };
    let mut table = tables_start;
    for (part, header) in meta.headers.iter().enumerate() {
        let coordinates = match header.blocks {
            exr::meta::BlockDescription::ScanLines => 4,
            exr::meta::BlockDescription::Tiles(_) => 16,
        };
        let count_at = part_number + coordinates;
        for chunk in 0..header.chunk_count {
            let offset = read_le(table, 8).ok_or_else(|| {
                invalid(format!(
                    "the offset table of part {part} runs past the end of the data ({end} bytes)"
                ))
            })?;
            table += 8;
            if header.deep {
                continue;
            }
            // The count is a signed 32-bit integer, read here as unsigned: a negative one does not
            // fit either.
            let chunk_end = read_le(offset.saturating_add(count_at), 4)
                .map(|count| offset + count_at + 4 + count);
            if chunk_end.is_none_or(|chunk_end| chunk_end > end) {
                return Err(invalid(format!(
                    "chunk {chunk} of part {part}, at byte {offset}, declares more bytes than \
                     the data holds ({end} bytes)"
                )));
            }
        }
    }
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;
    use exr::prelude::{Blocks, Compression, ImageAttributes, SpecificChannels};

    /// A 37 × 21 RGB pattern (x, y, ½) encoded in memory with `blocks` and `compression`, as
    /// one part or as two.
    fn encoded(blocks: Blocks, compression: Compression, two_parts: bool) -> Vec<u8> {
        let size = Vec2(37, 21);
        let encoding = Encoding {
            compression,
            blocks,
            line_order: LineOrder::Increasing,
        };
        let layer = |name: &str| {
            Layer::new(
                size,
                LayerAttributes::named(name),
                encoding,
                SpecificChannels::rgb(|p: Vec2<usize>| (p.x() as f32, p.y() as f32, 0.5_f32)),
            )
        };
        let image = Image::empty(ImageAttributes::new(IntegerBounds::from_dimensions(size)))
            .with_layer(layer("first"));
        let mut bytes = std::io::Cursor::new(Vec::new());
        if two_parts {
            let image = image.with_layer(layer("second"));
            image.write().to_buffered(&mut bytes).unwrap();
        } else {
            image.write().to_buffered(&mut bytes).unwrap();
        }
        bytes.into_inner()
    }

    /// The looked-up sRGB byte is the computed one: at every value near a step (four floats
    /// either side), at 2^20 values spread over the floats of [0, 1], and out of range.
    #[test]
    fn srgb_bytes_are_looked_up_as_computed() {
        // The table's premise: the byte steps up at most once per bin.
        let steps: Vec<f32> = (0..255u8).map(least_with_byte_above).collect();
        for pair in steps.windows(2) {
            assert!(pair[1] - pair[0] > 1.0 / SRGB_BINS as f32, "{pair:?}");
        }
        let computed = |v: f32| (linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0 + 0.5) as u8;
        let one = 1.0f32.to_bits();
        let near_steps = (0..255u8).flat_map(|k| {
            let step = least_with_byte_above(k).to_bits();
            (step.saturating_sub(4)..=(step + 4).min(one)).map(f32::from_bits)
        });
        let spread = (0..=one).step_by((one >> 20) as usize).map(f32::from_bits);
        for v in near_steps
            .chain(spread)
            .chain([0.0, -0.0, 1.0, -1.0, 2.0, f32::MAX])
        {
            assert_eq!(srgb_byte(v), computed(v), "at {v:e}");
        }
        assert_eq!(srgb_byte(f32::NAN), 0);
    }

    /// A PNG decodes to the bytes it was given; a buffer of the wrong size is refused.
    #[test]
    fn png_round_trips_and_refuses_a_wrong_size() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        let (w, h) = (13u32, 7u32);
        let bytes: Vec<u8> = (0..w * h * 3).map(|i| (i * 37 % 251) as u8).collect();
        write_rgb8_png(&path, w, h, bytes.clone()).unwrap();
        let file = std::fs::File::open(&path).unwrap();
        let mut reader = png::Decoder::new(std::io::BufReader::new(file))
            .read_info()
            .unwrap();
        let mut decoded = vec![0; reader.output_buffer_size().unwrap()];
        let frame = reader.next_frame(&mut decoded).unwrap();
        assert_eq!((frame.width, frame.height), (w, h));
        assert_eq!(frame.color_type, png::ColorType::Rgb);
        assert_eq!(decoded, bytes);
        let e = write_rgb8_png(&path, w + 1, h, bytes).unwrap_err();
        assert!(e.reason.contains("bytes for a 14×7 RGB image"), "{e}");
    }

    /// Scan lines and tiles, one part and two, each compressed or not.
    fn every_layout() -> Vec<(String, Vec<u8>)> {
        let mut files = Vec::new();
        for (name, blocks) in [
            ("scan lines", Blocks::ScanLines),
            ("tiles", Blocks::Tiles(Vec2(8, 8))),
        ] {
            for compression in [Compression::Uncompressed, Compression::ZIP16] {
                for two_parts in [false, true] {
                    let label = format!("{name}, {compression:?}, two parts: {two_parts}");
                    files.push((label, encoded(blocks, compression, two_parts)));
                }
            }
        }
        files
    }

    #[test]
    fn chunks_of_every_layout_are_read() {
        for (label, bytes) in every_layout() {
            let image = decode_exr_rgb(&bytes).unwrap_or_else(|e| panic!("{label}: {e:?}"));
            assert_eq!((image.width, image.height), (37, 21), "{label}");
            assert_eq!(image.pixels[3 * 37 + 5], Rgb::new(5.0, 3.0, 0.5), "{label}");
        }
    }

    /// One byte short, the last chunk no longer holds the bytes it declares. The check must say
    /// so itself, before the decoder reads: it fails for a layout whose count it looks for in
    /// the wrong place (a coordinate or a part number read as the count fits).
    #[test]
    fn a_chunk_past_the_end_is_refused_before_decoding() {
        for (label, bytes) in every_layout() {
            let short = &bytes[..bytes.len() - 1];
            let e = match decode_exr_rgb(short) {
                Err(DecodeError::Exr(e)) => e.to_string(),
                other => panic!("{label}: {other:?}"),
            };
            assert!(
                e.contains("declares more bytes than the data holds"),
                "{label}: {e}"
            );
        }
    }

    #[test]
    fn an_offset_table_past_the_end_is_refused() {
        let bytes = encoded(Blocks::Tiles(Vec2(8, 8)), Compression::Uncompressed, false);
        let mut headers_read = std::io::Cursor::new(bytes.as_slice());
        let meta = exr::meta::MetaData::read_from_buffered(&mut headers_read, false).unwrap();
        let tables_start = headers_read.position();
        // The data ends inside the first offset.
        let short = &bytes[..tables_start as usize + 5];
        let e = check_chunks_fit(short, &meta, tables_start).unwrap_err();
        assert!(
            matches!(&e, DecodeError::Exr(e) if e.to_string().contains("offset table of part 0 runs past")),
            "{e:?}"
        );
    }
}
