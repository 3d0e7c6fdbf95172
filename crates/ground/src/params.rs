//! Parameters of the ground segmentation, their defaults and their validation.

use serde::{Deserialize, Serialize};

/// Largest number of angular sectors: 0.1° each. More gives cells too thin to hold a point.
pub const MAX_SECTORS: usize = 3600;
/// Largest number of rings the zones may produce, so that a typo cannot allocate gigabytes.
pub const MAX_RINGS: usize = 4096;
/// Largest number of polar cells (sectors × rings): about 50 MB of scratch. The defaults use
/// 10,080.
pub const MAX_CELLS: usize = 1 << 20;

/// How the ground under each point is found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum GroundMethod {
    /// A local ground height per polar cell, propagated outward from the sensor under a slope
    /// and step limit (this crate's method; see the crate documentation).
    #[default]
    LocalHeight,
    /// One plane per scan, fitted by RANSAC and least squares: the sensor model's historical
    /// ground model, kept to compare against. Its sample depends on the point order.
    GlobalPlane,
    /// A level ground `sensor_height_m` below the sensor everywhere.
    FixedHeight,
}

/// A band of rings of equal width, from `from_m` (horizontal range from the sensor) to the next
/// zone's `from_m` or to `max_range_m`.
///
/// Rings widen with range because the returns of a spinning lidar on the ground thin out with
/// the square of the range (the concentric zones of Patchwork, Lim et al. 2021).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RingZone {
    /// Where the zone starts, metres of horizontal range.
    pub from_m: f64,
    /// Radial width of each ring of the zone, metres.
    pub ring_width_m: f64,
}

/// Parameters of [`crate::GroundSegmenter`]. Every field has a default; a TOML section may set
/// any subset (`#[serde(default)]`).
///
/// Heights are metres along the levelled frame's z axis (up), ranges metres of horizontal
/// distance from the sensor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GroundParams {
    /// How the ground is found. By default [`GroundMethod::LocalHeight`].
    pub method: GroundMethod,
    /// Height of the sensor above the ground under the vehicle, metres: the prior every sector
    /// starts from. By default 1.73 m, KITTI's Velodyne HDL-64E (Geiger et al. 2013).
    pub sensor_height_m: f64,
    /// How far the ground next to the vehicle may lie from `sensor_height_m` below the sensor,
    /// metres (load, pitch, a road's crown). By default 0.3 m.
    pub sensor_height_tolerance_m: f64,
    /// Points nearer than this (horizontal range) are [`crate::PointLabel::Invalid`]: the
    /// vehicle's own body and zero returns. By default 2.0 m, as the sensor model's
    /// `min_range_m`.
    pub min_range_m: f64,
    /// Points farther than this are [`crate::PointLabel::Invalid`]. By default 80 m, past the
    /// useful range of an HDL-64E on the ground.
    pub max_range_m: f64,
    /// Number of equal angular sectors around the sensor. By default 180 (2° each); 90 and 360
    /// measured the same on the KITTI scans (crate documentation).
    pub sectors: usize,
    /// Ring layout, by increasing `from_m`; the first zone must start at 0. By default 0.5 m
    /// rings to 10 m, 1 m to 20 m and 2 m beyond (4 m beyond 40 m changed nothing on the KITTI
    /// scans, and let a far ramp's cell mix two beams' heights).
    pub ring_zones: Vec<RingZone>,
    /// Steepest ground gradient (rise over run) the local ground may follow between two
    /// cells. By default 0.2 (11.3°): a 10° ramp is followed, a car's windscreen is not.
    pub max_slope: f64,
    /// Steepest gradient the local ground may have where it was not seen: from the vehicle to
    /// its first ground cell, and across more than 2 m between two ground cells (behind a
    /// parked car, between far beams). By default 0.06 (6 %, a steep urban street); see the
    /// crate documentation for what it trades.
    pub max_slope_unseen: f64,
    /// Highest step the local ground may take at once on top of the slope, metres: a kerb.
    /// By default 0.2 m (kerbs are 0.10–0.18 m high).
    pub max_step_m: f64,
    /// The lowest points of a cell, up to this much above its lowest point, make its ground
    /// candidate, metres. By default 0.1 m (the HDL-64E's range noise is about 2 cm).
    pub seed_band_m: f64,
    /// Lowest height above the local ground of an obstacle point, metres: lower points are
    /// ground. By default 0.3 m, as the sensor model's `min_obstacle_height_m`.
    pub min_obstacle_height_m: f64,
    /// Highest height above the local ground of an obstacle point, metres: higher points
    /// (branches, bridges) are [`crate::PointLabel::Overhanging`]. By default 2.5 m, as the
    /// sensor model's `max_obstacle_height_m`.
    pub max_obstacle_height_m: f64,
    /// Points more than this below the local ground are [`crate::PointLabel::BelowGround`]
    /// (reflections, noise), metres. By default 0.3 m.
    pub max_depth_below_ground_m: f64,
    /// Half-thickness of the band around the plane whose points the plane is fitted to
    /// ([`GroundMethod::GlobalPlane`] only), metres. By default 0.2 m, as the sensor model's
    /// `ground_band_m`.
    pub plane_band_m: f64,
}

impl Default for GroundParams {
    fn default() -> Self {
        Self {
            method: GroundMethod::LocalHeight,
            sensor_height_m: 1.73,
            sensor_height_tolerance_m: 0.3,
            min_range_m: 2.0,
            max_range_m: 80.0,
            sectors: 180,
            ring_zones: vec![
                RingZone {
                    from_m: 0.0,
                    ring_width_m: 0.5,
                },
                RingZone {
                    from_m: 10.0,
                    ring_width_m: 1.0,
                },
                RingZone {
                    from_m: 20.0,
                    ring_width_m: 2.0,
                },
            ],
            max_slope: 0.2,
            max_slope_unseen: 0.06,
            max_step_m: 0.2,
            seed_band_m: 0.1,
            min_obstacle_height_m: 0.3,
            max_obstacle_height_m: 2.5,
            max_depth_below_ground_m: 0.3,
            plane_band_m: 0.2,
        }
    }
}

/// Why a [`GroundParams`] was refused. Every variant names the parameter, as in a TOML file's
/// `[ground]` section.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GroundParamsError {
    /// The value must be positive and finite.
    #[error("ground.{name} = {value} must be a positive finite number")]
    NotPositive {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The value must be zero or positive, and finite.
    #[error("ground.{name} = {value} must be a finite number >= 0")]
    Negative {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// Two parameters must be strictly ordered.
    #[error("ground.{low_name} = {low} must be below ground.{high_name} = {high}")]
    Misordered {
        /// The parameter that must be lower.
        low_name: &'static str,
        /// Its value.
        low: f64,
        /// The parameter that must be higher.
        high_name: &'static str,
        /// Its value.
        high: f64,
    },
    /// A count is outside its range.
    #[error("ground.{name} = {value} must lie in {min}..={max}")]
    CountOutOfRange {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: usize,
        /// Smallest accepted value.
        min: usize,
        /// Largest accepted value.
        max: usize,
    },
    /// Sectors × rings exceed [`MAX_CELLS`].
    #[error("ground.sectors × rings = {sectors} × {rings} exceeds {max} cells")]
    TooManyCells {
        /// Sectors.
        sectors: usize,
        /// Rings the zones make.
        rings: usize,
        /// [`MAX_CELLS`].
        max: usize,
    },
    /// The ring zones are empty, do not start at 0, are not increasing, or make too many rings.
    #[error("ground.ring_zones: {reason}")]
    RingZones {
        /// What is wrong.
        reason: String,
    },
}

impl GroundParams {
    /// Checks every parameter's range.
    ///
    /// # Errors
    /// The first offending parameter: [`GroundParamsError::NotPositive`] for a non-positive
    /// sensor height, range, ring width or band; [`GroundParamsError::Negative`] for a negative
    /// tolerance, slope or step; [`GroundParamsError::Misordered`] for empty range or obstacle
    /// bands; [`GroundParamsError::CountOutOfRange`] for `sectors`;
    /// [`GroundParamsError::RingZones`] for a bad ring layout; [`GroundParamsError::TooManyCells`].
    pub fn validate(&self) -> Result<(), GroundParamsError> {
        positive("sensor_height_m", self.sensor_height_m)?;
        non_negative("sensor_height_tolerance_m", self.sensor_height_tolerance_m)?;
        non_negative("min_range_m", self.min_range_m)?;
        positive("max_range_m", self.max_range_m)?;
        ordered(
            ("min_range_m", self.min_range_m),
            ("max_range_m", self.max_range_m),
        )?;
        if !(1..=MAX_SECTORS).contains(&self.sectors) {
            return Err(GroundParamsError::CountOutOfRange {
                name: "sectors",
                value: self.sectors,
                min: 1,
                max: MAX_SECTORS,
            });
        }
        non_negative("max_slope", self.max_slope)?;
        non_negative("max_slope_unseen", self.max_slope_unseen)?;
        non_negative("max_step_m", self.max_step_m)?;
        non_negative("seed_band_m", self.seed_band_m)?;
        non_negative("min_obstacle_height_m", self.min_obstacle_height_m)?;
        positive("max_obstacle_height_m", self.max_obstacle_height_m)?;
        ordered(
            ("min_obstacle_height_m", self.min_obstacle_height_m),
            ("max_obstacle_height_m", self.max_obstacle_height_m),
        )?;
        non_negative("max_depth_below_ground_m", self.max_depth_below_ground_m)?;
        positive("plane_band_m", self.plane_band_m)?;
        let rings = self.ring_edges_m()?.len() - 1;
        if self.sectors * rings > MAX_CELLS {
            return Err(GroundParamsError::TooManyCells {
                sectors: self.sectors,
                rings,
                max: MAX_CELLS,
            });
        }
        Ok(())
    }

    /// The ring edges from `min_range_m` to `max_range_m`, increasing: ring `k` spans
    /// `edges[k]..edges[k + 1]`.
    ///
    /// # Errors
    /// [`GroundParamsError::RingZones`] if the zones are empty, the first does not start at 0,
    /// `from_m` does not increase, a width is not positive and finite, or there would be more
    /// than [`MAX_RINGS`] rings.
    pub fn ring_edges_m(&self) -> Result<Vec<f64>, GroundParamsError> {
        let zones = &self.ring_zones;
        let bad = |reason: String| Err(GroundParamsError::RingZones { reason });
        match zones.first() {
            None => return bad("no zone".into()),
            Some(z) if z.from_m != 0.0 => {
                return bad(format!("the first zone starts at {} m, not 0", z.from_m));
            }
            Some(_) => {}
        }
        for (k, z) in zones.iter().enumerate() {
            if !(z.ring_width_m > 0.0 && z.ring_width_m.is_finite()) {
                return bad(format!("zone {k}: ring_width_m = {}", z.ring_width_m));
            }
            if k > 0 && !(z.from_m > zones[k - 1].from_m && z.from_m.is_finite()) {
                return bad(format!("zone {k}: from_m = {} does not increase", z.from_m));
            }
        }
        // Edges are multiples of each zone's width from its start, cut where the next zone
        // begins, then clipped to the useful range.
        let (min_m, max_m) = (self.min_range_m, self.max_range_m);
        let mut edges = vec![min_m];
        for (k, z) in zones.iter().enumerate() {
            let end_m = zones
                .get(k + 1)
                .map_or(max_m, |next| next.from_m)
                .min(max_m);
            let start_m = z.from_m.max(min_m);
            if end_m <= start_m {
                continue;
            }
            let first = ((start_m - z.from_m) / z.ring_width_m).floor() + 1.0;
            let last = ((end_m - z.from_m) / z.ring_width_m).ceil();
            // Counted before the loop: a tiny width must be refused, not looped over.
            let count = last - first;
            if !(count.is_finite() && count < MAX_RINGS as f64)
                || edges.len() + count as usize > MAX_RINGS
            {
                return bad(format!("more than {MAX_RINGS} rings"));
            }
            let mut j = first;
            while j <= last {
                let edge = (z.from_m + j * z.ring_width_m).min(end_m);
                if edge > edges[edges.len() - 1] {
                    edges.push(edge);
                }
                j += 1.0;
            }
        }
        if edges.len() < 2 {
            return bad("no ring between min_range_m and max_range_m".into());
        }
        Ok(edges)
    }
}

fn positive(name: &'static str, value: f64) -> Result<(), GroundParamsError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(GroundParamsError::NotPositive { name, value })
    }
}

fn non_negative(name: &'static str, value: f64) -> Result<(), GroundParamsError> {
    if value >= 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(GroundParamsError::Negative { name, value })
    }
}

fn ordered(
    (low_name, low): (&'static str, f64),
    (high_name, high): (&'static str, f64),
) -> Result<(), GroundParamsError> {
    if low < high {
        Ok(())
    } else {
        Err(GroundParamsError::Misordered {
            low_name,
            low,
            high_name,
            high,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_valid() {
        assert_eq!(GroundParams::default().validate(), Ok(()));
    }

    #[test]
    fn default_rings_follow_the_zones() {
        let edges = GroundParams::default().ring_edges_m().expect("valid zones");
        // 2.0..10 by 0.5 (16 rings), 10..20 by 1 (10), 20..80 by 2 (30).
        assert_eq!(edges.len(), 16 + 10 + 30 + 1);
        assert_eq!(edges[0], 2.0);
        assert_eq!(edges[1], 2.5);
        assert_eq!(edges[16], 10.0);
        assert_eq!(edges[17], 11.0);
        assert_eq!(*edges.last().expect("edges"), 80.0);
        assert!(edges.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn a_range_inside_a_ring_starts_the_first_ring_there() {
        let params = GroundParams {
            min_range_m: 2.7,
            max_range_m: 4.2,
            ..GroundParams::default()
        };
        assert_eq!(
            params.ring_edges_m().expect("valid"),
            vec![2.7, 3.0, 3.5, 4.0, 4.2]
        );
    }

    #[test]
    fn errors_name_the_parameter() {
        let bad = |p: GroundParams| p.validate().expect_err("must be refused").to_string();
        let d = GroundParams::default;
        let msg = bad(GroundParams {
            sensor_height_m: f64::NAN,
            ..d()
        });
        assert!(msg.contains("ground.sensor_height_m"), "{msg}");
        let msg = bad(GroundParams {
            min_obstacle_height_m: 3.0,
            ..d()
        });
        assert!(msg.contains("ground.min_obstacle_height_m = 3"), "{msg}");
        assert!(msg.contains("ground.max_obstacle_height_m = 2.5"), "{msg}");
        let msg = bad(GroundParams { sectors: 0, ..d() });
        assert!(msg.contains("ground.sectors = 0"), "{msg}");
        let msg = bad(GroundParams {
            max_slope: -0.1,
            ..d()
        });
        assert!(msg.contains("ground.max_slope"), "{msg}");
        let msg = bad(GroundParams {
            max_range_m: 1.0,
            ..d()
        });
        assert!(msg.contains("ground.min_range_m"), "{msg}");
        let msg = bad(GroundParams {
            ring_zones: vec![],
            ..d()
        });
        assert!(msg.contains("ground.ring_zones"), "{msg}");
        let msg = bad(GroundParams {
            ring_zones: vec![RingZone {
                from_m: 0.0,
                ring_width_m: 1e-6,
            }],
            ..d()
        });
        assert!(msg.contains("rings"), "{msg}");
        let msg = bad(GroundParams {
            ring_zones: vec![
                RingZone {
                    from_m: 0.0,
                    ring_width_m: 1.0,
                },
                RingZone {
                    from_m: 0.0,
                    ring_width_m: 2.0,
                },
            ],
            ..d()
        });
        assert!(msg.contains("zone 1"), "{msg}");
        let msg = bad(GroundParams {
            sectors: 3600,
            ring_zones: vec![RingZone {
                from_m: 0.0,
                ring_width_m: 0.1,
            }],
            ..d()
        });
        assert!(msg.contains("3600 × 780"), "{msg}");
    }
}
