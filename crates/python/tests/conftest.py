"""Fixtures of the evigrid Python tests: the shared data and the `evigrid` command to compare with.

The shared data is found through ``EVIGRID_SHARED`` (default ``../shared`` beside the repository)
and the command through ``EVIGRID_CLI`` (default ``target/debug/evigrid``, which ``cargo test``
builds). Missing either, a test is skipped, unless ``EVIGRID_REQUIRE_SHARED=1`` (set by ``.ci/run``)
makes it fail.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any, List

import pytest

REPOSITORY = Path(__file__).resolve().parents[3]


def _missing(what: str) -> None:
    if os.environ.get("EVIGRID_REQUIRE_SHARED") == "1":
        pytest.fail(f"{what} not found, and EVIGRID_REQUIRE_SHARED=1")
    pytest.skip(f"{what} not found")


@pytest.fixture(scope="session")
def shared() -> Path:
    """The shared data folder."""
    path = Path(os.environ.get("EVIGRID_SHARED", REPOSITORY.parent / "shared"))
    if not (path / "vectors" / "belief-vectors.json").is_file():
        _missing(f"shared data at {path} (set EVIGRID_SHARED)")
    return path


@pytest.fixture(scope="session")
def vectors(shared: Path) -> List[Any]:
    """The belief-function test vectors of the shared data."""
    with open(shared / "vectors" / "belief-vectors.json", encoding="utf-8") as file:
        return json.load(file)["vectors"]


@pytest.fixture(scope="session")
def kitti(shared: Path) -> Path:
    """The shared KITTI raw drive (0013, 40 frames): its date folder."""
    path = shared / "data" / "lidar" / "kitti-raw-0013" / "2011_09_26"
    if not (path / "calib_imu_to_velo.txt").is_file():
        _missing(f"the KITTI raw drive at {path}")
    return path


class Cli:
    """Runs the `evigrid` command and reads its JSON output."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def json(self, *args: str) -> Any:
        done = subprocess.run(
            [str(self.path), *args], capture_output=True, text=True, timeout=600, check=False
        )
        assert done.returncode == 0, f"evigrid {' '.join(args)}: {done.stderr}"
        return json.loads(done.stdout)


@pytest.fixture(scope="session")
def cli() -> Cli:
    """The `evigrid` command."""
    path = Path(os.environ.get("EVIGRID_CLI", REPOSITORY / "target" / "debug" / "evigrid"))
    if not os.access(path, os.X_OK):
        _missing(f"the evigrid command at {path} (set EVIGRID_CLI)")
    return Cli(path)


@pytest.fixture(scope="session")
def cli_run(cli: Cli, kitti: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The output folder of `evigrid run` over the shared KITTI drive (defaults, no recording)."""
    out = tmp_path_factory.mktemp("cli-run") / "out"
    cli.json("run", "--drive", str(kitti), "--out", str(out), "--no-mcap", "--json")
    return out
