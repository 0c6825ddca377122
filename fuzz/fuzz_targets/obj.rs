//! cargo-fuzz target: laparo_core::mesh::read_obj must return Ok or Err, never panic, on any bytes.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.obj");
    std::fs::write(&p, data).unwrap();
    let p = p.as_path();
    let _ = laparo_core::mesh::read_obj(p);
});
