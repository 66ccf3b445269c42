"""Anatomic variant of the procedural shoulder (tools/gen_anatomy.py --anatomic).

Same frame, head centre, head radius, footprint, supraspinatus muscle and torn tendon (the cuff
meshes are byte-identical to the primitive scene's), with:
  - humerus: head as a sphere segment on an anatomical neck (neck-shaft angle, retroversion),
    greater tuberosity (today's, carrying the footprint), lesser tuberosity, bicipital groove
    between them, metaphysis and shaft; the articular cartilage is the physical group
    `cartilage` (sphere triangles inside the segment, outside the footprint);
  - acromion: a loft of elliptic sections with a curved undersurface (Bigliani type II curve)
    and the anterior hook (the primitive scene's spur cone, type III);
  - glenoid (scapula part): concave glenoid face, labrum rim, supraglenoid tubercle, scapular
    neck stump and coracoid process, one rigid body with groups glenoid / labrum /
    supraglenoid_tubercle / coracoid;
  - coracoacromial_ligament: a flat band from the coracoid to the anterior acromion (rigid);
  - biceps_tendon: starts at the supraglenoid tubercle, crosses the rotator interval in front
    of the supraspinatus and runs down the bicipital groove (same distal course and diameter).
Every dimension is measured on the meshes by verify_dimensions() and must lie in the cited
range (scenarios/README.md, "Anatomic scene").
"""

import math

import gmsh
import numpy as np

import anatomic_bursa as bursa
import gen_anatomy as base

# ----------------------------------------------------------------------------------------------
# Parameters (mm, degrees). Sources: scenarios/README.md "Anatomic scene".
# ----------------------------------------------------------------------------------------------
NECK_SHAFT_DEG = 132.5       # Boileau & Walch 1997: 129.6 (123-136); issue range 130-135
RETROVERSION_DEG = 25.0      # Boileau & Walch 1997: 17.9 +- 13.7; issue range 20-30
HEAD_HALF_ARC_DEG = 85.0     # segment half-angle: thickness R(1 - cos) = 20.5 mm (Iannotti: 15-24)
NECK_R = (18.5, 15.0)        # anatomical neck frustum radius at the cut plane / distal end
NECK_LEN = 16.0              # its length along -head axis
LT_C = (-3.0, 16.0, -8.0)    # lesser-tuberosity ellipsoid centre
LT_AX = (8.0, 8.0, 12.0)     # its semi-axes
GROOVE_R = 4.0               # bicipital groove channel radius (centred on the biceps axis)
GROOVE_MASS_R = 9.0          # tuberosity mass swept along the groove, radius
GROOVE_MASS_SHIFT = 8.0      # its axis 8 mm posterior of the biceps axis (mass top 1 mm proud)
GROOVE_TOP_Z = 2.0           # the groove (and its mass) start below this level

# Glenoid: faces lateral, 25 deg anterior (scapular plane ~30 deg to coronal, glenoid ~5 deg
# retroverted) and 4 deg superior (Churchill 2001: inclination 4.2); face centre 3 mm from the
# head (cartilage + joint space), 5 mm below the head centre (arm at the side).
GLENOID_FACING = (25.0, 4.0)             # anterior, superior tilt of the face normal (deg)
GLENOID_GAP = 3.0
GLENOID_DROP = 5.0
GLENOID_AX = (12.5, 17.5)                # semi-axes AP x SI (Churchill 2001: 23.6-27.8 x 32.6-37.5)
GLENOID_FACE_R = 35.0                    # bony face radius of curvature (> head: cartilage fills)
GLENOID_DEPTH = 5.0                      # glenoid rim bone behind the face centre
LABRUM_W, LABRUM_H = 2.5, 3.0            # labrum width on the rim, height above the face
TUBERCLE_C = (-22.5, -9.2, 14.5)        # supraglenoid tubercle (ellipsoid)
TUBERCLE_AX = (3.5, 2.0, 3.0)
CORACOID_PATH = [(-29.0, -12.0, 0.0), (-30.0, -10.0, 2.0), (-32.0, -4.0, 8.0), (-33.0, 7.0, 10.0),
                 (-28.5, 22.0, 13.5), (-18.0, 29.0, 18.5)]
CORACOID_R = 4.5

# Acromion sections (y, x_centre, z_centre, half-width x, half-thickness z): undersurface
# z_centre - half-thickness; 32.5 over the head (acromiohumeral 10 mm), rising posteriorly,
# falling anteriorly (type II curve) into the spur cone (hook, type III).
ACRO_SECTIONS = [(-28.0, 8.0, 37.0, 12.0, 3.5), (-18.0, 9.0, 36.4, 14.0, 3.9),
                 (-6.0, 9.0, 36.4, 15.0, 3.9), (6.0, 10.0, 36.2, 14.0, 3.7),
                 (14.0, 11.0, 35.6, 11.0, 3.6)]
CAL_ENDS = ((-17.0, 27.0, 21.0), (4.0, 12.0, 32.2))   # coracoid end, acromion end (centres)
CAL_HALF_W = (4.5, 7.0)                              # half-width at each end
CAL_HALF_T = 1.2                                     # half-thickness

# Biceps: from the supraglenoid tubercle (end plane y = BICEPS_Y0) in front of the supraspinatus
# to the groove; the distal part is the primitive scene's path.
BICEPS_PATH = [(-22.5, -12.0, 16.3), (-22.5, -6.5, 16.5), (-23.0, 4.0, 15.0), (-21.0, 13.0, 12.5),
               (-16.5, 18.5, 11.5), (-10.0, 23.5, 12.0), (1.0, 26.5, 5.0), (6.5, 25.0, -6.0), (6.5, 20.0, -18.0),
               (6.0, 16.5, -30.0), (6.0, 16.0, -40.0)]
BICEPS_Y0 = -6.5
GROOVE_PATH_FROM = 5         # the groove mass follows BICEPS_PATH from (-10, 23.5, 12) on
BICEPS_Z1 = base.BICEPS_Z1

H_HUM_FINE, H_HUM_COARSE, H_HUM_RAMP = 1.09, 2.1, 0.12
H_ACRO, H_GLENOID, H_CAL = 2.4, 2.6, 2.0
H_BICEPS = base.H_BICEPS

# Cited ranges the measured meshes must meet (checked by verify_dimensions).
RANGES = {
    "neck_shaft_angle_deg": (130.0, 135.0),     # issue; Boileau & Walch 1997 123-136
    "retroversion_deg": (20.0, 30.0),           # issue; Boileau & Walch 1997 17.9 +- 13.7
    "head_radius_mm": (22.0, 24.5),             # Iannotti 1992: 24 (19-28); Boileau 1997: 23
    "head_thickness_mm": (15.0, 24.0),          # Iannotti 1992: 19 (15-24)
    "footprint_ap_mm": (22.0, 24.0),            # Curtis 2006: 23
    "groove_depth_mm": (4.0, 6.0),              # Cone 1983: 4-6 (normal)
    "groove_width_mm": (7.0, 11.0),             # Cone 1983 / Pfahler 1999: ~8-11
    "glenoid_height_mm": (32.6, 37.5),          # Churchill 2001 (women-men means)
    "glenoid_width_mm": (23.6, 27.8),           # Churchill 2001
    "labrum_height_mm": (2.0, 5.0),             # Howell & Galinat 1989: doubles the depth
    "acromion_thickness_mm": (6.0, 9.0),        # Nicholson 1996: means 6.7 (F), 7.7 (M)
    "acromion_width_mm": (19.0, 31.0),          # not cited: Nicholson 1996 means 18.4-19.5
    "acromiohumeral_mm": (9.0, 10.5),           # Petersson 1984: 9-10 normal
    "hook_drop_mm": (2.0, 6.0),                 # Bigliani 1986 type III: anterior hook
    "cal_length_mm": (25.0, 40.0),              # BioMed Res Int 2019: 34.9 +- 4.6 (lateral)
    "biceps_diameter_mm": (5.0, 6.0),           # not cited (LHB ~5-6 mm)
    "bursa_thickness_mm": (0.5, 2.0),           # Tsai 2007: normally < 2 mm on ultrasound
}


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def head_axis():
    """Unit vector from the head centre to the centre of the articular surface: medial,
    superior by (neck-shaft - 90) deg, and posterior by the retroversion."""
    e = math.radians(NECK_SHAFT_DEG - 90.0)
    r = math.radians(RETROVERSION_DEG)
    return np.array([-math.cos(e) * math.cos(r), -math.cos(e) * math.sin(r), math.sin(e)])


def frame_from(w, up=(0.0, 0.0, 1.0)):
    """Orthonormal (u, v, w): v as close to `up` as possible."""
    w = unit(w)
    v = np.asarray(up, float) - np.dot(up, w) * w
    if np.linalg.norm(v) < 1e-9:
        v = np.array([0.0, 1.0, 0.0]) - w[1] * w
    v = unit(v)
    return np.cross(v, w), v, w


def place(dimtags, u, v, w, origin, scale=(1.0, 1.0, 1.0)):
    """Maps local (x, y, z) to origin + sx x u + sy y v + sz z w (affine)."""
    a = [u * scale[0], v * scale[1], w * scale[2]]
    m = []
    for i in range(3):
        m += [a[0][i], a[1][i], a[2][i], origin[i]]
    gmsh.model.occ.affineTransform(dimtags, m)


def glenoid_frame():
    """(u = anterior in the face, v = superior in the face, n = face normal toward the head,
    face centre)."""
    a, s = (math.radians(x) for x in GLENOID_FACING)
    n = np.array([math.cos(s) * math.cos(a), math.cos(s) * math.sin(a), math.sin(s)])
    centre = -(base.HEAD_R + GLENOID_GAP) * n + np.array([0.0, 0.0, -GLENOID_DROP])
    v = unit(np.array([0.0, 0.0, 1.0]) - n[2] * n)
    u = np.cross(n, v)       # n x v: anterior-ish
    return u, v, n, centre


# ----------------------------------------------------------------------------------------------
# Geometry
# ----------------------------------------------------------------------------------------------
def fuse_all(parts):
    out, _ = gmsh.model.occ.fuse(parts[:1], parts[1:])
    return out


def humerus_geometry():
    occ = gmsh.model.occ
    h = head_axis()
    u, v, w = frame_from(h, (0.0, 1.0, 0.0))
    R = base.HEAD_R
    d = R * math.cos(math.radians(HEAD_HALF_ARC_DEG))
    sphere = occ.addSphere(0, 0, 0, R)
    keep = occ.addBox(-R - 5, -R - 5, 0, 2 * R + 10, 2 * R + 10, R + 5)
    place([(3, keep)], u, v, w, d * h)
    head, _ = occ.intersect([(3, sphere)], [(3, keep)])
    neck = occ.addCone(0, 0, 0.5, 0, 0, -NECK_LEN - 0.5, NECK_R[0], NECK_R[1])
    place([(3, neck)], u, v, w, d * h)
    gt = occ.addSphere(0, 0, 0, 1.0)
    occ.dilate([(3, gt)], 0, 0, 0, *base.GT_AX)
    occ.translate([(3, gt)], *base.GT_C)
    lt = occ.addSphere(0, 0, 0, 1.0)
    occ.dilate([(3, lt)], 0, 0, 0, *LT_AX)
    occ.translate([(3, lt)], *LT_C)
    meta = occ.addCone(base.NECK_C[0], base.NECK_C[1], base.NECK_Z[0], 0, 0,
                       base.NECK_Z[1] - base.NECK_Z[0], *base.NECK_R)
    shaft = occ.addCylinder(base.NECK_C[0], base.NECK_C[1], base.SHAFT_Z[0], 0, 0,
                            base.SHAFT_Z[1] - base.SHAFT_Z[0], base.NECK_R[1])
    # Tuberosity mass along the groove, then the groove channel cut into it.
    below = occ.addBox(-60, -60, base.SHAFT_Z[0], 120, 120, GROOVE_TOP_Z - base.SHAFT_Z[0])
    mass_path = [(x, y - GROOVE_MASS_SHIFT, z) for x, y, z in BICEPS_PATH[GROOVE_PATH_FROM:]]
    mass = pipe(mass_path, GROOVE_MASS_R)
    mass, _ = occ.intersect(mass, [(3, below)], removeTool=False)
    parts = head + [(3, neck), (3, gt), (3, lt), (3, meta), (3, shaft)] + mass
    bone = fuse_all(parts)
    channel = pipe(BICEPS_PATH[GROOVE_PATH_FROM - 1:], GROOVE_R)
    channel, _ = occ.intersect(channel, [(3, below)])
    out, _ = occ.cut(bone, channel)
    return base.single_volume(out)


def pipe(path, radius):
    """Solid tube of `radius` along an interpolating spline through `path`."""
    occ = gmsh.model.occ
    pts = [occ.addPoint(*p) for p in path]
    wire = occ.addWire([occ.addSpline(pts)])
    p0, p1 = np.array(path[0]), np.array(path[1])
    disk = occ.addDisk(0, 0, 0, radius, radius)
    axis, angle = base.rotation_to(unit(p1 - p0))
    occ.rotate([(2, disk)], 0, 0, 0, *axis, angle)
    occ.translate([(2, disk)], *p0)
    return [d for d in occ.addPipe([(2, disk)], wire) if d[0] == 3]


def acromion_geometry():
    occ = gmsh.model.occ
    wires = []
    for y, xc, zc, a, b in ACRO_SECTIONS:
        e = occ.addEllipse(0, 0, 0, a, b)      # in the local xy plane, major axis along x
        # local x -> world x, local y -> world z, plane normal -> world -y
        place([(1, e)], np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([0, -1.0, 0]),
              (xc, y, zc))
        wires.append(occ.addWire([e]))
    plate = [d for d in occ.addThruSections(wires, makeSolid=True, makeRuled=False) if d[0] == 3]
    b, t = np.array(base.SPUR_BASE), np.array(base.SPUR_TIP)
    spur = occ.addCone(*b, *(t - b), *base.SPUR_R)
    out, _ = occ.fuse(plate, [(3, spur)])
    return base.single_volume(out)


def glenoid_geometry():
    occ = gmsh.model.occ
    u, v, n, c = glenoid_frame()
    a, b = GLENOID_AX
    # Bony glenoid: elliptic cylinder along -n from 6 mm in front of the face centre to
    # GLENOID_DEPTH behind it, its head side cut by the face sphere (concave face).
    body = occ.addCylinder(0, 0, 0, 0, 0, 1, 1.0)
    place([(3, body)], u, v, -n, c + 6.0 * n, (a, b, 6.0 + GLENOID_DEPTH))
    face_c = c + GLENOID_FACE_R * n
    face = occ.addSphere(*face_c, GLENOID_FACE_R)
    glen, _ = occ.cut([(3, body)], [(3, face)], removeTool=False)
    # Labrum: elliptic ring around the rim, its top LABRUM_H proud of the face.
    ring_o = occ.addCylinder(0, 0, 0, 0, 0, 1, 1.0)
    place([(3, ring_o)], u, v, -n, c + 10.0 * n, (a + LABRUM_W, b + LABRUM_W, 9.5))
    ring_i = occ.addCylinder(0, 0, 0, 0, 0, 1, 1.0)
    place([(3, ring_i)], u, v, -n, c + 11.0 * n, (a - 0.5, b - 0.5, 16.0))
    ring, _ = occ.cut([(3, ring_o)], [(3, ring_i)])
    top = occ.addSphere(*(face_c + LABRUM_H * n), GLENOID_FACE_R)
    ring, _ = occ.cut(ring, [(3, top)])
    # Scapular neck behind the glenoid: the vault tapers medially.
    neck = occ.addCone(0, 0, 0, 0, 0, 16.0, 1.0, 0.6)
    place([(3, neck)], u, v, -n, c - (GLENOID_DEPTH - 1.0) * n, (a, b, 1.0))
    tub = occ.addSphere(0, 0, 0, 1.0)
    occ.dilate([(3, tub)], 0, 0, 0, *TUBERCLE_AX)
    occ.translate([(3, tub)], *TUBERCLE_C)
    cor = pipe(CORACOID_PATH, CORACOID_R)
    tip = occ.addSphere(*CORACOID_PATH[-1], CORACOID_R)
    out = fuse_all(glen + ring + [(3, neck), (3, tub), (3, tip)] + cor)
    return base.single_volume(out)


def cal_geometry():
    occ = gmsh.model.occ
    p0, p1 = (np.array(p) for p in CAL_ENDS)
    axis = unit(p1 - p0)
    # Band: wide across (horizontal, perpendicular to the axis), thin roughly vertical.
    across = unit(np.cross(axis, [0.0, 0.0, 1.0]))
    thin = np.cross(across, axis)
    wires = []
    for p, hw in ((p0, CAL_HALF_W[0]), (p1, CAL_HALF_W[1])):
        e = occ.addEllipse(0, 0, 0, hw, CAL_HALF_T)
        place([(1, e)], across, thin, axis, p)
        wires.append(occ.addWire([e]))
    out = [d for d in occ.addThruSections(wires, makeSolid=True, makeRuled=True) if d[0] == 3]
    return base.single_volume(out)


def biceps_geometry():
    occ = gmsh.model.occ
    tube = pipe(BICEPS_PATH, base.BICEPS_R)
    keep = occ.addBox(-100.0, BICEPS_Y0, BICEPS_Z1, 200.0, 200.0, 200.0)
    out, _ = occ.intersect(tube, [(3, keep)])
    return base.single_volume(out)


def mesh_surface(name, geometry, size):
    gmsh.model.add(name)
    vol = geometry()
    base.background_size(size)
    gmsh.model.mesh.generate(2)
    return base.boundary_triangles(vol)


def build_meshes():
    """{name: (xyz, tris or tets)} of the anatomic scene (gmsh must be initialised)."""
    fx, fy, fz = base.footprint_center()
    out = {}
    out["humerus"] = mesh_surface(
        "humerus", humerus_geometry, "min(%r, %r + %r*sqrt((x-%r)^2+(y-%r)^2+(z-%r)^2))" % (
            H_HUM_COARSE, H_HUM_FINE, H_HUM_RAMP, fx, fy, fz))
    out["acromion"] = mesh_surface("acromion", acromion_geometry, "%r" % H_ACRO)
    out["glenoid"] = mesh_surface("glenoid", glenoid_geometry, "%r" % H_GLENOID)
    out["coracoacromial_ligament"] = mesh_surface("cal", cal_geometry, "%r" % H_CAL)
    out["supraspinatus_muscle"], out["supraspinatus_tendon"] = base.mesh_cuff()
    gmsh.model.add("biceps")
    vol = biceps_geometry()
    base.background_size("%r" % H_BICEPS)
    gmsh.model.mesh.generate(3)
    out["biceps_tendon"] = base.compact(base.elements_of(3, vol, 4), base.node_table())
    out[bursa.NAME] = bursa.mesh()
    return out


def biceps_centreline_at_x(x):
    """First crossing of the biceps centreline with the plane x (after the tubercle)."""
    c, lo, hi = base.spline_curve(BICEPS_PATH)
    ts = np.linspace(lo[0], hi[0], 2001)
    xs = np.array(gmsh.model.getValue(1, c, list(ts))).reshape(-1, 3)
    ys = xs[:, 1]
    # past the tubercle end plane, first sample whose x reaches `x` while x is rising
    i = int(np.argmax((ys > BICEPS_Y0) & (xs[:, 0] >= x) & (np.arange(len(ts)) > 0)))
    p = base.crossing_x(c, ts[i - 1], ts[i], x)
    samples = xs
    gmsh.model.remove()
    return p, samples


# ----------------------------------------------------------------------------------------------
# Groups (physical tags) of the rigid bodies
# ----------------------------------------------------------------------------------------------
def humerus_groups(xyz, tris, footprint_box):
    """Tag per triangle: 1 humerus, 2 footprint, 3 cartilage (on the head sphere inside the
    articular segment)."""
    h = head_axis()
    cosa = math.cos(math.radians(HEAD_HALF_ARC_DEG))
    r = np.linalg.norm(xyz, axis=1)
    on_cap = (np.abs(r - base.HEAD_R) < 0.02) & (xyz @ h >= base.HEAD_R * cosa - 1e-6)
    tag = np.ones(len(tris), dtype=int)
    tag[np.all(on_cap[tris], axis=1)] = 3
    tag[np.all(base.in_box(xyz, footprint_box)[tris], axis=1)] = 2
    return tag


def glenoid_groups(xyz, tris):
    """Tag per triangle: 1 glenoid (bone and face), 2 labrum, 3 supraglenoid tubercle,
    4 coracoid."""
    u, v, n, c = glenoid_frame()
    cen = xyz[tris].mean(axis=1)
    rel = cen - c
    a, b = GLENOID_AX
    ell = (rel @ u / a) ** 2 + (rel @ v / b) ** 2
    depth = -(rel @ n)                        # behind the face centre
    labrum = (ell > 1.0 - 1e-3) & (depth < 3.0) & (ell < ((a + LABRUM_W + 0.5) / a) ** 2)
    t = (cen - np.array(TUBERCLE_C)) / (np.array(TUBERCLE_AX) + 0.6)
    tub = np.sum(t * t, axis=1) < 1.0
    cor = coracoid_distance(cen) < CORACOID_R + 0.6
    tag = np.ones(len(tris), dtype=int)
    tag[labrum] = 2
    tag[tub & ~labrum] = 3
    tag[cor & ~labrum & ~tub] = 4
    return tag


def coracoid_distance(p):
    """Distance of points to the coracoid centreline polyline (mm)."""
    best = np.full(len(p), np.inf)
    for a, b in zip(CORACOID_PATH[:-1], CORACOID_PATH[1:]):
        a, b = np.array(a), np.array(b)
        t = np.clip((p - a) @ (b - a) / np.dot(b - a, b - a), 0, 1)
        best = np.minimum(best, np.linalg.norm(p - (a + t[:, None] * (b - a)), axis=1))
    return best


GROUP_NAMES = {
    "humerus": [(1, "humerus"), (2, "footprint"), (3, "cartilage")],
    "acromion": [(1, "acromion"), (2, "spur")],
    "glenoid": [(1, "glenoid"), (2, "labrum"), (3, "supraglenoid_tubercle"), (4, "coracoid")],
    "coracoacromial_ligament": [(1, "coracoacromial_ligament")],
}


# ----------------------------------------------------------------------------------------------
# Measurements on the meshes
# ----------------------------------------------------------------------------------------------
def measure(bodies, biceps_samples):
    """Dimensions measured on the meshes (not read back from the parameters)."""
    M = {}
    hum = bodies["humerus"]
    xyz, tris, tag = hum["xyz"], hum["tris"], hum["tag"]
    cart = tris[tag == 3]
    # Cartilage margin: its boundary edges (used once within the cartilage group).
    edges = {}
    for t in cart:
        for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            k = (min(a, b), max(a, b))
            edges[k] = edges.get(k, 0) + 1
    rim = np.unique([k for k, c in edges.items() if c == 1])
    cv = np.unique(cart)
    centre = np.zeros(3)   # the head sphere centre (fitted below as a check of the radius)
    A = np.column_stack([2 * xyz[cv], np.ones(len(cv))])
    sol = np.linalg.lstsq(A, np.sum(xyz[cv] ** 2, axis=1), rcond=None)[0]
    centre = sol[:3]
    M["head_radius_mm"] = float(math.sqrt(sol[3] + centre @ centre))
    M["head_centre_offset_mm"] = float(np.linalg.norm(centre))
    # Anatomical-neck plane: the part of the margin on the medial/inferior side, where the
    # segment is cut (laterally the margin is the crease with the tuberosities).
    h_guess = unit(xyz[cv].mean(axis=0) - centre)
    ang = np.degrees(np.arccos(np.clip((xyz[rim] - centre) @ h_guess /
                                       np.linalg.norm(xyz[rim] - centre, axis=1), -1, 1)))
    plane_pts = xyz[rim][ang > np.percentile(ang, 40)]
    q = plane_pts - plane_pts.mean(axis=0)
    normal = np.linalg.svd(q)[2][2]
    if normal @ h_guess < 0:
        normal = -normal
    M["neck_shaft_angle_deg"] = float(np.degrees(np.arccos(-normal[2])))
    M["retroversion_deg"] = float(np.degrees(math.atan2(-normal[1], -normal[0])))
    M["head_thickness_mm"] = float((xyz[cv] - centre).dot(normal).max() -
                                   (plane_pts - centre).dot(normal).mean())
    f = xyz[np.unique(tris[tag == 2])]
    M["footprint_ap_mm"] = float(np.ptp(f[:, 1]))
    M["groove_depth_mm"], M["groove_width_mm"] = groove_size(xyz, biceps_samples)
    # Glenoid face (group 1 triangles facing the head, inside the rim ellipse).
    g = bodies["glenoid"]
    u, v, n, c = glenoid_frame()
    gl = g["xyz"][np.unique(g["tris"][g["tag"] == 1])]
    rel = gl - c
    face = (np.abs(-(rel @ n)) < 7.0) & (((rel @ u) / GLENOID_AX[0]) ** 2 +
                                         ((rel @ v) / GLENOID_AX[1]) ** 2 <= 1.0 + 1e-6)
    M["glenoid_height_mm"] = float(np.ptp(rel[face] @ v))
    M["glenoid_width_mm"] = float(np.ptp(rel[face] @ u))
    lab = g["xyz"][np.unique(g["tris"][g["tag"] == 2])]
    # how far the labrum stands proud of the bony face surface (its sphere, extended)
    M["labrum_height_mm"] = float(GLENOID_FACE_R - np.linalg.norm(
        lab - (c + GLENOID_FACE_R * n), axis=1).min())
    a = bodies["acromion"]["xyz"]
    col = a[(np.abs(a[:, 0] - 9.0) < 3.0) & (np.abs(a[:, 1] + 6.0) < 3.0)]
    M["acromion_thickness_mm"] = float(np.ptp(col[:, 2]))
    row = a[(np.abs(a[:, 1] + 6.0) < 2.0)]
    M["acromion_width_mm"] = float(np.ptp(row[:, 0]))
    over = a[(np.abs(a[:, 0]) < 12.0) & (np.abs(a[:, 1]) < 10.0)]
    M["acromiohumeral_mm"] = float(over[:, 2].min() - xyz[:, 2].max())
    plate_low = min(zc - b for _, _, zc, _, b in ACRO_SECTIONS)
    M["hook_drop_mm"] = float(plate_low - a[:, 2].min())
    cal = bodies["coracoacromial_ligament"]["xyz"]
    ax = unit(np.array(CAL_ENDS[1]) - np.array(CAL_ENDS[0]))
    M["cal_length_mm"] = float(np.ptp(cal @ ax))
    # mean biceps diameter: tube volume / centreline length between the end planes
    cl = biceps_samples[(biceps_samples[:, 1] >= BICEPS_Y0) & (biceps_samples[:, 2] >= BICEPS_Z1)]
    length = float(np.sum(np.linalg.norm(np.diff(cl, axis=0), axis=1)))
    vol = float(base.tet_volumes(bodies["biceps_tendon"]["xyz"],
                                 bodies["biceps_tendon"]["tets"]).sum())
    M["biceps_diameter_mm"] = 2.0 * math.sqrt(vol / length / math.pi)
    # Subacromial bursa: radial extent of its shell about the head centre.
    rb = np.linalg.norm(bodies[bursa.NAME]["xyz"], axis=1)
    M["bursa_thickness_mm"] = float(rb.max() - rb.min())
    return M


def groove_size(xyz, centreline):
    """(depth, width) of the bicipital groove, mm, at z = -15: in the horizontal section the
    outward direction is from the shaft axis to the biceps axis; depth = highest wall (within
    GROOVE_R + 4 mm either side) minus the floor under the biceps axis; width = distance
    between the two wall crests."""
    z0 = -15.0
    c = centreline[np.argmin(np.abs(centreline[:, 2] - z0) + 100 * (centreline[:, 2] > 0))]
    out = unit(np.array([c[0] - base.NECK_C[0], c[1] - base.NECK_C[1], 0.0]))
    side = np.cross([0.0, 0.0, 1.0], out)
    sl = xyz[np.abs(xyz[:, 2] - c[2]) < 1.2]
    rel = sl - c
    s, o = rel @ side, rel @ out
    near = o > -15.0
    floor = o[near & (np.abs(s) < 1.0)]
    walls = []
    for sign in (1.0, -1.0):
        band = near & (sign * s > GROOVE_R - 1.0) & (sign * s < GROOVE_R + 4.0)
        i = np.argmax(np.where(band, o, -np.inf))
        walls.append((o[i], s[i]))
    if len(floor) == 0 or not np.isfinite(walls[0][0]) or not np.isfinite(walls[1][0]):
        return 0.0, 0.0
    depth = min(w[0] for w in walls) - floor.max()
    return float(depth), float(abs(walls[0][1] - walls[1][1]))


# ----------------------------------------------------------------------------------------------
# Scene: build, verify, files
# ----------------------------------------------------------------------------------------------
RIGID = ("humerus", "acromion", "glenoid", "coracoacromial_ligament")
SOFT = ("supraspinatus_muscle", "supraspinatus_tendon", "biceps_tendon", bursa.NAME)
MESH_DIR = "meshes/anatomic"


def anatomy_points():
    """The primitive scene's named points (same positions) with the biceps cut site on this
    biceps, plus the glenoid centre and the coracoid tip."""
    P = base.anatomy_points()
    P["biceps_cut_site"], samples = biceps_centreline_at_x(base.BICEPS_X0 + 9.0)
    u, v, n, c = glenoid_frame()
    P["glenoid_center"] = c
    tip = np.array(CORACOID_PATH[-1])
    P["coracoid_tip"] = tip + CORACOID_R * unit(tip - np.array(CORACOID_PATH[-2]))
    P["bursa_center"] = np.array(bursa.center())
    return P, samples


LANDMARK_BODY = dict(base.LANDMARK_BODY, glenoid_center="glenoid", coracoid_tip="glenoid",
                     bursa_center=bursa.NAME)


def region_boxes():
    """The primitive scene's regions; the proximal biceps end is the plane y = BICEPS_Y0."""
    R = base.region_boxes()
    e = 0.01
    R["biceps_ends_proximal"] = ("biceps_tendon", ((-30.0, BICEPS_Y0 - 1.0, 5.0),
                                                   (-15.0, BICEPS_Y0 + e, 25.0)))
    R.update(bursa.region_boxes())
    return R


def build(log):
    """Meshes of the anatomic scene as checked bodies, named points and centreline samples."""
    base.gmsh_setup()
    try:
        meshes = build_meshes()
        points, samples = anatomy_points()
    finally:
        gmsh.finalize()
    bodies = {}
    for name in RIGID:
        xyz, tris = meshes[name]
        tris, rep = base.orient_surface(xyz, tris)
        base.require(rep["euler"] == 2 and rep["volume"] > 0,
                     "%s not a closed sphere-like surface" % name)
        bodies[name] = {"xyz": xyz, "tris": tris, "surf": tris, "rep": rep}
    for name in SOFT:
        xyz, tets = meshes[name]
        tets = base.orient_tets(xyz, tets)
        vol = base.tet_volumes(xyz, tets)
        base.require(vol.min() > 0, "%s has degenerate tets" % name)
        surf, rep = base.orient_surface(xyz, base.tet_boundary(tets))
        base.require(rep["euler"] == 2, "%s boundary is not a closed surface" % name)
        rep["quality"] = base.tet_quality(xyz, tets)
        bodies[name] = {"xyz": xyz, "tets": tets, "surf": surf, "rep": rep}
    _, fbox = region_boxes()["footprint"]
    bodies["humerus"]["tag"] = humerus_groups(bodies["humerus"]["xyz"], bodies["humerus"]["tris"],
                                              fbox)
    _, sbox = region_boxes()["spur"]
    a = bodies["acromion"]
    a["tag"] = np.where(np.all(base.in_box(a["xyz"], sbox)[a["tris"]], axis=1), 2, 1)
    bodies["glenoid"]["tag"] = glenoid_groups(bodies["glenoid"]["xyz"], bodies["glenoid"]["tris"])
    bodies["coracoacromial_ligament"]["tag"] = np.ones(
        len(bodies["coracoacromial_ligament"]["tris"]), dtype=int)
    return bodies, points, samples


def self_intersections(xyz, tris):
    """Number of pairs of non-adjacent triangles that intersect (segment-triangle tests on
    candidate pairs from overlapping bounding boxes)."""
    lo, hi = xyz[tris].min(axis=1), xyz[tris].max(axis=1)
    order = np.argsort(lo[:, 0])
    count = 0
    for k, i in enumerate(order):
        j = order[k + 1:]
        j = j[lo[j, 0] <= hi[i, 0]]
        j = j[np.all((lo[j] <= hi[i]) & (hi[j] >= lo[i]), axis=1)]
        shared = np.isin(tris[j], tris[i]).any(axis=1)
        for jj in j[~shared]:
            if tri_tri_intersect(xyz[tris[i]], xyz[tris[jj]]):
                count += 1
    return count


def seg_tri(p, q, t):
    """Whether the segment pq crosses the triangle t (Moller-Trumbore, strict interior)."""
    d = q - p
    e1, e2 = t[1] - t[0], t[2] - t[0]
    h = np.cross(d, e2)
    a = e1 @ h
    if abs(a) < 1e-12:
        return False
    s = p - t[0]
    u = (s @ h) / a
    if u <= 1e-9 or u >= 1 - 1e-9:
        return False
    qv = np.cross(s, e1)
    v = (d @ qv) / a
    if v <= 1e-9 or u + v >= 1 - 1e-9:
        return False
    w = (e2 @ qv) / a
    return 1e-9 < w < 1 - 1e-9


def tri_tri_intersect(a, b):
    for t, o in ((a, b), (b, a)):
        for i in range(3):
            if seg_tri(o[i], o[(i + 1) % 3], t):
                return True
    return False


def verify(bodies, points, samples, log):
    B = bodies
    for name in RIGID + SOFT:
        b, r = B[name], B[name]["rep"]
        if "tets" in b:
            log("%-24s %5d nodes %5d tets   (boundary %d tris, volume %.0f mm3, min quality %.3f)"
                % (name, len(b["xyz"]), len(b["tets"]), len(b["surf"]), r["volume"], r["quality"]))
        else:
            groups = dict(GROUP_NAMES[name])
            counts = ", ".join("%s %d" % (groups[g], int(np.sum(b["tag"] == g)))
                               for g in sorted(groups))
            log("%-24s %5d nodes %5d tris   (closed, Euler %d, volume %.0f mm3; %s)"
                % (name, len(b["xyz"]), len(b["tris"]), r["euler"], r["volume"], counts))
            base.require(all(np.sum(b["tag"] == g) > 0 for g in groups),
                         "%s: an empty physical group" % name)
    for name in RIGID:
        n = self_intersections(B[name]["xyz"], B[name]["tris"])
        base.require(n == 0, "%s surface intersects itself (%d triangle pairs)" % (name, n))
    log("rigid surfaces: no self-intersections")
    # Soft bodies clear of every rigid body and of each other (nodes and tet centroids).
    for s in SOFT:
        pts = base.samples(B[s]["xyz"], B[s]["tets"])
        for o in RIGID + tuple(x for x in SOFT if x != s):
            if {s, o} == {"supraspinatus_muscle", "supraspinatus_tendon"}:
                continue
            n_in, dmin = base.near_obstacle(pts, "mesh:" + o, B[o])
            base.require(n_in == 0, "%s intersects %s (%d points inside)" % (s, o, n_in))
            base.require(dmin > 0.5, "%s within %.3f mm of %s" % (s, dmin, o))
            if dmin < 5:
                log("clearance %-20s -> %-24s %.2f mm" % (s, o, dmin))
    # Regions.
    for rname, (body, box) in region_boxes().items():
        sel = base.in_box(B[body]["xyz"], box)
        base.require(sel.sum() > 0, "region %s is empty" % rname)
        if rname in ("tendon_edge", "muscle_medial_end", "bursa_medial"):
            base.require(np.ptp(B[body]["xyz"][sel][:, 0]) < 1e-9, "%s not one end face" % rname)
        if rname in ("biceps_ends_proximal", "bursa_anterior", "bursa_posterior"):
            base.require(np.ptp(B[body]["xyz"][sel][:, 1]) < 1e-9, "%s not one end face" % rname)
        if rname == "biceps_ends_distal":
            base.require(np.ptp(B[body]["xyz"][sel][:, 2]) < 1e-9, "%s not one end face" % rname)
        log("region %-21s %-21s %4d nodes" % (rname, body, sel.sum()))
    # Landmarks on (rigid, within 0.6 mm of the surface) or in (soft) the body they name.
    for lname, p in points.items():
        body = LANDMARK_BODY.get(lname)
        if body is None:
            for o in B:
                w = base.winding(np.array([p]), B[o]["xyz"], B[o]["surf"])[0]
                base.require(w < 0.5, "free point %s inside %s" % (lname, o))
            continue
        if body in RIGID:
            d = base.point_tri_distance(np.array([p]), B[body]["xyz"], B[body]["surf"])[0]
            base.require(d < 0.6, "%s is %.2f mm from %s" % (lname, d, body))
        else:
            w = base.winding(np.array([p]), B[body]["xyz"], B[body]["surf"])[0]
            base.require(w > 0.5, "%s not inside %s" % (lname, body))
    # The biceps starts at the supraglenoid tubercle and lies in the groove.
    bi = B["biceps_tendon"]
    _, pbox = region_boxes()["biceps_ends_proximal"]
    end = bi["xyz"][base.in_box(bi["xyz"], pbox)]
    g = B["glenoid"]
    tub = g["tris"][g["tag"] == 3]
    d_end = base.point_tri_distance(end, g["xyz"], tub).min()
    base.require(d_end < 1.5, "biceps origin %.2f mm from the supraglenoid tubercle" % d_end)
    log("biceps origin to supraglenoid tubercle: %.2f mm" % d_end)
    # Dimensions measured on the meshes against the cited ranges.
    M = measure(B, samples)
    for k, (lo, hi) in RANGES.items():
        log("dimension %-24s %7.2f   cited range %g-%g" % (k, M[k], lo, hi))
        base.require(lo <= M[k] <= hi, "%s = %.2f outside the cited range %g-%g"
                     % (k, M[k], lo, hi))
    base.require(M["head_centre_offset_mm"] < 0.05, "head centre moved")
    for pname, p in base.PORTALS.items():
        for o in B:
            w = base.winding(np.array([p], float), B[o]["xyz"], B[o]["surf"])[0]
            base.require(w < 0.5, "portal %s inside %s" % (pname, o))
    for sname, (s, e) in base.suture_lines(points, base.SUTURE_NODES_REPAIR).items():
        pts = s + np.linspace(0, 1, base.SUTURE_NODES_REPAIR)[1:, None] * (e - s)
        for o in B:
            n_in, _ = base.near_obstacle(pts, "mesh:" + o, B[o])
            base.require(n_in == 0, "%s passes through %s" % (sname, o))
    # Instruments aim from their portals at landmarks: report paths the new bodies block.
    for pname, p in base.PORTALS.items():
        for lname, q in points.items():
            seg = np.asarray(p, float) + np.linspace(0.0, 0.85, 40)[:, None] * (q - np.asarray(p))
            for o in ("glenoid", "coracoacromial_ligament"):
                d = base.point_tri_distance(seg, B[o]["xyz"], B[o]["surf"]).min()
                if d < 2.0:
                    log("note: %s portal -> %s passes %.1f mm from %s" % (pname, lname, d, o))
    return M


def files(bodies, points):
    """{relative path: text} of the anatomic scene."""
    out = {}
    for name in RIGID:
        b = bodies[name]
        out["%s/%s.msh" % (MESH_DIR, name)] = base.msh22_text(
            b["xyz"], np.column_stack([b["tris"], b["tag"]]), 2, GROUP_NAMES[name])
    for name in SOFT:
        b = bodies[name]
        out["%s/%s.msh" % (MESH_DIR, name)] = base.msh22_text(
            b["xyz"], np.column_stack([b["tets"], np.ones(len(b["tets"]), int)]), 4, [(1, name)])
    header = [
        "Anatomic scene (scenarios/README.md, 'Anatomic scene'): the same head centre, head",
        "radius (45 mm), footprint (23 x 16 mm, Curtis 2006), supraspinatus muscle and torn tendon",
        "as rotator_cuff_repair.yaml; humeral head a sphere segment (neck-shaft angle %g deg,"
        % NECK_SHAFT_DEG,
        "retroversion %g deg) with cartilage (group), greater and lesser tuberosities and the"
        % RETROVERSION_DEG,
        "bicipital groove; acromion with a curved undersurface and anterior hook, 10 mm above the",
        "head; glenoid with labrum, supraglenoid tubercle and coracoid; coracoacromial ligament;",
        "cartilage and labrum are tissues of their own (drawn as such; burring them is collateral",
        "damage); a subacromial bursa (soft, 1.6 mm) between the acromion and the tendon;",
        "supraspinatus muscle and tendon with a conforming interface; full-thickness tear, tendon edge"]
    extra = [
        "  # Glenoid, labrum (group, a tissue of its own), supraglenoid tubercle and coracoid: one",
        "  # rigid body.",
        "  - {name: glenoid, kind: rigid, mesh: %s/glenoid.msh, hardness: 3, tissues: [labrum]}"
        % MESH_DIR,
        "  # Coracoacromial ligament: a rigid band [K: rigid to keep the FEM cost unchanged].",
        "  - {name: coracoacromial_ligament, kind: rigid, mesh: %s/coracoacromial_ligament.msh,"
        % MESH_DIR,
        "     hardness: 1}"]
    text = base.scenario_text(
        "rotator_cuff_repair_anatomic", 5.0, points, True,
        "arthroscopic repair of a retracted full-thickness supraspinatus tear, anatomic shoulder",
        [], anchored_sutures=True, mesh_dir=MESH_DIR, anatomy_header=header, extra_bodies=extra,
        regions=region_boxes(), landmark_body=LANDMARK_BODY, humerus_tissues=("cartilage",),
        extra_materials=bursa.MATERIAL, extra_soft_bodies=bursa.body_lines(MESH_DIR))
    text = text.replace(
        "# Long head of biceps from the supraglenoid region over the front of the head into the",
        "# Long head of biceps from the supraglenoid tubercle in front of the supraspinatus into the")
    out["rotator_cuff_repair_anatomic.yaml"] = text
    return out
