//! `glossy`: GGX (Trowbridge–Reitz) microfacet reflection with Smith masking-shadowing and
//! Schlick's Fresnel, over an optional diffuse base.
//!
//! Parameters:
//! - `roughness` (float, default 0.1, in [0.0001, 1]): the GGX α (≈ the squared perceptual
//!   roughness).
//! - `specular` (rgb, default (0.04, 0.04, 0.04), in [0, 1]): F0, the reflectance at normal
//!   incidence.
//! - `diffuse` (rgb, default (0, 0, 0), in [0, 1]): albedo of the diffuse base layer.
//! - `masking` (choice, default `height_correlated`, or `separable`): the Smith masking-shadowing
//!   term G₂(ωo, ωi). `height_correlated` is 1 / (1 + Λ(ωo) + Λ(ωi)) (Heitz 2014, the more
//!   accurate, and pbrt-v3's and pbrt-v4's); `separable` is G₁(ωo) G₁(ωi) =
//!   1 / ((1 + Λ(ωo))(1 + Λ(ωi))), as Mitsuba 3's `roughconductor` uses. They agree at normal
//!   incidence; the separable term is smaller by the factor (1 + Λ(ωo) + Λ(ωi)) /
//!   ((1 + Λ(ωo))(1 + Λ(ωi))) toward grazing angles.
//!
//! The base is Ashikhmin and Shirley's (2000) energy-conserving diffuse term, reciprocal and
//! weighted by (1 − F0) so that specular plus diffuse never reflect more than arrives.
//! Sampling: the specular lobe by its distribution of visible normals (Heitz 2018), the base
//! with the cosine-weighted hemisphere, chosen in proportion to their estimated albedos for
//! the given ωo; `pdf` is exactly that mixture's density.

use glam::{Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfFlags, BsdfSample, sample_from_pdf};
use lumis_core::math::warp::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
use lumis_core::math::{Rgb, luminance};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::BsdfPlugin;
use std::f32::consts::PI;
use std::sync::Arc;

pub struct Glossy {
    alpha: f32,
    f0: Rgb,
    diffuse: Rgb,
    masking: Masking,
}

/// The form of Smith's masking-shadowing term G₂.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Masking {
    /// 1 / (1 + Λ(ωo) + Λ(ωi)).
    HeightCorrelated,
    /// G₁(ωo) G₁(ωi), Mitsuba 3's.
    Separable,
}

/// Schlick's approximation of the Fresnel reflectance.
fn schlick(f0: Rgb, cos: f32) -> Rgb {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m5 = (m * m) * (m * m) * m;
    f0 + (Rgb::ONE - f0) * m5
}

impl Glossy {
    pub fn new(alpha: f32, f0: Rgb, diffuse: Rgb, masking: Masking) -> Self {
        Glossy {
            alpha,
            f0,
            diffuse,
            masking,
        }
    }

    /// GGX normal distribution D(h), h in the local frame.
    fn d(&self, h: Vec3) -> f32 {
        if h.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let cos2 = h.z * h.z;
        // (h.x² + h.y²)/α² + h.z², the form that keeps its precision for tiny α.
        let t = (h.x * h.x + h.y * h.y) / a2 + cos2;
        1.0 / (PI * a2 * t * t)
    }

    /// Smith's Λ(w) for GGX.
    fn lambda(&self, w: Vec3) -> f32 {
        let cos2 = w.z * w.z;
        if cos2 == 0.0 {
            return f32::INFINITY;
        }
        let tan2 = (w.x * w.x + w.y * w.y) / cos2;
        ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0) * 0.5
    }

    /// Masking-shadowing G2(ωo, ωi), given Λ(ωo).
    fn g2(&self, lambda_o: f32, wi: Vec3) -> f32 {
        let li = self.lambda(wi);
        match self.masking {
            Masking::HeightCorrelated => 1.0 / (1.0 + lambda_o + li),
            Masking::Separable => 1.0 / ((1.0 + lambda_o) * (1.0 + li)),
        }
    }

    /// Probability of sampling the specular lobe for this ωo.
    fn specular_probability(&self, wo: Vec3) -> f32 {
        if self.diffuse == Rgb::ZERO {
            return 1.0;
        }
        let spec = luminance(schlick(self.f0, wo.z));
        let base = luminance(self.diffuse) * (1.0 - self.f0.max_element());
        (spec / (spec + base)).clamp(0.1, 0.9)
    }

    fn diffuse_term(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let fo = 1.0 - (1.0 - 0.5 * wo.z).powi(5);
        let fi = 1.0 - (1.0 - 0.5 * wi.z).powi(5);
        self.diffuse * (1.0 - self.f0.max_element()) * (28.0 / (23.0 * PI) * fo * fi)
    }

    /// The specular lobe's F D G2 / (4 cos θo cos θi) · cos θi at half vector h (h.z > 0), given
    /// D(h) and Λ(ωo); zero where it is not finite.
    fn specular_value(&self, wo: Vec3, wi: Vec3, h: Vec3, d: f32, lambda_o: f32) -> Rgb {
        let spec = schlick(self.f0, wo.dot(h)) * (d * self.g2(lambda_o, wi) / (4.0 * wo.z));
        if spec.is_finite() { spec } else { Rgb::ZERO }
    }

    /// The specular lobe's sampling density (VNDF: D_ωo(h) / (4 ωo·h) = G1(ωo) D(h) / (4 cos
    /// θo)) given D(h) and Λ(ωo); zero where it is not finite.
    fn specular_pdf(&self, wo: Vec3, d: f32, lambda_o: f32) -> f32 {
        let pdf = (1.0 / (1.0 + lambda_o)) * d / (4.0 * wo.z);
        if pdf.is_finite() { pdf } else { 0.0 }
    }

    /// The mixture density of the two lobes, given the specular one's.
    fn mixture_pdf(&self, wo: Vec3, wi: Vec3, specular_pdf: f32) -> f32 {
        let p = self.specular_probability(wo);
        p * specular_pdf + (1.0 - p) * cosine_hemisphere_pdf(wi.z)
    }

    /// The diffuse base's value · cos θi (zero without a base, at no cost).
    fn diffuse_value(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if self.diffuse == Rgb::ZERO {
            return Rgb::ZERO;
        }
        self.diffuse_term(wo, wi) * wi.z
    }

    /// Heitz 2018: a visible normal for ωo.
    fn sample_visible_normal(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let vh = Vec3::new(self.alpha * wo.x, self.alpha * wo.y, wo.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 {
            Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        Vec3::new(self.alpha * nh.x, self.alpha * nh.y, nh.z.max(0.0)).normalize()
    }
}

impl Bsdf for Glossy {
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        let h = (wo + wi).normalize_or_zero();
        let f = self.diffuse_value(wo, wi);
        if h.z <= 0.0 {
            return f;
        }
        f + self.specular_value(wo, wi, h, self.d(h), self.lambda(wo))
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize_or_zero();
        let specular_pdf = if h.z > 0.0 {
            self.specular_pdf(wo, self.d(h), self.lambda(wo))
        } else {
            0.0
        };
        self.mixture_pdf(wo, wi, specular_pdf)
    }

    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let h = (wo + wi).normalize_or_zero();
        let f = self.diffuse_value(wo, wi);
        if h.z <= 0.0 {
            return (f, self.mixture_pdf(wo, wi, 0.0));
        }
        let (d, lambda_o) = (self.d(h), self.lambda(wo));
        (
            f + self.specular_value(wo, wi, h, d, lambda_o),
            self.mixture_pdf(wo, wi, self.specular_pdf(wo, d, lambda_o)),
        )
    }

    fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = if u_lobe < self.specular_probability(wo) {
            let h = self.sample_visible_normal(wo, u);
            2.0 * wo.dot(h) * h - wo
        } else {
            square_to_cosine_hemisphere(u)
        };
        sample_from_pdf(self, wo, wi)
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            diffuse: self.diffuse != Rgb::ZERO,
            glossy: true,
            delta: false,
        }
    }
}

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "roughness",
        kind: ParamKind::Float {
            default: Some(0.1),
            min: 1e-4,
            max: 1.0,
        },
        unit: "",
        description: "GGX α: width of the microfacet distribution",
    },
    ParamSpec {
        name: "specular",
        kind: ParamKind::Rgb {
            default: Some([0.04, 0.04, 0.04]),
            max: 1.0,
        },
        unit: "",
        description: "F0, Fresnel reflectance at normal incidence (Schlick), per channel in [0, 1]",
    },
    ParamSpec {
        name: "diffuse",
        kind: ParamKind::Rgb {
            default: Some([0.0, 0.0, 0.0]),
            max: 1.0,
        },
        unit: "",
        description: "albedo of the diffuse base layer, per channel in [0, 1]",
    },
    ParamSpec {
        name: "masking",
        kind: ParamKind::Choice {
            options: &["height_correlated", "separable"],
            default: "height_correlated",
        },
        unit: "",
        description: "Smith masking-shadowing G2: height-correlated (as pbrt), or separable G1·G1 (as Mitsuba 3)",
    },
];

fn create(params: &mut Params) -> Result<Arc<dyn Bsdf>, PluginError> {
    let alpha = params.float("roughness")?;
    let f0 = params.rgb("specular")?;
    let diffuse = params.rgb("diffuse")?;
    let masking = match params.choice("masking")? {
        "separable" => Masking::Separable,
        _ => Masking::HeightCorrelated,
    };
    Ok(Arc::new(Glossy::new(alpha, f0, diffuse, masking)))
}

inventory::submit! {
    BsdfPlugin {
        name: "glossy",
        description: "GGX microfacet reflection (visible-normal sampling) over an optional diffuse base",
        params: PARAMS,
        create,
    }
}
