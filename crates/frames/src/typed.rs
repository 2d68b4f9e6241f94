//! Frame-typed wrappers over nalgebra (after sguaba's design).
//!
//! Every wrapper is `Copy`, holds exactly the nalgebra value it wraps (the
//! frame is a zero-sized [`PhantomData`]) and forwards each operation to the
//! same nalgebra operation, marked `#[inline]`: typed code compiles to the
//! same floating-point operations, in the same order, as the raw code.

use std::fmt;
use std::marker::PhantomData;
use std::ops::{Add, AddAssign, Div, Index, Mul, Neg, Sub, SubAssign};

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

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

/// Last path segment of a frame marker's type name (for `Debug`).
fn frame_name<F>() -> &'static str {
    std::any::type_name::<F>()
        .rsplit("::")
        .next()
        .unwrap_or("?")
}

/// A 3-vector expressed in frame `F`.
pub struct Vec3<F> {
    v: Vector3<f64>,
    frame: PhantomData<F>,
}

impl<F> Clone for Vec3<F> {
    #[inline]
    fn clone(&self) -> Self {
        *self
    }
}
impl<F> Copy for Vec3<F> {}
impl<F> PartialEq for Vec3<F> {
    #[inline]
    fn eq(&self, o: &Self) -> bool {
        self.v == o.v
    }
}
impl<F> Default for Vec3<F> {
    #[inline]
    fn default() -> Self {
        Self::zeros()
    }
}
impl<F> fmt::Debug for Vec3<F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "Vec3<{}>({}, {}, {})",
            frame_name::<F>(),
            self.v.x,
            self.v.y,
            self.v.z
        )
    }
}
impl<F> fmt::Display for Vec3<F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "({}, {}, {}) in {}",
            self.v.x,
            self.v.y,
            self.v.z,
            frame_name::<F>()
        )
    }
}

impl<F> Vec3<F> {
    /// Components in frame `F`.
    #[inline]
    pub fn new(x: f64, y: f64, z: f64) -> Self {
        Self::assume_in_frame(Vector3::new(x, y, z))
    }
    /// The zero vector.
    #[inline]
    pub fn zeros() -> Self {
        Self::assume_in_frame(Vector3::zeros())
    }
    /// Declare that a raw vector is expressed in `F` (the caller asserts it).
    #[inline]
    pub fn assume_in_frame(v: Vector3<f64>) -> Self {
        Self {
            v,
            frame: PhantomData,
        }
    }
    /// The raw components (the frame is dropped).
    #[inline]
    pub fn raw(&self) -> Vector3<f64> {
        self.v
    }
    /// The raw components by reference.
    #[inline]
    pub fn as_raw(&self) -> &Vector3<f64> {
        &self.v
    }
    /// First component (north in NED).
    #[inline]
    pub fn x(&self) -> f64 {
        self.v.x
    }
    /// Second component (east in NED).
    #[inline]
    pub fn y(&self) -> f64 {
        self.v.y
    }
    /// Third component (down in NED).
    #[inline]
    pub fn z(&self) -> f64 {
        self.v.z
    }
    /// Euclidean norm.
    #[inline]
    pub fn norm(&self) -> f64 {
        self.v.norm()
    }
    /// Squared Euclidean norm.
    #[inline]
    pub fn norm_squared(&self) -> f64 {
        self.v.norm_squared()
    }
    /// Dot product with a vector in the same frame.
    #[inline]
    pub fn dot(&self, o: &Self) -> f64 {
        self.v.dot(&o.v)
    }
    /// Cross product with a vector in the same frame (in that frame too).
    #[inline]
    pub fn cross(&self, o: &Self) -> Self {
        Self::assume_in_frame(self.v.cross(&o.v))
    }
    /// Reinterpret in another frame (the caller asserts the frames coincide
    /// here, e.g. a vector measured by the IMU used as a body vector).
    #[inline]
    pub fn assume_frame<G>(self) -> Vec3<G> {
        Vec3::assume_in_frame(self.v)
    }
}

impl<F> Index<usize> for Vec3<F> {
    type Output = f64;
    #[inline]
    fn index(&self, i: usize) -> &f64 {
        &self.v[i]
    }
}
impl<F> Add for Vec3<F> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self::assume_in_frame(self.v + o.v)
    }
}
impl<F> AddAssign for Vec3<F> {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        self.v += o.v;
    }
}
impl<F> Sub for Vec3<F> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self::assume_in_frame(self.v - o.v)
    }
}
impl<F> SubAssign for Vec3<F> {
    #[inline]
    fn sub_assign(&mut self, o: Self) {
        self.v -= o.v;
    }
}
impl<F> Neg for Vec3<F> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self::assume_in_frame(-self.v)
    }
}
impl<F> Mul<f64> for Vec3<F> {
    type Output = Self;
    #[inline]
    fn mul(self, s: f64) -> Self {
        Self::assume_in_frame(self.v * s)
    }
}
impl<F> Mul<Vec3<F>> for f64 {
    type Output = Vec3<F>;
    #[inline]
    fn mul(self, v: Vec3<F>) -> Vec3<F> {
        Vec3::assume_in_frame(self * v.v)
    }
}
impl<F> Div<f64> for Vec3<F> {
    type Output = Self;
    #[inline]
    fn div(self, s: f64) -> Self {
        Self::assume_in_frame(self.v / s)
    }
}

/// Rotation taking vectors expressed in `From` to `To`: `v_to = R * v_from`,
/// stored as a unit quaternion (Hamilton convention, nalgebra's
/// [`UnitQuaternion`]; `R * v` is `q v q*`).
pub struct Rotation<From, To> {
    q: UnitQuaternion<f64>,
    frames: PhantomData<(From, To)>,
}

impl<A, B> Clone for Rotation<A, B> {
    #[inline]
    fn clone(&self) -> Self {
        *self
    }
}
impl<A, B> Copy for Rotation<A, B> {}
impl<A, B> PartialEq for Rotation<A, B> {
    #[inline]
    fn eq(&self, o: &Self) -> bool {
        self.q == o.q
    }
}
impl<A, B> fmt::Debug for Rotation<A, B> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "Rotation<{}, {}>({:?})",
            frame_name::<A>(),
            frame_name::<B>(),
            self.q
        )
    }
}

impl<From, To> Rotation<From, To> {
    /// Declare that `q` rotates `From` vectors into `To` (the caller asserts it).
    #[inline]
    pub fn assume_from_quaternion(q: UnitQuaternion<f64>) -> Self {
        Self {
            q,
            frames: PhantomData,
        }
    }
    /// The quaternion (the frames are dropped).
    #[inline]
    pub fn quaternion(&self) -> UnitQuaternion<f64> {
        self.q
    }
    /// The rotation `To → From`.
    #[inline]
    pub fn inverse(&self) -> Rotation<To, From> {
        Rotation::assume_from_quaternion(self.q.inverse())
    }
    /// The same rotation as a direction cosine matrix (nalgebra's
    /// `to_rotation_matrix`).
    #[inline]
    pub fn matrix(&self) -> RotationMatrix<From, To> {
        RotationMatrix::assume_from_matrix(self.q.to_rotation_matrix().into_inner())
    }
    /// Angle to another rotation between the same frames \[rad\].
    #[inline]
    pub fn angle_to(&self, o: &Self) -> f64 {
        self.q.angle_to(&o.q)
    }
}

impl<F> Rotation<F, F> {
    /// The identity: `F` onto itself.
    #[inline]
    pub fn identity() -> Self {
        Self::assume_from_quaternion(UnitQuaternion::identity())
    }
    /// The rotation by a rotation vector (axis × angle \[rad\]) expressed
    /// in `F` (nalgebra's `from_scaled_axis`): a small attitude correction,
    /// or the turn of a frame that moves (e.g. NED over one step).
    #[inline]
    pub fn from_rotation_vector(phi: Vec3<F>) -> Self {
        Self::assume_from_quaternion(UnitQuaternion::from_scaled_axis(phi.v))
    }
}

impl Rotation<Body, Ned> {
    /// Attitude from roll, pitch, yaw \[rad\] (z-y-x Tait–Bryan, aerospace:
    /// yaw about down, then pitch, then roll; nalgebra's `from_euler_angles`).
    #[inline]
    pub fn from_euler_angles(roll: f64, pitch: f64, yaw: f64) -> Self {
        Self::assume_from_quaternion(UnitQuaternion::from_euler_angles(roll, pitch, yaw))
    }
    /// Roll, pitch, yaw \[rad\] of this attitude (the inverse of
    /// [`from_euler_angles`](Self::from_euler_angles)).
    #[inline]
    pub fn euler_angles(&self) -> (f64, f64, f64) {
        self.q.euler_angles()
    }
}

impl<From, To> Mul<Vec3<From>> for Rotation<From, To> {
    type Output = Vec3<To>;
    #[inline]
    fn mul(self, v: Vec3<From>) -> Vec3<To> {
        Vec3::assume_in_frame(self.q * v.v)
    }
}

/// Chaining: (B→C) * (A→B) = A→C.
impl<A, B, C> Mul<Rotation<A, B>> for Rotation<B, C> {
    type Output = Rotation<A, C>;
    #[inline]
    fn mul(self, r: Rotation<A, B>) -> Rotation<A, C> {
        Rotation::assume_from_quaternion(self.q * r.q)
    }
}

/// Rotation `From → To` as a direction cosine matrix: `v_to = C * v_from`.
/// What the Earth-frame conversions return and what the filters' Jacobians
/// need; applying it is a matrix–vector product (not the quaternion
/// sandwich of [`Rotation`], which rounds differently).
pub struct RotationMatrix<From, To> {
    m: Matrix3<f64>,
    frames: PhantomData<(From, To)>,
}

impl<A, B> Clone for RotationMatrix<A, B> {
    #[inline]
    fn clone(&self) -> Self {
        *self
    }
}
impl<A, B> Copy for RotationMatrix<A, B> {}
impl<A, B> PartialEq for RotationMatrix<A, B> {
    #[inline]
    fn eq(&self, o: &Self) -> bool {
        self.m == o.m
    }
}
impl<A, B> fmt::Debug for RotationMatrix<A, B> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "RotationMatrix<{}, {}>({:?})",
            frame_name::<A>(),
            frame_name::<B>(),
            self.m
        )
    }
}

impl<From, To> RotationMatrix<From, To> {
    /// Declare that the orthonormal `m` takes `From` vectors into `To` (the
    /// caller asserts it).
    #[inline]
    pub fn assume_from_matrix(m: Matrix3<f64>) -> Self {
        Self {
            m,
            frames: PhantomData,
        }
    }
    /// The raw matrix (the frames are dropped).
    #[inline]
    pub fn raw(&self) -> Matrix3<f64> {
        self.m
    }
    /// The raw matrix by reference.
    #[inline]
    pub fn as_raw(&self) -> &Matrix3<f64> {
        &self.m
    }
    /// The rotation `To → From` (the transpose).
    #[inline]
    pub fn transpose(&self) -> RotationMatrix<To, From> {
        RotationMatrix::assume_from_matrix(self.m.transpose())
    }
}

impl<From, To> Mul<Vec3<From>> for RotationMatrix<From, To> {
    type Output = Vec3<To>;
    #[inline]
    fn mul(self, v: Vec3<From>) -> Vec3<To> {
        Vec3::assume_in_frame(self.m * v.v)
    }
}

/// Chaining: (B→C) * (A→B) = A→C.
impl<A, B, C> Mul<RotationMatrix<A, B>> for RotationMatrix<B, C> {
    type Output = RotationMatrix<A, C>;
    #[inline]
    fn mul(self, r: RotationMatrix<A, B>) -> RotationMatrix<A, C> {
        RotationMatrix::assume_from_matrix(self.m * r.m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chaining_equals_applying_in_turn() {
        let ab = Rotation::<Body, Ned>::from_euler_angles(0.1, -0.2, 0.3);
        let bc = Rotation::<Ned, Ecef>::assume_from_quaternion(UnitQuaternion::from_euler_angles(
            -0.4, 0.5, 1.2,
        ));
        let v = Vec3::<Body>::new(1.0, -2.0, 0.5);
        let d = (bc * ab * v - bc * (ab * v)).norm();
        assert!(d < 1e-14);
        assert!(((ab.inverse() * (ab * v)) - v).norm() < 1e-14);
        // The matrix form agrees, chains, and its transpose is the inverse.
        let (mab, mbc) = (ab.matrix(), bc.matrix());
        assert!((mbc * mab * v - bc * (ab * v)).norm() < 1e-14);
        assert!((mab.transpose() * (mab * v) - v).norm() < 1e-14);
    }

    #[test]
    fn wrappers_forward_bit_for_bit() {
        let (a, b) = (Vector3::new(0.1, -2.3, 4.7), Vector3::new(1e-3, 5.5, -0.7));
        let (ta, tb) = (
            Vec3::<Ned>::assume_in_frame(a),
            Vec3::<Ned>::assume_in_frame(b),
        );
        assert_eq!((0.5 * (ta + tb)).raw(), 0.5 * (a + b));
        assert_eq!((ta.cross(&tb) / 12.0).raw(), a.cross(&b) / 12.0);
        let mut s = ta;
        s += tb;
        s -= ta * 3.0;
        assert_eq!(s.raw(), a + b - a * 3.0);
        assert_eq!((s[0], s[1], s[2]), (s.x(), s.y(), s.z()));
        let q = UnitQuaternion::from_euler_angles(0.3, -0.1, 2.0);
        let r = Rotation::<Body, Ned>::assume_from_quaternion(q);
        assert_eq!((r * ta.assume_frame::<Body>()).raw(), q * a);
        assert_eq!(
            (r.matrix() * tb.assume_frame()).raw(),
            q.to_rotation_matrix().into_inner() * b
        );
        let e = r.euler_angles();
        assert!(r.angle_to(&Rotation::from_euler_angles(e.0, e.1, e.2)) < 1e-15);
        assert_eq!(
            (Rotation::<Ned, Ned>::from_rotation_vector(ta) * r).quaternion(),
            UnitQuaternion::from_scaled_axis(a) * q
        );
        assert_eq!(Rotation::<Ned, Ned>::identity() * ta, ta);
        assert_eq!(Vec3::<Body>::default(), Vec3::zeros());
    }

    #[test]
    fn wrappers_are_zero_sized_around_their_value() {
        use std::mem::size_of;
        assert_eq!(size_of::<Vec3<Ned>>(), size_of::<Vector3<f64>>());
        assert_eq!(
            size_of::<Rotation<Body, Ned>>(),
            size_of::<UnitQuaternion<f64>>()
        );
        assert_eq!(
            size_of::<RotationMatrix<Ecef, Ned>>(),
            size_of::<Matrix3<f64>>()
        );
    }
}
