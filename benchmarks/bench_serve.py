"""Benchmark: the interactive page (issue 19).

Target (issue 19): a full turn of JB1-3 with its dynamics for a new slider value in at most 50 ms
(p95, warm) on the server. Measured, warm, over 50 values each of the stitch regulator and of
the needle-bar link's length:
  - the server's work per turn (Session.turn and its JSON encoding, in this process);
  - the whole request as the page makes it (HTTP POST to a real uvicorn server on 127.0.0.1);
  - the separate checks request (timing events and checks, refined on the exact kinematics);
  - in Debian's Chromium (Playwright), slider-to-redraw latency: from the slider's input event
    to the page having drawn the new turn (mechanism, diagrams, numbers), one value at a time.
Prints a table and writes ``benchmarks/results/serve.json``; a missed target prints MISSED and
exits 0. ``--screenshot PATH`` also saves the page (as docs/serve.png shows it).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
from _timing import figure, write_results  # noqa: E402

from browser_helpers import CHROMIUM_ARGS
from sewmech.app.web.session import Session, shipped_texts

RESULTS = HERE / "results" / "serve.json"
TARGET_P95_MS = 50.0


def current_figures(out: dict) -> list[dict]:
    """The rows of the table of current figures (BENCHMARKS.md) from this script's results."""
    own = {k: r for k, r in out["rows"].items() if k.startswith("turn") and "own time" in k}
    worst = max(own.values(), key=lambda r: r["p95_ms"])
    return [figure("JB1-3 page, a turn with dynamics in the server, p95 (the worse of two"
                   " sliders)", worst["p95_ms"], "ms", target=out["target_p95_ms"])]
N = 50


def pct(times_s) -> dict:
    a = np.asarray(times_s) * 1e3
    return {"p50_ms": float(np.percentile(a, 50)), "p95_ms": float(np.percentile(a, 95)),
            "max_ms": float(a.max()), "n": int(a.size)}


def slider_values():
    reg = [{"input.regulator": float(v)} for v in np.linspace(-29.5, 29.5, N)]
    rod = [{"input.regulator": 20.0, "needle_bar.length": float(v)}
           for v in np.linspace(40.0, 48.0, N)]
    return reg, rod


def server_side() -> dict:
    file, text = shipped_texts()["jb1-3"]
    s = Session.from_text(text, file)
    for _ in range(3):
        json.dumps(s.turn({"input.regulator": 1.0}))
    out = {}
    for name, values in zip(("regulator", "needle_bar.length"), slider_values()):
        times = []
        for v in values:
            t0 = time.perf_counter()
            json.dumps(s.turn(v))
            times.append(time.perf_counter() - t0)
        out[f"turn, {name} (in process)"] = pct(times)
    times = []
    for v in slider_values()[0][:20]:
        t0 = time.perf_counter()
        json.dumps(s.checks(v))
        times.append(time.perf_counter() - t0)
    out["checks, regulator (in process)"] = pct(times)
    return out


def over_http(url: str) -> dict:
    """One keep-alive connection, as a browser's; the server's own time from its
    Server-Timing header."""
    import http.client

    host, port = url.split("//")[1].split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=60)

    def post(path, body):
        conn.request("POST", path, json.dumps(body), {"Content-Type": "application/json"})
        r = conn.getresponse()
        data = json.loads(r.read())
        assert r.status == 200, data
        dur = r.getheader("Server-Timing")
        return data, (float(dur.split("dur=")[1]) / 1e3 if dur else None)

    token = post("/api/sessions", {"machine": "jb1-3"})[0]["session"]
    for _ in range(3):
        post(f"/api/sessions/{token}/turn", {"set": {"input.regulator": 1.0}})
    out = {}
    for name, values in zip(("regulator", "needle_bar.length"), slider_values()):
        times, server = [], []
        for v in values:
            t0 = time.perf_counter()
            _, dur = post(f"/api/sessions/{token}/turn", {"set": v})
            times.append(time.perf_counter() - t0)
            server.append(dur)
        out[f"turn, {name} (sewmech serve's own time)"] = pct(server)
        out[f"turn, {name} (HTTP round trip)"] = pct(times)
    conn.close()
    return out


def in_browser(url: str, screenshot: str | None) -> dict:
    exe = shutil.which("chromium")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        exe = None
    if not exe:
        print("no Chromium/Playwright: the browser latency is not measured")
        return {}
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS)
        pg = browser.new_page(viewport={"width": 1800, "height": 1050})
        pg.goto(url)
        pg.wait_for_function("window.sewmech && window.sewmech.turn && window.sewmech.checks",
                             timeout=30000)
        out = {}
        for name in ("input.regulator", "needle_bar.length"):
            values = [v[name] for v in slider_values()[0 if name == "input.regulator" else 1]]
            pg.evaluate("window.sewmech.latency = []")
            parts = []
            for v in values:
                n = pg.evaluate("window.sewmech.redraws")
                # a slider move as the page receives it: the range input's value and its event
                pg.evaluate("([name, v]) => { const r = document.querySelector("
                            "`.param[data-name='${name}'] input[type=range]`); r.min ="
                            " Math.min(+r.min, v); r.max = Math.max(+r.max, v); r.value = v;"
                            " r.dispatchEvent(new Event('input')); }", [name, v])
                pg.wait_for_function(f"window.sewmech.redraws > {n} &&"
                                     " !window.sewmech.inFlight", timeout=20000)
                parts.append(pg.evaluate("[window.sewmech.serverMs, window.sewmech.drawMs]"))
            lat = pg.evaluate("window.sewmech.latency")
            out[f"slider to redraw, {name} (Chromium)"] = pct(np.asarray(lat) / 1e3)
            parts = np.asarray(parts) / 1e3
            out[f"  of which the request, {name}"] = pct(parts[:, 0])
            out[f"  of which the drawing, {name}"] = pct(parts[:, 1])
        if screenshot:
            pg.wait_for_function("window.sewmech.checks", timeout=20000)
            time.sleep(1.0)  # the checks request after the last move
            pg.click("#play")
            pg.evaluate("window.sewmech.k = 60")
            pg.locator("#scrub").fill("60")
            pg.screenshot(path=screenshot, full_page=False)
            print(f"screenshot: {screenshot}")
        browser.close()
    return out


def main():
    shot = None
    if "--screenshot" in sys.argv:
        shot = sys.argv[sys.argv.index("--screenshot") + 1]
    rows = server_side()
    # the server in a process of its own, as `sewmech serve` runs it
    proc = subprocess.Popen([sys.executable, "-c", "from sewmech.app.cli import main; main()",
                             "serve", "jb1-3", "--port", "0"], stdout=subprocess.PIPE,
                            text=True)
    try:
        line = proc.stdout.readline()
        url = "http://" + line.split("http://")[1].split("/")[0]
        rows.update(over_http(url))
        rows.update(in_browser(url, shot))
    finally:
        proc.terminate()
        proc.wait(20)
    print(f"{'what':48s} {'p50 ms':>8s} {'p95 ms':>8s} {'max ms':>8s}")
    for k, r in rows.items():
        print(f"{k:48s} {r['p50_ms']:8.1f} {r['p95_ms']:8.1f} {r['max_ms']:8.1f}")
    worst = max(r["p95_ms"] for k, r in rows.items() if k.startswith("turn") and "own time" in k)
    verdict = "met" if worst <= TARGET_P95_MS else "MISSED"
    print(f"target: a JB1-3 turn with dynamics at most {TARGET_P95_MS:g} ms p95 in the server:"
          f" {worst:.1f} ms, {verdict}")
    out = {"rows": rows, "target_p95_ms": TARGET_P95_MS, "verdict": verdict}
    write_results(RESULTS, out, current_figures(out))


if __name__ == "__main__":
    main()
