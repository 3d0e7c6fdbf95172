//! One ground plane per scan: the sensor model's plane ground model (`GroundModel::Plane` in
//! evigrid) and the baseline [`GroundMethod::GlobalPlane`](crate::GroundMethod::GlobalPlane)
//! that the local method is measured against. One implementation serves both.
//!
//! RANSAC over level-enough planes through three points drawn with a fixed seed from an even
//! sample of the near points, then two least-squares refits `z = a·x + b·y + c` on the points
//! within the band. The sample is taken by stride in point order, so unlike
//! [`crate::GroundMethod::LocalHeight`] the plane depends on that order.

use serde::Serialize;

/// A plane `{p : normal · p = offset_m}` in the levelled frame (world axes, sensor origin),
/// normal pointing up.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GroundPlane {
    /// Unit normal, pointing up (positive z).
    pub normal: [f64; 3],
    /// Signed distance of the plane from the sensor along the normal, metres: about −1.73 m for
    /// a lidar 1.73 m above a level road.
    pub offset_m: f64,
    /// Points within the band of the plane in its last refit.
    pub inliers: usize,
}

impl GroundPlane {
    /// Distance of `p` above the plane, along the normal (negative below), metres.
    #[inline]
    pub fn height_of(&self, p: [f64; 3]) -> f64 {
        dot(self.normal, p) - self.offset_m
    }

    /// Height of the plane at horizontal position `(x, y)`, metres.
    #[inline]
    pub fn z_at(&self, x: f64, y: f64) -> f64 {
        (self.offset_m - self.normal[0] * x - self.normal[1] * y) / self.normal[2]
    }
}

/// Fixed seed: the same scan always gives the same plane.
const SEED: u64 = 0x5EED_0F61_2000_0000;
/// Hypotheses per scan. With half the sample on the road a hypothesis is all-ground with
/// probability 1/8; 100 all miss with probability (7/8)^100 ≈ 2e-6.
const ITERATIONS: usize = 100;
/// Points drawn evenly from the near points to score hypotheses.
const SAMPLE: usize = 2048;
/// Hypotheses are drawn within this horizontal range: the road near the vehicle is the plane
/// wanted; far points are sparse and curve with the terrain.
const FIT_RANGE_M: f64 = 30.0;
/// Planes tilted more than this are refused (walls, car sides).
const MAX_TILT_DEG: f64 = 20.0;
/// Fewer inliers than this: no plane.
const MIN_INLIERS: usize = 50;

/// Fits one ground plane per scan; keeps its buffers between scans.
///
/// ```
/// use ground::PlaneFitter;
///
/// // A level road 1.73 m below the sensor, and a wall 8 m ahead.
/// let mut points = Vec::new();
/// for i in 0..40 {
///     for j in 0..40 {
///         points.push([-10.0 + 0.5 * f64::from(i), -10.0 + 0.5 * f64::from(j), -1.73]);
///     }
/// }
/// points.extend((0..300).map(|k| [8.0, -3.0 + 0.02 * f64::from(k), 0.5]));
/// let plane = PlaneFitter::default().fit(&points, 0.2).expect("a plane");
/// assert!((plane.offset_m + 1.73).abs() < 1e-9);
/// assert_eq!(plane.inliers, 1600);
/// ```
#[derive(Clone, Debug, Default)]
pub struct PlaneFitter {
    /// The even sample of near points that scores hypotheses.
    sample: Vec<[f64; 3]>,
    /// The inliers of the current refit.
    inliers: Vec<[f64; 3]>,
}

impl PlaneFitter {
    /// Fits the plane to `points` (levelled frame, metres) with inliers within `band_m` of it,
    /// or `None` when no plane tilted at most 20° gathers 50 points.
    pub fn fit(&mut self, points: &[[f64; 3]], band_m: f64) -> Option<GroundPlane> {
        self.fit_with(|| points.iter().copied(), band_m)
    }

    /// [`PlaneFitter::fit`] over the points `points()` yields, in the same order each call:
    /// the segmenter's `f32` points and the sensor model's `f64` ones share this code.
    pub(crate) fn fit_with<I>(&mut self, points: impl Fn() -> I, band_m: f64) -> Option<GroundPlane>
    where
        I: Iterator<Item = [f64; 3]>,
    {
        let near = |q: &[f64; 3]| q[0] * q[0] + q[1] * q[1] <= FIT_RANGE_M * FIT_RANGE_M;
        // Counted first, so that the near points are never all copied.
        let stride = points().filter(near).count().div_ceil(SAMPLE).max(1);
        self.sample.clear();
        self.sample.extend(points().filter(near).step_by(stride));
        let mut plane = best_hypothesis(&self.sample, band_m)?;
        for _ in 0..2 {
            plane = self.refit(points(), plane, band_m)?;
        }
        Some(plane)
    }

    /// Least squares `z = a·x + b·y + c` over the points within `band_m` of `plane`.
    fn refit(
        &mut self,
        points: impl Iterator<Item = [f64; 3]>,
        plane: GroundPlane,
        band_m: f64,
    ) -> Option<GroundPlane> {
        // Centred sums for conditioning: coordinates are tens of metres, heights centimetres.
        // The first pass keeps the inliers, so that the second reads only them.
        self.inliers.clear();
        let mut mean = [0.0f64; 3];
        for q in points.filter(|q| plane.height_of(*q).abs() <= band_m) {
            self.inliers.push(q);
            for k in 0..3 {
                mean[k] += q[k];
            }
        }
        let n = self.inliers.len();
        if n < MIN_INLIERS {
            return None;
        }
        let mean = mean.map(|v| v / n as f64);
        let (mut sxx, mut sxy, mut syy, mut sxz, mut syz) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for q in &self.inliers {
            let (x, y, z) = (q[0] - mean[0], q[1] - mean[1], q[2] - mean[2]);
            sxx += x * x;
            sxy += x * y;
            syy += y * y;
            sxz += x * z;
            syz += y * z;
        }
        let det = sxx * syy - sxy * sxy;
        if !(det.is_finite() && det.abs() > 1e-9) {
            return None;
        }
        let a = (sxz * syy - syz * sxy) / det;
        let b = (syz * sxx - sxz * sxy) / det;
        // z − z̄ = a (x − x̄) + b (y − ȳ)  ⇔  (−a, −b, 1) · p = z̄ − a x̄ − b ȳ
        let norm = (a * a + b * b + 1.0).sqrt();
        let plane = GroundPlane {
            normal: [-a / norm, -b / norm, 1.0 / norm],
            offset_m: (mean[2] - a * mean[0] - b * mean[1]) / norm,
            inliers: n,
        };
        plane.offset_m.is_finite().then_some(plane)
    }
}

/// The RANSAC hypothesis with the most sample points within `band_m`; ties go to the lower
/// plane. `None` if no hypothesis is level enough.
fn best_hypothesis(sample: &[[f64; 3]], band_m: f64) -> Option<GroundPlane> {
    if sample.len() < 3 {
        return None;
    }
    let min_normal_z = MAX_TILT_DEG.to_radians().cos();
    let mut rng = SplitMix64(SEED);
    let mut best: Option<(GroundPlane, usize)> = None;
    for _ in 0..ITERATIONS {
        let [a, b, c] = [0; 3].map(|_| sample[rng.below(sample.len())]);
        let n = cross(sub(b, a), sub(c, a));
        let norm = dot(n, n).sqrt();
        if !(norm.is_finite() && norm > 1e-9) {
            continue;
        }
        let sign = if n[2] < 0.0 { -1.0 } else { 1.0 };
        let normal = n.map(|v| sign * v / norm);
        if normal[2] < min_normal_z {
            continue;
        }
        let plane = GroundPlane {
            normal,
            offset_m: dot(normal, a),
            inliers: 0,
        };
        let score = sample
            .iter()
            .filter(|q| plane.height_of(**q).abs() <= band_m)
            .count();
        // Among equally supported planes the lower one: the road, not a kerb-high band.
        let better =
            best.is_none_or(|(b, s)| score > s || (score == s && plane.offset_m < b.offset_m));
        if better {
            best = Some((plane, score));
        }
    }
    best.map(|(plane, _)| plane)
}

/// SplitMix64 (Steele et al. 2014): a tiny deterministic generator for the draws.
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
        (self.next_u64() % n.max(1) as u64) as usize
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_tilted_plane_under_clutter() {
        // A 3° slope along x, 1.73 m below the sensor, plus a wall of points above it.
        let slope = 3f64.to_radians().tan();
        let mut points = Vec::new();
        for i in 0..60 {
            for j in 0..60 {
                let (x, y) = (-15.0 + 0.5 * f64::from(i), -15.0 + 0.5 * f64::from(j));
                points.push([x, y, -1.73 + slope * x]);
            }
        }
        for k in 0..500 {
            points.push([8.0, -5.0 + 0.02 * f64::from(k), 0.5]);
        }
        let plane = PlaneFitter::default().fit(&points, 0.2).expect("a plane");
        assert!((plane.z_at(0.0, 0.0) + 1.73).abs() < 1e-4, "{plane:?}");
        assert!((plane.z_at(10.0, 0.0) - (-1.73 + 10.0 * slope)).abs() < 1e-4);
        assert!(plane.height_of([0.0, 0.0, 0.0]) > 1.7);
        assert_eq!(plane.inliers, 3600);
    }

    #[test]
    fn too_few_or_degenerate_points_give_no_plane() {
        let mut fitter = PlaneFitter::default();
        assert_eq!(fitter.fit(&[], 0.2), None);
        let line: Vec<[f64; 3]> = (0..100).map(|i| [f64::from(i) * 0.1, 0.0, -1.7]).collect();
        assert_eq!(fitter.fit(&line, 0.2), None);
        // A level patch of 49 points: one short of a plane.
        let patch: Vec<[f64; 3]> = (0..49)
            .map(|i| [f64::from(i % 7), f64::from(i / 7), -1.7])
            .collect();
        assert_eq!(fitter.fit(&patch, 0.2), None);
        let wall: Vec<[f64; 3]> = (0..400)
            .map(|i| [5.0, f64::from(i % 20) * 0.1, f64::from(i / 20) * 0.1])
            .collect();
        assert_eq!(fitter.fit(&wall, 0.2), None, "a wall is not ground");
    }

    #[test]
    fn the_same_points_give_the_same_plane_whatever_the_buffers_held() {
        let points: Vec<[f64; 3]> = (0..2500)
            .map(|i| {
                let (x, y) = (
                    f64::from(i % 50) * 0.4 - 10.0,
                    f64::from(i / 50) * 0.4 - 10.0,
                );
                [x, y, -1.7 + 0.01 * x + if i % 7 == 0 { 1.0 } else { 0.0 }]
            })
            .collect();
        let fresh = PlaneFitter::default().fit(&points, 0.2);
        let mut used = PlaneFitter::default();
        used.fit(&points[..600], 0.1);
        assert_eq!(used.fit(&points, 0.2), fresh);
        assert!(fresh.is_some());
    }
}
