//! OXTS RT3003 GPS/IMU packets as KITTI raw publishes them, and the IMU poses they give.
//!
//! One packet is one text line of 30 numbers (see the drive's `oxts/dataformat.txt`):
//! `lat lon alt roll pitch yaw vn ve vf vl vu ax ay az af al au wx wy wz wf wl wu pos_accuracy
//! vel_accuracy navstat numsats posmode velmode orimode`. [`OxtsPacket`] keeps what places the
//! vehicle (position, orientation), how fast it moves, and how much to trust it.
//!
//! # From a packet to a pose
//!
//! The IMU frame is x forward, y left, z up. Its orientation in east-north-up is
//! `R = Rz(yaw) · Ry(pitch) · Rx(roll)`, with OXTS's own angles: yaw 0 = east, counter-clockwise
//! positive (so it is already an ENU heading), pitch positive = front down and roll positive =
//! left side up (both what right-handed rotations about y and x do). Its position is the
//! projected `(east, north)` of `(lat, lon)` and the altitude as up.
//!
//! The projection is the caller's: [`world_from_imu`] takes any `Fn(lat_deg, lon_deg) ->
//! (east_m, north_m)`, so the poses land in the same frame as the map (the CLI passes the map's
//! transverse Mercator). Because a projected grid's north is not true north away from the
//! projection's central meridian (grid convergence), the heading is turned by the angle at which
//! the projection draws true east at that point (measured numerically from the closure; zero for
//! Mercator, a fraction of a degree for a city-sized transverse Mercator). For callers without a
//! map, [`KittiMercator`] is the devkit's own projection.

use crate::error::ReadError;
use crate::text::{data_lines, file_error, line_error, numbers_on_line, read_text, show};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use std::path::Path;

/// Mean Earth radius used by the KITTI devkit's Mercator (the WGS84 semi-major axis), metres.
pub const KITTI_EARTH_RADIUS_M: f64 = 6_378_137.0;

/// One OXTS packet: the fields that place and qualify a pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OxtsPacket {
    /// Latitude of the OXTS unit, degrees.
    pub lat_deg: f64,
    /// Longitude of the OXTS unit, degrees.
    pub lon_deg: f64,
    /// Altitude of the OXTS unit, metres.
    pub alt_m: f64,
    /// Roll, radians: 0 level, positive = left side up.
    pub roll: f64,
    /// Pitch, radians: 0 level, positive = front down.
    pub pitch: f64,
    /// Heading, radians: 0 = east, positive counter-clockwise.
    pub yaw: f64,
    /// Velocity towards north, m/s.
    pub vn: f64,
    /// Velocity towards east, m/s.
    pub ve: f64,
    /// Forward velocity (parallel to the earth's surface), m/s.
    pub vf: f64,
    /// Leftward velocity (parallel to the earth's surface), m/s.
    pub vl: f64,
    /// Upward velocity, m/s.
    pub vu: f64,
    /// Position accuracy (north/east), metres.
    pub pos_accuracy_m: f64,
    /// Velocity accuracy (north/east), m/s.
    pub vel_accuracy_mps: f64,
}

impl OxtsPacket {
    /// Horizontal speed, m/s, from the north and east velocities.
    pub fn horizontal_speed(&self) -> f64 {
        self.vn.hypot(self.ve)
    }
}

/// Parses one packet line (30 numbers). `path` and `line` only name the source in errors.
///
/// # Errors
///
/// [`ReadError::Line`]: wrong count, a non-number or non-finite value, latitude outside
/// [-90, 90] or longitude outside [-180, 180].
pub fn parse_oxts_line(path: &Path, line: usize, text: &str) -> Result<OxtsPacket, ReadError> {
    let v = numbers_on_line::<30>(
        path,
        line,
        text,
        "an OXTS packet: lat lon alt roll pitch yaw vn ve vf vl vu ax ay az af al au \
         wx wy wz wf wl wu pos_accuracy vel_accuracy navstat numsats posmode velmode orimode",
    )?;
    check_lat_lon(v[0], v[1]).map_err(|m| line_error(path, line, m))?;
    check_plausible(v[2], [v[3], v[4], v[5]]).map_err(|m| line_error(path, line, m))?;
    Ok(OxtsPacket {
        lat_deg: v[0],
        lon_deg: v[1],
        alt_m: v[2],
        roll: v[3],
        pitch: v[4],
        yaw: v[5],
        vn: v[6],
        ve: v[7],
        vf: v[8],
        vl: v[9],
        vu: v[10],
        pos_accuracy_m: v[23],
        vel_accuracy_mps: v[24],
    })
}

/// Lowest altitude of a packet, metres: below any land surface (the Dead Sea shore is at -430 m).
pub const MIN_ALTITUDE_M: f64 = -1_000.0;

/// Highest altitude of a packet, metres: above any road (the highest are near 5,800 m).
pub const MAX_ALTITUDE_M: f64 = 10_000.0;

/// Largest roll, pitch or yaw of a packet, radians: the devkit gives them within ±π; a full
/// turn either way allows an unwrapped heading near ±π.
pub const MAX_ANGLE_RAD: f64 = 2.0 * std::f64::consts::PI;

/// Fastest a vehicle is taken to move between two packets, m/s (360 km/h).
pub const MAX_SPEED_MPS: f64 = 100.0;

/// What a GPS fix may jump between two packets beyond [`MAX_SPEED_MPS`], metres.
pub const FIX_JUMP_SLACK_M: f64 = 10.0;

/// Checks a packet's altitude and angles against physical bounds ([`MIN_ALTITUDE_M`],
/// [`MAX_ALTITUDE_M`], [`MAX_ANGLE_RAD`]).
fn check_plausible(alt_m: f64, angles: [f64; 3]) -> Result<(), String> {
    if !(MIN_ALTITUDE_M..=MAX_ALTITUDE_M).contains(&alt_m) {
        return Err(format!(
            "altitude {} m outside [{MIN_ALTITUDE_M}, {MAX_ALTITUDE_M}] m",
            show(alt_m)
        ));
    }
    for (name, angle) in ["roll", "pitch", "yaw"].into_iter().zip(angles) {
        if angle.abs() > MAX_ANGLE_RAD {
            return Err(format!(
                "{name} {} rad outside [-2π, 2π] (the devkit gives ±π)",
                show(angle)
            ));
        }
    }
    Ok(())
}

/// Checks that consecutive packets do not jump further than a vehicle moves
/// ([`MAX_SPEED_MPS`] over the time between them, plus [`FIX_JUMP_SLACK_M`]); the distance is
/// measured on a sphere of the WGS84 equatorial radius, enough for a bound.
///
/// # Errors
///
/// [`ReadError::Line`] naming the later packet's file.
pub fn check_packet_jumps(
    paths: &[std::path::PathBuf],
    times_s: &[f64],
    packets: &[OxtsPacket],
) -> Result<(), ReadError> {
    const EARTH_RADIUS_M: f64 = 6_378_137.0;
    for k in 1..packets.len().min(times_s.len()).min(paths.len()) {
        let (a, b) = (&packets[k - 1], &packets[k]);
        let (lat_a, lat_b) = (a.lat_deg.to_radians(), b.lat_deg.to_radians());
        let dlon = (b.lon_deg - a.lon_deg).to_radians();
        // Haversine.
        let h = ((lat_b - lat_a) / 2.0).sin().powi(2)
            + lat_a.cos() * lat_b.cos() * (dlon / 2.0).sin().powi(2);
        let distance_m = 2.0 * EARTH_RADIUS_M * h.sqrt().min(1.0).asin();
        let dt_s = (times_s[k] - times_s[k - 1]).abs();
        let allowed_m = MAX_SPEED_MPS * dt_s + FIX_JUMP_SLACK_M;
        if distance_m > allowed_m {
            return Err(line_error(
                &paths[k],
                1,
                format!(
                    "the position jumps {distance_m:.0} m from the previous packet in {dt_s} s (at most \
                     {allowed_m:.0} m at {MAX_SPEED_MPS} m/s)"
                ),
            ));
        }
    }
    Ok(())
}

/// Checks a geodetic position's range, saying which value is out and what the range is.
pub(crate) fn check_lat_lon(lat: f64, lon: f64) -> Result<(), String> {
    if !(-90.0..=90.0).contains(&lat) {
        return Err(format!("latitude {lat} outside [-90, 90] degrees"));
    }
    if !(-180.0..=180.0).contains(&lon) {
        return Err(format!("longitude {lon} outside [-180, 180] degrees"));
    }
    Ok(())
}

/// Reads one KITTI raw OXTS packet file (`oxts/data/NNNNNNNNNN.txt`): exactly one data line.
///
/// # Errors
///
/// [`ReadError`]: unreadable, no packet, more than one line of data, or a malformed packet.
pub fn read_oxts_packet(path: &Path) -> Result<OxtsPacket, ReadError> {
    let text = read_text(path)?;
    let mut lines = data_lines(&text);
    let Some((line, first)) = lines.next() else {
        return Err(file_error(
            path,
            "no OXTS packet (expected one line of 30 numbers)",
        ));
    };
    if let Some((extra, _)) = lines.next() {
        return Err(line_error(
            path,
            extra,
            "a second line of data; a KITTI raw OXTS file holds one packet",
        ));
    }
    parse_oxts_line(path, line, first)
}

/// Why a projection could not place a packet.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error(
    "the projection maps lat {lat_deg}, lon {lon_deg} to a non-finite point or cannot tell east \
     there (is it a projection of degrees (lat, lon) to metres (east, north)?)"
)]
pub struct ProjectionError {
    /// Latitude given to the projection, degrees.
    pub lat_deg: f64,
    /// Longitude given to the projection, degrees.
    pub lon_deg: f64,
}

/// Step, in degrees of longitude, over which the direction of true east is measured in the
/// caller's projection (about 0.7 m at 49° N: small against any map's curvature, large against
/// rounding in coordinates of millions of metres).
const EAST_STEP_DEG: f64 = 1e-5;

/// The angle (radians, counter-clockwise from the grid's x axis) at which `projection` draws true
/// east at `(lat, lon)`: the grid convergence, to be added to an ENU heading.
pub fn grid_convergence<P>(
    projection: &P,
    lat_deg: f64,
    lon_deg: f64,
) -> Result<f64, ProjectionError>
where
    P: Fn(f64, f64) -> (f64, f64) + ?Sized,
{
    let (e0, n0) = projection(lat_deg, lon_deg - EAST_STEP_DEG);
    let (e1, n1) = projection(lat_deg, lon_deg + EAST_STEP_DEG);
    let (de, dn) = (e1 - e0, n1 - n0);
    if !(de.is_finite() && dn.is_finite()) || de.hypot(dn) <= 0.0 {
        return Err(ProjectionError { lat_deg, lon_deg });
    }
    Ok(dn.atan2(de))
}

/// The pose of the IMU in the projection's metric frame (`world_from_imu`): translation
/// `(east, north, alt)`, rotation `Rz(yaw + γ) · Ry(pitch) · Rx(roll)` where γ is the
/// [`grid_convergence`] (see the module documentation).
///
/// # Errors
///
/// [`ProjectionError`] when the projection returns a non-finite point or cannot tell east.
pub fn world_from_imu<P>(
    packet: &OxtsPacket,
    projection: &P,
) -> Result<Isometry3<f64>, ProjectionError>
where
    P: Fn(f64, f64) -> (f64, f64) + ?Sized,
{
    world_from_geodetic(
        [packet.lat_deg, packet.lon_deg, packet.alt_m],
        [packet.roll, packet.pitch, packet.yaw],
        projection,
    )
}

/// The pose of a body at `[lat_deg, lon_deg, alt_m]` with ENU angles `[roll, pitch, yaw]`
/// (radians, `R = Rz(yaw) · Ry(pitch) · Rx(roll)`, yaw from true east) in the projection's metric
/// frame, the heading turned by the [`grid_convergence`]. Shared by OXTS packets and geodetic pose
/// files so both land in a map the same way.
///
/// # Errors
///
/// [`ProjectionError`] when the projection returns a non-finite point or cannot tell east.
pub fn world_from_geodetic<P>(
    [lat_deg, lon_deg, alt_m]: [f64; 3],
    [roll, pitch, yaw]: [f64; 3],
    projection: &P,
) -> Result<Isometry3<f64>, ProjectionError>
where
    P: Fn(f64, f64) -> (f64, f64) + ?Sized,
{
    let (east, north) = projection(lat_deg, lon_deg);
    if !(east.is_finite() && north.is_finite()) {
        return Err(ProjectionError { lat_deg, lon_deg });
    }
    let gamma = grid_convergence(projection, lat_deg, lon_deg)?;
    Ok(Isometry3::from_parts(
        Translation3::new(east, north, alt_m),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw + gamma),
    ))
}

/// The KITTI devkit's Mercator projection (`latToScale`, `latlonToMercator`), for callers that
/// have no map to take a projection from.
///
/// With `s = cos(lat0)`: `east = s · R · lon · π/180`, `north = s · R · ln(tan(π (90 + lat) /
/// 360))`, `R` = [`KITTI_EARTH_RADIUS_M`]. The scale makes it metric (within 0.1 % over a few
/// km) near the reference latitude `lat0`, which the devkit takes from the drive's first packet.
/// Being conformal, it keeps OXTS headings as they are.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KittiMercator {
    /// `s · R`: metres per radian of longitude.
    scaled_radius: f64,
    /// Subtracted from every result: `(0, 0)` for the devkit's absolute coordinates.
    origin: (f64, f64),
}

impl KittiMercator {
    /// The devkit's projection with reference latitude `lat0_deg` (absolute coordinates, as the
    /// devkit computes them before making poses relative to the first).
    pub fn new(lat0_deg: f64) -> Self {
        Self {
            scaled_radius: lat0_deg.to_radians().cos() * KITTI_EARTH_RADIUS_M,
            origin: (0.0, 0.0),
        }
    }

    /// The same projection shifted so that `(lat0, lon0)` maps to `(0, 0)`: the same geometry,
    /// with small coordinates.
    pub fn centered(lat0_deg: f64, lon0_deg: f64) -> Self {
        let absolute = Self::new(lat0_deg);
        Self {
            origin: absolute.project(lat0_deg, lon0_deg),
            ..absolute
        }
    }

    /// `(east, north)` in metres of a position in degrees.
    pub fn project(&self, lat_deg: f64, lon_deg: f64) -> (f64, f64) {
        let east = self.scaled_radius * lon_deg.to_radians();
        let north =
            self.scaled_radius * (std::f64::consts::PI * (90.0 + lat_deg) / 360.0).tan().ln();
        (east - self.origin.0, north - self.origin.1)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};
    use std::f64::consts::FRAC_PI_2;
    use std::path::PathBuf;

    /// The first packet of KITTI raw 2011_09_26_drive_0013, frame 80.
    const PACKET: &str = "49.013935274642 8.4374643465654 114.69784545898 -0.004931 0.004834 \
        1.9052983267949 10.862396074037 -3.6628511955263 11.463101441533 0.07925327337981 \
        0.085761452507219 -0.013296269366246 0.35893833658734 9.8371604300247 0.02572267625039 \
        0.40577203372438 9.835436500945 -0.0026489814375696 0.015006539816306 0.041466329256011 \
        -0.0024846475031987 0.015203852771253 0.041396600849405 0.21216267343715 \
        0.032526911934581 4 12 4 4 0";

    #[test]
    fn parses_a_packet() {
        let p = parse_oxts_line(Path::new("o.txt"), 1, PACKET).unwrap();
        assert_eq!(p.lat_deg, 49.013935274642);
        assert_eq!(p.yaw, 1.9052983267949);
        assert_eq!(p.vf, 11.463101441533);
        assert_eq!(p.pos_accuracy_m, 0.21216267343715);
        assert_eq!(p.vel_accuracy_mps, 0.032526911934581);
        // Heading 109° (north of west-ish): north velocity positive, east negative.
        assert!(p.vn > 0.0 && p.ve < 0.0);
        assert!((p.horizontal_speed() - 11.463).abs() < 0.01);
    }

    #[test]
    fn malformed_packets_name_file_and_line() {
        let short = PACKET.rsplit_once(' ').unwrap().0;
        let err = parse_oxts_line(Path::new("o.txt"), 3, short)
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("o.txt:3:") && err.contains("found 29"),
            "{err}"
        );
        let bad = PACKET.replacen("114.69784545898", "1l4.6", 1);
        let err = parse_oxts_line(Path::new("o.txt"), 1, &bad)
            .unwrap_err()
            .to_string();
        assert!(err.contains("`1l4.6` is not a number"), "{err}");
        let lat = PACKET.replacen("49.013935274642", "91", 1);
        let err = parse_oxts_line(Path::new("o.txt"), 1, &lat)
            .unwrap_err()
            .to_string();
        assert!(err.contains("latitude 91 outside [-90, 90]"), "{err}");
        let lon = PACKET.replacen("8.4374643465654", "-180.5", 1);
        let err = parse_oxts_line(Path::new("o.txt"), 1, &lon)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("longitude -180.5 outside [-180, 180]"),
            "{err}"
        );

        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("0000000000.txt");
        std::fs::write(&path, format!("{PACKET}\n{PACKET}\n")).unwrap();
        let err = read_oxts_packet(&path).unwrap_err().to_string();
        assert!(
            err.contains("0000000000.txt:2:") && err.contains("one packet"),
            "{err}"
        );
        std::fs::write(&path, "\n").unwrap();
        let err = read_oxts_packet(&path).unwrap_err().to_string();
        assert!(err.contains("no OXTS packet"), "{err}");
        std::fs::write(&path, format!("{PACKET}\n")).unwrap();
        assert_eq!(read_oxts_packet(&path).unwrap().alt_m, 114.69784545898);
    }

    #[test]
    fn absurd_altitudes_and_angles_are_refused_with_file_and_line() {
        // Issue 31: 1e308 was accepted for the angles and the altitude.
        let fields: Vec<&str> = PACKET.split_whitespace().collect();
        for (k, value, expected) in [
            (2, "1e308", "altitude 1e308 m outside [-1000, 10000] m"),
            (2, "-1500", "altitude -1500 m outside"),
            (3, "1e308", "roll 1e308 rad outside [-2π, 2π]"),
            (4, "-7", "pitch -7 rad outside"),
            (5, "1e308", "yaw 1e308 rad outside"),
        ] {
            let mut changed = fields.clone();
            changed[k] = value;
            let err = parse_oxts_line(Path::new("o.txt"), 4, &changed.join(" "))
                .unwrap_err()
                .to_string();
            assert!(
                err.starts_with("o.txt:4: ") && err.contains(expected),
                "{err}"
            );
        }
        let mut yaw = fields.clone();
        yaw[5] = "-3.1";
        assert!(parse_oxts_line(Path::new("o.txt"), 1, &yaw.join(" ")).is_ok());
    }

    #[test]
    fn a_jump_faster_than_a_vehicle_between_packets_is_refused() {
        let a = parse_oxts_line(Path::new("a.txt"), 1, PACKET).unwrap();
        let paths = [PathBuf::from("0.txt"), PathBuf::from("1.txt")];
        // 0.0001° of latitude is 11.1 m: within 100 m/s × 0.1 s + 10 m = 20 m.
        let near = OxtsPacket {
            lat_deg: a.lat_deg + 1e-4,
            ..a
        };
        check_packet_jumps(&paths, &[0.0, 0.1], &[a, near]).unwrap();
        // 0.0002° is 22.3 m: over 20 m.
        let far = OxtsPacket {
            lat_deg: a.lat_deg + 2e-4,
            ..a
        };
        let err = check_packet_jumps(&paths, &[0.0, 0.1], &[a, far])
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("1.txt:1: the position jumps 22 m") && err.contains("at most 20 m"),
            "{err}"
        );
        // Issue 31's 98° latitude jump (from 49° N to 49° S across the equator and beyond).
        let flipped = OxtsPacket {
            lat_deg: a.lat_deg - 98.0,
            ..a
        };
        assert!(check_packet_jumps(&paths, &[0.0, 0.1], &[a, flipped]).is_err());
        // A longer gap allows a longer way.
        check_packet_jumps(&paths, &[0.0, 1.0], &[a, far]).unwrap();
    }

    #[test]
    fn pose_from_packet_by_hand() {
        let mut p = parse_oxts_line(Path::new("o.txt"), 1, PACKET).unwrap();
        p.roll = 0.0;
        p.pitch = 0.1;
        p.yaw = FRAC_PI_2; // facing north
        let flat = |lat: f64, lon: f64| (lon * 1000.0, lat * 1000.0);
        let pose = world_from_imu(&p, &flat).unwrap();
        assert!(
            (pose.translation.vector
                - Vector3::new(8437.4643465654, 49013.935274642, 114.69784545898))
            .norm()
                < 1e-9
        );
        // Forward (x) points north and, with pitch 0.1 (front down), slightly down.
        let fwd = pose.rotation * Vector3::x();
        assert!(
            (fwd - Vector3::new(0.0, 0.1f64.cos(), -0.1f64.sin())).norm() < 1e-12,
            "{fwd}"
        );
        // Roll positive = left side up: left (y) gains +z.
        p.pitch = 0.0;
        p.roll = 0.2;
        let pose = world_from_imu(&p, &flat).unwrap();
        let left = pose.rotation * Vector3::y();
        assert!(
            (left - Vector3::new(-0.2f64.cos(), 0.0, 0.2f64.sin())).norm() < 1e-12,
            "{left}"
        );
    }

    #[test]
    fn grid_convergence_turns_the_heading() {
        let mut p = parse_oxts_line(Path::new("o.txt"), 1, PACKET).unwrap();
        (p.roll, p.pitch, p.yaw) = (0.0, 0.0, 0.0);
        // A "grid" turned 30° counter-clockwise from true east-north.
        let a = 30f64.to_radians();
        let turned = |lat: f64, lon: f64| {
            let (e, n) = (lon * 1000.0, lat * 1000.0);
            (a.cos() * e - a.sin() * n, a.sin() * e + a.cos() * n)
        };
        let pose = world_from_imu(&p, &turned).unwrap();
        let fwd = pose.rotation * Vector3::x();
        assert!(
            (fwd - Vector3::new(a.cos(), a.sin(), 0.0)).norm() < 1e-9,
            "{fwd}"
        );
        assert!(world_from_imu(&p, &|_, _| (f64::NAN, 0.0)).is_err());
        assert!(world_from_imu(&p, &|_, _| (1.0, 2.0)).is_err());
    }

    #[test]
    fn kitti_mercator_matches_the_devkit_formula() {
        let lat0 = 49.0f64;
        let m = KittiMercator::new(lat0);
        let s = lat0.to_radians().cos();
        let (e, n) = m.project(49.0, 8.0);
        assert!((e - s * 6_378_137.0 * 8.0 * std::f64::consts::PI / 180.0).abs() < 1e-6);
        let expected_n = s * 6_378_137.0 * ((std::f64::consts::PI * 139.0 / 360.0).tan()).ln();
        assert!((n - expected_n).abs() < 1e-6);
        // Metric near lat0: 0.001° of latitude is 111.2 m on the ground (WGS84, at 49°).
        let c = KittiMercator::centered(49.0, 8.0);
        assert_eq!(c.project(49.0, 8.0), (0.0, 0.0));
        let (_, dn) = c.project(49.001, 8.0);
        assert!((dn - 111.2).abs() < 0.5, "{dn}");
        // Conformal: no convergence.
        let gamma = grid_convergence(&|la, lo| c.project(la, lo), 49.0, 8.0).unwrap();
        assert!(gamma.abs() < 1e-9);
        // Centred on the packet itself, the packet lands on (0, 0, alt).
        let p = parse_oxts_line(Path::new("o.txt"), 1, PACKET).unwrap();
        let here = KittiMercator::centered(p.lat_deg, p.lon_deg);
        let pose = world_from_imu(&p, &|la, lo| here.project(la, lo)).unwrap();
        assert!((pose * Point3::origin() - Point3::new(0.0, 0.0, p.alt_m)).norm() < 1e-9);
    }
}
