//! Small timing helpers shared by the harnesses.
use std::time::Instant;

/// Minimum of `v` (+∞ for none).
pub fn vmin(v: &[f64]) -> f64 {
    v.iter().cloned().fold(f64::INFINITY, f64::min)
}

/// Median of timings (the workspace's one median, `laparo_core::stats::median`).
pub fn med(mut v: Vec<f64>) -> f64 {
    laparo_core::stats::median(&mut v)
}

/// One untimed warm-up call, then the minimum and the median (ms) of `runs` timed calls of `f`.
pub fn time_min_median(runs: usize, mut f: impl FnMut()) -> (f64, f64) {
    f();
    let ts: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    (vmin(&ts), med(ts))
}

/// Peak resident set size (VmHWM) of this process in MiB (NaN where /proc is unavailable).
pub fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("VmHWM:")).and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map(|kb| kb / 1024.0)
        .unwrap_or(f64::NAN)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn min_and_median_of_timings() {
        assert_eq!(vmin(&[3.0, 1.5, 2.0]), 1.5);
        assert_eq!(med(vec![3.0, 1.0, 2.0, 10.0]), 2.5);
        let mut calls = 0;
        let (lo, mid) = time_min_median(4, || calls += 1);
        assert_eq!(calls, 5); // warm-up + 4 timed runs
        assert!(lo <= mid && lo >= 0.0);
    }
}
