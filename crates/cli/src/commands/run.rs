//! `evigrid run`: the perception pipeline over a drive, with or without a map.
//!
//! ```text
//! evigrid run --drive 2011_09_26/ --out out/                       KITTI raw: scans, OXTS, calib
//! evigrid run --scans scans/ --poses poses.txt --map city.osm.pbf --out out/
//! evigrid run --scans scans/ --out out/                            poses from the lidar odometry
//! ```
//!
//! Wiring only: flags → drive (`drive::source`) → session (`session`) → sinks (`output::sink`)
//! → summary and lines for people. Where scans and poses come from and how they are matched is
//! the drive's; the frame loop, totals and summary are the session's; what is written is the
//! sinks'.

mod args;
mod report;

use anyhow::Result;
use drive::{Drive, SourceError};
use output::sink::{DecisionFrames, FinalOutputs, FrameSink, FramesLog, McapSink};
use session::{Map, SessionConfig, SessionError};

pub use args::RunArgs;

use crate::exit::BadInput;
use crate::input::read_params;

/// Runs `evigrid run`.
pub fn run(args: RunArgs) -> Result<()> {
    // Validated as it is read: the defaults are valid by construction.
    let params = read_params(args.config.as_deref())?;
    let origin = args.origin.as_deref().map(parse_origin).transpose()?;
    let drive = Drive::open(&args.drive_spec()?).map_err(source_error)?;
    // Checked before any work (a wrong --out must not cost the run), created once every input
    // has been checked (a bad input leaves no folder behind).
    crate::out_dir::OutDir::check(&args.out, &args.input_paths(), args.force)?;
    let interrupt = crate::interrupt::Interrupt::install();
    let map = match &args.map {
        Some(path) => Some(Map::load(path, origin).map_err(session_error)?),
        None => None,
    };
    if let Some(map) = &map {
        let (stats, e) = (&map.loaded.stats, &map.loaded.stats.extent_m);
        tracing::info!(
            "map: {} buildings, {} road polygons, {:.0} m x {:.0} m",
            stats.buildings,
            map.loaded.map.roads.len(),
            e.width_m,
            e.height_m
        );
    }
    let config = SessionConfig {
        params,
        method: args.method.into(),
        map,
        origin,
        strict: args.strict,
        max_frames: args.max_frames,
        out: args.out.display().to_string(),
    };
    let mut bars = report::Bars::new(args.json);
    let placement =
        session::place(drive, &config, interrupt.flag(), &mut bars).map_err(session_error)?;
    let scans = placement.drive.len();
    tracing::info!(
        "{scans} scans from {}; poses: {} (matched by {}); prior: {}",
        placement.drive.given_path().display(),
        placement.poses.origin,
        placement.poses.origin.matching().name(),
        if config.map.is_some() {
            "map"
        } else {
            "vacuous (no map)"
        }
    );
    let out_dir =
        crate::out_dir::OutDir::prepare(&args.out, &args.input_paths(), args.force, "run")?;
    let outcome = {
        let mut sinks = Sinks::create(&args, &config)?;
        let mut sinks = sinks.as_dyn();
        session::run_placed(placement, config, &mut sinks, interrupt.flag(), &mut bars)
            .map_err(session_error)?
    };
    let mut summary = outcome.summary;
    if outcome
        .error
        .as_ref()
        .is_some_and(SessionError::is_interrupted)
    {
        // The session knows its stop flag was raised, not by which signal: name it.
        summary.stopped = Some(crate::interrupt::Interrupted.to_string());
    }
    let text = serde_json::to_string_pretty(&WrittenSummary {
        tool: concat!("evigrid ", env!("CARGO_PKG_VERSION")),
        command_line: crate::input::command_line(),
        summary: &summary,
    })?;
    let summary_path = args.out.join("summary.json");
    let summary_written = output::write_atomic(&summary_path, |file| {
        std::io::Write::write_all(file, text.as_bytes())
    });
    if let Some(error) = outcome.error {
        // The summary says what was done; the error says why the run ended.
        let frames = format!("run stopped after {} of {scans} frames", summary.frames);
        let note = match summary_written {
            Ok(()) => format!(
                "{frames}, summary in {} (marked incomplete)",
                summary_path.display()
            ),
            Err(e) => format!("{frames}; the summary could not be written either ({e})"),
        };
        let _ = out_dir.finish();
        return Err(session_error(error).context(note));
    }
    summary_written?;
    out_dir.finish()?;
    if let Some(first) = summary.skipped_scans.first() {
        crate::errln!(
            "evigrid: {} scan(s) skipped, the first: {} (all in skipped_scans of {})",
            summary.skipped_scans.len(),
            first.error,
            summary_path.display()
        );
    }
    if args.json {
        crate::outln!("{text}");
    } else {
        report::print_summary(&summary);
    }
    Ok(())
}

/// `summary.json`: what wrote it and how to run it again, then the session's summary.
#[derive(serde::Serialize)]
struct WrittenSummary<'a> {
    /// `evigrid <version>`.
    tool: &'static str,
    /// The command line, as given (arguments quoted where needed).
    command_line: String,
    #[serde(flatten)]
    summary: &'a session::Summary,
}

/// The outputs of a run: the recording (unless `--no-mcap`), the per-frame pictures, the
/// per-frame records and the final figures and grids, in that order.
struct Sinks {
    mcap: Option<McapSink>,
    frames: DecisionFrames,
    log: FramesLog,
    last: FinalOutputs,
}

impl Sinks {
    fn create(args: &RunArgs, config: &SessionConfig) -> Result<Self> {
        let out = &args.out;
        let map = config.map.as_ref().map(|m| &m.loaded.map);
        Ok(Self {
            frames: DecisionFrames::create(&out.join("frames"))?,
            mcap: match args.no_mcap {
                true => None,
                false => Some(McapSink::create(&out.join("run.mcap"), map)?),
            },
            log: FramesLog::create(&out.join(session::FRAMES_FILE))?,
            last: FinalOutputs::new(out),
        })
    }

    fn as_dyn(&mut self) -> Vec<&mut dyn FrameSink> {
        let mut sinks: Vec<&mut dyn FrameSink> = Vec::with_capacity(4);
        if let Some(mcap) = &mut self.mcap {
            sinks.push(mcap);
        }
        sinks.push(&mut self.frames);
        sinks.push(&mut self.log);
        sinks.push(&mut self.last);
        sinks
    }
}

/// A drive's error as the command reports it: always the input's fault (exit code 2), with the
/// flags that fix a missing projection.
fn source_error(error: SourceError) -> anyhow::Error {
    match error {
        SourceError::NeedsProjection { what } => BadInput::new(format!(
            "{what}: WGS84 poses need --map or --origin (or a KITTI raw --drive)"
        )),
        other => BadInput::new(other.to_string()),
    }
}

/// A session's error as the command reports it: interrupted (exit 130), the input's fault
/// (exit 2), or an I/O failure.
fn session_error(error: SessionError) -> anyhow::Error {
    match error {
        SessionError::Source(e) => source_error(e),
        SessionError::Stopped { cause, .. } => session_error(*cause),
        e if e.is_interrupted() => crate::interrupt::Interrupted.into(),
        e if e.is_bad_input() => BadInput::new(e.to_string()),
        e => e.into(),
    }
}

/// Parses `LAT,LON` in degrees.
fn parse_origin(text: &str) -> Result<(f64, f64)> {
    let bad = || BadInput::new(format!("--origin {text}: expected LAT,LON in degrees"));
    let (lat, lon) = text.split_once(',').ok_or_else(bad)?;
    let lat: f64 = lat.trim().parse().map_err(|_| bad())?;
    let lon: f64 = lon.trim().parse().map_err(|_| bad())?;
    if !((-90.0..=90.0).contains(&lat) && (-180.0..=180.0).contains(&lon)) {
        return Err(bad());
    }
    Ok((lat, lon))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn origin_is_lat_comma_lon() {
        assert_eq!(parse_origin("60.17, 24.94").unwrap(), (60.17, 24.94));
        assert!(parse_origin("60.17").is_err());
        assert!(parse_origin("95,0").is_err());
    }
}
