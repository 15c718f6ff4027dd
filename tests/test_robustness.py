"""Bad, hostile and edge-case input, as a new user meets it: every case ends with a clear exit
code and a message that names the location, never a traceback, never a silent NaN, never a
design reported feasible that is not, and never a file of the user's touched.

The cases are grouped in the six classes of the robustness issue:
1 non-finite numbers, 2 output paths and user data, 3 ordinary mistakes that used to give
tracebacks, 4 impossible physics, 5 declared ranges, 6 newcomer frictions; and 7 (issue 29)
every number of the design files, measurements and options in a physically meaningful range,
and no NaN or infinity in any output.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import BENCH, FOURBAR, FOURBAR_LOOP, SLIDER_CRANK
from typer.testing import CliRunner

import sewmech
from sewmech.cli import app
from sewmech.assembly import prove_assembly
from sewmech.extremes import check_reference
from sewmech.errors import (
    AssemblyError,
    MachineFileError,
    OptionError,
    OutputError,
    ParameterError,
    SewmechError,
)

runner = CliRunner()
JB_FILE = Path(sewmech.shipped_machines()["jb1-3"])
JB = JB_FILE.read_text(encoding="utf-8")
FB = FOURBAR.format(**BENCH)


def snapshot(root: Path) -> dict:
    """Every file under root (hidden ones too) with its mode and content hash."""
    out = {}
    for p in sorted(root.rglob("*")):
        if p.is_file() and not p.is_symlink():
            out[str(p.relative_to(root))] = (p.stat().st_mode,
                                             hashlib.sha256(p.read_bytes()).hexdigest())
        elif p.is_dir():
            out[str(p.relative_to(root)) + "/"] = None
    return out


def run(args, *, code=2, has=(), cwd=None):
    """Run the CLI in-process; assert the exit code, the located message, no traceback."""
    old = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        out = runner.invoke(app, [str(a) for a in args])
    finally:
        os.chdir(old)
    text = out.stdout + out.stderr
    assert out.exit_code == code, (args, out.exit_code, text[-2000:])
    assert "Traceback" not in text, text[-2000:]
    assert out.exception is None or isinstance(out.exception, SystemExit), repr(out.exception)
    if code == 2:
        assert out.stderr.startswith("error: "), out.stderr
        assert "internal error" not in out.stderr
    for h in has:
        assert h in out.stderr or h in out.stdout, (h, text[-2000:])
    return out


def mutated(old: str, new: str, text: str = JB) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


# ---- class 1: non-finite numbers, where they enter ---------------------------------------------

FILE_NUMBERS = [  # (case, text to replace in jb1-3.toml, replacement, location in the message)
    ("point-x-nan", "[points.O]                   # upper-shaft axis\nx = 0.0",
     "[points.O]\nx = nan", "[points.O] x"),
    ("point-y-inf", "[points.O]                   # upper-shaft axis\nx = 0.0\ny = 0.0",
     "[points.O]\nx = 0.0\ny = inf", "[points.O] y"),
    ("point-huge", "[points.O]                   # upper-shaft axis\nx = 0.0",
     "[points.O]\nx = 1e300", "[points.O]"),
    ("speed-nan", "rpm = 1000.0 ", "rpm = nan ", "[speed] rpm"),
    ("speed-inf", "rpm = 1000.0 ", "rpm = inf ", "[speed] rpm"),
    ("speed-zero", "rpm = 1000.0 ", "rpm = 0.0 ", "[speed] rpm"),
    ("input-default-nan", "default_deg = 30.0 ", "default_deg = nan ",
     "[inputs.regulator] default_deg"),
    ("input-min-inf", "min_deg = -30.0 ", "min_deg = -inf ", "[inputs.regulator] min_deg"),
    ("crank-phase-nan", "phase_deg = 0.0              # needle crank",
     "phase_deg = nan # needle crank", 'units[0] "needle_crank"] phase_deg'),
    ("crank-point-inf", "points = { B = [15.35, 0.0]", "points = { B = [inf, 0.0]",
     'units[0] "needle_crank"] points.B[0]'),
    ("rrp-length-nan", "length = 44.0 ", "length = nan ", 'units[1] "needle_bar"] length'),
    ("rrp-guide-angle-inf", "guide_angle_deg = 90.0       # vertical guide",
     "guide_angle_deg = inf # vertical", 'units[1] "needle_bar"] guide_angle_deg'),
    ("rrr-length-nan", "lengths = [26.5, 20.1]", "lengths = [nan, 20.1]",
     'units[3] "take_up"] lengths[0]'),
    ("rrr-length-neg-inf", "lengths = [26.5, 20.1]", "lengths = [26.5, -inf]",
     'units[3] "take_up"] lengths[1]'),
    ("loop-init-nan", "unknown_links_deg = { feed_fork = 99.887",
     "unknown_links_deg = { feed_fork = nan", 'units[11] "feed_fork"] unknown_links_deg'),
    ("loop-length-init-inf", "unknown_lengths_mm = { fork_on_cam = 170.28",
     "unknown_lengths_mm = { fork_on_cam = inf", 'units[11] "feed_fork"] unknown_lengths_mm'),
    ("loop-term-length-nan", '{ link = "feed_fork", length = 125.0 }',
     '{ link = "feed_fork", length = nan }', "terms[2]"),
    ("loop-term-angle-inf", "length = 10.0, angle_deg = 90.0, sign = -1",
     "length = 10.0, angle_deg = inf, sign = -1", "angle_deg"),
    ("cam-width-nan", "constant_width = { width = 20.0", "constant_width = { width = nan",
     "[cams.feed_cam.constant_width] width"),
    ("cam-dwell-inf", "dwell_deg = 60.0 }", "dwell_deg = inf }",
     "[cams.feed_cam.constant_width] dwell_deg"),
    ("cam-arc-radius-nan", "radius = 8.0, normal_from_deg", "radius = nan, normal_from_deg",
     "[cams.lift_cam.arcs[0]] radius"),
    ("cam-arc-center-inf", "center = [1.3, 0.0]", "center = [inf, 0.0]",
     "[cams.lift_cam.arcs[0]] center[0]"),
    ("sewing-plate-nan", "plate_y = ", "plate_y = nan #", "[sewing] plate_y"),
    ("load-force-nan", "force_N = 2.94", "force_N = nan", 'loads[0] "'),
    ("load-window-inf", "within_of_max = 3.0 }]", "within_of_max = 3.0 }]\nwindows_deg = [[135.0, inf]]",
     'loads[0] "'),
    ("shaft-z-nan", "bearings = { front = ", "bearings = { front = nan, x = ", "[shaft]"),
]


@pytest.mark.parametrize("case,old,new,where", FILE_NUMBERS, ids=[c[0] for c in FILE_NUMBERS])
def test_1_file_numbers_must_be_finite(tmp_path, case, old, new, where):
    path = tmp_path / "m.toml"
    path.write_text(mutated(old, new))
    before = snapshot(tmp_path)
    out = run(["check", path], has=(str(path), where))
    assert snapshot(tmp_path) == before
    assert "nan" not in out.stdout.lower()


OPTION_NUMBERS = [  # (case, argv, the option named in the message)
    ("rpm-nan", ["kinematics", "jb1-3", "--rpm", "nan"], "--rpm"),
    ("rpm-inf", ["kinematics", "jb1-3", "--rpm", "inf"], "--rpm"),
    ("rpm-zero", ["dynamics", "jb1-3", "--rpm", "0"], "--rpm"),
    ("rpm-negative", ["dynamics", "jb1-3", "--rpm", "-5"], "--rpm"),
    ("rpm-huge", ["kinematics", "jb1-3", "--rpm", "1e9"], "--rpm"),
    ("step-nan", ["check", "jb1-3", "--step-deg", "nan"], "--step-deg"),
    ("step-inf", ["kinematics", "jb1-3", "--step-deg", "inf"], "--step-deg"),
    ("step-zero", ["kinematics", "jb1-3", "--step-deg", "0"], "--step-deg"),
    ("step-negative", ["dynamics", "jb1-3", "--step-deg", "-1"], "--step-deg"),
    ("step-tiny", ["check", "jb1-3", "--step-deg", "1e-6"], "--step-deg"),
    ("step-not-dividing", ["kinematics", "jb1-3", "--step-deg", "7"], "--step-deg"),
    ("step-too-big", ["kinematics", "jb1-3", "--step-deg", "400"], "--step-deg"),
    ("report-step-tiny", ["report", "jb1-3", "--step-deg", "0.01"], "--step-deg"),
    ("input-nan", ["kinematics", "jb1-3", "--input", "regulator=nan"], "--input"),
    ("input-inf", ["dynamics", "jb1-3", "--input", "regulator=inf"], "--input"),
    ("step-mm-zero", ["feed", "jb1-3", "--step-mm", "0"], "--step-mm"),
    ("step-mm-nan", ["feed", "jb1-3", "--step-mm", "nan"], "--step-mm"),
    ("step-mm-negative", ["feed", "jb1-3", "--step-mm", "-1"], "--step-mm"),
    ("alpha-nan", ["embroidery-take-up", "--alpha-deg", "nan"], "--alpha-deg"),
    ("beta-inf", ["embroidery-take-up", "--beta-deg", "inf"], "--beta-deg"),
    ("points-zero", ["embroidery-take-up", "--points", "0"], "--points"),
    ("points-huge", ["embroidery-take-up", "--points", "1000000000"], "--points"),
    ("phi-nan", ["kinematics", "jb1-3", "--phi-deg", "nan"], "--phi-deg"),
    ("phi-inf", ["dynamics", "jb1-3", "--phi-deg", "inf"], "--phi-deg"),
    ("set-nan", ["kinematics", "jb1-3", "--set", "needle_bar.length=nan"], "--set"),
    ("set-inf", ["check", "jb1-3", "--set", "needle_bar.length=inf"], "--set"),
]


@pytest.mark.parametrize("case,argv,option", OPTION_NUMBERS, ids=[c[0] for c in OPTION_NUMBERS])
def test_1_option_numbers_must_be_finite_and_in_range(tmp_path, case, argv, option):
    run(argv, has=(f"error: {option}",), cwd=tmp_path)
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_1_library_parameters_never_nan_feasible():
    m = sewmech.load_machine("fourbar-benchmark")
    phi = np.radians(np.arange(0.0, 360.0, 10.0))
    P = np.tile(m.defaults, (4, 1))
    P[1, m.parameter_index("dyad.length1")] = np.nan
    P[2, m.parameter_index("A.x")] = np.inf
    P[3, m.parameter_index("crank.phase")] = -np.inf
    r = sewmech.kinematics(m, phi, params=P, on_failure="mask")
    assert r.feasible[0].all() and not r.feasible[1:].any()
    assert np.isfinite(r.p[0]).all() and np.isnan(r.p[1:]).all()
    assert set(r.failure_reasons[1:].ravel()) == {"parameter"}
    assert list(r.failure_units[1:, 0]) == ["dyad", "(parameters)", "crank"]
    with pytest.raises(ParameterError, match=r"parameter 'dyad.length1' of design \(1,\): is nan"):
        sewmech.kinematics(m, phi, params=P)
    with pytest.raises(ParameterError, match="'dyad.length1'"):
        m.parameters({"dyad.length1": [40.0, np.nan]})
    with pytest.raises(ParameterError, match="'input.regulator'"):
        sewmech.load_machine("jb1-3").parameters(inputs={"regulator": np.inf})


@pytest.mark.parametrize("kw,name", [
    (dict(rpm=float("nan")), "rpm"), (dict(rpm=0.0), "rpm"), (dict(rpm=-5.0), "rpm"),
    (dict(omega=np.inf), "omega"), (dict(epsilon=np.nan), "epsilon"),
    (dict(phi=[0.0, np.nan]), "phi"), (dict(max_step_deg=0.0), "max_step_deg"),
    (dict(tol=np.nan), "tol"), (dict(on_failure="ignore"), "on_failure"),
], ids=["rpm-nan", "rpm-0", "rpm-neg", "omega-inf", "epsilon-nan", "phi-nan", "max-step-0",
        "tol-nan", "on-failure"])
def test_1_library_arguments_are_checked(kw, name):
    m = sewmech.load_machine("jb1-3")
    phi = kw.pop("phi", [0.0, 1.0])
    with pytest.raises(OptionError) as exc:
        sewmech.kinematics(m, phi, **kw)
    assert exc.value.option == name and str(exc.value).startswith(f"{name}:")


def test_1_dynamics_and_downstream_refuse_non_finite():
    from sewmech.dynamics import inverse_dynamics, speed_fluctuation

    m = sewmech.load_machine("jb1-3")
    phi = np.radians(np.arange(0.0, 360.0, 30.0))
    with pytest.raises(OptionError, match="rpm"):
        inverse_dynamics(m, phi, rpm=float("nan"))
    with pytest.raises(SewmechError, match="flywheel"):
        speed_fluctuation(m, flywheel=float("nan"))
    with pytest.raises(SewmechError, match="flywheel"):
        speed_fluctuation(m, flywheel=-1.0)
    from sewmech import feed

    with pytest.raises(SewmechError, match="regulator"):
        feed.feed_cycles(m, [float("nan")])
    with pytest.raises(SewmechError, match="step"):
        feed.scale_marks(m, float("nan"))


# ---- class 2: output paths; nothing of the user's is lost --------------------------------------


def _user_dir(tmp_path: Path) -> Path:
    d = tmp_path / "mine"
    d.mkdir()
    (d / "notes.txt").write_text("my notes")
    (d / "index.html").write_text("my page")
    return d


@pytest.mark.parametrize("argv", [
    ["report", "jb1-3", "--step-deg", "5"], ["demo"], ["kinematics", "jb1-3"],
    ["dynamics", "jb1-3"], ["embroidery-take-up"],
], ids=["report", "demo", "kinematics", "dynamics", "embroidery"])
def test_2_a_directory_with_the_users_files_is_refused(tmp_path, argv):
    d = _user_dir(tmp_path)
    before = snapshot(tmp_path)
    run(argv + ["--out", d], has=(f"--out {d}", "did not write", "notes.txt"))
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("argv", [
    ["report", "jb1-3"], ["kinematics", "jb1-3"], ["dynamics", "jb1-3"],
], ids=["report", "kinematics", "dynamics"])
def test_2_an_existing_file_as_out_is_refused(tmp_path, argv):
    f = tmp_path / "result.csv"
    f.write_text("mine")
    before = snapshot(tmp_path)
    run(argv + ["--out", f], has=("is a file, not a directory",))
    assert snapshot(tmp_path) == before


def test_2_a_device_or_fifo_is_never_replaced(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    run(["report", "jb1-3", "--out", fifo], has=("is a file, not a directory",))
    assert fifo.exists() and not fifo.is_dir() and sorted(os.listdir(tmp_path)) == ["pipe"]


def test_2_out_dot_in_a_project_directory_fails_at_once(tmp_path, monkeypatch):
    (tmp_path / "README.md").write_text("my project")
    import sewmech.report

    def never(*args, **kwargs):  # the refusal comes before the report is computed
        raise AssertionError("the report was started")

    monkeypatch.setattr(sewmech.report, "write_report", never)
    run(["report", "jb1-3", "--out", "."], has=("--out .", "README.md"), cwd=tmp_path)
    assert sorted(os.listdir(tmp_path)) == ["README.md"]


def test_2_home_is_expanded(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path))
    run(["kinematics", "jb1-3", "--out", "~/k"], code=0, cwd=tmp_path)
    assert (tmp_path / "k" / "jb1-3-kinematics.csv").exists()
    assert not (tmp_path / "~").exists()


def test_2_out_under_a_file_and_too_long(tmp_path):
    (tmp_path / "f").write_text("x")
    run(["kinematics", "jb1-3", "--out", tmp_path / "f" / "sub"], has=("--out",))
    run(["kinematics", "jb1-3", "--out", tmp_path / ("x" * 300)], has=("too long",))
    assert sorted(os.listdir(tmp_path)) == ["f"]


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_2_read_only_directory(tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o555)
    try:
        run(["kinematics", "jb1-3", "--out", d / "x"], has=("cannot write there",))
    finally:
        d.chmod(0o755)


def test_2_sewmechs_own_directory_is_updated_and_stale_files_go(tmp_path):
    d = tmp_path / "k"
    run(["kinematics", "jb1-3", "--out", d], code=0)
    run(["kinematics", "jb1-3", "--out", d, "--format", "json"], code=0)
    names = sorted(os.listdir(d))
    # the second run of the same command replaced the first one's files
    assert names == [".sewmech-manifest.json", ".sewmech.lock", "jb1-3-kinematics.json"]
    run(["dynamics", "jb1-3", "--out", d, "--step-deg", "30"], code=0)
    assert "jb1-3-kinematics.json" in os.listdir(d)  # another command's files stay
    manifest = json.loads((d / ".sewmech-manifest.json").read_text())["files"]
    assert manifest["jb1-3-kinematics.json"]["command"] == "kinematics"


def test_2_a_file_the_user_changed_is_not_overwritten(tmp_path):
    d = tmp_path / "k"
    run(["kinematics", "jb1-3", "--out", d], code=0)
    f = d / "jb1-3-kinematics.csv"
    f.write_text(f.read_text() + "my annotation\n")
    before = snapshot(tmp_path)
    run(["kinematics", "jb1-3", "--out", d], has=("changed since", "jb1-3-kinematics.csv"))
    assert snapshot(tmp_path) == before


def test_2_a_failing_run_leaves_the_previous_result_and_no_staging(tmp_path):
    d = tmp_path / "k"
    run(["kinematics", "jb1-3", "--out", d], code=0)
    before = snapshot(tmp_path)
    run(["kinematics", "jb1-3", "--out", d, "--input", "regulator=99"], has=("--input",))
    run(["kinematics", "jb1-3", "--out", d, "--set", "needle_bar.length=1"],
        has=("needle_bar",))
    assert snapshot(tmp_path) == before
    assert not [p for p in os.listdir(d) if p.startswith(".sewmech-staging")]


def test_2_a_new_directory_is_removed_when_the_run_fails(tmp_path):
    run(["kinematics", "jb1-3", "--out", tmp_path / "new" / "deeper",
         "--set", "needle_bar.length=1"], has=("needle_bar",))
    assert os.listdir(tmp_path) == []


def test_2_a_locked_directory_is_refused(tmp_path):
    import fcntl

    d = tmp_path / "k"
    run(["kinematics", "jb1-3", "--out", d], code=0)
    before = snapshot(tmp_path)
    fd = os.open(d / ".sewmech.lock", os.O_RDWR)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        run(["kinematics", "jb1-3", "--out", d], has=("another sewmech run",))
    finally:
        os.close(fd)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002])
def test_2_modes_follow_the_umask(tmp_path, mask):
    old = os.umask(mask)
    try:
        from sewmech import outdir

        outdir._UMASK = None
        run(["kinematics", "jb1-3", "--out", tmp_path / "k"], code=0)
    finally:
        os.umask(old)
        outdir._UMASK = None
    assert (tmp_path / "k").stat().st_mode & 0o777 == 0o777 & ~mask
    for p in (tmp_path / "k").iterdir():
        assert p.stat().st_mode & 0o777 == 0o666 & ~mask, p


def _cli() -> list[str]:
    exe = Path(sys.executable).with_name("sewmech")
    return [str(exe)] if exe.exists() else [sys.executable, "-c",
                                            "from sewmech.cli import main; main()"]


@pytest.mark.parametrize("signal_exc, code", [
    (lambda: __import__("sewmech.app.cli.common", fromlist=["x"]).Terminated(signal.SIGHUP), 129),
    (lambda: KeyboardInterrupt(), 130)])
def test_2_a_signal_stays_the_reason_when_the_unwinding_fails(signal_exc, code, capsys):
    """A signal raised inside drawing code whose own cleanup then fails (matplotlib's "Invalid
    bounding box" on a half-drawn figure: seen once in CI after SIGHUP) ends the command as
    the signal does, not as a user error with exit code 2."""
    import typer

    from sewmech.app.cli.common import _guard

    with pytest.raises(typer.Exit) as info:
        with _guard():
            try:
                raise signal_exc()
            finally:
                raise ValueError("Invalid bounding box")
    assert info.value.exit_code == code
    err = capsys.readouterr().err
    assert "Invalid bounding box" not in err and "nothing half-written" in err


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
@pytest.mark.parametrize("sig,code", [(signal.SIGHUP, 129), (signal.SIGINT, 130)],
                         ids=["sighup", "sigint"])
def test_2_a_signal_swallowed_by_a_finalizer_still_keeps_the_files_out(tmp_path, sig, code):
    """A signal whose handler runs while a __del__ or a weakref callback runs (matplotlib's
    figures run many) has its exception swallowed by Python and the command goes on: its
    files still do not move in, and it ends as the signal says (seen once in CI: a report
    sent SIGHUP finished and exited 0)."""
    import typer

    from sewmech.app.cli.common import _guard
    from sewmech.app.files.outdir import output_dir

    class Dying:
        def __del__(self):
            os.kill(os.getpid(), sig)
            for _ in range(10000):  # the handler runs in here, and its exception is lost
                pass

    went_on = False
    handler = signal.getsignal(sig)
    with pytest.raises(typer.Exit) as info:
        with _guard():
            with output_dir(tmp_path / "rep", command="report") as staging:
                (staging / "a.txt").write_text("half")
                Dying()  # dies at once
                went_on = True
    assert went_on  # the exception was swallowed indeed
    assert info.value.exit_code == code
    assert os.listdir(tmp_path) == []  # nothing moved in, the directory it made is gone
    assert signal.getsignal(sig) is handler  # the command's handler is gone again


@pytest.mark.slow
@pytest.mark.parametrize("sig,code", [(signal.SIGTERM, 143), (signal.SIGINT, 130),
                                      (signal.SIGHUP, 129)], ids=["sigterm", "sigint", "sighup"])
def test_2_interrupted_report_leaves_nothing(tmp_path, sig, code):
    d = tmp_path / "rep"
    # the command as a terminal starts it, SIGINT at its default: a test run started in the
    # background (`&`, a CI runner without job control) would hand it SIGINT ignored, and a
    # program that starts with SIGINT ignored rightly keeps ignoring it
    terminal = [sys.executable, "-c", ("import os, signal, sys; signal.signal(signal.SIGINT,"
                                       " signal.SIG_DFL); os.execv(sys.argv[1], sys.argv[1:])")]
    p = subprocess.Popen(terminal + _cli() + ["report", "jb1-3", "--out", str(d),
                                              "--step-deg", "0.5"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
    deadline = time.time() + 60
    while time.time() < deadline and not (d.exists() and any(
            n.startswith(".sewmech-staging") for n in os.listdir(d))):
        time.sleep(0.05)
    assert d.exists(), "the report never started writing"
    time.sleep(0.5)
    p.send_signal(sig)
    out, err = p.communicate(timeout=60)
    assert p.returncode == code, err.decode()
    assert b"Traceback" not in err and b"nothing half-written" in err
    assert os.listdir(tmp_path) == []  # the directory it created is gone too


@pytest.mark.slow
def test_2_concurrent_reports_end_with_one_complete_result(tmp_path):
    d = tmp_path / "rep"
    cmd = _cli() + ["report", "jb1-3", "--out", str(d), "--step-deg", "5"]
    procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
             for _ in range(2)]
    results = [(p.wait(timeout=300), p.stderr.read().decode()) for p in procs]
    codes = sorted(c for c, _ in results)
    assert codes in ([0, 0], [0, 2]), results
    for c, err in results:
        assert "Traceback" not in err
        if c == 2:
            assert "another sewmech run" in err
    manifest = json.loads((d / ".sewmech-manifest.json").read_text())["files"]
    for name, rec in manifest.items():
        assert (d / name).stat().st_size == rec["size"], name
    assert "index.html" in manifest and not [n for n in os.listdir(d)
                                             if n.startswith(".sewmech-staging")]


# ---- class 2b: nothing outside --out is touched, nothing of the user's inside it (issue 29) --


def _damage_manifest(d: Path, files) -> None:
    m = d / ".sewmech-manifest.json"
    data = json.loads(m.read_text())
    data["files"] = files(data["files"])
    m.write_text(json.dumps(data))


@pytest.mark.parametrize("name", ["../victim.txt", "{victim}", "sub/x.csv", "..", ".",
                                  ".sewmech.lock", "a\\b", ""])
def test_2b_a_manifest_naming_anything_but_its_own_files_is_refused(tmp_path, name):
    victim = tmp_path / "victim.txt"
    victim.write_text("mine")
    d = tmp_path / "o"
    run(["kinematics", "jb1-3", "--out", d, "--step-deg", "30"], code=0)
    (d / "sub").mkdir()
    (d / "sub" / "x.csv").write_text("mine too")
    _damage_manifest(d, lambda f: {**{k: {**v, "command": "kinematics"} for k, v in f.items()},
                                   name.format(victim=victim): {"command": "kinematics",
                                                                "size": 4, "mtime_ns": 0}})
    before = snapshot(tmp_path)
    run(["kinematics", "jb1-3", "--out", d, "--step-deg", "30"],
        has=(f"--out {d}", "damaged", "choose another directory"))
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("text, why", [
    ("{not json", "damaged"), ("[]", "not a record sewmech wrote"),
    ('{"written_by": "sewmech", "files": {"a.csv": {"command": "kinematics", "size": -1,'
     ' "mtime_ns": 0}}}', "entry for 'a.csv'"),
    ('{"written_by": "sewmech", "files": {"a.csv": {"command": 1, "size": 1, "mtime_ns": 0}}}',
     "entry for 'a.csv'"),
    ('{"written_by": "someone", "files": {}}', "not a record sewmech wrote")])
def test_2b_a_damaged_manifest_is_a_located_error(tmp_path, text, why):
    d = tmp_path / "o"
    d.mkdir()
    (d / ".sewmech-manifest.json").write_text(text)
    before = snapshot(tmp_path)
    run(["kinematics", "jb1-3", "--out", d, "--step-deg", "30"], has=(str(d), why))
    assert snapshot(tmp_path) == before


def test_2b_a_manifest_that_is_a_symlink_is_refused(tmp_path):
    d = tmp_path / "o"
    run(["kinematics", "jb1-3", "--out", d, "--step-deg", "30"], code=0)
    real = tmp_path / "elsewhere.json"
    (d / ".sewmech-manifest.json").rename(real)
    (d / ".sewmech-manifest.json").symlink_to(real)
    before = snapshot(tmp_path)
    run(["kinematics", "jb1-3", "--out", d, "--step-deg", "30"], has=("not a plain file",))
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("command", [["kinematics", "jb1-3", "--step-deg", "30"],
                                     ["sweep", str(Path(__file__).resolve().parents[1] /
                                                   "examples/sweeps/jb-feed-small.toml"),
                                      "--workers", "0"]], ids=["staged", "sweep"])
def test_2b_a_lock_that_is_a_symlink_never_truncates_its_target(tmp_path, command):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    d = tmp_path / "o"
    d.mkdir()
    (d / ".sewmech.lock").symlink_to(victim)
    before = snapshot(tmp_path)
    run(command + ["--out", d], has=(".sewmech.lock",))  # (a sweep: not a sweep's file)
    assert snapshot(tmp_path) == before and victim.read_text() == "precious"


def _run_writing(d: Path, during, command="kinematics"):
    """output_dir with a result a.csv and b.csv, calling ``during(d)`` while the run works."""
    from sewmech.app.files.outdir import output_dir

    notes = []
    with output_dir(d, command=command, notice=notes.append) as stage:
        (stage / "a.csv").write_text("new a")
        (stage / "b.csv").write_text("new b")
        during(d)
    return notes


def test_2b_a_file_the_user_saves_during_the_run_is_never_replaced(tmp_path):
    d = tmp_path / "o"
    _run_writing(d, lambda d: None)

    def user_saves(d):
        (d / "b.csv").unlink()  # (a user's own file of the same name, saved meanwhile)
        (d / "b.csv").write_text("the user's b")

    with pytest.raises(OutputError) as info:
        _run_writing(d, user_saves)
    text = str(info.value)
    assert "b.csv" in text and "none of them was replaced" in text
    assert (d / "b.csv").read_text() == "the user's b"
    kept = [p for p in d.iterdir() if p.name.startswith("sewmech-kept-kinematics-")]
    assert len(kept) == 1 and str(kept[0]) in text
    assert sorted(p.name for p in kept[0].iterdir()) == ["a.csv", "b.csv"]
    assert (kept[0] / "b.csv").read_text() == "new b"
    # the directory stays usable: the user's file is foreign now, so the next run refuses it
    with pytest.raises(OutputError, match="did not write"):
        _run_writing(d, lambda d: None)
    (d / "b.csv").unlink()
    _run_writing(d, lambda d: None)  # and a run goes through once it is moved away
    assert (d / "b.csv").read_text() == "new b"


def test_2b_a_new_name_taken_by_the_user_meanwhile_is_not_replaced(tmp_path):
    d = tmp_path / "o"
    with pytest.raises(OutputError, match="a.csv"):
        _run_writing(d, lambda d: (d / "a.csv").write_text("the user's a"))
    assert (d / "a.csv").read_text() == "the user's a"
    assert not (d / "b.csv").exists()  # nothing moved in once one name was taken


def test_2b_a_file_of_ours_the_user_edits_during_the_run_is_kept(tmp_path):
    d = tmp_path / "o"
    _run_writing(d, lambda d: None)
    before = (d / "a.csv").stat().st_mtime_ns

    def user_edits(d):
        with open(d / "a.csv", "a") as fh:
            fh.write(" + the user's note")
        os.utime(d / "a.csv", ns=(before + 10**9, before + 10**9))

    with pytest.raises(OutputError, match="a.csv"):
        _run_writing(d, user_edits)
    assert (d / "a.csv").read_text() == "new a + the user's note"


def test_2b_a_stale_file_the_user_edits_during_the_run_is_left_and_said(tmp_path):
    from sewmech.app.files.outdir import output_dir

    d = tmp_path / "o"
    _run_writing(d, lambda d: None)
    notes = []
    with output_dir(d, command="kinematics", notice=notes.append) as stage:
        (stage / "a.csv").write_text("only a now")  # b.csv is not written again: stale
        with open(d / "b.csv", "a") as fh:  # but the user edits it meanwhile
            fh.write(" edited")
    assert (d / "b.csv").read_text() == "new b edited"
    assert (d / "a.csv").read_text() == "only a now"
    assert any("b.csv changed since sewmech wrote it" in n for n in notes), notes
    manifest = json.loads((d / ".sewmech-manifest.json").read_text())["files"]
    assert sorted(manifest) == ["a.csv"]  # b.csv is the user's now


def test_2b_the_no_replace_move_without_renameat2(tmp_path, monkeypatch):
    from sewmech.app.files import outdir

    for fn in (outdir._RENAMEAT2, None):
        monkeypatch.setattr(outdir, "_RENAMEAT2", fn)
        (tmp_path / "src").write_text("s")
        (tmp_path / "dst").write_text("the user's")
        with pytest.raises(FileExistsError):
            outdir.move_no_replace(tmp_path / "src", tmp_path / "dst")
        assert (tmp_path / "dst").read_text() == "the user's"
        (tmp_path / "dst").unlink()
        outdir.move_no_replace(tmp_path / "src", tmp_path / "dst")
        assert (tmp_path / "dst").read_text() == "s" and not (tmp_path / "src").exists()
        (tmp_path / "dst").unlink()


def _gone(pgid: int, timeout: float = 10.0) -> bool:
    """Whether every process of the group ``pgid`` has ended (within ``timeout`` s)."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def _children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as fh:
            return [int(x) for x in fh.read().split()]
    except OSError:
        return []


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="needs Linux's /proc")
@pytest.mark.parametrize("command", [["report", "jb1-3"], ["dynamics", "jb1-3"]])
def test_2b_a_killed_command_leaves_no_worker_and_no_lock(tmp_path, command):
    """SIGKILL of the command while its figure workers draw: the workers end with it, the
    kernel releases the lock, and the next run goes through, saying what it recovered."""
    d = tmp_path / "o"
    p = subprocess.Popen(_cli() + command + ["--out", str(d)], stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, cwd=tmp_path, start_new_session=True)
    deadline = time.time() + 120
    while time.time() < deadline and not (len(_children(p.pid)) >= 1 and d.exists() and any(
            n.startswith(".sewmech-staging") for n in os.listdir(d))):
        time.sleep(0.02)
    assert _children(p.pid), "the command never started its workers"
    time.sleep(0.3)
    os.kill(p.pid, signal.SIGKILL)
    p.wait(timeout=30)
    assert _gone(p.pid), "a worker outlived the command"
    out = subprocess.run(_cli() + command + ["--out", str(d), "--step-deg", "10"],
                         capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "was stopped before it finished" in out.stderr, out.stderr
    assert not [n for n in os.listdir(d) if n.startswith(".sewmech-staging")]
    assert (d / ".sewmech.lock").read_text() == ""  # released, and no run holds it


def test_2b_a_forked_child_holds_no_lock_of_its_parent(tmp_path):
    """The lock belongs to the process that took it: a child forked while it is held (a figure
    worker) closes its copy, so the lock goes with its owner."""
    import fcntl

    from sewmech.app.files.outdir import output_dir

    d = tmp_path / "o"
    with output_dir(d, command="kinematics"):
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child: try the lock through a descriptor of its own
            fd = os.open(d / ".sewmech.lock", os.O_RDWR)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                os.write(w, b"free")  # (it must not be: the parent holds it)
            except BlockingIOError:
                os.write(w, b"held")
            inherited = [int(x) for x in os.listdir("/proc/self/fd")] \
                if Path("/proc/self/fd").exists() else []
            os.write(w, b" " + str(len([f for f in inherited if _is_lock(f, d)])).encode())
            os._exit(0)
        os.close(w)
        os.waitpid(pid, 0)
        said = os.read(r, 100).decode()
        os.close(r)
    assert said == "held 1", said  # the parent's lock holds; the child has only its own copy


def _is_lock(fd: int, d: Path) -> bool:
    try:
        return os.readlink(f"/proc/self/fd/{fd}") == str(d / ".sewmech.lock")
    except OSError:
        return False


# ---- class 3: ordinary mistakes (no traceback) ----------------------------------------------


def _bad_files(tmp_path: Path) -> dict[str, Path]:
    files = {}

    def put(name, data):
        p = tmp_path / name
        p.write_bytes(data if isinstance(data, bytes) else data.encode())
        files[name] = p

    put("latin1.toml", JB.replace("ESTIMATE", "Schätzung").encode("latin-1", "replace"))
    put("binary.toml", bytes(range(256)) * 4)
    put("empty.toml", "")
    put("nested.toml", "a = " + "[" * 5000 + "]" * 5000 + "\n")
    put("deep-tables.toml", "".join(f"[{'.'.join(['t'] * k)}]\n" for k in range(1, 60)))
    put("huge.toml", "# " + "x" * (5 * 2**20) + "\n")
    put("bad-syntax.toml", "[machine\nname = 'x'\n")
    put("string-number.toml", mutated("lengths = [26.5, 20.1]", 'lengths = ["26.5", 20.1]'))
    put("bool-number.toml", FB.replace("x = 38.0", "x = true"))
    put("misspelt-key.toml", FB.replace("lengths = [", "lenghts = ["))
    put("no-type.toml", FB.replace('type = "rrr"\n', ""))
    put("joint-twice.toml", FB.replace('joints = ["B", "D"]', 'joints = ["B", "B"]'))
    put("ratio-zero.toml", FB.replace('phase_deg = 0.0', 'phase_deg = 0.0\nratio = 0.0'))
    put("name-with-space.toml", FB.replace("P = [", '"P 1" = ['))
    put("flag-number.toml", FB + '[[loads]]\nname = "p"\nlink = "rocker"\npoint = "C"\n'
        'force_N = 1.0\nangle_deg = 0.0\nwindows_deg = []\n')
    put("table-for-number.toml", mutated("length = 44.0 ", "length = { a = 1 } "))
    put("list-for-table.toml", mutated("[speed]\nrpm = 1000.0 ", "speed = [1, 2]\n#"))
    put("missing-convention.toml", JB[:JB.index("[convention]")] + JB[JB.index("[speed]"):])
    put("no-units.toml", JB[:JB.index("[[units]]")])
    put("bom.toml", "\ufeff" + FB)
    put("unknown-unit-type.toml", mutated('type = "rrr"', 'type = "rrrr"'))
    put("duplicate-unit.toml", FB.replace('name = "cp"', 'name = "dyad"'))
    return files


BAD_FILES = [  # (file, message part)
    ("latin1.toml", "not UTF-8"), ("binary.toml", "binary file"), ("empty.toml", "missing"),
    ("nested.toml", "too deeply"), ("deep-tables.toml", "unknown key 't'"),
    ("huge.toml", "MiB"), ("bad-syntax.toml", "not valid TOML"),
    ("string-number.toml", "lengths[0]: must be a number, got the string '26.5'. Write it"
     " without quotes"),
    ("bool-number.toml", "[points.D] x: must be a number, got true"),
    ("misspelt-key.toml", "unknown key 'lenghts'; expected one of: branch, joints, lengths"),
    ("misspelt-key.toml", "Did you mean 'lengths'?"),
    ("no-type.toml", "missing key 'type'"),
    ("joint-twice.toml", "the two joints must be different points"),
    ("ratio-zero.toml", "ratio = 0"),
    ("name-with-space.toml", "'P 1' is not a name"),
    ("flag-number.toml", "windows_deg"),
    ("table-for-number.toml", "length"),
    ("list-for-table.toml", "speed"), ("missing-convention.toml", "convention"),
    ("no-units.toml", "units"), ("unknown-unit-type.toml", "unknown unit type"),
    ("duplicate-unit.toml", "used twice"),
]


@pytest.mark.parametrize("name,part", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_3_unreadable_and_malformed_files(tmp_path, name, part):
    path = _bad_files(tmp_path)[name]
    before = snapshot(tmp_path)
    run(["check", path], has=(str(path), part))
    assert snapshot(tmp_path) == before


def test_3_a_bom_is_fine_and_directories_and_missing_files_are_named(tmp_path):
    path = _bad_files(tmp_path)["bom.toml"]
    run(["check", path], code=0)
    run(["check", tmp_path], has=("is a directory",))
    run(["check", tmp_path / "nope.toml"], has=("nope.toml", "shipped machines"))
    run(["kinematics", "jb13"], has=("jb13", "jb1-3"))


def test_3_a_directory_named_like_a_shipped_machine_does_not_hide_it(tmp_path, monkeypatch):
    # `sewmech report jb8-2 --out jb8-2` leaves a directory of the machine's name behind: the
    # next command on the shipped name must still find the machine
    monkeypatch.chdir(tmp_path)
    (tmp_path / "jb8-2").mkdir()
    assert sewmech.load_machine("jb8-2").name == "jb8-2"
    run(["check", "jb8-2"], code=0)


@pytest.mark.parametrize("argv, where, what", [
    (["tolerance", "jb1-3", "--input", "regulator=0"], "sewmech tolerance", "no such option"),
    (["kinematics", "jb1-3", "--rpm", "abc"], "--rpm", "valid number"),
    (["check"], "sewmech check", "missing argument"),
    (["nosuch"], "sewmech", "no such command 'nosuch'"),
    (["kinematics", "jb1-3", "--format", "xml"], "--format", "'xml' is not one of"),
    (["kinematics", "jb1-3", "--step-deg"], "sewmech", "requires an argument"),
    (["embroidery-take-up", "--points", "x"], "--points", "valid integer"),
])
def test_3_command_line_mistakes_are_one_error_line(argv, where, what):
    """What click finds before a command runs (an unknown option or command, a missing or
    mistyped value) is one `error:` line like every other mistake, not a usage box."""
    out = run(argv, has=(what,))
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {where}: "), out.stderr
    assert "--help" in lines[0] and "╭" not in out.stderr


MISTAKES = [  # (case, argv, message part)
    ("input-twice", ["kinematics", "jb1-3", "--input", "regulator=10", "--input",
                     "regulator=-10"], "given twice"),
    ("set-twice", ["kinematics", "jb1-3", "--set", "needle_bar.length=44", "--set",
                   "needle_bar.length=45"], "given twice"),
    ("embroidery-layout", ["embroidery-take-up", "--machine", "fourbar-benchmark"],
     "is not laid out as the embroidery take-up"),
    ("feed-without-feed", ["feed", "fourbar-benchmark"], "[sewing]"),
    ("report-without-sewing", ["report", "fourbar-benchmark"], "[sewing]"),
    ("dynamics-without-masses", ["dynamics", "fourbar-benchmark"], "no [masses]"),
    ("embroidery-on-jb", ["embroidery-take-up", "--machine", "jb1-3"], "jb1-3"),
    ("compare-unknown", ["report", "jb1-3", "--compare", "jb9"], "jb9"),
    ("loads-missing", ["dynamics", "jb1-3", "--loads", "nope.toml"], "nope.toml"),
    ("input-unknown", ["kinematics", "jb1-3", "--input", "reg=20"], "no input 'reg'"),
    ("input-not-number", ["kinematics", "jb1-3", "--input", "regulator=x"], "NAME=DEGREES"),
    ("input-no-equals", ["kinematics", "jb1-3", "--input", "regulator"], "--input"),
    ("set-no-equals", ["kinematics", "jb1-3", "--set", "needle_bar.length"], "NAME=VALUE"),
    ("set-empty-name", ["kinematics", "jb1-3", "--set", "=3"], "NAME=VALUE"),
    ("set-not-number", ["kinematics", "jb1-3", "--set", "needle_bar.length=abc"],
     "not a number"),
    ("set-unknown", ["kinematics", "jb1-3", "--set", "nedle_bar.length=44"],
     "did you mean needle_bar.length"),
    ("set-wrong-unit", ["kinematics", "jb1-3", "--set", "needle_bar.length=44deg"],
     "is in mm, not deg"),
    ("set-cam-arc", ["kinematics", "jb1-3", "--set", "feed_cam.arc0.radius=3"],
     "constant-width cam"),
    ("set-negative-length", ["kinematics", "jb1-3", "--set", "needle_bar.length=-3"],
     'units[1] "needle_bar"] length'),
    ("set-breaks-assembly", ["kinematics", "jb1-3", "--set", "needle_bar.length=5"],
     "unit 'needle_bar'"),
]


@pytest.mark.parametrize("case,argv,part", MISTAKES, ids=[m[0] for m in MISTAKES])
def test_3_ordinary_mistakes_give_one_clear_line(tmp_path, case, argv, part):
    run(argv, has=(part,), cwd=tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_3_an_empty_load_file_is_refused(tmp_path):
    loads = tmp_path / "loads.toml"
    loads.write_text("# no loads yet\n")
    run(["dynamics", "jb1-3", "--loads", loads], has=("holds no [[loads]]", "--no-loads"))


def test_3_a_batch_too_big_for_memory_is_refused_before_allocating():
    m = sewmech.load_machine("fourbar-benchmark")
    P = m.parameters({"dyad.length1": np.linspace(39.0, 41.0, 10_000_000)})
    with pytest.raises(OptionError, match="GiB, more than this computer's"):
        sewmech.kinematics(m, np.radians(np.arange(360.0)), params=P, on_failure="mask")


def test_3_usage_errors_are_clean(tmp_path):
    out = runner.invoke(app, ["kinematics", "jb1-3", "--format", "xml", "--out", "x"])
    assert out.exit_code == 2 and "Traceback" not in out.output
    out = runner.invoke(app, ["kinematics", "jb1-3", "--rpm", "fast"])
    assert out.exit_code == 2 and "Traceback" not in out.output


def test_3_empty_angle_array_and_big_requests():
    m = sewmech.load_machine("jb1-3")  # three loop units
    r = sewmech.kinematics(m, [])
    assert r.p.shape == (0, len(m.point_names), 2) and r.all_feasible
    assert r.failures().empty
    from sewmech.dynamics import inverse_dynamics

    d = inverse_dynamics(m, [])
    assert d.input_torque.shape == (0,)


# ---- class 4: impossible physics --------------------------------------------------------------

MASS = '\n[masses.crank]\n{body}\n'
PHYSICS = [  # (case, [masses.crank] body, message part)
    ("negative-mass", "mass = -1.0\ncom = [0.0, 0.0]\ninertia_zz = 1.0", "mass"),
    ("zero-mass", "mass = 0.0\ncom = [0.0, 0.0]\ninertia_zz = 1.0", "mass"),
    ("negative-izz", "mass = 1.0\ncom = [0.0, 0.0]\ninertia_zz = -1.0", "inertia_zz"),
    ("nan-com", "mass = 1.0\ncom = [nan, 0.0]\ninertia_zz = 1.0", "com"),
    ("negative-definite",
     "mass = 1.0\ncom = [0.0, 0.0, 0.0]\ninertia = [[-1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]]",
     "not positive semi-definite"),
    ("triangle", "mass = 1.0\ncom = [0.0, 0.0, 0.0]\ninertia = [[1.0, 0, 0], [0, 1.0, 0],"
     " [0, 0, 5.0]]", "triangle inequality"),
    ("asymmetric", "mass = 1.0\ncom = [0.0, 0.0, 0.0]\ninertia = [[2.0, 0.5, 0], [0, 2.0, 0],"
     " [0, 0, 2.0]]", "symmetric"),
    ("hole-outside", 'density = 7850.0\nsolids = [ { type = "box", size = [10.0, 4.0, 4.0] },'
     ' { type = "cylinder", radius = 1.0, length = 4.0, base = [30.0, 0.0, -2.0],'
     ' hole = true } ]', "lies outside the material"),
    ("hole-bigger", 'density = 7850.0\nsolids = [ { type = "sphere", radius = 1.0 },'
     ' { type = "sphere", radius = 3.0, hole = true } ]', "lies outside the material"),
    ("negative-point-mass", 'density = 7850.0\nsolids = [ { type = "point", mass = -0.1 } ]',
     "mass"),
    ("negative-density", 'density = -7850.0\nsolids = [ { type = "sphere", radius = 1.0 } ]',
     "density"),
    ("unknown-material", 'material = "unobtainium"\nsolids = [ { type = "sphere",'
     ' radius = 1.0 } ]', "unknown material"),
    ("tube-inside-out", 'density = 7850.0\nsolids = [ { type = "hollow_cylinder", r_out = 2.0,'
     ' r_in = 3.0, length = 4.0 } ]', "r_in"),
    ("zero-radius", 'density = 7850.0\nsolids = [ { type = "sphere", radius = 0.0 } ]',
     "radius"),
]


@pytest.mark.parametrize("case,body,part", PHYSICS, ids=[p[0] for p in PHYSICS])
def test_4_impossible_mass_properties(tmp_path, case, body, part):
    path = tmp_path / "m.toml"
    path.write_text(FB + MASS.format(body=body))
    run(["check", path], has=(str(path), "masses.crank", part))


def test_4_shaft_links_need_full_inertia_and_every_crank(tmp_path):
    text = JB.replace("[masses.hook_crank]", "[masses.hook_crank]\nmass = 0.05\ncom = [5.0,"
                      " 0.0]\ninertia_zz = 10.0\n[masses.hook_crank_solids]", 1)
    text = text[:text.index("[masses.hook_crank_solids]")] + text[text.index(
        "[masses.big_rod]"):]
    path = tmp_path / "izz.toml"
    path.write_text(text)
    run(["check", path], has=("[masses.hook_crank] inertia_zz", "products of inertia"))
    line = next(ln for ln in JB.splitlines() if ln.startswith("links = {"))
    path.write_text(JB.replace(line, "links = { needle_crank = 0.0 }"))
    run(["check", path], has=("[shaft] links", "hook_crank, feed_cam turn(s) with the upper"))


def test_4_flywheel_and_machines_without_masses(tmp_path):
    from sewmech.dynamics import speed_fluctuation

    with pytest.raises(SewmechError, match="flywheel"):
        speed_fluctuation(sewmech.load_machine("jb1-3"), flywheel=-0.5)
    # no masses but a load: the forces are the load's, and the command says so
    path = tmp_path / "m.toml"
    path.write_text(SLIDER_CRANK.format(r=15.0, l=44.0, e=0.0, alpha=90.0, gx=0.0, gy=0.0,
                                        branch=1)
                    + '[[loads]]\nname = "press"\nlink = "block"\npoint = "C"\nforce_N = 10.0\n'
                      'angle_deg = -90.0\n')
    out = run(["dynamics", path, "--step-deg", "30"], code=0)
    assert "no [masses]" in out.stdout


# ---- class 5: declared ranges -------------------------------------------------------------------

RANGES = [  # (case, argv or file change, message part)
    ("input-above", ["kinematics", "jb1-3", "--input", "regulator=60"],
     "outside the range -30 .. 30 deg"),
    ("input-below", ["dynamics", "jb1-3", "--input", "regulator=-31"], "outside the range"),
    ("input-set", ["kinematics", "jb1-3", "--set", "input.regulator=45deg"],
     "default_deg 45"),
]


@pytest.mark.parametrize("case,argv,part", RANGES, ids=[r[0] for r in RANGES])
def test_5_settings_outside_their_declared_range(case, argv, part):
    run(argv, has=(part,))


FILE_RANGES = [
    ("default-outside", "default_deg = 30.0 ", "default_deg = 40.0 ", "default_deg 40"),
    ("min-above-max", "min_deg = -30.0 ", "min_deg = 31.0 ", "larger than max_deg"),
    ("window-beyond", "within_of_max = 3.0 }]", "within_of_max = 3.0 }]\nwindows_deg = [[400.0, 900.0]]",
     "[400, 900] is not a shaft-angle window"),
    ("window-negative", "within_of_max = 3.0 }]", "within_of_max = 3.0 }]\nwindows_deg = [[-10.0, 20.0]]",
     "not a shaft-angle window"),
    ("window-empty", "within_of_max = 3.0 }]", "within_of_max = 3.0 }]\nwindows_deg = [[20.0, 20.0]]",
     "from != to"),
    ("reference-false", "reference_phi_deg = 90.0", "reference_phi_deg = 80.0",
     "reference_phi_deg = 80 but needle.point at its top is at phi = 90"),
]


@pytest.mark.parametrize("case,old,new,part", FILE_RANGES, ids=[r[0] for r in FILE_RANGES])
def test_5_ranges_in_files(tmp_path, case, old, new, part):
    path = tmp_path / "m.toml"
    path.write_text(mutated(old, new))
    run(["check", path], has=(str(path), part))


def test_5_library_enforces_input_ranges_and_masks():
    m = sewmech.load_machine("jb1-3")
    phi = np.radians([0.0, 90.0])
    with pytest.raises(ParameterError, match="outside the range -30 deg .. 30 deg"):
        sewmech.kinematics(m, phi, inputs={"regulator": math.radians(40)})
    r = sewmech.kinematics(m, phi, inputs={"regulator": np.radians([20.0, 40.0])},
                           on_failure="mask")
    assert r.feasible[0].all() and not r.feasible[1].any()
    assert set(r.failure_reasons[1]) == {"parameter"}


def test_5_report_refuses_a_false_convention(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(mutated("reference_phi_deg = 90.0", "reference_phi_deg = 0.0"))
    run(["report", path, "--out", tmp_path / "rep"], has=("[convention] reference_phi_deg",
                                                          "Set reference_phi_deg = 90"))
    assert sorted(os.listdir(tmp_path)) == ["m.toml"]


def test_5_plate_and_fabric_must_be_reached_by_the_needle(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(mutated("plate_y = ", "plate_y = 500.0 #"))
    run(["report", path, "--out", tmp_path / "rep"], has=("[sewing] plate_y",
                                                          "never passes plate_y = 500"))


def test_5_adjust_range_where_the_take_up_never_assembles(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(mutated("min = 12.4\nmax = 22.0", "min = 100.0\nmax = 120.0"))
    run(["check", path], has=("Q.y = 100 ([thread.adjust] min)", "unit 'take_up'"))
    run(["report", path, "--out", tmp_path / "rep", "--step-deg", "5"],
        has=("cannot be assembled at any of the 57 settings of 'Q.y'",))
    assert sorted(os.listdir(tmp_path)) == ["m.toml"]


def test_5_machines_that_repeat_after_two_turns(tmp_path):
    half = FB.replace("phase_deg = 0.0", "phase_deg = 0.0\nratio = 0.5")
    proof = prove_assembly(sewmech.machine_from_toml(half), step_deg=5.0)
    assert proof.ok and proof.turns == 2 and proof.periodic
    path = tmp_path / "loop.toml"
    text = FOURBAR_LOOP.format(**BENCH, assembly=0.0, g_coupler=60.0, g_rocker=95.0)
    path.write_text(text.replace("phase_deg = 0.0", "phase_deg = 0.0\nratio = 0.5"))
    run(["check", path], has=("ratio = 0.5: a machine with loop units must repeat",))


def test_5_check_proves_assembly_between_grid_points(tmp_path):
    path = tmp_path / "gap.toml"
    path.write_text(FOURBAR.format(**{**BENCH, "bc": 30.0, "cd": 22.995, "phase": 2.5}))
    run(["check", path, "--step-deg", "5"], has=("fails over phi 175.75", "between the grid"))
    run(["check", path, "--step-deg", "5", "--set", "dyad.length2=23.1"], code=0)


# ---- class 6: newcomer frictions ------------------------------------------------------------

SIX_BAR = """
[machine]
name = "six-bar"
length_unit = "mm"
[convention]
reference_event = "crank along +x"
reference_phi_deg = 0.0
reference_link = "crank"
reference_angle_deg = 0.0
[points.A]
x = 0.0
y = 0.0
[points.D]
x = 38.0
y = 0.0
[points.F]
x = 60.0
y = -20.0
[[units]]
type = "crank"
name = "crank"
pivot = "A"
points = { B = { length = 15.0, angle_deg = 0.0 } }
[[units]]
type = "rrr"
name = "dyad1"
joints = ["B", "D"]
new = "C"
links = ["coupler", "rocker"]
lengths = [40.0, 35.0]
branch = -1
[[units]]
type = "point"
name = "coupler_point"
link = "coupler"
origin = "B"
points = { E = { length = 31.62, angle_deg = 18.43 } }
[[units]]
type = "rrp"
name = "slider"
pin = "E"
rod = "rod"
length = 50.0
new = "S"
slider = "block"
guide_point = "F"
guide_angle_deg = 0.0
variable = "block_x"
branch = 1
"""


def test_6_a_six_bar_from_the_docs(tmp_path):
    path = tmp_path / "six.toml"
    path.write_text(SIX_BAR)
    out = run(["check", path], code=0)
    assert "checked" in out.stdout and "proved" in out.stdout
    assert check_reference(sewmech.load_machine(path)).status == "ok"
    out = run(["kinematics", path, "--phi-deg", "30"], code=0)
    assert "q block_x" in out.stdout and "(constant)" not in out.stdout  # values at 30 deg
    out = run(["kinematics", path, "--step-deg", "10"], code=0)  # a turn: the summary
    assert "q block_x" in out.stdout and "(constant)" in out.stdout  # (its frame points)
    assert "unwrapped" in out.stdout
    m = sewmech.load_machine(path)
    # the polar point is read as (length cos, length sin)
    assert m.defaults[m.parameter_index("E.u")] == pytest.approx(31.62 * math.cos(
        math.radians(18.43)))


NEWCOMER = [  # (case, file change to the six-bar, message part)
    ("length-unit", ('length_unit = "mm"', 'length_unit = "in"'), "length_unit must be \"mm\""),
    ("point-form", ("{ length = 15.0, angle_deg = 0.0 }", "{ r = 15.0, a = 0.0 }"),
     "a local point is [u, v]"),
    ("point-three", ("{ length = 15.0, angle_deg = 0.0 }", "[15.0, 0.0, 1.0]"),
     "a local point is [u, v]"),
    ("reference-pair", ('reference_angle_deg = 0.0\n', ""), "reference_link and reference_angle"),
    ("reference-unknown-link", ('reference_link = "crank"', 'reference_link = "crnk"'),
     "reference_link"),
    ("slider-too-short", ("length = 50.0", "length = 5.0"), "unit 'slider'"),
]


@pytest.mark.parametrize("case,change,part", NEWCOMER, ids=[n[0] for n in NEWCOMER])
def test_6_newcomer_mistakes(tmp_path, case, change, part):
    path = tmp_path / "six.toml"
    path.write_text(mutated(*change, text=SIX_BAR))
    out = run(["check", path], has=(part,))
    assert str(path) in out.stderr


def test_6_assembly_errors_name_file_unit_ranges_and_no_python_hint(tmp_path):
    path = tmp_path / "six.toml"
    path.write_text(mutated("length = 50.0", "length = 5.0", text=SIX_BAR))
    out = run(["kinematics", path], has=(str(path), "unit 'slider'", "fails over phi"))
    assert "on_failure" not in out.stderr
    with pytest.raises(AssemblyError) as exc:
        sewmech.kinematics(sewmech.load_machine(path), np.radians(np.arange(0, 360, 5.0)))
    assert exc.value.file == str(path) and exc.value.ranges_deg


def test_6_parameters_listed_and_set_everywhere(tmp_path):
    out = run(["check", "jb1-3", "--parameters"], code=0)
    assert "needle_bar.length" in out.stdout and '[units[1] "needle_bar"] length' in out.stdout
    out = run(["check", "jb1-3", "--set", "needle_bar.length=45"], code=0)
    assert "needle_bar.length = 45" in out.stdout
    out = run(["kinematics", "jb1-3", "--json", "--step-deg", "90", "--set",
               "needle_crank.phase=0.5deg"], code=0)
    assert json.loads(out.stdout)["phi_deg"] == [0.0, 90.0, 180.0, 270.0]
    run(["feed", "jb1-3", "--json", "--set", "feed_cam.stroke=6.5"], code=0)
    run(["dynamics", "jb1-3", "--step-deg", "90", "--set", "needle_bar.length=45"], code=0)


def test_6_assembly_errors_say_by_how_much(tmp_path):
    path = tmp_path / "six.toml"
    path.write_text(mutated("length = 50.0", "length = 5.0", text=SIX_BAR))
    out = run(["check", path], has=("unit 'slider'", "from the guide line, farther than the rod"
                                    " reaches (length 5 mm)", "mm too short"))
    assert "fails over phi" in out.stderr
    four = tmp_path / "four.toml"
    four.write_text(FOURBAR.format(**{**BENCH, "bc": 10.0, "cd": 10.0}))
    run(["kinematics", four], has=("B and D are 23 mm apart, more than the links reach"
                                   " (l1 + l2 = 20 mm): 3 mm too short",))


def test_6_results_name_failing_units():
    m = sewmech.machine_from_toml(mutated("length = 50.0", "length = 5.0", text=SIX_BAR))
    r = sewmech.kinematics(m, np.radians(np.arange(0, 360, 5.0)), on_failure="mask")
    assert not r.all_feasible
    f = r.failures()
    assert list(f.unit) == ["slider"] and list(f.reason) == ["assembly"]
    assert set(r.failure_units[~r.feasible]) == {"slider"}


def test_6_docs_cover_what_newcomers_looked_for():
    root = Path(__file__).resolve().parents[1]
    files = (root / "docs" / "machine-files.md").read_text()
    assert "length_unit" in files and "angle_deg = 30.0" in files and "guide_point" in files
    assert "reference_point" in files and "--set" in files
    readme = (root / "README.md").read_text()
    assert 'r.link("take_up_lever").theta' in readme and "--phi-deg" in readme
    errors = (root / "docs" / "errors.md").read_text()
    for cls in ("MachineFileError", "OptionError", "ParameterError", "AssemblyError",
                "OutputError"):
        assert cls in errors


def test_library_errors_are_sewmech_errors():
    # every error class a user can meet is a SewmechError with where/message/hint
    for cls in (MachineFileError, OptionError, ParameterError, OutputError, AssemblyError):
        assert issubclass(cls, SewmechError)
    e = OutputError("--out x", "is a file", "Give a directory")
    assert str(e) == "--out x: is a file. Give a directory" and e.hint == "Give a directory"


# ---- class 7 (issue 29, item 4): every number that enters in range; none leaves as NaN --------
#
# Problem, sweep, tolerance and measurement files and the options once took NaN, infinity and
# numbers no machine has, and gave NaN or Infinity back (`optimize --json` printed bare NaN,
# `level-change` minus infinity, `trial-balance` +nan dB). Each case asserts exit code 2, the
# located message, no traceback and the user's files byte for byte unchanged; the cases that
# run (exit 0) assert that no NaN or Infinity leaves, and that an undefined figure says why.

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SWING = (EXAMPLES / "problems" / "fourbar-swing.toml").read_text(encoding="utf-8")
LIFT = (EXAMPLES / "problems" / "feed-lift.toml").read_text(encoding="utf-8")
SMALL_SWEEP = (EXAMPLES / "sweeps" / "jb-feed-small.toml").read_text(encoding="utf-8")
TOLERANCES = (EXAMPLES / "tolerances" / "jb1-3-feed.toml").read_text(encoding="utf-8")
VIBRATION = (EXAMPLES / "measurements" / "bartack-1820-vibration.csv").read_text(
    encoding="utf-8")
TRIALS = (EXAMPLES / "measurements" / "trial-runs.csv").read_text(encoding="utf-8")


def no_nan(text: str) -> None:
    """No NaN or infinity in a command's output, in any spelling Python or JSON gives them."""
    for token in ("NaN", "Infinity", "nan", "inf dB", "+inf", "-inf"):
        assert token not in text, (token, text[-2000:])


def run_file(tmp_path, name, text, argv, has):
    """Write a user's file, run the command on it: exit 2 with the file and ``has`` in the
    message, no traceback, the user's files unchanged, nothing written."""
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    before = snapshot(tmp_path)
    out = run([a if a != "FILE" else path for a in argv], has=(str(path), *has), cwd=tmp_path)
    assert snapshot(tmp_path) == before
    no_nan(out.stdout)
    return out


PROBLEM_NUMBERS = [  # (case, base text, old, new, message parts)
    ("target-nan", SWING, "target = 0.9 ", "target = nan ",
     ("[objective.parts[0]] target", "finite")),
    ("target-inf", SWING, "target = 0.9 ", "target = -inf ", ("target", "finite")),
    ("target-huge", SWING, "target = 0.9 ", "target = 1e300 ", ("target", "1e+06")),
    ("weight-nan", SWING, "target = 0.9 ", "target = 0.9\nweight = nan\n", ("weight",)),
    ("weight-negative", SWING, "target = 0.9 ", "target = 0.9\nweight = -1.0\n",
     ("weight", "0 .. 1e+06")),
    ("weight-huge", SWING, "target = 0.9 ", "target = 0.9\nweight = 1e9\n", ("weight",)),
    ("weights-all-zero", SWING, "target = 0.9 ", "target = 0.9\nweight = 0.0\n",
     ("[objective]", "weight 0")),
    ("scale-zero", SWING, "target = 0.9 ", "target = 0.9\nscale = 0.0\n",
     ("scale", "1e-06 .. 1e+06")),
    ("scale-inf", SWING, "target = 0.9 ", "target = 0.9\nscale = inf\n", ("scale", "finite")),
    ("lower-nan", SWING, "lower = 8.0", "lower = nan", ("[variables[0]] lower", "finite")),
    ("upper-inf", SWING, "upper = 18.0", "upper = inf", ("[variables[0]] upper", "finite")),
    ("upper-huge", SWING, "upper = 18.0", "upper = 1e7", ("upper", "1e+06")),
    ("start-nan", SWING, "upper = 18.0", "upper = 18.0\nstart = nan", ("start", "finite")),
    ("length-below-domain", LIFT, "lower = 7.0", "lower = -7.0",
     ("[variables] 1.lower", "lift_cam.arc0.radius", "a length must be positive")),
    ("min-nan", LIFT, "min = 1.3", "min = nan", ("[constraints[0]] min", "finite")),
    ("max-inf", LIFT, "max = 1.4", "max = inf", ("[constraints[0]] max", "finite")),
    ("max-huge", LIFT, "max = -0.3", "max = -1e300", ("[constraints[2]] max", "1e+06")),
    ("min-above-max", LIFT, "min = 1.3", "min = 1.5", ("[constraints[0]]", "min <= max")),
    ("regulator-nan", LIFT, "regulator_deg = 0.0", "regulator_deg = nan",
     ("regulator_deg", "finite")),
    ("regulator-huge", LIFT, "regulator_deg = 0.0", "regulator_deg = 1e300",
     ("regulator_deg", "-360 .. 360")),
    ("phi-inf", SWING, 'metric = "range:theta_rocker"',
     'metric = "range:theta_rocker"\nphi_deg = inf', ("phi_deg", "finite")),
    ("unknown-metric", SWING, "range:theta_rocker", "theta_rockr",
     ("[objective.parts] 0.metric", "unknown metric", "theta_rocker")),
]


@pytest.mark.parametrize("case,base,old,new,has", PROBLEM_NUMBERS,
                         ids=[c[0] for c in PROBLEM_NUMBERS])
def test_7_problem_file_numbers(tmp_path, case, base, old, new, has):
    run_file(tmp_path, "p.toml", mutated(old, new, base),
             ["optimize", "FILE", "--method", "slsqp", "--json"], has)


SWEEP_NUMBERS = [  # (case, old, new, message parts)
    ("lower-nan", "lower = 1.0", "lower = nan", ("[parameters[0]] lower", "finite")),
    ("upper-inf", "upper = 1.6", "upper = inf", ("[parameters[0]] upper", "finite")),
    ("lower-huge", "lower = 7.8", "lower = -1e300", ("[parameters[1]] lower", "1e+06")),
    ("radius-below-domain", "lower = 7.8", "lower = -7.8",
     ("[parameters] 1.lower", "a length must be positive")),
    ("min-nan", "min = 3.6", "min = nan", ("[outputs[0]] min", "finite")),
    ("max-inf", "max = 4.2", "max = inf", ("[outputs[0]] max", "finite")),
    ("min-above-max", "min = 1.2", "min = 1.6", ("[outputs[1]]", "min <= max")),
    ("regulator-inf", "regulator_deg = 30.0", "regulator_deg = inf", ("regulator_deg",)),
    ("rpm-zero", "step_deg = 5.0", "step_deg = 5.0\nrpm = 0.0", ("[dynamics] rpm",)),
    ("rpm-tiny", "step_deg = 5.0", "step_deg = 5.0\nrpm = 1e-300", ("[dynamics] rpm", "0.001")),
    ("rpm-nan", "step_deg = 5.0", "step_deg = 5.0\nrpm = nan", ("[dynamics] rpm", "finite")),
    ("curve-input-nan", "inputs = { regulator = 30.0 }", "inputs = { regulator = nan }",
     ("[curves] inputs.regulator", "finite")),
    ("seed-huge", 'method = "grid"', 'method = "grid"\nseed = 99999999999',
     ("[sampling] seed",)),
]


@pytest.mark.parametrize("case,old,new,has", SWEEP_NUMBERS, ids=[c[0] for c in SWEEP_NUMBERS])
def test_7_sweep_file_numbers(tmp_path, case, old, new, has):
    run_file(tmp_path, "s.toml", mutated(old, new, SMALL_SWEEP),
             ["sweep", "FILE", "--out", tmp_path / "out", "--workers", "0"], has)
    assert not (tmp_path / "out").exists()


TOLERANCE_NUMBERS = [  # (case, old, new, message parts)
    ("tolerance-nan", '"feed_cam.arc0.radius" = 0.01', '"feed_cam.arc0.radius" = nan',
     ("[parameters] feed_cam.arc0.radius", "finite")),
    ("tolerance-inf", '"feed_cam.arc0.cx" = 0.01', '"feed_cam.arc0.cx" = inf',
     ("feed_cam.arc0.cx", "finite")),
    ("tolerance-huge", '"feed_cam.arc0.cx" = 0.01', '"feed_cam.arc0.cx" = 1e300',
     ("[parameters]", "at most 10")),
    ("tolerance-negative", '"feed_cam.arc0.cx" = 0.01', '"feed_cam.arc0.cx" = -0.01',
     ("[parameters]", "finite number >= 0")),
    ("cost-nan", '"feed_cam.arc3.cx" = 2.0', '"feed_cam.arc3.cx" = nan',
     ("[cost] feed_cam.arc3.cx", "finite")),
    ("cost-huge", '"feed_cam.arc3.cx" = 2.0', '"feed_cam.arc3.cx" = 1e300',
     ("[cost]", "cost weight")),
    ("angle-inf", "angle_deg = 0.05", "angle_deg = inf", ("[defaults] angle_deg", "finite")),
    ("angle-huge", "angle_deg = 0.05", "angle_deg = 45.0",
     ("[defaults] angle_deg", "at most 10 deg")),
]


@pytest.mark.parametrize("case,old,new,has", TOLERANCE_NUMBERS,
                         ids=[c[0] for c in TOLERANCE_NUMBERS])
def test_7_tolerance_file_numbers(tmp_path, case, old, new, has):
    text = mutated(old, new, TOLERANCES)
    run_file(tmp_path, "tol.toml", text, ["tolerance", "jb1-3", "--output", "stitch_length",
                                          "--tolerances", "FILE", "--samples", "100", "--json"],
             has)
    run_file(tmp_path, "tol.toml", text, ["sensitivity", "jb1-3", "--output", "stitch_length",
                                          "--tolerances", "FILE", "--json"], has)


MEASUREMENT_NUMBERS = [  # (case, base, command, old, new, message parts)
    ("velocity-huge", VIBRATION, "trial-balance", "205.6,7.468,4.735", "205.6,1e300,4.735",
     (":10", "column vx_mm_s", "0 .. 1e+06 mm/s")),
    ("velocity-inf", VIBRATION, "trial-balance", "205.6,7.468,4.735", "205.6,7.468,inf",
     (":10", "column vy_mm_s", "not a number")),
    ("velocity-nan", VIBRATION, "trial-balance", "185,6.967,5.304", "185,nan,5.304",
     (":13", "column vx_mm_s")),
    ("static-moment-negative", VIBRATION, "trial-balance", "85,5.206,7.489", "-85,5.206,7.489",
     ("column s_add_gcm", "0 .. 1e+06 g cm")),
    ("static-moment-huge", VIBRATION, "trial-balance", "85,5.206,7.489", "8.5e9,5.206,7.489",
     ("column s_add_gcm",)),
    ("amplitude-huge", TRIALS, "influence-balance", "0,front-x@2000,1.9805,",
     "0,front-x@2000,1e7,", (":8", "column amplitude_mm_s", "0 .. 1e+06 mm/s")),
    ("phase-huge", TRIALS, "influence-balance", "1.9805,-144.79,", "1.9805,-1e300,",
     ("column phase_deg", "-360 .. 360 deg")),
    ("trial-mass-huge", TRIALS, "influence-balance", "1,front-x@2000,1.0923,-134.29,30,0",
     "1,front-x@2000,1.0923,-134.29,3e9,0", ("column trial_gcm",)),
    ("trial-angle-nan", TRIALS, "influence-balance", "1.0923,-134.29,30,0",
     "1.0923,-134.29,30,nan", ("column trial_angle_deg", "not a number")),
]


@pytest.mark.parametrize("case,base,command,old,new,has", MEASUREMENT_NUMBERS,
                         ids=[c[0] for c in MEASUREMENT_NUMBERS])
def test_7_measurement_numbers(tmp_path, case, base, command, old, new, has):
    run_file(tmp_path, "m.csv", mutated(old, new, base), [command, "FILE", "--json"], has)


OPTION_RANGES = [  # (case, argv, message parts)
    ("level-tiny-huge", ["level-change", "1e-300", "1e300"], ("BEFORE", "1e-06 .. 1e+06 mm/s")),
    ("level-subnormal", ["level-change", "5e-324", "1"], ("BEFORE",)),
    ("level-zero", ["level-change", "1", "0"], ("AFTER", "needs a velocity > 0")),
    ("level-huge", ["level-change", "1", "1e7", "--json"], ("AFTER",)),
    ("rpm-subnormal", ["dynamics", "jb1-3", "--rpm", "5e-324", "--json"],
     ("--rpm", "0.001 .. 100000 rev/min")),
    ("rpm-tiny", ["dynamics", "jb1-3", "--rpm", "1e-170"], ("--rpm",)),
    ("rpm-below", ["kinematics", "jb1-3", "--rpm", "1e-4"], ("--rpm",)),
    ("band-zero", ["tolerance", "jb1-3", "--output", "stitch_length", "--band", "0"],
     ("--band", "1e-06 .. 1000")),
    ("band-nan", ["tolerance", "jb1-3", "--output", "stitch_length", "--band", "nan"],
     ("--band",)),
    ("band-huge", ["tolerance", "jb1-3", "--output", "stitch_length", "--band", "1e300"],
     ("--band",)),
    ("seed-negative", ["tolerance", "jb1-3", "--output", "stitch_length", "--seed", "-1"],
     ("--seed", "0 .. 4294967295")),
    ("seed-huge", ["optimize", EXAMPLES / "problems" / "fourbar-swing.toml", "--seed",
                   "99999999999"], ("--seed",)),
    ("weight-nan", ["balance", "jb1-3", "--criterion", "weighted", "--weight",
                    "peak_force_N=nan"], ("--weight", "0 .. 1e+06")),
    ("weight-huge", ["balance", "jb1-3", "--criterion", "weighted", "--weight",
                     "peak_force_N=1e300"], ("--weight",)),
]


@pytest.mark.parametrize("case,argv,has", OPTION_RANGES, ids=[c[0] for c in OPTION_RANGES])
def test_7_option_ranges(tmp_path, case, argv, has):
    out = run(argv, has=has, cwd=tmp_path)
    no_nan(out.stdout)
    assert list(tmp_path.iterdir()) == []


LOADS = JB[JB.index("[[loads]]"):JB.index("\n# The feed bar rests on the lift roller")]


@pytest.mark.parametrize("old,new,part", [
    ("force_N = 2.94", "force_N = nan", "finite"),
    ("force_N = 14.7", "force_N = 1e300", "within +-100000 N"),
    ("force_N = 7.35", "force_N = -2e5", "within +-100000 N"),
], ids=["nan", "huge", "ten-tonnes"])
def test_7_load_file_forces(tmp_path, old, new, part):
    run_file(tmp_path, "loads.toml", mutated(old, new, LOADS),
             ["dynamics", "jb1-3", "--loads", "FILE", "--json"], ("force_N", part))


def test_7_machine_speed_range(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(mutated("rpm = 1000.0 ", "rpm = 1e-200 "))
    run(["check", path], has=(str(path), "[speed] rpm", "0.001"))
    with pytest.raises(OptionError, match="rpm"):
        sewmech.kinematics(sewmech.load_machine("jb1-3"), [0.0], rpm=1e-170)


def test_7_the_slowest_speed_computes_finite_figures():
    """At --rpm 0.001 every figure is a number: the reduced inertia is J(phi) of the motion's
    ratios, not 2 T / omega^2 of squares that leave the range of floats; and in Python, a
    prescribed speed so slow that omega^2 underflows (1e-170 rad/s) still assembles (the loop
    units' predictor no longer divides by omega^2 = 0) and gives the same J(phi)."""
    from sewmech.dynamics import inverse_dynamics

    out = run(["dynamics", "jb1-3", "--rpm", "0.001", "--step-deg", "30", "--json"], code=0)
    no_nan(out.stdout)
    rows = json.loads(out.stdout)["positions"]
    assert all(r["reduced_inertia_kgm2"] is not None for r in rows)
    m = sewmech.load_machine("jb1-3")
    phi = np.radians(np.arange(0.0, 360.0, 30.0))
    J = inverse_dynamics(m, phi).reduced_inertia
    assert [r["reduced_inertia_kgm2"] * 1e6 for r in rows] == pytest.approx(J, rel=1e-9)
    slow = inverse_dynamics(m, phi, omega=1e-170)
    np.testing.assert_allclose(slow.reduced_inertia, J, rtol=1e-12)
    np.testing.assert_allclose(slow.kin.p, inverse_dynamics(m, phi).kin.p, atol=1e-8)
    rest = inverse_dynamics(m, phi, omega=0.0)
    assert np.isnan(rest.reduced_inertia).all()  # at rest: no ratios, said so in the JSON


def test_7_a_rate_channel_is_a_metric_not_an_infinite_objective(tmp_path):
    """A rate channel in an objective was accepted and gave the objective Infinity (its
    derivative was asked of the positions' sensitivities); it is now evaluated, with its exact
    derivative."""
    path = tmp_path / "p.toml"
    path.write_text(mutated('metric = "range:theta_rocker"\ntarget = 0.9',
                            'metric = "omega_rocker"\nphi_deg = 30.0\ntarget = 10.0', SWING))
    out = run(["optimize", path, "--method", "slsqp", "--json"], code=0)
    no_nan(out.stdout)
    data = json.loads(out.stdout)
    assert data["objective"] is not None and data["objective_start"] is not None
    assert data["objective_parts"][0]["unit"] == "rad/s"


def test_7_an_undefined_objective_is_null_with_its_reason(tmp_path):
    """A start that does not assemble: the objective is not defined there. JSON: null and a
    note; the table: "undefined" and why; the page: the same words."""
    path = tmp_path / "p.toml"
    path.write_text(mutated("upper = 18.0", "upper = 40.0\nstart = 39.0", SWING))
    out = run(["optimize", path, "--method", "slsqp", "--json"], code=0)
    no_nan(out.stdout)
    data = json.loads(out.stdout)
    assert data["objective_start"] is None and "does not assemble" in \
        data["objective_start_note"]
    assert data["status"] == "failed"
    part = data["objective_parts"][0]
    assert part["start"] is None and "not defined" in part["start_note"]
    assert "value" not in part  # (start and answer; the part's value was given twice)
    if None in data["history"]:
        assert "history_note" in data
    out = run(["optimize", path, "--method", "slsqp", "--out", tmp_path / "rep"], code=0)
    no_nan(out.stdout)
    assert "objective undefined (the design does not assemble" in " ".join(out.stdout.split())
    page = (tmp_path / "rep" / "index.html").read_text(encoding="utf-8")
    assert "undefined (the design does not assemble" in " ".join(page.split())
    no_nan(re.sub(r"data:image/[a-z+]+;base64,[A-Za-z0-9+/=]+", "", page))  # (the figures)
    no_nan((tmp_path / "rep" / "optimize.json").read_text(encoding="utf-8"))


def test_7_lines_crossing_at_zero_velocity_say_the_level_is_undefined(tmp_path):
    """trial-balance printed "+nan dB" (and JSON NaN) when the fitted lines cross at 0 mm/s."""
    path = tmp_path / "zero.csv"
    path.write_text("s_add_gcm,vx_mm_s,vy_mm_s\n0,0,2\n0,0,2.1\n1,0,0\n1,0,0.1\n2,0,0\n2,0,0\n")
    before = snapshot(tmp_path)
    out = run(["trial-balance", path, "--json"], code=0)
    no_nan(out.stdout)
    data = json.loads(out.stdout)
    assert data["s_add_gcm"] == pytest.approx(1.6829268, abs=1e-6)  # g cm, the crossing
    assert data["level_change_db"] is None
    assert "velocity of 0 mm/s at the crossing" in data["level_change_note"]
    out = run(["trial-balance", path, "--out", tmp_path / "fit"], code=0)
    no_nan(out.stdout)
    assert "level change against S_add = 0 g cm: undefined (the fitted lines give a velocity" \
        in " ".join(out.stdout.split())
    no_nan((tmp_path / "fit" / "trial-balance.json").read_text(encoding="utf-8"))
    assert {k: v for k, v in snapshot(tmp_path).items() if not k.startswith("fit")} == before


def test_7_the_feed_at_the_zero_mark_says_why_it_has_no_mid_feed():
    out = run(["feed", "jb1-3"], code=0)
    no_nan(out.stdout)
    assert "undefined" in out.stdout
    assert "mid_feed_deg undefined at regulator 0 deg: the dog does not pass the middle" in \
        " ".join(out.stdout.split())
    out = run(["feed", "jb1-3", "--json"], code=0)
    zero = next(r for r in json.loads(out.stdout)["settings"] if r["regulator_deg"] == 0.0)
    assert zero["mid_feed_deg"] is None and "no feed" in zero["mid_feed_deg_note"]


def test_7_a_monte_carlo_without_a_design_says_why(monkeypatch):
    """Tolerances wider than the mechanism can be made within: no design drawn assembles, and
    the Monte Carlo's figures (mean, std, ...) are null with a note, not NaN (std of one design
    was NaN, of none an error of numpy's)."""
    from sewmech.design import tolerances as T

    real = T.sample_values

    def none_assemble(machine, metric, P, **kw):
        vals, how = real(machine, metric, P, **kw)
        vals = np.array(vals, dtype=float)
        vals[1:] = np.nan
        return vals, how

    monkeypatch.setattr(T, "sample_values", none_assemble)
    out = run(["tolerance", "jb1-3", "--output", "stitch_length", "--samples", "100", "--json"],
              code=0)
    no_nan(out.stdout)
    mc = json.loads(out.stdout)["monte_carlo"]
    assert mc["assembled"] == 0 and mc["std"] is None and mc["mean"] is None
    assert "no design of the 100 drawn assembles" in mc["note"]
    out = run(["tolerance", "jb1-3", "--output", "stitch_length", "--samples", "100"], code=0)
    no_nan(out.stdout)
    assert "Monte Carlo (100 designs): undefined (no design" in " ".join(out.stdout.split())


def test_7_json_is_strict_and_a_stray_nan_is_an_internal_error(monkeypatch, tmp_path):
    """Every command's JSON is strict: a NaN that ever reached it would stop the command as the
    bug it is (exit 70, naming where), never print the bare NaN JSON readers refuse."""
    import io

    from sewmech.app.files.io import dump_json
    from sewmech.design import vibration

    fh = io.StringIO()
    dump_json({"a": [1.0, {"b": 2.0}]}, fh)
    assert json.loads(fh.getvalue()) == {"a": [1.0, {"b": 2.0}]}
    with pytest.raises(RuntimeError, match=r"a non-finite number at a\[1\]\.b"):
        dump_json({"a": [1.0, {"b": float("nan")}]}, io.StringIO())
    monkeypatch.setattr(vibration, "level_db", lambda v, ref=vibration.V_REF_MM_S: np.inf)
    out = run(["level-change", "1", "2", "--json"], code=70, cwd=tmp_path)
    assert "internal error" in out.stderr and "before_db" in out.stderr
    no_nan(out.stdout)


# ---- class 8: the second hostile round (issue 29) ---------------------------------------------
#
# A hostile tester ran 140 cases against the command line. Each case below failed before: a
# traceback, an internal error, a false error, a figure no machine can have returned as an
# answer, or an option dropped without a word. Each asserts the exit code, the located line,
# no traceback, and the user's files unchanged.


def _sub(argv, *, env=None, stdout=subprocess.PIPE, preexec_fn=None, cwd=None):
    """The ``sewmech`` command in a process of its own (what the in-process runner cannot
    give: a closed stdout, a pipe without reader, a full device, the environment at import)."""
    return subprocess.run(_cli() + [str(a) for a in argv], stdout=stdout, stderr=subprocess.PIPE,
                          env={**os.environ, **(env or {})}, preexec_fn=preexec_fn, cwd=cwd,
                          timeout=300)


def _one_error_line(err: bytes, *parts: str) -> str:
    text = err.decode()
    assert text.startswith("error: ") and text.count("\n") == 1, text
    assert "Traceback" not in text and "internal error" not in text, text
    for part in parts:
        assert part in text, (part, text)
    return text


@pytest.mark.parametrize("argv", [["level-change", "1", "2", "--json"],
                                  ["level-change", "1", "2"]], ids=["json", "table"])
def test_8_a_closed_stdout_is_one_located_line_whatever_the_output(tmp_path, argv):
    """B1: `--json` with stdout closed (`>&-`) was an internal error (exit 70: sys.stdout is
    None), a table went nowhere with exit 0. Both now stop before any work, located."""
    p = _sub(argv, preexec_fn=lambda: os.close(1), stdout=None, cwd=tmp_path)
    assert p.returncode == 2
    _one_error_line(p.stderr, "stdout: is closed", "> /dev/null")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv", [["check", "fourbar-benchmark", "--parameters"],
                                  ["kinematics", "fourbar-benchmark", "--json"]],
                         ids=["table", "json"])
def test_8_a_reader_that_went_away_ends_both_outputs_with_141(argv):
    """#87: `check ... | head -1` ended with exit 1 and no word (rich's own exit on a broken
    pipe), `kinematics --json | head` with 141. Both end quietly with 141 now, as SIGPIPE
    would end them."""
    r, w = os.pipe()
    os.close(r)  # the reader is gone before the first line
    try:
        p = _sub(argv, stdout=w)
    finally:
        os.close(w)
    assert p.returncode == 141, p.stderr.decode()
    assert p.stderr == b""


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs Linux's /dev/full")
@pytest.mark.parametrize("argv", [["kinematics", "fourbar-benchmark"],
                                  ["kinematics", "fourbar-benchmark", "--json"]],
                         ids=["table", "json"])
def test_8_stdout_on_a_full_device_is_located(argv):
    """#88: `> /dev/full` gave `error: No space left on device` (no where, no what to do)."""
    with open("/dev/full", "w") as full:
        p = _sub(argv, stdout=full)
    assert p.returncode == 2
    _one_error_line(p.stderr, "error: stdout: ", "the disk is full", "send the output elsewhere")


@pytest.mark.parametrize("value, part", [("0", "is 0: numba needs at least one thread"),
                                         ("abc", "is 'abc', not a whole number"),
                                         ("2.5", "not a whole number")])
def test_8_numba_num_threads_is_checked_before_numba_starts(value, part):
    """B2, #91: NUMBA_NUM_THREADS=0 gave a 17-line traceback while numba was imported, even
    for --help; =abc numba's warning with a traceback in it."""
    p = _sub(["--help"], env={"NUMBA_NUM_THREADS": value})
    assert p.returncode == 2 and p.stdout == b""
    _one_error_line(p.stderr, "error: NUMBA_NUM_THREADS: ", part, "unset it")


REPEATED = [  # (argv, the option, what the user typed)
    (["kinematics", "fourbar-benchmark", "--step-deg", "5", "--step-deg", "10"], "--step-deg",
     "--step-deg 5, --step-deg 10"),
    (["kinematics", "fourbar-benchmark", "--rpm", "1000", "--rpm=2000"], "--rpm",
     "--rpm 1000, --rpm=2000"),
    (["kinematics", "fourbar-benchmark", "--out", "a", "--out", "b"], "--out",
     "--out a, --out b"),
    (["dynamics", "jb1-3", "--gravity", "--no-gravity"], "--gravity/--no-gravity",
     "a switch counts once"),
    (["balance", "bartack-1820", "--json", "--json"], "--json", "a switch counts once"),
    (["synthesize", "motion", "--pose", "0,0,0", "--pose", "20,5,20", "--pose", "35,15,45",
      "--out", "a", "--out", "b"], "--out", "--out a, --out b"),
]


@pytest.mark.parametrize("argv, option, typed", REPEATED, ids=[r[1] + str(i) for i, r in
                                                              enumerate(REPEATED)])
def test_8_an_option_of_one_value_given_twice_is_refused(tmp_path, argv, option, typed):
    """#4: only list options (--set, --input, --weight) were checked for repeats; the last
    --rpm, --step-deg, --out or --gravity/--no-gravity won silently."""
    out = run(argv, has=(f"error: {option}: is given 2 times", typed, "Give it once"),
              cwd=tmp_path)
    assert out.stdout == ""
    assert list(tmp_path.iterdir()) == []


def test_8_list_options_stay_repeatable():
    out = run(["kinematics", "fourbar-benchmark", "--phi-deg", "10", "--phi-deg", "20",
               "--set", "B.u=16", "--set", "dyad.length1=40"], code=0)
    assert "kinematics at phi = 10, 20 deg" in " ".join(out.stdout.split())


CONTRADICTING = [  # (argv, the option named, message parts)
    (["kinematics", "fourbar-benchmark", "--phi-deg", "30", "--step-deg", "7"], "--step-deg",
     ("and --phi-deg contradict each other", "Give one of them")),
    (["dynamics", "jb1-3", "--phi-deg", "30", "--step-deg", "5"], "--step-deg",
     ("and --phi-deg contradict each other",)),
    (["kinematics", "fourbar-benchmark", "--format", "json"], "--format",
     ("no --out is given", "Give --out DIR")),
    (["embroidery-take-up", "--json", "--out", "D"], "--out", ("and --json contradict",)),
    (["sensitivity", "jb1-3", "--output", "stitch_length", "--phi-deg", "77"], "--phi-deg",
     ("stitch_length is a metric read at its own events", "Leave --phi-deg out")),
    (["tolerance", "jb1-3", "--output", "feed_lift", "--phi-deg", "77"], "--phi-deg",
     ("feed_lift is a metric",)),
    (["sensitivity", "jb1-3", "--output", "needle_top_deg", "--input", "regulator=5"],
     "--input", ("read at the machine's working setting", "Leave --input out")),
    (["tolerance", "fourbar-benchmark", "--output", "p_P_y", "--regulator-deg", "10"],
     "--regulator-deg", ("has no stitch regulator", "Leave --regulator-deg out")),
    (["tolerance", "fourbar-benchmark", "--output", "p_P_y", "--regulator-deg", "1e9"],
     "--regulator-deg", ("has no stitch regulator",)),
    (["tolerance", "jb1-3", "--output", "needle_top_deg", "--regulator-deg", "10"],
     "--regulator-deg", ("the setting would be ignored",)),
]


@pytest.mark.parametrize("argv, option, parts", CONTRADICTING,
                         ids=[f"{c[0][0]}-{c[1]}-{i}" for i, c in enumerate(CONTRADICTING)])
def test_8_an_option_that_would_be_ignored_is_refused(tmp_path, argv, option, parts):
    """#2, #5, #6, #7, #8: each was accepted with exit 0 and had no effect (an invalid --step-deg
    was not even checked)."""
    run(argv, has=(f"error: {option}: ", *parts), cwd=tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_8_the_finest_scale_marks_stay_inside_the_regulators_travel():
    """B6: `feed jb1-3 --step-mm 0.01` (documented: 0.01 .. 10 mm) blamed the shipped file:
    "input.regulator ... is 30.0014 deg: outside the range": the scale-mark search took its
    second point 0.01 deg beyond the travel's end for the last mark."""
    out = run(["feed", "jb1-3", "--step-mm", "0.01", "--json"], code=0)
    marks = json.loads(out.stdout)["scale_marks"]
    stitches = [k["stitch_mm"] for k in marks]
    assert stitches[0] == pytest.approx(-4.08) and stitches[-1] == pytest.approx(4.08)
    assert np.allclose(np.diff(stitches), 0.01)
    assert all(-30.0 <= k["regulator_deg"] <= 30.0 for k in marks)


SMALL_DOC = (Path(__file__).resolve().parents[1] / "docs" / "machine-files.md").read_text(
    encoding="utf-8")


@pytest.mark.parametrize("metric", ["needle_top_deg", "take_up_lag_deg",
                                    "needle_descent_at_take_up_top"])
def test_8_needle_and_take_up_metrics_need_no_feed_dog(tmp_path, metric):
    """B7: the needle's and the take-up's metrics (docs/accuracy.md defines them from the
    needle and the take-up alone) were refused on every machine without a feed dog: "the feed
    analyses need [sewing] feed_dog" (sensitivity, optimize, sweep)."""
    out = run(["sensitivity", "bartack-1820", "--output", metric, "--json"], code=0)
    assert json.loads(out.stdout)["output"] == metric
    problem = tmp_path / "p.toml"
    problem.write_text(f'[problem]\nname = "p"\nmachine = "bartack-1820"\n[[variables]]\n'
                       f'parameter = "take_up.length1"\nlower = 29.5\nupper = 31.0\n'
                       f'[objective]\n[[objective.parts]]\nmetric = "{metric}"\n'
                       f'target = 1.0\n', encoding="utf-8")
    out = run(["optimize", problem, "--method", "golden", "--json"], code=0)
    assert json.loads(out.stdout)["objective"] is not None
    sweep = tmp_path / "s.toml"
    sweep.write_text(f'[sweep]\nname = "s"\nmachine = "bartack-1820"\n[sampling]\n'
                     f'method = "grid"\n[[parameters]]\nparameter = "take_up.length1"\n'
                     f'lower = 29.9\nupper = 30.5\npoints = 3\n[[outputs]]\n'
                     f'metric = "{metric}"\n', encoding="utf-8")
    out = run(["sweep", sweep, "--out", tmp_path / "sw", "--workers", "0"], code=0)
    assert "feasible: 3 of 3 designs" in out.stdout
    # how the designs were evaluated: no feed metric to locate on this machine
    assert "assembly decided on the 10 deg grid for 3 designs" in " ".join(out.stdout.split())
    assert "located from predicted events 0 times" in " ".join(out.stdout.split())


def test_8_an_answer_proved_to_assemble_is_not_called_undefined(tmp_path):
    """B8: SLSQP stops on its assembly-margin constraint to within its tolerance (2e-10 mm
    inside the searches' 0.01 mm clearance). The answer was then "failed: the design does not
    assemble over the whole turn" while the same output said "assembles over the whole turn =
    1 met" and `check` proved it. The table was right: the status and the objective are now
    judged by the same exact proof."""
    path = tmp_path / "p1.toml"
    path.write_text(mutated('target = 0.9 ', 'target = 3.0 ',
                            mutated("upper = 18.0", "upper = 36.0", SWING)), encoding="utf-8")
    out = run(["optimize", path, "--method", "slsqp", "--json"], code=0)
    data = json.loads(out.stdout)
    assembles = data["constraints"]["assembles over the whole turn"]
    assert assembles["satisfied"] and data["status"] == "success", data
    assert data["objective"] is not None and "objective_note" not in data
    assert data["x"]["B.u"] == pytest.approx(32.99, abs=1e-6)
    run(["check", "fourbar-benchmark", "--set", f"B.u={data['x']['B.u']!r}"], code=0)


def test_8_a_trial_run_that_changes_nothing_measurable_is_no_answer(tmp_path):
    """B9: a trial run that changed the reading by 1e-9 deg of phase gave a correction of
    1.719e12 g cm (17,000 t at 1 cm) as the answer; only an exact zero change was refused."""
    path = tmp_path / "ib.csv"
    path.write_text("run,place,amplitude_mm_s,phase_deg,trial_gcm,trial_angle_deg\n"
                    "0,a,1,0,0,0\n1,a,1,1e-9,30,0\n", encoding="utf-8")
    for solver in ("lsq", "minmax"):
        out = run_file(tmp_path, "ib.csv", path.read_text(), ["influence-balance", "FILE",
                                                              "--solver", solver, "--json"],
                       ("the trial mass of run 1 (30 g cm) changes the readings by",
                        "less than the 1 % a vibration meter resolves", "10 % or more"))
        assert out.stdout == ""
    # one plane of two whose trial hardly moved anything (0.1 %): named, and the mass it needs
    rows = [r for r in TRIALS.splitlines() if r[:1].isdigit()]
    base = {r.split(",")[1]: r.split(",") for r in rows if r.startswith("0,")}
    text = "run,place,amplitude_mm_s,phase_deg,trial_gcm,trial_angle_deg\n" + "\n".join(
        [r for r in rows if not r.startswith("2,")]
        + [f"2,{p},{float(b[2]) * 1.001!r},{b[3]},30,90" for p, b in base.items()]) + "\n"
    run_file(tmp_path, "ib2.csv", text, ["influence-balance", "FILE"],
             ("do not tell the planes apart: the trial mass of run 2 (30 g cm) changes the"
              " readings by 0.1 %", "(about 3e+03 g cm)"))
    # the shipped example still balances
    out = run(["influence-balance", EXAMPLES / "measurements" / "trial-runs.csv", "--json"],
              code=0)
    assert json.loads(out.stdout)["corrections"]["run 1"]["static_moment_gcm"] == \
        pytest.approx(60.0, rel=0.05)


@pytest.mark.parametrize("scale", [1e-20, 1e-300, 1e3])
def test_8_trial_balance_does_not_depend_on_the_size_of_the_static_moments(tmp_path, scale):
    """B10: static moments of 1e-300 g cm gave numpy's bare "error: Singular matrix", of 1e-20
    a false "the x and y lines do not cross" (the fit was not scale-free). Scaled, the shipped
    example gives the same crossing, scaled."""
    lines = VIBRATION.splitlines()
    body = [ln if not ln[:1].isdigit() else
            f"{float(ln.split(',')[0]) * scale!r},{ln.split(',', 1)[1]}" for ln in lines]
    path = tmp_path / "v.csv"
    path.write_text("\n".join(body) + "\n", encoding="utf-8")
    if scale * 300 > 1e6:  # beyond the range a static moment can have: refused where it enters
        run(["trial-balance", path], has=(str(path), "column s_add_gcm"))
        return
    out = run(["trial-balance", path, "--json"], code=0)
    no_nan(out.stdout)
    data = json.loads(out.stdout)
    assert data["s_add_gcm"] / scale == pytest.approx(141.77223932, rel=1e-9)
    assert [c / scale for c in data["ci95_gcm"]] == pytest.approx([139.7797816, 143.7486015],
                                                                   rel=1e-8)
    tiny = tmp_path / "tiny.csv"
    tiny.write_text("s_add_gcm,vx_mm_s,vy_mm_s\n1e-300,5,6\n2e-300,6,5\n3e-300,7,4\n")
    run(["trial-balance", tiny], has=(str(tiny), "1 measurement(s) below and 2 above the"
                                      " crossing at 1.5e-300 g cm"))


@pytest.mark.parametrize("command, text, where, part", [
    ("trial-balance", "s_add_gcm,s_add_gcm,vx_mm_s,vy_mm_s\n100,999,5,6\n150,999,5.5,5.5\n"
     "200,999,6,5\n", ":1", "the header names column(s) s_add_gcm more than once"),
    ("influence-balance", "run,place,amplitude_mm_s,phase_deg,trial_gcm,trial_angle_deg\n"
     "0,a,1,0,0,0\n1.5,a,2,0,30,0\n", ":3", "column run: '1.5' is not a run number"),
    ("influence-balance", "run,place,amplitude_mm_s,phase_deg,trial_gcm,trial_angle_deg\n"
     "0,,1,0,0,0\n1,,2,0,30,0\n", ":2", "column place is empty"),
], ids=["duplicate-column", "run-1.5", "empty-place"])
def test_8_measurement_files_say_which_column_and_line(tmp_path, command, text, where, part):
    """#110: a header naming a column twice used one of the two silently; #113: a run labelled
    1.5 (the docs: "Label the runs 0, 1, 2, ...") and empty place names were accepted."""
    out = run_file(tmp_path, "m.csv", text, [command, "FILE"], (where, part))
    assert out.stdout == ""


def test_8_sweep_workers_are_bounded_by_the_cores(tmp_path):
    """B11: `sweep --workers 1000` on 2 cores was accepted (up to 4096): no progress in 120 s,
    then four tracebacks of worker processes on SIGTERM."""
    from sewmech.app.sweep_run import WORKERS_PER_CORE, default_workers

    most = WORKERS_PER_CORE * default_workers()
    path = tmp_path / "s.toml"
    path.write_text(SMALL_SWEEP, encoding="utf-8")
    before = snapshot(tmp_path)
    run(["sweep", path, "--out", tmp_path / "o", "--workers", str(most + 1)],
        has=(f"error: --workers: must be in 0 .. {most} on this machine", "usable core",
             "--scheduler"))
    run(["sweep", path, "--out", tmp_path / "o", "--workers", "1000"], has=("--workers",))
    assert snapshot(tmp_path) == before


LOAD_ON_SELF = """[[loads]]
name = "self"
link = "needle_bar"
point = "needle.point"
force_N = 5.0
toward = ["needle.point", "needle.point"]
"""


def _small_machine() -> str:
    """The complete small machine of docs/machine-files.md (the tester's small.toml)."""
    text = SMALL_DOC[SMALL_DOC.index("```toml\n") + 8:]
    return text[:text.index("```")]


@pytest.mark.parametrize("where", ["load-file", "machine-file"])
def test_8_a_load_toward_its_own_point_is_refused_where_it_is_read(tmp_path, where):
    """B5: `toward = [its own point]` gave NaN forces as nulls with exit 0 (numpy's "invalid
    value encountered in divide"), "All-NaN slice encountered" or scipy's message in a report,
    and `check` called the file valid."""
    machine = tmp_path / "small.toml"
    machine.write_text(_small_machine(), encoding="utf-8")
    run(["check", machine], code=0)
    if where == "load-file":
        run_file(tmp_path, "ld.toml", LOAD_ON_SELF, ["dynamics", machine, "--loads", "FILE",
                                                     "--step-deg", "30", "--json"],
                 ('[loads[0] "self"] toward', "must differ from its point", "angle_deg"))
    else:
        run_file(tmp_path, "m.toml", _small_machine() + "\n" + LOAD_ON_SELF, ["check", "FILE"],
                 ('[loads[0] "self"] toward', "must differ from its point"))


def test_8_a_load_on_the_frame_says_what_to_name(tmp_path):
    """#71: `link = "frame"` said "has no moving link 'frame'. Did you mean frame?"."""
    machine = tmp_path / "small.toml"
    machine.write_text(_small_machine(), encoding="utf-8")
    out = run_file(tmp_path, "ld.toml", LOAD_ON_SELF.replace('link = "needle_bar"',
                                                             'link = "frame"'),
                   ["dynamics", machine, "--loads", "FILE"],
                   ('[loads[0] "self"] link', "a load on the frame moves nothing",
                    "Name the moving link it acts on: needle_crank"))
    assert "Did you mean frame" not in out.stderr


@pytest.mark.parametrize("host, part", [
    ("999.1.1.1", "is neither an address nor a name that resolves"),
    ("nonexistent.invalid", "is neither an address nor a name that resolves"),
    ("", "is empty: the server would listen on every network interface"),
    (" ", "is empty"),
])
def test_8_serve_host_mistakes_are_the_hosts(host, part):
    """#16, #17: `--host 999.1.1.1` was reported against --port ("Choose another --port");
    `--host ""` listened on every interface and printed `http://:PORT/`."""
    out = run(["serve", "fourbar-benchmark", "--host", host, "--port", "0"],
              has=("error: --host: ", part, "127.0.0.1"))
    assert out.stdout == ""


def test_8_serve_reads_its_file_again_when_a_page_opens_it(tmp_path):
    """#20: `serve FILE` read the file once: after an edit on disk, new pages still showed the
    old text and Export TOML returned it (saving it over the file lost the edit)."""
    from serve_helpers import call, running_server

    from sewmech.engine.spec import read_toml_text

    path = tmp_path / "m.toml"
    path.write_text(FB, encoding="utf-8")
    name = "fourbar (m.toml)"
    with running_server({name: ("m.toml", read_toml_text(path))}, name,
                        {name: path}) as url:
        def opened():
            status, body = call(f"{url}/api/sessions", {"machine": name})
            assert status == 200, body
            return body

        def bc(body):
            return next(p["value"] for p in body["machine"]["parameters"]
                        if p["name"] == "dyad.length1")

        first = opened()
        assert bc(first) == pytest.approx(BENCH["bc"])
        path.write_text(FB.replace(f"lengths = [{BENCH['bc']}", "lengths = [41.0"),
                        encoding="utf-8")
        second = opened()
        assert bc(second) == pytest.approx(41.0)
        status, text = call(f"{url}/api/sessions/{second['session']}/export.toml", {"set": {}})
        assert status == 200 and "lengths = [41.0" in text
        # the page opened before keeps its own text (docs/serve.md says so)
        status, text = call(f"{url}/api/sessions/{first['session']}/export.toml", {"set": {}})
        assert status == 200 and "lengths = [41.0" not in text
        path.write_text("[machine]\nname = 3\n", encoding="utf-8")
        status, body = call(f"{url}/api/sessions", {"machine": name})
        assert status == 422 and body["error"]["where"] == "m.toml: [machine] name", body
        path.unlink()  # deleted: served as last read
        status, body = call(f"{url}/api/sessions", {"machine": name})
        assert status == 422  # (the last text read is the broken one)
        path.write_text(FB, encoding="utf-8")
        assert bc(opened()) == pytest.approx(BENCH["bc"])
        path.unlink()
        assert bc(opened()) == pytest.approx(BENCH["bc"])


@pytest.mark.parametrize("command", [["sensitivity", "jb1-3", "--output", "stitch_length"],
                                     ["tolerance", "jb1-3", "--output", "stitch_length",
                                      "--samples", "100"]])
def test_8_a_setting_from_set_is_blamed_on_set(command):
    """#32: `--set input.regulator=0deg` was refused as "--input: ... e.g. --input
    regulator=30", an option that was not given."""
    out = run(command + ["--set", "input.regulator=0deg"],
              has=("error: --set: stitch_length at regulator 0 deg",
                   "--set input.regulator=30deg (the machine's working setting)"))
    assert "--input" not in out.stderr and "--regulator-deg" not in out.stderr


@pytest.mark.parametrize("old, new, where, part", [
    ("[masses.crank]", "[masses.ghost]", "[masses.ghost]",
     "Name the table [masses.LINK] after a moving link: crank, coupler, rocker"),
    ('[counterweights.cw]\nlink = "crank"', '[counterweights.cw]\nlink = "frame"',
     "[counterweights.cw] link", "'frame' is not a moving link: masses and counterweights on"
     " it enter no inertia force. Give a moving link: crank, coupler, rocker"),
], ids=["masses-of-no-link", "counterweight-on-the-frame"])
def test_8_a_table_on_no_moving_link_lists_the_links(tmp_path, old, new, where, part):
    """#40: `[masses.ghost]` and a counterweight on the frame said only "'ghost' is not a
    moving link of this machine." (no what to do, no list)."""
    text = FB + ("\n[masses.crank]\nmass = 0.1\ncom = [5.0, 0.0]\ninertia_zz = 10.0\n"
                 '\n[counterweights.cw]\nlink = "crank"\nmass_g = 5.0\nat_mm = [-10.0, 0.0]\n')
    (tmp_path / "ok.toml").write_text(text, encoding="utf-8")
    run(["check", tmp_path / "ok.toml"], code=0)
    run_file(tmp_path, "m.toml", mutated(old, new, text), ["check", "FILE"], (where, part))


@pytest.mark.parametrize("old, new, part", [
    ('reference_event = "crank along +x"', 'reference_event = "crank along +x"\n'
     'reference_point = "B"\nreference_extreme = "up"',
     "[convention] reference_extreme: must be 'top', 'bottom', 'left' or 'right', got 'up'."
     " Give one of them"),
    ('name = "fourbar"', 'name = 3', "[machine] name: must be a string, got 3. Write it in"
     " quotes"),
], ids=["literal", "string"])
def test_8_file_values_of_the_wrong_kind_say_what_to_give(tmp_path, old, new, part):
    """#50: `reference_extreme = "up"` gave pydantic's `Input should be 'top', ...` and
    `format = 2` `Input should be 1 (got 2)`: without the what-to-do."""
    out = run_file(tmp_path, "m.toml", mutated(old, new, FB), ["check", "FILE"], (part,))
    assert "Input should be" not in out.stderr


def test_8_check_refuses_a_fabric_the_needle_never_passes(tmp_path):
    """#52: `fabric_thickness = 100`: `check` said valid, `report` refused it."""
    run_file(tmp_path, "m.toml", mutated("fabric_thickness = 1.0", "fabric_thickness = 100.0",
                                         _small_machine()), ["check", "FILE"],
             ("[sewing] fabric_thickness", "never passes plate_y + fabric_thickness"))


def test_8_variants_are_checked_and_read_beside_their_file(tmp_path, monkeypatch):
    """#54, #55: `variants = ["nonexistent-machine"]` passed `check`, and `report` failed with
    an error that named neither the file nor `[machine] variants`; a file in `variants` was
    read relative to the working directory, not to the machine file."""
    d = tmp_path / "machines"
    d.mkdir()
    small = _small_machine()
    (d / "other.toml").write_text(mutated('name = "small-machine"', 'name = "other"', small),
                                  encoding="utf-8")
    path = d / "m.toml"
    path.write_text(mutated('title = "', 'variants = ["other.toml"]\ntitle = "', small),
                    encoding="utf-8")
    run(["check", path], code=0, cwd=tmp_path)  # other.toml is beside m.toml, not in the cwd
    path.write_text(mutated('title = "', 'variants = ["nonexistent-machine"]\ntitle = "',
                            small), encoding="utf-8")
    before = snapshot(tmp_path)
    for command in (["check", path], ["report", path, "--out", tmp_path / "r"]):
        run(command, has=(f"{path}: [machine] variants[0]: nonexistent-machine: no such file",
                          "a path relative to this file"), cwd=tmp_path)
    assert snapshot(tmp_path) == before
    path.write_text(mutated('title = "', 'variants = ["m.toml"]\ntitle = "', small),
                    encoding="utf-8")
    run(["check", path], has=("[machine] variants[0]: 'm.toml' is the machine reported again",),
        cwd=tmp_path)


@pytest.mark.parametrize("compare, part", [
    ("SELF", "is the machine reported again"),
    ("fourbar-benchmark", "--compare fourbar-benchmark: cannot be compared: machine"
     " 'fourbar-benchmark'"),
])
def test_8_compare_mistakes_are_the_compare_options(tmp_path, compare, part):
    """#96, #97: `report M --compare M` drew an empty comparison with matplotlib's raw
    "No artists with labels" warning; `--compare fourbar-benchmark` failed with an error that
    did not say it came from --compare."""
    path = tmp_path / "small.toml"
    path.write_text(_small_machine(), encoding="utf-8")
    out = run(["report", path, "--compare", path if compare == "SELF" else compare, "--out",
               tmp_path / "r"], has=("error: --compare ", part))
    assert "Warning" not in out.stderr and not (tmp_path / "r").exists()


@pytest.mark.slow
def test_8_machines_without_a_feed_are_compared_by_their_figures_alone(tmp_path):
    """#96: two machines without a feed dog: the comparison is their key figures (a table and
    its CSV), not two empty axes."""
    path, other = tmp_path / "small.toml", tmp_path / "two.toml"
    path.write_text(_small_machine(), encoding="utf-8")
    other.write_text(mutated("rpm = 1000.0", "rpm = 900.0", mutated(
        'name = "small-machine"', 'name = "small-two"', _small_machine())), encoding="utf-8")
    out = run(["report", path, "--compare", other, "--out", tmp_path / "r", "--step-deg", "2"],
              code=0)
    assert "Warning" not in out.stderr
    page = (tmp_path / "r" / "index.html").read_text(encoding="utf-8")
    assert "none of them has a feed dog" in page
    assert (tmp_path / "r" / "small-machine-comparison.csv").is_file()
    assert not (tmp_path / "r" / "small-machine-comparison.png").exists()


@pytest.mark.parametrize("argv, starts", [
    (["optimize", EXAMPLES / "problems" / "fourbar-swing.toml", "--method", "golden", "--json"],
     "{"),
    (["optimize", EXAMPLES / "problems" / "fourbar-swing.toml", "--method", "nsga2", "--json"],
     ""),
], ids=["answer", "error"])
def test_8_json_on_stdout_is_the_json_alone(argv, starts):
    """#119: `optimize --json` (and `tolerance --json`) printed a blank line before the JSON
    (the progress display's), and only that blank line on an error."""
    out = run(argv, code=0 if starts else 2)
    assert out.stdout[:1] == starts
    if starts:
        json.loads(out.stdout)


def test_8_a_problems_machine_is_located_in_the_problem_file(tmp_path):
    """#122: `machine = "."` gave "error: .: is a directory", naming neither the problem file
    nor [problem] machine."""
    run_file(tmp_path, "p.toml", mutated('machine = "fourbar-benchmark"', 'machine = "."',
                                         SWING), ["optimize", "FILE"],
             ("[problem] machine: '.' is neither a machine file beside the problem file",
              "fourbar-benchmark"))


def test_8_a_sweep_output_the_machine_cannot_give_is_refused_at_once(tmp_path):
    """#128: `needle_top_deg` on a machine without [sewing] passed the file check; every chunk
    then failed three times and an empty sweep directory was left behind."""
    text = ('[sweep]\nname = "s"\nmachine = "fourbar-benchmark"\n[sampling]\nmethod = "grid"\n'
            '[[parameters]]\nparameter = "B.u"\nlower = 14.0\nupper = 16.0\npoints = 3\n'
            '[[outputs]]\nmetric = "needle_top_deg"\n')
    run_file(tmp_path, "s.toml", text, ["sweep", "FILE", "--out", tmp_path / "o", "--workers",
                                        "0"],
             ("[outputs] 0.metric: needle_top_deg needs a [sewing] table",))
    assert not (tmp_path / "o").exists()


def test_8_a_sweep_whose_every_chunk_fails_leaves_no_empty_directory(tmp_path, monkeypatch):
    """#128: the SweepError was raised after the scope that removes a directory the run made
    and wrote no chunk into."""
    from sewmech.app import sweep_run

    def broken(*args, **kwargs):
        raise ValueError("the metric cannot be formed")

    monkeypatch.setattr(sweep_run, "evaluate_chunk", broken)
    path = tmp_path / "s.toml"
    path.write_text(SMALL_SWEEP, encoding="utf-8")
    run(["sweep", path, "--out", tmp_path / "o", "--workers", "0", "--retries", "0"],
        has=("chunks failed after 1 attempt each", "the metric cannot be formed",
             "the directory this run made is removed again"))
    assert not (tmp_path / "o").exists()


def _a_sweep(tmp_path) -> tuple[Path, Path]:
    path = tmp_path / "s.toml"
    path.write_text('[sweep]\nname = "s"\nmachine = "fourbar-benchmark"\n[sampling]\n'
                    'method = "grid"\n[[parameters]]\nparameter = "B.u"\nlower = 14.0\n'
                    'upper = 16.0\npoints = 6\n[[outputs]]\nmetric = "range:theta_rocker"\n',
                    encoding="utf-8")
    d = tmp_path / "sw"
    run(["sweep", path, "--out", d, "--workers", "0", "--chunk", "2"], code=0)
    return path, d


def test_8_a_chunk_cut_short_says_how_to_have_it_computed_again(tmp_path):
    """#126: a truncated chunk made `sweep-summary` and the resuming `sweep` fail with
    pyarrow's "Parquet magic bytes not found in footer", without a place or a way out."""
    path, d = _a_sweep(tmp_path)
    chunk = d / "chunks" / "chunk-000001.parquet"
    chunk.write_bytes(chunk.read_bytes()[:100])
    for argv in (["sweep-summary", d], ["sweep", path, "--out", d, "--workers", "0"]):
        run(argv, has=(f"error: {chunk}: is not a whole chunk of the sweep",
                       "Delete this file and run the same `sewmech sweep` command again"))
    chunk.unlink()
    out = run(["sweep", path, "--out", d, "--workers", "0"], code=0)
    assert "1 chunks computed" in out.stdout


def test_8_a_summary_inside_the_sweep_directory_keeps_it_resumable(tmp_path):
    """#84: `sweep-summary D --out D/sweep-summary`, as sweep-summary itself suggests, made D
    impossible to resume ("holds 1 file(s) that sewmech did not write (sweep-summary)")."""
    path, d = _a_sweep(tmp_path)
    run(["sweep-summary", d, "--out", d], has=(f"--out {d / 'sweep-summary'}",))
    run(["sweep-summary", d, "--out", d / "sweep-summary"], code=0)
    (d / "chunks" / "chunk-000002.parquet").unlink()  # a chunk still to compute
    out = run(["sweep", path, "--out", d, "--workers", "0"], code=0)
    assert "2 found done, 1 chunks computed" in out.stdout
    # a directory of the user's there still stops it
    (d / "mine").mkdir()
    run(["sweep", path, "--out", d, "--workers", "0"], has=("that sewmech did not write",
                                                            "mine"))


def test_8_feed_says_its_timing_is_undefined_and_gives_the_rest(tmp_path):
    """#136: `feed jb1-3 --set lift_cam.arc0.cx=30` ended with "the feed timing did not settle;
    check the feed mechanism" (no where) and none of the feed figures it had."""
    out = run(["feed", "jb1-3", "--set", "lift_cam.arc0.cx=30", "--json"], code=0)
    no_nan(out.stdout)
    data = json.loads(out.stdout)
    assert data["feed_cam_phase_for_mid_feed_at_top_deg"] is None
    assert "no phase of the feed cam puts the middle of the feed stroke" in \
        data["feed_cam_phase_for_mid_feed_at_top_deg_note"]
    assert len(data["settings"]) == 3 and data["scale_marks"]
    out = run(["feed", "jb1-3", "--set", "lift_cam.arc0.cx=30"], code=0)
    assert "is undefined (no phase of the feed cam" in " ".join(out.stdout.split())


def test_8_a_machine_name_too_long_for_a_file_name_is_said(tmp_path):
    """#60: a 300-character [machine] name with --out gave the OSError of a staging temporary
    file ("File name too long"), not what is too long or what to do."""
    long = "m" * 300
    path = tmp_path / "m.toml"
    path.write_text(mutated('name = "fourbar"', f'name = "{long}"', FB), encoding="utf-8")
    before = snapshot(tmp_path)
    out = run(["kinematics", path, "--out", tmp_path / "o"],
              has=(f"--out {tmp_path / 'o'}: a file name of the result is too long",
                   "mmm...mmm", "-kinematics.csv", "give it a shorter [machine] name"))
    assert ".sewmech-staging" not in out.stderr and ".tmp" not in out.stderr
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("kind", ["dangling", "loop"])
def test_8_out_a_symlink_to_nowhere_is_said(tmp_path, kind):
    """#77: `--out` a dangling symbolic link or a loop of links: "cannot write there (File
    exists)"."""
    link = tmp_path / "link"
    if kind == "dangling":
        link.symlink_to(tmp_path / "nowhere")
        part = f"is a symbolic link to {tmp_path / 'nowhere'}, which does not exist"
    else:
        (tmp_path / "other").symlink_to(link)
        link.symlink_to(tmp_path / "other")
        part = "a symbolic link in a loop of links"
    before = snapshot(tmp_path)
    for argv in (["kinematics", "fourbar-benchmark", "--out", link],
                 ["report", "jb1-3", "--out", link]):
        run(argv, has=(f"error: --out {link}: ", part))
    assert snapshot(tmp_path) == before and not (tmp_path / "nowhere").exists()


def test_8_another_machines_files_are_not_the_previous_run(tmp_path):
    """#78: `kinematics A --out D`, then `kinematics B --out D` deleted A's file without a
    word: files of another machine are not "the same command's previous run"."""
    d = tmp_path / "mix"
    small = tmp_path / "small.toml"
    small.write_text(_small_machine(), encoding="utf-8")
    run(["kinematics", "fourbar-benchmark", "--out", d], code=0)
    run(["kinematics", small, "--out", d], code=0)
    assert {"fourbar-benchmark-kinematics.csv", "small-machine-kinematics.csv"} <= set(
        os.listdir(d))
    run(["kinematics", "fourbar-benchmark", "--out", d, "--format", "json"], code=0)
    names = set(os.listdir(d))  # the same machine's previous run is replaced, as before
    assert "fourbar-benchmark-kinematics.json" in names
    assert "fourbar-benchmark-kinematics.csv" not in names
    assert "small-machine-kinematics.csv" in names
    manifest = json.loads((d / ".sewmech-manifest.json").read_text())["files"]
    assert manifest["small-machine-kinematics.csv"]["machine"] == "small-machine"


def test_8_the_papers_s_add_is_the_counterweights_static_moment(tmp_path):
    """#103: a file's extra counterweight at 1000 g cm printed "S_add -865 g cm" (and JSON
    -865.0): the difference from the file's value, a static moment no counterweight has."""
    text = (Path(sewmech.shipped_machines()["bartack-1820"])).read_text(encoding="utf-8")
    at = text.index("[counterweights.extra]")
    key = text.index("static_moment_gcm = ", at)
    end = text.index("\n", key)
    path = tmp_path / "m.toml"
    path.write_text(text[:key] + "static_moment_gcm = 1000.0" + text[end:], encoding="utf-8")
    out = run(["balance", path, "--step-deg", "2", "--json"], code=0)
    data = json.loads(out.stdout)
    s = data["counterweights"]["extra"]["static_moment_gcm"]
    assert data["paper"]["s_add_gcm"] == pytest.approx(s) and s > 0
    out = run(["balance", path, "--step-deg", "2"], code=0)
    assert f"S_add {s:.4g} g cm" in out.stdout and "S_add -" not in out.stdout


def test_8_the_papers_method_is_not_applied_to_a_coupler(tmp_path):
    """#105: `--criterion delta-q` on a counterweight on a coupler printed "S_1 200 g cm (the
    shaft's crank, all its solids)" about the coupler, and angles as "-0 deg"."""
    text = FB + ('\n[masses.coupler]\nmass = 0.1\ncom = [20.0, 0.0]\ninertia_zz = 20.0\n'
                 '[masses.crank]\nmass = 0.1\ncom = [5.0, 0.0]\ninertia_zz = 10.0\n'
                 '[masses.rocker]\nmass = 0.1\ncom = [15.0, 0.0]\ninertia_zz = 10.0\n'
                 '[counterweights.dyad]\nlink = "coupler"\nmass_g = 5.0\nat_mm = [10.0, 0.0]\n')
    path = tmp_path / "m.toml"
    path.write_text(text, encoding="utf-8")
    out = run(["balance", path, "--criterion", "delta-q", "--step-deg", "2"], code=0)
    flat = " ".join(out.stdout.split())
    assert "S_1 " not in flat and "the shaft's crank" not in flat
    assert "the balancing paper's method (S_1, S_add, the built counterweight) is for a" \
        " counterweight on a crank that turns with the upper shaft; 'dyad' is on 'coupler'" \
        in flat
    assert "-0 deg" not in flat and " -0 " not in flat
    data = json.loads(run(["balance", path, "--criterion", "delta-q", "--step-deg", "2",
                           "--json"], code=0).stdout)
    assert "paper" not in data and "is on 'coupler'" in data["paper_note"]


def test_8_check_proves_the_thread_guides_apart(tmp_path):
    """#66: two thread guides on one spot: `check` said valid, and `optimize` of a thread
    metric failed with "thread guides 0 and 1 overlap" (no file, no table)."""
    text = mutated('[points."thread.check_post"] # check-spring stud, a 2 mm pin the thread'
                   ' wraps anticlockwise\nx = 68.0                     # on its way up to the'
                   ' take-up eye (the eye stays left of and above\ny = -25.0',
                   '[points."thread.check_post"]\nx = 65.0\ny = -45.0')
    run_file(tmp_path, "m.toml", text, ["check", "FILE"],
             ("[thread] guides[0]: 'thread.tension' and the next guide, 'thread.check_post',"
              " overlap at phi = ", "Move the guides apart"))


@pytest.mark.parametrize("old, new, part", [
    ("[masses.needle_link]\nmass = 0.015\ncom = [22.5, 0.0]",
     "[masses.needle_link]\nmass = 0.015\ncom = [1e8, 0.0]",
     "[masses.needle_link] com: puts the centre of mass 1e+08 mm from the link's origin"),
    ("[masses.needle_link]\nmass = 0.015\n", '[masses.needle_link]\nmaterial = "steel"\n'
     "solids = []\n#", "[masses.needle_link]: solids = [] holds no solid"),
], ids=["com-1e8", "solids-empty"])
def test_8_mass_tables_no_part_can_have(tmp_path, old, new, part):
    """#59: `com = [1e8, 0]` was reported as "the equilibrium equations are singular (a
    mechanism at a dead centre ...); step around this angle"; #58: `solids = []` as
    "compose() needs at least one part" (an internal function's name, no what to do)."""
    text = mutated(old, new, _small_machine())
    if "solids" in new:  # (the table's measured values out: solids instead)
        text = mutated("\ninertia_zz = 3.0\n", "\n", text)
    run_file(tmp_path, "m.toml", text, ["check", "FILE"], (part,))
    run_file(tmp_path, "m.toml", text, ["dynamics", "FILE", "--step-deg", "30"], (part,))


def test_8_a_librarys_value_error_is_a_bug_not_a_users_mistake(monkeypatch, tmp_path):
    """B10 (the point behind it): a ValueError of numpy or scipy that reached the command was
    printed as a user's mistake, `error: Singular matrix` with exit 2: no place, nothing to do.
    It is a bug of sewmech's (it should have refused the input first): exit 70, said so; a
    ValueError sewmech raises itself stays a located user error."""
    from sewmech.design import vibration

    monkeypatch.setattr(vibration, "crossing",
                        lambda *a, **k: np.linalg.inv(np.zeros((2, 2))))
    path = tmp_path / "v.csv"
    path.write_text(VIBRATION, encoding="utf-8")
    out = run(["trial-balance", path], code=70)
    assert "internal error (LinAlgError: Singular matrix)" in out.stderr
    run(["feed", "fourbar-benchmark"], has=("error: machine 'fourbar-benchmark'",
                                            "the feed analyses need"))
