"""Every bad input names file, table and key (or unit and crank angle) and says what to do."""

import numpy as np
import pytest

import sewmech
from conftest import BENCH, FOURBAR, FOURBAR_LOOP, PHI, fourbar
from sewmech import AssemblyError, ConvergenceError, MachineFileError


def bad(text, **kw):
    with pytest.raises(MachineFileError) as exc:
        sewmech.machine_from_toml(text, file="bad.toml")
    return exc.value


def base(**kw):
    return FOURBAR.format(**{**BENCH, **kw})


def test_unknown_key():
    e = bad(base().replace('lengths = [', 'lenghts = [1.0, 2.0]\nlengths = ['))
    assert e.file == "bad.toml" and e.key == "lenghts"
    assert 'units[1] "dyad"' in e.table
    assert "unknown key 'lenghts'" in str(e) and "lengths" in str(e)


def test_unknown_key_in_points():
    e = bad(base().replace("[points.D]\n", "[points.D]\nz = 1.0\n"))
    assert e.table == "points.D" and e.key == "z" and "expected one of: note, x, y" in str(e)


def test_unknown_point():
    e = bad(base().replace('joints = ["B", "D"]', 'joints = ["B", "Dx"]'))
    assert e.key == "joints" and "unknown point 'Dx'" in str(e) and "Did you mean D" in str(e)


def test_point_used_before_it_is_solved():
    header = FOURBAR.split("[[units]]")[0].format(**BENCH)
    crank = '[[units]]\ntype = "crank"\nname = "crank"\npivot = "A"\npoints = { B = [15.0, 0.0] }\n'
    dyad = ('[[units]]\ntype = "rrr"\nname = "dyad"\njoints = ["B", "D"]\nnew = "C"\n'
            'links = ["coupler", "rocker"]\nlengths = [40.0, 35.0]\nbranch = 1\n')
    # a second dyad that needs C, placed above the dyad that solves C
    late = ('[[units]]\ntype = "rrr"\nname = "late"\njoints = ["C", "A"]\nnew = "E"\n'
            'links = ["l1", "l2"]\nlengths = [40.0, 35.0]\nbranch = 1\n')
    e = bad(header + crank + late + dyad)
    assert e.table == 'units[1] "late"' and e.key == "joints"
    assert "point 'C' is used before it is solved" in str(e) and "move the unit" in str(e)


def test_non_positive_length():
    e = bad(base(cd=-35.0))
    assert e.key == "lengths[1]" and "positive length" in str(e)
    e = bad(base(bc=0.0))
    assert e.key == "lengths[0]" and "positive length" in str(e)


def test_branch_not_plus_minus_one():
    e = bad(base(branch=2))
    assert e.key == "branch" and "+1 or -1" in str(e) and "got 2" in str(e)


def test_missing_key_and_bad_toml():
    e = bad(base().replace('new = "C"\n', ""))
    assert e.key == "new" and "missing required key" in str(e)
    e = bad("[machine\nname='x'")
    assert "not valid TOML" in str(e)


def test_unknown_unit_type():
    e = bad(base().replace('type = "rrr"', 'type = "rrrr"'))
    assert "unknown unit type 'rrrr'" in str(e)


def test_loop_counts_and_unused_unknowns():
    text = FOURBAR_LOOP.format(**BENCH, assembly=0.0, g_coupler=60.0, g_rocker=95.0)
    e = bad(text.replace("rocker = 95.0 }", "rocker = 95.0, extra = 1.0 }"))
    assert "3 unknowns" in str(e) and e.key == "loops"
    # two loop equations, two unknowns, but one unknown appears in no term
    e = bad(text.replace("rocker = 95.0 }", "spare = 1.0 }").replace(
        '{link = "rocker", length = 35.0, sign = -1}', '{point = "C", sign = -1}'))
    assert "unknown point 'C'" in str(e) or "appears in no loop term" in str(e)


def test_assembly_error_names_unit_and_angle():
    m = fourbar(bc=10.0, cd=10.0)  # 10 + 10 cannot bridge the 23..53 mm from B to D
    with pytest.raises(AssemblyError) as exc:
        sewmech.kinematics(m, PHI)
    e = exc.value
    assert e.unit == "dyad" and e.phi_deg == pytest.approx(0.0)
    assert "unit 'dyad' at shaft angle phi = 0 deg" in str(e) and "cannot be assembled" in str(e)


def test_assembly_error_at_a_later_angle():
    # a crank-rocker that fails only where B is far from D (near phi = 180 deg)
    m = fourbar(bc=25.0, cd=25.0)
    with pytest.raises(AssemblyError) as exc:
        sewmech.kinematics(m, PHI)
    assert 90.0 < exc.value.phi_deg < 270.0


def test_batch_gets_a_feasibility_mask_not_silent_nan():
    m = fourbar()
    params = m.parameters({"dyad.length1": np.array([40.0, 5.0]),
                           "dyad.length2": np.array([35.0, 5.0])})
    r = sewmech.kinematics(m, PHI, params=params, on_failure="mask")
    assert r.feasible[0].all() and not r.feasible[1].any()
    assert (r.failure_unit[1] == m.unit_names.index("dyad")).all()
    assert np.isfinite(r.p[0]).all()
    assert np.isnan(r.point("C").p[1]).all()
    with pytest.raises(AssemblyError) as exc:
        sewmech.kinematics(m, PHI, params=params)
    assert exc.value.design == (1,) and "design (1,)" in str(exc.value)


def test_loop_non_convergence_names_loop_angle_residual():
    # lengths that cannot close: the loop solver must say so, with the residual
    text = FOURBAR_LOOP.format(**{**BENCH, "bc": 5.0, "cd": 5.0}, assembly=0.0, g_coupler=60.0,
                               g_rocker=95.0)
    m = sewmech.machine_from_toml(text)
    with pytest.raises(ConvergenceError) as exc:
        sewmech.kinematics(m, PHI)
    e = exc.value
    assert e.unit == "fourbar" and e.phi_deg == pytest.approx(0.0)
    assert "loop 'ABCD'" in str(e)
    assert "residual" in str(e) or "singular" in str(e)


def test_unknown_names_in_api():
    m = fourbar()
    with pytest.raises(KeyError, match="did you mean dyad.length1"):
        m.parameters({"dyad.lenght1": 3.0})
    r = sewmech.kinematics(m, PHI)
    with pytest.raises(KeyError, match="no point 'Z'"):
        r.point("Z")
    with pytest.raises(ValueError, match="one-dimensional"):
        sewmech.kinematics(m, np.zeros((2, 2)))


def test_unreadable_file_and_unknown_machine(tmp_path):
    with pytest.raises(MachineFileError, match="shipped machines: .*jb1-3"):
        sewmech.load_machine(tmp_path / "nope.toml")


def test_sewing_roles_must_name_existing_parts():
    sew = '\n[sewing]\nplate_y = -10.0\nneedle_point = "{pt}"\nneedle_eye = "P"\n{extra}'
    e = bad(base() + sew.format(pt="Px", extra=""))
    assert e.table == "sewing" and e.key == "needle_point" and "unknown point 'Px'" in str(e)
    e = bad(base() + sew.format(pt="P", extra='shuttle_link = "rockr"\n'))
    assert e.key == "shuttle_link" and "Did you mean rocker" in str(e)
    e = bad(base() + sew.format(pt="P", extra='hook_crank = "dyad"\n'))
    assert e.key == "hook_crank" and "not the name of a crank unit" in str(e)
    e = bad(base() + sew.format(pt="P", extra="fabric_thickness = -1.0\n"))
    assert e.table == "sewing" and e.key == "fabric_thickness"
    # a machine without [sewing] gets a clear message from the timing analyses
    from sewmech import timing

    with pytest.raises(ValueError, match=r"no \[sewing\] table"):
        timing.loop_lift(fourbar())
