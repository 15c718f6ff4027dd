"""The embroidery take-up (Kozlov): design procedure, L(phi), the paper's table, deviation from a
base diagram, colour changer, CLI; against a plain-numpy model of the mechanism written here."""

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

import sewmech
from sewmech import embroidery as EM
from sewmech.cli import app


@pytest.fixture(scope="module")
def emb():
    return sewmech.load_machine("embroidery-131")


# AD and DE as the machine file gives them (its coordinates are rounded to 0.1 um)
_AD = math.hypot(6.4997, 1.1461)
_DE = math.hypot(25.3936, -17.781)


def _eye_y(phi, alpha, beta, ab=17.5, bc=16.3, cd=10.9, ad=_AD, de=_DE, ef=80.0):
    """The eye's height by hand: crank AB up at phi = 0, counter-clockwise; D = AD e(alpha);
    C left of B -> D; E = D + DE e(angle DC - beta); F on the vertical through D above E."""
    A = np.zeros(2)
    D = ad * np.array([math.cos(alpha), math.sin(alpha)])
    out = []
    for p in phi:
        B = A + ab * np.array([math.cos(math.pi / 2 + p), math.sin(math.pi / 2 + p)])
        d = D - B
        L = np.hypot(*d)
        a = (bc**2 - cd**2 + L**2) / (2 * L)
        h = math.sqrt(bc**2 - a**2)
        C = B + a * d / L + h * np.array([-d[1], d[0]]) / L
        g = math.atan2(C[1] - D[1], C[0] - D[0]) - beta
        E = D + de * np.array([math.cos(g), math.sin(g)])
        out.append(E[1] + math.sqrt(ef**2 - (E[0] - D[0]) ** 2))
    return np.array(out)


def test_design_procedure_reproduces_the_paper(emb):
    d = EM.design(emb)
    # the paper prints BC 16.3, CD 10.9, AD 6.6 (its K's times AB = 17.5, rounded), EF 80
    for got, paper in ((d.bc, 16.3), (d.cd, 10.9), (d.ad, 6.6)):
        assert abs(got - paper) <= 0.051
    assert d.de == 31.0 and d.ef == 80.0  # exact: 124 / 4 and the default 80 passed through
    assert 5.0 <= d.alpha_deg <= 30.0  # the paper's range for alpha
    # the procedure's own condition: DC turns half a turn from phi1 = 60 to 300 deg
    a = math.radians(d.alpha_deg)
    b = math.radians(d.beta_deg)
    p = emb.parameters({"four_bar.length1": d.bc, "four_bar.length2": d.cd,
                        "D.x": d.ad * math.cos(a), "D.y": d.ad * math.sin(a),
                        "E.u": d.de * math.cos(-b), "E.v": d.de * math.sin(-b)})
    th = np.unwrap(sewmech.kinematics(emb, np.radians(np.linspace(60, 300, 481)), params=p)
                   .link("DC").theta)
    assert abs(abs(th[-1] - th[0]) - math.pi) < 1e-9
    # and DE1 points up at phi1: E is at the top of its circle there
    r = sewmech.kinematics(emb, np.radians([60.0]), params=p)
    e = r.point("E").p[0] - r.point("D").p[0]
    assert math.degrees(math.atan2(e[1], e[0])) == pytest.approx(90.0, abs=1e-6)


@pytest.mark.parametrize("beta,alpha", EM.PAPER_PAIRS)
def test_thread_drawn_against_hand_geometry(emb, beta, alpha):
    phi_deg, L = EM.thread_drawn(emb, alpha, beta, n_points=12)
    y = _eye_y(np.radians(phi_deg), math.radians(alpha), math.radians(beta))
    yt = _eye_y(np.radians(np.arange(0, 360, 0.01)), math.radians(alpha), math.radians(beta))
    # with M and N on the eye's line below it, l = |MQ| + |QN| and L = l_max - l = 2 (y_top - y)
    np.testing.assert_allclose(L, 2 * (yt.max() - y), atol=2e-6)
    # L_max is twice the slider's stroke: the paper's l2 = 124 mm (= 4 DE)
    assert np.ptp(2 * yt) == pytest.approx(4 * _DE, abs=1e-6)
    assert 4 * _DE == pytest.approx(124.0, abs=1e-3)
    # the eye's top near 60-65 deg and its bottom near 300-310 deg (the paper: 65 and 310)
    top = np.arange(0, 360, 0.01)[np.argmax(yt)]
    bottom = np.arange(0, 360, 0.01)[np.argmin(yt)]
    assert 60.0 <= top <= 66.0 and 294.0 <= bottom <= 310.0


def test_paper_table_and_deviation(emb, tmp_path):
    t = EM.paper_table(emb)
    assert list(t["phi_deg"]) == [30.0 * i for i in range(12)] and t.shape == (12, 7)
    # a base diagram equal to the (35, 10) design is matched exactly by that pair
    fine_phi, L = EM.thread_drawn(emb, 10.0, 35.0, n_points=72)
    csv = tmp_path / "base.csv"
    csv.write_text("phi_deg,L_mm\n" + "\n".join(f"{a},{b}" for a, b in zip(fine_phi, L)))
    phi, ref = EM.read_diagram(csv)
    dev = EM.deviation(emb, phi, ref)
    best = dev.iloc[0]
    assert (best["beta_deg"], best["alpha_deg"]) == (35.0, 10.0)
    assert best["max_abs_dev_mm"] < 1e-3
    bad = tmp_path / "bad.csv"
    bad.write_text("angle,L\n0,1\n")
    with pytest.raises(ValueError, match="phi_deg and L_mm"):
        EM.read_diagram(bad)


def test_colour_changer(emb):
    phi, paths = EM.colour_changer(emb, 3, pitch_mm=12.0)
    q = sewmech.kinematics(emb, np.radians(phi)).point("Q").p
    np.testing.assert_allclose(paths[2], q)  # the engaged slider follows F
    assert np.allclose(paths[0, :, 0], q[:, 0] - 24.0) and np.ptp(paths[0, :, 1]) == 0.0
    assert np.allclose(paths[4, :, 0], q[:, 0] + 24.0)
    with pytest.raises(ValueError, match="1..5"):
        EM.colour_changer(emb, 6)


def test_cli_json():
    out = CliRunner().invoke(app, ["embroidery-take-up", "--alpha-deg", "10", "--beta-deg", "35",
                                   "--points", "12", "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.stdout)
    assert data["phi_deg"] == [30.0 * i for i in range(12)] and len(data["L_mm"]) == 12
    y = _eye_y(np.radians(data["phi_deg"]), math.radians(10), math.radians(35))
    yt = _eye_y(np.radians(np.arange(0, 360, 0.01)), math.radians(10), math.radians(35))
    np.testing.assert_allclose(data["L_mm"], 2 * (yt.max() - y), atol=2e-6)
