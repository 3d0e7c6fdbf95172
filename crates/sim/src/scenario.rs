//! Scenario description: what populates the world, how the ego drives, which sensor it carries
//! and which map and localisation errors are injected. Read from TOML; every field has a default,
//! so a file may set any subset.
//!
//! ```toml
//! seed = 7
//! duration_s = 30.0
//! [traffic]
//! moving_cars = 12
//! car_speed_mps = [7.0, 13.0]
//! [ego]
//! speed_mps = 8.0
//! [sensor]
//! kind = "ibeo"          # or "multibeam"
//! [errors]
//! missing_buildings = 1  # buildings in the world but not in the map (truth: U)
//! map_offset_m = [0.5, 0.0]
//! ```

use crate::SimError;
use serde::{Deserialize, Serialize};

/// A whole scenario. By default: 30 s of a 10 Hz IBEO-like scanner on an ego driving at 8 m/s
/// among 12 moving cars, 20 parked cars, 20 pedestrians and 30 pieces of street furniture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Scenario {
    /// Seed of every random choice; the same seed gives the same drive, scans and truth.
    pub seed: u64,
    /// Length of the drive, seconds.
    pub duration_s: f64,
    /// Other road users and street furniture.
    pub traffic: TrafficConfig,
    /// The ego vehicle.
    pub ego: EgoConfig,
    /// The scanner on the ego.
    pub sensor: SensorConfig,
    /// Map and localisation errors.
    pub errors: ErrorConfig,
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            seed: 1,
            duration_s: 30.0,
            traffic: TrafficConfig::default(),
            ego: EgoConfig::default(),
            sensor: SensorConfig::default(),
            errors: ErrorConfig::default(),
        }
    }
}

/// Actors other than the ego. Ranges `[lo, hi]` are sampled uniformly per actor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrafficConfig {
    /// Cars driving along the roads (they stop at junctions and queue).
    pub moving_cars: usize,
    /// Cruise speed of a moving car, m/s. By default 7–13 m/s (25–47 km/h, urban).
    pub car_speed_mps: [f64; 2],
    /// Probability that a car stops at a junction it reaches. By default 0.4.
    pub stop_probability: f64,
    /// How long a car waits at a junction stop, seconds. By default 2–8 s.
    pub stop_duration_s: [f64; 2],
    /// Cars parked along the road edges (and in wide paved areas such as car parks).
    pub parked_cars: usize,
    /// Pedestrians on the pavements.
    pub pedestrians: usize,
    /// Walking speed, m/s. By default 0.9–1.6 m/s.
    pub walking_speed_mps: [f64; 2],
    /// How long a pedestrian walks before standing, seconds. By default 4–15 s.
    pub walk_duration_s: [f64; 2],
    /// How long a pedestrian stands still, seconds. By default 2–10 s.
    pub stand_duration_s: [f64; 2],
    /// Unmapped street furniture on the pavements: poles, trees, bins, bollards.
    pub infrastructure: usize,
    /// Actors are placed on roads within this distance of the ego route, metres (0: anywhere on
    /// the map). By default 150 m, about twice the scanner's range: on a town-sized map the
    /// actors would otherwise mostly be out of sight.
    pub spawn_within_m: f64,
    /// Share of the moving cars that are 12 × 2.55 m city buses, turning on arcs of at least
    /// 9 m (`sim::actors::Body::BUS`); truth as a car's. By default 0.
    pub bus_share: f64,
    /// Share of the moving cars that are rigid trucks, 8–10 m (drawn per truck) × 2.5 m,
    /// turning on arcs of at least 8 m; truth as a car's. By default 0. `bus_share +
    /// truck_share` is at most 1; with both 0 the scene is drawn exactly as before they existed.
    pub truck_share: f64,
}

impl Default for TrafficConfig {
    fn default() -> Self {
        Self {
            moving_cars: 12,
            car_speed_mps: [7.0, 13.0],
            stop_probability: 0.4,
            stop_duration_s: [2.0, 8.0],
            parked_cars: 20,
            pedestrians: 20,
            walking_speed_mps: [0.9, 1.6],
            walk_duration_s: [4.0, 15.0],
            stand_duration_s: [2.0, 10.0],
            infrastructure: 30,
            spawn_within_m: 150.0,
            bus_share: 0.0,
            truck_share: 0.0,
        }
    }
}

/// The ego vehicle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EgoConfig {
    /// Cruise speed, m/s (it slows behind other cars). By default 8 m/s.
    pub speed_mps: f64,
    /// Waypoints in local metres; the route follows the roads through them. Empty: a random route
    /// long enough for the whole drive, drawn from the seed.
    #[serde(deserialize_with = "exact_pairs")]
    pub waypoints: Vec<[f64; 2]>,
}

/// Reads `[[x, y], …]` refusing pairs of any other length: the TOML reader would silently drop a
/// third value (a waypoint given as `[x, y, z]` is a mistake worth naming).
fn exact_pairs<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<[f64; 2]>, D::Error> {
    let rows: Vec<Vec<f64>> = Vec::deserialize(d)?;
    rows.into_iter()
        .enumerate()
        .map(|(k, row)| {
            <[f64; 2]>::try_from(row.as_slice()).map_err(|_| {
                serde::de::Error::custom(format!(
                    "waypoint {k} has {} values, expected [x, y] in metres",
                    row.len()
                ))
            })
        })
        .collect()
}

impl Default for EgoConfig {
    fn default() -> Self {
        Self {
            speed_mps: 8.0,
            waypoints: Vec::new(),
        }
    }
}

/// Which scanner.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScannerKind {
    /// IBEO Alasca/Lux-like: 4 layers, frontal field of view, about 800 points per scan.
    Ibeo,
    /// A 360° multi-beam scanner (Velodyne-like) seen in the plane: `beams` layers all round.
    Multibeam,
}

/// The scanner. By default an IBEO-like 4-layer scanner, 110° field of view, 200 points per layer
/// (800 per scan), 10 Hz, 80 m range, 3 cm range noise, 2 % dropouts, mounted 3.7 m ahead of the
/// ego's centre, as on the paper's vehicle (measured from its rear axle there; here that is 1.45 m
/// beyond the bumper of the 4.5 m car, and the ego keeps its gaps from the sensor).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorConfig {
    /// Scanner type.
    pub kind: ScannerKind,
    /// Number of layers: 4 for `ibeo`, the beam count for `multibeam` (by default 16).
    pub layers: Option<usize>,
    /// Horizontal field of view, degrees (110 for `ibeo`, 360 for `multibeam`).
    pub fov_deg: Option<f64>,
    /// Points per layer per scan (200 for `ibeo`, 900 — 0.4° — for `multibeam`).
    pub points_per_layer: Option<usize>,
    /// Scan rate, Hz. The simulation steps once per scan.
    pub rate_hz: f64,
    /// Maximum range, metres; no return beyond.
    pub max_range_m: f64,
    /// Standard deviation of the Gaussian range noise, metres.
    pub range_noise_m: f64,
    /// Probability that a return is lost.
    pub dropout_probability: f64,
    /// Sensor position ahead of the ego's centre, metres (None: 3.7 m for `ibeo`, 0 for `multibeam`).
    pub mount_forward_m: Option<f64>,
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self {
            kind: ScannerKind::Ibeo,
            layers: None,
            fov_deg: None,
            points_per_layer: None,
            rate_hz: 10.0,
            max_range_m: 80.0,
            range_noise_m: 0.03,
            dropout_probability: 0.02,
            mount_forward_m: None,
        }
    }
}

impl SensorConfig {
    /// Layers after defaults.
    pub fn layer_count(&self) -> usize {
        self.layers.unwrap_or(match self.kind {
            ScannerKind::Ibeo => 4,
            ScannerKind::Multibeam => 16,
        })
    }
    /// Field of view after defaults, radians.
    pub fn fov_rad(&self) -> f64 {
        self.fov_deg
            .unwrap_or(match self.kind {
                ScannerKind::Ibeo => 110.0,
                ScannerKind::Multibeam => 360.0,
            })
            .to_radians()
    }
    /// Points per layer after defaults.
    pub fn points_per_layer_count(&self) -> usize {
        self.points_per_layer.unwrap_or(match self.kind {
            ScannerKind::Ibeo => 200,
            ScannerKind::Multibeam => 900,
        })
    }
    /// Mount offset after defaults, metres.
    pub fn mount_forward(&self) -> f64 {
        self.mount_forward_m.unwrap_or(match self.kind {
            ScannerKind::Ibeo => 3.7,
            ScannerKind::Multibeam => 0.0,
        })
    }
    /// The ground model evigrid's sensor model needs for these scans (SPEC §3): `none` for
    /// every kind, because the simulated world is planar: every return is an obstacle, none
    /// is ground, and a fitted ground plane would have nothing to fit.
    pub fn ground_model(&self) -> evigrid::GroundModel {
        evigrid::GroundModel::None
    }
}

/// Map and localisation errors. By default none.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ErrorConfig {
    /// Buildings near the ego route that exist in the world but are left out of the map handed to
    /// the pipeline. Their truth class is U (unmapped infrastructure).
    pub missing_buildings: usize,
    /// Buildings near the ego route that stay in the map but are removed from the world
    /// (demolished since mapping). Their cells are free in truth.
    pub phantom_buildings: usize,
    /// Shift of the whole map handed to the pipeline, metres (east, north).
    pub map_offset_m: [f64; 2],
    /// Standard deviation of the position error of the estimated sensor pose, metres per axis,
    /// drawn independently each scan.
    pub pose_sigma_m: f64,
    /// Standard deviation of the heading error of the estimated pose, degrees.
    pub pose_sigma_heading_deg: f64,
}

impl Scenario {
    /// Parses a scenario from TOML and validates it.
    ///
    /// # Errors
    /// [`SimError::ScenarioToml`] for malformed TOML or unknown keys, [`SimError::InvalidScenario`]
    /// for out-of-range values.
    pub fn from_toml(text: &str) -> Result<Self, SimError> {
        let s: Scenario = toml::from_str(text).map_err(|e| SimError::ScenarioToml {
            message: e.to_string(),
        })?;
        s.validate()?;
        Ok(s)
    }

    /// Checks every value is in range.
    ///
    /// # Errors
    /// [`SimError::InvalidScenario`] naming the first offending field and its value.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |field: &'static str, value: f64| Err(SimError::InvalidScenario { field, value });
        let t = &self.traffic;
        let s = &self.sensor;
        let e = &self.errors;
        let positive: [(&'static str, f64); 4] = [
            ("duration_s", self.duration_s),
            ("sensor.rate_hz", s.rate_hz),
            ("sensor.max_range_m", s.max_range_m),
            ("sensor.fov_deg", s.fov_rad().to_degrees()),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, v);
            }
        }
        let non_negative: [(&'static str, f64); 7] = [
            ("ego.speed_mps", self.ego.speed_mps),
            ("traffic.spawn_within_m", t.spawn_within_m),
            ("sensor.range_noise_m", s.range_noise_m),
            ("errors.pose_sigma_m", e.pose_sigma_m),
            ("errors.pose_sigma_heading_deg", e.pose_sigma_heading_deg),
            ("errors.map_offset_m[0]", e.map_offset_m[0].abs()),
            ("errors.map_offset_m[1]", e.map_offset_m[1].abs()),
        ];
        for (field, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return bad(field, v);
            }
        }
        for (field, v) in [
            ("traffic.stop_probability", t.stop_probability),
            ("traffic.bus_share", t.bus_share),
            ("traffic.truck_share", t.truck_share),
            (
                "traffic.bus_share + traffic.truck_share",
                t.bus_share + t.truck_share,
            ),
            ("sensor.dropout_probability", s.dropout_probability),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return bad(field, v);
            }
        }
        for (field, r) in [
            ("traffic.car_speed_mps", t.car_speed_mps),
            ("traffic.stop_duration_s", t.stop_duration_s),
            ("traffic.walking_speed_mps", t.walking_speed_mps),
            ("traffic.walk_duration_s", t.walk_duration_s),
            ("traffic.stand_duration_s", t.stand_duration_s),
        ] {
            if !(r[0].is_finite() && r[1].is_finite() && r[0] >= 0.0 && r[1] >= r[0]) {
                return bad(field, if r[0] < 0.0 { r[0] } else { r[1] });
            }
        }
        if s.layer_count() == 0 || s.layer_count() > 256 {
            return bad("sensor.layers", s.layer_count() as f64);
        }
        if s.points_per_layer_count() == 0 || s.points_per_layer_count() > 100_000 {
            return bad("sensor.points_per_layer", s.points_per_layer_count() as f64);
        }
        if let Some(m) = s.mount_forward_m
            && !m.is_finite()
        {
            return bad("sensor.mount_forward_m", m);
        }
        if let Some(w) = self.ego.waypoints.iter().flatten().find(|v| !v.is_finite()) {
            return bad("ego.waypoints", *w);
        }
        self.check_limits()
    }

    /// Upper bounds: a hostile or mistyped scenario (`duration_s = 1e9`, `moving_cars = 1e9`)
    /// must be refused, not simulated for days.
    fn check_limits(&self) -> Result<(), SimError> {
        const RUN_TIME: &str = "the drive would run for hours";
        const MEMORY: &str = "the scan or world would not fit in memory";
        const PHYSICS: &str = "not a road vehicle or a lidar";
        let (t, s, e) = (&self.traffic, &self.sensor, &self.errors);
        let count = |n: usize| n as f64;
        let limits: [(&'static str, f64, f64, &'static str); 17] = [
            (
                "duration_s x sensor.rate_hz (frames)",
                self.duration_s * s.rate_hz,
                100_000.0,
                RUN_TIME,
            ),
            ("sensor.rate_hz", s.rate_hz, 100.0, PHYSICS),
            ("sensor.max_range_m", s.max_range_m, 1_000.0, PHYSICS),
            (
                "sensor.layers x sensor.points_per_layer",
                count(s.layer_count()) * count(s.points_per_layer_count()),
                4_000_000.0,
                MEMORY,
            ),
            (
                "traffic.moving_cars",
                count(t.moving_cars),
                10_000.0,
                RUN_TIME,
            ),
            (
                "traffic.parked_cars",
                count(t.parked_cars),
                10_000.0,
                RUN_TIME,
            ),
            (
                "traffic.pedestrians",
                count(t.pedestrians),
                10_000.0,
                RUN_TIME,
            ),
            (
                "traffic.infrastructure",
                count(t.infrastructure),
                10_000.0,
                RUN_TIME,
            ),
            ("traffic.spawn_within_m", t.spawn_within_m, 50_000.0, MEMORY),
            ("traffic.car_speed_mps", t.car_speed_mps[1], 100.0, PHYSICS),
            (
                "traffic.walking_speed_mps",
                t.walking_speed_mps[1],
                20.0,
                PHYSICS,
            ),
            ("ego.speed_mps", self.ego.speed_mps, 100.0, PHYSICS),
            (
                "ego.waypoints (count)",
                count(self.ego.waypoints.len()),
                10_000.0,
                RUN_TIME,
            ),
            (
                "errors.missing_buildings",
                count(e.missing_buildings),
                100_000.0,
                RUN_TIME,
            ),
            (
                "errors.phantom_buildings",
                count(e.phantom_buildings),
                100_000.0,
                RUN_TIME,
            ),
            (
                "errors.map_offset_m",
                e.map_offset_m[0].hypot(e.map_offset_m[1]),
                1_000.0,
                PHYSICS,
            ),
            ("errors.pose_sigma_m", e.pose_sigma_m, 100.0, PHYSICS),
        ];
        for (field, value, max, why) in limits {
            if value > max {
                return Err(SimError::ScenarioLimit {
                    field,
                    value,
                    max,
                    why,
                });
            }
        }
        Ok(())
    }

    /// Number of scans in the drive.
    pub fn frame_count(&self) -> usize {
        (self.duration_s * self.sensor.rate_hz).round().max(0.0) as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partial_toml_keeps_defaults() -> Result<(), SimError> {
        let s = Scenario::from_toml(
            "seed = 9\n[traffic]\nmoving_cars = 3\n[sensor]\nkind = \"multibeam\"\n",
        )?;
        assert_eq!(s.seed, 9);
        assert_eq!(s.traffic.moving_cars, 3);
        assert_eq!(s.traffic.parked_cars, 20);
        assert_eq!(s.sensor.layer_count(), 16);
        assert!((s.sensor.fov_rad() - std::f64::consts::TAU).abs() < 1e-12);
        assert_eq!(s.frame_count(), 300);
        Ok(())
    }

    #[test]
    fn bad_values_are_named() {
        let err = Scenario::from_toml("[traffic]\nstop_probability = 1.5\n");
        assert!(matches!(
            err,
            Err(SimError::InvalidScenario { field: "traffic.stop_probability", value }) if value == 1.5
        ));
        assert!(matches!(
            Scenario::from_toml("colour = 1\n"),
            Err(SimError::ScenarioToml { .. })
        ));
        assert!(matches!(
            Scenario::from_toml("duration_s = -1.0\n"),
            Err(SimError::InvalidScenario {
                field: "duration_s",
                ..
            })
        ));
    }

    #[test]
    fn scenarios_that_would_run_for_days_are_refused() {
        // The reproducers of issue 15: each ran forever.
        for (text, field) in [
            ("duration_s = 1e9\n", "duration_s x sensor.rate_hz (frames)"),
            (
                "[sensor]\nrate_hz = 1e6\n",
                "duration_s x sensor.rate_hz (frames)",
            ),
            (
                "[traffic]\nmoving_cars = 1000000000\n",
                "traffic.moving_cars",
            ),
            (
                "[sensor]\nlayers = 256\npoints_per_layer = 100000\n",
                "sensor.layers x sensor.points_per_layer",
            ),
        ] {
            match Scenario::from_toml(text) {
                Err(SimError::ScenarioLimit { field: f, .. }) => assert_eq!(f, field, "{text}"),
                other => panic!("{text}: {other:?}"),
            }
        }
        let message = Scenario::from_toml("[traffic]\nmoving_cars = 1000000000\n")
            .err()
            .map(|e| e.to_string());
        assert_eq!(
            message.as_deref(),
            Some(
                "scenario: traffic.moving_cars = 1000000000 is over the limit of 10000 (the drive \
                 would run for hours)"
            )
        );
    }

    #[test]
    fn a_waypoint_with_three_values_is_refused() {
        let result = Scenario::from_toml("[ego]\nwaypoints = [[1.0, 2.0], [1.0, 2.0, 3.0]]\n");
        let message = result.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(message.contains("waypoint 1 has 3 values"), "{message}");
    }
}
