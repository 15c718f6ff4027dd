"""The double-crank thread take-up of an embroidery semi-automatic (Kozlov,
[Kozlov-take-up]): design procedure, thread drawn L(phi) for any (alpha, beta),
the paper's table, the comparison with a base machine's diagram, and the colour changer.

The mechanism is the shipped machine file ``embroidery-131`` (or any file with the same point
and unit names): drag-link four-bar ABCD (crank AB on the main shaft), crank DE rigid with DC,
rod EF, slider F on the vertical through D carrying the eye Q, thread guides M and N. The thread
drawn is the paper's L = l_max - l, l = |MQ| + |QN|, l_max with the eye at its top; it is the
supply of the file's ``[thread]`` path M -> Q -> N.

Conventions (docs/embroidery.md; the paper's drawings are missing, these are our reconstruction):
phi = 0 at the needle's top dead centre with AB pointing up, counter-clockwise; alpha is the
angle of the frame line AD from +x (counter-clockwise); beta is the angle from DC to DE,
clockwise. The design positions are phi1 = 60 deg and phi2 = phi1 + 240 deg, with DC half a turn
apart. Angles in degrees at this module's edges (``*_deg``), lengths mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..engine.errors import AnalysisError
from ..engine.kinematics import kinematics
from ..engine.machine import Machine
from .thread import thread_path

#: the paper's six (beta, alpha) pairs, degrees
PAPER_PAIRS = ((35.0, 5.0), (35.0, 10.0), (34.0, 15.0), (34.0, 20.0), (33.0, 25.0), (33.0, 30.0))


@dataclass(frozen=True)
class Design:
    """Link lengths (mm) and the design-position angles (deg) of the take-up."""

    ab: float
    bc: float
    cd: float
    ad: float
    de: float
    ef: float
    alpha_deg: float
    beta_deg: float


def _length(machine: Machine, *names: str) -> float:
    return float(np.hypot(*(machine.defaults[machine.parameter_index(n)] for n in names)))


#: the parameters the (alpha, beta) study of the embroidery take-up moves
_LAYOUT = ("D.x", "D.y", "E.u", "E.v", "M.x", "N.x")


def overrides(machine: Machine, alpha_deg: ArrayLike, beta_deg: ArrayLike,
              params=None) -> np.ndarray:
    """Parameter vectors (batch of the broadcast alpha, beta) that set the frame line AD at
    ``alpha_deg`` and DE at ``beta_deg`` from DC, keeping AD, DE and the guides on the eye's
    line (M, N follow D)."""
    missing = [p for p in _LAYOUT if p not in machine.parameter_names]
    if missing:
        raise AnalysisError(machine.file, "is not laid out as the embroidery take-up (it has no"
                            f" {', '.join(missing)})", "This study works on machines like"
                            " embroidery-131: frame points D, M, N on the eye's line and the"
                            " crank point E")
    a, b = np.broadcast_arrays(np.radians(np.asarray(alpha_deg, dtype=float)),
                               np.radians(np.asarray(beta_deg, dtype=float)))
    base = None if params is None else np.asarray(params, dtype=float)
    ad = _length(machine, "D.x", "D.y")
    de = _length(machine, "E.u", "E.v")
    dx = ad * np.cos(a)
    return machine.parameters({"D.x": dx, "D.y": ad * np.sin(a), "E.u": de * np.cos(-b),
                               "E.v": de * np.sin(-b), "M.x": dx, "N.x": dx}, base=base)


def design(machine: Machine, *, ab: float = 17.5, k1: float = 0.93, k2: float = 0.62,
           k3: float = 0.38, l2: float = 124.0, ef: float = 80.0, phi1_deg: float = 60.0,
           phi12_deg: float = 240.0) -> Design:
    """The paper's design procedure, analytically.

    Lengths: BC = K1 AB, DC = K2 AB, AD = K3 AB, DE = l2 / 4, EF as given (the paper: 2-2.5 DE,
    80 mm). alpha: the frame angle at which DC turns exactly half a turn while the crank turns
    phi12 from phi1 (the paper's two design positions, C1 D C2 = pi). beta: the angle from DC1
    to DE1 with DE1 along the eye's line (vertical), so that E, and the eye, are at their top at
    phi1. Uses the machine file's topology (``embroidery-131``) with these lengths.
    """
    bc, cd, ad, de = k1 * ab, k2 * ab, k3 * ab, l2 / 4.0
    base = machine.parameters({"B.u": ab, "B.v": 0.0, "four_bar.length1": bc,
                               "four_bar.length2": cd, "slider_F.length": ef})
    phi = np.radians(np.linspace(phi1_deg, phi1_deg + phi12_deg, 241))

    def dc_turn(alpha):
        p = machine.parameters({"D.x": ad * math.cos(alpha), "D.y": ad * math.sin(alpha)},
                               base=base)
        th = kinematics(machine, phi, params=p, points=[], links=["DC"], variables=[],
                        on_failure="mask").link("DC").theta
        if not np.isfinite(th).all():
            return np.nan
        th = np.unwrap(th)
        return abs(th[-1] - th[0]) - math.pi

    grid = np.radians(np.arange(-90.0, 90.5, 1.0))
    # the grid in one batch call (a call per frame angle took 20 s)
    pg = machine.parameters({"D.x": ad * np.cos(grid), "D.y": ad * np.sin(grid)}, base=base)
    thg = kinematics(machine, phi, params=pg, points=[], links=["DC"], variables=[],
                     on_failure="mask").link("DC").theta
    ok = np.isfinite(thg).all(axis=-1)
    turn = np.unwrap(np.where(np.isfinite(thg), thg, 0.0), axis=-1)
    vals = np.where(ok, np.abs(turn[:, -1] - turn[:, 0]) - math.pi, np.nan)
    k = np.nonzero(np.isfinite(vals[:-1]) & np.isfinite(vals[1:]) & (vals[:-1] * vals[1:] < 0))[0]
    if k.size == 0:
        raise ValueError("no frame angle turns DC by half a turn between the design positions")
    # of the solutions, the one with the frame line nearest +x (the paper's small alpha)
    from scipy.optimize import brentq

    roots = [brentq(dc_turn, grid[i], grid[i + 1], xtol=1e-12) for i in k]
    alpha = min(roots, key=abs)
    p = machine.parameters({"D.x": ad * math.cos(alpha), "D.y": ad * math.sin(alpha)},
                           base=base)
    dc1 = float(kinematics(machine, np.radians([phi1_deg]), params=p, points=[], links=["DC"],
                           variables=[]).link("DC").theta[0])
    beta = (dc1 - math.pi / 2.0 + math.pi) % (2.0 * math.pi) - math.pi  # DE1 up, clockwise
    return Design(ab, bc, cd, ad, de, ef, math.degrees(alpha), math.degrees(beta))


def thread_drawn(machine: Machine, alpha_deg: ArrayLike, beta_deg: ArrayLike, *,
                 n_points: int = 12, params=None, refine: int = 4) -> tuple[np.ndarray,
                                                                           np.ndarray]:
    """L(phi) = l_max - l(phi) (mm) at ``n_points`` equally spaced angles from phi = 0, for a
    batch of (alpha, beta) pairs (degrees, broadcast).

    One kinematics pass on a grid ``refine`` times finer than the requested one (at least 1440
    steps per turn) gives both L at the requested angles and l_max, the eye at its top, refined
    by the parabola through the three best samples (error about 1e-7 mm at 0.25 deg steps).
    Returns (phi_deg (n_points,), L batch + (n_points,)); NaN for pairs that do not assemble.
    """
    P = overrides(machine, alpha_deg, beta_deg, params)
    sub = max(int(refine), math.ceil(1440 / n_points)) if refine > 1 else 1
    fine = n_points * sub
    grid = np.arange(fine) * (2.0 * math.pi / fine)
    lf = thread_path(machine, grid, params=P, on_failure="mask").total
    k = np.argmax(np.where(np.isfinite(lf), lf, -np.inf), axis=-1)
    y0 = np.take_along_axis(lf, ((k - 1) % fine)[..., None], -1)[..., 0]
    y1 = np.take_along_axis(lf, k[..., None], -1)[..., 0]
    y2 = np.take_along_axis(lf, ((k + 1) % fine)[..., None], -1)[..., 0]
    den = y0 - 2.0 * y1 + y2
    l_max = y1 - 0.125 * (y0 - y2) ** 2 / np.where(den != 0.0, den, -np.inf)
    return np.arange(n_points) * (360.0 / n_points), l_max[..., None] - lf[..., ::sub]


def paper_table(machine: Machine, pairs=PAPER_PAIRS):
    """The paper's table: L (mm) at its 12 positions (every 30 deg from phi = 0) for each
    (beta, alpha) pair, one column per pair."""
    import pandas as pd

    b = np.array([p[0] for p in pairs])
    a = np.array([p[1] for p in pairs])
    phi, L = thread_drawn(machine, a, b, n_points=12)
    df = pd.DataFrame({"phi_deg": phi})
    for (bb, aa), row in zip(pairs, L, strict=True):
        df[f"beta={bb:g}, alpha={aa:g}"] = row
    return df


def read_diagram(path) -> tuple[np.ndarray, np.ndarray]:
    """A base machine's thread (feed-and-take) diagram from CSV: columns ``phi_deg`` and
    ``L_mm`` (header names required), any angles in [0, 360)."""
    import pandas as pd

    df = pd.read_csv(path)
    missing = {"phi_deg", "L_mm"} - set(df.columns)
    if missing:
        raise ValueError(f"{path}: the diagram needs columns phi_deg and L_mm (missing:"
                         f" {', '.join(sorted(missing))})")
    if df[["phi_deg", "L_mm"]].isna().any().any():
        raise ValueError(f"{path}: empty or non-numeric values in phi_deg or L_mm")
    return df["phi_deg"].to_numpy(float) % 360.0, df["L_mm"].to_numpy(float)


def deviation(machine: Machine, base_phi_deg: ArrayLike, base_L: ArrayLike,
              pairs=PAPER_PAIRS):
    """Deviation of each (beta, alpha) pair's L(phi) from a base machine's diagram at the
    diagram's angles: max |dL| and RMS (mm), sorted best first (the paper picks the smallest)."""
    import pandas as pd

    phi = np.asarray(base_phi_deg, dtype=float)
    ref = np.asarray(base_L, dtype=float)
    rows = []
    grid, Lf = thread_drawn(machine, [p[1] for p in pairs], [p[0] for p in pairs],
                            n_points=1440, refine=1)
    for (b, a), row in zip(pairs, Lf, strict=True):
        d = np.interp(phi, grid, row, period=360.0) - ref
        rows.append({"beta_deg": b, "alpha_deg": a, "max_abs_dev_mm": float(np.abs(d).max()),
                     "rms_dev_mm": float(np.sqrt(np.mean(d * d)))})
    return pd.DataFrame(rows).sort_values("max_abs_dev_mm", ignore_index=True)


def colour_changer(machine: Machine, engaged: int, *, n_sliders: int = 5, pitch_mm: float = 12.0,
                   phi_deg: ArrayLike = np.arange(0.0, 360.0, 5.0), park_y: float | None = None):
    """The colour changer: eye sliders G1..Gn side by side on the needle holder, ``pitch_mm``
    apart along X. Shifting the holder by one pitch per colour puts slider ``engaged`` (1..n) on
    the line of F, whose bracket then carries it; the others rest at ``park_y`` (default: the
    eye's top, where a slider is engaged and released).

    Returns (phi_deg, paths (n_sliders, n_phi, 2)): each slider's eye in the machine frame.
    """
    if not 1 <= engaged <= n_sliders:
        raise ValueError(f"engaged slider must be 1..{n_sliders}, got {engaged}")
    phi = np.asarray(phi_deg, dtype=float)
    q = kinematics(machine, np.radians(phi), points=["Q"], links=[], variables=[]).point("Q").p
    top = q[:, 1].max() if park_y is None else park_y
    paths = np.empty((n_sliders, phi.size, 2))
    for i in range(1, n_sliders + 1):
        paths[i - 1, :, 0] = q[:, 0] + (i - engaged) * pitch_mm
        paths[i - 1, :, 1] = q[:, 1] if i == engaged else top
    return phi, paths
