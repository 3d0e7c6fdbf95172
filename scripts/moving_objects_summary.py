#!/usr/bin/env python3
"""Summarise the moving-object list of an `evigrid run` (its `frames.jsonl`) against issue 30's
checks for a real drive.

    python3 scripts/moving_objects_summary.py OUT_DIR/frames.jsonl [--max-speed 25] [--json]

Counts the object-frames listed as moving (held-back objects apart), the distinct ids, those
faster than `--max-speed` (the run's `[motion] max_speed_mps`), those without a velocity or σ,
the blips (object-frames of ids listed moving in at most two frames) and the longest tracks (the
number of frames each id is listed moving). Standard library only.
"""
import argparse
import collections
import json
import math
import sys


def summarise(lines, max_speed_mps):
    frames_of = collections.Counter()
    held_back = faster = without_velocity = 0
    for number, line in enumerate(lines, 1):
        try:
            frame = json.loads(line)
        except json.JSONDecodeError as e:
            raise ValueError(f"line {number}: not JSON ({e.msg})") from None
        for obj in frame.get("moving_objects") or []:
            if obj.get("held_back"):
                held_back += 1
                continue
            frames_of[obj["id"]] += 1
            velocity = obj.get("velocity_mps")
            if velocity is None or obj.get("sigma_mps") is None:
                without_velocity += 1
            elif math.hypot(*velocity) > max_speed_mps:
                faster += 1
    object_frames = sum(frames_of.values())
    blips = sum(n for n in frames_of.values() if n <= 2)
    return {
        "object_frames": object_frames,
        "ids": len(frames_of),
        "held_back_object_frames": held_back,
        "faster_than_max_speed": faster,
        "without_velocity": without_velocity,
        "blip_object_frames": blips,
        "blip_share": blips / object_frames if object_frames else 0.0,
        "longest_tracks_frames": sorted(frames_of.values(), reverse=True)[:5],
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("frames", help="frames.jsonl of an `evigrid run` output folder")
    ap.add_argument("--max-speed", type=float, default=25.0, help="the run's max_speed_mps")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    try:
        with open(a.frames, encoding="utf-8") as f:
            s = summarise(f, a.max_speed)
    except (OSError, ValueError, KeyError, TypeError) as e:
        print(f"error: {a.frames}: {e}", file=sys.stderr)
        sys.exit(2)
    if a.json:
        print(json.dumps(s))
        return
    print(f"{s['object_frames']} moving object-frames from {s['ids']} ids "
          f"({s['held_back_object_frames']} held back)")
    print(f"faster than {a.max_speed:g} m/s: {s['faster_than_max_speed']}; "
          f"without a velocity: {s['without_velocity']}")
    print(f"blips (ids moving in <= 2 frames): {s['blip_object_frames']} "
          f"({100 * s['blip_share']:.1f} %)")
    print("longest tracks (frames):", ", ".join(map(str, s["longest_tracks_frames"])))


if __name__ == "__main__":
    main()
