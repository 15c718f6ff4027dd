"""Exact derivatives of the needle-thread balance's figures by every design parameter.

The balance (:func:`sewmech.sewing.thread.thread_balance`) is read on its grid of shaft angles:
the overfeed at a grid angle k is

    overfeed(k) = supply(k) - (raw(k) - raw(k_top)),   supply(k) = L_tu(k_max) - L_tu(k),
    raw(k) = below(k) + penetration(k) + loop(k),      loop(k) = 2 (legs(k) - legs(k_s))

(while the loop is drawn), every term a thread length through moving guides. The length of a
taut thread is stationary in where it touches its pins, so it moves with a guide's centre by
the unit vector of the segment arriving there minus that of the segment leaving
(:func:`sewmech.sewing.thread.path_length_gradient`); the guides' motion by the design is the
position sensitivities at those grid angles (:func:`sewmech.engine.sensitivity.sensitivities`,
only the thread's points). The grid indices of the balance's events (the take-up's top, the
longest take-up section, seizure, the needle's bottom, cast-off, the least overfeed) stay where
they are for a small change of the design, so the figures move as the values at those indices
do; the needle's entry into the fabric is an event between grid angles and moves by
-(dy/dp) / (dy/dphi), the overfeed there being read by linear interpolation as the balance
reads it. These are the derivatives of the balance as computed (on its 0.5 deg grid): a change
that moves an event to another grid angle changes the figure by a step no derivative shows.

Units: mm per parameter unit (mm, rad, 1).
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.machine import Machine
from ..engine.sensitivity import sensitivities
from . import timing as T
from .gradients import Gradient
from .thread import _balance, _thread_spec, guide_radii, path_length, path_length_gradient

#: the balance's figures with exact derivatives: metric name -> ThreadBalance property
THREAD_FIGURES = {"thread_min_overfeed": "min_overfeed_while_loop_grows",
                  "thread_overfeed_at_needle_entry": "overfeed_at_needle_entry",
                  "thread_reserve": "reserve_after_cast_off"}


def thread_gradient(machine: Machine, name: str, *, params=None, stitch_mm: float = 2.5,
                    fabric_mm: float | None = None, step_deg: float = 0.5) -> Gradient:
    """The balance's figure ``name`` (a key of :data:`THREAD_FIGURES`), mm, and its exact
    derivative by every parameter (mm per parameter unit)."""
    if name not in THREAD_FIGURES:
        raise KeyError(f"unknown thread figure {name!r}; figures: {', '.join(THREAD_FIGURES)}")
    P = np.asarray(machine.defaults if params is None else params, dtype=float)
    b, x = _balance(machine, stitch_mm, fabric_mm, step_deg, P)
    n, h = len(b.phi_deg), x["h"]
    if name == "thread_min_overfeed":
        a, e = b.seizure_deg, b.loop_max_deg
        inside = np.nonzero((b.phi_deg - a) % 360.0 <= (e - a) % 360.0)[0]
        ks, ws = [int(inside[np.argmin(b.overfeed[inside])])], [1.0]
    elif name == "thread_reserve":
        ks, ws = [int(x["k_c"])], [1.0]
    else:
        f = x["entry"] / h
        k0 = math.floor(f) % n
        w = f - math.floor(f)
        ks, ws = [k0, (k0 + 1) % n], [1.0 - w, w]
    value = float(getattr(b, THREAD_FIGURES[name]))
    grid = sorted({*ks, x["k_top"], x["k_max"], x["k_s"], x["k_bdc"]})
    d_of = _overfeed_derivatives(machine, b, x, P, grid)
    d = sum(wk * d_of[k] for k, wk in zip(ks, ws))
    events = {"grid": [float(b.phi_deg[k]) for k in ks]}
    if name == "thread_overfeed_at_needle_entry":  # the entry angle moves with the design
        s = T.roles(machine)
        S = sensitivities(machine, np.array([x["entry"]]), params=P,
                          outputs=[f"p_{s.needle_point}_y"])
        _, dy, _ = S.channel(f"p_{s.needle_point}_y")
        w_shaft = float(S.kin.omega_shaft[..., 0])
        slope_y = float(S.kin.point(s.needle_point).v[..., 0, 1]) / w_shaft  # dy/dphi
        dphi = -dy[0] / slope_y
        k0, k1 = ks
        d = d + (b.overfeed[k1] - b.overfeed[k0]) / h * dphi
        events["needle_entry"] = math.degrees(x["entry"])
    return Gradient(name, value, "mm", machine.parameter_names, d, events)


def _overfeed_derivatives(machine: Machine, b, x: dict, P: np.ndarray, grid: list[int]
                          ) -> dict[int, np.ndarray]:
    """d overfeed(k) / d parameters (n_params,) at the grid indices ``grid`` (which hold the
    balance's own event indices)."""
    t = _thread_spec(machine)
    s = T.roles(machine)
    rho = guide_radii(machine)
    i0, i1 = t.take_up
    guides = [g.point for g in t.guides]
    sp, axis = x["shuttle_point"], x["axis"]
    points = list(dict.fromkeys(guides + [s.needle_point, s.needle_eye, sp, axis]))
    phi = np.radians(b.phi_deg[grid])
    S = sensitivities(machine, phi, params=P, outputs=[f"p_{q}_y" for q in points])
    pos = {q: S.kin.point(q).p for q in points}  # (n_grid, 2)
    dpos = {q: S.point(q) for q in points}  # (n_grid, 2, n_params)
    row = {k: j for j, k in enumerate(grid)}
    C = np.stack([pos[g] for g in guides], axis=1)  # (n_grid, n_guides, 2)
    dC = np.stack([dpos[g] for g in guides], axis=1)  # (n_grid, n_guides, 2, n_params)

    def d_section(k, lo, hi):  # d(length of guides lo..hi) at grid index k
        j = row[k]
        g = path_length_gradient(C[j, lo:hi + 1], rho[lo:hi + 1])
        return np.einsum("gc,gcp->p", g, dC[j, lo:hi + 1])

    needle_x_bdc = dpos[s.needle_point][row[x["k_bdc"]], 0]  # the needle line moves with it
    hole = x["hole"]

    def d_legs(k):  # the loop's legs: hole -> round the bobbin case -> shuttle point
        j = row[k]
        A, Cc, B = hole, pos[axis][j], pos[sp][j]
        dA = np.stack([needle_x_bdc, np.zeros_like(needle_x_bdc)])
        dCc, dB = dpos[axis][j], dpos[sp][j]
        R = t.bobbin_case_radius
        ab = B - A
        f = float(np.clip((Cc - A) @ ab / (ab @ ab), 0.0, 1.0))
        if np.linalg.norm(A + f * ab - Cc) >= R:  # straight past the case (as the balance)
            return ab / np.linalg.norm(ab) @ (dB - dA)
        pts = np.stack([A, Cc, B])
        side = min((0.0, R, 0.0), (0.0, -R, 0.0),
                   key=lambda r3: float(path_length(pts, np.array(r3))))
        g = path_length_gradient(pts, np.array(side))
        return g[0] @ dA + g[1] @ dCc + g[2] @ dB

    def d_raw(k):
        j = row[k]
        out = d_section(k, i1, len(guides) - 1)  # below the take-up section, to the eye
        if b.penetration[k] > 0.0:
            out = out - dpos[s.needle_eye][j, 1]
        if x["drawing"][k]:
            out = out + 2.0 * (d_legs(k) - d_legs(x["k_s"]))
        return out

    d_top = d_raw(x["k_top"])
    d_tu_max = d_section(x["k_max"], i0, i1)
    return {k: (d_tu_max - d_section(k, i0, i1)) - (d_raw(k) - d_top) for k in grid}
