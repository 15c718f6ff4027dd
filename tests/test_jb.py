"""The JB1-3 machine: hook drive, timing facts, relative positions. Each check is computed here
from an independent formula or a plain-numpy evaluation, not from the package's own function."""

import math

import numpy as np
import pytest

import sewmech
from sewmech import timing as T

PHI = np.radians(np.arange(0.0, 360.0, 0.5))


@pytest.fixture(scope="module")
def jb():
    return sewmech.load_machine("jb1-3")


def _spec_value(m, name):
    return float(m.defaults[m.parameter_index(name)])


def hook_closed_form(m, phi):
    """Lower-shaft angle of the hook drive in plain numpy: four-bar (circle intersection) then
    the slotted link (line through O2 at the rocking angle meets the circle about O3)."""
    g = lambda n: _spec_value(m, n)  # noqa: E731
    O2 = np.array([g("O2.x"), g("O2.y")])
    O3 = np.array([g("O3.x"), g("O3.y")])
    r1, rod, arm, r3 = g("E.u"), g("big_rod.length1"), g("big_rod.length2"), g("slotted_link.length")
    th = g("hook_crank.phase") + phi
    E = np.stack([r1 * np.cos(th), r1 * np.sin(th)], -1)
    d = O2 - E
    L = np.linalg.norm(d, axis=-1, keepdims=True)
    u = d / L
    a = (rod**2 - arm**2 + L**2) / (2 * L)
    h = np.sqrt(rod**2 - a**2)
    D = E + a * u + h * np.stack([-u[:, 1], u[:, 0]], -1)  # branch +1: left of E -> O2
    psi = np.arctan2(D[:, 1] - O2[1], D[:, 0] - O2[0])  # slot parallel to the arm
    e = np.stack([np.cos(psi), np.sin(psi)], -1)
    w = O2 - O3
    b = (w * e).sum(-1)
    s = -b + np.sqrt(b**2 - (w * w).sum() + r3**2)  # far intersection
    K = O2 + s[:, None] * e
    return np.arctan2(K[:, 1] - O3[1], K[:, 0] - O3[0])


def test_hook_drive_against_closed_form(jb):
    r = sewmech.kinematics(jb, PHI)
    np.testing.assert_allclose(r.link("lower_shaft").theta, hook_closed_form(jb, PHI),
                               atol=1e-11)


def test_shuttle_swing_fact(jb):
    th = np.unwrap(hook_closed_form(jb, np.radians(np.arange(0, 360, 0.01))))
    swing = math.degrees(th.max() - th.min())
    assert 206.0 <= swing <= 210.0
    assert T.shuttle_swing(jb).swing_deg == pytest.approx(swing, abs=1e-4)


def test_loop_lift_fact_against_slider_crank_formula(jb):
    """Rise after BDC from the in-line slider-crank formula h = r(1-cos d) + l[1-sqrt(1-(r/l)^2
    sin^2 d)] (the sign for a bar hanging below its crank)."""
    ll = T.loop_lift(jb)
    r, l = _spec_value(jb, "B.u"), _spec_value(jb, "needle_bar.length")
    dl = math.radians(ll.after_bdc_deg)
    h = r * (1 - math.cos(dl)) + l * (1 - math.sqrt(1 - (r / l) ** 2 * math.sin(dl) ** 2))
    assert ll.rise_mm == pytest.approx(h, abs=1e-9)
    assert 2.0 <= h <= 2.5
    # and the shuttle point really is on the needle line there, above its axis
    res = sewmech.kinematics(jb, np.radians([ll.phi_deg]))
    sp = res.point("shuttle.point").p[0]
    assert sp[0] == pytest.approx(res.point("needle.point").p[0, 0], abs=1e-9)
    assert sp[1] > _spec_value(jb, "O3.y")
    assert ll.point_above_eye_mm > 0


def test_set_hook_timing_hits_its_targets(jb):
    for target, seize in ((2.0, 20.0), (2.5, 30.0)):
        h = T.set_hook_timing(jb, loop_lift_mm=target, seize_after_reversal_deg=seize)
        p = jb.parameters(h.overrides)
        assert T.loop_lift(jb, p).rise_mm == pytest.approx(target, abs=1e-8)
        sw = T.shuttle_swing(jb, p)
        ll = T.loop_lift(jb, p)
        assert ll.shuttle_deg - sw.min_deg == pytest.approx(seize, abs=1e-6)
        # the point stays on its 17 mm circle
        assert math.hypot(*h.point_uv) == pytest.approx(17.0, abs=1e-3)


def test_take_up_lags_needle(jb):
    r = sewmech.kinematics(jb, np.radians(np.arange(0, 360, 0.01)))
    top_needle = np.degrees(r.phi[np.argmax(r.point("needle.point").p[:, 1])])
    top_eye = np.degrees(r.phi[np.argmax(r.point("take_up.eye").p[:, 1])])
    assert top_eye - top_needle == pytest.approx(T.take_up_lag_deg(jb), abs=0.02)
    assert T.take_up_lag_deg(jb) > 0


def test_checks_all_pass_on_the_shipped_machine(jb):
    checks = T.check_timing(jb)
    assert {c.name for c in checks} >= {"shuttle swing", "take-up eye top after needle top"}
    assert all(c.passed for c in checks), [c for c in checks if not c.passed]


def test_needle_window_against_grid(jb):
    w_in, w_below = T.needle_windows(jb)
    r = sewmech.kinematics(jb, np.radians(np.arange(0, 360, 0.01)))
    y = r.point("needle.point").p[:, 1]
    inside = y < -140.0 + 1.0
    assert np.mean(inside == w_in.contains(r.phi_deg)) > 0.9999
    assert w_below.start_deg > w_in.start_deg and w_below.end_deg < w_in.end_deg


def _feed_cam_switches(jb, r):
    """Grid steps in which the fork's contact passes from one arc of the feed cam to the next
    (computed here from the fork and cam angles and the arcs' normal ranges)."""
    rho = r.link("feed_fork").theta + np.pi / 2 - r.link("feed_cam").theta  # contact normal
    bounds = np.array([jb.defaults[jb.parameter_index(f"feed_cam.arc{k}.normal_from")]
                       for k in range(6)])
    span = np.diff(np.append(bounds, bounds[0] + 2 * np.pi))
    arc = np.array([np.nonzero(np.mod(x - bounds, 2 * np.pi) < span)[0][0] for x in rho])
    return np.nonzero(np.diff(np.append(arc, arc[0])))[0]


def test_every_channel_continuous(jb):
    """No branch jumps: every channel changes by little between neighbouring angles. Only
    accelerations may jump, and only where the fork's contact passes between two arcs of the
    feed cam (the arcs' curvatures differ; positions and velocities of the parts stay
    continuous there)."""
    phi = np.radians(np.arange(0.0, 360.0, 0.25))
    r = sewmech.kinematics(jb, phi)
    switches = _feed_cam_switches(jb, r)
    assert len(switches) == 6  # six arcs, each passed once per revolution
    for name, (x, unit) in r.channels().items():
        d = np.diff(np.concatenate([x, x[:1]]))  # closing the cycle too
        if name.startswith("theta_"):
            d = np.angle(np.exp(1j * d))  # a full turn is not a jump
        span = np.ptp(x) + 1e-12
        # the contact point's place on the fork face is continuous, but it slides at a rate
        # proportional to the arc radius, which jumps at a switch
        if name.split("_")[0] in ("a", "epsilon", "qdd") or name == "qd_fork_on_cam":
            d = np.delete(d, switches)
        assert np.abs(d).max() < 0.05 * span + 1e-9, name


def test_needle_descent_at_take_up_top_against_a_grid(jb):
    phi = np.radians(np.arange(0.0, 360.0, 0.01))
    r = sewmech.kinematics(jb, phi, points=["needle.point", "take_up.eye"], links=[],
                           variables=[])
    y_n = r.point("needle.point").p[:, 1]
    y_e = r.point("take_up.eye").p[:, 1]
    k = int(np.argmax(y_e))
    # the eye's top between grid points: the vertex of the parabola through three samples
    f = 0.5 * (y_e[k - 1] - y_e[k + 1]) / (y_e[k - 1] - 2 * y_e[k] + y_e[k + 1])
    d = y_n.max() - np.interp(k + f, np.arange(len(y_n)), y_n)
    assert T.needle_descent_at_take_up_top(jb) == pytest.approx(d, abs=1e-4)
    c = {x.name: x for x in T.check_timing(jb)}["needle descent when the take-up eye is at its top"]
    assert c.passed and 1.5 <= d <= 6.0
