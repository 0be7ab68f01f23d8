//! The tests of `lumis_textures::checkerboard` (`plugins/textures/src/checkerboard.rs`).

use glam::Vec2;
use glam::Vec4;
use lumis_core::math::Rgb;
use lumis_core::math::lanes::V2;
use lumis_core::texture::{Texture, TextureLanes, UvTransform};
use lumis_textures::checkerboard::*;

/// Mitsuba's rule at points of each check, on both sides of the edges at ½ and 1, and
/// beyond [0, 1]² (the pattern repeats); `eval_1` has the colours the other way round.
/// The mean of a colour's channels, as Mitsuba's `eval_1` of a colour.
fn mean(c: Rgb) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

#[test]
fn checks_follow_mitsubas_rule() {
    let (c0, c1) = (Rgb::new(0.1, 0.2, 0.3), Rgb::splat(0.8));
    let board = Checkerboard::new(c0, c1, UvTransform::IDENTITY);
    for (uv, first) in [
        ((0.25, 0.25), true),
        ((0.75, 0.75), true),
        ((0.75, 0.25), false),
        ((0.25, 0.75), false),
        ((0.5, 0.5), true),
        ((0.500_001, 0.25), false),
        ((1.25, -0.25), false),
        ((-0.25, -0.25), true),
        ((3.75, 7.75), true),
    ] {
        let uv = Vec2::from(uv);
        let (colour, number) = if first {
            (c0, mean(c1))
        } else {
            (c1, mean(c0))
        };
        assert_eq!(board.eval(uv), colour, "{uv}");
        assert_eq!(board.eval_1(uv), number, "{uv}");
    }
    assert_eq!(board.range(), [0.1, 0.8]);
}

/// `to_uv` applies first: scaled by 2, the checks are half as large.
#[test]
fn to_uv_maps_the_coordinates_first() {
    let scale = UvTransform {
        rows: [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0]],
    };
    let board = Checkerboard::new(Rgb::ZERO, Rgb::ONE, scale);
    assert_eq!(board.eval(Vec2::new(0.3, 0.1)), Rgb::ONE);
    assert_eq!(board.eval(Vec2::new(0.3, 0.3)), Rgb::ZERO);
}

/// The batch methods give what one call each gives, bit for bit, four lanes wide and as
/// wide as the processor has, for batches of every remainder.
#[test]
fn batches_give_what_single_calls_give() {
    let board = Checkerboard::new(
        Rgb::new(0.3, 0.6, 0.9),
        Rgb::new(0.05, 0.5, 0.0),
        UvTransform {
            rows: [[3.0, 0.5, 0.1], [-0.5, 2.0, 0.7]],
        },
    );
    let points: Vec<Vec2> = (0..37)
        .map(|i| Vec2::new(i as f32 * 0.137 - 2.0, (i * i) as f32 * 0.011 - 1.0))
        .collect();
    for n in [1, 3, 4, 5, 8, 9, 37] {
        let mut colours = vec![Rgb::NAN; n];
        let mut numbers = vec![f32::NAN; n];
        board.eval_batch(&points[..n], &mut colours);
        board.eval_1_batch(&points[..n], &mut numbers);
        for (k, &uv) in points[..n].iter().enumerate() {
            assert_eq!(colours[k], board.eval(uv), "{n}: {uv}");
            assert_eq!(
                numbers[k].to_bits(),
                board.eval_1(uv).to_bits(),
                "{n}: {uv}"
            );
        }
    }
    let four = V2::<Vec4>::from_fn(|i| points[i]);
    let colours = board.eval_lanes(four);
    for (i, &uv) in points[..4].iter().enumerate() {
        assert_eq!(colours.lane(i), board.eval(uv));
    }
}
