"""How numbers are shown to people (tables on the command line, the report, the page): at the
precision the quantity has, never as its round-off.

A computed quantity that is zero in exact arithmetic comes out of floating point as a few ulps
of the numbers it was computed from (a stitch of ``9.3e-07 mm`` at the zero mark of a regulator,
a derivative of ``6e-17``, ``-0.0000``). Shown as it is, it reads as a real, small value.
:func:`number` shows a value as ``0`` when it is below the round-off of its quantity's scale
(``scale``: the size of the numbers it was computed from, in the same unit), and otherwise
with ``digits`` significant digits; :func:`yes_no` shows a flag as a word.
"""

from __future__ import annotations

import math

#: the relative size below which a value is round-off of its scale (float64 carries about 16
#: digits; a chain of computations loses a few of them)
ROUND_OFF = 1e-9


def is_round_off(x: float, scale: float) -> bool:
    """Whether ``x`` is indistinguishable from zero for a quantity of size ``scale`` (same
    unit): ``|x| <= ROUND_OFF * |scale|``."""
    return abs(x) <= ROUND_OFF * abs(scale)


def number(x: float | None, scale: float | None = None, digits: int = 4,
           undefined: str = "none") -> str:
    """``x`` with ``digits`` significant digits, ``0`` where it is round-off of ``scale``
    (default: ``x`` is its own scale, so only an exact zero or ``-0.0`` reads ``0``), and
    ``undefined`` for None or NaN. Infinities read ``inf`` / ``-inf``."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return undefined
    x = float(x)
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x == 0.0 or (scale is not None and is_round_off(x, scale)):
        return "0"
    return f"{x:.{digits}g}"


def yes_no(flag: bool) -> str:
    """A flag as people read it."""
    return "yes" if bool(flag) else "no"
