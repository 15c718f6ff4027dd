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
import re

import numpy as np

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


#: the finest step in which machine files give lengths (mm) and angles (deg) (the shipped files
#: carry 4 decimals): a length or an angle computed from them is known no finer than this, so it
#: is shown no finer (a stitch of 9.3e-07 mm at the zero mark comes from a phase given to
#: 0.0001 deg, and reads 0)
RESOLUTION = {"mm": 1e-4, "deg": 1e-4}


def number_in(x: float | None, unit: str | None, scale: float | None = None, digits: int = 6,
              undefined: str = "none") -> str:
    """:func:`number` for a quantity in ``unit``: a length (mm) or an angle (deg) first rounded
    to its :data:`RESOLUTION`; any other unit as :func:`number` shows it."""
    res = RESOLUTION.get(unit or "")
    if res is not None and x is not None and math.isfinite(float(x)):
        x = float(f"{round(float(x) / res) * res:.12g}")
    return number(x, scale, digits, undefined)


_COLUMN_UNIT = re.compile(r"\[([^\]]+)\]|(?:^|_)(mm|deg)(?:_|$)|\s(mm|deg)$")


def column_unit(name: str) -> str | None:
    """The unit a table's column names: ``stitch change [mm]``, ``regulator_deg``,
    ``x_mm_reg_30deg``, ``height mm``; None if it names none."""
    m = _COLUMN_UNIT.search(str(name))
    return next((g for g in m.groups() if g), None) if m else None


def table_cells(df):
    """Every cell of a table (a pandas DataFrame) as it is shown: flags as yes/no, undefined
    values as "none", numbers at the precision of their quantity.

    A column that names its unit (``[mm]``, ``_deg``) is that unit's, and a value in it is
    round-off of the column's largest. In a table with a ``unit`` column the other numeric
    columns are each row's unit (one quantity a row, e.g. the checks), and a value there is
    round-off of the largest value of that unit in the table (a mean torque of 2e-17 N m
    beside a peak of 1.1 N m reads 0)."""
    import pandas as pd

    def numeric(v) -> bool:
        return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(
            v, (bool, np.bool_))

    def size(values) -> float:
        xs = [abs(float(v)) for v in values if numeric(v) and math.isfinite(float(v))]
        return max(xs, default=0.0)

    by_row = "unit" in df.columns
    own = {c: column_unit(c) for c in df.columns}
    rowwise = [c for c in df.columns if by_row and own[c] is None and c != "unit"]
    unit_scale: dict = {}
    if rowwise:
        for unit, rows in df.groupby(df["unit"].astype(str), sort=False):
            unit_scale[unit] = size(rows[rowwise].to_numpy().ravel().tolist())
    out = {}
    for c in df.columns:
        col_scale = size(df[c])
        cells = []
        for i, v in enumerate(df[c].tolist()):
            if isinstance(v, (bool, np.bool_)):
                cells.append(yes_no(v))
            elif v is None or (isinstance(v, (float, np.floating)) and math.isnan(v)):
                cells.append("none")
            elif isinstance(v, (int, np.integer)):
                cells.append(str(int(v)))
            elif numeric(v):
                if c in rowwise:
                    unit = df["unit"].iloc[i]
                    scale = unit_scale[str(unit)]
                else:
                    unit, scale = own[c], col_scale
                cells.append(number_in(float(v), unit if isinstance(unit, str) else None,
                                       scale or None))
            else:
                cells.append(str(v))
        out[c] = cells
    return pd.DataFrame(out, columns=df.columns)


def signed(x: float, decimals: int = 2) -> str:
    """``x`` with its sign and ``decimals`` decimals (a legend's ``+3.50 mm``); a value that
    rounds to zero there reads ``0``, never ``-0.00``."""
    v = round(float(x), decimals)
    return "0" if v == 0.0 else f"{v:+.{decimals}f}"
