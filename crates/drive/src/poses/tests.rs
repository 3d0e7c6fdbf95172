#![allow(clippy::unwrap_used)]

use super::*;
use nalgebra::Point3;
use std::f64::consts::{FRAC_PI_2, PI};

fn rz(angle: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle)
}

fn iso(x: f64, y: f64, z: f64, yaw: f64) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::new(x, y, z), rz(yaw))
}

fn close(a: &Isometry3<f64>, b: &Isometry3<f64>, eps: f64) -> bool {
    (a.translation.vector - b.translation.vector).norm() < eps
        && a.rotation.angle_to(&b.rotation) < eps
}

fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> PathBuf {
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn two_pose_track() -> PoseTrack {
    PoseTrack::new(
        vec![10.0, 12.0],
        vec![iso(0.0, 0.0, 0.0, 0.0), iso(2.0, 4.0, 0.0, FRAC_PI_2)],
    )
    .unwrap()
}

#[test]
fn track_interpolates_translation_linearly_and_rotation_by_slerp() {
    let track = two_pose_track();
    // A quarter of the way: (0.5, 1, 0), a quarter of 90° = 22.5°.
    let p = track.at(10.5).unwrap();
    assert!(close(&p, &iso(0.5, 1.0, 0.0, PI / 8.0), 1e-12), "{p}");
    // Within 1 ms outside the span: the end poses.
    assert_eq!(track.at(9.9995).unwrap(), track.poses()[0]);
    assert_eq!(track.at(12.0009).unwrap(), track.poses()[1]);
    assert_eq!(track.at(12.0).unwrap(), track.poses()[1]);
    // Beyond: an error naming the time and the span.
    let err = track.at(12.01).unwrap_err();
    assert!(matches!(err, TrackError::OutsideSpan { .. }));
    let text = err.to_string();
    assert!(
        text.contains("12.010000") && text.contains("[10.000000, 12.000000]"),
        "{text}"
    );
    assert!(track.at(f64::NAN).is_err());
    // Extrapolation at constant velocity along the last interval: 1/4 interval past the end.
    let p = track.at_extrapolated(12.5, 0.6).unwrap();
    assert!(
        close(&p, &iso(2.5, 5.0, 0.0, FRAC_PI_2 + PI / 8.0), 1e-12),
        "{p}"
    );
    let p = track.at_extrapolated(9.5, 0.6).unwrap();
    assert!(close(&p, &iso(-0.5, -1.0, 0.0, -PI / 8.0), 1e-12), "{p}");
    assert!(track.at_extrapolated(12.7, 0.6).is_err());
    // One pose: nothing to extrapolate with.
    let one = PoseTrack::new(vec![1.0], vec![iso(1.0, 0.0, 0.0, 0.0)]).unwrap();
    assert!(one.at(1.0005).is_ok());
    assert!(one.at_extrapolated(1.01, 0.05).is_err());
}

#[test]
fn interpolation_of_opposite_rotations_does_not_panic() {
    let a = iso(0.0, 0.0, 0.0, 0.0);
    let b = iso(0.0, 0.0, 0.0, PI);
    let half = interpolate(&a, &b, 0.5);
    assert!((half.rotation.angle() - FRAC_PI_2).abs() < 1e-12);
}

#[test]
fn track_construction_checks_its_invariants() {
    assert_eq!(PoseTrack::new(vec![], vec![]), Err(TrackError::Empty));
    assert!(matches!(
        PoseTrack::new(vec![0.0], vec![]),
        Err(TrackError::LengthMismatch { times: 1, poses: 0 })
    ));
    let p = iso(0.0, 0.0, 0.0, 0.0);
    assert!(matches!(
        PoseTrack::new(vec![0.0, 1.0, 1.0], vec![p; 3]),
        Err(TrackError::NotIncreasing { index: 2, .. })
    ));
    assert!(matches!(
        PoseTrack::new(vec![0.0, f64::NAN], vec![p; 2]),
        Err(TrackError::NonFinite { index: 1 })
    ));
    let shifted = two_pose_track().then(&iso(1.0, 0.0, 0.0, 0.0));
    // The second pose faces +y, so one metre ahead of it is (2, 5, 0).
    assert!((shifted.poses()[1].translation.vector - Vector3::new(2.0, 5.0, 0.0)).norm() < 1e-12);
}

#[test]
fn tum_reads_by_hand_and_refuses_malformed_lines() {
    let dir = tempfile::tempdir().unwrap();
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let path = write(
        &dir,
        "t.txt",
        &format!("# timestamp tx ty tz qx qy qz qw\n\n1.5 1 2 3 0 0 0 1\n2.5 4 5 6 0 0 {s} {s}\n"),
    );
    let track = read_tum(&path).unwrap();
    assert_eq!(track.times(), &[1.5, 2.5]);
    let p = track.poses()[1];
    assert_eq!(p.translation.vector, Vector3::new(4.0, 5.0, 6.0));
    // qz = qw = 1/√2 is Rz(90°): x goes to y.
    assert!((p.rotation * Vector3::x() - Vector3::y()).norm() < 1e-12);

    for (text, place, what) in [
        ("1 2 3 4 0 0 0\n", "t.txt:1:", "expected 8 numbers"),
        (
            "# c\n1 2 3 4 0 0 0 one\n",
            "t.txt:2:",
            "`one` is not a number",
        ),
        ("1 2 3 4 0 0 0 2\n", "t.txt:1:", "has norm 2.0000, not 1"),
        (
            "1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n",
            "t.txt:2:",
            "does not increase",
        ),
        (
            "1 0 0 0 0 0 0 1\n2 inf 0 0 0 0 0 1\n",
            "t.txt:2:",
            "not finite",
        ),
        ("# only a comment\n", "t.txt:", "no poses"),
    ] {
        let path = write(&dir, "t.txt", text);
        let err = read_tum(&path).unwrap_err().to_string();
        assert!(err.contains(place) && err.contains(what), "{text:?}: {err}");
    }
}

/// A KITTI-like `cam0_from_velo`: camera x = -velo y, camera y = -velo z, camera z = velo x;
/// the Velodyne 0.08 m above and 0.27 m behind the camera.
fn kitti_tr() -> Isometry3<f64> {
    let r =
        crate::calib::rotation_from_rows(&[0.0, -1.0, 0.0, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0]).unwrap();
    Isometry3::from_parts(Translation3::new(0.0, -0.08, -0.27), r)
}

#[test]
fn kitti_odometry_gives_velodyne_poses_in_a_z_up_world() {
    let dir = tempfile::tempdir().unwrap();
    // Frame 0 at the origin; frame 1 five metres forward (camera z); frame 2 turned 90° left
    // about the camera's vertical axis (-y) through the camera's centre.
    let path = write(
        &dir,
        "00.txt",
        "1 0 0 0 0 1 0 0 0 0 1 0\n\
         1 0 0 0 0 1 0 0 0 0 1 5\n\
         0 0 -1 0 0 1 0 0 1 0 0 0\n",
    );
    let tr = kitti_tr();
    let track = read_kitti_odometry(&path, &[0.0, 0.1, 0.2], &tr).unwrap();
    let p = track.poses();
    assert!(close(&p[0], &Isometry3::identity(), 1e-12), "{}", p[0]);
    // Forward in camera z is forward in velo x.
    assert!(close(&p[1], &iso(5.0, 0.0, 0.0, 0.0), 1e-12), "{}", p[1]);
    // A left turn is +90° about z; the Velodyne, 0.27 m behind the camera, swings to
    // (0.27, -0.27) around the camera at (0.27, 0).
    assert!(
        close(&p[2], &iso(0.27, -0.27, 0.0, FRAC_PI_2), 1e-12),
        "{}",
        p[2]
    );

    let err = read_kitti_odometry(&path, &[0.0, 0.1], &tr)
        .unwrap_err()
        .to_string();
    assert!(err.contains("3 poses for 2 times"), "{err}");
    let err = read_kitti_odometry(&path, &[0.0, 0.2, 0.1], &tr)
        .unwrap_err()
        .to_string();
    assert!(err.contains("does not increase"), "{err}");
    for (text, place, what) in [
        (
            "1 0 0 0 0 1 0 0 0 0 1\n",
            "00.txt:1:",
            "expected 12 numbers",
        ),
        (
            "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 x\n",
            "00.txt:2:",
            "`x` is not",
        ),
        ("2 0 0 0 0 1 0 0 0 0 1 0\n", "00.txt:1:", "not a rotation"),
    ] {
        let path = write(&dir, "00.txt", text);
        let err = read_kitti_odometry(&path, &[0.0], &tr)
            .unwrap_err()
            .to_string();
        assert!(err.contains(place) && err.contains(what), "{text:?}: {err}");
    }

    let times = write(&dir, "times.txt", "0.000000e+00\n1.036594e-01\n");
    assert_eq!(read_kitti_times(&times).unwrap(), vec![0.0, 0.1036594]);
    let times = write(&dir, "times.txt", "0.0\n0.1\n0.1\n");
    let err = read_kitti_times(&times).unwrap_err().to_string();
    assert!(
        err.contains("times.txt:3:") && err.contains("does not increase"),
        "{err}"
    );
}

fn wiggly_track() -> PoseTrack {
    // The last pose is far (shortest round-trip of large numbers), and late enough to be reached.
    let times = vec![0.0, 0.1036594, 0.2071, 1e5 + 1.0 / 3.0];
    let poses = vec![
        Isometry3::from_parts(
            Translation3::new(1.0, -2.0, 0.3),
            UnitQuaternion::from_euler_angles(0.01, -0.02, 2.5),
        ),
        Isometry3::from_parts(
            Translation3::new(1.7, -1.1, 0.31),
            UnitQuaternion::from_euler_angles(0.02, 0.03, 2.6),
        ),
        Isometry3::from_parts(
            Translation3::new(2.3, -0.2, 0.29),
            UnitQuaternion::from_euler_angles(-0.01, 0.01, -3.1),
        ),
        Isometry3::from_parts(
            Translation3::new(1e5 / 3.0, 7e6, -0.1),
            UnitQuaternion::from_euler_angles(0.3, -0.4, 0.5),
        ),
    ];
    PoseTrack::new(times, poses).unwrap()
}

#[test]
fn writers_round_trip_through_the_readers() {
    let dir = tempfile::tempdir().unwrap();
    let track = wiggly_track();

    let mut tum = Vec::new();
    write_tum(&mut tum, &track).unwrap();
    let back = read_tum(&write(&dir, "t.txt", std::str::from_utf8(&tum).unwrap())).unwrap();
    assert_eq!(back.times(), track.times());
    for (a, b) in back.poses().iter().zip(track.poses()) {
        assert!(close(a, b, 1e-12), "{a} vs {b}");
    }

    let tr = kitti_tr();
    let (mut poses, mut times) = (Vec::new(), Vec::new());
    write_kitti_odometry(&mut poses, &track, &tr).unwrap();
    write_kitti_times(&mut times, track.times()).unwrap();
    let times = read_kitti_times(&write(
        &dir,
        "times.txt",
        std::str::from_utf8(&times).unwrap(),
    ))
    .unwrap();
    assert_eq!(times, track.times());
    let path = write(&dir, "00.txt", std::str::from_utf8(&poses).unwrap());
    let back = read_kitti_odometry(&path, &times, &tr).unwrap();
    for (a, b) in back.poses().iter().zip(track.poses()) {
        assert!(close(a, b, 1e-9), "{a} vs {b}");
    }

    let mut evi = Vec::new();
    write_evigrid(&mut evi, &track).unwrap();
    let EvigridPoses::Local(back) =
        read_evigrid(&write(&dir, "p.txt", std::str::from_utf8(&evi).unwrap())).unwrap()
    else {
        panic!("local frame expected")
    };
    assert_eq!(back.times(), track.times());
    for (a, b) in back.poses().iter().zip(track.poses()) {
        assert!(close(a, b, 1e-12), "{a} vs {b}");
    }
}

#[test]
fn evigrid_local_and_wgs84() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        &dir,
        "p.txt",
        "# a comment\n0 1 2 3 0 0 1.5707963267948966\n0.1 1.5 2 3 0 0 0\n",
    );
    let EvigridPoses::Local(track) = read_evigrid(&path).unwrap() else {
        panic!("local frame expected")
    };
    assert_eq!(track.times(), &[0.0, 0.1]);
    let p = track.poses()[0];
    assert_eq!(p.translation.vector, Vector3::new(1.0, 2.0, 3.0));
    assert!((p.rotation * Vector3::x() - Vector3::y()).norm() < 1e-12);

    let path = write(
        &dir,
        "p.txt",
        "# frame: wgs84\n5.0 60.17 24.94 10 0 0 0\n5.1 60.18 24.95 11 0 0 0\n",
    );
    let poses = read_evigrid(&path).unwrap();
    let EvigridPoses::Wgs84 { poses: ref geo, .. } = poses else {
        panic!("wgs84 expected")
    };
    assert_eq!(
        geo[1],
        GeodeticPose {
            line: 3,
            time_s: 5.1,
            lat_deg: 60.18,
            lon_deg: 24.95,
            alt_m: 11.0,
            roll: 0.0,
            pitch: 0.0,
            yaw: 0.0
        }
    );
    let track = poses
        .into_track(&|lat: f64, lon: f64| (lon * 10.0, lat * 10.0))
        .unwrap();
    let t = track.poses()[0].translation.vector;
    assert!((t - Vector3::new(249.4, 601.7, 10.0)).norm() < 1e-9, "{t}");
    assert!(track.poses()[0].rotation.angle() < 1e-9);
    // The projection failing names the line.
    let err = read_evigrid(&path)
        .unwrap()
        .into_track(&|_: f64, _: f64| (f64::NAN, 0.0))
        .unwrap_err();
    assert!(err.to_string().contains("p.txt:2:"), "{err}");

    for (text, place, what) in [
        (
            "# frame: wgs84\n0 95 10 0 0 0 0\n",
            "p.txt:2:",
            "latitude 95 outside [-90, 90]",
        ),
        (
            "# frame: wgs84\n0 45 -200 0 0 0 0\n",
            "p.txt:2:",
            "longitude -200 outside [-180, 180]",
        ),
        (
            "0 1 2 3 0 0 0\n# frame: wgs84\n",
            "p.txt:2:",
            "must come first",
        ),
        ("# frame: utm\n", "p.txt:1:", "unknown frame `utm`"),
        (
            "0 1 2 3 0 0\n",
            "p.txt:1:",
            "expected 7 numbers (evigrid: t x y z roll pitch yaw), found 6",
        ),
        ("# frame: wgs84\n0 1 2 3 0 0\n", "p.txt:2:", "t lat lon alt"),
        (
            "0 1 2 3 0 0 0\n-1 1 2 3 0 0 0\n",
            "p.txt:2:",
            "does not increase",
        ),
        ("0 1 2 3 0 0 NaN\n", "p.txt:1:", "not finite"),
        ("# frame: wgs84\n", "p.txt:", "no poses"),
    ] {
        let path = write(&dir, "p.txt", text);
        let err = read_evigrid(&path).unwrap_err().to_string();
        assert!(err.contains(place) && err.contains(what), "{text:?}: {err}");
    }
}

#[test]
fn format_detection_and_dispatch() {
    let dir = tempfile::tempdir().unwrap();
    let evi = write(&dir, "a.txt", "# frame: local\n\n0 1 2 3 0 0 0\n");
    let tum = write(&dir, "b.txt", "# tum\n0 1 2 3 0 0 0 1\n");
    let kitti = write(&dir, "c.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n");
    assert_eq!(PoseFormat::detect(&evi).unwrap(), PoseFormat::Evigrid);
    assert_eq!(PoseFormat::detect(&tum).unwrap(), PoseFormat::Tum);
    assert_eq!(
        PoseFormat::detect(&kitti).unwrap(),
        PoseFormat::KittiOdometry
    );
    let bad = write(&dir, "d.txt", "\n# x\n1 2 3 4 5 6 7 8 9\n");
    let err = PoseFormat::detect(&bad).unwrap_err();
    assert!(matches!(
        err,
        ReadError::Columns {
            line: 3,
            found: 9,
            ..
        }
    ));
    let text = err.to_string();
    assert!(
        text.contains("d.txt:3:")
            && text.contains("7 (evigrid")
            && text.contains("8 (TUM")
            && text.contains("12 (KITTI"),
        "{text}"
    );
    assert!(!text.contains("commas"), "{text}");
    // A CSV file reads as one column a line: the error says why.
    let csv = write(&dir, "f.csv", "t,x,y,z,roll,pitch,yaw\n0.0,1,2,3,0,0,0\n");
    let text = PoseFormat::detect(&csv).unwrap_err().to_string();
    assert!(
        text.contains("f.csv:1: 1 columns (separated by commas? columns are separated by spaces"),
        "{text}"
    );
    assert!(PoseFormat::detect(&write(&dir, "e.txt", "# nothing\n")).is_err());

    assert_eq!("TUM".parse::<PoseFormat>().unwrap(), PoseFormat::Tum);
    assert_eq!(
        "kitti".parse::<PoseFormat>().unwrap(),
        PoseFormat::KittiOdometry
    );
    assert_eq!(
        "evigrid".parse::<PoseFormat>().unwrap(),
        PoseFormat::Evigrid
    );
    assert!(
        "csv"
            .parse::<PoseFormat>()
            .unwrap_err()
            .to_string()
            .contains("evigrid, tum or kitti")
    );

    assert_eq!(read_pose_track(&tum, None, None, None).unwrap().len(), 1);
    assert_eq!(read_pose_track(&evi, None, None, None).unwrap().len(), 1);
    let err = read_pose_track(&kitti, None, None, None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("need the scan times"), "{err}");
    let ctx = KittiOdometryContext {
        times: &[3.0],
        cam0_from_velo: kitti_tr(),
    };
    assert_eq!(
        read_pose_track(&kitti, None, Some(&ctx), None)
            .unwrap()
            .times(),
        &[3.0]
    );
    // Forcing a format that does not match the file fails on its reader's line check.
    let err = read_pose_track(&tum, Some(PoseFormat::Evigrid), None, None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("b.txt:2:") && err.contains("found 8"), "{err}");
    let wgs = write(&dir, "w.txt", "# frame: wgs84\n0 49 8 100 0 0 0\n");
    assert!(
        read_pose_track(&wgs, None, None, None)
            .unwrap_err()
            .to_string()
            .contains("need a projection")
    );
    let project = |lat: f64, lon: f64| (lon, lat);
    let track = read_pose_track(&wgs, None, None, Some(&project)).unwrap();
    assert_eq!(
        track.poses()[0].translation.vector,
        Vector3::new(8.0, 49.0, 100.0)
    );
}

#[test]
fn mounting_places_the_sensor_on_the_vehicle() {
    let m: Mounting = " 1, 0 ,2,0,0,1.5707963267948966".parse().unwrap();
    let world_from_vehicle = iso(10.0, 0.0, 0.0, FRAC_PI_2);
    let world_from_sensor = m.world_from_sensor(&world_from_vehicle);
    // The sensor sits 1 m ahead (the vehicle faces +y) and 2 m up, facing -x.
    assert!((world_from_sensor * Point3::origin() - Point3::new(10.0, 1.0, 2.0)).norm() < 1e-12);
    assert!((world_from_sensor.rotation * Vector3::x() + Vector3::x()).norm() < 1e-12);
    let track = PoseTrack::new(vec![0.0], vec![world_from_vehicle]).unwrap();
    assert_eq!(m.apply(&track).poses()[0], world_from_sensor);

    for (text, what) in [
        ("1,2,3,4,5", "5 values, expected 6"),
        ("1,2,3,4,5,6,7", "7 values"),
        ("1,2,x,0,0,0", "`x` is not a number"),
        ("", "is not a number"),
    ] {
        let err = text.parse::<Mounting>().unwrap_err().to_string();
        assert!(
            err.contains(what) && err.contains("x,y,z,roll,pitch,yaw"),
            "{text:?}: {err}"
        );
    }
}

#[test]
fn scan_times_in_either_kitti_form() {
    let dir = tempfile::tempdir().unwrap();
    let raw = write(
        &dir,
        "timestamps.txt",
        "2011-09-26 13:02:25.964389445\n2011-09-26 13:02:26.066575752\n",
    );
    let times = read_scan_times(&raw).unwrap();
    // 13:02:25 on 2011-09-26 is 1 317 042 145 s after the epoch.
    assert!((times[0] - 1_317_042_145.964_389).abs() < 1e-6, "{times:?}");
    assert!((times[1] - times[0] - 0.102_186_307).abs() < 1e-6);
    let plain = write(&dir, "times.txt", "0.0\n1.036594e-01\n");
    assert_eq!(read_scan_times(&plain).unwrap(), vec![0.0, 0.1036594]);
    let back = write(
        &dir,
        "back.txt",
        "2011-09-26 13:02:25.9\n2011-09-26 13:02:25.8\n",
    );
    let err = read_scan_times(&back).unwrap_err().to_string();
    assert!(err.contains("back.txt:2"), "{err}");
    let bad = write(&dir, "bad.txt", "0.0\nsoon\n");
    let err = read_scan_times(&bad).unwrap_err().to_string();
    assert!(err.contains("bad.txt:2"), "{err}");
    let empty = write(&dir, "empty.txt", "\n");
    assert!(read_scan_times(&empty).is_err());
}

#[test]
fn absurd_positions_jumps_and_angles_are_refused_with_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let read_err = |name: &str, text: &str| -> String {
        let path = write(&dir, name, text);
        match PoseFormat::detect(&path) {
            Ok(PoseFormat::Tum) => read_tum(&path).err().map(|e| e.to_string()),
            _ => read_evigrid(&path).err().map(|e| e.to_string()),
        }
        .unwrap_or_default()
    };
    // Issue 31: a TUM z of 1e308 was accepted.
    let err = read_err("z.tum", "0 0 0 0 0 0 0 1\n0.1 0 0 1e308 0 0 0 1\n");
    assert!(
        err.ends_with("z.tum:2: position coordinate 1e308 m is beyond ±1e7 m"),
        "{err}"
    );
    // 100 m/s × 0.1 s + 10 m = 20 m allowed; 25 m is not.
    let err = read_err("jump.tum", "0 0 0 0 0 0 0 1\n0.1 25 0 0 0 0 0 1\n");
    assert!(
        err.contains("jump.tum:2: the position jumps 25.0 m"),
        "{err}"
    );
    assert!(read_err("walk.tum", "0 0 0 0 0 0 0 1\n0.1 19 0 0 0 0 0 1\n").is_empty());
    let err = read_err("roll.txt", "0 0 0 0 1e308 0 0\n");
    assert!(err.contains("roll.txt:1: roll 1e308 rad"), "{err}");
    let err = read_err("alt.txt", "# frame: wgs84\n0 49 8 1e308 0 0 0\n");
    assert!(err.contains("alt.txt:2: altitude 1e308 m outside"), "{err}");
}

#[test]
fn negative_scan_times_are_refused_with_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, "times.txt", "-0.2\n-0.1\n0.0\n");
    let err = read_scan_times(&path).unwrap_err().to_string();
    assert!(
        err.contains("times.txt:1: time -0.2 s is negative"),
        "{err}"
    );
}

#[test]
fn a_mounting_far_from_the_vehicle_or_turned_absurdly_is_refused() {
    let err = "0,0,1e6,0,0,0".parse::<Mounting>().unwrap_err().to_string();
    assert!(
        err.contains("1000000 m from the vehicle's origin, beyond 50 m"),
        "{err}"
    );
    let err = "0,0,1.7,0,1e308,0"
        .parse::<Mounting>()
        .unwrap_err()
        .to_string();
    assert!(err.contains("pitch 1e308 rad"), "{err}");
    assert!("0.8,0,1.7,0,0,3.1".parse::<Mounting>().is_ok());
}
