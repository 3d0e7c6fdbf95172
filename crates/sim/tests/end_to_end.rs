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

/// The ego drives like a car: its heading changes by at most `v·dt / 5 m` a frame (a 5 m
/// turning radius, the bound `scenarios/README.md` states) and its IBEO, 3.7 m ahead of its
/// centre, moves by at most `v·dt·√(1 + (3.7 / 5)²)`, the speed of a point 3.7 m ahead of a car
/// on its tightest turn. Before the fix the pose took the heading of the lane polyline's segment,
/// so at every map vertex the heading stepped at once (45–66° at street corners) and the sensor
/// jumped 2.7–4.2 m in one frame of 0.8 m of travel: 14 such jumps over 1.5 m on
/// `helsinki-short`'s two seeds.
#[test]
fn the_ego_turns_corners_with_a_bounded_yaw_rate() -> Result<(), Box<dyn std::error::Error>> {
    const MIN_RADIUS_M: f64 = 5.0;
    let Some(map) = load("data/osm/helsinki-centre.osm.pbf") else {
        return Ok(());
    };
    let scenarios = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios");
    let base = Scenario::from_toml(&std::fs::read_to_string(
        scenarios.join("helsinki-short.toml"),
    )?)?;
    let mount_m = base.sensor.mount_forward();
    assert!((mount_m - 3.7).abs() < 1e-9, "{mount_m}");
    let sensor_factor = (1.0 + (mount_m / MIN_RADIUS_M).powi(2)).sqrt();
    let mut turned_rad = 0.0;
    for seed in [base.seed, base.seed.wrapping_add(1)] {
        let scenario = Scenario {
            seed,
            ..base.clone()
        };
        let mut drive = Drive::new(&map, &scenario)?;
        let dt = drive.dt_s();
        let mut previous: Option<(sim::geometry::Pose2, sim::geometry::Pose2)> = None;
        while let Some(frame) = drive.next_frame() {
            let ego = drive.ego_pose();
            let sensor = frame.scan.world_from_sensor_true;
            let speed = drive.actors()[drive.ego_id() as usize].speed_mps;
            if let Some((ego_before, sensor_before)) = previous {
                let step = speed * dt;
                let turn = sim::geometry::wrap_angle(ego.heading_rad - ego_before.heading_rad);
                turned_rad += turn.abs();
                assert!(
                    turn.abs() <= step / MIN_RADIUS_M + 1e-9,
                    "seed {seed} frame {}: heading step {:.1}° at {speed:.2} m/s",
                    frame.index,
                    turn.to_degrees()
                );
                let moved = sensor.position_m.minus(sensor_before.position_m).norm();
                assert!(
                    moved <= step * sensor_factor + 1e-6,
                    "seed {seed} frame {}: the sensor moved {moved:.2} m at {speed:.2} m/s",
                    frame.index
                );
            }
            previous = Some((ego, sensor));
        }
    }
    // The drives do turn (the corner near y ≈ −495 m; seed 11's ego, yielding to a car that
    // turns in ahead of it, reaches it only after the drive's end): the test is not of a
    // straight line.
    assert!(turned_rad > 1.0, "turned {turned_rad} rad");
    Ok(())
}

/// Every driving actor, the other cars as well as the ego, turns by at most `v·dt / 5 m` a
/// frame and moves by at most `v·dt`, also where a car's route ends and it takes the next. Before
/// the fix, besides every street corner, on `held-out/helsinki-random` seed 82 two cars at the
/// ends of short routes took new ones back the way they came, turning 164–180° and jumping
/// 2.9–3.6 m in one frame, 26 times in 12 s; and a car stopping at its route's end went from
/// 12 m/s to standing in one frame.
#[test]
fn every_car_turns_with_a_bounded_yaw_rate() -> Result<(), Box<dyn std::error::Error>> {
    const MIN_RADIUS_M: f64 = 5.0;
    let scenarios = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios");
    for (file, name) in [
        (
            "data/osm/helsinki-centre.osm.pbf",
            "held-out/helsinki-random.toml",
        ),
        ("data/osm/kouvola.osm.pbf", "kouvola-residential.toml"),
        ("data/osm/monaco.osm.gz", "families/dense360-monaco.toml"),
    ] {
        let Some(map) = load(file) else { continue };
        let base = Scenario::from_toml(&std::fs::read_to_string(scenarios.join(name))?)?;
        for seed in [base.seed, base.seed.wrapping_add(1)] {
            let scenario = Scenario {
                seed,
                ..base.clone()
            };
            let mut drive = Drive::new(&map, &scenario)?;
            let dt = drive.dt_s();
            let mut previous: Vec<sim::geometry::Pose2> = Vec::new();
            while let Some(frame) = drive.next_frame() {
                for (a, before) in drive.actors().iter().zip(&previous) {
                    if !matches!(a.motion, sim::actors::Motion::Driving(_)) {
                        continue;
                    }
                    let step = a.speed_mps * dt;
                    let turn = sim::geometry::wrap_angle(a.pose.heading_rad - before.heading_rad);
                    let moved = a.pose.position_m.minus(before.position_m).norm();
                    assert!(
                        // To a micrometre: an arc of a kilometre's radius and the line after it
                        // meet to within nanometres.
                        turn.abs() <= step / MIN_RADIUS_M + 1e-9 && moved <= step + 1e-6,
                        "{name} seed {seed} frame {} car {}: turned {:.1}°, moved {moved:.6} m \
                         at {:.6} m/s, over by {:e}",
                        frame.index,
                        a.id,
                        turn.to_degrees(),
                        a.speed_mps,
                        moved - step
                    );
                }
                previous = drive.actors().iter().map(|a| a.pose).collect();
            }
        }
    }
    Ok(())
}
