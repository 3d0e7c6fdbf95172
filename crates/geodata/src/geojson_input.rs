//! Reading a GeoJSON FeatureCollection with OSM-style properties.
//!
//! Properties are read with the same tag rules as OSM elements ([`crate::tags`]): `building`,
//! `highway`, `area:highway`, `area`, `amenity`, `parking`, `width`, `lanes`. Polygons and
//! MultiPolygons are areas (a polygon with a vehicle `highway` is a road surface, as an OSM way
//! with `area=yes`); LineStrings and MultiLineStrings with a vehicle `highway` are centrelines.

use geo::{Coord, LineString, Rect};
use serde_json::Value;

use crate::error::MapError;
use crate::features::{MapFeatures, RoadArea, RoadCentreline, SkipReason};
use crate::rings::clean_ring;
use crate::tags::{Level, Roles};

/// What the coordinates of a GeoJSON file mean.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CoordinateKind {
    /// `[longitude, latitude]` in degrees, checked against WGS84 ranges (RFC 7946).
    Wgs84,
    /// `[east, north]` in metres of a local frame, checked only for finiteness.
    LocalMetres,
}

/// Parses GeoJSON text into map features.
///
/// # Errors
/// [`MapError::Json`] for invalid JSON, [`MapError::GeoJson`] for JSON that is not a Feature or
/// FeatureCollection, [`MapError::UnknownGeometryType`] for a geometry type GeoJSON does not
/// define, [`MapError::CoordinateOutOfRange`] / [`MapError::NonFiniteCoordinate`] for bad
/// positions.
pub(crate) fn parse_geojson(bytes: &[u8], kind: CoordinateKind) -> Result<MapFeatures, MapError> {
    let root: Value = serde_json::from_slice(bytes).map_err(|e| MapError::Json {
        line: e.line(),
        column: e.column(),
        message: e.to_string(),
    })?;
    let mut features = MapFeatures::default();
    let single;
    let list: &[Value] = match root.get("type").and_then(Value::as_str) {
        Some("FeatureCollection") => root
            .get("features")
            .and_then(Value::as_array)
            .ok_or_else(|| geojson_error("FeatureCollection without a \"features\" array"))?,
        Some("Feature") => {
            single = [root.clone()];
            &single
        }
        Some(other) => {
            return Err(geojson_error(format!(
                "top-level type {other:?}; expected \"FeatureCollection\" or \"Feature\""
            )));
        }
        None => return Err(geojson_error("top-level object has no \"type\"")),
    };
    if let Some(bbox) = root.get("bbox") {
        features.declared_bounds = Some(parse_bbox(bbox, kind)?);
    }
    for (index, feature) in list.iter().enumerate() {
        read_feature(index, feature, kind, &mut features)?;
    }
    Ok(features)
}

fn geojson_error(message: impl Into<String>) -> MapError {
    MapError::GeoJson {
        message: message.into(),
    }
}

fn parse_bbox(bbox: &Value, kind: CoordinateKind) -> Result<Rect<f64>, MapError> {
    let numbers: Option<Vec<f64>> = bbox
        .as_array()
        .map(|values| values.iter().map(Value::as_f64).collect())
        .unwrap_or(None);
    match numbers.as_deref() {
        Some(&[x1, y1, x2, y2]) => {
            let a = checked_coord(x1, y1, kind, "bbox")?;
            let b = checked_coord(x2, y2, kind, "bbox")?;
            Ok(Rect::new(a, b))
        }
        _ => Err(geojson_error("\"bbox\" must be an array of 4 numbers")),
    }
}

fn checked_coord(
    x: f64,
    y: f64,
    kind: CoordinateKind,
    element: &str,
) -> Result<Coord<f64>, MapError> {
    match kind {
        CoordinateKind::Wgs84 => {
            if !(x.is_finite()
                && y.is_finite()
                && (-180.0..=180.0).contains(&x)
                && (-90.0..=90.0).contains(&y))
            {
                return Err(MapError::CoordinateOutOfRange {
                    element: element.to_owned(),
                    lat: y,
                    lon: x,
                });
            }
        }
        CoordinateKind::LocalMetres => {
            if !(x.is_finite() && y.is_finite()) {
                return Err(MapError::NonFiniteCoordinate {
                    element: element.to_owned(),
                    x,
                    y,
                });
            }
        }
    }
    Ok(Coord { x, y })
}

/// Properties as string tags; numbers and booleans are turned into their JSON text so that
/// `"width": 7` reads like `width=7`.
fn property_tags(feature: &Value) -> Vec<(String, String)> {
    let Some(properties) = feature.get("properties").and_then(Value::as_object) else {
        return Vec::new();
    };
    properties
        .iter()
        .filter_map(|(key, value)| {
            let text = match value {
                Value::String(s) => s.clone(),
                Value::Number(n) => n.to_string(),
                Value::Bool(b) => if *b { "yes" } else { "no" }.to_owned(),
                _ => return None,
            };
            Some((key.clone(), text))
        })
        .collect()
}

/// The geometry of one feature, parsed into rings and lines.
enum Shape {
    Areas(Vec<Vec<Vec<Coord<f64>>>>),
    Lines(Vec<Vec<Coord<f64>>>),
    Other,
}

fn read_feature(
    index: usize,
    feature: &Value,
    kind: CoordinateKind,
    features: &mut MapFeatures,
) -> Result<(), MapError> {
    if feature.get("type").and_then(Value::as_str) != Some("Feature") {
        return Err(geojson_error(format!(
            "feature {index} is not of type \"Feature\""
        )));
    }
    let tags = property_tags(feature);
    let roles =
        Roles::from_tags(|key| tags.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str()));
    let element = format!("feature {index}");
    let shape = match feature.get("geometry") {
        None | Some(Value::Null) => Shape::Other,
        Some(geometry) => parse_geometry(index, geometry, kind, &element, features)?,
    };
    if roles.building {
        features.source_counts.building_ways += 1;
    }
    if roles.highway {
        features.source_counts.highway_ways += 1;
    }
    if roles.vehicle_road.is_some() {
        features.source_counts.vehicle_road_ways += 1;
    }
    let wants_area = roles.building || roles.is_road_surface_area() || roles.vehicle_road.is_some();
    if roles.is_underground() {
        let lines = match shape {
            Shape::Areas(polygons) => polygons.into_iter().flatten().collect(),
            Shape::Lines(lines) => lines,
            Shape::Other => Vec::new(),
        };
        features.set_aside_underground(&roles, lines.into_iter().map(LineString::new));
        return Ok(());
    }
    match shape {
        Shape::Areas(polygons) => {
            if !wants_area {
                return Ok(());
            }
            let mut used_as_building = false;
            for rings in polygons {
                let Some((outer, inner)) = rings.split_first() else {
                    continue;
                };
                let outer = match clean_ring(outer) {
                    Ok(ring) => ring,
                    Err(reason) => {
                        features.skip(reason);
                        continue;
                    }
                };
                let mut holes = Vec::new();
                for ring in inner {
                    match clean_ring(ring) {
                        Ok(ring) => holes.push(ring),
                        Err(reason) => features.skip(reason),
                    }
                }
                let polygon = geo::Polygon::new(outer, holes);
                if roles.building {
                    used_as_building = true;
                    features.buildings.push(polygon.clone());
                }
                if roles.parking {
                    features.parking.push(polygon.clone());
                }
                // A polygon tagged with a vehicle `highway` is a surface, like area=yes in OSM.
                if let Some(class) = roles.road_area.as_ref().or(roles.vehicle_road.as_ref()) {
                    features.road_areas.push(RoadArea {
                        polygon,
                        highway: class.clone(),
                    });
                }
            }
            features.source_counts.building_ways_used += usize::from(used_as_building);
        }
        Shape::Lines(lines) => match &roles.vehicle_road {
            Some(class) => {
                let mut used = false;
                for line in lines {
                    if line.len() < 2 {
                        features.skip(SkipReason::RoadWayTooShort);
                        continue;
                    }
                    features.roads.push(RoadCentreline {
                        line: LineString::new(line),
                        highway: class.clone(),
                        width_tag: roles.width.clone(),
                        lanes_tag: roles.lanes.clone(),
                        covered: roles.level == Level::Covered,
                    });
                    used = true;
                }
                features.source_counts.vehicle_road_ways_used += usize::from(used);
                features.source_counts.covered_road_ways +=
                    usize::from(used && roles.level == Level::Covered);
            }
            None if wants_area => features.skip(SkipReason::UnsupportedGeometry),
            None => {}
        },
        Shape::Other => {
            if wants_area {
                features.skip(SkipReason::UnsupportedGeometry);
            }
        }
    }
    Ok(())
}

fn parse_geometry(
    index: usize,
    geometry: &Value,
    kind: CoordinateKind,
    element: &str,
    features: &mut MapFeatures,
) -> Result<Shape, MapError> {
    let Some(geometry_type) = geometry.get("type").and_then(Value::as_str) else {
        return Err(geojson_error(format!(
            "feature {index}: geometry has no \"type\""
        )));
    };
    let coordinates = || {
        geometry.get("coordinates").ok_or_else(|| {
            geojson_error(format!(
                "feature {index}: {geometry_type} has no \"coordinates\""
            ))
        })
    };
    let shape = match geometry_type {
        "Polygon" => {
            let value = coordinates()?;
            Shape::Areas(vec![parse_rings(index, value, kind, element, features)?])
        }
        "MultiPolygon" => {
            let value = coordinates()?;
            let polygons = as_array(index, value)?
                .iter()
                .map(|rings| parse_rings(index, rings, kind, element, features))
                .collect::<Result<_, _>>()?;
            Shape::Areas(polygons)
        }
        "LineString" => {
            let value = coordinates()?;
            Shape::Lines(vec![parse_positions(
                index, value, kind, element, features,
            )?])
        }
        "MultiLineString" => {
            let value = coordinates()?;
            let lines = as_array(index, value)?
                .iter()
                .map(|line| parse_positions(index, line, kind, element, features))
                .collect::<Result<_, _>>()?;
            Shape::Lines(lines)
        }
        "Point" | "MultiPoint" | "GeometryCollection" => Shape::Other,
        other => {
            return Err(MapError::UnknownGeometryType {
                feature: index,
                geometry_type: other.to_owned(),
            });
        }
    };
    Ok(shape)
}

fn as_array(index: usize, value: &Value) -> Result<&Vec<Value>, MapError> {
    value
        .as_array()
        .ok_or_else(|| geojson_error(format!("feature {index}: coordinates must be arrays")))
}

fn parse_rings(
    index: usize,
    value: &Value,
    kind: CoordinateKind,
    element: &str,
    features: &mut MapFeatures,
) -> Result<Vec<Vec<Coord<f64>>>, MapError> {
    as_array(index, value)?
        .iter()
        .map(|ring| parse_positions(index, ring, kind, element, features))
        .collect()
}

fn parse_positions(
    index: usize,
    value: &Value,
    kind: CoordinateKind,
    element: &str,
    features: &mut MapFeatures,
) -> Result<Vec<Coord<f64>>, MapError> {
    as_array(index, value)?
        .iter()
        .map(|position| {
            let numbers = as_array(index, position)?;
            let (Some(x), Some(y)) = (
                numbers.first().and_then(Value::as_f64),
                numbers.get(1).and_then(Value::as_f64),
            ) else {
                return Err(geojson_error(format!(
                    "feature {index}: a position must hold at least two numbers"
                )));
            };
            let coord = checked_coord(x, y, kind, element)?;
            features.include_coordinate(coord.x, coord.y);
            Ok(coord)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_roles_and_geometries() -> Result<(), MapError> {
        let text = r#"{"type":"FeatureCollection","features":[
          {"type":"Feature","properties":{"building":"yes"},
           "geometry":{"type":"Polygon","coordinates":[[[0,0],[10,0],[10,10],[0,10],[0,0]],
                                                       [[2,2],[4,2],[4,4],[2,4],[2,2]]]}},
          {"type":"Feature","properties":{"highway":"residential","lanes":2},
           "geometry":{"type":"LineString","coordinates":[[0,20],[50,20]]}},
          {"type":"Feature","properties":{"highway":"footway"},
           "geometry":{"type":"LineString","coordinates":[[0,30],[50,30]]}},
          {"type":"Feature","properties":{"amenity":"parking"},
           "geometry":{"type":"MultiPolygon","coordinates":[[[[20,0],[30,0],[30,5],[20,0]]]]}},
          {"type":"Feature","properties":{"building":"yes"},
           "geometry":{"type":"Point","coordinates":[5,5]}}
        ]}"#;
        let features = parse_geojson(text.as_bytes(), CoordinateKind::LocalMetres)?;
        assert_eq!(features.buildings.len(), 1);
        assert_eq!(features.buildings[0].interiors().len(), 1);
        assert_eq!(features.roads.len(), 1);
        assert_eq!(features.roads[0].width_m(), 6.5, "2 lanes × 3.25 m");
        assert_eq!(features.parking.len(), 1);
        assert_eq!(
            features.skipped.get(&SkipReason::UnsupportedGeometry),
            Some(&1)
        );
        assert_eq!(features.source_counts.highway_ways, 2);
        assert_eq!(features.source_counts.building_ways, 2);
        Ok(())
    }

    #[test]
    fn rejects_unknown_geometry_and_bad_coordinates() {
        let unknown = r#"{"type":"FeatureCollection","features":[
          {"type":"Feature","properties":{},"geometry":{"type":"Circle","coordinates":[0,0]}}]}"#;
        assert!(matches!(
            parse_geojson(unknown.as_bytes(), CoordinateKind::Wgs84),
            Err(MapError::UnknownGeometryType { feature: 0, ref geometry_type }) if geometry_type == "Circle"
        ));
        let out_of_range = r#"{"type":"FeatureCollection","features":[
          {"type":"Feature","properties":{"building":"yes"},
           "geometry":{"type":"Polygon","coordinates":[[[0,0],[1,95],[1,0],[0,0]]]}}]}"#;
        assert!(matches!(
            parse_geojson(out_of_range.as_bytes(), CoordinateKind::Wgs84),
            Err(MapError::CoordinateOutOfRange { lat, .. }) if lat == 95.0
        ));
        assert!(matches!(
            parse_geojson(b"{\"type\": ", CoordinateKind::Wgs84),
            Err(MapError::Json { line: 1, .. })
        ));
        assert!(matches!(
            parse_geojson(br#"{"type":"Topology"}"#, CoordinateKind::Wgs84),
            Err(MapError::GeoJson { .. })
        ));
    }
}
