//! A synthetic street and a ray-cast spinning lidar, for tests with known motion.
//!
//! The street runs along world x: gently undulating ground around z = 0 (a perfectly flat one
//! would make every scan's ground rings coincide with the last one's at zero motion, a false
//! minimum real roads do not have), buildings of varied length, height and
//! setback behind façade lines at y = −7 and y = +9 with gaps between them, porches, poles and
//! parked cars at irregular intervals, so that no direction is unobservable (ground and endless
//! façades alone would leave motion along x free).

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// A vertical cylinder from `bottom` to `top`: a pole, a trunk, a tree's crown.
struct Pole {
    x: f64,
    y: f64,
    radius: f64,
    bottom: f64,
    top: f64,
}

/// An axis-aligned box.
struct Block {
    min: Vector3<f64>,
    max: Vector3<f64>,
}

/// The street.
pub struct Street {
    poles: Vec<Pole>,
    blocks: Vec<Block>,
    /// For each slice of `CELL_M` along x from `FIRST_X_M`: the poles and blocks reaching into
    /// it, so that a ray tests only what lies along its way.
    cells: Vec<(Vec<usize>, Vec<usize>)>,
}

const FIRST_X_M: f64 = -160.0;
const LAST_X_M: f64 = 480.0;
const CELL_M: f64 = 4.0;

fn cell_of(x: f64) -> usize {
    ((x - FIRST_X_M) / CELL_M)
        .floor()
        .clamp(0.0, (LAST_X_M - FIRST_X_M) / CELL_M - 1.0) as usize
}

/// Deterministic pseudo-random numbers in [0, 1) (a 64-bit LCG): no dependency, same scene on
/// every platform.
pub struct Lcg(u64);

impl Lcg {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next_f64(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

const LEFT_FACADE_Y: f64 = 9.0;
const RIGHT_FACADE_Y: f64 = -7.0;

impl Street {
    /// A street from x = −150 to x = 450.
    pub fn new() -> Self {
        let mut random = Lcg::new(7);
        let mut poles = Vec::new();
        let mut x = -150.0;
        while x < 450.0 {
            x += 2.0 + 6.0 * random.next_f64();
            let side = if random.next_f64() < 0.5 { -5.5 } else { 7.0 };
            let y = side + 0.6 * random.next_f64();
            let top = 3.0 + 5.0 * random.next_f64();
            poles.push(Pole {
                x,
                y,
                radius: 0.1 + 0.15 * random.next_f64(),
                bottom: -GROUND_AMPLITUDE_M,
                top,
            });
            // Every other one is a tree.
            if random.next_f64() < 0.5 {
                poles.push(Pole {
                    x,
                    y,
                    radius: 1.0 + 1.2 * random.next_f64(),
                    bottom: top - 1.0,
                    top: top + 2.0 + 2.0 * random.next_f64(),
                });
            }
        }
        let mut blocks = Vec::new();
        // Parked cars.
        let mut x = -150.0;
        while x < 450.0 {
            x += 5.5 + 8.0 * random.next_f64();
            let (y0, y1) = if random.next_f64() < 0.5 {
                (-5.0, -3.2)
            } else {
                (4.4, 6.2)
            };
            let length = 3.5 + 1.5 * random.next_f64();
            blocks.push(Block {
                min: Vector3::new(x, y0, -GROUND_AMPLITUDE_M),
                max: Vector3::new(x + length, y1, 1.3 + 0.5 * random.next_f64()),
            });
        }
        for facade in [LEFT_FACADE_Y, RIGHT_FACADE_Y] {
            let outward = facade.signum();
            // Buildings, with gaps (side streets, yards) between them.
            let mut x = -150.0;
            while x < 450.0 {
                let length = 10.0 + 25.0 * random.next_f64();
                let front = facade + outward * 1.5 * random.next_f64();
                let back = facade + outward * 20.0;
                blocks.push(Block {
                    min: Vector3::new(x, front.min(back), -GROUND_AMPLITUDE_M),
                    max: Vector3::new(x + length, front.max(back), 6.0 + 15.0 * random.next_f64()),
                });
                // Pilasters: vertical relief along the façade.
                let mut pilaster = x + 0.5;
                while pilaster < x + length - 1.0 {
                    let (inner, outer) = (front - outward * 0.3, front + outward * 0.1);
                    blocks.push(Block {
                        min: Vector3::new(pilaster, inner.min(outer), -GROUND_AMPLITUDE_M),
                        max: Vector3::new(pilaster + 0.5, inner.max(outer), 5.0),
                    });
                    pilaster += 2.5 + 2.0 * random.next_f64();
                }
                x += length
                    + if random.next_f64() < 0.3 {
                        3.0 + 10.0 * random.next_f64()
                    } else {
                        0.0
                    };
            }
            // Porches and bay windows in front of the façades.
            let mut x = -150.0;
            while x < 450.0 {
                x += 5.0 + 12.0 * random.next_f64();
                let depth = 0.4 + 1.0 * random.next_f64();
                let width = 1.5 + 4.0 * random.next_f64();
                let (inner, outer) = (facade - outward * depth, facade + outward * 0.5);
                blocks.push(Block {
                    min: Vector3::new(x, inner.min(outer), -GROUND_AMPLITUDE_M),
                    max: Vector3::new(x + width, inner.max(outer), 2.0 + 3.0 * random.next_f64()),
                });
            }
        }
        let mut cells = vec![(Vec::new(), Vec::new()); cell_of(LAST_X_M) + 1];
        for (i, pole) in poles.iter().enumerate() {
            for cell in &mut cells[cell_of(pole.x - pole.radius)..=cell_of(pole.x + pole.radius)] {
                cell.0.push(i);
            }
        }
        for (i, block) in blocks.iter().enumerate() {
            for cell in &mut cells[cell_of(block.min.x)..=cell_of(block.max.x)] {
                cell.1.push(i);
            }
        }
        Self {
            poles,
            blocks,
            cells,
        }
    }

    /// Distance along the ray `origin + t·direction` (direction of unit length) to the first
    /// surface, if any is closer than `max_t`.
    pub fn cast(&self, origin: &Vector3<f64>, direction: &Vector3<f64>, max_t: f64) -> Option<f64> {
        let mut best = max_t;
        let consider = |best: &mut f64, t: f64| {
            if t > 1e-6 && t < *best {
                *best = t;
            }
        };
        if let Some(t) = ground_hit(origin, direction) {
            consider(&mut best, t);
        }
        // Walk the x slices along the ray until the next one starts beyond the best hit.
        let mut cell = cell_of(origin.x) as isize;
        let step: isize = if direction.x >= 0.0 { 1 } else { -1 };
        while let Some((pole_ids, block_ids)) =
            usize::try_from(cell).ok().and_then(|c| self.cells.get(c))
        {
            let entry_x = FIRST_X_M + CELL_M * (cell as f64 + if step > 0 { 0.0 } else { 1.0 });
            let entry_t = if cell == cell_of(origin.x) as isize {
                0.0
            } else {
                (entry_x - origin.x) / direction.x
            };
            if entry_t >= best {
                break;
            }
            for pole in pole_ids.iter().map(|&i| &self.poles[i]) {
                if let Some(t) = pole_hit(pole, origin, direction) {
                    consider(&mut best, t);
                }
            }
            for block in block_ids.iter().map(|&i| &self.blocks[i]) {
                if let Some(t) = block_hit(block, origin, direction) {
                    consider(&mut best, t);
                }
            }
            cell += step;
        }
        (best < max_t).then_some(best)
    }
}

fn pole_hit(pole: &Pole, origin: &Vector3<f64>, direction: &Vector3<f64>) -> Option<f64> {
    let (ox, oy) = (origin.x - pole.x, origin.y - pole.y);
    let a = direction.x * direction.x + direction.y * direction.y;
    if a < 1e-12 {
        return None;
    }
    let b = ox * direction.x + oy * direction.y;
    let c = ox * ox + oy * oy - pole.radius * pole.radius;
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let t = (-b - disc.sqrt()) / a;
    let z = origin.z + t * direction.z;
    (pole.bottom..=pole.top).contains(&z).then_some(t)
}

fn block_hit(block: &Block, origin: &Vector3<f64>, direction: &Vector3<f64>) -> Option<f64> {
    let mut near = f64::NEG_INFINITY;
    let mut far = f64::INFINITY;
    for axis in 0..3 {
        let inverse = 1.0 / direction[axis];
        let t0 = (block.min[axis] - origin[axis]) * inverse;
        let t1 = (block.max[axis] - origin[axis]) * inverse;
        near = near.max(t0.min(t1));
        far = far.min(t0.max(t1));
    }
    (near <= far && near > 0.0).then_some(near)
}

/// Bound on `|ground_height|`.
const GROUND_AMPLITUDE_M: f64 = 0.12;

/// Height of the ground: long low waves and a short-wavelength texture. The texture matters: a
/// scan's rings on a smooth surface look the same from wherever the sensor stands, and pull ICP
/// towards zero motion; real roads have texture at the scale of the ring spacing.
fn ground_height(x: f64, y: f64) -> f64 {
    0.05 * (0.31 * x + 0.17 * y).sin()
        + 0.03 * (0.83 * x - 0.57 * y).sin()
        + 0.012 * (5.1 * x + 3.3 * y).sin()
        + 0.012 * (-4.3 * x + 6.7 * y).sin()
        + 0.008 * (11.0 * x - 7.9 * y).sin()
        + 0.008 * (8.3 * x + 12.1 * y).sin()
}

/// Where a downward ray meets the ground: false position (Illinois) between the distances at
/// which the ray is at the highest and the lowest height the ground can have.
fn ground_hit(origin: &Vector3<f64>, direction: &Vector3<f64>) -> Option<f64> {
    if direction.z >= 0.0 {
        return None;
    }
    let above = |t: f64| {
        let p = origin + direction * t;
        p.z - ground_height(p.x, p.y)
    };
    let (mut low, mut high) = (
        ((GROUND_AMPLITUDE_M - origin.z) / direction.z).max(0.0),
        (-GROUND_AMPLITUDE_M - origin.z) / direction.z,
    );
    let (mut f_low, mut f_high) = (above(low), above(high));
    if f_low < 0.0 {
        return None;
    }
    let mut side = 0;
    for _ in 0..60 {
        let t = (low * f_high - high * f_low) / (f_high - f_low);
        let f = above(t);
        if f.abs() < 1e-9 {
            return Some(t);
        }
        if f > 0.0 {
            (low, f_low) = (t, f);
            if side == 1 {
                f_high *= 0.5;
            }
            side = 1;
        } else {
            (high, f_high) = (t, f);
            if side == -1 {
                f_low *= 0.5;
            }
            side = -1;
        }
    }
    Some(0.5 * (low + high))
}

/// A spinning lidar: `rings` beams between `lowest_deg` and `highest_deg` elevation,
/// `azimuth_steps` firings per turn, clockwise seen from above, one turn per `period_s`, the
/// sweep starting behind the sensor and facing forward at the scan time. As with a real sensor,
/// the firing azimuths do not repeat from one turn to the next (a random phase per scan): a
/// pattern repeating exactly would sample surfaces parallel to the motion at the same places in
/// every scan, and pin ICP to zero motion along them.
pub struct Lidar {
    pub rings: usize,
    pub lowest_deg: f64,
    pub highest_deg: f64,
    pub azimuth_steps: usize,
    pub period_s: f64,
    pub max_range_m: f64,
    /// Uniform range noise in ±this (metres).
    pub range_noise_m: f64,
    /// Fire each beam in a random direction within its cell of the elevation × azimuth grid
    /// rather than at the cell's corner: random samples of the visible surfaces, without the
    /// fixed ring pattern. On smooth synthetic surfaces that pattern looks the same from
    /// wherever the sensor stands and pulls point-to-point ICP towards zero motion (real
    /// surfaces are rough enough at the ring spacing to hide it).
    pub jitter: bool,
}

impl Lidar {
    /// A 64-beam sensor with the vertical field of view of KITTI's HDL-64 (evenly spaced
    /// beams), 0.36° azimuth resolution, 10 Hz.
    pub fn hdl64_like() -> Self {
        Self {
            rings: 64,
            lowest_deg: -24.8,
            highest_deg: 2.0,
            azimuth_steps: 1000,
            period_s: 0.1,
            max_range_m: 100.0,
            range_noise_m: 0.0,
            jitter: false,
        }
    }

    /// One scan: points in the sensor frame at each firing's own pose, with their times relative
    /// to the scan time. `world_from_sensor_at(τ)` is the sensor's pose `τ` seconds after it.
    pub fn scan(
        &self,
        street: &Street,
        world_from_sensor_at: impl Fn(f64) -> Isometry3<f64>,
        random: &mut Lcg,
    ) -> (Vec<[f32; 3]>, Vec<f32>) {
        let mut points = Vec::new();
        let mut times = Vec::new();
        let phase = random.next_f64();
        let ring_step = (self.highest_deg - self.lowest_deg) / (self.rings - 1).max(1) as f64;
        for step in 0..self.azimuth_steps {
            for ring in 0..self.rings {
                let (azimuth_offset, elevation_offset) = if self.jitter {
                    (random.next_f64(), random.next_f64() - 0.5)
                } else {
                    (0.0, 0.0)
                };
                let fraction = (step as f64 + phase + azimuth_offset) / self.azimuth_steps as f64;
                let time = (fraction - 0.5) * self.period_s;
                let pose = world_from_sensor_at(time);
                // Azimuth from +π (behind, sweep start) down through 0 (ahead) to −π.
                let azimuth = std::f64::consts::PI * (1.0 - 2.0 * fraction);
                let elevation =
                    (self.lowest_deg + ring_step * (ring as f64 + elevation_offset)).to_radians();
                let in_sensor = Vector3::new(
                    elevation.cos() * azimuth.cos(),
                    elevation.cos() * azimuth.sin(),
                    elevation.sin(),
                );
                let direction = pose.rotation * in_sensor;
                let origin = pose.translation.vector;
                if let Some(range) = street.cast(&origin, &direction, self.max_range_m) {
                    let noisy = range + self.range_noise_m * (2.0 * random.next_f64() - 1.0);
                    let p = in_sensor * noisy;
                    points.push([p.x as f32, p.y as f32, p.z as f32]);
                    times.push(time as f32);
                }
            }
        }
        (points, times)
    }
}

/// A pose from position and yaw, pitch, roll (radians).
pub fn pose(position: Vector3<f64>, yaw: f64, pitch: f64, roll: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(position),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

/// `truth[0]⁻¹ · truth[i]`: the truth in the first sensor frame, as odometry reports it.
pub fn relative_to_first(truth: &[Isometry3<f64>]) -> Vec<Isometry3<f64>> {
    let Some(first) = truth.first() else {
        return Vec::new();
    };
    let first_inverse = first.inverse();
    truth.iter().map(|p| first_inverse * p).collect()
}

/// Largest translation (m) and rotation (°) error between two trajectories.
pub fn max_errors(estimate: &[Isometry3<f64>], truth: &[Isometry3<f64>]) -> (f64, f64) {
    estimate
        .iter()
        .zip(truth)
        .map(|(e, t)| {
            let error = e.inverse() * t;
            (
                error.translation.vector.norm(),
                error.rotation.angle().to_degrees(),
            )
        })
        .fold((0.0, 0.0), |(a, b), (c, d)| {
            (f64::max(a, c), f64::max(b, d))
        })
}
