"""evigrid: evidential occupancy grids fused with OpenStreetMap maps, from Python.

The package is numpy-first and thin: the numbers come from the Rust library crates, built into
the extension module ``evigrid._evigrid``; what is here turns them into Python values.

- ``evigrid.open_drive(path, ...)``: any drive ``evigrid run`` reads (a KITTI raw folder, scans
  with a pose file, a ROS 2 recording, scans without poses) as an iterable of frames with
  ``.points`` (float32, N × 4), ``.pose`` (float64, 4 × 4, world from sensor), ``.time``, ``.name``.
- ``evigrid.Session(config, method=..., map=..., origin=...)``: the pipeline of ``evigrid run``,
  stepped frame by frame; ``.step(frame)`` gives ``.classes``, ``.masses``, ``.betp``,
  ``.velocity`` as numpy arrays, ``.objects``, ``.origin``, ``.cell_size``; ``.summary()`` the
  dict of ``summary.json``.
- ``evigrid.run(source, out=...)``: a whole ``evigrid run``, every output file, returning the
  summary.
- ``evigrid.mass``: the belief-function calculator of ``evigrid mass``.
- ``evigrid.Error``: the base class of every exception raised, with ``InputError`` (bad input, a
  ``ValueError``) and ``FileError`` (a file could not be read or written, an ``OSError``).

The GIL is released while a session steps and while a drive runs.

Example::

    >>> import evigrid
    >>> m1 = {"frame": ["a", "b"], "mass": {("a",): 0.2, ("b",): 0.6, ("a", "b"): 0.2}}
    >>> m2 = {"frame": ["a", "b"], "mass": {("a",): 0.7, ("b",): 0.1, ("a", "b"): 0.2}}
    >>> evigrid.mass.pignistic(evigrid.mass.combine([m1, m2], rule="dempster"))["a"]
    0.6071428571428571
"""

from __future__ import annotations

from evigrid import mass
from evigrid._errors import Error, FileError, InputError
from evigrid._evigrid import (
    Drive,
    Frame,
    Session,
    StepResult,
    __version__,
    open_drive,
    run,
)

CLASSES = ("unknown", "F", "I", "U", "S", "M")
"""The decision codes of ``StepResult.classes`` and ``classes.json``: 0 unknown, 1 F free, 2 I
mapped infrastructure, 3 U unmapped infrastructure, 4 S stopped, 5 M moving."""

FOCAL_SETS = tuple(
    "".join(name for bit, name in enumerate("FIUSM") if k >> bit & 1) or "empty" for k in range(32)
)
"""The name of each of the 32 focal sets of ``StepResult.masses``: set k is the bitmask k over
(F, I, U, S, M), named as in ``masses.json``: ``FOCAL_SETS[0] == "empty"``, ``FOCAL_SETS[3] == "FI"`` and ``FOCAL_SETS[31] == "FIUSM"`` (Ω)."""

__all__ = [
    "CLASSES",
    "Drive",
    "Error",
    "FOCAL_SETS",
    "FileError",
    "Frame",
    "InputError",
    "Session",
    "StepResult",
    "__version__",
    "mass",
    "open_drive",
    "run",
]
