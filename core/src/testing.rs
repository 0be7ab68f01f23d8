//! BSDFs for tests of the interface itself, not for scenes: a transmitting BSDF (the
//! chi-square harness's full-sphere densities, the shading point's transmission path) and a
//! BSDF made of two nested ones chosen by side (the registry's nested BSDFs and the context's
//! side). Tests register them as plugins with [`register_test_bsdfs`], as a run-time library
//! would; no built-in scene can name them.

use crate::bsdf::{
    Bsdf, BsdfContext, BsdfContextLanes, BsdfFlags, BsdfLanes, BsdfSample, BsdfSampleLanes, Side,
};
use crate::math::Rgb;
use crate::math::lanes::{Lanes, V3};
use crate::math::warp::square_to_cosine_hemisphere_lanes;
use crate::params::{ParamKind, ParamSpec, Params, PluginError};
use crate::registry::{BsdfPlugin, register_bsdfs};
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;
use std::sync::{Arc, OnceLock};

/// Rough diffuse transmission: Lambertian reflection of albedo `reflectance` on the viewer's
/// side, Lambertian transmission of `transmittance` on the far side. It samples the far side's
/// cosine lobe with probability `p_transmit`, the near side's otherwise, so that the density is
/// (1 − p) cos θ/π above the horizon and p |cos θ|/π below. η = 1: it does not bend light (a
/// thin rough sheet), and it is reciprocal. Written over lanes, so that its batches are tested
/// as the built-ins' are.
pub struct DiffuseTransmitter {
    pub reflectance: Rgb,
    pub transmittance: Rgb,
    pub p_transmit: f32,
}

impl BsdfLanes for DiffuseTransmitter {
    type Params<L: Lanes> = ();

    const READS_CONTEXT: bool = false;

    fn bsdf_flags(&self) -> BsdfFlags {
        BsdfFlags::DIFFUSE_REFLECTION | BsdfFlags::DIFFUSE_TRANSMISSION
    }

    #[inline(always)]
    fn params_lanes<L: Lanes>(&self, _ctx: &BsdfContextLanes<L>) {}

    #[inline(always)]
    fn eval_pdf_lanes<L: Lanes>(
        &self,
        _params: &(),
        _ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        wi: V3<L>,
    ) -> (V3<L>, L) {
        let zero = L::splat(0.0);
        let (up, down) = (wi.z.gt(zero), wi.z.lt(zero));
        let viewer_above = wo.z.gt(zero);
        let cos = wi.z.abs() * L::splat(FRAC_1_PI);
        let albedo = V3::select(
            up,
            V3::splat(self.reflectance),
            V3::select(down, V3::splat(self.transmittance), V3::zero()),
        );
        let p = L::splat(self.p_transmit);
        let probability = L::select(up, L::splat(1.0) - p, L::select(down, p, zero));
        (
            V3::select(viewer_above, albedo * cos, V3::zero()),
            L::select(viewer_above, probability * cos, zero),
        )
    }

    #[inline(always)]
    fn sample_lanes<L: Lanes>(
        &self,
        params: &(),
        ctx: &BsdfContextLanes<L>,
        wo: V3<L>,
        u_lobe: L,
        (u0, u1): (L, L),
    ) -> BsdfSampleLanes<L> {
        let mut wi = square_to_cosine_hemisphere_lanes(u0, u1);
        let through = u_lobe.lt(L::splat(self.p_transmit));
        wi.z = L::select(through, -wi.z, wi.z);
        let viewer_above = wo.z.gt(L::splat(0.0));
        BsdfSampleLanes::from_pdf(viewer_above, wi, self.eval_pdf_lanes(params, ctx, wo, wi))
    }
}

/// One BSDF seen from the front and another from the back, chosen by [`BsdfContext::side`]:
/// the smallest BSDF with nested BSDFs (Mitsuba's `twosided` with two, the materials' to
/// write), written the scalar way (the batch methods are the interface's defaults).
pub struct BySide {
    pub front: Arc<dyn Bsdf>,
    pub back: Arc<dyn Bsdf>,
}

impl BySide {
    fn seen(&self, ctx: &BsdfContext) -> &dyn Bsdf {
        match ctx.side {
            Side::Front => self.front.as_ref(),
            Side::Back => self.back.as_ref(),
        }
    }
}

impl Bsdf for BySide {
    fn eval(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> Rgb {
        self.seen(ctx).eval(ctx, wo, wi)
    }

    fn pdf(&self, ctx: &BsdfContext, wo: Vec3, wi: Vec3) -> f32 {
        self.seen(ctx).pdf(ctx, wo, wi)
    }

    fn sample(&self, ctx: &BsdfContext, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        self.seen(ctx).sample(ctx, wo, u_lobe, u)
    }

    fn flags(&self) -> BsdfFlags {
        self.front.flags() | self.back.flags()
    }
}

/// The test plugins' names.
pub const TRANSMITTER: &str = "test_transmitter";
pub const BY_SIDE: &str = "test_by_side";

static TRANSMITTER_PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "reflectance",
        kind: ParamKind::Rgb {
            default: Some([0.3, 0.3, 0.3]),
            max: 1.0,
        },
        unit: "",
        description: "albedo of the reflection",
    },
    ParamSpec {
        name: "transmittance",
        kind: ParamKind::Rgb {
            default: Some([0.5, 0.5, 0.5]),
            max: 1.0,
        },
        unit: "",
        description: "albedo of the transmission",
    },
    ParamSpec {
        name: "p_transmit",
        kind: ParamKind::Float {
            default: Some(0.6),
            min: 0.01,
            max: 0.99,
        },
        unit: "",
        description: "probability of sampling the transmission",
    },
];

static BY_SIDE_PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "front",
        kind: ParamKind::Bsdf,
        unit: "",
        description: "the BSDF seen from the front",
    },
    ParamSpec {
        name: "back",
        kind: ParamKind::Bsdf,
        unit: "",
        description: "the BSDF seen from the back",
    },
];

fn create_transmitter(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    Ok(Arc::new(DiffuseTransmitter {
        reflectance: params.rgb("reflectance")?,
        transmittance: params.rgb("transmittance")?,
        p_transmit: params.float("p_transmit")?,
    }))
}

fn create_by_side(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    Ok(Arc::new(BySide {
        front: params.bsdf("front")?,
        back: params.bsdf("back")?,
    }))
}

static TEST_BSDFS: [BsdfPlugin; 2] = [
    BsdfPlugin {
        name: TRANSMITTER,
        description: "test only: Lambertian reflection and transmission",
        params: TRANSMITTER_PARAMS,
        create: create_transmitter,
    },
    BsdfPlugin {
        name: BY_SIDE,
        description: "test only: one nested BSDF from the front, another from the back",
        params: BY_SIDE_PARAMS,
        create: create_by_side,
    },
];

/// Registers the test plugins ([`TRANSMITTER`], [`BY_SIDE`]) once in this process.
///
/// # Panics
/// If another plugin already has one of their names.
pub fn register_test_bsdfs() {
    static REGISTERED: OnceLock<()> = OnceLock::new();
    REGISTERED.get_or_init(|| register_bsdfs(&TEST_BSDFS).expect("test BSDF names are free"));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chi2::{Chi2Test, FAMILY_FALSE_ALARM, sidak, test_bsdf, test_sampler};
    use std::f64::consts::TAU;

    fn transmitter() -> DiffuseTransmitter {
        DiffuseTransmitter {
            reflectance: Rgb::new(0.3, 0.2, 0.1),
            transmittance: Rgb::new(0.5, 0.6, 0.7),
            p_transmit: 0.6,
        }
    }

    /// ωo at cos θ (azimuth 30°).
    fn incident(cos: f32) -> Vec3 {
        let sin = (1.0 - cos * cos).sqrt();
        let (s, c) = 30f32.to_radians().sin_cos();
        Vec3::new(sin * c, sin * s, cos).normalize()
    }

    /// The chi-square harness over the whole sphere: a transmitter's reflected and transmitted
    /// samples against its density, at normal, oblique and grazing incidence, seen from either
    /// side (the context changes nothing for it); the same samples against a density that
    /// splits the lobes ½–½ instead of 0.4–0.6 fail.
    #[test]
    fn transmitted_samples_match_their_density_over_the_whole_sphere() {
        let bsdf = transmitter();
        let cases: Vec<(f32, BsdfContext)> = [1.0, 0.6, 0.01]
            .into_iter()
            .flat_map(|cos| [(cos, BsdfContext::FRONT), (cos, BsdfContext::BACK)])
            .collect();
        let alpha = sidak(FAMILY_FALSE_ALARM, cases.len());
        for (cos, ctx) in &cases {
            let test = Chi2Test {
                samples: 200_000,
                ..Chi2Test::default()
            };
            let outcome = test_bsdf(&bsdf, ctx, incident(*cos), &test);
            outcome.assert_passes(alpha, &format!("transmitter cos={cos} {:?}", ctx.side));
            assert!(
                (outcome.integral - 1.0).abs() < 1e-3,
                "{}",
                outcome.integral
            );
        }
        let wrong = DiffuseTransmitter {
            p_transmit: 0.5,
            ..transmitter()
        };
        let wo = incident(0.6);
        let test = Chi2Test {
            samples: 200_000,
            ..Chi2Test::default()
        };
        let outcome = test.run(
            |s| {
                let u_lobe = s.next_1d();
                bsdf.sample(&BsdfContext::FRONT, wo, u_lobe, s.next_2d())
                    .map(|b| b.wi)
            },
            |wi| wrong.pdf(&BsdfContext::FRONT, wo, wi) as f64,
        );
        assert!(outcome.p_value < 1e-6, "{}", outcome.p_value);
    }

    /// Every sample's weight is eval / pdf on both sides, a transmitted one is flagged as such
    /// (η 1), and the batch methods give what single calls give, with one context or one each.
    #[test]
    fn transmitted_samples_weigh_eval_over_pdf() {
        let bsdf = transmitter();
        let mut s = test_sampler(41);
        let (mut up, mut down) = (0, 0);
        let ctx = BsdfContext::FRONT;
        let mut numbers = Vec::new();
        for _ in 0..20_000 {
            let (u_lobe, u) = (s.next_1d(), s.next_2d());
            numbers.push((u_lobe, u));
            let wo = incident(0.2 + 0.8 * s.next_1d());
            let Some(smp) = bsdf.sample(&ctx, wo, u_lobe, u) else {
                continue;
            };
            let (value, pdf) = bsdf.eval_pdf(&ctx, wo, smp.wi);
            assert!((pdf - smp.pdf).abs() <= 1e-6 * pdf, "{pdf} {}", smp.pdf);
            let expected = value / pdf;
            assert!(
                (smp.weight - expected).abs().max_element() <= 1e-5,
                "{smp:?}"
            );
            assert_eq!(smp.transmission(), smp.wi.z < 0.0);
            assert!(smp.eta == 1.0 && !smp.delta);
            if smp.transmission() {
                down += 1;
                assert!((smp.weight - bsdf.transmittance / 0.6).abs().max_element() < 1e-5);
            } else {
                up += 1;
            }
        }
        // 60 % transmitted: a binomial count of 20 000 within ±5 σ (σ ≈ 69).
        assert!(
            (down as f64 - 12_000.0).abs() < 350.0 && up + down > 19_900,
            "{up} {down}"
        );
        let wo = incident(0.7);
        let contexts: Vec<BsdfContext> = (0..numbers.len())
            .map(|k| if k % 3 == 0 { BsdfContext::BACK } else { ctx })
            .collect();
        for ctx in [&contexts[..1], &contexts[..]] {
            let mut out = vec![None; numbers.len()];
            bsdf.sample_batch(ctx, &[wo], &numbers, &mut out);
            for (k, (&(u_lobe, u), batch)) in numbers.iter().zip(&out).enumerate() {
                let c = ctx[if ctx.len() == 1 { 0 } else { k }];
                assert_eq!(*batch, bsdf.sample(&c, wo, u_lobe, u));
            }
        }
    }

    /// A density that jumps at the horizon between two positive values (0.3 of the mass
    /// uniform above, 0.7 below), binned about a tilted axis so that the horizon crosses the
    /// bins: with the horizon given, the regions across it are refined and the test passes
    /// with the integral 1.
    #[test]
    fn densities_that_jump_at_the_horizon_are_integrated_across_it() {
        let sample = |s: &mut crate::sampler::Sampler| {
            let below = s.next_1d() < 0.7;
            let u = s.next_2d();
            let z = u.x;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = std::f32::consts::TAU * u.y;
            let z = if below { -z } else { z };
            Some(Vec3::new(r * phi.cos(), r * phi.sin(), z)).filter(|d| d.z != 0.0)
        };
        let pdf = |d: Vec3| {
            if d.z > 0.0 {
                0.3 / TAU
            } else if d.z < 0.0 {
                0.7 / TAU
            } else {
                0.0
            }
        };
        let test = Chi2Test {
            axis: Vec3::new(0.4, -0.3, 0.8).normalize(),
            samples: 200_000,
            horizon: Some(Vec3::Z),
            ..Chi2Test::default()
        };
        let outcome = test.run(sample, pdf);
        outcome.assert_passes(FAMILY_FALSE_ALARM, "jump at the horizon");
        assert!(
            (outcome.integral - 1.0).abs() < 1e-3,
            "{} ± {}",
            outcome.integral,
            outcome.integral_error
        );
    }

    /// The side chooses the nested BSDF.
    #[test]
    fn the_side_chooses_the_nested_bsdf() {
        let by_side = BySide {
            front: Arc::new(transmitter()),
            back: Arc::new(DiffuseTransmitter {
                reflectance: Rgb::ONE,
                ..transmitter()
            }),
        };
        let (wo, wi) = (incident(0.5), incident(0.8));
        let front = by_side.eval(&BsdfContext::FRONT, wo, wi);
        let back = by_side.eval(&BsdfContext::BACK, wo, wi);
        assert!((front.x / back.x - 0.3).abs() < 1e-6, "{front} {back}");
        assert!(by_side.flags().transmission());
    }
}
