//! Which cells were occupied, and which were seen free, in each of the last eight frames: two
//! bytes a cell.
//!
//! Bit `f mod 8` of a cell's byte says whether the cell held a return in frame `f` (or, in the
//! second plane, was crossed by a ray without holding one). A frame's bit is cleared, eight
//! frames later, only in the cells that frame listed, so that one frame costs as many writes as
//! it has observed cells, whatever the window's size.

use std::ops::Range;

/// Frames kept: the bits of a byte.
pub(crate) const SLOTS: usize = 8;

/// The occupied cells of the last [`SLOTS`] frames, or, thinned, of eight frames reaching
/// about twice as far back.
#[derive(Clone, Debug)]
pub(crate) struct OccupancyHistory {
    bits: Vec<u8>,
    free_bits: Vec<u8>,
    /// The storage cells each slot's frame set, to clear them when the slot is reused.
    lists: [Vec<u32>; SLOTS],
    free_lists: [Vec<u32>; SLOTS],
    /// Time of each slot's frame, seconds.
    times_s: [f64; SLOTS],
    /// Number of each slot's frame (0 for the first frame recorded).
    frame_of: [u64; SLOTS],
    /// The slots holding a frame, newest first: `order[..kept]`.
    order: [usize; SLOTS],
    kept: usize,
    /// Frames recorded so far.
    frames: u64,
    /// Whether the frames kept are thinned ([`keeps_thinned`]) rather than the last eight.
    thinned: bool,
}

/// Whether a thinned history keeps frame number `frame` when it is `age` frames before the
/// frame being registered: the last four, the even ones up to eight back and every fourth up
/// to sixteen back. Those are eight frames at every step (four, two of the four frames 5-8
/// back and two of the eight frames 9-16 back), and a frame kept at one step was kept at every
/// step before: each push drops at most one frame. At 10 Hz they reach 1.3-1.6 s back instead
/// of 0.8 s: a car crawling at 1.5 m/s moves 4-5 cells of 0.5 m, not 2.4.
pub(crate) fn keeps_thinned(age: u64, frame: u64) -> bool {
    age <= 4 || (age <= 8 && frame.is_multiple_of(2)) || (age <= 16 && frame.is_multiple_of(4))
}

impl OccupancyHistory {
    /// Bytes of the per-cell bit planes (the lists scale with the scans, not the window).
    pub(crate) fn dense_bytes(&self) -> usize {
        self.bits.capacity() + self.free_bits.capacity()
    }

    pub(crate) fn new(len: usize) -> Self {
        Self {
            bits: vec![0; len],
            free_bits: vec![0; len],
            lists: Default::default(),
            free_lists: Default::default(),
            times_s: [0.0; SLOTS],
            frame_of: [0; SLOTS],
            order: [0; SLOTS],
            kept: 0,
            frames: 0,
            thinned: false,
        }
    }

    /// The same history keeping thinned frames ([`keeps_thinned`]) when `thinned`
    /// (`motion.history_thinned`).
    pub(crate) fn with_thinning(self, thinned: bool) -> Self {
        Self { thinned, ..self }
    }

    /// Forgets the cells of `range` (they entered the window). Stale indices in the lists only
    /// ever clear bits that are already clear.
    pub(crate) fn reset_range(&mut self, range: Range<usize>) {
        if let Some(cells) = self.bits.get_mut(range.clone()) {
            cells.fill(0);
        }
        if let Some(cells) = self.free_bits.get_mut(range) {
            cells.fill(0);
        }
    }

    /// Forgets everything.
    pub(crate) fn reset_all(&mut self) {
        self.bits.fill(0);
        self.free_bits.fill(0);
        for list in self.lists.iter_mut().chain(&mut self.free_lists) {
            list.clear();
        }
        self.kept = 0;
        self.frames = 0;
    }

    /// The history byte of a storage cell (0 outside).
    #[inline]
    pub(crate) fn bits(&self, idx: usize) -> u8 {
        self.bits.get(idx).copied().unwrap_or(0)
    }

    /// The seen-free history byte of a storage cell (0 outside).
    #[inline]
    pub(crate) fn free_bits(&self, idx: usize) -> u8 {
        self.free_bits.get(idx).copied().unwrap_or(0)
    }

    /// The bit and time of the `frames_back`-th newest frame kept (1 = the last recorded;
    /// without thinning, the frame that many frames before the next one), if there is one.
    pub(crate) fn frame_back(&self, frames_back: usize) -> Option<(u8, f64)> {
        if frames_back == 0 || frames_back > self.kept {
            return None;
        }
        let slot = self.order[frames_back - 1];
        Some((1 << slot, self.times_s[slot]))
    }

    /// The bits of the frames kept that are at most [`SLOTS`] frames before the next one (all
    /// of them without thinning): the frames whose seen-free cells tell an object that
    /// entered space seen empty.
    pub(crate) fn recent_bits(&self) -> u8 {
        self.order[..self.kept]
            .iter()
            .filter(|&&slot| self.frames - self.frame_of[slot] <= SLOTS as u64)
            .fold(0u8, |bits, &slot| bits | 1 << slot)
    }

    /// Records the occupied and the seen-free cells of the next frame, taken at `time_s`.
    /// Without thinning it takes the slot of the oldest frame once eight are kept; thinned, the
    /// frames [`keeps_thinned`] no longer keeps for the next registration are dropped first.
    pub(crate) fn push(&mut self, occupied: &[u32], free: &[u32], time_s: f64) {
        let frame = self.frames;
        if self.thinned {
            let mut k = 0;
            while k < self.kept {
                let slot = self.order[k];
                let age = frame + 1 - self.frame_of[slot];
                if keeps_thinned(age, self.frame_of[slot]) {
                    k += 1;
                } else {
                    self.drop_kept(k);
                }
            }
        }
        let slot = if self.thinned {
            if self.kept == SLOTS {
                self.drop_kept(SLOTS - 1);
            }
            (0..SLOTS)
                .find(|s| !self.order[..self.kept].contains(s))
                .unwrap_or(0)
        } else {
            let slot = (frame % SLOTS as u64) as usize;
            if let Some(k) = self.order[..self.kept].iter().position(|&s| s == slot) {
                self.drop_kept(k);
            }
            slot
        };
        let bit = 1u8 << slot;
        for (bits, list, cells) in [
            (&mut self.bits, &mut self.lists[slot], occupied),
            (&mut self.free_bits, &mut self.free_lists[slot], free),
        ] {
            list.extend_from_slice(cells);
            for &idx in cells {
                if let Some(b) = bits.get_mut(idx as usize) {
                    *b |= bit;
                }
            }
        }
        self.times_s[slot] = time_s;
        self.frame_of[slot] = frame;
        self.order.copy_within(0..self.kept, 1);
        self.order[0] = slot;
        self.kept += 1;
        self.frames += 1;
    }

    /// Forgets the `k`-th newest frame kept: its bits cleared in the cells it listed.
    fn drop_kept(&mut self, k: usize) {
        let slot = self.order[k];
        let bit = 1u8 << slot;
        for (bits, list) in [
            (&mut self.bits, &mut self.lists[slot]),
            (&mut self.free_bits, &mut self.free_lists[slot]),
        ] {
            for &idx in list.iter() {
                if let Some(b) = bits.get_mut(idx as usize) {
                    *b &= !bit;
                }
            }
            list.clear();
        }
        self.order.copy_within(k + 1..self.kept, k);
        self.kept -= 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_back_find_their_cells_and_old_frames_are_cleared() {
        let mut h = OccupancyHistory::new(4);
        assert_eq!(h.frame_back(1), None);
        h.push(&[0, 1], &[3], 0.0);
        h.push(&[1, 2], &[], 0.1);
        let (one_back, t1) = h.frame_back(1).unwrap_or_default();
        let (two_back, t2) = h.frame_back(2).unwrap_or_default();
        assert_eq!((t1, t2), (0.1, 0.0));
        let occupied = |h: &OccupancyHistory, bit: u8| {
            (0..4).filter(|&i| h.bits(i) & bit != 0).collect::<Vec<_>>()
        };
        assert_eq!(occupied(&h, one_back), vec![1, 2]);
        assert_eq!(occupied(&h, two_back), vec![0, 1]);
        assert_eq!(h.free_bits(3), two_back);
        assert_eq!(h.frame_back(3), None);
        // Eight frames later the first frame's slot is reused and its cells cleared.
        for k in 0..7 {
            h.push(&[3], &[], 0.2 + 0.1 * k as f64);
        }
        let (eight_back, _) = h.frame_back(8).unwrap_or_default();
        assert_eq!(occupied(&h, eight_back), vec![1, 2]);
        h.push(&[], &[], 1.0);
        assert_eq!(h.bits(0), 0, "frame 0's cell was cleared with its slot");
        assert_eq!(h.free_bits(3), 0);
        h.reset_range(3..4);
        assert_eq!(h.bits(3), 0);
    }

    #[test]
    fn a_thinned_history_keeps_eight_frames_reaching_sixteen_back() {
        let mut h = OccupancyHistory::new(20).with_thinning(true);
        // Frame k, at 0.1·k s, occupies cell k and sees cell 19 free.
        for k in 0..20u32 {
            h.push(&[k], &[19], 0.1 * f64::from(k));
            // Eight frames at most (the odd ones are dropped five frames back from the
            // start), and eight once frames reach sixteen back.
            assert!(h.kept <= SLOTS, "after frame {k}");
            if k >= 15 {
                assert_eq!(h.kept, SLOTS, "after frame {k}");
            }
        }
        // Before frame 20: ages 1-4 (frames 19-16), the even ones of ages 5-8 (14, 12) and
        // every fourth of ages 9-16 (8, 4).
        let kept: Vec<usize> = (1..=SLOTS)
            .filter_map(|k| h.frame_back(k))
            .map(|(bit, _)| (0..20).find(|&c| h.bits(c) & bit != 0).unwrap_or(99))
            .collect();
        assert_eq!(kept, vec![19, 18, 17, 16, 14, 12, 8, 4]);
        let times: Vec<f64> = (1..=SLOTS)
            .filter_map(|k| h.frame_back(k))
            .map(|(_, t)| (t * 10.0).round() / 10.0)
            .collect();
        assert_eq!(times, vec![1.9, 1.8, 1.7, 1.6, 1.4, 1.2, 0.8, 0.4]);
        assert_eq!(h.frame_back(9), None);
        // The frames dropped were cleared from their cells; the free plane holds the eight.
        for dropped in [0, 1, 2, 3, 5, 6, 7, 9, 10, 11, 13, 15] {
            assert_eq!(h.bits(dropped), 0, "frame {dropped}");
        }
        assert_eq!(h.free_bits(19).count_ones(), 8);
        // Only the frames at most eight back tell what entered space seen free.
        let recent = h.recent_bits();
        assert_eq!(recent.count_ones(), 6);
        assert_eq!(recent & h.bits(8), 0);
        assert_eq!(recent & h.bits(12), h.bits(12));
        // The rule itself: a frame kept at one step was kept at every step before.
        for frame in 0..40u64 {
            for age in 2..=20u64 {
                if keeps_thinned(age, frame) {
                    assert!(keeps_thinned(age - 1, frame), "frame {frame} age {age}");
                }
            }
        }
    }
}
