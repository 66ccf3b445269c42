"""Bones of the procedural shoulder: the humerus (head, greater tuberosity with the
supraspinatus footprint, neck and shaft stump) and the acromion with its anterior spur, as
closed triangle surfaces; their analytic inside test and the tuberosity's surface points."""

import math

import gmsh
import numpy as np

from .gmsh_mesh import background_size, boundary_triangles, single_volume
from .params import (ACRO_BOX, FOOTPRINT_ML, GT_AX, GT_C, H_ACRO, H_HUM_COARSE, H_HUM_FINE,
                     H_HUM_RAMP, HEAD_R, NECK_C, NECK_R, NECK_Z, SHAFT_Z, SPUR_BASE, SPUR_R,
                     SPUR_TIP)


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


def gt_normal(p):
    """Outward unit normal of the greater-tuberosity ellipsoid at p."""
    n = (np.asarray(p) - np.array(GT_C)) / np.square(np.array(GT_AX))
    return n / np.linalg.norm(n)


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
