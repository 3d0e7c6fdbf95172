//! Where the `evigrid` variant's occupied-static accuracy falls under `kurdej2013`'s: the
//! truth I, U and S cells in view that one variant decides M and the other does not, cell by
//! cell on the same frames, by truth and cause.
//!
//! ```text
//! cargo run --release -p evigrid-eval --example occupied_static_vs_kurdej -- MAP SCENARIO.toml [SEEDS] [CONFIG.toml]
//! ```
//! Both variants run on one front end (as `evigrid eval --variants evigrid,kurdej2013`). For
//! each frame and each cell in view whose truth is I, U or S, a cell `evigrid` decides M and
//! `kurdej2013` does not is counted under "evigrid only", with: its truth; what the motion
//! stage made of it this frame (`CellMotion`, or `-`: not a labelled cluster cell, so the
//! SPEC §5 step's decision); how many frames back the stage last gave it moving evidence
//! (`Moving` or `EnteredSeenFree`: "Mev now", "Mev k back", "Mev never" within the seed);
//! how many frames back within ten its truth was last M (a road user that just stopped); and
//! how many frames back the placed grid last saw it free ("free k back"), how many frames in a
//! row it has been occupied there ("occ run"). A cell `kurdej2013` decides M and `evigrid`
//! does not is counted under "kurdej only" with its truth and `evigrid`'s decision. The in-view
//! I/U/S totals and both variants' M among them are printed first: occupied-static accuracy of
//! each is 1 − M / total. SEEDS as in `diagnose_moving`. With `OCC_LIST` set, each
//! "evigrid only" cell-frame is also printed on stderr with its position and cluster.

mod common;

use std::collections::BTreeMap;

use eval::{Variant, evaluate_observed};
use evigrid::Label;
use evigrid::motion::CellMotion;

/// Frames back within which a cell's truth M counts as "just stopped".
const STOPPED_FRAMES: usize = 10;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let common::Inputs {
        map,
        scenario,
        seeds,
        config,
    } = common::inputs("occupied_static_vs_kurdej")?;
    let list = std::env::var_os("OCC_LIST").is_some();
    let mut counts: BTreeMap<String, u64> = BTreeMap::new();
    // `kurdej2013`'s decisions this frame (it runs first).
    let mut kurdej: Vec<Label> = Vec::new();
    // Per cell: the frame it last took moving evidence, last was truth M, last was seen free
    // in the placed grid, and since which frame it has been occupied there without a break.
    let mut last_evidence: Vec<Option<usize>> = Vec::new();
    let mut last_truth_m: Vec<Option<usize>> = Vec::new();
    let mut last_free: Vec<Option<usize>> = Vec::new();
    let mut occupied_since: Vec<Option<usize>> = Vec::new();
    evaluate_observed(
        &map,
        &scenario,
        &[Variant::Kurdej2013, Variant::Evigrid],
        &seeds,
        &config,
        &mut |_| {},
        &mut |f| {
            let decisions = f.fusion.decisions();
            if f.variant == Variant::Kurdej2013 {
                kurdej.clear();
                kurdej.extend_from_slice(decisions);
                return;
            }
            let window = f.front_end.window();
            let len = window.len();
            if f.frame == 0 || last_evidence.len() != len {
                last_evidence = vec![None; len];
                last_truth_m = vec![None; len];
                last_free = vec![None; len];
                occupied_since = vec![None; len];
            }
            for span in f.front_end.new_cell_spans() {
                for idx in span {
                    last_evidence[idx] = None;
                    last_truth_m[idx] = None;
                    last_free[idx] = None;
                    occupied_since[idx] = None;
                }
            }
            let sensor = f.front_end.sensor_grid();
            let placed = f.front_end.placed_sensor_grid();
            let states: std::collections::HashMap<u32, evigrid::motion::CellReport> = f
                .fusion
                .motion()
                .map(|m| m.cell_states().iter().map(|r| (r.idx, *r)).collect())
                .unwrap_or_default();
            for s in states.values() {
                if matches!(s.state, CellMotion::Moving | CellMotion::EnteredSeenFree) {
                    last_evidence[s.idx as usize] = Some(f.frame);
                }
            }
            for (since, &m) in occupied_since.iter_mut().zip(placed.m_occupied()) {
                if m > 0.0 {
                    since.get_or_insert(f.frame);
                } else {
                    *since = None;
                }
            }
            let back = |k: Option<usize>| match k {
                None => "never".to_owned(),
                Some(k) if k == f.frame => "now".to_owned(),
                Some(k) => format!("{} back", bucket(f.frame - k)),
            };
            for idx in 0..len {
                let in_view = sensor.m_occupied()[idx] > 0.0 || sensor.m_free()[idx] > 0.0;
                let truth = f.truth[idx];
                if in_view && matches!(truth, Label::I | Label::U | Label::S) {
                    *counts.entry(format!("0 total {truth:?}")).or_default() += 1;
                    let (e, k) = (decisions[idx] == Label::M, kurdej[idx] == Label::M);
                    if e {
                        *counts.entry(format!("1 evigrid M {truth:?}")).or_default() += 1;
                    }
                    if k {
                        *counts.entry(format!("1 kurdej M {truth:?}")).or_default() += 1;
                    }
                    if e && !k {
                        let state = states
                            .get(&(idx as u32))
                            .map_or("-".to_owned(), |s| format!("{:?}", s.state));
                        let stopped = match last_truth_m[idx] {
                            Some(k) if f.frame - k <= STOPPED_FRAMES => {
                                format!("M {} back", f.frame - k)
                            }
                            _ => "not M lately".to_owned(),
                        };
                        let run = occupied_since[idx].map_or(0, |s| f.frame - s + 1);
                        let key = format!(
                            "2 evigrid only | {truth:?} | {state} | Mev {} | {stopped} | free {} | occ run {} | kurdej {:?}",
                            back(last_evidence[idx]),
                            back(last_free[idx]),
                            bucket(run),
                            kurdej[idx],
                        );
                        *counts.entry(key).or_default() += 1;
                        if list {
                            let cell = window.cell_of_storage(idx);
                            eprintln!(
                                "OCC seed {} frame {} cell {:?} truth {truth:?} {:?}",
                                f.seed_index,
                                f.frame,
                                cell.map(|c| window.cell_centre(c.col, c.row)),
                                states.get(&(idx as u32)),
                            );
                        }
                    }
                    if k && !e {
                        *counts
                            .entry(format!(
                                "3 kurdej only | {truth:?} | evigrid {:?}",
                                decisions[idx]
                            ))
                            .or_default() += 1;
                    }
                }
            }
            for idx in 0..len {
                if f.truth[idx] == Label::M {
                    last_truth_m[idx] = Some(f.frame);
                }
                if placed.m_free()[idx] > 0.0 {
                    last_free[idx] = Some(f.frame);
                }
            }
        },
    )?;
    for (key, n) in &counts {
        println!("{n:>7}  {key}");
    }
    Ok(())
}

/// Frames in coarse buckets: 0, 1, 2, 3-5, 6-10, 11-20, > 20.
fn bucket(n: usize) -> &'static str {
    match n {
        0 => "0",
        1 => "1",
        2 => "2",
        3..=5 => "3-5",
        6..=10 => "6-10",
        11..=20 => "11-20",
        _ => ">20",
    }
}
