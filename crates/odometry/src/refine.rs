//! Pose refinement: a reported pose (GNSS/INS, a noisy localisation) corrected by registering
//! the scan against a local map of the previous scans.
//!
//! Unlike [`crate::Odometry`], the prior is the pose given with each scan. ICP starts from a
//! constant-velocity prediction of the poses used for the last two scans (by default,
//! [`RefineStart`]; or from the prior), its correction is measured from the prior and gated (a
//! failed or unconverged registration, or one that moves the pose farther from the prior than
//! the prior can be wrong, keeps the prior), and the accepted pose is pulled back towards the
//! prior: by the gain of a Kalman filter on the map frame's offset, strong in the directions the
//! scan does not constrain (along a corridor) and weak in those it does ([`RefineBlend`]), or by
//! a fixed fraction. Without that pull the refined poses would be consistent with each other but the
//! whole map would keep the error of the first scan's prior and drift from there; with it the
//! map frame follows the average of the priors.
//!
//! The map keeps its own frame: a scan joins it at its registered pose, and the pull moves the
//! offset between that frame and the world (`world_from_map`). Pulled poses put into the map
//! would not do: a voxel keeps its first points, so the next registration would snap back to
//! the first scans and undo the pull, leaving the first prior's error as a lasting bias (0.15 m
//! across the street on the simulated monaco drive with 0.1 m of pose noise).
//!
//! The map forgets what lies beyond the range, so memory does not grow with the drive. Planar
//! scans (all points at one height, level poses) work: the plane pins height, roll and pitch,
//! and its in-plane structure the rest; they get finer voxels (`planar_voxel_size_m`) than a
//! 3-D scan's.

use std::collections::VecDeque;

use nalgebra::{Isometry3, Matrix6, Vector3, Vector6};

use crate::OdometryError;
use crate::icp::{self, IcpSettings};
use crate::lie;
use crate::params::{Registration, check_registration, invalid, positive};
use crate::threshold::AdaptiveThreshold;
use crate::voxel::{VoxelMap, downsampled};

/// Parameters of [`PoseRefiner`].
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct RefineParams {
    /// Points farther than this from the sensor are not registered, and map points farther than
    /// this from the current position are forgotten (metres, default 80).
    pub max_range_m: f64,
    /// Points closer than this to the sensor are not registered (metres, default 2).
    pub min_range_m: f64,
    /// Edge of a local-map voxel for 3-D scans (metres, default 1, KISS-ICP's choice for an
    /// outdoor lidar). A scan is downsampled at half of it for the map and at 1.5 times it for
    /// registration, as in [`crate::Odometry`].
    pub voxel_size_m: f64,
    /// The same for planar scans, whose points all lie within [`PLANAR_SPREAD_M`] of one height
    /// (metres, default 0.25: a sparse planar scanner needs fine voxels, or point-to-point ICP
    /// settles on the map's sampling along a façade). The first scan with points decides.
    pub planar_voxel_size_m: f64,
    /// At most this many points are kept per map voxel (default 20).
    pub max_points_per_voxel: usize,
    /// Correspondence threshold before any correction has been observed (metres, default 1);
    /// then KISS-ICP's adaptive threshold from the corrections applied to the priors.
    pub initial_threshold_m: f64,
    /// Gauss–Newton iterations per scan at most (default 100).
    pub max_iterations: usize,
    /// ICP stops when an update's norm (metres and radians as one 6-vector) is below this
    /// (default 1e-4; 1e-3 halves the iterations on KITTI 0013 but flips a decision in a
    /// synthetic scene, `docs/benchmarks.md`).
    pub convergence_tolerance: f64,
    /// A registration that moves the position farther than this from the prior is refused and
    /// the prior kept (metres, default 1: five times a GNSS/INS's 0.2 m; chosen with the
    /// constant-velocity start on the tuning drives, `docs/motion.md`).
    pub max_correction_m: f64,
    /// A registration that turns the pose by more than this from the prior (about any axis) is
    /// refused and the prior kept (degrees, default 2: four times an INS's 0.5°).
    pub max_correction_deg: f64,
    /// [`RefineBlend::Fixed`]: fraction of the way from the registered pose back to the prior,
    /// in `[0, 1]` (default 0.2): keeps the map frame on the priors' average instead of drifting with the first
    /// scan's error. 1 keeps the prior (registration measured but not used).
    pub prior_weight: f64,
    /// A registration with fewer correspondences than this fraction of the registered points
    /// is refused (default 0.3): a scan that mostly sees what the map has not.
    pub min_overlap: f64,
    /// Where ICP starts (default [`RefineStart::ConstantVelocity`]).
    pub start: RefineStart,
    /// How the registered pose and the prior are combined (default
    /// [`RefineBlend::Information`], chosen on the validation drives, `docs/motion.md`).
    pub blend: RefineBlend,
    /// [`RefineBlend::Information`]: σ of the prior's position per axis (metres, default 0.2,
    /// a GNSS/INS's; with the next three chosen on the tuning drives).
    pub prior_sigma_m: f64,
    /// [`RefineBlend::Information`]: σ of the prior's rotation about each axis (degrees,
    /// default 0.5).
    pub prior_sigma_deg: f64,
    /// [`RefineBlend::Information`]: σ of the registration's error in a direction that every
    /// pair constrains (metres, default 0.01); a direction constrained by a fraction `f` of
    /// the pairs' weight gets `σ / √f`, and the rotations follow from the points' lever arms.
    pub registration_sigma_m: f64,
    /// [`RefineBlend::Information`]: σ of the start's error per axis in a direction the scan
    /// does not constrain, where the registration stays where it started (metres, default
    /// 0.2; the rotations get this over [`PREDICTION_LEVER_M`]).
    pub prediction_sigma_m: f64,
    /// [`RefineBlend::Information`]: where the prior's σ comes from (default
    /// [`PriorSigma::Estimated`], chosen on the validation drives, `docs/motion.md`).
    pub prior_sigma: PriorSigma,
}

/// Where [`RefineBlend::Information`] takes the prior's σ from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum PriorSigma {
    /// `prior_sigma_m` and `prior_sigma_deg`, whatever the priors are like.
    Fixed,
    /// `prior_sigma_m` and `prior_sigma_deg` as upper bounds, lowered when the priors
    /// themselves show less jitter: twice the estimate `median |second difference| / (0.6745
    /// · √6)` of the last [`SIGMA_WINDOW`] priors' horizontal positions and headings (in the
    /// frame of the middle one), which is σ for a white noise added to each prior
    /// independently (a vehicle's own acceleration adds `a·Δt²`, a centimetre at 10 Hz, and
    /// the median ignores the few scans where a turn starts). The configured σ until
    /// [`SIGMA_SAMPLES`] second differences have been seen; floored at 1 mm and 0.001°.
    /// Exact priors are then kept nearly as given; noisy ones are pulled as configured.
    #[default]
    Estimated,
}

/// [`PriorSigma::Estimated`]: the second differences of this many scans are kept.
pub const SIGMA_WINDOW: usize = 50;

/// [`PriorSigma::Estimated`]: the estimate replaces the configured σ after this many second
/// differences.
pub const SIGMA_SAMPLES: usize = 10;

/// [`PriorSigma::Estimated`] uses this many times the estimate (at most the configured σ): a
/// median of 50 second differences scatters by about 20 % of σ, and a prior that seems a
/// little better than configured should not be trusted more for it.
const ESTIMATE_MARGIN: f64 = 2.0;

/// The median absolute value of a zero-mean Gaussian is this times its σ; a second difference
/// of independent errors of σ has σ·√6.
const MEDIAN_OF_SECOND_DIFFERENCE: f64 = 0.674_489_750_196_081_7 * 2.449_489_742_783_178;

/// How [`PoseRefiner`] combines the registered pose with the prior.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum RefineBlend {
    /// `prior_weight` of the way back to the prior, in every direction alike.
    Fixed,
    /// A Kalman filter on the offset between the map's frame and the world (`world_from_map`),
    /// observed by each prior with covariance `prior_sigma_*`, and drifting by the
    /// registration's error: the registration's normal equations (their information per
    /// unit weight over `registration_sigma_m²`) plus the start's (`prediction_sigma_m`) give
    /// the covariance the scan adds, so the pull is weak in the directions the scan
    /// constrains and strong in those it does not (along a corridor).
    #[default]
    Information,
}

/// The rotation σ of the start in [`RefineBlend::Information`] is `prediction_sigma_m` over
/// this lever arm (metres): a turn that moves a point this far away by the position's σ.
pub const PREDICTION_LEVER_M: f64 = 20.0;

/// Where the registration of a scan starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[non_exhaustive]
pub enum RefineStart {
    /// From the given pose: ICP starts with the prior's whole error, and the nearest-neighbour
    /// search (the 27 voxels around a point) cannot reach the right pairs once that error
    /// nears a voxel (0.25 m on planar scans).
    Prior,
    /// From a constant-velocity prediction of the poses used for the last two scans that
    /// joined the map (world frame, the velocity scaled by the time since the last): a smooth
    /// drive is predicted within centimetres where a noisy prior can be decimetres off. The
    /// prior is the start for the first two scans, after a restart of the map, when the time
    /// does not advance, and when the prediction is farther from the prior than the gate
    /// (`max_correction_*`) accepts. The gate is still measured from the prior.
    #[default]
    ConstantVelocity,
}

impl Default for RefineParams {
    fn default() -> Self {
        Self {
            max_range_m: 80.0,
            min_range_m: 2.0,
            voxel_size_m: 1.0,
            planar_voxel_size_m: 0.25,
            max_points_per_voxel: 20,
            initial_threshold_m: 1.0,
            max_iterations: 100,
            convergence_tolerance: 1e-4,
            max_correction_m: 1.0,
            max_correction_deg: 2.0,
            prior_weight: 0.2,
            min_overlap: 0.3,
            start: RefineStart::ConstantVelocity,
            blend: RefineBlend::Information,
            prior_sigma_m: 0.2,
            prior_sigma_deg: 0.5,
            registration_sigma_m: 0.01,
            prediction_sigma_m: 0.2,
            prior_sigma: PriorSigma::Estimated,
        }
    }
}

impl RefineParams {
    /// Checks every field; the error names the first one that is out of range.
    ///
    /// # Errors
    /// [`OdometryError::InvalidParameter`].
    pub fn validate(&self) -> Result<(), OdometryError> {
        let registration = |voxel_name, voxel_size_m| Registration {
            max_range_m: self.max_range_m,
            min_range_m: self.min_range_m,
            voxel_name,
            voxel_size_m,
            max_points_per_voxel: self.max_points_per_voxel,
            initial_threshold_m: self.initial_threshold_m,
            max_iterations: self.max_iterations,
            convergence_tolerance: self.convergence_tolerance,
        };
        check_registration(&registration("voxel_size_m", self.voxel_size_m))?;
        check_registration(&registration(
            "planar_voxel_size_m",
            self.planar_voxel_size_m,
        ))?;
        let unit = |name: &'static str, value: f64| {
            if (0.0..=1.0).contains(&value) {
                Ok(())
            } else {
                Err(invalid(name, value, "must be within [0, 1]"))
            }
        };
        positive("max_correction_m", self.max_correction_m)?;
        if !(self.max_correction_deg.is_finite()
            && self.max_correction_deg > 0.0
            && self.max_correction_deg <= 180.0)
        {
            return Err(invalid(
                "max_correction_deg",
                self.max_correction_deg,
                "must be within (0, 180]",
            ));
        }
        unit("prior_weight", self.prior_weight)?;
        unit("min_overlap", self.min_overlap)?;
        positive("prior_sigma_m", self.prior_sigma_m)?;
        positive("prior_sigma_deg", self.prior_sigma_deg)?;
        positive("registration_sigma_m", self.registration_sigma_m)?;
        positive("prediction_sigma_m", self.prediction_sigma_m)?;
        Ok(())
    }
}

/// Why a scan kept its prior.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum KeptReason {
    /// The scan had no usable point, or the map none near it.
    NoData,
    /// ICP could not compute an update (too few correspondences, singular equations).
    Failed,
    /// ICP did not converge within the iteration limit.
    NotConverged,
    /// Too few of the scan's points found a map point.
    LowOverlap,
    /// The registration moved the pose farther from the prior than `max_correction_*`.
    TooFar,
}

/// How a scan's pose was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum RefineOutcome {
    /// The first scan with points: the map starts from its prior.
    First,
    /// Registered, gated and blended with the prior.
    Refined,
    /// The prior, for the reason given.
    KeptPrior(KeptReason),
}

/// A scan is planar when all its points lie within a band of heights this wide (metres): a 2-D
/// scanner's points have one height, a 3-D scanner's spread over metres.
pub const PLANAR_SPREAD_M: f64 = 0.05;

/// The first scan decides planar or 3-D only with at least this many usable points: two
/// points of a 3-D scan can share a height, and the choice holds for the whole drive.
const POINTS_TO_DECIDE: usize = 100;

/// After this many refused registrations in a row the map is dropped and started again from the
/// given pose: the given poses and the map disagree for good (a GNSS jump, a relocalisation), and
/// the map, not the poses, is what can be rebuilt.
const REFUSALS_TO_RESTART: usize = 10;

/// The refinement of one scan, from [`PoseRefiner::refine`]; hand it to
/// [`PoseRefiner::insert`] to add the scan to the map.
#[derive(Debug, Clone)]
pub struct Refinement {
    /// The pose to use: refined, or the prior.
    pub world_from_sensor: Isometry3<f64>,
    /// How it was obtained.
    pub outcome: RefineOutcome,
    /// `prior⁻¹ · registered` as ICP found it, gated or not (identity when ICP did not run).
    pub correction: Isometry3<f64>,
    /// Correspondences in ICP's last iteration.
    pub correspondences: usize,
    /// Points registered (the scan downsampled at 1.5 voxels).
    pub source_points: usize,
    /// Gauss–Newton iterations run.
    pub iterations: usize,
    /// The map's voxel edge (metres): `planar_voxel_size_m` or `voxel_size_m`.
    pub voxel_size_m: f64,
    /// The scan's pose in the map's own frame: where it joins the map.
    map_from_sensor: Isometry3<f64>,
    /// The scan downsampled for the map, sensor frame.
    frame: Vec<Vector3<f64>>,
    /// The scan's time (seconds), for the constant-velocity start.
    time_s: f64,
    /// The pose given with the scan.
    prior: Isometry3<f64>,
    /// [`RefineBlend::Information`]: the map frame's covariance after this scan, in the frame
    /// of `world_from_sensor` (twists right-multiplied on it).
    frame_covariance: Option<Matrix6<f64>>,
}

/// Refines reported poses against a local map of the previous scans. See the module docs.
#[derive(Debug, Clone)]
pub struct PoseRefiner {
    params: RefineParams,
    /// Created by the first scan with points, whose shape decides the voxel edge.
    map: Option<VoxelMap>,
    /// `world_from_map`: the map keeps its own frame (the world's, until the first pull), in
    /// which scans join it at their registered poses; this offset carries the slow pull towards
    /// the priors.
    world_from_map: Isometry3<f64>,
    threshold: AdaptiveThreshold,
    /// Registrations refused since the last accepted one.
    refused_in_a_row: usize,
    /// (time, `map_from_sensor`) of the last two scans that joined the map, oldest first: the
    /// constant-velocity start.
    track: Vec<(f64, Isometry3<f64>)>,
    /// [`RefineBlend::Information`]: the covariance of `world_from_map`'s error as seen from
    /// the last refined scan (twists right-multiplied on its pose, the pose); `None` until a
    /// scan was refined since the map started, when it is the prior's.
    frame_covariance: Option<(Isometry3<f64>, Matrix6<f64>)>,
    /// Maps started so far (the first included): a new map has a new frame.
    map_starts: usize,
    /// (time, prior) of the last three scans, oldest first: [`PriorSigma::Estimated`].
    priors: Vec<(f64, Isometry3<f64>)>,
    /// The last [`SIGMA_WINDOW`] scans' absolute second differences of the priors: position
    /// (x and y of the middle prior's frame, metres) and heading (radians).
    second_differences: VecDeque<([f64; 2], f64)>,
}

impl PoseRefiner {
    /// A refiner with an empty map.
    ///
    /// # Errors
    /// [`OdometryError::InvalidParameter`] naming the first invalid field.
    pub fn new(params: RefineParams) -> Result<Self, OdometryError> {
        params.validate()?;
        Ok(Self {
            map: None,
            world_from_map: Isometry3::identity(),
            refused_in_a_row: 0,
            track: Vec::with_capacity(2),
            frame_covariance: None,
            map_starts: 0,
            priors: Vec::with_capacity(3),
            second_differences: VecDeque::with_capacity(SIGMA_WINDOW),
            // As KISS-ICP: corrections under 0.1 m (bound at the range) are sampling noise, and
            // would shrink the threshold below the map's point spacing.
            threshold: AdaptiveThreshold::new(params.initial_threshold_m, 0.1, params.max_range_m),
            params,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &RefineParams {
        &self.params
    }

    /// `world_from_map`: the offset between the map's own frame and the world, as the last
    /// [`PoseRefiner::insert`] left it. A scan that joined the map was placed in the world at
    /// `world_from_map · map_from_sensor`, so two such scans of one map place a static point
    /// apart by the change of this offset between them, plus their registrations' errors.
    pub fn world_from_map(&self) -> &Isometry3<f64> {
        &self.world_from_map
    }

    /// Maps started so far, the first included: it grows when the map is started again after
    /// refusals in a row, whose frame is new (offsets of two maps are not comparable).
    pub fn map_starts(&self) -> usize {
        self.map_starts
    }

    /// Voxels in the local map.
    pub fn map_voxels(&self) -> usize {
        self.map.as_ref().map_or(0, VoxelMap::voxel_count)
    }

    /// Registers `points` (sensor frame; NaN, infinite and out-of-range points are skipped),
    /// taken at `time_s` (seconds, any origin), against the map, starting from `prior`
    /// (`world_from_sensor`) or from the prediction [`RefineParams::start`] asks for. Changes
    /// nothing: the map and the threshold are updated by [`PoseRefiner::insert`].
    pub fn refine(&self, points: &[[f32; 3]], prior: &Isometry3<f64>, time_s: f64) -> Refinement {
        let p = &self.params;
        let (min_sq, max_sq) = (p.min_range_m * p.min_range_m, p.max_range_m * p.max_range_m);
        // Sized once: collected from a filter, the vector grew by doubling, copying the scan's
        // points over and over.
        let mut kept: Vec<Vector3<f64>> = Vec::with_capacity(points.len());
        kept.extend(
            points
                .iter()
                .filter(|raw| raw.iter().all(|c| c.is_finite()))
                .map(|raw| Vector3::new(f64::from(raw[0]), f64::from(raw[1]), f64::from(raw[2])))
                .filter(|point| (min_sq..=max_sq).contains(&point.norm_squared())),
        );
        let voxel_size_m = match &self.map {
            Some(map) => map.voxel_size(),
            None if is_planar(&kept) => p.planar_voxel_size_m,
            None => p.voxel_size_m,
        };
        // Too few points to tell a planar scan from a 3-D one: no map starts from this scan.
        let kept = if self.map.is_none() && kept.len() < POINTS_TO_DECIDE {
            Vec::new()
        } else {
            kept
        };
        let frame = downsampled(&kept, 0.5 * voxel_size_m);
        let source = downsampled(&frame, 1.5 * voxel_size_m);
        let guess = self.world_from_map.inverse() * prior;
        let mut refinement = Refinement {
            world_from_sensor: *prior,
            map_from_sensor: guess,
            outcome: RefineOutcome::KeptPrior(KeptReason::NoData),
            correction: Isometry3::identity(),
            correspondences: 0,
            source_points: source.len(),
            iterations: 0,
            voxel_size_m,
            frame,
            time_s,
            prior: *prior,
            frame_covariance: None,
        };
        if refinement.frame.is_empty() {
            return refinement;
        }
        let Some(map) = self.map.as_ref().filter(|map| !map.is_empty()) else {
            refinement.outcome = RefineOutcome::First;
            return refinement;
        };
        let settings = IcpSettings::adaptive(
            self.threshold.sigma(),
            p.max_iterations,
            p.convergence_tolerance,
        );
        let predicted = self.predicted(time_s, prior);
        let start = predicted.map_or(guess, |predicted| self.world_from_map.inverse() * predicted);
        let outcome = icp::register(&source, map, &start, &settings);
        refinement.correspondences = outcome.correspondences;
        refinement.iterations = outcome.iterations;
        let correction = guess.inverse() * outcome.world_from_sensor;
        refinement.correction = correction;
        let reason = if outcome.failed {
            Some(KeptReason::Failed)
        } else if !outcome.converged {
            Some(KeptReason::NotConverged)
        } else if (outcome.correspondences as f64) < p.min_overlap * source.len() as f64 {
            Some(KeptReason::LowOverlap)
        } else if correction.translation.vector.norm() > p.max_correction_m
            || correction.rotation.angle() > p.max_correction_deg.to_radians()
        {
            Some(KeptReason::TooFar)
        } else {
            None
        };
        if let Some(reason) = reason {
            refinement.outcome = RefineOutcome::KeptPrior(reason);
            return refinement;
        }
        // registered · exp(K · log(registered⁻¹ · prior)) in the world: K of the way back to
        // the prior (K = w I, or the filter's gain). The scan joins the map at its registered
        // pose, and the pull moves the map's frame (`insert`), so that it accumulates over the
        // scans instead of being undone by the next registration against a map that kept the
        // first scans' error.
        let registered = self.world_from_map * outcome.world_from_sensor;
        let back = lie::log(&(registered.inverse() * prior));
        let back = match p.blend {
            RefineBlend::Information => {
                let information =
                    icp::surface_information(&source, map, &outcome.world_from_sensor, &settings);
                let (gain, covariance) = self.filter_gain(&registered, &information);
                refinement.frame_covariance = Some(covariance);
                gain * back
            }
            RefineBlend::Fixed => back * p.prior_weight,
        };
        refinement.world_from_sensor = registered * lie::exp(&back);
        refinement.map_from_sensor = outcome.world_from_sensor;
        refinement.outcome = RefineOutcome::Refined;
        refinement
    }

    /// The gain of [`RefineBlend::Information`] for a scan registered at `registered` (world)
    /// with `information` per unit weight (its frame), and the map frame's covariance after
    /// the update (the same frame).
    ///
    /// The map frame's covariance `V` is carried from the last refined scan's frame into this
    /// one, grows by what this registration can be off (`Q`, the inverse of the registration's
    /// information plus the start's), and the prior, of covariance `P`, observes it:
    /// `K = (V + Q)(V + Q + P)⁻¹`, and `(I − K)(V + Q)` after.
    fn filter_gain(
        &self,
        registered: &Isometry3<f64>,
        information: &Matrix6<f64>,
    ) -> (Matrix6<f64>, Matrix6<f64>) {
        let p = &self.params;
        let diagonal =
            |m: f64, rad: f64| Matrix6::from_diagonal(&Vector6::new(m, m, m, rad, rad, rad));
        let (sigma_m, sigma_rad) = self.prior_sigmas();
        let prior = diagonal(sigma_m.powi(2), sigma_rad.powi(2));
        let start = diagonal(
            p.prediction_sigma_m.powi(-2),
            (p.prediction_sigma_m / PREDICTION_LEVER_M).powi(-2),
        );
        let registration = information / p.registration_sigma_m.powi(2);
        let drift = symmetric_inverse(&(registration + start)).unwrap_or_else(|| {
            // Not expected (the start's information alone is positive definite): no drift.
            Matrix6::zeros()
        });
        let carried = match &self.frame_covariance {
            Some((last, covariance)) => {
                let to_here = lie::adjoint(&(registered.inverse() * last));
                to_here * covariance * to_here.transpose()
            }
            None => prior,
        };
        let predicted = carried + drift;
        let Some(innovation) = symmetric_inverse(&(predicted + prior)) else {
            return (Matrix6::zeros(), carried);
        };
        let gain = predicted * innovation;
        let after = (Matrix6::identity() - gain) * predicted;
        (gain, 0.5 * (after + after.transpose()))
    }

    /// The prior's σ (metres, radians) that [`RefineBlend::Information`] uses: the configured
    /// ones, or with [`PriorSigma::Estimated`] and enough scans, the estimate from the priors'
    /// second differences.
    pub fn prior_sigmas(&self) -> (f64, f64) {
        let p = &self.params;
        let configured = (p.prior_sigma_m, p.prior_sigma_deg.to_radians());
        if p.prior_sigma != PriorSigma::Estimated || self.second_differences.len() < SIGMA_SAMPLES {
            return configured;
        }
        let mut positions: Vec<f64> = self
            .second_differences
            .iter()
            .flat_map(|(position, _)| *position)
            .collect();
        let mut headings: Vec<f64> = self.second_differences.iter().map(|d| d.1).collect();
        let estimate = |values: &mut [f64], configured: f64, floor: f64| {
            (ESTIMATE_MARGIN * median(values) / MEDIAN_OF_SECOND_DIFFERENCE)
                .clamp(floor, configured.max(floor))
        };
        (
            estimate(&mut positions, configured.0, MIN_SIGMA_M),
            estimate(&mut headings, configured.1, MIN_SIGMA_RAD),
        )
    }

    /// Records the second difference of the last three priors, when their times advance: the
    /// motion from the middle one to the last less the motion from the first to the middle
    /// (scaled to the same time step), in the middle one's frame.
    fn observe_prior(&mut self, time_s: f64, prior: &Isometry3<f64>) {
        if self.params.prior_sigma != PriorSigma::Estimated {
            return;
        }
        if self.priors.len() == 3 {
            self.priors.remove(0);
        }
        self.priors.push((time_s, *prior));
        let [(first_s, first), (middle_s, middle), (last_s, last)] = self.priors.as_slice() else {
            return;
        };
        let (before_s, after_s) = (middle_s - first_s, last_s - middle_s);
        if !(before_s > 0.0 && after_s > 0.0 && (before_s + after_s).is_finite()) {
            return;
        }
        let difference = lie::log(&(middle.inverse() * last))
            - lie::log(&(first.inverse() * middle)) * (after_s / before_s);
        if !difference.iter().all(|v| v.is_finite()) {
            return;
        }
        if self.second_differences.len() == SIGMA_WINDOW {
            self.second_differences.pop_front();
        }
        self.second_differences.push_back((
            [difference[0].abs(), difference[1].abs()],
            difference[5].abs(),
        ));
    }

    /// The constant-velocity prediction of the pose at `time_s` in the map's frame, when
    /// [`RefineStart::ConstantVelocity`] is chosen, two scans have joined the map since it
    /// started, the time advances, and the prediction is within the gate of `prior_in_map`.
    fn predicted(&self, time_s: f64, prior: &Isometry3<f64>) -> Option<Isometry3<f64>> {
        let p = &self.params;
        if p.start != RefineStart::ConstantVelocity {
            return None;
        }
        let [(older_s, older), (last_s, last)] = self.track.as_slice() else {
            return None;
        };
        let (span_s, ahead_s) = (last_s - older_s, time_s - last_s);
        if !(span_s > 0.0 && ahead_s > 0.0 && ahead_s.is_finite()) {
            return None;
        }
        let velocity = lie::velocity(older, last, span_s);
        let predicted = last * lie::exp(&(velocity * ahead_s));
        let off = prior.inverse() * predicted;
        let within = off.translation.vector.norm() <= p.max_correction_m
            && off.rotation.angle() <= p.max_correction_deg.to_radians();
        (within && predicted.translation.vector.iter().all(|v| v.is_finite())).then_some(predicted)
    }

    /// Adds the scan of `refinement` to the map at its pose, moves the map's frame by the pull
    /// towards the prior, feeds the adaptive threshold with the correction and forgets the map
    /// beyond the range. A scan whose registration was refused is left out of the map (its only
    /// pose is the prior the map disagrees with), and after 10 refusals in a row the map starts
    /// again from the given pose.
    pub fn insert(&mut self, refinement: &Refinement) {
        self.observe_prior(refinement.time_s, &refinement.prior);
        match refinement.outcome {
            RefineOutcome::Refined => {
                self.threshold.observe(&refinement.correction);
                self.refused_in_a_row = 0;
                if let Some(covariance) = refinement.frame_covariance {
                    self.frame_covariance = Some((refinement.world_from_sensor, covariance));
                }
            }
            RefineOutcome::KeptPrior(KeptReason::NoData) | RefineOutcome::First => {}
            RefineOutcome::KeptPrior(_) => {
                self.refused_in_a_row += 1;
                if self.refused_in_a_row < REFUSALS_TO_RESTART {
                    return;
                }
                self.map = None;
                self.world_from_map = Isometry3::identity();
                self.refused_in_a_row = 0;
                self.track.clear();
                self.frame_covariance = None;
            }
        }
        // Nothing to add; and the map's voxels are chosen by the first scan with points.
        if refinement.frame.is_empty() {
            return;
        }
        // A restarted map starts from this scan at its given pose.
        let restarted = self.map.is_none();
        if restarted {
            self.map_starts += 1;
        }
        let pose = if restarted {
            &refinement.world_from_sensor
        } else {
            &refinement.map_from_sensor
        };
        let max_points = self.params.max_points_per_voxel;
        let map = self
            .map
            .get_or_insert_with(|| VoxelMap::new(refinement.voxel_size_m, max_points));
        map.add_and_remove_far(
            &refinement.frame,
            pose,
            &pose.translation.vector,
            self.params.max_range_m,
        );
        if self.track.len() == 2 {
            self.track.remove(0);
        }
        self.track
            .push((refinement.time_s, refinement.world_from_sensor));
        // The pose used is `world_from_map · map_from_sensor`; for a kept prior this leaves the
        // frame where it was.
        let mut world_from_map = refinement.world_from_sensor * pose.inverse();
        // Composed every scan: without this the quaternion's rounding compounds (each product
        // of the loop multiplies its norm error) until rotations scale the map.
        world_from_map.rotation.renormalize();
        self.world_from_map = world_from_map;
    }

    /// [`PoseRefiner::refine`] then [`PoseRefiner::insert`]: the pose to use for this scan.
    pub fn refine_and_insert(
        &mut self,
        points: &[[f32; 3]],
        prior: &Isometry3<f64>,
        time_s: f64,
    ) -> Refinement {
        let refinement = self.refine(points, prior, time_s);
        self.insert(&refinement);
        refinement
    }
}

/// [`PriorSigma::Estimated`]'s floor on the position σ (metres): the filter's gain stays defined.
const MIN_SIGMA_M: f64 = 1e-3;

/// [`PriorSigma::Estimated`]'s floor on the rotation σ (radians, 0.001°).
const MIN_SIGMA_RAD: f64 = 1.745_329_251_994_33e-5;

/// The median of `values` (the mean of the middle two for an even count), which it sorts; 0
/// for none.
fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    match values.len() {
        0 => 0.0,
        n if n % 2 == 1 => values[n / 2],
        n => 0.5 * (values[n / 2 - 1] + values[n / 2]),
    }
}

/// The inverse of a symmetric positive definite matrix, `None` when it is not one or the result
/// is not finite.
fn symmetric_inverse(matrix: &Matrix6<f64>) -> Option<Matrix6<f64>> {
    let inverse = matrix.cholesky()?.inverse();
    inverse.iter().all(|v| v.is_finite()).then_some(inverse)
}

/// All points within [`PLANAR_SPREAD_M`] of one height.
fn is_planar(points: &[Vector3<f64>]) -> bool {
    let (low, high) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(low, high), p| {
            (low.min(p.z), high.max(p.z))
        });
    high - low <= PLANAR_SPREAD_M
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    /// A planar world (z = 0): building walls along a street, and poles, as a 2-D scanner sees
    /// them.
    fn world_segments() -> Vec<([f64; 2], [f64; 2])> {
        // Poles every 6 m on both pavements, 0.3 m square: what pins the position along the
        // street, which the façades leave free.
        let poles = (-3..10).flat_map(|k| {
            let x = f64::from(k) * 6.0 + 1.0;
            [6.5, -7.5].into_iter().flat_map(move |y| {
                [
                    ([x, y], [x + 0.3, y]),
                    ([x + 0.3, y], [x + 0.3, y + 0.3]),
                    ([x + 0.3, y + 0.3], [x, y + 0.3]),
                    ([x, y + 0.3], [x, y]),
                ]
            })
        });
        let mut segments = vec![
            ([-20.0, 8.0], [60.0, 8.0]),
            ([-20.0, -9.0], [15.0, -9.0]),
            ([15.0, -9.0], [15.0, -25.0]),
            ([22.0, -9.0], [22.0, -25.0]),
            ([22.0, -9.0], [60.0, -9.0]),
            ([40.0, 8.0], [40.0, 30.0]),
            ([5.0, 3.0], [5.3, 3.0]),
            ([28.0, -4.0], [28.3, -4.0]),
        ];
        segments.extend(poles);
        segments
    }

    /// The outline of a planar scan as a 3-D scanner sees it: each return also 1 m higher.
    fn solid_scan(planar: &[[f32; 3]]) -> Vec<[f32; 3]> {
        planar
            .iter()
            .flat_map(|&[x, y, _]| [[x, y, 0.0], [x, y, 1.0]])
            .collect()
    }

    /// A 360° planar scan from `pose` (x, y, heading): the first wall hit per ray, every 0.25°.
    fn planar_scan(pose: (f64, f64, f64)) -> Vec<[f32; 3]> {
        planar_scan_of(&world_segments(), pose)
    }

    /// [`planar_scan`] of a world of `segments`.
    fn planar_scan_of(segments: &[([f64; 2], [f64; 2])], pose: (f64, f64, f64)) -> Vec<[f32; 3]> {
        let mut points = Vec::new();
        for k in 0..1440 {
            let bearing = f64::from(k) * 0.25_f64.to_radians();
            let (sin, cos) = (pose.2 + bearing).sin_cos();
            let mut best = f64::INFINITY;
            for (a, b) in segments {
                // Ray origin + t·d against segment a + s·(b − a).
                let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
                let denom = cos * ey - sin * ex;
                if denom.abs() < 1e-12 {
                    continue;
                }
                let (wx, wy) = (a[0] - pose.0, a[1] - pose.1);
                let t = (wx * ey - wy * ex) / denom;
                let s = (wx * sin - wy * cos) / denom;
                if t > 0.0 && (0.0..=1.0).contains(&s) {
                    best = best.min(t);
                }
            }
            if best < 80.0 {
                let (bs, bc) = bearing.sin_cos();
                points.push([(best * bc) as f32, (best * bs) as f32, 0.0]);
            }
        }
        points
    }

    fn level(x: f64, y: f64, heading: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, y, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, heading),
        )
    }

    fn errors(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> (f64, f64) {
        let delta = truth.inverse() * estimate;
        (delta.translation.vector.norm(), delta.rotation.angle())
    }

    #[test]
    fn a_noisy_planar_pose_is_pulled_back_to_the_truth() {
        let params = RefineParams {
            blend: RefineBlend::Fixed,
            prior_weight: 0.0,
            ..RefineParams::default()
        };
        let mut refiner = PoseRefiner::new(params).expect("valid");
        // Two scans at their true poses build the map.
        for x in [0.0, 0.8] {
            let truth = level(x, 0.0, 0.0);
            let first = refiner.refine_and_insert(&planar_scan((x, 0.0, 0.0)), &truth, 0.0);
            assert_ne!(first.outcome, RefineOutcome::KeptPrior(KeptReason::TooFar));
        }
        let truth = (1.6, 0.0, 0.0);
        let prior = level(1.6 + 0.15, -0.12, 0.3_f64.to_radians());
        let refinement = refiner.refine(&planar_scan(truth), &prior, 0.0);
        assert_eq!(refinement.voxel_size_m, 0.25);
        assert_eq!(refinement.outcome, RefineOutcome::Refined);
        let truth = level(truth.0, truth.1, truth.2);
        let (before_m, before_rad) = errors(&prior, &truth);
        let (after_m, after_rad) = errors(&refinement.world_from_sensor, &truth);
        assert!(before_m > 0.19 && before_rad > 0.005);
        assert!(after_m < 0.03, "{after_m} m");
        assert!(after_rad < 0.05_f64.to_radians(), "{after_rad} rad");
        // Planar stays planar: no height, roll or pitch appear.
        let pose = refinement.world_from_sensor;
        assert!(pose.translation.z.abs() < 1e-9);
        let (roll, pitch, _) = pose.rotation.euler_angles();
        assert!(roll.abs() < 1e-9 && pitch.abs() < 1e-9);
    }

    /// A refiner whose map holds the scans from (0, 0) and (0.8, 0) at t = 0 and 0.1 s, taken
    /// at their true poses: the vehicle drives 8 m/s along x.
    /// Inserts the scans of two true poses, 8 m/s along x (0.8 m in 0.1 s).
    fn drive_two_scans(refiner: &mut PoseRefiner, scan: fn((f64, f64, f64)) -> Vec<[f32; 3]>) {
        for (k, x) in [0.0, 0.8].into_iter().enumerate() {
            refiner.refine_and_insert(&scan((x, 0.0, 0.0)), &level(x, 0.0, 0.0), 0.1 * k as f64);
        }
    }

    fn driving(start: RefineStart) -> PoseRefiner {
        let mut refiner = PoseRefiner::new(RefineParams {
            start,
            blend: RefineBlend::Fixed,
            prior_weight: 0.0,
            ..RefineParams::default()
        })
        .expect("valid");
        drive_two_scans(&mut refiner, planar_scan);
        refiner
    }

    #[test]
    fn the_constant_velocity_start_converges_where_the_prior_start_does_not() {
        // The third scan, truly at (1.6, 0) at t = 0.2 s; its prior is 0.7 m ahead, 0.4 m
        // aside and turned 1.8° (0.63 m at 20 m): beyond the 27 voxels' reach of the true pairs
        // (0.25–0.5 m), within the 1 m / 2° gate (0.81 m). The prediction, (0.8, 0) + 0.1 s ×
        // 8 m/s, is the truth.
        let truth = level(1.6, 0.0, 0.0);
        let prior = level(1.6 + 0.7, 0.4, 1.8_f64.to_radians());
        let scan = planar_scan((1.6, 0.0, 0.0));
        let from_prior = driving(RefineStart::Prior).refine(&scan, &prior, 0.2);
        let predicted = driving(RefineStart::ConstantVelocity).refine(&scan, &prior, 0.2);
        assert_eq!(predicted.outcome, RefineOutcome::Refined);
        let (m, rad) = errors(&predicted.world_from_sensor, &truth);
        assert!(m < 0.02 && rad < 0.05_f64.to_radians(), "{m} m, {rad} rad");
        // The gate is measured from the prior: the whole 0.81 m is the correction.
        assert!((predicted.correction.translation.vector.norm() - 0.7_f64.hypot(0.4)).abs() < 0.03);
        // From the prior, ICP settles on the wrong pairs, 0.69 m from the truth, and passes the
        // gate.
        let (m, _) = errors(&from_prior.world_from_sensor, &truth);
        assert_eq!(from_prior.outcome, RefineOutcome::Refined);
        assert!(m > 0.5, "{m} m from the prior start");
    }

    #[test]
    fn the_prediction_is_not_used_without_time_or_beyond_the_gate() {
        let scan = planar_scan((1.6, 0.0, 0.0));
        let same_start = |prior: &Isometry3<f64>, time_s: f64| {
            let from_prior = driving(RefineStart::Prior).refine(&scan, prior, time_s);
            let predicted = driving(RefineStart::ConstantVelocity).refine(&scan, prior, time_s);
            from_prior.world_from_sensor == predicted.world_from_sensor
                && from_prior.iterations == predicted.iterations
        };
        let near = level(1.7, 0.1, 0.0);
        // From the prior when the time does not advance past the last scan's (0.1 s)...
        assert!(same_start(&near, 0.1));
        assert!(same_start(&near, f64::NAN));
        // ... or when the prediction, (1.6, 0), is beyond the 1 m gate from the prior.
        assert!(same_start(&level(2.7, 0.0, 0.0), 0.2));
        // Otherwise from the prediction: another start, another path.
        assert!(!same_start(&near, 0.2));
    }

    #[test]
    fn the_prior_weight_pulls_back_towards_the_prior() {
        let build = |prior_weight| {
            let mut refiner = PoseRefiner::new(RefineParams {
                blend: RefineBlend::Fixed,
                prior_weight,
                ..RefineParams::default()
            })
            .expect("valid");
            refiner.refine_and_insert(&planar_scan((0.0, 0.0, 0.0)), &level(0.0, 0.0, 0.0), 0.0);
            refiner
        };
        let prior = level(0.2, 0.0, 0.0);
        let scan = planar_scan((0.0, 0.0, 0.0));
        let x = |r: &Refinement| r.world_from_sensor.translation.x;
        let free = build(0.0).refine(&scan, &prior, 0.0);
        let half = build(0.5).refine(&scan, &prior, 0.0);
        // The pull moves the map's frame, not the scan in it: the scan joins the map at its
        // registered pose, and `world_from_map` carries it to the pose used.
        let mut pulled = build(0.5);
        assert_eq!(*pulled.world_from_map(), Isometry3::identity());
        pulled.insert(&half);
        let frame_x = pulled.world_from_map().translation.x;
        assert!((frame_x - (x(&half) - x(&free))).abs() < 1e-3, "{frame_x}");
        let kept = build(1.0).refine(&scan, &prior, 0.0);
        assert_eq!(half.outcome, RefineOutcome::Refined);
        assert!(x(&free).abs() < 0.02, "{}", x(&free));
        assert!(
            (x(&half) - 0.5 * (x(&free) + 0.2)).abs() < 1e-3,
            "{}",
            x(&half)
        );
        assert!((x(&kept) - 0.2).abs() < 1e-6, "{}", x(&kept));
    }

    #[test]
    fn a_registration_beyond_the_gate_keeps_the_prior() {
        let mut refiner = PoseRefiner::new(RefineParams {
            max_correction_m: 0.1,
            ..RefineParams::default()
        })
        .expect("valid");
        refiner.refine_and_insert(&planar_scan((0.0, 0.0, 0.0)), &level(0.0, 0.0, 0.0), 0.0);
        // The truth is 0.3 m from the prior: ICP finds it, the gate refuses it.
        let prior = level(0.3, 0.0, 0.0);
        let refinement = refiner.refine(&planar_scan((0.0, 0.0, 0.0)), &prior, 0.0);
        assert_eq!(
            refinement.outcome,
            RefineOutcome::KeptPrior(KeptReason::TooFar)
        );
        assert!(refinement.correction.translation.vector.norm() > 0.2);
        assert_eq!(refinement.world_from_sensor, prior);
    }

    #[test]
    fn refused_scans_stay_out_of_the_map_until_the_map_restarts() {
        let mut refiner = PoseRefiner::new(RefineParams {
            max_correction_m: 0.1,
            ..RefineParams::default()
        })
        .expect("valid");
        let scan = planar_scan((0.0, 0.0, 0.0));
        assert_eq!(refiner.map_starts(), 0);
        refiner.refine_and_insert(&scan, &level(0.0, 0.0, 0.0), 0.0);
        assert_eq!(refiner.map_starts(), 1);
        let voxels = refiner.map_voxels();
        // The given pose jumps 0.3 m for good (a relocalised GNSS): refused, left out.
        let jumped = level(0.3, 0.0, 0.0);
        for _ in 1..REFUSALS_TO_RESTART {
            let refinement = refiner.refine_and_insert(&scan, &jumped, 0.0);
            assert_eq!(
                refinement.outcome,
                RefineOutcome::KeptPrior(KeptReason::TooFar)
            );
            assert_eq!(refiner.map_voxels(), voxels);
        }
        assert_eq!(refiner.map_starts(), 1);
        // The last refusal in a row restarts the map from the given pose, which then holds:
        // a second map, whose frame is the world's again.
        refiner.refine_and_insert(&scan, &jumped, 0.0);
        assert_eq!(refiner.map_starts(), 2);
        assert_eq!(*refiner.world_from_map(), Isometry3::identity());
        let next = refiner.refine(&scan, &jumped, 0.0);
        assert_eq!(next.outcome, RefineOutcome::Refined);
        assert!(next.correction.translation.vector.norm() < 0.02);
        assert!((next.world_from_sensor.translation.x - 0.3).abs() < 0.02);
    }

    #[test]
    fn a_first_scan_of_a_few_points_does_not_choose_the_voxels() {
        let planar = planar_scan((0.0, 0.0, 0.0));
        let mut refiner = PoseRefiner::new(RefineParams::default()).expect("valid");
        // Two 3-D points at one height: not enough to call the drive planar.
        let few = [[5.0_f32, 0.0, 1.0], [0.0, 6.0, 1.0]];
        let first = refiner.refine_and_insert(&few, &level(0.0, 0.0, 0.0), 0.0);
        assert_eq!(first.outcome, RefineOutcome::KeptPrior(KeptReason::NoData));
        assert_eq!(refiner.map_voxels(), 0);
        let next = refiner.refine_and_insert(&solid_scan(&planar), &level(0.0, 0.0, 0.0), 0.0);
        assert_eq!(next.voxel_size_m, RefineParams::default().voxel_size_m);
    }

    #[test]
    fn a_scan_with_nothing_to_match_keeps_the_prior() {
        let mut refiner = PoseRefiner::new(RefineParams::default()).expect("valid");
        refiner.refine_and_insert(&planar_scan((0.0, 0.0, 0.0)), &level(0.0, 0.0, 0.0), 0.0);
        // A scan of a place 1 km away: no correspondence.
        let prior = level(1000.0, 0.0, 0.1);
        let refinement = refiner.refine(&planar_scan((0.0, 0.0, 0.0)), &prior, 0.0);
        assert_eq!(
            refinement.outcome,
            RefineOutcome::KeptPrior(KeptReason::Failed)
        );
        assert_eq!(refinement.world_from_sensor, prior);
        // No point at all, or only unusable ones.
        let empty = refiner.refine(&[[f32::NAN, 0.0, 0.0], [0.5, 0.0, 0.0]], &prior, 0.0);
        assert_eq!(empty.outcome, RefineOutcome::KeptPrior(KeptReason::NoData));
        assert_eq!(empty.world_from_sensor, prior);
    }

    #[test]
    fn the_first_scan_chooses_planar_or_3d_voxels_for_the_drive() {
        let planar = planar_scan((0.0, 0.0, 0.0));
        let solid = solid_scan(&planar);
        let params = RefineParams::default();
        let mut refiner = PoseRefiner::new(params.clone()).expect("valid");
        let first = refiner.refine_and_insert(&solid, &level(0.0, 0.0, 0.0), 0.0);
        assert_eq!(first.voxel_size_m, params.voxel_size_m);
        // The map's voxels stay what the first scan chose.
        let next = refiner.refine(&planar, &level(0.0, 0.0, 0.0), 0.0);
        assert_eq!(next.voxel_size_m, params.voxel_size_m);
        // A first scan without points decides nothing.
        let mut late = PoseRefiner::new(params.clone()).expect("valid");
        late.refine_and_insert(&[], &level(0.0, 0.0, 0.0), 0.0);
        assert_eq!(late.map_voxels(), 0);
        let first = late.refine_and_insert(&solid, &level(0.0, 0.0, 0.0), 0.0);
        assert_eq!(first.voxel_size_m, params.voxel_size_m);
        let mut flat = PoseRefiner::new(params.clone()).expect("valid");
        let first = flat.refine_and_insert(&planar, &level(0.0, 0.0, 0.0), 0.0);
        assert_eq!(first.voxel_size_m, params.planar_voxel_size_m);
        assert!(flat.map_voxels() > refiner.map_voxels());
    }

    /// A street without poles or corners: two façades along x, 8 m either side, 200 m long.
    fn corridor_scan(pose: (f64, f64, f64)) -> Vec<[f32; 3]> {
        planar_scan_of(
            &[
                ([-100.0, 8.0], [100.0, 8.0]),
                ([-100.0, -8.0], [100.0, -8.0]),
            ],
            pose,
        )
    }

    /// The information blend with round numbers: prior σ 0.1 m and 0.2°, registration σ
    /// 0.01 m, start σ 0.2 m.
    fn round() -> RefineParams {
        RefineParams {
            blend: RefineBlend::Information,
            prior_sigma_m: 0.1,
            prior_sigma_deg: 0.2,
            registration_sigma_m: 0.01,
            prediction_sigma_m: 0.2,
            ..RefineParams::default()
        }
    }

    #[test]
    fn the_gain_follows_what_the_scan_constrains() {
        // Prior σ 0.1 m and 0.2°, registration σ 0.01 m, start σ 0.2 m (rotation
        // 0.2 / 20 = 0.01 rad). A scan that says nothing along x, everything across y and z
        // (information 1 per unit weight) and turns with a 20 m lever arm (400), with a map
        // frame known exactly so far (carried covariance 0): K = Q (Q + P)⁻¹ per axis, with
        // Q = 1 / (information / 0.01² + 1 / σ_start²).
        let registered = level(5.0, 2.0, 0.3);
        let mut refiner = PoseRefiner::new(round()).expect("valid");
        refiner.frame_covariance = Some((registered, Matrix6::zeros()));
        let information = Matrix6::from_diagonal(&Vector6::new(0.0, 1.0, 1.0, 400.0, 400.0, 400.0));
        let (gain, after) = refiner.filter_gain(&registered, &information);
        // Along x: Q = 1 / 25 = 0.04, K = 0.04 / 0.05 = 0.8: the prior mostly wins.
        assert!((gain[(0, 0)] - 0.8).abs() < 1e-9, "{}", gain[(0, 0)]);
        // Across: Q = 1 / 10025, K = Q / (Q + 0.01) = 0.009877: the scan wins.
        let q = 1.0 / 10_025.0;
        assert!((gain[(1, 1)] - q / (q + 0.01)).abs() < 1e-9);
        assert!((gain[(1, 1)] - 0.009877).abs() < 1e-6);
        // Rotations: Q = 1 / (4e6 + 1e4), P = (0.2°)², K = 0.02006.
        let (q, p) = (1.0 / 4.01e6, 0.2_f64.to_radians().powi(2));
        assert!((gain[(5, 5)] - q / (q + p)).abs() < 1e-9);
        assert!((gain[(5, 5)] - 0.02006).abs() < 1e-5);
        // Diagonal in, diagonal out; after the update the covariance is (1 − K) Q.
        assert!((gain - Matrix6::from_diagonal(&gain.diagonal())).amax() < 1e-12);
        assert!((after[(0, 0)] - 0.2 * 0.04).abs() < 1e-12);
    }

    #[test]
    fn a_corridor_scan_has_no_information_along_the_street() {
        let mut refiner = PoseRefiner::new(RefineParams::default()).expect("valid");
        refiner.refine_and_insert(&corridor_scan((0.0, 0.0, 0.0)), &level(0.0, 0.0, 0.0), 0.0);
        let map = refiner.map.as_ref().expect("a map");
        let source: Vec<Vector3<f64>> = corridor_scan((0.4, 0.0, 0.0))
            .iter()
            .map(|p| Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
            .collect();
        let source = downsampled(&source, 1.5 * map.voxel_size());
        let settings = IcpSettings::adaptive(0.3, 10, 1e-4);
        let information = icp::surface_information(&source, map, &level(0.4, 0.0, 0.0), &settings);
        // Across the street and in height every pair with a line around its map point counts
        // (the far ends of the façades, sampled sparsely, have none: about half the pairs);
        // along the street none does.
        let (along, across, height) = (
            information[(0, 0)],
            information[(1, 1)],
            information[(2, 2)],
        );
        assert!(
            across > 0.3 && (height - across).abs() < 1e-9,
            "{information}"
        );
        assert!(along < 1e-3 * across, "{information}");
    }

    #[test]
    fn in_a_corridor_the_along_street_error_comes_from_the_likelier_source() {
        // Two scans at their true poses, 8 m/s along x; the third, truly at (1.6, 0), is given
        // 0.3 m ahead and 0.15 m aside. The start (constant velocity) is the truth; the walls
        // correct the 0.15 m across the street, nothing corrects along it.
        let run = |prediction_sigma_m| {
            let mut refiner = PoseRefiner::new(RefineParams {
                prediction_sigma_m,
                ..round()
            })
            .expect("valid");
            drive_two_scans(&mut refiner, corridor_scan);
            // The map frame known exactly (after many scans it is the average of many priors;
            // here, after two, it would still be half as uncertain as one).
            refiner.frame_covariance = Some((level(0.8, 0.0, 0.0), Matrix6::zeros()));
            let prior = level(1.9, 0.15, 0.0);
            let refinement = refiner.refine(&corridor_scan((1.6, 0.0, 0.0)), &prior, 0.2);
            assert_eq!(refinement.outcome, RefineOutcome::Refined);
            let pose = refinement.world_from_sensor.translation;
            (pose.x - 1.6, pose.y)
        };
        // A start that can be 1 m off: along the street the prior (σ 0.1 m) wins, K = 1 / 1.01
        // of the 0.3 m; across it the walls do, K ≈ 0.01 of the 0.15 m (registration σ 0.01 m
        // against the prior's 0.1 m).
        let (along, across) = run(1.0);
        assert!((along - 0.3).abs() < 0.01, "{along} m along");
        assert!(across.abs() < 0.01, "{across} m across");
        // A start good to 1 cm: it wins along the street too, K = 0.01² / (0.01² + 0.1²) ≈ 0.01
        // (what is left is the registration's own 2 cm along the façades' samples).
        let (along, across) = run(0.01);
        assert!(along.abs() < 0.03, "{along} m along");
        assert!(across.abs() < 0.01, "{across} m across");
    }

    proptest::proptest! {
        /// Whatever the scan's information and the map frame's covariance, the gain is finite
        /// and moves the pose towards the prior, never past it: in the prior's metric
        /// (`P⁻¹`), neither the step nor what is left of the way is longer than the way.
        #[test]
        fn the_information_gain_stays_between_the_registration_and_the_prior(
            factor in proptest::array::uniform6(proptest::array::uniform6(-30.0_f64..30.0)),
            carried in proptest::array::uniform6(0.0_f64..1.0),
            way in proptest::array::uniform6(-0.02_f64..0.02),
            scale in proptest::prop_oneof![
                proptest::strategy::Just(0.0),
                1e-9_f64..1.0,
                1.0_f64..1e9,
            ],
        ) {
            let factor = Matrix6::from_fn(|r, c| factor[r][c]);
            let information = factor.transpose() * factor * scale;
            let registered = level(3.0, -1.0, 0.2);
            let mut refiner = PoseRefiner::new(RefineParams::default()).expect("valid");
            let carried = Matrix6::from_diagonal(&Vector6::from_column_slice(&carried)) * 0.01;
            refiner.frame_covariance = Some((level(2.2, -1.0, 0.2), carried));
            let (gain, after) = refiner.filter_gain(&registered, &information);
            proptest::prop_assert!(gain.iter().chain(after.iter()).all(|v| v.is_finite()));
            let p = &refiner.params;
            let metric = Vector6::new(
                p.prior_sigma_m, p.prior_sigma_m, p.prior_sigma_m,
                p.prior_sigma_deg.to_radians(), p.prior_sigma_deg.to_radians(),
                p.prior_sigma_deg.to_radians(),
            );
            let norm = |v: Vector6<f64>| v.component_div(&metric).norm();
            let way = Vector6::from_column_slice(&way);
            let step = gain * way;
            proptest::prop_assert!(norm(step) <= norm(way) * (1.0 + 1e-9) + 1e-12);
            proptest::prop_assert!(norm(way - step) <= norm(way) * (1.0 + 1e-9) + 1e-12);
        }
    }

    proptest::proptest! {
        /// Whatever the scan and the given pose (finite: the front end refuses others), the
        /// refiner returns a finite pose and keeps working.
        #[test]
        fn hostile_scans_and_poses_give_finite_poses(
            raw in proptest::collection::vec(
                proptest::array::uniform3(proptest::prop_oneof![
                    -100.0_f32..100.0,
                    proptest::num::f32::ANY,
                    proptest::strategy::Just(0.0_f32),
                ]),
                0..300,
            ),
            x in proptest::prop_oneof![-1e3_f64..1e3, -1e12_f64..1e12],
            y in -1e6_f64..1e6,
            heading in -10.0_f64..10.0,
        ) {
            let mut refiner = PoseRefiner::new(RefineParams::default()).expect("valid");
            for k in 0..3 {
                let prior = level(x + f64::from(k) * 0.5, y, heading);
                // Times 0.1 s apart: the third scan starts from the prediction.
                let refinement = refiner.refine_and_insert(&raw, &prior, 0.1 * f64::from(k));
                let pose = refinement.world_from_sensor;
                proptest::prop_assert!(pose.translation.vector.iter().all(|v| v.is_finite()));
                proptest::prop_assert!(pose.rotation.coords.iter().all(|v| v.is_finite()));
            }
        }
    }

    #[test]
    fn the_map_stays_local() {
        let mut refiner = PoseRefiner::new(RefineParams::default()).expect("valid");
        refiner.refine_and_insert(&planar_scan((0.0, 0.0, 0.0)), &level(0.0, 0.0, 0.0), 0.0);
        assert!(refiner.map_voxels() > 0);
        // Far away: the old map is forgotten, only the new scan remains.
        let far =
            refiner.refine_and_insert(&planar_scan((0.0, 0.0, 0.0)), &level(500.0, 0.0, 0.0), 0.0);
        let alone = PoseRefiner::new(RefineParams::default())
            .expect("valid")
            .refine_and_insert(&planar_scan((0.0, 0.0, 0.0)), &level(500.0, 0.0, 0.0), 0.0);
        assert_eq!(far.frame.len(), alone.frame.len());
        let mut fresh = PoseRefiner::new(RefineParams::default()).expect("valid");
        fresh.insert(&alone);
        assert_eq!(refiner.map_voxels(), fresh.map_voxels());
    }

    /// A refiner estimating the prior's σ, fed empty scans every 0.1 s with `priors`.
    fn estimating(priors: impl IntoIterator<Item = Isometry3<f64>>) -> PoseRefiner {
        let mut refiner = PoseRefiner::new(RefineParams {
            prior_sigma: PriorSigma::Estimated,
            ..RefineParams::default()
        })
        .expect("valid");
        for (k, prior) in priors.into_iter().enumerate() {
            refiner.refine_and_insert(&[], &prior, 0.1 * k as f64);
        }
        refiner
    }

    #[test]
    fn the_prior_sigma_is_estimated_from_second_differences() {
        let configured = (0.2, 0.5_f64.to_radians());
        // Too few scans (two second differences from four): the configured σ.
        let early = estimating((0..4).map(|k| level(f64::from(k), 0.0, 0.0)));
        assert_eq!(early.prior_sigmas(), configured);
        // A steady drive along x at 10 m/s: every second difference is 0, so the floors.
        let steady = estimating((0..20).map(|k| level(f64::from(k), 0.0, 0.0)));
        assert_eq!(steady.prior_sigmas(), (MIN_SIGMA_M, MIN_SIGMA_RAD));
        // Every other prior 0.1 m to the left (y): each second difference of y is ±0.2 m
        // (0.1 − 2·0 + 0.1, or 0 − 2·0.1 + 0), of x 0. The median of |x| and |y| together is
        // the mean of the middle two, 0 and 0.2: σ = 0.1 / (0.6745·√6) = 0.060527 m, used
        // twice, 0.121054 m (under the configured 0.2); the heading's, all 0, is floored.
        let zigzag = estimating((0..20).map(|k| level(f64::from(k), 0.1 * f64::from(k % 2), 0.0)));
        let (sigma_m, sigma_rad) = zigzag.prior_sigmas();
        assert!((sigma_m - 0.121_054).abs() < 1e-6, "{sigma_m}");
        assert_eq!(sigma_rad, MIN_SIGMA_RAD);
        // Standing, every other prior turned 0.2°: heading second differences ±0.4°, so σ =
        // 0.4° / 1.65216 = 0.242108°, used twice, 0.484216°; the positions' are 0, floored.
        let turning =
            estimating((0..20).map(|k| level(0.0, 0.0, (0.2 * f64::from(k % 2)).to_radians())));
        let (sigma_m, sigma_rad) = turning.prior_sigmas();
        assert_eq!(sigma_m, MIN_SIGMA_M);
        assert!(
            (sigma_rad.to_degrees() - 0.484_216).abs() < 1e-6,
            "{sigma_rad}"
        );
        // Every other prior 0.3 m to the left and 1° turned: twice 0.3 / 1.65216 is 0.363 m,
        // twice 2° / 1.65216 is 2.42°, both above the configured σ, which bound them.
        let rough = estimating((0..20).map(|k| {
            let off = f64::from(k % 2);
            level(f64::from(k), 0.3 * off, off.to_radians())
        }));
        assert_eq!(rough.prior_sigmas(), configured);
        // `Fixed` keeps the configured σ whatever the priors.
        let mut fixed = PoseRefiner::new(RefineParams {
            prior_sigma: PriorSigma::Fixed,
            ..RefineParams::default()
        })
        .expect("valid");
        for k in 0..20 {
            fixed.refine_and_insert(&[], &level(f64::from(k), 0.0, 0.0), 0.1 * f64::from(k));
        }
        assert_eq!(fixed.prior_sigmas(), configured);
    }

    /// `scans` priors along x at 8 m/s with a deterministic Gaussian noise (a linear
    /// congruential generator through Box–Muller) of `sigma_m` per axis and `sigma_deg`.
    fn noisy_priors(scans: u32, sigma_m: f64, sigma_deg: f64) -> Vec<Isometry3<f64>> {
        let mut state: u64 = 12_345;
        let mut uniform = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut gaussian = move || {
            let (u, v) = (uniform(), uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        (0..scans)
            .map(|k| {
                level(
                    0.8 * f64::from(k) + sigma_m * gaussian(),
                    sigma_m * gaussian(),
                    sigma_deg.to_radians() * gaussian(),
                )
            })
            .collect()
    }

    #[test]
    fn the_prior_sigma_estimate_follows_a_white_noise() {
        // 0.05 m and 0.1°: the estimate from the last 50 second differences (their median
        // scatters by about 20 % of σ), doubled, within 25 % of 0.1 m and 0.2°.
        let (sigma_m, sigma_rad) = estimating(noisy_priors(200, 0.05, 0.1)).prior_sigmas();
        assert!((sigma_m / 0.1 - 1.0).abs() < 0.25, "{sigma_m}");
        assert!(
            (sigma_rad / 0.2_f64.to_radians() - 1.0).abs() < 0.25,
            "{sigma_rad}"
        );
        // A GNSS/INS's 0.2 m and 0.5°, as configured: doubled, the estimate is beyond the
        // configured σ, which it keeps.
        let configured = (0.2, 0.5_f64.to_radians());
        assert_eq!(
            estimating(noisy_priors(200, 0.2, 0.5)).prior_sigmas(),
            configured
        );
    }

    #[test]
    fn errors_name_the_parameter() {
        type Spoil = fn(&mut RefineParams);
        let cases: [(&str, Spoil); 7] = [
            ("max_range_m", |p| p.max_range_m = 0.0),
            ("min_range_m", |p| p.min_range_m = 100.0),
            ("voxel_size_m", |p| p.voxel_size_m = f64::NAN),
            ("planar_voxel_size_m", |p| p.planar_voxel_size_m = 0.0),
            ("max_correction_m", |p| p.max_correction_m = -1.0),
            ("max_correction_deg", |p| p.max_correction_deg = 200.0),
            ("prior_weight", |p| p.prior_weight = 1.5),
        ];
        for (expected, spoil) in cases {
            let mut params = RefineParams::default();
            spoil(&mut params);
            match PoseRefiner::new(params) {
                Err(OdometryError::InvalidParameter { name, .. }) => assert_eq!(name, expected),
                other => panic!("{expected}: {other:?}"),
            }
        }
    }
}
