//! `diffuse`: Lambertian reflection, sampled with the cosine-weighted hemisphere.
//!
//! Parameters:
//! - `reflectance` (rgb, default (0.5, 0.5, 0.5), dimensionless, each channel in [0, 1]): the
//!   albedo, the fraction of incident light reflected.
//!
//! One-sided in the shading frame: directions below the shading horizon get zero.

use glam::{Vec2, Vec3};
use lumis_core::bsdf::{
    Bsdf, BsdfFlags, BsdfLanes, BsdfSample, BsdfSampleLanes, eval_pdf_in_lanes, sample_in_lanes,
};
use lumis_core::math::Rgb;
use lumis_core::math::lanes::{Lanes, V3};
use lumis_core::math::warp::{cosine_hemisphere_pdf_lanes, square_to_cosine_hemisphere_lanes};
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

impl BsdfLanes for Diffuse {
    /// `eval` and `pdf` in each lane: the one formula of the scalar and the batch methods.
    #[inline(always)]
    fn eval_pdf_lanes<L: Lanes>(&self, wo: V3<L>, wi: V3<L>) -> (V3<L>, L) {
        let zero = L::splat(0.0);
        let below = wo.z.le(zero);
        let value = V3::splat(self.reflectance) * (L::splat(FRAC_1_PI) * wi.z);
        (
            V3::select(below | wi.z.le(zero), V3::zero(), value),
            L::select(below, zero, cosine_hemisphere_pdf_lanes(wi.z)),
        )
    }

    /// `sample` in each lane (one lobe: `u_lobe` is not used).
    #[inline(always)]
    fn sample_lanes<L: Lanes>(
        &self,
        wo: V3<L>,
        _u_lobe: L,
        (u0, u1): (L, L),
    ) -> BsdfSampleLanes<L> {
        let zero = L::splat(0.0);
        let wi = square_to_cosine_hemisphere_lanes(u0, u1);
        let pdf = cosine_hemisphere_pdf_lanes(wi.z);
        BsdfSampleLanes {
            valid: !wo.z.le(zero) & pdf.gt(zero),
            wi,
            pdf,
            weight: V3::splat(self.reflectance),
        }
    }
}

impl Bsdf for Diffuse {
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.eval_pdf(wo, wi).0
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        let (value, pdf) = self.eval_pdf_lanes::<f32>(V3::splat(wo), V3::splat(wi));
        (value.lane(0), pdf)
    }

    fn sample(&self, wo: Vec3, _u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        self.sample_lanes::<f32>(V3::splat(wo), 0.0, (u.x, u.y))
            .lane(0)
    }

    fn eval_pdf_batch(&self, wo: &[Vec3], wi: &[Vec3], out: &mut [(Rgb, f32)]) {
        eval_pdf_in_lanes(self, wo, wi, out);
    }

    fn sample_batch(&self, wo: &[Vec3], u: &[(f32, Vec2)], out: &mut [Option<BsdfSample>]) {
        sample_in_lanes(self, wo, u, out);
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            diffuse: true,
            glossy: false,
            delta: false,
        }
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "diffuse";
pub const REFLECTANCE: &str = "reflectance";

static PARAMS: &[ParamSpec] = &[ParamSpec {
    name: REFLECTANCE,
    kind: ParamKind::Rgb {
        default: Some([0.5, 0.5, 0.5]),
        max: 1.0,
    },
    unit: "",
    description: "albedo: fraction of incident light reflected, per channel, in [0, 1]",
}];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let reflectance = params.rgb(REFLECTANCE)?;
    Ok(Arc::new(Diffuse::new(reflectance)))
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "Lambertian reflection with cosine-weighted sampling",
        params: PARAMS,
        create,
    }
}
