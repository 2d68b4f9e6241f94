use super::frame::encode;
use super::*;

/// A NAV-PVT payload's fields, defaults of an RTK-fixed epoch on the walk.
#[derive(Clone, Copy)]
struct Pvt {
    itow_ms: u32,
    date: (u16, u8, u8),
    time: (u8, u8, u8),
    valid: u8,
    nano: i32,
    fix_type: u8,
    flags: u8,
    flags3: u8,
    lat: i32,
    lon: i32,
    height_mm: i32,
    hmsl_mm: i32,
    hacc_mm: u32,
    vacc_mm: u32,
    vel_mm_s: [i32; 3],
    sacc_mm_s: u32,
    len: usize,
}

impl Default for Pvt {
    fn default() -> Self {
        Self {
            itow_ms: 408_639_750,
            date: (2025, 8, 28),
            time: (17, 30, 21),
            valid: 0x07,
            nano: 749_542_955,
            fix_type: 3,
            flags: 0x83,
            flags3: 0,
            lat: 400_966_916,
            lon: -1_051_471_665,
            height_mm: 1_580_048,
            hmsl_mm: 1_601_435,
            hacc_mm: 14,
            vacc_mm: 10,
            vel_mm_s: [1, -2, -27],
            sacc_mm_s: 70,
            len: NAV_PVT_LEN,
        }
    }
}

impl Pvt {
    /// The payload bytes.
    fn payload(&self) -> Vec<u8> {
        let mut p = vec![0u8; self.len.max(80)];
        p[0..4].copy_from_slice(&self.itow_ms.to_le_bytes());
        p[4..6].copy_from_slice(&self.date.0.to_le_bytes());
        p[6] = self.date.1;
        p[7] = self.date.2;
        p[8] = self.time.0;
        p[9] = self.time.1;
        p[10] = self.time.2;
        p[11] = self.valid;
        p[16..20].copy_from_slice(&self.nano.to_le_bytes());
        p[20] = self.fix_type;
        p[21] = self.flags;
        p[23] = 25;
        p[24..28].copy_from_slice(&self.lon.to_le_bytes());
        p[28..32].copy_from_slice(&self.lat.to_le_bytes());
        p[32..36].copy_from_slice(&self.height_mm.to_le_bytes());
        p[36..40].copy_from_slice(&self.hmsl_mm.to_le_bytes());
        p[40..44].copy_from_slice(&self.hacc_mm.to_le_bytes());
        p[44..48].copy_from_slice(&self.vacc_mm.to_le_bytes());
        for (k, v) in self.vel_mm_s.iter().enumerate() {
            p[48 + 4 * k..52 + 4 * k].copy_from_slice(&v.to_le_bytes());
        }
        p[68..72].copy_from_slice(&self.sacc_mm_s.to_le_bytes());
        p[78] = self.flags3;
        p.truncate(self.len);
        p
    }

    fn frame(&self) -> Vec<u8> {
        encode(0x01, 0x07, &self.payload())
    }

    /// The same epoch `k` quarter-seconds later (UTC fields too).
    fn later(&self, k: u32) -> Self {
        let mut p = *self;
        p.itow_ms += 250 * k;
        let ms = u32::from(p.time.2) * 1000 + (self.nano / 1_000_000) as u32 + 250 * k;
        p.time.2 = (ms / 1000) as u8;
        p.nano = (ms % 1000) as i32 * 1_000_000 + self.nano % 1_000_000;
        p
    }
}

fn read(bytes: &[u8]) -> Result<(Vec<NavPvt>, Vec<String>)> {
    read_nav_pvt_from(bytes, Path::new("log.ubx"))
}

/// Start of GPS week `w`, seconds since 1970.
fn week_start(w: u32) -> f64 {
    GPS_EPOCH_1970_S + f64::from(w) * WEEK_S
}

#[test]
fn a_fixed_epoch_becomes_a_fix() {
    let (e, w) = read(&Pvt::default().frame()).unwrap();
    assert!(w.is_empty(), "{w:?}");
    let e = e[0];
    // 2025-08-28 is in GPS week 2381 (2025-08-24 … 30).
    assert_eq!(
        (e.week, e.itow_ms, e.offset, e.end),
        (2381, 408_639_750, 0, 100)
    );
    assert_eq!(e.fix.time_s, week_start(2381) + 408_639.75);
    assert_eq!(
        crate::text::date_time(e.fix.time_s),
        "2025-08-28 17:30:39.750"
    );
    let p = e.fix.position;
    assert!((p.latitude_rad.to_degrees() - 40.096_691_6).abs() < 1e-12);
    assert!((p.longitude_rad.to_degrees() + 105.147_166_5).abs() < 1e-12);
    assert_eq!(p.height_m, 1580.048);
    assert_eq!(e.height_msl_m, 1601.435);
    assert!((e.geoid_separation_m() + 21.387).abs() < 1e-9);
    assert_eq!(e.msl_fix().position.height_m, 1601.435);
    let s = 0.014 / 2f64.sqrt();
    assert_eq!(e.fix.position_sigma_neu, Vector3::new(s, s, 0.010));
    assert_eq!(
        e.fix.velocity_ned,
        Some(Vector3::new(0.001, -0.002, -0.027))
    );
    assert_eq!(
        e.fix.velocity_sigma_neu,
        Some(Vector3::repeat(0.070 / 2f64.sqrt()))
    );
    assert_eq!((e.fix.quality, e.fix.satellites), (1, 25));
}

#[test]
fn carrier_and_differential_flags_map_to_rtklib_q() {
    // (flags, Q): carrSoln 2 fixed, 1 float, else diffSoln → DGPS, else single.
    for (flags, q) in [
        (0x83, 1),
        (0x43, 2),
        (0x03, 4),
        (0x01, 5),
        (0xC3, 4),
        (0x81, 1),
    ] {
        let p = Pvt {
            flags,
            ..Pvt::default()
        };
        let (e, _) = read(&p.frame()).unwrap();
        assert_eq!(e[0].fix.quality, q, "flags {flags:#04x}");
    }
}

#[test]
fn epochs_without_a_position_are_skipped_and_counted() {
    let base = Pvt::default();
    let mut log = Vec::new();
    // No fix, dead reckoning only, time only, gnssFixOK clear, invalidLlh;
    // then a 2-D fix, a 3-D fix and GNSS + DR.
    for (k, (fix_type, flags, flags3)) in [
        (0, 0x83, 0),
        (1, 0x83, 0),
        (5, 0x83, 0),
        (3, 0x82, 0),
        (3, 0x83, 1),
        (2, 0x83, 0),
        (3, 0x83, 0),
        (4, 0x83, 0),
    ]
    .into_iter()
    .enumerate()
    {
        log.extend(
            Pvt {
                fix_type,
                flags,
                flags3,
                ..base.later(k as u32)
            }
            .frame(),
        );
    }
    let (e, w) = read(&log).unwrap();
    assert_eq!(e.iter().map(|e| e.fix_type).collect::<Vec<_>>(), [2, 3, 4]);
    assert_eq!(e[0].itow_ms, base.itow_ms + 5 * 250);
    assert!(
        w.iter()
            .any(|w| w.starts_with("log.ubx: 5 NAV-PVT epochs without a position fix")),
        "{w:?}"
    );
}

#[test]
fn the_week_is_right_on_both_sides_of_the_week_boundary() {
    // GPS week 2382 starts 2025-08-31 00:00:00 GPST = 2025-08-30 23:59:42
    // UTC. The epoch at iTOW 0 carries UTC 23:59:41.9995 (the receiver's
    // clock steering): truncating GPST from UTC would give week 2381.
    let first = Pvt {
        itow_ms: 0,
        date: (2025, 8, 30),
        time: (23, 59, 41),
        nano: 999_500_000,
        ..Pvt::default()
    };
    let (e, _) = read(&first.frame()).unwrap();
    assert_eq!((e[0].week, e[0].fix.time_s), (2382, week_start(2382)));
    // The last epoch of week 2381, its UTC already past the boundary.
    let last = Pvt {
        itow_ms: 604_799_750,
        date: (2025, 8, 30),
        time: (23, 59, 42),
        nano: 100_000,
        ..Pvt::default()
    };
    let (e, _) = read(&last.frame()).unwrap();
    assert_eq!(
        (e[0].week, e[0].fix.time_s),
        (2381, week_start(2382) - 0.25)
    );
}

#[test]
fn epochs_without_a_valid_date_take_the_nearest_week() {
    let dated = Pvt {
        itow_ms: 604_799_500,
        date: (2025, 8, 30),
        time: (23, 59, 41),
        nano: 500_000_000,
        ..Pvt::default()
    };
    // Undated before it (same week), undated after it across the boundary.
    let undated = |itow_ms: u32| Pvt {
        itow_ms,
        valid: 0x00,
        date: (2015, 1, 1),
        ..dated
    };
    let mut log = undated(604_799_250).frame();
    log.extend(dated.frame());
    log.extend(undated(604_799_750).frame());
    log.extend(undated(0).frame());
    log.extend(undated(250).frame());
    let (e, w) = read(&log).unwrap();
    let t0 = week_start(2382);
    assert_eq!(
        e.iter().map(|e| e.fix.time_s - t0).collect::<Vec<_>>(),
        [-0.75, -0.5, -0.25, 0.0, 0.25]
    );
    assert_eq!(
        e.iter().map(|e| e.week).collect::<Vec<_>>(),
        [2381, 2381, 2381, 2382, 2382]
    );
    assert!(
        w.iter()
            .any(|w| w.contains("4 NAV-PVT epochs without a valid UTC date")),
        "{w:?}"
    );
    // No valid date anywhere: an error at the first epoch.
    let e = read(&undated(100).frame()).unwrap_err().to_string();
    assert!(
        e.starts_with("log.ubx: byte 0: NAV-PVT date: none of the 1 NAV-PVT epochs"),
        "{e}"
    );
}

#[test]
fn a_receiver_without_leap_seconds_still_gets_its_week_and_a_warning() {
    // UTC 18 s late (leap seconds unknown): the week still rounds right.
    let p = Pvt {
        time: (17, 30, 39),
        ..Pvt::default()
    };
    let (e, w) = read(&p.frame()).unwrap();
    assert_eq!(e[0].week, 2381);
    assert!(w.iter().any(|w| w.contains("more than 1 s")), "{w:?}");
}

#[test]
fn damaged_frames_other_messages_and_nmea_are_counted() {
    let base = Pvt::default();
    let nmea = b"$GNGGA,173021.75,4005.80,N,10508.82,W,4,12,0.9,1601.4,M,-21.4,M,1.0,0000*5A\r\n";
    let mut log = nmea.to_vec();
    log.extend(base.frame());
    let mut damaged = base.later(1).frame();
    damaged[40] ^= 0x10;
    let damaged_at = log.len();
    log.extend(&damaged);
    log.extend(encode(0x02, 0x15, &[0; 16]));
    log.extend(encode(0x02, 0x15, &[1; 16]));
    log.extend(encode(0x02, 0x13, &[0; 8]));
    log.extend(base.later(2).frame());
    // A short NAV-PVT and the last frame cut short.
    log.extend(encode(0x01, 0x07, &[0; 40]));
    let cut_at = log.len();
    log.extend(&base.later(3).frame()[..50]);
    let (e, w) = read(&log).unwrap();
    assert_eq!(
        e.iter()
            .map(|e| e.itow_ms - base.itow_ms)
            .collect::<Vec<_>>(),
        [0, 500]
    );
    let all = w.join("\n");
    for want in [
        format!("1 UBX frames with a bad checksum skipped, the first at byte {damaged_at}"),
        format!(
            "1 sync pairs whose frame runs past the end of the file skipped (a truncated last frame, or a false sync), the first at byte {cut_at}"
        ),
        format!(
            "{} bytes outside UBX frames skipped",
            nmea.len() + damaged.len() + 50
        ),
        "3 UBX frames of other messages skipped (RXM-RAWX ×2, RXM-SFRBX ×1)".to_string(),
        "1 NAV-PVT frames shorter than 84 bytes skipped".to_string(),
    ] {
        assert!(all.contains(&want), "{want}\n in\n{all}");
    }
    // u-blox 7's 84-byte NAV-PVT is read.
    let (e, _) = read(
        &Pvt {
            len: NAV_PVT_LEN_V7,
            ..base
        }
        .frame(),
    )
    .unwrap();
    assert_eq!(e.len(), 1);
}

#[test]
fn impossible_values_name_the_byte_offset_and_field() {
    let base = Pvt::default();
    let prefix = encode(0x02, 0x15, &[0; 12]);
    let at = prefix.len();
    let cases: [(Pvt, &str); 6] = [
        (
            Pvt {
                lat: 910_000_000,
                ..base
            },
            "NAV-PVT lat: 91 deg is outside [-90, 90] deg",
        ),
        (
            Pvt {
                height_mm: 150_000_000,
                hmsl_mm: 150_000_000,
                ..base
            },
            "NAV-PVT height: 150000 m is outside",
        ),
        (
            Pvt {
                hmsl_mm: 1_300_000,
                ..base
            },
            "NAV-PVT height − hMSL: 280.048 m is outside [-200, 200] m",
        ),
        (Pvt { hacc_mm: 0, ..base }, "NAV-PVT hAcc: accuracy 0"),
        (
            Pvt {
                sacc_mm_s: 0,
                ..base
            },
            "NAV-PVT sAcc: accuracy 0",
        ),
        (
            Pvt {
                vel_mm_s: [3_000_000, 0, 0],
                ..base
            },
            "NAV-PVT velN/velE/velD: 3000 m/s is outside [0, 1000] m/s",
        ),
    ];
    for (pvt, want) in cases {
        let mut log = prefix.clone();
        log.extend(pvt.frame());
        let e = read(&log).unwrap_err().to_string();
        assert!(e.starts_with(&format!("log.ubx: byte {at}: {want}")), "{e}");
    }
}

#[test]
fn time_going_backwards_is_an_error_and_repeats_are_skipped() {
    let base = Pvt::default();
    let mut log = base.later(1).frame();
    log.extend(base.later(1).frame());
    let (e, w) = read(&log).unwrap();
    assert_eq!(e.len(), 1);
    assert!(
        w.iter().any(|w| w.contains("1 repeated NAV-PVT epochs")),
        "{w:?}"
    );
    let second = log.len();
    log.extend(base.frame());
    let e = read(&log).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!(
            "log.ubx: byte {second}: NAV-PVT iTOW: time 2025-08-28 17:30:39.750 GPST is before the previous epoch's 2025-08-28 17:30:40.000 (byte 0)"
        )),
        "{e}"
    );
}

#[test]
fn a_log_without_nav_pvt_says_what_it_holds() {
    let mut log = encode(0x02, 0x15, &[0; 16]);
    log.extend(encode(0x02, 0x13, &[0; 8]));
    log.extend(encode(0x02, 0x13, &[0; 8]));
    let e = read(&log).unwrap_err().to_string();
    assert_eq!(
        e,
        "log.ubx: byte 0: (file): no NAV-PVT epoch with a position fix in 56 bytes (UBX frames found: RXM-SFRBX ×2, RXM-RAWX ×1): enable UBX-NAV-PVT output on the receiver"
    );
    let e = read(b"$GPGGA,,,,*00\r\n").unwrap_err().to_string();
    assert!(e.contains("(no UBX frame at all)"), "{e}");
    let no_fix = Pvt {
        fix_type: 0,
        ..Pvt::default()
    };
    let e = read(&no_fix.frame()).unwrap_err().to_string();
    assert!(e.contains("no NAV-PVT epoch with a position fix"), "{e}");
}

/// The walk's raw log in the repository's data/.
fn walk() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/rtklibexplorer-gnss-imu/walk_0827")
}

/// Acceptance: the data set's `gnss_1730_sf.pos` is rtklibexplorer's
/// conversion of this log's NAV-PVT messages (upstream
/// `src/convert _ubx_file.py`: hMSL as the height, hAcc/√2, vAcc, sAcc/√2,
/// Q from carrSoln, time = UTC + nano + 18 s printed to the millisecond), so
/// the log read directly agrees with it epoch for epoch: the same 536
/// epochs, positions within a millimetre with the MSL height, σ and
/// velocity to the file's 7 decimals, the same fix types. The `.pos` time
/// is 1 ms earlier at every epoch: UTC + nano lies 0.42–0.46 ms before iTOW
/// (the receiver's clock steering), and the conversion truncates it to the
/// millisecond.
#[test]
fn the_walk_log_agrees_with_its_pos_conversion_epoch_for_epoch() {
    let dir = walk();
    let (epochs, warnings) = read_nav_pvt_from(
        &crate::text::read_bytes(&dir.join("gnss_1730.ubx")).unwrap(),
        &dir.join("gnss_1730.ubx"),
    )
    .unwrap();
    let (pos, _) = crate::rtklib::read_pos(&dir.join("gnss_1730_sf.pos")).unwrap();
    assert_eq!((epochs.len(), pos.len()), (536, 536));
    // The log interleaves NMEA (136 199 bytes) and raw measurements.
    let all = warnings.join("\n");
    assert!(all.contains(": 136199 bytes outside UBX frames"), "{all}");
    assert!(
        !all.contains("checksum") && !all.contains("past the end"),
        "{all}"
    );
    let (mut max_dt, mut max_d, mut max_sigma, mut max_v) = (0f64, 0f64, 0f64, 0f64);
    for (e, p) in epochs.iter().zip(&pos) {
        let u = e.msl_fix();
        // UTC + nano + 18 s is 0.42–0.46 ms before iTOW; truncated to the
        // millisecond it is iTOW − 1 ms, up to the parse's rounding.
        let dt = p.time_s - u.time_s;
        max_dt = max_dt.max((dt + 1e-3).abs());
        max_d = max_d.max(u.position.ned_to(&p.position).norm());
        max_sigma = max_sigma.max((u.position_sigma_neu - p.position_sigma_neu).amax());
        let (uv, pv) = (u.velocity_ned.unwrap(), p.velocity_ned.unwrap());
        max_v = max_v
            .max((uv - pv).amax())
            .max((u.velocity_sigma_neu.unwrap() - p.velocity_sigma_neu.unwrap()).amax());
        assert_eq!((u.quality, u.satellites), (p.quality, p.satellites));
    }
    eprintln!(
        "walk .ubx vs .pos: max |dt + 1 ms| {max_dt} s, max position difference {max_d} m, σ {max_sigma} m, velocity {max_v} m/s"
    );
    // Measured: |dt + 1 ms| ≤ 7e-8 s, 2.5e-9 m (the .pos prints NAV-PVT's
    // 1e-7° and mm exactly), σ 8.5e-9 m and velocity 4.9e-8 m/s (its 7
    // decimals).
    assert!(max_dt < 1e-6, "{max_dt}");
    assert!(max_d < 1e-6, "{max_d} m");
    assert!(
        max_sigma <= 5.1e-8 && max_v <= 5.1e-8,
        "{max_sigma} {max_v}"
    );
    // RTK fixed until about 88 s, then float (README): 349 fixed, 187 float.
    let fixed = epochs.iter().filter(|e| e.fix.quality == 1).count();
    let float = epochs.iter().filter(|e| e.fix.quality == 2).count();
    assert_eq!((fixed, float), (349, 187));
    // The ellipsoidal height is hMSL + the receiver's geoid undulation at
    // Boulder, −21.39 m (EGM96 there: about −21 m).
    for e in &epochs {
        assert!(
            (e.geoid_separation_m() + 21.39).abs() < 0.01,
            "{}",
            e.geoid_separation_m()
        );
    }
}

/// The `.ubx.tag` file: NAV-PVT frames arrive at the logging computer
/// 24–74 ms after their epoch (median 42 ms) — the receiver's latency plus
/// the computer clock's error, which also times the IMU.
#[test]
fn the_walk_tag_file_gives_arrival_latencies() {
    let dir = walk();
    let path = dir.join("gnss_1730.ubx");
    let (epochs, _) = read_nav_pvt_from(&crate::text::read_bytes(&path).unwrap(), &path).unwrap();
    let tags = crate::rtklib::read_time_tags(&dir.join("gnss_1730.ubx.tag")).unwrap();
    let mut lat: Vec<f64> = arrival_latencies_s(&epochs, &tags)
        .into_iter()
        .map(|l| l.unwrap())
        .collect();
    lat.sort_by(f64::total_cmp);
    let (min, median, max) = (lat[0], lat[lat.len() / 2], lat[lat.len() - 1]);
    assert!((0.020..0.030).contains(&min), "{min}");
    assert!((0.038..0.046).contains(&median), "{median}");
    assert!((0.070..0.080).contains(&max), "{max}");
}
