#!/usr/bin/env python3
"""springfitd's dashboard (--http) from the outside: pages, downloads, /healthz, /metrics,
escaping, bounds, the token; and /jobs/ID of a running job in headless Chromium, whose live
update must advance while the page is open.

Usage: dashboard_test.py SPRINGFITD SPRINGFIT SOURCE_DIR [SCREENSHOT.png]
Chromium comes from scripts/install-deps.sh; without it the test fails, naming the script.
Prints PASS/FAIL per check and exits non-zero on any failure.
"""

import http.client
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET

DAEMON, CLI, SRC = sys.argv[1:4]
SCREENSHOT = sys.argv[4] if len(sys.argv) > 4 else None
TMP = tempfile.mkdtemp(prefix="springfit-dashboard-")
TOKEN = "dashboard-token-0123456789abcdef"
LABEL = "<script>alert('x')</script> & \"quoted\"\ncritical FORGED: token accepted"
failures = []
current = "?"
procs = []


def fail(what):
    failures.append((current, what))
    print(f"FAIL: [{current}] {what}", flush=True)


def expect(cond, what):
    if not cond:
        fail(what)
    return cond


def start(name, *extra):
    port_file = os.path.join(TMP, name + ".port")
    http_file = os.path.join(TMP, name + ".http")
    log = open(os.path.join(TMP, name + ".log"), "w")
    proc = subprocess.Popen([DAEMON, "--listen", "127.0.0.1:0", "--db", os.path.join(TMP, name + ".db"),
                             "--port-file", port_file, "--http", "127.0.0.1:0", "--http-port-file",
                             http_file, "--workers", "2", *extra], stdout=log, stderr=subprocess.STDOUT)
    procs.append(proc)
    for _ in range(300):
        if os.path.exists(port_file) and os.path.exists(http_file):
            return proc, int(open(port_file).read()), int(open(http_file).read())
        time.sleep(0.05)
    raise RuntimeError(f"{name} did not start")


def cli(port, *args):
    env = dict(os.environ, SPRINGFIT_SERVER=f"127.0.0.1:{port}")
    return subprocess.run([CLI, *args], env=env, capture_output=True, text=True, timeout=60)


def get(port, path, method="GET", headers=None, body=None):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    c.request(method, path, body=body, headers=headers or {})
    r = c.getresponse()
    data = r.read().decode("utf-8", "replace")
    result = (r.status, dict((k.lower(), v) for k, v in r.getheaders()), data)
    c.close()
    return result


def wait_for(predicate, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.1)
    return False


def find_chromium():
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    return None


def chromium(url, *args):
    profile = tempfile.mkdtemp(dir=TMP)
    cmd = [find_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
           "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", "--disable-dev-shm-usage", f"--user-data-dir={profile}", *args, url]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=60)


def check_pages(rpc_port, port):
    global current
    current = "pages"
    running = int(cli(rpc_port, "submit", os.path.join(SRC, "examples", "kidney-2d.json"),
                      "--strategy", "paper", "--generations", "100000", "--label", LABEL).stdout)
    # The quick job's scene states its units: the card says them as `springfit run` does.
    quick = json.load(open(os.path.join(SRC, "examples", "paper-iso-5x5.json")))
    quick["units"] = {"length": "mm", "force": "mN"}
    quick_path = os.path.join(TMP, "paper-iso-5x5-mm.json")
    json.dump(quick, open(quick_path, "w"))
    done = int(cli(rpc_port, "submit", quick_path, "--label", "quick").stdout)
    expect(cli(rpc_port, "watch", str(done), "-q").returncode == 0, "the quick job did not finish")
    expect(wait_for(lambda: json.loads(get(port, f"/jobs/{running}/progress.json")[2])
                    .get("generation_number", -1) >= 2, 30), "the long job made no progress")
    # Its trace and improvements reach the store once a second.
    expect(wait_for(lambda: get(port, f"/jobs/{running}/error.svg")[0] == 200, 30),
           "the long job stored no trace")

    status, headers, page = get(port, "/")
    expect(status == 200 and headers["content-type"].startswith("text/html"), f"/: {status}")
    expect(f'href="/jobs/{running}"' in page and f'href="/jobs/{done}"' in page, "/ lists the jobs")
    expect(page.find(f'/jobs/{done}"') < page.find(f'/jobs/{running}"'), "/ lists newest first")
    expect("<script>alert" not in page, "a label's <script> reached the page unescaped")
    expect("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; &quot;quoted&quot;" in page or
           "&lt;script&gt;alert('x')&lt;/script&gt; &amp; &quot;quoted&quot;" in page,
           "the label is not shown escaped on /")
    # The label's newline cannot forge a log line (server/log_format.h).
    log = open(os.path.join(TMP, "main.log")).read()
    expect(not any(line.startswith("critical FORGED") for line in log.splitlines()),
           "a label forged a log line")
    expect("\\ncritical FORGED" in log, "the label's newline is not escaped in the log")
    status, _, filtered = get(port, "/?state=succeeded")
    expect(status == 200 and f'/jobs/{done}"' in filtered and f'/jobs/{running}"' not in filtered,
           "/?state=succeeded filters")
    status, _, by_label = get(port, "/?label=quick")
    expect(f'/jobs/{done}"' in by_label and f'/jobs/{running}"' not in by_label, "/?label= filters")
    expect(get(port, "/?state=bogus")[0] == 400, "an unknown state is a 400")

    status, _, page = get(port, f"/jobs/{running}")
    expect(status == 200, f"/jobs/{running}: {status}")
    expect('id="live"' in page and "fetch(" in page, "a running job's page updates itself")
    expect(re.search(r'<figure id="error-plot"><svg', page), "no error plot on the running job's page")
    expect("<script>alert" not in page, "the label is unescaped on the job page")
    status, _, page = get(port, f"/jobs/{done}")
    expect(re.search(r'<figure id="topology"><svg', page), "no result figure on the finished job's page")
    expect('id="identifiability"' in page, "no identifiability report")
    # The page opens with the result card: the verdict and E as `springfit result` gives them.
    result = json.loads(cli(rpc_port, "result", str(done), "--json").stdout)
    card = page.find('id="result-card"')
    expect(0 <= card < page.find('id="settings"') and card < page.find('id="topology"'),
           "the finished job's page does not open with its result card")
    expect('<strong class="verdict usable">usable</strong>' in page, "the card lacks the verdict")
    expect(f"<th>springs</th><td>{len(result['springs'])}</td>" in page,
           "the card's spring count is not the result's")
    expect(f"<th>E (named cases)</th><td>{result['outcome']['rms_error']:.3g}</td>" in page,
           "the card's E is not the result's")
    expect("<th>units</th><td>length mm, force mN, stiffness mN/mm, mass kg, time s (E is "
           "relative: no unit)</td>" in page, "the card does not state the scene's units")
    expect("<th>settings submitted</th>" in page and "<th>option: max_generations</th>" in page,
           "the card lacks the settings submitted and the options as run")
    status, _, listing = get(port, "/?label=quick")
    expect(f"<td>usable</td><td class=\"num\">{len(result['springs'])}</td>" in listing,
           "/ does not list the verdict and springs")
    for link in ("result.json", "trace.csv", "model.vtu"):
        expect(f'/jobs/{done}/{link}"' in page, f"no link to {link}")
    status, headers, body = get(port, f"/jobs/{done}/result.json")
    expect(status == 200 and json.loads(body)["state"] == "succeeded", "result.json")
    expect("attachment" in headers.get("content-disposition", ""), "result.json is a download")
    local = cli(rpc_port, "result", str(done), "--json")
    expect(json.loads(body)["springs"] == json.loads(local.stdout)["springs"],
           "result.json differs from job.result")
    status, _, body = get(port, f"/jobs/{done}/trace.csv")
    expect(status == 200 and body.splitlines()[0].startswith("generation,"), "trace.csv")
    status, _, body = get(port, f"/jobs/{done}/model.vtu")
    root = ET.fromstring(body)
    expect(status == 200 and root.tag == "VTKFile" and root.find("UnstructuredGrid") is not None,
           "model.vtu is not a VTK unstructured grid")
    status, headers, body = get(port, f"/jobs/{running}/topology.svg?of=best")
    expect(status == 200 and headers["content-type"] == "image/svg+xml" and "<svg" in body,
           "the best-so-far figure")
    expect(get(port, f"/jobs/{running}/result.json")[0] == 404, "a running job has no result.json")

    status, _, body = get(port, "/healthz")
    expect(status == 200 and body == "ok\n", f"/healthz: {status} {body!r}")
    status, headers, metrics = get(port, "/metrics")
    expect(status == 200 and headers["content-type"].startswith("text/plain; version=0.0.4"),
           "/metrics content type")
    for needle in ('springfit_jobs{state="running"} 1', 'springfit_jobs{state="succeeded"} 1',
                   # The finished job's verdict, as `springfit run` gives it (issue 33).
                   'springfit_jobs_finished_total{state="succeeded",verdict="usable"} 1',
                   "springfit_running_jobs 1", "springfit_queue_length 0",
                   'springfit_rpc_requests_total{method="job.submit"} 2',
                   'springfit_store_write_seconds_bucket{operation="progress",le="+Inf"}',
                   "springfit_evaluations_per_second "):
        expect(needle in metrics, f"/metrics lacks {needle}")
    evaluations = re.search(r"^springfit_evaluations_total (\d+)$", metrics, re.M)
    expect(evaluations and int(evaluations.group(1)) > 0, "no evaluations counted")

    expect(get(port, "/jobs/999999")[0] == 404, "an unknown job is a 404")
    expect(get(port, "/jobs/12abc")[0] == 404, "a bad id is a 404")
    expect(get(port, "/nothing")[0] == 404, "an unknown path is a 404")
    expect(get(port, "/", method="POST", body="x")[0] == 405, "POST / is a 405")
    expect(get(port, "/", headers={"X-Big": "a" * 20000})[0] == 431, "a huge header is a 431")
    expect(get(port, "/", headers={f"X-H{i}": "1" for i in range(100)})[0] == 431,
           "100 headers are a 431")
    # A client that sends half a request and stalls holds nothing: the others are served.
    stall = socket.create_connection(("127.0.0.1", port))
    stall.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n")
    expect(get(port, "/healthz")[0] == 200, "a stalled client blocked another")
    stall.close()
    return running


def check_browser(port, running):
    global current
    current = "browser"
    if not find_chromium():
        fail("Chromium is missing: run scripts/install-deps.sh")
        return
    url = f"http://127.0.0.1:{port}/jobs/{running}"
    # Six seconds of the page's own time: the live update polls once a second and fetches the
    # error plot again every fifth time.
    r = chromium(url, "--virtual-time-budget=6500", "--dump-dom")
    dom = r.stdout
    live = re.search(r'<table id="live"[^>]*>', dom)
    if not expect(live, f"no progress table in the page Chromium loaded: {r.stderr[-500:]}"):
        return
    attrs = dict(re.findall(r'([\w-]+)="([^"]*)"', live.group(0)))
    updates = int(attrs.get("data-updates", "0"))
    before, after = int(attrs["data-initial-generation"]), int(attrs["data-generation"])
    expect(updates >= 5, f"the page updated itself {updates} times in 6.5 s (the error plot is "
           "fetched again at the fifth)")
    expect(after > before, f"the progress shown did not advance ({before} -> {after})")
    shown = re.search(r'id="p-generation">(\d+) /', dom)
    expect(shown and int(shown.group(1)) == after, "the generation shown is not the one fetched")
    # The plot as the fifth update left it: an SVG element, no XML declaration turned comment.
    expect(re.search(r'<figure id="error-plot"><svg', dom),
           f"no error plot in the browser's page: {dom[dom.find('error-plot'):][:120]!r}")
    # (Inline, or above 256 KB, as the kidney's seven load cases are, a linked image.)
    expect(re.search(r'<figure id="topology">(<svg|<img src="/jobs/\d+/topology\.svg\?of=best")', dom),
           "no topology figure in the browser's page")
    if SCREENSHOT:
        shot = chromium(url, "--window-size=1280,2200", f"--screenshot={SCREENSHOT}",
                        "--virtual-time-budget=2500")
        expect(os.path.exists(SCREENSHOT) and os.path.getsize(SCREENSHOT) > 10000,
               f"no screenshot: {shot.stderr[-300:]}")


def check_token():
    global current
    current = "token"
    token_file = os.path.join(TMP, "token")
    with open(token_file, "w") as f:
        f.write(TOKEN + "\n")
    os.chmod(token_file, 0o600)
    _, _, port = start("auth", "--token-file", token_file)
    expect(get(port, "/")[0] == 401, "/ without the token")
    expect(get(port, "/metrics")[0] == 401, "/metrics without the token")
    status, headers, _ = get(port, "/", headers={"Accept": "text/html"})
    expect(status == 303 and headers.get("location") == "/login", "a browser is sent to /login")
    expect(get(port, "/healthz")[0] == 200, "/healthz needs no token")
    expect(get(port, "/", headers={"Authorization": "Bearer " + TOKEN})[0] == 200, "bearer token")
    expect(get(port, "/", headers={"Authorization": "Bearer " + TOKEN[:-1] + "X"})[0] == 401,
           "a wrong bearer token")
    form = {"Content-Type": "application/x-www-form-urlencoded"}
    expect(get(port, "/login", "POST", form, "token=wrong")[0] == 401, "a wrong login")
    status, headers, _ = get(port, "/login", "POST", form, "token=" + TOKEN)
    cookie = headers.get("set-cookie", "")
    expect(status == 303 and "HttpOnly" in cookie and "SameSite=Strict" in cookie,
           f"the login sets an HttpOnly cookie: {status} {cookie}")
    value = cookie.split(";")[0]
    expect(get(port, "/", headers={"Cookie": value})[0] == 200, "the login cookie opens /")


def check_phase(rpc_port, port):
    """A running continuous job shows its phase and E, live, and its steps, not generations of
    a limit (issue 33)."""
    global current
    current = "phase"
    job = int(cli(rpc_port, "submit", os.path.join(SRC, "examples", "fem-kidney-2d-fine.json"),
                  "--label", "phase").stdout)
    seen = {}

    def phase_shown():
        p = json.loads(get(port, f"/jobs/{job}/progress.json")[2])
        seen.update(p)
        return p.get("phase", "-") != "-"
    expect(wait_for(phase_shown, 30), f"no phase shown for the running continuous job: {seen}")
    name = seen.get("phase", "-").split(",")[0]
    expect(name in ("analysis", "probes", "probe_fit", "probe_path", "probe_lift",
                    "nonlinear_fit", "certificate", "nonlinear", "as_simulated", "fit", "path",
                    "refit", "held_out"), f"an unexpected phase: {seen.get('phase')}")
    # The probe fit's time left at most, as the CLI's progress line says it (issue 47 item 5).
    expect(wait_for(lambda: phase_shown() and "ETA <= " in seen.get("phase", ""), 60),
           f"no time left shown for the running probe fit: {seen}")
    expect("/" not in seen.get("generation", ""), f"a continuous job shown by generations: {seen}")
    status, _, page = get(port, f"/jobs/{job}")
    expect(status == 200 and '<span id="p-phase">' in page, "the job page has no live phase")
    cli(rpc_port, "cancel", str(job))


def main():
    global current
    try:
        _, rpc_port, port = start("main")
        running = check_pages(rpc_port, port)
        check_browser(port, running)
        check_phase(rpc_port, port)
        check_token()
    except Exception as e:  # noqa: BLE001 - a crash is a failure of the check it was in
        fail(f"{type(e).__name__}: {e}")
    finally:
        for p in procs:
            p.send_signal(signal.SIGKILL)
            p.wait()
    checks = ("pages", "browser", "phase", "token")
    failed = {name for name, _ in failures}
    for name in checks:
        print(f"{'FAIL' if name in failed else 'PASS'}: {name}")
    if failures:
        for name in os.listdir(TMP):
            if name.endswith(".log"):
                print(f"--- {name}\n" + open(os.path.join(TMP, name)).read()[-1500:])
    print(f"{len(checks) - len(failed & set(checks))} passed, {len(failed & set(checks))} failed")
    shutil.rmtree(TMP, ignore_errors=True)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
