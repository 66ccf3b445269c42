#!/usr/bin/python3
"""Tests of tools/gen_anatomy (CTest GenAnatomy.*; needs Debian's python3-gmsh).

  reproducible  regenerates both scenes into a temporary folder: every file is byte-identical
                to the committed one under scenarios/ and smaller than 3 MB.
  perturbed     one anatomic dimension set outside its cited range (--set NAME=VALUE) makes
                the generator's check fail, naming the measured dimension.
"""
import os
import subprocess
import sys
import tempfile

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
GEN = os.path.join(ROOT, "tools", "gen_anatomy.py")
PY = "/usr/bin/python3"

# (parameter=value, the dimension check that must catch it)
PERTURBATIONS = [
    ("NECK_SHAFT_DEG=128", "neck_shaft_angle_deg"),
    ("RETROVERSION_DEG=12", "retroversion_deg"),
    ("HEAD_HALF_ARC_DEG=70", "head_thickness_mm"),
    ("LABRUM_H=6", "labrum_height_mm"),
    ("BURSA_T=0.4", "bursa_thickness_mm"),
]


def reproducible():
    with tempfile.TemporaryDirectory() as out:
        r = subprocess.run([PY, GEN, "--quiet", "--out", out], capture_output=True, text=True)
        if r.returncode != 0:
            print(r.stdout, r.stderr)
            return 1
        bad = 0
        count = 0
        for dirpath, _, names in os.walk(out):
            for n in sorted(names):
                path = os.path.join(dirpath, n)
                rel = os.path.relpath(path, out)
                with open(path, "rb") as f:
                    made = f.read()
                with open(os.path.join(ROOT, "scenarios", rel), "rb") as f:
                    committed = f.read()
                count += 1
                if made != committed:
                    print("FAIL %s differs from the committed file" % rel)
                    bad += 1
                if len(made) >= 3 * 1024 * 1024:
                    print("FAIL %s is %d bytes (>= 3 MB)" % (rel, len(made)))
                    bad += 1
        print("%d files regenerated, %d problems" % (count, bad))
        return 1 if bad or count < 15 else 0


def perturbed():
    bad = 0
    for setting, dimension in PERTURBATIONS:
        r = subprocess.run([PY, GEN, "--check", "--quiet", "--set", setting],
                           capture_output=True, text=True)
        ok = r.returncode == 1 and dimension in r.stderr
        print("%s --set %s: exit %d, %s" % ("ok  " if ok else "FAIL", setting, r.returncode,
                                           r.stderr.strip()))
        bad += 0 if ok else 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit({"reproducible": reproducible, "perturbed": perturbed}[sys.argv[1]]())
