//! A small synthetic town and a short drive through it, for tests and examples that need a map
//! without reading files.
//!
//! ```
//! use sim::Drive;
//! use sim::testing::{small_scenario, town};
//! let mut drive = Drive::new(&town(), &small_scenario(3))?;
//! assert_eq!(drive.frame_count(), 50);
//! assert!(drive.next_frame().is_some());
//! # Ok::<(), sim::SimError>(())
//! ```

use crate::scenario::Scenario;
use geo::{Rect, coord, polygon};
use geodata::LocalMap;

/// A small town: two crossing 10 m streets, four 20 × 20 m buildings in the corners, 200 m
/// square (local frame from (0, 0)).
pub fn town() -> LocalMap {
    let rect = |x0: f64, y0: f64, x1: f64, y1: f64| polygon![(x: x0, y: y0), (x: x1, y: y0), (x: x1, y: y1), (x: x0, y: y1)];
    LocalMap::new(
        vec![
            rect(70.0, 70.0, 90.0, 90.0),
            rect(110.0, 70.0, 130.0, 90.0),
            rect(70.0, 110.0, 90.0, 130.0),
            rect(110.0, 110.0, 130.0, 130.0),
        ],
        vec![rect(0.0, 95.0, 200.0, 105.0), rect(95.0, 0.0, 105.0, 200.0)],
        Rect::new(coord! { x: 0.0, y: 0.0 }, coord! { x: 200.0, y: 200.0 }),
    )
}

/// Five seconds east along the east–west street of [`town`], with four moving cars, four parked
/// cars, four pedestrians and six pieces of street furniture.
pub fn small_scenario(seed: u64) -> Scenario {
    let mut s = Scenario {
        seed,
        duration_s: 5.0,
        ..Scenario::default()
    };
    s.traffic.moving_cars = 4;
    s.traffic.parked_cars = 4;
    s.traffic.pedestrians = 4;
    s.traffic.infrastructure = 6;
    s.ego.waypoints = vec![[5.0, 100.0], [195.0, 100.0]];
    s
}

/// The corners of the axis-aligned rectangle from (`x0`, `y0`) to (`x1`, `y1`), anticlockwise:
/// a ring for the roads and buildings of worlds that tests build by hand.
#[cfg(test)]
pub(crate) fn rect_ring(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<crate::geometry::Vec2> {
    use crate::geometry::Vec2;
    vec![
        Vec2::new(x0, y0),
        Vec2::new(x1, y0),
        Vec2::new(x1, y1),
        Vec2::new(x0, y1),
    ]
}
