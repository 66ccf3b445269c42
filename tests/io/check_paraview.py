#!/usr/bin/env pvpython
"""Opens XDMF sidecars of a run file with ParaView's readers and checks point and cell counts.

usage: pvpython check_paraview.py RUN.h5 XDMF3.xmf XDMF2.xmf
XDMF3.xmf (the sidecar RunWriter writes) is read with Xdmf3ReaderS and Xdmf3ReaderT (the reader
ParaView picks for a .xmf); XDMF2.xmf (`arthrosim info RUN.h5 --write-xdmf2`) with the legacy
XDMFReader. At every listed time the loaded points and cells, summed over the blocks, must equal
the frame's (node counts, alive tets, bone vertices and triangles, alive thread segments) as read
from RUN.h5 with h5py. Exit 0 if all hold.
"""
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np
from paraview import servermanager as sm
from paraview import simple as pv

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)


def expected(h, t):
    """Points and cells of frame t over every mesh that has cells in it."""
    points = cells = 0
    for name, b in h["bodies"].items():
        e = b["element_count"][t]
        n = int(np.sum(b["element_alive"][t, :e] == 1))
        if n > 0:
            points += int(b["node_count"][t])
            cells += n
    for name, b in h["bones"].items():
        n = int(b["triangles_count"][t])
        if n > 0:
            points += int(b["vertices_count"][t])
            cells += n
    for name, th in h["threads"].items():
        n = int(th["alive_segments_count"][t])
        if n > 0:
            points += int(th["node_count"][t])
            cells += n
    return points, cells


def listed_frames(xmf):
    frames = ET.parse(xmf).getroot().find("Domain/Grid").findall("Grid")
    return [(int(f.get("Name")[len("frame"):]), float(f.find("Time").get("Value"))) for f in frames]


def main():
    run, xmf3, xmf2 = sys.argv[1:4]
    with h5py.File(run, "r") as h:
        for reader, xmf in [("Xdmf3ReaderS", xmf3), ("Xdmf3ReaderT", xmf3), ("XDMFReader", xmf2)]:
            if reader == "XDMFReader":
                r = pv.XDMFReader(FileNames=[xmf])
            else:
                r = getattr(pv, reader)(FileName=[xmf])
            frames = listed_frames(xmf)
            check(len(r.TimestepValues) == len(frames),
                  f"{reader}: {len(r.TimestepValues)} times, {len(frames)} frames listed")
            for t, time in frames:
                r.UpdatePipeline(time)
                d = sm.Fetch(r)
                got = (d.GetNumberOfPoints(), d.GetNumberOfCells())
                want = expected(h, t)
                check(got == want, f"{reader} frame {t} (t={time}): {got} points/cells, want {want}")
            print(f"{reader}: {len(frames)} frames checked")
            pv.Delete(r)
    for f in failures[:30]:
        print("FAIL:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
