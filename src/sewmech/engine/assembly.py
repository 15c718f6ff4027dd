"""Assembly over the whole turn, proved rather than sampled.

Evaluating a machine on a grid of shaft angles shows that it assembles *at* those angles; a
machine can still fail between two of them (a coupler that just cannot reach for half a
degree). :func:`prove_assembly` closes that gap:

- Every closed-form unit has an assembly margin, a smooth function of the shaft angle that is
  positive exactly where the unit assembles (mm): for an RRR dyad l1 + l2 - |P1P2| and
  |P1P2| - |l1 - l2|; for an RRP slider l -+ the pin's distance from the guide line; for an
  RPR guide |AB| - |e|. Its derivative in phi is the kinematics' own rate at omega = 1 rad/s.
  Every minimum of a margin between two grid points is bracketed by the sign change of that
  derivative and located by Brent's method on the exact kinematics, so the smallest margin
  over the whole turn is known to 1e-12 rad of shaft angle, not just at the grid points.
- Loop units are continued at fine steps (0.25 deg) and every step is held against the exact
  rates: a continuous solution moves by at most h (max|q'| + 2 h max|q''|) in a step of h; a
  solution that jumps to another assembly branch between two steps moves by far more and is
  caught.

Where a margin falls below zero the angle range of the failure is located (Brent's method on
the margin) and named with its unit. Units: mm, rad inside; degrees in the report.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import _kernels as K
from .kinematics import check_design, kinematics
from .machine import Machine
from .margins import conditions
from .results import mask_runs

#: the largest step of the loop units' continuation check, deg
LOOP_STEP_DEG = 0.25
#: allowance (mm or rad) on top of the rate bound before a loop unknown is said to have jumped
#: to another branch between two continuation steps
JUMP_TOL = 1e-6


@dataclass(frozen=True)
class Margin:
    """The smallest assembly margin of one condition of a unit over the turn.

    Attributes
    ----------
    unit : str
    condition : str
        What the margin measures, e.g. "l1 + l2 - |B D|".
    value_mm : float
        Its smallest value over the turn, mm (negative: the unit fails there).
    phi_deg : float
        Where, deg.
    """

    unit: str
    condition: str
    value_mm: float
    phi_deg: float


@dataclass(frozen=True)
class AssemblyFailure:
    """A range of shaft angles over which a unit cannot be assembled (or jumps branch)."""

    unit: str
    from_deg: float
    to_deg: float
    reason: str


@dataclass(frozen=True)
class AssemblyProof:
    """Result of :func:`prove_assembly` for one design.

    ``margins`` holds the smallest margin of every condition of every closed-form unit;
    ``failures`` is empty when the machine assembles over the whole turn; ``loop_steps`` is
    the number of continuation steps at which the loop units were checked (0 without loops).
    ``turns`` is how many shaft turns were covered: the machine's period (2 with a crank at
    ratio 1/2); ``periodic`` is False for a machine that does not repeat within 100 turns (then
    one turn is covered).
    """

    grid_deg: float
    margins: tuple[Margin, ...]
    failures: tuple[AssemblyFailure, ...]
    loop_steps: int = 0
    loop_units: tuple[str, ...] = field(default=())
    turns: int = 1
    periodic: bool = True

    @property
    def ok(self) -> bool:
        return not self.failures

    @property
    def smallest(self) -> Margin | None:
        return min(self.margins, key=lambda m: m.value_mm, default=None)


class _UpstreamFails(Exception):
    pass


def prove_assembly(machine: Machine, *, params=None, inputs=None,
                   step_deg: float = 1.0) -> AssemblyProof:
    """Whether one design assembles at every shaft angle of the turn (see the module text).

    Parameters
    ----------
    machine : Machine
    params, inputs
        One design, as for :func:`sewmech.kinematics` (default: the file's).
    step_deg : float
        Grid of the bracketing scan, deg; every minimum of a margin between grid points is
        located exactly. Two minima of one margin within one step could merge (a margin
        that wiggles within a degree), which no machine part does.

    Returns
    -------
    AssemblyProof
    """
    from scipy.optimize import brentq  # (here, not at the top: a third of a second to import)

    turns = machine.period_turns or 1  # a crank at ratio 1/2 repeats after two turns
    h = 2.0 * math.pi / int(round(360.0 / step_deg))
    n = int(round(360.0 / step_deg)) * turns
    grid = np.arange(n) * h
    kw = dict(params=params, inputs=inputs, omega=1.0, epsilon=0.0, on_failure="mask")
    P = machine.parameters(inputs=inputs, base=params) if params is not None or inputs else \
        machine.defaults
    check_design(machine, P)
    res = kinematics(machine, grid, **kw)
    failures: list[AssemblyFailure] = []
    names = machine.unit_names
    if not res.all_feasible:  # failures at grid points: ranges of consecutive grid angles
        for ui in np.unique(res.failure_unit[~res.feasible]):
            mask = ~res.feasible & (res.failure_unit == ui)
            for a, b in mask_runs(mask):
                failures.append(AssemblyFailure(names[ui] if ui >= 0 else "?",
                                                math.degrees(grid[a]), math.degrees(grid[b]),
                                                "it cannot be assembled at these grid angles"))
        return AssemblyProof(step_deg, (), tuple(failures), turns=turns,
                             periodic=machine.period_turns is not None)

    margins = []
    for c in conditions(machine, P):
        m, dm = c.fn(res)
        k = int(np.argmin(m))
        best, best_phi = float(m[k]), float(grid[k])
        ui, label = c.unit, c.label
        for i in range(n):
            j = (i + 1) % n
            if not (dm[i] < 0.0 < dm[j]):
                continue
            x0, x1 = grid[i], grid[i] + h

            def exact(x, c=c):  # only the units the margin reads are solved
                r = kinematics(machine, np.array([x]), points=c.points, links=c.links,
                               variables=(), **kw)
                if not r.all_feasible:
                    raise _UpstreamFails
                return c.fn(r)

            def slope(x, exact=exact):
                return float(exact(x)[1][0])

            def value(x, exact=exact):
                return float(exact(x)[0][0])

            try:
                if not (slope(x0) < 0.0 < slope(x1)):  # a minimum at a grid point itself
                    continue
                xm = brentq(slope, x0, x1, xtol=1e-12)
                vm = value(xm)
                if vm < 0.0:  # the unit fails between two grid points: locate the range
                    a = brentq(value, x0, xm, xtol=1e-12)
                    b = brentq(value, xm, x1, xtol=1e-12)
            except _UpstreamFails:  # an earlier unit fails here: its own margin says where
                continue
            if vm < best:
                best, best_phi = vm, xm
            if vm < 0.0:
                failures.append(AssemblyFailure(
                    names[ui], math.degrees(a), math.degrees(b),
                    f"between the grid points, {label} falls to {vm:.3g} mm at phi ="
                    f" {math.degrees(xm):.6g} deg"))
        margins.append(Margin(names[ui], label, best, math.degrees(best_phi) % 360.0))
    loops = tuple(names[u] for u, t in enumerate(machine.unit_types) if t == "loop")
    steps = 0
    if loops:
        steps, jumps = _loop_continuity(machine, kw)
        failures += jumps
    return AssemblyProof(step_deg, tuple(margins), tuple(failures), steps, loops, turns,
                         machine.period_turns is not None)


def _loop_continuity(machine: Machine, kw: dict) -> tuple[int, list[AssemblyFailure]]:
    """Continue the loop units at LOOP_STEP_DEG and hold every step against the exact rates: a
    move beyond what they allow is a jump to another branch."""
    n = int(round(360.0 / LOOP_STEP_DEG))
    h = 2.0 * math.pi / n
    phi = machine.assembly_phi + np.arange(n + 1) * h
    res = kinematics(machine, phi, **{**kw, "on_failure": "mask"}, max_step_deg=LOOP_STEP_DEG)
    failures = []
    if not res.all_feasible:
        for ui in np.unique(res.failure_unit[~res.feasible]):
            mask = ~res.feasible & (res.failure_unit == ui)
            for a, b in mask_runs(mask):
                failures.append(AssemblyFailure(
                    machine.unit_names[ui] if ui >= 0 else "?",
                    math.degrees(phi[a]) % 360.0, math.degrees(phi[b]) % 360.0,
                    f"it cannot be assembled (continued at {LOOP_STEP_DEG:g} deg steps)"))
        return n, failures
    for g, (count, u0, *_rest) in enumerate(machine.groups):
        unit = machine.unit_names[next(u for u, r in zip(machine.kernel_unit_of_row,
                                                        machine.program)
                                       if r[0] == K.OP_LOOP and r[1] == g)]
        for j in range(u0, u0 + count):
            kind, idx = int(machine.unknowns[j, 0]), int(machine.unknowns[j, 1])
            if kind == 0:
                q, dq, ddq = (np.unwrap(res.theta[:, idx]), res.omega[:, idx],
                              res.epsilon[:, idx])
            else:
                q, dq, ddq = res.q[:, idx], res.q_dot[:, idx], res.q_ddot[:, idx]
            # a continuous solution moves by at most h sup|q'| in a step, and sup|q'| over
            # the step is at most the larger end rate plus h sup|q''| (the rates may have
            # kinks where a cam contact passes an arc joint); a jump to another branch moves
            # by far more
            rate = np.maximum(np.abs(dq[1:]), np.abs(dq[:-1]))
            curv = np.maximum(np.abs(ddq[1:]), np.abs(ddq[:-1]))
            miss = np.abs(q[1:] - q[:-1])
            bound = h * rate + 2.0 * h * h * curv + JUMP_TOL
            for a, b in mask_runs(miss > bound):
                failures.append(AssemblyFailure(
                    unit, math.degrees(phi[a]) % 360.0, math.degrees(phi[b + 1]) % 360.0,
                    f"the solution jumps to another branch (it moves by"
                    f" {miss[a:b + 1].max():.3g} in a {LOOP_STEP_DEG:g} deg step, more than its"
                    " rates allow): the loop passes a toggle or its assembly is ambiguous"
                    " here"))
    return n, failures
