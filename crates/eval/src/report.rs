//! The evaluation report: per variant, confusion matrices, scores, remanence, latency and time
//! per frame, serialisable (`metrics.json`) and printable as Markdown tables. The headline is the
//! in-view mask (`scores_visible`); the masks "observed at least once" (`scores`) and "all cells"
//! (`scores_all`) follow as secondary tables (see [`crate::metrics`]).

use crate::metrics::{ConfusionMatrix, DurationSummary, Scores, TRUTH_NAMES};
use crate::variant::Variant;
use serde::{Deserialize, Serialize};
use sim::Scenario;

/// Headline scores of one seed (cells in view).
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
    /// Counts over all seeds and frames, cells observed at least once.
    pub confusion: ConfusionMatrix,
    /// Scores of `confusion`.
    pub scores: Scores,
    /// Counts over the cells observed in the frame itself, the headline (see [`crate::metrics`]).
    pub confusion_visible: ConfusionMatrix,
    /// Scores of `confusion_visible`: the headline scores.
    pub scores_visible: Scores,
    /// Counts over the cells in view by the previous truth rule (an object's samples, the
    /// building band scored as static, the object outline band unscored), kept one release so
    /// that the change of rule can be read. Absent in reports written before the centre rule.
    #[serde(default)]
    pub confusion_visible_previous: Option<ConfusionMatrix>,
    /// Scores of `confusion_visible_previous`.
    #[serde(default)]
    pub scores_visible_previous: Option<Scores>,
    /// Counts over every cell of the window.
    pub confusion_all: ConfusionMatrix,
    /// Scores of `confusion_all`.
    pub scores_all: Scores,
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
    /// False when the evaluation was stopped before its last frame (a signal): the scores are
    /// those of the frames run.
    #[serde(default = "complete_by_default")]
    pub complete: bool,
    /// Frames run and scored, over every seed.
    #[serde(default)]
    pub frames_run: usize,
    /// Seeds run (the last one only in part when the evaluation was stopped).
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

/// Reports written before `complete` existed were complete.
fn complete_by_default() -> bool {
    true
}

fn fmt(v: Option<f64>) -> String {
    v.map_or_else(|| "–".to_string(), |x| format!("{x:.3}"))
}

fn fmt_frames(v: Option<u32>) -> String {
    v.map_or_else(|| "–".to_string(), |x| x.to_string())
}

/// Header of a table of the scores of one mask.
const MASK_HEADER: &str = "| variant | IoU M | DA | M precision | occupied-static acc | SA | macro-F1 (F,I,U,S,M) | macro-F1 (F,O,M) | HA |\n|---|---|---|---|---|---|---|---|---|\n";

fn mask_row(name: &str, sc: &Scores) -> String {
    format!(
        "| {name} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
        fmt(sc.moving_iou),
        fmt(sc.dynamic_accuracy),
        fmt(sc.moving_precision),
        fmt(sc.occupied_static_accuracy),
        fmt(sc.static_accuracy),
        fmt(sc.macro_f1),
        fmt(sc.macro_f1_coarse),
        fmt(sc.harmonic_accuracy),
    )
}

impl EvalReport {
    /// The report as Markdown tables: the in-view headline, the other masks, the boundary band,
    /// IoU per class and the confusion matrices (in view).
    pub fn to_markdown(&self) -> String {
        let mut s = String::new();
        if !self.complete {
            s.push_str(&format!(
                "**Incomplete**: stopped after {} frames; the scores are those of the frames \
                 run.\n\n",
                self.frames_run
            ));
        }
        s.push_str(&format!(
            "Seeds {:?}, {} frames each ({:.0} ms apart); simulation {:.2} ms per frame.\n\n",
            self.seeds,
            self.frames_per_seed,
            self.frame_period_s * 1000.0,
            self.simulation_ms_per_frame
        ));
        s.push_str(
            "**Cells in view** (the sensor has evidence there in this frame; the headline):\n\n",
        );
        s.push_str(MASK_HEADER);
        for v in &self.variants {
            s.push_str(&mask_row(v.variant.name(), &v.scores_visible));
        }
        s.push_str(
            "\nRemanence and latency (over the whole drive, not masked) and time per frame:\n\n",
        );
        s.push_str("| variant | remanence median / p95 (frames) | latency median / p95 (frames) | ms / frame |\n|---|---|---|---|\n");
        for v in &self.variants {
            s.push_str(&format!(
                "| {} | {} / {} | {} / {} | {:.2} |\n",
                v.variant.name(),
                fmt_frames(v.remanence.median_frames),
                fmt_frames(v.remanence.p95_frames),
                fmt_frames(v.latency.median_frames),
                fmt_frames(v.latency.p95_frames),
                v.ms_per_frame
            ));
        }
        s.push_str("\nCells observed at least once since entering the window (secondary: adds the grid's memory of occluded cells, car interiors included):\n\n");
        s.push_str(MASK_HEADER);
        for v in &self.variants {
            s.push_str(&mask_row(v.variant.name(), &v.scores));
        }
        s.push_str("\nEvery cell of the window (secondary: adds cells never observed):\n\n");
        s.push_str(MASK_HEADER);
        for v in &self.variants {
            s.push_str(&mask_row(v.variant.name(), &v.scores_all));
        }
        s.push_str("\nThe band (cells in view an object covers in part without their centre: truth F, scored as F), and the road users never seen moving (truth S, S and U both correct), as information:\n\n");
        s.push_str("| variant | band share of cell-frames | band predicted F | band predicted M | never-seen-moving cell-frames | of those predicted S or U |\n|---|---|---|---|---|---|\n");
        for v in &self.variants {
            let sc = &v.scores_visible;
            let m = &v.confusion_visible;
            let share = (sc.scored_cell_frames > 0)
                .then(|| sc.band_cell_frames as f64 / sc.scored_cell_frames as f64);
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} |\n",
                v.variant.name(),
                fmt(share),
                m.band[0],
                sc.band_predicted_moving,
                sc.never_seen_moving_cell_frames,
                m.never_seen_moving[2] + m.never_seen_moving[3],
            ));
        }
        s.push_str("\nThe same cells in view scored by the previous truth rule (an object claimed every cell it covers at one of 3 × 3 samples; the building band scored as static only, the object outline band not scored), kept one release so that the change can be read:\n\n");
        s.push_str(MASK_HEADER);
        for v in &self.variants {
            if let Some(previous) = &v.scores_visible_previous {
                s.push_str(&mask_row(v.variant.name(), previous));
            }
        }
        s.push_str("\nIoU per class, cells in view (five-class view; O = I ∪ U ∪ S in the coarse view):\n\n");
        s.push_str("| variant | F | I | U | S | M | O (coarse) |\n|---|---|---|---|---|---|---|\n");
        for v in &self.variants {
            let c = &v.scores_visible.classes;
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} |\n",
                v.variant.name(),
                fmt(c[0].iou),
                fmt(c[1].iou),
                fmt(c[2].iou),
                fmt(c[3].iou),
                fmt(c[4].iou),
                fmt(v.scores_visible.coarse_classes[1].iou)
            ));
        }
        for v in &self.variants {
            s.push_str(&format!(
                "\nConfusion of {} (cell-frames in view; rows truth, columns prediction):\n\n",
                v.variant.name()
            ));
            s.push_str("| truth \\ predicted | F | I | U | S | M | O | unknown |\n|---|---|---|---|---|---|---|---|\n");
            let m = &v.confusion_visible;
            let never = m.never_seen_moving;
            for (name, row) in TRUTH_NAMES
                .iter()
                .zip(&m.counts)
                .chain(std::iter::once((&"S never seen moving", &never)))
            {
                let cells: Vec<String> = row.iter().map(u64::to_string).collect();
                s.push_str(&format!("| {name} | {} |\n", cells.join(" | ")));
            }
        }
        s
    }
}
