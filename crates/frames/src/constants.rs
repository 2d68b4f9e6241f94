//! Named physical constants, each with its reference.

/// WGS-84 semi-major axis \[m\] (NIMA TR8350.2, Table 3.1).
pub const WGS84_A_M: f64 = 6_378_137.0;
/// WGS-84 flattening (NIMA TR8350.2, Table 3.1).
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// Earth rotation rate [rad/s] (NIMA TR8350.2, Table 3.1).
pub const OMEGA_IE_RAD_S: f64 = 7.292_115e-5;
/// Earth gravitational constant GM [m³/s²] (WGS-84; spec 10 uses the same value).
pub const GM_M3_S2: f64 = 3.986_004_418e14;
/// Mean Earth radius \[m\] used by the launch-frame model of spec 10.
pub const EARTH_MEAN_RADIUS_M: f64 = 6_371_000.0;
/// Standard gravity [m/s²] (CGPM 1901), the unit of "g" in specifications.
pub const STANDARD_GRAVITY_M_S2: f64 = 9.806_65;
