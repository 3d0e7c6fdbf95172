//! sim: simulated drives with per-cell ground truth, to evaluate evigrid on.
//!
//! **What.** A planar world built from a real map (buildings and road surface from
//! [`geodata::LocalMap`]), populated with cars that drive their lanes (corners rounded by arcs
//! of at least 5 m radius, slowing for them; `scenarios/README.md`), stop at junctions and
//! queue, parked cars, pedestrians who walk and stand, and unmapped street furniture; a
//! simulated IBEO-like 4-layer or 360° multi-beam scanner with exact ray casting; and per-cell
//! ground truth in the perception grid's classes {F, I, U, S, M} ([`Label`], the one label
//! type of truth and predictions). Scoring methods against that truth is the `evigrid-eval`
//! crate's business.
//!
//! **Why.** The paper's method (Kurdej et al. 2013) needs a benchmark with per-cell truth of
//! *moving* vs *stopped* vs *infrastructure*, which no public lidar data set gives together with
//! an OpenStreetMap prior. Simulation on real maps gives it, with map and localisation errors on
//! demand.
//!
//! **Key design decision.** Everything is deterministic for a seed: one seeded random stream for
//! traffic, another for sensor noise, actors updated in id order from a snapshot, no hash-map
//! iteration. Truth is computed on demand for any window, so memory does not grow with the drive.
//!
//! ```
//! use sim::{Drive, Scenario};
//! use geo::{coord, polygon, Rect};
//! // One 10 m wide east–west street with a house beside it.
//! let street = polygon![(x: 0.0, y: 45.0), (x: 200.0, y: 45.0), (x: 200.0, y: 55.0), (x: 0.0, y: 55.0)];
//! let house = polygon![(x: 90.0, y: 60.0), (x: 110.0, y: 60.0), (x: 110.0, y: 75.0), (x: 90.0, y: 75.0)];
//! let map = geodata::LocalMap::new(vec![house], vec![street],
//!     Rect::new(coord! { x: 0.0, y: 0.0 }, coord! { x: 200.0, y: 100.0 }));
//! let scenario = Scenario::from_toml("seed = 3\nduration_s = 1.0\n[ego]\nwaypoints = [[5.0, 50.0], [195.0, 50.0]]\n")?;
//! let mut drive = Drive::new(&map, &scenario)?;
//! let frame = drive.next_frame().expect("a 1 s drive has 10 frames");
//! assert!(frame.scan.points_in_sensor.len() > 100);
//! # Ok::<(), sim::SimError>(())
//! ```

#![deny(missing_docs)]

pub mod actors;
pub mod drive;
pub mod geometry;
pub mod label;
pub mod roadnet;
pub mod scenario;
pub mod sensor;
pub mod testing;
pub mod truth;
pub mod world;

pub use drive::{Drive, Frame};
pub use label::Label;
pub use scenario::Scenario;

/// Errors of the simulator.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// The scenario file is not valid TOML or has unknown keys.
    #[error("scenario TOML: {message}")]
    ScenarioToml {
        /// The parser's message.
        message: String,
    },
    /// A scenario value is out of range.
    #[error("scenario: {field} = {value} is out of range")]
    InvalidScenario {
        /// The offending field.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A scenario value is beyond what a simulated drive can be asked for (it would run for
    /// days or exhaust memory).
    #[error("scenario: {field} = {value} is over the limit of {max} ({why})")]
    ScenarioLimit {
        /// The offending field (or the quantity derived from fields).
        field: &'static str,
        /// Its value.
        value: f64,
        /// The largest value accepted.
        max: f64,
        /// What the limit protects.
        why: &'static str,
    },
    /// The map has no road wide enough to drive on.
    #[error("the map has no drivable road ({road_polygons} road polygons)")]
    NoRoads {
        /// Road polygons in the map.
        road_polygons: usize,
    },
    /// The map is too large for a simulated world (its indexes cover the whole extent).
    #[error(
        "the map spans {width_m:.0} m x {height_m:.0} m; simulated drives need a map at most \
         {max_m:.0} m across (cut one out with `evigrid map crop`)"
    )]
    MapTooLarge {
        /// East–west extent, metres.
        width_m: f64,
        /// North–south extent, metres.
        height_m: f64,
        /// [`drive::MAX_MAP_SPAN_M`].
        max_m: f64,
    },
    /// The ego route cannot reach a waypoint along the roads.
    #[error("no road route to ego waypoint {waypoint}")]
    NoEgoRoute {
        /// Index of the waypoint that cannot be reached.
        waypoint: usize,
    },
}
