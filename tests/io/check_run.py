#!/usr/bin/env python3
"""Checks a run file of the synthetic io test (tests/io/run_fixture.cpp) with h5py alone.

usage: check_run.py RUN.h5 --frames N        (exactly N frames, closed file)
       check_run.py RUN.h5 --min-frames N    (SWMR read of a killed writer: at least N frames)
Exit status 0 when every shape and value matches the fixture's formulas, 1 otherwise.
"""
import argparse
import math
import sys

import h5py
import numpy as np

from check_report import report

failures = []
POSITION_BOUND = 0.005  # mm: RunWriterOptions::position_tolerance_mm (default)


def check(cond, what):
    if not cond:
        failures.append(what)


def close(a, b, what, tol=1e-12):
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    ok = a.shape == b.shape and np.allclose(a, b, rtol=0, atol=tol, equal_nan=True)
    check(ok, f"{what}: got {a.tolist()} want {b.tolist()}")


def cube_rest():
    return np.array([[10.0 * (i & 1), 10.0 * ((i >> 1) & 1), 10.0 * ((i >> 2) & 1)]
                     for i in range(8)])


def moved(rest, f):
    i = np.arange(len(rest), dtype=float)
    return rest + np.stack([0.1 * f + 0 * i, 0.01 * f * i, -0.05 * f * f + 0 * i], axis=1)


CUBE_TETS = [[1, 2, 4, 7], [0, 1, 2, 4], [3, 2, 1, 7], [5, 1, 4, 7], [6, 4, 2, 7]]
SPLIT_TETS = [[8, 2, 4, 7], [1, 8, 4, 7], [1, 2, 8, 7], [1, 2, 4, 8]]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("run")
    ap.add_argument("--frames", type=int)
    ap.add_argument("--min-frames", type=int)
    args = ap.parse_args()

    with h5py.File(args.run, "r", swmr=args.min_frames is not None) as h:
        T = h["time"].shape[0]
        if args.frames is not None:
            check(T == args.frames, f"/time has {T} frames, want {args.frames}")
        if args.min_frames is not None:
            check(T >= args.min_frames, f"/time has {T} frames, want >= {args.min_frames}")
            # A killed writer may leave datasets one frame apart: use the common prefix.
            T = min(d.shape[0] for d in [h["time"], h["step"], h["bodies/cuff/positions_offset"],
                                         h["tools/grasper/pose"], h["events_end"]])
        check(h.attrs["format"] == "arthrosim-run", "format attribute")
        check(h.attrs["scenario_name"] == "io-synthetic", "scenario_name")
        check(len(h.attrs["scenario_sha256"]) == 64, "scenario_sha256 is 64 hex chars")
        close(h.attrs["dt"], 0.01, "dt")
        check(isinstance(h.attrs["arthrosim_version"], str), "arthrosim_version")
        yaml = h["meta/scenario_yaml"][()]
        yaml = yaml.decode() if isinstance(yaml, bytes) else yaml
        check(yaml.startswith("name: io-synthetic\n"), "scenario_yaml text")
        for key in ["compiler", "cxx_flags", "build_type", "hdf5_version", "created_utc"]:
            check(key in h["meta"].attrs, f"/meta attribute {key}")

        f = np.arange(T)
        close(h["step"][:T], 2 * f, "/step")
        close(h["time"][:T], 0.01 * (2 * f), "/time")
        check(h["step"].dtype == np.int64 and h["time"].dtype == np.float64, "time/step dtypes")

        cuff = h["bodies/cuff"]
        check(cuff["positions"].dtype == np.float64, "positions dtype")
        check(cuff["positions"].ndim == 2 and cuff["positions"].shape[1] == 3,
              "positions is a [P, 3] block series")
        check(cuff["elements"].dtype == np.int32 and cuff["elements"].shape[1] == 4,
              "elements is [E, 4] int32")
        check(cuff["element_alive"].dtype == np.uint8, "element_alive uint8")
        for t in range(T):
            n = 9 if t >= 6 else 8
            e = 9 if t >= 6 else 5
            check(cuff["node_count"][t] == n, f"cuff node_count[{t}]")
            check(cuff["element_count"][t] == e, f"cuff element_count[{t}]")
            rest = cube_rest()
            if t >= 6:
                rest = np.vstack([rest, [5, 5, 5]])
            o, c = cuff["positions_offset"][t], cuff["positions_count"][t]
            check(c == n, f"cuff positions_count[{t}]")
            # Stored quantised and held within the tolerance (docs/hdf5-layout.md): 5 um.
            close(cuff["positions"][o:o + c], moved(rest, t), f"cuff positions[{t}]",
                  tol=POSITION_BOUND)
            alive = np.ones(e, dtype=np.uint8)
            if t >= 3:
                alive[4] = 0
            if t >= 6:
                alive[0] = 0
            close(cuff["element_alive"][t, :e], alive, f"cuff element_alive[{t}]")
            # Alive-element blocks: the alive rows of /elements, in order.
            o, c = cuff["alive_elements_offset"][t], cuff["alive_elements_count"][t]
            want = np.asarray(CUBE_TETS + (SPLIT_TETS if t >= 6 else []))[alive == 1]
            close(cuff["alive_elements"][o:o + c], want, f"cuff alive_elements[{t}]")
        if T >= 7:
            close(cuff["elements"][:], CUBE_TETS + SPLIT_TETS, "cuff elements (initial + split)")
            # Alive set changes at frames 3 and 6 only: three blocks.
            check(len(set(cuff["alive_elements_offset"][:T].tolist())) == 3, "alive blocks")
        biceps = h["bodies/biceps"]
        check(biceps.attrs["index"] == 1 and cuff.attrs["index"] == 0, "body index attributes")
        # Blocks are stored once: one block for a static body (rows after it are the zero rows
        # that fill a chunk before a flush; no frame refers to them).
        check(len(set(biceps["positions_offset"][:T].tolist())) == 1 and
              biceps["positions_offset"][0] == 0, "static body's points written once")

        th = h["threads/suture"]
        for t in range(T):
            rest = np.array([[2.0 * i, -5.0, 0.0] for i in range(6)])
            want = rest + np.array([[0.0, 0.2 * t, 0.3 * i * t] for i in range(6)])
            o, c = th["positions_offset"][t], th["positions_count"][t]
            close(th["positions"][o:o + c], want, f"thread positions[{t}]", tol=POSITION_BOUND)
            alive = np.ones(6)
            if t >= 5:
                alive[3] = 0
            close(th["node_alive"][t], alive, f"thread node_alive[{t}]")
            c = th["alive_segments_count"][t]
            check(c == (3 if t >= 5 else 5), f"thread alive segments at {t}")

        bone = h["bones/humerus"]
        for t in range(T):
            nv = 5 if t >= 7 else 4
            nt = 6 if t >= 7 else 4
            check(bone["vertices_count"][t] == nv, f"bone vertex count[{t}]")
            check(bone["triangles_count"][t] == nt, f"bone triangle count[{t}]")
            o = bone["vertices_offset"][t]
            v0 = [0.5, 0.5, -10.5] if t >= 4 else [0, 0, -10]
            close(bone["vertices"][o], v0, f"bone vertex 0 at {t}")
            close(bone["removed_volume"][t], 0.25 * (t - 3) if t >= 4 else 0.0,
                  f"removed_volume[{t}]")
        if T >= 8:
            # Surface versions: frames 0-3, 4-6 (moved vertex), 7- (edge split).
            check(len(set(bone["vertices_offset"][:T].tolist())) == 3,
                  "bone vertex blocks written on change")
            check(len(set(bone["triangles_offset"][:T].tolist())) == 2,
                  "bone triangle blocks written on change")

        g = h["tools/grasper"]
        check(g["pose"].shape[1:] == (7,) and g["force"].shape[1:] == (3,), "tool shapes")
        for t in range(T):
            active = 1 if t >= 2 else 0
            check(g["active"][t] == active, f"grasper active[{t}]")
            if active:
                a = 0.05 * t
                close(g["pose"][t], [1 + t, 2, 3, math.cos(a), 0, 0, math.sin(a)],
                      f"grasper pose[{t}]")
                close(g["jaw"][t], 0.1 * t, f"grasper jaw[{t}]")
                close(g["force"][t], [0.5 * t, 0, -t], f"grasper force[{t}]")
                check(g["buttons"][t] == t % 4, f"grasper buttons[{t}]")
                check(g["slot"][t] == 0, f"grasper slot[{t}]")
            else:
                check(np.all(np.isnan(g["pose"][t])), f"inactive grasper pose NaN at {t}")
                check(g["slot"][t] == -1, f"grasper slot[{t}] = -1")
        burr = h["tools/burr"]
        close(burr["active"][:T], [1 if 4 <= t <= 7 else 0 for t in range(T)], "burr active")
        check(not np.any(h["tools/scissors/active"][:T]), "scissors never active")
        close(h["tool_slots/instrument"][:T],
              [[0 if t >= 2 else -1, 1 if 4 <= t <= 7 else -1] for t in range(T)],
              "tool_slots/instrument")

        close(h["camera/pose"][:T], [[0, 0, 50 + t, 1, 0, 0, 0] for t in range(T)], "camera")
        close(h["camera/lens_roll"][:T], 0.01 * f, "lens_roll")
        close(h["camera/head_roll"][:T], -0.02 * f, "head_roll")

        k = h["constraints"]
        for t in range(T):
            o, c = k["rows_offset"][t], k["rows_count"][t]
            rows = k["rows"][o:o + c]
            want = ([1] if 3 <= t < 8 else []) + ([2] if t >= 6 else [])
            check(rows["id"].tolist() == want, f"constraint ids at {t}: {rows['id'].tolist()}")
            for r in rows:
                if r["id"] == 2:
                    check(r["tag"] == b"suture", "suture tag")
                    close(r["b"]["weights"], [0.25] * 4, "suture weights")
                    check(r["a"]["kind"] == 2, "suture end a is a thread")

        ev = h["events"]
        end = int(h["events_end"][T - 1])
        rows = ev[:end]
        kinds = [x.decode() for x in rows["kind"]]
        want = ["insert", "grasp", "remove", "contact_start", "cut", "reshape"]
        check(kinds == want[:len(kinds)], f"event kinds {kinds}")
        if T >= 8:
            check(len(kinds) == 6, "6 events")
            check(rows["detail"][3].decode() == "Oberfl\u00e4che", "UTF-8 event detail")
            close(rows["position"][1], [10, 0, 10], "event position")
            check(rows["step"].tolist() == [4, 6, 6, 8, 10, 14], "event steps")

    return report(failures, f"check_run.py: {args.run}: {T} frames ok")


if __name__ == "__main__":
    sys.exit(main())
