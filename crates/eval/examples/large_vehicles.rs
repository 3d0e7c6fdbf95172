//! How the `evigrid` variant scores the large vehicles (buses and trucks,
//! `sim::actors::is_large_vehicle`) of a drive, beside the compact cars.
//!
//! ```text
//! cargo run --release -p evigrid-eval --example large_vehicles -- MAP SCENARIO.toml [SEEDS] [CONFIG.toml]
//! ```
//! For every frame and every cell the scan observed (a return or a ray through it, as
//! `diagnose_moving` counts), a truth-M cell is a large vehicle's when its centre lies in a bus's
//! or truck's body, a car's otherwise; it is a hit when decided M, a miss otherwise. A false M
//! (truth F, I, U or S, or the band, decided M) is a large vehicle's when its centre lies within
//! [`NEAR_M`] of a large vehicle's body. Printed per kind: hits, misses, false M, moving IoU
//! (hits / (hits + misses + false M)) and recall, and how many of the large vehicles' truth-M
//! cells the motion stage reported `TooLarge` (the `moving_max_extent_m` rule). SEEDS as for
//! `diagnose_moving`. A second drive of the same scenario and seed runs beside the evaluated
//! one, frame for frame, for the actors' poses (a drive is a function of its scenario).

mod common;

use eval::{Variant, evaluate_observed};
use evigrid::Label;
use evigrid::motion::CellMotion;
use sim::actors::{Actor, is_large_vehicle};
use sim::geometry::{Footprint, Vec2};

/// How far from a large vehicle's body a false M counts as its, metres.
const NEAR_M: f64 = 1.0;

/// Counts of one kind of vehicle.
#[derive(Default)]
struct Tally {
    hits: u64,
    misses: u64,
    false_m: u64,
    too_large: u64,
}

impl Tally {
    fn print(&self, name: &str) {
        let iou = self.hits as f64 / (self.hits + self.misses + self.false_m).max(1) as f64;
        let recall = self.hits as f64 / (self.hits + self.misses).max(1) as f64;
        println!(
            "{name:6} hits {:6} misses {:6} false M {:6} | moving IoU {iou:.4} recall {recall:.4} | TooLarge {}",
            self.hits, self.misses, self.false_m, self.too_large
        );
    }
}

/// Whether `p` lies within `grow_m` of `actor`'s rectangle.
fn near(actor: &Actor, p: Vec2, grow_m: f64) -> bool {
    let Footprint::Rect {
        half_length_m,
        half_width_m,
    } = actor.footprint
    else {
        return false;
    };
    let grown = Footprint::Rect {
        half_length_m: half_length_m + grow_m,
        half_width_m: half_width_m + grow_m,
    };
    grown.contains(&actor.pose, p)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let common::Inputs {
        map,
        scenario,
        seeds,
        config,
    } = common::inputs("large_vehicles")?;
    let (mut large, mut cars) = (Tally::default(), Tally::default());
    let mut large_ids = std::collections::BTreeSet::new();
    let mut twin: Option<sim::Drive> = None;
    let mut twin_frame = 0usize;
    evaluate_observed(
        &map,
        &scenario,
        &[Variant::Evigrid],
        &seeds,
        &config,
        &mut |_| {},
        &mut |f| {
            if f.frame == 0 {
                let s = sim::Scenario {
                    seed: seeds[f.seed_index],
                    ..scenario.clone()
                };
                twin = sim::Drive::new(&map, &s).ok();
                twin_frame = 0;
            }
            let Some(drive) = twin.as_mut() else { return };
            while twin_frame <= f.frame {
                if drive.next_frame().is_none() {
                    return;
                }
                twin_frame += 1;
            }
            let buses: Vec<&Actor> = drive
                .actors()
                .iter()
                .filter(|a| is_large_vehicle(a))
                .collect();
            large_ids.extend(buses.iter().map(|a| (f.seed_index, a.id)));
            let window = f.front_end.window();
            let sensor = f.front_end.sensor_grid();
            let (m_free, m_occupied) = (sensor.m_free(), sensor.m_occupied());
            let decisions = f.fusion.decisions();
            let cell_m = window.cell_size_m();
            let too_large: std::collections::HashSet<u32> = f
                .fusion
                .motion()
                .map(|m| {
                    m.cell_states()
                        .iter()
                        .filter(|r| r.state == CellMotion::TooLarge)
                        .map(|r| r.idx)
                        .collect()
                })
                .unwrap_or_default();
            for idx in 0..window.len() {
                if m_occupied[idx] <= 0.0 && m_free[idx] <= 0.0 {
                    continue;
                }
                let Some(cell) = window.cell_of_storage(idx) else {
                    continue;
                };
                let centre = Vec2::new(
                    (cell.col as f64 + 0.5) * cell_m,
                    (cell.row as f64 + 0.5) * cell_m,
                );
                let (truth, decided) = (f.truth[idx], decisions[idx]);
                if truth == Label::M {
                    let tally = if buses.iter().any(|a| near(a, centre, 0.0)) {
                        &mut large
                    } else {
                        &mut cars
                    };
                    if decided == Label::M {
                        tally.hits += 1;
                    } else {
                        tally.misses += 1;
                    }
                    tally.too_large += u64::from(too_large.contains(&(idx as u32)));
                } else if decided == Label::M
                    && matches!(truth, Label::F | Label::I | Label::U | Label::S)
                {
                    if buses.iter().any(|a| near(a, centre, NEAR_M)) {
                        large.false_m += 1;
                    } else {
                        cars.false_m += 1;
                    }
                }
            }
        },
    )?;
    println!(
        "large vehicles seen over the seeds: {} (buses and trucks placed)",
        large_ids.len()
    );
    large.print("large");
    cars.print("other");
    Ok(())
}
