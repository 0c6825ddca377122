//! Speckle filter (as OpenCV's `filterSpeckles`, Hirschmüller 2008 §4.1 "peak removal"):
//! 4-connected regions of valid pixels whose neighbouring disparities differ by at most
//! `max_diff` px are removed (set to +∞) when they have fewer than `max_size` pixels.

/// Remove small disparity regions in place; returns the number of pixels removed.
pub fn filter_speckles(disp: &mut [f32], w: usize, h: usize, max_size: usize, max_diff: f32) -> usize {
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
}
