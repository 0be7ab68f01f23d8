//! Spectra in Mitsuba XML (`<spectrum value="...">`) turned into linear sRGB (Rec. 709) as
//! Mitsuba 3's RGB variants turn them (`Properties::get_texture_impl` and
//! `spectrum_list_to_srgb`):
//!
//! - one value v: on a reflectance, the grey v; on an emitter, v times the sRGB of a constant
//!   spectrum, M·(1, 1, 1) = (1.204794, 0.948291, 0.908916) (sRGB's white is D65, not the
//!   constant spectrum), so that RGB renders match spectral ones;
//! - wavelength:value pairs (nm, increasing): the linear interpolant is integrated against the
//!   CIE 1931 2° colour matching functions at 1000 evenly spaced wavelengths over 360–830 nm
//!   (nothing outside the pairs' range), under the D65 illuminant for a reflectance and without
//!   it for an emitter, scaled by 470 nm / (1000 · 106.75…) and taken to sRGB by Mitsuba's
//!   XYZ→sRGB matrix; a reflectance is then clamped to [0, 1], an emission to ≥ 0.
//!
//! The tables are the CIE's (CIE 015: the 1931 2° observer and the D65 illuminant at 5 nm,
//! interpolated linearly between samples as Mitsuba does).

/// A `<spectrum>`'s value.
#[derive(Clone, Debug, PartialEq)]
pub enum Spectrum {
    Uniform(f64),
    /// Wavelengths (nm, increasing, at least two) and values.
    Sampled(Vec<f64>, Vec<f64>),
}

/// Parses a `<spectrum value>`: one number, or `wavelength:value` pairs separated by commas or
/// white space, wavelengths strictly increasing (as Mitsuba requires).
pub fn parse(text: &str) -> Result<Spectrum, String> {
    let tokens: Vec<&str> = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .collect();
    let number = |t: &str| {
        t.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("`{t}` is not a finite number"))
    };
    if let [one] = tokens.as_slice()
        && !one.contains(':')
    {
        return Ok(Spectrum::Uniform(number(one)?));
    }
    let (mut wavelengths, mut values) = (Vec::new(), Vec::new());
    for t in &tokens {
        let Some((w, v)) = t.split_once(':') else {
            return Err(format!(
                "`{t}` is not a wavelength:value pair (a spectrum is one value or pairs)"
            ));
        };
        wavelengths.push(number(w)?);
        values.push(number(v)?);
    }
    if wavelengths.len() < 2 {
        return Err(format!(
            "a sampled spectrum needs at least two wavelength:value pairs, found {}",
            wavelengths.len()
        ));
    }
    if let Some(i) = (1..wavelengths.len()).find(|&i| wavelengths[i] <= wavelengths[i - 1]) {
        return Err(format!(
            "wavelengths must increase: {} nm follows {} nm",
            wavelengths[i],
            wavelengths[i - 1]
        ));
    }
    Ok(Spectrum::Sampled(wavelengths, values))
}

/// The linear sRGB colour of `spectrum` as Mitsuba's RGB variants give it to an emitter
/// (`emitter`) or to anything else (a reflectance).
pub fn to_rgb(spectrum: &Spectrum, emitter: bool) -> [f64; 3] {
    match spectrum {
        Spectrum::Uniform(v) if emitter => {
            let white = xyz_to_srgb([1.0, 1.0, 1.0]);
            white.map(|c| c * v)
        }
        Spectrum::Uniform(v) => [*v; 3],
        Spectrum::Sampled(w, v) => sampled_to_srgb(w, v, !emitter, !emitter),
    }
}

const CIE_MIN: f64 = 360.0;
const CIE_MAX: f64 = 830.0;
/// Rows of [`CIE`]: every 5 nm from 360 to 830 nm.
pub const CIE_SAMPLES: usize = 95;
/// 1 / ∫ȳ over the table (Mitsuba's `MI_CIE_Y_NORMALIZATION`).
const CIE_Y_NORMALIZATION: f64 = 1.0 / 106.750_259_399_414_06;
/// Makes D65 integrate to a luminance of 1 (Mitsuba's `MI_CIE_D65_NORMALIZATION`).
const D65_NORMALIZATION: f64 = 1.0 / 98.997_417_518_762_55;

/// x̄, ȳ, z̄ and D65 (relative power, 100 at 560 nm) every 5 nm from 360 to 830 nm.
#[rustfmt::skip]
pub const CIE: [[f32; 4]; CIE_SAMPLES] = [
    [0.0001299, 3.917e-06, 0.0006061, 46.6383], // 360 nm
    [0.0002321, 6.965e-06, 0.001086, 49.3637], // 365 nm
    [0.0004149, 1.239e-05, 0.001946, 52.0891], // 370 nm
    [0.0007416, 2.202e-05, 0.003486, 51.0323], // 375 nm
    [0.001368, 3.9e-05, 0.00645, 49.9755], // 380 nm
    [0.002236, 6.4e-05, 0.01055, 52.3118], // 385 nm
    [0.004243, 0.00012, 0.02005, 54.6482], // 390 nm
    [0.00765, 0.000217, 0.03621, 68.7015], // 395 nm
    [0.01431, 0.000396, 0.06785, 82.7549], // 400 nm
    [0.02319, 0.00064, 0.1102, 87.1204], // 405 nm
    [0.04351, 0.00121, 0.2074, 91.486], // 410 nm
    [0.07763, 0.00218, 0.3713, 92.4589], // 415 nm
    [0.13438, 0.004, 0.6456, 93.4318], // 420 nm
    [0.21477, 0.0073, 1.03905, 90.057], // 425 nm
    [0.2839, 0.0116, 1.3856, 86.6823], // 430 nm
    [0.3285, 0.01684, 1.62296, 95.7736], // 435 nm
    [0.34828, 0.023, 1.74706, 104.865], // 440 nm
    [0.34806, 0.0298, 1.7826, 110.936], // 445 nm
    [0.3362, 0.038, 1.77211, 117.008], // 450 nm
    [0.3187, 0.048, 1.7441, 117.41], // 455 nm
    [0.2908, 0.06, 1.6692, 117.812], // 460 nm
    [0.2511, 0.0739, 1.5281, 116.336], // 465 nm
    [0.19536, 0.09098, 1.28764, 114.861], // 470 nm
    [0.1421, 0.1126, 1.0419, 115.392], // 475 nm
    [0.09564, 0.13902, 0.81295, 115.923], // 480 nm
    [0.05795, 0.1693, 0.6162, 112.367], // 485 nm
    [0.03201, 0.20802, 0.46518, 108.811], // 490 nm
    [0.0147, 0.2586, 0.3533, 109.082], // 495 nm
    [0.0049, 0.323, 0.272, 109.354], // 500 nm
    [0.0024, 0.4073, 0.2123, 108.578], // 505 nm
    [0.0093, 0.503, 0.1582, 107.802], // 510 nm
    [0.0291, 0.6082, 0.1117, 106.296], // 515 nm
    [0.06327, 0.71, 0.07825, 104.79], // 520 nm
    [0.1096, 0.7932, 0.05725, 106.239], // 525 nm
    [0.1655, 0.862, 0.04216, 107.689], // 530 nm
    [0.22575, 0.91485, 0.02984, 106.047], // 535 nm
    [0.2904, 0.954, 0.0203, 104.405], // 540 nm
    [0.3597, 0.9803, 0.0134, 104.225], // 545 nm
    [0.43345, 0.99495, 0.00875, 104.046], // 550 nm
    [0.51205, 1.0, 0.00575, 102.023], // 555 nm
    [0.5945, 0.995, 0.0039, 100.0], // 560 nm
    [0.6784, 0.9786, 0.00275, 98.1671], // 565 nm
    [0.7621, 0.952, 0.0021, 96.3342], // 570 nm
    [0.8425, 0.9154, 0.0018, 96.0611], // 575 nm
    [0.9163, 0.87, 0.00165, 95.788], // 580 nm
    [0.9786, 0.8163, 0.0014, 92.2368], // 585 nm
    [1.0263, 0.757, 0.0011, 88.6856], // 590 nm
    [1.0567, 0.6949, 0.001, 89.3459], // 595 nm
    [1.0622, 0.631, 0.0008, 90.0062], // 600 nm
    [1.0456, 0.5668, 0.0006, 89.8026], // 605 nm
    [1.0026, 0.503, 0.00034, 89.5991], // 610 nm
    [0.9384, 0.4412, 0.00024, 88.6489], // 615 nm
    [0.85445, 0.381, 0.00019, 87.6987], // 620 nm
    [0.7514, 0.321, 0.0001, 85.4936], // 625 nm
    [0.6424, 0.265, 5e-05, 83.2886], // 630 nm
    [0.5419, 0.217, 3e-05, 83.4939], // 635 nm
    [0.4479, 0.175, 2e-05, 83.6992], // 640 nm
    [0.3608, 0.1382, 1e-05, 81.863], // 645 nm
    [0.2835, 0.107, 2.11758e-22, 80.0268], // 650 nm
    [0.2187, 0.0816, 0.0, 80.1207], // 655 nm
    [0.1649, 0.061, 0.0, 80.2146], // 660 nm
    [0.1212, 0.04458, 0.0, 81.2462], // 665 nm
    [0.0874, 0.032, 0.0, 82.2778], // 670 nm
    [0.0636, 0.0232, 0.0, 80.281], // 675 nm
    [0.04677, 0.017, 0.0, 78.2842], // 680 nm
    [0.0329, 0.01192, 0.0, 74.0027], // 685 nm
    [0.0227, 0.00821, 0.0, 69.7213], // 690 nm
    [0.01584, 0.005723, 0.0, 70.6652], // 695 nm
    [0.0113592, 0.004102, 0.0, 71.6091], // 700 nm
    [0.00811092, 0.002929, 0.0, 72.979], // 705 nm
    [0.00579035, 0.002091, 0.0, 74.349], // 710 nm
    [0.00410946, 0.001484, 0.0, 67.9765], // 715 nm
    [0.00289933, 0.001047, 0.0, 61.604], // 720 nm
    [0.00204919, 0.00074, 0.0, 65.7448], // 725 nm
    [0.00143997, 0.00052, 0.0, 69.8856], // 730 nm
    [0.000999949, 0.0003611, 0.0, 72.4863], // 735 nm
    [0.000690079, 0.0002492, 0.0, 75.087], // 740 nm
    [0.000476021, 0.0001719, 0.0, 69.3398], // 745 nm
    [0.000332301, 0.00012, 0.0, 63.5927], // 750 nm
    [0.000234826, 8.48e-05, 0.0, 55.0054], // 755 nm
    [0.000166151, 6e-05, 0.0, 46.4182], // 760 nm
    [0.000117413, 4.24e-05, 0.0, 56.6118], // 765 nm
    [8.30753e-05, 3e-05, 0.0, 66.8054], // 770 nm
    [5.87065e-05, 2.12e-05, 0.0, 65.0941], // 775 nm
    [4.15099e-05, 1.499e-05, 0.0, 63.3828], // 780 nm
    [2.93533e-05, 1.06e-05, 0.0, 63.8434], // 785 nm
    [2.06738e-05, 7.4657e-06, 0.0, 64.304], // 790 nm
    [1.45598e-05, 5.2578e-06, 0.0, 61.8779], // 795 nm
    [1.0254e-05, 3.7029e-06, 0.0, 59.4519], // 800 nm
    [7.22146e-06, 2.6078e-06, 0.0, 55.7054], // 805 nm
    [5.08587e-06, 1.8366e-06, 0.0, 51.959], // 810 nm
    [3.58165e-06, 1.2934e-06, 0.0, 54.6998], // 815 nm
    [2.52252e-06, 9.1093e-07, 0.0, 57.4406], // 820 nm
    [1.77651e-06, 6.4153e-07, 0.0, 58.8765], // 825 nm
    [1.25114e-06, 4.5181e-07, 0.0, 60.3125], // 830 nm
];

/// Linear interpolation of table column(s) at `wavelength` (0 outside the table).
fn table_at(wavelength: f64) -> Option<(usize, f64)> {
    if !(CIE_MIN..=CIE_MAX).contains(&wavelength) {
        return None;
    }
    let t = (wavelength - CIE_MIN) * ((CIE_SAMPLES - 1) as f64 / (CIE_MAX - CIE_MIN));
    let i0 = (t as usize).min(CIE_SAMPLES - 2);
    Some((i0, t - i0 as f64))
}

fn interpolate(i0: usize, w1: f64, column: usize) -> f64 {
    (1.0 - w1) * CIE[i0][column] as f64 + w1 * CIE[i0 + 1][column] as f64
}

/// Mitsuba's XYZ to linear sRGB matrix (its constants, in f32).
fn xyz_to_srgb([x, y, z]: [f64; 3]) -> [f64; 3] {
    const M: [[f32; 3]; 3] = [
        [3.240479, -1.53715, -0.498535],
        [-0.969256, 1.875991, 0.041556],
        [0.055648, -0.204043, 1.057311],
    ];
    M.map(|r| r[0] as f64 * x + r[1] as f64 * y + r[2] as f64 * z)
}

/// `spectrum_list_to_srgb`: the spectrum's sRGB, under D65 if `d65`, clamped to [0, 1] if
/// `bounded`, else to ≥ 0.
fn sampled_to_srgb(wavelengths: &[f64], values: &[f64], bounded: bool, d65: bool) -> [f64; 3] {
    const STEPS: usize = 1000;
    let (first, last) = (wavelengths[0], wavelengths[wavelengths.len() - 1]);
    let mut xyz = [0.0f64; 3];
    for i in 0..STEPS {
        let w = CIE_MIN + (i as f64 / (STEPS - 1) as f64) * (CIE_MAX - CIE_MIN);
        if w < first || w > last {
            continue;
        }
        // The last sample at or below w, at most the second last.
        let index = wavelengths
            .partition_point(|&x| x <= w)
            .clamp(1, wavelengths.len() - 1)
            - 1;
        let (w0, w1) = (wavelengths[index], wavelengths[index + 1]);
        let (v0, v1) = (values[index], values[index + 1]);
        let v = ((w - w1) * v0 + (w0 - w) * v1) / (w0 - w1);
        let Some((i0, t)) = table_at(w) else {
            continue;
        };
        let illuminant = if d65 {
            interpolate(i0, t, 3) * D65_NORMALIZATION
        } else {
            1.0
        };
        for (c, sum) in xyz.iter_mut().enumerate() {
            *sum += interpolate(i0, t, c) * v * illuminant;
        }
    }
    let scale = (CIE_MAX - CIE_MIN) * CIE_Y_NORMALIZATION / STEPS as f64;
    let rgb = xyz_to_srgb(xyz.map(|c| c * scale));
    if bounded {
        rgb.map(|c| c.clamp(0.0, 1.0))
    } else {
        rgb.map(|c| c.max(0.0))
    }
}
