#![no_main]
//! cargo-fuzz target: `aidnav::fuzzing::run("nmea", …)`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = aidnav::fuzzing::run("nmea", data);
});
