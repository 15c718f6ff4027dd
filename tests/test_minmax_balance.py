"""influence-balance --solver minmax (issue 33): the smallest largest residual vibration as a
linear programme, against closed forms (one plane: the smallest circle round the points
-V0_i / A_i), against scipy's SLSQP on the exact circles (t^2 >= |w r|^2), weights, limits on
the correction masses, and the command."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize
from typer.testing import CliRunner

from sewmech.cli import app
from sewmech.design.minmax_balance import influence_minmax
from sewmech.design.vibration import influence_balance, phasor

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "measurements" / "trial-runs.csv"


def _one_plane(points, a=0.03 + 0.02j):
    """Readings whose minimiser is known: with A_i = a for every row, |r_i| = |a| |U - c_i| with
    c_i the given points; the trial run (30 g cm at 0 deg) moves every reading by 30 a."""
    c = np.asarray(points, dtype=complex)
    V0 = -a * c
    Vt = (V0 + 30.0 * a)[None, :]
    return V0, Vt, [30.0], [0.0]


def test_two_readings_midpoint():
    c1, c2 = 40 + 10j, -20 + 50j
    V0, Vt, s, ang = _one_plane([c1, c2])
    r = influence_minmax(V0, Vt, s, ang)
    U = r.correction_gcm[0] * np.exp(1j * math.radians(r.correction_angle_deg[0]))
    want = abs(0.03 + 0.02j) * abs(c1 - c2) / 2
    # the LP's polygons: within its stated accuracy of the midpoint answer
    assert r.after_max <= want * (1 + r.accuracy) + 1e-15
    assert r.lower_bound <= want + 1e-12
    assert abs(U - (c1 + c2) / 2) <= abs(c1 - c2) / 2 * math.sqrt(2 * r.accuracy) * 1.01


def test_three_readings_circumcircle():
    """An acute triangle: the smallest enclosing circle is the circumcircle."""
    pts = np.array([0 + 0j, 60 + 5j, 25 + 50j])
    V0, Vt, s, ang = _one_plane(pts)
    r = influence_minmax(V0, Vt, s, ang)
    a, b, c = pts
    d = 2 * (a.real * (b.imag - c.imag) + b.real * (c.imag - a.imag) + c.real * (a.imag - b.imag))
    ux = ((abs(a) ** 2) * (b.imag - c.imag) + (abs(b) ** 2) * (c.imag - a.imag)
          + (abs(c) ** 2) * (a.imag - b.imag)) / d
    uy = ((abs(a) ** 2) * (c.real - b.real) + (abs(b) ** 2) * (a.real - c.real)
          + (abs(c) ** 2) * (b.real - a.real)) / d
    R = abs(a - (ux + 1j * uy))
    want = abs(0.03 + 0.02j) * R
    assert want / (1 + r.accuracy) - 1e-12 <= r.lower_bound <= want + 1e-12
    assert want - 1e-12 <= r.after_max <= want * (1 + r.accuracy) + 1e-12


def _slsqp(A, V0, w, limits=None, start=None):
    """min t s.t. t^2 >= |w_i r_i|^2 and |U_j|^2 <= M_j^2: the exact circles, smooth."""
    n, m = A.shape

    def split(z):
        return z[:m] + 1j * z[m:2 * m], z[-1]

    cons = [{"type": "ineq", "fun": lambda z: split(z)[1] ** 2 - np.abs(
        w * (V0 + A @ split(z)[0])) ** 2}]
    if limits is not None:
        cons.append({"type": "ineq", "fun": lambda z: limits ** 2 - np.abs(split(z)[0]) ** 2})
    z0 = start if start is not None else np.zeros(2 * m + 1)
    r = minimize(lambda z: z[-1], z0, constraints=cons, method="SLSQP",
                 options={"ftol": 1e-14, "maxiter": 500})
    U, t = split(r.x)
    return U, float(np.max(w * np.abs(V0 + A @ U)))


def _example():
    import csv

    rows = [r for r in csv.reader(line for line in EXAMPLE.read_text().splitlines()
                                  if not line.startswith("#"))][1:]
    places = list(dict.fromkeys(r[1] for r in rows))
    table = {(r[0], r[1]): phasor(float(r[2]), float(r[3])) for r in rows}
    trial = {r[0]: (float(r[4]), float(r[5])) for r in rows if r[0] != "0"}
    V0 = np.array([table["0", p] for p in places])
    Vt = np.array([[table[k, p] for p in places] for k in ("1", "2")])
    return V0, Vt, [trial["1"][0], trial["2"][0]], [trial["1"][1], trial["2"][1]], places


@pytest.mark.parametrize("weights,limits", [(None, None), ([1, 2, 1, 0.5], None),
                                            (None, [40.0, np.inf]), ([3, 1, 1, 1], [50, 20])])
def test_against_slsqp_on_the_exact_circles(weights, limits):
    V0, Vt, s, ang, _ = _example()
    r = influence_minmax(V0, Vt, s, ang, weights=weights,
                         limits_gcm=None if limits is None else limits)
    w = np.ones(4) if weights is None else np.asarray(weights, float)
    lim = None if limits is None else np.asarray(limits, float)
    U = r.correction_gcm * np.exp(1j * np.radians(r.correction_angle_deg))
    z0 = np.concatenate([U.real, U.imag, [r.after_max]])
    _, best = _slsqp(r.coefficients, V0, w, None if lim is None else np.where(
        np.isfinite(lim), lim, 1e6), z0)
    # the exact optimum lies in the reported bracket, and the bracket is as narrow as the
    # module says: the residuals' polygons cost a factor 1 / cos(pi / K), the limits' inscribed
    # polygons at most w |A| M (1 - cos(pi / K)) for each plane at its limit
    assert r.lower_bound <= best * (1 + 1e-9) + 1e-12
    assert best <= r.after_max * (1 + 1e-9)
    shrink = 0.0
    if lim is not None:
        finite = np.isfinite(lim)
        shrink = float(np.max(w[:, None] * np.abs(r.coefficients[:, finite]) * lim[finite])
                       * finite.sum() * (1 - math.cos(math.pi / r.sides)))
    assert r.after_max - r.lower_bound <= r.accuracy * r.after_max + shrink + 1e-12
    if lim is not None:
        assert np.all(r.correction_gcm <= lim + 1e-12)  # the limits hold exactly
    # the residuals the result reports are V0 + A U, recomputed
    np.testing.assert_allclose(r.residual, V0 + r.coefficients @ U, rtol=0, atol=1e-12)


def test_minmax_beats_least_squares_on_the_largest_and_loses_on_rms():
    V0, Vt, s, ang, _ = _example()
    mm = influence_minmax(V0, Vt, s, ang)
    ls = influence_balance(V0, Vt, s, ang)
    U = ls.correction_gcm * np.exp(1j * np.radians(ls.correction_angle_deg))
    ls_res = V0 + ls.coefficients @ U
    assert mm.after_max <= np.abs(ls_res).max() * (1 + mm.accuracy)
    assert np.sqrt(np.mean(np.abs(ls_res) ** 2)) <= mm.after_rms * (1 + 1e-9)


def test_a_limit_that_binds():
    V0, Vt, s, ang, _ = _example()
    free = influence_minmax(V0, Vt, s, ang)
    assert free.correction_gcm[0] > 50
    r = influence_minmax(V0, Vt, s, ang, limits_gcm=[40.0, np.inf])
    assert r.at_limit.tolist() == [True, False]
    assert 40.0 * math.cos(math.pi / r.sides) * (1 - 1e-9) <= r.correction_gcm[0] <= 40.0
    assert r.after_max > free.after_max  # the limit costs vibration


def test_bad_weights_and_limits():
    V0, Vt, s, ang, _ = _example()
    from sewmech.engine.errors import OptionError

    with pytest.raises(OptionError, match="weights"):
        influence_minmax(V0, Vt, s, ang, weights=[0, 0, 0, 0])
    with pytest.raises(OptionError, match="limit"):
        influence_minmax(V0, Vt, s, ang, limits_gcm=[-1, 10])


def test_the_command():
    run = CliRunner().invoke
    r = run(app, ["influence-balance", str(EXAMPLE), "--solver", "minmax", "--weight",
                  "front-x@2500=2", "--max-gcm", "1=40", "--json"])
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)
    assert data["solver"] == "minmax" and data["corrections"]["run 1"]["at_limit"]
    assert data["weights"]["front-x@2500"] == 2.0
    assert data["lower_bound_mm_s"] <= data["after_max_mm_s"]
    r = run(app, ["influence-balance", str(EXAMPLE), "--solver", "minmax", "--weight",
                  "front-z@2500=2"])
    assert r.exit_code == 2 and "the file has no place 'front-z@2500'. Did you mean" in r.output
    r = run(app, ["influence-balance", str(EXAMPLE), "--weight", "front-x@2500=2"])
    assert r.exit_code == 2 and "--solver minmax" in r.output
    r = run(app, ["influence-balance", str(EXAMPLE), "--solver", "minimax"])
    assert r.exit_code == 2 and "Did you mean --solver minmax" in r.output
    r = run(app, ["influence-balance", str(EXAMPLE), "--solver", "minmax", "--max-gcm", "3=5"])
    assert r.exit_code == 2 and "error: --max-gcm" in r.output
