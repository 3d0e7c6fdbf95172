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
        floor_to_i32(point.x * inverse_size),
        floor_to_i32(point.y * inverse_size),
        floor_to_i32(point.z * inverse_size),
    ]
}

/// `value.floor() as i32`, exactly (NaN to 0, out of range saturated), without `floor`: on
/// x86-64 without SSE4.1 that is a call to a software routine of about 25 instructions, which
/// made 3.9 % of the default KITTI run's instructions (the search and the downsampling call it
/// three times a point). Truncation is one instruction; a negative non-integer is one below.
fn floor_to_i32(value: f64) -> i32 {
    // Saturating: |value| ≥ 2⁶³ is already an integer, and NaN gives 0, as `floor` would.
    let truncated = value as i64;
    // Exact below 2⁵³; from there `value` is an integer and `truncated` equals it.
    let floored = if (truncated as f64) > value {
        truncated.saturating_sub(1)
    } else {
        truncated
    };
    floored.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
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
    // Per voxel its slot in `chosen`, which holds the (rank, index) of the voxel's best point.
    // A scan's consecutive points mostly share a voxel (a ring's neighbours in azimuth), so the
    // last voxel's slot is kept and the hash map is asked only when the voxel changes.
    let mut slots: HashMap<VoxelKey, usize, BuildVoxelHasher> =
        HashMap::with_capacity_and_hasher(points.len() / 4, BuildVoxelHasher::default());
    let mut chosen: Vec<(u64, usize)> = Vec::with_capacity(points.len() / 4);
    let mut last: Option<(VoxelKey, usize)> = None;
    for (index, point) in points.iter().enumerate() {
        let rank = scramble(index as u64);
        let voxel = voxel_of(point, inverse);
        let slot = match last {
            Some((last_voxel, slot)) if last_voxel == voxel => slot,
            _ => *slots.entry(voxel).or_insert_with(|| {
                chosen.push((rank, index));
                chosen.len() - 1
            }),
        };
        last = Some((voxel, slot));
        if rank < chosen[slot].0 {
            chosen[slot] = (rank, index);
        }
    }
    // Ascending without a sort: one bit per point, read in order (each point is chosen at most
    // once).
    let mut kept = vec![0u64; points.len().div_ceil(64)];
    for &(_, index) in &chosen {
        kept[index / 64] |= 1 << (index % 64);
    }
    let mut indices = Vec::with_capacity(chosen.len());
    for (word_index, &word) in kept.iter().enumerate() {
        let mut bits = word;
        while bits != 0 {
            indices.push(word_index * 64 + bits.trailing_zeros() as usize);
            bits &= bits - 1;
        }
    }
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
        self.insert_points(points, world_from_sensor);
        self.reindex();
    }

    /// [`VoxelMap::add`] then [`VoxelMap::remove_far`], with the search store rebuilt once:
    /// the same map (the store's layout does not change what a search finds).
    pub(crate) fn add_and_remove_far(
        &mut self,
        points: &[Vector3<f64>],
        world_from_sensor: &Isometry3<f64>,
        centre: &Vector3<f64>,
        radius: f64,
    ) {
        self.insert_points(points, world_from_sensor);
        self.forget_far(centre, radius);
        self.reindex();
    }

    /// The per-voxel part of [`VoxelMap::add`].
    fn insert_points(&mut self, points: &[Vector3<f64>], world_from_sensor: &Isometry3<f64>) {
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
    }

    /// Forgets the voxels whose first point is farther than `radius` from `centre`: the map then
    /// covers what the sensor can see from there, whatever the length of the drive.
    pub(crate) fn remove_far(&mut self, centre: &Vector3<f64>, radius: f64) {
        self.forget_far(centre, radius);
        self.reindex();
    }

    /// The per-voxel part of [`VoxelMap::remove_far`].
    fn forget_far(&mut self, centre: &Vector3<f64>, radius: f64) {
        let radius_sq = radius * radius;
        self.voxels.retain(|_, points| {
            points
                .first()
                .is_some_and(|p| (p - centre).norm_squared() <= radius_sq)
        });
    }

    /// The map points within `radius` (at most a voxel edge) of `point`, from the 27 voxels
    /// around it, into `out` (cleared first): voxel by voxel in [`NEIGHBOURS`] order, each
    /// voxel's points in their order. A voxel whose box lies farther than `radius` from `point`
    /// by more than the rounding can reach ([`SKIP_MARGIN_M`], as the search's skip) holds no
    /// such point and is not looked up: the same points as reading all 27.
    pub(crate) fn points_near_into(
        &self,
        point: &Vector3<f64>,
        radius: f64,
        out: &mut Vec<Vector3<f64>>,
    ) {
        out.clear();
        let centre = voxel_of(point, self.inverse_size);
        let radius_sq = radius * radius;
        let scaled = point * self.inverse_size;
        let inside = [
            (scaled.x - f64::from(centre[0])) * self.voxel_size,
            (scaled.y - f64::from(centre[1])) * self.voxel_size,
            (scaled.z - f64::from(centre[2])) * self.voxel_size,
        ];
        let margin = SKIP_MARGIN_M * (1.0 + point.amax() / 1000.0);
        let reach_sq = (radius + margin) * (radius + margin);
        for offset in &NEIGHBOURS {
            let bound_sq = box_distance_sq(offset, inside, self.voxel_size);
            if bound_sq > reach_sq {
                continue;
            }
            let key = [
                centre[0].saturating_add(offset[0]),
                centre[1].saturating_add(offset[1]),
                centre[2].saturating_add(offset[2]),
            ];
            let Some(&(start, count)) = self.ranges.get(&key) else {
                continue;
            };
            let points = &self.flat[start as usize..(start + count) as usize];
            out.extend(
                points
                    .iter()
                    .filter(|p| (*p - point).norm_squared() <= radius_sq),
            );
        }
    }

    /// The nearest map point to `query` within the 27 voxels around it, if closer than
    /// `sqrt(max_distance_sq)`; with its squared distance.
    pub(crate) fn nearest(
        &self,
        query: &Vector3<f64>,
        max_distance_sq: f64,
    ) -> Option<(Vector3<f64>, f64)> {
        self.nearest_around(query, max_distance_sq, &mut Neighbourhood::default())
    }

    /// [`VoxelMap::nearest`] for a query that `around` followed before: the same answer, bit for
    /// bit, found with less work.
    ///
    /// The 27 voxels are looked up again only when the query has left the voxel `around` was
    /// resolved for. And the search itself is skipped while the query stays in that voxel and
    /// within the move that cannot change its answer (see [`Kept`]): the kept nearest point is
    /// returned with its distance computed as the search computes it, `None` when that is not
    /// below `max_distance_sq`.
    pub(crate) fn nearest_around(
        &self,
        query: &Vector3<f64>,
        max_distance_sq: f64,
        around: &mut Neighbourhood,
    ) -> Option<(Vector3<f64>, f64)> {
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
            around.kept = None;
        }
        if let Some(kept) = &around.kept
            && kept.max_distance_sq == max_distance_sq
            && (query - kept.query).norm_squared() < kept.free_move_sq
        {
            return kept.nearest.and_then(|point| {
                let distance_sq = (point - query).norm_squared();
                (distance_sq < max_distance_sq).then_some((point, distance_sq))
            });
        }
        // Position inside the voxel, in metres from its lower corner, per axis.
        let scaled = query * self.inverse_size;
        let inside = [
            (scaled.x - f64::from(centre[0])) * self.voxel_size,
            (scaled.y - f64::from(centre[1])) * self.voxel_size,
            (scaled.z - f64::from(centre[2])) * self.voxel_size,
        ];
        // The search proper (`best`, `best_sq`, the voxels it visits) is the plain nearest
        // search; beside it `others_sq` bounds from below the squared distance of every other
        // point of the 27 voxels within `wide_sq` (those beyond `wide_sq` are not looked at).
        let wide = max_distance_sq.sqrt() * WIDE_FACTOR;
        let wide_sq = wide * wide;
        let mut best: Option<Vector3<f64>> = None;
        let mut best_sq = max_distance_sq;
        let mut others_sq = wide_sq.max(max_distance_sq);
        for (&(start, count), offset) in around.ranges.iter().zip(&NEIGHBOURS) {
            if count == 0 {
                continue;
            }
            // Distance from the query to the neighbour voxel's box: a lower bound on any of its
            // points' distances.
            let bound_sq = box_distance_sq(offset, inside, self.voxel_size);
            // `others_sq >= best_sq` always (a point that does not become the nearest is at
            // least as far, and a replaced nearest was farther than its successor), so this
            // skips no voxel the plain search visits.
            if bound_sq >= others_sq {
                continue;
            }
            // The plain search visits this voxel.
            let searched = bound_sq < best_sq;
            let (start, count) = (start as usize, count as usize);
            for point in &self.flat[start..start + count] {
                let distance_sq = (point - query).norm_squared();
                if searched && distance_sq < best_sq {
                    if best.is_some() {
                        others_sq = others_sq.min(best_sq);
                    }
                    best_sq = distance_sq;
                    best = Some(*point);
                } else {
                    others_sq = others_sq.min(distance_sq);
                }
            }
        }
        around.kept = Some(Kept::after_search(
            query,
            max_distance_sq,
            best.map(|p| (p, best_sq)),
            others_sq,
        ));
        best.map(|p| (p, best_sq))
    }
}

/// How far the search bounds the other points, as a multiple of the correspondence distance `r`:
/// a query with no map point within `r` may then move by up to a quarter of `r` without a new
/// search, where with `r` alone it would search every time. On KITTI 0013 this took the full
/// searches from 739,022 to 456,961 of 4,295,490 (1.5 and 2: 455,443 and 455,442).
const WIDE_FACTOR: f64 = 1.25;

/// The rounding allowance of the skip (metres). The distances it compares are computed in f64,
/// with errors of about 1e-16 of the coordinates (1e-13 m a kilometre from the origin); the
/// allowance, `SKIP_MARGIN_M · (1 + |coordinate| / 1 km)`, is far above that at any scale and
/// far below the millimetres a point moves in an iteration.
const SKIP_MARGIN_M: f64 = 1e-6;

/// The answer of a query point's last full search, and how far the query may move from where
/// it was without changing that answer.
///
/// Triangle inequality: with `d₁` the distance to the nearest point `p` (within the
/// correspondence distance `r`) and `L` a lower bound on every other point's distance, after a
/// move of `m` the nearest is at most `d₁ + m` away and the others at least `L − m`; so `p` is
/// still strictly the nearest while `m < (L − d₁) / 2`, and every other point stays beyond `r`
/// while `m < L − r` (which also keeps an empty answer empty). The search's own answer at the
/// new position is then `p` when its distance, computed as the search computes it, is below
/// `r`, and none otherwise: no tie can arise and the voxel-box pruning cannot hide `p`, since
/// every inequality holds with [`SKIP_MARGIN_M`] to spare.
#[derive(Debug, Clone, Copy)]
struct Kept {
    query: Vector3<f64>,
    max_distance_sq: f64,
    nearest: Option<Vector3<f64>>,
    /// Squared move below which the answer stands; negative when none.
    free_move_sq: f64,
}

impl Kept {
    fn after_search(
        query: &Vector3<f64>,
        max_distance_sq: f64,
        nearest: Option<(Vector3<f64>, f64)>,
        others_sq: f64,
    ) -> Self {
        let scale = query.amax() + others_sq.sqrt();
        let margin = SKIP_MARGIN_M * (1.0 + scale * 1e-3);
        let others = others_sq.sqrt();
        let beyond_reach = others - max_distance_sq.sqrt() - margin;
        let free_move = match nearest {
            Some((_, nearest_sq)) => beyond_reach.max(0.5 * (others - nearest_sq.sqrt() - margin)),
            None => beyond_reach,
        };
        Self {
            query: *query,
            max_distance_sq,
            nearest: nearest.map(|(p, _)| p),
            free_move_sq: if free_move > 0.0 {
                free_move * free_move
            } else {
                -1.0
            },
        }
    }
}

/// What a query point keeps across a registration's iterations, in which it moves by
/// millimetres and mostly stays in its voxel: the search store's ranges of the 27 voxels around
/// its voxel (`NEIGHBOURS` order, empty where the map has no voxel), and its last full search
/// ([`Kept`]). Valid for one state of the map.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Neighbourhood {
    centre: Option<VoxelKey>,
    ranges: [(u32, u32); 27],
    kept: Option<Kept>,
}

/// Squared distance from a point at `inside` (metres from its voxel's lower corner, per axis)
/// to the box of the neighbouring voxel at `offset`: a lower bound on the squared distance of
/// any of that voxel's points.
fn box_distance_sq(offset: &[i32; 3], inside: [f64; 3], voxel_size: f64) -> f64 {
    let mut bound_sq = 0.0;
    for axis in 0..3 {
        let gap = match offset[axis] {
            -1 => inside[axis],
            1 => voxel_size - inside[axis],
            _ => 0.0,
        };
        bound_sq += gap * gap;
    }
    bound_sq
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_to_i32_is_floor_then_a_saturating_cast() {
        let two_31 = 2_f64.powi(31);
        let two_53 = 2_f64.powi(53);
        let edges = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1e-300,
            0.999_999_999_999_999_9,
            -0.999_999_999_999_999_9,
            two_31 - 0.5,
            two_31,
            -two_31,
            -two_31 - 0.5,
            -two_31 + 0.5,
            two_53 + 2.0,
            -two_53 - 2.0,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MIN_POSITIVE,
        ];
        for value in edges {
            assert_eq!(floor_to_i32(value), value.floor() as i32, "{value}");
        }
        let mut state = 3_u64;
        for _ in 0..100_000 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let unit = (state >> 11) as f64 / (1u64 << 53) as f64;
            // Coordinates over ±2000 voxels, with a quarter of them exactly on a boundary.
            let value = if state & 3 == 0 {
                (unit * 4000.0 - 2000.0).round()
            } else {
                unit * 4000.0 - 2000.0
            };
            assert_eq!(floor_to_i32(value), value.floor() as i32, "{value}");
        }
    }

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
    fn downsample_keeps_each_voxels_lowest_rank_when_voxels_recur() {
        // Runs of points in one voxel, and voxels visited again after others (as a ring comes
        // back to an object): the kept point of a voxel is its lowest-ranked one wherever it
        // came, as a plain pass over all points finds it.
        let points: Vec<Vector3<f64>> = (0..3000)
            .map(|i| {
                let i = f64::from(i);
                Vector3::new(
                    (i * 0.013) % 3.0,
                    (i * 0.0007) % 2.0,
                    0.5 * ((i / 50.0) % 2.0),
                )
            })
            .collect();
        let mut lowest: HashMap<VoxelKey, (u64, usize)> = HashMap::new();
        for (index, point) in points.iter().enumerate() {
            let candidate = (scramble(index as u64), index);
            let entry = lowest.entry(voxel_of(point, 2.0)).or_insert(candidate);
            *entry = (*entry).min(candidate);
        }
        let mut expected: Vec<usize> = lowest.into_values().map(|(_, index)| index).collect();
        expected.sort_unstable();
        assert!(expected.len() > 20);
        assert_eq!(downsample(&points, 0.5), expected);
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
    fn points_near_skips_only_voxels_that_hold_no_near_point() {
        // Every map point and every query on a lattice of quarter voxels, so that many lie
        // exactly on voxel faces and exactly at the radius: the voxels read must still give
        // every point within the radius, in the order of reading all 27.
        let mut map = VoxelMap::new(1.0, 1000);
        let lattice: Vec<Vector3<f64>> = (-8..8)
            .flat_map(|x| (-8..8).flat_map(move |y| (-4..4).map(move |z| [x, y, z])))
            .map(|[x, y, z]| Vector3::new(f64::from(x), f64::from(y), f64::from(z)) * 0.25)
            .collect();
        map.add(&lattice, &Isometry3::identity());
        let mut near = Vec::new();
        for query in lattice.iter().step_by(7) {
            for radius in [0.25, 0.5, 1.0] {
                let centre = voxel_of(query, 1.0);
                let all: Vec<Vector3<f64>> = NEIGHBOURS
                    .iter()
                    .filter_map(|o| {
                        map.ranges
                            .get(&[centre[0] + o[0], centre[1] + o[1], centre[2] + o[2]])
                    })
                    .flat_map(|&(start, count)| &map.flat[start as usize..(start + count) as usize])
                    .filter(|p| (*p - query).norm_squared() <= radius * radius)
                    .copied()
                    .collect();
                map.points_near_into(query, radius, &mut near);
                assert_eq!(near, all, "{query:?} {radius}");
                assert!(!near.is_empty());
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

    /// Where the last full search was made for `around`.
    fn searched_at(around: &Neighbourhood) -> Option<Vector3<f64>> {
        around.kept.map(|kept| kept.query)
    }

    #[test]
    fn a_small_move_keeps_the_nearest_without_a_search() {
        // Two map points on a line: A at x = 0.5, B at x = 0.9.
        let (a, b) = (Vector3::new(0.5, 0.5, 0.5), Vector3::new(0.9, 0.5, 0.5));
        let mut map = VoxelMap::new(1.0, 20);
        map.add(&[a, b], &Isometry3::identity());
        let mut around = Neighbourhood::default();
        // At x = 0.4: A at 0.1, B at 0.5, so the answer stands for any move below
        // (0.5 − 0.1) / 2 = 0.2 (less the 1 µm margin).
        let first = Vector3::new(0.4, 0.5, 0.5);
        let found = map.nearest_around(&first, 1.0, &mut around);
        assert_eq!(found, Some((a, (a - first).norm_squared())));
        let free = around.kept.map(|kept| kept.free_move_sq.sqrt());
        assert!(free.is_some_and(|f| (f - 0.2).abs() < 1e-5), "{free:?}");
        // 0.05 along x and y (0.0707 in all): no search, and the answer a search gives.
        let moved = Vector3::new(0.45, 0.55, 0.5);
        let kept = map.nearest_around(&moved, 1.0, &mut around);
        assert_eq!(searched_at(&around), Some(first));
        assert_eq!(kept, map.nearest(&moved, 1.0));
        assert_eq!(kept, Some((a, (a - moved).norm_squared())));
        // 0.199 from the first search, still no search.
        let moved = Vector3::new(0.599, 0.5, 0.5);
        let kept = map.nearest_around(&moved, 1.0, &mut around);
        assert_eq!(searched_at(&around), Some(first));
        assert_eq!(kept, map.nearest(&moved, 1.0));
    }

    #[test]
    fn a_move_beyond_half_the_gap_searches_again() {
        let (a, b) = (Vector3::new(0.5, 0.5, 0.5), Vector3::new(0.9, 0.5, 0.5));
        let mut map = VoxelMap::new(1.0, 20);
        map.add(&[a, b], &Isometry3::identity());
        let mut around = Neighbourhood::default();
        map.nearest_around(&Vector3::new(0.4, 0.5, 0.5), 1.0, &mut around);
        // 0.21 from the search at 0.4 (more than 0.2): A is still the nearest (0.11 against
        // 0.29), but that is now found by a search, which leaves a free move of 0.09.
        let second = Vector3::new(0.61, 0.5, 0.5);
        let found = map.nearest_around(&second, 1.0, &mut around);
        assert_eq!(searched_at(&around), Some(second));
        assert_eq!(found, Some((a, (a - second).norm_squared())));
        // 0.12 further on, past the middle of A and B: B, by a new search.
        let third = Vector3::new(0.73, 0.5, 0.5);
        let found = map.nearest_around(&third, 1.0, &mut around);
        assert_eq!(searched_at(&around), Some(third));
        assert_eq!(found, Some((b, (b - third).norm_squared())));
    }

    #[test]
    fn leaving_the_voxel_or_changing_the_distance_searches_again() {
        // A in voxel 0, C just across the boundary in voxel 1: from x = 0.95 a move of 0.1
        // is within half the gap (C at 0.15, no other point within 1 m) but changes voxel.
        let (a, c) = (Vector3::new(0.5, 0.5, 0.5), Vector3::new(1.1, 0.5, 0.5));
        let mut map = VoxelMap::new(1.0, 20);
        map.add(&[a, c], &Isometry3::identity());
        let mut around = Neighbourhood::default();
        map.nearest_around(&Vector3::new(0.99, 0.5, 0.5), 1.0, &mut around);
        let across = Vector3::new(1.01, 0.5, 0.5);
        let found = map.nearest_around(&across, 1.0, &mut around);
        assert_eq!(searched_at(&around), Some(across));
        assert_eq!(found, Some((c, (c - across).norm_squared())));
        // Same place, another correspondence distance: a new search, and now nothing (C is
        // 0.09 away).
        let found = map.nearest_around(&across, 0.005, &mut around);
        assert_eq!(found, None);
        assert_eq!(around.kept.map(|kept| kept.max_distance_sq), Some(0.005));
    }

    #[test]
    fn a_tie_is_never_skipped() {
        // The query halfway between A and B: no move keeps the answer certain, so every call
        // searches, and the search's tie rule (the first found) decides.
        let (a, b) = (Vector3::new(0.5, 0.5, 0.5), Vector3::new(0.9, 0.5, 0.5));
        let mut map = VoxelMap::new(1.0, 20);
        map.add(&[a, b], &Isometry3::identity());
        let mut around = Neighbourhood::default();
        let middle = Vector3::new(0.7, 0.5, 0.5);
        let found = map.nearest_around(&middle, 1.0, &mut around);
        assert_eq!(found, map.nearest(&middle, 1.0));
        assert!(around.kept.is_some_and(|kept| kept.free_move_sq < 0.0));
        let nudged = Vector3::new(0.7, 0.5, 0.500_000_1);
        map.nearest_around(&nudged, 1.0, &mut around);
        assert_eq!(searched_at(&around), Some(nudged));
    }

    #[test]
    fn the_correspondence_distance_is_checked_with_the_new_distance() {
        // A alone: from x = 0.12 it is 0.38 away, within r = 0.4, and nothing else is within
        // 1.25 r = 0.5, so the query may move by 0.5 − 0.4 = 0.1 without a search. At x = 0.08
        // A is 0.42 away: beyond r, so none, as a search says; back at 0.13, A again.
        let a = Vector3::new(0.5, 0.5, 0.5);
        let mut map = VoxelMap::new(1.0, 20);
        map.add(&[a], &Isometry3::identity());
        let max_sq = 0.4 * 0.4;
        let mut around = Neighbourhood::default();
        let first = Vector3::new(0.12, 0.5, 0.5);
        let found = map.nearest_around(&first, max_sq, &mut around);
        assert_eq!(found, Some((a, (a - first).norm_squared())));
        let free = around.kept.map(|kept| kept.free_move_sq.sqrt());
        assert!(free.is_some_and(|f| (f - 0.1).abs() < 1e-5), "{free:?}");
        let out = Vector3::new(0.08, 0.5, 0.5);
        assert_eq!(map.nearest_around(&out, max_sq, &mut around), None);
        assert_eq!(map.nearest(&out, max_sq), None);
        let back = Vector3::new(0.13, 0.5, 0.5);
        let found = map.nearest_around(&back, max_sq, &mut around);
        assert_eq!(found, Some((a, (a - back).norm_squared())));
        assert_eq!(found, map.nearest(&back, max_sq));
        assert_eq!(searched_at(&around), Some(first));
    }

    #[test]
    fn a_walk_in_small_steps_finds_what_fresh_searches_find_with_fewer_searches() {
        // Random map points over 4 × 4 × 2 voxels and queries walking in steps of about a
        // millimetre to a centimetre, as a registration's points do, for three correspondence
        // distances: every answer bit for bit a fresh search's.
        let mut state = 7_u64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut map = VoxelMap::new(1.0, 20);
        let cloud: Vec<Vector3<f64>> = (0..600)
            .map(|_| Vector3::new(next() * 4.0, next() * 4.0, next() * 2.0))
            .collect();
        map.add(&cloud, &Isometry3::identity());
        let (mut calls, mut searches) = (0, 0);
        for max_distance in [0.1, 0.3, 1.0] {
            let max_sq = max_distance * max_distance;
            for _ in 0..50 {
                let mut query = Vector3::new(next() * 4.0, next() * 4.0, next() * 2.0);
                let step = 0.001 + 0.01 * next();
                let direction =
                    Vector3::new(next() - 0.5, next() - 0.5, next() - 0.5).normalize() * step;
                let mut around = Neighbourhood::default();
                for _ in 0..40 {
                    let before = searched_at(&around);
                    let kept = map.nearest_around(&query, max_sq, &mut around);
                    assert_eq!(
                        kept,
                        map.nearest(&query, max_sq),
                        "{query:?} {max_distance}"
                    );
                    calls += 1;
                    searches += usize::from(searched_at(&around) != before);
                    query += direction;
                }
            }
        }
        assert_eq!(calls, 6000);
        // 1,512 searches for the 6,000 answers when written.
        assert!(searches < calls / 3, "{searches} searches");
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
    fn adding_and_removing_in_one_go_gives_the_map_of_the_two_steps() {
        let cloud: Vec<Vector3<f64>> = (0..400)
            .map(|i| {
                let t = f64::from(i);
                Vector3::new((t * 0.37) % 30.0 - 15.0, (t * 0.91) % 20.0 - 10.0, t % 3.0)
            })
            .collect();
        let pose = Isometry3::translation(0.5, -0.25, 0.0);
        let (centre, radius) = (Vector3::new(3.0, 1.0, 0.0), 9.0);
        let mut two_steps = VoxelMap::new(1.0, 20);
        two_steps.add(&cloud[..200], &Isometry3::identity());
        let mut one_go = two_steps.clone();
        two_steps.add(&cloud[200..], &pose);
        let added = two_steps.voxel_count();
        two_steps.remove_far(&centre, radius);
        // Some voxels were added and some forgotten.
        assert!(added > one_go.voxel_count() && two_steps.voxel_count() < added);
        one_go.add_and_remove_far(&cloud[200..], &pose, &centre, radius);
        assert_eq!(one_go.voxel_count(), two_steps.voxel_count());
        for (key, points) in &two_steps.voxels {
            assert_eq!(one_go.voxels.get(key), Some(points));
            let (start, count) = one_go.ranges[key];
            assert_eq!(
                &one_go.flat[start as usize..(start + count) as usize],
                &points[..]
            );
        }
        assert_eq!(one_go.flat.len(), two_steps.flat.len());
        assert_eq!(one_go.ranges.len(), two_steps.ranges.len());
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
