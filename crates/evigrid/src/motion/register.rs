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

use super::clusters::Cell;
use super::history::{OccupancyHistory, SLOTS};
use crate::params::MotionParams;
use crate::window::Window;

/// Cells of a cluster counted at most: a long façade is sampled evenly.
const MAX_COUNTED_CELLS: usize = 256;

/// A cluster's measured shift against one past frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Registration {
    /// Shift from the past frame to now, cells (east, north).
    pub(crate) shift_cells: (i32, i32),
    /// Which past frame (1 = previous).
    pub(crate) frames_back: usize,
    /// Time from that frame to now, seconds.
    pub(crate) span_s: f64,
}

/// Scratch buffers of the search, kept between clusters and frames.
#[derive(Clone, Debug, Default)]
pub(crate) struct Registrar {
    patch: Vec<u8>,
    counts: Vec<[u32; SLOTS]>,
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
        now_s: f64,
        params: &MotionParams,
    ) -> Option<Registration> {
        let first = cells.first()?;
        let radius = params.search_radius_cells as i64;
        let (mut c0, mut c1, mut r0, mut r1) = (first.col, first.col, first.row, first.row);
        for c in cells {
            (c0, c1) = (c0.min(c.col), c1.max(c.col));
            (r0, r1) = (r0.min(c.row), r1.max(c.row));
        }
        // The history around the cluster, `radius` cells beyond its bounding box.
        let pw = (c1 - c0 + 1 + 2 * radius) as usize;
        let ph = (r1 - r0 + 1 + 2 * radius) as usize;
        self.patch.clear();
        self.patch.resize(pw * ph, 0);
        for (pr, row) in (r0 - radius..=r1 + radius).enumerate() {
            for (pc, col) in (c0 - radius..=c1 + radius).enumerate() {
                if let Some(idx) = window.storage_index(col, row) {
                    self.patch[pr * pw + pc] = history.bits(idx);
                }
            }
        }

        // n_k(d) for every shift d and past frame k at once.
        let stride = cells.len().div_ceil(MAX_COUNTED_CELLS);
        let counted = cells.len().div_ceil(stride) as u32;
        let side = 2 * radius + 1;
        self.counts.clear();
        self.counts.resize((side * side) as usize, [0; SLOTS]);
        for (s, count) in self.counts.iter_mut().enumerate() {
            let (dx, dy) = (s as i64 % side - radius, s as i64 / side - radius);
            let mut lanes = 0u64;
            let mut in_lanes = 0;
            for c in cells.iter().step_by(stride) {
                let pc = (c.col - dx - c0 + radius) as usize;
                let pr = (c.row - dy - r0 + radius) as usize;
                lanes += SPREAD[usize::from(self.patch[pr * pw + pc])];
                in_lanes += 1;
                // A byte lane holds up to 255.
                if in_lanes == 255 {
                    flush(&mut lanes, count);
                    in_lanes = 0;
                }
            }
            flush(&mut lanes, count);
        }

        let zero = (radius * side + radius) as usize;
        let needed = (params.match_fraction * f64::from(counted)).max(1.0);
        let margin = (params.shift_margin_fraction * f64::from(counted))
            .ceil()
            .max(1.0) as u32;
        let cell_size_m = window.cell_size_m();
        let mut found = None;
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
            let (matched, dx, dy) = if best.0 >= n_zero + margin {
                best
            } else {
                (n_zero, 0, 0)
            };
            if f64::from(matched) < needed {
                continue;
            }
            found = Some(Registration {
                shift_cells: (dx as i32, dy as i32),
                frames_back,
                span_s,
            });
            // Two cells or more: precise enough, and further back a fast object leaves the
            // search radius.
            if dx * dx + dy * dy >= 4 {
                break;
            }
        }
        found
    }
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

    #[test]
    fn spread_puts_each_bit_in_its_byte() {
        assert_eq!(SPREAD[0b1000_0101], 0x0100_0000_0001_0001);
    }

    #[test]
    fn a_face_moving_two_cells_a_frame_is_found_and_a_wall_is_static() {
        let window = Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let params = MotionParams::default();
        let mut history = OccupancyHistory::new(window.len());
        // A 4-cell face at column 10 moving east by 2 cells a frame, and a wall at row 30.
        let face = |col: i64| (0..4).map(move |r| (col, 10 + r));
        let wall: Vec<(i64, i64)> = (0..20).map(|c| (c, 30)).collect();
        for k in 0..3 {
            let mut occupied: Vec<(i64, i64)> = face(10 + 2 * k).collect();
            occupied.extend(&wall);
            history.push(&indices(&window, &occupied), 0.1 * k as f64);
        }
        let mut registrar = Registrar::default();
        let now: Vec<(i64, i64)> = face(16).collect();
        let found = registrar
            .register(&cells(&window, &now), &window, &history, 0.3, &params)
            .unwrap_or_else(|| panic!("not registered"));
        assert_eq!(found.shift_cells, (2, 0));
        assert_eq!(found.frames_back, 1);
        assert!((found.span_s - 0.1).abs() < 1e-12);
        let still = registrar
            .register(&cells(&window, &wall), &window, &history, 0.3, &params)
            .unwrap_or_else(|| panic!("not registered"));
        // Static: zero shift, measured against the oldest frame kept (3 back).
        assert_eq!(still.shift_cells, (0, 0));
        assert_eq!(still.frames_back, 3);
    }

    #[test]
    fn a_slow_object_is_measured_against_older_frames_and_a_new_one_not_at_all() {
        let window = Window::new(40, 40, 0.5).unwrap_or_else(|e| panic!("{e}"));
        let params = MotionParams::default();
        let mut history = OccupancyHistory::new(window.len());
        // Two cells moving one cell every three frames (a walker at 1.7 m/s).
        for k in 0..7 {
            let col = 5 + k / 3;
            history.push(&indices(&window, &[(col, 5), (col, 6)]), 0.1 * k as f64);
        }
        let mut registrar = Registrar::default();
        let now = cells(&window, &[(7, 5), (7, 6)]);
        let found = registrar
            .register(&now, &window, &history, 0.7, &params)
            .unwrap_or_else(|| panic!("not registered"));
        // Frames 1 and 2 back read no shift or one cell; frame 2, five back, is at column 5:
        // two cells in 0.5 s.
        assert_eq!(found.shift_cells, (2, 0));
        assert_eq!(found.frames_back, 5);
        assert!((found.span_s - 0.5).abs() < 1e-9);
        let elsewhere = cells(&window, &[(30, 30), (30, 31)]);
        assert_eq!(
            registrar.register(&elsewhere, &window, &history, 0.7, &params),
            None
        );
    }
}
