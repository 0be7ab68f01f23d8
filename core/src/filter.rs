//! Reconstruction filters, as Mitsuba 3 defines them (`src/rfilters/`), applied by filter
//! importance sampling: each camera sample's film position is drawn from the filter around its
//! pixel's centre and its radiance weighted by f/p (the normalised filter over the density the
//! position was drawn from); a pixel's estimate is the sum of its samples' weighted radiance
//! divided by their count. Every sample belongs to one pixel, so pixels stay independent and
//! renders split by tiles or sample ranges add up exactly.
//!
//! - `box`: the pixel itself, [−½, ½)², sampled uniformly (weight 1): today's camera samples,
//!   bit for bit.
//! - `tent`: f(x) = max(0, 1 − |x|/r) per axis (radius r, default 1), sampled exactly by
//!   inverting its distribution (weight 1).
//! - `gaussian`: Mitsuba's windowed Gaussian, f(x) = max(0, exp(−x²/2σ²) − exp(−r²/2σ²)) with
//!   r = 4σ (σ default 0.5 pixel), sampled per axis from a piecewise-constant table of its
//!   integral over [`GAUSSIAN_BINS`] bins, uniformly within a bin: the weight is
//!   f(x)·Δ/(Z·P_k) for a position x in bin k of width Δ and probability P_k (Z the filter's
//!   integral), about f(x)/f̄_k: within 3 % of 1 up to 2σ from the centre, 7 % up to 3.5σ,
//!   and from 2.04 to 0 across the last bin, where f falls to 0 at the cut (σ = 0.5 pixel;
//!   computed by integrating the filter over the bins).
//!
//! The 2D filter is the product of the axes' (as Mitsuba's image blocks weigh samples). At the
//! film's edges Mitsuba takes samples only inside the film (`sample_border` off), so an edge
//! pixel's filter is cut by the edge and renormalised: here a position drawn outside the film
//! weighs 0 and the others are divided by the filter's mass inside the film (per axis,
//! integrated once when the filter is built). The edges are those of the whole film, not of a
//! crop window, so that a window renders the pixels the whole film renders.

use glam::{UVec2, Vec2};

/// Bins of the Gaussian's per-axis sampling table, over [−r, r].
pub const GAUSSIAN_BINS: usize = 256;

/// Largest `radius` of a tent and `stddev` × 4 of a Gaussian, in pixels: a filter wider than
/// this is refused (its samples would land far from their pixel).
pub const MAX_FILTER_RADIUS: f32 = 32.0;

/// A reconstruction filter, ready to place camera samples.
#[derive(Clone, Debug)]
pub struct Filter {
    shape: Shape,
    /// Per axis, indexed by a pixel's distance to the film's first edge (0 for the first pixel):
    /// the normalised filter mass beyond that edge, for the pixels the filter reaches past it.
    outside: Vec<f32>,
}

#[derive(Clone, Debug)]
enum Shape {
    Box,
    Tent { radius: f32 },
    Gaussian(Gaussian),
}

#[derive(Clone, Debug)]
struct Gaussian {
    stddev: f32,
    radius: f32,
    /// exp(−r²/2σ²), subtracted so that the filter reaches 0 at the radius.
    floor: f32,
    /// Cumulative normalised mass at the bins' edges, GAUSSIAN_BINS + 1 entries from 0 to 1.
    cdf: Vec<f32>,
    /// Per bin, Δ / m_k (m_k normalised): a position's weight is f(x) times it.
    weight_scale: Vec<f32>,
}

impl Filter {
    /// The box over the pixel (no parameter, as Mitsuba's).
    pub fn box_filter() -> Self {
        Filter {
            shape: Shape::Box,
            outside: Vec::new(),
        }
    }

    /// A tent of `radius` pixels, in (0, [`MAX_FILTER_RADIUS`]].
    pub fn tent(radius: f32) -> Result<Self, String> {
        if !(radius > 0.0 && radius <= MAX_FILTER_RADIUS) {
            return Err(format!(
                "tent filter `radius` must be in (0, {MAX_FILTER_RADIUS}] pixels, found {radius}"
            ));
        }
        Ok(Self::with_edges(Shape::Tent { radius }))
    }

    /// Mitsuba's windowed Gaussian of standard deviation `stddev` pixels, cut at 4σ, with 4σ in
    /// (0, [`MAX_FILTER_RADIUS`]].
    pub fn gaussian(stddev: f32) -> Result<Self, String> {
        if !(stddev > 0.0 && 4.0 * stddev <= MAX_FILTER_RADIUS) {
            return Err(format!(
                "gaussian filter `stddev` must be in (0, {}] pixels, found {stddev}",
                MAX_FILTER_RADIUS / 4.0
            ));
        }
        let radius = 4.0 * stddev;
        let mut g = Gaussian {
            stddev,
            radius,
            floor: (-(radius as f64).powi(2) / (2.0 * (stddev as f64).powi(2))).exp() as f32,
            cdf: Vec::new(),
            weight_scale: Vec::new(),
        };
        let width = 2.0 * radius as f64 / GAUSSIAN_BINS as f64;
        let shape = |x: f64| g.eval_f64(x);
        let masses: Vec<f64> = (0..GAUSSIAN_BINS)
            .map(|k| {
                let a = -(radius as f64) + k as f64 * width;
                integrate(&shape, a, a + width)
            })
            .collect();
        let total: f64 = masses.iter().sum();
        let mut cdf = vec![0.0f32];
        let mut running = 0.0;
        for m in &masses {
            running += m;
            cdf.push((running / total) as f32);
        }
        cdf[GAUSSIAN_BINS] = 1.0;
        // The density is the stored table's (its f32 steps), p = (c_{k+1} − c_k)/Δ, so the
        // weight f/(Z·p) is computed from those steps, not from the exact masses.
        g.weight_scale = cdf
            .windows(2)
            .map(|c| {
                let step = c[1] as f64 - c[0] as f64;
                if step > 0.0 {
                    (width / (total * step)) as f32
                } else {
                    0.0
                }
            })
            .collect();
        g.cdf = cdf;
        Ok(Self::with_edges(Shape::Gaussian(g)))
    }

    /// The filter of `shape`, with its mass beyond the film's edge for the pixels near it.
    fn with_edges(shape: Shape) -> Self {
        let mut filter = Filter {
            shape,
            outside: Vec::new(),
        };
        let radius = filter.radius() as f64;
        let total = filter.integral(-radius, radius);
        // Pixel k (from 0) has its centre k + ½ from the edge.
        let mut k = 0;
        while (k as f64 + 0.5) < radius {
            let beyond = filter.integral(-radius, -(k as f64 + 0.5)) / total;
            filter.outside.push(beyond as f32);
            k += 1;
        }
        filter
    }

    /// Half the width of the filter's support, in pixels.
    pub fn radius(&self) -> f32 {
        match &self.shape {
            Shape::Box => 0.5,
            Shape::Tent { radius } => *radius,
            Shape::Gaussian(g) => g.radius,
        }
    }

    /// The filter's profile along one axis at `x` pixels from the pixel's centre (not
    /// normalised; 1 at the centre for box and tent, as Mitsuba's `eval`).
    pub fn eval(&self, x: f32) -> f32 {
        match &self.shape {
            Shape::Box => f32::from(u8::from((-0.5..0.5).contains(&x))),
            Shape::Tent { radius } => (1.0 - x.abs() / radius).max(0.0),
            Shape::Gaussian(g) => g.eval_f64(x as f64) as f32,
        }
    }

    /// The density, along one axis, with which [`sample_axis`](Self::sample_axis) draws the
    /// offset `x`.
    pub fn pdf(&self, x: f32) -> f32 {
        match &self.shape {
            Shape::Box | Shape::Tent { .. } => self.eval(x) / self.eval_integral(),
            Shape::Gaussian(g) => match g.bin(x) {
                Some(k) => {
                    let width = 2.0 * g.radius / GAUSSIAN_BINS as f32;
                    (g.cdf[k + 1] - g.cdf[k]) / width
                }
                None => 0.0,
            },
        }
    }

    /// ∫ of [`eval`](Self::eval) over the line.
    fn eval_integral(&self) -> f32 {
        let r = self.radius() as f64;
        self.integral(-r, r) as f32
    }

    /// ∫ of the profile from `a` to `b` (within the support), in f64.
    fn integral(&self, a: f64, b: f64) -> f64 {
        match &self.shape {
            Shape::Box => (b.min(0.5) - a.max(-0.5)).max(0.0),
            Shape::Tent { radius } => {
                let r = *radius as f64;
                let tent = |x: f64| (1.0 - x.abs() / r).max(0.0);
                // Split at the kink, where Simpson's rule is not exact.
                if a < 0.0 && b > 0.0 {
                    integrate(&tent, a, 0.0) + integrate(&tent, 0.0, b)
                } else {
                    integrate(&tent, a, b)
                }
            }
            Shape::Gaussian(g) => integrate(&|x| g.eval_f64(x), a, b),
        }
    }

    /// An offset from the pixel's centre along one axis, drawn with `u` in [0, 1) from the
    /// filter (tabulated for the Gaussian), and its weight f/p (normalised f).
    #[inline]
    pub fn sample_axis(&self, u: f32) -> (f32, f32) {
        match &self.shape {
            Shape::Box => (u - 0.5, 1.0),
            Shape::Tent { radius } => {
                let x = if u < 0.5 {
                    (2.0 * u).sqrt() - 1.0
                } else {
                    1.0 - (2.0 - 2.0 * u).sqrt()
                };
                (x * radius, 1.0)
            }
            Shape::Gaussian(g) => g.sample(u),
        }
    }

    /// The film position of a camera sample of `pixel` drawn with `u` (each in [0, 1)), on a
    /// film of `size` pixels, and its weight. The box gives `pixel + u`, weight 1, exactly.
    #[inline(always)]
    pub fn film_position(&self, pixel: UVec2, u: Vec2, size: UVec2) -> (Vec2, f32) {
        match self.shape {
            Shape::Box => (pixel.as_vec2() + u, 1.0),
            _ => self.film_position_wide(pixel, u, size),
        }
    }

    /// [`film_position`](Self::film_position) for the filters that reach past their pixel.
    #[inline(never)]
    fn film_position_wide(&self, pixel: UVec2, u: Vec2, size: UVec2) -> (Vec2, f32) {
        let (dx, wx) = self.sample_axis(u.x);
        let (dy, wy) = self.sample_axis(u.y);
        let film = pixel.as_vec2() + Vec2::splat(0.5) + Vec2::new(dx, dy);
        let inside = |p: f32, n: u32| p >= 0.0 && p < n as f32;
        if !(inside(film.x, size.x) && inside(film.y, size.y)) {
            return (film, 0.0);
        }
        let kept = |i: u32, n: u32| {
            let beyond = |k: u32| self.outside.get(k as usize).copied().unwrap_or(0.0);
            1.0 - beyond(i) - beyond(n - 1 - i)
        };
        let weight = wx * wy / (kept(pixel.x, size.x) * kept(pixel.y, size.y));
        (film, weight)
    }
}

impl Gaussian {
    fn eval_f64(&self, x: f64) -> f64 {
        let s = self.stddev as f64;
        ((-x * x / (2.0 * s * s)).exp() - self.floor as f64).max(0.0)
    }

    /// The bin of the table holding `x`, if it is within the support.
    fn bin(&self, x: f32) -> Option<usize> {
        let t = (x + self.radius) / (2.0 * self.radius) * GAUSSIAN_BINS as f32;
        (t >= 0.0 && t < GAUSSIAN_BINS as f32).then(|| (t as usize).min(GAUSSIAN_BINS - 1))
    }

    #[inline]
    fn sample(&self, u: f32) -> (f32, f32) {
        // The last edge ≤ u (cdf[0] = 0 ≤ u < 1 = cdf[BINS]); a bin of no mass is never chosen.
        let k = self
            .cdf
            .partition_point(|&c| c <= u)
            .clamp(1, GAUSSIAN_BINS)
            - 1;
        let (lo, hi) = (self.cdf[k], self.cdf[k + 1]);
        let within = ((u - lo) / (hi - lo)).clamp(0.0, 1.0);
        let width = 2.0 * self.radius / GAUSSIAN_BINS as f32;
        let x = -self.radius + (k as f32 + within) * width;
        let f = ((-x * x / (2.0 * self.stddev * self.stddev)).exp() - self.floor).max(0.0);
        (x, f * self.weight_scale[k])
    }
}

/// ∫ₐᵇ f by Simpson's rule over 2048 intervals, in f64 (the filters are smooth within the
/// intervals they are integrated over: error below 1e-12 of their mass).
fn integrate(f: &dyn Fn(f64) -> f64, a: f64, b: f64) -> f64 {
    if b <= a {
        return 0.0;
    }
    const N: usize = 2048;
    let h = (b - a) / N as f64;
    let mut sum = f(a) + f(b);
    for i in 1..N {
        sum += f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    sum * h / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chi2::{FAMILY_FALSE_ALARM, histogram_p_value, sidak, test_sampler, z_limit};

    fn filters() -> Vec<(&'static str, Filter)> {
        vec![
            ("box", Filter::box_filter()),
            ("tent 1", Filter::tent(1.0).unwrap()),
            ("tent 1.25", Filter::tent(1.25).unwrap()),
            ("gaussian 0.5", Filter::gaussian(0.5).unwrap()),
            ("gaussian 0.3", Filter::gaussian(0.3).unwrap()),
        ]
    }

    /// Positions drawn along one axis follow the sampling density (`pdf`), by chi-square over
    /// 64 bins of the support; for box and tent that density is the normalised filter itself.
    /// One family: the five filters' tests share its false-alarm rate (Šidák).
    #[test]
    fn axis_sampling_follows_its_density() {
        let alpha = sidak(FAMILY_FALSE_ALARM, filters().len());
        for (name, filter) in filters() {
            let r = filter.radius();
            const BINS: usize = 64;
            const SAMPLES: usize = 400_000;
            let mut observed = vec![0.0; BINS];
            let mut sampler = test_sampler(17);
            for _ in 0..SAMPLES {
                let (x, _) = filter.sample_axis(sampler.next_1d());
                assert!(x.abs() <= r, "{name}: {x} outside ±{r}");
                let bin = (((x + r) / (2.0 * r)) * BINS as f32) as usize;
                observed[bin.min(BINS - 1)] += 1.0;
            }
            let width = 2.0 * r as f64 / BINS as f64;
            let expected: Vec<f64> = (0..BINS)
                .map(|b| {
                    let a = -r as f64 + b as f64 * width;
                    // The density integrated over the bin (piecewise: fine steps).
                    let n = 64;
                    (0..n)
                        .map(|i| {
                            let x = a + (i as f64 + 0.5) * width / n as f64;
                            filter.pdf(x as f32) as f64 * width / n as f64
                        })
                        .sum::<f64>()
                        * SAMPLES as f64
                })
                .collect();
            let p = histogram_p_value(&observed, &expected);
            assert!(
                p > alpha,
                "{name}: chi-square p = {p} (seed {})",
                crate::chi2::test_seed()
            );
        }
    }

    /// Box and tent are sampled exactly: every weight is 1. The Gaussian's weight is the
    /// normalised filter over the density, f(x)/(Z·p(x)), at every position (Z its integral).
    #[test]
    fn weights_are_the_filter_over_the_density() {
        let mut sampler = test_sampler(18);
        for (name, filter) in filters() {
            let z = filter.eval_integral();
            for _ in 0..20_000 {
                let (x, w) = filter.sample_axis(sampler.next_1d());
                match name {
                    n if n.starts_with("box") || n.starts_with("tent") => {
                        assert_eq!(w, 1.0, "{name}")
                    }
                    _ => {
                        let expected = filter.eval(x) / (z * filter.pdf(x));
                        assert!(
                            (w - expected).abs() <= 1e-4 * expected.max(1.0),
                            "{name}: {x}"
                        );
                        assert!((0.0..2.1).contains(&w), "{name}: weight {w} at {x}");
                    }
                }
            }
        }
    }

    /// The weighted positions estimate the normalised filter, so that a pixel's estimate is
    /// unbiased: the mean weight in each of 32 bins, times the bin's probability, is the
    /// filter's mass there, within the z-limit of the standard error measured from the samples
    /// (one family of 5 × 32 z-tests, Šidák; the Gaussian's table is what is checked here).
    #[test]
    fn weighted_samples_estimate_the_normalised_filter() {
        let limit = z_limit(sidak(FAMILY_FALSE_ALARM, 32 * filters().len()));
        for (name, filter) in filters() {
            let r = filter.radius();
            let z = filter.integral(-r as f64, r as f64);
            const BINS: usize = 32;
            const SAMPLES: usize = 400_000;
            let (mut sum, mut sum2) = (vec![0.0f64; BINS], vec![0.0f64; BINS]);
            let mut sampler = test_sampler(19);
            for _ in 0..SAMPLES {
                let (x, w) = filter.sample_axis(sampler.next_1d());
                let bin = ((((x + r) / (2.0 * r)) * BINS as f32) as usize).min(BINS - 1);
                sum[bin] += w as f64;
                sum2[bin] += (w as f64).powi(2);
            }
            let width = 2.0 * r as f64 / BINS as f64;
            for b in 0..BINS {
                let a = -r as f64 + b as f64 * width;
                let expected = filter.integral(a, a + width) / z;
                let mean = sum[b] / SAMPLES as f64;
                let var = (sum2[b] / SAMPLES as f64 - mean * mean).max(1e-30);
                let se = (var / SAMPLES as f64).sqrt();
                assert!(
                    (mean - expected).abs() <= limit * se + 1e-9,
                    "{name} bin {b}: {mean} against {expected} (standard error {se})"
                );
            }
        }
    }

    /// The box is today's camera sample: `pixel + u`, weight 1, bit for bit.
    #[test]
    fn the_box_places_samples_as_before() {
        let filter = Filter::box_filter();
        let mut sampler = test_sampler(20);
        for _ in 0..1000 {
            let u = sampler.next_2d();
            let pixel = UVec2::new(3, 7);
            let (film, w) = filter.film_position(pixel, u, UVec2::new(8, 8));
            assert_eq!(film, pixel.as_vec2() + u);
            assert_eq!(w, 1.0);
        }
    }

    /// At the film's edge the filter is cut and renormalised: an edge pixel's weighted samples
    /// still integrate to 1 (positions outside weigh 0), as a pixel far from the edges does, so
    /// that a constant image renders unbiased up to its corners (one family of 5 × 3 z-tests).
    #[test]
    fn edge_pixels_renormalise_the_cut_filter() {
        let limit = z_limit(sidak(FAMILY_FALSE_ALARM, 3 * filters().len()));
        for (name, filter) in filters() {
            for pixel in [UVec2::new(0, 0), UVec2::new(1, 9), UVec2::new(5, 5)] {
                let size = UVec2::new(10, 10);
                let mut sampler = test_sampler(21);
                let n = 200_000;
                let (mut sum, mut sum2) = (0.0f64, 0.0f64);
                for _ in 0..n {
                    let (film, w) = filter.film_position(pixel, sampler.next_2d(), size);
                    if w > 0.0 {
                        assert!(film.cmpge(Vec2::ZERO).all() && film.cmplt(size.as_vec2()).all());
                    }
                    sum += w as f64;
                    sum2 += (w as f64).powi(2);
                }
                let mean = sum / n as f64;
                let se = ((sum2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
                assert!(
                    (mean - 1.0).abs() <= limit * se + 1e-6,
                    "{name} {pixel}: mean weight {mean} (standard error {se})"
                );
            }
        }
    }

    #[test]
    fn filters_out_of_range_are_refused() {
        for bad in [0.0, -1.0, f32::NAN, 1e9] {
            assert!(Filter::tent(bad).unwrap_err().contains("radius"));
            assert!(Filter::gaussian(bad).unwrap_err().contains("stddev"));
        }
    }
}
