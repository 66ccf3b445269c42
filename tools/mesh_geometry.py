#!/usr/bin/python3
"""Triangle and tetrahedron mesh geometry for tools/gen_anatomy.py and tools/anatomic_shoulder.py:
orientation, volumes, boundaries, quality, winding numbers, point-triangle distances, and the
Gmsh 2.2 / YAML number writers. numpy only; deterministic."""

import math

import numpy as np

# ----------------------------------------------------------------------------------------------
# Mesh checks
# ----------------------------------------------------------------------------------------------
def orient_surface(xyz, tris):
    """Makes a closed triangle surface consistently outward oriented. Returns (tris, report)
    where report has the edge/Euler checks. Raises if the surface is not a closed manifold."""
    tris = tris.copy()
    edges = {}
    for i, (a, b, c) in enumerate(tris):
        for u, v in ((a, b), (b, c), (c, a)):
            edges.setdefault((min(u, v), max(u, v)), []).append(i)
    bad = [e for e, f in edges.items() if len(f) != 2]
    if bad:
        raise RuntimeError("surface not closed/manifold: %d bad edges" % len(bad))
    # Breadth-first propagation of a consistent orientation from triangle 0.
    flip = np.full(len(tris), -1)
    flip[0] = 0
    queue = [0]
    while queue:
        i = queue.pop()
        t = tris[i][::-1] if flip[i] else tris[i]
        for u, v in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            for j in edges[(min(u, v), max(u, v))]:
                if j == i or flip[j] >= 0:
                    continue
                tj = list(tris[j])
                # Consistent neighbour traverses the shared edge as (v, u).
                same = any(tj[k] == u and tj[(k + 1) % 3] == v for k in range(3))
                flip[j] = 1 if same else 0
                queue.append(j)
    if (flip < 0).any():
        raise RuntimeError("surface has several connected components")
    tris[flip == 1] = tris[flip == 1][:, ::-1]
    if signed_volume(xyz, tris) < 0:
        tris = tris[:, ::-1].copy()
    directed = set()
    for a, b, c in tris:
        for u, v in ((a, b), (b, c), (c, a)):
            if (u, v) in directed:
                raise RuntimeError("orientation not consistent")
            directed.add((u, v))
    euler = len(np.unique(tris)) - len(edges) + len(tris)
    return tris, {"edges": len(edges), "euler": euler, "volume": signed_volume(xyz, tris)}


def signed_volume(xyz, tris):
    a, b, c = xyz[tris[:, 0]], xyz[tris[:, 1]], xyz[tris[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def tet_volumes(xyz, tets):
    p0 = xyz[tets[:, 0]]
    return np.einsum("ij,ij->i", xyz[tets[:, 1]] - p0,
                     np.cross(xyz[tets[:, 2]] - p0, xyz[tets[:, 3]] - p0)) / 6.0


def orient_tets(xyz, tets):
    """Positive orientation (p1-p0).((p2-p0)x(p3-p0)) > 0, as TetMesh requires."""
    tets = tets.copy()
    neg = tet_volumes(xyz, tets) < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return tets


def tet_boundary(tets):
    """Outward boundary triangles of positively oriented tets (faces used once)."""
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]],
                            tets[:, [0, 2, 1]]])
    key = np.sort(faces, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[cnt[inv.ravel()] == 1]


def tet_quality(xyz, tets):
    """Minimum over tets of the normalised volume/edge^3 ratio (1 for a regular tet)."""
    v = tet_volumes(xyz, tets)
    e = [np.linalg.norm(xyz[tets[:, i]] - xyz[tets[:, j]], axis=1)
         for i, j in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))]
    lrms = np.sqrt(np.mean(np.square(e), axis=0))
    return float(np.min(6.0 * math.sqrt(2.0) * v / lrms ** 3))


def winding(points, xyz, tris):
    """Generalised winding number of each point w.r.t. a closed oriented surface (1 inside)."""
    out = np.zeros(len(points))
    for s in range(0, len(points), 256):
        p = points[s:s + 256, None, :]
        a, b, c = xyz[tris[:, 0]] - p, xyz[tris[:, 1]] - p, xyz[tris[:, 2]] - p
        la, lb, lc = (np.linalg.norm(v, axis=2) for v in (a, b, c))
        det = np.einsum("ijk,ijk->ij", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ijk,ijk->ij", a, b) * lc +
               np.einsum("ijk,ijk->ij", b, c) * la + np.einsum("ijk,ijk->ij", c, a) * lb)
        out[s:s + 256] = np.arctan2(det, den).sum(axis=1) / (2.0 * math.pi)
    return out


def point_tri_distance(points, xyz, tris):
    """Unsigned distance from each point to a triangle mesh (closest-point regions)."""
    best = np.full(len(points), np.inf)
    A, B, C = xyz[tris[:, 0]], xyz[tris[:, 1]], xyz[tris[:, 2]]
    for s in range(0, len(points), 128):
        p = points[s:s + 128, None, :]
        ab, ac, ap = B - A, C - A, p - A
        d1, d2 = np.einsum("jk,ijk->ij", ab, ap), np.einsum("jk,ijk->ij", ac, ap)
        bp = p - B
        d3, d4 = np.einsum("jk,ijk->ij", ab, bp), np.einsum("jk,ijk->ij", ac, bp)
        cp = p - C
        d5, d6 = np.einsum("jk,ijk->ij", ab, cp), np.einsum("jk,ijk->ij", ac, cp)
        va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
        with np.errstate(divide="ignore", invalid="ignore"):
            denom = va + vb + vc
            v = vb / denom
            w = vc / denom
            q = A + v[..., None] * ab + w[..., None] * ac            # interior
            t_ab = np.clip(d1 / (d1 - d3), 0, 1)
            t_ac = np.clip(d2 / (d2 - d6), 0, 1)
            t_bc = np.clip((d4 - d3) / ((d4 - d3) + (d5 - d6)), 0, 1)
        q = np.where(((vc <= 0) & (d1 >= 0) & (d3 <= 0))[..., None],
                     A + t_ab[..., None] * ab, q)
        q = np.where(((vb <= 0) & (d2 >= 0) & (d6 <= 0))[..., None],
                     A + t_ac[..., None] * ac, q)
        q = np.where(((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0))[..., None],
                     B + t_bc[..., None] * (C - B), q)
        q = np.where(((d1 <= 0) & (d2 <= 0))[..., None], A, q)
        q = np.where(((d3 >= 0) & (d4 <= d3))[..., None], B, q)
        q = np.where(((d6 >= 0) & (d5 <= d6))[..., None], C, q)
        best[s:s + 128] = np.linalg.norm(p - q, axis=2).min(axis=1)
    return best


def samples(xyz, tets):
    """Nodes and tet centroids: points that must all lie outside obstacles."""
    return np.concatenate([xyz, xyz[tets].mean(axis=1)])


def in_box(xyz, box):
    lo, hi = np.array(box[0]), np.array(box[1])
    return np.all((xyz >= lo) & (xyz <= hi), axis=1)


# ----------------------------------------------------------------------------------------------
# Writers
# ----------------------------------------------------------------------------------------------
def msh22_text(xyz, elems, etype, groups):
    """Gmsh 2.2 ASCII. groups: list of (physical tag, name); elems carry their tag in the
    last column. Doubles are written with repr, which round-trips exactly."""
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(groups))]
    dim = {2: 2, 4: 3}[etype]
    lines += ['%d %d "%s"' % (dim, tag, name) for tag, name in groups]
    lines += ["$EndPhysicalNames", "$Nodes", str(len(xyz))]
    lines += ["%d %r %r %r" % (i + 1, float(p[0]), float(p[1]), float(p[2]))
              for i, p in enumerate(xyz)]
    lines += ["$EndNodes", "$Elements", str(len(elems))]
    for i, row in enumerate(elems):
        conn, tag = row[:-1], int(row[-1])
        lines.append("%d %d 2 %d %d %s" % (i + 1, etype, tag, tag,
                                            " ".join(str(int(n) + 1) for n in conn)))
    lines += ["$EndElements", ""]
    return "\n".join(lines)


def fmt(v):
    """Short, stable decimal for YAML (3 decimals, no trailing zeros, no -0)."""
    s = "%.3f" % (round(float(v), 3) + 0.0)
    s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def vec(p):
    return "[%s]" % ", ".join(fmt(c) for c in p)
