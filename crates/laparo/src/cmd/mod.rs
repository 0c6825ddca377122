//! One file per subcommand group.
pub mod cats;
pub mod cats_stats;
pub mod cpc;
pub mod cpc_eval;
pub mod depth;
pub mod depth_tools;
pub mod features;
pub mod guide;
pub mod mpm;
pub mod register;
pub mod stereo;
pub mod stereo_match;
