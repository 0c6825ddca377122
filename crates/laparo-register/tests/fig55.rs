//! Fig. 5.5 in 2D: the body measurement (connected components, gap) against hand-built layouts, the
//! kinematic warm start against hand-computed velocities, the forward tear probe of both materials, and
//! the acceptance numbers of cases (a), (c) and (d).
use laparo_mpm::Vector;
use laparo_register::fig55::*;
use laparo_register::optimize::OptimizerConfig;

/// Two 10 × 10 blocks at spacing h, the second shifted by `gap` beyond the first's last column.
fn two_blocks(h: f64, gap: f64) -> Vec<Vector<2>> {
    let mut v = Vec::new();
    for i in 0..10 {
        for j in 0..10 {
            v.push(Vector::<2>::new(i as f64 * h, j as f64 * h));
            v.push(Vector::<2>::new(9.0 * h + gap + i as f64 * h, j as f64 * h));
        }
    }
    v
}

#[test]
fn components_link_at_one_and_a_half_cells() {
    let dx = 1.0 / 120.0;
    let h = dx / 2.0;
    // a gap of 1.49 Δx links the blocks, 1.51 Δx separates them (link = 1.5 Δx)
    let (_, s) = components(&two_blocks(h, 1.49 * dx), LINK_DX * dx);
    assert_eq!(s, vec![200]);
    let (label, mut s) = components(&two_blocks(h, 1.51 * dx), LINK_DX * dx);
    s.sort();
    assert_eq!(s, vec![100, 100]);
    // blocks are labelled by side: even indices left, odd right
    assert!(label.iter().step_by(2).all(|&l| l == label[0]));
    assert!(label.iter().skip(1).step_by(2).all(|&l| l == label[1]) && label[0] != label[1]);
    // a lattice stretched 2.9× along x (spacing 1.45 Δx) stays one body
    let line: Vec<Vector<2>> = (0..50).map(|i| Vector::<2>::new(i as f64 * 1.45 * dx, 0.0)).collect();
    assert_eq!(components(&line, LINK_DX * dx).1, vec![50]);
}

#[test]
fn fig55_a_stretch_acceptance() {
    let (m, _, _) = run_case(Case::Stretch, &OptimizerConfig { iterations: 50, ..Default::default() }).unwrap();
    eprintln!("{m:?}");
    let w = m.width_ratio.unwrap();
    assert!(m.residual_dx[1] < 0.1, "residual {} dx", m.residual_dx[1]);
    assert!((w - 1.0).abs() <= 0.02, "width {w} x target");
    assert!(m.mid_height_ratio <= 0.95, "mid-height ratio {}", m.mid_height_ratio);
    assert!(m.min_j > 0.2, "min J {}", m.min_j);
    assert_eq!(m.bodies.len(), 1, "bodies {:?}", m.bodies);
}

#[test]
fn kinematic_warm_start_is_the_nearest_lip_velocity() {
    let case = Case::Rupture;
    let setup = CaseSetup::for_case(case);
    let scene = square_scene_with(setup.material);
    let v = kinematic_warm_start(&scene, case, &setup).unwrap();
    // T Δt = 200 × 2e-4 = 0.04; RUPTURE_OPENING moves a left particle at height fraction s by
    // (−0.06, −0.03 s), a right one by (+0.06, −0.03 s); the lips' faces are columns 38 and 41 (KERF 1)
    let t = 0.04;
    let close = |a: Vector<2>, b: Vector<2>| (a - b).norm() < 1e-12;
    // top-left corner (a landmark, s = 1) and bottom of the left face (s = 0)
    assert!(close(v[idx(0, 79)], Vector::<2>::new(-0.06, -0.03) / t));
    assert!(close(v[idx(38, 0)], Vector::<2>::new(-0.06, 0.0) / t));
    // interior (10, 40): 28 spacings from the face column, 39 from the top edge → face particle (38, 40)
    assert!(close(v[idx(10, 40)], Vector::<2>::new(-0.06, -0.03 * 40.0 / 79.0) / t));
    // the kerf columns take their own side's face: (39, 5) ← (38, 5), (40, 5) ← (41, 5)
    assert!(close(v[idx(39, 5)], Vector::<2>::new(-0.06, -0.03 * 5.0 / 79.0) / t));
    assert!(close(v[idx(40, 5)], Vector::<2>::new(0.06, -0.03 * 5.0 / 79.0) / t));
    // right interior (70, 70): 9 spacings from the top edge, 29 from the face → top-edge particle (70, 79)
    assert!(close(v[idx(70, 70)], Vector::<2>::new(0.06, -0.03) / t));
}

#[test]
fn tear_probe_liver_stretches_soft_material_tears() {
    // a velocity jump of the lips' own opening speed (k = 1): the liver values keep one body, E 1 / ν 0.4
    // tears into two 39-column halves (0.4875 each) and the 2-column sliver of the kerf
    let liver = tear_probe(DIFFTAICHI_MATERIAL, &RUPTURE_OPENING, 1.0).unwrap();
    assert_eq!(liver.separation.bodies, vec![1.0], "gap {:?}", liver.separation.gap_dx);
    let soft = tear_probe(RUPTURE_MATERIAL, &RUPTURE_OPENING, 1.0).unwrap();
    let s = &soft.separation;
    eprintln!("bodies {:?} gap {:?} dx, min J {}", s.bodies, s.gap_dx, soft.min_j);
    assert!(ruptured(s), "bodies {:?} gap {:?}", s.bodies, s.gap_dx);
    assert_eq!(&soft.separation.bodies[..2], &[0.4875, 0.4875]);
}

fn rupture_acceptance(case: Case) -> CaseMetrics {
    let (m, _, _) = run_case(case, &OptimizerConfig { iterations: 30, ..Default::default() }).unwrap();
    let mut short = m.clone();
    short.curve_dx.clear();
    eprintln!("{short:?}");
    assert!(m.bodies.len() >= 2 && m.bodies[1] > 0.4, "bodies {:?}", m.bodies);
    assert!(m.gap_dx.unwrap() >= 2.0, "gap {:?} dx", m.gap_dx);
    m
}

#[test]
fn fig55_c_rupture_acceptance() {
    let m = rupture_acceptance(Case::Rupture);
    assert!(m.residual_dx[1] < 0.1, "residual {} dx", m.residual_dx[1]);
}

#[test]
fn fig55_d_rupture_stretch_acceptance() {
    let m = rupture_acceptance(Case::RuptureStretch);
    let w = m.width_ratio.unwrap();
    assert!(m.residual_dx[1] < 0.1, "residual {} dx", m.residual_dx[1]);
    assert!((w - 1.0).abs() <= 0.02, "width {w} x target");
    assert!(m.mid_height_ratio <= 0.95, "mid-height ratio {}", m.mid_height_ratio);
    assert!(m.min_j > 0.2, "min J {}", m.min_j);
}
