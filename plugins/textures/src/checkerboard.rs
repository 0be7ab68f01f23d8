//! `checkerboard`: Mitsuba 3's procedural checkerboard, two colours alternating over the unit
//! squares of texture space.
//!
//! Parameters:
//! - `color0` (rgb, default (0.4, 0.4, 0.4), each channel in [0, 1e6]): the colour of the
//!   squares where ⌊2u⌋ and ⌊2v⌋ have the same parity (the square at the origin).
//! - `color1` (rgb, default (0.2, 0.2, 0.2), each channel in [0, 1e6]): the colour of the others.
//! - `to_uv` (uv transform, default identity): the map applied to the texture coordinates first.
//!
//! With (u, v) = `to_uv`(uv), a point is in `color0` where u − ⌊u⌋ > ½ and v − ⌊v⌋ > ½ agree,
//! else in `color1`: each unit square of texture space holds 2 × 2 checks. The value of a
//! number parameter (`eval_1`) is the mean of the colour's channels, with the colours the other
//! way round, as Mitsuba 3.9's `eval_1` has them (`color0` where they disagree): a checkerboard
//! roughness in a converted Mitsuba scene matches Mitsuba's image. Mitsuba also accepts
//! textures for the two colours; these are constants.

use glam::Vec2;
use lumis_core::math::Rgb;
use lumis_core::math::lanes::{Lanes, V2, V3};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::TexturePlugin;
use lumis_core::texture::{Texture, TextureLanes, UvTransform, eval_1_in_lanes, eval_in_lanes};
use std::sync::Arc;

pub struct Checkerboard {
    color0: Rgb,
    color1: Rgb,
    to_uv: UvTransform,
}

impl Checkerboard {
    pub fn new(color0: Rgb, color1: Rgb, to_uv: UvTransform) -> Self {
        Checkerboard {
            color0,
            color1,
            to_uv,
        }
    }

    /// Where each lane's point is in a `color0` check, by `eval`'s rule.
    #[inline(always)]
    fn in_color0<L: Lanes>(&self, uv: V2<L>) -> L::Mask {
        let uv = self.to_uv.apply(uv);
        let half = L::splat(0.5);
        let upper_u = (uv.x - uv.x.floor()).gt(half);
        let upper_v = (uv.y - uv.y.floor()).gt(half);
        (upper_u & upper_v) | !(upper_u | upper_v)
    }
}

/// The mean of a colour's channels, as Mitsuba's `eval_1` of a colour.
fn mean(c: Rgb) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

impl TextureLanes for Checkerboard {
    #[inline(always)]
    fn eval_lanes<L: Lanes>(&self, uv: V2<L>) -> V3<L> {
        V3::select(
            self.in_color0(uv),
            V3::splat(self.color0),
            V3::splat(self.color1),
        )
    }

    /// Mitsuba's `eval_1`: `color0` where `eval` has `color1`.
    #[inline(always)]
    fn eval_1_lanes<L: Lanes>(&self, uv: V2<L>) -> L {
        L::select(
            self.in_color0(uv),
            L::splat(mean(self.color1)),
            L::splat(mean(self.color0)),
        )
    }
}

impl Texture for Checkerboard {
    fn eval(&self, uv: Vec2) -> Rgb {
        self.eval_lanes::<f32>(V2::splat(uv)).lane(0)
    }

    fn eval_1(&self, uv: Vec2) -> f32 {
        self.eval_1_lanes::<f32>(V2::splat(uv))
    }

    fn range(&self) -> [f32; 2] {
        let (least, most) = (self.color0.min(self.color1), self.color0.max(self.color1));
        [least.min_element(), most.max_element()]
    }

    fn eval_batch(&self, uv: &[Vec2], out: &mut [Rgb]) {
        eval_in_lanes(self, uv, out);
    }

    fn eval_1_batch(&self, uv: &[Vec2], out: &mut [f32]) {
        eval_1_in_lanes(self, uv, out);
    }
}

/// The plugin's name in scene files, and its parameters' names.
pub const NAME: &str = "checkerboard";
pub const COLOR0: &str = "color0";
pub const COLOR1: &str = "color1";
pub const TO_UV: &str = "to_uv";

static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: COLOR0,
        kind: ParamKind::Rgb {
            default: Some([0.4, 0.4, 0.4]),
            max: 1e6,
        },
        unit: "",
        description: "colour of the checks where the halves of u and v agree (the one at the origin)",
    },
    ParamSpec {
        name: COLOR1,
        kind: ParamKind::Rgb {
            default: Some([0.2, 0.2, 0.2]),
            max: 1e6,
        },
        unit: "",
        description: "colour of the other checks",
    },
    ParamSpec {
        name: TO_UV,
        kind: ParamKind::UvTransform,
        unit: "",
        description: "map of the texture coordinates applied first (Mitsuba's to_uv): 2 × 2 checks per unit square",
    },
];

fn create(params: &mut Params) -> Result<Arc<dyn Texture>, PluginError> {
    let color0 = params.rgb(COLOR0)?;
    let color1 = params.rgb(COLOR1)?;
    let to_uv = params.uv_transform(TO_UV)?;
    Ok(Arc::new(Checkerboard::new(color0, color1, to_uv)))
}

inventory::submit! {
    TexturePlugin {
        name: NAME,
        description: "Mitsuba's checkerboard: two colours alternating in 2 × 2 checks per unit square of texture space",
        params: PARAMS,
        create,
    }
}
