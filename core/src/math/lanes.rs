//! One formula for one sample or for several: the arithmetic a BSDF or a light needs, written
//! once over [`Lanes`], which is `f32` (one sample), glam's `Vec4` (four samples in one SSE2 or
//! NEON register), eight samples in one AVX register where the processor has AVX2, or sixteen
//! in one AVX-512 register on request (a batch kernel written as a [`LaneKernel`] runs with the
//! widest allowed: [`with_widest_lanes`], [`limit_width`]). A
//! plugin's scalar method and its batch method then run the same operations in the same order,
//! so that a sample comes out of the batch bit for bit as out of the scalar call: the batch
//! path is fast, and every statistical test of the scalar path holds for it. The BVH's node
//! tests are written over it too (a lane per child of a node, or per ray of a packet), their
//! AVX2 traversals running them through [`run_avx2`]: the SIMD intrinsics of the kernels are
//! in this file.
//!
//! Branches become masks: a kernel computes both sides where lanes disagree and picks per lane
//! with [`Lanes::select`]. Sine, cosine, arc tangent and arc cosine are polynomials in the same
//! operations (libm's functions have no SIMD form that rounds as they do, and cost more).
//!
//! Why one file of over 600 lines: the `Lanes` trait and its four implementations (f32, Vec4, the
//! AVX2 eight lanes, the AVX-512 sixteen) must stay in step, operation by operation; with its
//! tests.

use glam::{BVec4A, Vec2, Vec3, Vec4};
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The lanes' comparison results.
pub trait Mask: Copy + BitAnd<Output = Self> + BitOr<Output = Self> + Not<Output = Self> {
    /// Whether some lane is set.
    fn any(self) -> bool;
    /// Whether every lane is set.
    fn all(self) -> bool;
    /// Lane `i`.
    fn lane(self, i: usize) -> bool;
    /// The mask whose lane `i` is `f(i)`.
    fn from_fn(f: impl FnMut(usize) -> bool) -> Self;
    /// Lane `i` in bit `i` (a movemask).
    fn bits(self) -> u32;
}

/// f32 values, one or several, with IEEE single-precision operations that round alike in each
/// lane.
pub trait Lanes:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    type Mask: Mask;
    /// How many values.
    const WIDTH: usize;

    fn splat(v: f32) -> Self;
    /// The value whose lane `i` is `f(i)`.
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self;
    /// Lane `i`.
    fn lane(self, i: usize) -> f32;
    /// The lanes from `values[..WIDTH]`, in one vector load.
    fn load(values: &[f32]) -> Self;
    /// Writes the lanes into `out[..WIDTH]`, in one vector store.
    fn store(self, out: &mut [f32]);
    fn sqrt(self) -> Self;
    /// The largest integer not above `self`, as glam's SSE2 `floor` computes it: by truncation
    /// where |x| < 2²³ (so −0 gives +0), `self` itself elsewhere (NaN, infinities, integers).
    fn floor(self) -> Self;
    fn abs(self) -> Self;
    /// The magnitude of `self` with the sign of `sign`.
    fn copysign(self, sign: Self) -> Self;
    fn lt(self, rhs: Self) -> Self::Mask;
    fn le(self, rhs: Self) -> Self::Mask;
    fn gt(self, rhs: Self) -> Self::Mask;
    fn eq(self, rhs: Self) -> Self::Mask;
    fn is_finite(self) -> Self::Mask;
    /// `if_true` where `mask` is set, `if_false` elsewhere.
    fn select(mask: Self::Mask, if_true: Self, if_false: Self) -> Self;

    /// `self < rhs ? self : rhs` (SSE's `minps`: `rhs` if either is NaN).
    #[inline(always)]
    fn min(self, rhs: Self) -> Self {
        Self::select(self.lt(rhs), self, rhs)
    }

    /// `self > rhs ? self : rhs` (SSE's `maxps`: `rhs` if either is NaN).
    #[inline(always)]
    fn max(self, rhs: Self) -> Self {
        Self::select(self.gt(rhs), self, rhs)
    }

    /// As `f32::clamp`: NaN stays NaN.
    #[inline(always)]
    fn clamp(self, low: Self, high: Self) -> Self {
        let x = Self::select(self.lt(low), low, self);
        Self::select(x.gt(high), high, x)
    }

    /// Sine and cosine, from one polynomial each on [−π/4, π/4] after reduction by multiples
    /// of π/2 (Cephes' `sinf` and `cosf`): within 1.2·10⁻⁷ of the exact values (7.8·10⁻⁸ at
    /// worst in its test) for |x| up to 8192, where the reduction is exact; beyond, precision
    /// degrades. The same operations in every lane, so that four lanes give what one does (a
    /// call to `f32::sin_cos` per lane took 4–7 % of an N = 64 render, one profile each of
    /// Cornell and Veach).
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let one = Self::splat(1.0);
        // The nearest multiple k of π/2, and the rest, with π/2 split in three so that k times
        // the first part is exact.
        let k = (self * Self::splat(std::f32::consts::FRAC_2_PI) + Self::splat(0.5)).floor();
        let r = ((self - k * Self::splat(1.570_312_5)) - k * Self::splat(4.837_513e-4))
            - k * Self::splat(7.549_79e-8);
        let z = r * r;
        let sin_r = ((Self::splat(-1.951_529_6e-4) * z + Self::splat(8.332_161e-3)) * z
            - Self::splat(1.666_665_5e-1))
            * z
            * r
            + r;
        let cos_r = ((Self::splat(2.443_315_7e-5) * z - Self::splat(1.388_731_6e-3)) * z
            + Self::splat(4.166_664_6e-2))
            * z
            * z
            - Self::splat(0.5) * z
            + one;
        // The quadrant, k mod 4, decides which is which and their signs.
        let quadrant = k - Self::splat(4.0) * (k * Self::splat(0.25)).floor();
        let odd = quadrant.eq(one) | quadrant.eq(Self::splat(3.0));
        let (sin, cos) = (
            Self::select(odd, cos_r, sin_r),
            Self::select(odd, sin_r, cos_r),
        );
        let sin_negative = quadrant.gt(Self::splat(1.5));
        let cos_negative = quadrant.eq(one) | quadrant.eq(Self::splat(2.0));
        (
            Self::select(sin_negative, -sin, sin),
            Self::select(cos_negative, -cos, cos),
        )
    }

    /// The angle of the point (x, `self`) from the +x axis, in [−π, π], as `f32::atan2` for
    /// finite arguments: the smaller of |x| and |y| over the larger, reduced to
    /// [−tan π/8, tan π/8] and put through Cephes' `atanf` polynomial, then moved to its octant.
    /// Within 3·10⁻⁷ rad of the exact angle (1.25 units in the last place of π, to which the
    /// octant's offsets round; 2.6·10⁻⁷ at worst in its test), where libm's `atan2f` took 7 %
    /// of the dragon's render-loop instructions.
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
        let (zero, one) = (Self::splat(0.0), Self::splat(1.0));
        let (ax, ay) = (x.abs(), self.abs());
        let steep = ay.gt(ax);
        let (small, large) = (Self::select(steep, ax, ay), Self::select(steep, ay, ax));
        // Both zero: the angle of (±0, ±0) is 0 or π, with the sign of y, as atan2 gives it.
        let ratio = Self::select(large.gt(zero), small / large, zero);
        let above_eighth = ratio.gt(Self::splat(0.414_213_57));
        let t = Self::select(above_eighth, (ratio - one) / (ratio + one), ratio);
        let z = t * t;
        let atan_t = (((Self::splat(8.053_744_5e-2) * z - Self::splat(1.387_768_6e-1)) * z
            + Self::splat(1.997_771_1e-1))
            * z
            - Self::splat(3.333_295e-1))
            * z
            * t
            + t;
        let first_octant = Self::select(above_eighth, Self::splat(FRAC_PI_4), zero) + atan_t;
        let quadrant = Self::select(steep, Self::splat(FRAC_PI_2) - first_octant, first_octant);
        let x_negative = x.lt(zero) | (x.eq(zero) & Self::splat(1.0).copysign(x).lt(zero));
        let half = Self::select(x_negative, Self::splat(PI) - quadrant, quadrant);
        half.copysign(self)
    }

    /// The arc cosine, in [0, π], of `self` in [−1, 1] (NaN outside): Cephes' `acosf`, from
    /// its `asinf` polynomial of √((1 − |x|)/2) where |x| > ½ and of x elsewhere. Within
    /// 3·10⁻⁷ rad of the exact value (2.9·10⁻⁷ at worst in its test, near x = −1, where π − 2
    /// asin rounds to a unit in the last place of π).
    #[inline(always)]
    fn acos(self) -> Self {
        use std::f32::consts::{FRAC_PI_2, PI};
        let (zero, one, half) = (Self::splat(0.0), Self::splat(1.0), Self::splat(0.5));
        let a = self.abs();
        let near_one = a.gt(half);
        let z = Self::select(near_one, half * (one - a), a * a);
        let s = Self::select(near_one, z.sqrt(), a);
        let asin_s = ((((Self::splat(4.216_32e-2) * z + Self::splat(2.418_131_2e-2)) * z
            + Self::splat(4.547_002_6e-2))
            * z
            + Self::splat(7.495_300_3e-2))
            * z
            + Self::splat(1.666_675_2e-1))
            * z
            * s
            + s;
        // |x| > ½: acos |x| = 2 asin √((1 − |x|)/2), and acos x = π − acos |x| for x < 0.
        let twice = asin_s + asin_s;
        let from_one = Self::select(self.lt(zero), Self::splat(PI) - twice, twice);
        // |x| ≤ ½: acos x = π/2 − asin x.
        let from_zero = Self::splat(FRAC_PI_2) - asin_s.copysign(self);
        Self::select(near_one, from_one, from_zero)
    }
}

impl Mask for bool {
    #[inline(always)]
    fn any(self) -> bool {
        self
    }
    #[inline(always)]
    fn all(self) -> bool {
        self
    }
    #[inline(always)]
    fn lane(self, _i: usize) -> bool {
        self
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> bool) -> Self {
        f(0)
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        self as u32
    }
}

impl Lanes for f32 {
    type Mask = bool;
    const WIDTH: usize = 1;

    #[inline(always)]
    fn splat(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
        f(0)
    }
    #[inline(always)]
    fn lane(self, _i: usize) -> f32 {
        self
    }
    #[inline(always)]
    fn load(values: &[f32]) -> Self {
        values[0]
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        out[0] = self;
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn floor(self) -> Self {
        // Not `f32::floor`, which is a call to libm on x86-64 without SSE4.1.
        if self.abs() < 8_388_608.0 {
            // SAFETY: |self| < 2²³, so its integer part is an i32.
            let truncated = unsafe { self.to_int_unchecked::<i32>() } as f32;
            truncated + if truncated > self { -1.0 } else { 0.0 }
        } else {
            self
        }
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        f32::copysign(self, sign)
    }
    #[inline(always)]
    fn lt(self, rhs: Self) -> bool {
        self < rhs
    }
    #[inline(always)]
    fn le(self, rhs: Self) -> bool {
        self <= rhs
    }
    #[inline(always)]
    fn gt(self, rhs: Self) -> bool {
        self > rhs
    }
    #[inline(always)]
    fn eq(self, rhs: Self) -> bool {
        self == rhs
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    #[inline(always)]
    fn select(mask: bool, if_true: Self, if_false: Self) -> Self {
        if mask { if_true } else { if_false }
    }
}

impl Mask for BVec4A {
    #[inline(always)]
    fn any(self) -> bool {
        BVec4A::any(self)
    }
    #[inline(always)]
    fn all(self) -> bool {
        BVec4A::all(self)
    }
    #[inline(always)]
    fn lane(self, i: usize) -> bool {
        self.test(i)
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> bool) -> Self {
        BVec4A::new(f(0), f(1), f(2), f(3))
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        self.bitmask()
    }
}

impl Lanes for Vec4 {
    type Mask = BVec4A;
    const WIDTH: usize = 4;

    #[inline(always)]
    fn splat(v: f32) -> Self {
        Vec4::splat(v)
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
        Vec4::new(f(0), f(1), f(2), f(3))
    }
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        self[i]
    }
    #[inline(always)]
    fn load(values: &[f32]) -> Self {
        Vec4::from_slice(values)
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        self.write_to_slice(out)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Vec4::sqrt(self)
    }
    #[inline(always)]
    fn floor(self) -> Self {
        Vec4::floor(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Vec4::abs(self)
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        Vec4::copysign(self, sign)
    }
    #[inline(always)]
    fn lt(self, rhs: Self) -> BVec4A {
        self.cmplt(rhs)
    }
    #[inline(always)]
    fn le(self, rhs: Self) -> BVec4A {
        self.cmple(rhs)
    }
    #[inline(always)]
    fn gt(self, rhs: Self) -> BVec4A {
        self.cmpgt(rhs)
    }
    #[inline(always)]
    fn eq(self, rhs: Self) -> BVec4A {
        self.cmpeq(rhs)
    }
    #[inline(always)]
    fn is_finite(self) -> BVec4A {
        self.is_finite_mask()
    }
    #[inline(always)]
    fn select(mask: BVec4A, if_true: Self, if_false: Self) -> Self {
        Vec4::select(mask, if_true, if_false)
    }
    /// SSE2's `minps`, which is the trait's `self < rhs ? self : rhs`, NaN and zeros
    /// included: one instruction where the comparison and select take four (SSE2 has no
    /// blend). Elsewhere the comparison and select: NEON's `fmin` returns NaN if either is.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn min(self, rhs: Self) -> Self {
        use std::arch::x86_64::_mm_min_ps;
        // SAFETY: every x86-64 processor has SSE2.
        Vec4::from(unsafe { _mm_min_ps(self.into(), rhs.into()) })
    }
    /// SSE2's `maxps`, `self > rhs ? self : rhs`, as [`min`](Self::min) is `minps`.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn max(self, rhs: Self) -> Self {
        use std::arch::x86_64::_mm_max_ps;
        // SAFETY: every x86-64 processor has SSE2.
        Vec4::from(unsafe { _mm_max_ps(self.into(), rhs.into()) })
    }
}

/// A 3-vector of lanes (structure of arrays): x, y and z of one vector or of four. Its
/// operations round as glam's `Vec3` does (`dot` is `(x x' + y y') + z z'`, `normalize`
/// multiplies by the reciprocal of the length), so that a kernel ported from `Vec3` code keeps
/// its results.
#[derive(Clone, Copy, Debug)]
pub struct V3<L> {
    pub x: L,
    pub y: L,
    pub z: L,
}

impl<L: Lanes> V3<L> {
    #[inline(always)]
    pub fn new(x: L, y: L, z: L) -> Self {
        V3 { x, y, z }
    }

    /// `v` in every lane.
    #[inline(always)]
    pub fn splat(v: Vec3) -> Self {
        V3::new(L::splat(v.x), L::splat(v.y), L::splat(v.z))
    }

    /// The vector whose lane `i` is `f(i)`.
    #[inline(always)]
    pub fn from_fn(mut f: impl FnMut(usize) -> Vec3) -> Self {
        let mut lanes = [Vec3::ZERO; MAX_WIDTH];
        for (i, lane) in lanes.iter_mut().enumerate().take(L::WIDTH) {
            *lane = f(i);
        }
        V3::new(
            L::from_fn(|i| lanes[i].x),
            L::from_fn(|i| lanes[i].y),
            L::from_fn(|i| lanes[i].z),
        )
    }

    /// Lane `i`.
    #[inline(always)]
    pub fn lane(self, i: usize) -> Vec3 {
        Vec3::new(self.x.lane(i), self.y.lane(i), self.z.lane(i))
    }

    #[inline(always)]
    pub fn zero() -> Self {
        Self::splat(Vec3::ZERO)
    }

    #[inline(always)]
    pub fn dot(self, rhs: Self) -> L {
        self.x * rhs.x + self.y * rhs.y + self.z * rhs.z
    }

    #[inline(always)]
    pub fn cross(self, rhs: Self) -> Self {
        V3::new(
            self.y * rhs.z - rhs.y * self.z,
            self.z * rhs.x - rhs.z * self.x,
            self.x * rhs.y - rhs.x * self.y,
        )
    }

    #[inline(always)]
    pub fn length_squared(self) -> L {
        self.dot(self)
    }

    #[inline(always)]
    pub fn length(self) -> L {
        self.dot(self).sqrt()
    }

    /// As `Vec3::normalize`: times 1 / length, unchecked.
    #[inline(always)]
    pub fn normalize(self) -> Self {
        self * (L::splat(1.0) / self.length())
    }

    /// As `Vec3::normalize_or_zero`: zero where the reciprocal of the length is not finite and
    /// positive.
    #[inline(always)]
    pub fn normalize_or_zero(self) -> Self {
        let rcp = L::splat(1.0) / self.length();
        let ok = rcp.is_finite() & rcp.gt(L::splat(0.0));
        V3::select(ok, self * rcp, V3::zero())
    }

    /// Lane by lane, `if_true` where `mask` is set.
    #[inline(always)]
    pub fn select(mask: L::Mask, if_true: Self, if_false: Self) -> Self {
        V3::new(
            L::select(mask, if_true.x, if_false.x),
            L::select(mask, if_true.y, if_false.y),
            L::select(mask, if_true.z, if_false.z),
        )
    }

    /// Whether all three coordinates are finite.
    #[inline(always)]
    pub fn is_finite(self) -> L::Mask {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }

    /// Whether all three coordinates equal zero (±0), as `v == Vec3::ZERO`.
    #[inline(always)]
    pub fn is_zero(self) -> L::Mask {
        let zero = L::splat(0.0);
        self.x.eq(zero) & self.y.eq(zero) & self.z.eq(zero)
    }

    /// Coordinate-wise product, as `Vec3 * Vec3`.
    #[inline(always)]
    pub fn mul_elementwise(self, rhs: Self) -> Self {
        V3::new(self.x * rhs.x, self.y * rhs.y, self.z * rhs.z)
    }

    /// Coordinate-wise quotient, as `Vec3 / Vec3`.
    #[inline(always)]
    pub fn div_elementwise(self, rhs: Self) -> Self {
        V3::new(self.x / rhs.x, self.y / rhs.y, self.z / rhs.z)
    }
}

impl<L: Lanes> Add for V3<L> {
    type Output = Self;
    #[inline(always)]
    fn add(self, rhs: Self) -> Self {
        V3::new(self.x + rhs.x, self.y + rhs.y, self.z + rhs.z)
    }
}

impl<L: Lanes> Sub for V3<L> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, rhs: Self) -> Self {
        V3::new(self.x - rhs.x, self.y - rhs.y, self.z - rhs.z)
    }
}

impl<L: Lanes> Neg for V3<L> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        V3::new(-self.x, -self.y, -self.z)
    }
}

/// Scaling by one value per lane, as `Vec3 * f32`.
impl<L: Lanes> Mul<L> for V3<L> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, rhs: L) -> Self {
        V3::new(self.x * rhs, self.y * rhs, self.z * rhs)
    }
}

/// Division by one value per lane, as `Vec3 / f32`.
impl<L: Lanes> Div<L> for V3<L> {
    type Output = Self;
    #[inline(always)]
    fn div(self, rhs: L) -> Self {
        V3::new(self.x / rhs, self.y / rhs, self.z / rhs)
    }
}

/// A 2-vector of lanes (structure of arrays): the texture coordinates (u, v) of one point or of
/// several.
#[derive(Clone, Copy, Debug)]
pub struct V2<L> {
    pub x: L,
    pub y: L,
}

impl<L: Lanes> V2<L> {
    #[inline(always)]
    pub fn new(x: L, y: L) -> Self {
        V2 { x, y }
    }

    /// `v` in every lane.
    #[inline(always)]
    pub fn splat(v: Vec2) -> Self {
        V2::new(L::splat(v.x), L::splat(v.y))
    }

    /// The vector whose lane `i` is `f(i)`.
    #[inline(always)]
    pub fn from_fn(mut f: impl FnMut(usize) -> Vec2) -> Self {
        let mut lanes = [Vec2::ZERO; MAX_WIDTH];
        for (i, lane) in lanes.iter_mut().enumerate().take(L::WIDTH) {
            *lane = f(i);
        }
        V2::new(L::from_fn(|i| lanes[i].x), L::from_fn(|i| lanes[i].y))
    }

    /// Lane `i`.
    #[inline(always)]
    pub fn lane(self, i: usize) -> Vec2 {
        Vec2::new(self.x.lane(i), self.y.lane(i))
    }

    /// Lane by lane, `if_true` where `mask` is set.
    #[inline(always)]
    pub fn select(mask: L::Mask, if_true: Self, if_false: Self) -> Self {
        V2::new(
            L::select(mask, if_true.x, if_false.x),
            L::select(mask, if_true.y, if_false.y),
        )
    }
}

/// Element `k` of a batch argument that holds one value for every element or one for each.
#[inline(always)]
pub fn one_or_each<T: Copy>(values: &[T], k: usize) -> T {
    assert!(
        values.len() == 1 || k < values.len(),
        "one value, or one per element"
    );
    values[if values.len() == 1 { 0 } else { k }]
}

impl<L: Lanes> V3<L> {
    /// The lanes of a batch argument (see [`one_or_each`]) for the elements `k` (one per
    /// lane), each value's vector `vector(value)`: one vector in every lane, or each element's.
    #[inline(always)]
    pub fn gather<T: Copy, const W: usize>(
        values: &[T],
        k: [usize; W],
        vector: impl Fn(T) -> Vec3,
    ) -> Self {
        if let [one] = values {
            V3::splat(vector(*one))
        } else {
            V3::from_fn(|i| vector(values[k[i]]))
        }
    }
}

/// Runs `kernel` over the indices of `outputs` `W` at a time: each call gets `W` indices and
/// writes the results of as many as there are left (up to `W`) into the outputs it is given. A
/// last group of fewer than `W` repeats its last index in the lanes left, whose results are not
/// written.
#[inline(always)]
pub fn by_groups<const W: usize, O>(
    outputs: &mut [O],
    mut kernel: impl FnMut([usize; W], &mut [O]),
) {
    for (group, outputs) in outputs.chunks_mut(W).enumerate() {
        let last = outputs.len() - 1;
        let mut indices = [0; W];
        for (i, index) in indices.iter_mut().enumerate() {
            *index = W * group + i.min(last);
        }
        kernel(indices, outputs);
    }
}

/// The most lanes a [`Lanes`] type has.
pub const MAX_WIDTH: usize = 16;

/// A batch kernel written over [`Lanes`]: [`with_widest_lanes`] runs it with the widest lanes
/// the processor has.
pub trait LaneKernel {
    type Output;
    /// Runs with lanes `L`, `L::WIDTH` elements per group.
    fn run<L: Lanes, const W: usize>(self) -> Self::Output;
}

/// The widest lanes kernels run with unless [`limit_width`] says otherwise: eight (AVX2).
/// Sixteen AVX-512 lanes give the same results but are used only on request: on the Zen 4,
/// which executes a 512-bit operation as two 256-bit halves, they gained at most 12 % in one
/// binary (Cornell's interval; Veach's and the dragon's held no gain) and lost up to 10 %
/// against another build, and on an Intel Xeon they were 8–11 % slower (docs/performance.md,
/// "Tried and not kept").
pub const DEFAULT_WIDTH: usize = 8;

static WIDTH_LIMIT: AtomicUsize = AtomicUsize::new(DEFAULT_WIDTH);

/// Sets the widest lanes [`with_widest_lanes`] runs kernels with to `width` (4 or more; 8 is
/// used only where the processor has AVX2, 16 only where it has AVX-512; [`DEFAULT_WIDTH`]
/// until set), for the whole process: to time one width against another, or to test the
/// narrower on a processor that has the wider. The results are the same.
pub fn limit_width(width: usize) {
    assert!(width >= 4, "kernels run at least four lanes wide");
    WIDTH_LIMIT.store(width, Ordering::Relaxed);
}

/// Whether the processor has the AVX-512 subsets the sixteen lanes use (F for the arithmetic,
/// DQ for the bitwise operations on floats).
#[cfg(target_arch = "x86_64")]
#[inline]
fn has_avx512() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512dq")
}

/// The lanes [`with_widest_lanes`] runs kernels with: the widest of 16 (where the processor
/// has AVX-512), 8 (AVX2) and 4 that [`limit_width`] allows.
#[inline]
pub fn widest_width() -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        let limit = WIDTH_LIMIT.load(Ordering::Relaxed);
        if limit >= 16 && has_avx512() {
            return 16;
        }
        if limit >= 8 && std::arch::is_x86_feature_detected!("avx2") {
            return 8;
        }
    }
    4
}

/// Runs `kernel` with [`widest_width`] lanes: sixteen in AVX-512 registers, eight in AVX2
/// ones, or four (`Vec4`: SSE2, or NEON). Each lane computes what an `f32` would, so the
/// results are the same either way; only the time differs.
#[inline(always)]
pub fn with_widest_lanes<K: LaneKernel>(kernel: K) -> K::Output {
    #[cfg(target_arch = "x86_64")]
    match widest_width() {
        // SAFETY: the processor has AVX-512 F and DQ (`widest_width` is 16 only then).
        16 => return unsafe { sixteen::run_avx512(kernel) },
        // SAFETY: the processor has AVX2 (`widest_width` is 8 only then).
        8 => return unsafe { eight::run_avx2(kernel) },
        _ => {}
    }
    kernel.run::<Vec4, 4>()
}

/// As [`with_widest_lanes`], but at most eight lanes wide: for a kernel whose sums assign
/// elements to eight slots whatever the width, so that every width gives the same bits.
#[inline(always)]
pub fn with_lanes_up_to_eight<K: LaneKernel>(kernel: K) -> K::Output {
    #[cfg(target_arch = "x86_64")]
    if widest_width() >= 8 {
        // SAFETY: the processor has AVX2 (`widest_width` is 8 or more only then).
        return unsafe { eight::run_avx2(kernel) };
    }
    kernel.run::<Vec4, 4>()
}

#[cfg(target_arch = "x86_64")]
pub(crate) use eight::run_avx2;

/// Eight lanes in an AVX register. The type is private to this module and its values are
/// made only inside [`eight::run_avx2`], which runs only where the processor has AVX2: that is
/// what makes its intrinsics safe to call. Every method is inlined into that function, so
/// that the intrinsics are too.
#[cfg(target_arch = "x86_64")]
mod eight {
    use super::{LaneKernel, Lanes, Mask};
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

    /// Runs `kernel` eight lanes wide, in AVX registers. Safe to call from code compiled for
    /// AVX2 (the BVH's AVX2 traversals run their node tests so); elsewhere the caller checks
    /// that the processor has AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn run_avx2<K: LaneKernel>(kernel: K) -> K::Output {
        kernel.run::<F32x8, 8>()
    }

    #[derive(Clone, Copy)]
    pub(super) struct F32x8(__m256);

    /// Eight lanes in memory on a 32-byte boundary, where one vector access covers them within
    /// one cache line. Unaligned, wherever the stack happened to split them across two lines, a
    /// kernel's results written whole and read back a lane at a time ([`Lanes::lane`]) made each
    /// read wait for the split store to reach the cache, since it cannot be forwarded: a quarter
    /// of `balance`'s time at N = 64 on one thread.
    #[repr(C, align(32))]
    struct Aligned<T>([T; 8]);

    /// All bits set in a true lane, none in a false one, as AVX comparisons give them.
    #[derive(Clone, Copy)]
    pub(super) struct Mask8(__m256);

    // SAFETY (every `unsafe` block below): an `F32x8` or a `Mask8` exists only inside
    // `run_avx2`, so the processor has AVX2.

    macro_rules! binary {
        ($type:ident, $trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for $type {
                type Output = Self;
                #[inline(always)]
                fn $method(self, rhs: Self) -> Self {
                    $type(unsafe { $intrinsic(self.0, rhs.0) })
                }
            }
        };
    }
    binary!(F32x8, Add, add, _mm256_add_ps);
    binary!(F32x8, Sub, sub, _mm256_sub_ps);
    binary!(F32x8, Mul, mul, _mm256_mul_ps);
    binary!(F32x8, Div, div, _mm256_div_ps);
    binary!(Mask8, BitAnd, bitand, _mm256_and_ps);
    binary!(Mask8, BitOr, bitor, _mm256_or_ps);

    impl Neg for F32x8 {
        type Output = Self;
        #[inline(always)]
        fn neg(self) -> Self {
            F32x8(unsafe { _mm256_xor_ps(self.0, _mm256_set1_ps(-0.0)) })
        }
    }

    impl Not for Mask8 {
        type Output = Self;
        #[inline(always)]
        fn not(self) -> Self {
            Mask8(unsafe { _mm256_xor_ps(self.0, _mm256_castsi256_ps(_mm256_set1_epi32(-1))) })
        }
    }

    impl Mask for Mask8 {
        #[inline(always)]
        fn any(self) -> bool {
            self.bits() != 0
        }
        #[inline(always)]
        fn all(self) -> bool {
            self.bits() == 0xff
        }
        #[inline(always)]
        fn lane(self, i: usize) -> bool {
            self.bits() >> i & 1 != 0
        }
        #[inline(always)]
        fn from_fn(mut f: impl FnMut(usize) -> bool) -> Self {
            let mut lanes = Aligned([0i32; 8]);
            for (i, lane) in lanes.0.iter_mut().enumerate() {
                *lane = -(f(i) as i32);
            }
            // SAFETY: `Aligned` puts the eight i32 on the 32-byte boundary the load needs.
            Mask8(unsafe { _mm256_castsi256_ps(_mm256_load_si256(lanes.0.as_ptr().cast())) })
        }
        #[inline(always)]
        fn bits(self) -> u32 {
            unsafe { _mm256_movemask_ps(self.0) as u32 }
        }
    }

    impl F32x8 {
        #[inline(always)]
        fn compare<const PREDICATE: i32>(self, rhs: Self) -> Mask8 {
            Mask8(unsafe { _mm256_cmp_ps::<PREDICATE>(self.0, rhs.0) })
        }
    }

    impl Lanes for F32x8 {
        type Mask = Mask8;
        const WIDTH: usize = 8;

        #[inline(always)]
        fn splat(v: f32) -> Self {
            F32x8(unsafe { _mm256_set1_ps(v) })
        }
        #[inline(always)]
        fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
            let mut lanes = Aligned([0.0f32; 8]);
            for (i, lane) in lanes.0.iter_mut().enumerate() {
                *lane = f(i);
            }
            // SAFETY: `Aligned` puts the eight f32 on the 32-byte boundary the load needs.
            F32x8(unsafe { _mm256_load_ps(lanes.0.as_ptr()) })
        }
        /// Through an [`Aligned`] copy.
        #[inline(always)]
        fn lane(self, i: usize) -> f32 {
            let mut lanes = Aligned([0.0f32; 8]);
            // SAFETY: `Aligned` puts the eight f32 on the 32-byte boundary the store needs.
            unsafe { _mm256_store_ps(lanes.0.as_mut_ptr(), self.0) };
            lanes.0[i]
        }
        #[inline(always)]
        fn load(values: &[f32]) -> Self {
            assert!(values.len() >= 8, "eight values to load");
            // SAFETY: `values` holds the eight f32 the load reads.
            F32x8(unsafe { _mm256_loadu_ps(values.as_ptr()) })
        }
        #[inline(always)]
        fn store(self, out: &mut [f32]) {
            assert!(out.len() >= 8, "room for eight values");
            // SAFETY: `out` holds the eight f32 the store writes.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) }
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            F32x8(unsafe { _mm256_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn floor(self) -> Self {
            // `f32`'s floor (glam's SSE2 one) is the true floor but for −0, which it makes +0,
            // as adding +0 does.
            let floor =
                unsafe { _mm256_round_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(self.0) };
            F32x8(unsafe { _mm256_add_ps(floor, _mm256_setzero_ps()) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            F32x8(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        fn copysign(self, sign: Self) -> Self {
            unsafe {
                let sign_bit = _mm256_set1_ps(-0.0);
                F32x8(_mm256_or_ps(
                    _mm256_andnot_ps(sign_bit, self.0),
                    _mm256_and_ps(sign_bit, sign.0),
                ))
            }
        }
        #[inline(always)]
        fn lt(self, rhs: Self) -> Mask8 {
            self.compare::<_CMP_LT_OQ>(rhs)
        }
        #[inline(always)]
        fn le(self, rhs: Self) -> Mask8 {
            self.compare::<_CMP_LE_OQ>(rhs)
        }
        #[inline(always)]
        fn gt(self, rhs: Self) -> Mask8 {
            self.compare::<_CMP_GT_OQ>(rhs)
        }
        #[inline(always)]
        fn eq(self, rhs: Self) -> Mask8 {
            self.compare::<_CMP_EQ_OQ>(rhs)
        }
        #[inline(always)]
        fn is_finite(self) -> Mask8 {
            self.abs().lt(Self::splat(f32::INFINITY))
        }
        #[inline(always)]
        fn select(mask: Mask8, if_true: Self, if_false: Self) -> Self {
            F32x8(unsafe { _mm256_blendv_ps(if_false.0, if_true.0, mask.0) })
        }
        /// `vminps`, which is the trait's `self < rhs ? self : rhs`, NaN and zeros included
        /// (`rhs` unless `self` is the smaller): one instruction for a comparison and a blend.
        #[inline(always)]
        fn min(self, rhs: Self) -> Self {
            F32x8(unsafe { _mm256_min_ps(self.0, rhs.0) })
        }
        /// `vmaxps`, `self > rhs ? self : rhs`, as [`min`](Self::min) is `vminps`.
        #[inline(always)]
        fn max(self, rhs: Self) -> Self {
            F32x8(unsafe { _mm256_max_ps(self.0, rhs.0) })
        }
    }
}

/// Sixteen lanes in an AVX-512 register, as [`eight`] holds eight in an AVX one: the type is
/// made only inside [`sixteen::run_avx512`], which runs only where the processor has AVX-512 F
/// and DQ. Its masks are AVX-512's mask registers, one bit a lane.
#[cfg(target_arch = "x86_64")]
mod sixteen {
    use super::{LaneKernel, Lanes, Mask};
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

    /// Runs `kernel` sixteen lanes wide, in AVX-512 registers; the caller checks that the
    /// processor has AVX-512 F and DQ.
    #[target_feature(enable = "avx512f,avx512dq")]
    #[inline]
    pub(super) fn run_avx512<K: LaneKernel>(kernel: K) -> K::Output {
        kernel.run::<F32x16, 16>()
    }

    #[derive(Clone, Copy)]
    pub(super) struct F32x16(__m512);

    /// Sixteen lanes in memory on a 64-byte boundary, one cache line (see `eight`'s `Aligned`
    /// for why a vector read back a lane at a time must not straddle two).
    #[repr(C, align(64))]
    struct Aligned<T>([T; 16]);

    /// Bit `i` set where lane `i` is true.
    #[derive(Clone, Copy)]
    pub(super) struct Mask16(__mmask16);

    // SAFETY (every `unsafe` block below): an `F32x16` exists only inside `run_avx512`, so the
    // processor has AVX-512 F and DQ.

    macro_rules! binary {
        ($method:ident, $trait:ident, $intrinsic:ident) => {
            impl $trait for F32x16 {
                type Output = Self;
                #[inline(always)]
                fn $method(self, rhs: Self) -> Self {
                    F32x16(unsafe { $intrinsic(self.0, rhs.0) })
                }
            }
        };
    }
    binary!(add, Add, _mm512_add_ps);
    binary!(sub, Sub, _mm512_sub_ps);
    binary!(mul, Mul, _mm512_mul_ps);
    binary!(div, Div, _mm512_div_ps);

    impl Neg for F32x16 {
        type Output = Self;
        #[inline(always)]
        fn neg(self) -> Self {
            F32x16(unsafe { _mm512_xor_ps(self.0, _mm512_set1_ps(-0.0)) })
        }
    }

    impl BitAnd for Mask16 {
        type Output = Self;
        #[inline(always)]
        fn bitand(self, rhs: Self) -> Self {
            Mask16(self.0 & rhs.0)
        }
    }

    impl BitOr for Mask16 {
        type Output = Self;
        #[inline(always)]
        fn bitor(self, rhs: Self) -> Self {
            Mask16(self.0 | rhs.0)
        }
    }

    impl Not for Mask16 {
        type Output = Self;
        #[inline(always)]
        fn not(self) -> Self {
            Mask16(!self.0)
        }
    }

    impl Mask for Mask16 {
        #[inline(always)]
        fn any(self) -> bool {
            self.0 != 0
        }
        #[inline(always)]
        fn all(self) -> bool {
            self.0 == 0xffff
        }
        #[inline(always)]
        fn lane(self, i: usize) -> bool {
            self.0 >> i & 1 != 0
        }
        #[inline(always)]
        fn from_fn(mut f: impl FnMut(usize) -> bool) -> Self {
            Mask16((0..16).fold(0, |bits, i| bits | (f(i) as u16) << i))
        }
        #[inline(always)]
        fn bits(self) -> u32 {
            self.0 as u32
        }
    }

    impl F32x16 {
        #[inline(always)]
        fn compare<const PREDICATE: i32>(self, rhs: Self) -> Mask16 {
            Mask16(unsafe { _mm512_cmp_ps_mask::<PREDICATE>(self.0, rhs.0) })
        }
    }

    impl Lanes for F32x16 {
        type Mask = Mask16;
        const WIDTH: usize = 16;

        #[inline(always)]
        fn splat(v: f32) -> Self {
            F32x16(unsafe { _mm512_set1_ps(v) })
        }
        #[inline(always)]
        fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
            let mut lanes = Aligned([0.0f32; 16]);
            for (i, lane) in lanes.0.iter_mut().enumerate() {
                *lane = f(i);
            }
            // SAFETY: `Aligned` puts the sixteen f32 on the 64-byte boundary the load needs.
            F32x16(unsafe { _mm512_load_ps(lanes.0.as_ptr()) })
        }
        /// Through an [`Aligned`] copy.
        #[inline(always)]
        fn lane(self, i: usize) -> f32 {
            let mut lanes = Aligned([0.0f32; 16]);
            // SAFETY: `Aligned` puts the sixteen f32 on the 64-byte boundary the store needs.
            unsafe { _mm512_store_ps(lanes.0.as_mut_ptr(), self.0) };
            lanes.0[i]
        }
        #[inline(always)]
        fn load(values: &[f32]) -> Self {
            assert!(values.len() >= 16, "sixteen values to load");
            // SAFETY: `values` holds the sixteen f32 the load reads.
            F32x16(unsafe { _mm512_loadu_ps(values.as_ptr()) })
        }
        #[inline(always)]
        fn store(self, out: &mut [f32]) {
            assert!(out.len() >= 16, "room for sixteen values");
            // SAFETY: `out` holds the sixteen f32 the store writes.
            unsafe { _mm512_storeu_ps(out.as_mut_ptr(), self.0) }
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            F32x16(unsafe { _mm512_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn floor(self) -> Self {
            // As the eight lanes' floor: rounded toward −∞, then +0 added to make −0 +0.
            let floor = unsafe {
                _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(self.0)
            };
            F32x16(unsafe { _mm512_add_ps(floor, _mm512_setzero_ps()) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            F32x16(unsafe { _mm512_andnot_ps(_mm512_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        fn copysign(self, sign: Self) -> Self {
            unsafe {
                let sign_bit = _mm512_set1_ps(-0.0);
                F32x16(_mm512_or_ps(
                    _mm512_andnot_ps(sign_bit, self.0),
                    _mm512_and_ps(sign_bit, sign.0),
                ))
            }
        }
        #[inline(always)]
        fn lt(self, rhs: Self) -> Mask16 {
            self.compare::<_CMP_LT_OQ>(rhs)
        }
        #[inline(always)]
        fn le(self, rhs: Self) -> Mask16 {
            self.compare::<_CMP_LE_OQ>(rhs)
        }
        #[inline(always)]
        fn gt(self, rhs: Self) -> Mask16 {
            self.compare::<_CMP_GT_OQ>(rhs)
        }
        #[inline(always)]
        fn eq(self, rhs: Self) -> Mask16 {
            self.compare::<_CMP_EQ_OQ>(rhs)
        }
        #[inline(always)]
        fn is_finite(self) -> Mask16 {
            self.abs().lt(Self::splat(f32::INFINITY))
        }
        #[inline(always)]
        fn select(mask: Mask16, if_true: Self, if_false: Self) -> Self {
            F32x16(unsafe { _mm512_mask_blend_ps(mask.0, if_false.0, if_true.0) })
        }
        /// `vminps`, the trait's `self < rhs ? self : rhs`, NaN and zeros included.
        #[inline(always)]
        fn min(self, rhs: Self) -> Self {
            F32x16(unsafe { _mm512_min_ps(self.0, rhs.0) })
        }
        /// `vmaxps`, `self > rhs ? self : rhs`.
        #[inline(always)]
        fn max(self, rhs: Self) -> Self {
            F32x16(unsafe { _mm512_max_ps(self.0, rhs.0) })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values that exercise rounding, signs, zeros, infinities and NaN.
    const VALUES: [f32; 12] = [
        0.0,
        -0.0,
        1.0,
        -2.5,
        1e-30,
        3.4e38,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        0.1,
        7.0e-3,
        -1.0e5,
    ];

    fn same(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    /// Checks that every operation gives in each lane what it gives on an `f32`, for the lanes
    /// it runs with: lanes alternate (a, b) and (b, a) over all pairs of [`VALUES`].
    struct ComputeAsOne;

    impl LaneKernel for ComputeAsOne {
        type Output = usize;
        #[inline(always)]
        fn run<L: Lanes, const W: usize>(self) -> usize {
            type ScalarOp = fn(f32, f32) -> f32;
            for &a in &VALUES {
                for &b in &VALUES {
                    let pair = |i: usize| if i & 1 == 0 { (a, b) } else { (b, a) };
                    let (x, y) = (L::from_fn(|i| pair(i).0), L::from_fn(|i| pair(i).1));
                    let one = L::splat(1.0);
                    let values: [f32; MAX_WIDTH] = std::array::from_fn(|i| pair(i).0);
                    let mut stored = [f32::NAN; MAX_WIDTH];
                    L::load(&values).store(&mut stored);
                    for i in 0..W {
                        assert!(same(stored[i], values[i]), "{W} lanes, load and store");
                    }
                    let results: [(L, ScalarOp); 13] = [
                        (x + y, |x, y| x + y),
                        (x - y, |x, y| x - y),
                        (x * y, |x, y| x * y),
                        (x / y, |x, y| x / y),
                        (x.min(y), |x, y| Lanes::min(x, y)),
                        (x.max(y), |x, y| Lanes::max(x, y)),
                        (x.sqrt(), |x, _| Lanes::sqrt(x)),
                        (x.abs(), |x, _| Lanes::abs(x)),
                        (x.floor(), |x, _| Lanes::floor(x)),
                        (x.sin_cos().0, |x, _| Lanes::sin_cos(x).0),
                        (x.sin_cos().1, |x, _| Lanes::sin_cos(x).1),
                        (x.copysign(y), |x, y| Lanes::copysign(x, y)),
                        (x.clamp(y, one), |x, y| Lanes::clamp(x, y, 1.0)),
                    ];
                    for (op, (lanes, scalar)) in results.into_iter().enumerate() {
                        for i in 0..W {
                            let (x, y) = pair(i);
                            assert!(
                                same(lanes.lane(i), scalar(x, y)),
                                "{W} lanes, operation {op}, lane {i} of ({a}, {b})"
                            );
                        }
                    }
                    for i in 0..W {
                        let (x_i, y_i) = pair(i);
                        let masks = [
                            (x.lt(y), x_i < y_i),
                            (x.le(y), x_i <= y_i),
                            (x.gt(y), x_i > y_i),
                            (Lanes::eq(x, y), x_i == y_i),
                            (Lanes::is_finite(x), x_i.is_finite()),
                            (x.lt(y) | x.is_finite(), x_i < y_i || x_i.is_finite()),
                            (!x.is_finite() & x.le(y), !x_i.is_finite() && x_i <= y_i),
                            (x.le(y) & x.gt(y), false),
                        ];
                        for (m, (mask, expected)) in masks.into_iter().enumerate() {
                            assert_eq!(mask.lane(i), expected, "{W} lanes, mask {m}, lane {i}");
                            assert_eq!(mask.bits() >> i & 1 == 1, expected, "{W} lanes, bits");
                            assert_eq!(mask.bits() >> W, 0, "{W} lanes, bits past the lanes");
                        }
                        let single = L::Mask::from_fn(|j| j == i);
                        assert!(single.lane(i) && (0..W).all(|j| single.lane(j) == (j == i)));
                        assert!(single.any() && single.all() == (W == 1));
                    }
                    assert!(
                        L::Mask::from_fn(|_| true).all() && !(!L::Mask::from_fn(|_| true)).any()
                    );
                }
            }
            W
        }
    }

    /// Every operation gives in each lane of four (`Vec4`), eight (AVX2) and sixteen (AVX-512)
    /// what it gives on an `f32`, for each width the processor has; the widest allowed are the
    /// default eight unless more are asked for, and never wider than the processor's.
    #[test]
    fn lanes_of_every_width_compute_as_one() {
        assert_eq!(ComputeAsOne.run::<Vec4, 4>(), 4);
        #[cfg(target_arch = "x86_64")]
        let (has_avx2, has_avx512) = (std::arch::is_x86_feature_detected!("avx2"), has_avx512());
        #[cfg(not(target_arch = "x86_64"))]
        let (has_avx2, has_avx512) = (false, false);
        let expected = |limit: usize| match limit {
            16.. if has_avx512 => 16,
            8.. if has_avx2 => 8,
            _ => 4,
        };
        for limit in [4, 8, 16] {
            limit_width(limit);
            assert_eq!(widest_width(), expected(limit), "limited to {limit}");
            assert_eq!(with_widest_lanes(ComputeAsOne), expected(limit));
            assert_eq!(with_lanes_up_to_eight(ComputeAsOne), expected(limit.min(8)));
        }
        limit_width(DEFAULT_WIDTH);
        assert_eq!(widest_width(), expected(8), "eight by default");
    }

    /// A `V3` of four lanes normalises, crosses and dots as glam's `Vec3` does.
    #[test]
    fn vectors_of_lanes_round_as_glam_does() {
        let vectors = [
            Vec3::new(0.3, -1.7, 2.2),
            Vec3::new(1e-20, 0.0, -1e-21),
            Vec3::ZERO,
            Vec3::new(3e38, 3e38, 1.0),
        ];
        let v = V3::<Vec4>::from_fn(|i| vectors[i]);
        let w = V3::<Vec4>::splat(Vec3::new(-0.2, 0.9, 0.4));
        let (n, c, d) = (v.normalize_or_zero(), v.cross(w), v.dot(w));
        for (i, &u) in vectors.iter().enumerate() {
            let other = Vec3::new(-0.2, 0.9, 0.4);
            assert_eq!(n.lane(i), u.normalize_or_zero(), "lane {i}");
            assert_eq!(c.lane(i), u.cross(other), "lane {i}");
            assert!(same(d.lane(i), u.dot(other)), "lane {i}");
            assert_eq!(v.lane(i), u);
        }
    }

    /// The polynomial sine and cosine are within 1.2·10⁻⁷ (two units in the last place of 1) of
    /// the exact values over the angles the samplers use and well beyond (|x| ≤ 8192), at
    /// quadrant boundaries too, and give what `f32` gives in every lane.
    #[test]
    fn sine_and_cosine_are_accurate() {
        let mut worst = 0.0f64;
        let boundaries = (-64..=64).flat_map(|k| {
            let x = k as f32 * std::f32::consts::FRAC_PI_2;
            [x, next_up(x), next_down(x)]
        });
        let sweep = (0..200_000).map(|i| -8192.0 + 16384.0 * (i as f32 + 0.5) / 200_000.0);
        let turn = (0..100_000).map(|i| std::f32::consts::TAU * i as f32 / 100_000.0);
        for x in boundaries.chain(sweep).chain(turn) {
            let (sin, cos) = Lanes::sin_cos(x);
            let exact = (x as f64).sin_cos();
            worst = worst
                .max((sin as f64 - exact.0).abs())
                .max((cos as f64 - exact.1).abs());
            let (sin4, cos4) = Lanes::sin_cos(Vec4::new(x, -x, 0.5 * x, x));
            assert!(same(sin4[0], sin) && same(cos4[0], cos), "{x}");
            assert!(same(sin4[1], Lanes::sin_cos(-x).0), "{x}");
        }
        assert!(worst < 1.2e-7, "largest error {worst:e}");
        let (sin, cos) = Lanes::sin_cos(f32::NAN);
        assert!(sin.is_nan() && cos.is_nan());
    }

    /// The polynomial arc tangent is within 3·10⁻⁷ rad (1.25 units in the last place of π) of
    /// the exact angle over every direction of the plane, at the octant boundaries, the axes
    /// and signed zeros, and gives what `f32` gives in every lane.
    #[test]
    fn arc_tangent_is_accurate() {
        let mut worst = 0.0f64;
        let around = (0..400_000).map(|i| {
            let angle = std::f64::consts::TAU * (i as f64 + 0.5) / 400_000.0 - std::f64::consts::PI;
            let r = [1.0, 1e-3, 37.0, 1e-30][i % 4];
            ((r * angle.sin()) as f32, (r * angle.cos()) as f32)
        });
        let edges = [0.0f32, -0.0, 1.0, -1.0, 0.414_213_57, -2.0, 1e-38, 3e38]
            .into_iter()
            .flat_map(|a| [a, next_up(a), next_down(a)])
            .flat_map(|a| [(a, 1.0), (1.0, a), (a, -1.0), (-1.0, a), (a, a), (a, -a)]);
        for (y, x) in around.chain(edges) {
            let got = Lanes::atan2(y, x);
            let exact = (y as f64).atan2(x as f64);
            worst = worst.max((got as f64 - exact).abs());
            assert!(
                same(got.signum(), y.atan2(x).signum()) || got == 0.0,
                "({y}, {x})"
            );
            let four = Lanes::atan2(Vec4::new(y, -y, x, y), Vec4::new(x, x, y, -x));
            assert!(same(four[0], got), "({y}, {x})");
            assert!(same(four[1], Lanes::atan2(-y, x)), "({y}, {x})");
            assert!(same(four[2], Lanes::atan2(x, y)), "({y}, {x})");
        }
        for (y, x) in [(0.0f32, 0.0f32), (-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0)] {
            assert!(same(Lanes::atan2(y, x), y.atan2(x)), "({y}, {x})");
        }
        assert!(worst < 3e-7, "largest error {worst:e}");
        assert!(Lanes::atan2(f32::NAN, 1.0).is_nan());
    }

    /// The polynomial arc cosine is within 3·10⁻⁷ rad of the exact value over [−1, 1], at its
    /// ends and at ±½, where it changes form, and gives what `f32` gives in every lane.
    #[test]
    fn arc_cosine_is_accurate() {
        let mut worst = 0.0f64;
        let sweep = (0..=400_000).map(|i| -1.0 + 2.0 * i as f32 / 400_000.0);
        let edges = [-1.0f32, -0.5, 0.0, -0.0, 0.5, 1.0]
            .into_iter()
            .flat_map(|a| [a, next_up(a), next_down(a)])
            .filter(|a| a.abs() <= 1.0);
        for x in sweep.chain(edges) {
            let got = Lanes::acos(x);
            worst = worst.max((got as f64 - (x as f64).acos()).abs());
            let four = Lanes::acos(Vec4::new(x, -x, 0.5 * x, x));
            assert!(same(four[0], got) && same(four[1], Lanes::acos(-x)), "{x}");
        }
        assert!(worst < 3e-7, "largest error {worst:e}");
        assert_eq!(Lanes::acos(1.0), 0.0);
        assert!(Lanes::acos(1.5).is_nan() && Lanes::acos(f32::NAN).is_nan());
    }

    fn next_up(x: f32) -> f32 {
        crate::math::float::next_float_up(x)
    }

    fn next_down(x: f32) -> f32 {
        crate::math::float::next_float_down(x)
    }

    /// Doubles `len` inputs through `by_groups::<W>`, checking that a last partial group
    /// repeats its last index in the lanes left.
    fn doubled_by_groups<const W: usize>(len: usize) -> Vec<f32> {
        let inputs: Vec<f32> = (0..len).map(|i| i as f32).collect();
        let mut outputs = vec![f32::NAN; len];
        by_groups::<W, _>(&mut outputs, |indices, out| {
            let last = indices[out.len() - 1];
            assert!(indices[out.len()..].iter().all(|&i| i == last));
            for (o, i) in out.iter_mut().zip(indices) {
                *o = 2.0 * inputs[i];
            }
        });
        outputs
    }

    /// Groups of four, eight and sixteen cover every output once.
    #[test]
    fn groups_cover_every_input_once() {
        for len in [1, 3, 4, 7, 8, 9, 15, 16, 17, 33] {
            let expected: Vec<f32> = (0..len).map(|i| 2.0 * i as f32).collect();
            assert_eq!(
                doubled_by_groups::<4>(len),
                expected,
                "groups of four, {len} outputs"
            );
            assert_eq!(
                doubled_by_groups::<8>(len),
                expected,
                "groups of eight, {len} outputs"
            );
            assert_eq!(
                doubled_by_groups::<16>(len),
                expected,
                "groups of sixteen, {len} outputs"
            );
        }
    }
}
