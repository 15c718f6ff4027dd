"""The metrics of problem files (sewmech.design.metrics and the force analysis' metrics) where
else a designer reads an output (issue 32): the columns of a sweep, the tolerance analysis and
`sewmech sensitivity` / `sewmech tolerance` (--output, --at). Each against the one design's
exact value (sewmech.design.evaluate.metric_value) and derivative."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from sewmech.cli import app
from typer.testing import CliRunner

from sewmech.design._dynamic_metrics import ForceMetrics
from sewmech.design._models import MetricRef
from sewmech.design.evaluate import metric_value
from sewmech.design.sweep import evaluate_chunk, params_of, sample
from sewmech.design.sweep_file import load_sweep
from sewmech.design.tolerances import metric_gradient, tolerance_analysis
from sewmech.engine.errors import MachineFileError, OptionError
from sewmech.engine.machine import load_machine

ROOT = Path(__file__).resolve().parents[1]
SLIDER = ROOT / "examples" / "machines" / "slider-crank.toml"
runner = CliRunner()

SWEEP = f"""
[sweep]
name = "slider-crank"
machine = "{SLIDER.as_posix()}"
[sampling]
method = "grid"
[[parameters]]
parameter = "slider.offset"
lower = -5.0
upper = 5.0
points = 3
[[parameters]]
parameter = "slider.length"
lower = 55.0
upper = 70.0
points = 2
[[outputs]]
metric = "max:p_C_x"
[[outputs]]
metric = "rms:v_C_x"
[[outputs]]
metric = "transmission_angle_min:slider"
min = 65.0
[[outputs]]
metric = "p_C_y"
at = "max:p_C_x"
[[outputs]]
metric = "peak_torque"
[[outputs]]
metric = "peak_force:slider.guide"
[dynamics]
step_deg = 2.0
"""


def write(tmp_path, text):
    f = tmp_path / "s.toml"
    f.write_text(text)
    return f


def test_a_sweeps_columns_are_the_one_designs_metrics(tmp_path):
    s = load_sweep(write(tmp_path, SWEEP))
    c = evaluate_chunk(s, 0, 6)
    P = params_of(s, sample(s, 0, 6))
    forces = ForceMetrics(s.machine, s.spec.dynamics)
    assert [o.column for o in s.spec.outputs][3] == "p_C_y@max:p_C_x"
    for o in s.spec.outputs:
        want = [metric_value(s.machine, o, P[k], forces=forces).value for k in range(6)]
        np.testing.assert_allclose(c.columns[o.column], want, rtol=1e-9, atol=1e-9,
                                   err_msg=o.column)
    # the limit on the transmission angle decides feasibility
    np.testing.assert_array_equal(c.columns["feasible"],
                                  c.columns["transmission_angle_min:slider"] >= 65.0)


@pytest.mark.parametrize("change, key, says", [
    (('metric = "max:p_C_x"', 'metric = "max:p_Q_x"'), "0.metric", "not a channel"),
    (('"transmission_angle_min:slider"', '"transmission_angle_min:crank"'), "2.metric",
     "not an rrr, rrp or rpr unit"),
    (('"peak_force:slider.guide"', '"peak_force:guide"'), "5.metric", "one of: O, A, C, slider.guide"),
    (('at = "max:p_C_x"', 'at = "top:p_C_x"'), "3.at", "not an event"),
    (('metric = "rms:v_C_x"', 'metric = "rms:v_C_x"\nat = "max:p_C_x"'), "1.at",
     "only a channel"),
    (("[dynamics]\nstep_deg = 2.0", ""), "4.metric", "needs a [dynamics] table"),
])
def test_a_bad_output_of_a_sweep_is_a_located_error(tmp_path, change, key, says):
    with pytest.raises(MachineFileError) as e:
        load_sweep(write(tmp_path, SWEEP.replace(*change)))
    assert f"[outputs] {key}" in str(e.value) and says in str(e.value)


def test_tolerance_analysis_of_a_metric_over_the_turn_and_at_an_event():
    m = load_machine(str(SLIDER))
    for metric, at in (("max:p_C_x", None), ("transmission_angle_deviation:slider", None),
                       ("p_C_y", "max:p_C_x")):
        ref = MetricRef(metric=metric, at=at)
        mv = metric_value(m, ref, np.asarray(m.defaults, dtype=float))
        value, d, unit = metric_gradient(m, metric, at=at)
        assert value == pytest.approx(mv.value) and unit in ("mm", "deg")
        np.testing.assert_allclose(d, mv.d, rtol=1e-12, atol=1e-12)
        res = tolerance_analysis(m, metric, samples=2000, seed=1, at=at)
        mc = res.monte_carlo
        assert mc["assembled"] == mc["n"] == 2000
        # near linear over tolerances: the Monte Carlo's spread is the RSS's to a few percent
        assert mc["std"] == pytest.approx(res.sigma, rel=0.08), metric


def test_sensitivity_and_tolerance_take_the_metrics_on_the_command_line():
    out = runner.invoke(app, ["sensitivity", str(SLIDER), "--output",
                              "transmission_angle_min:slider", "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.output)
    m = load_machine(str(SLIDER))
    mv = metric_value(m, MetricRef(metric="transmission_angle_min:slider"),
                      np.asarray(m.defaults, dtype=float))
    assert data["value"] == pytest.approx(mv.value) and data["unit"] == "deg"
    assert data["d_dparam"]["slider.length"] == pytest.approx(
        mv.d[m.parameter_names.index("slider.length")])
    out = runner.invoke(app, ["sensitivity", str(SLIDER), "--output", "v_C_x", "--at",
                              "rising:p_C_x=70", "--json"])
    assert out.exit_code == 0, out.output
    assert json.loads(out.output)["at"] == "rising:p_C_x=70"
    out = runner.invoke(app, ["tolerance", str(SLIDER), "--output", "max:p_C_x", "--samples",
                              "300", "--json"])
    assert out.exit_code == 0, out.output
    assert json.loads(out.output)["unit"] == "mm"
    for args, says in (
            (["--output", "max:p_C_x", "--phi-deg", "3"], "--phi-deg"),
            (["--output", "max:p_Q_x"], "not a channel"),
            (["--output", "stitch_length", "--at", "max:p_C_x"], "only a channel"),
            (["--output", "p_C_y", "--at", "max:v_C_x"], "position channel")):
        out = runner.invoke(app, ["sensitivity", str(SLIDER), *args])
        assert out.exit_code == 2 and says in out.output, out.output


def test_a_value_only_metric_is_refused_by_the_derivatives_with_what_to_do():
    m = load_machine(str(SLIDER))
    with pytest.raises(OptionError) as e:
        metric_gradient(m, "friction_loss")
    assert "no exact derivative" in str(e.value) and "Choose" in str(e.value)
