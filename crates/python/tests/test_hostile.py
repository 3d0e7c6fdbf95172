"""The hostile inputs of the command's own campaign (crates/cli/tests/hostile.rs, issue 15) through
the package: each an evigrid.Error naming the input, never an abort of the interpreter."""

from __future__ import annotations

from pathlib import Path

import pytest

import evigrid


def pcd(header_lines: str, data: str) -> str:
    return (
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        f"{header_lines}\nVIEWPOINT 0 0 0 1 0 0 0\nDATA {data}"
    )


HOSTILE_SCANS = [
    ("points-4e9", pcd("WIDTH 1\nHEIGHT 1\nPOINTS 4000000000", "ascii\n1 2 3\n")),
    ("points-max", pcd("WIDTH 1\nHEIGHT 1\nPOINTS 18446744073709551615", "ascii\n1 2 3\n")),
    ("wh-4e9", pcd("WIDTH 4000000000\nHEIGHT 4000000000", "ascii\n1 2 3\n")),
    ("points-disagree", pcd("WIDTH 2\nHEIGHT 1\nPOINTS 2", "ascii\n1 2 3\n")),
    ("size", pcd("WIDTH 1\nHEIGHT 1\nPOINTS 1", "binary\n0123456789ab").replace("SIZE 4 4 4", "SIZE 4 4 18446744073709551612")),
    ("count", pcd("WIDTH 1\nHEIGHT 1\nPOINTS 1", "ascii\n1 2 3\n").replace("COUNT 1 1 1", "COUNT 1 1 1000000000000")),
]


def folder(tmp_path: Path, name: str, content: str) -> Path:
    scans = tmp_path / name
    scans.mkdir()
    (scans / "a.pcd").write_text(content, encoding="utf-8")
    return scans


@pytest.mark.parametrize("name, content", HOSTILE_SCANS, ids=[c[0] for c in HOSTILE_SCANS])
def test_a_hostile_scan_is_an_input_error_naming_it(tmp_path, name, content):
    scans = folder(tmp_path, name, content)
    poses = tmp_path / "p.txt"
    poses.write_text("0 0 0 0 0 0 0\n", encoding="utf-8")
    with pytest.raises(evigrid.InputError, match="a.pcd"):
        evigrid.run(scans, poses=poses, out=tmp_path / "o")
    drive = evigrid.open_drive(scans, poses=poses)
    assert list(drive) == []
    assert [s["scan"] for s in drive.skipped] == ["a.pcd"]
    with pytest.raises(evigrid.InputError, match="a.pcd"):
        list(evigrid.open_drive(scans, poses=poses, strict=True))


@pytest.mark.parametrize("width, height", [(4294967296, 1), (100000, 100000), (5000, 5000)])
def test_a_window_beyond_the_memory_budget_is_refused(tmp_path, width, height):
    config = tmp_path / "w.toml"
    config.write_text(f"[window]\nwidth_cells = {width}\nheight_cells = {height}\n", encoding="utf-8")
    with pytest.raises(evigrid.InputError, match="w.toml"):
        evigrid.Session(config)
    with pytest.raises(evigrid.InputError):
        evigrid.Session({"window": {"width_cells": width, "height_cells": height}})


def test_a_map_that_cannot_be_read_is_an_input_error_naming_it(tmp_path):
    broken = tmp_path / "broken.geojson"
    broken.write_text('{"type":"FeatureCollection","features":[{"type":"Feat', encoding="utf-8")
    with pytest.raises(evigrid.InputError, match="broken.geojson"):
        evigrid.Session(map=broken)
    not_a_map = tmp_path / "scan.pcd"
    not_a_map.write_bytes(b"\x00\x01garbage")
    with pytest.raises(evigrid.InputError, match="scan.pcd"):
        evigrid.Session(map=not_a_map)


def _snapshot(root: Path) -> dict:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()}


@pytest.mark.parametrize("force", [False, True])
def test_run_never_writes_onto_an_input_or_a_file_even_with_force(tmp_path, force):
    # Issue 31: the output policy of the command, in evigrid.run too.
    scans = folder(tmp_path, "scans", pcd("WIDTH 1\nHEIGHT 1\nPOINTS 1", "ascii\n5 1 0.5\n"))
    beside = tmp_path / "beside"
    beside.mkdir()
    poses = beside / "p.txt"
    poses.write_text("0 0 0 0 0 0 0\n", encoding="utf-8")
    # The scans' folder itself, a folder holding the pose file, the pose file, a link to it;
    # an existing file that is no input is refused too (not a folder), forced or not.
    (tmp_path / "notes.txt").write_text("mine", encoding="utf-8")
    (tmp_path / "link.txt").symlink_to(poses)
    before = _snapshot(tmp_path)
    for out, why in [
        (scans, "is the input"),
        (beside, "holds the input"),
        (poses, "is the input"),
        (tmp_path / "link.txt", "is the input"),
        (tmp_path / "notes.txt", "exists and is not a folder"),
    ]:
        with pytest.raises(evigrid.InputError, match=why) as raised:
            evigrid.run(scans, poses=poses, out=out, force=force)
        assert isinstance(raised.value, evigrid.Error)
        assert str(out) in str(raised.value)
    assert _snapshot(tmp_path) == before


def test_run_writes_into_a_folder_of_someone_elses_files_only_with_force(tmp_path):
    scans = folder(tmp_path, "scans", pcd("WIDTH 1\nHEIGHT 1\nPOINTS 1", "ascii\n5 1 0.5\n"))
    poses = tmp_path / "p.txt"
    poses.write_text("0 0 0 0 0 0 0\n", encoding="utf-8")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("precious", encoding="utf-8")
    with pytest.raises(evigrid.InputError, match="force=True"):
        evigrid.run(scans, poses=poses, out=mine)
    assert sorted(p.name for p in mine.iterdir()) == ["thesis.tex"]
    # Forced, the folder is taken (its marker written) and the user's file stays; whether the
    # one-point drive then runs to its end is not this test's matter.
    try:
        evigrid.run(scans, poses=poses, out=mine, force=True)
    except evigrid.InputError as error:
        assert "force" not in str(error)
    assert (mine / ".evigrid-output").is_file()
    assert (mine / "thesis.tex").read_text(encoding="utf-8") == "precious"
