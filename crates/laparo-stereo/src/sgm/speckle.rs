//! Speckle filter (as OpenCV's `filterSpeckles`, Hirschmüller 2008 §4.1 "peak removal"):
//! 4-connected regions of valid pixels whose neighbouring disparities differ by at most
//! `max_diff` px are removed (set to +∞) when they have fewer than `max_size` pixels.

/// Remove small disparity regions in place; returns the number of pixels removed.
///
/// Run-length connected components: each row is cut into runs of valid pixels whose horizontal
/// neighbours differ by at most `max_diff` (rows in parallel); runs of adjacent rows that touch
/// through a vertical pair within `max_diff` are merged by union–find; a region is the union of
/// its runs. The components (and so the output) are those of the 4-connected flood fill.
pub fn filter_speckles(disp: &mut [f32], w: usize, h: usize, max_size: usize, max_diff: f32) -> usize {
    use rayon::prelude::*;
    if max_size == 0 || w == 0 || h == 0 {
        return 0;
    }
    let close = |a: f32, b: f32| (a - b).abs() <= max_diff;
    // Runs [x0, x1) of each row.
    let row_runs: Vec<Vec<(u32, u32)>> = disp
        .par_chunks(w)
        .map(|row| {
            let mut runs = Vec::new();
            let mut x = 0;
            while x < w {
                if !row[x].is_finite() {
                    x += 1;
                    continue;
                }
                let x0 = x;
                x += 1;
                while x < w && row[x].is_finite() && close(row[x], row[x - 1]) {
                    x += 1;
                }
                runs.push((x0 as u32, x as u32));
            }
            runs
        })
        .collect();
    let mut first = Vec::with_capacity(h + 1); // index of each row's first run
    let mut runs = Vec::new();
    for r in &row_runs {
        first.push(runs.len());
        runs.extend_from_slice(r);
    }
    first.push(runs.len());
    drop(row_runs);
    let mut parent: Vec<u32> = (0..runs.len() as u32).collect();
    fn root(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            let g = parent[parent[i as usize] as usize];
            parent[i as usize] = g;
            i = g;
        }
        i
    }
    for y in 1..h {
        let (up, cur) = (&disp[(y - 1) * w..y * w], &disp[y * w..(y + 1) * w]);
        let (mut a, a1) = (first[y - 1], first[y]);
        let (mut b, b1) = (first[y], first[y + 1]);
        while a < a1 && b < b1 {
            let (ra, rb) = (runs[a], runs[b]);
            let (lo, hi) = (ra.0.max(rb.0), ra.1.min(rb.1));
            if lo < hi && (lo..hi).any(|x| close(cur[x as usize], up[x as usize])) {
                let (pa, pb) = (root(&mut parent, a as u32), root(&mut parent, b as u32));
                if pa != pb {
                    parent[pa.max(pb) as usize] = pa.min(pb);
                }
            }
            if ra.1 <= rb.1 {
                a += 1;
            } else {
                b += 1;
            }
        }
    }
    let mut size = vec![0usize; runs.len()];
    for (i, run) in runs.iter().enumerate() {
        let r = root(&mut parent, i as u32) as usize;
        size[r] += (run.1 - run.0) as usize;
    }
    let small: Vec<bool> = (0..runs.len()).map(|i| size[parent[i] as usize] < max_size).collect();
    disp.par_chunks_mut(w)
        .enumerate()
        .map(|(y, row)| {
            let mut n = 0;
            for i in first[y]..first[y + 1] {
                if small[i] {
                    let (x0, x1) = (runs[i].0 as usize, runs[i].1 as usize);
                    row[x0..x1].fill(f32::INFINITY);
                    n += x1 - x0;
                }
            }
            n
        })
        .sum()
}

/// The reference flood fill (4-connected, explicit stack) that [`filter_speckles`] reproduces.
#[cfg(test)]
pub fn filter_speckles_flood(disp: &mut [f32], w: usize, h: usize, max_size: usize, max_diff: f32) -> usize {
    if max_size == 0 {
        return 0;
    }
    let mut label = vec![0u32; w * h];
    let mut stack = Vec::new();
    let mut region = Vec::new();
    let mut removed = 0;
    let mut next = 0u32;
    for start in 0..w * h {
        if label[start] != 0 || !disp[start].is_finite() {
            continue;
        }
        next += 1;
        label[start] = next;
        stack.push(start);
        region.clear();
        while let Some(p) = stack.pop() {
            region.push(p);
            let (x, y) = (p % w, p / w);
            let dp = disp[p];
            let mut visit = |q: usize| {
                if label[q] == 0 && disp[q].is_finite() && (disp[q] - dp).abs() <= max_diff {
                    label[q] = next;
                    stack.push(q);
                }
            };
            if x > 0 {
                visit(p - 1);
            }
            if x + 1 < w {
                visit(p + 1);
            }
            if y > 0 {
                visit(p - w);
            }
            if y + 1 < h {
                visit(p + w);
            }
        }
        if region.len() < max_size {
            for &p in &region {
                disp[p] = f32::INFINITY;
            }
            removed += region.len();
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_island_removed_large_kept() {
        let (w, h) = (6, 4);
        let mut d = vec![10.0f32; w * h];
        d[w + 1] = 30.0; // 2-pixel island
        d[w + 2] = 31.0;
        d[3 * w + 5] = f32::INFINITY;
        let n = filter_speckles(&mut d, w, h, 3, 2.0);
        assert_eq!(n, 2);
        assert!(d[w + 1].is_infinite() && d[w + 2].is_infinite());
        assert_eq!(d.iter().filter(|v| v.is_finite()).count(), w * h - 3);
    }

    /// Run-length components = flood fill on random maps with many touching regions, U-shapes
    /// (merged only through a lower row) and invalid pixels.
    #[test]
    fn runs_equal_flood_fill() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for (w, h, size) in [(37usize, 23usize, 5usize), (64, 40, 20), (1, 9, 3), (9, 1, 3)] {
            for _ in 0..20 {
                let d: Vec<f32> = (0..w * h)
                    .map(|_| if rng.gen_bool(0.1) { f32::INFINITY } else { rng.gen_range(0..8) as f32 * 1.5 })
                    .collect();
                let (mut a, mut b) = (d.clone(), d.clone());
                let na = filter_speckles(&mut a, w, h, size, 2.0);
                let nb = filter_speckles_flood(&mut b, w, h, size, 2.0);
                assert_eq!(na, nb);
                assert_eq!(
                    a.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    b.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                );
            }
        }
        // U shape: the arms meet only in the bottom row.
        let inf = f32::INFINITY;
        #[rustfmt::skip]
        let mut u = vec![
            1.0, inf, 1.0,
            1.0, inf, 1.0,
            1.0, 1.0, 1.0,
        ];
        assert_eq!(filter_speckles(&mut u, 3, 3, 7, 0.5), 0);
        assert_eq!(filter_speckles(&mut u, 3, 3, 8, 0.5), 7);
    }
}
