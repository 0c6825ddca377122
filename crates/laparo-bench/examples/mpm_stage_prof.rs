use laparo_mpm::*;
use std::time::Instant;
fn main() {
    if std::env::args().nth(1).as_deref() == Some("2") {
        go::<2>([80, 80]);
    } else {
        go::<3>([16, 25, 17]);
    }
}

fn go<const D: usize>(counts: [usize; D]) {
    let (scene, _loss) = laparo_mpm::reference::rods_scene::<D>(counts, 120, 200, 2e-4);
    let mut cur = ParticleState::initial(&scene);
    let mut grid = sparse_grid::SparseGrid::<D>::new(scene.grid);
    let mut next = cur.clone();
    let mut aff = Vec::new();
    let (mu, la) = scene.material.lame();
    let mut t = [0.0f64; 5];
    let mut keys = vec![0u32; scene.n_particles()];
    for s in 0..200 {
        let t0 = Instant::now();
        grid.build(&cur.x, s).unwrap();
        let t1 = Instant::now();
        p2g::stress(&NeoHookean, mu, la, &scene, &cur.c, &cur.f, &mut next.f, &mut aff, s).unwrap();
        let t2 = Instant::now();
        p2g::scatter(&mut grid, &scene, &cur.x, &cur.v, &aff);
        let t3 = Instant::now();
        grid_update::update(&mut grid, &scene);
        let t4 = Instant::now();
        g2p::gather(&grid, &scene, &cur.x, &mut next.x, &mut next.v, &mut next.c, &mut keys, s).unwrap();
        let t5 = Instant::now();
        std::mem::swap(&mut cur, &mut next);
        for (i, (a, b)) in [(t0, t1), (t1, t2), (t2, t3), (t3, t4), (t4, t5)].iter().enumerate() {
            t[i] += (*b - *a).as_secs_f64();
        }
    }
    println!(
        "build {:.3} stress {:.3} p2g {:.3} grid {:.3} g2p {:.3}  nodes {}",
        t[0],
        t[1],
        t[2],
        t[3],
        t[4],
        grid.n_nodes()
    );
}
