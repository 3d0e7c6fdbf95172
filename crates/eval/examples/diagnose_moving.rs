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
//! With `DIAGNOSE_GEOMETRY` set, each count is split further by where the cell lies: whether
//! the grid placed by the surface holds it, where the truth-M cells among its neighbours lie
//! seen along its own ray (behind it, in front of it, beside it), and how many cells nearer on
//! its ray the first return lies.
//! With `DIAGNOSE_DETAIL` set, the truth-M cells that the object layer labelled outside a
//! track's rectangle (`OutsideObject`) in one of the previous [`OUTSIDE_FRAMES`] frames are
//! also counted as hits or misses "after outside": what the outside label costs later frames.
//! With `DIAGNOSE_DETAIL`, a miss's cluster is described by its size and the share of its cells
//! that are truth M (`M75%`: 75-99 %). With `DIAGNOSE_STARTED` set, each miss says how many
//! frames back, within [`STARTED_FRAMES`], its cell was last truth S (a road user that has just
//! started), or "not S lately".
//! With `DIAGNOSE_STOPPED` set, each false M says how many frames back, within
//! [`STARTED_FRAMES`], its cell was last truth M (a road user that has just stopped), or "not M
//! lately".
//! With `DIAGNOSE_PERSIST` set, each false M says how many frames back its cell last took
//! moving evidence from the stage (`Moving` or `EnteredSeenFree`), "Mev now" this frame, or
//! "Mev never" within the seed: M kept by the fusion after the evidence went, or made by the
//! fusion step's own free→occupied conflict.
//! With `DIAGNOSE_HITS` set, the hits are also counted by what the stage made of each
//! cell ("hit M by state").
//! With `DIAGNOSE_CONTEXT` set, the truth-M cells in view are also counted as hit or missed by
//! the map context of their cell (`truth M by context`): a road user on a cell the map calls
//! building meets the prior {I}.

mod common;

use std::collections::BTreeMap;

use eval::{Variant, evaluate_observed};
use evigrid::Label;
use evigrid::motion::CellMotion;

/// Frames back in which a missed cell's truth S counts as a start (`DIAGNOSE_STARTED`).
const STARTED_FRAMES: usize = 10;

/// Frames back in which an `OutsideObject` label counts for the "after outside" tally.
const OUTSIDE_FRAMES: usize = 3;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let common::Inputs {
        map,
        scenario,
        seeds,
        config,
    } = common::inputs("diagnose_moving")?;
    let detail = std::env::var_os("DIAGNOSE_DETAIL").is_some();
    let geometry = std::env::var_os("DIAGNOSE_GEOMETRY").is_some();
    let mut counts: BTreeMap<String, u64> = BTreeMap::new();
    // The storage indices labelled `OutsideObject`, one set per frame, newest last.
    let mut outside_before: std::collections::VecDeque<std::collections::HashSet<u32>> =
        std::collections::VecDeque::new();
    let started = std::env::var_os("DIAGNOSE_STARTED").is_some();
    let stopped = std::env::var_os("DIAGNOSE_STOPPED").is_some();
    let hits_by_state = std::env::var_os("DIAGNOSE_HITS").is_some();
    let by_context = std::env::var_os("DIAGNOSE_CONTEXT").is_some();
    // The truth of the last `STARTED_FRAMES` frames of the seed, newest last
    // (`DIAGNOSE_STARTED`).
    let mut truths: std::collections::VecDeque<Vec<Label>> = std::collections::VecDeque::new();
    let persist = std::env::var_os("DIAGNOSE_PERSIST").is_some();
    // The frame at which each cell last took moving evidence (`DIAGNOSE_PERSIST`).
    let mut last_evidence: std::collections::HashMap<u32, usize> = std::collections::HashMap::new();
    evaluate_observed(
        &map,
        &scenario,
        &[Variant::Evigrid],
        &seeds,
        &config,
        &mut |_| {},
        &mut |f| {
            if f.frame == 0 {
                truths.clear();
                last_evidence.clear();
            }
            let window = f.front_end.window();
            let sensor = f.front_end.sensor_grid();
            let decisions = f.fusion.decisions();
            let velocity = f.fusion.motion().map(|m| m.velocity_east());
            let speed_north = f.fusion.motion().map(|m| m.velocity_north());
            let (m_free, m_occupied) = (sensor.m_free(), sensor.m_occupied());
            let placed = f.front_end.placed_sensor_grid().m_occupied();
            let cell_m = window.cell_size_m();
            let states: std::collections::HashMap<u32, evigrid::motion::CellReport> = f
                .fusion
                .motion()
                .map(|m| m.cell_states().iter().map(|r| (r.idx, *r)).collect())
                .unwrap_or_default();
            if persist {
                for s in states.values() {
                    if matches!(s.state, CellMotion::Moving | CellMotion::EnteredSeenFree) {
                        last_evidence.insert(s.idx, f.frame);
                    }
                }
            }
            // Per cluster: its labelled cells and how many are truth M (`DIAGNOSE_DETAIL`).
            let mut composition: std::collections::HashMap<u32, (u32, u32)> =
                std::collections::HashMap::new();
            for s in states.values() {
                let e = composition.entry(s.cluster).or_default();
                e.0 += 1;
                e.1 += u32::from(f.truth[s.idx as usize] == Label::M);
            }
            if detail {
                for idx in 0..window.len() {
                    let outside = outside_before.iter().any(|s| s.contains(&(idx as u32)));
                    if !outside || f.truth[idx] != Label::M {
                        continue;
                    }
                    if m_occupied[idx] <= 0.0 && m_free[idx] <= 0.0 {
                        continue;
                    }
                    let key = if decisions[idx] == Label::M {
                        "after outside: hit M".to_owned()
                    } else {
                        format!("after outside: missed M decided {:?}", decisions[idx])
                    };
                    *counts.entry(key).or_default() += 1;
                }
                outside_before.push_back(
                    states
                        .values()
                        .filter(|r| r.state == CellMotion::OutsideObject)
                        .map(|r| r.idx)
                        .collect(),
                );
                if outside_before.len() > OUTSIDE_FRAMES {
                    outside_before.pop_front();
                }
            }
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
                // Frames back the cell was last truth S (a stopped road user), within
                // `STARTED_FRAMES` (`DIAGNOSE_STARTED`): a car that has just started.
                let was_stopped = truths
                    .iter()
                    .rev()
                    .position(|t| t.get(idx) == Some(&Label::S));
                let false_moving = decided == Label::M
                    && matches!(truth, Label::F | Label::I | Label::U | Label::S);
                let missed = truth == Label::M && decided != Label::M;
                if truth == Label::M && decided == Label::M {
                    // The hits, so that moving IoU and dynamic accuracy can be read off.
                    let key = match states.get(&(idx as u32)) {
                        Some(s) if persist => format!(
                            "hit M | {:?} m{} v{:.0}",
                            s.state,
                            s.measurements.min(9),
                            s.speed_mps
                        ),
                        None if persist => "hit M | -".to_owned(),
                        _ => "hit M".to_owned(),
                    };
                    *counts.entry(key).or_default() += 1;
                    if hits_by_state {
                        let state = states
                            .get(&(idx as u32))
                            .map_or("-".to_owned(), |s| format!("{:?}", s.state));
                        *counts.entry(format!("hit M by state {state}")).or_default() += 1;
                    }
                }
                if by_context && truth == Label::M {
                    // Truth M by the map's context of its cell: a road user where the map
                    // says building (a road under a building) has prior {I} against it.
                    let outcome = if decided == Label::M { "hit" } else { "missed" };
                    let context = f
                        .front_end
                        .gis()
                        .context
                        .get(idx)
                        .map_or("-".to_owned(), |c| format!("{c:?}"));
                    *counts
                        .entry(format!("truth M by context {context}: {outcome}"))
                        .or_default() += 1;
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
                            .map_or("-".to_owned(), |s| if detail {
                                format!(
                                    "{:?} n{} f{} m{} v{:.0} s{:.1}",
                                    s.state,
                                    s.cluster_cells.min(9),
                                    s.frames,
                                    s.measurements.min(9),
                                    s.speed_mps,
                                    s.sigma_mps,
                                )
                            } else {
                                format!("{:?}", s.state)
                            }),
                        if beside_moving { "beside M" } else { "apart" },
                        if has_velocity {
                            "velocity"
                        } else {
                            "no velocity"
                        }
                    )
                } else {
                    format!(
                        "missed M decided {:?} | {seen} | {} | {}{}",
                        decided,
                        if has_velocity {
                            "velocity"
                        } else {
                            "no velocity"
                        },
                        states
                            .get(&(idx as u32))
                            .map_or("-".to_owned(), |s| if detail {
                                let (n, m) = composition.get(&s.cluster).copied().unwrap_or((0, 0));
                                format!(
                                    "{:?} n{} M{}% f{} m{} v{:.1} s{:.1} age{:.1}",
                                    s.state,
                                    bucket(n),
                                    (100 * m / n.max(1)) / 25 * 25,
                                    s.frames,
                                    s.measurements.min(9),
                                    s.speed_mps,
                                    s.sigma_mps,
                                    s.track_age_s.min(1.0)
                                )
                            } else {
                                format!("{:?}", s.state)
                            }),
                        match (started, was_stopped) {
                            (false, _) => String::new(),
                            (true, None) => " | not S lately".to_owned(),
                            (true, Some(k)) => format!(" | S {} frames back", k + 1),
                        }
                    )
                };
                if persist
                    && false_moving
                    && std::env::var_os("DIAGNOSE_LIST").is_some()
                    && let Some(s) = states.get(&(idx as u32))
                {
                    eprintln!(
                        "LIST frame {} at {:?} cluster {} {:?} n{} f{} m{} v{:.1} s{:.1} age{:.1} truth {:?}",
                        f.frame,
                        window.cell_centre(cell.col, cell.row),
                        s.cluster,
                        s.state,
                        s.cluster_cells,
                        s.frames,
                        s.measurements,
                        s.speed_mps,
                        s.sigma_mps,
                        s.track_age_s,
                        truth
                    );
                }
                // Frames back the cell was last truth M, within `STARTED_FRAMES`
                // (`DIAGNOSE_STOPPED`): a road user that has just stopped.
                let key = if stopped && false_moving {
                    match truths
                        .iter()
                        .rev()
                        .position(|t| t.get(idx) == Some(&Label::M))
                    {
                        None => format!("{key} | not M lately"),
                        Some(k) => format!("{key} | M {} frames back", k + 1),
                    }
                } else {
                    key
                };
                let key = if persist && false_moving {
                    let back = match last_evidence.get(&(idx as u32)) {
                        None => "Mev never".to_owned(),
                        Some(&k) if k == f.frame => "Mev now".to_owned(),
                        Some(&k) => format!("Mev {} back", bucket((f.frame - k) as u32)),
                    };
                    format!("{key} | {back}")
                } else {
                    key
                };
                let key = if geometry {
                    let centre = [
                        (cell.col as f64 + 0.5) * cell_m,
                        (cell.row as f64 + 0.5) * cell_m,
                    ];
                    format!(
                        "{} || {}",
                        key,
                        where_on_its_ray(
                            &|c, r| window.storage_index(c, r),
                            f.truth,
                            m_occupied,
                            placed,
                            idx,
                            centre,
                            f.ego_position,
                            cell_m,
                        )
                    )
                } else {
                    key
                };
                *counts.entry(key).or_default() += 1;
            }
            if started || stopped {
                truths.push_back(f.truth.to_vec());
                if truths.len() > STARTED_FRAMES {
                    truths.pop_front();
                }
            }
        },
    )?;
    for (key, n) in &counts {
        println!("{n:>7}  {key}");
    }
    Ok(())
}

/// Where a cell lies against the object beside it and the returns on its own ray
/// (`DIAGNOSE_GEOMETRY`): whether the placed grid holds it, the direction of the truth-M cells
/// among its 8 neighbours seen along the ray (they lie behind it: the cell is in front of the
/// object; in front of it: behind the object; else beside it), and how far behind the nearest
/// return of its own ray (the SPEC §3 grid's first occupied cell walking back to the sensor)
/// its centre lies, in cells.
#[allow(clippy::too_many_arguments)]
fn where_on_its_ray(
    index: &dyn Fn(i64, i64) -> Option<usize>,
    truth: &[Label],
    returns: &[f32],
    placed: &[f32],
    idx: usize,
    centre: [f64; 2],
    sensor: [f64; 2],
    cell_m: f64,
) -> String {
    let (dx, dy) = (centre[0] - sensor[0], centre[1] - sensor[1]);
    let range = dx.hypot(dy).max(1e-9);
    let u = [dx / range, dy / range];
    let (col, row) = (
        (centre[0] / cell_m).floor() as i64,
        (centre[1] / cell_m).floor() as i64,
    );
    let (mut mx, mut my, mut n) = (0.0, 0.0, 0);
    for dr in -1..=1 {
        for dc in -1..=1 {
            if (dr, dc) != (0, 0)
                && index(col + dc, row + dr).is_some_and(|k| truth.get(k) == Some(&Label::M))
            {
                mx += dc as f64;
                my += dr as f64;
                n += 1;
            }
        }
    }
    let side = if n == 0 {
        "no M beside"
    } else {
        let norm = mx.hypot(my);
        if norm < 1e-9 {
            "M around"
        } else {
            let along = (mx * u[0] + my * u[1]) / norm;
            if along > 0.7 {
                "M behind it"
            } else if along < -0.7 {
                "M in front of it"
            } else {
                "M beside it"
            }
        }
    };
    // Walk back along the ray in quarter cells, up to 6 cells.
    let mut depth = "no return within 6 cells nearer".to_owned();
    for step in 0..=24 {
        let back = step as f64 * 0.25 * cell_m;
        let (x, y) = (centre[0] - u[0] * back, centre[1] - u[1] * back);
        if let Some(k) = index((x / cell_m).floor() as i64, (y / cell_m).floor() as i64)
            && returns.get(k).is_some_and(|m| *m > 0.0)
        {
            depth = format!("return {:.0} cells nearer", (back / cell_m).ceil());
            break;
        }
    }
    format!(
        "{} | {side} | {depth}",
        if placed.get(idx).is_some_and(|m| *m > 0.0) {
            "placed"
        } else {
            "not placed"
        }
    )
}

/// A cluster's size in coarse buckets: 1, 2, 3-5, 6-10, 11-20, 21-40, > 40 cells.
fn bucket(n: u32) -> &'static str {
    match n {
        0..=1 => "1",
        2 => "2",
        3..=5 => "3-5",
        6..=10 => "6-10",
        11..=20 => "11-20",
        21..=40 => "21-40",
        _ => ">40",
    }
}
