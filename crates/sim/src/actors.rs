//! Actors: cars (moving, stopping, queueing, parked), pedestrians (walking, standing) and
//! unmapped street furniture, each with a footprint and a class at every instant.
//!
//! Motion is kinematic and deliberately simple: a car follows its lane (a route offset to the
//! right of the road's middle, its corners rounded by arcs of radius at least
//! [`MIN_TURN_RADIUS_M`], so its heading turns continuously) at its cruise speed, slows for
//! corners ([`CORNER_LATERAL_MPS2`]), brakes to stop at junctions it decided to stop at, and
//! keeps a gap behind whatever is ahead in its lane, which makes queues form. All actors
//! are updated from a snapshot of the previous instant, in id order, so the result depends only
//! on the seed.

use crate::geometry::{Footprint, Polyline, Pose2, RoundedPath, Vec2, wrap_angle};
use crate::roadnet::{FREE_OF_BUILDING_M, RoadNetwork, Route, lane_offset_m};
use crate::scenario::TrafficConfig;
use rand::Rng;
use serde::{Deserialize, Serialize};

/// What an actor is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ActorKind {
    /// A car, moving or parked.
    Car,
    /// A pedestrian.
    Pedestrian,
    /// A lamp post or sign pole.
    Pole,
    /// A tree trunk.
    Tree,
    /// A litter or recycling bin.
    Bin,
    /// A bollard.
    Bollard,
}

impl ActorKind {
    /// Whether this is street furniture (truth class U) rather than a road user.
    pub fn is_infrastructure(self) -> bool {
        matches!(
            self,
            ActorKind::Pole | ActorKind::Tree | ActorKind::Bin | ActorKind::Bollard
        )
    }
    /// Footprint of this kind.
    pub fn footprint(self) -> Footprint {
        match self {
            ActorKind::Car => Body::CAR.footprint(),
            ActorKind::Pedestrian => Footprint::Circle { radius_m: 0.3 },
            ActorKind::Pole => Footprint::Circle { radius_m: 0.12 },
            ActorKind::Tree => Footprint::Circle { radius_m: 0.35 },
            ActorKind::Bin => Footprint::Rect {
                half_length_m: 0.3,
                half_width_m: 0.3,
            },
            ActorKind::Bollard => Footprint::Circle { radius_m: 0.1 },
        }
    }
}

/// Half of a car's length, metres (a 4.5 m compact car).
pub const CAR_HALF_LENGTH_M: f64 = 2.25;
/// Half of a car's width, metres (1.8 m).
pub const CAR_HALF_WIDTH_M: f64 = 0.9;
/// Tightest turn a bus drives, metres: the radius of the arc its centre follows (a 12 m city
/// bus sweeps a kerb-to-kerb circle of about 24 m across; its centre turns on about 9 m).
pub const BUS_MIN_TURN_RADIUS_M: f64 = 9.0;
/// Tightest turn a truck drives, metres (a 8–10 m rigid truck, about 20 m kerb to kerb).
pub const TRUCK_MIN_TURN_RADIUS_M: f64 = 8.0;
/// A truck's length, metres: drawn uniformly per truck.
pub const TRUCK_LENGTH_M: [f64; 2] = [8.0, 10.0];

/// A driving vehicle's body: its size and its tightest turn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body {
    /// Half its length, metres.
    pub half_length_m: f64,
    /// Half its width, metres.
    pub half_width_m: f64,
    /// The tightest arc its lane's corners are rounded by, metres.
    pub min_turn_radius_m: f64,
}

impl Body {
    /// A 4.5 × 1.8 m compact car turning on [`MIN_TURN_RADIUS_M`].
    pub const CAR: Body = Body {
        half_length_m: CAR_HALF_LENGTH_M,
        half_width_m: CAR_HALF_WIDTH_M,
        min_turn_radius_m: MIN_TURN_RADIUS_M,
    };
    /// A 12 × 2.55 m city bus turning on [`BUS_MIN_TURN_RADIUS_M`].
    pub const BUS: Body = Body {
        half_length_m: 6.0,
        half_width_m: 1.275,
        min_turn_radius_m: BUS_MIN_TURN_RADIUS_M,
    };

    /// A rigid truck `length_m` long and 2.5 m wide turning on [`TRUCK_MIN_TURN_RADIUS_M`].
    pub fn truck(length_m: f64) -> Body {
        Body {
            half_length_m: length_m / 2.0,
            half_width_m: 1.25,
            min_turn_radius_m: TRUCK_MIN_TURN_RADIUS_M,
        }
    }

    /// Its rectangle, centred on the vehicle's pose.
    pub fn footprint(&self) -> Footprint {
        Footprint::Rect {
            half_length_m: self.half_length_m,
            half_width_m: self.half_width_m,
        }
    }
}

/// Half the length of a road user's body along its heading, metres: a rectangle's half length,
/// a circle's radius.
pub fn half_length_m(footprint: &Footprint) -> f64 {
    match *footprint {
        Footprint::Rect { half_length_m, .. } => half_length_m,
        Footprint::Circle { radius_m } => radius_m,
    }
}

/// Whether an actor is a large vehicle (a bus or a truck): a car whose body is longer than 6 m.
pub fn is_large_vehicle(actor: &Actor) -> bool {
    actor.kind == ActorKind::Car && half_length_m(&actor.footprint) > 3.0
}
/// Comfortable deceleration for planned stops, m/s².
const BRAKE_MPS2: f64 = 3.0;
/// Acceleration, m/s².
const ACCEL_MPS2: f64 = 2.0;
/// Hardest braking allowed to avoid running into a leader, m/s².
const MAX_BRAKE_MPS2: f64 = 8.0;
/// Bumper-to-bumper gap kept when stopped in a queue, metres.
const STANDSTILL_GAP_M: f64 = 2.5;
/// Stop line distance before a junction centre, metres.
const STOP_LINE_BEFORE_JUNCTION_M: f64 = 9.0;
/// Tightest turn a car drives, metres: the radius of the arcs that round its lane's sharpest
/// corners (a compact car's kerb-to-kerb turning circle is about 10 m across). A car's heading
/// turns at most `v / MIN_TURN_RADIUS_M` radians a second.
pub const MIN_TURN_RADIUS_M: f64 = 5.0;
/// How far inside a lane's corner its arc passes, metres, where the segments leave room and the
/// radius stays above [`MIN_TURN_RADIUS_M`]: gentle bends get wide arcs, street corners the
/// tightest turn.
pub const CORNER_APEX_M: f64 = 1.0;
/// How far a parked car stands from a junction's centre at least, metres: a junction's
/// half-width and the 5 m before a crossing where parking is not allowed. Closer, it would
/// stand in the arc a car turning there drives (a turn cuts the corner by up to 2 m).
const PARKED_CLEAR_OF_JUNCTION_M: f64 = 10.0;
/// How far before the end of its lane a car takes its next route, metres: the new lane starts
/// where the car is, so the corner at the old lane's end is rounded like any other.
const ROUTE_JOIN_M: f64 = 10.0;
/// How many routes a car at the end of its lane draws, for one that does not turn back.
const NEXT_ROUTE_DRAWS: usize = 4;
/// Lateral acceleration a car accepts in a corner, m/s²: it slows to `√(a·R)` for an arc of
/// radius R (3.9 m/s on the tightest turn), braking for it at 3 m/s² beforehand (as for a stop).
pub const CORNER_LATERAL_MPS2: f64 = 3.0;

/// A car following a lane.
#[derive(Clone, Debug)]
pub struct Driving {
    /// The lane with its corners rounded (see [`MIN_TURN_RADIUS_M`]).
    lane: RoundedPath,
    junctions_m: Vec<f64>,
    s_m: f64,
    cruise_mps: f64,
    next_junction: usize,
    stop_at_m: Option<f64>,
    wait_left_s: f64,
    /// Junction stops on or off (the ego never stops on its own).
    stops: bool,
    /// How far ahead of its centre the car reaches, metres: half its length, or for the ego
    /// the sensor on its front when that sits further out. Gaps ahead are kept from there.
    front_m: f64,
    /// The tightest arc of its lane's corners, metres (its body's turning).
    min_turn_radius_m: f64,
    /// Whether the car has drawn its next route (once, [`ROUTE_JOIN_M`] before its lane's end).
    next_route_drawn: bool,
}

/// A pedestrian walking back and forth along a pavement.
#[derive(Clone, Debug)]
pub struct Walking {
    path: Polyline,
    s_m: f64,
    forward: bool,
    cruise_mps: f64,
    standing: bool,
    phase_left_s: f64,
}

/// How an actor moves.
#[derive(Clone, Debug)]
pub enum Motion {
    /// Never moves (parked cars, street furniture).
    Fixed,
    /// Follows a lane.
    Driving(Box<Driving>),
    /// Walks a pavement.
    Walking(Box<Walking>),
}

/// An actor at the current instant.
#[derive(Clone, Debug)]
pub struct Actor {
    /// Stable id (index in the actor list).
    pub id: u32,
    /// What it is.
    pub kind: ActorKind,
    /// Its shape.
    pub footprint: Footprint,
    /// `world_from_actor` now.
    pub pose: Pose2,
    /// Speed now, m/s (≥ 0).
    pub speed_mps: f64,
    /// How it moves.
    pub motion: Motion,
}

fn uniform(rng: &mut impl Rng, range: [f64; 2]) -> f64 {
    if range[1] > range[0] {
        rng.random_range(range[0]..=range[1])
    } else {
        range[0]
    }
}

impl Actor {
    /// Points of the lane a driving actor follows, every `step_m` metres from its start to its
    /// end; none for an actor that does not drive.
    pub fn lane_samples(&self, step_m: f64) -> Vec<Vec2> {
        let Motion::Driving(d) = &self.motion else {
            return Vec::new();
        };
        let length_m = d.lane.length_m();
        let count = (length_m / step_m.max(0.01)).ceil() as usize;
        (0..=count)
            .map(|i| d.lane.at((i as f64 * step_m).min(length_m)).0)
            .collect()
    }

    /// A car on `route`, driving on the right, starting `start_m` along it.
    pub fn driving_car(id: u32, route: &Route, start_m: f64, cruise_mps: f64, stops: bool) -> Self {
        Self::driving_vehicle(id, route, start_m, cruise_mps, stops, Body::CAR)
    }

    /// A vehicle of `body` on `route`, driving on the right, starting `start_m` along it: a
    /// car ([`ActorKind::Car`], truth as a car's) of that size, its lane's corners rounded by
    /// arcs of at least its turning radius, keeping its gaps from its front bumper.
    pub fn driving_vehicle(
        id: u32,
        route: &Route,
        start_m: f64,
        cruise_mps: f64,
        stops: bool,
        body: Body,
    ) -> Self {
        let driving = Driving::on_route(route, &[], cruise_mps, stops, body.min_turn_radius_m);
        let s_m = start_m.clamp(0.0, driving.lane.length_m());
        let (p, t) = driving.lane.at(s_m);
        Self {
            id,
            kind: ActorKind::Car,
            footprint: body.footprint(),
            pose: Pose2::new(p, t.y.atan2(t.x)),
            speed_mps: cruise_mps,
            motion: Motion::Driving(Box::new(Driving {
                s_m,
                front_m: body.half_length_m,
                ..driving
            })),
        }
    }

    /// This car with whatever it carries reaching `front_m` ahead of its centre (the ego's
    /// sensor): it keeps its gaps from there, so that it never stops with the sensor inside
    /// the car ahead. A reach shorter than the car changes nothing.
    pub fn with_front_reach(mut self, front_m: f64) -> Self {
        if let Motion::Driving(d) = &mut self.motion {
            d.front_m = front_m.max(d.front_m);
        }
        self
    }

    /// What this actor holds clear of: its footprint, stretched forward to its front reach
    /// (the ego's sensor), at its pose.
    pub fn clearance(&self) -> (Pose2, Footprint) {
        match (&self.motion, self.footprint) {
            (
                Motion::Driving(d),
                Footprint::Rect {
                    half_length_m,
                    half_width_m,
                },
            ) if d.front_m > half_length_m => {
                let half = (d.front_m + half_length_m) / 2.0;
                let centre = self
                    .pose
                    .world_from_body(Vec2::new((d.front_m - half_length_m) / 2.0, 0.0));
                (
                    Pose2::new(centre, self.pose.heading_rad),
                    Footprint::Rect {
                        half_length_m: half,
                        half_width_m,
                    },
                )
            }
            _ => (self.pose, self.footprint),
        }
    }

    /// A fixed actor.
    pub fn fixed(id: u32, kind: ActorKind, pose: Pose2) -> Self {
        Self {
            id,
            kind,
            footprint: kind.footprint(),
            pose,
            speed_mps: 0.0,
            motion: Motion::Fixed,
        }
    }

    /// A pedestrian on `path`.
    pub fn pedestrian(id: u32, path: Polyline, rng: &mut impl Rng, cfg: &TrafficConfig) -> Self {
        let s_m = rng.random_range(0.0..=path.length_m());
        let standing = rng.random_bool(0.3);
        let phase_left_s = uniform(
            rng,
            if standing {
                cfg.stand_duration_s
            } else {
                cfg.walk_duration_s
            },
        );
        let cruise_mps = uniform(rng, cfg.walking_speed_mps);
        let forward = rng.random_bool(0.5);
        let (p, t) = path.at(s_m);
        let heading = t.y.atan2(t.x) + if forward { 0.0 } else { std::f64::consts::PI };
        Self {
            id,
            kind: ActorKind::Pedestrian,
            footprint: ActorKind::Pedestrian.footprint(),
            pose: Pose2::new(p, wrap_angle(heading)),
            speed_mps: if standing { 0.0 } else { cruise_mps },
            motion: Motion::Walking(Box::new(Walking {
                path,
                s_m,
                forward,
                cruise_mps,
                standing,
                phase_left_s,
            })),
        }
    }

    /// Distance to the nearest obstacle ahead in this car's lane among `others` (bumper to
    /// bumper, metres), looking `horizon_m` ahead along the lane: an obstacle is in the lane
    /// when its centre lies within 1.6 m of it (a lane is 3.5 m wide), measured from the
    /// lane's nearest point of those a metre apart ahead. Along a curve this is not straight
    /// ahead: a car parked at the kerb of the street the lane turns into lies straight ahead
    /// of a car in the turn, but beside its lane. A car crossing from the right counts from
    /// where its body can reach the lane (see the body). Infinite for an actor that does not
    /// drive.
    fn gap_ahead(&self, others: &[Obstacle], horizon_m: f64) -> f64 {
        let Motion::Driving(d) = &self.motion else {
            return f64::INFINITY;
        };
        // Past the lane's end every sample is its end, and the first of them is the nearest:
        // beyond it, "along" continues straight on.
        let ahead: Vec<(f64, Vec2, Vec2)> = (0..=horizon_m.ceil() as usize)
            .map(|k| {
                let (p, t) = d.lane.at(d.s_m + k as f64);
                (k as f64, p, t)
            })
            .collect();
        let here = self.pose.position_m;
        let mut gap = f64::INFINITY;
        for o in others {
            if o.id == self.id || o.position.minus(here).norm() > horizon_m + 2.0 {
                continue;
            }
            let nearest = ahead.iter().min_by(|a, b| {
                let (da, db) = (a.1.minus(o.position), b.1.minus(o.position));
                da.dot(da).total_cmp(&db.dot(db))
            });
            let Some(&(k, p, t)) = nearest else { continue };
            let rel = o.position.minus(p);
            let along = k + rel.dot(t);
            // A car crossing the lane reaches into it by up to its half length times the sine
            // of the angle between them; one coming from the right (driving on the right, it
            // has the priority) counts from there, one from the left yields, so two cars
            // meeting at a crossing do not both stop for good.
            let side = t.cross(rel);
            let crossing = t.cross(Vec2::from_angle(o.heading_rad)).abs() * o.half_length_m;
            let reach = if side < 0.0 { 1.6 + crossing } else { 1.6 };
            if along > 0.0 && along < horizon_m && side.abs() < reach {
                gap = gap.min(along - d.front_m - o.half_length_m);
            }
        }
        gap
    }
}

/// What a driver looks at: another road user's position and half length along the lane.
#[derive(Clone, Copy, Debug)]
pub struct Obstacle {
    /// Actor id.
    pub id: u32,
    /// Centre, world metres.
    pub position: Vec2,
    /// Half length, metres.
    pub half_length_m: f64,
    /// Heading, radians (x east, counter-clockwise).
    pub heading_rad: f64,
}

/// The snapshot every car brakes for: cars and pedestrians (a pedestrian on a pavement never sits
/// in a lane, so only cars matter in practice).
pub fn obstacles(actors: &[Actor], extra: &[Obstacle]) -> Vec<Obstacle> {
    actors
        .iter()
        .filter(|a| a.kind == ActorKind::Car)
        .map(|a| Obstacle {
            id: a.id,
            position: a.pose.position_m,
            half_length_m: half_length_m(&a.footprint),
            heading_rad: a.pose.heading_rad,
        })
        .chain(extra.iter().copied())
        .collect()
}

/// Advances one actor by `dt_s` given the snapshot `others`. When a car reaches the end of its
/// lane it gets a new route from `net` starting where it is.
pub fn advance(
    actor: &mut Actor,
    others: &[Obstacle],
    dt_s: f64,
    cfg: &TrafficConfig,
    net: &RoadNetwork,
    rng: &mut impl Rng,
) {
    let gap = match &actor.motion {
        Motion::Driving(_) => actor.gap_ahead(others, 40.0),
        _ => f64::INFINITY,
    };
    match &mut actor.motion {
        Motion::Fixed => actor.speed_mps = 0.0,
        Motion::Driving(d) => {
            let mut v = if d.wait_left_s > 0.0 {
                d.wait_left_s -= dt_s;
                0.0
            } else {
                d.next_speed(actor.speed_mps, gap, dt_s, cfg, rng)
            };
            if d.s_m + v * dt_s >= d.lane.length_m() {
                // The ego keeps its route and stops at its end; so does a car with nowhere to
                // go. Its speed is what it covered.
                v = (d.lane.length_m() - d.s_m).max(0.0) / dt_s;
                d.s_m = d.lane.length_m();
            } else {
                d.s_m += v * dt_s;
            }
            if d.s_m >= d.lane.length_m() - ROUTE_JOIN_M && d.past_last_arc() {
                d.take_next_route(net, rng);
            }
            let (p, t) = d.lane.at(d.s_m);
            actor.pose = Pose2::new(p, t.y.atan2(t.x));
            actor.speed_mps = v;
        }
        Motion::Walking(w) => {
            let v = w.walk(dt_s, cfg, rng);
            let (p, t) = w.path.at(w.s_m);
            let heading = t.y.atan2(t.x) + if w.forward { 0.0 } else { std::f64::consts::PI };
            actor.pose = Pose2::new(p, wrap_angle(heading));
            actor.speed_mps = v;
        }
    }
}

impl Driving {
    /// The speed after `dt_s` from `v` (m/s), `gap_m` behind the leader: deciding about the
    /// next junction once it is within braking reach plus a margin, stopping at its line if
    /// so decided (and waiting there), and never driving into the leader.
    fn next_speed(
        &mut self,
        v: f64,
        gap_m: f64,
        dt_s: f64,
        cfg: &TrafficConfig,
        rng: &mut impl Rng,
    ) -> f64 {
        if self.stop_at_m.is_none()
            && let Some(&j) = self.junctions_m.get(self.next_junction)
        {
            let line = j - STOP_LINE_BEFORE_JUNCTION_M;
            let reach = v * v / (2.0 * BRAKE_MPS2) + 15.0;
            if line - self.s_m < reach {
                if self.stops && line > self.s_m && rng.random_bool(cfg.stop_probability) {
                    self.stop_at_m = Some(line);
                } else {
                    self.next_junction += 1;
                }
            }
        }
        let mut v_target = self.cruise_mps;
        if let Some(line) = self.stop_at_m {
            let to_line = (line - self.s_m).max(0.0);
            v_target = v_target.min((2.0 * BRAKE_MPS2 * to_line).sqrt());
            if to_line < 0.5 && v < 0.3 {
                self.wait_left_s = uniform(rng, cfg.stop_duration_s);
                self.stop_at_m = None;
                self.next_junction += 1;
                v_target = 0.0;
            }
        }
        v_target = v_target.min(self.corner_speed_mps());
        if !self.stops || self.next_route_drawn {
            // It stops at the end of its lane: the ego at its route's, a car with nowhere to go.
            let to_end = (self.lane.length_m() - self.s_m).max(0.0);
            v_target = v_target.min((2.0 * BRAKE_MPS2 * to_end).sqrt());
        }
        let free = (gap_m - STANDSTILL_GAP_M).max(0.0);
        v_target = v_target.min((2.0 * BRAKE_MPS2 * free).sqrt());
        let mut v = if v_target >= v {
            (v + ACCEL_MPS2 * dt_s).min(v_target)
        } else {
            (v - MAX_BRAKE_MPS2 * dt_s).max(v_target)
        };
        // Never drive into the leader, whatever the braking limit says.
        if gap_m.is_finite() {
            v = v.min(((gap_m - 0.5).max(0.0)) / dt_s);
        }
        v
    }

    /// The fastest speed at which the car can still slow, braking at [`BRAKE_MPS2`], to
    /// `√(CORNER_LATERAL_MPS2 · R)` by every arc of radius R ahead within its braking reach
    /// from cruise speed; inside an arc, that arc's speed.
    fn corner_speed_mps(&self) -> f64 {
        let reach_m = self.cruise_mps * self.cruise_mps / (2.0 * BRAKE_MPS2) + 5.0;
        self.lane
            .arcs()
            .skip_while(|&(_, end, _)| end <= self.s_m)
            .take_while(|&(start, _, _)| start - self.s_m < reach_m)
            .map(|(start, _, radius_m)| {
                let to_arc = (start - self.s_m).max(0.0);
                (CORNER_LATERAL_MPS2 * radius_m + 2.0 * BRAKE_MPS2 * to_arc).sqrt()
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// A car at the start of its lane: `route` offset to the right, after the points `lead_in`
    /// (where it is and where its last lane ended), its corners rounded.
    fn on_route(
        route: &Route,
        lead_in: &[Vec2],
        cruise_mps: f64,
        stops: bool,
        min_turn_radius_m: f64,
    ) -> Self {
        let offset = route
            .lane
            .clone()
            .unwrap_or_else(|| route.path.offset(-lane_offset_m(route.half_width_m)));
        let mut points = lead_in.to_vec();
        // The new lane from its first point ahead of where the last one ended.
        let ahead_of_end = |q: &Vec2| match lead_in {
            [.., a, b] => q.minus(*b).dot(b.minus(*a)) > 0.0,
            _ => true,
        };
        points.extend(
            offset
                .points()
                .iter()
                .copied()
                .skip_while(|q| !ahead_of_end(q)),
        );
        let lead_in_m: f64 = lead_in.windows(2).map(|w| w[1].minus(w[0]).norm()).sum();
        let lane = match Polyline::new(points) {
            Some(line) => RoundedPath::new(&line, min_turn_radius_m, CORNER_APEX_M),
            None => RoundedPath::new(&offset, min_turn_radius_m, CORNER_APEX_M),
        };
        let ratio = if route.path.length_m() > 0.0 {
            ((lane.length_m() - lead_in_m) / route.path.length_m()).max(0.0)
        } else {
            1.0
        };
        let junctions_m = route
            .junctions_m
            .iter()
            .map(|s| lead_in_m + s * ratio)
            .collect();
        Self {
            lane,
            junctions_m,
            s_m: 0.0,
            cruise_mps,
            next_junction: 0,
            stop_at_m: None,
            wait_left_s: 0.0,
            stops,
            front_m: CAR_HALF_LENGTH_M,
            min_turn_radius_m,
            next_route_drawn: false,
        }
    }

    /// Whether the car has left its lane's last arc behind: only the lane's final straight lies
    /// ahead. The next lane starts with the straight from where the car is to the old lane's
    /// end; taken on an arc, that chord would turn the car by half the arc left in one frame.
    fn past_last_arc(&self) -> bool {
        self.lane
            .arcs()
            .last()
            .is_none_or(|(_, end_m, _)| self.s_m >= end_m)
    }

    /// Near the end of its lane, a car that stops at junctions (not the ego) draws a new route
    /// from `net` starting where the lane ends, once, and takes the first of
    /// [`NEXT_ROUTE_DRAWS`] that does not turn back: the new lane runs from where the car is
    /// through the old lane's end, so the corner between them is rounded like any other. The
    /// car keeps its lane (and stops at its end) when no route is taken.
    fn take_next_route(&mut self, net: &RoadNetwork, rng: &mut impl Rng) {
        if !self.stops || self.next_route_drawn {
            return;
        }
        self.next_route_drawn = true;
        let here = self.lane.at(self.s_m).0;
        let (end, along) = self.lane.at(self.lane.length_m());
        for _draw in 0..NEXT_ROUTE_DRAWS {
            let Some(route) = net.random_route_from(end, 150.0, 600.0, rng) else {
                return;
            };
            let next = Self::on_route(
                &route,
                &[here, end],
                self.cruise_mps,
                self.stops,
                self.min_turn_radius_m,
            );
            // Ahead: the new lane 20 m on lies in front of the old lane's end.
            if next.lane.at(20.0).0.minus(end).dot(along) > 0.0 {
                *self = Self {
                    front_m: self.front_m,
                    ..next
                };
                return;
            }
        }
    }
}

impl Walking {
    /// Walks `dt_s` along the pavement stretch, standing and walking in turns, turning around
    /// at its ends; returns the speed, m/s.
    fn walk(&mut self, dt_s: f64, cfg: &TrafficConfig, rng: &mut impl Rng) -> f64 {
        self.phase_left_s -= dt_s;
        if self.phase_left_s <= 0.0 {
            self.standing = !self.standing;
            self.phase_left_s = uniform(
                rng,
                if self.standing {
                    cfg.stand_duration_s
                } else {
                    cfg.walk_duration_s
                },
            );
        }
        let v = if self.standing { 0.0 } else { self.cruise_mps };
        let len = self.path.length_m();
        let mut s = self.s_m + if self.forward { v * dt_s } else { -v * dt_s };
        // Turn around at the ends of the pavement stretch.
        if s > len {
            s = 2.0 * len - s;
            self.forward = false;
        } else if s < 0.0 {
            s = -s;
            self.forward = true;
        }
        self.s_m = s.clamp(0.0, len);
        v
    }
}

/// How far a parked car's long axis stays from the centre line of the lane kept clear, metres:
/// its half width, the passing car's, and 0.3 m between them.
pub const LANE_CLEARANCE_M: f64 = 0.9 + 0.9 + 0.3;

/// Distance from `q` to the segment `a`–`b`, metres.
fn distance_to_segment(q: Vec2, a: Vec2, b: Vec2) -> f64 {
    let ab = b.minus(a);
    let length_sq = ab.dot(ab);
    let u = if length_sq > 0.0 {
        (q.minus(a).dot(ab) / length_sq).clamp(0.0, 1.0)
    } else {
        0.0
    };
    q.minus(a.plus(ab.scale(u))).norm()
}

/// Places the scenario's actors on the road network. Fewer actors than asked are placed when the
/// map has no room for them (the count placed is the length of the returned list).
pub fn populate(
    net: &RoadNetwork,
    cfg: &TrafficConfig,
    keep_clear: &[(Pose2, Footprint)],
    lane_kept_clear: &[Vec2],
    rng: &mut impl Rng,
) -> Vec<Actor> {
    let mut actors: Vec<Actor> = Vec::new();
    if net.anchor_count() == 0 {
        return actors;
    }
    let place = Placement {
        net,
        cfg,
        keep_clear,
        lane_kept_clear,
    };
    for _ in 0..cfg.moving_cars {
        if let Some(car) = place.moving_car(&actors, rng) {
            actors.push(car);
        }
    }
    for _ in 0..cfg.parked_cars {
        if let Some(car) = place.parked_car(&actors, rng) {
            actors.push(car);
        }
    }
    for _ in 0..cfg.pedestrians {
        if let Some(pedestrian) = place.pedestrian(&actors, rng) {
            actors.push(pedestrian);
        }
    }
    for _ in 0..cfg.infrastructure {
        if let Some(furniture) = place.street_furniture(&actors, rng) {
            actors.push(furniture);
        }
    }
    actors
}

/// Where [`populate`] places actors: on `net`, with `cfg`'s speeds and durations, clear of
/// `keep_clear`, and parked cars clear of the lane `lane_kept_clear` samples.
struct Placement<'a> {
    net: &'a RoadNetwork,
    cfg: &'a TrafficConfig,
    keep_clear: &'a [(Pose2, Footprint)],
    lane_kept_clear: &'a [Vec2],
}

impl Placement<'_> {
    /// Whether no car of `actors` stands within `min_m` of `p`, that distance grown by how
    /// much longer than a compact car each of them is (a bus or a truck).
    fn far_from_cars(actors: &[Actor], p: Vec2, min_m: f64) -> bool {
        actors.iter().filter(|a| a.kind == ActorKind::Car).all(|a| {
            let longer_m = (half_length_m(&a.footprint) - CAR_HALF_LENGTH_M).max(0.0);
            a.pose.position_m.minus(p).norm() >= min_m + longer_m
        })
    }

    /// The body of the next moving car: a bus with probability `bus_share`, a truck
    /// ([`TRUCK_LENGTH_M`]) with `truck_share`, a car otherwise. With both shares 0 nothing is
    /// drawn, so a scene without large vehicles draws what it drew before they existed.
    fn body<R: Rng>(&self, rng: &mut R) -> Body {
        let (bus, truck) = (self.cfg.bus_share, self.cfg.truck_share);
        if bus + truck <= 0.0 {
            return Body::CAR;
        }
        let u: f64 = rng.random();
        if u < bus {
            Body::BUS
        } else if u < bus + truck {
            Body::truck(uniform(rng, TRUCK_LENGTH_M))
        } else {
            Body::CAR
        }
    }

    /// Whether `car` is clear of the places to keep clear. A car placed on the ego (or over its
    /// sensor) would be one its sensor sits in and cannot see, while truth counts it.
    fn clear(&self, car: &Actor) -> bool {
        self.keep_clear
            .iter()
            .all(|(pose, shape)| !car.footprint.overlaps(&car.pose, shape, pose))
    }

    /// Whether a parked car at `pose` leaves a car room to pass along the lane kept clear (the
    /// ego's): its long axis at least [`LANE_CLEARANCE_M`] from every sample of that lane. On a
    /// street under 10 m wide a car parked at the kerb reaches into the lane, and the ego would
    /// queue behind it for the rest of the drive.
    fn clear_of_lane(&self, pose: &Pose2) -> bool {
        let front = pose.world_from_body(Vec2::new(CAR_HALF_LENGTH_M, 0.0));
        let back = pose.world_from_body(Vec2::new(-CAR_HALF_LENGTH_M, 0.0));
        self.lane_kept_clear
            .iter()
            .all(|&q| distance_to_segment(q, back, front) >= LANE_CLEARANCE_M)
    }

    /// A moving car (or bus or truck, [`Placement::body`]) on a random route, 10 m from every
    /// car, more by how much longer than a car either is (20 attempts).
    fn moving_car<R: Rng>(&self, actors: &[Actor], rng: &mut R) -> Option<Actor> {
        for _attempt in 0..20 {
            let route = self.net.random_route(150.0, 600.0, rng)?;
            let start = rng.random_range(0.0..=route.path.length_m() * 0.5);
            let cruise = uniform(rng, self.cfg.car_speed_mps);
            let body = self.body(rng);
            let car =
                Actor::driving_vehicle(actors.len() as u32, &route, start, cruise, true, body);
            let longer_m = body.half_length_m - CAR_HALF_LENGTH_M;
            if Self::far_from_cars(actors, car.pose.position_m, 10.0 + longer_m) && self.clear(&car)
            {
                return Some(car);
            }
        }
        None
    }

    /// A parked car along the kerb of a road wide enough to keep a lane free (half-width
    /// ≥ 4 m), wholly on the road, clear of junctions ([`PARKED_CLEAR_OF_JUNCTION_M`]), 5.5 m
    /// from every car (40 attempts).
    fn parked_car<R: Rng>(&self, actors: &[Actor], rng: &mut R) -> Option<Actor> {
        let net = self.net;
        for _attempt in 0..40 {
            let route = net.random_route(10.0, 200.0, rng)?;
            let s = rng.random_range(0.0..=route.path.length_m());
            let (p, t) = route.path.at(s);
            let hw = net.half_width_at(p);
            if hw < 4.0 {
                continue;
            }
            let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let centre = p.plus(t.perp_left().scale(side * (hw - 1.2)));
            let heading = t.y.atan2(t.x)
                + if rng.random_bool(0.5) {
                    0.0
                } else {
                    std::f64::consts::PI
                };
            let pose = Pose2::new(centre, wrap_angle(heading));
            let corners = [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)]
                .map(|(a, b)| pose.world_from_body(Vec2::new(a * CAR_HALF_LENGTH_M, b * 0.9)));
            let car = Actor::fixed(actors.len() as u32, ActorKind::Car, pose);
            if corners.iter().all(|&c| net.is_road(c))
                && !net.junction_within(centre, PARKED_CLEAR_OF_JUNCTION_M)
                && Self::far_from_cars(actors, centre, 5.5)
                && self.clear(&car)
                && self.clear_of_lane(&pose)
            {
                // A car that would stand in a building (where the road surface overlaps one)
                // is not placed, and no other is drawn for it: the draws of the actors after
                // it stay those of a scene without the overlap.
                let in_building = net.building_within(centre, FREE_OF_BUILDING_M)
                    || corners.iter().any(|&c| net.is_building(c));
                return (!in_building).then_some(car);
            }
        }
        None
    }

    /// A pedestrian on a pavement 1.5 m beyond the kerb, where it is neither road nor building
    /// (30 attempts).
    fn pedestrian<R: Rng>(&self, actors: &[Actor], rng: &mut R) -> Option<Actor> {
        for _attempt in 0..30 {
            let route = self.net.random_route(30.0, 150.0, rng)?;
            let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let path = route.path.offset(side * (route.half_width_m + 1.5));
            if pavement_fraction(self.net, &path) >= 0.9 {
                let pedestrian = Actor::pedestrian(actors.len() as u32, path, rng, self.cfg);
                return Some(kept_out_of_buildings(self.net, pedestrian));
            }
        }
        None
    }

    /// Street furniture (a pole, tree, bin or bollard) 0.6 m beyond the kerb, off the road and
    /// outside buildings (30 attempts).
    fn street_furniture<R: Rng>(&self, actors: &[Actor], rng: &mut R) -> Option<Actor> {
        let net = self.net;
        for _attempt in 0..30 {
            let route = net.random_route(10.0, 200.0, rng)?;
            let s = rng.random_range(0.0..=route.path.length_m());
            let (p, t) = route.path.at(s);
            let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let q = p.plus(t.perp_left().scale(side * (net.half_width_at(p) + 0.6)));
            if !net.is_road(q) && !net.is_building(q) {
                let kind = [
                    ActorKind::Pole,
                    ActorKind::Tree,
                    ActorKind::Bin,
                    ActorKind::Bollard,
                ][rng.random_range(0..4)];
                let heading = t.y.atan2(t.x);
                return Some(Actor::fixed(
                    actors.len() as u32,
                    kind,
                    Pose2::new(q, heading),
                ));
            }
        }
        None
    }
}

/// `pedestrian` walking only the stretch of its pavement that holds it and is outside buildings
/// (the pavement's points every metre off building pixels), from where it stands; unchanged
/// when its whole pavement is outside them or where it stands is not. A pavement offset from
/// the road's middle runs through the buildings of a street narrower than its surface; the
/// pedestrian turns around at their walls instead, with the same draws and the same start.
fn kept_out_of_buildings(net: &RoadNetwork, mut pedestrian: Actor) -> Actor {
    let Motion::Walking(walking) = &mut pedestrian.motion else {
        return pedestrian;
    };
    let path = &walking.path;
    let n = path.length_m().ceil().max(1.0) as usize;
    let step = path.length_m() / n as f64;
    let clear: Vec<bool> = (0..=n)
        .map(|k| !net.is_building(path.at(k as f64 * step).0))
        .collect();
    if clear.iter().all(|&c| c) {
        return pedestrian;
    }
    // Where it stands, or the nearest clear point when that is in a building.
    let drawn = ((walking.s_m / step).round() as usize).min(n);
    let Some(here) = (0..=n)
        .filter(|&k| clear[k])
        .min_by_key(|&k| k.abs_diff(drawn))
    else {
        return pedestrian;
    };
    if here != drawn {
        walking.s_m = here as f64 * step;
        pedestrian.pose.position_m = path.at(walking.s_m).0;
    }
    let first = (0..=here)
        .rev()
        .take_while(|&k| clear[k])
        .last()
        .unwrap_or(here);
    let last = (here..=n).take_while(|&k| clear[k]).last().unwrap_or(here);
    let (sa, sb) = (first as f64 * step, last as f64 * step);
    if sb - sa < 1.0 || walking.s_m < sa || walking.s_m > sb {
        return pedestrian;
    }
    let mut points = vec![path.at(sa).0];
    for (p, s) in path.points().iter().zip(path_cumulative(path)) {
        if s > sa && s < sb {
            points.push(*p);
        }
    }
    points.push(path.at(sb).0);
    if let Some(kept) = Polyline::new(points) {
        walking.path = kept;
        walking.s_m -= sa;
    }
    pedestrian
}

/// Arc length at each vertex of `path`, metres.
fn path_cumulative(path: &Polyline) -> Vec<f64> {
    let mut acc = 0.0;
    let mut out = vec![0.0];
    for w in path.points().windows(2) {
        acc += w[1].minus(w[0]).norm();
        out.push(acc);
    }
    out
}

/// Fraction of points every 2 m along `path` that are off the road and outside buildings.
fn pavement_fraction(net: &RoadNetwork, path: &Polyline) -> f64 {
    let n = (path.length_m() / 2.0).ceil().max(1.0) as usize;
    let ok = (0..=n)
        .filter(|&k| {
            let p = path.at(k as f64 * 2.0).0;
            !net.is_road(p) && !net.is_building(p)
        })
        .count();
    ok as f64 / (n + 1) as f64
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::roadnet::Route;
    use crate::testing::rect_ring;

    fn straight_route(len: f64, junction_at: Option<f64>) -> Route {
        Route {
            path: Polyline::new(vec![Vec2::new(0.0, 0.0), Vec2::new(len, 0.0)]).unwrap(),
            junctions_m: junction_at.into_iter().collect(),
            half_width_m: 4.0,
            lane: None,
        }
    }

    fn net() -> RoadNetwork {
        RoadNetwork::new(&crate::world::World::new(
            vec![],
            vec![],
            (Vec2::new(0.0, -10.0), Vec2::new(10.0, 10.0)),
        ))
    }

    #[test]
    fn car_stops_at_junction_then_goes_again() {
        use rand::SeedableRng;
        let cfg = TrafficConfig {
            stop_probability: 1.0,
            stop_duration_s: [3.0, 3.0],
            ..TrafficConfig::default()
        };
        let net = net();
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let mut car = Actor::driving_car(0, &straight_route(500.0, Some(100.0)), 0.0, 10.0, true);
        // Lane is 1.75 m right of the middle (half-width 4 m).
        assert!((car.pose.position_m.y + 1.75).abs() < 1e-9);
        let mut stopped_for = 0.0;
        let mut max_x_while_stopped: f64 = 0.0;
        for _ in 0..400 {
            advance(&mut car, &[], 0.1, &cfg, &net, &mut rng);
            if car.speed_mps < 0.01 {
                stopped_for += 0.1;
                max_x_while_stopped = max_x_while_stopped.max(car.pose.position_m.x);
            }
        }
        // It waited about 3 s just before the 91 m stop line, then drove on.
        assert!((2.9..=3.6).contains(&stopped_for), "{stopped_for}");
        assert!(
            (89.0..=91.1).contains(&max_x_while_stopped),
            "{max_x_while_stopped}"
        );
        assert!(car.pose.position_m.x > 200.0);
    }

    /// Drives `car` (on a straight lane along y = −1.75 from x = 0) for 20 s towards a
    /// stopped leader whose centre is at x = 60 in the same lane.
    fn drive_up_to_a_stopped_leader(mut car: Actor) -> Actor {
        use rand::SeedableRng;
        let cfg = TrafficConfig::default();
        let net = net();
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let leader = Obstacle {
            id: 9,
            position: Vec2::new(60.0, -1.75),
            half_length_m: CAR_HALF_LENGTH_M,
            heading_rad: 0.0,
        };
        for _ in 0..200 {
            advance(&mut car, &[leader], 0.1, &cfg, &net, &mut rng);
        }
        car
    }

    #[test]
    fn follower_queues_behind_a_stopped_leader() {
        let route = straight_route(500.0, None);
        let car = drive_up_to_a_stopped_leader(Actor::driving_car(0, &route, 0.0, 10.0, true));
        let gap = 60.0 - car.pose.position_m.x - 2.0 * CAR_HALF_LENGTH_M;
        assert!(car.speed_mps < 0.01);
        assert!((0.5..=STANDSTILL_GAP_M + 0.5).contains(&gap), "gap {gap}");
    }

    #[test]
    fn a_car_carrying_a_sensor_ahead_keeps_its_gap_from_the_sensor() {
        let route = straight_route(500.0, None);
        // The sensor 3.7 m ahead of the centre, 1.45 m beyond the bumper.
        let car = drive_up_to_a_stopped_leader(
            Actor::driving_car(0, &route, 0.0, 10.0, false).with_front_reach(3.7),
        );
        let sensor_gap = 60.0 - CAR_HALF_LENGTH_M - (car.pose.position_m.x + 3.7);
        assert!(car.speed_mps < 0.01);
        assert!(
            (0.5..=STANDSTILL_GAP_M + 0.5).contains(&sensor_gap),
            "gap {sensor_gap}"
        );
        // What it holds clear: from its rear bumper to the sensor, as wide as the car.
        let (pose, shape) = car.clearance();
        let rear = car.pose.position_m.x - CAR_HALF_LENGTH_M;
        let touching = |x: f64| Pose2::new(Vec2::new(x, car.pose.position_m.y), 0.0);
        let pole = Footprint::Circle { radius_m: 0.05 };
        assert!(pole.overlaps(&touching(car.pose.position_m.x + 3.65), &shape, &pose));
        assert!(!pole.overlaps(&touching(car.pose.position_m.x + 3.76), &shape, &pose));
        assert!(pole.overlaps(&touching(rear + 0.04), &shape, &pose));
        assert!(!pole.overlaps(&touching(rear - 0.06), &shape, &pose));
        // A reach shorter than the car changes nothing.
        let plain = Actor::driving_car(0, &route, 0.0, 10.0, false);
        assert_eq!(
            plain.clone().with_front_reach(1.0).clearance(),
            plain.clearance()
        );
    }

    /// East 100 m, then a left turn north 100 m, on a road 8 m wide.
    fn east_then_north() -> Route {
        Route {
            path: Polyline::new(vec![
                Vec2::new(0.0, 0.0),
                Vec2::new(100.0, 0.0),
                Vec2::new(100.0, 100.0),
            ])
            .unwrap(),
            junctions_m: vec![],
            half_width_m: 4.0,
            lane: None,
        }
    }

    #[test]
    fn a_car_slows_for_a_corner_and_turns_it_continuously() {
        use rand::SeedableRng;
        // East 100 m, then a left turn north: the lane's corner is rounded by the tightest arc,
        // R = 5 m, where a car accepts 3 m/s² sideways: √(3 · 5) = 3.87 m/s.
        let route = east_then_north();
        let cfg = TrafficConfig::default();
        let net = net();
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let mut car = Actor::driving_car(0, &route, 0.0, 10.0, true);
        let corner_mps = (CORNER_LATERAL_MPS2 * MIN_TURN_RADIUS_M).sqrt();
        assert!((corner_mps - 3.873).abs() < 1e-3);
        let (mut slowest, mut fastest_after): (f64, f64) = (f64::INFINITY, 0.0);
        for _ in 0..250 {
            let before = car.pose;
            advance(&mut car, &[], 0.1, &cfg, &net, &mut rng);
            let heading = car.pose.heading_rad.to_degrees();
            // Its heading turns at most v·dt / R a frame.
            let turn = wrap_angle(car.pose.heading_rad - before.heading_rad);
            assert!(turn.abs() <= car.speed_mps * 0.1 / MIN_TURN_RADIUS_M + 1e-9);
            if (20.0..=70.0).contains(&heading) {
                assert!(car.speed_mps <= corner_mps + 1e-9, "{}", car.speed_mps);
            }
            // Before and in the corner; beyond it, up to the lane's end where it stops.
            if heading <= 80.0 {
                slowest = slowest.min(car.speed_mps);
            } else {
                fastest_after = fastest_after.max(car.speed_mps);
            }
        }
        // It slowed for the corner, not to a stop, and is back at its cruise speed beyond it.
        assert!(
            (corner_mps - 0.5..=corner_mps + 1e-9).contains(&slowest),
            "{slowest}"
        );
        assert!((fastest_after - 10.0).abs() < 1e-9, "{fastest_after}");
    }

    #[test]
    fn a_car_takes_its_next_route_without_a_jump_in_heading() {
        use rand::SeedableRng;
        // Streets 8 m wide east along y = 0 and north along x = 200. The car's route turns left
        // at (200, 0) and ends 8 m on, so that 10 m before its end it is still in the corner's
        // arc. Before the fix it drew its next route there and its new lane began with the
        // chord to the old lane's end: its heading jumped by up to half the arc left (17.6° on
        // `held-out/helsinki-random` seed 81). It now draws once past the arc.
        let rect = |x0: f64, y0: f64, x1: f64, y1: f64| vec![rect_ring(x0, y0, x1, y1)];
        let world = crate::world::World::new(
            vec![],
            vec![rect(0.0, -4.0, 204.0, 4.0), rect(196.0, -4.0, 204.0, 300.0)],
            (Vec2::new(-10.0, -10.0), Vec2::new(250.0, 310.0)),
        );
        let net = RoadNetwork::new(&world);
        let route = Route {
            path: Polyline::new(vec![
                Vec2::new(150.0, 0.0),
                Vec2::new(200.0, 0.0),
                Vec2::new(200.0, 8.0),
            ])
            .unwrap(),
            junctions_m: vec![],
            half_width_m: 4.0,
            lane: None,
        };
        let cfg = TrafficConfig::default();
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let mut car = Actor::driving_car(0, &route, 0.0, 8.0, true);
        for frame in 0..200 {
            let before = car.pose;
            advance(&mut car, &[], 0.1, &cfg, &net, &mut rng);
            let step = car.speed_mps * 0.1;
            let turn = wrap_angle(car.pose.heading_rad - before.heading_rad);
            assert!(
                turn.abs() <= step / MIN_TURN_RADIUS_M + 1e-9,
                "frame {frame}: turned {:.1}° at {:.2} m/s",
                turn.to_degrees(),
                car.speed_mps
            );
        }
        // It took a next route north and drove on it.
        assert!(car.pose.position_m.y > 60.0, "{:?}", car.pose);
    }

    /// A car on a lane east along y = −1.75, turning left at x ≈ 100 onto one north along
    /// x = 101.75, driven 25 s with the obstacles `others`.
    fn turn_left_past(others: &[Obstacle]) -> Actor {
        use rand::SeedableRng;
        let route = Route {
            path: Polyline::new(vec![
                Vec2::new(0.0, 0.0),
                Vec2::new(60.0, 0.0),
                Vec2::new(60.0, 100.0),
            ])
            .unwrap(),
            junctions_m: vec![],
            half_width_m: 4.0,
            lane: None,
        };
        let (cfg, net) = (TrafficConfig::default(), net());
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let mut car = Actor::driving_car(0, &route, 0.0, 8.0, true);
        for _ in 0..250 {
            advance(&mut car, others, 0.1, &cfg, &net, &mut rng);
        }
        car
    }

    #[test]
    fn a_car_brakes_for_a_car_crossing_from_the_right_and_not_for_one_from_the_left() {
        // A car at (0, −1.75) heading east on a straight lane along y = −1.75. A car heading
        // north whose centre is 6 m ahead and 3 m right of the lane, (6, −4.75), reaches
        // 2.25 m (its half length) towards it: it counts (1.6 + 2.25 = 3.85 m > 3 m), bumper to
        // bumper 6 − 2.25 − 2.25 = 1.5 m away. (On helsinki-short seed 11, a car turning across
        // the ego's lane from the right was seen only once its centre was inside the ego, and
        // both stood there for good.) The same car mirrored to the left, (6, 1.25) heading
        // south, must yield and is not waited for: infinite.
        let route = Route {
            path: Polyline::new(vec![Vec2::new(0.0, 0.0), Vec2::new(100.0, 0.0)]).unwrap(),
            junctions_m: vec![],
            half_width_m: 4.0,
            lane: None,
        };
        let car = Actor::driving_car(0, &route, 0.0, 8.0, true);
        assert!(
            (car.pose.position_m.y + 1.75).abs() < 1e-9,
            "{:?}",
            car.pose
        );
        let crossing = |y: f64, heading_rad: f64| Obstacle {
            id: 9,
            position: Vec2::new(6.0, y),
            half_length_m: CAR_HALF_LENGTH_M,
            heading_rad,
        };
        let from_right = car.gap_ahead(&[crossing(-4.75, std::f64::consts::FRAC_PI_2)], 40.0);
        assert!((from_right - 1.5).abs() < 1e-9, "{from_right}");
        let from_left = car.gap_ahead(&[crossing(1.25, -std::f64::consts::FRAC_PI_2)], 40.0);
        assert!(from_left.is_infinite(), "{from_left}");
        // Parked parallel at the right kerb, 3 m right of the lane: not in it.
        let parked = car.gap_ahead(&[crossing(-4.75, 0.0)], 40.0);
        assert!(parked.is_infinite(), "{parked}");
    }

    #[test]
    fn a_car_in_a_turn_brakes_for_what_is_in_its_lane_not_for_what_is_straight_ahead() {
        // Parked at the right kerb of the street it turns into, 2.75 m from its lane: straight
        // ahead of the car halfway round (at 45°, near (59.5, 0.2)), beside its lane.
        let kerb = Obstacle {
            id: 9,
            position: Vec2::new(64.5, 5.5),
            half_length_m: CAR_HALF_LENGTH_M,
            heading_rad: std::f64::consts::FRAC_PI_2,
        };
        let car = turn_left_past(&[kerb]);
        assert!(car.pose.position_m.y > 90.0, "{:?}", car.pose);
        // Stopped in its lane 30 m up the new street: it queues behind it, the gap measured
        // along the lane.
        let stopped = Obstacle {
            id: 9,
            position: Vec2::new(61.75, 30.0),
            half_length_m: CAR_HALF_LENGTH_M,
            heading_rad: std::f64::consts::FRAC_PI_2,
        };
        let car = turn_left_past(&[stopped]);
        let gap = 30.0 - car.pose.position_m.y - 2.0 * CAR_HALF_LENGTH_M;
        assert!(car.speed_mps < 0.01);
        // (The lane's corner is offset along the mean of its two segments' normals, so its
        // second segment leans a little: x = 61.56 at y = 23.)
        assert!(
            (car.pose.position_m.x - 61.75).abs() < 0.3,
            "{:?}",
            car.pose
        );
        assert!((0.5..=STANDSTILL_GAP_M + 0.5).contains(&gap), "gap {gap}");
    }

    #[test]
    fn a_moving_bus_covers_the_cells_whose_centres_it_holds() {
        use crate::label::Label;
        use crate::truth::{ActorRoles, CentreTruth, label_window_centre};
        use crate::world::World;
        use geodata::CellWindow;
        // A bus (12 × 2.55 m) at (10, 5) heading east at 8 m/s: x ∈ [4, 16], y ∈ [3.725, 6.275].
        // On 1 m cells from (0, 0) the centres c + 0.5 inside are columns 4–15 (12) and rows 4–5
        // (4.5, 5.5; 3.5 and 6.5 fall outside): 24 cells of truth M. Rows 3 and 6 are covered
        // in part (the band), from column 4 to 15: 24 band cells.
        let route = straight_route(100.0, None);
        let mut bus = Actor::driving_vehicle(0, &route, 0.0, 8.0, true, Body::BUS);
        bus.pose = Pose2::new(Vec2::new(10.0, 5.0), 0.0);
        assert_eq!(
            bus.footprint,
            Footprint::Rect {
                half_length_m: 6.0,
                half_width_m: 1.275
            }
        );
        assert!(is_large_vehicle(&bus));
        assert!(!is_large_vehicle(&Actor::driving_car(
            1, &route, 0.0, 8.0, true
        )));
        let world = World::new(vec![], vec![], (Vec2::new(0.0, 0.0), Vec2::new(24.0, 10.0)));
        let window = CellWindow {
            first_col: 0,
            first_row: 0,
            width: 24,
            height: 10,
            cell_size_m: 1.0,
        };
        let mut truth = CentreTruth::default();
        label_window_centre(&world, &[bus], ActorRoles::default(), &window, &mut truth);
        let moving: Vec<(usize, usize)> = (0..10)
            .flat_map(|r| (0..24).map(move |c| (c, r)))
            .filter(|&(c, r)| truth.labels[r * 24 + c] == Label::M)
            .collect();
        assert_eq!(moving.len(), 24);
        assert!(
            moving
                .iter()
                .all(|&(c, r)| (4..=15).contains(&c) && (4..=5).contains(&r))
        );
        let band = truth.band.iter().filter(|&&b| b).count();
        assert_eq!(band, 24);
    }

    #[test]
    fn a_bus_turns_on_its_own_wider_arc_and_slower() {
        use rand::SeedableRng;
        // East 100 m, then north: the corner is rounded by the bus's tightest arc, R = 9 m,
        // where it accepts 3 m/s² sideways: √(3 · 9) = 5.196 m/s (a car: 3.873 m/s on 5 m).
        let route = east_then_north();
        let (cfg, net) = (TrafficConfig::default(), net());
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let mut bus = Actor::driving_vehicle(0, &route, 0.0, 10.0, true, Body::BUS);
        let corner_mps = (CORNER_LATERAL_MPS2 * BUS_MIN_TURN_RADIUS_M).sqrt();
        assert!((corner_mps - 5.196).abs() < 1e-3);
        let (mut max_turn_per_m, mut slowest): (f64, f64) = (0.0, f64::INFINITY);
        for _ in 0..250 {
            let before = bus.pose;
            advance(&mut bus, &[], 0.1, &cfg, &net, &mut rng);
            let turn = wrap_angle(bus.pose.heading_rad - before.heading_rad).abs();
            let moved = bus.pose.position_m.minus(before.position_m).norm();
            if moved > 0.05 {
                max_turn_per_m = max_turn_per_m.max(turn / moved);
            }
            let heading = bus.pose.heading_rad.to_degrees();
            if (20.0..=70.0).contains(&heading) {
                assert!(bus.speed_mps <= corner_mps + 1e-9, "{}", bus.speed_mps);
                slowest = slowest.min(bus.speed_mps);
            }
        }
        // At most 1 / 9 rad a metre (a chord's heading change over its length is within a
        // hair of the arc's), and it turned the whole corner at the arc's speed, not slower.
        assert!(
            max_turn_per_m <= 1.0 / BUS_MIN_TURN_RADIUS_M + 1e-3,
            "{max_turn_per_m}"
        );
        assert!(
            max_turn_per_m > 1.0 / BUS_MIN_TURN_RADIUS_M - 0.01,
            "{max_turn_per_m}"
        );
        assert!(
            (corner_mps - 0.5..=corner_mps + 1e-9).contains(&slowest),
            "{slowest}"
        );
        assert!(bus.pose.position_m.y > 50.0, "{:?}", bus.pose);
    }

    #[test]
    fn a_car_queues_behind_a_stopped_bus_from_the_bus_rear() {
        // The bus's centre at x = 60: its rear at 54, so the car stops with its front bumper
        // 0.5–3 m before 54 (a car leader's rear would be at 57.75).
        use rand::SeedableRng;
        let route = straight_route(500.0, None);
        let bus = Actor::driving_vehicle(9, &route, 0.0, 0.0, true, Body::BUS);
        let mut bus_now = bus.clone();
        bus_now.pose = Pose2::new(Vec2::new(60.0, -1.75), 0.0);
        let leaders = obstacles(&[bus_now], &[]);
        assert_eq!(leaders[0].half_length_m, 6.0);
        let (cfg, net) = (TrafficConfig::default(), net());
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let mut car = Actor::driving_car(0, &route, 0.0, 10.0, true);
        for _ in 0..200 {
            advance(&mut car, &leaders, 0.1, &cfg, &net, &mut rng);
        }
        let gap = 54.0 - (car.pose.position_m.x + CAR_HALF_LENGTH_M);
        assert!(car.speed_mps < 0.01);
        assert!((0.5..=STANDSTILL_GAP_M + 0.5).contains(&gap), "gap {gap}");
    }

    #[test]
    fn shares_give_buses_and_trucks_and_zero_shares_draw_nothing_more() {
        use rand::SeedableRng;
        let town = crate::testing::town();
        let world = crate::world::World::from_polygons(&town.buildings, &town.roads, &town.extent);
        let net = RoadNetwork::new(&world);
        let only = |bus_share: f64, truck_share: f64| TrafficConfig {
            moving_cars: 6,
            parked_cars: 0,
            pedestrians: 0,
            infrastructure: 0,
            bus_share,
            truck_share,
            ..TrafficConfig::default()
        };
        let draw = |cfg: &TrafficConfig| {
            let mut rng = rand::rngs::StdRng::seed_from_u64(7);
            let actors = populate(&net, cfg, &[], &[], &mut rng);
            (actors, rng.random::<u64>())
        };
        // Every moving car a bus: 12 m long, and centres 10 + 3.75 + 3.75 = 17.5 m apart at
        // least (10 m between two cars' centres, grown by each bus's extra half length).
        let (buses, _) = draw(&only(1.0, 0.0));
        assert!(buses.len() >= 2, "{}", buses.len());
        for (i, a) in buses.iter().enumerate() {
            assert_eq!(a.footprint, Body::BUS.footprint());
            for b in &buses[i + 1..] {
                let d = a.pose.position_m.minus(b.pose.position_m).norm();
                assert!(d >= 17.5, "{d}");
            }
        }
        // Every one a truck, 8–10 m long and 2.5 m wide.
        let (trucks, _) = draw(&only(0.0, 1.0));
        assert!(!trucks.is_empty());
        for t in &trucks {
            let Footprint::Rect {
                half_length_m,
                half_width_m,
            } = t.footprint
            else {
                panic!("{:?}", t.footprint)
            };
            assert!((4.0..=5.0).contains(&half_length_m), "{half_length_m}");
            assert_eq!(half_width_m, 1.25);
        }
        // Shares 0: a compact car, and no draw for its body. One moving car on an empty
        // scene is placed at its first attempt: the route, its start and its cruise speed are
        // the only draws, so the stream after `populate` is the one after those three.
        let (cars, after) = draw(&TrafficConfig {
            moving_cars: 1,
            ..only(0.0, 0.0)
        });
        assert_eq!(cars.len(), 1);
        assert_eq!(cars[0].footprint, Body::CAR.footprint());
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let route = net.random_route(150.0, 600.0, &mut rng).unwrap();
        let _start = rng.random_range(0.0..=route.path.length_m() * 0.5);
        let _cruise = uniform(&mut rng, TrafficConfig::default().car_speed_mps);
        assert_eq!(after, rng.random::<u64>());
    }

    #[test]
    fn parked_cars_leave_the_kept_lane_free() {
        use rand::SeedableRng;
        // The town's 10 m north–south street at x = 100: a car parked at its kerb stands
        // 5 − 1.2 = 3.8 m from the middle, and the lane kept clear runs 1.75 m west of the middle
        // (x = 98.25): the west kerb's cars (x = 96.2) would stand 2.05 m from it, under the 2.1 m
        // clearance; the east kerb's (x = 103.8) 5.55 m.
        let town = crate::testing::town();
        let world = crate::world::World::from_polygons(&town.buildings, &town.roads, &town.extent);
        let net = RoadNetwork::new(&world);
        let cfg = TrafficConfig {
            moving_cars: 0,
            parked_cars: 30,
            pedestrians: 0,
            infrastructure: 0,
            ..TrafficConfig::default()
        };
        let lane: Vec<Vec2> = (0..=400)
            .map(|i| Vec2::new(98.25, i as f64 * 0.5))
            .collect();
        let in_lane = |cars: &[Actor]| {
            cars.iter()
                .filter(|car| {
                    let p = car.pose.position_m;
                    (p.x - 98.25).abs() < LANE_CLEARANCE_M && (0.0..=200.0).contains(&p.y)
                })
                .count()
        };
        let free = populate(
            &net,
            &cfg,
            &[],
            &[],
            &mut rand::rngs::StdRng::seed_from_u64(5),
        );
        assert!(in_lane(&free) > 0, "the draw must reach the west kerb");
        let kept = populate(
            &net,
            &cfg,
            &[],
            &lane,
            &mut rand::rngs::StdRng::seed_from_u64(5),
        );
        assert!(kept.len() >= 10, "{}", kept.len());
        assert_eq!(in_lane(&kept), 0);
    }

    #[test]
    fn parked_cars_stand_clear_of_junctions() {
        use rand::SeedableRng;
        // Two 10 m streets crossing at (100, 100): the pixels flagged around the junction span
        // x 97–102, y 98–103 (centres 97.5–101.5, 98.5–102.5); 10 m beyond them is clear.
        let town = crate::testing::town();
        let world = crate::world::World::from_polygons(&town.buildings, &town.roads, &town.extent);
        let net = RoadNetwork::new(&world);
        assert!(net.junction_within(Vec2::new(100.0, 100.0), 1.0));
        assert!(net.junction_within(Vec2::new(100.0, 89.0), 10.0));
        assert!(!net.junction_within(Vec2::new(100.0, 80.0), 10.0));
        let cfg = TrafficConfig {
            moving_cars: 0,
            parked_cars: 20,
            pedestrians: 0,
            infrastructure: 0,
            ..TrafficConfig::default()
        };
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let cars = populate(&net, &cfg, &[], &[], &mut rng);
        assert!(cars.len() >= 10, "{}", cars.len());
        for car in &cars {
            let to_crossing = car.pose.position_m.minus(Vec2::new(100.0, 100.0)).norm();
            assert!(to_crossing > 10.0, "{:?}", car.pose);
        }
    }

    /// A pedestrian on a pavement along y = 110 (x 0..200) through a building (x 60..140).
    fn pedestrian_through_a_building(s_m: f64) -> (RoadNetwork, Actor) {
        use rand::SeedableRng;
        let rect = rect_ring;
        let building = crate::world::Building::new(vec![rect(60.0, 105.0, 140.0, 115.0)]).unwrap();
        let net = RoadNetwork::new(&crate::world::World::new(
            vec![building],
            vec![vec![rect(0.0, 96.0, 200.0, 104.0)]],
            (Vec2::new(0.0, 0.0), Vec2::new(200.0, 200.0)),
        ));
        let path = Polyline::new(vec![Vec2::new(0.0, 110.0), Vec2::new(200.0, 110.0)]).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let mut pedestrian = Actor::pedestrian(0, path, &mut rng, &TrafficConfig::default());
        if let Motion::Walking(w) = &mut pedestrian.motion {
            w.s_m = s_m;
            pedestrian.pose.position_m = w.path.at(s_m).0;
        }
        (net, pedestrian)
    }

    fn walked(pedestrian: &Actor) -> (Vec<Vec2>, f64) {
        let Motion::Walking(w) = &pedestrian.motion else {
            panic!("not walking");
        };
        (w.path.points().to_vec(), w.s_m)
    }

    #[test]
    fn a_pedestrian_turns_at_a_wall_across_its_pavement() {
        // From x = 20 it walks x 0..59 (the pixel centred at 60.5 is the building's first).
        let (net, pedestrian) = pedestrian_through_a_building(20.0);
        let kept = kept_out_of_buildings(&net, pedestrian.clone());
        let (points, s_m) = walked(&kept);
        assert_eq!(points, vec![Vec2::new(0.0, 110.0), Vec2::new(59.0, 110.0)]);
        assert_eq!(s_m, 20.0);
        assert_eq!(kept.pose.position_m, pedestrian.pose.position_m);
        // Drawn inside, at x = 100: it starts at the nearest clear point, x = 140 (41 m to
        // x = 59), and walks x 140..200.
        let (net, pedestrian) = pedestrian_through_a_building(100.0);
        let kept = kept_out_of_buildings(&net, pedestrian);
        let (points, s_m) = walked(&kept);
        assert_eq!(
            points,
            vec![Vec2::new(140.0, 110.0), Vec2::new(200.0, 110.0)]
        );
        assert_eq!(s_m, 0.0);
        assert_eq!(kept.pose.position_m, Vec2::new(140.0, 110.0));
    }
}
