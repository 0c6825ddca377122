//! Distances vs brute force (1e-12 on 10⁴ random queries) and gradients vs central finite differences.
use laparo_mpm::Vector;
use laparo_register::distance::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn rnd<const D: usize>(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> Vector<D> {
    Vector::<D>::from_fn(|_, _| rng.gen_range(lo..hi))
}

/// Check closest(x) against brute force on 10⁴ queries, and (x − c)/|x − c| against central FD of
/// the distance where the closest primitive does not change within ±h (away from ties).
fn check<const D: usize>(t: &dyn ClosestPoint<D>, prim: &dyn Fn(usize, &Vector<D>) -> Vector<D>, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut checked = 0;
    for _ in 0..10_000 {
        let x = rnd::<D>(&mut rng, -1.5, 1.5);
        let (c, i) = t.closest(&x);
        let (cb, _) = brute_force(&x, t.len(), |k| prim(k, &x));
        let (d, db) = ((x - c).norm(), (x - cb).norm());
        assert!((d - db).abs() <= 1e-12, "distance {d} vs brute force {db}");
        if d < 1e-3 {
            continue;
        }
        let h = 1e-6;
        let mut same = true;
        let mut fd = Vector::<D>::zeros();
        for k in 0..D {
            let mut e = Vector::<D>::zeros();
            e[k] = h;
            let (cp, ip) = t.closest(&(x + e));
            let (cm, im) = t.closest(&(x - e));
            same &= ip == i && im == i;
            fd[k] = ((x + e - cp).norm() - (x - e - cm).norm()) / (2.0 * h);
        }
        if !same {
            continue;
        }
        let (_, g) = smoothed_distance(&(x - c), 0.0);
        let rel = (fd - g).norm() / g.norm();
        assert!(rel < 1e-6, "gradient rel error {rel:e} at {x:?}");
        checked += 1;
    }
    assert!(checked > 9_000, "only {checked} gradient checks away from ties");
}

#[test]
fn point_cloud_vs_brute_force_with_lattice_duplicates() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    // a lattice (many equal coordinates, the k-d tree's hard case) plus random points
    let mut pts: Vec<Vector<3>> = Vec::new();
    for i in 0..12 {
        for j in 0..12 {
            for k in 0..6 {
                pts.push(Vector::<3>::new(i as f64 * 0.1 - 0.6, j as f64 * 0.1 - 0.6, k as f64 * 0.1));
            }
        }
    }
    pts.extend((0..500).map(|_| rnd::<3>(&mut rng, -1.0, 1.0)));
    let cloud = PointCloud::new(pts.clone());
    check::<3>(&cloud, &|i, _| pts[i], 2);
    let pts2: Vec<Vector<2>> = (0..2000).map(|_| rnd::<2>(&mut rng, -1.0, 1.0)).collect();
    let c2 = PointCloud::new(pts2.clone());
    check::<2>(&c2, &|i, _| pts2[i], 3);
}

#[test]
fn polyline_vs_brute_force_2d_3d() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let v2: Vec<Vector<2>> = (0..300).map(|_| rnd::<2>(&mut rng, -1.0, 1.0)).collect();
    let p2 = Polyline::open(v2.clone());
    check::<2>(&p2, &|i, x| closest_on_segment(x, &v2[i], &v2[i + 1]), 5);
    // a smooth 3D curve with segments of very different lengths
    let v3: Vec<Vector<3>> = (0..200)
        .map(|i| {
            let t = (i as f64 / 199.0).powi(2) * 6.0;
            Vector::<3>::new(t.cos(), t.sin(), 0.2 * t - 0.6)
        })
        .collect();
    let p3 = Polyline::open(v3.clone());
    check::<3>(&p3, &|i, x| closest_on_segment(x, &v3[i], &v3[i + 1]), 6);
}

#[test]
fn triangle_mesh_vs_brute_force() {
    // a closed UV sphere of radius 1 plus random triangles
    let (nu, nv) = (24, 12);
    let mut v: Vec<Vector<3>> = Vec::new();
    for j in 0..=nv {
        for i in 0..nu {
            let (th, ph) =
                (std::f64::consts::PI * j as f64 / nv as f64, 2.0 * std::f64::consts::PI * i as f64 / nu as f64);
            v.push(Vector::<3>::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()));
        }
    }
    let mut f = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            let a = j * nu + i;
            let b = j * nu + (i + 1) % nu;
            f.push([a, b, a + nu]);
            f.push([b, b + nu, a + nu]);
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for _ in 0..100 {
        let c = rnd::<3>(&mut rng, -1.2, 1.2);
        let n0 = v.len();
        for _ in 0..3 {
            v.push(c + rnd::<3>(&mut rng, -0.3, 0.3));
        }
        f.push([n0, n0 + 1, n0 + 2]);
    }
    let surf = TriangleSurface::new(v.clone(), f.clone());
    check::<3>(&surf, &|i, x| closest_on_triangle(x, &v[f[i][0]], &v[f[i][1]], &v[f[i][2]]), 8);
}

#[test]
fn closest_on_triangle_matches_dense_sampling() {
    // independent check of the Voronoi-region logic: a dense barycentric sampling never beats it
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for _ in 0..200 {
        let (a, b, c) = (rnd::<3>(&mut rng, -1.0, 1.0), rnd::<3>(&mut rng, -1.0, 1.0), rnd::<3>(&mut rng, -1.0, 1.0));
        let x = rnd::<3>(&mut rng, -2.0, 2.0);
        let d = (x - closest_on_triangle(&x, &a, &b, &c)).norm();
        let n = 60;
        let mut best = f64::INFINITY;
        for i in 0..=n {
            for j in 0..=(n - i) {
                let (u, w) = (i as f64 / n as f64, j as f64 / n as f64);
                best = best.min((x - (a + (b - a) * u + (c - a) * w)).norm());
            }
        }
        assert!(d <= best + 1e-12, "{d} > sampled {best}");
        assert!(best - d < 0.05, "sampled {best} far above exact {d}");
    }
}
