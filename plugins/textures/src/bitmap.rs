//! `bitmap`: an image looked up at the shading point's texture coordinates, as Mitsuba 3's
//! `bitmap` texture (without MIP-mapping: no filtering over the pixel's footprint).
//!
//! Parameters:
//! - `filename` (path, required): a PNG (8 or 16 bits per channel, grey or colour, with or
//!   without alpha, palettes expanded), JPEG or OpenEXR (its first RGB layer) image, relative to
//!   the scene file.
//! - `filter_type` (choice, default `bilinear`, or `nearest`): bilinear interpolation between
//!   the four nearest pixel centres, or the pixel the point falls in.
//! - `wrap_mode` (choice, default `repeat`, or `mirror`, `clamp`): how coordinates outside
//!   [0, 1] are brought back: the image tiled, tiled with every other copy mirrored, or its
//!   edge pixels extended.
//! - `raw` (bool, default false): read 8- and 16-bit values as they are, without sRGB decoding
//!   (for data that is not a colour).
//! - `to_uv` (uv transform, default identity): a map applied to the texture coordinates first
//!   (Mitsuba's `to_uv`): `(scale: (2, 2), rotate: 30, translate: (0.5, 0))` or
//!   `(matrix: (a, b, c, d, e, f))`.
//!
//! As Mitsuba's RGB variants read them: PNG and JPEG values are sRGB-encoded and decoded to
//! linear RGB (unless `raw`), 8-bit ones per pixel before interpolation (a table of the 256
//! values), 16-bit ones when the image is read; EXR values are linear. The alpha channel is
//! dropped (Mitsuba keeps the colour as stored, not multiplied by alpha). Pixel (0, 0) is the
//! image's top-left; the point (u, v) falls in pixel (⌊u w⌋, ⌊v h⌋). A one-channel (grey)
//! image gives its value in all three channels. `eval_1`, a number parameter's value (a
//! roughness), is the grey value, or the luminance of a colour, as Mitsuba's.
//!
//! Bad input: a file that is missing, not an image of these formats, truncated or corrupt is an
//! error naming it; so is an image of more than 2²⁷ pixels, refused with the bytes it would
//! take before any pixel memory is allocated. Texture coordinates that are not finite are read
//! as (0, 0).

use glam::Vec2;
use lumis_core::image_io::{DecodeError, MAX_EXR_PIXELS, decode_exr_rgb};
use lumis_core::math::lanes::V2;
use lumis_core::math::{Rgb, luminance};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::TexturePlugin;
use lumis_core::texture::{Texture, UvTransform};
use std::path::Path;
use std::sync::Arc;

/// The most pixels a texture may have: 2²⁷ (a 16384 × 8192 image), as an environment map.
pub const MAX_PIXELS: usize = MAX_EXR_PIXELS;

/// How a lookup between pixel centres is answered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    Bilinear,
    Nearest,
}

/// How coordinates outside [0, 1] are brought back into the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    Mirror,
    Clamp,
}

/// The pixels as stored: 8-bit values decoded through a table of 256 (as Mitsuba keeps 8-bit
/// images), or linear floats; one channel (grey) or three, row by row from the top.
#[derive(Clone, Debug)]
enum Pixels {
    Bytes {
        values: Vec<u8>,
        decode: Box<[f32; 256]>,
    },
    Floats(Vec<f32>),
}

/// A decoded image.
#[derive(Clone, Debug)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    /// 1 (grey) or 3 (RGB).
    pub channels: usize,
    pixels: Pixels,
}

/// The sRGB transfer function's inverse, IEC 61966-2-1.
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The table of 256 values of an 8-bit channel: sRGB-decoded, or the value / 255 when raw.
fn byte_table(srgb: bool) -> Box<[f32; 256]> {
    Box::new(std::array::from_fn(|i| {
        let c = i as f64 / 255.0;
        (if srgb { srgb_to_linear(c) } else { c }) as f32
    }))
}

/// The refusal of an image of `width` × `height` pixels, or `None` if it is small enough.
fn too_large(
    width: usize,
    height: usize,
    channels: usize,
    bytes_per_channel: usize,
) -> Option<String> {
    let pixels = width as u128 * height as u128;
    if pixels <= MAX_PIXELS as u128 {
        return None;
    }
    let bytes = pixels * channels as u128 * bytes_per_channel as u128;
    Some(format!(
        "{width} × {height} pixels would take {bytes} bytes; lumis reads textures of at most \
         {MAX_PIXELS} pixels"
    ))
}

impl Image {
    /// The value of channel `c` of pixel (x, y).
    #[inline(always)]
    fn value(&self, x: usize, y: usize, c: usize) -> f32 {
        let i = (y * self.width + x) * self.channels + c;
        match &self.pixels {
            Pixels::Bytes { values, decode } => decode[values[i] as usize],
            Pixels::Floats(values) => values[i],
        }
    }

    /// Pixel (x, y) as a colour (grey in all three channels).
    #[inline(always)]
    fn rgb(&self, x: usize, y: usize) -> Rgb {
        if self.channels == 1 {
            Rgb::splat(self.value(x, y, 0))
        } else {
            Rgb::new(
                self.value(x, y, 0),
                self.value(x, y, 1),
                self.value(x, y, 2),
            )
        }
    }

    /// The least and greatest value of any channel.
    fn range(&self) -> [f32; 2] {
        let mut range = [f32::INFINITY, f32::NEG_INFINITY];
        let mut see = |v: f32| {
            range[0] = range[0].min(v);
            range[1] = range[1].max(v);
        };
        match &self.pixels {
            Pixels::Bytes { values, decode } => {
                let mut seen = [false; 256];
                for &b in values {
                    seen[b as usize] = true;
                }
                (0..256).filter(|&b| seen[b]).for_each(|b| see(decode[b]));
            }
            Pixels::Floats(values) => values.iter().for_each(|&v| see(v)),
        }
        range
    }

    /// Decodes PNG data (sRGB unless `raw`).
    pub fn decode_png(bytes: &[u8], raw: bool) -> Result<Image, String> {
        // The size from the header (IHDR, the first chunk, at a fixed place), before the
        // decoder reads on to the pixel data.
        if let Some(header) = bytes.get(12..26)
            && header.starts_with(b"IHDR")
        {
            let size = |i: usize| {
                u32::from_be_bytes([header[i], header[i + 1], header[i + 2], header[i + 3]])
            };
            let (width, height) = (size(4) as usize, size(8) as usize);
            let channels = match header[13] {
                0 => 1,
                4 => 2,
                6 => 4,
                _ => 3,
            };
            let bytes_per_channel = if header[12] == 16 { 2 } else { 1 };
            if let Some(refusal) = too_large(width, height, channels, bytes_per_channel) {
                return Err(refusal);
            }
        }
        let mut decoder = png::Decoder::new_with_limits(
            std::io::Cursor::new(bytes),
            png::Limits {
                bytes: MAX_PIXELS * 8,
            },
        );
        decoder.set_transformations(png::Transformations::EXPAND);
        let mut reader = decoder
            .read_info()
            .map_err(|e| format!("not a valid PNG: {e}"))?;
        let (width, height) = (reader.info().width as usize, reader.info().height as usize);
        let (color, depth) = reader.output_color_type();
        let stored = color.samples();
        if let Some(refusal) = too_large(width, height, stored, depth as usize / 8) {
            return Err(refusal);
        }
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| "the PNG's size does not fit in memory".to_string())?;
        let mut buffer = vec![0u8; size];
        let frame = reader
            .next_frame(&mut buffer)
            .map_err(|e| format!("not a valid PNG: {e}"))?;
        buffer.truncate(frame.buffer_size());
        // Grey stays grey; the alpha channel is dropped.
        let channels = if stored <= 2 { 1 } else { 3 };
        let pixels = match depth {
            png::BitDepth::Eight => Pixels::Bytes {
                values: buffer
                    .chunks_exact(stored)
                    .flat_map(|pixel| pixel[..channels].iter().copied())
                    .collect(),
                decode: byte_table(!raw),
            },
            png::BitDepth::Sixteen => {
                let values: Vec<u16> = buffer
                    .chunks_exact(2)
                    .map(|b| u16::from_be_bytes([b[0], b[1]]))
                    .collect();
                Pixels::Floats(
                    values
                        .chunks_exact(stored)
                        .flat_map(|pixel| pixel.iter().take(channels))
                        .map(|&v| {
                            let c = v as f64 / 65535.0;
                            (if raw { c } else { srgb_to_linear(c) }) as f32
                        })
                        .collect(),
                )
            }
            other => return Err(format!("{other:?} bits per channel is not read")),
        };
        Ok(Image {
            width,
            height,
            channels,
            pixels,
        })
    }

    /// Decodes JPEG data (sRGB unless `raw`).
    pub fn decode_jpeg(bytes: &[u8], raw: bool) -> Result<Image, String> {
        use zune_jpeg::zune_core::bytestream::ZCursor;
        use zune_jpeg::zune_core::colorspace::ColorSpace;
        use zune_jpeg::zune_core::options::DecoderOptions;
        let options = DecoderOptions::default()
            .jpeg_set_out_colorspace(ColorSpace::RGB)
            // A truncated or corrupt stream is an error, not an image padded with grey.
            .set_strict_mode(true)
            .set_max_width(usize::MAX)
            .set_max_height(usize::MAX);
        let mut decoder = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), options);
        decoder
            .decode_headers()
            .map_err(|e| format!("not a valid JPEG: {e:?}"))?;
        let (width, height) = decoder
            .dimensions()
            .ok_or_else(|| "not a valid JPEG: no dimensions".to_string())?;
        if let Some(refusal) = too_large(width, height, 3, 1) {
            return Err(refusal);
        }
        let values = decoder
            .decode()
            .map_err(|e| format!("not a valid JPEG: {e:?}"))?;
        if values.len() != width * height * 3 {
            return Err(format!(
                "not a valid JPEG: {} values for {width} × {height} pixels",
                values.len()
            ));
        }
        Ok(Image {
            width,
            height,
            channels: 3,
            pixels: Pixels::Bytes {
                values,
                decode: byte_table(!raw),
            },
        })
    }

    /// Decodes OpenEXR data: the first RGB layer, linear.
    pub fn decode_exr(bytes: &[u8]) -> Result<Image, String> {
        if let Ok(meta) =
            exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        {
            for header in &meta.headers {
                let size = header.layer_size;
                if let Some(refusal) = too_large(size.width(), size.height(), 3, 4) {
                    return Err(refusal);
                }
            }
        }
        let image = decode_exr_rgb(bytes).map_err(|e| match e {
            DecodeError::Exr(e) => format!("not a valid OpenEXR image: {e}"),
            DecodeError::Unusable(why) => why,
        })?;
        Ok(Image {
            width: image.width,
            height: image.height,
            channels: 3,
            pixels: Pixels::Floats(image.pixels.iter().flat_map(|p| p.to_array()).collect()),
        })
    }

    /// Decodes an image of the format its first bytes show (PNG, JPEG, EXR).
    pub fn decode(bytes: &[u8], raw: bool) -> Result<Image, String> {
        let image = if bytes.starts_with(b"\x89PNG") {
            Self::decode_png(bytes, raw)?
        } else if bytes.starts_with(&[0xff, 0xd8]) {
            Self::decode_jpeg(bytes, raw)?
        } else if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
            Self::decode_exr(bytes)?
        } else {
            return Err("not a PNG, JPEG or OpenEXR image".into());
        };
        if image.width == 0 || image.height == 0 {
            return Err("the image has no pixels".into());
        }
        Ok(image)
    }

    /// Reads and decodes the image file at `path`; errors name the path.
    pub fn read(path: &Path, raw: bool) -> Result<Image, String> {
        let bytes = std::fs::read(path)
            .map_err(|e| format!("cannot read texture `{}`: {e}", path.display()))?;
        Self::decode(&bytes, raw).map_err(|e| format!("texture `{}`: {e}", path.display()))
    }
}

/// The `bitmap` texture.
pub struct Bitmap {
    image: Image,
    filter: Filter,
    wrap: Wrap,
    to_uv: UvTransform,
    range: [f32; 2],
}

/// Integer pixel coordinate `i` brought into [0, n) by `wrap` (as Dr.Jit's textures do).
#[inline(always)]
fn wrap(i: i64, n: usize, mode: Wrap) -> usize {
    let n = n as i64;
    (match mode {
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Mirror => {
            let f = i.rem_euclid(2 * n);
            if f >= n { 2 * n - 1 - f } else { f }
        }
    }) as usize
}

impl Bitmap {
    pub fn new(image: Image, filter: Filter, wrap: Wrap, to_uv: UvTransform) -> Self {
        let range = image.range();
        Bitmap {
            image,
            filter,
            wrap,
            to_uv,
            range,
        }
    }

    /// The colour at texture coordinates `uv` (before `to_uv`).
    pub fn lookup(&self, uv: Vec2) -> Rgb {
        let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
        let p = self.to_uv.apply::<f32>(V2::splat(uv)).lane(0);
        let p = if p.is_finite() { p } else { Vec2::ZERO };
        let (w, h) = (self.image.width, self.image.height);
        let image = &self.image;
        match self.filter {
            Filter::Nearest => {
                let x = wrap((p.x * w as f32).floor() as i64, w, self.wrap);
                let y = wrap((p.y * h as f32).floor() as i64, h, self.wrap);
                image.rgb(x, y)
            }
            Filter::Bilinear => {
                let (fx, fy) = (p.x * w as f32 - 0.5, p.y * h as f32 - 0.5);
                let (ix, iy) = (fx.floor(), fy.floor());
                let (wx, wy) = (fx - ix, fy - iy);
                let (ix, iy) = (ix as i64, iy as i64);
                let (x0, x1) = (
                    wrap(ix, w, self.wrap),
                    wrap(ix.saturating_add(1), w, self.wrap),
                );
                let (y0, y1) = (
                    wrap(iy, h, self.wrap),
                    wrap(iy.saturating_add(1), h, self.wrap),
                );
                let top = image.rgb(x0, y0) * (1.0 - wx) + image.rgb(x1, y0) * wx;
                let bottom = image.rgb(x0, y1) * (1.0 - wx) + image.rgb(x1, y1) * wx;
                top * (1.0 - wy) + bottom * wy
            }
        }
    }
}

impl Texture for Bitmap {
    fn eval(&self, uv: Vec2) -> Rgb {
        self.lookup(uv)
    }

    fn eval_1(&self, uv: Vec2) -> f32 {
        let c = self.lookup(uv);
        if self.image.channels == 1 {
            c.x
        } else {
            luminance(c)
        }
    }

    fn range(&self) -> [f32; 2] {
        self.range
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "bitmap";
pub const FILENAME: &str = "filename";
pub const FILTER_TYPE: &str = "filter_type";
pub const WRAP_MODE: &str = "wrap_mode";
pub const RAW: &str = "raw";
pub const TO_UV: &str = "to_uv";
/// Values of its choices.
pub const BILINEAR: &str = "bilinear";
pub const NEAREST: &str = "nearest";
pub const REPEAT: &str = "repeat";
pub const MIRROR: &str = "mirror";
pub const CLAMP: &str = "clamp";

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: FILENAME,
        kind: ParamKind::Path,
        unit: "",
        description: "PNG, JPEG or OpenEXR image, relative to the scene file",
    },
    ParamSpec {
        name: FILTER_TYPE,
        kind: ParamKind::Choice {
            options: &[BILINEAR, NEAREST],
            default: BILINEAR,
        },
        unit: "",
        description: "interpolation between pixel centres, or the nearest pixel",
    },
    ParamSpec {
        name: WRAP_MODE,
        kind: ParamKind::Choice {
            options: &[REPEAT, MIRROR, CLAMP],
            default: REPEAT,
        },
        unit: "",
        description: "coordinates outside [0, 1]: tiled, tiled mirrored, or clamped to the edge",
    },
    ParamSpec {
        name: RAW,
        kind: ParamKind::Bool {
            default: Some(false),
        },
        unit: "",
        description: "read 8- and 16-bit values without sRGB decoding",
    },
    ParamSpec {
        name: TO_UV,
        kind: ParamKind::UvTransform,
        unit: "",
        description: "map applied to the texture coordinates first",
    },
];

fn create(params: &mut Params) -> Result<Arc<dyn Texture>, PluginError> {
    let path = params.path(FILENAME)?;
    let filter = match params.choice(FILTER_TYPE)? {
        NEAREST => Filter::Nearest,
        _ => Filter::Bilinear,
    };
    let wrap = match params.choice(WRAP_MODE)? {
        MIRROR => Wrap::Mirror,
        CLAMP => Wrap::Clamp,
        _ => Wrap::Repeat,
    };
    let raw = params.bool(RAW)?;
    let to_uv = params.uv_transform(TO_UV)?;
    let image = Image::read(&path, raw)
        .map_err(|e| PluginError::Invalid(format!("{}: {e}", params.plugin())))?;
    if let Some(bad) = match &image.pixels {
        Pixels::Floats(values) => values.iter().find(|v| !v.is_finite()),
        Pixels::Bytes { .. } => None,
    } {
        return Err(PluginError::Invalid(format!(
            "{}: texture `{}` holds the value {bad}; textures must be finite",
            params.plugin(),
            path.display()
        )));
    }
    Ok(Arc::new(Bitmap::new(image, filter, wrap, to_uv)))
}

inventory::submit! {
    TexturePlugin {
        name: NAME,
        description: "an image (PNG, JPEG, OpenEXR), bilinear or nearest, as Mitsuba's bitmap",
        params: PARAMS,
        create,
    }
}
