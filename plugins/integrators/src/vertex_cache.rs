//! A world-space cache of the one-sample mixture's α at the vertices of paths past the first
//! (`path`'s `deep_allocation`): a hashed grid of cells keyed on position and on the side the
//! geometric normal faces, whose statistics a pass adds to and the next pass reads frozen.
//!
//! A vertex x draws its continuation from q_α = α p_B + (1 − α) p_L (the paper's Eq. 3 in its
//! one-sample form) and the path's estimate of the light it reflects there is y = g/q_{α_s},
//! g = f · L_i, α_s the α it was drawn with. Each such sample adds to its cell:
//!
//! - for the learned α ([`Learning::SecondMoment`]), y² q_{α_s}/q_{α_i} on a grid of α_i
//!   ([`ALPHA_GRID`]), an unbiased estimate of the second moment m(α_i) = ∫ g²/q_{α_i}
//!   (docs/integrators.md, "What a pilot says about any α"); the next pass uses the grid's α of
//!   least m̂;
//! - for practical path guiding's learned BSDF-sampling fraction ([`Learning::GuidingFraction`],
//!   Müller et al. 2017/2019, `bsdfSamplingFraction`), the gradient of the KL divergence
//!   between g and q_α with respect to θ, α = sigmoid(θ): −y (p_B − p_L)/q_{α_s} · α(1 − α);
//!   between passes each cell takes one Adam step along the pass's mean gradient.
//!
//! Sums are fixed-point integers added atomically ([`FixedSum`]): an integer sum does not
//! depend on the order of its terms, so the frozen α, and the image, are the same bit for bit
//! for any number of threads; no lock is taken on the per-sample path.
//!
//! A pass adds to its own sums; `freeze` adds them to the sums of the passes before and reads
//! α from those. So the cache between passes is what `freeze` made (the *frozen* part: the
//! earlier passes' sums, α, the guiding fraction's θ and Adam moments) and what the last pass
//! added: [`VertexCache::save`] writes both, apart, for a state or shard file; the shards of a
//! pass share the frozen part and [`merge`] adds what each added, into what one process that
//! rendered every shard's tiles would hold, bit for bit.

use glam::Vec3;
use lumis_core::geometry::ShapeGeometry;
use lumis_core::scene::Scene;
use std::sync::atomic::{AtomicU64, Ordering};

mod state;
pub use state::merge;

/// The α a mixture vertex may take: the paper's defensive clamp, which also keeps BSDF
/// sampling, the only technique that finds indirect light, in every mixture.
pub const ALPHA_MIN: f64 = 0.025;
pub const ALPHA_MAX: f64 = 0.975;
/// The α at which the second moment is estimated: the argmin is read on this grid.
pub const ALPHA_GRID: [f64; 9] = [ALPHA_MIN, 0.1, 0.2, 0.35, 0.5, 0.65, 0.8, 0.9, ALPHA_MAX];
/// Cells of the hashed grid (a power of two): distinct cells that hash alike share statistics,
/// which costs only the quality of their α.
const SLOTS: usize = 1 << 15;
/// Samples a cell needs before its statistics are used.
const MIN_SAMPLES: u64 = 16;
/// Binary digits below the point of the fixed-point sums; a term is clamped to ±2^[`MAX_LOG2`].
const FRACTION_BITS: i32 = 40;
const MAX_LOG2: i32 = 22;
/// Adam's settings for the guiding fraction: one step per pass, so a larger rate than
/// Müller's per-sample 0.01.
const ADAM_RATE: f64 = 0.25;
const ADAM_BETA1: f64 = 0.9;
const ADAM_BETA2: f64 = 0.999;
const ADAM_EPSILON: f64 = 1e-8;

/// How a cell's α is learned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Learning {
    /// The grid α of least estimated second moment.
    SecondMoment,
    /// Müller et al.'s BSDF-sampling fraction, by gradient steps on the KL divergence.
    GuidingFraction,
}

/// A sum of real numbers as a 128-bit fixed-point integer, added to by any thread: the carry
/// of the low word is added to the high word, so the total is exact whatever the order.
#[derive(Default)]
pub struct FixedSum {
    low: AtomicU64,
    high: AtomicU64,
}

impl FixedSum {
    /// Adds `value` (rounded to 2^-40, clamped to ±2^22; NaN adds nothing).
    #[inline]
    pub fn add(&self, value: f64) {
        let limit = (2f64).powi(MAX_LOG2);
        let scaled = (value.clamp(-limit, limit) * (2f64).powi(FRACTION_BITS)).round();
        if !scaled.is_finite() || scaled == 0.0 {
            return;
        }
        let term = scaled as i64;
        let old = self.low.fetch_add(term as u64, Ordering::Relaxed);
        let carry = u64::from(old.checked_add(term as u64).is_none());
        let sign = if term < 0 { u64::MAX } else { 0 };
        let high = carry.wrapping_add(sign);
        if high != 0 {
            self.high.fetch_add(high, Ordering::Relaxed);
        }
    }

    /// The sum (read between passes, when no thread adds).
    pub fn value(&self) -> f64 {
        fixed_value(self.bits())
    }

    /// The sum as the fixed-point integer it is.
    fn bits(&self) -> i128 {
        (((self.high.load(Ordering::Relaxed) as u128) << 64)
            | self.low.load(Ordering::Relaxed) as u128) as i128
    }

    fn set(&self, bits: i128) {
        self.low.store(bits as u128 as u64, Ordering::Relaxed);
        self.high
            .store((bits as u128 >> 64) as u64, Ordering::Relaxed);
    }

    /// The sum's integer, the sum restarting from zero.
    fn take(&mut self) -> i128 {
        let bits = (((*self.high.get_mut() as u128) << 64) | *self.low.get_mut() as u128) as i128;
        *self.low.get_mut() = 0;
        *self.high.get_mut() = 0;
        bits
    }
}

/// The real number a fixed-point integer stands for.
fn fixed_value(bits: i128) -> f64 {
    bits as f64 * (2f64).powi(-FRACTION_BITS)
}

/// What one mixture sample tells its cell.
#[derive(Clone, Copy, Debug, Default)]
pub struct MixtureSample {
    pub slot: u32,
    /// The sample's estimate, luminance of g/q_{α_s}.
    pub y: f64,
    pub p_bsdf: f64,
    pub p_light: f64,
    /// α_s.
    pub alpha: f64,
}

/// The cache: statistics added during a pass, α frozen for it.
pub struct VertexCache {
    learning: Learning,
    /// Cells along the scene's longest side, the scene's bounding box's corner and cells per
    /// unit length.
    resolution: u32,
    origin: Vec3,
    cells_per_unit: f32,
    /// Every α before it is learned.
    initial: f64,
    /// Per slot, added to during a pass: the learning's sums ([`ALPHA_GRID`]'s second moments,
    /// or one gradient sum) and the samples.
    sums: Vec<FixedSum>,
    counts: Vec<AtomicU64>,
    /// The same of the passes before, kept by `freeze` (a cell of the guiding fraction keeps
    /// them until it has [`MIN_SAMPLES`]).
    frozen_sums: Vec<i128>,
    frozen_counts: Vec<u64>,
    /// Per slot, read during a pass: α, and the guiding fraction's θ and Adam moments.
    alpha: Vec<f32>,
    theta: Vec<f64>,
    adam: Vec<(f64, f64)>,
    steps: i32,
}

impl VertexCache {
    /// An empty cache over `scene`'s bounding box with `resolution` cells along its longest
    /// side, every α `initial` until learned.
    pub fn new(scene: &Scene, resolution: u32, learning: Learning, initial: f64) -> Self {
        let (lo, hi) = scene_bounds(scene);
        let extent = (hi - lo).max_element();
        let cells_per_unit = if extent > 0.0 && extent.is_finite() {
            resolution as f32 / extent
        } else {
            1.0
        };
        let per_slot = terms(learning);
        let initial = initial.clamp(ALPHA_MIN, ALPHA_MAX);
        let theta = state::initial_theta(initial);
        VertexCache {
            learning,
            resolution,
            origin: lo,
            cells_per_unit,
            initial,
            sums: (0..SLOTS * per_slot).map(|_| FixedSum::default()).collect(),
            counts: (0..SLOTS).map(|_| AtomicU64::new(0)).collect(),
            frozen_sums: vec![0; SLOTS * per_slot],
            frozen_counts: vec![0; SLOTS],
            alpha: vec![initial as f32; SLOTS],
            theta: vec![theta; SLOTS],
            adam: vec![(0.0, 0.0); SLOTS],
            steps: 0,
        }
    }

    /// The slot of a point at `position` whose geometric normal, on the viewer's side, is
    /// `normal`: its grid cell and the axis and sign its normal is closest to.
    #[inline]
    pub fn slot(&self, position: Vec3, normal: Vec3) -> u32 {
        let cell = ((position - self.origin) * self.cells_per_unit).floor();
        let a = normal.abs();
        let axis = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let side = (axis * 2) as u64 + u64::from(normal[axis] < 0.0);
        let key = (cell.x as i64 as u64)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add((cell.y as i64 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F))
            .wrapping_add((cell.z as i64 as u64).wrapping_mul(0x1656_67B1_9E37_79F9))
            .wrapping_add(side.wrapping_mul(0x27D4_EB2F_1656_67C5));
        (mix(key) as usize & (SLOTS - 1)) as u32
    }

    /// The α frozen for `slot` during this pass.
    #[inline]
    pub fn alpha(&self, slot: u32) -> f64 {
        self.alpha[slot as usize] as f64
    }

    /// Adds one sample's statistics to its cell.
    #[inline]
    pub fn record(&self, s: &MixtureSample) {
        let q = |alpha: f64| alpha * s.p_bsdf + (1.0 - alpha) * s.p_light;
        let q_s = q(s.alpha);
        if !(q_s > 0.0 && s.y.is_finite()) {
            return;
        }
        let base = s.slot as usize * terms(self.learning);
        match self.learning {
            Learning::SecondMoment => {
                for (i, &alpha) in ALPHA_GRID.iter().enumerate() {
                    self.sums[base + i].add(s.y * s.y * q_s / q(alpha));
                }
            }
            Learning::GuidingFraction => {
                let gradient = -s.y * (s.p_bsdf - s.p_light) / q_s * s.alpha * (1.0 - s.alpha);
                self.sums[base].add(gradient);
            }
        }
        self.counts[s.slot as usize].fetch_add(1, Ordering::Relaxed);
    }

    /// Between passes: each cell's α from everything added so far (the second moment: every
    /// pass; the guiding fraction: one Adam step along the mean gradient since its last step,
    /// whose sums then restart).
    pub fn freeze(&mut self) {
        self.steps += 1;
        let terms = terms(self.learning);
        for slot in 0..SLOTS {
            let base = slot * terms;
            let added = std::mem::take(self.counts[slot].get_mut());
            self.frozen_counts[slot] = self.frozen_counts[slot].saturating_add(added);
            for (frozen, sum) in self.frozen_sums[base..base + terms]
                .iter_mut()
                .zip(&mut self.sums[base..base + terms])
            {
                *frozen = frozen.wrapping_add(sum.take());
            }
            let count = self.frozen_counts[slot];
            if count < MIN_SAMPLES {
                continue;
            }
            match self.learning {
                Learning::SecondMoment => {
                    let mut best = (f64::INFINITY, 0.5);
                    for (i, &alpha) in ALPHA_GRID.iter().enumerate() {
                        let m = fixed_value(self.frozen_sums[base + i]);
                        if m < best.0 {
                            best = (m, alpha);
                        }
                    }
                    // All black: nothing to choose by, the balanced mixture.
                    if best.0 > 0.0 {
                        self.alpha[slot] = best.1 as f32;
                    }
                }
                Learning::GuidingFraction => {
                    let gradient = fixed_value(self.frozen_sums[base]) / count as f64;
                    self.frozen_sums[base] = 0;
                    self.frozen_counts[slot] = 0;
                    let (m, v) = &mut self.adam[slot];
                    *m = ADAM_BETA1 * *m + (1.0 - ADAM_BETA1) * gradient;
                    *v = ADAM_BETA2 * *v + (1.0 - ADAM_BETA2) * gradient * gradient;
                    let m_hat = *m / (1.0 - ADAM_BETA1.powi(self.steps));
                    let v_hat = *v / (1.0 - ADAM_BETA2.powi(self.steps));
                    self.theta[slot] -= ADAM_RATE * m_hat / (v_hat.sqrt() + ADAM_EPSILON);
                    let alpha = 1.0 / (1.0 + (-self.theta[slot]).exp());
                    self.alpha[slot] = alpha.clamp(ALPHA_MIN, ALPHA_MAX) as f32;
                }
            }
        }
    }
}

/// Sums per slot of a learning.
fn terms(learning: Learning) -> usize {
    match learning {
        Learning::SecondMoment => ALPHA_GRID.len(),
        Learning::GuidingFraction => 1,
    }
}

/// SplitMix64's finaliser: every input bit moves the slot.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The box around every shape of `scene` (the origin alone for a scene with none).
fn scene_bounds(scene: &Scene) -> (Vec3, Vec3) {
    let mut lo = Vec3::INFINITY;
    let mut hi = Vec3::NEG_INFINITY;
    for shape in scene.geometry.shapes() {
        match shape {
            ShapeGeometry::Mesh(mesh) => {
                for &p in &mesh.positions {
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
            ShapeGeometry::Sphere(s) => {
                lo = lo.min(s.center - Vec3::splat(s.radius));
                hi = hi.max(s.center + Vec3::splat(s.radius));
            }
        }
    }
    if lo.cmple(hi).all() {
        (lo, hi)
    } else {
        (Vec3::ZERO, Vec3::ZERO)
    }
}
