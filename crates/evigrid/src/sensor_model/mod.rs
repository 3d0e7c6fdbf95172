//! The sensor model: one lidar scan becomes a SensorGrid on Ω_SG = {F, O} (SPEC §3, after Moras
//! et al., ICRA 2011).
//!
//! The scan's points are moved into a *levelled* frame — world axes, origin at the sensor — with
//! the sensor's pose. They are split into obstacle and ground points: for a planar or multi-layer
//! scanner every return is an obstacle ([`GroundModel::None`]); for a 3-D lidar a ground plane is
//! fitted to the scan ([`GroundModel::Plane`]: the ground crate's [`ground::PlaneFitter`],
//! RANSAC with a fixed seed, then least squares on the inliers) and obstacle points are those
//! between `min_obstacle_height_m` and `max_obstacle_height_m` above it, ground points those
//! within `ground_band_m` of it.
//!
//! Around the sensor the plane is cut into angular sectors of `angular_resolution_deg`. Each
//! sector keeps only two numbers, the range of its nearest obstacle return and that of its
//! farthest ground return, so the cost of the free space does not grow with the number of
//! points: rays walk the world-fixed window cell by cell (Amanatides & Woo's exact traversal) up
//! to that range, enough rays per sector that neighbouring rays are less than a cell apart at
//! their far end. Then every obstacle point marks its own cell occupied, which also settles the
//! SPEC §3 decision that a cell both crossed and holding a return is occupied.
//!
//! Beyond SPEC §3, for a 3-D lidar only: an obstacle return with fewer than
//! `min_neighbourhood_returns` returns in its cell's 3 × 3 neighbourhood is *stray* (`stray`):
//! it is dropped before the sectors' nearest ranges are taken, so it neither occupies its cell
//! nor stops the free space behind it.
//!
//! Free cells are those a ray crosses *entirely* before the first obstacle range ("strictly
//! before"); where a sector has no obstacle, the cells it enters before its farthest ground
//! return (that return's own cell included: the ground was seen there).

mod classify;
mod ray;
mod stray;
mod surface;

use rayon::prelude::*;
use serde::Serialize;

use crate::grids::SensorGrid;
use crate::params::SensorParams;
use crate::window::Window;
use classify::{CLASSIFY_CHUNK, Classified, PointClassifier, horizontal_range, sector_of};
use ray::walk_ray;
use stray::StrayFilter;

use crate::params::GroundModel;
use crate::pose::{IsometryMatrix3, PoseExt};
pub use ground::GroundPlane;

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
    /// Obstacle points dropped as stray: their cell and its eight neighbours held fewer than
    /// `min_neighbourhood_returns` obstacle returns (3-D ground models only).
    pub stray_obstacle_points: usize,
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
    /// Per sector, whether its rays met nothing within `max_range_m`: a return beyond it, or
    /// none at all inside the field of view (planar scanners, `empty_without_return`).
    empty_sector: Vec<bool>,
    /// Per sector, whether any return lay in it (planar scanners).
    any_return: Vec<bool>,
    /// What each chunk of the current scan's points gave, in point order; kept between scans
    /// so that the chunks' buffers are not allocated again.
    classified: Vec<Classified>,
    /// Which cells hold only stray returns ([`GroundModel::Local`] and [`GroundModel::Plane`]).
    stray: StrayFilter,
    /// The plane fit of [`GroundModel::Plane`], with its buffers.
    plane_fitter: ground::PlaneFitter,
    /// The local ground model ([`GroundModel::Local`] only), with its buffers.
    segmenter: Option<ground::GroundSegmenter>,
    /// The levelled points in `f32` for the local ground model, and its label per point.
    levelled_f32: Vec<[f32; 3]>,
    labels: Vec<ground::PointLabel>,
    /// How far along its ray [`SensorModel::build_placed`] moves a return, m (0: not at all).
    return_depth_m: f64,
    /// Whether [`SensorModel::build_placed`] places the returns on their sector's nearest
    /// surface by that surface ([`SensorModel::set_placed_by_surface`]).
    placed_by_surface: bool,
    /// How far behind the surface, square to it, a placed cell centre may lie, m.
    surface_depth_m: f64,
    /// How many standard deviations of the pose's error a placed cell centre may lie in front
    /// of the surface.
    surface_pose_sigmas: f64,
    /// Whether the surface reaches past a silhouette's last return, square to the ray.
    surface_silhouette_faces: bool,
    /// Whether the surface between two returns on the faces of a convex corner follows the
    /// faces up to the corner.
    surface_convex_corners: bool,
    /// Per fine sector of [`surface::SECTOR_RAD`] (with `placed_by_surface`), the range of its
    /// nearest obstacle return (∞ if none) and that return's levelled position (east and north
    /// of the sensor).
    surface_range: Vec<f64>,
    /// See `surface_range`.
    nearest_xy: Vec<[f64; 2]>,
    /// What the last scan left for the rays' walk; `None` before a scan or after one that
    /// gave a vacuous grid.
    last: Option<LastScan>,
}

/// The ground model gave no ground, so no point of the scan is trusted.
#[derive(Clone, Copy, Debug)]
struct NoGround;

/// What [`SensorModel::build`] keeps of a scan, besides the sectors, to fill a grid again.
#[derive(Clone, Copy, Debug)]
struct LastScan {
    /// The sensor's position, in cells.
    origin: (f64, f64),
    /// Whether sectors that met nothing are noted as seen empty (planar scanners).
    note_empty: bool,
}

impl SensorModel {
    /// A sensor model with these parameters (read from the `[sensor]` section).
    pub fn new(params: SensorParams) -> Self {
        let segmenter = (params.ground_model == GroundModel::Local)
            .then(|| ground::GroundSegmenter::new(params.ground_params()).ok())
            .flatten();
        Self {
            segmenter,
            levelled_f32: Vec::new(),
            labels: Vec::new(),
            params,
            levelled: Vec::new(),
            obstacle_range: Vec::new(),
            ground_range: Vec::new(),
            empty_sector: Vec::new(),
            any_return: Vec::new(),
            classified: Vec::new(),
            stray: StrayFilter::default(),
            plane_fitter: ground::PlaneFitter::default(),
            return_depth_m: 0.0,
            placed_by_surface: false,
            surface_depth_m: 0.0,
            surface_pose_sigmas: 0.0,
            surface_silhouette_faces: false,
            surface_convex_corners: false,
            surface_range: Vec::new(),
            nearest_xy: Vec::new(),
            last: None,
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
    /// counted; so are obstacle points outside the window, and stray obstacle points of a 3-D
    /// lidar (`stray_obstacle_points`). A non-finite pose gives an empty
    /// (vacuous) grid and counts every point as non-finite.
    pub fn build(
        &mut self,
        points_in_sensor: &[[f32; 3]],
        world_from_sensor: &IsometryMatrix3,
        window: &Window,
        out: &mut SensorGrid,
    ) -> SensorStats {
        out.clear();
        self.last = None;
        let mut stats = SensorStats {
            points: points_in_sensor.len(),
            ..SensorStats::default()
        };
        if !world_from_sensor.is_finite() || out.len() != window.len() {
            stats.dropped_non_finite = points_in_sensor.len();
            return stats;
        }
        let sectors = self.sector_count();
        let sectors_per_radian = sectors as f64 / std::f64::consts::TAU;
        // A planar scanner's ray that returned beyond the range limit, or not at all, crossed
        // the whole range without meeting an obstacle (a 3-D lidar's beam may pass over one).
        let note_empty =
            self.params.ground_model == GroundModel::None && self.params.empty_without_return;
        let returns = self.level(
            points_in_sensor,
            world_from_sensor,
            (sectors, sectors_per_radian),
            note_empty,
            &mut stats,
        );
        let Ok(plane) = self.fit_ground(&mut stats) else {
            return stats;
        };
        let [sensor_x, sensor_y, _]: [f64; 3] = world_from_sensor.translation.vector.into();
        let classify = self.classifier(
            plane.as_ref(),
            window,
            (sensor_x, sensor_y),
            (sectors, sectors_per_radian),
        );
        self.classify(&classify);
        self.merge_ground(sectors, &mut stats);
        self.mark_stray(window);
        self.merge_obstacles(sectors, classify.fine_sectors, &mut stats);
        if note_empty {
            mark_gaps(&self.any_return, returns, &mut self.empty_sector);
        }
        self.last = Some(LastScan {
            origin: (
                sensor_x / window.cell_size_m(),
                sensor_y / window.cell_size_m(),
            ),
            note_empty,
        });
        let (free_cells, occupied_cells) = self.fill(window, 0.0, (0.0, 0.0), out);
        stats.free_cells = free_cells;
        stats.occupied_cells = occupied_cells;
        stats
    }

    /// Moves the scan's finite points within range into the levelled frame (`self.levelled`),
    /// counting the others; with `note_empty`, notes per sector (of `sectors`, with
    /// `sectors_per_radian`) whether any return lay in it and whether one lay beyond the range
    /// limit. Returns the finite points so noted.
    fn level(
        &mut self,
        points_in_sensor: &[[f32; 3]],
        world_from_sensor: &IsometryMatrix3,
        (sectors, sectors_per_radian): (usize, f64),
        note_empty: bool,
        stats: &mut SensorStats,
    ) -> usize {
        let (min_range_m, max_range_m) = (self.params.min_range_m, self.params.max_range_m);
        let mut returns = 0usize;
        self.empty_sector.clear();
        self.empty_sector.resize(sectors, false);
        self.any_return.clear();
        self.any_return.resize(sectors, false);
        // Levelled frame: rotate only, so that heights and ranges are metric and small numbers
        // keep full precision whatever the map's origin.
        self.levelled.clear();
        for p in points_in_sensor {
            if !p.iter().all(|v| v.is_finite()) {
                stats.dropped_non_finite += 1;
                continue;
            }
            let q =
                world_from_sensor.rotate_xyz([f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]);
            let range_m = horizontal_range(q);
            if note_empty {
                let s = sector_of(q, sectors_per_radian, sectors);
                self.any_return[s] = true;
                self.empty_sector[s] |= range_m > max_range_m;
                returns += 1;
            }
            if !(min_range_m..=max_range_m).contains(&range_m) {
                stats.dropped_out_of_range += 1;
                continue;
            }
            self.levelled.push(q);
        }
        returns
    }

    /// Runs the ground model on the levelled points: the fitted plane for
    /// [`GroundModel::Plane`] (also noted in `stats`), the labels per point (`self.labels`) for
    /// [`GroundModel::Local`], nothing for [`GroundModel::None`]. `Err` when the model gave no
    /// ground, so that no point can be trusted (every levelled point is counted unclassified).
    fn fit_ground(&mut self, stats: &mut SensorStats) -> Result<Option<GroundPlane>, NoGround> {
        match self.params.ground_model {
            GroundModel::None => Ok(None),
            GroundModel::Local => {
                self.levelled_f32.clear();
                self.levelled_f32
                    .extend(self.levelled.iter().map(|q| q.map(|v| v as f32)));
                self.labels.clear();
                match &mut self.segmenter {
                    Some(segmenter) => {
                        let segmentation = segmenter.segment(&self.levelled_f32);
                        self.labels.extend_from_slice(segmentation.labels());
                        Ok(None)
                    }
                    // Parameters the ground crate refuses (not validated by the caller): no
                    // ground model, so no point is trusted.
                    None => {
                        stats.unclassified_points = self.levelled.len();
                        Err(NoGround)
                    }
                }
            }
            GroundModel::Plane => {
                let plane = self
                    .plane_fitter
                    .fit(&self.levelled, self.params.ground_band_m);
                stats.ground_plane = plane;
                if plane.is_none() {
                    stats.unclassified_points = self.levelled.len();
                    return Err(NoGround);
                }
                Ok(plane)
            }
        }
    }

    /// How this model tells the points of a scan apart, with the scan's ground `plane`, the
    /// sensor at `sensor_xy` (world, m) and `sectors` (with `sectors_per_radian`).
    fn classifier<'a>(
        &self,
        plane: Option<&'a GroundPlane>,
        window: &'a Window,
        sensor_xy: (f64, f64),
        (sectors, sectors_per_radian): (usize, f64),
    ) -> PointClassifier<'a> {
        PointClassifier {
            plane,
            ground_band_m: self.params.ground_band_m,
            obstacle_heights_m: self.params.min_obstacle_height_m
                ..=self.params.max_obstacle_height_m,
            sectors,
            sectors_per_radian,
            window,
            sensor_xy,
            return_depth_m: self.return_depth_m,
            fine_sectors: if self.placed_by_surface {
                surface::sector_count()
            } else {
                0
            },
        }
    }

    /// Classifies the levelled points into `self.classified`.
    ///
    /// Points are classified in fixed chunks, in parallel, and the chunks merged in order:
    /// ranges by min/max, cells in point order, so the result does not depend on the number of
    /// threads.
    fn classify(&mut self, classify: &PointClassifier) {
        let local_labels = (self.params.ground_model == GroundModel::Local).then_some(&self.labels);
        let chunk_count = self.levelled.len().div_ceil(CLASSIFY_CHUNK);
        self.classified
            .resize_with(chunk_count, Classified::default);
        match local_labels {
            Some(labels) => self
                .levelled
                .par_chunks(CLASSIFY_CHUNK)
                .zip(labels.par_chunks(CLASSIFY_CHUNK))
                .zip(self.classified.par_iter_mut())
                .for_each(|((points, labels), out)| classify.chunk(points, Some(labels), out)),
            None => self
                .levelled
                .par_chunks(CLASSIFY_CHUNK)
                .zip(self.classified.par_iter_mut())
                .for_each(|(points, out)| classify.chunk(points, None, out)),
        }
    }

    /// The chunks' ground returns: each sector's farthest (`self.ground_range`, of `sectors`)
    /// and the counts in `stats`.
    fn merge_ground(&mut self, sectors: usize, stats: &mut SensorStats) {
        self.ground_range.clear();
        self.ground_range.resize(sectors, 0.0);
        for chunk in &self.classified {
            stats.ground_points += chunk.ground_points;
            stats.unclassified_points += chunk.unclassified_points;
            stats.dropped_outside_window += chunk.dropped_outside_window;
            for (all, this) in self.ground_range.iter_mut().zip(&chunk.ground_range) {
                *all = all.max(*this);
            }
        }
    }

    /// Marks the cells that hold only stray returns (`stray`), which neither occupy their cell
    /// nor stop their sector's rays (3-D ground models only).
    fn mark_stray(&mut self, window: &Window) {
        let min_returns = match self.params.ground_model {
            GroundModel::None => 1,
            GroundModel::Plane | GroundModel::Local => self.params.min_neighbourhood_returns,
        };
        if min_returns > 1 {
            let returns = self.classified.iter().flat_map(|c| &c.obstacle_cells);
            self.stray
                .mark(window, returns.map(|&(idx, _, _)| idx), min_returns);
        }
    }

    /// The chunks' obstacle returns that are not stray: each sector's nearest
    /// (`self.obstacle_range`, of `sectors`), with `fine_sectors` (the surface placement) each
    /// fine sector's nearest and its position (`self.surface_range`, `self.nearest_xy`), and
    /// the counts in `stats`.
    fn merge_obstacles(&mut self, sectors: usize, fine_sectors: usize, stats: &mut SensorStats) {
        self.obstacle_range.clear();
        self.obstacle_range.resize(sectors, f64::INFINITY);
        self.surface_range.clear();
        self.surface_range.resize(fine_sectors, f64::INFINITY);
        self.nearest_xy.clear();
        self.nearest_xy.resize(fine_sectors, [0.0; 2]);
        for chunk in &self.classified {
            let returns = chunk.obstacle_cells.iter().zip(&chunk.obstacle_xy);
            for (i, (&(idx, s, range_m), &xy)) in returns.enumerate() {
                if self.stray.is_stray(idx) {
                    stats.stray_obstacle_points += 1;
                    continue;
                }
                stats.obstacle_points += 1;
                let range = &mut self.obstacle_range[s as usize];
                *range = range.min(range_m);
                if fine_sectors == 0 {
                    continue;
                }
                let f = chunk.obstacle_fine_sector[i] as usize;
                if range_m < self.surface_range[f] {
                    self.surface_range[f] = range_m;
                    self.nearest_xy[f] = xy;
                }
            }
        }
    }

    /// How far along its ray, m, [`SensorModel::build_placed`] moves each return before taking
    /// its cell; 0 (the default) places every return in its own cell, as SPEC §3 does.
    pub(crate) fn set_return_depth_m(&mut self, depth_m: f64) {
        self.return_depth_m = depth_m;
    }

    /// Whether [`SensorModel::build_placed`] places a return that lies on its sector's nearest
    /// surface (within a cell of the sector's nearest return) by the surface drawn through the
    /// nearest returns of its sector and the neighbouring ones, instead of along its own ray
    /// (`[motion] placed_by_surface`), occupying the cells whose centre lies behind that
    /// surface by at most `depth_m`, square to it, or in front of it by at most
    /// `pose_sigmas` standard deviations of the pose's error ([`SensorModel::build_placed`]);
    /// past a silhouette's last return, a face square to the ray only with
    /// `silhouette_faces`; between two returns on two faces of a convex corner, the faces up
    /// to the corner with `convex_corners`.
    pub(crate) fn set_placed_by_surface(
        &mut self,
        on: bool,
        depth_m: f64,
        pose_sigmas: f64,
        silhouette_faces: bool,
        convex_corners: bool,
    ) {
        self.surface_convex_corners = convex_corners;
        self.placed_by_surface = on;
        self.surface_depth_m = depth_m;
        self.surface_pose_sigmas = pose_sigmas;
        self.surface_silhouette_faces = silhouette_faces;
    }

    /// The last scan's visible obstacle returns, positions from the sensor (levelled frame:
    /// world axes, metres): with the surface placement, the nearest return of each fine sector
    /// (0.1°: the faces the sensor sees, a few thousand points however dense the scan); else
    /// every return the stray filter kept. The motion stage's object layer fits each moving
    /// track's extent to them.
    pub(crate) fn visible_returns(&self) -> Box<dyn Iterator<Item = [f64; 2]> + '_> {
        if self.placed_by_surface && !self.surface_range.is_empty() {
            Box::new(
                self.surface_range
                    .iter()
                    .zip(&self.nearest_xy)
                    .filter(|(r, _)| r.is_finite())
                    .map(|(_, &xy)| xy),
            )
        } else {
            Box::new(
                self.classified
                    .iter()
                    .flat_map(|c| c.obstacle_cells.iter().zip(&c.obstacle_xy))
                    .filter(|&(&(idx, _, _), _)| !self.stray.is_stray(idx))
                    .map(|(_, &xy)| xy),
            )
        }
    }

    /// Fills `out` (cleared first) from the scan of the last [`SensorModel::build`], with each
    /// obstacle return's occupied evidence in the cell of the return moved `return_depth_m`
    /// further along its ray, and each ray's free space extended by as much: a cell is
    /// occupied when its centre lies behind the surface the return came from, seen from the
    /// sensor, and free when the ray passes its centre in front of it (issue 30: a cell is
    /// what covers its centre). With [`SensorModel::set_placed_by_surface`], the returns on
    /// the nearest surface of their direction are placed by that surface instead, with
    /// `pose_sigma` (σ per axis, metres; σ of the heading, radians) the estimated error of the
    /// pose used. A vacuous grid before the first scan. Returns the free and occupied cell
    /// counts.
    pub(crate) fn build_placed(
        &self,
        window: &Window,
        pose_sigma: (f64, f64),
        out: &mut SensorGrid,
    ) -> (usize, usize) {
        out.clear();
        if out.len() != window.len() {
            return (0, 0);
        }
        self.fill(window, self.return_depth_m, pose_sigma, out)
    }

    /// Writes the free and occupied cells of the last scan into the cleared `out`, the rays'
    /// free space reaching `depth_m` beyond the nearest obstacle of their sector and each
    /// return placed in its cell moved as far (`placed_cells`; its own cell when 0).
    fn fill(
        &self,
        window: &Window,
        depth_m: f64,
        pose_sigma: (f64, f64),
        out: &mut SensorGrid,
    ) -> (usize, usize) {
        let Some(last) = self.last else {
            return (0, 0);
        };
        let masses = Masses {
            free: self.params.mu_free as f32,
            occupied: self.params.mu_occupied as f32,
        };
        let mut free_cells = self.fill_free(window, last.origin, depth_m, masses.free, out);
        // Occupied cells are taken back from the free ones (SPEC §3: a cell both crossed and
        // holding a return is occupied).
        let by_surface = self.placed_by_surface && depth_m > 0.0 && !self.surface_range.is_empty();
        let mut occupied = self.occupy_returns(window, depth_m, by_surface, masses, out);
        if by_surface {
            let behind = self.occupy_behind_surface(window, last.origin, pose_sigma, masses, out);
            occupied.add(behind);
        }
        free_cells -= occupied.were_free;
        // Sectors whose rays met nothing within the range limit: seen empty up to it, outside
        // the SensorGrid's mass (SPEC §3 leaves them vacuous).
        if last.note_empty {
            self.note_empty_sectors(window, last.origin, out);
        }
        (free_cells, occupied.cells)
    }

    /// Gives m(F) = `mu_free` to the free space of the last scan: each sector's rays from
    /// `origin` (cells) up to its nearest obstacle plus `depth_m` (the cells crossed whole), or
    /// without one up to its farthest ground return; and each ground return's own cell within
    /// its sector's free range. Returns the cells made free.
    fn fill_free(
        &self,
        window: &Window,
        origin: (f64, f64),
        depth_m: f64,
        mu_free: f32,
        out: &mut SensorGrid,
    ) -> usize {
        let sectors = self.obstacle_range.len();
        let mut free_cells = 0usize;
        for s in 0..sectors {
            let (limit_m, whole_cells) = if self.obstacle_range[s].is_finite() {
                (self.obstacle_range[s] + depth_m, true)
            } else {
                (self.ground_range[s], false)
            };
            if limit_m <= 0.0 {
                continue;
            }
            walk_sector(window, origin, s, sectors, limit_m, whole_cells, |idx| {
                // Counted on the first visit: rays of a sector overlap near the sensor.
                free_cells += usize::from(out.m_free()[idx] != mu_free);
                out.set_free(idx, mu_free);
            });
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
        free_cells
    }

    /// Occupies the cell of each obstacle return of the last scan that is not stray: its own
    /// cell, or with `depth_m` its placed cell; with `by_surface`, the returns on the nearest
    /// surface of their fine sector are left to [`SensorModel::occupy_behind_surface`].
    fn occupy_returns(
        &self,
        window: &Window,
        depth_m: f64,
        by_surface: bool,
        masses: Masses,
        out: &mut SensorGrid,
    ) -> Occupied {
        let mut occupied = Occupied::default();
        let cell_size_m = window.cell_size_m();
        for chunk in &self.classified {
            let returns = chunk.obstacle_cells.iter().zip(&chunk.placed_cells);
            for (i, (&(idx, _, range_m), &placed)) in returns.enumerate() {
                if self.stray.is_stray(idx) {
                    continue;
                }
                // A return on the nearest surface of its fine sector is placed by that surface
                // (`occupy_behind_surface`). (`by_surface` implies the fine sectors of the last
                // `build`.)
                if by_surface
                    && chunk
                        .obstacle_fine_sector
                        .get(i)
                        .and_then(|&f| self.surface_range.get(f as usize))
                        .is_some_and(|&surface_m| range_m <= surface_m + cell_size_m)
                {
                    continue;
                }
                let Some(idx) = (if depth_m == 0.0 { Some(idx) } else { placed }) else {
                    continue;
                };
                masses.occupy(out, idx, &mut occupied);
            }
        }
        occupied
    }

    /// Occupies the cells behind the surface drawn through the nearest returns of the fine
    /// sectors, seen from `origin` (cells), with `pose_sigma` the pose's estimated error
    /// ([`SensorModel::set_placed_by_surface`]).
    fn occupy_behind_surface(
        &self,
        window: &Window,
        origin: (f64, f64),
        pose_sigma: (f64, f64),
        masses: Masses,
        out: &mut SensorGrid,
    ) -> Occupied {
        let mut occupied = Occupied::default();
        let cell_size_m = window.cell_size_m();
        let sectors = self.obstacle_range.len();
        let origin_m = (origin.0 * cell_size_m, origin.1 * cell_size_m);
        surface::for_each_cell_behind(
            &self.surface_range,
            &self.nearest_xy,
            std::f64::consts::PI / sectors as f64,
            window,
            origin_m,
            surface::Band {
                depth_m: self.surface_depth_m,
                pose_tolerance: (
                    self.surface_pose_sigmas * pose_sigma.0,
                    self.surface_pose_sigmas * pose_sigma.1,
                ),
                silhouette_faces: self.surface_silhouette_faces,
                convex_corners: self.surface_convex_corners,
            },
            |idx| masses.occupy(out, idx, &mut occupied),
        );
        occupied
    }

    /// Lists as seen empty (without mass) the cells still vacuous along the rays, from
    /// `origin` (cells) to the range limit, of the sectors whose rays met nothing.
    fn note_empty_sectors(&self, window: &Window, origin: (f64, f64), out: &mut SensorGrid) {
        let sectors = self.obstacle_range.len();
        for s in 0..sectors {
            if !self.empty_sector[s] || self.obstacle_range[s].is_finite() {
                continue;
            }
            let max_range_m = self.params.max_range_m;
            walk_sector(window, origin, s, sectors, max_range_m, true, |idx| {
                if out.m_free()[idx] == 0.0 && out.m_occupied()[idx] == 0.0 {
                    out.push_clear(idx);
                }
            });
        }
    }
}

/// The sensor's masses μ_F and μ_O as the grid stores them.
#[derive(Clone, Copy, Debug)]
struct Masses {
    free: f32,
    occupied: f32,
}

/// Cells newly occupied, and how many of them had been counted free.
#[derive(Clone, Copy, Debug, Default)]
struct Occupied {
    cells: usize,
    were_free: usize,
}

impl Occupied {
    /// Adds the counts of `other`.
    fn add(&mut self, other: Occupied) {
        self.cells += other.cells;
        self.were_free += other.were_free;
    }
}

impl Masses {
    /// Gives cell `idx` m(O) = μ_O and takes back its m(F), counting it in `occupied` on the
    /// first visit.
    #[inline(always)]
    fn occupy(self, out: &mut SensorGrid, idx: usize, occupied: &mut Occupied) {
        if out.m_occupied()[idx] != self.occupied {
            occupied.cells += 1;
            occupied.were_free += usize::from(out.m_free()[idx] == self.free && self.free != 0.0);
        }
        out.set_free(idx, 0.0);
        out.set_occupied(idx, self.occupied);
    }
}

/// Marks in `clear` the runs of sectors without a return inside the scanner's field of view.
///
/// The longest run is the part of the circle the scanner does not cover (a 360° scanner's
/// longest gap is left out too: a loss, not an error). A run between two returns is a gap in
/// which rays went out and met nothing, unless the rays themselves are that far apart: it must
/// span two sectors and three mean ray spacings, the spacing taken as the field of view over the
/// `returns` (an upper bound in a scan that lost rays to open space, so the rule only grows
/// stricter there).
fn mark_gaps(any_return: &[bool], returns: usize, clear: &mut [bool]) {
    let n = any_return.len();
    let Some(start) = any_return.iter().position(|&r| r) else {
        return;
    };
    let mut longest = (0, 0);
    for_each_gap(any_return, start, |first, len| {
        if len > longest.1 {
            longest = (first, len);
        }
    });
    // Returns per sector of the field of view; a real gap spans three ray spacings.
    let density = returns as f64 / (n - longest.1).max(1) as f64;
    let min_run = (3.0 / density).ceil().max(2.0);
    for_each_gap(any_return, start, |first, len| {
        if first != longest.0 && len as f64 >= min_run {
            for k in first..first + len {
                clear[(start + k) % n] = true;
            }
        }
    });
}

/// Calls `visit` with each run of sectors without a return, walking the circle from `start`
/// (a sector with one): the run's first sector counted from `start`, and its length.
fn for_each_gap(any_return: &[bool], start: usize, mut visit: impl FnMut(usize, usize)) {
    let n = any_return.len();
    let mut k = 0;
    while k < n {
        if any_return[(start + k) % n] {
            k += 1;
            continue;
        }
        let first = k;
        while k < n && !any_return[(start + k) % n] {
            k += 1;
        }
        visit(first, k - first);
    }
}

/// Walks the rays of sector `s` (of `sectors`) from `origin` (cells) out to `limit_m`, enough
/// of them that neighbours are under a cell apart at the far end (see [`walk_ray`]).
fn walk_sector(
    window: &Window,
    origin: (f64, f64),
    s: usize,
    sectors: usize,
    limit_m: f64,
    whole_cells: bool,
    mut visit: impl FnMut(usize),
) {
    let sector_width = std::f64::consts::TAU / sectors as f64;
    let cell_size_m = window.cell_size_m();
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
            &mut visit,
        );
    }
}

#[cfg(test)]
mod tests;
