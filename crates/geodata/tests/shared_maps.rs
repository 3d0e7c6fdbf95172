//! Integration tests on the real OSM extracts in `../shared/data/osm` (skipped with a note when
//! the shared directory is absent, failing when `EVIGRID_REQUIRE_SHARED=1`).

use geodata::testdata::osm_file;
use geodata::{
    ContextRaster, GeoBox, LoadOptions, MapContext, MapError, load_map, load_map_from_bytes,
};

/// Reference counts per file: OSM ways with `building=*` (not `no`), building multipolygon
/// relations, ways with `highway=*`. From the table in `shared/README.md` (counted with
/// pyosmium); the XML files were recounted with `tests/count_osm.py` (stdlib xml.etree), which
/// agrees, and which also gives the relation counts for them.
const REFERENCE: [(&str, usize, usize, usize); 4] = [
    ("helsinki-centre.osm.pbf", 433, 67, 2650),
    ("kouvola.osm.pbf", 2219, 0, 343),
    ("monaco.osm.gz", 962, 4, 866),
    ("bavarian-village.osm", 33, 0, 19),
];

#[test]
fn tagged_element_counts_match_the_reference() -> Result<(), MapError> {
    for (name, building_ways, building_relations, highway_ways) in REFERENCE {
        let Some(path) = osm_file(name) else {
            return Ok(());
        };
        let stats = load_map(&path, &LoadOptions::default())?.stats;
        let s = stats.source;
        assert_eq!(s.building_ways, building_ways, "{name}: building ways");
        assert_eq!(
            s.building_relations, building_relations,
            "{name}: building relations"
        );
        assert_eq!(s.highway_ways, highway_ways, "{name}: highway ways");
        // What was not used must be explained by skip counts: every building way not used is an
        // area way that is cut, unclosed or has a broken ring, or lies below the street.
        let area_skips: usize = stats
            .skipped
            .iter()
            .filter(|(reason, _)| {
                use geodata::SkipReason::*;
                matches!(
                    reason,
                    AreaWayMissingNodes | UnclosedAreaWay | DegenerateRing | SelfIntersectingRing
                )
            })
            .map(|(_, n)| n)
            .sum();
        assert!(
            s.building_ways - s.building_ways_used <= area_skips + s.underground_buildings,
            "{name}: {stats:?}"
        );
        let missing_relations = stats
            .skipped
            .get(&geodata::SkipReason::RelationMissingMembers)
            .copied()
            .unwrap_or(0);
        assert!(
            s.building_relations - s.building_relations_used
                <= missing_relations + stats.skipped.len(),
            "{name}"
        );
        // One polygon per used way, at least one per used relation.
        assert!(
            stats.buildings >= s.building_ways_used + s.building_relations_used,
            "{name}"
        );
        assert!(stats.road_pieces >= stats.road_centrelines, "{name}");
    }
    Ok(())
}

/// Runs `tests/count_osm.py` on the XML files and checks the reader's usable counts against it
/// (skipped when python3 is not installed).
#[test]
fn usable_counts_match_an_independent_python_count() -> Result<(), Box<dyn std::error::Error>> {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/count_osm.py");
    for name in ["bavarian-village.osm", "monaco.osm.gz"] {
        let Some(path) = osm_file(name) else {
            return Ok(());
        };
        let output = match std::process::Command::new("python3")
            .arg(script)
            .arg(&path)
            .output()
        {
            Ok(output) if output.status.success() => output,
            _ => {
                eprintln!("note: python3 not available; skipping the independent count");
                return Ok(());
            }
        };
        let counts: serde_json::Value = serde_json::from_slice(&output.stdout)?;
        let number = |key: &str| {
            counts[key]
                .as_u64()
                .map(|n| n as usize)
                .ok_or(format!("{key} missing"))
        };
        let stats = load_map(&path, &LoadOptions::default())?.stats;
        let s = stats.source;
        assert_eq!(s.building_ways, number("building_ways")?, "{name}");
        assert_eq!(
            s.building_relations,
            number("building_relations")?,
            "{name}"
        );
        assert_eq!(s.highway_ways, number("highway_ways")?, "{name}");
        assert_eq!(s.vehicle_road_ways, number("vehicle_road_ways")?, "{name}");
        assert_eq!(
            s.underground_road_ways,
            number("underground_road_ways")?,
            "{name}"
        );
        // Ways only: the Python count reads no relation's tags.
        assert!(s.underground_buildings >= number("underground_building_ways")?);
        assert_eq!(
            s.vehicle_road_ways_used,
            number("vehicle_road_ways_usable")?,
            "{name}"
        );
        // Complete building ways are used unless their ring is broken (self-intersecting or
        // degenerate), which Python does not check.
        let complete = number("building_ways_complete")?;
        let broken: usize = [
            geodata::SkipReason::SelfIntersectingRing,
            geodata::SkipReason::DegenerateRing,
        ]
        .iter()
        .filter_map(|r| stats.skipped.get(r))
        .sum();
        assert!(
            s.building_ways_used <= complete && complete <= s.building_ways_used + broken,
            "{name}: {complete} vs {s:?}"
        );
    }
    Ok(())
}

#[test]
fn projected_extents_have_the_known_size() -> Result<(), MapError> {
    // Expected sizes from the declared bounds with a spherical approximation (R = 6371 km,
    // east-west at the box's mid-latitude): an independent formula that agrees with the
    // ellipsoidal projection to about 0.5 %.
    let sphere = |min_lat: f64, min_lon: f64, max_lat: f64, max_lon: f64| {
        let r = 6_371_000.0_f64;
        let mid = ((min_lat + max_lat) / 2.0).to_radians();
        (
            r * (max_lon - min_lon).to_radians() * mid.cos(),
            r * (max_lat - min_lat).to_radians(),
        )
    };
    for (name, bounds) in [
        // README: "about 1.0 × 1.7 km".
        (
            "helsinki-centre.osm.pbf",
            (60.164155, 24.935176, 60.179113, 24.953415),
        ),
        // README: "about 2.2 × 2.2 km".
        ("kouvola.osm.pbf", (60.52, 26.93, 60.54, 26.97)),
        // README says "about 220 × 150 m", but its own <bounds> (0.002° lat × 0.003° lon at
        // 48.1° N) span 222 × 223 m.
        ("bavarian-village.osm", (48.135, 10.068, 48.137, 10.071)),
    ] {
        let Some(path) = osm_file(name) else {
            return Ok(());
        };
        let stats = load_map(&path, &LoadOptions::default())?.stats;
        let (width, height) = sphere(bounds.0, bounds.1, bounds.2, bounds.3);
        let m = stats.extent_m;
        assert!(
            (m.width_m / width - 1.0).abs() < 0.006,
            "{name}: width {} vs {width}",
            m.width_m
        );
        assert!(
            (m.height_m / height - 1.0).abs() < 0.006,
            "{name}: height {} vs {height}",
            m.height_m
        );
        // Default origin = the extent's centre, so the extent is centred on (0, 0).
        assert!(
            (m.min_x_m + m.max_x_m).abs() < 1e-6 && (m.min_y_m + m.max_y_m).abs() < 0.5,
            "{name}"
        );
    }
    // Monaco has no <bounds>: the extent is the box of its features, the principality plus the
    // harbour roads, about 3 km across (not the 27 km spanned by far-away boundary nodes).
    if let Some(path) = osm_file("monaco.osm.gz") {
        let m = load_map(&path, &LoadOptions::default())?.stats.extent_m;
        assert!(
            (2000.0..6000.0).contains(&m.width_m) && (2000.0..6000.0).contains(&m.height_m),
            "{m:?}"
        );
    }
    Ok(())
}

/// FNV-1a over the context bytes: a compact fingerprint of a raster for the snapshot.
fn fingerprint(contexts: &[MapContext]) -> u64 {
    contexts.iter().fold(0xcbf2_9ce4_8422_2325, |hash, &c| {
        (hash ^ c as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

#[test]
fn rendered_contexts_are_stable() -> Result<(), MapError> {
    let mut lines = Vec::new();
    for (name, ..) in REFERENCE {
        let Some(path) = osm_file(name) else {
            return Ok(());
        };
        let loaded = load_map(&path, &LoadOptions::default())?;
        let raster = ContextRaster::new(&loaded.map);
        let (window, contexts) = raster.rasterise_extent(0.5);
        let mut counts = [0usize; 4];
        for &c in &contexts {
            counts[c as usize] += 1;
        }
        lines.push(format!(
            "{name}: {}x{} cells from ({}, {}); unknown {} other {} road {} building {}; fnv {:016x}",
            window.width, window.height, window.first_col, window.first_row, counts[0], counts[1], counts[2], counts[3],
            fingerprint(&contexts)
        ));
        lines.push(format!(
            "  buildings {} road pieces {} road areas {} parking {} skipped {:?}",
            loaded.stats.buildings,
            loaded.stats.road_pieces,
            loaded.stats.road_areas,
            loaded.stats.parking_areas,
            loaded.stats.skipped
        ));
        let s = &loaded.stats.source;
        lines.push(format!(
            "  below the street: road ways {} buildings {}; covered road ways {}",
            s.underground_road_ways, s.underground_buildings, s.covered_road_ways
        ));
    }
    insta::assert_snapshot!(lines.join("\n"));
    Ok(())
}

#[test]
fn a_crop_reads_back_to_the_same_contexts() -> Result<(), Box<dyn std::error::Error>> {
    let Some(path) = osm_file("helsinki-centre.osm.pbf") else {
        return Ok(());
    };
    let whole = load_map(&path, &LoadOptions::default())?;
    // A 200 m × 300 m block in the middle of the map.
    let bbox = GeoBox {
        min_lat: 60.170,
        min_lon: 24.942,
        max_lat: 60.1727,
        max_lon: 24.9457,
    };
    let text = serde_json::to_string(&whole.features.crop(&bbox).to_geojson())?;
    let options = LoadOptions {
        origin: Some(whole.stats.origin),
    };
    let part = load_map_from_bytes(text.as_bytes(), &options)?;
    assert_eq!(part.stats.extent_wgs84.min_lat, bbox.min_lat);
    assert!(
        part.stats.buildings > 10 && part.stats.road_pieces > 10,
        "{:?}",
        part.stats
    );
    // Same origin, same cells: every cell of the crop's extent has the same context in both.
    let window = geodata::CellWindow::covering(&part.map.extent, 0.5);
    let (mut from_whole, mut from_part) = (
        vec![MapContext::Unknown; window.len()],
        vec![MapContext::Unknown; window.len()],
    );
    ContextRaster::new(&whole.map).fill(&window, &mut from_whole);
    ContextRaster::new(&part.map).fill(&window, &mut from_part);
    let mut compared = 0;
    for (a, b) in from_whole.iter().zip(&from_part) {
        if *b != MapContext::Unknown {
            assert_eq!(a, b);
            compared += 1;
        }
    }
    assert!(
        compared > window.len() * 9 / 10,
        "{compared} of {}",
        window.len()
    );
    Ok(())
}
