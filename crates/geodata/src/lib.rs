//! geodata: OpenStreetMap and GeoJSON maps turned into per-cell map contexts.
//!
//! **What.** Reads vector maps (OSM PBF, OSM XML, gzipped OSM XML, GeoJSON), keeps buildings and
//! road surface as defined in SPEC §4, projects them into a local metric frame with a transverse
//! Mercator projection, and rasterises them into [`MapContext`]s (building, road, other,
//! unknown) for any window of a world-fixed grid.
//!
//! **Why.** The map prior of an evidential grid (Kurdej et al. 2013, eq 32-38) needs, for each
//! cell of a window that follows the vehicle, what the map says at the cell's centre. This crate
//! answers that and knows nothing of belief functions.
//!
//! **Key design decision.** Polygons, not pixels, are the stored form: the map is kept as
//! polygons in local metres behind an R-tree, and each window is filled on demand by a scanline
//! fill over the few polygons that meet it ([`ContextRaster`]). Road centrelines are buffered into
//! one convex capsule per segment, which is exact for the cell-centre test and needs no polygon
//! union.
//!
//! ```
//! use geodata::{CellWindow, ContextRaster, LocalMap, MapContext};
//! let text = r#"{"type": "FeatureCollection", "bbox": [-20, -20, 20, 20], "features": [
//!   {"type": "Feature", "properties": {"building": "yes"},
//!    "geometry": {"type": "Polygon", "coordinates": [[[2, 2], [10, 2], [10, 10], [2, 10], [2, 2]]]}},
//!   {"type": "Feature", "properties": {"highway": "residential", "width": "4"},
//!    "geometry": {"type": "LineString", "coordinates": [[-20, 0], [20, 0]]}}]}"#;
//! let raster = ContextRaster::new(&LocalMap::from_local_geojson(text)?);
//! // Centres at x = 0.5 m and y = -2.5, 0.5, 5.5, 30.5 m.
//! assert_eq!(raster.context_at(0.5, -2.5), MapContext::Other);
//! assert_eq!(raster.context_at(0.5, 0.5), MapContext::Road);
//! assert_eq!(raster.context_at(5.5, 5.5), MapContext::Building);
//! assert_eq!(raster.context_at(0.5, 30.5), MapContext::Unknown);
//! # Ok::<(), geodata::MapError>(())
//! ```
#![deny(missing_docs)]

pub mod buffer;
mod context;
mod crop;
mod error;
mod features;
mod geojson_input;
mod load;
mod local_map;
mod osm;
mod osm_pbf;
mod osm_xml;
mod passage;
mod projection;
mod raster;
mod rings;
pub mod tags;
#[doc(hidden)]
pub mod testdata;

pub use context::{CellWindow, MapContext};
pub use error::MapError;
pub use features::{MapFeatures, RoadArea, RoadCentreline, SkipCounts, SkipReason, SourceCounts};
pub use load::{
    GeoBox, LoadOptions, LoadedMap, MapFormat, MapStats, MetricBox, load_map, load_map_from_bytes,
};
pub use local_map::LocalMap;
pub use projection::TransverseMercator;
pub use raster::ContextRaster;
