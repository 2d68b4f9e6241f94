#![no_main]
//! cargo-fuzz target: `aidnav::app::fuzzing::run("generic_baro", …)`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = aidnav::app::fuzzing::run("generic_baro", data);
});
