//! `laparo mesh ...`: volume meshing and incisions for the in-silico incision benchmark (thesis §5.4.2).
use anyhow::{bail, Context, Result};
use clap::{Subcommand, ValueEnum};
use laparo_core::mesh::{read_mesh, read_msh, read_vtk, write_msh, write_vtk, TetMesh};
use laparo_fem::mesh::{
    anatomical_on, non_anatomical_on, tetrahedralize_surface, AnatomicalParams, NonAnatomicalParams, Scenario,
    ScenarioFrame, TetraParams,
};
use nalgebra::Vector3;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

type V3 = Vector3<f64>;

/// The blade of a benchmark incision and the fixed region (register.md §4); every flag defaults to the
/// benchmark's scenario, so a run without them is the thesis-sized cut.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct CutArgs {
    /// Incision length along the organ surface (mm); default 60 (non-anatomical) or 100 (anatomical).
    #[arg(long)]
    pub cut_length_mm: Option<f64>,
    /// Non-anatomical blade depth below the surface (mm); default 25.
    #[arg(long)]
    pub cut_depth_mm: Option<f64>,
    /// Anatomical blade depth as a fraction of the local thickness (its median over ±10 mm along the cut, so a fold
    /// of the surface leaves no uncut slot), in (0, 1); default 0.6.
    #[arg(long)]
    pub cut_depth_fraction: Option<f64>,
    /// Anatomical cut plane shifted along its normal (mm, + towards side B); default 0. On the P2ILF liver
    /// the default plane splits an anterior ridge (side A's wall ≈ 10 mm); −15 cuts into the bulk.
    #[arg(long, allow_hyphen_values = true)]
    pub cut_offset_mm: Option<f64>,
    /// Fraction of the outer-surface nodes held fixed (the most posterior ones), in (0, 1); default 0.15.
    #[arg(long)]
    pub fixed_fraction: Option<f64>,
}

impl CutArgs {
    /// Fails when a depth flag is given but none of `scenarios` ("non-anatomical", "anatomical") takes it.
    pub fn check_for(&self, scenarios: &[&str]) -> Result<()> {
        if let Some(f) = self.cut_depth_fraction.filter(|_| !scenarios.contains(&"anatomical")) {
            bail!(
                "--cut-depth-fraction {f}: that is the anatomical blade's depth; the non-anatomical blade takes \
                 --cut-depth-mm"
            );
        }
        if let Some(o) = self.cut_offset_mm.filter(|_| !scenarios.contains(&"anatomical")) {
            bail!("--cut-offset-mm {o}: only the anatomical (planar) cut has a plane to shift");
        }
        if let Some(d) = self.cut_depth_mm.filter(|_| !scenarios.contains(&"non-anatomical")) {
            bail!(
                "--cut-depth-mm {d}: that is the non-anatomical blade's depth; the anatomical blade takes \
                 --cut-depth-fraction (of the local thickness)"
            );
        }
        Ok(())
    }

    /// The scenario frame with `--fixed-fraction` applied.
    pub fn frame(&self, mut frame: ScenarioFrame) -> Result<ScenarioFrame> {
        if let Some(f) = self.fixed_fraction {
            if !(f > 0.0 && f < 1.0) {
                bail!("--fixed-fraction {f}: must be in (0, 1)");
            }
            frame.fixed_fraction = f;
        }
        Ok(frame)
    }

    /// Scenario (i)'s parameters with `--cut-length-mm` and `--cut-depth-mm` applied.
    pub fn non_anatomical(&self) -> Result<NonAnatomicalParams> {
        let mut p = NonAnatomicalParams::default();
        if let Some(l) = self.cut_length_mm {
            p.length_mm = positive_mm("--cut-length-mm", l)?;
        }
        if let Some(d) = self.cut_depth_mm {
            p.depth_mm = positive_mm("--cut-depth-mm", d)?;
        }
        Ok(p)
    }

    /// Scenario (ii)'s parameters with `--cut-length-mm` and `--cut-depth-fraction` applied.
    pub fn anatomical(&self) -> Result<AnatomicalParams> {
        let mut p = AnatomicalParams::default();
        if let Some(l) = self.cut_length_mm {
            p.length_mm = positive_mm("--cut-length-mm", l)?;
        }
        if let Some(f) = self.cut_depth_fraction {
            if !(f > 0.0 && f < 1.0) {
                bail!("--cut-depth-fraction {f}: must be in (0, 1)");
            }
            p.depth_fraction = f;
        }
        if let Some(o) = self.cut_offset_mm {
            if !o.is_finite() {
                bail!("--cut-offset-mm {o}: must be a finite shift (mm)");
            }
            p.offset_mm = o;
        }
        Ok(p)
    }
}

fn positive_mm(flag: &str, v: f64) -> Result<f64> {
    if !(v.is_finite() && v > 0.0) {
        bail!("{flag} {v}: must be a finite length > 0 (mm)");
    }
    Ok(v)
}

/// Which benchmark incision.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ScenarioKind {
    /// (i) Virtual tumour r 12 mm, 20 mm deep; curved wedge cut 10 mm outside it, 60 mm long, 25 mm deep.
    NonAnatomical,
    /// (ii) Planar Cantlie-like cut, 100 mm long, 60 % of the local thickness deep.
    Anatomical,
}

#[derive(Subcommand)]
pub enum MeshCmd {
    /// Tetrahedralise a closed surface (OBJ/PLY/STL, mm) on a BCC lattice with boundary snapping;
    /// writes Gmsh `.msh` or legacy `.vtk` tetrahedra and optionally a quality report (JSON).
    Tetra {
        /// Closed triangle surface (mm).
        #[arg(long)]
        surface: PathBuf,
        /// Target edge length = lattice spacing (mm).
        #[arg(long, default_value_t = 6.0)]
        edge_mm: f64,
        /// Smallest dihedral angle a boundary snap may leave (deg).
        #[arg(long, default_value_t = 10.0)]
        min_dihedral_deg: f64,
        /// Output tet mesh (.vtk or .msh).
        #[arg(long)]
        out: PathBuf,
        /// Quality report (JSON).
        #[arg(long)]
        report: Option<PathBuf>,
    },
    /// Cut a tet mesh (.vtk/.msh, mm) with a benchmark incision; writes into DIR: cut.vtk (cell
    /// data `side`: 1/2 = tets owning lip A/B crack faces), lips.json, landmarks.json (N = 20, 50,
    /// 250), tumour.json, fixed_nodes.json, scenario.json, cut.png and crack.png (the crack face-on).
    Incision {
        /// Tetrahedral mesh (.vtk or .msh, mm), e.g. from `laparo mesh tetra`.
        #[arg(long)]
        mesh: PathBuf,
        /// Scenario.
        #[arg(long, value_enum)]
        scenario: ScenarioKind,
        /// Anterior axis "x,y,z" (default: the P2ILF liver's, from its falciform-ligament contour).
        #[arg(long)]
        anterior: Option<String>,
        /// Organ surface (.obj/.ply/.stl/.off, mm) to trace the blade on, e.g. the one `--mesh` was made from:
        /// every mesh of one surface then gets the same cut (default: the tet mesh's own boundary).
        #[arg(long)]
        surface: Option<PathBuf>,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        cut: CutArgs,
    },
}

pub fn run(c: MeshCmd) -> Result<()> {
    match c {
        MeshCmd::Tetra { surface, edge_mm, min_dihedral_deg, out, report } => {
            tetra_cmd(&surface, edge_mm, min_dihedral_deg, &out, report.as_deref())
        }
        MeshCmd::Incision { mesh, scenario, anterior, surface, out, cut } => {
            incision_cmd(&mesh, scenario, anterior.as_deref(), surface.as_deref(), &out, &cut)
        }
    }
}

fn write_tets(path: &Path, m: &TetMesh) -> Result<()> {
    match path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
        Some("vtk") => write_vtk(path, m)?,
        Some("msh") => write_msh(path, m)?,
        _ => bail!("{}: output must end in .vtk or .msh", path.display()),
    }
    Ok(())
}

fn read_tets(path: &Path) -> Result<TetMesh> {
    let m = match path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
        Some("vtk") => read_vtk(path)?,
        Some("msh") => read_msh(path)?,
        _ => bail!("{}: tet mesh must be .vtk or .msh", path.display()),
    };
    if m.tets.is_empty() {
        bail!("{}: no tetrahedra", path.display());
    }
    Ok(m)
}

fn write_json(path: &Path, v: &serde_json::Value) -> Result<()> {
    laparo_core::atomic::write_atomic(path, serde_json::to_string_pretty(v)?.as_bytes())?;
    Ok(())
}

/// Most candidate tetrahedra `mesh tetra` builds (about 3 GB at 100 bytes each): a 1.5 mm mesh of a
/// 200 mm liver fits.
const MAX_TETRA_CANDIDATES: f64 = 3e7;

fn tetra_cmd(surface: &Path, edge_mm: f64, min_dihedral_deg: f64, out: &Path, report: Option<&Path>) -> Result<()> {
    let mut outputs = vec![out];
    outputs.extend(report);
    laparo_core::atomic::refuse_overwrite_files(&outputs, &[surface]).context("--out / --report")?;
    super::check::positive("--edge-mm", edge_mm)?;
    super::check::number("--min-dihedral-deg", min_dihedral_deg, 0.0..60.0)?;
    let t0 = Instant::now();
    let tri = read_mesh(surface)?;
    if let Some((lo, hi)) = tri.bounding_box() {
        // The BCC lattice over the bounding box: 12 candidate tetrahedra per cell, allocated before
        // the inside test; refuse a spacing that would take gigabytes.
        let cells: f64 = (0..3).map(|d| ((hi[d] - lo[d]) / edge_mm).ceil() + 2.0).product();
        super::check::budget(
            &format!("--edge-mm {edge_mm} on {} ({:.1} mm across)", surface.display(), (hi - lo).norm()),
            12.0 * cells,
            MAX_TETRA_CANDIDATES,
            "lattice tetrahedra",
        )?;
    }
    let params = TetraParams { edge_mm, min_dihedral_deg, ..TetraParams::default() };
    let (tets, q) = tetrahedralize_surface(tri, &surface.display().to_string(), &params)?;
    let secs = t0.elapsed().as_secs_f64();
    write_tets(out, &tets)?;
    if let Some(r) = report {
        let mut v = serde_json::to_value(&q)?;
        v["params"] = serde_json::to_value(&params)?;
        v["surface"] = json!(surface.display().to_string());
        v["seconds"] = json!(secs);
        write_json(r, &v)?;
    }
    println!(
        "{}: {} nodes, {} tets, min dihedral {:.1}°, volume {:.0} mm³ vs surface {:.0} mm³ ({:+.3} %), max boundary distance {:.3} mm, {:.2} s",
        out.display(),
        q.nodes,
        q.tets,
        q.min_dihedral_deg,
        q.volume_mm3,
        q.surface_volume_mm3.unwrap_or(f64::NAN),
        100.0 * q.volume_rel_error.unwrap_or(f64::NAN),
        q.max_boundary_distance_mm.unwrap_or(f64::NAN),
        secs
    );
    for w in &q.warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}

fn parse_axis(s: &str) -> Result<[f64; 3]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .with_context(|| format!("--anterior '{s}': expected three numbers x,y,z"))?;
    if v.len() != 3 || !v.iter().all(|x| x.is_finite()) || v.iter().all(|&x| x == 0.0) {
        bail!("--anterior '{s}': expected three finite numbers x,y,z, not all zero");
    }
    Ok([v[0], v[1], v[2]])
}

fn v3(v: &V3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// The files `mesh incision` writes into its folder.
const INCISION_OUTPUTS: [&str; 8] = [
    "cut.vtk",
    "lips.json",
    "landmarks.json",
    "tumour.json",
    "fixed_nodes.json",
    "scenario.json",
    "cut.png",
    "crack.png",
];

fn incision_cmd(
    mesh_path: &Path,
    kind: ScenarioKind,
    anterior: Option<&str>,
    surface: Option<&Path>,
    out: &Path,
    cut_args: &CutArgs,
) -> Result<()> {
    let mut inputs = vec![mesh_path];
    inputs.extend(surface);
    laparo_core::atomic::refuse_overwrite_in(out, &INCISION_OUTPUTS, &inputs).context("--out")?;
    let t0 = Instant::now();
    let mut mesh = read_tets(mesh_path)?;
    mesh.orient_positive();
    cut_args.check_for(&[match kind {
        ScenarioKind::NonAnatomical => "non-anatomical",
        ScenarioKind::Anatomical => "anatomical",
    }])?;
    let mut frame = cut_args.frame(ScenarioFrame::default())?;
    if let Some(a) = anterior {
        frame.anterior = parse_axis(a)?;
    }
    let organ = match surface {
        Some(p) => {
            let s = read_mesh(p)?;
            laparo_fem::mesh::check_closed(&s, &p.display().to_string())?;
            s
        }
        None => mesh.boundary(),
    };
    let (sc, params) = match kind {
        ScenarioKind::NonAnatomical => {
            let p = cut_args.non_anatomical()?;
            (non_anatomical_on(&mesh, &organ, &frame, &p), serde_json::to_value(&p)?)
        }
        ScenarioKind::Anatomical => {
            let p = cut_args.anatomical()?;
            (anatomical_on(&mesh, &organ, &frame, &p), serde_json::to_value(&p)?)
        }
    };
    let sc = sc.with_context(|| format!("cutting {}", mesh_path.display()))?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let cut = &sc.cut;
    cut.write_vtk(&out.join("cut.vtk"))?;
    let x = &cut.mesh.vertices;
    let lip = |s: usize| {
        json!({
            "nodes": cut.lips[s],
            "positions_mm": cut.lip_positions(s, x).iter().map(v3).collect::<Vec<_>>(),
            "length_mm": cut.lip_length(s),
        })
    };
    write_json(&out.join("lips.json"), &json!({"side_a": lip(0), "side_b": lip(1)}))?;
    let mut lms = serde_json::Map::new();
    for n in [20, 50, 250] {
        let l = cut.landmarks(n)?;
        let pos: Vec<[f64; 3]> = l.landmark_positions(x).iter().map(v3).collect();
        lms.insert(n.to_string(), json!({"items": l.items, "positions_mm": pos}));
    }
    write_json(&out.join("landmarks.json"), &serde_json::Value::Object(lms))?;
    write_json(&out.join("tumour.json"), &serde_json::to_value(sc.tumour)?)?;
    write_json(&out.join("fixed_nodes.json"), &json!({"fixed_nodes": sc.fixed_nodes, "anterior": v3(&sc.anterior)}))?;
    let summary = json!({
        "scenario": sc.name,
        "mesh": mesh_path.display().to_string(),
        "params": params,
        "frame": frame,
        "anterior": v3(&sc.anterior),
        "entry_point_mm": v3(&sc.entry_point),
        "min_margin_mm": sc.min_margin_mm,
        "nodes_in": mesh.vertices.len(),
        "nodes_out": cut.mesh.vertices.len(),
        "tets": cut.mesh.tets.len(),
        "crack_faces": [cut.crack_faces[0].len(), cut.crack_faces[1].len()],
        "front_nodes": cut.front_nodes.len(),
        "lip_length_mm": [cut.lip_length(0), cut.lip_length(1)],
        "fixed_nodes": sc.fixed_nodes.len(),
        "blade": sc.blade,
        "crack_faces_a": cut.crack_faces[0],
        "crack_faces_b": cut.crack_faces[1],
        "original_node": cut.original_node,
    });
    write_json(&out.join("scenario.json"), &summary)?;
    let img = render(&sc);
    laparo_core::plot::save_rgb_png(out.join("cut.png"), img.0, img.1, &img.2)?;
    // the crack face-on, unrolled along the blade: its faces, its front (dots) and the blade (red); a hole inside
    // the outline is tissue the blade did not cut
    laparo_register::benchmark::figures::write_crack_opening(
        &out.join("crack.png"),
        &sc,
        None,
        &format!("{}: the crack face-on (front: dots, blade: red)", sc.name),
    )?;
    println!(
        "{}: {} cut, {} → {} nodes, {} tets, {} + {} crack faces, lips {:.1} / {:.1} mm{}, {} fixed nodes, {:.2} s",
        out.display(),
        sc.name,
        mesh.vertices.len(),
        cut.mesh.vertices.len(),
        cut.mesh.tets.len(),
        cut.crack_faces[0].len(),
        cut.crack_faces[1].len(),
        cut.lip_length(0),
        cut.lip_length(1),
        sc.min_margin_mm.map(|m| format!(", margin ≥ {m:.1} mm")).unwrap_or_default(),
        sc.fixed_nodes.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// One orthographic panel: shaded outer surface, crack faces blended over it (red = A, blue = B),
/// lips, landmarks (N = 50), tumour outline and fixed nodes.
struct Panel {
    w: usize,
    h: usize,
    rgb: Vec<u8>,
    r: V3,
    u: V3,
    f: V3,
    scale: f64,
    c: (f64, f64),
}

impl Panel {
    fn new(w: usize, h: usize, view: V3, up: V3, pts: &[V3]) -> Self {
        let f = view.normalize();
        let r = f.cross(&up).normalize();
        let u = r.cross(&f);
        let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for p in pts {
            x0 = x0.min(p.dot(&r));
            x1 = x1.max(p.dot(&r));
            y0 = y0.min(p.dot(&u));
            y1 = y1.max(p.dot(&u));
        }
        let scale = 0.9 * (w as f64 / (x1 - x0)).min(h as f64 / (y1 - y0));
        Panel { w, h, rgb: vec![255; w * h * 3], r, u, f, scale, c: ((x0 + x1) / 2.0, (y0 + y1) / 2.0) }
    }
    fn project(&self, p: &V3) -> (f64, f64, f64) {
        (
            self.w as f64 / 2.0 + (p.dot(&self.r) - self.c.0) * self.scale,
            self.h as f64 / 2.0 - (p.dot(&self.u) - self.c.1) * self.scale,
            p.dot(&self.f),
        )
    }
    /// Rasterise triangles with a z-buffer; returns per-pixel colour (None = empty) and depth.
    fn raster(&self, tris: &[([V3; 3], [f64; 3])]) -> (Vec<Option<[f64; 3]>>, Vec<f64>) {
        let mut z = vec![f64::INFINITY; self.w * self.h];
        let mut col = vec![None; self.w * self.h];
        for (p, c) in tris {
            let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
            if n.norm() == 0.0 {
                continue;
            }
            let shade = 0.35 + 0.65 * n.normalize().dot(&self.f).abs();
            let q = p.map(|x| self.project(&x));
            let (xa, xb) = (
                q.iter().map(|v| v.0).fold(f64::INFINITY, f64::min),
                q.iter().map(|v| v.0).fold(f64::NEG_INFINITY, f64::max),
            );
            let (ya, yb) = (
                q.iter().map(|v| v.1).fold(f64::INFINITY, f64::min),
                q.iter().map(|v| v.1).fold(f64::NEG_INFINITY, f64::max),
            );
            let d = (q[1].0 - q[0].0) * (q[2].1 - q[0].1) - (q[2].0 - q[0].0) * (q[1].1 - q[0].1);
            if d.abs() < 1e-12 {
                continue;
            }
            for py in (ya.floor().max(0.0) as usize)..=(yb.ceil().min(self.h as f64 - 1.0).max(0.0) as usize) {
                for px in (xa.floor().max(0.0) as usize)..=(xb.ceil().min(self.w as f64 - 1.0).max(0.0) as usize) {
                    let (x, y) = (px as f64 + 0.5, py as f64 + 0.5);
                    let b1 = ((x - q[0].0) * (q[2].1 - q[0].1) - (q[2].0 - q[0].0) * (y - q[0].1)) / d;
                    let b2 = ((q[1].0 - q[0].0) * (y - q[0].1) - (x - q[0].0) * (q[1].1 - q[0].1)) / d;
                    let b0 = 1.0 - b1 - b2;
                    if b0 < 0.0 || b1 < 0.0 || b2 < 0.0 {
                        continue;
                    }
                    let depth = b0 * q[0].2 + b1 * q[1].2 + b2 * q[2].2;
                    let k = py * self.w + px;
                    if depth < z[k] {
                        z[k] = depth;
                        col[k] = Some(c.map(|v| v * shade));
                    }
                }
            }
        }
        (col, z)
    }
    /// True when `p` is not hidden by the surface depth buffer `z` (2 mm tolerance).
    fn visible(&self, p: &V3, z: &[f64]) -> bool {
        let (x, y, d) = self.project(p);
        if x < 0.0 || y < 0.0 || x as usize >= self.w || y as usize >= self.h {
            return false;
        }
        d <= z[y as usize * self.w + x as usize] + 2.0
    }
    fn dot(&mut self, p: &V3, rad: i64, c: [u8; 3]) {
        let (x, y, _) = self.project(p);
        for dy in -rad..=rad {
            for dx in -rad..=rad {
                let (px, py) = (x as i64 + dx, y as i64 + dy);
                if px >= 0 && py >= 0 && (px as usize) < self.w && (py as usize) < self.h {
                    let k = (py as usize * self.w + px as usize) * 3;
                    self.rgb[k..k + 3].copy_from_slice(&c);
                }
            }
        }
    }
    fn line(&mut self, a: &V3, b: &V3, rad: i64, c: [u8; 3]) {
        let (pa, pb) = (self.project(a), self.project(b));
        let n = ((pb.0 - pa.0).abs().max((pb.1 - pa.1).abs()).ceil() as usize).max(1);
        for i in 0..=n {
            let t = i as f64 / n as f64;
            let p = a + (b - a) * t;
            self.dot(&p, rad, c);
        }
    }
}

fn render(sc: &Scenario) -> (usize, usize, Vec<u8>) {
    let cut = &sc.cut;
    let x = &cut.mesh.vertices;
    let crack: std::collections::BTreeSet<[usize; 3]> = cut
        .crack_faces
        .iter()
        .flatten()
        .map(|f| {
            let mut k = *f;
            k.sort_unstable();
            k
        })
        .collect();
    let outer: Vec<([V3; 3], [f64; 3])> = cut
        .mesh
        .boundary()
        .faces
        .iter()
        .filter(|f| {
            let mut k = **f;
            k.sort_unstable();
            !crack.contains(&k)
        })
        .map(|f| (f.map(|k| x[k]), [0.85, 0.82, 0.78]))
        .collect();
    let cracks: Vec<([V3; 3], [f64; 3])> = (0..2)
        .flat_map(|s| {
            cut.crack_faces[s]
                .iter()
                .map(move |f| (f.map(|k| x[k]), if s == 0 { [0.9, 0.2, 0.15] } else { [0.15, 0.3, 0.9] }))
        })
        .collect();
    let a = sc.anterior;
    let chord = {
        let l = &cut.lips[0];
        x[*l.last().unwrap_or(&l[0])] - x[l[0]]
    };
    let chord = (chord - a * a.dot(&chord)).normalize();
    let side_normal = a.cross(&chord).normalize();
    let (w, h) = (640usize, 560usize);
    let views = [(-a, chord), (-side_normal, a)];
    let mut out = vec![255u8; 2 * w * h * 3];
    let lms = cut.landmarks(50).ok();
    for (vi, (view, up)) in views.iter().enumerate() {
        let mut p = Panel::new(w, h, *view, *up, x);
        let (s, zs) = p.raster(&outer);
        let (c, _) = p.raster(&cracks);
        for k in 0..w * h {
            let px = match (s[k], c[k]) {
                (ss, Some(cc)) => {
                    let ss = ss.unwrap_or([1.0; 3]);
                    Some([0.6 * cc[0] + 0.4 * ss[0], 0.6 * cc[1] + 0.4 * ss[1], 0.6 * cc[2] + 0.4 * ss[2]])
                }
                (ss, None) => ss,
            };
            if let Some(v) = px {
                for (ch, val) in v.iter().enumerate() {
                    p.rgb[k * 3 + ch] = (val * 255.0).clamp(0.0, 255.0) as u8;
                }
            }
        }
        for &n in &sc.fixed_nodes {
            if p.visible(&x[n], &zs) {
                p.dot(&x[n], 1, [120, 60, 160]);
            }
        }
        if let Some(t) = sc.tumour {
            let m = 96;
            for i in 0..m {
                let (t0, t1) =
                    (i as f64 / m as f64 * std::f64::consts::TAU, (i + 1) as f64 / m as f64 * std::f64::consts::TAU);
                let q0 = t.centre + (p.r * t0.cos() + p.u * t0.sin()) * t.radius_mm;
                let q1 = t.centre + (p.r * t1.cos() + p.u * t1.sin()) * t.radius_mm;
                p.line(&q0, &q1, 1, [20, 150, 40]);
            }
        }
        for (s, col) in [(0usize, [150u8, 0, 0]), (1, [0, 0, 150])] {
            let l = cut.lip_positions(s, x);
            for seg in l.windows(2) {
                p.line(&seg[0], &seg[1], 1, col);
            }
        }
        if let Some(l) = &lms {
            for q in l.landmark_positions(x) {
                p.dot(&q, 2, [250, 200, 0]);
            }
        }
        for row in 0..h {
            let src = &p.rgb[row * w * 3..(row + 1) * w * 3];
            let dst = (row * 2 * w + vi * w) * 3;
            out[dst..dst + w * 3].copy_from_slice(src);
        }
    }
    (2 * w, h, out)
}
