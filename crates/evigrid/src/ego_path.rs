//! The ego-path check: a figure of merit for real drives that needs no labels.
//!
//! The vehicle will drive where its own poses say it drives next, so apart from traffic ahead
//! the cells along that path must be free. For frame k, the *ego path* is the polyline of the
//! sensor's positions from frame k on, cut at [`EGO_PATH_LENGTH_M`] of arc length (shorter at
//! the end of a drive); its cells are those whose centres lie within [`EGO_PATH_RADIUS_M`] of
//! it. Of those the frame's scan observed (non-vacuous SensorGrid cell), [`EgoPathCheck`] counts
//! how many the frame decided occupied (I, U, S) or moving (M). Every pose is known before a
//! run (from a pose file, a drive's GNSS/INS, or a first odometry pass), so the path ahead is
//! too.
//!
//! Positions are the sensor's, not the vehicle body's: on a roof lidar they differ by well under
//! the radius laterally, and the path is only used to pick cells.

use serde::Serialize;

use crate::grids::SensorGrid;
use crate::label::Label;
use crate::window::Window;

/// How far ahead the ego path reaches, metres of arc length.
pub const EGO_PATH_LENGTH_M: f64 = 20.0;
/// Cells whose centres lie within this distance of the path are on it, metres: about half a
/// car's width.
pub const EGO_PATH_RADIUS_M: f64 = 1.0;

/// The polyline from `positions[from]` along the following positions, cut at `length_m` of arc
/// length (the last vertex interpolated on its segment). Empty when `from` is out of range;
/// one vertex when the ego does not move after `from`.
pub fn path_ahead(positions: &[[f64; 2]], from: usize, length_m: f64) -> Vec<[f64; 2]> {
    let Some(&start) = positions.get(from) else {
        return Vec::new();
    };
    let mut path = vec![start];
    let mut left = length_m.max(0.0);
    for &next in positions.iter().skip(from + 1) {
        if left <= 0.0 {
            break;
        }
        let Some(&last) = path.last() else { break };
        let step = distance(last, next);
        if !step.is_finite() {
            break;
        }
        if step == 0.0 {
            continue;
        }
        if step <= left {
            path.push(next);
            left -= step;
        } else {
            let s = left / step;
            path.push([
                last[0] + (next[0] - last[0]) * s,
                last[1] + (next[1] - last[1]) * s,
            ]);
            left = 0.0;
        }
    }
    path
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// Unit direction of the segment of `path` nearest to `p` (the first, on ties); `None` when the
/// path has no segment of non-zero length.
fn nearest_segment_direction(path: &[[f64; 2]], p: [f64; 2]) -> Option<[f64; 2]> {
    let mut best: Option<(f64, [f64; 2])> = None;
    for w in path.windows(2) {
        let (a, b) = (w[0], w[1]);
        let length = distance(a, b);
        if !(length > 0.0 && length.is_finite()) {
            continue;
        }
        let d = distance_to_segment(p, a, b);
        if best.is_none_or(|(nearest, _)| d < nearest) {
            best = Some((d, [(b[0] - a[0]) / length, (b[1] - a[1]) / length]));
        }
    }
    best.map(|(_, direction)| direction)
}

/// Distance from `p` to the segment `a`–`b` (a point when `a == b`).
fn distance_to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let length2 = dx * dx + dy * dy;
    let s = if length2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    distance(p, [a[0] + dx * s, a[1] + dy * s])
}

/// Storage indices (sorted, each once) of the window's cells whose centres lie within
/// `radius_m` of the polyline `path` (of a single point, when it has one vertex). Cells outside
/// the window are left out.
pub fn cells_near_path(window: &Window, path: &[[f64; 2]], radius_m: f64) -> Vec<usize> {
    let mut cells = Vec::new();
    if !(radius_m.is_finite() && radius_m >= 0.0) {
        return cells;
    }
    let segments: Vec<([f64; 2], [f64; 2])> = match path {
        [] => Vec::new(),
        [only] => vec![(*only, *only)],
        _ => path.windows(2).map(|w| (w[0], w[1])).collect(),
    };
    for (a, b) in segments {
        let (Some(low), Some(high)) = (
            window.cell_of_point(a[0].min(b[0]) - radius_m, a[1].min(b[1]) - radius_m),
            window.cell_of_point(a[0].max(b[0]) + radius_m, a[1].max(b[1]) + radius_m),
        ) else {
            continue;
        };
        // Only the part of the segment's box inside the window.
        let cols = low.col.max(window.first_col())
            ..=high.col.min(window.first_col() + window.width() as i64 - 1);
        let rows = low.row.max(window.first_row())
            ..=high
                .row
                .min(window.first_row() + window.height() as i64 - 1);
        for row in rows {
            for col in cols.clone() {
                let (x, y) = window.cell_centre(col, row);
                if distance_to_segment([x, y], a, b) <= radius_m
                    && let Some(index) = window.storage_index(col, row)
                {
                    cells.push(index);
                }
            }
        }
    }
    cells.sort_unstable();
    cells.dedup();
    cells
}

/// The ego-path check of one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct EgoPathCheck {
    /// Cells on the ego path inside the window.
    pub path_cells: usize,
    /// Of those, cells the frame's scan observed (m(F) + m(O) > 0 in the SensorGrid).
    pub observed_cells: usize,
    /// Observed path cells decided I, U or S (occupied by something static).
    pub occupied_cells: usize,
    /// Observed path cells decided M (moving).
    pub moving_cells: usize,
    /// Of those, the cells the motion stage gave a velocity this frame that points along the
    /// path, within 45° of its nearest segment: traffic ahead going the ego's way, which the
    /// path may hold (see [`EgoPathCheck::count_traffic_ahead`]). Oncoming or crossing motion,
    /// and moving cells without a velocity, are not counted here.
    pub moving_along_path: usize,
}

/// The per-cell velocity the motion stage gave this frame (m/s east and north, 0 where it gave
/// none), in the window's storage order.
#[derive(Clone, Copy, Debug)]
pub struct CellVelocity<'a> {
    /// Velocity east, m/s.
    pub east: &'a [f32],
    /// Velocity north, m/s.
    pub north: &'a [f32],
}

impl EgoPathCheck {
    /// Counts, over `cells` (storage indices, as [`cells_near_path`] gives), those the sensor
    /// grid observed and, of those, the ones decided occupied or moving. Indices beyond the
    /// grids are ignored.
    pub fn count(cells: &[usize], sensor: &SensorGrid, decisions: &[Label]) -> Self {
        let (free, occupied) = (sensor.m_free(), sensor.m_occupied());
        let mut check = EgoPathCheck::default();
        for &i in cells {
            let (Some(f), Some(o), Some(d)) = (free.get(i), occupied.get(i), decisions.get(i))
            else {
                continue;
            };
            check.path_cells += 1;
            if f + o <= 0.0 {
                continue;
            }
            check.observed_cells += 1;
            match d {
                Label::I | Label::U | Label::S | Label::O | Label::Edge => {
                    check.occupied_cells += 1
                }
                Label::M => check.moving_cells += 1,
                Label::Unknown | Label::F => {}
            }
        }
        check
    }

    /// Counts [`Self::moving_along_path`]: of `cells` (as given to [`Self::count`]) those
    /// observed, decided M, and whose velocity lies within 45° of the direction of the nearest
    /// segment of `path` (the polyline the cells were taken from). A path of one vertex has no
    /// direction and counts none.
    pub fn count_traffic_ahead(
        &mut self,
        cells: &[usize],
        sensor: &SensorGrid,
        decisions: &[Label],
        window: &Window,
        path: &[[f64; 2]],
        velocity: CellVelocity<'_>,
    ) {
        let (free, occupied) = (sensor.m_free(), sensor.m_occupied());
        self.moving_along_path = 0;
        for &i in cells {
            let observed = free
                .get(i)
                .zip(occupied.get(i))
                .is_some_and(|(f, o)| f + o > 0.0);
            if !observed || decisions.get(i) != Some(&Label::M) {
                continue;
            }
            let (Some(&ve), Some(&vn), Some(cell)) = (
                velocity.east.get(i),
                velocity.north.get(i),
                window.cell_of_storage(i),
            ) else {
                continue;
            };
            let (x, y) = window.cell_centre(cell.col, cell.row);
            let Some([dx, dy]) = nearest_segment_direction(path, [x, y]) else {
                continue;
            };
            let (ve, vn) = (f64::from(ve), f64::from(vn));
            let speed = ve.hypot(vn);
            // cos 45° = √½: along the path, not across it or against it.
            if speed > 0.0 && (ve * dx + vn * dy) >= std::f64::consts::FRAC_1_SQRT_2 * speed {
                self.moving_along_path += 1;
            }
        }
    }

    /// Observed path cells decided occupied or moving.
    pub fn decided_occupied_or_moving(&self) -> usize {
        self.occupied_cells + self.moving_cells
    }

    /// [`Self::decided_occupied_or_moving`] over the observed path cells; `None` when none was
    /// observed.
    pub fn share(&self) -> Option<f64> {
        (self.observed_cells > 0)
            .then(|| self.decided_occupied_or_moving() as f64 / self.observed_cells as f64)
    }

    /// Observed path cells decided moving over the observed path cells; `None` when none was
    /// observed.
    pub fn moving_share(&self) -> Option<f64> {
        (self.observed_cells > 0).then(|| self.moving_cells as f64 / self.observed_cells as f64)
    }

    /// Observed path cells decided moving that are not traffic moving along the path, over the
    /// observed path cells: the moving cells the check forbids ("apart from traffic ahead, the
    /// path must be free"; occupied cells are counted apart). `None` when none was observed.
    pub fn moving_apart_from_traffic_share(&self) -> Option<f64> {
        (self.observed_cells > 0).then(|| {
            self.moving_cells.saturating_sub(self.moving_along_path) as f64
                / self.observed_cells as f64
        })
    }

    /// Adds another frame's counts (totals over a drive are sums of cell-frames).
    pub fn add(&mut self, other: &EgoPathCheck) {
        self.path_cells += other.path_cells;
        self.observed_cells += other.observed_cells;
        self.occupied_cells += other.occupied_cells;
        self.moving_cells += other.moving_cells;
        self.moving_along_path += other.moving_along_path;
    }
}

/// How a per-frame share spreads over a drive: its median and the frame furthest above it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ShareSpread {
    /// Median over the frames (mean of the two middle ones for an even count).
    pub median: f64,
    /// 0-based index of the frame with the largest share (the first, on ties).
    pub worst_frame: usize,
    /// Its share.
    pub worst: f64,
    /// `worst / median`; `None` when the median is 0.
    pub worst_to_median: Option<f64>,
}

impl ShareSpread {
    /// The spread of `shares` (non-finite values ignored); `None` without any finite value.
    pub fn of(shares: &[f64]) -> Option<Self> {
        let mut sorted: Vec<f64> = shares.iter().copied().filter(|v| v.is_finite()).collect();
        if sorted.is_empty() {
            return None;
        }
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let median = if n % 2 == 1 {
            sorted[n / 2]
        } else {
            0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
        };
        let (worst_frame, worst) = shares
            .iter()
            .copied()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .fold((0, f64::NEG_INFINITY), |best, (i, v)| {
                if v > best.1 { (i, v) } else { best }
            });
        Some(Self {
            median,
            worst_frame,
            worst,
            worst_to_median: (median > 0.0).then(|| worst / median),
        })
    }
}

/// [`ShareSpread`] of a drive of any length in constant memory: shares (in `[0, 1]`) go into a
/// histogram of [`ShareTracker::BINS`] bins, so the median is exact to half a bin (0.005
/// percentage points) and the worst frame exact.
#[derive(Clone, Debug)]
pub struct ShareTracker {
    bins: Vec<u64>,
    count: u64,
    frame: usize,
    worst: Option<(usize, f64)>,
}

impl Default for ShareTracker {
    fn default() -> Self {
        Self {
            bins: vec![0; Self::BINS],
            count: 0,
            frame: 0,
            worst: None,
        }
    }
}

impl ShareTracker {
    /// Bins of the histogram over `[0, 1]`.
    pub const BINS: usize = 10_000;

    /// Records the next frame's share (frames are numbered from 0 in push order; a non-finite
    /// share is skipped but still numbers its frame).
    pub fn push(&mut self, share: f64) {
        let frame = self.frame;
        self.frame += 1;
        if !share.is_finite() {
            return;
        }
        let bin = (share.clamp(0.0, 1.0) * Self::BINS as f64) as usize;
        self.bins[bin.min(Self::BINS - 1)] += 1;
        self.count += 1;
        if self.worst.is_none_or(|(_, w)| share > w) {
            self.worst = Some((frame, share));
        }
    }

    /// The spread so far; `None` before any finite share.
    pub fn spread(&self) -> Option<ShareSpread> {
        let (worst_frame, worst) = self.worst?;
        // The lower median's bin (the `(count + 1) / 2`-th value), at its centre.
        let rank = self.count.div_ceil(2);
        let mut seen = 0;
        let bin = self.bins.iter().position(|&n| {
            seen += n;
            seen >= rank
        })?;
        let median = (bin as f64 + 0.5) / Self::BINS as f64;
        Some(ShareSpread {
            median,
            worst_frame,
            worst,
            worst_to_median: (median > 0.0).then(|| worst / median),
        })
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn the_path_is_cut_at_its_length() {
        let positions = [[0.0, 0.0], [3.0, 4.0], [3.0, 14.0], [3.0, 30.0]];
        // 5 m, then 10 m, then 5 of the last 16 m.
        assert_eq!(
            path_ahead(&positions, 0, 20.0),
            vec![[0.0, 0.0], [3.0, 4.0], [3.0, 14.0], [3.0, 19.0]]
        );
        assert_eq!(
            path_ahead(&positions, 2, 20.0),
            vec![[3.0, 14.0], [3.0, 30.0]]
        );
        assert_eq!(path_ahead(&positions, 3, 20.0), vec![[3.0, 30.0]]);
        assert!(path_ahead(&positions, 4, 20.0).is_empty());
        // Standing still: repeated positions add nothing.
        assert_eq!(
            path_ahead(&[[1.0, 1.0], [1.0, 1.0], [1.0, 3.0]], 0, 1.0),
            vec![[1.0, 1.0], [1.0, 2.0]]
        );
    }

    #[test]
    fn cells_within_the_radius_of_a_straight_path() {
        // 1 m cells; a path along y = 0.5 from x = 0.5 to x = 3.5, radius 1: rows 0 (on the
        // line), -1 and 1 (centres 1 m off, included), cols 0..=3 (endpoints' own columns; the
        // centres at x = -0.5 and 4.5 are 1 m from the ends, included too).
        let mut window = Window::new(20, 20, 1.0).unwrap();
        let _ = window.move_to(-10, -10);
        let cells = cells_near_path(&window, &[[0.5, 0.5], [3.5, 0.5]], 1.0);
        let mut expected: Vec<usize> = (-1..=1)
            .flat_map(|row| (0..=3).map(move |col| (col, row)))
            .chain([(-1, 0), (4, 0)])
            .map(|(col, row)| window.storage_index(col, row).unwrap())
            .collect();
        expected.sort_unstable();
        assert_eq!(cells, expected);
        assert_eq!(cells.len(), 14);
        // One vertex: the cells around a point.
        assert_eq!(cells_near_path(&window, &[[0.5, 0.5]], 1.0).len(), 5);
        // Outside the window: nothing.
        assert!(cells_near_path(&window, &[[100.5, 0.5], [103.5, 0.5]], 1.0).is_empty());
    }

    #[test]
    fn counts_observed_cells_decided_occupied_or_moving() {
        let mut sensor = SensorGrid::new(6, 1);
        // Cells 0..5 observed (free or occupied), cell 5 not.
        sensor.m_free_mut()[..3].copy_from_slice(&[0.7, 0.7, 0.7]);
        sensor.m_occupied_mut()[3..5].copy_from_slice(&[0.8, 0.8]);
        let decisions = [
            Label::F,
            Label::M,
            Label::Unknown,
            Label::U,
            Label::S,
            Label::I, // not observed this frame: not counted
        ];
        let check = EgoPathCheck::count(&[0, 1, 2, 3, 4, 5, 99], &sensor, &decisions);
        assert_eq!(
            check,
            EgoPathCheck {
                path_cells: 6,
                observed_cells: 5,
                occupied_cells: 2,
                moving_cells: 1,
                moving_along_path: 0,
            }
        );
        assert_eq!(check.share(), Some(0.6));
        assert_eq!(check.moving_share(), Some(0.2));
        assert_eq!(check.moving_apart_from_traffic_share(), Some(0.2));
        let mut total = check;
        total.add(&EgoPathCheck {
            path_cells: 10,
            observed_cells: 5,
            occupied_cells: 0,
            moving_cells: 0,
            moving_along_path: 0,
        });
        assert_eq!(total.share(), Some(0.3));
        assert_eq!(EgoPathCheck::default().share(), None);
        assert_eq!(EgoPathCheck::default().moving_share(), None);
        assert_eq!(
            EgoPathCheck::default().moving_apart_from_traffic_share(),
            None
        );
    }

    #[test]
    fn traffic_ahead_is_moving_cells_whose_velocity_follows_the_path() {
        // 1 m cells; an L-shaped path: east along y = 0.5 to x = 8.5, then north. Cells
        // (0..6, 0) lie along the first leg, (9, 3) beside the second; all observed and decided
        // M, with velocities: east (along), 40° (along), 50° (not: beyond 45°), north (across),
        // west (oncoming), none (moving by past evidence only), and north at (9, 3) (along the
        // second leg, across the first).
        let mut window = Window::new(20, 20, 1.0).unwrap();
        let _ = window.move_to(-5, -5);
        let path = [[0.5, 0.5], [8.5, 0.5], [8.5, 10.5]];
        let cells: Vec<usize> = (0..6)
            .map(|col| (col, 0))
            .chain([(9, 3)])
            .map(|(col, row)| window.storage_index(col, row).unwrap())
            .collect();
        let mut sensor = SensorGrid::new(20, 20);
        let mut decisions = vec![Label::F; window.len()];
        let (mut east, mut north) = (vec![0.0f32; window.len()], vec![0.0f32; window.len()]);
        let at = |degrees: f32| {
            let a = degrees.to_radians();
            [10.0 * a.cos(), 10.0 * a.sin()]
        };
        for (&i, v) in cells.iter().zip([
            at(0.0),
            at(40.0),
            at(50.0),
            at(90.0),
            at(180.0),
            [0.0, 0.0],
            at(90.0),
        ]) {
            sensor.m_occupied_mut()[i] = 0.8;
            decisions[i] = Label::M;
            (east[i], north[i]) = (v[0], v[1]);
        }
        let mut check = EgoPathCheck::count(&cells, &sensor, &decisions);
        assert_eq!(check.moving_cells, 7);
        let velocity = CellVelocity {
            east: &east,
            north: &north,
        };
        check.count_traffic_ahead(&cells, &sensor, &decisions, &window, &path, velocity);
        assert_eq!(check.moving_along_path, 3);
        // 7 of 7 observed cells moving, 4 of them not traffic along the path.
        assert_eq!(check.moving_share(), Some(1.0));
        assert_eq!(check.moving_apart_from_traffic_share(), Some(4.0 / 7.0));
        // A path of one vertex has no direction.
        check.count_traffic_ahead(&cells, &sensor, &decisions, &window, &path[..1], velocity);
        assert_eq!(check.moving_along_path, 0);
    }

    #[test]
    fn the_spread_of_shares() {
        let spread = ShareSpread::of(&[0.2, 0.5, 0.1, f64::NAN, 0.3]).unwrap();
        // Finite values 0.1 0.2 0.3 0.5: median 0.25, worst 0.5 at index 1, ratio 2.
        assert_eq!(spread.median, 0.25);
        assert_eq!((spread.worst_frame, spread.worst), (1, 0.5));
        assert_eq!(spread.worst_to_median, Some(2.0));
        assert_eq!(
            ShareSpread::of(&[0.0, 0.0, 0.4]).unwrap().worst_to_median,
            None
        );
        assert!(ShareSpread::of(&[]).is_none());
    }

    #[test]
    fn the_tracker_agrees_with_the_exact_spread_to_half_a_bin() {
        let shares = [0.30, 0.25, f64::NAN, 0.61, 0.28, 0.29];
        let mut tracker = ShareTracker::default();
        for &s in &shares {
            tracker.push(s);
        }
        let approx = tracker.spread().unwrap();
        // Lower median of {0.25, 0.28, 0.29, 0.30, 0.61}: 0.29, in bin 2900.
        assert!(
            (approx.median - 0.29).abs() <= 0.5 / ShareTracker::BINS as f64,
            "{approx:?}"
        );
        assert_eq!((approx.worst_frame, approx.worst), (3, 0.61));
        let exact = ShareSpread::of(&shares).unwrap();
        assert_eq!(exact.worst_frame, approx.worst_frame);
        assert!((exact.median - approx.median).abs() <= 0.5 / ShareTracker::BINS as f64);
        assert!(ShareTracker::default().spread().is_none());
    }
}
