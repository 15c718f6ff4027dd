"""Exact derivatives of the needle-thread balance's figures (issue 18: the take-up problem with
SLSQP): against central differences of the balance itself, and the taut thread's length
against the moving guides."""

from __future__ import annotations

import numpy as np
import pytest

import sewmech
from sewmech.sewing.thread import _balance, path_length, path_length_gradient
from sewmech.sewing.thread_gradients import THREAD_FIGURES, thread_gradient

#: parameters of every part the balance reads: the take-up, the needle bar and its crank, the
#: hook drive, the thread guides
PARAMS = ("take_up.length1", "take_up.length2", "take_up.eye.u", "take_up.eye.v",
          "needle_bar.length", "needle_crank.phase", "hook_crank.phase", "big_rod.length1")


def test_the_taut_length_moves_with_each_guide_as_its_segments_turn():
    """d(length)/d(guide centre) of a path over pins of both wrap directions against central
    differences of path_length."""
    rng = np.random.default_rng(3)
    c = np.array([[0.0, 0.0], [10.0, 6.0], [22.0, -3.0], [31.0, 8.0], [40.0, 0.0]])
    rho = np.array([0.0, 2.0, -1.5, 3.0, 0.0])
    g = path_length_gradient(c, rho)
    for _ in range(5):
        dc = rng.normal(size=c.shape)
        h = 1e-6
        fd = (path_length(c + h * dc, rho) - path_length(c - h * dc, rho)) / (2 * h)
        assert np.sum(g * dc) == pytest.approx(float(fd), rel=1e-7)


@pytest.mark.parametrize("figure", sorted(THREAD_FIGURES))
def test_thread_figures_against_central_differences(figure):
    m = sewmech.load_machine("jb1-3")
    g = thread_gradient(m, figure)
    b0, _ = _balance(m, 2.5, None, 0.5, np.asarray(m.defaults))
    assert g.value == pytest.approx(getattr(b0, THREAD_FIGURES[figure]), abs=1e-12)
    P0 = np.array(m.defaults)
    checked = 0
    for name in PARAMS:
        j = m.parameter_names.index(name)
        h = 1e-6 * max(1.0, abs(P0[j]))
        vals, events = [], []
        for sign in (1.0, -1.0):
            P = P0.copy()
            P[j] += sign * h
            b, x = _balance(m, 2.5, None, 0.5, P)
            vals.append(getattr(b, THREAD_FIGURES[figure]))
            events.append((x["k_top"], x["k_s"], x["k_c"], x["k_m"], x["k_bdc"], x["k_max"]))
        if events[0] != events[1]:  # an event moved to another grid angle: a step, skip
            continue
        fd = (vals[0] - vals[1]) / (2 * h)
        assert g.d_dparam[j] == pytest.approx(fd, rel=1e-5, abs=1e-6), name
        checked += 1
    assert checked >= 6
