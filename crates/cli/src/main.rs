//! `evigrid`: the command-line face of the evigrid libraries.
//!
//! Only wiring lives here: argument parsing, reading and writing files, progress bars and turning
//! errors into exit codes. Every computation is in a library crate.

mod commands;
mod demo_page;
mod exit;
mod input;
mod interrupt;
mod out_dir;
mod progress;
mod stdout;

use clap::{Parser, Subcommand};

/// Evidential occupancy grids fused with geo-referenced maps.
#[derive(Debug, Parser)]
#[command(name = "evigrid", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// More diagnostics on standard error: -v what is read and decided, -vv per frame, -vvv
    /// everything. `RUST_LOG` (e.g. `RUST_LOG=evigrid=debug`) overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Errors only: no warnings, no progress bars.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
}

/// Sends `tracing` events to standard error at the level `-v`/`-q` chose, or as `RUST_LOG` says
/// (`level` or `target=level`, comma-separated: `tracing_subscriber`'s `Targets`, which needs no
/// regular-expression engine in the build, unlike its `EnvFilter`; a value that does not parse
/// is ignored).
fn init_logging(verbose: u8, quiet: bool) {
    use tracing_subscriber::filter::{LevelFilter, Targets};
    use tracing_subscriber::layer::SubscriberExt;
    use tracing_subscriber::util::SubscriberInitExt;
    let level = match (quiet, verbose) {
        (true, _) => LevelFilter::ERROR,
        (false, 0) => LevelFilter::WARN,
        (false, 1) => LevelFilter::INFO,
        (false, 2) => LevelFilter::DEBUG,
        (false, _) => LevelFilter::TRACE,
    };
    let filter = std::env::var("RUST_LOG")
        .ok()
        .and_then(|value| value.parse::<Targets>().ok())
        .unwrap_or_else(|| Targets::new().with_default(level));
    // `try_init`: a second initialisation (tests) is not an error worth failing for.
    let _ = tracing_subscriber::fmt()
        .with_max_level(LevelFilter::TRACE)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_target(false)
        .without_time()
        .finish()
        .with(filter)
        .try_init();
    progress::set_quiet(quiet);
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
    /// ROS 2 recordings (MCAP): info (topics, types, counts, time span, what a run would read).
    #[command(subcommand)]
    Bag(commands::bag::BagCommand),
    /// Speed of the fusion step against the memory floor and a naive baseline (ratios).
    Bench(commands::bench::BenchArgs),
    /// Variants side by side on simulated drives over a real map, scored against the truth.
    Eval(commands::eval::EvalArgs),
    /// The main job on embedded data, no input needed: drive, perception, views, evaluation.
    Demo(commands::demo::DemoArgs),
    /// Tunes the parameters on simulated drives and checks them on held-out drives.
    Tune(commands::tune::TuneArgs),
    /// The parameters as TOML: print the defaults, or check a file.
    Config(commands::config::ConfigArgs),
}

fn main() -> std::process::ExitCode {
    // Not `Cli::parse()`: it exits without a word when `--help` cannot be written (`>/dev/full`).
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(error) => {
            let printed = error.print();
            return match printed {
                Err(e) if !error.use_stderr() && e.kind() != std::io::ErrorKind::BrokenPipe => {
                    errln!("evigrid: standard output: {e}");
                    std::process::ExitCode::from(1)
                }
                _ => std::process::ExitCode::from(u8::try_from(error.exit_code()).unwrap_or(2)),
            };
        }
    };
    init_logging(cli.verbose, cli.quiet);
    let result = match cli.command {
        Command::Mass(cmd) => commands::mass::run(cmd),
        Command::Map(cmd) => commands::map::run(cmd),
        Command::Cell(args) => commands::cell::run(args),
        Command::Run(args) => commands::run::run(args),
        Command::Odometry(args) => commands::odometry::run(args),
        Command::Bag(cmd) => commands::bag::run(cmd),
        Command::Bench(args) => commands::bench::run(args),
        Command::Eval(args) => commands::eval::run(args),
        Command::Demo(args) => commands::demo::run(args),
        Command::Tune(args) => commands::tune::run(args),
        Command::Config(args) => commands::config::run(args),
    };
    exit::report(result)
}
