//! The fuzz targets on stable, in the default suite: every seed, corpus and
//! crash file under `fuzz/` replayed through `aidnav::fuzzing` (a crash file
//! the fuzzer once found stays a regression test), and proptest feeding
//! arbitrary bytes to every reader and loader. A panic fails the test.

use std::path::{Path, PathBuf};

use aidnav::fuzzing::{TARGETS, run};
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
    assert_eq!(aidnav::fuzzing::split(&data), (&b"abc"[..], &b"def"[..]));
    let mut long = u32::MAX.to_le_bytes().to_vec();
    long.extend(b"xy");
    assert_eq!(aidnav::fuzzing::split(&long), (&b"xy"[..], &b""[..]));
    assert_eq!(aidnav::fuzzing::split(b"ab"), (&b""[..], &b""[..]));
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
}
