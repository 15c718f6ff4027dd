"""Counterweights ([counterweights.NAME]): point masses on links, each value a parameter.

The dynamics adds them by superposition (the forces are linear in the masses); every test here
compares that with the same point masses written into the links' [masses] tables, which the
force kernel takes directly, or with a design compiled on its own.
"""

from __future__ import annotations

import math
from importlib import resources

import numpy as np
import pytest
from conftest import SLIDER_CRANK

from sewmech import machine_from_toml
from sewmech.engine.counterweights import counterweight_values, describe, static_moment
from sewmech.engine.dynamics import DynamicsPlan, inverse_dynamics
from sewmech.engine.errors import MachineFileError

HEAD = SLIDER_CRANK.format(r=15.0, l=44.0, e=0.0, alpha=90.0, gx=0.0, gy=0.0, branch=-1) + """
[masses.block]
mass = 0.05
com = [0.0, 0.0]
inertia_zz = 30.0
"""

WITH_COUNTERWEIGHTS = HEAD + """
[masses.rod]
mass = 0.012
com = [20.0, 0.5]
inertia_zz = 0.0
[counterweights.crank_cw]
link = "crank"
static_moment_gcm = 50.0
angle_deg = 170.0
radius_mm = 10.0
[counterweights.rod_cw]
link = "rod"
mass_g = 5.0
at_mm = [10.0, 2.0]
"""


def as_point_solids(crank_cw=(50.0, 170.0, 10.0), rod_cw=(5.0, 10.0, 2.0)) -> str:
    """The same machine with the counterweights written into [masses] as point solids."""
    S, ang, r = crank_cw
    m_g, u, v = rod_cw
    a = math.radians(ang)
    rod = (f'{{ type = "point", mass = 0.012, at = [20.0, 0.5, 0.0] }}, '
           f'{{ type = "point", mass = {m_g / 1000.0!r}, at = [{u!r}, {v!r}, 0.0] }}')
    crank = (f'{{ type = "point", mass = {S / 100.0 / r!r}, '
             f'at = [{r * math.cos(a)!r}, {r * math.sin(a)!r}, 0.0] }}')
    return HEAD + f"""
[masses.rod]
material = "steel"
solids = [ {rod} ]
[masses.crank]
material = "steel"
solids = [ {crank} ]
"""


PHI = np.radians(np.arange(0.0, 360.0, 5.0))
# a shaft speed that varies over the turn, so that every link has an angular acceleration
OMEGA = 100.0 + 20.0 * np.sin(PHI)
EPSILON = 20.0 * np.cos(PHI) * OMEGA  # d omega / dt = d omega / d phi * omega
QUANTITIES = ("unknowns", "shaking_force", "shaking_moment", "kinetic_energy",
              "kinetic_energy_rate", "potential_energy", "potential_energy_rate")


def close(a, b):
    scale = max(1.0, float(np.abs(b).max()))
    return np.allclose(a, b, rtol=0.0, atol=1e-11 * scale)


@pytest.mark.parametrize("speed", ["constant", "varying"])
def test_counterweights_are_point_masses(speed):
    kw = {} if speed == "constant" else {"omega": OMEGA, "epsilon": EPSILON}
    mine = inverse_dynamics(machine_from_toml(WITH_COUNTERWEIGHTS), PHI, **kw)
    ref = inverse_dynamics(machine_from_toml(as_point_solids()), PHI, **kw)
    for q in QUANTITIES:
        assert close(getattr(mine, q), getattr(ref, q)), q
    # and the power balance holds with them: P_in = dT/dt + dV/dt - P_loads
    rhs = mine.kinetic_energy_rate + mine.potential_energy_rate - mine.external_power
    assert close(mine.input_power, rhs)
    # the counterweights change the answer (the test above is not of two massless machines)
    plain = inverse_dynamics(machine_from_toml(HEAD), PHI, **kw)
    assert np.abs(plain.input_torque - mine.input_torque).max() > 1.0


def test_a_batch_of_counterweights_equals_each_design_alone():
    m = machine_from_toml(WITH_COUNTERWEIGHTS)
    values = {"crank_cw.static_moment": np.array([0.0, 0.3, 0.9]),
              "crank_cw.angle": np.array([0.5, 2.0, 3.5]),
              "rod_cw.mass": np.array([0.002, 0.0, 0.01]),
              "rod_cw.v": np.array([-3.0, 1.0, 4.0])}
    P = m.parameters(values)
    plan = DynamicsPlan(m, PHI)
    batch = plan(P)
    for k in range(3):
        alone = inverse_dynamics(m.with_parameters({n: v[k] for n, v in values.items()}), PHI)
        for q in ("unknowns", "shaking_force", "shaking_moment", "kinetic_energy"):
            assert close(getattr(batch, q)[k], getattr(alone, q)), (k, q)
    mass, u, v = counterweight_values(m.counterweights, P)
    assert np.allclose(mass[:, 0], values["crank_cw.static_moment"] / 10.0)
    assert np.allclose(u[:, 0], 10.0 * np.cos(values["crank_cw.angle"]))
    assert np.allclose(v[:, 1], values["rod_cw.v"])


def test_static_moment_and_description():
    S, ang = static_moment(0.05, -10.0, 0.0)
    assert math.isclose(S, 0.5) and math.isclose(ang, math.pi)
    m = machine_from_toml(WITH_COUNTERWEIGHTS)
    d = describe(m.counterweights[0], 0.05, 10.0 * math.cos(math.radians(170.0)),
                 10.0 * math.sin(math.radians(170.0)))
    assert math.isclose(d["static_moment_gcm"], 50.0) and math.isclose(d["mass_g"], 50.0)
    assert math.isclose(d["angle_deg"], 170.0) and math.isclose(d["radius_mm"], 10.0)


def jb13_text() -> str:
    return resources.files("sewmech.data.machines").joinpath("jb1-3.toml").read_text("utf-8")


def test_bearing_reactions_count_a_counterweight_on_the_shaft():
    """A counterweight on the needle crank at z = 260 mm (near the rear bearing) against the
    same point mass written among the crank's solids."""
    text = jb13_text()
    cw = text + """
[counterweights.added]
link = "needle_crank"
static_moment_gcm = 80.0
angle_deg = 200.0
radius_mm = 20.0
z_mm = 260.0
"""
    a = math.radians(200.0)
    u, v = 20.0 * math.cos(a), 20.0 * math.sin(a)
    marker = "  { type = \"cylinder\", radius = 12.0, length = 8.0, base = [0.0, 0.0, 322.0],"
    assert marker in text
    solid = (f"  {{ type = \"point\", mass = {0.8 / 20.0!r}, at = [{u!r}, {v!r}, 260.0] }},\n")
    ref_text = text.replace(marker, solid + marker)
    phi = np.radians(np.arange(0.0, 360.0, 10.0))
    mine = inverse_dynamics(machine_from_toml(cw), phi)
    ref = inverse_dynamics(machine_from_toml(ref_text), phi)
    for side in ("front", "rear"):
        assert close(getattr(mine.bearings, side), getattr(ref.bearings, side)), side
    assert close(mine.unknowns, ref.unknowns)
    plain = inverse_dynamics(machine_from_toml(text), phi)
    assert np.abs(plain.bearings.rear - mine.bearings.rear).max() > 1.0


@pytest.mark.parametrize("table, needle", [
    ('link = "crank"\nmass_g = 5.0\nat_mm = [1.0, 2.0]\nangle_deg = 3.0',
     "give either mass_g and at_mm"),
    ('link = "crank"\nstatic_moment_gcm = 5.0\nangle_deg = 3.0', "give either mass_g and at_mm"),
    ('link = "crankk"\nmass_g = 5.0\nat_mm = [1.0, 2.0]', "Did you mean crank"),
    ('link = "frame"\nmass_g = 5.0\nat_mm = [1.0, 2.0]', "not a moving link"),
    # out of its domain: what it means and what to give, not the validation library's words
    ('link = "crank"\nmass_g = -5.0\nat_mm = [1.0, 2.0]',
     "mass_g: is -5 g: a counterweight's mass cannot be negative. Give 0"),
    ('link = "crank"\nstatic_moment_gcm = 5.0\nangle_deg = 3.0\nradius_mm = 10.0\n'
     'max_static_moment_gcm = 0.0', "the largest static moment the space allows must be > 0"),
    ('link = "crank"\nstatic_moment_gcm = 5.0\nangle_deg = 3.0\nradius_mm = 10.0\n'
     'bore_mm = -8.0', "bore_mm: is -8 mm: the diameter of the shaft"),
])
def test_bad_counterweight_tables_are_located(table, needle):
    with pytest.raises(MachineFileError) as exc:
        machine_from_toml(HEAD + "[counterweights.cw]\n" + table + "\n")
    assert "counterweights.cw" in str(exc.value) and needle in str(exc.value)


def test_a_counterweight_name_cannot_take_a_parameter_of_the_machine():
    # the crank's point B has the parameters B.u and B.v; a counterweight called B would too
    with pytest.raises(MachineFileError, match="already a parameter"):
        machine_from_toml(HEAD + '[counterweights.B]\nlink = "crank"\nmass_g = 1.0\n'
                                 'at_mm = [1.0, 0.0]\n')


def test_a_counterweight_on_the_shaft_needs_its_plane():
    text = jb13_text() + ('\n[counterweights.added]\nlink = "needle_crank"\n'
                          'static_moment_gcm = 80.0\nangle_deg = 200.0\nradius_mm = 20.0\n')
    with pytest.raises(MachineFileError, match="z_mm"):
        machine_from_toml(text)


def test_negative_counterweight_parameter_is_refused_per_design():
    m = machine_from_toml(WITH_COUNTERWEIGHTS)
    P = m.parameters({"rod_cw.mass": np.array([0.01, -0.01])})
    from sewmech.engine.errors import ParameterError

    with pytest.raises(ParameterError, match="cannot be negative"):
        inverse_dynamics(m, PHI, params=P)


def test_command_line_sets_and_lists_counterweights_in_grams(tmp_path):
    import json

    from typer.testing import CliRunner

    from sewmech.cli import app

    f = tmp_path / "sc.toml"
    f.write_text(WITH_COUNTERWEIGHTS, encoding="utf-8")
    runner = CliRunner()
    out = runner.invoke(app, ["check", str(f), "--parameters"])
    assert out.exit_code == 0, out.output
    lines = [x.strip() for x in out.output.splitlines()]
    line = next(x for x in lines if x.startswith("crank_cw.static_moment"))
    assert line.split()[1:3] == ["50", "g"] and "g cm" in line
    line = next(x for x in lines if x.startswith("rod_cw.mass"))
    assert line.split()[1:3] == ["5", "g"]
    # --set in g cm and g: the same numbers as the library with the changed file
    out = runner.invoke(app, ["dynamics", str(f), "--step-deg", "30", "--json", "--set",
                              "crank_cw.static_moment=64.1gcm", "--set", "rod_cw.mass=0.002kg"])
    assert out.exit_code == 0, out.output
    rows = json.loads(out.output)["positions"]
    m = machine_from_toml(WITH_COUNTERWEIGHTS).with_parameters(
        {"crank_cw.static_moment": 0.641, "rod_cw.mass": 0.002})
    r = inverse_dynamics(m, np.radians(np.arange(0.0, 360.0, 30.0)))
    assert np.allclose([x["input_torque_Nm"] for x in rows], r.input_torque * 1e-3, atol=1e-12)
    assert math.isclose(m.spec.counterweights["crank_cw"].static_moment_gcm, 64.1)
    # a mass without its unit is refused with the way to write it
    out = runner.invoke(app, ["dynamics", str(f), "--set", "rod_cw.mass=5"])
    assert out.exit_code == 2 and "rod_cw.mass=5g" in out.output
