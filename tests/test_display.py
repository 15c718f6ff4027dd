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
