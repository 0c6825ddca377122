//! Hole filling: every invalid pixel takes the background value of its row, the smaller
//! disparity of the nearest valid pixels on its left and right (occlusions belong to the
//! background). Rows without any valid pixel stay invalid. This is also the "filled" rule of
//! `../shared/bench/sgbm_ref.py` (which puts 0 in empty rows).

/// Fill invalid (non-finite) pixels in place; returns how many were filled.
pub fn fill_background(disp: &mut [f32], w: usize, h: usize) -> usize {
    let mut n = 0;
    let mut left = vec![f32::INFINITY; w];
    for y in 0..h {
        let row = &mut disp[y * w..(y + 1) * w];
        let mut last = f32::INFINITY;
        for x in 0..w {
            if row[x].is_finite() {
                last = row[x];
            }
            left[x] = last;
        }
        let mut next = f32::INFINITY;
        for x in (0..w).rev() {
            if row[x].is_finite() {
                next = row[x];
            } else {
                let v = left[x].min(next);
                if v.is_finite() {
                    row[x] = v;
                    n += 1;
                }
            }
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fills_with_the_smaller_neighbour() {
        let inf = f32::INFINITY;
        let mut d = vec![inf, 5.0, inf, inf, 3.0, inf, inf, inf, inf, inf];
        assert_eq!(fill_background(&mut d, 5, 2), 3);
        assert_eq!(&d[..5], &[5.0, 5.0, 3.0, 3.0, 3.0]);
        assert!(d[5..].iter().all(|v| v.is_infinite()));
    }
}
