"""Anatomy and mesh-size parameters of the procedural shoulder (mm).

Frame: right shoulder, origin at the humeral-head centre, x lateral, y anterior, z superior.
Sources are named in scenarios/README.md. Read-only: every stage module imports them by name.
"""

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
