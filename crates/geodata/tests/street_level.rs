//! What a street-level scanner meets: roads and buildings below the street are not in the map, a
//! road through a building at street level is (tunnel, layer, location, covered; issue 30).

use geodata::{LoadOptions, LoadedMap, MapContext, MapError, load_map_from_bytes};

/// A hand-built town at 60° N (0.001° is 111 m north, 55.7 m east), without declared bounds:
/// - a street (1–2) running east into a tunnel (2–3, `tunnel=yes`, `layer=-1`) that ends the
///   map's features in the east;
/// - a road at `layer=-1` without a tunnel tag (4–5);
/// - a 22 m × 56 m building (10, 16, 11, 12, 17, 13) with a building passage through its middle
///   (16–17), fed by a street from the south (18–16);
/// - an underground station (`building=train_station`, `layer=-1`, 20–23) with a street over it
///   (30–31).
const TOWN: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6">
  <node id="1" lat="60.0000" lon="24.0000"/>
  <node id="2" lat="60.0000" lon="24.0020"/>
  <node id="3" lat="60.0000" lon="24.0040"/>
  <node id="4" lat="60.0010" lon="24.0000"/>
  <node id="5" lat="60.0010" lon="24.0020"/>
  <node id="10" lat="60.0020" lon="24.0005"/>
  <node id="16" lat="60.0020" lon="24.0010"/>
  <node id="11" lat="60.0020" lon="24.0015"/>
  <node id="12" lat="60.0022" lon="24.0015"/>
  <node id="17" lat="60.0022" lon="24.0010"/>
  <node id="13" lat="60.0022" lon="24.0005"/>
  <node id="18" lat="60.0015" lon="24.0010"/>
  <node id="20" lat="60.0030" lon="24.0000"/>
  <node id="21" lat="60.0030" lon="24.0010"/>
  <node id="22" lat="60.0032" lon="24.0010"/>
  <node id="23" lat="60.0032" lon="24.0000"/>
  <node id="30" lat="60.0031" lon="24.0000"/>
  <node id="31" lat="60.0031" lon="24.0010"/>
  <way id="100"><nd ref="1"/><nd ref="2"/><tag k="highway" v="residential"/></way>
  <way id="101"><nd ref="2"/><nd ref="3"/><tag k="highway" v="residential"/>
    <tag k="tunnel" v="yes"/><tag k="layer" v="-1"/></way>
  <way id="102"><nd ref="4"/><nd ref="5"/><tag k="highway" v="residential"/><tag k="layer" v="-1"/></way>
  <way id="103"><nd ref="10"/><nd ref="16"/><nd ref="11"/><nd ref="12"/><nd ref="17"/><nd ref="13"/>
    <nd ref="10"/><tag k="building" v="yes"/></way>
  <way id="104"><nd ref="16"/><nd ref="17"/><tag k="highway" v="service"/>
    <tag k="tunnel" v="building_passage"/></way>
  <way id="105"><nd ref="18"/><nd ref="16"/><tag k="highway" v="service"/></way>
  <way id="106"><nd ref="20"/><nd ref="21"/><nd ref="22"/><nd ref="23"/><nd ref="20"/>
    <tag k="building" v="train_station"/><tag k="layer" v="-1"/></way>
  <way id="107"><nd ref="30"/><nd ref="31"/><tag k="highway" v="residential"/></way>
</osm>"#;

fn town() -> Result<LoadedMap, MapError> {
    load_map_from_bytes(TOWN.as_bytes(), &LoadOptions::default())
}

/// The map context at `(lat, lon)`.
fn context(map: &LoadedMap, lat: f64, lon: f64) -> MapContext {
    let (x, y) = map.projection.forward(lat, lon);
    geodata::ContextRaster::new(&map.map).context_at(x, y)
}

#[test]
fn what_is_below_the_street_is_counted_and_left_out() -> Result<(), MapError> {
    let town = town()?;
    let s = town.stats.source;
    assert_eq!(s.vehicle_road_ways, 6);
    assert_eq!(
        s.underground_road_ways, 2,
        "the tunnel and the layer -1 road"
    );
    assert_eq!(s.vehicle_road_ways_used, 4);
    assert_eq!(s.covered_road_ways, 1, "the building passage");
    assert_eq!((s.building_ways, s.underground_buildings), (2, 1));
    // The station is left out; the passage cuts the other building in two.
    assert_eq!(town.stats.buildings, 2);
    Ok(())
}

#[test]
fn a_tunnel_is_not_road_surface() -> Result<(), MapError> {
    let town = town()?;
    assert_eq!(context(&town, 60.0, 24.0010), MapContext::Road);
    assert_eq!(context(&town, 60.0, 24.0030), MapContext::Other);
    Ok(())
}

#[test]
fn a_road_at_layer_minus_one_is_not_road_surface() -> Result<(), MapError> {
    assert_eq!(context(&town()?, 60.0010, 24.0010), MapContext::Other);
    Ok(())
}

#[test]
fn a_building_passage_is_road_through_the_building() -> Result<(), MapError> {
    let town = town()?;
    // The passage's middle, 11 m inside the building: road (a building won there before).
    assert_eq!(context(&town, 60.0021, 24.0010), MapContext::Road);
    // 17 m either side of it (the service road is 3.5 m wide): the building.
    assert_eq!(context(&town, 60.0021, 24.0007), MapContext::Building);
    assert_eq!(context(&town, 60.0021, 24.0013), MapContext::Building);
    Ok(())
}

#[test]
fn an_underground_building_is_not_a_building() -> Result<(), MapError> {
    let town = town()?;
    // On the street over the station: road; 5.5 m south of it, over the station: other.
    assert_eq!(context(&town, 60.0031, 24.0005), MapContext::Road);
    assert_eq!(context(&town, 60.00305, 24.0005), MapContext::Other);
    Ok(())
}

#[test]
fn leaving_the_tunnel_out_does_not_move_the_extent() -> Result<(), MapError> {
    // The tunnel's east end (24.004°) bounds the features: the local frame stays where it was.
    let extent = town()?.stats.extent_wgs84;
    assert!((extent.max_lon - 24.004).abs() < 1e-9, "{extent:?}");
    Ok(())
}

#[test]
fn geojson_features_follow_the_same_rules() -> Result<(), MapError> {
    let text = r#"{"type": "FeatureCollection", "bbox": [0, 0, 100, 100], "features": [
      {"type": "Feature", "properties": {"highway": "residential", "tunnel": "yes"},
       "geometry": {"type": "LineString", "coordinates": [[0, 50], [100, 50]]}},
      {"type": "Feature", "properties": {"building": "yes", "location": "underground"},
       "geometry": {"type": "Polygon", "coordinates": [[[10, 10], [20, 10], [20, 20], [10, 10]]]}},
      {"type": "Feature", "properties": {"highway": "service", "covered": "yes"},
       "geometry": {"type": "LineString", "coordinates": [[50, 0], [50, 100]]}}]}"#;
    let map = geodata::LocalMap::from_local_geojson(text)?;
    assert!(map.buildings.is_empty());
    let raster = geodata::ContextRaster::new(&map);
    assert_eq!(raster.context_at(25.0, 50.0), MapContext::Other);
    assert_eq!(raster.context_at(50.0, 25.0), MapContext::Road);
    Ok(())
}
