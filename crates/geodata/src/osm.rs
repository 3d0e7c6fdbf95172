//! The OSM data model shared by the PBF and XML readers, and its conversion to [`MapFeatures`].

use std::collections::HashMap;

use geo::{Coord, LineString, Rect};

use crate::error::MapError;
use crate::features::{MapFeatures, RoadArea, RoadCentreline, SkipReason};
use crate::rings::{assemble_rings, clean_ring, group_rings};
use crate::tags::{Level, Roles};

/// A way: its node references and what its tags make it.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct OsmWay {
    pub refs: Vec<i64>,
    pub roles: Roles,
}

/// Role of a way in a multipolygon relation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MemberRole {
    Outer,
    Inner,
}

/// A multipolygon relation whose tags make it a building or a surface.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct OsmMultipolygon {
    pub roles: Roles,
    /// Member ways with their roles (node and relation members are ignored).
    pub members: Vec<(i64, MemberRole)>,
}

/// What a reader collects from an OSM file: all node positions, all ways (untagged ones may be
/// multipolygon members), and the multipolygon relations of interest.
#[derive(Debug, Default, PartialEq)]
pub(crate) struct OsmData {
    /// Node id → (x = lon, y = lat), degrees.
    pub nodes: HashMap<i64, Coord<f64>>,
    pub ways: HashMap<i64, OsmWay>,
    /// Way ids in file order, so results do not depend on hash order.
    pub way_order: Vec<i64>,
    pub multipolygons: Vec<OsmMultipolygon>,
    /// `<bounds>` or the PBF header box, (x = lon, y = lat).
    pub bounds: Option<Rect<f64>>,
}

impl OsmData {
    /// Records a node after checking its coordinates.
    pub fn add_node(&mut self, id: i64, lat: f64, lon: f64) -> Result<(), MapError> {
        check_lat_lon(lat, lon, || format!("node {id}"))?;
        self.nodes.insert(id, Coord { x: lon, y: lat });
        Ok(())
    }

    /// Records a way.
    pub fn add_way(&mut self, id: i64, refs: Vec<i64>, roles: Roles) {
        if self.ways.insert(id, OsmWay { refs, roles }).is_none() {
            self.way_order.push(id);
        }
    }

    /// Records a relation if it is a multipolygon that is a building or a road surface.
    pub fn add_relation<'a>(
        &mut self,
        tag: impl Fn(&str) -> Option<&'a str>,
        members: impl Iterator<Item = (i64, &'a str)>,
    ) {
        if tag("type") != Some("multipolygon") {
            return;
        }
        let roles = Roles::from_tags(&tag);
        if !(roles.building || roles.is_road_surface_area()) {
            return;
        }
        let members = members
            .filter_map(|(way, role)| match role {
                "outer" | "" => Some((way, MemberRole::Outer)),
                "inner" => Some((way, MemberRole::Inner)),
                _ => None,
            })
            .collect();
        self.multipolygons.push(OsmMultipolygon { roles, members });
    }

    /// Sets the declared bounds from degrees.
    pub fn set_bounds(
        &mut self,
        min_lat: f64,
        min_lon: f64,
        max_lat: f64,
        max_lon: f64,
    ) -> Result<(), MapError> {
        check_lat_lon(min_lat, min_lon, || "bounds".to_owned())?;
        check_lat_lon(max_lat, max_lon, || "bounds".to_owned())?;
        self.bounds = Some(Rect::new(
            Coord {
                x: min_lon,
                y: min_lat,
            },
            Coord {
                x: max_lon,
                y: max_lat,
            },
        ));
        Ok(())
    }

    /// Builds buildings, road surfaces and centrelines, counting what had to be skipped.
    pub fn into_features(self) -> MapFeatures {
        let mut features = MapFeatures {
            declared_bounds: self.bounds,
            ..MapFeatures::default()
        };
        for coord in self.nodes.values() {
            features.include_coordinate(coord.x, coord.y);
        }
        for id in &self.way_order {
            let Some(way) = self.ways.get(id) else {
                continue;
            };
            self.add_way_features(way, &mut features);
        }
        for relation in &self.multipolygons {
            self.add_multipolygon(relation, &mut features);
        }
        features
    }

    fn add_way_features(&self, way: &OsmWay, features: &mut MapFeatures) {
        let roles = &way.roles;
        let counts = &mut features.source_counts;
        counts.building_ways += usize::from(roles.building);
        counts.highway_ways += usize::from(roles.highway);
        counts.vehicle_road_ways += usize::from(roles.vehicle_road.is_some());
        if roles.is_underground() {
            let line = way.refs.iter().filter_map(|r| self.nodes.get(r).copied());
            features.set_aside_underground(roles, [line.collect()]);
            return;
        }
        if roles.building || roles.is_road_surface_area() {
            match self.area_way_ring(way) {
                Ok(ring) => {
                    let polygon = geo::Polygon::new(ring, Vec::new());
                    if roles.building {
                        features.source_counts.building_ways_used += 1;
                        features.buildings.push(polygon.clone());
                    }
                    if roles.parking {
                        features.parking.push(polygon.clone());
                    }
                    if let Some(class) = roles.road_area_class() {
                        features.road_areas.push(RoadArea {
                            polygon,
                            highway: class.to_owned(),
                        });
                    }
                }
                Err(reason) => features.skip(reason),
            }
        }
        if let (Some(class), false) = (&roles.vehicle_road, roles.area_yes) {
            self.add_centreline(way, class, features);
        }
    }

    /// The closed ring of an area way, or why there is none.
    fn area_way_ring(&self, way: &OsmWay) -> Result<LineString<f64>, SkipReason> {
        if way.refs.len() < 4 || way.refs.first() != way.refs.last() {
            return Err(SkipReason::UnclosedAreaWay);
        }
        let points: Option<Vec<Coord<f64>>> = way
            .refs
            .iter()
            .map(|r| self.nodes.get(r).copied())
            .collect();
        let points = points.ok_or(SkipReason::AreaWayMissingNodes)?;
        clean_ring(&points)
    }

    /// Adds the runs of consecutive present nodes of a road way as centrelines: a road cut by the
    /// extract's border keeps the part inside.
    fn add_centreline(&self, way: &OsmWay, class: &str, features: &mut MapFeatures) {
        let mut runs: Vec<Vec<Coord<f64>>> = vec![Vec::new()];
        let mut missing = false;
        for node in &way.refs {
            match self.nodes.get(node) {
                Some(coord) => runs.last_mut().into_iter().for_each(|run| run.push(*coord)),
                None => {
                    missing = true;
                    if runs.last().is_some_and(|run| !run.is_empty()) {
                        runs.push(Vec::new());
                    }
                }
            }
        }
        let mut kept = 0;
        let covered = way.roles.level == Level::Covered;
        for run in runs.into_iter().filter(|run| run.len() >= 2) {
            kept += 1;
            features.roads.push(RoadCentreline {
                line: LineString::new(run),
                highway: class.to_owned(),
                width_tag: way.roles.width.clone(),
                lanes_tag: way.roles.lanes.clone(),
                covered,
            });
        }
        if kept > 0 {
            features.source_counts.vehicle_road_ways_used += 1;
            features.source_counts.covered_road_ways += usize::from(covered);
        }
        if kept == 0 {
            features.skip(SkipReason::RoadWayTooShort);
        } else if missing {
            features.skip(SkipReason::RoadWayPartlyMissing);
        }
    }

    /// Assembles a multipolygon from its member ways. Each relation is counted at most once in the
    /// skip counts, by the first reason that applies: members absent from the extract, rings that
    /// do not close, no outer ring.
    fn add_multipolygon(&self, relation: &OsmMultipolygon, features: &mut MapFeatures) {
        features.source_counts.building_relations += usize::from(relation.roles.building);
        if relation.roles.is_underground() {
            features.source_counts.underground_buildings += usize::from(relation.roles.building);
            let members = relation
                .members
                .iter()
                .filter_map(|(id, _)| self.ways.get(id));
            for way in members {
                let line = way.refs.iter().filter_map(|r| self.nodes.get(r).copied());
                features.underground.push(line.collect());
            }
            return;
        }
        let mut missing_members = false;
        let mut ways_by_role: [Vec<Vec<i64>>; 2] = [Vec::new(), Vec::new()];
        for (way_id, role) in &relation.members {
            match self.ways.get(way_id) {
                Some(way) if way.refs.iter().all(|r| self.nodes.contains_key(r)) => {
                    ways_by_role[usize::from(*role == MemberRole::Inner)].push(way.refs.clone());
                }
                _ => missing_members = true,
            }
        }
        let [outer_ways, inner_ways] = ways_by_role;
        let (outer_rings, open_outer) = assemble_rings(&outer_ways);
        let (inner_rings, open_inner) = assemble_rings(&inner_ways);
        let mut bad_ring = None;
        let mut to_rings = |rings: Vec<Vec<i64>>| -> Vec<LineString<f64>> {
            rings
                .iter()
                .filter_map(|ids| {
                    let points: Vec<Coord<f64>> = ids
                        .iter()
                        .filter_map(|r| self.nodes.get(r).copied())
                        .collect();
                    clean_ring(&points)
                        .map_err(|reason| bad_ring = Some(reason))
                        .ok()
                })
                .collect()
        };
        let outers = to_rings(outer_rings);
        let inners = to_rings(inner_rings);
        let reason = if missing_members {
            Some(SkipReason::RelationMissingMembers)
        } else if open_outer + open_inner > 0 {
            Some(SkipReason::RelationOpenRing)
        } else if outers.is_empty() {
            Some(bad_ring.unwrap_or(SkipReason::RelationNoOuterRing))
        } else {
            bad_ring
        };
        if let Some(reason) = reason {
            features.skip(reason);
        }
        let (polygons, orphans) = group_rings(outers, inners);
        for _ in 0..orphans {
            features.skip(SkipReason::OrphanInnerRing);
        }
        let roles = &relation.roles;
        if roles.building && !polygons.is_empty() {
            features.source_counts.building_relations_used += 1;
        }
        for polygon in polygons {
            if roles.building {
                features.buildings.push(polygon.clone());
            }
            if roles.parking {
                features.parking.push(polygon.clone());
            }
            if let Some(class) = roles.road_area_class() {
                features.road_areas.push(RoadArea {
                    polygon,
                    highway: class.to_owned(),
                });
            }
        }
    }
}

/// Rejects latitudes outside [−90, 90], longitudes outside [−180, 180] and non-finite values.
pub(crate) fn check_lat_lon(
    lat: f64,
    lon: f64,
    element: impl FnOnce() -> String,
) -> Result<(), MapError> {
    if lat.is_finite() && lon.is_finite() && lat.abs() <= 90.0 && lon.abs() <= 180.0 {
        Ok(())
    } else {
        Err(MapError::CoordinateOutOfRange {
            element: element(),
            lat,
            lon,
        })
    }
}
