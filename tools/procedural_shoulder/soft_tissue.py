"""Soft tissue of the procedural shoulder as tetrahedral meshes: the supraspinatus muscle and its
torn, retracted tendon (meshed together, one conforming interface face) and the long head of
biceps (a tube along its spline centreline)."""

import math

import gmsh
import numpy as np

from .gmsh_mesh import (background_size, compact, elements_of, node_table, rotation_to,
                        shell_patch, single_volume)
from .params import (BICEPS_PATH, BICEPS_R, BICEPS_X0, BICEPS_Z1, CUFF_GAP, H_BICEPS,
                     H_MUSCLE, H_TENDON, HEAD_R, MUSCLE_SECTIONS, TENDON_HALF_W, TENDON_T,
                     TENDON_X)


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
