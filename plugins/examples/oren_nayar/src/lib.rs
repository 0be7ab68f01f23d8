//! `oren_nayar`: rough diffuse reflection (Oren and Nayar 1994, the qualitative model), shipped as
//! a run-time plugin library to show how third parties extend lumis without rebuilding it.
//!
//! Parameters:
//! - `reflectance` (rgb or texture, default (0.5, 0.5, 0.5), in [0, 1]): albedo of the facets;
//!   a texture written inline makes it vary over the surface.
//! - `sigma` (float, default 20, degrees, in [0, 90]): standard deviation of the facet slopes;
//!   0 is Lambertian.
//!
//! Sampling: cosine-weighted hemisphere. Written the simple scalar way (`eval`, `pdf`,
//! `sample`; the batch methods are the interface's defaults), reading its reflectance at the
//! shading point's texture coordinates. Build with `cargo build -p lumis-oren-nayar` and list
//! the resulting `liblumis_oren_nayar.so` under a scene's `plugins`.

use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext, BsdfFlags, BsdfSample, sample_from_pdf};
use lumis_core::math::Rgb;
use lumis_core::math::warp::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use lumis_core::texture::{RgbSource, Textured};
use std::f32::consts::FRAC_1_PI;
use std::sync::Arc;

pub struct OrenNayar {
    reflectance: Textured<Rgb>,
    a: f32,
    b: f32,
}

impl OrenNayar {
    pub fn new(reflectance: Textured<Rgb>, sigma_degrees: f32) -> Self {
        let s2 = sigma_degrees.to_radians().powi(2);
        OrenNayar {
            reflectance,
            a: 1.0 - s2 / (2.0 * (s2 + 0.33)),
            b: 0.45 * s2 / (s2 + 0.09),
        }
    }
}

impl Bsdf for OrenNayar {
    fn eval(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        let sin_o = (1.0 - wo.z * wo.z).max(0.0).sqrt();
        let sin_i = (1.0 - wi.z * wi.z).max(0.0).sqrt();
        // cos(φi − φo) from the projections on the tangent plane.
        let cos_dphi = if sin_o > 1e-6 && sin_i > 1e-6 {
            ((wo.x * wi.x + wo.y * wi.y) / (sin_o * sin_i)).clamp(-1.0, 1.0)
        } else {
            0.0
        };
        // sin α tan β with α = max(θi, θo), β = min(θi, θo).
        let (sin_alpha, tan_beta) = if wi.z > wo.z {
            (sin_o, sin_i / wi.z)
        } else {
            (sin_i, sin_o / wo.z)
        };
        let f = self.a + self.b * cos_dphi.max(0.0) * sin_alpha * tan_beta;
        self.reflectance.value_at(ctx.uv) * (FRAC_1_PI * f * wi.z)
    }

    fn pdf(&self, _ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 {
            0.0
        } else {
            cosine_hemisphere_pdf(wi.z)
        }
    }

    fn sample(&self, ctx: &BsdfContext, wo: Vec3, _u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        sample_from_pdf(self, ctx, wo, square_to_cosine_hemisphere(u))
    }

    /// Its texture, if it has one, makes it vary over the surface (the scene loader would add
    /// the flag for a texture it handed out; saying it here keeps the BSDF right on its own).
    fn flags(&self) -> BsdfFlags {
        if self.reflectance.varies() {
            BsdfFlags::DIFFUSE_REFLECTION | BsdfFlags::SPATIALLY_VARYING
        } else {
            BsdfFlags::DIFFUSE_REFLECTION
        }
    }
}

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "reflectance",
        kind: ParamKind::RgbOrTexture {
            default: Some([0.5, 0.5, 0.5]),
            max: 1.0,
        },
        unit: "",
        description: "albedo of the facets, per channel in [0, 1], or a texture",
    },
    ParamSpec {
        name: "sigma",
        kind: ParamKind::Float {
            default: Some(20.0),
            min: 0.0,
            max: 90.0,
        },
        unit: "degrees",
        description: "standard deviation of the facet slopes (0: Lambertian)",
    },
];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    Ok(Arc::new(OrenNayar::new(
        params.rgb_or_texture("reflectance")?,
        params.float("sigma")?,
    )))
}

pub const OREN_NAYAR: BsdfPlugin = BsdfPlugin {
    name: "oren_nayar",
    description: "rough diffuse reflection (Oren-Nayar), from a run-time plugin library",
    params: PARAMS,
    create,
};

lumis_core::declare_plugin_library!(bsdfs: [OREN_NAYAR]);
