//! Planar geometry for the simulator: points, poses, footprints and exact ray intersections.
//!
//! Everything is in the map's local metric frame (x east, y north, metres) unless a name says
//! otherwise. Ray intersections return the ray parameter `t` in metres along a unit direction, so
//! the range of a return is `t` itself.

use serde::{Deserialize, Serialize};

/// A point or vector in the plane, metres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Vec2 {
    /// East (or sensor-forward in a sensor frame), metres.
    pub x: f64,
    /// North (or sensor-left in a sensor frame), metres.
    pub y: f64,
}

impl Vec2 {
    /// A point from its coordinates.
    pub const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }
    /// Unit vector at angle `angle_rad` from the x axis (counter-clockwise).
    pub fn from_angle(angle_rad: f64) -> Self {
        Self::new(angle_rad.cos(), angle_rad.sin())
    }
    /// Sum.
    pub fn plus(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y)
    }
    /// Difference `self − o`.
    pub fn minus(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y)
    }
    /// Scaled by `k`.
    pub fn scale(self, k: f64) -> Self {
        Self::new(self.x * k, self.y * k)
    }
    /// Dot product.
    pub fn dot(self, o: Self) -> f64 {
        self.x * o.x + self.y * o.y
    }
    /// z component of the cross product.
    pub fn cross(self, o: Self) -> f64 {
        self.x * o.y - self.y * o.x
    }
    /// Euclidean length.
    pub fn norm(self) -> f64 {
        self.x.hypot(self.y)
    }
    /// The vector turned by +90° (to the left of `self`).
    pub fn perp_left(self) -> Self {
        Self::new(-self.y, self.x)
    }
    /// Rotated counter-clockwise by `angle_rad`.
    pub fn rotated(self, angle_rad: f64) -> Self {
        let (s, c) = angle_rad.sin_cos();
        Self::new(c * self.x - s * self.y, s * self.x + c * self.y)
    }
}

/// A rigid planar transform `world_from_body`: position of the body origin in the world and the
/// heading of its x axis (radians, counter-clockwise from east).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose2 {
    /// Position of the body origin in the world frame, metres.
    pub position_m: Vec2,
    /// Heading of the body x axis, radians counter-clockwise from the world x axis.
    pub heading_rad: f64,
}

impl Pose2 {
    /// A pose from position and heading.
    pub const fn new(position_m: Vec2, heading_rad: f64) -> Self {
        Self {
            position_m,
            heading_rad,
        }
    }
    /// Maps a point in the body frame to the world frame.
    pub fn world_from_body(&self, point_in_body: Vec2) -> Vec2 {
        point_in_body
            .rotated(self.heading_rad)
            .plus(self.position_m)
    }
    /// Maps a point in the world frame to the body frame.
    pub fn body_from_world(&self, point_in_world: Vec2) -> Vec2 {
        point_in_world
            .minus(self.position_m)
            .rotated(-self.heading_rad)
    }
    /// Composition `self ∘ other`: the pose of a frame given relative to this body.
    pub fn compose(&self, body_from_child: &Pose2) -> Pose2 {
        Pose2::new(
            self.world_from_body(body_from_child.position_m),
            self.heading_rad + body_from_child.heading_rad,
        )
    }
}

/// The shape an actor occupies, in its own body frame (x forward).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Footprint {
    /// A disc of the given radius centred on the body origin.
    Circle {
        /// Radius, metres.
        radius_m: f64,
    },
    /// A rectangle centred on the body origin, `length` along body x, `width` along body y.
    Rect {
        /// Half of the length along body x, metres.
        half_length_m: f64,
        /// Half of the width along body y, metres.
        half_width_m: f64,
    },
}

impl Footprint {
    /// Radius of the smallest disc centred on the body origin that holds the footprint.
    pub fn bounding_radius_m(&self) -> f64 {
        match *self {
            Footprint::Circle { radius_m } => radius_m,
            Footprint::Rect {
                half_length_m,
                half_width_m,
            } => half_length_m.hypot(half_width_m),
        }
    }

    /// Whether a world point lies inside the footprint placed at `world_from_body`
    /// (boundary counts as inside).
    pub fn contains(&self, world_from_body: &Pose2, point_in_world: Vec2) -> bool {
        let p = world_from_body.body_from_world(point_in_world);
        match *self {
            Footprint::Circle { radius_m } => p.dot(p) <= radius_m * radius_m,
            Footprint::Rect {
                half_length_m,
                half_width_m,
            } => p.x.abs() <= half_length_m && p.y.abs() <= half_width_m,
        }
    }

    /// Whether this footprint placed at `world_from_body` and `other` placed at
    /// `world_from_other` share an area (touching does not count). Exact: discs by their
    /// distance, a disc against a rectangle's nearest point, two rectangles by separating axes.
    pub fn overlaps(
        &self,
        world_from_body: &Pose2,
        other: &Footprint,
        world_from_other: &Pose2,
    ) -> bool {
        match (*self, *other) {
            (Footprint::Circle { radius_m: a }, Footprint::Circle { radius_m: b }) => {
                let d = world_from_body
                    .position_m
                    .minus(world_from_other.position_m);
                d.dot(d) < (a + b) * (a + b)
            }
            (
                Footprint::Circle { radius_m },
                Footprint::Rect {
                    half_length_m,
                    half_width_m,
                },
            ) => {
                let c = world_from_other.body_from_world(world_from_body.position_m);
                let nearest = Vec2::new(
                    c.x.clamp(-half_length_m, half_length_m),
                    c.y.clamp(-half_width_m, half_width_m),
                );
                let d = c.minus(nearest);
                d.dot(d) < radius_m * radius_m
            }
            (Footprint::Rect { .. }, Footprint::Circle { .. }) => {
                other.overlaps(world_from_other, self, world_from_body)
            }
            (
                Footprint::Rect {
                    half_length_m: al,
                    half_width_m: aw,
                },
                Footprint::Rect {
                    half_length_m: bl,
                    half_width_m: bw,
                },
            ) => {
                let (ua, ub) = (
                    Vec2::from_angle(world_from_body.heading_rad),
                    Vec2::from_angle(world_from_other.heading_rad),
                );
                let (va, vb) = (ua.perp_left(), ub.perp_left());
                let between = world_from_other
                    .position_m
                    .minus(world_from_body.position_m);
                // Separated along an axis when the centres lie further apart along it than the
                // two half-extents projected on it.
                [ua, va, ub, vb].into_iter().all(|axis| {
                    let reach_a = al * ua.dot(axis).abs() + aw * va.dot(axis).abs();
                    let reach_b = bl * ub.dot(axis).abs() + bw * vb.dot(axis).abs();
                    between.dot(axis).abs() < reach_a + reach_b
                })
            }
        }
    }

    /// Whether the footprint placed at `world_from_body` and the axis-aligned rectangle
    /// `[min.x, max.x] × [min.y, max.y]` share an area (touching along an edge or at a corner
    /// does not count). Exact: a disc against the rectangle's nearest point, a rectangle by
    /// separating axes (the world's two and the footprint's two).
    pub fn overlaps_rect(&self, world_from_body: &Pose2, min: Vec2, max: Vec2) -> bool {
        let c = world_from_body.position_m;
        match *self {
            Footprint::Circle { radius_m } => {
                let nearest = Vec2::new(c.x.clamp(min.x, max.x), c.y.clamp(min.y, max.y));
                let d = c.minus(nearest);
                d.dot(d) < radius_m * radius_m
            }
            Footprint::Rect {
                half_length_m,
                half_width_m,
            } => {
                let u = Vec2::from_angle(world_from_body.heading_rad);
                let v = u.perp_left();
                let (hl, hw) = (half_length_m, half_width_m);
                // Half-extents of the footprint along the world axes.
                let ex = hl * u.x.abs() + hw * v.x.abs();
                let ey = hl * u.y.abs() + hw * v.y.abs();
                let separated =
                    |a_lo: f64, a_hi: f64, b_lo: f64, b_hi: f64| a_hi <= b_lo || b_hi <= a_lo;
                if separated(c.x - ex, c.x + ex, min.x, max.x)
                    || separated(c.y - ey, c.y + ey, min.y, max.y)
                {
                    return false;
                }
                // The rectangle's half-extent and centre along the footprint's own axes.
                let centre = Vec2::new((min.x + max.x) / 2.0, (min.y + max.y) / 2.0).minus(c);
                let (hx, hy) = ((max.x - min.x) / 2.0, (max.y - min.y) / 2.0);
                [(u, hl), (v, hw)].into_iter().all(|(axis, half)| {
                    let reach = hx * axis.x.abs() + hy * axis.y.abs();
                    let at = centre.dot(axis);
                    !separated(at - reach, at + reach, -half, half)
                })
            }
        }
    }

    /// Distance along a ray (unit `direction`) from `origin` to the first point of the footprint
    /// placed at `world_from_body`, if the ray hits it at `t > 0`. A ray starting inside reports
    /// no hit: a sensor inside an object sees nothing of that object.
    pub fn ray_hit(&self, world_from_body: &Pose2, origin: Vec2, direction: Vec2) -> Option<f64> {
        // Work in the body frame: the ray's length is preserved by the rotation.
        let o = world_from_body.body_from_world(origin);
        let d = direction.rotated(-world_from_body.heading_rad);
        match *self {
            Footprint::Circle { radius_m } => ray_circle(o, d, radius_m),
            Footprint::Rect {
                half_length_m,
                half_width_m,
            } => ray_centred_box(o, d, half_length_m, half_width_m),
        }
    }
}

/// Ray (`origin`, unit `direction`) against a disc of radius `radius_m` at the origin; the
/// entry distance when it is positive.
pub fn ray_circle(origin: Vec2, direction: Vec2, radius_m: f64) -> Option<f64> {
    // |o + t d|² = r²  ⇒  t² + 2 b t + c = 0 with b = o·d, c = |o|² − r².
    let b = origin.dot(direction);
    let c = origin.dot(origin) - radius_m * radius_m;
    if c <= 0.0 {
        return None;
    }
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    (t > 0.0).then_some(t)
}

/// Ray against the axis-aligned box [−hx, hx] × [−hy, hy] (slab method); the entry distance when
/// the origin is outside and the entry is ahead.
pub fn ray_centred_box(origin: Vec2, direction: Vec2, hx: f64, hy: f64) -> Option<f64> {
    if origin.x.abs() <= hx && origin.y.abs() <= hy {
        return None;
    }
    let mut t_enter = f64::NEG_INFINITY;
    let mut t_exit = f64::INFINITY;
    for (o, d, h) in [(origin.x, direction.x, hx), (origin.y, direction.y, hy)] {
        if d == 0.0 {
            if o.abs() > h {
                return None;
            }
        } else {
            let t1 = (-h - o) / d;
            let t2 = (h - o) / d;
            t_enter = t_enter.max(t1.min(t2));
            t_exit = t_exit.min(t1.max(t2));
        }
    }
    (t_enter <= t_exit && t_enter > 0.0).then_some(t_enter)
}

/// Ray against the segment `a`–`b`; the distance `t > 0` where they cross. Parallel rays never
/// hit (a grazing ray along a wall returns from the next wall instead).
pub fn ray_segment(origin: Vec2, direction: Vec2, a: Vec2, b: Vec2) -> Option<f64> {
    let e = b.minus(a);
    let denom = direction.cross(e);
    if denom == 0.0 {
        return None;
    }
    let ao = a.minus(origin);
    let t = ao.cross(e) / denom;
    let u = ao.cross(direction) / denom;
    (t > 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
}

/// Even–odd point-in-ring test (the ring may or may not repeat its first vertex).
pub fn ring_contains(ring: &[Vec2], p: Vec2) -> bool {
    let mut inside = false;
    let n = ring.len();
    if n < 3 {
        return false;
    }
    let mut j = n - 1;
    for i in 0..n {
        let (a, b) = (ring[i], ring[j]);
        if (a.y > p.y) != (b.y > p.y) {
            let x_cross = a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x);
            if p.x < x_cross {
                inside = !inside;
            }
        }
        j = i;
    }
    inside
}

/// Appends the x coordinates where the horizontal line at `y` crosses the edges of `rings`;
/// sorted pairs of them bound the inside (even–odd, so holes are respected). An edge counts
/// when one end is above `y` and the other at or below it, so a vertex on the line counts once.
pub fn ring_crossings<'a>(rings: impl IntoIterator<Item = &'a [Vec2]>, y: f64, out: &mut Vec<f64>) {
    for ring in rings {
        let n = ring.len();
        if n < 3 {
            continue;
        }
        let mut j = n - 1;
        for i in 0..n {
            let (a, b) = (ring[i], ring[j]);
            if (a.y > y) != (b.y > y) {
                out.push(a.x + (y - a.y) / (b.y - a.y) * (b.x - a.x));
            }
            j = i;
        }
    }
}

/// Wraps an angle to (−π, π].
pub fn wrap_angle(angle_rad: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut a = angle_rad % two_pi;
    if a <= -std::f64::consts::PI {
        a += two_pi;
    } else if a > std::f64::consts::PI {
        a -= two_pi;
    }
    a
}

/// A polyline with cumulative arc length, for moving along it by distance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Polyline {
    points: Vec<Vec2>,
    cumulative_m: Vec<f64>,
}

impl Polyline {
    /// Builds a polyline; consecutive duplicate points are dropped. `None` with fewer than two
    /// distinct points.
    pub fn new(points: Vec<Vec2>) -> Option<Self> {
        let mut kept: Vec<Vec2> = Vec::with_capacity(points.len());
        for p in points {
            if !(p.x.is_finite() && p.y.is_finite()) {
                return None;
            }
            if kept.last().is_none_or(|q| q.minus(p).norm() > 1e-9) {
                kept.push(p);
            }
        }
        if kept.len() < 2 {
            return None;
        }
        let mut cumulative_m = Vec::with_capacity(kept.len());
        let mut acc = 0.0;
        cumulative_m.push(0.0);
        for w in kept.windows(2) {
            acc += w[1].minus(w[0]).norm();
            cumulative_m.push(acc);
        }
        Some(Self {
            points: kept,
            cumulative_m,
        })
    }
    /// Vertices.
    pub fn points(&self) -> &[Vec2] {
        &self.points
    }
    /// Total length, metres.
    pub fn length_m(&self) -> f64 {
        self.cumulative_m.last().copied().unwrap_or(0.0)
    }
    /// Point and unit tangent at arc length `s_m` (clamped to the ends).
    pub fn at(&self, s_m: f64) -> (Vec2, Vec2) {
        let s = s_m.clamp(0.0, self.length_m());
        // Index of the segment holding s: last i with cumulative[i] <= s.
        let i = match self.cumulative_m.binary_search_by(|c| c.total_cmp(&s)) {
            Ok(i) => i,
            Err(i) => i.saturating_sub(1),
        }
        .min(self.points.len() - 2);
        let a = self.points[i];
        let b = self.points[i + 1];
        let seg = b.minus(a);
        let len = seg.norm();
        let tangent = if len > 0.0 {
            seg.scale(1.0 / len)
        } else {
            Vec2::new(1.0, 0.0)
        };
        let u = if len > 0.0 {
            (s - self.cumulative_m[i]) / len
        } else {
            0.0
        };
        (a.plus(seg.scale(u)), tangent)
    }
    /// The same path walked the other way.
    pub fn reversed(&self) -> Self {
        let mut pts = self.points.clone();
        pts.reverse();
        // Reversing a valid polyline keeps it valid.
        Self::new(pts).unwrap_or_else(|| self.clone())
    }
    /// The polyline shifted sideways by `offset_m` (positive to the left), vertex normals averaged
    /// at joints. Good for lanes and pavements along gently curving roads.
    pub fn offset(&self, offset_m: f64) -> Self {
        let n = self.points.len();
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let prev = if i > 0 {
                self.points[i - 1]
            } else {
                self.points[i]
            };
            let next = if i + 1 < n {
                self.points[i + 1]
            } else {
                self.points[i]
            };
            let t = next.minus(prev);
            let len = t.norm();
            let normal = if len > 0.0 {
                t.scale(1.0 / len).perp_left()
            } else {
                Vec2::default()
            };
            out.push(self.points[i].plus(normal.scale(offset_m)));
        }
        Self::new(out).unwrap_or_else(|| self.clone())
    }
}

/// A path a car can drive: a polyline whose corners are rounded by circular arcs, so that the
/// heading along it is continuous and turns at most `1 / min_radius_m` radians a metre.
///
/// Built once per lane ([`RoundedPath::new`]); [`RoundedPath::at`] then evaluates a line or an
/// arc exactly, with no densification. Each corner of deflection θ gets the arc of radius
/// `R = max(min_radius_m, apex_m / (sec(θ/2) − 1))`, the one passing `apex_m` inside the
/// corner (gentle bends get wide arcs, street corners the tightest turn), reduced where the
/// adjacent segments are too short to hold its tangent length `R·tan(θ/2)`, but never below
/// `min_radius_m`: a corner whose minimum tangent does not fit beside its neighbour's is taken
/// out of the polyline first (of the two, the one nearest the chord of its own neighbours).
#[derive(Clone, Debug, PartialEq)]
pub struct RoundedPath {
    pieces: Vec<Piece>,
    /// Arc length at the start of each piece, metres.
    start_m: Vec<f64>,
    length_m: f64,
}

/// One piece of a [`RoundedPath`].
#[derive(Clone, Copy, Debug, PartialEq)]
enum Piece {
    /// A straight stretch from `from` along the unit `direction`.
    Line {
        from: Vec2,
        direction: Vec2,
        length_m: f64,
    },
    /// An arc about `centre` starting at angle `start_rad` (of the start point seen from the
    /// centre), turning left when `left`, `length_m` long.
    Arc {
        centre: Vec2,
        radius_m: f64,
        start_rad: f64,
        left: bool,
        length_m: f64,
    },
}

impl Piece {
    fn length_m(&self) -> f64 {
        match *self {
            Piece::Line { length_m, .. } | Piece::Arc { length_m, .. } => length_m,
        }
    }

    /// Point and unit tangent `u_m` along the piece.
    fn at(&self, u_m: f64) -> (Vec2, Vec2) {
        match *self {
            Piece::Line {
                from, direction, ..
            } => (from.plus(direction.scale(u_m)), direction),
            Piece::Arc {
                centre,
                radius_m,
                start_rad,
                left,
                ..
            } => {
                let sign = if left { 1.0 } else { -1.0 };
                let radial = Vec2::from_angle(start_rad + sign * u_m / radius_m);
                (
                    centre.plus(radial.scale(radius_m)),
                    radial.perp_left().scale(sign),
                )
            }
        }
    }
}

/// A corner of a polyline about to be rounded: its deflection and the tangent lengths.
#[derive(Clone, Copy, Debug)]
struct Corner {
    /// Signed deflection, radians (positive turns left).
    turn_rad: f64,
    /// Tangent length of the tightest arc allowed, metres.
    min_tangent_m: f64,
    /// Tangent length of the preferred arc, metres.
    preferred_tangent_m: f64,
}

impl Corner {
    fn new(before: Vec2, at: Vec2, after: Vec2, min_radius_m: f64, apex_m: f64) -> Self {
        let (a, b) = (at.minus(before), after.minus(at));
        let turn_rad = a.cross(b).atan2(a.dot(b));
        let half = turn_rad.abs() / 2.0;
        if half < 1e-9 {
            return Self {
                turn_rad,
                min_tangent_m: 0.0,
                preferred_tangent_m: 0.0,
            };
        }
        // Beyond ~179.9° a corner is a reversal no arc rounds: no segment holds it, so it is
        // taken out of the path.
        if half > std::f64::consts::FRAC_PI_2 - 1e-3 {
            return Self {
                turn_rad,
                min_tangent_m: f64::INFINITY,
                preferred_tangent_m: f64::INFINITY,
            };
        }
        let preferred_radius_m = min_radius_m.max(apex_m / (1.0 / half.cos() - 1.0));
        Self {
            turn_rad,
            min_tangent_m: min_radius_m * half.tan(),
            preferred_tangent_m: preferred_radius_m * half.tan(),
        }
    }
}

impl RoundedPath {
    /// Rounds the corners of `line` with arcs of radius at least `min_radius_m` that pass
    /// `apex_m` inside the corner where the segments leave room (see [`RoundedPath`]). The ends
    /// stay where they are.
    pub fn new(line: &Polyline, min_radius_m: f64, apex_m: f64) -> Self {
        let mut points = line.points().to_vec();
        let corners = loop {
            let corners: Vec<Corner> = points
                .windows(3)
                .map(|w| Corner::new(w[0], w[1], w[2], min_radius_m, apex_m))
                .collect();
            match Self::crowded_corner(&points, &corners) {
                // Corner `k` is the polyline's vertex `k + 1`.
                Some(k) => {
                    points.remove(k + 1);
                    // A path that went there and back now has the same point twice.
                    points.dedup_by(|a, b| a.minus(*b).norm() <= 1e-9);
                }
                None => break corners,
            }
        };
        Self::from_corners(&points, &corners)
    }

    /// The index of a corner to take out because its minimum tangent and its neighbour's do
    /// not fit on the segment between them, if any.
    fn crowded_corner(points: &[Vec2], corners: &[Corner]) -> Option<usize> {
        let n = corners.len();
        // Segment j runs from vertex j to j + 1; corner k sits at vertex k + 1.
        for j in 0..points.len().saturating_sub(1) {
            let length = points[j + 1].minus(points[j]).norm();
            let before = j.checked_sub(1).filter(|&k| k < n);
            let after = Some(j).filter(|&k| k < n);
            let need: f64 = [before, after]
                .iter()
                .flatten()
                .map(|&k| corners[k].min_tangent_m)
                .sum();
            if need <= length {
                continue;
            }
            return match (before, after) {
                (Some(a), Some(b)) => {
                    // The one whose removal moves the path least.
                    let off_chord = |k: usize| {
                        let (p, q, r) = (points[k], points[k + 1], points[k + 2]);
                        let chord = r.minus(p);
                        let len = chord.norm();
                        if len > 0.0 {
                            (q.minus(p).cross(chord) / len).abs()
                        } else {
                            q.minus(p).norm()
                        }
                    };
                    Some(if off_chord(a) <= off_chord(b) { a } else { b })
                }
                (Some(k), None) | (None, Some(k)) => Some(k),
                (None, None) => None,
            };
        }
        None
    }

    /// The lines and arcs through `points` with their `corners` rounded; every corner's
    /// minimum tangent fits.
    fn from_corners(points: &[Vec2], corners: &[Corner]) -> Self {
        let n = corners.len();
        let seg = |j: usize| points[j + 1].minus(points[j]).norm();
        // What a corner may take of segment j: all of an end segment, else its minimum plus
        // half of what the two minimums leave.
        let share = |k: usize, j: usize| {
            let other = if j == k { j.checked_sub(1) } else { Some(j) };
            match other.filter(|&o| o < n) {
                None => seg(j),
                Some(o) => {
                    let slack = seg(j) - corners[k].min_tangent_m - corners[o].min_tangent_m;
                    corners[k].min_tangent_m + slack.max(0.0) / 2.0
                }
            }
        };
        let mut pieces = Vec::with_capacity(2 * n + 1);
        let mut from = points[0];
        for (k, corner) in corners.iter().enumerate() {
            let vertex = points[k + 1];
            let tangent_m = corner
                .preferred_tangent_m
                .min(share(k, k))
                .min(share(k, k + 1))
                .max(corner.min_tangent_m);
            let half = corner.turn_rad.abs() / 2.0;
            if tangent_m <= 0.0 || half.tan() <= 0.0 {
                Self::push_line(&mut pieces, from, vertex);
                from = vertex;
                continue;
            }
            let d_in = vertex.minus(points[k]).scale(1.0 / seg(k));
            let d_out = points[k + 2].minus(vertex).scale(1.0 / seg(k + 1));
            let enter = vertex.minus(d_in.scale(tangent_m));
            let radius_m = tangent_m / half.tan();
            let left = corner.turn_rad > 0.0;
            let side = if left { 1.0 } else { -1.0 };
            let centre = enter.plus(d_in.perp_left().scale(side * radius_m));
            let radial = enter.minus(centre);
            Self::push_line(&mut pieces, from, enter);
            pieces.push(Piece::Arc {
                centre,
                radius_m,
                start_rad: radial.y.atan2(radial.x),
                left,
                length_m: radius_m * corner.turn_rad.abs(),
            });
            from = vertex.plus(d_out.scale(tangent_m));
        }
        Self::push_line(&mut pieces, from, points[points.len() - 1]);
        if pieces.is_empty() {
            // A path back to where it started: it stays there.
            pieces.push(Piece::Line {
                from,
                direction: Vec2::new(1.0, 0.0),
                length_m: 0.0,
            });
        }
        let mut start_m = Vec::with_capacity(pieces.len());
        let mut length_m = 0.0;
        for piece in &pieces {
            start_m.push(length_m);
            length_m += piece.length_m();
        }
        Self {
            pieces,
            start_m,
            length_m,
        }
    }

    /// Appends the line `from`–`to` unless it has no length.
    fn push_line(pieces: &mut Vec<Piece>, from: Vec2, to: Vec2) {
        let d = to.minus(from);
        let length_m = d.norm();
        if length_m > 1e-9 {
            pieces.push(Piece::Line {
                from,
                direction: d.scale(1.0 / length_m),
                length_m,
            });
        }
    }

    /// Total length, metres.
    pub fn length_m(&self) -> f64 {
        self.length_m
    }

    /// Point and unit tangent at arc length `s_m` (clamped to the ends).
    pub fn at(&self, s_m: f64) -> (Vec2, Vec2) {
        let s = s_m.clamp(0.0, self.length_m);
        let i = match self.start_m.binary_search_by(|c| c.total_cmp(&s)) {
            Ok(i) => i,
            Err(i) => i.saturating_sub(1),
        };
        match self.pieces.get(i) {
            Some(piece) => piece.at((s - self.start_m[i]).min(piece.length_m())),
            // Never: a path has at least one piece.
            None => (Vec2::default(), Vec2::new(1.0, 0.0)),
        }
    }

    /// The arcs as (start, end along the path, radius), metres, in order.
    pub fn arcs(&self) -> impl Iterator<Item = (f64, f64, f64)> + '_ {
        self.pieces
            .iter()
            .zip(&self.start_m)
            .filter_map(|(piece, &start)| match *piece {
                Piece::Arc {
                    radius_m, length_m, ..
                } => Some((start, start + length_m, radius_m)),
                Piece::Line { .. } => None,
            })
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn footprints_overlap_each_other_exactly() {
        let v = Vec2::new;
        let car = Footprint::Rect {
            half_length_m: 2.0,
            half_width_m: 1.0,
        };
        let here = Pose2::new(v(0.0, 0.0), 0.0);
        // Side by side: 2.1 m apart clears two 1 m half-widths, 1.9 m does not.
        assert!(!car.overlaps(&here, &car, &Pose2::new(v(0.0, 2.1), 0.0)));
        assert!(car.overlaps(&here, &car, &Pose2::new(v(0.0, 1.9), 0.0)));
        // Across at 90°, its end 0.1 m into the first one's side; then 0.1 m short of it.
        let across = |y: f64| Pose2::new(v(0.0, y), std::f64::consts::FRAC_PI_2);
        assert!(car.overlaps(&here, &car, &across(2.9)));
        assert!(!car.overlaps(&here, &car, &across(3.1)));
        // A 4 × 0.2 m bar turned −45° across the corner (2, 1), on the line x + y = 4.2: the
        // boxes around the two overlap, but the bar's edge passes 0.75 m from the corner. Turned +45°
        // at (2.5, 1.5), its end (1.09, 0.09) is inside the car.
        let bar = Footprint::Rect {
            half_length_m: 2.0,
            half_width_m: 0.1,
        };
        let quarter = std::f64::consts::FRAC_PI_4;
        assert!(!car.overlaps(&here, &bar, &Pose2::new(v(2.6, 1.6), -quarter)));
        assert!(!bar.overlaps(&Pose2::new(v(2.6, 1.6), -quarter), &car, &here));
        assert!(car.overlaps(&here, &bar, &Pose2::new(v(2.5, 1.5), quarter)));
        // A disc against a rectangle's corner and against another disc; order does not matter.
        let disc = Footprint::Circle { radius_m: 0.5 };
        let off_corner = |d: f64| Pose2::new(v(2.0 + d, 1.0 + d), 0.0);
        assert!(disc.overlaps(&off_corner(0.3), &car, &here));
        assert!(car.overlaps(&here, &disc, &off_corner(0.3)));
        assert!(!disc.overlaps(&off_corner(0.4), &car, &here));
        assert!(disc.overlaps(&here, &disc, &Pose2::new(v(0.99, 0.0), 0.0)));
        assert!(!disc.overlaps(&here, &disc, &Pose2::new(v(1.0, 0.0), 0.0)));
    }

    #[test]
    fn footprints_overlap_rectangles_exactly() {
        let v = Vec2::new;
        let at_origin = Pose2::new(v(0.0, 0.0), 0.0);
        let car = Footprint::Rect {
            half_length_m: 2.0,
            half_width_m: 1.0,
        };
        // A sliver 0.1 m deep overlaps; an edge shared along x = 2 does not.
        assert!(car.overlaps_rect(&at_origin, v(1.9, 0.0), v(2.9, 1.0)));
        assert!(!car.overlaps_rect(&at_origin, v(2.0, 0.0), v(3.0, 1.0)));
        // Turned 45°, 2 × 0.2 m: a square on its diagonal overlaps; one off the diagonal, inside
        // its bounding box (±0.78 m) but 0.42 m from its axis, does not.
        let bar = Footprint::Rect {
            half_length_m: 1.0,
            half_width_m: 0.1,
        };
        let turned = Pose2::new(v(0.0, 0.0), std::f64::consts::FRAC_PI_4);
        assert!(bar.overlaps_rect(&turned, v(0.6, 0.6), v(1.0, 1.0)));
        assert!(!bar.overlaps_rect(&turned, v(0.3, -0.6), v(0.6, -0.3)));
        // A disc of 0.3 m: the square's corner at 0.283 m is inside, at 0.354 m is not.
        let disc = Footprint::Circle { radius_m: 0.3 };
        assert!(disc.overlaps_rect(&at_origin, v(0.2, 0.2), v(1.0, 1.0)));
        assert!(!disc.overlaps_rect(&at_origin, v(0.25, 0.25), v(1.0, 1.0)));
        // A square holding the whole disc.
        assert!(disc.overlaps_rect(&at_origin, v(-1.0, -1.0), v(1.0, 1.0)));
    }

    #[test]
    fn ring_crossings_respect_holes_and_count_a_vertex_on_the_line_once() {
        let square = |lo: f64, hi: f64| {
            vec![
                Vec2 { x: lo, y: lo },
                Vec2 { x: hi, y: lo },
                Vec2 { x: hi, y: hi },
                Vec2 { x: lo, y: hi },
            ]
        };
        let rings = [square(0.0, 10.0), square(4.0, 6.0)];
        let mut xs = Vec::new();
        // y = 5 crosses the outer ring at 0 and 10 and the hole at 4 and 6.
        ring_crossings(rings.iter().map(Vec::as_slice), 5.0, &mut xs);
        xs.sort_by(f64::total_cmp);
        assert_eq!(xs, [0.0, 4.0, 6.0, 10.0]);
        // y = 4 runs along the hole's lower edge: its vertical edges count once each.
        xs.clear();
        ring_crossings(rings.iter().map(Vec::as_slice), 4.0, &mut xs);
        xs.sort_by(f64::total_cmp);
        assert_eq!(xs, [0.0, 4.0, 6.0, 10.0]);
    }

    #[test]
    fn ray_hits_segment_at_exact_distance() {
        // Wall x = 5 from y = −1 to 1, ray from origin along +x: t = 5.
        let t = ray_segment(
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(5.0, -1.0),
            Vec2::new(5.0, 1.0),
        );
        assert_relative_eq!(t.unwrap(), 5.0);
        // Diagonal ray at 45° hits x = 5 at y = 5, outside the wall.
        let d = Vec2::from_angle(std::f64::consts::FRAC_PI_4);
        assert!(
            ray_segment(
                Vec2::default(),
                d,
                Vec2::new(5.0, -1.0),
                Vec2::new(5.0, 1.0)
            )
            .is_none()
        );
        // Behind the origin: no hit.
        assert!(
            ray_segment(
                Vec2::default(),
                Vec2::new(-1.0, 0.0),
                Vec2::new(5.0, -1.0),
                Vec2::new(5.0, 1.0)
            )
            .is_none()
        );
    }

    #[test]
    fn ray_hits_circle_at_entry() {
        // Disc radius 1 centred at (10, 0); ray along +x from origin enters at 9.
        let pose = Pose2::new(Vec2::new(10.0, 0.0), 0.3);
        let t = Footprint::Circle { radius_m: 1.0 }.ray_hit(
            &pose,
            Vec2::default(),
            Vec2::new(1.0, 0.0),
        );
        assert_relative_eq!(t.unwrap(), 9.0, epsilon = 1e-12);
        // Ray offset by y = 0.6: entry at 10 − sqrt(1 − 0.36) = 9.2.
        let t = Footprint::Circle { radius_m: 1.0 }.ray_hit(
            &pose,
            Vec2::new(0.0, 0.6),
            Vec2::new(1.0, 0.0),
        );
        assert_relative_eq!(t.unwrap(), 9.2, epsilon = 1e-12);
    }

    #[test]
    fn ray_hits_rotated_rectangle() {
        // 4 × 2 box rotated 90° at (10, 0): along x it spans 10 ± 1, so the entry is at 9.
        let pose = Pose2::new(Vec2::new(10.0, 0.0), std::f64::consts::FRAC_PI_2);
        let fp = Footprint::Rect {
            half_length_m: 2.0,
            half_width_m: 1.0,
        };
        let t = fp
            .ray_hit(&pose, Vec2::default(), Vec2::new(1.0, 0.0))
            .unwrap();
        assert_relative_eq!(t, 9.0, epsilon = 1e-12);
        assert!(fp.contains(&pose, Vec2::new(10.0, 1.9)));
        assert!(!fp.contains(&pose, Vec2::new(11.1, 0.0)));
    }

    #[test]
    fn ring_contains_uses_even_odd() {
        let sq = [
            Vec2::new(0.0, 0.0),
            Vec2::new(2.0, 0.0),
            Vec2::new(2.0, 2.0),
            Vec2::new(0.0, 2.0),
        ];
        assert!(ring_contains(&sq, Vec2::new(1.0, 1.0)));
        assert!(!ring_contains(&sq, Vec2::new(3.0, 1.0)));
    }

    #[test]
    fn polyline_walks_by_arc_length() {
        let pl = Polyline::new(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(3.0, 0.0),
            Vec2::new(3.0, 4.0),
        ])
        .unwrap();
        assert_relative_eq!(pl.length_m(), 7.0);
        let (p, t) = pl.at(5.0);
        assert_relative_eq!(p.x, 3.0);
        assert_relative_eq!(p.y, 2.0);
        assert_relative_eq!(t.y, 1.0);
        let left = pl.offset(1.0);
        assert_relative_eq!(left.points()[0].y, 1.0);
    }

    /// Walks `path` in steps of `step_m` and returns the largest heading change and the
    /// largest move of a step.
    fn largest_steps(path: &RoundedPath, step_m: f64) -> (f64, f64) {
        let n = (path.length_m() / step_m).floor() as usize;
        let (mut turn, mut moved): (f64, f64) = (0.0, 0.0);
        for k in 0..n {
            let (p, t) = path.at(k as f64 * step_m);
            let (q, u) = path.at((k + 1) as f64 * step_m);
            turn = turn.max(t.cross(u).atan2(t.dot(u)).abs());
            moved = moved.max(q.minus(p).norm());
        }
        (turn, moved)
    }

    #[test]
    fn a_right_angle_between_two_20_m_segments_is_a_5_m_arc() {
        let line = Polyline::new(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(20.0, 0.0),
            Vec2::new(20.0, 20.0),
        ])
        .unwrap();
        let path = RoundedPath::new(&line, 5.0, 1.0);
        // The arc passing 1 m inside a 90° corner would be R = 1 / (√2 − 1) = 2.41 m: below the
        // minimum, so R = 5 m, tangent length 5·tan 45° = 5 m: from (15, 0) to (20, 5) about
        // (15, 5), a quarter circle 7.854 m long between two 15 m lines.
        assert_eq!(path.arcs().collect::<Vec<_>>().len(), 1);
        let (start, end, radius) = path.arcs().next().unwrap();
        assert_relative_eq!(radius, 5.0, epsilon = 1e-12);
        assert_relative_eq!(start, 15.0, epsilon = 1e-12);
        assert_relative_eq!(end, 15.0 + 2.5 * std::f64::consts::PI, epsilon = 1e-12);
        assert_relative_eq!(
            path.length_m(),
            30.0 + 2.5 * std::f64::consts::PI,
            epsilon = 1e-12
        );
        // Halfway round: 5 m from the centre, at (15 + 5/√2, 5 − 5/√2), heading 45°, and
        // 5·(√2 − 1) = 2.071 m inside the corner.
        let (mid, tangent) = path.at((start + end) / 2.0);
        let centre = Vec2::new(15.0, 5.0);
        assert_relative_eq!(mid.minus(centre).norm(), 5.0, epsilon = 1e-12);
        assert_relative_eq!(mid.x, 15.0 + 5.0 / 2f64.sqrt(), epsilon = 1e-12);
        assert_relative_eq!(mid.y, 5.0 - 5.0 / 2f64.sqrt(), epsilon = 1e-12);
        assert_relative_eq!(tangent.y.atan2(tangent.x), std::f64::consts::FRAC_PI_4);
        assert_relative_eq!(
            mid.minus(Vec2::new(20.0, 0.0)).norm(),
            5.0 * (2f64.sqrt() - 1.0),
            epsilon = 1e-12
        );
        // The lines stay where they were, and the ends with them.
        let (p, t) = path.at(10.0);
        assert_eq!((p, t), (Vec2::new(10.0, 0.0), Vec2::new(1.0, 0.0)));
        let (p, t) = path.at(path.length_m());
        assert_relative_eq!(p.x, 20.0, epsilon = 1e-12);
        assert_relative_eq!(p.y, 20.0, epsilon = 1e-12);
        assert_relative_eq!(t.y, 1.0, epsilon = 1e-12);
        // At 8 m/s, 0.1 s a frame: a frame's step of 0.8 m turns the heading by at most
        // v·dt / R = 0.16 rad (9.2°), and does so on the arc; the polyline turned 90° at once.
        let (turn, moved) = largest_steps(&path, 0.8);
        assert_relative_eq!(turn, 0.8 / 5.0, epsilon = 1e-9);
        assert!(moved <= 0.8 + 1e-12, "{moved}");
    }

    #[test]
    fn a_gentle_bend_gets_the_arc_passing_its_apex_distance_inside() {
        // A 10° bend between two 100 m segments: R = 1 m / (sec 5° − 1) = 261.8 m, whose tangent
        // length 22.9 m fits, and whose middle lies 1 m from the corner.
        let bend = 10f64.to_radians();
        let line = Polyline::new(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(100.0, 0.0),
            Vec2::new(100.0, 0.0).plus(Vec2::from_angle(-bend).scale(100.0)),
        ])
        .unwrap();
        let path = RoundedPath::new(&line, 5.0, 1.0);
        let (start, end, radius) = path.arcs().next().unwrap();
        let expected = 1.0 / (1.0 / (bend / 2.0).cos() - 1.0);
        assert_relative_eq!(radius, expected, epsilon = 1e-9);
        assert_relative_eq!(radius, 261.8, epsilon = 0.05);
        assert_relative_eq!(start, 100.0 - radius * (bend / 2.0).tan(), epsilon = 1e-9);
        let mid = path.at((start + end) / 2.0).0;
        assert_relative_eq!(mid.minus(Vec2::new(100.0, 0.0)).norm(), 1.0, epsilon = 1e-9);
        // Turning right: the arc's middle lies below the corner.
        assert!(mid.y < 0.0);
    }

    #[test]
    fn crowded_corners_are_merged_so_no_turn_is_tighter_than_the_minimum() {
        let v = Vec2::new;
        for points in [
            // A 4 m jog: two 90° corners whose 5 m tangents cannot both fit on 4 m.
            vec![v(0.0, 0.0), v(20.0, 0.0), v(20.0, 4.0), v(40.0, 4.0)],
            // Three 45° corners 1 m apart, then a U-turn-like hairpin 30 m on.
            vec![
                v(0.0, 0.0),
                v(20.0, 0.0),
                v(20.7, 0.7),
                v(20.7, 1.7),
                v(50.0, 30.0),
                v(40.0, 40.0),
            ],
            // A short first segment before a right angle.
            vec![v(0.0, 0.0), v(2.0, 0.0), v(2.0, 30.0)],
            // There and back: no arc rounds a reversal, so the far end goes.
            vec![v(0.0, 0.0), v(20.0, 0.0), v(10.0, 0.0)],
        ] {
            let line = Polyline::new(points.clone()).unwrap();
            let path = RoundedPath::new(&line, 5.0, 1.0);
            assert!(path.arcs().all(|(_, _, r)| r >= 5.0 - 1e-9), "{points:?}");
            // Every 1 cm the heading turns at most 1 cm / 5 m and the point moves 1 cm.
            let (turn, moved) = largest_steps(&path, 0.01);
            assert!(turn <= 0.01 / 5.0 + 1e-9, "{points:?}: {turn}");
            assert!(moved <= 0.01 + 1e-9, "{points:?}: {moved}");
            // The ends stay.
            let last = *points.last().unwrap();
            assert!(path.at(0.0).0.minus(points[0]).norm() < 1e-9);
            assert!(path.at(path.length_m()).0.minus(last).norm() < 1e-9);
        }
        // The jog: the corner at (20, 0) goes (both lie 3.92 m off their chords), leaving one
        // 11.3° bend at (20, 4).
        let jog =
            Polyline::new(vec![v(0.0, 0.0), v(20.0, 0.0), v(20.0, 4.0), v(40.0, 4.0)]).unwrap();
        let arcs: Vec<_> = RoundedPath::new(&jog, 5.0, 1.0).arcs().collect();
        assert_eq!(arcs.len(), 1);
        let half = (4.0f64 / 20.0).atan() / 2.0;
        // The arc 1 m inside it, R = 1 / (sec(θ/2) − 1) = 204.7 m, would need a tangent of
        // 20.27 m; the last segment, an end segment, holds 20 m: R = 20 / tan(θ/2) = 202.0 m.
        assert!(20.0 < half.tan() / (1.0 / half.cos() - 1.0));
        assert_relative_eq!(arcs[0].2, 20.0 / half.tan(), epsilon = 1e-9);
        assert_relative_eq!(arcs[0].2, 202.0, epsilon = 0.05);
    }
}
