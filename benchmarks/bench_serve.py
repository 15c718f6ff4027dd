"""Benchmark: the interactive page (issues 19 and 34).

Target (issue 19): a full turn of JB1-3 with its dynamics for a new slider value in at most 50 ms
(p95, warm) on the server. Measured, warm, over 50 values each of the stitch regulator and of
the needle-bar link's length:
  - the server's work per turn (Session.turn_json: the turn and its JSON, in this process);
  - the whole request as the page makes it (HTTP POST to a real uvicorn server on 127.0.0.1);
  - the separate checks request (timing events and checks, refined on the exact kinematics);
  - in Debian's Chromium (Playwright), slider-to-redraw latency: from the slider's input event
    to the page having drawn the new turn (mechanism, diagrams, numbers), one value at a time.
Many pages at once (issue 34, item 4; ``--pages N``, ``--seconds S``): N pages on 127.0.0.1, each
with its own session, each dragging its own sliders as fast as the server answers (the page's
own rule: one turn in flight, the newest values sent when it returns; no pause between turns,
the worst case) for S seconds. Prints the turn's median, p95 and max latency, answers/s, the
server's memory (its process and its workers, RSS) at the start, every 10 s and at the end, and
the cross-talk check: every answer is for its own page's design (its regulator setting and
its needle-bar link's length, read off the answer's points at every angle), and a sample of
answers is exactly what the library computes for that design in this process.
Target (issue 34): 20 pages for 60 s, p95 at most 200 ms on the 2-core machine, no cross-talk,
memory flat.

Prints a table and writes ``benchmarks/results/serve.json``; a missed target prints MISSED and
exits 0. ``--screenshot PATH`` also saves the page (as docs/serve.png shows it); ``--only-pages``
measures only the many pages (the file's other figures are kept); ``--workers N`` is passed to
``sewmech serve`` (left out: the server's default).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
from _timing import figure, run_stamp, write_results  # noqa: E402

from browser_helpers import CHROMIUM_ARGS
from sewmech.app.web.session import Session, shipped_texts

RESULTS = HERE / "results" / "serve.json"
TARGET_P95_MS = 50.0
#: many pages at once (issue 34): the turn's p95 under 20 pages for 60 s
TARGET_PAGES_P95_MS = 200.0


def current_figures(out: dict) -> list[dict]:
    """The rows of the table of current figures (BENCHMARKS.md) from this script's results."""
    own = {k: r for k, r in out["rows"].items() if k.startswith("turn") and "own time" in k}
    worst = max(own.values(), key=lambda r: r["p95_ms"])
    return [figure("JB1-3 page, a turn with dynamics in the server, p95 (the worse of two"
                   " sliders)", worst["p95_ms"], "ms", target=out["target_p95_ms"])] + ([
        pages_figure(out["many_pages"])] if out.get("many_pages") else [])


#: how the row of the many pages begins in the table of current figures
PAGES_JOB = "JB1-3 page, "


def pages_figure(r: dict) -> dict:
    """The row of the many pages at once in the table of current figures."""
    return figure(f"{PAGES_JOB}{r['pages']} pages dragging at once for {r['seconds']:.0f} s,"
                  " p95 (no cross-talk)", r["p95_ms"], "ms", target=TARGET_PAGES_P95_MS,
                  condition=("no cross-talk", r["crosstalk"] == 0 and not r["sample_mismatch"]))
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
        s.turn_json({"input.regulator": 1.0})
    out = {}
    for name, values in zip(("regulator", "needle_bar.length"), slider_values()):
        times = []
        for v in values:
            t0 = time.perf_counter()
            s.turn_json(v)  # as the server writes it
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


# ---- many pages at once (issue 34) ---------------------------------------------------------------
def page_values(page: int, k: int) -> dict:
    """The ``k``-th design page ``page`` asks for: its own needle-bar link length (pages 0.2 mm
    apart, moving 0.001 mm a turn within that) and a regulator sweeping the whole range from a
    setting of its own, so that no two pages ever send the same design."""
    length = 42.0 + 0.2 * page + 0.001 * (k % 150)
    regulator = -29.5 + (2.9 * page + 0.7 * k) % 59.0
    return {"input.regulator": round(regulator, 6), "needle_bar.length": round(length, 6)}


def fingerprint(turn: dict) -> tuple:
    """A few numbers that differ between any two of the pages' designs."""
    d = turn["dynamics"] or {}
    return (turn["feed"]["stitch_mm"], d.get("mean_torque_Nmm"), turn["thread"]["consumption_mm"],
            turn["points"]["C"]["y"][7])


def crosstalk(turn: dict, values: dict) -> str | None:
    """Why an answer is not for the design asked (None: it is): its regulator setting, and the
    needle-bar link's length |BC| at every angle of the turn."""
    reg = turn["feed"]["regulator_deg"]
    if not math.isclose(reg, values["input.regulator"], abs_tol=1e-5):
        return f"regulator {reg} for {values['input.regulator']}"
    pb, pc = turn["points"]["B"], turn["points"]["C"]
    bc = np.hypot(np.subtract(pb["x"], pc["x"]), np.subtract(pb["y"], pc["y"]))
    if not np.allclose(bc, values["needle_bar.length"], atol=1e-5):
        return f"|BC| {bc.min():.6f} .. {bc.max():.6f} for {values['needle_bar.length']}"
    return None


_DECODER = json.JSONDecoder()


def essentials(raw: bytes) -> dict:
    """What :func:`crosstalk` reads of an answer, read without parsing its 160 kB (the pages
    share the server's cores: they should cost it little): the feed's regulator setting and
    the points B and C (the answer's own key order: "feed" after "points")."""
    text = raw.decode()
    pts = text.index('"points":{')
    out = {"points": {}}
    for name in ("B", "C"):
        k = text.index(f'"{name}":', pts)
        out["points"][name] = _DECODER.raw_decode(text, k + len(name) + 3)[0]
    k = text.index('"regulator_deg":', text.index('"feed":{'))
    out["feed"] = {"regulator_deg": _DECODER.raw_decode(text, k + 16)[0]}
    return out


class Connection:
    """A page's keep-alive HTTP connection, opened again when the server has closed it (as a
    browser does: uvicorn closes a connection idle for 5 s)."""

    def __init__(self, host: str, port: int):
        self.host, self.port, self.rw = host, port, None

    async def post(self, path: str, body: dict):
        """(status, headers, body bytes) of one POST (a turn is safe to send again)."""
        data = json.dumps(body).encode()
        req = (f"POST {path} HTTP/1.1\r\nHost: {self.host}\r\nContent-Type: application/json"
               f"\r\nContent-Length: {len(data)}\r\n\r\n").encode() + data
        for attempt in (0, 1):
            if self.rw is None:
                self.rw = await asyncio.open_connection(self.host, self.port)
            reader, writer = self.rw
            try:
                writer.write(req)
                await writer.drain()
                head = await reader.readuntil(b"\r\n\r\n")
                break
            except (asyncio.IncompleteReadError, ConnectionError):
                writer.close()
                self.rw = None
                if attempt:
                    raise
        lines = head.decode("latin-1").split("\r\n")
        status = int(lines[0].split()[1])
        headers = {k.strip().lower(): v.strip() for k, _, v in (ln.partition(":")
                                                                for ln in lines[1:] if ln)}
        raw = await reader.readexactly(int(headers["content-length"]))
        if headers.get("connection", "").lower() == "close":
            writer.close()
            self.rw = None
        return status, headers, raw

    def close(self):
        if self.rw is not None:
            self.rw[1].close()
            self.rw = None


def _cpu_s(pid: int) -> dict:
    """CPU seconds (user + system) so far of the server's process, of its children (the
    workers) and of this benchmark's process (the pages)."""
    out = {"bench": sum(os.times()[:2])}
    try:
        import psutil
    except ImportError:
        return out
    try:
        p = psutil.Process(pid)
        t = p.cpu_times()
        out["server"] = t.user + t.system
        out["workers"] = sum(sum(c.cpu_times()[:2]) for c in p.children(recursive=True))
    except psutil.Error:
        pass
    return out


def _rss_mb(pid: int) -> float | None:
    """The resident memory of a process and all its children (the server's workers), MB."""
    try:
        import psutil
    except ImportError:
        return None
    try:
        p = psutil.Process(pid)
        procs = [p] + p.children(recursive=True)
        return sum(q.memory_info().rss for q in procs if q.is_running()) / 1e6
    except psutil.Error:
        return None


async def _many_pages(url: str, pid: int, pages: int, seconds: float) -> dict:
    host, port = url.split("//")[1].split(":")
    lat, server, errors, mismatch, count = [], [], [], [], [0] * pages
    samples: dict[int, list] = {i: [] for i in range(pages)}
    conns = [Connection(host, int(port)) for _ in range(pages)]
    tokens = []
    for c in conns:  # one page after the other, as people arrive (each builds its machine)
        status, _, raw = await c.post("/api/sessions", {"machine": "jb1-3"})
        assert status == 200, raw[:300]
        tokens.append(json.loads(raw)["session"])

    async def page(i: int, until: float | None, record: bool):
        k = 0
        while until is None and k < 2 or until is not None and time.perf_counter() < until:
            values = page_values(i, k)
            t0 = time.perf_counter()
            status, headers, raw = await conns[i].post(f"/api/sessions/{tokens[i]}/turn",
                                                       {"set": values})
            dt = time.perf_counter() - t0
            k += 1
            if status != 200:
                errors.append((i, status, raw[:200]))
                continue
            sampled = record and len(samples[i]) < 3
            turn = json.loads(raw) if sampled else essentials(raw)
            why = crosstalk(turn, values)
            if why:
                mismatch.append((i, why))
            if record:
                lat.append(dt)
                st = headers.get("server-timing", "")
                if "dur=" in st:
                    server.append(float(st.split("dur=")[1]) / 1e3)
                if sampled:
                    samples[i].append((values, fingerprint(turn)))
        if record:
            count[i] += k

    await asyncio.gather(*(page(i, None, False) for i in range(pages)))  # warm: 2 turns each
    rss = [(0.0, _rss_mb(pid))]
    cpu0 = _cpu_s(pid)
    t_start = time.perf_counter()
    until = t_start + seconds

    async def watch():
        while time.perf_counter() < until:
            await asyncio.sleep(min(10.0, max(0.0, until - time.perf_counter())))
            rss.append((time.perf_counter() - t_start, _rss_mb(pid)))

    await asyncio.gather(watch(), *(page(i, until, True) for i in range(pages)))
    elapsed = time.perf_counter() - t_start
    cpu1 = _cpu_s(pid)
    cpu = {k: cpu1[k] - cpu0[k] for k in cpu1 if k in cpu0}
    for c in conns:
        c.close()
    return {"lat": lat, "server": server, "errors": errors, "mismatch": mismatch,
            "elapsed": elapsed, "count": count, "rss": rss, "samples": samples, "cpu": cpu}


def many_pages(url: str, pid: int, pages: int, seconds: float) -> dict:
    """``pages`` pages dragging their sliders at once for ``seconds`` s (module docstring)."""
    load = os.getloadavg()
    res = asyncio.run(_many_pages(url, pid, pages, seconds))
    # the sample of answers against the library's own numbers for the same designs
    file, text = shipped_texts()["jb1-3"]
    s = Session.from_text(text, file)
    sample_bad = [(i, v) for i, got in res["samples"].items() for v, fp in got
                  if not np.allclose(np.asarray(fingerprint(s.turn(v)), float),
                                     np.asarray(fp, float), rtol=1e-9, atol=1e-9)]
    n = len(res["lat"])
    lat = np.asarray(res["lat"]) * 1e3
    rss = res["rss"]
    out = {"pages": pages, "seconds": round(res["elapsed"], 1), "answers": n,
           "answers_per_s": n / res["elapsed"],
           "p50_ms": float(np.percentile(lat, 50)) if n else None,
           "p95_ms": float(np.percentile(lat, 95)) if n else None,
           "max_ms": float(lat.max()) if n else None,
           "server_time_p50_ms": float(np.median(res["server"]) * 1e3) if res["server"] else None,
           "answers_per_page_min_max": [min(res["count"]), max(res["count"])],
           "errors": len(res["errors"]), "crosstalk": len(res["mismatch"]),
           "sample_checked": sum(len(v) for v in res["samples"].values()),
           "sample_mismatch": len(sample_bad),
           "rss_mb": [[round(t, 1), None if m is None else round(m, 1)] for t, m in rss],
           "cpu_s_per_answer": {k: v / max(n, 1) for k, v in res["cpu"].items()},
           "cpu_share_of_the_cores": sum(res["cpu"].values()) / res["elapsed"]
           / (os.cpu_count() or 1),
           "load_average_before": [round(x, 2) for x in load],
           "load_average_after": [round(x, 2) for x in os.getloadavg()],
           "cpus": os.cpu_count()}
    if res["errors"]:
        print("errors:", res["errors"][:5])
    if res["mismatch"] or sample_bad:
        print("CROSS-TALK:", res["mismatch"][:5], sample_bad[:5])
    return out


def print_pages(r: dict) -> str:
    print(f"{r['pages']} pages for {r['seconds']} s on 127.0.0.1 ({r['cpus']} CPUs; load average"
          f" {r['load_average_before'][0]:.2f} before, {r['load_average_after'][0]:.2f} after)")
    print(f"  turn latency: p50 {r['p50_ms']:.1f} ms, p95 {r['p95_ms']:.1f} ms, max"
          f" {r['max_ms']:.1f} ms; {r['answers']} answers, {r['answers_per_s']:.1f} answers/s"
          f" (per page {r['answers_per_page_min_max'][0]} .. {r['answers_per_page_min_max'][1]});"
          f" the server's own time per turn p50 {r['server_time_p50_ms'] or float('nan'):.1f} ms")
    print(f"  cross-talk: {r['crosstalk']} of {r['answers']} answers not for their page's design;"
          f" {r['sample_mismatch']} of {r['sample_checked']} sampled answers differ from the"
          f" library's; {r['errors']} errors")
    c = r["cpu_s_per_answer"]
    print("  CPU per answer: " + ", ".join(f"{k} {v * 1e3:.1f} ms" for k, v in c.items())
          + f"; this run had {r['cpu_share_of_the_cores']:.0%} of the machine's cores")
    mem = ", ".join(f"{t:g} s {m:.0f} MB" for t, m in r["rss_mb"] if m is not None)
    print(f"  the server's memory (RSS, with its workers): {mem}")
    ok = (r["p95_ms"] is not None and r["p95_ms"] <= TARGET_PAGES_P95_MS and not r["crosstalk"]
          and not r["sample_mismatch"] and not r["errors"])
    verdict = "met" if ok else "MISSED"
    print(f"target: {r['pages']} pages, p95 at most {TARGET_PAGES_P95_MS:g} ms, no cross-talk:"
          f" {verdict}")
    return verdict


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--screenshot", metavar="PATH")
    ap.add_argument("--pages", type=int, default=20)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--only-pages", action="store_true")
    ap.add_argument("--label", help="what the many pages' run measured (kept as its 'code')")
    ap.add_argument("--out", type=Path, default=RESULTS, help="the results file (default:"
                    " benchmarks/results/serve.json)")
    args = ap.parse_args()
    shot = args.screenshot
    rows = {} if args.only_pages else server_side()
    # the server in a process of its own, as `sewmech serve` runs it
    cmd = [sys.executable, "-c", "from sewmech.app.cli import main; main()", "serve", "jb1-3",
           "--port", "0"]
    if args.workers is not None:
        cmd += ["--workers", str(args.workers)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    pages = None
    try:
        line = proc.stdout.readline()
        url = "http://" + line.split("http://")[1].split("/")[0]
        if not args.only_pages:
            rows.update(over_http(url))
            rows.update(in_browser(url, shot))
        if args.pages > 0:
            pages = many_pages(url, proc.pid, args.pages, args.seconds)
            pages["workers"] = args.workers
            if args.label:
                pages["code"] = args.label
    finally:
        proc.terminate()
        proc.wait(20)
    results = args.out
    results.parent.mkdir(exist_ok=True)
    if args.only_pages:
        old = json.loads(results.read_text()) if results.exists() else {}
        if pages is not None:
            pages["verdict"] = print_pages(pages)
            old["many_pages"] = pages
            # its row of the table of current figures, with this run's date and commit (the
            # file's own are those of the other rows' run)
            stamp = run_stamp()
            row = {**pages_figure(pages), "date": stamp["date"], "commit": stamp["commit"]}
            figures = old.setdefault("figures", [])
            at = [k for k, f in enumerate(figures) if f.get("job", "").startswith(PAGES_JOB)
                  and "pages dragging" in f.get("job", "")]
            if at:
                figures[at[0]] = row
            else:
                figures.append(row)
        results.write_text(json.dumps(old, indent=1) + "\n")
        return
    print(f"{'what':48s} {'p50 ms':>8s} {'p95 ms':>8s} {'max ms':>8s}")
    for k, r in rows.items():
        print(f"{k:48s} {r['p50_ms']:8.1f} {r['p95_ms']:8.1f} {r['max_ms']:8.1f}")
    worst = max(r["p95_ms"] for k, r in rows.items() if k.startswith("turn") and "own time" in k)
    verdict = "met" if worst <= TARGET_P95_MS else "MISSED"
    print(f"target: a JB1-3 turn with dynamics at most {TARGET_P95_MS:g} ms p95 in the server:"
          f" {worst:.1f} ms, {verdict}")
    out = {"rows": rows, "target_p95_ms": TARGET_P95_MS, "verdict": verdict}
    if pages is not None:
        pages["verdict"] = print_pages(pages)
        out["many_pages"] = pages
    write_results(results, out, current_figures(out))


if __name__ == "__main__":
    main()
