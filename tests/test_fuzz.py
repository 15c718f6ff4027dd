"""Property-based fuzzing of the command line with mutated shipped files (hypothesis): numbers,
keys, types and structure are changed, and no command may print a traceback or an internal
error (exit 70), exit 0 with a non-finite number, or report a design feasible that is not.

Machine files go through `check`, `kinematics` and `dynamics`; the examples' problem files
through `optimize`, sweep files through `sweep` and `sweep-summary`, the tolerance file through
`tolerance` and `sensitivity`, and the measurement files through `trial-balance` and
`influence-balance` (issue 29: these took NaN and gave it back). Their example counts are
bounded so that they add less than 30 s."""

from __future__ import annotations

import json
import math
import re
import tempfile
from pathlib import Path
from unittest import mock

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import sewmech
from sewmech.cli import app

runner = CliRunner()
SHIPPED = {n: Path(p).read_text(encoding="utf-8") for n, p in sewmech.shipped_machines().items()
           if n in ("jb1-3", "fourbar-benchmark", "embroidery-131")}
NUMBER = re.compile(r"(?<![\w.\"])-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?![\w.\"])")
KEY = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\s*=", re.MULTILINE)

NUMBERS = st.sampled_from(["nan", "inf", "-inf", "0", "0.0", "-0.0", "-1.0", "1e300", "-1e300",
                           "1e-300", "1e9", "1e6", "0.0001", "2", "-45.0", "720.0"]) | \
    st.floats(min_value=-1e4, max_value=1e4, allow_nan=False).map(repr)
OTHER_TYPES = st.sampled_from(['"x"', "[1, 2]", "{ a = 1 }", "true", "[]", '""', "[[1]]"])


@st.composite
def mutation(draw, text: str) -> str:
    kind = draw(st.sampled_from(["number", "number", "number", "type", "key", "delete",
                                 "duplicate", "truncate", "swap"]))
    lines = text.splitlines(keepends=True)
    spans = [m.span() for m in NUMBER.finditer(text)]
    keys = [m.span(1) for m in KEY.finditer(text)]
    if not lines or (kind in ("number", "type") and not spans) or (kind == "key" and not keys):
        return text + draw(st.sampled_from(["\n[x]\n", "\nx = 1\n", "]]", "\0"]))
    if kind in ("number", "type"):
        a, b = draw(st.sampled_from(spans))
        new = draw(NUMBERS if kind == "number" else OTHER_TYPES)
        return text[:a] + new + text[b:]
    if kind == "key":
        a, b = draw(st.sampled_from(keys))
        key = text[a:b]
        i = draw(st.integers(0, len(key) - 1))
        new = key[:i] + draw(st.sampled_from(["", "x", "_", key[i] * 2])) + key[i + 1:]
        return text[:a] + (new or "k") + text[b:]
    if kind == "delete":
        i = draw(st.integers(0, len(lines) - 1))
        return "".join(lines[:i] + lines[i + 1:])
    if kind == "duplicate":
        i = draw(st.integers(0, len(lines) - 1))
        return "".join(lines[:i + 1] + lines[i:])
    if kind == "swap":
        i, j = draw(st.integers(0, len(lines) - 1)), draw(st.integers(0, len(lines) - 1))
        lines[i], lines[j] = lines[j], lines[i]
        return "".join(lines)
    return text[:draw(st.integers(0, len(text)))]


@st.composite
def mutated_file(draw):
    name = draw(st.sampled_from(sorted(SHIPPED)))
    text = SHIPPED[name]
    for _ in range(draw(st.integers(1, 3))):
        text = draw(mutation(text))
    return name, text


def _invoke(args):
    out = runner.invoke(app, [str(a) for a in args])
    text = out.stdout + out.stderr
    assert out.exit_code in (0, 2), (args, out.exit_code, text[-3000:])
    assert "Traceback" not in text and "internal error" not in text, text[-3000:]
    assert out.exception is None or isinstance(out.exception, SystemExit), repr(out.exception)
    if out.exit_code == 2:
        assert out.stderr.startswith("error: "), out.stderr
    return out


def _finite(values) -> bool:
    if isinstance(values, list):
        return all(_finite(v) for v in values)
    return isinstance(values, (int, float)) and math.isfinite(values)


@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(mutated_file())
def test_mutated_machine_files_never_crash_nor_pass_nan(case):
    name, text = case
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"{name}.toml"
        path.write_text(text, encoding="utf-8")
        out = _invoke(["check", path, "--step-deg", "10"])
        if out.exit_code != 0:
            assert str(path) in out.stderr  # the error names the file
            return
        # the file passed check: its kinematics assembles everywhere, every value finite
        out = _invoke(["kinematics", path, "--json", "--step-deg", "10"])
        assert out.exit_code == 0, out.stderr
        data = json.loads(out.stdout)
        assert all(data["feasible"])
        for channel in data["channels"].values():
            assert _finite(channel["values"]), channel
        m = sewmech.load_machine(path)
        if m.spec.masses:
            out = _invoke(["dynamics", path, "--json", "--step-deg", "30"])
            if out.exit_code == 0:
                rows = json.loads(out.stdout)["positions"]
                assert all(_finite(r["input_torque_Nm"]) for r in rows)
                assert all(_finite(r["shaking_force_N"]) for r in rows)


# ---- the design files and measurements (issue 29, item 4) ---------------------------------------

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
PROBLEMS = {p.name: p.read_text(encoding="utf-8")
            for p in sorted((EXAMPLES / "problems").glob("*.toml"))}
SWEEP = (EXAMPLES / "sweeps" / "jb-feed-small.toml").read_text(encoding="utf-8")
TOLERANCES = (EXAMPLES / "tolerances" / "jb1-3-feed.toml").read_text(encoding="utf-8")
MEASUREMENTS = {"trial-balance": (EXAMPLES / "measurements" / "bartack-1820-vibration.csv"),
                "influence-balance": (EXAMPLES / "measurements" / "trial-runs.csv")}
MEASUREMENTS = {k: p.read_text(encoding="utf-8") for k, p in MEASUREMENTS.items()}
#: how the numbers of a CSV line are mutated besides the machine files' mutations
CELLS = st.sampled_from(["nan", "inf", "-inf", "1e300", "-1e300", "5e-324", "0", "-0.0", "-1",
                         "", "x", "1e7", "720"]) | st.floats(0.0, 300.0).map(lambda x: f"{x:.4g}")
FUZZ = settings(deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _mutate(draw, text: str, times: int = 3) -> str:
    for _ in range(draw(st.integers(1, times))):
        text = draw(mutation(text))
    return text


def _strict(out) -> None:
    """A command that succeeded printed strict JSON: no NaN, no Infinity."""
    assert out.exit_code == 0
    json.loads(out.stdout, parse_constant=lambda c: (_ for _ in ()).throw(
        AssertionError(f"{c} in the output")))


def _strict_files(root: Path) -> None:
    for p in root.rglob("*.json"):
        text = p.read_text(encoding="utf-8")
        json.loads(text, parse_constant=lambda c, p=p: (_ for _ in ()).throw(
            AssertionError(f"{c} in {p}")))


def _at_start(problem, method="slsqp", *, seed=0, **kw):
    """``optimize`` without the search: the answer is the start (the searches have their own
    tests; a mutated problem on JB1-3 may search for minutes). What is fuzzed is everything
    around it: reading, checking, every figure at the start and the answer, the JSON."""
    from scipy.optimize import OptimizeResult

    from sewmech.design import optimize as O

    O.check_seed(seed)
    x = problem.start.copy()
    fx = problem.objective(x)[0] if problem.design_ok(x) else math.inf
    f = OptimizeResult(x=x, fun=fx, objective_start=fx, constraints=problem.report(x),
                       status="failed", success=False, message="the start (fuzz)",
                       n_evaluations=problem.evaluations, history=[fx], method=method)
    f.fun_note = f.objective_start_note = (None if math.isfinite(fx) else
                                           O.undefined_objective(problem, x))
    return f


@st.composite
def mutated_problem(draw):
    name = draw(st.sampled_from(sorted(PROBLEMS)))
    return name, _mutate(draw, PROBLEMS[name])


@settings(FUZZ, max_examples=40)
@given(mutated_problem())
def test_mutated_problem_files_never_crash_nor_pass_nan(case):
    name, text = case
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / name
        path.write_text(text, encoding="utf-8")
        if name == "fourbar-swing.toml":  # a search on the four-bar takes a second
            out = _invoke(["optimize", path, "--method", "slsqp", "--json"])
        else:
            with mock.patch("sewmech.design.optimize.optimize", _at_start):
                out = _invoke(["optimize", path, "--json"])
        if out.exit_code != 0:
            assert str(path) in out.stderr or out.stderr.startswith("error: --")
            return
        _strict(out)


@st.composite
def mutated_sweep(draw):
    return _mutate(draw, SWEEP, 2)


@settings(FUZZ, max_examples=16)
@given(mutated_sweep())
def test_mutated_sweep_files_never_crash_nor_pass_nan(text):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "s.toml"
        path.write_text(text, encoding="utf-8")
        out = _invoke(["sweep", path, "--out", Path(d) / "out", "--workers", "0", "--json"])
        if out.exit_code != 0:
            assert str(path) in out.stderr
            assert not (Path(d) / "out").exists() or "chunk" in out.stderr
            return
        _strict(out)
        out = _invoke(["sweep-summary", Path(d) / "out", "--json"])
        _strict(out)
        _strict_files(Path(d) / "out")


@st.composite
def mutated_tolerances(draw):
    return _mutate(draw, TOLERANCES)


@settings(FUZZ, max_examples=24)
@given(mutated_tolerances())
def test_mutated_tolerance_files_never_crash_nor_pass_nan(text):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "tol.toml"
        path.write_text(text, encoding="utf-8")
        for argv in (["tolerance", "jb1-3", "--output", "stitch_length", "--samples", "100",
                      "--band", "0.05"],
                     ["sensitivity", "jb1-3", "--output", "stitch_length"]):
            out = _invoke([*argv, "--tolerances", path, "--json"])
            if out.exit_code != 0:
                assert str(path) in out.stderr or "tolerances" in out.stderr
                return
            _strict(out)


@st.composite
def mutated_measurements(draw):
    command = draw(st.sampled_from(sorted(MEASUREMENTS)))
    text = MEASUREMENTS[command]
    for _ in range(draw(st.integers(1, 2))):
        if draw(st.integers(0, 3)) == 0:
            text = draw(mutation(text))
        else:  # a cell of a data line
            lines = text.splitlines(keepends=True)
            rows = [k for k, ln in enumerate(lines) if ln[:1].isdigit() or ln[:1] == "-"]
            if not rows:
                continue
            k = draw(st.sampled_from(rows))
            cells = lines[k].rstrip("\n").split(",")
            j = draw(st.integers(0, len(cells) - 1))
            cells[j] = draw(CELLS)
            lines[k] = ",".join(cells) + "\n"
            text = "".join(lines)
    return command, text


@settings(FUZZ, max_examples=100)
@given(mutated_measurements())
def test_mutated_measurement_files_never_crash_nor_pass_nan(case):
    command, text = case
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "m.csv"
        path.write_text(text, encoding="utf-8")
        out = _invoke([command, path, "--json"])
        if out.exit_code != 0:
            assert str(path) in out.stderr
            return
        _strict(out)
        out = _invoke([command, path])  # the lines say what is undefined, in words
        assert not re.search(r"\b(nan|inf)\b", out.stdout), out.stdout
