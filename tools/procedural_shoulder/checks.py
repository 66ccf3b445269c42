"""Build and verify the procedural shoulder: mesh every body, orient and check it, then verify
the interface, clearances, regions, landmarks, portals, camera and sutures. A failed check
raises Failed naming what failed."""

import math

import gmsh
import numpy as np

from mesh_geometry import (in_box, orient_surface, orient_tets, point_tri_distance, samples,
                           tet_boundary, tet_quality, tet_volumes, winding)

from .bones import inside_bone, mesh_acromion, mesh_humerus
from .gmsh_mesh import gmsh_setup
from .landmarks import (CAMERA, PORTALS, SUTURE_NODES_BENCH, SUTURE_NODES_REPAIR, anatomy_points,
                        region_boxes, retraction, suture_lines)
from .params import ACRO_BOX, GT_AX, GT_C, TENDON_X
from .soft_tissue import mesh_biceps, mesh_cuff


class Failed(Exception):
    pass


def require(cond, what):
    if not cond:
        raise Failed(what)


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
