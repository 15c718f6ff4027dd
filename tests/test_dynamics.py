"""Inverse dynamics against closed forms written here, energy balances and virtual work."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import SLIDER_CRANK
from exudyn_fourbar import TEST_LINKS
from sewmech import load_machine
from sewmech.dynamics import GRAVITY, SingularForceSystem, in_windows, inverse_dynamics
from sewmech.kinematics import kinematics
from sewmech.machine import machine_from_toml
from sewmech.mass import MassProperties
from sewmech.spec import LoadSpec

W = 1000 * 2 * math.pi / 60  # 1000 rpm, rad/s


def planar(m, u, v, izz):
    inertia = np.zeros((3, 3))
    inertia[2, 2] = izz
    return MassProperties(m, np.array([u, v, 0.0]), inertia)


def cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def rot(v, th):
    """Vector v (u, v) of a link frame turned by th."""
    c, s = np.cos(th), np.sin(th)
    return np.stack([c * v[0] - s * v[1], s * v[0] + c * v[1]], axis=-1)


def perp(x):
    return np.stack([-x[..., 1], x[..., 0]], axis=-1)


def rigid(p, v, a, th, om, ep, r_local):
    """Position, velocity, acceleration of a body point from a reference point's motion."""
    r = rot(r_local, th)
    return (p + r, v + om[..., None] * perp(r),
            a + ep[..., None] * perp(r) - (om ** 2)[..., None] * r)


# ---- the four-bar: closed-form kinematics (Freudenstein's loop) and a sequential force solve ---

FB = dict(A=np.array([0.0, 0.0]), D=np.array([38.0, 0.0]), r=15.0, l2=40.0, l3=35.0)
FB_MASS = TEST_LINKS  # kg, (u, v) mm, kg mm^2 per link


def fourbar_kinematics(phi):
    A, D, r, l2, l3 = FB["A"], FB["D"], FB["r"], FB["l2"], FB["l3"]
    e1 = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    B = A + r * e1
    d = D - B
    dist = np.linalg.norm(d, axis=-1)
    a = (l2 ** 2 - l3 ** 2 + dist ** 2) / (2 * dist)
    h = np.sqrt(l2 ** 2 - a ** 2)
    u = d / dist[:, None]
    C = B + a[:, None] * u + h[:, None] * perp(u)  # left of B -> D: the upper assembly
    th2 = np.arctan2(C[:, 1] - B[:, 1], C[:, 0] - B[:, 0])
    th3 = np.arctan2(C[:, 1] - D[1], C[:, 0] - D[0])
    # velocities: i r w e1 + i l2 w2 e2 = i l3 w3 e3
    e2 = np.stack([np.cos(th2), np.sin(th2)], axis=-1)
    e3 = np.stack([np.cos(th3), np.sin(th3)], axis=-1)
    vB = W * r * perp(e1)
    M = np.stack([np.stack([-l2 * perp(e2)[:, 0], l3 * perp(e3)[:, 0]], -1),
                  np.stack([-l2 * perp(e2)[:, 1], l3 * perp(e3)[:, 1]], -1)], -2)
    w23 = np.linalg.solve(M, vB[..., None])[..., 0]
    w2, w3 = w23[:, 0], w23[:, 1]
    aB = -W ** 2 * r * e1
    rhs = aB - l2 * w2[:, None] ** 2 * e2 + l3 * w3[:, None] ** 2 * e3
    a23 = np.linalg.solve(M, rhs[..., None])[..., 0]
    return B, C, th2, th3, vB, aB, w2, w3, a23[:, 0], a23[:, 1]


def fourbar_closed_form(phi, gravity):
    """Pin forces and crank torque by free bodies taken one after the other."""
    A, D = FB["A"], FB["D"]
    B, C, th2, th3, vB, aB, w2, w3, e2, e3 = fourbar_kinematics(phi)
    zero = np.zeros_like(phi)
    th1 = phi
    m1, *g1, _ = FB_MASS["crank"]  # the crank turns at constant speed: no I alpha
    m2, *g2, I2 = FB_MASS["coupler"]
    m3, *g3, I3 = FB_MASS["rocker"]
    G1, _, a1 = rigid(A, zero[:, None], zero[:, None], th1, W + zero, zero, g1)
    G2, _, a2 = rigid(B, vB, aB, th2, w2, e2, g2)
    G3, _, a3 = rigid(D, zero[:, None], zero[:, None], th3, w3, e3, g3)
    g = np.array([0.0, -GRAVITY if gravity else 0.0])
    # inertia "loads": m a - m g (N), I alpha (N mm)
    R1, R2, R3 = (m * (acc * 1e-3 - g) for m, acc in ((m1, a1), (m2, a2), (m3, a3)))
    # rocker, moments about D: (C - D) x F_C + (G3 - D) x (m3 g) = I3 e3 + (G3 - D) x m3 a3
    #   -> (C - D) x F_C = I3 e3 1e-3 + (G3 - D) x R3
    # coupler, moments about B: (C - B) x (-F_C) = I2 e2 1e-3 + (G2 - B) x R2
    rD, rB = C - D, C - B
    b1 = I3 * e3 * 1e-3 + cross(G3 - D, R3)
    b2 = -(I2 * e2 * 1e-3 + cross(G2 - B, R2))
    M = np.stack([np.stack([-rD[:, 1], rD[:, 0]], -1), np.stack([-rB[:, 1], rB[:, 0]], -1)], -2)
    FC = np.linalg.solve(M, np.stack([b1, b2], -1)[..., None])[..., 0]  # on rocker from coupler
    FB_ = R2 + FC  # on coupler from crank: F_B - F_C = R2
    FD = R3 - FC  # on rocker from frame
    FA = R1 + FB_  # on crank from frame
    tau = -cross(B - A, -FB_) + cross(G1 - A, R1)
    return FA, FB_, FC, FD, tau


@pytest.mark.parametrize("gravity", [False, True])
def test_fourbar_against_closed_form(gravity):
    m = load_machine("fourbar-benchmark")
    masses = {k: planar(*v) for k, v in FB_MASS.items()}
    phi = np.linspace(0.0, 2 * math.pi, 181, endpoint=False)
    r = inverse_dynamics(m, phi, masses=masses, gravity=gravity, loads=[])
    FA, FB_, FC, FD, tau = fourbar_closed_form(phi, gravity)
    peak = np.abs(FA).max()
    for name, ref in (("A", FA), ("B", FB_), ("C", FC), ("D", FD)):
        assert np.abs(r.pair(name) - ref).max() <= 1e-9 * peak, name
    assert np.allclose(r.input_torque, tau, rtol=0, atol=1e-9 * np.abs(tau).max())
    assert np.abs(tau).max() > 100.0  # N mm: the test is not trivially zero


# ---- the slider-crank (the needle bar): closed form ------------------------------------------

SC_TOML = SLIDER_CRANK.format(r=15.0, l=44.0, e=0.0, alpha=90.0, gx=0.0, gy=0.0, branch=-1) + """
[masses.crank]
mass = 0.2
com = [-3.0, 1.0]
inertia_zz = 40.0
[masses.rod]
mass = 0.012
com = [20.0, 0.5]
inertia_zz = 2.5
[masses.block]
mass = 0.05
com = [-40.0, 0.3]
inertia_zz = 30.0
"""


def test_slider_crank_against_closed_form():
    m = machine_from_toml(SC_TOML)
    phi = np.linspace(0.0, 2 * math.pi, 144, endpoint=False)
    res = inverse_dynamics(m, phi, gravity=True, loads=[])
    r, l = 15.0, 44.0
    # closed form: B = r e^{i phi}; C = (0, y) below B with x_C = 0
    s, c = np.sin(phi), np.cos(phi)
    xb, yb = r * c, r * s
    k = np.sqrt(l ** 2 - xb ** 2)
    yc = yb - k
    dk = (xb * r * s) / k * W  # d/dt sqrt(l^2 - xb^2) = -xb xb' / k, xb' = -r s w
    vyc = r * c * W - dk
    # second derivative: differentiate yb' - k' exactly
    xbd = -r * s * W
    xbdd = -r * c * W ** 2
    kd = -xb * xbd / k
    kdd = -(xbd ** 2 + xb * xbdd) / k + (xb * xbd) * kd / k ** 2
    ayc = -r * s * W ** 2 - kdd
    assert np.allclose(res.kin.point("C").a[:, 1], ayc, rtol=1e-9, atol=1e-6)
    th2 = np.arctan2(yc - yb, -xb)  # rod B -> C
    w2 = (xbd * (yc - yb) - (vyc - r * c * W) * (-xb)) / l ** 2
    # rod angular acceleration from the rod direction's second derivative
    dx, dy = -xb, yc - yb
    dxd, dyd = -xbd, vyc - r * c * W
    dxdd, dydd = -xbdd, ayc + r * s * W ** 2
    e2 = ((dx * dydd - dy * dxdd) * l ** 2 - (dx * dyd - dy * dxd) * 2 * (dx * dxd + dy * dyd)) \
        / l ** 4
    w2 = (dx * dyd - dy * dxd) / l ** 2
    zero = np.zeros_like(phi)
    B = np.stack([xb, yb], -1)
    C = np.stack([zero, yc], -1)
    vB = np.stack([-r * s * W, r * c * W], -1)
    aB = np.stack([-r * c * W ** 2, -r * s * W ** 2], -1)
    g = np.array([0.0, -GRAVITY])
    mc, gc = 0.2, (-3.0, 1.0)  # the crank turns at constant speed, the bar does not turn:
    mr, gr, Ir = 0.012, (20.0, 0.5), 2.5  # only the rod's inertia enters
    mb, gb = 0.05, (-40.0, 0.3)
    G1, _, a1 = rigid(np.zeros((len(phi), 2)), zero[:, None], zero[:, None], phi, W + zero, zero,
                      gc)
    G2, _, a2 = rigid(B, vB, aB, th2, w2, e2, gr)
    G3 = C + np.array(rot(gb, math.pi / 2))
    a3 = np.stack([zero, ayc], -1)
    # bar (slider), vertical guide: x: N + F_Cx = mb a3x - mb gx; y: F_Cy = mb (a - g)_y
    FCy = mb * (a3[:, 1] * 1e-3 + GRAVITY)  # on the bar from the rod
    # rod: F_B - F_C = R2 ; moments about B: (C - B) x (-F_C) = I e2 + (G2 - B) x R2
    R2 = mr * (a2 * 1e-3 - g)
    rc = C - B
    rhs = Ir * e2 * 1e-3 + cross(G2 - B, R2)
    # -(rc_x F_Cy - rc_y F_Cx) = rhs  ->  F_Cx = (rhs + rc_x F_Cy) / rc_y
    FCx = (rhs + rc[:, 0] * FCy) / rc[:, 1]
    FC = np.stack([FCx, FCy], -1)
    FBr = R2 + FC  # on the rod from the crank
    # bar: normal force N (along the guide's normal, -x for a guide along +y) and couple M
    R3 = mb * (a3 * 1e-3 - g)
    N = -(R3[:, 0] - FCx)  # F_Cx + N * (-1) = R3_x
    R1 = mc * (a1 * 1e-3 - g)
    FA = R1 + FBr
    tau = cross(B, FBr) + cross(G1, R1)
    peak = np.abs(FA).max()
    assert np.abs(res.pair("C") - FC).max() <= 1e-9 * peak
    assert np.abs(res.pair("B") - FBr).max() <= 1e-9 * peak
    assert np.abs(res.pair("O") - FA).max() <= 1e-9 * peak
    assert np.allclose(res.pair("slider.guide")[..., 0], N, rtol=0, atol=1e-9 * peak)
    # the guide couple: moments on the bar about its COM: (C - G3) x F_C + M + (C - G3) x N n = 0
    n = np.array([-1.0, 0.0])
    Mref = -cross(C - G3, FC) - cross(C - G3, N[:, None] * n)
    assert np.allclose(res.pair("slider.guide")[..., 1], Mref, rtol=0, atol=1e-9 * peak * 100)
    assert np.allclose(res.input_torque, tau, rtol=0, atol=1e-9 * np.abs(tau).max())


# ---- the JB machine: energy, virtual work, the frame ------------------------------------------


def jb_loads():
    return [LoadSpec(name="take-up pull", link="take_up_lever", point="take_up.eye",
                     force_N=2.94, toward=["thread.check_post", "thread.face_guide"],
                     windows_deg=[(135.0, 155.0)]),
            LoadSpec(name="presser", link="feed_bar", point="feed_dog.tip", force_N=14.7,
                     angle_deg=-90.0, windows_deg=[(90.0, 175.0)]),
            LoadSpec(name="feed resistance", link="feed_bar", point="feed_dog.tip",
                     force_N=7.35, angle_deg=180.0, windows_deg=[(90.0, 175.0)])]


def jb_masses(m, seed=0):
    rng = np.random.default_rng(seed)
    return {n: planar(rng.uniform(0.01, 0.2), rng.uniform(-10, 10), rng.uniform(-5, 5),
                      rng.uniform(1, 50)) for n in m.link_names[1:]}


@pytest.mark.parametrize("name", ["jb1-3", "jb8-2"])
def test_power_balance_whole_machine(name):
    m = load_machine(name)
    phi = np.radians(np.arange(0.0, 360.0, 2.5))
    r = inverse_dynamics(m, phi, masses=jb_masses(m), loads=jb_loads(),
                         inputs={"regulator": math.radians(25.0)})
    # energy rates from the motion alone, not from the solved forces; friction and the
    # spring's damping take what they take (each from its own forces and relative speeds)
    bal = r.input_power - (r.kinetic_energy_rate + r.potential_energy_rate - r.external_power
                           + r.friction_power + r.damping_power)
    assert np.abs(bal).max() <= 1e-8 * np.abs(r.input_power).max()
    assert r.friction_power.min() >= 0.0 and r.friction_power.mean() > 0.0
    assert np.abs(r.external_power).max() > 0.0
    # and the energy rates are the derivatives of the energies (central differences, 0.01 deg)
    h = math.radians(0.01)
    rp, rm = (inverse_dynamics(m, phi + s * h, masses=jb_masses(m), loads=[],
                               inputs={"regulator": math.radians(25.0)}) for s in (1, -1))
    dT = (rp.kinetic_energy - rm.kinetic_energy) / (2 * h) * r.kin.omega_shaft
    dV = (rp.potential_energy - rm.potential_energy) / (2 * h) * r.kin.omega_shaft
    assert np.allclose(dT, r.kinetic_energy_rate, rtol=0,
                       atol=1e-6 * np.abs(r.kinetic_energy_rate).max())
    assert np.allclose(dV, r.potential_energy_rate, rtol=0,
                       atol=1e-6 * np.abs(r.potential_energy_rate).max())


def test_static_torque_is_virtual_work():
    """At vanishing speed the torque holds the weights and the loads: tau = dV/dphi - sum F .
    dX/dphi, with the derivatives by central differences of positions."""
    m = load_machine("jb1-3")
    masses = jb_masses(m, 3)
    phi = np.radians(np.array([10.0, 47.0, 100.0, 140.0, 150.0, 222.0, 300.0]))
    loads = jb_loads()
    r = inverse_dynamics(m, phi, masses=masses, loads=loads, omega=1e-7)
    h = 1e-4  # rad: the loop units close to 1e-10 mm, so a smaller step would see that noise
    rp, rm = (inverse_dynamics(m, phi + s * h, masses=masses, loads=loads, omega=1e-7)
              for s in (1, -1))
    dV = (rp.potential_energy - rm.potential_energy) / (2 * h)
    work = np.zeros_like(phi)
    for k, load in enumerate(loads):
        i = m.point_index(load.point)
        dX = (rp.kin.p[:, i] - rm.kin.p[:, i]) / (2 * h)
        work += np.sum(r.load_force[:, k] * dX, axis=-1)
    tau = dV - work
    assert np.abs(tau).max() > 10.0
    assert np.allclose(r.input_torque, tau, rtol=0, atol=1e-6 * np.abs(tau).max())


def test_frame_feels_the_shaking_force_and_moment():
    m = load_machine("jb1-3")
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    r = inverse_dynamics(m, phi, masses=jb_masses(m, 1), loads=[], gravity=False)
    total = sum(r.frame_reactions.values())
    assert np.allclose(total, r.shaking_force, rtol=0, atol=1e-9 * np.abs(total).max())
    # moments on the frame: its pairs' forces (friction along the sliding ones included) at
    # their points, the guides' couples and the friction moments at its pins, and the drivers'
    moment = np.zeros_like(phi)
    for name, F in r.frame_reactions.items():
        moment += cross(r.frame_reaction_points[name], F)
    moment += sum(r.frame_couples.values())
    assert "feed-bar spring" in r.frame_reactions  # the spring pulls on the frame too
    assert r.friction is not None and "O3" in r.frame_couples  # friction at the frame's pins
    for pair in r.pairs:
        if pair.kind == "driver":
            moment -= r.pair(pair.name)[..., 0]
    assert np.allclose(moment, r.shaking_moment, rtol=0, atol=1e-9 * np.abs(moment).max())


def test_batch_equals_loop():
    m = load_machine("jb1-3")
    phi = np.radians(np.arange(0.0, 360.0, 10.0))
    settings = np.radians([-30.0, 0.0, 20.0])
    P = m.parameters(inputs={"regulator": settings})
    batch = inverse_dynamics(m, phi, params=P, masses=jb_masses(m), loads=jb_loads())
    for k, s in enumerate(settings):
        one = inverse_dynamics(m, phi, inputs={"regulator": s}, masses=jb_masses(m),
                               loads=jb_loads())
        assert np.allclose(batch.unknowns[k], one.unknowns, rtol=1e-12, atol=1e-9)


def test_large_batch_runs_in_parallel_and_equals_one_design():
    m = load_machine("jb1-3")
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    P = m.parameters({"needle_bar.length": np.linspace(42.0, 46.0, 300)})  # 21,600 systems
    batch = inverse_dynamics(m, phi, params=P)
    for k in (0, 137, 299):
        one = inverse_dynamics(m, phi, params=P[k])
        # exact: each design is solved by the same compiled kernel on its own rows, whichever
        # thread or chunk it falls in
        assert np.array_equal(batch.unknowns[k], one.unknowns)


def test_windows():
    deg = np.array([0.0, 80.0, 90.0, 120.0, 175.0, 176.0, 350.0, 359.9])
    assert in_windows(deg, [(90.0, 175.0)]).tolist() == [0, 0, 1, 1, 1, 0, 0, 0]
    assert in_windows(deg, [(340.0, 10.0)]).tolist() == [1, 0, 0, 0, 0, 0, 1, 1]
    assert in_windows(deg, [(78.0, 82.0), (135.0, 155.0)]).tolist() == [0, 1, 0, 0, 0, 0, 0, 0]
    assert in_windows(deg, [(0.0, 360.0)]).all()


def test_missing_contact_is_named():
    m = machine_from_toml(SC_TOML)
    # drop the guide pair by hand: the count no longer matches
    object.__setattr__(m, "pairs", tuple(p for p in m.pairs if p.kind != "prismatic"))
    with pytest.raises(SingularForceSystem, match="3 moving links give 9 equilibrium equations"
                                                  " but the pairs give 7 unknowns"):
        inverse_dynamics(m, [0.0])


# ---- the upper shaft in 3-D --------------------------------------------------------------------

SHAFT_TOML = SC_TOML.replace("""[masses.crank]
mass = 0.2
com = [-3.0, 1.0]
inertia_zz = 40.0""", """[masses.crank]
material = "steel"
solids = [ { type = "cylinder", radius = 4.0, length = 200.0, base = [0.0, 0.0, -20.0] },
           { type = "point", mass = 0.03, at = [12.0, 0.0, 10.0] },
           { type = "point", mass = 0.05, at = [-9.0, 3.0, 150.0] } ]
[shaft]
links = { crank = 0.0 }
bearings = { front = 20.0, rear = 170.0 }""")


@pytest.mark.parametrize("gravity", [False, True])
def test_bearings_by_the_lever_rule(gravity):
    """Each point mass and the rod's pin force are carried by the two bearings in inverse
    proportion to their distances (the lever rule), written here for each load by itself."""
    m = machine_from_toml(SHAFT_TOML)
    phi = np.linspace(0.0, 2 * math.pi, 72, endpoint=False)
    r = inverse_dynamics(m, phi, gravity=gravity, loads=[])
    br = r.bearings
    zf, zr = 20.0, 170.0
    g = np.array([0.0, -GRAVITY if gravity else 0.0])
    front = np.zeros((len(phi), 2))
    rear = np.zeros((len(phi), 2))

    def carry(F, z):  # a force F on the shaft at z: the bearings' reactions
        nonlocal front, rear
        wr = (z - zf) / (zr - zf)
        front -= (1 - wr) * F
        rear -= wr * F

    # the shaft's solids, one by one: inertia and weight appear as forces at their own z
    rho = 7850e-9
    mc = rho * math.pi * 16.0 * 200.0
    parts = [(mc, (0.0, 0.0), 80.0), (0.03, (12.0, 0.0), 10.0), (0.05, (-9.0, 3.0), 150.0)]
    for mass, (u, v), z in parts:
        pos = rot((u, v), phi)
        acc = -W ** 2 * pos
        carry(mass * g - mass * acc * 1e-3, z)
    # the rod pulls the crank pin in the crank's plane z = 0
    carry(-r.pair("B"), 0.0)
    peak = np.abs(front).max()
    assert np.allclose(br.front, front, rtol=0, atol=1e-9 * peak)
    assert np.allclose(br.rear, rear, rtol=0, atol=1e-9 * peak)
    # the planar analysis' frame pin force on the crank is the sum of both bearings
    assert np.allclose(br.front + br.rear, r.pair("O"), rtol=0, atol=1e-9 * peak)
    assert np.abs(br.inertia_couple).max() > 1.0  # the masses at different z make a couple


def test_shaft_masses_are_about_the_axis():
    # refused when the file is read, with the key to change
    with pytest.raises(ValueError, match="masses.crank\\] origin: .*its mass frame's origin"
                                         " must be the shaft's axis point 'O' \\(it is 'B'\\)"):
        machine_from_toml(SHAFT_TOML.replace('[masses.crank]\nmaterial = "steel"',
                                             '[masses.crank]\nmaterial = "steel"\norigin = "B"'))


def test_bearings_need_products_of_inertia():
    # the slider-crank's crank has measured planar values only (mass, com, inertia_zz)
    with pytest.raises(ValueError, match="inertia_zz: link 'crank' turns with the upper shaft"
                                         ".*its bearing reactions need its products of inertia"):
        machine_from_toml(SC_TOML + "[shaft]\nlinks = { crank = 0.0 }\n"
                          "bearings = { front = 20.0, rear = 170.0 }\n")
    # and by the bearing reactions, for planar masses given to inverse_dynamics
    m = machine_from_toml(SHAFT_TOML)
    from sewmech.mass import from_spec
    from sewmech.spec import MassSpec

    measured = from_spec(MassSpec(mass=0.1, com=(5.0, 0.0), inertia_zz=1.0))  # planar only
    r = inverse_dynamics(m, [0.0, 1.0], loads=[], masses={"crank": measured})
    with pytest.raises(ValueError, match="gives only inertia_zz: the bearing reactions need"):
        _ = r.bearings


# ---- command line and load files ----------------------------------------------------------------


def test_cli_dynamics_json(tmp_path):
    import json

    from typer.testing import CliRunner

    from sewmech.cli import app

    out = CliRunner().invoke(app, ["dynamics", "jb1-3", "--rpm", "600", "--step-deg", "10",
                                   "--json", "--input", "regulator=30"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.output)
    rows = data["positions"]
    assert len(rows) == 36 and data["rpm"] == 600.0 and data["settings_deg"]["regulator"] == 30
    keys = {"phi_deg", "input_torque_Nm", "kinetic_energy_J", "potential_energy_J",
            "external_power_W", "shaking_force_N", "shaking_moment_Nm", "bearing_front_N",
            "bearing_rear_N"}
    assert keys <= set(rows[0])
    # the same numbers as the library, in SI
    m = load_machine("jb1-3")
    r = inverse_dynamics(m, np.radians(np.arange(0, 360, 10.0)), rpm=600,
                         inputs={"regulator": math.radians(30)})
    assert np.allclose([x["input_torque_Nm"] for x in rows], r.input_torque * 1e-3, atol=1e-12)
    assert np.allclose([x["bearing_rear_N"] for x in rows], r.bearings.rear, atol=1e-12)
    assert np.allclose([x["external_power_W"] for x in rows], r.external_power * 1e-3)
    e = data["pairs"]["E"]
    assert e["kind"] == "revolute" and e["links"] == ["hook_crank", "big_rod"]
    assert e["components"] == ["Fx_N", "Fy_N"] and np.allclose(e["values"], r.pair("E"))
    assert data["pairs"]["lift.cam"]["components"] == ["N_N"]
    # power balance on the JSON figures alone: P_in = dT/dt + dV/dt - P_ext, with the energy
    # derivatives from a periodic spline of the printed energies (a loose, independent check)
    from scipy.interpolate import CubicSpline

    t = np.radians([x["phi_deg"] for x in rows] + [360.0]) / (600 * 2 * math.pi / 60)
    E = [x["kinetic_energy_J"] + x["potential_energy_J"] for x in rows]
    dE = CubicSpline(t, E + E[:1], bc_type="periodic")(t[:-1], 1)
    P = np.array([x["input_torque_Nm"] for x in rows]) * 600 * 2 * math.pi / 60
    Pext = np.array([x["external_power_W"] for x in rows])
    loss = np.array([x["friction_power_W"] + x["damping_power_W"] for x in rows])
    assert np.abs(P + Pext - loss - dE).max() < 0.05 * np.abs(P).max() + 1e-9
    # the turn's means: what the motor puts in, friction, dampers and loads take out
    assert data["mean_input_power_W"] == pytest.approx(
        data["friction_loss_W"] + data["damping_loss_W"] + data["load_dissipation_W"],
        abs=0.02 * np.abs(P).max())
    assert [c["pair"] for c in data["contacts"]] == ["lift.cam", "lift.roller.slot"]


def test_load_file_errors(tmp_path):
    from typer.testing import CliRunner

    from sewmech.cli import app

    bad = tmp_path / "loads.toml"
    bad.write_text('[[loads]]\nname = "pull"\nlink = "take_up_lever"\npoint = "needle.eye"\n'
                   'force_N = 3.0\nangle_deg = -90.0\n')
    out = CliRunner().invoke(app, ["dynamics", "jb1-3", "--loads", str(bad)])
    assert out.exit_code == 2
    assert "loads.toml" in out.output and 'loads[0] "pull"' in out.output
    assert "'needle.eye' is not a point of link 'take_up_lever'" in out.output
    bad.write_text('[[loads]]\nname = "pull"\nlink = "take_up_lever"\npoint = "take_up.eye"\n'
                   'force_N = 3.0\n')
    out = CliRunner().invoke(app, ["dynamics", "jb1-3", "--loads", str(bad)])
    assert out.exit_code == 2 and "exactly one of angle_deg" in out.output
    good = tmp_path / "good.toml"
    good.write_text('[[loads]]\nname = "pull"\nlink = "take_up_lever"\npoint = "take_up.eye"\n'
                    'force_N = 3.0\nangle_deg = -90.0\nwindows_deg = [[350.0, 20.0]]\n')
    out = CliRunner().invoke(app, ["dynamics", "jb1-3", "--loads", str(good), "--out",
                                   str(tmp_path / "o")])
    assert out.exit_code == 0, out.output
    import pandas as pd

    df = pd.read_csv(tmp_path / "o" / "jb1-3-dynamics.csv")
    # the window's ends with room for the grid's round-off (degrees(radians(5 k)) is an ulp off
    # for some k; the load's own window test allows 1e-9 deg), far inside the 5 deg step
    on = (df.phi_deg >= 350 - 1e-6) | (df.phi_deg <= 20 + 1e-6)
    # exactly 0 outside: the kernel multiplies the load's force by its window flag (0 or 1)
    assert (df.external_power_W[~on] == 0).all() and (df.external_power_W[on] != 0).any()
    assert (tmp_path / "o" / "jb1-3-pair-forces.csv").exists()
    # and the figures at the command's settings: the torque figure sees the load file's window
    fig = pd.read_csv(tmp_path / "o" / "jb1-3-dyn-torque.csv")
    m = load_machine("jb1-3")
    r = inverse_dynamics(m, np.radians(fig.phi_deg), loads=[LoadSpec(
        name="pull", link="take_up_lever", point="take_up.eye", force_N=3.0, angle_deg=-90.0,
        windows_deg=[(350.0, 20.0)])])
    assert np.allclose(fig.torque_Nm, r.input_torque * 1e-3, rtol=1e-9, atol=1e-12)
    for name in ("dyn-bearings", "dyn-shaking", "dyn-needle"):
        assert (tmp_path / "o" / f"jb1-3-{name}.png").stat().st_size > 1000


# ---- speed fluctuation and force transmission ----------------------------------------------------


def text_without_friction(name: str) -> str:
    """A shipped machine file's text without its [friction] tables (the rest as shipped)."""
    from sewmech import shipped_machines

    out, skip = [], False
    for line in open(shipped_machines()[name], encoding="utf-8").read().splitlines():
        if line.startswith("["):
            skip = line.startswith("[friction")
        elif line.startswith("# the upper shaft in 3-D"):
            skip = False
        if not skip:
            out.append(line)
    return "\n".join(out) + "\n"


def without_friction(name: str):
    """A shipped machine without its [friction] tables (the rest as shipped)."""
    m = machine_from_toml(text_without_friction(name))
    assert m.spec.friction is None
    return m


def test_speed_fluctuation_obeys_the_equation_of_motion():
    """Without friction the energy method is exact: driven at its omega(phi), the force
    solve needs the motor torque it found, at every angle."""
    from sewmech.dynamics import speed_fluctuation

    m = without_friction("jb1-3")
    masses = jb_masses(m)
    sf = speed_fluctuation(m, flywheel=2000.0, masses=masses, loads=jb_loads(), n_phi=1440)
    # driven at the computed omega(phi), epsilon(phi), the force solve needs exactly the motor
    # torque (less what the flywheel takes): the energy method and Newton-Euler agree
    r = inverse_dynamics(m, sf.phi, omega=sf.omega, epsilon=sf.epsilon, masses=masses,
                         loads=jb_loads())
    tau = r.input_torque + 1e-3 * 2000.0 * sf.epsilon
    assert np.abs(tau - sf.motor_torque).max() <= 1e-9 * np.abs(sf.load_torque).max()
    # and omega(phi) is the integral of domega/dphi = epsilon / omega (trapezoids; the load
    # windows make epsilon jump, so no spline derivative)
    from scipy.integrate import cumulative_trapezoid

    rate = sf.epsilon / sf.omega
    rebuilt = sf.omega[0] + cumulative_trapezoid(rate, sf.phi, initial=0.0)
    assert np.abs(rebuilt - sf.omega).max() <= 1e-4 * W
    assert sf.delta > 1e-3
    assert math.isclose(sf.omega.mean(), W, rel_tol=1e-9)
    # a heavier flywheel smooths the speed about in proportion (delta ~ dE / (J w^2))
    big = speed_fluctuation(m, flywheel=20000.0, masses=masses, loads=jb_loads())
    assert 0.05 < big.delta / sf.delta < 0.2


def test_speed_fluctuation_with_friction_takes_it_on_the_nominal_motion():
    """With friction the energy method takes the friction of the motion at the nominal speed:
    driven at its omega(phi), the force solve's torque differs from its constant motor torque
    by the change of the friction with the speed's fluctuation: the inertia forces go with
    omega^2, so the friction changes by up to about 2 delta of itself (3 delta allowed; the
    friction torque is about 64 N mm: left out, it would be the whole of it)."""
    from sewmech.dynamics import speed_fluctuation

    m = load_machine("jb1-3")
    sf = speed_fluctuation(m, flywheel=2000.0, n_phi=1440)
    r = inverse_dynamics(m, sf.phi, omega=sf.omega, epsilon=sf.epsilon)
    tau = r.input_torque + 1e-3 * 2000.0 * sf.epsilon
    nominal = inverse_dynamics(m, sf.phi)
    friction_torque = nominal.friction_power.mean() / W
    assert friction_torque > 10.0  # N mm: friction is a good part of the load here
    assert np.abs(tau - sf.motor_torque).max() <= 3.0 * sf.delta * friction_torque
    # the motor's mean torque is the mean load: weights and springs give nothing over a
    # turn, friction and the loads take what they take
    assert sf.motor_torque == pytest.approx(
        (nominal.friction_power.mean() - nominal.external_power.mean()) / W, rel=1e-6)


@pytest.mark.parametrize("rpm", [1.0, 10.0])
def test_no_steady_cycle_at_a_crawl_is_said_not_a_root_finder_error(rpm):
    """At a few rev/min the weights' work over the turn would swing the shaft faster than the
    mean speed even from rest: no constant motor torque holds that mean (scipy's bracket error
    escaped before)."""
    from sewmech.dynamics import speed_fluctuation
    from sewmech.engine.errors import AnalysisError

    with pytest.raises(AnalysisError, match=f"no steady cycle at {rpm:g} rpm") as info:
        speed_fluctuation(load_machine("jb1-3"), rpm=rpm)
    assert "flywheel" in info.value.hint
    # a flywheel large enough carries it: the mean speed is then the one asked for
    sf = speed_fluctuation(load_machine("jb1-3"), rpm=rpm, flywheel=1e9)
    assert sf.omega.mean() == pytest.approx(rpm * 2 * math.pi / 60, rel=1e-9)


def test_speed_fluctuation_needs_inertia():
    from sewmech.dynamics import speed_fluctuation

    with pytest.raises(ValueError, match="reduced inertia J\\(phi\\) is zero"):
        speed_fluctuation(load_machine("fourbar-benchmark"))
    # and a JSON without [shaft] says why its bearings are null
    from sewmech.io import dynamics_to_dict

    m = load_machine("fourbar-benchmark")
    d = dynamics_to_dict(inverse_dynamics(m, [0.0, 1.0], masses={"crank": planar(0.1, 5, 0, 1)}))
    assert d["positions"][0]["bearing_front_N"] is None
    assert "null here: machine 'fourbar-benchmark' has no [shaft] table" in \
        d["conventions"]["bearing_rear_N"]


def test_pressure_angles_of_a_slider_crank():
    from sewmech.transmission import pressure_angles

    m = machine_from_toml(SC_TOML)
    phi = np.linspace(0.0, 2 * math.pi, 73)
    pa = pressure_angles(m, phi)
    # the rod's angle from the vertical guide: sin(angle) = x_B / l
    ref = np.degrees(np.arcsin(np.abs(15.0 * np.cos(phi)) / 44.0))
    assert np.allclose(pa.angles["slider"], ref, atol=1e-9)
    name, worst, at = pa.worst()[0]
    assert name == "slider" and math.isclose(worst, math.degrees(math.asin(15 / 44)), rel_tol=1e-9)


def test_needle_force_by_virtual_work():
    from sewmech.transmission import needle_force

    m = load_machine("jb1-3")
    nf = needle_force(m, 500.0, n_phi=360)
    assert (nf.depth >= 0).all() and nf.depth.max() > 10.0
    # at one angle: (M - M0) = F * (-dy/dphi) with dy/dphi by central differences
    k = len(nf.phi_deg) // 2
    phi = math.radians(nf.phi_deg[k])
    y = [kinematics(m, [phi + s * 1e-5]).point("needle.point").p[0, 1] for s in (1, -1)]
    dy = (y[0] - y[1]) / 2e-5
    M0 = inverse_dynamics(m, [phi], loads=[]).input_torque[0]
    assert math.isclose(nf.force[k], (500.0 - M0) / -dy, rel_tol=1e-7)


# ---- against an independent multibody engine -----------------------------------------------------


@pytest.mark.parametrize("gravity", [False, True])
def test_fourbar_against_exudyn(gravity):
    """Exudyn (prescribed crank angle, a second revolution after the start-up transient)
    against sewmech's force solve: every pin force and the drive torque within 1e-3 of its
    peak (measured: 2.5e-6)."""
    pytest.importorskip("exudyn")
    from exudyn_fourbar import solve_fourbar

    ref = solve_fourbar(FB_MASS, rpm=1000.0, n_per_rev=120, gravity=gravity, substeps=16,
                        g=GRAVITY)
    m = load_machine("fourbar-benchmark")
    masses = {k: planar(*v) for k, v in FB_MASS.items()}
    r = inverse_dynamics(m, ref["phi"], masses=masses, gravity=gravity, loads=[])
    for name in "ABCD":
        peak = np.abs(ref[f"F_{name}"]).max()
        assert np.abs(r.pair(name) - ref[f"F_{name}"]).max() <= 1e-3 * peak, name
    peak = np.abs(ref["torque_Nmm"]).max()
    assert np.abs(r.input_torque - ref["torque_Nmm"]).max() <= 1e-3 * peak


def test_one_sided_contacts_are_reported(tmp_path):
    from sewmech.app.drawing.figures import Figures
    from sewmech.report_dynamics import dynamics_section

    m = load_machine("jb1-3")
    sided = {p.name for p in m.pairs if p.one_sided}
    assert sided == {"lift.cam", "lift.roller.slot"}
    r = inverse_dynamics(m, np.radians(np.arange(0.0, 360.0, 1.0)),
                         inputs={"regulator": math.radians(30.0)})
    key = dynamics_section(Figures(tmp_path, m.name), m)
    for name in sorted(sided):
        row = key[key.quantity.str.contains(f"one-sided contact {name} ")]
        assert len(row) == 1
        # the least force: at most the 1 deg grid's, and no more than the force changes
        # across a grid step below it (it is looked for again between the grid's angles)
        grid = r.pair(name)[..., 0]
        least = float(row.value.iloc[0])
        assert least <= grid.min() + 1e-9 and least >= grid.min() - np.abs(
            np.diff(grid)).max()
        assert ("holds" in row.quantity.iloc[0]) == (least >= 1.0)
        opens = key[key.quantity == f"speed above which {name} opens"]
        assert len(opens) == 1 and opens.value.iloc[0] > 1000.0


def test_force_structure_blocks_and_plan_reuse():
    """The force equations split into the blocks of the Assur groups (four-bar: the driver, the
    crank's pin, the dyad); every block's coupling goes to later blocks only. A DynamicsPlan
    gives what inverse_dynamics gives and reuses its arrays call after call."""
    from sewmech.dynamics import DynamicsPlan, force_structure

    fb = load_machine("fourbar-benchmark")
    st = force_structure(fb)
    assert st.block_sizes == (1, 2, 6)
    P = st.pattern[np.ix_(st.rperm, st.cperm)]
    ends = st.blk_ptr
    for b in range(len(ends) - 1):  # nothing to the left of a diagonal block
        assert not P[ends[b]:ends[b + 1], :ends[b]].any()
    jb = load_machine("jb1-3")
    sj = force_structure(jb)
    assert sum(sj.block_sizes) == 3 * (len(jb.link_names) - 1) and max(sj.block_sizes) < 20
    phi = np.radians(np.arange(0.0, 360.0, 15.0))
    plan = DynamicsPlan(jb, phi, rpm=900)
    designs = jb.parameters({"needle_bar.length": [43.0, 44.0, 45.0]},
                            inputs={"regulator": 0.4})
    for params in (designs, designs[2]):
        ref = inverse_dynamics(jb, phi, params=params, rpm=900)
        got = plan(params)
        np.testing.assert_array_equal(got.unknowns, ref.unknowns)
        np.testing.assert_array_equal(got.load_force, ref.load_force)
        np.testing.assert_array_equal(got.com_a, ref.com_a)
    first = plan(designs)
    torque = first.input_torque.copy()
    again = plan(designs[::-1].copy())
    assert again is first and np.shares_memory(first.unknowns, again.unknowns)
    np.testing.assert_array_equal(again.unknowns[0], ref.unknowns)
    # the derived quantities cached from the first call are dropped, the designs copied
    np.testing.assert_array_equal(again.input_torque[::-1], torque)
    np.testing.assert_array_equal(again.params, designs[::-1])
    np.testing.assert_array_equal(again.input_torque[0], ref.input_torque)


def test_written_block_solvers(monkeypatch):
    """The force kernel's written block solvers (sewmech._blocks) are what the generator writes;
    each solves random blocks as numpy's LU does, reports a singular block, solves other
    right-hand sides with the factors it keeps (the friction steps),
    and the whole JB1-3 solve agrees with the kernel's generic loop."""
    from sewmech.dynamics import DynamicsPlan
    from sewmech.engine import _blockgen, _blocks, _kernels
    from sewmech.engine._kernels import PIVOT_MIN

    assert open(_blocks.__file__).read() == _blockgen.source(), (
        "sewmech/engine/_blocks.py is stale: run python -m sewmech.engine._blockgen")
    rng = np.random.default_rng(7)
    ch, nk = _blocks.CHUNK, 37  # not a multiple of the vector width
    for n in range(1, _blocks.MAX_BLOCK + 1):
        off, start = 3, 2  # the block's place in the flat scratch arrays
        A = rng.normal(size=(nk, n, n)) * 10.0 ** rng.uniform(-3, 3, size=(nk, 1, 1))
        A[0] = np.eye(n)[rng.permutation(n)]  # a permutation: zero pivots without pivoting
        A[1, -1] = A[1, 0] * (n > 1)  # singular: two equal rows (n = 1: zero)
        x = rng.normal(size=(nk, n))
        b = np.einsum("kij,kj->ki", A, x)
        W = np.zeros((off + n * n + 2) * ch)
        W.reshape(-1, ch)[off:off + n * n, :nk] = A.reshape(nk, n * n).T
        B = np.zeros((start + n + 1) * ch)
        B.reshape(-1, ch)[start:start + n, :nk] = b.T
        X = np.full_like(B, 7.0)
        worst = np.full(ch, np.inf)
        foff = 2
        F = np.full((foff + n * (n + 2) + 1) * ch, 7.0)
        assert _blocks.block_qr(n, W, off, F, foff, B.copy(), X, start, nk, worst)
        got = X.reshape(-1, ch)[start:start + n, :nk].T
        assert (F.reshape(-1, ch)[[foff - 1, foff + n * (n + 2)]] == 7.0).all()
        # the kept factors (R and the reflectors, then each one's v0 and tau) solve another
        # right-hand side, as the force kernel's friction steps use them
        fac = F.reshape(-1, ch)[foff:foff + n * (n + 2), :nk].T
        b2 = np.einsum("kij,kj->ki", A, x[::-1])
        got2 = np.empty_like(b2)
        for k in range(nk):
            a, v0, tau = fac[k, :n * n].reshape(n, n), fac[k, n * n:n * n + n], fac[k, -n:]
            r = b2[k].copy()
            for j in range(n):
                v = np.r_[v0[j], a[j + 1:, j]]
                r[j:] -= tau[j] * (v @ r[j:]) * v
            got2[k] = np.linalg.solve(np.triu(a), r) if k != 1 else 0.0
        ok = np.ones(nk, dtype=bool)
        ok[1] = False
        ref = np.linalg.solve(A[ok], b[ok][..., None])[..., 0]
        np.testing.assert_allclose(got[ok], ref, rtol=1e-9, atol=1e-9 * np.abs(x).max())
        np.testing.assert_allclose(got2[ok], x[::-1][ok], rtol=1e-9, atol=1e-9 * np.abs(x).max())
        assert (X.reshape(-1, ch)[[start - 1, start + n]] == 7.0).all()  # nothing else written
        # the singular block's relative pivot is round-off (for n = 6: 3.8e-15 measured with
        # fused multiply-adds, 1.8e-15 without): at most the kernel's threshold for singular
        assert worst[1] <= PIVOT_MIN and (worst[nk:] == np.inf).all()
        # the pivot check sees how well posed a block is: sigma_min <= |R_jj| <= column norm
        w, cond = worst[:nk][ok], np.linalg.cond(A[ok])
        assert (w >= (1 - 1e-9) / cond).all() and (w <= math.sqrt(n) * (1 + 1e-12)).all()
    assert not _blocks.block_qr(_blocks.MAX_BLOCK + 1, W, 0, F, 0, B, X, 0, nk, worst)
    jb = load_machine("jb1-3")
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    designs = jb.parameters({"needle_bar.length": [43.0, 45.0]}, inputs={"regulator": 0.4})
    # what the plan asks of each force-kernel call: the largest block for the written solvers
    limits = []
    solve = _kernels.force_solve
    monkeypatch.setattr(_kernels, "force_solve", lambda *a: (limits.append(a[-1]), solve(*a))[1])
    plan = DynamicsPlan(jb, phi, rpm=1000)
    written = plan(designs).unknowns.copy()
    first = len(limits)
    plan._max_written = 0
    generic = plan(designs).unknowns
    # the two paths did run (asked of the kernel, not told by the round-off: without fused
    # multiply-adds the two do the same operations in the same order and agree to the bit)
    assert first > 0 and set(limits[:first]) == {_blocks.MAX_BLOCK} and set(limits[first:]) == {0}
    scale = np.abs(written).max(axis=-1, keepdims=True)
    assert np.abs(written - generic).max() / scale.max() < 1e-12


def test_singular_position_message():
    """A position whose force equations have a zero pivot is named by its crank angle (and
    design); positions that did not assemble (masked) are not reported."""
    from sewmech.dynamics import DynamicsPlan

    fb = load_machine("fourbar-benchmark")
    phi = np.radians(np.arange(0.0, 360.0, 10.0))
    plan = DynamicsPlan(fb, phi, masses={k: planar(*v) for k, v in TEST_LINKS.items()})
    res = plan(fb.parameters({"P.u": [10.0, 11.0]}))
    feasible = np.ones((2, phi.size), dtype=bool)
    minpiv = np.full((2, phi.size), 0.5)
    minpiv[1, 7] = 0.0
    with pytest.raises(SingularForceSystem, match=r"design \(1,\), phi = 70 deg"):
        plan._raise_singular(res.kin, feasible, minpiv)
    feasible[1, 7] = False
    plan._raise_singular(res.kin, feasible, minpiv)  # masked: nothing to report
