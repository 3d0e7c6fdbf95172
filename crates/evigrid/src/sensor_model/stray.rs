//! Stray returns of a 3-D lidar: returns with too few others around them to be a surface.
//!
//! A 64-beam lidar puts many returns on anything solid, and a surface continues into the cells
//! around; a return with few others near it is stray (the HDL-64E's phantom returns about 2 m up
//! in mid-road, spray, dust). A cell is stray when it and its eight neighbours hold fewer than
//! `min_neighbourhood_returns` obstacle returns of the scan together. At the window's border a
//! cell has fewer neighbours inside the window, so an object there needs its returns closer
//! together; the border lies far beyond the sensor's range in the usual windows.

use crate::window::Window;

/// Per-scan scratch of the stray test, kept between scans: it costs the scan's returns, not the
/// window (only the cells the scan touched are reset).
#[derive(Clone, Debug, Default)]
pub(super) struct StrayFilter {
    /// Obstacle returns per cell of the current scan while counting, then [`STRAY`] or
    /// [`KEPT`] in the cells holding returns; zero elsewhere.
    returns_per_cell: Vec<u16>,
    /// The cells holding obstacle returns in the current scan, each once.
    cells: Vec<usize>,
    /// Whether each of `cells` is stray, while marking.
    stray: Vec<bool>,
}

const STRAY: u16 = 1;
const KEPT: u16 = 2;

impl StrayFilter {
    /// Counts the returns (their cells' storage indices, a cell once per return), then marks
    /// each cell holding one stray when it and its eight neighbours hold fewer than
    /// `min_returns`. Forgets the previous scan's marks first.
    pub(super) fn mark(
        &mut self,
        window: &Window,
        returns: impl Iterator<Item = usize>,
        min_returns: u32,
    ) {
        self.clear();
        self.returns_per_cell.resize(window.len(), 0);
        for idx in returns {
            let Some(count) = self.returns_per_cell.get_mut(idx) else {
                continue;
            };
            if *count == 0 {
                self.cells.push(idx);
            }
            *count = count.saturating_add(1);
        }
        for &idx in &self.cells {
            let own = u32::from(self.returns_per_cell[idx]);
            // Most cells of a surface hold enough returns on their own.
            if own >= min_returns {
                self.stray.push(false);
                continue;
            }
            let mut near = 0u32;
            if let Some(cell) = window.cell_of_storage(idx) {
                for dr in -1..=1 {
                    for dc in -1..=1 {
                        // Outside the window: `None`, not the cell the storage wraps to.
                        if let Some(n) = window.storage_index(cell.col + dc, cell.row + dr) {
                            near += u32::from(self.returns_per_cell[n]);
                        }
                    }
                }
            }
            self.stray.push(near < min_returns);
        }
        for (&idx, &stray) in self.cells.iter().zip(&self.stray) {
            self.returns_per_cell[idx] = if stray { STRAY } else { KEPT };
        }
    }

    /// Whether the return in cell `idx` is stray (false for a cell [`Self::mark`] did not see).
    #[inline]
    pub(super) fn is_stray(&self, idx: usize) -> bool {
        self.returns_per_cell.get(idx) == Some(&STRAY)
    }

    /// Resets the marked cells to zero.
    fn clear(&mut self) {
        for &idx in &self.cells {
            self.returns_per_cell[idx] = 0;
        }
        self.cells.clear();
        self.stray.clear();
    }
}
