"""Engine identities: analytic rates vs differences, loop solver vs closed-form units,
vectorised vs per-design loop, rigid-motion invariance, periodicity, closure residuals."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sewmech
from conftest import BENCH, FOURBAR_LOOP, PHI, fourbar, slider_crank

W = 1.0  # rad/s: then d/dt = d/dphi


def central(machine, phi, h=1e-5, **kw):
    """Central differences in phi of positions/angles/variables and their rates."""
    rp = sewmech.kinematics(machine, phi + h, omega=W, **kw)
    rm = sewmech.kinematics(machine, phi - h, omega=W, **kw)
    wrap = lambda x: np.angle(np.exp(1j * x))  # noqa: E731
    return {
        "v": (rp.p - rm.p) / (2 * h),
        "a": (rp.v - rm.v) / (2 * h),
        "omega": wrap(rp.theta - rm.theta) / (2 * h),
        "epsilon": (rp.omega - rm.omega) / (2 * h),
        "q_dot": (rp.q - rm.q) / (2 * h),
        "q_ddot": (rp.q_dot - rm.q_dot) / (2 * h),
    }


def assert_rates(machine, phi, rel=1e-6, **kw):
    r = sewmech.kinematics(machine, phi, omega=W, **kw)
    fd = central(machine, phi, **kw)
    for name, approx in fd.items():
        exact = getattr(r, name)
        if exact.size == 0:
            continue
        scale = max(np.abs(exact).max(), 1e-300)
        err = np.abs(approx - exact).max() / scale
        assert err <= rel, f"{name}: relative error {err:.2e}"


def rpr_machine(e=3.0, branch=1):
    """Crank-driven slotted link: the block pinned at the crank pin slides in the slot of a
    link pivoting at D (the hook-drive rotating guide), then a point on that link."""
    return sewmech.machine_from_toml(f"""
[machine]
name = "rpr"
[convention]
reference_event = "crank along +x"
reference_phi_deg = 0.0
[points.A]
x = 0.0
y = 0.0
[points.D]
x = 0.0
y = -40.0
[[units]]
type = "crank"
name = "crank"
pivot = "A"
points = {{ B = [15.0, 0.0] }}
[[units]]
type = "rpr"
name = "guide"
pin = "B"
pivot = "D"
link = "slotted"
block = "block"
offset = {e}
branch = {branch}
[[units]]
type = "point"
name = "tip"
link = "slotted"
origin = "D"
points = {{ T = [70.0, 5.0] }}
""")


def rrp_moving_guide():
    """Slider whose guide is a moving link (a slot in a rocker): four-bar, then a crank of a
    second shaft whose pin block slides in the rocker's slot."""
    return sewmech.machine_from_toml("""
[machine]
name = "rrp-slot"
[convention]
reference_event = "crank along +x"
reference_phi_deg = 0.0
[points.A]
x = 0.0
y = 0.0
[points.D]
x = 38.0
y = 0.0
[points.E]
x = 27.0
y = 28.0
[[units]]
type = "crank"
name = "crank"
pivot = "A"
points = { B = [15.0, 0.0] }
[[units]]
type = "rrr"
name = "dyad"
joints = ["B", "D"]
new = "C"
links = ["coupler", "rocker"]
lengths = [40.0, 35.0]
branch = 1
[[units]]
type = "rrp"
name = "slot"
pin = "E"
rod = "lower_crank"
length = 20.0
new = "K"
slider = "slot_block"
guide_point = "D"
guide_link = "rocker"
guide_angle_deg = 2.0
offset = 1.5
branch = 1
""")


def test_rates_fourbar():
    assert_rates(fourbar(), PHI)


def test_rates_slider_crank_offset():
    assert_rates(slider_crank(e=4.0, alpha=80.0, gx=3.0, gy=-2.0), PHI)


def test_rates_rotating_guide():
    assert_rates(rpr_machine(), PHI)


def test_rates_slider_on_moving_guide():
    assert_rates(rrp_moving_guide(), PHI)


def test_rates_loop_solver():
    m = sewmech.machine_from_toml(FOURBAR_LOOP.format(**BENCH, assembly=0.0, g_coupler=60.0,
                                                      g_rocker=95.0))
    assert_rates(m, PHI)


def test_rates_with_prescribed_speed_and_acceleration():
    """omega(phi), epsilon(phi): v = p' omega and a = p'' omega^2 + p' epsilon."""
    m = fourbar()
    omega = 100.0 + 20.0 * np.sin(PHI)
    eps = 30.0 * np.cos(2 * PHI)
    r = sewmech.kinematics(m, PHI, omega=omega, epsilon=eps)
    unit = sewmech.kinematics(m, PHI, omega=1.0)
    fd = central(m, PHI)
    np.testing.assert_allclose(r.v, unit.v * omega[:, None, None], rtol=1e-12, atol=1e-9)
    a_expected = fd["a"] * omega[:, None, None] ** 2 + unit.v * eps[:, None, None]
    scale = np.abs(r.a).max()
    assert np.abs(r.a - a_expected).max() / scale < 1e-6
    np.testing.assert_allclose(r.epsilon, unit.epsilon * omega[:, None] ** 2
                               + unit.omega * eps[:, None], rtol=1e-10, atol=1e-8)


def test_loop_solver_equals_closed_form_fourbar():
    closed = sewmech.kinematics(fourbar(), PHI)
    m = sewmech.machine_from_toml(FOURBAR_LOOP.format(**BENCH, assembly=40.0, g_coupler=70.0,
                                                      g_rocker=100.0))
    loop = sewmech.kinematics(m, PHI)
    for name in ("coupler", "rocker"):
        a, b = closed.link(name), loop.link(name)
        assert np.abs(np.angle(np.exp(1j * (a.theta - b.theta)))).max() < 1e-11
        np.testing.assert_allclose(b.omega, a.omega, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(b.epsilon, a.epsilon, rtol=1e-8, atol=1e-6)
    assert np.nanmax(loop.loop_residual) <= 1e-9


def test_loop_solver_equals_closed_form_slider_and_rotating_guide():
    """A loop with a length unknown (slider) and one with the slot angle unknown (guide)."""
    loop = sewmech.machine_from_toml("""
[machine]
name = "loops"
[convention]
reference_event = "crank along +x"
reference_phi_deg = 0.0
[points.A]
x = 0.0
y = 0.0
[points.D]
x = 0.0
y = -40.0
[[units]]
type = "crank"
name = "crank"
pivot = "A"
points = { B = [15.0, 0.0] }
[[units]]
type = "loop"
name = "guide"
unknown_links_deg = { slotted = 80.0 }
unknown_lengths_mm = { s = 40.0 }
loops = [ { name = "DB", terms = [ {point = "D"}, {link = "slotted", length = 3.0, angle_deg = 90.0},
          {link = "slotted", length = "s"}, {point = "B", sign = -1} ] } ]
""")
    a = sewmech.kinematics(rpr_machine(e=3.0), PHI)
    b = sewmech.kinematics(loop, PHI)
    assert np.abs(np.angle(np.exp(1j * (a.link("slotted").theta - b.link("slotted").theta)))).max() < 1e-11
    np.testing.assert_allclose(b.variable("s").q, a.variable("guide").q, atol=1e-10)
    np.testing.assert_allclose(b.variable("s").q_dot, a.variable("guide").q_dot, rtol=1e-9, atol=1e-8)
    np.testing.assert_allclose(b.variable("s").q_ddot, a.variable("guide").q_ddot, rtol=1e-8, atol=1e-5)
    np.testing.assert_allclose(b.link("slotted").epsilon, a.link("slotted").epsilon, rtol=1e-8, atol=1e-6)


@given(f=st.lists(st.floats(0.97, 1.03), min_size=4, max_size=4),
       pu=st.floats(-40, 40), pv=st.floats(-40, 40))
@settings(max_examples=30, deadline=None)
def test_closure_residual_random_designs(f, pu, pv):
    """Every joint distance holds to 1e-9 mm at every position (checked from the outputs)."""
    ab, bc, cd, ad = 15 * f[0], 40 * f[1], 35 * f[2], 38 * f[3]
    m = fourbar(ab=ab, bc=bc, cd=cd, dx=ad, pu=pu, pv=pv)
    r = sewmech.kinematics(m, PHI)
    A, B, C, D, P = (r.point(n).p for n in "ABCDP")
    dist = lambda x, y: np.hypot(*(x - y).T)  # noqa: E731
    assert np.abs(dist(A, B) - ab).max() <= 1e-9
    assert np.abs(dist(B, C) - bc).max() <= 1e-9
    assert np.abs(dist(C, D) - cd).max() <= 1e-9
    assert np.abs(dist(B, P) - math.hypot(pu, pv)).max() <= 1e-9
    assert np.abs(dist(C, P) - math.hypot(pu - bc, pv)).max() <= 1e-9


def test_vectorised_equals_per_design_loop(rng):
    m = fourbar()
    f = rng.uniform(0.97, 1.03, size=(4, 5, 4))
    params = m.parameters({"B.u": 15 * f[..., 0], "dyad.length1": 40 * f[..., 1],
                           "dyad.length2": 35 * f[..., 2], "D.x": 38 * f[..., 3]})
    batch = sewmech.kinematics(m, PHI, params=params, on_failure="mask")
    assert batch.p.shape == (4, 5, PHI.size, len(m.point_names), 2)
    for idx in np.ndindex(4, 5):
        one = sewmech.kinematics(m, PHI, params=params[idx], on_failure="mask")
        # exact: the kernel evaluates each design by itself (its own rows, the same compiled
        # code), so a batch holds the very numbers of its designs alone
        for name in ("p", "v", "a", "theta", "omega", "epsilon", "feasible"):
            np.testing.assert_array_equal(getattr(batch, name)[idx], getattr(one, name))


def test_loop_vectorised_equals_per_design(rng):
    m = sewmech.machine_from_toml(FOURBAR_LOOP.format(**BENCH, assembly=0.0, g_coupler=60.0,
                                                      g_rocker=95.0))
    params = m.parameters({"fourbar.ABCD.1.length": rng.uniform(39, 41, 6)})
    batch = sewmech.kinematics(m, PHI, params=params)
    for i in range(6):
        one = sewmech.kinematics(m, PHI, params=params[i])
        # exact, as above: the loop solver marches each design by itself
        np.testing.assert_array_equal(batch.theta[i], one.theta)
        np.testing.assert_array_equal(batch.epsilon[i], one.epsilon)


@pytest.mark.parametrize("gamma", [0.3, -2.0])
def test_rigid_motion_invariance(gamma):
    """Rotating the frame by gamma and shifting it rotates every point and adds gamma to every
    angle; speeds keep their size."""
    shift = np.array([12.0, -7.0])
    R = np.array([[math.cos(gamma), -math.sin(gamma)], [math.sin(gamma), math.cos(gamma)]])
    A2 = shift
    D2 = R @ np.array([38.0, 0.0]) + shift
    base = sewmech.kinematics(fourbar(), PHI)
    moved = sewmech.kinematics(fourbar(ax=A2[0], ay=A2[1], dx=D2[0], dy=D2[1],
                                       phase=math.degrees(gamma)), PHI)
    np.testing.assert_allclose(moved.p, base.p @ R.T + shift, atol=1e-10)
    np.testing.assert_allclose(moved.v, base.v @ R.T, rtol=1e-10, atol=1e-7)
    np.testing.assert_allclose(moved.a, base.a @ R.T, rtol=1e-10, atol=1e-5)
    d = np.angle(np.exp(1j * (moved.theta[:, 1:] - base.theta[:, 1:] - gamma)))
    assert np.abs(d).max() < 1e-11
    np.testing.assert_allclose(moved.omega, base.omega, rtol=1e-10, atol=1e-9)


@pytest.mark.parametrize("make", [fourbar, slider_crank, rpr_machine, rrp_moving_guide])
def test_periodicity(make):
    m = make()
    a = sewmech.kinematics(m, PHI)
    b = sewmech.kinematics(m, PHI + 2 * math.pi)
    np.testing.assert_allclose(b.p, a.p, atol=1e-10)
    np.testing.assert_allclose(b.v, a.v, rtol=1e-9, atol=1e-8)
    np.testing.assert_allclose(b.a, a.a, rtol=1e-9, atol=1e-6)


def test_loop_results_do_not_depend_on_the_requested_grid():
    """Continuation always starts at the assembly angle: one angle alone or in a grid agrees."""
    m = sewmech.machine_from_toml(FOURBAR_LOOP.format(**BENCH, assembly=0.0, g_coupler=60.0,
                                                      g_rocker=95.0))
    grid = sewmech.kinematics(m, PHI)
    for i in (0, 17, 100):
        one = sewmech.kinematics(m, PHI[i:i + 1])
        np.testing.assert_allclose(one.theta[0], grid.theta[i], atol=1e-12)


def test_branch_is_reported_and_respected():
    up = sewmech.kinematics(fourbar(branch=1), PHI)
    down = sewmech.kinematics(fourbar(branch=-1), PHI)
    assert up.branches == {"dyad": 1} and down.branches == {"dyad": -1}
    B, C_up, C_dn, D = up.point("B").p, up.point("C").p, down.point("C").p, up.point("D").p
    cross = lambda o, a, b: (a - o)[:, 0] * (b - o)[:, 1] - (a - o)[:, 1] * (b - o)[:, 0]  # noqa
    assert (cross(B, D, C_up) > 0).all() and (cross(B, D, C_dn) < 0).all()


def test_rotating_guide_closed_form():
    """Slot through the pin B = 15(cos t, sin t) with offset e from D: angle and s by hand."""
    e = 3.0
    r = sewmech.kinematics(rpr_machine(e=e), PHI)
    B = 15.0 * np.stack([np.cos(PHI), np.sin(PHI)], -1)
    d = B - np.array([0.0, -40.0])
    s = np.sqrt((d**2).sum(-1) - e * e)
    th = np.arctan2(d[:, 1], d[:, 0]) - np.arctan2(e, s)
    assert np.abs(np.angle(np.exp(1j * (r.link("slotted").theta - th)))).max() < 1e-12
    np.testing.assert_allclose(r.variable("guide").q, s, atol=1e-12)


@pytest.mark.parametrize("loop", [False, True])
def test_threaded_kernel_equals_serial(rng, monkeypatch, loop):
    """Big batches run on the threaded kernel (designs in chunks over the cores); it must give
    bit-for-bit the serial answer, infeasible designs and masks included."""
    import importlib

    kin = importlib.import_module("sewmech.kinematics")
    if loop:
        m = sewmech.machine_from_toml(FOURBAR_LOOP.format(**BENCH, assembly=0.0,
                                                          g_coupler=60.0, g_rocker=95.0))
        params = m.parameters({"fourbar.ABCD.1.length": rng.uniform(39, 41, 9)})
    else:
        m = fourbar()
        f = rng.uniform(0.97, 1.03, size=(9, 4))
        f[4, 0] = 2.6  # a crank of 39 mm: this design cannot turn fully
        params = m.parameters({"B.u": 15 * f[:, 0], "dyad.length1": 40 * f[:, 1],
                               "dyad.length2": 35 * f[:, 2], "D.x": 38 * f[:, 3]})
    calls = []
    orig = kin.run_chunks
    monkeypatch.setattr(kin, "run_chunks", lambda *a, **k: (calls.append("threads"),
                                                          orig(*a, **k))[1])
    monkeypatch.setattr(kin, "_PARALLEL_MIN_WORK", 10**12)
    serial = sewmech.kinematics(m, PHI, params=params, on_failure="mask")
    assert calls == []
    monkeypatch.setattr(kin, "_PARALLEL_MIN_WORK", 0)
    from sewmech.engine import _threads

    monkeypatch.setattr(_threads.config, "NUMBA_NUM_THREADS", 2)  # chunks on two threads
    threaded = sewmech.kinematics(m, PHI, params=params, on_failure="mask")
    assert calls == ["threads"]
    if not loop:
        assert 0 < (~serial.feasible).sum() < serial.feasible.size
    for name in ("p", "v", "a", "theta", "omega", "epsilon", "q", "feasible", "failure_unit",
                 "loop_residual"):
        np.testing.assert_array_equal(getattr(threaded, name), getattr(serial, name))


def test_only_the_units_an_output_needs_are_solved():
    """Asking for a few outputs evaluates only the units they depend on: the values are bit for
    bit those of the full evaluation, and a unit outside the chain cannot fail the call."""
    m = sewmech.load_machine("jb1-3")
    phi = np.radians(np.arange(0.0, 360.0, 10.0))
    full = sewmech.kinematics(m, phi)
    part = sewmech.kinematics(m, phi, points=["needle.eye"], links=["take_up_lever"],
                              variables=["needle_bar"])
    for name in ("p_needle.eye_x", "v_needle.eye_y", "a_needle.eye_y", "theta_take_up_lever",
                 "epsilon_take_up_lever", "qdd_needle_bar"):
        assert np.array_equal(part.channel(name)[0], full.channel(name)[0]), name
    assert np.isnan(part.loop_residual).all() and np.isfinite(full.loop_residual).all()
    rows = m.selection(["needle.eye"], [], [])[-1]
    assert {m.unit_names[m.kernel_unit_of_row[r]] for r in rows if m.kernel_unit_of_row[r] >= 0} \
        == {"needle_crank", "needle_bar", "needle"}
    # a feed that cannot be assembled (lift crank pad far above the eccentric) fails only the
    # calls that need the feed
    p = m.parameters({"lift.cam.3.length": 40.0})
    r = sewmech.kinematics(m, phi, params=p, points=["needle.eye"], links=[], variables=[])
    assert r.all_feasible
    with pytest.raises(sewmech.ConvergenceError, match="lift"):
        sewmech.kinematics(m, phi, params=p, points=["feed_dog.tip"], links=[], variables=[])
    masked = sewmech.kinematics(m, phi, params=p, on_failure="mask")
    assert not masked.feasible.any()
    assert {masked.unit_names[u] for u in np.unique(masked.failure_unit)} == {"lift"}


def test_parameters_on_a_given_base():
    m = sewmech.load_machine("fourbar-benchmark")
    base = m.parameters({"B.u": 14.0})
    p = m.parameters({"dyad.length1": [39.0, 41.0]}, base=base)
    assert p.shape == (2, m.defaults.size)
    assert np.all(p[:, m.parameter_index("B.u")] == 14.0)
    assert list(p[:, m.parameter_index("dyad.length1")]) == [39.0, 41.0]
    with pytest.raises(ValueError, match="base must end in"):
        m.parameters({}, base=np.zeros(3))


def test_plan_equals_kinematics_and_reuses_its_arrays():
    """A prepared plan gives bit for bit what kinematics() gives (loops, setting inputs, a
    batch); its result views the plan's arrays, so the next call of the same batch shape
    overwrites it, while a call with another batch shape leaves it alone."""
    m = sewmech.load_machine("jb1-3")
    phi = np.radians(np.arange(0.0, 360.0, 7.5))
    pts = ["feed_dog.tip", "take_up.eye"]
    plan = sewmech.KinematicsPlan(m, phi, points=pts, links=["feed_bar"], rpm=800)
    batch = m.parameters({"feed_cam.stroke": [6.5, 7.0, 7.5]})
    for params, inputs in ((None, {"regulator": 0.3}), (batch, {"regulator": -0.2}),
                           (batch[1], None)):
        ref = sewmech.kinematics(m, phi, params=params, inputs=inputs, points=pts,
                                 links=["feed_bar"], rpm=800)
        got = plan(params, inputs=inputs)
        for name in ("p", "v", "a", "theta", "omega", "epsilon", "feasible", "loop_residual"):
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)
    first = plan(batch, inputs={"regulator": 0.3})
    kept = first.p.copy()
    again = plan(batch, inputs={"regulator": -0.3})  # same batch shape: same arrays
    assert again is first and not np.array_equal(first.p, kept)
    kept = first.p.copy()
    other = plan(batch[0])  # another batch shape: new arrays, the old result is left alone
    assert np.array_equal(first.p, kept) and other.p.shape == kept.shape[1:]
    assert plan(batch) is not first and np.array_equal(first.p, kept)
    assert not first.p.flags.writeable


def test_plan_clears_the_failures_of_its_last_call():
    """feasible and failure_unit are reset when a design that failed is followed by one that
    assembles; on_failure='raise' names the unit and the angle as kinematics() does."""
    m = fourbar()
    plan = sewmech.KinematicsPlan(m, PHI, on_failure="mask")
    bad = m.parameters({"B.u": 39.0})  # this crank cannot turn fully
    r = plan(bad)
    assert 0 < (~r.feasible).sum() < r.feasible.size
    assert set(np.unique(r.failure_unit)) == {-1, m.unit_names.index("dyad")}
    assert np.isnan(r.p[~r.feasible]).all()
    r = plan()
    assert r.all_feasible and (r.failure_unit == -1).all()
    strict = sewmech.KinematicsPlan(m, PHI)
    with pytest.raises(sewmech.AssemblyError, match="dyad"):
        strict(bad)
    assert strict().all_feasible


def test_branch_free_atan2_matches_libm():
    """The kernels' atan2 (a rational approximation with selects, so that loops of it
    vectorise) is within 2 ulp of math.atan2 everywhere, the axes, diagonals and signed
    zeros included."""
    from sewmech.engine._kernels import atan2

    rng = np.random.default_rng(3)
    ang = np.concatenate([rng.uniform(-math.pi, math.pi, 20000),
                          np.repeat(np.arange(-4, 5) * math.pi / 4, 200)
                          + rng.normal(size=1800) * 1e-9,
                          np.arctan(0.66) + rng.normal(size=400) * 1e-12])
    rad = 10.0 ** rng.uniform(-6, 6, ang.size)
    for y, x in zip(rad * np.sin(ang), rad * np.cos(ang)):
        ref = math.atan2(y, x)
        assert abs(atan2(y, x) - ref) <= 2 * np.spacing(abs(ref)), (y, x)
    for y in (0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300):
        for x in (0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300):
            if y == 0.0 and x == 0.0 and math.copysign(1.0, x) > 0:
                assert atan2(y, x) == 0.0
                continue
            got, ref = atan2(y, x), math.atan2(y, x)
            assert abs(got - ref) <= 2 * np.spacing(abs(ref)) and (
                math.copysign(1.0, got) == math.copysign(1.0, ref)), (y, x, got, ref)


def test_one_compiled_kernel_for_read_only_and_writable_inputs():
    """The machine's tables and defaults are read-only, a caller's designs are not: the kernels
    get read-only views either way, so numba compiles each kernel once (a second compile of
    the interpreter costs about 20 s)."""
    from sewmech.engine import _kernels as K
    from sewmech.dynamics import inverse_dynamics

    m = sewmech.load_machine("fourbar-benchmark")
    phi = np.radians([0.0, 90.0])
    sewmech.kinematics(m, phi)
    inverse_dynamics(m, phi)
    n_kin, n_force = len(K.evaluate_program.signatures), len(K.force_solve.signatures)
    mine = m.parameters({"P.u": [10.0, 11.0]})
    assert mine.flags.writeable and not m.defaults.flags.writeable
    sewmech.kinematics(m, phi, params=mine, omega=np.full(2, 50.0))
    sewmech.KinematicsPlan(m, phi, points=["C"])(mine[0].copy())
    inverse_dynamics(m, phi, params=mine, masses={})
    assert len(K.evaluate_program.signatures) == n_kin
    assert len(K.force_solve.signatures) == n_force


def test_counterweights_and_friction_use_the_installs_force_kernel():
    """A counterweight of some mass adds force solves with no applied forces and frictionless,
    then a second solve with friction: all with the same array types as the machine's own
    solve, which the install compiles (a read-only array there cost a second 15 s compile in
    the first report, issue 34); the pairs' directions likewise."""
    from sewmech.engine import _kernels as K
    from sewmech.engine.dynamics import inverse_dynamics, pair_geometry

    m = sewmech.load_machine("jb1-3")  # [friction], and an extra counterweight of 0 g cm
    phi = np.radians([0.0, 90.0])
    inverse_dynamics(m, phi)
    pair_geometry(m, sewmech.kinematics(m, phi))
    n_force, n_pairs = len(K.force_solve.signatures), len(K.pair_geometry.signatures)
    heavy = m.parameters({"extra.static_moment": 200.0})
    inverse_dynamics(m, phi, params=heavy)
    assert len(K.force_solve.signatures) == n_force
    assert len(K.pair_geometry.signatures) == n_pairs


def test_one_off_calls_share_a_plan_but_not_their_arrays():
    """kinematics() keeps the plan of a call like an earlier one, yet every result owns its
    arrays: a later call never changes an earlier result."""
    m = fourbar()
    first = sewmech.kinematics(m, PHI)
    kept = first.p.copy()
    other = sewmech.kinematics(m, PHI, params=m.parameters({"dyad.length1": 41.0}))
    again = sewmech.kinematics(m, PHI)
    assert np.array_equal(first.p, kept) and np.array_equal(again.p, kept)
    assert not np.array_equal(other.p, kept)
    assert len(m._plans) == 1  # one prepared plan served all three
    sewmech.kinematics(m, PHI[:10])
    assert len(m._plans) == 2


def test_one_off_calls_key_their_plans_by_the_names_selected():
    """The points, links and variables selected (lists or tuples of names) key the kept plan:
    the same names share it, other names get their own."""
    m = fourbar()
    c = sewmech.kinematics(m, PHI, points=["C"], links=[])
    assert sewmech.kinematics(m, PHI, points=("C",), links=()).point_names == ("C",)
    assert len(m._plans) == 1
    p = sewmech.kinematics(m, PHI, points=["P"], links=[])
    both = sewmech.kinematics(m, PHI, points=["C", "P"], links=[])
    assert (c.point_names, p.point_names, both.point_names) == (("C",), ("P",), ("C", "P"))
    assert len(m._plans) == 3
    assert np.array_equal(both.p[:, 1], p.p[:, 0]) and np.array_equal(both.p[:, 0], c.p[:, 0])
