//! Every scenario shipped in `scenarios/` parses and validates, and the error scenarios carry
//! the errors their names promise.

#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

fn scenarios_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenarios")
}

fn read(name: &str) -> sim::Scenario {
    let path = scenarios_dir().join(name);
    let text = std::fs::read_to_string(&path).unwrap();
    sim::Scenario::from_toml(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The `.toml` files of `scenarios/<sub>`, as paths relative to `scenarios/`, sorted.
fn toml_names(sub: &str) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(scenarios_dir().join(sub))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".toml"))
        .map(|n| PathBuf::from(sub).join(n).to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn every_shipped_scenario_is_valid() {
    let names = toml_names("");
    assert!(names.len() >= 7, "{names:?}");
    for name in &names {
        let s = read(name);
        assert!(s.frame_count() > 0, "{name}");
    }
}

#[test]
fn every_held_out_scenario_is_valid_and_draws_its_route() {
    let names = toml_names("held-out");
    assert!(names.len() >= 6, "{names:?}");
    for name in &names {
        let s = read(name);
        assert!(s.frame_count() > 0, "{name}");
        // A route from the seed: nothing in the file was placed by hand.
        assert!(s.ego.waypoints.is_empty(), "{name}");
    }
}

#[test]
fn error_scenarios_differ_from_their_base_only_by_their_error() {
    let base = read("helsinki-short.toml");
    let noisy = read("helsinki-short-pose-noise.toml");
    assert_eq!(noisy.errors.pose_sigma_m, 0.1);
    assert_eq!(noisy.errors.pose_sigma_heading_deg, 0.2);
    let shifted = read("helsinki-short-map-offset.toml");
    let offset = shifted.errors.map_offset_m;
    let norm = offset[0].hypot(offset[1]);
    assert!((0.5..=1.0).contains(&norm), "{offset:?}");
    for mut s in [noisy, shifted] {
        s.errors = base.errors.clone();
        assert_eq!(s, base);
    }
}

#[test]
fn every_family_scenario_is_valid_draws_its_route_and_carries_its_family() {
    let names = toml_names("families");
    // Seven families, one drive per set, six more tuning drives of `pose-offset`, and six
    // tuning drives of `random` and `crawl`.
    assert_eq!(names.len(), 33, "{names:?}");
    let mut seeds = std::collections::BTreeMap::new();
    for name in &names {
        let s = read(name);
        // A drive of one set never reuses another's seed (its route and traffic).
        if let Some(other) = seeds.insert(s.seed, name) {
            panic!("{name} and {other} share seed {}", s.seed);
        }
        assert!(s.frame_count() > 0, "{name}");
        assert!(s.ego.waypoints.is_empty(), "{name}");
        let file = name.trim_start_matches("families/");
        let (t, e) = (&s.traffic, &s.errors);
        let offset = e.map_offset_m[0].hypot(e.map_offset_m[1]);
        if file.starts_with("dense360-") {
            assert_eq!((t.moving_cars, t.pedestrians), (40, 60), "{name}");
            assert_eq!(s.sensor.dropout_probability, 0.05, "{name}");
            assert_eq!(
                s.sensor.kind,
                sim::scenario::ScannerKind::Multibeam,
                "{name}"
            );
        } else if file.starts_with("crawl-") {
            assert_eq!(t.car_speed_mps, [1.5, 4.0], "{name}");
        } else if file.starts_with("fast-") {
            assert_eq!(s.ego.speed_mps, 14.0, "{name}");
            assert_eq!(t.car_speed_mps, [12.0, 20.0], "{name}");
        } else if file.starts_with("pose-noise-0.1-") {
            assert_eq!(
                (e.pose_sigma_m, e.pose_sigma_heading_deg),
                (0.1, 0.2),
                "{name}"
            );
            assert_eq!(offset, 0.0, "{name}");
        } else if file.starts_with("pose-noise-0.2-") {
            assert_eq!(
                (e.pose_sigma_m, e.pose_sigma_heading_deg),
                (0.2, 0.5),
                "{name}"
            );
            assert_eq!(offset, 0.0, "{name}");
        } else if file.starts_with("pose-offset-") {
            assert_eq!(
                (e.pose_sigma_m, e.pose_sigma_heading_deg),
                (0.2, 0.5),
                "{name}"
            );
            assert!((offset - 0.85).abs() < 0.01, "{name}: {offset}");
        } else if file.starts_with("large-") {
            assert_eq!((t.bus_share, t.truck_share), (0.1, 0.1), "{name}");
            assert_eq!(t.moving_cars, 25, "{name}");
        } else if file.starts_with("random-") {
            assert_eq!(t.car_speed_mps, [7.0, 13.0], "{name}");
        } else {
            panic!("{name}: no family");
        }
    }
}
