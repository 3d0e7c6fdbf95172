//! End-to-end: simulated drives on a real OpenStreetMap extract, every variant scored.

use eval::{EvalConfig, Variant, evaluate};
use geodata::testdata::shared_file;
use sim::Scenario;

fn load(relative: &str) -> Option<geodata::LocalMap> {
    let path = shared_file(relative)?;
    match geodata::load_map(&path, &geodata::LoadOptions::default()) {
        Ok(loaded) => Some(loaded.map),
        Err(e) => panic!("cannot load {}: {e}", path.display()),
    }
}

fn village_scenario() -> Scenario {
    let mut s = Scenario {
        duration_s: 10.0,
        ..Scenario::default()
    };
    s.traffic.moving_cars = 6;
    s.traffic.parked_cars = 8;
    s.traffic.pedestrians = 8;
    s.traffic.infrastructure = 15;
    s.ego.speed_mps = 6.0;
    s
}

#[test]
fn full_beats_no_map_on_the_bavarian_village() -> Result<(), Box<dyn std::error::Error>> {
    let Some(map) = load("data/osm/bavarian-village.osm") else {
        return Ok(());
    };
    let mut config = EvalConfig::default();
    // 100 m × 100 m: the IBEO's useful range ahead of the ego.
    config.params.window.width_cells = 200;
    config.params.window.height_cells = 200;
    let report = evaluate(
        &map,
        &village_scenario(),
        &Variant::ALL,
        &[1, 2],
        &config,
        &mut |_| {},
    )?;
    println!("{}", report.to_markdown());
    let variant = |v: Variant| {
        report
            .variants
            .iter()
            .find(|r| r.variant == v)
            .ok_or(format!("{} missing", v.name()))
    };
    let (paper, evigrid) = (variant(Variant::Kurdej2013)?, variant(Variant::Evigrid)?);
    println!("{}", serde_json::to_string(&paper.latency)?);
    let full = &paper.scores;
    let no_map = &variant(Variant::NoMap)?.scores;
    let f1 = |s: &eval::metrics::Scores| s.macro_f1.unwrap_or(0.0);
    assert!(
        f1(full) > f1(no_map),
        "full {:?} vs no-map {:?}",
        full.macro_f1,
        no_map.macro_f1
    );
    assert!(
        full.moving_iou.unwrap_or(0.0) > MOVING_IOU_FLOOR,
        "{:?}",
        full.moving_iou
    );
    let visible = paper.scores_visible.moving_iou.unwrap_or(0.0);
    assert!(visible > MOVING_IOU_VISIBLE_FLOOR, "{visible}");
    // The motion evidence finds more of the moving cells in view than the paper's method.
    let with_motion = evigrid.scores_visible.moving_iou.unwrap_or(0.0);
    assert!(
        with_motion > visible,
        "evigrid {with_motion} vs kurdej2013 {visible}"
    );
    Ok(())
}

/// Floor on the moving-class IoU of `full` over cells observed at least once. Measured 0.098 on
/// this drive (seeds 1 and 2) with evigrid's default parameters; it is low because the inside of
/// a moving car is never visible (see `eval::metrics`). Half of it: a pipeline that stops
/// deciding M, or decides it in the wrong cells, falls below; retuning the defaults does not.
const MOVING_IOU_FLOOR: f64 = 0.05;
/// Floor on the same IoU over the cells observed in each frame. Measured 0.230; half of it.
const MOVING_IOU_VISIBLE_FLOOR: f64 = 0.115;
