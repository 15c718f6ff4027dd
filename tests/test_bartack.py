"""The shipped class 1820 bar-tack machine (bartack-1820.toml): it loads and is listed, its
existing counterweight is the balancing paper's S_fact = 43.5 g cm, its needle stroke is the
centred slider-crank's 2 r, and the paper's Delta-Q balancing finds a root for the extra
counterweight."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sewmech.cli import app
from sewmech.mass import MATERIALS
from typer.testing import CliRunner

import sewmech
from sewmech.design.balancing import balance
from sewmech.engine.mass import from_spec

NAME = "bartack-1820"
S_FACT_KGMM = 0.435  # 43.5 g cm (Sunkuev, Radkevich, Tsvetkov): the counterweight before balancing


@pytest.fixture(scope="module")
def machine():
    return sewmech.load_machine(NAME)


def test_loads_and_is_listed(machine):
    assert machine.name == NAME
    assert NAME in sewmech.shipped_machines()
    out = CliRunner().invoke(app, ["machines"])
    assert out.exit_code == 0 and NAME in out.stdout
    out = CliRunner().invoke(app, ["check", NAME])
    assert out.exit_code == 0 and "checked" in out.stdout and "ready" in out.stdout


def _is_counterweight(solid) -> bool:
    return "EXISTING COUNTERWEIGHT" in solid.note


def test_existing_counterweight_is_the_papers_s_fact(machine):
    spec = machine.spec.masses["needle_crank"]
    cw = [s for s in spec.solids if _is_counterweight(s)]
    assert len(cw) == 1
    box = cw[0]
    # by hand: a steel box, rho * volume * distance of its centre from the shaft axis
    rho = 7850.0e-9  # kg/mm^3
    a, b, c = box.size
    m = rho * a * b * c
    r = math.hypot(box.center[0], box.center[1])
    assert m * r == pytest.approx(S_FACT_KGMM, rel=1e-5)
    assert box.center[0] < 0.0 and box.center[1] == 0.0  # opposite the crank pin B (+u)
    # against sewmech's mass properties: the crank link minus the link without the counterweight
    assert MATERIALS[spec.material] == pytest.approx(rho * 1e9)
    full = from_spec(spec)
    rest = from_spec(spec.model_copy(update={"solids": [s for s in spec.solids
                                                        if not _is_counterweight(s)]}))
    s_cw = full.mass * full.com[:2] - rest.mass * rest.com[:2]  # kg mm, in the crank's (u, v)
    assert s_cw[0] == pytest.approx(-m * r, rel=1e-12)  # the two agree exactly
    assert s_cw[0] == pytest.approx(-S_FACT_KGMM, rel=1e-5)  # centre given to 0.1 um
    assert abs(s_cw[1]) < 1e-12
    # the extra counterweight sits along the same direction and starts off
    extra = machine.spec.counterweights["extra"]
    assert extra.link == "needle_crank" and extra.angle_deg == 180.0
    assert extra.static_moment_gcm == 0.0


def test_needle_stroke_is_twice_the_crank_radius(machine):
    phi = np.radians(np.arange(0.0, 360.0, 1.0))  # holds both dead centres (90 and 270 deg)
    res = sewmech.kinematics(machine, phi)
    r_crank = np.hypot(*res.point("B").p.T)
    assert np.ptp(r_crank) < 1e-12
    r = float(r_crank[0])
    y = res.point("needle.point").p[:, 1]
    assert np.ptp(res.point("needle.point").p[:, 0]) < 1e-12  # the bar moves vertically
    assert np.ptp(y) == pytest.approx(2.0 * r, abs=1e-9)
    assert r == pytest.approx(17.5)  # 35 mm stroke ([Juki-six-elements]: Juki DDL-5550H)
    assert np.degrees(phi[np.argmax(y)]) == pytest.approx(90.0)  # the file's convention
    # closed form of the centred slider-crank at phi: y_C = r sin(phi) - sqrt(l^2 - r^2 cos^2)
    l = 50.0
    yc = res.point("C").p[:, 1]
    assert np.allclose(yc, r * np.sin(phi) - np.sqrt(l * l - (r * np.cos(phi)) ** 2),
                       atol=1e-9)


def test_delta_q_balancing_of_the_extra_counterweight(machine):
    res = balance(machine, "delta-q", ["extra"])
    assert res.status == "optimal"
    assert res.after["delta_q_N"] < 1e-6 * res.before["peak_force_N"]
    assert res.before["delta_q_N"] > 1.0  # there was something to balance
    s_add = res.counterweights["extra"]["static_moment_gcm"]
    # of the paper's order (64.1 g cm computed, 143 g cm measured), inside the file's limit
    assert 10.0 < s_add < 400.0
    assert res.counterweights["extra"]["angle_deg"] == pytest.approx(180.0)
    assert res.after["peak_force_N"] < res.before["peak_force_N"]


def test_the_files_header_states_what_the_command_prints(machine):
    """The header comment's numbers are the command's (S_opt was 178.5 g cm in the header,
    the sum of the two counterweights, where the command prints the crank's net 142.9)."""
    import re
    from pathlib import Path

    from sewmech.design.balancing import paper_workflow

    head = " ".join(line.lstrip("# ") for line in Path(machine.file).read_text(
        encoding="utf-8").splitlines() if line.startswith("#"))
    p = paper_workflow(machine, "extra")
    res = p["result"]
    said = {key: float(re.search(pattern, head).group(1)) for key, pattern in (
        ("s_add", r"finds S_add = ([\d.]+) g cm"),
        ("s_opt", r"prints S_opt = \|S_1 \+ S_add\| = ([\d.]+) g cm"),
        ("s1", r"S_1 = ([\d.]+) g cm being"),
        ("peak0", r"peak shaking force falls from ([\d.]+) N"),
        ("peak1", r"peak shaking force falls from [\d.]+ N to ([\d.]+) N"))}
    got = {"s_add": p["s_add_gcm"], "s_opt": p["s_opt_gcm"], "s1": p["s1_gcm"],
           "peak0": res.before["peak_force_N"], "peak1": res.after["peak_force_N"]}
    for key, value in said.items():  # each stated to one decimal
        assert abs(got[key] - value) <= 0.05 + 1e-9 * value, (key, got[key], value)
    # and the sum the paper's S_opt = S_fact + S_add would give, named as such
    assert f"43.5 + {said['s_add']:.1f} = {43.5 + said['s_add']:.1f} g cm" in head
    out = CliRunner().invoke(app, ["balance", NAME])
    assert out.exit_code == 0
    assert f"S_opt = |S_1 + S_add| {said['s_opt']:.4g} g cm" in " ".join(out.stdout.split())
