//! Tuning evigrid's parameters on simulated drives: a coordinate search over a declared box,
//! every candidate scored by [`evaluate`] on several drives.
//!
//! **Objective.** For each drive (one scenario on one map with one seed) the tuned variant
//! ([`TuneOptions::variant`], `kurdej2013` by default) is scored on the cells in view (the
//! evaluation's headline mask, [`crate::metrics`]); the objective is the mean over drives of
//! `macro-F1 + w · IoU(M)` ([`TuneOptions::moving_iou_weight`], 0.25 by default). Until the
//! in-view mask was the headline the objective used the cells observed at least once, where
//! the interiors of cars, which no scanner sees, were most of the moving class. Macro-F1 weighs
//! the five classes equally, so no class can be bought with another; moving IoU gets an extra
//! weight because detecting moving objects is what the accumulator and the discount rates exist
//! for, while M's F1 is only a fifth of macro-F1. Drives are averaged, not pooled, so a long or
//! crowded drive does not outvote the others. A score that is undefined (class absent) counts 0.
//!
//! **Search.** [`coordinate_search`] is a deterministic pattern search: in each round every
//! dimension in turn is moved by ±`step` while that improves the objective by more than
//! [`TuneOptions::min_gain`] (first up, then down if up did not help), then the step is halved for
//! the next round. Candidates are clamped to the declared bounds and never tried twice. It needs
//! no gradient, copes with the objective's plateaus (decisions are thresholds) and its cost is
//! predictable: about two evaluations per dimension per round.
//!
//! **Key design decision.** The search is generic over the objective (a closure of a point in the
//! box), so it is tested on synthetic functions with a known optimum; [`tune`] only binds it to
//! [`Knob`]s of [`Params`] and to [`evaluate`], whose drives run in parallel (rayon).
//!
//! ```
//! use eval::tune::{Bounds, coordinate_search};
//! // A bowl with its optimum at (0.25, 0.75), inside the box [0, 1]².
//! let bounds = [Bounds::new(0.0, 1.0, 0.25)?, Bounds::new(0.0, 1.0, 0.25)?];
//! let search = coordinate_search(&bounds, &[0.5, 0.5], 3, 0.0, |x: &[f64]| {
//!     Ok::<f64, ()>(-((x[0] - 0.25).powi(2) + (x[1] - 0.75).powi(2)))
//! })
//! .expect("the objective never fails");
//! assert_eq!(search.best, vec![0.25, 0.75]);
//! # Ok::<(), eval::EvalError>(())
//! ```

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};

use evigrid::Params;
use geodata::LocalMap;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::runner::{EvalConfig, Variant, evaluate};
use sim::Scenario;

/// The box and the first step of one dimension of the search.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    /// Smallest value tried.
    pub lo: f64,
    /// Largest value tried.
    pub hi: f64,
    /// Step of the first round; halved every round.
    pub step: f64,
}

impl Bounds {
    /// A dimension `[lo, hi]` searched with a first step `step`.
    ///
    /// # Errors
    /// [`EvalError::InvalidTuneOption`] naming `tune.bounds` when the values are not finite, `lo > hi`
    /// or `step` is not positive.
    pub fn new(lo: f64, hi: f64, step: f64) -> Result<Self, EvalError> {
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(EvalError::InvalidTuneOption {
                field: "tune.bounds",
                value: hi - lo,
            });
        }
        if !(step > 0.0 && step.is_finite()) {
            return Err(EvalError::InvalidTuneOption {
                field: "tune.step",
                value: step,
            });
        }
        Ok(Self { lo, hi, step })
    }

    fn clamp(&self, v: f64) -> f64 {
        // Rounded to 1e-9 so that halved steps do not leave 0.30000000000000004 in the TOML.
        (v.clamp(self.lo, self.hi) * 1e9).round() / 1e9
    }
}

/// One point tried by [`coordinate_search`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trial {
    /// Round (0-based) in which it was tried.
    pub round: usize,
    /// Index of the dimension moved (None for the starting point).
    pub dimension: Option<usize>,
    /// The point.
    pub point: Vec<f64>,
    /// Its objective.
    pub score: f64,
    /// Whether the search moved to it.
    pub accepted: bool,
}

/// Result of [`coordinate_search`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Search {
    /// The best point found.
    pub best: Vec<f64>,
    /// Its objective.
    pub best_score: f64,
    /// Every point evaluated, in order (the start first).
    pub trials: Vec<Trial>,
    /// False when the search was stopped before its end ([`coordinate_search_until`]): `best`
    /// is the best of the trials made.
    #[serde(default = "complete_by_default")]
    pub complete: bool,
}

/// Searches and reports written before `complete` existed were complete.
fn complete_by_default() -> bool {
    true
}

/// Maximises `objective` over the box `bounds` from `start` by coordinate pattern search (see the
/// module docs): `rounds` rounds, step halved each round, a move accepted when it gains more than
/// `min_gain`. `start` is clamped into the box; no point outside it is ever evaluated and no
/// point twice. Deterministic: same inputs, same trials.
///
/// # Errors
/// The objective's first error, returned as is.
pub fn coordinate_search<E>(
    bounds: &[Bounds],
    start: &[f64],
    rounds: usize,
    min_gain: f64,
    objective: impl FnMut(&[f64]) -> Result<f64, E>,
) -> Result<Search, E> {
    let never = AtomicBool::new(false);
    coordinate_search_until(bounds, start, rounds, min_gain, &never, objective)
}

/// [`coordinate_search`] that stops before the next evaluation of the objective once `stop` is
/// raised (a signal): the search so far, [`Search::complete`] false. The start is always
/// evaluated.
///
/// # Errors
/// The objective's first error, returned as is.
pub fn coordinate_search_until<E>(
    bounds: &[Bounds],
    start: &[f64],
    rounds: usize,
    min_gain: f64,
    stop: &AtomicBool,
    mut objective: impl FnMut(&[f64]) -> Result<f64, E>,
) -> Result<Search, E> {
    let mut best: Vec<f64> = bounds
        .iter()
        .zip(start.iter().chain(std::iter::repeat(&f64::NAN)))
        .map(|(b, &v)| if v.is_finite() { b.clamp(v) } else { b.lo })
        .collect();
    let key = |p: &[f64]| p.iter().map(|v| v.to_bits()).collect::<Vec<u64>>();
    let mut seen: BTreeMap<Vec<u64>, f64> = BTreeMap::new();
    let mut best_score = objective(&best)?;
    seen.insert(key(&best), best_score);
    let mut trials = vec![Trial {
        round: 0,
        dimension: None,
        point: best.clone(),
        score: best_score,
        accepted: true,
    }];
    let mut complete = true;
    'rounds: for round in 0..rounds {
        let scale = 0.5f64.powi(round as i32);
        for (d, b) in bounds.iter().enumerate() {
            let step = b.step * scale;
            for direction in [1.0, -1.0] {
                let mut moved = false;
                loop {
                    let mut candidate = best.clone();
                    candidate[d] = b.clamp(best[d] + direction * step);
                    if candidate[d] == best[d] {
                        break; // against the bound
                    }
                    let k = key(&candidate);
                    let score = match seen.get(&k) {
                        Some(&s) => s,
                        None => {
                            if stop.load(Ordering::Relaxed) {
                                complete = false;
                                break 'rounds;
                            }
                            let s = objective(&candidate)?;
                            seen.insert(k, s);
                            trials.push(Trial {
                                round,
                                dimension: Some(d),
                                point: candidate.clone(),
                                score: s,
                                accepted: false,
                            });
                            s
                        }
                    };
                    if score > best_score + min_gain {
                        if let Some(t) = trials.iter_mut().rev().find(|t| t.point == candidate) {
                            t.accepted = true;
                        }
                        best = candidate;
                        best_score = score;
                        moved = true;
                    } else {
                        break;
                    }
                }
                if moved {
                    break; // improved upwards: no need to look downwards
                }
            }
        }
    }
    Ok(Search {
        best,
        best_score,
        trials,
        complete,
    })
}

/// A tunable parameter of [`Params`], by its TOML path.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[non_exhaustive]
pub enum Knob {
    /// `sensor.mu_free`, μ_F.
    MuFree,
    /// `sensor.mu_occupied`, μ_O.
    MuOccupied,
    /// `map.beta_building`, β_B.
    BetaBuilding,
    /// `map.beta_road`, β_R.
    BetaRoad,
    /// `map.beta_other`, β_T.
    BetaOther,
    /// `fusion.discount_per_second.F`.
    RateFree,
    /// `fusion.discount_per_second.I`.
    RateMappedInfrastructure,
    /// `fusion.discount_per_second.U`.
    RateUnmappedInfrastructure,
    /// `fusion.discount_per_second.S`.
    RateStopped,
    /// `fusion.discount_per_second.M`.
    RateMoving,
    /// `accumulator.delta_inc`, δ_inc.
    DeltaInc,
    /// `accumulator.delta_dec`, δ_dec.
    DeltaDec,
    /// `accumulator.gamma_occupied`, γ_O.
    GammaOccupied,
    /// `accumulator.gamma_conflict`, γ_∅.
    GammaConflict,
}

impl Knob {
    /// The parameter's TOML path, e.g. `map.beta_road`.
    pub fn path(self) -> &'static str {
        match self {
            Knob::MuFree => "sensor.mu_free",
            Knob::MuOccupied => "sensor.mu_occupied",
            Knob::BetaBuilding => "map.beta_building",
            Knob::BetaRoad => "map.beta_road",
            Knob::BetaOther => "map.beta_other",
            Knob::RateFree => "fusion.discount_per_second.F",
            Knob::RateMappedInfrastructure => "fusion.discount_per_second.I",
            Knob::RateUnmappedInfrastructure => "fusion.discount_per_second.U",
            Knob::RateStopped => "fusion.discount_per_second.S",
            Knob::RateMoving => "fusion.discount_per_second.M",
            Knob::DeltaInc => "accumulator.delta_inc",
            Knob::DeltaDec => "accumulator.delta_dec",
            Knob::GammaOccupied => "accumulator.gamma_occupied",
            Knob::GammaConflict => "accumulator.gamma_conflict",
        }
    }

    fn slot(self, p: &mut Params) -> &mut f64 {
        let rates = &mut p.fusion.discount_per_second;
        match self {
            Knob::MuFree => &mut p.sensor.mu_free,
            Knob::MuOccupied => &mut p.sensor.mu_occupied,
            Knob::BetaBuilding => &mut p.map.beta_building,
            Knob::BetaRoad => &mut p.map.beta_road,
            Knob::BetaOther => &mut p.map.beta_other,
            Knob::RateFree => &mut rates.free,
            Knob::RateMappedInfrastructure => &mut rates.mapped_infrastructure,
            Knob::RateUnmappedInfrastructure => &mut rates.unmapped_infrastructure,
            Knob::RateStopped => &mut rates.stopped,
            Knob::RateMoving => &mut rates.moving,
            Knob::DeltaInc => &mut p.accumulator.delta_inc,
            Knob::DeltaDec => &mut p.accumulator.delta_dec,
            Knob::GammaOccupied => &mut p.accumulator.gamma_occupied,
            Knob::GammaConflict => &mut p.accumulator.gamma_conflict,
        }
    }

    /// The parameter's value in `params`.
    pub fn get(self, params: &Params) -> f64 {
        let rates = &params.fusion.discount_per_second;
        match self {
            Knob::MuFree => params.sensor.mu_free,
            Knob::MuOccupied => params.sensor.mu_occupied,
            Knob::BetaBuilding => params.map.beta_building,
            Knob::BetaRoad => params.map.beta_road,
            Knob::BetaOther => params.map.beta_other,
            Knob::RateFree => rates.free,
            Knob::RateMappedInfrastructure => rates.mapped_infrastructure,
            Knob::RateUnmappedInfrastructure => rates.unmapped_infrastructure,
            Knob::RateStopped => rates.stopped,
            Knob::RateMoving => rates.moving,
            Knob::DeltaInc => params.accumulator.delta_inc,
            Knob::DeltaDec => params.accumulator.delta_dec,
            Knob::GammaOccupied => params.accumulator.gamma_occupied,
            Knob::GammaConflict => params.accumulator.gamma_conflict,
        }
    }

    /// Sets the parameter in `params`.
    pub fn set(self, params: &mut Params, value: f64) {
        *self.slot(params) = value;
    }
}

/// One dimension of the search space: a parameter and its box.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Dimension {
    /// The parameter.
    pub knob: Knob,
    /// Its box and first step.
    pub bounds: Bounds,
}

/// The parameters the issue asks to tune, in search order (map prior, sensor, then time: rates
/// and accumulator), each with a box that keeps the method meaningful: masses and thresholds
/// strictly inside (0, 1), rates of F, U, S, M not so low that a cell never forgets nor so high
/// that it forgets within a scan, δ_inc above 0 so that ζ still grows. First step 0.2, so two
/// rounds reach a 0.1 resolution and three 0.05; 0.1 for the two small-valued parameters, the
/// rate of I and δ_inc (a first search with step 0.2 stopped δ_inc at its bound).
pub fn default_space() -> Vec<Dimension> {
    let d = |knob, lo, hi, step| Dimension {
        knob,
        bounds: Bounds { lo, hi, step },
    };
    vec![
        d(Knob::BetaBuilding, 0.5, 0.99, 0.2),
        d(Knob::BetaRoad, 0.3, 0.99, 0.2),
        d(Knob::BetaOther, 0.1, 0.95, 0.2),
        d(Knob::MuFree, 0.3, 0.95, 0.2),
        d(Knob::MuOccupied, 0.3, 0.95, 0.2),
        d(Knob::RateFree, 0.05, 0.99, 0.2),
        d(Knob::RateMappedInfrastructure, 0.0, 0.5, 0.1),
        d(Knob::RateUnmappedInfrastructure, 0.0, 0.9, 0.2),
        d(Knob::RateStopped, 0.05, 0.95, 0.2),
        d(Knob::RateMoving, 0.3, 0.999, 0.2),
        d(Knob::DeltaInc, 0.01, 0.5, 0.1),
        d(Knob::DeltaDec, 0.05, 1.0, 0.2),
        d(Knob::GammaOccupied, 0.1, 0.95, 0.2),
        d(Knob::GammaConflict, 0.02, 0.9, 0.2),
    ]
}

/// A set of drives: one scenario on one map, run with each seed.
#[derive(Clone, Copy, Debug)]
pub struct DriveSet<'a> {
    /// Short name for reports (e.g. the scenario's file stem).
    pub name: &'a str,
    /// The map.
    pub map: &'a LocalMap,
    /// The scenario (its seed replaced by each of `seeds`).
    pub scenario: &'a Scenario,
    /// The seeds; one drive each.
    pub seeds: &'a [u64],
}

/// Scores of one variant over drives.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VariantScore {
    /// The variant.
    pub variant: Variant,
    /// Mean over drives of macro-F1 (F, I, U, S, M), undefined counted 0.
    pub macro_f1: f64,
    /// Mean over drives of the moving IoU, undefined counted 0.
    pub moving_iou: f64,
    /// `macro_f1 + w · moving_iou`, the tuning objective.
    pub objective: f64,
    /// Drives averaged.
    pub drives: usize,
}

/// Scores `params` on every drive of `sets` for each of `variants` (drives run in parallel): the
/// mean over drives of macro-F1, of moving IoU and of the objective with weight
/// `moving_iou_weight`.
///
/// # Errors
/// [`evaluate`]'s errors (bad scenario, no road, bad parameters); [`EvalError::NoSeeds`] when
/// there is no drive at all.
pub fn score_drives(
    params: &Params,
    sets: &[DriveSet<'_>],
    variants: &[Variant],
    moving_iou_weight: f64,
) -> Result<Vec<VariantScore>, EvalError> {
    let jobs: Vec<(&DriveSet<'_>, u64)> = sets
        .iter()
        .flat_map(|s| s.seeds.iter().map(move |&seed| (s, seed)))
        .collect();
    if jobs.is_empty() {
        return Err(EvalError::NoSeeds);
    }
    let config = EvalConfig {
        params: params.clone(),
        ..EvalConfig::default()
    };
    let per_drive: Vec<Vec<(f64, f64)>> = jobs
        .par_iter()
        .map(|(set, seed)| {
            let report = evaluate(
                set.map,
                set.scenario,
                variants,
                &[*seed],
                &config,
                &mut |_| {},
            )?;
            Ok(report
                .variants
                .iter()
                .map(|v| {
                    (
                        v.scores_visible.macro_f1.unwrap_or(0.0),
                        v.scores_visible.moving_iou.unwrap_or(0.0),
                    )
                })
                .collect())
        })
        .collect::<Result<_, EvalError>>()?;
    let n = per_drive.len() as f64;
    Ok(variants
        .iter()
        .enumerate()
        .map(|(k, &variant)| {
            let (f1, iou) = per_drive.iter().fold((0.0, 0.0), |(a, b), d| {
                let (f, i) = d.get(k).copied().unwrap_or((0.0, 0.0));
                (a + f, b + i)
            });
            let (macro_f1, moving_iou) = (f1 / n, iou / n);
            VariantScore {
                variant,
                macro_f1,
                moving_iou,
                objective: macro_f1 + moving_iou_weight * moving_iou,
                drives: per_drive.len(),
            }
        })
        .collect())
}

/// Settings of [`tune`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TuneOptions {
    /// The parameters searched and their boxes. By default [`default_space`].
    pub space: Vec<Dimension>,
    /// Rounds of the coordinate search (the step halves each round). By default 2.
    pub rounds: usize,
    /// Weight `w` of the moving IoU in the objective `macro-F1 + w · IoU(M)`. By default 0.25.
    pub moving_iou_weight: f64,
    /// Smallest gain of the objective that moves the search: below it a difference is noise of
    /// the drives, not a better parameter. By default 0.002.
    pub min_gain: f64,
    /// The variant whose objective is maximised. By default `kurdej2013`. A variant that does
    /// not read evigrid's parameters (a baseline) leaves the objective flat.
    #[serde(default = "default_variant")]
    pub variant: Variant,
}

fn default_variant() -> Variant {
    Variant::Kurdej2013
}

impl Default for TuneOptions {
    fn default() -> Self {
        Self {
            space: default_space(),
            rounds: 2,
            moving_iou_weight: 0.25,
            min_gain: 0.002,
            variant: default_variant(),
        }
    }
}

/// A candidate tried by [`tune`], with the parameter values of the search space.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Order in which it was tried (0 = the starting parameters).
    pub index: usize,
    /// Round (0-based).
    pub round: usize,
    /// TOML path of the parameter moved (None for the start).
    pub moved: Option<String>,
    /// Values of the search space's parameters, in its order.
    pub values: Vec<f64>,
    /// Objective of the tuned variant on the tuning drives.
    pub objective: f64,
    /// Mean macro-F1 of the tuned variant (cells in view).
    pub macro_f1: f64,
    /// Mean moving IoU of the tuned variant (cells in view).
    pub moving_iou: f64,
    /// Whether the search moved to it.
    pub accepted: bool,
}

/// Result of [`tune`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TuneReport {
    /// The options used.
    pub options: TuneOptions,
    /// TOML paths of the searched parameters, in the order of [`Candidate::values`].
    pub parameters: Vec<String>,
    /// The parameters the search started from (searched values clamped into their boxes).
    pub start: Params,
    /// The best parameters found.
    pub best: Params,
    /// Every candidate tried, in order.
    pub candidates: Vec<Candidate>,
    /// False when the search was stopped before its end ([`tune_until`]): `best` is the best
    /// of the candidates tried.
    #[serde(default = "complete_by_default")]
    pub complete: bool,
}

impl TuneReport {
    /// The starting candidate (index 0).
    pub fn start_candidate(&self) -> Option<&Candidate> {
        self.candidates.first()
    }

    /// The best candidate (the last accepted one).
    pub fn best_candidate(&self) -> Option<&Candidate> {
        self.candidates.iter().rev().find(|c| c.accepted)
    }
}

/// Where [`tune`] is.
#[derive(Clone, Debug, PartialEq)]
pub struct TuneProgress {
    /// Candidates scored so far.
    pub candidates: usize,
    /// Best objective so far.
    pub best_objective: f64,
}

/// Tunes the parameters of `options.space`, starting from `start`, to maximise the objective of
/// `options.variant` over the drives of `sets` (see the module docs). Other parameters keep
/// their values in `start`. `progress` is called after every candidate.
///
/// # Errors
/// [`EvalError::NoSeeds`] without drives, [`EvalError::InvalidTuneOption`] for an empty search space
/// or bounds outside `[0, 1]`, and [`evaluate`]'s errors.
pub fn tune(
    start: &Params,
    sets: &[DriveSet<'_>],
    options: &TuneOptions,
    progress: &mut dyn FnMut(TuneProgress),
) -> Result<TuneReport, EvalError> {
    tune_until(start, sets, options, &AtomicBool::new(false), progress)
}

/// [`tune`] that stops between two candidates once `stop` is raised (a signal): the report of
/// the candidates tried, [`TuneReport::complete`] false. The starting candidate is always
/// scored.
///
/// # Errors
/// As [`tune`].
pub fn tune_until(
    start: &Params,
    sets: &[DriveSet<'_>],
    options: &TuneOptions,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(TuneProgress),
) -> Result<TuneReport, EvalError> {
    if options.space.is_empty() {
        return Err(EvalError::InvalidTuneOption {
            field: "tune.space",
            value: 0.0,
        });
    }
    for d in &options.space {
        // Every tunable parameter is a mass, rate or threshold in [0, 1].
        Bounds::new(d.bounds.lo, d.bounds.hi, d.bounds.step)?;
        if d.bounds.lo < 0.0 || d.bounds.hi > 1.0 {
            return Err(EvalError::InvalidTuneOption {
                field: "tune.bounds",
                value: if d.bounds.lo < 0.0 {
                    d.bounds.lo
                } else {
                    d.bounds.hi
                },
            });
        }
    }
    let bounds: Vec<Bounds> = options.space.iter().map(|d| d.bounds).collect();
    let initial: Vec<f64> = options.space.iter().map(|d| d.knob.get(start)).collect();
    let with = |values: &[f64]| {
        let mut p = start.clone();
        for (d, &v) in options.space.iter().zip(values) {
            d.knob.set(&mut p, v);
        }
        p
    };
    let mut scored: Vec<VariantScore> = Vec::new();
    let mut best_so_far = f64::NEG_INFINITY;
    let search = coordinate_search_until(
        &bounds,
        &initial,
        options.rounds,
        options.min_gain,
        stop,
        |x| {
            let score = score_drives(
                &with(x),
                sets,
                &[options.variant],
                options.moving_iou_weight,
            )?
            .into_iter()
            .next()
            .ok_or(EvalError::NoVariants)?;
            best_so_far = best_so_far.max(score.objective);
            let objective = score.objective;
            scored.push(score);
            progress(TuneProgress {
                candidates: scored.len(),
                best_objective: best_so_far,
            });
            Ok::<f64, EvalError>(objective)
        },
    )?;
    let candidates = search
        .trials
        .iter()
        .zip(&scored)
        .enumerate()
        .map(|(index, (t, s))| Candidate {
            index,
            round: t.round,
            moved: t
                .dimension
                .map(|d| options.space[d].knob.path().to_string()),
            values: t.point.clone(),
            objective: s.objective,
            macro_f1: s.macro_f1,
            moving_iou: s.moving_iou,
            accepted: t.accepted,
        })
        .collect();
    Ok(TuneReport {
        options: options.clone(),
        parameters: options
            .space
            .iter()
            .map(|d| d.knob.path().to_string())
            .collect(),
        // The search clamps the start into the box; report what it actually started from.
        start: with(search.trials.first().map_or(&initial, |t| &t.point)),
        best: with(&search.best),
        candidates,
        complete: search.complete,
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use sim::testing::{small_scenario, town};

    fn unit_box(step: f64, n: usize) -> Vec<Bounds> {
        vec![Bounds::new(0.0, 1.0, step).unwrap(); n]
    }

    #[test]
    fn finds_the_optimum_of_a_separable_bowl() {
        // Optimum (0.125, 0.875, 0.5) lies on the lattice of step 0.25 / 2 = 0.125 reached in
        // round 1 from the start 0.5.
        let target = [0.125, 0.875, 0.5];
        let search = coordinate_search(&unit_box(0.25, 3), &[0.5, 0.5, 0.5], 3, 0.0, |x| {
            Ok::<_, ()>(
                -x.iter()
                    .zip(&target)
                    .map(|(a, b)| (a - b).powi(2))
                    .sum::<f64>(),
            )
        })
        .unwrap();
        assert_eq!(search.best, target.to_vec());
        assert_eq!(search.best_score, 0.0);
    }

    #[test]
    fn optimum_on_a_bound_is_reached_and_never_passed() {
        // Increasing in x0 and decreasing in x1: optimum at the corner (0.9, 0.2).
        let bounds = [
            Bounds::new(0.1, 0.9, 0.3).unwrap(),
            Bounds::new(0.2, 0.8, 0.3).unwrap(),
        ];
        let mut tried = Vec::new();
        let search = coordinate_search(&bounds, &[0.5, 0.5], 4, 0.0, |x| {
            tried.push(x.to_vec());
            Ok::<_, ()>(x[0] - x[1])
        })
        .unwrap();
        assert_eq!(search.best, vec![0.9, 0.2]);
        for p in &tried {
            assert!(
                (0.1..=0.9).contains(&p[0]) && (0.2..=0.8).contains(&p[1]),
                "{p:?}"
            );
        }
        // No point evaluated twice.
        let mut unique = tried.clone();
        unique.sort_by(|a, b| a.partial_cmp(b).unwrap());
        unique.dedup();
        assert_eq!(unique.len(), tried.len());
        assert_eq!(search.trials.len(), tried.len());
    }

    #[test]
    fn start_outside_the_box_is_clamped_before_it_is_evaluated() {
        let mut first = None;
        coordinate_search(&unit_box(0.5, 1), &[3.0], 1, 0.0, |x| {
            first.get_or_insert(x[0]);
            Ok::<_, ()>(0.0)
        })
        .unwrap();
        assert_eq!(first, Some(1.0));
    }

    #[test]
    fn a_raised_stop_ends_the_search_before_the_next_candidate() {
        // Increasing in x: the whole search climbs 0.5 → 0.75 → 1.0 (step 0.25), three trials.
        let whole =
            coordinate_search(&unit_box(0.25, 1), &[0.5], 1, 0.0, |x| Ok::<_, ()>(x[0])).unwrap();
        assert!(whole.complete);
        assert_eq!(whole.trials.len(), 3);
        // Raised during the second evaluation: no third, the best of the two tried.
        let stop = AtomicBool::new(false);
        let mut evaluated = 0;
        let stopped = coordinate_search_until(&unit_box(0.25, 1), &[0.5], 1, 0.0, &stop, |x| {
            evaluated += 1;
            if evaluated == 2 {
                stop.store(true, Ordering::Relaxed);
            }
            Ok::<_, ()>(x[0])
        })
        .unwrap();
        assert_eq!(evaluated, 2);
        assert!(!stopped.complete);
        assert_eq!(stopped.best, vec![0.75]);
        assert_eq!(stopped.trials, whole.trials[..2]);
    }

    #[test]
    fn gains_below_min_gain_do_not_move_the_search() {
        // Slope 0.01 per unit: a step of 0.25 gains 0.0025 < 0.01.
        let search = coordinate_search(&unit_box(0.25, 1), &[0.5], 2, 0.01, |x| {
            Ok::<_, ()>(0.01 * x[0])
        })
        .unwrap();
        assert_eq!(search.best, vec![0.5]);
        assert!(search.trials.iter().skip(1).all(|t| !t.accepted));
    }

    #[test]
    fn search_is_deterministic_and_errors_propagate() {
        let f = |x: &[f64]| Ok::<_, ()>((x[0] * 7.0).sin() + (x[1] * 3.0).cos());
        let a = coordinate_search(&unit_box(0.2, 2), &[0.3, 0.6], 3, 0.0, f).unwrap();
        let b = coordinate_search(&unit_box(0.2, 2), &[0.3, 0.6], 3, 0.0, f).unwrap();
        assert_eq!(a, b);
        let failing = coordinate_search(&unit_box(0.2, 2), &[0.3, 0.6], 3, 0.0, |x| {
            if x[0] > 0.4 { Err("boom") } else { Ok(x[0]) }
        });
        assert_eq!(failing.err(), Some("boom"));
    }

    #[test]
    fn bounds_are_checked() {
        assert!(Bounds::new(0.5, 0.4, 0.1).is_err());
        assert!(Bounds::new(0.0, 1.0, 0.0).is_err());
        assert!(Bounds::new(f64::NAN, 1.0, 0.1).is_err());
    }

    #[test]
    fn knobs_read_and_write_their_own_parameter() {
        let space = default_space();
        let mut p = Params::default();
        for (k, d) in space.iter().enumerate() {
            d.knob.set(&mut p, 0.01 * (k + 1) as f64);
        }
        for (k, d) in space.iter().enumerate() {
            assert_eq!(d.knob.get(&p), 0.01 * (k + 1) as f64, "{}", d.knob.path());
        }
        let toml = p.to_toml_string().unwrap();
        assert!(toml.contains("gamma_conflict = 0.14"), "{toml}");
        // Every default lies inside its box, so the search starts from the defaults unchanged.
        let defaults = Params::default();
        for d in &space {
            let v = d.knob.get(&defaults);
            assert!(d.bounds.lo <= v && v <= d.bounds.hi, "{}", d.knob.path());
        }
    }

    #[test]
    fn tune_on_a_tiny_drive_never_worsens_and_reports_every_candidate() {
        let mut scenario = small_scenario(3);
        scenario.duration_s = 1.0;
        let map = town();
        let seeds = [3];
        let sets = [DriveSet {
            name: "town",
            map: &map,
            scenario: &scenario,
            seeds: &seeds,
        }];
        let mut start = Params::default();
        start.window.width_cells = 160;
        start.window.height_cells = 160;
        let options = TuneOptions {
            space: vec![
                Dimension {
                    knob: Knob::BetaBuilding,
                    bounds: Bounds::new(0.5, 0.99, 0.3).unwrap(),
                },
                Dimension {
                    knob: Knob::RateMoving,
                    bounds: Bounds::new(0.3, 0.999, 0.3).unwrap(),
                },
            ],
            rounds: 1,
            ..TuneOptions::default()
        };
        let mut calls = 0;
        let report = tune(&start, &sets, &options, &mut |_| calls += 1).unwrap();
        assert_eq!(calls, report.candidates.len());
        let first = report.start_candidate().unwrap();
        let best = report.best_candidate().unwrap();
        assert!(best.objective >= first.objective);
        assert_eq!(report.start, start);
        assert_eq!(
            Knob::BetaBuilding.get(&report.best),
            best.values[0],
            "best params carry the best candidate's values"
        );
        // Scoring the best parameters again gives the reported objective (deterministic).
        let again = score_drives(&report.best, &sets, &[Variant::Kurdej2013], 0.25).unwrap();
        assert_eq!(again[0].objective, best.objective);
        // Window size and other parameters are not touched.
        assert_eq!(report.best.window, start.window);
    }

    #[test]
    fn tune_rejects_a_box_outside_the_unit_interval_and_no_drives() {
        let options = TuneOptions {
            space: vec![Dimension {
                knob: Knob::DeltaInc,
                bounds: Bounds {
                    lo: 0.0,
                    hi: 2.0,
                    step: 0.5,
                },
            }],
            ..TuneOptions::default()
        };
        let map = town();
        let scenario = small_scenario(1);
        let sets = [DriveSet {
            name: "town",
            map: &map,
            scenario: &scenario,
            seeds: &[1],
        }];
        assert!(matches!(
            tune(&Params::default(), &sets, &options, &mut |_| {}),
            Err(EvalError::InvalidTuneOption { value, .. }) if value == 2.0
        ));
        assert!(matches!(
            tune(
                &Params::default(),
                &[],
                &TuneOptions::default(),
                &mut |_| {}
            ),
            Err(EvalError::NoSeeds)
        ));
    }
}
