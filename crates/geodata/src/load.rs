//! Loading a map file: format detection, reading, projection, statistics.

use std::io::Read;
use std::path::Path;

use geo::{Coord, Rect};

use crate::error::MapError;
use crate::features::{MapFeatures, SkipCounts, SourceCounts};
use crate::geojson_input::{CoordinateKind, parse_geojson};
use crate::local_map::LocalMap;
use crate::osm_pbf::read_osm_pbf;
use crate::osm_xml::read_osm_xml;
use crate::projection::TransverseMercator;

/// A map file format, recognised from content.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum MapFormat {
    /// OSM PBF: a sequence of length-prefixed `BlobHeader`s (first type `OSMHeader`).
    OsmPbf,
    /// OSM XML: starts with `<`.
    OsmXml,
    /// Gzip-compressed OSM XML: starts with the gzip magic `1f 8b`.
    OsmXmlGzip,
    /// GeoJSON in WGS84: starts with `{`.
    GeoJson,
}

impl MapFormat {
    /// Recognises the format from the first bytes (magic numbers), not from a file name.
    ///
    /// # Errors
    /// [`MapError::UnknownFormat`] when nothing matches.
    ///
    /// ```
    /// use geodata::MapFormat;
    /// assert_eq!(MapFormat::detect(b"\xef\xbb\xbf  <?xml version=\"1.0\"?><osm/>")?, MapFormat::OsmXml);
    /// assert_eq!(MapFormat::detect(b"\x1f\x8b\x08\x00")?, MapFormat::OsmXmlGzip);
    /// assert_eq!(MapFormat::detect(b"\n{\"type\": \"FeatureCollection\"}")?, MapFormat::GeoJson);
    /// assert!(MapFormat::detect(b"PK\x03\x04").is_err());
    /// # Ok::<(), geodata::MapError>(())
    /// ```
    pub fn detect(bytes: &[u8]) -> Result<Self, MapError> {
        if bytes.starts_with(&[0x1f, 0x8b]) {
            return Ok(Self::OsmXmlGzip);
        }
        if looks_like_pbf(bytes) {
            return Ok(Self::OsmPbf);
        }
        let text = bytes
            .strip_prefix(b"\xef\xbb\xbf".as_slice())
            .unwrap_or(bytes);
        match text.iter().find(|b| !b.is_ascii_whitespace()) {
            Some(b'<') => Ok(Self::OsmXml),
            Some(b'{') => Ok(Self::GeoJson),
            _ => Err(MapError::UnknownFormat {
                first_bytes: bytes
                    .iter()
                    .take(8)
                    .map(|b| format!("{b:02x}"))
                    .collect::<Vec<_>>()
                    .join(" "),
            }),
        }
    }
}

/// A PBF file starts with a 4-byte big-endian length (a BlobHeader is small) followed by the
/// BlobHeader message, whose field 1 (wire tag 0x0a) is the string `OSMHeader` or `OSMData`.
fn looks_like_pbf(bytes: &[u8]) -> bool {
    let Some(length) = bytes.get(..4) else {
        return false;
    };
    let length = u32::from_be_bytes([length[0], length[1], length[2], length[3]]);
    if !(1..=64 * 1024).contains(&length) || bytes.get(4) != Some(&0x0a) {
        return false;
    }
    let Some(&type_length) = bytes.get(5) else {
        return false;
    };
    matches!(
        bytes.get(6..6 + usize::from(type_length)),
        Some(b"OSMHeader" | b"OSMData")
    )
}

/// How to load a map.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoadOptions {
    /// Origin of the local frame as WGS84 `(lat, lon)` degrees. By default, the centre of the
    /// map's extent, which keeps the projection's scale error smallest over the map.
    pub origin: Option<(f64, f64)>,
}

/// Latitude/longitude box, degrees.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GeoBox {
    /// Southern edge.
    pub min_lat: f64,
    /// Western edge.
    pub min_lon: f64,
    /// Northern edge.
    pub max_lat: f64,
    /// Eastern edge.
    pub max_lon: f64,
}

/// Box in local metres.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MetricBox {
    /// Western edge, metres east of the origin.
    pub min_x_m: f64,
    /// Southern edge, metres north of the origin.
    pub min_y_m: f64,
    /// Eastern edge.
    pub max_x_m: f64,
    /// Northern edge.
    pub max_y_m: f64,
    /// East-west size, metres.
    pub width_m: f64,
    /// North-south size, metres.
    pub height_m: f64,
}

/// What was read from a map and what was left out.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MapStats {
    /// The detected format.
    pub format: MapFormat,
    /// Tagged elements in the source (for checking against an independent count).
    pub source: SourceCounts,
    /// Building polygons in the map (one per way, one per outer ring of a relation).
    pub buildings: usize,
    /// Vehicle-road centreline pieces buffered (a way cut at the border may give several).
    pub road_centrelines: usize,
    /// Road-surface polygons made from centrelines (one capsule per segment).
    pub road_pieces: usize,
    /// `area:highway` (and `highway` + `area=yes`) surface polygons.
    pub road_areas: usize,
    /// `amenity=parking` polygons.
    pub parking_areas: usize,
    /// Items skipped, by reason.
    pub skipped: SkipCounts,
    /// Extent, WGS84 degrees.
    pub extent_wgs84: GeoBox,
    /// Extent, local metres.
    pub extent_m: MetricBox,
    /// Origin of the local frame, `(lat, lon)` degrees.
    pub origin: (f64, f64),
}

/// A map ready to rasterise, with its projection and what loading found.
#[derive(Clone, Debug)]
pub struct LoadedMap {
    /// Buildings and road surface in local metres.
    pub map: LocalMap,
    /// WGS84 ↔ local metres.
    pub projection: TransverseMercator,
    /// Counts and extent.
    pub stats: MapStats,
    /// The features in WGS84 (x = lon, y = lat), as read, before projection and buffering.
    pub features: MapFeatures,
}

/// Loads a map file, recognising its format from its content.
///
/// # Errors
/// [`MapError::Io`] if the file cannot be read; otherwise the content errors of
/// [`load_map_from_bytes`], wrapped in [`MapError::InFile`] naming the file.
///
/// ```no_run
/// let loaded = geodata::load_map("helsinki-centre.osm.pbf", &geodata::LoadOptions::default())?;
/// println!("{} buildings, {:.0} m wide", loaded.stats.buildings, loaded.stats.extent_m.width_m);
/// # Ok::<(), geodata::MapError>(())
/// ```
pub fn load_map(path: impl AsRef<Path>, options: &LoadOptions) -> Result<LoadedMap, MapError> {
    let path = path.as_ref();
    let bytes = read_map_file(path)?;
    load_map_from_bytes(&bytes, options).map_err(|e| e.in_file(path))
}

/// Largest map file read, and largest gzipped map once decompressed, bytes. Parsing holds the
/// map's nodes and ways in memory on top of the bytes, so this keeps a whole load within the
/// memory a drive run may take; a city's PBF extract is a few MB.
pub const MAX_MAP_BYTES: u64 = 512 << 20;

/// Reads a map file whole, refusing what is not a regular file (checked before opening: opening
/// a FIFO with no writer blocks) and more than [`MAX_MAP_BYTES`] (bounded while reading too:
/// metadata of special files lies).
fn read_map_file(path: &Path) -> Result<Vec<u8>, MapError> {
    let io = |source| MapError::Io {
        path: path.to_owned(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(MapError::NotAFile {
            path: path.to_owned(),
        });
    }
    let too_large = || {
        MapError::TooLarge {
            what: "the file",
            max_mib: MAX_MAP_BYTES >> 20,
        }
        .in_file(path)
    };
    if meta.len() > MAX_MAP_BYTES {
        return Err(too_large());
    }
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .map_err(io)?
        .take(MAX_MAP_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > MAX_MAP_BYTES {
        return Err(too_large());
    }
    Ok(bytes)
}

/// Loads a map from bytes in memory (e.g. a map embedded with `include_bytes!`).
///
/// # Errors
/// [`MapError::UnknownFormat`]; the format's errors ([`MapError::Pbf`], [`MapError::Gzip`],
/// [`MapError::Xml`], [`MapError::Json`], [`MapError::GeoJson`],
/// [`MapError::UnknownGeometryType`]); [`MapError::CoordinateOutOfRange`];
/// [`MapError::InvalidOrigin`]; [`MapError::Empty`] when the map has no coordinate.
pub fn load_map_from_bytes(bytes: &[u8], options: &LoadOptions) -> Result<LoadedMap, MapError> {
    let format = MapFormat::detect(bytes)?;
    let features = read_features(bytes, format)?;
    project(features, format, options)
}

/// Reads features in WGS84 from bytes of a known format.
fn read_features(bytes: &[u8], format: MapFormat) -> Result<MapFeatures, MapError> {
    match format {
        MapFormat::OsmPbf => Ok(read_osm_pbf(bytes)?.into_features()),
        MapFormat::OsmXml => Ok(read_osm_xml(bytes)?.into_features()),
        MapFormat::GeoJson => parse_geojson(bytes, CoordinateKind::Wgs84),
        MapFormat::OsmXmlGzip => {
            // Bounded: a few MB of gzip can expand to gigabytes.
            let mut xml = Vec::new();
            flate2::read::MultiGzDecoder::new(bytes)
                .take(MAX_MAP_BYTES + 1)
                .read_to_end(&mut xml)
                .map_err(|e| MapError::Gzip {
                    message: e.to_string(),
                })?;
            if xml.len() as u64 > MAX_MAP_BYTES {
                return Err(MapError::TooLarge {
                    what: "the decompressed map",
                    max_mib: MAX_MAP_BYTES >> 20,
                });
            }
            match MapFormat::detect(&xml)? {
                MapFormat::OsmXmlGzip => Err(MapError::Gzip {
                    message: "gzip inside gzip".to_owned(),
                }),
                inner => read_features(&xml, inner),
            }
        }
    }
}

/// Projects WGS84 features into local metres around the origin and gathers the statistics.
pub(crate) fn project(
    features: MapFeatures,
    format: MapFormat,
    options: &LoadOptions,
) -> Result<LoadedMap, MapError> {
    let extent = across_antimeridian(features.extent().ok_or(MapError::Empty)?, &features);
    let (origin_lat, origin_lon) = options.origin.unwrap_or((
        (extent.min().y + extent.max().y) / 2.0,
        normalise_lon((extent.min().x + extent.max().x) / 2.0),
    ));
    let projection = TransverseMercator::new(origin_lat, origin_lon)?;
    let to_local = |c: Coord<f64>| {
        let (x, y) = projection.forward(c.y, c.x);
        Coord { x, y }
    };
    let extent_m = project_box(extent, to_local);
    let (buildings, roads, road_pieces) = features.to_local_polygons(to_local);
    let stats = MapStats {
        format,
        source: features.source_counts,
        buildings: buildings.len(),
        road_centrelines: features.roads.len(),
        road_pieces,
        road_areas: features.road_areas.len(),
        parking_areas: features.parking.len(),
        skipped: features.skipped.clone(),
        // As GeoJSON's bbox (RFC 7946 §5.2): across the antimeridian, min_lon > max_lon.
        extent_wgs84: GeoBox {
            min_lat: extent.min().y,
            min_lon: normalise_lon(extent.min().x),
            max_lat: extent.max().y,
            max_lon: normalise_lon(extent.max().x),
        },
        extent_m: MetricBox {
            min_x_m: extent_m.min().x,
            min_y_m: extent_m.min().y,
            max_x_m: extent_m.max().x,
            max_y_m: extent_m.max().y,
            width_m: extent_m.width(),
            height_m: extent_m.height(),
        },
        origin: (origin_lat, origin_lon),
    };
    Ok(LoadedMap {
        map: LocalMap::new(buildings, roads, extent_m),
        projection,
        stats,
        features,
    })
}

/// The metric bounding box of a lat/lon box: meridians and parallels are curves in the
/// projection, so sample the box's edges densely rather than only its corners.
/// The extent of a map that crosses the antimeridian as a box that does not go round the
/// world: when the features fit in less than half the globe with western longitudes counted
/// from 180° to 360°, but not as given, the box runs from the western end past 180°. A map
/// centred on the antimeridian would otherwise get its origin at longitude 0, half a world away.
fn across_antimeridian(extent: Rect<f64>, features: &MapFeatures) -> Rect<f64> {
    if extent.width() <= 180.0 {
        return extent;
    }
    match features.feature_bounds_east_of_antimeridian() {
        Some(wrapped) if wrapped.width() < 180.0 => Rect::new(
            Coord {
                x: wrapped.min().x,
                y: extent.min().y,
            },
            Coord {
                x: wrapped.max().x,
                y: extent.max().y,
            },
        ),
        _ => extent,
    }
}

/// A longitude in (−180°, 180°].
fn normalise_lon(lon: f64) -> f64 {
    let wrapped = (lon + 180.0).rem_euclid(360.0) - 180.0;
    if wrapped == -180.0 { 180.0 } else { wrapped }
}

fn project_box(extent: Rect<f64>, to_local: impl Fn(Coord<f64>) -> Coord<f64>) -> Rect<f64> {
    const SAMPLES: usize = 16;
    let (min, max) = (extent.min(), extent.max());
    let mut lo = Coord {
        x: f64::INFINITY,
        y: f64::INFINITY,
    };
    let mut hi = Coord {
        x: f64::NEG_INFINITY,
        y: f64::NEG_INFINITY,
    };
    for i in 0..=SAMPLES {
        let t = i as f64 / SAMPLES as f64;
        let lon = min.x + t * (max.x - min.x);
        let lat = min.y + t * (max.y - min.y);
        for c in [
            Coord { x: lon, y: min.y },
            Coord { x: lon, y: max.y },
            Coord { x: min.x, y: lat },
            Coord { x: max.x, y: lat },
        ] {
            let p = to_local(c);
            lo = Coord {
                x: lo.x.min(p.x),
                y: lo.y.min(p.y),
            };
            hi = Coord {
                x: hi.x.max(p.x),
                y: hi.y.max(p.y),
            };
        }
    }
    Rect::new(lo, hi)
}
