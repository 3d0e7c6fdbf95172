//! The map prior (SPEC §4, eq 32-38): the GISGrid mass function of each map context, and filling
//! the GISGrid's contexts through the window.
//!
//! The GISGrid stores one [`MapContext`] per storage cell. Its mass function, β on a focal set G
//! and 1 − β on Ω, is written once, here: [`prior_focal_set`] gives G and [`prior_beta`] gives β,
//! and the step derives its masses from them. Because the window is a circular buffer, only
//! the cells that entered after a move need new contexts: the map is rasterised for those blocks
//! alone ([`MapPrior::fill_entered`]), so the map costs nothing per frame while the vehicle stays
//! in the same cell. Without a map every cell is [`MapContext::Unknown`], a vacuous prior.
//!
//! ```
//! use evigrid::Params;
//! use evigrid::class::{F, M, S};
//! use evigrid::{prior_beta, prior_focal_set};
//! use geodata::MapContext;
//!
//! let params = Params::default();
//! // On a road the map says "free, or an object": β_R on {F, S, M}, the rest on Ω.
//! assert_eq!(prior_focal_set(MapContext::Road), F | S | M);
//! assert_eq!(prior_beta(MapContext::Road, &params.map), params.map.beta_road);
//! assert_eq!(prior_beta(MapContext::Unknown, &params.map), 0.0); // no map: vacuous
//! ```

use geodata::{CellWindow, ContextRaster, MapContext};

use crate::grids::{GisGrid, OMEGA, class};
use crate::params::MapParams;
use crate::window::{Entered, Window};

/// Every map context, in the order of their discriminants: a table indexed by
/// `context as usize` is built as `MAP_CONTEXTS.map(…)`.
pub const MAP_CONTEXTS: [MapContext; 5] = [
    MapContext::Unknown,
    MapContext::Other,
    MapContext::Road,
    MapContext::Building,
    MapContext::BuildingEdge,
];

/// The focal set G on which the GISGrid of a map context puts its mass β (a bitmask of Ω_PG, as
/// in [`class`]): {I} in a building, {F, S, M} on a road, {F, U, S, M} in the intermediate
/// space, Ω where the map says nothing.
///
/// Beyond SPEC, {F, I} beside a building ([`MapContext::BuildingEdge`], only in the `evigrid`
/// variant's boundary-aware prior, docs/motion.md): the cell holds the façade or free space, so
/// a return there is the building and a ray through it is free space.
///
/// # References
/// SPEC §4; Kurdej et al. 2013, eq 34-38.
pub const fn prior_focal_set(context: MapContext) -> usize {
    match context {
        MapContext::Unknown => OMEGA,
        MapContext::Other => class::F | class::U | class::S | class::M,
        MapContext::Road => class::F | class::S | class::M,
        MapContext::Building => class::I,
        MapContext::BuildingEdge => class::F | class::I,
    }
}

/// β, the mass the GISGrid of a map context puts on [`prior_focal_set`] (the rest, 1 − β, is on
/// Ω): the confidence in the map for that context, 0 where the map says nothing. Beside a
/// building it is β_B, the confidence in the footprint.
///
/// # References
/// SPEC §4; Kurdej et al. 2013, eq 34-38.
pub fn prior_beta(context: MapContext, map: &MapParams) -> f64 {
    match context {
        MapContext::Unknown => 0.0,
        MapContext::Other => map.beta_other,
        MapContext::Road => map.beta_road,
        MapContext::Building | MapContext::BuildingEdge => map.beta_building,
    }
}

/// The map (if any) and a scratch buffer to rasterise window blocks into.
#[derive(Clone, Debug, Default)]
pub struct MapPrior {
    raster: Option<ContextRaster>,
    scratch: Vec<MapContext>,
}

impl MapPrior {
    /// A prior from a rasteriser, or `None` for driving without a map (vacuous prior).
    pub fn new(raster: Option<ContextRaster>) -> Self {
        Self {
            raster,
            scratch: Vec::new(),
        }
    }

    /// True if there is a map.
    pub fn has_map(&self) -> bool {
        self.raster.is_some()
    }

    /// Fills every cell of the window (at start, or after a jump).
    pub fn fill_window(&mut self, window: &Window, grid: &mut GisGrid) {
        self.fill_block(window, &window.as_cell_window(), grid);
    }

    /// Fills the cells that entered in the last move of `window`.
    pub fn fill_entered(&mut self, window: &Window, entered: &Entered, grid: &mut GisGrid) {
        for block in entered.blocks() {
            self.fill_block(window, block, grid);
        }
    }

    /// Rasterises one block of world cells and scatters it into storage.
    fn fill_block(&mut self, window: &Window, block: &CellWindow, grid: &mut GisGrid) {
        let Some(raster) = &self.raster else {
            for span in window.storage_spans(block) {
                grid.context[span].fill(MapContext::Unknown);
            }
            return;
        };
        self.scratch.clear();
        self.scratch.resize(block.len(), MapContext::Unknown);
        raster.fill(block, &mut self.scratch);
        // Spans come row by row (south to north), west to east within a row: the order of the
        // rasteriser's row-major output.
        let mut next = 0;
        for span in window.storage_spans(block) {
            let len = span.len();
            grid.context[span].copy_from_slice(&self.scratch[next..next + len]);
            next += len;
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use geo::{Rect, coord, polygon};
    use geodata::LocalMap;

    /// A building on x ∈ [2, 6], y ∈ [0, 4]; a road y ∈ [−2, 0] across the map; extent
    /// [−10, 10]².
    fn raster() -> ContextRaster {
        let building =
            polygon![(x: 2.0, y: 0.0), (x: 6.0, y: 0.0), (x: 6.0, y: 4.0), (x: 2.0, y: 4.0)];
        let road = polygon![(x: -10.0, y: -2.0), (x: 10.0, y: -2.0), (x: 10.0, y: 0.0), (x: -10.0, y: 0.0)];
        let extent = Rect::new(coord! { x: -10.0, y: -10.0 }, coord! { x: 10.0, y: 10.0 });
        ContextRaster::new(&LocalMap::new(vec![building], vec![road], extent))
    }

    /// Checks every storage cell against a direct look-up of its centre.
    fn assert_matches_map(window: &Window, grid: &GisGrid, raster: &ContextRaster) {
        for idx in 0..window.len() {
            let cell = window.cell_of_storage(idx).unwrap();
            let (x, y) = window.cell_centre(cell.col, cell.row);
            assert_eq!(grid.context[idx], raster.context_at(x, y), "cell {cell:?}");
        }
    }

    #[test]
    fn map_contexts_are_listed_in_discriminant_order() {
        for (index, context) in MAP_CONTEXTS.into_iter().enumerate() {
            assert_eq!(context as usize, index, "{context:?}");
        }
    }

    #[test]
    fn filling_after_moves_equals_filling_from_scratch() {
        let raster = raster();
        let mut window = Window::new(8, 6, 1.0).unwrap();
        window.move_to(-4, -3);
        let mut grid = GisGrid::new(8, 6);
        let mut prior = MapPrior::new(Some(raster.clone()));
        prior.fill_window(&window, &mut grid);
        assert_matches_map(&window, &grid, &raster);
        assert_eq!(
            grid.context[window.storage_index(3, 1).unwrap()],
            MapContext::Building
        );
        assert_eq!(
            grid.context[window.storage_index(-4, -1).unwrap()],
            MapContext::Road
        );
        // Drive north-east and beyond the map's edge (x > 10 is Unknown).
        for (dc, dr) in [(1, 0), (2, 1), (0, -3), (5, 2), (4, 4), (-20, 0)] {
            let entered = window.move_to(window.first_col() + dc, window.first_row() + dr);
            prior.fill_entered(&window, &entered, &mut grid);
            assert_matches_map(&window, &grid, &raster);
        }
    }

    #[test]
    fn without_a_map_entered_cells_become_unknown() {
        let mut window = Window::new(4, 4, 1.0).unwrap();
        let mut grid = GisGrid::new(4, 4);
        grid.context.fill(MapContext::Road);
        let mut prior = MapPrior::new(None);
        let entered = window.move_to(1, 0);
        prior.fill_entered(&window, &entered, &mut grid);
        let unknown = grid
            .context
            .iter()
            .filter(|c| **c == MapContext::Unknown)
            .count();
        assert_eq!(unknown, 4);
        assert_eq!(
            grid.context[window.storage_index(4, 2).unwrap()],
            MapContext::Unknown
        );
        assert_eq!(
            grid.context[window.storage_index(3, 2).unwrap()],
            MapContext::Road
        );
    }
}
