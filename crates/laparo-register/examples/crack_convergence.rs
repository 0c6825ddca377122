//! Mesh convergence of the incision ground truth (thesis §5.4.2; not run in CI): one tetrahedron edge,
//! one scenario, one fixed crack pressure, so runs at several edges compare the same load.
//!
//! `cargo run --release -p laparo-register --example crack_convergence -- EDGE_MM non-anatomical|anatomical
//!  [PRESSURE_KPA] [STEPS] [FIXED_FRACTION] [LIVER] [CUT_LENGTH_MM] [CUT_DEPTH]`; `SOLVER=direct|two-level` in
//!  the environment forces the solver of the Newton directions (default: direct when its factor fits in 6 GiB);
//!  `NU=ν` changes Poisson's ratio (default 0.49); `OFFSET_MM=d` shifts the anatomical cut plane by d mm along
//!  its normal (towards side B).
//!  CUT_LENGTH_MM and CUT_DEPTH change the blade (anatomical: depth as a fraction of the local thickness;
//!  non-anatomical: depth in mm; default the benchmark's). `TARGET_GAP_MM=G` adds a second solve at the
//!  pressure the first one's gap scales to G (one secant step from zero), so cuts compare at one opening.
//!  `CRACK_PNG=path` draws the crack face-on, coloured by its opening (`write_crack_opening`).
//!
//! Prints the crack's resolution (`CrackResolution`: crack area against the blade's area inside the
//! organ, duplicated nodes, lip pairs) and, when PRESSURE_KPA > 0, the FEM at that pressure: the max
//! gap and its 50/90/99th percentiles over all crack node pairs, the mouth's opening profile along
//! the lip, and the largest displacement farther than 40/60/80 mm from the crack. The blade is traced
//! on the input surface (`non_anatomical_on` / `anatomical_on`), so every edge gets the same cut.
use laparo_core::geometry::closest_point_on_segment;
use laparo_fem::material::NeoHookean;
use laparo_fem::mesh::{
    anatomical_on, non_anatomical_on, tetrahedralize_surface, AnatomicalParams, NonAnatomicalParams, Scenario,
    ScenarioFrame, Surface, TetraParams,
};
use laparo_fem::solid::{solve, LinearSolver, Loads, Quadrature, SolidProblem, SolverSettings, Tet10Mesh};
use laparo_register::benchmark::build::{
    crack_gap_by_node_mm, crack_pair_gaps_mm, distance_to_crack_mm, drop_detached_fragments, lip_opening_profile_mm,
    max_gap_mm, CrackResolution,
};
use laparo_register::benchmark::figures::write_crack_opening;
use laparo_register::rigid::umeyama;
use nalgebra::Vector3;
use std::error::Error;

const P2ILF: &str = "../shared/data/meshes/p2ilf/patient2_1_3d-liver-model.obj";

fn parsed<T: std::str::FromStr>(args: &[String], i: usize, name: &str, default: T) -> Result<T, String> {
    match args.get(i) {
        None => Ok(default),
        Some(s) => s.parse().map_err(|_| format!("{name}: cannot parse {s:?}")),
    }
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        return Err("usage: crack_convergence EDGE_MM non-anatomical|anatomical [PRESSURE_KPA] [STEPS] \
                    [FIXED_FRACTION] [LIVER] [CUT_LENGTH_MM] [CUT_DEPTH]"
            .into());
    }
    let edge_mm: f64 = parsed(&args, 0, "EDGE_MM", 0.0)?;
    let scenario = args[1].as_str();
    let pressure_kpa: f64 = parsed(&args, 2, "PRESSURE_KPA", 0.0)?;
    let steps: usize = parsed(&args, 3, "STEPS", 8)?;
    let mut frame = ScenarioFrame::default();
    frame.fixed_fraction = parsed(&args, 4, "FIXED_FRACTION", frame.fixed_fraction)?;
    let liver = args.get(5).map(String::as_str).filter(|s| *s != "-").unwrap_or(P2ILF);
    let mut anat = AnatomicalParams::default();
    let mut non = NonAnatomicalParams::default();
    anat.length_mm = parsed(&args, 6, "CUT_LENGTH_MM", anat.length_mm)?;
    non.length_mm = parsed(&args, 6, "CUT_LENGTH_MM", non.length_mm)?;
    anat.depth_fraction = parsed(&args, 7, "CUT_DEPTH", anat.depth_fraction)?;
    non.depth_mm = parsed(&args, 7, "CUT_DEPTH", non.depth_mm)?;
    if let Ok(s) = std::env::var("OFFSET_MM") {
        anat.offset_mm = s.parse().map_err(|_| format!("OFFSET_MM: cannot parse {s:?}"))?;
    }
    let target_gap_mm: Option<f64> = match std::env::var("TARGET_GAP_MM") {
        Err(_) => None,
        Ok(s) => Some(s.parse().map_err(|_| format!("TARGET_GAP_MM: cannot parse {s:?}"))?),
    };

    let surface = laparo_core::mesh::read_mesh(liver)?;
    let organ = Surface::new(surface.clone(), liver)?;
    let params = TetraParams { edge_mm, ..Default::default() };
    let (mesh, quality) = tetrahedralize_surface(surface.clone(), liver, &params)?;
    let mut scn = match scenario {
        "anatomical" => anatomical_on(&mesh, &surface, &frame, &anat)?,
        "non-anatomical" => non_anatomical_on(&mesh, &surface, &frame, &non)?,
        other => return Err(format!("scenario {other:?}: expected non-anatomical or anatomical").into()),
    };
    let dropped = drop_detached_fragments(&mut scn);
    {
        // The blade's depth under each mouth sample (mm): a dip is tissue the blade does not cut.
        let d: Vec<String> = scn.blade.depths.iter().map(|d| format!("{d:.0}")).collect();
        println!("blade depth under each of the {} mouth samples (mm): [{}]", d.len(), d.join(", "));
    }
    // The tissue beside the cut: from points of the blade's middle third at depths below the mouth, the
    // distance along ± the blade normal to the organ surface (how thick each lip's wall is).
    {
        let b = &scn.blade;
        let n = (b.mouth[b.mouth.len() - 1] - b.mouth[0]).cross(&b.directions[0]).normalize();
        let m = b.mouth.len();
        let exit = |o: &Vector3<f64>, d: &Vector3<f64>| {
            surface
                .faces
                .iter()
                .filter_map(|f| {
                    let [p, q, r] = f.map(|k| surface.vertices[k]);
                    laparo_core::geometry::ray_triangle(o, d, &p, &q, &r)
                })
                .filter(|t| *t > 0.0)
                .fold(f64::INFINITY, f64::min)
        };
        let mut rows = Vec::new();
        for depth in [5.0, 15.0, 30.0, 50.0] {
            let (mut wa, mut wb) = (Vec::new(), Vec::new());
            for i in m / 3..=2 * m / 3 {
                if depth >= b.depths[i] {
                    continue;
                }
                let o = b.mouth[i] + b.directions[i].normalize() * depth;
                wa.push(exit(&o, &n));
                wb.push(exit(&o, &-n));
            }
            let med = |mut v: Vec<f64>| {
                v.sort_by(f64::total_cmp);
                v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
            };
            rows.push(format!("{depth} mm: A {:.0} / B {:.0} mm", med(wa), med(wb)));
        }
        println!("tissue beside the cut (median over the blade's middle third): {}", rows.join("; "));
    }
    {
        // how close the crack comes to the fixed (posterior) region
        let xs = &scn.cut.mesh.vertices;
        let fixed: Vec<Vector3<f64>> = scn.fixed_nodes.iter().map(|&k| xs[k]).collect();
        let mut d: Vec<f64> = scn.cut.crack_faces[0]
            .iter()
            .flatten()
            .map(|&k| fixed.iter().map(|f| (f - xs[k]).norm()).fold(f64::INFINITY, f64::min))
            .collect();
        d.sort_by(f64::total_cmp);
        println!(
            "crack nodes to the fixed region: min {:.0} mm, median {:.0} mm",
            d.first().copied().unwrap_or(f64::NAN),
            d.get(d.len() / 2).copied().unwrap_or(f64::NAN)
        );
    }
    let res = CrackResolution::of(&scn, &organ);
    println!(
        "edge {edge_mm} mm, {scenario}: {} nodes, {} tets, {dropped} fragment nodes dropped, fixed {}; crack {:.0} / {:.0} mm² \
         of {:.0} mm² blade inside ({:.2}), {} duplicated nodes, {} lip pairs",
        quality.nodes,
        quality.tets,
        scn.fixed_nodes.len(),
        res.crack_area_mm2[0],
        res.crack_area_mm2[1],
        res.blade_area_inside_mm2,
        res.area_fraction(),
        res.duplicated_nodes,
        res.lip_pairs
    );
    // how much of the crack can open: faces with every node duplicated, faces touching the front
    let front: std::collections::HashSet<usize> = scn.cut.front_nodes.iter().copied().collect();
    let [a_faces, _] = &scn.cut.crack_faces;
    let free = a_faces.iter().filter(|f| f.iter().all(|i| !front.contains(i))).count();
    let depth_of = |f: &[usize; 3]| {
        let c = f.iter().map(|&i| scn.cut.mesh.vertices[i]).sum::<Vector3<f64>>() / 3.0;
        scn.cut.lips[0].iter().map(|&i| (scn.cut.mesh.vertices[i] - c).norm()).fold(f64::INFINITY, f64::min)
    };
    let deepest_free =
        a_faces.iter().filter(|f| f.iter().all(|i| !front.contains(i))).map(depth_of).fold(0.0, f64::max);
    let deepest = a_faces.iter().map(depth_of).fold(0.0, f64::max);
    println!(
        "crack faces (side A): {} of {} with no crack-front node; farthest from the lip: {deepest_free:.1} mm \
         (any face: {deepest:.1} mm)",
        free,
        a_faces.len()
    );
    // Crack-front nodes should lie along the blade's edge inside the organ (its floor and its two
    // ends); one farther than two tet edges from that edge is a bridge pinning the crack shut.
    let b = &scn.blade;
    let n = b.mouth.len();
    let seg = |p: &Vector3<f64>, a: &Vector3<f64>, c: &Vector3<f64>| (p - closest_point_on_segment(p, a, c)).norm();
    let bottom: Vec<Vector3<f64>> = (0..n).map(|i| b.mouth[i] + b.directions[i].normalize() * b.depths[i]).collect();
    let top = |i: usize| b.mouth[i] - b.directions[i].normalize() * b.overshoot_mm;
    let to_edge = |p: &Vector3<f64>| {
        let floor = bottom.windows(2).map(|w| seg(p, &w[0], &w[1])).fold(f64::INFINITY, f64::min);
        floor.min(seg(p, &top(0), &bottom[0])).min(seg(p, &top(n - 1), &bottom[n - 1]))
    };
    let mut bridges: Vec<(f64, f64)> = scn
        .cut
        .front_nodes
        .iter()
        .map(|&k| {
            let p = scn.cut.mesh.vertices[k];
            let lip =
                scn.cut.lips[0].iter().map(|&i| (scn.cut.mesh.vertices[i] - p).norm()).fold(f64::INFINITY, f64::min);
            (to_edge(&p), lip)
        })
        .filter(|(d, _)| *d > 2.0 * edge_mm)
        .collect();
    bridges.sort_by(|a, b| b.0.total_cmp(&a.0));
    println!(
        "crack front: {} nodes, {} of them farther than {:.0} mm from the blade's edge (bridges); the farthest \
         (mm from the edge, mm from lip A): {:?}",
        scn.cut.front_nodes.len(),
        bridges.len(),
        2.0 * edge_mm,
        bridges.iter().take(8).map(|(d, l)| (d.round(), l.round())).collect::<Vec<_>>()
    );
    if pressure_kpa <= 0.0 {
        return Ok(());
    }

    let linear = match std::env::var("SOLVER").as_deref() {
        Err(_) => LinearSolver::default(),
        Ok("direct") => LinearSolver::Direct,
        Ok("two-level") => LinearSolver::TwoLevel,
        Ok(other) => return Err(format!("SOLVER={other:?}: expected direct or two-level").into()),
    };
    let gap = open_at(&scn, pressure_kpa, steps, linear)?;
    if let Some(target) = target_gap_mm {
        if !(target > 0.0 && gap > 0.0) {
            return Err(
                format!("TARGET_GAP_MM {target}: needs a positive target and a first gap > 0 (got {gap})").into()
            );
        }
        open_at(&scn, pressure_kpa * target / gap, steps, linear)?;
    }
    Ok(())
}

/// Opens the crack at `pressure_kpa`, prints the solver and crack-opening figures, returns the max gap (mm).
fn open_at(scn: &Scenario, pressure_kpa: f64, steps: usize, linear: LinearSolver) -> Result<f64, Box<dyn Error>> {
    let x = &scn.cut.mesh.vertices;
    let nu: f64 = match std::env::var("NU") {
        Err(_) => 0.49,
        Ok(s) => s.parse().map_err(|_| format!("NU: cannot parse {s:?}"))?,
    };
    let material = NeoHookean::from_young_poisson(4.1, nu)?;
    let m10 = Tet10Mesh::from_linear(&scn.cut.mesh)?;
    let fixed = SolidProblem::fixed_vertices(&m10, &scn.fixed_nodes)?;
    let face_tractions = scn.cut.crack_pressure(pressure_kpa);
    let loads = Loads { face_tractions, ..Default::default() };
    let problem = SolidProblem::new(m10, material, &fixed, &loads, Quadrature::Degree2)?;
    let t0 = std::time::Instant::now();
    let sol = solve(&problem, &SolverSettings { steps, rel_tol: 1e-8, linear, ..Default::default() })?;
    let t = &sol.timings;
    println!(
        "solver {}: {} free DOFs, factor nnz {}, Newton {} iterations, {} factorisations ({:.0} s), {} CG iterations, \
         assembly {:.0} s, solves {:.0} s",
        sol.linear_solver,
        sol.free_dofs,
        sol.factor_nnz,
        t.newton_iterations,
        t.factorizations,
        t.factorization_s,
        t.pcg_iterations,
        t.assembly_s,
        t.solve_s
    );
    let u = sol.vertex_displacements();
    let deformed: Vec<Vector3<f64>> = x.iter().zip(u).map(|(a, b)| a + b).collect();

    let mut gaps = crack_pair_gaps_mm(&scn.cut, &deformed);
    gaps.sort_by(f64::total_cmp);
    let pct = |q: f64| gaps.get(((gaps.len().max(1) - 1) as f64 * q).round() as usize).copied().unwrap_or(0.0);
    let profile: Vec<String> = lip_opening_profile_mm(&scn.cut, &deformed).iter().map(|g| format!("{g:.1}")).collect();
    let distance = distance_to_crack_mm(&scn.cut)?;
    let far = |r: f64| u.iter().zip(&distance).filter(|(_, &d)| d > r).map(|(u, _)| u.norm()).fold(0.0, f64::max);
    println!(
        "{pressure_kpa} kPa, {steps} steps: {:.0} s; max gap {:.2} mm; {} crack pairs: p50 {:.2} p90 {:.2} p99 {:.2} mm; \
         lip opening [{}] mm; |u| beyond 40/60/80 mm: {:.2} / {:.2} / {:.2} mm; max |u| {:.2} mm, min J {:.3}",
        t0.elapsed().as_secs_f64(),
        max_gap_mm(&scn.cut, &deformed),
        gaps.len(),
        pct(0.5),
        pct(0.9),
        pct(0.99),
        profile.join(", "),
        far(40.0),
        far(60.0),
        far(80.0),
        sol.max_displacement_mm,
        sol.min_j
    );
    // The blade normal towards side A, (mouth tangent) × (direction).
    let b = &scn.blade;
    let normal = (b.mouth[b.mouth.len() - 1] - b.mouth[0]).cross(&b.directions[0]).normalize();
    // Signed opening of each crack node pair, (u_A − u_B)·n with n the blade normal towards side A: a
    // negative value is the two lips passing through each other (the FEM has no contact), by depth.
    {
        let a_nodes: std::collections::HashSet<usize> = scn.cut.crack_faces[0].iter().flatten().copied().collect();
        let b_nodes: std::collections::HashSet<usize> = scn.cut.crack_faces[1].iter().flatten().copied().collect();
        let mut by_orig: std::collections::HashMap<usize, (Option<usize>, Option<usize>)> = Default::default();
        for (k, &o) in scn.cut.original_node.iter().enumerate() {
            let e = by_orig.entry(o).or_default();
            if a_nodes.contains(&k) && !b_nodes.contains(&k) {
                e.0 = Some(k);
            } else if b_nodes.contains(&k) && !a_nodes.contains(&k) {
                e.1 = Some(k);
            }
        }
        let mut bins: std::collections::BTreeMap<i64, (f64, f64, usize)> = Default::default();
        for (ka, kb) in by_orig.values().filter_map(|&(a, b)| a.zip(b)) {
            let open = (u[ka] - u[kb]).dot(&normal);
            let depth = scn.cut.lips[0].iter().map(|&i| (x[i] - x[ka]).norm()).fold(f64::INFINITY, f64::min);
            let e = bins.entry((depth / 20.0).floor() as i64).or_insert((f64::INFINITY, 0.0, 0));
            e.0 = e.0.min(open);
            e.1 += open;
            e.2 += 1;
        }
        let rows: Vec<String> = bins
            .iter()
            .map(|(d, (mn, sum, c))| {
                format!("{}–{} mm: mean {:.2} min {:.2} (n {c})", d * 20, d * 20 + 20, sum / *c as f64, mn)
            })
            .collect();
        println!("signed opening (u_A − u_B)·n by distance from lip A: {}", rows.join("; "));
        if let Ok(path) = std::env::var("CRACK_PNG") {
            let title = format!("{pressure_kpa} kPa: the crack face-on, unrolled along the blade");
            write_crack_opening(
                std::path::Path::new(&path),
                scn,
                Some(&crack_gap_by_node_mm(&scn.cut, &deformed)),
                &title,
            )?;
            println!("wrote {path}");
        }
    }
    // Where the far field moves: the nodes beyond 60 mm from the crack, by |u|.
    let mut far60: Vec<(f64, usize)> = (0..x.len()).filter(|&k| distance[k] > 60.0).map(|k| (u[k].norm(), k)).collect();
    far60.sort_by(|a, b| b.0.total_cmp(&a.0));
    let q = |f: f64| far60.get(((far60.len().max(1) - 1) as f64 * f) as usize).map_or(0.0, |v| v.0);
    let fixed_pts: Vec<Vector3<f64>> = scn.fixed_nodes.iter().map(|&k| x[k]).collect();
    let to_fixed = |p: &Vector3<f64>| fixed_pts.iter().map(|f| (f - p).norm()).fold(f64::INFINITY, f64::min);
    println!(
        "beyond 60 mm: {} nodes, |u| max {:.2} p99 {:.2} p95 {:.2} p50 {:.2} mm; {} above 1 mm; the five largest \
         (|u| mm, mm from the crack, mm from the fixed region, position): {:?}",
        far60.len(),
        q(0.0),
        q(0.01),
        q(0.05),
        q(0.5),
        far60.iter().filter(|v| v.0 > 1.0).count(),
        far60
            .iter()
            .take(5)
            .map(|&(m, k)| (
                (m * 100.0).round() / 100.0,
                distance[k].round(),
                to_fixed(&x[k]).round(),
                x[k].map(|c| c.round())
            ))
            .collect::<Vec<_>>()
    );
    // Do the two halves swing as rigid flaps? Per side of the blade, the best rigid motion (Umeyama, no
    // scale) of the nodes 20–60 mm from the crack: its rotation and the share of the motion it explains.
    for (side, sign) in [("A", 1.0), ("B", -1.0)] {
        let ids: Vec<usize> = (0..x.len())
            .filter(|&k| (20.0..60.0).contains(&distance[k]) && sign * (x[k] - b.mouth[0]).dot(&normal) > 0.0)
            .collect();
        if ids.len() < 4 {
            continue;
        }
        let src: Vec<Vector3<f64>> = ids.iter().map(|&k| x[k]).collect();
        let dst: Vec<Vector3<f64>> = ids.iter().map(|&k| deformed[k]).collect();
        let fit = umeyama(&src, &dst, false)?;
        let angle = ((fit.rotation.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees();
        let rms = |v: &mut dyn Iterator<Item = f64>| {
            let (s2, n) = v.fold((0.0, 0usize), |(s2, n), e| (s2 + e * e, n + 1));
            (s2 / n.max(1) as f64).sqrt()
        };
        let residual = rms(&mut src.iter().zip(&dst).map(|(a, b)| (fit.apply(a) - b).norm()));
        println!(
            "side {side}: {} nodes 20–60 mm from the crack; rigid fit rotates {angle:.2}°, leaves {residual:.2} mm RMS \
             of {:.2} mm RMS displacement",
            ids.len(),
            rms(&mut ids.iter().map(|&k| u[k].norm()))
        );
    }
    Ok(max_gap_mm(&scn.cut, &deformed))
}
