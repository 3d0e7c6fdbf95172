//! A simulated drive: the world, its actors and the ego, stepped once per scan.
//!
//! [`Drive::new`] builds everything from a map and a [`Scenario`]; [`Drive::next_frame`] advances
//! time by one scan period and returns the scan; [`Drive::truth`] labels any window at the
//! current instant. Two random streams are seeded from the scenario seed: one for traffic, one
//! for sensor noise, so changing the sensor never changes the traffic.

use crate::SimError;
use crate::actors::{self, Actor, Obstacle};
use crate::geometry::{Polyline, Pose2, Vec2};
use crate::label::Label;
use crate::roadnet::{RoadNetwork, Route};
use crate::scenario::Scenario;
use crate::sensor::{self, Scan};
use crate::truth;
use crate::world::World;
use geodata::{CellWindow, LocalMap};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};

/// Stream separator for the sensor's random numbers (any odd constant; this is 2⁶⁴/φ).
const SENSOR_STREAM: u64 = 0x9E37_79B9_7F4A_7C15;
/// Map errors are drawn among buildings whose bounds come within this distance of the ego route,
/// metres: farther ones would never be seen and the error would not be tested.
const ERROR_BUILDING_REACH_M: f64 = 40.0;

/// Spacing of the samples of the ego's lane that parked cars keep clear of, metres.
const EGO_LANE_SAMPLE_M: f64 = 0.5;

/// One simulated scan and when it was taken.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Index from 0.
    pub index: usize,
    /// The scan (time, returns, truth of returns, true and estimated sensor pose).
    pub scan: Scan,
}

/// A drive in progress.
#[derive(Debug)]
pub struct Drive {
    scenario: Scenario,
    world: World,
    pipeline_map: LocalMap,
    net: RoadNetwork,
    actors: Vec<Actor>,
    ego_id: u32,
    traffic_rng: StdRng,
    sensor_rng: StdRng,
    next_index: usize,
}

/// Widest map a drive is simulated on, metres. The world's spatial indexes and the truth cover
/// the map's whole extent; 50 km holds any city extract, and a continent-wide map (a GeoJSON
/// line across the globe once needed a 2.7 TB index) is refused instead.
pub const MAX_MAP_SPAN_M: f64 = 50_000.0;

/// Checks that a drive can be simulated on `map` at all: its extent is at most
/// [`MAX_MAP_SPAN_M`] across. Tools call it before any work; [`Drive::new`] calls it too.
///
/// # Errors
/// [`SimError::MapTooLarge`].
pub fn check_map_span(map: &LocalMap) -> Result<(), SimError> {
    let (width_m, height_m) = (map.extent.width(), map.extent.height());
    // `!(<=)` also refuses a non-finite extent.
    if width_m <= MAX_MAP_SPAN_M && height_m <= MAX_MAP_SPAN_M {
        Ok(())
    } else {
        Err(SimError::MapTooLarge {
            width_m,
            height_m,
            max_m: MAX_MAP_SPAN_M,
        })
    }
}

impl Drive {
    /// Builds a drive on `map`: the world is the map's buildings and roads, populated as the
    /// scenario says, with its map errors applied (the pipeline gets [`Drive::pipeline_map`]).
    ///
    /// # Errors
    /// [`SimError::InvalidScenario`] for a bad scenario, [`SimError::MapTooLarge`] for a map
    /// wider than [`MAX_MAP_SPAN_M`], [`SimError::NoRoads`] when the map has no
    /// road wide enough to drive on, [`SimError::NoEgoRoute`] when the waypoints cannot be joined.
    pub fn new(map: &LocalMap, scenario: &Scenario) -> Result<Self, SimError> {
        scenario.validate()?;
        check_map_span(map)?;
        let mut world = World::from_polygons(&map.buildings, &map.roads, &map.extent);
        let mut net = RoadNetwork::new(&world);
        if net.anchor_count() == 0 {
            return Err(SimError::NoRoads {
                road_polygons: map.roads.len(),
            });
        }
        let mut traffic_rng = StdRng::seed_from_u64(scenario.seed);
        let ego_route = ego_route(&net, scenario, &mut traffic_rng)?;
        net.set_focus(&ego_route.path, scenario.traffic.spawn_within_m);
        // The ego keeps its gaps from its sensor when that sits beyond its bumper (the IBEO's
        // mount), and no car starts where the ego or its sensor is.
        let mut ego = Actor::driving_car(u32::MAX, &ego_route, 0.0, scenario.ego.speed_mps, false)
            .with_front_reach(scenario.sensor.mount_forward());
        // Parked cars leave the ego's lane free: one standing in it would hold the ego for the
        // rest of the drive.
        let mut actors = actors::populate(
            &net,
            &scenario.traffic,
            &[ego.clearance()],
            &ego.lane_samples(EGO_LANE_SAMPLE_M),
            &mut traffic_rng,
        );
        let ego_id = actors.len() as u32;
        ego.id = ego_id;
        actors.push(ego);

        // Map errors, on the buildings nearest the ego route.
        let errors = &scenario.errors;
        let near = buildings_near_route(&world, &ego_route.path, ERROR_BUILDING_REACH_M);
        let missing: Vec<usize> = near
            .iter()
            .copied()
            .take(errors.missing_buildings)
            .collect();
        let phantom: Vec<usize> = near
            .iter()
            .copied()
            .skip(errors.missing_buildings)
            .take(errors.phantom_buildings)
            .collect();
        for &id in &missing {
            world.set_mapped(id, false);
        }
        let offset = Vec2::new(errors.map_offset_m[0], errors.map_offset_m[1]);
        let pipeline_map = pipeline_map(&world, map, offset);
        if !phantom.is_empty() {
            // Rebuild the world without the phantoms (ids change; nothing refers to them yet).
            let kept = world
                .buildings()
                .iter()
                .enumerate()
                .filter(|(id, _)| !phantom.contains(id))
                .map(|(_, b)| b.clone())
                .collect();
            world = World::new(kept, world.roads().to_vec(), world.extent());
        }
        Ok(Self {
            scenario: scenario.clone(),
            world,
            pipeline_map,
            net,
            actors,
            ego_id,
            traffic_rng,
            sensor_rng: StdRng::seed_from_u64(scenario.seed ^ SENSOR_STREAM),
            next_index: 0,
        })
    }

    /// The scenario.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }
    /// The world as it is (phantom buildings removed, missing ones still there).
    pub fn world(&self) -> &World {
        &self.world
    }
    /// The map handed to the perception pipeline (missing buildings left out, phantom buildings
    /// kept, everything shifted by the scenario's map offset).
    pub fn pipeline_map(&self) -> &LocalMap {
        &self.pipeline_map
    }
    /// All actors, the ego included (its id is [`Drive::ego_id`]).
    pub fn actors(&self) -> &[Actor] {
        &self.actors
    }
    /// Id of the ego in [`Drive::actors`].
    pub fn ego_id(&self) -> u32 {
        self.ego_id
    }

    /// The sensor's true pose now: the ego's, moved to the mount.
    fn world_from_sensor(&self) -> Pose2 {
        let mount = Pose2::new(Vec2::new(self.scenario.sensor.mount_forward(), 0.0), 0.0);
        self.ego_pose().compose(&mount)
    }

    /// `world_from_ego` now.
    pub fn ego_pose(&self) -> Pose2 {
        self.actors
            .get(self.ego_id as usize)
            .map(|a| a.pose)
            .unwrap_or_default()
    }
    /// Scan period, seconds.
    pub fn dt_s(&self) -> f64 {
        1.0 / self.scenario.sensor.rate_hz
    }
    /// Number of frames the drive has in total.
    pub fn frame_count(&self) -> usize {
        self.scenario.frame_count()
    }

    /// The next scan, or `None` after the last frame. The first frame is taken at t = 0; each
    /// later one first moves every actor by one scan period.
    pub fn next_frame(&mut self) -> Option<Frame> {
        if self.next_index >= self.frame_count() {
            return None;
        }
        if self.next_index > 0 {
            self.advance();
        }
        let index = self.next_index;
        self.next_index += 1;
        let world_from_sensor = self.world_from_sensor();
        let mut scan = sensor::scan(
            &self.scenario.sensor,
            &self.world,
            &self.actors,
            Some(self.ego_id),
            world_from_sensor,
            &mut self.sensor_rng,
        );
        scan.time_s = index as f64 * self.dt_s();
        scan.world_from_sensor_estimated = self.noisy(world_from_sensor);
        Some(Frame { index, scan })
    }

    /// The actors the sensor cannot see now: the ego, and any other whose footprint holds the
    /// sensor (placement and the ego's gaps keep that from happening, see `actors::populate`).
    fn unseen(&self) -> Vec<u32> {
        let sensor = self.world_from_sensor().position_m;
        self.actors
            .iter()
            .filter(|a| a.id == self.ego_id || a.footprint.contains(&a.pose, sensor))
            .map(|a| a.id)
            .collect()
    }

    /// Truth labels of `window` now (see [`truth::label_window`]).
    pub fn truth(&self, window: &CellWindow, out: &mut Vec<Label>) {
        truth::label_window(
            &self.world,
            &self.actors,
            &self.unseen(),
            window,
            truth::DEFAULT_SAMPLES_PER_AXIS,
            out,
        );
    }

    /// [`Drive::truth`], and the object outline band in `outline` (see
    /// [`truth::label_window_with_outline`]).
    pub fn truth_with_outline(
        &self,
        window: &CellWindow,
        out: &mut Vec<Label>,
        outline: &mut Vec<bool>,
    ) {
        truth::label_window_with_outline(
            &self.world,
            &self.actors,
            &self.unseen(),
            window,
            truth::DEFAULT_SAMPLES_PER_AXIS,
            out,
            outline,
        );
    }

    /// Truth of `window` now by the centre rule ([`truth::label_window_centre`]): the actors
    /// the sensor cannot see are ignored, and the S cells of the road users in
    /// `never_seen_moving` are flagged (the caller knows what the sensor saw).
    pub fn truth_centre(
        &self,
        window: &CellWindow,
        never_seen_moving: &[u32],
        out: &mut truth::CentreTruth,
    ) {
        let unseen = self.unseen();
        let roles = truth::ActorRoles {
            unseen: &unseen,
            never_seen_moving,
        };
        truth::label_window_centre(&self.world, &self.actors, roles, window, out);
    }

    fn advance(&mut self) {
        let dt = self.dt_s();
        let snapshot = actors::obstacles(&self.actors, &[] as &[Obstacle]);
        for actor in &mut self.actors {
            actors::advance(
                actor,
                &snapshot,
                dt,
                &self.scenario.traffic,
                &self.net,
                &mut self.traffic_rng,
            );
        }
    }

    fn noisy(&mut self, pose: Pose2) -> Pose2 {
        let e = &self.scenario.errors;
        let draw =
            |sigma: f64, rng: &mut StdRng| Normal::new(0.0, sigma).map_or(0.0, |n| n.sample(rng));
        if e.pose_sigma_m == 0.0 && e.pose_sigma_heading_deg == 0.0 {
            return pose;
        }
        let dx = draw(e.pose_sigma_m, &mut self.sensor_rng);
        let dy = draw(e.pose_sigma_m, &mut self.sensor_rng);
        let dh = draw(e.pose_sigma_heading_deg.to_radians(), &mut self.sensor_rng);
        Pose2::new(
            pose.position_m.plus(Vec2::new(dx, dy)),
            pose.heading_rad + dh,
        )
    }
}

/// The ego's route: through the waypoints, or a random one long enough for the drive.
fn ego_route(net: &RoadNetwork, scenario: &Scenario, rng: &mut StdRng) -> Result<Route, SimError> {
    let wps: Vec<Vec2> = scenario
        .ego
        .waypoints
        .iter()
        .map(|w| Vec2::new(w[0], w[1]))
        .collect();
    if wps.len() < 2 {
        let need = scenario.ego.speed_mps * scenario.duration_s + 50.0;
        let start_near = wps.first().copied();
        let route = match start_near {
            Some(p) => net.random_route_from(p, need, need * 3.0, rng),
            None => net.random_route(need, need * 3.0, rng),
        };
        return route.ok_or(SimError::NoEgoRoute { waypoint: 0 });
    }
    let mut points: Vec<Vec2> = Vec::new();
    let mut junctions = Vec::new();
    let mut half_width = f64::INFINITY;
    for (k, pair) in wps.windows(2).enumerate() {
        let leg = net
            .route_between(pair[0], pair[1])
            .ok_or(SimError::NoEgoRoute { waypoint: k + 1 })?;
        let base = Polyline::new(points.clone()).map_or(0.0, |p| p.length_m());
        junctions.extend(leg.junctions_m.iter().map(|s| s + base));
        half_width = half_width.min(leg.half_width_m);
        let skip = usize::from(!points.is_empty());
        points.extend(leg.path.points().iter().skip(skip));
    }
    let path = Polyline::new(points).ok_or(SimError::NoEgoRoute {
        waypoint: wps.len() - 1,
    })?;
    let lane = net.lane_clear_of_buildings(&path, half_width);
    Ok(Route {
        path,
        junctions_m: junctions,
        half_width_m: half_width,
        lane,
    })
}

/// Building ids whose bounds come within `reach_m` of the route (sampled every 2 m), nearest
/// first.
fn buildings_near_route(world: &World, route: &Polyline, reach_m: f64) -> Vec<usize> {
    let n = (route.length_m() / 2.0).ceil() as usize;
    let samples: Vec<Vec2> = (0..=n).map(|k| route.at(k as f64 * 2.0).0).collect();
    let mut scored: Vec<(f64, usize)> = world
        .buildings()
        .iter()
        .enumerate()
        .filter_map(|(id, b)| {
            let d = samples
                .iter()
                .map(|p| {
                    let dx = (b.bounds.0.x - p.x).max(p.x - b.bounds.1.x).max(0.0);
                    let dy = (b.bounds.0.y - p.y).max(p.y - b.bounds.1.y).max(0.0);
                    dx.hypot(dy)
                })
                .fold(f64::INFINITY, f64::min);
            (d <= reach_m).then_some((d, id))
        })
        .collect();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    scored.into_iter().map(|(_, id)| id).collect()
}

/// The map the pipeline sees: mapped buildings of the (unpruned) world, the original roads, all
/// shifted by `offset`.
fn pipeline_map(world: &World, map: &LocalMap, offset: Vec2) -> LocalMap {
    use geo::Translate;
    let buildings = world
        .buildings()
        .iter()
        .filter(|b| b.mapped)
        .map(|b| b.to_polygon(offset))
        .collect();
    let roads = map
        .roads
        .iter()
        .map(|p| p.translate(offset.x, offset.y))
        .collect();
    LocalMap::new(buildings, roads, map.extent.translate(offset.x, offset.y))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::testing::{small_scenario, town};

    fn run(seed: u64) -> (Vec<Frame>, Vec<Vec<Label>>) {
        let mut drive = Drive::new(&town(), &small_scenario(seed)).unwrap();
        let window = CellWindow {
            first_col: 0,
            first_row: 150,
            width: 400,
            height: 100,
            cell_size_m: 0.5,
        };
        let mut frames = Vec::new();
        let mut truths = Vec::new();
        while let Some(f) = drive.next_frame() {
            let mut t = Vec::new();
            drive.truth(&window, &mut t);
            frames.push(f);
            truths.push(t);
        }
        (frames, truths)
    }

    #[test]
    fn same_seed_same_drive_and_different_seed_different_drive() {
        let (fa, ta) = run(11);
        let (fb, tb) = run(11);
        assert_eq!(fa.len(), 50);
        assert_eq!(fa, fb);
        assert_eq!(ta, tb);
        let (fc, tc) = run(12);
        assert!(fa != fc || ta != tc);
    }

    #[test]
    fn ego_drives_its_waypoints_and_scans_see_buildings_and_actors() {
        let mut drive = Drive::new(&town(), &small_scenario(3)).unwrap();
        let start = drive.ego_pose().position_m;
        let mut building_hits = 0;
        let mut actor_hits = 0;
        while let Some(f) = drive.next_frame() {
            for h in &f.scan.hits {
                match h {
                    sensor::HitTarget::Building(_) => building_hits += 1,
                    sensor::HitTarget::Actor(id) => {
                        assert_ne!(*id, drive.ego_id());
                        actor_hits += 1;
                    }
                }
            }
        }
        let end = drive.ego_pose().position_m;
        // Eastward along y ≈ 100 − 1.75 (right lane), about 8 m/s × 4.9 s.
        assert!((end.x - start.x - 39.2).abs() < 2.0, "{start:?} → {end:?}");
        assert!((end.y - 98.25).abs() < 1.5, "{end:?}");
        assert!(
            building_hits > 0 && actor_hits > 0,
            "{building_hits} {actor_hits}"
        );
    }

    #[test]
    fn map_errors_change_the_pipeline_map_not_the_world() {
        let mut s = small_scenario(3);
        s.errors.missing_buildings = 1;
        s.errors.phantom_buildings = 1;
        s.errors.map_offset_m = [1.0, -2.0];
        let drive = Drive::new(&town(), &s).unwrap();
        // World: 4 − 1 phantom = 3 buildings, one of them unmapped.
        assert_eq!(drive.world().buildings().len(), 3);
        assert_eq!(
            drive
                .world()
                .buildings()
                .iter()
                .filter(|b| !b.mapped)
                .count(),
            1
        );
        // Pipeline map: 4 − 1 missing = 3 buildings, shifted.
        let pm = drive.pipeline_map();
        assert_eq!(pm.buildings.len(), 3);
        assert_eq!(pm.extent.min().x, 1.0);
        assert_eq!(pm.extent.min().y, -2.0);
    }

    #[test]
    fn an_object_holding_the_sensor_is_not_scored() {
        let mut drive = Drive::new(&town(), &small_scenario(3)).unwrap();
        let frame = drive.next_frame().unwrap();
        let sensor = frame.scan.world_from_sensor_true.position_m;
        // A car put over the sensor (placement no longer does this): its cells are ignored,
        // like the ego's, and it is the only one besides the ego.
        let other = (0..drive.actors.len() as u32)
            .find(|&id| {
                id != drive.ego_id
                    && drive.actors[id as usize].kind == crate::actors::ActorKind::Car
            })
            .unwrap();
        drive.actors[other as usize].pose = Pose2::new(sensor.plus(Vec2::new(0.0, 0.5)), 0.0);
        assert_eq!(drive.unseen(), vec![other, drive.ego_id]);
        let window = CellWindow {
            first_col: (sensor.x / 0.5).floor() as i64 - 10,
            first_row: (sensor.y / 0.5).floor() as i64 - 10,
            width: 21,
            height: 21,
            cell_size_m: 0.5,
        };
        let mut truth = Vec::new();
        drive.truth(&window, &mut truth);
        assert_eq!(truth[10 * 21 + 10], truth::IGNORED);
        assert!(!truth.contains(&Label::S) && !truth.contains(&Label::M));
    }
}
