//! GT preparation through files, as `laparo depth reproject` runs it: a 16-bit PNG depth in mm
//! from a "depth sensor", JSON calibration, output written and read back in another unit.
use laparo_core::{DepthUnit, Image};
use laparo_depth::reproject::{
    extrinsics_from_json, intrinsics_from_json, reproject_depth, ReprojectParams, TargetCamera,
};

#[test]
fn png16_mm_sensor_to_npy_m_laparoscope() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (120usize, 90usize);
    // Fronto-parallel wall at 200 mm with a 20 mm-high box at 150 mm in the middle.
    let mut mm = Image::filled(w, h, 1, 200u16);
    for y in 30..60 {
        for x in 45..75 {
            mm.set(x, y, 0, 150);
        }
    }
    let dp = dir.path().join("sensor.png");
    laparo_core::io::write_png16(&dp, &mm).unwrap();
    let sensor_json: serde_json::Value =
        serde_json::from_str(r#"{"fx": 150, "fy": 150, "cx": 59.5, "cy": 44.5, "width": 120, "height": 90}"#).unwrap();
    let lap_json: serde_json::Value =
        serde_json::from_str(r#"{"K": [[150,0,59.5],[0,150,44.5],[0,0,1]], "width": 120, "height": 90}"#).unwrap();
    // Laparoscope 10 mm closer to the scene than the sensor: P_L = P_DS + (0, 0, -10 mm).
    let ext_json: serde_json::Value =
        serde_json::from_str(r#"{"R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0, 0, -10], "unit": "mm"}"#).unwrap();
    let ks = intrinsics_from_json(&sensor_json, "sensor.json").unwrap();
    let kl = intrinsics_from_json(&lap_json, "lap.json").unwrap();
    let t = extrinsics_from_json(&ext_json, DepthUnit::M, "ext.json").unwrap();
    let depth = laparo_core::io::read_depth(&dp, DepthUnit::Mm).unwrap();
    let (out, st) = reproject_depth(
        &depth,
        &ks,
        &t,
        &TargetCamera { intrinsics: kl, distortion: None },
        None,
        &ReprojectParams::default(),
    )
    .unwrap();
    let op = dir.path().join("gt.npy");
    laparo_core::io::write_depth(&op, &out).unwrap();
    let back = laparo_core::io::read_depth(&op, DepthUnit::M).unwrap();
    assert!(st.triangles_dropped_jump > 0);
    // Centre pixel sees the box: 150 − 10 mm; elsewhere the wall: 200 − 10 mm. The nearer view
    // magnifies the scene, so even the corners are seen by the sensor.
    assert!((back.get(60, 45) - 0.140).abs() < 1e-12, "{}", back.get(60, 45));
    assert!((back.get(20, 15) - 0.190).abs() < 1e-12, "{}", back.get(20, 15));
    assert!((back.get(0, 0) - 0.190).abs() < 1e-12, "{}", back.get(0, 0));
    // The box edge is seen by both cameras (the nearer L sees past it no further than DS),
    // so only the rim pixels between dropped step triangles may stay empty.
    let nan = back.data.iter().filter(|v| v.is_nan()).count();
    assert!(nan < w * h / 50, "{nan} empty pixels");
    // Every valid value is one of the two surfaces (no interpolation across the step).
    for v in back.data.iter().filter(|v| v.is_finite()) {
        assert!((v - 0.14).abs() < 1e-12 || (v - 0.19).abs() < 1e-12, "{v}");
    }
}
