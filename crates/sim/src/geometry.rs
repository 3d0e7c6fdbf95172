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
}
