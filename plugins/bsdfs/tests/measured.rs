//! The tests of `lumis_bsdfs::measured` (`plugins/bsdfs/src/measured.rs`).

use glam::Vec3;
use lumis_bsdfs::measured::*;
use std::f32::consts::{FRAC_PI_2, PI};

#[test]
fn half_diff_round_trips() {
    for (th, td, pd) in [(0.3f32, 0.7f32, 1.0f32), (0.01, 0.2, 2.5), (1.2, 0.1, 0.3)] {
        let (wi, wo) = from_half_diff(th, td, pd);
        let (h, d, p) = half_diff(wi, wo);
        assert!(
            (h - th).abs() < 1e-4 && (d - td).abs() < 1e-4 && (p - pd).abs() < 1e-3,
            "{h} {d} {p}"
        );
    }
}

/// A MERL file's bytes: the header, then `stored(channel, entry)` for each channel.
fn merl_bytes(stored: impl Fn(usize, usize) -> f64) -> Vec<u8> {
    let mut bytes: Vec<u8> = [THETA_H as i32, THETA_D as i32, PHI_D as i32]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    for channel in 0..3 {
        for entry in 0..ENTRIES {
            bytes.extend(stored(channel, entry).to_le_bytes());
        }
    }
    bytes
}

/// MERL's files store each channel divided by its published scale (1/1500, 1.15/1500,
/// 1.66/1500: Matusik et al.'s `BRDFRead.cpp`); checked on bytes written here, not by
/// `write_merl`, which shares the constant.
#[test]
fn merl_channels_are_read_with_their_published_scales() {
    let stored = [1500.0f64, 1500.0 / 1.15 * 2.0, 1500.0 / 1.66 * 3.0];
    let table = MerlTable::parse(&merl_bytes(|channel, _| stored[channel])).unwrap();
    let f = table.lookup(Vec3::new(0.3, 0.1, 0.95).normalize(), Vec3::Z);
    for (channel, expected) in [f.x, f.y, f.z].into_iter().zip([1.0, 2.0, 3.0]) {
        assert!((channel - expected).abs() < 1e-5, "{f:?}");
    }
}

/// Between entries the table is interpolated trilinearly in MERL's indices (θh through its
/// square-root mapping): a table linear in the three indices is reproduced exactly.
#[test]
fn lookup_interpolates_trilinearly_between_entries() {
    // Entry i is index(h, d, p) = p + PHI_D · (d + THETA_D · h).
    let linear = |i: usize| {
        let (h, d, p) = (i / (THETA_D * PHI_D), i / PHI_D % THETA_D, i % PHI_D);
        (h + 2 * d + 3 * p) as f64
    };
    let bytes = merl_bytes(|channel, i| linear(i) / SCALE[channel]);
    let table = MerlTable::parse(&bytes).unwrap();
    for (xh, xd, xp) in [(20.3f32, 10.7f32, 30.2f32), (61.8, 44.1, 120.6)] {
        let theta_h = (xh / THETA_H as f32).powi(2) * FRAC_PI_2;
        let theta_d = xd / THETA_D as f32 * FRAC_PI_2;
        let phi_d = xp / PHI_D as f32 * PI;
        let (wi, wo) = from_half_diff(theta_h, theta_d, phi_d);
        let f = table.lookup(wi, wo);
        let expected = xh + 2.0 * xd + 3.0 * xp;
        // The directions' round trip moves the indices by about 0.01.
        assert!((f.x - expected).abs() < 0.05, "{f:?} against {expected}");
        assert!(
            (f.x - f.y).abs() < 1e-4 && (f.y - f.z).abs() < 1e-4,
            "{f:?}"
        );
    }
}

#[test]
fn malformed_files_are_refused() {
    assert!(
        MerlTable::parse(b"short")
            .err()
            .unwrap()
            .contains("shorter than its header")
    );
    let mut header: Vec<u8> = [90i32, 90, 90]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    assert!(
        MerlTable::parse(&header)
            .err()
            .unwrap()
            .contains("dimensions [90, 90, 90]")
    );
    header = [90i32, 90, 180]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    header.extend([0u8; 64]);
    assert!(
        MerlTable::parse(&header)
            .err()
            .unwrap()
            .contains("truncated")
    );
}
