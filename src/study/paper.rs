//! The paper's own numbers (Lu, Pacanowski, Granier 2013, supplemental Tables 1 and 2), so that a
//! study prints its ratios to the balance heuristic beside ours. Scenes `01` … `11` of
//! `scenes/paper/` are analogues of the paper's scenes 1 … 11: compare ratios, not values.

use super::config::{Choice, PAPER_BUDGET, PAPER_PREPROCESSED_PILOT};
use lumis_integrators::{alpha, balance, bsdf, light, max, power};

/// One scene's row of the paper's tables.
pub struct PaperScene {
    /// Table 1: mean sampling variance V[L_{1,α}] at N = 256.
    pub sampling_variance: PerMethod,
    /// Table 2: mean Lab error against a 32768-sample reference.
    pub lab_error: PerMethod,
    /// Table 2: rendering time in seconds at N = 256.
    pub time: PerMethod,
}

/// A value per balancing method; `alpha` is the integrated estimation (Table 2) except for
/// Table 1's sampling variance, where the paper also gives the preprocessed α.
#[derive(Clone, Copy)]
pub struct PerMethod {
    pub bsdf: f64,
    pub light: f64,
    pub balance: f64,
    pub power: f64,
    pub max: f64,
    pub alpha: f64,
    pub alpha_preprocessed: f64,
}

impl PerMethod {
    /// The value for a study integrator: its plugin name and, for `alpha`, its mode.
    pub fn get(&self, kind: &str, mode: Option<&str>) -> Option<f64> {
        let v = match (kind, mode) {
            (bsdf::NAME, _) => self.bsdf,
            (light::NAME, _) => self.light,
            (balance::NAME, _) => self.balance,
            (power::NAME, _) => self.power,
            (max::NAME, _) => self.max,
            (alpha::NAME, None | Some(alpha::INTEGRATED)) => self.alpha,
            (alpha::NAME, Some(alpha::PREPROCESSED)) => self.alpha_preprocessed,
            _ => return None,
        };
        v.is_finite().then_some(v)
    }

    /// The value relative to the balance heuristic's.
    pub fn ratio(&self, kind: &str, mode: Option<&str>) -> Option<f64> {
        self.get(kind, mode).map(|v| v / self.balance)
    }
}

const fn methods(v: [f64; 7]) -> PerMethod {
    PerMethod {
        bsdf: v[0],
        light: v[1],
        balance: v[2],
        power: v[3],
        max: v[4],
        alpha: v[5],
        alpha_preprocessed: v[6],
    }
}

/// Rows of Table 1 (BRDF, light, balance, power, maximum, preprocessed α) with Table 2's
/// integrated α, Lab errors and times, for scenes 1 … 11.
const SCENES: [PaperScene; 11] = {
    // Table 1 sampling variance: bsdf, light, balance, power, max; then integrated (Table 2)
    // and preprocessed (Table 1) α.
    const V: [[f64; 7]; 11] = [
        [67.3, 0.47, 0.90, 0.99, 1.24, 0.66, 0.42],
        [4597.0, 2.56, 4.76, 4.87, 5.11, 3.88, 2.95],
        [24.14, 0.005, 0.096, 0.097, 0.097, 0.065, 0.035],
        [0.294, 0.014, 0.027, 0.030, 0.035, 0.022, 0.016],
        [0.469, 4.131, 0.410, 0.450, 0.550, 0.35, 0.27],
        [1.260, 0.088, 0.120, 0.138, 0.157, 0.086, 0.047],
        [5.39, 61.7, 5.76, 6.42, 9.78, 5.68, 5.09],
        [2.070, 0.036, 0.043, 0.046, 0.061, 0.037, 0.033],
        [0.0198, 118.20, 0.250, 0.255, 0.256, 0.1700, 0.095],
        [139.75, 0.776, 0.402, 0.440, 0.618, 0.359, 0.301],
        [0.378, 0.127, 0.055, 0.059, 0.075, 0.051, 0.045],
    ];
    // Table 2 Lab error and time: bsdf, light, balance, power, max, integrated α.
    const LAB: [[f64; 6]; 11] = [
        [14.9, 0.14, 0.14, 0.11, 0.12, 0.13],
        [6.5, 1.11, 0.81, 0.83, 0.95, 0.78],
        [10.5, 0.25, 0.31, 0.31, 0.31, 0.29],
        [2.80, 0.78, 0.91, 0.93, 0.99, 0.86],
        [1.10, 7.50, 0.77, 0.78, 0.85, 0.74],
        [22.9, 0.23, 0.28, 0.28, 0.28, 0.26],
        [2.00, 3.60, 1.04, 1.06, 1.30, 1.02],
        [3.85, 1.16, 1.21, 1.22, 1.37, 1.15],
        [0.36, 15.9, 0.47, 0.46, 0.45, 0.44],
        [5.26, 2.00, 1.65, 1.70, 1.98, 1.60],
        [3.38, 2.25, 1.54, 1.59, 1.71, 1.51],
    ];
    const TIME: [[f64; 6]; 11] = [
        [158.6, 299.7, 237.7, 239.9, 239.0, 250.8],
        [138.1, 102.8, 123.5, 122.3, 121.6, 128.3],
        [40.6, 147.4, 95.5, 95.7, 95.4, 106.9],
        [55.1, 41.8, 48.9, 48.8, 48.1, 45.8],
        [33.7, 18.6, 28.0, 27.1, 26.0, 28.3],
        [16.9, 33.8, 25.5, 24.9, 24.5, 26.9],
        [59.1, 41.7, 52.0, 49.9, 49.5, 51.1],
        [36.5, 34.2, 36.2, 35.9, 34.9, 34.5],
        [49.2, 27.1, 40.0, 39.2, 38.5, 40.9],
        [354.0, 178.0, 281.0, 275.0, 264.0, 281.0],
        [91.0, 53.0, 74.0, 74.0, 71.1, 72.0],
    ];
    let mut scenes = [const {
        PaperScene {
            sampling_variance: methods([f64::NAN; 7]),
            lab_error: methods([f64::NAN; 7]),
            time: methods([f64::NAN; 7]),
        }
    }; 11];
    let mut i = 0;
    while i < 11 {
        let (l, t) = (LAB[i], TIME[i]);
        scenes[i] = PaperScene {
            sampling_variance: methods(V[i]),
            lab_error: methods([l[0], l[1], l[2], l[3], l[4], l[5], f64::NAN]),
            time: methods([t[0], t[1], t[2], t[3], t[4], t[5], f64::NAN]),
        };
        i += 1;
    }
    scenes
};

/// The paper's scene that a study scene is an analogue of: files named `01.ron` … `11.ron`.
pub fn scene(path: &std::path::Path) -> Option<&'static PaperScene> {
    let stem = path.file_stem()?.to_str()?;
    let n: usize = stem.parse().ok()?;
    (stem.len() == 2 && (1..=11).contains(&n)).then(|| &SCENES[n - 1])
}

/// The paper's efficiency, 1 / (variance × time), with Table 2's variance (Table 1's sampling
/// variance, integrated α for α).
pub fn efficiency(scene: &PaperScene, kind: &str, mode: Option<&str>) -> Option<f64> {
    Some(1.0 / (scene.sampling_variance.get(kind, mode)? * scene.time.get(kind, mode)?))
}

/// The paper's method that a study configuration measures exactly (the same quantity): the same
/// technique at the paper's N = 256 with its pilot sizes (integrated α: M = N/2; preprocessed α:
/// M = 4096) and no other parameter. As `(plugin name, α mode)` for [`PerMethod::get`].
pub fn method(choice: &Choice, samples: u32) -> Option<(&'static str, Option<&'static str>)> {
    if samples != PAPER_BUDGET {
        return None;
    }
    let params = &choice.spec.params;
    let kind = [
        bsdf::NAME,
        light::NAME,
        balance::NAME,
        power::NAME,
        max::NAME,
    ]
    .into_iter()
    .find(|&k| k == choice.spec.kind);
    if let Some(kind) = kind {
        return params.is_empty().then_some((kind, None));
    }
    if choice.spec.kind != alpha::NAME
        || params
            .keys()
            .any(|k| k != alpha::MODE && k != alpha::ALPHA_SAMPLES)
    {
        return None;
    }
    let pilot = choice.int_param(alpha::ALPHA_SAMPLES);
    match choice.string_param(alpha::MODE) {
        None | Some(alpha::INTEGRATED)
            if pilot.is_none_or(|m| m == 0 || m == u64::from(samples / 2)) =>
        {
            Some((alpha::NAME, Some(alpha::INTEGRATED)))
        }
        Some(alpha::PREPROCESSED)
            if pilot.is_none_or(|m| m == u64::from(PAPER_PREPROCESSED_PILOT)) =>
        {
            Some((alpha::NAME, Some(alpha::PREPROCESSED)))
        }
        _ => None,
    }
}
