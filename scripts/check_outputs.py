#!/usr/bin/env python3
"""Checks evigrid's outputs with tools that are not evigrid's.

    check_outputs.py OUT --frames N --origin LAT,LON [--kitti-drive DIR] [--geojson FILE]
                     [--no-map]

OUT is an `evigrid run` or `evigrid demo` output folder of N frames whose local frame is the
transverse Mercator around ORIGIN. Read with the Python `mcap` reader, `jsonschema`, numpy,
Pillow, PyYAML, tifffile, foxglove-schemas-protobuf and (optionally) pyproj:

- run.mcap: channels, schema names and encodings (/scan protobuf, the others JSON), message
  counts, every first JSON message valid against its channel's JSON Schema and parsed into
  Foxglove's own protobuf type (foxglove-schemas-protobuf: no unknown field, every type right),
  every channel's schema holding every field of Foxglove's current definition (LocationFix's
  heading, velocity, colour; /scan's descriptor set field for field Foxglove's PointCloud), every
  /scan message decoded both by foxglove-schemas-protobuf's PointCloud and by the descriptor set
  the file carries, alike, with no unknown field and in protobuf's own encoding (re-encoded to
  the same bytes), its points the scan's (with --kitti-drive: the first frame's .bin, every
  value), times after 2000 on the scans' timeline (with --kitti-drive: equal to the drive's
  velodyne timestamps.txt), the scene right in 3-D (in each frame the grid at most 3 m under
  the sensor of /tf, the first at z = 0, the first scan's ground on it; with --kitti-drive the
  scan's intensity), and the last decision grid decoded equal to occupancy.json and
  classes.json, one colour per class;
- occupancy.json: exactly the fields of ROS 2 nav_msgs/OccupancyGrid, valid against
  docs/schemas/occupancy.schema.json; classes.json and masses.json against theirs;
- map.pgm + map.yaml: loaded with nav2 map_server's rules (written here) equal occupancy.json;
- decision-map.png + .pgw + .prj: corners equal the grid's extent, the .prj's origin is ORIGIN;
- decision-map.tif (tifffile): pixels, tie point, pixel scale and GeoKeys;
  with pyproj, the .prj turns local metres into WGS84 agreeing with the KITTI OXTS fixes or the
  demo map's GeoJSON vertices.

Exit 0 when every check passes, 1 on a failed check, 77 when a Python package is missing.
"""

import argparse
import base64
import json
import math
import re
import sys
from pathlib import Path

try:
    import importlib

    import foxglove_schemas_protobuf  # noqa: F401  (its modules are imported by name below)
    import numpy as np
    import tifffile
    import yaml
    from jsonschema import Draft202012Validator
    from mcap.reader import make_reader
    from google.protobuf import (
        descriptor_pb2,
        descriptor_pool,
        json_format,
        message_factory,
        unknown_fields,
    )
    from google.protobuf.message import DecodeError
    from PIL import Image
except ImportError as error:  # pragma: no cover - the skip path
    print(f"check_outputs: missing Python package: {error.name}", file=sys.stderr)
    sys.exit(77)

try:
    import pyproj
except ImportError:
    pyproj = None

REPO = Path(__file__).resolve().parent.parent
SCHEMAS = REPO / "docs" / "schemas"

CHANNELS = {
    "/evigrid/decision": "foxglove.Grid",
    "/tf": "foxglove.FrameTransform",
    "/scan": "foxglove.PointCloud",
    "/map": "foxglove.SceneUpdate",
    "/gnss": "foxglove.LocationFix",
}
# Channels encoded as protobuf (schema: a FileDescriptorSet); the others are JSON.
PROTOBUF_CHANNELS = {"/scan"}

failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print(f"FAIL {what}")
    return condition


def load_json(path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def validate(instance, schema, what):
    errors = sorted(Draft202012Validator(schema).iter_errors(instance), key=str)
    check(not errors, f"{what}: {errors[0].message if errors else ''}")


def keys(value):
    return sorted(value.keys())


# ---------------------------------------------------------------------------------------------
# nav_msgs/OccupancyGrid, field for field (ROS 2: builtin_interfaces/Time is sec, nanosec).


def check_occupancy(occ):
    check(keys(occ) == ["data", "header", "info"], f"OccupancyGrid fields {keys(occ)}")
    check(keys(occ["header"]) == ["frame_id", "stamp"], "std_msgs/Header fields")
    check(keys(occ["header"]["stamp"]) == ["nanosec", "sec"], "builtin_interfaces/Time fields")
    info = occ["info"]
    check(
        keys(info) == ["height", "map_load_time", "origin", "resolution", "width"],
        f"MapMetaData fields {keys(info)}",
    )
    check(keys(info["origin"]) == ["orientation", "position"], "geometry_msgs/Pose fields")
    check(keys(info["origin"]["position"]) == ["x", "y", "z"], "geometry_msgs/Point fields")
    check(
        keys(info["origin"]["orientation"]) == ["w", "x", "y", "z"],
        "geometry_msgs/Quaternion fields",
    )
    check(len(occ["data"]) == info["width"] * info["height"], "data has width × height cells")
    check(set(occ["data"]) <= {-1, 0, 100}, "occupancy values in {-1, 0, 100}")
    validate(occ, load_json(SCHEMAS / "occupancy.schema.json"), "occupancy.json schema")


# ---------------------------------------------------------------------------------------------
# nav2 map_server's loader (nav2_map_server/src/map_io.cpp, trinary mode), written from its
# documented rules: occ = (255 - v) / 255 (negate 0), occupied above occupied_thresh, free below
# free_thresh, unknown otherwise; the image's bottom-left pixel at `origin`.


def read_pgm(path):
    data = Path(path).read_bytes()
    fields, pos = [], 0
    while len(fields) < 4:
        while data[pos : pos + 1].isspace():
            pos += 1
        if data[pos : pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        end = pos
        while not data[end : end + 1].isspace():
            end += 1
        fields.append(data[pos:end])
        pos = end
    magic, width, height, maxval = fields[0], int(fields[1]), int(fields[2]), int(fields[3])
    if magic != b"P5" or maxval != 255:
        raise ValueError(f"{path}: not an 8-bit P5 PGM")
    pos += 1  # the single whitespace after maxval
    pixels = np.frombuffer(data[pos : pos + width * height], dtype=np.uint8)
    return pixels.reshape(height, width)


def nav2_load(yaml_path):
    meta = yaml.safe_load(Path(yaml_path).read_text())
    pixels = read_pgm(Path(yaml_path).parent / meta["image"])
    shade = pixels.astype(np.float64) / 255.0
    occ = shade if meta.get("negate", 0) else 1.0 - shade
    grid = np.full(pixels.shape, -1, dtype=np.int8)
    grid[occ > meta["occupied_thresh"]] = 100
    grid[occ < meta["free_thresh"]] = 0
    # Row 0 of the OccupancyGrid is the image's bottom row.
    return meta, grid[::-1].reshape(-1)


def check_nav2(out, occ):
    meta, data = nav2_load(out / "map.yaml")
    check(meta["mode"] == "trinary", "map.yaml mode trinary")
    check(meta["negate"] == 0, "map.yaml negate 0")
    check((meta["occupied_thresh"], meta["free_thresh"]) == (0.65, 0.25), "map.yaml thresholds")
    info = occ["info"]
    check(math.isclose(meta["resolution"], info["resolution"]), "map.yaml resolution")
    p = info["origin"]["position"]
    check(meta["origin"] == [p["x"], p["y"], 0.0], f"map.yaml origin {meta['origin']}")
    check(
        np.array_equal(data, np.array(occ["data"], dtype=np.int8)),
        "map.pgm under nav2's rules equals occupancy.json",
    )


# ---------------------------------------------------------------------------------------------
# World file + .prj.


def check_georeference(out, occ, classes, origin):
    info = occ["info"]
    a, d, b, e, c, f = [float(x) for x in (out / "decision-map.pgw").read_text().split()]
    s = info["resolution"]
    check((a, d, b, e) == (s, 0.0, 0.0, -s), "world file: north-up, one cell per pixel")
    image = Image.open(out / "decision-map.png")
    check(image.size == (info["width"], info["height"]), "decision-map.png size")
    west, north = c - a / 2, f - e / 2
    east, south = west + a * image.size[0], north + e * image.size[1]
    x0, y0 = info["origin"]["position"]["x"], info["origin"]["position"]["y"]
    check(math.isclose(west, x0) and math.isclose(south, y0), "world file west/south = origin")
    check(
        math.isclose(east, x0 + s * info["width"]) and math.isclose(north, y0 + s * info["height"]),
        "world file east/north = origin + size",
    )
    alpha = np.asarray(image.convert("RGBA"))[::-1, :, 3].reshape(-1)
    cls = np.array(classes["data"])
    check(np.array_equal(alpha == 0, cls == 0), "transparent exactly where unknown")
    prj = (out / "decision-map.prj").read_text()
    lat = float(re.search(r'"latitude_of_origin",([-0-9.eE]+)', prj).group(1))
    lon = float(re.search(r'"central_meridian",([-0-9.eE]+)', prj).group(1))
    check(
        math.isclose(lat, origin[0], abs_tol=1e-9) and math.isclose(lon, origin[1], abs_tol=1e-9),
        f".prj origin {lat},{lon} vs {origin}",
    )
    aux = (out / "decision-map.png.aux.xml").read_text()
    check("Transverse_Mercator" in aux, "GDAL .aux.xml holds the SRS")
    proj = check_geotiff(out, occ, classes, origin)
    if pyproj is None:
        print("note: pyproj missing, the .prj is not checked against WGS84 positions")
        return None
    # The GeoTIFF's CRS (its PROJ string) and the .prj's WKT agree on a point 1 km out.
    from_tiff = pyproj.Transformer.from_crs(pyproj.CRS.from_proj4(proj), "EPSG:4326", always_xy=True)
    from_prj = pyproj.Transformer.from_crs(pyproj.CRS.from_wkt(prj), "EPSG:4326", always_xy=True)
    a, b = from_tiff.transform(700.0, -700.0), from_prj.transform(700.0, -700.0)
    check(metres_between(*a, *b) < 1e-3, f"GeoTIFF and .prj CRS agree ({a} vs {b})")
    to_wgs84 = pyproj.Transformer.from_crs(pyproj.CRS.from_wkt(prj), "EPSG:4326", always_xy=True)
    return to_wgs84


def check_geotiff(out, occ, classes, origin):
    """The GeoTIFF read by tifffile: pixels, tie point, pixel scale and GeoKeys."""
    info = occ["info"]
    with tifffile.TiffFile(out / "decision-map.tif") as tif:
        page = tif.pages[0]
        pixels = page.asarray()
        tags = {tag.code: tag.value for tag in page.tags}
        geo = tif.geotiff_metadata
    check(pixels.shape == (info["height"], info["width"]), "GeoTIFF size")
    check(
        np.array_equal(pixels[::-1].reshape(-1), np.array(classes["data"])),
        "GeoTIFF pixels (north up) = classes.json",
    )
    s = info["resolution"]
    x0, y0 = info["origin"]["position"]["x"], info["origin"]["position"]["y"]
    tie = tags[33922]
    check(tuple(tags[33550])[:2] == (s, s), "GeoTIFF ModelPixelScale = resolution")
    check(
        tuple(tie[:3]) == (0, 0, 0)
        and math.isclose(tie[3], x0)
        and math.isclose(tie[4], y0 + s * info["height"]),
        "GeoTIFF tie point = north-west corner",
    )
    check(int(geo["ProjCoordTransGeoKey"]) == 1, "GeoTIFF CT_TransverseMercator")
    check(int(geo["ProjectedCSTypeGeoKey"]) == 32767, "GeoTIFF user-defined projected CRS")
    check(int(geo["GeographicTypeGeoKey"]) == 4326, "GeoTIFF on WGS 84")
    check(
        math.isclose(geo["ProjNatOriginLatGeoKey"], origin[0], abs_tol=1e-9)
        and math.isclose(geo["ProjNatOriginLongGeoKey"], origin[1], abs_tol=1e-9),
        "GeoTIFF natural origin = origin",
    )
    check(geo["ProjScaleAtNatOriginGeoKey"] == 1.0, "GeoTIFF scale 1")
    citation = geo["PCSCitationGeoKey"]
    check(citation.startswith("+proj=tmerc"), f"GeoTIFF PCSCitation {citation}")
    check(tags.get(42113) == "0", "GeoTIFF no-data is 0 (unknown)")
    return citation


def metres_between(lon1, lat1, lon2, lat2):
    return pyproj.Geod(ellps="WGS84").inv(lon1, lat1, lon2, lat2)[2]


# ---------------------------------------------------------------------------------------------
# MCAP.


def to_protobuf_json(value):
    """Foxglove's JSON (times as {sec, nsec}) → protobuf's JSON mapping (RFC 3339 strings,
    durations as "Ns"); bytes are base64 in both."""
    if isinstance(value, dict):
        if set(value) == {"sec", "nsec"}:
            return {"seconds": value["sec"], "nanos": value["nsec"]}
        return {k: to_protobuf_json(v) for k, v in value.items()}
    if isinstance(value, list):
        return [to_protobuf_json(v) for v in value]
    return value


def check_against_foxglove(schema_name, value):
    """Parses a message into the official foxglove.* protobuf type (foxglove-schemas-protobuf):
    any field that is not in Foxglove's definition, or of the wrong type, fails."""
    name = schema_name.split(".")[1]
    module = importlib.import_module(f"foxglove_schemas_protobuf.{name}_pb2")
    message = getattr(module, name)()
    converted = to_protobuf_json(value)
    # Timestamp/Duration as objects: protobuf's JSON wants strings; build them from the parts.
    def fix_times(descriptor, data):
        for field in descriptor.fields:
            if field.name not in data or field.message_type is None:
                continue
            kind = field.message_type.full_name
            repeated = isinstance(data[field.name], list)
            items = data[field.name] if repeated else [data[field.name]]
            for k, item in enumerate(items):
                if kind in ("google.protobuf.Timestamp", "google.protobuf.Duration"):
                    total = f"{item['seconds']}.{item['nanos']:09d}"
                    if kind == "google.protobuf.Duration":
                        text = f"{total}s"
                    else:
                        from datetime import datetime, timezone

                        day = datetime.fromtimestamp(item["seconds"], tz=timezone.utc)
                        text = day.strftime("%Y-%m-%dT%H:%M:%S") + f".{item['nanos']:09d}Z"
                    if repeated:
                        data[field.name][k] = text
                    else:
                        data[field.name] = text
                else:
                    fix_times(field.message_type, item)

    fix_times(message.DESCRIPTOR, converted)
    try:
        json_format.ParseDict(converted, message)
        check(True, schema_name)
    except json_format.ParseError as error:
        check(False, f"{schema_name} against Foxglove's definition: {error}")


def check_mcap(out, frames, occ, classes, kitti_drive, with_map):
    counts, times, first = {}, {}, {}
    last_grid, last_tf, map_points = None, None, []
    # Heights by log time: the grid is written at 2 Hz (and the last frame), /tf every frame.
    tf_z, grid_z = {}, {}
    with open(out / "run.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        scan_class = None
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            check(CHANNELS.get(channel.topic) == schema.name, f"{channel.topic}: {schema.name}")
            if channel.topic in PROTOBUF_CHANNELS:
                check(channel.message_encoding == "protobuf", f"{channel.topic} message encoding")
                if check(schema.encoding == "protobuf", f"{channel.topic} schema encoding"):
                    scan_class = descriptor_set_class(schema.name, schema.data)
                continue
            check(channel.message_encoding == "json", f"{channel.topic} message encoding")
            check(schema.encoding == "jsonschema", f"{channel.topic} schema encoding")
            check(json.loads(schema.data)["title"] == schema.name, f"{schema.name} schema title")
            check_schema_is_current(schema.name, json.loads(schema.data))
        first_tf, first_grid, first_scan = None, None, None
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            topic = channel.topic
            if topic in PROTOBUF_CHANNELS:
                value = decode_point_cloud(message.data, scan_class)
                if value is None:
                    continue
            else:
                value = json.loads(message.data)
            counts[topic] = counts.get(topic, 0) + 1
            times.setdefault(topic, []).append(message.log_time)
            check(message.publish_time == message.log_time, f"{topic} publish = log time")
            stamp = value.get("timestamp") or value["entities"][0]["timestamp"]
            check(
                stamp["sec"] * 10**9 + stamp["nsec"] == message.log_time,
                f"{topic} stamp = log time",
            )
            if topic not in first and topic not in PROTOBUF_CHANNELS:
                first[topic] = True
                validate(value, json.loads(schema.data), f"{topic} first message vs its schema")
                check_against_foxglove(schema.name, value)
            check(message.log_time >= YEAR_2000_NS, f"{topic} time after 2000 (not 1970)")
            if topic == "/evigrid/decision":
                last_grid = value
                first_grid = first_grid or value
                grid_z[message.log_time] = value["pose"]["position"]["z"]
            elif topic == "/tf":
                last_tf = value
                first_tf = first_tf or value
                tf_z[message.log_time] = value["translation"]["z"]
            elif topic == "/scan" and first_scan is None:
                first_scan = value
            elif topic == "/map":
                for entity in value["entities"]:
                    if entity["id"] == "buildings":
                        for line in entity["lines"]:
                            map_points.extend((p["x"], p["y"]) for p in line["points"])
    gnss = frames if kitti_drive else 0
    # The grid is written at a rate (README: the first frame's, at most one per 0.5 s of drive,
    # and the last frame's), the pose and the scan every frame.
    grids = counts.pop("/evigrid/decision", 0)
    check(1 <= grids <= frames, f"{grids} decision grids for {frames} frames")
    expected = {"/tf": frames, "/scan": frames}
    if with_map:
        expected["/map"] = 1
    if gnss:
        expected["/gnss"] = gnss
    check(counts == expected, f"message counts {counts} vs {expected}")
    grid_times = times["/evigrid/decision"]
    check(grid_times == sorted(grid_times), "decision times increase")
    check(times["/tf"] == times.get("/scan"), "pose and scan share the scan time")
    check(
        set(grid_times) <= set(times["/tf"])
        and grid_times[0] == times["/tf"][0]
        and grid_times[-1] == times["/tf"][-1],
        "grids at scan times, the first and the last frame's among them",
    )
    if kitti_drive:
        velodyne = scan_times(kitti_drive)[:frames]
        # evigrid holds times as f64 seconds: at 1.3e9 s their step is 238 ns.
        worst = max(abs(t - v) for t, v in zip(times["/tf"], velodyne))
        check(
            len(velodyne) == frames and worst < 1000,
            f"log times are the velodyne timestamps.txt (worst {worst} ns)",
        )
    if not check(first_scan is not None, "a /scan message decoded"):
        return last_tf, map_points
    check_scene(first_tf, first_grid, first_scan, tf_z, grid_z, kitti_drive)
    if kitti_drive:
        check_scan_is_the_bin(first_scan, kitti_drive)
    # The last grid decoded: field by field from its own description.
    g = last_grid
    fields = {fl["name"]: fl for fl in g["fields"]}
    raw = np.frombuffer(base64.b64decode(g["data"]), dtype=np.uint8)
    rows = len(raw) // g["row_stride"]
    cells = raw.reshape(rows, g["row_stride"])[:, : g["column_count"] * g["cell_stride"]]
    cells = cells.reshape(rows, g["column_count"], g["cell_stride"])
    check(fields["occupancy"]["type"] == 2 and fields["class"]["type"] == 1, "grid field types")
    occupancy = cells[:, :, fields["occupancy"]["offset"]].view(np.int8).reshape(-1)
    cls = cells[:, :, fields["class"]["offset"]].reshape(-1)
    info = occ["info"]
    check((g["column_count"], rows) == (info["width"], info["height"]), "grid size")
    check(g["cell_size"]["x"] == info["resolution"], "grid cell size")
    # The grid's corner is occupancy.json's origin in x and y; its z is the ground under the
    # sensor of its frame (check_scene), where occupancy.json's map plane is z = 0.
    position, origin = g["pose"]["position"], info["origin"]["position"]
    check(
        (position["x"], position["y"]) == (origin["x"], origin["y"]),
        "grid pose = occupancy origin in x, y",
    )
    check(np.array_equal(occupancy, np.array(occ["data"])), "MCAP grid = occupancy.json")
    check(np.array_equal(cls, np.array(classes["data"])), "MCAP grid classes = classes.json")
    betp = sum(
        cells[:, :, fields[f"betp_{c}"]["offset"]].astype(int) for c in "FIUSM"
    ).reshape(-1)
    # betP sums to 1 where the cell has any mass (255 ± rounding of five terms).
    check(np.all((betp >= 252) & (betp <= 258)), "betP fields sum to 255 ± rounding")
    # The colour fields: one colour per class, a different one for each (the figures' palette).
    rgb = np.stack(
        [cells[:, :, fields[c]["offset"]].reshape(-1) for c in ("red", "green", "blue")], axis=1
    )
    colour_of = {}
    for code in np.unique(cls):
        colours = np.unique(rgb[cls == code], axis=0)
        check(len(colours) == 1, f"class {code}: one colour in the grid ({len(colours)})")
        colour_of[int(code)] = tuple(colours[0])
    check(
        len(set(colour_of.values())) == len(colour_of),
        f"a different colour for each class {colour_of}",
    )
    return last_tf, map_points


# 2000-01-01T00:00:00Z in nanoseconds: a recording before it has lost its clock.
YEAR_2000_NS = 946_684_800 * 10**9


def check_schema_is_current(schema_name, schema):
    """Every field of Foxglove's current definition (foxglove-schemas-protobuf) is a property
    of the channel's JSON Schema: the schema is not an older copy."""
    name = schema_name.split(".")[1]
    module = importlib.import_module(f"foxglove_schemas_protobuf.{name}_pb2")
    fields = {f.name for f in getattr(module, name).DESCRIPTOR.fields}
    missing = sorted(fields - set(schema.get("properties", {})))
    check(not missing, f"{schema_name} schema lacks current fields {missing}")


def descriptor_set_class(schema_name, data):
    """The message class of `schema_name` built from the FileDescriptorSet a protobuf channel
    carries (as Foxglove and mcap-protobuf-support's decoder build it), after checking that the
    set describes it field for field as Foxglove's own PointCloud (foxglove-schemas-protobuf)."""
    try:
        files = descriptor_pb2.FileDescriptorSet.FromString(data)
    except DecodeError as error:
        check(False, f"{schema_name} schema is not a FileDescriptorSet: {error}")
        return None
    pool = descriptor_pool.DescriptorPool()
    for file in files.file:
        pool.Add(file)
    ours = pool.FindMessageTypeByName(schema_name)
    name = schema_name.split(".")[1]
    theirs = getattr(importlib.import_module(f"foxglove_schemas_protobuf.{name}_pb2"), name)

    def fields(descriptor, seen):
        """(message.field, number, type, repeated, nested type) of a message and all it nests."""
        if descriptor.full_name in seen:
            return []
        seen.add(descriptor.full_name)
        result = []
        for f in descriptor.fields:
            nested = f.message_type or f.enum_type
            result.append(
                (f"{descriptor.full_name}.{f.name}", f.number, f.type, f.is_repeated,
                 nested.full_name if nested else None)
            )
            if f.message_type is not None:
                result.extend(fields(f.message_type, seen))
            if f.enum_type is not None:
                values = [(v.name, v.number) for v in f.enum_type.values]
                result.append((f.enum_type.full_name, values))
        return result

    check(
        fields(ours, set()) == fields(theirs.DESCRIPTOR, set()),
        f"{schema_name} descriptor set = Foxglove's {name}, field for field",
    )
    return message_factory.GetMessageClass(ours)


def decode_point_cloud(data, from_file):
    """A /scan message decoded by Foxglove's PointCloud and by the class of the file's own
    descriptor set, checked alike and complete, as Foxglove's JSON layout (`timestamp` as
    {sec, nsec}, `data` raw bytes); None, a failure, if it is not a PointCloud."""
    from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud

    try:
        message = PointCloud.FromString(data)
    except DecodeError as error:
        check(False, f"/scan is not a protobuf PointCloud: {error}")
        return None
    if check(from_file is not None, "/scan has its descriptor set"):
        other = from_file.FromString(data)
        check(
            json_format.MessageToDict(other) == json_format.MessageToDict(message),
            "/scan decoded alike by the file's descriptor set and foxglove-schemas-protobuf",
        )
    check(len(unknown_fields.UnknownFieldSet(message)) == 0, "/scan has no unknown field")
    check(message.SerializeToString() == data, "/scan re-encodes to the same bytes")
    return {
        "timestamp": {"sec": message.timestamp.seconds, "nsec": message.timestamp.nanos},
        "frame_id": message.frame_id,
        "pose": json_format.MessageToDict(message.pose),
        "point_stride": message.point_stride,
        "fields": [{"name": f.name, "offset": f.offset, "type": f.type} for f in message.fields],
        "data": message.data,
    }


def check_scan_is_the_bin(scan, drive):
    """The first /scan holds the first Velodyne .bin's points: x, y, z and intensity, every
    finite record, in order, bit for bit."""
    sync = next(Path(drive).glob("*_sync"))
    records = np.fromfile(sync / "velodyne_points" / "data" / "0000000000.bin", dtype="<f4")
    records = records.reshape(-1, 4)
    records = records[np.isfinite(records[:, :3]).all(axis=1)]
    fields = {f["name"]: f["offset"] for f in scan["fields"]}
    check(scan["point_stride"] == 16 and fields == {"x": 0, "y": 4, "z": 8, "intensity": 12},
          f"/scan x y z intensity at 0 4 8 12 of 16 ({fields})")
    points = np.frombuffer(scan["data"], dtype="<f4").reshape(-1, 4)
    same = points.shape == records.shape and np.array_equal(points, records)
    check(same, f"first /scan = first .bin ({len(points)} against {len(records)} points)")
    print(
        f"first /scan: {len(points)} points, the .bin's; first {points[0].tolist()},"
        f" last {points[-1].tolist()}"
    )


def quaternion_matrix(q):
    x, y, z, w = q["x"], q["y"], q["z"], q["w"]
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def check_scene(tf, grid, scan, tf_z, grid_z, kitti_drive):
    """The scene is right in 3-D: in every frame with a grid it lies at most 3 m below the sensor
    (its height above the ground: 1.73 m for KITTI's Velodyne, 0 for a planar scanner), the
    first frame's grid at z = 0, and the first scan's lowest returns (its ground), put in the
    map frame by /tf, lie on the grid. With KITTI the scan carries its intensity."""
    gaps = [tf_z[ns] - z for ns, z in grid_z.items() if ns in tf_z]
    check(
        len(gaps) == len(grid_z) > 0 and all(-1e-6 <= d <= 3.0 for d in gaps),
        f"/tf z - grid z within 0..3 m in every frame with a grid"
        f" ({min(gaps, default=0):.3f}..{max(gaps, default=0):.3f})",
    )
    first_z = grid_z[min(grid_z)] if grid_z else float("nan")
    check(abs(first_z) < 1e-9, f"first grid at z = 0 ({first_z})")
    fields = {f["name"]: f for f in scan["fields"]}
    stride = scan["point_stride"]
    raw = np.frombuffer(scan["data"], dtype=np.uint8).reshape(-1, stride)
    xyz = np.stack(
        [raw[:, fields[c]["offset"] : fields[c]["offset"] + 4].copy().view("<f4")[:, 0]
         for c in "xyz"],
        axis=1,
    ).astype(float)
    t = tf["translation"]
    in_map = xyz @ quaternion_matrix(tf["rotation"]).T + np.array([t["x"], t["y"], t["z"]])
    low = float(np.percentile(in_map[:, 2], 10))
    gz = grid["pose"]["position"]["z"]
    check(abs(low - gz) < 0.5, f"first scan's ground (10th percentile z {low:.2f}) on the grid ({gz:.2f})")
    print(f"scene: sensor {tf_z[min(tf_z)]:.2f} m above the first grid; scan ground at {low:.2f} m")
    if kitti_drive:
        intensity = fields.get("intensity")
        check(
            intensity is not None and intensity["type"] == 7 and stride >= 16,
            "/scan has a FLOAT32 intensity field",
        )
        if intensity is not None:
            off = intensity["offset"]
            values = raw[:, off : off + 4].copy().view("<f4")[:, 0]
            check(np.ptp(values) > 0, "/scan intensity varies over the scan")


def scan_times(drive):
    """Seconds since the epoch of KITTI raw's velodyne timestamps.txt, as integer nanoseconds."""
    from datetime import datetime, timezone

    sync = next(Path(drive).glob("*_sync"))
    result = []
    for line in (sync / "velodyne_points" / "timestamps.txt").read_text().split("\n"):
        if not line.strip():
            continue
        day, clock = line.split()
        whole, frac = clock.split(".")
        t = datetime.strptime(f"{day} {whole}", "%Y-%m-%d %H:%M:%S").replace(tzinfo=timezone.utc)
        result.append(int(t.timestamp()) * 10**9 + int(frac.ljust(9, "0")[:9]))
    return result


def oxts_fixes(drive, frames):
    sync = next(Path(drive).glob("*_sync"))
    files = sorted((sync / "oxts" / "data").glob("*.txt"))[:frames]
    return [tuple(float(v) for v in f.read_text().split()[:2]) for f in files]


def geojson_vertices(path):
    vertices = []
    for feature in load_json(path)["features"]:
        if "building" not in (feature.get("properties") or {}):
            continue
        geometry = feature["geometry"]
        rings = geometry["coordinates"]
        if geometry["type"] == "MultiPolygon":
            rings = [r for polygon in rings for r in polygon]
        for ring in rings:
            vertices.extend(tuple(p[:2]) for p in ring)
    return np.array(vertices)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--frames", type=int, required=True)
    parser.add_argument("--origin", required=True, help="LAT,LON of the local frame")
    parser.add_argument("--kitti-drive", type=Path)
    parser.add_argument("--geojson", type=Path, help="the map, to check the projection")
    parser.add_argument("--no-map", action="store_true", help="the run had no map: no /map")
    args = parser.parse_args()
    origin = tuple(float(v) for v in args.origin.split(","))
    out = args.out

    occ = load_json(out / "occupancy.json")
    classes = load_json(out / "classes.json")
    check_occupancy(occ)
    validate(classes, load_json(SCHEMAS / "classes.schema.json"), "classes.json schema")
    masses = load_json(out / "masses.json")
    validate(masses, load_json(SCHEMAS / "masses.schema.json"), "masses.json schema")
    size = (out / masses["data_file"]).stat().st_size
    check(size == masses["row_count"] * masses["row_stride"], "masses.bin size")
    planes = np.fromfile(out / masses["data_file"], dtype="<f4").reshape(
        -1, masses["cell_stride"] // 4
    )
    check(np.allclose(planes[:, :32].sum(axis=1), 1.0, atol=1e-4), "masses sum to 1 per cell")
    check(len(classes["data"]) == len(occ["data"]), "classes.json size")
    check_nav2(out, occ)
    to_wgs84 = check_georeference(out, occ, classes, origin)
    last_tf, map_points = check_mcap(
        out, args.frames, occ, classes, args.kitti_drive, not args.no_map
    )

    if to_wgs84 is not None and args.kitti_drive:
        t = last_tf["translation"]
        lon, lat = to_wgs84.transform(t["x"], t["y"])
        fix_lat, fix_lon = oxts_fixes(args.kitti_drive, args.frames)[-1]
        # The Velodyne sits about a metre from the OXTS unit (calib_imu_to_velo.txt).
        distance = metres_between(lon, lat, fix_lon, fix_lat)
        check(distance < 2.0, f"last pose via .prj is {distance:.2f} m from the OXTS fix")
        print(f"last pose through the .prj: {distance:.3f} m from the last OXTS fix")
    if to_wgs84 is not None and args.geojson:
        vertices = geojson_vertices(args.geojson)
        sample = map_points[:: max(1, len(map_points) // 200)]
        gaps = []
        for x, y in sample:
            lon, lat = to_wgs84.transform(x, y)
            nearest = vertices[np.argmin(np.hypot(vertices[:, 0] - lon, vertices[:, 1] - lat))]
            gaps.append(metres_between(lon, lat, nearest[0], nearest[1]))
        median = float(np.median(gaps))
        check(median < 0.01, f"map outlines via .prj: median {median:.4f} m from the GeoJSON")
        print(f"{len(sample)} building vertices through the .prj: median {median * 1000:.2f} mm")

    if failures:
        print(f"0 passed, {len(failures)} failed")
        sys.exit(1)
    print(f"check_outputs: {out}: all checks passed")


if __name__ == "__main__":
    main()
