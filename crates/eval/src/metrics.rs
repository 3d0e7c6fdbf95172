//! Scores of a per-cell classification against the simulator's truth, accumulated frame by
//! frame in constant memory.
//!
//! # What is scored
//! Every frame, every cell of the window that is (a) not [`IGNORED`](sim::truth::IGNORED) in
//! truth and (b) inside the caller's scoring mask adds one (truth, prediction) pair to a
//! confusion matrix. A cell is counted once per frame, so long-lived cells weigh more, as in a
//! per-frame benchmark. The runner keeps one matrix per mask (see "Three masks" below).
//!
//! Truth and predictions are both [`Label`]s. Predictions are one of {F, I, U, S, M, O,
//! unknown}, where O ("occupied, static, class not resolved") is what a two-class baseline says
//! of an occupied cell that is not moving. Because a baseline cannot name I, U or S, two views
//! are reported:
//! - **five-class** scores on the matrix as is (O counts as a miss for I, U and S);
//! - **coarse** scores on {F, O = I ∪ U ∪ S, M}: truth and predictions I, U, S, O merge into O,
//!   which compares every method fairly on free / static-occupied / moving.
//!
//! # The truth rule: a cell is what covers its centre
//! The headline truth is [`sim::truth::label_window_centre`]: one rule for every object,
//! building or road user. No cell in view is left out of any score. A cell an object covers in
//! part without its centre is truth F (calling it M is a false M; missing the object there is
//! no miss); these cells, the *band*, are counted a second time in [`ConfusionMatrix::band`]
//! and reported as information ([`Scores::band_cell_frames`], [`Scores::band_predicted_moving`]).
//! A road user never seen moving (standing since it came into view, on ground never seen free)
//! is truth S, but no evidence tells it from a pole, so S and U are both correct there: its
//! cells go to [`ConfusionMatrix::never_seen_moving`] and are scored as truth S, except that
//! predicted U is a correct U ([`ConfusionMatrix::scored_counts`]); their count is reported
//! ([`Scores::never_seen_moving_cell_frames`]).
//!
//! # The previous rule, kept one release
//! Before issue 30 truth was [`sim::truth::label_window_with_outline`], and the evaluation
//! still scores it beside the headline (`scores_visible_previous` of the report):
//! - **The boundary band.** A cell a building covers in part, not at its centre, was truth
//!   [`Label::Edge`]. Its row is kept apart ([`ConfusionMatrix::edge`]): it adds a false
//!   positive to M (and, in the coarse view, to coarse M) when predicted M, counts as static in
//!   the static accuracy, and touches no other class's score ([`Scores::edge_cell_frames`],
//!   [`Scores::edge_predicted_moving`]).
//! - **The object outline band.** A cell an actor overlaps only by a sliver, at none of the
//!   truth's 3 × 3 samples, was scored as no class: its predictions are counted apart
//!   ([`ConfusionMatrix::outline`], [`Scores::outline_cell_frames`],
//!   [`Scores::outline_predicted_moving`]). A cell an actor covers at any sample was the actor's.
//!
//! # Definitions (per class c, counts over scored cell-frames)
//! TP = truth c and predicted c; FP = predicted c, truth not c; FN = truth c, predicted not c
//! (unknown included: failing to decide is a miss). Precision TP/(TP+FP), recall TP/(TP+FN),
//! IoU TP/(TP+FP+FN), F1 2TP/(2TP+FP+FN); a ratio with a zero denominator is `None`. Macro-F1 is
//! the mean F1 over the classes whose F1 is defined (a class absent from truth and prediction
//! neither helps nor hurts). M precision is the precision of class M: of the cells called moving,
//! the share that are.
//!
//! Static and dynamic accuracy follow the KTH DynamicMap benchmark (Zhang, Khoche & Jensfelt,
//! "A Dynamic Points Removal Benchmark in Point Cloud Maps", ITSC 2023; their
//! `scripts/py/eval/evaluate_all.py`): SA = correctly kept static / all truly static, DA =
//! correctly flagged dynamic / all truly dynamic, HA = their harmonic mean. For grids: SA is the
//! fraction of cells whose truth is F, I, U, S (or the previous rule's edge) that are *not*
//! predicted M (unknown counts as kept: it does not wrongly delete a static object); DA is the
//! fraction of truly M cells predicted M. Because free cells are most of the static ones, SA is close to 1 for any method
//! that rarely says M; **occupied-static accuracy** is the same ratio over truth I, U and S
//! only, the static objects a method could mistake for moving ones.
//!
//! Remanence: for a cell whose truth goes from M to F while the sensor observes it, the number of
//! frames until it is first predicted F (0 = the same frame). Cells that leave the window, stop
//! being F in truth, or never turn F are censored (counted, not timed). Latency: per moving
//! episode of an actor (it has scan returns and moves; the episode ends when it stops or goes
//! unseen), the frames from the episode's first return until a cell holding one of its returns
//! is predicted M.
//!
//! # Three masks
//! - **In view** (the headline): cells the sensor has evidence in at this frame (a return or a
//!   ray crossing). It scores what the sensor can see, like point-wise benchmarks.
//! - **Observed at least once** since the cell entered the window: adds the grid's memory of
//!   occluded cells. A scanner sees the near face of an object, never its inside: the cells
//!   inside a moving car were seen free before it came and are not observed while it is there, so
//!   no method can get them right (in `evigrid demo` they are most of the truly moving
//!   cell-frames), which caps the M IoU far below 1 and flatters nothing but the free class.
//! - **All** cells of the window: adds cells never observed, which every method leaves unknown.

use crate::Label;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Names of the truth classes, in the matrix's row order.
pub const TRUTH_NAMES: [&str; 5] = ["F", "I", "U", "S", "M"];

/// Row of each [`Label`] (by code) in [`ConfusionMatrix::counts`]: F, I, U, S, M; unknown and O
/// are never truth, edge has its own row.
const ROW: [Option<usize>; 8] = [
    None,
    Some(0),
    Some(1),
    Some(2),
    Some(3),
    Some(4),
    None,
    None,
];
/// Column of each [`Label`] (by code): F, I, U, S, M, O, unknown (edge is never a prediction;
/// it would count as no decision).
const COLUMN: [usize; 8] = [6, 0, 1, 2, 3, 4, 5, 6];

/// Column of predicted M.
const M_COLUMN: usize = COLUMN[Label::M as usize];

/// Counts of (truth, prediction) pairs: `counts[truth][predicted]`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ConfusionMatrix {
    /// Rows: truth F, I, U, S, M. Columns: predicted F, I, U, S, M, O, unknown.
    pub counts: [[u64; 7]; 5],
    /// Truth edge (the boundary band of a building), same columns. Absent in reports written
    /// before the band existed: read as zeros.
    #[serde(default)]
    pub edge: [u64; 7],
    /// Cells in the object outline band (truth F there, a sliver of an object), same columns:
    /// counted, never scored. Absent in reports written before the band existed: read as zeros.
    #[serde(default)]
    pub outline: [u64; 7],
    /// Centre rule: the band, cells covered in part without their centre (truth F, scored in
    /// `counts` as F), counted here a second time as information. Same columns.
    #[serde(default)]
    pub band: [u64; 7],
    /// Centre rule: truth S of a road user never seen moving, where S and U are both correct.
    /// Same columns; scored as truth S, except that predicted U counts as a correct U.
    #[serde(default)]
    pub never_seen_moving: [u64; 7],
}

impl ConfusionMatrix {
    /// Adds one pair. A truth that is not scored (unknown: ignored cells) is skipped.
    pub fn add(&mut self, truth: Label, predicted: Label) {
        let column = COLUMN[predicted as usize];
        if let Some(row) = ROW[truth as usize] {
            self.counts[row][column] += 1;
        } else if truth == Label::Edge {
            self.edge[column] += 1;
        }
    }

    /// Adds a frame: cell `k` counts when `observed[k]` is true. Slices must have equal length
    /// (extra elements of the longer ones are ignored).
    pub fn add_frame(&mut self, truth: &[Label], predicted: &[Label], observed: &[bool]) {
        for ((&t, &p), &o) in truth.iter().zip(predicted).zip(observed) {
            if o {
                self.add(t, p);
            }
        }
    }

    /// [`add_frame`](Self::add_frame), with the cells where `outline[k]` is true (the object
    /// outline band) counted apart in [`outline`](Self::outline) instead of scored.
    pub fn add_frame_with_outline(
        &mut self,
        truth: &[Label],
        predicted: &[Label],
        observed: &[bool],
        outline: &[bool],
    ) {
        for (((&t, &p), &o), &band) in truth.iter().zip(predicted).zip(observed).zip(outline) {
            if !o {
                continue;
            }
            if band && t == Label::F {
                self.outline[COLUMN[p as usize]] += 1;
            } else {
                self.add(t, p);
            }
        }
    }

    /// Adds a frame scored by the centre rule (`sim::truth::label_window_centre`): cell `k`
    /// counts when `observed[k]`; a cell flagged in `never_seen_moving` with truth S goes to
    /// [`never_seen_moving`](Self::never_seen_moving), any other to its row, and a cell of the
    /// band with truth F is counted in [`band`](Self::band) too. Slices must have equal length.
    pub fn add_frame_centre(
        &mut self,
        truth: &sim::truth::CentreTruth,
        predicted: &[Label],
        observed: &[bool],
    ) {
        let cells = truth
            .labels
            .iter()
            .zip(&truth.band)
            .zip(&truth.never_seen_moving)
            .zip(predicted.iter().zip(observed));
        for (((&t, &band), &parked), (&p, &o)) in cells {
            if !o {
                continue;
            }
            let column = COLUMN[p as usize];
            if parked && t == Label::S {
                self.never_seen_moving[column] += 1;
                continue;
            }
            if band && t == Label::F {
                self.band[column] += 1;
            }
            self.add(t, p);
        }
    }

    /// The rows F, I, U, S, M as scored: [`counts`](Self::counts) with the never-seen-moving
    /// cells folded in (predicted U as a correct U, anything else as truth S).
    pub fn scored_counts(&self) -> [[u64; 7]; 5] {
        let mut out = self.counts;
        let u_column = COLUMN[Label::U as usize];
        for (column, &n) in self.never_seen_moving.iter().enumerate() {
            if column == u_column {
                out[2][u_column] += n;
            } else {
                out[3][column] += n;
            }
        }
        out
    }

    /// Adds another matrix.
    pub fn merge(&mut self, other: &ConfusionMatrix) {
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            for (x, y) in a.iter_mut().zip(b) {
                *x += y;
            }
        }
        for (x, y) in self.edge.iter_mut().zip(&other.edge) {
            *x += y;
        }
        for (x, y) in self.outline.iter_mut().zip(&other.outline) {
            *x += y;
        }
        for (x, y) in self.band.iter_mut().zip(&other.band) {
            *x += y;
        }
        for (x, y) in self
            .never_seen_moving
            .iter_mut()
            .zip(&other.never_seen_moving)
        {
            *x += y;
        }
    }

    /// Total scored cell-frames: the rows, the never-seen-moving cells and the building
    /// boundary band of the previous rule (its outline band is not scored; the centre rule's
    /// band is already in the rows).
    pub fn total(&self) -> u64 {
        self.counts.iter().flatten().sum::<u64>()
            + self.never_seen_moving.iter().sum::<u64>()
            + self.edge.iter().sum::<u64>()
    }

    /// This matrix with the boundary band counted as truth I: what the labelling rule before
    /// the band (a building claims every cell it covers at any sample) would have scored, for
    /// mapped buildings (the band of a building missing from the map was U then). Used to show
    /// what the band changes.
    pub fn band_as_infrastructure(&self) -> ConfusionMatrix {
        let mut out = self.clone();
        for (i, e) in out.counts[1].iter_mut().zip(&out.edge) {
            *i += e;
        }
        out.edge = [0; 7];
        out
    }

    /// This matrix with the object outline band scored as truth F, as the labelling rule
    /// before the band did (an object claimed only the cells it covers at a sample). Used to
    /// show what the band changes.
    pub fn outline_as_free(&self) -> ConfusionMatrix {
        let mut out = self.clone();
        for (f, o) in out.counts[0].iter_mut().zip(&out.outline) {
            *f += o;
        }
        out.outline = [0; 7];
        out
    }

    /// The coarse 3 × 4 view: rows truth F, O, M; columns predicted F, O, M, unknown.
    pub fn coarse(&self) -> [[u64; 4]; 3] {
        let row_of = [0usize, 1, 1, 1, 2];
        let col_of = [0usize, 1, 1, 1, 2, 1, 3];
        let mut out = [[0u64; 4]; 3];
        for (t, row) in self.scored_counts().iter().enumerate() {
            for (p, &n) in row.iter().enumerate() {
                out[row_of[t]][col_of[p]] += n;
            }
        }
        out
    }

    /// Every score.
    pub fn scores(&self) -> Scores {
        // The band adds false positives to M only (see the module docs).
        let edge_moving = self.edge[M_COLUMN];
        let counts = self.scored_counts();
        let five: Vec<ClassScores> = (0..5)
            .map(|c| {
                let tp = counts[c][c];
                let mut fp: u64 = (0..5).filter(|&t| t != c).map(|t| counts[t][c]).sum();
                if c == 4 {
                    fp += edge_moving;
                }
                let fn_: u64 = counts[c].iter().sum::<u64>() - tp;
                ClassScores::new(TRUTH_NAMES[c], tp, fp, fn_)
            })
            .collect();
        let coarse_m = self.coarse();
        let coarse: Vec<ClassScores> = (0..3)
            .map(|c| {
                let tp = coarse_m[c][c];
                let mut fp: u64 = (0..3).filter(|&t| t != c).map(|t| coarse_m[t][c]).sum();
                if c == 2 {
                    fp += edge_moving;
                }
                let fn_: u64 = coarse_m[c].iter().sum::<u64>() - tp;
                ClassScores::new(["F", "O", "M"][c], tp, fp, fn_)
            })
            .collect();
        let edge_total: u64 = self.edge.iter().sum();
        let kept = |rows: &[[u64; 7]]| -> (u64, u64) {
            rows.iter().fold((0, 0), |(kept, total), r| {
                let n: u64 = r.iter().sum();
                (kept + n - r[M_COLUMN], total + n)
            })
        };
        let (occupied_kept, occupied_total) = kept(&counts[1..4]);
        let (free_kept, free_total) = kept(&counts[..1]);
        let static_total = free_total + occupied_total + edge_total;
        let static_kept = free_kept + occupied_kept + edge_total - edge_moving;
        let dynamic_total: u64 = counts[4].iter().sum();
        let dynamic_found = counts[4][M_COLUMN];
        let sa = ratio(static_kept, static_total);
        let da = ratio(dynamic_found, dynamic_total);
        let ha = match (sa, da) {
            (Some(s), Some(d)) if s + d > 0.0 => Some(2.0 * s * d / (s + d)),
            (Some(_), Some(_)) => Some(0.0),
            _ => None,
        };
        Scores {
            macro_f1: macro_f1(&five),
            macro_f1_coarse: macro_f1(&coarse),
            moving_iou: five[4].iou,
            moving_precision: five[4].precision,
            occupied_static_accuracy: ratio(occupied_kept, occupied_total),
            edge_cell_frames: edge_total,
            edge_predicted_moving: edge_moving,
            outline_cell_frames: self.outline.iter().sum(),
            outline_predicted_moving: self.outline[M_COLUMN],
            band_cell_frames: self.band.iter().sum(),
            band_predicted_moving: self.band[M_COLUMN],
            never_seen_moving_cell_frames: self.never_seen_moving.iter().sum(),
            static_accuracy: sa,
            dynamic_accuracy: da,
            harmonic_accuracy: ha,
            classes: five,
            coarse_classes: coarse,
            scored_cell_frames: self.total(),
        }
    }
}

fn ratio(num: u64, den: u64) -> Option<f64> {
    (den > 0).then(|| num as f64 / den as f64)
}

fn macro_f1(classes: &[ClassScores]) -> Option<f64> {
    let defined: Vec<f64> = classes.iter().filter_map(|c| c.f1).collect();
    (!defined.is_empty()).then(|| defined.iter().sum::<f64>() / defined.len() as f64)
}

/// Scores of one class.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClassScores {
    /// Class name.
    pub class: String,
    /// True positives.
    pub tp: u64,
    /// False positives.
    pub fp: u64,
    /// False negatives.
    pub fn_: u64,
    /// TP / (TP + FP).
    pub precision: Option<f64>,
    /// TP / (TP + FN).
    pub recall: Option<f64>,
    /// TP / (TP + FP + FN).
    pub iou: Option<f64>,
    /// 2TP / (2TP + FP + FN).
    pub f1: Option<f64>,
}

impl ClassScores {
    fn new(class: &str, tp: u64, fp: u64, fn_: u64) -> Self {
        Self {
            class: class.to_string(),
            tp,
            fp,
            fn_,
            precision: ratio(tp, tp + fp),
            recall: ratio(tp, tp + fn_),
            iou: ratio(tp, tp + fp + fn_),
            f1: ratio(2 * tp, 2 * tp + fp + fn_),
        }
    }
}

/// All scores of a confusion matrix (see the module docs for definitions).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scores {
    /// Per class F, I, U, S, M.
    pub classes: Vec<ClassScores>,
    /// Per coarse class F, O (= I ∪ U ∪ S), M.
    pub coarse_classes: Vec<ClassScores>,
    /// Mean F1 over the five classes.
    pub macro_f1: Option<f64>,
    /// Mean F1 over the three coarse classes.
    pub macro_f1_coarse: Option<f64>,
    /// IoU of M.
    pub moving_iou: Option<f64>,
    /// Precision of M: of the cell-frames predicted M, the share truly M.
    #[serde(default)]
    pub moving_precision: Option<f64>,
    /// SA over truth I, U and S only.
    #[serde(default)]
    pub occupied_static_accuracy: Option<f64>,
    /// Cell-frames of the boundary band scored.
    #[serde(default)]
    pub edge_cell_frames: u64,
    /// Of those, predicted M.
    #[serde(default)]
    pub edge_predicted_moving: u64,
    /// Cell-frames in the object outline band, not scored.
    #[serde(default)]
    pub outline_cell_frames: u64,
    /// Of those, predicted M.
    #[serde(default)]
    pub outline_predicted_moving: u64,
    /// Centre rule: cell-frames of the band (covered in part without the centre, truth F),
    /// scored as F and reported here as information.
    #[serde(default)]
    pub band_cell_frames: u64,
    /// Of those, predicted M (false M of the centre rule).
    #[serde(default)]
    pub band_predicted_moving: u64,
    /// Centre rule: cell-frames of road users never seen moving (S and U both correct).
    #[serde(default)]
    pub never_seen_moving_cell_frames: u64,
    /// DynamicMap SA (truth F, I, U, S and edge).
    pub static_accuracy: Option<f64>,
    /// DynamicMap DA.
    pub dynamic_accuracy: Option<f64>,
    /// Harmonic mean of SA and DA.
    pub harmonic_accuracy: Option<f64>,
    /// Cell-frames scored.
    pub scored_cell_frames: u64,
}

/// Durations in frames, as a bounded histogram (the last bin holds everything at or beyond it).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FrameHistogram {
    bins: Vec<u64>,
}

impl Default for FrameHistogram {
    fn default() -> Self {
        Self {
            bins: vec![0; 1024],
        }
    }
}

impl FrameHistogram {
    /// Records one duration.
    pub fn add(&mut self, frames: u32) {
        let last = self.bins.len() - 1;
        self.bins[(frames as usize).min(last)] += 1;
    }
    /// Number of durations recorded.
    pub fn count(&self) -> u64 {
        self.bins.iter().sum()
    }
    /// Nearest-rank percentile (`p` in (0, 1]): the smallest duration d such that at least
    /// ⌈p·N⌉ recorded durations are ≤ d. `None` when empty.
    pub fn percentile(&self, p: f64) -> Option<u32> {
        let n = self.count();
        if n == 0 {
            return None;
        }
        let rank = ((p.clamp(0.0, 1.0) * n as f64).ceil() as u64).max(1);
        let mut acc = 0;
        for (d, &c) in self.bins.iter().enumerate() {
            acc += c;
            if acc >= rank {
                return Some(d as u32);
            }
        }
        None
    }
    /// Adds another histogram.
    pub fn merge(&mut self, other: &FrameHistogram) {
        for (a, b) in self.bins.iter_mut().zip(&other.bins) {
            *a += b;
        }
    }
}

/// Summary of a duration histogram.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DurationSummary {
    /// Events timed.
    pub timed: u64,
    /// Events started but never completed (censored).
    pub censored: u64,
    /// Median, frames.
    pub median_frames: Option<u32>,
    /// 95th percentile, frames.
    pub p95_frames: Option<u32>,
}

/// Remanence tracker over a fixed set of cells (indexed like the caller's grid storage).
#[derive(Clone, Debug)]
pub struct Remanence {
    /// Truth of the previous frame; [`IGNORED`](sim::truth::IGNORED) when there is none.
    previous_truth: Vec<Label>,
    /// Frame when the cell was vacated, or u32::MAX when not waiting.
    vacated_at: Vec<u32>,
    histogram: FrameHistogram,
    censored: u64,
}

const NOT_WAITING: u32 = u32::MAX;

impl Remanence {
    /// A tracker over `len` cells.
    pub fn new(len: usize) -> Self {
        Self {
            previous_truth: vec![sim::truth::IGNORED; len],
            vacated_at: vec![NOT_WAITING; len],
            histogram: FrameHistogram::default(),
            censored: 0,
        }
    }
    /// Forgets cell `idx` (it left the window): a pending wait is censored.
    pub fn reset(&mut self, idx: usize) {
        if let Some(v) = self.vacated_at.get_mut(idx) {
            if *v != NOT_WAITING {
                self.censored += 1;
            }
            *v = NOT_WAITING;
            self.previous_truth[idx] = sim::truth::IGNORED;
        }
    }
    /// Updates cell `idx` at `frame` with its truth, prediction and whether the sensor observes it
    /// in this frame.
    pub fn update(
        &mut self,
        idx: usize,
        frame: u32,
        truth: Label,
        predicted: Label,
        observed_now: bool,
    ) {
        let Some(prev) = self.previous_truth.get(idx).copied() else {
            return;
        };
        let (f, m) = (Label::F, Label::M);
        if prev == m && truth == f && observed_now && self.vacated_at[idx] == NOT_WAITING {
            self.vacated_at[idx] = frame;
        }
        let start = self.vacated_at[idx];
        if start != NOT_WAITING {
            if truth != f {
                self.censored += 1;
                self.vacated_at[idx] = NOT_WAITING;
            } else if predicted == Label::F {
                self.histogram.add(frame.saturating_sub(start));
                self.vacated_at[idx] = NOT_WAITING;
            }
        }
        self.previous_truth[idx] = truth;
    }
    /// Folds in another tracker's results (e.g. another seed's): its timed durations and its
    /// censored events, waiting cells included.
    pub fn merge(&mut self, other: &Remanence) {
        self.histogram.merge(&other.histogram);
        self.censored += other.summary().censored;
    }
    /// Summary so far (cells still waiting count as censored).
    pub fn summary(&self) -> DurationSummary {
        let waiting = self
            .vacated_at
            .iter()
            .filter(|&&v| v != NOT_WAITING)
            .count() as u64;
        DurationSummary {
            timed: self.histogram.count(),
            censored: self.censored + waiting,
            median_frames: self.histogram.percentile(0.5),
            p95_frames: self.histogram.percentile(0.95),
        }
    }
}

#[derive(Clone, Copy, Debug)]
struct LatencyState {
    /// Frame of the first return of the current moving episode, when one is being timed.
    pending_since: Option<u32>,
    /// The current moving episode has been decided M.
    decided: bool,
    /// Last frame the actor had returns.
    last_seen: u32,
}

/// Detection latency per actor and moving episode.
#[derive(Clone, Debug, Default)]
pub struct Latency {
    // BTreeMap: deterministic iteration order.
    actors: BTreeMap<u32, LatencyState>,
    histogram: FrameHistogram,
    censored: u64,
}

impl Latency {
    /// Records that `actor` has returns in `frame`; `moving` is its truth at that instant and
    /// `decided_moving` whether any cell holding one of its returns is predicted M.
    ///
    /// An episode starts at a frame where the actor has returns and moves; it is timed when a
    /// return cell is first decided M. It is censored (counted, not timed) when the actor stops
    /// first or goes unseen for a frame; the next return while moving starts a new episode.
    /// So a car that stops at a junction and drives off again is timed again when it restarts.
    pub fn observe(&mut self, actor: u32, frame: u32, moving: bool, decided_moving: bool) {
        let state = self.actors.entry(actor).or_insert(LatencyState {
            pending_since: None,
            decided: false,
            last_seen: frame,
        });
        let gap = frame.saturating_sub(state.last_seen) > 1;
        state.last_seen = frame;
        if !moving || gap {
            if state.pending_since.take().is_some() {
                self.censored += 1;
            }
            state.decided = false;
            if !moving {
                return;
            }
        }
        if state.decided {
            return;
        }
        let since = *state.pending_since.get_or_insert(frame);
        if decided_moving {
            self.histogram.add(frame.saturating_sub(since));
            state.pending_since = None;
            state.decided = true;
        }
    }
    /// Folds in another tracker's results (another drive: its actors are different actors).
    pub fn merge(&mut self, other: &Latency) {
        self.histogram.merge(&other.histogram);
        self.censored += other.summary().censored;
    }
    /// Summary so far.
    pub fn summary(&self) -> DurationSummary {
        DurationSummary {
            timed: self.histogram.count(),
            censored: self.censored
                + self
                    .actors
                    .values()
                    .filter(|s| s.pending_since.is_some())
                    .count() as u64,
            median_frames: self.histogram.percentile(0.5),
            p95_frames: self.histogram.percentile(0.95),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use Label as P;
    use approx::assert_relative_eq;

    fn hand_matrix() -> ConfusionMatrix {
        // Ten scored cells, one unobserved (would be F→M) and one ignored:
        // truth: F F F F I I   U S M M | F  | ignored
        // pred:  F F M U I unk U S M F | M  | M
        let truth = [
            P::F,
            P::F,
            P::F,
            P::F,
            P::I,
            P::I,
            P::U,
            P::S,
            P::M,
            P::M,
            P::F,
            sim::truth::IGNORED,
        ];
        let pred = [
            P::F,
            P::F,
            P::M,
            P::U,
            P::I,
            P::Unknown,
            P::U,
            P::S,
            P::M,
            P::F,
            P::M,
            P::M,
        ];
        let mut observed = [true; 12];
        observed[10] = false;
        let mut m = ConfusionMatrix::default();
        m.add_frame(&truth, &pred, &observed);
        m
    }

    #[test]
    fn confusion_matrix_counts_only_observed_scored_cells() {
        let m = hand_matrix();
        assert_eq!(m.total(), 10);
        assert_eq!(m.counts[0], [2, 0, 1, 0, 1, 0, 0]);
        assert_eq!(m.counts[1], [0, 1, 0, 0, 0, 0, 1]);
        assert_eq!(m.counts[4], [1, 0, 0, 0, 1, 0, 0]);
    }

    #[test]
    fn the_outline_band_is_counted_apart_and_scores_as_f_on_request() {
        use Label as P;
        // Truth F, F, F, M; the first two cells are in the outline band (F there only).
        let truth = [P::F, P::F, P::F, P::M];
        let pred = [P::M, P::F, P::M, P::M];
        let band = [true, true, false, true];
        let mut m = ConfusionMatrix::default();
        m.add_frame_with_outline(&truth, &pred, &[true; 4], &band);
        // Cell 3 is truly M: the band never hides a class.
        assert_eq!(m.outline, [1, 0, 0, 0, 1, 0, 0]);
        assert_eq!(m.counts[0], [0, 0, 0, 0, 1, 0, 0]);
        assert_eq!(m.counts[4], [0, 0, 0, 0, 1, 0, 0]);
        let s = m.scores();
        assert_eq!((s.outline_cell_frames, s.outline_predicted_moving), (2, 1));
        // M: TP 1, FP 1 → IoU 1/2; scored as F, the band's M is one more FP → 1/3.
        assert_eq!(s.moving_iou, Some(0.5));
        assert_eq!(m.outline_as_free().scores().moving_iou, Some(1.0 / 3.0));
    }

    #[test]
    fn centre_rule_band_is_scored_free_and_never_seen_moving_accepts_s_and_u() {
        use Label as P;
        // Truth F F F S S S M; cells 0, 1 in the band; cells 3, 4, 5 of a road user never
        // seen moving; cell 6 not observed.
        let truth = sim::truth::CentreTruth {
            labels: vec![P::F, P::F, P::F, P::S, P::S, P::S, P::M],
            band: vec![true, true, false, false, false, false, false],
            never_seen_moving: vec![false, false, false, true, true, true, false],
        };
        let pred = [P::M, P::F, P::F, P::U, P::S, P::M, P::M];
        let mut observed = [true; 7];
        observed[6] = false;
        let mut m = ConfusionMatrix::default();
        m.add_frame_centre(&truth, &pred, &observed);
        // The band is scored as F (one false M) and counted a second time apart.
        assert_eq!(m.counts[0], [2, 0, 0, 0, 1, 0, 0]);
        assert_eq!(m.band, [1, 0, 0, 0, 1, 0, 0]);
        assert_eq!(m.never_seen_moving, [0, 0, 1, 1, 1, 0, 0]);
        assert_eq!(m.total(), 6);
        let s = m.scores();
        assert_eq!((s.band_cell_frames, s.band_predicted_moving), (2, 1));
        assert_eq!(s.never_seen_moving_cell_frames, 3);
        // U: the one predicted U is correct (TP 1, FP 0). S: TP 1, FN 1 (predicted M).
        assert_eq!((s.classes[2].tp, s.classes[2].fp), (1, 0));
        assert_eq!(
            (s.classes[3].tp, s.classes[3].fp, s.classes[3].fn_),
            (1, 0, 1)
        );
        // M: TP 0 (the truly moving cell was not observed), FP 2: precision 0.
        assert_eq!((s.classes[4].tp, s.classes[4].fp), (0, 2));
        // Occupied-static: 3 cells, 2 kept (U, S); static: 6 cells, 4 kept.
        assert_relative_eq!(s.occupied_static_accuracy.unwrap_or(-1.0), 2.0 / 3.0);
        assert_relative_eq!(s.static_accuracy.unwrap_or(-1.0), 4.0 / 6.0);
    }

    #[test]
    fn every_score_matches_hand_computation() {
        let s = hand_matrix().scores();
        // F: TP 2, FP 1 (M→F), FN 2 (F→M, F→U): P 2/3, R 1/2, IoU 2/5, F1 4/7.
        let f = &s.classes[0];
        assert_eq!((f.tp, f.fp, f.fn_), (2, 1, 2));
        assert_relative_eq!(f.precision.unwrap_or(-1.0), 2.0 / 3.0);
        assert_relative_eq!(f.recall.unwrap_or(-1.0), 0.5);
        assert_relative_eq!(f.iou.unwrap_or(-1.0), 0.4);
        assert_relative_eq!(f.f1.unwrap_or(-1.0), 4.0 / 7.0);
        // I: TP 1, FP 0, FN 1 (unknown): P 1, R 1/2, IoU 1/2, F1 2/3.
        let i = &s.classes[1];
        assert_relative_eq!(i.precision.unwrap_or(-1.0), 1.0);
        assert_relative_eq!(i.recall.unwrap_or(-1.0), 0.5);
        assert_relative_eq!(i.iou.unwrap_or(-1.0), 0.5);
        // U: TP 1, FP 1 (F→U), FN 0: P 1/2, R 1, IoU 1/2, F1 2/3.
        let u = &s.classes[2];
        assert_relative_eq!(u.precision.unwrap_or(-1.0), 0.5);
        assert_relative_eq!(u.recall.unwrap_or(-1.0), 1.0);
        assert_relative_eq!(u.f1.unwrap_or(-1.0), 2.0 / 3.0);
        // S: perfect.
        assert_relative_eq!(s.classes[3].iou.unwrap_or(-1.0), 1.0);
        // M: TP 1, FP 1 (F→M), FN 1 (M→F): P 1/2, R 1/2, IoU 1/3, F1 1/2.
        assert_relative_eq!(s.moving_iou.unwrap_or(-1.0), 1.0 / 3.0);
        assert_relative_eq!(s.classes[4].f1.unwrap_or(-1.0), 0.5);
        // Macro-F1 = (4/7 + 2/3 + 2/3 + 1 + 1/2) / 5 = 0.680952…
        assert_relative_eq!(
            s.macro_f1.unwrap_or(-1.0),
            (4.0 / 7.0 + 2.0 / 3.0 + 2.0 / 3.0 + 1.0 + 0.5) / 5.0
        );
        assert_relative_eq!(
            s.macro_f1.unwrap_or(-1.0),
            0.680_952_380_952,
            epsilon = 1e-9
        );
        // SA: 8 static-truth cells (4 F, 2 I, 1 U, 1 S), one predicted M → 7/8.
        // DA: 1 of 2 M cells → 1/2. HA = 2·0.875·0.5 / 1.375 = 0.636363…
        assert_relative_eq!(s.static_accuracy.unwrap_or(-1.0), 0.875);
        assert_relative_eq!(s.dynamic_accuracy.unwrap_or(-1.0), 0.5);
        assert_relative_eq!(
            s.harmonic_accuracy.unwrap_or(-1.0),
            0.636_363_636_36,
            epsilon = 1e-9
        );
        // Coarse: O = I ∪ U ∪ S. Truth O cells: I→I, I→unk, U→U, S→S → TP 3, FN 1; FP 1 (F→U).
        // P 3/4, R 3/4, IoU 3/5, F1 3/4. F and M as before.
        let o = &s.coarse_classes[1];
        assert_eq!((o.tp, o.fp, o.fn_), (3, 1, 1));
        assert_relative_eq!(o.iou.unwrap_or(-1.0), 0.6);
        assert_relative_eq!(
            s.macro_f1_coarse.unwrap_or(-1.0),
            (4.0 / 7.0 + 0.75 + 0.5) / 3.0
        );
    }

    #[test]
    fn edge_band_counts_only_against_m_and_occupied_static_ignores_free() {
        let mut m = hand_matrix();
        // Hand matrix: M precision 1/2; occupied static (I, I, U, S) none predicted M → 1.
        let before = m.scores();
        assert_relative_eq!(before.moving_precision.unwrap_or(-1.0), 0.5);
        assert_eq!(before.occupied_static_accuracy, Some(1.0));
        // Three band cells: F, I, and M predictions; one S cell predicted M.
        m.add(P::Edge, P::F);
        m.add(P::Edge, P::I);
        m.add(P::Edge, P::M);
        m.add(P::S, P::M);
        assert_eq!(m.edge, [1, 1, 0, 0, 1, 0, 0]);
        assert_eq!(m.total(), 14);
        let s = m.scores();
        // F and I scores do not see the band: F as before; I gains nothing from edge → I.
        assert_eq!(s.classes[0], before.classes[0]);
        assert_eq!(s.classes[1], before.classes[1]);
        // M: TP 1, FP 1 (F→M) + 1 (S→M) + 1 (edge→M), FN 1 → precision 1/4, IoU 1/5.
        assert_eq!(
            (s.classes[4].tp, s.classes[4].fp, s.classes[4].fn_),
            (1, 3, 1)
        );
        assert_relative_eq!(s.moving_precision.unwrap_or(-1.0), 0.25);
        assert_relative_eq!(s.moving_iou.unwrap_or(-1.0), 0.2);
        assert_eq!(s.coarse_classes[2].fp, 3);
        // Occupied static: I, I, U, S, S(→M) → 4/5. SA: 8 + 1 static + 3 band = 12, 3 → M: 9/12.
        assert_relative_eq!(s.occupied_static_accuracy.unwrap_or(-1.0), 0.8);
        assert_relative_eq!(s.static_accuracy.unwrap_or(-1.0), 0.75);
        assert_eq!((s.edge_cell_frames, s.edge_predicted_moving), (3, 1));
        // Band counted as I: I gains a TP and two FN; M is scored the same.
        let old = m.band_as_infrastructure();
        assert_eq!(old.total(), m.total());
        assert_eq!(old.counts[1], [1, 2, 0, 0, 1, 0, 1]);
        let o = old.scores();
        assert_eq!(o.classes[4], s.classes[4]);
        assert_eq!(o.static_accuracy, s.static_accuracy);
        // Occupied static: I, I, U, S, S(→M), edge F, I, M(→M) → 6/8.
        assert_relative_eq!(o.occupied_static_accuracy.unwrap_or(-1.0), 0.75);
    }

    #[test]
    fn baseline_o_counts_as_static_in_coarse_view_only() {
        let mut m = ConfusionMatrix::default();
        // One I cell predicted O: five-class I recall 0, coarse O recall 1, SA 1.
        m.add(P::I, P::O);
        let s = m.scores();
        assert_eq!(s.classes[1].recall, Some(0.0));
        assert_eq!(s.coarse_classes[1].recall, Some(1.0));
        assert_eq!(s.static_accuracy, Some(1.0));
        assert_eq!(s.dynamic_accuracy, None);
        assert_eq!(s.harmonic_accuracy, None);
        // Undefined classes (F, U, S, M: no truth, no prediction) are left out of macro-F1:
        // only I (F1 0) counts.
        assert_eq!(s.macro_f1, Some(0.0));
    }

    #[test]
    fn remanence_times_vacated_cells_and_censors_the_rest() {
        let (f, m) = (P::F, P::M);
        let mut r = Remanence::new(4);
        // Cell 0: truth M M F F F F, pred M M M M F F → vacated at 2, F at 4: 2 frames.
        // Cell 1: truth M F, pred M F → 0 frames.
        // Cell 2: truth M F F, pred M M M → censored (still waiting).
        // Cell 3: truth M F, but not observed when vacated → never starts.
        let t0 = [m, m, f, f, f, f];
        let p0 = [P::M, P::M, P::M, P::M, P::F, P::F];
        for k in 0..6 {
            r.update(0, k as u32, t0[k], p0[k], true);
        }
        r.update(1, 0, m, P::M, true);
        r.update(1, 1, f, P::F, true);
        for k in 0..3 {
            r.update(2, k, if k == 0 { m } else { f }, P::M, true);
        }
        r.update(3, 0, m, P::M, true);
        r.update(3, 1, f, P::M, false);
        let s = r.summary();
        assert_eq!(s.timed, 2);
        assert_eq!(s.censored, 1);
        // Nearest rank over {0, 2}: median rank ⌈1⌉ = 1 → 0; p95 rank ⌈1.9⌉ = 2 → 2.
        assert_eq!(s.median_frames, Some(0));
        assert_eq!(s.p95_frames, Some(2));
        // Leaving the window censors nothing more here; a waiting cell reset is censored once.
        r.reset(2);
        assert_eq!(r.summary().censored, 1);
    }

    #[test]
    fn latency_times_moving_episodes_from_first_return() {
        let mut l = Latency::default();
        // Actor 1 first seen moving at frame 3, decided M at frame 6 → 3 frames; later frames of
        // the same episode add nothing.
        l.observe(1, 3, true, false);
        l.observe(1, 4, true, false);
        l.observe(1, 5, true, false);
        l.observe(1, 6, true, true);
        l.observe(1, 7, true, true);
        // It stops (frame 8), restarts at frame 9 and is decided at once → 0 frames.
        l.observe(1, 8, false, false);
        l.observe(1, 9, true, true);
        // Actor 2 first seen stopped: nothing; moving from frame 4, decided at 5 → 1 frame.
        l.observe(2, 0, false, false);
        l.observe(2, 4, true, false);
        l.observe(2, 5, true, true);
        // Actor 3 moving, unseen after frame 1 (gap), seen again at 5 → first episode censored;
        // second one still pending at the end → censored too.
        l.observe(3, 1, true, false);
        l.observe(3, 5, true, false);
        let s = l.summary();
        assert_eq!(s.timed, 3);
        assert_eq!(s.censored, 2);
        // Durations {0, 1, 3}: median rank 2 → 1; p95 rank 3 → 3.
        assert_eq!(s.median_frames, Some(1));
        assert_eq!(s.p95_frames, Some(3));
    }
}
