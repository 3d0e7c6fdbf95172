//! `evigrid demo`: the main job on embedded data, with no input files.
//!
//! ```text
//! evigrid demo [--out evigrid-demo] [--frames N] [--json]
//! ```
//!
//! A simulated drive with traffic over a real map of central Helsinki that ships inside the binary
//! (`assets/helsinki-demo.geojson`, cropped from the OpenStreetMap extract with `evigrid map crop`;
//! map data © OpenStreetMap contributors, ODbL). [`VARIANTS`] are scored against the
//! simulator's truth exactly as `evigrid eval` does (cells in view first), in one pass over the
//! drive; the [`VIEWS_OF`] method's decision beside the truth is rendered after every frame of
//! that pass and encoded into an animated GIF on a second thread, and its three views of the
//! paper's Fig. 2 after the last frame. No per-frame PNG: the page shows the drive as the GIF.
//!
//! Wiring only: the drive is `sim::Drive`'s, the perception evigrid's (`FrontEnd` and
//! `Fusion`), the scoring `eval::evaluate_observed`'s.

use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::mpsc;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use eval::{EvalConfig, FusionFrame, Progress, Variant};
use evigrid::Label;
use evigrid::Params;
use output::mcap::{EVERY_GRID_ZSTD_LEVEL, McapFrame, McapRecorder};
use output::raster::{GifAnimation, Rgb, RgbImage};
use output::{
    GridExports, Legend, Overlay, class_name, decision_image, figure, pignistic_image,
    readable_scale, trace_image, write_atomic, write_grid_exports, write_png,
};
use rayon::prelude::*;
use sim::Scenario;

use crate::exit::BadInput;
use output::run_figures::{COLOURS, DECISION_NOTE, OSM_ATTRIBUTION, PIGNISTIC_NOTE, TRACE_NOTE};

/// The embedded map: buildings, roads and car parks around the demo route, GeoJSON.
const MAP_GEOJSON: &[u8] = include_bytes!("../../assets/helsinki-demo.geojson");
/// The embedded drive: ego route, traffic, scanner, map errors.
const SCENARIO_TOML: &str = include_str!("../../assets/demo-scenario.toml");
/// Origin (lat, lon) of the full Helsinki extract's local frame, in which the scenario's
/// waypoints are given; the crop is loaded with it so that both share one frame.
const FULL_MAP_ORIGIN: (f64, f64) = (60.171_634_0, 24.944_295_4);
/// When the simulated drive starts on the recording's timeline, seconds since the Unix epoch
/// (2025-06-02 09:00:00 UTC, a Monday morning in Helsinki): the simulator counts from 0, and a
/// recording that starts in 1970 reads as a broken clock in Foxglove.
const DEMO_START_UNIX_S: f64 = 1_748_854_800.0;
/// The variants scored, in table order: the default method, the paper's, and no map.
const VARIANTS: [Variant; 3] = [Variant::Evigrid, Variant::Kurdej2013, Variant::NoMap];
/// The variant whose views are rendered: the default method of `evigrid run`.
const VIEWS_OF: Variant = Variant::Evigrid;

/// Arguments of `evigrid demo`.
#[derive(Debug, Args)]
#[command(after_long_help = OUTPUTS_HELP)]
pub struct DemoArgs {
    /// Output directory (created if missing).
    #[arg(long, default_value = "evigrid-demo")]
    out: PathBuf,
    /// Write into an existing --out folder that is not an evigrid output folder.
    #[arg(long)]
    force: bool,
    /// Run only the first N frames of the drive (at 10 Hz); the whole drive by default.
    #[arg(long)]
    frames: Option<usize>,
    /// Print the evaluation report as JSON on standard output instead of the table.
    #[arg(long)]
    json: bool,
    /// Do not write the Foxglove recording `run.mcap` (written by default).
    #[arg(long)]
    no_mcap: bool,
}

const OUTPUTS_HELP: &str = "\
Outputs (in --out):
  index.html                   open this: the animation, legend, final views, tables and plots
                               (self-contained, relative links only)
  decision.gif                 the simulator's truth beside `evigrid`'s decision over the whole
                               drive, 1 px per 0.5 m cell, 10 frames per second, Okabe-Ito
                               colours (F bluish green, I blue, U sky blue, S yellow,
                               M vermillion, black = unknown; the page's legend names them)
  decision.png, pignistic.png, trace.png
                               after the last frame: truth beside the decision, the betP colour
                               mix (with a key to the mixtures) and the trace of moving objects,
                               enlarged to >= 800 px a panel, map outlines in white, the ego's
                               path, legend, scale bar, north arrow
  metrics.json                 evaluation of evigrid, kurdej2013 and no-map against the truth
  report.md                    its tables (cells in view first), parameters and the command line
  confusion-<variant>.png      row-normalised confusion matrix per variant, cells in view
  per-class-iou.png            IoU of F, I, U, S, M per variant, cells in view
  run.mcap                     Foxglove recording of `evigrid`: per frame the decision grid, the
                               pose, the scan; the map's outlines (not with --no-mcap)
  occupancy.json, classes.json, masses.json/.bin, map.pgm/.yaml, decision-map.png/.pgw/.prj
                               the final grid of `evigrid`, as `evigrid run` writes them
Map data © OpenStreetMap contributors, ODbL.";

/// Runs `evigrid demo`.
pub fn run(args: DemoArgs) -> Result<()> {
    // Installed first, so that no signal finds the default action. The first signal stops the
    // drive between frames and the outputs of the frames run are finished (the GIF, the
    // recording, the report), marked incomplete; a second ends the command at once.
    let interrupt = crate::interrupt::Interrupt::install();
    let started = Instant::now();
    if args.frames == Some(0) {
        return Err(BadInput::new("--frames 0: at least one frame is needed"));
    }
    let loaded = geodata::load_map_from_bytes(
        MAP_GEOJSON,
        &geodata::LoadOptions {
            origin: Some(FULL_MAP_ORIGIN),
        },
    )
    .context("embedded demo map")?;
    let scenario = demo_scenario(args.frames)?;
    let frames = scenario.frame_count();
    let config = EvalConfig {
        params: Params::default(),
        ..EvalConfig::default()
    };
    // Every input is built in: no file to protect.
    let out_dir = crate::out_dir::OutDir::prepare(&args.out, &[], args.force, "demo")?;
    let bar = crate::progress::bar(frames as u64, "demo");
    let mut recorder = demo_recorder(&args, &loaded.map)?;
    let pass = DemoPass {
        out: &args.out,
        loaded: &loaded,
        scenario: &scenario,
        config: &config,
    };
    let PassResults {
        report,
        rendered,
        recorded,
        encoded,
    } = pass.run(interrupt.flag(), &bar, recorder.as_mut());
    let report = report.context("evaluating the demo drive")?;
    if report.frames_run == 0 {
        // Stopped before the first frame: nothing to show (the folder's marker says so).
        return Err(anyhow::Error::new(crate::interrupt::Interrupted)
            .context("stopped before the first frame, no output written"));
    }
    rendered?;
    recorded?;
    if let Some(recorder) = recorder {
        recorder.finish(None)?;
    }
    let gif_bytes = encoded?;
    bar.finish_and_clear();
    write_atomic(&args.out.join("decision.gif"), |f| f.write_all(&gif_bytes))?;

    let seconds = started.elapsed().as_secs_f64();
    let params = config.params_for(&scenario);
    let json = super::eval::write_outputs(&args.out, &report, &params, "evigrid demo", seconds)?;
    append_attribution(&args.out.join("report.md"))?;
    crate::demo_page::write_index(&args.out, &report, &COLOURS)?;
    out_dir.finish_or_stopped(report.complete, || {
        format!(
            "demo stopped after {} of {frames} frames; outputs in {} (marked incomplete)",
            report.frames_run,
            args.out.display()
        )
    })?;

    if args.json {
        crate::outln!("{json}");
    } else {
        print_table(&report, frames, seconds, &args.out);
    }
    Ok(())
}

/// The recording `run.mcap` with every frame's grid, unless `--no-mcap`.
fn demo_recorder(args: &DemoArgs, map: &geodata::LocalMap) -> Result<Option<McapRecorder>> {
    if args.no_mcap {
        return Ok(None);
    }
    // Every frame's grid: the demo's frames are what it shows; zstd at the level that keeps
    // them small.
    Ok(Some(
        McapRecorder::create_with_zstd_level(
            &args.out.join("run.mcap"),
            Some(map),
            EVERY_GRID_ZSTD_LEVEL,
        )?
        .with_grid_interval(0.0),
    ))
}

/// Prints the evaluation's table, what ran (`frames` in `seconds`) and the map's attribution.
fn print_table(report: &eval::EvalReport, frames: usize, seconds: f64, out: &Path) {
    crate::out!("{}", super::eval::table(report));
    crate::outln!(
        "{frames} frames ({:.1} s of driving) in {seconds:.1} s; outputs in {}",
        frames as f64 * report.frame_period_s,
        out.display()
    );
    crate::outln!("{OSM_ATTRIBUTION}");
}

/// The embedded drive, cut to its first `frames` frames when that is fewer.
fn demo_scenario(frames: Option<usize>) -> Result<Scenario> {
    let mut scenario = Scenario::from_toml(SCENARIO_TOML).context("embedded demo scenario")?;
    if let Some(frames) = frames
        && frames < scenario.frame_count()
    {
        // frame_count() rounds duration × rate, so this gives exactly `frames` frames.
        scenario.duration_s = frames as f64 / scenario.sensor.rate_hz;
    }
    Ok(scenario)
}

/// The demo's one pass over its drive, and where its outputs go.
struct DemoPass<'a> {
    out: &'a Path,
    loaded: &'a geodata::LoadedMap,
    scenario: &'a Scenario,
    config: &'a EvalConfig,
}

impl DemoPass<'_> {
    /// Evaluates the variants frame by frame until the drive ends or `stop` is raised,
    /// rendering the views of the [`VIEWS_OF`] method after every frame and recording it into
    /// `recorder`.
    ///
    /// One pass over the drive: the evaluation runs the variants frame by frame, and the
    /// views are rendered from its `VIEWS_OF` method, not from a second run of it. Encoding the
    /// GIF is the other half of the work; it runs on its own thread, fed through a
    /// short queue (memory stays bounded), while the pipelines go on with the next frames.
    fn run(
        &self,
        stop: &AtomicBool,
        bar: &indicatif::ProgressBar,
        mut recorder: Option<&mut McapRecorder>,
    ) -> PassResults {
        let (scenario, frames) = (self.scenario, self.scenario.frame_count());
        let delay_ms = (1000.0 / scenario.sensor.rate_hz).round() as u32;
        let (views_tx, views_rx) = mpsc::sync_channel::<FrameViews>(QUEUED_FRAMES);
        // The MCAP frames and the final exports, written from the observer.
        let mut recorded: Result<()> = Ok(());
        let (report, rendered, encoded) = std::thread::scope(|scope| {
            let out = self.out;
            let encoder = scope.spawn(move || encode_views(views_rx, out, delay_ms));
            let mut rendered: Result<()> = Ok(());
            // The ego's positions so far, for the path drawn over the views.
            let mut path: Vec<[f64; 2]> = Vec::with_capacity(frames);
            let period_s = 1.0 / scenario.sensor.rate_hz;
            let report = eval::evaluate_until(
                &self.loaded.map,
                scenario,
                &VARIANTS,
                &[scenario.seed],
                self.config,
                stop,
                &mut |p: Progress| bar.set_position(p.frame as u64),
                &mut |f: FusionFrame<'_>| {
                    if f.variant != VIEWS_OF || rendered.is_err() {
                        return;
                    }
                    path.push(f.ego_position);
                    let last = f.frame + 1 == frames;
                    rendered = render_views(&f, f.frame, &path, period_s, last).map(|views| {
                        // A closed queue means the encoder failed; its error is reported below.
                        let _ = views_tx.send(views);
                    });
                    if recorded.is_ok() {
                        recorded =
                            record_frame(&f, recorder.as_deref_mut(), frames, out, self.loaded);
                    }
                },
            );
            // Closing the queue ends the encoder.
            drop(views_tx);
            let encoded = encoder
                .join()
                .unwrap_or_else(|_| Err(anyhow::anyhow!("the frame encoder panicked")));
            (report, rendered, encoded)
        });
        PassResults {
            report,
            rendered,
            recorded,
            encoded,
        }
    }
}

/// What [`DemoPass::run`] gives: each part's outcome, reported by the caller in this order.
struct PassResults {
    /// The evaluation's report.
    report: Result<eval::EvalReport, eval::EvalError>,
    /// Whether every frame's views were rendered.
    rendered: Result<()>,
    /// Whether every frame was recorded and the final exports written.
    recorded: Result<()>,
    /// The GIF's bytes.
    encoded: Result<Vec<u8>>,
}

/// Adds the frame to the recording and, after the last frame, writes the final grid's exports.
fn record_frame(
    f: &FusionFrame<'_>,
    recorder: Option<&mut McapRecorder>,
    frames: usize,
    out: &Path,
    loaded: &geodata::LoadedMap,
) -> Result<()> {
    let (window, fusion) = (f.front_end.window(), f.fusion);
    if let Some(recorder) = recorder {
        recorder.write_frame(&McapFrame {
            time_s: DEMO_START_UNIX_S + f.time_s,
            window,
            decisions: fusion.decisions(),
            perception: fusion.perception(),
            world_from_sensor: f.world_from_sensor,
            points_in_sensor: f.points_in_sensor,
            // The simulated scanner gives no intensity.
            intensity: &[],
            // A planar scanner: its returns lie in its own plane, where the grid is drawn.
            sensor_height_m: 0.0,
            fix: None,
        })?;
    }
    if f.frame + 1 == frames {
        write_grid_exports(
            out,
            &GridExports {
                window,
                decisions: fusion.decisions(),
                perception: fusion.perception(),
                time_s: DEMO_START_UNIX_S + f.time_s,
                projection: Some(&loaded.projection),
            },
        )?;
    }
    Ok(())
}

/// Frames rendered ahead of the encoder at most (a GIF frame each, some 250 kB; the last frame
/// also its three final figures).
const QUEUED_FRAMES: usize = 8;

/// The views of one frame, composed and waiting to be encoded.
struct FrameViews {
    /// File name and figure: after the last frame, the final figures (no per-frame PNG: the
    /// page shows the drive as the GIF).
    figures: Vec<(String, RgbImage)>,
    /// The GIF frame: truth beside decision, one pixel per cell.
    gif: RgbImage,
}

/// The legend of the demo's figures: `legend` (the decided classes, or the pignistic view's
/// with its key to the mixtures), and the truth's edge band.
fn demo_legend(mut legend: Legend) -> Legend {
    legend
        .entries
        .push((COLOURS.of(Label::Edge), class_name(Label::Edge).to_owned()));
    legend
}

/// Renders the [`VIEWS_OF`] method's decision beside the simulator's truth after frame `index`
/// (the GIF's frame), and after the last frame (`last`) its three views of the paper's Fig. 2
/// beside the truth at [`readable_scale`], with the map's outlines and `path` (the ego so far).
/// Frames are `period_s` apart.
fn render_views(
    frame: &FusionFrame<'_>,
    index: usize,
    path: &[[f64; 2]],
    period_s: f64,
    last: bool,
) -> Result<FrameViews> {
    let (window, fusion) = (frame.front_end.window(), frame.fusion);
    let truth = decision_image(window, frame.truth, &COLOURS)?;
    let decision = decision_image(window, fusion.decisions(), &COLOURS)?;
    let mut figures = Vec::with_capacity(3);
    if last {
        let pignistic = pignistic_image(window, fusion.perception(), &COLOURS)?;
        let trace = trace_image(window, fusion.decisions(), fusion.trace(), &COLOURS)?;
        let arrows = output::run_figures::velocity_arrows(window, fusion.motion());
        let overlay = Overlay {
            gis: Some(frame.front_end.gis()),
            path,
            velocities: &arrows,
        };
        let name = VIEWS_OF.name();
        let time = format!("{:.1} s", index as f64 * period_s);
        let views = [
            (
                "decision",
                &decision,
                Legend::classes(&COLOURS, false, DECISION_NOTE),
            ),
            (
                "pignistic",
                &pignistic,
                Legend::pignistic(&COLOURS, PIGNISTIC_NOTE),
            ),
            (
                "trace",
                &trace,
                Legend::classes(&COLOURS, false, TRACE_NOTE),
            ),
        ];
        for (view, cells, legend) in views {
            let composed = figure(
                window,
                &[
                    (&format!("truth, {time}"), &truth),
                    (&format!("{name}: {view}"), cells),
                ],
                &overlay,
                &demo_legend(legend),
                readable_scale(window),
            )?;
            figures.push((format!("{view}.png"), composed));
        }
    }
    // The GIF: both panels at one pixel a cell with a strip between them, no text (the page
    // shows the legend beside it).
    let (w, h) = truth.dimensions();
    let mut gif = RgbImage::from_pixel(2 * w + GIF_GAP, h, Rgb([255, 255, 255]));
    gif.replace(&truth, 0, 0);
    gif.replace(&decision, i64::from(w + GIF_GAP), 0);
    Ok(FrameViews { figures, gif })
}

/// White columns between truth and decision in the GIF.
const GIF_GAP: u32 = 8;

/// Writes every frame's figures as PNG under `out` and returns the GIF of truth beside
/// decision (built in memory, a few hundred kB: few colours, long runs; written atomically by
/// the caller so that a write error is reported rather than lost in a drop).
fn encode_views(views: mpsc::Receiver<FrameViews>, out: &Path, delay_ms: u32) -> Result<Vec<u8>> {
    // Speed 30: the decision view has a handful of colours, so the quantiser has nothing to
    // gain from its slow modes.
    let mut gif = GifAnimation::new(30);
    let gif_path = || out.join("decision.gif").display().to_string();
    for v in views {
        // The figures are independent: encode them side by side.
        v.figures
            .par_iter()
            .try_for_each(|(name, image)| write_png(image, &out.join(name)))?;
        gif.push(&v.gif, delay_ms).with_context(gif_path)?;
    }
    gif.finish().with_context(gif_path)
}

/// Adds the map's attribution at the end of `report.md`.
fn append_attribution(path: &Path) -> Result<()> {
    let mut text =
        fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    text.push_str(&format!(
        "\nThe map is embedded in the binary (crates/cli/assets/helsinki-demo.geojson). \
         {OSM_ATTRIBUTION}.\n"
    ));
    write_atomic(path, |f| f.write_all(text.as_bytes()))?;
    Ok(())
}
