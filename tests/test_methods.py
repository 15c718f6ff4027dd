"""The JB kinematics report's optimisation methods (sewmech.design.methods) against scipy and
known optima: a unimodal function, Rosenbrock's valley, a constrained quadratic whose optimum is
a projection, and the two weighting forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq, minimize, minimize_scalar

from sewmech.design.methods import (
    GOLDEN,
    cyclic_coordinate,
    golden_section,
    golden_trials,
    interior_penalty,
    powell,
    weighted_sum,
    weighted_uniform,
)


def unimodal(x):
    return (x - 2.0) ** 2 + math.exp(0.3 * x)


def test_golden_section_against_scipy_and_its_trial_count():
    r = golden_section(unimodal, -5.0, 7.0, tol=1e-9)
    ref = minimize_scalar(unimodal, bounds=(-5.0, 7.0), method="bounded",
                          options={"xatol": 1e-12})
    # the true minimum: f'(x) = 2 (x - 2) + 0.3 e^(0.3 x) = 0. A search that compares values
    # finds it to about sqrt(machine epsilon) of its scale, where f stops changing
    true = brentq(lambda x: 2.0 * (x - 2.0) + 0.3 * math.exp(0.3 * x), 0.0, 2.0, xtol=1e-15)
    assert r.x[0] == pytest.approx(true, abs=1e-7)
    assert ref.x == pytest.approx(true, abs=1e-7)
    # the report's estimate of the trial points: the interval shrinks by 0.618 per point
    assert abs(r.nfev - golden_trials(-5.0, 7.0, 1e-9)) <= 1
    assert 12.0 * GOLDEN ** (r.nfev - 1) < 1e-9
    with pytest.raises(ValueError, match="a < b"):
        golden_section(unimodal, 3.0, 1.0)


def rosenbrock(x):
    return (1.0 - x[0]) ** 2 + 100.0 * (x[1] - x[0] ** 2) ** 2


@pytest.mark.parametrize("method", [cyclic_coordinate, powell])
def test_rosenbrock_valley(method):
    r = method(rosenbrock, [-1.2, 1.0], step=0.1, tol=1e-12, maxiter=20000)
    assert r.success, r.message
    np.testing.assert_allclose(r.x, [1.0, 1.0], atol=2e-4)
    ref = minimize(rosenbrock, [-1.2, 1.0], method="Powell", options={"xtol": 1e-10,
                                                                       "ftol": 1e-14})
    np.testing.assert_allclose(r.x, ref.x, atol=2e-4)
    assert r.history[-1] == r.fun and r.history[0] > r.fun


def test_powell_finds_a_quadratics_minimum_in_n_rounds():
    """On a positive definite quadratic the directions become conjugate: n + 1 rounds (the last
    confirms) reach the minimum, where cyclic search zig-zags."""
    A = np.array([[4.0, 1.9, 0.3], [1.9, 2.0, 0.5], [0.3, 0.5, 1.0]])
    b = np.array([1.0, -2.0, 0.5])

    def q(x):
        return 0.5 * x @ A @ x - b @ x

    r = powell(q, np.zeros(3), step=1.0, tol=1e-12)
    np.testing.assert_allclose(r.x, np.linalg.solve(A, b), atol=1e-7)
    c = cyclic_coordinate(q, np.zeros(3), step=1.0, tol=1e-12, maxiter=5000)
    assert r.nit < c.nit


@pytest.mark.parametrize("inner", ["powell", "cyclic"])
def test_interior_penalty_on_a_constrained_quadratic(inner):
    """min (x - 2)^2 + (y - 1)^2 subject to x + y <= 2 and x >= 0: the optimum is (2, 1)
    projected on x + y = 2, (1.5, 0.5); SLSQP agrees."""
    def f(v):
        return (v[0] - 2.0) ** 2 + (v[1] - 1.0) ** 2

    def g(v):
        return np.array([2.0 - v[0] - v[1], v[0]])

    r = interior_penalty(f, g, [0.5, 0.5], method=inner, tol=1e-9)
    assert r.success, r.message
    np.testing.assert_allclose(r.x, [1.5, 0.5], atol=1e-4)
    assert np.all(r.constr >= 0) and r.constr[0] < 1e-3
    ref = minimize(f, [0.5, 0.5], method="SLSQP",
                   constraints=[{"type": "ineq", "fun": g}])
    np.testing.assert_allclose(r.x, ref.x, atol=1e-4)
    with pytest.raises(ValueError, match="strictly feasible"):
        interior_penalty(f, g, [3.0, 0.5])


def test_weighting_forms():
    f1 = lambda x: (x[0] - 1.0) ** 2 + 1.0
    f2 = lambda x: (x[0] + 1.0) ** 2 + 1.0
    x0 = np.array([3.0])
    s = weighted_sum([f1, f2], [1.0, 1.0], x0)
    # normalised by the start values 5 and 17: the optimum of f1/5 + f2/17 is x = (17 - 5)/22
    r = golden_section(lambda t: s(np.array([t])), -3.0, 3.0, tol=1e-10)
    assert r.x[0] == pytest.approx((17.0 - 5.0) / 22.0, abs=1e-7)
    u = weighted_uniform([f1, f2], [1.0, 2.0], [1.0, 1.0], [1.0, 1.0])
    # max((x-1)^2, 2 (x+1)^2): equal where x - 1 = -sqrt(2) (x + 1)
    r = golden_section(lambda t: u(np.array([t])), -3.0, 3.0, tol=1e-10)
    assert r.x[0] == pytest.approx((1.0 - math.sqrt(2.0)) / (1.0 + math.sqrt(2.0)), abs=1e-7)
