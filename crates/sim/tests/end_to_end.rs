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
