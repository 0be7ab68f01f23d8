//! `diffuse`: Lambertian reflection, sampled with the cosine-weighted hemisphere.
//!
//! Parameters:
//! - `reflectance` (rgb, default (0.5, 0.5, 0.5), dimensionless, each channel in [0, 1]): the
//!   albedo, the fraction of incident light reflected.
//!
//! One-sided in the shading frame: directions below the shading horizon get zero.

use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfFlags, BsdfSample};
use lumis_core::math::Rgb;
use lumis_core::math::warp::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use std::f32::consts::FRAC_1_PI;
use std::sync::Arc;

pub struct Diffuse {
    reflectance: Rgb,
}

impl Diffuse {
    pub fn new(reflectance: Rgb) -> Self {
        Diffuse { reflectance }
    }
}

impl Bsdf for Diffuse {
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        self.reflectance * (FRAC_1_PI * wi.z)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 {
            0.0
        } else {
            cosine_hemisphere_pdf(wi.z)
        }
    }

    fn sample(&self, wo: Vec3, _u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = square_to_cosine_hemisphere(u);
        let pdf = cosine_hemisphere_pdf(wi.z);
        (pdf > 0.0).then_some(BsdfSample {
            wi,
            pdf,
            weight: self.reflectance,
            delta: false,
        })
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            diffuse: true,
            glossy: false,
            delta: false,
        }
    }
}

static PARAMS: &[ParamSpec] = &[ParamSpec {
    name: "reflectance",
    kind: ParamKind::Rgb {
        default: Some([0.5, 0.5, 0.5]),
        max: 1.0,
    },
    unit: "",
    description: "albedo: fraction of incident light reflected, per channel, in [0, 1]",
}];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let reflectance = params.rgb("reflectance")?;
    Ok(Arc::new(Diffuse::new(reflectance)))
}

inventory::submit! {
    BsdfPlugin {
        name: "diffuse",
        description: "Lambertian reflection with cosine-weighted sampling",
        params: PARAMS,
        create,
    }
}
