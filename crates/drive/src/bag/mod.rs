//! ROS 2 recordings (rosbag2 in MCAP) read as a drive: the scans of one
//! `sensor_msgs/msg/PointCloud2` topic and the poses that place them.
//!
//! [`BagDrive::open`] reads the file once, streaming: it lists the topics (type, encoding, count,
//! log-time span), checks every cloud's header, and gathers the chosen pose source; only the
//! poses are kept. [`BagDrive::scans`] then reads the file again and decodes one cloud at a time,
//! so memory is bounded by the largest chunk and the pose track, not by the recording.
//!
//! Pose sources ([`PoseSource`]), giving `world_from_sensor` for the cloud's `frame_id`:
//! - **tf**: `/tf` and `/tf_static` (`tf2_msgs/msg/TFMessage`); the chain from a fixed frame
//!   (by default the root of the tree above the cloud's frame, e.g. `map` or `odom`) down to the
//!   cloud's frame, sampled at the times of its moving edge;
//! - **odometry**: a `nav_msgs/msg/Odometry` topic, `header.frame_id` as the world and
//!   `child_frame_id` carried to the cloud's frame through `/tf_static`;
//! - **NavSatFix**: WGS84 positions, heading from successive fixes (see [`navsat`]), placed by a
//!   projection the caller gives ([`BagPoses::track`]);
//! - **none**: the caller places the scans itself (lidar odometry).
//!
//! Scan times are the clouds' header stamps (seconds; ROS time is usually Unix time), or the
//! message's log time when the stamp is zero. Poses at scan times come from
//! [`PoseTrack::at`]'s interpolation.
//!
//! Limits: CDR only (what rosbag2 writes); chunk compression none, zstd or lz4 (lz4 decoded in
//! Rust by `lz4`, not mcap's C binding); records above
//! [`MAX_RECORD_BYTES`] are refused; the cloud's `x`, `y`, `z` must be FLOAT32 or FLOAT64
//! (`intensity` may be any numeric type); a topic's clouds must share one `frame_id`. ROS 1 bags
//! (`.bag`) and rosbag2's SQLite storage (`.db3`) are not read: convert them with `mcap convert`.
//! A rosbag2 folder (`metadata.yaml` beside the files) may be given for its one MCAP file
//! ([`recording_file`]).

mod cdr;
pub mod error;
mod folder;
mod lz4;
mod msgs;
pub mod navsat;
mod tf;

pub use error::BagError;
pub use folder::recording_file;
pub use msgs::{NAVSATFIX, ODOMETRY, POINTCLOUD2, TFMESSAGE};
pub use navsat::{GeodeticFix, GeodeticTrack};

use crate::poses::PoseTrack;
use crate::scan::Scan;
use cdr::CdrError;
use mcap::sans_io::LinearReaderOptions;
use msgs::StampedTransform;
use nalgebra::Isometry3;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use tf::{TfTree, frame_key};

/// Largest MCAP record (or chunk, compressed or not) read, in bytes (1 GiB): far above a real
/// cloud (an Ouster OS2-128 frame is about 10 MB, rosbag2's chunks default to 768 KiB), and a
/// bound on what a corrupt length can make the reader allocate.
pub const MAX_RECORD_BYTES: usize = 1 << 30;

/// How many times its compressed size a chunk's content may be: far above what zstd or LZ4 make
/// of point clouds (2–10×), so that a file's size bounds what its lengths can make the reader
/// allocate.
const MAX_COMPRESSION_RATIO: usize = 256;

/// The record limit of the smallest files, bytes (64 MiB): a small recording of one large cloud
/// still opens.
const MIN_RECORD_LIMIT: usize = 1 << 26;

/// The largest record or chunk content a file of `file_len` bytes can hold: no record is longer
/// than the file, and no chunk's content more than [`MAX_COMPRESSION_RATIO`] times it. Without
/// this, an 18-byte file whose header record claims 800 MB made the reader allocate and zero
/// 800 MB (issue 31, a fuzz finding).
fn record_limit(file_len: u64) -> usize {
    usize::try_from(file_len)
        .unwrap_or(usize::MAX)
        .saturating_mul(MAX_COMPRESSION_RATIO)
        .clamp(MIN_RECORD_LIMIT, MAX_RECORD_BYTES)
}

/// Where the poses of a recording come from.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum PoseSource {
    /// The first that works of: tf (from the root above the cloud's frame), the odometry topic
    /// (the first by name when several), the NavSatFix topic (likewise), none.
    #[default]
    Auto,
    /// `/tf` and `/tf_static`, from `fixed_frame` (default: the root above the cloud's frame).
    Tf {
        /// The world frame, e.g. `map` or `odom`.
        fixed_frame: Option<String>,
    },
    /// A `nav_msgs/msg/Odometry` topic (default: the only one).
    Odometry {
        /// The topic.
        topic: Option<String>,
    },
    /// A `sensor_msgs/msg/NavSatFix` topic (default: the only one).
    NavSatFix {
        /// The topic.
        topic: Option<String>,
    },
    /// No poses: the caller places the scans.
    None,
}

impl std::str::FromStr for PoseSource {
    type Err = String;

    /// `auto`, `none`, `tf[:FIXED_FRAME]`, `odom[:TOPIC]`, `navsat[:TOPIC]` (for command lines).
    fn from_str(text: &str) -> Result<Self, String> {
        let (kind, arg) = match text.split_once(':') {
            Some((k, a)) if !a.is_empty() => (k, Some(a.to_owned())),
            Some((k, _)) => (k, None),
            None => (text, None),
        };
        match (kind, arg) {
            ("auto", None) => Ok(PoseSource::Auto),
            ("none", None) => Ok(PoseSource::None),
            ("tf", fixed_frame) => Ok(PoseSource::Tf { fixed_frame }),
            ("odom" | "odometry", topic) => Ok(PoseSource::Odometry { topic }),
            ("navsat" | "navsatfix" | "gps", topic) => Ok(PoseSource::NavSatFix { topic }),
            _ => Err(format!(
                "pose source `{text}`: expected auto, none, tf[:FIXED_FRAME], odom[:TOPIC] or \
                 navsat[:TOPIC]"
            )),
        }
    }
}

/// What to read from a recording.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct BagOptions {
    /// The PointCloud2 topic; default: the only one in the file.
    pub cloud_topic: Option<String>,
    /// Where the poses come from.
    pub pose_source: PoseSource,
}

/// One topic of a recording.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    /// The topic name.
    pub topic: String,
    /// The schema name, e.g. `sensor_msgs/msg/PointCloud2` (empty without a schema).
    pub schema: String,
    /// The message encoding, `cdr` for ROS 2.
    pub encoding: String,
    /// Messages on the topic.
    pub count: u64,
    /// First and last log time, nanoseconds (0 when there are no messages).
    pub log_time_ns: (u64, u64),
}

/// The poses of a recording, `world_from_sensor` for the cloud's frame.
#[derive(Debug, Clone, PartialEq)]
pub enum BagPoses {
    /// In a local metric frame (tf or odometry).
    Local(PoseTrack),
    /// WGS84 fixes, to be projected by the caller.
    Wgs84(GeodeticTrack),
    /// None (the source was [`PoseSource::None`], or `Auto` found nothing).
    None,
}

impl BagPoses {
    /// The track in the projection's frame: local poses as they are, fixes projected (see
    /// [`navsat`]); `None` without poses.
    ///
    /// # Errors
    ///
    /// [`BagError::Poses`] from [`GeodeticTrack::into_track`].
    pub fn track<P>(&self, projection: &P) -> Result<Option<PoseTrack>, BagError>
    where
        P: Fn(f64, f64) -> (f64, f64) + ?Sized,
    {
        match self {
            BagPoses::Local(t) => Ok(Some(t.clone())),
            BagPoses::Wgs84(g) => g.into_track(projection).map(Some),
            BagPoses::None => Ok(None),
        }
    }
}

/// One scan of a recording.
#[derive(Debug, Clone, PartialEq)]
pub struct BagScan {
    /// 0-based index among the cloud topic's messages.
    pub index: u64,
    /// Header stamp (or log time when the stamp is zero), seconds.
    pub time_s: f64,
    /// The points, in the cloud's frame.
    pub scan: Scan,
}

/// A ROS 2 MCAP recording opened as a drive (see the module documentation).
#[derive(Debug, Clone)]
pub struct BagDrive {
    path: PathBuf,
    topics: Vec<TopicInfo>,
    cloud_topic: String,
    cloud_frame: String,
    scan_times: Vec<f64>,
    poses: BagPoses,
    pose_source: String,
}

/// What one pass gathers per topic.
#[derive(Default)]
struct Gathered {
    topics: BTreeMap<String, TopicInfo>,
    tf: TfTree,
    odometry: BTreeMap<String, Vec<StampedTransform>>,
    fixes: BTreeMap<String, (String, Vec<GeodeticFix>)>,
    /// Per PointCloud2 topic: frame id and scan times.
    clouds: BTreeMap<String, (String, Vec<f64>)>,
}

fn reader(path: &Path) -> Result<mcap::io::MessageReader<BufReader<File>>, BagError> {
    let io = |source| BagError::Io {
        path: path.to_path_buf(),
        source,
    };
    // Checked before opening: opening a FIFO with no writer blocks forever (issue 31).
    let metadata = std::fs::metadata(path).map_err(io)?;
    if !metadata.is_file() {
        return Err(io(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a regular file",
        )));
    }
    let file = File::open(path).map_err(io)?;
    let options =
        LinearReaderOptions::default().with_record_length_limit(record_limit(metadata.len()));
    let mut reader = mcap::io::MessageReader::new_with_options(BufReader::new(file), options);
    reader
        .add_decompressor(lz4::Lz4Chunks::new())
        .map_err(|source| mcap_error(path, 0, source))?;
    Ok(reader)
}

fn mcap_error(path: &Path, messages: u64, source: mcap::McapError) -> BagError {
    match source {
        mcap::McapError::UnsupportedCompression(compression) => BagError::Compression {
            path: path.to_path_buf(),
            compression,
        },
        mcap::McapError::Io(source) => BagError::Io {
            path: path.to_path_buf(),
            source,
        },
        source => BagError::Mcap {
            path: path.to_path_buf(),
            messages,
            source,
        },
    }
}

fn schema_name<'m>(message: &'m mcap::Message<'_>) -> &'m str {
    message
        .channel
        .schema
        .as_ref()
        .map_or("", |s| s.name.as_str())
}

/// Lists the topics of a recording: type, encoding, count and log-time span, in name order.
///
/// # Errors
///
/// [`BagError`]: unreadable file, malformed container, unsupported compression.
pub fn list_topics(path: &Path) -> Result<Vec<TopicInfo>, BagError> {
    let path = &recording_file(path)?;
    let mut topics = BTreeMap::new();
    for (seen, message) in (0u64..).zip(reader(path)?) {
        let message = message.map_err(|e| mcap_error(path, seen, e))?;
        count(&mut topics, &message);
    }
    Ok(topics.into_values().collect())
}

/// Counts a message on its topic; returns its 0-based index there.
fn count(topics: &mut BTreeMap<String, TopicInfo>, message: &mcap::Message<'_>) -> u64 {
    let info = topics
        .entry(message.channel.topic.clone())
        .or_insert_with(|| TopicInfo {
            topic: message.channel.topic.clone(),
            schema: schema_name(message).to_owned(),
            encoding: message.channel.message_encoding.clone(),
            count: 0,
            log_time_ns: (message.log_time, message.log_time),
        });
    info.log_time_ns.0 = info.log_time_ns.0.min(message.log_time);
    info.log_time_ns.1 = info.log_time_ns.1.max(message.log_time);
    info.count += 1;
    info.count - 1
}

/// `topic (type, count)` for every topic, for error messages.
fn available(topics: &[TopicInfo]) -> String {
    if topics.is_empty() {
        return "no messages".to_owned();
    }
    topics
        .iter()
        .map(|t| format!("{} ({}, {})", t.topic, t.schema, t.count))
        .collect::<Vec<_>>()
        .join(", ")
}

/// What a pass decodes besides counting.
struct Wanted {
    tf: bool,
    /// Odometry and NavSatFix topics to gather; `None` means every topic of the type.
    odometry: Option<Option<String>>,
    fixes: Option<Option<String>>,
}

impl Wanted {
    /// What the poses of `source` need gathered.
    fn for_source(source: &PoseSource) -> Self {
        match source {
            PoseSource::Auto => Wanted {
                tf: true,
                odometry: Some(None),
                fixes: Some(None),
            },
            PoseSource::Tf { .. } => Wanted {
                tf: true,
                odometry: None,
                fixes: None,
            },
            // Static tf carries the child frame to the cloud's frame.
            PoseSource::Odometry { topic } => Wanted {
                tf: true,
                odometry: Some(topic.clone()),
                fixes: None,
            },
            PoseSource::NavSatFix { topic } => Wanted {
                tf: true,
                odometry: None,
                fixes: Some(topic.clone()),
            },
            PoseSource::None => Wanted {
                tf: false,
                odometry: None,
                fixes: None,
            },
        }
    }
}

/// The poses of the clouds (in `cloud_frame`) from `source`, built from what was gathered
/// (`g`, `topics`), and the source's description.
fn bag_poses(
    path: &Path,
    g: &Gathered,
    topics: &[TopicInfo],
    cloud_frame: &str,
    source: &PoseSource,
) -> Result<(BagPoses, String), BagError> {
    let poses_error = |message: String| BagError::Poses {
        path: path.to_path_buf(),
        message,
    };
    Ok(match source {
        PoseSource::None => (BagPoses::None, "none".to_owned()),
        PoseSource::Tf { fixed_frame } => {
            let fixed = fixed_frame
                .clone()
                .unwrap_or_else(|| g.tf.root_of(cloud_frame));
            let track = g.tf.track(&fixed, cloud_frame).map_err(poses_error)?;
            (
                BagPoses::Local(track),
                format!("tf {fixed} -> {cloud_frame}"),
            )
        }
        PoseSource::Odometry { topic } => {
            let topic = pick_topic(
                path,
                topics,
                topic.as_deref(),
                ODOMETRY,
                "an odometry topic",
            )?;
            let track = odometry_track(g, &topic, cloud_frame).map_err(poses_error)?;
            (BagPoses::Local(track), format!("odometry {topic}"))
        }
        PoseSource::NavSatFix { topic } => {
            let topic = pick_topic(
                path,
                topics,
                topic.as_deref(),
                NAVSATFIX,
                "a NavSatFix topic",
            )?;
            let track = fix_track(path, g, &topic, cloud_frame).map_err(poses_error)?;
            (BagPoses::Wgs84(track), format!("navsatfix {topic}"))
        }
        PoseSource::Auto => auto_poses(path, g, topics, cloud_frame),
    })
}

fn wants(filter: &Option<Option<String>>, topic: &str) -> bool {
    match filter {
        None => false,
        Some(None) => true,
        Some(Some(t)) => t == topic,
    }
}

impl BagDrive {
    /// Opens a recording: one streaming pass that lists topics, checks the clouds' headers and
    /// gathers the poses of `options.pose_source`.
    ///
    /// # Errors
    ///
    /// [`BagError`]: unreadable or malformed file, unknown or ambiguous topic (the error lists
    /// the topics), a topic of the wrong type, a malformed message (topic and index), or poses
    /// that cannot be built from the chosen source.
    pub fn open(path: &Path, options: &BagOptions) -> Result<Self, BagError> {
        let path = &recording_file(path)?;
        let wanted = Wanted::for_source(&options.pose_source);
        let mut g = Gathered::default();
        for (seen, message) in (0u64..).zip(reader(path)?) {
            let message = message.map_err(|e| mcap_error(path, seen, e))?;
            let index = count(&mut g.topics, &message);
            gather(path, &mut g, &wanted, &message, index)?;
        }
        g.tf.finish();
        let topics: Vec<TopicInfo> = g.topics.values().cloned().collect();

        let cloud_topic = pick_topic(
            path,
            &topics,
            options.cloud_topic.as_deref(),
            POINTCLOUD2,
            "--cloud-topic",
        )?;
        let Some((cloud_frame, scan_times)) = g.clouds.remove(&cloud_topic) else {
            return Err(BagError::Topic {
                path: path.to_path_buf(),
                message: format!("topic {cloud_topic} has no messages"),
                available: available(&topics),
            });
        };
        let (poses, pose_source) =
            bag_poses(path, &g, &topics, &cloud_frame, &options.pose_source)?;
        Ok(Self {
            path: path.to_path_buf(),
            topics,
            cloud_topic,
            cloud_frame,
            scan_times,
            poses,
            pose_source,
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Every topic, in name order.
    pub fn topics(&self) -> &[TopicInfo] {
        &self.topics
    }

    /// The cloud topic read.
    pub fn cloud_topic(&self) -> &str {
        &self.cloud_topic
    }

    /// The clouds' `frame_id` (the sensor frame), without a leading slash.
    pub fn cloud_frame(&self) -> &str {
        &self.cloud_frame
    }

    /// Scan times (seconds), in file order.
    pub fn scan_times(&self) -> &[f64] {
        &self.scan_times
    }

    /// The poses, `world_from_sensor` in the source's own world frame (tf's fixed frame,
    /// odometry's `frame_id`, or the caller's projection for NavSatFix).
    pub fn poses(&self) -> &BagPoses {
        &self.poses
    }

    /// Which source gave the poses, e.g. `tf odom -> velodyne` or `none`.
    pub fn pose_source(&self) -> &str {
        &self.pose_source
    }

    /// The scans, decoded one at a time as the file is read again.
    ///
    /// # Errors
    ///
    /// [`BagError::Io`] when the file cannot be reopened; each item may be an error too.
    pub fn scans(&self) -> Result<BagScans, BagError> {
        Ok(BagScans {
            reader: reader(&self.path)?,
            path: self.path.clone(),
            topic: self.cloud_topic.clone(),
            index: 0,
            seen: 0,
        })
    }
}

/// The single topic of `schema`, or the requested one checked to exist and have that schema.
fn pick_topic(
    path: &Path,
    topics: &[TopicInfo],
    requested: Option<&str>,
    schema: &'static str,
    how: &str,
) -> Result<String, BagError> {
    if let Some(topic) = requested {
        let Some(info) = topics.iter().find(|t| t.topic == topic) else {
            return Err(BagError::UnknownTopic {
                path: path.to_path_buf(),
                topic: topic.to_owned(),
                available: available(topics),
            });
        };
        if info.schema != schema || info.encoding != "cdr" {
            return Err(BagError::WrongType {
                path: path.to_path_buf(),
                topic: topic.to_owned(),
                found: info.schema.clone(),
                encoding: info.encoding.clone(),
                expected: schema,
            });
        }
        return Ok(topic.to_owned());
    }
    let matching: Vec<&TopicInfo> = topics
        .iter()
        .filter(|t| t.schema == schema && t.encoding == "cdr")
        .collect();
    match matching.as_slice() {
        [one] => Ok(one.topic.clone()),
        [] => Err(BagError::Topic {
            path: path.to_path_buf(),
            message: format!("no {schema} topic in cdr"),
            available: available(topics),
        }),
        several => Err(BagError::Topic {
            path: path.to_path_buf(),
            message: format!("{} {schema} topics; choose {how}", several.len()),
            available: available(topics),
        }),
    }
}

/// Decodes what the pass needs from one message.
fn gather(
    path: &Path,
    g: &mut Gathered,
    wanted: &Wanted,
    message: &mcap::Message<'_>,
    index: u64,
) -> Result<(), BagError> {
    let schema = schema_name(message);
    if message.channel.message_encoding != "cdr" {
        return Ok(());
    }
    let topic = message.channel.topic.as_str();
    let bad = |message: String| BagError::Message {
        path: path.to_path_buf(),
        topic: topic.to_owned(),
        index,
        kind: schema.to_owned(),
        message,
    };
    let cdr = |e: CdrError| bad(e.0);
    match schema {
        POINTCLOUD2 => {
            let h = msgs::decode_header(&message.data).map_err(cdr)?;
            let time = stamp_or_log_time(h.stamp_s, message.log_time);
            let frame = frame_key(&h.frame_id).to_owned();
            let (first, times) = g
                .clouds
                .entry(topic.to_owned())
                .or_insert_with(|| (frame.clone(), Vec::new()));
            if *first != frame {
                return Err(bad(format!(
                    "frame_id `{frame}` differs from the topic's first, `{first}`"
                )));
            }
            times.push(time);
        }
        TFMESSAGE if wanted.tf => {
            let is_static = topic.ends_with("tf_static");
            for t in msgs::decode_tf(&message.data).map_err(cdr)? {
                g.tf.add(t, is_static).map_err(&bad)?;
            }
        }
        ODOMETRY if wants(&wanted.odometry, topic) => {
            let o = msgs::decode_odometry(&message.data).map_err(cdr)?;
            g.odometry.entry(topic.to_owned()).or_default().push(o);
        }
        NAVSATFIX if wants(&wanted.fixes, topic) => {
            let f = msgs::decode_navsatfix(&message.data).map_err(cdr)?;
            let usable = f.status >= 0 && f.lat_deg.is_finite() && f.lon_deg.is_finite();
            let entry = g
                .fixes
                .entry(topic.to_owned())
                .or_insert_with(|| (frame_key(&f.header.frame_id).to_owned(), Vec::new()));
            if usable {
                crate::oxts::check_lat_lon(f.lat_deg, f.lon_deg).map_err(&bad)?;
                if !f.alt_m.is_finite() {
                    return Err(bad(format!("altitude {} is not finite", f.alt_m)));
                }
                entry.1.push(GeodeticFix {
                    time_s: f.header.stamp_s,
                    lat_deg: f.lat_deg,
                    lon_deg: f.lon_deg,
                    alt_m: f.alt_m,
                });
            }
        }
        _ => {}
    }
    Ok(())
}

fn stamp_or_log_time(stamp_s: f64, log_time_ns: u64) -> f64 {
    if stamp_s == 0.0 {
        log_time_ns as f64 * 1e-9
    } else {
        stamp_s
    }
}

/// `frame_from_sensor` through static tf, the identity when they are the same frame.
fn static_to_sensor(
    g: &Gathered,
    frame: &str,
    cloud_frame: &str,
) -> Result<Isometry3<f64>, String> {
    if frame_key(frame) == frame_key(cloud_frame) {
        return Ok(Isometry3::identity());
    }
    g.tf.static_chain(frame, cloud_frame).ok_or_else(|| {
        format!(
            "no static tf chain from `{frame}` to the cloud's frame `{cloud_frame}`; tree: {}",
            g.tf.describe()
        )
    })
}

/// The odometry topic's poses carried to the cloud's frame.
fn odometry_track(g: &Gathered, topic: &str, cloud_frame: &str) -> Result<PoseTrack, String> {
    let Some(samples) = g.odometry.get(topic).filter(|s| !s.is_empty()) else {
        return Err(format!("{topic}: no odometry messages"));
    };
    let child = &samples[0].child;
    if let Some(other) = samples
        .iter()
        .find(|s| frame_key(&s.child) != frame_key(child))
    {
        return Err(format!(
            "{topic}: child_frame_id changes from `{child}` to `{}`",
            other.child
        ));
    }
    // In the order they were logged: a stamp earlier than the one before it is a clock that
    // went back (a replayed or spliced recording), not something to sort away (issue 31).
    if let Some(k) = samples.windows(2).position(|w| w[1].stamp_s < w[0].stamp_s) {
        return Err(format!(
            "{topic}: header stamps run backwards: message {} at {} s after {} s",
            k + 2,
            samples[k + 1].stamp_s,
            samples[k].stamp_s
        ));
    }
    let child_from_sensor = static_to_sensor(g, child, cloud_frame)?;
    let mut sorted: Vec<(f64, Isometry3<f64>)> = samples
        .iter()
        .map(|s| (s.stamp_s, s.parent_from_child * child_from_sensor))
        .collect();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    sorted.dedup_by(|b, a| b.0 == a.0);
    let (times, poses) = sorted.into_iter().unzip();
    PoseTrack::new(times, poses).map_err(|e| format!("{topic}: {e}"))
}

/// The NavSatFix topic's fixes and the static transform to the cloud's frame.
fn fix_track(
    path: &Path,
    g: &Gathered,
    topic: &str,
    cloud_frame: &str,
) -> Result<GeodeticTrack, String> {
    let Some((frame, fixes)) = g.fixes.get(topic).filter(|(_, f)| !f.is_empty()) else {
        return Err(format!(
            "{topic}: no usable fixes (status >= 0, finite position)"
        ));
    };
    let fix_from_sensor = static_to_sensor(g, frame, cloud_frame)?;
    let mut fixes = fixes.clone();
    fixes.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    fixes.dedup_by(|b, a| b.time_s == a.time_s);
    Ok(GeodeticTrack {
        path: path.to_path_buf(),
        topic: topic.to_owned(),
        fixes,
        fix_from_sensor,
    })
}

/// [`PoseSource::Auto`]: tf, then odometry, then NavSatFix, then none.
fn auto_poses(
    path: &Path,
    g: &Gathered,
    topics: &[TopicInfo],
    cloud_frame: &str,
) -> (BagPoses, String) {
    if !g.tf.is_empty() {
        let fixed = g.tf.root_of(cloud_frame);
        if let Ok(track) = g.tf.track(&fixed, cloud_frame) {
            return (
                BagPoses::Local(track),
                format!("tf {fixed} -> {cloud_frame}"),
            );
        }
    }
    let first_of = |schema: &str| {
        topics
            .iter()
            .find(|t| t.schema == schema && t.encoding == "cdr")
    };
    if let Some(t) = first_of(ODOMETRY)
        && let Ok(track) = odometry_track(g, &t.topic, cloud_frame)
    {
        return (BagPoses::Local(track), format!("odometry {}", t.topic));
    }
    if let Some(t) = first_of(NAVSATFIX)
        && let Ok(track) = fix_track(path, g, &t.topic, cloud_frame)
    {
        return (BagPoses::Wgs84(track), format!("navsatfix {}", t.topic));
    }
    (BagPoses::None, "none".to_owned())
}

/// The scans of a [`BagDrive`], read lazily (see [`BagDrive::scans`]).
pub struct BagScans {
    reader: mcap::io::MessageReader<BufReader<File>>,
    path: PathBuf,
    topic: String,
    index: u64,
    seen: u64,
}

impl std::fmt::Debug for BagScans {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BagScans")
            .field("path", &self.path)
            .field("topic", &self.topic)
            .field("index", &self.index)
            .finish_non_exhaustive()
    }
}

impl Iterator for BagScans {
    type Item = Result<BagScan, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        for message in self.reader.by_ref() {
            let message = match message {
                Ok(m) => m,
                Err(e) => return Some(Err(mcap_error(&self.path, self.seen, e))),
            };
            self.seen += 1;
            if message.channel.topic != self.topic {
                continue;
            }
            let index = self.index;
            self.index += 1;
            return Some(
                msgs::decode_pointcloud2(&message.data)
                    .map(|cloud| BagScan {
                        index,
                        time_s: stamp_or_log_time(cloud.header.stamp_s, message.log_time),
                        scan: cloud.scan,
                    })
                    .map_err(|e| BagError::Message {
                        path: self.path.clone(),
                        topic: self.topic.clone(),
                        index,
                        kind: POINTCLOUD2.to_owned(),
                        message: e.0,
                    }),
            );
        }
        None
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn a_fifo_is_refused_without_opening_it() {
        // Issue 31: `mkfifo f.mcap; evigrid bag info f.mcap` hung in the open.
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("f.mcap");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("skipped: mkfifo is not available");
            return;
        }
        let err = reader(&fifo)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert_eq!(err, format!("{}: not a regular file", fifo.display()));
    }

    #[test]
    fn the_record_limit_follows_the_file_size_between_64_mib_and_1_gib() {
        assert_eq!(record_limit(18), 1 << 26);
        assert_eq!(record_limit(1 << 20), 1 << 28);
        assert_eq!(record_limit(1 << 22), 1 << 30);
        assert_eq!(record_limit(u64::MAX), 1 << 30);
    }

    #[test]
    fn a_header_length_beyond_a_small_file_is_refused_before_it_is_read() {
        // Issue 31 (fuzz finding): 18 bytes whose header record claims 808,464,433 bytes made
        // the reader allocate and zero them, 0.4 s and 800 MB, before finding the file short.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("short.mcap");
        let mut bytes = b"\x89MCAP0\r\n\x01".to_vec();
        bytes.extend_from_slice(&808_464_433u64.to_le_bytes());
        bytes.push(0);
        std::fs::write(&path, &bytes).unwrap();
        let err = BagDrive::open(&path, &BagOptions::default())
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(err.contains("exceeds limit"), "{err}");
    }

    #[test]
    fn pose_sources_parse() {
        let p = |t: &str| t.parse::<PoseSource>();
        assert_eq!(p("auto"), Ok(PoseSource::Auto));
        assert_eq!(p("none"), Ok(PoseSource::None));
        assert_eq!(p("tf"), Ok(PoseSource::Tf { fixed_frame: None }));
        assert_eq!(
            p("tf:map"),
            Ok(PoseSource::Tf {
                fixed_frame: Some("map".into())
            })
        );
        assert_eq!(
            p("odom:/odometry/filtered"),
            Ok(PoseSource::Odometry {
                topic: Some("/odometry/filtered".into())
            })
        );
        assert_eq!(p("navsat"), Ok(PoseSource::NavSatFix { topic: None }));
        assert!(p("imu").unwrap_err().contains("tf[:FIXED_FRAME]"));
        assert!(p("none:x").is_err());
    }

    fn topic(name: &str, schema: &str) -> TopicInfo {
        TopicInfo {
            topic: name.into(),
            schema: schema.into(),
            encoding: "cdr".into(),
            count: 3,
            log_time_ns: (0, 1),
        }
    }

    #[test]
    fn topics_are_picked_or_the_choice_is_explained() {
        let path = Path::new("b.mcap");
        let topics = [
            topic("/front/points", POINTCLOUD2),
            topic("/odom", ODOMETRY),
            topic("/rear/points", POINTCLOUD2),
        ];
        let err = pick_topic(path, &topics, None, POINTCLOUD2, "--cloud-topic")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("2 sensor_msgs/msg/PointCloud2 topics; choose --cloud-topic"),
            "{err}"
        );
        assert!(
            err.contains("/rear/points (sensor_msgs/msg/PointCloud2, 3)"),
            "{err}"
        );
        assert_eq!(
            pick_topic(path, &topics, Some("/rear/points"), POINTCLOUD2, "").unwrap(),
            "/rear/points"
        );
        assert_eq!(
            pick_topic(path, &topics, None, ODOMETRY, "").unwrap(),
            "/odom"
        );
        let err = pick_topic(path, &topics, None, NAVSATFIX, "")
            .unwrap_err()
            .to_string();
        assert!(err.contains("no sensor_msgs/msg/NavSatFix topic"), "{err}");
    }
}
