//! MIS weighting: how one phase's samples of one light are combined into an estimate.
//!
//! With counts n_B, n_L and densities p_B, p_L, the multi-sample MIS estimate is
//!
//! ```text
//!   L̂ = Σ_{BSDF samples} w_B f / (n_B p_B) + Σ_{light samples} w_L f / (n_L p_L),
//! ```
//!
//! unbiased whenever w_B + w_L = 1 wherever f ≠ 0 (Veach 1997). A [`Weighting`] sees the whole
//! phase at once, so methods whose weights depend on every sample (optimal MIS weights from a
//! linear system over the batch) fit as well as per-sample [`Heuristic`]s, which [`PerSample`]
//! turns into a weighting.

use crate::estimator::SampleRecord;
use crate::phase::{Phase, PhaseRole, SampleSplit};
use glam::{UVec2, Vec4};
use lumis_core::math::Rgb;
use lumis_core::math::lanes::Lanes;
use lumis_core::scene::Scene;

/// Combines one phase's samples into its estimate.
pub trait Weighting: Send + Sync {
    /// Writes each record's contribution to the estimate into `contributions` (as long as
    /// `phase.records`, all zero on entry; black records contribute zero) and returns their
    /// sum, the phase's estimate.
    fn weigh(&self, phase: &Phase, contributions: &mut [Rgb]) -> Rgb;

    /// Whether `weigh` needs both densities of every record, black ones included
    /// ([`crate::estimator::Densities::Both`]): asked once per phase; the default, false, costs
    /// no pdf evaluation for samples that do not reach the light.
    fn needs_both_densities(&self) -> bool {
        false
    }

    /// Whether each record's contribution depends on that record alone (a per-sample
    /// heuristic), so that [`record_contribution`](Self::record_contribution) gives it: a phase
    /// whose records nobody reads is then summed as they are drawn, none kept
    /// ([`LightSampling::phases_together`]). The default, false, for weightings that need the
    /// whole phase.
    ///
    /// [`LightSampling::phases_together`]: crate::sampling::LightSampling::phases_together
    fn weighs_records_alone(&self) -> bool {
        false
    }

    /// The contribution of non-black `record` (drawn by the BSDF if `from_bsdf`, else by the
    /// light) to a phase of `split`, bit for bit what `weigh` writes for it. Only called where
    /// [`weighs_records_alone`](Self::weighs_records_alone) is true, which a weighting must not
    /// say without overriding this (the default gives zero).
    fn record_contribution(
        &self,
        _split: SampleSplit,
        _from_bsdf: bool,
        _record: &SampleRecord,
    ) -> Rgb {
        Rgb::ZERO
    }

    /// Work once per scene before rendering (e.g. a pilot pass that measures per-technique
    /// statistics per block of pixels, which `weigh` then reads through `phase.pixel`).
    fn preprocess(&mut self, _scene: &Scene) {}
}

/// A weighting chosen at run time (e.g. by name, as `path` chooses its own): each phase's
/// weights through one dynamic call, the same arithmetic.
impl<W: Weighting + ?Sized> Weighting for Box<W> {
    #[inline]
    fn weigh(&self, phase: &Phase, contributions: &mut [Rgb]) -> Rgb {
        (**self).weigh(phase, contributions)
    }

    #[inline]
    fn needs_both_densities(&self) -> bool {
        (**self).needs_both_densities()
    }

    #[inline]
    fn weighs_records_alone(&self) -> bool {
        (**self).weighs_records_alone()
    }

    #[inline]
    fn record_contribution(
        &self,
        split: SampleSplit,
        from_bsdf: bool,
        record: &SampleRecord,
    ) -> Rgb {
        (**self).record_contribution(split, from_bsdf, record)
    }

    fn preprocess(&mut self, scene: &Scene) {
        (**self).preprocess(scene);
    }
}

/// A per-sample weight: the weight of a sample whose technique has n·p = `mine` against the
/// other technique's n·p = `other` at the sample's direction. Only called with `mine ≠ other`
/// (equal products weigh ½ each); must satisfy w(a, b) + w(b, a) = 1 for all a, b ≥ 0,
/// including 0 and ∞, so that the estimate is unbiased.
pub trait Heuristic: Send + Sync {
    fn weight(&self, mine: f32, other: f32) -> f32;

    /// Four weights at once, lane i being `weight(mine[i], other[i])` bit for bit; lanes with
    /// equal products are discarded, whatever they hold. The default calls `weight` four times;
    /// a heuristic whose formula is plain arithmetic overrides it with vector arithmetic (four
    /// divisions for the price of one: the weighting pass is bound by its divisions), writing
    /// the formula once over [`Lanes`] for both methods, as [`balance`] is.
    #[inline]
    fn weight4(&self, mine: Vec4, other: Vec4) -> Vec4 {
        Vec4::new(
            self.weight(mine.x, other.x),
            self.weight(mine.y, other.y),
            self.weight(mine.z, other.z),
            self.weight(mine.w, other.w),
        )
    }
}

/// The balance heuristic, w_i = n_i p_i / Σ_k n_k p_k, written with the ratio r = other / mine
/// so that huge or tiny products neither overflow nor divide 0 by 0: the `balance` plugin's
/// weights, and those of every method that weighs its pilots or phases with it.
pub struct Balance;

impl Heuristic for Balance {
    #[inline]
    fn weight(&self, mine: f32, other: f32) -> f32 {
        balance(mine, other)
    }

    #[inline]
    fn weight4(&self, mine: Vec4, other: Vec4) -> Vec4 {
        balance(mine, other)
    }
}

/// [`Balance`]'s weight, for one sample or for several: 1 / (1 + other / mine).
#[inline(always)]
pub fn balance<L: Lanes>(mine: L, other: L) -> L {
    L::splat(1.0) / (L::splat(1.0) + other / mine)
}

/// The multi-sample estimator with the per-sample weights of a [`Heuristic`]. A Dirac BSDF
/// sample, which light sampling cannot produce, has weight 1 and contributes f / n_B (its
/// record's f is already divided by the Dirac density).
pub struct PerSample<H>(pub H);

impl<H: Heuristic> PerSample<H> {
    /// The phase weighed with each technique's n·p multiplied by a factor, `factors` = (c_B,
    /// c_L): w_t = h(c_t n_t p_t, c_o n_o p_o), e.g. variance-aware weights (factors 1: the
    /// heuristic itself, bit for bit). Contributions and their sum as [`Weighting::weigh`].
    ///
    /// Weights are computed four records at a time over the whole phase, BSDF records then
    /// light records, each lane taking its technique's products: a phase of a few samples fills
    /// one vector rather than one per technique, which halves the divisions the pass is bound
    /// by. Each lane computes what it would in a vector of its technique alone, and the records
    /// are added in order, so the estimate is the same. A phase of at most [`SCALAR_RECORDS`]
    /// records (one sample per technique, as in the race scenes) is weighed record by record
    /// instead, with the same arithmetic: its lit records are one or two, and the vectors' set-up
    /// cost more than their divisions saved.
    pub fn weigh_scaled(&self, phase: &Phase, contributions: &mut [Rgb], factors: [f32; 2]) -> Rgb {
        let products = Products::of(phase.split, factors);
        if phase.records.len() <= SCALAR_RECORDS {
            self.weigh_each(phase, contributions, products)
        } else {
            self.weigh_in_lanes(phase, contributions, products)
        }
    }

    /// [`weigh_scaled`](Self::weigh_scaled) four records at a time.
    #[inline(always)]
    fn weigh_in_lanes(&self, phase: &Phase, contributions: &mut [Rgb], products: Products) -> Rgb {
        let Products { n, k, factor } = products;
        let (bsdf_factor, light_factor) = (Vec4::splat(factor[0]), Vec4::splat(factor[1]));
        let n_bsdf = phase.split.n_bsdf as usize;
        // Black records keep the zero their contribution starts with (adding it to the sum
        // would change no bit).
        let mut value = Rgb::ZERO;
        // `chunks` alone, the contributions sliced by index: zipped `chunks` and `step_by`
        // iterators cost more to set up than the arithmetic of a phase of two records.
        for (chunk_index, chunk) in phase.records.chunks(4).enumerate() {
            let first = 4 * chunk_index;
            let out = &mut contributions[first..first + chunk.len()];
            // Lanes past the end are not used.
            let (mut p_bsdf, mut p_light) = ([1.0f32; 4], [1.0f32; 4]);
            for (i, r) in chunk.iter().enumerate() {
                (p_bsdf[i], p_light[i]) = (r.p_bsdf, r.p_light);
            }
            // n·p of each technique: a BSDF record's own product is `bsdf`, its other
            // `light`, and the reverse for a light record.
            let bsdf = Vec4::from_array(p_bsdf) * k[0];
            let light = Vec4::from_array(p_light) * k[1];
            let bsdf_lanes = n_bsdf.saturating_sub(first);
            let is_bsdf = Vec4::new(0.0, 1.0, 2.0, 3.0).cmplt(Vec4::splat(bsdf_lanes as f32));
            let mine = Vec4::select(is_bsdf, bsdf, light);
            let other = Vec4::select(is_bsdf, light, bsdf);
            let w = Vec4::select(
                mine.cmpeq(other),
                Vec4::splat(0.5),
                self.0.weight4(mine, other),
            );
            // w / (n p): the factor of f in the contribution (Dirac and black lanes unused).
            let own_factor = Vec4::select(is_bsdf, bsdf_factor, light_factor);
            let scale = (w / mine * own_factor).to_array();
            for (i, ((r, c), scale)) in chunk.iter().zip(out).zip(scale).enumerate() {
                if r.is_black() {
                    continue;
                }
                *c = if !r.delta {
                    r.f * scale
                } else if i < bsdf_lanes {
                    r.f / n[0]
                } else {
                    r.f / n[1]
                };
                value += *c;
            }
        }
        value
    }

    /// [`weigh_scaled`](Self::weigh_scaled) record by record, for phases of at most
    /// [`SCALAR_RECORDS`] records: `weight` gives each lane of `weight4` bit for bit, so each
    /// lit record gets [`weigh_in_lanes`](Self::weigh_in_lanes)' contribution, without its
    /// set-up for the lanes.
    #[inline(always)]
    fn weigh_each(&self, phase: &Phase, contributions: &mut [Rgb], products: Products) -> Rgb {
        let n_bsdf = phase.split.n_bsdf as usize;
        let mut value = Rgb::ZERO;
        for (i, (r, c)) in phase.records.iter().zip(contributions).enumerate() {
            if r.is_black() {
                continue;
            }
            *c = self.contribution(products, i < n_bsdf, r);
            value += *c;
        }
        value
    }

    /// The contribution of non-black record `r`, drawn by the BSDF if `from_bsdf`.
    #[inline(always)]
    fn contribution(&self, products: Products, from_bsdf: bool, r: &SampleRecord) -> Rgb {
        let Products { n, k, factor } = products;
        // Technique 0 is the BSDF's, 1 the light's.
        let (own, other) = if from_bsdf { (0, 1) } else { (1, 0) };
        if r.delta {
            r.f / n[own]
        } else {
            let p = [r.p_bsdf, r.p_light];
            let (mine, theirs) = (p[own] * k[own], p[other] * k[other]);
            let w = if mine == theirs {
                0.5
            } else {
                self.0.weight(mine, theirs)
            };
            r.f * (w / mine * factor[own])
        }
    }
}

/// The largest phase weighed record by record: the race scenes' phases of one sample per
/// technique spent most of the lanes' time on their set-up.
const SCALAR_RECORDS: usize = 2;

/// Per technique (BSDF, light) of one phase: n, k = c·n and the factor k / n of w / (k p) in
/// w / (n p).
#[derive(Clone, Copy)]
struct Products {
    n: [f32; 2],
    k: [f32; 2],
    factor: [f32; 2],
}

impl Products {
    /// For `split` with the factors c = `factors`. Where c is 1, k / n is exactly 1 and the
    /// division is skipped.
    #[inline(always)]
    fn of(split: SampleSplit, factors: [f32; 2]) -> Self {
        let n = [split.n_bsdf as f32, split.n_light as f32];
        let k = [factors[0] * n[0], factors[1] * n[1]];
        let factor = std::array::from_fn(|t| if factors[t] == 1.0 { 1.0 } else { k[t] / n[t] });
        Products { n, k, factor }
    }
}

impl<H: Heuristic> Weighting for PerSample<H> {
    fn weigh(&self, phase: &Phase, contributions: &mut [Rgb]) -> Rgb {
        self.weigh_scaled(phase, contributions, [1.0, 1.0])
    }

    #[inline]
    fn weighs_records_alone(&self) -> bool {
        true
    }

    #[inline(always)]
    fn record_contribution(
        &self,
        split: SampleSplit,
        from_bsdf: bool,
        record: &SampleRecord,
    ) -> Rgb {
        self.contribution(Products::of(split, [1.0, 1.0]), from_bsdf, record)
    }
}

// Checks for the tests of a heuristic, public so that one written outside this crate is tested
// as the built-in ones are.

/// Asserts that `h`'s weights are in [0, 1] and sum to one over the two techniques, for
/// ordinary, equal, zero, infinite and extreme products, and that `weight4`'s lanes are
/// `weight` bit for bit.
pub fn assert_partition_of_unity(h: &dyn Heuristic) {
    let values = [
        0.0f32,
        1e-30,
        0.3,
        1.0,
        1.0 + 1e-7,
        2.0,
        3.0,
        1e30,
        f32::INFINITY,
    ];
    for a in values {
        for b in values {
            let w = |x: f32, y: f32| if x == y { 0.5 } else { h.weight(x, y) };
            let (wa, wb) = (w(a, b), w(b, a));
            assert!((0.0..=1.0).contains(&wa), "w({a}, {b}) = {wa}");
            if a != b {
                let lanes = h.weight4(Vec4::new(a, 1.0, a, 2.0), Vec4::new(b, 3.0, b, 0.5));
                assert_eq!(
                    lanes.x.to_bits(),
                    wa.to_bits(),
                    "weight4 lane of ({a}, {b})"
                );
            }
            assert!(
                (wa + wb - 1.0).abs() < 1e-6,
                "w({a}, {b}) + w({b}, {a}) = {}",
                wa + wb
            );
        }
    }
}

/// Asserts that phases of at most `SCALAR_RECORDS` records, which are weighed record by record
/// (`weigh_each`), get bit for bit what the lanes (`weigh_in_lanes`) give the same phase, each
/// contribution and the estimate, with `h`'s weights, with and without factors, for lit, black
/// and Dirac records, equal, zero and infinite products; and that, without factors, each lit
/// record weighed alone ([`Weighting::record_contribution`]), as a packet's phases are summed
/// while drawn, gets the same contribution, and their sum in order the same estimate.
pub fn assert_small_phases_weigh_as_the_lanes_do(h: &dyn Heuristic) {
    let densities = [0.0f32, 1e-30, 0.37, 1.0, 2.5, 1e30, f32::INFINITY];
    let splits = [(1, 1), (2, 0), (0, 2), (1, 0), (0, 1)];
    let bits =
        |v: &[Rgb]| -> Vec<[u32; 3]> { v.iter().map(|c| c.to_array().map(f32::to_bits)).collect() };
    let mut checked = 0;
    for factors in [[1.0f32, 1.0], [0.3, 1.7]] {
        let weighting = PerSample(DynHeuristic(h));
        for (n_bsdf, n_light) in splits {
            let split = SampleSplit { n_bsdf, n_light };
            let products = Products::of(split, factors);
            for (&p, &q, kind) in densities.iter().flat_map(|p| {
                densities
                    .iter()
                    .flat_map(move |q| (0..3).map(move |k| (p, q, k)))
            }) {
                let record = |i: usize| SampleRecord {
                    f: if kind == 1 && i == 0 {
                        Rgb::ZERO
                    } else {
                        Rgb::new(0.25, 0.5 + i as f32, 3.0)
                    },
                    p_bsdf: if i == 0 { p } else { q },
                    p_light: if i == 0 { q } else { p },
                    delta: kind == 2 && i == 0 && n_bsdf > 0,
                };
                let records: Vec<_> = (0..split.total() as usize).map(record).collect();
                let phase = Phase {
                    pixel: UVec2::ZERO,
                    light: 0,
                    split,
                    role: PhaseRole::ESTIMATE,
                    records: &records,
                };
                let mut each = vec![Rgb::ZERO; records.len()];
                let mut lanes = each.clone();
                let value_each = weighting.weigh_each(&phase, &mut each, products);
                let value_lanes = weighting.weigh_in_lanes(&phase, &mut lanes, products);
                let case = format!("{records:?}, {split:?}, factors {factors:?}");
                assert_eq!(bits(&each), bits(&lanes), "{case}");
                assert_eq!(bits(&[value_each]), bits(&[value_lanes]), "{case}");
                if factors == [1.0, 1.0] {
                    // Weighed record by record as drawn, summed in the same order.
                    let mut value = Rgb::ZERO;
                    for (i, (r, c)) in records.iter().zip(&lanes).enumerate() {
                        if !r.is_black() {
                            let alone =
                                weighting.record_contribution(split, i < n_bsdf as usize, r);
                            assert_eq!(bits(&[alone]), bits(&[*c]), "record {i} of {case}");
                            value += alone;
                        }
                    }
                    assert_eq!(bits(&[value]), bits(&[value_lanes]), "{case}");
                }
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 2 * 5 * 7 * 7 * 3);
}

/// A heuristic behind a reference, as `PerSample` takes it by value.
struct DynHeuristic<'a>(&'a dyn Heuristic);

impl Heuristic for DynHeuristic<'_> {
    fn weight(&self, mine: f32, other: f32) -> f32 {
        self.0.weight(mine, other)
    }

    fn weight4(&self, mine: Vec4, other: Vec4) -> Vec4 {
        self.0.weight4(mine, other)
    }
}
