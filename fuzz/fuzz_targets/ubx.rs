#![no_main]
//! cargo-fuzz target: `aidnav::fuzzing::run("ubx", …)`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = aidnav::fuzzing::run("ubx", data);
});
