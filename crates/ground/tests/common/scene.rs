//! Synthetic lidar scans: an HDL-64E-like sensor ray-cast against a ground height field and
//! boxes, each return knowing its true height above the ground.

/// A ground height field `z = f(x, y)` in the levelled frame, metres, plus boxes standing on it.
pub struct Scene {
    /// Height of the ground at `(x, y)`.
    pub ground: Box<dyn Fn(f64, f64) -> f64>,
    /// Axis-aligned boxes `[min, max]`, metres.
    pub boxes: Vec<([f64; 3], [f64; 3])>,
}

/// One return of a synthetic scan.
#[derive(Clone, Copy, Debug)]
pub struct Return {
    /// The point, levelled frame.
    pub point: [f32; 3],
    /// True height above the ground under it, metres.
    pub height_m: f64,
    /// True when the ray hit a box.
    pub on_box: bool,
}

/// Sensor height of the synthetic scans (KITTI's HDL-64E), metres.
pub const SENSOR_HEIGHT_M: f64 = 1.73;

impl Scene {
    /// A scene with ground `ground` and no box.
    pub fn new(ground: impl Fn(f64, f64) -> f64 + 'static) -> Self {
        Self {
            ground: Box::new(ground),
            boxes: Vec::new(),
        }
    }

    /// Level ground 1.73 m below the sensor.
    pub fn flat() -> Self {
        Self::new(|_, _| -SENSOR_HEIGHT_M)
    }

    /// Adds a box.
    pub fn with_box(mut self, min: [f64; 3], max: [f64; 3]) -> Self {
        self.boxes.push((min, max));
        self
    }

    /// Casts `beams` beams from −24.8° to +2° of elevation (the HDL-64E's span) every
    /// `azimuth_step_deg`, out to 80 m, with a deterministic ±1 cm range noise.
    pub fn scan(&self, beams: usize, azimuth_step_deg: f64) -> Vec<Return> {
        let mut out = Vec::new();
        let columns = (360.0 / azimuth_step_deg).round() as usize;
        for b in 0..beams {
            let elevation = (-24.8 + 26.8 * b as f64 / (beams - 1).max(1) as f64).to_radians();
            for c in 0..columns {
                let azimuth = (c as f64 * azimuth_step_deg).to_radians();
                let d = [
                    elevation.cos() * azimuth.cos(),
                    elevation.cos() * azimuth.sin(),
                    elevation.sin(),
                ];
                if let Some(r) = self.cast(d, (b * columns + c) as u64) {
                    out.push(r);
                }
            }
        }
        out
    }

    fn cast(&self, d: [f64; 3], seed: u64) -> Option<Return> {
        let mut t_hit = self.ground_hit(d);
        let mut on_box = false;
        for (min, max) in &self.boxes {
            if let Some(t) = slab(d, *min, *max)
                && t_hit.is_none_or(|g| t < g)
            {
                t_hit = Some(t);
                on_box = true;
            }
        }
        let t = t_hit?;
        // ±1 cm of range noise, from a hash of the ray: deterministic.
        let noise = ((seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as f64 / (1u64 << 24) as f64
            - 0.5)
            * 0.02;
        let t = t + noise;
        let p = [t * d[0], t * d[1], t * d[2]];
        if p[0].hypot(p[1]) > 80.0 {
            return None;
        }
        Some(Return {
            point: [p[0] as f32, p[1] as f32, p[2] as f32],
            height_m: p[2] - (self.ground)(p[0], p[1]),
            on_box,
        })
    }

    /// First crossing of the ground along the ray: marched every 5 cm of range, then bisected.
    fn ground_hit(&self, d: [f64; 3]) -> Option<f64> {
        let above = |t: f64| t * d[2] - (self.ground)(t * d[0], t * d[1]);
        let mut t0 = 0.0;
        let step = 0.05;
        while t0 < 90.0 {
            let t1 = t0 + step;
            if above(t1) <= 0.0 {
                let (mut lo, mut hi) = (t0, t1);
                for _ in 0..30 {
                    let mid = 0.5 * (lo + hi);
                    if above(mid) > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                return Some(hi);
            }
            t0 = t1;
        }
        None
    }
}

/// Entry distance of the ray from the origin along `d` into the box, if it hits it.
fn slab(d: [f64; 3], min: [f64; 3], max: [f64; 3]) -> Option<f64> {
    let (mut near, mut far) = (0.0f64, f64::INFINITY);
    for k in 0..3 {
        if d[k].abs() < 1e-12 {
            if 0.0 < min[k] || 0.0 > max[k] {
                return None;
            }
            continue;
        }
        let (a, b) = (min[k] / d[k], max[k] / d[k]);
        near = near.max(a.min(b));
        far = far.min(a.max(b));
    }
    (near <= far && near > 0.0).then_some(near)
}
