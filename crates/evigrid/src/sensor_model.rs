//! The sensor model: one lidar scan becomes a SensorGrid on Ω_SG = {F, O} (SPEC §3, after Moras
//! et al., ICRA 2011).
//!
//! The scan's points are moved into a *levelled* frame — world axes, origin at the sensor — with
//! the sensor's pose. They are split into obstacle and ground points: for a planar or multi-layer
//! scanner every return is an obstacle ([`GroundModel::None`]); for a 3-D lidar a ground plane is
//! fitted to the scan ([`GroundModel::Plane`]: RANSAC with a fixed seed, then least squares on the
//! inliers) and obstacle points are those between `min_obstacle_height_m` and
//! `max_obstacle_height_m` above it, ground points those within `ground_band_m` of it.
//!
//! Around the sensor the plane is cut into angular sectors of `angular_resolution_deg`. Each
//! sector keeps only two numbers, the range of its nearest obstacle return and that of its
//! farthest ground return, so the cost of the free space does not grow with the number of
//! points: rays walk the world-fixed window cell by cell (Amanatides & Woo's exact traversal) up
//! to that range, enough rays per sector that neighbouring rays are less than a cell apart at
//! their far end. Then every obstacle point marks its own cell occupied, which also settles the
//! SPEC §3 decision that a cell both crossed and holding a return is occupied.
//!
//! Free cells are those a ray crosses *entirely* before the first obstacle range ("strictly
//! before"); where a sector has no obstacle, the cells it enters before its farthest ground
//! return (that return's own cell included: the ground was seen there).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::grids::SensorGrid;
use crate::params::SensorParams;
use crate::window::Window;

/// How a scan's points are split into obstacle and ground points (SPEC §3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GroundModel {
    /// Planar or multi-layer scanner: every return is an obstacle; there are no ground returns.
    None,
    /// 3-D lidar: fit a ground plane to each scan; obstacles lie between the obstacle heights
    /// above it, ground returns within the ground band of it.
    #[default]
    Plane,
}

/// A rigid transform in 3-D (rotation then translation), in `f64`.
///
/// Named by what it maps, as `world_from_sensor`: `world_from_sensor.transform_point(p_sensor)`
/// gives the point in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Isometry3 {
    /// Rotation matrix, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Translation, metres: where the source frame's origin lies in the target frame.
    pub translation: [f64; 3],
}

impl Isometry3 {
    /// The identity transform.
    pub const IDENTITY: Self = Self {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation: [0.0; 3],
    };

    /// From a position (metres) and roll, pitch, yaw (radians) in the ROS convention: rotations
    /// about the fixed x, y, z axes in that order, so `R = Rz(yaw) · Ry(pitch) · Rx(roll)`.
    pub fn from_xyz_rpy(x_m: f64, y_m: f64, z_m: f64, roll: f64, pitch: f64, yaw: f64) -> Self {
        let (sr, cr) = roll.sin_cos();
        let (sp, cp) = pitch.sin_cos();
        let (sy, cy) = yaw.sin_cos();
        Self {
            rotation: [
                [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                [-sp, cp * sr, cp * cr],
            ],
            translation: [x_m, y_m, z_m],
        }
    }

    /// Rotates a vector (no translation).
    #[inline]
    pub fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [
            r[0][0] * v[0] + r[0][1] * v[1] + r[0][2] * v[2],
            r[1][0] * v[0] + r[1][1] * v[1] + r[1][2] * v[2],
            r[2][0] * v[0] + r[2][1] * v[1] + r[2][2] * v[2],
        ]
    }

    /// Maps a point: `R · p + t`.
    #[inline]
    pub fn transform_point(&self, p: [f64; 3]) -> [f64; 3] {
        let v = self.rotate(p);
        [
            v[0] + self.translation[0],
            v[1] + self.translation[1],
            v[2] + self.translation[2],
        ]
    }

    /// True if every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.rotation
            .iter()
            .flatten()
            .chain(&self.translation)
            .all(|v| v.is_finite())
    }
}

/// A plane `{p : normal · p = offset_m}` in the levelled frame (world axes, sensor origin).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GroundPlane {
    /// Unit normal, pointing up (positive z).
    pub normal: [f64; 3],
    /// Signed distance of the plane from the sensor along the normal, metres: about −1.73 m for
    /// a lidar 1.73 m above a level road.
    pub offset_m: f64,
    /// Points of the scan within the ground band of the plane.
    pub inliers: usize,
}

impl GroundPlane {
    /// Height of a point above the plane, metres (negative below it).
    #[inline]
    pub fn height_of(&self, p: [f64; 3]) -> f64 {
        self.normal[0] * p[0] + self.normal[1] * p[1] + self.normal[2] * p[2] - self.offset_m
    }
}

/// What became of one scan's points and cells.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SensorStats {
    /// Points in the scan.
    pub points: usize,
    /// Points dropped because a coordinate was NaN or infinite.
    pub dropped_non_finite: usize,
    /// Points dropped because their horizontal distance from the sensor is below `min_range_m`
    /// (the vehicle's own body, invalid zero returns) or beyond `max_range_m`.
    pub dropped_out_of_range: usize,
    /// Obstacle points whose cell lies outside the window.
    pub dropped_outside_window: usize,
    /// Points used as obstacle returns.
    pub obstacle_points: usize,
    /// Points used as ground returns.
    pub ground_points: usize,
    /// Finite points in range that are neither: below the ground band, between the band and the
    /// lowest obstacle height, above the highest obstacle height, or every point when no ground
    /// plane could be fitted.
    pub unclassified_points: usize,
    /// Cells given m(F) = μ_F.
    pub free_cells: usize,
    /// Cells given m(O) = μ_O.
    pub occupied_cells: usize,
    /// The fitted ground plane ([`GroundModel::Plane`] only; `None` if no plane was found).
    pub ground_plane: Option<GroundPlane>,
}

/// Builds SensorGrids from scans; keeps its scratch buffers between scans.
#[derive(Clone, Debug)]
pub struct SensorModel {
    params: SensorParams,
    /// Points in the levelled frame (world axes, sensor origin), kept between scans.
    levelled: Vec<[f64; 3]>,
    /// Horizontal range of the nearest obstacle per sector (∞ if none).
    obstacle_range: Vec<f64>,
    /// Horizontal range of the farthest ground return per sector (0 if none).
    ground_range: Vec<f64>,
    /// What each chunk of the current scan's points gave, in point order; kept between scans
    /// so that the chunks' buffers are not allocated again.
    classified: Vec<Classified>,
    /// Indices of the ground plane's inliers (scratch of the fit).
    inliers: Vec<usize>,
}

/// Fixed RANSAC seed: the same scan always gives the same plane.
const RANSAC_SEED: u64 = 0x5EED_0F61_2000_0000;
/// RANSAC hypotheses per scan. With half the sample on the road, a hypothesis is all-ground with
/// probability 1/8, so 100 of them all miss with probability (7/8)^100 ≈ 2e-6.
const RANSAC_ITERATIONS: usize = 100;
/// Points drawn (evenly, by stride) from the scan to score hypotheses.
const RANSAC_SAMPLE: usize = 2048;
/// Ground candidates lie within this horizontal range: the road near the vehicle is the plane
/// we want, far points are sparse and curve with the terrain.
const GROUND_FIT_RANGE_M: f64 = 30.0;
/// A ground plane tilted more than this from level is refused (a wall, a car's side).
const MAX_GROUND_TILT_DEG: f64 = 20.0;
/// Fewer ground inliers than this: no plane.
const MIN_GROUND_INLIERS: usize = 50;

impl SensorModel {
    /// A sensor model with these parameters (read from the `[sensor]` section).
    pub fn new(params: SensorParams) -> Self {
        Self {
            params,
            levelled: Vec::new(),
            obstacle_range: Vec::new(),
            ground_range: Vec::new(),
            classified: Vec::new(),
            inliers: Vec::new(),
        }
    }

    /// The parameters in use.
    pub fn params(&self) -> &SensorParams {
        &self.params
    }

    /// Number of angular sectors: `ceil(360° / angular_resolution_deg)`, at least 1.
    pub fn sector_count(&self) -> usize {
        let n = (360.0 / self.params.angular_resolution_deg).ceil();
        if n.is_finite() && n >= 1.0 {
            (n as usize).min(1 << 20)
        } else {
            1
        }
    }

    /// Fills `out` (cleared first) from one scan.
    ///
    /// `points_in_sensor` are the scan's points in the sensor frame; `world_from_sensor` is the
    /// sensor's pose in the map's local frame at scan time; `window` maps world cells to the
    /// storage of `out`, which must have the window's size.
    ///
    /// Points with a NaN or infinite coordinate, or beyond `max_range_m`, are dropped and
    /// counted; so are obstacle points outside the window. A non-finite pose gives an empty
    /// (vacuous) grid and counts every point as non-finite.
    pub fn build(
        &mut self,
        points_in_sensor: &[[f32; 3]],
        world_from_sensor: &Isometry3,
        window: &Window,
        out: &mut SensorGrid,
    ) -> SensorStats {
        out.clear();
        let mut stats = SensorStats {
            points: points_in_sensor.len(),
            ..SensorStats::default()
        };
        if !world_from_sensor.is_finite() || out.len() != window.len() {
            stats.dropped_non_finite = points_in_sensor.len();
            return stats;
        }
        let (min_range_m, max_range_m) = (self.params.min_range_m, self.params.max_range_m);
        // Levelled frame: rotate only, so that heights and ranges are metric and small numbers
        // keep full precision whatever the map's origin.
        self.levelled.clear();
        for p in points_in_sensor {
            if !p.iter().all(|v| v.is_finite()) {
                stats.dropped_non_finite += 1;
                continue;
            }
            let q = world_from_sensor.rotate([f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]);
            let range_m = horizontal_range(q);
            if !(min_range_m..=max_range_m).contains(&range_m) {
                stats.dropped_out_of_range += 1;
                continue;
            }
            self.levelled.push(q);
        }
        let plane = match self.params.ground_model {
            GroundModel::None => None,
            GroundModel::Plane => {
                let plane = fit_ground_plane_into(
                    &self.levelled,
                    self.params.ground_band_m,
                    &mut self.inliers,
                );
                stats.ground_plane = plane;
                if plane.is_none() {
                    stats.unclassified_points = self.levelled.len();
                    return stats;
                }
                plane
            }
        };

        let sectors = self.sector_count();
        let sector_width = std::f64::consts::TAU / sectors as f64;
        let sectors_per_radian = sectors as f64 / std::f64::consts::TAU;
        // Points are classified in fixed chunks, in parallel, and the chunks merged in order:
        // ranges by min/max, cells in point order, so the result does not depend on the number
        // of threads.
        let [sensor_x, sensor_y, _] = world_from_sensor.translation;
        let classify = PointClassifier {
            plane: plane.as_ref(),
            ground_band_m: self.params.ground_band_m,
            obstacle_heights_m: self.params.min_obstacle_height_m
                ..=self.params.max_obstacle_height_m,
            sectors,
            sectors_per_radian,
            window,
            sensor_xy: (sensor_x, sensor_y),
        };
        let chunk_count = self.levelled.len().div_ceil(CLASSIFY_CHUNK);
        self.classified
            .resize_with(chunk_count, Classified::default);
        self.levelled
            .par_chunks(CLASSIFY_CHUNK)
            .zip(self.classified.par_iter_mut())
            .for_each(|(points, out)| classify.chunk(points, out));
        self.obstacle_range.clear();
        self.obstacle_range.resize(sectors, f64::INFINITY);
        self.ground_range.clear();
        self.ground_range.resize(sectors, 0.0);
        for chunk in &self.classified {
            stats.ground_points += chunk.ground_points;
            stats.unclassified_points += chunk.unclassified_points;
            stats.obstacle_points += chunk.obstacle_cells.len();
            stats.dropped_outside_window += chunk.dropped_outside_window;
            for (all, this) in self.ground_range.iter_mut().zip(&chunk.ground_range) {
                *all = all.max(*this);
            }
            for (all, this) in self.obstacle_range.iter_mut().zip(&chunk.obstacle_range) {
                *all = all.min(*this);
            }
        }

        let mu_free = self.params.mu_free as f32;
        let mu_occupied = self.params.mu_occupied as f32;
        let cell_size_m = window.cell_size_m();
        let origin = (sensor_x / cell_size_m, sensor_y / cell_size_m);
        let mut free_cells = 0usize;
        for s in 0..sectors {
            let (limit_m, whole_cells) = if self.obstacle_range[s].is_finite() {
                (self.obstacle_range[s], true)
            } else {
                (self.ground_range[s], false)
            };
            if limit_m <= 0.0 {
                continue;
            }
            // Enough rays that neighbours are under a cell apart at the far end.
            let rays = ((limit_m * sector_width / cell_size_m).ceil() as usize).clamp(1, 4096);
            let first_angle = -std::f64::consts::PI + s as f64 * sector_width;
            for k in 0..rays {
                let angle = first_angle + (k as f64 + 0.5) * sector_width / rays as f64;
                walk_ray(
                    window,
                    origin,
                    angle.sin_cos(),
                    limit_m / cell_size_m,
                    whole_cells,
                    |idx| {
                        // Counted on the first visit: rays of a sector overlap near the sensor.
                        free_cells += usize::from(out.m_free()[idx] != mu_free);
                        out.set_free(idx, mu_free);
                    },
                );
            }
        }
        // A ground return's own cell was seen free, if it lies within its sector's free range
        // (a ray may enter that cell just after the return's range, or miss its corner).
        let ground_cells = self.classified.iter().flat_map(|c| &c.ground_cells);
        for &(idx, s, range_m) in ground_cells {
            let s = s as usize;
            if range_m < self.obstacle_range[s] {
                free_cells += usize::from(out.m_free()[idx] != mu_free);
                out.set_free(idx, mu_free);
            }
        }
        let mut occupied_cells = 0;
        for &idx in self.classified.iter().flat_map(|c| &c.obstacle_cells) {
            if out.m_occupied()[idx] != mu_occupied {
                occupied_cells += 1;
                free_cells -= usize::from(out.m_free()[idx] == mu_free && mu_free != 0.0);
            }
            out.set_free(idx, 0.0);
            out.set_occupied(idx, mu_occupied);
        }
        stats.free_cells = free_cells;
        stats.occupied_cells = occupied_cells;
        stats
    }
}

/// Points classified per parallel task: enough that a task's per-sector arrays cost little.
const CLASSIFY_CHUNK: usize = 8192;

/// How the points of a scan are told apart: ground (within the band of the fitted plane),
/// obstacle (within the obstacle heights above it, or every point without a ground model) or
/// neither.
struct PointClassifier<'a> {
    plane: Option<&'a GroundPlane>,
    ground_band_m: f64,
    obstacle_heights_m: std::ops::RangeInclusive<f64>,
    sectors: usize,
    sectors_per_radian: f64,
    window: &'a Window,
    sensor_xy: (f64, f64),
}

/// What one chunk of points gives.
#[derive(Clone, Debug, Default)]
struct Classified {
    ground_points: usize,
    unclassified_points: usize,
    dropped_outside_window: usize,
    /// Farthest ground return and nearest obstacle return per sector.
    ground_range: Vec<f64>,
    obstacle_range: Vec<f64>,
    /// (cell, sector, range) of each ground return in the window; cell of each obstacle return.
    ground_cells: Vec<(usize, u32, f64)>,
    obstacle_cells: Vec<usize>,
}

impl PointClassifier<'_> {
    /// Classifies `points` into `out`, whose buffers are cleared and reused.
    fn chunk(&self, points: &[[f64; 3]], out: &mut Classified) {
        out.ground_points = 0;
        out.unclassified_points = 0;
        out.dropped_outside_window = 0;
        out.ground_range.clear();
        out.ground_range.resize(self.sectors, 0.0);
        out.obstacle_range.clear();
        out.obstacle_range.resize(self.sectors, f64::INFINITY);
        out.ground_cells.clear();
        out.obstacle_cells.clear();
        let (sensor_x, sensor_y) = self.sensor_xy;
        for &q in points {
            let is_obstacle = match self.plane {
                None => true,
                Some(plane) => {
                    let h = plane.height_of(q);
                    if h.abs() <= self.ground_band_m {
                        out.ground_points += 1;
                        let s = sector_of(q, self.sectors_per_radian, self.sectors);
                        let range_m = horizontal_range(q);
                        out.ground_range[s] = out.ground_range[s].max(range_m);
                        if let Some(idx) = self
                            .window
                            .storage_index_of_point(sensor_x + q[0], sensor_y + q[1])
                        {
                            out.ground_cells.push((idx, s as u32, range_m));
                        }
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
                    out.obstacle_cells.push(idx);
                    let s = sector_of(q, self.sectors_per_radian, self.sectors);
                    out.obstacle_range[s] = out.obstacle_range[s].min(horizontal_range(q));
                }
                None => out.dropped_outside_window += 1,
            }
        }
    }
}

/// Horizontal distance from the sensor. (`f64::hypot` guards against overflow we cannot have
/// here, at several times the cost.)
#[inline]
fn horizontal_range(q: [f64; 3]) -> f64 {
    (q[0] * q[0] + q[1] * q[1]).sqrt()
}

/// Sector of a levelled point by its bearing, `atan2(y, x)` measured from −π.
#[inline]
fn sector_of(q: [f64; 3], sectors_per_radian: f64, sectors: usize) -> usize {
    let angle = fast_atan2(q[1], q[0]) + std::f64::consts::PI;
    // `as usize` saturates: a tiny negative angle gives sector 0.
    ((angle * sectors_per_radian) as usize).min(sectors - 1)
}

/// `atan2(y, x)` within 1e-7 rad: octant reduction and a fitted polynomial for atan on
/// [0, 1]. Sector assignment only needs a small fraction of a sector's width, and this is
/// several times faster than the libm call on 100k points per scan.
#[inline]
fn fast_atan2(y: f64, x: f64) -> f64 {
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

/// Walks the cells a ray crosses (Amanatides & Woo 1987), in cell units, from `origin` along
/// the unit direction `(sin, cos)` of its angle, calling `visit` with the storage index of each
/// window cell it marks free: with `whole_cells`, cells left at or before `limit` (the ray
/// leaves them before reaching the obstacle range); otherwise cells entered before `limit`.
fn walk_ray(
    window: &Window,
    origin: (f64, f64),
    (sin, cos): (f64, f64),
    limit: f64,
    whole_cells: bool,
    mut visit: impl FnMut(usize),
) {
    let (ox, oy) = origin;
    let mut col = ox.floor() as i64;
    let mut row = oy.floor() as i64;
    let step_col: i64 = if cos >= 0.0 { 1 } else { -1 };
    let step_row: i64 = if sin >= 0.0 { 1 } else { -1 };
    // Ray parameter t (cell units of distance) at which the next column / row boundary is met.
    let next_boundary = |o: f64, cell: i64, step: i64| (cell + i64::from(step > 0)) as f64 - o;
    let mut t_col = if cos != 0.0 {
        next_boundary(ox, col, step_col) / cos
    } else {
        f64::INFINITY
    };
    let mut t_row = if sin != 0.0 {
        next_boundary(oy, row, step_row) / sin
    } else {
        f64::INFINITY
    };
    let dt_col = if cos != 0.0 {
        1.0 / cos.abs()
    } else {
        f64::INFINITY
    };
    let dt_row = if sin != 0.0 {
        1.0 / sin.abs()
    } else {
        f64::INFINITY
    };
    let mut t_enter = 0.0;
    let (w, h) = (window.width() as i64, window.height() as i64);
    let (c0, r0) = (window.first_col(), window.first_row());
    // Storage column and row, stepped with the global ones: no division per cell.
    let mut storage_col = col.rem_euclid(w);
    let mut storage_row = row.rem_euclid(h);
    let wrap = |v: i64, n: i64| {
        if v == n {
            0
        } else if v < 0 {
            n - 1
        } else {
            v
        }
    };
    loop {
        let t_exit = t_col.min(t_row);
        let marked = if whole_cells {
            t_exit <= limit
        } else {
            t_enter < limit
        };
        if !marked {
            return;
        }
        let (dc, dr) = (col - c0, row - r0);
        if (0..w).contains(&dc) && (0..h).contains(&dr) {
            visit((storage_row * w + storage_col) as usize);
        } else if (dc < 0 && step_col < 0)
            || (dc >= w && step_col > 0)
            || (dr < 0 && step_row < 0)
            || (dr >= h && step_row > 0)
        {
            // Outside the window and moving away from it: the ray cannot come back.
            return;
        }
        t_enter = t_exit;
        if t_col < t_row {
            col += step_col;
            storage_col = wrap(storage_col + step_col, w);
            t_col += dt_col;
        } else {
            row += step_row;
            storage_row = wrap(storage_row + step_row, h);
            t_row += dt_row;
        }
    }
}

/// Splitmix64: a tiny deterministic generator for RANSAC draws.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// Fits the ground plane to levelled points: RANSAC over near, roughly level hypotheses scored
/// on an even sample, then two least-squares refits `z = a·x + b·y + c` on all inliers within
/// `band_m`. `None` if no level plane gathers enough points.
pub fn fit_ground_plane(levelled: &[[f64; 3]], band_m: f64) -> Option<GroundPlane> {
    fit_ground_plane_into(levelled, band_m, &mut Vec::new())
}

/// [`fit_ground_plane`] with a buffer for the inliers' indices, kept between scans.
fn fit_ground_plane_into(
    levelled: &[[f64; 3]],
    band_m: f64,
    inlier_indices: &mut Vec<usize>,
) -> Option<GroundPlane> {
    // Every stride-th near point, counted first so that the near points are never copied.
    let is_near = |q: &&[f64; 3]| horizontal_range(**q) <= GROUND_FIT_RANGE_M;
    let stride = levelled
        .iter()
        .filter(is_near)
        .count()
        .div_ceil(RANSAC_SAMPLE)
        .max(1);
    let candidates: Vec<[f64; 3]> = levelled
        .iter()
        .filter(is_near)
        .step_by(stride)
        .copied()
        .collect();
    if candidates.len() < 3 {
        return None;
    }
    let min_normal_z = MAX_GROUND_TILT_DEG.to_radians().cos();
    let mut rng = SplitMix64(RANSAC_SEED);
    let mut best: Option<([f64; 3], f64, usize)> = None;
    for _ in 0..RANSAC_ITERATIONS {
        let p0 = candidates[rng.below(candidates.len())];
        let p1 = candidates[rng.below(candidates.len())];
        let p2 = candidates[rng.below(candidates.len())];
        let u = sub(p1, p0);
        let v = sub(p2, p0);
        let n = cross(u, v);
        let norm = dot(n, n).sqrt();
        if norm.is_nan() || norm <= 1e-9 {
            continue;
        }
        let sign = if n[2] < 0.0 { -1.0 } else { 1.0 };
        let n = [sign * n[0] / norm, sign * n[1] / norm, sign * n[2] / norm];
        if n[2] < min_normal_z {
            continue;
        }
        let offset = dot(n, p0);
        let score = candidates
            .iter()
            .filter(|q| (dot(n, **q) - offset).abs() <= band_m)
            .count();
        // Among equally supported planes prefer the lower one: the road, not a kerb-high band.
        let better = match best {
            None => true,
            Some((_, best_offset, best_score)) => {
                score > best_score || (score == best_score && offset < best_offset)
            }
        };
        if better {
            best = Some((n, offset, score));
        }
    }
    let (mut normal, mut offset, _) = best?;
    let mut inliers = 0;
    for _ in 0..2 {
        let (fit, count) = least_squares_plane(levelled, normal, offset, band_m, inlier_indices)?;
        inliers = count;
        (normal, offset) = fit;
    }
    (inliers >= MIN_GROUND_INLIERS).then_some(GroundPlane {
        normal,
        offset_m: offset,
        inliers,
    })
}

/// Least-squares `z = a·x + b·y + c` over the points within `band_m` of the plane
/// `normal · p = offset`; returns the refitted unit normal and offset, and the inlier count.
fn least_squares_plane(
    levelled: &[[f64; 3]],
    normal: [f64; 3],
    offset: f64,
    band_m: f64,
    inliers: &mut Vec<usize>,
) -> Option<(([f64; 3], f64), usize)> {
    // Centred sums for conditioning: coordinates are tens of metres, heights centimetres. The
    // first pass notes the inliers, so that the second reads only them.
    inliers.clear();
    let mut mean = [0.0f64; 3];
    for (index, q) in levelled.iter().enumerate() {
        if (dot(normal, *q) - offset).abs() <= band_m {
            inliers.push(index);
            for k in 0..3 {
                mean[k] += q[k];
            }
        }
    }
    let n = inliers.len();
    if n < MIN_GROUND_INLIERS {
        return None;
    }
    let mean = mean.map(|v| v / n as f64);
    let (mut sxx, mut sxy, mut syy, mut sxz, mut syz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &index in inliers.iter() {
        let q = levelled[index];
        let (x, y, z) = (q[0] - mean[0], q[1] - mean[1], q[2] - mean[2]);
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        sxz += x * z;
        syz += y * z;
    }
    let det = sxx * syy - sxy * sxy;
    if det.is_nan() || det.abs() <= 1e-9 {
        return None;
    }
    let a = (sxz * syy - syz * sxy) / det;
    let b = (syz * sxx - sxz * sxy) / det;
    // z − mean_z = a (x − mean_x) + b (y − mean_y)  ⇔  (−a, −b, 1) · p = mean_z − a·mean_x − b·mean_y
    let norm = (a * a + b * b + 1.0).sqrt();
    let unit = [-a / norm, -b / norm, 1.0 / norm];
    let offset = (mean[2] - a * mean[0] - b * mean[1]) / norm;
    Some(((unit, offset), n))
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn planar_params() -> SensorParams {
        SensorParams {
            ground_model: GroundModel::None,
            angular_resolution_deg: 1.0,
            max_range_m: 50.0,
            ..SensorParams::default()
        }
    }

    /// A 21 × 21 window of 1 m cells centred on the origin (cells -10..=10).
    fn small_window() -> Window {
        let mut w = Window::new(21, 21, 1.0).unwrap();
        w.recentre(0.5, 0.5).unwrap();
        w
    }

    fn at(window: &Window, grid: &[f32], x: f64, y: f64) -> f32 {
        grid[window.storage_index_of_point(x, y).unwrap()]
    }

    #[test]
    fn fast_atan2_is_within_a_tenth_of_a_microradian() {
        let mut worst = 0.0f64;
        for k in 0..100_000 {
            let angle = -std::f64::consts::PI + k as f64 * std::f64::consts::TAU / 100_000.0;
            let (y, x) = (3.7 * angle.sin(), 3.7 * angle.cos());
            let d = (fast_atan2(y, x) - y.atan2(x)).abs();
            // ±π are the same bearing.
            worst = worst.max(d.min((d - std::f64::consts::TAU).abs()));
        }
        assert!(worst < 1e-7, "{worst}");
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
    }

    #[test]
    fn rpy_follows_the_ros_convention() {
        // Yaw 90°: the sensor's x axis points north. Pitch 90°: x points down.
        let yaw = Isometry3::from_xyz_rpy(1.0, 2.0, 3.0, 0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let p = yaw.transform_point([1.0, 0.0, 0.0]);
        assert!(
            (p[0] - 1.0).abs() < 1e-12 && (p[1] - 3.0).abs() < 1e-12 && (p[2] - 3.0).abs() < 1e-12
        );
        let pitch = Isometry3::from_xyz_rpy(0.0, 0.0, 0.0, 0.0, std::f64::consts::FRAC_PI_2, 0.0);
        let p = pitch.rotate([1.0, 0.0, 0.0]);
        assert!((p[2] + 1.0).abs() < 1e-12 && p[0].abs() < 1e-12);
        // Roll 90°: y points up.
        let roll = Isometry3::from_xyz_rpy(0.0, 0.0, 0.0, std::f64::consts::FRAC_PI_2, 0.0, 0.0);
        let p = roll.rotate([0.0, 1.0, 0.0]);
        assert!((p[2] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_wall_ahead_gives_free_cells_before_it_and_occupied_cells_on_it() {
        let window = small_window();
        let mut grid = SensorGrid::new(21, 21);
        let mut model = SensorModel::new(planar_params());
        // A wall at x = 5.5 m from y = −2 to 2, seen from the centre of cell (0, 0).
        let points: Vec<[f32; 3]> = (-20..=20).map(|k| [5.5, k as f32 * 0.1, 0.0]).collect();
        let pose = Isometry3::from_xyz_rpy(0.5, 0.5, 0.0, 0.0, 0.0, 0.0);
        let stats = model.build(&points, &pose, &window, &mut grid);
        assert_eq!(stats.obstacle_points, 41);
        // Wall points: y from −2 + 0.5 to 2 + 0.5 in world, x 6.0 → column 6, rows −2..=2.
        for row in -2..=2 {
            let y = row as f64 + 0.5;
            assert_eq!(at(&window, grid.m_occupied(), 6.5, y), 0.8, "row {row}");
            assert_eq!(at(&window, grid.m_free(), 6.5, y), 0.0);
        }
        // Cells 0..=5 along the row of the sensor are free; beyond the wall nothing is known.
        for col in 0..=5 {
            assert_eq!(
                at(&window, grid.m_free(), col as f64 + 0.5, 0.5),
                0.7,
                "col {col}"
            );
        }
        assert_eq!(at(&window, grid.m_free(), 7.5, 0.5), 0.0);
        assert_eq!(at(&window, grid.m_occupied(), 7.5, 0.5), 0.0);
        // Behind the sensor no return: no free space is invented.
        assert_eq!(at(&window, grid.m_free(), -3.5, 0.5), 0.0);
        assert_eq!(stats.occupied_cells, 5);
    }

    #[test]
    fn bad_points_are_dropped_and_counted() {
        let window = small_window();
        let mut grid = SensorGrid::new(21, 21);
        let mut model = SensorModel::new(SensorParams {
            max_range_m: 30.0,
            ..planar_params()
        });
        let points = [
            [f32::NAN, 0.0, 0.0],
            [f32::INFINITY, 1.0, 0.0],
            [40.0, 0.0, 0.0], // beyond 30 m
            [15.0, 0.0, 0.0], // in range, outside the 21-cell window
            [3.0, 0.0, 0.0],  // kept
        ];
        let stats = model.build(&points, &Isometry3::IDENTITY, &window, &mut grid);
        assert_eq!(stats.points, 5);
        assert_eq!(stats.dropped_non_finite, 2);
        assert_eq!(stats.dropped_out_of_range, 1);
        assert_eq!(stats.dropped_outside_window, 1);
        assert_eq!(stats.obstacle_points, 1);
        assert!(
            grid.m_occupied()
                .iter()
                .chain(grid.m_free())
                .all(|v| v.is_finite())
        );
        // A non-finite pose: nothing at all.
        let pose = Isometry3::from_xyz_rpy(f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0);
        let stats = model.build(&points, &pose, &window, &mut grid);
        assert_eq!(stats.dropped_non_finite, 5);
        assert!(grid.m_free().iter().all(|&v| v == 0.0));
    }

    #[test]
    fn ground_returns_make_free_space_up_to_the_farthest_one() {
        let window = small_window();
        let mut grid = SensorGrid::new(21, 21);
        let mut model = SensorModel::new(SensorParams {
            ground_model: GroundModel::Plane,
            ground_band_m: 0.2,
            ..planar_params()
        });
        // A flat ground 1.5 m below the sensor, sampled densely to 8 m, plus one box at
        // (−4, 0) rising 1 m.
        let mut points = Vec::new();
        for i in 0..400 {
            let angle = i as f32 * std::f32::consts::TAU / 400.0;
            for r in [3.0f32, 4.0, 5.0, 6.0, 7.0, 8.0] {
                points.push([r * angle.cos(), r * angle.sin(), -1.5]);
            }
        }
        // The box's face: x = −3.8 m, y from −1 to 1.5 m, heights 0.5 to 1.3 m above ground.
        // 2 cm apart, so that every 1° sector across the face holds some of its points.
        for dy in 0..=125 {
            for dz in 0..5 {
                points.push([-3.8, -1.0 + dy as f32 * 0.02, -1.0 + dz as f32 * 0.2]);
            }
        }
        let stats = model.build(&points, &Isometry3::IDENTITY, &window, &mut grid);
        let plane = stats.ground_plane.unwrap();
        assert!((plane.offset_m + 1.5).abs() < 1e-6 && (plane.normal[2] - 1.0).abs() < 1e-9);
        assert_eq!(stats.ground_points, 2400);
        // Heights 0.5, 0.7, …, 1.3 m: all within the default 0.3 – 2.5 m obstacle band.
        assert_eq!(stats.obstacle_points, 126 * 5);
        assert_eq!(at(&window, grid.m_occupied(), -3.5, 0.5), 0.8);
        assert_eq!(at(&window, grid.m_occupied(), -2.5, 0.5), 0.0);
        // Free to 8 m east (the cell at 8 m holds a ground return), not beyond.
        assert_eq!(at(&window, grid.m_free(), 8.5, 0.5), 0.7);
        assert_eq!(at(&window, grid.m_free(), 9.5, 0.5), 0.0);
        // West: free before the box only; the ground seen beyond it does not count.
        assert_eq!(at(&window, grid.m_free(), -2.5, 0.5), 0.7);
        assert_eq!(at(&window, grid.m_free(), -4.5, 0.5), 0.0);
        assert_eq!(at(&window, grid.m_free(), -5.5, 0.5), 0.0);
    }

    #[test]
    fn an_empty_scan_gives_a_vacuous_grid() {
        let window = small_window();
        let mut grid = SensorGrid::new(21, 21);
        grid.m_free_mut().fill(0.3);
        let stats = SensorModel::new(SensorParams::default()).build(
            &[],
            &Isometry3::IDENTITY,
            &window,
            &mut grid,
        );
        assert_eq!(stats.free_cells + stats.occupied_cells, 0);
        assert!(
            grid.m_free()
                .iter()
                .chain(grid.m_occupied())
                .all(|&v| v == 0.0)
        );
    }

    #[test]
    fn rays_leave_no_gaps_at_long_range() {
        // A ring of obstacles at 9.7 m: every cell strictly inside 8.5 m must be free.
        let window = small_window();
        let mut grid = SensorGrid::new(21, 21);
        let mut model = SensorModel::new(SensorParams {
            angular_resolution_deg: 5.0,
            ..planar_params()
        });
        let points: Vec<[f32; 3]> = (0..3600)
            .map(|i| {
                let a = i as f32 * std::f32::consts::TAU / 3600.0;
                [9.7 * a.cos(), 9.7 * a.sin(), 0.0]
            })
            .collect();
        model.build(
            &points,
            &Isometry3::from_xyz_rpy(0.5, 0.5, 0.0, 0.0, 0.0, 0.0),
            &window,
            &mut grid,
        );
        for col in -10..=10i64 {
            for row in -10..=10i64 {
                let (cx, cy) = window.cell_centre(col, row);
                let far_corner = ((cx - 0.5).abs() + 0.5).hypot((cy - 0.5).abs() + 0.5);
                if far_corner < 8.5 {
                    assert_eq!(
                        at(&window, grid.m_free(), cx, cy),
                        0.7,
                        "cell ({col}, {row})"
                    );
                }
            }
        }
    }

    fn shared_scan(name: &str) -> Option<drive::Scan> {
        let path = geodata::testdata::shared_file(&format!("data/lidar/kitti-city-22/{name}"))?;
        Some(drive::read_scan(&path).unwrap())
    }

    #[test]
    fn finds_the_road_under_the_kitti_lidar() {
        let Some(scan) = shared_scan("0000000000.pcd") else {
            return;
        };
        let levelled: Vec<[f64; 3]> = scan
            .points_in_sensor
            .iter()
            .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
            .collect();
        let plane = fit_ground_plane(&levelled, 0.2).unwrap();
        // KITTI's HDL-64E is mounted 1.73 m above the road (Geiger et al. 2013).
        assert!(plane.normal[2] > 0.995, "{plane:?}");
        assert!((plane.offset_m + 1.73).abs() < 0.15, "{plane:?}");
        assert!(plane.inliers > scan.len() / 4, "{plane:?}");
    }

    #[test]
    fn a_real_scan_into_a_large_window() {
        let Some(scan) = shared_scan("0000000000.pcd") else {
            return;
        };
        let mut window = Window::new(1000, 1000, 0.2).unwrap();
        window.recentre(0.0, 0.0).unwrap();
        let mut grid = SensorGrid::new(1000, 1000);
        let mut model = SensorModel::new(SensorParams::default());
        let stats = model.build(
            &scan.points_in_sensor,
            &Isometry3::IDENTITY,
            &window,
            &mut grid,
        );
        // The points are classified in parallel: any number of threads gives the same grid.
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut again = SensorGrid::new(1000, 1000);
            let stats_again = pool.install(|| {
                SensorModel::new(SensorParams::default()).build(
                    &scan.points_in_sensor,
                    &Isometry3::IDENTITY,
                    &window,
                    &mut again,
                )
            });
            assert_eq!(stats_again, stats, "{threads} threads");
            assert!(again.m_free() == grid.m_free() && again.m_occupied() == grid.m_occupied());
        }
        assert_eq!(stats.points, 119_978);
        // The grid knows which blocks of 64 cells the scan left vacuous (the step skips them):
        // every cell with mass lies in a noted block, and most blocks of this window are not.
        let noted = grid.may_hold_mass();
        for (idx, (&free, &occupied)) in grid.m_free().iter().zip(grid.m_occupied()).enumerate() {
            assert!(free + occupied == 0.0 || noted[idx / 64], "cell {idx}");
        }
        let share = noted.iter().filter(|&&b| b).count() as f64 / noted.len() as f64;
        assert!(share < 0.2, "{share}");
        assert_eq!(
            stats.points,
            stats.dropped_non_finite
                + stats.dropped_out_of_range
                + stats.dropped_outside_window
                + stats.obstacle_points
                + stats.ground_points
                + stats.unclassified_points
        );
        assert!(
            stats.obstacle_points > 1000 && stats.ground_points > 30_000,
            "{stats:?}"
        );
        assert!(
            stats.free_cells > 10_000 && stats.occupied_cells > 500,
            "{stats:?}"
        );
        // The sensor's own cell is seen free (the road under the car), not occupied.
        let own = window.storage_index_of_point(0.0, 0.0).unwrap();
        assert_eq!(grid.m_occupied()[own], 0.0);
    }
}
