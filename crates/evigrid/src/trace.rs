//! The moving trace: which cells were ever decided moving during the drive (paper Fig. 2,
//! picture 4), kept world-fixed in the window.

use crate::label::Label;
use crate::window::{Entered, Window};

/// Which cells were ever decided moving during the drive: a world-fixed flag per storage cell
/// (paper Fig. 2, picture 4). Cells that enter the window start clear, so memory stays that of
/// the window.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MovingTrace {
    ever_moving: Vec<bool>,
}

impl MovingTrace {
    /// An empty trace for a window of `len` cells.
    pub fn new(len: usize) -> Self {
        Self {
            ever_moving: vec![false; len],
        }
    }

    /// Clears the cells that entered the window in its last move.
    pub fn reset_entered(&mut self, window: &Window, entered: &Entered) {
        for block in entered.blocks() {
            for span in window.storage_spans(block) {
                self.ever_moving[span].fill(false);
            }
        }
    }

    /// Clears the storage cells in `range` (they just entered the window).
    pub fn reset_range(&mut self, range: std::ops::Range<usize>) {
        let len = self.ever_moving.len();
        self.ever_moving[range.start.min(len)..range.end.min(len)].fill(false);
    }

    /// Adds the cells decided moving now (`decisions` in storage order).
    pub fn record(&mut self, decisions: &[Label]) {
        for (flag, decision) in self.ever_moving.iter_mut().zip(decisions) {
            *flag |= *decision == Label::M;
        }
    }

    /// The flags, in storage order.
    pub fn as_slice(&self) -> &[bool] {
        &self.ever_moving
    }

    /// Number of cells flagged.
    pub fn count(&self) -> usize {
        self.ever_moving.iter().filter(|f| **f).count()
    }
}
