#!/usr/bin/python3
"""Procedural right-shoulder anatomy for arthrosim (meshes + scenario files).

Builds, with Debian's gmsh 4.8 Python API (OpenCASCADE kernel), a humerus (head, neck/shaft
stump, greater tuberosity with the supraspinatus footprint), an acromion with an anterior
spur, a supraspinatus muscle + retracted (torn) tendon meshed together so that their interface
is conforming, and the long head of biceps. Writes Gmsh 2.2 ASCII meshes to scenarios/meshes/
and the scenarios rotator_cuff_repair.yaml and bench_full.yaml.

Frame: right shoulder, origin at the humeral-head centre, x lateral, y anterior, z superior,
millimetres.

Deterministic: one thread, fixed random seed and algorithms, nodes renumbered in gmsh tag order,
doubles written with repr (exact round trip). Running it twice gives byte-identical files.

Usage: tools/gen_anatomy.py [--out DIR] [--check]   (--check: build and verify, write nothing)
"""

import argparse
import hashlib
import math
import os
import sys

import gmsh
import numpy as np

# Mesh checks and writers (tools/anatomic_shoulder.py uses them as base.<name>).
from mesh_geometry import (fmt, in_box, msh22_text, orient_surface, orient_tets,  # noqa: F401
                           point_tri_distance, samples, signed_volume, tet_boundary,
                           tet_quality, tet_volumes, vec, winding)

# ----------------------------------------------------------------------------------------------
# Anatomy parameters (mm). Sources are named in scenarios/README.md.
# ----------------------------------------------------------------------------------------------
HEAD_R = 22.5                      # humeral head radius (diameter 45 mm)
GT_C = (12.0, 0.0, 0.0)            # greater-tuberosity ellipsoid centre
GT_AX = (16.0, 22.0, 16.0)         # its semi-axes (x, y, z): broad antero-posteriorly
NECK_C = (5.0, 0.0)                # neck/shaft axis (x, y): shaft lies lateral of the head centre
NECK_Z = (-8.0, -32.0)             # cone from z0 (radius 17) down to z1 (radius 11)
NECK_R = (17.0, 11.0)
SHAFT_Z = (-50.0, -30.0)           # shaft cylinder (radius NECK_R[1]) z range
FOOTPRINT_AP = 23.0                # Curtis 2006: 23 x 16 mm (length AP x width ML)
FOOTPRINT_ML = 16.0

ACRO_BOX = (-8.0, -28.0, 32.5, 26.0, 14.0, 40.0)  # acromion plate (xmin ymin zmin xmax ymax zmax)
SPUR_BASE = (12.0, 9.0, 36.5)      # spur cone base centre (inside the plate)
SPUR_TIP = (12.0, 20.0, 28.5)      # spur tip: anterior and inferior of the plate
SPUR_R = (4.0, 0.5)                # spur base / tip radius

CUFF_GAP = 0.8                     # tendon undersurface to head surface
TENDON_T = 5.0                     # tendon thickness
TENDON_HALF_W = FOOTPRINT_AP / 2   # tendon is as wide (AP) as the footprint
TENDON_X = (-14.0, 6.3)            # musculotendinous junction .. lateral (torn, retracted) edge
# Muscle sections (x, zc, r_inner, thickness, half_width): annular sectors in planes x = const,
# inner arc centre (x, 0, zc). The first one is the tendon's medial face (computed below).
MUSCLE_SECTIONS = [
    (-24.0, 4.0, 18.0, 10.0, 13.0),
    (-40.0, 0.0, 24.0, 15.0, 15.0),
    (-58.0, 0.0, 26.0, 17.0, 16.0),
    (-72.0, 0.0, 27.0, 17.0, 16.0),
]

BICEPS_R = 2.75                    # long head of biceps, diameter 5.5 mm
# Centreline (interpolating spline) incl. extensions cut off at the two end planes.
BICEPS_PATH = [(-29.0, 14.5, 12.0), (-21.0, 18.0, 12.5), (-10.0, 23.5, 12.0), (1.0, 26.5, 5.0),
               (6.5, 25.0, -6.0), (6.5, 20.0, -18.0), (6.0, 16.5, -30.0), (6.0, 16.0, -40.0)]
BICEPS_X0 = -21.0                  # proximal end plane x = BICEPS_X0 (supraglenoid region)
BICEPS_Z1 = -32.0                  # distal end plane z = BICEPS_Z1 (in the bicipital groove)

# Mesh sizes (mm), tuned to the paper's counts.
H_HUM_FINE, H_HUM_COARSE, H_HUM_RAMP = 1.09, 1.93, 0.12
H_ACRO = 13.7
H_TENDON, H_MUSCLE = 2.38, 4.35
H_BICEPS = 2.6

SEED = 1


def gmsh_setup():
    """Fresh gmsh session with the deterministic options."""
    gmsh.initialize(["-noenv"])
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.option.setNumber("Mesh.RandomSeed", SEED)
    gmsh.option.setNumber("Mesh.Algorithm", 6)       # Frontal-Delaunay 2D
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)     # Delaunay 3D
    gmsh.option.setNumber("Mesh.Optimize", 1)
    gmsh.option.setNumber("Mesh.OptimizeNetgen", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.ElementOrder", 1)


def background_size(formula):
    """Uses a MathEval size field F(x, y, z) (mm) everywhere."""
    f = gmsh.model.mesh.field.add("MathEval")
    gmsh.model.mesh.field.setString(f, "F", formula)
    gmsh.model.mesh.field.setAsBackgroundMesh(f)


def node_table():
    """All model nodes as {tag: (x, y, z)}."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    xyz = np.asarray(coords, dtype=float).reshape(-1, 3)
    return {int(t): xyz[i] for i, t in enumerate(tags)}


def elements_of(dim, tag, etype):
    """Connectivity (gmsh node tags) of elements of type etype on entity (dim, tag)."""
    types, _, conn = gmsh.model.mesh.getElements(dim, tag)
    npe = {2: 3, 4: 4}[etype]
    for t, c in zip(types, conn):
        if t == etype:
            return np.asarray(c, dtype=np.int64).reshape(-1, npe)
    return np.zeros((0, npe), dtype=np.int64)


def compact(conn, table):
    """Renumbers the used nodes densely in ascending gmsh-tag order. Returns (xyz, conn0)."""
    used = np.unique(conn)
    index = {int(t): i for i, t in enumerate(used)}
    xyz = np.array([table[int(t)] for t in used], dtype=float)
    out = np.vectorize(lambda t: index[int(t)])(conn) if conn.size else conn
    return xyz, out.astype(np.int64)


# ----------------------------------------------------------------------------------------------
# Geometry + meshing
# ----------------------------------------------------------------------------------------------
def gt_point(y, s):
    """Point on the greater tuberosity in the plane y, s mm of arc lateral of the articular
    margin (the crease between the head sphere and the tuberosity ellipsoid)."""
    cx, _, _ = GT_C
    rho = GT_AX[0] * math.sqrt(1.0 - (y / GT_AX[1]) ** 2)  # circle of the ellipsoid at y
    xc = (HEAD_R ** 2 - y * y - rho * rho + cx * cx) / (2.0 * cx)
    zc = math.sqrt(HEAD_R ** 2 - y * y - xc * xc)
    theta = math.atan2(xc - cx, zc) + s / rho
    return np.array([cx + rho * math.sin(theta), y, rho * math.cos(theta)])


def footprint_center():
    return gt_point(0.0, FOOTPRINT_ML / 2)


def shell_patch(r_in, r_out, x_range, half_w):
    """The part of the spherical shell r_in..r_out (mm) about the origin over the box x in
    x_range, |y| <= half_w, z >= 0 (the cuff's and the bursa's shape over the head); OCC
    dimtags of the intersection."""
    occ = gmsh.model.occ
    outer = occ.addSphere(0, 0, 0, r_out)
    inner = occ.addSphere(0, 0, 0, r_in)
    shell, _ = occ.cut([(3, outer)], [(3, inner)])
    x0, x1 = x_range
    box = occ.addBox(x0, -half_w, 0.0, x1 - x0, 2 * half_w, r_out + 1.0)
    out, _ = occ.intersect(shell, [(3, box)])
    return out


def single_volume(out):
    """The tag of the one volume a boolean operation gave (`out`), after synchronizing."""
    gmsh.model.occ.synchronize()
    assert len(out) == 1 and out[0][0] == 3, out
    return out[0][1]


def boundary_triangles(vol):
    """The meshed boundary surfaces of volume `vol` as one compact triangle mesh."""
    table = node_table()
    surfs = [t for _, t in gmsh.model.getBoundary([(3, vol)], oriented=False)]
    tris = np.concatenate([elements_of(2, s, 2) for s in sorted(surfs)])
    return compact(tris, table)


def humerus_geometry():
    occ = gmsh.model.occ
    head = occ.addSphere(0, 0, 0, HEAD_R)
    gt = occ.addSphere(0, 0, 0, 1.0)
    occ.dilate([(3, gt)], 0, 0, 0, *GT_AX)
    occ.translate([(3, gt)], *GT_C)
    neck = occ.addCone(NECK_C[0], NECK_C[1], NECK_Z[0], 0, 0, NECK_Z[1] - NECK_Z[0], *NECK_R)
    shaft = occ.addCylinder(NECK_C[0], NECK_C[1], SHAFT_Z[0], 0, 0, SHAFT_Z[1] - SHAFT_Z[0],
                            NECK_R[1])
    out, _ = occ.fuse([(3, head)], [(3, gt), (3, neck), (3, shaft)])
    return single_volume(out)


def mesh_humerus():
    gmsh.model.add("humerus")
    vol = humerus_geometry()
    fx, fy, fz = footprint_center()
    # Finer near the footprint (anchor, burr and suture work), coarser elsewhere.
    background_size("min(%r, %r + %r*sqrt((x-%r)^2+(y-%r)^2+(z-%r)^2))" % (
        H_HUM_COARSE, H_HUM_FINE, H_HUM_RAMP, fx, fy, fz))
    gmsh.model.mesh.generate(2)
    return boundary_triangles(vol)


def acromion_geometry():
    occ = gmsh.model.occ
    x0, y0, z0, x1, y1, z1 = ACRO_BOX
    plate = occ.addBox(x0, y0, z0, x1 - x0, y1 - y0, z1 - z0)
    b, t = np.array(SPUR_BASE), np.array(SPUR_TIP)
    spur = occ.addCone(*b, *(t - b), *SPUR_R)
    out, _ = occ.fuse([(3, plate)], [(3, spur)])
    return single_volume(out)


def mesh_acromion():
    gmsh.model.add("acromion")
    vol = acromion_geometry()
    background_size("%r" % H_ACRO)
    gmsh.option.setNumber("Mesh.MinimumCirclePoints", 4)  # coarse like the paper's 69 nodes
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MinimumCirclePoints", 7)
    return boundary_triangles(vol)


def sector_wire(x, zc, ri, t, w):
    """Closed wire of an annular sector in the plane x: inner arc radius ri and outer arc
    radius ri + t around (x, 0, zc), cut by y = -w and y = +w. Same edge order for every
    section so that ThruSections pairs them."""
    occ = gmsh.model.occ
    ro = ri + t
    c = occ.addPoint(x, 0, zc)
    zi, zo = math.sqrt(ri * ri - w * w), math.sqrt(ro * ro - w * w)
    p1 = occ.addPoint(x, -w, zc + zi)
    p2 = occ.addPoint(x, w, zc + zi)
    p3 = occ.addPoint(x, w, zc + zo)
    p4 = occ.addPoint(x, -w, zc + zo)
    curves = [occ.addCircleArc(p1, c, p2), occ.addLine(p2, p3), occ.addCircleArc(p3, c, p4),
              occ.addLine(p4, p1)]
    return occ.addWire(curves)


def tendon_section():
    """The tendon's medial face as (x, zc, r_inner, thickness, half_width)."""
    x = TENDON_X[0]
    ri = math.sqrt((HEAD_R + CUFF_GAP) ** 2 - x * x)
    ro = math.sqrt((HEAD_R + CUFF_GAP + TENDON_T) ** 2 - x * x)
    return (x, 0.0, ri, ro - ri, TENDON_HALF_W)


def cuff_geometry():
    """Tendon (spherical shell patch over the head) and muscle (loft of sections), fragmented
    so the two volumes share one conforming interface face. Returns (muscle, tendon) tags."""
    occ = gmsh.model.occ
    tendon = shell_patch(HEAD_R + CUFF_GAP, HEAD_R + CUFF_GAP + TENDON_T, TENDON_X, TENDON_HALF_W)
    assert len(tendon) == 1
    wires = [sector_wire(*tendon_section())] + [sector_wire(*s) for s in MUSCLE_SECTIONS]
    muscle = occ.addThruSections(wires, makeSolid=True, makeRuled=False)
    muscle = [d for d in muscle if d[0] == 3]
    assert len(muscle) == 1
    out, out_map = occ.fragment(muscle, tendon)
    occ.synchronize()
    m = [t for d, t in out_map[0] if d == 3]
    t = [t for d, t in out_map[1] if d == 3]
    assert len(m) == 1 and len(t) == 1, (out_map, out)
    return m[0], t[0]


def mesh_cuff():
    gmsh.model.add("cuff")
    vm, vt = cuff_geometry()
    shared = set(s for _, s in gmsh.model.getBoundary([(3, vm)], oriented=False)) & set(
        s for _, s in gmsh.model.getBoundary([(3, vt)], oriented=False))
    assert len(shared) == 1, shared
    # Tendon size lateral of the junction, muscle size a few mm medial of it.
    x0 = TENDON_X[0]
    background_size("%r + %r*min(1, max(0, (%r - x)/8))" % (H_TENDON, H_MUSCLE - H_TENDON, x0))
    gmsh.model.mesh.generate(3)
    table = node_table()
    muscle = compact(elements_of(3, vm, 4), table)
    tendon = compact(elements_of(3, vt, 4), table)
    return muscle, tendon


def rotation_to(v):
    """Axis and angle rotating +z onto the unit vector v."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, v)
    s = np.linalg.norm(axis)
    if s < 1e-12:
        return np.array([1.0, 0.0, 0.0]), (0.0 if v[2] > 0 else math.pi)
    return axis / s, math.atan2(s, float(np.dot(z, v)))


def biceps_geometry():
    occ = gmsh.model.occ
    pts = [occ.addPoint(*p) for p in BICEPS_PATH]
    spline = occ.addSpline(pts)
    wire = occ.addWire([spline])
    p0, p1 = np.array(BICEPS_PATH[0]), np.array(BICEPS_PATH[1])
    tangent = (p1 - p0) / np.linalg.norm(p1 - p0)
    disk = occ.addDisk(0, 0, 0, BICEPS_R, BICEPS_R)
    axis, angle = rotation_to(tangent)
    occ.rotate([(2, disk)], 0, 0, 0, *axis, angle)
    occ.translate([(2, disk)], *p0)
    tube = occ.addPipe([(2, disk)], wire)
    tube = [d for d in tube if d[0] == 3]
    keep = occ.addBox(BICEPS_X0, -100.0, BICEPS_Z1, 200.0, 200.0, 200.0)
    out, _ = occ.intersect(tube, [(3, keep)])
    return single_volume(out)


def mesh_biceps():
    gmsh.model.add("biceps")
    vol = biceps_geometry()
    background_size("%r" % H_BICEPS)
    gmsh.model.mesh.generate(3)
    return compact(elements_of(3, vol, 4), node_table())


# ----------------------------------------------------------------------------------------------
# Landmarks, regions, portals, instruments
# ----------------------------------------------------------------------------------------------
def gt_normal(p):
    """Outward unit normal of the greater-tuberosity ellipsoid at p."""
    n = (np.asarray(p) - np.array(GT_C)) / np.square(np.array(GT_AX))
    return n / np.linalg.norm(n)


def retraction():
    """(arc at tendon mid-thickness, distance in x) from the torn edge to the footprint's
    medial edge, in the plane y = 0, mm."""
    m = gt_point(0.0, 0.0)
    rm = HEAD_R + CUFF_GAP + TENDON_T / 2
    arc = (math.atan2(m[0], m[2]) - math.asin(TENDON_X[1] / rm)) * rm
    return arc, m[0] - TENDON_X[1]


def tendon_mid_point(y, s_medial):
    """Mid-thickness tendon point in the plane y, s_medial mm of arc medial of the free edge."""
    rc = math.sqrt((HEAD_R + CUFF_GAP + TENDON_T / 2) ** 2 - y * y)
    phi = math.asin(TENDON_X[1] / rc) - s_medial / rc
    return np.array([rc * math.sin(phi), y, rc * math.cos(phi)])


def spline_curve(path, name="biceps_curve"):
    """A gmsh interpolating spline through `path` in a new model `name` (the curve the biceps
    mesh follows): (curve tag, lower and upper parameter bounds)."""
    gmsh.model.add(name)
    pts = [gmsh.model.occ.addPoint(*p) for p in path]
    c = gmsh.model.occ.addSpline(pts)
    gmsh.model.occ.synchronize()
    lo, hi = gmsh.model.getParametrizationBounds(1, c)
    return c, lo, hi


def crossing_x(c, a, b, x):
    """The point of curve c where its x reaches `x`, by 60 bisections of the parameter interval
    [a, b] (x below `x` at a, not below at b)."""
    for _ in range(60):
        m = 0.5 * (a + b)
        if gmsh.model.getValue(1, c, [m])[0] < x:
            a = m
        else:
            b = m
    return np.array(gmsh.model.getValue(1, c, [0.5 * (a + b)]))


def biceps_centreline_at_x(x):
    """Point where the biceps centreline (the same gmsh spline as the mesh) first crosses x."""
    c, lo, hi = spline_curve(BICEPS_PATH)
    p = crossing_x(c, lo[0], hi[0], x)  # x only rises from -29 to 6.5 and never comes back below
    gmsh.model.remove()
    return p


def anatomy_points():
    """All named points (mm)."""
    P = {}
    P["footprint_center"] = footprint_center()
    P["anchor_site_1"] = gt_point(5.0, 3.0)    # anterior medial-row anchor
    P["anchor_site_2"] = gt_point(-5.0, 3.0)   # posterior, 10 mm apart
    P["spur_tip"] = np.array(SPUR_TIP)
    rm = HEAD_R + CUFF_GAP + TENDON_T / 2
    P["tear_edge_center"] = np.array([TENDON_X[1], 0.0, math.sqrt(rm * rm - TENDON_X[1] ** 2)])
    P["bite_target_1"] = tendon_mid_point(5.0, 11.0)
    P["bite_target_2"] = tendon_mid_point(-5.0, 11.0)
    P["biceps_cut_site"] = biceps_centreline_at_x(BICEPS_X0 + 9.0)
    top = math.sqrt((HEAD_R + CUFF_GAP + TENDON_T) ** 2 - TENDON_X[1] ** 2)
    P["subacromial_center"] = np.array([TENDON_X[1], 0.0, 0.5 * (top + ACRO_BOX[2])])
    P["glenohumeral_view"] = np.array([-24.0, 4.0, 8.0])
    s = MUSCLE_SECTIONS[1]
    P["muscle_belly"] = np.array([-50.0, 0.0, s[1] + s[2] + s[3] / 2])
    return P


LANDMARK_BODY = {
    "footprint_center": "humerus", "anchor_site_1": "humerus", "anchor_site_2": "humerus",
    "spur_tip": "acromion", "tear_edge_center": "supraspinatus_tendon",
    "bite_target_1": "supraspinatus_tendon", "bite_target_2": "supraspinatus_tendon",
    "biceps_cut_site": "biceps_tendon", "muscle_belly": "supraspinatus_muscle",
}

PORTALS = {  # on a skin envelope 35-45 mm from the head centre, beach-chair right shoulder
    "posterior": (-5.0, -40.0, 10.0),   # "soft spot", posterior to the joint line
    "anterior": (0.0, 40.0, 12.0),      # lateral to the coracoid, into the rotator interval
    "lateral": (38.0, 2.0, 18.0),       # ~2-3 cm distal of the lateral acromial edge
}


def region_boxes():
    """Named node sets as (body, (min, max)) axis-aligned boxes, mm."""
    e = 0.01
    fx0 = gt_point(0.0, 0.0)[0]                   # articular margin at y = 0
    fz0 = gt_point(0.0, FOOTPRINT_ML)[2]          # lateral edge of the footprint at y = 0
    h = FOOTPRINT_AP / 2
    x0, y0, z0, x1, y1, z1 = ACRO_BOX
    boxes = {
        "muscle_medial_end": ("supraspinatus_muscle",
                              ((MUSCLE_SECTIONS[-1][0] - 1, -30, -10),
                               (MUSCLE_SECTIONS[-1][0] + e, 30, 70))),
        "tendon_edge": ("supraspinatus_tendon", ((TENDON_X[1] - e, -15, 0), (TENDON_X[1] + 1, 15, 40))),
        "biceps_ends_proximal": ("biceps_tendon", ((BICEPS_X0 - 1, 0, 0), (BICEPS_X0 + e, 30, 30))),
        "biceps_ends_distal": ("biceps_tendon", ((-10, 0, BICEPS_Z1 - 1), (20, 30, BICEPS_Z1 + e))),
        "footprint": ("humerus", ((fx0 - 1e-3, -h, fz0), (40, h, 30))),
        "spur": ("acromion", ((SPUR_TIP[0] - 6, y1 + e, 20), (SPUR_TIP[0] + 6, 30, z0 + 6))),
        "spur_region": ("acromion", ((x0 + 8, y1 - 10, 20), (x1, 30, z0 + 4))),
    }
    # Rounded as written to the YAML, so the checks select exactly what the simulator will.
    return {k: (b, tuple(tuple(float(fmt(c)) for c in p) for p in box))
            for k, (b, box) in boxes.items()}


INSTRUMENTS = [  # name = kind; sizes in mm (shaver, cannula: Wheeless' Textbook; [K] no source)
    # kind, portal, shaft_diameter, shaft_length, tip_length, tip_radius
    ("scissors", "anterior", 3.5, 150, 8, 1.75),        # biceps tenotomy
    ("cutter", "lateral", 3.5, 150, 6, 1.75),           # suture cutter
    ("burr", "lateral", 5.5, 150, 5.5, 2.75),           # 5.5 mm round burr, acromioplasty
    ("shaver", "lateral", 5.5, 150, 8, 2.75),           # 5.5 mm full-radius shaver
    ("electrocautery", "anterior", 4.0, 150, 5, 1.5),   # RF ablation wand
    ("awl", "lateral", 4.5, 150, 12, 2.0),              # punch for 4.5-5.5 mm anchors
    ("retriever", "anterior", 3.5, 150, 6, 1.0),        # suture retriever
    ("grasper", "anterior", 3.5, 150, 10, 1.75),        # tissue grasper
    ("scorpion_needle", "lateral", 5.0, 150, 12, 2.5),  # suture passer
    ("knot_pusher", "lateral", 3.5, 150, 5, 1.0),
    ("hook", "anterior", 3.5, 150, 4, 1.0),             # probe / crochet hook
]

CAMERA = {"portal": "posterior", "position": (4.0, -20.0, 29.0)}


# Suture node counts. The benchmark keeps the paper's two 60-node threads (60 mm); the repair
# scenes' limbs are 80 nodes at the same 60/59 mm spacing (80.3 mm, the first 60 nodes where the
# 60-node limbs were): the knot pusher's half hitch needs ~24 nodes of a limb beyond its bite
# plus the loop (docs/operations.md, "On the shoulder scene").
SUTURE_NODES_BENCH = 60
SUTURE_NODES_REPAIR = 80
SUTURE_SPACING_MM = 60.0 / 59.0


def suture_lines(points, nodes=SUTURE_NODES_BENCH):
    """Two sutures of a double-loaded anchor at anchor_site_1, 0.4 mm either side of it along
    the surface (so the fixed first nodes do not coincide), running toward the lateral portal,
    `nodes` nodes SUTURE_SPACING_MM apart."""
    a = points["anchor_site_1"]
    n = gt_normal(a)
    t = np.array([0.0, 1.0, 0.0]) - n[1] * n
    t /= np.linalg.norm(t)
    lat = np.array(PORTALS["lateral"])
    out = {}
    for name, sgn in (("suture_a", 1.0), ("suture_b", -1.0)):
        start = a + sgn * 0.4 * t
        d = lat + sgn * 2.0 * t - start
        end60 = start + 60.0 * d / np.linalg.norm(d)
        if nodes == SUTURE_NODES_BENCH:
            out[name] = (start, end60)
        else:
            # Longer limbs extend the 60-node limb as the scenario writes it (3 decimals) along
            # its own line, so their first 60 nodes are where the 60-node limbs' nodes were,
            # to the bit: the repair scripts were tuned on those.
            s3, e3 = (np.round(v, 3) for v in (start, end60))
            out[name] = (start, s3 + (e3 - s3) * (nodes - 1) / (SUTURE_NODES_BENCH - 1))
    return out


def scenario_text(name, duration, points, with_biceps, title, extra_header, anchored_sutures,
                  mesh_dir="meshes", anatomy_header=None, extra_bodies=(), regions=None,
                  landmark_body=None, humerus_tissues=(), extra_materials=(),
                  extra_soft_bodies=()):
    """The scenario YAML (docs/scenario-format.md). The keyword arguments describe the anatomic
    variant (tools/anatomic_shoulder.py): its mesh folder, header lines, extra rigid bodies
    (YAML lines), region boxes, landmark bodies, the humerus's own tissues (surface groups),
    extra materials and soft bodies (YAML lines, after the biceps); the defaults give the
    primitive scene."""
    regions = region_boxes() if regions is None else regions
    landmark_body = LANDMARK_BODY if landmark_body is None else landmark_body
    L = []
    w = L.append
    w("# arthrosim scenario: %s" % title)
    w("# GENERATED by tools/gen_anatomy.py: change the generator and rerun it, do not hand-edit.")
    w("#")
    w("# Frame: right shoulder, origin at the humeral-head centre, x lateral, y anterior,")
    w("# z superior, millimetres. Beach-chair position: z is up, so gravity is -z.")
    for line in anatomy_header or [
            "Anatomy (scenarios/README.md): humeral head diameter 45 mm; greater tuberosity with the",
            "supraspinatus footprint 23 x 16 mm (Curtis 2006), medial edge at the articular margin;",
            "acromion undersurface 10 mm above the head with an anterior spur (hook); supraspinatus",
            "muscle and tendon share a conforming interface (joins); full-thickness tear, tendon edge"]:
        w("# " + line)
    arc, dx = retraction()
    w("# retracted medial of the footprint by %.1f mm in x (%.1f mm of arc along the tendon)." % (
        dx, arc))
    if with_biceps:
        w("# Long head of biceps from the supraglenoid region over the front of the head into the")
        w("# bicipital groove, both ends fixed.")
    for line in extra_header:
        w("# " + line if line else "#")
    w("name: %s" % name)
    w("seed: 1")
    w("time: {dt: 0.02, duration: %s}" % fmt(duration))
    w("gravity: [0, 0, -9810]")
    w("solver: {integrator: implicit_euler, cg_max_iterations: 100, cg_tolerance: 1.0e-6}")
    w("output: {every: 1}")
    # Every product scene: the tool proxy slides along bone (god-object contact planes;
    # docs/contact-model.md, "The tool proxy").
    w("# The tool proxy slides along the bone it meets (god-object; docs/contact-model.md, \"The tool")
    w("# proxy\"): the instrument stays outside bone at the hand's nearest reachable point.")
    if anchored_sutures:  # the repair scenes' scripts; bench_full keeps the default rule
        w("# Tissue trapped between an instrument and bone: the earlier rule (trapped_gap_mm 0: the")
        w("# advance along the push bounded per step, no floor, free sliding). The scripted demonstrations")
        w("# and the expert repair were tuned under it; with the default floor (1 mm) and friction (0.5)")
        w("# their tools stick where they press tissue on bone (docs/haptics.md, tests/sim/trapped_tissue_test).")
        w("haptics: {slide: true, trapped_gap_mm: 0}")
    else:
        w("haptics: {slide: true}")
    w("")
    w("materials:")
    w("  # Passive skeletal muscle at rest: E 25 kPa (shear-wave elastography of the deltoid:")
    w("  # 15-35 kPa at rest; Bosboom 2001 Ogden mu 15.6 kPa), nu 0.45 (nearly incompressible")
    w("  # while avoiding volumetric locking of linear tets), rho 1060 kg/m3.")
    w("  muscle: {young_modulus: 25000, poisson_ratio: 0.45, density: 1060,")
    w("           rayleigh_mass: 0.1, rayleigh_stiffness: 0.001}")
    w("  # Tendon (supraspinatus; long head of biceps uses the same): linear elastic E 60 MPa, the")
    w("  # low end of the 60-200 MPa along-fibre range of linear models without a toe region")
    w("  # (Cronje et al., fresh tissue with DIC: tendinous layers 59.6-67.1 MPa); nu 0.45, rho 1100.")
    w("  # On these meshes the modulus barely changes the CG cost (scenarios/README.md, Materials).")
    w("  tendon: {young_modulus: 60000000, poisson_ratio: 0.45, density: 1100,")
    w("           rayleigh_mass: 0.1, rayleigh_stiffness: 0.001}")
    for line in extra_materials:
        w(line)
    w("")
    w("bodies:")
    if humerus_tissues:
        w("  # Articular cartilage: the mesh's triangle group, a tissue of its own (drawn as")
        w("  # cartilage; burring it is collateral damage, docs/operations.md, Bone).")
    w("  - {name: humerus, kind: rigid, mesh: %s/humerus.msh, hardness: 1%s}" % (
        mesh_dir, ", tissues: [%s]" % ", ".join(humerus_tissues) if humerus_tissues else ""))
    w("  # Acromion: denser cortical bone than the sparse greater-tuberosity footprint (BV/TV")
    w("  # 0.02-0.04, Kirchhoff 2012), so burr removal is slower [K: divisor chosen, not measured].")
    w("  - {name: acromion, kind: rigid, mesh: %s/acromion.msh, hardness: 3}" % mesh_dir)
    for line in extra_bodies:
        w(line)
    w("  - {name: supraspinatus_muscle, kind: soft, mesh: %s/supraspinatus_muscle.msh," % mesh_dir)
    w("     material: muscle, fixed: [muscle_medial_end]}")
    w("  - {name: supraspinatus_tendon, kind: soft, mesh: %s/supraspinatus_tendon.msh," % mesh_dir)
    w("     material: tendon}")
    if with_biceps:
        w("  - {name: biceps_tendon, kind: soft, mesh: %s/biceps_tendon.msh, material: tendon," % mesh_dir)
        w("     fixed: [biceps_ends_proximal, biceps_ends_distal]}")
    for line in extra_soft_bodies:
        w(line)
    if anchored_sutures:
        w("  # Two limbs of a double-loaded anchor, running out toward the lateral portal. They belong to")
        w("  # the anchor (operations.anchor.sutures below): out of the scene until the awl seats it,")
        w("  # then laid from its eyelet (this shape, moved there) and held to it. No. 2 FiberWire:")
        w("  # d 0.55 mm, EA 5 kN (~5 % elongation at failure, Turker 2011), rho 1300; 80 nodes over")
        w("  # 80.3 mm (the first 60 where the 60-node limbs were; the knot pusher's half hitch needs ~24")
        w("  # nodes of each limb beyond its bite plus the loop, docs/operations.md \"On the shoulder scene\").")
    else:
        w("  # Two limbs of a double-loaded anchor at anchor_site_1 (0.4 mm either side of it), running")
        w("  # out toward the lateral portal. No. 2 FiberWire: d 0.55 mm, EA 5 kN (~5 % elongation at")
        w("  # failure, Turker 2011), rho 1300; 60 nodes over 60 mm.")
    nodes = SUTURE_NODES_REPAIR if anchored_sutures else SUTURE_NODES_BENCH
    sut = suture_lines(points, nodes)
    for sname in ("suture_a", "suture_b"):
        s, e = sut[sname]
        w("  - name: %s" % sname)
        w("    kind: thread")
        w("    thread: {start: %s, end: %s, nodes: %d," % (vec(s), vec(e), nodes))
        w("             diameter: 0.55, density: 1300, stretch_stiffness: 5000, bend_stiffness: 0,")
        w("             damping: 0, max_speed: 500, self_collision: true%s}" % (
            "" if anchored_sutures else ", fixed_nodes: [0]"))
    w("")
    w("joins:")
    w("  - {a: supraspinatus_muscle, b: supraspinatus_tendon}")
    w("")
    w("# Skin entry points on an envelope 35-45 mm from the head centre.")
    w("portals:")
    for pname, p in PORTALS.items():
        w("  - {name: %s, position: %s}" % (pname, vec(p)))
    w("")
    w("# Sizes, mm: shaver 5.5 mm and cannula 6.5 mm (Wheeless' Textbook); 5.5 mm burr;")
    w("# graspers, scissors, cutters, retrievers, probes 3.5-5 mm [K].")
    w("instruments:")
    for kind, portal, sd, sl, tl, tr in INSTRUMENTS:
        w("  - {name: %s, kind: %s, portal: %s, shaft_diameter: %s, shaft_length: %s," % (
            kind, kind, portal, fmt(sd), fmt(sl)))
        w("     tip_length: %s, tip_radius: %s}" % (fmt(tl), fmt(tr)))
    w("")
    w("# 4 mm 30-degree arthroscope, 105-degree field of view (Kwak 2019), in the posterior")
    w("# portal, tip in the posterior subacromial space looking at its centre.")
    w("camera: {portal: %s, fov: 105, lens_angle: 30, diameter: 4, near: 1, far: 100," % (
        CAMERA["portal"]))
    w("         position: %s, look_at: %s}" % (vec(CAMERA["position"]),
                                                vec(points["subacromial_center"])))
    w("")
    w("landmarks:")
    for lname, p in points.items():
        body = landmark_body.get(lname)
        if body == "biceps_tendon" and not with_biceps:
            body = None
        if body:
            w("  - {name: %s, body: %s, position: %s}" % (lname, body, vec(p)))
        else:
            w("  - {name: %s, position: %s}" % (lname, vec(p)))
    w("")
    w("# Node sets: the nodes of `body` inside the box. biceps_ends is two boxes (the schema has")
    w("# one box per region), both listed in the biceps body's `fixed`.")
    w("regions:")
    for rname, (body, (lo, hi)) in regions.items():
        if body == "biceps_tendon" and not with_biceps:
            continue
        w("  - {name: %s, body: %s, box: {min: %s, max: %s}}" % (rname, body, vec(lo), vec(hi)))
    if anchored_sutures:
        w("")
        w("# Instrument operations (docs/scenario-format.md, docs/operations.md); defaults elsewhere.")
        w("operations:")
        w("  anchor: {sutures: [suture_a, suture_b]}")
    return "\n".join(L) + "\n"


# ----------------------------------------------------------------------------------------------
# Main: build, verify, write
# ----------------------------------------------------------------------------------------------
class Failed(Exception):
    pass


def require(cond, what):
    if not cond:
        raise Failed(what)


def inside_bone(points, name):
    """Analytic inside test of the bone primitives (the mesh chords lie within 0.05 mm)."""
    p = np.asarray(points, dtype=float)
    if name == "humerus":
        e = np.sum(np.square((p - np.array(GT_C)) / np.array(GT_AX)), axis=1)
        rxy = np.hypot(p[:, 0] - NECK_C[0], p[:, 1] - NECK_C[1])
        z = p[:, 2]
        u = np.clip((z - NECK_Z[0]) / (NECK_Z[1] - NECK_Z[0]), 0, 1)
        cone = (z <= NECK_Z[0]) & (z >= NECK_Z[1]) & (rxy < NECK_R[0] + u * (NECK_R[1] - NECK_R[0]))
        shaft = (z >= SHAFT_Z[0]) & (z <= SHAFT_Z[1]) & (rxy < NECK_R[1])
        return (np.linalg.norm(p, axis=1) < HEAD_R) | (e < 1) | cone | shaft
    x0, y0, z0, x1, y1, z1 = ACRO_BOX
    box = np.all((p >= (x0, y0, z0)) & (p <= (x1, y1, z1)), axis=1)
    b, t = np.array(SPUR_BASE), np.array(SPUR_TIP)
    length = np.linalg.norm(t - b)
    a = (t - b) / length
    s = (p - b) @ a
    r = np.linalg.norm((p - b) - s[:, None] * a, axis=1)
    cone = (s >= 0) & (s <= length) & (r < SPUR_R[0] + s / length * (SPUR_R[1] - SPUR_R[0]))
    return box | cone


def near_obstacle(points, name, body, margin=6.0):
    """(number of points inside the body, min distance of the points to its surface, or inf if
    none is within margin). Bones use the analytic solids for inside-ness, soft bodies the
    winding number of their boundary; distances only look at triangles near the points."""
    xyz, tris = body["xyz"], body["surf"]
    if name in ("humerus", "acromion"):
        n_in = int(inside_bone(points, name).sum())
    else:
        lo, hi = xyz.min(axis=0) - 1, xyz.max(axis=0) + 1
        p = points[np.all((points >= lo) & (points <= hi), axis=1)]
        n_in = int((winding(p, xyz, tris) > 0.5).sum()) if len(p) else 0
    tri_lo, tri_hi = xyz[tris].min(axis=1), xyz[tris].max(axis=1)
    plo, phi = points.min(axis=0) - margin, points.max(axis=0) + margin
    near_tris = tris[np.all((tri_hi >= plo) & (tri_lo <= phi), axis=1)]
    if len(near_tris) == 0:
        return n_in, math.inf
    lo, hi = xyz[near_tris].min(axis=(0, 1)) - margin, xyz[near_tris].max(axis=(0, 1)) + margin
    p = points[np.all((points >= lo) & (points <= hi), axis=1)]
    if len(p) == 0:
        return n_in, math.inf
    d = point_tri_distance(p, xyz, near_tris).min()
    return n_in, float(d) if d < margin else math.inf


def build(log):
    gmsh_setup()
    try:
        hum = mesh_humerus()
        acro = mesh_acromion()
        muscle, tendon = mesh_cuff()
        biceps = mesh_biceps()
        points = anatomy_points()
    finally:
        gmsh.finalize()
    bodies = {}
    for name, (xyz, tris) in (("humerus", hum), ("acromion", acro)):
        tris, rep = orient_surface(xyz, tris)
        require(rep["euler"] == 2 and rep["volume"] > 0, "%s not a closed sphere-like surface" % name)
        bodies[name] = {"xyz": xyz, "tris": tris, "surf": tris, "rep": rep}
    for name, (xyz, tets) in (("supraspinatus_muscle", muscle),
                              ("supraspinatus_tendon", tendon), ("biceps_tendon", biceps)):
        tets = orient_tets(xyz, tets)
        vol = tet_volumes(xyz, tets)
        require(vol.min() > 0, "%s has degenerate tets" % name)
        surf, rep = orient_surface(xyz, tet_boundary(tets))
        require(rep["euler"] == 2, "%s boundary is not a closed sphere-like surface" % name)
        require(abs(rep["volume"] - vol.sum()) < 1e-6 * vol.sum(), "%s boundary volume" % name)
        rep["quality"] = tet_quality(xyz, tets)
        bodies[name] = {"xyz": xyz, "tets": tets, "surf": surf, "rep": rep}
    return bodies, points


def verify(bodies, points, log):
    B = bodies
    for name, b in B.items():
        r = b["rep"]
        if "tets" in b:
            log("%-22s %5d nodes %5d tets   (boundary %d tris, volume %.0f mm3, min quality %.3f)"
                % (name, len(b["xyz"]), len(b["tets"]), len(b["surf"]), r["volume"], r["quality"]))
        else:
            log("%-22s %5d nodes %5d tris   (closed, Euler %d, outward, volume %.0f mm3)"
                % (name, len(b["xyz"]), len(b["tris"]), r["euler"], r["volume"]))
    # Conforming muscle/tendon interface: bit-identical coordinates, all on the junction plane.
    m, t = B["supraspinatus_muscle"]["xyz"], B["supraspinatus_tendon"]["xyz"]
    shared = set(map(tuple, m)) & set(map(tuple, t))
    on_plane_t = int(np.sum(np.abs(t[:, 0] - TENDON_X[0]) < 1e-9))
    on_plane_m = int(np.sum(np.abs(m[:, 0] - TENDON_X[0]) < 1e-9))
    require(len(shared) > 0 and len(shared) == on_plane_t == on_plane_m,
            "interface not conforming: %d shared, %d/%d on plane" % (len(shared), on_plane_t,
                                                                     on_plane_m))
    log("muscle/tendon interface: %d nodes with bit-identical coordinates (all on x = %g); "
        "combined %d nodes, %d tets" % (len(shared), TENDON_X[0], len(m) + len(t) - len(shared),
                                        len(B["supraspinatus_muscle"]["tets"]) +
                                        len(B["supraspinatus_tendon"]["tets"])))
    # No soft body intersects a bone or another soft body (nodes, centroids, edge midpoints).
    soft = ["supraspinatus_muscle", "supraspinatus_tendon", "biceps_tendon"]
    for s in soft:
        pts = samples(B[s]["xyz"], B[s]["tets"])
        for o in ["humerus", "acromion"] + [x for x in soft if x != s]:
            if {s, o} == {"supraspinatus_muscle", "supraspinatus_tendon"}:
                continue
            n_in, dmin = near_obstacle(pts, o, B[o])
            require(n_in == 0, "%s intersects %s (%d points inside)" % (s, o, n_in))
            require(dmin > 0.5, "%s within %.3f mm of %s" % (s, dmin, o))
            if dmin < 5:
                log("clearance %-20s -> %-20s %.2f mm" % (s, o, dmin))
    # Subacromial space.
    head_top = B["humerus"]["xyz"][:, 2].max()
    log("subacromial space (acromion undersurface to head top): %.2f mm" % (ACRO_BOX[2] - head_top))
    # Regions.
    for rname, (body, box) in region_boxes().items():
        sel = in_box(B[body]["xyz"], box)
        require(sel.sum() > 0, "region %s is empty" % rname)
        log("region %-21s %-21s %4d nodes" % (rname, body, sel.sum()))
        if rname == "footprint":
            f = B[body]["xyz"][sel]
            log("  footprint extent: y %.1f..%.1f (AP %.1f), x %.1f..%.1f, z %.1f..%.1f"
                % (f[:, 1].min(), f[:, 1].max(), np.ptp(f[:, 1]), f[:, 0].min(),
                   f[:, 0].max(), f[:, 2].min(), f[:, 2].max()))
            # Every footprint vertex lies on the tuberosity, lateral of the articular margin.
            e = np.sum(np.square((f - np.array(GT_C)) / np.array(GT_AX)), axis=1)
            require(np.all(e > 1 - 1e-2), "footprint vertex on the articular surface")
        if rname in ("tendon_edge", "muscle_medial_end", "biceps_ends_proximal"):
            x = B[body]["xyz"][sel][:, 0]
            require(np.ptp(x) < 1e-9, "region %s is not a single end face" % rname)
        if rname == "biceps_ends_distal":
            require(np.ptp(B[body]["xyz"][sel][:, 2]) < 1e-9, "distal biceps end not planar")
    # Landmarks.
    def inside(p, body):
        return winding(np.array([p]), B[body]["xyz"], B[body]["surf"])[0] > 0.5

    def dist(p, body):
        return point_tri_distance(np.array([p]), B[body]["xyz"], B[body]["surf"])[0]

    for lname in ("footprint_center", "anchor_site_1", "anchor_site_2"):
        require(dist(points[lname], "humerus") < 0.1, "%s not on the humerus" % lname)
    require(dist(points["spur_tip"], "acromion") < 0.6, "spur_tip not on the acromion")
    for lname in ("tear_edge_center", "bite_target_1", "bite_target_2"):
        require(inside(points[lname], "supraspinatus_tendon"), "%s not in the tendon" % lname)
    require(inside(points["muscle_belly"], "supraspinatus_muscle"), "muscle_belly")
    require(inside(points["biceps_cut_site"], "biceps_tendon"), "biceps_cut_site")
    a1, a2 = points["anchor_site_1"], points["anchor_site_2"]
    log("anchor spacing %.2f mm; bite targets %.1f / %.1f mm (arc) from the tendon edge"
        % (np.linalg.norm(a1 - a2), 11.0, 11.0))
    arc, dx = retraction()
    require(10 <= dx and arc <= 15, "retraction outside 10-15 mm")
    log("tear edge to footprint medial edge: %.1f mm arc at mid-thickness, %.1f mm in x"
        % (arc, dx))
    free = [p for k, p in points.items() if k in ("subacromial_center", "glenohumeral_view")]
    free += [np.array(p) for p in PORTALS.values()] + [np.array(CAMERA["position"])]
    for p in free:
        for body in B:
            require(not inside(p, body), "point %s inside %s" % (p, body))
    for pname, p in PORTALS.items():
        r = np.linalg.norm(p)
        require(35 <= r <= 45, "portal %s at %.1f mm from the head centre" % (pname, r))
    cam = np.array(CAMERA["position"])
    require(min(dist(cam, b) for b in B) > 2.0 + 0.5, "camera tip too close to tissue")
    # Sutures: clear of everything except at the anchor.
    for sname, (s, e) in suture_lines(points, SUTURE_NODES_REPAIR).items():
        u = np.linspace(0, 1, SUTURE_NODES_REPAIR)[1:, None]
        pts = s + u * (e - s)
        for body in B:
            n_in, dmin = near_obstacle(pts, body, B[body])
            require(n_in == 0, "%s passes through %s" % (sname, body))
        require(dist(s, "humerus") < 0.1, "%s does not start on the bone" % sname)
    log("sutures: 2 x %d nodes, %.1f mm (the benchmark: %d), start 0.4 mm either side of "
        "anchor_site_1" % (SUTURE_NODES_REPAIR, np.linalg.norm(e - s), SUTURE_NODES_BENCH))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--out", default=os.path.join(here, "..", "scenarios"),
                    help="scenario directory (meshes go to OUT/meshes)")
    ap.add_argument("--check", action="store_true", help="build and verify only, write nothing")
    ap.add_argument("--quiet", action="store_true")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="override a parameter of tools/anatomic_shoulder.py or "
                    "tools/anatomic_bursa.py (a number), e.g. "
                    "NECK_SHAFT_DEG=128: shows that the dimension checks catch it")
    args = ap.parse_args()
    log = (lambda *_: None) if args.quiet else print
    # tools/anatomic_shoulder.py imports this file as gen_anatomy: share one module instance.
    sys.modules.setdefault("gen_anatomy", sys.modules[__name__])
    import anatomic_bursa
    import anatomic_shoulder
    for item in args.set:
        key, _, value = item.partition("=")
        owner = [m for m in (anatomic_shoulder, anatomic_bursa)
                 if isinstance(getattr(m, key, None), float)]
        if not owner:
            print("gen_anatomy: --set %s: not a numeric parameter of anatomic_shoulder.py or "
                  "anatomic_bursa.py" % key, file=sys.stderr)
            return 2
        setattr(owner[0], key, float(value))
    try:
        bodies, points = build(log)
        verify(bodies, points, log)
        log("-- anatomic scene (tools/anatomic_shoulder.py)")
        a_bodies, a_points, a_samples = anatomic_shoulder.build(log)
        anatomic_shoulder.verify(a_bodies, a_points, a_samples, log)
    except Failed as e:
        print("gen_anatomy: check failed: %s" % e, file=sys.stderr)
        return 1
    except (AssertionError, RuntimeError) as e:  # a boolean or mesh step gave a broken shape
        print("gen_anatomy: check failed: geometry: %s" % (e or type(e).__name__),
              file=sys.stderr)
        return 1
    files = {}
    for name in ("humerus", "acromion"):
        b = bodies[name]
        sub = "footprint" if name == "humerus" else "spur"
        _, box = region_boxes()[sub]
        tag = np.where(np.all(in_box(b["xyz"], box)[b["tris"]], axis=1), 2, 1)
        files["meshes/%s.msh" % name] = msh22_text(
            b["xyz"], np.column_stack([b["tris"], tag]), 2, [(1, name), (2, sub)])
    for name in ("supraspinatus_muscle", "supraspinatus_tendon", "biceps_tendon"):
        b = bodies[name]
        files["meshes/%s.msh" % name] = msh22_text(
            b["xyz"], np.column_stack([b["tets"], np.ones(len(b["tets"]), int)]), 4, [(1, name)])
    files["rotator_cuff_repair.yaml"] = scenario_text(
        "rotator_cuff_repair", 5.0, points, True,
        "arthroscopic repair of a retracted full-thickness supraspinatus tear", [],
        anchored_sutures=True)
    files["bench_full.yaml"] = scenario_text(
        "bench_full", 2.0, points, False, "benchmark, sized like the paper's model",
        ["", "Benchmark: the paper's model was one muscle, one tendon and two bones (muscle 627",
         "nodes / 2026 tets, tendon 398 / 1261, bones 3010 / 6016 and 69 / 134 triangles) plus",
         "two 60-node threads; this file uses the same meshes as rotator_cuff_repair.yaml",
         "without the biceps so the FEM size matches the paper."], anchored_sutures=False)
    files.update(anatomic_shoulder.files(a_bodies, a_points))
    if args.check:
        return 0
    for rel, text in sorted(files.items()):
        path = os.path.normpath(os.path.join(args.out, rel))
        os.makedirs(os.path.dirname(path), exist_ok=True)
        data = text.encode()
        with open(path, "wb") as f:
            f.write(data)
        log("wrote %-36s %8d bytes  sha256 %s" % (rel, len(data),
                                                   hashlib.sha256(data).hexdigest()[:16]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
