//! Variants side by side on the same simulated drive, scored against the truth.
//!
//! For every seed, one [`Drive`] is simulated and each scan is fed to every variant:
//! - `full`: evigrid's [`Pipeline`] as SPEC specifies, with the drive's pipeline map;
//! - `no-map`: the same pipeline without a map (GISGrid vacuous everywhere);
//! - `moras2011`, `log-odds`: the [`baselines`](crate::baselines), fed the SensorGrid of a shared
//!   front end (evigrid's own [`SensorModel`] on a [`Window`] recentred exactly as the pipeline's).
//!
//! Scans go in with the *estimated* sensor pose (localisation noise included); truth is labelled
//! in the world's true frame on the same world-fixed cells. The scanner is planar, so the sensor
//! model's ground model is forced to `none`. A cell is scored once it has been observed (the
//! shared SensorGrid had evidence in it at least once since it entered the window), the same
//! cells for every variant; a second confusion matrix scores only the cells observed in the frame
//! itself (`scores_visible`, see [`crate::metrics`] for why both). Per frame only counts are added
//! ([`crate::metrics`]): memory does not
//! depend on the length of the drive. Time per frame is wall-clock time of each variant's own
//! work; baselines are charged the shared SensorGrid build as well.

use crate::SimError;
use crate::baselines::{Baseline, LogOdds, LogOddsParams, Moras2011, Moras2011Params};
use crate::drive::Drive;
use crate::metrics::{ConfusionMatrix, DurationSummary, Latency, Predicted, Remanence, Scores};
use crate::scenario::Scenario;
use crate::sensor::HitTarget;
use crate::truth::{self, TruthClass};
use evigrid::pipeline::Pipeline;
use evigrid::sensor_model::{GroundModel, SensorModel};
use evigrid::{Decision, Params, SensorGrid, Window};
use geodata::{ContextRaster, LocalMap};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// A method to evaluate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Variant {
    /// evigrid with the map prior.
    #[serde(rename = "full")]
    Full,
    /// evigrid without a map.
    #[serde(rename = "no-map")]
    NoMap,
    /// Moras et al. 2011 two-class evidential grid.
    #[serde(rename = "moras2011")]
    Moras2011,
    /// OctoMap-style log-odds grid.
    #[serde(rename = "log-odds")]
    LogOdds,
}

impl Variant {
    /// All variants, in report order.
    pub const ALL: [Variant; 4] = [
        Variant::Full,
        Variant::NoMap,
        Variant::Moras2011,
        Variant::LogOdds,
    ];
    /// The name used on command lines and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Full => "full",
            Variant::NoMap => "no-map",
            Variant::Moras2011 => "moras2011",
            Variant::LogOdds => "log-odds",
        }
    }
    /// Parses a name.
    ///
    /// # Errors
    /// [`SimError::UnknownVariant`] for any other name.
    pub fn parse(name: &str) -> Result<Self, SimError> {
        Self::ALL
            .into_iter()
            .find(|v| v.name() == name)
            .ok_or_else(|| SimError::UnknownVariant {
                name: name.to_string(),
            })
    }
}

/// Settings of the methods under evaluation. By default evigrid's default parameters (with the
/// planar ground model) and the baselines' defaults.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EvalConfig {
    /// evigrid's parameters, for `full` and `no-map` and for the shared front end.
    pub params: Params,
    /// The Moras 2011 baseline.
    pub moras2011: Moras2011Params,
    /// The log-odds baseline.
    pub log_odds: LogOddsParams,
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

/// Scores of one seed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SeedScores {
    /// The seed.
    pub seed: u64,
    /// Macro-F1 over five classes.
    pub macro_f1: Option<f64>,
    /// IoU of M.
    pub moving_iou: Option<f64>,
}

/// Results of one variant over all seeds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VariantReport {
    /// The variant.
    pub variant: Variant,
    /// Counts over all seeds and frames.
    pub confusion: ConfusionMatrix,
    /// Scores of `confusion`.
    pub scores: Scores,
    /// Counts over the cells observed in the frame itself (see [`crate::metrics`]).
    pub confusion_visible: ConfusionMatrix,
    /// Scores of `confusion_visible`.
    pub scores_visible: Scores,
    /// Frames until a vacated cell is free again.
    pub remanence: DurationSummary,
    /// Frames from a moving actor's first return to a return cell decided M.
    pub latency: DurationSummary,
    /// Mean wall-clock time per frame, milliseconds.
    pub ms_per_frame: f64,
    /// Per-seed headline scores.
    pub per_seed: Vec<SeedScores>,
}

/// The evaluation report (serialisable).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalReport {
    /// The scenario (its seed replaced by each of `seeds`).
    pub scenario: Scenario,
    /// Seeds run.
    pub seeds: Vec<u64>,
    /// Frames per seed.
    pub frames_per_seed: usize,
    /// Scan period, seconds (to turn frames into seconds).
    pub frame_period_s: f64,
    /// One report per variant, in the order asked.
    pub variants: Vec<VariantReport>,
    /// Mean wall-clock time per frame of the simulation itself (actors, scan, truth), ms.
    pub simulation_ms_per_frame: f64,
}

struct Runner {
    variant: Variant,
    pipeline: Option<Pipeline>,
    baseline: Option<Box<dyn Baseline>>,
    predicted: Vec<Predicted>,
    confusion: ConfusionMatrix,
    seed_confusion: ConfusionMatrix,
    visible: ConfusionMatrix,
    remanence: Remanence,
    latency: Latency,
    seconds: f64,
}

fn predicted_of(d: Decision) -> Predicted {
    match d {
        Decision::Unknown => Predicted::Unknown,
        Decision::F => Predicted::F,
        Decision::I => Predicted::I,
        Decision::U => Predicted::U,
        Decision::S => Predicted::S,
        Decision::M => Predicted::M,
    }
}

/// Runs every variant on the drive of every seed and scores them.
///
/// # Errors
/// [`SimError`] from building a drive (bad scenario, no roads), [`SimError::Pipeline`] from
/// evigrid (bad parameters), [`SimError::NoSeeds`] / [`SimError::NoVariants`] for empty lists.
pub fn evaluate(
    map: &LocalMap,
    scenario: &Scenario,
    variants: &[Variant],
    seeds: &[u64],
    config: &EvalConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<EvalReport, SimError> {
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

/// What an observer of [`evaluate_observed`] sees after a pipeline variant has processed a frame.
#[derive(Clone, Copy)]
pub struct PipelineFrame<'a> {
    /// The variant (`full` or `no-map`).
    pub variant: Variant,
    /// Index of the seed in the seed list.
    pub seed_index: usize,
    /// Index of the frame in the drive.
    pub frame: usize,
    /// The pipeline, just after processing the frame: its window, grids and decisions.
    pub pipeline: &'a Pipeline,
}

/// [`evaluate`], calling `observer` after every frame of every pipeline variant (`full`,
/// `no-map`), so that a caller can render the views of the drive it scores without running the
/// pipeline a second time (`evigrid demo` does).
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
    observer: &mut dyn FnMut(PipelineFrame<'_>),
) -> Result<EvalReport, SimError> {
    if seeds.is_empty() {
        return Err(SimError::NoSeeds);
    }
    if variants.is_empty() {
        return Err(SimError::NoVariants);
    }
    let mut params = config.params.clone();
    params.sensor.ground_model = GroundModel::None;
    params
        .validate()
        .map_err(|e| SimError::Pipeline(e.into()))?;
    let (w, h) = (params.window.width_cells, params.window.height_cells);
    let len = w * h;
    let mut totals: Vec<Runner> = Vec::new();
    let mut per_seed: Vec<Vec<SeedScores>> = vec![Vec::new(); variants.len()];
    let mut frames_per_seed = 0;
    let mut frame_period_s = 0.0;
    let mut simulation_s = 0.0;
    for (seed_index, &seed) in seeds.iter().enumerate() {
        let scenario = Scenario {
            seed,
            ..scenario.clone()
        };
        let mut drive = Drive::new(map, &scenario)?;
        frames_per_seed = drive.frame_count();
        frame_period_s = drive.dt_s();
        let mut runners = Vec::with_capacity(variants.len());
        for &v in variants {
            let (pipeline, baseline): (Option<Pipeline>, Option<Box<dyn Baseline>>) = match v {
                Variant::Full => (
                    Some(Pipeline::new(
                        params.clone(),
                        Some(ContextRaster::new(drive.pipeline_map())),
                    )?),
                    None,
                ),
                Variant::NoMap => (Some(Pipeline::new(params.clone(), None)?), None),
                Variant::Moras2011 => (None, Some(Box::new(Moras2011::new(len, config.moras2011)))),
                Variant::LogOdds => (None, Some(Box::new(LogOdds::new(len, config.log_odds)))),
            };
            runners.push(Runner {
                variant: v,
                pipeline,
                baseline,
                predicted: vec![Predicted::Unknown; len],
                confusion: ConfusionMatrix::default(),
                seed_confusion: ConfusionMatrix::default(),
                visible: ConfusionMatrix::default(),
                remanence: Remanence::new(len),
                latency: Latency::default(),
                seconds: 0.0,
            });
        }
        simulation_s += run_drive(
            &mut drive,
            &params,
            &mut runners,
            seed_index,
            seeds.len(),
            progress,
            observer,
        )?;
        for (k, r) in runners.into_iter().enumerate() {
            let s = r.seed_confusion.scores();
            per_seed[k].push(SeedScores {
                seed,
                macro_f1: s.macro_f1,
                moving_iou: s.moving_iou,
            });
            match totals.get_mut(k) {
                Some(t) => {
                    t.confusion.merge(&r.seed_confusion);
                    t.visible.merge(&r.visible);
                    t.seconds += r.seconds;
                    // Remanence and latency histograms are per seed; fold them in.
                    t.remanence = merge_remanence(&t.remanence, &r.remanence);
                    t.latency = merge_latency(&t.latency, &r.latency);
                }
                None => {
                    let mut r = r;
                    r.confusion = r.seed_confusion.clone();
                    totals.push(r);
                }
            }
        }
    }
    let frames_total = (frames_per_seed * seeds.len()).max(1) as f64;
    let variants = totals
        .into_iter()
        .zip(per_seed)
        .map(|(r, per_seed)| VariantReport {
            variant: r.variant,
            scores: r.confusion.scores(),
            confusion: r.confusion,
            scores_visible: r.visible.scores(),
            confusion_visible: r.visible,
            remanence: r.remanence.summary(),
            latency: r.latency.summary(),
            ms_per_frame: r.seconds * 1000.0 / frames_total,
            per_seed,
        })
        .collect();
    Ok(EvalReport {
        scenario: scenario.clone(),
        seeds: seeds.to_vec(),
        frames_per_seed,
        frame_period_s,
        variants,
        simulation_ms_per_frame: simulation_s * 1000.0 / frames_total,
    })
}

fn merge_remanence(a: &Remanence, b: &Remanence) -> Remanence {
    let mut out = a.clone();
    out.merge(b);
    out
}

fn merge_latency(a: &Latency, b: &Latency) -> Latency {
    let mut out = a.clone();
    out.merge(b);
    out
}

/// Feeds one drive to every runner; returns the seconds spent simulating (scans and truth).
fn run_drive(
    drive: &mut Drive,
    params: &Params,
    runners: &mut [Runner],
    seed_index: usize,
    seeds: usize,
    progress: &mut dyn FnMut(Progress),
    observer: &mut dyn FnMut(PipelineFrame<'_>),
) -> Result<f64, SimError> {
    let mut simulation_s = 0.0;
    let (w, h, cell) = (
        params.window.width_cells,
        params.window.height_cells,
        params.grid.cell_size_m,
    );
    let len = w * h;
    let mut window = Window::new(w, h, cell).map_err(|e| SimError::Pipeline(e.into()))?;
    let mut sensor_model = SensorModel::new(params.sensor.clone());
    let mut sensor_grid = SensorGrid::new(w, h);
    let mut observed = vec![false; len];
    let mut observed_now = vec![false; len];
    let mut truth_world = Vec::new();
    let mut truth_storage = vec![truth::IGNORED; len];
    let mut first = true;
    let frames = drive.frame_count();
    loop {
        let started = Instant::now();
        let Some(frame) = drive.next_frame() else {
            break;
        };
        simulation_s += started.elapsed().as_secs_f64();
        let scan = &frame.scan;
        let est = scan.world_from_sensor_estimated;
        let pose = scan.estimated_isometry();
        let points = scan.points_xyz_f32();

        // Shared front end: window, observed mask, SensorGrid for the baselines.
        let started = Instant::now();
        let entered = window
            .recentre(est.position_m.x, est.position_m.y)
            .map_err(|e| SimError::Pipeline(e.into()))?;
        let mut entered_spans = Vec::new();
        if first {
            entered_spans.push(0..len);
        } else {
            for block in entered.blocks() {
                entered_spans.extend(window.storage_spans(block));
            }
        }
        sensor_model.build(&points, &pose, &window, &mut sensor_grid);
        let front_end_s = started.elapsed().as_secs_f64();
        for span in &entered_spans {
            observed[span.clone()].fill(false);
        }
        for ((o, now), (&f, &m)) in observed
            .iter_mut()
            .zip(observed_now.iter_mut())
            .zip(sensor_grid.m_free().iter().zip(sensor_grid.m_occupied()))
        {
            *now = f > 0.0 || m > 0.0;
            *o |= *now;
        }

        // Truth over the window, rearranged into storage order.
        let started = Instant::now();
        drive.truth(&window.as_cell_window(), &mut truth_world);
        simulation_s += started.elapsed().as_secs_f64();
        let mut k = 0;
        for span in window.world_order_spans() {
            for idx in span {
                truth_storage[idx] = truth_world.get(k).copied().unwrap_or(truth::IGNORED);
                k += 1;
            }
        }

        // Every variant.
        for r in runners.iter_mut() {
            let started = Instant::now();
            if let Some(p) = r.pipeline.as_mut() {
                p.process(&points, &pose, scan.time_s)?;
                // The pipeline's window is recentred from the same pose, so its storage layout
                // is ours; checked rather than assumed.
                if p.window().first_col() != window.first_col()
                    || p.window().first_row() != window.first_row()
                {
                    return Err(SimError::WindowMismatch);
                }
                for (out, &d) in r.predicted.iter_mut().zip(p.decisions()) {
                    *out = predicted_of(d);
                }
                r.seconds += started.elapsed().as_secs_f64();
                observer(PipelineFrame {
                    variant: r.variant,
                    seed_index,
                    frame: frame.index,
                    pipeline: p,
                });
            } else if let Some(b) = r.baseline.as_mut() {
                for span in &entered_spans {
                    b.reset_range(span.clone());
                }
                b.update(&sensor_grid, if first { 0.0 } else { drive.dt_s() });
                b.decide(&mut r.predicted);
                r.seconds += started.elapsed().as_secs_f64() + front_end_s;
            }
            for span in &entered_spans {
                for idx in span.clone() {
                    r.remanence.reset(idx);
                }
            }
            r.seed_confusion
                .add_frame(&truth_storage, &r.predicted, &observed);
            r.visible
                .add_frame(&truth_storage, &r.predicted, &observed_now);
            let frame_no = frame.index as u32;
            for idx in 0..len {
                r.remanence.update(
                    idx,
                    frame_no,
                    truth_storage[idx],
                    r.predicted[idx],
                    observed_now[idx],
                );
            }
            update_latency(&mut r.latency, drive, &frame, &window, &r.predicted);
        }
        first = false;
        progress(Progress {
            seed_index,
            seeds,
            frame: frame.index + 1,
            frames,
        });
    }
    Ok(simulation_s)
}

/// Latency bookkeeping for one frame: per actor with returns, is any return's cell decided M?
fn update_latency(
    latency: &mut Latency,
    drive: &Drive,
    frame: &crate::drive::Frame,
    window: &Window,
    predicted: &[Predicted],
) {
    let scan = &frame.scan;
    let est = scan.world_from_sensor_estimated;
    // Actors with returns, in id order (BTreeMap: deterministic).
    let mut per_actor: std::collections::BTreeMap<u32, bool> = std::collections::BTreeMap::new();
    for (p, hit) in scan.points_in_sensor.iter().zip(&scan.hits) {
        if let HitTarget::Actor(id) = *hit {
            let q = est.world_from_body(*p);
            let decided = window
                .storage_index_of_point(q.x, q.y)
                .and_then(|i| predicted.get(i))
                .is_some_and(|&d| d == Predicted::M);
            *per_actor.entry(id).or_insert(false) |= decided;
        }
    }
    for (id, decided) in per_actor {
        let moving = drive
            .actors()
            .get(id as usize)
            .is_some_and(|a| truth::actor_class(a) == TruthClass::M);
        latency.observe(id, frame.index as u32, moving, decided);
    }
}

fn fmt(v: Option<f64>) -> String {
    v.map_or_else(|| "–".to_string(), |x| format!("{x:.3}"))
}

fn fmt_frames(v: Option<u32>) -> String {
    v.map_or_else(|| "–".to_string(), |x| x.to_string())
}

impl EvalReport {
    /// The report as Markdown tables: headline scores, then IoU per class.
    pub fn to_markdown(&self) -> String {
        let mut s = String::new();
        s.push_str(&format!(
            "Seeds {:?}, {} frames each ({:.0} ms apart); simulation {:.2} ms per frame.\n\n",
            self.seeds,
            self.frames_per_seed,
            self.frame_period_s * 1000.0,
            self.simulation_ms_per_frame
        ));
        s.push_str("Cells observed at least once since entering the window:\n\n");
        s.push_str("| variant | macro-F1 (F,I,U,S,M) | macro-F1 (F,O,M) | IoU M | SA | DA | HA | remanence median / p95 (frames) | latency median / p95 (frames) | ms / frame |\n");
        s.push_str("|---|---|---|---|---|---|---|---|---|---|\n");
        for v in &self.variants {
            let sc = &v.scores;
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} / {} | {} / {} | {:.2} |\n",
                v.variant.name(),
                fmt(sc.macro_f1),
                fmt(sc.macro_f1_coarse),
                fmt(sc.moving_iou),
                fmt(sc.static_accuracy),
                fmt(sc.dynamic_accuracy),
                fmt(sc.harmonic_accuracy),
                fmt_frames(v.remanence.median_frames),
                fmt_frames(v.remanence.p95_frames),
                fmt_frames(v.latency.median_frames),
                fmt_frames(v.latency.p95_frames),
                v.ms_per_frame
            ));
        }
        s.push_str("\nCells observed in the frame itself (what the sensor sees now):\n\n");
        s.push_str("| variant | macro-F1 (F,I,U,S,M) | macro-F1 (F,O,M) | IoU M | SA | DA | HA |\n|---|---|---|---|---|---|---|\n");
        for v in &self.variants {
            let sc = &v.scores_visible;
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} |\n",
                v.variant.name(),
                fmt(sc.macro_f1),
                fmt(sc.macro_f1_coarse),
                fmt(sc.moving_iou),
                fmt(sc.static_accuracy),
                fmt(sc.dynamic_accuracy),
                fmt(sc.harmonic_accuracy),
            ));
        }
        s.push_str("\nIoU per class, cells observed at least once (five-class view; O = I ∪ U ∪ S in the coarse view):\n\n");
        s.push_str("| variant | F | I | U | S | M | O (coarse) |\n|---|---|---|---|---|---|---|\n");
        for v in &self.variants {
            let c = &v.scores.classes;
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} |\n",
                v.variant.name(),
                fmt(c[0].iou),
                fmt(c[1].iou),
                fmt(c[2].iou),
                fmt(c[3].iou),
                fmt(c[4].iou),
                fmt(v.scores.coarse_classes[1].iou)
            ));
        }
        for v in &self.variants {
            s.push_str(&format!(
                "\nConfusion of {} (cell-frames observed at least once; rows truth, columns prediction):\n\n",
                v.variant.name()
            ));
            s.push_str("| truth \\ predicted | F | I | U | S | M | O | unknown |\n|---|---|---|---|---|---|---|---|\n");
            for (name, row) in crate::metrics::TRUTH_NAMES.iter().zip(&v.confusion.counts) {
                let cells: Vec<String> = row.iter().map(u64::to_string).collect();
                s.push_str(&format!("| {name} | {} |\n", cells.join(" | ")));
            }
        }
        s
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::drive::tests::{small_scenario, town};

    #[test]
    fn variant_names_round_trip() {
        for v in Variant::ALL {
            assert_eq!(Variant::parse(v.name()).unwrap(), v);
        }
        assert!(matches!(
            Variant::parse("octomap"),
            Err(SimError::UnknownVariant { .. })
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
        let variants = [Variant::Full, Variant::LogOdds, Variant::NoMap];
        let mut seen = Vec::new();
        let observed = evaluate_observed(
            &town(),
            &scenario,
            &variants,
            &[6, 7],
            &small_config(),
            &mut |_| {},
            &mut |f: PipelineFrame<'_>| {
                assert_eq!(f.pipeline.decisions().len(), 240 * 240);
                seen.push((f.seed_index, f.frame, f.variant));
            },
        )
        .unwrap();
        // Per seed, per frame, the pipeline variants in the order asked; baselines are not seen.
        let mut expected = Vec::new();
        for seed_index in 0..2 {
            for frame in 0..10 {
                expected.push((seed_index, frame, Variant::Full));
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
        assert_eq!(report.variants.len(), 4);
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
        assert!(md.contains("| full |") && md.contains("| log-odds |"));
        let json = serde_json::to_string(&report).unwrap();
        assert!(json.contains("\"no-map\""));
    }
}
