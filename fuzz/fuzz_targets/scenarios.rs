#![no_main]
//! cargo-fuzz target: `aidnav::fuzzing::run("scenarios", …)`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = aidnav::fuzzing::run("scenarios", data);
});
