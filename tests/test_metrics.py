"""The metrics of sewmech.design.metrics (a channel's least, largest, travel, mean and RMS over
the turn, a channel at an event, the transmission angle of rrr, rrp and rpr units, the cam
pressure angle) and the force analysis' metrics (sewmech.design._dynamic_metrics): each exact
derivative against central differences of the exact values and of the batch values, the batch
against the one design, the transmission angle against the pressure angles on a dense grid and
against closed forms, and the file checks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sewmech.dynamics import inverse_dynamics

import sewmech
from conftest import fourbar, slider_crank
from sewmech.design import metrics as M
from sewmech.design._dynamic_metrics import ForceMetrics
from sewmech.design._dynamic_metrics import check_name as check_dynamic
from sewmech.sewing.transmission import pressure_angles

ROTATING_GUIDE = """
[machine]
name = "slotted-lever"
[convention]
reference_event = "crank along +x"
reference_phi_deg = 0.0
[points.O]
x = 0.0
y = 0.0
[points.Q]
x = 0.0
y = {qy}
[[units]]
type = "crank"
name = "crank"
pivot = "O"
points = {{ A = [{r}, 0.0] }}
[[units]]
type = "rpr"
name = "lever"
pin = "A"
pivot = "Q"
link = "lever"
offset = {e}
block = "block"
branch = 1
"""


def rotating_guide(r=20.0, qy=-50.0, e=5.0):
    return sewmech.machine_from_toml(ROTATING_GUIDE.format(r=r, qy=qy, e=e))


def central(fn, P, j, h=1e-6):
    a, b = P.copy(), P.copy()
    a[j] += h
    b[j] -= h
    return (fn(a) - fn(b)) / (2.0 * h)


def assert_gradient(machine, value, d, rel=1e-6, skip=("crank.ratio",)):
    """d against central differences of ``value`` by every parameter, to ``rel`` of the
    gradient's largest component (a parameter that moves the curve along the turn, such as a
    crank's phase, has a derivative 0 that the located extreme's angle gives to ~1e-9)."""
    P = np.asarray(machine.defaults, dtype=float)
    scale = max(float(np.max(np.abs(d))), 1e-12)
    for j, name in enumerate(machine.parameter_names):
        if name in skip:
            continue
        fd = central(value, P, j)
        assert abs(fd - d[j]) <= rel * scale, (name, d[j], fd)


KINEMATIC = [
    (fourbar, {}, "max:p_C_x"), (fourbar, {}, "min:p_P_y"), (fourbar, {}, "range:theta_rocker"),
    (fourbar, {}, "mean:p_P_x"), (fourbar, {}, "rms:v_P_y"), (fourbar, {}, "max:v_P_y"),
    (fourbar, {}, "max:a_P_x"), (fourbar, {}, "min:epsilon_rocker"),
    (fourbar, {}, "max:theta_rocker"), (fourbar, {}, "mean:theta_coupler"),
    (fourbar, {}, "rms:omega_rocker"),
    (fourbar, {}, "transmission_angle_deviation:dyad"),
    (fourbar, {}, "transmission_angle_min:dyad"),
    (slider_crank, {"e": 4.0}, "transmission_angle_deviation:slider"),
    (slider_crank, {"e": 4.0}, "transmission_angle_min:slider"),
    (slider_crank, {"e": 4.0}, "max:q_slider"), (slider_crank, {"e": 4.0}, "min:qdd_slider"),
    (rotating_guide, {}, "transmission_angle_deviation:lever"),
    (rotating_guide, {}, "max:theta_lever"),
]


@pytest.mark.parametrize("make, kw, name", KINEMATIC)
def test_exact_derivatives_against_central_differences(make, kw, name):
    """Every kinematic metric's exact derivative (the envelope theorem at its located extremes,
    the mean of the derivatives over the turn, the link angles' derivatives for the
    transmission angle) equals the central differences of its exact values and of its batch
    values (the derivative-free methods' path), to 1e-6 of the gradient; the batch equals the
    exact value to 1e-6 of its size."""
    m = make(**kw)
    P = np.asarray(m.defaults, dtype=float)
    mv = M.metric_value(m, name, P)
    assert_gradient(m, lambda Q: M.metric_value(m, name, Q).value, mv.d)
    assert_gradient(m, lambda Q: M.metric_batch_values(m, name, Q[None, :])[0], mv.d, rel=2e-5)
    batch = M.metric_batch_values(m, name, P[None, :])[0]
    assert batch == pytest.approx(mv.value, rel=1e-6, abs=1e-6)
    if mv.kind is not None:  # the value is the largest (least) of its pieces
        top = np.max(mv.pieces) if mv.kind == "max" else np.min(mv.pieces)
        assert top == mv.value
        assert mv.pieces_d.shape == (len(mv.pieces), len(P))


@pytest.mark.parametrize("at, channel", [("max:p_P_y", "p_P_x"), ("falling:p_C_y=30", "v_P_y"),
                                         ("rising:p_P_x=10", "theta_rocker"),
                                         ("min:q_slider", "p_B_y")])
def test_a_channel_at_an_event(at, channel):
    """A channel read where a position channel is largest, least or crosses a level: its
    derivative with the event's motion against central differences; the batch's value equals
    the located one."""
    m = slider_crank(e=4.0) if "slider" in at else fourbar()
    P = np.asarray(m.defaults, dtype=float)
    mv = M.event_value(m, channel, at, P)
    assert_gradient(m, lambda Q: M.event_value(m, channel, at, Q).value, mv.d)
    assert M.event_batch(m, channel, at, P[None, :])[0] == pytest.approx(mv.value, rel=1e-6,
                                                                        abs=1e-7)


def test_transmission_angle_against_the_pressure_angles_and_closed_forms():
    """The worst deviation of a dyad's and a slider's transmission angle from 90 deg equals the
    largest of their pressure angles (sewmech.transmission) on a dense grid; a crank-rocker's
    least transmission angle is at a dead centre of the crank with the ground (cosine rule);
    the rotating guide's deviation is asin(e / |QA|) at the pin's nearest approach."""
    dense = np.linspace(0.0, 2.0 * math.pi, 200_001)
    for m, unit in ((fourbar(), "dyad"), (slider_crank(e=4.0), "slider")):
        worst = {n: a for n, a, _ in pressure_angles(m, dense).worst()}[unit]
        mv = M.metric_value(m, f"transmission_angle_deviation:{unit}", m.defaults)
        assert mv.value == pytest.approx(worst, abs=1e-7)
        least = M.metric_value(m, f"transmission_angle_min:{unit}", m.defaults).value
        assert least == pytest.approx(90.0 - worst, abs=1e-7)
    # four-bar a = 15, b = 40, c = 35, d = 38: mu at |BD| = d - a and d + a
    a, b, c, d = 15.0, 40.0, 35.0, 38.0
    mu = [math.degrees(math.acos((b * b + c * c - s * s) / (2 * b * c))) for s in (d - a, d + a)]
    assert M.metric_value(fourbar(), "transmission_angle_deviation:dyad",
                          fourbar().defaults).value == pytest.approx(
        max(abs(90 - u) for u in mu), abs=1e-9)
    m = rotating_guide(r=20.0, qy=-50.0, e=5.0)
    assert M.metric_value(m, "transmission_angle_deviation:lever", m.defaults).value == \
        pytest.approx(math.degrees(math.asin(5.0 / 30.0)), abs=1e-9)
    # a symmetric slider-crank: the two dead centres' pieces tie (the kink of the maximum)
    mv = M.metric_value(slider_crank(e=0.0), "transmission_angle_deviation:slider",
                        slider_crank().defaults)
    assert len(mv.pieces) == 2 and mv.pieces[0] == pytest.approx(mv.pieces[1], abs=1e-9)
    j = slider_crank().parameter_names.index("slider.offset")
    assert mv.pieces_d[0, j] == pytest.approx(-mv.pieces_d[1, j], rel=1e-9)


def test_batches_equal_a_loop_over_designs(rng):
    """A batch of designs in one call equals each design evaluated alone (vectorised ==
    loop); a design that does not assemble is NaN, never a number."""
    m = fourbar()
    P = np.tile(np.asarray(m.defaults), (5, 1))
    j = m.parameter_names.index("dyad.length1")
    P[:, j] = [36.0, 38.0, 40.0, 42.0, 70.0]  # the last does not assemble
    for name in ("max:p_C_x", "rms:v_P_y", "transmission_angle_min:dyad",
                 "range:theta_rocker"):
        got = M.metric_batch_values(m, name, P)
        assert np.isnan(got[-1])
        for k in range(4):
            assert got[k] == pytest.approx(M.metric_batch_values(m, name, P[k:k + 1])[0],
                                           rel=1e-12), name
            assert got[k] == pytest.approx(M.metric_value(m, name, P[k]).value, rel=1e-6)


def test_loop_units_and_a_rrr_of_jb13():
    """The metrics on loop units (the feed bar of JB1-3) and on one of its dyads: exact against
    batch, and a derivative against central differences for two parameters."""
    m = sewmech.load_machine("jb1-3")
    P = np.asarray(m.defaults, dtype=float)
    for name in ("max:p_feed_dog.tip_y", "transmission_angle_deviation:take_up",
                 "mean:v_needle.point_y"):
        mv = M.metric_value(m, name, P)
        assert M.metric_batch_values(m, name, P[None, :])[0] == pytest.approx(
            mv.value, rel=1e-6, abs=1e-6)
        scale = float(np.max(np.abs(mv.d)))
        for pn in ("needle_crank.phase", "take_up.length2", "big_rod.length1"):
            if pn not in m.parameter_names:
                continue
            j = m.parameter_names.index(pn)
            fd = central(lambda Q, n=name: M.metric_value(m, n, Q).value, P, j)
            assert abs(fd - mv.d[j]) <= 1e-6 * max(scale, 1e-9), (name, pn)


@pytest.mark.parametrize("name, needle", [
    ("max:p_Q_z", "'p_Q_z' is not a channel"),
    ("range:v_C_x", "a range is of a position channel"),
    ("max:theta_crank", "turns a whole revolution"),
    ("transmission_angle_min:crank", "'crank' is not an rrr, rrp or rpr unit"),
    ("pressure_angle_max:dyad", "'dyad' is not a cam contact"),
])
def test_names_the_machine_lacks(name, needle):
    with pytest.raises(M.MetricNameError, match=needle):
        M.check_name(fourbar(), name, list(sewmech.kinematics(fourbar(), [0.0]).channel_names()))


def test_dynamic_metrics_values_and_checks():
    """The force analysis' metrics from one DynamicsPlan call for a batch equal
    inverse_dynamics' own figures of each design; a pair the machine lacks, a contact that is
    not one-sided and a machine without masses or loads are refused."""
    m = sewmech.load_machine("jb1-3")
    fm = ForceMetrics(m)
    names = ["peak_torque", "rms_torque", "peak_shaking_force", "peak_shaking_moment",
             "friction_loss", "peak_bearing_reaction", "peak_bearing_reaction:rear",
             "peak_force:B", "least_contact_force:lift.cam"]
    names = [n for n in names if n.partition(":")[2] in ("", "rear")
             or n.partition(":")[2] in [p.name for p in m.pairs]]
    P = np.tile(np.asarray(m.defaults), (2, 1))
    j = m.parameter_names.index("needle_bar.length")
    P[1, j] += 2.0
    got = fm.values(names, P)
    phi = fm.phi
    for k in range(2):
        r = inverse_dynamics(m, phi, params=P[k])
        ref = {"peak_torque": np.abs(r.input_torque).max() * 1e-3,
               "rms_torque": np.sqrt(np.mean(r.input_torque ** 2)) * 1e-3,
               "peak_shaking_force": np.linalg.norm(r.shaking_force, axis=-1).max(),
               "peak_shaking_moment": np.abs(r.shaking_moment).max() * 1e-3,
               "friction_loss": np.mean(r.friction_power) * 1e-3,
               "peak_bearing_reaction": max(np.linalg.norm(r.bearings.front, axis=-1).max(),
                                            np.linalg.norm(r.bearings.rear, axis=-1).max()),
               "peak_bearing_reaction:rear": np.linalg.norm(r.bearings.rear, axis=-1).max()}
        for n in names:
            if n in ref:
                assert got[n][k] == pytest.approx(ref[n], rel=1e-9), n
            elif n.startswith("peak_force:"):
                assert got[n][k] == pytest.approx(r.magnitude(n.partition(":")[2]).max(),
                                                  rel=1e-9)
            elif n.startswith("least_contact_force:"):
                assert got[n][k] == pytest.approx(
                    np.asarray(r.pair(n.partition(":")[2]))[..., 0].min(), rel=1e-9)
    assert check_dynamic(m, "peak_torque")
    with pytest.raises(M.MetricNameError, match="needs a pair with a force"):
        check_dynamic(m, "peak_force:nowhere")
    with pytest.raises(M.MetricNameError, match="one-sided contact"):
        check_dynamic(m, "least_contact_force:feed_fork.cam")
    with pytest.raises(M.MetricNameError, match="neither \\[masses\\] nor \\[\\[loads\\]\\]"):
        check_dynamic(fourbar(), "peak_torque")
    assert not check_dynamic(m, "max:p_C_x")
