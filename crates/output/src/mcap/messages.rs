//! The JSON messages of the recording: `foxglove.*` values built from evigrid's grids, poses,
//! fixes and map, with the two encodings JSON needs for them (base64 bytes, `{sec, nsec}`
//! times). The scan is protobuf ([`super::protobuf`]).

use evigrid::nalgebra::UnitQuaternion;
use evigrid::{IsometryMatrix3, Label, PerceptionGrid, Window, betp_cells};
use serde_json::{Value, json};

use crate::georef::gis_colour;

/// `foxglove.NumericType` codes used here.
pub(crate) const UINT8: u8 = 1;
pub(crate) const INT8: u8 = 2;
pub(crate) const FLOAT32: u8 = 7;

/// The cell fields of the decision grid, in byte order: the decided class ([`Label`] code,
/// 0 unknown … 5 M), the ROS occupancy (−1, 0, 100), betP of F, I, U, S, M scaled to 0–255
/// (`round(255·betP)`), then the class's colour as `red`, `green`, `blue`, `alpha` (the one
/// palette of every output, [`gis_colour`]: Foxglove's 3D panel draws them with its
/// "RGBA (separate fields)" colour mode, `docs/foxglove-layout.json`).
pub const GRID_FIELDS: [(&str, u8); 11] = [
    ("class", UINT8),
    ("occupancy", INT8),
    ("betp_F", UINT8),
    ("betp_I", UINT8),
    ("betp_U", UINT8),
    ("betp_S", UINT8),
    ("betp_M", UINT8),
    ("red", UINT8),
    ("green", UINT8),
    ("blue", UINT8),
    ("alpha", UINT8),
];

const BASE64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Standard base64 with padding (RFC 4648 §4), as JSON carries `bytes` fields.
pub fn base64(bytes: &[u8]) -> String {
    let mut out = Vec::with_capacity(bytes.len().div_ceil(3) * 4);
    let symbol = |n: u32, shift: u32| BASE64[((n >> shift) & 63) as usize];
    // Whole groups of three bytes, four symbols at a time: a grid's 1.1 MB is encoded at 2 Hz.
    let mut groups = bytes.chunks_exact(3);
    for group in &mut groups {
        let n = (u32::from(group[0]) << 16) | (u32::from(group[1]) << 8) | u32::from(group[2]);
        out.extend_from_slice(&[symbol(n, 18), symbol(n, 12), symbol(n, 6), symbol(n, 0)]);
    }
    match *groups.remainder() {
        [a] => {
            let n = u32::from(a) << 16;
            out.extend_from_slice(&[symbol(n, 18), symbol(n, 12), b'=', b'=']);
        }
        [a, b] => {
            let n = (u32::from(a) << 16) | (u32::from(b) << 8);
            out.extend_from_slice(&[symbol(n, 18), symbol(n, 12), symbol(n, 6), b'=']);
        }
        _ => {}
    }
    // Every byte is one of the 65 ASCII symbols above, so this cannot fail.
    String::from_utf8(out).unwrap_or_default()
}

/// A time in nanoseconds since the epoch, from seconds; `None` if negative, not finite or from
/// 1.8·10¹⁰ s on (the year 2540: u64 nanoseconds end in 2554).
pub fn nanoseconds(time_s: f64) -> Option<u64> {
    // Split first: at 1.3·10⁹ s an f64 of nanoseconds is only good to 256 ns.
    let sec = time_s.floor();
    if !(0.0..1.8e10).contains(&sec) {
        return None;
    }
    let nsec = ((time_s - sec) * 1e9).round() as u64;
    (sec as u64).checked_mul(1_000_000_000)?.checked_add(nsec)
}

/// `{sec, nsec}` of a time in nanoseconds.
pub(crate) fn stamp(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

/// A message with one `bytes` field kept out of its JSON value: the field's base64 holds nothing
/// JSON escapes, so [`WithBytes::to_json`] appends it to the serialised object as it is, instead
/// of the serialiser scanning megabytes of it character by character.
pub(crate) struct WithBytes {
    /// The message without the field (a JSON object).
    pub value: Value,
    /// The field's name.
    pub field: &'static str,
    /// The field's bytes, base64.
    pub base64: String,
}

impl WithBytes {
    /// The message as JSON text, the bytes field last.
    pub(crate) fn to_json(&self) -> String {
        let mut text = self.value.to_string();
        // An object's text ends with its closing brace; `{}` alone takes no comma.
        let closing = text.pop();
        debug_assert_eq!(closing, Some('}'));
        text.reserve(self.field.len() + self.base64.len() + 8);
        if text.len() > 1 {
            text.push(',');
        }
        text.push('"');
        text.push_str(self.field);
        text.push_str("\":\"");
        text.push_str(&self.base64);
        text.push_str("\"}");
        text
    }
}

fn identity_pose(x: f64, y: f64, z: f64) -> Value {
    json!({
        "position": {"x": x, "y": y, "z": z},
        "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
    })
}

/// The ROS occupancy of a decision: 0 free, 100 occupied, −1 unknown.
pub fn occupancy(label: Label) -> i8 {
    match label {
        Label::Unknown => -1,
        Label::F => 0,
        // Edge is truth only (a building's boundary band): static and occupied in part.
        Label::I | Label::U | Label::S | Label::M | Label::O | Label::Edge => 100,
    }
}

/// The decision grid after a frame as a `foxglove.Grid` in `frame_id`, cells in
/// [`GRID_FIELDS`] layout, row-major from the south-west cell (as `nav_msgs/OccupancyGrid`),
/// in the plane z = `ground_z_m`. `decisions` and `grid` have the window's size (checked by the
/// caller).
pub(crate) fn grid(
    ns: u64,
    frame_id: &str,
    window: &Window,
    decisions: &[Label],
    grid: &PerceptionGrid,
    ground_z_m: f64,
) -> WithBytes {
    let s = window.cell_size_m();
    let stride = GRID_FIELDS.len();
    let mut data = Vec::with_capacity(stride * window.len());
    // betP a span at a time, plane by plane: gathering each cell's 32 masses was most of the
    // recording's cost.
    let mut probabilities: [Vec<f32>; 5] = Default::default();
    for span in window.world_order_spans() {
        betp_cells(grid, span.clone(), &mut probabilities);
        for (i, idx) in span.enumerate() {
            let label = decisions[idx];
            data.push(label as u8);
            data.push(occupancy(label).to_le_bytes()[0]);
            for pk in &probabilities {
                data.push(unit_to_byte(pk[i]));
            }
            data.extend_from_slice(&gis_colour(label));
        }
    }
    let fields: Vec<Value> = GRID_FIELDS
        .iter()
        .enumerate()
        .map(|(offset, (name, kind))| json!({"name": name, "offset": offset, "type": kind}))
        .collect();
    WithBytes {
        value: json!({
            "timestamp": stamp(ns),
            "frame_id": frame_id,
            "pose": identity_pose(
                window.first_col() as f64 * s,
                window.first_row() as f64 * s,
                ground_z_m,
            ),
            "column_count": window.width(),
            "cell_size": {"x": s, "y": s},
            "row_stride": stride * window.width(),
            "cell_stride": stride,
            "fields": fields,
        }),
        field: "data",
        base64: base64(&data),
    }
}

/// `round(255·p)` of `p` clamped to [0, 1], half away from zero, as `f32::round` gives it, for
/// NaN 0; without the call to `roundf` that the baseline x86-64 target makes of `round` (five a
/// cell of the grid, a sixth of the grid message's cost, `docs/benchmarks.md`).
fn unit_to_byte(p: f32) -> u8 {
    let scaled = 255.0 * p.clamp(0.0, 1.0);
    // `as` truncates (NaN to 0); the fraction of a float in [0, 255] is exact, so comparing it
    // with one half rounds as `round` does.
    let whole = scaled as u8;
    whole + u8::from(scaled - f32::from(whole) >= 0.5)
}

/// The pose of `child` in `parent` as a `foxglove.FrameTransform`.
pub(crate) fn frame_transform(ns: u64, parent: &str, child: &str, pose: &IsometryMatrix3) -> Value {
    let [x, y, z]: [f64; 3] = pose.translation.vector.into();
    let q = UnitQuaternion::from_rotation_matrix(&pose.rotation);
    let [qx, qy, qz, qw] = [q.i, q.j, q.k, q.w];
    json!({
        "timestamp": stamp(ns),
        "parent_frame_id": parent,
        "child_frame_id": child,
        "translation": {"x": x, "y": y, "z": z},
        "rotation": {"x": qx, "y": qy, "z": qz, "w": qw},
    })
}

/// A GNSS fix as a `foxglove.LocationFix` (covariance unknown; no heading or velocity: the
/// fix carries none), drawn in the ego path's colour.
pub(crate) fn location_fix(ns: u64, frame_id: &str, fix: &super::GnssFix) -> Value {
    let [r, g, b] = crate::figure::PATH.0.map(|c| f64::from(c) / 255.0);
    json!({
        "timestamp": stamp(ns),
        "frame_id": frame_id,
        "latitude": fix.lat_deg,
        "longitude": fix.lon_deg,
        "altitude": fix.alt_m,
        "position_covariance": ([0.0f64; 9]),
        "position_covariance_type": 0,
        "color": {"r": r, "g": g, "b": b, "a": 1.0},
        "metadata": [],
    })
}

/// One `foxglove.SceneEntity` of closed outlines (LINE_LOOP), in `frame_id`, forever.
pub(crate) fn outline_entity(
    ns: u64,
    frame_id: &str,
    id: &str,
    outlines: &[Vec<[f64; 2]>],
    rgba: [f64; 4],
) -> Value {
    let lines: Vec<Value> = outlines
        .iter()
        .map(|ring| {
            let points: Vec<Value> = ring
                .iter()
                .map(|[x, y]| json!({"x": x, "y": y, "z": 0.0}))
                .collect();
            json!({
                "type": 1,
                "pose": identity_pose(0.0, 0.0, 0.0),
                "thickness": 2.0,
                "scale_invariant": true,
                "points": points,
                "color": {"r": rgba[0], "g": rgba[1], "b": rgba[2], "a": rgba[3]},
                "colors": [],
                "indices": [],
            })
        })
        .collect();
    json!({
        "timestamp": stamp(ns),
        "frame_id": frame_id,
        "id": id,
        "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": false,
        "metadata": [],
        "arrows": [],
        "cubes": [],
        "spheres": [],
        "cylinders": [],
        "lines": lines,
        "triangles": [],
        "texts": [],
        "models": [],
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn a_probability_becomes_the_byte_round_gives() {
        // 255 · 0.5 = 127.5, half away from zero: 128; 255 · 0.2 = 51.000004: 51; clamped ends.
        assert_eq!(unit_to_byte(0.5), 128);
        assert_eq!(unit_to_byte(0.2), 51);
        assert_eq!(unit_to_byte(-0.1), 0);
        assert_eq!(unit_to_byte(1.5), 255);
        assert_eq!(unit_to_byte(f32::NAN), 0);
        // Against `round` itself: every 97th float from 0 to 1 (bit patterns, so the small
        // values are dense), and the floats around each half step (k + 0.5) / 255.
        let reference = |p: f32| (255.0 * p.clamp(0.0, 1.0)).round() as u8;
        let mut bits = 0u32;
        while bits <= 1.0f32.to_bits() {
            let p = f32::from_bits(bits);
            assert_eq!(unit_to_byte(p), reference(p), "{p:e}");
            bits += 97;
        }
        for k in 0..255u16 {
            let half = (f32::from(k) + 0.5) / 255.0;
            for p in [half.next_down(), half, half.next_up()] {
                assert_eq!(unit_to_byte(p), reference(p), "{p:e}");
            }
        }
    }

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        // RFC 4648 §10.
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(plain.as_bytes()), coded);
        }
    }

    #[test]
    fn bytes_are_appended_as_a_json_field() {
        let message = WithBytes {
            value: json!({"frame_id": "map", "fields": [{"name": "x"}]}),
            field: "data",
            base64: base64(b"foob"),
        };
        let parsed: Value = serde_json::from_str(&message.to_json()).unwrap();
        assert_eq!(
            parsed,
            json!({"frame_id": "map", "fields": [{"name": "x"}], "data": "Zm9vYg=="})
        );
        let alone = WithBytes {
            value: json!({}),
            field: "data",
            base64: String::new(),
        };
        assert_eq!(alone.to_json(), r#"{"data":""}"#);
    }

    #[test]
    fn a_transform_carries_the_translation_and_the_rotation_as_a_quaternion() {
        use evigrid::PoseExt;
        let yaw = 0.7_f64;
        let pose = IsometryMatrix3::from_xyz_rpy(1.0, 2.0, 3.0, 0.0, 0.0, yaw);
        let tf = frame_transform(5, "map", "velodyne", &pose);
        assert_eq!(tf["translation"], json!({"x": 1.0, "y": 2.0, "z": 3.0}));
        let r = &tf["rotation"];
        let q = ["x", "y", "z", "w"].map(|k| r[k].as_f64().unwrap());
        let expected = [0.0, 0.0, (yaw / 2.0).sin(), (yaw / 2.0).cos()];
        for (a, b) in q.iter().zip(expected) {
            assert!((a - b).abs() < 1e-12, "{q:?}");
        }
        // Half turn about x: trace −1, where dividing by w ≈ 0 would fail.
        let pose = IsometryMatrix3::from_xyz_rpy(0.0, 0.0, 0.0, std::f64::consts::PI, 0.0, 0.0);
        let r = &frame_transform(5, "map", "velodyne", &pose)["rotation"];
        let q = ["x", "y", "z", "w"].map(|k| r[k].as_f64().unwrap());
        assert!(
            (q[0].abs() - 1.0).abs() < 1e-12 && q[3].abs() < 1e-12,
            "{q:?}"
        );
    }

    #[test]
    fn times_are_split_into_seconds_and_nanoseconds() {
        let ns = nanoseconds(1_317_380_000.25).unwrap();
        assert_eq!(
            stamp(ns),
            json!({"sec": 1_317_380_000u64, "nsec": 250_000_000u64})
        );
        assert_eq!(nanoseconds(-1.0), None);
        assert_eq!(nanoseconds(f64::NAN), None);
    }
}
