//! The one error type of the crate.

use std::path::PathBuf;

/// Why a map could not be read.
///
/// Incomplete data (ways cut at the extract's border, relations with missing members, broken
/// rings) is *not* an error: such items are skipped and counted in
/// [`MapStats::skipped`](crate::MapStats::skipped). Errors are reserved for input that cannot be a
/// map at all.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MapError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The path is not a regular file (a directory, a FIFO, a device): reading it could block
    /// forever or never end.
    #[error("{path}: not a regular file")]
    NotAFile {
        /// The path.
        path: PathBuf,
    },
    /// The map, or a gzipped map once decompressed, is larger than evigrid reads.
    #[error(
        "{what} is larger than {max_mib} MiB, the most evigrid reads (cut the area you need out \
         of it, e.g. with `osmium extract`)"
    )]
    TooLarge {
        /// What is too large: `the file` or `the decompressed map`.
        what: &'static str,
        /// The limit, MiB.
        max_mib: u64,
    },
    /// An error in the content of a file, with the file's name.
    #[error("{path}: {source}")]
    InFile {
        /// The file.
        path: PathBuf,
        /// What is wrong with its content.
        source: Box<MapError>,
    },
    /// The content is none of the supported formats.
    #[error(
        "unknown map format (first bytes {first_bytes}); expected OSM PBF, OSM XML, gzipped OSM XML or GeoJSON"
    )]
    UnknownFormat {
        /// The first bytes of the content, in hexadecimal.
        first_bytes: String,
    },
    /// The OSM PBF content is truncated or corrupt.
    #[error("invalid OSM PBF: {message}")]
    Pbf {
        /// The decoder's message.
        message: String,
    },
    /// The gzip stream is truncated or corrupt.
    #[error("invalid gzip data: {message}")]
    Gzip {
        /// The decompressor's message.
        message: String,
    },
    /// The OSM XML content is not well-formed or not OSM.
    #[error("invalid OSM XML at byte {position}: {message}")]
    Xml {
        /// Byte offset in the (decompressed) XML where the problem was found.
        position: u64,
        /// What is wrong.
        message: String,
    },
    /// The JSON content does not parse.
    #[error("invalid JSON at line {line}, column {column}: {message}")]
    Json {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The parser's message.
        message: String,
    },
    /// The JSON is valid but not a GeoJSON map this crate understands.
    #[error("invalid GeoJSON: {message}")]
    GeoJson {
        /// What is wrong, naming the feature index where there is one.
        message: String,
    },
    /// A GeoJSON geometry has a `type` that GeoJSON does not define.
    #[error("invalid GeoJSON: feature {feature} has unknown geometry type {geometry_type:?}")]
    UnknownGeometryType {
        /// Index of the feature in the collection.
        feature: usize,
        /// The offending type name.
        geometry_type: String,
    },
    /// A coordinate is not a WGS84 latitude/longitude (|lat| > 90, |lon| > 180 or not finite).
    #[error("coordinate out of WGS84 range in {element}: lat {lat}, lon {lon}")]
    CoordinateOutOfRange {
        /// The element holding it (`node 42`, `feature 3`).
        element: String,
        /// Latitude, degrees.
        lat: f64,
        /// Longitude, degrees.
        lon: f64,
    },
    /// A coordinate in a local-metre map is not finite.
    #[error("non-finite coordinate in {element}: ({x}, {y})")]
    NonFiniteCoordinate {
        /// The element holding it.
        element: String,
        /// East, metres.
        x: f64,
        /// North, metres.
        y: f64,
    },
    /// The projection origin given by the caller is not a WGS84 latitude/longitude.
    #[error("invalid projection origin: lat {lat}, lon {lon} (need |lat| < 90, |lon| <= 180)")]
    InvalidOrigin {
        /// Latitude, degrees.
        lat: f64,
        /// Longitude, degrees.
        lon: f64,
    },
    /// The map holds no coordinate at all, so it has no extent.
    #[error("the map contains no coordinates")]
    Empty,
}

impl MapError {
    /// Attaches the file name to a content error (I/O errors already carry it).
    pub(crate) fn in_file(self, path: impl Into<PathBuf>) -> Self {
        match self {
            Self::Io { .. } | Self::InFile { .. } | Self::NotAFile { .. } => self,
            other => Self::InFile {
                path: path.into(),
                source: Box::new(other),
            },
        }
    }
}
