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

The stages live in tools/procedural_shoulder/ (parameters, gmsh helpers, bones, soft tissue,
landmarks + regions, scenario writing, build + checks); this file re-exports their names
(tools/anatomic_shoulder.py and tools/anatomic_bursa.py use them as base.<name>) and runs them.

Usage: tools/gen_anatomy.py [--out DIR] [--check]   (--check: build and verify, write nothing)
"""

import argparse
import hashlib
import os
import sys

# Mesh checks and writers, and the stages (tools/anatomic_shoulder.py uses them as base.<name>).
from mesh_geometry import (fmt, in_box, msh22_text, orient_surface, orient_tets,  # noqa: F401
                           point_tri_distance, samples, signed_volume, tet_boundary,
                           tet_quality, tet_volumes, vec, winding)
from procedural_shoulder.bones import (acromion_geometry, footprint_center,  # noqa: F401
                                       gt_normal, gt_point, humerus_geometry, inside_bone,
                                       mesh_acromion, mesh_humerus)
from procedural_shoulder.checks import (Failed, build, near_obstacle, require,  # noqa: F401
                                        verify)
from procedural_shoulder.gmsh_mesh import (background_size, boundary_triangles,  # noqa: F401
                                           compact, crossing_x, elements_of, gmsh_setup,
                                           node_table, rotation_to, shell_patch, single_volume,
                                           spline_curve)
from procedural_shoulder.landmarks import (CAMERA, INSTRUMENTS, LANDMARK_BODY,  # noqa: F401
                                           PORTALS, SUTURE_NODES_BENCH, SUTURE_NODES_REPAIR,
                                           SUTURE_SPACING_MM, anatomy_points,
                                           biceps_centreline_at_x, region_boxes, retraction,
                                           suture_lines, tendon_mid_point)
from procedural_shoulder.params import *  # noqa: F401,F403  (HEAD_R, GT_C, ... SEED)
from procedural_shoulder.scenario import primitive_files, scenario_text  # noqa: F401
from procedural_shoulder.soft_tissue import (biceps_geometry, cuff_geometry,  # noqa: F401
                                             mesh_biceps, mesh_cuff, sector_wire,
                                             tendon_section)


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
    files = primitive_files(bodies, points)
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
