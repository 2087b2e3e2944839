//! Eight lanes of `f32` maths, for the packet integrator's stages (`render::packet`): each
//! operation is the scalar one lane by lane, so a lane's answer is the one-path integrator's bit
//! for bit, and where the caller is compiled for AVX2 the loops over lanes become vector
//! instructions. Lane-wide versions of the warps and frames live beside their scalar ones.

use glam::{Vec2, Vec3};
use std::ops::{Add, Div, Mul, Neg, Sub};

/// Lanes of a packet: an AVX2 vector of `f32`.
pub const LANES: usize = 8;

/// One `f32` per lane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct F32s(pub [f32; LANES]);

/// One flag per lane.
pub type Mask = [bool; LANES];

impl F32s {
    #[inline(always)]
    pub fn splat(v: f32) -> Self {
        F32s([v; LANES])
    }

    // Plain loops over the lanes: `array::map` and `from_fn` were left out of line, compiled
    // without the caller's AVX2.

    /// Lane `i` from `f(i)`.
    #[inline(always)]
    pub fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
        let mut v = [0.0; LANES];
        for (i, v) in v.iter_mut().enumerate() {
            *v = f(i);
        }
        F32s(v)
    }

    #[inline(always)]
    pub fn map(self, f: impl Fn(f32) -> f32) -> Self {
        let mut v = self.0;
        for v in &mut v {
            *v = f(*v);
        }
        F32s(v)
    }

    #[inline(always)]
    pub fn zip(self, other: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        let mut v = self.0;
        for (v, &b) in v.iter_mut().zip(&other.0) {
            *v = f(*v, b);
        }
        F32s(v)
    }

    #[inline(always)]
    pub fn sqrt(self) -> Self {
        self.map(f32::sqrt)
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        self.map(f32::abs)
    }

    /// `f32::max` lane by lane (a NaN lane takes the other operand).
    #[inline(always)]
    pub fn max(self, other: Self) -> Self {
        self.zip(other, f32::max)
    }

    /// `f32::min` lane by lane.
    #[inline(always)]
    pub fn min(self, other: Self) -> Self {
        self.zip(other, f32::min)
    }

    /// `a > b ? a : b` lane by lane, glam's `max_element` step.
    #[inline(always)]
    pub fn greater_of(self, other: Self) -> Self {
        self.zip(other, |a, b| if a > b { a } else { b })
    }

    /// Lanes where `f(self, other)`.
    #[inline(always)]
    pub fn test(self, other: Self, f: impl Fn(f32, f32) -> bool) -> Mask {
        let mut m = [false; LANES];
        for (m, (&a, &b)) in m.iter_mut().zip(self.0.iter().zip(&other.0)) {
            *m = f(a, b);
        }
        m
    }

    /// `a` where `mask`, else `b`.
    #[inline(always)]
    pub fn select(mask: Mask, a: Self, b: Self) -> Self {
        let mut v = b.0;
        for (v, (&m, &a)) in v.iter_mut().zip(mask.iter().zip(&a.0)) {
            if m {
                *v = a;
            }
        }
        F32s(v)
    }
}

macro_rules! lane_ops {
    ($($op:ident $f:ident),*) => {$(
        impl $op for F32s {
            type Output = F32s;
            #[inline(always)]
            fn $f(self, rhs: F32s) -> F32s {
                self.zip(rhs, |a, b| a.$f(b))
            }
        }
        impl $op<f32> for F32s {
            type Output = F32s;
            #[inline(always)]
            fn $f(self, rhs: f32) -> F32s {
                self.map(|a| a.$f(rhs))
            }
        }
        impl $op<F32s> for f32 {
            type Output = F32s;
            #[inline(always)]
            fn $f(self, rhs: F32s) -> F32s {
                rhs.map(|b| self.$f(b))
            }
        }
    )*};
}
lane_ops!(Add add, Sub sub, Mul mul, Div div);

impl Neg for F32s {
    type Output = F32s;
    #[inline(always)]
    fn neg(self) -> F32s {
        self.map(|a| -a)
    }
}

/// One `Vec3` per lane, as three rows (structure of arrays). Each operation is glam's `Vec3`
/// one in its order of operations.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3s {
    pub x: F32s,
    pub y: F32s,
    pub z: F32s,
}

impl Vec3s {
    #[inline(always)]
    pub fn new(x: F32s, y: F32s, z: F32s) -> Self {
        Vec3s { x, y, z }
    }

    #[inline(always)]
    pub fn splat(v: Vec3) -> Self {
        Vec3s::new(F32s::splat(v.x), F32s::splat(v.y), F32s::splat(v.z))
    }

    /// Lane `i` from `f(i)`.
    #[inline(always)]
    pub fn from_fn(mut f: impl FnMut(usize) -> Vec3) -> Self {
        let mut v = Vec3s::default();
        for i in 0..LANES {
            let lane = f(i);
            (v.x.0[i], v.y.0[i], v.z.0[i]) = (lane.x, lane.y, lane.z);
        }
        v
    }

    /// Lane `i`.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Vec3 {
        Vec3::new(self.x.0[i], self.y.0[i], self.z.0[i])
    }

    #[inline(always)]
    pub fn dot(self, rhs: Self) -> F32s {
        (self.x * rhs.x) + (self.y * rhs.y) + (self.z * rhs.z)
    }

    #[inline(always)]
    pub fn cross(self, rhs: Self) -> Self {
        Vec3s::new(
            self.y * rhs.z - rhs.y * self.z,
            self.z * rhs.x - rhs.z * self.x,
            self.x * rhs.y - rhs.x * self.y,
        )
    }

    /// Each row times `s`.
    #[inline(always)]
    pub fn scale(self, s: F32s) -> Self {
        Vec3s::new(self.x * s, self.y * s, self.z * s)
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        Vec3s::new(self.x.abs(), self.y.abs(), self.z.abs())
    }

    /// glam's `max_element`: `max(x, max(y, z))` with `a > b ? a : b`.
    #[inline(always)]
    pub fn max_element(self) -> F32s {
        self.x.greater_of(self.y.greater_of(self.z))
    }

    /// glam's `normalize_or_zero`: times `1 / length` where that is finite and positive.
    #[inline(always)]
    pub fn normalize_or_zero(self) -> Self {
        let rcp = 1.0 / self.dot(self).sqrt();
        // `is_finite() && > 0` as two comparisons, which vectorise (`is_finite` does not).
        let ok = rcp.test(F32s::splat(0.0), |r, zero| r > zero && r < f32::INFINITY);
        Vec3s::select(ok, self.scale(rcp), Vec3s::default())
    }

    /// Lanes where all three components are zero (`== Vec3::ZERO`).
    #[inline(always)]
    pub fn is_zero(self) -> Mask {
        let zero = |v: F32s| v.test(F32s::splat(0.0), |a, b| a == b);
        let (x, y, z) = (zero(self.x), zero(self.y), zero(self.z));
        let mut m = x;
        for (m, (&y, &z)) in m.iter_mut().zip(y.iter().zip(&z)) {
            *m &= y && z;
        }
        m
    }

    /// `a` where `mask`, else `b`.
    #[inline(always)]
    pub fn select(mask: Mask, a: Self, b: Self) -> Self {
        Vec3s::new(
            F32s::select(mask, a.x, b.x),
            F32s::select(mask, a.y, b.y),
            F32s::select(mask, a.z, b.z),
        )
    }
}

impl Add for Vec3s {
    type Output = Vec3s;
    #[inline(always)]
    fn add(self, rhs: Vec3s) -> Vec3s {
        Vec3s::new(self.x + rhs.x, self.y + rhs.y, self.z + rhs.z)
    }
}

impl Sub for Vec3s {
    type Output = Vec3s;
    #[inline(always)]
    fn sub(self, rhs: Vec3s) -> Vec3s {
        Vec3s::new(self.x - rhs.x, self.y - rhs.y, self.z - rhs.z)
    }
}

impl Neg for Vec3s {
    type Output = Vec3s;
    #[inline(always)]
    fn neg(self) -> Vec3s {
        Vec3s::new(-self.x, -self.y, -self.z)
    }
}

/// One `Vec2` per lane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec2s {
    pub x: F32s,
    pub y: F32s,
}

impl Vec2s {
    #[inline(always)]
    pub fn from_fn(mut f: impl FnMut(usize) -> Vec2) -> Self {
        let mut v = Vec2s::default();
        for i in 0..LANES {
            let lane = f(i);
            (v.x.0[i], v.y.0[i]) = (lane.x, lane.y);
        }
        v
    }

    #[inline(always)]
    pub fn lane(&self, i: usize) -> Vec2 {
        Vec2::new(self.x.0[i], self.y.0[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_follow_glam_bit_for_bit() {
        let mut rng = crate::sampling::Rng::new(7, 1);
        let mut v = || (rng.uniform() - 0.5) * 10.0;
        for round in 0..64 {
            let a: [Vec3; LANES] = std::array::from_fn(|_| Vec3::new(v(), v(), v()));
            let mut b: [Vec3; LANES] = std::array::from_fn(|_| Vec3::new(v(), v(), v()));
            // Degenerate lanes: zero, and huge (length overflows).
            if round % 4 == 0 {
                b[3] = Vec3::ZERO;
                b[5] = Vec3::splat(3e38);
            }
            let (sa, sb) = (Vec3s::from_fn(|i| a[i]), Vec3s::from_fn(|i| b[i]));
            for i in 0..LANES {
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(sa.dot(sb).0[i].to_bits(), a[i].dot(b[i]).to_bits());
                assert_eq!(bits(sa.cross(sb).lane(i)), bits(a[i].cross(b[i])));
                assert_eq!(
                    bits(sb.normalize_or_zero().lane(i)),
                    bits(b[i].normalize_or_zero())
                );
                assert_eq!(
                    sb.abs().max_element().0[i].to_bits(),
                    b[i].abs().max_element().to_bits()
                );
                assert_eq!(sb.is_zero()[i], b[i] == Vec3::ZERO);
            }
        }
    }
}
