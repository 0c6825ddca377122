//! Resumable results: one JSON file per (scenario, method, column, seed), written atomically, so an
//! interrupted benchmark resumes where it stopped and a finished run is never recomputed.
use super::protocol::Column;
use super::tre::{BinStats, Stats};
use crate::error::{RegisterError, Result};
use laparo_core::atomic::write_atomic;
use std::path::{Path, PathBuf};

/// What identifies one run.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunKey {
    /// Scenario (`non-anatomical`, `anatomical`).
    pub scenario: String,
    /// Method (`ARAP`, `DRBC`, `Francois`, `LDDMM`, `RODS-MPM`).
    pub method: String,
    /// Table 5.1 column.
    pub column: Column,
    /// Noise seed.
    pub seed: u64,
}

impl RunKey {
    /// File name stem: `lm50_sigma5_seed3`.
    pub fn stem(&self) -> String {
        format!("{}_seed{}", self.column.key(), self.seed)
    }
}

/// The scored result of one run.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunResult {
    /// The run.
    pub key: RunKey,
    /// TRE over every volume node (mm).
    pub tre_volume: Stats,
    /// TRE over the surface nodes (mm).
    pub tre_surface: Stats,
    /// TRE by distance to the nearest source landmark (Fig. 5.8).
    pub bins: Vec<BinStats>,
    /// Largest ground-truth node displacement (mm), to read TRE relative to it.
    pub max_gt_displacement_mm: f64,
    /// Mean landmark distance after registration (eq. 5.10, mm).
    pub landmark_distance_mm: f64,
    /// Wall time of the registration (s).
    pub seconds: f64,
    /// Non-fatal findings of the method (horizon, convergence).
    pub notes: Vec<String>,
    /// What the run was made from: a stored run is resumed only for the same case and method settings.
    #[serde(default)]
    pub provenance: Provenance,
    /// FNV-1a hash (hex) of the method's settings ([`config_hash`](super::case::config_hash)): any changed
    /// hyperparameter changes it (empty in files written before it was recorded).
    #[serde(default)]
    pub config_hash: String,
    /// Scores at the common evaluation points (v2 protocol; None for a case scored at its nodes only).
    #[serde(default)]
    pub points: Option<super::tre::PointScores>,
    /// The floor row that bounds this method's representation (None for a floor itself and for "none").
    #[serde(default)]
    pub floor: Option<String>,
    /// Energy audit of a simulating method (RODS-MPM: KE(0), KE(T), elastic at T, dissipated); None for the
    /// mesh methods, which do not simulate a trajectory.
    #[serde(default)]
    pub energy: Option<crate::optimize::EnergyAudit>,
}

/// The inputs of a run beyond its [`RunKey`]: the case (mesh, ground truth, lips, fixed region; see
/// [`BenchmarkCase::fingerprint`](super::case::BenchmarkCase::fingerprint)) and the method's settings
/// ([`Method::settings`](super::case::Method::settings)). Files written before it existed carry empty strings
/// and are not resumed.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Provenance {
    /// Fingerprint of the case (hex).
    pub case: String,
    /// The method's settings, as it describes them.
    pub settings: String,
}

/// A folder of [`RunResult`] files: `<root>/<scenario>/<method>/<column>_seed<k>.json`.
pub struct ResultStore {
    root: PathBuf,
}

impl ResultStore {
    /// A store under `root` (created on the first save).
    pub fn new(root: impl Into<PathBuf>) -> Self {
        ResultStore { root: root.into() }
    }

    /// The file of `key`.
    pub fn path(&self, key: &RunKey) -> PathBuf {
        self.root.join(sanitize(&key.scenario)).join(sanitize(&key.method)).join(format!("{}.json", key.stem()))
    }

    /// The stored result of `key`, if a complete one exists (a file that does not parse, belongs to another
    /// key, or was made from another case or other method settings than `provenance`, is an error naming it
    /// and what differs: delete it, or write to another folder, to recompute).
    pub fn load(&self, key: &RunKey, provenance: &Provenance) -> Result<Option<RunResult>> {
        let p = self.path(key);
        if !p.exists() {
            return Ok(None);
        }
        let text =
            std::fs::read_to_string(&p).map_err(|e| RegisterError::bad(p.display().to_string(), e.to_string()))?;
        let r: RunResult = serde_json::from_str(&text).map_err(|e| {
            RegisterError::bad(p.display().to_string(), format!("unreadable result ({e}); delete it to recompute"))
        })?;
        if &r.key != key {
            return Err(RegisterError::bad(p.display().to_string(), "holds the result of another run"));
        }
        if r.provenance.case != provenance.case {
            return Err(RegisterError::bad(
                p.display().to_string(),
                format!(
                    "was made on another case (mesh, ground truth or landmarks: fingerprint {:?}, now {:?}); delete it or write to another folder to recompute",
                    r.provenance.case, provenance.case
                ),
            ));
        }
        if r.provenance.settings != provenance.settings {
            return Err(RegisterError::bad(
                p.display().to_string(),
                format!(
                    "was made with other settings of {} ({:?}, now {:?}); delete it or write to another folder to recompute",
                    key.method, r.provenance.settings, provenance.settings
                ),
            ));
        }
        Ok(Some(r))
    }

    /// Save `r` atomically (temporary file, then rename).
    pub fn save(&self, r: &RunResult) -> Result<PathBuf> {
        let p = self.path(&r.key);
        create_parent(&p)?;
        let text = serde_json::to_string_pretty(r).map_err(|e| RegisterError::bad("result", e.to_string()))?;
        write_atomic(&p, text.as_bytes())?;
        Ok(p)
    }

    /// Whether any result of `scenario` is stored (a ground truth must not change under stored runs).
    pub fn holds_runs(&self, scenario: &str) -> bool {
        let mut files = Vec::new();
        collect_json(&self.root.join(sanitize(scenario)), &mut files);
        !files.is_empty()
    }

    /// Every stored result under the root, sorted by path (deterministic).
    pub fn all(&self) -> Result<Vec<RunResult>> {
        let mut files = Vec::new();
        collect_json(&self.root, &mut files);
        files.sort();
        let mut out = Vec::new();
        for p in files {
            let text =
                std::fs::read_to_string(&p).map_err(|e| RegisterError::bad(p.display().to_string(), e.to_string()))?;
            out.push(
                serde_json::from_str(&text).map_err(|e| RegisterError::bad(p.display().to_string(), e.to_string()))?,
            );
        }
        Ok(out)
    }
}

fn sanitize(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.' { c } else { '_' }).collect()
}

fn create_parent(p: &Path) -> Result<()> {
    if let Some(d) = p.parent() {
        std::fs::create_dir_all(d)
            .map_err(|e| RegisterError::bad(d.display().to_string(), format!("cannot create: {e}")))?;
    }
    Ok(())
}

fn collect_json(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else { return };
    for e in rd.flatten() {
        let p = e.path();
        if p.is_dir() {
            collect_json(&p, out);
        } else if p.extension().is_some_and(|x| x == "json")
            && !p.file_name().and_then(|n| n.to_str()).is_some_and(laparo_core::atomic::is_temp_name)
        {
            out.push(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result(method: &str, sigma: f64, seed: u64, mean: f64) -> RunResult {
        RunResult {
            key: RunKey {
                scenario: "non-anatomical".into(),
                method: method.into(),
                column: Column { landmarks: 50, noise_sigma_mm: sigma },
                seed,
            },
            tre_volume: Stats { n: 3, mean, ..Default::default() },
            tre_surface: Stats::default(),
            bins: vec![],
            max_gt_displacement_mm: 12.0,
            landmark_distance_mm: 0.5,
            seconds: 1.0,
            notes: vec![],
            provenance: Provenance { case: "c1".into(), settings: format!("{method} defaults") },
            config_hash: String::new(),
            points: None,
            floor: None,
            energy: None,
        }
    }

    #[test]
    fn round_trip_resume_and_listing() {
        let dir = tempfile::tempdir().unwrap();
        let s = ResultStore::new(dir.path());
        let r = result("RODS-MPM", 5.0, 2, 1.5);
        assert!(s.load(&r.key, &r.provenance).unwrap().is_none());
        let p = s.save(&r).unwrap();
        assert!(p.ends_with("non-anatomical/RODS-MPM/lm50_sigma5_seed2.json"), "{}", p.display());
        assert_eq!(s.load(&r.key, &r.provenance).unwrap(), Some(r.clone()));
        s.save(&result("ARAP", 0.0, 0, 2.0)).unwrap();
        let all = s.all().unwrap();
        assert_eq!(all.len(), 2);
        assert_eq!(all[0].key.method, "ARAP");
    }

    #[test]
    fn a_corrupt_or_foreign_file_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let s = ResultStore::new(dir.path());
        let r = result("DRBC", 0.0, 0, 1.0);
        let p = s.save(&r).unwrap();
        std::fs::write(&p, "{").unwrap();
        let e = s.load(&r.key, &r.provenance).unwrap_err().to_string();
        assert!(e.contains("lm50_seed0.json") && e.contains("delete"), "{e}");
        let mut other = result("DRBC", 0.0, 0, 1.0);
        other.key.scenario = "anatomical".into();
        std::fs::write(&p, serde_json::to_string(&other).unwrap()).unwrap();
        assert!(s.load(&r.key, &r.provenance).unwrap_err().to_string().contains("another run"));
    }

    #[test]
    fn a_run_of_another_case_or_other_settings_is_not_resumed() {
        let dir = tempfile::tempdir().unwrap();
        let s = ResultStore::new(dir.path());
        let r = result("RODS-MPM", 0.0, 0, 1.0);
        s.save(&r).unwrap();
        let other_case = Provenance { case: "c2".into(), ..r.provenance.clone() };
        let e = s.load(&r.key, &other_case).unwrap_err().to_string();
        assert!(e.contains("another case") && e.contains("\"c1\"") && e.contains("\"c2\""), "{e}");
        let other_settings = Provenance { settings: "RODS-MPM ν 0.3".into(), ..r.provenance.clone() };
        let e = s.load(&r.key, &other_settings).unwrap_err().to_string();
        assert!(e.contains("other settings of RODS-MPM") && e.contains("lm50_seed0.json"), "{e}");
        // a file written before provenance existed (no such field) is not resumed either
        let mut v = serde_json::to_value(&r).unwrap();
        v.as_object_mut().unwrap().remove("provenance");
        std::fs::write(s.path(&r.key), v.to_string()).unwrap();
        assert!(s.load(&r.key, &r.provenance).is_err());
    }
}
