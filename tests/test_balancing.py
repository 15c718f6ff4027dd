"""Balancing: counterweights chosen by criterion, checked against closed forms and against the
whole machine evaluated again.

- a slider-crank with a counterweight opposite its crank: the balancing paper's Delta-Q = 0 at
  S = (1 + lambda) / 2 * m r and the least RMS shaking force at S = m r / 2, for several
  lambda = r / l (the slider's inertia force is m r w^2 (cos phi + lambda cos 2 phi + ...)
  along the guide; the counterweight's is S w^2 along the crank);
- a four-bar with a heavy coupler fully force-balanced by counterweights on crank and rocker
  (Berkof and Lowen's conditions, [Berkof-Lowen-1969]), where the shaking force vanishes at
  every angle;
- the linear basis against the dynamics of the whole machine for arbitrary counterweights, and
  each peak criterion's answer against a brute-force search on the whole machine.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
import pytest

from conftest import BENCH, FOURBAR, SLIDER_CRANK
from sewmech import machine_from_toml
from sewmech.design.balancing import FIGURES, balance, balance_basis, figures
from sewmech.engine.errors import AnalysisError, OptionError


def slider_crank_with_cw(r=15.0, l=44.0, m_s=0.05, radius=12.0, limit=None):
    text = SLIDER_CRANK.format(r=r, l=l, e=0.0, alpha=90.0, gx=0.0, gy=0.0, branch=1)
    text += f"""
[masses.block]
mass = {m_s}
com = [0.0, 0.0]
inertia_zz = 0.0
[counterweights.cw]
link = "crank"
static_moment_gcm = 0.0
angle_deg = 180.0
radius_mm = {radius}
"""
    if limit is not None:
        text += f"max_static_moment_gcm = {limit}\n"
    return machine_from_toml(text)


@pytest.mark.parametrize("r, l", [(15.0, 44.0), (10.0, 60.0), (20.0, 45.0)])
def test_delta_q_root_of_a_slider_crank_is_the_closed_form(r, l):
    m_s = 0.05
    res = balance(slider_crank_with_cw(r, l, m_s), "delta-q")
    lam = r / l
    expected_gcm = (1.0 + lam) / 2.0 * m_s * r * 100.0  # kg mm -> g cm
    cw = res.counterweights["cw"]
    assert res.status == "optimal"
    assert cw["static_moment_gcm"] == pytest.approx(expected_gcm, rel=1e-9)
    assert abs(abs(cw["angle_deg"]) - 180.0) < 1e-9
    assert res.after["delta_q_N"] < 1e-9 * res.before["peak_force_N"]
    assert res.before["delta_q_N"] > 1.0  # there was something to balance
    assert res.basis_error < 1e-10


@pytest.mark.parametrize("r, l", [(15.0, 44.0), (10.0, 60.0), (20.0, 45.0)])
def test_least_rms_of_a_slider_crank_is_half_the_slider(r, l):
    m_s = 0.05
    res = balance(slider_crank_with_cw(r, l, m_s), "rms")
    cw = res.counterweights["cw"]
    assert res.status == "optimal"
    assert cw["static_moment_gcm"] == pytest.approx(m_s * r / 2.0 * 100.0, rel=1e-9)
    assert abs(abs(cw["angle_deg"]) - 180.0) < 1e-9
    # the mass follows from the radius the file gives: m = S / r
    assert cw["mass_g"] == pytest.approx(m_s * r / 2.0 / 12.0 * 1000.0, rel=1e-9)
    assert res.after["rms_force_N"] < res.before["rms_force_N"]


def berkof_lowen(m2=0.08, z2=complex(18.0, 6.0), radius=10.0):
    """The benchmark four-bar with a coupler of mass m2 (kg) whose centre is at z2 (mm, in the
    coupler's frame: origin B, u along B->C), and counterweights of radius ``radius`` on the
    crank (frame origin A, u along A->B) and the rocker (origin D, u along D->C).

    Full force balance: m1 z1 = m2 a (z2 / b - 1) and m3 z3 = -m2 z2 c / b (the centre of mass
    of the three links, written with the loop a e^{i t1} + b e^{i t2} = D + c e^{i t3}, does not
    move). Returns the machine and the two static moments (kg mm, complex)."""
    text = FOURBAR.format(**BENCH) + f"""
[masses.coupler]
mass = {m2}
com = [{z2.real}, {z2.imag}]
inertia_zz = 20.0
[counterweights.crank_cw]
link = "crank"
static_moment_gcm = 0.0
angle_deg = 0.0
radius_mm = {radius}
[counterweights.rocker_cw]
link = "rocker"
static_moment_gcm = 0.0
angle_deg = 0.0
radius_mm = {radius}
"""
    a, b, c = BENCH["ab"], BENCH["bc"], BENCH["cd"]
    return machine_from_toml(text), m2 * a * (z2 / b - 1.0), -m2 * z2 * c / b


@pytest.mark.parametrize("criterion", ["rms", "peak"])
def test_a_four_bar_is_fully_force_balanced_by_two_counterweights(criterion):
    m, s1, s3 = berkof_lowen()
    res = balance(m, criterion)
    assert res.status == "optimal"
    assert res.before["peak_force_N"] > 1.0
    assert res.after["peak_force_N"] < 1e-9 * res.before["peak_force_N"]
    for name, s in (("crank_cw", s1), ("rocker_cw", s3)):
        got = res.counterweights[name]
        assert got["static_moment_gcm"] == pytest.approx(abs(s) * 100.0, rel=1e-8)
        diff = cmath.phase(cmath.exp(1j * (math.radians(got["angle_deg"]) - cmath.phase(s))))
        assert abs(diff) < 1e-8


def test_the_basis_is_the_whole_machine_for_any_counterweights(rng):
    """Counterweights on the crank, the coupler (whose S terms do not vanish: the coupler turns
    at varying speed) and the rocker, at arbitrary static moments: the basis' quantities
    against the dynamics of the machine with those counterweights."""
    text = FOURBAR.format(**BENCH) + """
[masses.coupler]
mass = 0.08
com = [18.0, 6.0]
inertia_zz = 20.0
[counterweights.crank_cw]
link = "crank"
static_moment_gcm = 10.0
angle_deg = 30.0
radius_mm = 10.0
[counterweights.coupler_cw]
link = "coupler"
mass_g = 4.0
at_mm = [-5.0, 3.0]
[counterweights.rocker_cw]
link = "rocker"
static_moment_gcm = 0.0
angle_deg = 0.0
radius_mm = 8.0
"""
    m = machine_from_toml(text)
    B = balance_basis(m, step_deg=5.0, moment_point=(3.0, -4.0))
    assert B.moment_point == (3.0, -4.0)
    for _ in range(3):
        xy = rng.normal(scale=0.5, size=(3, 2))
        q, exact = B.quantities(xy), B.evaluate(xy)
        for k in exact:
            scale = max(1.0, float(np.abs(exact[k]).max()))
            assert np.abs(q[k] - exact[k]).max() < 1e-11 * scale, k
    # a batch of designs at once gives each one's figures
    xys = rng.normal(scale=0.5, size=(4, 3, 2))
    batch = B.criteria(xys)
    for i in range(4):
        one = figures(B.evaluate(xys[i]))
        for k in ("peak_force_N", "rms_force_N", "peak_moment_Nm", "torque_fluctuation_Nm"):
            assert batch[k][i] == pytest.approx(one[k], rel=1e-10, abs=1e-12)


def nelder_mead_from(B, key, xy0):
    """The least ``key`` found by scipy's Nelder-Mead on the whole machine's figures, started at
    ``xy0`` (n, 2): the brute-force reference for a peak criterion."""
    from scipy.optimize import minimize

    n = len(B.counterweights)

    def f(z):
        q = figures(B.evaluate(z.reshape(n, 2)))
        if key == "bearings":
            return max(q["bearing_front_peak_N"], q["bearing_rear_peak_N"])
        return q[key]

    return minimize(f, xy0.reshape(-1), method="Nelder-Mead",
                    options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 4000}).fun


@pytest.mark.parametrize("criterion, key", [("peak", "peak_force_N"),
                                            ("moment", "peak_moment_Nm"),
                                            ("torque", "torque_fluctuation_Nm")])
def test_peak_criteria_are_no_worse_than_a_search_on_the_whole_machine(criterion, key):
    m, _, _ = berkof_lowen()
    B = balance_basis(m, step_deg=2.0)
    res = balance(m, criterion, basis=B)
    assert res.status == "optimal"
    # started near the answer and far from it, the search finds nothing better
    for start in (res.xy + 0.05, np.zeros((2, 2)) + 0.3):
        # (both may be round-off: a full balance leaves a peak force of ~1e-13 N, so the
        # allowance is scaled to the forces that cancel)
        assert res.after[key] <= (nelder_mead_from(B, key, start) * (1.0 + 1e-7)
                                  + 1e-12 * res.before[key])
    assert res.after[key] <= res.before[key]


def test_bearing_criterion_on_jb13_with_two_counterweights():
    from importlib import resources

    text = resources.files("sewmech.data.machines").joinpath("jb1-3.toml").read_text("utf-8")
    text += """
[counterweights.front_cw]
link = "needle_crank"
static_moment_gcm = 0.0
angle_deg = 180.0
radius_mm = 20.0
z_mm = 40.0
[counterweights.rear_cw]
link = "needle_crank"
static_moment_gcm = 0.0
angle_deg = 180.0
radius_mm = 20.0
z_mm = 300.0
"""
    m = machine_from_toml(text)
    B = balance_basis(m, ["front_cw", "rear_cw"], step_deg=4.0)
    res = balance(m, "bearings", basis=B)
    assert res.status == "optimal" and res.basis_error < 1e-9
    after = max(res.after["bearing_front_peak_N"], res.after["bearing_rear_peak_N"])
    before = max(res.before["bearing_front_peak_N"], res.before["bearing_rear_peak_N"])
    assert after < before
    assert after <= nelder_mead_from(B, "bearings", res.xy + 0.1) * (1.0 + 1e-7)
    for crit in ("rms", "weighted"):
        r = balance(m, crit, basis=B)
        assert r.status == "optimal" and set(r.after) == set(FIGURES)


def test_a_limit_bounds_the_answer_and_delta_q_says_when_it_cannot_reach_zero():
    m_s, r = 0.05, 15.0
    # the least RMS wants 37.5 g cm; the space allows 30
    res = balance(slider_crank_with_cw(r=r, m_s=m_s, limit=30.0), "rms")
    assert res.status == "bounded"
    assert res.counterweights["cw"]["static_moment_gcm"] == pytest.approx(30.0, rel=1e-9)
    assert "max_static_moment_gcm" in res.message
    # Delta-Q = 0 needs 50.3 g cm: with 30 allowed there is no root; the least Delta-Q is at
    # 30, kept for information (nothing is proposed)
    res = balance(slider_crank_with_cw(r=r, m_s=m_s, limit=30.0), "delta-q")
    assert res.status == "infeasible" and not res.proposed
    closest = res.closest
    assert closest["counterweights"]["cw"]["static_moment_gcm"] == pytest.approx(30.0, rel=1e-6)
    assert closest["figures"]["delta_q_N"] > 1.0
    assert "max_static_moment_gcm" in res.message


def test_bad_balancing_options_are_located():
    m = slider_crank_with_cw()
    with pytest.raises(OptionError, match="unknown criterion"):
        balance(m, "lowest")
    with pytest.raises(OptionError, match="not a counterweight"):
        balance(m, "rms", ["cww"])
    with pytest.raises(OptionError, match="no \\[shaft\\] table"):
        balance(m, "bearings")
    with pytest.raises(OptionError, match="divide 360"):
        balance(m, "rms", step_deg=7.0)
    with pytest.raises(OptionError, match="unknown part"):
        balance(m, "weighted", weights={"peak": 1.0})
    fb, _, _ = berkof_lowen()
    with pytest.raises(OptionError, match="one\\s+counterweight"):
        balance(fb, "delta-q")
    plain = machine_from_toml(SLIDER_CRANK.format(r=15.0, l=44.0, e=0.0, alpha=90.0, gx=0.0,
                                                  gy=0.0, branch=1))
    # the file lacks them, not an option: the error names the machine, not --counterweight
    with pytest.raises(AnalysisError, match="has no counterweights") as exc:
        balance(plain, "rms")
    assert "--counterweight" not in str(exc.value)
    with pytest.raises(OptionError, match="'cw' is not a counterweight.*it has none"):
        balance(plain, "rms", ["cw"])


def test_the_trade_off_front_is_what_no_other_set_beats():
    from sewmech.design.balancing import pareto_front, spread, tradeoff

    # the sample spreads evenly: every cell of a 8 x 8 grid of the square gets points
    u = spread(1024, 2)
    counts = np.histogram2d(u[:, 0], u[:, 1], bins=8, range=[[0, 1], [0, 1]])[0]
    assert counts.min() >= 12 and counts.max() <= 20  # 16 each for a perfect spread
    # the front against brute force: a point is on it iff no other is <= in all, < in one
    rng = np.random.default_rng(5)
    F = rng.random((300, 3))
    front = pareto_front(F)
    for i in range(len(F)):
        dominated = np.any(np.all(F <= F[i], axis=1) & np.any(F < F[i], axis=1))
        assert front[i] == (not dominated)
    m, _, _ = berkof_lowen()
    T = tradeoff(balance_basis(m, step_deg=6.0), n=256)
    assert T["front"].any() and T["xy"].shape == (256, 2, 2)


def slider_crank_cw_text(angle_deg, extra=""):
    """The text of the slider-crank of :func:`slider_crank_with_cw` with its counterweight
    turned to ``angle_deg`` (no limit), and ``extra`` lines for its table."""
    text = SLIDER_CRANK.format(r=15.0, l=44.0, e=0.0, alpha=90.0, gx=0.0, gy=0.0, branch=1)
    return text + f"""
[masses.block]
mass = 0.05
com = [0.0, 0.0]
inertia_zz = 0.0
[counterweights.cw]
link = "crank"
static_moment_gcm = 0.0
angle_deg = {angle_deg}
radius_mm = 12.0
{extra}"""


def slider_crank_cw_at(angle_deg, extra=""):
    """That slider-crank as a machine."""
    return machine_from_toml(slider_crank_cw_text(angle_deg, extra))


def test_an_infeasible_delta_q_proposes_nothing_and_says_what_is_achievable():
    """Along 45 deg Delta-Q has no root: the static moment of least Delta-Q would make the
    peak shaking force several times worse, so it is kept for information only; the machine
    stays as the file has it, and the least peak force with the same counterweight is what
    the result offers instead."""
    res = balance(slider_crank_cw_at(45.0), "delta-q")
    assert res.status == "infeasible" and not res.proposed
    peak0 = res.before["peak_force_N"]
    assert res.closest["figures"]["peak_force_N"] > 3.0 * peak0  # what was presented before
    # nothing changed: no counterweight, no overrides, the figures after are the file's
    assert res.counterweights == res.counterweights_before
    assert res.counterweights["cw"]["static_moment_gcm"] == 0.0 and res.overrides == {}
    assert res.after == res.before
    alt = res.alternative
    assert alt.criterion == "peak" and alt.proposed
    assert alt.after["peak_force_N"] < 0.9 * peak0
    assert "No counterweight is proposed" in res.message and "--criterion peak" in res.message
    data = res.to_json()
    assert data["status"] == "infeasible"
    assert data["counterweights"] is None and data["after"] is None
    assert data["alternative"]["option"] == "--criterion peak"
    assert data["alternative"]["after"]["peak_force_N"] == pytest.approx(
        float(alt.after["peak_force_N"]), rel=1e-12)
    assert "not proposed" in data["closest"]["note"]
    # the paper's workflow: no S_add, no S_opt and no recipe for an infeasible answer
    from sewmech.design.balancing import paper_workflow

    paper = paper_workflow(slider_crank_cw_at(45.0), "cw", result=res)
    assert paper["s_add_gcm"] is None and paper["s_opt_gcm"] is None
    assert paper["build"] is None and "no root" in paper["build_refused"]


def test_a_delta_q_root_that_raises_the_peak_force_says_so():
    worse = balance(slider_crank_cw_at(120.0), "delta-q")  # equal peaks at 2.5 x the peak
    assert worse.status == "optimal"
    assert worse.after["peak_force_N"] > 2.0 * worse.before["peak_force_N"]
    assert "raise the peak shaking force" in worse.message
    assert "--criterion peak" in worse.message
    better = balance(slider_crank_cw_at(180.0), "delta-q")
    assert better.after["peak_force_N"] < better.before["peak_force_N"]
    assert "raise" not in better.message
