//! End-to-end: simulated drives on real OpenStreetMap extracts.

use geodata::testdata::shared_file;
use sim::{Drive, Scenario};

fn load(relative: &str) -> Option<geodata::LocalMap> {
    let path = shared_file(relative)?;
    match geodata::load_map(&path, &geodata::LoadOptions::default()) {
        Ok(loaded) => Some(loaded.map),
        Err(e) => panic!("cannot load {}: {e}", path.display()),
    }
}

#[test]
fn drives_on_every_shared_map_are_deterministic() -> Result<(), Box<dyn std::error::Error>> {
    for file in ["data/osm/bavarian-village.osm", "data/osm/monaco.osm.gz"] {
        let Some(map) = load(file) else { continue };
        let s = Scenario {
            duration_s: 1.0,
            ..Scenario::default()
        };
        let run = || -> Result<Vec<sim::Frame>, sim::SimError> {
            let mut d = Drive::new(&map, &s)?;
            Ok(std::iter::from_fn(|| d.next_frame()).collect())
        };
        let a = run()?;
        assert_eq!(a.len(), 10);
        assert!(
            a.iter().all(|f| !f.scan.points_in_sensor.is_empty()),
            "{file}: empty scan"
        );
        assert_eq!(a, run()?);
    }
    Ok(())
}

/// The sensor never sits inside another road user: truth would count that object, which the
/// sensor cannot see from inside. Before the fix, on `kouvola-residential` a car started just
/// ahead of the ego over its sensor (seed 31, frame 0) and one on the ego itself (seed 32: the
/// sensor inside it for frames 1–5); on `monaco-condamine` (seed 51) the ego, its IBEO 3.7 m
/// ahead of its centre, queued behind a parked car with the sensor inside it for its last 21
/// frames.
#[test]
fn the_sensor_is_never_inside_another_actor() -> Result<(), Box<dyn std::error::Error>> {
    let scenarios = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios");
    for (file, name) in [
        ("data/osm/kouvola.osm.pbf", "kouvola-residential.toml"),
        ("data/osm/monaco.osm.gz", "monaco-condamine.toml"),
    ] {
        let Some(map) = load(file) else { continue };
        let base = Scenario::from_toml(&std::fs::read_to_string(scenarios.join(name))?)?;
        // The seeds `evigrid eval --seeds 2` drives: the scenario's and the next.
        for seed in [base.seed, base.seed.wrapping_add(1)] {
            let scenario = Scenario {
                seed,
                ..base.clone()
            };
            let mut drive = Drive::new(&map, &scenario)?;
            while let Some(frame) = drive.next_frame() {
                let sensor = frame.scan.world_from_sensor_true.position_m;
                for a in drive.actors() {
                    assert!(
                        a.id == drive.ego_id() || !a.footprint.contains(&a.pose, sensor),
                        "{name} seed {seed} frame {}: the sensor is inside actor {}",
                        frame.index,
                        a.id
                    );
                }
            }
        }
    }
    Ok(())
}
