"""Assembly margins of the closed-form units: how far each is from failing to assemble.

Every closed-form unit assembles exactly where a smooth function of the shaft angle, its
margin (mm), is not negative: for an RRR dyad l1 + l2 - |P1P2| and |P1P2| - |l1 - l2|; for an
RRP slider l -+ the pin's distance from the guide line; for an RPR guide |AB| - |e|. Each
:class:`Condition` computes its margin and the margin's derivative in phi from a kinematics
result at omega = 1 rad/s (where rates are derivatives in phi), reading only the points and
links it names, so that it can be evaluated where the unit itself fails.
:mod:`sewmech.engine.assembly` brackets their minima between grid points;
:func:`describe` turns a failure into the distance that does not fit and by how much.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _kernels as K
from .machine import Machine


@dataclass(frozen=True)
class Condition:
    unit: int  # index into unit_names
    label: str
    points: tuple[str, ...]  # what the margin reads: only the units these need are solved,
    links: tuple[str, ...]  # so the margin is known where the unit itself fails
    fn: object  # KinematicsResult at omega = 1 -> (margin mm, d margin / d phi)


def distance(res, a: str, b: str):
    """|b - a| and its rate."""
    pa, pb = res.point(a), res.point(b)
    d = pb.p - pa.p
    n = np.hypot(d[..., 0], d[..., 1])
    rate = np.einsum("...k,...k->...", d, pb.v - pa.v) / np.where(n > 0, n, np.nan)
    return n, rate


def _less(s, value_rate):
    """s - x and its rate, from (x, its rate): the quantity is computed once."""
    return s - value_rate[0], -value_rate[1]


def _more(value_rate, s):
    """x - s and its rate, from (x, its rate)."""
    return value_rate[0] - s, value_rate[1]


def conditions(machine: Machine, params: np.ndarray) -> list[Condition]:
    """Every assembly condition of the machine's closed-form units."""
    out = []
    names = machine.point_names
    for r, row in enumerate(machine.program):
        op = int(row[0])
        if op not in (K.OP_RRR, K.OP_RRP, K.OP_RPR):
            continue
        ui = machine.kernel_unit_of_row[r]
        if op == K.OP_RRR:
            a, b = names[row[1]], names[row[2]]
            s, dif = params[row[6]] + params[row[7]], abs(params[row[6]] - params[row[7]])
            out.append(Condition(ui, f"l1 + l2 - |{a} {b}|", (a, b), (),
                                  lambda res, a=a, b=b, s=s: _less(s, distance(res, a, b))))
            out.append(Condition(ui, f"|{a} {b}| - |l1 - l2|", (a, b), (),
                                  lambda res, a=a, b=b, dif=dif: _more(distance(res, a, b),
                                                                       dif)))
        elif op == K.OP_RRP:
            pin, gp, gl = names[row[1]], names[row[2]], machine.link_names[row[3]]
            length, alpha, e = params[row[7]], params[row[8]], params[row[9]]

            def offset(res, pin=pin, gp=gp, gl=gl, alpha=alpha, e=e):
                g, b, lk = res.point(gp), res.point(pin), res.link(gl)
                beta = lk.theta + alpha
                wb = lk.omega
                ux, uy = np.cos(beta), np.sin(beta)
                wx = g.p[..., 0] - e * uy - b.p[..., 0]
                wy = g.p[..., 1] + e * ux - b.p[..., 1]
                wvx = g.v[..., 0] - e * wb * ux - b.v[..., 0]
                wvy = g.v[..., 1] - e * wb * uy - b.v[..., 1]
                return wx * uy - wy * ux, wvx * uy - wvy * ux + wb * (wx * ux + wy * uy)

            links = (gl,)
            label = f"l - |distance of {pin} from the guide|"
            out.append(Condition(ui, label, (pin, gp), links, lambda res, f=offset, s=length:
                                  _less(s, f(res))))
            out.append(Condition(ui, label, (pin, gp), links, lambda res, f=offset, s=length:
                                  _more(f(res), -s)))
        else:
            pin, pivot = names[row[1]], names[row[2]]
            e = abs(params[row[5]])
            out.append(Condition(ui, f"|{pivot} {pin}| - |offset|", (pivot, pin), (),
                                  lambda res, a=pivot, b=pin, e=e: _more(distance(res, a, b),
                                                                         e)))
    return out


def describe(machine: Machine, unit: int, params: np.ndarray, evaluate) -> str:
    """Why closed-form unit ``unit`` cannot be assembled, with the distance that does not fit
    and by how much (mm); "" for other units, or when its inputs cannot be computed either.

    ``evaluate(condition)`` returns the kinematics result (omega = 1) of the points and links
    that ``condition`` names at the failing angle, or None where they fail too."""
    P = np.asarray(params, dtype=float)
    conds = [c for c in conditions(machine, P) if c.unit == unit]
    if not conds:
        return ""
    c = conds[0]
    r = evaluate(c)
    if r is None:
        return ""
    row = machine.program[[k for k, u in enumerate(machine.kernel_unit_of_row)
                           if u == unit][0]]
    if row[0] == K.OP_RRR:
        a, b = c.points
        d = float(distance(r, a, b)[0][0])
        l1, l2 = P[row[6]], P[row[7]]
        if d > l1 + l2:
            return (f"{a} and {b} are {d:.6g} mm apart, more than the links reach"
                    f" (l1 + l2 = {l1 + l2:.6g} mm): {d - l1 - l2:.3g} mm too short")
        return (f"{a} and {b} are {d:.6g} mm apart, less than the links can fold to"
                f" (|l1 - l2| = {abs(l1 - l2):.6g} mm): {abs(l1 - l2) - d:.3g} mm too close")
    if row[0] == K.OP_RRP:
        m_lo, m_hi = (float(cc.fn(r)[0][0]) for cc in conds[:2])
        length = P[row[7]]
        off = length - min(m_lo, m_hi)
        return (f"the pin {c.points[0]} is {off:.6g} mm from the guide line, farther than the"
                f" rod reaches (length {length:.6g} mm): {off - length:.3g} mm too short")
    d = float(distance(r, c.points[0], c.points[1])[0][0])
    e = abs(P[row[5]])
    return (f"{c.points[1]} is {d:.6g} mm from the pivot {c.points[0]}, less than the slot's"
            f" offset ({e:.6g} mm): {e - d:.3g} mm too close")
