"""One setting of a machine, evaluated once and read by every event, extreme and check.

A design (its parameters, setting inputs included) is evaluated on a fine grid of shaft angles
at omega = 1 rad/s, where every rate is a derivative in phi (velocity = dp/dphi, acceleration
= d2p/dphi2). Extremes and crossings of any channel are bracketed on that grid and refined on
the exact kinematics by Newton's method inside the bracket (the channel's next derivative comes
with each evaluation, so two or three evaluations reach 1e-12 rad), falling back to bisection
whenever a Newton step would leave the bracket.

An exact evaluation between grid points (:meth:`Evaluation.at`) continues the loop units from
the grid's solution just below the angle, one step, instead of from the assembly angle: the
continuation follows the same branch and costs one Newton step per loop.

:func:`evaluation` keeps the last few evaluations of each machine, so that the timing, the feed
and the report, asking for the same setting one after the other, share one. Units: mm, rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ._kernels import OP_CRANK, OP_LOOP
from .kinematics import KinematicsPlan, kinematics
from .machine import Machine
from .results import CHANNEL_KINDS, KinematicsResult

#: shaft angles of the shared grid per turn (0.5 deg)
N_GRID = 720
#: evaluations kept per machine (one per setting: a report reads a handful)
KEEP = 16


def newton_in_bracket(fn, a: float, b: float, fa: float, fb: float, xtol: float,
                      max_iter: int = 80) -> float:
    """The root of ``fn`` (x -> (f, f')) in [a, b] where f changes sign (``fa``, ``fb`` its
    values at the ends): Newton's method from the chord's root, kept inside the bracket (a
    bisection step wherever Newton would leave it), to ``xtol`` in x."""
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    x = a - fa * (b - a) / (fb - fa)  # the chord's root
    for _ in range(max_iter):
        f, df = fn(x)
        if f == 0.0:
            return x
        if (f < 0.0) == (fa < 0.0):
            a, fa = x, f
        else:
            b = x
        nxt = x - f / df if df and math.isfinite(df) else math.inf
        if not a <= nxt <= b:  # (a root on the bracket's end is taken as it is)
            nxt = 0.5 * (a + b)
        if abs(nxt - x) <= xtol or b - a <= xtol:
            return nxt
        x = nxt
    return x


@dataclass(frozen=True)
class Root:
    """A located event: shaft angle (rad) and the sign of the channel's slope there."""

    phi: float
    direction: int


class Evaluation:
    """The motion of one design of a machine over a turn, shared by its readers.

    Attributes
    ----------
    machine : Machine
    params : ndarray, shape (n_parameters,)
        The design, internal units (mm, rad), setting inputs included.
    grid : KinematicsResult
        Every point, link and joint variable at ``N_GRID`` angles from 0 at omega = 1 rad/s
        (one compiled call, on first use).
    """

    def __init__(self, machine: Machine, params: np.ndarray, n_grid: int = N_GRID):
        self.machine = machine
        self.params = np.array(params, dtype=float)
        self.params.setflags(write=False)
        self.n_grid = int(n_grid)
        self.h = 2.0 * math.pi / self.n_grid
        self.phi = np.arange(self.n_grid) * self.h

    @cached_property
    def grid(self) -> KinematicsResult:
        return kinematics(self.machine, self.phi, params=self.params, omega=1.0)

    @cached_property
    def _inits(self) -> tuple[np.ndarray, np.ndarray]:
        """Parameter index of each loop unknown's initial value, and its value at every grid
        angle (n_grid, n_unknowns): the known solutions to continue from."""
        m = self.machine
        if not m.has_loops:
            return np.empty(0, dtype=np.int64), np.empty((self.n_grid, 0))
        g = self.grid
        cols = []
        for kind, idx, _, _ in m.unknowns:
            cols.append(g.theta[:, idx] if kind == 0 else g.q[:, idx])
        return m.unknowns[:, 3].astype(np.int64), np.stack(cols, axis=1)

    @cached_property
    def init_params(self) -> np.ndarray:
        """Parameter index of each loop unknown's initial value (the columns :meth:`at_angles`
        sets from its guess)."""
        return self.machine.unknowns[:, 3].astype(np.int64)

    @cached_property
    def _init_rates(self) -> tuple[np.ndarray, np.ndarray]:
        """The loop unknowns' first and second derivatives by the shaft angle at every grid
        angle, (n_grid, n_unknowns) each (the grid is at omega = 1 rad/s)."""
        m = self.machine
        if not m.has_loops:
            return np.empty((self.n_grid, 0)), np.empty((self.n_grid, 0))
        g = self.grid
        d1 = [g.omega[:, i] if kind == 0 else g.q_dot[:, i] for kind, i, _, _ in m.unknowns]
        d2 = [g.epsilon[:, i] if kind == 0 else g.q_ddot[:, i] for kind, i, _, _ in m.unknowns]
        return np.stack(d1, axis=1), np.stack(d2, axis=1)

    def unknown_selection(self, points: list[str]) -> dict:
        """The links and joint variables that are unknowns of the loop units the ``points``
        depend on, as a selection for :meth:`at_angles` (with :meth:`unknowns_of` reading them
        back)."""
        m = self.machine
        rows = m.selection(points, [], [])[-1]
        links, variables = set(), set()
        for row in m.program[rows]:
            if row[0] != OP_LOOP:
                continue
            n, u0 = int(m.groups[row[1], 0]), int(m.groups[row[1], 1])
            for kind, i, _, _ in m.unknowns[u0:u0 + n]:
                (links if kind == 0 else variables).add(
                    (m.link_names if kind == 0 else m.variable_names)[i])
        return {"points": list(points), "links": sorted(links), "variables": sorted(variables)}

    def unknowns_of(self, r: KinematicsResult, step: np.ndarray) -> np.ndarray:
        """The loop unknowns of the designs of ``r`` (an :meth:`at_angles` result that
        selected :meth:`unknown_selection`) carried ``step`` (m,) (rad) further along their
        second-order Taylor polynomial: initial values for the next :meth:`at_angles`,
        (m, n_unknowns; 0 for the unknowns of loops ``r`` did not solve)."""
        cols = []
        for kind, i, _, _ in self.machine.unknowns:
            name = (self.machine.link_names if kind == 0 else self.machine.variable_names)[i]
            if name not in (r.link_names if kind == 0 else r.variable_names):
                cols.append(np.zeros(step.size))
                continue
            if kind == 0:
                j = r.link_names.index(self.machine.link_names[i])
                q, q1, q2 = r.theta[:, 0, j], r.omega[:, 0, j], r.epsilon[:, 0, j]
            else:
                j = r.variable_names.index(self.machine.variable_names[i])
                q, q1, q2 = r.q[:, 0, j], r.q_dot[:, 0, j], r.q_ddot[:, 0, j]
            cols.append(q + step * (q1 + 0.5 * step * q2))
        return np.stack(cols, axis=1) if cols else np.empty((step.size, 0))

    def at(self, phi, **selection) -> KinematicsResult:
        """The exact motion at shaft angles ``phi`` (rad, any), at omega = 1 rad/s: one compiled
        call; loop units continue from the grid solution at the grid angle just below the first
        angle. ``selection``: ``points``, ``links``, ``variables`` as for kinematics()."""
        phi = np.array(phi, dtype=float, ndmin=1)
        P = self.params
        start = None
        if self.machine.has_loops and phi.size:
            k = self._below(phi[0])
            idx, values = self._inits
            P = self.params.copy()
            P[idx] = values[k]
            start = float(self.phi[k])
        plan = KinematicsPlan(self.machine, phi, omega=1.0, start_phi=start,
                              max_step_deg=math.degrees(self.h), **selection)
        return plan(P)

    def _below(self, phi: float) -> int:
        """The grid angle at or just below ``phi`` (rad, any), as its index (a grid angle
        itself, up to round-off, is its own)."""
        return int(np.floor(float(np.mod(phi, 2.0 * math.pi)) / self.h + 1e-9)) % self.n_grid

    @cached_property
    def _shaft_cranks(self) -> tuple[np.ndarray, np.ndarray]:
        """Parameter indices of the phase and the speed ratio of every crank the shaft turns
        (not the setting links, whose angle is an input)."""
        u = self.machine.program
        shaft = (u[:, 0] == OP_CRANK) & (u[:, 4] < 0)
        return u[shaft, 2].astype(np.int64), u[shaft, 3].astype(np.int64)

    def at_angles(self, params, phi, *, guess: np.ndarray | None = None,
                  overwrite: bool = False, **selection) -> KinematicsResult:
        """A batch of designs ``params`` (m, n_parameters) close to this one, each at its own
        shaft angle ``phi`` (m,) (rad), at omega = 1 rad/s, in one compiled call (the result
        has one angle, 0).

        The shaft angle enters the motion only through the cranks it turns (theta = phase +
        ratio phi), so a design at phi_d is the design with every such crank's phase advanced
        by ratio phi_d, at angle 0. Each design's loop units are assembled by Newton's method
        from ``guess`` (m, n_unknowns; e.g. :meth:`unknowns_of` an earlier result) or from
        this design's solution carried from the grid angle nearest phi_d along its Taylor
        polynomial. A design that does not assemble reads as infeasible. ``overwrite``: ``params`` is the caller's float array
        and may take the changed phases and initial values itself (the caller restores them).
        ``selection``: ``points``, ``links``, ``variables``."""
        P = params if overwrite else np.array(params, dtype=float)
        phi = np.asarray(phi, dtype=float)
        if P.ndim != 2 or phi.shape != P.shape[:1]:
            raise ValueError("at_angles(): params (m, n_parameters) and phi (m,)")
        phase, ratio = self._shaft_cranks
        for j, r in zip(phase, ratio):
            P[:, j] += P[:, r] * phi
        if self.machine.has_loops:
            idx = self.init_params
            if guess is None:  # (the grid is computed only here)
                values = self._inits[1]
                x = np.mod(phi, 2.0 * math.pi) / self.h
                k = np.rint(x).astype(np.int64)
                d = ((x - k) * self.h)[:, None]
                k %= self.n_grid
                d1, d2 = self._init_rates
                guess = values[k] + d * (d1[k] + 0.5 * d * d2[k])
            P[:, idx] = guess
        key = tuple((k, tuple(v) if isinstance(v, (list, tuple)) else v)
                    for k, v in sorted(selection.items()))
        plan = self._at_plans.get(key)
        if plan is None:  # (prepared once per selection: a locator calls this many times)
            plan = self._at_plans[key] = KinematicsPlan(
                self.machine, [0.0], omega=1.0, start_phi=0.0, on_failure="mask", **selection)
        return plan.run(plan.designs(P), fresh=True)

    @cached_property
    def _at_plans(self) -> dict:
        return {}

    # ---- events ------------------------------------------------------------------------------
    @cached_property
    def _roots(self) -> dict:
        return {}

    @cached_property
    def memo(self) -> dict:
        """What the analyses built on this design keep of it (extremes, curves), by key."""
        return {}

    def roots(self, channel: str, level: float = 0.0, *, phi0: float = 0.0,
              xtol: float = 1e-12) -> list[Root]:
        """Where ``channel`` equals ``level`` (its unit), in [phi0, phi0 + 2 pi): bracketed on
        the grid, refined on the exact kinematics (each once: asked again, the same list)."""
        key = (channel, float(level), float(xtol))
        found = self._roots.get(key)
        if found is None:
            found = self._roots[key] = self._locate(channel, float(level), xtol)
        return sorted((Root(float(phi0 + np.mod(r.phi - phi0, 2.0 * math.pi)), r.direction)
                       for r in found), key=lambda r: r.phi)

    def _locate(self, channel: str, level: float, xtol: float) -> list[Root]:
        g, unit = self.grid.channel(channel)
        kind, _, rest = channel.partition("_")
        deriv = CHANNEL_KINDS[kind][2]
        slope = self.grid.channel(f"{deriv}_{rest}")[0] if deriv else None
        f = g - level
        n = self.n_grid
        out = []
        for i in np.flatnonzero((f == 0.0) | (f * np.roll(f, -1) < 0.0)):
            j = (i + 1) % n
            a = float(self.phi[i])
            b = a + self.h
            if f[i] == 0.0:
                x = a
            elif slope is None:
                from scipy.optimize import brentq

                x = brentq(lambda t: float(self.at([t]).channel(channel)[0][0]) - level, a, b,
                           xtol=xtol)
            else:
                def fn(t, ch=channel, dch=f"{deriv}_{rest}"):
                    r = self.at([t])
                    return float(r.channel(ch)[0][0]) - level, float(r.channel(dch)[0][0])

                x = newton_in_bracket(fn, a, b, float(f[i]), float(f[j]), xtol, 60)
            out.append(Root(float(x), 1 if f[j] > f[i] else -1))
        return out


def evaluation(machine: Machine, params=None, inputs=None, n_grid: int = N_GRID) -> Evaluation:
    """The :class:`Evaluation` of one design (``params``: one parameter vector, default the
    file's; ``inputs``: setting inputs, rad), shared: asking again for the same design returns
    the same evaluation (the last ``KEEP`` designs of each machine are kept)."""
    if params is not None and np.ndim(params) != 1:
        raise ValueError("an evaluation is of one design: params must have shape"
                         f" (n_parameters,), got {np.shape(params)}")
    P = machine.parameters(inputs=inputs, base=params) if (params is not None or inputs) \
        else machine.defaults
    cache = machine._evaluations
    key = (np.asarray(P, dtype=float).tobytes(), int(n_grid))
    ev = cache.pop(key, None)
    if ev is None:
        ev = Evaluation(machine, P, n_grid)
        while len(cache) >= KEEP:
            cache.pop(next(iter(cache)))
    cache[key] = ev  # the newest last
    return ev
