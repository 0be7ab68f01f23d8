//! Orthonormal shading frames: BSDFs work in a local frame whose z axis is the shading normal.

use crate::math::lanes::{Lanes, V3};
use glam::Vec3;

/// An orthonormal basis (s, t, n), n the shading normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// Builds a frame around a unit normal with the branchless construction of Duff et al. 2017
    /// ("Building an orthonormal basis, revisited"), exact for n = ±z. Inlined: returned through
    /// memory, its frame was read back by the caller in wider pieces than it had been written
    /// in, which stalls until the stores reach the cache.
    #[inline]
    pub fn from_normal(n: Vec3) -> Self {
        let f = FrameLanes::<f32>::from_normal(V3::splat(n));
        Frame {
            s: f.s.lane(0),
            t: f.t.lane(0),
            n,
        }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// [`Frame`]s over [`Lanes`]: one per lane, built and applied as `Frame` is, bit for bit.
#[derive(Clone, Copy, Debug)]
pub struct FrameLanes<L> {
    pub s: V3<L>,
    pub t: V3<L>,
    pub n: V3<L>,
}

impl<L: Lanes> FrameLanes<L> {
    /// As [`Frame::from_normal`] in each lane.
    #[inline(always)]
    pub fn from_normal(n: V3<L>) -> Self {
        let one = L::splat(1.0);
        let sign = one.copysign(n.z);
        let a = -one / (sign + n.z);
        let b = n.x * n.y * a;
        let s = V3::new(one + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = V3::new(b, sign + n.y * n.y * a, -n.y);
        FrameLanes { s, t, n }
    }

    /// As [`Frame::to_world`] in each lane.
    #[inline(always)]
    pub fn to_world(&self, v: V3<L>) -> V3<L> {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn check_orthonormal(f: &Frame) {
        for (a, b) in [(f.s, f.t), (f.t, f.n), (f.n, f.s)] {
            assert!(a.dot(b).abs() < 1e-5, "not orthogonal: {f:?}");
        }
        for v in [f.s, f.t, f.n] {
            assert!((v.length() - 1.0).abs() < 1e-5, "not unit: {f:?}");
        }
        assert!(f.s.cross(f.t).dot(f.n) > 0.999, "not right-handed: {f:?}");
    }

    #[test]
    fn poles_give_orthonormal_frames() {
        check_orthonormal(&Frame::from_normal(Vec3::Z));
        check_orthonormal(&Frame::from_normal(-Vec3::Z));
    }

    proptest! {
        #[test]
        fn any_normal_gives_an_orthonormal_frame(x in -1.0f32..1.0, y in -1.0f32..1.0, z in -1.0f32..1.0) {
            let v = Vec3::new(x, y, z);
            prop_assume!(v.length() > 1e-3);
            let f = Frame::from_normal(v.normalize());
            check_orthonormal(&f);
            let w = Vec3::new(0.3, -0.2, 0.9).normalize();
            prop_assert!((f.to_world(f.to_local(w)) - w).length() < 1e-5);
        }
    }
}
