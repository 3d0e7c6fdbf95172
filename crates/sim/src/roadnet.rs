//! Drivable centrelines derived from road-surface polygons.
//!
//! The map gives the road *surface* (buffered centrelines, `area:highway`, parking), not a graph.
//! We rasterise the surface at [`RoadNetwork::RESOLUTION_M`], thin it to a one-pixel skeleton
//! (Zhang & Suen 1984) which runs along the middle of every street, and plan routes on the skeleton
//! by breadth-first search. The distance transform of the surface gives the local half-width of
//! the road, which places lanes, parked cars, kerbs and pavements.
//!
//! Key design decision: everything that moves follows a [`Polyline`] route taken from the skeleton
//! and offset sideways, so the simulator needs no lane topology from the map.

use crate::geometry::{Polyline, Vec2};
use crate::world::World;
use rand::Rng;

const ROAD: u8 = 1;
const BUILDING: u8 = 2;
const SKELETON: u8 = 4;
const JUNCTION: u8 = 8;
/// How far a route may depart from the skeleton it is traced on, metres (Douglas–Peucker
/// tolerance). The skeleton of a straight street wanders a pixel or two either side of its
/// middle where the surface widens (bays, driveways, buffered vertices) and along a slant's
/// staircase; kept, each wander is a corner, and a lane rounded through them weaves (the ego
/// swung ±10° about once a second on such a street). 1.0 m drops those wanders and keeps every
/// real bend; the lane stays within 1 m of the road's middle plus its offset, and parked cars
/// (placed from routes too) within 2 m of their kerb.
const ROUTE_TOLERANCE_M: f64 = 1.0;
/// A lane point is in a building when a building pixel's centre lies within this distance,
/// metres (the point is in that pixel). On a narrow street the road surface (a centreline
/// buffered at its class's width) overlaps the buildings, and the lane, offset from the
/// surface's middle, ran through them; a lane with no point in a building is left as it was,
/// so that scenes without the defect stay identical.
pub const FACADE_CLEARANCE_M: f64 = 0.5;
/// How steeply a lane moved off a façade returns to its place, metres sideways per metre along
/// (a 1 m shift is taken over 5 m, a gentle lane change, not a step).
const LANE_SHIFT_SLOPE: f64 = 0.2;
/// The least offset of a lane moved into a street's free part from that part's middle,
/// metres: cars whose centres are 1.7 m apart pass each other (a car keeps its gap from what is
/// within 1.6 m of its lane), where the lane rule's half of the half-width would put two
/// opposite cars in each other's way for good. Never beyond the free part.
const PASSING_OFFSET_M: f64 = 0.85;
/// How far from a building pixel's centre a point is free of the building, metres: half the
/// diagonal of a 1 m pixel.
pub const FREE_OF_BUILDING_M: f64 = 0.75;
/// Steps of the sideways search across a road for the part free of buildings, metres.
const LANE_SHIFT_STEP_M: f64 = 0.25;
/// How far a moved lane may depart from its points (Douglas–Peucker tolerance), metres.
const MOVED_LANE_TOLERANCE_M: f64 = 0.1;

/// Lateral offset of a lane from the road's middle, metres: a 3.5 m lane on roads 7 m or wider,
/// half of the half-width on narrower ones.
pub(crate) fn lane_offset_m(half_width_m: f64) -> f64 {
    (half_width_m * 0.5).min(1.75)
}

/// A route: a polyline plus the arc lengths of the junctions it passes.
#[derive(Clone, Debug)]
pub struct Route {
    /// The path, local metres.
    pub path: Polyline,
    /// Arc lengths of junctions along `path`, metres, ascending.
    pub junctions_m: Vec<f64>,
    /// Median half-width of the road surface along the route, metres.
    pub half_width_m: f64,
    /// The lane cars follow where `path` offset to the right (`lane_offset_m`), or the
    /// opposite lane, runs into a building ([`FACADE_CLEARANCE_M`]): that offset moved
    /// sideways, within the road, into the part free of buildings
    /// ([`RoadNetwork::lane_clear_of_buildings`]). `None`: the offset keeps its clearance and
    /// is the lane.
    pub lane: Option<Polyline>,
}

/// Rasterised road surface with its skeleton, for route planning.
#[derive(Clone, Debug)]
pub struct RoadNetwork {
    origin: Vec2,
    cols: usize,
    rows: usize,
    flags: Vec<u8>,
    /// Distance from a road pixel to the nearest off-road pixel, metres (0 off road).
    dist_m: Vec<f32>,
    /// Skeleton pixels wide enough for a car (index into the raster), for drawing route ends.
    anchors: Vec<u32>,
    /// Anchors near the focus path, where random routes start (all anchors when empty).
    focus: Vec<u32>,
    /// Raster index → compact skeleton index (u32::MAX off the skeleton).
    skeleton_index: Vec<u32>,
    /// Compact skeleton index → raster index.
    skeleton_pixels: Vec<u32>,
    /// 8-neighbour adjacency of skeleton pixels (CSR over compact indices).
    adjacency_start: Vec<u32>,
    adjacency: Vec<u32>,
}

/// Result of a breadth-first search over the skeleton (compact indices).
struct Search {
    parent: Vec<u32>,
    hops: Vec<u32>,
    order: Vec<u32>,
}

impl RoadNetwork {
    /// Raster resolution, metres. One metre resolves 3 m lanes and keeps a 2 km town at 4 M pixels.
    pub const RESOLUTION_M: f64 = 1.0;
    /// Minimum road half-width for a route end, metres: narrower skeleton pixels are spurs and
    /// slivers, not streets.
    const MIN_ANCHOR_HALF_WIDTH_M: f32 = 2.5;

    /// Builds the network from the world's road polygons and buildings.
    pub fn new(world: &World) -> Self {
        let (lo, hi) = world.extent();
        let res = Self::RESOLUTION_M;
        let cols = (((hi.x - lo.x) / res).ceil().max(1.0) as usize).min(20_000);
        let rows = (((hi.y - lo.y) / res).ceil().max(1.0) as usize).min(20_000);
        let mut net = Self {
            origin: lo,
            cols,
            rows,
            flags: vec![0; cols * rows],
            dist_m: vec![0.0; cols * rows],
            anchors: Vec::new(),
            focus: Vec::new(),
            skeleton_index: Vec::new(),
            skeleton_pixels: Vec::new(),
            adjacency_start: Vec::new(),
            adjacency: Vec::new(),
        };
        let mut xs = Vec::new();
        for polygon in world.roads() {
            net.fill(polygon.iter().map(|r| r.as_slice()), ROAD, &mut xs);
        }
        for b in world.buildings() {
            net.fill(b.rings.iter().map(|r| r.as_slice()), BUILDING, &mut xs);
        }
        net.distance_transform();
        net.thin();
        net.mark_junctions();
        net.anchors = (0..cols * rows)
            .filter(|&i| {
                net.flags[i] & SKELETON != 0 && net.dist_m[i] >= Self::MIN_ANCHOR_HALF_WIDTH_M
            })
            .map(|i| i as u32)
            .collect();
        net.build_adjacency();
        net
    }

    /// Compact indices and the neighbour lists of skeleton pixels, so a search costs memory in
    /// proportion to the skeleton, not to the raster.
    fn build_adjacency(&mut self) {
        let n = self.flags.len();
        self.skeleton_index = vec![u32::MAX; n];
        self.skeleton_pixels = (0..n)
            .filter(|&i| self.flags[i] & SKELETON != 0)
            .map(|i| i as u32)
            .collect();
        for (k, &i) in self.skeleton_pixels.iter().enumerate() {
            self.skeleton_index[i as usize] = k as u32;
        }
        let w = self.cols as i64;
        self.adjacency_start = Vec::with_capacity(self.skeleton_pixels.len() + 1);
        self.adjacency_start.push(0);
        for &i in &self.skeleton_pixels {
            let (c, r) = (
                (i as usize % self.cols) as i64,
                (i as usize / self.cols) as i64,
            );
            for (dc, dr) in [
                (0, 1),
                (1, 0),
                (0, -1),
                (-1, 0),
                (1, 1),
                (1, -1),
                (-1, -1),
                (-1, 1),
            ] {
                let (cc, rr) = (c + dc, r + dr);
                if cc < 0 || rr < 0 || cc >= w || rr as usize >= self.rows {
                    continue;
                }
                let k = self.skeleton_index[(rr * w + cc) as usize];
                if k != u32::MAX {
                    self.adjacency.push(k);
                }
            }
            self.adjacency_start.push(self.adjacency.len() as u32);
        }
    }

    /// Number of skeleton pixels usable as route ends (0: no drivable road in the world).
    pub fn anchor_count(&self) -> usize {
        self.anchors.len()
    }

    fn centre(&self, idx: usize) -> Vec2 {
        let (c, r) = (idx % self.cols, idx / self.cols);
        Vec2::new(
            self.origin.x + (c as f64 + 0.5) * Self::RESOLUTION_M,
            self.origin.y + (r as f64 + 0.5) * Self::RESOLUTION_M,
        )
    }

    fn index_of(&self, p: Vec2) -> Option<usize> {
        let c = ((p.x - self.origin.x) / Self::RESOLUTION_M).floor();
        let r = ((p.y - self.origin.y) / Self::RESOLUTION_M).floor();
        (c >= 0.0 && r >= 0.0 && (c as usize) < self.cols && (r as usize) < self.rows)
            .then(|| r as usize * self.cols + c as usize)
    }

    /// Whether a point is on the road surface.
    pub fn is_road(&self, p: Vec2) -> bool {
        self.index_of(p).is_some_and(|i| self.flags[i] & ROAD != 0)
    }
    /// Whether a point is inside a building.
    pub fn is_building(&self, p: Vec2) -> bool {
        self.index_of(p)
            .is_some_and(|i| self.flags[i] & BUILDING != 0)
    }
    /// Local road half-width at a point (largest distance-to-edge in the 3 × 3 pixels around it),
    /// metres; 0 off road.
    pub fn half_width_at(&self, p: Vec2) -> f64 {
        let Some(i) = self.index_of(p) else {
            return 0.0;
        };
        let (c, r) = ((i % self.cols) as i64, (i / self.cols) as i64);
        let mut best = 0.0f32;
        for dr in -1..=1 {
            for dc in -1..=1 {
                let (cc, rr) = (c + dc, r + dr);
                if cc >= 0 && rr >= 0 && (cc as usize) < self.cols && (rr as usize) < self.rows {
                    best = best.max(self.dist_m[rr as usize * self.cols + cc as usize]);
                }
            }
        }
        f64::from(best)
    }

    /// Whether a junction of the skeleton (or the pixels flagged around one) lies within
    /// `radius_m` of `p`.
    pub fn junction_within(&self, p: Vec2, radius_m: f64) -> bool {
        let reach = (radius_m / Self::RESOLUTION_M).ceil() as i64;
        let Some(i) = self.index_of(p) else {
            return false;
        };
        let (c, r) = ((i % self.cols) as i64, (i / self.cols) as i64);
        (-reach..=reach).any(|dr| {
            (-reach..=reach).any(|dc| {
                let (cc, rr) = (c + dc, r + dr);
                cc >= 0
                    && rr >= 0
                    && (cc as usize) < self.cols
                    && (rr as usize) < self.rows
                    && self.flags[rr as usize * self.cols + cc as usize] & JUNCTION != 0
                    && self
                        .centre(rr as usize * self.cols + cc as usize)
                        .minus(p)
                        .norm()
                        <= radius_m
            })
        })
    }

    /// Scanline fill of one polygon (rings, even–odd) at pixel centres.
    fn fill<'a>(
        &mut self,
        rings: impl Iterator<Item = &'a [Vec2]> + Clone,
        flag: u8,
        xs: &mut Vec<f64>,
    ) {
        let mut lo_y = f64::INFINITY;
        let mut hi_y = f64::NEG_INFINITY;
        for r in rings.clone() {
            for p in r {
                lo_y = lo_y.min(p.y);
                hi_y = hi_y.max(p.y);
            }
        }
        if !(lo_y.is_finite() && hi_y.is_finite()) {
            return;
        }
        let res = Self::RESOLUTION_M;
        let r0 = (((lo_y - self.origin.y) / res - 0.5).ceil().max(0.0)) as usize;
        let r1 =
            ((((hi_y - self.origin.y) / res - 0.5).floor()).min(self.rows as f64 - 1.0)).max(-1.0);
        if r1 < 0.0 {
            return;
        }
        for row in r0..=(r1 as usize) {
            let y = self.origin.y + (row as f64 + 0.5) * res;
            xs.clear();
            crate::geometry::ring_crossings(rings.clone(), y, xs);
            xs.sort_by(f64::total_cmp);
            for pair in xs.chunks_exact(2) {
                let c0 = ((pair[0] - self.origin.x) / res - 0.5).ceil().max(0.0) as usize;
                let c1 = ((pair[1] - self.origin.x) / res - 0.5)
                    .floor()
                    .min(self.cols as f64 - 1.0);
                if c1 < 0.0 {
                    continue;
                }
                for col in c0..=(c1 as usize) {
                    self.flags[row * self.cols + col] |= flag;
                }
            }
        }
    }

    /// Chamfer (3, 4) distance transform of the road mask, two passes.
    fn distance_transform(&mut self) {
        let (w, h) = (self.cols, self.rows);
        let big = u32::MAX / 2;
        let mut d: Vec<u32> = self
            .flags
            .iter()
            .map(|&f| if f & ROAD != 0 { big } else { 0 })
            .collect();
        for r in 0..h {
            for c in 0..w {
                let i = r * w + c;
                if d[i] == 0 {
                    continue;
                }
                // Pixels outside the raster count as off-road.
                let get = |cc: i64, rr: i64| -> u32 {
                    if cc < 0 || rr < 0 || cc as usize >= w || rr as usize >= h {
                        0
                    } else {
                        d[rr as usize * w + cc as usize]
                    }
                };
                let (ci, ri) = (c as i64, r as i64);
                let v = (get(ci - 1, ri) + 3)
                    .min(get(ci, ri - 1) + 3)
                    .min(get(ci - 1, ri - 1) + 4)
                    .min(get(ci + 1, ri - 1) + 4);
                d[i] = d[i].min(v);
            }
        }
        for r in (0..h).rev() {
            for c in (0..w).rev() {
                let i = r * w + c;
                if d[i] == 0 {
                    continue;
                }
                let get = |cc: i64, rr: i64| -> u32 {
                    if cc < 0 || rr < 0 || cc as usize >= w || rr as usize >= h {
                        0
                    } else {
                        d[rr as usize * w + cc as usize]
                    }
                };
                let (ci, ri) = (c as i64, r as i64);
                let v = (get(ci + 1, ri) + 3)
                    .min(get(ci, ri + 1) + 3)
                    .min(get(ci + 1, ri + 1) + 4)
                    .min(get(ci - 1, ri + 1) + 4);
                d[i] = d[i].min(v);
            }
        }
        for (out, v) in self.dist_m.iter_mut().zip(&d) {
            *out = (*v as f32 / 3.0) * Self::RESOLUTION_M as f32;
        }
    }

    /// The 8 neighbours P2..P9 of pixel (c, r), clockwise from north, as skeleton booleans.
    fn ring(&self, skel: &[bool], c: usize, r: usize) -> [bool; 8] {
        let w = self.cols;
        let at = |dc: i64, dr: i64| -> bool {
            let (cc, rr) = (c as i64 + dc, r as i64 + dr);
            cc >= 0
                && rr >= 0
                && (cc as usize) < w
                && (rr as usize) < self.rows
                && skel[rr as usize * w + cc as usize]
        };
        // Row index grows northwards (y up), so "north" is dr = +1.
        [
            at(0, 1),
            at(1, 1),
            at(1, 0),
            at(1, -1),
            at(0, -1),
            at(-1, -1),
            at(-1, 0),
            at(-1, 1),
        ]
    }

    /// Zhang–Suen thinning of the road mask into the SKELETON flag.
    fn thin(&mut self) {
        let mut skel: Vec<bool> = self.flags.iter().map(|&f| f & ROAD != 0).collect();
        let mut candidates: Vec<usize> = (0..skel.len()).filter(|&i| skel[i]).collect();
        let mut to_clear = Vec::new();
        loop {
            let mut changed = false;
            for sub in 0..2 {
                to_clear.clear();
                for &i in &candidates {
                    if !skel[i] {
                        continue;
                    }
                    let p = self.ring(&skel, i % self.cols, i / self.cols);
                    let b = p.iter().filter(|&&v| v).count();
                    if !(2..=6).contains(&b) {
                        continue;
                    }
                    let a = (0..8).filter(|&k| !p[k] && p[(k + 1) % 8]).count();
                    if a != 1 {
                        continue;
                    }
                    // p[0]=N, p[2]=E, p[4]=S, p[6]=W.
                    let (n, e, s, w) = (p[0], p[2], p[4], p[6]);
                    let ok = if sub == 0 {
                        !(e && s && (n || w))
                    } else {
                        !(n && w && (e || s))
                    };
                    if ok {
                        to_clear.push(i);
                    }
                }
                for &i in &to_clear {
                    skel[i] = false;
                }
                changed |= !to_clear.is_empty();
            }
            candidates.retain(|&i| skel[i]);
            if !changed {
                break;
            }
        }
        for (f, s) in self.flags.iter_mut().zip(&skel) {
            if *s {
                *f |= SKELETON;
            }
        }
    }

    fn skeleton_mask(&self) -> Vec<bool> {
        self.flags.iter().map(|&f| f & SKELETON != 0).collect()
    }

    /// A junction is a skeleton pixel whose 8-ring has three or more separate skeleton runs.
    fn mark_junctions(&mut self) {
        let skel = self.skeleton_mask();
        let mut junctions = Vec::new();
        for i in 0..skel.len() {
            if !skel[i] {
                continue;
            }
            let p = self.ring(&skel, i % self.cols, i / self.cols);
            let runs = (0..8).filter(|&k| !p[k] && p[(k + 1) % 8]).count();
            if runs >= 3 {
                junctions.push(i);
            }
        }
        // A shortest path may cut the corner past a junction pixel: flag its 5 × 5 surroundings.
        for i in junctions {
            let (c, r) = ((i % self.cols) as i64, (i / self.cols) as i64);
            for dr in -2..=2 {
                for dc in -2..=2 {
                    let (cc, rr) = (c + dc, r + dr);
                    if cc >= 0 && rr >= 0 && (cc as usize) < self.cols && (rr as usize) < self.rows
                    {
                        self.flags[rr as usize * self.cols + cc as usize] |= JUNCTION;
                    }
                }
            }
        }
    }

    /// Breadth-first search over skeleton pixels from raster pixel `start`, expanding no pixel
    /// more than `max_hops` steps away.
    fn bfs(&self, start: usize, max_hops: u32) -> Search {
        let n = self.skeleton_pixels.len();
        let mut search = Search {
            parent: vec![u32::MAX; n],
            hops: vec![u32::MAX; n],
            order: Vec::new(),
        };
        let Some(&s) = self.skeleton_index.get(start).filter(|&&k| k != u32::MAX) else {
            return search;
        };
        search.parent[s as usize] = s;
        search.hops[s as usize] = 0;
        search.order.push(s);
        let mut head = 0;
        while let Some(&k) = search.order.get(head) {
            head += 1;
            let h = search.hops[k as usize];
            if h >= max_hops {
                continue;
            }
            let (a, b) = (
                self.adjacency_start[k as usize] as usize,
                self.adjacency_start[k as usize + 1] as usize,
            );
            for &j in &self.adjacency[a..b] {
                if search.parent[j as usize] == u32::MAX {
                    search.parent[j as usize] = k;
                    search.hops[j as usize] = h + 1;
                    search.order.push(j);
                }
            }
        }
        search
    }

    fn nearest_anchor(&self, p: Vec2) -> Option<usize> {
        self.anchors.iter().map(|&i| i as usize).min_by(|&a, &b| {
            self.centre(a)
                .minus(p)
                .norm()
                .total_cmp(&self.centre(b).minus(p).norm())
        })
    }

    /// A route from the skeleton pixel nearest `start` with a length (in skeleton steps ≈ metres)
    /// drawn in `[min_len_m, max_len_m]`; the longest reachable when none is that long.
    pub fn random_route_from(
        &self,
        start: Vec2,
        min_len_m: f64,
        max_len_m: f64,
        rng: &mut impl Rng,
    ) -> Option<Route> {
        let s = self.nearest_anchor(start)?;
        self.route_from_pixel(s, min_len_m, max_len_m, rng)
    }

    /// Makes random routes start within `radius_m` of `path` (e.g. the ego route), so that a
    /// few actors on a large map are where the sensor can see them. A radius ≤ 0, or no anchor
    /// that near, lets routes start anywhere.
    pub fn set_focus(&mut self, path: &Polyline, radius_m: f64) {
        self.focus.clear();
        if radius_m <= 0.0 {
            return;
        }
        let n = (path.length_m() / 5.0).ceil() as usize;
        let samples: Vec<Vec2> = (0..=n).map(|k| path.at(k as f64 * 5.0).0).collect();
        let r2 = radius_m * radius_m;
        self.focus = self
            .anchors
            .iter()
            .copied()
            .filter(|&a| {
                let p = self.centre(a as usize);
                samples.iter().any(|q| {
                    let d = p.minus(*q);
                    d.dot(d) <= r2
                })
            })
            .collect();
    }

    /// A route starting at a random anchor (near the focus, if one is set).
    pub fn random_route(
        &self,
        min_len_m: f64,
        max_len_m: f64,
        rng: &mut impl Rng,
    ) -> Option<Route> {
        let pool = if self.focus.is_empty() {
            &self.anchors
        } else {
            &self.focus
        };
        if pool.is_empty() {
            return None;
        }
        let s = pool[rng.random_range(0..pool.len())] as usize;
        self.route_from_pixel(s, min_len_m, max_len_m, rng)
    }

    /// The shortest skeleton route between the pixels nearest `from` and `to`.
    pub fn route_between(&self, from: Vec2, to: Vec2) -> Option<Route> {
        let s = self.nearest_anchor(from)?;
        let g = self.nearest_anchor(to)?;
        let search = self.bfs(s, u32::MAX);
        self.trace(&search, s, g)
    }

    fn route_from_pixel(
        &self,
        s: usize,
        min_len_m: f64,
        max_len_m: f64,
        rng: &mut impl Rng,
    ) -> Option<Route> {
        let lo = (min_len_m / Self::RESOLUTION_M) as u32;
        let hi = (max_len_m / Self::RESOLUTION_M).min(f64::from(u32::MAX - 1)) as u32;
        let search = self.bfs(s, hi);
        let is_anchor = |k: u32| {
            self.dist_m[self.skeleton_pixels[k as usize] as usize] >= Self::MIN_ANCHOR_HALF_WIDTH_M
        };
        let in_range: Vec<u32> = search
            .order
            .iter()
            .copied()
            .filter(|&k| is_anchor(k) && search.hops[k as usize] >= lo)
            .collect();
        // BFS order is by hop count, so the last anchor visited is the farthest.
        let goal = if in_range.is_empty() {
            search.order.iter().rev().copied().find(|&k| is_anchor(k))?
        } else {
            in_range[rng.random_range(0..in_range.len())]
        };
        self.trace(&search, s, self.skeleton_pixels[goal as usize] as usize)
    }

    fn trace(&self, search: &Search, start: usize, goal: usize) -> Option<Route> {
        let (s, g) = (
            *self.skeleton_index.get(start)?,
            *self.skeleton_index.get(goal)?,
        );
        if s == u32::MAX
            || g == u32::MAX
            || search.parent.get(g as usize).is_none_or(|&p| p == u32::MAX)
        {
            return None;
        }
        let mut compact = vec![g];
        let mut cur = g;
        while cur != s {
            cur = search.parent[cur as usize];
            compact.push(cur);
        }
        compact.reverse();
        let pixels: Vec<usize> = compact
            .iter()
            .map(|&k| self.skeleton_pixels[k as usize] as usize)
            .collect();
        let points: Vec<Vec2> = pixels.iter().map(|&i| self.centre(i)).collect();
        // Raw pixel path length, to map junction positions onto the simplified polyline.
        let mut raw_s = Vec::with_capacity(points.len());
        let mut acc = 0.0;
        raw_s.push(0.0);
        for w in points.windows(2) {
            acc += w[1].minus(w[0]).norm();
            raw_s.push(acc);
        }
        let simplified = douglas_peucker(&points, ROUTE_TOLERANCE_M);
        let path = Polyline::new(simplified)?;
        let scale = if acc > 0.0 {
            path.length_m() / acc
        } else {
            1.0
        };
        let mut junctions_m: Vec<f64> = Vec::new();
        for (k, &i) in pixels.iter().enumerate() {
            if self.flags[i] & JUNCTION != 0 {
                let s = raw_s[k] * scale;
                // Several junction pixels cluster at one crossing: keep one per 10 m.
                if junctions_m.last().is_none_or(|&last| s - last > 10.0) {
                    junctions_m.push(s);
                }
            }
        }
        let mut widths: Vec<f32> = pixels.iter().map(|&i| self.dist_m[i]).collect();
        widths.sort_by(f32::total_cmp);
        let half_width_m = f64::from(widths[widths.len() / 2]);
        let lane = self.lane_clear_of_buildings(&path, half_width_m);
        Some(Route {
            path,
            junctions_m,
            half_width_m,
            lane,
        })
    }

    /// Distance from `p` to the nearest building pixel's centre, metres, capped at `reach_m`
    /// (`reach_m` when none is nearer).
    fn building_distance(&self, p: Vec2, reach_m: f64) -> f64 {
        let Some(i) = self.index_of(p) else {
            return reach_m;
        };
        let reach = (reach_m / Self::RESOLUTION_M).ceil() as i64 + 1;
        let (c, r) = ((i % self.cols) as i64, (i / self.cols) as i64);
        let mut best = reach_m;
        for rr in (r - reach).max(0)..=(r + reach).min(self.rows as i64 - 1) {
            for cc in (c - reach).max(0)..=(c + reach).min(self.cols as i64 - 1) {
                let j = rr as usize * self.cols + cc as usize;
                if self.flags[j] & BUILDING != 0 {
                    best = best.min(self.centre(j).minus(p).norm());
                }
            }
        }
        best
    }

    /// Whether a building pixel's centre lies within `radius_m` of `p`.
    pub fn building_within(&self, p: Vec2, radius_m: f64) -> bool {
        self.building_distance(p, radius_m) < radius_m
    }

    /// The right-hand lane of `path` (a road of median half-width `half_width_m`) kept out of
    /// buildings, or `None` when neither it nor the opposite lane runs into one
    /// ([`FACADE_CLEARANCE_M`]; then nothing changes). Sampled every metre, each point where
    /// either lane is in a building moves sideways to where the lane rule puts it in the free
    /// part of the road's cross-section (`RoadNetwork::free_space_shift`). Every shift fades out
    /// at `LANE_SHIFT_SLOPE` either side, and the moved points are simplified again.
    pub fn lane_clear_of_buildings(&self, path: &Polyline, half_width_m: f64) -> Option<Polyline> {
        let offset_m = lane_offset_m(half_width_m);
        let lane = path.offset(-offset_m);
        let samples = lane_samples(&lane);
        let shifts: Vec<f64> = samples
            .iter()
            .map(|&(p, normal, _)| {
                // This lane's point and the opposite lane's: both move, or neither, so that
                // the two stay apart.
                let opposite = p.plus(normal.scale(2.0 * offset_m));
                if !self.building_within(p, FACADE_CLEARANCE_M)
                    && !self.building_within(opposite, FACADE_CLEARANCE_M)
                {
                    return 0.0;
                }
                self.free_space_shift(p, normal, offset_m - half_width_m, offset_m + half_width_m)
            })
            .collect();
        if shifts.iter().all(|&d| d == 0.0) {
            return None;
        }
        let arc_m: Vec<f64> = samples.iter().map(|&(_, _, s)| s).collect();
        let faded = fade_shifts(&shifts, &arc_m, LANE_SHIFT_SLOPE);
        let moved: Vec<Vec2> = samples
            .iter()
            .zip(&faded)
            .map(|(&(p, normal, _), &d)| p.plus(normal.scale(d)))
            .collect();
        Polyline::new(douglas_peucker(&moved, MOVED_LANE_TOLERANCE_M))
    }

    /// The sideways shift (along `normal`) that puts lane point `p` where the lane rule
    /// ([`lane_offset_m`]) puts it in the free part of the road's cross-section: the stretch
    /// of `[min_m, max_m]` whose points are [`FREE_OF_BUILDING_M`] from building pixels,
    /// nearest the point, taken as the road; the lane runs right of its middle by half its
    /// half-width, at most 1.75 m. So a street narrower between façades than its surface keeps
    /// two lanes apart and each out of the walls. 0 when no point of the cross-section is free.
    fn free_space_shift(&self, p: Vec2, normal: Vec2, min_m: f64, max_m: f64) -> f64 {
        let steps = ((max_m - min_m) / LANE_SHIFT_STEP_M).floor().max(0.0) as usize;
        let at = |k: usize| min_m + k as f64 * LANE_SHIFT_STEP_M;
        let free: Vec<bool> = (0..=steps)
            .map(|k| {
                let q = p.plus(normal.scale(at(k)));
                self.building_distance(q, FREE_OF_BUILDING_M) >= FREE_OF_BUILDING_M
            })
            .collect();
        // The free runs (first, last step), and the one nearest the point (shift 0).
        let mut best: Option<(f64, usize, usize)> = None;
        let mut k = 0;
        while k <= steps {
            if !free[k] {
                k += 1;
                continue;
            }
            let first = k;
            while k < steps && free[k + 1] {
                k += 1;
            }
            let (a, b) = (at(first), at(k));
            let distance = if a > 0.0 {
                a
            } else if b < 0.0 {
                -b
            } else {
                0.0
            };
            if best.is_none_or(|(d, _, _)| distance < d) {
                best = Some((distance, first, k));
            }
            k += 1;
        }
        let Some((_, first, last)) = best else {
            return 0.0;
        };
        let (a, b) = (at(first), at(last));
        let free_half_width_m = (b - a) / 2.0;
        let offset_m = lane_offset_m(free_half_width_m)
            .max(PASSING_OFFSET_M)
            .min(free_half_width_m);
        (a + b) / 2.0 - offset_m
    }
}

/// Points of `lane` every metre or closer, its vertices among them, each with the unit normal
/// to its left (at a vertex, that of the chord of its neighbours, as [`Polyline::offset`]) and
/// its arc length.
fn lane_samples(lane: &Polyline) -> Vec<(Vec2, Vec2, f64)> {
    let points = lane.points();
    let normal_of = |a: Vec2, b: Vec2| {
        let t = b.minus(a);
        let len = t.norm();
        if len > 0.0 {
            t.scale(1.0 / len).perp_left()
        } else {
            Vec2::default()
        }
    };
    let mut out = Vec::new();
    let mut arc = 0.0;
    for (i, w) in points.windows(2).enumerate() {
        let (a, b) = (w[0], w[1]);
        let vertex_normal = normal_of(points[i.saturating_sub(1)], b);
        out.push((a, vertex_normal, arc));
        let len = b.minus(a).norm();
        let n = (len / RoadNetwork::RESOLUTION_M).ceil().max(1.0) as usize;
        for k in 1..n {
            let u = k as f64 / n as f64;
            out.push((a.plus(b.minus(a).scale(u)), normal_of(a, b), arc + u * len));
        }
        arc += len;
    }
    if let [.., a, b] = points {
        out.push((*b, normal_of(*a, *b), arc));
    }
    out
}

/// The shifts fanned out: at each sample the largest of `shifts` less `slope` times its
/// distance along the lane (by magnitude, with its sign), so that every shift is reached
/// gradually and left gradually.
fn fade_shifts(shifts: &[f64], arc_m: &[f64], slope: f64) -> Vec<f64> {
    let n = shifts.len();
    let mut forward = shifts.to_vec();
    for i in 1..n {
        let carried = forward[i - 1].abs() - slope * (arc_m[i] - arc_m[i - 1]);
        if carried > forward[i].abs() {
            forward[i] = forward[i - 1].signum() * carried;
        }
    }
    let mut both = forward.clone();
    for i in (0..n.saturating_sub(1)).rev() {
        let carried = both[i + 1].abs() - slope * (arc_m[i + 1] - arc_m[i]);
        if carried > both[i].abs() {
            both[i] = both[i + 1].signum() * carried;
        }
    }
    both
}

/// Douglas–Peucker simplification with tolerance `eps_m`.
fn douglas_peucker(points: &[Vec2], eps_m: f64) -> Vec<Vec2> {
    if points.len() < 3 {
        return points.to_vec();
    }
    let mut keep = vec![false; points.len()];
    keep[0] = true;
    keep[points.len() - 1] = true;
    let mut stack = vec![(0usize, points.len() - 1)];
    while let Some((a, b)) = stack.pop() {
        if b <= a + 1 {
            continue;
        }
        let (pa, pb) = (points[a], points[b]);
        let ab = pb.minus(pa);
        let len = ab.norm();
        let mut worst = (0.0, a);
        for (k, p) in points.iter().enumerate().take(b).skip(a + 1) {
            let d = if len > 0.0 {
                (p.minus(pa).cross(ab) / len).abs()
            } else {
                p.minus(pa).norm()
            };
            if d > worst.0 {
                worst = (d, k);
            }
        }
        if worst.0 > eps_m {
            keep[worst.1] = true;
            stack.push((a, worst.1));
            stack.push((worst.1, b));
        }
    }
    points
        .iter()
        .zip(&keep)
        .filter(|(_, k)| **k)
        .map(|(p, _)| *p)
        .collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::testing::rect_ring;
    use rand::SeedableRng;

    /// A plus-shaped crossing of two 8 m wide streets, 200 m long each, centred at (100, 100).
    pub(crate) fn crossing_world() -> World {
        let rect = |x0: f64, y0: f64, x1: f64, y1: f64| vec![rect_ring(x0, y0, x1, y1)];
        World::new(
            vec![],
            vec![rect(0.0, 96.0, 200.0, 104.0), rect(96.0, 0.0, 104.0, 200.0)],
            (Vec2::new(0.0, 0.0), Vec2::new(200.0, 200.0)),
        )
    }

    #[test]
    fn skeleton_runs_along_street_middles_with_a_junction() {
        let net = RoadNetwork::new(&crossing_world());
        assert!(net.anchor_count() > 200);
        // Route from the west end to the north end passes the crossing.
        let route = net
            .route_between(Vec2::new(10.0, 100.0), Vec2::new(100.0, 190.0))
            .unwrap();
        // Every vertex lies within a pixel or so of a street's middle line.
        for p in route.path.points() {
            let off = (p.y - 100.0).abs().min((p.x - 100.0).abs());
            assert!(off <= 1.5, "vertex {p:?} is {off} m off the middle");
        }
        assert_eq!(route.junctions_m.len(), 1, "{:?}", route.junctions_m);
        // Half the 8 m width, within the chamfer approximation and pixel rounding.
        assert!(
            (route.half_width_m - 4.0).abs() <= 1.0,
            "{}",
            route.half_width_m
        );
        // West end to centre ≈ 90 m, centre to north end ≈ 90 m.
        assert!(
            (route.path.length_m() - 180.0).abs() < 15.0,
            "{}",
            route.path.length_m()
        );
    }

    #[test]
    fn a_route_along_a_straight_street_with_bays_does_not_zigzag() {
        // A straight 8 m wide street north along x = 100, with 2 m deep bays (parking,
        // driveways) on its east side for 10 m of every 20: its middle, and so its skeleton,
        // steps between x = 100 and x = 101 every 10 m. A lane following each step would weave
        // (the ego swung ±10° about once a second on such a street); the route keeps straight
        // on: the turns between its consecutive segments add up to (almost) nothing.
        let rect = |x0: f64, y0: f64, x1: f64, y1: f64| vec![rect_ring(x0, y0, x1, y1)];
        let mut roads = vec![rect(96.0, 0.0, 104.0, 200.0)];
        roads.extend((0..10).map(|k| {
            let y0 = 20.0 * f64::from(k) + 5.0;
            rect(103.0, y0, 106.0, y0 + 10.0)
        }));
        let world = World::new(
            vec![],
            roads,
            (Vec2::new(0.0, 0.0), Vec2::new(200.0, 200.0)),
        );
        let net = RoadNetwork::new(&world);
        let route = net
            .route_between(Vec2::new(100.0, 10.0), Vec2::new(100.0, 190.0))
            .unwrap();
        let headings: Vec<f64> = route
            .path
            .points()
            .windows(2)
            .map(|w| {
                let d = w[1].minus(w[0]);
                d.y.atan2(d.x)
            })
            .collect();
        let turned_deg: f64 = headings
            .windows(2)
            .map(|h| crate::geometry::wrap_angle(h[1] - h[0]).abs().to_degrees())
            .sum();
        assert!(
            turned_deg < 5.0,
            "{turned_deg}° over {:?}",
            route.path.points()
        );
        assert!(route.path.length_m() > 170.0, "{}", route.path.length_m());
    }

    /// A map in local metres through geodata's tag rules: a street west to east along y = 50
    /// whose east half (x 100..200) is a tunnel (`tunnel=yes`), and a street south to north along
    /// x = 150 through a 40 m × 20 m building (y 90..110) by a building passage.
    fn tunnel_and_passage_world() -> World {
        let text = r#"{"type": "FeatureCollection", "bbox": [0, 0, 200, 200], "features": [
          {"type": "Feature", "properties": {"highway": "residential", "width": "8"},
           "geometry": {"type": "LineString", "coordinates": [[0, 50], [100, 50]]}},
          {"type": "Feature", "properties": {"highway": "residential", "width": "8", "tunnel": "yes"},
           "geometry": {"type": "LineString", "coordinates": [[100, 50], [200, 50]]}},
          {"type": "Feature", "properties": {"highway": "residential", "width": "8"},
           "geometry": {"type": "LineString", "coordinates": [[150, 0], [150, 90]]}},
          {"type": "Feature", "properties": {"highway": "residential", "width": "8",
             "tunnel": "building_passage"},
           "geometry": {"type": "LineString", "coordinates": [[150, 90], [150, 110]]}},
          {"type": "Feature", "properties": {"highway": "residential", "width": "8"},
           "geometry": {"type": "LineString", "coordinates": [[150, 110], [150, 200]]}},
          {"type": "Feature", "properties": {"building": "yes"},
           "geometry": {"type": "Polygon",
             "coordinates": [[[130, 90], [170, 90], [170, 110], [130, 110], [130, 90]]]}}]}"#;
        let map = geodata::LocalMap::from_local_geojson(text).unwrap();
        World::from_polygons(&map.buildings, &map.roads, &map.extent)
    }

    #[test]
    fn a_tunnel_is_not_drivable() {
        let net = RoadNetwork::new(&tunnel_and_passage_world());
        assert!(net.is_road(Vec2::new(50.0, 50.0)));
        // The tunnel, away from the street crossing above it at x = 150.
        assert!(!net.is_road(Vec2::new(120.0, 50.0)));
        assert!(!net.is_road(Vec2::new(180.0, 50.0)));
        // A route from the open street's west end to where the tunnel ends stays off it.
        if let Some(route) = net.route_between(Vec2::new(5.0, 50.0), Vec2::new(195.0, 50.0)) {
            for p in route.path.points() {
                assert!(p.x <= 105.0 || (p.x - 150.0).abs() <= 5.0, "{p:?}");
            }
        }
    }

    #[test]
    fn a_building_passage_is_drivable_and_open() {
        let world = tunnel_and_passage_world();
        let net = RoadNetwork::new(&world);
        let middle = Vec2::new(150.0, 100.0);
        assert!(net.is_road(middle) && !net.is_building(middle));
        // The building stands on either side of the passage, cut in two.
        assert!(net.is_building(Vec2::new(140.0, 100.0)));
        assert!(net.is_building(Vec2::new(160.0, 100.0)));
        assert_eq!(world.buildings().len(), 2);
        // A route from south to north drives through it.
        let route = net
            .route_between(Vec2::new(150.0, 5.0), Vec2::new(150.0, 195.0))
            .unwrap();
        assert!(route.path.length_m() < 200.0, "{}", route.path.length_m());
        // A ray along the passage from its south end is not stopped by a façade.
        let hit = world.ray_cast_buildings(Vec2::new(150.0, 80.0), Vec2::new(0.0, 1.0), 50.0);
        assert!(hit.is_none(), "{hit:?}");
    }

    #[test]
    fn random_routes_are_deterministic_by_seed() {
        let net = RoadNetwork::new(&crossing_world());
        let mut a = rand::rngs::StdRng::seed_from_u64(3);
        let mut b = rand::rngs::StdRng::seed_from_u64(3);
        let ra = net.random_route(50.0, 150.0, &mut a).unwrap();
        let rb = net.random_route(50.0, 150.0, &mut b).unwrap();
        assert_eq!(ra.path, rb.path);
    }

    /// An 8 m street along y = 100 (x 0..200) and, when `facade_y` is given, a building
    /// (x 60..140) from y = 80 up to `facade_y`: above 96 it covers the street's south side.
    fn street_with_facade(facade_y: Option<f64>) -> World {
        let rect = rect_ring;
        let buildings = facade_y
            .and_then(|y| crate::world::Building::new(vec![rect(60.0, 80.0, 140.0, y)]))
            .into_iter()
            .collect();
        World::new(
            buildings,
            vec![vec![rect(0.0, 96.0, 200.0, 104.0)]],
            (Vec2::new(0.0, 0.0), Vec2::new(200.0, 200.0)),
        )
    }

    /// The lane's y where it crosses x.
    fn lane_y_at(lane: &Polyline, x: f64) -> f64 {
        let n = (lane.length_m() * 10.0).ceil() as usize;
        (0..=n)
            .map(|k| lane.at(k as f64 * 0.1).0)
            .min_by(|a, b| (a.x - x).abs().total_cmp(&(b.x - x).abs()))
            .unwrap()
            .y
    }

    #[test]
    fn a_lane_keeps_out_of_a_facade_over_the_road_and_from_the_opposite_lane() {
        // The façade at y = 99 covers the pixel rows centred at 96.5..98.5; the eastbound lane,
        // 1.75 m right of the middle (y ≈ 98.25), ran through it.
        let net = RoadNetwork::new(&street_with_facade(Some(99.0)));
        let east = net
            .route_between(Vec2::new(5.0, 100.0), Vec2::new(195.0, 100.0))
            .unwrap();
        let west = net
            .route_between(Vec2::new(195.0, 100.0), Vec2::new(5.0, 100.0))
            .unwrap();
        let (east_lane, west_lane) = (east.lane.clone().unwrap(), west.lane.clone().unwrap());
        let plain = east.path.offset(-lane_offset_m(east.half_width_m));
        // Beside the building: out of it (free from 99.25, 0.75 m off the pixel centres at
        // 98.5) and the two lanes 1.7 m apart (PASSING_OFFSET_M either side of the free middle).
        let (e, w) = (lane_y_at(&east_lane, 100.0), lane_y_at(&west_lane, 100.0));
        assert!((99.25..104.0).contains(&e), "eastbound lane at y {e}");
        assert!(w - e >= 1.6, "lanes at {e} and {w}");
        assert!(!net.is_building(Vec2::new(100.0, e)));
        // Far from it, the lane as before (within the moved lane's simplification); the shift
        // fades in at 0.2 m a metre (1.8 m over 9 m, from x ≈ 51.5 to the building at 60).
        for x in [10.0, 45.0, 190.0] {
            let (moved, before) = (lane_y_at(&east_lane, x), lane_y_at(&plain, x));
            assert!(
                (moved - before).abs() <= MOVED_LANE_TOLERANCE_M,
                "x {x}: {moved} vs {before}"
            );
        }
    }

    #[test]
    fn a_lane_with_no_facade_in_the_road_is_exactly_as_before() {
        // The building's edge at y = 95 leaves the street (y 96..104) free.
        for world in [street_with_facade(None), street_with_facade(Some(95.0))] {
            let net = RoadNetwork::new(&world);
            let route = net
                .route_between(Vec2::new(5.0, 100.0), Vec2::new(195.0, 100.0))
                .unwrap();
            assert!(route.lane.is_none());
        }
    }

    #[test]
    fn shifts_fade_out_at_their_slope_and_keep_their_sign() {
        let arc: Vec<f64> = (0..7).map(f64::from).collect();
        let faded = fade_shifts(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -0.1], &arc, 0.2);
        let expected = [0.4, 0.6, 0.8, 1.0, 0.8, 0.6, 0.4];
        for (f, e) in faded.iter().zip(expected) {
            assert!((f - e).abs() < 1e-12, "{faded:?}");
        }
        let faded = fade_shifts(&[0.0, -0.5, 0.0], &[0.0, 1.0, 2.0], 0.2);
        for (f, e) in faded.iter().zip([-0.3, -0.5, -0.3]) {
            assert!((f - e).abs() < 1e-12, "{faded:?}");
        }
    }
}
