//! Storage of the three grids: structure-of-arrays over one W × H layout (SPEC §2).
//!
//! Each grid stores one plane per quantity, every plane indexed `storage_row · W + storage_col`.
//! How a world cell maps to a storage cell (the circular buffer) is the window's business; the
//! fusion step only walks the storage linearly. Meaning sits on top: these types know the frame
//! Ω_PG only through the plane index, which is the focal set's bitmask
//! (F = bit 0, I = bit 1, U = bit 2, S = bit 3, M = bit 4; plane 0 is ∅).
//!
//! Memory per cell: PerceptionGrid 32 mass planes + ζ + ∅_FO + ∅_OF (4 bytes each) + the seen
//! flag (1 byte) + 8 bytes of non-zero plane bits per 64 cells = 141.125 bytes; SensorGrid
//! 8 bytes + 1 byte per 64 cells; GisGrid 1 byte: 150.14 bytes in all. The step updates the PerceptionGrid in place,
//! so there is no second copy.

use geodata::MapContext;
use std::ops::Range;

/// Number of focal sets of Ω_PG = {F, I, U, S, M}: one mass plane each.
pub const N_SETS: usize = 32;
/// Bitmask of Ω_PG, the index of the plane m(Ω).
pub const OMEGA: usize = 31;

/// Bit of each class of Ω_PG, in frame order.
pub mod class {
    /// F, free space.
    pub const F: usize = 1;
    /// I, mapped infrastructure (buildings).
    pub const I: usize = 1 << 1;
    /// U, unmapped infrastructure.
    pub const U: usize = 1 << 2;
    /// S, stopped objects.
    pub const S: usize = 1 << 3;
    /// M, moving objects.
    pub const M: usize = 1 << 4;
    /// O = {I, U, S, M}, occupied (the refinement of the sensor's O, eq 18).
    pub const O: usize = I | U | S | M;
    /// Class letters in frame order (bit 0 first).
    pub const LETTERS: [char; 5] = ['F', 'I', 'U', 'S', 'M'];
}

/// The PerceptionGrid: a mass function on Ω_PG per cell, with the accumulator ζ, the last
/// conflict masses ∅_FO and ∅_OF, and whether the cell was ever observed.
#[derive(Clone, Debug)]
pub struct PerceptionGrid {
    width: usize,
    height: usize,
    /// The 32 mass planes one after the other: plane `set` is
    /// `masses[set·len .. (set+1)·len]`.
    masses: Vec<f32>,
    zeta: Vec<f32>,
    conflict_fo: Vec<f32>,
    conflict_of: Vec<f32>,
    seen: Vec<u8>,
    /// Per block of [`CELLS_PER_BLOCK`] storage cells, the planes that may hold a value other
    /// than +0 there: bit `set` for m(set), then [`ZETA_BIT`], [`CONFLICT_FO_BIT`] and
    /// [`CONFLICT_OF_BIT`]. A clear bit is a promise that the plane is +0 in every cell of the
    /// block, so that a step neither reads nor writes it there: far from the sensor a cell holds
    /// mass on two or three of the 32 sets.
    nonzero: Vec<PlaneBits>,
    /// Whether a mass may lie outside the 17 focal sets that a vacuous grid can reach when it is
    /// discounted to Ω (see `step`): false as long as only vacuous resets and such steps wrote
    /// the masses, so that a step can leave the other 15 planes untouched.
    may_leave_reachable: bool,
}

/// Cells per block of [`PerceptionGrid`]'s non-zero plane bits (and the step's unit of work).
pub(crate) const CELLS_PER_BLOCK: usize = 64;

/// A set of planes of a [`PerceptionGrid`]: bit `set` for m(set), then ζ, ∅_FO, ∅_OF.
pub(crate) type PlaneBits = u64;

/// The bit of m(Ω).
pub(crate) const OMEGA_BIT: PlaneBits = 1 << OMEGA;
/// The bits of the 32 mass planes.
pub(crate) const MASS_BITS: PlaneBits = (1 << N_SETS) - 1;
/// The bit of ζ.
pub(crate) const ZETA_BIT: PlaneBits = 1 << N_SETS;
/// The bit of ∅_FO.
pub(crate) const CONFLICT_FO_BIT: PlaneBits = 1 << (N_SETS + 1);
/// The bit of ∅_OF.
pub(crate) const CONFLICT_OF_BIT: PlaneBits = 1 << (N_SETS + 2);

/// Equal grids hold equal values; `nonzero` and `may_leave_reachable` are only notes on how they
/// were written.
impl PartialEq for PerceptionGrid {
    fn eq(&self, other: &Self) -> bool {
        (self.width, self.height) == (other.width, other.height)
            && self.masses == other.masses
            && self.zeta == other.zeta
            && self.conflict_fo == other.conflict_fo
            && self.conflict_of == other.conflict_of
            && self.seen == other.seen
    }
}

impl PerceptionGrid {
    /// A `width × height` grid whose cells are all vacuous (m(Ω) = 1), with ζ = 0, no conflict,
    /// never observed.
    pub fn new(width: usize, height: usize) -> Self {
        let len = width * height;
        let mut masses = vec![0.0; N_SETS * len];
        masses[OMEGA * len..].fill(1.0);
        Self {
            width,
            height,
            masses,
            zeta: vec![0.0; len],
            conflict_fo: vec![0.0; len],
            conflict_of: vec![0.0; len],
            seen: vec![0; len],
            nonzero: vec![OMEGA_BIT; len.div_ceil(CELLS_PER_BLOCK)],
            may_leave_reachable: false,
        }
    }

    /// Number of columns.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Number of rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Number of cells, `width · height`.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Bytes of the grid's heap storage (what the memory budget counts).
    pub fn heap_bytes(&self) -> usize {
        4 * (self.masses.capacity()
            + self.zeta.capacity()
            + self.conflict_fo.capacity()
            + self.conflict_of.capacity())
            + self.seen.capacity()
            + std::mem::size_of::<PlaneBits>() * self.nonzero.capacity()
    }

    /// True for a grid without cells.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Makes one cell vacuous again (m(Ω) = 1, ζ = 0, no conflict, never observed): for a cell that
    /// enters the window.
    ///
    /// # Panics
    /// If `idx` is not below [`len`](Self::len).
    pub fn reset_cell(&mut self, idx: usize) {
        self.reset_range(idx..idx + 1);
    }

    /// Makes a range of storage cells vacuous again, as [`reset_cell`](Self::reset_cell).
    ///
    /// # Panics
    /// If the range goes past [`len`](Self::len).
    pub fn reset_range(&mut self, range: Range<usize>) {
        let len = self.len();
        assert!(
            range.start <= range.end && range.end <= len,
            "cell range {range:?} outside a grid of {len} cells"
        );
        for (set, plane) in self.masses.chunks_exact_mut(len.max(1)).enumerate() {
            let value = if set == OMEGA { 1.0 } else { 0.0 };
            plane[range.clone()].fill(value);
        }
        self.zeta[range.clone()].fill(0.0);
        self.conflict_fo[range.clone()].fill(0.0);
        self.conflict_of[range.clone()].fill(0.0);
        self.seen[range.clone()].fill(0);
        if range.is_empty() {
            return;
        }
        // A block wholly inside the range is now vacuous; one it only overlaps gained m(Ω).
        let (first, last) = (
            range.start / CELLS_PER_BLOCK,
            (range.end - 1) / CELLS_PER_BLOCK,
        );
        for (block, bits) in self.nonzero[first..=last].iter_mut().enumerate() {
            let start = (first + block) * CELLS_PER_BLOCK;
            let end = (start + CELLS_PER_BLOCK).min(len);
            if range.start <= start && end <= range.end {
                *bits = OMEGA_BIT;
            } else {
                *bits |= OMEGA_BIT;
            }
        }
    }

    /// Makes every cell vacuous again.
    pub fn reset_all(&mut self) {
        self.reset_range(0..self.len());
    }

    /// m(set) at storage cell `idx`; `set` is a bitmask of Ω_PG (see [`class`]).
    ///
    /// # Panics
    /// If `set ≥ 32` or `idx ≥ len`.
    pub fn mass(&self, set: usize, idx: usize) -> f32 {
        self.plane(set)[idx]
    }

    /// The plane of m(set) over all cells.
    ///
    /// # Panics
    /// If `set ≥ 32`.
    pub fn plane(&self, set: usize) -> &[f32] {
        let len = self.len();
        &self.masses[set * len..(set + 1) * len]
    }

    /// The plane of m(set), writable (to set up a scene or a test).
    ///
    /// # Panics
    /// If `set ≥ 32`.
    pub fn plane_mut(&mut self, set: usize) -> &mut [f32] {
        assert!(set < N_SETS, "no focal set {set} in a frame of 5 classes");
        self.may_leave_reachable = true;
        for bits in &mut self.nonzero {
            *bits |= 1 << set;
        }
        let len = self.len();
        &mut self.masses[set * len..(set + 1) * len]
    }

    /// The 32 masses of one cell, indexed by bitmask.
    ///
    /// # Panics
    /// If `idx ≥ len`.
    pub fn cell_masses(&self, idx: usize) -> [f32; N_SETS] {
        std::array::from_fn(|set| self.mass(set, idx))
    }

    /// Overwrites the 32 masses of one cell (to set up a scene or a test; not checked).
    ///
    /// # Panics
    /// If `idx ≥ len`.
    pub fn set_cell_masses(&mut self, idx: usize, masses: &[f32; N_SETS]) {
        let len = self.len();
        assert!(idx < len, "cell {idx} outside a grid of {len} cells");
        self.may_leave_reachable = true;
        for (set, &m) in masses.iter().enumerate() {
            self.masses[set * len + idx] = m;
            if m.to_bits() != 0 {
                self.nonzero[idx / CELLS_PER_BLOCK] |= 1 << set;
            }
        }
    }

    /// The non-zero plane bits of every block (see the field `nonzero`).
    #[cfg(test)]
    pub(crate) fn nonzero_bits(&self) -> &[PlaneBits] {
        &self.nonzero
    }

    /// Makes every plane of every block count as possibly non-zero: nothing is skipped.
    #[cfg(test)]
    pub(crate) fn mark_every_plane_nonzero(&mut self) {
        self.nonzero.fill(PlaneBits::MAX);
    }

    /// See the field `may_leave_reachable`.
    pub(crate) fn may_leave_reachable(&self) -> bool {
        self.may_leave_reachable
    }

    /// Notes that a step may have put mass outside the reachable sets.
    pub(crate) fn note_may_leave_reachable(&mut self) {
        self.may_leave_reachable = true;
    }

    /// Bytes of state the grid holds: 32 mass planes, ζ, ∅_FO, ∅_OF (4 bytes a cell each), the
    /// seen flags (1 byte a cell) and 8 bytes of non-zero plane bits per 64 cells.
    pub fn state_bytes(&self) -> usize {
        std::mem::size_of_val(self.masses.as_slice())
            + std::mem::size_of_val(self.zeta.as_slice())
            + std::mem::size_of_val(self.conflict_fo.as_slice())
            + std::mem::size_of_val(self.conflict_of.as_slice())
            + std::mem::size_of_val(self.seen.as_slice())
            + std::mem::size_of_val(self.nonzero.as_slice())
    }

    /// The seen flags, writable (to set up a scene or a test).
    pub fn seen_mut(&mut self) -> &mut [u8] {
        &mut self.seen
    }

    /// The accumulator ζ of every cell (eq 24-27), in `[0, 1]`.
    pub fn zeta(&self) -> &[f32] {
        &self.zeta
    }

    /// The accumulator ζ, writable.
    pub fn zeta_mut(&mut self) -> &mut [f32] {
        for bits in &mut self.nonzero {
            *bits |= ZETA_BIT;
        }
        &mut self.zeta
    }

    /// ∅_FO of the last step (eq 23): free before, occupied now: an object appeared.
    pub fn conflict_fo(&self) -> &[f32] {
        &self.conflict_fo
    }

    /// ∅_OF of the last step (eq 22): occupied before, free now: an object left.
    pub fn conflict_of(&self) -> &[f32] {
        &self.conflict_of
    }

    /// 1 where the sensor has ever said something about the cell (non-vacuous SensorGrid since
    /// the cell entered the window), else 0.
    pub fn seen(&self) -> &[u8] {
        &self.seen
    }

    /// Every plane as disjoint writable slices, for the step.
    pub(crate) fn planes_mut(&mut self) -> PerceptionPlanesMut<'_> {
        let len = self.len();
        let mut masses: [&mut [f32]; N_SETS] = Default::default();
        if len > 0 {
            for (slot, plane) in masses.iter_mut().zip(self.masses.chunks_exact_mut(len)) {
                *slot = plane;
            }
        }
        PerceptionPlanesMut {
            masses,
            zeta: &mut self.zeta,
            conflict_fo: &mut self.conflict_fo,
            conflict_of: &mut self.conflict_of,
            seen: &mut self.seen,
            nonzero: &mut self.nonzero,
        }
    }
}

/// Writable views of the planes of a run of consecutive storage cells of a PerceptionGrid.
pub(crate) struct PerceptionPlanesMut<'a> {
    pub(crate) masses: [&'a mut [f32]; N_SETS],
    pub(crate) zeta: &'a mut [f32],
    pub(crate) conflict_fo: &'a mut [f32],
    pub(crate) conflict_of: &'a mut [f32],
    pub(crate) seen: &'a mut [u8],
    /// The non-zero plane bits of the run's blocks (see [`PerceptionGrid`]).
    pub(crate) nonzero: &'a mut [PlaneBits],
}

impl<'a> PerceptionPlanesMut<'a> {
    /// Number of cells in the run.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.zeta.len()
    }

    /// Splits the run into cells `..mid` and `mid..`.
    ///
    /// # Panics
    /// If `mid` is not a multiple of [`CELLS_PER_BLOCK`]: a block's bits belong to one run.
    pub(crate) fn split_at(self, mid: usize) -> (Self, Self) {
        assert!(
            mid.is_multiple_of(CELLS_PER_BLOCK),
            "a run split inside a block"
        );
        let (nonzero_l, nonzero_r) = self.nonzero.split_at_mut(mid / CELLS_PER_BLOCK);
        let mut left: [&'a mut [f32]; N_SETS] = Default::default();
        let mut right: [&'a mut [f32]; N_SETS] = Default::default();
        for ((l, r), plane) in left.iter_mut().zip(right.iter_mut()).zip(self.masses) {
            (*l, *r) = plane.split_at_mut(mid);
        }
        let (zeta_l, zeta_r) = self.zeta.split_at_mut(mid);
        let (fo_l, fo_r) = self.conflict_fo.split_at_mut(mid);
        let (of_l, of_r) = self.conflict_of.split_at_mut(mid);
        let (seen_l, seen_r) = self.seen.split_at_mut(mid);
        (
            Self {
                masses: left,
                zeta: zeta_l,
                conflict_fo: fo_l,
                conflict_of: of_l,
                seen: seen_l,
                nonzero: nonzero_l,
            },
            Self {
                masses: right,
                zeta: zeta_r,
                conflict_fo: fo_r,
                conflict_of: of_r,
                seen: seen_r,
                nonzero: nonzero_r,
            },
        )
    }
}

/// The SensorGrid of one scan: a mass function on Ω_SG = {F, O} per cell (SPEC §3).
///
/// m(Ω) = 1 − m(F) − m(O) is not stored. The step reads masses outside `[0, 1]`, a sum above 1
/// or a NaN as the nearest valid mass function (NaN counts as 0).
#[derive(Clone, Debug)]
pub struct SensorGrid {
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// m({F}) per cell, `width · height` values.
    m_free: Vec<f32>,
    /// m({O}) per cell, `width · height` values.
    m_occupied: Vec<f32>,
    /// Per block of [`CELLS_PER_BLOCK`] cells, whether a cell may hold sensor mass: false only
    /// where the grid was cleared and nothing wrote since, so that the step need not read the
    /// block's planes (a scan reaches a few percent of a large window). Writes through
    /// [`SensorGrid::m_free_mut`] and [`SensorGrid::m_occupied_mut`] set every block.
    may_hold_mass: Vec<bool>,
    /// Cells the scan saw empty that SPEC §3 leaves vacuous: with a planar scanner, up to
    /// `max_range_m` along the sectors whose rays met nothing within it (a return beyond it,
    /// or none inside the field of view; `sensor.empty_without_return`). Written after the
    /// masses, so none of them holds mass; the motion stage's seen tests read them. May
    /// repeat a cell.
    clear_cells: Vec<u32>,
}

/// Equal grids hold equal masses; `may_hold_mass` is only a note on how they were written.
impl PartialEq for SensorGrid {
    fn eq(&self, other: &Self) -> bool {
        (self.width, self.height) == (other.width, other.height)
            && self.m_free == other.m_free
            && self.m_occupied == other.m_occupied
    }
}

impl SensorGrid {
    /// A vacuous `width × height` SensorGrid (the sensor says nothing).
    pub fn new(width: usize, height: usize) -> Self {
        let len = width * height;
        Self {
            width,
            height,
            m_free: vec![0.0; len],
            m_occupied: vec![0.0; len],
            may_hold_mass: vec![false; len.div_ceil(CELLS_PER_BLOCK)],
            clear_cells: Vec::new(),
        }
    }

    /// Number of cells, `width · height`.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Bytes of the grid's heap storage (what the memory budget counts).
    pub fn heap_bytes(&self) -> usize {
        4 * (self.m_free.capacity() + self.m_occupied.capacity() + self.clear_cells.capacity())
            + self.may_hold_mass.capacity()
    }

    /// True for a grid without cells.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// m({F}) of every cell.
    pub fn m_free(&self) -> &[f32] {
        &self.m_free
    }

    /// m({O}) of every cell.
    pub fn m_occupied(&self) -> &[f32] {
        &self.m_occupied
    }

    /// m({F}) of every cell, writable. The next step reads every cell's masses.
    pub fn m_free_mut(&mut self) -> &mut [f32] {
        self.may_hold_mass.fill(true);
        &mut self.m_free
    }

    /// m({O}) of every cell, writable. The next step reads every cell's masses.
    pub fn m_occupied_mut(&mut self) -> &mut [f32] {
        self.may_hold_mass.fill(true);
        &mut self.m_occupied
    }

    /// Sets m({F}) of one cell, noting its block (for the sensor model, which writes a few
    /// percent of a large window).
    #[inline]
    pub(crate) fn set_free(&mut self, idx: usize, mass: f32) {
        self.m_free[idx] = mass;
        self.may_hold_mass[idx / CELLS_PER_BLOCK] = true;
    }

    /// Sets m({O}) of one cell, noting its block.
    #[inline]
    pub(crate) fn set_occupied(&mut self, idx: usize, mass: f32) {
        self.m_occupied[idx] = mass;
        self.may_hold_mass[idx / CELLS_PER_BLOCK] = true;
    }

    /// Bytes of state the grid holds: two planes of 4 bytes a cell and one byte per 64 cells
    /// noting the blocks that may hold mass.
    pub fn state_bytes(&self) -> usize {
        std::mem::size_of_val(self.m_free.as_slice())
            + std::mem::size_of_val(self.m_occupied.as_slice())
            + std::mem::size_of_val(self.may_hold_mass.as_slice())
    }

    /// Storage indices of the cells the scan saw empty without a return within the sensor
    /// model's range (see the field); they hold no mass.
    pub fn clear_cells(&self) -> &[u32] {
        &self.clear_cells
    }

    /// Notes a cell seen empty that gets no mass.
    #[inline]
    pub(crate) fn push_clear(&mut self, idx: usize) {
        self.clear_cells.push(idx as u32);
    }

    /// Per block of 64 cells, whether a cell may hold sensor mass (false: all its masses are 0).
    pub(crate) fn may_hold_mass(&self) -> &[bool] {
        &self.may_hold_mass
    }

    /// The storage cells of the blocks that may hold sensor mass, a range per block (the
    /// other cells are vacuous).
    pub(crate) fn written_cells(&self) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        let len = self.m_occupied.len();
        self.may_hold_mass
            .iter()
            .enumerate()
            .filter(|(_, may)| **may)
            .map(move |(block, _)| {
                let first = block * CELLS_PER_BLOCK;
                first..(first + CELLS_PER_BLOCK).min(len)
            })
    }

    /// Makes every cell vacuous, ready for the next scan.
    pub fn clear(&mut self) {
        use rayon::prelude::*;
        // Megabytes per scan for a large window: in parallel, as the step's own passes are.
        for plane in [&mut self.m_free, &mut self.m_occupied] {
            plane
                .par_chunks_mut(1 << 16)
                .for_each(|chunk| chunk.fill(0.0));
        }
        self.may_hold_mass.fill(false);
        self.clear_cells.clear();
    }
}

/// The GISGrid: the map context of every cell (SPEC §4). Its mass function on Ω_PG is derived
/// from the context and the β parameters when the step runs, so a cell costs one byte.
#[derive(Clone, Debug, PartialEq)]
pub struct GisGrid {
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// Map context per cell, `width · height` values.
    pub context: Vec<MapContext>,
}

impl GisGrid {
    /// A `width × height` GISGrid without map information (every cell `Unknown`: vacuous).
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            context: vec![MapContext::Unknown; width * height],
        }
    }

    /// Number of cells, `width · height`.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Bytes of the grid's heap storage (what the memory budget counts).
    pub fn heap_bytes(&self) -> usize {
        std::mem::size_of::<MapContext>() * self.context.capacity()
    }

    /// True for a grid without cells.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_grid_is_vacuous_everywhere() {
        let pg = PerceptionGrid::new(3, 2);
        assert_eq!(pg.len(), 6);
        for idx in 0..6 {
            let m = pg.cell_masses(idx);
            assert_eq!(m[OMEGA], 1.0);
            assert_eq!(m.iter().sum::<f32>(), 1.0);
        }
        assert!(pg.zeta().iter().all(|&z| z == 0.0));
        assert!(pg.seen().iter().all(|&s| s == 0));
    }

    #[test]
    fn reset_range_touches_only_that_range() {
        let mut pg = PerceptionGrid::new(4, 1);
        let mut occupied = [0.0; N_SETS];
        occupied[class::S] = 1.0;
        for idx in 0..4 {
            pg.set_cell_masses(idx, &occupied);
            pg.zeta_mut()[idx] = 0.5;
        }
        pg.reset_range(1..3);
        assert_eq!(pg.cell_masses(0), occupied);
        assert_eq!(pg.mass(OMEGA, 1), 1.0);
        assert_eq!(pg.mass(class::S, 2), 0.0);
        assert_eq!(pg.zeta(), &[0.5, 0.0, 0.0, 0.5]);
        assert_eq!(pg.cell_masses(3), occupied);
        pg.reset_cell(3);
        assert_eq!(pg.mass(OMEGA, 3), 1.0);
    }

    #[test]
    fn planes_split_into_disjoint_runs() {
        let mut pg = PerceptionGrid::new(130, 1);
        let planes = pg.planes_mut();
        let (left, right) = planes.split_at(64);
        assert_eq!((left.len(), right.len()), (64, 66));
        assert!(left.masses.iter().all(|p| p.len() == 64));
        assert!(right.masses.iter().all(|p| p.len() == 66));
        assert_eq!((left.nonzero.len(), right.nonzero.len()), (1, 2));
        right.masses[OMEGA][0] = 0.25;
        assert_eq!(pg.mass(OMEGA, 64), 0.25);
    }

    #[test]
    fn nonzero_bits_cover_every_plane_that_holds_mass() {
        let mut pg = PerceptionGrid::new(100, 2);
        assert!(pg.nonzero.iter().all(|&bits| bits == OMEGA_BIT));
        let mut m = [0.0; N_SETS];
        m[class::S] = 0.5;
        m[OMEGA] = 0.5;
        pg.set_cell_masses(70, &m);
        assert_eq!(pg.nonzero[1], OMEGA_BIT | 1 << class::S);
        // Cells 64..128 are block 1: a reset of part of it keeps its bits, of all of it clears them.
        pg.reset_range(60..100);
        assert_eq!(pg.nonzero[1], OMEGA_BIT | 1 << class::S);
        pg.reset_range(64..128);
        assert_eq!(pg.nonzero[1], OMEGA_BIT);
        pg.zeta_mut()[0] = 0.25;
        assert!(pg.nonzero.iter().all(|&bits| bits & ZETA_BIT != 0));
        pg.plane_mut(class::F)[199] = 1.0;
        assert!(pg.nonzero.iter().all(|&bits| bits & (1 << class::F) != 0));
    }

    #[test]
    fn empty_grids_are_allowed() {
        let mut pg = PerceptionGrid::new(0, 7);
        assert!(pg.is_empty());
        pg.reset_all();
        assert_eq!(pg.planes_mut().len(), 0);
        assert!(SensorGrid::new(0, 0).is_empty());
        assert!(GisGrid::new(3, 0).is_empty());
    }

    #[test]
    fn sensor_grid_clear_makes_it_vacuous() {
        let mut sg = SensorGrid::new(2, 2);
        sg.m_free_mut()[1] = 0.7;
        sg.m_occupied_mut()[2] = 0.8;
        sg.clear();
        assert_eq!(sg, SensorGrid::new(2, 2));
    }
}
