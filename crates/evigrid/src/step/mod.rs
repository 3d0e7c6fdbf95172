//! One time step of the fusion (SPEC §5, eq 16-31), for every cell of the window.
//!
//! The PerceptionGrid is updated in place. Cells are processed in blocks of 64 loaded from
//! the mass planes into a small stack buffer; every stage is a pass over the block (module
//! `passes`, each derived there), so the work per cell is a fixed sequence of vectorisable
//! multiply-adds without per-cell branches or allocation. Per-block branches only skip work that
//! is exactly a no-op. Row ranges run in parallel with rayon; each cell is computed alone and
//! the statistics are integer counts, so the result is bit-identical whatever the number of
//! threads (ARCHITECTURE.md, "The fusion kernel").
//!
//! ```
//! use evigrid::{GisGrid, Params, PerceptionGrid, SensorGrid, step::step};
//! use evigrid::grids::class;
//! use geodata::MapContext;
//!
//! let mut pg = PerceptionGrid::new(2, 1);
//! let mut sg = SensorGrid::new(2, 1);
//! let mut gg = GisGrid::new(2, 1);
//! sg.m_free_mut()[0] = 0.7; // the sensor sees cell 0 free …
//! gg.context[0] = MapContext::Road; // … on a road
//! let mut params = Params::default();
//! params.map.beta_road = 0.8;
//! let stats = step(&mut pg, &sg, &gg, &params, 0.1);
//! assert_eq!(stats.observed_cells, 1);
//! // r(SG) ⊕ GG on a road: {F} 0.7, {F,S,M} 0.8·0.3 = 0.24, Ω 0.06; the vacuous past changes nothing.
//! assert!((pg.mass(class::F, 0) - 0.7).abs() < 1e-6);
//! assert!((pg.mass(class::F | class::S | class::M, 0) - 0.24).abs() < 1e-6);
//! assert_eq!(pg.mass(31, 1), 1.0); // cell 1 was not observed: still vacuous
//! ```

// Lane loops index several arrays by the same cell index `i`: that is the form the compiler
// vectorises, and zipped iterators over five arrays would only hide it.
#![allow(clippy::needless_range_loop)]

mod passes;

use crate::decision::{Decision, decide_lanes};
use crate::grids::{
    CONFLICT_FO_BIT, CONFLICT_OF_BIT, GisGrid, MASS_BITS, N_SETS, OMEGA, OMEGA_BIT, PerceptionGrid,
    PerceptionPlanesMut, PlaneBits, SensorGrid, ZETA_BIT, class,
};
use crate::params::{DiscountMode, Params, ResidualPolicy, SetRate, UnobservedCells};
use geodata::MapContext;
use passes::{
    ALL_SETS, BLOCK, BlockMasses, Lanes, Live, REACHABLE, Restriction, TOO_SMALL_TO_RESCALE,
    add_class, is_live, occupied_mass, sum_sets,
};
use rayon::iter::{IndexedParallelIterator, IntoParallelIterator, ParallelIterator};

/// A Dempster conflict K between the sensor and the map at or above `1 − this` counts as total
/// (K = 1, SPEC §5 step 2): dividing by a smaller 1 − K would only amplify f32 rounding.
const TOTAL_CONFLICT_MARGIN: f32 = 1e-6;

/// Cells whose planes are brought into cache together before their blocks are stepped
/// ([`CellRun::warm`]): 40 planes of 1024 cells are 160 KiB, within L2.
const TILE: usize = 1024;

/// Cells per parallel task (a multiple of [`BLOCK`]): enough tasks that a thread that finishes
/// early takes work from a busier one (observed cells and mixed map contexts are not spread
/// evenly over the window, and on a shared machine one core may run slower than the other), and
/// small enough that the last task, which no one else can take, is short. In a traced
/// one-thread step over 1000 × 1000 cells, the 123 tasks' own times summed to within about 1 %
/// of the step's.
const CELLS_PER_TASK: usize = 8 * 1024;

/// What happened during one step, counted over the window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct StepStats {
    /// Cells updated.
    pub cells: u64,
    /// Cells whose SensorGrid was not vacuous.
    pub observed_cells: u64,
    /// Cells where the sensor and the map were in total conflict (K = 1, SPEC §5 step 2): the
    /// refined sensor grid r(SG) was used there without the map.
    pub total_map_conflicts: u64,
    /// Times the `normalise` residual policy had nothing left to rescale and fell back to
    /// `to_omega` (fusion or specialisation; a cell may count twice).
    pub normalisation_fallbacks: u64,
    /// Bytes of grid state the step read and wrote: the planes of each block it could not skip
    /// (see [`PerceptionGrid`]), with the SensorGrid and GisGrid planes.
    pub state_bytes_moved: u64,
}

impl StepStats {
    fn merged(self, other: StepStats) -> StepStats {
        StepStats {
            cells: self.cells + other.cells,
            observed_cells: self.observed_cells + other.observed_cells,
            total_map_conflicts: self.total_map_conflicts + other.total_map_conflicts,
            normalisation_fallbacks: self.normalisation_fallbacks + other.normalisation_fallbacks,
            state_bytes_moved: self.state_bytes_moved + other.state_bytes_moved,
        }
    }
}

/// Runs one time step (SPEC §5) on every cell: fuses the SensorGrid `sg` of this scan and the
/// map prior `gg` into the PerceptionGrid `pg`, `dt_s` seconds after the previous step.
///
/// `params` should have passed [`Params::validate`]. A negative or NaN `dt_s` counts as 0 (no
/// discounting). Runs on the current rayon pool (use `ThreadPool::install` to choose one).
///
/// # Panics
/// If the three grids do not have the same width and height, or a SensorGrid or GisGrid plane
/// does not hold `width · height` values.
///
/// # References
/// SPEC §5; Kurdej et al. 2013, eq 16-31.
pub fn step(
    pg: &mut PerceptionGrid,
    sg: &SensorGrid,
    gg: &GisGrid,
    params: &Params,
    dt_s: f64,
) -> StepStats {
    step_cells(pg, sg, gg, params, dt_s, None, |run, k| run.step(k))
}

/// [`step`], then the decision of every cell (SPEC §6, as [`decide_grid`]) into `decisions`,
/// made while each block of cells is still in cache: one pass over the grid instead of two.
///
/// # Panics
/// As [`step`], and if `decisions.len()` is not the number of cells.
///
/// [`decide_grid`]: crate::decision::decide_grid
pub fn step_and_decide(
    pg: &mut PerceptionGrid,
    sg: &SensorGrid,
    gg: &GisGrid,
    params: &Params,
    dt_s: f64,
    decisions: &mut [Decision],
) -> StepStats {
    assert_eq!(decisions.len(), pg.len(), "decision buffer size");
    step_cells(pg, sg, gg, params, dt_s, Some(decisions), |run, k| {
        run.step(k)
    })
}

fn step_cells(
    pg: &mut PerceptionGrid,
    sg: &SensorGrid,
    gg: &GisGrid,
    params: &Params,
    dt_s: f64,
    decisions: Option<&mut [Decision]>,
    kernel: impl Fn(CellRun<'_>, &StepConstants) -> StepStats + Sync,
) -> StepStats {
    let (width, len) = (pg.width(), pg.len());
    assert!(
        (sg.width, sg.height, gg.width, gg.height) == (width, pg.height(), width, pg.height()),
        "grid sizes differ: PerceptionGrid {width}×{}, SensorGrid {}×{}, GisGrid {}×{}",
        pg.height(),
        sg.width,
        sg.height,
        gg.width,
        gg.height
    );
    assert!(
        sg.m_free().len() == len && sg.m_occupied().len() == len && gg.context.len() == len,
        "a SensorGrid or GisGrid plane does not hold {len} cells"
    );
    let constants = StepConstants::new(params, dt_s);
    // A grid that only ever held mass on the 16 reachable sets keeps it there under discounting
    // to Ω: its other 16 planes are +0 and need not even be read. Mercier's discounting moves
    // mass anywhere.
    let to_omega = matches!(constants.discount, Discount::ToOmega(_));
    let reachable_only = to_omega && !pg.may_leave_reachable();
    if !to_omega {
        pg.note_may_leave_reachable();
    }
    let cells = CellRun {
        reachable_only,
        pg: pg.planes_mut(),
        m_free: sg.m_free(),
        m_occupied: sg.m_occupied(),
        sensor_blocks: sg.may_hold_mass(),
        context: &gg.context,
        decisions,
    };
    cells
        .into_tasks()
        .into_par_iter()
        .with_max_len(1)
        .map(|run| kernel(run, &constants))
        .reduce(StepStats::default, StepStats::merged)
}

/// Everything the step derives from the parameters once, before touching a cell.
#[derive(Clone, Debug)]
struct StepConstants {
    discount: Discount,
    /// The GISGrid mass function of each map context, indexed by `MapContext as u8`.
    map_prior: [MapPrior; 4],
    residual: ResidualPolicy,
    delta_inc: f32,
    delta_dec: f32,
    gamma_occupied: f32,
    gamma_conflict: f32,
    /// SG' of a cell the scan did not reach, per map context.
    unobserved_evidence: [CellEvidence; 4],
    /// SPEC §6: above this m(Ω) a cell is decided unknown.
    unknown_threshold: f32,
    unobserved: UnobservedCells,
    /// The transfers of the specialisation (step 6): A ∋ M to A∖{M}.
    specialisation: Restrictions,
}

/// The discounting of step 3, as rates for this step's `dt`.
#[derive(Clone, Debug)]
enum Discount {
    /// Classical and class-rate discounting: the rate α_A(dt) of every focal set, to Ω.
    ToOmega([f32; N_SETS]),
    /// Mercier contextual discounting: the rate α_θ(dt) of each class context {θ}.
    Mercier([f32; 5]),
}

/// The GISGrid of one map context: β on the focal set G, 1 − β on Ω (eq 34-38), with the
/// indicators SG' needs, as 0/1 factors.
#[derive(Clone, Copy, Debug)]
struct MapPrior {
    /// The focal set G.
    g: usize,
    /// The transfers of m ∩ GG, for blocks on the reachable sets and for any block.
    restriction: Restrictions,
    beta: f32,
    /// [F ∈ G], [O ∩ G ≠ ∅], [G = {F}], [∅ ≠ G ⊆ O].
    free_in_g: f32,
    occupied_meets_g: f32,
    g_is_free: f32,
    g_within_occupied: f32,
}

impl MapPrior {
    fn new(g: usize, beta: f64) -> Self {
        let indicator = |condition: bool| if condition { 1.0 } else { 0.0 };
        MapPrior {
            g,
            restriction: Restrictions::new(g),
            beta: beta as f32,
            free_in_g: indicator(g & class::F != 0),
            occupied_meets_g: indicator(g & class::O != 0),
            g_is_free: indicator(g == class::F),
            g_within_occupied: indicator(g != 0 && g & class::F == 0),
        }
    }

    /// Whether combining with this prior can change a mass function.
    fn is_informative(&self) -> bool {
        self.g != OMEGA && self.beta > 0.0
    }
}

/// The [`Restriction`] to one focal set G, for the two families of live sets a block can have.
#[derive(Clone, Copy, Debug)]
struct Restrictions {
    reachable: Restriction,
    all: Restriction,
}

impl Restrictions {
    fn new(g: usize) -> Self {
        Restrictions {
            reachable: Restriction::new(g, REACHABLE),
            all: Restriction::new(g, ALL_SETS),
        }
    }

    /// The transfers for a block whose live sets are `live`: those among the [`REACHABLE`] sets
    /// if `live` lies within them, else all.
    #[inline(always)]
    fn for_live(&self, live: Live) -> &Restriction {
        if live & !REACHABLE == 0 {
            &self.reachable
        } else {
            &self.all
        }
    }
}

/// α(dt) = 1 − (1 − α_1s)^dt: a rate per second applied over `dt_s` seconds (SPEC §5 step 3).
pub fn rate_for_step(rate_per_second: f64, dt_s: f64) -> f64 {
    1.0 - (1.0 - rate_per_second).powf(dt_s)
}

/// α_A per second from the rates of the classes in A (`class_rates` and `classical` modes).
///
/// For A = ∅ (mass kept on ∅ by the `keep` policy) the classes of Ω are used, so that equal rates
/// give classical discounting on every set, ∅ included (eq 13).
pub fn set_rate_per_second(set: usize, class_rates: &[f64; 5], set_rate: SetRate) -> f64 {
    let members = if set == 0 { OMEGA } else { set };
    let rates = (0..5)
        .filter(|k| members & (1 << k) != 0)
        .map(|k| class_rates[k]);
    match set_rate {
        SetRate::Min => rates.fold(f64::INFINITY, f64::min),
        SetRate::Max => rates.fold(f64::NEG_INFINITY, f64::max),
        SetRate::Mean => {
            let count = members.count_ones() as f64;
            rates.sum::<f64>() / count
        }
    }
}

impl StepConstants {
    fn new(params: &Params, dt_s: f64) -> Self {
        let dt_s = if dt_s > 0.0 { dt_s } else { 0.0 };
        let fusion = &params.fusion;
        let class_rates = fusion.discount_per_second.as_array();
        let discount = match fusion.discount_mode {
            DiscountMode::Classical => {
                let rate = set_rate_per_second(OMEGA, &class_rates, fusion.set_rate);
                Discount::ToOmega([rate_for_step(rate, dt_s) as f32; N_SETS])
            }
            DiscountMode::ClassRates => Discount::ToOmega(std::array::from_fn(|set| {
                let rate = set_rate_per_second(set, &class_rates, fusion.set_rate);
                rate_for_step(rate, dt_s) as f32
            })),
            DiscountMode::Mercier => {
                Discount::Mercier(class_rates.map(|rate| rate_for_step(rate, dt_s) as f32))
            }
        };
        let map = &params.map;
        let mut map_prior = [MapPrior::new(OMEGA, 0.0); 4];
        map_prior[MapContext::Other as usize] =
            MapPrior::new(class::F | class::U | class::S | class::M, map.beta_other);
        map_prior[MapContext::Road as usize] =
            MapPrior::new(class::F | class::S | class::M, map.beta_road);
        map_prior[MapContext::Building as usize] = MapPrior::new(class::I, map.beta_building);
        let acc = &params.accumulator;
        StepConstants {
            discount,
            map_prior,
            residual: fusion.residual,
            delta_inc: acc.delta_inc as f32,
            delta_dec: acc.delta_dec as f32,
            gamma_occupied: acc.gamma_occupied as f32,
            gamma_conflict: acc.gamma_conflict as f32,
            unobserved_evidence: map_prior.map(|prior| CellEvidence::unobserved(&prior)),
            unknown_threshold: params.decision.unknown_threshold as f32,
            unobserved: fusion.unobserved,
            specialisation: Restrictions::new(OMEGA ^ class::M),
        }
    }
}

/// A run of consecutive storage cells: the unit of parallel work.
struct CellRun<'a> {
    pg: PerceptionPlanesMut<'a>,
    m_free: &'a [f32],
    m_occupied: &'a [f32],
    /// Per block, whether the SensorGrid may hold mass there (false: its planes are 0 and are
    /// not read).
    sensor_blocks: &'a [bool],
    context: &'a [MapContext],
    /// Where to write the decision of each cell, if wanted.
    decisions: Option<&'a mut [Decision]>,
    /// Every mass outside the [`REACHABLE`] sets is +0 (see `step_cells`).
    reachable_only: bool,
}

impl<'a> CellRun<'a> {
    /// Cuts the run into tasks of [`CELLS_PER_TASK`] cells (whole blocks; the last task takes
    /// the rest). The tasks do not depend on the number of threads, nor does any result.
    fn into_tasks(self) -> Vec<Self> {
        let mut tasks = Vec::with_capacity(self.m_free.len().div_ceil(CELLS_PER_TASK));
        let mut rest = self;
        while rest.m_free.len() > CELLS_PER_TASK {
            let (task, after) = rest.split_at(CELLS_PER_TASK);
            tasks.push(task);
            rest = after;
        }
        tasks.push(rest);
        tasks
    }

    /// The first `mid` cells and the rest.
    fn split_at(self, mid: usize) -> (Self, Self) {
        let (pg_left, pg_right) = self.pg.split_at(mid);
        let (free_left, free_right) = self.m_free.split_at(mid);
        let (occ_left, occ_right) = self.m_occupied.split_at(mid);
        let (ctx_left, ctx_right) = self.context.split_at(mid);
        let (blocks_left, blocks_right) = self.sensor_blocks.split_at(mid / BLOCK);
        let (decisions_left, decisions_right) = match self.decisions {
            Some(decisions) => {
                let (left, right) = decisions.split_at_mut(mid);
                (Some(left), Some(right))
            }
            None => (None, None),
        };
        let left = CellRun {
            pg: pg_left,
            m_free: free_left,
            m_occupied: occ_left,
            sensor_blocks: blocks_left,
            context: ctx_left,
            decisions: decisions_left,
            reachable_only: self.reachable_only,
        };
        let right = CellRun {
            pg: pg_right,
            m_free: free_right,
            m_occupied: occ_right,
            sensor_blocks: blocks_right,
            context: ctx_right,
            decisions: decisions_right,
            reachable_only: self.reachable_only,
        };
        (left, right)
    }

    /// Steps every cell of the run, with the widest vector instructions this CPU has.
    fn step(self, k: &StepConstants) -> StepStats {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            return self.step_avx2(k);
        }
        self.step_blocks(k, None::<fn(*const i8)>)
    }

    /// [`CellRun::step_blocks`] compiled for AVX2: the same operations in the same order on
    /// 8 lanes instead of 4, so the result is bit-identical to the portable code (no fused
    /// multiply-add is ever used: Rust does not contract `a * b + c`).
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code, reason = "calling a target_feature function; see SAFETY")]
    fn step_avx2(self, k: &StepConstants) -> StepStats {
        #[target_feature(enable = "avx2")]
        fn step_blocks_avx2(run: CellRun<'_>, k: &StepConstants) -> StepStats {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            // A prefetch is a hint: it reads nothing the program sees and never faults. Safe
            // here, inside a function compiled for AVX2 (which includes SSE).
            run.step_blocks(k, Some(|line| _mm_prefetch::<_MM_HINT_T0>(line)))
        }
        // SAFETY: the caller checked with `is_x86_feature_detected!("avx2")` that this CPU
        // runs AVX2 instructions, the only requirement of a `target_feature` function.
        unsafe { step_blocks_avx2(self, k) }
    }

    /// Steps every cell of the run, block by block, through one reused block buffer.
    ///
    /// Only the planes a block's non-zero bits name are read, and only those that were or became
    /// non-zero are written back: the other planes hold +0 before and after, in memory and in the
    /// buffer.
    ///
    /// Memory is brought in ahead of the blocks, two ways. With `prefetch` (a CPU prefetch
    /// instruction), each block asks for the lines of the block one tile ahead, so the memory
    /// latency overlaps the computation. Without, each tile is read plane by plane before its
    /// blocks are stepped ([`CellRun::warm`]). The results are the same bits.
    #[inline(always)]
    fn step_blocks(mut self, k: &StepConstants, prefetch: Option<impl Fn(*const i8)>) -> StepStats {
        let mut stats = StepStats::default();
        let mut block = Block::vacuous();
        let known_live = self.reachable_only.then_some(REACHABLE);
        let planes = PlaneBits::from(known_live.unwrap_or(ALL_SETS))
            | ZETA_BIT
            | CONFLICT_FO_BIT
            | CONFLICT_OF_BIT;
        let len = self.m_free.len();
        let mut tile_start = 0;
        while tile_start < len {
            let tile_end = (tile_start + TILE).min(len);
            if prefetch.is_none() || tile_start == 0 {
                let tile_blocks = tile_start / BLOCK..tile_end.div_ceil(BLOCK);
                let in_tile = self.pg.nonzero[tile_blocks]
                    .iter()
                    .fold(0, |all, &bits| all | bits);
                self.warm(tile_start..tile_end, in_tile & planes);
            }
            let mut start = tile_start;
            while start < tile_end {
                let end = (start + BLOCK).min(tile_end);
                if let Some(prefetch) = &prefetch {
                    self.prefetch_block(start + TILE, planes, prefetch);
                }
                let stored = self.pg.nonzero[start / BLOCK];
                let read = block.load(&self, start..end, stored & planes);
                let mut events = step_block(&mut block, k, known_live);
                let now = block.nonzero(stored);
                let written = block.store(&mut self, start..end, stored | now);
                events.state_bytes_moved = read + written;
                self.pg.nonzero[start / BLOCK] = now;
                if let Some(decisions) = self.decisions.as_deref_mut() {
                    let m = &block.m;
                    decide_lanes(
                        m,
                        block.live,
                        &block.seen,
                        k.unknown_threshold,
                        &mut decisions[start..end],
                    );
                }
                stats = stats.merged(events);
                start = end;
            }
            tile_start = tile_end;
        }
        stats
    }

    /// Asks `prefetch` for every cache line the block at `start` will read, if the run has one
    /// there.
    #[inline(always)]
    fn prefetch_block(&self, start: usize, planes: PlaneBits, prefetch: &impl Fn(*const i8)) {
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
    fn warm(&self, cells: std::ops::Range<usize>, planes: PlaneBits) {
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
struct Block {
    m: BlockMasses,
    zeta: Lanes,
    conflict_fo: Lanes,
    conflict_of: Lanes,
    seen: [u8; BLOCK],
    sensor_free: Lanes,
    sensor_occupied: Lanes,
    context: [MapContext; BLOCK],
    /// Scratch for stages 1-2, kept here so that it is not rebuilt (and moved) for every block.
    sensor: SensorEvidence,
    /// Lanes holding real cells.
    len: usize,
    /// The focal sets that may hold mass in this block ([`live_sets`]).
    live: Live,
    /// The planes of `m` and `zeta` that may not be +0 in the buffer (from the last block).
    buffered: PlaneBits,
    /// The block's non-zero plane bits before the step.
    stored_masses: PlaneBits,
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
    fn vacuous() -> Block {
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
    fn load(
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
    fn nonzero(&mut self, before: PlaneBits) -> PlaneBits {
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
    fn store(
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

/// SPEC §5 on one block: PG_{t−1}, ζ_{t−1} in the block become PG_t, ζ_t.
#[inline(always)]
fn step_block(block: &mut Block, k: &StepConstants, known_live: Option<Live>) -> StepStats {
    // 1-2. The sensor's evidence, refined to Ω_PG and combined with the map prior by Dempster's
    //      rule: SG'_t = r(SG_t) ⊕ GG (eq 16-21), per cell in compact form.
    block.sensor.fill(
        &block.sensor_free,
        &block.sensor_occupied,
        &block.context,
        k,
    );
    block.live = known_live.unwrap_or_else(|| live_sets(&block.m, &k.discount));
    if !block.sensor.any_observed && matches!(k.discount, Discount::ToOmega(_)) {
        // Far from the sensor a block holds mass on a few sets, and the step can only reach a
        // few more: passes visit those alone.
        block.live &= reachable_this_step(block.stored_masses, &block.sensor, k);
    }
    if k.unobserved == UnobservedCells::Fuse || block.sensor.all_observed {
        return fuse_block(block, k);
    }
    // `discount_only`: cells the scan did not reach are only discounted (step 3).
    if !block.sensor.any_observed {
        discount_only(&mut block.m, &k.discount, block.live);
        block.conflict_fo = [0.0; BLOCK];
        block.conflict_of = [0.0; BLOCK];
        return StepStats {
            cells: block.len as u64,
            ..StepStats::default()
        };
    }
    // Some of each: every cell fused, then the unobserved ones given their discounted past.
    let (mut discounted, zeta) = (block.m, block.zeta);
    discount_only(&mut discounted, &k.discount, block.live);
    let stats = fuse_block(block, k);
    let observed = &block.sensor.observed;
    for (plane, past) in block.m.iter_mut().zip(&discounted) {
        for i in 0..BLOCK {
            plane[i] = if observed[i] != 0 { plane[i] } else { past[i] };
        }
    }
    for i in 0..BLOCK {
        let keep = observed[i] != 0;
        block.zeta[i] = if keep { block.zeta[i] } else { zeta[i] };
        block.conflict_fo[i] = if keep { block.conflict_fo[i] } else { 0.0 };
        block.conflict_of[i] = if keep { block.conflict_of[i] } else { 0.0 };
    }
    stats
}

/// The focal sets that can hold mass after a step of a block the scan did not reach, whose
/// masses before lie on `before` (its non-zero plane bits), with discounting to Ω.
///
/// Those sets, Ω (discounting, ∅_OF), A ∩ G for the map context's G (the map prior), ∅ and {M}
/// (the conflicts), then A∖{M} of all of these (the specialisation). A pass may skip every
/// other set: its mass is +0 before and after.
#[inline(always)]
fn reachable_this_step(before: PlaneBits, sensor: &SensorEvidence, k: &StepConstants) -> Live {
    let mut live = (before & MASS_BITS) as Live | 1 << OMEGA;
    let mut restricted = live;
    for (c, prior) in k.map_prior.iter().enumerate() {
        if sensor.contexts_present & (1 << c) != 0 && prior.is_informative() {
            for_each_bit(PlaneBits::from(live), |set| {
                restricted |= 1 << (set & prior.g)
            });
        }
    }
    live = restricted | 1 << class::M | 1;
    let mut specialised = live;
    for_each_bit(PlaneBits::from(live), |set| {
        specialised |= 1 << (set & !class::M)
    });
    specialised
}

/// The focal sets a step of this block must visit: the 16 [`REACHABLE`] ones when every mass
/// outside them is +0 and the discounting moves mass to Ω only (Mercier's moves it to any
/// superset), else all 32. The usual grid, started vacuous, never leaves them.
#[inline(always)]
fn live_sets(m: &BlockMasses, discount: &Discount) -> Live {
    if matches!(discount, Discount::Mercier(_)) {
        return ALL_SETS;
    }
    // The bits of every mass outside, OR-ed: 0 only if all are +0.0 (not -0.0, whose sign bit a
    // skipped pass could have changed).
    let mut bits = [0u32; BLOCK];
    for (set, plane) in m.iter().enumerate() {
        if !is_live(REACHABLE, set) {
            for i in 0..BLOCK {
                bits[i] |= plane[i].to_bits();
            }
        }
    }
    if any_lane(&bits, |b| b != 0) {
        ALL_SETS
    } else {
        REACHABLE
    }
}

/// Step 3 alone: the discounting of every cell of the block.
#[inline(always)]
fn discount_only(m: &mut BlockMasses, discount: &Discount, live: Live) {
    match discount {
        Discount::ToOmega(rate_per_set) => discount_to_omega(m, rate_per_set, live),
        Discount::Mercier(rate_per_class) => {
            for (bit, &alpha) in rate_per_class.iter().enumerate() {
                add_class(m, 1 << bit, alpha);
            }
        }
    }
}

/// Every A ≠ Ω gives `rate[A]`·m(A) to Ω: the discounting of
/// [`discount_and_combine_with_refined_sensor`] alone, with the same operations in the same
/// order (so a cell's result does not depend on its block's other cells).
#[inline(always)]
fn discount_to_omega(m: &mut BlockMasses, rate_per_set: &[f32; N_SETS], live: Live) {
    let mut to_omega = [0.0; BLOCK];
    for_each_bit(PlaneBits::from(live & !(1 << OMEGA)), |set| {
        discount_in_place(&mut m[set], rate_per_set[set], &mut to_omega);
    });
    for i in 0..BLOCK {
        m[OMEGA][i] += to_omega[i];
    }
}

/// Steps 3-7 of SPEC §5 on every cell of the block, with SG' already in `block.sensor`.
#[inline(always)]
fn fuse_block(block: &mut Block, k: &StepConstants) -> StepStats {
    let sensor = &block.sensor;
    let m = &mut block.m;
    // 3. Discount the previous grid, so that old information fades; 4. the modified conjunctive
    //    rule (eq 22-23, 30-31). c = PG^α ∩ SG' = (PG^α ∩ r(SG) ∩ GG − K·Σm·δ_∅) / (1 − K): the
    //    discounting and the sensor's three focal sets in one pass, then the map's restriction,
    //    then Dempster's normalisation of SG' (see `discount_and_combine_with_refined_sensor`
    //    for why this order is exact). ∅_FO = m^α({F})·m'(O) and ∅_OF = m^α(O)·m'({F}) are read
    //    on the way.
    let rate_per_set = match &k.discount {
        Discount::ToOmega(rate_per_set) => rate_per_set,
        Discount::Mercier(rate_per_class) => {
            for (bit, &alpha) in rate_per_class.iter().enumerate() {
                add_class(m, 1 << bit, alpha);
            }
            &[0.0; N_SETS]
        }
    };
    let before = if sensor.any_observed || sensor.any_sensor_free {
        discount_and_combine_with_refined_sensor(m, rate_per_set, sensor, block.live)
    } else {
        // r(SG) is vacuous in every cell, so its combination changes nothing; m_SG'({F}) = 0
        // makes ∅_OF = 0 and K = 0 needs no Σm.
        discount_to_omega(m, rate_per_set, block.live);
        BeforeSensor {
            free: m[class::F],
            occupied: [0.0; BLOCK],
            total: [0.0; BLOCK],
        }
    };
    let mut conflict_fo = [0.0; BLOCK];
    let mut conflict_of = [0.0; BLOCK];
    for i in 0..BLOCK {
        conflict_fo[i] = before.free[i] * sensor.sg_occupied[i];
        conflict_of[i] = before.occupied[i] * sensor.sg_free[i];
    }
    combine_with_map_prior(m, &block.context, sensor, k, block.live);
    if sensor.any_sensor_map_conflict {
        remove_sensor_map_conflict(m, sensor, &before.total, block.live);
    }
    //    ∅_FO goes to {M} (an object appeared), ∅_OF to Ω (an object left), the residual conflict
    //    to the policy.
    for i in 0..BLOCK {
        m[class::M][i] += conflict_fo[i];
        m[OMEGA][i] += conflict_of[i];
        m[0][i] = (m[0][i] - conflict_fo[i] - conflict_of[i]).max(0.0);
    }
    let fallbacks_fusion = settle_empty_set(m, k.residual, block.live);
    // 5. Update the accumulator ζ with m(O) and ∅_FO + ∅_OF of this step (eq 24-27).
    update_accumulator(
        &mut block.zeta,
        &occupied_mass(m, block.live),
        &conflict_fo,
        &conflict_of,
        k,
    );
    // 6. Specialise (eq 28-29): every A ∋ M gives ζ·m(A) to A∖{M}; what {M} gives to ∅ follows
    //    the residual policy.
    //    With ζ = 0 in every cell (no cell of the block has been steadily occupied) this moves
    //    nothing, exactly, and is skipped. The residual policy still runs: under `normalise` it
    //    rescales again, and a cell must get the same bits whatever its neighbours' ζ.
    if any_lane(&block.zeta, |zeta| zeta > 0.0) {
        // The restriction to Ω∖{M}: the specialisation is that combination (passes.rs).
        k.specialisation
            .for_live(block.live)
            .apply(m, &block.zeta, block.live);
    }
    let fallbacks_specialisation = settle_empty_set(m, k.residual, block.live);
    // 7. Keep the conflict masses for display, and whether the sensor ever saw the cell.
    block.conflict_fo = conflict_fo;
    block.conflict_of = conflict_of;
    for i in 0..BLOCK {
        block.seen[i] |= sensor.observed[i];
    }
    let real = block.len;
    let counted = match k.unobserved {
        UnobservedCells::Fuse => [1; BLOCK],
        UnobservedCells::DiscountOnly => sensor.observed,
    };
    // Only observed cells are counted or in total conflict (K needs sensor mass), and only
    // `normalise` falls back.
    let (observed, total_conflicts) = if sensor.any_observed {
        (
            count(&sensor.observed[..real]),
            count(&sensor.total_conflict[..real]),
        )
    } else {
        (0, 0)
    };
    let fallbacks = if k.residual == ResidualPolicy::Normalise {
        // Under `discount_only` the unobserved cells' fusion is discarded, and so are its events.
        count_where(&fallbacks_fusion[..real], &counted[..real])
            + count_where(&fallbacks_specialisation[..real], &counted[..real])
    } else {
        0
    };
    StepStats {
        cells: real as u64,
        observed_cells: observed,
        total_map_conflicts: total_conflicts,
        normalisation_fallbacks: fallbacks,
        state_bytes_moved: 0,
    }
}

/// Whether `test` holds for any lane. A fold with `|`, not `Iterator::any`: no early exit, so
/// the compiler vectorises it.
#[inline(always)]
pub(crate) fn any_lane<T: Copy, const N: usize>(lanes: &[T; N], test: impl Fn(T) -> bool) -> bool {
    lanes.iter().fold(false, |any, &x| any | test(x))
}

/// Calls `f` with the index of every set bit of `bits`, lowest first.
#[inline(always)]
fn for_each_bit(mut bits: PlaneBits, mut f: impl FnMut(usize)) {
    while bits != 0 {
        f(bits.trailing_zeros() as usize);
        bits &= bits - 1;
    }
}

/// Whether any lane is not +0 (a -0 counts): the bits OR-ed eight lanes at a time, which the
/// compiler keeps in one vector register (a plain fold became 64 scalar ORs).
#[inline(always)]
fn any_bits(lanes: &Lanes) -> bool {
    let mut bits = [0u32; 8];
    for chunk in lanes.chunks_exact(8) {
        for (acc, x) in bits.iter_mut().zip(chunk) {
            *acc |= x.to_bits();
        }
    }
    bits.iter().fold(0, |all, &b| all | b) != 0
}

#[inline(always)]
fn count(flags: &[u8]) -> u64 {
    flags.iter().map(|&f| u64::from(f)).sum()
}

/// Flags set in both `flags` and `mask`.
#[inline(always)]
fn count_where(flags: &[u8], mask: &[u8]) -> u64 {
    flags
        .iter()
        .zip(mask)
        .map(|(&f, &m)| u64::from(f & m))
        .sum()
}

/// SG'_t = r(SG_t) ⊕ GG of one cell: see [`SensorEvidence`].
#[derive(Clone, Copy, Debug)]
struct CellEvidence {
    free: f32,
    occupied: f32,
    omega: f32,
    beta: f32,
    conflict: f32,
    inv_normaliser: f32,
    sg_free: f32,
    sg_occupied: f32,
    observed: bool,
    total_conflict: bool,
}

impl CellEvidence {
    /// From the SensorGrid masses and the map prior's
    /// `[β, [F ∈ G], [O ∩ G ≠ ∅], [G = {F}], [∅ ≠ G ⊆ O]]`.
    #[inline(always)]
    fn new(m_free: f32, m_occupied: f32, prior: [f32; 5]) -> Self {
        let [beta, in_f, meets_o, is_f, within_o] = prior;
        // A valid mass function whatever the input: NaN → 0 (`max` ignores NaN), sum ≤ 1.
        #[allow(clippy::manual_clamp, reason = "clamp keeps NaN; this turns it into 0")]
        let free = m_free.max(0.0).min(1.0);
        let occupied = m_occupied.max(0.0).min(1.0 - free);
        let omega = 1.0 - free - occupied;
        let conflict = beta * (free * (1.0 - in_f) + occupied * (1.0 - meets_o));
        let total = conflict >= 1.0 - TOTAL_CONFLICT_MARGIN;
        let (beta, conflict) = if total { (0.0, 0.0) } else { (beta, conflict) };
        let inv = 1.0 / (1.0 - conflict);
        CellEvidence {
            free,
            occupied,
            omega,
            beta,
            conflict,
            inv_normaliser: inv,
            sg_free: (free * (1.0 - beta) + free * beta * in_f + omega * beta * is_f) * inv,
            sg_occupied: (occupied * (1.0 - beta)
                + occupied * beta * meets_o
                + omega * beta * within_o)
                * inv,
            observed: free + occupied > 0.0,
            total_conflict: total,
        }
    }

    /// A cell the scan did not reach, in map context `prior`.
    fn unobserved(prior: &MapPrior) -> Self {
        let MapPrior {
            beta,
            free_in_g,
            occupied_meets_g,
            g_is_free,
            g_within_occupied,
            ..
        } = *prior;
        let prior = [
            beta,
            free_in_g,
            occupied_meets_g,
            g_is_free,
            g_within_occupied,
        ];
        CellEvidence::new(0.0, 0.0, prior)
    }
}

/// SG'_t = r(SG_t) ⊕ GG per cell, in the compact form the fusion needs.
///
/// r(SG) has mass m_F on {F}, m_O on O = {I,U,S,M}, m_Ω on Ω (eq 16-20). GG has β on G, 1 − β on
/// Ω. Their conjunctive combination has m_F·β on {F}∩G, m_F(1 − β) on {F}, m_O·β on O∩G,
/// m_O(1 − β) on O, m_Ω·β on G, m_Ω(1 − β) on Ω; the conflict K is the part of m_F·β and m_O·β
/// whose intersection is empty, and Dempster's rule divides the rest by 1 − K (eq 9-11, 21).
struct SensorEvidence {
    /// r(SG): m_F, m_O, m_Ω, after clamping to a valid mass function.
    free: Lanes,
    occupied: Lanes,
    omega: Lanes,
    /// β of the cell's context; 0 where the conflict is total (then SG' = r(SG)).
    beta: Lanes,
    /// K and 1 / (1 − K).
    conflict: Lanes,
    inv_normaliser: Lanes,
    /// m_SG'({F}) and m_SG'(O), the masses eq 22-23 multiply.
    sg_free: Lanes,
    sg_occupied: Lanes,
    /// Non-vacuous sensor grid (1) or not (0); total conflict (1) or not (0).
    observed: [u8; BLOCK],
    total_conflict: [u8; BLOCK],
    /// Bit c set when a cell of the block has map context c.
    contexts_present: u8,
    /// Whether K > 0 in any cell of the block (outside building cells it is 0).
    any_sensor_map_conflict: bool,
    /// Whether m_SG'({F}) ≠ 0 in any cell of the block (never where the scan saw nothing, with
    /// the map contexts there are).
    any_sensor_free: bool,
    /// Whether any cell, or every cell, of the block has a non-vacuous SensorGrid.
    any_observed: bool,
    all_observed: bool,
}

impl SensorEvidence {
    fn zeroed() -> Self {
        SensorEvidence {
            free: [0.0; BLOCK],
            occupied: [0.0; BLOCK],
            omega: [0.0; BLOCK],
            beta: [0.0; BLOCK],
            conflict: [0.0; BLOCK],
            inv_normaliser: [0.0; BLOCK],
            sg_free: [0.0; BLOCK],
            sg_occupied: [0.0; BLOCK],
            observed: [0; BLOCK],
            total_conflict: [0; BLOCK],
            contexts_present: 0,
            any_sensor_map_conflict: false,
            any_sensor_free: false,
            any_observed: false,
            all_observed: false,
        }
    }

    #[inline(always)]
    fn fill(
        &mut self,
        m_free: &Lanes,
        m_occupied: &Lanes,
        context: &[MapContext; BLOCK],
        k: &StepConstants,
    ) {
        let e = self;
        let mut present = 0u8;
        for &c in context {
            present |= 1 << (c as u8);
        }
        e.contexts_present = present;
        let one_context = present
            .is_power_of_two()
            .then(|| present.trailing_zeros() as usize);
        // (NaN and negative masses count as 0, as in `CellEvidence::new`.)
        let unobserved = !any_lane(m_free, |free| free > 0.0) && !any_lane(m_occupied, |o| o > 0.0);
        if unobserved {
            // A block the scan did not reach (most blocks of a large window): every cell has
            // SG' = GG of its context, computed once per step. A block inside one context takes
            // it as a broadcast; one across contexts (half the blocks in a city centre) takes each
            // context's in its cells, a vectorised select.
            match one_context {
                Some(c) => e.broadcast(&k.unobserved_evidence[c]),
                None => e.select_unobserved(context, present, &k.unobserved_evidence),
            }
        } else {
            // The map prior of each cell, selected the same way.
            // The map prior of each cell: a broadcast inside one context, else a lookup in the
            // four contexts' values by the two bits of the context (three selects a value).
            let table = |field: fn(&MapPrior) -> f32| k.map_prior.map(|prior| field(&prior));
            let bits = match one_context {
                Some(_) => [[0; BLOCK]; 2],
                None => context_bits(context),
            };
            let lanes = |values: [f32; 4]| match one_context {
                Some(c) => [values[c]; BLOCK],
                None => lookup_by_context(&bits, values),
            };
            let beta = lanes(table(|p| p.beta));
            let in_f = lanes(table(|p| p.free_in_g));
            let meets_o = lanes(table(|p| p.occupied_meets_g));
            let is_f = lanes(table(|p| p.g_is_free));
            let within_o = lanes(table(|p| p.g_within_occupied));
            for i in 0..BLOCK {
                let v = CellEvidence::new(
                    m_free[i],
                    m_occupied[i],
                    [beta[i], in_f[i], meets_o[i], is_f[i], within_o[i]],
                );
                e.free[i] = v.free;
                e.occupied[i] = v.occupied;
                e.omega[i] = v.omega;
                e.beta[i] = v.beta;
                e.conflict[i] = v.conflict;
                e.inv_normaliser[i] = v.inv_normaliser;
                e.sg_free[i] = v.sg_free;
                e.sg_occupied[i] = v.sg_occupied;
                e.observed[i] = u8::from(v.observed);
                e.total_conflict[i] = u8::from(v.total_conflict);
            }
        }
        // Boolean reductions, kept out of the loop above: an in-order float sum there would
        // stop the compiler from vectorising it.
        e.any_sensor_map_conflict = any_lane(&e.conflict, |conflict| conflict > 0.0);
        e.any_sensor_free = any_lane(&e.sg_free, |free| free != 0.0);
        e.any_observed = any_lane(&e.observed, |observed| observed != 0);
        e.all_observed = !any_lane(&e.observed, |observed| observed == 0);
    }
}

impl SensorEvidence {
    /// Every lane set to the evidence `v`.
    #[inline(always)]
    fn broadcast(&mut self, v: &CellEvidence) {
        let e = self;
        e.free = [v.free; BLOCK];
        e.occupied = [v.occupied; BLOCK];
        e.omega = [v.omega; BLOCK];
        e.beta = [v.beta; BLOCK];
        e.conflict = [v.conflict; BLOCK];
        e.inv_normaliser = [v.inv_normaliser; BLOCK];
        e.sg_free = [v.sg_free; BLOCK];
        e.sg_occupied = [v.sg_occupied; BLOCK];
        e.observed = [u8::from(v.observed); BLOCK];
        e.total_conflict = [u8::from(v.total_conflict); BLOCK];
    }

    /// Each lane set to the evidence of a cell the scan did not reach in its map context, for
    /// a block whose cells are in the contexts of `present`.
    ///
    /// Without sensor mass, SG' = GG: m_F = m_O = K = 0, m_Ω = 1 and 1/(1 − K) = 1 in every
    /// context ([`CellEvidence::unobserved`] computes exactly these), so only β, m_SG'({F}) and
    /// m_SG'(O) can differ from cell to cell, and each is selected per context only where the
    /// contexts present disagree on it.
    #[inline(always)]
    fn select_unobserved(
        &mut self,
        context: &[MapContext; BLOCK],
        present: u8,
        evidence: &[CellEvidence; 4],
    ) {
        let e = self;
        let any = &evidence[present.trailing_zeros() as usize];
        e.broadcast(any);
        let contexts = || (0..4).filter(move |&c| present & (1 << c) != 0);
        let bits = context_bits(context);
        // Each value that can vary, looked up by context where the contexts present disagree.
        let values = |v: &CellEvidence| [v.beta, v.sg_free, v.sg_occupied];
        for field in 0..3 {
            let differs = contexts()
                .any(|c| values(&evidence[c])[field].to_bits() != values(any)[field].to_bits());
            if differs {
                let lanes = lookup_by_context(&bits, evidence.each_ref().map(|v| values(v)[field]));
                match field {
                    0 => e.beta = lanes,
                    1 => e.sg_free = lanes,
                    _ => e.sg_occupied = lanes,
                }
            }
        }
    }
}

/// All bits set in the lanes chosen, none in the others.
type Mask = [u32; BLOCK];

/// The two bits of each lane's map context (`MapContext` discriminants are 0 to 3), as masks.
#[inline(always)]
fn context_bits(context: &[MapContext; BLOCK]) -> [Mask; 2] {
    let mut bits = [[0; BLOCK]; 2];
    for i in 0..BLOCK {
        let c = context[i] as u8;
        bits[0][i] = if c & 1 != 0 { u32::MAX } else { 0 };
        bits[1][i] = if c & 2 != 0 { u32::MAX } else { 0 };
    }
    bits
}

/// `values[context]` in each lane, with `bits` from [`context_bits`]: three bit selects.
#[inline(always)]
fn lookup_by_context(bits: &[Mask; 2], values: [f32; 4]) -> Lanes {
    let v = values.map(f32::to_bits);
    let pick = |mask: u32, set: u32, clear: u32| (set & mask) | (clear & !mask);
    let mut lanes = [0.0; BLOCK];
    for i in 0..BLOCK {
        let (low, high) = (bits[0][i], bits[1][i]);
        let value = pick(high, pick(low, v[3], v[2]), pick(low, v[1], v[0]));
        lanes[i] = f32::from_bits(value);
    }
    lanes
}

/// What [`discount_and_combine_with_refined_sensor`] read of the discounted grid PG^α before
/// combining it.
struct BeforeSensor {
    /// m^α({F}), for ∅_FO (eq 22).
    free: Lanes,
    /// m^α(O) = Σ_{∅ ≠ A ⊆ O} m^α(A), for ∅_OF (eq 23).
    occupied: Lanes,
    /// Σ_A m^α(A), for Dempster's normalisation of SG'.
    total: Lanes,
}

/// m ← m^α ∩ r(SG_t) in place, in one pass over the pairs (A, A ∪ {F}) with F ∉ A.
///
/// Discounting (step 3): every A ≠ Ω keeps 1 − α_A of its mass and gives the rest to Ω
/// (eq 13-14 with one rate; class-rate discounting with one per set). `rate_per_set` is all 0
/// when the grid was discounted before (Mercier's discounting is not to Ω): then m^α = m,
/// exactly.
///
/// Combination: m ∩ r(SG) = m_Ω·m + m_O·(m restricted to O) + m_F·(m restricted to {F}).
/// Restricting to O gives A ⊆ O its own mass and that of A ∪ {F}; restricting to {F} puts
/// pl(F) = Σ_{A∋F} m(A) on {F} and the rest on ∅. So per pair, A gets m_Ω·m(A) +
/// m_O·(m(A) + m(A ∪ {F})) and A ∪ {F} keeps m_Ω·m(A ∪ {F}). Ω's pair waits until every set
/// has given Ω its share, and (∅, {F}) until the sums for the m_F terms are known.
///
/// Combining with SG' = (r(SG) ∩ GG − K·δ_∅) / (1 − K) instead follows by associativity:
/// m ∩ SG' = (m ∩ r(SG) ∩ GG − K·Σm·δ_∅) / (1 − K), since m ∩ δ_∅ is all of m's mass on ∅
/// ([`combine_with_map_prior`], then [`remove_sensor_map_conflict`]).
#[inline(always)]
fn discount_and_combine_with_refined_sensor(
    m: &mut BlockMasses,
    rate_per_set: &[f32; N_SETS],
    sensor: &SensorEvidence,
    live: Live,
) -> BeforeSensor {
    let (s_free, s_occupied, s_omega) = (&sensor.free, &sensor.occupied, &sensor.omega);
    let mut to_omega = [0.0; BLOCK];
    let empty = discounted(m, 0, rate_per_set, &mut to_omega);
    let free = discounted(m, class::F, rate_per_set, &mut to_omega);
    let mut occupied = [0.0; BLOCK];
    let mut with_free = free;
    for set in (2..N_SETS).step_by(2) {
        // A pair that holds no mass stays empty (the last pair, Ω's, always holds some).
        if !is_live(live, set) && !is_live(live, set | class::F) {
            continue;
        }
        let a = discounted(m, set, rate_per_set, &mut to_omega);
        let a_and_f = if set | class::F == OMEGA {
            // The last pair: every other set has given Ω its share by now.
            let mut omega = m[OMEGA];
            for i in 0..BLOCK {
                omega[i] += to_omega[i];
            }
            omega
        } else {
            discounted(m, set | class::F, rate_per_set, &mut to_omega)
        };
        for i in 0..BLOCK {
            occupied[i] += a[i];
            with_free[i] += a_and_f[i];
        }
        // A vacuous r(SG) (m_Ω = 1, m_F = m_O = 0) leaves every discounted mass exactly as it
        // is: a block the scan did not reach is only discounted.
        if sensor.any_observed {
            for i in 0..BLOCK {
                m[set][i] = s_omega[i] * a[i] + s_occupied[i] * (a[i] + a_and_f[i]);
                m[set | class::F][i] = s_omega[i] * a_and_f[i];
            }
        } else {
            m[set] = a;
            m[set | class::F] = a_and_f;
        }
    }
    let mut before = BeforeSensor {
        free,
        occupied,
        total: [0.0; BLOCK],
    };
    for i in 0..BLOCK {
        let without_free = empty[i] + occupied[i];
        m[0][i] =
            s_omega[i] * empty[i] + s_occupied[i] * (empty[i] + free[i]) + s_free[i] * without_free;
        m[class::F][i] = s_omega[i] * free[i] + s_free[i] * with_free[i];
        before.total[i] = without_free + with_free[i];
    }
    before
}

/// m(A) discounted at `rate`, in place (a copy returned and stored back costs a `memcpy`); what
/// it loses is added to `to_omega`. The same operations as [`discounted`].
#[inline(always)]
fn discount_in_place(masses: &mut Lanes, rate: f32, to_omega: &mut Lanes) {
    for i in 0..BLOCK {
        let moved = rate * masses[i];
        masses[i] -= moved;
        to_omega[i] += moved;
    }
}

/// m(A) discounted at A's rate; what it loses is added to `to_omega`.
#[inline(always)]
fn discounted(
    m: &BlockMasses,
    set: usize,
    rate_per_set: &[f32; N_SETS],
    to_omega: &mut Lanes,
) -> Lanes {
    let (rate, mut kept) = (rate_per_set[set], m[set]);
    for i in 0..BLOCK {
        let moved = rate * kept[i];
        kept[i] -= moved;
        to_omega[i] += moved;
    }
    kept
}

/// m ← m ∩ GG in place: for each map context in the block, its restriction to G with share β
/// in that context's cells and 0 elsewhere ([`Restriction`]). A block inside one context, the
/// usual case, makes one pass; cells where the map says nothing (G = Ω) make none.
#[inline(always)]
fn combine_with_map_prior(
    m: &mut BlockMasses,
    context: &[MapContext; BLOCK],
    sensor: &SensorEvidence,
    k: &StepConstants,
    live: Live,
) {
    for (index, prior) in k.map_prior.iter().enumerate() {
        if sensor.contexts_present & (1 << index) == 0 || !prior.is_informative() {
            continue;
        }
        let restriction = prior.restriction.for_live(live);
        if sensor.contexts_present == 1 << index {
            // Every cell is in this context.
            restriction.apply(m, &sensor.beta, live);
            continue;
        }
        let mut share = [0.0; BLOCK];
        for i in 0..BLOCK {
            share[i] = if context[i] as u8 == index as u8 {
                sensor.beta[i]
            } else {
                0.0
            };
        }
        restriction.apply(m, &share, live);
    }
}

/// Dempster's normalisation of SG' (eq 21), applied to m ∩ r(SG) ∩ GG: removes K·Σm from ∅ and
/// divides by 1 − K. K·Σm, not K: equal in exact arithmetic, but with K alone the f32 rounding
/// in Σm grew by 1/(1 − K) at every step.
#[inline(always)]
fn remove_sensor_map_conflict(
    m: &mut BlockMasses,
    sensor: &SensorEvidence,
    total: &Lanes,
    live: Live,
) {
    for i in 0..BLOCK {
        m[0][i] -= sensor.conflict[i] * total[i];
    }
    for (_, plane) in m
        .iter_mut()
        .enumerate()
        .filter(|(set, _)| is_live(live, *set))
    {
        for i in 0..BLOCK {
            plane[i] *= sensor.inv_normaliser[i];
        }
    }
}

/// Applies the residual policy to the mass on ∅; returns 1 per cell where `normalise` had
/// nothing to rescale and fell back to `to_omega`.
///
/// - `to_omega`: m(Ω) += m(∅), m(∅) = 0.
/// - `keep`: m(∅) stays.
/// - `normalise`: every other mass is divided by their sum, m(∅) = 0.
#[inline(always)]
fn settle_empty_set(m: &mut BlockMasses, policy: ResidualPolicy, live: Live) -> [u8; BLOCK] {
    let mut fallback = [0; BLOCK];
    match policy {
        ResidualPolicy::ToOmega => {
            for i in 0..BLOCK {
                m[OMEGA][i] += m[0][i];
                m[0][i] = 0.0;
            }
        }
        ResidualPolicy::Keep => {}
        ResidualPolicy::Normalise => {
            let rest = sum_sets(m, live, |set| set != 0);
            let mut scale = [1.0; BLOCK];
            let mut to_omega = [0.0; BLOCK];
            for i in 0..BLOCK {
                let enough = rest[i] > TOO_SMALL_TO_RESCALE;
                scale[i] = if enough { 1.0 / rest[i] } else { 1.0 };
                to_omega[i] = if enough { 0.0 } else { m[0][i] };
                fallback[i] = u8::from(!enough);
            }
            for plane in m.iter_mut().skip(1) {
                for i in 0..BLOCK {
                    plane[i] *= scale[i];
                }
            }
            for i in 0..BLOCK {
                m[OMEGA][i] += to_omega[i];
                m[0][i] = 0.0;
            }
        }
    }
    fallback
}

/// ζ += δ_inc (capped at 1) if m(O) ≥ γ_O and ∅_FO + ∅_OF ≤ γ_∅; ζ −= δ_dec (floored at 0) if
/// ∅_FO + ∅_OF > γ_∅; else unchanged (eq 24-27).
#[inline(always)]
fn update_accumulator(
    zeta: &mut Lanes,
    occupied: &Lanes,
    conflict_fo: &Lanes,
    conflict_of: &Lanes,
    k: &StepConstants,
) {
    for i in 0..BLOCK {
        let conflict = conflict_fo[i] + conflict_of[i];
        let increase = occupied[i] >= k.gamma_occupied && conflict <= k.gamma_conflict;
        let decrease = conflict > k.gamma_conflict;
        let raised = (zeta[i] + k.delta_inc).min(1.0);
        let lowered = (zeta[i] - k.delta_dec).max(0.0);
        zeta[i] = if increase {
            raised
        } else if decrease {
            lowered
        } else {
            zeta[i]
        };
    }
}

#[cfg(test)]
mod tests;
