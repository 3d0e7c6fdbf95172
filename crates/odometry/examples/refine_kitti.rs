//! The pose refinement on a real drive: KITTI raw OXTS poses, as given and with seeded noise
//! added, refined against the drive's own Velodyne scans. OXTS (RTK GNSS/INS) is the reference.
//!
//! ```text
//! cargo run --release -p evigrid-odometry --example refine_kitti -- \
//!     <shared>/data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync \
//!     [--sigma-m 0.1] [--sigma-deg 0.2] [--seed 1] [--write-tum noisy.tum]
//! ```
//!
//! Per setting it prints the RMS horizontal position and heading error against OXTS, the RMS
//! change of that error from one scan to the next (what makes a static object jump between
//! grids), the refiner's outcomes and its time per scan. The noise is independent per scan,
//! horizontal position `sigma_m` per axis and heading `sigma_deg`, as the simulator's.
//! `--write-tum` writes the noisy poses as a TUM file, for `evigrid run --drive DIR --poses`.

mod common;

use std::collections::BTreeMap;
use std::time::Instant;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use odometry::{PoseRefiner, RefineParams, RefineStart};

/// A normal sample from a seeded linear congruential generator (Box–Muller): reproducible
/// without a dependency.
fn normal(state: &mut u64) -> f64 {
    let mut uniform = || {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((*state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let (a, b) = (uniform(), uniform());
    (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
}

fn heading(pose: &Isometry3<f64>) -> f64 {
    pose.rotation.euler_angles().2
}

/// Horizontal position error (x, y) and heading error (radians, wrapped) of `pose`.
fn error(pose: &Isometry3<f64>, reference: &Isometry3<f64>) -> [f64; 3] {
    let d = pose.translation.vector - reference.translation.vector;
    let turn = (heading(pose) - heading(reference) + std::f64::consts::PI)
        .rem_euclid(std::f64::consts::TAU)
        - std::f64::consts::PI;
    [d.x, d.y, turn]
}

/// RMS error of `poses` against `reference` and RMS scan-to-scan change of the error:
/// `(m, deg, step m, step deg)`.
fn summary(poses: &[Isometry3<f64>], reference: &[Isometry3<f64>]) -> (f64, f64, f64, f64) {
    let errors: Vec<[f64; 3]> = poses
        .iter()
        .zip(reference)
        .map(|(p, r)| error(p, r))
        .collect();
    let n = errors.len().max(1) as f64;
    let rms_m = (errors
        .iter()
        .map(|e| e[0] * e[0] + e[1] * e[1])
        .sum::<f64>()
        / n)
        .sqrt();
    let rms_rad = (errors.iter().map(|e| e[2] * e[2]).sum::<f64>() / n).sqrt();
    let steps = errors.windows(2).map(|w| {
        let (a, b) = (w[0], w[1]);
        (
            (b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2),
            (b[2] - a[2]).powi(2),
        )
    });
    let m = errors.len().saturating_sub(1).max(1) as f64;
    let (step_sq_m, step_sq_rad) = steps.fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    (
        rms_m,
        rms_rad.to_degrees(),
        (step_sq_m / m).sqrt(),
        (step_sq_rad / m).sqrt().to_degrees(),
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = args
        .next()
        .ok_or("usage: refine_kitti <drive_sync dir> [--sigma-m M] [--sigma-deg D] [--seed N] [--write-tum FILE] [--start prior|constant_velocity]")?;
    let (mut sigma_m, mut sigma_deg, mut seed) = (0.1_f64, 0.2_f64, 1_u64);
    let mut tum: Option<std::path::PathBuf> = None;
    let mut params = RefineParams::default();
    while let Some(flag) = args.next() {
        let value = args.next().ok_or(format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--sigma-m" => sigma_m = value.parse()?,
            "--sigma-deg" => sigma_deg = value.parse()?,
            "--seed" => seed = value.parse()?,
            "--write-tum" => tum = Some(value.into()),
            "--start" => {
                params.start = match value.as_str() {
                    "prior" => RefineStart::Prior,
                    "constant_velocity" => RefineStart::ConstantVelocity,
                    other => return Err(format!("--start: unknown start {other}").into()),
                }
            }
            other => return Err(format!("unknown flag {other}").into()),
        }
    }
    let common::KittiDrive { reference, scans } = common::read_drive(&dir)?;

    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(1);
    let noisy: Vec<Isometry3<f64>> = reference
        .iter()
        .map(|pose| {
            let (dx, dy) = (sigma_m * normal(&mut state), sigma_m * normal(&mut state));
            let dh = sigma_deg.to_radians() * normal(&mut state);
            // Position off in the world's axes, heading turned about the sensor itself.
            Isometry3::from_parts(
                Translation3::from(pose.translation.vector + nalgebra::Vector3::new(dx, dy, 0.0)),
                UnitQuaternion::from_euler_angles(0.0, 0.0, dh) * pose.rotation,
            )
        })
        .collect();

    if let Some(path) = &tum {
        let track =
            drive::poses::PoseTrack::new(scans.iter().map(|s| s.1).collect(), noisy.clone())?;
        let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
        drive::poses::write_tum(&mut out, &track)?;
    }
    println!(
        "{} scans; noise {sigma_m} m per axis, {sigma_deg}° heading, seed {seed}",
        scans.len()
    );
    for (name, priors) in [("OXTS", &reference), ("OXTS + noise", &noisy)] {
        let (m, deg, step_m, step_deg) = summary(priors, &reference);
        println!(
            "{name:>13}, as given: RMS {m:.3} m, {deg:.3}°; scan to scan {step_m:.3} m, {step_deg:.3}°"
        );
        let mut refiner = PoseRefiner::new(params.clone())?;
        let mut outcomes: BTreeMap<String, usize> = BTreeMap::new();
        let mut used = Vec::with_capacity(scans.len());
        let start = Instant::now();
        for ((points, time_s), prior) in scans.iter().zip(priors.iter()) {
            let refinement = refiner.refine_and_insert(points, prior, *time_s);
            *outcomes
                .entry(format!("{:?}", refinement.outcome))
                .or_default() += 1;
            used.push(refinement.world_from_sensor);
        }
        let ms = start.elapsed().as_secs_f64() * 1e3 / scans.len().max(1) as f64;
        let (m, deg, step_m, step_deg) = summary(&used, &reference);
        println!(
            "{name:>13}, refined:  RMS {m:.3} m, {deg:.3}°; scan to scan {step_m:.3} m, {step_deg:.3}°; {ms:.1} ms a scan; {outcomes:?}"
        );
    }
    Ok(())
}
