//! The local method: a ground height per polar cell, propagated outward from the sensor.
//!
//! Each cell's candidate is the centroid (range, height) of its lowest points: those at most
//! `seed_band_m` above the cell's lowest point. Walking each sector outward from the sensor, a
//! candidate becomes a ground node unless one of these refuses it (each guards against a
//! failure seen on the KITTI scans or the synthetic scenes of the tests):
//!
//! - **the blind radius**: nearer than where the sensor's steepest beam meets the prior ground
//!   (measured on the scan, 3.7 m for KITTI's HDL-64E), no ground can be seen, only what
//!   stands on it — a wall or a parked car alongside;
//! - **the slope cone**: the ground rises or falls by at most `max_slope` per metre plus one
//!   `max_step_m` (a kerb) from *every* earlier node, the vehicle's own ground at range 0
//!   included, so steps cannot be chained up a car's side;
//! - **unseen stretches**: across more than 3 m without a node (behind an occlusion, between
//!   sparse far beams) and before the first node, only `max_slope_unseen` per metre around the
//!   sector's recent trend: a ramp is seen all the way up, a car's hood beyond a parked car is
//!   not;
//! - **rising cells must be surfaces**: a candidate more than 5 cm above the last node needs
//!   half its cell's points within the seed band of the slope cone through the lowest point:
//!   the lowest returns of a wall or a car's flank rise too, but most of their cell stands
//!   above them.
//!
//! Between accepted nodes the ground height is interpolated linearly in range, so a ramp is
//! followed inside cells too; beyond a sector's last node it stays level.
//!
//! Cell statistics are order-independent: a minimum (ties broken by range), counts, and sums
//! of offsets from the minimum quantised to integers (exact in any order), so labels do not
//! depend on the point order.

use crate::params::GroundParams;
use crate::polar::{NO_CELL, PolarLayout};

/// A rise between consecutive ground nodes below this is the road's own roughness and range
/// noise (2 cm on an HDL-64E), not a step onto something, metres.
const ROUGHNESS_M: f32 = 0.05;

/// Ground cells at most this far apart along a sector are taken as seen continuously: the
/// spacing of an HDL-64E's beams on a level road up to 25 m (and on a 10° ramp up to 50 m),
/// metres.
const SEEN_GAP_M: f32 = 3.0;

/// The trend of a sector's ground is its gradient over this range behind the last node (or
/// over its last three nodes, where they are farther apart), metres.
const TREND_M: f32 = 10.0;

/// Fixed-point scale of the seed sums: 2^20 steps per metre (about 1 µm).
const FIXED_PER_M: f32 = (1u32 << 20) as f32;

/// The ground height along the range inside one cell: `a + b·r` in two pieces, split at the
/// cell's own node (nodes of neighbouring rings bound the pieces).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct CellProfile {
    split_m: f32,
    near: [f32; 2],
    far: [f32; 2],
}

impl CellProfile {
    /// Ground height at horizontal range `range_m` within the cell.
    #[inline]
    pub(crate) fn z_at(&self, range_m: f32) -> f32 {
        let [a, b] = if range_m < self.split_m {
            self.near
        } else {
            self.far
        };
        a + b * range_m
    }
}

/// Per-cell scratch of the local method, kept between scans.
#[derive(Clone, Debug, Default)]
pub(crate) struct LocalHeight {
    min_z: Vec<f32>,
    /// Range of the lowest point (the nearest among equally low ones).
    min_r: Vec<f32>,
    /// Points per cell, and those on the surface through its lowest point (see `fit`).
    count: Vec<u32>,
    surface_count: Vec<u32>,
    seed_count: Vec<u32>,
    /// Sum over seeds of (range − ring start), fixed point.
    seed_dr: Vec<u64>,
    /// Sum over seeds of (z − cell minimum), fixed point.
    seed_dz: Vec<u64>,
    /// The current sector's nodes within `TREND_M` of its last one (at least three).
    recent: Vec<(f32, f32)>,
    /// Accepted node (range, height) per cell; NaN range where none.
    node: Vec<(f32, f32)>,
    /// The profile each point's ground height is read from.
    pub(crate) profile: Vec<CellProfile>,
}

/// What the propagation counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Counts {
    pub(crate) accepted: usize,
    pub(crate) refused: usize,
}

impl LocalHeight {
    /// Fits the profiles of every cell to the points (`cell[i]`, `range_m[i]` from the binning).
    pub(crate) fn fit(
        &mut self,
        layout: &PolarLayout,
        params: &GroundParams,
        points: &[[f32; 3]],
        cell: &[u32],
        range_m: &[f32],
    ) -> Counts {
        let cells = layout.cells();
        reset(&mut self.min_z, cells, f32::INFINITY);
        reset(&mut self.min_r, cells, f32::INFINITY);
        reset(&mut self.count, cells, 0);
        reset(&mut self.surface_count, cells, 0);
        reset(&mut self.seed_count, cells, 0);
        reset(&mut self.seed_dr, cells, 0);
        reset(&mut self.seed_dz, cells, 0);
        reset(&mut self.node, cells, (f32::NAN, f32::NAN));
        reset(&mut self.profile, cells, CellProfile::default());

        for ((p, &c), &r) in points.iter().zip(cell).zip(range_m) {
            let c = c as usize;
            if c >= cells {
                continue;
            }
            // Lowest first, then nearest: the same point whatever the order.
            if p[2] < self.min_z[c] || (p[2] == self.min_z[c] && r < self.min_r[c]) {
                self.min_z[c] = p[2];
                self.min_r[c] = r;
            }
        }
        let rings = layout.rings();
        let seed_band_m = params.seed_band_m as f32;
        let slope = params.max_slope as f32;
        for ((p, &c), &r) in points.iter().zip(cell).zip(range_m) {
            let c = c as usize;
            if c >= cells {
                continue;
            }
            let dz = p[2] - self.min_z[c];
            self.count[c] += 1;
            // On the surface: within the seed band of the slope cone through the lowest point.
            // A ramp's cell is all surface; a wall's or a car's side is mostly above it.
            let cone = seed_band_m + slope * (r - self.min_r[c]).abs();
            self.surface_count[c] += u32::from(dz <= cone);
            if dz <= seed_band_m {
                let dr = r - layout.ring_start_m(c % rings);
                self.seed_count[c] += 1;
                // Casts saturate; offsets are small and non-negative by construction.
                self.seed_dr[c] = self.seed_dr[c].saturating_add((dr * FIXED_PER_M) as u64);
                self.seed_dz[c] = self.seed_dz[c].saturating_add((dz * FIXED_PER_M) as u64);
            }
        }

        let blind_m = blind_radius_m(params, points, cell, range_m);
        let mut counts = Counts::default();
        for s in 0..layout.sectors() {
            let sector = s * rings..(s + 1) * rings;
            counts = self.propagate(layout, params, blind_m, sector.clone(), counts);
            self.profiles(params, sector);
        }
        counts
    }

    /// Accepts or refuses the candidates of one sector's cells, nearest first.
    fn propagate(
        &mut self,
        layout: &PolarLayout,
        params: &GroundParams,
        blind_m: f32,
        sector: std::ops::Range<usize>,
        mut counts: Counts,
    ) -> Counts {
        let slope = params.max_slope as f32;
        let unseen = params.max_slope_unseen as f32;
        let step = params.max_step_m as f32;
        // Three bounds on a candidate at range r, height z:
        // - every accepted node j: |z − z_j| ≤ step + slope·|r − r_j|, so that steps cannot be
        //   chained up a car's side; only the tightest counts, kept as
        //   `ceiling = min_j (z_j − slope·r_j)` and `floor = max_j (z_j + slope·r_j)`;
        // - the last node, across a gap longer than `SEEN_GAP_M` (an occlusion, sparse far
        //   beams): z within step + unseen·gap of the range from z_last to z_last + trend·gap,
        //   the trend being the sector's recent gradient. A ramp is seen all the way up; a
        //   car's hood beyond an occlusion rises faster than the road before it;
        // - before the first node, the vehicle's own ground: |z − prior| ≤ tolerance +
        //   unseen·r (after it, the prior is one more node of the slope cone).
        let prior_z = -params.sensor_height_m as f32;
        let tolerance = params.sensor_height_tolerance_m as f32;
        // The vehicle's ground is a node at range 0 in the slope cone.
        let mut ceiling = prior_z + tolerance - step;
        let mut floor = prior_z - tolerance + step;
        self.recent.clear();
        let rings = layout.rings();
        for c in sector {
            let n = self.seed_count[c];
            if n == 0 {
                continue;
            }
            let r =
                layout.ring_start_m(c % rings) + self.seed_dr[c] as f32 / FIXED_PER_M / n as f32;
            let z = self.min_z[c] + self.seed_dz[c] as f32 / FIXED_PER_M / n as f32;
            let mut highest = ceiling + slope * r + step;
            let mut lowest = floor - slope * r - step;
            let last_z = match self.recent.last() {
                Some(&(last_r, last_z)) => {
                    let gap = r - last_r;
                    if gap > SEEN_GAP_M {
                        // Between the level and the trend, so that a bank's rise is not
                        // extrapolated onto the flat behind it.
                        let trended = last_z + trend(&self.recent, slope) * gap;
                        let band = step + unseen * gap;
                        highest = highest.min(last_z.max(trended) + band);
                        lowest = lowest.max(last_z.min(trended) - band);
                    }
                    last_z
                }
                None => {
                    let band = tolerance + unseen * r;
                    highest = highest.min(prior_z + band);
                    lowest = lowest.max(prior_z - band);
                    prior_z
                }
            };
            // Rising ground must look like a surface: the lowest points of a wall or a car's
            // side rise too, but most of their cell stands above them.
            let rising = z > last_z + ROUGHNESS_M;
            let surface = 2 * self.surface_count[c] >= self.count[c];
            // Nearer than the blind radius the ground cannot be seen at the prior height:
            // whatever is there stands on it.
            let beyond_blind = r >= blind_m;
            if beyond_blind && (lowest..=highest).contains(&z) && (surface || !rising) {
                self.node[c] = (r, z);
                ceiling = ceiling.min(z - slope * r);
                floor = floor.max(z + slope * r);
                // The trend looks back `TREND_M`, or three nodes where they are sparser.
                let old = self.recent.partition_point(|&(rj, _)| rj < r - TREND_M);
                let old = old.min(self.recent.len().saturating_sub(2));
                self.recent.drain(..old);
                self.recent.push((r, z));
                counts.accepted += 1;
            } else {
                counts.refused += 1;
            }
        }
        counts
    }

    /// Turns one sector's nodes into per-cell profiles: linear between consecutive nodes,
    /// from the sensor's prior ground before the first, level after the last.
    fn profiles(&mut self, params: &GroundParams, sector: std::ops::Range<usize>) {
        let prior = (0.0f32, -params.sensor_height_m as f32);
        let line = |(r0, z0): (f32, f32), next: Option<(f32, f32)>| match next {
            Some((r1, z1)) if r1 - r0 > 1e-3 => {
                let b = (z1 - z0) / (r1 - r0);
                [z0 - b * r0, b]
            }
            Some((_, z1)) => [z1, 0.0],
            None => [z0, 0.0],
        };
        // Backward: the next node beyond each cell (its own excluded).
        let mut next: Option<(f32, f32)> = None;
        for c in sector.clone().rev() {
            // Stored in `far` for now; `near` is set on the forward pass.
            self.profile[c].far = match next {
                Some(n) => [n.0, n.1],
                None => [f32::NAN, f32::NAN],
            };
            if !self.node[c].0.is_nan() {
                next = Some(self.node[c]);
            }
        }
        let mut previous = prior;
        for c in sector {
            let beyond = self.profile[c].far;
            let beyond = (!beyond[0].is_nan()).then_some((beyond[0], beyond[1]));
            let own = self.node[c];
            self.profile[c] = if own.0.is_nan() {
                let piece = line(previous, beyond);
                CellProfile {
                    split_m: f32::INFINITY,
                    near: piece,
                    far: piece,
                }
            } else {
                let profile = CellProfile {
                    split_m: own.0,
                    near: line(previous, Some(own)),
                    far: line(own, beyond),
                };
                previous = own;
                profile
            };
        }
    }
}

/// Range within which the sensor cannot see ground at its prior height, metres: where its
/// steepest beam meets that ground. A cell nearer than this holds only what stands above the
/// ground (a wall, a car alongside), whose lowest points say nothing of the ground under them:
/// it gives no node, and the slope allowance from the prior starts there.
///
/// The steepest beam is measured on the scan (the largest depression `−z / range`), so that no
/// sensor model is needed; a noise point below the ground only shrinks the radius, back to the
/// plain slope limit.
fn blind_radius_m(
    params: &GroundParams,
    points: &[[f32; 3]],
    cell: &[u32],
    range_m: &[f32],
) -> f32 {
    let mut steepest = 0.0f32;
    for ((p, &c), &r) in points.iter().zip(cell).zip(range_m) {
        if c != NO_CELL && r > 0.0 {
            steepest = steepest.max(-p[2] / r);
        }
    }
    if steepest > 0.0 {
        (params.sensor_height_m as f32 / steepest).min(params.max_range_m as f32)
    } else {
        0.0
    }
}

/// Least-squares gradient of the ground through `nodes` (range, height), within
/// `±max_slope`; level with fewer than two nodes or less than 2 m between them.
fn trend(nodes: &[(f32, f32)], max_slope: f32) -> f32 {
    let (Some(first), Some(last)) = (nodes.first(), nodes.last()) else {
        return 0.0;
    };
    if last.0 - first.0 < 2.0 {
        return 0.0;
    }
    let n = nodes.len() as f32;
    let (mean_r, mean_z) = nodes
        .iter()
        .fold((0.0, 0.0), |(a, b), &(r, z)| (a + r / n, b + z / n));
    let (mut srr, mut srz) = (0.0f32, 0.0f32);
    for &(r, z) in nodes {
        srr += (r - mean_r) * (r - mean_r);
        srz += (r - mean_r) * (z - mean_z);
    }
    if srr > 0.0 {
        (srz / srr).clamp(-max_slope, max_slope)
    } else {
        0.0
    }
}

fn reset<T: Clone>(v: &mut Vec<T>, len: usize, value: T) {
    v.clear();
    v.resize(len, value);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_trend_is_the_least_squares_gradient_within_the_slope_limit() {
        let line: Vec<(f32, f32)> = (0..5)
            .map(|k| (10.0 + k as f32, -1.73 + 0.05 * k as f32))
            .collect();
        assert!((trend(&line, 0.2) - 0.05).abs() < 1e-5);
        let steep: Vec<(f32, f32)> = (0..5).map(|k| (10.0 + k as f32, k as f32)).collect();
        assert_eq!(trend(&steep, 0.2), 0.2);
        // Under 2 m of range, or a single node: level.
        assert_eq!(trend(&[(10.0, -1.7), (11.5, -1.5)], 0.2), 0.0);
        assert_eq!(trend(&[(10.0, -1.7)], 0.2), 0.0);
        assert_eq!(trend(&[], 0.2), 0.0);
    }

    #[test]
    fn profiles_interpolate_between_nodes_and_stay_level_after_the_last() {
        let params = GroundParams::default();
        // One sector of 5 cells; nodes in cells 1 (at 4 m, −1.7) and 3 (at 8 m, −1.5).
        let mut node = vec![(f32::NAN, f32::NAN); 5];
        node[1] = (4.0, -1.7);
        node[3] = (8.0, -1.5);
        let mut local = LocalHeight {
            node,
            profile: vec![CellProfile::default(); 5],
            ..LocalHeight::default()
        };
        local.profiles(&params, 0..5);
        // Before the first node: from the prior (0 m, −1.73) to (4 m, −1.7).
        assert!((local.profile[0].z_at(2.0) - (-1.715)).abs() < 1e-6);
        // Cell 1, both sides of its node.
        assert!((local.profile[1].z_at(3.0) - (-1.7075)).abs() < 1e-6);
        assert!((local.profile[1].z_at(5.0) - (-1.65)).abs() < 1e-6);
        // Cell 2 has no node: one line from node 1 to node 3.
        assert!((local.profile[2].z_at(6.0) - (-1.6)).abs() < 1e-6);
        // After the last node: level.
        assert!((local.profile[3].z_at(9.0) - (-1.5)).abs() < 1e-6);
        assert!((local.profile[4].z_at(30.0) - (-1.5)).abs() < 1e-6);
    }

    #[test]
    fn the_blind_radius_is_where_the_steepest_return_meets_the_prior_ground() {
        let params = GroundParams::default();
        // Steepest return: 1 m down at 2 m, a depression of 0.5: blind radius 1.73 / 0.5.
        let points = [[2.0, 0.0, -1.0], [10.0, 0.0, -1.73], [5.0, 0.0, 1.0]];
        let ranges = [2.0, 10.0, 5.0];
        let blind = blind_radius_m(&params, &points, &[0, 1, 2], &ranges);
        assert!((blind - 3.46).abs() < 1e-5, "{blind}");
        // Invalid points do not count; nothing below the sensor: no blind zone.
        assert_eq!(
            blind_radius_m(&params, &points, &[NO_CELL, NO_CELL, 2], &ranges),
            0.0
        );
    }
}
