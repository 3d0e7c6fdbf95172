"""The decision over the shared KITTI raw drive, stepped from Python and drawn with matplotlib.

    pip install ./crates/python matplotlib
    python crates/python/examples/kitti_decision.py ../shared/data/lidar/kitti-raw-0013/2011_09_26 decision.png
"""

from __future__ import annotations

import sys

import matplotlib

matplotlib.use("Agg")  # draw to a file; remove to show a window
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import ListedColormap

import evigrid

drive_dir, picture = sys.argv[1], sys.argv[2]
drive = evigrid.open_drive(drive_dir)  # KITTI raw: scans, OXTS poses, calibration
session = evigrid.Session()  # the defaults of `evigrid run`
moving_per_frame = []
for frame in drive:
    result = session.step(frame)  # the GIL is released while the frame is fused
    moving_per_frame.append(int(np.count_nonzero(result.classes == 5)))

# The last step's grids, row 0 south: extent in metres of the local frame.
classes = result.classes
east, north = result.origin
height, width = classes.shape
extent = (east, east + width * result.cell_size, north, north + height * result.cell_size)
colours = ListedColormap(["#f0f0f0", "#ffffff", "#0072b2", "#009e73", "#e69f00", "#d55e00"])

figure, (left, right) = plt.subplots(1, 2, figsize=(12, 5.5), width_ratios=(1.1, 1))
left.imshow(classes, origin="lower", extent=extent, cmap=colours, vmin=-0.5, vmax=5.5,
            interpolation="nearest")
path = drive.ego_path
left.plot(path[:, 0], path[:, 1], color="black", linewidth=1, label="ego path")
for obj in result.objects:
    x, y = obj["position_m"]
    left.plot(x, y, "o", markersize=8, markerfacecolor="none", markeredgecolor="#d55e00")
    if obj["velocity_mps"] is not None:
        vx, vy = obj["velocity_mps"]
        left.arrow(x, y, vx, vy, color="#d55e00", width=0.15)
handles = [plt.Rectangle((0, 0), 1, 1, color=colours(k)) for k in range(6)]
left.legend(handles, ["unknown", "F free", "I mapped infra.", "U unmapped infra.", "S stopped", "M moving"],
            loc="lower left", fontsize=8)
left.set(title=f"Decision after {session.frames} frames", xlabel="east (m)", ylabel="north (m)")
left.set_aspect("equal")

masses = result.masses  # H × W × 32; set 16 is {M}
right.plot(moving_per_frame, marker=".")
right.set(title="Cells decided moving, per frame", xlabel="frame", ylabel="cells")
figure.tight_layout()
figure.savefig(picture, dpi=100)
summary = session.summary()
print(f"{summary['frames']} frames, final classes {summary['final_classes']}, "
      f"max m({{M}}) {float(masses[..., 16].max()):.2f}; picture in {picture}")
