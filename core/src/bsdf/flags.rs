//! What a BSDF says of its lobes: [`BsdfFlags`].

use std::ops::{BitAnd, BitOr, BitOrAssign};

/// Which kinds of lobes a BSDF has, and whether it varies over the surface; integrators use
/// them to skip work (light sampling is useless for a purely delta BSDF), the shading point to
/// know whether to compute texture coordinates and whether light may pass through.
///
/// A set of bits, combined with `|`: `BsdfFlags::DIFFUSE_REFLECTION | BsdfFlags::GLOSSY_REFLECTION`.
/// Each lobe kind comes as a reflection and a transmission bit (Mitsuba 3's `BSDFFlags`), so
/// that a transmitting BSDF says so; [`diffuse`](Self::diffuse), [`transmission`](Self::transmission)
/// and the other queries test either.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct BsdfFlags(u32);

impl BsdfFlags {
    /// No lobe: the surface scatters nothing (the back of a one-sided BSDF).
    pub const NONE: Self = BsdfFlags(0);
    pub const DIFFUSE_REFLECTION: Self = BsdfFlags(1);
    pub const GLOSSY_REFLECTION: Self = BsdfFlags(1 << 1);
    /// A Dirac lobe of reflection (a mirror): `eval` and `pdf` are zero for every given direction.
    pub const DELTA_REFLECTION: Self = BsdfFlags(1 << 2);
    pub const DIFFUSE_TRANSMISSION: Self = BsdfFlags(1 << 3);
    pub const GLOSSY_TRANSMISSION: Self = BsdfFlags(1 << 4);
    /// A Dirac lobe of transmission (smooth glass).
    pub const DELTA_TRANSMISSION: Self = BsdfFlags(1 << 5);
    /// The BSDF reads [`BsdfContext::uv`](super::BsdfContext::uv) (a textured parameter): the shading point computes
    /// the texture coordinates for it. The scene loader adds it to the flags of a BSDF that
    /// was given a texture, so a BSDF need not say it for its textured parameters.
    pub const SPATIALLY_VARYING: Self = BsdfFlags(1 << 6);

    pub const DIFFUSE: Self = BsdfFlags(Self::DIFFUSE_REFLECTION.0 | Self::DIFFUSE_TRANSMISSION.0);
    pub const GLOSSY: Self = BsdfFlags(Self::GLOSSY_REFLECTION.0 | Self::GLOSSY_TRANSMISSION.0);
    pub const DELTA: Self = BsdfFlags(Self::DELTA_REFLECTION.0 | Self::DELTA_TRANSMISSION.0);
    pub const REFLECTION: Self = BsdfFlags(
        Self::DIFFUSE_REFLECTION.0 | Self::GLOSSY_REFLECTION.0 | Self::DELTA_REFLECTION.0,
    );
    pub const TRANSMISSION: Self = BsdfFlags(
        Self::DIFFUSE_TRANSMISSION.0 | Self::GLOSSY_TRANSMISSION.0 | Self::DELTA_TRANSMISSION.0,
    );

    /// The bits of both.
    pub const fn union(self, other: Self) -> Self {
        BsdfFlags(self.0 | other.0)
    }

    /// Whether every bit of `other` is set.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    /// Whether some bit of `other` is set.
    pub const fn intersects(self, other: Self) -> bool {
        self.0 & other.0 != 0
    }

    /// A diffuse lobe, of reflection or transmission.
    pub const fn diffuse(self) -> bool {
        self.intersects(Self::DIFFUSE)
    }

    /// A glossy lobe, of reflection or transmission.
    pub const fn glossy(self) -> bool {
        self.intersects(Self::GLOSSY)
    }

    /// A Dirac lobe, of reflection or transmission.
    pub const fn delta(self) -> bool {
        self.intersects(Self::DELTA)
    }

    /// Some lobe of reflection.
    pub const fn reflection(self) -> bool {
        self.intersects(Self::REFLECTION)
    }

    /// Some lobe of transmission: directions on the far side of the surface (`wi.z < 0`) are
    /// valid.
    pub const fn transmission(self) -> bool {
        self.intersects(Self::TRANSMISSION)
    }

    /// See [`SPATIALLY_VARYING`](Self::SPATIALLY_VARYING).
    pub const fn spatially_varying(self) -> bool {
        self.intersects(Self::SPATIALLY_VARYING)
    }

    /// Only Dirac lobes, which light sampling can never reach.
    pub const fn is_pure_delta(self) -> bool {
        self.delta() && !self.intersects(Self::DIFFUSE.union(Self::GLOSSY))
    }

    /// No lobe at all: the surface scatters nothing.
    pub const fn is_black(self) -> bool {
        !self.intersects(Self::REFLECTION.union(Self::TRANSMISSION))
    }
}

impl BitOr for BsdfFlags {
    type Output = Self;
    fn bitor(self, rhs: Self) -> Self {
        self.union(rhs)
    }
}

impl BitOrAssign for BsdfFlags {
    fn bitor_assign(&mut self, rhs: Self) {
        *self = self.union(rhs);
    }
}

impl BitAnd for BsdfFlags {
    type Output = Self;
    fn bitand(self, rhs: Self) -> Self {
        BsdfFlags(self.0 & rhs.0)
    }
}
