#!/usr/bin/env python3
"""Compares two run files dataset by dataset and attribute by attribute (bytes, shapes, dtypes,
chunking, filters, fill values).

usage: compare_runs.py A.h5 B.h5 [--quiet] [--ignore-event KIND ...]
Wall-clock metadata (/meta attribute created_utc) and the input's provenance (/meta attributes
trajectory, trajectory_sha256, end_step) are the only things allowed to differ; the HDF5
files themselves may differ in bytes (object addresses, timestamps). --ignore-event KIND leaves
out events of that kind from /events and /events_end before comparing them (e.g. realtime_lag,
which a live run records about the wall clock and its replay cannot). Exit 0 if equal, 1 if not.
"""
import sys

import h5py
import numpy as np

from check_report import report

WALL_CLOCK = {("/meta", "created_utc")}
# Where the input came from (a live session and its replay name it differently) and the step the
# run was asked to reach (open-ended live): provenance, not what was simulated.
WALL_CLOCK |= {("/meta", k) for k in ("trajectory", "trajectory_sha256", "end_step")}
# Storage settings that must match too (chunk shape, filters, growable dimensions).
STORAGE = ("chunks", "compression", "compression_opts", "shuffle", "maxshape")


def items(h):
    out = {}

    def visit(name, obj):
        out["/" + name] = obj
    h.visititems(visit)
    out["/"] = h
    return out


def attrs(obj, path):
    return {k: v for k, v in obj.attrs.items() if (path, k) not in WALL_CLOCK}


def same_value(a, b):
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    return type(a) is type(b) and a == b


def without_events(h, ignored):
    """(/events rows, /events_end) with the rows of the ignored kinds left out."""
    rows = h["events"][()]
    end = h["events_end"][()]
    keep = np.array([r.decode().rstrip("\0") not in ignored if isinstance(r, bytes) else
                     str(r) not in ignored for r in rows["kind"]], dtype=bool)
    kept = np.concatenate([[0], np.cumsum(keep)]).astype(end.dtype)
    return rows[keep], kept[end]


def main():
    a_path, b_path = sys.argv[1], sys.argv[2]
    quiet = "--quiet" in sys.argv
    ignored = {sys.argv[i + 1] for i in range(3, len(sys.argv) - 1)
               if sys.argv[i] == "--ignore-event"}
    diffs = []
    with h5py.File(a_path, "r") as a, h5py.File(b_path, "r") as b:
        ia, ib = items(a), items(b)
        if sorted(ia) != sorted(ib):
            diffs.append(f"objects differ: {sorted(set(ia) ^ set(ib))}")
        compared = 0
        for path in sorted(set(ia) & set(ib)):
            oa, ob = ia[path], ib[path]
            if type(oa) is not type(ob):
                diffs.append(f"{path}: group vs dataset")
                continue
            xa, xb = attrs(oa, path), attrs(ob, path)
            if sorted(xa) != sorted(xb):
                diffs.append(f"{path}: attribute names differ")
            for k in sorted(set(xa) & set(xb)):
                if not same_value(xa[k], xb[k]):
                    diffs.append(f"{path}@{k}: {xa[k]!r} != {xb[k]!r}")
            if isinstance(oa, h5py.Dataset):
                compared += 1
                for prop in STORAGE:
                    if getattr(oa, prop) != getattr(ob, prop):
                        diffs.append(f"{path}: {prop} {getattr(oa, prop)} vs {getattr(ob, prop)}")
                # (h5py crashes on the fill value of variable-length strings: skipped)
                if oa.dtype.kind != "O" and ob.dtype.kind != "O":
                    fa, fb = oa.fillvalue, ob.fillvalue
                    if np.asarray(fa).tobytes() != np.asarray(fb).tobytes():
                        diffs.append(f"{path}: fill value {fa!r} vs {fb!r}")
                if ignored and path in ("/events", "/events_end"):
                    ea, eb = without_events(a, ignored), without_events(b, ignored)
                    k = 0 if path == "/events" else 1
                    if ea[k].tobytes() != eb[k].tobytes():
                        diffs.append(f"{path}: data differs (ignoring {sorted(ignored)})")
                    continue
                if oa.dtype != ob.dtype or oa.shape != ob.shape:
                    diffs.append(f"{path}: {oa.dtype}{oa.shape} vs {ob.dtype}{ob.shape}")
                elif oa.dtype.kind == "O":  # variable-length strings
                    if oa[()] != ob[()]:
                        diffs.append(f"{path}: string differs")
                elif np.asarray(oa[()]).tobytes() != np.asarray(ob[()]).tobytes():
                    diffs.append(f"{path}: data differs")
    return report(diffs, f"compare_runs.py: {compared} datasets identical", tag="DIFF:", most=20,
                  quiet=quiet)


if __name__ == "__main__":
    sys.exit(main())
