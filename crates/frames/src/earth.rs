//! The WGS-84 Earth of spec 40: geodetic ↔ ECEF ↔ local NED, meridian and
//! transverse radii of curvature, normal gravity with height, Earth rate and
//! transport rate in NED.
//!
//! ```
//! use aidnav_frames::earth::{Geodetic, normal_gravity};
//! let p = Geodetic { latitude_rad: 30f64.to_radians(), longitude_rad: 114f64.to_radians(), height_m: 20.0 };
//! let back = Geodetic::from_ecef(&p.to_ecef()); // through a `Vec3<Ecef>`
//! assert!((back.latitude_rad - p.latitude_rad).abs() < 1e-12);
//! assert!((back.height_m - 20.0).abs() < 1e-6);
//! // NED offsets are `Vec3<Ned>`: 10 m north, 2 m up.
//! let q = p.offset_by(&aidnav_frames::Vec3::new(10.0, 0.0, -2.0));
//! assert!((p.ned_to(&q).x() - 10.0).abs() < 1e-4);
//! // Normal gravity at the equator on the ellipsoid.
//! assert!((normal_gravity(0.0, 0.0) - 9.7803253359).abs() < 1e-9);
//! ```

use nalgebra::Matrix3;

use crate::constants::{GM_M3_S2, OMEGA_IE_RAD_S, WGS84_A_M, WGS84_F};
use crate::{Ecef, Ned, RotationMatrix, Vec3};

/// First eccentricity squared e² = f (2 − f).
pub const WGS84_E2: f64 = WGS84_F * (2.0 - WGS84_F);
/// Semi-minor axis b = a (1 − f) \[m\].
pub const WGS84_B_M: f64 = WGS84_A_M * (1.0 - WGS84_F);
/// Normal gravity at the equator γ_e [m/s²].
pub const GAMMA_EQUATOR: f64 = 9.780_325_335_9;
/// Somigliana's constant k = (b γ_p − a γ_e) / (a γ_e).
pub const SOMIGLIANA_K: f64 = 0.001_931_852_652_41;

/// Geodetic position on WGS-84.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Geodetic {
    /// Latitude φ \[rad\].
    pub latitude_rad: f64,
    /// Longitude λ \[rad\].
    pub longitude_rad: f64,
    /// Height above the ellipsoid h \[m\].
    pub height_m: f64,
}

/// Meridian (north–south) and transverse (east–west, prime vertical) radii
/// of curvature (R_M, R_N) at latitude φ \[m\].
pub fn radii(latitude_rad: f64) -> (f64, f64) {
    let s2 = latitude_rad.sin().powi(2);
    let w = (1.0 - WGS84_E2 * s2).sqrt();
    (WGS84_A_M * (1.0 - WGS84_E2) / (w * w * w), WGS84_A_M / w)
}

/// Normal gravity (Somigliana) at latitude φ and ellipsoidal height h,
/// with the second-order free-air correction [m/s²].
pub fn normal_gravity(latitude_rad: f64, height_m: f64) -> f64 {
    let s2 = latitude_rad.sin().powi(2);
    let g0 = GAMMA_EQUATOR * (1.0 + SOMIGLIANA_K * s2) / (1.0 - WGS84_E2 * s2).sqrt();
    let m = OMEGA_IE_RAD_S.powi(2) * WGS84_A_M.powi(2) * WGS84_B_M / GM_M3_S2;
    let a = WGS84_A_M;
    g0 * (1.0 - 2.0 / a * (1.0 + WGS84_F + m - 2.0 * WGS84_F * s2) * height_m
        + 3.0 * height_m * height_m / (a * a))
}

/// Earth rate ω_ie in NED at latitude φ \[rad/s\].
#[inline]
pub fn earth_rate_ned(latitude_rad: f64) -> Vec3<Ned> {
    Vec3::new(
        OMEGA_IE_RAD_S * latitude_rad.cos(),
        0.0,
        -OMEGA_IE_RAD_S * latitude_rad.sin(),
    )
}

/// Transport rate ω_en in NED for NED velocity v at position p \[rad/s\].
#[inline]
pub fn transport_rate_ned(p: &Geodetic, v: &Vec3<Ned>) -> Vec3<Ned> {
    let (rm, rn) = radii(p.latitude_rad);
    let (rmh, rnh) = (rm + p.height_m, rn + p.height_m);
    Vec3::new(
        v.y() / rnh,
        -v.x() / rmh,
        -v.y() * p.latitude_rad.tan() / rnh,
    )
}

impl Geodetic {
    /// Earth-centred, Earth-fixed coordinates \[m\].
    pub fn to_ecef(&self) -> Vec3<Ecef> {
        let (_, rn) = radii(self.latitude_rad);
        let (sp, cp) = self.latitude_rad.sin_cos();
        let (sl, cl) = self.longitude_rad.sin_cos();
        Vec3::new(
            (rn + self.height_m) * cp * cl,
            (rn + self.height_m) * cp * sl,
            (rn * (1.0 - WGS84_E2) + self.height_m) * sp,
        )
    }

    /// Geodetic coordinates of an ECEF point (iterated to 1e-12 rad; 10
    /// iterations at most, plenty anywhere above the Earth's centre region).
    pub fn from_ecef(r: &Vec3<Ecef>) -> Self {
        let r = r.as_raw();
        let p = r.x.hypot(r.y);
        let longitude_rad = r.y.atan2(r.x);
        let mut lat = r.z.atan2(p * (1.0 - WGS84_E2));
        let mut h = 0.0;
        for _ in 0..10 {
            let (_, rn) = radii(lat);
            let (s, c) = lat.sin_cos();
            // Stable at every latitude (no division by cos φ near the poles).
            h = p * c + (r.z + WGS84_E2 * rn * s) * s - rn;
            let next = r.z.atan2(p * (1.0 - WGS84_E2 * rn / (rn + h)));
            let done = (next - lat).abs() < 1e-12;
            lat = next;
            if done {
                break;
            }
        }
        Self {
            latitude_rad: lat,
            longitude_rad,
            height_m: h,
        }
    }

    /// Rotation ECEF → NED at this position (`v_ned = C v_ecef`).
    pub fn ecef_to_ned(&self) -> RotationMatrix<Ecef, Ned> {
        let (sp, cp) = self.latitude_rad.sin_cos();
        let (sl, cl) = self.longitude_rad.sin_cos();
        RotationMatrix::assume_from_matrix(Matrix3::new(
            -sp * cl,
            -sp * sl,
            cp,
            -sl,
            cl,
            0.0,
            -cp * cl,
            -cp * sl,
            -sp,
        ))
    }

    /// NED offset of `other` from this position (through ECEF; exact).
    pub fn ned_to(&self, other: &Geodetic) -> Vec3<Ned> {
        self.ecef_to_ned() * (other.to_ecef() - self.to_ecef())
    }

    /// The position a small NED offset away (first order in the offset,
    /// exact radii at this latitude): what a lever arm or a filter
    /// correction needs.
    pub fn offset_by(&self, ned: &Vec3<Ned>) -> Self {
        let (rm, rn) = radii(self.latitude_rad);
        Self {
            latitude_rad: self.latitude_rad + ned.x() / (rm + self.height_m),
            longitude_rad: self.longitude_rad
                + ned.y() / ((rn + self.height_m) * self.latitude_rad.cos()),
            height_m: self.height_m - ned.z(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ecef_round_trips_everywhere() {
        for lat in [-89.9, -60.0, -12.3, 0.0, 0.001, 37.5, 80.0, 89.99] {
            for lon in [-179.0, -45.0, 0.0, 114.3] {
                for h in [-400.0, 0.0, 95.0, 12_000.0, 400_000.0] {
                    let p = Geodetic {
                        latitude_rad: f64::to_radians(lat),
                        longitude_rad: f64::to_radians(lon),
                        height_m: h,
                    };
                    let q = Geodetic::from_ecef(&p.to_ecef());
                    assert!(
                        (q.latitude_rad - p.latitude_rad).abs() < 1e-11,
                        "{lat} {lon} {h}"
                    );
                    assert!((q.longitude_rad - p.longitude_rad).abs() < 1e-12);
                    assert!(
                        (q.height_m - h).abs() < 1e-5,
                        "{lat} {lon} {h}: {}",
                        q.height_m
                    );
                }
            }
        }
    }

    #[test]
    fn known_values() {
        // Equator, prime meridian: ECEF (a, 0, 0); radii a(1 − e²) and a.
        let p = Geodetic::default();
        assert!((p.to_ecef() - Vec3::new(WGS84_A_M, 0.0, 0.0)).norm() < 1e-6);
        let (rm, rn) = radii(0.0);
        assert!((rm - 6_335_439.327).abs() < 1e-3 && (rn - WGS84_A_M).abs() < 1e-6);
        // Normal gravity at the pole: γ_p = 9.8321849378.
        assert!((normal_gravity(std::f64::consts::FRAC_PI_2, 0.0) - 9.832_184_937_8).abs() < 1e-8);
        // Free-air gradient ≈ −3.086e-6 s⁻² at mid latitude.
        let lat = 45f64.to_radians();
        let grad = normal_gravity(lat, 1000.0) - normal_gravity(lat, 0.0);
        assert!((grad / 1000.0 + 3.086e-6).abs() < 0.01e-6, "{grad}");
        // NED is a rotation and points north/east/down.
        let q = Geodetic {
            latitude_rad: lat,
            longitude_rad: 0.3,
            height_m: 0.0,
        };
        let c = q.ecef_to_ned().raw();
        assert!((c * c.transpose() - Matrix3::identity()).norm() < 1e-15);
        let up = q.ecef_to_ned().transpose() * Vec3::new(0.0, 0.0, -1.0);
        let higher = Geodetic { height_m: 1.0, ..q };
        assert!((higher.to_ecef() - q.to_ecef() - up).norm() < 1e-9);
    }

    #[test]
    fn small_offsets_agree_with_the_exact_ned_difference() {
        let p = Geodetic {
            latitude_rad: 0.8,
            longitude_rad: -1.2,
            height_m: 250.0,
        };
        let d = Vec3::new(30.0, -20.0, 5.0);
        let q = p.offset_by(&d);
        assert!((p.ned_to(&q) - d).norm() < 1e-3);
    }
}
