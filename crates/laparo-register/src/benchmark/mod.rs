//! The in-silico incision benchmark protocol (thesis §5.4.2, Table 5.1, Figs. 5.7–5.8): target registration
//! error at mesh nodes, error against the distance to the nearest incision landmark, the Table 5.1 columns
//! (landmark counts, landmark noise), the [`Method`] interface, RODS-MPM on a cut mesh, a resumable store
//! of per-run results and the pictures.
//!
//! The ground truth (a cut tetrahedral mesh deformed by a quasi-static FEM) comes from `laparo-fem`, never
//! from `laparo-mpm`; this module only scores positions against it.
pub mod build;
pub mod case;
pub mod convergence;
pub mod figures;
pub mod methods;
pub mod points;
pub mod protocol;
pub mod rods;
pub mod store;
pub mod table;
pub mod tre;
pub mod tuning;

pub use case::{
    column_landmarks, config_hash, run_protocol, score, BenchmarkCase, LandmarkSet, MaterialPoint, Method,
    MethodOutput, RunEvent,
};
pub use points::{EvalPoints, PointKind};
pub use protocol::{noisy_targets, table51_columns, Column};
pub use rods::{OracleMode, RodsMethod, RodsOracle, Rung, TwoField, RODS_MPM_NAME};
pub use store::{ResultStore, RunKey, RunResult};
pub use table::{aggregate, table_csv, table_json, table_markdown, Cell};
pub use tre::{
    binned, distance_to_nearest, node_errors, BinStats, PointScores, Stats, DISTANCE_BIN_EDGES_MM, FAR_FIELD_MM,
};
