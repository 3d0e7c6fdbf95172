//! `evigrid-fuzz`: long fuzzing runs of evigrid's parsers, findings written to a directory.
//!
//! ```text
//! evigrid-fuzz [--target NAME]... [--seconds 60] [--executions N] [--seed 1] [--findings DIR]
//! ```
//!
//! Exits 1 if any target panicked or was slow, after writing each finding as
//! `DIR/<target>-<n>.bin` with its message in `DIR/<target>-<n>.txt`.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::Parser;
use fuzz::{Budget, Scratch, TARGETS, run, target, targets};

/// Mutation fuzzing of evigrid's parsers.
#[derive(Debug, Parser)]
#[command(name = "evigrid-fuzz", version, about)]
struct Args {
    /// Targets to run (default: all). One of: pcd, kitti-bin, map, poses, kitti-raw-text,
    /// odometry, bag, params, scenario.
    #[arg(long = "target")]
    targets: Vec<String>,
    /// Wall-time budget per target, seconds.
    #[arg(long, default_value_t = 60.0)]
    seconds: f64,
    /// Execution budget per target.
    #[arg(long, default_value_t = u64::MAX)]
    executions: u64,
    /// Seed of the mutation stream; the same seed replays the same inputs.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Where findings are written.
    #[arg(long, default_value = "fuzz-findings")]
    findings: PathBuf,
    /// Shared data folder for extra seeds (default: `$EVIGRID_SHARED`, else none).
    #[arg(long)]
    shared: Option<PathBuf>,
}

fn main() -> Result<()> {
    let args = Args::parse();
    if !(args.seconds.is_finite() && args.seconds > 0.0 && args.seconds <= 7.0 * 86_400.0) {
        bail!(
            "--seconds {}: expected a duration in (0, 604800]",
            args.seconds
        );
    }
    let chosen: Vec<_> = if args.targets.is_empty() {
        TARGETS.iter().collect()
    } else {
        args.targets
            .iter()
            .map(|name| target(name).with_context(|| format!("--target {name}: no such target")))
            .collect::<Result<_>>()?
    };
    let shared = args
        .shared
        .clone()
        .or_else(|| std::env::var_os("EVIGRID_SHARED").map(PathBuf::from));
    let budget = Budget {
        executions: args.executions,
        duration: Duration::from_secs_f64(args.seconds),
    };
    let scratch = Scratch::new().context("creating the scratch directory")?;
    let (mut total, mut total_findings) = (0u64, 0usize);
    println!(
        "{:<16} {:>12} {:>10} {:>9} {:>10} {:>8}",
        "target", "executions", "accepted", "exec/s", "slowest", "findings"
    );
    for t in chosen {
        let seeds = targets::seeds(t, shared.as_deref());
        let report = run(t, &seeds, &scratch, budget, args.seed);
        let rate = report.executions as f64 / report.elapsed.as_secs_f64().max(1e-9);
        println!(
            "{:<16} {:>12} {:>10} {:>9.0} {:>8.1}ms {:>8}",
            t.name,
            report.executions,
            report.accepted,
            rate,
            report.slowest.as_secs_f64() * 1e3,
            report.findings.len()
        );
        if !report.findings.is_empty() {
            std::fs::create_dir_all(&args.findings)
                .with_context(|| format!("{}: cannot create", args.findings.display()))?;
            for (k, finding) in report.findings.iter().enumerate() {
                let stem = args.findings.join(format!("{}-{k}", t.name));
                std::fs::write(stem.with_extension("bin"), &finding.input)?;
                std::fs::write(stem.with_extension("txt"), &finding.problem)?;
                eprintln!("{}: {}", t.name, finding.problem.replace('\n', " "));
            }
        }
        total += report.executions;
        total_findings += report.findings.len();
    }
    println!("total executions: {total}, findings: {total_findings}");
    if total_findings > 0 {
        bail!(
            "{total_findings} findings written to {}",
            args.findings.display()
        );
    }
    Ok(())
}
