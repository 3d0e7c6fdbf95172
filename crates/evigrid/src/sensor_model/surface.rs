//! Returns placed by the surface they lie on (`[motion] placed_by_surface`).
//!
//! A return lies on the visible surface of an object; issue 30's truth calls a cell the
//! object's when the object covers the cell's centre. Moving a return along its own ray finds
//! the cell behind it, which is right for a face square to the ray; a face seen at a slant (a
//! car's side) covers cell centres beside each return's ray, and the push misses some and
//! overshoots into others. Here the surface is drawn through the nearest returns of fine
//! sectors of [`SECTOR_RAD`]: a ray meets the segment between the returns either side of its
//! bearing (within [`NEIGHBOUR_SECTORS`], joined when at most [`JOIN_M`] apart), or, past the
//! last return of a surface, a face square to it within half a ray spacing. Each cell around a
//! return is occupied when its centre lies behind the surface its own ray meets, and at most
//! `surface_depth_cells` from it, measured square to the surface (a cell holding a point of
//! the surface has its centre within half a diagonal of it; deeper cells are the object's body
//! in the shadow of its face).

use crate::window::Window;

/// Two neighbouring returns this close, metres, lie on one surface: a car's side seen at a
/// slant, its returns 0.55° apart, stays one surface down to 9° from the ray at 25 m. Chosen
/// on the tuning drives among 1, 2 and 3 m (`docs/motion.md`, "Returns placed by the
/// surface").
pub(super) const JOIN_M: f64 = 2.0;

/// Width of the fine sectors whose nearest returns draw the surface, radians (0.1°): finer
/// than the rays of the scanners in use, so that neighbouring rays keep their own returns.
pub(super) const SECTOR_RAD: f64 = 0.1 * std::f64::consts::PI / 180.0;

/// How many fine sectors on a neighbouring return is looked for: 1.2°, a little more than
/// twice the planar scanner's 0.55° between rays (one ray may be lost).
pub(super) const NEIGHBOUR_SECTORS: usize = 12;

/// Number of fine sectors around the sensor.
pub(super) fn sector_count() -> usize {
    (std::f64::consts::TAU / SECTOR_RAD).round() as usize
}

/// Fine sector of a levelled position by its bearing, measured from −π, of `sectors`.
#[inline]
pub(super) fn sector_of(xy: [f64; 2], sectors: usize) -> usize {
    use super::classify::{bearing, fine_sector_at};
    fine_sector_at(bearing([xy[0], xy[1], 0.0]), sectors)
}

/// 2-D cross product.
#[inline]
fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// The corner where the face through `a2` and `a` meets the face through `b` and `b2`
/// (sensor-relative, metres; `a` and `b` neighbouring returns, `a2` and `b2` the next ones
/// beyond them), when it is convex as seen from the sensor: it lies between the rays of `a`
/// and `b`, on the sensor's side of the segment between them and at most half that segment's
/// length from it (a right-angled corner seen square to its diagonal, the most a rectangle's
/// corner stands out). `None` otherwise: the faces run on in line, or meet behind the segment
/// (a concave corner, where the segment is in front of the true surface anyway).
fn convex_corner(a2: [f64; 2], a: [f64; 2], b: [f64; 2], b2: [f64; 2]) -> Option<[f64; 2]> {
    let (da, db) = ([a[0] - a2[0], a[1] - a2[1]], [b2[0] - b[0], b2[1] - b[1]]);
    let den = cross(da, db);
    if den.abs() <= 1e-12 {
        return None;
    }
    let ab = [b[0] - a[0], b[1] - a[1]];
    // a + t·da = b + s·db → t = cross(b − a, db) / cross(da, db).
    let t = cross(ab, db) / den;
    let c = [a[0] + t * da[0], a[1] + t * da[1]];
    let length = ab[0].hypot(ab[1]);
    let turn = cross(a, b);
    let between = cross(a, c) * turn > 0.0 && cross(c, b) * turn > 0.0;
    // Signed distance from the segment, positive on the sensor's side.
    let side = cross(ab, [-a[0], -a[1]]).signum();
    let standing_out = cross(ab, [c[0] - a[0], c[1] - a[1]]) * side / length.max(1e-12);
    (t.is_finite() && between && standing_out > 0.0 && standing_out <= 0.5 * length).then_some(c)
}

/// Where the ray from the sensor along the unit direction `u` meets the line through `a` and
/// `b` (sensor-relative, metres): its range, and |u · n| for n the line's unit normal (a step
/// Δr along the ray behind the line is Δr·|u · n| from it); `None` when the ray runs along
/// the line or meets it behind the sensor.
#[inline]
fn meet_line(a: [f64; 2], b: [f64; 2], u: [f64; 2]) -> Option<(f64, f64)> {
    let ab = [b[0] - a[0], b[1] - a[1]];
    let den = cross(u, ab);
    let length = ab[0].hypot(ab[1]);
    if den.abs() <= 1e-12 || length <= 0.0 {
        return None;
    }
    let range = cross(a, b) / den;
    (range.is_finite() && range > 0.0).then(|| (range, den.abs() / length))
}

/// The surface a ray from the sensor along the unit direction `u` meets: the segment between
/// the nearest returns of the fine sectors on either side of its bearing (within `span`
/// sectors, `nearest_range` ∞ where a sector has none) when they are at most `join_m` apart,
/// else, within `half_width_rad` of the nearer of them, a surface square to the ray through
/// it, where that return's surface goes on behind something nearer: the return on the ray's
/// other side is nearer than it. At a silhouette (the return on the other side farther, or
/// none) the neighbouring ray went past the object, so nothing says the object reaches
/// behind its last return along this ray: no surface there, unless `silhouette_faces` (the
/// rule before issue 30's object work). With `convex_corners`, where the returns beyond the
/// two either side (within `span` sectors and `join_m`) draw two faces that meet in a convex
/// corner in front of the segment ([`convex_corner`]), the surface between the two returns is
/// those two faces up to the corner, not the segment that cuts it. Its range along `u` and
/// |u · n| as in [`meet_line`]; `None` where no surface is met.
pub(super) fn surface_at(
    u: [f64; 2],
    nearest_range: &[f64],
    nearest_xy: &[[f64; 2]],
    span: usize,
    join_m: f64,
    half_width_rad: f64,
    rules: Rules,
) -> Option<(f64, f64)> {
    let Rules {
        silhouette_faces,
        convex_corners,
    } = rules;
    let sectors = nearest_range.len();
    if sectors == 0 {
        return None;
    }
    let at = sector_of(u, sectors);
    let reach = span.min(sectors / 2);
    let (mut left, mut right) = (None, None);
    for k in 0..=reach {
        let (l, r) = ((at + sectors - k) % sectors, (at + k) % sectors);
        if left.is_none() && nearest_range[l].is_finite() && cross(nearest_xy[l], u) >= 0.0 {
            left = Some((nearest_xy[l], k));
        }
        if right.is_none() && nearest_range[r].is_finite() && cross(nearest_xy[r], u) < 0.0 {
            right = Some((nearest_xy[r], k));
        }
    }
    if let (Some((a, ka)), Some((b, kb))) = (left, right)
        && (b[0] - a[0]).hypot(b[1] - a[1]) <= join_m
    {
        if convex_corners {
            // The next return beyond each of the two, within `span` sectors of it and
            // `join_m` of it: the faces `a` and `b` lie on.
            let beyond = |from: usize, step_left: bool, p: [f64; 2]| {
                (1..=reach).find_map(|k| {
                    let s = if step_left {
                        (from + 2 * sectors - k) % sectors
                    } else {
                        (from + k) % sectors
                    };
                    let q = nearest_xy[s];
                    (nearest_range[s].is_finite() && (q[0] - p[0]).hypot(q[1] - p[1]) <= join_m)
                        .then_some(q)
                })
            };
            let (sa, sb) = ((at + sectors - ka) % sectors, (at + kb) % sectors);
            if let (Some(a2), Some(b2)) = (beyond(sa, true, a), beyond(sb, false, b))
                && let Some(c) = convex_corner(a2, a, b, b2)
            {
                // The ray meets the face of the side of the corner it passes on.
                return if cross(c, u) >= 0.0 {
                    meet_line(c, b, u)
                } else {
                    meet_line(a, c, u)
                };
            }
        }
        return meet_line(a, b, u);
    }
    // The end of a surface: within half a ray's spacing of its last return, where the
    // surface goes on behind a nearer return on the ray's other side.
    let (left, right) = (left.map(|(p, _)| p), right.map(|(p, _)| p));
    let max_sin = half_width_rad.sin();
    let range_of = |p: Option<[f64; 2]>| p.map_or(f64::INFINITY, |p| p[0].hypot(p[1]));
    [(left, range_of(right)), (right, range_of(left))]
        .into_iter()
        .filter_map(|(p, other_range)| {
            p.filter(|p| silhouette_faces || other_range < p[0].hypot(p[1]))
        })
        .filter_map(|p| {
            let range = p[0].hypot(p[1]);
            let cos = (p[0] * u[0] + p[1] * u[1]) / range;
            let sin = cross(p, u).abs() / range;
            (range > 0.0 && cos > 0.0 && sin <= max_sin).then(|| (sin, range / cos, cos))
        })
        .min_by(|x, y| x.0.total_cmp(&y.0))
        .map(|(_, range, cos)| (range, cos))
}

/// Which of the optional rules [`surface_at`] follows.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Rules {
    /// Past a silhouette's last return, a face square to the ray.
    pub(super) silhouette_faces: bool,
    /// Between two returns on two faces of a convex corner, the faces up to the corner.
    pub(super) convex_corners: bool,
}

/// Where a cell centre may lie around the surface its ray meets and still be occupied.
#[derive(Clone, Copy, Debug)]
pub(super) struct Band {
    /// At most this far behind the surface, square to it, metres.
    pub(super) depth_m: f64,
    /// At most this far in front of it: (metres, radians), the tolerance at range r being
    /// √(m² + (r·rad)²).
    pub(super) pose_tolerance: (f64, f64),
    /// Past a silhouette's last return, a face square to the ray too ([`surface_at`]).
    pub(super) silhouette_faces: bool,
    /// Between two returns on two faces of a convex corner, the faces up to the corner
    /// ([`surface_at`]).
    pub(super) convex_corners: bool,
}

/// Calls `visit` with the storage index of every cell around a fine sector's nearest return
/// (its cell and the eight around it) whose centre lies behind the surface its own ray meets
/// ([`surface_at`], the ray from `origin_m`, the sensor, world metres), at most `depth_m` from
/// it, square to the surface, or in front of it by no more than the pose's error allows:
/// `pose_tolerance` is (metres, radians), the tolerance at range r being their combination
/// √(m² + (r·rad)²) (both in `band`). `nearest_range` is each fine sector's nearest obstacle
/// range (∞: none), `nearest_xy` that return's position relative to the sensor;
/// `half_width_rad` half the scanner's angle between rays. Each cell is visited at most
/// once.
pub(super) fn for_each_cell_behind(
    nearest_range: &[f64],
    nearest_xy: &[[f64; 2]],
    half_width_rad: f64,
    window: &Window,
    origin_m: (f64, f64),
    band: Band,
    mut visit: impl FnMut(usize),
) {
    let cell_size_m = window.cell_size_m();
    let Band {
        depth_m,
        pose_tolerance,
        silhouette_faces,
        convex_corners,
    } = band;
    // Whether a cell is visited depends on the cell alone (its centre's ray and range), and
    // neighbouring fine sectors' returns mostly share their cells: each cell is judged once.
    let mut judged = CellSet::new(window.len());
    for (&range, &a) in nearest_range.iter().zip(nearest_xy) {
        if !range.is_finite() {
            continue;
        }
        let col = ((origin_m.0 + a[0]) / cell_size_m).floor() as i64;
        let row = ((origin_m.1 + a[1]) / cell_size_m).floor() as i64;
        for dr in -1..=1 {
            for dc in -1..=1 {
                let (c, r) = (col + dc, row + dr);
                let Some(idx) = window.storage_index(c, r) else {
                    continue;
                };
                if !judged.insert(idx) {
                    continue;
                }
                let centre = [
                    (c as f64 + 0.5) * cell_size_m - origin_m.0,
                    (r as f64 + 0.5) * cell_size_m - origin_m.1,
                ];
                let range_c = centre[0].hypot(centre[1]);
                if range_c <= 0.0 {
                    continue;
                }
                let u = [centre[0] / range_c, centre[1] / range_c];
                let Some((range_s, square)) = surface_at(
                    u,
                    nearest_range,
                    nearest_xy,
                    NEIGHBOUR_SECTORS,
                    JOIN_M,
                    half_width_rad,
                    Rules {
                        silhouette_faces,
                        convex_corners,
                    },
                ) else {
                    continue;
                };
                let tolerance_m = pose_tolerance.0.hypot(range_c * pose_tolerance.1);
                let behind = (range_c - range_s) * square;
                if behind >= -tolerance_m && behind <= depth_m {
                    visit(idx);
                }
            }
        }
    }
}

/// A set of storage indices below a fixed bound, one bit each.
struct CellSet {
    words: Vec<u64>,
}

impl CellSet {
    /// An empty set of indices below `len`.
    fn new(len: usize) -> Self {
        Self {
            words: vec![0; len.div_ceil(64)],
        }
    }

    /// Adds `idx`; whether it was not in the set yet.
    #[inline]
    fn insert(&mut self, idx: usize) -> bool {
        let (word, bit) = (idx / 64, 1u64 << (idx % 64));
        let fresh = self.words[word] & bit == 0;
        self.words[word] |= bit;
        fresh
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn faces(silhouette_faces: bool) -> Rules {
        Rules {
            silhouette_faces,
            convex_corners: false,
        }
    }

    fn unit(deg: f64) -> [f64; 2] {
        let (s, c) = deg.to_radians().sin_cos();
        [c, s]
    }

    /// The fine-sector table of these returns (nearest per sector).
    fn table(returns: &[[f64; 2]]) -> (Vec<f64>, Vec<[f64; 2]>) {
        let n = sector_count();
        let (mut range, mut xy) = (vec![f64::INFINITY; n], vec![[0.0; 2]; n]);
        for &p in returns {
            let s = sector_of(p, n);
            let r = p[0].hypot(p[1]);
            if r < range[s] {
                (range[s], xy[s]) = (r, p);
            }
        }
        (range, xy)
    }

    #[test]
    fn a_ray_between_two_returns_meets_the_segment_between_them() {
        // Returns at (10, −0.1) and (10, 0.1), 1.15° apart: the ray at 0° meets x = 10 at
        // 10 m, square (|u · n| = 1); the ray at 0.5° at 10/cos 0.5° = 10.00038 m.
        let (range, xy) = table(&[[10.0, -0.1], [10.0, 0.1]]);
        let (r, square) =
            surface_at(unit(0.0), &range, &xy, 12, 1.0, 0.005, faces(true)).unwrap_or_default();
        assert!(
            (r - 10.0).abs() < 1e-9 && (square - 1.0).abs() < 1e-9,
            "{r} {square}"
        );
        // A slanted side from (10, 0) to (10.1, 0.1), on y = x − 10, 0.57° apart: the ray at
        // 0.3° meets it where x·tan 0.3° = x − 10, x = 10/(1 − tan 0.3°) = 10.05263, range
        // 10.05263/cos 0.3° = 10.05277; its normal is (1, −1)/√2, |u · n| = (cos 0.3° −
        // sin 0.3°)/√2 = 0.70340.
        let (range, xy) = table(&[[10.0, 0.0], [10.1, 0.1]]);
        let (r, square) =
            surface_at(unit(0.3), &range, &xy, 12, 1.0, 0.005, faces(true)).unwrap_or_default();
        assert!((r - 10.05277).abs() < 1e-4, "{r}");
        assert!((square - 0.70340).abs() < 1e-4, "{square}");
        // The same two returns 1.5 m apart are not joined (join 1 m): (10, 0) and (11.06,
        // 1.06) are 1.5 m apart and 5.2° apart: the ray at 0.3° meets no surface.
        let (range, xy) = table(&[[10.0, 0.0], [11.06, 1.06]]);
        assert_eq!(
            surface_at(unit(0.3), &range, &xy, 60, 1.0, 0.005, faces(true)),
            None
        );
    }

    #[test]
    fn past_the_last_return_the_surface_reaches_half_a_ray_spacing() {
        // A return at (10, 0) alone, half-width 0.25°: at 0.2° the surface is square to the
        // ray, 10/cos 0.2°; at 0.3° there is none.
        let (range, xy) = table(&[[10.0, 0.0]]);
        let half = 0.25f64.to_radians();
        let (r, square) =
            surface_at(unit(0.2), &range, &xy, 12, 1.0, half, faces(true)).unwrap_or_default();
        assert!((r - 10.0 / 0.2f64.to_radians().cos()).abs() < 1e-9, "{r}");
        assert!(
            (square - 0.2f64.to_radians().cos()).abs() < 1e-9,
            "{square}"
        );
        assert_eq!(
            surface_at(unit(0.3), &range, &xy, 12, 1.0, half, faces(true)),
            None
        );
    }

    #[test]
    fn past_a_silhouette_no_surface_past_an_occluded_end_a_face() {
        // The last return of a surface at (10, 0); the ray at 0.2°, within the 0.25°
        // half-width. Beyond it, at 0.6°, a return at 15 m: the ray there went past the
        // surface (a silhouette): no surface at 0.2°, unless `silhouette_faces`, which gives
        // the face square to the ray, 10/cos 0.2°. With that return at 5 m instead, nearer,
        // the surface goes on behind it: the face either way (the 5 m return is 0.4° off,
        // outside the half-width, and more than 1 m from (10, 0): not joined).
        let half = 0.25f64.to_radians();
        let face = 10.0 / 0.2f64.to_radians().cos();
        let beyond = |r: f64| {
            let (s, c) = 0.6f64.to_radians().sin_cos();
            [r * c, r * s]
        };
        let (range, xy) = table(&[[10.0, 0.0], beyond(15.0)]);
        assert_eq!(
            surface_at(unit(0.2), &range, &xy, 12, 1.0, half, faces(false)),
            None
        );
        let (r, _) =
            surface_at(unit(0.2), &range, &xy, 12, 1.0, half, faces(true)).unwrap_or_default();
        assert!((r - face).abs() < 1e-9, "{r}");
        // Nothing beyond it at all: a silhouette too.
        let (range, xy) = table(&[[10.0, 0.0]]);
        assert_eq!(
            surface_at(unit(0.2), &range, &xy, 12, 1.0, half, faces(false)),
            None
        );
        let (range, xy) = table(&[[10.0, 0.0], beyond(5.0)]);
        for silhouette_faces in [false, true] {
            let (r, square) = surface_at(
                unit(0.2),
                &range,
                &xy,
                12,
                1.0,
                half,
                faces(silhouette_faces),
            )
            .unwrap_or_default();
            assert!((r - face).abs() < 1e-9, "{r}");
            assert!(
                (square - 0.2f64.to_radians().cos()).abs() < 1e-9,
                "{square}"
            );
        }
    }
    #[test]
    fn a_convex_corner_between_two_returns_is_met_at_its_faces() {
        // A car's corner at (10, 0) pointing at the sensor: returns (10.2, −0.4), (10.1, −0.2)
        // on one face, (10.1, 0.2), (10.2, 0.4) on the other (x = 10 + 0.5|y|). The segment
        // between (10.1, ∓0.2) is x = 10.1 and cuts the corner off; the faces meet at (10, 0),
        // 0.1 m in front of it (at most half the segment's 0.4 m).
        let corners = Rules {
            silhouette_faces: false,
            convex_corners: true,
        };
        let (range, xy) = table(&[[10.2, -0.4], [10.1, -0.2], [10.1, 0.2], [10.2, 0.4]]);
        // The ray at 0° meets the corner at 10 m, the face's normal (2, ±1)/√5: |u · n| =
        // 2/√5 = 0.894427; without the rule, the segment at 10.1 m, square.
        let (r, square) =
            surface_at(unit(0.0), &range, &xy, 60, 1.0, 0.005, corners).unwrap_or_default();
        assert!((r - 10.0).abs() < 1e-9, "{r}");
        assert!((square - 0.894427).abs() < 1e-6, "{square}");
        let (r, square) =
            surface_at(unit(0.0), &range, &xy, 60, 1.0, 0.005, faces(false)).unwrap_or_default();
        assert!(
            (r - 10.1).abs() < 1e-9 && (square - 1.0).abs() < 1e-9,
            "{r}"
        );
        // The ray at 0.5° meets the face x = 10 + 0.5 y where x = 10/(1 − 0.5 tan 0.5°) =
        // 10.043824, range 10.043824/cos 0.5° = 10.044208, |u · n| = (0.2 cos 0.5° − 0.1
        // sin 0.5°)/√0.05 = 0.890491 (the segment: 10.1/cos 0.5° = 10.100385).
        let (r, square) =
            surface_at(unit(0.5), &range, &xy, 60, 1.0, 0.005, corners).unwrap_or_default();
        assert!((r - 10.044208).abs() < 1e-6, "{r}");
        assert!((square - 0.890491).abs() < 1e-6, "{square}");
        // A straight face (the returns beyond in line, x = 10.1) and a concave corner (beyond
        // them at x = 10.0, the faces meeting behind the segment): the segment.
        for beyond_x in [10.1, 10.0] {
            let (range, xy) =
                table(&[[beyond_x, -0.4], [10.1, -0.2], [10.1, 0.2], [beyond_x, 0.4]]);
            let (r, _) =
                surface_at(unit(0.0), &range, &xy, 60, 1.0, 0.005, corners).unwrap_or_default();
            assert!((r - 10.1).abs() < 1e-9, "{beyond_x}: {r}");
        }
        // A corner standing out more than half the segment: faces x = 9.6 + 2.5|y| through
        // (10.1, ±0.2) and (10.6, ±0.4) meet 0.5 m in front of it, more than a right angle
        // allows (0.2 m): the segment.
        let (range, xy) = table(&[[10.6, -0.4], [10.1, -0.2], [10.1, 0.2], [10.6, 0.4]]);
        let (r, _) =
            surface_at(unit(0.0), &range, &xy, 60, 1.0, 0.005, corners).unwrap_or_default();
        assert!((r - 10.1).abs() < 1e-9, "{r}");
    }
}
