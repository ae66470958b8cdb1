#!/usr/bin/env python3
"""Identification on FEM references (issue 16): the default strategy (continuous) on each FEM
example, against the closed-form baseline, with the time to the first model better than it,
the sparsity path's ends, the held-out error and its worst case, the seconds to the model and
in all (bench/RESULTS.md, "Identification on FEM
references").

    python3 bench/fem_identification.py [--springfit build/client/springfit] [--threads 1]
        [examples/fem-plate-5x5.json ...]

Each scene is run once with `springfit run -o`; times are wall seconds on this machine.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

DEFAULT_SCENES = ["examples/fem-plate-5x5.json", "examples/fem-kidney-2d.json",
                  "examples/fem-kidney-2d-nl.json", "examples/fem-kidney-2d-fine.json",
                  "examples/fem-block-3d.json"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", default=DEFAULT_SCENES)
    parser.add_argument("--springfit", default="build/client/springfit")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--extra", nargs=argparse.REMAINDER, default=[],
                        help="further options for springfit run")
    args = parser.parse_args()
    print("| scene | genes | response | baseline E | E | springs | first model < baseline | "
          "fit E (springs) | path: springs at 1.5x E | held-out E (x E) | worst predicted case | "
          "model s | total s |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for scene in args.scenes:
            out = os.path.join(tmp, "result.json")
            cmd = [args.springfit, "run", scene, "-q", "--threads", str(args.threads), "-o", out]
            cmd += args.extra
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
            r = json.load(open(out))
            c = r["continuous"]
            base = r["baseline"]["rms_error"] if r["baseline"]["converged"] else float("nan")
            first = next((row for row in r["trace"]
                          if math.sqrt(row["best_normalized_error"]) < base), None)
            first_text = ("%.2f s (E %.3g)" % (first["wall_seconds"],
                                               math.sqrt(first["best_normalized_error"]))
                          if first else "never")
            e = r["rms_error"]
            path = c["path"]
            fit = path[0]
            near = [p for p in path if p["rms_error"] <= 1.5 * fit["rms_error"]]
            smallest = min(near, key=lambda p: p["springs"])
            held = c["held_out_rms_error"]
            held_text = "%.4g (%.2fx)" % (held, held / e) if held is not None else "-"
            per_case = c["held_out_rms_error_per_case"]
            worst_text = "-"
            if per_case:
                # null: no equilibrium, the worst there is
                k = max(range(len(per_case)),
                        key=lambda i: math.inf if per_case[i] is None else per_case[i])
                worst_text = "%s: %s (%.3g fitted)" % (
                    r["load_cases"][k]["name"],
                    "none" if per_case[k] is None else "%.3g" % per_case[k],
                    math.sqrt(r["load_cases"][k]["normalized_error"]))
            print("| %s | %d | %s | %.4g | %.4g | %d | %s | %.4g (%d) | %d (E %.3g) | %s | %s | "
                  "%.1f | %.1f |" % (
                      r["scene"], r["genes"], r["response"], base, e, len(r["springs"]),
                      first_text, fit["rms_error"], fit["springs"], smallest["springs"],
                      smallest["rms_error"], held_text, worst_text, c["model_seconds"],
                      r["wall_seconds"]))
            sys.stdout.flush()


if __name__ == "__main__":
    main()
