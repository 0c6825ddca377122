//! One file per subcommand group.
pub mod cats;
pub mod cpc;
pub mod depth;
pub mod mpm;
pub mod stereo;
