"""Assembly over the whole turn (sewmech.assembly) and the angle convention's reference event,
each against a closed form or a brute-force scan."""

import math

import numpy as np
import pytest
from conftest import BENCH, FOURBAR, FOURBAR_LOOP, SLIDER_CRANK
from typer.testing import CliRunner

import sewmech
from sewmech.assembly import prove_assembly
from sewmech.cli import app
from sewmech.extremes import check_reference

runner = CliRunner()


def _gap_fourbar(cd=22.995):
    """A crank-rocker whose coupler and rocker (30 + cd mm) just fail to reach D when B is
    farthest from it (|BD| = 15 + 38 = 53 mm at crank angle 180 deg), i.e. at phi = 177.5 deg,
    halfway between two grid points of a 5 deg grid (the crank's phase is 2.5 deg)."""
    return sewmech.machine_from_toml(FOURBAR.format(**{**BENCH, "bc": 30.0, "cd": cd,
                                                      "phase": 2.5}), "gap.toml")


def test_a_failure_between_grid_points_is_found_with_its_exact_range(tmp_path):
    m = _gap_fourbar()
    grid = sewmech.kinematics(m, np.radians(np.arange(0.0, 360.0, 5.0)))
    assert grid.all_feasible  # the grid alone would pass this machine
    proof = prove_assembly(m, step_deg=5.0)
    assert not proof.ok and len(proof.failures) == 1
    f = proof.failures[0]
    # closed form: |BD|^2 = 15^2 + 38^2 - 2 15 38 cos(theta) > 52.995^2, theta = phi + 2.5 deg
    c = (15.0**2 + 38.0**2 - 52.995**2) / (2 * 15.0 * 38.0)
    half = 180.0 - math.degrees(math.acos(c))
    assert f.unit == "dyad"
    assert f.from_deg == pytest.approx(177.5 - half, abs=1e-8)
    assert f.to_deg == pytest.approx(177.5 + half, abs=1e-8)
    low = min(proof.margins, key=lambda g: g.value_mm)
    assert low.value_mm == pytest.approx(-0.005, abs=1e-9) and low.phi_deg == pytest.approx(177.5)
    # the CLI refuses it, naming the unit and the range
    with pytest.raises(sewmech.errors.ParameterError, match="outside the range -30 deg .. 30"):
        prove_assembly(sewmech.load_machine("jb1-3"), inputs={"regulator": math.radians(31)})
    path = tmp_path / "gap.toml"
    path.write_text(FOURBAR.format(**{**BENCH, "bc": 30.0, "cd": 22.995, "phase": 2.5}))
    out = runner.invoke(app, ["check", str(path), "--step-deg", "5"])
    assert out.exit_code == 2 and "unit 'dyad' fails over phi 175.75" in out.stderr


def test_a_machine_that_assembles_gets_its_smallest_margins_exactly():
    # against a brute-force scan at 0.001 deg: the located minimum is never above the scan's
    m = _gap_fourbar(cd=23.2)
    proof = prove_assembly(m, step_deg=5.0)
    assert proof.ok
    phi = np.radians(np.arange(0.0, 360.0, 0.001))
    r = sewmech.kinematics(m, phi)
    d = np.linalg.norm(r.point("C").p - r.point("B").p, axis=-1)  # = 30 always
    bd = np.linalg.norm(r.point("B").p - np.array([38.0, 0.0]), axis=-1)
    assert np.allclose(d, 30.0)
    by = {g.condition: g for g in proof.margins}
    outer = by["l1 + l2 - |B D|"]
    assert outer.value_mm == pytest.approx(53.2 - 53.0, abs=1e-9)
    assert outer.value_mm <= (53.2 - bd).min() + 1e-12
    inner = by["|B D| - |l1 - l2|"]
    assert inner.value_mm == pytest.approx((bd - 6.8).min(), abs=1e-6)


def test_slider_and_rotating_guide_margins_against_a_scan():
    # offset slider-crank: the rod must reach the guide line from the crank pin
    m = sewmech.machine_from_toml(SLIDER_CRANK.format(r=15.0, l=44.0, e=10.0, alpha=90.0,
                                                      gx=0.0, gy=0.0, branch=1))
    proof = prove_assembly(m, step_deg=10.0)
    phi = np.radians(np.arange(0.0, 360.0, 0.001))
    bx = sewmech.kinematics(m, phi).point("B").p[:, 0]
    # the guide is the vertical x = -10 (offset 10 to the left of +y): distance |bx + 10|
    margins = sorted(g.value_mm for g in proof.margins)
    assert margins[0] == pytest.approx((44.0 - np.abs(bx + 10.0)).min(), abs=1e-6)
    assert margins[0] == pytest.approx(44.0 - 25.0, abs=1e-9)


def test_jb_machines_are_proved_at_every_regulator_limit():
    for name in ("jb1-3", "jb8-2"):
        m = sewmech.load_machine(name)
        spec = m.spec.inputs["regulator"]
        for reg in (spec.min_deg, 0.0, spec.max_deg):  # both ends and the zero mark
            proof = prove_assembly(m, inputs={"regulator": math.radians(reg)}, step_deg=5.0)
            assert proof.ok, (name, reg, proof.failures)
            assert proof.loop_steps == 1440 and set(proof.loop_units) == {
                "feed_fork", "lift", "feed_bar"}
            assert proof.smallest.value_mm > 1.0


def test_a_loop_that_cannot_pass_a_change_point_is_reported():
    # a parallelogram four-bar as a loop unit: at the change points (crank along AD) the loop
    # Jacobian is singular and the continuation cannot go on on its branch
    text = FOURBAR_LOOP.format(**{**BENCH, "ab": 15.0, "bc": 38.0, "cd": 15.0, "dx": 38.0},
                               assembly=10.0, g_coupler=0.0, g_rocker=10.0)
    proof = prove_assembly(sewmech.machine_from_toml(text), step_deg=5.0)
    assert not proof.ok and {f.unit for f in proof.failures} == {"fourbar"}


def test_reference_event_is_checked():
    for name in ("jb1-3", "jb8-2", "embroidery-131", "fourbar-benchmark"):
        assert check_reference(sewmech.load_machine(name)).status == "ok", name
    # the needle top is at 90 deg in JB1-3: a file claiming 80 deg is wrong by 10
    m = sewmech.load_machine("jb1-3")
    text = open(m.file).read().replace("reference_phi_deg = 90.0", "reference_phi_deg = 80.0")
    bad = sewmech.machine_from_toml(text, "jb.toml")
    ref = check_reference(bad)
    assert ref.status == "mismatch" and ref.found_deg == pytest.approx(90.0, abs=1e-6)
    # without the keys it says that it did not check
    plain = sewmech.machine_from_toml(FOURBAR.format(**BENCH))
    assert check_reference(plain).status == "unchecked"
    assert "not checked" in check_reference(plain).text


def test_branch_hint_names_the_upstream_branch_that_assembles(tmp_path):
    # a slider on a guide 28.7 mm below the frame line, driven from the four-bar's joint C:
    # only the dyad's lower branch (C below B -> D, y in -35 .. -22.4 mm) brings C within the
    # rod's 20 mm of the guide
    text = FOURBAR.format(**BENCH) + (
        '[points.G]\nx = 20.0\ny = -28.7\n[[units]]\ntype = "rrp"\nname = "slide"\npin = "C"\n'
        'rod = "rod"\nlength = 20.0\nnew = "S"\nslider = "block"\nguide_point = "G"\n'
        'guide_angle_deg = 0.0\nbranch = 1\n')
    m = sewmech.machine_from_toml(text, "six.toml")
    with pytest.raises(sewmech.AssemblyError) as exc:
        sewmech.kinematics(m, np.radians(np.arange(0.0, 360.0, 5.0)))
    e = exc.value
    assert e.unit == "slide" and e.file == "six.toml" and e.ranges_deg == [(0.0, 355.0)]
    assert "With branch = -1 in unit 'dyad'" in str(e)
    fixed = sewmech.machine_from_toml(text.replace("branch = 1\n[[units]]\ntype = \"point\"",
                                                   "branch = -1\n[[units]]\ntype = \"point\""))
    assert sewmech.kinematics(fixed, np.radians(np.arange(0.0, 360.0, 5.0))).all_feasible
