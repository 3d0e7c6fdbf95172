//! The scan as a protobuf `foxglove.PointCloud`, with the few pieces of the protobuf wire
//! encoding it needs (varint keys and integers, fixed32, doubles, length-delimited strings,
//! messages and bytes).
//!
//! Why protobuf for the scan alone: as JSON its `data` is base64 text, a third larger than the
//! points and slow to compress (issue 29); protobuf carries the bytes as they are. Field numbers
//! and types are those of Foxglove's `.proto` files (`foxglove/PointCloud.proto` and the
//! messages it nests), whose descriptor set the channel carries ([`super::schemas`]); a test
//! reads them back from that descriptor set. Fields at their default (0, empty) are left out,
//! as every protobuf encoder does for proto3.
//!
//! # References
//!
//! Protocol Buffers, "Encoding" (protobuf.dev/programming-guides/encoding).

use super::messages::FLOAT32;

/// Wire type of varint fields (`int64`, `int32`, enums).
const VARINT: u8 = 0;
/// Wire type of `double`, `fixed64`.
const I64: u8 = 1;
/// Wire type of length-delimited fields (strings, bytes, messages).
const LEN: u8 = 2;
/// Wire type of `fixed32`, `float`.
const I32: u8 = 5;

/// Field numbers of `foxglove.PointCloud`.
mod point_cloud {
    pub const TIMESTAMP: u32 = 1;
    pub const FRAME_ID: u32 = 2;
    pub const POSE: u32 = 3;
    /// `fixed32`.
    pub const POINT_STRIDE: u32 = 4;
    pub const FIELDS: u32 = 5;
    pub const DATA: u32 = 6;
}

/// Field numbers of `foxglove.PackedElementField`.
mod packed_element_field {
    pub const NAME: u32 = 1;
    /// `fixed32`.
    pub const OFFSET: u32 = 2;
    /// The `NumericType` enum.
    pub const TYPE: u32 = 3;
}

/// Field numbers of `google.protobuf.Timestamp` (`int64 seconds`, `int32 nanos`).
mod timestamp {
    pub const SECONDS: u32 = 1;
    pub const NANOS: u32 = 2;
}

/// Field numbers of `foxglove.Pose` and of the `foxglove.Quaternion` in it.
mod pose {
    pub const ORIENTATION: u32 = 2;
    /// `Quaternion.w`, a `double`.
    pub const W: u32 = 4;
}

/// Appends `value` as a base-128 varint, low group first.
fn varint(out: &mut Vec<u8>, mut value: u64) {
    while value >= 0x80 {
        out.push((value as u8 & 0x7f) | 0x80);
        value >>= 7;
    }
    out.push(value as u8);
}

/// Appends a field's key: its number and wire type.
fn key(out: &mut Vec<u8>, field: u32, wire_type: u8) {
    varint(out, (u64::from(field) << 3) | u64::from(wire_type));
}

/// Appends a varint field unless it is 0.
fn uint(out: &mut Vec<u8>, field: u32, value: u64) {
    if value != 0 {
        key(out, field, VARINT);
        varint(out, value);
    }
}

/// Appends a `fixed32` field unless it is 0.
fn fixed32(out: &mut Vec<u8>, field: u32, value: u32) {
    if value != 0 {
        key(out, field, I32);
        out.extend_from_slice(&value.to_le_bytes());
    }
}

/// Appends a `double` field unless it is +0.
fn double(out: &mut Vec<u8>, field: u32, value: f64) {
    if value.to_bits() != 0 {
        key(out, field, I64);
        out.extend_from_slice(&value.to_le_bytes());
    }
}

/// Appends the key and length of a length-delimited field whose `len` bytes follow.
fn len_prefix(out: &mut Vec<u8>, field: u32, len: usize) {
    key(out, field, LEN);
    varint(out, len as u64);
}

/// Appends a string field unless it is empty.
fn string(out: &mut Vec<u8>, field: u32, text: &str) {
    if !text.is_empty() {
        len_prefix(out, field, text.len());
        out.extend_from_slice(text.as_bytes());
    }
}

/// Appends a message field (always: a message field is present even when empty) encoded by
/// `fill`.
fn message(out: &mut Vec<u8>, field: u32, fill: impl FnOnce(&mut Vec<u8>)) {
    let mut inner = Vec::new();
    fill(&mut inner);
    len_prefix(out, field, inner.len());
    out.extend_from_slice(&inner);
}

/// A scan as a `foxglove.PointCloud` of `x, y, z` FLOAT32 little-endian in `frame_id` at
/// `ns`, and `intensity` (FLOAT32) after them when the scan has one per point, into `out`
/// (cleared first, so a caller can keep one buffer for every frame); the pose is the identity.
/// Non-finite points are left out (a viewer would place them at infinity).
pub(crate) fn point_cloud(
    out: &mut Vec<u8>,
    ns: u64,
    frame_id: &str,
    points: &[[f32; 3]],
    intensity: &[f32],
) {
    let with_intensity = !points.is_empty() && intensity.len() == points.len();
    let stride: u32 = if with_intensity { 16 } else { 12 };
    let finite = points
        .iter()
        .filter(|p| p.iter().all(|c| c.is_finite()))
        .count();
    out.clear();
    out.reserve(finite * stride as usize + 128);
    message(out, point_cloud::TIMESTAMP, |t| {
        uint(t, timestamp::SECONDS, ns / 1_000_000_000);
        uint(t, timestamp::NANOS, ns % 1_000_000_000);
    });
    string(out, point_cloud::FRAME_ID, frame_id);
    // The identity: position (0, 0, 0) is the default, left out; orientation w = 1.
    message(out, point_cloud::POSE, |p| {
        message(p, pose::ORIENTATION, |q| double(q, pose::W, 1.0));
    });
    fixed32(out, point_cloud::POINT_STRIDE, stride);
    let names: &[&str] = if with_intensity {
        &["x", "y", "z", "intensity"]
    } else {
        &["x", "y", "z"]
    };
    for (k, name) in (0u32..).zip(names) {
        message(out, point_cloud::FIELDS, |f| {
            string(f, packed_element_field::NAME, name);
            fixed32(f, packed_element_field::OFFSET, 4 * k);
            uint(f, packed_element_field::TYPE, u64::from(FLOAT32));
        });
    }
    // The points straight into the message, after the length counted above (no point: no
    // field, as an empty `bytes` is the default), each written whole into its slot: four
    // `extend_from_slice` a point, each checking the capacity, were most of the message's cost.
    if finite > 0 {
        len_prefix(out, point_cloud::DATA, finite * stride as usize);
    }
    let start = out.len();
    out.resize(start + finite * stride as usize, 0);
    let slots = out[start..].chunks_exact_mut(stride as usize);
    let xyz = |slot: &mut [u8], p: &[f32; 3]| {
        slot[0..4].copy_from_slice(&p[0].to_le_bytes());
        slot[4..8].copy_from_slice(&p[1].to_le_bytes());
        slot[8..12].copy_from_slice(&p[2].to_le_bytes());
    };
    match (finite == points.len(), with_intensity) {
        // Every point finite (a KITTI scan): no test per point.
        (true, true) => {
            for ((p, i), slot) in points.iter().zip(intensity).zip(slots) {
                xyz(slot, p);
                slot[12..16].copy_from_slice(&i.to_le_bytes());
            }
        }
        (true, false) => {
            for (p, slot) in points.iter().zip(slots) {
                xyz(slot, p);
            }
        }
        (false, _) => {
            let finite_points = points
                .iter()
                .enumerate()
                .filter(|(_, p)| p.iter().all(|c| c.is_finite()));
            for ((k, p), slot) in finite_points.zip(slots) {
                xyz(slot, p);
                if with_intensity {
                    slot[12..16].copy_from_slice(&intensity[k].to_le_bytes());
                }
            }
        }
    }
}

/// A protobuf message decoded one level deep, for the tests: each field's number and value.
#[cfg(test)]
#[allow(clippy::unwrap_used)]
pub(crate) mod decode {
    /// A field's value by wire type.
    #[derive(Clone, Debug, PartialEq)]
    pub(crate) enum Value<'a> {
        Varint(u64),
        I64([u8; 8]),
        Len(&'a [u8]),
        I32([u8; 4]),
    }

    fn varint(bytes: &[u8], at: &mut usize) -> u64 {
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = bytes[*at];
            *at += 1;
            value |= u64::from(byte & 0x7f) << shift;
            if byte < 0x80 {
                return value;
            }
        }
        panic!("varint longer than 10 bytes");
    }

    /// The fields of `bytes` in order (panics on malformed input: tests only).
    pub(crate) fn fields(bytes: &[u8]) -> Vec<(u32, Value<'_>)> {
        let mut at = 0;
        let mut out = Vec::new();
        while at < bytes.len() {
            let key = varint(bytes, &mut at);
            let field = u32::try_from(key >> 3).unwrap();
            let value = match key & 7 {
                0 => Value::Varint(varint(bytes, &mut at)),
                1 => {
                    at += 8;
                    Value::I64(bytes[at - 8..at].try_into().unwrap())
                }
                2 => {
                    let len = usize::try_from(varint(bytes, &mut at)).unwrap();
                    at += len;
                    Value::Len(&bytes[at - len..at])
                }
                5 => {
                    at += 4;
                    Value::I32(bytes[at - 4..at].try_into().unwrap())
                }
                other => panic!("wire type {other}"),
            };
            out.push((field, value));
        }
        out
    }

    /// The values of field `number`, in order.
    pub(crate) fn all<'a>(fields: &[(u32, Value<'a>)], number: u32) -> Vec<Value<'a>> {
        fields
            .iter()
            .filter(|(n, _)| *n == number)
            .map(|(_, v)| v.clone())
            .collect()
    }

    /// The bytes of length-delimited field `number` (its last occurrence), or empty.
    pub(crate) fn len<'a>(fields: &[(u32, Value<'a>)], number: u32) -> &'a [u8] {
        match all(fields, number).pop() {
            Some(Value::Len(bytes)) => bytes,
            _ => &[],
        }
    }

    /// The varint field `number` (its last occurrence), or 0.
    pub(crate) fn uint(fields: &[(u32, Value<'_>)], number: u32) -> u64 {
        match all(fields, number).pop() {
            Some(Value::Varint(v)) => v,
            _ => 0,
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// The `data` bytes and the point stride of a point cloud of `points` and `intensity`.
    fn data_of(points: &[[f32; 3]], intensity: &[f32]) -> (Vec<u8>, u32) {
        let mut out = Vec::new();
        point_cloud(&mut out, 5, "sensor", points, intensity);
        let fields = decode::fields(&out);
        let stride = match decode::all(&fields, 4)[..] {
            [decode::Value::I32(bytes)] => u32::from_le_bytes(bytes),
            ref other => panic!("{other:?}"),
        };
        (decode::len(&fields, 6).to_vec(), stride)
    }

    /// Little-endian bytes of the floats.
    fn le(values: &[f32]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    #[test]
    fn points_are_written_whole_with_or_without_intensity_and_non_finite_ones_left_out() {
        let points = [[1.0, -2.0, 3.5], [0.25, 1e-3, -7.0]];
        // All finite, with intensity: x, y, z, intensity a point, 16 bytes.
        let (data, s) = data_of(&points, &[0.5, 0.75]);
        assert_eq!(data, le(&[1.0, -2.0, 3.5, 0.5, 0.25, 1e-3, -7.0, 0.75]));
        assert_eq!(s, 16);
        // All finite, no intensity: 12 bytes a point.
        let (data, s) = data_of(&points, &[]);
        assert_eq!(data, le(&[1.0, -2.0, 3.5, 0.25, 1e-3, -7.0]));
        assert_eq!(s, 12);
        // An infinite point between them is left out with its intensity.
        let with_gap = [points[0], [f32::INFINITY, 0.0, 0.0], points[1]];
        let (data, _) = data_of(&with_gap, &[0.5, 0.6, 0.75]);
        assert_eq!(data, le(&[1.0, -2.0, 3.5, 0.5, 0.25, 1e-3, -7.0, 0.75]));
        let (data, _) = data_of(&with_gap, &[]);
        assert_eq!(data, le(&[1.0, -2.0, 3.5, 0.25, 1e-3, -7.0]));
    }

    #[test]
    fn varints_are_base_128_low_group_first() {
        // protobuf.dev's example: 150 is 96 01.
        for (value, bytes) in [
            (0u64, &[0x00][..]),
            (1, &[0x01]),
            (127, &[0x7f]),
            (128, &[0x80, 0x01]),
            (150, &[0x96, 0x01]),
            (
                u64::MAX,
                &[0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x01],
            ),
        ] {
            let mut out = Vec::new();
            varint(&mut out, value);
            assert_eq!(out, bytes, "{value}");
        }
    }

    /// Every field of every message in the descriptor set: `("package.Message.field", (number,
    /// type, type name))`, types as `FieldDescriptorProto.Type` codes.
    fn described_fields() -> Vec<(String, (u32, u64, String))> {
        use decode::{all, fields, len, uint};
        let text = |bytes: &[u8]| String::from_utf8(bytes.to_vec()).unwrap();
        let mut out = Vec::new();
        // FileDescriptorSet.file = 1; FileDescriptorProto.package = 2, message_type = 4;
        // DescriptorProto.name = 1, field = 2; FieldDescriptorProto.name = 1, number = 3,
        // type = 5, type_name = 6.
        for file in all(&fields(super::super::schemas::POINT_CLOUD_DESCRIPTORS), 1) {
            let decode::Value::Len(file) = file else {
                panic!("file {file:?}")
            };
            let file = fields(file);
            let package = text(len(&file, 2));
            for message in all(&file, 4) {
                let decode::Value::Len(message) = message else {
                    panic!("message {message:?}")
                };
                let message = fields(message);
                let name = text(len(&message, 1));
                for field in all(&message, 2) {
                    let decode::Value::Len(field) = field else {
                        panic!("field {field:?}")
                    };
                    let field = fields(field);
                    out.push((
                        format!("{package}.{name}.{}", text(len(&field, 1))),
                        (
                            u32::try_from(uint(&field, 3)).unwrap(),
                            uint(&field, 5),
                            text(len(&field, 6)),
                        ),
                    ));
                }
            }
        }
        out
    }

    #[test]
    fn field_numbers_and_types_are_those_of_the_descriptor_set() {
        // FieldDescriptorProto.Type codes.
        let (double, int64, int32, fixed32, string, message, bytes, enumeration) =
            (1, 3, 5, 7, 9, 11, 12, 14);
        let described = described_fields();
        let find = |name: &str| {
            described
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, field)| field.clone())
                .unwrap_or_else(|| panic!("{name} not in the descriptor set"))
        };
        let plain = |number: u32, kind: u64| (number, kind, String::new());
        let nested = |number: u32, name: &str| (number, message, name.to_string());
        assert_eq!(
            find("foxglove.PointCloud.timestamp"),
            nested(point_cloud::TIMESTAMP, ".google.protobuf.Timestamp")
        );
        assert_eq!(
            find("foxglove.PointCloud.frame_id"),
            plain(point_cloud::FRAME_ID, string)
        );
        assert_eq!(
            find("foxglove.PointCloud.pose"),
            nested(point_cloud::POSE, ".foxglove.Pose")
        );
        assert_eq!(
            find("foxglove.PointCloud.point_stride"),
            plain(point_cloud::POINT_STRIDE, fixed32)
        );
        assert_eq!(
            find("foxglove.PointCloud.fields"),
            nested(point_cloud::FIELDS, ".foxglove.PackedElementField")
        );
        assert_eq!(
            find("foxglove.PointCloud.data"),
            plain(point_cloud::DATA, bytes)
        );
        assert_eq!(
            find("foxglove.PackedElementField.name"),
            plain(packed_element_field::NAME, string)
        );
        assert_eq!(
            find("foxglove.PackedElementField.offset"),
            plain(packed_element_field::OFFSET, fixed32)
        );
        assert_eq!(
            find("foxglove.PackedElementField.type"),
            (
                packed_element_field::TYPE,
                enumeration,
                ".foxglove.PackedElementField.NumericType".to_string()
            )
        );
        assert_eq!(
            find("google.protobuf.Timestamp.seconds"),
            plain(timestamp::SECONDS, int64)
        );
        assert_eq!(
            find("google.protobuf.Timestamp.nanos"),
            plain(timestamp::NANOS, int32)
        );
        assert_eq!(
            find("foxglove.Pose.orientation"),
            nested(pose::ORIENTATION, ".foxglove.Quaternion")
        );
        assert_eq!(find("foxglove.Quaternion.w"), plain(pose::W, double));
        // PointCloud has no field this encoder does not know of.
        let cloud = described
            .iter()
            .filter(|(n, _)| n.starts_with("foxglove.PointCloud."))
            .count();
        assert_eq!(cloud, 6);
    }

    #[test]
    fn a_two_point_cloud_has_the_hand_computed_bytes() {
        // 100.25 s; a NaN point between the two is left out with its intensity.
        let mut out = vec![0xaa; 3]; // cleared first
        point_cloud(
            &mut out,
            100_250_000_000,
            "sensor",
            &[[1.0, 2.0, 3.0], [f32::NAN, 0.0, 0.0], [4.0, 5.0, 6.0]],
            &[0.25, 9.0, 0.75],
        );
        let mut expected: Vec<u8> = vec![
            // 1 timestamp, 7 bytes: seconds 100; nanos 250 000 000 = 0x0EE6B280, in 7-bit
            // groups from the lowest 0x00, 0x65, 0x1A, 0x77.
            0x0a, 0x07, 0x08, 0x64, 0x10, 0x80, 0xe5, 0x9a, 0x77, // 2 frame_id "sensor"
            0x12, 0x06, b's', b'e', b'n', b's', b'o', b'r',
            // 3 pose, 11 bytes: 2 orientation, 9 bytes: 4 w = 1.0 (double, key 0x21)
            0x1a, 0x0b, 0x12, 0x09, 0x21, 0, 0, 0, 0, 0, 0, 0xf0, 0x3f,
            // 4 point_stride fixed32 (key 0x25) 16
            0x25, 16, 0, 0, 0,
            // 5 fields: name, offset (fixed32, key 0x15; 0 left out), type FLOAT32 = 7
            0x2a, 0x05, 0x0a, 0x01, b'x', 0x18, 0x07, 0x2a, 0x0a, 0x0a, 0x01, b'y', 0x15, 4, 0, 0,
            0, 0x18, 0x07, 0x2a, 0x0a, 0x0a, 0x01, b'z', 0x15, 8, 0, 0, 0, 0x18, 0x07, 0x2a, 0x12,
            0x0a, 0x09, b'i', b'n', b't', b'e', b'n', b's', b'i', b't', b'y', 0x15, 12, 0, 0, 0,
            0x18, 0x07, // 6 data, 32 bytes
            0x32, 0x20,
        ];
        // 1, 2, 3, 0.25, 4, 5, 6, 0.75 as little-endian IEEE 754 singles.
        for bits in [
            0x3f80_0000u32,
            0x4000_0000,
            0x4040_0000,
            0x3e80_0000,
            0x4080_0000,
            0x40a0_0000,
            0x40c0_0000,
            0x3f40_0000,
        ] {
            expected.extend_from_slice(&bits.to_le_bytes());
        }
        assert_eq!(out, expected);
    }

    #[test]
    fn a_scan_without_intensity_has_three_fields_and_a_stride_of_12() {
        let mut out = Vec::new();
        point_cloud(&mut out, 0, "sensor", &[[1.0, 2.0, 3.0]], &[]);
        let fields = decode::fields(&out);
        // Time 0: an empty timestamp message, still present.
        assert_eq!(decode::len(&fields, point_cloud::TIMESTAMP), b"");
        assert_eq!(
            decode::all(&fields, point_cloud::POINT_STRIDE),
            [decode::Value::I32(12u32.to_le_bytes())]
        );
        assert_eq!(decode::all(&fields, point_cloud::FIELDS).len(), 3);
        assert_eq!(decode::len(&fields, point_cloud::DATA).len(), 12);
        // No point: no intensity even if given, and no data field (empty bytes are the
        // default); nor with no finite point.
        point_cloud(&mut out, 0, "sensor", &[], &[1.0]);
        let fields = decode::fields(&out);
        assert_eq!(decode::all(&fields, point_cloud::FIELDS).len(), 3);
        assert!(decode::all(&fields, point_cloud::DATA).is_empty());
        point_cloud(&mut out, 0, "sensor", &[[f32::INFINITY, 0.0, 0.0]], &[1.0]);
        assert!(decode::all(&decode::fields(&out), point_cloud::DATA).is_empty());
    }
}
