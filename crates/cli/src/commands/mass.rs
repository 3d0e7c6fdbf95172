//! `evigrid mass`: the belief-function calculator (being written).

use clap::Subcommand;

/// Subcommands of `evigrid mass`.
#[derive(Debug, Subcommand)]
pub enum MassCommand {}

/// Runs one `evigrid mass` subcommand.
pub fn run(command: MassCommand) -> anyhow::Result<()> {
    match command {}
}
