//! One module per subcommand: each has its clap arguments and a `run` returning `anyhow::Result`.

pub mod mass;
