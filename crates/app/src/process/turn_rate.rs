//! The gyro against the GNSS course: a unit mistake (degrees read as
//! radians, or radians as degrees) makes the gyro turn 57.3× too much or
//! too little, which nothing at rest can show.
//!
//! The evidence is a regression of the course change on the gyro's yaw
//! change over windows of about a second, not a sum of the course changes
//! between fixes: at 10 Hz the ±1° jitter of each fix's course adds up to
//! hundreds of degrees of "turning" on a straight road, and a regression
//! of the gyro on such a course is diluted towards 0 (the errors are in
//! the regressor). Here the regressor is the gyro (precise over a second),
//! the course's noise is the residual, and the log is judged only where
//! the estimate's own σ rules the unit mistake in or out.

use std::f64::consts::{PI, TAU};
use std::path::Path;

use aidnav_ins::alignment::course;
use aidnav_io::kfgins::GyroUnit;
use aidnav_io::rtklib::{GnssFix, ImuSample};
use nalgebra::Vector3;

use super::ProcessError;

/// Speed above which a course is used \[m/s\] (below it the course of a
/// receiver's velocity, or of a position difference, is noise).
pub const TURN_CHECK_MIN_SPEED_MPS: f64 = 1.0;
/// Shortest window of a course change \[s\]: long enough that the gyro's
/// yaw change outgrows the course noise in a turn, short enough that no
/// turn exceeds half a revolution.
const WINDOW_S: f64 = 1.0;
/// Longest gap between two course samples inside a window \[s\].
const MAX_GAP_S: f64 = 1.5;
/// Windows needed before a log is judged.
const MIN_WINDOWS: usize = 20;
/// σ of the fit a refusal must clear: the course-per-gyro factor's
/// interval k ± Z·σ must lie wholly outside the plausible range.
/// Neighbouring windows share a course sample and real residuals are not
/// Gaussian (a handheld's sway, multipath), hence a wide margin.
const Z: f64 = 5.0;
/// Plausible range of the course change per gyro yaw change: a handheld
/// or a loosely held sensor, lever arms, side slip and gyro scale errors
/// stay well within 5× either way; a unit mistake gives 57.3 or 1/57.3.
const PLAUSIBLE_COURSE_PER_GYRO: std::ops::RangeInclusive<f64> = 0.2..=5.0;
/// σ of a horizontal velocity without its own \[m/s\] (relative weights
/// only: the fit estimates the scale of the residuals itself).
const NOMINAL_VELOCITY_SIGMA_MPS: f64 = 0.1;

/// What the gyro and the GNSS course say about each other.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurnRateFit {
    /// Course change per gyro yaw change (1 for a right unit).
    pub course_per_gyro: f64,
    /// Its σ, from the scatter of the residuals.
    pub sigma: f64,
    /// Windows fitted (after the outliers were dropped).
    pub windows: usize,
    /// Σ |course change| over those windows \[rad\].
    pub course_turned_rad: f64,
    /// Σ |gyro yaw change| over those windows \[rad\].
    pub gyro_turned_rad: f64,
}

impl TurnRateFit {
    /// The gyro's yaw change per course change (1 / `course_per_gyro`).
    pub fn gyro_per_course(&self) -> f64 {
        1.0 / self.course_per_gyro
    }

    /// Whether the fit rules a right unit out: its interval at Z σ lies
    /// wholly above or below the plausible range.
    pub fn is_implausible(&self) -> bool {
        let (lo, hi) = (
            self.course_per_gyro - Z * self.sigma,
            self.course_per_gyro + Z * self.sigma,
        );
        lo > *PLAUSIBLE_COURSE_PER_GYRO.end() || hi < *PLAUSIBLE_COURSE_PER_GYRO.start()
    }
}

/// A course of the vehicle, with its variance \[rad²\]: at an instant
/// (from a velocity, `half_span_s` 0) or the mean over
/// `time_s ± half_span_s` (the direction between two positions).
#[derive(Debug, Clone, Copy)]
struct CourseSample {
    time_s: f64,
    half_span_s: f64,
    course_rad: f64,
    variance: f64,
}

/// Largest σ of a course from positions \[rad\]: the displacement must
/// exceed √2·σ_p / this.
const MAX_POSITION_COURSE_SIGMA_RAD: f64 = 0.2;
/// Longest span of two positions giving a course \[s\].
const MAX_POSITION_SPAN_S: f64 = 10.0;

/// The vehicle's course at every fix where it is known well enough: from
/// the fix's velocity above [`TURN_CHECK_MIN_SPEED_MPS`], else from the
/// nearest fixes around it (at least [`WINDOW_S`], at most
/// [`MAX_POSITION_SPAN_S`] apart) whose displacement outgrows their
/// position σ (a slow vehicle, or no velocity).
fn course_samples(gnss: &[GnssFix]) -> Vec<CourseSample> {
    let horizontal_sigma = |s: &Vector3<f64>| (0.5 * (s.x * s.x + s.y * s.y)).sqrt();
    let mut out = Vec::new();
    for (j, fix) in gnss.iter().enumerate() {
        if let Some(v) = fix.velocity_ned {
            let speed = v.xy().norm();
            if speed >= TURN_CHECK_MIN_SPEED_MPS && speed.is_finite() {
                let sigma_v = fix
                    .velocity_sigma_neu
                    .as_ref()
                    .map_or(NOMINAL_VELOCITY_SIGMA_MPS, horizontal_sigma);
                let sigma_c = sigma_v.max(1e-3) / speed;
                out.push(CourseSample {
                    time_s: fix.time_s,
                    half_span_s: 0.0,
                    course_rad: course(&v),
                    variance: sigma_c * sigma_c,
                });
                continue;
            }
        }
        let position_course = (1..=200).find_map(|m| {
            let (a, b) = (gnss.get(j.checked_sub(m)?)?, gnss.get(j + m)?);
            let span = b.time_s - a.time_s;
            if span > MAX_POSITION_SPAN_S {
                return Some(None);
            }
            let d = a.position.ned_to(&b.position);
            let distance = d.x().hypot(d.y());
            let sigma_p = horizontal_sigma(&a.position_sigma_neu)
                .max(horizontal_sigma(&b.position_sigma_neu));
            let sigma_c = std::f64::consts::SQRT_2 * sigma_p / distance;
            (span >= WINDOW_S && sigma_c <= MAX_POSITION_COURSE_SIGMA_RAD).then_some(Some(
                CourseSample {
                    time_s: 0.5 * (a.time_s + b.time_s),
                    half_span_s: 0.5 * span,
                    course_rad: d.y().atan2(d.x()),
                    variance: sigma_c * sigma_c,
                },
            ))
        });
        if let Some(Some(sample)) = position_course {
            out.push(sample);
        }
    }
    out
}

/// The gyro's change of the mean heading from course sample `a` to `b`
/// (each heading averaged over its sample's span, as its course is) about
/// the mean specific-force axis (vertical when the vehicle does not
/// accelerate much, whatever the mounting); None without at least three
/// IMU samples.
fn gyro_yaw(imu: &[ImuSample], a: &CourseSample, b: &CourseSample) -> Option<f64> {
    let (t0, t1) = (a.time_s - a.half_span_s, b.time_s + b.half_span_s);
    let lo = imu.partition_point(|s| s.time_s < t0);
    let hi = imu.partition_point(|s| s.time_s <= t1);
    if hi < lo + 3 {
        return None;
    }
    let up: Vector3<f64> = imu[lo..hi].iter().map(|s| s.specific_force).sum();
    let down = (-up).try_normalize(1e-9)?;
    // The heading at each sample from t0, and its mean over each span.
    let (mut heading, mut mean_a, mut n_a, mut mean_b, mut n_b) = (0.0, 0.0, 0usize, 0.0, 0usize);
    let mut previous = imu[lo.saturating_sub(1)];
    for s in &imu[lo..hi] {
        let dt = s.time_s - previous.time_s.max(t0);
        if dt > 0.0 {
            heading += previous.angular_rate.dot(&down) * dt;
        }
        previous = *s;
        if (s.time_s - a.time_s).abs() <= a.half_span_s.max(0.0) {
            mean_a += heading;
            n_a += 1;
        }
        if (s.time_s - b.time_s).abs() <= b.half_span_s.max(0.0) {
            mean_b += heading;
            n_b += 1;
        }
    }
    // An instant's heading: the sample nearest before it.
    let at = |t: f64| {
        let mut h = 0.0;
        let mut previous = imu[lo.saturating_sub(1)];
        for s in imu[lo..hi].iter().take_while(|s| s.time_s <= t) {
            let dt = s.time_s - previous.time_s.max(t0);
            if dt > 0.0 {
                h += previous.angular_rate.dot(&down) * dt;
            }
            previous = *s;
        }
        h
    };
    let mean = |sum: f64, n: usize, sample: &CourseSample| {
        if n > 0 {
            sum / n as f64
        } else {
            at(sample.time_s)
        }
    };
    Some(mean(mean_b, n_b, b) - mean(mean_a, n_a, a))
}

/// One window: course change, gyro yaw change, duration, weight.
#[derive(Debug, Clone, Copy)]
struct Window {
    course: f64,
    gyro: f64,
    duration: f64,
    weight: f64,
}

/// The windows: consecutive course samples chained into spans of at least
/// [`WINDOW_S`] (and of the samples' own spans) without a gap over
/// [`MAX_GAP_S`].
fn windows(imu: &[ImuSample], samples: &[CourseSample]) -> Vec<Window> {
    let mut out = Vec::new();
    let mut i = 0;
    while i + 1 < samples.len() {
        let a = samples[i];
        let length = WINDOW_S.max(2.0 * a.half_span_s);
        let mut j = i + 1;
        let mut broken = false;
        while j < samples.len() && samples[j].time_s - a.time_s < length {
            if samples[j].time_s - samples[j - 1].time_s > MAX_GAP_S {
                broken = true;
                break;
            }
            j += 1;
        }
        if broken || j >= samples.len() || samples[j].time_s - samples[j - 1].time_s > MAX_GAP_S {
            i = j.max(i + 1);
            continue;
        }
        let b = samples[j];
        if let Some(gyro) = gyro_yaw(imu, &a, &b) {
            let course = (b.course_rad - a.course_rad + PI).rem_euclid(TAU) - PI;
            out.push(Window {
                course,
                gyro,
                duration: b.time_s - a.time_s,
                weight: 1.0 / (a.variance + b.variance),
            });
        }
        i = j;
    }
    out
}

/// Weighted least squares of `course = k·gyro + β·duration` (β takes a
/// gyro bias) over the windows `keep` selects: (k, β, the residual
/// variance per unit weight, the (k, k) element of the normal matrix's
/// inverse).
fn fit(windows: &[Window], keep: &[bool]) -> Option<(f64, f64, f64, f64)> {
    let (mut a11, mut a12, mut a22, mut b1, mut b2, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0, 0usize);
    for (w, _) in windows.iter().zip(keep).filter(|(_, k)| **k) {
        a11 += w.weight * w.gyro * w.gyro;
        a12 += w.weight * w.gyro * w.duration;
        a22 += w.weight * w.duration * w.duration;
        b1 += w.weight * w.gyro * w.course;
        b2 += w.weight * w.duration * w.course;
        n += 1;
    }
    let det = a11 * a22 - a12 * a12;
    let determined = det > 1e-12 * a11 * a22;
    if n < MIN_WINDOWS || !determined {
        return None;
    }
    let k = (a22 * b1 - a12 * b2) / det;
    let beta = (a11 * b2 - a12 * b1) / det;
    let rss: f64 = windows
        .iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(w, _)| w.weight * (w.course - k * w.gyro - beta * w.duration).powi(2))
        .sum();
    Some((k, beta, rss / (n - 2) as f64, a22 / det))
}

/// Fit the course change to the gyro's yaw change while moving (body-frame
/// or sensor-frame IMU: the yaw is taken about the specific force); None
/// when fewer than 20 windows of a second above 1 m/s exist or they do not
/// determine the fit. Windows whose normalised residual exceeds 4 robust σ
/// of the first fit (a course wrap at low speed, a multipath jump) are
/// dropped before the second.
pub fn turn_rate_fit(imu: &[ImuSample], gnss: &[GnssFix]) -> Option<TurnRateFit> {
    let windows = windows(imu, &course_samples(gnss));
    let mut keep = vec![true; windows.len()];
    let (k, beta, _, _) = fit(&windows, &keep)?;
    let mut normalised: Vec<f64> = windows
        .iter()
        .map(|w| ((w.course - k * w.gyro - beta * w.duration) * w.weight.sqrt()).abs())
        .collect();
    let mut sorted = normalised.clone();
    sorted.sort_by(f64::total_cmp);
    let robust_sigma = 1.4826 * sorted[sorted.len() / 2];
    if robust_sigma > 0.0 {
        for (keep, u) in keep.iter_mut().zip(&mut normalised) {
            *keep = *u <= 4.0 * robust_sigma;
        }
    }
    let (k, _, variance, inverse_kk) = fit(&windows, &keep)?;
    let (mut course_turned_rad, mut gyro_turned_rad) = (0.0, 0.0);
    for (w, _) in windows.iter().zip(&keep).filter(|(_, k)| **k) {
        course_turned_rad += w.course.abs();
        gyro_turned_rad += w.gyro.abs();
    }
    Some(TurnRateFit {
        course_per_gyro: k,
        sigma: (variance * inverse_kk).sqrt(),
        windows: keep.iter().filter(|k| **k).count(),
        course_turned_rad,
        gyro_turned_rad,
    })
}

/// The gyro's turn rate against the GNSS course ([`turn_rate_fit`]): an
/// error naming the evidence and the likely unit mistake when the fit
/// rules a right unit out ([`TurnRateFit::is_implausible`]); the fit
/// otherwise (None: too little motion to judge). `declared` is the gyro
/// unit the configuration declared (`data.imu_units`, a generic CSV), so
/// the hint never asks for the unit already given.
pub fn check_turn_rate(
    imu: &[ImuSample],
    gnss: &[GnssFix],
    imu_path: &Path,
    gnss_path: &Path,
    declared: Option<GyroUnit>,
) -> Result<Option<TurnRateFit>, ProcessError> {
    let Some(fit) = turn_rate_fit(imu, gnss) else {
        return Ok(None);
    };
    if !fit.is_implausible() {
        return Ok(Some(fit));
    }
    let degrees = 180.0 / PI;
    let near_degrees = |x: f64| (0.5 * degrees..2.0 * degrees).contains(&x);
    let too_little = fit.course_per_gyro > *PLAUSIBLE_COURSE_PER_GYRO.end();
    let hint = match (too_little, declared) {
        (true, Some(GyroUnit::DegPerS)) if near_degrees(fit.course_per_gyro) => {
            "radians per second read as degrees? (the columns look like rad/s: imu_units.gyro = \"rad_s\")"
        }
        (true, None) if near_degrees(fit.course_per_gyro) => {
            "radians per second read as degrees? (a generic CSV: imu_units.gyro = \"rad_s\")"
        }
        (false, Some(GyroUnit::RadPerS)) if near_degrees(fit.gyro_per_course()) => {
            "degrees per second read as radians? (the columns look like deg/s: imu_units.gyro = \"deg_s\")"
        }
        (false, None) if near_degrees(fit.gyro_per_course()) => {
            "degrees per second read as radians? (a generic CSV: imu_units.gyro = \"deg_s\")"
        }
        _ => "a scaled gyro, or the wrong IMU file for this GNSS log?",
    };
    Err(ProcessError::Data(format!(
        "{}: the gyro turns {:.3}× the GNSS course of {} (the course {} ± {} rad per gyro radian, outside {}–{} at {Z} σ): over {} windows of {WINDOW_S} s or more while moving the course turned {:.0}° and the gyro's yaw {:.0}° — {hint} ([checks] turn_rate = \"warn\" or \"off\" to go on)",
        imu_path.display(),
        fit.gyro_per_course(),
        gnss_path.display(),
        significant(fit.course_per_gyro),
        significant(fit.sigma),
        PLAUSIBLE_COURSE_PER_GYRO.start(),
        PLAUSIBLE_COURSE_PER_GYRO.end(),
        fit.windows,
        fit.course_turned_rad.to_degrees(),
        fit.gyro_turned_rad.to_degrees()
    )))
}

/// `x` with three significant digits (0.0175, 1.00, 57.3).
fn significant(x: f64) -> String {
    let digits = if x == 0.0 || !x.is_finite() {
        0
    } else {
        (2 - x.abs().log10().floor() as i32).clamp(0, 12) as usize
    };
    format!("{x:.digits$}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_frames::earth::Geodetic;
    use rand::{RngExt, SeedableRng};
    use rand_distr::StandardNormal;

    /// 2025-07-08 19:34:18 GPST in seconds since 1970.
    const T0: f64 = 1_752_003_258.0;

    /// A vehicle at `speed` m/s whose course at `t` s is `course(t)`: a
    /// 100 Hz IMU whose yaw rate is the course rate × `gyro_scale` plus a
    /// bias, and `rate_hz` fixes whose velocity (or, without it, position)
    /// carries white noise of `sigma_v` (`sigma_p`).
    struct Drive {
        speed: f64,
        seconds: f64,
        rate_hz: f64,
        gyro_scale: f64,
        sigma_v: f64,
        sigma_p: f64,
        with_velocity: bool,
        course: fn(f64) -> f64,
        course_rate: fn(f64) -> f64,
    }

    fn drive(d: &Drive, seed: u64) -> (Vec<ImuSample>, Vec<GnssFix>) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut noise = |s: f64| s * rng.sample::<f64, _>(StandardNormal);
        let imu = (0..(d.seconds * 100.0) as usize)
            .map(|k| {
                let t = k as f64 * 0.01;
                ImuSample {
                    time_s: T0 + t,
                    specific_force: Vector3::new(0.0, 0.0, -9.8),
                    angular_rate: Vector3::new(0.0, 0.0, (d.course_rate)(t) * d.gyro_scale + 0.002),
                }
            })
            .collect();
        // The position along the path, integrated finely.
        let origin = Geodetic {
            latitude_rad: 0.6,
            longitude_rad: 0.2,
            height_m: 10.0,
        };
        let (mut north, mut east, mut t) = (0.0, 0.0, 0.0);
        let mut gnss = Vec::new();
        let step = 1.0 / d.rate_hz;
        while t < d.seconds {
            let c = (d.course)(t);
            let v = Vector3::new(d.speed * c.cos(), d.speed * c.sin(), 0.0);
            let noisy_v = v + Vector3::new(noise(d.sigma_v), noise(d.sigma_v), 0.0);
            let offset =
                aidnav_frames::Vec3::new(north + noise(d.sigma_p), east + noise(d.sigma_p), 0.0);
            gnss.push(GnssFix {
                time_s: T0 + t,
                position: origin.offset_by(&offset),
                quality: 1,
                satellites: 20,
                position_sigma_neu: Vector3::repeat(d.sigma_p.max(0.01)),
                velocity_ned: d.with_velocity.then_some(noisy_v),
                velocity_sigma_neu: d.with_velocity.then_some(Vector3::repeat(d.sigma_v)),
            });
            for _ in 0..100 {
                let c = (d.course)(t);
                north += d.speed * c.cos() * step / 100.0;
                east += d.speed * c.sin() * step / 100.0;
                t += step / 100.0;
            }
        }
        (imu, gnss)
    }

    /// Turns at 0.1 … 1.1 rad/s at 5 m/s, 4 Hz fixes with velocity. (A
    /// constant turn rate would not tell a scale from a gyro bias.)
    fn circling(gyro_scale: f64) -> Drive {
        Drive {
            speed: 5.0,
            seconds: 30.0,
            rate_hz: 4.0,
            gyro_scale,
            sigma_v: 0.05,
            sigma_p: 0.02,
            with_velocity: true,
            course: |t| 0.6 * t - 0.5 / 0.7 * (0.7 * t).cos(),
            course_rate: |t| 0.6 + 0.5 * (0.7 * t).sin(),
        }
    }

    #[test]
    fn a_gyro_in_the_wrong_unit_is_caught_by_the_gnss_course() {
        let (i, g) = (Path::new("imu.csv"), Path::new("g.pos"));
        let (imu, gnss) = drive(&circling(1.0), 1);
        let fit = check_turn_rate(&imu, &gnss, i, g, None).unwrap().unwrap();
        assert!(
            (fit.course_per_gyro - 1.0).abs() < 0.02 && fit.sigma < 0.02,
            "{fit:?}"
        );
        let (imu, gnss) = drive(&circling(180.0 / PI), 1);
        let e = check_turn_rate(&imu, &gnss, i, g, None)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("imu.csv: the gyro turns 57.")
                && e.contains("(the course 0.0175 ± 0.000")
                && e.contains("degrees per second read as radians? (a generic CSV: imu_units.gyro = \"deg_s\")")
                && e.contains("[checks] turn_rate"),
            "{e}"
        );
        let e = check_turn_rate(&imu, &gnss, i, g, Some(GyroUnit::RadPerS))
            .unwrap_err()
            .to_string();
        assert!(e.contains("the columns look like deg/s"), "{e}");
        // The other way, and the hint never asks for the unit declared.
        let (imu, gnss) = drive(&circling(PI / 180.0), 1);
        let e = check_turn_rate(&imu, &gnss, i, g, Some(GyroUnit::DegPerS))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the gyro turns 0.017")
                && e.contains("radians per second read as degrees? (the columns look like rad/s"),
            "{e}"
        );
        let e = check_turn_rate(&imu, &gnss, i, g, Some(GyroUnit::RadPerS))
            .unwrap_err()
            .to_string();
        assert!(e.contains("a scaled gyro"), "{e}");
        // Standing still: nothing to judge.
        let mut still = gnss.clone();
        let here = still[0].position;
        for f in &mut still {
            f.velocity_ned = Some(Vector3::new(0.1, 0.0, 0.0));
            f.position = here;
        }
        assert_eq!(check_turn_rate(&imu, &still, i, g, None).unwrap(), None);
    }

    /// The refused phone log's case: 10 Hz fixes on a nearly straight
    /// highway at 30 m/s, each course ±1° of jitter (σ_v 0.5 m/s). Summed
    /// between fixes, the jitter "turned" hundreds of degrees against a few
    /// of the gyro; the fit sees a course that does not determine the
    /// factor and does not judge — and a unit mistake on the same road is
    /// still caught where the road bends enough.
    #[test]
    fn course_jitter_of_fast_fixes_on_a_straight_road_refuses_nothing() {
        let (i, g) = (Path::new("imu.csv"), Path::new("g.pos"));
        let highway = |gyro_scale| Drive {
            speed: 30.0,
            seconds: 120.0,
            rate_hz: 10.0,
            gyro_scale,
            sigma_v: 0.5,
            sigma_p: 1.0,
            with_velocity: true,
            // A gentle S: ±3° of course over two minutes.
            course: |t| 0.05 * (t / 20.0).sin(),
            course_rate: |t| 0.05 / 20.0 * (t / 20.0).cos(),
        };
        for seed in 0..20 {
            let (imu, gnss) = drive(&highway(1.0), seed);
            let fit = check_turn_rate(&imu, &gnss, i, g, None);
            assert!(
                matches!(fit, Ok(Some(_)) | Ok(None)),
                "seed {seed}: {fit:?}"
            );
            // Summed between fixes, the course "turned" far more than the road.
            let jitter: f64 = gnss
                .windows(2)
                .map(|w| {
                    let (a, b) = (w[0].velocity_ned.unwrap(), w[1].velocity_ned.unwrap());
                    ((course(&b) - course(&a) + PI).rem_euclid(TAU) - PI).abs()
                })
                .sum();
            assert!(jitter.to_degrees() > 100.0, "{}", jitter.to_degrees());
        }
        // The wrong unit with the road's turns too small to tell is not
        // judged either way; with real turns it is caught.
        let mut bendy = highway(PI / 180.0);
        bendy.course = |t| 0.5 * (t / 10.0).sin();
        bendy.course_rate = |t| 0.05 * (t / 10.0).cos();
        let (imu, gnss) = drive(&bendy, 3);
        assert!(check_turn_rate(&imu, &gnss, i, g, None).is_err());
    }

    /// Without velocity the course comes from positions at least a second
    /// apart: 0.7 m position noise at 1 Hz on a 5 m/s rover.
    #[test]
    fn the_course_from_positions_judges_a_log_without_velocity() {
        let (i, g) = (Path::new("imu.csv"), Path::new("g.pos"));
        let rover = |gyro_scale| Drive {
            seconds: 120.0,
            rate_hz: 1.0,
            sigma_p: 0.7,
            with_velocity: false,
            // A slalom of ±86° every minute.
            course: |t| -1.5 * (t / 10.0).cos(),
            course_rate: |t| 0.15 * (t / 10.0).sin(),
            ..circling(gyro_scale)
        };
        let (imu, gnss) = drive(&rover(1.0), 5);
        let fit = check_turn_rate(&imu, &gnss, i, g, None).unwrap().unwrap();
        assert!(
            (fit.course_per_gyro - 1.0).abs() < 5.0 * fit.sigma,
            "{fit:?}"
        );
        let (imu, gnss) = drive(&rover(180.0 / PI), 5);
        assert!(check_turn_rate(&imu, &gnss, i, g, None).is_err());
        let (imu, gnss) = drive(&rover(PI / 180.0), 5);
        assert!(check_turn_rate(&imu, &gnss, i, g, None).is_err());
    }
}
