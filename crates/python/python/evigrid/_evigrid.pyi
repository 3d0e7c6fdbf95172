"""Type stubs of the extension module ``evigrid._evigrid`` (Rust, PyO3).

``evigrid`` re-exports the classes and functions users call; ``mass`` is wrapped by
``evigrid.mass``.
"""

import os
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, "os.PathLike[str]"]
_Config = Union[_Path, Dict[str, Any], None]
_Origin = Union[Tuple[float, float], str, None]

class Frame:
    """One scan with its pose."""

    @property
    def points(self) -> npt.NDArray[np.float32]:
        """Points in the sensor frame, N × 4 (x, y, z, intensity; NaN where unknown), read-only."""
    @property
    def pose(self) -> npt.NDArray[np.float64]:
        """World from sensor, 4 × 4."""
    @property
    def time(self) -> float: ...
    @property
    def name(self) -> str: ...
    @property
    def index(self) -> int: ...
    def __len__(self) -> int: ...

class Frames(Iterator[Frame]):
    """One pass over a drive's frames, in order."""

    def __iter__(self) -> "Frames": ...
    def __next__(self) -> Frame: ...

class Drive:
    """A drive: iterate it for its frames; ``len()`` is their number."""

    def __len__(self) -> int: ...
    def __iter__(self) -> Frames: ...
    @property
    def path(self) -> str: ...
    @property
    def poses(self) -> str: ...
    @property
    def pose_matching(self) -> str: ...
    @property
    def ego_path(self) -> npt.NDArray[np.float64]: ...
    @property
    def skipped(self) -> List[Dict[str, str]]: ...

def open_drive(
    path: _Path,
    *,
    poses: Optional[_Path] = None,
    pose_format: Optional[str] = None,
    calib: Optional[_Path] = None,
    times: Optional[_Path] = None,
    mounting: Union[str, Sequence[float], None] = None,
    cloud_topic: Optional[str] = None,
    pose_source: Optional[str] = None,
    map: Optional[_Path] = None,
    origin: _Origin = None,
    max_frames: Optional[int] = None,
    strict: bool = False,
) -> Drive: ...

class StepResult:
    """What one step gives; grids in world order (row 0 south, column 0 west)."""

    @property
    def classes(self) -> npt.NDArray[np.uint8]:
        """H × W decision codes (0 unknown, 1 F, 2 I, 3 U, 4 S, 5 M)."""
    @property
    def masses(self) -> npt.NDArray[np.float32]:
        """H × W × 32, set k the bitmask k over (F, I, U, S, M)."""
    @property
    def betp(self) -> npt.NDArray[np.float32]:
        """H × W × 5 pignistic probabilities of F, I, U, S, M."""
    @property
    def velocity(self) -> Optional[npt.NDArray[np.float32]]:
        """H × W × 2, east and north in m/s; None for kurdej2013."""
    @property
    def objects(self) -> List[Dict[str, Any]]: ...
    @property
    def record(self) -> Dict[str, Any]: ...
    @property
    def origin(self) -> Tuple[float, float]: ...
    @property
    def cell_size(self) -> float: ...
    @property
    def name(self) -> str: ...
    @property
    def index(self) -> int: ...
    @property
    def time(self) -> float: ...

class Session:
    """The pipeline of ``evigrid run``, one frame at a time.

    Stepping the frames of an ``open_drive`` drive names that drive in the summary and, for
    scans placed by the lidar odometry, turns the pose refinement off, as ``evigrid run`` does.
    """

    def __init__(
        self,
        config: _Config = None,
        *,
        method: str = "evigrid",
        map: Optional[_Path] = None,
        origin: _Origin = None,
        strict: bool = False,
    ) -> None: ...
    def step(
        self,
        frame: Union[Frame, npt.ArrayLike],
        pose: Optional[npt.ArrayLike] = None,
        time: Optional[float] = None,
        *,
        name: Optional[str] = None,
    ) -> StepResult: ...
    def summary(self) -> Dict[str, Any]: ...
    @property
    def frames(self) -> int: ...

def run(
    source: Union[_Path, Drive],
    *,
    out: Optional[_Path],
    config: _Config = None,
    method: str = "evigrid",
    map: Optional[_Path] = None,
    origin: _Origin = None,
    poses: Optional[_Path] = None,
    pose_format: Optional[str] = None,
    calib: Optional[_Path] = None,
    times: Optional[_Path] = None,
    mounting: Union[str, Sequence[float], None] = None,
    cloud_topic: Optional[str] = None,
    pose_source: Optional[str] = None,
    max_frames: Optional[int] = None,
    strict: bool = False,
    # Write into a folder of someone else's files; never onto a file or into a folder holding
    # an input (evigrid.InputError).
    force: bool = False,
    mcap: bool = True,
    # Called every 50 ms while the drive runs; a true answer stops it between frames, and the
    # summary (marked incomplete) is returned.
    stop: Optional[Callable[[], object]] = None,
    # A thread pool of that many threads, kept for the next runs (default: the shared pool).
    threads: Optional[int] = None,
) -> Dict[str, Any]: ...

# A mass function as the Python layer passes it: (label, frame names, [(set names, mass)]).
_MassArg = Tuple[str, List[str], List[Tuple[List[str], float]]]
# A mass function as returned: (frame names, [(set names, mass)]) in bitmask order.
_MassOut = Tuple[List[str], List[Tuple[List[str], float]]]

class mass:
    """The belief-function calculator (``evigrid.mass`` wraps it)."""

    @staticmethod
    def check(m: _MassArg) -> _MassOut: ...
    @staticmethod
    def combine(rule: str, inputs: List[_MassArg]) -> _MassOut: ...
    @staticmethod
    def discount(
        m: _MassArg,
        alpha: Optional[float] = None,
        contexts: Optional[List[Tuple[List[str], float]]] = None,
        class_rates: Optional[List[Tuple[str, float]]] = None,
        set_rate: Optional[str] = None,
    ) -> _MassOut: ...
    @staticmethod
    def pignistic(m: _MassArg) -> List[Tuple[str, float]]: ...
    @staticmethod
    def transform(m: _MassArg, to: str) -> List[Tuple[List[str], float]]: ...
