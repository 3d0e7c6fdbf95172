//! How far a cluster moved: its occupied cells shifted against the occupied cells of the last
//! frames (a correlation search over whole-cell shifts), one past frame after another.
//!
//! For each past frame `k` (1 = the previous one) and each shift `d` within the search radius,
//! `n_k(d)` counts the cluster's cells `c` whose cell `c − d` was occupied in frame `k`. A
//! non-zero best shift is kept only if it explains at least `shift_margin_fraction` of the
//! cluster (and one cell) more than the zero shift, so that a static object, whose best shift
//! is zero give or take a cell of pose error or of a face that slid into view, reads as
//! static; the shift is a measurement only if it explains at least `match_fraction` of the
//! cluster (an object first seen explains nothing and gives none). Frames further back are
//! tried until the shift is at least two cells long: a car at 10 m/s moves two cells in a
//! tenth of a second, a pedestrian needs the eight frames kept. All past frames are counted in
//! one pass per shift: each history byte is spread into eight byte lanes of a `u64`.
//!
//! The search works on whole cells of the world-fixed grid, so a pose error below a cell moves
//! no static cell's shift, and one of a cell or more moves all the clusters of a frame alike,
//! which the zero-shift preference absorbs for objects that stay in view.

use super::clusters::{Cell, Clusters};
use super::history::{OccupancyHistory, SLOTS};
use crate::params::MotionParams;
use crate::window::Window;

/// A past frame whose shift is this far, cells, from the velocity of the newer frames shows a
/// change of motion and ends the search.
const CHANGE_CELLS: f64 = 1.5;

/// Cells of a cluster counted at most: a long façade is sampled evenly.
const MAX_COUNTED_CELLS: usize = 256;

/// A cluster's velocity measured against the past frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Registration {
    /// Velocity in cells per second (east, north): the least-squares slope through the
    /// origin of the shifts d_k against the time spans τ_k of the frames that matched,
    /// Σ d_k·τ_k / Σ τ_k².
    pub(crate) velocity_cells_per_s: (f64, f64),
    /// Σ τ_k² of those frames, s².
    pub(crate) sum_span_sq: f64,
    /// Σ τ_k of those frames, s.
    pub(crate) sum_span: f64,
    /// Frames that matched.
    pub(crate) frames: usize,
}

/// The shift of the oldest frame a registration used, to tell a cluster's cells apart
/// ([`Registrar::moved`]).
#[derive(Clone, Copy, Debug, Default)]
struct LastShift {
    dx: i64,
    dy: i64,
    bit: u8,
}

/// The frame being registered: its time, its clusters and which of them is registered.
#[derive(Clone, Copy)]
pub(crate) struct Now<'a> {
    pub(crate) time_s: f64,
    pub(crate) clusters: &'a Clusters,
    pub(crate) cluster: u32,
    /// m(F) of the frame's SensorGrid: where rays crossed.
    pub(crate) m_free: &'a [f32],
    /// Cells seen empty by rays that met nothing within the sensor model's range
    /// ([`crate::SensorGrid::clear_cells`]).
    pub(crate) clear_now: &'a [bool],
    /// The sensor's position, in cells (column, row).
    pub(crate) sensor_cell: (f64, f64),
    /// Standard deviation per axis of the pose's position error, cells, and of its heading
    /// error, radians: what a static cluster's apparent shift between two scans comes from.
    pub(crate) pose_sigma_cells: f64,
    /// See `pose_sigma_cells`.
    pub(crate) pose_sigma_rad: f64,
    /// The velocity, cells/s (east, north), that a moving track predicts for the cluster
    /// (`motion.prior_after_moving_frames`; see [`Registrar::predicted_shift`]), if any.
    pub(crate) predicted_cells_per_s: Option<(f64, f64)>,
}

/// What a moving track's prediction makes of one past frame ([`Registrar::predicted_shift`]).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Prior {
    /// Nothing: no prediction, a predicted shift of zero, or neither it nor zero fits better.
    None,
    /// The shift near the prediction, with its count (`n`, `dx`, `dy`): taken.
    Taken(u32, i64, i64),
    /// Zero explains the cluster better than any shift near a prediction of a cell or more:
    /// the object stopped.
    Refuted,
}

/// Scratch buffers of the search, kept between clusters and frames.
#[derive(Clone, Debug, Default)]
pub(crate) struct Registrar {
    /// Per patch cell, the occupied-history byte (0 where another cluster is now).
    patch: Vec<u8>,
    /// Per patch cell, the seen-free history byte.
    free: Vec<u8>,
    /// Per patch cell, 0xff if the cell is seen free now, else 0.
    left: Vec<u8>,
    /// Patch index of each counted cell of the cluster.
    heres: Vec<usize>,
    /// As `counts`, only the cells whose move is seen (see `register`).
    seen_counts: Vec<[u32; SLOTS]>,
    counts: Vec<[u32; SLOTS]>,
    /// Patch geometry of the last cluster: width, first column and row (radius included).
    patch_origin: (usize, i64, i64),
    last: LastShift,
    /// The cells of a cluster it registers on, when not all of them
    /// (`MotionStage::update_registering`).
    pub(crate) own_cells: Vec<Cell>,
}

/// `SPREAD[b]` has byte `j` equal to bit `j` of `b`.
const SPREAD: [u64; 256] = {
    let mut table = [0u64; 256];
    let mut b = 0;
    while b < 256 {
        let mut j = 0;
        while j < 8 {
            if b & (1 << j) != 0 {
                table[b] |= 1 << (8 * j);
            }
            j += 1;
        }
        b += 1;
    }
    table
};

impl Registrar {
    /// The shift of the cluster `cells` (this frame's, at `now_s`) against the history, or
    /// `None` when no past frame explains enough of it.
    pub(crate) fn register(
        &mut self,
        cells: &[Cell],
        window: &Window,
        history: &OccupancyHistory,
        now: Now<'_>,
        params: &MotionParams,
    ) -> Option<Registration> {
        let now_s = now.time_s;
        let first = cells.first()?;
        let radius = params.search_radius_cells as i64;
        let (mut c0, mut c1, mut r0, mut r1) = (first.col, first.col, first.row, first.row);
        for c in cells {
            (c0, c1) = (c0.min(c.col), c1.max(c.col));
            (r0, r1) = (r0.min(c.row), r1.max(c.row));
        }
        let pw = self.copy_history_around(window, history, &now, (c0, c1, r0, r1), radius);
        let counted = self.count_matches(cells, (c0, r0), radius, pw);
        let side = 2 * radius + 1;
        let zero = (radius * side + radius) as usize;
        // The shortest shift the pose's error does not explain: the apparent shift of a static
        // cluster between two scans has, per axis, twice the variance of one pose's error at
        // the cluster's range.
        let range_cells = ((c0 + c1) as f64 / 2.0 + 0.5 - now.sensor_cell.0)
            .hypot((r0 + r1) as f64 / 2.0 + 0.5 - now.sensor_cell.1);
        let pose_shift_sigma =
            std::f64::consts::SQRT_2 * now.pose_sigma_cells.hypot(range_cells * now.pose_sigma_rad);
        let pose_gate_sq = (params.pose_gate_sigmas * pose_shift_sigma).powi(2);
        let needed = (params.match_fraction * f64::from(counted)).max(1.0);
        let margin = shift_margin(counted, params);
        let cell_size_m = window.cell_size_m();
        let (mut sum_dt_x, mut sum_dt_y, mut sum_tt, mut frames) = (0.0, 0.0, 0.0, 0);
        let mut sum_t = 0.0;
        // Whether every frame kept so far read zero only for want of margin: a non-zero shift
        // explained more of the cluster, not clearly more (see below).
        let mut unresolved = true;
        // Whether zero refuted the moving track's prediction against a newer frame.
        let mut refuted = false;
        // The slot and time span of each frame in the fit, newest first.
        let mut fitted = [(0usize, 0.0f64); SLOTS];
        // Per frame in the fit read at zero, the non-zero shift that explained more of the
        // cluster, if any ((0, 0) where none did), and whether its move was seen on the
        // margin's cells (a lean; see `weak_line`).
        let mut leaned = [((0i64, 0i64), false); SLOTS];
        // Per frame in the fit, whether zero shift explained every cell of the cluster (a
        // stopped object matches itself exactly; a move hidden by what is visible does not).
        let mut exact = [false; SLOTS];
        for frames_back in 1..=params.history_frames {
            let Some((bit, then_s)) = history.frame_back(frames_back) else {
                break;
            };
            let span_s = now_s - then_s;
            if span_s <= 0.0 {
                continue;
            }
            let slot = bit.trailing_zeros() as usize;
            let reach = ((params.max_speed_mps * span_s / cell_size_m).ceil() as i64).min(radius);
            let mut best = (self.counts[zero][slot], 0i64, 0i64);
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    let n = self.counts[((dy + radius) * side + dx + radius) as usize][slot];
                    let closer = dx * dx + dy * dy < best.1 * best.1 + best.2 * best.2;
                    if n > best.0 || (n == best.0 && closer) {
                        best = (n, dx, dy);
                    }
                }
            }
            let n_zero = self.counts[zero][slot];
            // A non-zero shift must explain the cluster clearly better than none, and its
            // move must be seen on at least `margin` cells: where neither the cells left nor
            // the cells entered were seen, the match may be a change of what is visible (a
            // parked car whose visible part slides as the ego passes), not a move.
            let seen =
                self.seen_counts[((best.2 + radius) * side + best.1 + radius) as usize][slot];
            // And it must be longer than the pose's error explains at the cluster's range.
            let explained_by_pose = ((best.1 * best.1 + best.2 * best.2) as f64) <= pose_gate_sq;
            let clear = best.0 >= n_zero + margin && seen >= margin && !explained_by_pose;
            // Where no shift beats zero clearly, a moving track's prediction breaks the tie
            // (`motion.prior_after_moving_frames`), until zero refutes it.
            let prior = match now.predicted_cells_per_s {
                Some(v) if !clear && !refuted => self.predicted_shift(
                    v,
                    (slot, span_s),
                    (reach, radius),
                    pose_gate_sq,
                    margin,
                    params.stop_evidence_cells,
                ),
                _ => Prior::None,
            };
            refuted |= prior == Prior::Refuted;
            let (matched, dx, dy) = match prior {
                _ if clear => best,
                Prior::Taken(n, dx, dy) => (n, dx, dy),
                Prior::None | Prior::Refuted => (n_zero, 0, 0),
            };
            let predicted = matches!(prior, Prior::Taken(..));
            if f64::from(matched) < needed {
                continue;
            }
            // A shift off the line of the newer frames by more than CHANGE_CELLS: the object
            // changed its motion (a car that just stopped shows no shift against the last
            // frames and a long one against older ones); keep the newer frames only. Unless
            // the newer frames could not tell: a face sliding along itself (a car passing
            // side-on) matches itself at zero shift but for its ends, and a shift explains
            // only those few cells more until it has grown over the older frames. They could
            // not tell when (a) every one read zero only for want of margin, or some of the
            // cluster's cells were seen free in one of them (it entered space seen empty: a
            // stopped object does not), and (b) none is explained better by zero than by the
            // move this frame's shift predicts for it: a car that stopped matches its newer
            // frames exactly at zero, its predicted move leaves its ends unmatched.
            if frames > 0 {
                let off_x = dx as f64 - sum_dt_x / sum_tt * span_s;
                let off_y = dy as f64 - sum_dt_y / sum_tt * span_s;
                // A predicted shift off the line of newer frames that all read zero: those
                // could not tell (their predicted shifts were zero or tied with it); newer
                // frames that measured a move are kept.
                let newer_zero = sum_dt_x == 0.0 && sum_dt_y == 0.0;
                if predicted && off_x.abs().max(off_y.abs()) > CHANGE_CELLS {
                    if !newer_zero {
                        break;
                    }
                    (sum_dt_x, sum_dt_y, sum_tt, sum_t, frames) = (0.0, 0.0, 0.0, 0.0, 0);
                } else if off_x.abs().max(off_y.abs()) > CHANGE_CELLS {
                    let newer = &fitted[..frames];
                    let newer_bits = newer.iter().fold(0u8, |bits, &(slot, _)| bits | 1 << slot);
                    let undecided =
                        unresolved || self.heres.iter().any(|&h| self.free[h] & newer_bits != 0);
                    // A moving track's prediction refuted by a newer frame is the evidence
                    // of a stop too.
                    let stop_seen = refuted
                        || self.zero_fits_better(
                            newer,
                            (dx, dy),
                            span_s,
                            radius,
                            params.stop_evidence_cells,
                        );
                    let restart = clear && undecided && !stop_seen;
                    if !restart {
                        // Newer frames that all read zero against an older one that shows a
                        // clear move: a stop, or a move the newer frames hid (a side sliding
                        // along itself, its visible part bounded by an occluder). A stopped
                        // object matches itself exactly at zero; where zero left a cell of
                        // some newer frame unexplained, `contradicted_unmeasured` leaves the
                        // cluster unmeasured this frame rather than read static on the newer
                        // frames, if the move is longer than the pose's error explains.
                        let beyond_pose = ((dx * dx + dy * dy) as f64).sqrt()
                            > params.displaced_pose_sigmas * pose_shift_sigma;
                        let rigid = exact[..frames].iter().all(|&e| e);
                        if params.contradicted_unmeasured && newer_zero && beyond_pose && !rigid {
                            return None;
                        }
                        break;
                    }
                    (sum_dt_x, sum_dt_y, sum_tt, sum_t, frames) = (0.0, 0.0, 0.0, 0.0, 0);
                }
            }
            unresolved &= !clear && !predicted && best.0 > n_zero;
            // Read at zero, though a non-zero shift explains more of the cluster (not by the
            // margin) and is longer than the pose's error explains; a lean if its move is seen
            // on the margin's cells, as a clear shift's must be.
            let reading = !clear
                && !predicted
                && (best.1, best.2) != (0, 0)
                && best.0 > n_zero
                && !explained_by_pose;
            leaned[frames] = if reading {
                ((best.1, best.2), seen >= margin)
            } else {
                ((0, 0), false)
            };
            fitted[frames] = (slot, span_s);
            exact[frames] = n_zero >= counted;
            sum_dt_x += dx as f64 * span_s;
            sum_dt_y += dy as f64 * span_s;
            sum_tt += span_s * span_s;
            sum_t += span_s;
            frames += 1;
            self.last = LastShift { dx, dy, bit };
            // Two cells or more: precise enough, and further back a fast object leaves the
            // search radius.
            if dx * dx + dy * dy >= 4 {
                break;
            }
        }
        let mut velocity_cells_per_s = (sum_dt_x / sum_tt, sum_dt_y / sum_tt);
        if params.weak_shift_frames > 0 && frames > 0 && velocity_cells_per_s == (0.0, 0.0) {
            let spans = fitted[..frames].iter().map(|&(_, span_s)| span_s);
            // The line must reach further than the pose's error moves a static cluster
            // (`displaced_pose_sigmas` of its apparent shift, as for a track's displacement):
            // a pose off the same way for a while makes a static object lean on a line too.
            let reach_cells = (params.displaced_pose_sigmas * pose_shift_sigma).max(1.0);
            let leans = &leaned[..frames];
            if let Some(line) = weak_line(leans, spans, params.weak_shift_frames, reach_cells) {
                velocity_cells_per_s = line;
            }
        }
        (frames > 0).then_some(Registration {
            velocity_cells_per_s,
            sum_span_sq: sum_tt,
            sum_span: sum_t,
            frames,
        })
    }

    /// Copies the history around the cluster, `radius` cells beyond its bounding box
    /// `(c0, c1, r0, r1)` (cells), into the patch planes: the frames' occupied bits, their free
    /// bits, and whether each cell is seen empty now (`left`). Returns the patch's width.
    fn copy_history_around(
        &mut self,
        window: &Window,
        history: &OccupancyHistory,
        now: &Now<'_>,
        (c0, c1, r0, r1): (i64, i64, i64, i64),
        radius: i64,
    ) -> usize {
        let pw = (c1 - c0 + 1 + 2 * radius) as usize;
        let ph = (r1 - r0 + 1 + 2 * radius) as usize;
        for plane in [&mut self.patch, &mut self.free, &mut self.left] {
            plane.clear();
            plane.resize(pw * ph, 0);
        }
        self.patch_origin = (pw, c0 - radius, r0 - radius);
        self.last = LastShift::default();
        for (pr, row) in (r0 - radius..=r1 + radius).enumerate() {
            for (pc, col) in (c0 - radius..=c1 + radius).enumerate() {
                let Some(idx) = window.storage_index(col, row) else {
                    continue;
                };
                let p = pr * pw + pc;
                self.free[p] = history.free_bits(idx);
                match now.clusters.label_of(idx) {
                    // Another cluster occupies it now: that object is still there, so this
                    // one did not come from it.
                    Some(l) if l != now.cluster => {}
                    Some(_) => self.patch[p] = history.bits(idx),
                    None => {
                        self.patch[p] = history.bits(idx);
                        if now.m_free.get(idx).is_some_and(|&f| f > 0.0)
                            || now.clear_now.get(idx) == Some(&true)
                        {
                            self.left[p] = 0xff;
                        }
                    }
                }
            }
        }
        pw
    }

    /// n_k(d), and the same counted only where the move is seen, for every shift d within
    /// `radius` and past frame k at once, over the cluster's cells (at most
    /// `MAX_COUNTED_CELLS`, sampled evenly); the patch starts at `(c0, r0)` less `radius` and
    /// is `pw` wide. Returns how many cells were counted.
    fn count_matches(
        &mut self,
        cells: &[Cell],
        (c0, r0): (i64, i64),
        radius: i64,
        pw: usize,
    ) -> u32 {
        let stride = cells.len().div_ceil(MAX_COUNTED_CELLS);
        let counted = cells.len().div_ceil(stride) as u32;
        let side = 2 * radius + 1;
        for counts in [&mut self.counts, &mut self.seen_counts] {
            counts.clear();
            counts.resize((side * side) as usize, [0; SLOTS]);
        }
        self.heres.clear();
        self.heres.extend(
            cells
                .iter()
                .step_by(stride)
                .map(|c| (c.row - r0 + radius) as usize * pw + (c.col - c0 + radius) as usize),
        );
        for (s, (count, seen_count)) in self
            .counts
            .iter_mut()
            .zip(self.seen_counts.iter_mut())
            .enumerate()
        {
            let (dx, dy) = (s as i64 % side - radius, s as i64 / side - radius);
            // Patch index of the cell a shift d came from: here − (dy·pw + dx), always inside
            // the patch (it reaches `radius` beyond the cluster).
            let offset = (dy * pw as i64 + dx) as isize;
            let (mut lanes, mut seen_lanes) = (0u64, 0u64);
            for chunk in self.heres.chunks(255) {
                for &here in chunk {
                    let from = here.wrapping_sub_signed(offset);
                    let came_from = self.patch[from];
                    lanes += SPREAD[usize::from(came_from)];
                    // The move is seen where the cell it came from is seen empty now, or where
                    // this cell was seen free then.
                    let seen = self.free[here] | self.left[from];
                    seen_lanes += SPREAD[usize::from(came_from & seen)];
                }
                // A byte lane holds up to 255.
                flush(&mut lanes, count);
                flush(&mut seen_lanes, seen_count);
            }
        }
        counted
    }
}

impl Registration {
    /// Variance per axis of the velocity, (cells/s)², for shifts of standard deviation
    /// `shift_sigma_cells` against one past frame.
    ///
    /// A shift d_k = x_now − x_k is quantised at both ends: e_now − e_k, each end of variance
    /// σ²/2. The error e_now of this frame is the same in every d_k, so the frames are not
    /// independent: the slope Σ d_k τ_k / Σ τ_k² has variance
    /// σ²/2 · ((Σ τ_k)² / (Σ τ_k²)² + 1 / Σ τ_k²), which is σ² / τ² for one frame but
    /// shrinks far less with more frames than σ² / Σ τ_k² would say. A slow object that shows
    /// no whole-cell shift over a few tenths of a second is not known to stand still.
    pub(crate) fn variance_cells(&self, shift_sigma_cells: f64) -> f64 {
        let common = self.sum_span * self.sum_span / (self.sum_span_sq * self.sum_span_sq);
        0.5 * shift_sigma_cells * shift_sigma_cells * (common + 1.0 / self.sum_span_sq)
    }
}

impl Registrar {
    /// Against the past frame in `slot`, `span_s` back (after the counts of the last
    /// `register`), what the velocity `velocity_cells_per_s` a moving track predicts makes of
    /// the cluster: the shift within a cell (per axis) of the predicted one, not zero, that
    /// explains most of the cluster (ties: the nearest the prediction) is taken if it
    /// explains at least as much as zero, its move is seen on `margin` cells (as a clear
    /// shift's), it is within the frame's `reach` and longer than the pose's error explains
    /// (`pose_gate_sq`, cells²). Where the predicted shift is at least `stop_evidence_cells`
    /// long and zero explains more, the object stopped: refuted. A crawling car sliding along
    /// its own length ties with zero on the cells its ends leave and enter; a stopped one
    /// matches itself at zero on all of them.
    fn predicted_shift(
        &self,
        velocity_cells_per_s: (f64, f64),
        (slot, span_s): (usize, f64),
        (reach, radius): (i64, i64),
        pose_gate_sq: f64,
        margin: u32,
        stop_evidence_cells: f64,
    ) -> Prior {
        let (ex, ey) = (
            velocity_cells_per_s.0 * span_s,
            velocity_cells_per_s.1 * span_s,
        );
        let (px, py) = (ex.round() as i64, ey.round() as i64);
        if (px, py) == (0, 0) {
            return Prior::None;
        }
        let side = 2 * radius + 1;
        let at = |dx: i64, dy: i64| ((dy + radius) * side + dx + radius) as usize;
        let n_zero = self.counts[at(0, 0)][slot];
        let mut best: Option<(u32, i64, i64)> = None;
        for dy in (py - 1).max(-reach)..=(py + 1).min(reach) {
            for dx in (px - 1).max(-reach)..=(px + 1).min(reach) {
                if (dx, dy) == (0, 0) {
                    continue;
                }
                let n = self.counts[at(dx, dy)][slot];
                let nearer = |(_, bx, by): (u32, i64, i64)| {
                    (dx - px).pow(2) + (dy - py).pow(2) < (bx - px).pow(2) + (by - py).pow(2)
                };
                if best.is_none_or(|b| n > b.0 || (n == b.0 && nearer(b))) {
                    best = Some((n, dx, dy));
                }
            }
        }
        let Some((n, dx, dy)) = best else {
            return Prior::None;
        };
        let seen = self.seen_counts[at(dx, dy)][slot];
        let explained_by_pose = ((dx * dx + dy * dy) as f64) <= pose_gate_sq;
        if n >= n_zero && seen >= margin && !explained_by_pose {
            Prior::Taken(n, dx, dy)
        } else if n_zero > n && ex.hypot(ey) >= stop_evidence_cells {
            Prior::Refuted
        } else {
            Prior::None
        }
    }

    /// Whether one of the `newer` frames (slot, time span) is explained better by zero shift
    /// than by the shift that `shift`, measured over `span_s`, predicts for it (after the
    /// counts of the last `register`), among the frames whose predicted shift is at least
    /// `stop_evidence_cells` long (`motion.stop_evidence_cells`).
    fn zero_fits_better(
        &self,
        newer: &[(usize, f64)],
        shift: (i64, i64),
        span_s: f64,
        radius: i64,
        stop_evidence_cells: f64,
    ) -> bool {
        let side = 2 * radius + 1;
        let zero = (radius * side + radius) as usize;
        newer.iter().any(|&(slot, newer_span_s)| {
            let scale = newer_span_s / span_s;
            // A predicted shift shorter than this is no evidence either way (the object's
            // ends quantised to whole cells may read zero or one cell).
            if (shift.0 as f64 * scale).hypot(shift.1 as f64 * scale) < stop_evidence_cells {
                return false;
            }
            let px = (shift.0 as f64 * scale).round() as i64;
            let py = (shift.1 as f64 * scale).round() as i64;
            // Always inside the radius: a newer frame's span is shorter.
            let predicted = self
                .counts
                .get(((py + radius) * side + px + radius) as usize)
                .map_or(0, |c| c[slot]);
            self.counts[zero][slot] > predicted
        })
    }

    /// After the last registration, whether one of its cells may have moved: false for a cell
    /// that was occupied in the oldest frame used and is not explained by the shift found
    /// there (a static object merged into a moving one's cluster, such as a car waiting
    /// beside crossing traffic); true wherever no shift was found (nothing to tell apart).
    pub(crate) fn moved(&self, cell: &Cell) -> bool {
        let LastShift { dx, dy, bit } = self.last;
        if (dx, dy) == (0, 0) {
            return true;
        }
        let (pw, col0, row0) = self.patch_origin;
        let at = |col: i64, row: i64| {
            let (pc, pr) = (col - col0, row - row0);
            usize::try_from(pc)
                .ok()
                .zip(usize::try_from(pr).ok())
                .and_then(|(pc, pr)| (pc < pw).then(|| self.patch.get(pr * pw + pc)).flatten())
                .is_some_and(|&b| b & bit != 0)
        };
        at(cell.col - dx, cell.row - dy) || !at(cell.col, cell.row)
    }
}

/// How many cells more than zero a non-zero shift must explain, of a cluster of `counted`
/// cells: `shift_margin_fraction` of them, at most `shift_margin_max_cells` (when set), at
/// least one.
fn shift_margin(counted: u32, params: &MotionParams) -> u32 {
    let mut margin = (params.shift_margin_fraction * f64::from(counted)).ceil();
    if params.shift_margin_max_cells > 0.0 {
        margin = margin.min(params.shift_margin_max_cells.ceil());
    }
    margin.max(1.0) as u32
}

/// The velocity, cells/s, of a slow object read at zero against every frame in its fit
/// (`motion.weak_shift_frames`), or `None`. `leaned` holds, per frame of the fit, its reading:
/// the non-zero shift d_k that explained more of the cluster than zero, not clearly more
/// ((0, 0) where none did), and whether that shift's move was seen on the margin's cells (a
/// lean); `spans_s` their time spans τ_k, seconds.
///
/// A side sliding along its own length beats zero only by the cells at its ends, under the
/// margin, however often it is measured; a static object's shifts that beat zero (a cell of
/// pose error, a face sliding into view) come and go from frame to frame, or are not seen.
/// So: at least `min_frames` frames lean, and every frame of the fit lies within a cell, per
/// axis, of the least-squares line through the origin of the readings against the spans
/// (v = Σ d_k·τ_k / Σ τ_k²), which reaches at least `reach_cells` (one cell, or more under
/// pose error) over the longest span: the line is the velocity.
fn weak_line(
    leaned: &[((i64, i64), bool)],
    spans_s: impl Iterator<Item = f64> + Clone,
    min_frames: usize,
    reach_cells: f64,
) -> Option<(f64, f64)> {
    let leaning = leaned.iter().filter(|&&(_, lean)| lean).count();
    if leaning < min_frames {
        return None;
    }
    let (mut sx, mut sy, mut stt, mut longest) = (0.0, 0.0, 0.0, 0.0f64);
    for (&((dx, dy), _), span_s) in leaned.iter().zip(spans_s.clone()) {
        sx += dx as f64 * span_s;
        sy += dy as f64 * span_s;
        stt += span_s * span_s;
        longest = longest.max(span_s);
    }
    if stt <= 0.0 {
        return None;
    }
    let (vx, vy) = (sx / stt, sy / stt);
    let reaches = (vx * longest).hypot(vy * longest) >= reach_cells;
    let on_line = leaned.iter().zip(spans_s).all(|(&((dx, dy), _), span_s)| {
        (dx as f64 - vx * span_s).abs() <= 1.0 && (dy as f64 - vy * span_s).abs() <= 1.0
    });
    (reaches && on_line).then_some((vx, vy))
}

/// Adds the eight byte lanes of `lanes` to `count` and clears them.
fn flush(lanes: &mut u64, count: &mut [u32; SLOTS]) {
    for (j, c) in count.iter_mut().enumerate() {
        *c += ((*lanes >> (8 * j)) & 0xff) as u32;
    }
    *lanes = 0;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cells(window: &Window, list: &[(i64, i64)]) -> Vec<Cell> {
        list.iter()
            .map(|&(col, row)| Cell {
                idx: window.storage_index(col, row).unwrap_or(0) as u32,
                col,
                row,
            })
            .collect()
    }

    fn indices(window: &Window, list: &[(i64, i64)]) -> Vec<u32> {
        cells(window, list).iter().map(|c| c.idx).collect()
    }

    /// Every cell of the 40 × 40 test window seen free now (except the clusters').
    static ALL_FREE: [f32; 1600] = [0.7; 1600];

    /// A frame at `time_s` with no other cluster in it, everything else seen free.
    fn alone(time_s: f64, none: &Clusters) -> Now<'_> {
        Now {
            time_s,
            clusters: none,
            cluster: 0,
            m_free: &ALL_FREE,
            clear_now: &[],
            sensor_cell: (0.0, 0.0),
            pose_sigma_cells: 0.0,
            pose_sigma_rad: 0.0,
            predicted_cells_per_s: None,
        }
    }

    /// Frames 0.1 s apart of a side on row 10: each frame's visible columns occupied, the road
    /// ahead of them (to the window's edge) seen free.
    fn side_history(window: &Window, sides: &[std::ops::Range<i64>]) -> OccupancyHistory {
        let row = |cols: std::ops::Range<i64>| cols.map(|c| (c, 10)).collect::<Vec<_>>();
        let mut history = OccupancyHistory::new(window.len());
        for (k, side) in sides.iter().enumerate() {
            history.push(
                &indices(window, &row(side.clone())),
                &indices(window, &row(side.end..40)),
                0.1 * k as f64,
            );
        }
        history
    }

    /// The registration of the side now on row 10's columns `cols`, 0.8 s after the first
    /// frame of `history` (a `side_history` of eight frames), alone in its frame.
    fn register_side(
        window: &Window,
        history: &OccupancyHistory,
        cols: std::ops::Range<i64>,
    ) -> Registration {
        let now = cells(window, &cols.map(|c| (c, 10)).collect::<Vec<_>>());
        let none = Clusters::new(window.len());
        Registrar::default()
            .register(
                &now,
                window,
                history,
                alone(0.8, &none),
                &MotionParams::default(),
            )
            .unwrap_or_else(|| panic!("not registered"))
    }

    fn window() -> Window {
        Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"))
    }

    #[test]
    fn the_margin_is_a_fraction_of_the_cluster_capped_for_a_long_one() {
        let with = |fraction: f64, cap: f64| MotionParams {
            shift_margin_fraction: fraction,
            shift_margin_max_cells: cap,
            ..MotionParams::default()
        };
        // 0.15 × 40 = 6 cells; a bus side-on gains only its ends' cells, so a cap of 2 asks 2.
        assert_eq!(shift_margin(40, &with(0.15, 0.0)), 6);
        assert_eq!(shift_margin(40, &with(0.15, 2.0)), 2);
        // A car of 10 cells: ⌈1.5⌉ = 2, under the cap; of 4 cells: ⌈0.6⌉ = 1.
        assert_eq!(shift_margin(10, &with(0.15, 2.0)), 2);
        assert_eq!(shift_margin(4, &with(0.15, 2.0)), 1);
        // At least one cell, even with no fraction; a fractional cap rounds up.
        assert_eq!(shift_margin(40, &with(0.0, 2.0)), 1);
        assert_eq!(shift_margin(40, &with(0.15, 2.5)), 3);
    }

    #[test]
    fn spread_puts_each_bit_in_its_byte() {
        assert_eq!(SPREAD[0b1000_0101], 0x0100_0000_0001_0001);
    }

    #[test]
    fn a_face_moving_two_cells_a_frame_is_found_and_a_wall_is_static() {
        let (window, params, none) = (window(), MotionParams::default(), Clusters::new(1600));
        let mut history = OccupancyHistory::new(window.len());
        // A 4-cell face at column 10 moving east by 2 cells a frame, and a wall at row 30.
        let face = |col: i64| (0..4).map(move |r| (col, 10 + r));
        let wall: Vec<(i64, i64)> = (0..20).map(|c| (c, 30)).collect();
        for k in 0..3 {
            let mut occupied: Vec<(i64, i64)> = face(10 + 2 * k).collect();
            occupied.extend(&wall);
            history.push(&indices(&window, &occupied), &[], 0.1 * k as f64);
        }
        let mut registrar = Registrar::default();
        let now: Vec<(i64, i64)> = face(16).collect();
        let found = registrar
            .register(
                &cells(&window, &now),
                &window,
                &history,
                alone(0.3, &none),
                &params,
            )
            .unwrap_or_else(|| panic!("not registered"));
        // Two cells in 0.1 s, from the previous frame alone.
        assert_eq!(found.frames, 1);
        assert!((found.velocity_cells_per_s.0 - 20.0).abs() < 1e-9);
        assert!(found.velocity_cells_per_s.1.abs() < 1e-12);
        assert!((found.sum_span_sq - 0.01).abs() < 1e-12);
        assert!(registrar.moved(&cells(&window, &[(16, 10)])[0]));
        let still = registrar
            .register(
                &cells(&window, &wall),
                &window,
                &history,
                alone(0.3, &none),
                &params,
            )
            .unwrap_or_else(|| panic!("not registered"));
        // Static: zero shift against each of the three frames kept.
        assert_eq!(still.velocity_cells_per_s, (0.0, 0.0));
        assert_eq!(still.frames, 3);
        assert!((still.sum_span_sq - (0.01 + 0.04 + 0.09)).abs() < 1e-9);
        assert!((still.sum_span - 0.6).abs() < 1e-9);
    }

    #[test]
    fn the_velocity_variance_counts_the_shared_error_of_the_current_frame() {
        let one = Registration {
            velocity_cells_per_s: (0.0, 0.0),
            sum_span_sq: 0.01,
            sum_span: 0.1,
            frames: 1,
        };
        // One frame 0.1 s back, σ = 0.5 cell: 0.125 · (100 + 100) = 25 = 0.5² / 0.1².
        assert!((one.variance_cells(0.5) - 25.0).abs() < 1e-9);
        // Three frames 0.1, 0.2, 0.3 s back: 0.125 · (0.36 / 0.0196 + 1 / 0.14) = 3.188 76,
        // not 0.25 / 0.14 = 1.786 (independent frames).
        let three = Registration {
            sum_span_sq: 0.14,
            sum_span: 0.6,
            frames: 3,
            ..one
        };
        assert!((three.variance_cells(0.5) - 3.188_775_510_204_082).abs() < 1e-9);
    }

    #[test]
    fn a_shift_the_pose_error_explains_is_not_motion_and_a_longer_one_is() {
        // The gate is an option (off by default): on at 3σ here.
        let params = MotionParams {
            pose_gate_sigmas: 3.0,
            ..MotionParams::default()
        };
        let (window, none) = (window(), Clusters::new(1600));
        // A pole of two cells at column 7 a frame ago, at column 8 now: the pose moved it.
        let mut history = OccupancyHistory::new(window.len());
        history.push(&indices(&window, &[(7, 5), (7, 6)]), &[], 0.0);
        let pole = cells(&window, &[(8, 5), (8, 6)]);
        // Exact pose: one cell in 0.1 s, 10 cells/s.
        let exact =
            Registrar::default().register(&pole, &window, &history, alone(0.1, &none), &params);
        assert!(exact.is_some_and(|r| (r.velocity_cells_per_s.0 - 10.0).abs() < 1e-9));
        // The pose off by σ = 0.4 cell per axis: the apparent shift of a static cluster has
        // σ = √2 · 0.4 = 0.566 cell per axis, and the gate of 3σ = 1.697 cells takes in the
        // one-cell shift (and a diagonal one, √2 = 1.414). Zero shift explains none of the
        // pole: no registration.
        let noisy = Now {
            pose_sigma_cells: 0.4,
            ..alone(0.1, &none)
        };
        assert_eq!(
            Registrar::default().register(&pole, &window, &history, noisy, &params),
            None
        );
        // The same σ from the heading alone, 0.01 rad at 40 cells from the sensor (the
        // pole's centre (8.5, 6) lies 40 cells east of (−31.5, 6)): the same gate.
        let turned = Now {
            sensor_cell: (-31.5, 6.0),
            pose_sigma_rad: 0.01,
            ..alone(0.1, &none)
        };
        assert_eq!(
            Registrar::default().register(&pole, &window, &history, turned, &params),
            None
        );
        // Nearer the sensor the heading explains less: at 10 cells, σ = √2 · 0.1 = 0.141 cell,
        // gate 0.424, and the one-cell shift is motion again.
        let near = Now {
            sensor_cell: (-1.5, 6.0),
            ..turned
        };
        let found = Registrar::default().register(&pole, &window, &history, near, &params);
        assert!(found.is_some_and(|r| (r.velocity_cells_per_s.0 - 10.0).abs() < 1e-9));
        // Two cells in 0.1 s is beyond the 1.697-cell gate: motion.
        let car = cells(&window, &[(9, 5), (9, 6)]);
        let moved = Registrar::default().register(&car, &window, &history, noisy, &params);
        assert!(moved.is_some_and(|r| (r.velocity_cells_per_s.0 - 20.0).abs() < 1e-9));
        // Gate off, the default: the one-cell shift is motion whatever the σ.
        let off = MotionParams::default();
        assert_eq!(off.pose_gate_sigmas, 0.0);
        let ungated = Registrar::default().register(&pole, &window, &history, noisy, &off);
        assert!(ungated.is_some_and(|r| (r.velocity_cells_per_s.0 - 10.0).abs() < 1e-9));
    }

    #[test]
    fn a_slow_object_is_measured_against_older_frames_and_a_new_one_not_at_all() {
        let (window, params, none) = (window(), MotionParams::default(), Clusters::new(1600));
        let mut history = OccupancyHistory::new(window.len());
        // Two cells moving one cell every three frames (a walker at 1.7 m/s).
        for k in 0..7 {
            let col = 5 + k / 3;
            history.push(
                &indices(&window, &[(col, 5), (col, 6)]),
                &[],
                0.1 * k as f64,
            );
        }
        let mut registrar = Registrar::default();
        let now = cells(&window, &[(7, 5), (7, 6)]);
        let found = registrar
            .register(&now, &window, &history, alone(0.7, &none), &params)
            .unwrap_or_else(|| panic!("not registered"));
        // One frame back: no shift (0.1 s); two to four back: one cell (0.2, 0.3, 0.4 s); five
        // back, at column 5: two cells (0.5 s), where the search stops. Slope
        // (0 + 0.2 + 0.3 + 0.4 + 2·0.5) / (0.01 + 0.04 + 0.09 + 0.16 + 0.25) = 1.9 / 0.55.
        assert_eq!(found.frames, 5);
        assert!((found.velocity_cells_per_s.0 - 1.9 / 0.55).abs() < 1e-9);
        let elsewhere = cells(&window, &[(30, 30), (30, 31)]);
        let none_found =
            registrar.register(&elsewhere, &window, &history, alone(0.7, &none), &params);
        assert_eq!(none_found, None);
    }

    #[test]
    fn an_object_that_just_stopped_is_measured_on_the_frames_since() {
        let (window, params, none) = (window(), MotionParams::default(), Clusters::new(1600));
        let mut history = OccupancyHistory::new(window.len());
        // Two cells a frame east until column 14, then stopped there for two frames.
        for (k, col) in [8, 10, 12, 14, 14].into_iter().enumerate() {
            history.push(
                &indices(&window, &[(col, 5), (col, 6)]),
                &[],
                0.1 * k as f64,
            );
        }
        let now = cells(&window, &[(14, 5), (14, 6)]);
        let found = Registrar::default()
            .register(&now, &window, &history, alone(0.5, &none), &params)
            .unwrap_or_else(|| panic!("not registered"));
        // Zero shift against frames 1 and 2 back; 3 back shows two cells off that line.
        assert_eq!(found.velocity_cells_per_s, (0.0, 0.0));
        assert_eq!(found.frames, 2);
    }

    #[test]
    fn a_face_sliding_along_itself_is_measured_on_the_older_frames_that_resolve_it() {
        let window = window();
        // The side of a car passing side-on: ten cells on row 10 moving east one cell a frame,
        // the cells ahead of it seen free. Against the last two frames zero shift explains
        // 9 and 8 of 10, the true shift 10: more, not by the margin of ⌈0.25 · 10⌉ = 3.
        // Three frames back it is 7 against 10, and the cells entered were seen free then.
        let sides: Vec<_> = (10..18).map(|first| first..first + 10).collect();
        let found = register_side(&window, &side_history(&window, &sides), 18..28);
        // Three cells in 0.3 s: the two frames that could not tell are dropped.
        assert_eq!(found.frames, 1);
        assert!(
            (found.velocity_cells_per_s.0 - 10.0).abs() < 1e-9,
            "{found:?}"
        );
        assert!(found.velocity_cells_per_s.1.abs() < 1e-12);
    }

    #[test]
    fn a_static_cell_merged_into_a_moving_cluster_is_told_apart() {
        let (window, params, none) = (window(), MotionParams::default(), Clusters::new(1600));
        let mut history = OccupancyHistory::new(window.len());
        // Three cells moving two cells a frame east, and a static cell at (20, 20).
        let object = |col: i64| (10..13).map(move |r| (col, r));
        for (k, col) in [10, 12].into_iter().enumerate() {
            let mut occupied: Vec<(i64, i64)> = object(col).collect();
            occupied.push((20, 20));
            history.push(&indices(&window, &occupied), &[], 0.1 * k as f64);
        }
        let mut now: Vec<(i64, i64)> = object(14).collect();
        now.push((20, 20));
        let now = cells(&window, &now);
        let mut registrar = Registrar::default();
        // Shift (2, 0) explains 3 of 4 cells, zero 1: moving.
        let found = registrar.register(&now, &window, &history, alone(0.2, &none), &params);
        assert!(found.is_some_and(|r| (r.velocity_cells_per_s.0 - 20.0).abs() < 1e-9));
        assert!(registrar.moved(&now[0]));
        assert!(!registrar.moved(&now[3]), "the static cell");
    }

    #[test]
    fn an_object_first_seen_beside_a_static_one_is_not_its_past() {
        let window = window();
        let params = MotionParams::default();
        let mut history = OccupancyHistory::new(window.len());
        // B at (5, 5) in every frame; A appears at (7, 5): shifted 2 cells, B's cell fits.
        for k in 0..2 {
            history.push(&indices(&window, &[(5, 5)]), &[], 0.1 * k as f64);
        }
        let a = cells(&window, &[(7, 5)]);
        let none = Clusters::new(window.len());
        let mut registrar = Registrar::default();
        let alone_found = registrar.register(&a, &window, &history, alone(0.2, &none), &params);
        assert!(alone_found.is_some_and(|r| r.velocity_cells_per_s.0 > 0.0));
        // With B seen now as another cluster, its cell is not where A came from.
        let mut clusters = Clusters::new(window.len());
        clusters.label(&window, &indices(&window, &[(7, 5), (5, 5)]));
        let own = clusters.label_of(a[0].idx as usize).unwrap_or(u32::MAX);
        let now = Now {
            time_s: 0.2,
            clusters: &clusters,
            cluster: own,
            m_free: &ALL_FREE,
            clear_now: &[],
            sensor_cell: (0.0, 0.0),
            pose_sigma_cells: 0.0,
            pose_sigma_rad: 0.0,
            predicted_cells_per_s: None,
        };
        assert_eq!(
            registrar.register(&a, &window, &history, now, &params),
            None
        );
    }

    #[test]
    fn a_static_side_whose_visible_part_slides_is_static() {
        let (window, params) = (window(), MotionParams::default());
        let mut history = OccupancyHistory::new(window.len());
        // A parked car's side on row 5: columns 0-8 visible a frame ago, 4-12 now, 0-3 now
        // hidden (not seen free). Shift 4 matches all nine cells, zero only five; but the
        // cells it would have come from are hidden now, and the new cells were not seen
        // free then: nothing shows a move.
        let side = |cols: std::ops::Range<i64>| cols.map(|c| (c, 5)).collect::<Vec<_>>();
        history.push(&indices(&window, &side(0..9)), &[], 0.0);
        let now = cells(&window, &side(4..13));
        let mut clusters = Clusters::new(window.len());
        clusters.label(&window, &indices(&window, &side(4..13)));
        let no_free = vec![0.0; window.len()];
        let now_frame = Now {
            time_s: 0.1,
            clusters: &clusters,
            cluster: 0,
            m_free: &no_free,
            clear_now: &[],
            sensor_cell: (0.0, 0.0),
            pose_sigma_cells: 0.0,
            pose_sigma_rad: 0.0,
            predicted_cells_per_s: None,
        };
        let found = Registrar::default().register(&now, &window, &history, now_frame, &params);
        assert!(found.is_some_and(|r| r.velocity_cells_per_s == (0.0, 0.0)));
        // Had columns 0-3 been seen empty now, the side would have moved.
        let mut free = no_free.clone();
        for idx in indices(&window, &side(0..4)) {
            free[idx as usize] = 0.7;
        }
        let seen = Now {
            m_free: &free,
            ..now_frame
        };
        let moved = Registrar::default().register(&now, &window, &history, seen, &params);
        assert!(moved.is_some_and(|r| (r.velocity_cells_per_s.0 - 40.0).abs() < 1e-9));
        // Or seen empty by rays that met nothing within range (no mass on them).
        let mut clear = vec![false; window.len()];
        for idx in indices(&window, &side(0..4)) {
            clear[idx as usize] = true;
        }
        let seen = Now {
            clear_now: &clear,
            ..now_frame
        };
        let moved = Registrar::default().register(&now, &window, &history, seen, &params);
        assert!(moved.is_some_and(|r| (r.velocity_cells_per_s.0 - 40.0).abs() < 1e-9));
    }

    #[test]
    fn newer_frames_that_cannot_tell_give_way_and_a_stop_does_not() {
        let window = window();
        // A side of ten cells moving east a cell a frame, the road ahead of it seen free.
        // The last frame saw only its front seven cells (the rest hidden): zero and a shift
        // of one explain 7 each, a tie, and zero wins. But the cell the side entered since
        // was seen free in that frame.
        let mut sides: Vec<_> = (10..17).map(|first| first..first + 10).collect();
        sides.push(20..27);
        let found = register_side(&window, &side_history(&window, &sides), 18..28);
        // Three cells in 0.3 s: the two newer frames predicted a shift of 1 and 2, which
        // explain them as well as zero (7 = 7, 10 > 8).
        assert_eq!(found.frames, 1);
        assert!(
            (found.velocity_cells_per_s.0 - 10.0).abs() < 1e-9,
            "{found:?}"
        );

        // The same side stopped three frames ago: zero explains the newer frames exactly,
        // the predicted shift leaves an end unmatched. With `stop_evidence_cells` at 0.5 (the
        // rule before it), the stop is kept: the shift of two cells over 0.5 s predicts 0.8
        // cell (rounded: one) against the frame 0.2 s back, which zero explains better (10
        // against 9).
        let sides: Vec<_> = [10, 11, 12, 13, 14, 15, 15, 15]
            .into_iter()
            .map(|first| first..first + 10)
            .collect();
        let history = side_history(&window, &sides);
        let stopped = cells(&window, &(15..25).map(|c| (c, 10)).collect::<Vec<_>>());
        let none = Clusters::new(window.len());
        let register = |params: &MotionParams, now: Now<'_>| {
            Registrar::default()
                .register(&stopped, &window, &history, now, params)
                .unwrap_or_else(|| panic!("not registered"))
        };
        let before = MotionParams {
            stop_evidence_cells: 0.5,
            contradicted_unmeasured: false,
            ..MotionParams::default()
        };
        let found = register(&before, alone(0.8, &none));
        assert_eq!(found.velocity_cells_per_s, (0.0, 0.0), "{found:?}");
        // With `contradicted_unmeasured` too, the newer frames read zero but the one 0.4 s
        // back (before the stop) matches 9 of 10 cells at zero, not all: the cluster is not
        // measured this frame (the cost of the rule: a stop 0.3 s old, its last move one
        // cell).
        let unmeasured = MotionParams {
            stop_evidence_cells: 0.5,
            ..MotionParams::default()
        };
        let found = Registrar::default().register(
            &stopped,
            &window,
            &history,
            alone(0.8, &none),
            &unmeasured,
        );
        assert_eq!(found, None);
        // With the default 1.5, the newer frames' predicted shifts (0.4, 0.8, 1.2 cells) are
        // no evidence, and the one of 1.6 cells 0.4 s back (rounded: two) explains 9 cells,
        // as zero does: the shift of two cells over 0.5 s is taken, 4 cells/s.
        let params = MotionParams::default();
        let found = register(&params, alone(0.8, &none));
        assert!(
            (found.velocity_cells_per_s.0 - 4.0).abs() < 1e-9,
            "{found:?}"
        );
        // A track that saw the side move at a cell a frame (10 cells/s) predicts two cells
        // 0.2 s back, which explain 9 of 10 (one to three cells: 9, 8, 7) against zero's 10:
        // refuted, the stop's evidence; the search keeps the newer frames and reads zero
        // (without `contradicted_unmeasured`). With it (the default), the frame 0.4 s back
        // matches 9 of 10 at zero, not all: the cluster is not measured this frame (keeping
        // the refuted stop instead was measured worse on the tuning drives, `docs/motion.md`,
        // "Newer frames that read zero against an older move").
        let tracked = Now {
            predicted_cells_per_s: Some((10.0, 0.0)),
            ..alone(0.8, &none)
        };
        let rule_before = MotionParams {
            contradicted_unmeasured: false,
            ..MotionParams::default()
        };
        let found = register(&rule_before, tracked);
        assert_eq!(found.velocity_cells_per_s, (0.0, 0.0), "{found:?}");
        let found = Registrar::default().register(&stopped, &window, &history, tracked, &params);
        assert_eq!(found, None);
    }

    /// A side of `len` cells on row 10 whose first column in eight frames 0.1 s apart is
    /// `firsts` (the road ahead of it seen free), registered 0.8 s after the first frame at
    /// the last first column, as the one cluster of its frame (the cells behind it seen
    /// empty now), with the velocity a track predicts for it; the default parameters but
    /// `weak_shift_frames` off (the rules before "Leaning frames: a slow slide") and the
    /// margin uncapped (`shift_margin_max_cells` 0: these sides are read at zero for want of
    /// the fraction's margin, which the cap of 2 would grant a two-cell shift).
    fn register_crawl(
        firsts: [i64; 8],
        len: i64,
        predicted_cells_per_s: Option<(f64, f64)>,
    ) -> Option<Registration> {
        let without_leans = MotionParams {
            weak_shift_frames: 0,
            shift_margin_max_cells: 0.0,
            ..MotionParams::default()
        };
        register_crawl_with(firsts, len, predicted_cells_per_s, 0.0, &without_leans)
    }

    /// As `register_crawl`, with `params` and the pose's error per axis, cells (the sensor at
    /// the window's corner).
    fn register_crawl_with(
        firsts: [i64; 8],
        len: i64,
        predicted_cells_per_s: Option<(f64, f64)>,
        pose_sigma_cells: f64,
        params: &MotionParams,
    ) -> Option<Registration> {
        let window = window();
        let sides: Vec<_> = firsts.iter().map(|&f| f..f + len).collect();
        let history = side_history(&window, &sides);
        let first = firsts[7];
        let list: Vec<(i64, i64)> = (first..first + len).map(|c| (c, 10)).collect();
        let mut clusters = Clusters::new(window.len());
        clusters.label(&window, &indices(&window, &list));
        let now = Now {
            time_s: 0.8,
            clusters: &clusters,
            cluster: 0,
            m_free: &ALL_FREE,
            clear_now: &[],
            sensor_cell: (0.0, 0.0),
            pose_sigma_cells,
            pose_sigma_rad: 0.0,
            predicted_cells_per_s,
        };
        Registrar::default().register(&cells(&window, &list), &window, &history, now, params)
    }

    #[test]
    fn a_slide_leaning_on_a_line_moves_and_one_that_stopped_does_not() {
        // The margin uncapped: with `shift_margin_max_cells` 2 the two-cell shifts below
        // would be clear, not leans.
        let params = MotionParams {
            shift_margin_max_cells: 0.0,
            ..MotionParams::default()
        };
        // The 20-cell side of `a_tracks_prediction_keeps_a_crawling_side_moving_until_zero_
        // refutes_it`, alone: read at zero against all eight frames (one cell explains 20
        // against 19 at 0.3-0.5 s, two cells 20 against 18 at 0.6-0.8 s; the margin is 3).
        // Six frames read a shift; the three two-cell ones lean (their move seen on four
        // cells, the margin's 3; the one-cell shifts are seen on two): the default's two at
        // least. The line through the
        // readings: Σ d·τ = 1·(0.3 + 0.4 + 0.5) + 2·(0.6 + 0.7 + 0.8) = 5.4 cell·s, Σ τ² =
        // 2.04 s², v = 45/17 = 2.6471 cells/s; every frame within a cell of it (0.26 at 0.1 s
        // read 0, 1.32 at 0.5 s read 1, 2.12 at 0.8 s read 2), and it reaches 2.12 cells: the
        // velocity, over the same eight frames.
        let crawl = [10, 10, 10, 11, 11, 11, 12, 12];
        let leaning = register_crawl_with(crawl, 20, None, 0.0, &params);
        assert!(
            leaning.is_some_and(|r| r.frames == 8
                && (r.velocity_cells_per_s.0 - 45.0 / 17.0).abs() < 1e-9
                && r.velocity_cells_per_s.1 == 0.0
                && (r.sum_span_sq - 2.04).abs() < 1e-9),
            "{leaning:?}"
        );
        // Off: static.
        let off = register_crawl(crawl, 20, None);
        assert!(off.is_some_and(|r| r.velocity_cells_per_s == (0.0, 0.0)));
        // Three leaning frames are not four.
        let four = MotionParams {
            weak_shift_frames: 4,
            ..params.clone()
        };
        let too_few = register_crawl_with(crawl, 20, None, 0.0, &four);
        assert!(too_few.is_some_and(|r| r.velocity_cells_per_s == (0.0, 0.0)));
        // Under a pose error of 0.8 cell per axis a static cluster's apparent shift has
        // σ = √2 · 0.8 = 1.131 cells, and the line must reach 2σ = 2.263 cells
        // (`displaced_pose_sigmas` = 2), not the 2.12 it does: static.
        let two_sigmas = MotionParams {
            displaced_pose_sigmas: 2.0,
            ..params.clone()
        };
        let posed = register_crawl_with(crawl, 20, None, 0.8, &two_sigmas);
        assert!(posed.is_some_and(|r| r.velocity_cells_per_s == (0.0, 0.0)));
        // At 0.7 cell, 2σ = 1.980 cells: it moves.
        let posed = register_crawl_with(crawl, 20, None, 0.7, &two_sigmas);
        assert!(posed.is_some_and(|r| (r.velocity_cells_per_s.0 - 45.0 / 17.0).abs() < 1e-9));
        // The side that stopped 0.5 s ago (10, 10, 10, then 12 from 0.5 s back): three frames
        // lean two cells (0.6-0.8 s), v = 2·2.1 / 2.04 = 2.0588 cells/s, but 0.5 s back it
        // reads zero (it matches itself there) where the line says 1.03 cells: off the line,
        // static.
        let stopped = register_crawl_with([10, 10, 10, 12, 12, 12, 12, 12], 20, None, 0.0, &params);
        assert!(stopped.is_some_and(|r| r.velocity_cells_per_s == (0.0, 0.0) && r.frames == 8));
    }

    #[test]
    fn leans_that_come_and_go_or_reach_no_cell_are_no_line() {
        let spans = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8];
        // Every non-zero reading seen on the margin's cells (a lean).
        let leans = |d: [(i64, i64); 8]| d.map(|d| (d, d != (0, 0)));
        let z = (0, 0);
        // Five older frames one cell east: Σ d·τ = 3.0, v = 3 / 2.04 = 1.4706 cells/s,
        // 1.18 cells at 0.8 s: a line.
        let crawl = leans([z, z, z, (1, 0), (1, 0), (1, 0), (1, 0), (1, 0)]);
        let line = weak_line(&crawl, spans.iter().copied(), 3, 1.0);
        assert!(line.is_some_and(|(vx, vy)| (vx - 3.0 / 2.04).abs() < 1e-12 && vy == 0.0));
        assert_eq!(weak_line(&crawl, spans.iter().copied(), 6, 1.0), None);
        // Nor when the pose's error moves a static cluster 1.2 cells.
        assert_eq!(weak_line(&crawl, spans.iter().copied(), 3, 1.2), None);
        // A cell of jitter this way and that (four leans): v = (0.6, 0.6) / 2.04 = 0.29 cells/s
        // per axis, 0.24 cell at 0.8 s: no whole cell.
        let jitter = leans([z, (1, 0), z, (-1, 0), z, (0, 1), z, (1, 0)]);
        assert_eq!(weak_line(&jitter, spans.iter().copied(), 3, 1.0), None);
        // Three cells 0.8 s back beside one cell 0.4-0.7 s back: v = 4.6 / 2.04 = 2.25
        // cells/s, 1.80 at 0.8 s, 1.20 cells from the three read there: off the line.
        let jump = leans([z, z, z, (1, 0), (1, 0), (1, 0), (1, 0), (3, 0)]);
        assert_eq!(weak_line(&jump, spans.iter().copied(), 3, 1.0), None);
    }

    #[test]
    fn a_crawl_whose_newer_frames_read_zero_by_quantisation_is_measured() {
        // A 10-cell side crawling east, two cells in 0.5 s, its first column 10, 10, 10, 10,
        // 11, 11, 12, 12 and 12 now. Against 0.1 and 0.2 s back zero explains all 10; 0.3
        // and 0.4 s back 9, one cell 10 (not the margin of ⌈1.5⌉ = 2 more); 0.5 s back zero
        // 8, two cells 10: clear. The newer frames' zeros are off its line by two cells. The
        // shift predicts 0.4, 0.8, 1.2 and 1.6 cells for them; only the last is stop
        // evidence (≥ 1.5 cells), and there two cells explain 9, as zero does: they could not
        // tell (the side's front cell was seen free 0.3 s back), so they give way: 4 cells/s.
        let found = register_crawl([10, 10, 10, 10, 11, 11, 12, 12], 10, None);
        assert!(found.is_some_and(|r| r.frames == 1
            && (r.velocity_cells_per_s.0 - 4.0).abs() < 1e-9
            && r.velocity_cells_per_s.1 == 0.0));
    }

    #[test]
    fn a_tracks_prediction_keeps_a_crawling_side_moving_until_zero_refutes_it() {
        // A 20-cell side (a long vehicle, or two joined) crawling east at about 3 cells/s
        // (1.5 m/s): first column 10, 10, 10, 11, 11, 11, 12, 12, and 12 now. A shift of one
        // cell explains 20 against zero's 19 (0.3-0.5 s back), two cells 20 against 18
        // (0.6-0.8 s back): never the margin ⌈0.15 · 20⌉ = 3 more. Alone, and without
        // leaning frames (`register_crawl`; with them it moves, `a_slide_leaning_on_a_line_
        // moves_and_one_that_stopped_does_not`), it reads static.
        let crawl = [10, 10, 10, 11, 11, 11, 12, 12];
        let alone_found = register_crawl(crawl, 20, None);
        assert!(alone_found.is_some_and(|r| r.velocity_cells_per_s == (0.0, 0.0) && r.frames == 8));
        // Its track predicts 3 cells/s. 0.1 s back: 0.3 cell, rounded zero, no prior. 0.2 s
        // back: 0.6 cell, rounded one, which explains 19 against zero's 20, and 0.6 cell is
        // no stop evidence: zero. 0.3-0.5 s back: one cell, 20 against 19, but its move is
        // seen on two cells only (the cell left behind, seen empty now, and the front cell,
        // seen free then), not the margin's 3: zero. 0.6 s back: 1.8 cells, rounded two, 20
        // against 18, seen on four: taken, and the newer zeros give way: 2 cells in 0.6 s.
        let tracked = register_crawl(crawl, 20, Some((3.0, 0.0)));
        assert!(
            tracked.is_some_and(|r| r.frames == 1
                && (r.velocity_cells_per_s.0 - 2.0 / 0.6).abs() < 1e-9
                && (r.sum_span_sq - 0.36).abs() < 1e-9),
            "{tracked:?}"
        );
        // The same side stopped 0.5 s ago (first column 10, 10, 10, 12, 12, 12, 12, 12), its
        // track at 4 cells/s: 0.4 s back the prediction is 1.6 cells (rounded two), and the
        // shifts of one to three cells explain 19, 18, 17 against zero's 20: refuted. 0.6 s
        // back, before the stop, two cells would explain 20 against 18 and be seen on four,
        // but the prior has ended: zero there too, and the track is told it stopped.
        let stopped = register_crawl([10, 10, 10, 12, 12, 12, 12, 12], 20, Some((4.0, 0.0)));
        assert!(stopped.is_some_and(|r| r.velocity_cells_per_s == (0.0, 0.0) && r.frames == 8));
    }

    #[test]
    fn a_pole_given_a_passing_cars_prediction_stays_static() {
        let (window, params, none) = (window(), MotionParams::default(), Clusters::new(1600));
        // A pole of two cells at column 20 in every frame; a car's track at 10 cells/s
        // predicts into it. 0.1 s back: one cell, which explains none of it (zero: both),
        // and a cell is no stop evidence; 0.2 s back: two cells, none against two: refuted.
        // Zero against all eight frames.
        let mut history = OccupancyHistory::new(window.len());
        for k in 0..8 {
            history.push(&indices(&window, &[(20, 5), (20, 6)]), &[], 0.1 * k as f64);
        }
        let pole = cells(&window, &[(20, 5), (20, 6)]);
        let now = Now {
            predicted_cells_per_s: Some((10.0, 0.0)),
            ..alone(0.8, &none)
        };
        let found = Registrar::default().register(&pole, &window, &history, now, &params);
        assert!(found.is_some_and(|r| r.velocity_cells_per_s == (0.0, 0.0) && r.frames == 8));
    }

    #[test]
    fn a_slow_side_shows_its_move_only_to_a_thinned_history() {
        // A 10-cell side on row 10 creeping east one cell a second (0.5 m/s at 0.5 m cells):
        // its first column in frame k (0.1·k s) is 10 + ⌊k / 10⌋, the road ahead seen free.
        // Registered at frame 20 (2.0 s, columns 12-21).
        let window = window();
        let row = |first: i64| (first..first + 10).map(|c| (c, 10)).collect::<Vec<_>>();
        let register_with = |thinned: bool, params: &MotionParams| {
            let mut history = OccupancyHistory::new(window.len()).with_thinning(thinned);
            for k in 0..20 {
                let first = 10 + k / 10;
                let ahead: Vec<_> = (first + 10..40).map(|c| (c, 10)).collect();
                history.push(
                    &indices(&window, &row(first)),
                    &indices(&window, &ahead),
                    0.1 * k as f64,
                );
            }
            let none = Clusters::new(window.len());
            Registrar::default().register(
                &cells(&window, &row(12)),
                &window,
                &history,
                alone(2.0, &none),
                params,
            )
        };
        // Without leaning frames (the rules before "Leaning frames: a slow slide").
        let without_leans = MotionParams {
            weak_shift_frames: 0,
            ..MotionParams::default()
        };
        let register = |thinned: bool| register_with(thinned, &without_leans);
        // The last eight frames (1.2-1.9 s) all hold columns 11-20: one cell explains 10 cells
        // against zero's 9, not the margin of ⌈0.15 · 10⌉ = 2 more: static, on all eight.
        let eight = register(false);
        assert!(
            eight.is_some_and(|r| r.velocity_cells_per_s == (0.0, 0.0) && r.frames == 8),
            "{eight:?}"
        );
        // With them (the default): every one of the eight leans one cell, its move seen on the
        // margin's two cells (column 11, left and seen empty now; column 21, seen free then),
        // and lies within a cell of the line Σ τ / Σ τ² = 3.6 / 2.04 = 30/17 cells/s (0.18
        // cell at 0.1 s, 1.41 at 0.8 s, which reaches a cell): 30/17 cells/s, the average
        // creep of one cell a second over-read by the newest frames' whole cell.
        let leaning = register_with(false, &MotionParams::default());
        assert!(
            leaning.is_some_and(|r| r.frames == 8
                && (r.velocity_cells_per_s.0 - 30.0 / 17.0).abs() < 1e-9
                && r.velocity_cells_per_s.1 == 0.0),
            "{leaning:?}"
        );
        // Thinned, the frames kept are 1.9, 1.8, 1.7, 1.6, 1.4, 1.2, 0.8 and 0.4 s. The six
        // newest read zero the same way (one cell more than zero each time: they could not
        // tell); 1.2 s back (columns 10-19) two cells explain 10 against 8, and the cells
        // entered (20, 21) were seen free then: clear. The shift predicts at most 2 · 0.8 / 1.2
        // = 1.33 cells for the newer frames, no stop evidence (1.5), so they give way: two
        // cells in 1.2 s.
        let thinned = register(true);
        assert!(
            thinned.is_some_and(|r| r.frames == 1
                && (r.velocity_cells_per_s.0 - 2.0 / 1.2).abs() < 1e-9
                && r.velocity_cells_per_s.1 == 0.0),
            "{thinned:?}"
        );
    }

    #[test]
    fn newer_frames_at_zero_against_an_older_move_leave_the_cluster_unmeasured() {
        // A 4-cell face (rows 10-13) at column 10 at 0.0 s; at column 13 at 0.1, 0.2 and
        // 0.3 s, where only rows 10-12 were visible (the last hidden); now (0.4 s) rows 10-13
        // at column 13. Nothing seen free in the past frames. Newest first: 0.1, 0.2 and 0.3 s
        // back zero explains 3 of the 4 cells (no shift more: one row north ties, 3); 0.4 s
        // back three cells east explain all 4 against zero's none, more than the margin
        // ⌈0.15 · 4⌉ = 1, the move seen on 4 cells (column 10 seen empty now): clear, but 3
        // cells off the newer frames' line (0), and they could tell (zero was their best, no
        // cell seen free in them). The rule before reads it static on the three newer frames.
        let window = window();
        let face =
            |col: i64, rows: std::ops::Range<i64>| rows.map(|r| (col, r)).collect::<Vec<_>>();
        let register = |newer_rows: std::ops::Range<i64>, params: &MotionParams, pose: f64| {
            let mut history = OccupancyHistory::new(window.len());
            history.push(&indices(&window, &face(10, 10..14)), &[], 0.0);
            for k in 1..4 {
                let occupied = indices(&window, &face(13, newer_rows.clone()));
                history.push(&occupied, &[], 0.1 * k as f64);
            }
            let none = Clusters::new(window.len());
            let now = Now {
                pose_sigma_cells: pose,
                ..alone(0.4, &none)
            };
            Registrar::default().register(
                &cells(&window, &face(13, 10..14)),
                &window,
                &history,
                now,
                params,
            )
        };
        let is_static = |r: Option<Registration>| {
            r.is_some_and(|r| r.velocity_cells_per_s == (0.0, 0.0) && r.frames == 3)
        };
        let before = MotionParams {
            contradicted_unmeasured: false,
            ..MotionParams::default()
        };
        let found = register(10..13, &before, 0.0);
        assert!(is_static(found), "{found:?}");
        // With `contradicted_unmeasured` (the default; exact pose): not measured this frame.
        let params = MotionParams::default();
        assert_eq!(register(10..13, &params, 0.0), None);
        // Under a pose error of 2 cells per axis the apparent shift of a static cluster has σ
        // √2 · 2 = 2.83 cells; the 3-cell move is within `displaced_pose_sigmas` (1.5) of it,
        // 4.24 cells: read static on the newer frames as before.
        let found = register(10..13, &params, 2.0);
        assert!(is_static(found), "{found:?}");
        // A face that stopped: the newer frames hold all four rows, zero explains each
        // exactly. The stop is read as before.
        let found = register(10..14, &params, 0.0);
        assert!(is_static(found), "{found:?}");
    }
}
