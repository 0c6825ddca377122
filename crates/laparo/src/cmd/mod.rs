//! One file per subcommand group.
pub mod cats;
pub mod cats_stats;
pub mod check;
pub mod cpc;
pub mod cpc_eval;
pub mod depth;
pub mod depth_tools;
pub mod features;
pub mod fem;
pub mod guide;
pub mod mesh;
pub mod mpm;
pub mod register;
pub mod register_benchmark;
pub mod register_convergence;
pub mod stereo;
pub mod stereo_match;
