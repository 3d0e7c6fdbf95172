//! Decoders of the few ROS 2 messages a drive needs, from CDR (see [`super::cdr`]). Each decodes
//! the fields it uses in order and ignores what follows them.

use super::cdr::{Cdr, CdrError, CdrResult};
use crate::scan::Scan;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

/// Schema names, as rosbag2 writes them.
pub const POINTCLOUD2: &str = "sensor_msgs/msg/PointCloud2";
/// `tf2_msgs/msg/TFMessage` (topics `/tf` and `/tf_static`).
pub const TFMESSAGE: &str = "tf2_msgs/msg/TFMessage";
/// `nav_msgs/msg/Odometry`.
pub const ODOMETRY: &str = "nav_msgs/msg/Odometry";
/// `sensor_msgs/msg/NavSatFix`.
pub const NAVSATFIX: &str = "sensor_msgs/msg/NavSatFix";

/// Largest deviation from 1 accepted for a quaternion's norm before it is normalised: a norm
/// far from 1 means a corrupt or mis-decoded message, not rounding.
const QUATERNION_NORM_TOLERANCE: f64 = 1e-2;

/// `std_msgs/Header`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Header {
    /// `stamp` in seconds.
    pub stamp_s: f64,
    pub frame_id: String,
}

fn header(c: &mut Cdr<'_>) -> CdrResult<Header> {
    let sec = c.i32("header.stamp.sec")?;
    let nanosec = c.u32("header.stamp.nanosec")?;
    if nanosec >= 1_000_000_000 {
        return Err(CdrError(format!(
            "header.stamp.nanosec {nanosec} is not below 1e9"
        )));
    }
    let frame_id = c.string("header.frame_id")?;
    Ok(Header {
        stamp_s: f64::from(sec) + f64::from(nanosec) * 1e-9,
        frame_id,
    })
}

/// Only the header of a message that starts with one (PointCloud2, Odometry, NavSatFix).
pub(crate) fn decode_header(bytes: &[u8]) -> CdrResult<Header> {
    header(&mut Cdr::new(bytes)?)
}

fn finite(values: &[f64], what: &str) -> CdrResult<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(CdrError(format!("{what} is not finite: {values:?}")))
    }
}

/// `geometry_msgs/Vector3` (or `Point`) then `Quaternion`, as a rigid transform.
fn pose(c: &mut Cdr<'_>, what: &str) -> CdrResult<Isometry3<f64>> {
    let mut v = [0.0; 7];
    for x in &mut v {
        *x = c.f64(what)?;
    }
    finite(&v, what)?;
    let q = Quaternion::new(v[6], v[3], v[4], v[5]);
    let norm = q.norm();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
        return Err(CdrError(format!(
            "{what}: quaternion (x y z w) = {:?} has norm {norm}, not 1",
            &v[3..]
        )));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// One `geometry_msgs/TransformStamped`: `parent_from_child` at a time.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct StampedTransform {
    pub stamp_s: f64,
    pub parent: String,
    pub child: String,
    pub parent_from_child: Isometry3<f64>,
}

/// `tf2_msgs/msg/TFMessage`.
pub(crate) fn decode_tf(bytes: &[u8]) -> CdrResult<Vec<StampedTransform>> {
    let mut c = Cdr::new(bytes)?;
    // Smallest TransformStamped: 8 (stamp) + 4 + 4 (empty strings) + 56 (7 float64).
    let n = c.count(72, "transforms")?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let h = header(&mut c)?;
        let child = c.string("child_frame_id")?;
        let parent_from_child = pose(&mut c, "transform")?;
        out.push(StampedTransform {
            stamp_s: h.stamp_s,
            parent: h.frame_id,
            child,
            parent_from_child,
        });
    }
    Ok(out)
}

/// `nav_msgs/msg/Odometry`: header, child frame and `pose.pose` (covariance and twist unused).
pub(crate) fn decode_odometry(bytes: &[u8]) -> CdrResult<StampedTransform> {
    let mut c = Cdr::new(bytes)?;
    let h = header(&mut c)?;
    let child = c.string("child_frame_id")?;
    let parent_from_child = pose(&mut c, "pose.pose")?;
    Ok(StampedTransform {
        stamp_s: h.stamp_s,
        parent: h.frame_id,
        child,
        parent_from_child,
    })
}

/// `sensor_msgs/msg/NavSatFix`, position only.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Fix {
    pub header: Header,
    /// `status.status`: -1 no fix, 0 fix, 1 SBAS, 2 GBAS.
    pub status: i8,
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
}

pub(crate) fn decode_navsatfix(bytes: &[u8]) -> CdrResult<Fix> {
    let mut c = Cdr::new(bytes)?;
    let header = header(&mut c)?;
    let status = i8::from_ne_bytes([c.u8("status.status")?]);
    let _service = c.u16("status.service")?;
    let lat_deg = c.f64("latitude")?;
    let lon_deg = c.f64("longitude")?;
    let alt_m = c.f64("altitude")?;
    Ok(Fix {
        header,
        status,
        lat_deg,
        lon_deg,
        alt_m,
    })
}

/// `sensor_msgs/PointField` datatypes.
fn datatype_size(datatype: u8) -> Option<usize> {
    match datatype {
        1 | 2 => Some(1),
        3 | 4 => Some(2),
        5..=7 => Some(4),
        8 => Some(8),
        _ => None,
    }
}

#[derive(Debug, Clone, Copy)]
struct Field {
    offset: usize,
    datatype: u8,
}

/// Reads one value of `datatype` at `bytes[..size]` (the caller checked the length).
fn value(bytes: &[u8], datatype: u8, big: bool) -> f64 {
    let mut b = [0u8; 8];
    let size = datatype_size(datatype).unwrap_or(0).min(bytes.len());
    b[..size].copy_from_slice(&bytes[..size]);
    if big {
        b[..size].reverse();
    }
    // Now little-endian in b[..size].
    match datatype {
        1 => f64::from(b[0] as i8),
        2 => f64::from(b[0]),
        3 => f64::from(i16::from_le_bytes([b[0], b[1]])),
        4 => f64::from(u16::from_le_bytes([b[0], b[1]])),
        5 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        6 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        7 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        _ => f64::from_le_bytes(b),
    }
}

/// A decoded `sensor_msgs/msg/PointCloud2`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Cloud {
    pub header: Header,
    pub scan: Scan,
}

/// `sensor_msgs/msg/PointCloud2`: fields `x`, `y`, `z` of type FLOAT32 or FLOAT64 (count 1) at
/// their offsets, and `intensity` (any numeric type) when present; `width × height` points of
/// `point_step` bytes in rows of `row_step`, checked against the data's length. Points are kept
/// as they are (NaN included), in row order.
pub(crate) fn decode_pointcloud2(bytes: &[u8]) -> CdrResult<Cloud> {
    let mut c = Cdr::new(bytes)?;
    let header = header(&mut c)?;
    let height = c.u32("height")? as usize;
    let width = c.u32("width")? as usize;
    // Smallest PointField: 4 + 1 (name) + pad + 4 + 1 + pad + 4 = 16 bytes, say 13 unaligned.
    let n_fields = c.count(13, "fields")?;
    let (mut x, mut y, mut z, mut intensity) = (None, None, None, None);
    for _ in 0..n_fields {
        let name = c.string("fields.name")?;
        let offset = c.u32("fields.offset")? as usize;
        let datatype = c.u8("fields.datatype")?;
        let count = c.u32("fields.count")?;
        let slot = match name.as_str() {
            "x" => &mut x,
            "y" => &mut y,
            "z" => &mut z,
            "intensity" => &mut intensity,
            _ => continue,
        };
        if datatype_size(datatype).is_none() {
            return Err(CdrError(format!(
                "field `{name}` has datatype {datatype}, not one of 1..=8"
            )));
        }
        if name != "intensity" && !matches!(datatype, 7 | 8) {
            return Err(CdrError(format!(
                "field `{name}` has datatype {datatype}; x, y, z must be FLOAT32 (7) or FLOAT64 (8)"
            )));
        }
        if count != 1 {
            return Err(CdrError(format!("field `{name}` has count {count}, not 1")));
        }
        *slot = Some(Field { offset, datatype });
    }
    let is_bigendian = c.bool("is_bigendian")?;
    let point_step = c.u32("point_step")? as usize;
    let row_step = c.u32("row_step")? as usize;
    let data = c.byte_seq("data")?;
    let need = |f: Option<Field>, name: &str| {
        f.ok_or_else(|| CdrError(format!("no field `{name}` (need x, y, z)")))
    };
    let (x, y, z) = (need(x, "x")?, need(y, "y")?, need(z, "z")?);
    for (name, f) in [
        ("x", Some(x)),
        ("y", Some(y)),
        ("z", Some(z)),
        ("intensity", intensity),
    ] {
        let Some(f) = f else { continue };
        let end = f.offset.checked_add(datatype_size(f.datatype).unwrap_or(8));
        if end.is_none_or(|end| end > point_step) {
            return Err(CdrError(format!(
                "field `{name}` at offset {} does not fit in point_step {point_step}",
                f.offset
            )));
        }
    }
    let row_bytes = width.checked_mul(point_step);
    if row_bytes.is_none_or(|r| r > row_step) {
        return Err(CdrError(format!(
            "width {width} × point_step {point_step} exceeds row_step {row_step}"
        )));
    }
    if height.checked_mul(row_step) != Some(data.len()) {
        return Err(CdrError(format!(
            "height {height} × row_step {row_step} is not the data length {}",
            data.len()
        )));
    }
    // Both products are now bounded by data.len(), so the allocation is too.
    let n = width * height;
    let mut scan = Scan {
        points_in_sensor: Vec::with_capacity(n),
        intensity: Vec::with_capacity(if intensity.is_some() { n } else { 0 }),
    };
    let read = |point: &[u8], f: Field| value(&point[f.offset..], f.datatype, is_bigendian);
    if point_step > 0 {
        for row in data.chunks_exact(row_step.max(1)).take(height) {
            for point in row.chunks_exact(point_step).take(width) {
                scan.points_in_sensor.push([
                    read(point, x) as f32,
                    read(point, y) as f32,
                    read(point, z) as f32,
                ]);
                if let Some(f) = intensity {
                    scan.intensity.push(read(point, f) as f32);
                }
            }
        }
    }
    Ok(Cloud { header, scan })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
pub(crate) mod tests {
    use super::*;

    /// A little CDR writer for tests: aligned primitives after a 4-byte header.
    pub(crate) struct W {
        pub buf: Vec<u8>,
        big: bool,
    }

    impl W {
        pub fn new(big: bool) -> Self {
            Self {
                buf: vec![0, if big { 0 } else { 1 }, 0, 0],
                big,
            }
        }
        fn align(&mut self, n: usize) {
            while !(self.buf.len() - 4).is_multiple_of(n) {
                self.buf.push(0);
            }
        }
        fn raw(&mut self, mut b: Vec<u8>) {
            self.align(b.len());
            if self.big {
                b.reverse();
            }
            self.buf.extend(b);
        }
        pub fn u8(&mut self, v: u8) -> &mut Self {
            self.buf.push(v);
            self
        }
        pub fn u32(&mut self, v: u32) -> &mut Self {
            self.raw(v.to_le_bytes().to_vec());
            self
        }
        pub fn f64(&mut self, v: f64) -> &mut Self {
            self.raw(v.to_le_bytes().to_vec());
            self
        }
        pub fn string(&mut self, s: &str) -> &mut Self {
            self.u32(s.len() as u32 + 1);
            self.buf.extend(s.as_bytes());
            self.buf.push(0);
            self
        }
        pub fn header(&mut self, sec: u32, nsec: u32, frame: &str) -> &mut Self {
            self.u32(sec).u32(nsec).string(frame)
        }
    }

    /// A PointCloud2 with the given fields `(name, offset, datatype)` and raw data.
    pub(crate) fn cloud(
        big: bool,
        fields: &[(&str, u32, u8)],
        (height, width, point_step, row_step): (u32, u32, u32, u32),
        data: &[u8],
    ) -> Vec<u8> {
        let mut w = W::new(big);
        w.header(10, 5, "lidar").u32(height).u32(width);
        w.u32(fields.len() as u32);
        for &(name, offset, datatype) in fields {
            w.string(name).u32(offset).u8(datatype).u32(1);
        }
        w.u8(u8::from(big)).u32(point_step).u32(row_step);
        w.u32(data.len() as u32);
        w.buf.extend(data);
        w.u8(1);
        w.buf
    }

    #[test]
    fn float64_big_endian_cloud_with_padding_and_rows() {
        // 2 rows × 1 point, point_step 32 (x y z f64 at 0, 8, 16; intensity u16 at 24), rows
        // padded to 40 bytes.
        let mut data = Vec::new();
        for p in [[1.0f64, -2.0, 3.5], [4.0, 5.0, -6.25]] {
            for v in p {
                data.extend(v.to_be_bytes());
            }
            data.extend(300u16.to_be_bytes());
            data.extend([0u8; 14]);
        }
        let fields = [("x", 0, 8), ("y", 8, 8), ("z", 16, 8), ("intensity", 24, 4)];
        let msg = cloud(true, &fields, (2, 1, 32, 40), &data);
        let c = decode_pointcloud2(&msg).unwrap();
        assert_eq!(c.header.frame_id, "lidar");
        assert!((c.header.stamp_s - 10.000_000_005).abs() < 1e-12);
        assert_eq!(
            c.scan.points_in_sensor,
            vec![[1.0, -2.0, 3.5], [4.0, 5.0, -6.25]]
        );
        assert_eq!(c.scan.intensity, vec![300.0, 300.0]);
    }

    #[test]
    fn inconsistent_clouds_are_errors() {
        let f32s = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)];
        let data = vec![0u8; 24];
        assert!(decode_pointcloud2(&cloud(false, &f32s, (1, 2, 12, 24), &data)).is_ok());
        let err = |fields: &[(&str, u32, u8)], dims, data: &[u8]| {
            decode_pointcloud2(&cloud(false, fields, dims, data))
                .unwrap_err()
                .0
        };
        // Field beyond the point.
        assert!(err(&f32s, (1, 2, 8, 24), &data).contains("point_step"));
        // Width too large for the row.
        assert!(err(&f32s, (1, 3, 12, 24), &data).contains("row_step"));
        // Height × row_step not the data length, including overflow.
        assert!(err(&f32s, (2, 2, 12, 24), &data).contains("data length"));
        let huge = (u32::MAX, u32::MAX, u32::MAX, u32::MAX);
        assert!(err(&f32s, huge, &data).contains("row_step"));
        // Missing z; integer x.
        assert!(err(&f32s[..2], (1, 2, 12, 24), &data).contains("`z`"));
        assert!(
            err(
                &[("x", 0, 5), ("y", 4, 7), ("z", 8, 7)],
                (1, 2, 12, 24),
                &data
            )
            .contains("FLOAT")
        );
        // Zero point_step with zero width reads no points.
        let c = decode_pointcloud2(&cloud(
            false,
            &[("x", 0, 7), ("y", 0, 7), ("z", 0, 7)],
            (0, 0, 4, 0),
            &[],
        ))
        .unwrap();
        assert!(c.scan.is_empty());
    }

    #[test]
    fn tf_message_and_bad_quaternion() {
        let mut w = W::new(false);
        w.u32(1).header(1, 0, "odom").string("base_link");
        for v in [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0] {
            w.f64(v);
        }
        let tf = decode_tf(&w.buf).unwrap();
        assert_eq!(tf.len(), 1);
        assert_eq!(
            (tf[0].parent.as_str(), tf[0].child.as_str()),
            ("odom", "base_link")
        );
        assert_eq!(tf[0].parent_from_child.translation.vector.z, 3.0);
        let mut w = W::new(false);
        w.u32(1).header(1, 0, "odom").string("base_link");
        for v in [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 2.0] {
            w.f64(v);
        }
        assert!(decode_tf(&w.buf).unwrap_err().0.contains("norm"));
    }
}

/// Every message of the fixture, mutated: truncated at every length (clouds: at 300 lengths),
/// a u32 overwritten with huge or odd values at every 4-byte offset of the first 160 bytes, and
/// random byte edits (proptest). The decoders must return, never panic; truncation before the
/// last field they read must be an error.
#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod mutations {
    use super::*;
    use proptest::prelude::*;
    use std::sync::OnceLock;

    fn fixture_messages() -> &'static [(String, Vec<u8>)] {
        static MESSAGES: OnceLock<Vec<(String, Vec<u8>)>> = OnceLock::new();
        MESSAGES.get_or_init(|| {
            let path = concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/tests/fixtures/kitti-0013.mcap"
            );
            let bytes = std::fs::read(path).unwrap();
            let mut seen = std::collections::HashSet::new();
            mcap::MessageStream::new(&bytes)
                .unwrap()
                .map(Result::unwrap)
                // The first two messages of each topic suffice: the rest have the same layout.
                .filter(|m| {
                    let n = seen
                        .iter()
                        .filter(|t: &&String| **t == m.channel.topic)
                        .count();
                    seen.insert(format!("{}#{n}", m.channel.topic));
                    !seen.contains(&format!("{}#2", m.channel.topic))
                })
                .map(|m| {
                    let schema = m.channel.schema.as_ref().unwrap().name.clone();
                    (schema, m.data.into_owned())
                })
                .collect()
        })
    }

    /// Decodes with the decoder for `schema`; `Ok(())` or the error.
    fn decode(schema: &str, data: &[u8]) -> CdrResult<()> {
        match schema {
            POINTCLOUD2 => decode_pointcloud2(data).map(drop),
            TFMESSAGE => decode_tf(data).map(drop),
            ODOMETRY => decode_odometry(data).map(drop),
            NAVSATFIX => decode_navsatfix(data).map(drop),
            other => panic!("unexpected schema {other}"),
        }
    }

    #[test]
    fn every_fixture_message_decodes() {
        let messages = fixture_messages();
        assert!(messages.len() >= 5, "{}", messages.len());
        for (schema, data) in messages {
            decode(schema, data).unwrap();
        }
    }

    #[test]
    fn truncations_are_errors() {
        for (schema, data) in fixture_messages() {
            let step = (data.len() / 300).max(1);
            for keep in (0..data.len()).step_by(step) {
                let cut = &data[..keep];
                // Odometry's twist and NavSatFix's covariance are not read: cuts there pass.
                let used = match schema.as_str() {
                    ODOMETRY => data.len() - (8 * 36 + 8 * 6 + 8 * 36),
                    NAVSATFIX => data.len() - (8 * 9 + 1),
                    POINTCLOUD2 => data.len() - 1,
                    _ => data.len(),
                };
                let result = decode(schema, cut);
                if keep < used {
                    assert!(result.is_err(), "{schema} cut at {keep} of {}", data.len());
                }
            }
        }
    }

    #[test]
    fn huge_counts_and_steps_are_errors_or_harmless() {
        for (schema, data) in fixture_messages() {
            for at in (0..data.len().saturating_sub(4).min(160)).step_by(4) {
                for v in [u32::MAX, 0x8000_0000, 0x7fff_ffff, 65_536, 3, 0] {
                    let mut d = data.clone();
                    d[at..at + 4].copy_from_slice(&v.to_le_bytes());
                    let _ = decode(schema, &d);
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        #[test]
        fn random_edits_never_panic(
            which in 0usize..64,
            edits in proptest::collection::vec((0usize..4096, any::<u8>()), 1..8),
            cut in proptest::option::of(0usize..70_000),
        ) {
            let messages = fixture_messages();
            let (schema, data) = &messages[which % messages.len()];
            let mut d = data.clone();
            for (at, byte) in edits {
                if let Some(slot) = d.get_mut(at) {
                    *slot = byte;
                }
            }
            if let Some(cut) = cut {
                d.truncate(cut);
            }
            let _ = decode(schema, &d);
        }
    }
}
