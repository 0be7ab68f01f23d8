//! Reconstruction filters as Mitsuba 3's film applies them, by filter importance sampling: each
//! camera sample's film position is drawn from the filter around its pixel's centre and its
//! radiance weighted by f/p (the normalised filter over the density the position was drawn
//! from); a pixel's estimate is the sum of its samples' weighted radiance divided by their
//! count (not by the weights' sum, a ratio estimator that is biased). Every sample belongs to
//! one pixel, so pixels stay independent and renders split by tiles or sample ranges add up
//! exactly.
//!
//! - `box`: the pixel itself, [−½, ½)², sampled uniformly (weight 1): today's camera samples,
//!   bit for bit.
//! - `tent`: g(x) = max(0, 1 − |x|/r) per axis (radius r, default 1).
//! - `gaussian`: Mitsuba's windowed Gaussian, g(x) = max(0, exp(−x²/2σ²) − exp(−r²/2σ²)) with
//!   r = 4σ (σ default 0.5 pixel).
//!
//! Mitsuba's image blocks do not weigh samples by g itself but by its table
//! (`ReconstructionFilter::eval_discretized`, 31 steps per radius): f(x) = g(i·Δ) for
//! i = ⌊|x|/Δ⌋ < 31, Δ = r/31, and 0 beyond r — a staircase that takes each step's value at its
//! inner edge, up to 10 % above g (at 1σ); measured on Mitsuba 3.9.1's `ImageBlock::put`, whose
//! weights are these values. lumis applies that staircase, so that its images are Mitsuba's: the
//! 62 steps over [−r, r] are sampled in proportion to their mass and uniformly within, so each
//! weight f·Δ/(Z·P_k) (Z the staircase's integral, P_k the step's stored probability) is 1
//! up to the rounding of the stored probabilities.
//!
//! The 2D filter is the product of the axes' (as Mitsuba's image blocks weigh samples). At the
//! film's edges Mitsuba takes samples only inside the film (`sample_border` off), so an edge
//! pixel's filter is cut by the edge and renormalised: here a position drawn outside the film
//! weighs 0 and the others are divided by the filter's mass inside the film (per axis,
//! integrated once when the filter is built). The edges are those of the whole film, not of a
//! crop window, so that a window renders the pixels the whole film renders.

use glam::{UVec2, Vec2};

/// Steps of Mitsuba's filter table per radius (`MI_FILTER_RESOLUTION`).
pub const STEPS: usize = 31;

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
    /// A tent or a Gaussian, as Mitsuba's table of it (boxed: the box's filter stays small).
    Staircase(Box<Staircase>),
}

/// Mitsuba's tabulated filter over [−r, r]: `2 · STEPS` steps of width Δ = r / STEPS.
#[derive(Clone, Debug)]
struct Staircase {
    radius: f32,
    /// Δ, the width of a step.
    step: f32,
    /// g(i·Δ) for i in 0..STEPS: the value on the steps at distance [iΔ, (i+1)Δ) from the centre.
    values: [f64; STEPS],
    /// Cumulative normalised mass at the steps' edges, from −r: 2·STEPS + 1 entries, 0 to 1.
    cdf: Vec<f32>,
    /// Per step (from −r), f·Δ/(Z·P_k) with the stored P_k: a position's weight.
    weights: Vec<f32>,
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
        let r = radius as f64;
        Ok(Self::staircase(radius, |x| (1.0 - x / r).max(0.0)))
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
        let alpha = -1.0 / (2.0 * (stddev as f64).powi(2));
        let floor = (alpha * (radius as f64).powi(2)).exp();
        Ok(Self::staircase(radius, |x| {
            ((alpha * x * x).exp() - floor).max(0.0)
        }))
    }

    /// The table of `profile` (g of the distance to the centre) over `radius`, with its
    /// sampling distribution and its mass beyond the film's edge for the pixels near it.
    fn staircase(radius: f32, profile: impl Fn(f64) -> f64) -> Self {
        let step = radius / STEPS as f32;
        let values: [f64; STEPS] = std::array::from_fn(|i| profile(i as f64 * step as f64));
        // Steps from −r: the first STEPS mirror the last.
        let value = |k: usize| values[if k < STEPS { STEPS - 1 - k } else { k - STEPS }];
        let total: f64 = (0..2 * STEPS).map(value).sum();
        let mut cdf = vec![0.0f32];
        let mut running = 0.0;
        for k in 0..2 * STEPS {
            running += value(k);
            cdf.push((running / total) as f32);
        }
        cdf[2 * STEPS] = 1.0;
        // The density is the stored table's (its f32 steps), p = (c_{k+1} − c_k)/Δ, so the
        // weight f/(Z·p) is computed from those steps, not from the exact masses.
        let weights = (0..2 * STEPS)
            .map(|k| {
                let p = cdf[k + 1] as f64 - cdf[k] as f64;
                if p > 0.0 {
                    (value(k) / (total * p)) as f32
                } else {
                    0.0
                }
            })
            .collect();
        let mut filter = Filter {
            shape: Shape::Staircase(Box::new(Staircase {
                radius,
                step,
                values,
                cdf,
                weights,
            })),
            outside: Vec::new(),
        };
        let r = radius as f64;
        let mass = filter.integral(-r, r);
        // Pixel k (from 0) has its centre k + ½ from the edge.
        let mut k = 0;
        while (k as f64 + 0.5) < r {
            let beyond = filter.integral(-r, -(k as f64 + 0.5)) / mass;
            filter.outside.push(beyond as f32);
            k += 1;
        }
        filter
    }

    /// Half the width of the filter's support, in pixels.
    pub fn radius(&self) -> f32 {
        match &self.shape {
            Shape::Box => 0.5,
            Shape::Staircase(s) => s.radius,
        }
    }

    /// The filter's profile along one axis at `x` pixels from the pixel's centre (not
    /// normalised; Mitsuba's `eval_discretized`).
    pub fn eval(&self, x: f32) -> f32 {
        match &self.shape {
            Shape::Box => f32::from(u8::from((-0.5..0.5).contains(&x))),
            Shape::Staircase(s) => {
                let i = (x.abs() / s.step) as usize;
                s.values.get(i).map_or(0.0, |&v| v as f32)
            }
        }
    }

    /// The density, along one axis, with which [`sample_axis`](Self::sample_axis) draws the
    /// offset `x`.
    pub fn pdf(&self, x: f32) -> f32 {
        match &self.shape {
            Shape::Box => self.eval(x),
            Shape::Staircase(s) => match s.bin(x) {
                Some(k) => (s.cdf[k + 1] - s.cdf[k]) / s.step,
                None => 0.0,
            },
        }
    }

    /// ∫ of [`eval`](Self::eval) over the line.
    #[cfg(test)]
    fn eval_integral(&self) -> f32 {
        let r = self.radius() as f64;
        self.integral(-r, r) as f32
    }

    /// ∫ of the profile from `a` to `b`, exactly (it is piecewise constant), in f64.
    fn integral(&self, a: f64, b: f64) -> f64 {
        match &self.shape {
            Shape::Box => (b.min(0.5) - a.max(-0.5)).max(0.0),
            Shape::Staircase(s) => {
                let (r, step) = (s.radius as f64, s.step as f64);
                (0..2 * STEPS)
                    .map(|k| {
                        let lo = -r + k as f64 * step;
                        let overlap = (b.min(lo + step) - a.max(lo)).max(0.0);
                        let i = if k < STEPS { STEPS - 1 - k } else { k - STEPS };
                        overlap * s.values[i]
                    })
                    .sum()
            }
        }
    }

    /// An offset from the pixel's centre along one axis, drawn with `u` in [0, 1) from the
    /// filter, and its weight f/p (normalised f).
    #[inline]
    pub fn sample_axis(&self, u: f32) -> (f32, f32) {
        match &self.shape {
            Shape::Box => (u - 0.5, 1.0),
            Shape::Staircase(s) => s.sample(u),
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

impl Staircase {
    /// The step (from −r) holding `x`, if it is within the support.
    fn bin(&self, x: f32) -> Option<usize> {
        let t = (x + self.radius) / self.step;
        (t >= 0.0 && t < (2 * STEPS) as f32).then(|| (t as usize).min(2 * STEPS - 1))
    }

    #[inline]
    fn sample(&self, u: f32) -> (f32, f32) {
        // The last edge ≤ u (cdf[0] = 0 ≤ u < 1 = cdf[end]); a step of no mass is never chosen.
        let k = self.cdf.partition_point(|&c| c <= u).clamp(1, 2 * STEPS) - 1;
        let (lo, hi) = (self.cdf[k], self.cdf[k + 1]);
        let within = ((u - lo) / (hi - lo)).clamp(0.0, 1.0);
        let x = -self.radius + (k as f32 + within) * self.step;
        // Rounding can carry x onto the next step, whose value differs: the weight is the
        // chosen step's, and x is kept inside it.
        let x = x.clamp(
            -self.radius + k as f32 * self.step,
            (-self.radius + (k + 1) as f32 * self.step).next_down(),
        );
        (x, self.weights[k])
    }
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

    /// The staircases are sampled in proportion to their steps' mass: every weight is 1 up to
    /// the rounding of the stored probabilities (f32 steps of the cumulative table, 6·10⁻⁸, over
    /// the step's probability), and f/(Z·p) is 1 in the middle of every step (Z the
    /// staircase's integral).
    #[test]
    fn weights_are_the_filter_over_the_density() {
        let mut sampler = test_sampler(18);
        for (name, filter) in filters() {
            let Shape::Staircase(s) = &filter.shape else {
                for _ in 0..1000 {
                    assert_eq!(filter.sample_axis(sampler.next_1d()).1, 1.0, "{name}");
                }
                continue;
            };
            for _ in 0..20_000 {
                let (x, w) = filter.sample_axis(sampler.next_1d());
                let p_step = (filter.pdf(x) * s.step) as f64;
                let rounding = 2.0 * f32::EPSILON as f64 / p_step;
                assert!(
                    (w as f64 - 1.0).abs() <= rounding + 1e-6,
                    "{name}: weight {w} at {x} (step probability {p_step})"
                );
            }
            let z = filter.eval_integral();
            for k in 0..2 * STEPS {
                let x = -s.radius + (k as f32 + 0.5) * s.step;
                let p_step = (filter.pdf(x) * s.step) as f64;
                let ratio = (filter.eval(x) / (z * filter.pdf(x))) as f64;
                assert!(
                    (ratio - 1.0).abs() <= 2.0 * f32::EPSILON as f64 / p_step + 1e-6,
                    "{name}: f/(Z p) = {ratio} at {x}"
                );
            }
        }
    }

    /// The profile is Mitsuba 3.9.1's `eval_discretized` (printed by its Python bindings,
    /// `scalar_rgb`): its Gaussian (σ = 0.5) and tent (r = 1) at chosen offsets. Mitsuba's own
    /// Gaussian is offset by about 4·10⁻⁴ from exp(−x²/2σ²) − exp(−8) (its value at 0 is
    /// 0.999247), within the tolerance.
    #[test]
    fn profiles_are_mitsuba_s_tables() {
        let gaussian = Filter::gaussian(0.5).unwrap();
        for (x, mitsuba) in [
            (0.0, 0.999247),
            (0.05, 0.99925),
            (0.1, 0.99099),
            (0.2, 0.92735),
            (0.5, 0.66496),
            (0.8, 0.30115),
            (1.2, 0.06707),
            (1.5, 0.01188),
            (1.9, 0.00057),
            (1.99, 0.00022),
            (2.0, 0.0),
        ] {
            let ours = gaussian.eval(x);
            assert!(
                (ours - mitsuba).abs() < 1e-3,
                "gaussian at {x}: {ours} vs {mitsuba}"
            );
        }
        let tent = Filter::tent(1.0).unwrap();
        for (x, mitsuba) in [(0.0, 1.0), (0.05, 0.96774), (0.5, 0.51613), (0.95, 0.06452)] {
            let ours = tent.eval(x);
            assert!(
                (ours - mitsuba).abs() < 1e-5,
                "tent at {x}: {ours} vs {mitsuba}"
            );
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
