//! The polar grid around the sensor: equal angular sectors, rings that widen with range.

use crate::params::{GroundParams, GroundParamsError};

/// Entries of the pseudo-angle → sector table: 4096 per quadrant, a step of at most 0.02°, far
/// finer than any sector.
const TABLE_PER_QUADRANT: usize = 4096;

/// Marks a point that is in no cell (invalid).
pub(crate) const NO_CELL: u32 = u32::MAX;

/// Cells of a polar grid, numbered `sector * rings + ring`, ring 0 nearest the sensor.
#[derive(Clone, Debug)]
pub(crate) struct PolarLayout {
    sectors: usize,
    /// Ring edges, increasing, `rings + 1` of them, from `min_range_m` to `max_range_m`.
    edges_m: Vec<f32>,
    /// Sector of each step of the pseudo-angle: no trigonometry per point.
    sector_of_pseudo_angle: Vec<u16>,
}

impl PolarLayout {
    /// The layout of `params` (which must be valid).
    ///
    /// # Errors
    /// Those of [`GroundParams::ring_edges_m`].
    pub(crate) fn new(params: &GroundParams) -> Result<Self, GroundParamsError> {
        let edges_m: Vec<f32> = params
            .ring_edges_m()?
            .into_iter()
            .map(|e| e as f32)
            .collect();
        let sectors = params.sectors.clamp(1, crate::params::MAX_SECTORS);
        let sector_of_pseudo_angle = (0..4 * TABLE_PER_QUADRANT)
            .map(|t| {
                // The angle at the middle of table step t, from the pseudo-angle's definition.
                let p = (t as f64 + 0.5) / TABLE_PER_QUADRANT as f64;
                let quadrant = p.floor();
                let f = p - quadrant;
                let angle = f.atan2(1.0 - f) + quadrant * std::f64::consts::FRAC_PI_2;
                let s = (angle / std::f64::consts::TAU * sectors as f64).floor() as usize;
                s.min(sectors - 1) as u16
            })
            .collect();
        Ok(Self {
            sectors,
            edges_m,
            sector_of_pseudo_angle,
        })
    }

    pub(crate) fn sectors(&self) -> usize {
        self.sectors
    }

    pub(crate) fn rings(&self) -> usize {
        self.edges_m.len() - 1
    }

    pub(crate) fn cells(&self) -> usize {
        self.sectors * self.rings()
    }

    /// Inner edge of ring `ring`, metres.
    pub(crate) fn ring_start_m(&self, ring: usize) -> f32 {
        self.edges_m[ring]
    }

    /// Ring holding horizontal range `range_m`, or `None` outside `min_range_m..=max_range_m`
    /// (NaN included).
    #[inline]
    pub(crate) fn ring_of(&self, range_m: f32) -> Option<usize> {
        let (first, last) = (self.edges_m[0], self.edges_m[self.edges_m.len() - 1]);
        if !(range_m >= first && range_m <= last) {
            return None;
        }
        // Index of the first edge above the range, minus one; the outer edge belongs to the
        // last ring.
        let above = self.edges_m.partition_point(|&e| e <= range_m);
        Some(above.saturating_sub(1).min(self.rings() - 1))
    }

    /// Sector of the horizontal direction `(x, y)`, counter-clockwise from +x; `(0, 0)` gives
    /// sector 0.
    #[inline]
    pub(crate) fn sector_of(&self, x: f32, y: f32) -> usize {
        let t = (pseudo_angle(x, y) * TABLE_PER_QUADRANT as f32) as usize;
        let t = t.min(self.sector_of_pseudo_angle.len() - 1);
        usize::from(self.sector_of_pseudo_angle[t])
    }

    /// Cell of a finite point and its horizontal range, or `None` when out of range.
    #[inline]
    pub(crate) fn cell_of(&self, p: [f32; 3]) -> Option<(u32, f32)> {
        let range_m = (p[0] * p[0] + p[1] * p[1]).sqrt();
        let ring = self.ring_of(range_m)?;
        let cell = self.sector_of(p[0], p[1]) * self.rings() + ring;
        Some((cell as u32, range_m))
    }
}

/// A number in `[0, 4)` that grows with the direction's angle from +x, counter-clockwise, one
/// unit per quadrant: `y / (|x| + |y|)` folded per quadrant. One division, no trigonometry.
#[inline]
fn pseudo_angle(x: f32, y: f32) -> f32 {
    let sum = x.abs() + y.abs();
    if !(sum.is_finite() && sum > 0.0) {
        return 0.0;
    }
    let (x, y) = (x / sum, y / sum);
    // In each quadrant the point (x, y) on the diamond |x| + |y| = 1 is rotated into the first
    // quadrant, where its y is the fraction of the quadrant.
    if y >= 0.0 {
        if x > 0.0 { y } else { 1.0 - x }
    } else if x < 0.0 {
        2.0 - y
    } else {
        3.0 + x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout(sectors: usize) -> PolarLayout {
        PolarLayout::new(&GroundParams {
            sectors,
            ..GroundParams::default()
        })
        .expect("valid params")
    }

    #[test]
    fn sectors_follow_the_angle() {
        let l = layout(360);
        for deg in 0..360 {
            let a = (f64::from(deg) + 0.5).to_radians();
            let (x, y) = ((10.0 * a.cos()) as f32, (10.0 * a.sin()) as f32);
            assert_eq!(l.sector_of(x, y), deg as usize, "{deg}°");
        }
        // Degenerate directions do not panic.
        assert_eq!(l.sector_of(0.0, 0.0), 0);
        assert_eq!(l.sector_of(f32::MAX, f32::MAX), 0);
        assert!(l.sector_of(-f32::MIN_POSITIVE, -1e-30) < 360);
    }

    #[test]
    fn rings_follow_the_range() {
        let l = layout(180);
        assert_eq!(l.ring_of(1.9), None);
        assert_eq!(l.ring_of(f32::NAN), None);
        assert_eq!(l.ring_of(80.1), None);
        assert_eq!(l.ring_of(2.0), Some(0));
        assert_eq!(l.ring_of(2.49), Some(0));
        assert_eq!(l.ring_of(2.5), Some(1));
        assert_eq!(l.ring_of(10.5), Some(16));
        assert_eq!(l.ring_of(80.0), Some(l.rings() - 1));
        assert_eq!(l.cell_of([f32::INFINITY, 0.0, 0.0]), None);
        assert_eq!(l.cell_of([1e30, 1e30, 0.0]), None);
    }
}
