"""The machine's own physics (issue 30): friction in the pairs, springs and dampers, process
loads that act while their condition holds, one-sided contacts and the speed at which each
opens. Each against something independent: the Newton-Euler equations written out here and
solved by scipy's root finder, virtual work with finite differences, the energy balance, the
thread model of sewmech.sewing, brute-force re-evaluation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq, root
from sewmech.dynamics import DynamicsPlan, inverse_dynamics
from sewmech.errors import MachineFileError
from sewmech.kinematics import kinematics
from sewmech.machine import machine_from_toml

import sewmech
from sewmech.engine.contacts import contact_margins
from test_dynamics import SC_TOML, W, text_without_friction

#: jb1-3 as shipped, its [friction] left out (the tests add their own)
JB_TEXT = text_without_friction("jb1-3")


def with_text(base: str, extra: str) -> sewmech.Machine:
    return machine_from_toml(base + "\n" + extra)


def cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def s(x, scale):
    return x / math.sqrt(x * x + scale * scale)


# ---- friction against the Newton-Euler equations written out ------------------------------------

SC_FRICTION = """
[friction]
coefficient = 0.15
pin_radius_mm = 4.0
smooth_mm_s = 1.0
pairs = { "B" = { coefficient = 0.2, pin_radius_mm = 3.0 }, "slider.guide" = { coefficient = 0.12 } }
"""


def slider_crank_with_friction_by_hand(m, phi, mu_pin, r_pin, mu_slide, smooth):
    """The slider-crank's nine unknowns at every position from its three links' Newton-Euler
    equations with Coulomb friction, solved by scipy's root finder (from zero forces).

    Unknowns: F_O (frame on crank), F_B (crank on rod), F_C (rod on block), N (frame on block
    along the guide's normal n = (-1, 0)), M (the guide's couple on the block), tau (motor on
    crank). Friction: at each pin a moment -mu r |F| s(r w_rel) on the pair's second link and
    the opposite on its first; at the slider -mu |N| s(v) along the guide on the block, v the
    block's velocity along the guide (+y)."""
    kin = kinematics(m, phi)
    res0 = inverse_dynamics(m, phi, loads=[])  # only for the centres of mass' motion
    G, A = res0.com_p, res0.com_a  # (n, links, 2), mm, mm/s^2
    th_w = kin.omega
    mass = {n: sp.mass for n, sp in m.spec.masses.items()}
    izz = {n: m.masses[n].inertia[2, 2] for n in m.spec.masses}
    idx = {n: m.link_names.index(n) for n in ("crank", "rod", "block")}
    g = np.array([0.0, -9.80665])
    out = np.zeros((len(phi), 9))
    for k in range(len(phi)):
        O, B, C = (kin.point(p).p[k] for p in ("O", "B", "C"))
        w1, w2, w3 = (th_w[k, idx[n]] for n in ("crank", "rod", "block"))
        vC = kin.point("C").v[k]
        eps = {n: kin.epsilon[k, idx[n]] for n in idx}

        def R(n):
            return mass[n] * (A[k, idx[n]] * 1e-3 - g)  # m a - m g, N

        def Ia(n):
            return izz[n] * eps[n] * 1e-3  # N mm

        def eqs(x):
            FO, FB, FC = x[0:2], x[2:4], x[4:6]
            Nn, Mg, tau = x[6], x[7], x[8]
            mO = -mu_pin["O"] * r_pin["O"] * np.hypot(*FO) * s(r_pin["O"] * w1, smooth)
            mB = -mu_pin["B"] * r_pin["B"] * np.hypot(*FB) * s(r_pin["B"] * (w2 - w1), smooth)
            mC = -mu_pin["C"] * r_pin["C"] * np.hypot(*FC) * s(r_pin["C"] * (w3 - w2), smooth)
            n = np.array([-1.0, 0.0])
            t = np.array([0.0, 1.0])
            fs = -mu_slide * abs(Nn) * s(vC @ t, smooth)
            Gc, Gr, Gb = (G[k, idx[n]] for n in ("crank", "rod", "block"))
            e = np.empty(9)
            e[0:2] = FO - FB - R("crank")
            e[2] = (cross(O - Gc, FO) + cross(B - Gc, -FB) + tau + mO - mB) - Ia("crank")
            e[3:5] = FB - FC - R("rod")
            e[5] = (cross(B - Gr, FB) + cross(C - Gr, -FC) + mB - mC) - Ia("rod")
            e[6:8] = FC + Nn * n + fs * t - R("block")
            e[8] = (cross(C - Gb, FC) + cross(C - Gb, Nn * n + fs * t) + Mg + mC) - Ia("block")
            return e

        sol = root(eqs, np.zeros(9), method="hybr", tol=1e-13)
        # (it may stop on "no further improvement" at round-off: the residual says whether
        # it solved the equations)
        assert np.abs(eqs(sol.x)).max() <= 1e-11 * max(1.0, np.abs(sol.x).max()), (k, sol)
        out[k] = sol.x
    return out


def test_slider_crank_with_friction_against_its_equations_solved_by_scipy():
    m = with_text(SC_TOML, SC_FRICTION)
    phi = np.linspace(0.0, 2 * math.pi, 48, endpoint=False)
    res = inverse_dynamics(m, phi, loads=[])
    ref = slider_crank_with_friction_by_hand(
        m, phi, {"O": 0.15, "B": 0.2, "C": 0.15}, {"O": 4.0, "B": 3.0, "C": 4.0}, 0.12, 1.0)
    peak = np.abs(ref[:, :6]).max()
    for name, cols in (("O", slice(0, 2)), ("B", slice(2, 4)), ("C", slice(4, 6))):
        assert np.abs(res.pair(name) - ref[:, cols]).max() <= 1e-8 * peak, name
    assert np.abs(res.pair("slider.guide")[:, 0] - ref[:, 6]).max() <= 1e-8 * peak
    mpeak = np.abs(ref[:, 7]).max() + np.abs(ref[:, 8]).max()
    assert np.abs(res.pair("slider.guide")[:, 1] - ref[:, 7]).max() <= 1e-8 * mpeak
    assert np.abs(res.input_torque - ref[:, 8]).max() <= 1e-8 * np.abs(ref[:, 8]).max()
    # friction is not negligible here: it moves the torque by a good part of its peak
    res0 = inverse_dynamics(with_text(SC_TOML, ""), phi, loads=[])
    assert np.abs(res.input_torque - res0.input_torque).max() > 0.05 * np.abs(
        res0.input_torque).max()
    # and it only ever takes energy out, pair by pair
    assert (res.friction.power >= 0.0).all()
    assert set(res.friction.pairs) == {"O", "B", "C", "slider.guide"}


def test_friction_of_zero_is_the_frictionless_analysis():
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    m0 = with_text(JB_TEXT, "")  # jb1-3 without its [friction]
    a = inverse_dynamics(m0, phi)
    b = inverse_dynamics(with_text(JB_TEXT, "[friction]\ncoefficient = 0.0\n"
                                   "pin_radius_mm = 3.0\n"), phi)
    assert b.friction is None  # no frictional pair: the same single solve
    np.testing.assert_array_equal(a.unknowns, b.unknowns)
    # a vanishing coefficient approaches it continuously
    c = inverse_dynamics(with_text(JB_TEXT, "[friction]\ncoefficient = 1e-9\n"
                                   "pin_radius_mm = 3.0\n"), phi)
    assert np.abs(c.unknowns - a.unknowns).max() <= 1e-6 * np.abs(a.unknowns).max()


JB_PHYSICS = """
[friction]
coefficient = 0.1
pin_radius_mm = 3.0
viscous_N_mm_s = 0.0

[[springs]]
name = "lift return spring"
links = ["feed_bar", "frame"]
points = ["feed_dog.tip", "H"]
stiffness_N_per_mm = 0.8
free_length_mm = 20.0
damping_N_s_per_mm = 0.002

[[torsion_springs]]
name = "rock shaft spring"
pair = "H"
stiffness_N_mm_per_deg = 2.0
free_angle_deg = -160.0
damping_N_mm_s_per_deg = 0.01
"""


def test_the_power_balance_closes_at_every_position_with_friction_and_springs():
    """P_in = dT/dt + dV/dt - P_loads + P_friction + P_damping at every position of JB1-3
    (each term computed on its own: the motor's torque from the force solve, the rest from the
    motion and the applied forces)."""
    m = with_text(JB_TEXT, JB_PHYSICS)
    phi = np.radians(np.arange(0.0, 360.0, 1.0))
    r = inverse_dynamics(m, phi)
    peak = np.abs(r.input_power).max()
    assert np.abs(r.power_balance).max() <= 1e-9 * peak
    assert r.friction_power.mean() > 0.0 and r.damping_power.mean() > 0.0
    assert (r.friction.power >= 0.0).all() and (r.damping_power >= 0.0).all()


SC_SPRING = """
[[springs]]
name = "block spring"
links = ["block", "frame"]
points = ["C", "G"]
stiffness_N_per_mm = 1.5
free_length_mm = 30.0
damping_N_s_per_mm = 0.01

[[torsion_springs]]
name = "block pin spring"
pair = "C"
stiffness_N_mm_per_deg = 3.0
preload_N_mm = 20.0
angle_deg = -80.0
"""


SC_LOSSES = SC_FRICTION + SC_SPRING + """
[[loads]]
name = "resistance while the block is high"
link = "block"
point = "C"
law = "resistive"
force_N = 5.0
angle_deg = 90.0
when = { channel = "p_C_y", above = -40.0 }

[[loads]]
name = "pad pressed while the block is low"
link = "block"
point = "C"
law = "elastic"
force_N = 3.0
rate_N_per_mm = 0.4
angle_deg = 90.0
when = { channel = "p_C_y", below = -45.0 }
"""


def test_over_a_turn_the_motor_puts_in_what_friction_dampers_and_loads_take_out():
    """Mean input power = friction loss + damping loss + the resistive load's dissipation
    (computed from its own force and velocity), and the elastic load gives back what it
    takes: nothing else, to 1e-6 of the peak power (a slider-crank: its energies are smooth
    in the shaft angle, so a turn's mean of their rates vanishes to round-off on a uniform
    grid)."""
    m = with_text(SC_TOML, SC_LOSSES)
    phi = np.linspace(0.0, 2 * math.pi, 720, endpoint=False)
    r = inverse_dynamics(m, phi)
    v = r.kin.point("C").v
    resistive = -np.sum(r.load_force[:, 0] * v, axis=-1)
    elastic = np.sum(r.load_force[:, 1] * v, axis=-1)
    assert (resistive >= 0.0).all() and resistive.mean() > 0.0
    peak = np.abs(r.input_power).max()
    losses = r.friction.power.sum(axis=-1).mean() + r.damping_power.mean() + resistive.mean()
    assert r.input_power.mean() > 0.0
    assert abs(r.input_power.mean() - losses) <= 1e-6 * peak
    # the elastic load acts where the block is low, and it is conservative there
    assert r.load_on[:, 1].any() and abs(elastic.mean()) <= 1e-6 * peak


# ---- springs by virtual work -----------------------------------------------------------------

def test_springs_by_virtual_work():
    """The torque a spring adds is its force times its length's rate over the shaft's
    (virtual work), dL/dphi by central differences of the kinematics; the damper adds
    c omega (dL/dphi)^2; a torsion spring k d (dtheta/dphi)."""
    m1 = with_text(SC_TOML, SC_SPRING)
    m0 = with_text(SC_TOML, "")
    phi = np.linspace(0.1, 2 * math.pi, 37)
    d_tau = inverse_dynamics(m1, phi, loads=[]).input_torque - \
        inverse_dynamics(m0, phi, loads=[]).input_torque
    h = 1e-6

    def L(ph):
        k = kinematics(m0, ph)
        return np.linalg.norm(k.point("C").p - k.point("G").p, axis=-1)

    def rel(ph):
        k = kinematics(m0, ph)
        return k.link("block").theta - k.link("rod").theta

    dL = (L(phi + h) - L(phi - h)) / (2 * h)
    drel = (rel(phi + h) - rel(phi - h)) / (2 * h)
    tension = 1.5 * (L(phi) - 30.0) + 0.01 * W * dL
    kt = 3.0 * 180 / math.pi
    free = math.radians(-80.0) - 20.0 / kt
    moment = kt * (np.mod(rel(phi) - free + math.pi, 2 * math.pi) - math.pi)
    expected = tension * dL + moment * drel
    assert np.abs(d_tau - expected).max() <= 1e-6 * np.abs(expected).max()
    r = inverse_dynamics(m1, phi, loads=[])
    np.testing.assert_allclose(r.springs.of("block spring"), tension, rtol=1e-7)
    assert np.abs(r.power_balance).max() <= 1e-9 * np.abs(r.input_power).max()


# ---- process loads that act while their condition holds ---------------------------------------

STATE_LOADS = """
[[loads]]
name = "presser foot through the fabric"
link = "feed_bar"
point = "feed_dog.tip"
law = "elastic"
force_N = 14.7
rate_N_per_mm = 3.0
angle_deg = -90.0
when = { channel = "p_feed_dog.tip_y", above = -140.0 }

[[loads]]
name = "feed resistance"
link = "feed_bar"
point = "feed_dog.tip"
law = "resistive"
force_N = 7.35
angle_deg = 0.0
when = { channel = "p_feed_dog.tip_y", above = -140.0 }

[[loads]]
name = "thread pull while the take-up sets the stitch"
link = "take_up_lever"
point = "take_up.eye"
force_N = 2.94
toward = ["thread.check_post", "thread.face_guide"]
when = [{ channel = "thread.take_up_mm", rising = true },
        { channel = "thread.take_up_mm", within_of_max = 6.0 }]
"""


def state_machine():
    text = JB_TEXT.split("[[loads]]", 1)[0] + "[shaft]" + JB_TEXT.split("[shaft]", 1)[1]
    return with_text(text, STATE_LOADS)


def test_state_loads_act_where_their_condition_holds():
    m = state_machine()
    phi = np.radians(np.arange(0.0, 360.0, 0.5))
    r = inverse_dynamics(m, phi)
    kin = kinematics(m, phi)
    above = kin.point("feed_dog.tip").p[:, 1] > -140.0
    on = r.load_on
    np.testing.assert_array_equal(on[:, 0] > 0.5, above)
    np.testing.assert_array_equal(on[:, 1] > 0.5, above)
    # the elastic force: 14.7 N plus 3 N per mm above the plate, downwards
    y = kin.point("feed_dog.tip").p[:, 1]
    np.testing.assert_allclose(r.load_force[above, 0, 1], -(14.7 + 3.0 * (y[above] + 140.0)),
                               rtol=1e-12)
    assert (r.load_force[~above, 0] == 0.0).all()
    # the thread pull: where the thread model says the take-up draws its last 6 mm back
    from sewmech.thread import thread_path

    tp = thread_path(m, phi)
    rising = np.gradient(tp.take_up, phi) > 0.0
    want = (tp.supply < 6.0) & rising
    got = on[:, 2] > 0.5
    differ = np.nonzero(got != want)[0]
    # (the model's rate is exact, np.gradient's is not: they may differ only where the rate
    # changes sign, at the take-up's top)
    assert len(differ) <= 2, r.phi_deg[differ]
    assert got.sum() >= 20  # it acts: some 10 deg or more


def test_the_jb_state_loads_only_take_energy_out():
    """With the state loads the JB report's process no longer drives the machine: the loads'
    mean power is negative (they take energy out), the mean driving torque positive."""
    m = state_machine()
    phi = np.radians(np.arange(0.0, 360.0, 0.5))
    r = inverse_dynamics(m, phi)
    v = r.kin.point("feed_dog.tip").v
    resistive = -np.sum(r.load_force[:, 1] * v, axis=-1)
    assert (resistive >= -1e-12).all() and resistive.mean() > 0.0
    assert r.external_power.mean() < 0.0 and r.input_torque.mean() > 0.0


# ---- contacts ----------------------------------------------------------------------------------


def test_the_lift_contact_opens_where_the_force_analysis_says():
    """JB1-3's feed-lift contact at 1000 rpm: its least force over the turn, and the speed at
    which it opens against brute force (the least force over the same grid at speeds around
    it, found by bisection on the full analysis)."""
    m = sewmech.load_machine("jb1-3")
    cm = {c.name: c for c in contact_margins(m)}
    c = cm["lift.cam"]
    phi = np.radians(np.arange(360.0))
    r = inverse_dynamics(m, phi)
    N = r.pair("lift.cam")[:, 0]
    assert c.least_force_N <= N.min() + 1e-9 and c.least_force_N >= N.min() - 0.01
    assert abs(c.at_phi_deg - r.phi_deg[np.argmin(N)]) <= 1.0

    def least(rpm):
        return inverse_dynamics(m, phi, rpm=rpm).pair("lift.cam")[:, 0].min()

    if c.least_force_N < 0:  # open at 1000 rpm: it closes below its opening speed
        opens = brentq(least, 100.0, 1000.0, xtol=1e-10)
    else:
        opens = brentq(least, 1000.0, 20000.0, xtol=1e-10)
    assert c.opens_above_rpm == pytest.approx(opens, rel=1e-8)


def test_a_spring_closes_the_lift_contact():
    m = with_text(JB_TEXT, """
[[springs]]
name = "lift spring"
links = ["feed_bar", "frame"]
points = ["feed_dog.tip", "H"]
stiffness_N_per_mm = 0.5
preload_N = 12.0
length_mm = 60.0
""")
    cm = {c.name: c for c in contact_margins(m)}
    assert cm["lift.cam"].least_force_N > cm["lift.cam"].margin_N
    assert cm["lift.cam"].opens_above_rpm is None or cm["lift.cam"].opens_above_rpm > 1000.0


# ---- bad input -------------------------------------------------------------------------------


@pytest.mark.parametrize("extra, where", [
    ("[[springs]]\nname = \"s\"\nlinks = [\"feed_bar\", \"frame\"]\npoints = [\"feed_dog.tip\","
     " \"H\"]\nstiffness_N_per_mm = -1.0\nfree_length_mm = 10.0\n", "stiffness_N_per_mm"),
    ("[friction]\ncoefficient = -0.1\n", "coefficient"),
    ("[friction]\ncoefficient = 0.1\npin_radius_mm = -2.0\n", "pin_radius_mm"),
    ("[friction]\ncoefficient = 0.1\npairs = { \"nope\" = { coefficient = 0.2 } }\n", "nope"),
    ("[friction]\npairs = { \"lift.cam\" = { pin_radius_mm = 2.0 } }\n", "has no pin"),
    ("[[springs]]\nname = \"s\"\nlinks = [\"feed_bar\", \"feed_bar\"]\npoints = ["
     "\"feed_dog.tip\", \"feed_bar.pin\"]\nstiffness_N_per_mm = 1.0\nfree_length_mm = 10.0\n",
     "one link"),
    ("[[torsion_springs]]\nname = \"t\"\npair = \"lift.cam\"\nstiffness_N_mm_per_deg = 1.0\n"
     "free_angle_deg = 0.0\n", "sits at a pin"),
    ("[[loads]]\nname = \"x\"\nlink = \"feed_bar\"\npoint = \"feed_dog.tip\"\nforce_N = 1.0\n"
     "angle_deg = 0.0\nwhen = { channel = \"p_feed_dog.top_y\", above = 0.0 }\n",
     "no channel 'p_feed_dog.top_y'"),
    ("[[loads]]\nname = \"x\"\nlink = \"feed_bar\"\npoint = \"feed_dog.tip\"\nforce_N = 1.0\n"
     "angle_deg = 0.0\nlaw = \"elastic\"\n", "rate_N_per_mm"),
])
def test_bad_physics_is_a_located_error(extra, where):
    with pytest.raises(MachineFileError) as info:
        with_text(JB_TEXT, extra)
    assert where in str(info.value), str(info.value)


def test_self_locking_friction_is_said_not_returned():
    m = with_text(SC_TOML, "[friction]\ncoefficient = 1.0\npin_radius_mm = 1000.0\n")
    from sewmech.errors import AnalysisError

    with pytest.raises(AnalysisError, match="did not settle"):
        inverse_dynamics(m, np.linspace(0.0, 2 * math.pi, 24, endpoint=False), loads=[])


def test_friction_batch_equals_one_design_at_a_time():
    m = with_text(JB_TEXT, JB_PHYSICS)
    phi = np.radians(np.arange(0.0, 360.0, 10.0))
    P = m.parameters({"needle_bar.length": [43.0, 44.0, 45.5]})
    plan = DynamicsPlan(m, phi)
    batch = plan(P).unknowns.copy()
    for i in range(3):
        one = inverse_dynamics(m, phi, params=P[i]).unknowns
        assert np.abs(batch[i] - one).max() <= 1e-9 * np.abs(one).max()


def test_designs_with_the_same_take_up_share_its_thread_channel(monkeypatch):
    """The JB loads' conditions read the take-up's thread length (a path and its gradient at
    every position): a batch computes it once for designs whose take-up parameters agree (a
    sweep of the feed's dimensions), and every design's loads and forces are still its own
    (each against the design analysed alone)."""
    from sewmech.engine import loads

    m = sewmech.load_machine("jb1-3")
    P = np.stack([m.defaults] * 3)
    P[1, m.parameter_names.index("feed_fork.slot.1.length")] += 0.5  # the feed only
    P[2, m.parameter_names.index("take_up.length1")] += 0.3  # the take-up itself
    sizes = []
    real = loads.channel_values

    def counting(ref, a, thread=None):
        if ref.kind == "thread":
            sizes.append(a["P"].shape[0])
        return real(ref, a, thread)

    monkeypatch.setattr(loads, "channel_values", counting)
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    batch = inverse_dynamics(m, phi, params=P)
    assert 2 in sizes and 3 not in sizes  # (designs 0 and 1 share it)
    for d in range(3):
        one = inverse_dynamics(m, phi, params=P[d])
        np.testing.assert_array_equal(batch.load_on[d], one.load_on)
        np.testing.assert_allclose(batch.load_force[d], one.load_force, rtol=0,
                                   atol=1e-12 * np.abs(one.load_force).max())
        np.testing.assert_allclose(batch.unknowns[d], one.unknowns, rtol=0,
                                   atol=1e-12 * np.abs(one.unknowns).max())
