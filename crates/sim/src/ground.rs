//! The truth trajectory of a land vehicle on the WGS-84 ellipsoid, driven
//! from a route: a start position and heading, then segments (change speed,
//! cruise, turn at a yaw rate, stop for a while) and hills along the road.
//!
//! Kinematics (body = vehicle: x forward, y right, z down): no sideslip and
//! no vertical body velocity, so the velocity lies along body x —
//! `v_n = s (cos θ cos ψ, cos θ sin ψ, −sin θ)` for speed s, pitch θ and
//! heading ψ — and the non-holonomic constraint holds exactly. Roll is zero
//! (no road bank, no suspension motion). The pitch is the road grade, a
//! function of the distance driven.
//!
//! Smoothness: speed changes and turns are raised-cosine pulses of
//! acceleration and yaw rate (rise time [`CarRoute::accel_rise_s`],
//! [`CarRoute::yaw_rate_rise_s`]), so the acceleration, the yaw rate and
//! their first derivatives (jerk, yaw acceleration) are continuous; a hill's
//! grade is `θ_max sin³(2π ξ)` over its length (ξ ∈ [0, 1)), C² in the
//! distance, up and back to the height it started from.
//!
//! Position (latitude, longitude, height) and the distance driven are
//! integrated by fourth-order Runge–Kutta, one step per sample, from the
//! analytic speed, heading and grade; the inertial quantities of each
//! sample (specific force, angular rate) follow in closed form
//! ([`crate::truth`]).
//!
//! ```
//! use aidnav_sim::ground::{CarRoute, Segment, drive};
//! let route = CarRoute {
//!     segments: vec![
//!         Segment::Accelerate { speed_mps: 10.0, accel_mps2: 1.0 },
//!         Segment::Turn { angle_deg: 90.0, rate_deg_s: 10.0 },
//!         Segment::Stop { duration_s: 5.0, decel_mps2: 2.0 },
//!     ],
//!     hills: vec![],
//!     ..CarRoute::default()
//! };
//! let truth = drive(&route, 100.0, 0.0).unwrap();
//! let end = truth.last().unwrap();
//! assert!(end.speed_mps == 0.0);
//! let (_, _, yaw) = end.attitude.euler_angles();
//! assert!((yaw.to_degrees() - (route.start_heading_deg + 90.0)).abs() < 1e-9);
//! ```

use std::f64::consts::{PI, TAU};

use aidnav_frames::constants::STANDARD_GRAVITY_M_S2;
use aidnav_frames::earth::{Geodetic, earth_rate_ned, radii, transport_rate_ned};
use aidnav_frames::{Body, Ned, Rotation, Vec3};
use aidnav_ins::ned::gravity_ned;
use serde::{Deserialize, Serialize};

use crate::error::{SimError, check, finite, non_negative, positive};
use crate::truth::TruthSample;

/// Largest hill grade accepted \[deg\] (a 58 % road; cars manage ~ 20°).
const MAX_HILL_PITCH_DEG: f64 = 30.0;

/// One piece of a route; segments are driven one after the other.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Segment {
    /// Change speed (up or down) to `speed_mps` at a peak acceleration of
    /// magnitude `accel_mps2`, driving straight on.
    Accelerate {
        /// Speed at the end of the segment \[m/s\] (≥ 0).
        speed_mps: f64,
        /// Peak |acceleration| [m/s²] (> 0).
        accel_mps2: f64,
    },
    /// Drive straight on at the current speed (stand still if it is 0).
    Cruise {
        /// Duration \[s\] (≥ 0).
        duration_s: f64,
    },
    /// Turn by `angle_deg` (positive: to the right, clockwise seen from
    /// above) at a peak yaw rate `rate_deg_s`, at the current speed (which
    /// must not be 0).
    Turn {
        /// Heading change \[deg\] (positive right).
        angle_deg: f64,
        /// Peak |yaw rate| \[deg/s\] (> 0).
        rate_deg_s: f64,
    },
    /// Brake to standstill at a peak deceleration `decel_mps2` (if moving),
    /// then stand still for `duration_s`.
    Stop {
        /// Time at standstill \[s\] (≥ 0).
        duration_s: f64,
        /// Peak |deceleration| [m/s²] (> 0).
        decel_mps2: f64,
    },
}

/// A hill on the road, by its [`HillShape`]: a bump (the grade rises and
/// falls as `max_pitch_deg · sin³(2π ξ)` over `length_m`, ξ the fraction of
/// the hill driven; the road climbs for the first half and comes back down
/// to its starting height, peak ≈ `2/(3π) · length · max_pitch`, radians)
/// or a climb (grade `max_pitch_deg · sin²(π ξ)`: the path climbs — or,
/// for a negative grade, descends — by `length · max_pitch / 2` and levels
/// off; an aircraft's take-off climb and descent).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Hill {
    /// Distance driven from the route start to the foot of the hill \[m\].
    pub start_m: f64,
    /// Length of road over the hill \[m\] (> 0).
    pub length_m: f64,
    /// Largest grade \[deg\] (negative: a dip), |·| ≤ 30.
    pub max_pitch_deg: f64,
    /// Profile of the grade. Default `bump`.
    #[serde(default)]
    pub shape: HillShape,
}

/// Profile of a [`Hill`]'s grade over its length.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HillShape {
    /// Up and back down to the starting height: `sin³(2π ξ)`.
    #[default]
    Bump,
    /// Up (or down) and level again at the new height: `sin²(π ξ)`.
    Climb,
}

impl Hill {
    /// Pitch \[rad\] and its derivative with distance \[rad/m\] at distance
    /// `d_m` driven (0 off the hill).
    fn pitch(&self, d_m: f64) -> (f64, f64) {
        let xi = (d_m - self.start_m) / self.length_m;
        if !(0.0..1.0).contains(&xi) {
            return (0.0, 0.0);
        }
        let peak = self.max_pitch_deg.to_radians();
        match self.shape {
            HillShape::Bump => {
                let (s, c) = (TAU * xi).sin_cos();
                (
                    peak * s * s * s,
                    peak * 3.0 * s * s * c * TAU / self.length_m,
                )
            }
            HillShape::Climb => {
                let (s, c) = (PI * xi).sin_cos();
                (peak * s * s, peak * 2.0 * s * c * PI / self.length_m)
            }
        }
    }
}

/// A drive: where it starts, the segments, the hills and the smoothing of
/// the speed and heading changes. The default is a 7.5 minute urban drive
/// (see [`CarRoute::default`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CarRoute {
    /// Start latitude \[deg\]. Default 30.5 (a mid-latitude city).
    pub start_latitude_deg: f64,
    /// Start longitude \[deg\]. Default 114.3.
    pub start_longitude_deg: f64,
    /// Start ellipsoidal height \[m\]. Default 25.
    pub start_height_m: f64,
    /// Start heading, clockwise from north \[deg\]. Default 30.
    pub start_heading_deg: f64,
    /// Rise (and fall) time of each acceleration pulse \[s\] (> 0): the
    /// jerk peaks at `π/2 · accel / rise`. Default 1.
    pub accel_rise_s: f64,
    /// Rise (and fall) time of each yaw-rate pulse \[s\] (> 0). Default 1.5.
    pub yaw_rate_rise_s: f64,
    /// The segments, driven in order, from standstill.
    pub segments: Vec<Segment>,
    /// Hills, by distance driven; they must not overlap.
    pub hills: Vec<Hill>,
    /// Bank into turns as an aircraft does in a coordinated turn: roll
    /// `atan(v ψ̇ / g₀)`, so the specific force stays in the body x–z plane.
    /// Default false (a land vehicle: roll 0).
    pub bank_in_turns: bool,
    /// The oscillation of a walker's steps (pedestrian platforms); none by
    /// default.
    pub steps: Option<StepMotion>,
}

/// The periodic motion of walking, added to the route's smooth path: the
/// body bobs up and down once per step and sways in roll once per stride
/// (two steps), both in proportion to the speed up to `walking_speed_mps`
/// (no oscillation standing still).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StepMotion {
    /// Step frequency \[Hz\] (> 0). Default 1.8.
    pub frequency_hz: f64,
    /// Vertical bob amplitude at walking speed \[m\]. Default 0.03.
    pub bob_m: f64,
    /// Roll sway amplitude at walking speed \[deg\]. Default 2.
    pub sway_deg: f64,
    /// The speed of the full amplitudes \[m/s\] (> 0). Default 1.4.
    pub walking_speed_mps: f64,
}

impl Default for StepMotion {
    fn default() -> Self {
        Self {
            frequency_hz: 1.8,
            bob_m: 0.03,
            sway_deg: 2.0,
            walking_speed_mps: 1.4,
        }
    }
}

impl Default for CarRoute {
    /// An urban drive of 450 s and 6.0 km from standstill, starting
    /// heading 30° at 30.5° N, 114.3° E, 25 m: 20 s standing (alignment),
    /// 50 km/h (14 m/s) streets with three right-angle turns (at 8–11 m/s,
    /// 10–12 °/s, lateral acceleration ≤ 1.9 m/s²), a traffic-light stop of
    /// 15 s, a straight stretch of 150 s at 79 km/h (22 m/s, 3.3 km), a
    /// U-turn in two right-angle turns at 8 m/s and a final stop of 19 s;
    /// a 5.9 m hill (4°, 400 m) on the first street and a 7.4 m one (2.5°,
    /// 800 m) on the straight. Accelerations 1.1–2 m/s².
    fn default() -> Self {
        use Segment::{Accelerate, Cruise, Stop, Turn};
        Self {
            start_latitude_deg: 30.5,
            start_longitude_deg: 114.3,
            start_height_m: 25.0,
            start_heading_deg: 30.0,
            accel_rise_s: 1.0,
            yaw_rate_rise_s: 1.5,
            segments: vec![
                Cruise { duration_s: 20.0 },
                Accelerate {
                    speed_mps: 14.0,
                    accel_mps2: 2.0,
                },
                Cruise { duration_s: 30.0 },
                Accelerate {
                    speed_mps: 8.0,
                    accel_mps2: 2.0,
                },
                Turn {
                    angle_deg: 90.0,
                    rate_deg_s: 12.0,
                },
                Accelerate {
                    speed_mps: 14.0,
                    accel_mps2: 1.5,
                },
                Cruise { duration_s: 25.0 },
                Stop {
                    duration_s: 15.0,
                    decel_mps2: 2.0,
                },
                Accelerate {
                    speed_mps: 11.0,
                    accel_mps2: 1.1,
                },
                Turn {
                    angle_deg: -90.0,
                    rate_deg_s: 10.0,
                },
                Cruise { duration_s: 30.0 },
                Turn {
                    angle_deg: 90.0,
                    rate_deg_s: 10.0,
                },
                Accelerate {
                    speed_mps: 22.0,
                    accel_mps2: 1.1,
                },
                Cruise { duration_s: 150.0 },
                Accelerate {
                    speed_mps: 8.0,
                    accel_mps2: 2.0,
                },
                Turn {
                    angle_deg: 90.0,
                    rate_deg_s: 12.0,
                },
                Cruise { duration_s: 8.0 },
                Turn {
                    angle_deg: 90.0,
                    rate_deg_s: 12.0,
                },
                Accelerate {
                    speed_mps: 12.0,
                    accel_mps2: 2.0,
                },
                Cruise { duration_s: 40.0 },
                Stop {
                    duration_s: 19.0,
                    decel_mps2: 2.0,
                },
            ],
            hills: vec![
                Hill {
                    start_m: 100.0,
                    length_m: 400.0,
                    max_pitch_deg: 4.0,
                    shape: HillShape::Bump,
                },
                Hill {
                    start_m: 2500.0,
                    length_m: 800.0,
                    max_pitch_deg: 2.5,
                    shape: HillShape::Bump,
                },
            ],
            bank_in_turns: false,
            steps: None,
        }
    }
}

impl CarRoute {
    /// The start position (from the degree fields; height in metres).
    pub fn start_position(&self) -> Geodetic {
        Geodetic {
            latitude_rad: self.start_latitude_deg.to_radians(),
            longitude_rad: self.start_longitude_deg.to_radians(),
            height_m: self.start_height_m,
        }
    }
}

/// A raised-cosine pulse: rises from 0 to `peak` over `rise_s`, holds,
/// falls back over `rise_s`; `duration_s` ≥ 2 `rise_s` in all.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pulse {
    peak: f64,
    rise_s: f64,
    duration_s: f64,
}

impl Pulse {
    /// The pulse of area `area` with |peak| `peak_abs` (lower, a bump of
    /// duration 2 `rise_s`, when the area is too small to reach it).
    fn with_area(area: f64, peak_abs: f64, rise_s: f64) -> Self {
        if area.abs() >= peak_abs * rise_s {
            Self {
                peak: peak_abs.copysign(area),
                rise_s,
                duration_s: area.abs() / peak_abs + rise_s,
            }
        } else {
            Self {
                peak: area / rise_s,
                rise_s,
                duration_s: 2.0 * rise_s,
            }
        }
    }

    /// Value and integral from 0 at time `tau` into the pulse.
    fn at(&self, tau: f64) -> (f64, f64) {
        let (p, r) = (self.peak, self.rise_s);
        let hold = self.duration_s - 2.0 * r;
        if tau < r {
            let (s, c) = (PI * tau / r).sin_cos();
            (0.5 * p * (1.0 - c), 0.5 * p * (tau - r / PI * s))
        } else if tau < r + hold {
            (p, p * (0.5 * r + (tau - r)))
        } else {
            let u = (tau - r - hold).min(r);
            let (s, c) = (PI * u / r).sin_cos();
            (
                0.5 * p * (1.0 + c),
                p * (0.5 * r + hold + 0.5 * (u + r / PI * s)),
            )
        }
    }
}

/// What changes during a phase of the drive.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Change {
    /// Constant speed and heading.
    None,
    /// The acceleration is this pulse.
    Speed(Pulse),
    /// The yaw rate is this pulse.
    Heading(Pulse),
}

/// A phase of the drive: from `t0_s` for `duration_s`, starting at speed
/// `speed0_mps` and heading `heading0_rad`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Phase {
    t0_s: f64,
    duration_s: f64,
    speed0_mps: f64,
    heading0_rad: f64,
    change: Change,
}

/// Speed, acceleration, heading and yaw rate at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Motion {
    speed_mps: f64,
    accel_mps2: f64,
    heading_rad: f64,
    yaw_rate_rad_s: f64,
}

/// The route turned into timed phases, checked.
#[derive(Debug, Clone, PartialEq)]
struct Plan {
    phases: Vec<Phase>,
    hills: Vec<Hill>,
    duration_s: f64,
    start_heading_rad: f64,
    bank_in_turns: bool,
    steps: Option<StepMotion>,
}

impl Plan {
    fn new(route: &CarRoute) -> Result<Self, SimError> {
        finite("route.start_latitude_deg", route.start_latitude_deg)?;
        check(
            "route.start_latitude_deg",
            route.start_latitude_deg,
            route.start_latitude_deg.abs() < 89.0,
            "must be within ±89° (the NED mechanization is singular at the poles)",
        )?;
        finite("route.start_longitude_deg", route.start_longitude_deg)?;
        finite("route.start_height_m", route.start_height_m)?;
        finite("route.start_heading_deg", route.start_heading_deg)?;
        positive("route.accel_rise_s", route.accel_rise_s)?;
        positive("route.yaw_rate_rise_s", route.yaw_rate_rise_s)?;
        let mut phases = Vec::new();
        let (mut t, mut speed, mut heading) = (0.0, 0.0, route.start_heading_deg.to_radians());
        let mut push = |t: &mut f64, speed: f64, heading: f64, duration_s: f64, change| {
            if duration_s > 0.0 {
                phases.push(Phase {
                    t0_s: *t,
                    duration_s,
                    speed0_mps: speed,
                    heading0_rad: heading,
                    change,
                });
                *t += duration_s;
            }
        };
        for (i, seg) in route.segments.iter().enumerate() {
            let field = |name: &str| format!("route.segments[{i}].{name}");
            match *seg {
                Segment::Accelerate {
                    speed_mps,
                    accel_mps2,
                } => {
                    non_negative(field("speed_mps"), speed_mps)?;
                    positive(field("accel_mps2"), accel_mps2)?;
                    let dv = speed_mps - speed;
                    if dv != 0.0 {
                        let p = Pulse::with_area(dv, accel_mps2, route.accel_rise_s);
                        push(&mut t, speed, heading, p.duration_s, Change::Speed(p));
                    }
                    speed = speed_mps;
                }
                Segment::Cruise { duration_s } => {
                    non_negative(field("duration_s"), duration_s)?;
                    push(&mut t, speed, heading, duration_s, Change::None);
                }
                Segment::Turn {
                    angle_deg,
                    rate_deg_s,
                } => {
                    finite(field("angle_deg"), angle_deg)?;
                    positive(field("rate_deg_s"), rate_deg_s)?;
                    if angle_deg != 0.0 {
                        if speed <= 0.0 {
                            return Err(SimError::InfeasibleSegment {
                                index: i,
                                reason: "a car cannot turn at standstill (accelerate first)",
                            });
                        }
                        let p = Pulse::with_area(
                            angle_deg.to_radians(),
                            rate_deg_s.to_radians(),
                            route.yaw_rate_rise_s,
                        );
                        push(&mut t, speed, heading, p.duration_s, Change::Heading(p));
                        heading += angle_deg.to_radians();
                    }
                }
                Segment::Stop {
                    duration_s,
                    decel_mps2,
                } => {
                    non_negative(field("duration_s"), duration_s)?;
                    positive(field("decel_mps2"), decel_mps2)?;
                    if speed > 0.0 {
                        let p = Pulse::with_area(-speed, decel_mps2, route.accel_rise_s);
                        push(&mut t, speed, heading, p.duration_s, Change::Speed(p));
                        speed = 0.0;
                    }
                    push(&mut t, speed, heading, duration_s, Change::None);
                }
            }
        }
        let mut hills = route.hills.clone();
        for (i, h) in hills.iter().enumerate() {
            non_negative(format!("route.hills[{i}].start_m"), h.start_m)?;
            positive(format!("route.hills[{i}].length_m"), h.length_m)?;
            check(
                format!("route.hills[{i}].max_pitch_deg"),
                h.max_pitch_deg,
                h.max_pitch_deg.abs() <= MAX_HILL_PITCH_DEG,
                "must be within ±30°",
            )?;
        }
        hills.sort_by(|a, b| a.start_m.total_cmp(&b.start_m));
        for w in hills.windows(2) {
            check(
                "route.hills.start_m",
                w[1].start_m,
                w[1].start_m >= w[0].start_m + w[0].length_m,
                "hills must not overlap",
            )?;
        }
        if let Some(st) = &route.steps {
            positive("route.steps.frequency_hz", st.frequency_hz)?;
            positive("route.steps.walking_speed_mps", st.walking_speed_mps)?;
            check(
                "route.steps.bob_m",
                st.bob_m,
                st.bob_m.is_finite() && st.bob_m.abs() <= 1.0,
                "must be within ±1 m",
            )?;
            check(
                "route.steps.sway_deg",
                st.sway_deg,
                st.sway_deg.is_finite() && st.sway_deg.abs() <= 30.0,
                "must be within ±30°",
            )?;
        }
        Ok(Self {
            phases,
            hills,
            duration_s: t,
            start_heading_rad: route.start_heading_deg.to_radians(),
            bank_in_turns: route.bank_in_turns,
            steps: route.steps,
        })
    }

    /// Speed, acceleration, heading and yaw rate at `t_s` from the start.
    fn motion(&self, t_s: f64) -> Motion {
        let i = self
            .phases
            .partition_point(|p| p.t0_s <= t_s)
            .saturating_sub(1);
        let Some(p) = self.phases.get(i) else {
            return Motion {
                speed_mps: 0.0,
                accel_mps2: 0.0,
                heading_rad: self.start_heading_rad,
                yaw_rate_rad_s: 0.0,
            };
        };
        let tau = (t_s - p.t0_s).clamp(0.0, p.duration_s);
        let mut m = Motion {
            speed_mps: p.speed0_mps,
            accel_mps2: 0.0,
            heading_rad: p.heading0_rad,
            yaw_rate_rad_s: 0.0,
        };
        match p.change {
            Change::None => {}
            Change::Speed(pulse) => {
                let (a, dv) = pulse.at(tau);
                m.accel_mps2 = a;
                m.speed_mps = (p.speed0_mps + dv).max(0.0);
            }
            Change::Heading(pulse) => {
                let (r, dpsi) = pulse.at(tau);
                m.yaw_rate_rad_s = r;
                m.heading_rad += dpsi;
            }
        }
        m
    }

    /// Pitch \[rad\] and its derivative with distance \[rad/m\].
    fn pitch(&self, d_m: f64) -> (f64, f64) {
        let i = self
            .hills
            .partition_point(|h| h.start_m <= d_m)
            .saturating_sub(1);
        self.hills.get(i).map_or((0.0, 0.0), |h| h.pitch(d_m))
    }

    /// Roll at `t_s` \[rad\]: the coordinated-turn bank plus the step sway.
    fn roll(&self, t_s: f64) -> f64 {
        let m = self.motion(t_s);
        let bank = if self.bank_in_turns {
            (m.speed_mps * m.yaw_rate_rad_s / STANDARD_GRAVITY_M_S2).atan()
        } else {
            0.0
        };
        let sway = self.steps.map_or(0.0, |st| {
            let k = (m.speed_mps / st.walking_speed_mps).min(1.0);
            k * st.sway_deg.to_radians() * (PI * st.frequency_hz * t_s).sin()
        });
        bank + sway
    }

    /// Roll and roll rate at `t_s` \[rad, rad/s\] (the rate by a central
    /// difference of the analytic roll: its error, O(h²) of the third
    /// derivative, is below 1e-9 rad/s).
    fn roll_and_rate(&self, t_s: f64) -> (f64, f64) {
        if !self.bank_in_turns && self.steps.is_none() {
            return (0.0, 0.0);
        }
        const H: f64 = 1e-4;
        let rate = (self.roll(t_s + H) - self.roll(t_s - H)) / (2.0 * H);
        (self.roll(t_s), rate)
    }

    /// The step bob at `t_s`: height offset, its rate and acceleration
    /// \[m, m/s, m/s²\] (up positive), `k v sin(ω t)` with `k = bob / v_walk`
    /// below walking speed — the speed's second derivative (the jerk) by a
    /// central difference of the analytic acceleration.
    fn bob(&self, t_s: f64) -> (f64, f64, f64) {
        let Some(st) = self.steps else {
            return (0.0, 0.0, 0.0);
        };
        const H: f64 = 1e-4;
        let m = self.motion(t_s);
        let w = TAU * st.frequency_hz;
        let (sn, cs) = (w * t_s).sin_cos();
        if m.speed_mps >= st.walking_speed_mps {
            let a = st.bob_m;
            return (a * sn, a * w * cs, -a * w * w * sn);
        }
        let k = st.bob_m / st.walking_speed_mps;
        let jerk = (self.motion(t_s + H).accel_mps2 - self.motion(t_s - H).accel_mps2) / (2.0 * H);
        let (v, dv) = (m.speed_mps, m.accel_mps2);
        (
            k * v * sn,
            k * (dv * sn + v * w * cs),
            k * (jerk * sn + 2.0 * dv * w * cs - v * w * w * sn),
        )
    }
}

/// Position and distance driven: the integrated part of the state.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Integrated {
    latitude_rad: f64,
    longitude_rad: f64,
    height_m: f64,
    distance_m: f64,
}

impl Integrated {
    fn plus(&self, k: &[f64; 4], h: f64) -> Self {
        Self {
            latitude_rad: self.latitude_rad + h * k[0],
            longitude_rad: self.longitude_rad + h * k[1],
            height_m: self.height_m + h * k[2],
            distance_m: self.distance_m + h * k[3],
        }
    }
}

/// d/dt of (latitude, longitude, height, distance) at `t_s`.
fn rates(plan: &Plan, t_s: f64, y: &Integrated) -> [f64; 4] {
    let m = plan.motion(t_s);
    let (theta, _) = plan.pitch(y.distance_m);
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = m.heading_rad.sin_cos();
    let (rm, rn) = radii(y.latitude_rad);
    let s = m.speed_mps;
    [
        s * ct * cp / (rm + y.height_m),
        s * ct * sp / ((rn + y.height_m) * y.latitude_rad.cos()),
        s * st,
        s,
    ]
}

/// One RK4 step of `dt_s` from `t_s`.
fn rk4(plan: &Plan, t_s: f64, y: &Integrated, dt_s: f64) -> Integrated {
    let k1 = rates(plan, t_s, y);
    let k2 = rates(plan, t_s + 0.5 * dt_s, &y.plus(&k1, 0.5 * dt_s));
    let k3 = rates(plan, t_s + 0.5 * dt_s, &y.plus(&k2, 0.5 * dt_s));
    let k4 = rates(plan, t_s + dt_s, &y.plus(&k3, dt_s));
    let k: [f64; 4] = std::array::from_fn(|i| (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]) / 6.0);
    y.plus(&k, dt_s)
}

/// The truth sample at `t_s` from the start with integrated state `y`:
/// velocity, attitude and, in closed form, the specific force and angular
/// rate a perfect body-fixed IMU measures (the inverse of the NED
/// mechanization's differential equations, same gravity model):
///
/// - `f_b = C_nb (v̇_n − g_n + (2 ω_ie + ω_en) × v_n)`,
/// - `ω_ib = ω_nb + C_nb (ω_ie + ω_en)`, with the body rate of the Euler
///   angles (roll φ, pitch θ, yaw ψ)
///   `ω_nb = (φ̇ − ψ̇ sin θ, θ̇ cos φ + ψ̇ cos θ sin φ, −θ̇ sin φ + ψ̇ cos θ cos φ)`.
///
/// The step bob (if any) adds to the height, the down velocity and the
/// down acceleration; the roll (bank, sway) turns the body about its
/// velocity, which stays along body x on the smooth path.
fn sample(plan: &Plan, t_s: f64, y: &Integrated, start_time_s: f64) -> TruthSample {
    let m = plan.motion(t_s);
    let (theta, dtheta_dd) = plan.pitch(y.distance_m);
    let (phi, phi_rate) = plan.roll_and_rate(t_s);
    let (bob, bob_rate, bob_accel) = plan.bob(t_s);
    let s = m.speed_mps;
    let theta_rate = dtheta_dd * s;
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = m.heading_rad.sin_cos();
    let u = Vec3::<Ned>::new(ct * cp, ct * sp, -st);
    let du_dtheta = Vec3::<Ned>::new(-st * cp, -st * sp, -ct);
    let du_dpsi = Vec3::<Ned>::new(-ct * sp, ct * cp, 0.0);
    let down = Vec3::<Ned>::new(0.0, 0.0, 1.0);
    let velocity = s * u - bob_rate * down;
    let accel_ned = m.accel_mps2 * u + s * (theta_rate * du_dtheta + m.yaw_rate_rad_s * du_dpsi)
        - bob_accel * down;
    let position = Geodetic {
        latitude_rad: y.latitude_rad,
        longitude_rad: y.longitude_rad,
        height_m: y.height_m + bob,
    };
    let attitude = Rotation::<Body, Ned>::from_euler_angles(phi, theta, m.heading_rad);
    let c_nb = attitude.inverse();
    let w_ie = earth_rate_ned(position.latitude_rad);
    let w_en = transport_rate_ned(&position, &velocity);
    let f_ned = accel_ned - gravity_ned(&position) + (2.0 * w_ie + w_en).cross(&velocity);
    let (sf, cf) = phi.sin_cos();
    let psi_rate = m.yaw_rate_rad_s;
    let w_nb = Vec3::<Body>::new(
        phi_rate - psi_rate * st,
        theta_rate * cf + psi_rate * ct * sf,
        -theta_rate * sf + psi_rate * ct * cf,
    );
    TruthSample {
        time_s: start_time_s + t_s,
        position,
        velocity_ned: velocity,
        attitude,
        angular_rate_body: w_nb + c_nb * (w_ie + w_en),
        specific_force_body: c_nb * f_ned,
        speed_mps: s,
        distance_m: y.distance_m,
    }
}

/// Drive `route`, sampled at `rate_hz` \[Hz\] from GPST `start_time_s`
/// \[s since 1970\]: one [`TruthSample`] at each `start_time_s + k / rate_hz`
/// for k = 0 … ⌊duration · rate⌋, the IMU's sample times.
pub fn drive(
    route: &CarRoute,
    rate_hz: f64,
    start_time_s: f64,
) -> Result<Vec<TruthSample>, SimError> {
    positive("imu.rate_hz", rate_hz)?;
    finite("start_time_s", start_time_s)?;
    let plan = Plan::new(route)?;
    let dt = 1.0 / rate_hz;
    let steps = (plan.duration_s * rate_hz + 1e-9).floor() as usize;
    let start = route.start_position();
    let mut y = Integrated {
        latitude_rad: start.latitude_rad,
        longitude_rad: start.longitude_rad,
        height_m: start.height_m,
        distance_m: 0.0,
    };
    let mut out = Vec::with_capacity(steps + 1);
    for k in 0..=steps {
        let t = k as f64 * dt;
        out.push(sample(&plan, t, &y, start_time_s));
        if k < steps {
            y = rk4(&plan, t, &y, dt);
        }
    }
    Ok(out)
}

/// Duration of `route` \[s\] (the time of its last sample from the start,
/// up to the sampling).
pub fn route_duration_s(route: &CarRoute) -> Result<f64, SimError> {
    Ok(Plan::new(route)?.duration_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pulse_integral_matches_its_value() {
        for p in [
            Pulse::with_area(5.0, 1.5, 1.0),
            Pulse::with_area(-0.3, 1.5, 1.0),
        ] {
            let n = 100_000;
            let h = p.duration_s / n as f64;
            let mut sum = 0.0;
            for k in 0..n {
                sum += p.at((k as f64 + 0.5) * h).0 * h;
            }
            let (end_value, end_area) = p.at(p.duration_s);
            assert!(end_value.abs() < 1e-12);
            assert!((sum - end_area).abs() < 1e-8, "{sum} {end_area}");
        }
        assert!((Pulse::with_area(5.0, 1.5, 1.0).at(10.0).1 - 5.0).abs() < 1e-12);
        assert!((Pulse::with_area(-0.3, 1.5, 1.0).at(2.0).1 + 0.3).abs() < 1e-12);
    }

    #[test]
    fn bad_routes_are_errors() {
        let turn_at_rest = CarRoute {
            segments: vec![Segment::Turn {
                angle_deg: 90.0,
                rate_deg_s: 10.0,
            }],
            ..CarRoute::default()
        };
        assert!(matches!(
            drive(&turn_at_rest, 100.0, 0.0),
            Err(SimError::InfeasibleSegment { index: 0, .. })
        ));
        let negative_accel = CarRoute {
            segments: vec![Segment::Accelerate {
                speed_mps: 5.0,
                accel_mps2: -1.0,
            }],
            ..CarRoute::default()
        };
        let err = drive(&negative_accel, 100.0, 0.0).unwrap_err();
        assert!(
            err.to_string().contains("route.segments[0].accel_mps2"),
            "{err}"
        );
        let overlapping = CarRoute {
            hills: vec![
                Hill {
                    start_m: 0.0,
                    length_m: 100.0,
                    max_pitch_deg: 2.0,
                    shape: HillShape::Bump,
                },
                Hill {
                    start_m: 50.0,
                    length_m: 100.0,
                    max_pitch_deg: 2.0,
                    shape: HillShape::Bump,
                },
            ],
            ..CarRoute::default()
        };
        assert!(drive(&overlapping, 100.0, 0.0).is_err());
        assert!(drive(&CarRoute::default(), f64::NAN, 0.0).is_err());
    }
}
