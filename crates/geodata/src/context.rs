//! What a map says about one cell, and which cells a window covers.

/// The map context of one grid cell, decided by its centre (SPEC §4, eq 34-38), or derived
/// from its neighbours ([`BuildingEdge`](Self::BuildingEdge)).
///
/// The discriminants are fixed so that a context plane can be stored as bytes.
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MapContext {
    /// No map information: the cell centre is outside the map's extent (the prior is vacuous).
    Unknown = 0,
    /// Inside the map's extent but neither building nor road: the intermediate space T.
    Other = 1,
    /// Road surface ℛ: buffered vehicle-road centrelines, `area:highway` polygons, parking areas.
    Road = 2,
    /// Building ℬ. Wins over road where both contain the centre (SPEC §4 decision).
    Building = 3,
    /// Intermediate space beside a building: a cell a façade may cross although its centre is
    /// outside the footprint. The centre rule above never gives it; evigrid's boundary-aware
    /// prior derives it from the [`Building`](Self::Building) cells nearby.
    BuildingEdge = 4,
}

impl MapContext {
    /// Lower-case name used in JSON output and logs: `unknown`, `other`, `road`, `building`,
    /// `building-edge`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Unknown => "unknown",
            Self::Other => "other",
            Self::Road => "road",
            Self::Building => "building",
            Self::BuildingEdge => "building-edge",
        }
    }
}

/// A rectangular block of the world-fixed grid, in the map's local metric frame.
///
/// Global cell `(col, row)` covers `[col·s, (col+1)·s) × [row·s, (row+1)·s)` metres (x east,
/// y north, `s = cell_size_m`) and its centre is `((col+0.5)·s, (row+0.5)·s)`. The window holds
/// columns `first_col..first_col + width` and rows `first_row..first_row + height`; a buffer for it
/// is indexed `row_in_window * width + col_in_window`, row 0 being the southernmost row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellWindow {
    /// Global column index of the window's westernmost column.
    pub first_col: i64,
    /// Global row index of the window's southernmost row.
    pub first_row: i64,
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// Side of a square cell, metres.
    pub cell_size_m: f64,
}

impl CellWindow {
    /// The smallest window whose cells cover the rectangle `rect` (local metres) at `cell_size_m`.
    ///
    /// Every point of `rect` lies in a cell of the window; cells are those whose half-open extent
    /// meets `rect`. A non-positive or non-finite `cell_size_m`, or a non-finite `rect`, gives an
    /// empty window (width and height 0).
    ///
    /// ```
    /// use geodata::CellWindow;
    /// let rect = geo::Rect::new(geo::coord! { x: -1.0, y: 0.0 }, geo::coord! { x: 1.0, y: 2.2 });
    /// let window = CellWindow::covering(&rect, 0.5);
    /// assert_eq!((window.first_col, window.first_row), (-2, 0));
    /// assert_eq!((window.width, window.height), (5, 5)); // x: cells -2..=2, y: cells 0..=4
    /// ```
    pub fn covering(rect: &geo::Rect<f64>, cell_size_m: f64) -> Self {
        let valid = cell_size_m.is_finite()
            && cell_size_m > 0.0
            && [rect.min().x, rect.min().y, rect.max().x, rect.max().y]
                .iter()
                .all(|v| v.is_finite());
        if !valid {
            return Self {
                first_col: 0,
                first_row: 0,
                width: 0,
                height: 0,
                cell_size_m,
            };
        }
        let first_col = (rect.min().x / cell_size_m).floor() as i64;
        let first_row = (rect.min().y / cell_size_m).floor() as i64;
        let last_col = (rect.max().x / cell_size_m).floor() as i64;
        let last_row = (rect.max().y / cell_size_m).floor() as i64;
        // Checked: `as i64` saturates for a world-sized extent at a small cell, and the span of
        // two saturated ends overflows.
        let span = |first: i64, last: i64| {
            last.checked_sub(first)
                .and_then(|d| d.checked_add(1))
                .and_then(|n| usize::try_from(n).ok())
                .unwrap_or(0)
        };
        Self {
            first_col,
            first_row,
            width: span(first_col, last_col),
            height: span(first_row, last_row),
            cell_size_m,
        }
    }

    /// Number of cells, `width · height` (saturating: a window that large is refused by every
    /// user before anything is allocated).
    pub fn len(&self) -> usize {
        self.width.saturating_mul(self.height)
    }

    /// True when the window holds no cell.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Centre of global cell `(col, row)`, local metres.
    pub fn cell_centre(&self, col: i64, row: i64) -> (f64, f64) {
        (
            cell_centre_coordinate(col, self.cell_size_m),
            cell_centre_coordinate(row, self.cell_size_m),
        )
    }
}

/// Centre coordinate of cell `index` along one axis, `(index + 0.5)·s`.
///
/// Every decision about cell centres goes through this one expression so that the scanline fill
/// and any point-in-polygon check agree to the last bit.
#[inline]
pub(crate) fn cell_centre_coordinate(index: i64, cell_size_m: f64) -> f64 {
    (index as f64 + 0.5) * cell_size_m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn discriminants_are_the_contract() {
        assert_eq!(MapContext::Unknown as u8, 0);
        assert_eq!(MapContext::Other as u8, 1);
        assert_eq!(MapContext::Road as u8, 2);
        assert_eq!(MapContext::Building as u8, 3);
        assert_eq!(MapContext::BuildingEdge as u8, 4);
    }

    #[test]
    fn covering_includes_cells_touched_by_the_max_edge() {
        // x in [0, 1] at s = 0.5: the point x = 1.0 lies in cell 2 ([1.0, 1.5)), so 3 columns.
        let rect = geo::Rect::new(
            geo::coord! { x: 0.0, y: 0.0 },
            geo::coord! { x: 1.0, y: 0.1 },
        );
        let window = CellWindow::covering(&rect, 0.5);
        assert_eq!((window.first_col, window.width), (0, 3));
        assert_eq!((window.first_row, window.height), (0, 1));
        assert_eq!(window.cell_centre(-1, 2), (-0.25, 1.25));
    }

    #[test]
    fn covering_with_bad_cell_size_is_empty() {
        let rect = geo::Rect::new(
            geo::coord! { x: 0.0, y: 0.0 },
            geo::coord! { x: 1.0, y: 1.0 },
        );
        assert!(CellWindow::covering(&rect, 0.0).is_empty());
        assert!(CellWindow::covering(&rect, f64::NAN).is_empty());
    }
}
