//! cargo-fuzz target: laparo_core::mesh::read_vtk_mixed must return Ok or Err, never panic, on any bytes.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.vtk");
    std::fs::write(&p, data).unwrap();
    let p = p.as_path();
    let _ = laparo_core::mesh::read_vtk_mixed(p);
});
