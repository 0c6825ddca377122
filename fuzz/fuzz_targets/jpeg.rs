//! cargo-fuzz target: laparo_core::io::read_image must return Ok or Err, never panic, on any bytes.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.jpg");
    std::fs::write(&p, data).unwrap();
    let p = p.as_path();
    let _ = laparo_core::io::read_image(p);
});
