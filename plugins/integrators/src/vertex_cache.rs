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
//!
//! Why one file of over 600 lines: the cache and its saved form (save, restore, merge and the
//! reader of saved bytes) share the cache's private fields and layout; split into a child
//! module, the two import each other (an import circle, `tests/module_layers.rs`).

use glam::Vec3;
use lumis_core::geometry::ShapeGeometry;
use lumis_core::scene::Scene;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};

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
        let theta = initial_theta(initial);
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

/// The layout of a cache's state ([`VertexCache::save`]), its version in the last byte.
const STATE_MAGIC: &[u8; 8] = b"LUMISVC1";

/// The fields of a saved cache that make it this render's cache: its learning and grid.
#[derive(Clone, Copy)]
struct Geometry {
    learning: Learning,
    resolution: u32,
    origin: [f32; 3],
    cells_per_unit: f32,
    slots: u32,
    initial: f64,
}

/// A saved cache, read and checked ([`VertexCache::save`] has the layout).
struct Saved<'a> {
    geometry: Geometry,
    steps: i32,
    /// Slots whose frozen part differs from a new cache's, ascending; their sums, `terms` each.
    frozen: Vec<FrozenSlot>,
    frozen_sums: Vec<i128>,
    /// The bytes of the geometry, the steps and the frozen slots: the part the shards of one
    /// pass share.
    frozen_bytes: &'a [u8],
    /// Slots the last pass added to, ascending; their sums, `terms` each.
    added: Vec<(u32, u64)>,
    added_sums: Vec<i128>,
}

#[derive(Clone, Copy)]
struct FrozenSlot {
    slot: u32,
    count: u64,
    alpha: f32,
    theta: f64,
    adam: (f64, f64),
}

impl VertexCache {
    fn geometry(&self) -> Geometry {
        Geometry {
            learning: self.learning,
            resolution: self.resolution,
            origin: self.origin.to_array(),
            cells_per_unit: self.cells_per_unit,
            slots: SLOTS as u32,
            initial: self.initial,
        }
    }

    /// The cache between passes as bytes, little-endian: [`STATE_MAGIC`]; the learning (0 the
    /// second moment, 1 the guiding fraction), the resolution, the origin and cells per unit
    /// (f32), the slots, the initial α (f64) and the freezes so far (Adam's steps); the frozen
    /// part, slot by slot where it is not a new cache's (slot, samples, sums as i128, α (f32),
    /// with the guiding fraction θ and Adam's two moments (f64)); then what the last pass
    /// added, slot by slot where it added (slot, samples, sums). Only touched slots are
    /// written: a slot costs 160 bytes frozen and 156 added with the second moment (9 sums), 56
    /// and 28 with the guiding fraction; with every one of the 2^15 slots touched, 10.4 MB and
    /// 2.8 MB.
    pub fn save(&self) -> Vec<u8> {
        let terms = terms(self.learning);
        let mut out = Vec::new();
        out.extend_from_slice(STATE_MAGIC);
        let g = self.geometry();
        put(&mut out, &learning_code(g.learning).to_le_bytes());
        put(&mut out, &g.resolution.to_le_bytes());
        for v in g.origin {
            put(&mut out, &v.to_le_bytes());
        }
        put(&mut out, &g.cells_per_unit.to_le_bytes());
        put(&mut out, &g.slots.to_le_bytes());
        put(&mut out, &g.initial.to_le_bytes());
        put(&mut out, &self.steps.to_le_bytes());
        let fresh_alpha = self.initial as f32;
        let fresh_theta = initial_theta(self.initial);
        let frozen: Vec<usize> = (0..SLOTS)
            .filter(|&slot| {
                self.frozen_counts[slot] != 0
                    || self.frozen_sums[slot * terms..][..terms]
                        .iter()
                        .any(|&s| s != 0)
                    || self.alpha[slot].to_bits() != fresh_alpha.to_bits()
                    || self.theta[slot].to_bits() != fresh_theta.to_bits()
                    || self.adam[slot].0.to_bits() != 0
                    || self.adam[slot].1.to_bits() != 0
            })
            .collect();
        put(&mut out, &(frozen.len() as u32).to_le_bytes());
        for slot in frozen {
            put(&mut out, &(slot as u32).to_le_bytes());
            put(&mut out, &self.frozen_counts[slot].to_le_bytes());
            for sum in &self.frozen_sums[slot * terms..][..terms] {
                put(&mut out, &sum.to_le_bytes());
            }
            put(&mut out, &self.alpha[slot].to_le_bytes());
            if self.learning == Learning::GuidingFraction {
                put(&mut out, &self.theta[slot].to_le_bytes());
                put(&mut out, &self.adam[slot].0.to_le_bytes());
                put(&mut out, &self.adam[slot].1.to_le_bytes());
            }
        }
        let added: Vec<(usize, u64)> = (0..SLOTS)
            .map(|slot| (slot, self.counts[slot].load(Ordering::Relaxed)))
            .filter(|&(_, count)| count != 0)
            .collect();
        put(&mut out, &(added.len() as u32).to_le_bytes());
        for (slot, count) in added {
            put(&mut out, &(slot as u32).to_le_bytes());
            put(&mut out, &count.to_le_bytes());
            for sum in &self.sums[slot * terms..][..terms] {
                put(&mut out, &sum.bits().to_le_bytes());
            }
        }
        out
    }

    /// Continues from `bytes`, a cache [`save`](Self::save) wrote between passes: the frozen
    /// part and the last pass's sums become this cache's. A cache of another learning, grid or
    /// scene box is refused, naming what differs; a malformed one too. On an error the cache
    /// is left as it was.
    pub fn restore(&mut self, bytes: &[u8]) -> Result<(), String> {
        let saved = Saved::read(bytes)?;
        check_geometry(
            &saved.geometry,
            &self.geometry(),
            "the saved cache",
            "this render's",
        )?;
        let terms = terms(self.learning);
        self.steps = saved.steps;
        self.frozen_sums.fill(0);
        self.frozen_counts.fill(0);
        self.alpha.fill(self.initial as f32);
        self.theta.fill(initial_theta(self.initial));
        self.adam.fill((0.0, 0.0));
        for (f, sums) in saved
            .frozen
            .iter()
            .zip(saved.frozen_sums.chunks_exact(terms))
        {
            let slot = f.slot as usize;
            self.frozen_counts[slot] = f.count;
            self.frozen_sums[slot * terms..][..terms].copy_from_slice(sums);
            self.alpha[slot] = f.alpha;
            self.theta[slot] = f.theta;
            self.adam[slot] = f.adam;
        }
        self.sums.iter().for_each(|s| s.set(0));
        self.counts
            .iter()
            .for_each(|c| c.store(0, Ordering::Relaxed));
        for (&(slot, count), sums) in saved.added.iter().zip(saved.added_sums.chunks_exact(terms)) {
            let slot = slot as usize;
            self.counts[slot].store(count, Ordering::Relaxed);
            for (sum, &bits) in self.sums[slot * terms..][..terms].iter().zip(sums) {
                sum.set(bits);
            }
        }
        Ok(())
    }
}

/// The caches `a` and `b` that two shards of one pass saved ([`VertexCache::save`]) as one:
/// their frozen part, which must be the same (both resumed from one merged state), and the sums
/// each added in the pass, added (integers: in any order, the sums one process adds). A
/// mismatch is refused, naming it.
pub fn merge(a: &[u8], b: &[u8]) -> Result<Vec<u8>, String> {
    let (a, b) = (Saved::read(a)?, Saved::read(b)?);
    check_geometry(&b.geometry, &a.geometry, "one shard's cache", "the other's")?;
    if a.frozen_bytes != b.frozen_bytes {
        return Err(format!(
            "the shards' caches were frozen from different passes (after {} and {} steps, or other sums): not shards of one pass resumed from one merged state",
            a.steps, b.steps
        ));
    }
    let terms = terms(a.geometry.learning);
    let mut slots: BTreeMap<u32, (u64, Vec<i128>)> = BTreeMap::new();
    for saved in [&a, &b] {
        for (&(slot, count), sums) in saved.added.iter().zip(saved.added_sums.chunks_exact(terms)) {
            let (total, totals) = slots.entry(slot).or_insert_with(|| (0, vec![0; terms]));
            *total = total.checked_add(count).ok_or_else(|| {
                format!("slot {slot} of the shards' caches has more samples than a count holds")
            })?;
            for (total, &sum) in totals.iter_mut().zip(sums) {
                *total = total.wrapping_add(sum);
            }
        }
    }
    let mut out = a.frozen_bytes.to_vec();
    put(&mut out, &(slots.len() as u32).to_le_bytes());
    for (slot, (count, sums)) in slots {
        put(&mut out, &slot.to_le_bytes());
        put(&mut out, &count.to_le_bytes());
        for sum in sums {
            put(&mut out, &sum.to_le_bytes());
        }
    }
    Ok(out)
}

/// Refuses a cache `found` of another learning, grid or scene than `wanted`.
fn check_geometry(
    found: &Geometry,
    wanted: &Geometry,
    found_name: &str,
    wanted_name: &str,
) -> Result<(), String> {
    let learning = |l: Learning| match l {
        Learning::SecondMoment => "the second moment (`learned`)",
        Learning::GuidingFraction => "the guiding fraction (`guiding_fraction`)",
    };
    let differs = if found.learning != wanted.learning {
        format!(
            "{found_name} learns {}, {wanted_name} {}",
            learning(found.learning),
            learning(wanted.learning)
        )
    } else if found.resolution != wanted.resolution {
        format!(
            "{found_name} has a resolution of {} cells along the scene's longest side (`cache_resolution`), {wanted_name} {}",
            found.resolution, wanted.resolution
        )
    } else if found.slots != wanted.slots {
        format!(
            "{found_name} has {} slots, {wanted_name} {}",
            found.slots, wanted.slots
        )
    } else if found.origin.map(f32::to_bits) != wanted.origin.map(f32::to_bits)
        || found.cells_per_unit.to_bits() != wanted.cells_per_unit.to_bits()
    {
        format!(
            "{found_name} covers a scene box from {:?} at {} cells per unit, {wanted_name} from {:?} at {}",
            found.origin, found.cells_per_unit, wanted.origin, wanted.cells_per_unit
        )
    } else if found.initial.to_bits() != wanted.initial.to_bits() {
        format!(
            "{found_name} starts from α = {}, {wanted_name} from {}",
            found.initial, wanted.initial
        )
    } else {
        return Ok(());
    };
    Err(format!("not this render's cache of α: {differs}"))
}

impl<'a> Saved<'a> {
    fn read(bytes: &'a [u8]) -> Result<Self, String> {
        let mut r = Cursor { bytes, at: 0 };
        if r.take(8, "its kind")? != STATE_MAGIC {
            return Err(
                "the learned state is not a cache of α of this lumis's layout (`LUMISVC1`)".into(),
            );
        }
        let learning = match r.u32("the learning")? {
            0 => Learning::SecondMoment,
            1 => Learning::GuidingFraction,
            other => return Err(format!("the cache's learning has an unknown code {other}")),
        };
        let resolution = r.u32("the resolution")?;
        let origin = [
            r.f32("the origin")?,
            r.f32("the origin")?,
            r.f32("the origin")?,
        ];
        let cells_per_unit = r.f32("the cells per unit")?;
        let slots = r.u32("the slots")?;
        let initial = r.f64("the initial α")?;
        let steps = r.u32("the steps")? as i32;
        if steps < 0 {
            return Err(format!("the cache counts {steps} Adam steps"));
        }
        let geometry = Geometry {
            learning,
            resolution,
            origin,
            cells_per_unit,
            slots,
            initial,
        };
        let terms = terms(learning);
        // Slots ascending, each of the cache's.
        let read_slot = |r: &mut Cursor, last: &mut Option<u32>| -> Result<u32, String> {
            let slot = r.u32("a slot")?;
            if slot >= slots {
                return Err(format!("the cache lists slot {slot} of {slots}"));
            }
            if let Some(last) = last.filter(|&l| slot <= l) {
                return Err(format!(
                    "the cache lists slot {slot} after slot {last}: not in ascending order"
                ));
            }
            *last = Some(slot);
            Ok(slot)
        };
        let n = r.count(terms * 16 + 16, "the frozen slots")?;
        let (mut frozen, mut frozen_sums, mut last) = (Vec::new(), Vec::new(), None);
        for _ in 0..n {
            let slot = read_slot(&mut r, &mut last)?;
            let count = r.u64("a slot's samples")?;
            for _ in 0..terms {
                frozen_sums.push(r.i128("a slot's sum")?);
            }
            let alpha = r.f32("a slot's α")?;
            let (theta, adam) = if learning == Learning::GuidingFraction {
                let theta = r.f64("a slot's θ")?;
                (
                    theta,
                    (r.f64("a slot's moment")?, r.f64("a slot's moment")?),
                )
            } else {
                (initial_theta(initial), (0.0, 0.0))
            };
            let in_range = (ALPHA_MIN as f32..=ALPHA_MAX as f32).contains(&alpha);
            let moments = adam.0.is_finite() && adam.1.is_finite() && adam.1 >= 0.0;
            if !in_range || !theta.is_finite() || !moments {
                return Err(format!(
                    "slot {slot} of the cache holds α = {alpha}, θ = {theta}, moments {adam:?}"
                ));
            }
            frozen.push(FrozenSlot {
                slot,
                count,
                alpha,
                theta,
                adam,
            });
        }
        let frozen_bytes = &bytes[..r.at];
        let n = r.count(terms * 16 + 12, "the added slots")?;
        let (mut added, mut added_sums, mut last) = (Vec::new(), Vec::new(), None);
        for _ in 0..n {
            let slot = read_slot(&mut r, &mut last)?;
            added.push((slot, r.u64("a slot's samples")?));
            for _ in 0..terms {
                added_sums.push(r.i128("a slot's sum")?);
            }
        }
        if r.at != bytes.len() {
            return Err(format!(
                "{} bytes after the cache's last slot",
                bytes.len() - r.at
            ));
        }
        Ok(Saved {
            geometry,
            steps,
            frozen,
            frozen_sums,
            frozen_bytes,
            added,
            added_sums,
        })
    }
}

/// Reads a saved cache's fields, each checked against the bytes left.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, field: &str) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(format!(
                "the cache's state is truncated: {field} needs {n} bytes at byte {}, it has {}",
                self.at,
                self.bytes.len()
            ));
        };
        let bytes: &'a [u8] = self.bytes;
        let taken = &bytes[self.at..end];
        self.at = end;
        Ok(taken)
    }

    fn array<const N: usize>(&mut self, field: &str) -> Result<[u8; N], String> {
        let mut array = [0; N];
        array.copy_from_slice(self.take(N, field)?);
        Ok(array)
    }

    fn u32(&mut self, field: &str) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.array(field)?))
    }

    fn u64(&mut self, field: &str) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.array(field)?))
    }

    fn i128(&mut self, field: &str) -> Result<i128, String> {
        Ok(i128::from_le_bytes(self.array(field)?))
    }

    fn f32(&mut self, field: &str) -> Result<f32, String> {
        Ok(f32::from_le_bytes(self.array(field)?))
    }

    fn f64(&mut self, field: &str) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.array(field)?))
    }

    /// A count of records of at least `width` bytes each that the bytes left can hold.
    fn count(&mut self, width: usize, field: &str) -> Result<usize, String> {
        let n = self.u32(field)? as usize;
        if n.saturating_mul(width) > self.bytes.len() - self.at {
            return Err(format!(
                "the cache's state is truncated: {n} of {field} do not fit in its {} bytes",
                self.bytes.len()
            ));
        }
        Ok(n)
    }
}

fn put(out: &mut Vec<u8>, bytes: &[u8]) {
    out.extend_from_slice(bytes);
}

fn learning_code(learning: Learning) -> u32 {
    match learning {
        Learning::SecondMoment => 0,
        Learning::GuidingFraction => 1,
    }
}

/// θ of a cell not yet learned: α = sigmoid(θ).
fn initial_theta(initial: f64) -> f64 {
    (initial / (1.0 - initial)).ln()
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
