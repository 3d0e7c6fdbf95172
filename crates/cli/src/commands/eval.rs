//! `evigrid eval`: variants side by side on simulated drives over a real map, scored against the
//! simulator's truth.
//!
//! ```text
//! evigrid eval --map city.osm.pbf --scenario drive.toml --out eval/ \
//!     [--variants kurdej2013,no-map,moras2011,log-odds] [--seeds 3] [--config params.toml] [--json]
//! ```
//!
//! Wiring only: reading and checking the inputs, the progress bar, writing the outputs. The work
//! is `eval::evaluate`'s, the pictures `eval::plots`'.

use std::fmt::Write as _;
use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use eval::{EvalConfig, EvalError, EvalReport, Progress, Variant, plots};
use evigrid::Params;
use output::{write_atomic, write_png};
use sim::{Scenario, SimError};

use crate::exit::BadInput;
use crate::input::{command_line, one_line, read_params, with_path};

/// Arguments of `evigrid eval`.
#[derive(Debug, Args)]
#[command(after_long_help = OUTPUTS_HELP)]
pub struct EvalArgs {
    /// Vector map: OSM PBF, OSM XML (optionally gzipped) or GeoJSON. Its local frame has its
    /// origin at the map's centre; the scenario's waypoints are in that frame.
    #[arg(long)]
    map: PathBuf,
    /// Scenario (TOML): traffic, ego route, sensor, map errors (see scenarios/README.md).
    #[arg(long)]
    scenario: PathBuf,
    /// Methods to compare, comma-separated: kurdej2013 (the paper's method, SPEC §5), no-map,
    /// evigrid (with motion evidence, docs/motion.md), moras2011, log-odds; every variant by default. `full` is the deprecated name of
    /// kurdej2013.
    #[arg(long, value_delimiter = ',')]
    variants: Option<Vec<String>>,
    /// Number of seeds: the scenario's seed, seed + 1, … (one drive each).
    #[arg(long, default_value_t = 1)]
    seeds: u64,
    /// evigrid parameters (TOML, any subset of SPEC §7's layout); defaults otherwise. The
    /// simulated scanner is planar, so the sensor's ground model is always `none`.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Output directory (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Write into an existing --out folder that is not an evigrid output folder.
    #[arg(long)]
    force: bool,
    /// Print the whole report as JSON on standard output instead of the table.
    #[arg(long)]
    json: bool,
}

const OUTPUTS_HELP: &str = "\
Outputs (in --out, each written atomically):
  metrics.json              the evaluation report: confusion matrices (cells in view, observed
                            at least once, all), scores, timings per variant
  report.md                 the report's tables (cells in view first), the parameters used
                            (TOML), the command line
  confusion-<variant>.png   row-normalised confusion matrix per variant, cells in view (rows
                            truth F I U S M, columns prediction F I U S M O ?, darker = larger
                            share of the row)
  per-class-iou.png         IoU of F, I, U, S, M in view, one bar per variant

Table: scores over the cells in view (the sensor has evidence there in this frame), truth by
the centre rule (a cell is what covers its centre, building or road user; a cell covered in part
without its centre is free, its share and M calls shown as the band), then the moving IoU and M
precision by the previous truth rule, for comparison: see docs/evaluation.md.";

/// Most seeds one evaluation runs: each is a whole simulated drive, so a thousand already takes
/// hours; more is a typo.
pub(crate) const MAX_SEEDS: u64 = 1000;

/// Runs `evigrid eval`.
pub fn run(args: EvalArgs) -> Result<()> {
    // Installed first, so that no signal finds the default action. The first signal stops the
    // evaluation between frames and the outputs of the frames run are written, marked
    // incomplete; a second ends the command at once.
    let interrupt = crate::interrupt::Interrupt::install();
    let started = Instant::now();
    // Every input is checked before any work, and nothing is written before the evaluation has
    // succeeded: a bad input leaves no output behind.
    if args.seeds == 0 {
        return Err(BadInput::new("--seeds 0: at least one seed is needed"));
    }
    if args.seeds > MAX_SEEDS {
        return Err(BadInput::new(format!(
            "--seeds {}: at most {MAX_SEEDS} drives per evaluation",
            args.seeds
        )));
    }
    let (variants, warnings) = match &args.variants {
        Some(names) => parse_variants(names)?,
        None => (Variant::ALL.to_vec(), Vec::new()),
    };
    let params = read_params(args.config.as_deref())?;
    let scenario_text = crate::input::read_text(&args.scenario)?;
    let scenario = Scenario::from_toml(&scenario_text)
        .map_err(|e| BadInput::new(one_line(&format!("{}: {e}", args.scenario.display()))))?;
    let loaded = geodata::load_map(&args.map, &geodata::LoadOptions { origin: None })
        .map_err(|e| BadInput::new(with_path(&args.map, &e.to_string())))?;
    sim::drive::check_map_span(&loaded.map)
        .map_err(|e| BadInput::new(with_path(&args.map, &e.to_string())))?;

    let inputs: Vec<&Path> = [Some(&args.map), Some(&args.scenario), args.config.as_ref()]
        .into_iter()
        .flatten()
        .map(PathBuf::as_path)
        .collect();
    let out_dir = crate::out_dir::OutDir::prepare(&args.out, &inputs, args.force, "eval")?;

    let seeds: Vec<u64> = (0..args.seeds)
        .map(|k| scenario.seed.wrapping_add(k))
        .collect();
    let config = EvalConfig {
        params,
        ..EvalConfig::default()
    };
    let frames = scenario.frame_count();
    let bar = crate::progress::bar(frames as u64 * seeds.len() as u64, "eval");
    let report = eval::evaluate_until(
        &loaded.map,
        &scenario,
        &variants,
        &seeds,
        &config,
        interrupt.flag(),
        &mut |p: Progress| {
            bar.set_position((p.seed_index * p.frames + p.frame) as u64);
        },
        &mut |_| {},
    )
    .map_err(|e| evaluation_error(e, &args))?;
    bar.finish_and_clear();
    if report.frames_run == 0 {
        // Stopped before the first frame: nothing to report (the folder's marker says so).
        return Err(anyhow::Error::new(crate::interrupt::Interrupted)
            .context("stopped before the first frame, no report written"));
    }
    // Only now that every input has proved good: a bad input gets its one line and no other.
    for warning in warnings {
        crate::errln!("{warning}");
    }

    let json = write_outputs(
        &args.out,
        &report,
        &config.params_for(&scenario),
        "evigrid eval",
        started.elapsed().as_secs_f64(),
    )?;
    out_dir.finish_or_stopped(report.complete, || {
        format!(
            "evaluation stopped after {} frames; outputs in {} (marked incomplete)",
            report.frames_run,
            args.out.display()
        )
    })?;

    if args.json {
        crate::outln!("{json}");
    } else {
        crate::out!("{}", table(&report));
        crate::outln!(
            "{} seed(s) × {} frames in {:.1} s; outputs in {}",
            report.seeds.len(),
            report.frames_per_seed,
            started.elapsed().as_secs_f64(),
            args.out.display()
        );
    }
    Ok(())
}

/// Writes `metrics.json`, `confusion-<variant>.png`, `per-class-iou.png` and `report.md` (headed
/// `title`, listing `params`: the parameters that ran, from `EvalConfig::params_for`) into `out`,
/// creating it if missing; returns the JSON written to `metrics.json`. Shared with `evigrid
/// demo`, which reports the same evaluation.
pub(crate) fn write_outputs(
    out: &Path,
    report: &EvalReport,
    params: &Params,
    title: &str,
    seconds: f64,
) -> Result<String> {
    fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let json = serde_json::to_string_pretty(report)?;
    write_atomic(&out.join("metrics.json"), |f| {
        f.write_all(json.as_bytes())?;
        f.write_all(b"\n")
    })?;
    for v in &report.variants {
        let name = format!("confusion-{}.png", v.variant.name());
        write_png(&plots::variant_heatmap(v), &out.join(name))?;
    }
    write_png(
        &plots::report_iou_chart(report),
        &out.join("per-class-iou.png"),
    )?;
    let markdown = report_markdown(report, params, title, seconds)?;
    write_atomic(&out.join("report.md"), |f| f.write_all(markdown.as_bytes()))?;
    Ok(json)
}

/// Variant names → variants, in the order given, and a warning for each deprecated name (to be
/// printed once every input has been checked); an unknown or repeated name is bad input.
fn parse_variants(names: &[String]) -> Result<(Vec<Variant>, Vec<String>)> {
    let mut variants = Vec::with_capacity(names.len());
    let mut deprecated = Vec::new();
    for name in names {
        let name = name.trim();
        let v = Variant::parse(name).map_err(|e| BadInput::new(format!("--variants: {e}")))?;
        if variants.contains(&v) {
            return Err(BadInput::new(format!(
                "--variants: {} is given twice",
                v.name()
            )));
        }
        if name != v.name() {
            deprecated.push((name, v));
        }
        variants.push(v);
    }
    if variants.is_empty() {
        return Err(BadInput::new("--variants: no variant given"));
    }
    let warnings = deprecated
        .into_iter()
        .map(|(name, v)| {
            format!(
                "warning: --variants: `{name}` is deprecated, use `{}`",
                v.name()
            )
        })
        .collect();
    Ok((variants, warnings))
}

/// Errors of the evaluation itself, blamed on the input they come from.
fn evaluation_error(error: EvalError, args: &EvalArgs) -> anyhow::Error {
    let config = args.config.as_deref().map_or_else(
        || "default parameters".to_string(),
        |p| p.display().to_string(),
    );
    match error {
        EvalError::Sim(SimError::NoRoads { .. }) => {
            BadInput::new(with_path(&args.map, &error.to_string()))
        }
        EvalError::Pipeline(_) => BadInput::new(format!("{config}: {error}")),
        EvalError::Sim(
            SimError::ScenarioToml { .. }
            | SimError::InvalidScenario { .. }
            | SimError::NoEgoRoute { .. },
        ) => BadInput::new(format!("{}: {error}", args.scenario.display())),
        other => anyhow::Error::new(other).context("evaluation failed"),
    }
}

fn fmt_score(v: Option<f64>) -> String {
    v.map_or_else(|| "-".to_string(), |x| format!("{x:.3}"))
}

/// The stdout table: one line per variant, the in-view scores by the centre rule first, then
/// the band's share and what it holds called M, then the moving IoU and M precision in view by
/// the previous truth rule (one release, so that the change can be read), then a line saying so.
pub(crate) fn table(report: &EvalReport) -> String {
    let mut s = format!(
        "{:<12} {:>7} {:>7} {:>7} {:>7} {:>7} {:>8} {:>8} | {:>6} {:>7} | {:>7} {:>7}\n",
        "variant",
        "IoU M",
        "dynamic",
        "M prec",
        "occ-st",
        "static",
        "macro-F1",
        "ms/frame",
        "band",
        "band M",
        "IoU M",
        "M prec"
    );
    for v in &report.variants {
        let now = &v.scores_visible;
        let previous = v.scores_visible_previous.as_ref();
        let band_share = (now.scored_cell_frames > 0)
            .then(|| now.band_cell_frames as f64 / now.scored_cell_frames as f64);
        let band_moving = (now.band_cell_frames > 0)
            .then(|| now.band_predicted_moving as f64 / now.band_cell_frames as f64);
        // Writing to a String cannot fail.
        let _ = writeln!(
            s,
            "{:<12} {:>7} {:>7} {:>7} {:>7} {:>7} {:>8} {:>8.2} | {:>6} {:>7} | {:>7} {:>7}",
            v.variant.name(),
            fmt_score(now.moving_iou),
            fmt_score(now.dynamic_accuracy),
            fmt_score(now.moving_precision),
            fmt_score(now.occupied_static_accuracy),
            fmt_score(now.static_accuracy),
            fmt_score(now.macro_f1),
            v.ms_per_frame,
            fmt_score(band_share),
            fmt_score(band_moving),
            fmt_score(previous.and_then(|p| p.moving_iou)),
            fmt_score(previous.and_then(|p| p.moving_precision)),
        );
    }
    s.push_str(
        "Left: cells in view, truth by the centre rule (occ-st: static accuracy over truth I, U, S). \
         band: share of the cells covered in part without their centre (truth F), band M: \
         share of those called M. Right: IoU M and M precision by the previous truth rule.\n",
    );
    s
}

/// `report.md`: the report's tables, how to read the pictures, the parameters and the command.
fn report_markdown(
    report: &EvalReport,
    params: &Params,
    title: &str,
    seconds: f64,
) -> Result<String> {
    let params_toml = params.to_toml_string()?;
    let scenario_toml = toml::to_string(&report.scenario)?;
    let mut s = format!("# {title}\n\n");
    let _ = writeln!(s, "Command (wall time {seconds:.1} s):\n");
    let _ = writeln!(s, "```sh\n{}\n```\n", command_line());
    s.push_str("## Scores\n\n");
    s.push_str(&report.to_markdown());
    s.push_str(
        "\nTruth: a cell is what covers its centre (building or road user); a cell covered in \
         part without its centre is F (the band); a road user never seen moving is S, with S \
         and U both correct. SA: share of truly static cells (F, I, U, S) not predicted \
         M; occupied-static accuracy: the same over truth I, U and S only; DA: share of truly \
         moving cells predicted M; M precision: share of the cells predicted M that are moving; \
         HA: harmonic mean of SA and DA. Two-class baselines predict O (occupied, static) \
         and never I, U or S, so their five-class scores for I, U, S are 0 by construction; \
         compare them on the coarse columns.\n",
    );
    s.push_str("\n## Pictures\n\n");
    s.push_str(
        "- `confusion-<variant>.png`: confusion matrix over the cells in view. \
         Rows: truth F, I, U, S, M (top to bottom). Columns: prediction F, I, U, S, M, O \
         (occupied, static, class not resolved), unknown (no decision), left to right. Each cell shows \
         its share of the row in per cent and is shaded from white (0 %) to dark blue (100 %); a \
         grey row has no truth cell.\n",
    );
    s.push_str(
        "- `per-class-iou.png`: IoU per class over the cells in view, groups F, I, U, S, M from \
         left to right, one bar \
         per variant in this order and colour:",
    );
    let colours = [
        "blue",
        "orange",
        "bluish green",
        "reddish purple",
        "vermillion",
        "sky blue",
        "yellow",
        "black",
    ];
    for (k, v) in report.variants.iter().enumerate() {
        let _ = write!(
            s,
            "{} {} ({})",
            if k == 0 { "" } else { "," },
            v.variant.name(),
            colours[k % colours.len()]
        );
    }
    s.push_str(
        ". Axis 0–1 with grid lines every 0.25, each bar's value above it; a grey stub under \
         the axis, marked n/a, is an undefined IoU (class absent from truth and prediction).\n",
    );
    let _ = writeln!(
        s,
        "\n## Parameters used\n\nevigrid (the front end all variants share, `kurdej2013` and `no-map`; \
         `sensor.ground_model` is the simulated scanner's, `none`, whatever the configuration \
         says):\n\n```toml\n{params_toml}```\n"
    );
    let _ = writeln!(
        s,
        "Scenario (seed replaced by each of {:?}):\n\n```toml\n{scenario_toml}```",
        report.seeds
    );
    Ok(s)
}
