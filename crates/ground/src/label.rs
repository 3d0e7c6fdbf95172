//! What the segmentation says about each point, and what it counted.

use std::time::Duration;

use serde::Serialize;

/// The class of one point (SPEC §3's split of a 3-D scan into ground and obstacle returns).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
#[repr(u8)]
pub enum PointLabel {
    /// A return from the ground: within `max_depth_below_ground_m` below and
    /// `min_obstacle_height_m` above the local ground. Free space extends to it.
    Ground,
    /// A return between `min_obstacle_height_m` and `max_obstacle_height_m` above the local
    /// ground: its cell is occupied and the free space of its direction stops before it.
    Obstacle,
    /// Higher than `max_obstacle_height_m` above the local ground (branches, bridges, signs
    /// overhead): not in the way, to be ignored.
    Overhanging,
    /// More than `max_depth_below_ground_m` below the local ground (reflections, noise): to
    /// be ignored.
    BelowGround,
    /// A NaN or infinite coordinate, or a horizontal range outside `min_range_m..=max_range_m`;
    /// also every point when no ground could be found (a [`crate::GroundMethod::GlobalPlane`]
    /// fit that failed). To be ignored.
    #[default]
    Invalid,
}

/// Counts and timing of one segmentation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct GroundStats {
    /// Points in the scan.
    pub points: usize,
    /// Points labelled [`PointLabel::Ground`].
    pub ground: usize,
    /// Points labelled [`PointLabel::Obstacle`].
    pub obstacle: usize,
    /// Points labelled [`PointLabel::Overhanging`].
    pub overhanging: usize,
    /// Points labelled [`PointLabel::BelowGround`].
    pub below_ground: usize,
    /// Points labelled [`PointLabel::Invalid`] for a NaN or infinite coordinate.
    pub non_finite: usize,
    /// Points labelled [`PointLabel::Invalid`] for their range, or because no ground was found.
    pub out_of_range: usize,
    /// Polar cells whose ground candidate was accepted ([`crate::GroundMethod::LocalHeight`]).
    pub ground_cells: usize,
    /// Polar cells whose ground candidate was refused as too high or too low for its
    /// neighbours nearer the sensor ([`crate::GroundMethod::LocalHeight`]).
    pub refused_cells: usize,
    /// Wall-clock time of the segmentation (not deterministic, unlike everything else).
    pub elapsed: Duration,
}

impl GroundStats {
    /// Counts one label.
    pub(crate) fn count(&mut self, label: PointLabel) {
        match label {
            PointLabel::Ground => self.ground += 1,
            PointLabel::Obstacle => self.obstacle += 1,
            PointLabel::Overhanging => self.overhanging += 1,
            PointLabel::BelowGround => self.below_ground += 1,
            PointLabel::Invalid => {}
        }
    }
}

/// The result of one segmentation: a label and a local ground height per input point, in input
/// order, and the stats. Owned by the [`crate::GroundSegmenter`] and overwritten by its next
/// scan.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Segmentation {
    pub(crate) labels: Vec<PointLabel>,
    pub(crate) ground_z_m: Vec<f32>,
    pub(crate) stats: GroundStats,
}

impl Segmentation {
    /// One label per input point, in input order.
    pub fn labels(&self) -> &[PointLabel] {
        &self.labels
    }

    /// The height of the local ground under each point, in input order.
    ///
    /// # Units
    /// Metres along the levelled frame's z axis, relative to the sensor (about −1.73 on a level
    /// road under KITTI's lidar). NaN for [`PointLabel::Invalid`] points.
    pub fn ground_z_m(&self) -> &[f32] {
        &self.ground_z_m
    }

    /// Counts and timing.
    pub fn stats(&self) -> &GroundStats {
        &self.stats
    }

    /// Number of points (of the last scan).
    pub fn len(&self) -> usize {
        self.labels.len()
    }

    /// True when the last scan had no point.
    pub fn is_empty(&self) -> bool {
        self.labels.is_empty()
    }
}
