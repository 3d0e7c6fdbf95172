//! The KITTI raw reader on the shared frames of `2011_09_26_drive_0013` (frames 80–119,
//! renumbered from 0), and its errors on partial copies of that layout.

#![allow(clippy::unwrap_used)]

use drive::kitti_raw::{KittiRawDrive, KittiRawError};
use drive::oxts::{KittiMercator, world_from_imu};
use drive::{ReadError, read_scan};
use nalgebra::{Point3, Vector3};
use std::path::{Path, PathBuf};

const DATE: &str = "data/lidar/kitti-raw-0013/2011_09_26";
const DRIVE: &str = "2011_09_26_drive_0013_sync";

fn date_dir() -> Option<PathBuf> {
    geodata::testdata::shared_file(DATE)
}

fn open() -> Option<KittiRawDrive> {
    Some(KittiRawDrive::open(&date_dir()?.join(DRIVE)).unwrap())
}

/// The Mercator of the KITTI devkit, centred on the drive's first packet.
fn mercator(drive: &KittiRawDrive) -> impl Fn(f64, f64) -> (f64, f64) {
    let first = drive.oxts()[0];
    let m = KittiMercator::centered(first.lat_deg, first.lon_deg);
    move |lat, lon| m.project(lat, lon)
}

#[test]
fn opens_the_drive_folder_and_the_date_folder() {
    let Some(drive) = open() else { return };
    assert_eq!(drive.len(), 40);
    let frames = drive.frames();
    assert_eq!(frames.len(), 40);
    for (i, frame) in frames.iter().enumerate() {
        assert_eq!(frame.index, i);
        assert!(
            frame
                .scan_path
                .ends_with(format!("velodyne_points/data/{i:010}.bin"))
        );
        assert!(frame.scan_path.is_file());
        // Karlsruhe.
        assert!((frame.oxts.lat_deg - 49.0).abs() < 0.1 && (frame.oxts.lon_deg - 8.4).abs() < 0.1);
        // Synced data: each scan comes 12–22 ms before its packet.
        let lead = frame.oxts_time_s - frame.time_s;
        assert!((0.005..0.03).contains(&lead), "frame {i}: {lead}");
    }
    // 2011-09-26 13:10:59.442711794, clock read as UTC.
    assert!((frames[0].time_s - 1_317_042_659.442_712).abs() < 1e-5);
    // Scans every ~0.1 s (10 Hz), strictly increasing.
    for w in drive.scan_times().windows(2) {
        let dt = w[1] - w[0];
        assert!((0.095..0.105).contains(&dt), "{dt}");
    }
    // The date folder holds exactly this drive.
    let by_date = KittiRawDrive::open(&date_dir().unwrap()).unwrap();
    assert_eq!(by_date.drive_dir(), drive.drive_dir());
    assert_eq!(by_date.scan_times(), drive.scan_times());
    // The scans themselves read.
    let scan = read_scan(&frames[0].scan_path).unwrap();
    assert!(scan.len() > 100_000, "{}", scan.len());
}

#[test]
fn velodyne_poses_are_oxts_poses_at_scan_times_with_the_lever_arm() {
    let Some(drive) = open() else { return };
    let project = mercator(&drive);
    let imu = drive.world_from_imu(&project).unwrap();
    let velo = drive.world_from_velodyne(&project).unwrap();
    assert_eq!(velo.len(), 40);
    for (i, frame) in drive.frames().iter().enumerate() {
        // The interpolated IMU pose at the scan time sits behind the packet's own pose by the
        // distance driven in the 12–22 ms between them.
        let at_packet = world_from_imu(&frame.oxts, &project).unwrap();
        let at_scan = imu
            .at_extrapolated(frame.time_s, drive::kitti_raw::MAX_EXTRAPOLATION_S)
            .unwrap();
        let gap = (at_packet.translation.vector - at_scan.translation.vector).norm();
        let p = frame.oxts;
        let speed = (p.vn * p.vn + p.ve * p.ve + p.vu * p.vu).sqrt();
        let expected = speed * (frame.oxts_time_s - frame.time_s);
        assert!(
            (gap - expected).abs() < 0.03,
            "frame {i}: {gap} m vs {expected} m"
        );
        // The Velodyne is where the calibration puts it on the IMU.
        let imu_from_velo = at_scan.inverse() * velo[i];
        let arm = imu_from_velo.translation.vector;
        assert!(
            (arm - Vector3::new(0.81, -0.31, 0.80)).norm() < 0.015,
            "{arm}"
        );
        assert!(
            (imu_from_velo
                .rotation
                .angle_to(&drive.imu_from_velo().rotation))
                < 1e-9
        );
    }
}

#[test]
fn consecutive_velodyne_poses_move_at_the_oxts_speed_and_heading() {
    let Some(drive) = open() else { return };
    let velo = drive.world_from_velodyne(&mercator(&drive)).unwrap();
    let speeds: Vec<f64> = drive.oxts().iter().map(|p| p.horizontal_speed()).collect();
    let (lo, hi) = speeds
        .iter()
        .fold((f64::MAX, 0.0f64), |(lo, hi), &s| (lo.min(s), hi.max(s)));
    // The drive is a real car at city speed: the band comes from its own velocities.
    assert!(lo > 1.0 && hi < 30.0, "OXTS speeds {lo}..{hi} m/s");
    let times = drive.scan_times();
    for i in 1..velo.len() {
        let step = velo[i].translation.vector - velo[i - 1].translation.vector;
        let dt = times[i] - times[i - 1];
        let moved = Vector3::new(step.x, step.y, 0.0).norm() / dt;
        // Against the two packets' mean speed: within 3 %.
        let oxts_speed = 0.5 * (speeds[i] + speeds[i - 1]);
        assert!(
            (moved / oxts_speed - 1.0).abs() < 0.03,
            "step {i}: {moved} vs {oxts_speed} m/s"
        );
        assert!(
            moved > 0.95 * lo && moved < 1.05 * hi,
            "step {i}: {moved} m/s"
        );
        // The car moves along its own x axis (the Velodyne's x is forward): within 3°.
        let forward = velo[i].rotation * Vector3::x();
        let along = Vector3::new(forward.x, forward.y, 0.0).normalize();
        let cos = along.dot(&Vector3::new(step.x, step.y, 0.0).normalize());
        assert!(
            cos > 3f64.to_radians().cos(),
            "step {i}: heading off by {}°",
            cos.acos().to_degrees()
        );
    }
}

#[test]
fn map_projection_and_devkit_mercator_agree() {
    let Some(drive) = open() else { return };
    let first = drive.oxts()[0];
    let tm = geodata::TransverseMercator::new(first.lat_deg, first.lon_deg).unwrap();
    let a = drive
        .world_from_velodyne(&|la, lo| tm.forward(la, lo))
        .unwrap();
    let b = drive.world_from_velodyne(&mercator(&drive)).unwrap();
    // Over a few hundred metres around a shared origin, the map's ellipsoidal transverse
    // Mercator and the devkit's scaled spherical Mercator agree to a fraction of a percent.
    for (pa, pb) in a.iter().zip(&b) {
        let (ta, tb) = (pa * Point3::origin(), pb * Point3::origin());
        let dist = ta.coords.xy().norm();
        assert!((ta - tb).norm() < 0.01 * dist.max(1.0), "{ta} vs {tb}");
        assert!(pa.rotation.angle_to(&pb.rotation) < 0.2f64.to_radians());
    }
}

// ---------------------------------------------------------------------------------------------
// Partial layouts

/// Builds the drive's layout under `root` (a date folder `2011_09_26` holding the drive), with
/// the text files copied and the scans linked, leaving out the relative paths in `skip`.
fn build_layout(root: &Path, skip: &[&str]) -> PathBuf {
    let src = date_dir().unwrap();
    let date = root.join("2011_09_26");
    let files = [
        "calib_imu_to_velo.txt".to_string(),
        format!("{DRIVE}/velodyne_points/timestamps.txt"),
        format!("{DRIVE}/oxts/timestamps.txt"),
    ];
    let mut all: Vec<String> = files.to_vec();
    for i in 0..40 {
        all.push(format!("{DRIVE}/velodyne_points/data/{i:010}.bin"));
        all.push(format!("{DRIVE}/oxts/data/{i:010}.txt"));
    }
    for rel in all {
        if skip
            .iter()
            .any(|s| rel.starts_with(&format!("{DRIVE}/{s}")) || rel == *s)
        {
            continue;
        }
        let to = date.join(&rel);
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        let from = src.join(&rel);
        if rel.ends_with(".bin") {
            link(&from, &to);
        } else {
            std::fs::copy(&from, &to).unwrap();
        }
    }
    date
}

#[cfg(unix)]
fn link(from: &Path, to: &Path) {
    std::os::unix::fs::symlink(from, to).unwrap();
}

#[cfg(not(unix))]
fn link(from: &Path, to: &Path) {
    std::fs::copy(from, to).unwrap();
}

fn open_err(path: &Path) -> (KittiRawError, String) {
    let err = KittiRawDrive::open(path).unwrap_err();
    let text = err.to_string();
    (err, text)
}

#[test]
fn a_complete_copy_opens() {
    if date_dir().is_none() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let date = build_layout(tmp.path(), &[]);
    assert_eq!(KittiRawDrive::open(&date).unwrap().len(), 40);
}

#[test]
fn missing_files_are_named_with_the_expected_layout() {
    if date_dir().is_none() {
        return;
    }
    for (skip, missing) in [
        ("calib_imu_to_velo.txt", "calib_imu_to_velo.txt"),
        (
            "velodyne_points/timestamps.txt",
            "velodyne_points/timestamps.txt",
        ),
        ("velodyne_points/data", "velodyne_points/data"),
        ("velodyne_points", "velodyne_points"),
        ("oxts/timestamps.txt", "oxts/timestamps.txt"),
        ("oxts/data", "oxts/data"),
    ] {
        let tmp = tempfile::tempdir().unwrap();
        let date = build_layout(tmp.path(), &[skip]);
        // velodyne_points missing: the drive folder is still recognised by its name.
        let (err, text) = open_err(&date.join(DRIVE));
        assert!(
            matches!(err, KittiRawError::Missing { .. }),
            "{skip}: {text}"
        );
        assert!(
            text.contains(missing) && text.contains("KITTI raw layout"),
            "{skip}: {text}"
        );
        let (_, by_date) = open_err(&date);
        assert!(by_date.contains(missing), "{skip}: {by_date}");
    }
    let (err, _) = open_err(Path::new("/nonexistent/kitti"));
    assert!(matches!(err, KittiRawError::Missing { .. }));
}

#[test]
fn counts_names_and_drives_are_checked() {
    if date_dir().is_none() {
        return;
    }
    // One scan file fewer than the timestamps.
    let tmp = tempfile::tempdir().unwrap();
    let date = build_layout(tmp.path(), &["velodyne_points/data/0000000039.bin"]);
    let (err, text) = open_err(&date);
    assert!(
        matches!(
            err,
            KittiRawError::CountMismatch {
                files: 39,
                times: 40,
                ..
            }
        ),
        "{text}"
    );
    assert!(
        text.contains("velodyne_points/data") && text.contains("timestamps.txt"),
        "{text}"
    );

    // A gap: frame 7 missing, a stray frame 40 in its place.
    let tmp = tempfile::tempdir().unwrap();
    let date = build_layout(tmp.path(), &["velodyne_points/data/0000000007.bin"]);
    let data = date.join(DRIVE).join("velodyne_points/data");
    std::fs::write(data.join("0000000040.bin"), []).unwrap();
    let (err, text) = open_err(&date);
    assert!(
        matches!(err, KittiRawError::UnexpectedName { ref expected, .. } if expected == "0000000007.bin"),
        "{text}"
    );

    // OXTS packets short of the scans, with timestamps to match.
    let tmp = tempfile::tempdir().unwrap();
    let date = build_layout(tmp.path(), &["oxts/data/0000000039.txt"]);
    let ts = date.join(DRIVE).join("oxts/timestamps.txt");
    let text = std::fs::read_to_string(&ts).unwrap();
    let kept: Vec<&str> = text.lines().take(39).collect();
    std::fs::write(&ts, kept.join("\n")).unwrap();
    let (err, text) = open_err(&date);
    assert!(
        matches!(
            err,
            KittiRawError::FrameCount {
                scans: 40,
                packets: 39,
                ..
            }
        ),
        "{text}"
    );

    // A malformed timestamp and a malformed packet name file and line.
    let tmp = tempfile::tempdir().unwrap();
    let date = build_layout(tmp.path(), &[]);
    let ts = date.join(DRIVE).join("velodyne_points/timestamps.txt");
    let text =
        std::fs::read_to_string(&ts)
            .unwrap()
            .replacen("13:10:59.546276717", "13:61:59.5", 1);
    std::fs::write(&ts, text).unwrap();
    let (err, text) = open_err(&date);
    assert!(
        matches!(err, KittiRawError::Read(ReadError::Line { line: 2, .. })),
        "{text}"
    );
    assert!(text.contains("velodyne_points/timestamps.txt:2:"), "{text}");
    let tmp = tempfile::tempdir().unwrap();
    let date = build_layout(tmp.path(), &[]);
    let packet = date.join(DRIVE).join("oxts/data/0000000003.txt");
    std::fs::write(&packet, "49.0 8.4 114\n").unwrap();
    let (_, text) = open_err(&date);
    assert!(
        text.contains("0000000003.txt:1:") && text.contains("found 3"),
        "{text}"
    );

    // Two drives in one date folder; none in an empty folder.
    let tmp = tempfile::tempdir().unwrap();
    let date = build_layout(tmp.path(), &[]);
    std::fs::create_dir_all(date.join("2011_09_26_drive_0001_sync/velodyne_points")).unwrap();
    let (err, text) = open_err(&date);
    assert!(
        matches!(err, KittiRawError::SeveralDrives { ref drives, .. } if drives.len() == 2),
        "{text}"
    );
    assert!(
        text.contains("2011_09_26_drive_0001_sync") && text.contains(DRIVE),
        "{text}"
    );
    let empty = tempfile::tempdir().unwrap();
    let (err, text) = open_err(empty.path());
    assert!(matches!(err, KittiRawError::NoDrive { .. }), "{text}");
}
