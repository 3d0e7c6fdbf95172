#!/usr/bin/env python3
"""Writes a small ROS 2 MCAP recording from the shared KITTI raw frames of drive 0013.

An *independent writer* for the bag reader of `crates/drive` (`drive::bag`): the CDR encoding is
done by `mcap-ros2-support`, not by evigrid, and the poses are computed here from the OXTS
packets with our own few lines of the KITTI devkit's maths, so the Rust tests compare two
implementations.

Contents (all stamps are the KITTI clock read as UTC):
  /velodyne_points  sensor_msgs/msg/PointCloud2   frames FRAMES, every STRIDE-th point of the
                                                  .bin (x, y, z, intensity as FLOAT32), frame
                                                  `velodyne`, stamp = the scan's timestamps.txt
  /tf_static        tf2_msgs/msg/TFMessage        base_link -> velodyne, inverse of
                                                  calib_imu_to_velo.txt (base_link = the OXTS IMU)
  /tf               tf2_msgs/msg/TFMessage        odom -> base_link at every OXTS packet
  /odom             nav_msgs/msg/Odometry         the same poses, child base_link
  /gps/fix          sensor_msgs/msg/NavSatFix     the OXTS lat/lon/alt, frame base_link

`odom` is the devkit's Mercator (scale cos(lat0), R = 6378137 m) centred on the drive's first
packet, z = altitude, orientation Rz(yaw) Ry(pitch) Rx(roll).

Usage: EVIGRID_SHARED=/work/shared python3 scripts/make_ros2_bag.py OUT.mcap
Requirements: scripts/requirements.txt.
"""

import math
import os
import struct
import sys
from datetime import datetime, timezone

from mcap.writer import CompressionType
from mcap_ros2.writer import Writer

FRAMES = [2, 7, 12, 17]
STRIDE = 32
EARTH_RADIUS_M = 6378137.0
DRIVE = "data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync"
CALIB = "data/lidar/kitti-raw-0013/2011_09_26/calib_imu_to_velo.txt"

SEP = "=" * 80 + "\n"
TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
VECTOR3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
QUAT = "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
POINT = "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"


def msgdef(main, *deps):
    return main + "".join(SEP + d for d in deps)


POINTCLOUD2 = msgdef(
    "std_msgs/Header header\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\n"
    "bool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n",
    HEADER,
    TIME,
    "MSG: sensor_msgs/PointField\nuint8 INT8 = 1\nuint8 UINT8 = 2\nuint8 INT16 = 3\n"
    "uint8 UINT16 = 4\nuint8 INT32 = 5\nuint8 UINT32 = 6\nuint8 FLOAT32 = 7\nuint8 FLOAT64 = 8\n"
    "string name\nuint32 offset\nuint8 datatype\nuint32 count\n",
)
TFMESSAGE = msgdef(
    "geometry_msgs/TransformStamped[] transforms\n",
    "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/Transform transform\n",
    HEADER,
    TIME,
    "MSG: geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\n"
    "geometry_msgs/Quaternion rotation\n",
    VECTOR3,
    QUAT,
)
ODOMETRY = msgdef(
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n"
    "geometry_msgs/TwistWithCovariance twist\n",
    HEADER,
    TIME,
    "MSG: geometry_msgs/PoseWithCovariance\ngeometry_msgs/Pose pose\nfloat64[36] covariance\n",
    "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
    POINT,
    QUAT,
    "MSG: geometry_msgs/TwistWithCovariance\ngeometry_msgs/Twist twist\nfloat64[36] covariance\n",
    "MSG: geometry_msgs/Twist\ngeometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n",
    VECTOR3,
)
NAVSATFIX = msgdef(
    "std_msgs/Header header\nsensor_msgs/NavSatStatus status\nfloat64 latitude\n"
    "float64 longitude\nfloat64 altitude\nfloat64[9] position_covariance\n"
    "uint8 COVARIANCE_TYPE_UNKNOWN = 0\nuint8 COVARIANCE_TYPE_APPROXIMATED = 1\n"
    "uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN = 2\nuint8 COVARIANCE_TYPE_KNOWN = 3\n"
    "uint8 position_covariance_type\n",
    HEADER,
    TIME,
    "MSG: sensor_msgs/NavSatStatus\nint8 STATUS_NO_FIX = -1\nint8 STATUS_FIX = 0\n"
    "int8 STATUS_SBAS_FIX = 1\nint8 STATUS_GBAS_FIX = 2\nint8 status\n"
    "uint16 SERVICE_GPS = 1\nuint16 SERVICE_GLONASS = 2\nuint16 SERVICE_COMPASS = 4\n"
    "uint16 SERVICE_GALILEO = 8\nuint16 service\n",
)


def stamp_ns(text):
    """'2011-09-26 13:10:59.455982982' (UTC) -> integer nanoseconds since the Unix epoch."""
    day_time, frac = text.strip().split(".")
    whole = datetime.strptime(day_time, "%Y-%m-%d %H:%M:%S").replace(tzinfo=timezone.utc)
    return int(whole.timestamp()) * 1_000_000_000 + int(frac.ljust(9, "0")[:9])


def stamp(ns):
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def quat_from_rpy(roll, pitch, yaw):
    """Hamilton quaternion (x, y, z, w) of Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def quat_from_matrix(m):
    """Quaternion (x, y, z, w) of a (near-)rotation matrix, rows m[0..3] (Shepperd)."""
    t = m[0][0] + m[1][1] + m[2][2]
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        q = ((m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, s / 4)
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2
        q = (s / 4, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s, (m[2][1] - m[1][2]) / s)
    elif m[1][1] > m[2][2]:
        s = math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2
        q = ((m[0][1] + m[1][0]) / s, s / 4, (m[1][2] + m[2][1]) / s, (m[0][2] - m[2][0]) / s)
    else:
        s = math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2
        q = ((m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, s / 4, (m[1][0] - m[0][1]) / s)
    n = math.sqrt(sum(c * c for c in q))
    return tuple(c / n for c in q)


def base_link_from_velodyne(path):
    """calib_imu_to_velo.txt holds velo_from_imu (R, T); return its inverse as (t, q)."""
    rows = {}
    with open(path) as f:
        for line in f:
            key, _, value = line.partition(":")
            rows[key.strip()] = value.split()
    r = [float(v) for v in rows["R"]]
    t = [float(v) for v in rows["T"]]
    rm = [r[0:3], r[3:6], r[6:9]]
    rt = [[rm[j][i] for j in range(3)] for i in range(3)]  # inverse rotation
    ti = [-sum(rt[i][j] * t[j] for j in range(3)) for i in range(3)]
    return ti, quat_from_matrix(rt)


def mercator(lat0):
    scale = math.cos(math.radians(lat0))

    def project(lat, lon):
        east = scale * EARTH_RADIUS_M * math.radians(lon)
        north = scale * EARTH_RADIUS_M * math.log(math.tan(math.pi * (90.0 + lat) / 360.0))
        return east, north

    return project


def transform(ns, parent, child, t, q):
    return {
        "header": {"stamp": stamp(ns), "frame_id": parent},
        "child_frame_id": child,
        "transform": {
            "translation": {"x": t[0], "y": t[1], "z": t[2]},
            "rotation": {"x": q[0], "y": q[1], "z": q[2], "w": q[3]},
        },
    }


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    shared = os.environ.get("EVIGRID_SHARED")
    if not shared:
        sys.exit("set EVIGRID_SHARED to the shared data folder")
    drive = os.path.join(shared, DRIVE)
    with open(os.path.join(drive, "oxts/timestamps.txt")) as f:
        oxts_ns = [stamp_ns(line) for line in f if line.strip()]
    with open(os.path.join(drive, "velodyne_points/timestamps.txt")) as f:
        scan_ns = [stamp_ns(line) for line in f if line.strip()]
    packets = []
    for i in range(len(oxts_ns)):
        with open(os.path.join(drive, f"oxts/data/{i:010}.txt")) as f:
            packets.append([float(v) for v in f.read().split()])
    project = mercator(packets[0][0])
    east0, north0 = project(packets[0][0], packets[0][1])
    t_static, q_static = base_link_from_velodyne(os.path.join(shared, CALIB))

    events = []  # (log_time_ns, order, topic, schema key, message)
    static = {"transforms": [transform(oxts_ns[0], "base_link", "velodyne", t_static, q_static)]}
    events.append((oxts_ns[0], 0, "/tf_static", "tf", static))
    for ns, p in zip(oxts_ns, packets):
        lat, lon, alt, roll, pitch, yaw = p[0:6]
        vf, vl, vu = p[8:11]
        wf, wl, wu = p[20:23]
        east, north = project(lat, lon)
        t = (east - east0, north - north0, alt)
        q = quat_from_rpy(roll, pitch, yaw)
        events.append((ns, 1, "/tf", "tf", {"transforms": [transform(ns, "odom", "base_link", t, q)]}))
        odom = {
            "header": {"stamp": stamp(ns), "frame_id": "odom"},
            "child_frame_id": "base_link",
            "pose": {
                "pose": {
                    "position": {"x": t[0], "y": t[1], "z": t[2]},
                    "orientation": {"x": q[0], "y": q[1], "z": q[2], "w": q[3]},
                },
                "covariance": [0.0] * 36,
            },
            "twist": {
                "twist": {
                    "linear": {"x": vf, "y": vl, "z": vu},
                    "angular": {"x": wf, "y": wl, "z": wu},
                },
                "covariance": [0.0] * 36,
            },
        }
        events.append((ns, 2, "/odom", "odom", odom))
        sigma = p[23]  # pos_accuracy
        fix = {
            "header": {"stamp": stamp(ns), "frame_id": "base_link"},
            "status": {"status": 0, "service": 1},
            "latitude": lat,
            "longitude": lon,
            "altitude": alt,
            "position_covariance": [sigma * sigma, 0, 0, 0, sigma * sigma, 0, 0, 0, sigma * sigma],
            "position_covariance_type": 2,
        }
        events.append((ns, 3, "/gps/fix", "fix", fix))
    for i in FRAMES:
        with open(os.path.join(drive, f"velodyne_points/data/{i:010}.bin"), "rb") as f:
            raw = f.read()
        records = [raw[k : k + 16] for k in range(0, len(raw) - 15, 16)][::STRIDE]
        data = b"".join(struct.pack("<4f", *struct.unpack("<4f", r)) for r in records)
        cloud = {
            "header": {"stamp": stamp(scan_ns[i]), "frame_id": "velodyne"},
            "height": 1,
            "width": len(records),
            "fields": [
                {"name": n, "offset": 4 * k, "datatype": 7, "count": 1}
                for k, n in enumerate(["x", "y", "z", "intensity"])
            ],
            "is_bigendian": False,
            "point_step": 16,
            "row_step": 16 * len(records),
            "data": data,
            "is_dense": True,
        }
        events.append((scan_ns[i], 4, "/velodyne_points", "cloud", cloud))
    events.sort(key=lambda e: (e[0], e[1]))

    with open(sys.argv[1], "wb") as out:
        writer = Writer(out, compression=CompressionType.ZSTD)
        schemas = {
            "cloud": writer.register_msgdef("sensor_msgs/msg/PointCloud2", POINTCLOUD2),
            "tf": writer.register_msgdef("tf2_msgs/msg/TFMessage", TFMESSAGE),
            "odom": writer.register_msgdef("nav_msgs/msg/Odometry", ODOMETRY),
            "fix": writer.register_msgdef("sensor_msgs/msg/NavSatFix", NAVSATFIX),
        }
        for seq, (ns, _, topic, key, message) in enumerate(events):
            writer.write_message(topic, schemas[key], message, log_time=ns, publish_time=ns, sequence=seq)
        writer.finish()
    print(f"{sys.argv[1]}: {len(events)} messages, frames {FRAMES}, every {STRIDE}th point")


if __name__ == "__main__":
    main()
