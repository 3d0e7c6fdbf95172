//! `evigrid map` from the outside: exit codes, stdout, files written.

use std::path::PathBuf;
use std::process::{Command, Output};

mod common;
use common::read_png;

/// The shared data directory (same rule as `geodata::testdata::shared_dir`): `$EVIGRID_SHARED`,
/// else `<workspace>/../shared`; skip when absent unless `EVIGRID_REQUIRE_SHARED=1`.
fn osm_file(name: &str) -> Option<PathBuf> {
    geodata::testdata::osm_file(name)
}

fn evigrid(args: &[&str]) -> std::io::Result<Output> {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .output()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn info_prints_extent_and_counts() -> Result<(), Box<dyn std::error::Error>> {
    let Some(path) = osm_file("helsinki-centre.osm.pbf") else {
        return Ok(());
    };
    let path = path.to_str().ok_or("path")?;
    let output = evigrid(&["map", "info", path])?;
    assert!(output.status.success(), "{}", text(&output.stderr));
    let stdout = text(&output.stdout);
    assert!(
        stdout.contains(
            "buildings: 454 (from 385 of 433 building ways and 61 of 67 building relations)"
        ),
        "{stdout}"
    );
    // The service tunnels under the centre are left out; 7 building passages cut 6 buildings
    // more out of the 448 footprints.
    assert!(
        stdout.contains(
            "below the street (left out): 53 vehicle-road ways, 0 buildings; under a roof at \
             street level: 7 vehicle-road ways"
        ),
        "{stdout}"
    );
    assert!(
        stdout.contains("1012.7 m east-west x 1666.6 m north-south"),
        "{stdout}"
    );
    assert!(
        stdout.contains("skipped: area_way_missing_nodes 54"),
        "{stdout}"
    );

    let output = evigrid(&["map", "info", path, "--json"])?;
    assert!(output.status.success());
    let json: serde_json::Value = serde_json::from_slice(&output.stdout)?;
    assert_eq!(json["source"]["building_ways"], 433);
    assert_eq!(json["source"]["highway_ways"], 2650);
    assert_eq!(json["source"]["underground_road_ways"], 53);
    assert_eq!(json["format"], "osm_pbf");
    assert!(
        json["skipped"]["relation_missing_members"]
            .as_u64()
            .is_some()
    );
    Ok(())
}

#[test]
fn render_writes_a_png_with_the_map_size() -> Result<(), Box<dyn std::error::Error>> {
    let Some(path) = osm_file("bavarian-village.osm") else {
        return Ok(());
    };
    let dir = tempfile::tempdir()?;
    let out = dir.path().join("village.png");
    let output = evigrid(&[
        "map",
        "render",
        path.to_str().ok_or("path")?,
        "--cell",
        "0.5",
        "--out",
        out.to_str().ok_or("out")?,
        "--json",
    ])?;
    assert!(output.status.success(), "{}", text(&output.stderr));
    assert!(
        text(&output.stderr).contains("scale bar bottom left: 20 m in alternating 10 m blocks"),
        "{}",
        text(&output.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout)?;
    // 223 m × 222 m at 0.5 m → 448 × 446 cells (see the geodata snapshot).
    assert_eq!(
        (summary["width_px"].as_u64(), summary["height_px"].as_u64()),
        (Some(448), Some(446))
    );
    let (width, height, colour, _) = read_png(&out);
    assert_eq!((width, height, colour), (448, 446, png::ColorType::Rgb));
    // Only the final file remains: the temporary one was renamed.
    assert_eq!(std::fs::read_dir(dir.path())?.count(), 1);
    Ok(())
}

#[test]
fn crop_writes_geojson_that_reads_back() -> Result<(), Box<dyn std::error::Error>> {
    let Some(path) = osm_file("kouvola.osm.pbf") else {
        return Ok(());
    };
    let dir = tempfile::tempdir()?;
    let out = dir.path().join("crop.geojson");
    let out_str = out.to_str().ok_or("out")?;
    let output = evigrid(&[
        "map",
        "crop",
        path.to_str().ok_or("path")?,
        "--bbox",
        "60.528,26.945,60.532,26.955",
        "--out",
        out_str,
        "--json",
    ])?;
    assert!(output.status.success(), "{}", text(&output.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout)?;
    assert!(
        summary["buildings"].as_u64().is_some_and(|n| n > 5),
        "{summary}"
    );
    let output = evigrid(&["map", "info", out_str, "--json"])?;
    assert!(output.status.success(), "{}", text(&output.stderr));
    let info: serde_json::Value = serde_json::from_slice(&output.stdout)?;
    assert_eq!(info["format"], "geo_json");
    assert_eq!(info["buildings"], summary["buildings"]);
    assert_eq!(info["extent_wgs84"]["min_lat"], 60.528);
    Ok(())
}

#[test]
fn bad_input_exits_2_with_one_line_naming_the_file() -> Result<(), Box<dyn std::error::Error>> {
    let dir = tempfile::tempdir()?;
    let cases: [(&str, &[u8], &str); 4] = [
        ("bad.osm", b"<osm><node id='1' lat='1' lon='1'></way></osm>", "invalid OSM XML"),
        ("bad.geojson", br#"{"type":"FeatureCollection","features":[{"type":"Feature","properties":{},"geometry":{"type":"Blob","coordinates":[]}}]}"#, "unknown geometry type"),
        ("far.osm", b"<osm><node id='1' lat='100' lon='1'/></osm>", "out of WGS84 range"),
        ("mystery.bin", b"\x00\x01\x02\x03garbage", "unknown map format"),
    ];
    for (name, content, expected) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, content)?;
        let output = evigrid(&["map", "info", path.to_str().ok_or("path")?])?;
        let stderr = text(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{name}: {stderr}");
        assert!(
            stderr.contains(name) && stderr.contains(expected),
            "{name}: {stderr}"
        );
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    }
    let missing = dir.path().join("missing.osm.pbf");
    let output = evigrid(&["map", "info", missing.to_str().ok_or("path")?])?;
    assert_eq!(output.status.code(), Some(2));
    assert!(text(&output.stderr).contains("missing.osm.pbf"));
    if let Some(path) = osm_file("helsinki-centre.osm.pbf") {
        let bytes = std::fs::read(path)?;
        let cut = dir.path().join("cut.osm.pbf");
        std::fs::write(&cut, &bytes[..bytes.len() / 3])?;
        let output = evigrid(&["map", "info", cut.to_str().ok_or("path")?])?;
        assert_eq!(output.status.code(), Some(2));
        assert!(
            text(&output.stderr).contains("cut.osm.pbf: invalid OSM PBF"),
            "{}",
            text(&output.stderr)
        );
    }
    let output = evigrid(&[
        "map",
        "crop",
        "x.osm",
        "--bbox",
        "1,2,3",
        "--out",
        "y.geojson",
    ])?;
    assert_eq!(output.status.code(), Some(2));
    assert!(text(&output.stderr).contains("--bbox"));
    Ok(())
}

#[test]
fn an_unwritable_out_is_bad_input_and_leaves_no_temporary() -> Result<(), Box<dyn std::error::Error>>
{
    let Some(path) = osm_file("bavarian-village.osm") else {
        return Ok(());
    };
    // `--out` names an existing directory: the temporary is written, the rename fails.
    let dir = tempfile::tempdir()?;
    let taken = dir.path().join("taken.png");
    std::fs::create_dir(&taken)?;
    std::fs::write(taken.join("inside"), b"x")?;
    let output = evigrid(&[
        "map",
        "render",
        path.to_str().ok_or("path")?,
        "--out",
        taken.to_str().ok_or("out")?,
    ])?;
    assert_eq!(output.status.code(), Some(2), "{}", text(&output.stderr));
    assert!(
        text(&output.stderr).contains("--out"),
        "{}",
        text(&output.stderr)
    );
    let names: Vec<_> = std::fs::read_dir(dir.path())?.collect::<Result<_, _>>()?;
    assert_eq!(names.len(), 1, "{names:?}");
    Ok(())
}
