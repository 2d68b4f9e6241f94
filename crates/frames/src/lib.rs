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
//! Conventions: rotations are passive-free "From → To" direction cosine
//! operators (`v_to = R * v_from`), stored as unit quaternions (Hamilton
//! convention, nalgebra's). The Earth-frame conversions (WGS-84
//! geodetic/ECEF/NED, radii, normal gravity, Earth and transport rate) are in
//! [`earth`]; the launch frame of spec 10, its
//! orientation matrix D and central gravity are in [`launch`].
//!
//! ## Limitations
//! Only the frame markers below exist so far; time-varying frames (NED moving
//! with the vehicle) are not distinguished by epoch in the type.

pub mod constants;
pub mod earth;
pub mod launch;
mod typed;

pub use typed::{Body, Ecef, Launch, Ned, Rotation, RotationMatrix, Vec3};
