//! Cutting a small self-contained map out of a large one, and writing it as GeoJSON.

use geo::{BoundingRect, Coord, Intersects, LineString, Polygon, Rect};
use serde_json::{Value, json};

use crate::features::{MapFeatures, RoadCentreline};
use crate::load::GeoBox;

/// Widest road half-width a centreline can have (the largest `width` accepted is 60 m), metres:
/// a centreline this far outside the crop box can still cover cells inside it.
const SELECTION_MARGIN_M: f64 = 30.0;

/// Metres per degree of latitude (mean), for the selection margin only.
const METRES_PER_DEGREE: f64 = 111_320.0;

impl MapFeatures {
    /// The features of a WGS84 map (x = lon, y = lat) that matter inside `bbox` (corners in any
    /// order).
    ///
    /// Polygons (buildings, road areas, parking) whose bounding box meets `bbox` are kept whole;
    /// centrelines are cut to the runs of segments that come within the widest road half-width
    /// (30 m) of `bbox`, so that every cell centre inside `bbox` gets the same context from the
    /// crop as from the whole map. The crop's declared bounds are `bbox` clipped to this map's
    /// extent. Source and skip counts are not carried over.
    pub fn crop(&self, bbox: &GeoBox) -> MapFeatures {
        let bbox = Rect::new(
            Coord {
                x: bbox.min_lon,
                y: bbox.min_lat,
            },
            Coord {
                x: bbox.max_lon,
                y: bbox.max_lat,
            },
        );
        let mid_lat = (bbox.min().y + bbox.max().y) / 2.0;
        let margin_lat = SELECTION_MARGIN_M / METRES_PER_DEGREE;
        let margin_lon = margin_lat / mid_lat.to_radians().cos().max(0.01);
        let selection = Rect::new(
            Coord {
                x: bbox.min().x - margin_lon,
                y: bbox.min().y - margin_lat,
            },
            Coord {
                x: bbox.max().x + margin_lon,
                y: bbox.max().y + margin_lat,
            },
        );
        let keep = |p: &Polygon<f64>| p.bounding_rect().is_some_and(|r| r.intersects(&bbox));
        let mut crop = MapFeatures {
            buildings: self.buildings.iter().filter(|p| keep(p)).cloned().collect(),
            road_areas: self
                .road_areas
                .iter()
                .filter(|a| keep(&a.polygon))
                .cloned()
                .collect(),
            parking: self.parking.iter().filter(|p| keep(p)).cloned().collect(),
            declared_bounds: Some(match self.extent() {
                Some(extent) => intersection(&bbox, &extent).unwrap_or(bbox),
                None => bbox,
            }),
            ..MapFeatures::default()
        };
        for road in &self.roads {
            for run in segment_runs(&road.line, &selection) {
                crop.roads.push(RoadCentreline {
                    line: run,
                    ..road.clone()
                });
            }
        }
        crop
    }

    /// The features as a GeoJSON FeatureCollection with OSM-style properties, which
    /// [`load_map_from_bytes`](crate::load_map_from_bytes) reads back to the same map: buildings
    /// as polygons with `building=yes`, road areas with `area:highway=<class>`, parking with
    /// `amenity=parking`, centrelines as LineStrings with `highway` and the original `width` and
    /// `lanes` tags (and `covered=yes` for a road at street level under a roof). Nothing below
    /// the street is written. The collection's `bbox` is the map's extent.
    pub fn to_geojson(&self) -> Value {
        let mut features = Vec::new();
        for polygon in &self.buildings {
            features.push(feature(
                json!({"building": "yes"}),
                polygon_geometry(polygon),
            ));
        }
        for area in &self.road_areas {
            features.push(feature(
                json!({"area:highway": area.highway}),
                polygon_geometry(&area.polygon),
            ));
        }
        for polygon in &self.parking {
            features.push(feature(
                json!({"amenity": "parking"}),
                polygon_geometry(polygon),
            ));
        }
        for road in &self.roads {
            let mut properties = json!({"highway": road.highway});
            if let Some(width) = &road.width_tag {
                properties["width"] = json!(width);
            }
            if let Some(lanes) = &road.lanes_tag {
                properties["lanes"] = json!(lanes);
            }
            if road.covered {
                properties["covered"] = json!("yes");
            }
            let geometry = json!({"type": "LineString", "coordinates": positions(&road.line)});
            features.push(feature(properties, geometry));
        }
        let mut collection = json!({"type": "FeatureCollection", "features": features});
        if let Some(extent) = self.extent() {
            collection["bbox"] = json!([
                extent.min().x,
                extent.min().y,
                extent.max().x,
                extent.max().y
            ]);
        }
        collection
    }
}

fn feature(properties: Value, geometry: Value) -> Value {
    json!({"type": "Feature", "properties": properties, "geometry": geometry})
}

fn positions(line: &LineString<f64>) -> Vec<[f64; 2]> {
    line.0.iter().map(|c| [c.x, c.y]).collect()
}

fn polygon_geometry(polygon: &Polygon<f64>) -> Value {
    let rings: Vec<Vec<[f64; 2]>> = std::iter::once(polygon.exterior())
        .chain(polygon.interiors())
        .map(positions)
        .collect();
    json!({"type": "Polygon", "coordinates": rings})
}

fn intersection(a: &Rect<f64>, b: &Rect<f64>) -> Option<Rect<f64>> {
    let min = Coord {
        x: a.min().x.max(b.min().x),
        y: a.min().y.max(b.min().y),
    };
    let max = Coord {
        x: a.max().x.min(b.max().x),
        y: a.max().y.min(b.max().y),
    };
    (min.x <= max.x && min.y <= max.y).then(|| Rect::new(min, max))
}

/// The maximal runs of consecutive segments of `line` whose bounding boxes meet `selection`.
fn segment_runs(line: &LineString<f64>, selection: &Rect<f64>) -> Vec<LineString<f64>> {
    let mut runs = Vec::new();
    let mut current: Vec<Coord<f64>> = Vec::new();
    for segment in line.lines() {
        let segment_box = Rect::new(segment.start, segment.end);
        if segment_box.intersects(selection) {
            if current.is_empty() {
                current.push(segment.start);
            }
            current.push(segment.end);
        } else if !current.is_empty() {
            runs.push(LineString::new(std::mem::take(&mut current)));
        }
    }
    if !current.is_empty() {
        runs.push(LineString::new(current));
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centrelines_are_cut_to_the_runs_near_the_box() {
        // Degrees; the margin is 30 m ≈ 0.00027° of latitude.
        let line = LineString::from(vec![
            (0.0, 0.0),
            (0.0, 0.001),
            (0.0, 0.01),
            (0.0, 0.02),
            (0.0, 0.021),
        ]);
        let bbox = Rect::new(
            Coord {
                x: -0.001,
                y: -0.0005,
            },
            Coord {
                x: 0.001,
                y: 0.0005,
            },
        );
        let runs = segment_runs(&line, &bbox);
        assert_eq!(runs, vec![LineString::from(vec![(0.0, 0.0), (0.0, 0.001)])]);
    }
}
