//! Behaviour of the whole pipeline on small hand-made scenes (SPEC §2-§6).
//!
//! A planar scanner sits at the origin of a 30 m × 30 m window of 0.5 m cells, in a map made by
//! hand with `LocalMap::new`: a road along the x axis (|y| ≤ 3 m), a building on
//! x ∈ [5, 12], y ∈ [6, 12], pavement (the intermediate space T) elsewhere within ±20 m. A square
//! fence at ±13 m gives every beam a return, so the sensor sees free space everywhere inside.
//! Scans are cast exactly against axis-aligned boxes, one beam every 0.1°, at 10 Hz.
//!
//! Every scenario runs with the default parameters (except the sensor's ground model, which is
//! set for a planar scanner). A scenario the defaults cannot satisfy is a finding, not a test to
//! bend: it is marked `#[ignore]` with the measured numbers in its reason, as an open question.

#![allow(clippy::unwrap_used)]

use evigrid::{
    FrameStats, GroundModel, IsometryMatrix3, Label, N_SETS, OMEGA, Params, Pipeline, PoseExt,
    PoseRefinement, UnobservedCells, class,
};
use geo::{Rect, coord, polygon};
use geodata::{ContextRaster, LocalMap};

const DT_S: f64 = 0.1;

/// An axis-aligned box in the plane of the scanner, metres.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    min: [f64; 2],
    max: [f64; 2],
}

const fn aabb(x0: f64, y0: f64, x1: f64, y1: f64) -> Aabb {
    Aabb {
        min: [x0, y0],
        max: [x1, y1],
    }
}

const FENCE: [Aabb; 4] = [
    aabb(13.0, -13.5, 13.5, 13.5),
    aabb(-13.5, -13.5, -13.0, 13.5),
    aabb(-13.5, 13.0, 13.5, 13.5),
    aabb(-13.5, -13.5, 13.5, -13.0),
];
const BUILDING: Aabb = aabb(5.0, 6.0, 12.0, 12.0);
/// A car-sized object on the road, 4 m ahead.
const CAR: Aabb = aabb(4.0, -0.9, 8.0, 0.9);
/// A pole on the pavement, north-west of the scanner.
const POLE: Aabb = aabb(-6.5, 5.5, -6.0, 6.0);

fn map() -> ContextRaster {
    let building =
        polygon![(x: 5.0, y: 6.0), (x: 12.0, y: 6.0), (x: 12.0, y: 12.0), (x: 5.0, y: 12.0)];
    let road =
        polygon![(x: -20.0, y: -3.0), (x: 20.0, y: -3.0), (x: 20.0, y: 3.0), (x: -20.0, y: 3.0)];
    let extent = Rect::new(coord! { x: -20.0, y: -20.0 }, coord! { x: 20.0, y: 20.0 });
    ContextRaster::new(&LocalMap::new(vec![building], vec![road], extent))
}

fn params() -> Params {
    let mut p = Params::default();
    p.window.width_cells = 60;
    p.window.height_cells = 60;
    p.sensor.ground_model = GroundModel::None;
    p
}

/// Casts 3600 beams from the origin against the boxes; a beam returns its nearest hit.
fn scan(boxes: &[Aabb]) -> Vec<[f32; 3]> {
    let mut points = Vec::new();
    for k in 0..3600 {
        let angle = (k as f64 + 0.5) * std::f64::consts::TAU / 3600.0;
        let dir = [angle.cos(), angle.sin()];
        let nearest = boxes
            .iter()
            .filter_map(|b| hit(b, dir))
            .fold(f64::INFINITY, f64::min);
        if nearest.is_finite() {
            points.push([(nearest * dir[0]) as f32, (nearest * dir[1]) as f32, 0.0]);
        }
    }
    points
}

/// Slab test: entry distance of a ray from the origin into a box, if it hits it ahead.
fn hit(b: &Aabb, dir: [f64; 2]) -> Option<f64> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for ((&d, &lo), &hi) in dir.iter().zip(&b.min).zip(&b.max) {
        if d.abs() < 1e-12 {
            if !(lo <= 0.0 && 0.0 <= hi) {
                return None;
            }
            continue;
        }
        let (a, c) = (lo / d, hi / d);
        t0 = t0.max(a.min(c));
        t1 = t1.min(a.max(c));
    }
    (t0 <= t1 && t0 > 0.0).then_some(t0)
}

struct Drive {
    pipeline: Pipeline,
    time_s: f64,
}

impl Drive {
    fn new(params: Params, with_map: bool) -> Self {
        Self {
            pipeline: Pipeline::new(params, with_map.then(map)).unwrap(),
            time_s: 0.0,
        }
    }

    fn frame(&mut self, boxes: &[Aabb]) -> FrameStats {
        self.frame_points(&scan(boxes))
    }

    fn frame_points(&mut self, points: &[[f32; 3]]) -> FrameStats {
        let stats = self
            .pipeline
            .process(points, &IsometryMatrix3::identity(), self.time_s)
            .unwrap();
        self.time_s += DT_S;
        stats
    }

    fn idx(&self, x: f64, y: f64) -> usize {
        self.pipeline.window().storage_index_of_point(x, y).unwrap()
    }

    fn decision(&self, x: f64, y: f64) -> Label {
        self.pipeline.decisions()[self.idx(x, y)]
    }

    fn masses(&self, x: f64, y: f64) -> [f32; N_SETS] {
        self.pipeline.perception().cell_masses(self.idx(x, y))
    }

    /// Storage indices of the cells the last scan marked occupied inside `region`.
    fn occupied_cells_in(&self, region: Aabb) -> Vec<usize> {
        let window = self.pipeline.window();
        let sensor = self.pipeline.sensor_grid();
        (0..window.len())
            .filter(|&idx| {
                let cell = window.cell_of_storage(idx).unwrap();
                let (x, y) = window.cell_centre(cell.col, cell.row);
                sensor.m_occupied()[idx] > 0.0
                    && (region.min[0]..=region.max[0]).contains(&x)
                    && (region.min[1]..=region.max[1]).contains(&y)
            })
            .collect()
    }
}

fn widen(b: Aabb, margin: f64) -> Aabb {
    aabb(
        b.min[0] - margin,
        b.min[1] - margin,
        b.max[0] + margin,
        b.max[1] + margin,
    )
}

/// Road cells between the scanner and the fence, east and west.
const FREE_ROAD_PROBES: [(f64, f64); 4] =
    [(2.25, 0.25), (9.75, -1.25), (-4.25, 2.25), (-11.75, -0.75)];

#[test]
fn a_free_road_stays_free() {
    let mut drive = Drive::new(params(), true);
    for frame in 0..30 {
        drive.frame(&FENCE);
        for (x, y) in FREE_ROAD_PROBES {
            assert_eq!(
                drive.decision(x, y),
                Label::F,
                "frame {frame} at ({x}, {y})"
            );
        }
    }
}

#[test]
fn an_object_appearing_on_free_road_is_moving_within_one_step() {
    let mut drive = Drive::new(params(), true);
    for _ in 0..10 {
        drive.frame(&FENCE);
    }
    let scene = [FENCE.as_slice(), &[CAR]].concat();
    drive.frame(&scene);
    let cells = drive.occupied_cells_in(widen(CAR, 0.5));
    assert!(cells.len() >= 4, "the car's near side spans several cells");
    for idx in cells {
        assert_eq!(drive.pipeline.decisions()[idx], Label::M, "cell {idx}");
        // The past said free, the present occupied: ∅_FO carried the evidence to M (eq 22).
        assert!(drive.pipeline.perception().conflict_fo()[idx] > 0.3);
    }
}

/// Frames after its appearance until every cell of an object that stays is decided stopped.
fn frames_until_stopped(params: Params) -> usize {
    let mut drive = Drive::new(params, true);
    for _ in 0..10 {
        drive.frame(&FENCE);
    }
    let scene = [FENCE.as_slice(), &[CAR]].concat();
    for frame in 1..=200 {
        drive.frame(&scene);
        let cells = drive.occupied_cells_in(widen(CAR, 0.5));
        if cells
            .iter()
            .all(|&idx| drive.pipeline.decisions()[idx] == Label::S)
        {
            return frame;
        }
    }
    usize::MAX
}

#[test]
fn an_object_that_stays_becomes_stopped_as_fast_as_delta_inc_allows() {
    let defaults = params();
    let delta_inc = defaults.accumulator.delta_inc;
    let frames = frames_until_stopped(defaults.clone());
    eprintln!("stopped after {frames} frames with δ_inc = {delta_inc}");
    // ζ grows by δ_inc per conflict-free step from the second frame on (the first has ∅_FO), and
    // specialisation moves ζ·m(A) from every A ∋ M to A ∖ {M}: S overtakes M once about half
    // of the moving mass has moved, i.e. within 1/δ_inc steps of growth.
    assert!(
        frames > 1,
        "an object cannot be stopped at its first sighting"
    );
    assert!(
        frames <= 1 + (1.0 / delta_inc).ceil() as usize,
        "{frames} frames"
    );
    // Doubling δ_inc makes it faster; halving it slower.
    let mut faster = defaults.clone();
    faster.accumulator.delta_inc = 2.0 * delta_inc;
    let mut slower = defaults.clone();
    slower.accumulator.delta_inc = 0.5 * delta_inc;
    let (fast, slow) = (frames_until_stopped(faster), frames_until_stopped(slower));
    eprintln!("δ_inc ×2: {fast} frames, ×½: {slow} frames");
    // Frames are discrete, so neighbouring rates may need the same number of frames.
    assert!(
        fast <= frames && frames <= slow && fast < slow,
        "{fast} ≤ {frames} ≤ {slow}"
    );
}

#[test]
fn without_accumulation_an_object_is_never_stopped() {
    let mut never = params();
    never.accumulator.delta_inc = 0.0;
    assert_eq!(frames_until_stopped(never), usize::MAX);
}

#[test]
fn a_vacated_cell_shows_conflict_of_then_returns_to_free() {
    let mut drive = Drive::new(params(), true);
    for _ in 0..5 {
        drive.frame(&FENCE);
    }
    let scene = [FENCE.as_slice(), &[CAR]].concat();
    for _ in 0..30 {
        drive.frame(&scene);
    }
    let cells = drive.occupied_cells_in(widen(CAR, 0.5));
    assert!(!cells.is_empty());
    for &idx in &cells {
        assert_eq!(drive.pipeline.decisions()[idx], Label::S);
    }
    // The car leaves: its cells are seen free; past O against present F is ∅_OF (eq 23).
    drive.frame(&FENCE);
    for &idx in &cells {
        let conflict_of = drive.pipeline.perception().conflict_of()[idx];
        assert!(conflict_of > 0.3, "∅_OF = {conflict_of} at cell {idx}");
        assert!(drive.pipeline.perception().conflict_fo()[idx] < 1e-6);
    }
    let mut frames_to_free = None;
    for frame in 1..=30 {
        drive.frame(&FENCE);
        if cells
            .iter()
            .all(|&idx| drive.pipeline.decisions()[idx] == Label::F)
        {
            frames_to_free = Some(frame);
            break;
        }
    }
    eprintln!("vacated cells free again after {frames_to_free:?} more frames");
    assert!(frames_to_free.is_some());
}

#[test]
fn an_obstacle_inside_a_building_is_mapped_infrastructure() {
    let mut drive = Drive::new(params(), true);
    let scene = [FENCE.as_slice(), &[BUILDING]].concat();
    for _ in 0..5 {
        drive.frame(&scene);
    }
    let cells = drive.occupied_cells_in(widen(BUILDING, 0.5));
    assert!(cells.len() > 10);
    let window = drive.pipeline.window();
    for idx in cells {
        let cell = window.cell_of_storage(idx).unwrap();
        let (x, y) = window.cell_centre(cell.col, cell.row);
        if (5.0..12.0).contains(&x) && (6.0..12.0).contains(&y) {
            assert_eq!(
                drive.pipeline.decisions()[idx],
                Label::I,
                "cell centre ({x}, {y})"
            );
        }
    }
}

/// Runs the pole scene for three seconds; returns betP of every cell the pole occupies.
fn pole_cells() -> Vec<(Label, [f32; 5])> {
    let mut drive = Drive::new(params(), true);
    let scene = [FENCE.as_slice(), &[POLE]].concat();
    for _ in 0..30 {
        drive.frame(&scene);
    }
    let cells = drive.occupied_cells_in(widen(POLE, 0.5));
    assert!(!cells.is_empty());
    cells
        .into_iter()
        .map(|idx| {
            let m = drive.pipeline.perception().cell_masses(idx);
            (drive.pipeline.decisions()[idx], evigrid::betp(&m))
        })
        .collect()
}

#[test]
fn an_obstacle_staying_on_the_pavement_is_unmapped_infrastructure() {
    for (decision, p) in pole_cells() {
        assert_eq!(decision, Label::U, "betP F I U S M = {p:?}");
    }
}

/// A finding kept as a test: on pavement (prior T = {F,U,S,M}) nothing in SPEC §5 separates U
/// from S. The map leaves both possible, the accumulator only moves mass from sets with M to the
/// same sets without it, and no rule tells a pole from a parked car, so both keep equal betP and
/// U is decided by the tie order of `decision::decide` (see its `TIE_ORDER`). If evidence that
/// separates them is ever added (object shape, a longer memory), this test should change.
#[test]
fn on_the_pavement_u_and_s_are_not_separated_by_evidence() {
    for (_, p) in pole_cells() {
        assert!((p[2] - p[3]).abs() < 1e-6, "U {} vs S {}", p[2], p[3]);
        assert!(p[2] > p[0] && p[2] > p[4], "U and S lead: {p:?}");
    }
}

#[test]
fn without_a_map_the_same_obstacles_are_never_mapped_infrastructure() {
    let mut drive = Drive::new(params(), false);
    let scene = [FENCE.as_slice(), &[BUILDING, POLE]].concat();
    for frame in 0..30 {
        drive.frame(&scene);
        let i_cells = drive
            .pipeline
            .decisions()
            .iter()
            .filter(|d| **d == Label::I)
            .count();
        assert_eq!(
            i_cells, 0,
            "frame {frame}: {i_cells} cells decided I without a map"
        );
    }
}

#[test]
fn cells_out_of_view_fade_towards_omega_at_the_configured_rates() {
    let params = params();
    let free_rate = params.fusion.discount_per_second.free;
    let mut drive = Drive::new(params, false);
    for _ in 0..10 {
        drive.frame(&FENCE);
    }
    // Without a map a free cell holds only {F} and Ω.
    let (x, y) = (9.75, 0.25);
    let before = drive.masses(x, y);
    assert!(before[class::F] > 0.9 && before[class::F] + before[OMEGA] > 0.999);
    // A box right in front of the scanner hides the cell for one second.
    let occluder = aabb(2.5, -0.5, 3.0, 0.5);
    let scene = [FENCE.as_slice(), &[occluder]].concat();
    for _ in 0..10 {
        drive.frame(&scene);
    }
    let after = drive.masses(x, y);
    // α(1 s) = α_F per second: m(F) keeps (1 − α_F) of itself, the rest goes to Ω.
    let expected = before[class::F] * (1.0 - free_rate as f32);
    assert!(
        (after[class::F] - expected).abs() < 1e-4,
        "{} vs {expected}",
        after[class::F]
    );
    assert!((after[OMEGA] - (1.0 - expected)).abs() < 1e-4);
}

#[test]
fn scrolling_the_window_keeps_world_fixed_content_exact() {
    let scene = [FENCE.as_slice(), &[CAR, BUILDING, POLE]].concat();
    // The window's arithmetic alone: the pose as given. The scanner sits on a cell corner, and
    // the pose refinement's sub-millimetre corrections would place the still window a cell off
    // whenever they cross it.
    let mut exact_pose = params();
    exact_pose.localisation.refinement = PoseRefinement::None;
    let mut still = Drive::new(exact_pose.clone(), true);
    let mut moved = Drive::new(exact_pose, true);
    for _ in 0..8 {
        still.frame(&scene);
        moved.frame(&scene);
    }
    // One more frame without points: one pipeline stays, the other is 7 cells east, 3 south.
    still.frame_points(&[]);
    let shifted = IsometryMatrix3::from_xyz_rpy(3.6, -1.4, 0.0, 0.0, 0.0, 0.0);
    let stats = moved.pipeline.process(&[], &shifted, moved.time_s).unwrap();
    assert_eq!(stats.entered_cells, 60 * 60 - 53 * 57);
    let (a, b) = (still.pipeline.window(), moved.pipeline.window());
    let mut compared = 0;
    for idx in 0..b.len() {
        let cell = b.cell_of_storage(idx).unwrap();
        let masses = moved.pipeline.perception().cell_masses(idx);
        match a.storage_index(cell.col, cell.row) {
            Some(old) => {
                assert_eq!(
                    masses,
                    still.pipeline.perception().cell_masses(old),
                    "{cell:?}"
                );
                assert_eq!(
                    moved.pipeline.gis().context[idx],
                    still.pipeline.gis().context[old]
                );
                compared += 1;
            }
            // An entered cell starts vacuous and unseen; the step then fuses the map prior alone
            // into it (SPEC §5 step 2 with a vacuous sensor), so it holds exactly GG.
            None => {
                assert_eq!(moved.pipeline.decisions()[idx], Label::Unknown);
                let map = &moved.pipeline.params().map;
                let beta = match moved.pipeline.gis().context[idx] {
                    geodata::MapContext::Building => map.beta_building,
                    geodata::MapContext::Road => map.beta_road,
                    geodata::MapContext::Other => map.beta_other,
                    _ => 0.0,
                };
                assert!(
                    (masses[OMEGA] - (1.0 - beta) as f32).abs() < 1e-6,
                    "{cell:?}: {masses:?}"
                );
            }
        }
    }
    assert_eq!(compared, 53 * 57);
}

/// With `unobserved = "discount_only"`. The default, `fuse`, follows SPEC §5 (every step runs on
/// every cell, so an unobserved cell is fused with the map prior again); it measured better on
/// `evigrid eval` (macro-F1 on cells observed at least once: Helsinki 0.502 against 0.415,
/// Kouvola 0.428 against 0.359; equal on the cells in view), see the next test for it.
#[test]
fn a_scan_with_zero_points_changes_nothing_but_discounting() {
    let mut params = params();
    params.fusion.unobserved = UnobservedCells::DiscountOnly;
    let rates = params.fusion.discount_per_second.as_array();
    let mut drive = Drive::new(params, false);
    let scene = [FENCE.as_slice(), &[CAR, BUILDING, POLE]].concat();
    for _ in 0..3 {
        drive.frame(&scene);
    }
    let before: Vec<[f32; N_SETS]> = (0..drive.pipeline.window().len())
        .map(|i| drive.pipeline.perception().cell_masses(i))
        .collect();
    let stats = drive.frame_points(&[]);
    assert_eq!(stats.observed_cells, 0);
    for (idx, m) in before.iter().enumerate() {
        let after = drive.pipeline.perception().cell_masses(idx);
        // class_rates with set_rate = max: A keeps (1 − α_A(dt)) of its mass, α_A the largest
        // per-second rate of its classes turned into a rate over dt (SPEC §5 step 3).
        for set in 1..OMEGA {
            let rate = (0..5)
                .filter(|k| set & (1 << k) != 0)
                .map(|k| rates[k])
                .fold(0.0, f64::max);
            let kept = (1.0 - rate).powf(DT_S) as f32;
            assert!(
                (after[set] - m[set] * kept).abs() < 1e-5,
                "cell {idx}, set {set}: {} vs {}",
                after[set],
                m[set] * kept
            );
        }
    }
}

#[test]
fn by_default_a_scan_with_zero_points_still_fuses_the_map_prior() {
    // SPEC §5: SG' = GG for a cell the scan did not reach, fused again at every step. A cell of
    // the mapped building, seen before, gains mass on {I} from the prior alone, where discounting
    // alone would lose some.
    let params = params();
    assert_eq!(params.fusion.unobserved, UnobservedCells::Fuse);
    let mut drive = Drive::new(params, true);
    let scene = [FENCE.as_slice(), &[BUILDING]].concat();
    for _ in 0..3 {
        drive.frame(&scene);
    }
    let (x, y) = (5.25, 6.25);
    let before = drive.masses(x, y);
    let stats = drive.frame_points(&[]);
    assert_eq!(stats.observed_cells, 0);
    let after = drive.masses(x, y);
    assert!(
        after[class::I] > before[class::I],
        "m(I) {} → {}",
        before[class::I],
        after[class::I]
    );
}
