//! `twosided`: one BSDF seen from the front of a surface and another from its back (Mitsuba
//! 3's `twosided`), or one BSDF seen the same from both.
//!
//! Parameters:
//! - `front` (bsdf, required): the BSDF of the side the surface's normal points to, the name of
//!   one of the scene's `bsdfs` or one written inline.
//! - `back` (bsdf, required only for a different back: absent, `front` is seen from both
//!   sides): the BSDF of the other side.
//!
//! Each side's BSDF is evaluated in the shading frame turned toward the viewer, as every lumis
//! BSDF is: a `bsdfs` entry is already seen the same from both sides unless it is
//! `one_sided: true`, so Mitsuba's `twosided` around one BSDF is that BSDF (the importer writes
//! it so). Reflection only, as Mitsuba requires: a nested BSDF that transmits is refused.

use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext, BsdfFlags, BsdfSample, Side};
use lumis_core::math::Rgb;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use std::sync::Arc;

/// A front and a back BSDF.
pub struct TwoSided {
    front: Arc<dyn Bsdf>,
    back: Arc<dyn Bsdf>,
}

impl TwoSided {
    /// The BSDF of the side `ctx` is seen from.
    fn side(&self, ctx: &BsdfContext) -> &dyn Bsdf {
        match ctx.side {
            Side::Front => self.front.as_ref(),
            Side::Back => self.back.as_ref(),
        }
    }

    /// The BSDF all of `ctx` is seen from, if they share a side.
    fn one_side(&self, ctx: &[BsdfContext]) -> Option<&dyn Bsdf> {
        let first = ctx.first()?.side;
        ctx.iter()
            .all(|c| c.side == first)
            .then(|| self.side(&ctx[0]))
    }
}

impl Bsdf for TwoSided {
    fn eval(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> Rgb {
        self.side(ctx).eval(ctx, wo, wi)
    }

    fn pdf(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> f32 {
        self.side(ctx).pdf(ctx, wo, wi)
    }

    fn eval_pdf(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        self.side(ctx).eval_pdf(ctx, wo, wi)
    }

    fn sample(&self, ctx: &BsdfContext, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        self.side(ctx).sample(ctx, wo, u_lobe, u)
    }

    fn flags(&self) -> BsdfFlags {
        self.front.flags() | self.back.flags()
    }

    /// One side's batch method when every element is seen from it (the samples of one shading
    /// point), else one call each.
    fn eval_pdf_batch(
        &self,
        ctx: &[BsdfContext],
        wo: &[Vec3],
        wi: &[Vec3],
        out: &mut [(Rgb, f32)],
    ) {
        match self.one_side(ctx) {
            Some(bsdf) => bsdf.eval_pdf_batch(ctx, wo, wi, out),
            None => {
                assert!(wi.len() == out.len() && ctx.len() == out.len());
                for (k, out) in out.iter_mut().enumerate() {
                    let wo = wo[if wo.len() == 1 { 0 } else { k }];
                    *out = self.eval_pdf(&ctx[k], wo, wi[k]);
                }
            }
        }
    }

    fn sample_batch(
        &self,
        ctx: &[BsdfContext],
        wo: &[Vec3],
        u: &[(f32, Vec2)],
        out: &mut [Option<BsdfSample>],
    ) {
        match self.one_side(ctx) {
            Some(bsdf) => bsdf.sample_batch(ctx, wo, u, out),
            None => {
                assert!(u.len() == out.len() && ctx.len() == out.len());
                for (k, out) in out.iter_mut().enumerate() {
                    let wo = wo[if wo.len() == 1 { 0 } else { k }];
                    *out = self.sample(&ctx[k], wo, u[k].0, u[k].1);
                }
            }
        }
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "twosided";
pub const FRONT: &str = "front";
pub const BACK: &str = "back";

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: FRONT,
        kind: ParamKind::Bsdf,
        unit: "",
        description: "the BSDF seen from the side the normal points to",
    },
    ParamSpec {
        name: BACK,
        kind: ParamKind::Bsdf,
        unit: "",
        description: "the BSDF seen from the other side (`front` when absent)",
    },
];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let front = params.bsdf(FRONT)?;
    let back = if params.is_given(BACK) {
        params.bsdf(BACK)?
    } else {
        front.clone()
    };
    for (name, bsdf) in [(FRONT, &front), (BACK, &back)] {
        if bsdf.flags().transmission() {
            return Err(PluginError::Invalid(format!(
                "parameter `{name}` of {}: a BSDF that transmits light is seen from both sides \
                 already; `twosided` takes reflecting BSDFs",
                params.plugin()
            )));
        }
    }
    Ok(Arc::new(TwoSided { front, back }))
}

inventory::submit! {
    BsdfPlugin {
        name: NAME,
        description: "a front and a back BSDF, chosen by the side the surface is seen from",
        params: PARAMS,
        create,
    }
}
