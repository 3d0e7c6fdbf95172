//! How the step walks the grid: the window's storage cut into tasks (the unit of parallel
//! work), each task into tiles and blocks, each block loaded, stepped, decided and stored; and
//! the run-time choice between the AVX2 and the portable build of the same code.

use super::StepStats;
use super::constants::StepConstants;
use super::fuse::step_block;
use super::memory::{Block, CellRun};
use super::passes::{ALL_SETS, BLOCK, REACHABLE};
use crate::decision::decide_lanes;
use crate::grids::{CONFLICT_FO_BIT, CONFLICT_OF_BIT, PlaneBits, ZETA_BIT};

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

impl<'a> CellRun<'a> {
    /// Cuts the run into tasks of [`CELLS_PER_TASK`] cells (whole blocks; the last task takes
    /// the rest). The tasks do not depend on the number of threads, nor does any result.
    pub(super) fn into_tasks(self) -> Vec<Self> {
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
    pub(super) fn step(self, k: &StepConstants) -> StepStats {
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
    pub(super) fn step_blocks(
        mut self,
        k: &StepConstants,
        prefetch: Option<impl Fn(*const i8)>,
    ) -> StepStats {
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
}
