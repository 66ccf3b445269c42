#!/usr/bin/env python3
"""Checks a run.xmf sidecar against its HDF5 file without ParaView.

usage: check_xdmf.py RUN.xmf RUN.h5
Parses the XML; for every frame checks the time, and for every grid the hyperslab arithmetic
(start + count <= rows of the referenced dataset, 2-D selections, relative file name) and that
the selected rows are exactly the frame's alive tets / bone triangles / alive thread segments and
its points. Exit 0 if all hold.
"""
import os
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np

from check_report import report

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)


def slab(item, h, h5name, columns):
    """Returns the rows a frame's data item selects, after checking its form: an HDF item with an
    inline selection (file:/path|start:stride:count:dataspace, the Xdmf3 form) or a HyperSlab
    item (the Xdmf2 form)."""
    if item.get("ItemType") == "HyperSlab":
        sel, data = item.findall("DataItem")
        check(sel.get("Dimensions") == "3 2" and sel.get("Format") == "XML", "selection item")
        s0, s1, st0, st1, c0, c1 = [int(x) for x in sel.text.split()]
        fname, dpath = data.text.strip().split(":", 1)
        rows, cols = [int(x) for x in data.get("Dimensions").split()]
    else:
        check(item.get("Format") == "HDF", "HDF item")
        ref, selection = item.text.strip().split("|")
        fname, dpath = ref.split(":", 1)
        start, stride, count, space = [[int(x) for x in p.split()] for p in selection.split(":")]
        s0, s1 = start
        st0, st1 = stride
        c0, c1 = count
        rows, cols = space
    check(s1 == 0 and st0 == 1 and st1 == 1 and c1 == columns, f"2-D row selection {s0} {c0}")
    check(item.get("Dimensions") == f"{c0} {columns}", "item Dimensions")
    check(fname == h5name and not os.path.isabs(fname), f"relative HDF5 reference {fname}")
    ds = h[dpath]
    check(rows == ds.shape[0] and cols == ds.shape[1] == columns,
          f"{dpath}: Dimensions {rows} {cols} vs dataset {ds.shape}")
    check(s0 >= 0 and s0 + c0 <= ds.shape[0], f"{dpath}: rows {s0}+{c0} beyond {ds.shape[0]}")
    return ds[s0:s0 + c0]


def main():
    xmf, run = sys.argv[1], sys.argv[2]
    root = ET.parse(xmf).getroot()
    check(root.tag == "Xdmf", "root element")
    temporal = root.find("Domain/Grid")
    check(temporal.get("CollectionType") == "Temporal", "temporal collection")
    frames = temporal.findall("Grid")
    h5name = os.path.basename(run)
    with h5py.File(run, "r") as h:
        T = h["time"].shape[0]
        # Frames are listed at least XdmfRun::interval_s apart, the first and the last always.
        listed = [int(fr.get("Name")[len("frame"):]) for fr in frames]
        check(listed and listed[0] == 0 and listed[-1] == T - 1, f"first/last frame {listed[:3]}")
        check(all(a < b for a, b in zip(listed, listed[1:])), "frames increase")
        grids_seen = 0
        for t, fr in zip(listed, frames):
            check(fr.get("CollectionType") == "Spatial", "spatial collection per frame")
            check(float(fr.find("Time").get("Value")) == h["time"][t], f"time of frame {t}")
            for g in fr.findall("Grid"):
                grids_seen += 1
                kind, name = g.get("Name").split(":", 1)
                topo, geo = g.find("Topology"), g.find("Geometry")
                n = int(topo.get("NumberOfElements"))
                check(geo.get("GeometryType") == "XYZ", "XYZ geometry")
                points = slab(geo.find("DataItem"), h, h5name, 3)
                if kind == "body":
                    b = h["bodies/" + name]
                    e, nn = b["element_count"][t], b["node_count"][t]
                    alive = b["element_alive"][t, :e] == 1
                    check(topo.get("TopologyType") == "Tetrahedron", "tet topology")
                    check(n == alive.sum(), f"{name} frame {t}: {n} cells, {alive.sum()} alive")
                    cells = slab(topo.find("DataItem"), h, h5name, 4)
                    check(np.array_equal(cells, b["elements"][:e][alive]),
                          f"{name} frame {t}: cells are the alive elements")
                    o = b["positions_offset"][t]
                    check(np.array_equal(points, b["positions"][o:o + nn]),
                          f"{name} frame {t}: points")
                elif kind == "bone":
                    b = h["bones/" + name]
                    check(topo.get("TopologyType") == "Triangle", "triangle topology")
                    check(n == b["triangles_count"][t], f"{name} frame {t}: triangle count")
                    cells = slab(topo.find("DataItem"), h, h5name, 3)
                    check(cells.max() < len(points), f"{name} frame {t}: indices in range")
                    o = b["vertices_offset"][t]
                    check(np.array_equal(points, b["vertices"][o:o + len(points)]), "bone points")
                elif kind == "thread":
                    th = h["threads/" + name]
                    a = th["node_alive"][t, :th["node_count"][t]]
                    pairs = [[i, i + 1] for i in range(len(a) - 1) if a[i] and a[i + 1]]
                    check(topo.get("TopologyType") == "Polyline" and
                          topo.get("NodesPerElement") == "2", "polyline topology")
                    check(n == len(pairs), f"{name} frame {t}: {n} segments, {len(pairs)} alive")
                    cells = slab(topo.find("DataItem"), h, h5name, 2)
                    check(cells.tolist() == pairs, f"{name} frame {t}: alive segments")
                else:
                    check(False, f"unknown grid {g.get('Name')}")
        check(grids_seen > 0, "some grids")
    return report(failures, f"check_xdmf.py: {len(frames)} frames, {grids_seen} grids ok")


if __name__ == "__main__":
    sys.exit(main())
