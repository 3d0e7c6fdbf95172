//! `evigrid config`: the parameters as TOML, to start a configuration from or to check one.
//!
//! ```text
//! evigrid config --print                 the defaults, every key in SPEC §7's layout
//! evigrid config --check my.toml [--json] the file's parameters after validation (exit 2 if bad)
//! ```

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use evigrid::Params;

use crate::input::read_params;

/// Arguments of `evigrid config`.
#[derive(Debug, Args)]
#[command(group = clap::ArgGroup::new("what").required(true))]
pub struct ConfigArgs {
    /// Print the default parameters as TOML (every key; a file may set any subset).
    #[arg(long, group = "what")]
    print: bool,
    /// Read and validate a parameter file, then print the parameters it gives (defaults filled
    /// in).
    #[arg(long, value_name = "FILE", group = "what")]
    check: Option<PathBuf>,
    /// Print the parameters as JSON instead of TOML.
    #[arg(long)]
    json: bool,
}

/// Runs `evigrid config`.
pub fn run(args: ConfigArgs) -> Result<()> {
    let params = match &args.check {
        Some(path) => read_params(Some(path))?,
        None => Params::default(),
    };
    let text = if args.json {
        serde_json::to_string_pretty(&params)? + "\n"
    } else {
        params.to_toml_string()?
    };
    crate::out!("{text}");
    Ok(())
}
