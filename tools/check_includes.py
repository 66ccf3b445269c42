#!/usr/bin/env python3
"""Checks that each subsystem includes only the subsystems below it (the layer rule).

usage: check_includes.py SOURCE_DIR
Scans src/<sub>/ and include/arthrosim/<sub>/ for `#include "arthrosim/<other>/..."` and fails
(exit 1, one line per violation: file:line: sub may not include other) when <other> is not in
ALLOWED[<sub>]. Tests may include more (they build fixtures from several layers) and are not
scanned.
"""
import os
import re
import sys

# Bottom to top. core, mesh -> physics, collision, input, io, render -> instruments -> sim ->
# scoring -> cli. collision reads physics' contact types; render draws instruments from
# collision's shapes (what the trainee sees is what cuts); scoring reads run files through io and
# may render thumbnails.
BASE = {"core", "mesh"}
ALLOWED = {
    "core": {"core"},
    "mesh": {"core", "mesh"},
    "physics": BASE | {"physics"},
    "collision": BASE | {"physics", "collision"},
    "input": BASE | {"input"},
    "io": BASE | {"io"},
    "render": BASE | {"physics", "collision", "render"},
    "instruments": BASE | {"physics", "collision", "instruments"},
    "sim": BASE | {"physics", "collision", "instruments", "sim"},
    "scoring": BASE | {"io", "render", "scoring"},
    "cli": None,  # the top: may include every subsystem
}

# Known violations still to be removed, as (file, included subsystem). Keep this empty.
EXCEPTIONS = set()

INCLUDE = re.compile(r'^\s*#\s*include\s*"arthrosim/([a-z_]+)/')


def main(root):
    violations = []
    seen_exceptions = set()
    for sub, allowed in ALLOWED.items():
        for top in (os.path.join(root, "src", sub), os.path.join(root, "include", "arthrosim", sub)):
            for dirpath, _, files in os.walk(top):
                for name in sorted(files):
                    if not name.endswith((".h", ".cpp", ".hpp", ".cc", ".inl")):
                        continue
                    path = os.path.join(dirpath, name)
                    rel = os.path.relpath(path, root)
                    with open(path, encoding="utf-8", errors="replace") as f:
                        for lineno, line in enumerate(f, 1):
                            m = INCLUDE.match(line)
                            if not m or allowed is None or m.group(1) in allowed:
                                continue
                            if (rel, m.group(1)) in EXCEPTIONS:
                                seen_exceptions.add((rel, m.group(1)))
                                continue
                            violations.append(f"{rel}:{lineno}: {sub} may not include "
                                              f"{m.group(1)} (allowed: {', '.join(sorted(allowed))})")
    for rel, other in sorted(EXCEPTIONS - seen_exceptions):
        violations.append(f"{rel}: listed as an exception for {other} but no longer includes it: "
                          "remove it from EXCEPTIONS")
    for v in violations:
        print(v)
    if violations:
        print(f"check_includes: {len(violations)} layer violation(s)", file=sys.stderr)
        return 1
    print("check_includes: layers respected")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "."))
