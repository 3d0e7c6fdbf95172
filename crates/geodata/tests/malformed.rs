//! Malformed input is rejected with a clear error naming the file and the problem.

use geodata::testdata::osm_file;
use geodata::{LoadOptions, MapError, load_map, load_map_from_bytes};

fn write_temp(
    bytes: &[u8],
    name: &str,
) -> std::io::Result<(tempfile::TempDir, std::path::PathBuf)> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join(name);
    std::fs::write(&path, bytes)?;
    Ok((dir, path))
}

#[test]
fn truncated_pbf_is_an_error_naming_the_file() -> Result<(), Box<dyn std::error::Error>> {
    let Some(source) = osm_file("helsinki-centre.osm.pbf") else {
        return Ok(());
    };
    let bytes = std::fs::read(source)?;
    let (_dir, path) = write_temp(&bytes[..bytes.len() / 2], "cut.osm.pbf")?;
    let error = load_map(&path, &LoadOptions::default())
        .err()
        .ok_or("accepted a truncated PBF")?;
    let message = error.to_string();
    assert!(
        message.contains("cut.osm.pbf") && message.contains("invalid OSM PBF"),
        "{message}"
    );
    Ok(())
}

#[test]
fn invalid_xml_is_an_error() -> Result<(), Box<dyn std::error::Error>> {
    let Some(source) = osm_file("bavarian-village.osm") else {
        return Ok(());
    };
    let bytes = std::fs::read(source)?;
    let (_dir, path) = write_temp(&bytes[..bytes.len() * 2 / 3], "cut.osm")?;
    let message = load_map(&path, &LoadOptions::default())
        .err()
        .ok_or("accepted truncated XML")?
        .to_string();
    assert!(
        message.contains("cut.osm") && message.contains("invalid OSM XML"),
        "{message}"
    );
    let broken = b"<osm><node id='1' lat='1' lon='1'></way></osm>";
    assert!(matches!(
        load_map_from_bytes(broken, &LoadOptions::default()),
        Err(MapError::Xml { .. })
    ));
    Ok(())
}

#[test]
fn truncated_gzip_is_an_error() -> Result<(), Box<dyn std::error::Error>> {
    let Some(source) = osm_file("monaco.osm.gz") else {
        return Ok(());
    };
    let bytes = std::fs::read(source)?;
    let result = load_map_from_bytes(&bytes[..bytes.len() / 2], &LoadOptions::default());
    assert!(matches!(result, Err(MapError::Gzip { .. })), "{result:?}");
    Ok(())
}

#[test]
fn unknown_geojson_geometry_is_an_error() {
    let text = br#"{"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"building": "yes"},
         "geometry": {"type": "Triangle", "coordinates": [[0, 0], [1, 0], [0, 1]]}}]}"#;
    let result = load_map_from_bytes(text, &LoadOptions::default());
    let message = result
        .as_ref()
        .map(|_| String::new())
        .unwrap_or_else(|e| e.to_string());
    assert!(
        message.contains("unknown geometry type \"Triangle\"") && message.contains("feature 0"),
        "{message}"
    );
}

#[test]
fn out_of_range_coordinates_are_errors() {
    let xml = br#"<osm><node id="7" lat="60.1" lon="190.5"/></osm>"#;
    let result = load_map_from_bytes(xml, &LoadOptions::default());
    assert!(
        matches!(&result, Err(MapError::CoordinateOutOfRange { element, lon, .. }) if element == "node 7" && *lon == 190.5),
        "{result:?}"
    );
    let json = br#"{"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"highway": "primary"},
         "geometry": {"type": "LineString", "coordinates": [[24.9, 60.1], [24.9, -91]]}}]}"#;
    assert!(matches!(
        load_map_from_bytes(json, &LoadOptions::default()),
        Err(MapError::CoordinateOutOfRange { .. })
    ));
}

#[test]
fn unknown_format_missing_file_and_empty_map() -> Result<(), Box<dyn std::error::Error>> {
    assert!(matches!(
        load_map_from_bytes(b"PK\x03\x04 zip", &LoadOptions::default()),
        Err(MapError::UnknownFormat { .. })
    ));
    let dir = tempfile::tempdir()?;
    let missing = dir.path().join("nowhere.osm");
    let message = load_map(&missing, &LoadOptions::default())
        .err()
        .ok_or("read a missing file")?
        .to_string();
    assert!(
        message.contains("nowhere.osm") && message.contains("cannot read"),
        "{message}"
    );
    assert!(matches!(
        load_map_from_bytes(b"<osm></osm>", &LoadOptions::default()),
        Err(MapError::Empty)
    ));
    assert!(matches!(
        load_map_from_bytes(
            b"<osm><node id='1' lat='1' lon='1'/></osm>",
            &LoadOptions {
                origin: Some((95.0, 0.0))
            }
        ),
        Err(MapError::InvalidOrigin { .. })
    ));
    Ok(())
}
