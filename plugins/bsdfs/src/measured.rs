//! `measured`: an isotropic measured BRDF in the MERL binary format (Matusik et al. 2003).
//!
//! Parameters:
//! - `file` (path, required): the `.binary` file, relative to the scene file.
//!
//! Format: three little-endian int32 (90, 90, 180), then 3 × 1 458 000 float64 (red block, green,
//! blue) indexed by Rusinkiewicz half/difference angles: θh (90 bins, square-root spaced), θd
//! (90 bins), φd (180 bins over [0, π), reciprocity folds the rest). Channels are scaled by 1/1500,
//! 1.15/1500 and 1.66/1500; negative entries mark invalid measurements.
//!
//! Evaluation interpolates the table trilinearly, ignoring invalid corners. Sampling: at load,
//! for each of 32 incident elevations, a 2D piecewise-constant distribution of luminance(f)·cos θi
//! over (cos θi, φi − φo) is tabulated; a direction is drawn from the table of ωo's elevation, or
//! with probability 1/10 from the cosine-weighted hemisphere so that every direction the BRDF
//! reflects into can be drawn. `pdf` is exactly that mixture.

use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext, BsdfFlags, BsdfSample, sample_from_pdf};
use lumis_core::image_io::write_atomically;
use lumis_core::math::warp::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
use lumis_core::math::{Distribution2D, Rgb, luminance};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use std::f32::consts::{FRAC_PI_2, PI, TAU};
use std::io::Write;
use std::path::Path;
use std::sync::Arc;

/// The table's bins of θh (square-root spaced over [0, π/2]).
pub const THETA_H: usize = 90;
/// The table's bins of θd (over [0, π/2]).
pub const THETA_D: usize = 90;
/// The table's bins of φd (over [0, π)).
pub const PHI_D: usize = 180;
/// Entries per channel.
pub const ENTRIES: usize = THETA_H * THETA_D * PHI_D;
/// The published scales of the red, green and blue channels (a file stores each divided by it).
pub const SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
/// Size of a MERL file: header and three channels of float64.
pub const MERL_FILE_SIZE: usize = 12 + 3 * ENTRIES * 8;

/// Sampling tables: incident elevations, and the (cos θi, φ) grid of each.
const TABLE_ELEVATIONS: usize = 32;
const TABLE_COS: usize = 64;
const TABLE_PHI: usize = 128;
/// Probability of drawing from the cosine-weighted hemisphere instead of the table.
const DEFENSIVE: f32 = 0.1;

/// The table of a MERL BRDF, scaled to reflectance units; negative: invalid.
pub struct MerlTable {
    values: Vec<[f32; 3]>,
}

/// Rotates `v` by `angle` about the unit `axis` (Rodrigues).
fn rotate(v: Vec3, axis: Vec3, angle: f32) -> Vec3 {
    let (sin, cos) = angle.sin_cos();
    v * cos + axis * axis.dot(v) * (1.0 - cos) + axis.cross(v) * sin
}

/// (θh, θd, φd) of a pair of unit directions above the surface.
pub fn half_diff(wi: Vec3, wo: Vec3) -> (f32, f32, f32) {
    let h = (wi + wo).normalize();
    let theta_h = h.z.clamp(-1.0, 1.0).acos();
    let phi_h = h.y.atan2(h.x);
    let d = rotate(rotate(wi, Vec3::Z, -phi_h), Vec3::Y, -theta_h);
    (theta_h, d.z.clamp(-1.0, 1.0).acos(), d.y.atan2(d.x))
}

/// The directions (ωi, ωo) of half/difference angles, with φh = 0.
pub fn from_half_diff(theta_h: f32, theta_d: f32, phi_d: f32) -> (Vec3, Vec3) {
    let h = Vec3::new(theta_h.sin(), 0.0, theta_h.cos());
    let d = Vec3::new(
        theta_d.sin() * phi_d.cos(),
        theta_d.sin() * phi_d.sin(),
        theta_d.cos(),
    );
    let wi = rotate(d, Vec3::Y, theta_h);
    (wi, 2.0 * wi.dot(h) * h - wi)
}

fn index(th: usize, td: usize, pd: usize) -> usize {
    pd + PHI_D * (td + THETA_D * th)
}

impl MerlTable {
    /// Reads a MERL `.binary` file; the error says what is wrong (callers add the path).
    pub fn read(path: &Path) -> Result<Self, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("cannot read measured BRDF: {e}"))?;
        Self::parse(&bytes)
    }

    /// Reads a MERL file's bytes; the error says what is wrong.
    pub fn parse(bytes: &[u8]) -> Result<Self, String> {
        if bytes.len() < 12 {
            return Err(format!(
                "not a MERL file: {} bytes, shorter than its header",
                bytes.len()
            ));
        }
        let dims: Vec<i32> = bytes[..12]
            .chunks_exact(4)
            .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if dims != [THETA_H as i32, THETA_D as i32, PHI_D as i32] {
            return Err(format!(
                "not a MERL file: dimensions {dims:?}, expected [90, 90, 180]"
            ));
        }
        if bytes.len() != MERL_FILE_SIZE {
            return Err(format!(
                "truncated or oversized MERL file: {} bytes, expected {MERL_FILE_SIZE}",
                bytes.len()
            ));
        }
        let data = &bytes[12..];
        let channel = |c: usize, i: usize| {
            let at = (c * ENTRIES + i) * 8;
            let v = f64::from_le_bytes(data[at..at + 8].try_into().expect("8 bytes"));
            // NaN and negative entries both mean "no measurement".
            if v >= 0.0 && v.is_finite() {
                (v * SCALE[c]) as f32
            } else {
                -1.0
            }
        };
        let values = (0..ENTRIES)
            .map(|i| [channel(0, i), channel(1, i), channel(2, i)])
            .collect();
        Ok(MerlTable { values })
    }

    /// The BRDF value f(ωi, ωo) (no cosine), interpolated trilinearly over valid entries.
    pub fn lookup(&self, wi: Vec3, wo: Vec3) -> Rgb {
        let (theta_h, theta_d, mut phi_d) = half_diff(wi, wo);
        if phi_d < 0.0 {
            phi_d += PI;
        }
        let xh = ((theta_h.max(0.0) / FRAC_PI_2).sqrt() * THETA_H as f32)
            .clamp(0.0, (THETA_H - 1) as f32);
        let xd = (theta_d / FRAC_PI_2 * THETA_D as f32).clamp(0.0, (THETA_D - 1) as f32);
        let xp = (phi_d / PI * PHI_D as f32).clamp(0.0, PHI_D as f32);
        let (h0, d0, p0) = (
            xh.floor() as usize,
            xd.floor() as usize,
            xp.floor() as usize,
        );
        let (th, td, tp) = (xh - h0 as f32, xd - d0 as f32, xp - p0 as f32);
        let mut sum = Rgb::ZERO;
        let mut weight = 0.0;
        for (h, wh) in [(h0, 1.0 - th), ((h0 + 1).min(THETA_H - 1), th)] {
            for (d, wd) in [(d0, 1.0 - td), ((d0 + 1).min(THETA_D - 1), td)] {
                // φd is periodic with period π.
                for (p, wp) in [(p0 % PHI_D, 1.0 - tp), ((p0 + 1) % PHI_D, tp)] {
                    let w = wh * wd * wp;
                    let v = self.values[index(h, d, p)];
                    if w > 0.0 && v[0] >= 0.0 {
                        sum += w * Rgb::from(v);
                        weight += w;
                    }
                }
            }
        }
        if weight > 0.0 {
            sum / weight
        } else {
            Rgb::ZERO
        }
    }
}

/// Writes a MERL-format file tabulating `f(ωi, ωo)` (no cosine) at the table's grid points;
/// pairs below the horizon are stored as invalid (−1), as measured files do.
pub fn write_merl(path: &Path, f: impl Fn(Vec3, Vec3) -> Rgb + Sync) -> Result<(), String> {
    let mut bytes = Vec::with_capacity(MERL_FILE_SIZE);
    for d in [THETA_H as i32, THETA_D as i32, PHI_D as i32] {
        bytes.extend(d.to_le_bytes());
    }
    let mut channels = vec![0f64; 3 * ENTRIES];
    for th in 0..THETA_H {
        // The entry of index i holds θh = (i / 90)² · π/2 (the square-root spacing).
        let theta_h = (th as f32 / THETA_H as f32).powi(2) * FRAC_PI_2;
        for td in 0..THETA_D {
            let theta_d = td as f32 / THETA_D as f32 * FRAC_PI_2;
            for pd in 0..PHI_D {
                let phi_d = pd as f32 / PHI_D as f32 * PI;
                let (wi, wo) = from_half_diff(theta_h, theta_d, phi_d);
                let i = index(th, td, pd);
                let value = if wi.z > 0.0 && wo.z > 0.0 {
                    Some(f(wi, wo))
                } else {
                    None
                };
                for c in 0..3 {
                    channels[c * ENTRIES + i] = value.map_or(-1.0, |v| v[c] as f64 / SCALE[c]);
                }
            }
        }
    }
    for v in channels {
        bytes.extend(v.to_le_bytes());
    }
    write_atomically(path, |file| {
        file.write_all(&bytes).map_err(|e| e.to_string())
    })
    .map_err(|e| e.to_string())
}

pub struct Measured {
    table: MerlTable,
    /// One sampling table per incident elevation band (uniform in θo).
    sampling: Vec<Option<Distribution2D>>,
}

/// The elevation band of ωo.
fn elevation_band(wo: Vec3) -> usize {
    let theta = wo.z.clamp(0.0, 1.0).acos();
    ((theta / FRAC_PI_2 * TABLE_ELEVATIONS as f32) as usize).min(TABLE_ELEVATIONS - 1)
}

/// φ of `w` relative to that of `wo`, in [0, 1) of a turn.
fn relative_phi(wo: Vec3, w: Vec3) -> f32 {
    let phi = w.y.atan2(w.x) - wo.y.atan2(wo.x);
    (phi / TAU).rem_euclid(1.0)
}

impl Measured {
    pub fn new(table: MerlTable) -> Self {
        let sampling = (0..TABLE_ELEVATIONS)
            .map(|band| {
                let theta_o = (band as f32 + 0.5) / TABLE_ELEVATIONS as f32 * FRAC_PI_2;
                let wo = Vec3::new(theta_o.sin(), 0.0, theta_o.cos());
                let mut values = Vec::with_capacity(TABLE_COS * TABLE_PHI);
                for row in 0..TABLE_COS {
                    let cos = (row as f32 + 0.5) / TABLE_COS as f32;
                    let sin = (1.0 - cos * cos).sqrt();
                    for col in 0..TABLE_PHI {
                        let phi = (col as f32 + 0.5) / TABLE_PHI as f32 * TAU;
                        let wi = Vec3::new(sin * phi.cos(), sin * phi.sin(), cos);
                        values.push(luminance(table.lookup(wi, wo)).max(0.0) * cos);
                    }
                }
                Distribution2D::new(&values, TABLE_PHI, TABLE_COS)
            })
            .collect();
        Measured { table, sampling }
    }

    fn table_pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match &self.sampling[elevation_band(wo)] {
            // Point (φ turn, cos θ) on the unit square; dω = d(cos θ) dφ = 2π dx dy.
            Some(d) => d.pdf(Vec2::new(relative_phi(wo, wi), wi.z)) / TAU,
            None => 0.0,
        }
    }
}

impl Bsdf for Measured {
    fn eval(&self, _ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        self.table.lookup(wi, wo) * wi.z
    }

    fn pdf(&self, _ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let table = if self.sampling[elevation_band(wo)].is_some() {
            1.0 - DEFENSIVE
        } else {
            0.0
        };
        table * self.table_pdf(wo, wi) + (1.0 - table) * cosine_hemisphere_pdf(wi.z)
    }

    fn sample(&self, ctx: &BsdfContext, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = match &self.sampling[elevation_band(wo)] {
            Some(d) if u_lobe >= DEFENSIVE => {
                let p = d.sample(u);
                let cos = p.y;
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let phi = p.x * TAU + wo.y.atan2(wo.x);
                Vec3::new(sin * phi.cos(), sin * phi.sin(), cos)
            }
            _ => square_to_cosine_hemisphere(u),
        };
        sample_from_pdf(self, ctx, wo, wi)
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags::DIFFUSE_REFLECTION | BsdfFlags::GLOSSY_REFLECTION
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "measured";
pub const FILE: &str = "file";

static PARAMS: &[ParamSpec] = &[ParamSpec {
    name: FILE,
    kind: ParamKind::Path,
    unit: "",
    description: "MERL .binary file of the measured BRDF, relative to the scene file",
}];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let path = params.path(FILE)?;
    let table = MerlTable::read(&path).map_err(|e| {
        PluginError::Invalid(format!("{}: `{}`: {e}", params.plugin(), path.display()))
    })?;
    Ok(Arc::new(Measured::new(table)))
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "isotropic measured BRDF (MERL format), interpolated and importance sampled from tables",
        params: PARAMS,
        create,
    }
}
