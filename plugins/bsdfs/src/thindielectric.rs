//! `thindielectric`: a thin dielectric sheet (a window pane modelled as one surface), Mitsuba 3's
//! `thindielectric`: light is reflected specularly or passes straight through, undeflected, with
//! the sheet's internal reflections summed in closed form.
//!
//! Parameters:
//! - `int_ior` (float or name, default 1.5046, bk7): index of refraction of the sheet; a number
//!   in [1e-6, 1e6] or one of Mitsuba's material names (`ior.rs`).
//! - `ext_ior` (float or name, default 1.000277, air): index of refraction around it.
//! - `specular_reflectance` (rgb or texture, default (1, 1, 1), in [0, 1]): factor of the
//!   reflected light (1 for physical realism).
//! - `specular_transmittance` (rgb or texture, default (1, 1, 1), in [0, 1]): factor of the
//!   transmitted light (1 for physical realism).
//!
//! With F the Fresnel reflectance of one face at cos θo (η = int_ior / ext_ior, the same from
//! either side: the sheet has the same medium on both), the sheet reflects R = F + T²F Σ F²ᵏ
//! = 2F / (1 + F) of the light (paths R, TRT, TR³T, …) and transmits 1 − R. `sample` reflects
//! with probability R (weight `specular_reflectance`) and transmits along −ωo with probability
//! 1 − R (weight `specular_transmittance`, η = 1: the sheet's two faces undo each other's
//! bending and radiance compression). Both lobes are Dirac: `eval` and `pdf` are zero.

use crate::dielectric::{
    SPECULAR_REFLECTANCE, SPECULAR_REFLECTANCE_SPEC, SPECULAR_TRANSMITTANCE,
    SPECULAR_TRANSMITTANCE_SPEC,
};
use crate::ior::{self, EXT_IOR_SPEC, INT_IOR_SPEC};
use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext, BsdfFlags, BsdfSample};
use lumis_core::math::Rgb;
use lumis_core::params::{ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use lumis_core::texture::{RgbSource, Textured};
use std::sync::Arc;

/// A thin sheet of relative index `eta`.
pub struct ThinDielectric {
    eta: f32,
    reflectance: Textured<Rgb>,
    transmittance: Textured<Rgb>,
}

impl ThinDielectric {
    /// The fraction of light the sheet reflects at cos θo = `cos_o`, its internal reflections
    /// included.
    pub fn reflectance(&self, cos_o: f32) -> f32 {
        let (f, _) = ior::fresnel(cos_o, self.eta);
        2.0 * f / (1.0 + f)
    }
}

impl Bsdf for ThinDielectric {
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
        let r = self.reflectance(wo.z);
        if u_lobe < r {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            return Some(BsdfSample::delta(wi, r, self.reflectance.value_at(ctx.uv)));
        }
        Some(BsdfSample::delta(
            -wo,
            1.0 - r,
            self.transmittance.value_at(ctx.uv),
        ))
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

/// The plugin's name in scene files.
pub const NAME: &str = "thindielectric";

static PARAMS: &[ParamSpec] = &[
    INT_IOR_SPEC,
    EXT_IOR_SPEC,
    SPECULAR_REFLECTANCE_SPEC,
    SPECULAR_TRANSMITTANCE_SPEC,
];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let eta = ior::read_eta(params)?;
    Ok(Arc::new(ThinDielectric {
        eta,
        reflectance: params.rgb_or_texture(SPECULAR_REFLECTANCE)?,
        transmittance: params.rgb_or_texture(SPECULAR_TRANSMITTANCE)?,
    }))
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "thin dielectric sheet (a window pane): specular reflection and undeflected transmission, internal reflections included",
        params: PARAMS,
        create,
    }
}
