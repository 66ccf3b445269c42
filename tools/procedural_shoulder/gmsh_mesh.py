"""Gmsh primitives of the procedural shoulder: the deterministic session, size fields, node and
element tables, compact renumbering, the shell patch and single-volume booleans, and the spline
helpers (gmsh 4.8 Python API, OpenCASCADE kernel)."""

import math

import gmsh
import numpy as np

from .params import SEED


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


def rotation_to(v):
    """Axis and angle rotating +z onto the unit vector v."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, v)
    s = np.linalg.norm(axis)
    if s < 1e-12:
        return np.array([1.0, 0.0, 0.0]), (0.0 if v[2] > 0 else math.pi)
    return axis / s, math.atan2(s, float(np.dot(z, v)))


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
