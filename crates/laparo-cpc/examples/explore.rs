use laparo_cpc::*;
use laparo_cpc::scene::*;
fn main() {
    for (tilt, surf) in [(58.0, 0), (45.0, 0), (45.0, 1), (60.0, 2)] {
        let mut spec = bumpy_bowl_spec();
        spec.pose = tilted_pose(tilt, 100.0);
        if surf == 1 { spec.surface = Surface::Bumpy { rcurv_mm: 1e9, bumps: SCENE_PY_BUMPS.to_vec() }; }
        if surf == 2 { spec.surface = Surface::Plane; spec.half_mm = 60.0; }
        let sc = spec.render().unwrap();
        let mesh = CpcMesh::build(&sc.roi, &sc.depth, &sc.intrinsics, &MeshParams::default()).unwrap();
        let sys = CpcSystem::assemble(&mesh, &ConformalParams::default()).unwrap();
        println!("tilt {tilt} surf {surf}");
        for lam in [0.1, 0.3, 0.5, 0.7, 0.8, 0.9, 0.95, 0.98, 0.99, 0.995, 0.999, 0.9999, 0.99999, 0.999999] {
            let p = sys.solve(lam).unwrap();
            let (a, b) = metrics::displacement_px(&p, &mesh.p_init);
            println!("lam {lam} angle {:.3} da {:.3} flips {} disp {:.1} {:.1}", metrics::angle_error_deg(&p, &mesh.x3d, &mesh.faces), metrics::delta_area(&p, &mesh.p_init, &mesh.faces), metrics::n_flipped(&p, &mesh.faces), a, b);
        }
    }
}
