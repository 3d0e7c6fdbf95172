//! The single ground plane of [`GroundModel::Plane`](crate::params::GroundModel::Plane): RANSAC
//! with a fixed seed over near, roughly level hypotheses, then least squares on the inliers.

use serde::Serialize;

use super::classify::horizontal_range;

/// A plane `{p : normal · p = offset_m}` in the levelled frame (world axes, sensor origin).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GroundPlane {
    /// Unit normal, pointing up (positive z).
    pub normal: [f64; 3],
    /// Signed distance of the plane from the sensor along the normal, metres: about −1.73 m for
    /// a lidar 1.73 m above a level road.
    pub offset_m: f64,
    /// Points of the scan within the ground band of the plane.
    pub inliers: usize,
}

impl GroundPlane {
    /// Height of a point above the plane, metres (negative below it).
    #[inline]
    pub fn height_of(&self, p: [f64; 3]) -> f64 {
        self.normal[0] * p[0] + self.normal[1] * p[1] + self.normal[2] * p[2] - self.offset_m
    }
}

/// Fixed RANSAC seed: the same scan always gives the same plane.
const RANSAC_SEED: u64 = 0x5EED_0F61_2000_0000;
/// RANSAC hypotheses per scan. With half the sample on the road, a hypothesis is all-ground with
/// probability 1/8, so 100 of them all miss with probability (7/8)^100 ≈ 2e-6.
const RANSAC_ITERATIONS: usize = 100;
/// Points drawn (evenly, by stride) from the scan to score hypotheses.
const RANSAC_SAMPLE: usize = 2048;
/// Ground candidates lie within this horizontal range: the road near the vehicle is the plane
/// we want, far points are sparse and curve with the terrain.
const GROUND_FIT_RANGE_M: f64 = 30.0;
/// A ground plane tilted more than this from level is refused (a wall, a car's side).
const MAX_GROUND_TILT_DEG: f64 = 20.0;
/// Fewer ground inliers than this: no plane.
const MIN_GROUND_INLIERS: usize = 50;

/// Splitmix64: a tiny deterministic generator for RANSAC draws.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// Fits the ground plane to levelled points: RANSAC over near, roughly level hypotheses scored
/// on an even sample, then two least-squares refits `z = a·x + b·y + c` on all inliers within
/// `band_m`. `None` if no level plane gathers enough points.
pub fn fit_ground_plane(levelled: &[[f64; 3]], band_m: f64) -> Option<GroundPlane> {
    fit_ground_plane_into(levelled, band_m, &mut Vec::new())
}

/// [`fit_ground_plane`] with a buffer for the inliers' indices, kept between scans.
pub(super) fn fit_ground_plane_into(
    levelled: &[[f64; 3]],
    band_m: f64,
    inlier_indices: &mut Vec<usize>,
) -> Option<GroundPlane> {
    // Every stride-th near point, counted first so that the near points are never copied.
    let is_near = |q: &&[f64; 3]| horizontal_range(**q) <= GROUND_FIT_RANGE_M;
    let stride = levelled
        .iter()
        .filter(is_near)
        .count()
        .div_ceil(RANSAC_SAMPLE)
        .max(1);
    let candidates: Vec<[f64; 3]> = levelled
        .iter()
        .filter(is_near)
        .step_by(stride)
        .copied()
        .collect();
    if candidates.len() < 3 {
        return None;
    }
    let min_normal_z = MAX_GROUND_TILT_DEG.to_radians().cos();
    let mut rng = SplitMix64(RANSAC_SEED);
    let mut best: Option<([f64; 3], f64, usize)> = None;
    for _ in 0..RANSAC_ITERATIONS {
        let p0 = candidates[rng.below(candidates.len())];
        let p1 = candidates[rng.below(candidates.len())];
        let p2 = candidates[rng.below(candidates.len())];
        let u = sub(p1, p0);
        let v = sub(p2, p0);
        let n = cross(u, v);
        let norm = dot(n, n).sqrt();
        if norm.is_nan() || norm <= 1e-9 {
            continue;
        }
        let sign = if n[2] < 0.0 { -1.0 } else { 1.0 };
        let n = [sign * n[0] / norm, sign * n[1] / norm, sign * n[2] / norm];
        if n[2] < min_normal_z {
            continue;
        }
        let offset = dot(n, p0);
        let score = candidates
            .iter()
            .filter(|q| (dot(n, **q) - offset).abs() <= band_m)
            .count();
        // Among equally supported planes prefer the lower one: the road, not a kerb-high band.
        let better = match best {
            None => true,
            Some((_, best_offset, best_score)) => {
                score > best_score || (score == best_score && offset < best_offset)
            }
        };
        if better {
            best = Some((n, offset, score));
        }
    }
    let (mut normal, mut offset, _) = best?;
    let mut inliers = 0;
    for _ in 0..2 {
        let (fit, count) = least_squares_plane(levelled, normal, offset, band_m, inlier_indices)?;
        inliers = count;
        (normal, offset) = fit;
    }
    (inliers >= MIN_GROUND_INLIERS).then_some(GroundPlane {
        normal,
        offset_m: offset,
        inliers,
    })
}

/// Least-squares `z = a·x + b·y + c` over the points within `band_m` of the plane
/// `normal · p = offset`; returns the refitted unit normal and offset, and the inlier count.
fn least_squares_plane(
    levelled: &[[f64; 3]],
    normal: [f64; 3],
    offset: f64,
    band_m: f64,
    inliers: &mut Vec<usize>,
) -> Option<(([f64; 3], f64), usize)> {
    // Centred sums for conditioning: coordinates are tens of metres, heights centimetres. The
    // first pass notes the inliers, so that the second reads only them.
    inliers.clear();
    let mut mean = [0.0f64; 3];
    for (index, q) in levelled.iter().enumerate() {
        if (dot(normal, *q) - offset).abs() <= band_m {
            inliers.push(index);
            for k in 0..3 {
                mean[k] += q[k];
            }
        }
    }
    let n = inliers.len();
    if n < MIN_GROUND_INLIERS {
        return None;
    }
    let mean = mean.map(|v| v / n as f64);
    let (mut sxx, mut sxy, mut syy, mut sxz, mut syz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &index in inliers.iter() {
        let q = levelled[index];
        let (x, y, z) = (q[0] - mean[0], q[1] - mean[1], q[2] - mean[2]);
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        sxz += x * z;
        syz += y * z;
    }
    let det = sxx * syy - sxy * sxy;
    if det.is_nan() || det.abs() <= 1e-9 {
        return None;
    }
    let a = (sxz * syy - syz * sxy) / det;
    let b = (syz * sxx - sxz * sxy) / det;
    // z − mean_z = a (x − mean_x) + b (y − mean_y)  ⇔  (−a, −b, 1) · p = mean_z − a·mean_x − b·mean_y
    let norm = (a * a + b * b + 1.0).sqrt();
    let unit = [-a / norm, -b / norm, 1.0 / norm];
    let offset = (mean[2] - a * mean[0] - b * mean[1]) / norm;
    Some(((unit, offset), n))
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
