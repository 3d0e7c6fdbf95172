//! A Patchwork-style ground model, written here only to compare the local method against the
//! field's usual choice, on the same unlabelled measures as `ground_eval`.
//!
//! After Lim et al. (RA-L 2021) and Lee et al. (IROS 2022), in outline: a concentric zone model
//! (4 zones of 2/4/4/4 rings and 16/32/54/32 sectors from 2.7 to 80 m); in each bin, seeds are
//! the points below the mean of its 20 lowest plus 0.125 m; a plane is fitted by PCA to them and
//! refitted three times to the points within 0.125 m of it; the bin is ground if the plane is
//! upright (normal z ≥ 0.707) and, in the four nearest rings, low enough (mean height below
//! −h + 0.523 / 0.746 / 0.879 / 1.125 m) or flat enough (smallest eigenvalue below 0.0005 /
//! 0.000725 / 0.001 / 0.001). No temporal or region-wise revert (no poses here).
//!
//! To be measured like the local method, points are labelled by their height above their
//! bin's plane where the bin is ground, above the sensor-height prior elsewhere, with the same
//! thresholds (`GroundParams` defaults).
//!
//! Run: `EVIGRID_SHARED=/work/shared cargo run --release -p evigrid-ground --example
//! compare_zone_planes`.

use std::time::Instant;

use ground::{GroundParams, PointLabel};

#[path = "../tests/common/mod.rs"]
mod common;

const SENSOR_HEIGHT_M: f32 = 1.73;
const MIN_RANGE_M: f32 = 2.7;
const MAX_RANGE_M: f32 = 80.0;
const ZONE_STARTS_M: [f32; 4] = [2.7, 12.3625, 22.025, 41.35];
const ZONE_RINGS: [usize; 4] = [2, 4, 4, 4];
const ZONE_SECTORS: [usize; 4] = [16, 32, 54, 32];
const ELEVATION_M: [f32; 4] = [0.523, 0.746, 0.879, 1.125];
const FLATNESS: [f32; 4] = [0.0005, 0.000725, 0.001, 0.001];
const LOWEST_POINTS: usize = 20;
const SEED_BAND_M: f32 = 0.125;
const PLANE_BAND_M: f32 = 0.125;
const ITERATIONS: usize = 3;
const MIN_POINTS: usize = 10;
const MIN_UPRIGHT: f32 = 0.707;

/// Bin index of a point, or `None` outside 2.7–80 m.
fn bin_of(p: &[f32; 3]) -> Option<usize> {
    let r = p[0].hypot(p[1]);
    if !(MIN_RANGE_M..MAX_RANGE_M).contains(&r) {
        return None;
    }
    let zone = ZONE_STARTS_M.iter().rposition(|&s| r >= s)?;
    let end = ZONE_STARTS_M.get(zone + 1).copied().unwrap_or(MAX_RANGE_M);
    let width = (end - ZONE_STARTS_M[zone]) / ZONE_RINGS[zone] as f32;
    let ring = (((r - ZONE_STARTS_M[zone]) / width) as usize).min(ZONE_RINGS[zone] - 1);
    let angle = p[1].atan2(p[0]) + std::f32::consts::PI;
    let sectors = ZONE_SECTORS[zone];
    let sector = ((angle / std::f32::consts::TAU * sectors as f32) as usize).min(sectors - 1);
    let before: usize = (0..zone).map(|z| ZONE_RINGS[z] * ZONE_SECTORS[z]).sum();
    Some(before + ring * sectors + sector)
}

/// Global ring index (0 nearest) of a bin.
fn ring_of_bin(bin: usize) -> usize {
    let (mut before, mut rings) = (0, 0);
    for z in 0..4 {
        let n = ZONE_RINGS[z] * ZONE_SECTORS[z];
        if bin < before + n {
            return rings + (bin - before) / ZONE_SECTORS[z];
        }
        before += n;
        rings += ZONE_RINGS[z];
    }
    rings
}

/// Smallest eigenpair of a symmetric 3×3 matrix, by cyclic Jacobi rotations.
fn smallest_eigen(mut a: [[f64; 3]; 3]) -> (f64, [f64; 3]) {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..30 {
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q].abs() < 1e-15 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let (c, s) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
            for row in &mut a {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            a[p] = [0, 1, 2].map(|k| c * row_p[k] - s * row_q[k]);
            a[q] = [0, 1, 2].map(|k| s * row_p[k] + c * row_q[k]);
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let k = (0..3)
        .min_by(|&i, &j| a[i][i].total_cmp(&a[j][j]))
        .unwrap_or(0);
    (a[k][k], [v[0][k], v[1][k], v[2][k]])
}

/// Plane (unit normal up, point on it) and smallest eigenvalue of `points`.
fn pca(points: &[[f32; 3]]) -> Option<([f32; 3], [f32; 3], f32)> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let mut mean = [0.0f64; 3];
    for p in points {
        for k in 0..3 {
            mean[k] += f64::from(p[k]) / n;
        }
    }
    let mut cov = [[0.0f64; 3]; 3];
    for p in points {
        let d = [0, 1, 2].map(|k| f64::from(p[k]) - mean[k]);
        for i in 0..3 {
            for j in 0..3 {
                cov[i][j] += d[i] * d[j] / n;
            }
        }
    }
    let (lambda, mut normal) = smallest_eigen(cov);
    if normal[2] < 0.0 {
        normal = normal.map(|v| -v);
    }
    Some((
        normal.map(|v| v as f32),
        mean.map(|v| v as f32),
        lambda as f32,
    ))
}

/// Labels of one scan by the zone-plane model.
fn zone_planes(points: &[[f32; 3]], params: &GroundParams) -> Vec<PointLabel> {
    let bins = (0..4).map(|z| ZONE_RINGS[z] * ZONE_SECTORS[z]).sum();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); bins];
    for (i, p) in points.iter().enumerate() {
        if p.iter().all(|v| v.is_finite())
            && let Some(b) = bin_of(p)
        {
            members[b].push(i);
        }
    }
    let label = |h: f32| {
        if h < -params.max_depth_below_ground_m as f32 {
            PointLabel::BelowGround
        } else if h < params.min_obstacle_height_m as f32 {
            PointLabel::Ground
        } else if h <= params.max_obstacle_height_m as f32 {
            PointLabel::Obstacle
        } else {
            PointLabel::Overhanging
        }
    };
    let mut labels = vec![PointLabel::Invalid; points.len()];
    let mut bin_points = Vec::new();
    for (b, idx) in members.iter_mut().enumerate() {
        idx.sort_by(|&i, &j| points[i][2].total_cmp(&points[j][2]));
        let ring = ring_of_bin(b);
        let mut plane = None;
        if idx.len() >= MIN_POINTS {
            let lowest = idx.len().min(LOWEST_POINTS);
            let lpr = idx[..lowest].iter().map(|&i| points[i][2]).sum::<f32>() / lowest as f32;
            bin_points.clear();
            bin_points.extend(
                idx.iter()
                    .map(|&i| points[i])
                    .filter(|p| p[2] < lpr + SEED_BAND_M),
            );
            let mut fit = pca(&bin_points);
            for _ in 0..ITERATIONS {
                let Some((n, c, _)) = fit else { break };
                bin_points.clear();
                bin_points.extend(idx.iter().map(|&i| points[i]).filter(|p| {
                    (n[0] * (p[0] - c[0]) + n[1] * (p[1] - c[1]) + n[2] * (p[2] - c[2])).abs()
                        < PLANE_BAND_M
                }));
                fit = pca(&bin_points).or(fit);
            }
            if let Some((n, c, lambda)) = fit {
                let upright = n[2] >= MIN_UPRIGHT;
                let low = ring >= 4 || c[2] < -SENSOR_HEIGHT_M + ELEVATION_M[ring];
                let flat = ring >= 4 || lambda < FLATNESS[ring];
                if upright && (low || flat) {
                    plane = Some((n, c));
                }
            }
        }
        for &i in idx.iter() {
            let p = points[i];
            let h = match plane {
                Some((n, c)) => (n[0] * (p[0] - c[0]) + n[1] * (p[1] - c[1])) / -n[2] + p[2] - c[2],
                None => p[2] + SENSOR_HEIGHT_M,
            };
            labels[i] = label(h);
        }
    }
    labels
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let params = GroundParams::default();
    for (name, paths) in [
        ("kitti-raw-0013", common::raw_0013_scans()),
        ("kitti-city-22", common::city_22_scans()),
    ] {
        let Some(paths) = paths else {
            eprintln!("{name}: shared data absent");
            continue;
        };
        let mut frames = Vec::new();
        for path in &paths {
            let points = common::read_points(path)?;
            let start = Instant::now();
            let labels = zone_planes(&points, &params);
            let ms = start.elapsed().as_secs_f64() * 1e3;
            let mut measure = common::measure_labels(&points, &labels);
            measure.ms = ms;
            frames.push(measure);
        }
        println!("{name} ZonePlanes: {}", common::Summary::of(&frames));
    }
    Ok(())
}
