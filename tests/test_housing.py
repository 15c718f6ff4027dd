"""The housing on its mounts (issue 31): closed forms for the response and the modes, the
excitation against the shaking force and moment, balancing on the predicted vibration against
brute force and against Delta-Q, and the located errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sewmech.dynamics import inverse_dynamics

import sewmech
from sewmech.engine.errors import MachineFileError
from sewmech.engine.housing import (
    V_REF_MM_S,
    Housing,
    build_housing,
    excitation,
    housing_vibration,
    vibration,
)
from sewmech.engine.spec import HousingSpec
from test_dynamics import SC_TOML


def spec(**kw) -> HousingSpec:
    base = dict(mass={"mass": 10.0, "com": [0.0, 0.0, 0.0],
                      "inertia": [[2e5, 0.0, 0.0], [0.0, 3e5, 0.0], [0.0, 0.0, 4e5]]},
                mounts=[{"name": f"m{i}", "at_mm": p, "stiffness_N_per_mm": [50.0, 80.0, 60.0],
                         "damping_N_s_per_mm": [0.05, 0.08, 0.06]}
                        for i, p in enumerate([[100, 0, 0], [-100, 0, 0], [0, 100, 0],
                                               [0, -100, 0], [0, 0, 100], [0, 0, -100]])],
                control_points={"c": [0.0, 0.0, 0.0], "edge": [50.0, 20.0, -30.0]})
    base.update(kw)
    return HousingSpec.model_validate(base)


def house(**kw) -> Housing:
    return build_housing("test", "test.toml", spec(**kw))


def harmonic_wrench(n_phi, order, amp):
    """A wrench amp (6,) cos(order phi) over a turn of n_phi equal steps."""
    phi = np.arange(n_phi) * 2 * math.pi / n_phi
    return np.cos(order * phi)[:, None] * np.asarray(amp, float)


def test_a_symmetric_housing_is_six_single_oscillators():
    """Mounts placed symmetrically about the centre of mass decouple the six motions: each
    mode is one of them at sqrt(k/m), and a harmonic force along x at the centre of mass moves
    it as a single mass on a spring-damper: x = F / (k - m w^2 + i w c)."""
    h = house()
    f, shapes = h.modes()
    k = np.array([6 * 50.0 - 0, 0, 0]).sum()  # (ones along x: all six mounts' x stiffness)
    kx, ky, kz = 6 * 50.0, 6 * 80.0, 6 * 60.0
    # rotations: about x the y and z mounts' stiffness at 100 mm arms: 2 (ky_z + kz_y) 1e4
    krx = 2 * (80.0 + 60.0) * 100.0 ** 2
    kry = 2 * (50.0 + 60.0) * 100.0 ** 2
    krz = 2 * (50.0 + 80.0) * 100.0 ** 2
    want = np.sort([math.sqrt(kk / (1e-3 * mm)) / (2 * math.pi) for kk, mm in (
        (kx, 10.0), (ky, 10.0), (kz, 10.0), (krx, 2e5), (kry, 3e5), (krz, 4e5))])
    np.testing.assert_allclose(f, want, rtol=1e-12)
    assert k == kx
    for j in range(6):  # each mode one coordinate
        assert np.sort(np.abs(shapes[:, j]))[-2] < 1e-9
    rpm, F0 = 600.0, 12.0
    v = vibration(h, harmonic_wrench(72, 1, [F0, 0, 0, 0, 0, 0]), rpm)
    w = rpm * math.pi / 30
    x = (F0 / 2) / (kx - 1e-3 * 10.0 * w * w + 1j * w * 6 * 0.05)  # the e^{+iwt} amplitude
    assert v.Q[0, 0] == pytest.approx(x, rel=1e-12)
    assert np.abs(v.Q[1:]).max() <= 1e-15 * abs(x) and np.abs(v.Q[0, 1:]).max() <= 1e-15
    # the control point at the centre of mass: RMS = |w x| sqrt(2) ... of a real cos
    assert v.rms_velocity[0, 0] == pytest.approx(math.sqrt(2) * abs(1j * w * x), rel=1e-12)
    assert v.level_db[0, 0] == pytest.approx(
        20 * math.log10(v.rms_velocity[0, 0] / V_REF_MM_S), rel=1e-12)
    # the velocity over the turn is the derivative of the displacement: its RMS
    vt = v.velocity_in_time(720)
    assert np.sqrt(np.mean(vt[:, 0, 0] ** 2)) == pytest.approx(v.rms_velocity[0, 0], rel=1e-12)


def test_a_bar_on_two_mounts_bounces_and_pitches_as_its_two_degrees_of_freedom():
    """A body on two vertical mounts at x = -a and x = +b (the other directions held by soft
    springs at its centre): bounce and pitch coupled, against the 2 x 2 closed form."""
    a, b, k1, k2, m, J = 120.0, 80.0, 90.0, 40.0, 6.0, 4e4
    mounts = [{"name": "left", "at_mm": [-a, 0, 0], "stiffness_N_per_mm": [0.0, k1, 0.0]},
              {"name": "right", "at_mm": [b, 0, 0], "stiffness_N_per_mm": [0.0, k2, 0.0]},
              {"name": "hold", "at_mm": [0, 0, 0], "stiffness_N_per_mm": [30.0, 0.0, 30.0]},
              {"name": "hold rx", "at_mm": [0, 0, 50], "stiffness_N_per_mm": [0.0, 20.0, 0.0]},
              {"name": "hold ry", "at_mm": [0, 0, 50], "stiffness_N_per_mm": [20.0, 0.0, 0.0]},
              {"name": "hold ry2", "at_mm": [0, 0, -50], "stiffness_N_per_mm": [20.0, 20.0,
                                                                                0.0]}]
    h = house(mass={"mass": m, "com": [0.0, 0.0, 0.0],
                    "inertia": [[3e4, 0, 0], [0, 3e4, 0], [0, 0, J]]},
              mounts=mounts, loss_factor=0.0, control_points={"c": [0.0, 0.0, 0.0]})
    # bounce y and pitch about z: K = [[k1 + k2, k2 b - k1 a], [.., k1 a^2 + k2 b^2]]
    K2 = np.array([[k1 + k2 + 20.0 * 2, k2 * b - k1 * a], [k2 * b - k1 * a,
                                                           k1 * a * a + k2 * b * b]])
    M2 = np.diag([m, J]) * 1e-3
    from scipy.linalg import eigh

    want = np.sqrt(eigh(K2, M2, eigvals_only=True)) / (2 * math.pi)
    f, _ = h.modes()
    for w in want:
        assert np.min(np.abs(f - w)) <= 1e-9 * w
    # a moment about z at 2 x the shaft speed: the 2 x 2 solve
    rpm, Mz = 900.0, 3000.0
    v = vibration(h, harmonic_wrench(90, 2, [0, 0, 0, 0, 0, Mz]), rpm)
    w = 2 * rpm * math.pi / 30
    q = np.linalg.solve(K2 - w * w * M2, np.array([0.0, Mz / 2]))
    np.testing.assert_allclose(v.Q[1, [1, 5]], q, rtol=1e-10)


def test_the_excitation_adds_up_to_the_shaking_force_and_moment():
    """The wrench on the housing (the bearings in 3-D, each pair in its plane, the springs,
    the couples, the motor's reaction): its x and y forces are the shaking force and its moment
    about z the shaking moment, at every angle (no gravity); its moments about x and y those of
    the same forces at their planes."""
    m = sewmech.load_machine("jb1-3")
    h = Housing.of(m)
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    r = inverse_dynamics(m, phi, gravity=False, loads=[])
    W = excitation(m, h, r)
    scale = np.abs(r.shaking_force).max()
    np.testing.assert_allclose(W[:, :2], r.shaking_force, rtol=0, atol=1e-9 * scale)
    assert np.abs(W[:, 2]).max() == 0.0
    np.testing.assert_allclose(W[:, 5], r.shaking_moment, rtol=0,
                               atol=1e-9 * np.abs(r.shaking_moment).max())
    assert np.abs(W[:, 3:5]).max() > 100.0  # N mm: the planes along the shaft matter


def test_vibration_of_a_batch_equals_one_design_at_a_time():
    m = sewmech.load_machine("jb1-3")
    P = m.parameters({"needle_bar.length": [43.0, 44.0, 45.0]})
    batch = housing_vibration(m, 5.0, params=P)
    for i in range(3):
        one = housing_vibration(m, 5.0, params=P[i])
        np.testing.assert_allclose(batch.level_db[i], one.level_db, rtol=1e-12)


def test_balancing_on_vibration_against_brute_force():
    """balance --criterion vibration and equal-levels on JB1-3's extra counterweight against the
    whole machine evaluated at many static moments (the housing's response from each design's
    own inverse dynamics, not the basis)."""
    from sewmech.balancing import balance, balance_basis

    m = with_text_no_friction("jb1-3")
    B = balance_basis(m, ["extra"], step_deg=4.0)
    S = np.linspace(0.0, 3.0, 13)  # kg mm
    curves = []
    for s_ in S:
        mm = m.with_parameters({"extra.static_moment": s_, "extra.angle": math.pi})
        v = housing_vibration(mm, 4.0)
        curves.append(v.rms_velocity[0, :2])
    curves = np.array(curves)
    pred = B.velocities(B.quantities(S[:, None, None] * np.array([-1.0, 0.0]))["W"])
    np.testing.assert_allclose(pred, curves, rtol=1e-9)
    # the criteria's fast route (the basis' velocity harmonics combined) is the same
    fast = B.velocities_at(S[:, None, None] * np.array([-1.0, 0.0]))
    np.testing.assert_allclose(fast, curves, rtol=1e-9)
    res = balance(m, "vibration", basis=B)
    xy = np.array([[res.counterweights["extra"]["static_moment_gcm"] / 100 * math.cos(
        math.radians(res.counterweights["extra"]["angle_deg"])),
        res.counterweights["extra"]["static_moment_gcm"] / 100 * math.sin(
        math.radians(res.counterweights["extra"]["angle_deg"]))]])
    best = float(B.velocities(B.quantities(xy[None])["W"]).max())
    # no static moment on a grid around it does better
    rng = np.random.default_rng(7)
    trial = xy[None] + rng.normal(0.0, 0.05, (400, 1, 2))
    assert B.velocities(B.quantities(trial)["W"]).max(axis=-1).min() >= best - 1e-9 * best


def with_text_no_friction(name):
    from test_dynamics import without_friction

    return without_friction(name)


def test_equal_levels_reduce_to_delta_q_for_a_pure_first_harmonic():
    """With equal mounts along x and y, the control point at the centre of mass, and a
    slider-crank whose rod is so long that its shaking force is a pure first harmonic
    (r / l = 1e-4), equal x and y levels are max|Qx| = max|Qy|: the balancing paper's Delta-Q
    and its measured criterion agree (to the second harmonic's share, r / l)."""
    from sewmech.balancing import balance, balance_basis

    text = SC_TOML.replace("length = 44.0", "length = 150000.0") + """
[counterweights.cw]
link = "crank"
static_moment_gcm = 0.0
angle_deg = 180.0
radius_mm = 20.0

[housing]
loss_factor = 0.05
control_points = { com = [0.0, 0.0, 0.0] }
[housing.mass]
mass = 8.0
com = [0.0, 0.0, 0.0]
inertia = [[4e4, 0.0, 0.0], [0.0, 4e4, 0.0], [0.0, 0.0, 4e4]]
[[housing.mounts]]
name = "a"
at_mm = [100.0, 0.0, 0.0]
stiffness_N_per_mm = [60.0, 60.0, 60.0]
[[housing.mounts]]
name = "b"
at_mm = [-100.0, 0.0, 0.0]
stiffness_N_per_mm = [60.0, 60.0, 60.0]
[[housing.mounts]]
name = "c"
at_mm = [0.0, 100.0, 0.0]
stiffness_N_per_mm = [60.0, 60.0, 60.0]
[[housing.mounts]]
name = "d"
at_mm = [0.0, -100.0, 0.0]
stiffness_N_per_mm = [60.0, 60.0, 60.0]
[[housing.mounts]]
name = "e"
at_mm = [0.0, 0.0, 100.0]
stiffness_N_per_mm = [60.0, 60.0, 60.0]
[[housing.mounts]]
name = "f"
at_mm = [0.0, 0.0, -100.0]
stiffness_N_per_mm = [60.0, 60.0, 60.0]
""".replace("guide_point = \"G\"", "guide_point = \"G\"")
    m = sewmech.machine_from_toml(text.replace("branch = -1", "branch = -1"))
    B = balance_basis(m, ["cw"], step_deg=5.0, moment_point=(0.0, 0.0))
    dq = balance(m, "delta-q", basis=B).counterweights["cw"]["static_moment_gcm"]
    eq = balance(m, "equal-levels", basis=B).counterweights["cw"]["static_moment_gcm"]
    assert eq == pytest.approx(dq, rel=1e-3)


@pytest.mark.parametrize("change, says", [
    (dict(mounts=[{"name": "only", "at_mm": [0, 0, 0], "stiffness_N_per_mm": [10, 10, 10]}]),
     "free to move"),
    (dict(control_points={"far": [0, 900.0, 0]}, bounds_mm=[[-200, 200], [-200, 200],
                                                           [-200, 200]]), "not on the housing"),
])
def test_bad_housings_are_located_errors(change, says):
    with pytest.raises(MachineFileError, match=says):
        house(**change)


@pytest.mark.parametrize("text, key", [
    ('stiffness_N_per_mm = [-5.0, 10.0, 10.0]', "stiffness_N_per_mm"),
    ('damping_N_s_per_mm = [-0.1, 0.0, 0.0]', "damping_N_s_per_mm"),
])
def test_negative_mount_values_are_refused(text, key):
    mounts = [{"name": "m", "at_mm": [0, 0, 0], "stiffness_N_per_mm": [1, 1, 1]}]
    bad = dict(mounts[0])
    field, value = text.split(" = ")
    bad[field] = eval(value)  # noqa: S307 (a literal list)
    with pytest.raises(Exception, match=key):
        spec(mounts=[bad])


def test_balance_on_the_housing_from_the_command_line(tmp_path):
    """balance --criterion equal-levels/vibration: the answer is the library's, the levels
    before and after are reported, the predicted v_x(S), v_y(S) figure is written, and the
    options that do not fit are located."""
    import json

    from sewmech.design.balancing import balance
    from sewmech.engine.machine import load_machine
    from test_balancing_cli import run

    code, text = run("balance", "bartack-1820", "--criterion", "equal-levels", "--json")
    assert code == 0, text
    data = json.loads(text)
    lib = balance(load_machine("bartack-1820"), "equal-levels", ["extra"])
    S = data["counterweights"]["extra"]["static_moment_gcm"]
    assert S == pytest.approx(lib.counterweights["extra"]["static_moment_gcm"], rel=1e-9)
    assert data["after"]["vibration_x_db"] == pytest.approx(data["after"]["vibration_y_db"],
                                                            abs=1e-6)
    code, text = run("balance", "bartack-1820", "--criterion", "vibration", "--out",
                     tmp_path / "b")
    assert code == 0, text
    assert "vibration level at the control point along x" in text and " dB " in text
    levels = (tmp_path / "b" / "bartack-1820-bal-levels.csv").read_text()
    assert levels.startswith("S_gcm,vx_mm_s,vy_mm_s")
    code, text = run("balance", "bartack-1820", "--criterion", "peak", "--control-point",
                     "hands")
    assert code == 2 and "--control-point" in text
    code, text = run("balance", "bartack-1820", "--criterion", "vibration",
                     "--control-point", "elbow")
    assert code == 2 and "--control-point" in text and "hands" in text
    code, text = run("balance", "fourbar-benchmark", "--criterion", "vibration")
    assert code == 2 and "[housing]" in text and "Traceback" not in text


def test_a_plane_for_a_pair_the_machine_lacks_is_located():
    """planes_mm names frame pairs and springs: a misspelt one would act in the default plane
    without a word, so it is refused with the names there are."""
    from importlib import resources

    from sewmech.engine.machine import machine_from_toml

    text = resources.files("sewmech.data.machines").joinpath("jb1-3.toml").read_text("utf-8")
    text = text.replace('planes_mm = { "needle_bar.guide" = 0.0,',
                        'planes_mm = { "needle_bar.guid" = 0.0,', 1)
    assert "needle_bar.guid\"" in text
    m = machine_from_toml(text)
    with pytest.raises(MachineFileError, match=r"planes_mm.*needle_bar\.guid.*needle_bar\.guide"):
        Housing.of(m)
