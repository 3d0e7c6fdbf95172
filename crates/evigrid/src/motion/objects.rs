//! The object layer (`[motion] object_layer`, `docs/motion.md`, "An object layer"): each
//! moving track whose heading is known gets an oriented rectangle fitted to its returns, and
//! its cells are labelled by their centres against it.
//!
//! The surface placement occupies a cell when its centre lies behind the surface the returns
//! draw; beside a car, across the rays, and in front of its corners, that places cells the car
//! covers only in part (truth free by the centre rule). A track's returns over several frames
//! tell more: the heading from its velocity (the faces' direction searched around it: the
//! returns' smallest box), and its length and width in its own frame, seen end-on one frame
//! and at a slant the next. Per track the layer keeps the extents observed
//! over the last [`EXTENT_FRAMES`] frames it was fitted in (the largest is the extent known:
//! it never grows beyond what was seen); per frame it anchors the rectangle on the faces the
//! sensor sees (the extreme returns towards the sensor along each axis) and reaches the known
//! extent away from the sensor. An axis whose extent is not known (under
//! [`MIN_KNOWN_EXTENT_M`], a car seen only from behind has no known length) is left open on
//! the far side: the placement's depth bounds it, unless no extent of 1 m is known on either
//! axis (a small road user: a pedestrian), which reaches `object_small_depth_m` beyond its
//! faces. The far sides drawn from an extent seen take `object_far_margin_m` of slack (the
//! largest extent seen is a lower bound). A track whose velocity's heading is not sure is
//! fitted with `object_fit_unsure_heading`, the faces' direction searched over every direction
//! of a box. The stage gives the track's placed cells inside the moving evidence, those
//! outside `object_outside_static` on Ω∖{M}.

use std::collections::HashMap;

use super::clusters::Clusters;

/// Frames of observed extents a track keeps.
pub(crate) const EXTENT_FRAMES: usize = 8;

/// An extent shorter than this, metres, is not known: the rectangle is open on the far side.
pub(crate) const MIN_KNOWN_EXTENT_M: f64 = 1.0;

/// The faces' direction of a track whose velocity's heading is not sure is searched this far,
/// degrees, either side of it: every direction of a box.
pub(crate) const UNSURE_SEARCH_DEG: f64 = 45.0;

/// A moving object's extent as the object layer fitted it this frame (world frame).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ObjectExtent {
    /// Centre of the rectangle, world metres (x east, y north). Along an axis whose extent is
    /// not known, the centre of the returns seen.
    pub centre_m: [f64; 2],
    /// Length along the heading, metres: the extent known (the largest seen in the last eight
    /// frames fitted), or the returns' extent this frame where it is not known (a small
    /// object's: `motion.object_small_depth_m` where that is larger).
    pub length_m: f32,
    /// Width across the heading, metres, likewise.
    pub width_m: f32,
    /// Heading, radians counter-clockwise from east: the faces' direction, within
    /// `motion.object_heading_fit_deg` of the velocity's (within 45° where the velocity's
    /// heading is not sure, `motion.object_fit_unsure_heading`).
    pub heading_rad: f32,
}

/// An oriented rectangle in the sensor-centred object frame: a point p is inside when its
/// coordinates u along the heading and w across it, from `origin`, lie in `along` and
/// `across` (either end may be infinite: an open side).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Rect {
    origin: [f64; 2],
    /// cos and sin of the heading.
    axis: [f64; 2],
    along: [f64; 2],
    across: [f64; 2],
}

impl Rect {
    /// Whether `p` (world metres) lies inside, the bounds included.
    pub(crate) fn contains(&self, p: [f64; 2]) -> bool {
        let [u, w] = to_object(p, self.origin, self.axis);
        (self.along[0]..=self.along[1]).contains(&u)
            && (self.across[0]..=self.across[1]).contains(&w)
    }
}

/// `p` in the frame of origin `origin` whose first axis is `axis` (cos, sin).
fn to_object(p: [f64; 2], origin: [f64; 2], axis: [f64; 2]) -> [f64; 2] {
    let (dx, dy) = (p[0] - origin[0], p[1] - origin[1]);
    [dx * axis[0] + dy * axis[1], -dx * axis[1] + dy * axis[0]]
}

/// What a track needs for a fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Motion {
    /// The track's identifier.
    pub(crate) id: u64,
    /// Its velocity east and north, m/s.
    pub(crate) velocity_mps: [f64; 2],
    /// √(σx² + σy²) of it, m/s.
    pub(crate) sigma_mps: f64,
}

/// The limits of a fit (from `[motion]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Limits {
    /// tan of `object_heading_max_deg`.
    pub(crate) heading_tan: f64,
    /// Half-width of the search for the faces' direction around the velocity's, whole
    /// degrees (`object_heading_fit_deg`; 0: the velocity's).
    pub(crate) heading_search_deg: f64,
    pub(crate) max_length_m: f64,
    pub(crate) max_width_m: f64,
    /// How far outside a cell centre still counts as inside, metres.
    pub(crate) margin_m: f64,
    /// A small object's depth beyond the faces seen, metres (`object_small_depth_m`; 0: open).
    pub(crate) small_depth_m: f64,
    /// Fit a track whose velocity's heading is not sure too, the faces' direction searched
    /// over [`UNSURE_SEARCH_DEG`] (`object_fit_unsure_heading`).
    pub(crate) fit_unsure: bool,
    /// How far beyond a far side (one not anchored on a face seen, or a silhouette's end) a
    /// cell centre still counts as inside, metres (`object_far_margin_m`).
    pub(crate) far_margin_m: f64,
}

/// One track's extents over the last frames it was fitted in (object frame, metres).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct ObjectState {
    along: [f64; EXTENT_FRAMES],
    across: [f64; EXTENT_FRAMES],
    /// Frames filled (at most `EXTENT_FRAMES`) and the next slot written.
    filled: usize,
    next: usize,
    last_s: f64,
}

impl ObjectState {
    fn push(&mut self, along: f64, across: f64, time_s: f64) {
        self.along[self.next] = along;
        self.across[self.next] = across;
        self.next = (self.next + 1) % EXTENT_FRAMES;
        self.filled = (self.filled + 1).min(EXTENT_FRAMES);
        self.last_s = time_s;
    }

    /// The largest extents seen (along, across).
    fn known(&self) -> [f64; 2] {
        let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
        [
            max(&self.along[..self.filled]),
            max(&self.across[..self.filled]),
        ]
    }
}

/// The extents kept per track.
#[derive(Clone, Debug, Default)]
pub(crate) struct Extents {
    states: HashMap<u64, ObjectState>,
}

/// The layer: per-track extents and this frame's returns by cluster. Buffers are kept.
#[derive(Clone, Debug, Default)]
pub(crate) struct ObjectLayer {
    extents: Extents,
    /// This frame's returns: storage index of the cell, world position.
    returns: Vec<(u32, [f64; 2])>,
    /// The returns in cluster order: cluster `k`'s are `sorted[starts[k]..starts[k + 1]]`.
    sorted: Vec<[f64; 2]>,
    starts: Vec<usize>,
}

impl ObjectLayer {
    /// Takes this frame's returns (storage index of the cell, world metres).
    pub(crate) fn set_returns(&mut self, returns: impl Iterator<Item = (usize, [f64; 2])>) {
        self.returns.clear();
        self.returns
            .extend(returns.filter_map(|(idx, p)| Some((u32::try_from(idx).ok()?, p))));
    }

    /// Groups this frame's returns by the cluster of their cell (a counting sort); returns
    /// outside every cluster are dropped. The returns are consumed.
    pub(crate) fn group(&mut self, clusters: &Clusters) {
        let n = clusters.len();
        self.starts.clear();
        self.starts.resize(n + 2, 0);
        for &(idx, _) in &self.returns {
            if let Some(k) = clusters.label_of(idx as usize) {
                self.starts[k as usize + 2] += 1;
            }
        }
        for k in 2..self.starts.len() {
            self.starts[k] += self.starts[k - 1];
        }
        // starts[k + 1] is now where cluster k begins; it is advanced as its returns land.
        self.sorted.clear();
        self.sorted.resize(self.starts[n + 1], [0.0; 2]);
        for &(idx, p) in &self.returns {
            if let Some(k) = clusters.label_of(idx as usize) {
                let slot = &mut self.starts[k as usize + 1];
                self.sorted[*slot] = p;
                *slot += 1;
            }
        }
        self.starts.pop();
        self.returns.clear();
    }

    /// Forgets the tracks not fitted since `before_s`.
    pub(crate) fn forget_before(&mut self, before_s: f64) {
        self.extents.forget_before(before_s);
    }

    /// Forgets everything.
    pub(crate) fn clear(&mut self) {
        self.extents.states.clear();
        self.returns.clear();
        self.sorted.clear();
        self.starts.clear();
    }

    /// [`Extents::fit`] to the returns of cluster `k` this frame.
    pub(crate) fn fit_cluster(
        &mut self,
        k: usize,
        track: Motion,
        sensor: [f64; 2],
        time_s: f64,
        limits: Limits,
    ) -> Option<(Rect, ObjectExtent)> {
        let returns = match (self.starts.get(k), self.starts.get(k + 1)) {
            (Some(&a), Some(&b)) if a <= b && b <= self.sorted.len() => &self.sorted[a..b],
            _ => &[],
        };
        self.extents.fit(track, returns, sensor, time_s, limits)
    }
}

impl Extents {
    /// Forgets the tracks not fitted since `before_s`.
    pub(crate) fn forget_before(&mut self, before_s: f64) {
        self.states.retain(|_, s| s.last_s >= before_s);
    }

    /// Tracks with extents kept.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.states.len()
    }

    /// Fits the rectangle of a track seen as `returns` (world metres) from `sensor` at
    /// `time_s`, and keeps its extents. `None`, and nothing kept, when its heading is not
    /// known (the velocity's σ over the speed above `limits.heading_tan`) unless
    /// `limits.fit_unsure`, it has fewer than two returns, or its returns span more than the
    /// largest object.
    pub(crate) fn fit(
        &mut self,
        track: Motion,
        returns: &[[f64; 2]],
        sensor: [f64; 2],
        time_s: f64,
        limits: Limits,
    ) -> Option<(Rect, ObjectExtent)> {
        let [vx, vy] = track.velocity_mps;
        let speed = vx.hypot(vy);
        let sure = speed > 0.0 && track.sigma_mps <= speed * limits.heading_tan;
        if !(sure || limits.fit_unsure) || returns.len() < 2 {
            return None;
        }
        let heading = if speed > 0.0 { vy.atan2(vx) } else { 0.0 };
        // The faces' direction: the smallest box of the returns within the search, whole
        // degrees from the velocity's heading (the nearest to it on a tie); a heading not
        // sure is searched over every direction of a box (±45°).
        let search = if sure {
            limits.heading_search_deg
        } else {
            UNSURE_SEARCH_DEG
        };
        let steps = search.max(0.0).floor() as i32;
        let (heading, lo, hi) = (0..=2 * steps)
            .map(|k| {
                let delta = if k % 2 == 1 { (k + 1) / 2 } else { -(k / 2) };
                let heading = heading + f64::from(delta).to_radians();
                let (lo, hi) = bounds(returns, sensor, heading);
                (heading, lo, hi)
            })
            .min_by(|a, b| {
                let area =
                    |(_, lo, hi): &(f64, [f64; 2], [f64; 2])| (hi[0] - lo[0]) * (hi[1] - lo[1]);
                area(a).total_cmp(&area(b))
            })?;
        let axis = [heading.cos(), heading.sin()];
        let seen = [hi[0] - lo[0], hi[1] - lo[1]];
        if !(seen[0] <= limits.max_length_m && seen[1] <= limits.max_width_m) {
            return None;
        }
        let state = self.states.entry(track.id).or_default();
        state.push(seen[0], seen[1], time_s);
        let known = state.known();
        // A small object (no extent known on either axis: a pedestrian) is closed at the
        // prior depth where it would be open.
        let small = known[0] < MIN_KNOWN_EXTENT_M && known[1] < MIN_KNOWN_EXTENT_M;
        let depth = (small && limits.small_depth_m > 0.0).then_some(limits.small_depth_m);
        let mut inside = [[0.0; 2]; 2];
        let mut reported = [[0.0; 2]; 2];
        for a in 0..2 {
            (inside[a], reported[a]) = interval(
                lo[a],
                hi[a],
                known[a],
                depth,
                limits.margin_m,
                limits.far_margin_m,
            );
        }
        let [u, w] = reported.map(|[l, h]| (l + h) / 2.0);
        let centre_m = [
            sensor[0] + u * axis[0] - w * axis[1],
            sensor[1] + u * axis[1] + w * axis[0],
        ];
        let rect = Rect {
            origin: sensor,
            axis,
            along: inside[0],
            across: inside[1],
        };
        let extent = ObjectExtent {
            centre_m,
            length_m: (reported[0][1] - reported[0][0]) as f32,
            width_m: (reported[1][1] - reported[1][0]) as f32,
            heading_rad: heading as f32,
        };
        Some((rect, extent))
    }
}

/// The returns' smallest and largest coordinates along and across `heading` (radians), from
/// `sensor`.
fn bounds(returns: &[[f64; 2]], sensor: [f64; 2], heading: f64) -> ([f64; 2], [f64; 2]) {
    let axis = [heading.cos(), heading.sin()];
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &p in returns {
        let q = to_object(p, sensor, axis);
        for a in 0..2 {
            lo[a] = lo[a].min(q[a]);
            hi[a] = hi[a].max(q[a]);
        }
    }
    (lo, hi)
}

/// One axis of the rectangle, the sensor at 0, the returns seen between `lo` and `hi`, the
/// extent known `known` (at least `hi − lo`): (the interval a cell centre must lie in, with
/// `margin` either side; the object's interval reported). Seen from below (0 < `lo`) the face
/// at `lo` is anchored and the object reaches the known extent beyond it; from above,
/// likewise from `hi`; from between, the faces are silhouettes and the returns' span is the
/// object's. A far side whose extent is not known (under [`MIN_KNOWN_EXTENT_M`]) is open in
/// the first interval (infinite) and the returns' span in the second; with `small_depth`
/// (a small object) it is that far beyond the face seen instead, in both.
fn interval(
    lo: f64,
    hi: f64,
    known: f64,
    small_depth: Option<f64>,
    margin: f64,
    far_margin: f64,
) -> ([f64; 2], [f64; 2]) {
    let mut extent = known.max(hi - lo);
    let mut open = extent < MIN_KNOWN_EXTENT_M;
    // The slack of a far side drawn from an extent seen (the largest seen is a lower bound);
    // none for a small object's prior depth.
    let mut slack = far_margin;
    if let (true, Some(depth)) = (open, small_depth) {
        (extent, open, slack) = (extent.max(depth), false, 0.0);
    }
    if lo > 0.0 {
        let far = lo + extent;
        let inside = [
            lo - margin,
            if open {
                f64::INFINITY
            } else {
                far + margin + slack
            },
        ];
        (inside, [lo, if open { hi } else { far }])
    } else if hi < 0.0 {
        let far = hi - extent;
        let inside = [
            if open {
                f64::NEG_INFINITY
            } else {
                far - margin - slack
            },
            hi + margin,
        ];
        (inside, [if open { lo } else { far }, hi])
    } else {
        // Both ends silhouettes.
        (
            [lo - margin - far_margin, hi + margin + far_margin],
            [lo, hi],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: Limits = Limits {
        heading_tan: 0.267_949_192_431_122_7, // tan 15°
        heading_search_deg: 0.0,
        max_length_m: 10.0,
        max_width_m: 3.0,
        margin_m: 0.0,
        small_depth_m: 0.0,
        fit_unsure: false,
        far_margin_m: 0.0,
    };

    fn east(id: u64) -> Motion {
        Motion {
            id,
            velocity_mps: [10.0, 0.0],
            sigma_mps: 0.5,
        }
    }

    #[test]
    fn a_car_seen_from_behind_is_anchored_on_its_rear_face_and_open_ahead() {
        // Driving east away from a sensor at the origin: its rear face x = 10, y from 4.1 to
        // 5.9. Along the heading the returns span 0 m: no length known, open ahead; across
        // they span 1.8 m (known), the sensor below (y 0 < 4.1): anchored at 4.1, 1.8 wide.
        let mut layer = Extents::default();
        let rear = [[10.0, 4.1], [10.0, 5.0], [10.0, 5.9]];
        let (rect, extent) = layer
            .fit(east(1), &rear, [0.0, 0.0], 0.0, LIMITS)
            .unwrap_or_else(|| panic!("fitted"));
        assert!(rect.contains([10.25, 4.25]));
        assert!(rect.contains([30.0, 5.75]), "open ahead");
        assert!(!rect.contains([9.75, 4.25]), "in front of the rear face");
        assert!(!rect.contains([10.25, 6.25]), "beside it");
        assert!(
            !rect.contains([10.25, 3.75]),
            "beside it, on the sensor's side"
        );
        assert_eq!(
            (extent.length_m, extent.width_m, extent.heading_rad),
            (0.0, 1.8_f32, 0.0)
        );
        assert!(
            (extent.centre_m[0] - 10.0).abs() < 1e-12 && (extent.centre_m[1] - 5.0).abs() < 1e-12
        );
    }

    #[test]
    fn a_length_seen_at_a_slant_is_kept_when_the_car_is_seen_end_on() {
        // Frame 0: its side y = 4.1 from x = 10 to 14.5 and its rear x = 10 (4.5 m long, 1.8
        // wide, the sensor at the origin, south-west of it). Frame 1, 0.1 s later, only the
        // rear face, now at x = 11: the rectangle reaches the 4.5 m seen before, to 15.5.
        let mut layer = Extents::default();
        let slant = [[10.0, 5.9], [10.0, 4.1], [12.0, 4.1], [14.5, 4.1]];
        let (rect, extent) = layer
            .fit(east(1), &slant, [0.0, 0.0], 0.0, LIMITS)
            .unwrap_or_else(|| panic!("fitted"));
        assert_eq!((extent.length_m, extent.width_m), (4.5, 1.8_f32));
        assert!(rect.contains([14.25, 5.75]) && !rect.contains([14.75, 4.25]));
        let rear = [[11.0, 4.1], [11.0, 5.9]];
        let (rect, extent) = layer
            .fit(east(1), &rear, [0.0, 0.0], 0.1, LIMITS)
            .unwrap_or_else(|| panic!("fitted"));
        assert_eq!((extent.length_m, extent.width_m), (4.5, 1.8_f32));
        assert!((extent.centre_m[0] - 13.25).abs() < 1e-12);
        assert!(rect.contains([15.25, 5.75]), "the length seen before");
        assert!(!rect.contains([15.75, 5.0]), "not beyond it");
        assert!(!rect.contains([10.75, 5.0]), "nor in front of the face");
    }

    #[test]
    fn an_extent_never_grows_beyond_what_was_seen() {
        // Two returns 2 m apart along the heading, then 3 m, then 1 m: the length known is
        // the largest seen, 3 m, never more; a span over the largest object (12 m) is not
        // fitted and not kept; once eight newer frames are kept the 3 m has left them.
        let mut layer = Extents::default();
        let sensor = [0.0, 0.0];
        let span = |l: f64| [[10.0, 5.0], [10.0 + l, 5.0]];
        let fit = |layer: &mut Extents, l: f64, t: f64| {
            layer
                .fit(east(1), &span(l), sensor, t, LIMITS)
                .map(|(_, e)| e.length_m)
        };
        assert_eq!(fit(&mut layer, 2.0, 0.0), Some(2.0));
        assert_eq!(fit(&mut layer, 3.0, 0.1), Some(3.0));
        assert_eq!(fit(&mut layer, 1.0, 0.2), Some(3.0));
        assert_eq!(fit(&mut layer, 12.0, 0.3), None);
        assert_eq!(fit(&mut layer, 1.0, 0.4), Some(3.0));
        // Kept now: 3, 1, 1 and five more frames of 1 m; the ninth frame drops the 3.
        for k in 0..5 {
            assert_eq!(fit(&mut layer, 1.0, 0.5 + 0.1 * k as f64), Some(3.0), "{k}");
        }
        assert_eq!(fit(&mut layer, 1.0, 1.0), Some(1.0));
        // A track not fitted for a while is forgotten; a new fit starts from its returns.
        layer.forget_before(5.0);
        assert_eq!(layer.len(), 0);
    }

    #[test]
    fn a_wall_joined_to_an_object_is_not_fitted() {
        // A car's rear face (x = 10, y 4.1 to 5.9) joined to the returns of a wall it passes
        // (y = 3.8 from x = 2 to 20): 18 m along the heading, over the largest object (10 m):
        // no rectangle, nothing kept (the wall keeps what the registration made of it).
        let mut extents = Extents::default();
        let mut returns = vec![[10.0, 4.1], [10.0, 5.9]];
        returns.extend((0..=18).map(|k| [2.0 + k as f64, 3.8]));
        assert!(
            extents
                .fit(east(1), &returns, [0.0; 2], 0.0, LIMITS)
                .is_none()
        );
        assert_eq!(extents.len(), 0);
    }

    #[test]
    fn the_faces_direction_is_searched_around_the_velocity() {
        // A car heading 5° north of east (its side from (10, 4) to 10 + 4.5·(cos 5°, sin 5°),
        // its rear face 1.8 m from (10, 4) at 95°), its velocity due east: with the search
        // (±8°) the smallest box of the returns is at 5°, 4.5 by 1.8 m (8.1 m²); without, at
        // 0°, the box is (4.5·cos 5° + 1.8·sin 5° = 4.6398) m by (1.8·cos 5° = 1.7932) m.
        let (c, s) = (5f64.to_radians().cos(), 5f64.to_radians().sin());
        let side: Vec<[f64; 2]> = (0..=9)
            .map(|k| [10.0 + 0.5 * k as f64 * c, 4.0 + 0.5 * k as f64 * s])
            .collect();
        let rear = [
            [10.0 - 1.8 * s, 4.0 + 1.8 * c],
            [10.0 - 0.9 * s, 4.0 + 0.9 * c],
        ];
        let returns: Vec<[f64; 2]> = side.into_iter().chain(rear).collect();
        let searched = Limits {
            heading_search_deg: 8.0,
            ..LIMITS
        };
        let (_, e) = Extents::default()
            .fit(east(1), &returns, [0.0; 2], 0.0, searched)
            .unwrap_or_else(|| panic!("fitted"));
        assert!((e.heading_rad - 5f32.to_radians()).abs() < 1e-5, "{e:?}");
        assert!(
            (e.length_m - 4.5).abs() < 1e-4 && (e.width_m - 1.8).abs() < 1e-4,
            "{e:?}"
        );
        let (_, e) = Extents::default()
            .fit(east(1), &returns, [0.0; 2], 0.0, LIMITS)
            .unwrap_or_else(|| panic!("fitted"));
        assert_eq!(e.heading_rad, 0.0);
        assert!(
            (f64::from(e.length_m) - (4.5 * c + 1.8 * s)).abs() < 1e-4,
            "{e:?}"
        );
        assert!((f64::from(e.width_m) - 1.8 * c).abs() < 1e-4, "{e:?}");
    }

    #[test]
    fn no_rectangle_without_a_known_heading() {
        // 10 ± 3 m/s: 3/10 = 0.3 > tan 15° = 0.268; 10 ± 2.5 fits. One return does not.
        let mut layer = Extents::default();
        let returns = [[10.0, 4.1], [10.0, 5.9]];
        let uncertain = Motion {
            sigma_mps: 3.0,
            ..east(1)
        };
        assert!(
            layer
                .fit(uncertain, &returns, [0.0; 2], 0.0, LIMITS)
                .is_none()
        );
        assert_eq!(layer.len(), 0);
        let known = Motion {
            sigma_mps: 2.5,
            ..east(1)
        };
        assert!(layer.fit(known, &returns, [0.0; 2], 0.0, LIMITS).is_some());
        assert!(
            layer
                .fit(known, &returns[..1], [0.0; 2], 0.0, LIMITS)
                .is_none()
        );
    }

    #[test]
    fn a_rotated_car_and_its_margin() {
        // Heading north (0, 10 m/s), the sensor at (0, 0), a car's rear face y = 10 from
        // x = 3 to 4.8, seen from below along the heading: the rear face anchored, open ahead
        // (no length); across (w = −x) the returns span −4.8 to −3, the sensor above (0 >
        // −3): anchored at w = −3 (x = 3), 1.8 wide. With a 0.1 m margin, a centre at x = 2.95
        // is in, at 2.85 out.
        let mut layer = Extents::default();
        let north = Motion {
            id: 2,
            velocity_mps: [0.0, 10.0],
            sigma_mps: 0.5,
        };
        let limits = Limits {
            margin_m: 0.1,
            ..LIMITS
        };
        let (rect, extent) = layer
            .fit(north, &[[3.0, 10.0], [4.8, 10.0]], [0.0; 2], 0.0, limits)
            .unwrap_or_else(|| panic!("fitted"));
        assert!(rect.contains([2.95, 12.0]) && !rect.contains([2.85, 12.0]));
        assert!(rect.contains([4.85, 10.0]) && !rect.contains([4.95, 10.0]));
        assert!(rect.contains([4.0, 9.95]) && !rect.contains([4.0, 9.85]));
        assert!((extent.heading_rad - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert!((extent.width_m - 1.8).abs() < 1e-6);
    }

    #[test]
    fn a_small_object_reaches_the_prior_depth_beyond_its_faces() {
        // A pedestrian walking east, seen from the origin: its front returns at x = 10, y 4.8
        // and 5.1. Along the heading they span 0 m, across 0.3 m: no extent of 1 m known on
        // either axis, a small object. Without the prior both far sides are open (a centre
        // at x = 10.75, 1.5 cells behind the face, is inside); with 0.6 m the object reaches
        // x = 10.6 along and y = 4.8 + 0.6 = 5.4 across (the face at 4.8, the sensor below).
        let returns = [[10.0, 4.8], [10.0, 5.1]];
        let walker = Motion {
            id: 3,
            velocity_mps: [1.5, 0.0],
            sigma_mps: 0.2,
        };
        let (open, _) = Extents::default()
            .fit(walker, &returns, [0.0; 2], 0.0, LIMITS)
            .unwrap_or_else(|| panic!("fitted"));
        assert!(open.contains([10.75, 5.25]) && open.contains([10.25, 5.75]));
        let small = Limits {
            small_depth_m: 0.6,
            ..LIMITS
        };
        let (rect, extent) = Extents::default()
            .fit(walker, &returns, [0.0; 2], 0.0, small)
            .unwrap_or_else(|| panic!("fitted"));
        assert!(rect.contains([10.25, 5.25]), "the cell of its returns");
        assert!(!rect.contains([10.75, 5.25]), "behind it along the heading");
        assert!(
            !rect.contains([10.25, 5.75]),
            "behind it across the heading"
        );
        assert!(!rect.contains([9.75, 5.25]), "in front of its face");
        assert!((extent.length_m - 0.6).abs() < 1e-6 && (extent.width_m - 0.6).abs() < 1e-6);
        assert!(
            (extent.centre_m[0] - 10.3).abs() < 1e-12 && (extent.centre_m[1] - 5.1).abs() < 1e-12
        );
    }

    #[test]
    fn a_car_seen_from_behind_is_not_a_small_object() {
        // The rear face of a car (x = 10, y 4.1 to 5.9: 1.8 m known across): not small, so
        // with the small object's depth set it stays open ahead, as without.
        let small = Limits {
            small_depth_m: 0.6,
            ..LIMITS
        };
        let mut layer = Extents::default();
        let rear = [[10.0, 4.1], [10.0, 5.0], [10.0, 5.9]];
        let (rect, _) = layer
            .fit(east(1), &rear, [0.0; 2], 0.0, small)
            .unwrap_or_else(|| panic!("fitted"));
        assert!(rect.contains([30.0, 5.75]), "open ahead");
        // Once 1.8 m has been seen, a frame that sees only 0.3 m of it (the rest hidden) is
        // still not small: the extent kept is 1.8 m.
        let (rect, extent) = layer
            .fit(east(1), &[[10.5, 4.1], [10.5, 4.4]], [0.0; 2], 0.1, small)
            .unwrap_or_else(|| panic!("fitted"));
        assert!(rect.contains([30.0, 5.75]), "open ahead");
        assert!((extent.width_m - 1.8).abs() < 1e-6);
    }

    #[test]
    fn an_l_of_a_car_at_30_degrees_gives_its_heading_and_extent_when_the_velocity_is_unsure() {
        // A 4.5 × 1.8 m car heading 30°, its corner at (10, 2): its side from the corner
        // along (cos 30°, sin 30°), 10 returns 0.5 m apart, and its rear face along
        // (−sin 30°, cos 30°), 7 returns 0.3 m apart. Its velocity says 1 m/s east, ± 3 m/s:
        // no heading from it (3 > tan 15°). With the unsure fit the faces' direction is
        // searched over ±45° of east: the smallest box is at 30°, 4.5 by 1.8 m (8.1 m²).
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let side = (0..=9).map(|k| [10.0 + 0.5 * k as f64 * c, 2.0 + 0.5 * k as f64 * s]);
        let rear = (1..=6).map(|k| [10.0 - 0.3 * k as f64 * s, 2.0 + 0.3 * k as f64 * c]);
        let returns: Vec<[f64; 2]> = side.chain(rear).collect();
        let unsure = Motion {
            id: 4,
            velocity_mps: [1.0, 0.0],
            sigma_mps: 3.0,
        };
        assert!(
            Extents::default()
                .fit(unsure, &returns, [0.0; 2], 0.0, LIMITS)
                .is_none()
        );
        let limits = Limits {
            fit_unsure: true,
            ..LIMITS
        };
        let (rect, e) = Extents::default()
            .fit(unsure, &returns, [0.0; 2], 0.0, limits)
            .unwrap_or_else(|| panic!("fitted"));
        assert!((e.heading_rad - 30f32.to_radians()).abs() < 1e-5, "{e:?}");
        assert!(
            (e.length_m - 4.5).abs() < 1e-4 && (e.width_m - 1.8).abs() < 1e-4,
            "{e:?}"
        );
        // Its centre: the corner + 2.25 along + 0.9 across.
        let centre = [10.0 + 2.25 * c - 0.9 * s, 2.0 + 2.25 * s + 0.9 * c];
        assert!(
            (e.centre_m[0] - centre[0]).abs() < 1e-9 && (e.centre_m[1] - centre[1]).abs() < 1e-9,
            "{e:?}"
        );
        assert!(rect.contains(centre));
        // 0.1 m beyond its side face: out.
        assert!(!rect.contains([10.0 + 2.0 * c + 0.1 * s, 2.0 + 2.0 * s - 0.1 * c]));
        // A standing object (no velocity at all) is fitted likewise.
        let standing = Motion {
            velocity_mps: [0.0, 0.0],
            ..unsure
        };
        let (_, e) = Extents::default()
            .fit(standing, &returns, [0.0; 2], 0.0, limits)
            .unwrap_or_else(|| panic!("fitted"));
        assert!((e.heading_rad - 30f32.to_radians()).abs() < 1e-5, "{e:?}");
    }

    #[test]
    fn the_far_margin_widens_only_the_sides_reached_by_the_extent_seen() {
        // The car of the slant test (rear face x = 10, side y = 4.1 from x = 10 to 14.5, rear
        // from y = 4.1 to 5.9; the sensor at the origin, below both): the faces seen are
        // x = 10 and y = 4.1, the far sides x = 14.5 and y = 5.9. With a far margin of
        // 0.15 m a centre at x = 14.6 or y = 6.0 is in, at 14.7 or 6.1 out; the faces seen
        // take no slack (x = 9.95, y = 4.05 out).
        let limits = Limits {
            far_margin_m: 0.15,
            ..LIMITS
        };
        let slant = [[10.0, 5.9], [10.0, 4.1], [12.0, 4.1], [14.5, 4.1]];
        let (rect, extent) = Extents::default()
            .fit(east(1), &slant, [0.0; 2], 0.0, limits)
            .unwrap_or_else(|| panic!("fitted"));
        assert_eq!(
            (extent.length_m, extent.width_m),
            (4.5, 1.8_f32),
            "reported unwidened"
        );
        assert!(rect.contains([14.6, 5.0]) && !rect.contains([14.7, 5.0]));
        assert!(rect.contains([12.0, 6.0]) && !rect.contains([12.0, 6.1]));
        assert!(!rect.contains([9.95, 5.0]) && !rect.contains([12.0, 4.05]));
        // Seen from between along the heading (the sensor at x = 12, beside the car), both
        // ends of its side are silhouettes: both widened.
        let (rect, _) = Extents::default()
            .fit(east(2), &slant, [12.0, 0.0], 0.0, limits)
            .unwrap_or_else(|| panic!("fitted"));
        assert!(rect.contains([9.9, 5.0]) && rect.contains([14.6, 5.0]));
        assert!(!rect.contains([9.8, 5.0]) && !rect.contains([14.7, 5.0]));
    }
}
