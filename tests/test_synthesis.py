"""Classical synthesis (issue 33): Freudenstein function generation, Burmester motion
generation, timed path generation, the embroidery paper's take-up method, and the command.

Oracles, each independent of the code under test: Freudenstein's equation written out here;
four-bars solved here by circle intersection; the kinematics engine on the written machine
file (brute-force re-evaluation at every precision point); Chebyshev's points in closed form;
the embroidery paper's printed lengths and the shipped embroidery machine's L_i table."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

import sewmech
from sewmech.cli import app
from sewmech.design import burmester as BU
from sewmech.design import synthesis as SY
from sewmech.design.take_up_synthesis import synthesize_take_up
from sewmech.engine.machine import machine_from_toml
from sewmech.sewing import embroidery as EM


def _freudenstein(a, b, c, d, t2, t4):
    """Freudenstein's equation's residual, written out (signed a, c)."""
    K1, K2, K3 = d / a, d / c, (a * a - b * b + c * c + d * d) / (2 * a * c)
    return K1 * np.cos(t4) - K2 * np.cos(t2) + K3 - np.cos(t2 - t4)


def _output_by_intersection(a, b, c, d, t2, branch):
    """theta4 of the four-bar A = 0, D = (d, 0), B = a e^{i t2}: C at |C - B| = b, |C - D| = c,
    on the side of B -> D that ``branch`` says (+1 left), by circle intersection."""
    B = a * np.exp(1j * np.asarray(t2))
    D = d + 0j
    L = abs(D - B)
    e = (D - B) / L
    x = (b * b - c * c + L * L) / (2 * L)
    h = np.sqrt(b * b - x * x)
    C = B + e * (x + 1j * branch * h)
    return np.angle(C - D)


def test_chebyshev_spacing_closed_form():
    x = SY.chebyshev_spacing(1.0, 2.0, 3)
    h = math.sqrt(3.0) / 4.0  # (xf - x0) / 2 cos(30 deg)
    np.testing.assert_allclose(x, [1.5 - h, 1.5, 1.5 + h], rtol=0, atol=1e-15)


@pytest.fixture(scope="module")
def log_generator():
    return SY.synthesize_function("log10(x)", (1.0, 2.0), (30.0, 120.0), (240.0, 330.0),
                                  ground_mm=100.0)


def test_freudenstein_three_points_exact(log_generator):
    r = log_generator
    fb = r.fourbar
    t2, t4 = np.radians(r.theta2_deg), np.radians(r.theta4_deg)
    # the precision points: Chebyshev's, and y = log10(x) there
    np.testing.assert_allclose(r.x, SY.chebyshev_spacing(1, 2, 3), rtol=0, atol=1e-15)
    np.testing.assert_allclose(r.y, np.log10(r.x), rtol=0, atol=1e-15)
    # Freudenstein's equation, written out here, holds with the signed lengths
    res = _freudenstein(fb.input_u, fb.b, fb.output_u, fb.d, t2, t4)
    assert np.abs(res).max() < 1e-12
    # and the four-bar solved by circle intersection on its branch passes through each point
    th = _output_by_intersection(fb.input_u, fb.b, fb.output_u, fb.d, t2, fb.branch)
    th = th - (0.0 if fb.output_u > 0 else math.pi)
    assert np.abs(np.angle(np.exp(1j * (th - t4)))).max() < 1e-12
    assert r.grashof.kind == "double-crank"


def test_structural_error_against_the_engine(log_generator, tmp_path):
    """The structural error over the range re-evaluated through the kinematics engine on the
    machine file: the setting input at each grid point, the output link's angle read back."""
    r = log_generator
    text = SY.machine_text(r.fourbar, name="fg", title="t", notes=[], drive="setting",
                           input_range_deg=(30.0, 120.0))
    m = machine_from_toml(text, "fg.toml")

    def y_engine(x):
        out = []
        for t in np.radians(30.0 + (np.asarray(x) - 1.0) * 90.0):
            kin = sewmech.kinematics(m, [0.0], inputs={"input": t}, points=["C", "D"])
            c = kin.point("C").p[0] - kin.point("D").p[0]
            out.append(math.atan2(c[1], c[0]) + math.pi)  # C at u = -c: the link's angle + pi
        t4 = np.unwrap(np.array(out))
        t4 += np.round((np.radians(240.0) - t4[0]) / (2 * math.pi)) * 2 * math.pi
        return (t4 - math.radians(240.0)) / math.radians(90.0) * math.log10(2.0)

    x = r.x_grid[::40]
    np.testing.assert_allclose(y_engine(x), r.y_generated[::40], rtol=0, atol=1e-10)
    np.testing.assert_allclose(r.error[::40], y_engine(x) - np.log10(x), rtol=0, atol=1e-10)
    # the machine file meets the function at the precision points, to round-off
    np.testing.assert_allclose(y_engine(r.x), np.log10(r.x), rtol=0, atol=1e-12)
    assert r.max_error == pytest.approx(np.abs(r.error).max())


def test_least_squares_recovers_a_known_four_bar():
    """Points taken from a known four-bar (by circle intersection, here): the least-squares
    Freudenstein fit over 15 of them returns its lengths exactly."""
    a, b, c, d = 30.0, 70.0, 55.0, 60.0
    t2 = np.radians(np.linspace(40.0, 140.0, 15))
    t4 = _output_by_intersection(a, b, c, d, t2, 1)
    K, rms = SY.freudenstein_k(t2, t4)
    assert rms < 1e-14
    aa, bb, cc = SY.lengths_from_k(K, d)
    np.testing.assert_allclose([aa, bb, cc], [a, b, c], rtol=1e-12)


def test_least_squares_function_generator():
    r = SY.synthesize_function("x**1.5", (1.0, 4.0), (60.0, 150.0), (90.0, 160.0), points=25)
    assert r.method == "least squares" and r.x.size == 25
    # the least-squares fit beats the three-point answer's worst structural error? Not always;
    # but its Freudenstein residual is the smallest any K gives: a perturbed K is worse
    t2, t4 = np.radians(r.theta2_deg), np.radians(r.theta4_deg)
    M = np.stack([np.cos(t4), -np.cos(t2), np.ones_like(t2)], 1)
    base = np.sum((M @ r.K - np.cos(t2 - t4)) ** 2)
    rng = np.random.default_rng(3)
    for _ in range(20):
        Kp = r.K + 1e-4 * rng.standard_normal(3)
        assert np.sum((M @ Kp - np.cos(t2 - t4)) ** 2) > base


@pytest.mark.parametrize("args,where,what", [
    (("x**2", (0, 1), (45, 135), (90, 180)), "precision points", "branch defect"),
    (("1/x", (1, 2), (30, 120), (240, 150)), "--input-range-deg", "dead centre"),
    (("x", (0, 1), (0, 360), (0, 200)), "--output-range-deg", "no crank-rocker"),
    (("x", (0, 1), (0, 0), (0, 90)), "--input-range-deg/--output-range-deg", "zero width"),
    (("1", (0, 1), (0, 90), (0, 90)), "--function", "cannot be mapped"),
    (("__import__('os')", (0, 1), (0, 90), (0, 90)), "--function", "not allowed"),
])
def test_function_requirements_no_four_bar_meets(args, where, what):
    with pytest.raises(SY.SynthesisError) as e:
        SY.synthesize_function(*args)
    assert e.value.where == where and what in e.value.message


def test_coincident_precision_points():
    with pytest.raises(SY.SynthesisError, match="precision points 1 and 3 coincide"):
        SY.freudenstein_k(np.radians([10.0, 20.0, 10.0]), np.radians([30.0, 40.0, 30.0]))
    with pytest.raises(SY.SynthesisError, match="coincide"):
        SY.synthesize_function("x", (0, 1), (0, 90), (0, 90), x_points=[0.2, 0.5, 0.5])


def test_grashof_types():
    assert SY.grashof(15, 40, 35, 38).kind == "crank-rocker"
    assert SY.grashof(17.5, 16.275, 10.85, 6.65).kind == "double-crank"
    assert SY.grashof(30, 10, 30, 25).kind == "double-rocker"
    assert SY.grashof(30, 40, 10, 35).kind == "rocker-crank"
    assert SY.grashof(40, 60, 25, 30).kind == "triple-rocker"  # 25 + 60 > 40 + 30
    assert SY.grashof(10, 20, 10, 20).change_point


# ---- motion generation ------------------------------------------------------------------------

POSES4 = [[0.0, 0.0, 0.0], [20.0, 5.0, 20.0], [35.0, 15.0, 45.0], [45.0, 30.0, 70.0]]
POSES3 = [[0.0, 0.0, 0.0], [20.0, 5.0, 20.0], [35.0, 15.0, 45.0]]


def _engine_poses(res):
    text = SY.machine_text(res.fourbar, name="mg", title="t", notes=[], ratio=res.ratio,
                           phase_deg=float(res.input_deg[0])) if res.drive == "shaft" else \
        SY.machine_text(res.fourbar, name="mg", title="t", notes=[], drive="setting",
                        input_range_deg=(res.input_deg.min(), res.input_deg.max()))
    m = machine_from_toml(text, "mg.toml")
    got = []
    for phi in res.phi_deg:
        kw = ({"inputs": {"input": math.radians(phi)}} if res.drive == "setting" else {})
        kin = sewmech.kinematics(m, [math.radians(phi) if res.drive == "shaft" else 0.0],
                                 points=["P"], links=["coupler"], **kw)
        got.append([*kin.point("P").p[0], kin.link("coupler").theta[0] + res.body_offset])
    return np.array(got)


@pytest.mark.parametrize("poses", [POSES3, POSES4])
def test_motion_poses_reached_through_the_engine(poses):
    res = BU.synthesize_motion(poses)
    got = _engine_poses(res)
    want = np.array(poses, dtype=float)
    np.testing.assert_allclose(got[:, :2], want[:, :2], rtol=0, atol=1e-9)
    dang = np.angle(np.exp(1j * (got[:, 2] - np.radians(want[:, 2]))))
    assert np.abs(dang).max() < 1e-11
    # each dyad's circle point is equally far from its centre point in every pose
    P = res.poses
    for d in res.dyads:
        q = BU.pose_points(P, d.m)
        r = np.linalg.norm(q - d.K, axis=-1)
        assert np.ptp(r) < 1e-9 * r.mean()


def test_burmester_curves_are_circle_points():
    """Every sampled point pair of the curves: the circle point's four positions lie on one
    circle about the centre point (checked by distances, not by the dyad equation)."""
    P = np.array(POSES4, dtype=float)
    P[:, 2] = np.radians(P[:, 2])
    c = BU.burmester_curves(P, samples=360)
    assert c.centre.shape[0] > 300
    for K, m in zip(c.centre, c.m, strict=True):
        r = np.linalg.norm(BU.pose_points(P, m) - K, axis=-1)
        assert np.ptp(r) <= 1e-9 * max(r.mean(), 1.0)


def test_three_poses_with_given_circle_points_and_their_defects():
    P = np.array(POSES3, dtype=float)
    P[:, 2] = np.radians(P[:, 2])
    g = np.linspace(-40, 40, 9)
    good = bad = None
    for m1 in ((u, v) for u in g for v in g):
        for m2 in ((u, v) for u in g[::2] for v in g[::2]):
            if m1 == m2:
                continue
            try:
                d1, d2 = BU.three_pose_dyad(P, m1), BU.three_pose_dyad(P, m2)
            except SY.SynthesisError:
                continue
            # branch by hand: the side of C relative to B -> D in each pose
            B, C = BU.pose_points(P, d1.m), BU.pose_points(P, d2.m)
            u, w = d2.K - B, C - B
            side = np.sign(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0])
            if np.unique(side).size > 1 and bad is None:
                bad = (m1, m2)
            elif np.unique(side).size == 1 and good is None:
                good = (m1, m2)
        if good and bad:
            break
    with pytest.raises(SY.SynthesisError) as e:
        BU.synthesize_motion(POSES3, bad)
    assert e.value.where == "--circle-point" and "branch defect" in e.value.message
    try:
        res = BU.synthesize_motion(POSES3, good)
    except SY.SynthesisError as exc:  # an order defect instead: also named
        assert "order defect" in exc.message
    else:
        np.testing.assert_allclose(_engine_poses(res)[:, :2], P[:, :2], atol=1e-9)


def test_motion_bad_input():
    with pytest.raises(SY.SynthesisError, match="poses 1 and 3 coincide"):
        BU.synthesize_motion([[0, 0, 0], [10, 0, 10], [0, 0, 0]])
    with pytest.raises(SY.SynthesisError, match="three or four poses"):
        BU.synthesize_motion([[0, 0, 0], [10, 0, 10]])
    with pytest.raises(SY.SynthesisError, match="on one line"):
        # a circle point that only translates along a line between the poses
        BU.synthesize_motion([[0, 0, 0], [10, 0, 0], [20, 0, 0]], [(0, 0), (0, 5)])


# ---- path generation --------------------------------------------------------------------------


def test_path_generation_from_an_exact_start():
    m = sewmech.load_machine("fourbar-benchmark")
    phi = np.arange(0.0, 360.0, 30.0)
    Z = sewmech.kinematics(m, np.radians(phi), points=["P"]).point("P").p.copy()
    res = BU.synthesize_path(Z, phi)
    # the start meets its three points exactly (through the engine, on its machine file)
    ms = machine_from_toml(res.start_text, "s.toml")
    p0 = sewmech.kinematics(ms, np.radians(phi[list(res.start.exact)]),
                            points=["P"]).point("P").p
    np.testing.assert_allclose(p0, Z[list(res.start.exact)], rtol=0, atol=1e-9)
    # the answer, re-evaluated: every point to 1e-6 mm (SLSQP's tolerance on the squares)
    ma = machine_from_toml(res.answer_text, "a.toml")
    pa = sewmech.kinematics(ma, np.radians(phi), points=["P"]).point("P").p
    assert np.linalg.norm(pa - Z, axis=-1).max() < 1e-6
    assert res.answer_rms_mm < 1e-6 < res.start_rms_mm


def test_path_bad_input():
    with pytest.raises(SY.SynthesisError, match="same input angle"):
        BU.path_start([[0, 0], [1, 1], [2, 0]], [0.0, 90.0, 360.0])


# ---- the embroidery take-up -------------------------------------------------------------------


def test_take_up_reproduces_the_paper():
    r = synthesize_take_up(crank_mm=17.5, stroke_mm=124.0)
    # the paper prints 16.3, 10.9, 6.6 (0.1 mm): the method's exact values are within half
    # the printed step
    for got, paper in ((r.bc, 16.3), (r.cd, 10.9), (r.ad, 6.6)):
        assert abs(got - paper) <= 0.05 + 1e-12
    assert (r.de, r.ef) == (31.0, pytest.approx(80.0, abs=1e-12))
    assert abs(r.dc_turn_deg - 180.0) < 1e-7  # the design positions' condition
    assert r.drawn_mm == pytest.approx(124.0, abs=1e-9)  # 2 x the eye's stroke = 4 DE
    assert r.eye_top_deg == pytest.approx(60.0, abs=0.25)  # DE up at phi1 = 60 deg
    assert 5.0 <= r.design_alpha_deg <= 30.0  # the paper's range for alpha
    assert r.grashof.kind == "double-crank"


def test_take_up_l_table_of_the_shipped_machine():
    """The lengths as the paper prints them (and its chosen pair) through the existing study:
    the L_i table of the shipped embroidery-131, to the 0.1 um its coordinates are written
    to; with its AD and DE exact, to round-off."""
    r = synthesize_take_up(lengths_mm=(16.3, 10.9, 6.6), alpha_deg=10.0, beta_deg=35.0)
    ours = EM.paper_table(machine_from_toml(r.text, "t.toml"))
    ship = sewmech.load_machine("embroidery-131")
    shipped = EM.paper_table(ship)
    assert list(ours.columns) == list(shipped.columns)
    assert np.abs(ours.values - shipped.values).max() < 3e-4
    a, b = math.radians(10.0), math.radians(35.0)
    exact = ship.with_parameters({"D.x": 6.6 * math.cos(a), "D.y": 6.6 * math.sin(a),
                                  "M.x": 6.6 * math.cos(a), "N.x": 6.6 * math.cos(a),
                                  "E.u": 31.0 * math.cos(-b), "E.v": 31.0 * math.sin(-b)})
    assert np.abs(ours.values - EM.paper_table(exact).values).max() < 1e-7


def test_take_up_requirements():
    with pytest.raises(SY.SynthesisError, match="double crank"):
        synthesize_take_up(k=(0.93, 0.62, 1.2))
    with pytest.raises(SY.SynthesisError, match="longer than the crank DE"):
        synthesize_take_up(ef_mm=20.0)
    with pytest.raises(SY.SynthesisError, match="--crank-mm"):
        synthesize_take_up(crank_mm=-1.0)


# ---- the command ------------------------------------------------------------------------------


def _run(args):
    return CliRunner().invoke(app, args)


@pytest.mark.parametrize("kind,args,stem", [
    ("function", ["--function", "log10(x)", "--x-range", "1", "2", "--input-range-deg", "30",
                  "120", "--output-range-deg", "240", "330"], "function-generator"),
    ("motion", ["--pose", "0,0,0", "--pose", "20,5,20", "--pose", "35,15,45"],
     "motion-generator"),
    ("embroidery-take-up", ["--crank-mm", "17.5", "--stroke-mm", "124"], "take-up"),
])
def test_synthesize_writes_a_file_check_accepts(kind, args, stem, tmp_path):
    out = tmp_path / "out"
    r = _run(["synthesize", kind, *args, "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout.strip().splitlines()[-1])
    assert data["kind"] == kind
    assert (out / f"{stem}.toml").is_file() and (out / "index.html").is_file()
    page = (out / "index.html").read_text()
    assert "Written by sewmech." in page and "<img" in page
    c = _run(["check", str(out / f"{stem}.toml")])
    assert c.exit_code == 0, c.output
    assert "valid" in c.output


def test_synthesize_path_command(tmp_path):
    m = sewmech.load_machine("fourbar-benchmark")
    phi = np.arange(0.0, 360.0, 30.0)
    Z = sewmech.kinematics(m, np.radians(phi), points=["P"]).point("P").p
    csv = tmp_path / "path.csv"
    csv.write_text("phi_deg,x_mm,y_mm\n" + "".join(f"{a},{float(x)!r},{float(y)!r}\n"
                                                   for a, (x, y) in zip(phi, Z, strict=True)))
    out = tmp_path / "out"
    r = _run(["synthesize", "path", str(csv), "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout.strip().splitlines()[-1])
    assert data["answer_max_mm"] < 1e-6
    assert _run(["check", str(out / "path-generator.toml")]).exit_code == 0
    assert (out / "problem.toml").is_file()


def test_synthesize_errors_are_located_and_keep_the_users_files(tmp_path):
    mine = tmp_path / "mine.toml"
    mine.write_text("my own file\n")
    r = _run(["synthesize", "embroidery-take-up", "--out", str(mine)])
    assert r.exit_code == 2
    assert "error: --out" in r.output and "is a file" in r.output
    assert mine.read_text() == "my own file\n"
    d = tmp_path / "dir"
    d.mkdir()
    (d / "notes.txt").write_text("keep me")
    r = _run(["synthesize", "embroidery-take-up", "--out", str(d)])
    assert r.exit_code == 2 and "did not write" in r.output
    assert (d / "notes.txt").read_text() == "keep me" and len(list(d.iterdir())) == 1
    r = _run(["synthesize", "function", "--function", "x", "--x-range", "0", "1",
              "--input-range-deg", "0", "360", "--output-range-deg", "0", "200"])
    assert r.exit_code == 2
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: --output-range-deg:")
    r = _run(["synthesize", "motion", "--pose", "0,0,0", "--pose", "1,2"])
    assert r.exit_code == 2 and "error: --pose" in r.output
    r = _run(["synthesize", "motion", "--pose", "0,0,0", "--pose", "0,0,0", "--pose", "1,1,1"])
    assert r.exit_code == 2 and "coincide" in r.output


def test_freudenstein_equals_pylinkages_independent_solver():
    """pylinkage's function_generation (another implementation, installed with the benchmarks'
    extra) gives the same four-bar for the same three angle pairs."""
    fg = pytest.importorskip("pylinkage.synthesis.function_generation")
    r = SY.synthesize_function("x**1.5", (1.0, 4.0), (60.0, 150.0), (90.0, 160.0))
    pairs = list(zip(np.radians(r.theta2_deg), np.radians(r.theta4_deg), strict=True))
    s = fg.function_generation(pairs, ground_length=100.0, require_grashof=False).raw_solutions
    assert len(s) >= 1
    np.testing.assert_allclose([s[0].crank_length, s[0].coupler_length, s[0].rocker_length],
                               [r.fourbar.a, r.fourbar.b, r.fourbar.c], rtol=1e-12)
