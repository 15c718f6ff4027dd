"""The page's server computes in worker processes (issue 34, item 4): pages served at once, in
the same worker or in different ones, never see each other's designs; a session's requests
sent at once are all answered, each for its own values; a worker that dies is started again
and its pages are told to load their machine again; the workers end with the server; and
``--workers`` takes only a count of processes, with an error that says so. No wall-clock time
is asserted here (benchmarks/bench_serve.py measures it)."""

from __future__ import annotations

import logging
import math
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import psutil
import pytest
from sewmech.feed import feed_cycles

import sewmech
from serve_helpers import call, running_app

CLI = "from sewmech.app.cli import main; main()"
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


@pytest.fixture(scope="module")
def served():
    with running_app(workers=2) as (url, app):
        yield url, app


@pytest.fixture(scope="module")
def machine():
    return sewmech.load_machine("jb1-3")


def _design(page: int, k: int) -> dict:
    """Page ``page``'s ``k``-th design: a needle-bar link and a regulator setting of its own."""
    return {"input.regulator": -25.0 + 12.0 * page + 1.5 * k,
            "needle_bar.length": 42.0 + 0.5 * page + 0.01 * k}


def _mine(turn: dict, values: dict) -> bool:
    """Whether a turn is for ``values``: its regulator setting, and the needle-bar link's
    length |BC| at every angle of the turn."""
    pb, pc = turn["points"]["B"], turn["points"]["C"]
    bc = np.hypot(np.subtract(pb["x"], pc["x"]), np.subtract(pb["y"], pc["y"]))
    return (math.isclose(turn["feed"]["regulator_deg"], values["input.regulator"],
                         abs_tol=1e-6)
            and np.allclose(bc, values["needle_bar.length"], atol=1e-5))


def _open(url: str) -> str:
    status, body = call(f"{url}/api/sessions", {"machine": "jb1-3"})
    assert status == 200, body
    return body["session"]


def test_pages_served_at_once_never_see_each_others_designs(served, machine):
    url, app = served
    pages = 4
    tokens = [_open(url) for _ in range(pages)]
    where = [app.compute.where[t] for t in tokens]
    assert sorted(where) == [0, 0, 1, 1]  # two pages share each worker, two do not
    answers: dict[int, list] = {i: [] for i in range(pages)}
    start = threading.Barrier(pages)

    def page(i: int):
        start.wait()
        for k in range(6):
            values = _design(i, k)
            status, turn = call(f"{url}/api/sessions/{tokens[i]}/turn", {"set": values})
            answers[i].append((values, status, turn))
            if k == 2:  # the checks and an export, as the page asks for them, meanwhile
                status, checks = call(f"{url}/api/sessions/{tokens[i]}/checks", {"set": values})
                assert status == 200, checks
                status, text = call(f"{url}/api/sessions/{tokens[i]}/export.toml",
                                    {"set": values})
                assert status == 200 and f"length = {values['needle_bar.length']}" in text

    threads = [threading.Thread(target=page, args=(i,)) for i in range(pages)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(300)
    for i in range(pages):
        assert len(answers[i]) == 6
        for values, status, turn in answers[i]:
            assert status == 200, turn
            assert _mine(turn, values), (i, values, turn["feed"]["regulator_deg"])
        # and the last answer is the library's own for that design, to the last digit kept
        values, _, turn = answers[i][-1]
        P = machine.parameters({"needle_bar.length": values["needle_bar.length"]},
                               inputs={"regulator": math.radians(values["input.regulator"])})
        want = feed_cycles(machine, values["input.regulator"], params=P).stitch_mm
        assert turn["feed"]["stitch_mm"] == pytest.approx(float(want), abs=1e-6)


def test_a_sessions_requests_sent_at_once_are_each_answered_for_their_own_values(served):
    url, _ = served
    token = _open(url)
    out = {}

    def send(k: int):
        out[k] = (_design(0, k), *call(f"{url}/api/sessions/{token}/turn",
                                       {"set": _design(0, k)}))

    threads = [threading.Thread(target=send, args=(k,)) for k in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(300)
    assert sorted(out) == list(range(6))
    for values, status, turn in out.values():
        assert status == 200 and _mine(turn, values)


def test_a_worker_that_dies_is_started_again_and_its_pages_load_again(served):
    url, app = served
    token = _open(url)
    i = app.compute.where[token]
    victim = list(app.compute.pools[i]._processes)[0]
    os.kill(victim, signal.SIGKILL)
    deadline = time.monotonic() + 30
    while psutil.pid_exists(victim) and psutil.Process(victim).status() != "zombie":
        assert time.monotonic() < deadline
        time.sleep(0.05)
    status, body = call(f"{url}/api/sessions/{token}/turn", {"set": {}})
    assert status == 503 and body["error"]["hint"] == "Load the machine again", body
    status, body = call(f"{url}/api/sessions/{token}/turn", {"set": {}})
    assert status == 404 and body["error"]["hint"] == "Load the machine again", body
    again = _open(url)  # the server goes on, with a worker in the dead one's place
    status, turn = call(f"{url}/api/sessions/{again}/turn", {"set": _design(1, 0)})
    assert status == 200 and _mine(turn, _design(1, 0))
    assert victim not in app.compute.pids() and len(app.compute.pids()) == 2


def test_a_bug_in_a_worker_is_a_500_whose_traceback_goes_to_the_servers_log(monkeypatch,
                                                                             caplog):
    from sewmech.app.web.session import Session

    def broken(self, values):
        raise RuntimeError("a bug in the worker")

    monkeypatch.setattr(Session, "curves_csv", broken)  # the workers are forked with it
    with running_app(workers=1) as (url, _):
        token = _open(url)
        with caplog.at_level(logging.ERROR, logger="sewmech.serve"):
            status, body = call(f"{url}/api/sessions/{token}/curves.csv", {"set": {}})
        assert status == 500 and body["error"]["kind"] == "InternalError", body
        assert "RuntimeError" in body["error"]["what"] and "Traceback" not in str(body)
        logged = "\n".join(r.getMessage() for r in caplog.records)
        assert "internal error in curves_csv" in logged and "a bug in the worker" in logged
        status, turn = call(f"{url}/api/sessions/{token}/turn", {"set": _design(2, 0)})
        assert status == 200 and _mine(turn, _design(2, 0))  # the worker goes on


def _sessions_in_worker() -> int:
    from sewmech.app.web import compute

    return len(compute._SESSIONS)


def test_a_dropped_session_leaves_its_worker(monkeypatch):
    """The server keeps the last MAX_SESSIONS pages; an older page's session is dropped in its
    worker too (the memory stays flat however many pages come and go)."""
    import sewmech.app.web.server as server

    monkeypatch.setattr(server, "MAX_SESSIONS", 3)
    with running_app(workers=2) as (url, app):
        tokens = [_open(url) for _ in range(5)]
        status, body = call(f"{url}/api/sessions/{tokens[0]}/turn", {"set": {}})
        assert status == 404 and body["error"]["hint"] == "Load the machine again"
        assert call(f"{url}/api/sessions/{tokens[-1]}/turn", {"set": {}})[0] == 200
        assert sorted(app.compute.where) == sorted(tokens[2:]) and sum(app.compute.count) == 3
        held = [p.submit(_sessions_in_worker).result(60) for p in app.compute.pools]
        assert sorted(held) == sorted(app.compute.count) and sum(held) == 3


def _serve(*args):
    return subprocess.Popen([sys.executable, "-c", CLI, "serve", "jb1-3", "--port", "0",
                             *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGKILL])
def test_the_workers_end_with_the_server(stop):
    proc = _serve("--workers", "2")
    try:
        line = proc.stdout.readline()
        base = "http://" + line.split("http://")[1].split("/")[0]
        assert call(f"{base}/api/sessions", {"machine": "jb1-3"})[0] == 200
        workers = psutil.Process(proc.pid).children(recursive=True)
        assert len(workers) >= 2
        proc.send_signal(stop)
        proc.wait(60)
        gone, alive = psutil.wait_procs(workers, timeout=30)
        assert alive == []
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(20)
        proc.stdout.close()
        proc.stderr.close()


@pytest.mark.parametrize("value", ["-1", "65", "two", "1.5"])
def test_workers_takes_a_count_of_processes(value):
    r = subprocess.run([sys.executable, "-c", CLI, "serve", "jb1-3", "--port", "0",
                        "--workers", value], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert "--workers" in r.stderr and "Traceback" not in r.stderr
    if value in ("-1", "65"):
        assert "must be 0 .. 64" in r.stderr


@pytest.mark.parametrize("value", [-1, 65, 1.5, "2", True])
def test_create_app_refuses_a_workers_that_is_no_count(value):
    from sewmech.app.web.server import create_app

    with pytest.raises(ValueError, match="workers must be"):
        create_app(workers=value)
