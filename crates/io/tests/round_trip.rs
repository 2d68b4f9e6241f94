//! Every writer against its reader: write → read with the crate's reader →
//! compare with the input within the format's resolution.

use std::path::Path;

use aidnav_frames::earth::Geodetic;
use aidnav_io::formats::{BaroFormat, GnssFormat, ImuFormat, TimeSystem, WheelSpeedFormat};
use aidnav_sensors::{BaroSample, GnssFix, ImuSample, WheelSpeedSample};
use nalgebra::Vector3;

/// 2024-08-27 00:00:00 GPST.
const T0: f64 = 1_724_716_800.0;

fn imu(n: usize) -> Vec<ImuSample> {
    (0..n)
        .map(|k| {
            let x = k as f64;
            ImuSample {
                time_s: T0 + 0.01 * x,
                specific_force: Vector3::new(
                    0.1 + 0.01 * (0.3 * x).sin(),
                    -0.2,
                    -9.8 + 1e-3 * x.cos(),
                ),
                angular_rate: Vector3::new(1e-3 * (0.1 * x).sin(), -2e-3, 0.01 + 1e-4 * x),
            }
        })
        .collect()
}

/// 10 Hz fixes from `t0`, south-west of Greenwich when `west`.
fn fixes(n: usize, t0: f64, velocity: bool, west: bool) -> Vec<GnssFix> {
    let sign = if west { -1.0 } else { 1.0 };
    (0..n)
        .map(|k| {
            let x = k as f64;
            GnssFix {
                time_s: t0 + 0.1 * x,
                position: Geodetic {
                    latitude_rad: (sign * (30.5 + 1.234_567e-6 * x)).to_radians(),
                    longitude_rad: (sign * (114.3 - 2.345_678e-6 * x)).to_radians(),
                    height_m: 20.0 + 0.012_345 * x,
                },
                quality: [1, 2, 4, 5][k % 4],
                satellites: 12 + (k % 5) as u32,
                position_sigma_neu: Vector3::new(0.02 + 0.001 * x, 0.02 + 0.001 * x, 0.04),
                velocity_ned: velocity.then(|| Vector3::new(10.0 + 0.01 * x, -3.0 * sign, 0.25)),
                velocity_sigma_neu: velocity.then(|| Vector3::repeat(0.05)),
            }
        })
        .collect()
}

fn deg(a: f64) -> f64 {
    a.to_degrees()
}

/// Positions and times within the given tolerances \[s, deg, m\].
fn check_positions(a: &[GnssFix], b: &[GnssFix], dt: f64, dangle: f64, dh: f64) {
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(b) {
        assert!(
            (x.time_s - y.time_s).abs() <= dt,
            "time {} {}",
            x.time_s,
            y.time_s
        );
        let (p, q) = (&x.position, &y.position);
        assert!(
            (deg(p.latitude_rad) - deg(q.latitude_rad)).abs() <= dangle,
            "{p:?} {q:?}"
        );
        assert!(
            (deg(p.longitude_rad) - deg(q.longitude_rad)).abs() <= dangle,
            "{p:?} {q:?}"
        );
        assert!((p.height_m - q.height_m).abs() <= dh, "{p:?} {q:?}");
    }
}

fn near(a: Vector3<f64>, b: Vector3<f64>, tol: f64) -> bool {
    (a - b).amax() <= tol
}

/// Equal or within 2 ulp (relative 4.5e-16).
fn ulps(a: f64, b: f64) -> bool {
    a == b || (a - b).abs() <= 4.5e-16 * a.abs().max(b.abs())
}

#[test]
fn generic_imu_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("imu.csv");
    let s = imu(300);
    assert_eq!(
        ImuFormat::GenericCsv.write(&path, &s).unwrap(),
        vec![path.clone()]
    );
    let (back, _) = ImuFormat::GenericCsv
        .read(&path, &Default::default())
        .unwrap();
    assert_eq!(back, s);
}

#[test]
fn tagged_imu_round_trips_with_its_tag_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("logs/imu.csv");
    let s = imu(500);
    let written = ImuFormat::RtklibTagged.write(&path, &s).unwrap();
    assert_eq!(
        written,
        vec![path.clone(), dir.path().join("logs/imu.csv.tag")]
    );
    let (back, warnings) = ImuFormat::RtklibTagged
        .read(
            &path,
            &aidnav_io::formats::ImuReadOptions {
                tags: Some(&written[1]),
                ..Default::default()
            },
        )
        .unwrap();
    // Only the reader's note about the dropped first and last lines.
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert_eq!(back.len(), s.len());
    for (a, b) in s.iter().zip(&back) {
        assert!(
            (a.time_s - b.time_s).abs() < 1e-6,
            "{} {}",
            a.time_s,
            b.time_s
        );
        assert!(
            near(a.specific_force, b.specific_force, 1e-14),
            "{a:?} {b:?}"
        );
        assert!(near(a.angular_rate, b.angular_rate, 1e-17), "{a:?} {b:?}");
    }
    assert_eq!(back[0].time_s, s[0].time_s);
}

#[test]
fn kfgins_imu_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("imu.txt");
    let s = imu(300);
    ImuFormat::KfGins.write(&path, &s).unwrap();
    let (back, _) = ImuFormat::KfGins.read(&path, &Default::default()).unwrap();
    assert_eq!(back.len(), s.len());
    for (a, b) in s.iter().zip(&back) {
        assert!(
            (a.time_s - b.time_s).abs() < 1e-6,
            "{} {}",
            a.time_s,
            b.time_s
        );
        assert!(
            near(a.specific_force, b.specific_force, 1e-13),
            "{a:?} {b:?}"
        );
        assert!(near(a.angular_rate, b.angular_rate, 1e-16), "{a:?} {b:?}");
    }
}

#[test]
fn imu_writers_refuse_what_cannot_be_read() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = imu(3);
    s[2].time_s = s[1].time_s;
    for f in [
        ImuFormat::GenericCsv,
        ImuFormat::RtklibTagged,
        ImuFormat::KfGins,
    ] {
        let path = dir.path().join("bad.csv");
        let e = f.write(&path, &s).unwrap_err().to_string();
        assert!(e.contains("bad.csv: cannot write"), "{e}");
        assert!(!path.exists());
        assert!(f.write(&path, &imu(1)[..0]).is_err());
    }
}

#[test]
fn generic_gnss_is_exact_in_gpst_and_utc() {
    let dir = tempfile::tempdir().unwrap();
    // Across a UTC midnight (GPST 23:59:55 + 18 s leap).
    for t0 in [T0 + 3.0, T0 + 86_400.0 + 18.0 - 2.05] {
        for velocity in [false, true] {
            for time in [TimeSystem::Gpst, TimeSystem::Utc] {
                let f = fixes(60, t0, velocity, velocity);
                let path = dir.path().join(format!("g_{velocity}_{time:?}.csv"));
                GnssFormat::GenericCsv.write(&path, &f, time).unwrap();
                let text = std::fs::read_to_string(&path).unwrap();
                let first = text.lines().next().unwrap();
                assert!(first.starts_with(if time == TimeSystem::Utc {
                    "utc,"
                } else {
                    "gpst_s,"
                }));
                let (back, warnings) = GnssFormat::GenericCsv.read(&path, None).unwrap();
                assert!(warnings.is_empty(), "{warnings:?}");
                assert_eq!(back.len(), f.len());
                for (a, b) in f.iter().zip(&back) {
                    assert_eq!(a.time_s, b.time_s, "{time:?}");
                    assert!(ulps(a.position.latitude_rad, b.position.latitude_rad));
                    assert!(ulps(a.position.longitude_rad, b.position.longitude_rad));
                    assert_eq!(a.position.height_m, b.position.height_m);
                    assert_eq!(
                        (
                            a.quality,
                            a.satellites,
                            a.position_sigma_neu,
                            a.velocity_ned,
                            a.velocity_sigma_neu
                        ),
                        (
                            b.quality,
                            b.satellites,
                            b.position_sigma_neu,
                            b.velocity_ned,
                            b.velocity_sigma_neu
                        )
                    );
                }
            }
        }
    }
    // UTC stamps are GPST − 18 s.
    let path = dir.path().join("utc.csv");
    GnssFormat::GenericCsv
        .write(&path, &fixes(1, T0 + 0.25, false, false), TimeSystem::Utc)
        .unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.lines()
            .nth(1)
            .unwrap()
            .starts_with("2024-08-26T23:59:42.25Z,"),
        "{text}"
    );
}

#[test]
fn generic_gnss_without_sigma_needs_the_configured_sigma() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("g.csv");
    let mut f = fixes(5, T0, false, false);
    for x in &mut f {
        x.position_sigma_neu = Vector3::repeat(f64::NAN);
    }
    GnssFormat::GenericCsv
        .write(&path, &f, TimeSystem::Gpst)
        .unwrap();
    assert!(GnssFormat::GenericCsv.read(&path, None).is_err());
    let (back, _) = GnssFormat::GenericCsv
        .read(&path, Some([0.5, 1.0]))
        .unwrap();
    assert_eq!(back[0].position_sigma_neu, Vector3::new(0.5, 0.5, 1.0));
    // σ on some fixes only: refused.
    f[0].position_sigma_neu = Vector3::repeat(1.0);
    assert!(
        GnssFormat::GenericCsv
            .write(&path, &f, TimeSystem::Gpst)
            .is_err()
    );
}

#[test]
fn pos_round_trips_in_gpst_and_utc_with_and_without_velocity() {
    let dir = tempfile::tempdir().unwrap();
    for t0 in [T0 + 3.0, T0 + 86_400.0 + 18.0 - 2.05] {
        for velocity in [false, true] {
            for time in [TimeSystem::Gpst, TimeSystem::Utc] {
                let f = fixes(60, t0, velocity, !velocity);
                let path = dir.path().join(format!("g_{velocity}_{time:?}.pos"));
                GnssFormat::RtklibPos.write(&path, &f, time).unwrap();
                let (back, warnings) = GnssFormat::RtklibPos.read(&path, None).unwrap();
                assert!(warnings.is_empty(), "{warnings:?}");
                check_positions(&f, &back, 1e-6, 1e-9, 5e-5);
                for (a, b) in f.iter().zip(&back) {
                    assert_eq!((a.quality, a.satellites), (b.quality, b.satellites));
                    assert!(near(a.position_sigma_neu, b.position_sigma_neu, 5e-5));
                    match (a.velocity_ned, b.velocity_ned) {
                        (Some(v), Some(w)) => assert!(near(v, w, 5e-6), "{v} {w}"),
                        (None, None) => {}
                        other => panic!("{other:?}"),
                    }
                    assert_eq!(a.velocity_sigma_neu, b.velocity_sigma_neu);
                }
            }
        }
    }
    let path = dir.path().join("utc.pos");
    GnssFormat::RtklibPos
        .write(&path, &fixes(1, T0 + 0.25, false, false), TimeSystem::Utc)
        .unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("%  UTC "), "{text}");
    assert!(text.contains("\n2024/08/26 23:59:42.250 "), "{text}");
}

#[test]
fn kfgins_gnss_holds_velocity_in_13_columns() {
    let dir = tempfile::tempdir().unwrap();
    for velocity in [false, true] {
        let f = fixes(30, T0, velocity, false);
        let path = dir.path().join(format!("g_{velocity}.txt"));
        GnssFormat::KfGins
            .write(&path, &f, TimeSystem::Utc)
            .unwrap();
        let (back, _) = GnssFormat::KfGins.read(&path, None).unwrap();
        for (a, b) in f.iter().zip(&back) {
            assert_eq!(a.time_s, b.time_s);
            assert!(ulps(a.position.latitude_rad, b.position.latitude_rad));
            assert!(ulps(a.position.longitude_rad, b.position.longitude_rad));
            assert_eq!(a.position.height_m, b.position.height_m);
            assert_eq!(
                (a.position_sigma_neu, a.velocity_ned, a.velocity_sigma_neu),
                (b.position_sigma_neu, b.velocity_ned, b.velocity_sigma_neu)
            );
            // Quality and satellites are not in the format.
            assert_eq!((b.quality, b.satellites), (0, 0));
        }
    }
}

#[test]
fn nmea_round_trips_in_utc_across_midnight() {
    let dir = tempfile::tempdir().unwrap();
    for t0 in [T0 + 3.0, T0 + 86_400.0 + 18.0 - 2.05] {
        for (velocity, west) in [(false, false), (true, true), (true, false)] {
            let f = fixes(60, t0, velocity, west);
            let path = dir.path().join(format!("g_{velocity}_{west}.nmea"));
            // The time system given does not matter: NMEA is UTC.
            GnssFormat::Nmea.write(&path, &f, TimeSystem::Gpst).unwrap();
            let (back, warnings) = GnssFormat::Nmea.read(&path, None).unwrap();
            assert!(warnings.is_empty(), "{warnings:?}");
            check_positions(&f, &back, 1e-6, 1e-9, 5e-5);
            for (a, b) in f.iter().zip(&back) {
                assert_eq!((a.quality, a.satellites), (b.quality, b.satellites));
                assert!(near(a.position_sigma_neu, b.position_sigma_neu, 5e-5));
                match (a.velocity_ned, b.velocity_ned) {
                    (Some(v), Some(w)) => {
                        assert!(
                            (v.x - w.x).abs() < 1e-4 && (v.y - w.y).abs() < 1e-4,
                            "{v} {w}"
                        );
                        assert_eq!(w.z, 0.0);
                    }
                    (None, None) => {}
                    other => panic!("{other:?}"),
                }
            }
        }
    }
    let path = dir.path().join("one.nmea");
    GnssFormat::Nmea
        .write(&path, &fixes(1, T0 + 0.25, false, false), TimeSystem::Gpst)
        .unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.starts_with("$GNRMC,235942.25,A,3030.0000000,N,11418.0000000,E,,,260824,,,A*"),
        "{text}"
    );
}

#[test]
fn ubx_round_trips_to_its_integer_resolution() {
    let dir = tempfile::tempdir().unwrap();
    // Across a UTC midnight and the end of GPS week 2329 (Saturday 2024-08-31
    // 23:59:59.x GPST).
    let week_end = T0 + 5.0 * 86_400.0 - 2.05;
    for t0 in [T0 + 3.0, T0 + 86_400.0 + 18.0 - 2.05, week_end] {
        for (velocity, west) in [(false, false), (true, true), (true, false)] {
            let f = fixes(60, t0, velocity, west);
            let path = dir.path().join(format!("g_{velocity}_{west}.ubx"));
            GnssFormat::Ubx.write(&path, &f, TimeSystem::Utc).unwrap();
            let (back, warnings) = GnssFormat::Ubx.read(&path, None).unwrap();
            assert!(warnings.is_empty(), "{warnings:?}");
            check_positions(&f, &back, 1e-6, 0.6e-7, 5e-4);
            for (a, b) in f.iter().zip(&back) {
                assert_eq!((a.quality, a.satellites), (b.quality, b.satellites));
                assert!(
                    near(a.position_sigma_neu, b.position_sigma_neu, 5e-4),
                    "{a:?} {b:?}"
                );
                match a.velocity_ned {
                    Some(v) => {
                        assert!(near(v, b.velocity_ned.unwrap(), 5e-4));
                        let s = b.velocity_sigma_neu.unwrap();
                        assert!((s.x - 0.05).abs() < 5e-4 && s.x == s.z, "{s}");
                    }
                    None => {
                        assert_eq!(b.velocity_ned, Some(Vector3::zeros()));
                        assert!(b.velocity_sigma_neu.unwrap().x > 99.0);
                    }
                }
            }
        }
    }
}

#[test]
fn gnss_writers_refuse_two_fixes_in_one_resolution_step() {
    let dir = tempfile::tempdir().unwrap();
    let mut f = fixes(3, T0, true, false);
    f[2].time_s = f[1].time_s + 1e-4;
    for format in [GnssFormat::RtklibPos, GnssFormat::Nmea, GnssFormat::Ubx] {
        let path = dir.path().join("g");
        let e = format
            .write(&path, &f, TimeSystem::Gpst)
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot write"), "{e}");
        assert!(!path.exists());
    }
    f[2].time_s = f[1].time_s;
    for format in [GnssFormat::GenericCsv, GnssFormat::KfGins] {
        assert!(
            format
                .write(Path::new("/nonexistent/g"), &f, TimeSystem::Gpst)
                .is_err()
        );
    }
}

#[test]
fn wheel_speed_and_baro_are_exact() {
    let dir = tempfile::tempdir().unwrap();
    for with_sigma in [false, true] {
        let wheel: Vec<WheelSpeedSample> = (0..40)
            .map(|k| WheelSpeedSample {
                time_s: T0 + 0.02 * k as f64,
                speed_mps: 10.0 + 0.1 * k as f64 - 1.0 / 3.0,
                sigma_mps: (with_sigma && k != 5).then_some(0.05 + 1e-3 * k as f64),
            })
            .collect();
        let path = dir.path().join(format!("w_{with_sigma}.csv"));
        assert_eq!(
            WheelSpeedFormat::GenericCsv.write(&path, &wheel).unwrap(),
            vec![path.clone()]
        );
        let (back, _) = WheelSpeedFormat::GenericCsv.read(&path).unwrap();
        assert_eq!(back, wheel);
        let baro: Vec<BaroSample> = (0..40)
            .map(|k| BaroSample {
                time_s: T0 + 0.04 * k as f64,
                height_m: 52.5 - 0.01 * k as f64,
                sigma_m: (with_sigma && k != 7).then_some(0.5),
            })
            .collect();
        let path = dir.path().join(format!("b_{with_sigma}.csv"));
        BaroFormat::GenericCsv.write(&path, &baro).unwrap();
        let (back, _) = BaroFormat::GenericCsv.read(&path).unwrap();
        assert_eq!(back, baro);
    }
}

/// A `.pos` declaring UTC in its column header is read as UTC + the leap
/// seconds; one declaring JST is refused; GPST and no header read as GPST.
#[test]
fn pos_time_system_comes_from_the_column_header() {
    let row = "2024/08/26 23:59:42.250 30.5 114.3 20.0 1 12 0.02 0.02 0.04 0 0 0 0 0\n";
    let read = |header: &str| {
        GnssFormat::RtklibPos.read_from(
            format!("{header}{row}").as_bytes(),
            Path::new("g.pos"),
            None,
        )
    };
    let columns = "  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)\n";
    let gpst = T0 - 18.0 + 0.25;
    assert_eq!(read("").unwrap().0[0].time_s, gpst);
    assert_eq!(
        read(&format!("%  GPST {columns}")).unwrap().0[0].time_s,
        gpst
    );
    assert_eq!(
        read(&format!("% program : UTC\n%  UTC {columns}"))
            .unwrap()
            .0[0]
            .time_s,
        T0 + 0.25
    );
    let e = read(&format!("%\n%  JST {columns}"))
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("g.pos:2: column `(header)`: JST"), "{e}");
}
