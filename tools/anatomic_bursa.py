"""Subacromial bursa of the anatomic scene (tools/anatomic_shoulder.py).

A thin soft layer between the acromion's undersurface and the cuff: a spherical shell patch
concentric with the humeral head, BURSA_GAP above the tendon's bursal surface and BURSA_T thick,
over the tendon from x = BURSA_X[0] to BURSA_X[1] (medial of the torn edge, so the edge stays in
view), BURSA_HALF_W either side of y = 0 (clear of the anterior hook). Its medial, anterior and
posterior end faces are fixed (the bursa's roof adheres to the acromion and the coracoacromial
ligament); the lateral edge is free, where the shaver from the lateral portal meets it first.
Sizes: scenarios/README.md, "Anatomic scene".
"""

import math

import gmsh

import gen_anatomy as base

BURSA_GAP = 0.8          # mm above the tendon's bursal surface (its clearance to the tendon)
BURSA_T = 1.6            # thickness, mm (normal bursa < 2 mm on ultrasound: README)
BURSA_X = (-10.0, 4.0)   # medial end face .. free lateral edge (x, mm)
BURSA_HALF_W = 9.0       # half-width antero-posteriorly (y, mm)
H_BURSA = 2.0            # mesh size, mm: a few hundred tets
NAME = "subacromial_bursa"


def radii():
    """Inner and outer radius (mm) of the shell about the head centre."""
    r_in = base.HEAD_R + base.CUFF_GAP + base.TENDON_T + BURSA_GAP
    return r_in, r_in + BURSA_T


def geometry():
    r_in, r_out = radii()
    return base.single_volume(base.shell_patch(r_in, r_out, BURSA_X, BURSA_HALF_W))


def mesh():
    """(xyz, tets) of the bursa (gmsh must be initialised)."""
    gmsh.model.add("bursa")
    vol = geometry()
    base.background_size("%r" % H_BURSA)
    gmsh.model.mesh.generate(3)
    return base.compact(base.elements_of(3, vol, 4), base.node_table())


def center():
    """Landmark `bursa_center`: mid-thickness above the head apex, 2 mm medial of it."""
    r_in, r_out = radii()
    r, x = 0.5 * (r_in + r_out), -2.0
    return (x, 0.0, math.sqrt(r * r - x * x))


def region_boxes():
    """The fixed end faces as node boxes: {name: (body, (lo, hi))}."""
    e = 0.01
    x0, _ = BURSA_X
    w = BURSA_HALF_W
    return {
        "bursa_medial": (NAME, ((x0 - 1.0, -w - 1.0, 0.0), (x0 + e, w + 1.0, 40.0))),
        "bursa_anterior": (NAME, ((x0 - 1.0, w - e, 0.0), (40.0, w + 1.0, 40.0))),
        "bursa_posterior": (NAME, ((x0 - 1.0, -w - 1.0, 0.0), (40.0, -w + e, 40.0))),
    }


MATERIAL = [
    "  # Subacromial bursa: not cited (no measured modulus of the bursa known to us); as soft as",
    "  # the passive muscle [K].",
    "  bursa: {young_modulus: 25000, poisson_ratio: 0.45, density: 1060,",
    "          rayleigh_mass: 0.1, rayleigh_stiffness: 0.001}",
]


def body_lines(mesh_dir):
    """The scenario's body entry (YAML lines)."""
    return [
        "  # Subacromial bursa: a thin soft layer (%g mm) between the acromion and the cuff, %g mm"
        % (BURSA_T, BURSA_GAP),
        "  # above the tendon; the shaver and the electrocautery debride it (docs/operations.md).",
        "  # End faces fixed (its roof adheres to the acromion), the lateral edge free.",
        "  - {name: %s, kind: soft, mesh: %s/%s.msh, material: bursa," % (NAME, mesh_dir, NAME),
        "     fixed: [bursa_medial, bursa_anterior, bursa_posterior]}",
    ]
