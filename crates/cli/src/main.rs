//! `evigrid`: the command-line face of the evigrid libraries.
//!
//! Only wiring lives here: argument parsing, reading and writing files, progress bars and turning
//! errors into exit codes. Every computation is in a library crate.

mod commands;
mod demo_page;
mod drive_input;
mod exit;
mod figures;
mod input;
mod progress;

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
    /// Vector maps: info (extent, counts), render (contexts as PNG), crop (to a small GeoJSON).
    #[command(subcommand)]
    Map(commands::map::MapCommand),
    /// One cell, step by step: masses, betP, ζ, conflicts and decision after each observation.
    Cell(commands::cell::CellArgs),
    /// The perception pipeline over a drive: scans + poses + map → decision maps and grids.
    Run(commands::run::RunArgs),
    /// Lidar odometry: poses from the scans alone, written as TUM or KITTI odometry.
    Odometry(commands::odometry::OdometryArgs),
    /// Speed of the fusion step against the memory floor and a naive baseline (ratios).
    Bench(commands::bench::BenchArgs),
    /// Variants side by side on simulated drives over a real map, scored against the truth.
    Eval(commands::eval::EvalArgs),
    /// The main job on embedded data, no input needed: drive, perception, views, evaluation.
    Demo(commands::demo::DemoArgs),
    /// Tunes the parameters on simulated drives and checks them on held-out drives.
    Tune(commands::tune::TuneArgs),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Mass(cmd) => commands::mass::run(cmd),
        Command::Map(cmd) => commands::map::run(cmd),
        Command::Cell(args) => commands::cell::run(args),
        Command::Run(args) => commands::run::run(args),
        Command::Odometry(args) => commands::odometry::run(args),
        Command::Bench(args) => commands::bench::run(args),
        Command::Eval(args) => commands::eval::run(args),
        Command::Demo(args) => commands::demo::run(args),
        Command::Tune(args) => commands::tune::run(args),
    };
    exit::report(result)
}
