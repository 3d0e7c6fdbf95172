//! Odometry on 40 scans of KITTI raw drive 2011_09_26_drive_0013, against its OXTS poses.
//!
//! Skipped (with a note) when the shared data is absent.

use drive::kitti_raw::KittiRawDrive;
use drive::oxts::KittiMercator;
use odometry::metrics::relative_errors;
use odometry::{FrameOutcome, Odometry, OdometryParams};

const DRIVE: &str = "data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync";

#[test]
fn kitti_raw_0013_matches_oxts() {
    let Some(dir) = geodata::testdata::shared_file(DRIVE) else {
        return;
    };
    let drive = KittiRawDrive::open(&dir).expect("a readable drive");
    let frames = drive.frames();
    assert_eq!(frames.len(), 40);
    let first = &frames[0].oxts;
    let projection = KittiMercator::centered(first.lat_deg, first.lon_deg);
    let reference = drive
        .world_from_velodyne(&|lat: f64, lon: f64| projection.project(lat, lon))
        .expect("OXTS poses");

    let mut odometry = Odometry::new(OdometryParams::default()).expect("valid params");
    for frame in &frames {
        let scan = drive::read_scan(&frame.scan_path).expect("a readable scan");
        odometry
            .register(&scan.points_in_sensor, frame.time_s)
            .expect("a valid scan");
        let report = odometry.last_report().expect("a report");
        assert!(
            matches!(
                report.outcome,
                FrameOutcome::First | FrameOutcome::Registered { converged: true }
            ),
            "frame {}: {report:?}",
            frame.index
        );
    }

    let errors = relative_errors(odometry.poses(), &reference, &[10.0, 20.0, 30.0], 1)
        .expect("one pose per frame");
    for length in [10.0, 20.0, 30.0] {
        let of_length = errors.of_length(length);
        let translation = of_length.mean_translation_pct().expect("segments");
        let heading = of_length.mean_heading_deg_per_m().expect("segments");
        let rotation = of_length.mean_rotation_deg_per_m().expect("segments");
        eprintln!(
            "{length} m: translation {translation:.2} %, heading {heading:.4} deg/m, rotation \
             {rotation:.4} deg/m"
        );
        // Targets of the issue: 1.5 % and 0.02 deg/m.
        assert!(translation <= 1.5, "{length} m: {translation} %");
        assert!(heading <= 0.02, "{length} m: {heading} deg/m");
    }
}
