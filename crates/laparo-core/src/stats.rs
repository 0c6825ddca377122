//! Order statistics shared by every laparo crate: the one median of the workspace.
//!
//! [`median`] is the reference (numpy semantics: the mean of the two middle values for an even
//! count, NaN for no values); [`fast_median`] returns the same value without reordering its input
//! and is the one used on whole images (one radix-histogram pass instead of a copy + quickselect).

use std::cell::RefCell;

/// Median of `v` (reorders `v`); the mean of the two middle values for an even count (numpy).
/// NaN for an empty slice. NaN values sort above every number (`f64::total_cmp`).
pub fn median(v: &mut [f64]) -> f64 {
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    let k = n / 2;
    let (lo, mid, _) = v.select_nth_unstable_by(k, |a, b| a.partial_cmp(b).unwrap_or_else(|| a.total_cmp(b)));
    let hi = *mid;
    if n % 2 == 1 {
        hi
    } else {
        let below = lo.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (below + hi) / 2.0
    }
}

/// Order-preserving u64 key of an f64 (for non-NaN values: `a < b` ⇔ `key(a) < key(b)`).
#[inline(always)]
fn order_key(x: f64) -> u64 {
    let b = x.to_bits();
    if b >> 63 == 1 {
        !b
    } else {
        b | (1 << 63)
    }
}

thread_local! {
    static HIST: RefCell<Vec<u32>> = const { RefCell::new(Vec::new()) };
}

/// Median of `v` without reordering it: the same value as [`median`] for NaN-free input.
/// `scratch` is reused between calls. Large inputs take one radix-histogram pass on the top 16
/// bits of the order key, then a selection among the few values of the median's bucket(s)
/// (a full copy + quickselect costs ~3× more on a 640×480 image).
pub fn fast_median(v: &[f64], scratch: &mut Vec<f64>) -> f64 {
    let n = v.len();
    scratch.clear();
    if n < 4096 {
        scratch.extend_from_slice(v);
        return median(scratch);
    }
    HIST.with(|h| {
        let mut hist = h.borrow_mut();
        hist.clear();
        hist.resize(1 << 16, 0);
        for &x in v {
            hist[(order_key(x) >> 48) as usize] += 1;
        }
        let (rlo, rhi) = ((n - 1) / 2, n / 2);
        let (mut cum, mut blo, mut below_lo, mut bhi) = (0usize, usize::MAX, 0usize, 0usize);
        for (b, &c) in hist.iter().enumerate() {
            let c = c as usize;
            if blo == usize::MAX && cum + c > rlo {
                blo = b;
                below_lo = cum;
            }
            if cum + c > rhi {
                bhi = b;
                break;
            }
            cum += c;
        }
        for &x in v {
            let b = (order_key(x) >> 48) as usize;
            if b >= blo && b <= bhi {
                scratch.push(x);
            }
        }
        let (k_lo, k_hi) = (rlo - below_lo, rhi - below_lo);
        let (lo, mid, _) = scratch.select_nth_unstable_by(k_hi, |a, b| order_key(*a).cmp(&order_key(*b)));
        let hi = *mid;
        if k_lo == k_hi {
            hi
        } else {
            let below = lo.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (below + hi) / 2.0
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn odd_and_even_counts_by_hand() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&mut [5.0]), 5.0);
        assert!(median(&mut []).is_nan());
        assert_eq!(median(&mut [-1.0, 7.0]), 3.0);
    }

    /// Deterministic pseudo-random values in [-50, 50) (xorshift64), 10 % of them repeated.
    fn values(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed | 1;
        (0..n)
            .map(|i| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                if i % 10 == 0 {
                    1.25
                } else {
                    (s >> 11) as f64 / (1u64 << 53) as f64 * 100.0 - 50.0
                }
            })
            .collect()
    }

    #[test]
    fn radix_median_equals_sorting_median() {
        let mut s = Vec::new();
        for v in [values(9797, 3), values(9000, 5), values(9001, 7), values(100, 9)] {
            let mut sorted = v.clone();
            sorted.sort_by(f64::total_cmp);
            let n = sorted.len();
            let expect = if n % 2 == 1 { sorted[n / 2] } else { (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0 };
            assert_eq!(fast_median(&v, &mut s), expect);
        }
        // Many ties, negative values.
        let v: Vec<f64> = (0..10000).map(|i| ((i % 7) as f64 - 3.0) * 0.5).collect();
        assert_eq!(fast_median(&v, &mut s), 0.0);
    }
}
