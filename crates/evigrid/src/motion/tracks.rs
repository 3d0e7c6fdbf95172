//! Tracks: clusters followed from frame to frame, each with a filtered velocity.
//!
//! Every frame, tracks are predicted (position moved by the velocity, the velocity's variance
//! grown), then each cluster joins the nearest free track predicted within the gate (greedy, by
//! distance), or starts a new one. A track keeps its velocity while its object is hidden, for
//! up to `max_coast_s`, so that an object coming out of occlusion, whose cells have no history
//! to register against, still carries its speed.

use super::REPORT_MIN_EXISTENCE;
use super::kalman::VelocityFilter;
use crate::params::MotionParams;

/// What a frame says about one cluster.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Observation {
    /// Centroid of the cluster's cells, m (east, north).
    pub(crate) centroid_m: [f64; 2],
    /// Velocity measured by registration, m/s, with its variance per axis, (m/s)².
    pub(crate) velocity: Option<([f64; 2], f64)>,
    /// The registration's mean span, s (Σ τ_k² / Σ τ_k over the past frames it matched: the
    /// time its velocity's displacement covers), 0 without a velocity.
    pub(crate) span_s: f64,
}

/// How wrong the pose of this frame may be, for the displacement test of
/// `motion.displaced_pose_sigmas`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct PoseError {
    /// The sensor's position, world metres.
    pub(crate) sensor_xy_m: [f64; 2],
    /// Standard deviation of the position's error per axis, m.
    pub(crate) sigma_m: f64,
    /// Standard deviation of the heading's error, rad.
    pub(crate) sigma_rad: f64,
}

impl PoseError {
    /// The standard deviation per axis of the apparent displacement of a static object at
    /// `at_m` between two scans with independent pose errors: √2 · √(σ² + (r·σ_θ)²), r its
    /// range (the heading's error moves it by its lever arm).
    pub(crate) fn displacement_sigma_m(&self, at_m: [f64; 2]) -> f64 {
        let range_m = (at_m[0] - self.sensor_xy_m[0]).hypot(at_m[1] - self.sensor_xy_m[1]);
        std::f64::consts::SQRT_2 * self.sigma_m.hypot(range_m * self.sigma_rad)
    }
}

/// One followed object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Track {
    /// Stable identifier, unique over the stage's life.
    pub(crate) id: u64,
    /// Last centroid, moved by the velocity while the object is not seen, m.
    pub(crate) position_m: [f64; 2],
    /// Velocity east and north.
    pub(crate) velocity: [VelocityFilter; 2],
    /// Time the track was last observed, s.
    pub(crate) last_seen_s: f64,
    /// Time the track started, s.
    pub(crate) first_seen_s: f64,
    /// Registrations that measured its velocity (none: it knows nothing of motion).
    pub(crate) measurements: u32,
    /// Net displacement, m, summed over the frames the track was judged moving in
    /// ([`is_moving`]): once it reaches `mobile_after_travel_m` the object is a
    /// mobile one, so when static it is stopped (S), not infrastructure.
    pub(crate) travel_m: [f64; 2],
    /// Frames an observation joined the track (its first included).
    pub(crate) hits: u32,
    /// Frames the track was predicted but not observed (coasting).
    pub(crate) misses: u32,
    /// Frames the track was judged moving ([`is_moving`]).
    pub(crate) moving_frames: u32,
    /// Time the track was judged moving, s: with `travel_m`, what makes it a mobile object.
    pub(crate) moving_s: f64,
    /// Net displacement as registered, m: the first registration's velocity times its mean
    /// span, then each registration's velocity times the frame's interval. A static object's
    /// apparent shifts under pose error come and go, so this stays within the pose's error;
    /// a mover's grows.
    pub(crate) registered_m: [f64; 2],
    /// Whether `registered_m` is longer than `motion.displaced_pose_sigmas` standard
    /// deviations of the displacement the pose's error explains at the track's range (always
    /// with the test off): moving evidence requires it.
    pub(crate) displaced: bool,
}

/// Probability that a return-producing cluster is a real object, per frame: of a track being
/// observed when it exists (detection), and of a cluster appearing where nothing is (false
/// alarm: noise, a face of a static object reappearing). With them the existence probability
/// of a track is a binary Bayes filter from even odds: × P_D/P_FA per hit, × (1 − P_D)/(1 −
/// P_FA) per miss.
const P_DETECTION: f64 = 0.9;
/// See [`P_DETECTION`].
const P_FALSE_ALARM: f64 = 0.3;

impl Track {
    /// The probability that the object exists: `P_DETECTION` / `P_FALSE_ALARM` Bayes filter over
    /// its hits and misses, from even odds. 1 hit: 0.75, 2: 0.9, 3: 0.964; a miss divides the
    /// odds by 7.
    pub(crate) fn existence_probability(&self) -> f64 {
        let log_odds = f64::from(self.hits) * (P_DETECTION / P_FALSE_ALARM).ln()
            + f64::from(self.misses) * ((1.0 - P_DETECTION) / (1.0 - P_FALSE_ALARM)).ln();
        1.0 / (1.0 + (-log_odds).exp())
    }
}

/// Whether the track moves now: fast enough, and registered often enough to say so. (Its
/// cells take moving evidence only once it is `displaced` too, [`super::evidence::track_mass`];
/// its prior and its travel do not wait for that: a slow mover held back whose registrations
/// lose the prior would read zero and never get displaced.)
pub(crate) fn is_moving(track: &Track, params: &MotionParams) -> bool {
    let [x, y] = track.velocity;
    track.measurements > 0
        && (track.measurements as usize) >= params.moving_after_measurements
        && x.mean_mps.hypot(y.mean_mps) >= params.min_speed_mps
}

/// The tracks and the association scratch, kept between frames.
#[derive(Clone, Debug, Default)]
pub(crate) struct Tracks {
    tracks: Vec<Track>,
    pairs: Vec<(f64, u32, u32)>,
    taken: Vec<bool>,
    /// After [`Tracks::update`], the track of each observation.
    assigned: Vec<u32>,
    /// After [`Tracks::predictions`], the track predicting into each cluster.
    predicting: Vec<u32>,
    /// The id the next track gets.
    next_id: u64,
}

impl Tracks {
    /// Forgets every track.
    pub(crate) fn clear(&mut self) {
        self.tracks.clear();
    }

    /// Number of tracks.
    pub(crate) fn len(&self) -> usize {
        self.tracks.len()
    }

    /// The track observation `k` of the last update belongs to.
    pub(crate) fn of_observation(&self, k: usize) -> Option<&Track> {
        self.tracks.get(*self.assigned.get(k)? as usize)
    }

    /// Predicts every track to `now_s` (`dt_s` after the last frame), drops those unseen for
    /// too long, and assigns the frame's observations to tracks, new ones where none is near.
    /// `pose` is this frame's pose error, for the displacement test.
    pub(crate) fn update(
        &mut self,
        observations: &[Observation],
        now_s: f64,
        dt_s: f64,
        pose: PoseError,
        params: &MotionParams,
    ) {
        // Predict, and drop tracks lost for too long.
        self.tracks
            .retain(|t| now_s - t.last_seen_s <= params.max_coast_s);
        for t in &mut self.tracks {
            let before = t.velocity.map(|v| v.mean_mps);
            for (p, v) in t.position_m.iter_mut().zip(&mut t.velocity) {
                *p += v.mean_mps * dt_s;
                v.predict(dt_s, params.accel_sigma_mps2, params.jerk_sigma_mps3);
            }
            // A braking road user stops; it does not back up: an acceleration that carries
            // the velocity through zero leaves it at rest.
            let [x, y] = t.velocity.map(|v| v.mean_mps);
            if x * before[0] + y * before[1] < 0.0 {
                for v in &mut t.velocity {
                    v.mean_mps = 0.0;
                    v.accel_mps2 = 0.0;
                }
            }
            braking_only(&mut t.velocity);
        }

        // Confirmed tracks first (existence probability at least `REPORT_MIN_EXISTENCE`: two
        // hits without a miss), nearest pairs first within each tier, each track and
        // observation used once. A tentative track (a stray cluster seen once, coasting) must
        // not take the cluster of an object tracked for a while because it happens to sit
        // nearer its centroid than that track's prediction.
        self.pairs.clear();
        let gate_sq = params.gate_m * params.gate_m;
        for (ti, t) in self.tracks.iter().enumerate() {
            for (oi, o) in observations.iter().enumerate() {
                let dx = t.position_m[0] - o.centroid_m[0];
                let dy = t.position_m[1] - o.centroid_m[1];
                let d_sq = dx * dx + dy * dy;
                if d_sq <= gate_sq && velocity_agrees(t, o) {
                    self.pairs.push((d_sq, ti as u32, oi as u32));
                }
            }
        }
        let tracks = &self.tracks;
        let tentative = |ti: u32| {
            tracks
                .get(ti as usize)
                .is_none_or(|t| (t.existence_probability() as f32) < REPORT_MIN_EXISTENCE)
        };
        // Within a tier, an observation with a velocity before one without: a piece of a
        // cluster left unmeasured (`contradicted_unmeasured`) agrees with every track and
        // must not take a moving track from the piece whose velocity fits it.
        let unmeasured = |oi: u32| {
            observations
                .get(oi as usize)
                .is_none_or(|o| o.velocity.is_none())
        };
        self.pairs.sort_unstable_by(|a, b| {
            tentative(a.1)
                .cmp(&tentative(b.1))
                .then(unmeasured(a.2).cmp(&unmeasured(b.2)))
                .then(a.0.total_cmp(&b.0))
        });
        pair_in_order(
            &self.pairs,
            self.tracks.len(),
            observations.len(),
            &mut self.taken,
            &mut self.assigned,
        );

        // Update the tracks observed; start one for each observation left.
        let unknown_variance = params.max_speed_mps * params.max_speed_mps;
        for (oi, o) in observations.iter().enumerate() {
            let ti = match self.assigned[oi] {
                u32::MAX => {
                    self.next_id += 1;
                    self.tracks.push(Track {
                        id: self.next_id,
                        position_m: o.centroid_m,
                        velocity: [VelocityFilter::new(0.0, unknown_variance); 2],
                        last_seen_s: now_s,
                        first_seen_s: now_s,
                        measurements: 0,
                        travel_m: [0.0; 2],
                        hits: 0,
                        misses: 0,
                        moving_frames: 0,
                        moving_s: 0.0,
                        registered_m: [0.0; 2],
                        displaced: params.displaced_pose_sigmas == 0.0,
                    });
                    self.assigned[oi] = (self.tracks.len() - 1) as u32;
                    self.tracks.len() - 1
                }
                ti => ti as usize,
            };
            let t = &mut self.tracks[ti];
            t.position_m = o.centroid_m;
            t.last_seen_s = now_s;
            t.hits = t.hits.saturating_add(1);
            if let Some((v, variance)) = o.velocity {
                // The registration's velocity is the mean over its frames, half its mean
                // span back on average (`motion.jerk_sigma_mps3`).
                for (filter, &z) in t.velocity.iter_mut().zip(&v) {
                    filter.update_lagged(z, variance, o.span_s / 2.0);
                }
                braking_only(&mut t.velocity);
                // The first registration covers its whole span; each later one adds the
                // frame's interval (its span overlaps the ones before).
                let span_s = if t.measurements == 0 { o.span_s } else { dt_s };
                for (d, z) in t.registered_m.iter_mut().zip(v) {
                    *d += z * span_s;
                }
                t.measurements = t.measurements.saturating_add(1);
            }
            t.displaced = params.displaced_pose_sigmas == 0.0
                || t.registered_m[0].hypot(t.registered_m[1])
                    > params.displaced_pose_sigmas * pose.displacement_sigma_m(t.position_m);
            if is_moving(t, params) {
                for (d, v) in t.travel_m.iter_mut().zip(&t.velocity) {
                    *d += v.mean_mps * dt_s;
                }
                t.moving_frames = t.moving_frames.saturating_add(1);
                t.moving_s += dt_s;
            }
        }
        // The tracks predicted and not observed coast: one miss each.
        for (t, &taken) in self.tracks.iter_mut().zip(&self.taken) {
            if !taken {
                t.misses = t.misses.saturating_add(1);
            }
        }
    }
}

impl Tracks {
    /// The velocity, m/s, that a moving track predicts for each of this frame's clusters
    /// (centroids `centroids_m`, `dt_s` after the last frame, at `now_s`), or `None`: the
    /// prior of `motion.prior_after_moving_frames` (off at 0: every entry `None`).
    ///
    /// A track gives its prior when it is confirmed (existence probability at least
    /// [`REPORT_MIN_EXISTENCE`]), moving ([`is_moving`]) and has been judged moving for at
    /// least `prior_after_moving_frames` frames; it goes to the cluster nearest its predicted
    /// position within `gate_m`, nearest pairs first, each track and cluster used once (the
    /// association of [`Tracks::update`] before any velocity is measured).
    pub(crate) fn predictions(
        &mut self,
        centroids_m: &[[f64; 2]],
        now_s: f64,
        dt_s: f64,
        params: &MotionParams,
        out: &mut Vec<Option<[f64; 2]>>,
    ) {
        out.clear();
        out.resize(centroids_m.len(), None);
        let needed = params.prior_after_moving_frames;
        if needed == 0 {
            return;
        }
        self.pairs.clear();
        let gate_sq = params.gate_m * params.gate_m;
        for (ti, t) in self.tracks.iter().enumerate() {
            let gives = now_s - t.last_seen_s <= params.max_coast_s
                && is_moving(t, params)
                && t.moving_frames as usize >= needed
                && t.existence_probability() as f32 >= REPORT_MIN_EXISTENCE;
            if !gives {
                continue;
            }
            let [x, y] = [0, 1].map(|a| t.position_m[a] + t.velocity[a].mean_mps * dt_s);
            for (ci, c) in centroids_m.iter().enumerate() {
                let d_sq = (x - c[0]).powi(2) + (y - c[1]).powi(2);
                if d_sq <= gate_sq {
                    self.pairs.push((d_sq, ti as u32, ci as u32));
                }
            }
        }
        self.pairs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        pair_in_order(
            &self.pairs,
            self.tracks.len(),
            centroids_m.len(),
            &mut self.taken,
            &mut self.predicting,
        );
        for (prediction, &ti) in out.iter_mut().zip(&self.predicting) {
            if let Some(track) = self.tracks.get(ti as usize) {
                *prediction = Some(track.velocity.map(|v| v.mean_mps));
            }
        }
    }
}

/// Keeps only the part of the acceleration that slows the velocity down or turns it: its
/// component along the velocity is dropped when it speeds the velocity up.
fn braking_only(velocity: &mut [VelocityFilter; 2]) {
    let [vx, vy] = velocity.map(|v| v.mean_mps);
    let [ax, ay] = velocity.map(|v| v.accel_mps2);
    let speed_sq = vx * vx + vy * vy;
    let along = ax * vx + ay * vy;
    if speed_sq > 0.0 && along > 0.0 {
        velocity[0].accel_mps2 -= along / speed_sq * vx;
        velocity[1].accel_mps2 -= along / speed_sq * vy;
    }
}

/// Pairs each track with at most one observation and each observation with at most one track,
/// taking `pairs` (distance², track, observation) in their order: `assigned[o]` is the track
/// paired with observation `o` (`u32::MAX`: none), `taken[t]` whether track `t` was paired.
fn pair_in_order(
    pairs: &[(f64, u32, u32)],
    tracks: usize,
    observations: usize,
    taken: &mut Vec<bool>,
    assigned: &mut Vec<u32>,
) {
    taken.clear();
    taken.resize(tracks, false);
    assigned.clear();
    assigned.resize(observations, u32::MAX);
    for &(_, ti, oi) in pairs {
        if !taken[ti as usize] && assigned[oi as usize] == u32::MAX {
            taken[ti as usize] = true;
            assigned[oi as usize] = ti;
        }
    }
}

/// χ²(2) quantile 0.999: a measured velocity further than this (in Mahalanobis distance
/// squared) from a track's is another object, typically a parked car that a passing car's
/// track reaches.
const VELOCITY_GATE: f64 = 13.8;

/// Whether the observation's measured velocity, if any, fits the track's, if it has one.
fn velocity_agrees(track: &Track, observation: &Observation) -> bool {
    let Some((v, variance)) = observation.velocity else {
        return true;
    };
    if track.measurements == 0 {
        return true;
    }
    let chi_sq: f64 = track
        .velocity
        .iter()
        .zip(&v)
        .map(|(f, &z)| (z - f.mean_mps).powi(2) / (f.variance + variance))
        .sum();
    chi_sq <= VELOCITY_GATE
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seen(x: f64, v: Option<f64>) -> Observation {
        Observation {
            centroid_m: [x, 0.0],
            velocity: v.map(|v| ([v, 0.0], 1.0)),
            span_s: 0.1,
        }
    }

    #[test]
    fn existence_probability_grows_with_hits_and_falls_with_misses() {
        let params = MotionParams::default();
        let mut tracks = Tracks::default();
        let p = |t: &Tracks| t.tracks[0].existence_probability();
        tracks.update(&[seen(0.0, None)], 0.0, 0.1, PoseError::default(), &params);
        // Odds 3 per hit from even: 1 hit 3/4, 2 hits 9/10.
        assert!((p(&tracks) - 0.75).abs() < 1e-12);
        tracks.update(&[seen(0.0, None)], 0.1, 0.1, PoseError::default(), &params);
        assert!((p(&tracks) - 0.9).abs() < 1e-12);
        // A miss: odds 9 · (0.1 / 0.7) = 9/7, p = 9/16.
        tracks.update(&[], 0.2, 0.1, PoseError::default(), &params);
        assert_eq!((tracks.tracks[0].hits, tracks.tracks[0].misses), (2, 1));
        assert!((p(&tracks) - 9.0 / 16.0).abs() < 1e-12);
    }

    #[test]
    fn a_track_follows_its_object_and_coasts_through_a_gap() {
        let params = MotionParams::default();
        let mut tracks = Tracks::default();
        tracks.update(&[seen(0.0, None)], 0.0, 0.0, PoseError::default(), &params);
        assert_eq!(tracks.len(), 1);
        assert!(
            tracks
                .of_observation(0)
                .is_some_and(|t| t.measurements == 0)
        );
        // 10 m/s east, measured from the second frame.
        for k in 1..6 {
            let x = k as f64;
            tracks.update(
                &[seen(x, Some(10.0))],
                0.1 * k as f64,
                0.1,
                PoseError::default(),
                &params,
            );
        }
        assert_eq!(tracks.len(), 1);
        let v = tracks
            .of_observation(0)
            .map_or(0.0, |t| t.velocity[0].mean_mps);
        assert!((v - 10.0).abs() < 0.5, "{v}");
        // Hidden for three frames, then seen where it should be, with no registration.
        for k in 6..9 {
            tracks.update(&[], 0.1 * k as f64, 0.1, PoseError::default(), &params);
        }
        tracks.update(&[seen(9.0, None)], 0.9, 0.1, PoseError::default(), &params);
        assert_eq!(tracks.len(), 1, "joined the coasting track");
        let t = tracks.of_observation(0).copied();
        assert!(t.is_some_and(|t| t.measurements == 5 && t.velocity[0].mean_mps > 9.0));
        // Far away: a new track; and after max_coast_s unseen, the old one is gone.
        tracks.update(&[seen(50.0, None)], 1.0, 0.1, PoseError::default(), &params);
        assert_eq!(tracks.len(), 2);
        tracks.update(&[], 2.05, 1.05, PoseError::default(), &params);
        assert_eq!(tracks.len(), 0);
    }

    #[test]
    fn a_track_remembers_its_net_travel_while_moving() {
        let params = MotionParams::default();
        let mut tracks = Tracks::default();
        // 5 m/s east for 6 frames of 0.1 s, measured (σ = 1 m/s) from the second one, then
        // braking at 5 m/s² to a stop, measured still for 10 more frames.
        let speeds = (0..6)
            .map(|_| 5.0)
            .chain((0..10).map(|k| 4.5 - 0.5 * k as f64));
        let mut x = 0.0;
        for (k, v) in speeds.chain([0.0; 10]).enumerate() {
            x += v * 0.1;
            let measured = (k > 0).then_some(v);
            tracks.update(
                &[seen(x, measured)],
                0.1 * k as f64,
                0.1,
                PoseError::default(),
                &params,
            );
        }
        assert_eq!(tracks.len(), 1);
        let t = tracks.of_observation(0).copied();
        // Every frame judged moving adds the filtered v·dt, which lags the braking (gain
        // about 0.26 with σ = 1 m/s): the 4.75 m driven and about 1.3 m more; the frames
        // below min_speed_mps add nothing.
        let travel = t.map_or(0.0, |t| t.travel_m[0]);
        assert!(travel > 4.75 && travel < 6.5, "{travel}");
        assert!(t.is_some_and(|t| !is_moving(&t, &params)));

        // A static object whose cluster jumps a cell back and forth (pose noise): each jump
        // registered against the last frame alone (0.5 m in 0.1 s, σ = 2.5 m/s), alternating
        // in sign; its net travel stays near zero.
        let mut tracks = Tracks::default();
        for k in 0..20 {
            let (x, v) = if k % 2 == 0 { (0.5, 5.0) } else { (0.0, -5.0) };
            let jump = Observation {
                centroid_m: [x, 0.0],
                velocity: Some(([v, 0.0], 6.25)),
                span_s: 0.1,
            };
            tracks.update(&[jump], 0.1 * k as f64, 0.1, PoseError::default(), &params);
        }
        assert_eq!(tracks.len(), 1);
        let travel = tracks.of_observation(0).map_or(9.0, |t| t.travel_m[0]);
        assert!(travel.abs() < params.mobile_after_travel_m, "{travel}");
    }

    #[test]
    fn a_static_cluster_does_not_join_a_moving_track_that_passes_it() {
        let params = MotionParams::default();
        let mut tracks = Tracks::default();
        for k in 0..5 {
            tracks.update(
                &[seen(k as f64, Some(10.0))],
                0.1 * k as f64,
                0.1,
                PoseError::default(),
                &params,
            );
        }
        // At 5 m the track meets a cluster measured static: a new track, still 2 in all.
        tracks.update(
            &[seen(5.0, Some(0.0))],
            0.5,
            0.1,
            PoseError::default(),
            &params,
        );
        assert_eq!(tracks.len(), 2);
        let v = tracks
            .of_observation(0)
            .map_or(1.0, |t| t.velocity[0].mean_mps);
        assert_eq!(v, 0.0);
    }

    #[test]
    fn a_piece_with_a_velocity_keeps_the_moving_track_against_a_nearer_unmeasured_one() {
        let params = MotionParams::default();
        let mut tracks = Tracks::default();
        // A track at 10 m/s east, seen at 0, 1, ..., 4 m (predicted at 5 m next).
        for k in 0..5 {
            tracks.update(
                &[seen(k as f64, Some(10.0))],
                0.1 * k as f64,
                0.1,
                PoseError::default(),
                &params,
            );
        }
        let id = tracks.of_observation(0).map(|t| t.id);
        // Two pieces of the cluster next frame, both within the 2 m gate of the prediction:
        // one unmeasured 0.5 m from it, one measured at 10 m/s 1.5 m from it. The measured
        // piece keeps the track (nearest first, the unmeasured piece would have taken it).
        tracks.update(
            &[seen(5.5, None), seen(6.5, Some(10.0))],
            0.5,
            0.1,
            PoseError::default(),
            &params,
        );
        assert_eq!(tracks.of_observation(1).map(|t| t.id), id);
        assert_ne!(tracks.of_observation(0).map(|t| t.id), id);
    }

    #[test]
    fn a_moving_track_predicts_into_the_nearest_cluster_only() {
        // The constant-velocity filter, whose numbers are worked out below (with
        // `jerk_sigma_mps3` the acceleration's variance after one prediction moves them a
        // little: the registration is read 0.05 s back).
        let params = MotionParams {
            jerk_sigma_mps3: 0.0,
            ..MotionParams::default()
        };
        let mut tracks = Tracks::default();
        // At x = 0, then at 1 m measured at 10 m/s (variance 1) from the new track's 0 ± 25
        // m/s (variance 625 + (3 · 0.1)² = 625.09): 10 · 625.09 / 626.09 = 9.98403 m/s.
        // Two hits (existence 0.9: confirmed), one frame judged moving.
        tracks.update(&[seen(0.0, None)], 0.0, 0.1, PoseError::default(), &params);
        tracks.update(
            &[seen(1.0, Some(10.0))],
            0.1,
            0.1,
            PoseError::default(),
            &params,
        );
        let v = 10.0 * 625.09 / 626.09;
        // Next frame it is predicted at 1 + 0.1 v = 1.9984 m: the car's cluster at 2.0 m
        // (0.0016 m off) takes the prior; a pole at 3.5 m, within the 2 m gate too, does not.
        let centroids = [[3.5, 0.0], [2.0, 0.0]];
        let mut out = Vec::new();
        tracks.predictions(&centroids, 0.2, 0.1, &params, &mut out);
        assert_eq!(out.len(), 2);
        assert_eq!(out[0], None);
        assert!(out[1].is_some_and(|[vx, vy]| (vx - v).abs() < 1e-9 && vy == 0.0));
        // The car's cluster missing, the pole alone: the track predicts into it.
        tracks.predictions(&centroids[..1], 0.2, 0.1, &params, &mut out);
        assert!(out[0].is_some());
        // Two frames judged moving needed, or the prior off: none.
        for frames in [2, 0] {
            let p = MotionParams {
                prior_after_moving_frames: frames,
                ..params.clone()
            };
            tracks.predictions(&centroids, 0.2, 0.1, &p, &mut out);
            assert_eq!(out, vec![None, None]);
        }
    }

    #[test]
    fn a_confirmed_track_keeps_its_object_against_a_nearer_tentative_one() {
        let params = MotionParams::default();
        let mut tracks = Tracks::default();
        // Track 1 from x = 0, then at 1.0 m moving at 10 m/s (variance 1): two hits, existence
        // 0.9, confirmed. A stray cluster at 3.0 m starts track 2 (3 m from track 1's
        // prediction, beyond the 2 m gate): one hit, existence 0.75, tentative.
        tracks.update(&[seen(0.0, None)], 0.0, 0.1, PoseError::default(), &params);
        tracks.update(
            &[seen(1.0, Some(10.0)), seen(3.0, None)],
            0.1,
            0.1,
            PoseError::default(),
            &params,
        );
        assert_eq!(tracks.of_observation(1).map(|t| t.id), Some(2));
        // Track 1 predicts 1.0 + 0.1 · 9.98 = 2.0 m; the car is seen at 2.9 m, 0.9 m from it
        // and 0.1 m from the stray track. Nearest first would hand the car to track 2; the
        // confirmed track is matched first.
        tracks.update(
            &[seen(2.9, Some(10.0))],
            0.2,
            0.1,
            PoseError::default(),
            &params,
        );
        let t = tracks.of_observation(0);
        assert_eq!(t.map(|t| (t.id, t.hits, t.measurements)), Some((1, 3, 2)));
    }

    #[test]
    fn the_pose_explains_a_displacement_of_root_two_sigma_at_the_range() {
        // Range 50 m (30, 40), σ = 0.3 m, σ_θ = 0.008 rad: √(0.3² + 0.4²) = 0.5, × √2.
        let pose = PoseError {
            sensor_xy_m: [1.0, 2.0],
            sigma_m: 0.3,
            sigma_rad: 0.008,
        };
        let sigma = pose.displacement_sigma_m([31.0, 42.0]);
        assert!(
            (sigma - 0.5 * std::f64::consts::SQRT_2).abs() < 1e-12,
            "{sigma}"
        );
    }

    /// `displaced_pose_sigmas` 3 under a pose error of 0.2 m per axis (heading exact): a
    /// static object's apparent displacement has σ = 0.2 · √2 = 0.28284 m, the gate is
    /// 0.84853 m.
    fn noisy_pose() -> (MotionParams, PoseError) {
        let params = MotionParams {
            displaced_pose_sigmas: 3.0,
            ..MotionParams::default()
        };
        let pose = PoseError {
            sensor_xy_m: [0.0, 10.0],
            sigma_m: 0.2,
            sigma_rad: 0.0,
        };
        (params, pose)
    }

    /// The pose's error at frame `k`, east, m: 0, +1 cell, 0, −1 cell (0.5 m cells), again.
    fn jitter(k: usize) -> f64 {
        [0.0, 0.5, 0.0, -0.5][k % 4]
    }

    /// Frame `k` of an object at `x` m east (seen at `x + jitter`), registered against the
    /// frame before (0.1 s): velocity (x_k − x_{k−1}) / 0.1, σ = 2.5 m/s (half a cell's
    /// quantisation each way over 0.1 s), from the second frame.
    fn seen_at(k: usize, x: impl Fn(usize) -> f64) -> Observation {
        let at = |k: usize| x(k) + jitter(k);
        Observation {
            centroid_m: [at(k), 0.0],
            velocity: (k > 0).then(|| ([(at(k) - at(k - 1)) / 0.1, 0.0], 6.25)),
            span_s: 0.1,
        }
    }

    #[test]
    fn a_parked_car_jittering_with_the_pose_is_never_displaced() {
        let (params, pose) = noisy_pose();
        let mut tracks = Tracks::default();
        let mut fast_frames = 0;
        for k in 0..20 {
            tracks.update(&[seen_at(k, |_| 0.0)], 0.1 * k as f64, 0.1, pose, &params);
            let Some(t) = tracks.of_observation(0) else {
                panic!("frame {k}: no track");
            };
            // Registered net displacement = x_k − x_0 = the jitter: at most 0.5 m.
            assert!((t.registered_m[0] - jitter(k)).abs() < 1e-9, "frame {k}");
            assert!(!t.displaced, "frame {k}");
            let [x, y] = t.velocity;
            fast_frames += usize::from(x.mean_mps.hypot(y.mean_mps) >= params.min_speed_mps);
        }
        assert_eq!(tracks.len(), 1);
        // Without the test the jumps alone would have made it move (4.95 m/s after the first).
        assert!(fast_frames > 0);
    }

    #[test]
    fn a_car_crawling_under_the_same_jitter_is_displaced_once_it_has_moved_beyond_it() {
        let (params, pose) = noisy_pose();
        let mut tracks = Tracks::default();
        let mut displaced = Vec::new();
        for k in 0..16 {
            // 1.5 m/s east: 0.15 m a frame.
            let crawl = |k: usize| 0.15 * k as f64;
            tracks.update(&[seen_at(k, crawl)], 0.1 * k as f64, 0.1, pose, &params);
            let Some(t) = tracks.of_observation(0) else {
                panic!("frame {k}: no track");
            };
            // Net displacement 0.15 k + jitter(k): above 0.84853 m at frames 5 (1.25 m) and 6
            // (0.9 m), not 7 (0.55 m), and from frame 8 (1.2 m) on (at least 1.15 m).
            let expected = 0.15 * k as f64 + jitter(k);
            assert!((t.registered_m[0] - expected).abs() < 1e-9, "frame {k}");
            displaced.push(t.displaced);
        }
        let expected: Vec<bool> = (0..16).map(|k| matches!(k, 5 | 6) || k >= 8).collect();
        assert_eq!(displaced, expected);
        // And it moves: 1.5 m/s filtered from the noisy registrations.
        let t = tracks.of_observation(0).copied();
        assert!(
            t.is_some_and(|t| is_moving(&t, &params) && t.displaced),
            "{t:?}"
        );
    }

    #[test]
    fn a_first_registration_counts_its_whole_span() {
        let (params, pose) = noisy_pose();
        let mut tracks = Tracks::default();
        // A car out of occlusion, registered at once against cells 0.4 s old at 2 m/s: 0.8 m
        // registered, under the gate; the next frame adds 2 · 0.1: 1.0 m, beyond it.
        let car = |x: f64, span_s: f64| Observation {
            centroid_m: [x, 0.0],
            velocity: Some(([2.0, 0.0], 0.25)),
            span_s,
        };
        tracks.update(&[car(0.0, 0.4)], 0.0, 0.1, pose, &params);
        let t = tracks.of_observation(0).copied();
        assert!(t.is_some_and(|t| (t.registered_m[0] - 0.8).abs() < 1e-12 && !t.displaced));
        tracks.update(&[car(0.2, 0.4)], 0.1, 0.1, pose, &params);
        let t = tracks.of_observation(0).copied();
        assert!(t.is_some_and(|t| (t.registered_m[0] - 1.0).abs() < 1e-12 && t.displaced));
        // With the test off every track counts as displaced.
        let mut tracks = Tracks::default();
        let off = MotionParams {
            displaced_pose_sigmas: 0.0,
            ..MotionParams::default()
        };
        tracks.update(&[car(0.0, 0.4)], 0.0, 0.1, pose, &off);
        assert!(tracks.of_observation(0).is_some_and(|t| t.displaced));
    }

    #[test]
    fn by_default_a_track_is_displaced_beyond_one_and_a_half_sigma_of_the_pose() {
        // The default `displaced_pose_sigmas`, 1.5 (re-chosen on the new scenes, issue 30; 2
        // before), under a pose error of 0.2 m per axis (heading exact): the apparent
        // displacement of a static object has σ = 0.2 · √2 = 0.28284 m, so the test is at
        // 0.42426 m (0.56569 m at 2 σ). A car first registered over 0.25 s at 2 m/s has moved
        // 0.5 m: displaced now, not with 2 σ.
        let params = MotionParams::default();
        assert_eq!(params.displaced_pose_sigmas, 1.5);
        let two = MotionParams {
            displaced_pose_sigmas: 2.0,
            ..MotionParams::default()
        };
        let pose = PoseError {
            sensor_xy_m: [0.0, 10.0],
            sigma_m: 0.2,
            sigma_rad: 0.0,
        };
        let car = Observation {
            centroid_m: [0.0, 0.0],
            velocity: Some(([2.0, 0.0], 0.25)),
            span_s: 0.25,
        };
        let displaced = |params: &MotionParams| {
            let mut tracks = Tracks::default();
            tracks.update(&[car], 0.0, 0.1, pose, params);
            tracks
                .of_observation(0)
                .map(|t| ((t.registered_m[0] - 0.5).abs() < 1e-12, t.displaced))
        };
        assert_eq!(displaced(&params), Some((true, true)));
        assert_eq!(displaced(&two), Some((true, false)));
    }

    #[test]
    fn only_the_braking_part_of_an_acceleration_is_kept() {
        let filter = |v: f64, a: f64| VelocityFilter {
            accel_mps2: a,
            ..VelocityFilter::new(v, 0.1)
        };
        // v = (3, 4), a = (3, 0): the part along v, (a·v)/|v|² · v = 9/25 · (3, 4), goes,
        // leaving (1.92, −1.44), square to v.
        let mut speeding = [filter(3.0, 3.0), filter(4.0, 0.0)];
        braking_only(&mut speeding);
        assert!((speeding[0].accel_mps2 - 1.92).abs() < 1e-12);
        assert!((speeding[1].accel_mps2 + 1.44).abs() < 1e-12);
        // Braking, (−3, 0) against (3, 4): kept.
        let mut braking = [filter(3.0, -3.0), filter(4.0, 0.0)];
        braking_only(&mut braking);
        assert_eq!(braking[0].accel_mps2, -3.0);
        assert_eq!(braking[1].accel_mps2, 0.0);
    }

    #[test]
    fn a_braking_track_predicted_through_zero_stands() {
        let params = MotionParams::default();
        let mut tracks = Tracks::default();
        tracks.update(&[seen(0.0, None)], 0.0, 0.1, PoseError::default(), &params);
        // 0.2 m/s east braking at 3 m/s²: 0.1 s on, 0.2 − 0.3 = −0.1 m/s, backwards.
        for v in &mut tracks.tracks[0].velocity {
            v.variance = 0.01;
        }
        tracks.tracks[0].velocity[0].mean_mps = 0.2;
        tracks.tracks[0].velocity[0].accel_mps2 = -3.0;
        tracks.update(&[], 0.1, 0.1, PoseError::default(), &params);
        let v = tracks.tracks[0].velocity;
        assert_eq!(v.map(|v| v.mean_mps), [0.0, 0.0]);
        assert_eq!(v.map(|v| v.accel_mps2), [0.0, 0.0]);
    }

    /// Frames, of a car driving east at 6 m/s for 2 s, braking at 3 m/s² to a stop (2 s)
    /// and standing 2 s, in which its track is judged moving after it stopped, and before:
    /// each frame registered as its mean velocity over the last `frames` frames (what the
    /// registration's line through the past frames reads), σ = 0.5 m/s.
    fn moving_frames_around_a_stop(params: &MotionParams, frames: usize) -> (usize, usize) {
        let dt = 0.1;
        let speed = |k: usize| {
            let t = k as f64 * dt;
            if t <= 2.0 {
                6.0
            } else {
                (6.0 - 3.0 * (t - 2.0)).max(0.0)
            }
        };
        // The position at frame k: the speed's integral, exactly per frame (trapezoids of a
        // piecewise-linear speed whose corners fall on frames).
        let mut x = vec![0.0];
        for k in 1..60 {
            x.push(x[k - 1] + (speed(k - 1) + speed(k)) / 2.0 * dt);
        }
        let mut tracks = Tracks::default();
        let (mut after, mut before) = (0, 0);
        for k in 0..60 {
            let back = frames.min(k);
            // Mean velocity over the frames back: Σ d_j·τ_j / Σ τ_j², τ_j = j·dt.
            let (num, den) = (1..=back).fold((0.0, 0.0), |(n, d), j| {
                let tau = j as f64 * dt;
                (n + (x[k] - x[k - j]) * tau, d + tau * tau)
            });
            let span_s = (1..=back).map(|j| (j as f64 * dt).powi(2)).sum::<f64>()
                / (1..=back).map(|j| j as f64 * dt).sum::<f64>().max(dt);
            let o = Observation {
                centroid_m: [x[k], 0.0],
                velocity: (back > 0).then(|| ([num / den, 0.0], 0.25)),
                span_s,
            };
            tracks.update(&[o], k as f64 * dt, dt, PoseError::default(), params);
            let moving = tracks
                .of_observation(0)
                .is_some_and(|t| is_moving(t, params));
            if speed(k) < params.min_speed_mps {
                after += usize::from(moving);
            } else if k > frames {
                before += usize::from(!moving);
            }
        }
        (after, before)
    }

    #[test]
    fn a_braking_car_is_seen_to_stop_sooner_with_its_acceleration() {
        // The car stops at 4 s (frame 40). Registrations over 6 frames lag its braking by a
        // quarter of a second and more; the constant-velocity filter lags them in turn.
        let off = MotionParams {
            jerk_sigma_mps3: 0.0,
            ..MotionParams::default()
        };
        let on = MotionParams::default();
        assert_eq!(on.jerk_sigma_mps3, 1.0);
        let (after_off, before_off) = moving_frames_around_a_stop(&off, 6);
        let (after_on, before_on) = moving_frames_around_a_stop(&on, 6);
        // Neither loses the car while it moves at 0.5 m/s or more.
        assert_eq!((before_off, before_on), (0, 0));
        assert!(after_off >= 3, "{after_off}");
        assert!(after_on < after_off, "{after_on} vs {after_off}");
    }
}
