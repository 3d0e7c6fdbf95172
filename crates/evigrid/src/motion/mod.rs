//! Motion evidence: scan-to-scan registration of the occupied cells, filtered per track, fed
//! to the PerceptionGrid as belief (the `evigrid` fusion variant; `docs/motion.md`).
//!
//! The paper's method tells moving from static by the conflict between the past and the
//! present of a cell, which a car driving away never creates: its visible face enters cells
//! never seen free, their mass sits on {S, M} and the accumulator breaks the tie to S. This
//! stage measures motion directly, per object, on the grid:
//!
//! 1. the occupied cells of the scan (SensorGrid m(O) > 0) are grouped into 8-connected
//!    clusters (`clusters`);
//! 2. each cluster is registered against the occupied cells of up to eight past frames
//!    (`history`, `register`): the whole-cell shift that explains it best, if it explains
//!    it clearly better than no shift, is its displacement;
//! 3. clusters join tracks whose velocity a Kalman filter follows through occlusions
//!    (`tracks`, `kalman`);
//! 4. each track's velocity and its uncertainty give its cells mass on {M} (moving), on {S}
//!    (static after travelling: a stopped road user) or on Ω∖{M} (static), combined
//!    conjunctively with the cell's mass after the SPEC §5 step (`evidence`); the cells it
//!    touched are decided again.
//!
//! The stage also keeps the boundary-aware map prior of the variant (`context`) and a
//! velocity per cell. Memory is sized by the window; after the first frames nothing is
//! allocated (buffers are kept and only grow to the largest frame seen).

mod clusters;
mod context;
mod evidence;
mod history;
mod kalman;
mod objects;
mod register;
mod tracks;

use std::ops::Range;
use std::time::Instant;

pub use evidence::{MotionMass, combine};
pub use objects::ObjectExtent;

use crate::decision::decide;
use crate::grids::{CELLS_PER_BLOCK, GisGrid, N_SETS, PerceptionGrid, SensorGrid};
use crate::label::Label;
use crate::params::{MotionParams, ResidualPolicy};
use crate::window::{Entered, Window};
use clusters::Clusters;
use geodata::MapContext;
use history::OccupancyHistory;
use rayon::prelude::*;
use register::{Now, Registrar, Registration};
use tracks::{Observation, Tracks};

/// What the motion stage did in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotionStats {
    /// Occupied cells of the scan.
    pub occupied_cells: usize,
    /// Clusters of them.
    pub clusters: usize,
    /// Clusters whose shift was measured.
    pub registered_clusters: usize,
    /// Tracks alive after the frame.
    pub tracks: usize,
    /// Cells given mass on {M}.
    pub moving_cells: usize,
    /// Cells given mass on Ω∖{M}, or on {S} (a stopped track).
    pub static_cells: usize,
    /// Wall time, milliseconds.
    pub ms: f64,
}

/// What the motion stage made of an occupied cell this frame (for diagnosis).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum CellMotion {
    /// Its track was never registered, and no first-sighting evidence.
    Unregistered,
    /// Its track gave no evidence (never registered, or uncertain), but its cells were seen
    /// free in the frames kept: moving evidence.
    EnteredSeenFree,
    /// Registered, slow, too uncertain to be static: no evidence.
    Uncertain,
    /// Registered fast, but its track's net registered displacement is within what the
    /// pose's error explains (`motion.displaced_pose_sigmas`): no evidence.
    WithinPoseError,
    /// Registered slow and certain: m(Ω∖{M}).
    Static,
    /// Static after travelling: m({S}).
    Stopped,
    /// Moving: m({M}).
    Moving,
    /// A cell of a moving cluster explained as static: no evidence.
    StaticPart,
    /// A cell of a moving track whose centre lies outside the track's rectangle
    /// (`object_layer`): `object_outside_static` on Ω∖{M}, or no evidence.
    OutsideObject,
    /// Judged moving, but the cells that moved span more than a road user
    /// (`motion.moving_max_extent_m`): a static thing that the pose's error shifted,
    /// m(Ω∖{M}) as a static track's cells.
    TooLarge,
}

/// One cluster cell of the last frame, for diagnosis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellReport {
    /// Storage index.
    pub idx: u32,
    /// What the stage made of it.
    pub state: CellMotion,
    /// Cells of its cluster.
    pub cluster_cells: u32,
    /// Its cluster's index this frame (cells of one cluster share it).
    pub cluster: u32,
    /// Past frames its cluster's registration used this frame (0: not registered).
    pub frames: u32,
    /// Its track's speed, m/s, and √(σx² + σy²), m/s.
    pub speed_mps: f32,
    /// See `speed_mps`.
    pub sigma_mps: f32,
    /// Its track's registrations.
    pub measurements: u32,
    /// Its track's age, s.
    pub track_age_s: f32,
}

/// An object the stage judged moving this frame: a track and the cells of its cluster that
/// received moving evidence.
///
/// The list ([`MotionStage::moving_objects`]) holds an object only once the evidence suffices
/// (see [`MovingObject::held_back`]); no reported speed exceeds `motion.max_speed_mps`,
/// because a registration that implies a faster shift is refused (the cluster gets no velocity
/// measurement that frame), never clamped; and each object is listed once: tracks of two
/// pieces of one object (within `motion.gate_m`, velocities within 1 m/s or 2σ) are merged
/// into the one with more hits.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MovingObject {
    /// The track's identifier: the same object keeps it from frame to frame while it is
    /// tracked (it coasts through `max_coast_s` unseen).
    pub id: u64,
    /// Centroid of its moving cells, world frame (x east, y north), metres.
    pub position_m: [f64; 2],
    /// Estimated velocity east and north, m/s (the track's filtered velocity).
    pub velocity_mps: [f32; 2],
    /// √(σx² + σy²) of `velocity_mps`, m/s.
    pub sigma_mps: f32,
    /// Time since the track started, s.
    pub age_s: f32,
    /// Frames an observation joined the track.
    pub hits: u32,
    /// The probability that the object exists: a binary Bayes filter over the track's hits and
    /// misses (detection 0.9, false alarm 0.3 per frame, from even odds; `docs/motion.md`).
    pub existence_probability: f32,
    /// Whether the evidence is below the reporting threshold: no velocity measured yet (an
    /// object judged moving because it entered space seen free), fewer than
    /// `motion.report_after_moving_frames` frames judged moving, or an existence probability
    /// under [`REPORT_MIN_EXISTENCE`]. Such objects are listed only with
    /// `motion.report_held_back = true`; their cells get the moving evidence all the same.
    pub held_back: bool,
    /// Cells given moving evidence this frame.
    pub cells: u32,
    /// Its rectangle, with `motion.object_layer` when its heading is known (not written
    /// otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub extent: Option<ObjectExtent>,
}

/// The existence probability an object needs to be reported (two hits without a miss).
pub const REPORT_MIN_EXISTENCE: f32 = 0.9;

/// The motion stage of one window: history, clusters, tracks, and their scratch buffers.
#[derive(Clone, Debug)]
pub struct MotionStage {
    params: MotionParams,
    residual: ResidualPolicy,
    unknown_threshold: f64,
    /// m(Ω∖{M}) given to an occupied cell beside a building: the map's β_B.
    edge_not_moving: f32,
    history: OccupancyHistory,
    clusters: Clusters,
    /// One registrar (search scratch) per worker: clusters are registered in parallel.
    registrars: Vec<Registrar>,
    /// This frame's registration of each cluster.
    registrations: Vec<Option<Registration>>,
    tracks: Tracks,
    observations: Vec<Observation>,
    occupied: Vec<u32>,
    /// The occupied cells of the grid registered on, when it is not the grid labelled
    /// ([`MotionStage::update_registering`]); empty otherwise.
    registered_on: Vec<u32>,
    /// The scan's cells crossed by a ray without a return, and the cells it saw empty without
    /// a return within range ([`SensorGrid::clear_cells`]).
    free: Vec<u32>,
    /// Per cell, whether it is among this frame's clear cells (reset through `clear_list`).
    clear_now: Vec<bool>,
    clear_list: Vec<u32>,
    /// Per cell of the clusters, in cluster order: whether it may have moved
    /// (`Registrar::moved`).
    moved: Vec<bool>,
    /// The boundary-aware map prior (`context`).
    gis: GisGrid,
    velocity_east: Vec<f32>,
    velocity_north: Vec<f32>,
    /// Cells whose velocity is set, to clear them on the next frame.
    velocity_cells: Vec<u32>,
    /// This frame's cluster cells and what the stage made of them.
    cell_states: Vec<CellReport>,
    moving_objects: Vec<MovingObject>,
    /// Past frames each cluster's registration used this frame.
    cluster_frames: Vec<u32>,
    /// The sensor's position this frame, world metres (`set_pose_uncertainty`).
    sensor_xy_m: [f64; 2],
    /// Standard deviation of the pose's error from one scan to another, per axis, metres.
    pose_sigma_m: f64,
    /// The same for the heading, radians.
    pose_sigma_rad: f64,
    /// This frame's cluster centroids, m, and the velocity, m/s, a moving track predicts for
    /// each (`motion.prior_after_moving_frames`; empty when off).
    prior_centroids: Vec<[f64; 2]>,
    /// See `prior_centroids`.
    predictions: Vec<Option<[f64; 2]>>,
    /// The object layer (`object_layer`): extents per track, this frame's returns.
    objects: objects::ObjectLayer,
}

impl MotionStage {
    /// A stage for a `width × height` window, with the motion parameters and the fusion's
    /// residual policy and unknown threshold (the cells it changes are decided again).
    pub fn new(params: &crate::Params, width: usize, height: usize) -> Self {
        let len = width * height;
        Self {
            params: params.motion.clone(),
            residual: params.fusion.residual,
            unknown_threshold: params.decision.unknown_threshold,
            edge_not_moving: params.map.beta_building as f32,
            history: OccupancyHistory::new(len).with_thinning(params.motion.history_thinned),
            clusters: Clusters::new(len),
            registrars: Vec::new(),
            registrations: Vec::new(),
            tracks: Tracks::default(),
            observations: Vec::new(),
            occupied: Vec::new(),
            registered_on: Vec::new(),
            free: Vec::new(),
            clear_now: vec![false; len],
            clear_list: Vec::new(),
            moved: Vec::new(),
            gis: GisGrid::new(width, height),
            velocity_east: vec![0.0; len],
            velocity_north: vec![0.0; len],
            velocity_cells: Vec::new(),
            cell_states: Vec::new(),
            moving_objects: Vec::new(),
            cluster_frames: Vec::new(),
            sensor_xy_m: [0.0; 2],
            pose_sigma_m: 0.0,
            pose_sigma_rad: 0.0,
            prior_centroids: Vec::new(),
            predictions: Vec::new(),
            objects: objects::ObjectLayer::default(),
        }
    }

    /// Forgets everything (the first frame of a drive).
    pub fn reset_all(&mut self) {
        self.history.reset_all();
        self.clusters.clear();
        self.tracks.clear();
        self.objects.clear();
        self.velocity_east.fill(0.0);
        self.velocity_north.fill(0.0);
        self.velocity_cells.clear();
    }

    /// Forgets the cells of a storage range (they entered the window).
    pub fn reset_range(&mut self, range: Range<usize>) {
        self.history.reset_range(range.clone());
        if let Some(v) = self.velocity_east.get_mut(range.clone()) {
            v.fill(0.0);
        }
        if let Some(v) = self.velocity_north.get_mut(range) {
            v.fill(0.0);
        }
    }

    /// Brings the boundary-aware map prior up to date with `source` (the front end's GISGrid)
    /// over the whole window (`entered = None`) or where cells entered.
    pub fn refresh_prior(&mut self, source: &GisGrid, window: &Window, entered: Option<&Entered>) {
        context::refresh(
            &mut self.gis,
            source,
            window,
            entered,
            self.params.building_margin_cells,
        );
    }

    /// The boundary-aware map prior, in storage order.
    pub fn prior(&self) -> &GisGrid {
        &self.gis
    }

    /// Bytes of the stage's per-cell buffers: cluster marks, the history's bit planes, the
    /// boundary-aware context, the marks of the cells seen empty without a return and the two
    /// velocity planes (what the memory budget counts; the lists of a scan's cells and the
    /// tracks scale with the scene, not the window).
    pub fn heap_bytes(&self) -> usize {
        self.clusters.dense_bytes()
            + self.history.dense_bytes()
            + self.gis.heap_bytes()
            + self.clear_now.capacity()
            + 4 * (self.velocity_east.capacity() + self.velocity_north.capacity())
    }

    /// The objects judged moving this frame, with their velocity.
    pub fn moving_objects(&self) -> &[MovingObject] {
        &self.moving_objects
    }

    /// This frame's cluster cells (storage index) and what the stage made of each.
    pub fn cell_states(&self) -> &[CellReport] {
        &self.cell_states
    }

    /// Estimated velocity east of every cell, m/s (0 where no moving track covers it).
    pub fn velocity_east(&self) -> &[f32] {
        &self.velocity_east
    }

    /// Estimated velocity north of every cell, m/s (0 where no moving track covers it).
    pub fn velocity_north(&self) -> &[f32] {
        &self.velocity_north
    }

    /// Where the sensor is this frame (world metres, x east, y north) and how wrong its pose
    /// may be: `sigma_m` per axis (metres) and `sigma_rad` of the heading (radians), for
    /// the next [`MotionStage::update`]. A shift the pose's error explains at a cluster's
    /// range (within `motion.pose_gate_sigmas` of it) is not taken as motion. Non-finite or
    /// negative σ count as 0.
    pub fn set_pose(&mut self, x_m: f64, y_m: f64, sigma_m: f64, sigma_rad: f64) {
        let clean = |v: f64| if v.is_finite() && v > 0.0 { v } else { 0.0 };
        self.sensor_xy_m = [x_m, y_m].map(|v| if v.is_finite() { v } else { 0.0 });
        self.pose_sigma_m = clean(sigma_m);
        self.pose_sigma_rad = clean(sigma_rad);
    }

    /// This frame's obstacle returns (the storage index of each one's cell, its position in
    /// world metres), for the object layer (`motion.object_layer`) of the next
    /// [`MotionStage::update`]; without them no rectangle is fitted.
    pub fn set_returns(&mut self, returns: impl Iterator<Item = (usize, [f64; 2])>) {
        self.objects.set_returns(returns);
    }

    /// Measures the motion of the scan in `sensor` (taken at `time_s`, `dt_s` after the
    /// previous one), combines the evidence into `perception` after its step, and decides the
    /// cells it changed again in `decisions`.
    ///
    /// # Panics
    /// If `perception`, `decisions` or `sensor` hold fewer cells than `window` (the
    /// [`Fusion`](crate::pipeline::Fusion) back end sizes them all from one window).
    pub fn update(
        &mut self,
        window: &Window,
        sensor: &SensorGrid,
        time_s: f64,
        dt_s: f64,
        perception: &mut PerceptionGrid,
        decisions: &mut [Label],
    ) -> MotionStats {
        self.update_registering(window, sensor, sensor, time_s, dt_s, perception, decisions)
    }

    /// As [`MotionStage::update`], but the clusters are registered on the occupied cells of
    /// `returns` (and those, with its free cells, are what the history keeps), while the
    /// occupied cells of `sensor` take the evidence (`[motion] surface_register_on_returns`:
    /// `returns` the SPEC §3 grid of the returns themselves, `sensor` the grid placed by the
    /// surface). A cluster is an 8-connected group of the cells occupied in either grid; its
    /// velocity comes from its cells occupied in `returns`, its centroid too, and only its
    /// cells occupied in `sensor` are given evidence and reported. With `returns` the same
    /// grid as `sensor`, this is [`MotionStage::update`].
    ///
    /// # Panics
    /// As [`MotionStage::update`], and if `returns` holds fewer cells than `window`.
    #[allow(clippy::too_many_arguments)]
    pub fn update_registering(
        &mut self,
        window: &Window,
        sensor: &SensorGrid,
        returns: &SensorGrid,
        time_s: f64,
        dt_s: f64,
        perception: &mut PerceptionGrid,
        decisions: &mut [Label],
    ) -> MotionStats {
        let start = Instant::now();
        let cell_size_m = window.cell_size_m();
        let split = !std::ptr::eq(sensor, returns);

        // 1. The scan's occupied and free cells, only in the blocks the sensor model wrote.
        self.collect_scan_cells(sensor, returns, split);
        let (m_free, m_occupied) = (returns.m_free(), returns.m_occupied());
        let labelled = sensor.m_occupied();
        // The history keeps these; the list grows by the labelled cells for the clustering.
        let registered_len = self.registered_on.len();
        // Whether a cluster cell is registered on (occupied in `returns`), and whether it is
        // given evidence (occupied in `sensor`): both, unless `split`.
        let registers = |c: &clusters::Cell| !split || m_occupied[c.idx as usize] > 0.0;
        let labels = |c: &clusters::Cell| !split || labelled[c.idx as usize] > 0.0;

        // 2-3. Clusters, each registered against the past frames, then observed: a centroid
        // and, when the registration is believable, a velocity.
        self.register_clusters(window, m_free, &registers, split, time_s, dt_s);
        let registered = self.observe_clusters(&registers, cell_size_m);

        // 4. Tracks.
        self.tracks.update(
            &self.observations,
            time_s,
            dt_s,
            self.pose_error(),
            &self.params,
        );

        // 5. Evidence into the grid, the decision again, the velocity planes.
        self.clear_velocities();
        self.cell_states.clear();
        self.moving_objects.clear();
        let (mut moving_cells, mut static_cells) = (0, 0);
        // The history bits of the frames kept, for the seen-free test below.
        let recent = (1..=self.params.history_frames)
            .filter_map(|k| self.history.frame_back(k))
            .fold(0u8, |bits, (bit, _)| bits | bit)
            & self.history.recent_bits();
        let object_layer = self.params.object_layer;
        if object_layer {
            self.objects.group(&self.clusters);
        }
        let pose = self.pose_error();
        let mut first = 0;
        for k in 0..self.clusters.len() {
            let cells = self.clusters.cluster(k);
            let moved = &self.moved[first..first + cells.len()];
            first += cells.len();
            let Some(track) = self.tracks.of_observation(k) else {
                continue;
            };
            let mut mass = evidence::track_mass(track, &self.params);
            let mut state = match mass {
                MotionMass::Vacuous if track.measurements == 0 => CellMotion::Unregistered,
                MotionMass::Vacuous if evidence::within_pose_error(track, &self.params) => {
                    CellMotion::WithinPoseError
                }
                MotionMass::Vacuous => CellMotion::Uncertain,
                MotionMass::Moving(_) => CellMotion::Moving,
                MotionMass::Static(_) => CellMotion::Static,
                MotionMass::Stopped(_) => CellMotion::Stopped,
            };
            // A track that says nothing (a first sighting, with nothing to register against,
            // or a slow one whose registrations cannot tell standing from walking): if most
            // of its cells were seen free in the frames kept, the object entered space seen
            // empty (the cue of SPEC §5's free→occupied conflict, per object). An object that
            // comes out of occlusion, or into the field of view, entered no cell seen free;
            // a static one occupies its cells in every frame.
            // A track held back by the displacement test takes none: its cells come and go
            // with the pose's error, which is what that test keeps from being motion.
            if mass == MotionMass::Vacuous && state != CellMotion::WithinPoseError && recent != 0 {
                let (mut entered, mut counted) = (0usize, 0usize);
                for c in cells.iter().filter(|c| registers(c)) {
                    counted += 1;
                    entered += usize::from(self.history.free_bits(c.idx as usize) & recent != 0);
                }
                let share = entered as f64 / counted.max(1) as f64;
                mass = evidence::entered_seen_free(mass, share, &self.params);
                if mass != MotionMass::Vacuous {
                    state = CellMotion::EnteredSeenFree;
                }
            }
            // Cells that moved spanning more than a road user: a static thing the pose's
            // error shifted (`moving_max_extent_m`), "not moving" as a static track's, unless
            // they are narrow across the track's velocity, or, its heading unsure, across their
            // own long axis (`moving_max_across_m`), and no longer than a bus
            // (`moving_max_length_m`).
            let [vx, vy] = track.velocity;
            if let MotionMass::Moving(_) = mass
                && too_large_to_move(
                    cells,
                    moved,
                    &labels,
                    cell_size_m,
                    [vx.mean_mps, vy.mean_mps],
                    (vx.variance + vy.variance).sqrt(),
                    &self.params,
                )
            {
                mass = MotionMass::Static(self.params.mu_static as f32);
                state = CellMotion::TooLarge;
            }
            let mass = evidence::off_buildings(
                mass,
                cells
                    .iter()
                    .map(|c| self.gis.context.get(c.idx as usize).copied()),
            );
            if let (MotionMass::Static(_), CellMotion::Stopped) = (mass, state) {
                state = CellMotion::Static;
            }
            let [vx, vy] = track.velocity.map(|v| v.mean_mps as f32);
            let sigma_mps = (track.velocity[0].variance + track.velocity[1].variance).sqrt() as f32;
            // The object layer: a moving track's rectangle, fitted to its returns.
            let fitted = match mass {
                MotionMass::Moving(_) if object_layer => {
                    let limits = self.object_limits(self.observations[k].centroid_m);
                    let motion = objects::Motion {
                        id: track.id,
                        velocity_mps: track.velocity.map(|v| v.mean_mps),
                        sigma_mps: f64::from(sigma_mps),
                    };
                    self.objects
                        .fit_cluster(k, motion, self.sensor_xy_m, time_s, limits)
                }
                _ => None,
            };
            let within = |c: &clusters::Cell| {
                fitted.as_ref().map(|(rect, _)| {
                    rect.contains([
                        (c.col as f64 + 0.5) * cell_size_m,
                        (c.row as f64 + 0.5) * cell_size_m,
                    ])
                })
            };
            // What each cell takes: with a rectangle, a placed cell of the track whose centre
            // it holds takes the track's evidence, one outside it does not
            // (`object_outside_static` on Ω∖{M}, or nothing). A static part of a moving
            // cluster takes nothing; a cell only of the grid registered on, nothing either
            // (given the moving evidence inside the rectangle, they were measured: more false
            // M than hits, `docs/motion.md`, "An object layer").
            let outside = if self.params.object_outside_static > 0.0 {
                MotionMass::Static(self.params.object_outside_static as f32)
            } else {
                MotionMass::Vacuous
            };
            // A return's cell of a static cluster seen free and never holding a return in the
            // frames kept: an object that entered space seen empty beside the static one
            // (`static_part_entered`).
            let static_part_entered = self.params.static_part_entered && recent != 0;
            let history = &self.history;
            let entered_cell = |c: &clusters::Cell| {
                let idx = c.idx as usize;
                history.free_bits(idx) & recent != 0 && history.bits(idx) & recent == 0
            };
            let of_cell = |c: &clusters::Cell, moved: bool| -> Option<(MotionMass, CellMotion)> {
                if !labels(c) {
                    return None;
                }
                let within = within(c);
                Some(match (mass, within) {
                    (MotionMass::Moving(_), _) if !moved => {
                        (MotionMass::Vacuous, CellMotion::StaticPart)
                    }
                    (MotionMass::Static(_) | MotionMass::Stopped(_), _)
                        if static_part_entered
                            && state != CellMotion::TooLarge
                            && registers(c)
                            && entered_cell(c) =>
                    {
                        (
                            MotionMass::Moving(self.params.mu_moving as f32),
                            CellMotion::EnteredSeenFree,
                        )
                    }
                    (MotionMass::Moving(_), Some(false)) => (outside, CellMotion::OutsideObject),
                    _ => (mass, state),
                })
            };
            let moving_before = moving_cells;
            let labelled_cells = cells.iter().filter(|c| labels(c)).count() as u32;
            // Where the cluster's cells take no moving evidence, an M decision is the step's
            // own conflict: "not moving" where the pose's error explains it
            // (`unsupported_pose_sigmas`).
            let unsupported = evidence::unsupported_by_motion(
                pose.displacement_sigma_m(self.observations[k].centroid_m),
                cell_size_m,
                &self.params,
            );
            let (residual, threshold) = (self.residual, self.unknown_threshold);
            // The cell's M decision, if any, becomes "not moving", as this frame's decision
            // only: the grid keeps the step's masses (fused, it was measured no better).
            let veto = |idx: usize, perception: &PerceptionGrid, decisions: &mut [Label]| {
                if decisions[idx] != Label::M {
                    return;
                }
                let mut m = perception.cell_masses(idx);
                combine(&mut m, unsupported, residual);
                decisions[idx] = decide(&m, perception.seen()[idx] != 0, threshold);
            };
            // A track held by the displacement test (`WithinPoseError`) keeps the step's M:
            // it is as often a mover not yet beyond the pose's error (measured: the veto there
            // lost validation's moving IoU and dynamic accuracy).
            let no_support = matches!(state, CellMotion::Unregistered | CellMotion::Uncertain);
            for (c, &moved) in cells.iter().zip(moved) {
                // A cell only of the grid registered on takes no evidence.
                let Some((mass, cell_state)) = of_cell(c, moved) else {
                    if unsupported != MotionMass::Vacuous {
                        veto(c.idx as usize, perception, decisions);
                    }
                    continue;
                };
                let idx = c.idx as usize;
                self.cell_states.push(CellReport {
                    idx: c.idx,
                    state: cell_state,
                    cluster_cells: labelled_cells,
                    cluster: k as u32,
                    frames: self.cluster_frames.get(k).copied().unwrap_or(0),
                    speed_mps: vx.hypot(vy),
                    sigma_mps,
                    measurements: track.measurements,
                    track_age_s: (time_s - track.first_seen_s) as f32,
                });
                match mass {
                    MotionMass::Vacuous => {
                        if no_support && unsupported != MotionMass::Vacuous {
                            veto(idx, perception, decisions);
                        }
                        continue;
                    }
                    MotionMass::Moving(_) => {
                        moving_cells += 1;
                        self.velocity_east[idx] = vx;
                        self.velocity_north[idx] = vy;
                        self.velocity_cells.push(c.idx);
                    }
                    MotionMass::Static(_) | MotionMass::Stopped(_) => static_cells += 1,
                }
                let mut m = perception.cell_masses(idx);
                combine(&mut m, mass, self.residual);
                // The outside label and a stop's, unfused, are this frame's decision only: the
                // grid keeps the step's masses, and the car that covers the cell next frame, or
                // pulls away from the stop, meets no static mass there.
                let this_frame_only = (cell_state == CellMotion::OutsideObject
                    && !self.params.object_outside_fused)
                    || (cell_state == CellMotion::Stopped && !self.params.stopped_fused);
                if !this_frame_only {
                    write_cell(perception, idx, &m);
                }
                decisions[idx] = decide(&m, perception.seen()[idx] != 0, self.unknown_threshold);
            }
            if let MotionMass::Moving(_) = mass {
                let cells_moving = (moving_cells - moving_before) as u32;
                let object = MovingObject {
                    id: track.id,
                    position_m: self.observations[k].centroid_m,
                    velocity_mps: [vx, vy],
                    sigma_mps,
                    age_s: (time_s - track.first_seen_s) as f32,
                    hits: track.hits,
                    existence_probability: track.existence_probability() as f32,
                    held_back: is_held_back(track, state, &self.params),
                    cells: cells_moving,
                    extent: fitted.map(|(_, extent)| extent),
                };
                let fast = f64::from(vx.hypot(vy)) > self.params.max_speed_mps;
                if cells_moving > 0 && !fast && (!object.held_back || self.params.report_held_back)
                {
                    self.moving_objects.push(object);
                }
            }
        }

        self.keep_building_edges_not_moving(perception, decisions);

        merge_pieces(&mut self.moving_objects, self.params.gate_m);
        if object_layer {
            self.objects.forget_before(time_s - self.params.max_coast_s);
        }

        // 6. This frame joins the history.
        let registered_on = if split {
            &self.registered_on[..registered_len]
        } else {
            &self.occupied[..]
        };
        self.history.push(registered_on, &self.free, time_s);
        MotionStats {
            occupied_cells: self.occupied.len(),
            clusters: self.clusters.len(),
            registered_clusters: registered,
            tracks: self.tracks.len(),
            moving_cells,
            static_cells,
            ms: start.elapsed().as_secs_f64() * 1e3,
        }
    }

    /// Step 1 of [`MotionStage::update_registering`]: the occupied cells of `returns`
    /// (registered on) and of `sensor` (labelled), one list unless `split`, the free cells of
    /// `returns`, and the cells its rays crossed without a return (`clear_now`).
    fn collect_scan_cells(&mut self, sensor: &SensorGrid, returns: &SensorGrid, split: bool) {
        self.occupied.clear();
        self.registered_on.clear();
        self.free.clear();
        let (m_free, m_occupied) = (returns.m_free(), returns.m_occupied());
        let registered_on = if split {
            &mut self.registered_on
        } else {
            &mut self.occupied
        };
        for cells in returns.written_cells() {
            for idx in cells {
                if m_occupied[idx] > 0.0 {
                    registered_on.push(idx as u32);
                } else if m_free[idx] > 0.0 {
                    self.free.push(idx as u32);
                }
            }
        }
        let labelled = sensor.m_occupied();
        if split {
            for cells in sensor.written_cells() {
                self.occupied.extend(
                    cells
                        .filter(|&idx| labelled[idx] > 0.0)
                        .map(|idx| idx as u32),
                );
            }
        }
        for &idx in &self.clear_list {
            if let Some(c) = self.clear_now.get_mut(idx as usize) {
                *c = false;
            }
        }
        self.clear_list.clear();
        // They hold no mass (the sensor model lists them after the masses); a cell may repeat.
        for &idx in returns.clear_cells() {
            if let Some(c) = self.clear_now.get_mut(idx as usize)
                && !*c
            {
                *c = true;
                self.clear_list.push(idx);
                self.free.push(idx);
            }
        }
    }

    /// Steps 2-3: the clusters labelled, each registered against the past frames
    /// (`registrations`, and per cell whether it `moved`): independent searches, run in
    /// parallel over a few contiguous runs of clusters of about equal cell counts, each with its
    /// own scratch, writing its own part of the outputs. With `split`, a cluster is registered
    /// on its cells that `registers`.
    fn register_clusters(
        &mut self,
        window: &Window,
        m_free: &[f32],
        registers: &(impl Fn(&clusters::Cell) -> bool + Sync),
        split: bool,
        time_s: f64,
        dt_s: f64,
    ) {
        let cell_size_m = window.cell_size_m();
        if split {
            // Both lists, a cell possibly in each: the labelling takes a cell once.
            self.registered_on.extend_from_slice(&self.occupied);
            self.clusters.label(window, &self.registered_on);
        } else {
            self.clusters.label(window, &self.occupied);
        }
        let n_clusters = self.clusters.len();
        let total_cells: usize = (0..n_clusters)
            .map(|k| self.clusters.cluster(k).len())
            .sum();
        self.moved.clear();
        self.moved.resize(total_cells, false);
        self.registrations.clear();
        self.registrations.resize(n_clusters, None);
        // The prior of a moving track's prediction, per cluster (off: none).
        self.prior_centroids.clear();
        if self.params.prior_after_moving_frames > 0 {
            for k in 0..n_clusters {
                let centroid_m =
                    Self::registered_centroid_m(self.clusters.cluster(k), registers, cell_size_m);
                self.prior_centroids.push(centroid_m);
            }
        }
        self.tracks.predictions(
            &self.prior_centroids,
            time_s,
            dt_s,
            &self.params,
            &mut self.predictions,
        );
        let parts = rayon::current_num_threads().clamp(1, 64);
        if self.registrars.len() < parts {
            self.registrars.resize_with(parts, Registrar::default);
        }
        {
            let (clusters, history, params) = (&self.clusters, &self.history, &self.params);
            let predictions = &self.predictions[..];
            let clear_now = &self.clear_now[..];
            let sensor_cell = (
                self.sensor_xy_m[0] / cell_size_m,
                self.sensor_xy_m[1] / cell_size_m,
            );
            let (pose_sigma_cells, pose_sigma_rad) =
                (self.pose_sigma_m / cell_size_m, self.pose_sigma_rad);
            let mut runs = Vec::with_capacity(parts);
            let (mut moved, mut registrations) = (&mut self.moved[..], &mut self.registrations[..]);
            let mut registrars = self.registrars.iter_mut();
            let (mut k, mut done_cells) = (0, 0);
            for part in 0..parts {
                let target = total_cells * (part + 1) / parts;
                let start = k;
                let mut cells_in_run = 0;
                while k < n_clusters && (done_cells + cells_in_run < target || part + 1 == parts) {
                    cells_in_run += clusters.cluster(k).len();
                    k += 1;
                }
                done_cells += cells_in_run;
                let (run_moved, rest_moved) = std::mem::take(&mut moved).split_at_mut(cells_in_run);
                let (run_regs, rest_regs) =
                    std::mem::take(&mut registrations).split_at_mut(k - start);
                (moved, registrations) = (rest_moved, rest_regs);
                if let Some(registrar) = registrars.next() {
                    runs.push((start..k, run_moved, run_regs, registrar));
                }
            }
            runs.into_par_iter()
                .for_each(|(range, run_moved, run_regs, registrar)| {
                    let mut first = 0;
                    for (k, slot) in range.zip(run_regs.iter_mut()) {
                        let cells = clusters.cluster(k);
                        let now = Now {
                            time_s,
                            clusters,
                            cluster: k as u32,
                            m_free,
                            clear_now,
                            sensor_cell,
                            pose_sigma_cells,
                            pose_sigma_rad,
                            predicted_cells_per_s: predictions
                                .get(k)
                                .copied()
                                .flatten()
                                .map(|[vx, vy]| (vx / cell_size_m, vy / cell_size_m)),
                        };
                        *slot = if split {
                            let mut own = std::mem::take(&mut registrar.own_cells);
                            own.clear();
                            own.extend(cells.iter().filter(|c| registers(c)));
                            let registration =
                                registrar.register(&own, window, history, now, params);
                            registrar.own_cells = own;
                            registration
                        } else {
                            registrar.register(cells, window, history, now, params)
                        };
                        for (flag, c) in run_moved[first..first + cells.len()].iter_mut().zip(cells)
                        {
                            *flag = slot.is_none() || registrar.moved(c);
                        }
                        first += cells.len();
                    }
                });
        }
    }

    /// The centroid, metres, of the cells of `cells` that `registers` (the registration's own).
    fn registered_centroid_m(
        cells: &[clusters::Cell],
        registers: &impl Fn(&clusters::Cell) -> bool,
        cell_size_m: f64,
    ) -> [f64; 2] {
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0usize);
        for c in cells.iter().filter(|c| registers(c)) {
            sx += c.col as f64 + 0.5;
            sy += c.row as f64 + 0.5;
            n += 1;
        }
        let n = n.max(1) as f64;
        [sx / n * cell_size_m, sy / n * cell_size_m]
    }

    /// Each cluster's observation for the tracks: its centroid and, when it was registered at
    /// a believable speed, its velocity. Returns how many clusters have a velocity.
    fn observe_clusters(
        &mut self,
        registers: &impl Fn(&clusters::Cell) -> bool,
        cell_size_m: f64,
    ) -> usize {
        self.observations.clear();
        self.cluster_frames.clear();
        let mut registered = 0;
        for k in 0..self.clusters.len() {
            let centroid_m =
                Self::registered_centroid_m(self.clusters.cluster(k), registers, cell_size_m);
            let registration = self.registrations[k];
            self.cluster_frames
                .push(registration.map_or(0, |r| r.frames as u32));
            // A registration that implies a speed above `max_speed_mps` is refused: no
            // velocity measured this frame (the search's per-axis reach lets a diagonal shift
            // exceed it, and two shifts from different pasts can too).
            let velocity = registration
                .map(|r| {
                    let sigma =
                        r.variance_cells(self.params.shift_sigma_cells).sqrt() * cell_size_m;
                    let (vx, vy) = r.velocity_cells_per_s;
                    ([vx * cell_size_m, vy * cell_size_m], sigma * sigma)
                })
                .filter(|([vx, vy], _)| vx.hypot(*vy) <= self.params.max_speed_mps);
            registered += usize::from(velocity.is_some());
            let span_s = match registration {
                Some(r) if velocity.is_some() && r.sum_span > 0.0 => r.sum_span_sq / r.sum_span,
                _ => 0.0,
            };
            self.observations.push(Observation {
                centroid_m,
                velocity,
                span_s,
            });
        }
        registered
    }

    /// The object layer's limits for an object centred at `centroid_m`: the `[motion]
    /// object_*` keys, the margin widened by `surface_pose_sigmas` times the pose's error at
    /// the object's range.
    fn object_limits(&self, centroid_m: [f64; 2]) -> objects::Limits {
        let range_m =
            (centroid_m[0] - self.sensor_xy_m[0]).hypot(centroid_m[1] - self.sensor_xy_m[1]);
        let pose_m = self.pose_sigma_m.hypot(range_m * self.pose_sigma_rad);
        objects::Limits {
            heading_tan: self.params.object_heading_max_deg.to_radians().tan(),
            heading_search_deg: self.params.object_heading_fit_deg,
            max_length_m: self.params.object_max_length_m,
            max_width_m: self.params.object_max_width_m,
            margin_m: self.params.object_margin_m + self.params.surface_pose_sigmas * pose_m,
            small_depth_m: self.params.object_small_depth_m,
            fit_unsure: self.params.object_fit_unsure_heading,
            far_margin_m: self.params.object_far_margin_m,
        }
    }

    /// This frame's pose and its estimated error, for the tracks' displacement test.
    fn pose_error(&self) -> tracks::PoseError {
        tracks::PoseError {
            sensor_xy_m: self.sensor_xy_m,
            sigma_m: self.pose_sigma_m,
            sigma_rad: self.pose_sigma_rad,
        }
    }

    /// Zeroes the velocity planes where the last frame wrote them.
    fn clear_velocities(&mut self) {
        for &idx in &self.velocity_cells {
            if let Some(v) = self.velocity_east.get_mut(idx as usize) {
                *v = 0.0;
            }
            if let Some(v) = self.velocity_north.get_mut(idx as usize) {
                *v = 0.0;
            }
        }
        self.velocity_cells.clear();
    }

    /// The map says a cell beside a building holds the façade or free space, not a mobile
    /// object. The SPEC §5 step puts a cell's free→occupied conflict on {M} whatever its prior,
    /// and there the conflict is the façade: rays cross the cell, then end in it, as the ego
    /// moves. The prior's "no mobile object" (β_B on Ω∖{M}) is applied to those cells after the
    /// step, to every cell that could have gained {M} (occupied now).
    fn keep_building_edges_not_moving(
        &self,
        perception: &mut PerceptionGrid,
        decisions: &mut [Label],
    ) {
        let edge = MotionMass::Static(self.edge_not_moving);
        for &idx in &self.occupied {
            let idx = idx as usize;
            if self.gis.context.get(idx) != Some(&MapContext::BuildingEdge) {
                continue;
            }
            let mut m = perception.cell_masses(idx);
            combine(&mut m, edge, self.residual);
            write_cell(perception, idx, &m);
            decisions[idx] = decide(&m, perception.seen()[idx] != 0, self.unknown_threshold);
        }
    }
}

/// Whether a track judged moving is too large to be a road user: the cells of its cluster
/// that moved (`moved`, one flag per cell of `cells`) and take evidence (`labels`) span more than
/// `moving_max_extent_m`, and they are not a narrow mover (at most `moving_max_across_m` across
/// `velocity_mps` and at most `moving_max_length_m` in all: a bus or a truck along its length).
fn too_large_to_move(
    cells: &[clusters::Cell],
    moved: &[bool],
    labels: &impl Fn(&clusters::Cell) -> bool,
    cell_size_m: f64,
    velocity_mps: [f64; 2],
    velocity_sigma_mps: f64,
    params: &MotionParams,
) -> bool {
    if params.moving_max_extent_m <= 0.0 {
        return false;
    }
    let moved_cells = || {
        cells
            .iter()
            .zip(moved)
            .filter(|(c, m)| **m && labels(c))
            .map(|(c, _)| c)
    };
    let extent_m = moved_extent_m(moved_cells(), cell_size_m);
    if extent_m <= params.moving_max_extent_m {
        return false;
    }
    let within_length = params.moving_max_length_m <= 0.0 || extent_m <= params.moving_max_length_m;
    let narrow_across = |direction: [f64; 2]| {
        moved_across_m(moved_cells(), cell_size_m, direction)
            .is_some_and(|across| across <= params.moving_max_across_m)
    };
    let narrow = params.moving_max_across_m > 0.0
        && within_length
        && (narrow_across(velocity_mps)
            || (heading_unsure(velocity_mps, velocity_sigma_mps, params)
                && principal_axis(moved_cells()).is_some_and(narrow_across)));
    !narrow
}

/// Whether a track's heading is too unsure to measure its span across its velocity alone:
/// its velocity σ is at least `moving_across_own_axis_unsure` of its speed (0: never).
fn heading_unsure(velocity_mps: [f64; 2], velocity_sigma_mps: f64, params: &MotionParams) -> bool {
    params.moving_across_own_axis_unsure > 0.0
        && velocity_sigma_mps
            >= params.moving_across_own_axis_unsure * velocity_mps[0].hypot(velocity_mps[1])
}

/// The unit direction (east, north) of the long axis of `cells`' centres: the principal
/// axis of their spread, at ½·atan2(2·s_xy, s_xx − s_yy). `None` without cells.
fn principal_axis<'a>(cells: impl Iterator<Item = &'a clusters::Cell>) -> Option<[f64; 2]> {
    let (mut n, mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for c in cells {
        let (x, y) = (c.col as f64, c.row as f64);
        n += 1.0;
        sx += x;
        sy += y;
        sxx += x * x;
        syy += y * y;
        sxy += x * y;
    }
    if n == 0.0 {
        return None;
    }
    let (mx, my) = (sx / n, sy / n);
    let (cxx, cyy, cxy) = (sxx / n - mx * mx, syy / n - my * my, sxy / n - mx * my);
    let angle = 0.5 * (2.0 * cxy).atan2(cxx - cyy);
    Some([angle.cos(), angle.sin()])
}

/// The diagonal, metres, of the box (along east and north) of `cells`; 0 without any.
fn moved_extent_m<'a>(cells: impl Iterator<Item = &'a clusters::Cell>, cell_size_m: f64) -> f64 {
    let mut bounds: Option<[i64; 4]> = None;
    for c in cells {
        let (col, row) = (c.col, c.row);
        bounds = Some(match bounds {
            None => [col, col, row, row],
            Some([c0, c1, r0, r1]) => [c0.min(col), c1.max(col), r0.min(row), r1.max(row)],
        });
    }
    bounds.map_or(0.0, |[c0, c1, r0, r1]| {
        ((c1 - c0 + 1) as f64 * cell_size_m).hypot((r1 - r0 + 1) as f64 * cell_size_m)
    })
}

/// The span, metres, of `cells` across `velocity_mps` (east, north): the spread of their centres
/// along the velocity's normal, plus one cell's width seen along it (`cell_size_m · (|n_x| +
/// |n_y|)`). `None` without cells or without a direction (speed under 1 mm/s).
fn moved_across_m<'a>(
    cells: impl Iterator<Item = &'a clusters::Cell>,
    cell_size_m: f64,
    velocity_mps: [f64; 2],
) -> Option<f64> {
    let speed = velocity_mps[0].hypot(velocity_mps[1]);
    if speed.is_nan() || speed <= 1e-3 {
        return None;
    }
    let normal = [-velocity_mps[1] / speed, velocity_mps[0] / speed];
    let mut span: Option<(f64, f64)> = None;
    for c in cells {
        let along_normal = (c.col as f64 * normal[0] + c.row as f64 * normal[1]) * cell_size_m;
        span = Some(match span {
            None => (along_normal, along_normal),
            Some((lo, hi)) => (lo.min(along_normal), hi.max(along_normal)),
        });
    }
    span.map(|(lo, hi)| hi - lo + cell_size_m * (normal[0].abs() + normal[1].abs()))
}

/// Whether a track judged moving is held back from the moving-object list (`docs/motion.md`,
/// "The moving-object list"): judged moving only because it entered space seen free, never
/// registered, judged moving in fewer than `report_after_moving_frames` frames, or of an
/// existence probability below [`REPORT_MIN_EXISTENCE`].
fn is_held_back(track: &tracks::Track, state: CellMotion, params: &MotionParams) -> bool {
    state == CellMotion::EnteredSeenFree
        || track.measurements == 0
        || (track.moving_frames as usize) < params.report_after_moving_frames
        || (track.existence_probability() as f32) < REPORT_MIN_EXISTENCE
}

/// Merges the objects that are pieces of one (centroids within `gate_m`, velocities within
/// 1 m/s or twice their σ) into the one with more hits (reported before held back, then more
/// hits, then the older id), its position the cell-weighted centroid: one id per object.
fn merge_pieces(objects: &mut Vec<MovingObject>, gate_m: f64) {
    objects.sort_by(|a, b| {
        a.held_back
            .cmp(&b.held_back)
            .then(b.hits.cmp(&a.hits))
            .then(a.id.cmp(&b.id))
    });
    let mut kept: Vec<MovingObject> = Vec::with_capacity(objects.len());
    for o in objects.drain(..) {
        let piece_of = kept.iter_mut().find(|k| {
            let d = (k.position_m[0] - o.position_m[0]).hypot(k.position_m[1] - o.position_m[1]);
            let dv = (k.velocity_mps[0] - o.velocity_mps[0])
                .hypot(k.velocity_mps[1] - o.velocity_mps[1]);
            d <= gate_m && dv <= (2.0 * k.sigma_mps.max(o.sigma_mps)).max(1.0)
        });
        match piece_of {
            Some(k) => {
                let (a, b) = (f64::from(k.cells), f64::from(o.cells));
                for (p, q) in k.position_m.iter_mut().zip(o.position_m) {
                    *p = (*p * a + q * b) / (a + b).max(1.0);
                }
                k.cells += o.cells;
            }
            None => kept.push(o),
        }
    }
    *objects = kept;
}

/// Writes one cell's masses, keeping the grid's notes true: the block's bits gain the planes
/// now non-zero, and, as [`combine`] moves mass on A only to A ∩ {M} or A∖{M} (or ∅, Ω), masses
/// stay on the sets the step can reach, so the grid is not marked as leaving them (which
/// would make every later step read all 32 planes).
fn write_cell(perception: &mut PerceptionGrid, idx: usize, m: &[f32; N_SETS]) {
    let planes = perception.planes_mut();
    let mut bits = 0;
    for (set, (plane, &v)) in planes.masses.into_iter().zip(m).enumerate() {
        plane[idx] = v;
        if v.to_bits() != 0 {
            bits |= 1 << set;
        }
    }
    planes.nonzero[idx / CELLS_PER_BLOCK] |= bits;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(id: u64, x: f64, vx: f32, hits: u32, cells: u32) -> MovingObject {
        MovingObject {
            id,
            position_m: [x, 0.0],
            velocity_mps: [vx, 0.0],
            sigma_mps: 0.3,
            age_s: 1.0,
            hits,
            existence_probability: 0.99,
            held_back: false,
            cells,
            extent: None,
        }
    }

    /// A car driving away from a sensor to the west, its rear face one cell a frame east
    /// (0.1 s, 0.5 m cells: 5 m/s) on rows 10-13: in frame `t` the face is column 10 + t.
    /// `returns` holds the face and one return in front of it, at (9 + t, 10); `placed`
    /// holds the face and the four columns behind it (a surface placement five cells deep);
    /// both see free the rows' cells from column 2 up to the face.
    fn driving_away(t: i64, window: &Window) -> (SensorGrid, SensorGrid) {
        let (w, h) = (window.width(), window.height());
        let (mut returns, mut placed) = (SensorGrid::new(w, h), SensorGrid::new(w, h));
        let face = 10 + t;
        let at = |col: i64, row: i64| window.storage_index(col, row).unwrap_or(0);
        for row in 10..=13 {
            for col in 2..face {
                if (col, row) != (face - 1, 10) {
                    returns.set_free(at(col, row), 0.7);
                    placed.set_free(at(col, row), 0.7);
                }
            }
            returns.set_occupied(at(face, row), 0.8);
            for col in face..face + 5 {
                placed.set_occupied(at(col, row), 0.8);
            }
        }
        returns.set_occupied(at(face - 1, 10), 0.8);
        (returns, placed)
    }

    #[test]
    fn a_car_driving_off_under_pose_error_is_held_until_it_has_left_it() {
        let window = Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let (w, h) = (window.width(), window.height());
        let params = crate::Params::default();
        let mut stage = MotionStage::new(&params, w, h);
        let mut perception = PerceptionGrid::new(w, h);
        let mut decisions = vec![Label::Unknown; w * h];
        let mut states = Vec::new();
        for t in 0..3 {
            // 0.3 m of pose error per axis, heading exact: a static object's apparent
            // displacement has σ = 0.3 · √2 = 0.42426 m, 1.5 σ (the default) 0.63640 m.
            stage.set_pose(0.0, 0.0, 0.3, 0.0);
            let (returns, placed) = driving_away(t, &window);
            stage.update_registering(
                &window,
                &placed,
                &returns,
                0.1 * t as f64,
                0.1,
                &mut perception,
                &mut decisions,
            );
            let mut now: Vec<CellMotion> = stage.cell_states().iter().map(|r| r.state).collect();
            now.dedup();
            states.push(now);
        }
        // Frame 0: nothing to register against. Frame 1: one cell east in 0.1 s, 5 m/s over a
        // span of 0.1 s: 0.5 m registered, within 0.636 m: held, no evidence. Frame 2: one
        // more cell, 5 m/s × 0.1 s more: 1.0 m, beyond it: moving.
        assert_eq!(
            states,
            vec![
                vec![CellMotion::Unregistered],
                vec![CellMotion::WithinPoseError],
                vec![CellMotion::Moving]
            ]
        );
    }

    /// Frames 0 to `last` of [`driving_away`] under 0.3 m of pose error per axis, with
    /// `unsupported_pose_sigmas` = `k`. Before frame `last`'s update, three cells are given the
    /// masses the SPEC §5 step leaves after a free→occupied conflict, and decided M as it
    /// decides them: a cell of the face, (10 + last, 11); the return in front of the face,
    /// (9 + last, 10), which the placed grid does not occupy; and (30, 30), in no cluster.
    /// Returns the face's state, and the three cells' masses and decisions after that frame.
    fn step_conflict_after(k: f64, last: i64) -> (CellMotion, Vec<([f32; N_SETS], Label)>) {
        use crate::grids::{OMEGA, class};
        let window = Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let (w, h) = (window.width(), window.height());
        let mut params = crate::Params::default();
        params.motion.unsupported_pose_sigmas = k;
        let mut stage = MotionStage::new(&params, w, h);
        let mut perception = PerceptionGrid::new(w, h);
        perception.seen_mut().fill(1);
        let mut decisions = vec![Label::Unknown; w * h];
        let at = |col: i64, row: i64| window.storage_index(col, row).unwrap_or(0);
        let cells = [at(10 + last, 11), at(9 + last, 10), at(30, 30)];
        for t in 0..=last {
            stage.set_pose(0.0, 0.0, 0.3, 0.0);
            if t == last {
                // m({M}) 0.56, m({I, U, S, M}) 0.24, m(Ω) 0.2: BetP(M) = 0.56 + 0.06 + 0.04.
                let mut m = [0.0; N_SETS];
                m[class::M] = 0.56;
                m[class::I | class::U | class::S | class::M] = 0.24;
                m[OMEGA] = 0.2;
                for &idx in &cells {
                    perception.set_cell_masses(idx, &m);
                    decisions[idx] = decide(&m, true, params.decision.unknown_threshold);
                }
            }
            let (returns, placed) = driving_away(t, &window);
            stage.update_registering(
                &window,
                &placed,
                &returns,
                0.1 * t as f64,
                0.1,
                &mut perception,
                &mut decisions,
            );
        }
        let face = stage
            .cell_states()
            .iter()
            .find(|r| r.idx as usize == cells[0])
            .map(|r| r.state);
        let after = cells
            .iter()
            .map(|&idx| (perception.cell_masses(idx), decisions[idx]))
            .collect();
        (
            face.unwrap_or_else(|| panic!("the face is a cluster cell")),
            after,
        )
    }

    #[test]
    fn the_steps_own_m_on_cells_without_moving_evidence_is_not_moving_under_pose_error() {
        use crate::grids::{OMEGA, class};
        let mut conflict = [0.0; N_SETS];
        conflict[class::M] = 0.56;
        conflict[class::I | class::U | class::S | class::M] = 0.24;
        conflict[OMEGA] = 0.2;
        let m_everywhere = vec![(conflict, Label::M); 3];
        // Off: the step's M stays on all three.
        assert_eq!(
            step_conflict_after(0.0, 0),
            (CellMotion::Unregistered, m_everywhere.clone())
        );
        // The apparent shift's σ is 0.3 · √2 = 0.424264 m at any range (heading exact).
        // k = 0.5: 0.212 m, not half a 0.5 m cell: nothing changes.
        assert_eq!(
            step_conflict_after(0.5, 0),
            (CellMotion::Unregistered, m_everywhere.clone())
        );
        // k = 6 (the default): 2.55 m. Frame 0, nothing to register against: the face's cell
        // and the return's take m(Ω∖{M}) = 0.9 for the decision: {M} keeps 0.056 and gives
        // 0.504 to Ω (the conflict, `to_omega`), {I, U, S, M} keeps 0.024 and gives 0.216 to
        // {I, U, S}, Ω keeps 0.02 and gives 0.18 to Ω∖{M}; m(Ω) = 0.524 > 0.5: unknown. The
        // grid keeps the step's masses. The cell in no cluster keeps its M.
        assert_eq!(crate::Params::default().motion.unsupported_pose_sigmas, 6.0);
        let unknown = vec![
            (conflict, Label::Unknown),
            (conflict, Label::Unknown),
            (conflict, Label::M),
        ];
        assert_eq!(
            step_conflict_after(6.0, 0),
            (CellMotion::Unregistered, unknown)
        );
        // Frame 1: the face is held by the displacement test (0.5 m registered within
        // 1.5 σ = 0.636 m): its M stays; the return in front of it does not.
        assert_eq!(
            step_conflict_after(6.0, 1),
            (
                CellMotion::WithinPoseError,
                vec![
                    (conflict, Label::M),
                    (conflict, Label::Unknown),
                    (conflict, Label::M)
                ]
            )
        );
    }

    #[test]
    fn a_whole_wall_that_slides_is_too_large_to_move_and_a_car_is_not() {
        // An object of `len` cells along a row (columns 4 on) moves one row north a frame
        // (0.5 m in 0.1 s: 5 m/s) from row 18, rows 16-24 seen free around it from column 2
        // to 38: what a façade does when a scan's pose is off, or a car driving side-on.
        // Exact poses (σ 0, refinement off).
        // The cells that moved span len × 0.5 m along east and 0.5 m along north: a 30-cell
        // wall √(15² + 0.5²) = 15.008 m, an 8-cell car √(4² + 0.5²) = 4.031 m.
        let window = Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let (w, h) = (window.width(), window.height());
        let at = |col: i64, row: i64| window.storage_index(col, row).unwrap_or(0);
        let last_states = |len: i64, max_extent_m: f64| {
            let mut params = crate::Params::default();
            params.motion.moving_max_extent_m = max_extent_m;
            // The extent alone (the 8-cell car spans 4 m across its velocity).
            params.motion.moving_max_across_m = 0.0;
            let mut stage = MotionStage::new(&params, w, h);
            let mut perception = PerceptionGrid::new(w, h);
            let mut decisions = vec![Label::Unknown; w * h];
            for t in 0..4 {
                let mut grid = SensorGrid::new(w, h);
                for row in 16..=24 {
                    for col in 2..39 {
                        if row == 18 + t && (4..4 + len).contains(&col) {
                            grid.set_occupied(at(col, row), 0.8);
                        } else {
                            grid.set_free(at(col, row), 0.7);
                        }
                    }
                }
                if t == 3 {
                    // What the SPEC §5 step would have made of the cells the object entered
                    // (free before, occupied now): m({M}) = 0.5, m(Ω) = 0.5.
                    let mut m = [0.0; N_SETS];
                    (m[crate::grids::class::M], m[crate::grids::OMEGA]) = (0.5, 0.5);
                    for col in 4..4 + len {
                        write_cell(&mut perception, at(col, 21), &m);
                    }
                }
                stage.update(
                    &window,
                    &grid,
                    0.1 * t as f64,
                    0.1,
                    &mut perception,
                    &mut decisions,
                );
            }
            let mut states: Vec<CellMotion> = stage.cell_states().iter().map(|r| r.state).collect();
            states.dedup();
            // The object's cells in the last frame (row 21): the least and the largest m({M}).
            let m_moving: Vec<f32> = (4..4 + len)
                .map(|col| perception.cell_masses(at(col, 21))[crate::grids::class::M])
                .collect();
            let lo = m_moving.iter().copied().fold(1.0, f32::min);
            let hi = m_moving.iter().copied().fold(0.0, f32::max);
            (states, lo, hi)
        };
        // Off: both move, m({M}) raised above 0.5 on every cell. At 13 m the wall (15.008 m)
        // takes "not moving", m(Ω∖{M}) = 0.9: m({M}) = 0.5 · (1 − 0.9) = 0.05 on every cell;
        // the car (4.031 m) moves. At 4 m the car is too large too.
        let moves = |(states, lo, _): (Vec<CellMotion>, f32, f32)| {
            states == vec![CellMotion::Moving] && lo > 0.5
        };
        let too_large = |(states, lo, hi): (Vec<CellMotion>, f32, f32)| {
            states == vec![CellMotion::TooLarge]
                && (lo - 0.05).abs() < 1e-6
                && (hi - 0.05).abs() < 1e-6
        };
        assert!(moves(last_states(30, 0.0)));
        assert!(moves(last_states(8, 0.0)));
        assert!(too_large(last_states(30, 13.0)));
        assert!(moves(last_states(8, 13.0)));
        assert!(too_large(last_states(8, 4.0)));
    }

    #[test]
    fn the_span_across_the_motion_is_the_spread_along_the_velocity_s_normal_plus_a_cell() {
        // A bus of 24 × 2 cells of 0.5 m: columns 4-27, rows 20-21.
        let cells: Vec<clusters::Cell> = (20..=21)
            .flat_map(|row| (4..=27).map(move |col| clusters::Cell { idx: 0, col, row }))
            .collect();
        let across = |v: [f64; 2]| moved_across_m(cells.iter(), 0.5, v);
        // Driving east: across is north, rows 20-21: 0.5 + 0.5 = 1 m.
        assert!((across([5.0, 0.0]).unwrap_or(0.0) - 1.0).abs() < 1e-9);
        // Sliding north (a façade the pose shifted): columns 4-27, 23 · 0.5 + 0.5 = 12 m.
        assert!((across([0.0, -2.0]).unwrap_or(0.0) - 12.0).abs() < 1e-9);
        // North-east: the normal (−1, 1)/√2; row − col spans −7 to 17, 24 · 0.5 / √2 =
        // 8.485 m, plus 0.5 · (1/√2 + 1/√2) = 0.707 m: 9.192 m.
        assert!((across([3.0, 3.0]).unwrap_or(0.0) - 9.192).abs() < 1e-3);
        // No direction, or no cell that moved: nothing to measure.
        assert_eq!(across([0.0, 0.0]), None);
        assert_eq!(moved_across_m(std::iter::empty(), 0.5, [5.0, 0.0]), None);
    }

    #[test]
    fn a_slow_bus_of_unsure_heading_is_measured_across_its_own_axis() {
        // A bus of 24 × 2 cells of 0.5 m (columns 4-27, rows 20-21): its box's diagonal
        // √(12² + 1²) = 12.04 m, over 8 m and within 13 m. Its velocity (0.3, 0.6) m/s, speed
        // 0.671 m/s, points 63.4° off its length: across it, the columns spread 23 · 0.5 ·
        // 0.894 = 10.29 m, far over 4 m. Its own axis is east (the centres' covariance has
        // s_xy = 0, s_xx > s_yy): across it 1 m.
        let cells: Vec<clusters::Cell> = (20..=21)
            .flat_map(|row| (4..=27).map(move |col| clusters::Cell { idx: 0, col, row }))
            .collect();
        let moved = vec![true; cells.len()];
        assert_eq!(principal_axis(cells.iter()), Some([1.0, 0.0]));
        assert_eq!(principal_axis(std::iter::empty()), None);
        let too_large = |sigma_mps: f64, unsure: f64| {
            let mut params = MotionParams {
                moving_max_extent_m: 8.0,
                ..crate::Params::default().motion
            };
            params.moving_across_own_axis_unsure = unsure;
            too_large_to_move(
                &cells,
                &moved,
                &|_| true,
                0.5,
                [0.3, 0.6],
                sigma_mps,
                &params,
            )
        };
        // σ 1 m/s ≥ 1 × 0.671 m/s: unsure, measured across its own axis, it moves.
        assert!(!too_large(1.0, 1.0));
        // σ 0.5 m/s < 0.671 m/s: its heading is trusted, 10.29 m across, too large.
        assert!(too_large(0.5, 1.0));
        // 0: across the velocity only, as before.
        assert!(too_large(1.0, 0.0));
    }

    #[test]
    fn a_bus_driving_along_its_length_keeps_moving_and_a_sliding_wall_does_not_when_bounded() {
        // Exact poses (σ 0, refinement off), 0.5 m cells, rows 14-26 seen free from column 2
        // to 38 around the objects. The bus: 20 × 2 cells (10 × 1 m), rows 20-21, columns
        // 4 + t to 23 + t in frame t, driving east a cell a frame (5 m/s). Its cells span
        // √(10² + 1²) = 10.05 m on the box's diagonal, more than 8 m, and 1 m across its
        // velocity. The wall: 30 cells of row 18 + t, columns 4-33, sliding north a row a frame:
        // √(15² + 0.5²) = 15.008 m, and 15 m across its velocity. A wall as thick as the bus
        // sliding east along its own length, two cells a frame (rows 20-21, 28 columns from
        // 4 + 2t; a scan's pose off along the street): √(14² + 1²) = 14.036 m, and 1 m across
        // its velocity. (At one cell a frame, all but one of its cells explained at zero, it
        // stays uncertain.)
        #[derive(Clone, Copy)]
        enum Object {
            Bus,
            WallAcross,
            WallAlong,
        }
        let window = Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let (w, h) = (window.width(), window.height());
        let at = |col: i64, row: i64| window.storage_index(col, row).unwrap_or(0);
        let last_states = |object: Object, max_across_m: f64, max_length_m: f64| {
            let mut params = crate::Params::default();
            params.motion.moving_max_extent_m = 8.0;
            params.motion.moving_max_across_m = max_across_m;
            params.motion.moving_max_length_m = max_length_m;
            let mut stage = MotionStage::new(&params, w, h);
            let mut perception = PerceptionGrid::new(w, h);
            let mut decisions = vec![Label::Unknown; w * h];
            let occupied = |t: i64, col: i64, row: i64| match object {
                Object::Bus => (20..=21).contains(&row) && (4 + t..24 + t).contains(&col),
                Object::WallAcross => row == 18 + t && (4..34).contains(&col),
                Object::WallAlong => {
                    (20..=21).contains(&row) && (4 + 2 * t..32 + 2 * t).contains(&col)
                }
            };
            for t in 0..4 {
                let mut grid = SensorGrid::new(w, h);
                for row in 14..=26 {
                    for col in 2..39 {
                        if occupied(t, col, row) {
                            grid.set_occupied(at(col, row), 0.8);
                        } else {
                            grid.set_free(at(col, row), 0.7);
                        }
                    }
                }
                stage.update(
                    &window,
                    &grid,
                    0.1 * t as f64,
                    0.1,
                    &mut perception,
                    &mut decisions,
                );
            }
            let mut states: Vec<CellMotion> = stage.cell_states().iter().map(|r| r.state).collect();
            states.sort();
            states.dedup();
            states
        };
        // The 8 m rule alone: all too large. Across ≤ 4 m: the bus (1 m) moves, the wall
        // sliding across (15 m) stays too large, the wall sliding along (1 m) moves too,
        // unless no narrow mover may span more than 13 m (it spans 14.036 m; the bus 10.05 m).
        let too_large = vec![CellMotion::TooLarge];
        let moving = vec![CellMotion::Moving];
        for object in [Object::Bus, Object::WallAcross, Object::WallAlong] {
            assert_eq!(last_states(object, 0.0, 0.0), too_large);
        }
        assert_eq!(last_states(Object::Bus, 4.0, 0.0), moving);
        assert_eq!(last_states(Object::WallAcross, 4.0, 0.0), too_large);
        assert_eq!(last_states(Object::WallAlong, 4.0, 0.0), moving);
        assert_eq!(last_states(Object::Bus, 4.0, 13.0), moving);
        assert_eq!(last_states(Object::WallAcross, 4.0, 13.0), too_large);
        assert_eq!(last_states(Object::WallAlong, 4.0, 13.0), too_large);
        assert_eq!(last_states(Object::Bus, 4.0, 10.0), too_large);
    }

    #[test]
    fn a_cell_that_joins_a_wall_from_space_seen_free_is_moving_with_static_part_entered() {
        // A wall on row 20, columns 5-14, in ten frames 0.1 s apart; rows 18-22 from column 2
        // to 29 seen free around it. In the last frame a walker stands at (15, 20), beside
        // the wall's end: one cluster of 11 cells, read at zero (zero and one cell east both
        // explain 10; ties go to zero), a static track after nine zero registrations.
        let window = Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let (w, h) = (window.width(), window.height());
        let at = |col: i64, row: i64| window.storage_index(col, row).unwrap_or(0);
        let run = |static_part_entered: bool, held_before: Option<i64>| {
            let mut params = crate::Params::default();
            params.motion.static_part_entered = static_part_entered;
            let mut stage = MotionStage::new(&params, w, h);
            let mut perception = PerceptionGrid::new(w, h);
            let mut decisions = vec![Label::Unknown; w * h];
            for t in 0..10 {
                let mut grid = SensorGrid::new(w, h);
                for row in 18..=22 {
                    for col in 2..30 {
                        let wall = row == 20 && (5..15).contains(&col);
                        let walker = (col, row) == (15, 20) && (t == 9 || held_before == Some(t));
                        if wall || walker {
                            grid.set_occupied(at(col, row), 0.8);
                        } else {
                            grid.set_free(at(col, row), 0.7);
                        }
                    }
                }
                stage.update(
                    &window,
                    &grid,
                    0.1 * t as f64,
                    0.1,
                    &mut perception,
                    &mut decisions,
                );
            }
            stage
        };
        let state_of = |stage: &MotionStage, col: i64| {
            stage
                .cell_states()
                .iter()
                .find(|r| r.idx as usize == at(col, 20))
                .map(|r| r.state)
        };
        // Off (the rule before): the whole cluster is static, the walker too.
        let off = run(false, None);
        assert_eq!(off.cell_states().len(), 11);
        assert!(
            off.cell_states()
                .iter()
                .all(|r| r.state == CellMotion::Static),
            "{:?}",
            off.cell_states()
        );
        // On (the default): the walker's cell, seen free in the frames kept and never
        // holding a return, takes m({M}) = mu_moving; the wall stays static.
        let on = run(true, None);
        assert_eq!(state_of(&on, 15), Some(CellMotion::EnteredSeenFree));
        assert_eq!(on.velocity_east()[at(15, 20)], 0.0);
        for col in 5..15 {
            assert_eq!(state_of(&on, col), Some(CellMotion::Static), "column {col}");
        }
        let entered = on.cell_states().iter();
        assert_eq!(
            entered
                .filter(|r| r.state == CellMotion::EnteredSeenFree)
                .count(),
            1
        );
        // A cell that held a return 0.4 s ago (frame 5) is no newcomer: static.
        let flicker = run(true, Some(5));
        assert_eq!(state_of(&flicker, 15), Some(CellMotion::Static));
    }

    #[test]
    fn a_cluster_registered_on_its_returns_moves_where_its_placed_cells_read_zero() {
        let window = Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"));
        // The margin before "A car's corner, and the margin of a crawl" (0.25; 0.15 now).
        let mut params = crate::Params::default();
        params.motion.shift_margin_fraction = 0.25;
        params.motion.shift_margin_max_cells = 0.0;
        let (w, h) = (window.width(), window.height());
        let at = |col: i64, row: i64| window.storage_index(col, row).unwrap_or(0);
        let run_with = |params: &crate::Params, on_returns: bool| {
            let mut stage = MotionStage::new(params, w, h);
            let mut perception = PerceptionGrid::new(w, h);
            let mut decisions = vec![Label::Unknown; w * h];
            for t in 0..2 {
                let (returns, placed) = driving_away(t, &window);
                let returns = if on_returns { &returns } else { &placed };
                stage.update_registering(
                    &window,
                    &placed,
                    returns,
                    0.1 * t as f64,
                    0.1,
                    &mut perception,
                    &mut decisions,
                );
            }
            stage
        };
        let run = |on_returns: bool| run_with(&params, on_returns);

        // On the placed cells (columns 11-15 now, 10-14 before): zero shift explains 16 of
        // the 20 cells, one cell east all 20, not the 25 % (5 cells) more a move needs. The
        // zero shift over 0.1 s is a velocity of 0 ± 2.5 m/s (½ cell of quantisation at
        // either end): too uncertain to call the car static, so no evidence.
        let placed = run(false);
        assert_eq!(placed.cell_states().len(), 20);
        assert!(
            placed
                .cell_states()
                .iter()
                .all(|r| r.state == CellMotion::Uncertain && r.speed_mps == 0.0),
            "{:?}",
            placed.cell_states()
        );

        // On the returns (the face, column 11, and the return at (10, 10)): one cell east
        // explains all 5 against 1 at zero (margin 2), and is seen on 4 (the cells it left
        // are seen free now, but for the return's own cell): 10 cells/s, 5 m/s with variance
        // 0.25 m² × 25 cells²/s² = 6.25 (m/s)², filtered from the new track's 0 ± 25 m/s
        // (variance 625 + (3 m/s² · 0.1 s)² = 625.09): 5 · 625.09 / 631.34 = 4.9505 m/s. The
        // 20 placed cells take the moving evidence; the return in front of the surface, not
        // a placed cell, takes none.
        let returns = run(true);
        assert_eq!(returns.cell_states().len(), 20);
        for r in returns.cell_states() {
            assert_eq!(r.state, CellMotion::Moving, "{r:?}");
            assert!((r.speed_mps - 4.9505).abs() < 1e-3, "{r:?}");
            assert!((returns.velocity_east()[r.idx as usize] - 4.9505).abs() < 1e-3);
        }
        assert_eq!(returns.velocity_east()[at(10, 10)], 0.0);
        // With the default margin, 15 % (⌈3⌉ = 3 cells), the placed cells move too: one cell
        // east explains 20, zero 16, and 20 ≥ 16 + 3; the same 4.9505 m/s.
        let placed_default = run_with(&crate::Params::default(), false);
        assert_eq!(placed_default.cell_states().len(), 20);
        for r in placed_default.cell_states() {
            assert_eq!(r.state, CellMotion::Moving, "{r:?}");
            assert!((r.speed_mps - 4.9505).abs() < 1e-3, "{r:?}");
        }
        assert!(
            returns
                .cell_states()
                .iter()
                .all(|r| r.idx as usize != at(10, 10))
        );
        assert_eq!(
            returns.moving_objects().len(),
            0,
            "held back: one frame moving"
        );
    }

    #[test]
    fn a_cell_outside_the_rectangle_in_one_frame_is_moving_when_the_car_covers_it_the_next() {
        // The car of `driving_away` over three frames (face columns 10, 11, 12), seen wider
        // in the third: rows 10-14 there, 10-13 before. In the second frame two more placed
        // cells beside it, (12, 14) and (13, 14) (centre y 7.25), lie outside its rectangle
        // (across it between the returns at y 5.05 and 6.95); in the third the car covers
        // row 14 (returns up to y 7.45), and (13, 14), explained by the shift from (12, 14),
        // takes the moving evidence. Fused, the outside label's m(Ω∖{M}) = 0.9 is still in
        // the grid there: against m({M}) = 0.8 (conflict 0.72; m({M}) 0.08 against
        // m(Ω∖{M}) 0.18) the cell is not decided M (issue 30). Unfused, it was only the
        // second frame's decision: m({M}) = 0.8, M.
        let window = Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let (w, h) = (window.width(), window.height());
        let at = |col: i64, row: i64| window.storage_index(col, row).unwrap_or(0);
        let x = at(13, 14);
        let run = |fused: bool| {
            let mut params = crate::Params::default();
            params.motion.object_heading_max_deg = 40.0;
            params.motion.object_heading_fit_deg = 0.0;
            params.motion.object_outside_fused = fused;
            let mut stage = MotionStage::new(&params, w, h);
            let mut perception = PerceptionGrid::new(w, h);
            // Every cell seen (the step would have marked them), so that a cell is decided.
            perception.seen_mut().fill(1);
            let mut decisions = vec![Label::Unknown; w * h];
            let mut states = Vec::new();
            for t in 0..3 {
                let (mut returns, mut placed) = driving_away(t, &window);
                let face = 10 + t;
                let xm = 0.5 * face as f64;
                let mut far_y = 6.95;
                if t == 1 {
                    placed.set_occupied(at(12, 14), 0.8);
                    placed.set_occupied(at(13, 14), 0.8);
                }
                if t == 2 {
                    returns.set_occupied(at(face, 14), 0.8);
                    for col in face..face + 5 {
                        placed.set_occupied(at(col, 14), 0.8);
                    }
                    far_y = 7.45;
                }
                let points = [
                    (at(face, 10), [xm + 0.05, 5.05]),
                    (at(face, 13 + i64::from(t == 2)), [xm + 0.05, far_y]),
                    (at(face - 1, 10), [xm - 0.4, 5.3]),
                ];
                stage.set_pose(1.0, 6.0, 0.0, 0.0);
                stage.set_returns(points.into_iter());
                stage.update_registering(
                    &window,
                    &placed,
                    &returns,
                    0.1 * t as f64,
                    0.1,
                    &mut perception,
                    &mut decisions,
                );
                let state = stage
                    .cell_states()
                    .iter()
                    .find(|r| r.idx as usize == x)
                    .map(|r| r.state);
                states.push((state, decisions[x]));
            }
            states
        };
        let (fused, unfused) = (run(true), run(false));
        for states in [&fused, &unfused] {
            assert_eq!(states[1].0, Some(CellMotion::OutsideObject), "{states:?}");
            assert_ne!(states[1].1, Label::M, "{states:?}");
            assert_eq!(states[2].0, Some(CellMotion::Moving), "{states:?}");
        }
        assert_ne!(fused[2].1, Label::M, "{fused:?}");
        assert_eq!(unfused[2].1, Label::M, "{unfused:?}");
    }

    /// The car of [`driving_away`] driving 16 frames, standing 12 (its face at column 26),
    /// then driving again (`stopped_fused` as given): per frame, the state and decision of the cell (28, 11), covered
    /// by the standing car and by the one pulling away for two frames, and its grid m({S}).
    fn stop_and_go(stopped_fused: bool) -> Vec<(Option<CellMotion>, Label, f32)> {
        let window = Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let (w, h) = (window.width(), window.height());
        let x = window.storage_index(28, 11).unwrap_or(0);
        let mut params = crate::Params::default();
        params.motion.stopped_fused = stopped_fused;
        let mut stage = MotionStage::new(&params, w, h);
        let mut perception = PerceptionGrid::new(w, h);
        perception.seen_mut().fill(1);
        let mut decisions = vec![Label::Unknown; w * h];
        let mut out = Vec::new();
        for frame in 0..31i64 {
            let t = frame.min(16) + (frame - 28).max(0);
            let (returns, placed) = driving_away(t, &window);
            stage.set_pose(0.0, 0.0, 0.0, 0.0);
            stage.update_registering(
                &window,
                &placed,
                &returns,
                0.1 * frame as f64,
                0.1,
                &mut perception,
                &mut decisions,
            );
            let state = stage
                .cell_states()
                .iter()
                .find(|r| r.idx as usize == x)
                .map(|r| r.state);
            let s = perception.cell_masses(x)[crate::grids::class::S];
            out.push((state, decisions[x], s));
        }
        out
    }

    #[test]
    fn a_stop_s_label_unfused_leaves_no_stopped_mass_for_the_car_pulling_away() {
        // Exact poses, no SPEC §5 step (the grid holds only what the stage writes). The car
        // (its face and four cells behind) covers (28, 11) from frame 14 on, moving; it
        // stands from frame 17 (face at column 26), is stopped from frame 21 (slow and sure,
        // after more than 1 s and 2 m judged moving) and drives again from frame 29.
        let (fused, unfused) = (stop_and_go(true), stop_and_go(false));
        for run in [&fused, &unfused] {
            assert!(
                run[14..21].iter().all(|r| r.0 == Some(CellMotion::Moving)),
                "{run:?}"
            );
            assert!(
                run[21..29].iter().all(|r| r.0 == Some(CellMotion::Stopped)),
                "{run:?}"
            );
            assert_eq!(run[29].0, Some(CellMotion::Moving), "{run:?}");
        }
        // Fused, m({S}) = 0.9 a frame piles up: 0.81 after the frame that met the moving
        // phase's m({M}) (0.1 of it left, 0.9 on Ω), 0.99999934 by frame 28; the car
        // pulling away meets it (0.6588 left) and is decided S.
        assert!(fused[22..29].iter().all(|r| r.1 == Label::S), "{fused:?}");
        assert!((fused[22].2 - 0.81).abs() < 1e-5, "{fused:?}");
        assert!(fused[28].2 > 0.99999, "{fused:?}");
        assert_eq!(fused[29].1, Label::S, "{fused:?}");
        // Unfused, the stop decides each frame and the grid keeps no m({S}): the car pulling
        // away is M at once. (Here the grid still holds the moving phase's m({M}), which meets
        // the stop's m({S}) as conflict: Unknown; in the pipeline the step fades it.)
        assert!(unfused.iter().all(|r| r.2 == 0.0), "{unfused:?}");
        assert_eq!(unfused[29].1, Label::M, "{unfused:?}");
    }

    #[test]
    fn the_object_layer_labels_the_cells_whose_centre_its_rectangle_holds() {
        // The car of `driving_away`, with one more placed cell beside its face, (face, 14),
        // and its returns as points: the face x = 0.5·face + 0.05 on y = 5.05 and 6.95 (rows
        // 10-13 span y 5-7), and the return in front of the face at x = 0.5·face − 0.4, in
        // cell face − 1 of row 10 (y 5.3), whose centre the rectangle holds. The sensor at (1, 6). Frame 1 (face column 11):
        // the track moves east, 4.9505 m/s (as above), σ 2.5 m/s per axis, √2·2.5 = 3.54
        // over 4.95: 35.5° of heading error, within the test's 40°.
        let window = Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let (w, h) = (window.width(), window.height());
        let at = |col: i64, row: i64| window.storage_index(col, row).unwrap_or(0);
        let run = |layer: bool| {
            let mut params = crate::Params::default();
            params.motion.object_layer = layer;
            params.motion.object_heading_max_deg = 40.0;
            params.motion.object_heading_fit_deg = 0.0;
            params.motion.object_outside_static = 0.0;
            let mut stage = MotionStage::new(&params, w, h);
            let mut perception = PerceptionGrid::new(w, h);
            let mut decisions = vec![Label::Unknown; w * h];
            for t in 0..2 {
                let (returns, mut placed) = driving_away(t, &window);
                let face = 10 + t;
                placed.set_occupied(at(face, 14), 0.8);
                let x = 0.5 * face as f64;
                let points = [
                    (at(face, 10), [x + 0.05, 5.05]),
                    (at(face, 13), [x + 0.05, 6.95]),
                    (at(face - 1, 10), [x - 0.4, 5.3]),
                ];
                stage.set_pose(1.0, 6.0, 0.0, 0.0);
                stage.set_returns(points.into_iter());
                stage.update_registering(
                    &window,
                    &placed,
                    &returns,
                    0.1 * t as f64,
                    0.1,
                    &mut perception,
                    &mut decisions,
                );
            }
            stage
        };
        let state = |stage: &MotionStage, idx: usize| {
            stage
                .cell_states()
                .iter()
                .find(|r| r.idx as usize == idx)
                .map(|r| r.state)
        };
        let (off, on) = (run(false), run(true));
        // Without the layer: the 20 placed cells and the one beside move; the return in front
        // of the face, not placed, takes nothing.
        assert_eq!(off.cell_states().len(), 21);
        assert_eq!(state(&off, at(11, 14)), Some(CellMotion::Moving));
        assert_eq!(state(&off, at(10, 10)), None);
        // With it: heading east, along the sensor (x 1) is below the nearest return (x 5.1):
        // the face anchored at 5.1, open behind (no length seen); across it lies between y
        // 5.05 and 6.95 (silhouettes). The cell beside (centre y 7.25) is outside; the
        // return's cell in front (centre (5.25, 5.25), behind x 5.1) is inside, but not a
        // placed cell: it takes nothing.
        assert_eq!(state(&on, at(11, 14)), Some(CellMotion::OutsideObject));
        assert_eq!(state(&on, at(10, 10)), None);
        let moving = |stage: &MotionStage| {
            stage
                .cell_states()
                .iter()
                .filter(|r| r.state == CellMotion::Moving)
                .count()
        };
        assert_eq!((moving(&off), moving(&on)), (21, 20));
        // The layer never changes a track's speed.
        for r in on.cell_states() {
            assert!((r.speed_mps - 4.9505).abs() < 1e-3, "{r:?}");
        }
        assert_eq!(on.velocity_east()[at(11, 14)], 0.0);
        assert!((on.velocity_east()[at(11, 10)] - 4.9505).abs() < 1e-3);
    }

    #[test]
    fn two_pieces_of_one_object_are_listed_once_under_the_older_track() {
        // Pieces 1.5 m apart at 8.0 and 8.4 m/s (within 1 m/s): one object, the id of the one
        // with more hits, at the cell-weighted centroid (3 cells at 0, 1 at 1.5: 0.375).
        // A third at 1 m from them but 3 m/s slower is another object.
        let mut list = vec![
            object(7, 1.5, 8.4, 3, 1),
            object(2, 0.0, 8.0, 9, 3),
            object(5, 1.0, 5.0, 9, 2),
        ];
        merge_pieces(&mut list, 2.0);
        assert_eq!(list.len(), 2, "{list:?}");
        assert_eq!((list[0].id, list[0].cells), (2, 4));
        assert!((list[0].position_m[0] - 0.375).abs() < 1e-12);
        assert_eq!(list[1].id, 5);
    }
}
