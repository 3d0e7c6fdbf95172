//! `evigrid`: the command-line face of the evigrid libraries.
//!
//! Only wiring lives here: argument parsing, reading and writing files, progress bars and turning
//! errors into exit codes. Every computation is in a library crate.

mod commands;
mod exit;

use clap::{Parser, Subcommand};

/// Evidential occupancy grids fused with geo-referenced maps.
#[derive(Debug, Parser)]
#[command(name = "evigrid", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Belief-function calculator: combine, discount, transform mass functions given as JSON.
    #[command(subcommand)]
    Mass(commands::mass::MassCommand),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Mass(cmd) => commands::mass::run(cmd),
    };
    exit::report(result)
}
