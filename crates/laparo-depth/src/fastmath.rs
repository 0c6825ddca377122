//! A branch-free natural logarithm that the compiler can inline and vectorise (the libm call
//! in the metric loop costs a call and register spills per pixel). Hand-written because no
//! workspace crate offers an inlinable, accurate f64 log; the algorithm is fdlibm's
//! `__ieee754_log` (error < 1 ulp) without its special-case branches.

#![allow(clippy::excessive_precision)] // fdlibm's published constants, kept verbatim

const LN2_HI: f64 = 6.93147180369123816490e-01;
const LN2_LO: f64 = 1.90821492927058770002e-10;
const LG1: f64 = 6.666666666666735130e-01;
const LG2: f64 = 3.999999999940941908e-01;
const LG3: f64 = 2.857142874366239149e-01;
const LG4: f64 = 2.222219843214978396e-01;
const LG5: f64 = 1.818357216161805012e-01;
const LG6: f64 = 1.531383769920937332e-01;
const LG7: f64 = 1.479819860511658591e-01;

/// True when `x` is a positive normal finite number, the domain of [`ln_normal`].
#[inline(always)]
pub fn is_positive_normal(x: f64) -> bool {
    let e = x.to_bits() >> 52; // sign bit included: negative -> e >= 2048
    (1..2047).contains(&e)
}

/// ln(x) for a positive normal finite `x` (garbage otherwise: check [`is_positive_normal`]).
#[inline(always)]
pub fn ln_normal(x: f64) -> f64 {
    let bits = x.to_bits();
    // k = exponent as f64 without an int->float conversion instruction.
    let ebits = bits >> 52;
    let kf = f64::from_bits(ebits | 0x4330_0000_0000_0000) - 4503599627370496.0 - 1023.0;
    let m = f64::from_bits((bits & 0x000F_FFFF_FFFF_FFFF) | 0x3FF0_0000_0000_0000); // [1, 2)
    let big = m > std::f64::consts::SQRT_2;
    let m = if big { m * 0.5 } else { m };
    let k = if big { kf + 1.0 } else { kf };
    let f = m - 1.0;
    let s = f / (2.0 + f);
    let z = s * s;
    let w = z * z;
    let t1 = w * (LG2 + w * (LG4 + w * LG6));
    let t2 = z * (LG1 + w * (LG3 + w * (LG5 + w * LG7)));
    let r = t2 + t1;
    let hfsq = 0.5 * f * f;
    k * LN2_HI - ((hfsq - (s * (hfsq + r) + k * LN2_LO)) - f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_libm_to_an_ulp_or_two() {
        let mut x = 1e-300f64;
        let mut worst: f64 = 0.0;
        while x < 1e300 {
            for m in [1.0, 1.0000001, 1.2345, std::f64::consts::SQRT_2, 1.41422, 1.5, 1.99999999] {
                let v = x * m;
                assert!(is_positive_normal(v));
                let (a, b) = (ln_normal(v), v.ln());
                let ulp = f64::EPSILON * b.abs().max(f64::MIN_POSITIVE);
                worst = worst.max((a - b).abs() / ulp);
            }
            x *= 1.37;
        }
        assert!(worst <= 2.0, "worst error {worst} ulp");
        assert_eq!(ln_normal(1.0), 0.0);
        assert!(!is_positive_normal(0.0) && !is_positive_normal(-1.0) && !is_positive_normal(f64::INFINITY));
        assert!(!is_positive_normal(f64::NAN) && !is_positive_normal(1e-310));
    }
}
