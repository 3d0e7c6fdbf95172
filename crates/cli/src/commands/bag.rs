//! `evigrid bag`: inspect ROS 2 recordings (MCAP) before running on them.
//!
//! ```text
//! evigrid bag info FILE [--json]
//! ```
//!
//! Lists the topics (type, encoding, count, log-time span) and what `evigrid run --bag` would read
//! with the default choices: the PointCloud2 topic, its frame, the scans and the pose source
//! (or why it cannot). A file that cannot be read exits with status 2 and one line naming the
//! file and the problem. All the work is `drive::bag`'s.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::{Args, Subcommand};
use drive::bag::{BagDrive, BagOptions, BagPoses, TopicInfo, list_topics};
use serde::Serialize;

use crate::exit::BadInput;

/// Subcommands of `evigrid bag`.
#[derive(Debug, Subcommand)]
pub enum BagCommand {
    /// Topics with types and counts, time span, and the drive the default choices read.
    Info(InfoArgs),
}

/// Arguments of `evigrid bag info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The recording (`.mcap`, ROS 2 CDR messages), or the rosbag2 folder holding it.
    file: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// Runs one `evigrid bag` subcommand.
pub fn run(command: BagCommand) -> Result<()> {
    match command {
        BagCommand::Info(args) => info(&args),
    }
}

#[derive(Serialize)]
struct Topic<'a> {
    topic: &'a str,
    schema: &'a str,
    encoding: &'a str,
    count: u64,
    /// First and last log time, seconds.
    start_s: f64,
    end_s: f64,
}

/// What the default options read, or why they cannot.
#[derive(Serialize)]
struct DriveSummary {
    cloud_topic: Option<String>,
    cloud_frame: Option<String>,
    scans: usize,
    pose_source: Option<String>,
    poses: usize,
    error: Option<String>,
}

#[derive(Serialize)]
struct Info<'a> {
    file: &'a Path,
    messages: u64,
    start_s: Option<f64>,
    end_s: Option<f64>,
    topics: Vec<Topic<'a>>,
    drive: DriveSummary,
}

fn seconds(ns: u64) -> f64 {
    ns as f64 * 1e-9
}

fn drive_summary(file: &Path) -> DriveSummary {
    match BagDrive::open(file, &BagOptions::default()) {
        Ok(bag) => DriveSummary {
            cloud_topic: Some(bag.cloud_topic().to_owned()),
            cloud_frame: Some(bag.cloud_frame().to_owned()),
            scans: bag.scan_times().len(),
            pose_source: Some(bag.pose_source().to_owned()),
            poses: match bag.poses() {
                BagPoses::Local(t) => t.len(),
                BagPoses::Wgs84(g) => g.fixes.len(),
                // Scans placed by lidar odometry later.
                _ => 0,
            },
            error: None,
        },
        Err(e) => DriveSummary {
            cloud_topic: None,
            cloud_frame: None,
            scans: 0,
            pose_source: None,
            poses: 0,
            error: Some(e.to_string()),
        },
    }
}

fn info(args: &InfoArgs) -> Result<()> {
    let topics: Vec<TopicInfo> =
        list_topics(&args.file).map_err(|e| BadInput::new(e.to_string()))?;
    let with_messages = || topics.iter().filter(|t| t.count > 0);
    let info = Info {
        file: &args.file,
        messages: topics.iter().map(|t| t.count).sum(),
        start_s: with_messages().map(|t| t.log_time_ns.0).min().map(seconds),
        end_s: with_messages().map(|t| t.log_time_ns.1).max().map(seconds),
        topics: topics
            .iter()
            .map(|t| Topic {
                topic: &t.topic,
                schema: &t.schema,
                encoding: &t.encoding,
                count: t.count,
                start_s: seconds(t.log_time_ns.0),
                end_s: seconds(t.log_time_ns.1),
            })
            .collect(),
        drive: drive_summary(&args.file),
    };
    if args.json {
        crate::outln!("{}", serde_json::to_string_pretty(&info)?);
        return Ok(());
    }
    crate::outln!("file: {}", args.file.display());
    match (info.start_s, info.end_s) {
        (Some(a), Some(b)) => crate::outln!(
            "messages: {} over {:.3} s (log time {a:.3} .. {b:.3} s)",
            info.messages,
            b - a
        ),
        _ => crate::outln!("messages: 0"),
    }
    let width = topics.iter().map(|t| t.topic.len()).max().unwrap_or(0);
    let schema_width = topics.iter().map(|t| t.schema.len()).max().unwrap_or(0);
    for t in &info.topics {
        crate::outln!(
            "  {:<width$}  {:<schema_width$}  {:>7}  {}",
            t.topic,
            t.schema,
            t.count,
            t.encoding
        );
    }
    let d = &info.drive;
    match (&d.error, &d.cloud_topic) {
        (Some(e), _) => crate::outln!("drive (default choices): cannot read: {e}"),
        (None, Some(topic)) => crate::outln!(
            "drive (default choices): {} scans on {topic} (frame {}), poses: {} ({} samples)",
            d.scans,
            d.cloud_frame.as_deref().unwrap_or(""),
            d.pose_source.as_deref().unwrap_or("none"),
            d.poses
        ),
        (None, None) => {}
    }
    Ok(())
}
