//! One module per subcommand: each has its clap arguments and a `run` returning `anyhow::Result`.

pub mod bag;
pub mod bench;
pub mod cell;
pub mod config;
pub mod demo;
pub mod eval;
pub mod map;
pub mod mass;
pub mod odometry;
pub mod run;
pub mod tune;
