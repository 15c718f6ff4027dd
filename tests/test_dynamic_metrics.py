"""The exact gradients of the force analysis' metrics (sewmech.design._dynamic_metrics.GRADIENTS,
issue 32): the peak and RMS driving torque, the peak force in a pair, the peak bearing reaction,
the peak shaking force and moment and the least contact force, each against central differences
of its values, one design per call and a batch of designs in one call, on a slider-crank (every
parameter) and on JB1-3 with friction, springs, process loads and a counterweight (a parameter
of every kind)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import sewmech
from sewmech.design._dynamic_metrics import GRADIENTS, ForceMetrics, has_gradient
from sewmech.design._models import DynamicsTable

ROOT = Path(__file__).resolve().parents[1]
SLIDER = ROOT / "examples" / "machines" / "slider-crank.toml"

JB_PARAMS = ("B.u", "take_up.length1", "Lp.x", "feed_cam.arc0.radius", "lift.cam.3.length",
             "extra.static_moment", "extra.angle", "needle_crank.phase",
             "feed_bar.spring_anchor.y", "feed_bar.pin.v")
JB_METRICS = ("peak_torque", "rms_torque", "peak_bearing_reaction",
              "peak_bearing_reaction:rear", "peak_shaking_force", "peak_shaking_moment",
              "peak_force:B", "least_contact_force:lift.cam")
SLIDER_METRICS = ("peak_torque", "rms_torque", "peak_force:slider.guide", "peak_force:A",
                  "peak_shaking_force", "peak_shaking_moment")


def _differences(fm: ForceMetrics, name: str, P0: np.ndarray, cols, batch: bool):
    """Central differences at h and h / 2, extrapolated (Richardson), of the metric's values
    (one design per call, or every design of the differences in one batch call)."""
    designs = []
    for j in cols:
        h = 1e-5 * max(1.0, abs(P0[j]))
        for step in (h, h / 2):
            for sign in (1.0, -1.0):
                P = P0.copy()
                P[j] += sign * step
                designs.append(P)
    X = np.array(designs)
    if batch:
        v = fm.values([name], X)[name]
    else:
        v = np.array([fm.values([name], x[None])[name][0] for x in X])
    v = v.reshape(len(cols), 2, 2)
    hs = np.array([1e-5 * max(1.0, abs(P0[j])) for j in cols])
    d1 = (v[:, 0, 0] - v[:, 0, 1]) / (2.0 * hs)
    d2 = (v[:, 1, 0] - v[:, 1, 1]) / hs
    return (4.0 * d2 - d1) / 3.0


def _check(machine, name, step_deg, cols, tol):
    fm = ForceMetrics(machine, DynamicsTable(step_deg=step_deg))
    P0 = np.asarray(machine.defaults, dtype=float)
    mv = fm.value(name, P0)
    assert mv.d is not None and has_gradient(name)
    # the exact path's value is the batch's, its pieces the grid's and its peak their extreme
    assert mv.value == pytest.approx(fm.values([name], P0[None])[name][0], rel=1e-12)
    if mv.kind is not None:
        assert len(mv.pieces) == len(fm.phi) and mv.pieces_d.shape == (len(fm.phi), len(P0))
        k = int(np.argmax(mv.pieces) if mv.kind == "max" else np.argmin(mv.pieces))
        np.testing.assert_array_equal(mv.d, mv.pieces_d[k])
    exact = mv.d[list(cols)]
    # a derivative's scale: its own size, or the metric's per unit of the parameter
    scale = np.maximum(np.abs(exact), 1e-3 * abs(mv.value)
                       / np.maximum(1.0, np.abs(P0[list(cols)])))
    for batch in (False, True):
        fd = _differences(fm, name, P0, cols, batch)
        err = np.abs(fd - exact) / scale
        assert err.max() < tol, (name, "batch" if batch else "single",
                                 machine.parameter_names[cols[int(np.argmax(err))]], err.max())
    return mv


@pytest.mark.parametrize("name", SLIDER_METRICS)
def test_slider_crank_every_parameter(name):
    # with a counterweight on the crank (the file has none: its static moment at 0 cannot be
    # stepped below)
    m = sewmech.load_machine(str(SLIDER)).with_parameters({"cw.static_moment": 0.8})
    _check(m, name, 2.0, list(range(len(m.parameter_names))), 1e-6)


@pytest.fixture(scope="module")
def jb():
    return sewmech.load_machine("jb1-3").with_parameters(
        {"extra.static_moment": 0.6, "input.regulator": math.radians(20.0)})


@pytest.mark.parametrize("name", JB_METRICS)
def test_jb13_a_parameter_of_every_kind(jb, name):
    cols = [jb.parameter_names.index(p) for p in JB_PARAMS]
    _check(jb, name, 5.0, cols, 1e-6)


def test_every_force_metric_but_the_friction_loss_has_its_gradient():
    from sewmech.design._dynamic_metrics import DYNAMIC_METRICS

    assert set(DYNAMIC_METRICS) - set(GRADIENTS) == {"friction_loss"}
