//! The paper's second-order sums (Lu, Pacanowski and Granier 2013): Î₁ and Î₂ over samples
//! drawn at α = ½, gathered by an observer in lanes ([`SecondOrderMoments`]), and the α̂ they
//! give ([`second_order_alpha`]). Used by `alpha` on each shading point's first phase and by
//! `pooled_alpha` on its pilot; docs/integrators.md derives them.

use crate::estimator::SampleRecord;
use crate::phase::{Observer, Phase};
use lumis_core::math::lanes::{LaneKernel, Lanes, Mask, V3, with_lanes_up_to_eight};
use lumis_core::math::{Rgb, luminance, luminance_lanes};

/// The paper's sums over samples drawn at α = ½ (a stratified sample of p̄): M·Î₁ = Σ f²Δp/p̄³
/// and M·Î₂ = Σ f²Δp²/p̄⁴, with f the luminance of the integrand, summed in f64. Samples with
/// f = 0 or p̄ not a positive finite number add nothing. A Dirac BSDF sample (p_B → ∞) adds the
/// limit of both terms, 4 (f/p_B)², which gives the supplemental's α = 3/4 for mirrors.
///
/// As an [`Observer`], it computes the terms of a phase in lanes, in `f32`, written as
/// q² r and q² r² with q = f/p̄ (the sample's estimate at α = ½) and r = Δp/p̄ in [−1, 1]; they
/// are summed in lanes over blocks of [`BLOCK`] records, whose sums join the f64 totals. A
/// block whose lane sums overflow, are not numbers, or are too small for `f32` to hold their
/// digits (Î₂'s below [`SMALLEST_LANE_SUM`]) is summed again record by record in f64
/// ([`add`](Self::add)), so the f64 range is kept.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SecondOrderMoments {
    pub i1: f64,
    pub i2: f64,
}

impl SecondOrderMoments {
    /// Adds one sample of scalar integrand `f` and densities `p_bsdf`, `p_light`.
    pub fn add(&mut self, f: f32, p_bsdf: f32, p_light: f32) {
        let (f, p_b, p_l) = (f as f64, p_bsdf as f64, p_light as f64);
        let p_bar = 0.5 * (p_b + p_l);
        // p̄ positive and finite in two comparisons (NaN fails both).
        if f == 0.0 || !(p_bar > 0.0 && p_bar < f64::INFINITY) {
            return;
        }
        let delta_p = 0.5 * (p_b - p_l);
        let f2 = f * f;
        self.i1 += f2 * delta_p / (p_bar * p_bar * p_bar);
        self.i2 += f2 * delta_p * delta_p / (p_bar * p_bar * p_bar * p_bar);
    }

    /// Adds one Dirac BSDF sample whose f / p_B is `weight` (luminance).
    pub fn add_dirac(&mut self, weight: f32) {
        let w = weight as f64;
        self.i1 += 4.0 * w * w;
        self.i2 += 4.0 * w * w;
    }

    /// α̂ = ½ + ¼ · Î₁/Î₂ clamped to `clamp`, or ½ when Î₂ is zero or not finite (no sample saw
    /// the light, or p_B = p_L everywhere).
    pub fn alpha(&self, clamp: [f64; 2]) -> f64 {
        second_order_alpha(self.i1, self.i2)
            .unwrap_or(0.5)
            .clamp(clamp[0], clamp[1])
    }

    /// Adds one record's terms in f64 (the lanes compute the same terms in `f32`).
    pub fn add_record(&mut self, record: &SampleRecord) {
        if record.is_black() {
            return;
        }
        if record.delta {
            self.add_dirac(luminance(record.f));
        } else {
            self.add(luminance(record.f), record.p_bsdf, record.p_light);
        }
    }
}

impl Observer for SecondOrderMoments {
    fn observe(&mut self, phase: &Phase, _contributions: &[Rgb]) {
        for block in phase.records.chunks(BLOCK) {
            match with_lanes_up_to_eight(BlockTerms { records: block }) {
                Some((i1, i2)) => {
                    self.i1 += i1;
                    self.i2 += i2;
                }
                None => block.iter().for_each(|r| self.add_record(r)),
            }
        }
    }
}

/// Records whose terms are summed in `f32` lanes before their sums join the f64 totals: each of
/// the [`SLOTS`] slots then sums at most eight terms in `f32`.
pub const BLOCK: usize = 64;

/// The slots a block's terms are summed in, record k in slot k mod `SLOTS`, whatever the lanes'
/// width (at most eight: [`with_lanes_up_to_eight`]).
pub const SLOTS: usize = 8;

/// The smallest sum of a block's Î₂ terms kept from the lanes: from about 10⁻³⁸ `f32` loses
/// digits, so a block of samples this dim (or with p_B = p_L everywhere, where Î₂ is 0) is
/// summed again in f64.
pub const SMALLEST_LANE_SUM: f64 = 1e-30;

/// The sums of the second-order terms of at most [`BLOCK`] records, in lanes, or `None` where
/// `f32` cannot hold them.
struct BlockTerms<'a> {
    records: &'a [SampleRecord],
}

impl LaneKernel for BlockTerms<'_> {
    type Output = Option<(f64, f64)>;

    #[inline(always)]
    fn run<L: Lanes, const W: usize>(self) -> Self::Output {
        // Record k is summed in slot k mod SLOTS whatever the width, and the slots in order,
        // so that four and eight lanes give the same bits; wider lanes could not keep it.
        const { assert!(W <= SLOTS, "at most SLOTS lanes") };
        let mut sums = [(L::splat(0.0), L::splat(0.0)); SLOTS];
        let slots = SLOTS / W;
        let mut lit = L::Mask::from_fn(|_| false);
        let groups = self.records.chunks_exact(W);
        let rest = groups.remainder();
        let full = groups.len();
        for (g, group) in groups.enumerate() {
            let group: &[SampleRecord; W] = group.try_into().expect("a group of W records");
            lit = lit | add_group_terms(&mut sums[g % slots], group);
        }
        if !rest.is_empty() {
            // Default records are black: they add zero.
            let mut padded = [SampleRecord::default(); W];
            padded[..rest.len()].copy_from_slice(rest);
            lit = lit | add_group_terms(&mut sums[full % slots], &padded);
        }
        let (mut i1, mut i2) = (0.0f64, 0.0f64);
        for (t1, t2) in &sums[..slots] {
            for i in 0..W {
                i1 += t1.lane(i) as f64;
                i2 += t2.lane(i) as f64;
            }
        }
        let held = i1.is_finite() && i2.is_finite() && (i2 >= SMALLEST_LANE_SUM || !lit.any());
        held.then_some((i1, i2))
    }
}

/// Adds the terms q² r and q² r² of W records to `sums` (zero where a record adds nothing), and
/// returns which lanes add something. (A function, not a closure: a closure left out of line
/// would not have the kernel's AVX2.)
#[inline(always)]
fn add_group_terms<L: Lanes, const W: usize>(
    sums: &mut (L, L),
    group: &[SampleRecord; W],
) -> L::Mask {
    let (zero, half, one) = (L::splat(0.0), L::splat(0.5), L::splat(1.0));
    let f = luminance_lanes(V3::<L>::from_fn(|i| group[i].f));
    let delta = L::Mask::from_fn(|i| group[i].delta);
    // Halves first: p_B + p_L may overflow where p̄ does not.
    let (p_bsdf, p_light) = (
        half * L::from_fn(|i| group[i].p_bsdf),
        half * L::from_fn(|i| group[i].p_light),
    );
    let (p_bar, delta_p) = (p_bsdf + p_light, p_bsdf - p_light);
    let p_bar_usable = p_bar.gt(zero) & p_bar.lt(L::splat(f32::INFINITY));
    // A Dirac sample needs no p̄.
    let adds = !f.eq(zero) & (delta | p_bar_usable);
    let inv_p_bar = one / p_bar;
    // A Dirac sample's limit: q = 2 f/p_B (its record's f is f/p_B), r = 1.
    let q = L::select(delta, L::splat(2.0) * f, f * inv_p_bar);
    let r = L::select(delta, one, delta_p * inv_p_bar);
    // Selected last: r is not a number where p̄ is 0.
    let t1 = q * q * r;
    let (t1, t2) = (L::select(adds, t1, zero), L::select(adds, t1 * r, zero));
    *sums = (sums.0 + t1, sums.1 + t2);
    adds
}

/// The unclamped second-order α from the sums of [`SecondOrderMoments`]: ½ + ¼ · I₁ / I₂, or
/// `None` when I₂ is zero or not finite.
pub fn second_order_alpha(i1: f64, i2: f64) -> Option<f64> {
    let ratio = i1 / i2;
    (i2 > 0.0 && i2.is_finite() && ratio.is_finite()).then_some(0.5 + 0.25 * ratio)
}
