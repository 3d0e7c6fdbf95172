//! Fixtures and unlabelled measures shared by the integration tests and the `ground_eval`
//! example: the shared KITTI scans, and what a segmentation of them looks like per frame.
#![allow(dead_code)]

use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

use ground::{PointLabel, Segmentation};

pub mod scene;

/// The 40 scans of KITTI raw drive 2011_09_26_0013 (frames 80–119), or `None` when the shared
/// data is absent.
pub fn raw_0013_scans() -> Option<Vec<PathBuf>> {
    scans("data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync/velodyne_points/data")
}

/// The 22 scans of the Karlsruhe street, or `None` when the shared data is absent.
pub fn city_22_scans() -> Option<Vec<PathBuf>> {
    scans("data/lidar/kitti-city-22")
}

fn scans(relative: &str) -> Option<Vec<PathBuf>> {
    let dir = geodata::testdata::shared_file(relative)?;
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .ok()?
        .filter_map(|entry| Some(entry.ok()?.path()))
        .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("bin" | "pcd")))
        .collect();
    paths.sort();
    Some(paths)
}

/// The points of one scan: a KITTI `.bin` (little-endian `f32` records `x y z intensity`) or a
/// binary PCD with exactly those fields, as the shared scans are. KITTI's sensor frame is close
/// to levelled: the car's roll and pitch stay within 1° on these drives.
pub fn read_points(path: &Path) -> Result<Vec<[f32; 3]>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let data = if path.extension().and_then(|e| e.to_str()) == Some("pcd") {
        const HEADER_END: &[u8] = b"DATA binary\n";
        let end = bytes
            .windows(HEADER_END.len())
            .position(|w| w == HEADER_END)
            .ok_or_else(|| format!("{}: not a binary PCD", path.display()))?;
        let header = String::from_utf8_lossy(&bytes[..end]);
        if !header.contains("FIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F") {
            return Err(format!(
                "{}: fields other than x y z intensity (f32)",
                path.display()
            ));
        }
        &bytes[end + HEADER_END.len()..]
    } else {
        &bytes[..]
    };
    let f = |r: &[u8], i: usize| f32::from_le_bytes([r[i], r[i + 1], r[i + 2], r[i + 3]]);
    Ok(data
        .chunks_exact(16)
        .map(|r| [f(r, 0), f(r, 4), f(r, 8)])
        .collect())
}

/// The lane ahead: 3 m < x < 20 m, |y| < 1 m (the car drives straight in both drives).
fn in_corridor(p: &[f32; 3]) -> bool {
    p[0] > 3.0 && p[0] < 20.0 && p[1].abs() < 1.0
}

/// A corridor obstacle point lower than this above the corridor's road is a ground return
/// called obstacle, metres.
pub const CORRIDOR_FALSE_OBSTACLE_HEIGHT_M: f32 = 0.25;

/// The road surface of the corridor, found independently of any ground method: a line
/// `z = a + b·x` through the lowest return of each metre of the corridor, refitted twice
/// without the metres more than 0.1 m above it (a car ahead, a bump).
pub fn corridor_road(points: &[[f32; 3]]) -> Option<(f32, f32)> {
    let mut lowest = [f32::INFINITY; 17];
    for p in points.iter().filter(|p| in_corridor(p)) {
        let k = ((p[0] - 3.0) as usize).min(16);
        lowest[k] = lowest[k].min(p[2]);
    }
    let mut keep = [true; 17];
    let mut line = None;
    for _ in 0..3 {
        let (mut n, mut sx, mut sz, mut sxx, mut sxz) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
        for k in 0..17 {
            if keep[k] && lowest[k].is_finite() {
                let (x, z) = (3.5 + k as f64, f64::from(lowest[k]));
                n += 1.0;
                sx += x;
                sz += z;
                sxx += x * x;
                sxz += x * z;
            }
        }
        let det = n * sxx - sx * sx;
        if n < 3.0 || det.abs() < 1e-9 {
            return line;
        }
        let b = (n * sxz - sx * sz) / det;
        let a = (sz - b * sx) / n;
        line = Some((a as f32, b as f32));
        for k in 0..17 {
            keep[k] = lowest[k] - (a + b * (3.5 + k as f64)) as f32 <= 0.1;
        }
    }
    line
}

/// What one frame's segmentation looks like.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameMeasure {
    /// Points labelled ground, over all points.
    pub ground_share: f64,
    /// Points labelled obstacle, over all points.
    pub obstacle_share: f64,
    /// Points in the corridor.
    pub corridor_points: usize,
    /// Corridor points labelled obstacle.
    pub corridor_obstacle: usize,
    /// Corridor points labelled obstacle lower than [`CORRIDOR_FALSE_OBSTACLE_HEIGHT_M`] above
    /// the corridor's road ([`corridor_road`]).
    pub corridor_false_obstacle: usize,
    /// `corridor_false_obstacle / corridor_points`.
    pub corridor_false_obstacle_share: f64,
    /// Obstacle points farther than 5 m (horizontal range), over all points: the share without
    /// what stands right alongside the vehicle.
    pub far_obstacle_share: f64,
    /// Obstacle points on a flat patch: in a 0.5 m square of at least 5 returns that span
    /// less than 0.1 m in height. Ground seen as obstacle (a car's roof is rarely alone in its
    /// square), over all points.
    pub flat_obstacle_share: f64,
    /// Ground points more than 0.3 m above the lowest return of their 1 m square: an object's
    /// side seen as ground (a kerb is half that), over all points.
    pub lifted_ground_share: f64,
    /// Milliseconds the segmentation took.
    pub ms: f64,
}

/// Lowest and highest z and count of the returns per square of `side_m`.
fn squares(points: &[[f32; 3]], side_m: f32) -> HashMap<(i32, i32), (f32, f32, u32)> {
    let mut map: HashMap<(i32, i32), (f32, f32, u32)> = HashMap::new();
    for p in points.iter().filter(|p| p.iter().all(|v| v.is_finite())) {
        let key = square_of(p, side_m);
        let e = map
            .entry(key)
            .or_insert((f32::INFINITY, f32::NEG_INFINITY, 0));
        *e = (e.0.min(p[2]), e.1.max(p[2]), e.2 + 1);
    }
    map
}

fn square_of(p: &[f32; 3], side_m: f32) -> (i32, i32) {
    (
        (p[0] / side_m).floor() as i32,
        (p[1] / side_m).floor() as i32,
    )
}

/// Measures one frame.
pub fn measure(points: &[[f32; 3]], result: &Segmentation) -> FrameMeasure {
    let mut m = measure_labels(points, result.labels());
    m.ms = result.stats().elapsed.as_secs_f64() * 1e3;
    m
}

/// Measures one frame's labels (from any method).
pub fn measure_labels(points: &[[f32; 3]], labels: &[PointLabel]) -> FrameMeasure {
    let n = points.len().max(1) as f64;
    let count = |want: PointLabel| labels.iter().filter(|&&l| l == want).count() as f64;
    let mut m = FrameMeasure {
        ground_share: count(PointLabel::Ground) / n,
        obstacle_share: count(PointLabel::Obstacle) / n,
        ..FrameMeasure::default()
    };
    let fine = squares(points, 0.5);
    let coarse = squares(points, 1.0);
    let (mut flat, mut lifted, mut far) = (0usize, 0usize, 0usize);
    for (p, &label) in points.iter().zip(labels) {
        match label {
            PointLabel::Obstacle => {
                far += usize::from(p[0].hypot(p[1]) > 5.0);
                let (lo, hi, count) = fine[&square_of(p, 0.5)];
                flat += usize::from(count >= 5 && hi - lo < 0.1);
            }
            PointLabel::Ground => lifted += usize::from(p[2] - coarse[&square_of(p, 1.0)].0 > 0.3),
            _ => {}
        }
    }
    m.flat_obstacle_share = flat as f64 / n;
    m.far_obstacle_share = far as f64 / n;
    m.lifted_ground_share = lifted as f64 / n;
    let road = corridor_road(points);
    for (p, &label) in points.iter().zip(labels) {
        if !in_corridor(p) {
            continue;
        }
        m.corridor_points += 1;
        if label == PointLabel::Obstacle {
            m.corridor_obstacle += 1;
            if let Some((a, b)) = road
                && p[2] - (a + b * p[0]) < CORRIDOR_FALSE_OBSTACLE_HEIGHT_M
            {
                m.corridor_false_obstacle += 1;
            }
        }
    }
    m.corridor_false_obstacle_share =
        m.corridor_false_obstacle as f64 / m.corridor_points.max(1) as f64;
    m
}

/// A drive's frames summarised.
#[derive(Clone, Copy, Debug, Default)]
pub struct Summary {
    /// Obstacle share: smallest, median, largest over the frames.
    pub obstacle_share: [f64; 3],
    /// Largest obstacle share over the median.
    pub worst_over_median: f64,
    /// Obstacle share beyond 5 m: smallest, median, largest over the frames.
    pub far_obstacle_share: [f64; 3],
    /// Largest obstacle share beyond 5 m over its median.
    pub far_worst_over_median: f64,
    /// Ground share: smallest, median, largest.
    pub ground_share: [f64; 3],
    /// Corridor false obstacles over corridor points, all frames pooled.
    pub corridor_false_obstacle_share: f64,
    /// Corridor points, and those labelled obstacle, all frames.
    pub corridor_points: [usize; 2],
    /// The worst frame's corridor false-obstacle share.
    pub corridor_false_obstacle_worst: f64,
    /// Flat-patch obstacles, all frames: mean and worst frame.
    pub flat_obstacle_share: [f64; 2],
    /// Lifted ground, all frames: mean and worst frame.
    pub lifted_ground_share: [f64; 2],
    /// Milliseconds per scan: median.
    pub ms_median: f64,
}

fn min_median_max(mut v: Vec<f64>) -> [f64; 3] {
    if v.is_empty() {
        return [0.0; 3];
    }
    v.sort_by(f64::total_cmp);
    [v[0], v[v.len() / 2], v[v.len() - 1]]
}

fn mean_max(v: impl Iterator<Item = f64>) -> [f64; 2] {
    let (mut n, mut sum, mut max) = (0.0, 0.0, 0.0f64);
    for x in v {
        n += 1.0;
        sum += x;
        max = max.max(x);
    }
    [sum / f64::max(n, 1.0), max]
}

impl Summary {
    /// Summarises `frames`.
    pub fn of(frames: &[FrameMeasure]) -> Self {
        let obstacle_share = min_median_max(frames.iter().map(|f| f.obstacle_share).collect());
        let ground_share = min_median_max(frames.iter().map(|f| f.ground_share).collect());
        let far_obstacle_share =
            min_median_max(frames.iter().map(|f| f.far_obstacle_share).collect());
        let ms = min_median_max(frames.iter().map(|f| f.ms).collect());
        let corridor: usize = frames.iter().map(|f| f.corridor_points).sum();
        let false_obstacle: usize = frames.iter().map(|f| f.corridor_false_obstacle).sum();
        Self {
            obstacle_share,
            worst_over_median: obstacle_share[2] / obstacle_share[1].max(1e-12),
            far_obstacle_share,
            far_worst_over_median: far_obstacle_share[2] / far_obstacle_share[1].max(1e-12),
            ground_share,
            corridor_false_obstacle_share: false_obstacle as f64 / corridor.max(1) as f64,
            corridor_points: [corridor, frames.iter().map(|f| f.corridor_obstacle).sum()],
            corridor_false_obstacle_worst: frames
                .iter()
                .map(|f| f.corridor_false_obstacle_share)
                .fold(0.0, f64::max),
            flat_obstacle_share: mean_max(frames.iter().map(|f| f.flat_obstacle_share)),
            lifted_ground_share: mean_max(frames.iter().map(|f| f.lifted_ground_share)),
            ms_median: ms[1],
        }
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let pct = |v: [f64; 3]| {
            format!(
                "{:.1}/{:.1}/{:.1}%",
                100.0 * v[0],
                100.0 * v[1],
                100.0 * v[2]
            )
        };
        write!(
            f,
            "obstacle min/med/max {} (worst {:.2}x median; beyond 5 m {}, {:.2}x), ground {}, corridor {}/{} obstacle, false obstacles {:.3}% (worst frame {:.3}%), flat obstacles {:.2}% (worst {:.2}%), lifted ground {:.2}% (worst {:.2}%), {:.2} ms",
            pct(self.obstacle_share),
            self.worst_over_median,
            pct(self.far_obstacle_share),
            self.far_worst_over_median,
            pct(self.ground_share),
            self.corridor_points[1],
            self.corridor_points[0],
            100.0 * self.corridor_false_obstacle_share,
            100.0 * self.corridor_false_obstacle_worst,
            100.0 * self.flat_obstacle_share[0],
            100.0 * self.flat_obstacle_share[1],
            100.0 * self.lifted_ground_share[0],
            100.0 * self.lifted_ground_share[1],
            self.ms_median
        )
    }
}
