//! Statistical tests of the sampling code (warps, the discrete and 2D distributions, the
//! sampler) through its public interface: each sampler's histogram against the density it
//! claims, by Pearson's χ² at the family-wise false-alarm rate `FAMILY_FALSE_ALARM` per test,
//! with random numbers from the suite's seed (`LUMIS_TEST_SEED`).

use glam::Vec2;
use lumis_core::chi2::{FAMILY_FALSE_ALARM, histogram_p_value, sidak, test_sampler};
use lumis_core::math::warp::{
    cosine_hemisphere_pdf, square_to_cosine_hemisphere, square_to_disk_concentric,
    square_to_triangle_barycentrics,
};
use lumis_core::math::{Distribution1D, Distribution2D};
use lumis_core::sampler::Sampler;
use std::f32::consts::TAU;

fn assert_fits(observed: &[f64], expected: &[f64], alpha: f64, what: &str) {
    let p = histogram_p_value(observed, expected);
    eprintln!("chi2 `{what}`: p = {p:.4e}");
    assert!(
        p >= alpha,
        "{what}: p = {p:.3e} < {alpha:.1e} (seed {})",
        lumis_core::chi2::test_seed()
    );
}

/// Points on the unit disk are uniform: counts over 16 rings of equal area × 32 sectors.
#[test]
fn concentric_disk_is_uniform() {
    let (rings, sectors, n) = (16, 32, 400_000);
    let mut observed = vec![0.0; rings * sectors];
    let mut s = test_sampler(10);
    for _ in 0..n {
        let p = square_to_disk_concentric(s.next_2d());
        let r2 = p.length_squared();
        assert!(r2 <= 1.0 + 1e-6, "{p} off the disk");
        let ring = ((r2 * rings as f32) as usize).min(rings - 1);
        let sector =
            ((p.y.atan2(p.x).rem_euclid(TAU) / TAU * sectors as f32) as usize).min(sectors - 1);
        observed[ring * sectors + sector] += 1.0;
    }
    let expected = vec![n as f64 / (rings * sectors) as f64; rings * sectors];
    assert_fits(&observed, &expected, FAMILY_FALSE_ALARM, "concentric disk");
}

/// Shirley–Chiu's map sends the square's centre to the disk's, the middles of its edges to the
/// circle's axis points, and is odd about the centre (low distortion: concentric squares to
/// concentric circles).
#[test]
fn concentric_disk_maps_the_square_symmetrically() {
    for (u, expected) in [
        (Vec2::new(0.5, 0.5), Vec2::ZERO),
        (Vec2::new(1.0, 0.5), Vec2::new(1.0, 0.0)),
        (Vec2::new(0.5, 1.0), Vec2::new(0.0, 1.0)),
        (Vec2::new(0.0, 0.5), Vec2::new(-1.0, 0.0)),
        (Vec2::new(0.5, 0.0), Vec2::new(0.0, -1.0)),
        (
            Vec2::new(1.0, 1.0),
            Vec2::splat(std::f32::consts::FRAC_1_SQRT_2),
        ),
        (Vec2::new(0.75, 0.5), Vec2::new(0.5, 0.0)),
    ] {
        let p = square_to_disk_concentric(u);
        assert!(
            (p - expected).length() < 1e-6,
            "{u} → {p}, expected {expected}"
        );
    }
    let mut s = test_sampler(11);
    for _ in 0..1000 {
        let u = s.next_2d();
        let (a, b) = (
            square_to_disk_concentric(u),
            square_to_disk_concentric(Vec2::ONE - u),
        );
        assert!((a + b).length() < 1e-6, "{u}: {a} and {b}");
        // Concentric: the square's "radius" max(|2u − 1|) is the disk's radius.
        let r = (2.0 * u - Vec2::ONE).abs().max_element();
        assert!(
            (a.length() - r).abs() < 1e-6,
            "{u}: radius {} vs {r}",
            a.length()
        );
    }
}

/// The cosine-weighted density is zero at and below the horizon and cos θ / π above it, and the
/// warp's directions are unit vectors whose density it is (the χ² of this pair is
/// `chi2::tests::a_correct_sampler_passes_and_a_wrong_density_fails`).
#[test]
fn cosine_hemisphere_density_and_directions() {
    assert_eq!(cosine_hemisphere_pdf(0.0), 0.0);
    assert_eq!(cosine_hemisphere_pdf(-0.5), 0.0);
    assert!((cosine_hemisphere_pdf(0.5) - 0.5 / std::f32::consts::PI).abs() < 1e-7);
    let mut s = test_sampler(12);
    for _ in 0..1000 {
        let u = s.next_2d();
        let w = square_to_cosine_hemisphere(u);
        let d = square_to_disk_concentric(u);
        assert!((w.length() - 1.0).abs() < 1e-5 && w.z >= 0.0, "{w}");
        // Malley's method: the direction projects onto the disk point.
        assert!((w.truncate() - d).length() < 1e-6, "{w} vs {d}");
    }
}

/// Barycentrics are uniform over the triangle: (b0, b1) over a 32 × 32 grid of the unit square,
/// where cells below the diagonal b0 + b1 = 1 hold area 1/32², those it cuts in half (i + j =
/// 31) half that, and those above none.
#[test]
fn triangle_barycentrics_are_uniform() {
    let (k, n) = (32usize, 400_000);
    let mut observed = vec![0.0; k * k];
    let mut s = test_sampler(13);
    for _ in 0..n {
        let (b0, b1) = square_to_triangle_barycentrics(s.next_2d());
        assert!(
            b0 >= 0.0 && b1 >= 0.0 && b0 + b1 <= 1.0 + 1e-6,
            "({b0}, {b1})"
        );
        let (i, j) = (
            ((b0 * k as f32) as usize).min(k - 1),
            ((b1 * k as f32) as usize).min(k - 1),
        );
        observed[i * k + j] += 1.0;
    }
    let cell = 2.0 * n as f64 / (k * k) as f64;
    let expected: Vec<f64> = (0..k * k)
        .map(|c| match (c / k + c % k).cmp(&(k - 1)) {
            std::cmp::Ordering::Less => cell,
            std::cmp::Ordering::Equal => 0.5 * cell,
            std::cmp::Ordering::Greater => 0.0,
        })
        .collect();
    assert_fits(&observed, &expected, FAMILY_FALSE_ALARM, "triangle");
}

/// A discrete distribution picks bins with their probabilities (never a zero-weight one) and
/// the reused number is uniform within each bin: two χ² tests, one family.
#[test]
fn discrete_distribution_frequencies_and_reused_numbers() {
    let weights = [3.0, 0.0, 1.0, 5.0, 0.5, 2.0, 0.0, 0.25, 7.0, 1e-3];
    let d = Distribution1D::new(&weights).unwrap();
    let total: f32 = weights.iter().sum();
    assert_eq!(d.len(), weights.len());
    let total64: f64 = weights.iter().map(|&w| w as f64).sum();
    assert!((d.total() - total64).abs() < 1e-12 * total64);
    let n = 500_000;
    let sub = 8;
    let mut bins = vec![0.0; weights.len()];
    let mut within = vec![0.0; weights.len() * sub];
    let mut s = test_sampler(14);
    for _ in 0..n {
        let (i, r) = d.sample_reuse(s.next_1d());
        assert!((0.0..1.0).contains(&r), "reused {r}");
        bins[i] += 1.0;
        within[i * sub + ((r * sub as f32) as usize).min(sub - 1)] += 1.0;
    }
    let expected: Vec<f64> = weights
        .iter()
        .enumerate()
        .map(|(i, &w)| {
            assert!((d.pmf(i) - w / total).abs() < 1e-7, "pmf of bin {i}");
            n as f64 * (w / total) as f64
        })
        .collect();
    let alpha = sidak(FAMILY_FALSE_ALARM, 2);
    assert_fits(&bins, &expected, alpha, "bin frequencies");
    let expected_within: Vec<f64> = expected
        .iter()
        .flat_map(|&e| std::iter::repeat_n(e / sub as f64, sub))
        .collect();
    assert_fits(&within, &expected_within, alpha, "reused numbers");
}

/// A 2D piecewise-constant distribution draws cells in proportion to their values, uniformly
/// within each cell, and `pdf` gives each cell its value over their mean.
#[test]
fn distribution_2d_draws_cells_in_proportion_and_uniformly_within() {
    let (nx, ny) = (5, 4);
    let values: Vec<f32> = (0..nx * ny)
        .map(|c| [0.0, 1.0, 2.5, 0.3, 4.0][c % nx] * [1.0, 0.0, 2.0, 0.5][c / nx])
        .collect();
    let total: f32 = values.iter().sum();
    let d = Distribution2D::new(&values, nx, ny).unwrap();
    let (n, sub) = (400_000, 4);
    let mut observed = vec![0.0; nx * ny * sub * sub];
    let mut s = test_sampler(15);
    for _ in 0..n {
        let p = d.sample(s.next_2d());
        // Closed: (col + u)/nx rounds to 1 for the last column when u is within an ulp of 1
        // (about 1e-7 of samples), although `sample` documents [0, 1)²; its users wrap or
        // clamp there.
        assert!(
            (0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.y),
            "{p}"
        );
        let (fx, fy) = (p.x * (nx * sub) as f32, p.y * (ny * sub) as f32);
        let (x, y) = (
            (fx as usize).min(nx * sub - 1),
            (fy as usize).min(ny * sub - 1),
        );
        observed[y * nx * sub + x] += 1.0;
    }
    let expected: Vec<f64> = (0..nx * ny * sub * sub)
        .map(|c| {
            let (x, y) = (c % (nx * sub) / sub, c / (nx * sub) / sub);
            let v = values[y * nx + x];
            // The density is the value over its mean.
            let density = v / total * (nx * ny) as f32;
            assert!(
                (d.pdf(Vec2::new(
                    (x as f32 + 0.5) / nx as f32,
                    (y as f32 + 0.5) / ny as f32
                )) - density)
                    .abs()
                    < 1e-5
            );
            n as f64 * (v / total) as f64 / (sub * sub) as f64
        })
        .collect();
    assert_fits(&observed, &expected, FAMILY_FALSE_ALARM, "2D distribution");
    assert!(Distribution2D::new(&[0.0; 6], 3, 2).is_none());
}

/// The sampler's numbers are uniform on [0, 1) in one and two dimensions (pairs of successive
/// numbers), and streams of neighbouring pixels and sample indices are not correlated (pairs of
/// their first numbers): three χ² tests, one family.
#[test]
fn sampler_numbers_are_uniform_and_streams_independent() {
    let seed = lumis_core::chi2::test_seed();
    let k = 32;
    let n = 200_000;
    let mut single = vec![0.0; k * k];
    let mut pairs = vec![0.0; k * k];
    let mut neighbours = vec![0.0; k * k];
    let bin = |u: f32| {
        assert!((0.0..1.0).contains(&u), "{u}");
        ((u * k as f32) as usize).min(k - 1)
    };
    let mut s = Sampler::new(seed, 7, 0);
    for _ in 0..n * k {
        // k² bins of single numbers: each number's leading 10 bits.
        let u = s.next_1d();
        single[((u * (k * k) as f32) as usize).min(k * k - 1)] += 1.0;
    }
    for _ in 0..n {
        let (a, b) = (s.next_1d(), s.next_1d());
        pairs[bin(a) * k + bin(b)] += 1.0;
    }
    for p in 0..n as u64 {
        let a = Sampler::new(seed, p, p % 3).next_1d();
        let b = Sampler::new(seed, p + 1, p % 3 + (p & 1)).next_1d();
        neighbours[bin(a) * k + bin(b)] += 1.0;
    }
    let alpha = sidak(FAMILY_FALSE_ALARM, 3);
    assert_fits(
        &single,
        &vec![(n * k) as f64 / (k * k) as f64; k * k],
        alpha,
        "single numbers",
    );
    for (what, h) in [
        ("successive pairs", &pairs),
        ("neighbouring streams", &neighbours),
    ] {
        assert_fits(h, &vec![n as f64 / (k * k) as f64; k * k], alpha, what);
    }
}
