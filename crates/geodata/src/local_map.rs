//! A map in local metres: the input of the rasteriser.

use geo::{Polygon, Rect};

use crate::error::MapError;
use crate::geojson_input::{CoordinateKind, parse_geojson};

/// Building and road-surface polygons in the map's local metric frame (x east, y north, metres),
/// with the extent over which the map is known.
///
/// Road surface is already final: centrelines buffered to their width, `area:highway` polygons
/// and parking areas. Polygons may overlap; the rasteriser decides a cell by its centre with
/// buildings winning over roads (SPEC §4).
#[derive(Clone, Debug, PartialEq)]
pub struct LocalMap {
    /// Building footprints, local metres.
    pub buildings: Vec<Polygon<f64>>,
    /// Road-surface polygons, local metres.
    pub roads: Vec<Polygon<f64>>,
    /// Where the map is known, local metres. Outside it every cell is
    /// [`MapContext::Unknown`](crate::MapContext::Unknown).
    pub extent: Rect<f64>,
}

impl LocalMap {
    /// A map from polygons already in local metres.
    ///
    /// ```
    /// use geo::{coord, polygon, Rect};
    /// let house = polygon![(x: 0.0, y: 0.0), (x: 10.0, y: 0.0), (x: 10.0, y: 8.0), (x: 0.0, y: 8.0)];
    /// let extent = Rect::new(coord! { x: -50.0, y: -50.0 }, coord! { x: 50.0, y: 50.0 });
    /// let map = geodata::LocalMap::new(vec![house], vec![], extent);
    /// assert_eq!(map.buildings.len(), 1);
    /// ```
    pub fn new(buildings: Vec<Polygon<f64>>, roads: Vec<Polygon<f64>>, extent: Rect<f64>) -> Self {
        Self {
            buildings,
            roads,
            extent,
        }
    }

    /// A map from a GeoJSON FeatureCollection whose coordinates are local metres `[east, north]`
    /// (handy for synthetic scenes and tests).
    ///
    /// Features are read with the OSM tag rules (see [`crate::tags`]): Polygon/MultiPolygon with
    /// `building` → building; with `area:highway`, a vehicle `highway` or `amenity=parking` → road
    /// surface; LineString/MultiLineString with a vehicle `highway` → centreline buffered to its
    /// `width`, `lanes` × 3.25 m or class default. The extent is the collection's `bbox`
    /// (`[min_x, min_y, max_x, max_y]`) if present, else the bounding box of all coordinates.
    ///
    /// # Errors
    /// Invalid JSON or GeoJSON, an unknown geometry type, a non-finite coordinate, or
    /// [`MapError::Empty`] when there is no coordinate and no `bbox`.
    ///
    /// ```
    /// let text = r#"{"type": "FeatureCollection", "bbox": [0, 0, 100, 100], "features": [
    ///   {"type": "Feature", "properties": {"highway": "residential", "width": "6"},
    ///    "geometry": {"type": "LineString", "coordinates": [[0, 50], [100, 50]]}}]}"#;
    /// let map = geodata::LocalMap::from_local_geojson(text)?;
    /// assert_eq!(map.roads.len(), 1); // one capsule per centreline segment
    /// assert_eq!(map.extent.width(), 100.0);
    /// # Ok::<(), geodata::MapError>(())
    /// ```
    pub fn from_local_geojson(text: &str) -> Result<Self, MapError> {
        let features = parse_geojson(text.as_bytes(), CoordinateKind::LocalMetres)?;
        let extent = features.extent().ok_or(MapError::Empty)?;
        let (buildings, roads, _) = features.to_local_polygons(|c| c);
        Ok(Self::new(buildings, roads, extent))
    }
}
