//! Estimates with 95 % intervals: a stratified delete-one jackknife over runs.
//!
//! The randomness of a study is in its runs: K renders with independent seeds. Within a run,
//! pixels are estimated from their own random streams, so the noise of different pixels is
//! independent, except where a method shares work between neighbours (a pooled pilot): square
//! pixel blocks keep such correlation inside a block. Blocks are therefore independent *strata*
//! and runs the replicates within each: a statistic's replicate (h, k) leaves run k out of
//! stratum h only. The variance estimate
//!
//! ```text
//!     v = Σ_h v_h,   v_h = (K − 1)/K · Σ_k (θ_(h,k) − θ̄_(h))²
//! ```
//!
//! is exactly the unbiased variance of a statistic linear in the runs (a mean error), and
//! conservative (by the Efron–Stein inequality) for symmetric ones such as a variance across
//! runs; smooth functions of several statistics (ratios, interpolated times) follow by the delta
//! method. Because every block contributes its own K − 1 degrees of freedom, the interval of a
//! mean over many blocks is far tighter than one from K runs alone; where a few blocks dominate
//! (highlights holding most of the variance) the Welch–Satterthwaite degrees of freedom
//! df = v² / Σ_h v_h² / (K − 1) fall toward K − 1 and the Student quantile widens the interval
//! accordingly. Timing noise is a stratum of its own (a run's CPU time), and statistics that
//! are not sums over blocks (medians over pixels) use one global stratum (run k left out of
//! every pixel). Replicates pair configurations: run k is the same seed for all of them, so a
//! ratio's interval benefits from the correlation of its numerator and denominator.
//!
//! Ratios and other positive quantities get their interval on the log scale (symmetric in
//! log, as ratios are), others on the linear scale.

use statrs::distribution::{ContinuousCDF, StudentsT};

/// The strata of a study's replicates: `blocks` pixel blocks, the time stratum and the global
/// stratum, each with `runs` replicates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Design {
    pub runs: usize,
    pub blocks: usize,
}

/// A stratum of a [`Design`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stratum {
    Block(usize),
    /// The runs' CPU times.
    Time,
    /// Run k left out of everything: for statistics that are not sums over blocks.
    Global,
}

impl Design {
    pub fn strata(&self) -> usize {
        self.blocks + 2
    }

    fn index(&self, stratum: Stratum) -> usize {
        match stratum {
            Stratum::Block(b) => b,
            Stratum::Time => self.blocks,
            Stratum::Global => self.blocks + 1,
        }
    }
}

/// A statistic and its jackknife replicates: `deltas[h · K + k]` is how much the statistic moves
/// when run k is left out of stratum h (zero where it does not depend on that stratum).
#[derive(Clone, Debug, PartialEq)]
pub struct Jack {
    pub value: f64,
    design: Design,
    deltas: Vec<f64>,
}

impl Jack {
    /// A number known exactly.
    pub fn constant(design: Design, value: f64) -> Self {
        Jack {
            value,
            design,
            deltas: vec![0.0; design.strata() * design.runs],
        }
    }

    pub fn design(&self) -> Design {
        self.design
    }

    fn delta_mut(&mut self, stratum: Stratum, run: usize) -> &mut f64 {
        let h = self.design.index(stratum);
        &mut self.deltas[h * self.design.runs + run]
    }

    /// The mean over runs of a per-run quantity summed over blocks, divided by `scale`:
    /// (1 / (K · scale)) Σ_k Σ_b `per_run[k][b]`. Leaving run k out of block b replaces that
    /// block's mean over runs by the mean of the other runs.
    pub fn run_block_mean(design: Design, per_run: &[&[f64]], scale: f64) -> Self {
        let k = design.runs;
        assert_eq!(per_run.len(), k, "one block vector per run");
        let mut jack = Jack::constant(design, 0.0);
        for b in 0..design.blocks {
            let sum: f64 = per_run.iter().map(|r| r[b]).sum();
            let mean = sum / k as f64;
            jack.value += mean / scale;
            for (run, r) in per_run.iter().enumerate() {
                let others = (sum - r[b]) / (k - 1) as f64;
                *jack.delta_mut(Stratum::Block(b), run) = (others - mean) / scale;
            }
        }
        jack
    }

    /// A sum over blocks, Σ_b `full[b]` / `scale`, whose value in block b without run k is
    /// `left_out(b, k)` (e.g. a variance across runs recomputed from the other runs).
    pub fn block_sum(
        design: Design,
        full: &[f64],
        left_out: impl Fn(usize, usize) -> f64,
        scale: f64,
    ) -> Self {
        let mut jack = Jack::constant(design, full.iter().sum::<f64>() / scale);
        for (b, &value) in full.iter().enumerate() {
            for run in 0..design.runs {
                *jack.delta_mut(Stratum::Block(b), run) = (left_out(b, run) - value) / scale;
            }
        }
        jack
    }

    /// The mean of one value per run, in `stratum` (the time stratum for CPU times, the global
    /// one for per-run statistics that are not sums over blocks).
    pub fn run_mean(design: Design, stratum: Stratum, values: &[f64]) -> Self {
        let k = design.runs;
        assert_eq!(values.len(), k, "one value per run");
        let sum: f64 = values.iter().sum();
        let mean = sum / k as f64;
        let mut jack = Jack::constant(design, mean);
        for (run, v) in values.iter().enumerate() {
            *jack.delta_mut(stratum, run) = (sum - v) / (k - 1) as f64 - mean;
        }
        jack
    }

    /// A statistic computed from all runs (`value`) and from all runs but run k
    /// (`left_out[k]`), in the global stratum.
    pub fn global(design: Design, value: f64, left_out: &[f64]) -> Self {
        assert_eq!(left_out.len(), design.runs, "one replicate per run");
        let mut jack = Jack::constant(design, value);
        for (run, v) in left_out.iter().enumerate() {
            *jack.delta_mut(Stratum::Global, run) = v - value;
        }
        jack
    }

    /// f of this statistic, replicate by replicate.
    pub fn map(&self, f: impl Fn(f64) -> f64) -> Self {
        Jack::combine(&[self], |v| f(v[0]))
    }

    /// f of two statistics (e.g. their ratio), replicate by replicate.
    pub fn zip(&self, other: &Jack, f: impl Fn(f64, f64) -> f64) -> Self {
        Jack::combine(&[self, other], |v| f(v[0], v[1]))
    }

    pub fn ratio(&self, other: &Jack) -> Self {
        self.zip(other, |a, b| a / b)
    }

    /// f of several statistics of the same design, replicate by replicate: the replicate
    /// (h, k) of the result is f of the inputs' replicates (h, k).
    pub fn combine(inputs: &[&Jack], f: impl Fn(&[f64]) -> f64) -> Self {
        let design = inputs[0].design;
        assert!(
            inputs.iter().all(|j| j.design == design),
            "statistics of different designs"
        );
        let mut values: Vec<f64> = inputs.iter().map(|j| j.value).collect();
        let value = f(&values);
        let deltas = (0..design.strata() * design.runs)
            .map(|i| {
                if inputs.iter().all(|j| j.deltas[i] == 0.0) {
                    return 0.0;
                }
                for (v, j) in values.iter_mut().zip(inputs) {
                    *v = j.value + j.deltas[i];
                }
                f(&values) - value
            })
            .collect();
        Jack {
            value,
            design,
            deltas,
        }
    }

    /// The jackknife variance, each stratum's share, and the Welch–Satterthwaite degrees of
    /// freedom.
    fn variance(&self) -> (f64, f64) {
        let k = self.design.runs;
        let factor = (k - 1) as f64 / k as f64;
        let (mut total, mut squares) = (0.0, 0.0);
        for stratum in self.deltas.chunks(k) {
            let mean = stratum.iter().sum::<f64>() / k as f64;
            let v = factor * stratum.iter().map(|d| (d - mean) * (d - mean)).sum::<f64>();
            total += v;
            squares += v * v / (k - 1) as f64;
        }
        let df = if squares > 0.0 {
            total * total / squares
        } else {
            f64::INFINITY
        };
        (total, df)
    }

    /// The 95 % interval, on the linear scale.
    pub fn interval(&self) -> Estimate {
        let (variance, df) = self.variance();
        let se = variance.sqrt();
        let t = student_quantile(df);
        Estimate {
            value: self.value,
            lo: self.value - t * se,
            hi: self.value + t * se,
            se,
            df,
        }
    }

    /// The 95 % interval on the log scale, for a positive statistic (a ratio); on the linear
    /// scale if the statistic or a replicate is not positive.
    pub fn log_interval(&self) -> Estimate {
        let positive = self.value > 0.0
            && self.value.is_finite()
            && self.deltas.iter().all(|d| (self.value + d) > 0.0);
        if !positive {
            return self.interval();
        }
        let log = self.map(f64::ln).interval();
        Estimate {
            value: self.value,
            lo: log.lo.exp(),
            hi: log.hi.exp(),
            se: log.se,
            df: log.df,
        }
    }
}

/// The 0.975 quantile of Student's t with `df` degrees of freedom (the normal's for df = ∞).
pub fn student_quantile(df: f64) -> f64 {
    const NORMAL: f64 = 1.959_963_984_540_054;
    if !(df.is_finite()) || df > 1e7 {
        return NORMAL;
    }
    StudentsT::new(0.0, 1.0, df.max(1.0)).map_or(NORMAL, |t| t.inverse_cdf(0.975))
}

/// A value with its 95 % interval [lo, hi]; `se` is the standard error (of the log for an
/// interval on the log scale) and `df` its degrees of freedom.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Estimate {
    pub value: f64,
    pub lo: f64,
    pub hi: f64,
    pub se: f64,
    pub df: f64,
}

impl Estimate {
    /// A value without an interval (NaN bounds).
    pub fn bare(value: f64) -> Self {
        Estimate {
            value,
            lo: f64::NAN,
            hi: f64::NAN,
            se: f64::NAN,
            df: f64::NAN,
        }
    }

    pub fn contains(&self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// A ratio whose interval contains 1: not significant at 5 %.
    pub fn not_significant(&self) -> bool {
        self.contains(1.0)
    }

    /// The interval's largest relative distance from the value: 0.05 for ±5 %.
    pub fn relative_half_width(&self) -> f64 {
        ((self.hi / self.value) - 1.0).max(1.0 - self.lo / self.value)
    }
}

/// The median of some values (NaN for none); reorders them.
pub fn median(values: &mut [f64]) -> f64 {
    let n = values.len();
    if n == 0 {
        return f64::NAN;
    }
    let (_, &mut upper, _) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    if n % 2 == 1 {
        upper
    } else {
        let lower = values[..n / 2]
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lower + upper)
    }
}

/// Where a curve reaches a level, in log coordinates: `Within` the measured points, or
/// extrapolated beyond the first or last point along the curve's least-squares slope.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reach {
    Within(f64),
    BeforeFirst(f64),
    AfterLast(f64),
}

impl Reach {
    pub fn log(self) -> f64 {
        match self {
            Reach::Within(v) | Reach::BeforeFirst(v) | Reach::AfterLast(v) => v,
        }
    }
}

/// The x at which a piecewise-linear curve through `points` (x, y) first reaches the level `y`,
/// all in log coordinates, with the points in the order of the curve (budget order). A curve
/// that does not reach it between its points is extrapolated from its nearer end along the
/// least-squares slope of all its points (Monte Carlo curves are close to straight lines in
/// log-log); `None` if it cannot be (fewer than two points, or a flat or rising fit where a
/// falling one is needed).
pub fn reach(points: &[(f64, f64)], level: f64) -> Option<Reach> {
    if points.len() < 2 || points.iter().any(|p| !(p.0.is_finite() && p.1.is_finite())) {
        return None;
    }
    for w in points.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        let (lo, hi) = (y0.min(y1), y0.max(y1));
        if lo <= level && level <= hi {
            // At a point, that point's x (the interpolation can miss it by a rounding error);
            // between two, an x between theirs.
            let x = if level == y0 {
                x0
            } else if level == y1 {
                x1
            } else {
                (x0 + (level - y0) * (x1 - x0) / (y1 - y0)).clamp(x0.min(x1), x0.max(x1))
            };
            return Some(Reach::Within(x));
        }
    }
    let slope = least_squares_slope(points)?; // dy/dx
    if slope == 0.0 || !slope.is_finite() {
        return None;
    }
    let (first, last) = (points[0], points[points.len() - 1]);
    // Which end is nearer the level, along the direction the curve runs.
    let x_first = first.0 + (level - first.1) / slope;
    let x_last = last.0 + (level - last.1) / slope;
    if (x_first - first.0).abs() <= (x_last - last.0).abs() {
        (x_first <= first.0).then_some(Reach::BeforeFirst(x_first))
    } else {
        (x_last >= last.0).then_some(Reach::AfterLast(x_last))
    }
}

fn least_squares_slope(points: &[(f64, f64)]) -> Option<f64> {
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
    let sxx: f64 = points.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}
