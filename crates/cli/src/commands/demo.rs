//! `evigrid demo`: the main job on embedded data, with no input files.
//!
//! ```text
//! evigrid demo [--out evigrid-demo] [--frames N] [--json]
//! ```
//!
//! A simulated drive with traffic over a real map of central Helsinki that ships inside the binary
//! (`assets/helsinki-demo.geojson`, cropped from the OpenStreetMap extract with `evigrid map crop`;
//! map data © OpenStreetMap contributors, ODbL). The `full` pipeline runs frame by frame and its
//! views of the paper's Fig. 2 are written per frame; then `full` and `no-map` are scored against
//! the simulator's truth exactly as `evigrid eval` does, and the same report is written.
//!
//! Wiring only: the drive is `sim::Drive`'s, the perception `evigrid::Pipeline`'s, the scoring
//! `sim::evaluate`'s.

use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use evigrid::Params;
use evigrid::pipeline::Pipeline;
use evigrid::render::{
    ClassColours, decision_image, pignistic_image, trace_image, write_atomic, write_png,
};
use evigrid::sensor_model::GroundModel;
use geodata::{ContextRaster, LocalMap};
use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, DynamicImage, RgbImage};
use sim::eval::{EvalConfig, Progress, Variant};
use sim::{Drive, Scenario};

use crate::exit::BadInput;

/// The embedded map: buildings, roads and car parks around the demo route, GeoJSON.
const MAP_GEOJSON: &[u8] = include_bytes!("../../assets/helsinki-demo.geojson");
/// The embedded drive: ego route, traffic, scanner, map errors.
const SCENARIO_TOML: &str = include_str!("../../assets/demo-scenario.toml");
/// Origin (lat, lon) of the full Helsinki extract's local frame, in which the scenario's
/// waypoints are given; the crop is loaded with it so that both share one frame.
const FULL_MAP_ORIGIN: (f64, f64) = (60.171_634_0, 24.944_295_4);
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
}

const OUTPUTS_HELP: &str = "\
Outputs (in --out):
  frames/pignistic-NNNNNN.png  per frame, `full`: betP colour mix (F green, I dark blue,
                               U mid blue, S light blue, M red; black = never observed)
  frames/decision-NNNNNN.png   per frame, `full`: decided class, same colours
  frames/trace-NNNNNN.png      per frame, `full`: decision map with every cell ever decided
                               moving painted red (trace of moving objects)
  decision.gif                 the decision view over the whole drive, 10 frames per second
  metrics.json                 evaluation of full and no-map against the simulator's truth
  report.md                    its tables, parameters and the command line
  confusion-<variant>.png      row-normalised confusion matrix per variant
  per-class-iou.png            IoU of F, I, U, S, M per variant
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
    let mut params = Params::default();
    // The simulated scanner is planar; evaluate() forces the same.
    params.sensor.ground_model = GroundModel::None;

    let bar = crate::progress::bar(2 * frames as u64, "demo");
    drive_full(&loaded.map, &scenario, &params, &args.out, &mut || {
        bar.inc(1);
    })?;
    let config = EvalConfig {
        params,
        ..EvalConfig::default()
    };
    let report = sim::evaluate(
        &loaded.map,
        &scenario,
        &[Variant::Full, Variant::NoMap],
        &[scenario.seed],
        &config,
        &mut |p: Progress| bar.set_position((frames + p.frame + 1) as u64),
    )
    .context("evaluating the demo drive")?;
    bar.finish_and_clear();

    let seconds = started.elapsed().as_secs_f64();
    let json =
        super::eval::write_outputs(&args.out, &report, &config.params, "evigrid demo", seconds)?;
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

/// Drives the `full` pipeline frame by frame, writing its three views per frame and the decision
/// view as an animated GIF. `step` is called once per frame.
fn drive_full(
    map: &LocalMap,
    scenario: &Scenario,
    params: &Params,
    out: &Path,
    step: &mut dyn FnMut(),
) -> Result<()> {
    let frames_dir = out.join("frames");
    fs::create_dir_all(&frames_dir)
        .with_context(|| format!("cannot create {}", frames_dir.display()))?;
    let mut drive = Drive::new(map, scenario).context("demo drive")?;
    let mut pipeline = Pipeline::new(
        params.clone(),
        Some(ContextRaster::new(drive.pipeline_map())),
    )?;
    // The GIF is built in memory (a few hundred kB: few colours, long runs) and written
    // atomically at the end, so a write error is reported rather than lost in a drop.
    let mut gif_bytes = Vec::new();
    // Speed 30: the decision view has a handful of colours, so the quantiser has nothing to
    // gain from its slow modes.
    let mut gif = GifEncoder::new_with_speed(&mut gif_bytes, 30);
    gif.set_repeat(Repeat::Infinite)?;
    let delay_ms = (1000.0 / scenario.sensor.rate_hz).round() as u32;
    let five = ClassColours::FIVE_CLASSES;
    while let Some(frame) = drive.next_frame() {
        let scan = &frame.scan;
        pipeline.process(
            &scan.points_xyz_f32(),
            &scan.estimated_isometry(),
            scan.time_s,
        )?;
        let window = pipeline.window();
        let k = frame.index;
        let decision = decision_image(window, pipeline.decisions(), &five)?;
        write_png(
            &pignistic_image(window, pipeline.perception(), &five)?,
            &frames_dir.join(format!("pignistic-{k:06}.png")),
        )?;
        write_png(
            &trace_image(window, pipeline.decisions(), pipeline.trace(), &five)?,
            &frames_dir.join(format!("trace-{k:06}.png")),
        )?;
        write_png(&decision, &frames_dir.join(format!("decision-{k:06}.png")))?;
        gif.encode_frame(gif_frame(decision, delay_ms))?;
        step();
    }
    // Dropping the encoder writes the GIF trailer.
    drop(gif);
    write_atomic(&out.join("decision.gif"), |f| f.write_all(&gif_bytes))?;
    Ok(())
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
