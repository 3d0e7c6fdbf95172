//! Properties: the labels do not depend on the point order or the number of threads, and no
//! input makes the segmenter panic.

use std::sync::OnceLock;

use ground::{GroundMethod, GroundParams, GroundSegmenter, PointLabel, RingZone};
use proptest::prelude::*;

use crate::common::scene::{SENSOR_HEIGHT_M, Scene};

/// A small scan of a street: kerb, wall, parked car, a car ahead; 32 beams every 1°.
fn street() -> &'static [[f32; 3]] {
    static POINTS: OnceLock<Vec<[f32; 3]>> = OnceLock::new();
    POINTS.get_or_init(|| {
        Scene::new(|_, y| -SENSOR_HEIGHT_M + if y < -4.0 { 0.15 } else { 0.0 })
            .with_box([-40.0, -9.0, -2.0], [40.0, -8.0, 6.0])
            .with_box([-2.0, 2.5, -SENSOR_HEIGHT_M], [2.5, 4.3, -0.23])
            .with_box([8.0, -0.9, -SENSOR_HEIGHT_M], [12.5, 0.9, -0.23])
            .scan(32, 1.0)
            .into_iter()
            .map(|r| r.point)
            .collect()
    })
}

/// Labels and ground heights (as bits, so that NaN compares) of `points`.
fn segment(segmenter: &mut GroundSegmenter, points: &[[f32; 3]]) -> (Vec<PointLabel>, Vec<u32>) {
    let result = segmenter.segment(points);
    (
        result.labels().to_vec(),
        result.ground_z_m().iter().map(|z| z.to_bits()).collect(),
    )
}

/// A permutation of `0..n` from a seed (Fisher–Yates with a SplitMix64 stream).
fn permutation(n: usize, mut seed: u64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        seed = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = seed;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        order.swap(i, (z % (i as u64 + 1)) as usize);
    }
    order
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn labels_do_not_depend_on_the_point_order(seed in any::<u64>()) {
        let points = street();
        let mut segmenter = GroundSegmenter::new(GroundParams::default()).expect("defaults");
        let (labels, ground_z) = segment(&mut segmenter, points);
        let order = permutation(points.len(), seed);
        let shuffled: Vec<[f32; 3]> = order.iter().map(|&i| points[i]).collect();
        let (labels_s, ground_z_s) = segment(&mut segmenter, &shuffled);
        for (k, &i) in order.iter().enumerate() {
            prop_assert_eq!(labels_s[k], labels[i]);
            prop_assert_eq!(ground_z_s[k], ground_z[i]);
        }
    }

    #[test]
    fn labels_do_not_depend_on_the_number_of_threads(threads in 1usize..5) {
        let points = street();
        let expected = segment(&mut GroundSegmenter::new(GroundParams::default()).expect("defaults"), points);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a pool");
        let got = pool.install(|| {
            segment(&mut GroundSegmenter::new(GroundParams::default()).expect("defaults"), points)
        });
        prop_assert_eq!(got, expected);
    }

    #[test]
    fn any_points_are_labelled_without_panic(
        points in prop::collection::vec(
            prop::array::uniform3(prop_oneof![
                any::<f32>(),
                -100.0f32..100.0,
                Just(f32::NAN),
                Just(f32::INFINITY),
                Just(-1.73f32),
            ]),
            0..400,
        )
    ) {
        for method in [GroundMethod::LocalHeight, GroundMethod::GlobalPlane, GroundMethod::FixedHeight] {
            let mut segmenter = GroundSegmenter::new(GroundParams { method, ..GroundParams::default() })
                .expect("defaults");
            let result = segmenter.segment(&points);
            let s = *result.stats();
            prop_assert_eq!(result.len(), points.len());
            prop_assert_eq!(result.ground_z_m().len(), points.len());
            prop_assert_eq!(
                s.points,
                s.ground + s.obstacle + s.overhanging + s.below_ground + s.non_finite + s.out_of_range
            );
            for (label, z) in result.labels().iter().zip(result.ground_z_m()) {
                prop_assert_eq!(*label == PointLabel::Invalid, z.is_nan());
            }
        }
    }

    #[test]
    fn any_parameters_are_accepted_or_refused_without_panic(
        values in prop::collection::vec(prop_oneof![any::<f64>(), -1.0f64..100.0], 14),
        sectors in 0usize..5000,
        zones in prop::collection::vec((prop_oneof![any::<f64>(), 0.0f64..100.0], prop_oneof![any::<f64>(), 0.01f64..10.0]), 0..4),
    ) {
        let params = GroundParams {
            method: GroundMethod::LocalHeight,
            sensor_height_m: values[0],
            sensor_height_tolerance_m: values[1],
            min_range_m: values[2],
            max_range_m: values[3],
            sectors,
            ring_zones: zones.into_iter().map(|(from_m, ring_width_m)| RingZone { from_m, ring_width_m }).collect(),
            max_slope: values[4],
            max_slope_unseen: values[5],
            max_step_m: values[6],
            seed_band_m: values[7],
            min_obstacle_height_m: values[8],
            max_obstacle_height_m: values[9],
            max_depth_below_ground_m: values[10],
            plane_band_m: values[11],
        };
        if let Ok(mut segmenter) = GroundSegmenter::new(params) {
            let result = segmenter.segment(street());
            prop_assert_eq!(result.len(), street().len());
        }
    }
}
