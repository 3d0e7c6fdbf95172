//! Where the `evigrid` variant's in-view moving errors come from, by kind of cell.
//!
//! ```text
//! cargo run --release -p evigrid-eval --example diagnose_moving -- MAP SCENARIO.toml [SEEDS] [CONFIG.toml]
//! ```
//! For every frame and every cell the scan observed (the in-view mask), a false M (truth F, I,
//! U or S decided M) and a missed M (truth M decided otherwise) are counted by what the scan
//! saw in the cell now (a return, or a ray through it), whether a truth-M cell is among its
//! 8 neighbours (partial cover of an object), and whether the motion stage gave the cell a
//! velocity this frame; the hits (truth M decided M) are counted too ("hit M"), so that moving
//! IoU and dynamic accuracy can be read off. A false M in the band (cells an object covers in
//! part, not at their centre: truth F under issue 30's centre rule, and scored so) is listed
//! as truth "band (F)". SEEDS is a comma-separated list (default:
//! the scenario's seed and the next, as `evigrid eval --seeds 2`).

mod common;

use std::collections::BTreeMap;

use eval::{Variant, evaluate_observed};
use evigrid::Label;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let common::Inputs {
        map,
        scenario,
        seeds,
        config,
    } = common::inputs("diagnose_moving")?;
    let detail = std::env::var_os("DIAGNOSE_DETAIL").is_some();
    let mut counts: BTreeMap<String, u64> = BTreeMap::new();
    evaluate_observed(
        &map,
        &scenario,
        &[Variant::Evigrid],
        &seeds,
        &config,
        &mut |_| {},
        &mut |f| {
            let window = f.front_end.window();
            let sensor = f.front_end.sensor_grid();
            let decisions = f.fusion.decisions();
            let velocity = f.fusion.motion().map(|m| m.velocity_east());
            let speed_north = f.fusion.motion().map(|m| m.velocity_north());
            let (m_free, m_occupied) = (sensor.m_free(), sensor.m_occupied());
            let states: std::collections::HashMap<u32, evigrid::motion::CellReport> = f
                .fusion
                .motion()
                .map(|m| m.cell_states().iter().map(|r| (r.idx, *r)).collect())
                .unwrap_or_default();
            for idx in 0..window.len() {
                let seen = if m_occupied[idx] > 0.0 {
                    "return"
                } else if m_free[idx] > 0.0 {
                    "ray"
                } else {
                    continue;
                };
                let truth = f.truth[idx];
                let decided = decisions[idx];
                let false_moving = decided == Label::M
                    && matches!(truth, Label::F | Label::I | Label::U | Label::S);
                let missed = truth == Label::M && decided != Label::M;
                if truth == Label::M && decided == Label::M {
                    // The hits, so that moving IoU and dynamic accuracy can be read off.
                    *counts.entry("hit M".to_owned()).or_default() += 1;
                }
                if !false_moving && !missed {
                    continue;
                }
                let Some(cell) = window.cell_of_storage(idx) else {
                    continue;
                };
                let beside_moving = (-1..=1).any(|dr| {
                    (-1..=1).any(|dc| {
                        (dr, dc) != (0, 0)
                            && window
                                .storage_index(cell.col + dc, cell.row + dr)
                                .is_some_and(|n| f.truth[n] == Label::M)
                    })
                });
                let has_velocity = velocity.is_some_and(|v| v[idx] != 0.0)
                    || speed_north.is_some_and(|v| v[idx] != 0.0);
                // The band (an object covers the cell in part, not at its centre) is truth F,
                // and scored so: say which F it is.
                let truth_name = if f.outline.get(idx) == Some(&true) {
                    "band (F)".to_owned()
                } else {
                    format!("{truth:?}")
                };
                let key = if false_moving {
                    format!(
                        "false M  truth {truth_name} | {seen} | {} | {} | {}",
                        states
                            .get(&(idx as u32))
                            .map_or("-".to_owned(), |s| format!("{:?}", s.state)),
                        if beside_moving { "beside M" } else { "apart" },
                        if has_velocity {
                            "velocity"
                        } else {
                            "no velocity"
                        }
                    )
                } else {
                    format!(
                        "missed M decided {:?} | {seen} | {} | {}",
                        decided,
                        if has_velocity {
                            "velocity"
                        } else {
                            "no velocity"
                        },
                        states
                            .get(&(idx as u32))
                            .map_or("-".to_owned(), |s| if detail {
                                format!(
                                    "{:?} n{} f{} m{} v{:.1} s{:.1} age{:.1}",
                                    s.state,
                                    s.cluster_cells.min(9),
                                    s.frames,
                                    s.measurements.min(9),
                                    s.speed_mps,
                                    s.sigma_mps,
                                    s.track_age_s.min(1.0)
                                )
                            } else {
                                format!("{:?}", s.state)
                            })
                    )
                };
                *counts.entry(key).or_default() += 1;
            }
        },
    )?;
    for (key, n) in &counts {
        println!("{n:>7}  {key}");
    }
    Ok(())
}
