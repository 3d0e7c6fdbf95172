//! Map features as read from a file, before projection: the common output of every reader.

use std::collections::BTreeMap;

use geo::{LineString, Polygon, Rect};

use crate::buffer::buffer_line;
use crate::passage::cut_passages;
use crate::tags::{Roles, road_width_m};

/// A vehicle-road centreline with the tags that decide its width.
#[derive(Clone, Debug, PartialEq)]
pub struct RoadCentreline {
    /// The centreline, in the coordinates of the [`MapFeatures`] holding it.
    pub line: LineString<f64>,
    /// The `highway` class (a vehicle class, see [`is_vehicle_road`](crate::tags::is_vehicle_road)).
    pub highway: String,
    /// The raw `width` tag, if any.
    pub width_tag: Option<String>,
    /// The raw `lanes` tag, if any.
    pub lanes_tag: Option<String>,
    /// At street level under a roof ([`Level::Covered`](crate::tags::Level::Covered): a building
    /// passage, a covered way): its surface is cut out of the buildings it crosses.
    pub covered: bool,
}

impl RoadCentreline {
    /// The width the centreline is buffered to, metres (see [`road_width_m`]).
    pub fn width_m(&self) -> f64 {
        road_width_m(
            &self.highway,
            self.width_tag.as_deref(),
            self.lanes_tag.as_deref(),
        )
        .unwrap_or(0.0)
    }
}

/// A road-surface polygon (`area:highway`, or a vehicle `highway` with `area=yes`).
#[derive(Clone, Debug, PartialEq)]
pub struct RoadArea {
    /// The surface, in the coordinates of the [`MapFeatures`] holding it.
    pub polygon: Polygon<f64>,
    /// Its vehicle class (the `area:highway` or `highway` value).
    pub highway: String,
}

/// Why an item of the input was left out of the map.
///
/// Real OSM extracts are incomplete at their border; these are counted, not errors.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum SkipReason {
    /// An area way refers to nodes absent from the extract (cut at the border).
    AreaWayMissingNodes,
    /// A road way refers to nodes absent from the extract; the present runs were kept, this counts
    /// the ways that lost part of their length.
    RoadWayPartlyMissing,
    /// A road way with fewer than two present nodes: nothing left to draw.
    RoadWayTooShort,
    /// An area way that is not closed (first node ≠ last node).
    UnclosedAreaWay,
    /// A ring with fewer than three distinct points.
    DegenerateRing,
    /// A ring that crosses itself.
    SelfIntersectingRing,
    /// Some member ways of a multipolygon relation are absent from the extract (or cut). The
    /// rings that still close are used; the relation is counted here once either way.
    RelationMissingMembers,
    /// A multipolygon relation whose (present) member ways do not all join into closed rings;
    /// the rings that close are used.
    RelationOpenRing,
    /// A multipolygon relation with no usable outer ring.
    RelationNoOuterRing,
    /// An inner ring of a multipolygon that lies in none of its outer rings.
    OrphanInnerRing,
    /// A GeoJSON feature whose geometry type cannot carry its role (a Point, a LineString
    /// building, a GeometryCollection, no geometry).
    UnsupportedGeometry,
}

impl SkipReason {
    /// snake_case name, as in JSON output.
    pub fn name(self) -> &'static str {
        match self {
            Self::AreaWayMissingNodes => "area_way_missing_nodes",
            Self::RoadWayPartlyMissing => "road_way_partly_missing",
            Self::RoadWayTooShort => "road_way_too_short",
            Self::UnclosedAreaWay => "unclosed_area_way",
            Self::DegenerateRing => "degenerate_ring",
            Self::SelfIntersectingRing => "self_intersecting_ring",
            Self::RelationMissingMembers => "relation_missing_members",
            Self::RelationOpenRing => "relation_open_ring",
            Self::RelationNoOuterRing => "relation_no_outer_ring",
            Self::OrphanInnerRing => "orphan_inner_ring",
            Self::UnsupportedGeometry => "unsupported_geometry",
        }
    }
}

/// Counts of skipped items by reason.
pub type SkipCounts = BTreeMap<SkipReason, usize>;

/// Counts of tagged elements in the source and of how many of them were used. The first four
/// make a reader checkable against an independent count (e.g. pyosmium's); the `_used` ones show
/// what an extract cut at its border cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SourceCounts {
    /// OSM ways (or GeoJSON features) tagged `building=*` other than `no`.
    pub building_ways: usize,
    /// OSM multipolygon relations tagged `building=*` other than `no`.
    pub building_relations: usize,
    /// OSM ways (or GeoJSON features) tagged `highway=*`, any class.
    pub highway_ways: usize,
    /// Of those, the ones of a vehicle class.
    pub vehicle_road_ways: usize,
    /// Building ways that became a building polygon.
    pub building_ways_used: usize,
    /// Building relations that gave at least one building polygon.
    pub building_relations_used: usize,
    /// Vehicle-road ways of which at least one piece of centreline was kept.
    pub vehicle_road_ways_used: usize,
    /// Vehicle-road ways below the street (a tunnel, `layer` < 0): left out of the road surface.
    pub underground_road_ways: usize,
    /// Building ways and relations below the street (`layer` < 0, `location=underground`): left
    /// out of the buildings.
    pub underground_buildings: usize,
    /// Vehicle-road ways at street level under a roof (a building passage, `covered=yes`), used,
    /// their surface cut out of the buildings they cross.
    pub covered_road_ways: usize,
}

/// Everything a reader extracted from a map, in the file's coordinates (x = longitude,
/// y = latitude for WGS84 sources; metres for local sources).
#[derive(Clone, Debug, Default)]
pub struct MapFeatures {
    /// Building footprints (outer ring, holes).
    pub buildings: Vec<Polygon<f64>>,
    /// `area:highway` surfaces and vehicle `highway` ways tagged `area=yes`.
    pub road_areas: Vec<RoadArea>,
    /// `amenity=parking` areas.
    pub parking: Vec<Polygon<f64>>,
    /// Vehicle-road centrelines, to be buffered.
    pub roads: Vec<RoadCentreline>,
    /// The lines and rings of roads and buildings below the street: not in the map, but in its
    /// [`extent`](Self::extent), so that leaving them out never moves the local frame.
    pub underground: Vec<LineString<f64>>,
    /// The extent the file declares (OSM `<bounds>`, the PBF header box, a GeoJSON `bbox`).
    pub declared_bounds: Option<Rect<f64>>,
    /// The bounding box of every coordinate read (all nodes, not only used ones).
    pub coordinate_bounds: Option<Rect<f64>>,
    /// Tagged elements seen.
    pub source_counts: SourceCounts,
    /// Items left out, by reason.
    pub skipped: SkipCounts,
}

impl MapFeatures {
    /// Counts one skipped item.
    pub(crate) fn skip(&mut self, reason: SkipReason) {
        *self.skipped.entry(reason).or_insert(0) += 1;
    }

    /// Counts an element below the street and, when it would have been a building or road
    /// surface, keeps its `lines` for the extent only: no street-level scanner sees it, so it is
    /// neither, but leaving it out must not move the local frame. Every reader calls this.
    pub(crate) fn set_aside_underground(
        &mut self,
        roles: &Roles,
        lines: impl IntoIterator<Item = LineString<f64>>,
    ) {
        self.source_counts.underground_road_ways += usize::from(roles.vehicle_road.is_some());
        self.source_counts.underground_buildings += usize::from(roles.building);
        if roles.building || roles.vehicle_road.is_some() || roles.is_road_surface_area() {
            self.underground.extend(lines);
        }
    }

    /// Extends the coordinate bounds to hold `(x, y)`.
    pub(crate) fn include_coordinate(&mut self, x: f64, y: f64) {
        let point = geo::coord! { x: x, y: y };
        self.coordinate_bounds = Some(match self.coordinate_bounds {
            None => Rect::new(point, point),
            Some(rect) => Rect::new(
                geo::coord! { x: rect.min().x.min(x), y: rect.min().y.min(y) },
                geo::coord! { x: rect.max().x.max(x), y: rect.max().y.max(y) },
            ),
        });
    }

    /// The map's extent in source coordinates: the declared bounds if any; else the bounding box
    /// of the features kept (buildings, road surfaces, centrelines); else, for a map without
    /// features, the bounding box of all coordinates.
    ///
    /// Extracts without declared bounds (e.g. `monaco.osm.gz`) hold a few far-away nodes of
    /// boundary relations; bounding the features keeps the extent to where the map says
    /// something (Monaco: 3 km instead of 27 km).
    pub fn extent(&self) -> Option<Rect<f64>> {
        self.declared_bounds
            .or_else(|| self.feature_bounds())
            .or(self.coordinate_bounds)
    }

    /// Bounding box of every kept feature's coordinates.
    pub fn feature_bounds(&self) -> Option<Rect<f64>> {
        bounds_of(self.feature_coords())
    }

    /// Bounding box of every kept feature's coordinates with western longitudes counted from
    /// 180° to 360° (`lon + 360` for `lon < 0`): for a map across the antimeridian, the box that
    /// does not go round the world.
    pub fn feature_bounds_east_of_antimeridian(&self) -> Option<Rect<f64>> {
        bounds_of(self.feature_coords().map(|c| {
            geo::coord! {
                x: if c.x < 0.0 { c.x + 360.0 } else { c.x },
                y: c.y,
            }
        }))
    }

    fn feature_coords(&self) -> impl Iterator<Item = geo::Coord<f64>> + '_ {
        use geo::CoordsIter;
        let polygons = self
            .buildings
            .iter()
            .chain(self.road_areas.iter().map(|a| &a.polygon))
            .chain(&self.parking);
        polygons
            .flat_map(|p| p.exterior().coords_iter())
            .chain(self.roads.iter().flat_map(|r| r.line.coords_iter()))
            .chain(self.underground.iter().flat_map(|l| l.coords_iter()))
    }

    /// Converts the features to road-surface and building polygons in local metres, with
    /// `to_local` mapping one source coordinate to local metres. Centrelines are converted then
    /// buffered in metres; the surface of a covered one is cut out of the buildings it crosses
    /// (a street-level scanner sees into a building passage). Returns
    /// `(buildings, road_surface, road_pieces_from_centrelines)`.
    pub(crate) fn to_local_polygons(
        &self,
        to_local: impl Fn(geo::Coord<f64>) -> geo::Coord<f64>,
    ) -> (Vec<Polygon<f64>>, Vec<Polygon<f64>>, usize) {
        use geo::MapCoords;
        let buildings: Vec<Polygon<f64>> = self
            .buildings
            .iter()
            .map(|p| p.map_coords(&to_local))
            .collect();
        let mut roads: Vec<Polygon<f64>> = self
            .road_areas
            .iter()
            .map(|a| &a.polygon)
            .chain(&self.parking)
            .map(|p| p.map_coords(&to_local))
            .collect();
        let areas = roads.len();
        let mut passages = Vec::new();
        for road in &self.roads {
            let first_piece = roads.len();
            buffer_line(&road.line.map_coords(&to_local), road.width_m(), &mut roads);
            if road.covered {
                passages.extend_from_slice(&roads[first_piece..]);
            }
        }
        let pieces = roads.len() - areas;
        (cut_passages(buildings, &passages), roads, pieces)
    }
}

/// Bounding box of `coords`, `None` for none.
fn bounds_of(coords: impl Iterator<Item = geo::Coord<f64>>) -> Option<Rect<f64>> {
    let mut bounds: Option<Rect<f64>> = None;
    for c in coords {
        bounds = Some(match bounds {
            None => Rect::new(c, c),
            Some(rect) => Rect::new(
                geo::coord! { x: rect.min().x.min(c.x), y: rect.min().y.min(c.y) },
                geo::coord! { x: rect.max().x.max(c.x), y: rect.max().y.max(c.y) },
            ),
        });
    }
    bounds
}
