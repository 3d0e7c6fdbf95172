//! The run as an MCAP recording that Foxglove opens as it is: one `run.mcap` per run, written
//! frame by frame (memory stays flat over the drive) through [`AtomicFile`].
//!
//! Each channel's schema is named after the `foxglove.*` message it holds, Foxglove's own
//! ([`schemas`]), so Foxglove's panels recognise it. The scan is protobuf (schema encoding
//! `protobuf`, the schema a descriptor set of Foxglove's `.proto` files): its points go in as
//! bytes, where JSON would carry them as base64 text a third larger that zstd compresses slowly
//! and badly (issue 29, `docs/benchmarks.md`). The other channels are JSON with a `jsonschema`
//! schema, which any MCAP reader decodes without a descriptor. Topics (frames: `map` the map's
//! local frame, x east, y north; `sensor` the scanner):
//!
//! | topic | schema | encoding | when |
//! |---|---|---|---|
//! | `/evigrid/decision` | `foxglove.Grid` in `map`, fields [`GRID_FIELDS`] | JSON | the first frame, then every [`GRID_INTERVAL_S`] of drive at most, and the last frame |
//! | `/tf` | `foxglove.FrameTransform` `map` → `sensor` | JSON | every frame |
//! | `/scan` | `foxglove.PointCloud` in `sensor` | protobuf | every frame |
//! | `/map` | `foxglove.SceneUpdate`, buildings and roads as line loops in `map` | JSON | once, first frame |
//! | `/gnss` | `foxglove.LocationFix` | JSON | every frame with a fix (KITTI OXTS) |
//!
//! Log and publish times are the scan's time (a fix: its own time), so Foxglove's timeline is the
//! drive's.
//!
//! The grid is the recording's costly message (betP of every cell, base64): a viewer shows the
//! latest grid at every instant, so writing it at 2 Hz (the scan, pose and fix at every frame)
//! cut the default KITTI run's CPU by about a tenth (`docs/benchmarks.md`). The last frame's grid
//! is always written ([`McapRecorder::finish`]), so the recording ends on the run's final grid.
//! The chunks are zstd at a fast level, [`ZSTD_LEVEL`]: the scans' raw floats barely compress,
//! and compressing them at level 1 was a quarter of the run's instructions.
//!
//! Heights are relative to the ground under the first pose, so that the scene is right in 3-D:
//! the first frame's ground (the sensor's z less its height above the ground,
//! [`McapFrame::sensor_height_m`]) is z = 0 of `map`; `/tf` places the sensor at its height
//! over it, and each frame's grid lies on the ground under the sensor of that frame. A drive's
//! absolute altitude (KITTI's poses carry the GPS altitude, 115 m in Karlsruhe) would otherwise
//! float the scan far above a grid at z = 0. The map's outlines lie at z = 0.

mod messages;
mod protobuf;
pub mod schemas;

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use ::mcap::records::MessageHeader;
use evigrid::{IsometryMatrix3, Label, PerceptionGrid, Window};
use geodata::LocalMap;

pub use messages::{GRID_FIELDS, base64, nanoseconds, occupancy};

use crate::atomic::AtomicFile;
use crate::error::{OutputError, check_len};

/// Topic of the decision grid.
pub const TOPIC_DECISION: &str = "/evigrid/decision";
/// Topic of the sensor's pose.
pub const TOPIC_TF: &str = "/tf";
/// Topic of the scan.
pub const TOPIC_SCAN: &str = "/scan";
/// Topic of the map's outlines.
pub const TOPIC_MAP: &str = "/map";
/// Topic of the GNSS fixes.
pub const TOPIC_GNSS: &str = "/gnss";
/// The map's local frame.
pub const FRAME_MAP: &str = "map";
/// The scanner's frame.
pub const FRAME_SENSOR: &str = "sensor";
/// The GNSS receiver's frame (no transform is published for it: a fix is a WGS84 position).
pub const FRAME_GNSS: &str = "gnss";

/// The zstd level of the recording's chunks: −5, one of zstd's fast levels, which store the
/// literals raw and look for matches at every few bytes only. The scan is most of the bytes
/// (1.9 MB a KITTI frame of raw floats, which no level compresses by more than a fifth); at −5
/// the default KITTI run's recording took 2.6 G instructions fewer than at level 1, 0.3 s of
/// CPU, for a file 17 % larger (72.3 against 61.8 MB for the 40 frames of KITTI 0013,
/// `docs/benchmarks.md`). Compression runs on the writing thread, no pool. Named here, not left
/// to the `mcap` crate's features: built alone this crate would write uncompressed chunks, in
/// the CLI (whose drive reader enables zstd) zstd at level 3.
pub const ZSTD_LEVEL: i32 = -5;

/// The zstd level of a recording that holds every frame's grid (`evigrid demo`,
/// [`McapRecorder::with_grid_interval`] 0): its grids, base64 text, compress about twice as
/// well at level 1 as at [`ZSTD_LEVEL`], which keeps the demo's folder under its 40 MB (35.9 MB
/// at level 1, 46.5 MB at −5).
pub const EVERY_GRID_ZSTD_LEVEL: i32 = 1;

/// The writer's options: zstd at `level` on the writing thread (no pool), no profile.
fn write_options(level: i32) -> ::mcap::WriteOptions {
    // The `mcap` crate takes the level as a `u32` and hands zstd `level as i32`
    // (`ChunkWriter::zstd_encoder` in its `write.rs`), so a negative ("fast") level goes
    // through as its two's complement (tested).
    ::mcap::WriteOptions::new()
        .compression(Some(::mcap::Compression::Zstd))
        .compression_level(level.cast_unsigned())
        .compression_threads(0)
        .profile("")
        .library(concat!("evigrid-output ", env!("CARGO_PKG_VERSION")))
}

/// A GNSS fix, WGS84.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssFix {
    /// Time of the fix, seconds (same clock as the scans).
    pub time_s: f64,
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Altitude, metres.
    pub alt_m: f64,
}

/// What one frame adds to the recording.
#[derive(Clone, Copy, Debug)]
pub struct McapFrame<'a> {
    /// The scan's time, seconds since the epoch (or since the drive's start).
    pub time_s: f64,
    /// The grid's window after the frame.
    pub window: &'a Window,
    /// Decisions after the frame, storage order.
    pub decisions: &'a [Label],
    /// Masses after the frame.
    pub perception: &'a PerceptionGrid,
    /// The scanner's pose in the map frame.
    pub world_from_sensor: &'a IsometryMatrix3,
    /// The scan, sensor frame.
    pub points_in_sensor: &'a [[f32; 3]],
    /// The intensity of each point, or empty when the scan has none (then `/scan` has no
    /// intensity field).
    pub intensity: &'a [f32],
    /// The sensor's height above the ground under it, metres: the grid is drawn this far below
    /// the sensor (`sensor.ground.sensor_height_m`, 1.73 m for KITTI's Velodyne).
    pub sensor_height_m: f64,
    /// The GNSS fix taken with the scan, if any.
    pub fix: Option<GnssFix>,
}

/// The decision grid is written at most once per this much drive time, seconds (2 Hz), plus the
/// first and the last frame's ([`McapRecorder::with_grid_interval`] changes it; 0 writes every
/// frame's).
pub const GRID_INTERVAL_S: f64 = 0.5;

/// The grid after the last frame, for [`McapRecorder::finish`].
#[derive(Clone, Copy, Debug)]
pub struct McapGrid<'a> {
    /// The grid's window.
    pub window: &'a Window,
    /// Decisions, storage order.
    pub decisions: &'a [Label],
    /// Masses.
    pub perception: &'a PerceptionGrid,
}

/// Messages written per topic.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct McapCounts {
    /// Per topic, in topic order.
    pub messages: BTreeMap<String, u64>,
}

struct Channels {
    decision: u16,
    tf: u16,
    scan: u16,
    map: u16,
    gnss: u16,
}

/// The recording being written: [`McapRecorder::create`], one [`McapRecorder::write_frame`] per
/// frame, then [`McapRecorder::finish`]; dropped before `finish`, nothing is left on disk.
pub struct McapRecorder {
    writer: ::mcap::Writer<BufWriter<File>>,
    atomic: AtomicFile,
    path: PathBuf,
    channels: Channels,
    /// Outlines of the map's buildings and roads, sent with the first frame.
    map_outlines: Option<(Vec<Outline>, Vec<Outline>)>,
    counts: McapCounts,
    sequence: u32,
    /// [`GRID_INTERVAL_S`] or the interval chosen, nanoseconds.
    grid_interval_ns: u64,
    /// Time of the last grid written, nanoseconds.
    last_grid_ns: Option<u64>,
    /// Time of the last frame written, nanoseconds.
    last_frame_ns: Option<u64>,
    /// The scan message's buffer, kept from frame to frame (megabytes on a Velodyne).
    scan_buffer: Vec<u8>,
    /// The map-frame z of the ground under the first pose: subtracted from every height.
    ground_z_origin_m: Option<f64>,
    /// The last frame's ground z relative to the origin: where [`McapRecorder::finish`]'s grid lies.
    last_ground_z_m: f64,
}

impl std::fmt::Debug for McapRecorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapRecorder")
            .field("path", &self.path)
            .field("counts", &self.counts)
            .finish_non_exhaustive()
    }
}

/// `seconds` as whole nanoseconds, 0 for a negative or NaN value.
fn seconds_to_ns(seconds: f64) -> u64 {
    // `as` saturates: a huge interval writes the first and the last grid only.
    (seconds * 1e9).round() as u64
}

/// A closed outline, local metres.
type Outline = Vec<[f64; 2]>;

/// Exterior rings of polygons as closed outlines (the repeated last point dropped: LINE_LOOP
/// closes them).
fn outlines(polygons: &[geo::Polygon<f64>]) -> Vec<Outline> {
    polygons
        .iter()
        .map(|p| {
            let mut ring: Vec<[f64; 2]> = p.exterior().coords().map(|c| [c.x, c.y]).collect();
            if ring.len() > 1 && ring.first() == ring.last() {
                ring.pop();
            }
            ring
        })
        .filter(|ring| ring.len() >= 2)
        .collect()
}

impl McapRecorder {
    /// Starts the recording at `path` (the file appears on [`finish`](Self::finish)). With a
    /// map, its buildings and roads go out once, with the first frame.
    ///
    /// # Errors
    ///
    /// [`OutputError::Io`] or [`OutputError::Mcap`] naming `path`.
    pub fn create(path: &Path, map: Option<&LocalMap>) -> Result<Self, OutputError> {
        Self::create_with_zstd_level(path, map, ZSTD_LEVEL)
    }

    /// [`create`](Self::create) with the chunks compressed at zstd `level` instead of
    /// [`ZSTD_LEVEL`] (negative: zstd's fast levels; 0: zstd's default, 3), such as
    /// [`EVERY_GRID_ZSTD_LEVEL`] for a recording of every frame's grid.
    ///
    /// # Errors
    ///
    /// [`OutputError::Io`] or [`OutputError::Mcap`] naming `path`.
    pub fn create_with_zstd_level(
        path: &Path,
        map: Option<&LocalMap>,
        level: i32,
    ) -> Result<Self, OutputError> {
        let (atomic, file) = AtomicFile::create(path)?;
        let mcap_error = |source| OutputError::Mcap {
            path: path.to_path_buf(),
            source,
        };
        let mut writer = write_options(level)
            .create(BufWriter::new(file))
            .map_err(mcap_error)?;
        let json = (schemas::SCHEMA_ENCODING, schemas::MESSAGE_ENCODING);
        let protobuf = (
            schemas::PROTOBUF_SCHEMA_ENCODING,
            schemas::PROTOBUF_MESSAGE_ENCODING,
        );
        let mut channel = |topic: &str, name: &str, encodings: (&str, &str), schema: &[u8]| {
            let (schema_encoding, message_encoding) = encodings;
            let schema_id = writer.add_schema(name, schema_encoding, schema)?;
            writer.add_channel(schema_id, topic, message_encoding, &BTreeMap::new())
        };
        let channels = (|| {
            Ok::<_, ::mcap::McapError>(Channels {
                decision: channel(
                    TOPIC_DECISION,
                    "foxglove.Grid",
                    json,
                    schemas::GRID.as_bytes(),
                )?,
                tf: channel(
                    TOPIC_TF,
                    "foxglove.FrameTransform",
                    json,
                    schemas::FRAME_TRANSFORM.as_bytes(),
                )?,
                scan: channel(
                    TOPIC_SCAN,
                    "foxglove.PointCloud",
                    protobuf,
                    schemas::POINT_CLOUD_DESCRIPTORS,
                )?,
                map: channel(
                    TOPIC_MAP,
                    "foxglove.SceneUpdate",
                    json,
                    schemas::SCENE_UPDATE.as_bytes(),
                )?,
                gnss: channel(
                    TOPIC_GNSS,
                    "foxglove.LocationFix",
                    json,
                    schemas::LOCATION_FIX.as_bytes(),
                )?,
            })
        })()
        .map_err(mcap_error)?;
        Ok(Self {
            writer,
            atomic,
            path: path.to_path_buf(),
            channels,
            map_outlines: map.map(|m| (outlines(&m.buildings), outlines(&m.roads))),
            counts: McapCounts::default(),
            sequence: 0,
            grid_interval_ns: seconds_to_ns(GRID_INTERVAL_S),
            last_grid_ns: None,
            last_frame_ns: None,
            scan_buffer: Vec::new(),
            ground_z_origin_m: None,
            last_ground_z_m: 0.0,
        })
    }

    /// Writes the decision grid at most once per `interval_s` of drive time (seconds; 0 or less:
    /// every frame), instead of [`GRID_INTERVAL_S`].
    #[must_use]
    pub fn with_grid_interval(mut self, interval_s: f64) -> Self {
        self.grid_interval_ns = seconds_to_ns(interval_s);
        self
    }

    /// The grid message of `grid` at `ns`, sent.
    fn send_grid(&mut self, ns: u64, grid: &McapGrid<'_>) -> Result<(), OutputError> {
        check_len("decisions", grid.decisions.len(), grid.window)?;
        check_len("perception grid", grid.perception.len(), grid.window)?;
        let message = messages::grid(
            ns,
            FRAME_MAP,
            grid.window,
            grid.decisions,
            grid.perception,
            self.last_ground_z_m,
        );
        self.send(
            self.channels.decision,
            TOPIC_DECISION,
            ns,
            message.to_json().as_bytes(),
        )?;
        self.last_grid_ns = Some(ns);
        Ok(())
    }

    fn send(&mut self, channel: u16, topic: &str, ns: u64, data: &[u8]) -> Result<(), OutputError> {
        self.sequence = self.sequence.wrapping_add(1);
        let header = MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time: ns,
            publish_time: ns,
        };
        self.writer
            .write_to_known_channel(&header, data)
            .map_err(|source| OutputError::Mcap {
                path: self.path.clone(),
                source,
            })?;
        *self.counts.messages.entry(topic.to_string()).or_default() += 1;
        Ok(())
    }

    /// Appends one frame: grid, pose, scan, the fix if any, and the map with the first frame.
    ///
    /// # Errors
    ///
    /// [`OutputError::Size`] if the decisions or the grid do not have the window's size,
    /// [`OutputError::Time`] if a time is negative or not finite, [`OutputError::Mcap`] if
    /// writing fails.
    pub fn write_frame(&mut self, frame: &McapFrame<'_>) -> Result<(), OutputError> {
        check_len("decisions", frame.decisions.len(), frame.window)?;
        check_len("perception grid", frame.perception.len(), frame.window)?;
        let time = |time_s: f64| {
            nanoseconds(time_s).ok_or_else(|| OutputError::Time {
                path: self.path.clone(),
                time_s,
            })
        };
        let ns = time(frame.time_s)?;
        let fix_ns = frame.fix.map(|f| time(f.time_s)).transpose()?;
        if let Some((buildings, roads)) = self.map_outlines.take() {
            let update = serde_json::json!({
                "deletions": [],
                "entities": [
                    messages::outline_entity(ns, FRAME_MAP, "buildings", &buildings,
                        [0.55, 0.55, 0.6, 1.0]),
                    messages::outline_entity(ns, FRAME_MAP, "roads", &roads,
                        [0.95, 0.75, 0.2, 1.0]),
                ],
            });
            self.send(
                self.channels.map,
                TOPIC_MAP,
                ns,
                update.to_string().as_bytes(),
            )?;
        }
        // Heights relative to the first pose's ground (module docs).
        let mut world_from_sensor = *frame.world_from_sensor;
        let ground_z_m = world_from_sensor.translation.z - frame.sensor_height_m;
        let origin_m = *self.ground_z_origin_m.get_or_insert(ground_z_m);
        world_from_sensor.translation.z -= origin_m;
        self.last_ground_z_m = ground_z_m - origin_m;
        let tf = messages::frame_transform(ns, FRAME_MAP, FRAME_SENSOR, &world_from_sensor);
        self.send(self.channels.tf, TOPIC_TF, ns, tf.to_string().as_bytes())?;
        let grid_due = self
            .last_grid_ns
            .is_none_or(|last| ns >= last.saturating_add(self.grid_interval_ns));
        if grid_due {
            let grid = McapGrid {
                window: frame.window,
                decisions: frame.decisions,
                perception: frame.perception,
            };
            self.send_grid(ns, &grid)?;
        }
        self.last_frame_ns = Some(ns);
        let mut scan = std::mem::take(&mut self.scan_buffer);
        protobuf::point_cloud(
            &mut scan,
            ns,
            FRAME_SENSOR,
            frame.points_in_sensor,
            frame.intensity,
        );
        let sent = self.send(self.channels.scan, TOPIC_SCAN, ns, &scan);
        self.scan_buffer = scan;
        sent?;
        if let (Some(fix), Some(fix_ns)) = (frame.fix, fix_ns) {
            let message = messages::location_fix(fix_ns, FRAME_GNSS, &fix);
            self.send(
                self.channels.gnss,
                TOPIC_GNSS,
                fix_ns,
                message.to_string().as_bytes(),
            )?;
        }
        Ok(())
    }

    /// Writes `last`, the grid after the last frame written, if the interval skipped that
    /// frame's grid (give `None` only when every frame's grid was written: an interval of 0);
    /// then the summary and index, and moves the recording into place.
    ///
    /// # Errors
    ///
    /// [`OutputError::Size`] if `last` does not have its window's size, [`OutputError::Mcap`]
    /// or [`OutputError::Io`] naming the file.
    pub fn finish(mut self, last: Option<&McapGrid<'_>>) -> Result<McapCounts, OutputError> {
        if let (Some(ns), Some(grid)) = (self.last_frame_ns, last)
            && self.last_grid_ns != Some(ns)
        {
            self.send_grid(ns, grid)?;
        }
        let mcap_error = |source| OutputError::Mcap {
            path: self.path.clone(),
            source,
        };
        self.writer.finish().map_err(mcap_error)?;
        let file = self
            .writer
            .into_inner()
            .into_inner()
            .map_err(|e| OutputError::Io {
                path: self.path.clone(),
                source: e.into_error(),
            })?;
        self.atomic.commit(file)?;
        Ok(self.counts)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::testing::{decisions, window};
    use geo::{coord, polygon};

    #[test]
    fn a_recording_holds_every_topic_and_decodes() {
        let w = window();
        let d = decisions(&w, |col, _| if col == 10 { Label::F } else { Label::S });
        let pg = PerceptionGrid::new(w.width(), w.height());
        let house =
            polygon![(x: 0.0, y: 0.0), (x: 4.0, y: 0.0), (x: 4.0, y: 3.0), (x: 0.0, y: 0.0)];
        let extent = geo::Rect::new(coord! { x: -9.0, y: -9.0 }, coord! { x: 9.0, y: 9.0 });
        let map = LocalMap::new(vec![house], vec![], extent);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.mcap");
        let mut recorder = McapRecorder::create(&path, Some(&map)).unwrap();
        let pose = IsometryMatrix3::identity();
        for k in 0..3 {
            recorder
                .write_frame(&McapFrame {
                    time_s: 100.0 + 0.1 * k as f64,
                    window: &w,
                    decisions: &d,
                    perception: &pg,
                    world_from_sensor: &pose,
                    points_in_sensor: &[[1.0, 2.0, 3.0], [f32::NAN, 0.0, 0.0]],
                    intensity: &[],
                    sensor_height_m: 1.73,
                    fix: (k == 1).then_some(GnssFix {
                        time_s: 100.1,
                        lat_deg: 60.0,
                        lon_deg: 25.0,
                        alt_m: 5.0,
                    }),
                })
                .unwrap();
        }
        assert!(!path.exists(), "the file appears on finish only");
        let last = McapGrid {
            window: &w,
            decisions: &d,
            perception: &pg,
        };
        let counts = recorder.finish(Some(&last)).unwrap();
        // The first frame's grid, then none for 0.5 s, and the last frame's from `finish`.
        assert_eq!(counts.messages[TOPIC_DECISION], 2);
        assert_eq!(counts.messages[TOPIC_TF], 3);
        assert_eq!(counts.messages[TOPIC_MAP], 1);
        assert_eq!(counts.messages[TOPIC_GNSS], 1);
        let bytes = std::fs::read(&path).unwrap();
        let mut per_topic: BTreeMap<String, u64> = BTreeMap::new();
        let mut times = Vec::new();
        for message in ::mcap::MessageStream::new(&bytes).unwrap() {
            let message = message.unwrap();
            *per_topic.entry(message.channel.topic.clone()).or_default() += 1;
            let schema = message.channel.schema.as_ref().unwrap();
            if message.channel.topic == TOPIC_SCAN {
                assert_eq!(schema.encoding, "protobuf");
                assert_eq!(message.channel.message_encoding, "protobuf");
                assert_eq!(&schema.data[..], schemas::POINT_CLOUD_DESCRIPTORS);
                // The NaN point is left out: 12 bytes of data (field 6).
                let fields = protobuf::decode::fields(&message.data);
                assert_eq!(protobuf::decode::len(&fields, 6).len(), 12);
                continue;
            }
            assert_eq!(schema.encoding, "jsonschema");
            assert_eq!(message.channel.message_encoding, "json");
            let value: serde_json::Value = serde_json::from_slice(&message.data).unwrap();
            if message.channel.topic == TOPIC_DECISION {
                times.push(message.log_time);
                assert_eq!(value["column_count"], 3);
                assert_eq!(value["cell_stride"], 11);
                // First cell (10, -1): F, occupancy 0; second: S, 100.
                let data = value["data"].as_str().unwrap();
                assert!(data.starts_with(&base64(&[1, 0])[..2]), "{data}");
            }
        }
        assert_eq!(per_topic, counts.messages);
        assert_eq!(times, [100_000_000_000, 100_200_000_000]);
        // Chunks are zstd whatever the features the rest of a build gives the `mcap` crate.
        let summary = ::mcap::Summary::read(&bytes).unwrap().unwrap();
        assert!(!summary.chunk_indexes.is_empty());
        assert!(
            summary
                .chunk_indexes
                .iter()
                .all(|chunk| chunk.compression == "zstd")
        );
    }

    /// Decision-grid times in a recording of frames at `times_s` with grid interval
    /// `interval_s`, finished with the last frame's grid.
    fn grid_times(times_s: &[f64], interval_s: f64) -> Vec<u64> {
        let w = window();
        let d = decisions(&w, |_, _| Label::F);
        let pg = PerceptionGrid::new(w.width(), w.height());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.mcap");
        let mut recorder = McapRecorder::create(&path, None)
            .unwrap()
            .with_grid_interval(interval_s);
        for &time_s in times_s {
            let frame = McapFrame {
                time_s,
                window: &w,
                decisions: &d,
                perception: &pg,
                world_from_sensor: &IsometryMatrix3::identity(),
                points_in_sensor: &[],
                intensity: &[],
                sensor_height_m: 0.0,
                fix: None,
            };
            recorder.write_frame(&frame).unwrap();
        }
        let last = McapGrid {
            window: &w,
            decisions: &d,
            perception: &pg,
        };
        recorder.finish(Some(&last)).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        ::mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap())
            .filter(|m| m.channel.topic == TOPIC_DECISION)
            .map(|m| m.log_time / 100_000_000)
            .collect()
    }

    #[test]
    fn the_grid_is_written_at_its_interval_and_on_the_last_frame() {
        // Frames every 0.1 s (times in tenths of a second below).
        let times: Vec<f64> = (0..12).map(|k| 10.0 + 0.1 * f64::from(k)).collect();
        // 0.5 s: the first frame, then each frame at least 0.5 s after the last grid, and the
        // last frame's from `finish`.
        assert_eq!(grid_times(&times, 0.5), [100, 105, 110, 111]);
        // The last frame's grid already due is not written twice.
        assert_eq!(grid_times(&times[..11], 0.5), [100, 105, 110]);
        // 0: every frame's, once each.
        assert_eq!(grid_times(&times, 0.0), (100..112).collect::<Vec<u64>>());
        // One frame: its grid, once.
        assert_eq!(grid_times(&times[..1], 0.5), [100]);
    }

    /// The messages of `topic` in a recording, decoded.
    fn messages_of(bytes: &[u8], topic: &str) -> Vec<serde_json::Value> {
        ::mcap::MessageStream::new(bytes)
            .unwrap()
            .map(|m| m.unwrap())
            .filter(|m| m.channel.topic == topic)
            .map(|m| serde_json::from_slice(&m.data).unwrap())
            .collect()
    }

    #[test]
    fn the_grid_lies_on_the_ground_under_the_sensor_and_scans_keep_their_intensity() {
        // A KITTI-like pose: the sensor at the GPS altitude, 115.5 m, then 0.5 m higher. With
        // 1.73 m above the ground, the first frame's ground (113.77 m) becomes z = 0: the sensor
        // at 1.73 then 2.23 m, each frame's grid at 0 then 0.5 m, under the sensor.
        let w = window();
        let d = decisions(&w, |_, _| Label::F);
        let pg = PerceptionGrid::new(w.width(), w.height());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.mcap");
        let mut recorder = McapRecorder::create(&path, None).unwrap();
        for (k, z) in [115.5, 116.0].into_iter().enumerate() {
            let pose = IsometryMatrix3::translation(3.0, 4.0, z);
            recorder
                .write_frame(&McapFrame {
                    time_s: 1.0 + k as f64,
                    window: &w,
                    decisions: &d,
                    perception: &pg,
                    world_from_sensor: &pose,
                    points_in_sensor: &[[1.0, 2.0, 3.0], [f32::NAN, 0.0, 0.0], [4.0, 5.0, 6.0]],
                    intensity: &[0.25, 0.5, 0.75],
                    sensor_height_m: 1.73,
                    fix: None,
                })
                .unwrap();
        }
        recorder.finish(None).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let tf = messages_of(&bytes, TOPIC_TF);
        let grids = messages_of(&bytes, TOPIC_DECISION);
        for (k, (sensor_z, grid_z)) in [(1.73, 0.0), (2.23, 0.5)].into_iter().enumerate() {
            let tf_z = tf[k]["translation"]["z"].as_f64().unwrap();
            let pose_z = grids[k]["pose"]["position"]["z"].as_f64().unwrap();
            assert!((tf_z - sensor_z).abs() < 1e-9, "frame {k}: {tf_z}");
            assert!((pose_z - grid_z).abs() < 1e-9, "frame {k}: {pose_z}");
            assert_eq!(tf[k]["translation"]["x"], 3.0);
        }
        // Two finite points of x, y, z, intensity: 32 bytes, the NaN point and its intensity
        // left out; the second point's intensity is 0.75. PointCloud's fields: 4 point_stride
        // (fixed32), 5 fields (PackedElementField: 1 name), 6 data.
        let scans: Vec<Vec<u8>> = ::mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap())
            .filter(|m| m.channel.topic == TOPIC_SCAN)
            .map(|m| m.data.into_owned())
            .collect();
        assert_eq!(scans.len(), 2);
        let scan = protobuf::decode::fields(&scans[0]);
        assert_eq!(
            protobuf::decode::all(&scan, 4),
            [protobuf::decode::Value::I32(16u32.to_le_bytes())]
        );
        let names: Vec<&[u8]> = protobuf::decode::all(&scan, 5)
            .into_iter()
            .map(|field| match field {
                protobuf::decode::Value::Len(bytes) => {
                    protobuf::decode::len(&protobuf::decode::fields(bytes), 1)
                }
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(names, [&b"x"[..], b"y", b"z", b"intensity"]);
        let mut expected = Vec::new();
        for v in [1.0f32, 2.0, 3.0, 0.25, 4.0, 5.0, 6.0, 0.75] {
            expected.extend_from_slice(&v.to_le_bytes());
        }
        assert_eq!(protobuf::decode::len(&scan, 6), expected);
    }

    /// The size of a recording of one message of `data`, chunks compressed at zstd `level`.
    fn recorded_size(level: i32, data: &[u8]) -> usize {
        let mut writer = write_options(level)
            .create(std::io::Cursor::new(Vec::new()))
            .unwrap();
        let schema = writer.add_schema("bytes", "", &[]).unwrap();
        let channel = writer
            .add_channel(schema, "/bytes", "", &BTreeMap::new())
            .unwrap();
        let header = MessageHeader {
            channel_id: channel,
            sequence: 0,
            log_time: 0,
            publish_time: 0,
        };
        writer.write_to_known_channel(&header, data).unwrap();
        writer.finish().unwrap();
        writer.into_inner().into_inner().len()
    }

    #[test]
    fn a_negative_zstd_level_reaches_zstd_as_a_fast_level() {
        // 256 kB of 16 symbols in no order (a linear congruential sequence): no repeats to
        // match, half a byte of entropy a byte. Levels from 1 up code the literals with
        // Huffman, about 2:1; zstd's negative levels store them raw. Were the `mcap` crate to
        // read -5 as a huge positive level, zstd would take its strongest, 22: smaller still.
        let mut state = 12_345u32;
        let data: Vec<u8> = (0..262_144)
            .map(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                b'a' + (state >> 28) as u8
            })
            .collect();
        let (level_1, fast) = (recorded_size(1, &data), recorded_size(-5, &data));
        assert!(level_1 < 150_000, "{level_1}");
        assert!(fast > 250_000, "{fast}");
    }

    #[test]
    fn a_negative_time_is_refused_and_leaves_no_file() {
        let w = window();
        let d = decisions(&w, |_, _| Label::Unknown);
        let pg = PerceptionGrid::new(w.width(), w.height());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.mcap");
        let mut recorder = McapRecorder::create(&path, None).unwrap();
        let error = recorder
            .write_frame(&McapFrame {
                time_s: -1.0,
                window: &w,
                decisions: &d,
                perception: &pg,
                world_from_sensor: &IsometryMatrix3::identity(),
                points_in_sensor: &[],
                intensity: &[],
                sensor_height_m: 0.0,
                fix: None,
            })
            .unwrap_err();
        assert!(matches!(error, OutputError::Time { .. }), "{error}");
        drop(recorder);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
