//! Colour maps for scalar images (depth, disparity, error maps); colour bars are drawn by
//! [`crate::plot::with_colorbar`] (plot depends on colormap, never the reverse).
//!
//! Turbo interpolates every 8th entry of Google's published table (A. Mikhailov, 2019); Viridis
//! and Magma use the published 6th-order polynomial fits of the matplotlib maps (M. Zucker).
//! All agree with the reference 256-entry tables within 0.02 per channel (tested on entries that
//! are not knots).
use crate::error::{CoreError, Result};
use crate::image::Image;
use serde::{Deserialize, Serialize};

/// Colour used for non-finite values by [`colorize`] (dark grey).
pub const INVALID_RGB: [u8; 3] = [48, 48, 48];

/// A colour map from t in [0, 1] to sRGB.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Colormap {
    /// Google's Turbo (rainbow-like, perceptually smoother than jet): depth, disparity.
    #[default]
    Turbo,
    /// Perceptually uniform blue–green–yellow.
    Viridis,
    /// Perceptually uniform black–purple–orange–white: error maps.
    Magma,
    /// Black to white.
    Gray,
}

impl std::str::FromStr for Colormap {
    type Err = CoreError;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "turbo" => Ok(Colormap::Turbo),
            "viridis" => Ok(Colormap::Viridis),
            "magma" => Ok(Colormap::Magma),
            "gray" | "grey" => Ok(Colormap::Gray),
            _ => Err(CoreError::invalid("colour map", format!("'{s}' (expected turbo, viridis, magma or gray)"))),
        }
    }
}

impl std::fmt::Display for Colormap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Colormap::Turbo => "turbo",
            Colormap::Viridis => "viridis",
            Colormap::Magma => "magma",
            Colormap::Gray => "gray",
        })
    }
}

#[inline]
fn horner(t: f64, c: &[f64; 7]) -> f64 {
    c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * (c[5] + t * c[6])))))
}

// Zucker's fits, per channel, coefficients of t^0 .. t^6.
const VIRIDIS: [[f64; 7]; 3] = [
    [
        0.2777273272234177,
        0.1050930431085774,
        -0.3308618287255563,
        -4.634230498983486,
        6.228269936347081,
        4.776384997670288,
        -5.435455855934631,
    ],
    [
        0.005407344544966578,
        1.404613529898575,
        0.214847559468213,
        -5.799100973351585,
        14.17993336680509,
        -13.74514537774601,
        4.645852612178535,
    ],
    [
        0.3340998053353061,
        1.384590162594685,
        0.09509516302823659,
        -19.33244095627987,
        56.69055260068105,
        -65.35303263337234,
        26.3124352495832,
    ],
];
const MAGMA: [[f64; 7]; 3] = [
    [
        -0.002136485053939582,
        0.2516605407371642,
        8.353717279216625,
        -27.66873308576866,
        52.17613981234068,
        -50.76852536473588,
        18.65570506591883,
    ],
    [
        -0.000749655052795221,
        0.6775232436837668,
        -3.577719514958484,
        14.26473078096533,
        -27.94360607168351,
        29.04658282127291,
        -11.48977351997711,
    ],
    [
        -0.005386127855323933,
        2.494026599312351,
        0.3144679030132573,
        -13.64921318813922,
        12.94416944238394,
        4.23415299384598,
        -5.601961508734096,
    ],
];

/// Every 8th entry (0, 8, ..., 248) and the last entry (255) of Google's published 256-entry
/// Turbo table (A. Mikhailov, 2019, Apache-2.0). Google's polynomial fit is off by up to 0.12 at
/// the ends, so we interpolate the table linearly instead (max error about 0.005).
const TURBO_KNOTS: [[f64; 3]; 33] = [
    [0.18995, 0.07176, 0.23217],
    [0.22500, 0.16354, 0.45096],
    [0.25107, 0.25237, 0.63374],
    [0.26816, 0.33825, 0.78050],
    [0.27628, 0.42118, 0.89123],
    [0.27543, 0.50115, 0.96594],
    [0.25862, 0.57958, 0.99876],
    [0.21382, 0.65886, 0.97959],
    [0.15844, 0.73551, 0.92305],
    [0.11167, 0.80569, 0.84525],
    [0.09267, 0.86554, 0.76230],
    [0.12014, 0.91193, 0.68660],
    [0.19659, 0.94901, 0.59466],
    [0.30513, 0.97697, 0.48987],
    [0.42778, 0.99419, 0.38575],
    [0.54658, 0.99907, 0.29581],
    [0.64362, 0.98999, 0.23356],
    [0.72596, 0.96470, 0.20640],
    [0.80473, 0.92452, 0.20459],
    [0.87530, 0.87267, 0.21555],
    [0.93301, 0.81236, 0.22667],
    [0.97323, 0.74682, 0.22536],
    [0.99314, 0.67408, 0.20348],
    [0.99593, 0.58703, 0.16899],
    [0.98360, 0.49291, 0.12849],
    [0.95801, 0.39958, 0.08831],
    [0.92105, 0.31489, 0.05475],
    [0.87422, 0.24526, 0.03297],
    [0.81608, 0.18462, 0.01809],
    [0.74617, 0.13098, 0.00851],
    [0.66449, 0.08436, 0.00424],
    [0.57103, 0.04474, 0.00529],
    [0.47960, 0.01583, 0.01055],
];

fn turbo(t: f64) -> [f64; 3] {
    let u = t * 255.0;
    let (i, a) = if u >= 248.0 {
        (31, (u - 248.0) / 7.0)
    } else {
        let i = (u / 8.0).floor() as usize;
        (i, (u - 8.0 * i as f64) / 8.0)
    };
    let (p, q) = (TURBO_KNOTS[i], TURBO_KNOTS[i + 1]);
    [p[0] + a * (q[0] - p[0]), p[1] + a * (q[1] - p[1]), p[2] + a * (q[2] - p[2])]
}

impl Colormap {
    /// All colour maps, for CLIs and tests.
    pub const ALL: [Colormap; 4] = [Colormap::Turbo, Colormap::Viridis, Colormap::Magma, Colormap::Gray];

    /// sRGB in [0, 1] at t (clamped to [0, 1]; NaN → 0).
    pub fn rgb_f64(self, t: f64) -> [f64; 3] {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        let c = match self {
            Colormap::Turbo => turbo(t),
            Colormap::Viridis => [horner(t, &VIRIDIS[0]), horner(t, &VIRIDIS[1]), horner(t, &VIRIDIS[2])],
            Colormap::Magma => [horner(t, &MAGMA[0]), horner(t, &MAGMA[1]), horner(t, &MAGMA[2])],
            Colormap::Gray => [t, t, t],
        };
        [c[0].clamp(0.0, 1.0), c[1].clamp(0.0, 1.0), c[2].clamp(0.0, 1.0)]
    }

    /// 8-bit sRGB at t (clamped to [0, 1]).
    pub fn rgb(self, t: f64) -> [u8; 3] {
        let c = self.rgb_f64(t);
        [(c[0] * 255.0).round() as u8, (c[1] * 255.0).round() as u8, (c[2] * 255.0).round() as u8]
    }

    /// A 256-entry 8-bit lookup table.
    pub fn lut(self) -> [[u8; 3]; 256] {
        let mut l = [[0u8; 3]; 256];
        for (i, e) in l.iter_mut().enumerate() {
            *e = self.rgb(i as f64 / 255.0);
        }
        l
    }
}

/// Map channel 0 of `img` linearly from [lo, hi] to the colour map (values outside are clamped;
/// lo > hi reverses the map; lo == hi paints every finite pixel with the middle colour).
/// Non-finite values become [`INVALID_RGB`]. Returns a 3-channel image.
pub fn colorize(img: &Image<f64>, lo: f64, hi: f64, cmap: Colormap) -> Image<u8> {
    let lut = cmap.lut();
    let span = hi - lo;
    let degenerate = !(span.is_finite() && span != 0.0 && lo.is_finite());
    let ch = img.channels.max(1);
    let mut data = Vec::with_capacity(img.width * img.height * 3);
    for px in img.data.chunks_exact(ch) {
        let v = px[0];
        let c = if !v.is_finite() {
            INVALID_RGB
        } else {
            let t = if degenerate { 0.5 } else { ((v - lo) / span).clamp(0.0, 1.0) };
            lut[(t * 255.0).round() as usize]
        };
        data.extend_from_slice(&c);
    }
    Image { width: img.width, height: img.height, channels: 3, data }
}

/// Smallest and largest finite value of channel 0, or `None` if there is none.
pub fn finite_range(img: &Image<f64>) -> Option<(f64, f64)> {
    let ch = img.channels.max(1);
    let mut r: Option<(f64, f64)> = None;
    for v in img.data.iter().step_by(ch).copied().filter(|v| v.is_finite()) {
        r = Some(match r {
            None => (v, v),
            Some((a, b)) => (a.min(v), b.max(v)),
        });
    }
    r
}

/// The `lo_pct` and `hi_pct` percentiles (0–100, nearest rank) of the finite values of channel 0:
/// a display range robust to outliers. `None` if there is no finite value.
pub fn percentile_range(img: &Image<f64>, lo_pct: f64, hi_pct: f64) -> Option<(f64, f64)> {
    let ch = img.channels.max(1);
    let mut v: Vec<f64> = img.data.iter().step_by(ch).copied().filter(|v| v.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_unstable_by(|a, b| a.total_cmp(b));
    let at = |p: f64| v[((p.clamp(0.0, 100.0) / 100.0) * (v.len() - 1) as f64).round() as usize];
    Some((at(lo_pct), at(hi_pct)))
}

/// "Nice" tick values (1, 2, 2.5 or 5 × 10^k steps) covering [min(lo,hi), max(lo,hi)], about
/// `target` of them, and the number of decimals needed to print them.
pub fn nice_ticks(lo: f64, hi: f64, target: usize) -> (Vec<f64>, usize) {
    let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
    if !(a.is_finite() && b.is_finite()) {
        return (Vec::new(), 0);
    }
    if b - a <= f64::EPSILON * a.abs().max(1.0) {
        return (vec![a], decimals_for(a.abs().max(1e-12) / 10.0));
    }
    let raw = (b - a) / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    let first = (a / step).ceil() * step;
    let dec = decimals_for(step);
    let mut ticks = Vec::new();
    let mut k = 0;
    loop {
        let t = first + k as f64 * step;
        if t > b + step * 1e-9 {
            break;
        }
        // Snap rounding noise (0.6000000000000001 → 0.6, -0 → 0).
        let p = 10f64.powi(dec as i32);
        let t = (t * p).round() / p;
        ticks.push(if t == 0.0 { 0.0 } else { t });
        k += 1;
    }
    (ticks, dec)
}

fn decimals_for(step: f64) -> usize {
    let mut d = 0usize;
    while d < 8 && ((step * 10f64.powi(d as i32)).round() - step * 10f64.powi(d as i32)).abs() > 1e-6 {
        d += 1;
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(c: [f64; 3], r: [f64; 3], tol: f64) -> bool {
        (0..3).all(|i| (c[i] - r[i]).abs() <= tol)
    }

    #[test]
    fn polynomials_match_reference_tables() {
        // Entries 0, 64, 128, 192, 255 of the published 256-entry tables (matplotlib, Google).
        // Turbo: knots are exact; entries between knots (not in the code) within 0.01.
        assert!(close(Colormap::Turbo.rgb_f64(0.0), [0.18995, 0.07176, 0.23217], 1e-12));
        assert!(close(Colormap::Turbo.rgb_f64(1.0), [0.47960, 0.01583, 0.01055], 1e-12));
        let turbo_ref = [
            (4, [0.20860, 0.11802, 0.34607]),
            (44, [0.27106, 0.54015, 0.98930]),
            (100, [0.24797, 0.96423, 0.54303]),
            (172, [0.98549, 0.71250, 0.21650]),
            (252, [0.51989, 0.02756, 0.00780]),
        ];
        for (i, r) in turbo_ref {
            let c = Colormap::Turbo.rgb_f64(i as f64 / 255.0);
            assert!(close(c, r, 0.01), "turbo[{i}] = {c:?} vs {r:?}");
        }
        let viridis_ref = [
            (0, [0.267004, 0.004874, 0.329415]),
            (128, [0.127568, 0.566949, 0.550556]),
            (255, [0.993248, 0.906157, 0.143936]),
        ];
        for (i, r) in viridis_ref {
            let c = Colormap::Viridis.rgb_f64(i as f64 / 255.0);
            assert!(close(c, r, 0.02), "viridis[{i}] = {c:?} vs {r:?}");
        }
        let magma_ref = [
            (0, [0.001462, 0.000466, 0.013866]),
            (128, [0.716387, 0.214982, 0.475290]),
            (255, [0.987053, 0.991438, 0.749504]),
        ];
        for (i, r) in magma_ref {
            let c = Colormap::Magma.rgb_f64(i as f64 / 255.0);
            assert!(close(c, r, 0.02), "magma[{i}] = {c:?} vs {r:?}");
        }
        assert_eq!(Colormap::Gray.rgb(0.5), [128, 128, 128]);
        // Viridis and magma lightness increases monotonically (sum of channels as a proxy).
        for cm in [Colormap::Viridis, Colormap::Magma] {
            let l = cm.lut();
            let lum = |c: [u8; 3]| 0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64;
            for i in 8..256 {
                assert!(lum(l[i]) >= lum(l[i - 8]) - 1.0, "{cm} not monotone at {i}");
            }
        }
    }

    #[test]
    fn colorize_maps_range_and_invalid() {
        let img = Image::from_vec(4, 1, 1, vec![0.0, 10.0, f64::NAN, 20.0]).unwrap();
        let c = colorize(&img, 0.0, 10.0, Colormap::Gray);
        assert_eq!(c.channels, 3);
        assert_eq!(c.pixel(0, 0), &[0, 0, 0]);
        assert_eq!(c.pixel(1, 0), &[255, 255, 255]);
        assert_eq!(c.pixel(2, 0), &INVALID_RGB);
        assert_eq!(c.pixel(3, 0), &[255, 255, 255]); // clamped
        let rev = colorize(&img, 10.0, 0.0, Colormap::Gray);
        assert_eq!(rev.pixel(0, 0), &[255, 255, 255]);
        let flat = colorize(&img, 5.0, 5.0, Colormap::Gray);
        assert_eq!(flat.pixel(0, 0), &[128, 128, 128]);
        assert_eq!(finite_range(&img), Some((0.0, 20.0)));
        assert_eq!(percentile_range(&img, 0.0, 50.0), Some((0.0, 10.0)));
        assert_eq!("Viridis".parse::<Colormap>().unwrap(), Colormap::Viridis);
        assert!("jet".parse::<Colormap>().is_err());
    }

    #[test]
    fn nice_ticks_by_hand() {
        assert_eq!(nice_ticks(0.0, 1.0, 5), (vec![0.0, 0.2, 0.4, 0.6, 0.8, 1.0], 1));
        assert_eq!(nice_ticks(12.0, 97.0, 4), (vec![25.0, 50.0, 75.0], 0));
        assert_eq!(nice_ticks(0.3, 0.0, 3).0, vec![0.0, 0.1, 0.2, 0.3]);
        let (t, d) = nice_ticks(-0.013, 0.021, 4);
        assert_eq!(d, 2);
        assert_eq!(t, vec![-0.01, 0.0, 0.01, 0.02]);
        assert_eq!(nice_ticks(5.0, 5.0, 5).0, vec![5.0]);
    }
}
