"""Property-based fuzzing of the command line with mutated shipped machine files (hypothesis):
numbers, keys, types and structure are changed, and `check`, `kinematics` and `dynamics` must
never print a traceback or an internal error, never exit 0 with a non-finite number, and never
report a design feasible that is not."""

from __future__ import annotations

import json
import math
import re
import tempfile
from pathlib import Path

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
