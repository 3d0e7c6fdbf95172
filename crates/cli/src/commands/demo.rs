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
//! drive; the [`VIEWS_OF`] method's views of the paper's Fig. 2 are rendered after every frame of that pass and encoded
//! (PNG per frame, animated GIF) on a second thread, so the minute-long drive stays well under a
//! minute of wall time.
//!
//! Wiring only: the drive is `sim::Drive`'s, the perception evigrid's (`FrontEnd` and
//! `Fusion`), the scoring `eval::evaluate_observed`'s.

use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use eval::{EvalConfig, FusionFrame, Progress, Variant};
use evigrid::Params;
use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, DynamicImage, RgbImage};
use output::mcap::{McapFrame, McapRecorder};
use output::{
    ClassColours, GridExports, decision_image, pignistic_image, trace_image, write_atomic,
    write_grid_exports, write_png,
};
use rayon::prelude::*;
use sim::Scenario;

use crate::exit::BadInput;

/// The embedded map: buildings, roads and car parks around the demo route, GeoJSON.
const MAP_GEOJSON: &[u8] = include_bytes!("../../assets/helsinki-demo.geojson");
/// The embedded drive: ego route, traffic, scanner, map errors.
const SCENARIO_TOML: &str = include_str!("../../assets/demo-scenario.toml");
/// Origin (lat, lon) of the full Helsinki extract's local frame, in which the scenario's
/// waypoints are given; the crop is loaded with it so that both share one frame.
const FULL_MAP_ORIGIN: (f64, f64) = (60.171_634_0, 24.944_295_4);
/// The variants scored, in table order.
const VARIANTS: [Variant; 2] = [Variant::Kurdej2013, Variant::NoMap];
/// The variant whose views are rendered.
const VIEWS_OF: Variant = Variant::Kurdej2013;
/// Attribution the map's licence requires wherever the map is shown.
pub(crate) const OSM_ATTRIBUTION: &str = "Map data © OpenStreetMap contributors, ODbL";

/// Arguments of `evigrid demo`.
#[derive(Debug, Args)]
#[command(after_long_help = OUTPUTS_HELP)]
pub struct DemoArgs {
    /// Output directory (created if missing).
    #[arg(long, default_value = "evigrid-demo")]
    out: PathBuf,
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
  frames/pignistic-NNNNNN.png  per frame, `kurdej2013`: betP colour mix (F green, I dark blue,
                               U mid blue, S light blue, M red; black = never observed)
  frames/decision-NNNNNN.png   per frame, `kurdej2013`: decided class, same colours
  frames/trace-NNNNNN.png      per frame, `kurdej2013`: decision map with every cell ever
                               decided moving painted red (trace of moving objects)
  decision.gif                 the decision view over the whole drive, 10 frames per second
  metrics.json                 evaluation of kurdej2013 and no-map against the simulator's truth
  report.md                    its tables (cells in view first), parameters and the command line
  confusion-<variant>.png      row-normalised confusion matrix per variant, cells in view
  per-class-iou.png            IoU of F, I, U, S, M per variant, cells in view
  run.mcap                     Foxglove recording of `kurdej2013`: per frame the decision grid, the
                               pose, the scan; the map's outlines (not with --no-mcap)
  occupancy.json, classes.json, masses.json/.bin, map.pgm/.yaml, decision-map.png/.pgw/.prj
                               the final grid of `kurdej2013`, as `evigrid run` writes them
Map data © OpenStreetMap contributors, ODbL.";

/// Runs `evigrid demo`.
pub fn run(args: DemoArgs) -> Result<()> {
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
    let mut scenario = Scenario::from_toml(SCENARIO_TOML).context("embedded demo scenario")?;
    if let Some(frames) = args.frames
        && frames < scenario.frame_count()
    {
        // frame_count() rounds duration × rate, so this gives exactly `frames` frames.
        scenario.duration_s = frames as f64 / scenario.sensor.rate_hz;
    }
    let frames = scenario.frame_count();
    let config = EvalConfig {
        params: Params::default(),
        ..EvalConfig::default()
    };
    let frames_dir = args.out.join("frames");
    fs::create_dir_all(&frames_dir)
        .with_context(|| format!("cannot create {}", frames_dir.display()))?;
    let delay_ms = (1000.0 / scenario.sensor.rate_hz).round() as u32;

    // One pass over the drive: the evaluation runs the variants frame by frame, and the
    // views are rendered from its `VIEWS_OF` method, not from a second run of it. Encoding the
    // PNGs and the GIF is the other half of the work; it runs on its own thread, fed through a
    // short queue (memory stays bounded), while the pipelines go on with the next frames.
    let bar = crate::progress::bar(frames as u64, "demo");
    let (views_tx, views_rx) = mpsc::sync_channel::<FrameViews>(QUEUED_FRAMES);
    let mut recorder = if args.no_mcap {
        None
    } else {
        Some(McapRecorder::create(
            &args.out.join("run.mcap"),
            Some(&loaded.map),
        )?)
    };
    // The MCAP frames and the final exports, written from the observer.
    let mut recorded: Result<()> = Ok(());
    let (report, rendered, encoded) = std::thread::scope(|scope| {
        let frames_dir = &frames_dir;
        let encoder = scope.spawn(move || encode_views(views_rx, frames_dir, delay_ms));
        let mut rendered: Result<()> = Ok(());
        let report = eval::evaluate_observed(
            &loaded.map,
            &scenario,
            &VARIANTS,
            &[scenario.seed],
            &config,
            &mut |p: Progress| bar.set_position(p.frame as u64),
            &mut |f: FusionFrame<'_>| {
                if f.variant != VIEWS_OF || rendered.is_err() {
                    return;
                }
                rendered = render_views(&f, f.frame).map(|views| {
                    // A closed queue means the encoder failed; its error is reported below.
                    let _ = views_tx.send(views);
                });
                if recorded.is_ok() {
                    recorded = record_frame(&f, recorder.as_mut(), frames, &args.out, &loaded);
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
    let report = report.context("evaluating the demo drive")?;
    rendered?;
    recorded?;
    if let Some(recorder) = recorder {
        recorder.finish()?;
    }
    let gif_bytes = encoded?;
    bar.finish_and_clear();
    write_atomic(&args.out.join("decision.gif"), |f| f.write_all(&gif_bytes))?;

    let seconds = started.elapsed().as_secs_f64();
    let params = config.params_for(&scenario);
    let json = super::eval::write_outputs(&args.out, &report, &params, "evigrid demo", seconds)?;
    append_attribution(&args.out.join("report.md"))?;

    if args.json {
        println!("{json}");
    } else {
        print!("{}", super::eval::table(&report));
        println!(
            "{frames} frames ({:.1} s of driving) in {seconds:.1} s; outputs in {}",
            frames as f64 * report.frame_period_s,
            args.out.display()
        );
        println!("{OSM_ATTRIBUTION}");
    }
    Ok(())
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
            time_s: f.time_s,
            window,
            decisions: fusion.decisions(),
            perception: fusion.perception(),
            world_from_sensor: f.world_from_sensor,
            points_in_sensor: f.points_in_sensor,
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
                time_s: f.time_s,
                projection: Some(&loaded.projection),
            },
        )?;
    }
    Ok(())
}

/// Frames rendered ahead of the encoder at most (three 320 × 320 RGB images each, 300 kB).
const QUEUED_FRAMES: usize = 8;

/// The three views of one frame, rendered and waiting to be encoded.
struct FrameViews {
    index: usize,
    pignistic: RgbImage,
    trace: RgbImage,
    decision: RgbImage,
}

/// Renders the [`VIEWS_OF`] method's three views of the paper's Fig. 2 after frame `index`.
fn render_views(frame: &FusionFrame<'_>, index: usize) -> Result<FrameViews> {
    let five = ClassColours::FIVE_CLASSES;
    let (window, fusion) = (frame.front_end.window(), frame.fusion);
    Ok(FrameViews {
        index,
        pignistic: pignistic_image(window, fusion.perception(), &five)?,
        trace: trace_image(window, fusion.decisions(), fusion.trace(), &five)?,
        decision: decision_image(window, fusion.decisions(), &five)?,
    })
}

/// Writes every frame's views as PNG into `frames_dir` and returns the decision view encoded as
/// an animated GIF (built in memory, a few hundred kB: few colours, long runs; written atomically
/// by the caller so that a write error is reported rather than lost in a drop).
fn encode_views(
    views: mpsc::Receiver<FrameViews>,
    frames_dir: &Path,
    delay_ms: u32,
) -> Result<Vec<u8>> {
    let mut gif_bytes = Vec::new();
    {
        // Speed 30: the decision view has a handful of colours, so the quantiser has nothing to
        // gain from its slow modes.
        let mut gif = GifEncoder::new_with_speed(&mut gif_bytes, 30);
        gif.set_repeat(Repeat::Infinite)?;
        for v in views {
            let k = v.index;
            // The three PNGs are independent: encode them side by side.
            let pngs = [
                (&v.pignistic, format!("pignistic-{k:06}.png")),
                (&v.trace, format!("trace-{k:06}.png")),
                (&v.decision, format!("decision-{k:06}.png")),
            ];
            pngs.par_iter()
                .try_for_each(|(image, name)| write_png(image, &frames_dir.join(name)))?;
            gif.encode_frame(gif_frame(v.decision, delay_ms))?;
        }
        // Dropping the encoder writes the GIF trailer.
    }
    Ok(gif_bytes)
}

fn gif_frame(image: RgbImage, delay_ms: u32) -> image::Frame {
    image::Frame::from_parts(
        DynamicImage::ImageRgb8(image).to_rgba8(),
        0,
        0,
        Delay::from_numer_denom_ms(delay_ms, 1),
    )
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
