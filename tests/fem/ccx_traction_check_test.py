#!/usr/bin/env python3
"""The ccx harness's (tests/fem/ccx_reference.py) resolution of tractions into nodal forces, and
its refusal of what it does not model; no ccx is run.

Usage: ccx_traction_check_test.py [SPRINGFIT_BINARY PROJECT_SOURCE_DIR] [--keep DIR]

`traction_self_check()` checks the nodal forces problem_from_scene gives tractions on a 2D bar
and a 3D block against hand values and exact resultants and moments (a constrained node's
share dropped, interior edges and faces carrying nothing, `per_length` not multiplied by the
thickness), and that the harness refuses load-case fields it does not model.

Prints one line per check and ends with `N passed, M failed`; exits 1 if any failed, 2 on bad
usage. Python 3 standard library only (the shared part: ccx_validation_support.py).
"""

import math
import sys

from ccx_validation_support import block_nodes, block_tets, grid_nodes, grid_triangles, run

cr = None  # the ccx_reference module, imported by run()


def traction_self_check(tally):
    """ccx_reference's resolution of tractions into nodal forces (problem_from_scene) against
    values worked out by hand: a traction t on linear facets is equivalent to nodal forces
    whose sum is the resultant t x (loaded length or area) and whose first moment
    sum_i f_i x_i is t x the integral of x over the loaded facets (exact for linear shape
    functions); on a 2 x 1 bar's right end (3 nodes, edges of length 0.5) the shares are
    1/4, 1/2, 1/4 of the total. Also: the share of a constrained node is dropped, interior
    edges and faces carry nothing, `per_length` is not multiplied by the thickness, and
    unknown fields are refused."""
    def run(label, sc, expect):
        """expect(cases) -> (ok, detail)."""
        try:
            prob = cr.problem_from_scene(sc)
        except cr.SceneError as e:
            tally.fail(label, f"harness refused the scene: {e}")
            return
        ok, detail = expect(prob.cases)
        tally.check(label, ok, detail)

    def close(a, b):
        return abs(a - b) <= 1e-14 * max(1.0, abs(b))

    def resultant(forces, d):
        return math.fsum(f[d] for f in forces.values())

    mat = {"model": "linear", "young": 10.0, "poisson": 0.3}

    # 2D: 2 x 1 bar, 5 x 3 nodes at spacing 0.5, thickness 0.1 (which must not scale tractions).
    nodes = grid_nodes(4, 2, 0.5, 0.5)
    tris = grid_triangles(4, 2)
    right = [i for i, p in enumerate(nodes) if p[0] == 2.0]    # y = 0, 0.5, 1
    left = [i for i, p in enumerate(nodes) if p[0] == 0.0]
    sets = {"left": left, "right": right, "all": list(range(len(nodes))),
            "corner": [right[0], right[1]]}
    base = {"name": "bar", "nodes": nodes, "node_sets": sets,
            "reference": {"type": "fem", "elements": tris, "material": mat, "thickness": 0.1}}
    F, q = 0.02, 0.03
    sc = dict(base, load_cases=[
        {"name": "total", "fixed": "left", "tractions": [{"on": "right", "total": [F, 0.0]}]},
        {"name": "per_length", "fixed": "left",
         "tractions": [{"on": "right", "per_length": [0.0, q]}]},
        {"name": "held corner", "fixed": left + [right[0]],
         "tractions": [{"on": "right", "total": [F, 0.0]}]},
        {"name": "with a force", "fixed": "left",
         "forces": [{"node": right[1], "force": [0.0, 0.001]}],
         "tractions": [{"on": "right", "total": [F, 0.0]}, {"on": "corner", "total": [0.0, F]}]},
        {"name": "whole boundary", "fixed": "left",
         "tractions": [{"on": "all", "per_length": [q, 0.0]}]},
    ])
    a, b, c = right

    def expect_2d(cases):
        want = [
            {a: [F / 4, 0.0], b: [F / 2, 0.0], c: [F / 4, 0.0]},
            {a: [0.0, q / 4], b: [0.0, q / 2], c: [0.0, q / 4]},
            {b: [F / 2, 0.0], c: [F / 4, 0.0]},
            {a: [F / 4, F / 2], b: [F / 2, F / 2 + 0.001], c: [F / 4, 0.0]},
        ]
        bad = []
        for k, w in enumerate(want):
            got = cases[k].forces
            if set(got) != set(w) or not all(close(got[i][d], w[i][d])
                                             for i in w for d in range(2)):
                bad.append(f"{cases[k].name}: {got} != {w}")
        # The perimeter is 6; the fixed left end takes all of its 1 and half of each of the
        # two edges (length 0.5) that end on it: q (6 - 1 - 2 x 0.25) on the free nodes.
        got = cases[4].forces
        want_sum = q * (6.0 - 1.0 - 2 * 0.25)
        if not close(resultant(got, 0), want_sum) or resultant(got, 1) != 0.0:
            bad.append(f"whole boundary: resultant {resultant(got, 0)} != {want_sum}")
        return not bad, "; ".join(bad) or "5 cases"

    run("self-check tractions 2D nodal forces (bar end, held node, forces add, boundary only)",
        sc, expect_2d)

    # 3D: 2 x 1 x 1 block, 5 x 3 x 3 nodes at spacing 0.5; its right end is the unit square
    # x = 2 (16 triangles). Resultant t; first moments sum f_z y = sum f_z z = t_z / 2.
    nodes = block_nodes(4, 2, 2, h=0.5)
    tets = block_tets(4, 2, 2)
    right = [i for i, p in enumerate(nodes) if p[0] == 2.0]
    left = [i for i, p in enumerate(nodes) if p[0] == 0.0]
    sets = {"left": left, "right": right, "all": list(range(len(nodes)))}
    base = {"name": "block", "nodes": nodes, "node_sets": sets,
            "reference": {"type": "fem", "elements": tets, "material": mat}}
    p, T = 0.03, 0.05
    sc = dict(base, load_cases=[
        {"name": "per_area", "fixed": "left",
         "tractions": [{"on": "right", "per_area": [0.0, 0.0, p]}]},
        {"name": "total", "fixed": "left",
         "tractions": [{"on": "right", "total": [0.0, 0.0, T]}]},
        {"name": "whole boundary", "fixed": "left",
         "tractions": [{"on": "all", "per_area": [p, 0.0, 0.0]}]},
    ])

    def expect_3d(cases):
        bad = []
        for k, tz in ((0, p), (1, T)):
            f = cases[k].forces
            r = [resultant(f, d) for d in range(3)]
            my = math.fsum(v[2] * nodes[i][1] for i, v in f.items())
            mz = math.fsum(v[2] * nodes[i][2] for i, v in f.items())
            if not (close(r[2], tz) and r[0] == 0.0 and r[1] == 0.0 and close(my, tz / 2)
                    and close(mz, tz / 2) and set(f) == set(right)):
                bad.append(f"{cases[k].name}: resultant {r}, moments {my}, {mz} (want {tz}, "
                           f"{tz / 2})")
        # The surface is 10; the fixed left face's nodes take all of its 1 and, on the strip
        # 0 <= x <= 0.5 of the four sides (perimeter 4), the integral of the sum of their hat
        # functions, 1 - 2x: 4 x 0.25 = 1. The free nodes carry p (10 - 1 - 1) = 8 p.
        f = cases[2].forces
        free_sum = resultant(f, 0)
        if not close(free_sum, 8.0 * p) or any(i in f for i in left):
            bad.append(f"whole boundary: free resultant {free_sum} != {8 * p}")
        return not bad, "; ".join(bad) or "3 cases"

    run("self-check tractions 3D nodal forces (resultants, moments, boundary only)", sc,
        expect_3d)

    # Refusals: what the harness does not model must not pass silently.
    plain = {"name": "refusals", "nodes": grid_nodes(1, 1), "node_sets": {"top": [2, 3]},
             "reference": {"type": "fem", "elements": grid_triangles(1, 1), "material": mat}}
    good = {"name": "ok", "fixed": [0, 1], "tractions": [{"on": "top", "total": [0.0, 0.1]}]}
    refusals = [
        ("an unknown load-case field", dict(good, pressure=[{"on": "top", "value": 1.0}])),
        ("a 3D density in 2D", dict(good, tractions=[{"on": "top", "per_area": [0.0, 1.0]}])),
        ("an unknown traction field", dict(good, tractions=[{"on": "top", "total": [0.0, 1.0],
                                                              "follower": True}])),
        ("total and per_length", dict(good, tractions=[{"on": "top", "total": [0.0, 1.0],
                                                         "per_length": [0.0, 1.0]}])),
        ("a node list as on", dict(good, tractions=[{"on": [2, 3], "total": [0.0, 1.0]}])),
        ("a set with no boundary edge", dict(good, fixed=[1, 2])),
        ("an unknown force field", dict(good, forces=[{"node": 2, "force": [0.0, 1.0],
                                                       "follower": True}])),
    ]
    # (top = [2, 3] is a boundary edge; for "a set with no boundary edge" the set becomes
    # the ends of the diagonal (0, 3), the one interior edge.)
    missed = []
    for why, case in refusals:
        sc = dict(plain, load_cases=[case])
        if why == "a set with no boundary edge":
            sc["node_sets"] = {"top": [0, 3]}
        try:
            cr.problem_from_scene(sc)
            missed.append(why)
        except cr.SceneError:
            pass
    try:
        cr.problem_from_scene(dict(plain, load_cases=[good]))
    except cr.SceneError as e:
        missed.append(f"the valid case was refused: {e}")
    tally.check("self-check the harness refuses what it does not model", not missed,
                "accepted: " + ", ".join(missed) if missed else f"{len(refusals)} refusals")




def checks(tally, args, tmp, harness):
    global cr
    cr = harness
    traction_self_check(tally)


def main(argv=None):
    return run(argv, "the ccx harness's tractions against hand values", checks, tools=())


if __name__ == "__main__":
    sys.exit(main())
