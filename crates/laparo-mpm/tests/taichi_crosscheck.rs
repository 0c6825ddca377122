//! laparo-mpm against DiffTaichi (f64) fixtures produced by `scripts/check_mpm_taichi.sh`:
//! same initial particles, material, Δt and grid; final positions after 200 steps within 1e-6 of a
//! cell width and ∂L/∂v₀ within 1e-4 relative of Taichi's autodiff.
use laparo_mpm::reference::TaichiFixture;

fn load(name: &str) -> Option<TaichiFixture> {
    let path = format!("{}/tests/fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
    match std::fs::read_to_string(&path) {
        Ok(s) => Some(serde_json::from_str(&s).expect("fixture parses")),
        Err(_) => {
            eprintln!("SKIP: {path} missing (run scripts/check_mpm_taichi.sh with UPDATE_FIXTURE=1)");
            None
        }
    }
}

#[test]
fn matches_difftaichi_2d() {
    let Some(fx) = load("taichi_small2d.json") else { return };
    assert_eq!(fx.steps, 200);
    let c = fx.compare::<2>().unwrap();
    eprintln!("{c:?}");
    assert!(c.max_position_diff_cells < 1e-6, "{c:?}");
    assert!(c.loss_rel_diff < 1e-9, "{c:?}");
    assert!(c.grad_rel_diff < 1e-4 && c.grad_max_rel_diff < 1e-4, "{c:?}");
}

#[test]
fn matches_difftaichi_3d() {
    let Some(fx) = load("taichi_small3d.json") else { return };
    let c = fx.compare::<3>().unwrap();
    eprintln!("{c:?}");
    assert!(c.max_position_diff_cells < 1e-6, "{c:?}");
    assert!(c.loss_rel_diff < 1e-9, "{c:?}");
    assert!(c.grad_rel_diff < 1e-4 && c.grad_max_rel_diff < 1e-4, "{c:?}");
}
