//! Point-to-point ICP against the voxel map: Gauss–Newton on SE(3) with a Geman–McClure kernel.
//!
//! Each iteration pairs every source point with its nearest map point within the correspondence
//! threshold and solves the weighted normal equations for a left-multiplied twist. The search and
//! the accumulation run on rayon over fixed chunks whose partial sums are added in chunk order:
//! the result does not depend on the number of threads.

use nalgebra::{Isometry3, Matrix3, Matrix6, Point3, Vector3, Vector6};
use rayon::prelude::*;

use crate::lie;
use crate::voxel::{Neighbourhood, VoxelMap};

/// Points per parallel work item; also the unit of the deterministic reduction.
const CHUNK: usize = 512;

/// Fewer correspondences than this cannot pin down six degrees of freedom with any confidence.
pub(crate) const MIN_CORRESPONDENCES: usize = 10;

/// How one registration is run.
#[derive(Debug, Clone, Copy)]
pub(crate) struct IcpSettings {
    /// Pairs farther apart than this are not correspondences (metres).
    pub max_correspondence_m: f64,
    /// Scale of the Geman–McClure kernel (metres): a pair this far apart weighs a quarter.
    pub kernel_scale_m: f64,
    pub max_iterations: usize,
    pub tolerance: f64,
}

impl IcpSettings {
    /// KISS-ICP's settings for the adaptive threshold's `sigma`: pairs up to 3σ apart, the
    /// kernel at σ/3.
    pub(crate) fn adaptive(sigma: f64, max_iterations: usize, tolerance: f64) -> Self {
        Self {
            max_correspondence_m: 3.0 * sigma,
            kernel_scale_m: sigma / 3.0,
            max_iterations,
            tolerance,
        }
    }
}

/// What a registration found.
#[derive(Debug, Clone)]
pub(crate) struct IcpOutcome {
    /// The refined pose, or the initial one when `failed`.
    pub world_from_sensor: Isometry3<f64>,
    pub iterations: usize,
    pub converged: bool,
    /// Correspondences in the last iteration.
    pub correspondences: usize,
    /// True when not even the first update could be computed (too few correspondences or
    /// singular normal equations).
    pub failed: bool,
}

/// Weighted sums from which the 6×6 normal equations are assembled. With `J = [I, -[p]×]` for a
/// point `p` and residual `r`, `JᵀJ` and `Jᵀr` need only these, which is cheaper than
/// accumulating 6×6 products per point.
#[derive(Debug, Clone, Copy)]
struct NormalSums {
    count: usize,
    weight: f64,
    weighted_point: Vector3<f64>,
    weighted_outer: Matrix3<f64>,
    weighted_norm_sq: f64,
    weighted_residual: Vector3<f64>,
    weighted_moment: Vector3<f64>,
}

impl NormalSums {
    fn zero() -> Self {
        Self {
            count: 0,
            weight: 0.0,
            weighted_point: Vector3::zeros(),
            weighted_outer: Matrix3::zeros(),
            weighted_norm_sq: 0.0,
            weighted_residual: Vector3::zeros(),
            weighted_moment: Vector3::zeros(),
        }
    }

    fn add_pair(&mut self, point: &Vector3<f64>, residual: &Vector3<f64>, weight: f64) {
        self.count += 1;
        self.weight += weight;
        self.weighted_point += point * weight;
        self.weighted_outer += point * point.transpose() * weight;
        self.weighted_norm_sq += point.norm_squared() * weight;
        self.weighted_residual += residual * weight;
        self.weighted_moment += point.cross(residual) * weight;
    }

    fn merge(&mut self, other: &Self) {
        self.count += other.count;
        self.weight += other.weight;
        self.weighted_point += other.weighted_point;
        self.weighted_outer += other.weighted_outer;
        self.weighted_norm_sq += other.weighted_norm_sq;
        self.weighted_residual += other.weighted_residual;
        self.weighted_moment += other.weighted_moment;
    }

    /// `(JᵀWJ, JᵀWr)`.
    fn normal_equations(&self) -> (Matrix6<f64>, Vector6<f64>) {
        let p = self.weighted_point;
        let cross = Matrix3::new(0.0, -p.z, p.y, p.z, 0.0, -p.x, -p.y, p.x, 0.0);
        let mut jtj = Matrix6::zeros();
        jtj.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(Matrix3::identity() * self.weight));
        jtj.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-cross));
        jtj.fixed_view_mut::<3, 3>(3, 0).copy_from(&cross);
        jtj.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(Matrix3::identity() * self.weighted_norm_sq - self.weighted_outer));
        let mut jtr = Vector6::zeros();
        jtr.fixed_rows_mut::<3>(0)
            .copy_from(&self.weighted_residual);
        jtr.fixed_rows_mut::<3>(3).copy_from(&self.weighted_moment);
        (jtj, jtr)
    }
}

/// Geman–McClure weight `(k² / (k² + r²))²`: 1 for a perfect pair, falling off as `k⁴ / r⁴`.
fn geman_mcclure_weight(residual_sq: f64, scale_sq: f64) -> f64 {
    let ratio = scale_sq / (scale_sq + residual_sq);
    ratio * ratio
}

fn accumulate(
    points: &[Vector3<f64>],
    around: &mut [Neighbourhood],
    map: &VoxelMap,
    settings: &IcpSettings,
) -> NormalSums {
    let max_sq = settings.max_correspondence_m * settings.max_correspondence_m;
    let scale_sq = settings.kernel_scale_m * settings.kernel_scale_m;
    let mut sums = NormalSums::zero();
    for (point, around) in points.iter().zip(around) {
        if let Some((nearest, distance_sq)) = map.nearest_around(point, max_sq, around) {
            let residual = point - nearest;
            sums.add_pair(
                point,
                &residual,
                geman_mcclure_weight(distance_sq, scale_sq),
            );
        }
    }
    sums
}

/// Registers sensor-frame `source` points against `map`, starting from `initial`.
pub(crate) fn register(
    source: &[Vector3<f64>],
    map: &VoxelMap,
    initial: &Isometry3<f64>,
    settings: &IcpSettings,
) -> IcpOutcome {
    let mut estimate = *initial;
    let mut moved: Vec<Vector3<f64>> = source
        .iter()
        .map(|p| (initial * Point3::from(*p)).coords)
        .collect();
    // Each point's 27 voxels, looked up again only when it changes voxel, and its last search,
    // skipped while the point's move since cannot have changed the answer.
    let mut around = vec![Neighbourhood::default(); moved.len()];
    let mut outcome = IcpOutcome {
        world_from_sensor: estimate,
        iterations: 0,
        converged: false,
        correspondences: 0,
        failed: true,
    };
    for iteration in 1..=settings.max_iterations {
        let partial: Vec<NormalSums> = moved
            .par_chunks(CHUNK)
            .zip(around.par_chunks_mut(CHUNK))
            .map(|(chunk, around)| accumulate(chunk, around, map, settings))
            .collect();
        let mut sums = NormalSums::zero();
        for part in &partial {
            sums.merge(part);
        }
        outcome.correspondences = sums.count;
        if sums.count < MIN_CORRESPONDENCES {
            break;
        }
        let (jtj, jtr) = sums.normal_equations();
        let Some(step) = jtj.cholesky().map(|c| c.solve(&(-jtr))) else {
            break;
        };
        if !step.iter().all(|v| v.is_finite()) {
            break;
        }
        let update = lie::exp(&step);
        for point in &mut moved {
            *point = (update * Point3::from(*point)).coords;
        }
        estimate = update * estimate;
        outcome.world_from_sensor = estimate;
        outcome.iterations = iteration;
        outcome.failed = false;
        if step.norm() < settings.tolerance {
            outcome.converged = true;
            break;
        }
    }
    outcome
}

/// Spread (σ along a direction, as a fraction of the voxel edge) above which the map points
/// within a voxel edge of a pair's map point extend along that direction: the pair says
/// nothing about it. Points spread evenly along a surface through the ball have σ ≈ 0.45 of
/// the edge along it (0.58 along a line), and a few hundredths across it.
const SPREAD_FRACTION: f64 = 0.15;

/// The information of a registration about a twist right-multiplied on `map_from_sensor`
/// (the scan's own frame), per unit weight of the pairs: each source point paired, as the last
/// iteration pairs it, with its nearest map point, but only across the surface that the map's
/// points within a voxel edge of it sample (`Σ w Jᵀ P J / Σ w`, `P` the projector on the directions the
/// voxel's points do not spread along: the normal of a façade, the two normals of a pole or of a
/// planar scan's wall). Unlike point-to-point normal equations, whose translation block is the
/// same in every direction, it shows a corridor: little information along it. Zero without
/// pairs.
pub(crate) fn surface_information(
    source: &[Vector3<f64>],
    map: &VoxelMap,
    map_from_sensor: &Isometry3<f64>,
    settings: &IcpSettings,
) -> Matrix6<f64> {
    let max_sq = settings.max_correspondence_m * settings.max_correspondence_m;
    let scale_sq = settings.kernel_scale_m * settings.kernel_scale_m;
    let spread_sq = (SPREAD_FRACTION * map.voxel_size()).powi(2);
    let rotation = map_from_sensor.rotation.to_rotation_matrix().into_inner();
    // A mean per unit weight: every k-th point estimates it as well, at a fraction of the
    // searches on a dense 3-D scan (KITTI: about 10,000 points).
    let stride = source.len().div_ceil(INFORMATION_POINTS).max(1);
    let sample: Vec<Vector3<f64>> = source.iter().step_by(stride).copied().collect();
    let partial: Vec<(Matrix6<f64>, f64)> = sample
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut information = Matrix6::zeros();
            let mut weight_sum = 0.0;
            let mut near = Vec::new();
            for point in chunk {
                let moved = (map_from_sensor * Point3::from(*point)).coords;
                let Some((nearest, distance_sq)) = map.nearest(&moved, max_sq) else {
                    continue;
                };
                let weight = geman_mcclure_weight(distance_sq, scale_sq);
                weight_sum += weight;
                map.points_near_into(&nearest, map.voxel_size(), &mut near);
                // Too few map points to see a surface (the sparse far end of a façade): the pair
                // counts in the weight but claims no information, which its sampling alone would
                // fake along the surface.
                if near.len() < MIN_SURFACE_POINTS {
                    continue;
                }
                let across = across_surface(&near, spread_sq);
                let mut jacobian = nalgebra::Matrix3x6::zeros();
                jacobian
                    .fixed_view_mut::<3, 3>(0, 0)
                    .copy_from(&Matrix3::identity());
                jacobian
                    .fixed_view_mut::<3, 3>(0, 3)
                    .copy_from(&(-crate::lie::skew(point)));
                // The residual `R p + t − q` moves by `R J ξ` for a twist ξ of the scan's frame.
                let across = rotation.transpose() * across * rotation;
                information += jacobian.transpose() * across * jacobian * weight;
            }
            (information, weight_sum)
        })
        .collect();
    let (information, weight_sum) = partial.iter().fold(
        (Matrix6::zeros(), 0.0),
        |(information, weight_sum), (part, weight)| (information + part, weight_sum + weight),
    );
    if weight_sum > 0.0 {
        information / weight_sum
    } else {
        Matrix6::zeros()
    }
}

/// [`surface_information`] reads at most about this many points of a scan, evenly spaced in
/// its order.
const INFORMATION_POINTS: usize = 1024;

/// A pair's map point needs this many map points within a voxel edge (itself included) for
/// [`surface_information`] to read a surface there.
const MIN_SURFACE_POINTS: usize = 3;

/// The projector on the directions along which `points` do not spread by more than
/// `sqrt(spread_sq)` (σ about their mean).
fn across_surface(points: &[Vector3<f64>], spread_sq: f64) -> Matrix3<f64> {
    let n = points.len() as f64;
    let mean = points.iter().sum::<Vector3<f64>>() / n;
    let scatter = points
        .iter()
        .map(|p| (p - mean) * (p - mean).transpose())
        .sum::<Matrix3<f64>>()
        / n;
    let eigen = scatter.symmetric_eigen();
    let mut across = Matrix3::identity();
    for (value, vector) in eigen
        .eigenvalues
        .iter()
        .zip(eigen.eigenvectors.column_iter())
    {
        if *value > spread_sq {
            across -= vector * vector.transpose();
        }
    }
    across
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_equations_match_the_jacobian_products() {
        let pairs = [
            (
                Vector3::new(1.0, 2.0, 3.0),
                Vector3::new(0.1, -0.2, 0.05),
                0.7,
            ),
            (
                Vector3::new(-4.0, 0.5, 1.0),
                Vector3::new(0.0, 0.3, -0.1),
                0.2,
            ),
        ];
        let mut sums = NormalSums::zero();
        let mut jtj = Matrix6::zeros();
        let mut jtr = Vector6::zeros();
        for (p, r, w) in pairs {
            sums.add_pair(&p, &r, w);
            let mut jacobian = nalgebra::Matrix3x6::zeros();
            jacobian
                .fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&Matrix3::identity());
            let cross = Matrix3::new(0.0, -p.z, p.y, p.z, 0.0, -p.x, -p.y, p.x, 0.0);
            jacobian.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-cross));
            jtj += jacobian.transpose() * jacobian * w;
            jtr += jacobian.transpose() * r * w;
        }
        let (a, b) = sums.normal_equations();
        assert!((a - jtj).norm() < 1e-12);
        assert!((b - jtr).norm() < 1e-12);
    }

    #[test]
    fn recovers_a_small_offset_of_a_structured_cloud() {
        // Random points on three orthogonal planes: every degree of freedom is observable, and
        // no lattice offers false minima.
        let mut state = 99_u64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 10.0
        };
        let mut cloud = Vec::new();
        for _ in 0..3000 {
            let (a, b) = (next(), next());
            cloud.push(Vector3::new(a, b, 0.0));
            cloud.push(Vector3::new(a, 0.0, b));
            cloud.push(Vector3::new(0.0, a, b));
        }
        let mut map = VoxelMap::new(1.0, 20);
        map.add(&cloud, &Isometry3::identity());
        let truth = lie::exp(&Vector6::new(0.3, -0.2, 0.1, 0.01, -0.02, 0.03));
        let source: Vec<Vector3<f64>> = cloud
            .iter()
            .map(|p| (truth.inverse() * Point3::from(*p)).coords)
            .collect();
        let settings = IcpSettings {
            max_correspondence_m: 1.0,
            kernel_scale_m: 0.5,
            max_iterations: 100,
            tolerance: 1e-8,
        };
        let outcome = register(&source, &map, &Isometry3::identity(), &settings);
        assert!(outcome.converged && !outcome.failed);
        let error = outcome.world_from_sensor.inverse() * truth;
        assert!(error.translation.vector.norm() < 1e-3, "{error}");
        assert!(error.rotation.angle() < 3e-4);
    }

    #[test]
    fn too_few_correspondences_fail_without_moving() {
        let mut map = VoxelMap::new(1.0, 20);
        map.add(&[Vector3::new(0.0, 0.0, 0.0)], &Isometry3::identity());
        let settings = IcpSettings {
            max_correspondence_m: 1.0,
            kernel_scale_m: 0.5,
            max_iterations: 10,
            tolerance: 1e-6,
        };
        let start = lie::exp(&Vector6::new(0.1, 0.0, 0.0, 0.0, 0.0, 0.0));
        let outcome = register(&[Vector3::new(0.0, 0.0, 0.0)], &map, &start, &settings);
        assert!(outcome.failed);
        assert_eq!(outcome.world_from_sensor, start);
    }
}
