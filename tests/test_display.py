"""Numbers as people read them: round-off of a quantity's scale shows as 0, flags as words."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sewmech.app.display import is_round_off, number, yes_no


def test_round_off_of_the_scale_reads_zero():
    # a zero stitch computed from 4 mm strokes: a few ulps of 4 mm
    assert number(9.3e-07 * 1e-9, scale=4.0) == "0"
    assert number(6e-17, scale=1.0) == "0"
    assert number(-0.0) == "0" and number(0.0) == "0"
    # a real small value of a small quantity is not round-off
    assert number(9.3e-07, scale=9.3e-07) == "9.3e-07"
    assert number(2.13e-14) == "2.13e-14"  # no scale given: only an exact zero is 0


def test_digits_undefined_and_infinite():
    assert number(math.pi) == "3.142"
    assert number(math.pi, digits=6) == "3.14159"
    assert number(None) == "none" and number(float("nan"), undefined="n/a") == "n/a"
    assert number(np.float64(2.5)) == "2.5"
    assert number(float("inf")) == "inf" and number(-float("inf")) == "-inf"


@pytest.mark.parametrize("x, scale, zero", [(1e-10, 1.0, True), (2e-9, 1.0, False),
                                            (-5e-7, 1000.0, True), (1e-3, 1000.0, False)])
def test_the_round_off_boundary_is_relative(x, scale, zero):
    assert is_round_off(x, scale) is zero


def test_flags_read_yes_or_no():
    assert yes_no(True) == "yes" and yes_no(np.bool_(False)) == "no"


def test_lengths_and_angles_are_shown_no_finer_than_the_files_give_them():
    from sewmech.app.display import number_in

    # a stitch of 9.3e-07 mm at the zero mark comes from a phase given to 0.0001 deg
    assert number_in(9.3e-07, "mm") == "0" and number_in(-1.2e-05, "deg") == "0"
    assert number_in(3.85812, "mm") == "3.8581" and number_in(208.032, "deg") == "208.032"
    assert number_in(-8.5e-05, "mm") == "-0.0001"
    # other units keep their significant digits
    assert number_in(0.000529327, "kg m^2") == "0.000529327"
    assert number_in(float("nan"), "mm") == "none" and number_in(None, "mm") == "none"


def test_table_cells_by_column_unit_and_by_row_unit():
    import pandas as pd

    from sewmech.app.display import column_unit, table_cells

    assert [column_unit(c) for c in ("stitch change -5% [mm]", "regulator_deg", "x_mm_reg_30deg",
                                     "S [g cm]", "peak_Nm", "feasible")] == [
        "mm", "deg", "mm", "g cm", None, None]
    sens = pd.DataFrame({"parameter": ["width"], "stitch change [mm]": [1.42e-14],
                         "timing change [deg]": [-2.27e-13], "feasible": [np.True_]})
    assert table_cells(sens).iloc[0].tolist() == ["width", "0", "0", "yes"]
    # one quantity a row: its unit, and round-off of the row's largest value
    crit = pd.DataFrame({"figure": ["Delta-Q", "peak"], "unit": ["N", "N"],
                         "before": [8.28995, 32.1611], "delta-q": [2.13163e-14, 24.8537],
                         "n": [3, 4]})
    shown = table_cells(crit)
    assert shown["delta-q"].tolist() == ["0", "24.8537"]
    assert shown["n"].tolist() == ["3", "4"]
    checks = pd.DataFrame({"check": ["swing", "zero stitch"], "value": [208.032, 9.29e-07],
                           "unit": ["deg", "mm"], "passed": [True, False]})
    assert table_cells(checks)["value"].tolist() == ["208.032", "0"]
    assert table_cells(checks)["passed"].tolist() == ["yes", "no"]
    assert table_cells(pd.DataFrame({"x": [np.nan, -0.0]}))["x"].tolist() == ["none", "0"]
    key = pd.DataFrame({"quantity": ["peak torque", "mean torque", "peak power", "mean power",
                                     "inertia"],
                        "value": [1.09469, -1.97373e-17, 229.3, -2.58701e-15, 0.000529327],
                        "unit": ["N m", "N m", "W", "W", "kg m^2"]})
    assert table_cells(key)["value"].tolist() == ["1.09469", "0", "229.3", "0", "0.000529327"]


def test_signed_values_of_legends_have_no_negative_zero():
    from sewmech.app.display import signed

    assert signed(-1.22e-05) == "0" and signed(-1.22e-05, 4) == "0"
    assert signed(3.5) == "+3.50" and signed(-25.7343) == "-25.73"
    assert signed(-25.7343, 4) == "-25.7343"
