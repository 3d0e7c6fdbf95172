//! Connected components of a scan's occupied cells (8-neighbours, world-fixed cells).
//!
//! Only the occupied cells are visited: a label plane marks them and is cleared again after the
//! labelling, so that one frame costs about nine lookups per occupied cell.

use crate::window::Window;

/// Label of a cell that is not occupied (or already assigned).
const FREE: u32 = u32::MAX;
/// Label of an occupied cell not yet reached by the flood fill.
const PENDING: u32 = u32::MAX - 1;

/// One cell of a cluster: its storage index and global column and row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Cell {
    pub(crate) idx: u32,
    pub(crate) col: i64,
    pub(crate) row: i64,
}

/// The clusters of one frame; buffers are kept between frames.
#[derive(Clone, Debug, Default)]
pub(crate) struct Clusters {
    marks: Vec<u32>,
    /// Cells grouped by cluster: cluster `k` is `cells[starts[k]..starts[k + 1]]`.
    cells: Vec<Cell>,
    starts: Vec<usize>,
    stack: Vec<Cell>,
}

impl Clusters {
    pub(crate) fn new(len: usize) -> Self {
        Self {
            marks: vec![FREE; len],
            ..Self::default()
        }
    }

    /// Bytes of the per-cell buffer (the cluster lists scale with a scan, not the window).
    pub(crate) fn dense_bytes(&self) -> usize {
        std::mem::size_of::<u32>() * self.marks.capacity()
    }

    /// Labels the occupied storage cells `occupied` of `window` into 8-connected clusters.
    pub(crate) fn label(&mut self, window: &Window, occupied: &[u32]) {
        // The labels of the previous frame are cleared first (they are kept until now so that
        // `label_of` can answer).
        for c in &self.cells {
            if let Some(m) = self.marks.get_mut(c.idx as usize) {
                *m = FREE;
            }
        }
        self.cells.clear();
        self.starts.clear();
        for &idx in occupied {
            if let Some(m) = self.marks.get_mut(idx as usize) {
                *m = PENDING;
            }
        }
        for &seed in occupied {
            if self.marks.get(seed as usize) != Some(&PENDING) {
                continue;
            }
            let Some(cell) = window.cell_of_storage(seed as usize) else {
                continue;
            };
            let label = self.starts.len() as u32;
            self.starts.push(self.cells.len());
            self.marks[seed as usize] = label;
            self.stack.push(Cell {
                idx: seed,
                col: cell.col,
                row: cell.row,
            });
            while let Some(c) = self.stack.pop() {
                self.cells.push(c);
                for (dc, dr) in NEIGHBOURS {
                    let (col, row) = (c.col + dc, c.row + dr);
                    let Some(n) = window.storage_index(col, row) else {
                        continue;
                    };
                    if self.marks[n] == PENDING {
                        self.marks[n] = label;
                        self.stack.push(Cell {
                            idx: n as u32,
                            col,
                            row,
                        });
                    }
                }
            }
        }
        self.starts.push(self.cells.len());
    }

    /// The cluster of an occupied storage cell of the last labelling, `None` for a cell that
    /// is not occupied.
    pub(crate) fn label_of(&self, idx: usize) -> Option<u32> {
        self.marks.get(idx).copied().filter(|&m| m < PENDING)
    }

    /// Forgets the labels (the window's storage was reassigned).
    pub(crate) fn clear(&mut self) {
        for c in &self.cells {
            if let Some(m) = self.marks.get_mut(c.idx as usize) {
                *m = FREE;
            }
        }
        self.cells.clear();
        self.starts.clear();
    }

    /// Number of clusters.
    pub(crate) fn len(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    /// The cells of cluster `k`.
    pub(crate) fn cluster(&self, k: usize) -> &[Cell] {
        &self.cells[self.starts[k]..self.starts[k + 1]]
    }
}

const NEIGHBOURS: [(i64, i64); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagonal_cells_join_and_a_gap_of_one_cell_separates() {
        // 6 × 4 window at the origin; storage index = row·6 + col.
        //   row 3: . . . . . X
        //   row 2: . . . . . X
        //   row 1: . X . . . .
        //   row 0: X . . X . .
        let window = Window::new(6, 4, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let occupied = [0, 7, 3, 17, 23];
        let mut clusters = Clusters::new(24);
        clusters.label(&window, &occupied);
        assert_eq!(clusters.len(), 3);
        let mut sets: Vec<Vec<u32>> = (0..3)
            .map(|k| {
                let mut v: Vec<u32> = clusters.cluster(k).iter().map(|c| c.idx).collect();
                v.sort();
                v
            })
            .collect();
        sets.sort();
        assert_eq!(sets, vec![vec![0, 7], vec![3], vec![17, 23]]);
        let zero = clusters.label_of(0);
        assert!(zero.is_some() && zero == clusters.label_of(7));
        assert_ne!(zero, clusters.label_of(3));
        assert_eq!(clusters.label_of(1), None);
        // Labelling again clears the old labels first.
        clusters.label(&window, &[1]);
        assert_eq!(clusters.len(), 1);
        assert_eq!(clusters.label_of(0), None);
        assert_eq!(clusters.label_of(1), Some(0));
    }

    #[test]
    fn cells_on_opposite_edges_of_the_window_are_not_neighbours() {
        // Storage columns 0 and 5 are adjacent in memory modulo the width, not in the world.
        let window = Window::new(6, 1, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let mut clusters = Clusters::new(6);
        clusters.label(&window, &[0, 5]);
        assert_eq!(clusters.len(), 2);
    }
}
