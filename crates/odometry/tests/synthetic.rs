//! Odometry on a synthetic street with known motion.

mod common;

use common::scene::{Lcg, Lidar, Street, max_errors, pose, relative_to_first};
use nalgebra::{Isometry3, Vector3};
use odometry::metrics::relative_errors;
use odometry::{FrameOutcome, Odometry, OdometryError, OdometryParams};

const SENSOR_HEIGHT_M: f64 = 1.8;
const FRAME_PERIOD_S: f64 = 0.1;

/// An HDL-64-like sensor with 1 cm range noise, sampling at random within its beam grid (see
/// [`Lidar::jitter`]).
fn sensor() -> Lidar {
    Lidar {
        range_noise_m: 0.01,
        jitter: true,
        ..Lidar::hdl64_like()
    }
}

/// Straight along the street at 10 m/s.
fn straight(t: f64) -> Isometry3<f64> {
    pose(Vector3::new(10.0 * t, 0.0, SENSOR_HEIGHT_M), 0.0, 0.0, 0.0)
}

/// Accelerating from 8 m/s at 1 m/s², weaving across the street, pitching and rolling a little.
fn weaving(t: f64) -> Isometry3<f64> {
    let (x, y) = (8.0 * t + 0.5 * t * t, 1.5 * (0.8 * t).sin());
    let (dx, dy) = (8.0 + t, 1.2 * (0.8 * t).cos());
    pose(
        Vector3::new(x, y, SENSOR_HEIGHT_M + 0.05 * (3.0 * t).sin()),
        dy.atan2(dx),
        0.01 * (2.0 * t).sin(),
        0.01 * (1.5 * t).cos(),
    )
}

/// Swerving at 12 m/s from one side of the street to the other, turning at up to 30°/s: the
/// sensor turns 3° during a sweep.
fn swerving(t: f64) -> Isometry3<f64> {
    let (x, y) = (12.0 * t, 2.5 * (1.6 * t).sin());
    let (dx, dy) = (12.0, 4.0 * (1.6 * t).cos());
    pose(Vector3::new(x, y, SENSOR_HEIGHT_M), dy.atan2(dx), 0.0, 0.0)
}

/// Runs the odometry over `frames` scans of `motion`. With `skewed`, each firing sees the street
/// from the pose at its own time, and the scan carries those times when `give_times`.
fn run(
    params: OdometryParams,
    lidar: &Lidar,
    motion: fn(f64) -> Isometry3<f64>,
    frames: usize,
    skewed: bool,
    give_times: bool,
) -> (Vec<Isometry3<f64>>, Vec<Isometry3<f64>>) {
    let street = Street::new();
    let mut random = Lcg::new(11);
    let mut odometry = Odometry::new(params).expect("valid params");
    let mut truth = Vec::new();
    for frame in 0..frames {
        let time = frame as f64 * FRAME_PERIOD_S;
        let (points, times) = lidar.scan(
            &street,
            |tau| motion(if skewed { time + tau } else { time }),
            &mut random,
        );
        let result = if give_times {
            odometry.register_with_point_times(&points, &times, time)
        } else {
            odometry.register(&points, time)
        };
        result.expect("valid scan");
        truth.push(motion(time));
    }
    (odometry.poses().to_vec(), relative_to_first(&truth))
}

#[test]
fn a_straight_drive_is_recovered() {
    let lidar = sensor();
    let (estimate, truth) = run(
        OdometryParams::default(),
        &lidar,
        straight,
        30,
        false,
        false,
    );
    let (translation_m, rotation_deg) = max_errors(&estimate, &truth);
    eprintln!("straight: {translation_m:.4} m, {rotation_deg:.4} deg");
    // Over 29 m; roll is the least constrained in a street 16 m wide.
    assert!(translation_m < 0.05, "{translation_m} m");
    assert!(rotation_deg < 0.25, "{rotation_deg} deg");
}

#[test]
fn a_weaving_accelerating_drive_with_range_noise_is_recovered() {
    let lidar = Lidar {
        range_noise_m: 0.02,
        ..sensor()
    };
    let (estimate, truth) = run(OdometryParams::default(), &lidar, weaving, 40, false, false);
    let (translation_m, rotation_deg) = max_errors(&estimate, &truth);
    eprintln!("weaving: {translation_m:.4} m, {rotation_deg:.4} deg");
    // 40 frames cover about 36 m.
    assert!(translation_m < 0.1, "{translation_m} m");
    assert!(rotation_deg < 0.3, "{rotation_deg} deg");
}

#[test]
fn deskewing_corrects_the_motion_within_a_sweep() {
    let lidar = sensor();
    let plain = OdometryParams::default();
    let (skewed, truth) = run(plain.clone(), &lidar, swerving, 30, true, false);
    let (with_times, _) = run(plain.clone(), &lidar, swerving, 30, true, true);
    let azimuth = OdometryParams {
        azimuth_times: true,
        ..plain
    };
    let (with_azimuth, _) = run(azimuth, &lidar, swerving, 30, true, false);
    // Relative errors over 5 m, so that the second scan, registered before any velocity is
    // known and hence not deskewed, does not dominate.
    let relative = |estimate: &[Isometry3<f64>]| {
        let errors = relative_errors(estimate, &truth, &[5.0], 1).expect("same lengths");
        (
            errors.mean_translation_pct().unwrap_or(f64::INFINITY),
            errors.mean_rotation_deg_per_m().unwrap_or(f64::INFINITY),
        )
    };
    let (unskewed, _) = run(plain.clone(), &lidar, swerving, 30, false, false);
    let (skewed_error, times_error, azimuth_error, unskewed_error) = (
        relative(&skewed),
        relative(&with_times),
        relative(&with_azimuth),
        relative(&unskewed),
    );
    eprintln!(
        "% and deg/m over 5 m: skewed {skewed_error:?}, given times {times_error:?}, azimuth \
         {azimuth_error:?}, no skew {unskewed_error:?}"
    );
    for deskewed in [times_error, azimuth_error] {
        assert!(
            deskewed.0 < 0.7 * skewed_error.0,
            "{deskewed:?} vs {skewed_error:?}"
        );
        assert!(
            deskewed.1 < 0.7 * skewed_error.1,
            "{deskewed:?} vs {skewed_error:?}"
        );
    }
}

#[test]
fn poses_do_not_depend_on_the_number_of_threads() {
    let lidar = Lidar {
        range_noise_m: 0.02,
        ..sensor()
    };
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool")
            .install(|| run(OdometryParams::default(), &lidar, weaving, 8, false, false).0)
    };
    assert_eq!(on(1), on(3));
}

#[test]
fn the_local_map_stays_bounded_on_a_long_drive() {
    // A sparser, shorter-range sensor keeps the simulation cheap; the map keeps 100 m.
    let lidar = Lidar {
        azimuth_steps: 400,
        max_range_m: 40.0,
        ..sensor()
    };
    let street = Street::new();
    let mut random = Lcg::new(3);
    let mut odometry = Odometry::new(OdometryParams::default()).expect("valid params");
    let mut voxels = Vec::new();
    // From rest to 15 m/s in 5 s, then on to 337.5 m.
    let distance = |t: f64| {
        if t < 5.0 {
            1.5 * t * t
        } else {
            37.5 + 15.0 * (t - 5.0)
        }
    };
    for frame in 0..250 {
        let time = frame as f64 * FRAME_PERIOD_S;
        let at = |_| {
            pose(
                Vector3::new(distance(time), 0.0, SENSOR_HEIGHT_M),
                0.0,
                0.0,
                0.0,
            )
        };
        let (points, _) = lidar.scan(&street, at, &mut random);
        odometry.register(&points, time).expect("valid scan");
        voxels.push(odometry.last_report().expect("a report").map_voxels);
    }
    // The map covers 100 m around the sensor: full after some 130 m (frame 110).
    let full = voxels[110..130].iter().max().copied().unwrap_or(0);
    let late = voxels[230..].iter().max().copied().unwrap_or(0);
    eprintln!("map voxels: {full} at ~150 m, {late} at ~320 m");
    assert!(late < full * 6 / 5, "{full} -> {late}");
    let end = odometry.poses().last().expect("poses").translation.vector;
    let expected = distance(24.9);
    assert!(
        (end - Vector3::new(expected, 0.0, 0.0)).norm() < 0.01 * expected,
        "{end}"
    );
}

#[test]
fn degenerate_scans_do_not_panic() {
    let lidar = sensor();
    let street = Street::new();
    let mut random = Lcg::new(5);
    let mut odometry = Odometry::new(OdometryParams::default()).expect("valid params");

    // No map yet: an empty, all-NaN or one-point scan has nothing to give a pose but the
    // identity, so it is refused (issue 31: such drives wrote identity poses, exit 0), and the
    // state is left as it was.
    let broken = [
        [f32::NAN, 0.0, 0.0],
        [0.0, f32::INFINITY, 1.0],
        [1.0, 2.0, f32::NAN],
    ];
    let one = [[10.0, 0.0, 0.0]];
    for (scan, time, usable) in [
        (&[][..], 0.0, 0),
        (&broken[..], 0.1, 0),
        (&one[..], 0.15, 1),
    ] {
        let refused = odometry.register(scan, time);
        assert!(
            matches!(
                refused,
                Err(OdometryError::TooFewPoints { usable: u, min: 10, .. }) if u == usable
            ),
            "{refused:?}"
        );
    }
    assert!(odometry.poses().is_empty() && odometry.last_report().is_none());

    // Real scans, then degenerate ones: these get the constant-velocity prediction.
    for frame in 2..8 {
        let time = frame as f64 * FRAME_PERIOD_S;
        let (points, _) = lidar.scan(&street, |_| straight(time), &mut random);
        odometry.register(&points, time).expect("valid scan");
    }
    assert!(matches!(
        odometry.last_report().map(|r| r.outcome),
        Some(FrameOutcome::Registered { .. })
    ));
    let single = odometry
        .register(&[[10.0, 0.0, 0.0]], 0.8)
        .expect("one point");
    assert_eq!(
        odometry.last_report().map(|r| r.outcome),
        Some(FrameOutcome::Predicted)
    );
    let empty = odometry.register(&[], 0.9).expect("empty scan");
    let nan = odometry
        .register(&[[f32::NAN; 3]; 100], 1.0)
        .expect("NaN scan");
    // Poses continue at the speed seen (1 m per frame along x, from where frame 2 began).
    let step = single.inverse() * empty;
    assert!((step.translation.vector - Vector3::new(1.0, 0.0, 0.0)).norm() < 0.05);
    assert!(((empty.inverse() * nan).translation.vector - step.translation.vector).norm() < 1e-9);
    assert_eq!(odometry.poses().len(), 9);

    // Scans resume.
    let (points, _) = lidar.scan(&street, |_| straight(1.1), &mut random);
    odometry.register(&points, 1.1).expect("valid scan");
    assert!(
        odometry
            .poses()
            .iter()
            .all(|p| p.translation.vector.iter().all(|v| v.is_finite()))
    );

    assert!(matches!(
        odometry.register(&points, 1.1),
        Err(OdometryError::TimeNotIncreasing { .. })
    ));
}
