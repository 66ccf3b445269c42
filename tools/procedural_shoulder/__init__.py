"""The procedural shoulder of tools/gen_anatomy.py, one module per stage:

  params       anatomy and mesh-size parameters (mm)
  gmsh_mesh    the deterministic gmsh session and mesh/boolean/spline helpers
  bones        humerus and acromion surfaces, their analytic inside test
  soft_tissue  supraspinatus muscle + tendon (conforming) and long head of biceps tetrahedra
  landmarks    landmarks, region boxes, portals, instruments, camera, suture limbs
  scenario     the scenario YAML and the primitive scene's files
  checks       build every body and verify the scene (Failed names the failed check)

tools/gen_anatomy.py re-exports their names (tools/anatomic_shoulder.py and
tools/anatomic_bursa.py use them as base.<name>).
"""
