"""Exact design sensitivities of positions: d(point position, link angle, joint variable) /
d(every parameter), at every shaft angle, from the solved mechanism.

Each unit of the compiled program is differentiated where it is solved, in solve order
(forward mode, every parameter direction at once): a closed-form unit's closure equations give
its outputs' tangents from its inputs' tangents and its own parameters' (for a dyad,
(C - B1) . (dC - dB1) = l1 dl1 and (C - B2) . (dC - dB2) = l2 dl2: a 2 x 2 system per angle); a
loop unit's closure F(q, known, p) = 0 gives J_q dq = -(dF/dknown dknown + dF/dp dp), with the
same terms (points, vectors of parameter or variable length, circular-arc cam contacts) as the
kernel's loop solver. The positions come from the kinematics kernel; the tangents from a second
compiled kernel (:mod:`sewmech.engine._tangents`), vectorised over designs and angles.

The tangents are sparse: a quantity depends only on its unit's parameters and, transitively,
its inputs' (its *support*, :mod:`sewmech.engine._supports`, found once per machine and output
selection). The kernel carries only those; :class:`Sensitivities` scatters one channel by every
parameter on :meth:`~Sensitivities.channel`, and the dense arrays (``dp``, ``dtheta``, ...)
only when they are read.

With ``rates=True`` the velocities, angular velocities and joint rates follow the same way: each
unit's velocity relation (for a dyad (C - B_k) . (v_C - v_k) = 0; for a loop J q_dot = -b)
differentiated with the position tangents known; then the accelerations from the acceleration
relations (for a dyad (C - B_k) . (a_C - a_k) + |v_C - v_k|^2 = 0) with both known.

Derivatives are in internal units: mm, rad, mm/s, rad/s per unit of the parameter (mm, rad, 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from . import _tangents
from ._supports import TangentLayout, tangent_layout
from ._threads import run_chunks
from .errors import AnalysisError, name_index
from .kinematics import kernel_input, kinematics
from .machine import Machine
from .results import KinematicsResult

#: the most memory the tangents of one call may take, bytes
MAX_BYTES = 2 * 2**30

#: positions below which the tangent kernel runs on one thread
_PARALLEL_MIN_POSITIONS = 4096

#: a channel's kind: (tangent level, quantity family, the result's value attribute, unit)
_KINDS = {"p": (0, "p", "p", "mm"), "v": (1, "p", "v", "mm/s"), "a": (2, "p", "a", "mm/s^2"),
          "theta": (0, "l", "theta", "rad"), "omega": (1, "l", "omega", "rad/s"),
          "epsilon": (2, "l", "epsilon", "rad/s^2"),
          "q": (0, "v", "q", ""), "qd": (1, "v", "q_dot", "/s"), "qdd": (2, "v", "q_ddot", "/s^2")}


class Sensitivities:
    """Tangents of the positions (and with ``rates`` of the velocities and accelerations) with
    respect to every parameter.

    kin : the kinematics the tangents belong to. The dense arrays are made on first access
    (a channel's gradient is cheaper through :meth:`channel`): dp : (batch, n_phi, n_points, 2,
    n_params) d(point position)/d(parameter), mm per parameter unit; dtheta : (batch, n_phi,
    n_links, n_params) rad per unit; dq : (batch, n_phi, n_variables, n_params) per unit (mm or
    rad); dv, domega, dqd, da, depsilon, dqdd : the same for the velocities (mm/s), angular
    velocities (rad/s), joint rates and their accelerations, or None without ``rates``.
    """

    def __init__(self, kin: KinematicsResult, plan: _Plan, tangents: tuple[np.ndarray, ...]):
        self.kin = kin
        self._plan = plan
        self._t = tangents  # per level (blocks, layout width, LANES): see _tangents
        self._shape = kin.p.shape[:-2]  # batch + (n_phi,)
        self._dense_cache: dict = {}

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return self._plan.parameter_names

    @property
    def rates(self) -> bool:
        return len(self._t) > 1

    def _dense(self, level: int, family: str) -> np.ndarray | None:
        """The dense tangents of one level and family, made on first access and kept."""
        if level >= len(self._t):
            return None
        key = (level, family)
        if key in self._dense_cache:
            return self._dense_cache[key]
        plan, t = self._plan, self._t[level]
        sel = plan.sel[family]
        n = int(np.prod(self._shape))
        point = family == "p"
        out = np.zeros((n, len(sel)) + ((2,) if point else ()) + (len(plan.parameter_names),))
        for c, q in enumerate(plan.quantity[family][sel]):
            off, m, sup = plan.layout.qoff[q], plan.layout.qm[q], plan.support[q]
            if point:
                out[:, c, 0, sup] = _lanes(t, off, m, n)
                out[:, c, 1, sup] = _lanes(t, off + m, m, n)
            else:
                out[:, c, sup] = _lanes(t, off, m, n)
        out = out.reshape(self._shape + out.shape[1:])
        self._dense_cache[key] = out
        return out

    @property
    def dp(self) -> np.ndarray:
        return self._dense(0, "p")

    @property
    def dtheta(self) -> np.ndarray:
        return self._dense(0, "l")

    @property
    def dq(self) -> np.ndarray:
        return self._dense(0, "v")

    @property
    def dv(self) -> np.ndarray | None:
        return self._dense(1, "p")

    @property
    def domega(self) -> np.ndarray | None:
        return self._dense(1, "l")

    @property
    def dqd(self) -> np.ndarray | None:
        return self._dense(1, "v")

    @property
    def da(self) -> np.ndarray | None:
        return self._dense(2, "p")

    @property
    def depsilon(self) -> np.ndarray | None:
        return self._dense(2, "l")

    @property
    def dqdd(self) -> np.ndarray | None:
        return self._dense(2, "v")

    def compact(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
        """A channel's values (batch + (n_phi,)), its derivatives by its support's parameters
        only (batch + (n_phi, m)), those parameters' indices (m,) and its unit: the
        derivatives by every other parameter are 0."""
        level, family, attr, unit, i, comp = self._parse(name)
        r = self.kin
        value = getattr(r, attr)
        plan = self._plan
        q = plan.quantity[family][plan.sel[family][i]]
        off, m = plan.layout.qoff[q], plan.layout.qm[q]
        if family == "p":
            value = value[..., i, comp]
            off += comp * m
        else:
            value = value[..., i]
            if family == "v":
                unit = r.variable_units[i] + unit
        d = _lanes(self._t[level], off, m, int(np.prod(self._shape))).reshape(self._shape + (m,))
        return value, d, plan.support[q], unit

    def channel(self, name: str) -> tuple[np.ndarray, np.ndarray, str]:
        """A channel (``p_POINT_x``/``_y``, ``theta_LINK``, ``q_VAR``; with ``rates``:
        ``v_POINT_x``/``_y``, ``omega_LINK``, ``qd_VAR``): its values (batch + (n_phi,)), its
        derivatives (batch + (n_phi, n_params)) and its unit."""
        value, d, sup, unit = self.compact(name)
        out = np.zeros(self._shape + (len(self._plan.parameter_names),))
        out[..., sup] = d
        return value, out, unit

    def point(self, name: str, level: int = 0) -> np.ndarray:
        """d(position) (level 0), d(velocity) (1) or d(acceleration) (2) of one point by every
        parameter: batch + (n_phi, 2, n_params) (mm, mm/s, mm/s^2 per parameter unit)."""
        kind = "pva"[level]
        return np.stack([self.channel(f"{kind}_{name}_{c}")[1] for c in "xy"], axis=-2)

    def _parse(self, name: str):
        """(level, family, value attribute, unit, index in the result, coordinate) of a
        channel name."""
        r = self.kin
        kind, _, rest = name.partition("_")
        if kind not in _KINDS:
            raise KeyError(f"'{name}' is not a channel: p_POINT_x, p_POINT_y, theta_LINK,"
                           " q_VAR, their rates v_, omega_, qd_ and accelerations a_, epsilon_,"
                           " qdd_")
        level, family, attr, unit = _KINDS[kind]
        if level and not self.rates:
            raise KeyError(f"'{name}' is a rate: ask sensitivities(..., rates=True)")
        comp = 0
        if family == "p":
            pt, _, c = rest.rpartition("_")
            if c not in ("x", "y"):
                raise KeyError(f"channel '{name}': a point channel ends in _x or _y")
            i = name_index(r.point_names, pt, "point")
            comp = "xy".index(c)
        elif family == "l":
            i = name_index(r.link_names, rest, "link")
        else:
            i = name_index(r.variable_names, rest, "joint variable")
        return level, family, attr, unit, i, comp


def _lanes(t: np.ndarray, off: int, m: int, n: int) -> np.ndarray:
    """Columns off .. off + m - 1 of a level's tangents (blocks, width, LANES) as (n, m): the
    n positions in order."""
    if m == 0:  # a constant (the frame's angle)
        return np.zeros((n, 0))
    return t[:, off:off + m, :].transpose(0, 2, 1).reshape(-1, m)[:n]


@dataclass(frozen=True)
class _Plan:
    """What a sensitivities() call with some outputs needs besides the designs and angles,
    made once per machine and output selection: the rows solved, the names the kinematics
    returns, the tangent layout and the kernel's tables."""

    names: dict  # "points"/"links"/"variables" -> names for kinematics() (None: all)
    sel: dict  # "p"/"l"/"v" -> global indices of the result's points, links, variables
    quantity: dict  # "p"/"l"/"v" -> the quantity number of every point, link, variable
    layout: TangentLayout
    support: tuple  # per quantity its parameters (index arrays)
    parameter_names: tuple
    tables: tuple  # the kernel's arguments from units to vcol


def _plan(machine: Machine, outputs) -> _Plan:
    key = None if outputs is None else tuple([outputs] if isinstance(outputs, str) else outputs)
    plans = machine._tangent_plans
    hit = plans.get(key)
    if hit is not None:
        return hit
    rows, pt_sel, lk_sel, var_sel = _outputs_of(machine, outputs)
    layout = tangent_layout(machine, rows)
    n_pt, n_l, n_v = (len(machine.point_names), len(machine.link_names),
                      len(machine.variable_names))
    cols = []
    for n, sel in ((n_pt, pt_sel), (n_l, lk_sel), (n_v, var_sel)):
        col = np.full(n, -1, dtype=np.int64)
        col[sel] = np.arange(len(sel))
        cols.append(col)
    groups = machine.groups
    max_n = int(groups[:, 0].max(initial=1)) if len(groups) else 1
    max_t = int(groups[:, 4].max(initial=1)) if len(groups) else 1
    tables = tuple(kernel_input(x) if isinstance(x, np.ndarray) else x for x in (
        machine.program[rows], layout.qoff, layout.qm, layout.row_out, layout.rin, layout.ppos,
        layout.tin, layout.maps, int(layout.max_m), max_n, max_t, machine.groups,
        machine.unknowns,
        machine.terms, machine.cams, machine.arcs, n_pt, n_l, *cols))
    names = ({} if outputs is None else {
        "points": [machine.point_names[i] for i in pt_sel],
        "links": [machine.link_names[i] for i in lk_sel],
        "variables": [machine.variable_names[i] for i in var_sel]})
    plan = _Plan(names, {"p": pt_sel, "l": lk_sel, "v": var_sel},
                 {"p": np.arange(n_pt), "l": n_pt + np.arange(n_l),
                  "v": n_pt + n_l + np.arange(n_v)},
                 layout, tuple(np.asarray(s, dtype=np.int64) for s in layout.support),
                 machine.parameter_names, tables)
    plans[key] = plan
    return plan


def sensitivities(machine: Machine, phi: ArrayLike, *, params: ArrayLike | None = None,
                  inputs=None, rates: bool = False,
                  outputs: list[str] | None = None, kin=None) -> Sensitivities:
    """Exact derivatives of every point position, link angle and joint variable with respect
    to every parameter (``machine.parameter_names``), at shaft angles ``phi`` (rad), for the
    designs ``params`` (default: the file's) and setting ``inputs`` (rad, as for
    :func:`sewmech.kinematics`). With ``rates`` the velocities, angular velocities, joint
    rates and the accelerations are differentiated too (at the file's speed). A position where
    the mechanism cannot be assembled raises (the derivatives are not defined there).

    ``outputs`` (channel names as :meth:`Sensitivities.channel` takes them, e.g.
    ``["p_needle.point_y"]``; None: every channel): only the units these depend on are solved
    and differentiated, and the result holds the points, links and variables of those units
    (a gradient of one channel then costs a few of its own kinematics evaluations).

    ``kin``: the kinematics of these very designs, angles and settings at the file's speed,
    when the caller has them (every point, link and variable; ``outputs`` None): they are
    not computed again."""
    designs = int(np.prod(np.shape(params)[:-1])) if params is not None else 1
    for v in (inputs or {}).values():
        designs = max(designs, int(np.size(v)))
    _check_size(machine, designs * int(np.size(phi)) * (3 if rates else 1))
    plan = _plan(machine, outputs)
    if kin is not None and outputs is None:
        r = kin
    else:
        r = kinematics(machine, phi, params=params, inputs=inputs, **plan.names)
    if not r.all_feasible:
        raise AnalysisError(f"machine '{machine.name}'", "cannot be assembled at some of the"
                            " angles: the sensitivities are not defined there",
                            "Choose angles where it assembles (sewmech check)")
    shape = r.p.shape[:-2]  # batch + (n_phi,)
    n_phi = shape[-1]
    n = int(np.prod(shape))
    par = _design_params(machine, params, inputs)
    if par.shape[:-1] != shape[:-1]:  # (the designs as the kinematics broadcast them)
        par = np.broadcast_to(par, shape[:-1] + par.shape[-1:])
    par = kernel_input(par.reshape(-1, par.shape[-1]))
    n_pt, n_l, n_v = (len(plan.sel[k]) for k in "plv")
    level = 2 if rates else 0
    if rates:  # positions, velocities, accelerations stacked (levels, n, ...)
        PS = np.stack((r.p, r.v, r.a)).reshape(3, n, n_pt, 2)
        THS = np.stack((r.theta, r.omega, r.epsilon)).reshape(3, n, n_l)
        QS = np.stack((r.q, r.q_dot, r.q_ddot)).reshape(3, n, n_v)
    else:
        PS = r.p.reshape(1, n, n_pt, 2)
        THS = r.theta.reshape(1, n, n_l)
        QS = r.q.reshape(1, n, n_v)
    blocks = -(-n // _tangents.LANES)
    T = np.empty((level + 1, blocks, plan.layout.width, _tangents.LANES))
    args = (level, plan.tables[0], par, n_phi, *plan.tables[1:], kernel_input(PS),
            kernel_input(THS), kernel_input(QS), T)
    if n >= _PARALLEL_MIN_POSITIONS:
        bad = run_chunks(_tangents.tangents, blocks, args)
    else:
        bad = _tangents.tangents(0, blocks, *args)
    if bad:
        raise AnalysisError(f"machine '{machine.name}'", "a cam contact lies on no arc of its"
                            " profile", "Check the cam's arcs (sewmech check)")
    return Sensitivities(r, plan, tuple(T))
def _outputs_of(machine: Machine, outputs) -> tuple:
    """The program rows (indices) the channels ``outputs`` depend on (None: all) and the points, links
    and variables those rows write (indices): what the tangents need solved."""
    if outputs is None:
        return (np.arange(len(machine.program)), np.arange(len(machine.point_names)),
                np.arange(len(machine.link_names)), np.arange(len(machine.variable_names)))
    pts, lks, vrs = [], [], []
    for name in ([outputs] if isinstance(outputs, str) else outputs):
        kind, _, rest = str(name).partition("_")
        if kind in ("p", "v", "a"):
            pt, _, comp = rest.rpartition("_")
            if comp not in ("x", "y"):
                raise KeyError(f"channel '{name}': a point channel ends in _x or _y")
            pts.append(name_index(machine.point_names, pt, "point"))
        elif kind in ("theta", "omega", "epsilon"):
            lks.append(name_index(machine.link_names, rest, "link"))
        elif kind in ("q", "qd", "qdd"):
            vrs.append(name_index(machine.variable_names, rest, "joint variable"))
        else:  # (KeyError, as Sensitivities.channel raises for a name it does not know)
            raise KeyError(f"'{name}' is not a channel: p_POINT_x, p_POINT_y, theta_LINK,"
                           " q_VAR, their rates v_, omega_, qd_ and accelerations a_,"
                           " epsilon_, qdd_")
    rows = machine.rows_for(pts, lks, vrs)
    written: set = set()
    for k in rows:
        written |= machine._row_io[k][1]
    sel = [np.array(sorted(i for t, i in written if t == tag), dtype=np.int64)
           for tag in ("p", "l", "v")]
    return (rows, *sel)


def _check_size(machine: Machine, n: int) -> None:
    """Refuse a call whose tangents would not fit in :data:`MAX_BYTES`."""
    need = n * (2 * len(machine.point_names) + len(machine.link_names)
                + len(machine.variable_names)) * len(machine.parameter_names) * 8
    if need > MAX_BYTES:
        raise AnalysisError(f"machine '{machine.name}'", f"the derivatives of {n} positions"
                            f" (designs x angles) by {len(machine.parameter_names)} parameters"
                            f" take {need / 2**30:.1f} GiB", "Ask for fewer designs or angles"
                            f" at a time (at most {MAX_BYTES / 2**30:g} GiB)")


def _design_params(machine: Machine, params, inputs) -> np.ndarray:
    """The parameter vectors the kinematics used: batch + (n_params,)."""
    return machine.parameters(base=params, inputs=inputs) if params is not None or inputs \
        else np.asarray(machine.defaults)
