//! The tests of `lumis_bsdfs::ior` (`plugins/bsdfs/src/ior.rs`).

use lumis_bsdfs::ior::*;

/// Against the closed forms: normal incidence ((η − 1)/(η + 1))², Brewster's angle (the
/// p-polarised part vanishes: half the s-polarised one), total internal reflection past
/// the critical angle, the symmetry of the reflectance across the interface
/// (R(θo, η) = R(θt, 1/η)), and finite values at the extreme indices.
#[test]
fn fresnel_matches_closed_forms() {
    for eta in [1.5f32, 1.333, 2.419, 1.0 / 1.5, MIN, MAX] {
        let (r, cos_t) = fresnel(1.0, eta);
        let expected = ((eta - 1.0) / (eta + 1.0)).powi(2);
        assert!(
            (r - expected).abs() <= 1e-6 * expected.max(1e-6),
            "{eta}: {r}"
        );
        assert!(cos_t.is_finite() && cos_t <= 0.0);
        for cos in [1e-7f32, 0.01, 0.5] {
            let (r, cos_t) = fresnel(cos, eta);
            assert!((0.0..=1.0).contains(&r) && cos_t.is_finite(), "{eta} {cos}");
        }
    }
    // Brewster: tan θ_B = η.
    let eta = 1.5f32;
    let theta_b = eta.atan();
    let (r, cos_t) = fresnel(theta_b.cos(), eta);
    let sin_t = theta_b.sin() / eta;
    let r_s = ((theta_b.cos() + eta * cos_t) / (theta_b.cos() - eta * cos_t)).powi(2);
    assert!((r - 0.5 * r_s).abs() < 1e-6, "{r} {r_s}");
    assert!((cos_t + (1.0 - sin_t * sin_t).sqrt()).abs() < 1e-6);
    // Total internal reflection from glass beyond asin(1/1.5) = 41.8°.
    assert!(fresnel(40f32.to_radians().cos(), 1.0 / 1.5).0 < 1.0);
    assert_eq!(fresnel(43f32.to_radians().cos(), 1.0 / 1.5), (1.0, 0.0));
    // Reciprocal across the interface.
    for cos_o in [0.9f32, 0.5, 0.1] {
        let (r, cos_t) = fresnel(cos_o, 1.5);
        let (back, cos_back) = fresnel(-cos_t, 1.0 / 1.5);
        assert!((r - back).abs() < 1e-5, "{cos_o}: {r} vs {back}");
        assert!((cos_back + cos_o).abs() < 1e-5);
    }
    let (r, cos_t) = fresnel(0.3, 1.0);
    assert!(
        r == 0.0 && (cos_t + 0.3).abs() < 1e-6,
        "index-matched: {r} {cos_t}"
    );
}
