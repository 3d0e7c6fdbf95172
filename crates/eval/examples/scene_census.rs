//! What a simulated drive's scene is, in a few numbers that change when the scene changes: the
//! ego's route and the actors placed, and how often a road user is inside a building.
//!
//! ```text
//! cargo run --release -p evigrid-eval --example scene_census -- MAP SCENARIO.toml [SEEDS]
//! ```
//! One line per seed: the ego's lane (its length and a hash of it: the same hash, the same
//! route), its start and end (metres, local frame) and the distance it drove;
//! a hash of every actor's kind and starting position (two runs with the same hash placed the
//! same actors); the actors by kind; and, over every frame, the frames in which the ego, a
//! moving car or a pedestrian stands with its centre inside a building of the world, out of the
//! frames of each (a road user in a building is hidden from the scanner by the façade).
//! With `CENSUS_WHERE` set, every actor-frame inside a building is listed with the building's
//! bounds. Written to compare scenes before and after a change to the world (issue 30, tunnels).

mod common;

use sim::actors::{ActorKind, Motion};
use sim::{Drive, Scenario};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let common::Inputs {
        map,
        scenario,
        seeds,
        config: _parameters_unused,
    } = common::inputs("scene_census")?;
    for seed in seeds {
        let scenario = Scenario {
            seed,
            ..scenario.clone()
        };
        census(&map, &scenario)?;
    }
    Ok(())
}

/// Prints the census line of one seed.
fn census(map: &geodata::LocalMap, scenario: &Scenario) -> Result<(), Box<dyn std::error::Error>> {
    let mut drive = Drive::new(map, scenario)?;
    let ego = drive.ego_id() as usize;
    let start = drive.ego_pose().position_m;
    // The ego's lane, sampled every metre: the same route gives the same samples.
    let lane = drive.actors()[ego].lane_samples(1.0);
    let mut lane_hash: u64 = 0xcbf2_9ce4_8422_2325;
    for p in &lane {
        for byte in format!("{:.1} {:.1}", p.x, p.y).bytes() {
            lane_hash = (lane_hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    let mut kinds = std::collections::BTreeMap::new();
    for actor in drive.actors() {
        let p = actor.pose.position_m;
        let key = format!("{:?} {:.1} {:.1}", actor.kind, p.x, p.y);
        for byte in key.bytes() {
            hash = (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3);
        }
        *kinds.entry(format!("{:?}", actor.kind)).or_insert(0) += 1;
    }
    // [ego, moving car, pedestrian]: (frames inside a building, frames).
    let mut inside = [(0u64, 0u64); 3];
    let mut driven = 0.0;
    let mut last = start;
    let where_inside = std::env::var_os("CENSUS_WHERE").is_some();
    while let Some(frame) = drive.next_frame().map(|f| f.index) {
        let world = drive.world();
        for (id, actor) in drive.actors().iter().enumerate() {
            let class = match (&actor.motion, actor.kind) {
                _ if id == ego => 0,
                (Motion::Driving(_), ActorKind::Car) => 1,
                (Motion::Walking(_), ActorKind::Pedestrian) => 2,
                _ => continue,
            };
            let p = actor.pose.position_m;
            let building = world.building_at(p);
            if let (Some(b), true) = (building, where_inside) {
                let (lo, hi) = world.buildings()[b as usize].bounds;
                println!(
                    "  frame {frame} actor {id} at ({:.1}, {:.1}) in building {b} ({:.1}, {:.1})..({:.1}, {:.1})",
                    p.x, p.y, lo.x, lo.y, hi.x, hi.y
                );
            }
            inside[class].0 += u64::from(building.is_some());
            inside[class].1 += 1;
        }
        let now = drive.ego_pose().position_m;
        driven += now.minus(last).norm();
        last = now;
    }
    println!(
        "seed {} ego lane {} m {:016x}, ({:.1}, {:.1}) -> ({:.1}, {:.1}) {:.0} m; actors {:016x} {:?}; in buildings: ego {}/{} cars {}/{} pedestrians {}/{}",
        scenario.seed,
        lane.len(),
        lane_hash,
        start.x,
        start.y,
        last.x,
        last.y,
        driven,
        hash,
        kinds,
        inside[0].0,
        inside[0].1,
        inside[1].0,
        inside[1].1,
        inside[2].0,
        inside[2].1
    );
    Ok(())
}
