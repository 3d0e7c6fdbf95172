//! The segmenter: owns the parameters, the polar layout and every buffer, reused across scans.

use std::time::Instant;

use rayon::prelude::*;

use crate::label::{GroundStats, PointLabel, Segmentation};
use crate::local::{CellProfile, LocalHeight};
use crate::params::{GroundMethod, GroundParams, GroundParamsError};
use crate::plane::{GroundPlane, PlaneFitter};
use crate::polar::{NO_CELL, PolarLayout};

/// Points per parallel task: large enough that scheduling costs little, small enough that two
/// cores share a scan evenly.
const CHUNK: usize = 16 * 1024;

/// Splits lidar scans into ground and obstacle points (SPEC §3) with one of the
/// [`GroundMethod`]s; keeps its buffers between scans, so that a drive allocates only on its
/// first scan.
///
/// Deterministic: the same scan gives the same labels whatever the number of rayon threads;
/// with [`GroundMethod::LocalHeight`] also whatever the order of the points.
#[derive(Clone, Debug)]
pub struct GroundSegmenter {
    params: GroundParams,
    layout: PolarLayout,
    /// Cell of each point ([`NO_CELL`] if invalid) and its horizontal range.
    cell: Vec<u32>,
    range_m: Vec<f32>,
    local: LocalHeight,
    plane: PlaneFitter,
    out: Segmentation,
}

/// The ground model one scan was labelled against.
#[derive(Clone, Copy)]
enum Ground<'a> {
    Profiles(&'a [CellProfile]),
    Plane(GroundPlane),
    Level(f32),
    Unknown,
}

impl GroundSegmenter {
    /// A segmenter with these parameters.
    ///
    /// # Errors
    /// The first invalid parameter, as [`GroundParams::validate`] finds it.
    pub fn new(params: GroundParams) -> Result<Self, GroundParamsError> {
        params.validate()?;
        let layout = PolarLayout::new(&params)?;
        Ok(Self {
            params,
            layout,
            cell: Vec::new(),
            range_m: Vec::new(),
            local: LocalHeight::default(),
            plane: PlaneFitter::default(),
            out: Segmentation::default(),
        })
    }

    /// The parameters in use.
    pub fn params(&self) -> &GroundParams {
        &self.params
    }

    /// Labels every point of one scan and finds the ground height under it.
    ///
    /// `points_levelled` are in the *levelled* frame: origin at the sensor, z up along gravity,
    /// x and y horizontal (any heading), metres. Any input is accepted: a point with a NaN or
    /// infinite coordinate, or out of the range limits, is [`PointLabel::Invalid`].
    ///
    /// The result lives in the segmenter until the next call.
    pub fn segment(&mut self, points_levelled: &[[f32; 3]]) -> &Segmentation {
        let start = Instant::now();
        let n = points_levelled.len();
        self.bin(points_levelled);
        let mut stats = GroundStats {
            points: n,
            ..GroundStats::default()
        };
        for (p, &c) in points_levelled.iter().zip(&self.cell) {
            if c == NO_CELL {
                if p.iter().all(|v| v.is_finite()) {
                    stats.out_of_range += 1;
                } else {
                    stats.non_finite += 1;
                }
            }
        }
        let ground = match self.params.method {
            GroundMethod::LocalHeight => {
                let counts = self.local.fit(
                    &self.layout,
                    &self.params,
                    points_levelled,
                    &self.cell,
                    &self.range_m,
                );
                stats.ground_cells = counts.accepted;
                stats.refused_cells = counts.refused;
                Ground::Profiles(&self.local.profile)
            }
            GroundMethod::GlobalPlane => {
                let valid = || {
                    points_levelled
                        .iter()
                        .zip(&self.cell)
                        .filter(|(_, c)| **c != NO_CELL)
                        .map(|(p, _)| p.map(f64::from))
                };
                match self.plane.fit_with(valid, self.params.plane_band_m) {
                    Some(plane) => Ground::Plane(plane),
                    None => Ground::Unknown,
                }
            }
            GroundMethod::FixedHeight => Ground::Level(-self.params.sensor_height_m as f32),
        };
        let out = &mut self.out;
        out.labels.clear();
        out.labels.resize(n, PointLabel::Invalid);
        out.ground_z_m.clear();
        out.ground_z_m.resize(n, f32::NAN);
        let thresholds = Thresholds::new(&self.params);
        points_levelled
            .par_chunks(CHUNK)
            .zip(self.cell.par_chunks(CHUNK))
            .zip(self.range_m.par_chunks(CHUNK))
            .zip(out.labels.par_chunks_mut(CHUNK))
            .zip(out.ground_z_m.par_chunks_mut(CHUNK))
            .for_each(|((((points, cells), ranges), labels), ground_z)| {
                for i in 0..points.len() {
                    let (label, z) =
                        label_point(points[i], cells[i], ranges[i], ground, &thresholds);
                    labels[i] = label;
                    ground_z[i] = z;
                }
            });
        if matches!(ground, Ground::Unknown) {
            // No ground at all: every valid point is counted with the out-of-range ones.
            stats.out_of_range = n - stats.non_finite;
        }
        for &label in &out.labels {
            stats.count(label);
        }
        stats.elapsed = start.elapsed();
        out.stats = stats;
        &self.out
    }

    /// Fills the cell and the horizontal range of every point.
    fn bin(&mut self, points: &[[f32; 3]]) {
        let n = points.len();
        self.cell.clear();
        self.cell.resize(n, NO_CELL);
        self.range_m.clear();
        self.range_m.resize(n, f32::NAN);
        let layout = &self.layout;
        points
            .par_chunks(CHUNK)
            .zip(self.cell.par_chunks_mut(CHUNK))
            .zip(self.range_m.par_chunks_mut(CHUNK))
            .for_each(|((points, cells), ranges)| {
                for i in 0..points.len() {
                    let p = points[i];
                    if !p.iter().all(|v| v.is_finite()) {
                        continue;
                    }
                    if let Some((c, r)) = layout.cell_of(p) {
                        cells[i] = c;
                        ranges[i] = r;
                    }
                }
            });
    }
}

/// The height bands of the labels, in `f32` like the points.
struct Thresholds {
    min_obstacle_m: f32,
    max_obstacle_m: f32,
    max_depth_m: f32,
}

impl Thresholds {
    fn new(params: &GroundParams) -> Self {
        Self {
            min_obstacle_m: params.min_obstacle_height_m as f32,
            max_obstacle_m: params.max_obstacle_height_m as f32,
            max_depth_m: params.max_depth_below_ground_m as f32,
        }
    }

    /// The label of a point `height_m` above the ground (negative below).
    #[inline]
    fn label(&self, height_m: f32) -> PointLabel {
        if height_m < -self.max_depth_m {
            PointLabel::BelowGround
        } else if height_m < self.min_obstacle_m {
            PointLabel::Ground
        } else if height_m <= self.max_obstacle_m {
            PointLabel::Obstacle
        } else if height_m.is_nan() {
            PointLabel::Invalid
        } else {
            PointLabel::Overhanging
        }
    }
}

/// Label and ground height of one point.
#[inline]
fn label_point(
    p: [f32; 3],
    cell: u32,
    range_m: f32,
    ground: Ground<'_>,
    thresholds: &Thresholds,
) -> (PointLabel, f32) {
    if cell == NO_CELL {
        return (PointLabel::Invalid, f32::NAN);
    }
    match ground {
        Ground::Profiles(profiles) => match profiles.get(cell as usize) {
            Some(profile) => {
                let z = profile.z_at(range_m);
                (thresholds.label(p[2] - z), z)
            }
            None => (PointLabel::Invalid, f32::NAN),
        },
        Ground::Plane(plane) => {
            let q = [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])];
            let z = plane.z_at(q[0], q[1]) as f32;
            // Along the normal, as the sensor model measures it.
            (thresholds.label(plane.height_of(q) as f32), z)
        }
        Ground::Level(z) => (thresholds.label(p[2] - z), z),
        Ground::Unknown => (PointLabel::Invalid, f32::NAN),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_follow_the_height_bands() {
        let t = Thresholds::new(&GroundParams::default());
        assert_eq!(t.label(-0.31), PointLabel::BelowGround);
        assert_eq!(t.label(-0.3), PointLabel::Ground);
        assert_eq!(t.label(0.0), PointLabel::Ground);
        assert_eq!(t.label(0.29), PointLabel::Ground);
        assert_eq!(t.label(0.3), PointLabel::Obstacle);
        assert_eq!(t.label(2.5), PointLabel::Obstacle);
        assert_eq!(t.label(2.51), PointLabel::Overhanging);
        assert_eq!(t.label(f32::INFINITY), PointLabel::Overhanging);
        assert_eq!(t.label(f32::NEG_INFINITY), PointLabel::BelowGround);
        assert_eq!(t.label(f32::NAN), PointLabel::Invalid);
    }

    #[test]
    fn buffers_are_reused_across_scans() {
        let mut segmenter = GroundSegmenter::new(GroundParams::default()).expect("defaults");
        let big: Vec<[f32; 3]> = (0..1000)
            .map(|i| [5.0 + 0.01 * i as f32, 0.0, -1.73])
            .collect();
        segmenter.segment(&big);
        let capacity = segmenter.cell.capacity();
        let result = segmenter.segment(&big[..10]);
        assert_eq!(result.len(), 10);
        assert_eq!(segmenter.cell.capacity(), capacity);
    }

    #[test]
    fn invalid_params_are_refused_by_name() {
        let err = GroundSegmenter::new(GroundParams {
            seed_band_m: -1.0,
            ..GroundParams::default()
        })
        .expect_err("refused");
        assert!(err.to_string().contains("ground.seed_band_m"), "{err}");
    }
}
