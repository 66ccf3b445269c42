#!/usr/bin/env python3
"""Writes a synthetic script that repeats a trajectory script N times, for long-run measurements
(run-file size per simulated minute, writer memory over a 10-minute session; docs/hdf5-layout.md,
"Size").

    tools/loop_script.py trajectories/rotator_cuff_tour.yaml 18 -o /tmp/tour_x18.yaml
    build/src/cli/arthrosim run scenarios/rotator_cuff_repair.yaml \
        --trajectory /tmp/tour_x18.yaml --duration 600 --out /tmp/tour.h5

Loop k (0-based) starts at k * PERIOD seconds (default: the script's length rounded up to a whole
second, from the latest `at:` plus the durations after it): every `at:` of the copy is shifted by
that, and the first action of each track without an `at:` gets `at: k * PERIOD`. Names resolve
against the scenario as in the original; the script's noise profile and seed are kept.
"""
import argparse
import copy
import math
import sys

import yaml

TRACKS = ("camera", "slot0", "slot1")


def action_duration(action):
    """Length of one action (s): its `duration` (or a bare `wait` number), 0 when instant."""
    (kind, args), = action.items()
    if kind == "wait" and not isinstance(args, dict):
        return float(args)
    if isinstance(args, dict):
        return float(args.get("duration", 1.0 if kind in ("pick", "move", "withdraw") else 0.0))
    return 0.0


def track_end(track):
    """End time of a track (s): actions run one after another, `at:` delays a start."""
    t = 0.0
    for action in track:
        (_, args), = action.items()
        if isinstance(args, dict) and "at" in args:
            t = max(t, float(args["at"]))
        t += action_duration(action)
    return t


def shifted(track, offset):
    out = []
    for i, action in enumerate(copy.deepcopy(track)):
        (kind, args), = action.items()
        if not isinstance(args, dict):
            args = {"duration": float(args)}
            action = {kind: args}
        if "at" in args:
            args["at"] = round(float(args["at"]) + offset, 6)
        elif i == 0:
            args["at"] = round(offset, 6)
        out.append(action)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("script")
    ap.add_argument("loops", type=int)
    ap.add_argument("-o", "--out", required=True)
    ap.add_argument("--period", type=float, default=0, help="s between loop starts")
    a = ap.parse_args()
    with open(a.script, encoding="utf-8") as f:
        src = yaml.safe_load(f)
    period = a.period or math.ceil(max(track_end(src.get(k, [])) for k in TRACKS)) + 1
    out = {k: v for k, v in src.items() if k not in TRACKS}
    out["name"] = f"{src.get('name', 'script')}_x{a.loops}"
    out["description"] = f"{a.script} repeated {a.loops} times, every {period} s"
    for k in TRACKS:
        if k in src:
            out[k] = [x for loop in range(a.loops) for x in shifted(src[k], loop * period)]
    with open(a.out, "w", encoding="utf-8") as f:
        yaml.safe_dump(out, f, sort_keys=False)
    print(f"{a.out}: {a.loops} loops of {period} s = {a.loops * period} s", file=sys.stderr)


if __name__ == "__main__":
    main()
