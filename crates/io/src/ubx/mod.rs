//! u-blox UBX binary logs: the receiver's own navigation solution,
//! `UBX-NAV-PVT` (class 0x01, id 0x07), one [`GnssFix`] per epoch.
//!
//! Framing ([`frame`]): `0xB5 0x62`, class, id, little-endian u16 length,
//! payload, 8-bit Fletcher checksum over class … payload. Frames of other
//! messages (raw measurements, subframes, …) and bytes outside frames (a
//! receiver often interleaves NMEA) are skipped and counted; a frame with a
//! bad checksum, or cut short by the end of the file, is counted and the
//! scan resynchronises at the next sync pair. The scan is linear in the
//! file size and keeps no per-frame record beyond the decoded epochs, so no
//! input can make it loop or grow without bound.
//!
//! NAV-PVT (92-byte payload of u-blox 8/9/10; the 84-byte one of u-blox 7 is
//! read too) → [`GnssFix`]:
//! - **epochs kept**: `gnssFixOK` (flags bit 0) set, fixType 2-D, 3-D or
//!   GNSS + dead reckoning (2, 3, 4), and `invalidLlh` (flags3 bit 0) clear;
//!   the others (no fix, dead reckoning only, time only) are skipped and
//!   counted;
//! - **time**: GPST seconds since 1970 = GPS week start + `iTOW`. The GPS
//!   week is not in the message; it comes from the message's UTC date and
//!   time (when `validDate` and `validTime` are set): GPST ≈ UTC + the leap
//!   seconds of that date ([`crate::text::gps_minus_utc_s`]), and the week is
//!   the integer `w` that puts `week_start(w) + iTOW` nearest to it. Rounding
//!   to the nearest week rather than truncating makes the week boundary safe
//!   (at Saturday/Sunday midnight the UTC fields and `iTOW` may sit on
//!   either side of it by a fraction of a second) and tolerates a receiver
//!   whose UTC is off by whole seconds (leap seconds not yet known) by up to
//!   half a week. Epochs without a valid UTC date take the week from the
//!   nearest epoch that has one (the week that keeps the two `iTOW`s within
//!   half a week) and are counted in a warning; a log without any valid
//!   date is an error. `iTOW` (whole milliseconds) is the navigation
//!   epoch's tag, shared by every NAV message of that epoch; UTC + `nano`
//!   states the epoch's time to the receiver's time accuracy and lies
//!   0.42–0.46 ms before `iTOW` on the rtklibexplorer walk (the receiver's
//!   clock offset) — under 1 cm of travel at 20 m/s, so `iTOW` is used and
//!   the fixes fall on the receiver's regular epoch grid;
//! - **position**: `lat`, `lon` (1e-7°) and the **ellipsoidal** height
//!   (`height`, mm above the WGS-84 ellipsoid) — the height the NED
//!   mechanization and its gravity model are defined in, and what the NMEA
//!   reader gives (altitude + geoid separation). The height above mean sea
//!   level (`hMSL`) is kept beside it in [`NavPvt::height_msl_m`], and
//!   [`NavPvt::msl_fix`] gives the fix with it: that is what an RTKLIB
//!   `.pos` converted from NAV-PVT by rtklibexplorer's script carries (the
//!   data set's `gnss_*_sf.pos`), which `aidnav process` reads "as written".
//!   Mixing the two in one run would shift the height by the geoid
//!   undulation (−21.4 m on the walk); within one run the choice only moves
//!   the gravity model by 0.3 mGal per metre, far below a MEMS
//!   accelerometer's bias;
//! - **quality** as RTKLIB's Q: carrSoln 2 (RTK fixed) → 1, carrSoln 1 (RTK
//!   float) → 2, else `diffSoln` (DGNSS) → 4, else single → 5;
//! - **σ** north, east, up: `hAcc`/√2, `hAcc`/√2, `vAcc` (hAcc read as the
//!   horizontal RMS, shared equally between north and east, as the data set's
//!   conversion to `.pos` does);
//! - **velocity** `velN, velE, velD` (mm/s) with σ `sAcc`/√2 on each axis
//!   (the same conversion's choice, so a `.pos` made from the log and the
//!   log itself give the filter the same input).
//!
//! Errors name the file, the byte offset of the frame and the field: a
//! latitude beyond ±90°, a height outside the bounds of [`crate::limits`],
//! a geoid separation beyond ±200 m, a speed beyond
//! [`crate::limits::MAX_SPEED_M_S`], an accuracy of 0 (no σ to weight the
//! fix with), time going backwards; a file without any usable NAV-PVT is an
//! error saying which messages it holds. A repeated epoch (same `iTOW`) is
//! skipped and counted.
//!
//! The RTKLIB time-tag file that `str2str`/`rtkrcv` write beside a log
//! (`.ubx.tag`: header with the start time in GPST, then one (ms since the
//! start, file position after the write) record per chunk received, made
//! for replaying the log in real time) is not needed: the receiver's own
//! `iTOW` times each fix. It does tell when each fix *arrived* at the
//! logging computer, the clock that also time-tags the IMU:
//! [`arrival_latencies_s`].

pub mod frame;

use std::collections::BTreeMap;
use std::path::Path;

use aidnav_frames::earth::Geodetic;
use nalgebra::Vector3;

use crate::error::{IoError, Result};
use crate::rtklib::{GnssFix, TimeTags};
use crate::text::{GPS_EPOCH_1970_S, WEEK_S, days_from_civil, gps_minus_utc_s};

/// NAV-PVT's class and id.
pub const NAV_PVT: (u8, u8) = (0x01, 0x07);
/// Payload length of NAV-PVT from u-blox 8 on.
pub const NAV_PVT_LEN: usize = 92;
/// Payload length of u-blox 7's NAV-PVT (the fields read here are at the
/// same offsets).
pub const NAV_PVT_LEN_V7: usize = 84;

/// Largest geoid undulation magnitude accepted \[m\]: EGM2008 spans about
/// −107 m (Indian Ocean) to +86 m (New Guinea); 200 m leaves room for any
/// receiver's coarser model.
const MAX_GEOID_SEPARATION_M: f64 = 200.0;

/// Milliseconds in a GPS week.
const WEEK_MS: i64 = 604_800_000;

/// One decoded NAV-PVT epoch: the fix and what a [`GnssFix`] does not carry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavPvt {
    /// Byte offset of the frame's first sync byte.
    pub offset: usize,
    /// Byte offset just after the frame (its last checksum byte + 1).
    pub end: usize,
    /// GPS time of week \[ms\].
    pub itow_ms: u32,
    /// GPS week (derived, see the module docs).
    pub week: u32,
    /// fixType (2 2-D, 3 3-D, 4 GNSS + dead reckoning).
    pub fix_type: u8,
    /// The flags byte (gnssFixOK bit 0, diffSoln bit 1, carrSoln bits 6–7).
    pub flags: u8,
    /// The fix, ellipsoidal height.
    pub fix: GnssFix,
    /// Height above mean sea level (`hMSL`) \[m\].
    pub height_msl_m: f64,
}

impl NavPvt {
    /// Ellipsoidal height − height above mean sea level \[m\]: the geoid
    /// undulation of the receiver's model.
    pub fn geoid_separation_m(&self) -> f64 {
        self.fix.position.height_m - self.height_msl_m
    }

    /// The fix with the height above mean sea level instead of the
    /// ellipsoidal one (as an RTKLIB `.pos` converted from NAV-PVT with
    /// `hMSL` has it).
    pub fn msl_fix(&self) -> GnssFix {
        let mut fix = self.fix;
        fix.position.height_m = self.height_msl_m;
        fix
    }
}

/// Read a UBX log: one fix per usable NAV-PVT epoch (ellipsoidal heights)
/// and the warnings (counts of what was skipped).
///
/// ```
/// use aidnav_io::ubx::{frame::encode, read_ubx_from};
/// // A NAV-PVT payload: 2025-08-28 17:30:21 UTC, iTOW 408 639 750 ms, RTK
/// // fixed, 40.0966916° N 105.1471665° W, 1580.048 m above the ellipsoid.
/// let mut p = vec![0u8; 92];
/// p[0..4].copy_from_slice(&408_639_750u32.to_le_bytes());
/// p[4..6].copy_from_slice(&2025u16.to_le_bytes());
/// p[6..11].copy_from_slice(&[8, 28, 17, 30, 21]);
/// p[11] = 0x07; // validDate, validTime, fullyResolved
/// p[20] = 3; // 3-D fix
/// p[21] = 0x83; // gnssFixOK, diffSoln, carrSoln = 2 (fixed)
/// p[23] = 25;
/// p[24..28].copy_from_slice(&(-1_051_471_665i32).to_le_bytes());
/// p[28..32].copy_from_slice(&400_966_916i32.to_le_bytes());
/// p[32..36].copy_from_slice(&1_580_048i32.to_le_bytes());
/// p[36..40].copy_from_slice(&1_601_435i32.to_le_bytes());
/// p[40..44].copy_from_slice(&14u32.to_le_bytes());
/// p[44..48].copy_from_slice(&10u32.to_le_bytes());
/// p[68..72].copy_from_slice(&70u32.to_le_bytes());
/// let (fixes, _) = read_ubx_from(&encode(0x01, 0x07, &p), "log.ubx".as_ref()).unwrap();
/// assert_eq!((fixes.len(), fixes[0].quality, fixes[0].satellites), (1, 1, 25));
/// // GPS week 2381 (from the UTC date), plus iTOW.
/// assert_eq!(fixes[0].time_s, 315_964_800.0 + 2381.0 * 604_800.0 + 408_639.75);
/// assert!((fixes[0].position.height_m - 1580.048).abs() < 1e-9);
/// assert!((fixes[0].position_sigma_neu.x - 0.014 / 2f64.sqrt()).abs() < 1e-12);
/// ```
pub fn read_ubx(path: &Path) -> Result<(Vec<GnssFix>, Vec<String>)> {
    read_ubx_from(&crate::text::read_bytes(path)?, path)
}

/// [`read_ubx`] on the file's bytes; `path` names the origin in messages.
pub fn read_ubx_from(bytes: &[u8], path: &Path) -> Result<(Vec<GnssFix>, Vec<String>)> {
    let (epochs, warnings) = read_nav_pvt_from(bytes, path)?;
    Ok((epochs.iter().map(|e| e.fix).collect(), warnings))
}

/// The NAV-PVT epochs of a UBX log with their details (offsets, week,
/// `hMSL`, flags) and the warnings; [`read_ubx_from`] keeps the fixes only.
pub fn read_nav_pvt_from(bytes: &[u8], path: &Path) -> Result<(Vec<NavPvt>, Vec<String>)> {
    let (frames, counts) = frame::frames(bytes);
    let mut others: BTreeMap<(u8, u8), usize> = BTreeMap::new();
    let mut skipped = Skipped::default();
    let mut decoded: Vec<(Raw, Option<u32>)> = Vec::new();
    for f in &frames {
        if (f.class, f.id) != NAV_PVT {
            *others.entry((f.class, f.id)).or_default() += 1;
            continue;
        }
        let Some(raw) = Raw::parse(f.offset, f.payload) else {
            skipped.short += 1;
            continue;
        };
        if !raw.has_position() {
            skipped.no_fix += 1;
            continue;
        }
        raw.check(path)?;
        let week = raw.week_from_utc();
        if week.is_some_and(|(_, off_s)| off_s.abs() > 1.0) {
            skipped.utc_off += 1;
        }
        decoded.push((raw, week.map(|(w, _)| w)));
    }
    let weeks = fill_weeks(&decoded).ok_or_else(|| no_epochs(path, &decoded, &others, bytes))?;
    skipped.week_inferred = decoded.iter().filter(|(_, w)| w.is_none()).count();
    let mut epochs: Vec<NavPvt> = Vec::with_capacity(decoded.len());
    for ((raw, _), week) in decoded.iter().zip(weeks) {
        let epoch = raw.epoch(week);
        if let Some(prev) = epochs.last() {
            if epoch.fix.time_s == prev.fix.time_s {
                skipped.duplicates += 1;
                continue;
            }
            if epoch.fix.time_s < prev.fix.time_s {
                return Err(binary_error(
                    path,
                    raw.offset,
                    "NAV-PVT iTOW",
                    format!(
                        "time {} GPST is before the previous epoch's {} (byte {}): time goes backwards (two logs joined?)",
                        crate::text::date_time(epoch.fix.time_s),
                        crate::text::date_time(prev.fix.time_s),
                        prev.offset
                    ),
                ));
            }
        }
        epochs.push(epoch);
    }
    Ok((epochs, warnings(path, &counts, &skipped, &others)))
}

/// The delay from each epoch's time to the arrival of the chunk holding the
/// end of its frame at the logging computer \[s\], from the RTKLIB time-tag
/// file written beside the log (None when the tags end before the frame).
///
/// A tag record is (ms since the start, file position after that chunk was
/// written); the tag header's start time is the logging computer's clock in
/// GPST. The delay is the receiver's computation and transmission time plus
/// the computer clock's error; on the rtklibexplorer walk it is 24–74 ms
/// (median 42 ms) — so that computer's clock, which also times the IMU
/// through the IMU's own tag file, agrees with GPST to within a few tens of
/// milliseconds.
pub fn arrival_latencies_s(epochs: &[NavPvt], tags: &TimeTags) -> Vec<Option<f64>> {
    epochs
        .iter()
        .map(|e| {
            let k = tags
                .tags
                .partition_point(|&(_, pos)| (pos as usize) < e.end);
            tags.tags
                .get(k)
                .map(|&(ms, _)| tags.start_s + f64::from(ms) / 1000.0 - e.fix.time_s)
        })
        .collect()
}

/// What was skipped, for the warnings.
#[derive(Debug, Default)]
struct Skipped {
    short: usize,
    no_fix: usize,
    duplicates: usize,
    week_inferred: usize,
    utc_off: usize,
}

/// The fields of a NAV-PVT payload read here (u-blox protocol
/// specification, UBX-NAV-PVT: offsets in bytes).
#[derive(Debug, Clone, Copy)]
struct Raw {
    offset: usize,
    end: usize,
    itow_ms: u32,
    year: u16,
    month: u8,
    day: u8,
    hour: u8,
    minute: u8,
    second: u8,
    valid: u8,
    nano: i32,
    fix_type: u8,
    flags: u8,
    num_sv: u8,
    lon: i32,
    lat: i32,
    height_mm: i32,
    hmsl_mm: i32,
    hacc_mm: u32,
    vacc_mm: u32,
    vel_mm_s: [i32; 3],
    sacc_mm_s: u32,
    flags3: u8,
}

/// Little-endian readers that return 0 past the end (callers check the
/// length first).
fn u8_at(p: &[u8], o: usize) -> u8 {
    p.get(o).copied().unwrap_or(0)
}
fn u16_at(p: &[u8], o: usize) -> u16 {
    u16::from_le_bytes([u8_at(p, o), u8_at(p, o + 1)])
}
fn u32_at(p: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([
        u8_at(p, o),
        u8_at(p, o + 1),
        u8_at(p, o + 2),
        u8_at(p, o + 3),
    ])
}
fn i32_at(p: &[u8], o: usize) -> i32 {
    u32_at(p, o) as i32
}

impl Raw {
    /// The fields of a payload of at least [`NAV_PVT_LEN_V7`] bytes.
    fn parse(offset: usize, p: &[u8]) -> Option<Self> {
        if p.len() < NAV_PVT_LEN_V7 {
            return None;
        }
        Some(Self {
            offset,
            end: offset + frame::OVERHEAD + p.len(),
            itow_ms: u32_at(p, 0),
            year: u16_at(p, 4),
            month: u8_at(p, 6),
            day: u8_at(p, 7),
            hour: u8_at(p, 8),
            minute: u8_at(p, 9),
            second: u8_at(p, 10),
            valid: u8_at(p, 11),
            nano: i32_at(p, 16),
            fix_type: u8_at(p, 20),
            flags: u8_at(p, 21),
            num_sv: u8_at(p, 23),
            lon: i32_at(p, 24),
            lat: i32_at(p, 28),
            height_mm: i32_at(p, 32),
            hmsl_mm: i32_at(p, 36),
            hacc_mm: u32_at(p, 40),
            vacc_mm: u32_at(p, 44),
            vel_mm_s: [i32_at(p, 48), i32_at(p, 52), i32_at(p, 56)],
            sacc_mm_s: u32_at(p, 68),
            flags3: u8_at(p, 78),
        })
    }

    /// gnssFixOK, a position fix type, and lat/lon/height not flagged
    /// invalid.
    fn has_position(&self) -> bool {
        self.flags & 0x01 != 0 && (2..=4).contains(&self.fix_type) && self.flags3 & 0x01 == 0
    }

    /// RTKLIB's Q (see the module docs).
    fn quality(&self) -> u8 {
        match self.flags >> 6 {
            2 => 1,
            1 => 2,
            _ if self.flags & 0x02 != 0 => 4,
            _ => 5,
        }
    }

    /// The GPS week from the UTC date and time (None when they are not
    /// flagged valid or are no calendar date) and how far GPST from UTC
    /// lies from the week start + iTOW \[s\].
    fn week_from_utc(&self) -> Option<(u32, f64)> {
        let (y, m, d) = (
            i64::from(self.year),
            i64::from(self.month),
            i64::from(self.day),
        );
        let valid = self.valid & 0x03 == 0x03
            && (1980..=9999).contains(&y)
            && crate::text::is_date(y, m, d)
            && self.hour < 24
            && self.minute < 60
            && self.second <= 60
            && self.nano.unsigned_abs() < 1_000_000_000;
        if !valid {
            return None;
        }
        let days = days_from_civil(y, m, d);
        let utc_s = days as f64 * 86_400.0
            + f64::from(u32::from(self.hour) * 3600 + u32::from(self.minute) * 60)
            + f64::from(self.second)
            + f64::from(self.nano) * 1e-9;
        let gpst_s = utc_s + gps_minus_utc_s(days);
        let tow_s = f64::from(self.itow_ms) / 1000.0;
        let week = ((gpst_s - GPS_EPOCH_1970_S - tow_s) / WEEK_S).round();
        if !(0.0..=f64::from(u16::MAX)).contains(&week) {
            return None;
        }
        let off = gpst_s - (GPS_EPOCH_1970_S + week * WEEK_S + tow_s);
        Some((week as u32, off))
    }

    /// Values no receiver on Earth reports: an error naming the byte offset.
    fn check(&self, path: &Path) -> Result<()> {
        use crate::limits::*;
        let bad =
            |field: &str, message: String| Err(binary_error(path, self.offset, field, message));
        let lat = f64::from(self.lat) * 1e-7;
        let lon = f64::from(self.lon) * 1e-7;
        let height = f64::from(self.height_mm) / 1000.0;
        let separation = height - f64::from(self.hmsl_mm) / 1000.0;
        for (field, value, limit, unit, why) in [
            ("NAV-PVT lat", lat, MAX_LATITUDE_DEG, "deg", "the poles"),
            ("NAV-PVT lon", lon, 180.0, "deg", "±180°"),
            (
                "NAV-PVT height − hMSL",
                separation,
                MAX_GEOID_SEPARATION_M,
                "m",
                "the geoid undulation spans −107…+86 m",
            ),
        ] {
            if let Some(m) = outside(value, -limit, limit, unit, why) {
                return bad(field, m);
            }
        }
        if let Some(m) = outside(
            height,
            MIN_HEIGHT_M,
            MAX_HEIGHT_M,
            "m",
            "below the lowest land or above 100 km",
        ) {
            return bad("NAV-PVT height", m);
        }
        for (field, value) in [
            ("NAV-PVT hAcc", self.hacc_mm),
            ("NAV-PVT vAcc", self.vacc_mm),
            ("NAV-PVT sAcc", self.sacc_mm_s),
        ] {
            if value == 0 {
                return bad(
                    field,
                    "accuracy 0: the fix cannot be weighted (a σ must be > 0)".into(),
                );
            }
        }
        let speed = self.velocity().norm();
        if let Some(m) = outside(
            speed,
            0.0,
            MAX_SPEED_M_S,
            "m/s",
            "faster than any vehicle a receiver reports",
        ) {
            return bad("NAV-PVT velN/velE/velD", m);
        }
        Ok(())
    }

    fn velocity(&self) -> Vector3<f64> {
        Vector3::from(self.vel_mm_s.map(|v| f64::from(v) / 1000.0))
    }

    /// The epoch in GPS week `week`.
    fn epoch(&self, week: u32) -> NavPvt {
        let h_sigma = f64::from(self.hacc_mm) / 1000.0 / std::f64::consts::SQRT_2;
        let v_sigma = f64::from(self.sacc_mm_s) / 1000.0 / std::f64::consts::SQRT_2;
        NavPvt {
            offset: self.offset,
            end: self.end,
            itow_ms: self.itow_ms,
            week,
            fix_type: self.fix_type,
            flags: self.flags,
            fix: GnssFix {
                time_s: GPS_EPOCH_1970_S
                    + f64::from(week) * WEEK_S
                    + f64::from(self.itow_ms) / 1000.0,
                position: Geodetic {
                    latitude_rad: (f64::from(self.lat) * 1e-7).to_radians(),
                    longitude_rad: (f64::from(self.lon) * 1e-7).to_radians(),
                    height_m: f64::from(self.height_mm) / 1000.0,
                },
                quality: self.quality(),
                satellites: u32::from(self.num_sv),
                position_sigma_neu: Vector3::new(
                    h_sigma,
                    h_sigma,
                    f64::from(self.vacc_mm) / 1000.0,
                ),
                velocity_ned: Some(self.velocity()),
                velocity_sigma_neu: Some(Vector3::repeat(v_sigma)),
            },
            height_msl_m: f64::from(self.hmsl_mm) / 1000.0,
        }
    }
}

/// The week of every epoch: its own, or that of the nearest epoch with one
/// (earlier first), adjusted so the two `iTOW`s lie within half a week.
/// None when no epoch has a week (or there are no epochs).
fn fill_weeks(decoded: &[(Raw, Option<u32>)]) -> Option<Vec<u32>> {
    // Nearest earlier epoch with a week, then nearest later one.
    let mut before: Vec<Option<(u32, u32)>> = Vec::with_capacity(decoded.len());
    let mut last = None;
    for (raw, week) in decoded {
        if let Some(w) = week {
            last = Some((*w, raw.itow_ms));
        }
        before.push(last);
    }
    let mut after: Vec<Option<(u32, u32)>> = vec![None; decoded.len()];
    let mut next = None;
    for (k, (raw, week)) in decoded.iter().enumerate().rev() {
        if let Some(w) = week {
            next = Some((*w, raw.itow_ms));
        }
        if let Some(slot) = after.get_mut(k) {
            *slot = next;
        }
    }
    decoded
        .iter()
        .zip(before.iter().zip(&after))
        .map(|((raw, _), (b, a))| {
            let (week, itow) = (*b).or(*a)?;
            // w = week + round((itow_known − itow) / week): the GPS time
            // nearest to the known epoch's.
            let diff = i64::from(itow) - i64::from(raw.itow_ms);
            let shift = (diff + WEEK_MS / 2).div_euclid(WEEK_MS);
            u32::try_from(i64::from(week) + shift).ok()
        })
        .collect::<Option<Vec<u32>>>()
        .filter(|w| !w.is_empty())
}

/// The error of a log without a usable NAV-PVT epoch, saying what it holds.
fn no_epochs(
    path: &Path,
    decoded: &[(Raw, Option<u32>)],
    others: &BTreeMap<(u8, u8), usize>,
    bytes: &[u8],
) -> IoError {
    if let Some((raw, _)) = decoded.first() {
        return binary_error(
            path,
            raw.offset,
            "NAV-PVT date",
            format!(
                "none of the {} NAV-PVT epochs with a fix has a valid UTC date (validDate and validTime): the GPS week cannot be derived",
                decoded.len()
            ),
        );
    }
    binary_error(
        path,
        0,
        "(file)",
        format!(
            "no NAV-PVT epoch with a position fix in {} bytes ({}): enable UBX-NAV-PVT output on the receiver",
            bytes.len(),
            if others.is_empty() {
                "no UBX frame at all".to_string()
            } else {
                format!("UBX frames found: {}", message_counts(others))
            }
        ),
    )
}

/// `NAV-PVT`-style names of the commonest classes and ids with counts.
fn message_counts(others: &BTreeMap<(u8, u8), usize>) -> String {
    let mut v: Vec<(&(u8, u8), &usize)> = others.iter().collect();
    v.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
    let mut parts: Vec<String> = v
        .iter()
        .take(6)
        .map(|((c, i), n)| format!("{} ×{n}", message_name(*c, *i)))
        .collect();
    if v.len() > 6 {
        parts.push(format!("{} other kinds", v.len() - 6));
    }
    parts.join(", ")
}

/// A message's name for the classes and ids a log usually holds, else
/// `0xCC-0xII`.
fn message_name(class: u8, id: u8) -> String {
    let known = match (class, id) {
        (0x01, 0x07) => "NAV-PVT",
        (0x01, 0x14) => "NAV-HPPOSLLH",
        (0x01, 0x3C) => "NAV-RELPOSNED",
        (0x01, 0x35) => "NAV-SAT",
        (0x01, 0x03) => "NAV-STATUS",
        (0x02, 0x13) => "RXM-SFRBX",
        (0x02, 0x15) => "RXM-RAWX",
        (0x10, 0x02) => "ESF-MEAS",
        (0x0D, 0x03) => "TIM-TM2",
        _ => return format!("0x{class:02X}-0x{id:02X}"),
    };
    known.to_string()
}

/// The warnings: one line per kind of thing skipped, with its count.
fn warnings(
    path: &Path,
    counts: &frame::ScanCounts,
    skipped: &Skipped,
    others: &BTreeMap<(u8, u8), usize>,
) -> Vec<String> {
    let p = path.display();
    let at = |o: Option<usize>| o.map_or(String::new(), |o| format!(", the first at byte {o}"));
    let other_frames: usize = others.values().sum();
    [
        (
            counts.bad_checksum,
            format!("UBX frames with a bad checksum skipped{}", at(counts.first_bad_checksum)),
        ),
        (
            counts.truncated,
            format!(
                "sync pairs whose frame runs past the end of the file skipped (a truncated last frame, or a false sync){}",
                at(counts.first_truncated)
            ),
        ),
        (
            counts.outside_bytes,
            "bytes outside UBX frames skipped (NMEA, RTCM or noise)".to_string(),
        ),
        (
            other_frames,
            format!(
                "UBX frames of other messages skipped ({})",
                message_counts(others)
            ),
        ),
        (
            skipped.short,
            format!("NAV-PVT frames shorter than {NAV_PVT_LEN_V7} bytes skipped"),
        ),
        (
            skipped.no_fix,
            "NAV-PVT epochs without a position fix (gnssFixOK clear, fixType not 2-D/3-D/GNSS+DR, or invalidLlh) skipped".to_string(),
        ),
        (
            skipped.duplicates,
            "repeated NAV-PVT epochs (same iTOW) skipped".to_string(),
        ),
        (
            skipped.week_inferred,
            "NAV-PVT epochs without a valid UTC date: GPS week taken from the nearest epoch with one".to_string(),
        ),
        (
            skipped.utc_off,
            "NAV-PVT epochs whose UTC + leap seconds differs from GPS week + iTOW by more than 1 s (the receiver's leap seconds not yet known, or this table out of date)".to_string(),
        ),
    ]
    .into_iter()
    .filter(|(n, _)| *n > 0)
    .map(|(n, what)| format!("{p}: {n} {what}"))
    .collect()
}

/// A binary-file error at a byte offset.
fn binary_error(path: &Path, offset: usize, field: &str, message: String) -> IoError {
    IoError::Binary {
        path: path.to_path_buf(),
        offset,
        field: field.to_string(),
        message,
    }
}

#[cfg(test)]
mod tests;
