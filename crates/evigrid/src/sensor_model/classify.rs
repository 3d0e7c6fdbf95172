//! Points into sectors: each levelled point is told ground, obstacle or neither; every sector
//! keeps the range of its farthest ground return, and every return its cell, sector and range.

use ground::PointLabel;

use crate::window::Window;
use ground::GroundPlane;

/// Points classified per parallel task: enough that a task's per-sector arrays cost little.
pub(super) const CLASSIFY_CHUNK: usize = 8192;

/// How the points of a scan are told apart: ground (within the band of the fitted plane, or
/// labelled so by the local ground model), obstacle (within the obstacle heights above the
/// plane, labelled so, or every point without a ground model) or neither.
pub(super) struct PointClassifier<'a> {
    pub(super) plane: Option<&'a GroundPlane>,
    pub(super) ground_band_m: f64,
    pub(super) obstacle_heights_m: std::ops::RangeInclusive<f64>,
    pub(super) sectors: usize,
    pub(super) sectors_per_radian: f64,
    pub(super) window: &'a Window,
    pub(super) sensor_xy: (f64, f64),
    /// How far along its ray, m, a return is moved before its placed cell is taken
    /// ([`SensorModel::set_return_depth_m`](super::SensorModel::set_return_depth_m)); 0: its own.
    pub(super) return_depth_m: f64,
    /// Fine sectors of the surface placement (`surface::sector_count`), 0 without it.
    pub(super) fine_sectors: usize,
}

/// What one chunk of points gives.
#[derive(Clone, Debug, Default)]
pub(super) struct Classified {
    pub(super) ground_points: usize,
    pub(super) unclassified_points: usize,
    pub(super) dropped_outside_window: usize,
    /// Farthest ground return per sector.
    pub(super) ground_range: Vec<f64>,
    /// (cell, sector, range) of each ground and each obstacle return in the window. Obstacle
    /// returns are kept apart because a cell's count decides whether they count at all.
    pub(super) ground_cells: Vec<(usize, u32, f64)>,
    pub(super) obstacle_cells: Vec<(usize, u32, f64)>,
    /// Per obstacle return, in the order of `obstacle_cells`: its placed cell, the cell of the
    /// return moved `return_depth_m` further along its ray (`None` outside the window).
    pub(super) placed_cells: Vec<Option<usize>>,
    /// Per obstacle return, in the order of `obstacle_cells`: its levelled position (east and
    /// north of the sensor), m.
    pub(super) obstacle_xy: Vec<[f64; 2]>,
    /// Per obstacle return, in the order of `obstacle_cells`: its fine sector of the surface
    /// placement ([`fine_sector_at`], from the bearing its sector was found by);
    /// empty without the surface placement.
    pub(super) obstacle_fine_sector: Vec<u32>,
}

impl PointClassifier<'_> {
    /// Notes a ground return: its sector's farthest ground range and its cell.
    fn ground_return(&self, q: [f64; 3], out: &mut Classified) {
        out.ground_points += 1;
        let s = sector_of(q, self.sectors_per_radian, self.sectors);
        let range_m = horizontal_range(q);
        out.ground_range[s] = out.ground_range[s].max(range_m);
        let (sensor_x, sensor_y) = self.sensor_xy;
        if let Some(idx) = self
            .window
            .storage_index_of_point(sensor_x + q[0], sensor_y + q[1])
        {
            out.ground_cells.push((idx, s as u32, range_m));
        }
    }

    /// The cell of the obstacle return `q` (levelled, in cell `idx`, `range_m` from the sensor)
    /// moved `return_depth_m` further along its horizontal ray: the cell whose centre lies
    /// behind the surface the return came from.
    fn placed_cell(&self, q: [f64; 3], range_m: f64, idx: usize) -> Option<usize> {
        if self.return_depth_m == 0.0 || range_m == 0.0 {
            return Some(idx);
        }
        let scale = 1.0 + self.return_depth_m / range_m;
        let (sensor_x, sensor_y) = self.sensor_xy;
        self.window
            .storage_index_of_point(sensor_x + q[0] * scale, sensor_y + q[1] * scale)
    }

    /// Classifies `points` into `out`, whose buffers are cleared and reused.
    pub(super) fn chunk(
        &self,
        points: &[[f64; 3]],
        labels: Option<&[PointLabel]>,
        out: &mut Classified,
    ) {
        out.ground_points = 0;
        out.unclassified_points = 0;
        out.dropped_outside_window = 0;
        out.ground_range.clear();
        out.ground_range.resize(self.sectors, 0.0);
        out.ground_cells.clear();
        out.obstacle_cells.clear();
        out.placed_cells.clear();
        out.obstacle_xy.clear();
        out.obstacle_fine_sector.clear();
        let (sensor_x, sensor_y) = self.sensor_xy;
        for (i, &q) in points.iter().enumerate() {
            let is_obstacle = match (labels, self.plane) {
                (Some(labels), _) => match labels.get(i) {
                    Some(PointLabel::Ground) => {
                        self.ground_return(q, out);
                        continue;
                    }
                    Some(PointLabel::Obstacle) => true,
                    _ => false,
                },
                (None, None) => true,
                (None, Some(plane)) => {
                    let h = plane.height_of(q);
                    if h.abs() <= self.ground_band_m {
                        self.ground_return(q, out);
                        continue;
                    }
                    self.obstacle_heights_m.contains(&h)
                }
            };
            if !is_obstacle {
                out.unclassified_points += 1;
                continue;
            }
            match self
                .window
                .storage_index_of_point(sensor_x + q[0], sensor_y + q[1])
            {
                Some(idx) => {
                    // One bearing for both sectors (the fine one was computed twice more, by
                    // the surface table and the placed grid).
                    let bearing = bearing(q);
                    let s = sector_at(bearing, self.sectors_per_radian, self.sectors);
                    let range_m = horizontal_range(q);
                    out.obstacle_cells.push((idx, s as u32, range_m));
                    out.placed_cells.push(self.placed_cell(q, range_m, idx));
                    out.obstacle_xy.push([q[0], q[1]]);
                    if self.fine_sectors > 0 {
                        out.obstacle_fine_sector
                            .push(fine_sector_at(bearing, self.fine_sectors) as u32);
                    }
                }
                None => out.dropped_outside_window += 1,
            }
        }
    }
}

/// Horizontal distance from the sensor. (`f64::hypot` guards against overflow we cannot have
/// here, at several times the cost.)
#[inline]
pub(super) fn horizontal_range(q: [f64; 3]) -> f64 {
    (q[0] * q[0] + q[1] * q[1]).sqrt()
}

/// Sector of a levelled point by its bearing, `atan2(y, x)` measured from −π.
#[inline]
pub(super) fn sector_of(q: [f64; 3], sectors_per_radian: f64, sectors: usize) -> usize {
    sector_at(bearing(q), sectors_per_radian, sectors)
}

/// Bearing of a levelled point, `atan2(y, x)` measured from −π: what [`sector_of`] and
/// `surface::sector_of` divide.
#[inline]
pub(super) fn bearing(q: [f64; 3]) -> f64 {
    fast_atan2(q[1], q[0]) + std::f64::consts::PI
}

/// [`sector_of`] of the bearing `angle` ([`bearing`]).
#[inline]
fn sector_at(angle: f64, sectors_per_radian: f64, sectors: usize) -> usize {
    // `as usize` saturates: a tiny negative angle gives sector 0.
    ((angle * sectors_per_radian) as usize).min(sectors - 1)
}

/// The fine sector of the surface placement (`surface::sector_of`) of the bearing
/// `angle` ([`bearing`]), of `sectors`.
#[inline]
pub(super) fn fine_sector_at(angle: f64, sectors: usize) -> usize {
    ((angle * sectors as f64 / std::f64::consts::TAU) as usize).min(sectors.saturating_sub(1))
}

/// `atan2(y, x)` within 1e-7 rad: octant reduction and a fitted polynomial for atan on
/// [0, 1]. Sector assignment only needs a small fraction of a sector's width, and this is
/// several times faster than the libm call on 100k points per scan.
#[inline]
pub(super) fn fast_atan2(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (num, den) = if ay > ax { (ax, ay) } else { (ay, ax) };
    if den == 0.0 {
        return 0.0;
    }
    let z = num / den;
    let z2 = z * z;
    // atan(z) ≈ z·P(z²) on [0, 1]: a degree-15 odd polynomial, least-squares fitted on
    // Chebyshev nodes (maximum error 4e-8 rad).
    const C: [f64; 8] = [
        0.999_999_438_324_601_7,
        -0.333_301_127_400_456_2,
        0.199_485_768_955_586_34,
        -0.139_161_315_520_430_1,
        0.096_570_694_736_276_69,
        -0.056_073_881_742_006_86,
        0.021_953_772_647_316_73,
        -0.004_075_223_254_295_879,
    ];
    let mut poly = C[7];
    for c in C[..7].iter().rev() {
        poly = poly * z2 + c;
    }
    let mut a = z * poly;
    if ay > ax {
        a = FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    if y < 0.0 { -a } else { a }
}
