#!/usr/bin/env python3
"""The include graph check (issue 35): an include that runs upward fails the test.

Two orders are checked, each from the bottom up; a file may include files of its own room and
of rooms below it, never above nor beside (server/ and client/ know nothing of each other):
  the top-level folders:  engine < proto < io < figures < server, client, testing < bench, tests
  engine's rooms:         runtime < linalg < api < model, genome < fem < problem < direct < fit
                          < search < probe_fit < identification < examples
                          (engine's root holds no source: every file sits in the room of its kind)
proto/, io/, figures/, server/ and client/ include the engine only through engine/api/, its
public surface. api/ sits just above runtime and linalg: it defines the vocabulary (a scene, a
problem, a result, the entry point) that the rooms include from it and implement, as leveldb's
include/ is implemented by db/; so nothing on the surface reaches a room's machinery.
KNOWN lists the upward includes that are still there, each with why; the check also fails when
one of them is gone (so the list shrinks with the code).
It also counts the internal engine headers reachable from engine/api/ (through any chain of
includes) and fails unless the count is REACHABLE_FROM_API: more is a surface that grew, fewer
a number to lower here (docs/ARCHITECTURE.md, "The engine's surface").
  include_graph_check.py SOURCE_DIR
"""
import os
import re
import sys

TOP = {"engine": 0, "proto": 1, "io": 2, "figures": 3, "server": 4, "client": 4, "testing": 4,
       "bench": 5, "tests": 5}
ENGINE = {"runtime": 0, "linalg": 1, "api": 2, "model": 3, "genome": 3, "fem": 4, "problem": 5,
          "direct": 6, "fit": 7, "search": 8, "probe_fit": 9, "identification": 10,
          "examples": 11}
# The folders that see the engine only through its public surface, engine/api/ (tests/, bench/
# and testing/ reach inside it: they test and measure its parts).
SURFACE_ONLY = {"proto", "io", "figures", "server", "client"}
# Upward includes not yet removed, each with why (none left: Problem's preparation moved to its
# own room above fem/, and the positions reference's force balance with it).
KNOWN = set()
# Internal engine headers reachable from engine/api/ (issue 49's target: at most 10).
REACHABLE_FROM_API = 8
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def room(path):
    parts = path.split("/")
    if parts[0] != "engine":
        return ("top", parts[0])
    return ("engine", parts[1] if len(parts) > 2 else ".")


def level(r):
    kind, name = r
    return (TOP if kind == "top" else ENGINE).get(name)


def reachable_from_api(root):
    """The internal engine headers that some chain of includes from engine/api/ reaches."""
    api = os.path.join(root, "engine", "api")
    stack = [os.path.join("engine", "api", n) for n in sorted(os.listdir(api)) if n.endswith(".h")]
    seen = set()
    while stack:
        path = stack.pop()
        if path in seen:
            continue
        seen.add(path)
        with open(os.path.join(root, path), encoding="utf-8") as f:
            for line in f:
                m = INCLUDE.match(line)
                if m and m.group(1).startswith("engine/") and \
                        os.path.exists(os.path.join(root, m.group(1))):
                    stack.append(m.group(1))
    return sorted(p for p in seen if not p.startswith("engine/api/"))


def main():
    root = sys.argv[1]
    upward, seen_known, files = [], set(), 0
    for folder in TOP:
        for dirpath, _, names in os.walk(os.path.join(root, folder)):
            for name in sorted(names):
                if not name.endswith((".h", ".cpp")):
                    continue
                path = os.path.relpath(os.path.join(dirpath, name), root)
                files += 1
                if room(path) == ("engine", "."):
                    upward.append(f"{path}: a source in engine's root: put it in the room of "
                                  "its kind (runtime, linalg, model, genome, ...)")
                with open(os.path.join(root, path), encoding="utf-8") as f:
                    for number, line in enumerate(f, 1):
                        m = INCLUDE.match(line)
                        if not m or "/" not in m.group(1):
                            continue
                        target = m.group(1)
                        if target.split("/")[0] not in TOP:
                            continue
                        a, b = room(path), room(target)
                        if (path.split("/")[0] in SURFACE_ONLY and b[0] == "engine"
                                and b[1] != "api"):
                            upward.append(f"{path}:{number}: includes {target}, inside the "
                                          "engine: include its public surface, engine/api/")
                            continue
                        if a[0] != b[0]:
                            # Across the top level: engine's rooms count as engine.
                            a, b = ("top", path.split("/")[0]), ("top", target.split("/")[0])
                        la, lb = level(a), level(b)
                        if la is None or lb is None:
                            upward.append(f"{path}:{number}: {target}: a room the check does "
                                          "not know (add it to the orders)")
                        elif lb > la or (lb == la and a != b):
                            if (path, target) in KNOWN:
                                seen_known.add((path, target))
                            else:
                                upward.append(f"{path}:{number}: includes {target}, a room above "
                                              f"its own or beside it ({a[1]}, {b[1]})")
    gone = sorted(KNOWN - seen_known)
    reached = reachable_from_api(root)
    if len(reached) > REACHABLE_FROM_API:
        upward.append(f"engine/api/ reaches {len(reached)} internal headers, more than "
                      f"{REACHABLE_FROM_API}: keep machinery out of what the surface includes "
                      "(docs/ARCHITECTURE.md, \"The engine's surface\")")
    elif len(reached) < REACHABLE_FROM_API:
        upward.append(f"engine/api/ reaches {len(reached)} internal headers: lower "
                      f"REACHABLE_FROM_API from {REACHABLE_FROM_API} to {len(reached)}")
    for line in upward:
        print("FAIL: " + line)
    for path, target in gone:
        print(f"FAIL: {path} no longer includes {target}: remove it from KNOWN")
    print(f"include_graph_check: {files} files, {len(upward)} upward includes, "
          f"{len(seen_known)} known ones left, {len(reached)} internal headers reachable from "
          "engine/api/")
    return 1 if upward or gone else 0


if __name__ == "__main__":
    sys.exit(main())
