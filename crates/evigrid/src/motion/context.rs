//! The boundary-aware map prior of the `evigrid` variant: cells of the intermediate space T
//! near a building cell take the context [`MapContext::BuildingEdge`], prior {F, I}.
//!
//! The SPEC §4 prior rasterises by the cell centre, so a cell that a façade cuts but whose
//! centre is outside the footprint gets the context T although the scanner hits the wall in
//! it: as the ego moves, rays alternately cross it and end in it, and each switch is the
//! free→occupied conflict of a moving object. Here such cells, up to `building_margin_cells`
//! 4-neighbour steps from a building cell, hold "the façade or free space": a return there is
//! the building, a ray through it is free space, and neither is a moving object. (Giving them
//! the building's own prior {I} stopped the flicker too, but decided free space beside every
//! wall as building.) Road cells are left alone: a road beside a building carries traffic.
//! The grid is kept up to date where the window moved: the cells that entered and a margin
//! around them (their neighbours may have gained a building neighbour).

use geodata::{CellWindow, MapContext};

use crate::grids::GisGrid;
use crate::window::{Entered, Window};

/// Refreshes `out` from `source` over the whole window (`entered = None`) or around the cells
/// that entered it.
pub(crate) fn refresh(
    out: &mut GisGrid,
    source: &GisGrid,
    window: &Window,
    entered: Option<&Entered>,
    margin: usize,
) {
    let whole = window.as_cell_window();
    match entered {
        None => refresh_rect(out, source, window, &whole, 0, margin),
        Some(entered) => {
            for block in entered.blocks() {
                refresh_rect(out, source, window, block, margin as i64, margin);
            }
        }
    }
}

fn refresh_rect(
    out: &mut GisGrid,
    source: &GisGrid,
    window: &Window,
    block: &CellWindow,
    grow: i64,
    margin: usize,
) {
    let m = margin as i64;
    for row in block.first_row - grow..block.first_row + block.height as i64 + grow {
        for col in block.first_col - grow..block.first_col + block.width as i64 + grow {
            let Some(idx) = window.storage_index(col, row) else {
                continue;
            };
            let own = source.context[idx];
            let near_building = || {
                (-m..=m).any(|dr| {
                    let reach = m - dr.abs();
                    (-reach..=reach).any(|dc| {
                        window
                            .storage_index(col + dc, row + dr)
                            .is_some_and(|n| source.context[n] == MapContext::Building)
                    })
                })
            };
            out.context[idx] = if own == MapContext::Other && margin > 0 && near_building() {
                MapContext::BuildingEdge
            } else {
                own
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn other_cells_beside_a_building_become_its_edge_roads_do_not() {
        // 5 × 3 window; a building cell at (2, 1), road on row 0.
        let window = Window::new(5, 3, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let mut source = GisGrid::new(5, 3);
        source.context.fill(MapContext::Other);
        source.context[..5].fill(MapContext::Road);
        source.context[7] = MapContext::Building;
        let mut out = GisGrid::new(5, 3);
        refresh(&mut out, &source, &window, None, 1);
        let (b, e) = (MapContext::Building, MapContext::BuildingEdge);
        let (o, r) = (MapContext::Other, MapContext::Road);
        assert_eq!(
            out.context,
            vec![r, r, r, r, r, o, e, b, e, o, o, o, e, o, o]
        );
        refresh(&mut out, &source, &window, None, 0);
        assert_eq!(out.context, source.context);
    }

    #[test]
    fn after_a_move_the_entered_cells_and_their_neighbours_are_refreshed() {
        let mut window = Window::new(4, 1, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let mut source = GisGrid::new(4, 1);
        source.context.fill(MapContext::Other);
        let mut out = source.clone();
        refresh(&mut out, &source, &window, None, 1);
        // Column 4 enters (storage 0) and is a building: column 3 (storage 3) now touches it.
        let entered = window.move_to(1, 0);
        source.context[0] = MapContext::Building;
        refresh(&mut out, &source, &window, Some(&entered), 1);
        let (o, b, e) = (
            MapContext::Other,
            MapContext::Building,
            MapContext::BuildingEdge,
        );
        assert_eq!(out.context, vec![b, o, o, e]);
    }
}
