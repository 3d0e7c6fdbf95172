//! Roads through buildings at street level: a building passage's surface cut out of the building.
//!
//! OSM draws a building over the archway a street passes through (`tunnel=building_passage`,
//! `covered=yes`); a scanner on that street sees the passage's walls, not the façade across it.
//! Cutting the passage's surface out of the footprint makes the map say what the scanner meets,
//! and the building rule (a building wins over road where both hold a cell centre) stays as it is
//! everywhere else.

use geo::{Area, BooleanOps, BoundingRect, Intersects, MultiPolygon, Polygon};

/// Pieces of a cut building smaller than this are dropped, m²: a sliver left between a passage's
/// edge and a wall holds no cell centre worth a wall (a 0.2 m cell is 0.04 m²).
const MIN_PIECE_M2: f64 = 0.01;

/// `buildings` with every polygon of `passages` (road surface at street level under a roof) cut
/// out of those it overlaps; a building cut in two becomes two polygons. Buildings no passage
/// touches are kept as they are, in order. Local metres.
pub(crate) fn cut_passages(
    buildings: Vec<Polygon<f64>>,
    passages: &[Polygon<f64>],
) -> Vec<Polygon<f64>> {
    if passages.is_empty() {
        return buildings;
    }
    let passage_boxes: Vec<_> = passages.iter().map(BoundingRect::bounding_rect).collect();
    let mut out = Vec::with_capacity(buildings.len());
    for building in buildings {
        let Some(bounds) = building.bounding_rect() else {
            out.push(building);
            continue;
        };
        let crossing: Vec<&Polygon<f64>> = passages
            .iter()
            .zip(&passage_boxes)
            .filter(|(_, b)| b.is_some_and(|b| b.intersects(&bounds)))
            .map(|(p, _)| p)
            .filter(|p| p.intersects(&building))
            .collect();
        if crossing.is_empty() {
            out.push(building);
            continue;
        }
        let mut rest = MultiPolygon::new(vec![building]);
        for passage in crossing {
            rest = rest.difference(passage);
        }
        out.extend(
            rest.0
                .into_iter()
                .filter(|p| p.unsigned_area() >= MIN_PIECE_M2),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo::{Contains, coord, point, polygon};

    fn house() -> Polygon<f64> {
        polygon![(x: 0.0, y: 0.0), (x: 20.0, y: 0.0), (x: 20.0, y: 10.0), (x: 0.0, y: 10.0)]
    }

    #[test]
    fn a_passage_through_a_building_cuts_it_in_two() {
        // A 4 m wide passage from south to north through the middle of a 20 m × 10 m house.
        let passage = geo::Rect::new(coord! { x: 8.0, y: -2.0 }, coord! { x: 12.0, y: 12.0 });
        let pieces = cut_passages(vec![house()], &[passage.to_polygon()]);
        assert_eq!(pieces.len(), 2);
        // What is left: two 8 m × 10 m halves, 160 m² of the 200 m².
        let area: f64 = pieces.iter().map(Area::unsigned_area).sum();
        assert!((area - 160.0).abs() < 1e-9, "{area}");
        assert!(
            !pieces
                .iter()
                .any(|p| p.contains(&point! { x: 10.0, y: 5.0 }))
        );
        assert!(
            pieces
                .iter()
                .any(|p| p.contains(&point! { x: 4.0, y: 5.0 }))
        );
        assert!(
            pieces
                .iter()
                .any(|p| p.contains(&point! { x: 16.0, y: 5.0 }))
        );
    }

    #[test]
    fn buildings_a_passage_does_not_touch_stay_as_they_were() {
        let far = geo::Rect::new(coord! { x: 50.0, y: 0.0 }, coord! { x: 54.0, y: 10.0 });
        let near_box = geo::Rect::new(coord! { x: 19.0, y: 11.0 }, coord! { x: 23.0, y: 15.0 });
        assert_eq!(
            cut_passages(vec![house()], &[far.to_polygon()]),
            vec![house()]
        );
        // Bounding boxes apart by 1 m diagonally: nothing to cut.
        assert_eq!(
            cut_passages(vec![house()], &[near_box.to_polygon()]),
            vec![house()]
        );
        assert_eq!(cut_passages(vec![house()], &[]), vec![house()]);
    }

    #[test]
    fn a_passage_into_a_courtyard_notches_the_building() {
        // A 4 m passage from the south into the middle (y 0..5): a U-shaped building of 180 m².
        let passage = geo::Rect::new(coord! { x: 8.0, y: -2.0 }, coord! { x: 12.0, y: 5.0 });
        let pieces = cut_passages(vec![house()], &[passage.to_polygon()]);
        assert_eq!(pieces.len(), 1);
        assert!((pieces[0].unsigned_area() - 180.0).abs() < 1e-9);
    }
}
