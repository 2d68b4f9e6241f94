#![no_main]
//! cargo-fuzz target: `aidnav::app::fuzzing::run("rtklib_tagged_imu", …)`.

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = aidnav::app::fuzzing::run("rtklib_tagged_imu", data);
});
