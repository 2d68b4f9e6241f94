//! The fuzz targets on stable, in the default suite: every seed, corpus and
//! crash file under `fuzz/` replayed through `aidnav_app::fuzzing` (a crash file
//! the fuzzer once found stays a regression test), and proptest feeding
//! arbitrary bytes to every reader and loader. A panic fails the test.

use std::path::{Path, PathBuf};

use aidnav_app::fuzzing::{TARGETS, run};
use proptest::prelude::*;

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz")
}

/// The files of `fuzz/<kind>/<target>/`, sorted (none when absent).
fn files(kind: &str, target: &str) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(fuzz_dir().join(kind).join(target)) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
}

#[test]
fn every_target_has_seeds_and_replays_its_corpus_and_crashes() {
    for (name, _) in TARGETS {
        let corpus = files("corpus", name);
        assert!(
            corpus.iter().any(|p| p
                .file_name()
                .is_some_and(|f| f.to_string_lossy().starts_with("seed-"))),
            "fuzz/corpus/{name} has no seed (scripts/fuzz-seeds.py makes them)"
        );
        for path in corpus.iter().chain(&files("artifacts", name)) {
            let data = std::fs::read(path).unwrap();
            // A panic here names the file through the test's output.
            eprintln!("replaying {}", path.display());
            run(name, &data).unwrap();
        }
    }
}

#[test]
fn the_tagged_imu_cut_is_the_first_four_bytes() {
    let mut data = 3u32.to_le_bytes().to_vec();
    data.extend(b"abcdef");
    assert_eq!(
        aidnav_app::fuzzing::split(&data),
        (&b"abc"[..], &b"def"[..])
    );
    let mut long = u32::MAX.to_le_bytes().to_vec();
    long.extend(b"xy");
    assert_eq!(aidnav_app::fuzzing::split(&long), (&b"xy"[..], &b""[..]));
    assert_eq!(aidnav_app::fuzzing::split(b"ab"), (&b""[..], &b""[..]));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Arbitrary bytes: every target returns.
    #[test]
    fn arbitrary_bytes_never_panic(data in proptest::collection::vec(any::<u8>(), 0..2048)) {
        for (name, _) in TARGETS {
            run(name, &data).unwrap();
        }
    }

    /// Arbitrary text made of the readers' own alphabet (digits, separators,
    /// signs, exponents, newlines): closer to valid rows than random bytes.
    #[test]
    fn arbitrary_numeric_text_never_panics(text in "[0-9eE+\\-., \t\r\n/:$*A-Z=\\[\\]\"]{0,1500}") {
        for (name, _) in TARGETS {
            run(name, text.as_bytes()).unwrap();
        }
    }

    /// UBX frames with valid checksums (mostly NAV-PVT, arbitrary
    /// payloads of any length) between junk bytes and false syncs: what
    /// random bytes almost never reach — the NAV-PVT decoder, the week
    /// derivation and the value checks.
    #[test]
    fn checksummed_ubx_frames_never_panic(
        frames in proptest::collection::vec(
            (any::<bool>(), proptest::collection::vec(any::<u8>(), 0..120), proptest::collection::vec(any::<u8>(), 0..8)),
            0..24,
        )
    ) {
        use aidnav_io::ubx::frame::encode;
        let mut log = Vec::new();
        for (pvt, payload, junk) in &frames {
            let (class, id) = if *pvt { (0x01, 0x07) } else { (0x02, 0x15) };
            log.extend(encode(class, id, payload));
            log.extend(junk);
            log.extend([0xB5, 0x62]);
        }
        run("ubx", &log).unwrap();
    }

    /// A generic GNSS CSV with a header of known column names — one of the
    /// valid layouts, or any subset, order and repeats — and cells drawn
    /// from numbers, dates, words and blanks: past the header checks into
    /// every value path.
    #[test]
    fn generic_gnss_rows_never_panic(
        layout in 0..5usize,
        columns in proptest::collection::vec(0..aidnav_io::generic_gnss::KNOWN_COLUMNS.len(), 1..10),
        rows in proptest::collection::vec(
            proptest::collection::vec("(-?[0-9]{1,10}(\\.[0-9]{0,6})?|20[0-9]{2}-[01][0-9]-[0-3][0-9][T ][0-2][0-9]:[0-5][0-9]:[0-6][0-9](\\.[0-9]{1,3})?(Z|[+-][0-9]{2}:?[0-9]{2})?|fixed|float|NaN|inf|)", 0..10),
            0..12,
        )
    ) {
        let names = aidnav_io::generic_gnss::KNOWN_COLUMNS;
        let header = match layout {
            0 => "gpst_s,lat_deg,lon_deg,height_m,sigma_n_m,sigma_e_m,sigma_u_m,vel_n_mps,vel_e_mps,vel_d_mps,sigma_vel_mps".to_string(),
            1 => "utc,lat_deg,lon_deg,height_msl_m,geoid_sep_m,sigma_h_m,sigma_v_m,speed_mps,course_deg,quality".to_string(),
            2 => "gps_week,tow_s,ecef_x_m,ecef_y_m,ecef_z_m,sigma_h_m,sigma_v_m,speed_mps,course_deg,vertical_speed_mps".to_string(),
            3 => "gpst_s,lat_deg,lon_deg,height_m,quality,satellites".to_string(),
            _ => columns.iter().map(|&c| names[c]).collect::<Vec<_>>().join(","),
        };
        let mut text = header + "\n";
        for row in &rows {
            text += &(row.join(",") + "\n");
        }
        run("generic_gnss", text.as_bytes()).unwrap();
    }
}
