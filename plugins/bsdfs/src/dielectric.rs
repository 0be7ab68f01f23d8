//! `dielectric`: a smooth interface between two dielectrics (glass, water), Mitsuba 3's
//! `dielectric`: specular reflection and refraction, chosen in proportion to the Fresnel
//! reflectance, both Dirac lobes.
//!
//! Parameters:
//! - `int_ior` (float or name, default 1.5046, bk7): index of refraction inside, on the side
//!   the surface's normal points away from (a sphere's inside); a number in [1e-6, 1e6] or one
//!   of Mitsuba's material names ("vacuum", "air", "water", "bk7", "diamond", …, `ior.rs`).
//! - `ext_ior` (float or name, default 1.000277, air): index of refraction outside.
//! - `specular_reflectance` (rgb or texture, default (1, 1, 1), in [0, 1]): factor of the
//!   reflected light (1 for physical realism).
//! - `specular_transmittance` (rgb or texture, default (1, 1, 1), in [0, 1]): factor of the
//!   transmitted light (1 for physical realism).
//!
//! Seen from outside (the context's side `Front`) light crosses into the inside, η = int_ior /
//! ext_ior; from inside the reverse. With cos θo = ωo·n and the Fresnel reflectance F (`ior.rs`),
//! `sample` reflects with probability F (weight `specular_reflectance`) and refracts with
//! probability 1 − F, ωi bent by Snell's law, weight `specular_transmittance` / η² (radiance is
//! compressed as it crosses: the interface's 1/η², core's `bsdf` module), η = η_i / η_o. Past
//! the critical angle F = 1: total internal reflection. `eval` and `pdf` are zero (Dirac
//! lobes): light sampling never reaches such a surface; paths reach lights through it by BSDF
//! sampling. At η = 1 (index-matched) F = 0 and light passes straight through.

use crate::ior::{self, EXT_IOR_SPEC, INT_IOR_SPEC, eta_seen_from};
use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext, BsdfFlags, BsdfSample};
use lumis_core::math::Rgb;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use lumis_core::texture::{RgbSource, Textured};
use std::sync::Arc;

/// A smooth dielectric interface of relative index `eta` (inside over outside).
pub struct Dielectric {
    eta: f32,
    reflectance: Textured<Rgb>,
    transmittance: Textured<Rgb>,
}

impl Dielectric {
    pub fn new(eta: f32, reflectance: Textured<Rgb>, transmittance: Textured<Rgb>) -> Self {
        Dielectric {
            eta,
            reflectance,
            transmittance,
        }
    }
}

impl Bsdf for Dielectric {
    fn eval(&self, _ctx: &BsdfContext, _wo: Vec3, _wi: Vec3) -> Rgb {
        Rgb::ZERO
    }

    fn pdf(&self, _ctx: &BsdfContext, _wo: Vec3, _wi: Vec3) -> f32 {
        0.0
    }

    fn sample(&self, ctx: &BsdfContext, wo: Vec3, u_lobe: f32, _u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 || !wo.is_finite() {
            return None;
        }
        let eta = eta_seen_from(ctx.side, self.eta);
        let (f, cos_t) = ior::fresnel(wo.z, eta);
        if u_lobe < f {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            let weight = self.reflectance.value_at(ctx.uv);
            return Some(BsdfSample::delta(wi, f, weight));
        }
        let wi = Vec3::new(-wo.x / eta, -wo.y / eta, cos_t);
        let weight = self.transmittance.value_at(ctx.uv) / (eta * eta);
        // A refraction too close to the horizon to leave it (cos θt rounds to 0) is no sample.
        (cos_t < 0.0 && weight.is_finite() && wi.is_finite())
            .then(|| BsdfSample::delta(wi, 1.0 - f, weight).with_eta(eta))
    }

    fn flags(&self) -> BsdfFlags {
        let varying = if self.reflectance.varies() || self.transmittance.varies() {
            BsdfFlags::SPATIALLY_VARYING
        } else {
            BsdfFlags::NONE
        };
        BsdfFlags::DELTA_REFLECTION | BsdfFlags::DELTA_TRANSMISSION | varying
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "dielectric";
pub const SPECULAR_REFLECTANCE: &str = "specular_reflectance";
pub const SPECULAR_TRANSMITTANCE: &str = "specular_transmittance";

/// `specular_reflectance`, shared with the other dielectrics.
pub const SPECULAR_REFLECTANCE_SPEC: ParamSpec = ParamSpec {
    name: SPECULAR_REFLECTANCE,
    kind: ParamKind::RgbOrTexture {
        default: Some([1.0, 1.0, 1.0]),
        max: 1.0,
    },
    unit: "",
    description: "factor of the reflected light, per channel in [0, 1] (1 for physical realism); or a texture",
};

/// `specular_transmittance`, shared with the other dielectrics.
pub const SPECULAR_TRANSMITTANCE_SPEC: ParamSpec = ParamSpec {
    name: SPECULAR_TRANSMITTANCE,
    kind: ParamKind::RgbOrTexture {
        default: Some([1.0, 1.0, 1.0]),
        max: 1.0,
    },
    unit: "",
    description: "factor of the transmitted light, per channel in [0, 1] (1 for physical realism); or a texture",
};

static PARAMS: &[ParamSpec] = &[
    INT_IOR_SPEC,
    EXT_IOR_SPEC,
    SPECULAR_REFLECTANCE_SPEC,
    SPECULAR_TRANSMITTANCE_SPEC,
];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let eta = ior::read_eta(params)?;
    let reflectance = params.rgb_or_texture(SPECULAR_REFLECTANCE)?;
    let transmittance = params.rgb_or_texture(SPECULAR_TRANSMITTANCE)?;
    Ok(Arc::new(Dielectric::new(eta, reflectance, transmittance)))
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "smooth dielectric interface (glass, water): Fresnel-weighted specular reflection and refraction",
        params: PARAMS,
        create,
    }
}
