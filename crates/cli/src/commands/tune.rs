//! `evigrid tune`: tunes the default parameters on simulated drives, and checks the result on
//! held-out drives.
//!
//! ```text
//! evigrid tune --map city.osm.pbf --scenario a.toml [--map town.osm.pbf --scenario b.toml …] \
//!     [--holdout-map other.osm.pbf --holdout-scenario c.toml …] [--seeds 2] [--holdout-seeds 2] \
//!     [--rounds 2] [--variant kurdej2013] [--config start.toml] --out tune/ [--json]
//! ```
//!
//! Wiring only: reading and checking the inputs, the progress bar, writing the outputs. The search
//! and the objective are `eval::tune`'s (see its docs and docs/tuning.md).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use eval::tune::{DriveSet, TuneOptions, TuneProgress, TuneReport, VariantScore};
use eval::{EvalError, Variant};
use geodata::LocalMap;
use output::write_atomic;
use serde::Serialize;
use sim::{Scenario, SimError};

use crate::exit::BadInput;
use crate::input::{command_line, one_line, read_params, with_path};

/// Arguments of `evigrid tune`.
#[derive(Debug, Args)]
#[command(after_long_help = OUTPUTS_HELP)]
pub struct TuneArgs {
    /// Map of the tuning drives (OSM PBF, OSM XML, GeoJSON). Give one for all `--scenario`s, or
    /// one per `--scenario`, in the same order.
    #[arg(long, required = true)]
    map: Vec<PathBuf>,
    /// Scenario (TOML) of the tuning drives; repeat for several.
    #[arg(long, required = true)]
    scenario: Vec<PathBuf>,
    /// Map of the held-out drives: one for all `--holdout-scenario`s, or one per scenario.
    #[arg(long)]
    holdout_map: Vec<PathBuf>,
    /// Scenario (TOML) of drives never used for tuning, on which the starting and the tuned
    /// parameters are compared; repeat for several.
    #[arg(long)]
    holdout_scenario: Vec<PathBuf>,
    /// Tuning seeds per scenario: the scenario's seed, seed + 1, … (one drive each).
    #[arg(long, default_value_t = 2)]
    seeds: u64,
    /// Held-out seeds per held-out scenario, taken after the tuning seeds (seed + --seeds, …), so
    /// that a scenario used for tuning gives other drives when held out.
    #[arg(long, default_value_t = 2)]
    holdout_seeds: u64,
    /// Rounds of the coordinate search; the step halves every round.
    #[arg(long, default_value_t = 2)]
    rounds: usize,
    /// The variant whose objective is maximised (the comparison shows every variant).
    #[arg(long, default_value = "kurdej2013")]
    variant: String,
    /// Starting parameters (TOML, any subset of SPEC §7's layout); the defaults otherwise.
    /// Parameters outside the search space (window, cell size, modes) keep these values.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Write into an existing --out folder that is not an evigrid output folder.
    #[arg(long)]
    force: bool,
    /// Print the whole result as JSON on standard output instead of the tables.
    #[arg(long)]
    json: bool,
}

const OUTPUTS_HELP: &str = "\
Objective: mean over tuning drives of macro-F1 + 0.25 × moving IoU of --variant (`kurdej2013` by
default), on the cells in view (see docs/tuning.md).

Outputs (in --out, each written atomically):
  tuned.toml    the best parameters, every key (load with --config)
  tune.json     the search: space, every candidate and its scores, start and best parameters,
                and the comparison of start and best on the tuning and held-out drives
  report.md     the same as tables, with the command line";

/// The tuning run and its check, as written to `tune.json`.
#[derive(Debug, Serialize)]
struct TuneOutput {
    /// Tuning drives: scenario name and seeds.
    tuning_drives: Vec<(String, Vec<u64>)>,
    /// Held-out drives.
    holdout_drives: Vec<(String, Vec<u64>)>,
    /// The search.
    search: TuneReport,
    /// Every variant with the starting and the best parameters, on both sets.
    comparison: Vec<ComparisonRow>,
}

/// One line of the comparison: a set of drives, a variant, starting against tuned parameters.
#[derive(Debug, Serialize)]
struct ComparisonRow {
    set: &'static str,
    variant: Variant,
    start: VariantScore,
    tuned: VariantScore,
}

/// Scenarios paired with their maps, as read.
struct Drives {
    maps: BTreeMap<PathBuf, LocalMap>,
    /// (name, map path, scenario)
    scenarios: Vec<(String, PathBuf, Scenario)>,
}

/// Runs `evigrid tune`.
pub fn run(args: TuneArgs) -> Result<()> {
    // Installed first, so that no signal finds the default action. The first signal stops the
    // search between candidates and the best so far is written, marked incomplete; a second
    // ends the command at once.
    let interrupt = crate::interrupt::Interrupt::install();
    let started = Instant::now();
    // Every input is checked before any work; nothing is written before the search succeeds.
    let variant = check_counts(&args)?;
    check_pairs(&args.map, &args.scenario, "--map", "--scenario")?;
    check_pairs(
        &args.holdout_map,
        &args.holdout_scenario,
        "--holdout-map",
        "--holdout-scenario",
    )?;
    let start = read_params(args.config.as_deref())?;
    let tuning = read_drives(&args.map, &args.scenario, "--map", "--scenario")?;
    let holdout = read_drives(
        &args.holdout_map,
        &args.holdout_scenario,
        "--holdout-map",
        "--holdout-scenario",
    )?;
    let inputs: Vec<&Path> = (args.map.iter())
        .chain(&args.scenario)
        .chain(&args.holdout_map)
        .chain(&args.holdout_scenario)
        .chain(&args.config)
        .map(PathBuf::as_path)
        .collect();
    let out_dir = crate::out_dir::OutDir::prepare(&args.out, &inputs, args.force, "tune")?;
    let tuning_seeds: Vec<Vec<u64>> = seeds_of(&tuning, 0, args.seeds);
    let holdout_seeds: Vec<Vec<u64>> = seeds_of(&holdout, args.seeds, args.holdout_seeds);
    let tuning_sets = sets(&tuning, &tuning_seeds);
    let holdout_sets = sets(&holdout, &holdout_seeds);

    let options = TuneOptions {
        rounds: args.rounds,
        variant,
        ..TuneOptions::default()
    };
    let report = search(&start, &tuning_sets, &options, interrupt.flag(), &args)?;
    let mut stopped = !report.complete;
    let comparison = compare(
        &report,
        [("tuning", &tuning_sets), ("held-out", &holdout_sets)],
        options.moving_iou_weight,
        (interrupt.flag(), &mut stopped),
        &args,
    )?;

    let output = TuneOutput {
        tuning_drives: names_and_seeds(&tuning, &tuning_seeds),
        holdout_drives: names_and_seeds(&holdout, &holdout_seeds),
        search: report,
        comparison,
    };
    let seconds = started.elapsed().as_secs_f64();
    let json = write_outputs(&args.out, &output, seconds)?;
    out_dir.finish_or_stopped(!stopped, || {
        format!(
            "search stopped after {} candidates, the best so far in {} (marked incomplete)",
            output.search.candidates.len(),
            args.out.join("tuned.toml").display()
        )
    })?;
    print_result(&args, &output, &json, seconds)
}

/// Checks the counts of `args` (seeds, held-out seeds, rounds) and reads `--variant`.
fn check_counts(args: &TuneArgs) -> Result<Variant> {
    if args.seeds == 0 {
        return Err(BadInput::new("--seeds 0: at least one seed is needed"));
    }
    let max_seeds = crate::commands::eval::MAX_SEEDS;
    for (flag, seeds) in [
        ("--seeds", args.seeds),
        ("--holdout-seeds", args.holdout_seeds),
    ] {
        if seeds > max_seeds {
            return Err(BadInput::new(format!(
                "{flag} {seeds}: at most {max_seeds} drives per scenario"
            )));
        }
    }
    if args.rounds == 0 || args.rounds > 100 {
        return Err(BadInput::new(format!(
            "--rounds {}: expected 1 to 100 rounds",
            args.rounds
        )));
    }
    if !args.holdout_scenario.is_empty() && args.holdout_seeds == 0 {
        return Err(BadInput::new(
            "--holdout-seeds 0: at least one seed is needed for the held-out scenarios",
        ));
    }
    Variant::parse(args.variant.trim()).map_err(|e| BadInput::new(format!("--variant: {e}")))
}

/// The search from `start` on the tuning drives, with a progress bar, until it ends or `stop`
/// is raised.
fn search(
    start: &evigrid::Params,
    tuning_sets: &[DriveSet<'_>],
    options: &TuneOptions,
    stop: &AtomicBool,
    args: &TuneArgs,
) -> Result<TuneReport> {
    // About two candidates per dimension per round; the bar grows if the search needs more.
    let estimate = 1 + 2 * options.space.len() * options.rounds;
    let bar = crate::progress::bar(estimate as u64, "tune");
    let report =
        eval::tune::tune_until(start, tuning_sets, options, stop, &mut |p: TuneProgress| {
            if p.candidates as u64 > bar.length().unwrap_or(0) {
                bar.set_length(p.candidates as u64);
            }
            bar.set_position(p.candidates as u64);
        })
        .map_err(|e| search_error(e, args))?;
    bar.finish_and_clear();
    Ok(report)
}

/// Starting against tuned parameters, every variant, on each named set of drives (skipped
/// when empty), the objective weighing moving IoU by `moving_iou_weight`. A stopped search
/// is not compared: that would be the long work the signal declined; `stopped` notes a
/// signal raised on `stop` meanwhile.
fn compare(
    report: &TuneReport,
    named_sets: [(&'static str, &Vec<DriveSet<'_>>); 2],
    moving_iou_weight: f64,
    (stop, stopped): (&AtomicBool, &mut bool),
    args: &TuneArgs,
) -> Result<Vec<ComparisonRow>> {
    let mut comparison = Vec::new();
    for (set_name, drive_sets) in named_sets {
        *stopped |= stop.load(std::sync::atomic::Ordering::Relaxed);
        if drive_sets.is_empty() || *stopped {
            continue;
        }
        let w = moving_iou_weight;
        let before = eval::tune::score_drives(&report.start, drive_sets, &Variant::ALL, w)
            .map_err(|e| search_error(e, args))?;
        let after = eval::tune::score_drives(&report.best, drive_sets, &Variant::ALL, w)
            .map_err(|e| search_error(e, args))?;
        for (start, tuned) in before.into_iter().zip(after) {
            comparison.push(ComparisonRow {
                set: set_name,
                variant: start.variant,
                start,
                tuned,
            });
        }
    }
    Ok(comparison)
}

/// Prints the result: its JSON with `--json`, else the best parameters and the tables.
fn print_result(args: &TuneArgs, output: &TuneOutput, json: &str, seconds: f64) -> Result<()> {
    if args.json {
        crate::outln!("{json}");
    } else {
        crate::outln!(
            "# Best parameters (also in {})",
            args.out.join("tuned.toml").display()
        );
        crate::out!("{}", output.search.best.to_toml_string()?);
        crate::outln!();
        crate::out!("{}", candidates_table(&output.search));
        crate::outln!();
        crate::out!("{}", comparison_table(&output.comparison));
        crate::outln!(
            "{} candidates in {seconds:.1} s; outputs in {}",
            output.search.candidates.len(),
            args.out.display()
        );
    }
    Ok(())
}

/// Checks that maps and scenarios pair up: one map for all scenarios, or one per scenario.
fn check_pairs(
    maps: &[PathBuf],
    scenarios: &[PathBuf],
    map_flag: &str,
    scenario_flag: &str,
) -> Result<()> {
    if scenarios.is_empty() && !maps.is_empty() {
        return Err(BadInput::new(format!(
            "{map_flag} given without {scenario_flag}: a map needs a scenario to drive on it"
        )));
    }
    if maps.len() != 1 && maps.len() != scenarios.len() {
        return Err(BadInput::new(format!(
            "{map_flag} given {} times for {} {scenario_flag}: give one map for all scenarios or one per scenario",
            maps.len(),
            scenarios.len()
        )));
    }
    Ok(())
}

/// Pairs maps with scenarios (one map for all, or one each) and reads them, each map once.
fn read_drives(
    maps: &[PathBuf],
    scenarios: &[PathBuf],
    map_flag: &str,
    scenario_flag: &str,
) -> Result<Drives> {
    check_pairs(maps, scenarios, map_flag, scenario_flag)?;
    let mut drives = Drives {
        maps: BTreeMap::new(),
        scenarios: Vec::new(),
    };
    for (k, scenario_path) in scenarios.iter().enumerate() {
        // check_pairs: one map for all, or one per scenario.
        let Some(map_path) = maps.get(if maps.len() == 1 { 0 } else { k }) else {
            return Err(BadInput::new(format!(
                "{map_flag}: no map for {scenario_flag} {k}"
            )));
        };
        if !drives.maps.contains_key(map_path) {
            let loaded = geodata::load_map(map_path, &geodata::LoadOptions { origin: None })
                .map_err(|e| BadInput::new(with_path(map_path, &e.to_string())))?;
            sim::drive::check_map_span(&loaded.map)
                .map_err(|e| BadInput::new(with_path(map_path, &e.to_string())))?;
            drives.maps.insert(map_path.clone(), loaded.map);
        }
        let text = crate::input::read_text(scenario_path)?;
        let scenario = Scenario::from_toml(&text)
            .map_err(|e| BadInput::new(one_line(&format!("{}: {e}", scenario_path.display()))))?;
        let name = scenario_path.file_stem().map_or_else(
            || scenario_path.display().to_string(),
            |s| s.to_string_lossy().into_owned(),
        );
        drives.scenarios.push((name, map_path.clone(), scenario));
    }
    Ok(drives)
}

/// Seeds `seed + skip .. seed + skip + count` of every scenario.
fn seeds_of(drives: &Drives, skip: u64, count: u64) -> Vec<Vec<u64>> {
    drives
        .scenarios
        .iter()
        .map(|(_, _, s)| {
            (0..count)
                .map(|k| s.seed.wrapping_add(skip).wrapping_add(k))
                .collect()
        })
        .collect()
}

fn sets<'a>(drives: &'a Drives, seeds: &'a [Vec<u64>]) -> Vec<DriveSet<'a>> {
    drives
        .scenarios
        .iter()
        .zip(seeds)
        .filter_map(|((name, map_path, scenario), seeds)| {
            Some(DriveSet {
                name,
                map: drives.maps.get(map_path)?,
                scenario,
                seeds,
            })
        })
        .collect()
}

fn names_and_seeds(drives: &Drives, seeds: &[Vec<u64>]) -> Vec<(String, Vec<u64>)> {
    drives
        .scenarios
        .iter()
        .zip(seeds)
        .map(|((name, _, _), s)| (name.clone(), s.clone()))
        .collect()
}

/// Errors of the search, blamed on the input they come from where one is to blame.
fn search_error(error: EvalError, args: &TuneArgs) -> anyhow::Error {
    let config = args.config.as_deref().map_or_else(
        || "default parameters".to_string(),
        |p| p.display().to_string(),
    );
    match error {
        EvalError::Sim(SimError::NoRoads { .. }) => {
            BadInput::new(format!("a --map has no drivable road: {error}"))
        }
        EvalError::Pipeline(_) => BadInput::new(format!("{config}: {error}")),
        EvalError::Sim(
            SimError::ScenarioToml { .. }
            | SimError::InvalidScenario { .. }
            | SimError::NoEgoRoute { .. },
        ) => BadInput::new(format!("a --scenario: {error}")),
        other => anyhow::Error::new(other).context("tuning failed"),
    }
}

/// Writes `tuned.toml`, `tune.json` and `report.md`; returns the JSON.
fn write_outputs(out: &Path, output: &TuneOutput, seconds: f64) -> Result<String> {
    fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let toml = output.search.best.to_toml_string()?;
    write_atomic(&out.join("tuned.toml"), |f| f.write_all(toml.as_bytes()))?;
    let json = serde_json::to_string_pretty(output)?;
    write_atomic(&out.join("tune.json"), |f| {
        f.write_all(json.as_bytes())?;
        f.write_all(b"\n")
    })?;
    let mut md = String::from("# evigrid tune\n\n");
    if !output.search.complete {
        let _ = writeln!(
            md,
            "**Incomplete**: the search was stopped after {} candidates; the parameters are the \
             best of those, not compared on the drives.\n",
            output.search.candidates.len()
        );
    }
    let _ = writeln!(
        md,
        "Command (wall time {seconds:.1} s):\n\n```sh\n{}\n```\n",
        command_line()
    );
    let _ = writeln!(
        md,
        "Tuning drives: {}.\n",
        drives_text(&output.tuning_drives)
    );
    if !output.holdout_drives.is_empty() {
        let _ = writeln!(
            md,
            "Held-out drives: {}.\n",
            drives_text(&output.holdout_drives)
        );
    }
    md.push_str("## Starting against tuned parameters\n\n");
    md.push_str(&comparison_markdown(&output.comparison));
    md.push_str("\n## Candidates\n\n");
    md.push_str(&candidates_markdown(&output.search));
    let _ = writeln!(md, "\n## Tuned parameters\n\n```toml\n{toml}```");
    write_atomic(&out.join("report.md"), |f| f.write_all(md.as_bytes()))?;
    Ok(json)
}

fn drives_text(drives: &[(String, Vec<u64>)]) -> String {
    drives
        .iter()
        .map(|(n, s)| format!("`{n}` seeds {s:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The candidates as an aligned table: index, round, parameter moved and its new value, scores.
fn candidates_table(report: &TuneReport) -> String {
    let mut s = format!(
        "{:>4} {:>5} {:<30} {:>7} {:>9} {:>8} {:>9}  \n",
        "#", "round", "moved", "to", "macro-F1", "IoU M", "objective"
    );
    for c in &report.candidates {
        let (moved, to) = moved_and_value(report, c.moved.as_deref(), &c.values);
        let _ = writeln!(
            s,
            "{:>4} {:>5} {:<30} {:>7} {:>9.4} {:>8.4} {:>9.4} {}",
            c.index,
            c.round,
            moved,
            to,
            c.macro_f1,
            c.moving_iou,
            c.objective,
            if c.accepted { "*" } else { "" }
        );
    }
    s.push_str("* = accepted (the search moved there)\n");
    s
}

fn candidates_markdown(report: &TuneReport) -> String {
    let mut s = String::from(
        "`*` marks the candidates the search moved to.\n\n| # | round | moved | to | macro-F1 | IoU M | objective | |\n|---|---|---|---|---|---|---|---|\n",
    );
    for c in &report.candidates {
        let (moved, to) = moved_and_value(report, c.moved.as_deref(), &c.values);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.4} | {:.4} | {:.4} | {} |",
            c.index,
            c.round,
            moved,
            to,
            c.macro_f1,
            c.moving_iou,
            c.objective,
            if c.accepted { "*" } else { "" }
        );
    }
    s
}

fn moved_and_value(report: &TuneReport, moved: Option<&str>, values: &[f64]) -> (String, String) {
    match moved {
        None => ("(start)".to_string(), String::new()),
        Some(name) => {
            let value = report
                .parameters
                .iter()
                .position(|p| p == name)
                .and_then(|k| values.get(k))
                .map_or_else(String::new, |v| format!("{v}"));
            (name.to_string(), value)
        }
    }
}

fn comparison_table(rows: &[ComparisonRow]) -> String {
    let mut s = format!(
        "{:<9} {:<10} {:>15} {:>15} {:>15}\n",
        "drives", "variant", "macro-F1", "IoU M", "objective"
    );
    for r in rows {
        let _ = writeln!(
            s,
            "{:<9} {:<10} {:>6.3} → {:>6.3} {:>6.3} → {:>6.3} {:>6.3} → {:>6.3}",
            r.set,
            r.variant.name(),
            r.start.macro_f1,
            r.tuned.macro_f1,
            r.start.moving_iou,
            r.tuned.moving_iou,
            r.start.objective,
            r.tuned.objective
        );
    }
    s.push_str("(starting → tuned parameters; mean over drives)\n");
    s
}

fn comparison_markdown(rows: &[ComparisonRow]) -> String {
    let mut s = String::from(
        "Mean over drives, starting → tuned parameters.\n\n| drives | variant | macro-F1 | IoU M | objective |\n|---|---|---|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} → {:.3} | {:.3} → {:.3} | {:.3} → {:.3} |",
            r.set,
            r.variant.name(),
            r.start.macro_f1,
            r.tuned.macro_f1,
            r.start.moving_iou,
            r.tuned.moving_iou,
            r.start.objective,
            r.tuned.objective
        );
    }
    s
}
