//! Left–right consistency check (Hirschmüller 2008, §3.4), in OpenCV's single-volume form: the
//! right disparity of right pixel `x_R` is the best left disparity among the left pixels that
//! chose it (`x_R = x − d`, lowest S wins); a left disparity `d` is rejected when both
//! `⌊d⌋` and `⌈d⌉` point to a right pixel whose right disparity differs by more than `max_diff`.
//! Right pixels that no left pixel chose do not reject anything (as OpenCV's `disp12MaxDiff`).

/// One row: `best[x]` integer disparity (px) and `smin[x]` its aggregated cost for every left
/// pixel, `disp[x]` the sub-pixel disparity (+∞ = already invalid). Returns how many were
/// rejected.
pub fn lr_check_row(best: &[i32], smin: &[u16], disp: &mut [f32], max_diff: i32) -> usize {
    let w = best.len();
    let mut right = vec![i32::MIN; w];
    let mut right_cost = vec![u16::MAX; w];
    for x in 0..w {
        let xr = x as i64 - best[x] as i64;
        if (0..w as i64).contains(&xr) {
            let xr = xr as usize;
            if smin[x] < right_cost[xr] {
                right_cost[xr] = smin[x];
                right[xr] = best[x];
            }
        }
    }
    let inconsistent = |dc: i32, x: usize| -> bool {
        let xr = x as i64 - dc as i64;
        if !(0..w as i64).contains(&xr) {
            return false;
        }
        let r = right[xr as usize];
        r != i32::MIN && (r - dc).abs() > max_diff
    };
    let mut n = 0;
    for (x, dx) in disp.iter_mut().enumerate() {
        let d = *dx;
        if !d.is_finite() {
            continue;
        }
        let (lo, hi) = floor_ceil(d);
        if inconsistent(lo, x) & inconsistent(hi, x) {
            *dx = f32::INFINITY;
            n += 1;
        }
    }
    n
}

/// `(⌊d⌋, ⌈d⌉)` for finite |d| < 2³¹ without libm calls (the baseline x86-64 target has no
/// `roundss`).
#[inline(always)]
fn floor_ceil(d: f32) -> (i32, i32) {
    let t = d as i32; // towards zero
    let tf = t as f32;
    (t - (tf > d) as i32, t + (tf < d) as i32) // branch-free: d is data
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_ceil_as_std() {
        for d in [0.0f32, -0.0, 0.25, -0.25, 3.0, -3.0, 2.5, -2.5, 63.996_094, -47.003_906] {
            assert_eq!(floor_ceil(d), (d.floor() as i32, d.ceil() as i32), "{d}");
        }
    }

    #[test]
    fn occluded_pixel_rejected_consistent_kept() {
        // x = 3 and x = 4 both choose x_R = 1 (d = 2 and d = 3); x = 4 has the lower cost, so the
        // right pixel 1 says d = 3 and x = 3 (d = 2 → |3 − 2| = 1 ≤ 1 kept with max_diff 1,
        // rejected with 0). x = 1, 2 match outside the image (d = 9): nothing to check.
        let best = [0, 9, 9, 2, 3];
        let smin = [5, 5, 5, 9, 4];
        let mut d = [0.0f32, 9.0, 9.0, 2.0, 3.0];
        assert_eq!(lr_check_row(&best, &smin, &mut d, 1), 0);
        assert_eq!(lr_check_row(&best, &smin, &mut d, 0), 1);
        assert!(d[3].is_infinite() && d[4] == 3.0);
    }
}
