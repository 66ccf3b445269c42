#!/usr/bin/python3
"""Derives the trainee variants that are the expert script with one error from
trajectories/rotator_cuff_repair_expert.yaml, so they follow every re-tune of the expert.

  novice_bite: the second bite taken BITE_X mm along x from bite_target_1 (~4.5 mm from the torn
               edge) instead of the expert's aim; every other line the expert's.
  novice_knot: the knot pusher's button-2 push (which slides the knot down onto its target)
               replaced by a wait of the same length; every other line the expert's.
  novice_economy: every duration, wait, start time (`at`) and camera transition doubled: the
               expert's steps at half speed (run it with --noise-scale 1 for the trainee noise).

Each variant keeps its own header comment (everything before its `name:` line); the rest is the
expert's text with the variant's edits. Usage: tools/derive_variants.py [--check]
(--check: exit 1, naming the file, if a committed variant differs from its derivation; CTest
DeriveVariants.upToDate runs it).
"""

import argparse
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TRAJ = os.path.join(ROOT, "trajectories")
EXPERT_DESCRIPTION = ("description: the full repair in the paper's order, one anchor with two "
                      "limbs (expert, no noise)")
BITE_X = "15.1"  # x offset of the trainee's second bite from bite_target_1, mm


class DeriveError(Exception):
    pass


def variant_path(name):
    return os.path.join(TRAJ, "rotator_cuff_repair_%s.yaml" % name)


def expert_body():
    text = open(os.path.join(TRAJ, "rotator_cuff_repair_expert.yaml")).read()
    body = text[text.index("name: rotator_cuff_repair_expert"):]
    if EXPERT_DESCRIPTION not in body:
        raise DeriveError("expert script: description line changed (update EXPERT_DESCRIPTION)")
    return body


def header(name):
    text = open(variant_path(name)).read()
    return text[:text.index("name: rotator_cuff_repair_novice")]


def renamed(body, name, description):
    body = body.replace("name: rotator_cuff_repair_expert", "name: rotator_cuff_repair_" + name, 1)
    return body.replace(EXPERT_DESCRIPTION, "description: " + description, 1)


def bite(body):
    """The second scorpion-needle approach (its standoff move and the move onto the tendon)
    aimed at x = BITE_X."""
    aims = re.findall(r"  - move: \{to: bite_target_1, offset: \[(-?[\d.]+), (-?[\d.]+), "
                      r"(-?[\d.]+)\], standoff: 8, aim: portal, roll: 90,", body)
    if len(aims) != 2:
        raise DeriveError("expert script: expected 2 needle approaches, found %d" % len(aims))
    x, y, z = aims[1]
    old = "[%s, %s, %s]" % (x, y, z)
    new = "[%s, %s, %s]" % (BITE_X, y, z)
    approach = ("  - move: {to: bite_target_1, offset: %s, standoff: 8, aim: portal, roll: 90,"
                % old)
    onto = "  - move: {to: bite_target_1, offset: %s, aim: portal, roll: 90," % old
    if body.count(approach) != 1 or body.count(onto) != 1:
        raise DeriveError("expert script: the second needle approach is not unique")
    note = ("  # (the trainee's second bite: %.1f mm more lateral than the expert's, ~4.5 mm from "
            "the edge)\n" % (float(BITE_X) - float(x)))
    body = body.replace(approach, note + approach.replace(old, new))
    return body.replace(onto, onto.replace(old, new))


def knot(body):
    """The knot pusher's push with button 2 held replaced by a wait as long."""
    push = re.search(r"  - hold: \{button: 2\}\n  - push: \{depth: [\d.]+, duration: ([\d.]+)\}\n"
                     r"  - release: \{button: 2\}\n", body)
    if push is None or body.count("  - hold: {button: 2}\n  - push:") != 1:
        raise DeriveError("expert script: expected one button-2 push (the knot pusher's)")
    return body.replace(push.group(0), "  # (the trainee does not push the knot down: it stays "
                        "where it was thrown, above its target)\n  - wait: %s\n" % push.group(1))


def economy(body):
    """Every duration, wait, start time and camera transition of the script doubled."""
    def doubled(m):
        return "%s%s" % (m.group(1), "%g" % (2 * float(m.group(2))))
    body = re.sub(r"(\b(?:duration|transition|at): )(\d+(?:\.\d+)?)", doubled, body)
    return re.sub(r"(  - wait: )(\d+(?:\.\d+)?)", doubled, body)


def derived():
    body = expert_body()
    return {
        "novice_bite": header("novice_bite") + bite(renamed(
            body, "novice_bite", "the expert repair with the second bite too close to the torn "
            "edge (~4.5 mm)")),
        "novice_knot": header("novice_knot") + knot(renamed(
            body, "novice_knot", "the expert repair with the knot thrown but never pushed down "
            "onto its target")),
        "novice_economy": header("novice_economy") + economy(renamed(
            body, "novice_economy", "the expert's steps at half speed (a trainee slow in time "
            "and motion)")),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare, write nothing")
    args = ap.parse_args()
    try:
        variants = derived()
    except (DeriveError, OSError, ValueError) as e:
        print("derive_variants: %s" % e, file=sys.stderr)
        return 2
    stale = []
    for name, text in variants.items():
        path = variant_path(name)
        if args.check:
            if open(path).read() != text:
                stale.append(path)
        else:
            with open(path, "w") as f:
                f.write(text)
    for path in stale:
        print("derive_variants: %s differs from its derivation from the expert script "
              "(run tools/derive_variants.py)" % os.path.relpath(path, ROOT), file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
