//! How far the front end's pose is from the truth, with and without pose refinement.
//!
//! ```text
//! cargo run --release -p evigrid-eval --example pose_error -- MAP SCENARIO.toml [SEEDS] [CONFIG.toml]
//! ```
//! Runs the scenario's drives through a `FrontEnd` twice, with `[localisation] refinement`
//! `"none"` (the pose the localisation reports) and `"scan_to_map"` (the other keys from
//! CONFIG), and prints the root mean square position and heading errors against the true
//! sensor pose, and of their change from one scan to the next (what makes a static object jump
//! a cell), with the refinement outcomes. SEEDS as in `diagnose_moving` (default: the
//! scenario's seed and the next). With `POSE_ERROR_FRAMES` set, each frame is printed too: its
//! seed, time, true sensor pose (x, y, heading), the refinement's outcome, the error of the pose
//! used and the scan's point count.

mod common;

use std::collections::BTreeMap;

use evigrid::{FrontEnd, PoseRefinement};
use sim::{Drive, Scenario};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let common::Inputs {
        map,
        scenario,
        seeds,
        config,
    } = common::inputs("pose_error")?;
    for refinement in [PoseRefinement::None, PoseRefinement::ScanToMap] {
        let mut params = config.params_for(&scenario);
        params.localisation.refinement = refinement;
        let (mut sum_sq_m, mut sum_sq_rad, mut frames) = (0.0, 0.0, 0usize);
        // Changes of the error from one scan to the next: what makes a static object jump.
        let (mut step_sq_m, mut step_sq_rad, mut steps) = (0.0, 0.0, 0usize);
        // The change of the position error over 8 scans, per second: the speed a static point
        // appears to have over the motion stage's history.
        let (mut drift_sq, mut drifts) = (0.0, 0usize);
        // The same over pairs of scans placed in one map's frames, the earlier scan's error
        // carried by the frame's change: what is left of the jump once the frame's move is
        // taken out (and that jump itself over the same pairs).
        let (mut kept_sq_m, mut kept_sq_rad, mut raw_sq_m, mut raw_sq_rad, mut pairs) =
            (0.0, 0.0, 0.0, 0.0, 0usize);
        let mut outcomes: BTreeMap<String, usize> = BTreeMap::new();
        let mut ms = 0.0;
        for &seed in &seeds {
            let scenario = Scenario {
                seed,
                ..scenario.clone()
            };
            let mut drive = Drive::new(&map, &scenario)?;
            let mut front_end = FrontEnd::new(&params, None)?;
            let mut last_error: Option<(f64, f64, f64)> = None;
            // The position errors of the last 8 scans with their times: the apparent speed of a
            // static point over the motion stage's history (8 frames).
            let mut recent: std::collections::VecDeque<(f64, f64, f64)> =
                std::collections::VecDeque::new();
            // The last scan's frame, pose used (x, y, heading) and true pose.
            let mut last_framed: Option<(evigrid::MapFrame, [f64; 3], [f64; 3])> = None;
            while let Some(frame) = drive.next_frame() {
                let scan = &frame.scan;
                let stats = front_end.process(
                    &scan.points_xyz_f32(),
                    &scan.estimated_isometry(),
                    scan.time_s,
                )?;
                *outcomes
                    .entry(format!("{:?}", stats.pose_refinement.outcome))
                    .or_default() += 1;
                ms += stats.pose_refinement.ms;
                let used = front_end.world_from_sensor();
                let truth = scan.world_from_sensor_true;
                let dx = used.translation.x - truth.position_m.x;
                let dy = used.translation.y - truth.position_m.y;
                let heading = used.rotation[(1, 0)].atan2(used.rotation[(0, 0)]);
                let turn = (heading - truth.heading_rad + std::f64::consts::PI)
                    .rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
                if let Some((lx, ly, lh)) = last_error {
                    step_sq_m += (dx - lx).powi(2) + (dy - ly).powi(2);
                    step_sq_rad += (turn - lh).powi(2);
                    steps += 1;
                }
                last_error = Some((dx, dy, turn));
                if std::env::var_os("POSE_ERROR_FRAMES").is_some() {
                    println!(
                        "frame seed {seed} t {:.1} true ({:.2}, {:.2}, {:.1}°) {:?} error {:.3} m \
                         {:.3}° points {}",
                        scan.time_s,
                        truth.position_m.x,
                        truth.position_m.y,
                        truth.heading_rad.to_degrees(),
                        stats.pose_refinement.outcome,
                        dx.hypot(dy),
                        turn.to_degrees(),
                        stats.sensor.points
                    );
                }
                if recent.len() == 8
                    && let Some(&(then_s, ox, oy)) = recent.front()
                    && scan.time_s > then_s
                {
                    let span = scan.time_s - then_s;
                    drift_sq += ((dx - ox) / span).powi(2) + ((dy - oy) / span).powi(2);
                    drifts += 1;
                }
                if recent.len() == 8 {
                    recent.pop_front();
                }
                recent.push_back((scan.time_s, dx, dy));
                let wrap = |a: f64| {
                    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                        - std::f64::consts::PI
                };
                let frame = front_end.map_frame();
                let true_pose = [truth.position_m.x, truth.position_m.y, truth.heading_rad];
                let used_pose = [used.translation.x, used.translation.y, heading];
                if let (Some(now), Some((then, then_used, then_true))) = (frame, last_framed)
                    && now.map == then.map
                {
                    let (cx, cy) = now.moved_from(&then, then_used[0], then_used[1]);
                    let ch = then_used[2] + now.heading_rad - then.heading_rad;
                    let (ex, ey) = (cx - then_true[0], cy - then_true[1]);
                    let eh = wrap(ch - then_true[2]);
                    kept_sq_m += (dx - ex).powi(2) + (dy - ey).powi(2);
                    kept_sq_rad += wrap(turn - eh).powi(2);
                    let (rx, ry) = (then_used[0] - then_true[0], then_used[1] - then_true[1]);
                    let rh = wrap(then_used[2] - then_true[2]);
                    raw_sq_m += (dx - rx).powi(2) + (dy - ry).powi(2);
                    raw_sq_rad += wrap(turn - rh).powi(2);
                    pairs += 1;
                }
                last_framed = frame.map(|f| (f, used_pose, true_pose));
                sum_sq_m += dx * dx + dy * dy;
                sum_sq_rad += turn * turn;
                frames += 1;
            }
        }
        let n = frames.max(1) as f64;
        let m = steps.max(1) as f64;
        println!(
            "refinement {refinement:?}: {frames} frames, RMS position error {:.4} m, RMS heading \
             error {:.4}°; scan to scan {:.4} m, {:.4}°; refinement {:.2} ms/frame, outcomes \
             {outcomes:?}",
            (sum_sq_m / n).sqrt(),
            (sum_sq_rad / n).sqrt().to_degrees(),
            (step_sq_m / m).sqrt(),
            (step_sq_rad / m).sqrt().to_degrees(),
            ms / n,
        );
        if drifts > 0 {
            println!(
                "  apparent speed of a static point over 8 scans (RMS of the error's change over \
                 8 scans / their span): {:.3} m/s",
                (drift_sq / drifts as f64).sqrt()
            );
        }
        if pairs > 0 {
            let p = pairs as f64;
            println!(
                "  {pairs} pairs of scans in one map's frames: scan to scan {:.4} m, {:.4}°; the \
                 frame's move taken out {:.4} m, {:.4}°",
                (raw_sq_m / p).sqrt(),
                (raw_sq_rad / p).sqrt().to_degrees(),
                (kept_sq_m / p).sqrt(),
                (kept_sq_rad / p).sqrt().to_degrees(),
            );
        }
    }
    Ok(())
}
