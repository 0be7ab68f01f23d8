//! The texture interface: a value that varies over a surface, looked up at the shading point's
//! texture coordinates, and what a BSDF holds for a parameter that accepts a constant or a
//! texture.
//!
//! A texture plugin implements [`Texture`] (dyn-compatible: a BSDF holds an
//! `Arc<dyn Texture>`) and registers a [`TexturePlugin`](crate::registry::TexturePlugin);
//! scenes name it inline where a parameter accepts a texture,
//! `reflectance: (type: "checkerboard", color0: 0.2, color1: 0.8)`. Textures are built only
//! where a scene names one: a scene without textures runs no texture code.
//!
//! A BSDF parameter that accepts a texture ([`ParamKind::RgbOrTexture`],
//! [`ParamKind::FloatOrTexture`]) is read as a [`Textured`] value. The BSDF is generic over
//! where its parameter comes from ([`RgbSource`], [`FloatSource`]): built with the plain
//! constant (`Rgb`, `f32`) when the scene gave a number, so that its code is what it was
//! without textures (no lookup, no call, no branch), and with the [`Textured`] value when it
//! gave a texture.
//!
//! [`ParamKind::RgbOrTexture`]: crate::params::ParamKind::RgbOrTexture
//! [`ParamKind::FloatOrTexture`]: crate::params::ParamKind::FloatOrTexture

use crate::math::Rgb;
use crate::math::lanes::{LaneKernel, Lanes, MAX_WIDTH, V2, V3, by_groups, with_widest_lanes};
use glam::Vec2;
use std::sync::Arc;

/// A value over texture space (u, v), not filtered (a lookup at a point, as Mitsuba 3's
/// `bitmap` and `checkerboard` without MIP-mapping).
pub trait Texture: Send + Sync {
    /// The colour at `uv` (linear RGB).
    fn eval(&self, uv: Vec2) -> Rgb;
    /// One value at `uv`, for a parameter that is a number (a roughness): Mitsuba's `eval_1`
    /// (the mean of the channels, for a colour).
    fn eval_1(&self, uv: Vec2) -> f32;
    /// The least and the greatest value any channel of `eval` or `eval_1` takes anywhere: the
    /// scene loader refuses a texture whose values leave the range of the parameter it is
    /// given to.
    fn range(&self) -> [f32; 2];

    /// [`eval`](Self::eval) at each of `uv`, into `out`, bit for bit. The default makes one
    /// call each; a texture written over [`Lanes`] ([`TextureLanes`]) runs [`eval_in_lanes`].
    fn eval_batch(&self, uv: &[Vec2], out: &mut [Rgb]) {
        assert_eq!(uv.len(), out.len(), "one value per point");
        for (uv, out) in uv.iter().zip(out) {
            *out = self.eval(*uv);
        }
    }

    /// [`eval_1`](Self::eval_1) at each of `uv`, into `out`, bit for bit.
    fn eval_1_batch(&self, uv: &[Vec2], out: &mut [f32]) {
        assert_eq!(uv.len(), out.len(), "one value per point");
        for (uv, out) in uv.iter().zip(out) {
            *out = self.eval_1(*uv);
        }
    }
}

/// A texture whose lookups are written over [`Lanes`]: [`eval_in_lanes`] and
/// [`eval_1_in_lanes`] run them as its batch methods, its scalar methods on `f32`.
pub trait TextureLanes {
    /// `eval` in each lane.
    fn eval_lanes<L: Lanes>(&self, uv: V2<L>) -> V3<L>;
    /// `eval_1` in each lane.
    fn eval_1_lanes<L: Lanes>(&self, uv: V2<L>) -> L;
}

/// [`Texture::eval_batch`] of a texture written over [`Lanes`], four, eight or sixteen at a time.
pub fn eval_in_lanes<T: TextureLanes + ?Sized>(texture: &T, uv: &[Vec2], out: &mut [Rgb]) {
    assert_eq!(uv.len(), out.len(), "one value per point");
    struct Eval<'a, T: ?Sized>(&'a T, &'a [Vec2], &'a mut [Rgb]);
    impl<T: TextureLanes + ?Sized> LaneKernel for Eval<'_, T> {
        type Output = ();
        #[inline(always)]
        fn run<L: Lanes, const W: usize>(self) {
            let Eval(texture, uv, out) = self;
            by_groups::<W, _>(out, |k, out| {
                let value = texture.eval_lanes::<L>(V2::from_fn(|i| uv[k[i]]));
                for (i, out) in out.iter_mut().enumerate() {
                    *out = value.lane(i);
                }
            });
        }
    }
    with_widest_lanes(Eval(texture, uv, out));
}

/// [`Texture::eval_1_batch`] of a texture written over [`Lanes`], four or eight at a time.
pub fn eval_1_in_lanes<T: TextureLanes + ?Sized>(texture: &T, uv: &[Vec2], out: &mut [f32]) {
    assert_eq!(uv.len(), out.len(), "one value per point");
    struct Eval1<'a, T: ?Sized>(&'a T, &'a [Vec2], &'a mut [f32]);
    impl<T: TextureLanes + ?Sized> LaneKernel for Eval1<'_, T> {
        type Output = ();
        #[inline(always)]
        fn run<L: Lanes, const W: usize>(self) {
            let Eval1(texture, uv, out) = self;
            by_groups::<W, _>(out, |k, out| {
                let value = texture.eval_1_lanes::<L>(V2::from_fn(|i| uv[k[i]]));
                for (i, out) in out.iter_mut().enumerate() {
                    *out = value.lane(i);
                }
            });
        }
    }
    with_widest_lanes(Eval1(texture, uv, out));
}

/// A parameter as the scene gave it: a constant, or a texture.
#[derive(Clone)]
pub enum Textured<T> {
    Constant(T),
    Texture(Arc<dyn Texture>),
}

impl<T: std::fmt::Debug> std::fmt::Debug for Textured<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Textured::Constant(value) => f.debug_tuple("Constant").field(value).finish(),
            Textured::Texture(_) => f.write_str("Texture(..)"),
        }
    }
}

/// Where a colour parameter of a BSDF comes from: the constant itself (`Rgb`), or a
/// [`Textured`] value. A BSDF generic over it (`Diffuse<R: RgbSource>`) is built with `Rgb`
/// when the scene gave a constant, and its lanes then hold a splat of it, as they did before
/// textures.
pub trait RgbSource: Send + Sync + 'static {
    /// The value at each lane's texture coordinates.
    fn at<L: Lanes>(&self, uv: V2<L>) -> V3<L>;
    /// The value at one point's texture coordinates (a BSDF written the scalar way reads its
    /// parameter with `self.reflectance.value_at(ctx.uv)`).
    #[inline(always)]
    fn value_at(&self, uv: Vec2) -> Rgb {
        self.at::<f32>(V2::splat(uv)).lane(0)
    }
    /// Whether it varies over the surface (a texture): the BSDF's flags then include
    /// [`BsdfFlags::SPATIALLY_VARYING`](crate::bsdf::BsdfFlags::SPATIALLY_VARYING).
    fn varies(&self) -> bool;
    /// Whether a value of this type may vary (`false` for the plain constant): a BSDF generic
    /// over its sources tells its [`BsdfLanes::READS_CONTEXT`](crate::bsdf::BsdfLanes::READS_CONTEXT) with it.
    const MAY_VARY: bool;
}

/// [`RgbSource`] for a number parameter (a roughness).
pub trait FloatSource: Send + Sync + 'static {
    /// The value at each lane's texture coordinates.
    fn at<L: Lanes>(&self, uv: V2<L>) -> L;
    /// The value at one point's texture coordinates.
    #[inline(always)]
    fn value_at(&self, uv: Vec2) -> f32 {
        self.at::<f32>(V2::splat(uv))
    }
    /// Whether it varies over the surface (a texture).
    fn varies(&self) -> bool;
    /// Whether a value of this type may vary (`false` for the plain constant).
    const MAY_VARY: bool;
}

impl RgbSource for Rgb {
    const MAY_VARY: bool = false;

    #[inline(always)]
    fn at<L: Lanes>(&self, _uv: V2<L>) -> V3<L> {
        V3::splat(*self)
    }
    fn varies(&self) -> bool {
        false
    }
}

impl FloatSource for f32 {
    const MAY_VARY: bool = false;

    #[inline(always)]
    fn at<L: Lanes>(&self, _uv: V2<L>) -> L {
        L::splat(*self)
    }
    fn varies(&self) -> bool {
        false
    }
}

impl RgbSource for Textured<Rgb> {
    const MAY_VARY: bool = true;

    #[inline(always)]
    fn at<L: Lanes>(&self, uv: V2<L>) -> V3<L> {
        match self {
            Textured::Constant(value) => V3::splat(*value),
            Textured::Texture(texture) => rgb_lookup(texture.as_ref(), uv),
        }
    }
    fn varies(&self) -> bool {
        matches!(self, Textured::Texture(_))
    }
}

impl FloatSource for Textured<f32> {
    const MAY_VARY: bool = true;

    #[inline(always)]
    fn at<L: Lanes>(&self, uv: V2<L>) -> L {
        match self {
            Textured::Constant(value) => L::splat(*value),
            Textured::Texture(texture) => float_lookup(texture.as_ref(), uv),
        }
    }
    fn varies(&self) -> bool {
        matches!(self, Textured::Texture(_))
    }
}

/// A texture's colours at the lanes' uv: one `eval` for one lane, else one `eval_batch` call
/// (a texture's lanes are its own kernel: a dyn texture cannot be inlined into the BSDF's).
#[inline(always)]
fn rgb_lookup<L: Lanes>(texture: &dyn Texture, uv: V2<L>) -> V3<L> {
    if L::WIDTH == 1 {
        return V3::splat(texture.eval(uv.lane(0)));
    }
    let points: [Vec2; MAX_WIDTH] = std::array::from_fn(|i| uv.lane(i.min(L::WIDTH - 1)));
    let mut values = [Rgb::ZERO; MAX_WIDTH];
    texture.eval_batch(&points[..L::WIDTH], &mut values[..L::WIDTH]);
    V3::from_fn(|i| values[i])
}

/// [`rgb_lookup`] of one value.
#[inline(always)]
fn float_lookup<L: Lanes>(texture: &dyn Texture, uv: V2<L>) -> L {
    if L::WIDTH == 1 {
        return L::splat(texture.eval_1(uv.lane(0)));
    }
    let points: [Vec2; MAX_WIDTH] = std::array::from_fn(|i| uv.lane(i.min(L::WIDTH - 1)));
    let mut values = [0.0; MAX_WIDTH];
    texture.eval_1_batch(&points[..L::WIDTH], &mut values[..L::WIDTH]);
    L::from_fn(|i| values[i])
}

/// A 2D affine map of texture coordinates, (u, v) ↦ (a u + b v + c, d u + e v + f): Mitsuba's
/// `to_uv` (its 3 × 3 transform, or the upper-left 2 × 2 and the translation of a 4 × 4 one).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    /// Rows (a, b, c) and (d, e, f).
    pub rows: [[f32; 3]; 2],
}

impl UvTransform {
    pub const IDENTITY: UvTransform = UvTransform {
        rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
    };

    /// The map applied to each lane's coordinates.
    #[inline(always)]
    pub fn apply<L: Lanes>(&self, uv: V2<L>) -> V2<L> {
        let [[a, b, c], [d, e, f]] = self.rows;
        V2::new(
            L::splat(a) * uv.x + L::splat(b) * uv.y + L::splat(c),
            L::splat(d) * uv.x + L::splat(e) * uv.y + L::splat(f),
        )
    }

    /// `self` after `first`: the map that applies `first`, then `self`.
    pub fn after(&self, first: &UvTransform) -> UvTransform {
        let [[a, b, c], [d, e, f]] = self.rows;
        let [[p, q, r], [s, t, w]] = first.rows;
        UvTransform {
            rows: [
                [a * p + b * s, a * q + b * t, a * r + b * w + c],
                [d * p + e * s, d * q + e * t, d * r + e * w + f],
            ],
        }
    }
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform::IDENTITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec4;

    /// A texture whose colour is (u, v, u v), written over lanes.
    struct Ramp;

    impl TextureLanes for Ramp {
        fn eval_lanes<L: Lanes>(&self, uv: V2<L>) -> V3<L> {
            V3::new(uv.x, uv.y, uv.x * uv.y)
        }
        fn eval_1_lanes<L: Lanes>(&self, uv: V2<L>) -> L {
            uv.x - uv.y
        }
    }

    impl Texture for Ramp {
        fn eval(&self, uv: Vec2) -> Rgb {
            self.eval_lanes::<f32>(V2::splat(uv)).lane(0)
        }
        fn eval_1(&self, uv: Vec2) -> f32 {
            self.eval_1_lanes::<f32>(V2::splat(uv))
        }
        fn range(&self) -> [f32; 2] {
            [f32::NEG_INFINITY, f32::INFINITY]
        }
        fn eval_batch(&self, uv: &[Vec2], out: &mut [Rgb]) {
            eval_in_lanes(self, uv, out);
        }
        fn eval_1_batch(&self, uv: &[Vec2], out: &mut [f32]) {
            eval_1_in_lanes(self, uv, out);
        }
    }

    /// A textured source looks the texture up at each lane's uv, with one lane or four, and a
    /// constant one gives its constant everywhere.
    #[test]
    fn sources_look_textures_up_at_each_lane() {
        let points = [
            Vec2::new(0.1, 0.2),
            Vec2::new(0.5, -3.0),
            Vec2::new(7.0, 0.25),
            Vec2::new(-1.0, 1.0),
        ];
        let textured: Textured<Rgb> = Textured::Texture(Arc::new(Ramp));
        let number: Textured<f32> = Textured::Texture(Arc::new(Ramp));
        let four = V2::<Vec4>::from_fn(|i| points[i]);
        let (colours, values) = (textured.at(four), number.at(four));
        for (i, &uv) in points.iter().enumerate() {
            assert_eq!(colours.lane(i), Ramp.eval(uv));
            assert_eq!(textured.at::<f32>(V2::splat(uv)).lane(0), Ramp.eval(uv));
            assert_eq!(values.lane(i), uv.x - uv.y);
        }
        assert!(textured.varies() && !Rgb::ONE.varies() && !0.5f32.varies());
        let constant: Textured<Rgb> = Textured::Constant(Rgb::new(0.1, 0.2, 0.3));
        assert_eq!(constant.at(four).lane(3), Rgb::new(0.1, 0.2, 0.3));
        assert!(!constant.varies());
    }

    #[test]
    fn uv_transforms_compose_as_maps() {
        let scale = UvTransform {
            rows: [[2.0, 0.0, 0.0], [0.0, 3.0, 0.0]],
        };
        let shift = UvTransform {
            rows: [[1.0, 0.0, 0.5], [0.0, 1.0, -1.0]],
        };
        let uv = V2::<f32>::splat(Vec2::new(0.25, 0.5));
        let both = shift.after(&scale).apply(uv).lane(0);
        assert_eq!(both, shift.apply(scale.apply(uv)).lane(0));
        assert_eq!(both, Vec2::new(1.0, 0.5));
        assert_eq!(
            UvTransform::default().apply(uv).lane(0),
            Vec2::new(0.25, 0.5)
        );
    }
}
