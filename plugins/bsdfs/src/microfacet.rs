//! Microfacet distributions shared by the rough BSDFs (`glossy`, `roughconductor`,
//! `roughplastic`, and the rough dielectric): GGX (Trowbridge–Reitz) and Beckmann, isotropic,
//! written once over [`Lanes`] so that a BSDF's scalar and batch methods run the same
//! operations.
//!
//! For a distribution of roughness α ([`Microfacet`]):
//! - D(h), the density of microfacet normals h per unit projected area (∫ D(h) cos θh dωh = 1);
//! - Λ(ω), Smith's auxiliary function, from which G1(ω) = 1 / (1 + Λ(ω)) and the two forms of
//!   the masking-shadowing term G2 ([`Masking`]);
//! - the distribution of normals visible from ωo, D_ωo(h) = G1(ωo) max(0, ωo·h) D(h) / cos θo,
//!   its sampling ([`Microfacet::sample_visible_normal`]) and density
//!   ([`Microfacet::visible_normal_pdf`]), and the density of a direction reflected about such a
//!   normal, D_ωo(h) / (4 ωo·h) ([`Microfacet::reflection_pdf`]).
//!
//! GGX: D(h) = 1 / (π α² (tan²θ/α² + 1)² cos⁴θ) and Λ(ω) = (√(1 + α² tan²θ) − 1) / 2 (Walter et
//! al. 2007); visible normals sampled as Heitz (2018) does, exactly.
//!
//! Beckmann: D(h) = exp(−tan²θ / α²) / (π α² cos⁴θ) and Λ(ω) = (erf(a) − 1) / 2 +
//! exp(−a²) / (2 a √π), a = 1 / (α tan θ) (Walter et al. 2007), evaluated exactly (to f32
//! rounding), where Mitsuba 3 uses a rational fit of G1 (within 0.35 %): lumis' density is then
//! exactly that of its samples. Visible normals are sampled in slope space as Mitsuba 3 does
//! (Jakob 2014): the visible slope's marginal CDF, written in the erf domain, is inverted by
//! Newton's method, here safeguarded by bisection and run to convergence; the other slope is
//! normal. exp and log are libm's, one lane at a time (deterministic, so batches and scalar
//! calls still agree bit for bit).
//!
//! Roughness: a BSDF clamps α to at least [`MIN_ALPHA`], as Mitsuba does (a smooth surface is
//! the smooth BSDF's job).

use lumis_core::math::lanes::{Lanes, V3};
use std::f32::consts::PI;
use std::marker::PhantomData;

/// The smallest roughness α a rough BSDF uses (Mitsuba 3 clamps to the same).
pub const MIN_ALPHA: f32 = 1e-4;

/// 1/√π.
const FRAC_1_SQRT_PI: f32 = 0.564_189_6;

/// A normal distribution of microfacets: GGX or Beckmann. Its formulas take the roughness in
/// lanes ([`Microfacet`]); a rough BSDF is generic over it.
pub trait Distribution: Copy + Send + Sync + 'static {
    /// The name scene files give it (`distribution: "ggx"`).
    const NAME: &'static str;
    /// D(h), h a unit vector in the local frame; 0 for h on or below the surface.
    fn d<L: Lanes>(m: &Microfacet<Self, L>, h: V3<L>) -> L;
    /// Smith's Λ(ω), ω a unit vector (its side does not matter); infinite at grazing ω.
    fn lambda<L: Lanes>(m: &Microfacet<Self, L>, w: V3<L>) -> L;
    /// A normal drawn from the normals visible from `wo` (above the surface), with density
    /// [`Microfacet::visible_normal_pdf`], from the uniform numbers `u`.
    fn sample_visible_normal<L: Lanes>(m: &Microfacet<Self, L>, wo: V3<L>, u: (L, L)) -> V3<L>;
}

/// GGX (Trowbridge–Reitz).
#[derive(Clone, Copy, Debug, Default)]
pub struct Ggx;

/// Beckmann (Gaussian slopes), Mitsuba's default.
#[derive(Clone, Copy, Debug, Default)]
pub struct Beckmann;

/// A distribution of roughness α, in each lane.
#[derive(Clone, Copy, Debug)]
pub struct Microfacet<D, L> {
    alpha: L,
    /// α².
    alpha2: L,
    distribution: PhantomData<D>,
}

/// The form of Smith's masking-shadowing term G2(ωo, ωi).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Masking {
    /// 1 / (1 + Λ(ωo) + Λ(ωi)) (Heitz 2014; pbrt's).
    HeightCorrelated,
    /// G1(ωo) G1(ωi) = 1 / ((1 + Λ(ωo))(1 + Λ(ωi))) (Mitsuba 3's).
    Separable,
}

impl Masking {
    /// G2 from Λ(ωo) and Λ(ωi).
    #[inline(always)]
    pub fn g2<L: Lanes>(self, lambda_o: L, lambda_i: L) -> L {
        let one = L::splat(1.0);
        match self {
            Masking::HeightCorrelated => one / (one + lambda_o + lambda_i),
            Masking::Separable => one / ((one + lambda_o) * (one + lambda_i)),
        }
    }
}

/// `wo` reflected about the unit normal `h`.
#[inline(always)]
pub fn reflect<L: Lanes>(wo: V3<L>, h: V3<L>) -> V3<L> {
    h * (L::splat(2.0) * wo.dot(h)) - wo
}

impl<D: Distribution, L: Lanes> Microfacet<D, L> {
    /// Roughness α in each lane (α² computed in each).
    #[inline(always)]
    pub fn new(alpha: L) -> Self {
        Microfacet {
            alpha,
            alpha2: alpha * alpha,
            distribution: PhantomData,
        }
    }

    /// Roughness α in every lane (α² computed once).
    #[inline(always)]
    pub fn constant(alpha: f32) -> Self {
        Microfacet {
            alpha: L::splat(alpha),
            alpha2: L::splat(alpha * alpha),
            distribution: PhantomData,
        }
    }

    /// α.
    #[inline(always)]
    pub fn alpha(&self) -> L {
        self.alpha
    }

    /// D(h).
    #[inline(always)]
    pub fn d(&self, h: V3<L>) -> L {
        D::d(self, h)
    }

    /// Λ(ω).
    #[inline(always)]
    pub fn lambda(&self, w: V3<L>) -> L {
        D::lambda(self, w)
    }

    /// G1(ω) = 1 / (1 + Λ(ω)): the fraction of the microsurface seen from ω that is not
    /// masked (without the test that h faces ω, which the callers make).
    #[inline(always)]
    pub fn g1(&self, w: V3<L>) -> L {
        let one = L::splat(1.0);
        one / (one + self.lambda(w))
    }

    /// A normal visible from `wo` (`wo.z > 0`).
    #[inline(always)]
    pub fn sample_visible_normal(&self, wo: V3<L>, u: (L, L)) -> V3<L> {
        D::sample_visible_normal(self, wo, u)
    }

    /// The density of [`sample_visible_normal`](Self::sample_visible_normal),
    /// G1(ωo) max(0, ωo·h) D(h) / cos θo; 0 where it is not finite (grazing ωo).
    #[inline(always)]
    pub fn visible_normal_pdf(&self, wo: V3<L>, h: V3<L>) -> L {
        let zero = L::splat(0.0);
        let pdf = self.g1(wo) * wo.dot(h).max(zero) * self.d(h) / wo.z;
        L::select(pdf.is_finite(), pdf, zero)
    }

    /// The density of ωi = reflect(ωo, h) for h drawn by
    /// [`sample_visible_normal`](Self::sample_visible_normal), G1(ωo) D(h) / (4 cos θo),
    /// given D(h) and Λ(ωo) (which a BSDF shares with its value); 0 where it is not finite.
    #[inline(always)]
    pub fn reflection_pdf(wo: V3<L>, d: L, lambda_o: L) -> L {
        let one = L::splat(1.0);
        let pdf = (one / (one + lambda_o)) * d / (L::splat(4.0) * wo.z);
        L::select(pdf.is_finite(), pdf, L::splat(0.0))
    }
}

impl Distribution for Ggx {
    const NAME: &'static str = "ggx";

    #[inline(always)]
    fn d<L: Lanes>(m: &Microfacet<Self, L>, h: V3<L>) -> L {
        let a2 = m.alpha2;
        let cos2 = h.z * h.z;
        // (h.x² + h.y²)/α² + h.z², the form that keeps its precision for tiny α.
        let t = (h.x * h.x + h.y * h.y) / a2 + cos2;
        let d = L::splat(1.0) / (L::splat(PI) * a2 * t * t);
        L::select(h.z.le(L::splat(0.0)), L::splat(0.0), d)
    }

    #[inline(always)]
    fn lambda<L: Lanes>(m: &Microfacet<Self, L>, w: V3<L>) -> L {
        let cos2 = w.z * w.z;
        let tan2 = (w.x * w.x + w.y * w.y) / cos2;
        let lambda = ((L::splat(1.0) + m.alpha2 * tan2).sqrt() - L::splat(1.0)) * L::splat(0.5);
        L::select(cos2.eq(L::splat(0.0)), L::splat(f32::INFINITY), lambda)
    }

    /// Heitz 2018: the view direction stretched to the hemisphere configuration, a point of
    /// the projected disk warped toward its visible half, lifted and unstretched.
    #[inline(always)]
    fn sample_visible_normal<L: Lanes>(
        m: &Microfacet<Self, L>,
        wo: V3<L>,
        (u0, u1): (L, L),
    ) -> V3<L> {
        let (zero, one, alpha) = (L::splat(0.0), L::splat(1.0), m.alpha);
        let vh = V3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = V3::select(
            len2.gt(zero),
            V3::new(-vh.y, vh.x, zero) / len2.sqrt(),
            V3::splat(glam::Vec3::X),
        );
        let t2 = vh.cross(t1);
        let r = u0.sqrt();
        let (sin, cos) = (L::splat(2.0 * PI) * u1).sin_cos();
        let p1 = r * cos;
        let s = L::splat(0.5) * (one + vh.z);
        let p2 = (one - s) * (one - p1 * p1).max(zero).sqrt() + s * r * sin;
        let nh = t1 * p1 + t2 * p2 + vh * (one - p1 * p1 - p2 * p2).max(zero).sqrt();
        V3::new(alpha * nh.x, alpha * nh.y, nh.z.max(zero)).normalize()
    }
}

/// libm's exp in each lane.
#[inline(always)]
fn exp<L: Lanes>(x: L) -> L {
    L::from_fn(
        #[inline(always)]
        |i| x.lane(i).exp(),
    )
}

/// libm's natural logarithm in each lane.
#[inline(always)]
fn ln<L: Lanes>(x: L) -> L {
    L::from_fn(
        #[inline(always)]
        |i| x.lane(i).ln(),
    )
}

/// erfc(z) / exp(−z²) for z ≥ 0, with t = 1 / (1 + z/2): the Chebyshev fit of Numerical Recipes
/// (Press et al., `erfcc`), fractional error below 1.2·10⁻⁷ over z ≥ 0. Written so that the
/// tail's exp(−z²) can be applied by the caller (Λ needs erfc(a) beside exp(−a²)/a).
#[inline(always)]
fn erfc_scaled<L: Lanes>(t: L) -> L {
    let c = |x: f32| L::splat(x);
    let p = c(-1.265_512_2)
        + t * (c(1.000_023_7)
            + t * (c(0.374_091_96)
                + t * (c(0.096_784_18)
                    + t * (c(-0.186_288_06)
                        + t * (c(0.278_868_07)
                            + t * (c(-1.135_204)
                                + t * (c(1.488_515_9)
                                    + t * (c(-0.822_152_2) + t * c(0.170_872_77)))))))));
    t * exp(p)
}

/// erf(x): its Maclaurin series (to x¹³, within 2·10⁻⁸) for |x| < ½, else 1 − erfc(|x|) with
/// its sign from [`erfc_scaled`], to about 2·10⁻⁷ absolute.
#[inline(always)]
pub fn erf<L: Lanes>(x: L) -> L {
    let one = L::splat(1.0);
    let z = x.abs();
    let t = one / (one + L::splat(0.5) * z);
    let erfc = erfc_scaled(t) * exp(-(z * z));
    let tail = (one - erfc).copysign(x);
    // 2/√π Σ (−1)ⁿ x²ⁿ⁺¹ / (n! (2n + 1)).
    let x2 = x * x;
    let c = |v: f32| L::splat(v);
    let series = x
        * (c(std::f32::consts::FRAC_2_SQRT_PI)
            + x2 * (c(-0.376_126_4)
                + x2 * (c(0.112_837_91)
                    + x2 * (c(-0.026_866_17)
                        + x2 * (c(0.005_223_977_6)
                            + x2 * (c(-0.000_854_832_7) + x2 * c(0.000_120_553_3)))))));
    L::select(z.lt(L::splat(0.5)), series, tail)
}

/// The inverse of erf on (−1, 1), ±∞ at ±1: Giles' single-precision approximation ("Approximating
/// the erfinv function", GPU Computing Gems, 2011), about 3·10⁻⁷ relative.
#[inline(always)]
pub fn erfinv<L: Lanes>(x: L) -> L {
    let c = |v: f32| L::splat(v);
    let w = -ln((c(1.0) - x) * (c(1.0) + x));
    let central = w.lt(c(5.0));
    let wc = w - c(2.5);
    let pc = c(1.501_409_4)
        + wc * (c(0.246_640_73)
            + wc * (c(-0.004_177_681_6)
                + wc * (c(-0.001_253_725)
                    + wc * (c(0.000_218_580_87)
                        + wc * (c(-4.391_506_5e-6)
                            + wc * (c(-3.523_387_7e-6)
                                + wc * (c(3.432_739_4e-7) + wc * c(2.810_226_4e-8))))))));
    let wt = w.sqrt() - c(3.0);
    let pt = c(2.832_976_8)
        + wt * (c(1.001_674)
            + wt * (c(0.009_438_871)
                + wt * (c(-0.007_622_461_3)
                    + wt * (c(0.005_739_507_7)
                        + wt * (c(-0.003_673_428_4)
                            + wt * (c(0.001_349_343_2)
                                + wt * (c(0.000_100_950_56) + wt * c(-0.000_200_214_26))))))));
    let value = L::select(central, pc, pt) * x;
    L::select(x.abs().lt(c(1.0)), value, c(f32::INFINITY).copysign(x))
}

/// Newton steps of the Beckmann visible-slope inversion; with the bisection safeguard and the
/// starting point below, the residual is at f32 rounding after four for every incidence and
/// number tested (`beckmann_slope_inversion_converges` in the tests).
const BECKMANN_NEWTON_STEPS: usize = 6;

impl Distribution for Beckmann {
    const NAME: &'static str = "beckmann";

    #[inline(always)]
    fn d<L: Lanes>(m: &Microfacet<Self, L>, h: V3<L>) -> L {
        let zero = L::splat(0.0);
        let cos2 = h.z * h.z;
        let tan2_over_a2 = (h.x * h.x + h.y * h.y) / (m.alpha2 * cos2);
        let d = exp(-tan2_over_a2) / (L::splat(PI) * m.alpha2 * cos2 * cos2);
        // Grazing normals: exp underflows to 0 before cos⁴θ does, unless both do (0/0).
        L::select(h.z.le(zero) | !d.is_finite(), zero, d)
    }

    #[inline(always)]
    fn lambda<L: Lanes>(m: &Microfacet<Self, L>, w: V3<L>) -> L {
        let (zero, one) = (L::splat(0.0), L::splat(1.0));
        let sin2 = w.x * w.x + w.y * w.y;
        // a = 1 / (α tan θ) = |cos θ| / (α sin θ): ∞ at normal incidence (Λ = 0), 0 at grazing.
        let a = w.z.abs() / (m.alpha * sin2.sqrt());
        let t = one / (one + L::splat(0.5) * a);
        // Λ = (exp(−a²)/(a√π) − erfc(a)) / 2, with erfc(a) = exp(−a²) · erfc_scaled.
        let lambda =
            L::splat(0.5) * exp(-(a * a)) * (L::splat(FRAC_1_SQRT_PI) / a - erfc_scaled(t));
        let lambda = L::select(a.eq(zero), L::splat(f32::INFINITY), lambda.max(zero));
        L::select(sin2.eq(zero), zero, lambda)
    }

    /// In the configuration stretched to α = 1 with ωo at azimuth 0, visible slopes (x̃, ỹ)
    /// have density ∝ max(0, cot θ − x̃) exp(−x̃² − ỹ²): ỹ is normal, ỹ = erfinv(2u₁ − 1), and
    /// x̃'s CDF, times 2 / (√π cot θ) and written in e = erf(x̃), is
    /// g(e) = 1 + e + tan θ exp(−erfinv(e)²) / √π, increasing from g(−1) = 0 to
    /// g(erf(cot θ)), with g'(e) = 1 − x̃ tan θ. Newton's method solves g(e) = u₀ g(erf(cot θ))
    /// from the grazing-incidence solution e = erf(cot θ) − (1 + erf(cot θ)) erf(√(−ln u₀)),
    /// keeping a bracket and bisecting where a step leaves it. The slopes are then turned to
    /// ωo's azimuth and scaled by α.
    #[inline(always)]
    fn sample_visible_normal<L: Lanes>(
        m: &Microfacet<Self, L>,
        wo: V3<L>,
        (u0, u1): (L, L),
    ) -> V3<L> {
        let c = |v: f32| L::splat(v);
        let (zero, one) = (c(0.0), c(1.0));
        let alpha = m.alpha;
        let stretched = V3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
        let sin_theta = (stretched.x * stretched.x + stretched.y * stretched.y).sqrt();
        let cos_theta = stretched.z;
        let tan_theta = sin_theta / cos_theta;
        let cot_theta = cos_theta / sin_theta;
        let e_max = erf(cot_theta);
        // tan θ exp(−cot²θ) / √π: 0 at normal incidence (tan θ = 0, cot θ = ∞).
        let tail = L::select(
            sin_theta.eq(zero),
            zero,
            tan_theta * exp(-(cot_theta * cot_theta)) * c(FRAC_1_SQRT_PI),
        );
        let target = u0 * (one + e_max + tail);
        let mut e = e_max - (one + e_max) * erf((-ln(u0)).max(zero).sqrt());
        let (mut low, mut high) = (c(-1.0), e_max);
        for _ in 0..BECKMANN_NEWTON_STEPS {
            let slope = erfinv(e);
            let g = one + e + c(FRAC_1_SQRT_PI) * tan_theta * exp(-(slope * slope));
            let g = L::select(sin_theta.eq(zero), one + e, g);
            let residual = g - target;
            let above = residual.gt(zero);
            high = L::select(above, e, high);
            low = L::select(above, low, e);
            let derivative = L::select(sin_theta.eq(zero), one, one - slope * tan_theta);
            let newton = e - residual / derivative;
            // A step that stays in the bracket, its ends included (u₀ = 0 solves at e = −1).
            let inside = (newton.gt(low) | newton.eq(low)) & (newton.lt(high) | newton.eq(high));
            e = L::select(inside, newton, c(0.5) * (low + high));
        }
        // The open interval keeps both slopes finite (u₁ = 0 would give erfinv(−1) = −∞).
        let nearly_one = c(1.0 - f32::EPSILON / 2.0);
        let slope_x = erfinv(e.max(-nearly_one).min(nearly_one));
        let slope_y = erfinv((c(2.0) * u1 - one).max(-nearly_one));
        // Turned to ωo's azimuth (φ = 0 at normal incidence), unstretched.
        let has_azimuth = sin_theta.gt(zero);
        let cos_phi = L::select(has_azimuth, stretched.x / sin_theta, one);
        let sin_phi = L::select(has_azimuth, stretched.y / sin_theta, zero);
        let x = (cos_phi * slope_x - sin_phi * slope_y) * alpha;
        let y = (sin_phi * slope_x + cos_phi * slope_y) * alpha;
        V3::new(-x, -y, one).normalize()
    }
}
