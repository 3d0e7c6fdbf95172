//! Moving state between the grids and the block being stepped: [`CellRun`], the grids' planes
//! over a run of cells; [`Block`], the stack buffer one block is stepped in, loaded from the
//! planes that may not be +0 and stored back where they changed; and memory brought in ahead
//! of the work (a prefetch per block on AVX2, tiles read plane by plane otherwise).

use super::evidence::SensorEvidence;
use super::lanes::{any_bits, for_each_bit};
use super::passes::{ALL_SETS, BLOCK, BlockMasses, Lanes, Live};
use crate::grids::{
    CONFLICT_FO_BIT, CONFLICT_OF_BIT, MASS_BITS, N_SETS, OMEGA, OMEGA_BIT, PerceptionPlanesMut,
    PlaneBits, ZETA_BIT,
};
use crate::label::Label;
use geodata::MapContext;

/// A run of consecutive storage cells: the unit of parallel work.
pub(super) struct CellRun<'a> {
    pub(super) pg: PerceptionPlanesMut<'a>,
    pub(super) m_free: &'a [f32],
    pub(super) m_occupied: &'a [f32],
    /// Per block, whether the SensorGrid may hold mass there (false: its planes are 0 and are
    /// not read).
    pub(super) sensor_blocks: &'a [bool],
    pub(super) context: &'a [MapContext],
    /// Where to write the decision of each cell, if wanted.
    pub(super) decisions: Option<&'a mut [Label]>,
    /// Every mass outside the [`REACHABLE`](super::passes::REACHABLE) sets is +0 (see
    /// `step_cells`).
    pub(super) reachable_only: bool,
}

impl CellRun<'_> {
    /// Asks `prefetch` for every cache line the block at `start` will read, if the run has one
    /// there.
    #[inline(always)]
    pub(super) fn prefetch_block(
        &self,
        start: usize,
        planes: PlaneBits,
        prefetch: &impl Fn(*const i8),
    ) {
        const F32_PER_LINE: usize = 64 / 4;
        let Some(&stored) = self.pg.nonzero.get(start / BLOCK) else {
            return;
        };
        let cells = start..(start + BLOCK).min(self.m_free.len());
        let pg = &self.pg;
        let lines = |plane: &[f32]| {
            let cells = &plane[cells.clone()];
            for line in 0..cells.len().div_ceil(F32_PER_LINE) {
                prefetch(cells.as_ptr().wrapping_add(line * F32_PER_LINE).cast());
            }
        };
        for_each_bit(stored & planes & MASS_BITS, |set| lines(pg.masses[set]));
        for (bit, plane) in [
            (ZETA_BIT, &pg.zeta),
            (CONFLICT_FO_BIT, &pg.conflict_fo),
            (CONFLICT_OF_BIT, &pg.conflict_of),
        ] {
            if stored & planes & bit != 0 {
                lines(plane);
            }
        }
        if self.sensor_blocks[start / BLOCK] {
            lines(self.m_free);
            lines(self.m_occupied);
        }
        prefetch(pg.seen[cells.clone()].as_ptr().cast());
        prefetch(self.context[cells].as_ptr().cast());
    }

    /// Reads one value per cache line of every plane in `cells`, one plane after the other.
    ///
    /// The step reads ~40 planes at once, more streams than the hardware prefetcher follows;
    /// touching a tile plane by plane first turns that into sequential reads, and the blocks
    /// of the tile then find their lines in cache. The values are summed as bits (integer
    /// additions, no floating-point dependency chain) only so that the reads are not elided.
    #[inline(always)]
    pub(super) fn warm(&self, cells: std::ops::Range<usize>, planes: PlaneBits) {
        const F32_PER_LINE: usize = 64 / 4;
        let mut checksum = 0u32;
        let pg = &self.pg;
        let state = [
            (ZETA_BIT, &pg.zeta[..]),
            (CONFLICT_FO_BIT, &pg.conflict_fo[..]),
            (CONFLICT_OF_BIT, &pg.conflict_of[..]),
        ];
        let f32_planes = (pg.masses.iter().enumerate())
            .map(|(set, plane)| (1 << set, &plane[..]))
            .chain(state)
            .filter(|(bit, _)| planes & bit != 0)
            .map(|(_, plane)| plane)
            .chain([self.m_free, self.m_occupied]);
        for plane in f32_planes {
            for value in plane[cells.clone()].iter().step_by(F32_PER_LINE) {
                checksum = checksum.wrapping_add(value.to_bits());
            }
        }
        for i in cells.step_by(64) {
            checksum = checksum
                .wrapping_add(u32::from(self.pg.seen[i]))
                .wrapping_add(self.context[i] as u32);
        }
        std::hint::black_box(checksum);
    }
}

/// The state of up to [`BLOCK`] cells, one lane each; lanes past the run's end are vacuous
/// padding, computed and discarded.
pub(super) struct Block {
    pub(super) m: BlockMasses,
    pub(super) zeta: Lanes,
    pub(super) conflict_fo: Lanes,
    pub(super) conflict_of: Lanes,
    pub(super) seen: [u8; BLOCK],
    pub(super) sensor_free: Lanes,
    pub(super) sensor_occupied: Lanes,
    pub(super) context: [MapContext; BLOCK],
    /// Scratch for stages 1-2, kept here so that it is not rebuilt (and moved) for every block.
    pub(super) sensor: SensorEvidence,
    /// Lanes holding real cells.
    pub(super) len: usize,
    /// The focal sets that may hold mass in this block (`live_sets` and `reachable_this_step` in
    /// `fuse`).
    pub(super) live: Live,
    /// The planes of `m` and `zeta` that may not be +0 in the buffer (from the last block).
    buffered: PlaneBits,
    /// The block's non-zero plane bits before the step.
    pub(super) stored_masses: PlaneBits,
}

/// Copies a run of at most [`BLOCK`] values into lanes; a full block is one fixed-size copy,
/// which compiles to a few vector moves instead of a call to `memcpy`.
#[inline(always)]
fn load_lanes<T: Copy>(lanes: &mut [T; BLOCK], values: &[T]) {
    match <&[T; BLOCK]>::try_from(values) {
        Ok(full) => *lanes = *full,
        Err(_) => load_partial(lanes, values),
    }
}

/// The reverse of [`load_lanes`].
#[inline(always)]
fn store_lanes<T: Copy>(values: &mut [T], lanes: &[T; BLOCK]) {
    match <&mut [T; BLOCK]>::try_from(&mut *values) {
        Ok(full) => *full = *lanes,
        Err(_) => store_partial(values, lanes),
    }
}

/// Writes `lanes` over `values`, if `compare` only where a bit differs; returns whether it
/// wrote. A cache line that is only read stays clean and is never written back to memory: far
/// from the sensor a block often reaches its fixed point (the map prior, discounted), and its
/// planes stop changing.
#[inline(always)]
fn store_if_changed(values: &mut [f32], lanes: &Lanes, compare: bool) -> bool {
    let Ok(full) = <&mut Lanes>::try_from(&mut *values) else {
        store_partial(values, lanes);
        return true;
    };
    if !compare {
        *full = *lanes;
        return true;
    }
    // The differing bits, OR-ed eight lanes at a time (one vector register).
    let mut differ = [0u32; 8];
    for (old, new) in full.chunks_exact(8).zip(lanes.chunks_exact(8)) {
        for ((acc, a), b) in differ.iter_mut().zip(old).zip(new) {
            *acc |= a.to_bits() ^ b.to_bits();
        }
    }
    if differ.iter().fold(0, |all, &d| all | d) == 0 {
        return false;
    }
    *full = *lanes;
    true
}

// The last, partial block of a run, out of line: inlined, its variable-length copy and the full
// block's fixed one were merged into one `memcpy` call for every plane of every block.
#[cold]
#[inline(never)]
fn load_partial<T: Copy>(lanes: &mut [T; BLOCK], values: &[T]) {
    lanes[..values.len()].copy_from_slice(values);
}

#[cold]
#[inline(never)]
fn store_partial<T: Copy>(values: &mut [T], lanes: &[T; BLOCK]) {
    values.copy_from_slice(&lanes[..values.len()]);
}

impl Block {
    #[inline(always)]
    pub(super) fn vacuous() -> Block {
        let mut m = [[0.0; BLOCK]; N_SETS];
        m[OMEGA] = [1.0; BLOCK];
        Block {
            m,
            zeta: [0.0; BLOCK],
            conflict_fo: [0.0; BLOCK],
            conflict_of: [0.0; BLOCK],
            seen: [0; BLOCK],
            sensor_free: [0.0; BLOCK],
            sensor_occupied: [0.0; BLOCK],
            context: [MapContext::Unknown; BLOCK],
            sensor: SensorEvidence::zeroed(),
            len: 0,
            live: ALL_SETS,
            buffered: OMEGA_BIT,
            stored_masses: MASS_BITS,
        }
    }

    /// Loads the cells' state: the mass planes and ζ named in `planes`; the others are +0 in
    /// the grid, and are made +0 in the buffer where the last block left something. Returns the
    /// bytes read.
    #[inline(always)]
    pub(super) fn load(
        &mut self,
        run: &CellRun<'_>,
        cells: std::ops::Range<usize>,
        mut planes: PlaneBits,
    ) -> u64 {
        self.len = cells.len();
        if self.len < BLOCK {
            // Only the last block of the grid: pad with vacuous cells, not the previous block,
            // and read every plane (the padding's m(Ω) = 1 is not the real cells').
            *self = Block::vacuous();
            self.len = cells.len();
            planes |= MASS_BITS | ZETA_BIT;
        }
        self.stored_masses = planes & MASS_BITS;
        for_each_bit(planes & MASS_BITS, |set| {
            load_lanes(&mut self.m[set], &run.pg.masses[set][cells.clone()]);
        });
        for_each_bit(self.buffered & !planes & MASS_BITS, |set| {
            self.m[set] = [0.0; BLOCK];
        });
        if planes & ZETA_BIT != 0 {
            load_lanes(&mut self.zeta, &run.pg.zeta[cells.clone()]);
        } else {
            self.zeta = [0.0; BLOCK];
        }
        load_lanes(&mut self.seen, &run.pg.seen[cells.clone()]);
        // A block the SensorGrid knows to be vacuous is not read.
        let sensor_read = run.sensor_blocks[cells.start / BLOCK];
        if sensor_read {
            load_lanes(&mut self.sensor_free, &run.m_free[cells.clone()]);
            load_lanes(&mut self.sensor_occupied, &run.m_occupied[cells.clone()]);
        } else {
            self.sensor_free = [0.0; BLOCK];
            self.sensor_occupied = [0.0; BLOCK];
        }
        load_lanes(&mut self.context, &run.context[cells.clone()]);
        // The state planes named, the SensorGrid planes if read; seen and the context, a byte each.
        let f32_planes =
            (planes & (MASS_BITS | ZETA_BIT)).count_ones() + 2 * u32::from(sensor_read);
        cells.len() as u64 * (4 * u64::from(f32_planes) + 2)
    }

    /// The planes that may not be +0 after the step: those of `live` with a lane whose bits are
    /// not all zero (a -0 counts), the others as they were (`before`).
    #[inline(always)]
    pub(super) fn nonzero(&mut self, before: PlaneBits) -> PlaneBits {
        let live = PlaneBits::from(self.live);
        let mut bits = before & MASS_BITS & !live;
        for_each_bit(live, |set| {
            if any_bits(&self.m[set]) {
                bits |= 1 << set;
            }
        });
        for (bit, lanes) in [
            (ZETA_BIT, &self.zeta),
            (CONFLICT_FO_BIT, &self.conflict_fo),
            (CONFLICT_OF_BIT, &self.conflict_of),
        ] {
            if any_bits(lanes) {
                bits |= bit;
            }
        }
        self.buffered = bits & (MASS_BITS | ZETA_BIT);
        bits
    }

    /// Writes back the planes named in `planes` (those that were or became non-zero) where they
    /// changed, and the seen flags if the scan reached the block; returns the bytes written.
    #[inline(always)]
    pub(super) fn store(
        &self,
        run: &mut CellRun<'_>,
        cells: std::ops::Range<usize>,
        planes: PlaneBits,
    ) -> u64 {
        let planes = planes & (PlaneBits::from(self.live) | !MASS_BITS);
        // A block the scan reached changes: comparing first would only cost.
        let compare = !self.sensor.any_observed;
        let mut written = 0u32;
        for_each_bit(planes & MASS_BITS, |set| {
            let plane = &mut run.pg.masses[set][cells.clone()];
            written += u32::from(store_if_changed(plane, &self.m[set], compare));
        });
        let pg = &mut run.pg;
        for (bit, plane, lanes) in [
            (ZETA_BIT, &mut pg.zeta, &self.zeta),
            (CONFLICT_FO_BIT, &mut pg.conflict_fo, &self.conflict_fo),
            (CONFLICT_OF_BIT, &mut pg.conflict_of, &self.conflict_of),
        ] {
            if planes & bit != 0 {
                written += u32::from(store_if_changed(&mut plane[cells.clone()], lanes, compare));
            }
        }
        // `seen` only changes where the scan saw a cell.
        let seen_written = self.sensor.any_observed;
        if seen_written {
            store_lanes(&mut pg.seen[cells.clone()], &self.seen);
        }
        let cells = cells.len() as u64;
        cells * (4 * u64::from(written) + u64::from(seen_written))
    }
}
