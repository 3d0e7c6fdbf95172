//! Voxel downsampling and the voxel-hash local map with its nearest-neighbour search.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use nalgebra::{Isometry3, Vector3};

/// Index of a voxel: the point's coordinates divided by the voxel size, floored.
pub(crate) type VoxelKey = [i32; 3];

/// The voxel holding `point`, for voxels of edge `1 / inverse_size`. Casts saturate, so a
/// (validated-against) absurd coordinate lands in an edge voxel rather than misbehaving.
pub(crate) fn voxel_of(point: &Vector3<f64>, inverse_size: f64) -> VoxelKey {
    [
        (point.x * inverse_size).floor() as i32,
        (point.y * inverse_size).floor() as i32,
        (point.z * inverse_size).floor() as i32,
    ]
}

/// A multiplicative hasher for voxel keys (the FxHash scheme): keys are not attacker-chosen, and
/// SipHash would be the largest cost of the map lookups.
#[derive(Default, Clone, Copy)]
pub(crate) struct VoxelHasher(u64);

const HASH_MULTIPLIER: u64 = 0x51_7c_c1_b7_27_22_0a_95;

impl VoxelHasher {
    fn mix(&mut self, word: u64) {
        self.0 = (self.0.rotate_left(5) ^ word).wrapping_mul(HASH_MULTIPLIER);
    }
}

impl Hasher for VoxelHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        let mut words = bytes.chunks_exact(4);
        for word in &mut words {
            let word = u32::from_le_bytes([word[0], word[1], word[2], word[3]]);
            self.mix(u64::from(word));
        }
        for &byte in words.remainder() {
            self.mix(u64::from(byte));
        }
    }

    fn write_u32(&mut self, value: u32) {
        self.mix(u64::from(value));
    }

    fn write_i32(&mut self, value: i32) {
        self.mix(u64::from(value as u32));
    }

    fn write_usize(&mut self, value: usize) {
        self.mix(value as u64);
    }
}

type BuildVoxelHasher = BuildHasherDefault<VoxelHasher>;

/// The points [`downsample`] keeps, in their order.
pub(crate) fn downsampled(points: &[Vector3<f64>], voxel_size: f64) -> Vec<Vector3<f64>> {
    downsample(points, voxel_size)
        .into_iter()
        .map(|i| points[i])
        .collect()
}

/// One point per voxel of edge `voxel_size`: indices, ascending.
///
/// The representative is an original point (KISS-ICP's choice over a centroid: the scan's own
/// samples), but a pseudo-random one, not the first in input order. The first in sweep order
/// sits where the sweep enters the voxel, and the voxels are fixed to the sensor: every scan
/// would then keep points along the same sensor-fixed lines on a surface, and a scan would match
/// the last one best at zero motion. A fixed scramble of the index keeps the choice
/// deterministic.
pub(crate) fn downsample(points: &[Vector3<f64>], voxel_size: f64) -> Vec<usize> {
    let inverse = 1.0 / voxel_size;
    let mut chosen: HashMap<VoxelKey, (u64, usize), BuildVoxelHasher> =
        HashMap::with_capacity_and_hasher(points.len() / 4, BuildVoxelHasher::default());
    for (index, point) in points.iter().enumerate() {
        let rank = scramble(index as u64);
        chosen
            .entry(voxel_of(point, inverse))
            .and_modify(|best| {
                if rank < best.0 {
                    *best = (rank, index);
                }
            })
            .or_insert((rank, index));
    }
    let mut indices: Vec<usize> = chosen.into_values().map(|(_, index)| index).collect();
    indices.sort_unstable();
    indices
}

/// A bijective mix of 64 bits (the SplitMix64 finaliser).
fn scramble(value: u64) -> u64 {
    let mut z = value.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The 27 voxels around a voxel (itself included), nearest first: the search visits the point's
/// own voxel first and then can skip most neighbours as farther than what it already found.
const NEIGHBOURS: [[i32; 3]; 27] = {
    let mut out = [[0; 3]; 27];
    let mut n = 0;
    let mut order = 0;
    while order <= 3 {
        let mut i = 0;
        while i < 27 {
            let offset = [i / 9 - 1, (i / 3) % 3 - 1, i % 3 - 1];
            let nonzero =
                (offset[0] != 0) as i32 + (offset[1] != 0) as i32 + (offset[2] != 0) as i32;
            if nonzero == order {
                out[n] = offset;
                n += 1;
            }
            i += 1;
        }
        order += 1;
    }
    out
};

/// The local map: world-frame points hashed by voxel, at most `max_points` per voxel and no two
/// closer than `voxel_size / sqrt(max_points)`, so a voxel's points spread over it instead of
/// piling up where the first scans happened to sample it.
///
/// The points are held twice: per voxel (`voxels`, which `add` grows) and, for the search, in one
/// contiguous store (`flat`, each voxel's points in their order, found by `ranges`), rebuilt after
/// every change. A registration makes millions of lookups between two changes, and a lookup then
/// reads the points right after a small index entry instead of following a `Vec`'s pointer.
#[derive(Debug, Clone)]
pub(crate) struct VoxelMap {
    voxel_size: f64,
    inverse_size: f64,
    max_points: usize,
    min_spacing_sq: f64,
    voxels: HashMap<VoxelKey, Vec<Vector3<f64>>, BuildVoxelHasher>,
    /// Voxel → (first index in `flat`, number of points).
    ranges: HashMap<VoxelKey, (u32, u32), BuildVoxelHasher>,
    flat: Vec<Vector3<f64>>,
}

impl VoxelMap {
    pub(crate) fn new(voxel_size: f64, max_points: usize) -> Self {
        Self {
            voxel_size,
            inverse_size: 1.0 / voxel_size,
            max_points,
            min_spacing_sq: voxel_size * voxel_size / max_points as f64,
            voxels: HashMap::default(),
            ranges: HashMap::default(),
            flat: Vec::new(),
        }
    }

    /// Rebuilds the search store from `voxels`.
    fn reindex(&mut self) {
        self.flat.clear();
        self.ranges.clear();
        self.ranges.reserve(self.voxels.len());
        for (key, points) in &self.voxels {
            // A voxel holds at most `max_points` points, and the store is local: u32 suffices
            // for any map that fits in memory.
            let start = self.flat.len() as u32;
            self.flat.extend_from_slice(points);
            self.ranges.insert(*key, (start, points.len() as u32));
        }
    }

    /// The voxel edge, metres.
    pub(crate) fn voxel_size(&self) -> f64 {
        self.voxel_size
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.voxels.is_empty()
    }

    /// Number of occupied voxels.
    pub(crate) fn voxel_count(&self) -> usize {
        self.voxels.len()
    }

    /// Number of points over all voxels.
    #[cfg(test)]
    pub(crate) fn point_count(&self) -> usize {
        self.voxels.values().map(Vec::len).sum()
    }

    /// Adds sensor-frame points placed by `world_from_sensor`.
    pub(crate) fn add(&mut self, points: &[Vector3<f64>], world_from_sensor: &Isometry3<f64>) {
        for point in points {
            let world = world_from_sensor * nalgebra::Point3::from(*point);
            let world = world.coords;
            let voxel = self
                .voxels
                .entry(voxel_of(&world, self.inverse_size))
                .or_default();
            if voxel.len() < self.max_points
                && voxel
                    .iter()
                    .all(|kept| (kept - world).norm_squared() >= self.min_spacing_sq)
            {
                voxel.push(world);
            }
        }
        self.reindex();
    }

    /// Forgets the voxels whose first point is farther than `radius` from `centre`: the map then
    /// covers what the sensor can see from there, whatever the length of the drive.
    pub(crate) fn remove_far(&mut self, centre: &Vector3<f64>, radius: f64) {
        let radius_sq = radius * radius;
        self.voxels.retain(|_, points| {
            points
                .first()
                .is_some_and(|p| (p - centre).norm_squared() <= radius_sq)
        });
        self.reindex();
    }

    /// The nearest map point to `query` within the 27 voxels around it, if closer than
    /// `sqrt(max_distance_sq)`; with its squared distance.
    #[cfg(test)]
    pub(crate) fn nearest(
        &self,
        query: &Vector3<f64>,
        max_distance_sq: f64,
    ) -> Option<(Vector3<f64>, f64)> {
        self.nearest_around(query, max_distance_sq, &mut Neighbourhood::default())
    }

    /// [`VoxelMap::nearest`] for a query that `around` followed before: the 27 voxels are
    /// looked up again only when the query has left the voxel `around` was resolved for. The
    /// same points in the same order as a fresh search, so the same answer, bit for bit.
    pub(crate) fn nearest_around(
        &self,
        query: &Vector3<f64>,
        max_distance_sq: f64,
        around: &mut Neighbourhood,
    ) -> Option<(Vector3<f64>, f64)> {
        let scaled = query * self.inverse_size;
        let centre = voxel_of(query, self.inverse_size);
        if around.centre != Some(centre) {
            for (range, offset) in around.ranges.iter_mut().zip(&NEIGHBOURS) {
                let key = [
                    centre[0].saturating_add(offset[0]),
                    centre[1].saturating_add(offset[1]),
                    centre[2].saturating_add(offset[2]),
                ];
                *range = self.ranges.get(&key).copied().unwrap_or((0, 0));
            }
            around.centre = Some(centre);
        }
        // Position inside the voxel, in metres from its lower corner, per axis.
        let inside = [
            (scaled.x - f64::from(centre[0])) * self.voxel_size,
            (scaled.y - f64::from(centre[1])) * self.voxel_size,
            (scaled.z - f64::from(centre[2])) * self.voxel_size,
        ];
        let mut best: Option<Vector3<f64>> = None;
        let mut best_sq = max_distance_sq;
        for (&(start, count), offset) in around.ranges.iter().zip(&NEIGHBOURS) {
            if count == 0 {
                continue;
            }
            // Distance from the query to the neighbour voxel's box: a lower bound on any of its
            // points' distances.
            let mut bound_sq = 0.0;
            for axis in 0..3 {
                let gap = match offset[axis] {
                    -1 => inside[axis],
                    1 => self.voxel_size - inside[axis],
                    _ => 0.0,
                };
                bound_sq += gap * gap;
            }
            if bound_sq >= best_sq {
                continue;
            }
            let (start, count) = (start as usize, count as usize);
            for point in &self.flat[start..start + count] {
                let distance_sq = (point - query).norm_squared();
                if distance_sq < best_sq {
                    best_sq = distance_sq;
                    best = Some(*point);
                }
            }
        }
        best.map(|p| (p, best_sq))
    }
}

/// The search store's ranges of the 27 voxels around one voxel (`NEIGHBOURS` order, empty where
/// the map has no voxel), kept per query point across a registration's iterations: a point moves
/// by millimetres from one iteration to the next and mostly stays in its voxel. Valid for one
/// state of the map.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Neighbourhood {
    centre: Option<VoxelKey>,
    ranges: [(u32, u32); 27],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbours_are_all_27_offsets_nearest_first() {
        assert_eq!(NEIGHBOURS[0], [0, 0, 0]);
        let mut sorted = NEIGHBOURS.to_vec();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), 27);
        let order = |o: &[i32; 3]| o.iter().filter(|&&c| c != 0).count();
        assert!(NEIGHBOURS.windows(2).all(|w| order(&w[0]) <= order(&w[1])));
    }

    #[test]
    fn downsample_keeps_one_point_per_voxel_in_input_order() {
        let points = [
            Vector3::new(0.1, 0.1, 0.1),
            Vector3::new(0.2, 0.2, 0.2),
            Vector3::new(-0.1, 0.1, 0.1),
            Vector3::new(1.5, 0.0, 0.0),
            Vector3::new(-0.2, 0.3, 0.4),
            Vector3::new(0.7, 0.3, 0.4),
        ];
        let kept = downsample(&points, 1.0);
        assert_eq!(kept.len(), 3);
        assert!(kept.windows(2).all(|w| w[0] < w[1]));
        let mut voxels: Vec<VoxelKey> = kept.iter().map(|&i| voxel_of(&points[i], 1.0)).collect();
        voxels.sort_unstable();
        assert_eq!(voxels, vec![[-1, 0, 0], [0, 0, 0], [1, 0, 0]]);
    }

    #[test]
    fn downsample_does_not_favour_the_first_point() {
        // 64 points per voxel in 100 voxels: the first would always be index 0 of its voxel.
        let points: Vec<Vector3<f64>> = (0..6400)
            .map(|i| Vector3::new(f64::from(i / 64) + 0.01 * f64::from(i % 64), 0.5, 0.5))
            .collect();
        let firsts = downsample(&points, 1.0)
            .iter()
            .filter(|&&i| i % 64 == 0)
            .count();
        assert!(firsts < 10, "{firsts}");
    }

    #[test]
    fn nearest_matches_brute_force_over_the_neighbourhood() {
        let mut map = VoxelMap::new(1.0, 20);
        let mut cloud = Vec::new();
        // A deterministic scatter of points over a few voxels.
        let mut state = 12_345_u64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..2000 {
            cloud.push(Vector3::new(
                next() * 6.0 - 3.0,
                next() * 6.0 - 3.0,
                next() * 2.0,
            ));
        }
        map.add(&cloud, &Isometry3::identity());
        let kept: Vec<Vector3<f64>> = map.voxels.values().flatten().copied().collect();
        for _ in 0..500 {
            let query = Vector3::new(next() * 6.0 - 3.0, next() * 6.0 - 3.0, next() * 2.0);
            let centre = voxel_of(&query, 1.0);
            let brute = kept
                .iter()
                .filter(|p| {
                    let k = voxel_of(p, 1.0);
                    (0..3).all(|a| (k[a] - centre[a]).abs() <= 1)
                })
                .map(|p| (p - query).norm_squared())
                .fold(f64::INFINITY, f64::min);
            let found = map.nearest(&query, 4.0).map(|(_, d)| d);
            if brute < 4.0 {
                assert_eq!(found, Some(brute));
            } else {
                assert_eq!(found, None);
            }
        }
    }

    #[test]
    fn a_kept_neighbourhood_finds_what_a_fresh_search_finds() {
        let mut map = VoxelMap::new(1.0, 20);
        let cloud: Vec<Vector3<f64>> = (0..400)
            .map(|i| {
                let i = f64::from(i);
                Vector3::new((i * 0.37) % 5.0, (i * 0.61) % 4.0, (i * 0.13) % 2.0)
            })
            .collect();
        map.add(&cloud, &Isometry3::identity());
        // One query walking through several voxels in steps of 7 cm, as a registration's point
        // moves: the kept neighbourhood must follow it from voxel to voxel.
        let mut around = Neighbourhood::default();
        let mut resolved = 0;
        for step in 0..60 {
            let t = f64::from(step) * 0.07;
            let query = Vector3::new(0.2 + t, 0.3 + 0.5 * t, 0.9);
            if around.centre != Some(voxel_of(&query, 1.0)) {
                resolved += 1;
            }
            let kept = map.nearest_around(&query, 2.0, &mut around);
            let fresh = map.nearest(&query, 2.0);
            assert_eq!(kept, fresh, "step {step}");
            assert!(fresh.is_some());
            assert_eq!(around.centre, Some(voxel_of(&query, 1.0)));
        }
        // The first look-up, then one per voxel boundary crossed (x from 0.2 to 4.33 crosses 4,
        // y from 0.3 to 2.37 crosses 2): 7 look-ups of the 27 voxels, not 60.
        assert_eq!(resolved, 7);
    }

    #[test]
    fn voxels_are_capped_and_spaced() {
        let mut map = VoxelMap::new(1.0, 4);
        let points: Vec<Vector3<f64>> = (0..100)
            .map(|i| Vector3::new(0.01 * f64::from(i % 10), 0.09 * f64::from(i / 10), 0.5))
            .collect();
        map.add(&points, &Isometry3::identity());
        assert_eq!(map.voxel_count(), 1);
        let kept = &map.voxels[&[0, 0, 0]];
        assert!(kept.len() <= 4);
        for (i, a) in kept.iter().enumerate() {
            for b in &kept[i + 1..] {
                assert!((a - b).norm() >= 0.5 - 1e-12);
            }
        }
    }

    #[test]
    fn remove_far_forgets_distant_voxels() {
        let mut map = VoxelMap::new(1.0, 20);
        let points: Vec<Vector3<f64>> = (0..300)
            .map(|i| Vector3::new(f64::from(i), 0.5, 0.5))
            .collect();
        map.add(&points, &Isometry3::identity());
        assert_eq!(map.voxel_count(), 300);
        map.remove_far(&Vector3::new(250.0, 0.5, 0.5), 100.0);
        assert_eq!(map.voxel_count(), 150);
        assert_eq!(map.point_count(), 150);
    }
}
