"""The JB1-3 feed: the six-arc cam, the fork, stitch length, lift, scale marks, feed timing.

Every figure of sewmech.feed is checked against a computation written here: dense grids of the
dog's tooth tip with linear interpolation, plane geometry of the fork and the cam, and finite
differences of the loop solver's positions.
"""

import math

import numpy as np
import pytest

import sewmech
from sewmech import feed as F
from sewmech.cams import constant_width_arcs, support

DOG = "feed_dog.tip"
PLATE = -140.0


@pytest.fixture(scope="module")
def jb():
    return sewmech.load_machine("jb1-3")


def _arcs(m, cam, params=None):
    p = m.defaults if params is None else params
    return {k: np.array([p[m.parameter_index(f"{cam}.arc{i}.{k}")] for i in range(6)])
            for k in ("cx", "cy", "radius", "normal_from", "normal_to")}


def _profile(arcs, n=20001):
    """Points of the cam outline, sampled densely along every arc."""
    pts = []
    for cx, cy, r, a, b in zip(*(arcs[k] for k in ("cx", "cy", "radius", "normal_from",
                                                     "normal_to"))):
        t = np.linspace(a, b, n)
        pts.append(np.stack([cx + r * np.cos(t), cy + r * np.sin(t)], axis=1))
    return np.concatenate(pts)


# ---- the cam ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("W,S,dwell_deg", [(20.0, 7.0, 60.0), (18.0, 4.0, 30.0), (25.0, 9.0, 80.0)])
def test_constant_width_cam_from_its_outline(W, S, dwell_deg):
    """Width from the sampled outline (max - min of projections) is W in every direction; the
    fork rests (the support is flat) over each dwell and travels S between them."""
    arcs = constant_width_arcs(W, S, math.radians(dwell_deg))
    pts = _profile(arcs)
    for ang in np.radians(np.arange(0.0, 180.0, 7.5)):
        proj = pts @ np.array([math.cos(ang), math.sin(ang)])
        assert proj.max() - proj.min() == pytest.approx(W, abs=1e-7)
    # arcs join with a common tangent: consecutive arcs share their end point
    for k in range(6):
        j = (k + 1) % 6
        t = arcs["normal_to"][k]
        e = np.array([math.cos(t), math.sin(t)])
        a = np.array([arcs["cx"][k], arcs["cy"][k]]) + arcs["radius"][k] * e
        b = np.array([arcs["cx"][j], arcs["cy"][j]]) + arcs["radius"][j] * e
        assert np.hypot(*(a - b)) < 1e-12
    dw = math.radians(dwell_deg) / 2
    inner = np.linspace(-dw, dw, 50)
    outer = inner + math.pi
    proj_in = np.array([(pts @ [math.cos(a), math.sin(a)]).max() for a in inner])
    proj_out = np.array([(pts @ [math.cos(a), math.sin(a)]).max() for a in outer])
    assert np.ptp(proj_in) < 1e-7 and np.ptp(proj_out) < 1e-7
    assert proj_out.mean() - proj_in.mean() == pytest.approx(S, abs=1e-7)
    assert np.allclose(support(arcs, inner), proj_in, atol=1e-7)


def test_cam_without_dwell_is_an_eccentric():
    arcs = constant_width_arcs(20.0, 6.0, 0.0)
    th = np.linspace(0, 2 * np.pi, 37)
    assert np.allclose(support(arcs, th), 10.0 - 3.0 * np.cos(th), atol=1e-12)


def test_cam_design_values_as_batch_parameters(jb):
    """Machine.parameters({'feed_cam.stroke': ...}) rebuilds the arcs like a file that says so."""
    text = jb.spec.model_dump_json()
    assert "constant_width" in text
    p = jb.parameters({"feed_cam.stroke": [6.0, 8.0]})
    for row, S in zip(p, (6.0, 8.0)):
        a = _arcs(jb, "feed_cam", row)
        ref = constant_width_arcs(20.0, S, math.radians(60.0))
        for k in a:
            assert np.allclose(a[k], ref[k], atol=1e-12)
    with pytest.raises(ValueError, match="stroke < width"):
        jb.parameters({"feed_cam.stroke": 25.0})


def test_a_cam_design_value_that_gives_no_cam_is_located(jb):
    """One design: a ParameterError naming the cam's design value, what fails and the way
    out. A batch: only the designs that give no convex cam are infeasible (NaN arcs), the
    others are evaluated, and the error of a raising call says why."""
    from sewmech.engine.cams import constant_width_fault
    from sewmech.errors import ParameterError

    with pytest.raises(ParameterError, match="feed_cam.dwell.*dwell < 180 deg") as e:
        jb.parameters({"feed_cam.dwell": math.radians(190.0)})
    assert e.value.parameter == "feed_cam.dwell" and "convex" in e.value.hint
    with pytest.raises(ParameterError, match="no convex constant-width cam for width 20 mm"):
        jb.parameters({"feed_cam.dwell": math.radians(179.0)})
    assert constant_width_fault(20.0, [6.0, 6.0], [1.0, 3.2]).endswith(
        "got 183.346 deg (design (1,))")
    P = jb.parameters({"feed_cam.stroke": np.array([6.0, 21.0, 7.0])})
    r = sewmech.kinematics(jb, np.radians([10.0, 20.0]), params=P, on_failure="mask")
    assert r.feasible.all(axis=1).tolist() == [True, False, True]
    with pytest.raises(ParameterError, match="design \\(1,\\).*feed_cam's design values"):
        sewmech.kinematics(jb, np.radians([10.0, 20.0]), params=P)


def test_bad_constant_width_cam_is_a_file_error():
    from sewmech.errors import MachineFileError
    from sewmech.spec import parse_machine

    text = """
[machine]
name = "c"
[convention]
reference_event = "x"
reference_phi_deg = 0
[points.O]
x = 0
y = 0
[cams.c]
link = "k"
pivot = "O"
constant_width = { width = 10.0, stroke = 12.0, dwell_deg = 60.0 }
[[units]]
type = "crank"
name = "k"
pivot = "O"
"""
    with pytest.raises(MachineFileError, match=r"cams\.c.*stroke 12.0 mm must be smaller"):
        parse_machine(text, "c.toml")


# ---- the fork on the cam ------------------------------------------------------------------------


def test_fork_faces_both_touch_the_cam(jb):
    """The fork's two contact points stay W apart across the fork, to 1e-9 mm: the second
    face (not in the loop equations) touches the cam at every angle."""
    phi = np.radians(np.arange(0.0, 360.0, 1.0))
    W = 20.0
    arcs = _arcs(jb, "feed_cam")
    for reg in (-30.0, 0.0, 17.0, 30.0):
        r = sewmech.kinematics(jb, phi, inputs={"regulator": math.radians(reg)})
        tf = r.link("feed_fork").theta
        tc = r.link("feed_cam").theta
        E = r.point("feed_fork.pin").p
        ev = np.stack([np.cos(tf + np.pi / 2), np.sin(tf + np.pi / 2)], axis=1)
        for side in (+1, -1):
            # the cam's point whose outward normal is side * ev, from its arcs (cam frame)
            rho = np.mod(tf + np.pi / 2 + (0 if side > 0 else np.pi) - tc, 2 * np.pi)
            k = np.array([np.nonzero(np.mod(x - arcs["normal_from"], 2 * np.pi)
                                     < arcs["normal_to"] - arcs["normal_from"])[0][0]
                          for x in rho])
            c = np.stack([arcs["cx"][k], arcs["cy"][k]], axis=1)
            cw = np.stack([np.cos(tc) * c[:, 0] - np.sin(tc) * c[:, 1],
                           np.sin(tc) * c[:, 0] + np.cos(tc) * c[:, 1]], axis=1)
            pt = cw + arcs["radius"][k][:, None] * side * ev  # cam axis is at the origin
            off = np.einsum("ij,ij->i", pt - E, ev)  # distance of the contact from the fork axis
            assert np.abs(off - side * W / 2).max() < 1e-9, (reg, side)


def test_slide_block_stays_in_the_slot(jb):
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    r = sewmech.kinematics(jb, phi, inputs={"regulator": math.radians(20.0)})
    tf = r.link("feed_fork").theta
    block = r.point("feed_fork.pin").p + 125.0 * np.stack([np.cos(tf), np.sin(tf)], axis=1)
    G = np.array([jb.defaults[jb.parameter_index("G.x")], jb.defaults[jb.parameter_index("G.y")]])
    a = r.link("regulator").theta
    normal = np.stack([-np.sin(a), np.cos(a)], axis=1)
    assert np.abs(np.einsum("ij,ij->i", block - G, normal)).max() < 1e-9
    assert np.allclose(np.degrees(a), 9.8871 + 20.0)


def test_feed_rates_against_finite_differences(jb):
    """Velocities and accelerations of the loop units against central differences of their
    positions (omega = 1 rad/s, so rates are derivatives wrt phi), away from the cam's arc
    switches where the acceleration jumps."""
    h = 1e-5
    phi = np.radians(np.arange(3.0, 360.0, 10.0))
    reg = {"regulator": math.radians(25.0)}
    # positions closed to 1e-13 mm: a difference quotient amplifies the solver's tolerance by 1/h
    r = sewmech.kinematics(jb, phi, inputs=reg, omega=1.0, tol=1e-13)
    rp = sewmech.kinematics(jb, phi + h, inputs=reg, omega=1.0, tol=1e-13)
    rm = sewmech.kinematics(jb, phi - h, inputs=reg, omega=1.0, tol=1e-13)
    for pt in (DOG, "feed_fork.pin", "feed_bar.pin", "lift.roller"):
        v_fd = (rp.point(pt).p - rm.point(pt).p) / (2 * h)
        a_fd = (rp.point(pt).v - rm.point(pt).v) / (2 * h)
        assert np.abs(r.point(pt).v - v_fd).max() < 1e-6, pt
        assert np.abs(r.point(pt).a - a_fd).max() < 1e-5, pt
    for link in ("feed_fork", "feed_rock_shaft", "lift_crank", "feed_bar"):
        w_fd = (rp.link(link).theta - rm.link(link).theta) / (2 * h)
        e_fd = (rp.link(link).omega - rm.link(link).omega) / (2 * h)
        assert np.abs(r.link(link).omega - w_fd).max() < 1e-8, link
        assert np.abs(r.link(link).epsilon - e_fd).max() < 1e-7, link


# ---- stitch, lift, timing ----------------------------------------------------------------------------


def _dense(jb, reg_deg, params=None, step=0.01):
    phi = np.radians(np.arange(0.0, 360.0, step))
    r = sewmech.kinematics(jb, phi, params=params, inputs={"regulator": math.radians(reg_deg)},
                           points=[DOG], links=[], variables=[])
    return np.degrees(phi), r.point(DOG).p


def _cross(phi_deg, f, direction):
    """Linear-interpolated crossing angles of f through 0 in a direction (+1 up, -1 down)."""
    g = np.roll(f, -1)
    k = np.nonzero((f < 0) & (g >= 0) if direction > 0 else (f > 0) & (g <= 0))[0]
    t = f[k] / (f[k] - g[k])
    return k, t


def _reference(jb, reg_deg, params=None):
    """Stitch, lift, rise and fall of the tooth tip from a 0.01 deg grid, written here."""
    ph, p = _dense(jb, reg_deg, params)
    y = p[:, 1] - PLATE
    ku, tu = _cross(ph, y, +1)
    kd, td = _cross(ph, y, -1)
    assert len(ku) == len(kd) == 1  # one window above the plate per revolution
    x = p[:, 0]
    xu = x[ku[0]] + tu[0] * (x[(ku[0] + 1) % len(x)] - x[ku[0]])
    xd = x[kd[0]] + td[0] * (x[(kd[0] + 1) % len(x)] - x[kd[0]])
    return dict(stitch=xd - xu, lift=y.max(), rise=(ku[0] + tu[0]) * 0.01,
                fall=(kd[0] + td[0]) * 0.01, top=ph[np.argmax(y)], x=x, y=y, phi=ph)


@pytest.mark.parametrize("reg", [-30.0, -12.5, 8.0, 30.0])
def test_stitch_lift_and_window_against_a_dense_grid(jb, reg):
    c = F.feed_cycles(jb, reg)
    ref = _reference(jb, reg)
    assert float(c.stitch_mm) == pytest.approx(ref["stitch"], abs=2e-5)
    assert float(c.lift_mm) == pytest.approx(ref["lift"], abs=1e-6)
    assert float(c.rise_deg) == pytest.approx(ref["rise"], abs=1e-3)
    assert float(c.fall_deg) == pytest.approx(ref["fall"], abs=1e-3)
    assert float(c.top_deg) == pytest.approx(ref["top"], abs=0.02)
    assert float(c.stroke_mm) == pytest.approx(np.ptp(ref["x"]), abs=1e-6)
    assert float(c.drop_mm) == pytest.approx(ref["y"].min(), abs=1e-6)


def test_zero_mark_gives_no_feed(jb):
    """The regulator's zero mark of the file (slot square to the fork) feeds nothing; the feed
    checks read it there (the regulator's 0 deg), not at the file's working setting."""
    from sewmech.timing import check_timing

    assert abs(_reference(jb, 0.0)["stitch"]) <= 0.01
    assert abs(F.stitch_length(jb, 0.0)) <= 0.01
    assert abs(F.zero_mark(jb)) < 0.01  # deg
    checks = {c.name: c for c in check_timing(jb)}
    assert abs(checks["stitch at the regulator's zero mark"].value) <= 1e-5
    assert checks["feed dog above the plate at the top of lift (zero mark)"].value == \
        pytest.approx(float(F.feed_cycles(jb, 0.0).lift_mm), abs=1e-12)


@pytest.mark.parametrize("name", ["jb1-3", "jb8-2"])
def test_the_working_setting_is_the_longest_forward_stitch(name):
    """A machine file's default_deg is its working setting: the JB machines' is the forward end
    of the regulator's travel, so the library (and every command and the page) analyse a
    stitch, not the zero mark's round-off."""
    m = sewmech.load_machine(name)
    spec = m.spec.inputs["regulator"]
    assert spec.default_deg == spec.max_deg > 0.0
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    at_default = sewmech.kinematics(m, phi).point(DOG).p
    at_max = sewmech.kinematics(m, phi, inputs={"regulator": math.radians(spec.max_deg)}
                                ).point(DOG).p
    np.testing.assert_array_equal(at_default, at_max)
    assert 3.6 <= float(F.feed_cycles(m, spec.default_deg).stitch_mm) <= 4.2


def test_stitch_curve_monotonic_and_four_mm_both_ways(jb):
    c = F.stitch_curve(jb, 121)
    assert np.all(np.diff(c.stitch_mm) > 0)
    assert 3.6 <= c.stitch_mm[-1] <= 4.2 and -4.2 <= c.stitch_mm[0] <= -3.6
    assert np.all((c.lift_mm > 1.2) & (c.lift_mm < 1.5))


def test_scale_marks(jb):
    marks = F.scale_marks(jb, 0.5)
    # exact: a mark's stitch is its target, a whole multiple of 0.5 mm (a binary fraction)
    assert [m.stitch_mm for m in marks] == [k * 0.5 for k in range(-8, 9)]
    regs = [m.regulator_deg for m in marks]
    assert np.all(np.diff(regs) > 0)
    for m in marks[::4]:  # the marks' settings reproduce their stitch on a dense grid
        assert _reference(jb, m.regulator_deg)["stitch"] == pytest.approx(m.stitch_mm, abs=1e-4)
    # from a curve the caller already has (the report's): the same marks
    same = F.scale_marks(jb, 0.5, curve=F.stitch_curve(jb, 121))
    assert [m.stitch_mm for m in same] == [m.stitch_mm for m in marks]
    np.testing.assert_allclose([m.regulator_deg for m in same], regs, atol=1e-4)


@pytest.mark.parametrize("target", [0.0, 15.0])
def test_set_feed_timing(jb, target):
    ft = F.set_feed_timing(jb, target)
    p = jb.parameters(ft.overrides)
    ref = _reference(jb, 30.0, p)
    x = ref["x"]
    mid = 0.5 * (x.max() + x.min())
    k, t = _cross(ref["phi"], x - mid, +1)
    inside = [(kk + tt) * 0.01 for kk, tt in zip(k, t)
              if (kk * 0.01 - ref["rise"]) % 360 < (ref["fall"] - ref["rise"]) % 360]
    assert len(inside) == 1
    lag = (inside[0] - ref["top"] + 180) % 360 - 180
    assert lag == pytest.approx(target, abs=0.02)  # the dense grid's top is good to 0.01 deg
    assert float(ft.cycle.mid_feed_deg - ft.cycle.top_deg) == pytest.approx(target, abs=1e-5)


def test_shipped_feed_cam_phase_is_the_timing_setting(jb):
    assert F.set_feed_timing(jb, 0.0).phase_deg == pytest.approx(22.973, abs=1e-3)


def test_feed_needs_roles():
    m = sewmech.load_machine("fourbar-benchmark")
    with pytest.raises(ValueError, match="feed_dog"):
        F.feed_cycles(m, 0.0)


def test_feed_checks_against_a_dense_grid(jb):
    """Dog height as the needle point reaches the plate, and no angle with the needle in the
    fabric and the dog above the plate, from a 0.01 deg grid of both points."""
    from sewmech.timing import check_timing

    checks = {c.name: c for c in check_timing(jb)}
    phi = np.radians(np.arange(0.0, 360.0, 0.01))
    for reg in (-30.0, 0.0, 30.0):
        r = sewmech.kinematics(jb, phi, inputs={"regulator": math.radians(reg)},
                               points=["needle.point", DOG], links=[], variables=[])
        needle = r.point("needle.point").p[:, 1]
        dog = r.point(DOG).p[:, 1]
        assert not np.any((needle < PLATE + 1.0) & (dog > PLATE)), reg
        if reg == 30.0:
            k = np.nonzero((needle > PLATE) & (np.roll(needle, -1) <= PLATE))[0][0]
            t = (needle[k] - PLATE) / (needle[k] - needle[k + 1])
            h = dog[k] + t * (dog[k + 1] - dog[k]) - PLATE
            assert checks["dog height when the needle point reaches the plate"].value == \
                pytest.approx(h, abs=1e-6)
    assert checks["overlap of 'needle in fabric' and 'dog above plate'"].value == 0.0
    assert all(c.passed for c in checks.values())


def test_jb8_2_variant():
    """The second variant meets the same facts, and its file's feed-cam phase is the timing
    setting; it differs from JB1-3 where its file says so."""
    from sewmech.timing import check_timing

    m = sewmech.load_machine("jb8-2")
    assert all(c.passed for c in check_timing(m))
    assert F.set_feed_timing(m, 0.0).phase_deg == pytest.approx(23.9054, abs=1e-3)
    assert abs(F.stitch_length(m, 0.0)) <= 0.01
    c = F.stitch_curve(m, 57)
    assert np.all(np.diff(c.stitch_mm) > 0)
    assert m.cam_designs["feed_cam"]["stroke"] == 6.5
    assert m.spec.machine.variants == ["jb1-3"]


def test_sensitivity_against_single_designs(jb):
    """Each row of the batched study equals a separate evaluation of that changed design."""
    sens = F.sensitivity(jb, 0.05)
    assert sens.cycles.stitch_mm.shape == (len(jb.spec.sewing.feed_parameters), 3)
    assert np.allclose(sens.cycles.stitch_mm[:, 1], F.stitch_length(jb, 30.0), atol=1e-12)
    label = "slide block up the fork"
    i = sens.labels.index(label)
    p = jb.parameters({"feed_fork.slot.2.length": 125.0 * 1.05})
    ref = _reference(jb, 30.0, p)
    assert sens.cycles.stitch_mm[i, 2] == pytest.approx(ref["stitch"], abs=2e-5)
    assert sens.cycles.lift_mm[i, 2] == pytest.approx(ref["lift"], abs=1e-6)
    t = sens.table()
    row = t[t["parameter"] == label].iloc[0]
    assert row["stitch change +5% [mm]"] == pytest.approx(ref["stitch"] - F.stitch_length(jb, 30.0),
                                                          abs=2e-5)
    # the cam width moves the fork gap with it: nothing changes
    w = t[t["parameter"] == "feed cam width (fork gap)"].iloc[0]
    assert abs(w["stitch change +5% [mm]"]) < 1e-9 and abs(w["lift change -5% [mm]"]) < 1e-9


@pytest.mark.parametrize("a,b,expected", [((10, 50), (40, 90), 10.0), ((350, 20), (10, 30), 10.0),
                                          ((350, 20), (340, 355), 5.0), ((0, 10), (20, 30), 0.0),
                                          ((300, 100), (90, 310), 20.0)])
def test_window_overlap(a, b, expected):
    assert F._overlap_deg(*a, *b) == pytest.approx(expected)
    assert F._overlap_deg(*b, *a) == pytest.approx(expected)
