//! A [`VertexCache`] between passes as bytes, for state and shard files: saved, restored, and
//! merged across the shards of a pass (the parent module has the argument).

use super::{ALPHA_MAX, ALPHA_MIN, Learning, SLOTS, VertexCache, terms};
use std::collections::BTreeMap;
use std::sync::atomic::Ordering;

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
pub(super) fn initial_theta(initial: f64) -> f64 {
    (initial / (1.0 - initial)).ln()
}
