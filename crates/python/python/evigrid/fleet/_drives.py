"""The drives of a fleet: what the user gave (paths, dicts, list files) and the folder names.

No file of a drive is read here (a cluster's driver may not be where the drives are fastest to
read): a drive that cannot be opened fails in its own task, like any other failure.
"""

from __future__ import annotations

import os
import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Iterable, List, Mapping, Tuple, Union

from evigrid._errors import InputError

__all__ = ["DRIVE_OPTIONS", "DriveSpec", "drive_specs", "folder_names"]

DrivePath = Union[str, "os.PathLike[str]"]
DriveArg = Union[DrivePath, Mapping[str, Any]]

# The per-drive options of `evigrid.run` / `evigrid.open_drive`, as list-file flags; the ones
# naming files are resolved against the list file's folder.
DRIVE_OPTIONS: Dict[str, bool] = {
    "poses": True,
    "pose_format": False,
    "calib": True,
    "times": True,
    "mounting": False,
    "cloud_topic": False,
    "pose_source": False,
    "origin": False,
    "max_frames": False,
}

# The first bytes of an MCAP file: such a file is a drive, any other file a list of drives.
_MCAP_MAGIC = b"\x89MCAP0\r\n"

# File names the fleet writes into its folder, which a drive's folder must not take.
RESERVED = {"fleet.parquet", "fleet.md", "fleet.html", "fleet.svg"}


@dataclass(frozen=True)
class DriveSpec:
    """One drive of the fleet: the path as given, its absolute path, its per-drive options."""

    given: str
    """The path as the user gave it (a list file's entries joined to the list's folder)."""
    path: str
    """The absolute path the task opens."""
    options: Dict[str, Any] = field(default_factory=dict)
    """Keyword options of ``evigrid.run`` for this drive (``poses``, ``times``, …)."""


def drive_specs(drives: Iterable[DriveArg]) -> List[DriveSpec]:
    """The drives given: paths, dicts ``{"path": ..., "poses": ..., ...}``, or text files
    listing drives one a line (``PATH [--poses FILE] [--times FILE] ...``; ``#`` comments).

    # Errors
    ``evigrid.InputError`` naming the list file and line, or the dict, that cannot be read.
    """
    if isinstance(drives, (str, os.PathLike)):
        drives = [drives]
    specs: List[DriveSpec] = []
    for drive in drives:
        if isinstance(drive, Mapping):
            specs.append(_from_mapping(drive))
        elif isinstance(drive, (str, os.PathLike)):
            given = os.fspath(drive)
            if _is_list_file(given):
                specs.extend(_from_list_file(given))
            else:
                specs.append(DriveSpec(given, os.path.abspath(given)))
        else:
            raise InputError(
                f"drive {drive!r}: expected a path, a dict with a 'path', or a list file"
            )
    if not specs:
        raise InputError("no drive given")
    return specs


def _is_list_file(path: str) -> bool:
    """A regular file that is not an MCAP recording lists drives."""
    if not os.path.isfile(path):
        return False
    try:
        with open(path, "rb") as file:
            return file.read(len(_MCAP_MAGIC)) != _MCAP_MAGIC
    except OSError:
        return False


def _from_mapping(drive: Mapping[str, Any]) -> DriveSpec:
    options = dict(drive)
    path = options.pop("path", None)
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"drive {dict(drive)!r}: no 'path'")
    unknown = sorted(set(options) - set(DRIVE_OPTIONS))
    if unknown:
        raise InputError(
            f"drive {os.fspath(path)}: unknown option {unknown[0]!r} "
            f"(known: {', '.join(DRIVE_OPTIONS)})"
        )
    given = os.fspath(path)
    resolved = {
        key: os.path.abspath(os.fspath(value)) if DRIVE_OPTIONS[key] else value
        for key, value in options.items()
        if value is not None
    }
    return DriveSpec(given, os.path.abspath(given), resolved)


def _from_list_file(list_path: str) -> List[DriveSpec]:
    base = os.path.dirname(list_path)
    try:
        with open(list_path, encoding="utf-8") as file:
            lines = file.read().splitlines()
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"{list_path}: cannot be read as a list of drives: {error}") from None
    specs = []
    for number, line in enumerate(lines, start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        where = f"{list_path}:{number}"
        try:
            words = shlex.split(line, comments=True)
        except ValueError as error:
            raise InputError(f"{where}: {error}") from None
        path, options = words[0], _list_options(words[1:], where)
        drive: Dict[str, Any] = {"path": os.path.join(base, path)}
        for key, value in options.items():
            drive[key] = os.path.join(base, value) if DRIVE_OPTIONS[key] else value
        spec = _from_mapping(drive)
        specs.append(spec)
    return specs


def _list_options(words: List[str], where: str) -> Dict[str, Any]:
    options: Dict[str, Any] = {}
    flags = iter(words)
    for flag in flags:
        key = flag[2:].replace("-", "_") if flag.startswith("--") else ""
        if key not in DRIVE_OPTIONS:
            known = ", ".join("--" + k.replace("_", "-") for k in DRIVE_OPTIONS)
            raise InputError(f"{where}: unknown option {flag!r} (known: {known})")
        value = next(flags, None)
        if value is None:
            raise InputError(f"{where}: {flag} needs a value")
        if key == "max_frames":
            if not value.isdigit():
                raise InputError(f"{where}: --max-frames {value!r} is not a whole number")
            options[key] = int(value)
        else:
            options[key] = value
    return options


def folder_names(specs: List[DriveSpec]) -> List[str]:
    """One folder name per drive, unique: the drive's last path component (``.mcap`` dropped),
    with as many parent folders as it takes to tell apart drives of the same name
    (``part-1-2011_09_26``), then ``-2``, ``-3`` for a drive given twice.

    Names depend on the paths alone, so a rerun with the same drives finds the same folders.
    """
    parts = [_components(spec.path) for spec in specs]
    depth = [1] * len(specs)

    def name(i: int) -> str:
        return _clean("-".join(parts[i][-depth[i] :]))

    while True:
        groups: Dict[str, List[int]] = {}
        for i in range(len(specs)):
            groups.setdefault(name(i), []).append(i)
        deeper = [
            i
            for members in groups.values()
            if len(members) > 1
            for i in members
            if depth[i] < len(parts[i])
        ]
        if not deeper:
            break
        for i in deeper:
            depth[i] += 1
    names: List[str] = []
    seen: Dict[str, int] = {}
    for i in range(len(specs)):
        base = name(i)
        count = seen.get(base, 0) + 1
        seen[base] = count
        names.append(base if count == 1 else f"{base}-{count}")
    return names


def _components(path: str) -> Tuple[str, ...]:
    components = tuple(part for part in Path(path).parts if part not in ("/", ""))
    if not components:
        return ("drive",)
    last = components[-1]
    if last.lower().endswith(".mcap"):
        last = last[: -len(".mcap")] or "drive"
    return components[:-1] + (last,)


def _clean(name: str) -> str:
    """A folder name safe everywhere: letters, digits, ``.``, ``_`` and ``-``; never hidden nor
    one of the fleet's own files."""
    name = re.sub(r"[^A-Za-z0-9._-]", "_", name).lstrip(".") or "drive"
    return f"drive-{name}" if name in RESERVED else name
