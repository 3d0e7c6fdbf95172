//! JSON Schemas of the `foxglove.*` messages the recording uses, for channels encoded as JSON.
//!
//! Foxglove recognises a channel by its schema *name* (`foxglove.Grid`, …) and decodes its
//! messages as JSON when the schema encoding is `jsonschema`: timestamps are `{sec, nsec}`,
//! byte arrays base64 strings (`contentEncoding: base64`), enums their integer values. The
//! schemas below state exactly the fields this crate writes, after the published
//! `foxglove.*` message definitions, so that any JSON Schema validator can check a message.

use serde_json::{Value, json};

/// Schema encoding of every channel of the recording.
pub const SCHEMA_ENCODING: &str = "jsonschema";
/// Message encoding of every channel of the recording.
pub const MESSAGE_ENCODING: &str = "json";

fn object(title: &str, properties: Value) -> Value {
    let required: Vec<String> = properties
        .as_object()
        .map(|p| p.keys().cloned().collect())
        .unwrap_or_default();
    json!({
        "title": title,
        "type": "object",
        "properties": properties,
        "required": required,
    })
}

fn time() -> Value {
    object(
        "time",
        json!({
            "sec": {"type": "integer", "minimum": 0},
            "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999},
        }),
    )
}

fn vector3() -> Value {
    object(
        "foxglove.Vector3",
        json!({"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}),
    )
}

fn vector2() -> Value {
    object(
        "foxglove.Vector2",
        json!({"x": {"type": "number"}, "y": {"type": "number"}}),
    )
}

fn quaternion() -> Value {
    object(
        "foxglove.Quaternion",
        json!({
            "x": {"type": "number"}, "y": {"type": "number"},
            "z": {"type": "number"}, "w": {"type": "number"},
        }),
    )
}

fn pose() -> Value {
    object(
        "foxglove.Pose",
        json!({"position": vector3(), "orientation": quaternion()}),
    )
}

fn color() -> Value {
    object(
        "foxglove.Color",
        json!({
            "r": {"type": "number"}, "g": {"type": "number"},
            "b": {"type": "number"}, "a": {"type": "number"},
        }),
    )
}

/// `foxglove.PackedElementField`; `type` is `foxglove.NumericType` (1 UINT8, 2 INT8, 7 FLOAT32).
fn packed_fields() -> Value {
    json!({
        "type": "array",
        "items": object(
            "foxglove.PackedElementField",
            json!({
                "name": {"type": "string"},
                "offset": {"type": "integer", "minimum": 0},
                "type": {"type": "integer", "minimum": 0, "maximum": 8},
            }),
        ),
    })
}

fn bytes() -> Value {
    json!({"type": "string", "contentEncoding": "base64"})
}

fn with_schema_keyword(mut schema: Value) -> Value {
    if let Some(map) = schema.as_object_mut() {
        map.insert(
            "$schema".to_string(),
            json!("https://json-schema.org/draft/2020-12/schema"),
        );
    }
    schema
}

/// `foxglove.Grid`.
pub fn grid() -> Value {
    with_schema_keyword(object(
        "foxglove.Grid",
        json!({
            "timestamp": time(),
            "frame_id": {"type": "string"},
            "pose": pose(),
            "column_count": {"type": "integer", "minimum": 0},
            "cell_size": vector2(),
            "row_stride": {"type": "integer", "minimum": 0},
            "cell_stride": {"type": "integer", "minimum": 0},
            "fields": packed_fields(),
            "data": bytes(),
        }),
    ))
}

/// `foxglove.PointCloud`.
pub fn point_cloud() -> Value {
    with_schema_keyword(object(
        "foxglove.PointCloud",
        json!({
            "timestamp": time(),
            "frame_id": {"type": "string"},
            "pose": pose(),
            "point_stride": {"type": "integer", "minimum": 0},
            "fields": packed_fields(),
            "data": bytes(),
        }),
    ))
}

/// `foxglove.FrameTransform`.
pub fn frame_transform() -> Value {
    with_schema_keyword(object(
        "foxglove.FrameTransform",
        json!({
            "timestamp": time(),
            "parent_frame_id": {"type": "string"},
            "child_frame_id": {"type": "string"},
            "translation": vector3(),
            "rotation": quaternion(),
        }),
    ))
}

/// `foxglove.LocationFix`; `position_covariance_type` 0 is UNKNOWN.
pub fn location_fix() -> Value {
    with_schema_keyword(object(
        "foxglove.LocationFix",
        json!({
            "timestamp": time(),
            "frame_id": {"type": "string"},
            "latitude": {"type": "number"},
            "longitude": {"type": "number"},
            "altitude": {"type": "number"},
            "position_covariance": {
                "type": "array", "items": {"type": "number"}, "minItems": 9, "maxItems": 9,
            },
            "position_covariance_type": {"type": "integer", "minimum": 0, "maximum": 3},
        }),
    ))
}

/// `foxglove.SceneUpdate` with line primitives only (`type` 0 LINE_STRIP, 1 LINE_LOOP,
/// 2 LINE_LIST); the other primitive arrays are written empty.
pub fn scene_update() -> Value {
    let empty_array = json!({"type": "array", "maxItems": 0});
    let line = object(
        "foxglove.LinePrimitive",
        json!({
            "type": {"type": "integer", "minimum": 0, "maximum": 2},
            "pose": pose(),
            "thickness": {"type": "number"},
            "scale_invariant": {"type": "boolean"},
            "points": {"type": "array", "items": vector3()},
            "color": color(),
            "colors": empty_array,
            "indices": empty_array,
        }),
    );
    let entity = object(
        "foxglove.SceneEntity",
        json!({
            "timestamp": time(),
            "frame_id": {"type": "string"},
            "id": {"type": "string"},
            "lifetime": {
                "title": "duration", "type": "object",
                "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}},
                "required": ["sec", "nsec"],
            },
            "frame_locked": {"type": "boolean"},
            "metadata": empty_array,
            "arrows": empty_array,
            "cubes": empty_array,
            "spheres": empty_array,
            "cylinders": empty_array,
            "lines": {"type": "array", "items": line},
            "triangles": empty_array,
            "texts": empty_array,
            "models": empty_array,
        }),
    );
    with_schema_keyword(object(
        "foxglove.SceneUpdate",
        json!({
            "deletions": empty_array,
            "entities": {"type": "array", "items": entity},
        }),
    ))
}
