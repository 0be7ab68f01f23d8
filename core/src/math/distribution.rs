//! Piecewise-constant 1D distribution, sampled in constant time with Walker's alias method.
//!
//! Inverting a CDF by binary search touches about log₂ n cache lines per sample; for an
//! environment map's 10⁶ cells those are cache misses, which made that search one of the
//! profile's hottest functions. An alias table answers with two reads.

/// One slot of the alias table: a uniform slot index keeps its own bin with probability
/// `keep`, and gives way to bin `alias` otherwise.
#[derive(Clone, Copy, Debug)]
struct AliasSlot {
    keep: f32,
    alias: u32,
}

/// A discrete distribution over `n` bins with probabilities proportional to the given weights.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    slots: Vec<AliasSlot>,
    pmf: Vec<f32>,
    total: f64,
}

/// Vose's construction of the alias table of `pmf` (which sums to 1), in f64.
fn alias_table(pmf: &[f64]) -> Vec<AliasSlot> {
    let n = pmf.len();
    let mut scaled: Vec<f64> = pmf.iter().map(|&p| p * n as f64).collect();
    let mut slots = vec![
        AliasSlot {
            keep: 1.0,
            alias: 0,
        };
        n
    ];
    for (i, slot) in slots.iter_mut().enumerate() {
        slot.alias = i as u32;
    }
    let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| scaled[i] < 1.0);
    while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
        small.pop();
        slots[s] = AliasSlot {
            keep: scaled[s] as f32,
            alias: l as u32,
        };
        scaled[l] -= 1.0 - scaled[s];
        if scaled[l] < 1.0 {
            large.pop();
            small.push(l);
        }
    }
    // What is left holds probability one up to rounding: it keeps its own bin, unless that bin
    // has none (rounding must never make a zero-weight bin reachable).
    let donor = pmf.iter().position(|&p| p > 0.0).unwrap_or(0) as u32;
    for i in small.into_iter().chain(large) {
        slots[i] = if pmf[i] > 0.0 {
            AliasSlot {
                keep: 1.0,
                alias: i as u32,
            }
        } else {
            AliasSlot {
                keep: 0.0,
                alias: donor,
            }
        };
    }
    slots
}

impl Distribution1D {
    /// Builds the distribution; `None` when no weight is positive and finite.
    pub fn new(weights: &[f32]) -> Option<Self> {
        let valid = |w: f32| {
            if w.is_finite() && w > 0.0 {
                w as f64
            } else {
                0.0
            }
        };
        let total: f64 = weights.iter().map(|&w| valid(w)).sum();
        if total <= 0.0 {
            return None;
        }
        let pmf: Vec<f64> = weights.iter().map(|&w| valid(w) / total).collect();
        Some(Distribution1D {
            slots: alias_table(&pmf),
            pmf: pmf.iter().map(|&p| p as f32).collect(),
            total,
        })
    }

    pub fn len(&self) -> usize {
        self.pmf.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }

    /// Sum of the weights the distribution was built from.
    pub fn total(&self) -> f64 {
        self.total
    }

    /// Probability of bin `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.pmf[i]
    }

    /// Picks a bin for `u` in [0, 1): returns the bin and `u` rescaled to [0, 1) within it,
    /// so the same random number can be reused for a continuous choice inside the bin.
    ///
    /// `u` picks a slot and a position in it; the slot keeps its bin for positions below its
    /// threshold and hands the rest to its alias. Either part, stretched back to [0, 1), is
    /// uniform, whichever slots a bin is reached from.
    #[inline]
    pub fn sample_reuse(&self, u: f32) -> (usize, f32) {
        let (slot, v) = slot_of(u, self.slots.len());
        let AliasSlot { keep, alias } = self.slots[slot];
        match split(v, keep) {
            (true, rescaled) => (slot, rescaled),
            (false, rescaled) => (alias as usize, rescaled),
        }
    }
}

/// The slot of `n` that `u` in [0, 1) falls in, and the position in it, in [0, 1).
#[inline]
fn slot_of(u: f32, n: usize) -> (usize, f32) {
    let x = u * n as f32;
    let slot = (x as usize).min(n - 1);
    (slot, x - slot as f32)
}

/// Whether position `v` of a slot keeps the slot's own bin (below `keep`), and `v` stretched
/// back to [0, 1) within the part it fell in.
#[inline]
fn split(v: f32, keep: f32) -> (bool, f32) {
    let (kept, rescaled) = if v < keep {
        (true, v / keep)
    } else {
        (false, (v - keep) / (1.0 - keep))
    };
    (kept, rescaled.clamp(0.0, 1.0 - f32::EPSILON / 2.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_or_zero_weights_give_none() {
        assert!(Distribution1D::new(&[]).is_none());
        assert!(Distribution1D::new(&[0.0, 0.0]).is_none());
        assert!(Distribution1D::new(&[f32::NAN, -1.0]).is_none());
    }

    #[test]
    fn frequencies_match_the_pmf_and_zero_bins_are_never_chosen() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0, 0.0]).unwrap();
        let n = 100_000;
        let mut counts = [0usize; 4];
        for k in 0..n {
            let (i, r) = d.sample_reuse((k as f32 + 0.5) / n as f32);
            assert!((0.0..1.0).contains(&r));
            counts[i] += 1;
        }
        assert_eq!(counts[1], 0);
        assert_eq!(counts[3], 0);
        assert!((counts[0] as f32 / n as f32 - 0.25).abs() < 1e-3);
        assert!((d.pmf(2) - 0.75).abs() < 1e-6);
    }

    /// The position reused within a bin is uniform, whether the bin was reached from its own
    /// alias slot or from others'.
    #[test]
    fn reused_positions_are_uniform_within_each_bin() {
        let weights = [3.0, 0.0, 1.0, 5.0, 0.5, 2.0, 0.0, 0.25];
        let d = Distribution1D::new(&weights).unwrap();
        let n = 400_000;
        let (mut counts, mut sums, mut low) = ([0usize; 8], [0.0f64; 8], [0usize; 8]);
        for k in 0..n {
            let (i, r) = d.sample_reuse((k as f32 + 0.5) / n as f32);
            assert!((0.0..1.0).contains(&r));
            counts[i] += 1;
            sums[i] += r as f64;
            low[i] += (r < 0.25) as usize;
        }
        let total: f32 = weights.iter().sum();
        for i in 0..8 {
            let expected = weights[i] / total;
            assert!(
                (counts[i] as f32 / n as f32 - expected).abs() < 1e-4,
                "bin {i}"
            );
            if counts[i] > 0 {
                let c = counts[i] as f64;
                assert!(
                    (sums[i] / c - 0.5).abs() < 1e-3,
                    "bin {i}: mean {}",
                    sums[i] / c
                );
                assert!((low[i] as f64 / c - 0.25).abs() < 1e-3, "bin {i}");
            }
        }
    }
}

/// A piecewise-constant density on [0, 1]², sampled by its marginal over rows and the
/// conditional distribution of the chosen row (pbrt's PiecewiseConstant2D).
#[derive(Clone, Debug)]
pub struct Distribution2D {
    /// Every row's alias table, rows back to back. A sample reads a uniformly chosen slot of its
    /// row, which for a large table (an environment map's) is a cache miss: at 8 bytes a slot,
    /// twice as much of the table stays in the caches as with the densities beside each slot.
    slots: Vec<AliasSlot>,
    /// Density of each cell with respect to area on the unit square, row-major.
    pdfs: Vec<f32>,
    marginal: Distribution1D,
    nx: usize,
}

impl Distribution2D {
    /// `values` holds `ny` rows of `nx` non-negative weights; `None` when all are zero.
    pub fn new(values: &[f32], nx: usize, ny: usize) -> Option<Self> {
        assert_eq!(
            values.len(),
            nx * ny,
            "Distribution2D: {nx}x{ny} values expected"
        );
        let rows: Vec<Option<Distribution1D>> =
            values.chunks_exact(nx).map(Distribution1D::new).collect();
        let row_weights: Vec<f32> = rows
            .iter()
            .map(|r| r.as_ref().map_or(0.0, |d| d.total() as f32))
            .collect();
        let marginal = Distribution1D::new(&row_weights)?;
        let scale = (nx * ny) as f32;
        let mut slots = crate::huge_pages::vec_with_capacity(nx * ny);
        let mut pdfs = crate::huge_pages::vec_with_capacity(nx * ny);
        for (row, dist) in rows.iter().enumerate() {
            match dist {
                Some(dist) => {
                    slots.extend_from_slice(&dist.slots);
                    pdfs.extend((0..nx).map(|col| marginal.pmf(row) * dist.pmf(col) * scale));
                }
                // Never chosen by the marginal; zero density.
                None => {
                    slots.extend((0..nx).map(|col| AliasSlot {
                        keep: 1.0,
                        alias: col as u32,
                    }));
                    pdfs.extend(std::iter::repeat_n(0.0, nx));
                }
            }
        }
        Some(Distribution2D {
            slots,
            pdfs,
            marginal,
            nx,
        })
    }

    /// A point in [0, 1)², distributed with the density [`Distribution2D::pdf`] gives (which a
    /// sample does not read: where the caller needs it, it often has it at hand already).
    #[inline]
    pub fn sample(&self, u: glam::Vec2) -> glam::Vec2 {
        let (col, row, within) = self.sample_cell(u);
        let ny = self.marginal.len();
        glam::Vec2::new(
            (col as f32 + within.x) / self.nx as f32,
            (row as f32 + within.y) / ny as f32,
        )
    }

    /// A cell (column, row) and a uniformly distributed position within it in [0, 1)²: for
    /// warps that continue inside the cell (a bilinear patch) without the rounding of a round
    /// trip through [0, 1)². The cell's density is [`Distribution2D::cell_pdf`].
    #[inline]
    pub fn sample_cell(&self, u: glam::Vec2) -> (usize, usize, glam::Vec2) {
        let (row, slot, uy, v) = self.start(u);
        let AliasSlot { keep, alias } = self.slots[row * self.nx + slot];
        let (col, ux) = match split(v, keep) {
            (true, ux) => (slot, ux),
            (false, ux) => (alias as usize, ux),
        };
        (col, row, glam::Vec2::new(ux, uy))
    }

    /// Where sampling with `u` starts: the row (from the marginal, with its reused number) and
    /// the alias slot within it (with the number's position inside the slot).
    #[inline]
    fn start(&self, u: glam::Vec2) -> (usize, usize, f32, f32) {
        let (row, uy) = self.marginal.sample_reuse(u.y);
        let (slot, v) = slot_of(u.x, self.nx);
        (row, slot, uy, v)
    }

    /// Prefetches what [`Distribution2D::sample_cell`] of `u` will read from memory (the
    /// alias slot of the cell it starts from), and returns that cell's row-major index, which
    /// is the sampled cell unless the slot sends the sample to its alias: a caller may prefetch
    /// its own per-cell data there.
    #[inline]
    pub fn prefetch_sample(&self, u: glam::Vec2) -> usize {
        let (row, slot, _, _) = self.start(u);
        let index = row * self.nx + slot;
        super::cache::prefetch(&self.slots[index]);
        index
    }

    /// Density of cell (`col`, `row`) (with respect to area on the unit square).
    #[inline]
    pub fn cell_pdf(&self, col: usize, row: usize) -> f32 {
        self.pdfs[row * self.nx + col]
    }

    /// Density at a point of [0, 1]² (with respect to area on the unit square).
    #[inline]
    pub fn pdf(&self, p: glam::Vec2) -> f32 {
        let ny = self.marginal.len();
        let col = ((p.x * self.nx as f32) as usize).min(self.nx - 1);
        let row = ((p.y * ny as f32) as usize).min(ny - 1);
        self.cell_pdf(col, row)
    }
}

#[cfg(test)]
mod tests_2d {
    use super::*;

    /// The prefetched cell is in the sampled row, and is the sampled cell or the one its slot
    /// sends samples to; for a smooth distribution, mostly the sampled cell itself.
    #[test]
    fn prefetched_cells_are_the_sampled_ones_or_their_alias_slots() {
        let (nx, ny) = (16, 8);
        let values: Vec<f32> = (0..nx * ny).map(|i| 1.0 + (i % 7) as f32).collect();
        let d = Distribution2D::new(&values, nx, ny).unwrap();
        let mut sampler = crate::sampler::Sampler::new(3, 1, 4);
        let mut same = 0;
        for _ in 0..10_000 {
            let u = sampler.next_2d();
            let index = d.prefetch_sample(u);
            let (col, row, _) = d.sample_cell(u);
            assert_eq!(index / nx, row, "u {u}");
            let slot = d.slots[index];
            assert!(index % nx == col || slot.alias as usize == col, "u {u}");
            same += usize::from(index % nx == col);
        }
        assert!(
            same > 5_000,
            "only {same} of 10 000 prefetched cells sampled"
        );
    }

    #[test]
    fn sampled_points_have_the_tabulated_density() {
        let values = [0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 3.0, 0.5, 0.0];
        let d = Distribution2D::new(&values, 3, 3).unwrap();
        let total: f32 = values.iter().sum();
        let mut counts = [0usize; 9];
        let n = 300;
        for i in 0..n {
            for j in 0..n {
                let u = glam::Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let p = d.sample(u);
                let cell = (p.y * 3.0) as usize * 3 + (p.x * 3.0) as usize;
                assert!(values[cell] > 0.0, "sampled a zero cell");
                counts[cell] += 1;
            }
        }
        for (c, v) in counts.iter().zip(values) {
            let expected = v / total;
            assert!((*c as f32 / (n * n) as f32 - expected).abs() < 2e-3);
        }
    }
}
