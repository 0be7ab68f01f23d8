//! Fresnel reflectance shared by the BSDFs, over [`Lanes`]: at a dielectric interface (a real
//! relative index of refraction η) and at a conductor (a complex one, η + i k); the
//! hemispherical average of the dielectric one (the diffuse Fresnel reflectance a coating
//! reflects internally); and the named indices of refraction scene files may give instead of a
//! number (Mitsuba's table, from Hecht's *Optics*, measured at about 589 nm).
//!
//! Unpolarised light: the reflectance is the mean of the s- and p-polarised ones.

use lumis_core::math::lanes::{Lanes, V3};

/// The Fresnel reflectance of unpolarised light at a smooth dielectric interface, for light
/// meeting it at cos θi (its side by the sign: positive on the side the normal points to, where
/// the relative index η = η_inside / η_outside applies; negative from inside, where 1/η does),
/// with the cosine of the refracted direction, signed opposite to cos θi (0 under total
/// internal reflection, where the reflectance is 1). η = 1 reflects nothing.
///
/// Returns (F, cos θt, η_it, η_ti): the reflectance, the refracted cosine, and the relative
/// index along the direction of travel and its reciprocal (the factor of the refracted
/// direction's tangential components).
#[inline(always)]
pub fn dielectric<L: Lanes>(cos_i: L, eta: L) -> (L, L, L, L) {
    let (zero, one) = (L::splat(0.0), L::splat(1.0));
    let outside = cos_i.gt(zero) | cos_i.eq(zero);
    let rcp_eta = one / eta;
    let eta_it = L::select(outside, eta, rcp_eta);
    let eta_ti = L::select(outside, rcp_eta, eta);
    // Snell: sin²θt = (1 − cos²θi) / η_it².
    let cos_t2 = one - (one - cos_i * cos_i) * (eta_ti * eta_ti);
    let cos_i_abs = cos_i.abs();
    let cos_t_abs = cos_t2.max(zero).sqrt();
    let a_s = (cos_i_abs - eta_it * cos_t_abs) / (cos_i_abs + eta_it * cos_t_abs);
    let a_p = (cos_t_abs - eta_it * cos_i_abs) / (cos_t_abs + eta_it * cos_i_abs);
    let r = L::splat(0.5) * (a_s * a_s + a_p * a_p);
    // η = 1: nothing reflected; grazing incidence: everything (0/0 above).
    let matched = eta.eq(one);
    let r = L::select(matched, zero, L::select(cos_i_abs.eq(zero), one, r));
    let cos_t = cos_t_abs.copysign(-cos_i);
    (r, L::select(cos_t2.lt(zero), zero, cos_t), eta_it, eta_ti)
}

/// The Fresnel reflectance of unpolarised light at a conductor of complex relative index
/// η + i k, per channel, for light arriving from outside at cos θi in [0, 1] (Moeller, *Optics*,
/// 1988, the form Mitsuba 3 uses). Clamped to [0, 1], and 1 where the formula has no value
/// (η = k = 0 at normal incidence: 0/0), its limit as η and k fall to 0.
#[inline(always)]
pub fn conductor<L: Lanes>(cos_i: L, eta: V3<L>, k: V3<L>) -> V3<L> {
    V3::new(
        conductor_channel(cos_i, eta.x, k.x),
        conductor_channel(cos_i, eta.y, k.y),
        conductor_channel(cos_i, eta.z, k.z),
    )
}

#[inline(always)]
fn conductor_channel<L: Lanes>(cos_i: L, eta: L, k: L) -> L {
    let (zero, one, half) = (L::splat(0.0), L::splat(1.0), L::splat(0.5));
    let cos2 = cos_i * cos_i;
    let sin2 = one - cos2;
    let sin4 = sin2 * sin2;
    let t1 = eta * eta - k * k - sin2;
    let a2_plus_b2 = (t1 * t1 + L::splat(4.0) * k * k * eta * eta)
        .max(zero)
        .sqrt();
    let a = (half * (a2_plus_b2 + t1)).max(zero).sqrt();
    let term1 = a2_plus_b2 + cos2;
    let term2 = L::splat(2.0) * cos_i * a;
    let r_s = (term1 - term2) / (term1 + term2);
    let term3 = a2_plus_b2 * cos2 + sin4;
    let term4 = term2 * sin2;
    let r_p = r_s * (term3 - term4) / (term3 + term4);
    let r = half * (r_s + r_p);
    L::select(r.is_finite(), r.clamp(zero, one), one)
}

/// The hemispherical average 2 ∫ F(μ) μ dμ of the dielectric reflectance of relative index
/// `eta` (light from the side where η applies), by the fits Mitsuba 3 uses: Egan and Hilgeman
/// (1973) for η < 1, d'Eon and Irving (2011) for η ≥ 1 (within 0.1 % for η in [1, 2]).
pub fn diffuse_reflectance(eta: f32) -> f32 {
    let inv = 1.0 / eta;
    if eta < 1.0 {
        0.0636 * inv + eta * (eta * -1.4399 + 0.7099) + 0.6681
    } else {
        // A polynomial in 1/η (Horner).
        let coefficients = [0.919_317, -3.4793, 6.753_35, -7.809_89, 4.985_54, -1.368_81];
        coefficients.iter().rev().fold(0.0, |acc, &c| acc * inv + c)
    }
}

/// Indices of refraction by name, as Mitsuba's scene files give them (`int_ior="bk7"`):
/// Mitsuba 3's table (`ior.h`), from Hecht's *Optics*, 4th edition, measured between 0 and
/// 20 °C at about 589 nm.
pub const NAMED_IORS: &[(&str, f32)] = &[
    ("vacuum", 1.0),
    ("helium", 1.000_036),
    ("hydrogen", 1.000_132),
    ("air", 1.000_277),
    ("carbon dioxide", 1.000_45),
    ("water", 1.333),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.520_45),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.47),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.575),
    ("diamond", 2.419),
];

/// The index of refraction named `name` (case-insensitive), or an error listing the names.
pub fn named_ior(name: &str) -> Result<f32, String> {
    let lower = name.to_lowercase();
    NAMED_IORS
        .iter()
        .find(|(n, _)| *n == lower)
        .map(|&(_, ior)| ior)
        .ok_or_else(|| {
            let names: Vec<&str> = NAMED_IORS.iter().map(|(n, _)| *n).collect();
            format!(
                "unknown index of refraction `{name}`; known: {}",
                names.join(", ")
            )
        })
}

/// Mitsuba 3's named conductors (`material: "Au"`) as its RGB variants use them: the complex
/// index of refraction η + i k per linear sRGB channel, each the material's measured spectrum
/// (Mitsuba's `data/ior`) integrated against the CIE 1931 matching functions, negative
/// channels clamped to 0. Printed by `benches/mitsuba/named_conductors.py`, which does the
/// integral and checks every value against Mitsuba 3.9.1's own (within 1.2·10⁻⁷).
pub const NAMED_CONDUCTORS: &[(&str, [f32; 3], [f32; 3])] = &[
    ("Al", [1.6575, 0.880405, 0.521244], [9.22381, 6.2695, 4.837]),
    (
        "AlAs",
        [3.6053, 3.23294, 2.21632],
        [0.000679437, 0.0, 0.00751271],
    ),
    (
        "AlAs_palik",
        [3.6053, 3.23294, 2.21632],
        [0.000679437, 0.0, 0.00751271],
    ),
    ("AlSb", [0.0, 4.13937, 4.66925], [0.0, 0.0940091, 1.30057]),
    (
        "AlSb_palik",
        [0.0, 4.13937, 4.66925],
        [0.0, 0.0940091, 1.30057],
    ),
    (
        "Au",
        [0.143036, 0.375307, 1.44205],
        [3.983, 2.38556, 1.60336],
    ),
    (
        "Be",
        [4.18501, 3.18503, 2.78406],
        [3.83547, 3.01012, 2.86899],
    ),
    (
        "Be_palik",
        [4.18501, 3.18503, 2.78406],
        [3.83547, 3.01012, 2.86899],
    ),
    ("Cr", [4.36967, 2.91651, 1.6549], [5.20655, 4.23131, 3.7547]),
    ("CsI", [2.1449, 1.70232, 1.66243], [0.0, 0.0, 0.0]),
    ("CsI_palik", [2.1449, 1.70232, 1.66243], [0.0, 0.0, 0.0]),
    (
        "Cu",
        [0.201006, 0.923749, 1.10222],
        [3.91326, 2.45305, 2.14209],
    ),
    (
        "Cu2O",
        [3.55177, 2.94987, 2.75188],
        [0.114207, 0.193897, 0.606134],
    ),
    (
        "Cu2O_palik",
        [3.55177, 2.94987, 2.75188],
        [0.114207, 0.193897, 0.606134],
    ),
    (
        "CuO",
        [3.24754, 2.44781, 2.21022],
        [0.52109, 0.570031, 0.722179],
    ),
    (
        "CuO_palik",
        [3.24754, 2.44781, 2.21022],
        [0.52109, 0.570031, 0.722179],
    ),
    (
        "Cu_palik",
        [0.213229, 0.919715, 1.10241],
        [3.92187, 2.45733, 2.13658],
    ),
    (
        "Hg",
        [2.39894, 1.44003, 0.90957],
        [6.32759, 4.37192, 3.42176],
    ),
    (
        "HgTe",
        [4.77904, 3.2312, 2.6599],
        [1.63161, 1.58081, 1.72929],
    ),
    (
        "HgTe_palik",
        [4.77904, 3.2312, 2.6599],
        [1.63161, 1.58081, 1.72929],
    ),
    (
        "Hg_palik",
        [2.39894, 1.44003, 0.90957],
        [6.32759, 4.37192, 3.42176],
    ),
    (
        "Ir",
        [3.0863, 2.08219, 1.61791],
        [5.59215, 4.06709, 3.26731],
    ),
    (
        "Ir_palik",
        [3.0863, 2.08219, 1.61791],
        [5.59215, 4.06709, 3.26731],
    ),
    (
        "K",
        [0.0640432, 0.0464098, 0.0381849],
        [2.1042, 1.34894, 0.913126],
    ),
    (
        "K_palik",
        [0.0640432, 0.0464098, 0.0381849],
        [2.1042, 1.34894, 0.913126],
    ),
    (
        "Li",
        [0.265791, 0.195618, 0.220949],
        [3.54016, 2.31112, 1.66861],
    ),
    (
        "Li_palik",
        [0.265791, 0.195618, 0.220949],
        [3.54016, 2.31112, 1.66861],
    ),
    (
        "MgO",
        [2.08958, 1.65072, 1.59488],
        [4.3327e-12, 0.0, 2.49865e-11],
    ),
    (
        "MgO_palik",
        [2.08958, 1.65072, 1.59488],
        [4.3327e-12, 0.0, 2.49865e-11],
    ),
    (
        "Mo",
        [4.48397, 3.52513, 2.77631],
        [4.11144, 3.42083, 3.15061],
    ),
    (
        "Mo_palik",
        [4.48397, 3.52513, 2.77631],
        [4.11144, 3.42083, 3.15061],
    ),
    (
        "Na_palik",
        [0.0602694, 0.0561409, 0.0619884],
        [3.17927, 2.11249, 1.57904],
    ),
    (
        "Nb",
        [3.42007, 2.79009, 2.39563],
        [3.44139, 2.73767, 2.57975],
    ),
    (
        "Nb_palik",
        [3.42007, 2.79009, 2.39563],
        [3.44139, 2.73767, 2.57975],
    ),
    (
        "Ni_palik",
        [2.3673, 1.66337, 1.46708],
        [4.49881, 3.05015, 2.34544],
    ),
    (
        "Rh",
        [2.58579, 1.86022, 1.55426],
        [6.78226, 4.70299, 3.97607],
    ),
    (
        "Rh_palik",
        [2.58579, 1.86022, 1.55426],
        [6.78226, 4.70299, 3.97607],
    ),
    (
        "Se",
        [4.05831, 2.84293, 2.82085],
        [0.75405, 0.638444, 0.521807],
    ),
    (
        "Se-e",
        [5.72285, 4.16574, 4.08134],
        [0.871136, 1.10516, 1.56532],
    ),
    (
        "Se-e_palik",
        [5.72285, 4.16574, 4.08134],
        [0.871136, 1.10516, 1.56532],
    ),
    (
        "Se_palik",
        [4.05831, 2.84293, 2.82085],
        [0.75405, 0.638444, 0.521807],
    ),
    (
        "SiC",
        [3.17234, 2.52597, 2.47937],
        [7.53766e-07, 0.0, 1.01925e-05],
    ),
    (
        "SiC_palik",
        [3.17234, 2.52597, 2.47937],
        [7.53766e-07, 0.0, 1.01925e-05],
    ),
    ("SnTe", [4.52425, 1.98164, 1.28159], [0.0, 0.0, 0.0]),
    ("SnTe_palik", [4.52425, 1.98164, 1.28159], [0.0, 0.0, 0.0]),
    (
        "Ta",
        [2.06272, 2.39294, 2.62793],
        [2.40836, 1.74149, 1.94703],
    ),
    (
        "Ta_palik",
        [2.06272, 2.39294, 2.62793],
        [2.40836, 1.74149, 1.94703],
    ),
    (
        "Te",
        [7.39023, 4.4821, 2.63711],
        [3.25602, 3.52706, 3.29205],
    ),
    (
        "Te-e",
        [7.50891, 4.29643, 2.36999],
        [5.58393, 4.9472, 3.99759],
    ),
    (
        "Te-e_palik",
        [7.50891, 4.29643, 2.36999],
        [5.58393, 4.9472, 3.99759],
    ),
    (
        "Te_palik",
        [7.39023, 4.4821, 2.63711],
        [3.25602, 3.52706, 3.29205],
    ),
    ("ThF4", [1.83071, 1.44223, 1.38765], [0.0, 0.0, 0.0]),
    ("ThF4_palik", [1.83071, 1.44223, 1.38765], [0.0, 0.0, 0.0]),
    (
        "TiC",
        [3.70053, 2.83742, 2.58229],
        [3.26564, 2.35159, 2.17279],
    ),
    (
        "TiC_palik",
        [3.70053, 2.83742, 2.58229],
        [3.26564, 2.35159, 2.17279],
    ),
    (
        "TiN",
        [1.64845, 1.15052, 1.37982],
        [3.36833, 1.9435, 1.10207],
    ),
    (
        "TiN_palik",
        [1.64845, 1.15052, 1.37982],
        [3.36833, 1.9435, 1.10207],
    ),
    (
        "TiO2",
        [3.45661, 2.80174, 2.90517],
        [0.000105265, 0.0, 0.000652887],
    ),
    (
        "TiO2-e",
        [3.10656, 2.51317, 2.58244],
        [2.97516e-05, 0.0, 0.000182698],
    ),
    (
        "TiO2-e_palik",
        [3.10656, 2.51317, 2.58244],
        [2.97516e-05, 0.0, 0.000182698],
    ),
    (
        "TiO2_palik",
        [3.45661, 2.80174, 2.90517],
        [0.000105265, 0.0, 0.000652887],
    ),
    (
        "VC",
        [3.65757, 2.75274, 2.53267],
        [3.0683, 2.19869, 1.96319],
    ),
    (
        "VC_palik",
        [3.65757, 2.75274, 2.53267],
        [3.0683, 2.19869, 1.96319],
    ),
    (
        "VN",
        [2.8656, 2.11919, 1.94009],
        [3.03224, 2.05612, 1.61631],
    ),
    (
        "VN_palik",
        [2.8656, 2.11919, 1.94009],
        [3.03224, 2.05612, 1.61631],
    ),
    (
        "V_palik",
        [4.27758, 3.51295, 2.76107],
        [3.4913, 2.88945, 3.11152],
    ),
    (
        "W",
        [4.37082, 3.30025, 2.99841],
        [3.50064, 2.60487, 2.27323],
    ),
    (
        "a-C",
        [2.94405, 2.22714, 1.96816],
        [0.887465, 0.799298, 0.81529],
    ),
    ("d-C", [2.70872, 2.31883, 2.2289], [0.0, 0.0, 0.0]),
    ("d-C_palik", [2.70872, 2.31883, 2.2289], [0.0, 0.0, 0.0]),
];

/// The complex index (η, k) of the conductor named `name` (case-sensitive, as Mitsuba), or an
/// error listing the names.
pub fn named_conductor(name: &str) -> Result<([f32; 3], [f32; 3]), String> {
    NAMED_CONDUCTORS
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|&(_, eta, k)| (eta, k))
        .ok_or_else(|| {
            let names: Vec<&str> = NAMED_CONDUCTORS.iter().map(|(n, _, _)| *n).collect();
            format!(
                "unknown conductor `{name}`; known: none, {}",
                names.join(", ")
            )
        })
}
