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
//! scenario's seed and the next).

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
    }
    Ok(())
}
