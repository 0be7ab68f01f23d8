//! The paper's second-order sums (Lu, Pacanowski and Granier 2013): Î₁ and Î₂ over samples
//! drawn at α = ½, gathered by an observer in lanes ([`SecondOrderMoments`]), and the α̂ they
//! give ([`second_order_alpha`]). Used by `alpha` on each shading point's first phase and by
//! `pooled_alpha` on its pilot; docs/integrators.md derives them.

use crate::estimator::SampleRecord;
use crate::phase::{Observer, Phase};
use lumis_core::math::lanes::{LaneKernel, Lanes, MAX_WIDTH, Mask, V3, with_widest_lanes};
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
            match with_widest_lanes(BlockTerms { records: block }) {
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
/// the eight slots then sums at most eight terms in `f32`.
pub const BLOCK: usize = 64;

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
        // Record k is summed in slot k mod MAX_WIDTH whatever the width, and the slots in
        // order, so that four and eight lanes give the same bits.
        let mut sums = [(L::splat(0.0), L::splat(0.0)); MAX_WIDTH];
        let slots = MAX_WIDTH / W;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::SampleSplit;

    /// The moments of a synthetic integrand on [0, 1]: the concentrated density is a box of
    /// height k (width 1/k), the other is 1, and f follows the concentrated one. Half the
    /// samples come from each density (a stratified sample of p̄), as at α = ½.
    fn synthetic_moments(k: f32, concentrated_is_bsdf: bool) -> SecondOrderMoments {
        let mut moments = SecondOrderMoments::default();
        let n = 20_000;
        for i in 0..n {
            let u = (i as f32 + 0.5) / n as f32;
            for x in [u / k, u] {
                let p = if x < 1.0 / k { k } else { 0.0 };
                if concentrated_is_bsdf {
                    moments.add(p, p, 1.0);
                } else {
                    moments.add(p, 1.0, p);
                }
            }
        }
        moments
    }

    #[test]
    fn a_near_mirror_lobe_under_a_broad_light_gives_three_quarters() {
        // f concentrated where p_B is: the supplemental's §1.4 limit.
        let alpha = synthetic_moments(1e4, true).alpha([0.0, 1.0]);
        assert!((alpha - 0.75).abs() < 1e-3, "{alpha}");
    }

    #[test]
    fn a_tiny_light_over_a_broad_lobe_gives_one_quarter() {
        let alpha = synthetic_moments(1e4, false).alpha([0.0, 1.0]);
        assert!((alpha - 0.25).abs() < 1e-3, "{alpha}");
    }

    #[test]
    fn mirrors_give_three_quarters() {
        let mut moments = SecondOrderMoments::default();
        moments.add_dirac(0.8);
        assert_eq!(moments.alpha([0.0, 1.0]), 0.75);
    }

    /// Records of every kind: black, Dirac, lit with densities from 10⁻³ to 10³ (some BSDF
    /// samples the light cannot produce), integrands from 10⁻³ to 10³.
    fn varied_records(n: usize, seed: u64) -> Vec<SampleRecord> {
        let mut s = lumis_core::sampler::Sampler::new(seed, 1, 2);
        let spread = |s: &mut lumis_core::sampler::Sampler| 10f32.powf(6.0 * s.next_1d() - 3.0);
        (0..n)
            .map(|i| {
                let f = Rgb::new(spread(&mut s), spread(&mut s), spread(&mut s));
                match (i + 3) % 7 {
                    0 => SampleRecord::default(),
                    // Chosen among two lobes.
                    1 => SampleRecord {
                        f,
                        p_bsdf: 0.5,
                        p_light: 0.0,
                        delta: true,
                    },
                    2 => SampleRecord {
                        f,
                        p_bsdf: spread(&mut s),
                        p_light: 0.0,
                        delta: false,
                    },
                    _ => SampleRecord {
                        f,
                        p_bsdf: spread(&mut s),
                        p_light: spread(&mut s),
                        delta: false,
                    },
                }
            })
            .collect()
    }

    fn observed(records: &[SampleRecord]) -> SecondOrderMoments {
        let split = SampleSplit {
            n_bsdf: records.len() as u32,
            n_light: 0,
        };
        let mut moments = SecondOrderMoments::default();
        moments.observe(&Phase::of(split, records), &[]);
        moments
    }

    fn in_f64(records: &[SampleRecord]) -> SecondOrderMoments {
        let mut moments = SecondOrderMoments::default();
        records.iter().for_each(|r| moments.add_record(r));
        moments
    }

    #[test]
    fn the_lanes_sum_what_f64_sums_within_f32_rounding() {
        // Against the f64 sums of the same f32 inputs, a term q²r = f²Δp/p̄³ carries the
        // roundings of p̄ (three times, as p̄⁻³), 1/p̄ (three), q (two), Δp, r, q² and q²r: 12;
        // q²r² five more (Δp, p̄, 1/p̄ and r again, and the product): 17. A slot sums at most
        // BLOCK / 8 terms from zero: 7 roundings. So |error| ≤ ((1 + γ(n))(1 + γ(7)) − 1) ·
        // Σ|term|, n = 12 and 17 (pbrt-v4's γ(n) = nε/(1 − nε), ε = 2⁻²⁴).
        let gamma =
            |n: f64| n * f64::from(f32::EPSILON) / 2.0 / (1.0 - n * f64::from(f32::EPSILON) / 2.0);
        let sums = gamma((BLOCK / MAX_WIDTH - 1) as f64);
        let bound = |n: f64| (1.0 + gamma(n)) * (1.0 + sums) - 1.0;
        let (bound_i1, bound_i2) = (bound(12.0), bound(17.0));
        for n in [1, 7, 8, 9, 31, 64, 65, 150] {
            let records = varied_records(n, n as u64);
            let (lanes, exact) = (observed(&records), in_f64(&records));
            let mut absolute = SecondOrderMoments::default();
            for r in &records {
                let mut one = SecondOrderMoments::default();
                one.add_record(r);
                absolute.i1 += one.i1.abs();
                absolute.i2 += one.i2.abs();
            }
            assert!(exact.i2 > 0.0, "{n} records: some are lit");
            assert!(
                (lanes.i1 - exact.i1).abs() <= bound_i1 * absolute.i1,
                "{n}: I₁ {lanes:?} vs {exact:?}"
            );
            assert!(
                (lanes.i2 - exact.i2).abs() <= bound_i2 * absolute.i2,
                "{n}: I₂ {lanes:?} vs {exact:?}"
            );
        }
    }

    #[test]
    fn four_and_eight_lanes_give_the_same_bits() {
        let records = varied_records(150, 9);
        lumis_core::math::lanes::limit_width(4);
        let four = observed(&records);
        lumis_core::math::lanes::limit_width(MAX_WIDTH);
        let widest = observed(&records);
        assert_eq!(four.i1.to_bits(), widest.i1.to_bits());
        assert_eq!(four.i2.to_bits(), widest.i2.to_bits());
    }

    #[test]
    fn terms_beyond_the_range_of_f32_are_summed_in_f64() {
        let lit = |f: f32, p_bsdf: f32, p_light: f32| SampleRecord {
            f: Rgb::splat(f),
            p_bsdf,
            p_light,
            delta: false,
        };
        // q = f / p̄ ≈ 10³⁰: q² overflows f32. Then f = 10⁻²⁵: q² r² underflows it.
        for scale in [1e30, 1e-25] {
            let records: Vec<_> = (0..20)
                .map(|i| lit(scale * (1.0 + i as f32), 1.0 + (i % 3) as f32, 2.0))
                .collect();
            let (lanes, exact) = (observed(&records), in_f64(&records));
            assert_eq!(lanes, exact, "f scaled by {scale}");
            assert!(exact.i1.is_finite() && exact.i2 > 0.0, "{exact:?}");
            // α does not depend on the integrand's scale.
            let unscaled: Vec<_> = records
                .iter()
                .map(|r| lit(r.f.x / scale, r.p_bsdf, r.p_light))
                .collect();
            let alpha = observed(&unscaled).alpha([0.0, 1.0]);
            assert!(
                (lanes.alpha([0.0, 1.0]) - alpha).abs() < 1e-6,
                "f scaled by {scale}"
            );
        }
    }

    #[test]
    fn undefined_estimates_give_one_half_within_the_clamp() {
        assert_eq!(second_order_alpha(0.0, 0.0), None);
        assert_eq!(second_order_alpha(1.0, f64::INFINITY), None);
        // p_B = p_L everywhere: Δp = 0, I₂ = 0, so α is undefined (the integrator uses ½).
        let mut moments = SecondOrderMoments::default();
        for i in 0..100 {
            moments.add(1.0 + i as f32, 2.0, 2.0);
        }
        assert_eq!(second_order_alpha(moments.i1, moments.i2), None);
        assert_eq!(moments.alpha([0.025, 0.975]), 0.5);
        assert_eq!(moments.alpha([0.6, 0.9]), 0.6);
    }
}
