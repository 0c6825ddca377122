//! Long experiments (`cargo test --release -p laparo-register --test long -- --ignored --nocapture`):
//! the Fig. 5.5 acceptance figures and the P2ILF ridge-contour registration at 3 mm spacing.
use laparo_register::fig55::{run_case, Case};
use laparo_register::optimize::OptimizerConfig;

#[test]
#[ignore]
fn fig55_acceptance() {
    // (a): residual < 0.1 Δx, width within 2 % of the target, mid-width height reduced ≥ 5 %, min J > 0.2,
    // one body; (c): two bodies of > 40 % of the particles each, gap ≥ 2 Δx; (d): both. (c) and (d) fail
    // today (no rupture: see the README).
    let cfg = OptimizerConfig { iterations: 50, ..Default::default() };
    let mut fails = Vec::new();
    for case in Case::ALL {
        let (m, _, _) = run_case(case, &cfg).unwrap();
        eprintln!("{}", serde_json::to_string(&m).unwrap());
        let two = m.bodies.len() >= 2 && m.bodies[1] > 0.4 && m.gap_dx.unwrap_or(0.0) >= 2.0;
        let stretch = m.residual_dx[1] < 0.1
            && m.width_ratio.is_some_and(|w| (w - 1.0).abs() <= 0.02)
            && m.mid_height_ratio <= 0.95
            && m.min_j > 0.2;
        match case {
            Case::Stretch if !(stretch && m.bodies.len() == 1) => fails.push(format!("(a) {m:?}")),
            Case::Rupture if !two => fails.push(format!("(c) {m:?}")),
            Case::RuptureStretch if !(two && stretch) => fails.push(format!("(d) {m:?}")),
            _ => {}
        }
    }
    assert!(fails.is_empty(), "{fails:#?}");
}

#[test]
#[ignore]
fn p2ilf_ridge_registration_3mm() {
    use laparo_register::io::{read_p2ilf_contours, TargetSpec};
    use laparo_register::organ::OrganConfig;
    use laparo_register::pipeline::{run_job, Job};
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/meshes/p2ilf");
    if !dir.exists() {
        eprintln!("SKIP: {} absent", dir.display());
        return;
    }
    let organ = dir.join("patient2_1_3d-liver-model.obj");
    let mesh = laparo_core::mesh::read_mesh(&organ).unwrap();
    let mut groups = read_p2ilf_contours(&dir.join("patient2_1_3D-contours.json"), &mesh.vertices).unwrap();
    groups.retain(|g| g.name.starts_with("Ridge"));
    let all: Vec<_> = groups.iter().flat_map(|g| g.points.clone()).collect();
    let c = all.iter().sum::<laparo_mpm::Vector<3>>() / all.len() as f64;
    let field = |x: &laparo_mpm::Vector<3>| {
        let r = (x - c) / 60.0;
        laparo_mpm::Vector::<3>::new(
            (r[0] + 0.3).sin() + 0.5 * r[1],
            (1.3 * r[1] - 0.2).sin() - 0.4 * r[2],
            (0.7 * r[2] + 0.9 * r[0]).cos(),
        )
    };
    let m = all.iter().map(|x| field(x).norm()).fold(0.0, f64::max);
    let targets = groups
        .iter()
        .map(|g| TargetSpec::Points(g.points.iter().map(|p| p + field(p) * (10.0 / m)).collect()))
        .collect();
    let out = tempfile::tempdir().unwrap();
    let job = Job {
        organ,
        organ_config: OrganConfig { spacing_mm: 3.0, ..Default::default() },
        landmarks: groups,
        targets,
        region_weight: 0.0,
        optimizer: OptimizerConfig { iterations: 50, target_mean_distance: 0.5, ..Default::default() },
        tumour: None,
        overlay: None,
        out: out.path().to_path_buf(),
        resume: false,
        checkpoint_every: 10,
    };
    let r =
        run_job(&job, &mut |it| eprintln!("it {} mean {:.3} mm ({:.0} s)", it.iteration, it.mean_distance, it.seconds))
            .unwrap();
    eprintln!("{}", serde_json::to_string_pretty(&r).unwrap());
    assert!(r.mean_distance_mm[1] < 1.0, "mean landmark error {} mm", r.mean_distance_mm[1]);
}

/// How fast must the two halves of the Fig. 5.5 square be pulled apart for the MLS-MPM body to tear?
/// v₀ = the (c) book opening (each half ∓(LIP_BOTTOM + (LIP_TOP − LIP_BOTTOM) s, −LIP_UP s)/(T Δt),
/// a velocity jump across x = 0.5) times k; prints the bodies and the lip gaps after T steps.
#[test]
#[ignore]
fn fig55_rupture_threshold() {
    use laparo_register::fig55::*;
    let scene = square_scene();
    let x = &scene.positions;
    let (yb, yt) = (x[idx(0, 0)][1], x[idx(0, SIDE - 1)][1]);
    let t = scene.steps as f64 * scene.dt;
    let dx = scene.grid.dx;
    let mut split_at = None;
    for k in [1.0, 2.0, 4.0, 6.0, 8.0, 12.0] {
        let mut s = scene.clone();
        s.velocities = (0..x.len())
            .map(|p| {
                let sx = if p / SIDE < SIDE / 2 { -1.0 } else { 1.0 };
                let h = (x[p][1] - yb) / (yt - yb);
                laparo_mpm::Vector::<2>::new(sx * (LIP_BOTTOM + (LIP_TOP - LIP_BOTTOM) * h), LIP_UP * h) * (k / t)
            })
            .collect();
        let fin = laparo_mpm::simulate(&s).unwrap().final_state;
        let (_, mut sizes) = components(&fin.x, LINK_DX * dx);
        sizes.sort_by(|a, b| b.cmp(a));
        let (l, r) = (idx(SIDE / 2 - 1, SIDE - 1), idx(SIDE / 2, SIDE - 1));
        let (lb, rb) = (idx(SIDE / 2 - 1, 0), idx(SIDE / 2, 0));
        eprintln!(
            "k {k}: jump {:.1} units/s at the top, bodies {:?}, lip gap top {:.2} Δx (target {:.1}), bottom {:.2} Δx (target {:.1})",
            2.0 * k * LIP_TOP / t,
            &sizes[..sizes.len().min(4)],
            (fin.x[r][0] - fin.x[l][0]) / dx,
            (2.0 * LIP_TOP + dx / 2.0) / dx,
            (fin.x[rb][0] - fin.x[lb][0]) / dx,
            (2.0 * LIP_BOTTOM + dx / 2.0) / dx
        );
        if split_at.is_none() && sizes.len() >= 2 && sizes[1] as f64 > 0.4 * x.len() as f64 {
            split_at = Some(k);
        }
    }
    // measured 2026-12-03: one body up to k = 8, two halves at k = 12
    assert_eq!(split_at, Some(12.0));
}
