//! `diffuse`: Lambertian reflection, sampled with the cosine-weighted hemisphere.
//!
//! Parameters:
//! - `reflectance` (rgb or texture, default (0.5, 0.5, 0.5), dimensionless, each channel in
//!   [0, 1]): the albedo, the fraction of incident light reflected; a texture written inline
//!   (`(type: "checkerboard", ...)`) makes it vary over the surface.
//!
//! Reflection only: directions below the shading horizon (`wi.z ≤ 0`) get zero.

use lumis_core::bsdf::{Bsdf, BsdfContextLanes, BsdfFlags, BsdfLanes, BsdfSampleLanes};
use lumis_core::math::Rgb;
use lumis_core::math::lanes::{Lanes, V3};
use lumis_core::math::warp::{cosine_hemisphere_pdf_lanes, square_to_cosine_hemisphere_lanes};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use lumis_core::texture::{RgbSource, Textured};
use std::f32::consts::FRAC_1_PI;
use std::sync::Arc;

/// Lambertian reflection of albedo `reflectance`: a constant (`Rgb`, the default) or a
/// texture ([`Textured`]).
pub struct Diffuse<R: RgbSource = Rgb> {
    reflectance: R,
}

impl<R: RgbSource> Diffuse<R> {
    pub fn new(reflectance: R) -> Self {
        Diffuse { reflectance }
    }
}

impl<R: RgbSource> BsdfLanes for Diffuse<R> {
    /// The reflectance at each lane's point.
    type Params<L: Lanes> = V3<L>;

    /// Only a textured reflectance reads the uv; the side is never read.
    const READS_CONTEXT: bool = R::MAY_VARY;

    fn bsdf_flags(&self) -> BsdfFlags {
        let varying = if self.reflectance.varies() {
            BsdfFlags::SPATIALLY_VARYING
        } else {
            BsdfFlags::NONE
        };
        BsdfFlags::DIFFUSE_REFLECTION | varying
    }

    #[inline(always)]
    fn params_lanes<L: Lanes>(&self, ctx: &BsdfContextLanes<L>) -> V3<L> {
        self.reflectance.at(ctx.uv)
    }

    /// `eval` and `pdf` in each lane: the one formula of the scalar and the batch methods.
    #[inline(always)]
    fn eval_pdf_lanes<L: Lanes>(
        &self,
        reflectance: &V3<L>,
        _ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        wi: V3<L>,
    ) -> (V3<L>, L) {
        let zero = L::splat(0.0);
        let below = wo.z.le(zero);
        let value = *reflectance * (L::splat(FRAC_1_PI) * wi.z);
        (
            V3::select(below | wi.z.le(zero), V3::zero(), value),
            L::select(below, zero, cosine_hemisphere_pdf_lanes(wi.z)),
        )
    }

    /// `sample` in each lane (one lobe: `u_lobe` is not used).
    #[inline(always)]
    fn sample_lanes<L: Lanes>(
        &self,
        reflectance: &V3<L>,
        _ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        _u_lobe: L,
        (u0, u1): (L, L),
    ) -> BsdfSampleLanes<L> {
        let zero = L::splat(0.0);
        let wi = square_to_cosine_hemisphere_lanes(u0, u1);
        let pdf = cosine_hemisphere_pdf_lanes(wi.z);
        BsdfSampleLanes::new(!wo.z.le(zero) & pdf.gt(zero), wi, pdf, *reflectance)
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "diffuse";
pub const REFLECTANCE: &str = "reflectance";

static PARAMS: &[ParamSpec] = &[ParamSpec {
    name: REFLECTANCE,
    kind: ParamKind::RgbOrTexture {
        default: Some([0.5, 0.5, 0.5]),
        max: 1.0,
    },
    unit: "",
    description: "albedo: fraction of incident light reflected, per channel, in [0, 1]; or a texture",
}];

/// A constant reflectance builds `Diffuse<Rgb>`, whose code is the untextured one.
fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    Ok(match params.rgb_or_texture(REFLECTANCE)? {
        Textured::Constant(reflectance) => Arc::new(Diffuse::new(reflectance)),
        textured => Arc::new(Diffuse::new(textured)),
    })
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "Lambertian reflection with cosine-weighted sampling",
        params: PARAMS,
        create,
    }
}
