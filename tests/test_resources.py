"""Resources, as a careless or unlucky user meets them (issue 29, class 5 and the rest of class
6): the largest sweep a file may ask for starts at once in bounded memory, files that are not
regular files are refused instead of read for ever, a full disk and an exhausted memory are
located errors that say what to change, paths with an unknown ``~user`` and contradictory
options are one ``error:`` line, and Ctrl-C during a sweep on the default local cluster stops
it at once, in one line, leaving no process behind."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sewmech.cli import app
from sewmech.design.sweep import chunk_bounds, sample
from sewmech.design.sweep_file import load_sweep
from sewmech.errors import MachineFileError

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "examples" / "sweeps" / "jb-feed-small.toml"
BIG = ROOT / "examples" / "sweeps" / "jb-feed.toml"
PROBLEM = ROOT / "examples" / "problems" / "fourbar-swing.toml"
runner = CliRunner()


def _cli() -> list[str]:
    exe = Path(sys.executable).with_name("sewmech")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "sewmech"]


def run(args, *, code=2, has=()):
    out = runner.invoke(app, [str(a) for a in args])
    text = out.stdout + out.stderr
    assert out.exit_code == code, (args, out.exit_code, text[-2000:])
    assert "Traceback" not in text and "internal error" not in text, text[-2000:]
    if code == 2:
        assert out.stderr.startswith("error: ") and out.stderr.count("\n") == 1, out.stderr
    for h in has:
        assert h in text, (h, text[-2000:])
    return out


def _sampled(text: str, method: str, designs: int) -> str:
    """The small sweep file as a ``method`` sample of ``designs`` designs."""
    text = text.replace('method = "grid"', f'method = "{method}"\ndesigns = {designs}')
    return "\n".join(line for line in text.splitlines() if not line.startswith("points ="))


# ---- the largest sweep -----------------------------------------------------------------------


def test_the_chunks_of_the_largest_sweep_are_never_listed():
    tracemalloc.start()
    try:
        b = chunk_bounds(10**10, 250)
        n, first, last = len(b), b[0], b[-1]
        mid = b[12_345_678]
        size = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert n == 4 * 10**7 and first == (0, 250) and last == (10**10 - 250, 10**10)
    assert mid == (12_345_678 * 250, 12_345_679 * 250)
    assert size < 100_000  # bytes: nothing of the 4e7 chunks is held
    assert chunk_bounds(10, 4)[-1] == (8, 10) and len(chunk_bounds(10, 4)) == 3
    assert chunk_bounds(10, 4).designs_in({0, 2, 7}) == 6
    assert list(chunk_bounds(10, 4)) == [(0, 4), (4, 8), (8, 10)]


#: a command as a terminal starts it, SIGINT at its default: a test run started in the
#: background (`&`, a CI runner without job control) hands its processes SIGINT ignored, and a
#: program that starts with SIGINT ignored rightly keeps ignoring it
TERMINAL = [sys.executable, "-c", ("import os, signal, sys; signal.signal(signal.SIGINT,"
                                   " signal.SIG_DFL); os.execv(sys.argv[1], sys.argv[1:])")]


@pytest.mark.slow
def test_a_sweep_of_1e10_designs_starts_at_once_in_bounded_memory(tmp_path):
    f = tmp_path / "big.toml"
    f.write_text(_sampled(SMALL.read_text(), "random", 10**10))
    d = tmp_path / "out"
    p = subprocess.Popen(TERMINAL + _cli() + ["sweep", str(f), "--workers", "0", "--out",
                                              str(d)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
    deadline = time.time() + 120
    while time.time() < deadline and not list((d / "chunks").glob("chunk-*.parquet")):
        time.sleep(0.1)
    p.send_signal(signal.SIGINT)
    deadline = time.time() + 60
    while True:  # (never a suite that waits forever on a command that did not stop)
        pid, status, usage = os.wait4(p.pid, os.WNOHANG)
        if pid:
            break
        if time.time() > deadline:
            p.kill()
            p.wait()
            pytest.fail("the sweep did not stop within 60 s of its Ctrl-C")
        time.sleep(0.1)
    err = p.stderr.read().decode()
    assert os.waitstatus_to_exitcode(status) == 130, err
    assert list((d / "chunks").glob("chunk-*.parquet")), "no chunk in 120 s"
    assert "Traceback" not in err and "chunks are written" in err
    assert usage.ru_maxrss * 1024 < 1.5 * 2**30, usage.ru_maxrss  # (Linux: kB); was 8 GB
    record = json.loads((d / "sweep.json").read_text())
    assert record["n_designs"] == 10**10 and record["n_chunks"] == 4 * 10**7


def test_a_latin_hypercube_beyond_memory_is_a_located_error(tmp_path):
    f = tmp_path / "lhs.toml"
    f.write_text(_sampled(SMALL.read_text(), "lhs", 10**10))
    with pytest.raises(MachineFileError) as info:
        load_sweep(f)
    e = info.value
    assert (e.table, e.key) == ("sampling", "designs"), e
    assert "GiB" in str(e) and "sobol" in str(e)
    run(["sweep", f, "--out", tmp_path / "o"], has=("[sampling] designs", "Latin hypercube"))
    assert not (tmp_path / "o").exists()


def test_a_sobol_sample_up_to_2_to_the_30_designs(tmp_path):
    f = tmp_path / "sobol.toml"
    f.write_text(_sampled(SMALL.read_text(), "sobol", 2**30))
    s = load_sweep(f)
    X = sample(s, 2**30 - 4, 2**30)  # the last designs, fast-forwarded to
    lo = np.array([p.lower for p in s.spec.parameters])
    hi = np.array([p.upper for p in s.spec.parameters])
    assert X.shape == (4, 3) and np.isfinite(X).all()
    assert ((X >= lo) & (X <= hi)).all() and len({tuple(x) for x in X}) == 4
    f.write_text(_sampled(SMALL.read_text(), "sobol", 2**30 + 1))
    run(["sweep", f, "--out", tmp_path / "o"], has=("[sampling] designs", "2**30", "random"))
    assert not (tmp_path / "o").exists()


# ---- files that are not files ----------------------------------------------------------------


@pytest.mark.parametrize("args", [
    ["check", "{fifo}"], ["dynamics", "jb1-3", "--loads", "{fifo}"], ["optimize", "{fifo}"],
    ["sweep", "{fifo}", "--out", "o"],
    ["tolerance", "jb1-3", "--output", "stitch_length", "--tolerances", "{fifo}"],
    ["trial-balance", "{fifo}"], ["influence-balance", "{fifo}"]],
    ids=["machine", "loads", "problem", "sweep", "tolerances", "trial-csv", "influence-csv"])
def test_a_named_pipe_is_refused_not_read_for_ever(tmp_path, args):
    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)
    t = time.perf_counter()
    old = os.getcwd()
    os.chdir(tmp_path)
    try:
        run([a.format(fifo=fifo) for a in args], has=(str(fifo), "named pipe"))
    finally:
        os.chdir(old)
    assert time.perf_counter() - t < 60
    assert sorted(os.listdir(tmp_path)) == ["pipe.toml"]


def test_a_device_is_refused():
    run(["check", "/dev/zero"], has=("/dev/zero", "is a device"))
    run(["trial-balance", "/dev/zero"], has=("/dev/zero", "is a device"))


# ---- paths and options -----------------------------------------------------------------------


@pytest.mark.parametrize("args, where", [
    (["check", "~nosuchuser-sewmech/m.toml"], "~nosuchuser-sewmech/m.toml:"),
    (["kinematics", "jb1-3", "--out", "~nosuchuser-sewmech/o"], "--out:"),
    (["trial-balance", "~nosuchuser-sewmech/v.csv"], "~nosuchuser-sewmech/v.csv:"),
    (["sweep", "~nosuchuser-sewmech/s.toml", "--out", "o"], "~nosuchuser-sewmech/s.toml:"),
    (["sweep", str(SMALL), "--out", "~nosuchuser-sewmech/o"], "--out:"),
    (["sweep-summary", "~nosuchuser-sewmech/d"], "DIR:"),
    (["optimize", "~nosuchuser-sewmech/p.toml"], "~nosuchuser-sewmech/p.toml:"),
    (["serve", "~nosuchuser-sewmech/m.toml"], "MACHINE:"),
], ids=["machine", "out", "csv", "sweep", "sweep-out", "summary", "problem", "serve"])
def test_an_unknown_users_home_is_a_located_error(tmp_path, args, where):
    old = os.getcwd()
    os.chdir(tmp_path)
    try:
        out = run(args, has=("no such user",))
    finally:
        os.chdir(old)
    assert out.stderr.startswith(f"error: {where}"), out.stderr
    assert os.listdir(tmp_path) == []


def test_loads_and_no_loads_together_are_refused(tmp_path):
    run(["dynamics", "jb1-3", "--loads", tmp_path / "l.toml", "--no-loads"],
        has=("--no-loads", "contradict"))


def test_out_of_memory_in_a_sweep_names_its_chunk(tmp_path, monkeypatch):
    from sewmech.app import sweep_run

    def no_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(sweep_run, "evaluate_chunk", no_memory)
    run(["sweep", SMALL, "--workers", "0", "--out", tmp_path / "o"],
        has=("sewmech sweep: out of memory", "--chunk"))
    assert not (tmp_path / "o").exists()  # it made the directory and wrote no chunk


# ---- a full disk -----------------------------------------------------------------------------


def _limited(limit_bytes: int):
    def pre():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails (EFBIG)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
    return pre


@pytest.mark.slow
@pytest.mark.parametrize("args", [["report", "jb1-3", "--step-deg", "10"],
                                  ["sweep", str(SMALL), "--workers", "0", "--chunk", "2"]],
                         ids=["report", "sweep"])
def test_a_write_beyond_the_space_left_is_a_located_error(tmp_path, args):
    """Writing beyond what the file system allows (here RLIMIT_FSIZE, the same error path as a
    full disk): a located error, nothing half-written; a sweep keeps its finished chunks."""
    d = tmp_path / "out"
    out = subprocess.run(_cli() + args + ["--out", str(d)], capture_output=True, text=True,
                         cwd=tmp_path, preexec_fn=_limited(40_000), timeout=300)
    assert out.returncode == 2, out.stderr
    assert "Traceback" not in out.stderr
    assert f"error: --out {d}: the disk is full" in out.stderr, out.stderr
    if args[0] == "report":
        assert not d.exists()
    else:  # whatever is there is whole: every chunk file reads
        import pandas as pd

        for p in (d / "chunks").glob("*.parquet") if d.exists() else ():
            pd.read_parquet(p)


@pytest.fixture
def tiny_disk(tmp_path):
    """A file system of 512 kB (tmpfs; needs the right to mount, else the test is skipped)."""
    mnt = tmp_path / "tiny"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=512k", "tmpfs", str(mnt)],
                       capture_output=True)
    if r.returncode != 0:
        pytest.skip("cannot mount a small file system here")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


@pytest.mark.slow
def test_a_full_disk_is_a_located_error(tiny_disk):
    d = tiny_disk / "r"
    out = subprocess.run(_cli() + ["report", "jb1-3", "--step-deg", "10", "--out", str(d)],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 2 and "Traceback" not in out.stderr, out.stderr
    assert f"error: --out {d}: the disk is full" in out.stderr
    assert os.listdir(tiny_disk) == []  # nothing half-written, not even the directory


# ---- Ctrl-C during a sweep on the default local cluster --------------------------------------


@pytest.mark.slow
def test_ctrl_c_stops_a_sweep_on_a_local_cluster_at_once_and_quietly(tmp_path):
    """Ctrl-C as a terminal sends it (to the whole foreground group: the command and its
    cluster's processes) at seeded moments from the imports to the chunks: the command stops
    within seconds with exit code 130 and one line, and no process of the group is left."""
    for k, t in enumerate(np.sort(np.random.default_rng(29).uniform(0.2, 5.0, 6))):
        d = tmp_path / f"o{k}"
        p = subprocess.Popen(TERMINAL + _cli() + ["sweep", str(BIG), "--out", str(d)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             start_new_session=True)
        time.sleep(t)
        os.killpg(p.pid, signal.SIGINT)
        t0 = time.time()
        _, err = p.communicate(timeout=60)
        stopped = time.time() - t0
        err = err.decode()
        lines = [x for x in err.splitlines() if x.strip()]
        assert p.returncode == 130, (t, p.returncode, err[-2000:])
        assert "Traceback" not in err and len(lines) <= 2, (t, err[-2000:])
        assert lines[-1].startswith("error: interrupted (Ctrl-C)"), (t, err)
        assert stopped < 15, (t, stopped)
        deadline = time.time() + 10
        while time.time() < deadline:
            try:
                os.killpg(p.pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.1)
        else:
            os.killpg(p.pid, signal.SIGKILL)
            raise AssertionError(f"a process of the sweep outlived it (Ctrl-C after {t:.2f} s)")
