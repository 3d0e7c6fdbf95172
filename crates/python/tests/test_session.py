"""evigrid.open_drive, evigrid.Session and evigrid.run over the shared KITTI drive: the numbers of
`evigrid run`, arrays of the documented shapes, the GIL released, errors for bad input."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import evigrid


def classes_json(out: Path) -> np.ndarray:
    with open(out / "classes.json", encoding="utf-8") as file:
        exported = json.load(file)
    return np.array(exported["data"], dtype=np.uint8).reshape(exported["height"], exported["width"])


def test_a_drive_is_an_iterable_of_frames(kitti):
    drive = evigrid.open_drive(kitti)
    assert len(drive) == 40
    assert drive.pose_matching == "time" and drive.poses.startswith("OXTS of")
    assert drive.ego_path.shape == (40, 2) and drive.ego_path.dtype == np.float64
    frames = iter(drive)
    first, second = next(frames), next(frames)
    assert first.points.dtype == np.float32 and first.points.ndim == 2 and first.points.shape[1] == 4
    assert len(first.points) == len(first) > 100_000
    # KITTI's Velodyne gives intensity in [0, 1] for every point.
    assert np.all((first.points[:, 3] >= 0) & (first.points[:, 3] <= 1))
    assert not first.points.flags.writeable
    pose = first.pose
    assert pose.shape == (4, 4) and pose.dtype == np.float64
    np.testing.assert_array_equal(pose[3], [0, 0, 0, 1])
    np.testing.assert_allclose(pose[:3, :3].T @ pose[:3, :3], np.eye(3), atol=1e-9)
    # The first pose sits at the first fix, the origin of the local frame (the Velodyne's lever
    # arm aside).
    assert np.hypot(*pose[:2, 3]) < 2.0
    # KITTI's Velodyne spins at 10 Hz.
    assert second.time - first.time == pytest.approx(0.1, abs=0.01)
    assert (first.index, second.index) == (0, 1) and first.name.endswith(".bin")
    assert sum(1 for _ in drive) == 40  # each iteration starts again


def test_the_final_decision_equals_the_commands_cell_for_cell(kitti, cli_run):
    drive = evigrid.open_drive(kitti)
    session = evigrid.Session()
    result = None
    for frame in drive:
        result = session.step(frame)
    assert result is not None and session.frames == 40
    want = classes_json(cli_run)
    got = result.classes
    assert got.dtype == np.uint8 and got.shape == want.shape
    differ = int(np.count_nonzero(got != want))
    assert differ == 0, f"{differ} of {want.size} cells differ from the command's classes.json"
    # The summary's figures are the command's too.
    with open(cli_run / "summary.json", encoding="utf-8") as file:
        cli_summary = json.load(file)
    summary = session.summary()
    for key in ("frames", "points", "final_classes", "moving_trace_cells", "dropped_outside_window",
                "scans", "poses", "pose_matching", "skipped_scans"):
        assert summary[key] == cli_summary[key], key
    for key in ("cell_frames", "occupied", "moving", "moving_along_path"):
        assert summary["ego_path"][key] == cli_summary["ego_path"][key], f"ego_path.{key}"


def test_scans_placed_by_the_odometry_are_stepped_as_the_command_runs_them(shared, cli, tmp_path):
    # Scans without poses: the lidar odometry places them, and the command then turns the pose
    # refinement off (a second registration of the same scans). A session stepping the drive's
    # frames does the same, and its summary names the drive as the command's does.
    scans = shared / "data" / "lidar" / "kitti-city-22"
    out = tmp_path / "out"
    cli.json("run", "--scans", str(scans), "--max-frames", "6", "--out", str(out), "--no-mcap", "--json")
    with open(out / "summary.json", encoding="utf-8") as file:
        want = json.load(file)
    session = evigrid.Session()
    for frame in evigrid.open_drive(scans, max_frames=6):
        result = session.step(frame)
    summary = session.summary()
    assert want["params"]["localisation"]["refinement"] == "none"
    assert summary["params"]["localisation"] == want["params"]["localisation"]
    for key in ("scans", "poses", "pose_matching", "frames", "points", "final_classes", "skipped_scans"):
        assert summary[key] == want[key], key
    assert summary["pose_matching"] == "odometry"
    differ = int(np.count_nonzero(result.classes != classes_json(out)))
    assert differ == 0, f"{differ} cells differ from the command's classes.json"


def test_a_steps_grids_have_the_documented_shapes_and_masses_sum_to_one(kitti):
    session = evigrid.Session()
    frames = iter(evigrid.open_drive(kitti, max_frames=3))
    for frame in frames:
        result = session.step(frame)
    height, width = result.classes.shape
    assert (height, width) == (320, 320) and result.cell_size == 0.5
    masses = result.masses
    assert masses.shape == (height, width, 32) and masses.dtype == np.float32
    assert np.all(masses >= 0)
    np.testing.assert_allclose(masses.sum(axis=2), 1.0, atol=1e-5)
    betp = result.betp
    assert betp.shape == (height, width, 5) and betp.dtype == np.float32
    np.testing.assert_allclose(betp.sum(axis=2), 1.0, atol=1e-4)
    velocity = result.velocity
    assert velocity.shape == (height, width, 2) and velocity.dtype == np.float32
    assert np.all(np.isfinite(velocity))
    # Seen cells: a decision other than unknown where m(Ω) is low.
    assert set(np.unique(result.classes)) <= {0, 1, 2, 3, 4, 5}
    assert np.count_nonzero(result.classes == 1) > 1000
    # Free cells carry most of their mass on {F}: set 1.
    free = result.classes == 1
    assert float(np.mean(masses[free][:, 1])) > 0.5
    # The window is centred on the sensor: its origin half a window south-west of the pose.
    east, north = result.origin
    pose = frame.pose
    assert east <= pose[0, 3] <= east + width * result.cell_size
    assert north <= pose[1, 3] <= north + height * result.cell_size
    assert isinstance(result.objects, list)
    assert result.record["scan"] == frame.name
    assert not masses.flags.writeable
    assert result.masses is masses  # kept after the first read


def test_a_result_read_after_the_next_step_is_refused(kitti):
    session = evigrid.Session()
    frames = iter(evigrid.open_drive(kitti, max_frames=2))
    first = session.step(next(frames))
    classes = first.classes  # read in time: kept
    session.step(next(frames))
    assert first.classes is classes
    with pytest.raises(evigrid.InputError, match="stale"):
        first.masses


def test_stepping_arrays_gives_the_numbers_of_stepping_frames(kitti):
    by_frame, by_arrays = evigrid.Session(), evigrid.Session()
    for frame in evigrid.open_drive(kitti, max_frames=3):
        a = by_frame.step(frame)
        b = by_arrays.step(frame.points, frame.pose, frame.time, name=frame.name)
    np.testing.assert_array_equal(a.classes, b.classes)
    np.testing.assert_array_equal(a.masses, b.masses)
    # Three columns (no intensity) are accepted too, and float64 points.
    c = evigrid.Session().step(np.asarray(frame.points[:, :3], dtype=np.float64), frame.pose, frame.time)
    assert c.classes.shape == a.classes.shape


def test_kurdej2013_has_no_velocity_and_a_config_dict_is_the_toml_layout(kitti):
    session = evigrid.Session({"window": {"width_cells": 64, "height_cells": 48}}, method="kurdej2013")
    result = session.step(next(iter(evigrid.open_drive(kitti, max_frames=1))))
    assert result.classes.shape == (48, 64)
    assert result.velocity is None
    assert session.summary()["method"] == "kurdej2013"
    assert session.summary()["params"]["window"]["width_cells"] == 64


def test_run_writes_every_output_of_the_command(kitti, cli_run, tmp_path):
    out = tmp_path / "out"
    summary = evigrid.run(kitti, out=out, mcap=False)
    assert summary["complete"] and summary["frames"] == 40
    wanted = sorted(p.relative_to(cli_run).as_posix() for p in cli_run.rglob("*") if p.is_file())
    written = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    assert written == wanted
    np.testing.assert_array_equal(classes_json(out), classes_json(cli_run))
    with open(out / "summary.json", encoding="utf-8") as file:
        assert json.load(file)["final_classes"] == summary["final_classes"]
    # Run again into its own folder: allowed, the old outputs replaced.
    again = evigrid.run(kitti, out=out, mcap=False, max_frames=2)
    assert again["frames"] == 2
    # Without out nothing is written and the summary is the same.
    assert evigrid.run(kitti, out=None)["final_classes"] == summary["final_classes"]


def test_run_refuses_a_folder_of_someone_elses_files(kitti, tmp_path):
    (tmp_path / "thesis.tex").write_text("precious", encoding="utf-8")
    with pytest.raises(evigrid.InputError, match="is not an evigrid output folder"):
        evigrid.run(kitti, out=tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thesis.tex"]


def test_ctrl_c_in_a_long_run_finishes_the_outputs_then_raises_keyboard_interrupt(kitti, tmp_path):
    out = tmp_path / "out"
    timer = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt) as raised:
            evigrid.run(kitti, out=out, mcap=False, config={"window": {"width_cells": 1000, "height_cells": 1000}})
    finally:
        timer.cancel()
    summary = raised.value.summary
    assert summary["complete"] is False and "interrupted" in summary["stopped"]
    assert 0 < summary["frames"] < 40
    with open(out / "summary.json", encoding="utf-8") as file:
        assert json.load(file)["frames"] == summary["frames"]
    assert (out / "classes.json").is_file()
    assert not list(out.rglob("*.tmp*")), "a temporary file was left"


def test_a_run_asked_to_stop_by_its_stop_callable_finishes_the_outputs_and_returns(
    kitti, tmp_path
):
    out = tmp_path / "out"
    asked = []

    def stop() -> bool:
        asked.append(time.monotonic())
        log = out / "frames.jsonl"
        return log.is_file() and log.read_text().count("\n") >= 3

    summary = evigrid.run(kitti, out=out, mcap=False, stop=stop)
    assert summary["complete"] is False and summary["stopped"] == "interrupted (stop requested)"
    assert 3 <= summary["frames"] < 40
    with open(out / "summary.json", encoding="utf-8") as file:
        assert json.load(file)["frames"] == summary["frames"]
    assert (out / "classes.json").is_file()
    assert not list(out.rglob("*.tmp*")), "a temporary file was left"
    # Asked every 50 ms, not after the stop.
    assert len(asked) >= 2 and max(b - a for a, b in zip(asked, asked[1:])) < 1.0


def test_a_run_whose_stop_callable_never_says_stop_is_complete(kitti):
    summary = evigrid.run(kitti, out=None, max_frames=5, stop=lambda: False)
    assert summary["complete"] is True and summary["frames"] == 5


def test_what_the_stop_callable_raises_stops_the_run_and_is_raised_with_the_summary(
    kitti, tmp_path
):
    def stop() -> bool:
        raise RuntimeError("the stop callable's own error")

    with pytest.raises(RuntimeError, match="the stop callable's own error") as raised:
        evigrid.run(kitti, out=tmp_path / "out", mcap=False, stop=stop)
    assert raised.value.summary["complete"] is False
    assert raised.value.summary["frames"] < 40


def test_a_stop_that_is_not_callable_is_an_input_error(kitti, tmp_path):
    with pytest.raises(evigrid.InputError, match="stop: must be a callable"):
        evigrid.run(kitti, out=tmp_path / "out", stop=True)
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="thread names from /proc")
@pytest.mark.parametrize("threads", [1, 2])
def test_a_run_with_threads_runs_on_a_pool_of_that_many_threads_and_decides_the_same(
    kitti, threads
):
    seen = set()

    def threads_now() -> bool:
        # Asked every 50 ms while the drive runs: the names of this process's threads.
        for task in os.listdir("/proc/self/task"):
            try:
                with open(f"/proc/self/task/{task}/comm", encoding="utf-8") as file:
                    seen.add(file.read().strip())
            except OSError:
                pass
        return False

    summary = evigrid.run(kitti, out=None, max_frames=12, threads=threads, stop=threads_now)
    assert {name for name in seen if name.startswith(f"evigrid-p{threads}-")} == {
        f"evigrid-p{threads}-{k}" for k in range(threads)
    }
    assert summary["final_classes"] == evigrid.run(kitti, out=None, max_frames=12)["final_classes"]


def test_threads_0_is_an_input_error(kitti):
    with pytest.raises(evigrid.InputError, match="threads 0: must be 1 or more"):
        evigrid.run(kitti, out=None, threads=0)


def test_the_gil_is_released_while_a_session_steps(kitti):
    frames = list(evigrid.open_drive(kitti, max_frames=4))
    session = evigrid.Session({"window": {"width_cells": 1000, "height_cells": 1000}})
    counted = 0
    stepping = threading.Event()
    done = threading.Event()

    def count() -> None:
        nonlocal counted
        stepping.wait()
        while not done.is_set():
            counted += 1

    counter = threading.Thread(target=count)
    counter.start()
    stepping.set()
    started = time.perf_counter()
    for frame in frames:
        session.step(frame)
    seconds = time.perf_counter() - started
    done.set()
    counter.join()
    # Python ran the counting loop while Rust stepped: far more than the switches of a held GIL.
    assert counted > 1000, f"{counted} iterations in {seconds:.2f} s of stepping"


TWO_SESSIONS = """
import json, sys, threading, time
import evigrid
frames = list(evigrid.open_drive(sys.argv[1], max_frames=int(sys.argv[2])))
finals = []
def drive():
    session = evigrid.Session()
    for frame in frames:
        result = session.step(frame)
    finals.append(result.classes.tobytes())
def both():
    threads = [threading.Thread(target=drive) for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
def timed(work):
    started = time.perf_counter()
    work()
    return time.perf_counter() - started
drive()  # warm the caches
# Interleaved rounds, the best of each: a busy machine only ever slows a round down.
rounds = [(timed(lambda: (drive(), drive())), timed(both)) for _ in range(3)]
print(json.dumps({
    "serial": min(r[0] for r in rounds),
    "parallel": min(r[1] for r in rounds),
    "same": len(set(finals)) == 1 and len(finals) == 13,
}))
"""


def test_two_sessions_in_two_threads_run_together_and_agree(kitti):
    done = subprocess.run(
        [sys.executable, "-c", TWO_SESSIONS, str(kitti), "8"],
        capture_output=True, text=True, timeout=600, check=True,
    )
    times = json.loads(done.stdout)
    ratio = times["parallel"] / times["serial"]
    # Printed, not asserted: on two cores the step already spreads over both (rayon), so the
    # gain of a second thread is the overlap of the steps' serial parts, and a machine shared
    # with other work decides it. test_the_gil_is_released_while_a_session_steps asserts what
    # the binding controls.
    print(f"two sessions (best of 3): serial {times['serial']:.2f} s, "
          f"two threads {times['parallel']:.2f} s, ratio {ratio:.2f}")
    assert times["same"], "sessions stepped in parallel decided differently from one alone"


BAD_STEPS = [
    ("points of 2 columns", lambda f: (np.zeros((5, 2)), f.pose, f.time), "2 columns"),
    ("points of one dimension", lambda f: (np.zeros(5), f.pose, f.time), "N × 3 or N × 4"),
    ("points as text", lambda f: ([["a", "b", "c"]], f.pose, f.time), "points"),
    ("pose 3 × 3", lambda f: (f.points, np.eye(3), f.time), "4 × 4"),
    ("pose not rigid", lambda f: (f.points, np.diag([2.0, 1.0, 1.0, 1.0]), f.time), "not a rotation"),
    ("pose mirrored", lambda f: (f.points, np.diag([-1.0, 1.0, 1.0, 1.0]), f.time), "not a rotation"),
    ("pose with NaN", lambda f: (f.points, np.full((4, 4), np.nan), f.time), "not finite"),
    ("projective pose", lambda f: (f.points, np.vstack([np.eye(4)[:3], [0, 0, 1, 1]]), f.time), "last row"),
    ("time NaN", lambda f: (f.points, f.pose, float("nan")), "time NaN"),
]


@pytest.mark.parametrize("case, arguments, needle", BAD_STEPS, ids=[c[0] for c in BAD_STEPS])
def test_bad_arrays_are_input_errors(kitti, case, arguments, needle):
    frame = next(iter(evigrid.open_drive(kitti, max_frames=1)))
    session = evigrid.Session()
    with pytest.raises(evigrid.InputError, match=needle):
        session.step(*arguments(frame))
    assert session.frames == 0


def test_a_frame_going_back_in_time_is_refused_and_the_grids_kept(kitti):
    frames = list(evigrid.open_drive(kitti, max_frames=2))
    session = evigrid.Session()
    session.step(frames[1])
    with pytest.raises(evigrid.InputError):
        session.step(frames[0])
    assert session.frames == 1
    assert [s["scan"] for s in session.summary()["skipped_scans"]] == [frames[0].name]


def test_bad_sessions_and_drives_are_errors_naming_the_input(kitti, tmp_path):
    (tmp_path / "empty").mkdir()
    bad_toml = tmp_path / "bad.toml"
    bad_toml.write_text("[sensor]\nmu_free = 1.5\n", encoding="utf-8")
    cases = [
        (lambda: evigrid.Session({"sensor": {"mu_fre": 0.5}}), evigrid.InputError, "mu_fre"),
        (lambda: evigrid.Session({"sensor": {"mu_free": 2.0}}), evigrid.InputError, "sensor.mu_free"),
        (lambda: evigrid.Session({"window": {"width_cells": 5000, "height_cells": 5000}}), evigrid.InputError, "memory budget"),
        (lambda: evigrid.Session(bad_toml), evigrid.InputError, "bad.toml"),
        (lambda: evigrid.Session(tmp_path / "missing.toml"), evigrid.FileError, "missing.toml"),
        (lambda: evigrid.Session(method="moras"), evigrid.InputError, "method 'moras'|method \"moras\""),
        (lambda: evigrid.Session(origin=(91.0, 0.0)), evigrid.InputError, "origin"),
        (lambda: evigrid.Session(map=tmp_path / "missing.osm"), evigrid.Error, "missing.osm"),
        (lambda: evigrid.open_drive(tmp_path / "nowhere"), evigrid.FileError, "nowhere: does not exist"),
        (lambda: evigrid.open_drive(tmp_path / "empty"), evigrid.InputError, "no .pcd or .bin scans"),
        (lambda: evigrid.open_drive(kitti, pose_format="ply"), evigrid.InputError, "pose_format"),
        (lambda: evigrid.open_drive(kitti, cloud_topic="/points"), evigrid.InputError, "cloud_topic"),
        (lambda: evigrid.open_drive(kitti, poses=tmp_path / "missing.txt"), evigrid.Error, "missing.txt"),
        (lambda: evigrid.open_drive(kitti, mounting="1,2,3"), evigrid.InputError, "mounting"),
        (lambda: evigrid.run(kitti, out=tmp_path / "o", method="moras"), evigrid.InputError, "method"),
    ]
    for call, kind, needle in cases:
        with pytest.raises(kind, match=needle):
            call()
