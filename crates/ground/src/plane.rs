//! The baseline: one ground plane per scan (the sensor model's historical ground model).
//!
//! RANSAC over level-enough planes through three points drawn with a fixed seed from an even
//! sample of the near points, then two least-squares refits `z = a·x + b·y + c` on the points
//! within the band. Kept to measure the local method against; its sample is taken by stride in
//! point order, so unlike [`crate::GroundMethod::LocalHeight`] it depends on that order.

/// A plane `{p : normal · p = offset_m}` in the levelled frame, normal pointing up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Plane {
    pub(crate) normal: [f64; 3],
    pub(crate) offset_m: f64,
}

impl Plane {
    /// Distance of `p` above the plane, along the normal (negative below).
    #[inline]
    pub(crate) fn height_of(&self, p: [f64; 3]) -> f64 {
        dot(self.normal, p) - self.offset_m
    }

    /// Height of the plane at horizontal position `(x, y)`.
    #[inline]
    pub(crate) fn z_at(&self, x: f64, y: f64) -> f64 {
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
/// Hypotheses are drawn within this range: the road near the vehicle.
const FIT_RANGE_M: f64 = 30.0;
/// Planes tilted more than this are refused (walls, car sides).
const MAX_TILT_DEG: f64 = 20.0;
/// Fewer inliers than this: no plane.
const MIN_INLIERS: usize = 50;

/// Fits the plane to the valid points (`usable[i]`), or `None` when no level plane gathers
/// enough of them. `sample` is scratch, kept between scans.
pub(crate) fn fit(
    points: &[[f32; 3]],
    usable: &[bool],
    band_m: f64,
    sample: &mut Vec<[f64; 3]>,
) -> Option<Plane> {
    let widen = |p: &[f32; 3]| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])];
    let near = |(p, &ok): (&[f32; 3], &bool)| {
        let q = widen(p);
        (ok && q[0] * q[0] + q[1] * q[1] <= FIT_RANGE_M * FIT_RANGE_M).then_some(q)
    };
    let near_count = points.iter().zip(usable).filter_map(near).count();
    let stride = near_count.div_ceil(SAMPLE).max(1);
    sample.clear();
    sample.extend(points.iter().zip(usable).filter_map(near).step_by(stride));
    if sample.len() < 3 {
        return None;
    }
    let min_normal_z = MAX_TILT_DEG.to_radians().cos();
    let mut rng = SplitMix64(SEED);
    let mut best: Option<(Plane, usize)> = None;
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
        let plane = Plane {
            normal,
            offset_m: dot(normal, a),
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
    let (mut plane, _) = best?;
    for _ in 0..2 {
        plane = refit(points, usable, plane, band_m)?;
    }
    Some(plane)
}

/// Least squares `z = a·x + b·y + c` over the points within `band_m` of `plane`.
fn refit(points: &[[f32; 3]], usable: &[bool], plane: Plane, band_m: f64) -> Option<Plane> {
    let inliers = || {
        points
            .iter()
            .zip(usable)
            .filter(|(_, ok)| **ok)
            .map(|(p, _)| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
            .filter(move |q| plane.height_of(*q).abs() <= band_m)
    };
    // Centred sums for conditioning: coordinates are tens of metres, heights centimetres.
    let (mut n, mut mean) = (0usize, [0.0f64; 3]);
    for q in inliers() {
        n += 1;
        for k in 0..3 {
            mean[k] += q[k];
        }
    }
    if n < MIN_INLIERS {
        return None;
    }
    let mean = mean.map(|v| v / n as f64);
    let (mut sxx, mut sxy, mut syy, mut sxz, mut syz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for q in inliers() {
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
    let plane = Plane {
        normal: [-a / norm, -b / norm, 1.0 / norm],
        offset_m: (mean[2] - a * mean[0] - b * mean[1]) / norm,
    };
    plane.offset_m.is_finite().then_some(plane)
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
                points.push([x as f32, y as f32, (-1.73 + slope * x) as f32]);
            }
        }
        for k in 0..500 {
            points.push([8.0, -5.0 + 0.02 * k as f32, 0.5]);
        }
        let usable = vec![true; points.len()];
        let plane = fit(&points, &usable, 0.2, &mut Vec::new()).expect("a plane");
        assert!((plane.z_at(0.0, 0.0) + 1.73).abs() < 1e-4, "{plane:?}");
        assert!((plane.z_at(10.0, 0.0) - (-1.73 + 10.0 * slope)).abs() < 1e-4);
        assert!(plane.height_of([0.0, 0.0, 0.0]) > 1.7);
    }

    #[test]
    fn too_few_or_degenerate_points_give_no_plane() {
        assert_eq!(fit(&[], &[], 0.2, &mut Vec::new()), None);
        let line: Vec<[f32; 3]> = (0..100).map(|i| [i as f32 * 0.1, 0.0, -1.7]).collect();
        assert_eq!(fit(&line, &[true; 100], 0.2, &mut Vec::new()), None);
    }
}
