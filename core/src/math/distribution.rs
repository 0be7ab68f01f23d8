//! Piecewise-constant 1D distribution, sampled by inverting its CDF.

/// A discrete distribution over `n` bins with probabilities proportional to the given weights.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    cdf: Vec<f32>,
    pmf: Vec<f32>,
    total: f64,
}

impl Distribution1D {
    /// Builds the distribution; `None` when no weight is positive and finite.
    pub fn new(weights: &[f32]) -> Option<Self> {
        let mut total = 0.0f64;
        let mut cdf = Vec::with_capacity(weights.len() + 1);
        cdf.push(0.0);
        for &w in weights {
            if w.is_finite() && w > 0.0 {
                total += w as f64;
            }
            cdf.push(total as f32);
        }
        if total <= 0.0 {
            return None;
        }
        let inv = 1.0 / total;
        let pmf = weights
            .iter()
            .map(|&w| {
                if w.is_finite() && w > 0.0 {
                    (w as f64 * inv) as f32
                } else {
                    0.0
                }
            })
            .collect();
        let cdf = cdf.iter().map(|&c| (c as f64 * inv) as f32).collect();
        Some(Distribution1D { cdf, pmf, total })
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
    pub fn sample_reuse(&self, u: f32) -> (usize, f32) {
        // Last index whose CDF value is <= u, skipping zero-probability bins.
        let n = self.pmf.len();
        let mut i = self
            .cdf
            .partition_point(|&c| c <= u)
            .saturating_sub(1)
            .min(n - 1);
        while self.pmf[i] == 0.0 && i > 0 {
            i -= 1;
        }
        while self.pmf[i] == 0.0 && i + 1 < n {
            i += 1;
        }
        let rescaled = ((u - self.cdf[i]) / self.pmf[i]).clamp(0.0, 1.0 - f32::EPSILON / 2.0);
        (i, rescaled)
    }
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
}

/// A piecewise-constant density on [0, 1]², sampled by its marginal over rows and the
/// conditional distribution of the chosen row (pbrt's PiecewiseConstant2D).
#[derive(Clone, Debug)]
pub struct Distribution2D {
    /// One distribution per row (y); `None` for rows of zero weight, which are never chosen.
    rows: Vec<Option<Distribution1D>>,
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
        Some(Distribution2D { rows, marginal, nx })
    }

    /// A point in [0, 1)² and its density with respect to area on the unit square.
    pub fn sample(&self, u: glam::Vec2) -> (glam::Vec2, f32) {
        let (row, uy) = self.marginal.sample_reuse(u.y);
        let dist = self.rows[row]
            .as_ref()
            .expect("the marginal never picks an empty row");
        let (col, ux) = dist.sample_reuse(u.x);
        let ny = self.marginal.len();
        let point = glam::Vec2::new(
            (col as f32 + ux) / self.nx as f32,
            (row as f32 + uy) / ny as f32,
        );
        let pdf = self.marginal.pmf(row) * dist.pmf(col) * (self.nx * ny) as f32;
        (point, pdf)
    }

    /// Density at a point of [0, 1]² (with respect to area on the unit square).
    pub fn pdf(&self, p: glam::Vec2) -> f32 {
        let ny = self.marginal.len();
        let col = ((p.x * self.nx as f32) as usize).min(self.nx - 1);
        let row = ((p.y * ny as f32) as usize).min(ny - 1);
        match &self.rows[row] {
            Some(dist) => self.marginal.pmf(row) * dist.pmf(col) * (self.nx * ny) as f32,
            None => 0.0,
        }
    }
}

#[cfg(test)]
mod tests_2d {
    use super::*;

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
                let (p, pdf) = d.sample(u);
                assert!((pdf - d.pdf(p)).abs() < 1e-4, "{pdf} vs {}", d.pdf(p));
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
