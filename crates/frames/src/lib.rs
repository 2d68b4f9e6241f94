//! # aidnav-frames — frames, Earth constants, frame-typed vectors
//!
//! Vectors and rotations carry their frame in the type, so adding a NED
//! vector to a body vector, or applying a body→NED rotation to a launch-frame
//! vector, does not compile:
//!
//! ```compile_fail
//! use aidnav_frames::{Vec3, Ned, Body};
//! let a = Vec3::<Ned>::new(1.0, 0.0, 0.0);
//! let b = Vec3::<Body>::new(0.0, 1.0, 0.0);
//! let _ = a + b; // error: no `Add<Vec3<Body>>` for `Vec3<Ned>`
//! ```
//!
//! ```
//! use aidnav_frames::{Vec3, Rotation, Ned, Body};
//! use nalgebra::UnitQuaternion;
//! // Body → NED for a 90° yaw: the body x axis points east.
//! let c_nb = Rotation::<Body, Ned>::assume_from_quaternion(
//!     UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2));
//! let v_n = c_nb * Vec3::<Body>::new(1.0, 0.0, 0.0);
//! assert!((v_n.raw().y - 1.0).abs() < 1e-15);
//! // The inverse swaps the ends.
//! let back = c_nb.inverse() * v_n;
//! assert!((back.raw().x - 1.0).abs() < 1e-15);
//! ```
//!
//! Nor does applying a body → NED rotation to a NED vector:
//!
//! ```compile_fail
//! use aidnav_frames::{Vec3, Rotation, Ned, Body};
//! let c_nb = Rotation::<Body, Ned>::from_euler_angles(0.0, 0.0, 1.0);
//! let _ = c_nb * Vec3::<Ned>::new(1.0, 0.0, 0.0); // expects a `Vec3<Body>`
//! ```
//!
//! Conventions: rotations are passive-free "From → To" direction cosine
//! operators (`v_to = R * v_from`), stored as unit quaternions (Hamilton
//! convention, nalgebra's) in [`Rotation`], or as the direction cosine
//! matrix in [`RotationMatrix`] where a matrix product is what the
//! algebra (and the numbers) need. Rotations chain only where the frames
//! meet (`Rotation<B, C> * Rotation<A, B>`); `inverse()` / `transpose()`
//! swap the ends. A raw nalgebra value enters a frame only through a
//! constructor named `assume_…` and leaves it through `raw()` /
//! `quaternion()`; every wrapper is `Copy`, zero-sized around its value and
//! forwards to the same nalgebra operation (no cost, same rounding).
//!
//! Where frames meet in aidnav: the WGS-84 conversions of [`earth`] return
//! `Vec3<Ecef>` (`to_ecef`), `Vec3<Ned>` (`ned_to`, Earth and transport
//! rate), `RotationMatrix<Ecef, Ned>` (`ecef_to_ned`) and take a `Vec3<Ned>`
//! offset (`offset_by`); the NED mechanization and filter (`aidnav-ins`,
//! `aidnav-integration`) hold velocity as `Vec3<Ned>`, attitude as
//! `Rotation<Body, Ned>`, IMU increments and the lever arm as `Vec3<Body>`.
//! The launch frame of spec 10, its orientation matrix D and central gravity
//! are in [`launch`].
//!
//! ## Limitations
//! Only the frame markers below exist so far; time-varying frames (NED moving
//! with the vehicle) are not distinguished by epoch in the type: the turn of
//! the navigation frame over a step is a `Rotation<Ned, Ned>`. The spec 10
//! launch frame, the flat-Earth local-level INS and the error-state
//! Jacobians still use raw nalgebra values; the NED filter's instrument
//! corrections (biases, scale factors) are raw per-axis vectors.

pub mod constants;
pub mod earth;
pub mod launch;
mod typed;

pub use typed::{Body, Ecef, Launch, Ned, Rotation, RotationMatrix, Vec3};
