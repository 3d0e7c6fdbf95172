//! The world-fixed window of cells that follows the vehicle (SPEC §2).
//!
//! Cells are fixed in the map's local metric frame (x east, y north, metres): global cell
//! `(col, row)` covers `[col·s, (col+1)·s) × [row·s, (row+1)·s)` for a cell size `s`. The live
//! area is a window of `W × H` of those cells. The grids store it as a *circular buffer*, as
//! grid_map does: global cell `(col, row)` always lives at storage index
//! `row.rem_euclid(H) · W + col.rem_euclid(W)`, whatever the window's position. Moving the window
//! by whole cells therefore moves no data: only the cells that enter must be reset, and
//! [`Window::move_to`] says which they are. There is no resampling, so world-fixed content stays
//! exact however far the vehicle drives, and memory does not grow with the drive.
//!
//! This module owns the only world ↔ cell ↔ storage conversion of the crate.

use std::ops::Range;

use geodata::CellWindow;

/// An invalid window geometry, or a position that cannot be mapped to cells.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum WindowError {
    /// Width or height is zero.
    #[error("window of {width} × {height} cells is empty")]
    Empty {
        /// Requested width in cells.
        width: usize,
        /// Requested height in cells.
        height: usize,
    },
    /// The cell size is not a positive finite number.
    #[error("cell size {cell_size_m} m is not a positive finite number")]
    CellSize {
        /// Requested cell size in metres.
        cell_size_m: f64,
    },
    /// A position is NaN, infinite or too far away to index cells with 64-bit integers.
    #[error("position ({x_m}, {y_m}) m cannot be mapped to a cell")]
    Position {
        /// East coordinate in metres.
        x_m: f64,
        /// North coordinate in metres.
        y_m: f64,
    },
}

/// A world-fixed cell, by its global column (east) and row (north) index.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct GlobalCell {
    /// Column: the cell covers `[col·s, (col+1)·s)` in x (east).
    pub col: i64,
    /// Row: the cell covers `[row·s, (row+1)·s)` in y (north).
    pub row: i64,
}

/// The cells that entered the window in one move, as at most two disjoint world rectangles.
///
/// Each rectangle is a [`CellWindow`], ready for [`geodata::ContextRaster`]-style filling; use
/// [`Window::storage_spans`] to reach their cells in storage. Resetting these cells to vacuous
/// is the caller's business (the window owns no masses).
#[derive(Debug, Clone, PartialEq)]
pub struct Entered {
    /// Up to two rectangles; `None` entries are unused.
    blocks: [Option<CellWindow>; 2],
}

impl Entered {
    /// The rectangles of entered cells (zero, one or two, disjoint).
    pub fn blocks(&self) -> impl Iterator<Item = &CellWindow> {
        self.blocks.iter().flatten()
    }

    /// Number of cells that entered.
    pub fn cell_count(&self) -> usize {
        self.blocks().map(|b| b.width * b.height).sum()
    }

    /// True if no cell entered (the window did not move).
    pub fn is_empty(&self) -> bool {
        self.cell_count() == 0
    }
}

/// A `W × H` window of world-fixed square cells over a circular storage buffer.
///
/// # Example
///
/// ```
/// use evigrid::Window;
///
/// let mut window = Window::new(4, 3, 0.5)?;
/// // The point (1.2 m, 0.7 m) is in global cell (2, 1), stored at row 1, column 2.
/// assert_eq!(window.storage_index_of_point(1.2, 0.7), Some(1 * 4 + 2));
/// // One cell east: column 4 enters and takes the storage column that column 0 left.
/// let entered = window.move_to(1, 0);
/// assert_eq!(entered.cell_count(), 3);
/// assert_eq!(window.storage_index(4, 1), Some(1 * 4 + 0));
/// assert_eq!(window.storage_index(0, 1), None);
/// # Ok::<(), evigrid::WindowError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Window {
    width: usize,
    height: usize,
    cell_size_m: f64,
    first_col: i64,
    first_row: i64,
    /// Storage column and row of the first cell, `first_col mod W` and `first_row mod H`, kept
    /// so that indexing needs no division.
    first_storage_col: usize,
    first_storage_row: usize,
}

/// Beyond this many cells from the origin, `f64` cannot tell neighbouring cell edges apart at
/// any useful cell size; refusing such positions keeps every conversion exact.
const MAX_CELL_INDEX: f64 = (1u64 << 52) as f64;

/// ⌊v⌋ for |v| < 2^52, where truncation to an integer is exact. `f64::floor` is a call into the
/// maths library on x86_64's baseline (rounding instructions came with SSE4.1), and this runs
/// for every point of a scan.
#[inline]
fn floor_below_2_52(v: f64) -> i64 {
    let truncated = v as i64;
    truncated - i64::from(truncated as f64 > v)
}

impl Window {
    /// A window of `width × height` cells of side `cell_size_m` whose first (south-west) cell is
    /// global cell (0, 0).
    ///
    /// # Errors
    ///
    /// [`WindowError::Empty`] for a zero dimension, [`WindowError::CellSize`] for a cell size
    /// that is not positive and finite.
    pub fn new(width: usize, height: usize, cell_size_m: f64) -> Result<Self, WindowError> {
        if width == 0 || height == 0 {
            return Err(WindowError::Empty { width, height });
        }
        if !(cell_size_m.is_finite() && cell_size_m > 0.0) {
            return Err(WindowError::CellSize { cell_size_m });
        }
        Ok(Self {
            width,
            height,
            cell_size_m,
            first_col: 0,
            first_row: 0,
            first_storage_col: 0,
            first_storage_row: 0,
        })
    }

    /// Width in cells (W).
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in cells (H).
    pub fn height(&self) -> usize {
        self.height
    }

    /// Number of cells, W · H: the length of every grid plane.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Always false: a window has at least one cell. (Here for API symmetry with `len`.)
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Side of a cell in metres.
    pub fn cell_size_m(&self) -> f64 {
        self.cell_size_m
    }

    /// Global column of the window's westmost cells.
    pub fn first_col(&self) -> i64 {
        self.first_col
    }

    /// Global row of the window's southmost cells.
    pub fn first_row(&self) -> i64 {
        self.first_row
    }

    /// The window as a [`CellWindow`] (world rectangle of cells, row-major from its south-west
    /// cell), as the map rasteriser expects.
    pub fn as_cell_window(&self) -> CellWindow {
        CellWindow {
            first_col: self.first_col,
            first_row: self.first_row,
            width: self.width,
            height: self.height,
            cell_size_m: self.cell_size_m,
        }
    }

    /// The global cell containing the point (`x_m`, `y_m`), by `floor(x / s)`, `floor(y / s)`.
    ///
    /// `None` if a coordinate is NaN or infinite, or so far away (beyond 2^52 cells) that `f64`
    /// can no longer resolve cell boundaries.
    pub fn cell_of_point(&self, x_m: f64, y_m: f64) -> Option<GlobalCell> {
        let (x, y) = (x_m / self.cell_size_m, y_m / self.cell_size_m);
        // `!(a < b)` rather than `a >= b` so that NaN is refused too.
        if !(x.abs() < MAX_CELL_INDEX && y.abs() < MAX_CELL_INDEX) {
            return None;
        }
        let (col, row) = (floor_below_2_52(x), floor_below_2_52(y));
        // floor(−2^52 + ε) = −2^52 is refused too, as its magnitude is not below 2^52.
        let limit = MAX_CELL_INDEX as i64;
        (col.abs() < limit && row.abs() < limit).then_some(GlobalCell { col, row })
    }

    /// Centre of a global cell in metres: `((col + ½)·s, (row + ½)·s)`.
    pub fn cell_centre(&self, col: i64, row: i64) -> (f64, f64) {
        (
            (col as f64 + 0.5) * self.cell_size_m,
            (row as f64 + 0.5) * self.cell_size_m,
        )
    }

    /// True if the global cell lies inside the window.
    pub fn contains(&self, col: i64, row: i64) -> bool {
        let dc = col.wrapping_sub(self.first_col);
        let dr = row.wrapping_sub(self.first_row);
        (0..self.width as i64).contains(&dc) && (0..self.height as i64).contains(&dr)
    }

    /// Storage index of a global cell: `(row mod H)·W + (col mod W)`, or `None` outside the
    /// window.
    #[inline]
    pub fn storage_index(&self, col: i64, row: i64) -> Option<usize> {
        // Offsets inside the window, then a conditional wrap: the same as `rem_euclid` for
        // cells inside, without its integer divisions (this runs for every point of a scan).
        let dc = usize::try_from(col.wrapping_sub(self.first_col)).ok()?;
        let dr = usize::try_from(row.wrapping_sub(self.first_row)).ok()?;
        if dc >= self.width || dr >= self.height {
            return None;
        }
        let wrap = |v: usize, n: usize| if v >= n { v - n } else { v };
        let storage_col = wrap(self.first_storage_col + dc, self.width);
        let storage_row = wrap(self.first_storage_row + dr, self.height);
        Some(storage_row * self.width + storage_col)
    }

    /// Storage index of the cell containing a point, or `None` outside the window (or for a
    /// non-finite point).
    #[inline]
    pub fn storage_index_of_point(&self, x_m: f64, y_m: f64) -> Option<usize> {
        let cell = self.cell_of_point(x_m, y_m)?;
        self.storage_index(cell.col, cell.row)
    }

    /// The global cell stored at `index` (the inverse of [`Window::storage_index`]), or `None`
    /// if `index ≥ W·H`.
    pub fn cell_of_storage(&self, index: usize) -> Option<GlobalCell> {
        if index >= self.len() {
            return None;
        }
        let storage_row = (index / self.width) as i64;
        let storage_col = (index % self.width) as i64;
        // The window's first cell sits at storage (first mod size); count forward from there.
        let col_offset =
            (storage_col - self.storage_col(self.first_col) as i64).rem_euclid(self.width as i64);
        let row_offset =
            (storage_row - self.storage_row(self.first_row) as i64).rem_euclid(self.height as i64);
        Some(GlobalCell {
            col: self.first_col + col_offset,
            row: self.first_row + row_offset,
        })
    }

    #[inline]
    fn storage_col(&self, col: i64) -> usize {
        col.rem_euclid(self.width as i64) as usize
    }

    #[inline]
    fn storage_row(&self, row: i64) -> usize {
        row.rem_euclid(self.height as i64) as usize
    }

    /// Storage ranges covering a rectangle of global cells, one or two contiguous ranges per
    /// row of the rectangle (two where its columns wrap around the buffer's edge).
    ///
    /// The rectangle should lie inside the window (its cell size is ignored); cells outside
    /// would alias cells inside, so they are clipped away.
    pub fn storage_spans<'a>(
        &'a self,
        block: &CellWindow,
    ) -> impl Iterator<Item = Range<usize>> + use<'a> {
        let clipped = self.clip(block);
        let (cols, rows) = clipped.unwrap_or((0..0, 0..0));
        let width = self.width;
        rows.flat_map(move |row| {
            let row_start = self.storage_row(row) * width;
            let first = self.storage_col(cols.start);
            let count = (cols.end - cols.start) as usize;
            let head_len = count.min(width - first);
            let head = row_start + first..row_start + first + head_len;
            let tail = row_start..row_start + (count - head_len);
            std::iter::once(head).chain((!tail.is_empty()).then_some(tail))
        })
    }

    /// The part of a rectangle inside the window, as global column and row ranges.
    fn clip(&self, block: &CellWindow) -> Option<(Range<i64>, Range<i64>)> {
        let col_start = block.first_col.max(self.first_col);
        let col_end = (block.first_col.saturating_add(block.width as i64))
            .min(self.first_col + self.width as i64);
        let row_start = block.first_row.max(self.first_row);
        let row_end = (block.first_row.saturating_add(block.height as i64))
            .min(self.first_row + self.height as i64);
        (col_start < col_end && row_start < row_end)
            .then_some((col_start..col_end, row_start..row_end))
    }

    /// Storage ranges covering the whole window row by row from its south-west cell, in world
    /// order: row-major from `(first_col, first_row)`, as ROS `OccupancyGrid` exports expect.
    pub fn world_order_spans(&self) -> impl Iterator<Item = Range<usize>> + '_ {
        self.storage_spans(&self.as_cell_window())
    }

    /// Moves the window so that its first (south-west) cell is global cell
    /// (`first_col`, `first_row`), and returns the cells that entered.
    ///
    /// No data moves: cells that stay keep their storage index. A move by at least the window's
    /// width or height makes every cell new.
    pub fn move_to(&mut self, first_col: i64, first_row: i64) -> Entered {
        let dc = first_col.saturating_sub(self.first_col);
        let dr = first_row.saturating_sub(self.first_row);
        let (w, h) = (self.width as i64, self.height as i64);
        self.first_col = first_col;
        self.first_row = first_row;
        self.first_storage_col = self.storage_col(first_col);
        self.first_storage_row = self.storage_row(first_row);
        let block = |first_col: i64, first_row: i64, width: i64, height: i64| {
            (width > 0 && height > 0).then_some(CellWindow {
                first_col,
                first_row,
                width: width as usize,
                height: height as usize,
                cell_size_m: self.cell_size_m,
            })
        };
        if dc.unsigned_abs() >= w as u64 || dr.unsigned_abs() >= h as u64 {
            return Entered {
                blocks: [Some(self.as_cell_window()), None],
            };
        }
        // Rows that entered span the full width; columns that entered cover only the rows that
        // stayed, so the two blocks are disjoint.
        let (new_rows_first, kept_rows_first) = if dr >= 0 {
            (first_row + h - dr, first_row)
        } else {
            (first_row, first_row - dr)
        };
        let rows_block = block(first_col, new_rows_first, w, dr.abs());
        let new_cols_first = if dc >= 0 {
            first_col + w - dc
        } else {
            first_col
        };
        let cols_block = block(new_cols_first, kept_rows_first, dc.abs(), h - dr.abs());
        Entered {
            blocks: [rows_block, cols_block],
        }
    }

    /// Moves the window so that the cell containing (`x_m`, `y_m`) is its centre cell
    /// (column `W/2`, row `H/2`, rounding down), and returns the cells that entered.
    ///
    /// # Errors
    ///
    /// [`WindowError::Position`] if the point cannot be mapped to a cell (NaN, infinite, absurdly
    /// far); the window is then left where it was.
    pub fn recentre(&mut self, x_m: f64, y_m: f64) -> Result<Entered, WindowError> {
        let cell = self
            .cell_of_point(x_m, y_m)
            .ok_or(WindowError::Position { x_m, y_m })?;
        Ok(self.move_to(
            cell.col - (self.width / 2) as i64,
            cell.row - (self.height / 2) as i64,
        ))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn floor_without_the_maths_library_is_floor() {
        for v in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999,
            -2.999,
            1e15 + 0.5,
            -1e15 - 0.5,
        ] {
            assert_eq!(floor_below_2_52(v), v.floor() as i64, "{v}");
        }
        let w = Window::new(10, 10, 1.0).unwrap();
        let edge = MAX_CELL_INDEX - 0.5;
        assert_eq!(w.cell_of_point(-edge, 0.0), None);
        assert!(w.cell_of_point(edge - 1.0, 0.0).is_some());
    }

    #[test]
    fn cell_of_point_uses_floor_and_half_open_cells() {
        let w = Window::new(10, 10, 0.5).unwrap();
        // 0.5 m cells: x = 1.0 is the west edge of column 2; -0.01 is in column -1.
        assert_eq!(
            w.cell_of_point(1.0, 0.0),
            Some(GlobalCell { col: 2, row: 0 })
        );
        assert_eq!(
            w.cell_of_point(0.999, -0.01),
            Some(GlobalCell { col: 1, row: -1 })
        );
        assert_eq!(
            w.cell_of_point(-0.5, -1.0),
            Some(GlobalCell { col: -1, row: -2 })
        );
        assert_eq!(w.cell_of_point(f64::NAN, 0.0), None);
        assert_eq!(w.cell_of_point(0.0, f64::INFINITY), None);
        assert_eq!(w.cell_of_point(1e300, 0.0), None);
        assert_eq!(w.cell_centre(-1, 2), (-0.25, 1.25));
    }

    #[test]
    fn rejects_bad_geometry() {
        assert!(matches!(
            Window::new(0, 3, 1.0),
            Err(WindowError::Empty { .. })
        ));
        assert!(matches!(
            Window::new(3, 3, 0.0),
            Err(WindowError::CellSize { .. })
        ));
        assert!(matches!(
            Window::new(3, 3, f64::NAN),
            Err(WindowError::CellSize { .. })
        ));
        let mut w = Window::new(3, 3, 1.0).unwrap();
        assert!(w.recentre(f64::NAN, 0.0).is_err());
        assert_eq!(w.first_col(), 0);
    }

    #[test]
    fn storage_index_is_modular_with_negative_cells() {
        let mut w = Window::new(4, 3, 1.0).unwrap();
        w.move_to(-6, -4);
        // (-6) mod 4 = 2, (-4) mod 3 = 2 → index 2·4 + 2.
        assert_eq!(w.storage_index(-6, -4), Some(10));
        // (-3) mod 4 = 1, (-2) mod 3 = 1 → 1·4 + 1.
        assert_eq!(w.storage_index(-3, -2), Some(5));
        assert_eq!(w.storage_index(-2, -4), None);
        assert_eq!(w.storage_index(-6, -1), None);
        assert_eq!(w.storage_index(-7, -4), None);
    }

    #[test]
    fn recentre_puts_the_point_in_the_centre_cell() {
        let mut w = Window::new(5, 4, 2.0).unwrap();
        w.recentre(11.0, -3.0).unwrap();
        // Cell (5, -2); centre cell is (W/2, H/2) = (2, 2) → first cell (3, -4).
        assert_eq!((w.first_col(), w.first_row()), (3, -4));
    }

    #[test]
    fn a_diagonal_move_reports_disjoint_rows_and_columns() {
        let mut w = Window::new(5, 4, 1.0).unwrap();
        let entered = w.move_to(2, -1);
        // Rows entering: the one at the south (row -1), full width. Columns entering: 5, 6 over
        // the kept rows 0..3.
        let blocks: Vec<_> = entered.blocks().cloned().collect();
        assert_eq!(blocks.len(), 2);
        assert_eq!((blocks[0].first_col, blocks[0].first_row), (2, -1));
        assert_eq!((blocks[0].width, blocks[0].height), (5, 1));
        assert_eq!((blocks[1].first_col, blocks[1].first_row), (5, 0));
        assert_eq!((blocks[1].width, blocks[1].height), (2, 3));
        assert_eq!(entered.cell_count(), 5 + 6);
    }

    #[test]
    fn a_long_jump_makes_everything_new() {
        let mut w = Window::new(5, 4, 1.0).unwrap();
        assert_eq!(w.move_to(5, 0).cell_count(), 20);
        assert_eq!(w.move_to(5, -4).cell_count(), 20);
        assert!(w.move_to(5, -4).is_empty());
    }

    #[test]
    fn storage_spans_wrap_at_the_buffer_edge() {
        let mut w = Window::new(4, 2, 1.0).unwrap();
        w.move_to(3, 0);
        let block = CellWindow {
            first_col: 3,
            first_row: 0,
            width: 3,
            height: 1,
            cell_size_m: 1.0,
        };
        // Columns 3, 4, 5 live at storage columns 3, 0, 1.
        let spans: Vec<_> = w.storage_spans(&block).collect();
        assert_eq!(spans, vec![3..4, 0..2]);
    }

    /// Simulates the pipeline: stores each cell's own global coordinates, scrolls at random,
    /// resets what entered, and checks that every cell still holds exactly its own coordinates.
    fn scroll_and_check(width: usize, height: usize, moves: &[(i64, i64)]) {
        let mut w = Window::new(width, height, 0.5).unwrap();
        let mut store = vec![None; w.len()];
        let fill = |w: &Window, store: &mut Vec<Option<GlobalCell>>, block: &CellWindow| {
            for span in w.storage_spans(block) {
                for idx in span {
                    store[idx] = w.cell_of_storage(idx);
                }
            }
        };
        fill(&w, &mut store, &w.as_cell_window());
        let mut seen_new = 0;
        for &(dc, dr) in moves {
            let entered = w.move_to(w.first_col() + dc, w.first_row() + dr);
            let before: Vec<_> = store.clone();
            for block in entered.blocks() {
                for span in w.storage_spans(block) {
                    for idx in span {
                        store[idx] = None;
                        seen_new += 1;
                    }
                }
            }
            assert_eq!(seen_new, entered.cell_count(), "blocks must be disjoint");
            seen_new = 0;
            for idx in 0..w.len() {
                let cell = w.cell_of_storage(idx).unwrap();
                assert_eq!(w.storage_index(cell.col, cell.row), Some(idx));
                match store[idx] {
                    // A kept cell holds its own world-fixed content, untouched by the move.
                    Some(content) => {
                        assert_eq!(content, cell);
                        assert_eq!(before[idx], Some(cell));
                    }
                    None => store[idx] = Some(cell),
                }
            }
            // Every cell not reported as entered was there before the move.
            let reported = entered.cell_count();
            let kept = before
                .iter()
                .enumerate()
                .filter(|(i, c)| **c == w.cell_of_storage(*i))
                .count();
            assert_eq!(kept + reported, w.len());
        }
    }

    #[test]
    fn scrolling_keeps_world_fixed_content_exact() {
        scroll_and_check(
            7,
            5,
            &[(1, 0), (0, 1), (-3, 2), (2, -4), (6, 0), (-7, 0), (0, 9)],
        );
    }

    proptest! {
        #[test]
        fn scrolling_keeps_world_fixed_content_exact_prop(
            width in 1usize..9,
            height in 1usize..9,
            moves in proptest::collection::vec((-10i64..10, -10i64..10), 1..8),
        ) {
            scroll_and_check(width, height, &moves);
        }

        #[test]
        fn storage_index_round_trips(col in -1000i64..1000, row in -1000i64..1000) {
            let mut w = Window::new(6, 5, 0.2).unwrap();
            w.move_to(col - 3, row - 2);
            let idx = w.storage_index(col, row).unwrap();
            // The SPEC §2 formula: (row mod H)·W + (col mod W).
            prop_assert_eq!(idx, row.rem_euclid(5) as usize * 6 + col.rem_euclid(6) as usize);
            prop_assert_eq!(w.cell_of_storage(idx), Some(GlobalCell { col, row }));
            let (x, y) = w.cell_centre(col, row);
            prop_assert_eq!(w.cell_of_point(x, y), Some(GlobalCell { col, row }));
        }
    }
}
