//! `evigrid bench`: the fusion step against the memory floor and the naive baseline.

use crate::exit::BadInput;
use crate::progress;
use anyhow::Context;
use clap::Args;
use evigrid_bench::{BenchOptions, BenchReport, real::RealInputs};
use std::path::PathBuf;

/// Arguments of `evigrid bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Window sizes in cells per side, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "200,1000")]
    sizes: Vec<usize>,
    /// Timed rounds after one warm-up round; every ratio is a median of per-round ratios.
    #[arg(long, default_value_t = 7)]
    rounds: usize,
    /// Rounds that include the naive step (about a hundred times slower than the kernel).
    #[arg(long, default_value_t = 3)]
    naive_rounds: usize,
    /// Lidar scan for the `sensor` and `frame` cases (PCD or KITTI .bin). By default the first
    /// scan of `$EVIGRID_SHARED/data/lidar/kitti-city-22`.
    #[arg(long)]
    scan: Option<PathBuf>,
    /// Map for the `prior` and `frame` cases. By default
    /// `$EVIGRID_SHARED/data/osm/helsinki-centre.osm.pbf`.
    #[arg(long)]
    map: Option<PathBuf>,
    /// Folder of consecutive scans of one drive (0.1 s apart) for the `odometry` case; its first
    /// 20 are registered in turn. By default the shared KITTI raw drive 0013
    /// (`$EVIGRID_SHARED/data/lidar/kitti-raw-0013/…/velodyne_points/data`), the case skipped
    /// when it is absent.
    #[arg(long)]
    odometry_scans: Option<PathBuf>,
    /// KITTI raw drive for the `drive` case, which then runs after the window cases: the whole
    /// default run of `evigrid run --drive` with every default output, into a temporary
    /// folder, its CPU time (user + sys) against the drive's duration.
    #[arg(long)]
    drive: Option<PathBuf>,
    /// Run the `drive` case alone (no window cases), on `--drive` or by default the shared
    /// KITTI raw drive 0013 (`$EVIGRID_SHARED/data/lidar/kitti-raw-0013/2011_09_26`; skipped
    /// with a note when absent). The goal is stated for one core: `taskset -c 0`.
    #[arg(long)]
    drive_only: bool,
    /// Skip the real-data cases (`sensor`, `prior`, `frame`, `ground`, `odometry`; no
    /// `drive`).
    #[arg(long)]
    synthetic_only: bool,
    /// Cell size of the real-data cases, metres.
    #[arg(long, default_value_t = 0.2)]
    cell_size: f64,
    /// Print the report as JSON on standard output.
    #[arg(long)]
    json: bool,
}

/// Scans the `odometry` case registers in turn before starting again.
const ODOMETRY_SCANS: usize = 20;

/// Runs `evigrid bench`.
pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    // Installed first, so that no signal finds the default action. The first signal stops the
    // bench between rounds and the rounds measured are reported (`complete: false`); a second
    // ends it at once.
    let interrupt = crate::interrupt::Interrupt::install();
    check_args(&args)?;
    if args.drive_only {
        let drive = drive_case(args.drive.as_deref())?;
        match (args.json, drive) {
            (true, drive) => crate::outln!(
                "{}",
                serde_json::to_string_pretty(&serde_json::json!({ "drive": drive }))
                    .context("serialising the report")?
            ),
            (false, Some(drive)) => crate::out!("{}", drive_table(&drive)),
            (false, None) => {}
        }
        return Ok(());
    }
    let real = if args.synthetic_only {
        None
    } else {
        Some(real_inputs(&args)?)
    };
    let options = BenchOptions {
        sizes: args.sizes,
        rounds: args.rounds,
        naive_rounds: args.naive_rounds.min(args.rounds),
        real,
        cell_size_m: args.cell_size,
    };
    let total = options.sizes.len() as u64 * (options.rounds as u64 + 1);
    let bar = progress::bar(total, "bench");
    let report = evigrid_bench::run_until(&options, interrupt.flag(), |round| {
        bar.set_message(round.to_string());
        bar.inc(1);
    });
    bar.finish_and_clear();
    let report = report.map_err(|e| match e {
        evigrid_bench::BenchError::Real(real) => BadInput::new(real.to_string()),
        other => anyhow::Error::new(other),
    })?;
    // The drive case after the windows only when asked for (`--drive`): a whole drive's run.
    let drive = match args.drive.as_deref() {
        Some(dir) if report.complete => drive_case(Some(dir))?,
        _ => None,
    };
    print_report(args.json, &report, drive.as_ref())?;
    if !report.complete {
        return Err(
            anyhow::Error::new(crate::interrupt::Interrupted).context(format!(
                "bench stopped; {} window(s) measured, the report above is incomplete",
                report.windows.len()
            )),
        );
    }
    Ok(())
}

/// Checks the flags that need no file: sizes, rounds, cell size, the cases asked for, and that
/// `--drive` is a folder.
fn check_args(args: &BenchArgs) -> anyhow::Result<()> {
    if args.sizes.is_empty() || args.sizes.contains(&0) {
        return Err(BadInput::new(
            "--sizes: every size must be a positive number of cells",
        ));
    }
    for &size in &args.sizes {
        evigrid::check_window_size(size, size)
            .map_err(|e| BadInput::new(format!("--sizes {size}: {e}")))?;
    }
    if args.rounds == 0 || args.rounds > 10_000 {
        return Err(BadInput::new(format!(
            "--rounds {}: expected 1 to 10000",
            args.rounds
        )));
    }
    if !(args.cell_size.is_finite() && args.cell_size > 0.0) {
        return Err(BadInput::new(format!(
            "--cell-size {}: must be a positive number of metres",
            args.cell_size
        )));
    }
    if args.synthetic_only && (args.drive_only || args.drive.is_some()) {
        return Err(BadInput::new(
            "--synthetic-only with --drive or --drive-only: the drive case is a real-data case",
        ));
    }
    if let Some(dir) = args.drive.as_deref().filter(|dir| !dir.is_dir()) {
        return Err(BadInput::new(format!(
            "--drive {}: not a folder",
            dir.display()
        )));
    }
    Ok(())
}

/// The real-data cases' inputs: `--scan`, `--map` and `--odometry-scans`, or the shared data's
/// (the odometry case without scans when the shared drive is absent).
fn real_inputs(args: &BenchArgs) -> anyhow::Result<RealInputs> {
    let shared =
        PathBuf::from(std::env::var("EVIGRID_SHARED").unwrap_or_else(|_| "../shared".into()));
    let scan = args
        .scan
        .clone()
        .unwrap_or_else(|| shared.join("data/lidar/kitti-city-22/0000000000.pcd"));
    let map = args
        .map
        .clone()
        .unwrap_or_else(|| shared.join("data/osm/helsinki-centre.osm.pbf"));
    for (what, path) in [("scan", &scan), ("map", &map)] {
        if !path.is_file() {
            return Err(BadInput::new(format!(
                "{}: {what} file not found (give --{what}, set EVIGRID_SHARED, or use --synthetic-only)",
                path.display()
            )));
        }
    }
    let default_odometry = shared.join(
        "data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync/velodyne_points/data",
    );
    let odometry_scans = match &args.odometry_scans {
        Some(dir) => drive::list_scans(dir).map_err(|e| BadInput::new(e.to_string()))?,
        None if default_odometry.is_dir() => {
            drive::list_scans(&default_odometry).map_err(|e| BadInput::new(e.to_string()))?
        }
        None => Vec::new(),
    };
    if args.odometry_scans.is_some() && odometry_scans.len() < 2 {
        return Err(BadInput::new(
            "--odometry-scans: the odometry case needs at least two scans",
        ));
    }
    Ok(RealInputs {
        scan,
        map,
        odometry_scans: odometry_scans.into_iter().take(ODOMETRY_SCANS).collect(),
    })
}

/// Prints the report, with the drive case's when it ran: as JSON (`json`) or as tables.
fn print_report(
    json: bool,
    report: &BenchReport,
    drive: Option<&evigrid_bench::drive_run::DriveRunReport>,
) -> anyhow::Result<()> {
    if json {
        let mut value = serde_json::to_value(report).context("serialising the report")?;
        if let (Some(object), Some(drive)) = (value.as_object_mut(), drive) {
            object.insert(
                "drive".into(),
                serde_json::to_value(drive).context("serialising the drive report")?,
            );
        }
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&value).context("serialising the report")?
        );
    } else {
        crate::out!("{}", table(report));
        if let Some(drive) = drive {
            crate::out!("{}", drive_table(drive));
        }
    }
    Ok(())
}

/// The report as aligned text tables, one per window size.
fn table(report: &BenchReport) -> String {
    let mut out = String::new();
    for w in &report.windows {
        out += &format!(
            "window {0}×{0} ({1} cells), {2} threads; state {3:.1} B/cell; copying it all moves \
             {4:.1} MB, the step moved {5:.1} MB\n",
            w.size,
            w.cells,
            w.threads,
            w.state_bytes_per_cell,
            w.bytes_moved_per_step as f64 / 1e6,
            w.bytes_step_moved as f64 / 1e6
        );
        out += &format!(
            "  step inputs: {} ({:.0}% of cells observed)\n",
            w.step_inputs,
            100.0 * w.observed_fraction
        );
        out += &format!("  {:<16} {:>12} {:>16}\n", "case", "ms/frame", "cells/s");
        for t in &w.timings {
            out += &format!(
                "  {:<16} {:>12.3} {:>16.3e}\n",
                t.case, t.median_ms, t.cells_per_second
            );
        }
        out += &format!("  {:<24} {:>8}  {:<8}\n", "ratio", "value", "target");
        for (name, value) in &w.ratios {
            let target = match evigrid_bench::target_of(name) {
                Some(t) if t.is_met(*value) => format!("{t:<8} met"),
                Some(t) => format!("{t:<8} not met"),
                None => String::new(),
            };
            out += &format!("  {name:<24} {value:>8.3}  {target}\n");
        }
        if let Some(odometry) = w.timing("odometry@1") {
            out += &format!(
                "  odometry: {:.1} ms per scan on one core (target ≤ 50 ms: {})\n",
                odometry.median_ms,
                if odometry.median_ms <= 50.0 {
                    "met"
                } else {
                    "not met"
                }
            );
        }
        if let (Some(allowed), Some(reached)) =
            (w.ratio("step@1/ideal@N"), w.ratio("ideal@N/step@N"))
        {
            out += &format!(
                "  all threads: when every core stepped its own grid, together they did \
                 {allowed:.2}× the work of one thread alone (step@1/ideal@N); the step on all \
                 threads reached {reached:.2} of that\n"
            );
        }
        out += "\n";
    }
    out += &format!(
        "naive vs library, largest difference on random cells: {:.2e}\n",
        report.naive_max_difference
    );
    out
}

/// The `drive` case ([`evigrid_bench::drive_run`]) on `drive` (by default the shared KITTI raw
/// drive 0013; `None`, with a note, when that is absent).
fn drive_case(
    drive: Option<&std::path::Path>,
) -> anyhow::Result<Option<evigrid_bench::drive_run::DriveRunReport>> {
    let default_drive =
        PathBuf::from(std::env::var("EVIGRID_SHARED").unwrap_or_else(|_| "../shared".into()))
            .join("data/lidar/kitti-raw-0013/2011_09_26");
    let dir = match drive {
        Some(dir) => dir.to_path_buf(),
        None if default_drive.is_dir() => default_drive,
        None => {
            crate::errln!(
                "evigrid bench: drive case skipped: {} not found (give --drive or set \
                 EVIGRID_SHARED)",
                default_drive.display()
            );
            return Ok(None);
        }
    };
    let out = tempfile::tempdir().context("creating a temporary folder for the drive case")?;
    let report = evigrid_bench::drive_run::run_drive(&dir, out.path())
        .map_err(|e| BadInput::new(format!("--drive {}: {e}", dir.display())))?;
    Ok(Some(report))
}

/// The `drive` case's report as text: the ratio with its target, then the stages' shares.
fn drive_table(report: &evigrid_bench::drive_run::DriveRunReport) -> String {
    let target = evigrid_bench::drive_run::TARGET_DRIVE_PER_CPU;
    let mut text = format!(
        "drive {} ({} frames, {:.3} s of drive), every default output on: {:.2} CPU-s \
         (user + sys), {:.2} s wall\n",
        report.drive, report.frames, report.drive_s, report.cpu_s, report.wall_s
    );
    text += &format!(
        "  {:<24} {:>8.3}  ≥ {target:<6} {}   ({:.3} CPU-s per second of drive)\n",
        "drive_s/cpu_s",
        report.drive_per_cpu,
        if report.drive_per_cpu >= target {
            "met"
        } else {
            "not met"
        },
        1.0 / report.drive_per_cpu
    );
    text += "  share of the wall time:";
    for stage in &report.stages {
        text += &format!(" {} {:.1} %,", stage.stage, 100.0 * stage.share);
    }
    text.pop();
    text += "\n";
    text
}
