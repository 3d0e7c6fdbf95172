//! The shared KITTI scans, without labels: the unlabelled measures of `common` per drive, for
//! the local method against the global-plane baseline. Skipped when the shared data is absent.
//!
//! Measured with the defaults (per-frame obstacle share min/median/max; flat-patch obstacles
//! and lifted ground as mean / worst frame; see `common::FrameMeasure`):
//!
//! | drive | method | obstacle share | beyond 5 m | corridor false obstacles | flat obstacles | lifted ground |
//! | --- | --- | --- | --- | --- | --- | --- |
//! | raw 0013 (40) | global plane | 29.7/37.8/54.4 % (1.44×) | 15.3/29.0/35.9 % (1.24×) | 0 of 124,627 | 4.89 / 10.77 % | 0.73 / 1.56 % |
//! | raw 0013 (40) | local height | 23.1/28.1/47.3 % (1.68×) | 14.4/20.7/24.9 % (1.21×) | 0 of 124,627 | 0.10 / 0.19 % | 0.85 / 1.51 % |
//! | city 22 | global plane | 46.8/49.2/59.3 % (1.20×) | 36.9/45.7/48.0 % (1.05×) | 0 of 67,356 | 0.48 / 1.03 % | 1.18 / 4.68 % |
//! | city 22 | local height | 46.4/49.1/60.1 % (1.22×) | 37.4/45.3/47.0 % (1.04×) | 0 of 67,356 | 0.39 / 0.63 % | 1.12 / 1.89 % |
//!
//! The whole-scan worst frame of raw 0013 (1.68× its median) is not a ground failure: from
//! frame 28 on, a wall at least 2 m high runs 2.7 m to the right of the car, and its ~27,000
//! returns within 5 m are obstacles. Beyond 5 m the share stays within 1.21× its median.

use std::path::PathBuf;

use ground::{GroundMethod, GroundParams, GroundSegmenter, PointLabel};

use crate::common::{self, FrameMeasure, Summary};

fn run(paths: &[PathBuf], method: GroundMethod) -> Vec<FrameMeasure> {
    let mut segmenter = GroundSegmenter::new(GroundParams {
        method,
        ..GroundParams::default()
    })
    .expect("default params");
    paths
        .iter()
        .map(|path| {
            let points = common::read_points(path).expect("a shared scan");
            common::measure(&points, segmenter.segment(&points))
        })
        .collect()
}

/// The targets every drive must meet with the local method, with their margins over the
/// measured values in the table above.
fn assert_targets(name: &str, local: &Summary) {
    // Target: no frame above 1.6× the median, met beyond 5 m (1.21× and 1.04× measured); the
    // whole scan is held to 1.75× because of the wall alongside in raw 0013 (1.68×).
    assert!(local.far_worst_over_median <= 1.6, "{name}: {local}");
    assert!(local.worst_over_median <= 1.75, "{name}: {local}");
    // No lane return called obstacle was measured on either drive; a bound of 0.1 % allows
    // about 3 points a frame, fewer than a single ring crossing the lane (~20 points).
    assert!(
        local.corridor_false_obstacle_share <= 0.001,
        "{name}: {local}"
    );
    // Flat-patch obstacles: 0.10 % and 0.39 % measured (worst frames 0.19 %, 0.63 %).
    assert!(local.flat_obstacle_share[0] <= 0.005, "{name}: {local}");
    assert!(local.flat_obstacle_share[1] <= 0.01, "{name}: {local}");
    // Lifted ground: 0.85 % and 1.12 % measured (worst frames 1.51 %, 1.89 %); part of it is
    // pavement next to light wells and reflections, below the lowest return of its square.
    assert!(local.lifted_ground_share[0] <= 0.015, "{name}: {local}");
    assert!(local.lifted_ground_share[1] <= 0.025, "{name}: {local}");
}

#[test]
fn raw_0013_obstacle_share_is_stable_and_no_ground_ring_is_obstacle() {
    let Some(paths) = common::raw_0013_scans() else {
        return;
    };
    assert_eq!(paths.len(), 40);
    let local = Summary::of(&run(&paths, GroundMethod::LocalHeight));
    let plane = Summary::of(&run(&paths, GroundMethod::GlobalPlane));
    assert_targets("raw 0013", &local);
    // The baseline's tilted plane turns whole ground rings into obstacles (4.9 % of the points
    // on flat patches, 10.8 % in its worst frame): the local method removes 98 % of that
    // (asserted: 95 %).
    assert!(
        local.flat_obstacle_share[0] * 20.0 <= plane.flat_obstacle_share[0],
        "local {local}\nplane {plane}"
    );
    // And the median frame has a quarter fewer obstacle points.
    assert!(
        local.obstacle_share[1] <= 0.8 * plane.obstacle_share[1],
        "local {local}\nplane {plane}"
    );
}

#[test]
fn city_22_obstacle_share_is_stable_and_no_ground_ring_is_obstacle() {
    let Some(paths) = common::city_22_scans() else {
        return;
    };
    assert_eq!(paths.len(), 22);
    let local = Summary::of(&run(&paths, GroundMethod::LocalHeight));
    let plane = Summary::of(&run(&paths, GroundMethod::GlobalPlane));
    assert_targets("city 22", &local);
    // A level street: the plane holds there, and the local method is no worse.
    assert!(
        local.flat_obstacle_share[0] <= plane.flat_obstacle_share[0],
        "local {local}\nplane {plane}"
    );
}

#[test]
fn a_real_scan_gives_the_same_labels_in_any_order_and_on_any_number_of_threads() {
    let Some(paths) = common::raw_0013_scans() else {
        return;
    };
    let Some(path) = paths.get(30) else {
        return;
    };
    let points = common::read_points(path).expect("a shared scan");
    let mut segmenter = GroundSegmenter::new(GroundParams::default()).expect("default params");
    let labels = segmenter.segment(&points).labels().to_vec();
    let ground_z: Vec<u32> = segmenter
        .segment(&points)
        .ground_z_m()
        .iter()
        .map(|z| z.to_bits())
        .collect();
    let reversed: Vec<[f32; 3]> = points.iter().rev().copied().collect();
    let result = segmenter.segment(&reversed);
    assert!(result.labels().iter().rev().eq(labels.iter()));
    assert!(
        result
            .ground_z_m()
            .iter()
            .rev()
            .map(|z| z.to_bits())
            .eq(ground_z.iter().copied())
    );
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool");
        let again = pool.install(|| segmenter.segment(&points).labels().to_vec());
        assert_eq!(again, labels, "{threads} threads");
    }
    // A sanity check on the scene: most of the points are ground or obstacle.
    let counted = labels
        .iter()
        .filter(|&&l| matches!(l, PointLabel::Ground | PointLabel::Obstacle))
        .count();
    assert!(counted > points.len() * 9 / 10);
}
