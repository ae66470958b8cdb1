#!/usr/bin/env python3
"""The Python client library (python/springfit_client): every method on jobs, against a real
springfitd.

Usage: client_library_jobs_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts springfitd on 127.0.0.1 (a free port, SQLite in a temporary directory, a token file)
and checks: submit, watch with a progress callback (notifications and polling), result with
springs and a verdict, list and trace over several pages, export to .vtu and .scn, cancelling
a finished job (-32006) and a running one, delete, unknown job ids (-32002), idempotency keys,
search options, a submission's notices and phases, and submit_mesh through `springfit
import`. Python 3 standard library only (the shared part: client_library_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import json
import os
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
from client_library_support import expect_rpc_error, run_groups, test_setup as shared_setup  # noqa: E402
# (harness.py is in tests/daemon, which importing client_library_support puts on sys.path)
from harness import R, require, short  # noqa: E402

JOB_TIMEOUT = 60.0        # for a small job to finish (watch's timeout)
VERDICTS = ("usable", "unmet_request", "unusable")

sf = None   # the springfit_client module, imported from SOURCE_DIR/python in setup


def test_setup(ctx):
    """client_library_support's setup; the springfit_client module it imports is sf here."""
    global sf
    sf = shared_setup(ctx)


def wait_for(c, job_id, states, timeout):
    deadline = time.monotonic() + timeout
    while True:
        job = c.status(job_id)
        if job.state in states or time.monotonic() > deadline:
            return job
        time.sleep(0.05)


def test_round_trip(ctx):
    label = f"round-trip-{ctx.nonce}"
    with ctx.client() as c:
        # A job of a couple of seconds, so that job.progress notifications come while it runs.
        job_id = c.submit(ctx.kidney_path, label=label, seed=5, priority=3, strategy="paper",
                          generations=40)
        R.expect(isinstance(job_id, int), f"submit returned {job_id!r}, not a job id")
        seen = []
        job = c.watch(job_id, on_progress=seen.append, timeout=JOB_TIMEOUT)
        R.expect(job.job_id == job_id and job.state == "succeeded", f"the watched job: {job}")
        R.expect(job.verdict in VERDICTS and job.outcome.verdict == job.verdict and
                 isinstance(job.outcome.rms_error, float), f"the finished job's verdict: {job.outcome}")
        R.expect(job.label == label and job.seed == 5 and job.priority == 3 and
                 job.strategy == "paper" and job.max_generations == 40,
                 f"the job's label, seed, priority, strategy, generation limit: {job}")
        live = [p for p in seen if not p.final]
        R.expect(len(seen) >= 1, "watch: on_progress was never called")
        R.expect(len(live) >= 1, f"watch: no job.progress notification reached on_progress: {seen}")
        R.expect(all(p.job_id == job_id and p.max_generations == 40 for p in seen),
                 f"progress of another job or without its limit: {seen}")
        gens = [p.generation for p in seen]
        R.expect(gens == sorted(gens) and len(set(gens)) == len(gens), f"progress generations: {gens}")
        R.expect(seen[-1].generation == 40 and seen[-1].final == (len(seen) > len(live)),
                 f"the last progress reported: {seen[-1]}")
        ctx.finished_job = (job_id, job)
        # Watching a finished job, by notifications and by polling: its last row, once.
        for poll in (None, 0.05):
            again = []
            job2 = c.watch(job_id, on_progress=again.append, poll_interval=poll, timeout=JOB_TIMEOUT)
            R.expect(job2.state == "succeeded" and job2.verdict == job.verdict,
                     f"watch (poll_interval {poll}) of the finished job: {job2}")
            R.expect([(p.generation, p.final, p.job_id) for p in again] == [(40, True, job_id)],
                     f"watch (poll_interval {poll}) of the finished job reported {again}")

        result = c.result(job_id)
        R.expect(result.job_id == job_id and result.state == "succeeded", f"result: {result}")
        R.expect(isinstance(result.springs, list) and len(result.springs) > 0 and
                 all(isinstance(s, list) and len(s) == 2 for s in result.springs),
                 f"result.springs: {short(result.springs)}")
        R.expect(result.verdict == job.verdict and result.outcome.springs == len(result.springs),
                 f"result.outcome {result.outcome} against the job's verdict {job.verdict}")
        R.expect(result.generations == 40 and result.ran == "paper" and result.seed == 5,
                 f"result: {result}")

        rows = c.trace(job_id)
        R.expect([r.generation for r in rows] == list(range(41)),
                 f"trace generations: {[r.generation for r in rows]}")
        R.expect(all(isinstance(r.best_normalized_error, float) for r in rows), "trace rows' errors")

        listed = [j for j in c.list() if j.job_id == job_id]
        R.expect(len(listed) == 1 and listed[0].verdict == job.verdict, f"list() finds the job: {listed}")
        by_label = c.list(label=label)
        R.expect([j.job_id for j in by_label] == [job_id], f"list(label=...): {by_label}")
        R.expect(job_id in [j.job_id for j in c.list(state="succeeded")], "list(state='succeeded')")
        R.expect(c.list(label=label, state="running") == [], "list(label, state='running') is not empty")

        vtu = os.path.join(ctx.tmp, "model.vtu")
        R.expect(c.export(job_id, vtu) == vtu, "export returns the path")
        with open(vtu, "rb") as f:
            head = f.read(4096)
        R.expect(head.startswith(b"<?xml") and b'<VTKFile type="UnstructuredGrid"' in head,
                 f"the exported .vtu: {short(head)}")
        # The command's options, by the same names: a SOFA scene for a release, with masses.
        scn = os.path.join(ctx.tmp, "model.scn")
        c.export(job_id, scn, node_mass=2.5, sofa_version="v24.06", dead_fraction=1e-4)
        with open(scn, encoding="utf-8") as f:
            text = f.read()
        R.expect("SOFA v24.06" in text and 'vertexMass="2.5"' in text,
                 f"export's options reach the scene: {short(text)}")
        try:
            c.export(job_id, scn, sofa_version="v1.0")
            R.fail("export with an unknown SOFA release: no error")
        except sf.CliError as e:
            R.expect(e.returncode == 2 and "v1.0" in e.stderr, f"an unknown release: {e}")
        try:
            c.export(987654, os.path.join(ctx.tmp, "none.vtu"))
            R.fail("export of an unknown job: no error")
        except sf.CliError as e:
            R.expect(e.returncode == 4 and "no such job" in e.stderr, f"export of an unknown job: {e}")

        # Cancelling a finished job: -32006 with its state.
        e = expect_rpc_error("cancel of a finished job", sf.WRONG_STATE, c.cancel, job_id)
        R.expect(e is None or e.data.get("state") == "succeeded", f"its data: {e and e.data}")
        R.expect(c.status(job_id).state == "succeeded", "the finished job changed after cancel")

        # An unknown id: -32002 with the id, from every method that names a job.
        unknown = 987654
        for name, fn in (("status", c.status), ("result", c.result), ("trace", c.trace),
                         ("cancel", c.cancel), ("delete", c.delete), ("watch", c.watch)):
            e = expect_rpc_error(f"{name} of an unknown job", sf.NO_SUCH_JOB, fn, unknown)
            R.expect(e is None or e.data.get("job_id") == unknown, f"{name}: the error's data: {e and e.data}")
        R.expect(c.status(job_id).job_id == job_id, "the connection after the errors")


def test_paging(ctx):
    """list() and trace() follow next_cursor / next_after: the pages made small."""
    label = f"paging-{ctx.nonce}"
    client_module = sys.modules["springfit_client.client"]
    saved = client_module._LIST_PAGE, client_module._TRACE_PAGE
    try:
        with ctx.client() as c:
            ids = [c.submit(ctx.iso_path, label=label) for _ in range(5)]
            for job_id in ids:
                c.watch(job_id, timeout=JOB_TIMEOUT)
            client_module._LIST_PAGE, client_module._TRACE_PAGE = 2, 7
            R.expect([j.job_id for j in c.list(label=label)] == ids, f"list over pages of 2: {ids}")
            R.expect([j.job_id for j in c.list(label=label, order="newest")] == ids[::-1],
                     "list newest first over pages of 2")
            R.expect([j.job_id for j in c.list(label=label, limit=3)] == ids[:3], "list with limit 3")
            if ctx.finished_job is not None:
                rows = c.trace(ctx.finished_job[0])
                R.expect([r.generation for r in rows] == list(range(41)),
                         f"trace over pages of 7: {[r.generation for r in rows]}")
    finally:
        client_module._LIST_PAGE, client_module._TRACE_PAGE = saved


def test_submit_options(ctx):
    key = f"key-{ctx.nonce}"
    with ctx.client() as c:
        with open(ctx.iso_path) as f:
            scene = json.load(f)
        before = json.dumps(scene, sort_keys=True)
        first = c.submit_job(scene, idempotency_key=key, strategy="paper", generations=7, stall=3,
                             search={"population": 12})
        R.expect(first.created is True and first.job.idempotency_key == key, f"first submit: {first}")
        again = c.submit_job(scene, idempotency_key=key, strategy="paper", generations=7, stall=3,
                             search={"population": 12})
        R.expect(again.created is False and again.job.job_id == first.job.job_id,
                 f"a second submit with the key: {again}")
        R.expect(json.dumps(scene, sort_keys=True) == before, "submit changed the caller's scene")
        stored = c.scene(first.job.job_id)
        want = {"strategy": "paper", "max_generations": 7, "stall_generations": 3, "population": 12}
        got = {k: stored.get("search", {}).get(k) for k in want}
        R.expect(got == want, f"the stored scene's search: {got}, expected {want}")
        c.watch(first.job.job_id, timeout=JOB_TIMEOUT)
        # The probe fit's options, as springfit submit's --max-spread and --load-size write them.
        tuned = c.submit(ctx.kidney_path, label=f"tuned-{ctx.nonce}", strategy="continuous",
                         max_spread=1000, load_size=0.5)
        search = c.scene(tuned).get("search", {})
        R.expect(search.get("max_spread") == 1000 and search.get("load_size") == 0.5,
                 f"the stored scene's search: {search}")
        c.watch(tuned, timeout=JOB_TIMEOUT)
        try:
            c.submit(scene, generation=5)
            R.fail("submit with an unknown option: accepted")
        except TypeError:
            pass
        # An invalid scene: -32003 with the field's path.
        bad = json.loads(before)
        bad["reference"]["springs"][0] = [0, 999]
        e = expect_rpc_error("an invalid scene", sf.INVALID_SCENE, c.submit, bad)
        R.expect(e is None or e.data.get("path", "").startswith("reference.springs[0]"),
                 f"the invalid scene's path: {e and e.data}")


def test_notices_and_phases(ctx):
    """A submission's notices, and the phases a watch reports between rows (job.phase)."""
    with open(os.path.join(ctx.source, "examples", "fem-kidney-2d.json")) as f:
        scene = json.load(f)
    scene["reference"]["material"]["poisson"] = 0.495
    scene["name"] = f"locking kidney {ctx.nonce}"
    with ctx.client() as c:
        submitted = c.submit_job(scene)
        R.expect(submitted.created and any("0.495" in n for n in submitted.notices or []),
                 f"the submission's notices: {submitted.notices}")
        phases, rows = [], []
        job = c.watch(submitted.job.job_id, on_phase=phases.append, on_progress=rows.append,
                      timeout=JOB_TIMEOUT)
        R.expect(job.finished, f"the job: {job}")
        # (A continuous job's rows are its fit's steps: no generation limit, where the watch
        # reported "generation 0/1000", issue 47 item 6.)
        R.expect(job.strategy == "continuous" and job.max_generations == 0 and rows and
                 all(r.max_generations == 0 for r in rows + phases),
                 f"a continuous job's generation limit: {job.max_generations}, "
                 f"{[r.max_generations for r in rows + phases]}")
        known = {"direct", "genetic", "regularization", "fit", "path", "refit", "held_out",
                 "probes", "probe_fit", "probe_path", "probe_lift",
                 "nonlinear_fit", "certificate", "nonlinear"}
        R.expect(phases and all(isinstance(p, sf.Phase) and p.job_id == job.job_id and
                                p.phase in known and p.wall_seconds >= 0 for p in phases),
                 f"on_phase: {phases}")


def test_cancel_delete(ctx):
    with ctx.client() as c:
        job_id = c.submit(ctx.kidney_path, label=f"long-{ctx.nonce}", strategy="paper",
                          generations=100000)
        ctx.long_jobs.append(job_id)
        job = wait_for(c, job_id, ("running",), 20)
        require(job.state == "running", f"the long job does not run: {job}")
        e = expect_rpc_error("delete of a running job", sf.WRONG_STATE, c.delete, job_id)
        R.expect(e is None or e.data.get("state") == "running", f"its data: {e and e.data}")
        # A watch that times out leaves the job running and the client usable.
        t0 = time.monotonic()
        try:
            c.watch(job_id, timeout=1.0)
            R.fail("watch(timeout=1) of a long job returned")
        except sf.WatchTimeout as e:
            R.expect(e.job is not None and e.job.job_id == job_id, f"WatchTimeout.job: {e.job}")
        R.expect(time.monotonic() - t0 < 5, f"watch(timeout=1) took {time.monotonic() - t0:.1f} s")
        R.expect(c.status(job_id).state == "running", "the job after a watch's timeout")
        state = c.cancel(job_id)
        R.expect(state == "cancelling", f"cancel of a running job: {state!r}, expected 'cancelling'")
        seen = []
        job = c.watch(job_id, on_progress=seen.append, poll_interval=0.1, timeout=JOB_TIMEOUT)
        R.expect(job.state == "cancelled" and job.finished, f"the cancelled job: {job}")
        R.expect(len(seen) >= 1 and seen[-1].job_id == job_id, f"polling watch's progress: {seen}")
        result = c.result(job_id)   # the best so far of a job cancelled while running
        R.expect(result.state == "cancelled" and result.stop == "cancelled", f"its result: {result}")
        c.delete(job_id)
        expect_rpc_error("status of a deleted job", sf.NO_SUCH_JOB, c.status, job_id)


def write_square_mesh(path, n=4, size=1.0):
    """An n x n-node square as Gmsh MSH 2.2 (ASCII): 2 (n-1)^2 triangles, physical curves
    "left" and "right", physical surface "body"."""
    h = size / (n - 1)

    def tag(x, y):
        return y * n + x + 1
    nodes = [f"{tag(x, y)} {x * h:g} {y * h:g} 0" for y in range(n) for x in range(n)]
    elements = []
    for y in range(n - 1):
        elements.append(("1 2 1 1", (tag(0, y), tag(0, y + 1))))
        elements.append(("1 2 2 2", (tag(n - 1, y), tag(n - 1, y + 1))))
        for x in range(n - 1):
            a, b, c, d = tag(x, y), tag(x + 1, y), tag(x + 1, y + 1), tag(x, y + 1)
            elements += [("2 2 3 3", (a, b, c)), ("2 2 3 3", (a, c, d))]
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", "3",
             '1 1 "left"', '1 2 "right"', '2 3 "body"', "$EndPhysicalNames",
             "$Nodes", str(len(nodes))] + nodes + ["$EndNodes", "$Elements", str(len(elements))]
    lines += [f"{i + 1} {kind} {' '.join(map(str, ns))}" for i, (kind, ns) in enumerate(elements)]
    lines.append("$EndElements")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def test_submit_mesh(ctx):
    mesh = os.path.join(ctx.tmp, "square.msh")
    loads = os.path.join(ctx.tmp, "square-loads.json")
    write_square_mesh(mesh)
    with open(loads, "w") as f:
        json.dump({"reference": {"material": {"model": "linear", "young": 1, "poisson": 0.3},
                                 "plane": "stress", "thickness": 1},
                   "load_cases": [{"name": "stretch", "fixed": "left",
                                   "tractions": [{"on": "right", "total": [0.01, 0]}]},
                                  {"name": "shear", "fixed": "left",
                                   "tractions": [{"on": "right", "total": [0, 0.002]}]}]}, f)
    with ctx.client() as c:
        job_id = c.submit_mesh(mesh, loads, label=f"mesh-{ctx.nonce}")
        job = c.watch(job_id, timeout=JOB_TIMEOUT)
        R.expect(job.scene == "square" and job.state == "succeeded" and job.strategy == "continuous",
                 f"the mesh's job: {job}")
        R.expect(job.verdict in VERDICTS and job.outcome.baseline_rms_error is not None,
                 f"the mesh job's outcome: {job.outcome}")
        stored = c.scene(job_id)
        R.expect(len(stored.get("nodes", [])) == 16 and stored.get("reference", {}).get("type") == "fem",
                 f"the stored scene of the mesh: {short(stored)}")
        # A mesh alone (no loads) is imported, and refused for its missing load cases.
        e = expect_rpc_error("submit of a mesh without loads", sf.INVALID_SCENE, c.submit, mesh)
        R.expect(e is None or e.data.get("path") == "load_cases", f"its data: {e and e.data}")
        try:
            c.submit_mesh(os.path.join(ctx.tmp, "no-such.msh"), loads)
            R.fail("submit_mesh of a missing file: no error")
        except sf.CliError as e:
            R.expect(e.returncode == 2 and "no-such.msh" in e.stderr, f"submit_mesh of a missing file: {e}")


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("setup", test_setup, True),
        ("submit, watch, result, list, trace, export", test_round_trip, False),
        ("paging", test_paging, False),
        ("submit options", test_submit_options, False),
        ("notices and phases", test_notices_and_phases, False),
        ("cancel and delete", test_cancel_delete, False),
        ("submit_mesh", test_submit_mesh, False),
    ]))
