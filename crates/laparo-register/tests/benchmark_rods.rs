//! RODS-MPM on a tetrahedral box through the benchmark adapter: landmarks pulled towards targets get
//! closer, nodes near them follow, nodes outside the region of interest stay.
use laparo_register::benchmark::rods::{run_rods, RodsProblem, SideGroup};
use laparo_register::optimize::OptimizerConfig;
use laparo_register::organ::{OrganConfig, Roi};
use nalgebra::Vector3;

/// A one-field problem with no fixed node.
fn free_problem<'a>(
    nodes: &'a [Vector3<f64>],
    tets: &'a [[usize; 4]],
    side: &'a [u8],
    groups: Vec<SideGroup>,
    organ: OrganConfig,
    optimizer: OptimizerConfig,
) -> RodsProblem<'a> {
    RodsProblem {
        nodes,
        tets,
        node_side: side,
        fixed_nodes: &[],
        groups,
        organ,
        optimizer,
        crack: None,
        landmark_offsets: false,
    }
}

/// A box of nx×ny×nz cubes of edge h (mm), 6 tetrahedra per cube (Kuhn split).
fn box_mesh(nx: usize, ny: usize, nz: usize, h: f64) -> (Vec<Vector3<f64>>, Vec<[usize; 4]>) {
    let id = |i: usize, j: usize, k: usize| (k * (ny + 1) + j) * (nx + 1) + i;
    let mut v = Vec::new();
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                v.push(Vector3::new(i as f64, j as f64, k as f64) * h);
            }
        }
    }
    let mut t = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let c = |a: usize, b: usize, d: usize| id(i + a, j + b, k + d);
                let (v0, v7) = (c(0, 0, 0), c(1, 1, 1));
                for p in [[1usize, 0, 0], [0, 1, 0], [0, 0, 1]] {
                    for q in [[1usize, 0, 0], [0, 1, 0], [0, 0, 1]] {
                        if p == q {
                            continue;
                        }
                        let a = c(p[0], p[1], p[2]);
                        let b = c(p[0] + q[0], p[1] + q[1], p[2] + q[2]);
                        t.push([v0, a, b, v7]);
                    }
                }
            }
        }
    }
    (v, t)
}

#[test]
fn landmarks_pull_the_box_and_the_far_end_stays() {
    let (nodes, tets) = box_mesh(8, 4, 4, 5.0); // 40 × 20 × 20 mm
    let side = vec![0u8; nodes.len()];
    // four landmarks on the top face near x = 5 mm, pulled 3 mm up
    let src: Vec<Vector3<f64>> =
        [(5.0, 5.0), (5.0, 15.0), (10.0, 5.0), (10.0, 15.0)].iter().map(|&(x, y)| Vector3::new(x, y, 20.0)).collect();
    let groups: Vec<SideGroup> = src
        .iter()
        .enumerate()
        .map(|(i, s)| SideGroup {
            name: format!("lm{i}"),
            sources: vec![(*s, 0)],
            target: vec![s + Vector3::new(-1.0, 0.0, 3.0), s + Vector3::new(1.0, 0.0, 3.0)],
        })
        .collect();
    // a region of interest: a ball of 28 mm around the landmarks, its boundary particles fixed
    let roi = Some(Roi::Ball { center: [7.5, 10.0, 20.0], radius_mm: 28.0 });
    let organ = OrganConfig { spacing_mm: 2.5, steps: 60, roi, ..Default::default() };
    let optimizer = OptimizerConfig { iterations: 15, ..Default::default() };
    let problem = free_problem(&nodes, &tets, &side, groups.clone(), organ.clone(), optimizer.clone());
    let out = run_rods(&problem, &mut |_| {}).unwrap();
    assert_eq!(out.nodes.len(), nodes.len());
    assert!(out.particles > 100);
    // within a memory budget of a third of every step's checkpoints the adjoint recomputes segments: the
    // same registration bit for bit, and a note says so
    let full = out.particles as f64 * 60.0 * laparo_register::organ::CHECKPOINT_BYTES_PER_PARTICLE_STEP;
    let tight = OrganConfig { memory_limit_bytes: Some(full / 3.0), ..organ };
    let seg = run_rods(&free_problem(&nodes, &tets, &side, groups, tight, optimizer), &mut |_| {}).unwrap();
    assert_eq!(seg.nodes, out.nodes);
    assert_eq!(seg.landmark_distance_mm, out.landmark_distance_mm);
    assert!(seg.notes.iter().any(|n| n.contains("checkpoints every")), "{:?}", seg.notes);
    assert!(!out.notes.iter().any(|n| n.contains("checkpoints every")), "{:?}", out.notes);
    let [before, after] = out.landmark_distance_mm;
    assert!((before - 3.0).abs() < 0.6, "landmark particles start ≈3 mm from their targets: {before}");
    assert!(after < 0.5 * before, "registration halves the landmark distance: {before} → {after}");
    // the top node at (5, 10, 20) moved up; the far bottom corner did not move much
    let near = nodes.iter().position(|p| (p - Vector3::new(5.0, 10.0, 20.0)).norm() < 1e-9).unwrap();
    let far = nodes.iter().position(|p| (p - Vector3::new(40.0, 0.0, 0.0)).norm() < 1e-9).unwrap();
    let up = out.nodes[near][2] - nodes[near][2];
    assert!(up > 1.0, "the node among the landmarks follows them: Δz = {up}");
    assert_eq!(out.nodes[far], nodes[far], "outside the region of interest nodes keep their rest position");
    // a node inside the ROI, near its fixed boundary, moves much less than the pulled region
    let edge = nodes.iter().position(|p| (p - Vector3::new(30.0, 10.0, 10.0)).norm() < 1e-9).unwrap();
    let edge_move = (out.nodes[edge] - nodes[edge]).norm();
    assert!(edge_move < 0.3 * up, "near the fixed ROI boundary: {edge_move} vs {up}");
}

/// With Δt from the CFL condition (Δt ∝ 1/√E) nothing but E sets a time scale, so scaling E by f and the
/// optimiser's velocities by √f is the same motion: the registered nodes must not depend on E (this is why
/// the Fig. 5.9 E sweep holds Δt fixed), and at a fixed Δt they must.
#[test]
fn the_registered_shape_is_invariant_to_e_under_the_cfl_step_and_not_at_a_fixed_step() {
    let (nodes, tets) = box_mesh(4, 2, 2, 5.0); // 20 × 10 × 10 mm
    let side = vec![0u8; nodes.len()];
    let groups = vec![SideGroup {
        name: "top".into(),
        sources: vec![(Vector3::new(5.0, 5.0, 10.0), 0), (Vector3::new(10.0, 5.0, 10.0), 0)],
        target: vec![Vector3::new(4.0, 5.0, 12.0), Vector3::new(11.0, 5.0, 12.0)],
    }];
    let run = |youngs_modulus_kpa: f64, dt_s: Option<f64>| {
        let organ = OrganConfig { spacing_mm: 2.5, steps: 30, youngs_modulus_kpa, dt_s, ..Default::default() };
        let optimizer = OptimizerConfig { iterations: 4, ..Default::default() };
        let problem = RodsProblem {
            nodes: &nodes,
            tets: &tets,
            node_side: &side,
            fixed_nodes: &[],
            groups: groups.clone(),
            organ,
            optimizer,
            crack: None,
            landmark_offsets: false,
        };
        run_rods(&problem, &mut |_| {}).unwrap()
    };
    let soft = run(4.1, None);
    let stiff = run(4.1 * 9.0, None);
    let moved = soft.nodes.iter().zip(&nodes).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(moved > 0.3, "the registration moves the box: {moved} mm");
    let diff = soft.nodes.iter().zip(&stiff.nodes).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(diff < 1e-9 * moved.max(1.0), "E × 9 under the CFL step: largest node difference {diff} mm");
    // the same two moduli at one Δt (the stiff one's CFL step) give different shapes
    let dt =
        OrganConfig { spacing_mm: 2.5, youngs_modulus_kpa: 4.1 * 9.0, ..Default::default() }.time_step_s().unwrap();
    let soft_fixed = run(4.1, Some(dt));
    let diff = soft_fixed.nodes.iter().zip(&stiff.nodes).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(diff > 1e-3, "at a fixed Δt E matters: largest node difference {diff} mm");
}

/// The ground truth's fixed nodes hold RODS-MPM's particles too: with the far end fixed and no region of
/// interest, the far end stays at rest while the landmarks are still reached; without it the free box drifts.
#[test]
fn fixed_nodes_hold_their_particles() {
    let (nodes, tets) = box_mesh(8, 2, 2, 5.0); // 40 × 10 × 10 mm
    let side = vec![0u8; nodes.len()];
    let fixed: Vec<usize> = (0..nodes.len()).filter(|&i| nodes[i][0] >= 30.0 - 1e-9).collect();
    let groups = vec![SideGroup {
        name: "top".into(),
        sources: vec![(Vector3::new(5.0, 5.0, 10.0), 0), (Vector3::new(10.0, 5.0, 10.0), 0)],
        target: vec![Vector3::new(4.0, 5.0, 13.0), Vector3::new(11.0, 5.0, 13.0)],
    }];
    let run = |fixed_nodes: &[usize]| {
        let organ = OrganConfig { spacing_mm: 2.5, steps: 40, ..Default::default() };
        let optimizer = OptimizerConfig { iterations: 8, ..Default::default() };
        let problem = RodsProblem {
            nodes: &nodes,
            tets: &tets,
            node_side: &side,
            fixed_nodes,
            groups: groups.clone(),
            organ,
            optimizer,
            crack: None,
            landmark_offsets: false,
        };
        run_rods(&problem, &mut |_| {}).unwrap()
    };
    let held = run(&fixed);
    assert!(held.notes.iter().any(|n| n.contains("particles held in the fixed region")), "{:?}", held.notes);
    let [before, after] = held.landmark_distance_mm;
    assert!(after < 0.6 * before, "the landmarks are still reached: {before} → {after}");
    let far = nodes.iter().position(|p| (p - Vector3::new(40.0, 10.0, 10.0)).norm() < 1e-9).unwrap();
    assert!((held.nodes[far] - nodes[far]).norm() < 1e-9, "a node inside the fixed region stays at rest");
    let free = run(&[]);
    let drift = (free.nodes[far] - nodes[far]).norm();
    assert!(drift > 1e-3, "without the fixed region the far end moves: {drift} mm");
    // a bad fixed node is named
    let problem = RodsProblem {
        nodes: &nodes,
        tets: &tets,
        node_side: &side,
        fixed_nodes: &[nodes.len()],
        groups: groups.clone(),
        organ: OrganConfig { spacing_mm: 2.5, steps: 40, ..Default::default() },
        optimizer: OptimizerConfig::default(),
        crack: None,
        landmark_offsets: false,
    };
    let err = run_rods(&problem, &mut |_| {}).unwrap_err().to_string();
    assert!(err.contains("fixed nodes"), "{err}");
}

/// The ballistic oracle (v₀ = u_GT / (T Δt)) on a ground truth that is a rigid translation: a stress-free
/// motion MLS-MPM carries exactly, so every node lands on its ground-truth position to round-off; on a
/// ground truth that stretches the box it does not (elasticity pulls back), which is what the oracle
/// measures. The dense oracle on the translation gets its landmarks closer than the ballistic guess on
/// the stretch. A ground truth of the wrong length is refused.
#[test]
fn rods_oracles_carry_a_rigid_translation_exactly() {
    use laparo_register::benchmark::rods::{run_rods_oracle, OracleMode};
    let (nodes, tets) = box_mesh(4, 3, 3, 5.0); // 20 × 15 × 15 mm
    let side = vec![0u8; nodes.len()];
    let shift = Vector3::new(1.5, -0.8, 0.6);
    let truth: Vec<Vector3<f64>> = nodes.iter().map(|p| p + shift).collect();
    let groups = vec![SideGroup {
        name: "lm".into(),
        sources: vec![(Vector3::new(10.0, 7.5, 15.0), 0)],
        target: vec![Vector3::new(10.0, 7.5, 15.0) + shift],
    }];
    let organ = OrganConfig { spacing_mm: 2.5, steps: 40, ..Default::default() };
    let optimizer = OptimizerConfig { iterations: 5, ..Default::default() };
    let problem = free_problem(&nodes, &tets, &side, groups, organ, optimizer);
    let out = run_rods_oracle(&problem, &truth, OracleMode::Ballistic, 0.0).unwrap();
    let err = out.nodes.iter().zip(&truth).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(err < 1e-9, "a rigid translation is carried exactly: max node error {err} mm");
    assert!(out.landmark_distance_mm[1] < 1e-9);
    // a stretch along x (10 %): the ballistic guess falls short of it
    let stretch: Vec<Vector3<f64>> = nodes.iter().map(|p| p + Vector3::new(0.1 * (p[0] - 10.0), 0.0, 0.0)).collect();
    let s = run_rods_oracle(&problem, &stretch, OracleMode::Ballistic, 0.0).unwrap();
    let serr = s.nodes.iter().zip(&stretch).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(serr > 1e-3, "elasticity resists the stretch: max node error {serr} mm");
    let d = run_rods_oracle(&problem, &truth, OracleMode::Dense, 0.0).unwrap();
    assert!(d.nodes.iter().zip(&truth).all(|(a, b)| (a - b).norm() < 0.5), "dense targets follow the translation");
    assert!(run_rods_oracle(&problem, &truth[1..], OracleMode::Ballistic, 0.0).is_err());
    // a kerf needs a crack: this box has none, and the error names the parameter
    let Err(e) = run_rods_oracle(&problem, &truth, OracleMode::Ballistic, 5.0) else { panic!("kerf without a crack") };
    assert!(e.to_string().contains("kerf_mm"), "{e}");
}

/// A box split through x = 10 mm (crack nodes duplicated: side 1 left, side 2 right) whose ground truth
/// translates the two halves 1.5 mm apart. With the two-field grid along the crack plane the ballistic
/// oracle carries the opening exactly (every node to round-off, both lips included); the one-field grid
/// of the thesis averages the lips' velocities on the nodes they share and cannot.
#[test]
fn two_field_grid_opens_a_zero_thickness_cut_exactly() {
    use laparo_register::benchmark::rods::{run_rods_oracle, CrackSurface, OracleMode};
    let (mut nodes, mut tets) = box_mesh(4, 3, 3, 5.0); // 20 × 15 × 15 mm
    let mut side = vec![0u8; nodes.len()];
    let on_crack: Vec<usize> = (0..nodes.len()).filter(|&i| (nodes[i][0] - 10.0).abs() < 1e-9).collect();
    let mut copy = std::collections::HashMap::new();
    for &i in &on_crack {
        side[i] = 1;
        copy.insert(i, nodes.len());
        nodes.push(nodes[i]);
        side.push(2);
    }
    for t in tets.iter_mut() {
        let cx = t.iter().map(|&i| nodes[i][0]).sum::<f64>() / 4.0;
        if cx > 10.0 {
            for i in t.iter_mut() {
                if let Some(&j) = copy.get(i) {
                    *i = j;
                }
            }
        }
    }
    let a = 0.75;
    let truth: Vec<Vector3<f64>> = (0..nodes.len())
        .map(|i| {
            let right = nodes[i][0] > 10.0 + 1e-9 || side[i] == 2;
            nodes[i] + Vector3::new(if right { a } else { -a }, 0.0, 0.0)
        })
        .collect();
    let groups = vec![SideGroup {
        name: "lm".into(),
        sources: vec![(Vector3::new(15.0, 7.5, 15.0), 0)],
        target: vec![Vector3::new(15.0 + a, 7.5, 15.0)],
    }];
    let crack = CrackSurface {
        vertices: vec![
            Vector3::new(10.0, -1.0, -1.0),
            Vector3::new(10.0, 16.0, -1.0),
            Vector3::new(10.0, 16.0, 16.0),
            Vector3::new(10.0, -1.0, 16.0),
        ],
        faces: vec![[0, 1, 2], [0, 2, 3]],
        band_mm: None,
    };
    let problem = |crack: Option<CrackSurface>| RodsProblem {
        nodes: &nodes,
        tets: &tets,
        node_side: &side,
        fixed_nodes: &[],
        groups: groups.clone(),
        organ: OrganConfig { spacing_mm: 2.5, steps: 40, ..Default::default() },
        optimizer: OptimizerConfig::default(),
        crack,
        landmark_offsets: false,
    };
    let max_err = |out: &laparo_register::benchmark::rods::RodsOutput| {
        out.nodes.iter().zip(&truth).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max)
    };
    let two = run_rods_oracle(&problem(Some(crack.clone())), &truth, OracleMode::Ballistic, 0.0).unwrap();
    assert!(two.notes.iter().any(|n| n.starts_with("two-field grid")), "{:?}", two.notes);
    assert!(max_err(&two) < 1e-9, "two-field: max node error {} mm", max_err(&two));
    let one = run_rods_oracle(&problem(None), &truth, OracleMode::Ballistic, 0.0).unwrap();
    assert!(max_err(&one) > 0.1 * a, "one-field: max node error {} mm", max_err(&one));
    // the true crack of the split mesh: the 3 × 3 squares of x = 10 mm, two triangles each, normals +x
    let found = laparo_register::benchmark::rods::true_crack(&nodes, &tets, &side);
    assert_eq!(found.faces.len(), 18);
    for f in &found.faces {
        let [p, q, r] = f.map(|i| found.vertices[i]);
        let n = (q - p).cross(&(r - p)).normalize();
        assert!((n - Vector3::x()).norm() < 1e-12 && (p[0] - 10.0).abs() < 1e-12, "face {f:?}: normal {n:?}");
    }
    let exact = run_rods_oracle(&problem(Some(found)), &truth, OracleMode::Ballistic, 0.0).unwrap();
    assert!(max_err(&exact) < 1e-9, "two-field on the true crack: {} mm", max_err(&exact));
    // a crack face that names a missing vertex is refused
    let bad = CrackSurface { faces: vec![[0, 1, 7]], ..crack };
    let err = run_rods_oracle(&problem(Some(bad)), &truth, OracleMode::Ballistic, 0.0).unwrap_err().to_string();
    assert!(err.contains("crack surface"), "{err}");
}

/// Crack sides by hand on the square crack z = 0, x, y ∈ [0, 10] mm (normal +z).
#[test]
fn crack_sides_by_hand() {
    use laparo_register::benchmark::rods::{crack_sides, CrackSurface};
    let crack = CrackSurface {
        vertices: vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(10.0, 0.0, 0.0),
            Vector3::new(10.0, 10.0, 0.0),
            Vector3::new(0.0, 10.0, 0.0),
        ],
        faces: vec![[0, 1, 2], [0, 2, 3]],
        band_mm: None,
    };
    let pts = [
        Vector3::new(5.0, 5.0, 2.0),  // above: +1
        Vector3::new(5.0, 5.0, -2.0), // below: −1
        Vector3::new(5.0, 5.0, 9.0),  // beyond the 8 mm band: 0
        Vector3::new(14.0, 5.0, 0.5), // ahead of the crack front (offset ≈ in-plane): 0
        Vector3::new(11.0, 5.0, 3.0), // past the edge but within 60° of the normal (atan(1/3) = 18°): +1
        Vector3::new(5.0, 5.0, 0.0),  // on the crack: judged by its inside point (below): −1
    ];
    let inside = [pts[0], pts[1], pts[2], pts[3], pts[4], Vector3::new(5.0, 5.0, -1.0)];
    assert_eq!(crack_sides(&pts, &inside, &crack, 8.0).unwrap(), vec![1, -1, 0, 0, 1, -1]);
    assert!(crack_sides(&pts, &inside, &crack, 0.0).unwrap_err().to_string().contains("band"));
}
