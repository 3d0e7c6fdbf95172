//! The floor: a STREAM-like pass over the bytes of a step that reads and writes the whole state.
//!
//! A step over the whole state reads and writes every PerceptionGrid plane in place (32 mass
//! planes, ζ, ∅_FO, ∅_OF and the seen flags) and reads the SensorGrid and GisGrid planes.
//! [`CopyFloor::run`] does that traffic with the least possible work: every written plane is
//! scaled in place by a factor the compiler cannot see (so the store cannot be elided), and every
//! read-only plane is summed. No kernel that touches the whole state can be faster, so
//! `copy / step` is the fraction of that floor the kernel reaches. The library's step skips the
//! planes it knows hold +0 (`StepStats::state_bytes_moved`, shown beside the floor's traffic), so
//! it can go below the floor.

use rayon::prelude::*;
use std::hint::black_box;

/// Planes of the same size and count as one step's working set.
#[derive(Clone, Debug)]
pub struct CopyFloor {
    read_write_f32: Vec<Vec<f32>>,
    read_write_u8: Vec<u8>,
    read_only_f32: Vec<Vec<f32>>,
    read_only_u8: Vec<u8>,
}

impl CopyFloor {
    /// The working set of a step on `cells` cells: 35 f32 planes and one u8 plane read and
    /// written, two f32 planes and one u8 plane read.
    pub fn new(cells: usize) -> Self {
        CopyFloor {
            read_write_f32: vec![vec![1.0; cells]; 35],
            read_write_u8: vec![1; cells],
            read_only_f32: vec![vec![0.5; cells]; 2],
            read_only_u8: vec![2; cells],
        }
    }

    /// Bytes read plus bytes written by one pass.
    pub fn bytes_moved(&self) -> usize {
        let cells = self.read_only_u8.len();
        2 * (35 * 4 + 1) * cells + (2 * 4 + 1) * cells
    }

    /// One pass on the current rayon pool, rows of `row_cells` cells in parallel.
    pub fn run(&mut self, row_cells: usize) -> f32 {
        let scale = black_box(1.0f32);
        let chunk = row_cells.max(1) * 16;
        for plane in &mut self.read_write_f32 {
            plane
                .par_chunks_mut(chunk)
                .for_each(|cells| cells.iter_mut().for_each(|x| *x *= scale));
        }
        let bump = black_box(0u8);
        self.read_write_u8
            .par_chunks_mut(chunk)
            .for_each(|cells| cells.iter_mut().for_each(|x| *x = x.wrapping_add(bump)));
        let mut checksum = 0.0;
        for plane in &self.read_only_f32 {
            checksum += plane
                .par_chunks(chunk)
                .map(|cells| cells.iter().sum::<f32>())
                .sum::<f32>();
        }
        checksum
            + self
                .read_only_u8
                .par_chunks(chunk)
                .map(|cells| cells.iter().map(|&x| u32::from(x)).sum::<u32>() as f32)
                .sum::<f32>()
    }
}
