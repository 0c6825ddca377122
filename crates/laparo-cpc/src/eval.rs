//! Does CPC help matching? The evaluation protocol of thesis §4.5.1 (Table 4.1, Figs. 4.8, 4.9,
//! 4.12): for two views with depth, intrinsics, ROI masks and ground-truth poses, each detector is
//! run on the original images and on the CPC-warped images (detect and match in the warped domain,
//! keypoints mapped back through the warp, evaluated in the original images), and the matches are
//! judged by the ground-truth transfer of `laparo_features::gt` (correct iff the two-way averaged
//! transfer error is below ε = 3 px).
//!
//! Defaults are the settings of the thesis code (`../shared/spec/features.md` §1): keypoints kept
//! in the ROI eroded by a 25 px disk; SIFT matched by `vl_ubcmatch` with threshold 2.8 (squared
//! distances, ≡ Lowe ratio 0.598, one-way); ORB matched by nearest neighbour (Hamming) with a
//! mutual check (the thesis says "NN" and gives no setting). In the warped domain the detector mask
//! is the warp's validity mask eroded by a few pixels (the black background around the warped
//! region would otherwise make corners), and a keypoint is kept only if it maps back into the
//! eroded ROI of the original image; scale and orientation are kept as detected (only positions
//! are evaluated).
use crate::error::{CpcError, Result};
use crate::lambda::{default_lambda_grid, LambdaSweep};
use crate::pipeline::{cpc_warp, CpcParams, CpcResult, CpcStats, LambdaChoice};
use crate::warp::Warp;
use laparo_core::camera::Intrinsics;
use laparo_core::depth::DepthMap;
use laparo_core::image::{Image, Mask};
use laparo_core::se3::Se3;
use laparo_core::table::Table;
use laparo_features::detect::to_gray_u8;
use laparo_features::gt::{evaluate_matches, DepthView, EvalConfig, GroundTruth, MatchEval, MatchLabel};
use laparo_features::{
    detect_and_describe, match_features, DetectorConfig, Features, Keypoint, Match, MatchConfig, OrbParams, RatioTest,
    SiftParams,
};
use rayon::prelude::*;
use serde::Serialize;

/// One view: image, metric depth (mm), intrinsics, ROI and the ground-truth pose.
#[derive(Clone, Copy)]
pub struct View<'a> {
    /// The image (grey or RGB, 8 bit).
    pub image: &'a Image<u8>,
    /// Depth along the optical axis (mm); must be finite inside `roi`.
    pub depth: &'a DepthMap,
    /// Pinhole intrinsics (px).
    pub intrinsics: &'a Intrinsics,
    /// Region of interest (the surface).
    pub roi: &'a Mask,
    /// Camera-from-world pose (mm), X_cam = R X_world + t.
    pub cam_from_world: Se3,
}

impl<'a> View<'a> {
    /// A rendered scene as a view (world = the surface patch frame).
    pub fn of_scene(s: &'a crate::scene::Scene) -> View<'a> {
        View { image: &s.image, depth: &s.depth, intrinsics: &s.intrinsics, roi: &s.roi, cam_from_world: s.pose }
    }
}

/// A detector + matcher combination (one row pair of Table 4.1).
#[derive(Clone, Debug, Serialize)]
pub struct Method {
    /// Name as in Table 4.1 ("SIFT+UBCMatcher", "ORB+NN").
    pub name: String,
    /// Detector and descriptor.
    pub detector: DetectorConfig,
    /// Matcher.
    pub matching: MatchConfig,
}

impl Method {
    /// SIFT (OpenCV defaults) + `vl_ubcmatch` with threshold 2.8, one-way (the thesis code).
    pub fn sift_ubcmatch(threshold: f32) -> Method {
        Method {
            name: "SIFT+UBCMatcher".into(),
            detector: DetectorConfig::Sift(SiftParams::default()),
            matching: MatchConfig { ratio: RatioTest::Ubc(threshold), mutual: false },
        }
    }

    /// ORB (OpenCV defaults) + nearest neighbour (Hamming) with a mutual check.
    pub fn orb_nn() -> Method {
        Method {
            name: "ORB+NN".into(),
            detector: DetectorConfig::Orb(OrbParams::default()),
            matching: MatchConfig { ratio: RatioTest::None, mutual: true },
        }
    }
}

/// Settings of the evaluation.
#[derive(Clone, Debug)]
pub struct EvalSettings {
    /// The methods (default: SIFT+UBCMatcher 2.8 and ORB+NN).
    pub methods: Vec<Method>,
    /// Keypoints are kept in the ROI eroded by a disk of this radius (px; thesis code: 25).
    pub roi_erosion_px: f64,
    /// In the warped image the detector runs inside the validity mask eroded by this radius (px).
    pub warped_mask_erosion_px: f64,
    /// Ground-truth protocol (ε = 3 px).
    pub gt: EvalConfig,
    /// CPC parameters (default: automatic λ, §4.5.4).
    pub cpc: CpcParams,
}

impl Default for EvalSettings {
    fn default() -> Self {
        EvalSettings {
            methods: vec![Method::sift_ubcmatch(2.8), Method::orb_nn()],
            roi_erosion_px: 25.0,
            warped_mask_erosion_px: 4.0,
            gt: EvalConfig::default(),
            cpc: CpcParams { lambda: CpcParams::auto_lambda(), ..CpcParams::default() },
        }
    }
}

/// The numbers of one method on one pair (one cell group of Table 4.1).
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Method name.
    pub method: String,
    /// Whether the images were CPC-warped.
    pub cpc: bool,
    /// Keypoints of image 1 / image 2 (inside the eroded ROI).
    pub n_keypoints: [usize; 2],
    /// #Crsp: matches returned by the matcher.
    pub n_matches: usize,
    /// #C.Crsp: matches whose two-way transfer error is below ε.
    pub n_correct: usize,
    /// Matches that cannot be verified (no depth, occluded, outside).
    pub n_unverifiable: usize,
    /// n_correct / n_matches.
    pub precision: f64,
    /// n_correct / n_matchable (see `laparo_features::gt`).
    pub recall: f64,
    /// Ground-truth matchable keypoint pairs (the recall denominator).
    pub n_matchable: usize,
    /// Matching score (see `laparo_features::gt`).
    pub matching_score: f64,
    /// Repeatability (see `laparo_features::gt`).
    pub repeatability: f64,
}

/// Keypoints, matches and their labels of one method on one pair (for match pictures).
#[derive(Clone, Debug)]
pub struct MethodRun {
    /// Summary numbers.
    pub row: Row,
    /// Keypoints of image 1, in original image coordinates.
    pub kp1: Vec<Keypoint>,
    /// Keypoints of image 2, in original image coordinates.
    pub kp2: Vec<Keypoint>,
    /// The matches.
    pub matches: Vec<Match>,
    /// Per match: correct, wrong or unverifiable.
    pub labels: Vec<MatchLabel>,
}

/// The result of [`evaluate_pair`].
pub struct PairEval {
    /// Per method: without CPC, then with CPC.
    pub runs: Vec<MethodRun>,
    /// CPC statistics of view 1 and view 2.
    pub cpc_stats: [CpcStats; 2],
    /// The λ sweeps of view 1 and view 2 when λ was automatic.
    pub sweeps: [Option<LambdaSweep>; 2],
    /// The two CPC results (warped images, warps).
    pub cpc: [CpcResult; 2],
}

/// Where a view is detected: the original or the warped image.
struct Domain<'a> {
    gray: Image<u8>,
    detect_mask: Mask,
    roi_eroded: &'a Mask,
    warp: Option<&'a Warp>,
}

fn original_domain<'a>(v: &View, roi_eroded: &'a Mask) -> Domain<'a> {
    Domain { gray: to_gray_u8(v.image), detect_mask: roi_eroded.clone(), roi_eroded, warp: None }
}

fn cpc_domain<'a>(r: &'a CpcResult, roi_eroded: &'a Mask, s: &EvalSettings) -> Domain<'a> {
    Domain {
        gray: to_gray_u8(&r.warped),
        detect_mask: r.mask.erode_disk(s.warped_mask_erosion_px),
        roi_eroded,
        warp: Some(&r.warp),
    }
}

fn feat_err(what: &str, e: laparo_features::FeaturesError) -> CpcError {
    CpcError::invalid(what, e.to_string())
}

/// Detect in the domain and return the features in original image coordinates (kept only inside
/// the eroded ROI).
fn detect(d: &Domain, det: &DetectorConfig) -> Result<Features> {
    let f = detect_and_describe(&d.gray, det, Some(&d.detect_mask)).map_err(|e| feat_err("detector", e))?;
    let mut keep = Vec::with_capacity(f.keypoints.len());
    let mut kps = Vec::with_capacity(f.keypoints.len());
    for (i, k) in f.keypoints.iter().enumerate() {
        let p = match d.warp {
            None => Some([k.x, k.y]),
            Some(w) => w.warped_to_original(k.x, k.y),
        };
        let Some(p) = p else { continue };
        let (x, y) = (p[0].round(), p[1].round());
        if x < 0.0 || y < 0.0 || x as usize >= d.roi_eroded.width || y as usize >= d.roi_eroded.height {
            continue;
        }
        if !d.roi_eroded.get(x as usize, y as usize, 0) {
            continue;
        }
        keep.push(i);
        kps.push(Keypoint { x: p[0], y: p[1], ..*k });
    }
    Ok(Features { keypoints: kps, descriptors: f.descriptors.select(&keep) })
}

fn row(method: &Method, cpc: bool, f1: &Features, f2: &Features, m: &[Match], e: &MatchEval) -> Row {
    Row {
        method: method.name.clone(),
        cpc,
        n_keypoints: [f1.len(), f2.len()],
        n_matches: e.n_matches,
        n_correct: e.n_correct,
        n_unverifiable: e.n_unverifiable,
        precision: e.precision,
        recall: e.recall,
        n_matchable: e.n_matchable,
        matching_score: e.matching_score,
        repeatability: e.repeatability,
    }
    .with_matches(m.len())
}

impl Row {
    fn with_matches(mut self, n: usize) -> Row {
        self.n_matches = n;
        self
    }

    /// Method name with the "CPC+" prefix when warped (Table 4.1).
    pub fn label(&self) -> String {
        if self.cpc {
            format!("CPC+{}", self.method)
        } else {
            self.method.clone()
        }
    }
}

fn run_method(
    d1: &Domain,
    d2: &Domain,
    gt: &GroundTruth,
    method: &Method,
    cfg: &EvalConfig,
    cpc: bool,
) -> Result<MethodRun> {
    let f1 = detect(d1, &method.detector)?;
    let f2 = detect(d2, &method.detector)?;
    let matches = match_features(&f1, &f2, &method.matching).map_err(|e| feat_err("matcher", e))?;
    let e =
        evaluate_matches(&f1.keypoints, &f2.keypoints, &matches, gt, cfg).map_err(|e| feat_err("ground truth", e))?;
    Ok(MethodRun {
        row: row(method, cpc, &f1, &f2, &matches, &e),
        labels: e.labels.clone(),
        kp1: f1.keypoints,
        kp2: f2.keypoints,
        matches,
    })
}

/// Check one view: sizes agree, depth finite and positive inside the ROI (names the view).
pub fn validate_view(v: &View, name: &str) -> Result<()> {
    let (w, h) = (v.image.width, v.image.height);
    if (v.depth.width, v.depth.height) != (w, h) || (v.roi.width, v.roi.height) != (w, h) {
        return Err(CpcError::SizeMismatch(format!(
            "{name}: image {w}x{h}, depth {}x{}, mask {}x{}",
            v.depth.width, v.depth.height, v.roi.width, v.roi.height
        )));
    }
    let d = v.depth.to_image();
    let bad =
        (0..w * h).filter(|&i| v.roi.data[i * v.roi.channels] && !(d.data[i].is_finite() && d.data[i] > 0.0)).count();
    if bad > 0 {
        return Err(CpcError::invalid(
            format!("{name} depth"),
            format!("{bad} pixels inside the mask have a NaN, infinite or non-positive depth"),
        ));
    }
    if v.roi.count() == 0 {
        return Err(CpcError::invalid(format!("{name} mask"), "is empty"));
    }
    Ok(())
}

/// The depth image for the ground truth: mm, 0 (= no depth) outside the ROI and wherever the
/// depth is missing (laparo writes NaN there; the protocol refuses NaN).
fn gt_depth(v: &View) -> Image<f64> {
    let mut d = v.depth.to_image();
    let to_mm = v.depth.unit.to_metres() * 1e3;
    for (i, z) in d.data.iter_mut().enumerate() {
        *z *= to_mm;
        if !v.roi.data[i * v.roi.channels] || !z.is_finite() {
            *z = 0.0;
        }
    }
    d
}

fn ground_truth<'a>(v1: &View<'a>, v2: &View<'a>, d1: &'a Image<f64>, d2: &'a Image<f64>) -> GroundTruth<'a> {
    GroundTruth::DepthPose(
        DepthView { depth_mm: d1, intrinsics: v1.intrinsics, cam_from_world: v1.cam_from_world, roi: Some(v1.roi) },
        DepthView { depth_mm: d2, intrinsics: v2.intrinsics, cam_from_world: v2.cam_from_world, roi: Some(v2.roi) },
    )
}

fn warp_view(v: &View, p: &CpcParams) -> Result<CpcResult> {
    cpc_warp(v.image, v.depth, v.intrinsics, v.roi, p)
}

/// Table 4.1 for one pair: every method without and with CPC.
pub fn evaluate_pair(v1: &View, v2: &View, s: &EvalSettings) -> Result<PairEval> {
    validate_view(v1, "view 1")?;
    validate_view(v2, "view 2")?;
    let (dm1, dm2) = (gt_depth(v1), gt_depth(v2));
    let gt = ground_truth(v1, v2, &dm1, &dm2);
    let (e1, e2) = (v1.roi.erode_disk(s.roi_erosion_px), v2.roi.erode_disk(s.roi_erosion_px));
    let (r1, r2) = rayon::join(|| warp_view(v1, &s.cpc), || warp_view(v2, &s.cpc));
    let (r1, r2) = (r1?, r2?);
    let (o1, o2) = (original_domain(v1, &e1), original_domain(v2, &e2));
    let (c1, c2) = (cpc_domain(&r1, &e1, s), cpc_domain(&r2, &e2, s));
    let jobs: Vec<(usize, bool)> = (0..s.methods.len()).flat_map(|i| [(i, false), (i, true)]).collect();
    let runs = jobs
        .par_iter()
        .map(|&(i, cpc)| {
            let (a, b) = if cpc { (&c1, &c2) } else { (&o1, &o2) };
            run_method(a, b, &gt, &s.methods[i], &s.gt, cpc)
        })
        .collect::<Result<Vec<_>>>()?;
    let cpc_stats = [r1.stats.clone(), r2.stats.clone()];
    let sweeps = [r1.sweep.clone(), r2.sweep.clone()];
    Ok(PairEval { runs, cpc_stats, sweeps, cpc: [r1, r2] })
}

impl PairEval {
    /// The rows (method without CPC, with CPC, next method ...).
    pub fn rows(&self) -> Vec<Row> {
        self.runs.iter().map(|r| r.row.clone()).collect()
    }

    /// Relative change of #correct with CPC for `method` ((with − without) / without; +inf when
    /// without is 0 and with is not).
    pub fn gain(&self, method: &str) -> Option<f64> {
        let get =
            |cpc: bool| self.runs.iter().find(|r| r.row.method == method && r.row.cpc == cpc).map(|r| r.row.n_correct);
        let (a, b) = (get(false)? as f64, get(true)? as f64);
        Some(if a == 0.0 {
            if b == 0.0 {
                0.0
            } else {
                f64::INFINITY
            }
        } else {
            (b - a) / a
        })
    }
}

/// Table 4.1-shaped table of one pair: method, #kp, #Crsp, #C.Crsp, precision, recall, …
pub fn pair_table(rows: &[Row]) -> Table {
    let mut t = Table::new([
        "method",
        "#kp1",
        "#kp2",
        "#Crsp",
        "#C.Crsp",
        "Precision",
        "Recall",
        "#matchable",
        "#unverifiable",
        "matching score",
        "repeatability",
    ]);
    for r in rows {
        t.push_row([
            r.label(),
            r.n_keypoints[0].to_string(),
            r.n_keypoints[1].to_string(),
            r.n_matches.to_string(),
            r.n_correct.to_string(),
            format!("{:.2}", r.precision),
            format!("{:.2}", r.recall),
            r.n_matchable.to_string(),
            r.n_unverifiable.to_string(),
            format!("{:.3}", r.matching_score),
            format!("{:.3}", r.repeatability),
        ]);
    }
    t
}

/// Table 4.1 proper: two pairs side by side ("easy / hard" in every cell).
pub fn easy_hard_table(easy: &[Row], hard: &[Row]) -> Table {
    let mut t = Table::new(["method", "#Crsp", "#C.Crsp", "Precision", "Recall"]);
    for (a, b) in easy.iter().zip(hard) {
        t.push_row([
            a.label(),
            format!("{} / {}", a.n_matches, b.n_matches),
            format!("{} / {}", a.n_correct, b.n_correct),
            format!("{:.2} / {:.2}", a.precision, b.precision),
            format!("{:.2} / {:.2}", a.recall, b.recall),
        ]);
    }
    t
}

/// CSV of rows (one line per row, all fields).
pub fn rows_csv(rows: &[Row]) -> String {
    let mut s = String::from(
        "method,cpc,n_kp1,n_kp2,n_matches,n_correct,n_unverifiable,precision,recall,n_matchable,matching_score,repeatability\n",
    );
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{}\n",
            r.method,
            r.cpc,
            r.n_keypoints[0],
            r.n_keypoints[1],
            r.n_matches,
            r.n_correct,
            r.n_unverifiable,
            r.precision,
            r.recall,
            r.n_matchable,
            r.matching_score,
            r.repeatability
        ));
    }
    s
}

/// Match picture like Fig. 4.8: the two original images side by side, correct matches green,
/// wrong red, unverifiable yellow.
pub fn match_picture(img1: &Image<u8>, img2: &Image<u8>, run: &MethodRun) -> Image<u8> {
    let colours: Vec<[u8; 3]> = run
        .labels
        .iter()
        .map(|l| match l {
            MatchLabel::Correct => [0, 220, 0],
            MatchLabel::Wrong => [230, 0, 0],
            MatchLabel::Unverifiable => [240, 220, 0],
        })
        .collect();
    laparo_features::draw_matches(&img1.to_rgb(), &img2.to_rgb(), &run.kp1, &run.kp2, &run.matches, &colours)
}

/// One λ of the matching sweep (Fig. 4.12).
#[derive(Clone, Debug, Serialize)]
pub struct LambdaMatchPoint {
    /// λ applied to both views.
    pub lambda: f64,
    /// #correct per method (order of [`EvalSettings::methods`]).
    pub n_correct: Vec<usize>,
    /// δ_area (eq. 4.13) of view 1 and view 2 at this λ.
    pub delta_area: [f64; 2],
}

/// The matching λ sweep: #correct against λ, with δ_area and the automatic ℓ.
#[derive(Clone, Debug, Serialize)]
pub struct LambdaMatchSweep {
    /// Method names.
    pub methods: Vec<String>,
    /// One point per λ.
    pub points: Vec<LambdaMatchPoint>,
    /// Automatic λ of view 1 and view 2 (§4.5.4; fallback when the fit failed).
    pub ell: [f64; 2],
    /// #correct per method with the automatic λ of each view.
    pub n_correct_auto: Vec<usize>,
    /// #correct per method without CPC.
    pub n_correct_plain: Vec<usize>,
}

/// #correct against λ (same λ on both views) for every method, plus the automatic choice.
pub fn lambda_match_sweep(v1: &View, v2: &View, s: &EvalSettings, grid: &[f64]) -> Result<LambdaMatchSweep> {
    validate_view(v1, "view 1")?;
    validate_view(v2, "view 2")?;
    for &l in grid {
        crate::solve::validate_lambda(l)?;
    }
    let (dm1, dm2) = (gt_depth(v1), gt_depth(v2));
    let gt = ground_truth(v1, v2, &dm1, &dm2);
    let (e1, e2) = (v1.roi.erode_disk(s.roi_erosion_px), v2.roi.erode_disk(s.roi_erosion_px));
    let count = |d1: &Domain, d2: &Domain, cpc: bool| -> Result<Vec<usize>> {
        s.methods.iter().map(|m| Ok(run_method(d1, d2, &gt, m, &s.gt, cpc)?.row.n_correct)).collect()
    };
    let n_correct_plain = count(&original_domain(v1, &e1), &original_domain(v2, &e2), false)?;
    let auto = CpcParams { lambda: LambdaChoice::Auto(default_lambda_grid()), ..s.cpc.clone() };
    let (a1, a2) = (warp_view(v1, &auto)?, warp_view(v2, &auto)?);
    let ell = [a1.stats.lambda, a2.stats.lambda];
    let n_correct_auto = count(&cpc_domain(&a1, &e1, s), &cpc_domain(&a2, &e2, s), true)?;
    let points = grid
        .par_iter()
        .map(|&l| {
            let p = CpcParams { lambda: LambdaChoice::Fixed(l), ..s.cpc.clone() };
            let (r1, r2) = (warp_view(v1, &p)?, warp_view(v2, &p)?);
            let n = count(&cpc_domain(&r1, &e1, s), &cpc_domain(&r2, &e2, s), true)?;
            Ok(LambdaMatchPoint { lambda: l, n_correct: n, delta_area: [r1.stats.delta_area, r2.stats.delta_area] })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(LambdaMatchSweep {
        methods: s.methods.iter().map(|m| m.name.clone()).collect(),
        points,
        ell,
        n_correct_auto,
        n_correct_plain,
    })
}

impl LambdaMatchSweep {
    /// CSV: `lambda,<method>_correct...,delta_area_1,delta_area_2`.
    pub fn to_csv(&self) -> String {
        let mut s = String::from("lambda");
        for m in &self.methods {
            s.push_str(&format!(",{}_correct", m.replace('+', "_")));
        }
        s.push_str(",delta_area_1,delta_area_2\n");
        for p in &self.points {
            s.push_str(&p.lambda.to_string());
            for n in &p.n_correct {
                s.push_str(&format!(",{n}"));
            }
            s.push_str(&format!(",{},{}\n", p.delta_area[0], p.delta_area[1]));
        }
        s
    }

    /// Sweep maximum of #correct for method `i`.
    pub fn max_correct(&self, i: usize) -> usize {
        self.points.iter().map(|p| p.n_correct[i]).max().unwrap_or(0)
    }

    /// Fig. 4.12-like PNG: #correct against λ per method (left axis), δ_area of both views
    /// (right axis, dashed) and the automatic ℓ of each view (vertical lines).
    pub fn plot_png(&self, path: &std::path::Path) -> Result<()> {
        use plotters::prelude::*;
        let nmax = self.points.iter().flat_map(|p| p.n_correct.iter().copied()).max().unwrap_or(1).max(1) as f64 * 1.1;
        let dmax =
            self.points.iter().flat_map(|p| p.delta_area).filter(|v| v.is_finite()).fold(0.1_f64, f64::max) * 1.1;
        let me = self.clone();
        laparo_core::plot::draw_png(path, 820, 500, move |root| {
            let mut chart = ChartBuilder::on(&root)
                .caption("#correct matches vs λ (Fig. 4.12); δ_area dashed, automatic ℓ vertical", ("sans-serif", 19))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(55)
                .right_y_label_area_size(55)
                .build_cartesian_2d(0f64..1f64, 0f64..nmax)?
                .set_secondary_coord(0f64..1f64, 0f64..dmax);
            chart.configure_mesh().x_desc("λ").y_desc("#correct (transfer error < 3 px)").draw()?;
            chart.configure_secondary_axes().y_desc("δ_area (eq. 4.13)").draw()?;
            let colours = [BLUE, RED, GREEN, MAGENTA];
            for (i, name) in me.methods.iter().enumerate() {
                let c = colours[i % colours.len()];
                chart
                    .draw_series(LineSeries::new(
                        me.points.iter().map(|p| (p.lambda, p.n_correct[i] as f64)),
                        c.stroke_width(2),
                    ))?
                    .label(format!("CPC+{name}"))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
                chart.draw_series(
                    me.points.iter().map(|p| Circle::new((p.lambda, p.n_correct[i] as f64), 3, c.filled())),
                )?;
                let y0 = me.n_correct_plain[i] as f64;
                chart
                    .draw_series(LineSeries::new(vec![(0.0, y0), (1.0, y0)], c.mix(0.4).stroke_width(1)))?
                    .label(format!("{name} without CPC"))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.mix(0.4).stroke_width(1)));
            }
            for (v, c) in [(0usize, BLACK), (1, RGBColor(120, 120, 120))] {
                let pts: Vec<(f64, f64)> = me.points.iter().map(|p| (p.lambda, p.delta_area[v])).collect();
                chart
                    .draw_secondary_series(DashedLineSeries::new(pts, 6, 4, c.stroke_width(2)))?
                    .label(format!("δ_area view {}", v + 1))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
                let l = me.ell[v];
                chart
                    .draw_series(LineSeries::new(vec![(l, 0.0), (l, nmax)], c.stroke_width(1)))?
                    .label(format!("ℓ view {} = {l:.3}", v + 1))
                    .legend(move |(x, y)| PathElement::new(vec![(x + 10, y - 6), (x + 10, y + 6)], c.stroke_width(1)));
            }
            chart.configure_series_labels().position(SeriesLabelPosition::UpperLeft).border_style(BLACK).draw()?;
            Ok(())
        })?;
        Ok(())
    }
}

/// One frame of the sequence mode (§4.5.2, Fig. 4.9).
#[derive(Clone, Debug, Serialize)]
pub struct SequenceRow {
    /// Frame index.
    pub frame: usize,
    /// Method name.
    pub method: String,
    /// #correct without CPC.
    pub n_correct: usize,
    /// #correct with CPC.
    pub n_correct_cpc: usize,
    /// #matches without / with CPC.
    pub n_matches: [usize; 2],
    /// n_correct_cpc / n_correct (NaN when both are 0, +inf when only the plain count is 0).
    pub ratio: f64,
}

/// Sequence mode (§4.5.2): every frame against `frames[keyframe]`, with and without CPC.
pub fn evaluate_sequence(frames: &[View], keyframe: usize, s: &EvalSettings) -> Result<Vec<SequenceRow>> {
    if keyframe >= frames.len() {
        return Err(CpcError::invalid("keyframe", format!("{keyframe} is not below the {} frames", frames.len())));
    }
    for (i, f) in frames.iter().enumerate() {
        validate_view(f, &format!("frame {i}"))?;
    }
    let key = &frames[keyframe];
    let rows = frames
        .par_iter()
        .enumerate()
        .filter(|(i, _)| *i != keyframe)
        .map(|(i, f)| -> Result<Vec<SequenceRow>> {
            let e = evaluate_pair(key, f, s)?;
            Ok(s.methods
                .iter()
                .map(|m| {
                    let get = |cpc: bool| e.runs.iter().find(|r| r.row.method == m.name && r.row.cpc == cpc).unwrap();
                    let (a, b) = (get(false), get(true));
                    let ratio = b.row.n_correct as f64 / a.row.n_correct as f64;
                    SequenceRow {
                        frame: i,
                        method: m.name.clone(),
                        n_correct: a.row.n_correct,
                        n_correct_cpc: b.row.n_correct,
                        n_matches: [a.row.n_matches, b.row.n_matches],
                        ratio,
                    }
                })
                .collect())
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(rows.into_iter().flatten().collect())
}

/// CSV of the sequence rows.
pub fn sequence_csv(rows: &[SequenceRow]) -> String {
    let mut s = String::from("frame,method,n_correct,n_correct_cpc,n_matches,n_matches_cpc,ratio\n");
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{},{},{},{}\n",
            r.frame, r.method, r.n_correct, r.n_correct_cpc, r.n_matches[0], r.n_matches[1], r.ratio
        ));
    }
    s
}

/// Fig. 4.9-like PNG: #correct per frame with and without CPC (top) and their ratio (bottom).
pub fn plot_sequence_png(rows: &[SequenceRow], path: &std::path::Path) -> Result<()> {
    use plotters::prelude::*;
    let rows = rows.to_vec();
    let mut methods: Vec<String> = Vec::new();
    for r in &rows {
        if !methods.contains(&r.method) {
            methods.push(r.method.clone());
        }
    }
    let fmax = rows.iter().map(|r| r.frame).max().unwrap_or(1) as f64 + 0.5;
    let nmax = rows.iter().map(|r| r.n_correct.max(r.n_correct_cpc)).max().unwrap_or(1).max(1) as f64 * 1.1;
    let rmax = rows.iter().map(|r| r.ratio).filter(|v| v.is_finite()).fold(2.0_f64, f64::max) * 1.1;
    laparo_core::plot::draw_png(path, 820, 640, move |root| {
        let (top, bottom) = root.split_vertically(360);
        let colours = [BLUE, RED, GREEN, MAGENTA];
        let mut c1 = ChartBuilder::on(&top)
            .caption("sequence: every frame vs the keyframe (Fig. 4.9)", ("sans-serif", 19))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(-0.5f64..fmax, 0f64..nmax)?;
        c1.configure_mesh().x_desc("frame").y_desc("#correct").draw()?;
        for (i, m) in methods.iter().enumerate() {
            let c = colours[i % colours.len()];
            let plain: Vec<(f64, f64)> =
                rows.iter().filter(|r| &r.method == m).map(|r| (r.frame as f64, r.n_correct as f64)).collect();
            let cpc: Vec<(f64, f64)> =
                rows.iter().filter(|r| &r.method == m).map(|r| (r.frame as f64, r.n_correct_cpc as f64)).collect();
            c1.draw_series(DashedLineSeries::new(plain, 5, 4, c.stroke_width(2)))?
                .label(m.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(1)));
            c1.draw_series(LineSeries::new(cpc, c.stroke_width(2)))?
                .label(format!("CPC+{m}"))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(3)));
        }
        c1.configure_series_labels().position(SeriesLabelPosition::UpperRight).border_style(BLACK).draw()?;
        let mut c2 = ChartBuilder::on(&bottom)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(-0.5f64..fmax, 0f64..rmax)?;
        c2.configure_mesh().x_desc("frame").y_desc("#correct ratio CPC / without").draw()?;
        c2.draw_series(LineSeries::new(vec![(-0.5, 1.0), (fmax, 1.0)], BLACK.mix(0.5)))?;
        for (i, m) in methods.iter().enumerate() {
            let c = colours[i % colours.len()];
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| &r.method == m && r.ratio.is_finite())
                .map(|r| (r.frame as f64, r.ratio))
                .collect();
            c2.draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))?;
            c2.draw_series(pts.into_iter().map(|p| Circle::new(p, 3, c.filled())))?;
        }
        Ok(())
    })?;
    Ok(())
}
