//! Frame-typed wrappers over nalgebra (after sguaba's design).

use std::fmt;
use std::marker::PhantomData;
use std::ops::{Add, Mul, Neg, Sub};

use nalgebra::{UnitQuaternion, Vector3};

/// North-East-Down local-level frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ned;
/// Earth-centred Earth-fixed frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ecef;
/// Vehicle body frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Body;
/// Launch-point inertial frame of spec 10 (Y up at the launch point).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Launch;

/// A 3-vector expressed in frame `F`.
pub struct Vec3<F> {
    v: Vector3<f64>,
    frame: PhantomData<F>,
}

impl<F> Clone for Vec3<F> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<F> Copy for Vec3<F> {}
impl<F> PartialEq for Vec3<F> {
    fn eq(&self, o: &Self) -> bool {
        self.v == o.v
    }
}
impl<F> fmt::Debug for Vec3<F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "Vec3<{}>({}, {}, {})",
            std::any::type_name::<F>()
                .rsplit("::")
                .next()
                .unwrap_or("?"),
            self.v.x,
            self.v.y,
            self.v.z
        )
    }
}

impl<F> Vec3<F> {
    /// Components in frame `F`.
    pub fn new(x: f64, y: f64, z: f64) -> Self {
        Self::assume_in_frame(Vector3::new(x, y, z))
    }
    /// Declare that a raw vector is expressed in `F` (the caller asserts it).
    pub fn assume_in_frame(v: Vector3<f64>) -> Self {
        Self {
            v,
            frame: PhantomData,
        }
    }
    /// The raw components.
    pub fn raw(&self) -> Vector3<f64> {
        self.v
    }
    /// Euclidean norm.
    pub fn norm(&self) -> f64 {
        self.v.norm()
    }
}

impl<F> Add for Vec3<F> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self::assume_in_frame(self.v + o.v)
    }
}
impl<F> Sub for Vec3<F> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self::assume_in_frame(self.v - o.v)
    }
}
impl<F> Neg for Vec3<F> {
    type Output = Self;
    fn neg(self) -> Self {
        Self::assume_in_frame(-self.v)
    }
}
impl<F> Mul<f64> for Vec3<F> {
    type Output = Self;
    fn mul(self, s: f64) -> Self {
        Self::assume_in_frame(self.v * s)
    }
}

/// Rotation taking vectors expressed in `From` to `To`: `v_to = R * v_from`.
pub struct Rotation<From, To> {
    q: UnitQuaternion<f64>,
    frames: PhantomData<(From, To)>,
}

impl<A, B> Clone for Rotation<A, B> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<A, B> Copy for Rotation<A, B> {}
impl<A, B> fmt::Debug for Rotation<A, B> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Rotation({:?})", self.q)
    }
}

impl<From, To> Rotation<From, To> {
    /// Declare that `q` rotates `From` vectors into `To` (the caller asserts it).
    pub fn assume_from_quaternion(q: UnitQuaternion<f64>) -> Self {
        Self {
            q,
            frames: PhantomData,
        }
    }
    /// The quaternion.
    pub fn quaternion(&self) -> UnitQuaternion<f64> {
        self.q
    }
    /// The rotation `To → From`.
    pub fn inverse(&self) -> Rotation<To, From> {
        Rotation::assume_from_quaternion(self.q.inverse())
    }
}

impl<From, To> Mul<Vec3<From>> for Rotation<From, To> {
    type Output = Vec3<To>;
    fn mul(self, v: Vec3<From>) -> Vec3<To> {
        Vec3::assume_in_frame(self.q * v.v)
    }
}

/// Chaining: (B→C) * (A→B) = A→C.
impl<A, B, C> Mul<Rotation<A, B>> for Rotation<B, C> {
    type Output = Rotation<A, C>;
    fn mul(self, r: Rotation<A, B>) -> Rotation<A, C> {
        Rotation::assume_from_quaternion(self.q * r.q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chaining_equals_applying_in_turn() {
        let ab = Rotation::<Body, Ned>::assume_from_quaternion(UnitQuaternion::from_euler_angles(
            0.1, -0.2, 0.3,
        ));
        let bc = Rotation::<Ned, Ecef>::assume_from_quaternion(UnitQuaternion::from_euler_angles(
            -0.4, 0.5, 1.2,
        ));
        let v = Vec3::<Body>::new(1.0, -2.0, 0.5);
        let d = (bc * ab * v - bc * (ab * v)).norm();
        assert!(d < 1e-14);
        assert!(((ab.inverse() * (ab * v)) - v).norm() < 1e-14);
    }
}
