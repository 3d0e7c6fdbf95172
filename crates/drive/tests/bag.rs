//! The ROS 2 MCAP reader on `fixtures/kitti-0013.mcap`, written by an independent writer
//! (`scripts/make_ros2_bag.py`, Python `mcap-ros2-support`) from the shared KITTI raw frames of
//! drive 0013: points against the `.bin` files, poses against the KITTI raw reader's, and
//! malformed recordings derived from the fixture.

#![allow(clippy::unwrap_used)]

use drive::bag::{BagDrive, BagError, BagOptions, BagPoses, PoseSource, list_topics};
use drive::kitti_raw::KittiRawDrive;
use drive::oxts::KittiMercator;
use drive::read_scan;
use nalgebra::Isometry3;
use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What the script wrote (keep in step with `FRAMES` and `STRIDE` there).
const FRAMES: [usize; 4] = [2, 7, 12, 17];
const STRIDE: usize = 32;
const DRIVE: &str = "data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync";

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/kitti-0013.mcap")
}

fn open(pose_source: PoseSource) -> BagDrive {
    BagDrive::open(
        &fixture(),
        &BagOptions {
            cloud_topic: None,
            pose_source,
        },
    )
    .unwrap()
}

fn kitti() -> Option<KittiRawDrive> {
    Some(KittiRawDrive::open(&geodata::testdata::shared_file(DRIVE)?).unwrap())
}

/// The script's odom frame: the devkit's Mercator centred on the drive's first packet.
fn mercator(drive: &KittiRawDrive) -> impl Fn(f64, f64) -> (f64, f64) + use<> {
    let first = drive.oxts()[0];
    let m = KittiMercator::centered(first.lat_deg, first.lon_deg);
    move |lat, lon| m.project(lat, lon)
}

/// Translation (m) and rotation (degrees) between two poses.
fn gap(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    (
        (a.translation.vector - b.translation.vector).norm(),
        a.rotation.angle_to(&b.rotation).to_degrees(),
    )
}

#[test]
fn lists_topics_types_and_counts() {
    let topics = list_topics(&fixture()).unwrap();
    let summary: Vec<(&str, &str, u64)> = topics
        .iter()
        .map(|t| (t.topic.as_str(), t.schema.as_str(), t.count))
        .collect();
    assert_eq!(
        summary,
        [
            ("/gps/fix", "sensor_msgs/msg/NavSatFix", 40),
            ("/odom", "nav_msgs/msg/Odometry", 40),
            ("/tf", "tf2_msgs/msg/TFMessage", 40),
            ("/tf_static", "tf2_msgs/msg/TFMessage", 1),
            ("/velodyne_points", "sensor_msgs/msg/PointCloud2", 4),
        ]
    );
    assert!(topics.iter().all(|t| t.encoding == "cdr"));
    let cloud = &topics[4];
    assert!(cloud.log_time_ns.0 < cloud.log_time_ns.1);
}

#[test]
fn decoded_points_are_the_kitti_points_the_script_wrote() {
    let bag = open(PoseSource::Auto);
    assert_eq!(bag.cloud_topic(), "/velodyne_points");
    assert_eq!(bag.cloud_frame(), "velodyne");
    let Some(kitti) = kitti() else { return };
    let scans: Vec<_> = bag.scans().unwrap().map(Result::unwrap).collect();
    assert_eq!(scans.len(), FRAMES.len());
    for (scan, frame) in scans.iter().zip(FRAMES) {
        // Header stamps are the scans' timestamps.txt, to the nanosecond (f64 keeps ~0.2 µs).
        assert!((scan.time_s - kitti.scan_times()[frame]).abs() < 1e-6);
        let bin = read_scan(&kitti.frames()[frame].scan_path).unwrap();
        let expected: Vec<[f32; 3]> = bin
            .points_in_sensor
            .iter()
            .step_by(STRIDE)
            .copied()
            .collect();
        let intensity: Vec<f32> = bin.intensity.iter().step_by(STRIDE).copied().collect();
        assert_eq!(scan.scan.points_in_sensor, expected, "frame {frame}");
        assert_eq!(scan.scan.intensity, intensity, "frame {frame}");
        assert!(scan.scan.len() > 3000);
    }
    assert_eq!(
        bag.scan_times(),
        scans.iter().map(|s| s.time_s).collect::<Vec<_>>()
    );
}

/// The bag's poses at the scan times against the KITTI raw reader's `world_from_velodyne`.
fn check_local_poses(bag: &BagDrive, max_m: f64, max_deg: f64) {
    let Some(kitti) = kitti() else { return };
    let expected = kitti.world_from_velodyne(&mercator(&kitti)).unwrap();
    let BagPoses::Local(track) = bag.poses() else {
        panic!("{:?}", bag.poses())
    };
    let mut worst = (0.0f64, 0.0f64);
    for (&t, frame) in bag.scan_times().iter().zip(FRAMES) {
        let (dm, ddeg) = gap(&track.at(t).unwrap(), &expected[frame]);
        worst = (worst.0.max(dm), worst.1.max(ddeg));
    }
    eprintln!(
        "{}: worst {:.2e} m, {:.2e}°",
        bag.pose_source(),
        worst.0,
        worst.1
    );
    assert!(worst.0 < max_m && worst.1 < max_deg, "{worst:?}");
}

#[test]
fn tf_poses_are_the_oxts_poses_at_scan_times() {
    let auto = open(PoseSource::Auto);
    assert_eq!(auto.pose_source(), "tf odom -> velodyne");
    check_local_poses(&auto, 1e-3, 0.01);
    let tf = open(PoseSource::Tf {
        fixed_frame: Some("odom".into()),
    });
    assert_eq!(tf.poses(), auto.poses());
    // A fixed frame that is not above the cloud's names the chain it found.
    let err = BagDrive::open(
        &fixture(),
        &BagOptions {
            cloud_topic: None,
            pose_source: PoseSource::Tf {
                fixed_frame: Some("map".into()),
            },
        },
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("velodyne -> base_link -> odom"), "{err}");
}

#[test]
fn odometry_poses_are_the_oxts_poses_at_scan_times() {
    let bag = open(PoseSource::Odometry { topic: None });
    assert_eq!(bag.pose_source(), "odometry /odom");
    check_local_poses(&bag, 1e-3, 0.01);
}

#[test]
fn navsat_positions_are_the_oxts_positions_and_heading_the_course() {
    let bag = open(PoseSource::NavSatFix {
        topic: Some("/gps/fix".into()),
    });
    let Some(kitti) = kitti() else { return };
    let project = mercator(&kitti);
    let track = bag.poses().track(&project).unwrap().unwrap();
    let imu = kitti.world_from_imu(&project).unwrap();
    for (&t, frame) in bag.scan_times().iter().zip(FRAMES) {
        let velo = track.at(t).unwrap();
        // The fix's frame (base_link) is the IMU: take the lever arm back off.
        let base = velo * kitti.velo_from_imu();
        let truth = imu.at(t).unwrap();
        let dz = (base.translation.vector - truth.translation.vector).norm();
        let yaw_bag = base.rotation.euler_angles().2;
        let yaw = truth.rotation.euler_angles().2;
        let dyaw = (yaw_bag - yaw).sin().asin().abs().to_degrees();
        eprintln!("frame {frame}: {dz:.2e} m, course - yaw {dyaw:.2}°");
        // Position: the fix itself, interpolated like the OXTS track.
        assert!(dz < 1e-3, "frame {frame}: {dz}");
        // Heading: the course over ground, within a few degrees of the car's yaw on this
        // straight drive; roll and pitch (zero here) are lost.
        assert!(dyaw < 3.0, "frame {frame}: {dyaw}");
    }
}

#[test]
fn unknown_or_wrong_topics_list_what_the_file_has() {
    let err = BagDrive::open(
        &fixture(),
        &BagOptions {
            cloud_topic: Some("/points_raw".into()),
            pose_source: PoseSource::Auto,
        },
    )
    .unwrap_err();
    assert!(matches!(err, BagError::UnknownTopic { .. }), "{err:?}");
    let text = err.to_string();
    for needle in [
        "kitti-0013.mcap",
        "/points_raw",
        "/velodyne_points (sensor_msgs/msg/PointCloud2, 4)",
        "/odom (nav_msgs/msg/Odometry, 40)",
    ] {
        assert!(text.contains(needle), "{needle} not in {text}");
    }
    let err = BagDrive::open(
        &fixture(),
        &BagOptions {
            cloud_topic: Some("/odom".into()),
            pose_source: PoseSource::None,
        },
    )
    .unwrap_err();
    assert!(matches!(err, BagError::WrongType { .. }), "{err:?}");
    let err = BagDrive::open(
        &fixture(),
        &BagOptions {
            cloud_topic: None,
            pose_source: PoseSource::Odometry {
                topic: Some("/gps/fix".into()),
            },
        },
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("nav_msgs/msg/Odometry"), "{err}");
}

// ---------------------------------------------------------------------------------------------
// Malformed recordings, derived from the fixture.

/// The fixture rewritten with `edit(topic, index on topic, data)` applied to every message
/// (`None` keeps it), chunks compressed with `compression`.
fn rewrite(
    dir: &Path,
    compression: Option<mcap::Compression>,
    edit: impl FnMut(&str, usize, &[u8]) -> Option<Vec<u8>>,
) -> PathBuf {
    rewrite_without(dir, compression, &[], edit)
}

/// As [`rewrite`], leaving out the messages of `dropped` topics.
fn rewrite_without(
    dir: &Path,
    compression: Option<mcap::Compression>,
    dropped: &[&str],
    mut edit: impl FnMut(&str, usize, &[u8]) -> Option<Vec<u8>>,
) -> PathBuf {
    let bytes = std::fs::read(fixture()).unwrap();
    let mut out = mcap::WriteOptions::new()
        .compression(compression)
        .create(std::io::Cursor::new(Vec::new()))
        .unwrap();
    let mut counts = std::collections::HashMap::new();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        if dropped.contains(&message.channel.topic.as_str()) {
            continue;
        }
        let index = counts
            .entry(message.channel.topic.clone())
            .or_insert(0usize);
        let data = edit(&message.channel.topic, *index, &message.data);
        *index += 1;
        let channel = Arc::new(mcap::Channel {
            schema: message.channel.schema.clone(),
            ..(*message.channel).clone()
        });
        out.write(&mcap::Message {
            channel,
            data: data.map_or(message.data.clone(), Cow::Owned),
            ..message
        })
        .unwrap();
    }
    out.finish().unwrap();
    let path = dir.join("edited.mcap");
    std::fs::write(&path, out.into_inner().into_inner()).unwrap();
    path
}

#[test]
fn rewritten_uncompressed_and_lz4_read_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let reference: Vec<_> = open(PoseSource::None)
        .scans()
        .unwrap()
        .map(Result::unwrap)
        .collect();
    for compression in [None, Some(mcap::Compression::Lz4)] {
        let path = rewrite(dir.path(), compression, |_, _, _| None);
        let bag = BagDrive::open(&path, &BagOptions::default()).unwrap();
        let scans: Vec<_> = bag.scans().unwrap().map(Result::unwrap).collect();
        assert_eq!(scans, reference, "{compression:?}");
        assert_eq!(bag.pose_source(), "tf odom -> velodyne");
    }
}

#[test]
fn a_bad_point_step_names_file_topic_and_message() {
    let dir = tempfile::tempdir().unwrap();
    // The third cloud claims 12-byte points: its intensity field (offset 12) no longer fits.
    let path = rewrite(dir.path(), None, |topic, i, data| {
        (topic == "/velodyne_points" && i == 2).then(|| {
            let mut d = data.to_vec();
            let at = point_step_offset(&d);
            d[at..at + 4].copy_from_slice(&12u32.to_le_bytes());
            d
        })
    });
    let bag = BagDrive::open(&path, &BagOptions::default()).unwrap();
    let results: Vec<_> = bag.scans().unwrap().collect();
    assert!(results[0].is_ok() && results[1].is_ok() && results[3].is_ok());
    let err = results[2].as_ref().unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, BagError::Message { index: 2, .. }), "{err:?}");
    assert!(
        text.contains("edited.mcap") && text.contains("/velodyne_points"),
        "{text}"
    );
    assert!(
        text.contains("message #2") && text.contains("point_step 12"),
        "{text}"
    );
}

/// Offset of `point_step` in a PointCloud2 as the script writes it: `point_step` (16),
/// `row_step`, the data's length (equal to `row_step`, height 1), the data, `is_dense`.
fn point_step_offset(d: &[u8]) -> usize {
    let u32_at = |o: usize| u32::from_le_bytes(d[o..o + 4].try_into().unwrap()) as usize;
    (0..d.len() - 12)
        .step_by(4)
        .find(|&o| {
            u32_at(o) == 16 && u32_at(o + 4) == u32_at(o + 8) && o + 13 + u32_at(o + 8) == d.len()
        })
        .expect("point_step not found")
}

#[test]
fn truncated_and_inflated_messages_are_errors_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    // Every message of one topic at once, for each topic, truncated at a few lengths or with
    // a u32 overwritten by a huge count at a few offsets: open (and the scans) must return
    // errors naming the topic, or succeed, but never panic.
    for topic in ["/velodyne_points", "/tf", "/tf_static", "/odom", "/gps/fix"] {
        let mut errors = 0;
        for mutation in 0..12usize {
            let path = rewrite(dir.path(), None, |t, _, data| {
                (t == topic).then(|| {
                    let mut d = data.to_vec();
                    if mutation < 6 {
                        d.truncate(d.len() * mutation / 6);
                    } else {
                        let at = (4 + 4 * (mutation - 6) * 3).min(d.len().saturating_sub(4));
                        d[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
                    }
                    d
                })
            });
            let options = BagOptions {
                cloud_topic: None,
                pose_source: match topic {
                    "/odom" => PoseSource::Odometry { topic: None },
                    "/gps/fix" => PoseSource::NavSatFix { topic: None },
                    _ => PoseSource::Tf { fixed_frame: None },
                },
            };
            match BagDrive::open(&path, &options) {
                Ok(bag) => {
                    for scan in bag.scans().unwrap() {
                        if let Err(e) = scan {
                            errors += 1;
                            assert!(e.to_string().contains(topic), "{topic}: {e}");
                        }
                    }
                }
                Err(e) => {
                    errors += 1;
                    let text = e.to_string();
                    assert!(
                        text.contains(topic) || text.contains("poses:"),
                        "{topic} #{mutation}: {text}"
                    );
                }
            }
        }
        // At least the empty messages fail (later cuts of Odometry and NavSatFix fall in fields
        // the reader skips).
        assert!(errors >= 1, "{topic}: {errors} errors");
    }
}

#[test]
fn a_truncated_file_is_an_error() {
    let bytes = std::fs::read(fixture()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for keep in [0, 7, 100, bytes.len() / 2, bytes.len() - 10] {
        let path = dir.path().join("cut.mcap");
        std::fs::write(&path, &bytes[..keep]).unwrap();
        let err = list_topics(&path).unwrap_err();
        assert!(err.to_string().contains("cut.mcap"), "{err}");
    }
    let err = list_topics(Path::new("/nonexistent/x.mcap")).unwrap_err();
    assert!(matches!(err, BagError::Io { .. }));
}

/// The committed fixture is what the script writes today: regenerate it with the independent
/// writer and compare what the reader gets from both. Skips (with a note) when Python or its
/// `mcap-ros2-support` is not installed; `.ci/run` installs `scripts/requirements.txt`.
#[test]
fn the_script_regenerates_the_fixture() {
    let Some(shared) = geodata::testdata::shared_dir() else {
        return;
    };
    let has_writer = std::process::Command::new("python3")
        .args(["-c", "import mcap_ros2.writer"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_writer {
        eprintln!("note: python3 with mcap-ros2-support not found; skipping the regeneration");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("regenerated.mcap");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/make_ros2_bag.py");
    let run = std::process::Command::new("python3")
        .arg(&script)
        .arg(&out)
        .env("EVIGRID_SHARED", &shared)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let options = BagOptions::default();
    let (new, old) = (
        BagDrive::open(&out, &options).unwrap(),
        BagDrive::open(&fixture(), &options).unwrap(),
    );
    assert_eq!(new.topics(), old.topics());
    assert_eq!(new.poses(), old.poses());
    let scans = |b: &BagDrive| b.scans().unwrap().map(Result::unwrap).collect::<Vec<_>>();
    assert_eq!(scans(&new), scans(&old));
}

#[test]
fn auto_falls_back_from_tf_to_odometry_to_navsat_to_none() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&[&str], &str); 3] = [
        (&["/tf"], "odometry /odom"),
        (&["/tf", "/odom"], "navsatfix /gps/fix"),
        (&["/tf", "/odom", "/gps/fix"], "none"),
    ];
    for (dropped, expected) in cases {
        let path = rewrite_without(dir.path(), None, dropped, |_, _, _| None);
        let bag = BagDrive::open(&path, &BagOptions::default()).unwrap();
        assert_eq!(bag.pose_source(), expected, "without {dropped:?}");
        if expected == "odometry /odom" {
            check_local_poses(&bag, 1e-3, 0.01);
        }
        assert_eq!(bag.scans().unwrap().count(), FRAMES.len());
    }
    // Odometry of base_link cannot place the velodyne's clouds without /tf_static.
    let path = rewrite_without(dir.path(), None, &["/tf_static"], |_, _, _| None);
    let err = BagDrive::open(
        &path,
        &BagOptions {
            cloud_topic: None,
            pose_source: PoseSource::Odometry { topic: None },
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("no static tf chain from `base_link` to the cloud's frame `velodyne`"),
        "{err}"
    );
}

#[test]
fn clouds_that_change_frame_are_refused_at_open() {
    let dir = tempfile::tempdir().unwrap();
    // "velodyne" -> "velodyme" in the second cloud's header (same length, same layout).
    let path = rewrite(dir.path(), None, |topic, i, data| {
        (topic == "/velodyne_points" && i == 1).then(|| {
            let mut d = data.to_vec();
            let at = d.windows(8).position(|w| w == b"velodyne").unwrap();
            d[at + 6] = b'm';
            d
        })
    });
    let err = BagDrive::open(&path, &BagOptions::default()).unwrap_err();
    assert!(matches!(err, BagError::Message { index: 1, .. }), "{err:?}");
    assert!(err.to_string().contains("`velodyme` differs"), "{err}");
}

#[test]
fn odometry_whose_stamps_run_backwards_is_refused() {
    // Issue 31: a recording whose odometry clock went back was sorted into a drive, exit 0.
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(fixture()).unwrap();
    let odom: Vec<Vec<u8>> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(Result::unwrap)
        .filter(|m| m.channel.topic == "/odom")
        .map(|m| m.data.to_vec())
        .collect();
    let path = rewrite(dir.path(), None, |topic, k, _| match (topic, k) {
        ("/odom", 5) => Some(odom[6].clone()),
        ("/odom", 6) => Some(odom[5].clone()),
        _ => None,
    });
    let err = BagDrive::open(
        &path,
        &BagOptions {
            cloud_topic: None,
            pose_source: PoseSource::Odometry { topic: None },
        },
    )
    .err()
    .map(|e| e.to_string())
    .unwrap_or_default();
    assert!(
        err.contains("/odom: header stamps run backwards: message 7"),
        "{err}"
    );
}
