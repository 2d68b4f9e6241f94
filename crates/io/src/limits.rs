//! Physical bounds the readers check each value against, so that a value no
//! sensor or place on Earth can produce (usually a unit mistake) is refused
//! with the file, line and column rather than surfacing later as a filter
//! failure. Each bound states its reason.

/// Largest angular rate accepted \[rad/s\] (≈ 2 900 °/s): above the measuring
/// range of consumer and tactical MEMS gyros (typically ≤ 2 000 °/s), so a
/// larger value is a unit mistake (degrees for radians, milli-degrees…).
pub const MAX_ANGULAR_RATE_RAD_S: f64 = 50.0;

/// Largest specific force accepted \[m/s²\] (≈ 200 g): beyond the range of
/// navigation accelerometers (≤ 200 g even for high-g parts).
pub const MAX_SPECIFIC_FORCE_M_S2: f64 = 2_000.0;

/// Range of the median specific-force magnitude of a log \[m/s²\] (½ g to
/// 2 g): a vehicle on Earth reads about 1 g on average; a median near 1 means
/// the accelerometer is in g, not m/s².
pub const MEDIAN_SPECIFIC_FORCE_M_S2: std::ops::RangeInclusive<f64> = 4.9..=19.6;

/// Largest latitude magnitude \[deg\]: the poles.
pub const MAX_LATITUDE_DEG: f64 = 90.0;

/// Largest longitude magnitude \[deg\]: ±180° or 0–360° conventions.
pub const MAX_LONGITUDE_DEG: f64 = 360.0;

/// Lowest height accepted \[m\]: below the deepest dry land and mines
/// (Dead Sea shore ≈ −430 m, geoid undulation ≥ −110 m).
pub const MIN_HEIGHT_M: f64 = -1_000.0;

/// Highest height accepted \[m\]: aircraft and balloons stay below 100 km (the
/// Kármán line); above that a GNSS-aided INS of this kind does not apply.
pub const MAX_HEIGHT_M: f64 = 100_000.0;

/// Largest speed accepted \[m/s\]: civil receivers stop reporting above
/// the COCOM limit of 515 m/s, and the fastest crewed aircraft (SR-71,
/// ≈ 980 m/s) stays below 1 km/s; a larger value is a unit mistake (km/h,
/// knots ×1000, mm/s).
pub const MAX_SPEED_M_S: f64 = 1_000.0;

/// Largest wheel (odometer) speed magnitude accepted \[m/s\] (612 km/h):
/// above the fastest wheeled vehicles an odometer-aided INS rides on — the
/// rail speed record (TGV, 574.8 km/h ≈ 160 m/s, 2007) and production cars
/// (≈ 140 m/s); a larger value is a unit mistake (mm/s, or a wheel's
/// angular rate in rpm).
pub const MAX_WHEEL_SPEED_M_S: f64 = 170.0;

/// The message for a value outside `[lo, hi]`, or `None` when inside.
pub(crate) fn outside(value: f64, lo: f64, hi: f64, unit: &str, why: &str) -> Option<String> {
    use crate::text::num;
    (!(lo..=hi).contains(&value)).then(|| {
        format!(
            "{} {unit} is outside [{}, {}] {unit} ({why})",
            num(value),
            num(lo),
            num(hi)
        )
    })
}
