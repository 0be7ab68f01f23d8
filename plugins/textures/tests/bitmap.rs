//! The `bitmap` texture: decoding (PNG of 8 and 16 bits, grey and alpha; JPEG; EXR), sRGB
//! decoding, bilinear filtering, wrap modes, `to_uv`, and the refusals of bad images.

use glam::Vec2;
use lumis_core::math::Rgb;
use lumis_core::texture::{Texture, UvTransform};
use lumis_textures::bitmap::{Bitmap, Filter, Image, Wrap, srgb_to_linear};
use std::path::Path;

/// A PNG of `width` × `height` pixels of `color` type and `depth`, holding `data`.
fn png(
    width: u32,
    height: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(color);
    encoder.set_depth(depth);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(data).unwrap();
    writer.finish().unwrap();
    bytes
}

fn bitmap(image: Image, filter: Filter, wrap: Wrap) -> Bitmap {
    Bitmap::new(image, filter, wrap, UvTransform::IDENTITY)
}

fn close(a: Rgb, b: Rgb, tolerance: f32) -> bool {
    (a - b).abs().max_element() <= tolerance
}

/// 8-bit sRGB values, decoded as Mitsuba decodes them, at the pixels' centres; raw as v / 255.
#[test]
fn eight_bit_png_is_srgb_decoded() {
    let data = [0u8, 128, 255, 10, 20, 30];
    let bytes = png(2, 1, png::ColorType::Rgb, png::BitDepth::Eight, &data);
    let decoded = bitmap(
        Image::decode(&bytes, false).unwrap(),
        Filter::Nearest,
        Wrap::Repeat,
    );
    let expected = |v: u8| srgb_to_linear(v as f64 / 255.0) as f32;
    let left = decoded.eval(Vec2::new(0.25, 0.5));
    assert!(
        close(
            left,
            Rgb::new(expected(0), expected(128), expected(255)),
            1e-7
        ),
        "{left}"
    );
    assert!(
        (expected(128) - 0.215_860_5).abs() < 1e-6,
        "sRGB 128 is 0.2158605 linear"
    );
    let raw = bitmap(
        Image::decode(&bytes, true).unwrap(),
        Filter::Nearest,
        Wrap::Repeat,
    );
    let right = raw.eval(Vec2::new(0.75, 0.5));
    assert!(
        close(right, Rgb::new(10.0, 20.0, 30.0) / 255.0, 1e-7),
        "{right}"
    );
}

/// A 16-bit RGBA PNG: the alpha channel dropped, the 16-bit values decoded; grey with alpha
/// gives its grey in all three channels.
#[test]
fn sixteen_bit_and_alpha_channels() {
    let pixel: [u16; 4] = [65535, 32768, 0, 1000];
    let data: Vec<u8> = pixel.iter().flat_map(|v| v.to_be_bytes()).collect();
    let bytes = png(1, 1, png::ColorType::Rgba, png::BitDepth::Sixteen, &data);
    let texture = bitmap(
        Image::decode(&bytes, false).unwrap(),
        Filter::Bilinear,
        Wrap::Repeat,
    );
    let value = texture.eval(Vec2::new(0.5, 0.5));
    let expected = Rgb::new(1.0, srgb_to_linear(32768.0 / 65535.0) as f32, 0.0);
    assert!(close(value, expected, 1e-6), "{value}");

    let bytes = png(
        1,
        1,
        png::ColorType::GrayscaleAlpha,
        png::BitDepth::Eight,
        &[255, 0],
    );
    let grey = bitmap(
        Image::decode(&bytes, false).unwrap(),
        Filter::Bilinear,
        Wrap::Repeat,
    );
    assert_eq!(grey.eval(Vec2::new(0.3, 0.9)), Rgb::ONE);
    assert_eq!(grey.eval_1(Vec2::new(0.3, 0.9)), 1.0);
}

/// A 2 × 1 image of black and white (raw): bilinear halfway between the centres is ½, a
/// quarter of the way ¼; outside [0, 1] by each wrap mode.
#[test]
fn bilinear_filtering_and_wrap_modes() {
    let bytes = png(
        2,
        1,
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        &[0, 255],
    );
    let image = Image::decode(&bytes, true).unwrap();
    let at = |wrap, u: f32| {
        bitmap(image.clone(), Filter::Bilinear, wrap)
            .eval(Vec2::new(u, 0.5))
            .x
    };
    // Pixel centres at u = ¼ and ¾.
    assert_eq!(at(Wrap::Clamp, 0.25), 0.0);
    assert_eq!(at(Wrap::Clamp, 0.75), 1.0);
    assert!((at(Wrap::Clamp, 0.5) - 0.5).abs() < 1e-6);
    assert!((at(Wrap::Clamp, 0.375) - 0.25).abs() < 1e-6);
    // Repeat: u = 0 lies between the last pixel (white) and the first (black).
    assert!((at(Wrap::Repeat, 0.0) - 0.5).abs() < 1e-6);
    assert!((at(Wrap::Repeat, 1.375) - 0.25).abs() < 1e-6);
    // Clamp: the edge pixel beyond the image.
    assert_eq!(at(Wrap::Clamp, 0.0), 0.0);
    assert_eq!(at(Wrap::Clamp, 7.0), 1.0);
    // Mirror: [1, 2] is [0, 1] reversed.
    assert!((at(Wrap::Mirror, 1.625) - 0.25).abs() < 1e-6);
    assert_eq!(at(Wrap::Mirror, 1.25), 1.0);
    assert_eq!(at(Wrap::Mirror, -0.25), 0.0);
    // Nearest: the pixel the point falls in.
    let nearest = bitmap(image.clone(), Filter::Nearest, Wrap::Repeat);
    assert_eq!(nearest.eval(Vec2::new(0.49, 0.5)).x, 0.0);
    assert_eq!(nearest.eval(Vec2::new(0.51, 0.5)).x, 1.0);
    // Coordinates that are not finite give a finite value.
    for uv in [Vec2::NAN, Vec2::new(f32::INFINITY, 0.5), Vec2::splat(1e30)] {
        assert!(
            bitmap(image.clone(), Filter::Bilinear, Wrap::Mirror)
                .eval(uv)
                .is_finite()
        );
    }
}

/// `to_uv` scales and offsets the coordinates before the lookup.
#[test]
fn to_uv_scale_and_offset() {
    let bytes = png(
        2,
        1,
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        &[0, 255],
    );
    let image = Image::decode(&bytes, true).unwrap();
    // u' = 2u + 0.5: u = 0.125 maps to 0.75 (white), u = 0.375 to 1.25 ≡ 0.25 (black).
    let to_uv = UvTransform {
        rows: [[2.0, 0.0, 0.5], [0.0, 1.0, 0.0]],
    };
    let texture = Bitmap::new(image, Filter::Bilinear, Wrap::Repeat, to_uv);
    assert_eq!(texture.eval(Vec2::new(0.125, 0.5)).x, 1.0);
    assert_eq!(texture.eval(Vec2::new(0.375, 0.5)).x, 0.0);
}

/// A JPEG (written by Mitsuba 3.9.1, quality 100): two colours, sRGB decoded.
#[test]
fn jpeg_is_decoded() {
    let bytes =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/assets/two_colours.jpg"))
            .unwrap();
    let texture = bitmap(
        Image::decode(&bytes, false).unwrap(),
        Filter::Nearest,
        Wrap::Repeat,
    );
    let srgb = |c: [f64; 3]| Rgb::from(c.map(|v| srgb_to_linear(v / 255.0) as f32));
    // Mitsuba reads the left half as (200, 100, 50) and the right as (20, 220, 121); a
    // decoder may differ by one 8-bit unit, at most 0.0089 once decoded (the slope of the sRGB
    // curve at 1 is 2.275).
    let tolerance = 0.0089;
    let left = texture.eval(Vec2::new(0.125, 0.5));
    assert!(close(left, srgb([200.0, 100.0, 50.0]), tolerance), "{left}");
    let right = texture.eval(Vec2::new(0.875, 0.5));
    assert!(
        close(right, srgb([20.0, 220.0, 121.0]), tolerance),
        "{right}"
    );
}

/// An EXR's values are linear, read as they are.
#[test]
fn exr_is_linear() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.exr");
    exr::prelude::write_rgb_file(&path, 2, 1, |x, _| {
        if x == 0 {
            (0.25f32, 2.0f32, 8.0f32)
        } else {
            (1.0, 1.0, 1.0)
        }
    })
    .unwrap();
    let texture = bitmap(
        Image::read(&path, false).unwrap(),
        Filter::Nearest,
        Wrap::Repeat,
    );
    assert_eq!(texture.eval(Vec2::new(0.25, 0.5)), Rgb::new(0.25, 2.0, 8.0));
}

/// An image of 100 000 × 100 000 pixels is refused from its header, with the bytes it would
/// take, before its pixels are allocated (the file holds no pixel data at all).
#[test]
fn huge_image_is_refused_with_its_size() {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, 100_000, 100_000);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    drop(encoder.write_header().unwrap());
    let error = Image::decode(&bytes, false).unwrap_err();
    assert!(
        error.contains("100000 × 100000 pixels would take 30000000000 bytes"),
        "{error}"
    );
}

/// Truncated and corrupt files are errors that name the file and the problem.
#[test]
fn truncated_and_corrupt_files_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let good = png(4, 4, png::ColorType::Rgb, png::BitDepth::Eight, &[7; 48]);
    let jpeg =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/assets/two_colours.jpg"))
            .unwrap();
    let cases: [(&str, Vec<u8>, &str); 5] = [
        (
            "truncated.png",
            good[..good.len() - 20].to_vec(),
            "not a valid PNG",
        ),
        ("header.png", good[..20].to_vec(), "not a valid PNG"),
        ("truncated.jpg", jpeg[..jpeg.len() / 2].to_vec(), "JPEG"),
        (
            "garbage.jpg",
            vec![0xff, 0xd8, 1, 2, 3, 4, 5],
            "not a valid JPEG",
        ),
        (
            "text.png",
            b"hello".to_vec(),
            "not a PNG, JPEG or OpenEXR image",
        ),
    ];
    for (name, bytes, problem) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, &bytes).unwrap();
        match Image::read(&path, false) {
            Ok(image) => panic!("{name} decoded as {} × {}", image.width, image.height),
            Err(error) => {
                assert!(
                    error.contains(name) && error.contains(problem),
                    "{name}: {error}"
                )
            }
        }
    }
    let missing = Image::read(&dir.path().join("absent.png"), false).unwrap_err();
    assert!(missing.contains("absent.png"), "{missing}");
}

/// Values Mitsuba 3.9.1 (scalar_rgb) gives for a 2 × 1 PNG of (200, 100, 50) and (20, 220, 120):
/// `eval` and `eval_1` at the first pixel's centre and between the centres (8-bit values
/// sRGB-decoded before the bilinear interpolation; `eval_1` the luminance).
#[test]
fn matches_mitsuba_lookups() {
    let data = [200u8, 100, 50, 20, 220, 120];
    let bytes = png(2, 1, png::ColorType::Rgb, png::BitDepth::Eight, &data);
    let texture = bitmap(
        Image::decode(&bytes, false).unwrap(),
        Filter::Bilinear,
        Wrap::Repeat,
    );
    for (u, rgb, one) in [
        (0.25, Rgb::new(0.577581, 0.127438, 0.031896), 0.216_274_98),
        (0.4, Rgb::new(0.406405, 0.303915, 0.078_673_4), 0.309_455_87),
    ] {
        let uv = Vec2::new(u, 0.5);
        assert!(
            close(texture.eval(uv), rgb, 2e-6),
            "{u}: {}",
            texture.eval(uv)
        );
        assert!(
            (texture.eval_1(uv) - one).abs() < 2e-6,
            "{u}: {}",
            texture.eval_1(uv)
        );
    }
}
