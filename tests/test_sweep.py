"""Design sweeps (sewmech.design.sweep, sewmech.app.sweep_run, `sewmech sweep`): the samples,
every output against an independent evaluation of single designs, Dask against in-process
(a LocalCluster, and a scheduler and two workers started as separate processes), resuming,
retries and failed chunks, bad sweep files and output directories that are not a sweep's."""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from sewmech.cli import app
from typer.testing import CliRunner

import sewmech
from sewmech.app import sweep_run
from sewmech.app.sweep_run import SweepError, run_sweep
from sewmech.design.sweep import chunk_bounds, evaluate_chunk, sample
from sewmech.design.sweep_file import Sweep, load_sweep
from sewmech.engine.errors import MachineFileError, OptionError, OutputError

ROOT = Path(__file__).resolve().parent.parent
SMALL = ROOT / "examples" / "sweeps" / "jb-feed-small.toml"
BIG = ROOT / "examples" / "sweeps" / "jb-feed.toml"
runner = CliRunner()


@pytest.fixture(scope="module")
def small() -> Sweep:
    return load_sweep(SMALL)


@pytest.fixture(scope="module")
def reference(small, tmp_path_factory):
    """The small sweep run in this process, chunks of 5 designs: (directory, table)."""
    out = tmp_path_factory.mktemp("sweep") / "ref"
    r = run_sweep(small, out, workers=0, chunk=5)
    assert r.computed == [0, 1, 2, 3] and not r.failed
    return out, table(out)


def table(out: Path):
    return pq.read_table(out / "chunks").sort_by("design")


def curves(out: Path) -> dict:
    import zarr

    g = zarr.open_group(str(out / "curves.zarr"), mode="r")
    return {k: g[k][:] for k in ("p_feed_dog.tip_x", "p_feed_dog.tip_y")}


def write(tmp_path, text, name="s.toml"):
    f = tmp_path / name
    f.write_text(text, encoding="utf-8")
    return f


# ---- sampling -----------------------------------------------------------------------------------

def sweep_text(method: str, extra: str = "", points: bool = False) -> str:
    pts = "points = 3\n" if points else ""
    count = "" if method == "grid" else "designs = 1000\n"
    return (f'[sweep]\nname = "t"\nmachine = "fourbar-benchmark"\n[sampling]\nmethod ='
            f' "{method}"\n{count}seed = 7\n{extra}'
            f'[[parameters]]\nparameter = "B.u"\nlower = 10.0\nupper = 12.0\n{pts}'
            f'[[parameters]]\nparameter = "dyad.length1"\nlower = 38.0\nupper = 42.0\n'
            f'{pts.replace("3", "4")}'
            '[[outputs]]\nmetric = "range:theta_rocker"\n')


def test_a_grid_is_the_product_of_the_parameters_values(tmp_path):
    s = load_sweep(write(tmp_path, sweep_text("grid", points=True)))
    assert s.n_designs == 12
    X = sample(s, 0, 12)
    expect = [(a, b) for a in np.linspace(10, 12, 3) for b in np.linspace(38, 42, 4)]
    np.testing.assert_array_equal(X, np.array(expect))
    np.testing.assert_array_equal(sample(s, 5, 9), X[5:9])


@pytest.mark.parametrize("method", ["sobol", "lhs", "random"])
def test_samples_are_in_bounds_reproducible_and_the_same_whatever_the_chunks(tmp_path,
                                                                              method):
    s = load_sweep(write(tmp_path, sweep_text(method)))
    X = sample(s, 0, 1000)
    assert X.shape == (1000, 2)
    assert (X[:, 0] >= 10).all() and (X[:, 0] <= 12).all()
    assert (X[:, 1] >= 38).all() and (X[:, 1] <= 42).all()
    np.testing.assert_array_equal(X, sample(load_sweep(s.file), 0, 1000))
    parts = np.concatenate([sample(s, a, b) for a, b in chunk_bounds(1000, 137)])
    np.testing.assert_array_equal(parts, X)
    if method == "lhs":  # one design in each of the 1000 strata of every parameter
        for j, (lo, hi) in enumerate(((10, 12), (38, 42))):
            strata = np.floor((X[:, j] - lo) / (hi - lo) * 1000).astype(int)
            assert sorted(strata) == list(range(1000))
    other = load_sweep(write(tmp_path, sweep_text(method).replace("seed = 7", "seed = 8"),
                             "o.toml"))
    assert not np.array_equal(sample(other, 0, 1000), X)


# ---- the numbers --------------------------------------------------------------------------------

def test_every_output_equals_an_independent_evaluation_of_single_designs(small, reference):
    """Each design rebuilt as its own machine (with_parameters, the file's units turned to
    internal ones independently), its metrics located by Newton's method on the exact
    kinematics (the gradient functions, not the batch's grid and interpolants), its assembly
    checked at both ends of the regulator, its forces by inverse_dynamics."""
    from sewmech.engine.dynamics import inverse_dynamics
    from sewmech.engine.extremes import extremes
    from sewmech.sewing.gradients import METRICS

    _, t = reference
    m0 = small.machine
    rows = t.to_pylist()
    assert sum(r["feasible"] for r in rows) >= 1 and sum(not r["feasible"] for r in rows) >= 1
    for r in rows[::3] + [r for r in rows if r["feasible"]][:2]:
        values = {"lift_cam.arc0.cx": r["lift_cam.arc0.cx"],
                  "lift_cam.arc0.radius": r["lift_cam.arc0.radius"],
                  "regulator.phase": math.radians(r["regulator.phase_deg"])}
        m = m0.with_parameters(values)
        ok = True
        for reg in (-30.0, 30.0):
            k = sewmech.kinematics(m, np.radians(np.arange(360.0)),
                                   inputs={"regulator": math.radians(reg)}, on_failure="mask")
            ok &= bool(k.feasible.all())
        assert r["assembles"] == ok
        for col, name, reg in (("stitch_length@30deg", "stitch_length", 30.0),
                               ("feed_lift@0deg", "feed_lift", 0.0),
                               ("dog_height_at_needle_plate@30deg",
                                "dog_height_at_needle_plate", 30.0)):
            try:
                exact = METRICS[name](m, reg).value
            except sewmech.SewmechError:  # (no stitch: the dog never rises through the plate)
                exact = math.nan
            if math.isnan(exact):
                assert r[col] is None or math.isnan(r[col]), (col, r)
            else:
                assert r[col] == pytest.approx(exact, abs=1e-6), (col, r)
        ex = extremes(m, "p_feed_dog.tip_y", inputs={"regulator": 0.0})
        assert r["range:p_feed_dog.tip_y@0deg"] == pytest.approx(
            ex.maximum.value - ex.minimum.value, abs=1e-8)
        d = inverse_dynamics(m, np.radians(np.arange(0.0, 360.0, 5.0)))
        # N m, as every table of sewmech gives a torque (the dynamics answers N mm)
        assert r["peak_torque"] == pytest.approx(np.abs(d.input_torque).max() * 1e-3, rel=1e-12)
        assert r["peak_shaking_force"] == pytest.approx(
            np.linalg.norm(d.shaking_force, axis=-1).max(), rel=1e-12)
        lim = r["stitch_length@30deg"]
        within = (lim is not None and 3.6 <= lim <= 4.2 and 1.2 <= r["feed_lift@0deg"] <= 1.5
                  and r["dog_height_at_needle_plate@30deg"] <= -0.3)
        assert r["feasible"] == (ok and within)


def test_curves_equal_the_kinematics_of_each_design(small, reference):
    out, t = reference
    c = curves(out)
    phi = np.radians(np.arange(0.0, 360.0, 10.0))
    for r in t.to_pylist()[::5]:
        m = small.machine.with_parameters({
            "lift_cam.arc0.cx": r["lift_cam.arc0.cx"],
            "lift_cam.arc0.radius": r["lift_cam.arc0.radius"],
            "regulator.phase": math.radians(r["regulator.phase_deg"])})
        k = sewmech.kinematics(m, phi, inputs={"regulator": math.radians(30.0)})
        i = r["design"]
        np.testing.assert_allclose(c["p_feed_dog.tip_x"][i], k.channel("p_feed_dog.tip_x")[0],
                                   rtol=0, atol=1e-9)
        np.testing.assert_allclose(c["p_feed_dog.tip_y"][i], k.channel("p_feed_dog.tip_y")[0],
                                   rtol=0, atol=1e-9)


# ---- Dask ---------------------------------------------------------------------------------------

def _worker_threads():
    from sewmech.engine._threads import n_threads

    return os.environ.get("NUMBA_NUM_THREADS"), os.environ.get("OMP_NUM_THREADS"), n_threads()


def test_a_local_cluster_gives_exactly_the_in_process_result(small, reference, tmp_path):
    from distributed import Client

    ref, t = reference
    with sweep_run.local_cluster(2) as cluster, Client(cluster) as client:
        r = run_sweep(small, tmp_path / "dask", chunk=5, client=client)
        # one thread per worker process: numba's, OpenMP's, sewmech's kernel threads
        assert set(client.run(_worker_threads).values()) == {("1", "1", 1)}
    assert sorted(r.computed) == [0, 1, 2, 3] and not r.failed
    assert table(tmp_path / "dask").equals(t)
    for k, v in curves(tmp_path / "dask").items():
        np.testing.assert_array_equal(v, curves(ref)[k])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def _cluster(tmp_path, nanny: bool = True):
    """A scheduler and two one-thread workers, each its own process (as on a user's cluster),
    always stopped: (address, the processes, scheduler first). Without a nanny a worker's
    process is the worker itself (killing it kills the worker, nothing restarts it)."""
    dask = Path(sys.executable).parent / "dask"
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    procs = []
    log = open(tmp_path / "dask.log", "w")  # noqa: SIM115  (closed in finally)
    try:
        procs.append(subprocess.Popen([str(dask), "scheduler", "--host", "127.0.0.1", "--port",
                                       str(port), "--no-dashboard"], stdout=log, stderr=log,
                                      env=env))
        for _ in range(2):
            procs.append(subprocess.Popen([str(dask), "worker", address, "--nthreads", "1",
                                           "--nworkers", "1", "--no-dashboard"]
                                          + ([] if nanny else ["--no-nanny"]), stdout=log,
                                          stderr=log, env=env))
        from distributed import Client

        with Client(address, timeout="30s") as c:
            c.wait_for_workers(2, timeout=60)
        yield address, procs
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        log.close()


@pytest.fixture
def dask_cluster(tmp_path):
    with _cluster(tmp_path) as (address, _):
        yield address


def test_the_cli_runs_on_a_scheduler_and_workers_given_by_address(dask_cluster, reference,
                                                                   tmp_path):
    out = tmp_path / "remote"
    res = runner.invoke(app, ["sweep", str(SMALL), "--scheduler", dask_cluster, "--chunk", "5",
                              "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    assert '"chunks_computed": 4' in res.stdout
    assert '"chunks_written_by_workers": 4' in res.stdout  # the workers see this directory
    ev = json.loads(res.stdout)["evaluation"]  # the workers' counts reached the client
    assert ev["assembly_coarse"] + ev["assembly_whole_grid"] == 18
    assert ev["feed_located"] + ev["feed_whole_turn"] == 3 * 18  # three feed metrics
    assert ev["feed_checked"] == 2 * 3  # designs 0 and 16
    assert table(out).equals(reference[1])


def test_workers_write_their_chunks_and_one_killed_mid_chunk_changes_nothing(small, reference,
                                                                            tmp_path):
    """Issue 34, item 2: each worker writes the chunks it computes into the directory (here a
    file system it shares with the client); the client only records them. A worker killed
    outright while it holds chunks: the scheduler gives them to the other worker, every chunk
    is written exactly once, whole, the results are the in-process run's, and the killed
    writer's temporary files are gone."""
    import signal

    from distributed import Client

    out = tmp_path / "writers"
    with _cluster(tmp_path, nanny=False) as (address, procs), \
            Client(address, timeout="30s") as client:
        pids = client.run(os.getpid)  # worker address -> its process (no nanny: the Popen's)
        assert sorted(pids.values()) == sorted(p.pid for p in procs[1:])
        killed = {}

        def on_chunk(k, n):
            if killed:
                return
            busy = {w: t for w, t in client.processing().items() if t}
            if busy:
                w, tasks = next(iter(busy.items()))
                os.kill(pids[w], signal.SIGKILL)
                killed.update(worker=w, tasks=tasks)

        r = run_sweep(small, out, chunk=1, client=client, on_chunk=on_chunk)
    assert killed["tasks"], "no worker held a chunk when one was killed"
    n = small.n_designs  # chunks of one design
    assert sorted(r.computed) == list(range(n)) and not r.failed, r.failed
    assert r.written_by_workers == n  # the client wrote none
    assert sweep_run.done_chunks(out) == set(range(n))
    assert not [e for e in os.listdir(out / "chunks") if e.endswith(".tmp")]
    assert table(out).equals(reference[1])
    for k, v in curves(out).items():
        np.testing.assert_array_equal(v, curves(reference[0])[k])


def test_a_worker_that_does_not_see_the_directory_hands_its_chunk_to_the_client(small,
                                                                                 reference,
                                                                                 tmp_path):
    """A worker on a machine without the client's file system (the run's probe file is not
    there, or not this run's) returns its chunk for the client to write and writes nothing;
    one that sees it writes the chunk as the client would."""
    from sewmech.design.sweep import texts_of

    out = tmp_path / "probe"
    run_sweep(small, out, workers=0, chunk=5, stop_after=1)  # the directory, chunk 0
    texts = texts_of(small)
    c = sweep_run.evaluate_and_write(texts, str(out), "a" * 32, 1, 5, 10)
    assert c is not None and list(c.columns["design"]) == [5, 6, 7, 8, 9]
    assert sweep_run.done_chunks(out) == {0}
    sweep_run._probe_path(out, "b" * 32).write_text("b" * 32, encoding="ascii")
    assert not isinstance(sweep_run.evaluate_and_write(texts, str(out), "a" * 32, 1, 5, 10),
                          dict)
    counts = sweep_run.evaluate_and_write(texts, str(out), "b" * 32, 1, 5, 10)
    assert counts == c.counts  # written: only how its designs were evaluated comes back
    assert counts["assembly_coarse"] + counts["assembly_whole_grid"] == 5
    assert sweep_run.done_chunks(out) == {0, 1}
    sweep_run._probe_path(out, "b" * 32).unlink()
    run_sweep(small, out, workers=0)
    assert table(out).equals(reference[1])


def test_an_unreachable_scheduler_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setattr(sweep_run, "CONNECT_TIMEOUT", "2s")
    res = runner.invoke(app, ["sweep", str(SMALL), "--scheduler",
                              f"tcp://127.0.0.1:{_free_port()}", "--out", str(tmp_path / "o")])
    assert res.exit_code == 2
    assert "--scheduler" in res.output and "Traceback" not in res.output
    assert not (tmp_path / "o").exists()  # nothing written before the cluster answers


# ---- resuming, retries, failures ----------------------------------------------------------------

def test_an_interrupted_sweep_resumes_with_only_the_missing_chunks(small, reference, tmp_path):
    out = tmp_path / "r"
    r1 = run_sweep(small, out, workers=0, chunk=5, stop_after=2)
    assert r1.stopped and r1.computed == [0, 1]
    res = runner.invoke(app, ["sweep-summary", str(out)])
    assert res.exit_code == 0 and "partial: 2 of 4 chunks written" in res.output
    # a killed run's half-written chunk (a temporary file) is never taken for a chunk
    (out / "chunks" / ".chunk-000002.parquet.x1y2.tmp").write_bytes(b"PAR1 half")
    with pytest.raises(OptionError, match="--chunk 5"):
        run_sweep(small, out, workers=0, chunk=4)
    r2 = run_sweep(small, out, workers=0)
    assert r2.done_before == 2 and r2.computed == [2, 3]
    assert table(out).equals(reference[1])
    assert not [e for e in os.listdir(out / "chunks") if e.endswith(".tmp")]
    for k, v in curves(out).items():
        np.testing.assert_array_equal(v, curves(reference[0])[k])
    r3 = run_sweep(small, out, workers=0)
    assert r3.computed == [] and r3.done_before == 4


def test_a_failing_chunk_is_retried_then_reported_and_the_rest_written(small, reference,
                                                                       tmp_path, monkeypatch):
    calls = {}
    real = evaluate_chunk

    def flaky(sweep, start, stop):  # chunk 1 fails once, chunk 2 always
        k = start // 5
        calls[k] = calls.get(k, 0) + 1
        if k == 2 or (k == 1 and calls[k] == 1):
            raise RuntimeError(f"injected failure of chunk {k}")
        return real(sweep, start, stop)

    monkeypatch.setattr(sweep_run, "evaluate_chunk", flaky)
    out = tmp_path / "f"
    with pytest.raises(SweepError) as e:
        run_sweep(small, out, workers=0, chunk=5, retries=2)
    msg = str(e.value)
    assert "1 of 4 chunks failed after 3 attempts" in msg and "chunk 2 (designs 10 .. 14)" in msg
    assert "injected failure of chunk 2" in msg and "run the same command again" in msg
    assert calls == {0: 1, 1: 2, 2: 3, 3: 1}
    assert sweep_run.done_chunks(out) == {0, 1, 3}
    monkeypatch.setattr(sweep_run, "evaluate_chunk", real)
    r = run_sweep(small, out, workers=0)
    assert r.computed == [2]
    assert table(out).equals(reference[1])


def test_the_cli_reports_failed_chunks_and_how_to_resume(tmp_path, monkeypatch):
    def broken(sweep, start, stop):
        raise RuntimeError("no")

    monkeypatch.setattr(sweep_run, "evaluate_chunk", broken)
    res = runner.invoke(app, ["sweep", str(SMALL), "--workers", "0", "--retries", "0",
                              "--chunk", "5", "--out", str(tmp_path / "o")])
    assert res.exit_code == 2
    assert "4 of 4 chunks failed" in res.output and "run the same command again" in res.output
    assert "Traceback" not in res.output


# ---- files and directories ----------------------------------------------------------------------

def test_bad_sweep_files_get_located_errors(tmp_path):
    good = SMALL.read_text(encoding="utf-8").replace('machine = "jb1-3"', 'machine = "jb1-3"')
    cases = [
        (good.replace('"lift_cam.arc0.cx"', '"lift_cam.arc0.cxx"'),
         r"\[parameters\] 0.parameter.*lift_cam.arc0.cx"),
        (good.replace('metric = "feed_lift"', 'metric = "feed_lfit"'),
         r"\[outputs\] 1.metric.*feed_lift"),
        (good.replace("points = 2", "points = 1"), r"parameters.*points"),
        (good.replace('method = "grid"', 'method = "sobol"'), r"sampling.*designs"),
        (good.replace('channels = ["p_feed_dog.tip_x"', 'channels = ["p_feed_dog_x"'),
         r"\[curves\] channels.0"),
        (good.replace("[dynamics]", "[dynamic]"), r"dynamic"),
        (good.replace("lower = 7.8", "lower = 8.5"), r"lower < upper"),
    ]
    for k, (text, pattern) in enumerate(cases):
        f = write(tmp_path, text, f"bad{k}.toml")
        with pytest.raises(MachineFileError, match=pattern):
            load_sweep(f)
    res = runner.invoke(app, ["sweep", str(tmp_path / "bad0.toml"), "--out",
                              str(tmp_path / "o")])
    assert res.exit_code == 2 and "bad0.toml" in res.output and "Traceback" not in res.output
    assert not (tmp_path / "o").exists()


def test_a_directory_that_is_not_the_sweeps_is_refused(small, reference, tmp_path):
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="not a sweep's"):
        run_sweep(small, foreign, workers=0)
    assert os.listdir(foreign) == ["notes.txt"]
    # a sweep directory with a file of the user's in it
    out = tmp_path / "s"
    shutil.copytree(reference[0], out)
    (out / "chunks" / "extra.csv").write_text("x")
    with pytest.raises(OutputError, match="did not write.*chunks/extra.csv"):
        run_sweep(small, out, workers=0)
    (out / "chunks" / "extra.csv").unlink()
    (out / ".notes.tmp").write_text("mine too")  # (not a name a sweep writes: kept, refused)
    with pytest.raises(OutputError, match="did not write.*notes.tmp"):
        run_sweep(small, out, workers=0)
    assert (out / ".notes.tmp").read_text() == "mine too"
    (out / ".notes.tmp").unlink()
    # the same directory for a changed sweep file, or another machine file
    changed = write(tmp_path, SMALL.read_text(encoding="utf-8").replace("upper = 12.0",
                                                                        "upper = 13.0"))
    with pytest.raises(OutputError, match="another sweep file"):
        run_sweep(load_sweep(changed), out, workers=0)
    res = runner.invoke(app, ["sweep", str(changed), "--workers", "0", "--out", str(out)])
    assert res.exit_code == 2 and "another sweep file" in res.output
    machine = write(tmp_path, Path(small.machine_file).read_text(encoding="utf-8")
                    + "\n# changed\n", "jb1-3")  # found beside the sweep file first
    moved = write(tmp_path, SMALL.read_text(encoding="utf-8"))
    assert load_sweep(moved).machine_file == str(machine)
    with pytest.raises(OutputError, match="another machine file"):
        run_sweep(load_sweep(moved), out, workers=0)


def test_the_summary_shows_the_feasible_designs(reference, tmp_path):
    out, t = reference
    res = runner.invoke(app, ["sweep-summary", str(out), "--json", "--best", "3",
                              "--out", str(tmp_path / "sum")])
    assert res.exit_code == 0, res.output
    import json

    s = json.loads(res.stdout)
    feasible = [r for r in t.to_pylist() if r["feasible"]]
    assert s["feasible"] == len(feasible) and s["complete"] and s["designs_written"] == 18
    assert [b["design"] for b in s["best"]] == [r["design"] for r in sorted(
        feasible, key=lambda r: r["stitch_length@30deg"])][:3]
    for name in ("scatter-matrix.png", "histograms.png", "best.csv", "summary.json"):
        assert (tmp_path / "sum" / name).is_file()
    res = runner.invoke(app, ["sweep-summary", str(out), "--sort-by", "nope"])
    assert res.exit_code == 2 and "--sort-by" in res.output
    res = runner.invoke(app, ["sweep-summary", str(tmp_path)])
    assert res.exit_code == 2 and "not a sweep" in res.output


def test_the_shipped_sweep_file_loads():
    s = load_sweep(BIG)
    assert s.n_designs == 100_000 and s.spec.sampling.method == "sobol"
    X = sample(s, 0, 64)
    assert np.isfinite(evaluate_chunk(s, 0, 8).columns["assembles"]).all()
    assert X.shape == (64, len(s.names))


# ---- the summary as a newcomer reads it -----------------------------------------------------

def _row(out: str, first: str) -> list[str]:
    line = next(x for x in out.splitlines() if x.startswith(f"│ {first} "))
    return [c.strip() for c in line.split("│")[1:-1]]


def test_the_summary_prints_the_feasible_region_and_torques_in_N_m(reference):
    out, t = reference
    res = runner.invoke(app, ["sweep-summary", str(out)])
    assert res.exit_code == 0, res.output
    assert "feasible region" in res.output
    rows = t.to_pylist()
    feasible = [r for r in rows if r["feasible"]]
    for p, name in (("lift_cam.arc0.cx", "lift_cam.arc0.cx"),
                    ("regulator.phase", "regulator.phase_deg")):
        cells = _row(res.output, name)
        lo, hi = (min(r[name] for r in feasible), max(r[name] for r in feasible))
        bounds = next(q for q in load_sweep(SMALL).spec.parameters if q.parameter == p)
        assert cells[1] == ("deg" if name.endswith("_deg") else "mm")
        assert [float(c) for c in cells[2:]] == pytest.approx(
            [bounds.lower, bounds.upper, lo, hi], rel=1e-5)
    cells = _row(res.output, "peak_torque")  # N m, as every other table gives a torque
    assert cells[1] == "N m"
    m = sewmech.load_machine("jb1-3")
    from sewmech.dynamics import inverse_dynamics

    d = inverse_dynamics(m, np.radians(np.arange(0.0, 360.0, 5.0)))
    peak = np.abs(d.input_torque).max() * 1e-3  # the file's design is inside the sweep's range
    assert float(cells[3]) <= peak <= float(cells[4]) and 0.1 < peak < 2.0


def test_a_round_off_spread_is_one_colour_and_a_note_not_a_colour_bar(reference):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sewmech.app.cli.sweep import histograms, load_results, scatter_matrix

    out, _ = reference
    record, cols, _ = load_results(out)
    params = [p["column"] for p in record["parameters"]]
    summary = {"feasible": int(cols["feasible"].sum()), "designs_written": len(cols["design"])}
    shown = np.arange(len(cols["design"]))
    stitch = cols["stitch_length@30deg"][cols["feasible"]]
    assert np.ptp(stitch) < 1e-9 * stitch.max()  # the lift cam cannot change the stitch
    fig = scatter_matrix(record, summary, cols, params, "stitch_length@30deg", shown)
    try:
        assert len(fig.axes) == len(params) ** 2  # no colour bar
        title = " ".join(fig._suptitle.get_text().split())
        assert f"stitch_length@30deg = {np.median(stitch):.6g} mm in every feasible design" in title
        colours = {tuple(c) for ax in fig.axes for coll in ax.collections
                   for c in np.round(coll.get_facecolors(), 6) if len(coll.get_offsets())}
        assert len(colours) == 2  # feasible green, the others grey
    finally:
        plt.close(fig)
    # an output that does vary over the feasible designs keeps its colour bar
    fig = scatter_matrix(record, summary, cols, params, "feed_lift@0deg", shown)
    try:
        assert len(fig.axes) == len(params) ** 2 + 1
    finally:
        plt.close(fig)
    # a histogram of one value: one bar at it, an axis at the scale of the value
    flat = {**cols, "stitch_length@30deg": 3.7765 + 1.6e-11 * np.arange(len(cols["design"]))}
    fig = histograms(record, flat, ["stitch_length@30deg"])
    try:
        ax = fig.axes[0]
        lo, hi = ax.get_xlim()
        assert lo < 3.7765 < hi and hi - lo > 0.01
        assert "round-off" in ax.get_title()
    finally:
        plt.close(fig)
