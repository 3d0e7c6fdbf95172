//! What `evigrid run` shows a person: progress bars, one line per frame, the summary's lines.

use indicatif::ProgressBar;
use session::{FrameRecord, Progress, Summary};

/// The progress bars and per-frame lines of a run (no lines with `--json`).
pub struct Bars {
    json: bool,
    bar: Option<ProgressBar>,
}

impl Bars {
    /// Bars, and per-frame lines unless `json`.
    pub fn new(json: bool) -> Self {
        Self { json, bar: None }
    }

    fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}

impl Progress for Bars {
    fn odometry_started(&mut self, scans: usize) {
        self.bar = Some(crate::progress::bar(scans as u64, "odometry"));
    }

    fn odometry_scan(&mut self, _odometry: &odometry::Odometry) {
        if let Some(bar) = &self.bar {
            bar.inc(1);
        }
    }

    fn odometry_finished(&mut self) {
        self.finish();
    }

    fn frames_started(&mut self, frames: usize) {
        self.bar = Some(crate::progress::bar(frames as u64, "run"));
    }

    fn frame(&mut self, index: usize, record: Option<&FrameRecord>) {
        let Some(bar) = &self.bar else { return };
        if let Some(record) = record {
            tracing::debug!(
                "frame {index}: read {:.1} ms, process {:.1} ms, render {:.1} ms",
                record.read_ms,
                record.process_ms,
                record.render_ms
            );
            if !self.json {
                let line = frame_line(index, record);
                bar.suspend(|| crate::outln!("{line}"));
            }
        }
        bar.inc(1);
    }

    fn frames_finished(&mut self) {
        self.finish();
    }
}

/// One frame's numbers on one line.
fn frame_line(k: usize, f: &FrameRecord) -> String {
    format!(
        "frame {k:>4} {}: points {:.1} % ground, {:.1} % obstacle; cells {:.1} % occupied; {} \
         cells decided moving; ego path {}/{} observed cells occupied or moving ({})",
        f.scan,
        100.0 * f.ground_share,
        100.0 * f.obstacle_share,
        100.0 * f.obstacle_cell_share,
        f.classes[5],
        f.ego_path.decided_occupied_or_moving(),
        f.ego_path.observed_cells,
        percent(f.ego_path_share)
    )
}

fn percent(share: Option<f64>) -> String {
    share.map_or_else(|| "n/a".to_string(), |s| format!("{:.2} %", 100.0 * s))
}

/// The summary for people: totals, the ego-path check, the pose refinement, the spreads.
pub fn print_summary(summary: &Summary) {
    let [unknown, f, i, u, s, m] = summary.final_classes;
    crate::outln!(
        "{} frames, {:.1} ms per frame; final cells: {f} free, {i} mapped infrastructure, \
         {u} unmapped infrastructure, {s} stopped, {m} moving, {unknown} unknown; prior: {}; \
         poses: {} (matched by {}); outputs in {}",
        summary.frames,
        summary.mean_process_ms,
        summary.prior,
        summary.poses,
        summary.pose_matching,
        summary.out
    );
    let e = &summary.ego_path;
    crate::outln!(
        "ego path ({} m ahead, {} m either side): {} of {} observed cell-frames decided \
         occupied or moving ({}; {} occupied, {} moving ({}){})",
        e.length_m,
        e.radius_m,
        e.decided_occupied_or_moving,
        e.cell_frames,
        percent(e.share),
        e.occupied,
        e.moving,
        percent(e.moving_share),
        e.moving_along_path
            .zip(e.moving_apart_from_traffic_share)
            .map(|(n, rest)| format!(
                ", {n} of them traffic moving along the path, {} not ({} of the observed)",
                e.moving.saturating_sub(n),
                percent(Some(rest))
            ))
            .unwrap_or_default()
    );
    if let Some(line) = refinement_line(summary) {
        crate::outln!("{line}");
    }
    for (spread, what) in [
        (&summary.obstacle_share, "of a scan's points are obstacles"),
        (
            &summary.obstacle_cell_share,
            "of the observed cells are occupied",
        ),
    ] {
        if let Some(spread) = spread {
            crate::outln!(
                "median {:.1} % {what}; worst frame {} at {:.1} %, {} the median",
                100.0 * spread.median,
                spread.worst_frame,
                100.0 * spread.worst,
                spread
                    .worst_to_median
                    .map_or_else(|| "n/a ×".to_string(), |r| format!("{r:.2}×"))
            );
        }
    }
}

/// What the pose refinement did, on one line; `None` when it was off.
fn refinement_line(summary: &Summary) -> Option<String> {
    let r = summary.pose_refinement.as_ref()?;
    let refined = r.outcomes.get("refined").copied().unwrap_or(0);
    let kept: Vec<String> = r
        .outcomes
        .iter()
        .filter_map(|(name, n)| {
            let why = name.strip_prefix("kept_")?;
            Some(format!("{n} {}", why.replace('_', " ")))
        })
        .collect();
    let kept = if kept.is_empty() {
        String::new()
    } else {
        format!(", kept as given: {}", kept.join(", "))
    };
    let corrections = match (
        r.median_correction_m,
        r.largest_correction_m,
        r.largest_correction_frame,
    ) {
        (Some(median), Some(largest), Some(frame)) => {
            format!("; correction median {median:.3} m, largest {largest:.3} m (frame {frame})")
        }
        _ => String::new(),
    };
    Some(format!(
        "pose refinement: {refined} of {} poses refined{kept}{corrections}",
        summary.frames
    ))
}
