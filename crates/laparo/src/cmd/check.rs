//! Numbers from flags and files, checked at the boundary (issue 49): one helper for "finite and in
//! range" and one for "the work this asks for fits a budget", so that a NaN, an infinity or a size
//! that would take gigabytes is refused with the flag's name before anything is allocated.
use anyhow::{bail, Result};
use std::ops::{Bound, RangeBounds};

/// `value` of `flag` (e.g. "--max-tilt", or "poses x.json: view1.t_mm[2]"), refused unless finite and
/// inside `range` (any Rust range: `0.0..90.0`, `1e-3..`, `..=1.0`, `..`). Returns the value.
pub fn number(flag: &str, value: f64, range: impl RangeBounds<f64>) -> Result<f64> {
    let lo_ok = match range.start_bound() {
        Bound::Included(&lo) => value >= lo,
        Bound::Excluded(&lo) => value > lo,
        Bound::Unbounded => true,
    };
    let hi_ok = match range.end_bound() {
        Bound::Included(&hi) => value <= hi,
        Bound::Excluded(&hi) => value < hi,
        Bound::Unbounded => true,
    };
    if value.is_finite() && lo_ok && hi_ok {
        return Ok(value);
    }
    let lo = match range.start_bound() {
        Bound::Included(lo) => format!("[{lo}"),
        Bound::Excluded(lo) => format!("({lo}"),
        Bound::Unbounded => "(-inf".to_string(),
    };
    let hi = match range.end_bound() {
        Bound::Included(hi) => format!("{hi}]"),
        Bound::Excluded(hi) => format!("{hi})"),
        Bound::Unbounded => "inf)".to_string(),
    };
    bail!("{flag} {value}: must be a finite number in {lo}, {hi}")
}

/// [`number`] in (0, ∞): a length, a focal length, a scale.
pub fn positive(flag: &str, value: f64) -> Result<f64> {
    number(flag, value, (Bound::Excluded(0.0), Bound::Unbounded))
}

/// Refuse work whose estimated size `estimate` (in `unit`, e.g. "tetrahedra", "bytes") exceeds `max`,
/// naming `flag` (the input that sets it) and what would be needed. NaN and infinite estimates fail.
pub fn budget(flag: &str, estimate: f64, max: f64, unit: &str) -> Result<()> {
    if estimate.is_finite() && estimate <= max {
        return Ok(());
    }
    bail!("{flag}: this asks for about {estimate:.3e} {unit}, more than the {max:.3e} allowed; choose a smaller size")
}

/// Largest |coordinate| (mm) of a mesh or point cloud read by a command: 1 km.
pub const MAX_COORD_MM: f64 = 1e6;

/// Two point sets that a rigid fit pairs: finite coordinates within ±[`MAX_COORD_MM`], not all on one
/// point, and sizes (bounding-box diagonals) within a factor 1000 of each other, else a unit error
/// (mm against m, a source scaled by 1e15). `a` and `b` are (name, points), the name e.g.
/// "--source liver.obj".
pub fn comparable_clouds(a: (&str, &[nalgebra::Vector3<f64>]), b: (&str, &[nalgebra::Vector3<f64>])) -> Result<()> {
    let size = |(name, pts): (&str, &[nalgebra::Vector3<f64>])| -> Result<f64> {
        let (mut lo, mut hi) = (nalgebra::Vector3::repeat(f64::INFINITY), nalgebra::Vector3::repeat(f64::NEG_INFINITY));
        for (i, p) in pts.iter().enumerate() {
            if let Some(x) = p.iter().find(|x| x.is_nan() || x.abs() > MAX_COORD_MM) {
                bail!("{name}: point {i} has the coordinate {x:e}, beyond ±{MAX_COORD_MM:e} mm (wrong units?)");
            }
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let d = (hi - lo).norm();
        if d.is_nan() || d <= 0.0 {
            bail!("{name}: all {} points coincide (no extent)", pts.len());
        }
        Ok(d)
    };
    let (da, db) = (size(a)?, size(b)?);
    if !(da / db <= 1e3 && db / da <= 1e3) {
        bail!(
            "{} is {da:.4e} mm across and {} {db:.4e} mm: sizes differ by more than 1000x (wrong units or scale?)",
            a.0,
            b.0
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_outside_their_range_or_not_finite_are_refused() {
        assert_eq!(number("--a", 3.0, 0.0..90.0).unwrap(), 3.0);
        assert!(number("--a", 90.0, 0.0..=90.0).is_ok() && number("--a", 90.0, 0.0..90.0).is_err());
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let e = number("--max-tilt", bad, ..).unwrap_err().to_string();
            assert!(e.starts_with("--max-tilt") && e.contains("finite"), "{e}");
        }
        let e = positive("--baseline-mm", 0.0).unwrap_err().to_string();
        assert!(e.contains("(0, inf)"), "{e}");
        assert!(budget("--edge-mm", 1e6, 1e7, "tetrahedra").is_ok());
        let e = budget("--edge-mm", 2.4e8, 2e7, "tetrahedra").unwrap_err().to_string();
        assert!(e.contains("--edge-mm") && e.contains("2.400e8 tetrahedra"), "{e}");
        assert!(budget("--frames", f64::NAN, 1.0, "frames").is_err());
    }

    #[test]
    fn clouds_of_other_units_or_out_of_range_are_refused() {
        use nalgebra::Vector3;
        let a: Vec<Vector3<f64>> =
            (0..8).map(|i| Vector3::new((i & 1) as f64, (i >> 1 & 1) as f64, (i >> 2) as f64) * 30.0).collect();
        let huge: Vec<Vector3<f64>> = a.iter().map(|p| p * 1e15).collect();
        let cm: Vec<Vector3<f64>> = a.iter().map(|p| p * 0.1).collect();
        assert!(comparable_clouds(("--source s", &cm), ("--target t", &a)).is_ok());
        let e = comparable_clouds(("--source s", &huge), ("--target t", &a)).unwrap_err().to_string();
        assert!(e.contains("--source s") && e.contains("beyond"), "{e}");
        let tiny: Vec<Vector3<f64>> = a.iter().map(|p| p * 1e-5).collect();
        let e = comparable_clouds(("--source s", &tiny), ("--target t", &a)).unwrap_err().to_string();
        assert!(e.contains("1000x"), "{e}");
        let e = comparable_clouds(("--source s", &a[..1]), ("--target t", &a)).unwrap_err().to_string();
        assert!(e.contains("coincide"), "{e}");
    }
}
