//! Brute-force matching against an independent naive implementation and hand examples.
use laparo_features::matching::knn2;
use laparo_features::{match_features, Descriptors, Features, Keypoint, Match, MatchConfig, RatioTest};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn kps(n: usize) -> Vec<Keypoint> {
    (0..n).map(|i| Keypoint { x: i as f64, y: 0.0, size_px: 1.0, angle_rad: 0.0, response: 0.0, octave: 0 }).collect()
}

fn float_feats(rows: &[Vec<f32>]) -> Features {
    Features { keypoints: kps(rows.len()), descriptors: Descriptors::Float { dim: rows[0].len(), data: rows.concat() } }
}

fn random_binary(n: usize, rng: &mut ChaCha8Rng) -> Features {
    let data: Vec<u8> = (0..n * 32).map(|_| rng.gen()).collect();
    Features { keypoints: kps(n), descriptors: Descriptors::Binary { bytes: 32, data } }
}

/// Hamming distance bit by bit (no count_ones).
fn naive_hamming(a: &[u8], b: &[u8]) -> u32 {
    a.iter().zip(b).map(|(x, y)| (0..8).filter(|k| ((x ^ y) >> k) & 1 == 1).count() as u32).sum()
}

/// Naive 2-NN by sorting all distances (f64), ties broken by index.
fn naive_matches(a: &Features, b: &Features, ratio: RatioTest, mutual: bool) -> Vec<(u32, u32)> {
    let dist = |fa: &Features, fb: &Features, i: usize, j: usize| -> f64 {
        match (&fa.descriptors, &fb.descriptors) {
            (Descriptors::Binary { bytes, data: x }, Descriptors::Binary { data: y, .. }) => {
                naive_hamming(&x[i * bytes..(i + 1) * bytes], &y[j * bytes..(j + 1) * bytes]) as f64
            }
            (Descriptors::Float { dim, data: x }, Descriptors::Float { data: y, .. }) => {
                (0..*dim).map(|k| (x[i * dim + k] as f64 - y[j * dim + k] as f64).powi(2)).sum::<f64>().sqrt()
            }
            _ => unreachable!(),
        }
    };
    let best2 = |fa: &Features, fb: &Features, i: usize| {
        let mut d: Vec<(f64, usize)> = (0..fb.len()).map(|j| (dist(fa, fb, i, j), j)).collect();
        d.sort_by(|p, q| p.partial_cmp(q).unwrap());
        (d[0].1, d[0].0, d.get(1).map(|x| x.0).unwrap_or(f64::INFINITY))
    };
    let mut out = vec![];
    for i in 0..a.len() {
        let (j, d1, d2) = best2(a, b, i);
        let ok = match ratio {
            RatioTest::None => true,
            RatioTest::Lowe(r) => d1 < r as f64 * d2,
            RatioTest::Ubc(t) => t as f64 * d1 * d1 < d2 * d2,
        };
        if ok && (!mutual || best2(b, a, j).0 == i) {
            out.push((i as u32, j as u32));
        }
    }
    out
}

fn pairs(m: &[Match]) -> Vec<(u32, u32)> {
    m.iter().map(|m| (m.i1, m.i2)).collect()
}

#[test]
fn hand_example_l2_ratio_and_mutual() {
    // a0 = (0,0), a1 = (10,0); b0 = (1,0), b1 = (10,5), b2 = (0,3).
    let a = float_feats(&[vec![0.0, 0.0], vec![10.0, 0.0]]);
    let b = float_feats(&[vec![1.0, 0.0], vec![10.0, 5.0], vec![0.0, 3.0]]);
    // a0: d(b0)=1, d(b2)=3 → ratio 1/3; a1: d(b1)=5, d(b0)=9 → ratio 5/9 = 0.556.
    let none = match_features(&a, &b, &MatchConfig { ratio: RatioTest::None, mutual: false }).unwrap();
    assert_eq!(pairs(&none), vec![(0, 0), (1, 1)]);
    assert!((none[0].distance - 1.0).abs() < 1e-6 && (none[1].distance - 5.0).abs() < 1e-6);
    let lowe = match_features(&a, &b, &MatchConfig { ratio: RatioTest::Lowe(0.5), mutual: false }).unwrap();
    assert_eq!(pairs(&lowe), vec![(0, 0)]);
    // ubc 3.0: 3·1 < 9 yes; 3·25 = 75 < 81 yes.  ubc 3.3: 82.5 > 81 → a1 rejected.
    let ubc = match_features(&a, &b, &MatchConfig { ratio: RatioTest::Ubc(3.0), mutual: false }).unwrap();
    assert_eq!(pairs(&ubc), vec![(0, 0), (1, 1)]);
    let ubc = match_features(&a, &b, &MatchConfig { ratio: RatioTest::Ubc(3.3), mutual: false }).unwrap();
    assert_eq!(pairs(&ubc), vec![(0, 0)]);
    // mutual: b1's nearest in a is a1 (5 vs 11.2), b0's is a0 → both mutual.
    let mu = match_features(&a, &b, &MatchConfig { ratio: RatioTest::None, mutual: true }).unwrap();
    assert_eq!(pairs(&mu), vec![(0, 0), (1, 1)]);
    // Make b0 closer to a1 than to a0 from b's side: a = (0,0),(2,0); b0 = (1.5,0) → a0→b0 (1.5 vs 3+),
    // but b0→a1 (0.5): a0's match is not mutual.
    let a = float_feats(&[vec![0.0, 0.0], vec![2.0, 0.0]]);
    let b = float_feats(&[vec![1.5, 0.0], vec![0.0, 3.0]]);
    let mu = match_features(&a, &b, &MatchConfig { ratio: RatioTest::None, mutual: true }).unwrap();
    assert_eq!(pairs(&mu), vec![(1, 0)]);
}

#[test]
fn binary_matches_equal_naive_for_all_ratio_modes() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let a = random_binary(300, &mut rng);
    // b = a's first 200 rows with a few flipped bits, plus 100 random rows, shuffled order kept simple.
    let mut b = random_binary(100, &mut rng);
    if let (Descriptors::Binary { data: da, .. }, Descriptors::Binary { data: db, .. }) =
        (&a.descriptors, &mut b.descriptors)
    {
        let mut rows = da[..200 * 32].to_vec();
        for _ in 0..2000 {
            let k = rng.gen_range(0..rows.len());
            rows[k] ^= 1 << rng.gen_range(0..8);
        }
        db.splice(0..0, rows);
    }
    b.keypoints = kps(300);
    for ratio in [RatioTest::None, RatioTest::Lowe(0.8), RatioTest::Ubc(1.5), RatioTest::Ubc(2.8)] {
        for mutual in [false, true] {
            let got = match_features(&a, &b, &MatchConfig { ratio, mutual }).unwrap();
            assert_eq!(pairs(&got), naive_matches(&a, &b, ratio, mutual), "{ratio:?} mutual {mutual}");
        }
    }
    let m = match_features(&a, &b, &MatchConfig::default()).unwrap();
    assert!(m.len() >= 190, "perturbed copies should match: {}", m.len());
}

#[test]
fn float_matches_equal_naive_and_ubc_equals_lowe() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let rows = |n: usize, rng: &mut ChaCha8Rng| -> Vec<Vec<f32>> {
        (0..n).map(|_| (0..128).map(|_| rng.gen::<f32>()).collect()).collect()
    };
    let ra = rows(150, &mut rng);
    let mut rb: Vec<Vec<f32>> =
        ra[..100].iter().map(|r| r.iter().map(|v| v + 0.05 * rng.gen::<f32>()).collect()).collect();
    rb.extend(rows(80, &mut rng));
    let (a, b) = (float_feats(&ra), float_feats(&rb));
    for ratio in [RatioTest::None, RatioTest::Lowe(0.8), RatioTest::Ubc(2.8)] {
        for mutual in [false, true] {
            let got = match_features(&a, &b, &MatchConfig { ratio, mutual }).unwrap();
            assert_eq!(pairs(&got), naive_matches(&a, &b, ratio, mutual), "{ratio:?} mutual {mutual}");
        }
    }
    // ubcmatch 2.8 on squared distances ≡ Lowe 1/sqrt(2.8) = 0.5976 on distances.
    let u = match_features(&a, &b, &MatchConfig { ratio: RatioTest::Ubc(2.8), mutual: false }).unwrap();
    let l =
        match_features(&a, &b, &MatchConfig { ratio: RatioTest::Lowe(1.0 / 2.8f32.sqrt()), mutual: false }).unwrap();
    assert_eq!(pairs(&u), pairs(&l));
    assert!(!u.is_empty());
}

#[test]
fn identical_for_one_and_two_threads() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let a = random_binary(2000, &mut rng);
    let b = random_binary(2000, &mut rng);
    let run = |t: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap();
        pool.install(|| {
            (
                knn2(&a.descriptors, &b.descriptors).unwrap(),
                match_features(&a, &b, &MatchConfig { ratio: RatioTest::Lowe(0.95), mutual: true }).unwrap(),
            )
        })
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn empty_and_bad_inputs() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let a = random_binary(5, &mut rng);
    let empty = Features { keypoints: vec![], descriptors: Descriptors::Binary { bytes: 32, data: vec![] } };
    assert!(match_features(&a, &empty, &MatchConfig::default()).unwrap().is_empty());
    assert!(match_features(&empty, &a, &MatchConfig::default()).unwrap().is_empty());
    // One reference row: no second neighbour, the ratio test rejects, plain NN accepts.
    let one = random_binary(1, &mut rng);
    assert!(match_features(&a, &one, &MatchConfig { ratio: RatioTest::Lowe(0.8), mutual: false }).unwrap().is_empty());
    assert_eq!(match_features(&a, &one, &MatchConfig { ratio: RatioTest::None, mutual: false }).unwrap().len(), 5);
    let f = float_feats(&vec![vec![0.0; 32]; 5]);
    let e = match_features(&a, &f, &MatchConfig::default()).unwrap_err().to_string();
    assert!(e.contains("descriptors"), "{e}");
    let e =
        match_features(&a, &a, &MatchConfig { ratio: RatioTest::Lowe(1.5), mutual: false }).unwrap_err().to_string();
    assert!(e.contains("ratio"), "{e}");
}
