//! Variants side by side on the same simulated drive, scored against the truth.
//!
//! For every seed, one [`Drive`] is simulated and each scan goes once through one shared
//! [`FrontEnd`] (the window recentred on the pose, the map prior, the SensorGrid: evigrid's own
//! sensor model, run once per scan), whose output every variant's [`GridMethod`] consumes:
//! - `kurdej2013`: the paper's method as SPEC §5 specifies it, evigrid's [`Fusion`] of the
//!   drive's pipeline map ([`Prior::Map`]); `full` is its former, deprecated name;
//! - `no-map`: the same fusion with a vacuous GISGrid ([`Prior::Vacuous`]);
//! - `evigrid`: the fusion of the map prior followed by the motion stage
//!   ([`evigrid::Method::Evigrid`], `docs/motion.md`);
//! - `moras2011`, `log-odds`: the [`baselines`](crate::baselines).
//!
//! Scans go in with the *estimated* sensor pose (localisation noise included); truth is labelled
//! in the world's true frame on the same world-fixed cells. The scanner is planar: the sensor
//! model runs with the ground model the scenario's scanner calls for
//! ([`EvalConfig::params_for`], `none`), whatever the configuration says, and reports print
//! those parameters. A cell is scored once it has been observed (the shared SensorGrid had
//! evidence in it at least once since it entered the window), the same cells for every variant;
//! two more confusion matrices score the cells observed in the frame itself (`scores_visible`,
//! the headline) and every cell of the window (`scores_all`); see [`crate::metrics`] for why.
//! Per frame only counts are added
//! ([`crate::metrics`]): memory does not depend on the length of the drive.
//!
//! Time per frame is wall-clock time of each variant's own work plus the shared front end it
//! needs, as if it ran alone: the window and the SensorGrid for every variant, the map prior for
//! the variants that fuse it ([`Variant::uses_map`]).

use crate::EvalError;
use crate::Label;
use crate::baselines::{LogOdds, LogOddsParams, Moras2011, Moras2011Params};
use crate::method::GridMethod;
use crate::metrics::{ConfusionMatrix, Latency, Remanence};
use crate::report::{EvalReport, SeedScores, VariantReport};
pub use crate::variant::Variant;
use evigrid::Params;
use evigrid::PoseExt;
use evigrid::{FrontEnd, FrontEndStats, Fusion, Method as FusionMethod, Prior, Window};
use geodata::{ContextRaster, LocalMap};
use serde::{Deserialize, Serialize};
use sim::drive::{Drive, Frame};
use sim::scenario::Scenario;
use sim::sensor::HitTarget;
use sim::truth;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Settings of the methods under evaluation. By default evigrid's default parameters and the
/// baselines' defaults.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EvalConfig {
    /// evigrid's parameters, for the shared front end, `kurdej2013` and `no-map`. The sensor's ground
    /// model is replaced by the scanner's (see [`EvalConfig::params_for`]).
    pub params: Params,
    /// The Moras 2011 baseline.
    pub moras2011: Moras2011Params,
    /// The log-odds baseline.
    pub log_odds: LogOddsParams,
}

impl EvalConfig {
    /// The evigrid parameters that run on `scenario`'s scans: [`EvalConfig::params`] with the
    /// ground model the simulated scanner calls for
    /// ([`SensorConfig::ground_model`](sim::scenario::SensorConfig::ground_model), `none`: a
    /// planar world has no ground returns). Print these, not `params`, in a report.
    pub fn params_for(&self, scenario: &Scenario) -> Params {
        let mut params = self.params.clone();
        params.sensor.ground_model = scenario.sensor.ground_model();
        params
    }
}

/// Where the evaluation is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    /// Seed being run (index into the seed list).
    pub seed_index: usize,
    /// Number of seeds.
    pub seeds: usize,
    /// Frames done in this seed.
    pub frame: usize,
    /// Frames per seed.
    pub frames: usize,
}

/// What an observer of [`evaluate_observed`] sees after an evigrid variant (`kurdej2013`,
/// `no-map`) has processed a frame.
#[derive(Clone, Copy)]
pub struct FusionFrame<'a> {
    /// The variant (`kurdej2013` or `no-map`).
    pub variant: Variant,
    /// Index of the seed in the seed list.
    pub seed_index: usize,
    /// Index of the frame in the drive.
    pub frame: usize,
    /// The shared front end after the frame: window, SensorGrid, GISGrid.
    pub front_end: &'a FrontEnd,
    /// The variant's fusion after the frame: PerceptionGrid, decisions, trace.
    pub fusion: &'a Fusion,
    /// The simulator's truth over the window after the frame by the centre rule, in storage
    /// order ([`IGNORED`](sim::truth::IGNORED) where the ego's own sensor cannot see), for
    /// pictures of truth beside prediction.
    pub truth: &'a [evigrid::Label],
    /// The band over the window, in storage order: cells an object covers in part without
    /// their centre (truth F, scored as F; see `docs/evaluation.md`).
    pub outline: &'a [bool],
    /// The sensor's position (x east, y north, metres) as the method was given it this frame.
    pub ego_position: [f64; 2],
    /// The frame's scan, sensor frame.
    pub points_in_sensor: &'a [[f32; 3]],
    /// The (estimated) sensor pose the scan went in with.
    pub world_from_sensor: &'a evigrid::IsometryMatrix3,
    /// The scan's time, seconds.
    pub time_s: f64,
}

/// A variant's method: evigrid's fusion is kept by type so that observers can see its grids.
enum Method {
    Fusion(Box<Fusion>),
    Other(Box<dyn GridMethod>),
}

impl Method {
    fn as_grid_method(&mut self) -> &mut dyn GridMethod {
        match self {
            Method::Fusion(fusion) => fusion.as_mut(),
            Method::Other(method) => method.as_mut(),
        }
    }
}

/// One variant's method and its counts over one drive.
struct Runner {
    variant: Variant,
    method: Method,
    predicted: Vec<Label>,
    confusion: ConfusionMatrix,
    visible: ConfusionMatrix,
    /// Cells in view, scored by the previous truth rule (one release, for comparison).
    visible_previous: ConfusionMatrix,
    all: ConfusionMatrix,
    remanence: Remanence,
    latency: Latency,
    seconds: f64,
}

impl Runner {
    fn new(
        variant: Variant,
        params: &Params,
        config: &EvalConfig,
        len: usize,
    ) -> Result<Self, EvalError> {
        let method = match variant {
            Variant::Kurdej2013 => {
                Method::Fusion(Box::new(Fusion::new(params.clone(), Prior::Map)?))
            }
            Variant::NoMap => {
                Method::Fusion(Box::new(Fusion::new(params.clone(), Prior::Vacuous)?))
            }
            Variant::Evigrid => Method::Fusion(Box::new(Fusion::with_method(
                params.clone(),
                Prior::Map,
                FusionMethod::Evigrid,
            )?)),
            Variant::Moras2011 => Method::Other(Box::new(Moras2011::new(len, config.moras2011))),
            Variant::LogOdds => Method::Other(Box::new(LogOdds::new(len, config.log_odds))),
        };
        Ok(Self {
            variant,
            method,
            predicted: vec![Label::Unknown; len],
            confusion: ConfusionMatrix::default(),
            visible: ConfusionMatrix::default(),
            visible_previous: ConfusionMatrix::default(),
            all: ConfusionMatrix::default(),
            remanence: Remanence::new(len),
            latency: Latency::default(),
            seconds: 0.0,
        })
    }

    /// Folds another drive's counts into these.
    fn merge(&mut self, other: &Runner) {
        self.confusion.merge(&other.confusion);
        self.visible.merge(&other.visible);
        self.visible_previous.merge(&other.visible_previous);
        self.all.merge(&other.all);
        self.remanence.merge(&other.remanence);
        self.latency.merge(&other.latency);
        self.seconds += other.seconds;
    }
}

/// Runs every variant on the drive of every seed and scores them.
///
/// # Errors
/// [`EvalError::Sim`] from building a drive (bad scenario, no roads), [`EvalError::Pipeline`]
/// from evigrid (bad parameters), [`EvalError::NoSeeds`] / [`EvalError::NoVariants`] for empty
/// lists.
pub fn evaluate(
    map: &LocalMap,
    scenario: &Scenario,
    variants: &[Variant],
    seeds: &[u64],
    config: &EvalConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<EvalReport, EvalError> {
    evaluate_observed(
        map,
        scenario,
        variants,
        seeds,
        config,
        progress,
        &mut |_| {},
    )
}

/// [`evaluate`], calling `observer` after every frame of every evigrid variant (`kurdej2013`,
/// `no-map`), so that a caller can render the views of the drive it scores without running the
/// method a second time (`evigrid demo` does).
///
/// # Errors
/// As [`evaluate`].
pub fn evaluate_observed(
    map: &LocalMap,
    scenario: &Scenario,
    variants: &[Variant],
    seeds: &[u64],
    config: &EvalConfig,
    progress: &mut dyn FnMut(Progress),
    observer: &mut dyn FnMut(FusionFrame<'_>),
) -> Result<EvalReport, EvalError> {
    let never = AtomicBool::new(false);
    evaluate_until(
        map, scenario, variants, seeds, config, &never, progress, observer,
    )
}

/// [`evaluate_observed`] that stops between two frames once `stop` is raised (a signal, a
/// caller's deadline): the report then scores the frames run so far, in the seeds started
/// ([`EvalReport::seeds`]), and says so ([`EvalReport::complete`] false).
///
/// # Errors
/// As [`evaluate`]; stopping is not an error.
#[allow(clippy::too_many_arguments)]
pub fn evaluate_until(
    map: &LocalMap,
    scenario: &Scenario,
    variants: &[Variant],
    seeds: &[u64],
    config: &EvalConfig,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(Progress),
    observer: &mut dyn FnMut(FusionFrame<'_>),
) -> Result<EvalReport, EvalError> {
    if seeds.is_empty() {
        return Err(EvalError::NoSeeds);
    }
    if variants.is_empty() {
        return Err(EvalError::NoVariants);
    }
    let params = config.params_for(scenario);
    params.validate().map_err(evigrid::PipelineError::from)?;
    let evaluation = Evaluation {
        map,
        variants,
        params: &params,
        config,
        stop,
    };
    let mut totals: Vec<Runner> = Vec::new();
    let mut per_seed: Vec<Vec<SeedScores>> = vec![Vec::new(); variants.len()];
    let mut frames_per_seed = 0;
    let mut frame_period_s = 0.0;
    let mut simulation_s = 0.0;
    let mut frames_run = 0;
    let mut seeds_run = Vec::with_capacity(seeds.len());
    let mut complete = true;
    for (seed_index, &seed) in seeds.iter().enumerate() {
        if stop.load(Ordering::Relaxed) {
            complete = false;
            break;
        }
        seeds_run.push(seed);
        let scenario = Scenario {
            seed,
            ..scenario.clone()
        };
        let run = evaluation.run_seed(&scenario, (seed_index, seeds.len()), progress, observer)?;
        frames_per_seed = run.frames_per_seed;
        frame_period_s = run.frame_period_s;
        simulation_s += run.simulation_s;
        frames_run += run.frames;
        complete &= run.frames == run.frames_per_seed;
        for (k, r) in run.runners.into_iter().enumerate() {
            // Per seed, the headline mask: cells in view.
            let s = r.visible.scores();
            per_seed[k].push(SeedScores {
                seed,
                macro_f1: s.macro_f1,
                moving_iou: s.moving_iou,
            });
            match totals.get_mut(k) {
                Some(t) => t.merge(&r),
                None => totals.push(r),
            }
        }
    }
    let frames_total = frames_run.max(1) as f64;
    Ok(EvalReport {
        scenario: scenario.clone(),
        complete,
        frames_run,
        seeds: seeds_run,
        frames_per_seed,
        frame_period_s,
        variants: variant_reports(totals, per_seed, frames_total),
        simulation_ms_per_frame: simulation_s * 1000.0 / frames_total,
    })
}

/// What every seed of an evaluation shares: the map, the variants, the parameters that run
/// (checked), the configuration and the stop flag.
struct Evaluation<'a> {
    map: &'a LocalMap,
    variants: &'a [Variant],
    params: &'a Params,
    config: &'a EvalConfig,
    stop: &'a AtomicBool,
}

/// One seed's drive through every variant.
struct SeedRun {
    /// Each variant's runner, with its counts over the drive.
    runners: Vec<Runner>,
    /// Seconds spent simulating (scans and truth).
    simulation_s: f64,
    /// Frames run, and frames in the drive.
    frames: usize,
    frames_per_seed: usize,
    /// Seconds between two frames.
    frame_period_s: f64,
}

impl Evaluation<'_> {
    /// Simulates `scenario`'s drive (its seed is the one run) and runs it through one shared
    /// front end and a runner per variant, until its end or until `stop` is raised.
    /// `(seed_index, seeds)`: where this seed is in the seed list.
    fn run_seed(
        &self,
        scenario: &Scenario,
        (seed_index, seeds): (usize, usize),
        progress: &mut dyn FnMut(Progress),
        observer: &mut dyn FnMut(FusionFrame<'_>),
    ) -> Result<SeedRun, EvalError> {
        let params = self.params;
        let len = params.window.width_cells * params.window.height_cells;
        let mut drive = Drive::new(self.map, scenario)?;
        let frames_per_seed = drive.frame_count();
        let frame_period_s = drive.dt_s();
        // The map is rasterised only if a variant fuses it.
        let pipeline_map = (self.variants.iter())
            .any(|v| v.uses_map())
            .then(|| ContextRaster::new(drive.pipeline_map()));
        let mut front_end = FrontEnd::new(params, pipeline_map)?;
        let mut runners = (self.variants.iter())
            .map(|&v| Runner::new(v, params, self.config, len))
            .collect::<Result<Vec<_>, _>>()?;
        let (simulation_s, frames) = run_drive(
            &mut drive,
            &mut front_end,
            &mut runners,
            (seed_index, seeds),
            self.stop,
            progress,
            observer,
        )?;
        Ok(SeedRun {
            runners,
            simulation_s,
            frames,
            frames_per_seed,
            frame_period_s,
        })
    }
}

/// Each variant's report from its runner's counts over every seed and its scores per seed;
/// times per frame over `frames_total` frames.
fn variant_reports(
    totals: Vec<Runner>,
    per_seed: Vec<Vec<SeedScores>>,
    frames_total: f64,
) -> Vec<VariantReport> {
    totals
        .into_iter()
        .zip(per_seed)
        .map(|(r, per_seed)| VariantReport {
            variant: r.variant,
            scores: r.confusion.scores(),
            confusion: r.confusion,
            scores_visible: r.visible.scores(),
            confusion_visible: r.visible,
            scores_visible_previous: Some(r.visible_previous.scores()),
            confusion_visible_previous: Some(r.visible_previous),
            scores_all: r.all.scores(),
            confusion_all: r.all,
            remanence: r.remanence.summary(),
            latency: r.latency.summary(),
            ms_per_frame: r.seconds * 1000.0 / frames_total,
            per_seed,
        })
        .collect()
}

/// Feeds one drive to the front end, then every runner, until its end or until `stop` is
/// raised (checked before each frame); returns the seconds spent simulating (scans and truth)
/// and the frames run. `(seed_index, seeds)`: where this drive is in the seed list.
fn run_drive(
    drive: &mut Drive,
    front_end: &mut FrontEnd,
    runners: &mut [Runner],
    (seed_index, seeds): (usize, usize),
    stop: &AtomicBool,
    progress: &mut dyn FnMut(Progress),
    observer: &mut dyn FnMut(FusionFrame<'_>),
) -> Result<(f64, usize), EvalError> {
    let mut simulation_s = 0.0;
    let mut truth = DriveTruth::new(front_end.window().len());
    let frames = drive.frame_count();
    let mut frames_run = 0;
    loop {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        let started = Instant::now();
        let Some(frame) = drive.next_frame() else {
            break;
        };
        simulation_s += started.elapsed().as_secs_f64();
        let scan = &frame.scan;
        let points = scan.points_xyz_f32();

        // The shared front end: window, map prior, SensorGrid, once for every variant.
        let pose = scan.estimated_isometry();
        let stats = front_end.process(&points, &pose, scan.time_s)?;
        // The pose the SensorGrid was built with: the estimated one, or its refinement.
        let pose = *front_end.world_from_sensor();
        truth.observe(drive, &frame, front_end);
        simulation_s += truth.label(drive, front_end.window());
        // After the truth: the cells seen free up to this frame, for the next one's newcomers.
        truth.note_seen_free(front_end);

        // Every variant on the same front end.
        for r in runners.iter_mut() {
            r.process(front_end, &stats)?;
            if let Method::Fusion(fusion) = &r.method {
                observer(FusionFrame {
                    variant: r.variant,
                    seed_index,
                    frame: frame.index,
                    front_end,
                    fusion,
                    truth: &truth.centre.labels,
                    outline: &truth.centre.band,
                    ego_position: [pose.translation.x, pose.translation.y],
                    points_in_sensor: &points,
                    world_from_sensor: &pose,
                    time_s: scan.time_s,
                });
            }
            r.score(front_end, &truth, drive, &frame, &pose);
        }
        frames_run += 1;
        progress(Progress {
            seed_index,
            seeds,
            frame: frame.index + 1,
            frames,
        });
    }
    Ok((simulation_s, frames_run))
}

impl Runner {
    /// Runs the variant's method on the front end's frame and decides every cell; its time is
    /// charged with its share of the front end's (`stats`).
    fn process(&mut self, front_end: &FrontEnd, stats: &FrontEndStats) -> Result<(), EvalError> {
        let started = Instant::now();
        let method = self.method.as_grid_method();
        method.process(front_end)?;
        method.decide(&mut self.predicted);
        self.seconds += started.elapsed().as_secs_f64() + front_end_seconds(stats, self.variant);
        Ok(())
    }

    /// Adds this frame's decisions to the counts: the confusion matrices of the observed cells,
    /// the cells in view, every cell and the previous truth rule, the remanence and the
    /// latency. `world_from_sensor`: the pose the frame's SensorGrid was built with.
    fn score(
        &mut self,
        front_end: &FrontEnd,
        truth: &DriveTruth,
        drive: &Drive,
        frame: &Frame,
        world_from_sensor: &evigrid::IsometryMatrix3,
    ) {
        for span in front_end.new_cell_spans() {
            for idx in span {
                self.remanence.reset(idx);
            }
        }
        let (centre, predicted) = (&truth.centre, &self.predicted);
        self.confusion
            .add_frame_centre(centre, predicted, &truth.observed);
        self.visible
            .add_frame_centre(centre, predicted, &truth.observed_now);
        self.all
            .add_frame_centre(centre, predicted, &truth.everywhere);
        self.visible_previous.add_frame_with_outline(
            &truth.previous_storage,
            predicted,
            &truth.observed_now,
            &truth.outline_storage,
        );
        let frame_no = frame.index as u32;
        let cells = centre.labels.iter().zip(predicted).zip(&truth.observed_now);
        for (idx, ((&class, &decided), &now)) in cells.enumerate() {
            self.remanence.update(idx, frame_no, class, decided, now);
        }
        let window = front_end.window();
        update_latency(
            &mut self.latency,
            drive,
            frame,
            world_from_sensor,
            window,
            predicted,
        );
    }
}

/// What one drive's frames are scored against, in storage order, and what it is built from
/// (the truth in world order, the cells observed so far, the never-seen-moving rule).
struct DriveTruth {
    /// Cells with sensor evidence at least once since they entered the window.
    observed: Vec<bool>,
    /// Cells with sensor evidence in this frame.
    observed_now: Vec<bool>,
    /// Every cell.
    everywhere: Vec<bool>,
    /// The truth by the previous rule, in world order and in storage order.
    previous_world: Vec<Label>,
    previous_storage: Vec<Label>,
    /// The previous rule's object outlines, in world order and in storage order.
    outline_world: Vec<bool>,
    outline_storage: Vec<bool>,
    /// The truth by the centre rule, in world order and in storage order.
    centre_world: truth::CentreTruth,
    centre: truth::CentreTruth,
    never_seen_moving: NeverSeenMoving,
}

impl DriveTruth {
    /// Nothing observed yet, over a window of `len` cells.
    fn new(len: usize) -> Self {
        Self {
            observed: vec![false; len],
            observed_now: vec![false; len],
            everywhere: vec![true; len],
            previous_world: Vec::new(),
            previous_storage: vec![truth::IGNORED; len],
            outline_world: Vec::new(),
            outline_storage: vec![false; len],
            centre_world: truth::CentreTruth::default(),
            centre: truth::CentreTruth {
                labels: vec![truth::IGNORED; len],
                band: vec![false; len],
                never_seen_moving: vec![false; len],
            },
            never_seen_moving: NeverSeenMoving {
                seen_free: vec![false; len],
                ..NeverSeenMoving::default()
            },
        }
    }

    /// Takes in the front end's frame: the cells that entered the window forget what was seen
    /// there, the never-seen-moving passes take this frame's returns, and the cells with
    /// sensor evidence are observed.
    fn observe(&mut self, drive: &Drive, frame: &Frame, front_end: &FrontEnd) {
        let window = front_end.window();
        for span in front_end.new_cell_spans() {
            self.observed[span.clone()].fill(false);
            self.never_seen_moving.seen_free[span].fill(false);
        }
        self.never_seen_moving.update(drive, frame, window);
        let sensor_grid = front_end.sensor_grid();
        for ((o, now), (&f, &m)) in self
            .observed
            .iter_mut()
            .zip(self.observed_now.iter_mut())
            .zip(sensor_grid.m_free().iter().zip(sensor_grid.m_occupied()))
        {
            *now = f > 0.0 || m > 0.0;
            *o |= *now;
        }
    }

    /// The truth over `window` by both rules, rearranged into storage order; returns the
    /// seconds the simulator took to label it.
    fn label(&mut self, drive: &Drive, window: &Window) -> f64 {
        let started = Instant::now();
        let cell_window = window.as_cell_window();
        drive.truth_centre(
            &cell_window,
            &self.never_seen_moving.ids,
            &mut self.centre_world,
        );
        drive.truth_with_outline(
            &cell_window,
            &mut self.previous_world,
            &mut self.outline_world,
        );
        let seconds = started.elapsed().as_secs_f64();
        let (centre_world, centre) = (&self.centre_world, &mut self.centre);
        let mut k = 0;
        for span in window.world_order_spans() {
            for idx in span {
                centre.labels[idx] = centre_world
                    .labels
                    .get(k)
                    .copied()
                    .unwrap_or(truth::IGNORED);
                centre.band[idx] = centre_world.band.get(k).copied().unwrap_or(false);
                centre.never_seen_moving[idx] = centre_world
                    .never_seen_moving
                    .get(k)
                    .copied()
                    .unwrap_or(false);
                self.previous_storage[idx] = self
                    .previous_world
                    .get(k)
                    .copied()
                    .unwrap_or(truth::IGNORED);
                self.outline_storage[idx] = self.outline_world.get(k).copied().unwrap_or(false);
                k += 1;
            }
        }
        seconds
    }

    /// Notes the cells the front end's SensorGrid saw free (for the never-seen-moving rule).
    fn note_seen_free(&mut self, front_end: &FrontEnd) {
        for (seen, &f) in self
            .never_seen_moving
            .seen_free
            .iter_mut()
            .zip(front_end.sensor_grid().m_free())
        {
            *seen |= f > 0.0;
        }
    }
}

/// Who the truth's never-seen-moving rule covers: road users standing since they came into
/// view (their first scan return), on ground not seen free before (the cell of their centre
/// had no free evidence since it entered the window). One that moves after it came into view
/// loses the pass for good; one that appears on ground seen free never has it.
#[derive(Default)]
struct NeverSeenMoving {
    /// Per actor id: `None` until its first return, then whether it holds the pass.
    pass: Vec<Option<bool>>,
    /// Per storage cell: free evidence since the cell entered the window.
    seen_free: Vec<bool>,
    /// The actors holding the pass now (stopped), for the truth.
    ids: Vec<u32>,
}

impl NeverSeenMoving {
    /// Updates the passes with this frame's returns and classes, before `seen_free` takes in
    /// this frame's scan.
    fn update(&mut self, drive: &Drive, frame: &Frame, window: &Window) {
        let actors = drive.actors();
        self.pass.resize(actors.len(), None);
        let mut returns = vec![false; actors.len()];
        for hit in &frame.scan.hits {
            if let HitTarget::Actor(id) = *hit
                && let Some(r) = returns.get_mut(id as usize)
            {
                *r = true;
            }
        }
        self.ids.clear();
        for ((a, pass), &seen) in actors.iter().zip(self.pass.iter_mut()).zip(&returns) {
            if a.kind.is_infrastructure() {
                continue;
            }
            let moving = truth::actor_class(a) == Label::M;
            match pass {
                Some(p) if moving => *p = false,
                None if seen => {
                    let p = a.pose.position_m;
                    let ground_seen_free = window
                        .storage_index_of_point(p.x, p.y)
                        .and_then(|i| self.seen_free.get(i))
                        .is_some_and(|&f| f);
                    *pass = Some(!moving && !ground_seen_free);
                }
                _ => {}
            }
            if *pass == Some(true) {
                self.ids.push(a.id);
            }
        }
    }
}

/// The share of the front end's time a variant is charged: what it would cost the variant
/// alone (the map prior only for the variant that fuses it).
fn front_end_seconds(stats: &FrontEndStats, variant: Variant) -> f64 {
    let prior_ms = if variant.uses_map() {
        stats.prior_ms
    } else {
        0.0
    };
    (stats.pose_refinement.ms + stats.window_ms + prior_ms + stats.sensor_ms) / 1e3
}

/// Latency bookkeeping for one frame: per actor with returns, is any return's cell decided M?
fn update_latency(
    latency: &mut Latency,
    drive: &Drive,
    frame: &Frame,
    world_from_sensor: &evigrid::IsometryMatrix3,
    window: &Window,
    predicted: &[Label],
) {
    let scan = &frame.scan;
    // Actors with returns, in id order (BTreeMap: deterministic).
    let mut per_actor: std::collections::BTreeMap<u32, bool> = std::collections::BTreeMap::new();
    for (p, hit) in scan.points_in_sensor.iter().zip(&scan.hits) {
        if let HitTarget::Actor(id) = *hit {
            let [x, y, _] = world_from_sensor.transform_xyz([p.x, p.y, 0.0]);
            let decided = window
                .storage_index_of_point(x, y)
                .and_then(|i| predicted.get(i))
                .is_some_and(|&d| d == Label::M);
            *per_actor.entry(id).or_insert(false) |= decided;
        }
    }
    for (id, decided) in per_actor {
        let moving = drive
            .actors()
            .get(id as usize)
            .is_some_and(|a| truth::actor_class(a) == Label::M);
        latency.observe(id, frame.index as u32, moving, decided);
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use sim::testing::{small_scenario, town};

    #[test]
    fn variant_names_round_trip() {
        for v in Variant::ALL {
            assert_eq!(Variant::parse(v.name()).unwrap(), v);
        }
        // The paper's variant under its former name; serialised under its new one.
        assert_eq!(Variant::parse("full").unwrap(), Variant::Kurdej2013);
        assert_eq!(
            serde_json::to_string(&Variant::Kurdej2013).unwrap(),
            "\"kurdej2013\""
        );
        assert_eq!(
            serde_json::from_str::<Variant>("\"full\"").unwrap(),
            Variant::Kurdej2013
        );
        assert!(matches!(
            Variant::parse("octomap"),
            Err(EvalError::UnknownVariant { .. })
        ));
    }

    fn small_config() -> EvalConfig {
        let mut config = EvalConfig::default();
        config.params.window.width_cells = 240;
        config.params.window.height_cells = 240;
        config
    }

    #[test]
    fn observer_sees_every_frame_of_every_pipeline_variant_and_changes_nothing() {
        let mut scenario = small_scenario(6);
        scenario.duration_s = 1.0;
        let variants = [Variant::Kurdej2013, Variant::LogOdds, Variant::NoMap];
        let mut seen = Vec::new();
        let observed = evaluate_observed(
            &town(),
            &scenario,
            &variants,
            &[6, 7],
            &small_config(),
            &mut |_| {},
            &mut |f: FusionFrame<'_>| {
                assert_eq!(f.fusion.decisions().len(), 240 * 240);
                seen.push((f.seed_index, f.frame, f.variant));
            },
        )
        .unwrap();
        // Per seed, per frame, the pipeline variants in the order asked; baselines are not seen.
        let mut expected = Vec::new();
        for seed_index in 0..2 {
            for frame in 0..10 {
                expected.push((seed_index, frame, Variant::Kurdej2013));
                expected.push((seed_index, frame, Variant::NoMap));
            }
        }
        assert_eq!(seen, expected);
        let plain = evaluate(
            &town(),
            &scenario,
            &variants,
            &[6, 7],
            &small_config(),
            &mut |_| {},
        )
        .unwrap();
        for (a, b) in observed.variants.iter().zip(&plain.variants) {
            assert_eq!(a.confusion, b.confusion);
        }
    }

    #[test]
    fn a_raised_stop_ends_the_evaluation_between_frames_with_what_was_scored() {
        let mut scenario = small_scenario(6);
        scenario.duration_s = 1.0;
        let variants = [Variant::Kurdej2013, Variant::LogOdds];
        let stop = AtomicBool::new(false);
        let mut frames_seen = 0;
        // Raised after the fourth frame of the first seed: no fifth frame, no second seed.
        let report = evaluate_until(
            &town(),
            &scenario,
            &variants,
            &[6, 7],
            &small_config(),
            &stop,
            &mut |p: Progress| {
                frames_seen += 1;
                if p.frame == 4 {
                    stop.store(true, Ordering::Relaxed);
                }
            },
            &mut |_| {},
        )
        .unwrap();
        assert_eq!(frames_seen, 4);
        assert!(!report.complete);
        assert_eq!(report.frames_run, 4);
        assert_eq!(report.seeds, [6]);
        assert_eq!(report.frames_per_seed, 10);
        assert_eq!(report.variants[0].per_seed.len(), 1);
        // The four frames scored are those a four-frame drive scores.
        let mut short = scenario.clone();
        short.duration_s = 0.4;
        let whole = evaluate(
            &town(),
            &short,
            &variants,
            &[6],
            &small_config(),
            &mut |_| {},
        )
        .unwrap();
        assert!(whole.complete && whole.frames_run == 4);
        for (a, b) in report.variants.iter().zip(&whole.variants) {
            assert_eq!(a.confusion, b.confusion);
        }
        // Raised before the start: nothing run, still a report.
        let none = evaluate_until(
            &town(),
            &scenario,
            &variants,
            &[6],
            &small_config(),
            &AtomicBool::new(true),
            &mut |_| {},
            &mut |_| {},
        )
        .unwrap();
        assert!(!none.complete && none.frames_run == 0 && none.seeds.is_empty());
    }

    #[test]
    fn evaluation_runs_every_variant_and_is_deterministic() {
        let mut scenario = small_scenario(5);
        scenario.duration_s = 3.0;
        let mut calls = 0;
        let report = evaluate(
            &town(),
            &scenario,
            &Variant::ALL,
            &[5],
            &small_config(),
            &mut |_| calls += 1,
        )
        .unwrap();
        assert_eq!(calls, 30);
        assert_eq!(report.variants.len(), 5);
        for v in &report.variants {
            assert!(v.scores.scored_cell_frames > 0);
        }
        let again = evaluate(
            &town(),
            &scenario,
            &Variant::ALL,
            &[5],
            &small_config(),
            &mut |_| {},
        )
        .unwrap();
        for (a, b) in report.variants.iter().zip(&again.variants) {
            assert_eq!(a.confusion, b.confusion);
        }
        let md = report.to_markdown();
        assert!(md.contains("| kurdej2013 |") && md.contains("| log-odds |"));
        // The masks nest: in view ⊆ observed once ⊆ all.
        for v in &report.variants {
            let (now, once, all) = (
                v.confusion_visible.total(),
                v.confusion.total(),
                v.confusion_all.total(),
            );
            assert!(0 < now && now <= once && once <= all, "{now} {once} {all}");
        }
        let json = serde_json::to_string(&report).unwrap();
        assert!(json.contains("\"no-map\""));
    }
}
