#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use super::*;

const DATE: &str = "data/lidar/kitti-raw-0013/2011_09_26";
const CITY: &str = "data/lidar/kitti-city-22";

fn fixture_bag() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/kitti-0013.mcap")
}

/// A local frame for the shared drive: a flat-earth projection about its first fix (metres per
/// degree at the equator scaled by cos(lat)), enough to place the drive a few hundred metres.
fn flat(origin: (f64, f64)) -> impl Fn(f64, f64) -> (f64, f64) {
    let m_per_deg = 111_320.0;
    move |lat, lon| {
        (
            (lon - origin.1) * m_per_deg * origin.0.to_radians().cos(),
            (lat - origin.0) * m_per_deg,
        )
    }
}

/// Links the first `n` shared city scans into `dir`.
fn link_city_scans(dir: &Path, n: usize) -> Option<()> {
    let source = geodata::testdata::shared_file(CITY)?;
    let mut names: Vec<_> = std::fs::read_dir(&source)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    names.sort();
    std::fs::create_dir_all(dir).unwrap();
    for p in names.into_iter().take(n) {
        std::os::unix::fs::symlink(&p, dir.join(p.file_name().unwrap())).unwrap();
    }
    Some(())
}

#[test]
fn a_kitti_raw_drive_is_placed_by_its_oxts_at_the_first_fix() {
    let Some(dir) = geodata::testdata::shared_file(DATE) else {
        return;
    };
    let drive = Drive::open(&DriveSpec::KittiRaw {
        dir: dir.clone(),
        poses: None,
    })
    .unwrap();
    assert_eq!(drive.len(), 40);
    assert!(matches!(drive.pose_origin(), PoseOrigin::Oxts { .. }));
    assert_eq!(drive.pose_origin().matching(), PoseMatching::Time);
    let fix = drive.first_fix().unwrap();
    // Without a projection the OXTS packets cannot be placed.
    assert!(matches!(
        drive.place(None, usize::MAX),
        Err(SourceError::NeedsProjection { .. })
    ));
    let projection = flat(fix);
    let poses = drive.place(Some(&projection), usize::MAX).unwrap();
    assert_eq!(poses.len(), 40);
    // The first scan is within a few metres of the first fix (the lever arm, and the scan's
    // time a few ms after the packet's), the drive moves on from there.
    let first = poses.world_from_sensor[0].translation;
    assert!(first.x.hypot(first.y) < 3.0, "{first:?}");
    let last = poses.world_from_sensor[39].translation;
    assert!(last.x.hypot(last.y) > 10.0, "{last:?}");
    let frames: Vec<_> = drive.frames(&poses).unwrap().collect();
    assert_eq!(frames.len(), 40);
    let frame = frames[3].as_ref().unwrap();
    assert_eq!(frame.index, 3);
    assert_eq!(frame.name, "0000000003.bin");
    assert_eq!(frame.time_s, drive.times().unwrap()[3]);
    assert_eq!(frame.world_from_sensor, poses.world_from_sensor[3]);
    assert!(frame.points_in_sensor.len() > 100_000);
    assert_eq!(frame.intensity.len(), frame.points_in_sensor.len());
    assert!(frame.fix.is_some());
}

#[test]
fn a_scan_folder_without_times_takes_pose_line_k_for_scan_k() {
    let tmp = tempfile::tempdir().unwrap();
    let scans = tmp.path().join("scans");
    if link_city_scans(&scans, 3).is_none() {
        return;
    }
    let poses = tmp.path().join("poses.txt");
    std::fs::write(
        &poses,
        "# t x y z roll pitch yaw\n5.0 1 2 3 0 0 0\n5.5 4 2 3 0 0 0\n6.0 7 2 3 0 0 0\n",
    )
    .unwrap();
    let file = PoseFileSpec {
        path: poses.clone(),
        format: None,
        calib: None,
        mounting: None,
    };
    let drive = Drive::open(&DriveSpec::ScanFolder {
        dir: scans.clone(),
        times: None,
        poses: Some(file.clone()),
    })
    .unwrap();
    assert_eq!(
        drive.pose_origin(),
        PoseOrigin::File {
            path: poses.clone(),
            matching: PoseMatching::LineOrder
        }
    );
    assert_eq!(drive.times_or_period(), vec![0.0, 0.1, 0.2]);
    let placed = drive.place(None, usize::MAX).unwrap();
    // The lines' times and positions, one for one.
    assert_eq!(placed.times, vec![5.0, 5.5, 6.0]);
    assert_eq!(placed.positions(), vec![[1.0, 2.0], [4.0, 2.0], [7.0, 2.0]]);
    assert_eq!(placed.origin.to_string(), poses.display().to_string());

    // Two lines for three scans: refused, naming the file and the counts.
    std::fs::write(&poses, "0 0 0 0 0 0 0\n1 1 0 0 0 0 0\n").unwrap();
    let error = drive.place(None, usize::MAX).unwrap_err().to_string();
    assert!(
        error.contains("poses.txt") && error.contains("2 poses for 3 scans"),
        "{error}"
    );
}

#[test]
fn a_scan_folder_with_times_interpolates_the_pose_at_each_scan_time() {
    let tmp = tempfile::tempdir().unwrap();
    let scans = tmp.path().join("scans");
    if link_city_scans(&scans, 2).is_none() {
        return;
    }
    std::fs::write(scans.join("times.txt"), "0.25\n0.5\n").unwrap();
    let poses = tmp.path().join("poses.txt");
    // 0 → 1 s: x from 0 to 10 m, so 2.5 m at 0.25 s and 5 m at 0.5 s.
    std::fs::write(&poses, "0 0 0 0 0 0 0\n1 10 0 0 0 0 0\n").unwrap();
    let drive = Drive::open(&DriveSpec::ScanFolder {
        dir: scans,
        times: None,
        poses: Some(PoseFileSpec {
            path: poses,
            format: None,
            calib: None,
            mounting: None,
        }),
    })
    .unwrap();
    assert_eq!(drive.pose_origin().matching(), PoseMatching::Time);
    let placed = drive.place(None, usize::MAX).unwrap();
    assert_eq!(placed.times, vec![0.25, 0.5]);
    let x: Vec<f64> = placed.positions().iter().map(|p| p[0]).collect();
    assert!(
        (x[0] - 2.5).abs() < 1e-12 && (x[1] - 5.0).abs() < 1e-12,
        "{x:?}"
    );
}

#[test]
fn a_scan_folder_without_poses_is_placed_by_the_caller() {
    let tmp = tempfile::tempdir().unwrap();
    let scans = tmp.path().join("scans");
    if link_city_scans(&scans, 3).is_none() {
        return;
    }
    let mut drive = Drive::open(&DriveSpec::ScanFolder {
        dir: scans,
        times: None,
        poses: None,
    })
    .unwrap();
    assert_eq!(drive.pose_origin(), PoseOrigin::Odometry);
    assert!(matches!(
        drive.place(None, usize::MAX),
        Err(SourceError::NoPoses(_))
    ));
    // A pass reads the scans in order with their times 0.1 s apart…
    let read: Vec<_> = drive.scans().unwrap().map(Result::unwrap).collect();
    assert_eq!(read.len(), 3);
    assert_eq!(read[2].time_s, 0.2);
    assert_eq!(read[2].name, "0000000002.pcd");
    // …and leaves one out: the frames are those kept, with the caller's poses.
    drive.keep(&[0, 2]);
    let poses = drive.place_with(
        vec![0.0, 0.2],
        vec![Isometry3::identity(), Isometry3::translation(1.0, 0.0, 0.0)],
    );
    let frames: Vec<_> = drive.frames(&poses).unwrap().map(Result::unwrap).collect();
    assert_eq!(frames.len(), 2);
    assert_eq!(frames[1].name, "0000000002.pcd");
    assert_eq!(frames[1].world_from_sensor.translation.x, 1.0);
    assert_eq!(poses.origin.to_string(), "lidar odometry");
}

#[test]
fn a_recording_is_placed_by_its_own_poses() {
    let drive = Drive::open(&DriveSpec::Bag {
        path: fixture_bag(),
        cloud_topic: None,
        pose_source: PoseSource::Auto,
    })
    .unwrap();
    assert_eq!(drive.len(), 4);
    assert!(drive.is_recording());
    let origin = drive.pose_origin();
    assert!(matches!(origin, PoseOrigin::Bag { .. }), "{origin:?}");
    assert!(origin.to_string().ends_with("kitti-0013.mcap"));
    // Only the first two must be placed: two are.
    let poses = drive.place(None, 2).unwrap();
    assert_eq!(poses.len(), 2);
    let frames: Vec<_> = drive.frames(&poses).unwrap().map(Result::unwrap).collect();
    assert_eq!(frames.len(), 2);
    assert_eq!(frames[1].name, "kitti-0013.mcap#000001");
    assert_eq!(frames[1].time_s, drive.times().unwrap()[1]);
    assert!(!frames[1].points_in_sensor.is_empty());
}

#[test]
fn a_recording_placed_by_navsatfix_needs_a_projection() {
    let drive = Drive::open(&DriveSpec::Bag {
        path: fixture_bag(),
        cloud_topic: None,
        pose_source: PoseSource::NavSatFix { topic: None },
    })
    .unwrap();
    let error = drive.place(None, usize::MAX).unwrap_err();
    assert!(
        matches!(error, SourceError::NeedsProjection { .. }),
        "{error}"
    );
}

#[test]
fn a_spec_names_every_input_path() {
    let poses = PoseFileSpec {
        path: PathBuf::from("p.txt"),
        format: None,
        calib: Some(PathBuf::from("calib.txt")),
        mounting: None,
    };
    let folder = DriveSpec::ScanFolder {
        dir: PathBuf::from("scans"),
        times: Some(PathBuf::from("times.txt")),
        poses: Some(poses.clone()),
    };
    let names = |spec: &DriveSpec| -> Vec<String> {
        (spec.input_paths().iter())
            .map(|p| p.display().to_string())
            .collect()
    };
    assert_eq!(names(&folder), ["scans", "times.txt", "p.txt", "calib.txt"]);
    let raw = DriveSpec::KittiRaw {
        dir: PathBuf::from("2011_09_26"),
        poses: None,
    };
    assert_eq!(names(&raw), ["2011_09_26"]);
    let bag = DriveSpec::Bag {
        path: PathBuf::from("d.mcap"),
        cloud_topic: None,
        pose_source: PoseSource::Auto,
    };
    assert_eq!(names(&bag), ["d.mcap"]);
}
