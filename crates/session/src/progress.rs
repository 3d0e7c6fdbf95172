//! What a caller hears as a drive runs.

use crate::summary::FrameRecord;

/// What a caller hears as a drive runs (a progress bar, per-frame lines). Every method does
/// nothing by default; `()` hears nothing.
pub trait Progress {
    /// The odometry pass starts over `scans` scans.
    fn odometry_started(&mut self, scans: usize) {
        let _ = scans;
    }
    /// The odometry registered (or left out) one scan; its last report says how it went.
    fn odometry_scan(&mut self, odometry: &odometry::Odometry) {
        let _ = odometry;
    }
    /// The odometry pass ended.
    fn odometry_finished(&mut self) {}
    /// The frames start: `frames` of them.
    fn frames_started(&mut self, frames: usize) {
        let _ = frames;
    }
    /// Frame `index` was processed (`record`) or skipped (`None`).
    fn frame(&mut self, index: usize, record: Option<&FrameRecord>) {
        let _ = (index, record);
    }
    /// The frames ended.
    fn frames_finished(&mut self) {}
}

impl Progress for () {}
