"""Balancing: choosing counterweights from their effect on the shaking, the bearings, the torque.

The balancing paper in our sources (class 1820 bar-tack semi-automatic) chooses the static moment
of a counterweight on the main shaft so that the peaks of the two components of the machine's
resultant inertia force are equal, Delta-Q = | max|Qx| - max|Qy| | = 0; the JB dynamics report
adds whole-machine balancing (several counterweights at once) and the upper shaft's bearing
reactions as the objective. Here every such criterion is computed for any set of counterweights
and solved exactly.

Why it is fast and exact: the counterweights do not change the motion, and every force of the
machine is linear in the loads a point mass puts on its link (see :mod:`sewmech.dynamics`). For a
counterweight of fixed radius r whose static moment S turns freely (components x = S cos(beta),
y = S sin(beta), kg mm), every quantity is

    Q = Q_0 + sum_c [ x_c A_c + y_c B_c + S_c (C_c / r_c + r_c D_c) ],

with A, B, C, D its responses to unit m u, m v, m and m r^2: one batch of 1 + 4 n designs
through the dynamics gives them all (:class:`BalanceBasis`). The S terms vanish for the inertia
force of a counterweight on a crank turning at constant speed, which makes the classic problems
linear: least squares for an RMS, cutting planes (a linear programme per step, whose value
bounds the optimum from below) for a peak, a range or a weighted sum, and a root for Delta-Q.
Where they do not vanish (weights in the bearing reactions, a coupler's counterweight, the
shaking moment of a rocker's) the problem is smooth in each counterweight's (S, beta) and SLSQP
solves it from several starts. Every answer is evaluated again on the whole machine.

Units: static moments kg mm inside (g cm in results: 1 kg mm = 100 g cm), forces N, moments and
torques N mm inside (N m in results), angles rad inside (deg in results).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from ..engine.counterweights import GCM_PER_KGMM, Counterweight, counterweight_values, describe
from ..engine.dynamics import DynamicsPlan
from ..engine.errors import AnalysisError, OptionError
from ..engine.housing import Housing
from ..engine.machine import Machine
from ._minimax import _linear, _minimise, _natural, _s_terms, _within_limits

#: the criteria :func:`balance` can minimise
CRITERIA = ("delta-q", "peak", "rms", "moment", "bearings", "torque", "weighted", "vibration",
            "equal-levels")

#: the figures every result reports, before and after (keys of :meth:`BalanceBasis.criteria`)
FIGURES = ("delta_q_N", "peak_force_N", "rms_force_N", "peak_moment_Nm", "bearing_front_peak_N",
           "bearing_rear_peak_N", "bearing_front_rms_N", "bearing_rear_rms_N",
           "torque_fluctuation_Nm", "vibration_x_db", "vibration_y_db")

# the four probes of a counterweight: (radius mm, angle rad), 1 kg each; their (m, m u, m v,
# m r^2) rows are independent, so the responses to the four follow from one solve
_PROBES = ((1.0, 0.0), (1.0, 0.5 * math.pi), (1.0, math.pi), (2.0, 0.0))
_G = np.array([[1.0, r * math.cos(a), r * math.sin(a), r * r] for r, a in _PROBES])


@dataclass(frozen=True, eq=False)
class BalanceBasis:
    """The balancing quantities of a machine as functions of chosen counterweights' static
    moments, at one speed over one turn.

    Attributes
    ----------
    machine : Machine
    counterweights : tuple[Counterweight, ...]
        The chosen counterweights (their static moments and angles are the variables; their
        radii stay).
    radius : ndarray (n,)
        Each one's radius, mm.
    s_max : ndarray (n,)
        Each one's largest static moment (``max_static_moment_gcm``), kg mm; inf: no limit.
    phi : ndarray (n_phi,)
        Shaft angles, rad.
    rpm : float
    moment_point : (float, float)
        The point the shaking moment is taken about, mm (default: the upper shaft's axis).
    base : dict
        The quantities with the chosen counterweights taken off: ``F`` shaking force (n_phi, 2)
        N, ``M`` shaking moment about ``moment_point`` (n_phi,) N mm, ``T`` driving torque
        (n_phi,) N mm and, with a ``[shaft]`` table, ``Bf`` and ``Br`` the front and rear
        bearing reactions (n_phi, 2) N.
    resp : dict
        Each quantity's responses (n, 4, ...) to unit m, m u, m v and m r^2 of each
        counterweight.
    plan : DynamicsPlan
        The dynamics the basis came from, for evaluating designs on the whole machine.
    """

    machine: Machine
    counterweights: tuple[Counterweight, ...]
    radius: np.ndarray
    s_max: np.ndarray
    phi: np.ndarray
    rpm: float
    moment_point: tuple[float, float]
    base: dict
    resp: dict
    plan: DynamicsPlan = field(repr=False)
    start: np.ndarray = field(repr=False)
    housing: Housing | None = field(default=None, repr=False)
    control: int = 0

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.counterweights)

    @property
    def has_bearings(self) -> bool:
        return "Bf" in self.base

    # ---- evaluation ---------------------------------------------------------------------------
    def quantities(self, xy: ArrayLike) -> dict:
        """The quantities for static moments ``xy`` (batch + (n, 2): S cos(beta), S sin(beta),
        kg mm): each batch + its shape in :attr:`base`."""
        xy = np.asarray(xy, dtype=float)
        x, y = xy[..., 0], xy[..., 1]
        s = np.hypot(x, y)
        coef = np.stack([s / self.radius, x, y, s * self.radius], axis=-1)  # batch + (n, 4)
        out = {}
        for key, b in self.base.items():
            r = self.resp[key]  # (n, 4) + shape
            out[key] = b + np.tensordot(coef, r, axes=([-2, -1], [0, 1]))
        return out

    def criteria(self, xy: ArrayLike) -> dict:
        """Every balancing figure (:data:`FIGURES`) for static moments ``xy`` (batch + (n, 2)),
        each of shape batch (None for the bearings of a machine without ``[shaft]``, and for
        the vibration of one without ``[housing]``)."""
        return figures(self.quantities(xy), self.levels)

    @property
    def control_name(self) -> str | None:
        return None if self.housing is None else self.housing.control_names[self.control]

    def velocities(self, W: np.ndarray) -> np.ndarray:
        """The control point's RMS velocity along x and y (mm/s), batch + (2,), under the
        excitation ``W`` (batch + (n_phi, 6))."""
        from ..engine.housing import vibration

        return vibration(self.housing, W, self.rpm).rms_velocity[..., self.control, :2]

    @cached_property
    def _velocity_basis(self) -> tuple[np.ndarray, np.ndarray]:
        """The control point's x and y velocity harmonics (complex, mm/s) of the base and of
        each counterweight's four responses: (n_h, 2) and (n, 4, n_h, 2). The velocities are
        linear in the wrench, so any design's are theirs combined as the wrench's are."""
        from ..engine.housing import vibration

        W0, R = self.base["W"], self.resp["W"]
        stack = np.concatenate([W0[None], R.reshape(-1, *W0.shape)])
        cv = vibration(self.housing, stack, self.rpm).control_v[..., self.control, :2]
        return cv[0], cv[1:].reshape(R.shape[:2] + cv.shape[1:])

    def velocities_at(self, xy: ArrayLike) -> np.ndarray:
        """The control point's RMS velocity along x and y (mm/s), batch + (2,), for static
        moments ``xy`` (batch + (n, 2), kg mm): :meth:`velocities` of their wrench, from the
        velocity harmonics of the basis (no Fourier series or solve per design)."""
        xy = np.asarray(xy, dtype=float)
        x, y = xy[..., 0], xy[..., 1]
        s = np.hypot(x, y)
        coef = np.stack([s / self.radius, x, y, s * self.radius], axis=-1)  # batch + (n, 4)
        v0, vr = self._velocity_basis
        V = v0 + np.tensordot(coef, vr, axes=([-2, -1], [0, 1]))
        return np.sqrt(2.0 * np.sum(np.abs(V) ** 2, axis=-2))

    def levels(self, W: np.ndarray) -> np.ndarray:
        """The control point's vibration levels along x and y, dB re 5e-8 m/s, batch + (2,)."""
        from ..engine.housing import V_REF_MM_S

        with np.errstate(divide="ignore"):
            return 20.0 * np.log10(self.velocities(W) / V_REF_MM_S)

    def design(self, xy: ArrayLike) -> dict[str, float]:
        """The parameter values (internal units) that give the counterweights static moments
        ``xy`` (n, 2) at their radii: for :meth:`Machine.with_parameters` or
        :meth:`Machine.parameters`."""
        xy = np.asarray(xy, dtype=float)
        out = {}
        for c, r, (x, y) in zip(self.counterweights, self.radius, xy):
            S, beta = math.hypot(x, y), math.atan2(y, x)
            if c.by_moment:
                out[f"{c.name}.static_moment"], out[f"{c.name}.angle"] = S, beta
            else:
                out[f"{c.name}.mass"] = S / r
                out[f"{c.name}.u"], out[f"{c.name}.v"] = r * math.cos(beta), r * math.sin(beta)
        return out

    def evaluate(self, xy: ArrayLike) -> dict:
        """The quantities of static moments ``xy`` (batch + (n, 2)) computed on the whole
        machine (its dynamics with those counterweights, one batch call), not from the basis."""
        xy = np.asarray(xy, dtype=float)
        flat = xy.reshape(-1, *xy.shape[-2:])
        designs = [self.design(one) for one in flat]
        P = self.machine.parameters({k: np.array([d[k] for d in designs]) for k in designs[0]})
        q = _quantities(self.plan(P), self.moment_point, self.has_bearings, self.housing)
        return {k: v.reshape(xy.shape[:-2] + v.shape[1:]) for k, v in q.items()}

    def describe(self, xy: ArrayLike) -> dict[str, dict]:
        """Each counterweight of static moments ``xy`` (n, 2) as people read it (static moment
        g cm, angle deg, mass g, radius and u, v mm)."""
        out = {}
        for c, r, (x, y) in zip(self.counterweights, self.radius, np.asarray(xy, dtype=float)):
            S = math.hypot(x, y)
            beta = math.atan2(y, x)
            out[c.name] = describe(c, S / r, r * math.cos(beta), r * math.sin(beta))
        return out


def figures(q: Mapping[str, np.ndarray], levels=None) -> dict:
    """The balancing figures (:data:`FIGURES`, N and N m, dB) of quantities ``q`` (the keys of
    :attr:`BalanceBasis.base`, each batch + (n_phi, ...)); ``levels``: the control point's
    levels (x, y) dB of the housing's excitation ``q["W"]`` (:meth:`BalanceBasis.levels`)."""
    F = q["F"]
    mag = np.hypot(F[..., 0], F[..., 1])
    out = {
        "delta_q_N": np.abs(np.abs(F[..., 0]).max(axis=-1) - np.abs(F[..., 1]).max(axis=-1)),
        "peak_force_N": mag.max(axis=-1),
        "rms_force_N": np.sqrt(np.mean(mag ** 2, axis=-1)),
        "peak_moment_Nm": 1e-3 * np.abs(q["M"]).max(axis=-1),
        "torque_fluctuation_Nm": 1e-3 * (q["T"].max(axis=-1) - q["T"].min(axis=-1)),
    }
    for side, key in (("front", "Bf"), ("rear", "Br")):
        if key in q:
            b = np.hypot(q[key][..., 0], q[key][..., 1])
            out[f"bearing_{side}_peak_N"] = b.max(axis=-1)
            out[f"bearing_{side}_rms_N"] = np.sqrt(np.mean(b ** 2, axis=-1))
        else:
            out[f"bearing_{side}_peak_N"] = out[f"bearing_{side}_rms_N"] = None
    if "W" in q and levels is not None:
        lv = levels(q["W"])
        out["vibration_x_db"], out["vibration_y_db"] = lv[..., 0], lv[..., 1]
    else:
        out["vibration_x_db"] = out["vibration_y_db"] = None
    return {k: out[k] for k in FIGURES}


def _difference(key: str, a: np.ndarray, b: np.ndarray) -> float:
    """The largest difference of a quantity, N or N m (the housing's wrench: its forces N,
    its moments N m)."""
    d = np.abs(np.asarray(a) - np.asarray(b))
    if key in ("M", "T"):
        return float(d.max()) * 1e-3
    if key == "W":
        return max(float(d[..., :3].max()), float(d[..., 3:].max()) * 1e-3)
    return float(d.max())


def _quantities(res, point: tuple[float, float], bearings: bool,
                housing: Housing | None = None) -> dict:
    """The balancing quantities of a dynamics result (see :attr:`BalanceBasis.base`); with a
    housing, ``W`` the wrench the mechanisms put on it (n_phi, 6: N, N mm)."""
    F = res.shaking_force
    x0, y0 = point
    out = {"F": F, "M": res.shaking_moment - (x0 * F[..., 1] - y0 * F[..., 0]),
           "T": res.input_torque}
    if bearings:
        out["Bf"], out["Br"] = res.bearings.front, res.bearings.rear
    if housing is not None:
        from ..engine.housing import excitation

        out["W"] = excitation(res.machine, housing, res)
    return out


def shaft_axis(machine: Machine) -> tuple[float, float]:
    """The upper shaft's axis point (x, y), mm: the pivot of the cranks the shaft turns at
    ratio 1 (the ``[shaft]`` cranks' pivot when there is a ``[shaft]`` table)."""
    spec = machine.spec
    names = set(spec.shaft.links) if spec.shaft is not None else None
    for u in spec.units:
        if u.type == "crank" and u.input == "shaft" and u.ratio == 1.0 and (
                names is None or (u.link or u.name) in names):
            p = spec.points[u.pivot]
            return float(p.x), float(p.y)
    return 0.0, 0.0


def shaft_counterweight(machine: Machine) -> str | None:
    """The counterweight the balancing paper's workflow applies to: the first one on a crank
    that turns with the upper shaft (ratio 1), else None."""
    cranks = {u.link or u.name for u in machine.spec.units
              if u.type == "crank" and u.input == "shaft" and u.ratio == 1.0}
    for c in machine.counterweights:
        if c.link in cranks:
            return c.name
    return None


def balance_basis(machine: Machine, counterweights: Sequence[str] | None = None, *,
                  rpm: float | None = None, step_deg: float = 1.0,
                  moment_point: tuple[float, float] | None = None,
                  gravity: bool = True, control_point: str | None = None) -> BalanceBasis:
    """The balancing quantities of ``machine`` as functions of the static moments of its
    counterweights ``counterweights`` (names; default: all of the file's), at ``rpm``
    (default: the file's) on a grid of ``step_deg`` over one turn; the shaking moment about
    ``moment_point`` (x, y mm; default: the upper shaft's axis). The other counterweights stay
    as the file has them. With a ``[housing]``, the wrench on it too (the vibration criteria;
    ``control_point``: where they judge it, default the housing's first)."""
    chosen = _chosen(machine, counterweights)
    n_phi = round(360.0 / step_deg)
    if not (0.1 <= step_deg <= 30.0) or abs(n_phi * step_deg - 360.0) > 1e-9:
        raise OptionError("step_deg", f"must divide 360 and be in 0.1 .. 30 deg, got {step_deg}",
                          "Give e.g. 1 or 5")
    phi = np.arange(n_phi) * math.radians(step_deg)
    point = shaft_axis(machine) if moment_point is None else tuple(map(float, moment_point))
    plan = DynamicsPlan(machine, phi, rpm=rpm, gravity=gravity)
    bearings = machine.spec.shaft is not None
    n = len(chosen)
    # designs: the chosen counterweights off, then each one's four probes (1 kg at radius r and
    # angle a; the others off). The responses to the probes are the frictionless machine's,
    # whose forces are linear in the counterweights; the base is the whole machine's (its
    # friction included: see balance())
    rows = [_set(machine, chosen, {})]
    for c in chosen:
        for r, a in _PROBES:
            rows.append(_set(machine, chosen, {c.name: (1.0, r, a)}))
    linear = plan if machine.spec.friction is None else DynamicsPlan(
        machine, phi, rpm=rpm, gravity=gravity, friction=False)
    housing = None
    if machine.spec.housing is not None:
        from ..engine.housing import Housing

        housing = Housing.of(machine)
    res = linear(np.stack(rows))
    q = _quantities(res, point, bearings, housing)
    if linear is not plan:
        q0 = _quantities(plan(rows[0]), point, bearings, housing)
        base = {k: np.asarray(v).copy() for k, v in q0.items()}
        q = {k: np.concatenate([v[:1] * 0.0 + q0[k][None], v[1:] - v[:1] + q0[k][None]])
             for k, v in q.items()}
    else:
        base = {k: v[0].copy() for k, v in q.items()}
    resp = {}
    Ginv = np.linalg.inv(_G)
    for k, v in q.items():
        probes = (v[1:] - v[0]).reshape((n, 4) + v.shape[1:])
        resp[k] = np.einsum("ij,cj...->ci...", Ginv, probes)  # (n, [m, mu, mv, mr2], ...)
    radius, s_max, start = _radii(machine, chosen)
    if rpm is None:
        rpm = machine.rpm
    control = 0
    if housing is not None and control_point is not None:
        if control_point not in housing.control_names:
            raise OptionError("--control-point", f"'{control_point}' is not a control point of"
                              f" '{machine.name}'", "Its housing's control points:"
                              f" {', '.join(housing.control_names)}")
        control = housing.control_names.index(control_point)
    return BalanceBasis(machine, chosen, radius, s_max, phi, float(rpm), point, base, resp,
                        plan, start, housing, control)


def _chosen(machine: Machine, names: Sequence[str] | None) -> tuple[Counterweight, ...]:
    have = {c.name: c for c in machine.counterweights}
    if not have:
        add = ("Add a [counterweights.NAME] table (docs/balancing.md) on the link to balance,"
               " with the static moment it has now (0 for a new one)")
        if names:
            raise OptionError("--counterweight", f"'{names[0]}' is not a counterweight of"
                              f" '{machine.name}': it has none", add)
        raise AnalysisError(machine.file or f"machine '{machine.name}'", f"machine"
                            f" '{machine.name}' has no counterweights to balance with", add)
    if not names:
        return tuple(machine.counterweights)
    out = []
    for name in names:
        if name not in have:
            raise OptionError("--counterweight", f"'{name}' is not a counterweight of"
                              f" '{machine.name}'", f"Its counterweights: {', '.join(have)}")
        if have[name] in out:
            raise OptionError("--counterweight", f"'{name}' is given twice", "Name it once")
        out.append(have[name])
    return tuple(out)


def _radii(machine: Machine, chosen) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Radius (mm), largest static moment (kg mm) and present static moment (x, y kg mm) of
    each chosen counterweight, from the file."""
    m, u, v = counterweight_values(chosen, machine.defaults)
    radius = np.hypot(u, v)
    for c, r in zip(chosen, radius):
        if not r > 0.0:
            raise OptionError("--counterweight", f"'{c.name}' sits on its link's frame origin"
                              " (radius 0): its static moment cannot be chosen",
                              f"Give [counterweights.{c.name}] a radius where it can sit")
    s_max = np.array([np.inf if machine.spec.counterweights[c.name].max_static_moment_gcm is None
                      else machine.spec.counterweights[c.name].max_static_moment_gcm
                      / GCM_PER_KGMM for c in chosen])
    return radius, s_max, np.stack([m * u, m * v], axis=-1)


def _set(machine: Machine, chosen, values: Mapping[str, tuple[float, float, float]]
         ) -> np.ndarray:
    """A parameter vector with the chosen counterweights off except ``values`` (name ->
    (mass kg, radius mm, angle rad))."""
    P = np.array(machine.defaults)
    for c in chosen:
        m, r, a = values.get(c.name, (0.0, None, None))
        i, j, k = c.params
        if r is None:  # off, where it is
            P[i] = 0.0
            continue
        if c.by_moment:
            P[i], P[j], P[k] = m * r, a, r
        else:
            P[i], P[j], P[k] = m, r * math.cos(a), r * math.sin(a)
    return P


# ---- solving --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BalanceResult:
    """What :func:`balance` chose and what it does.

    criterion : the criterion minimised; status : ``"optimal"``, ``"bounded"`` (a counterweight
    at its ``max_static_moment_gcm``), ``"infeasible"`` (Delta-Q cannot reach 0 within the
    limits: nothing is proposed, see below) or ``"not converged"`` (the best design found is
    given); message : how it was solved, or why not, and for ``"infeasible"`` what to try;
    xy : the static moments chosen (n, 2), kg mm; counterweights, counterweights_before : each
    as people read it (:meth:`BalanceBasis.describe`); before, after : the balancing figures
    (:data:`FIGURES`) of the machine as the file has it and with the chosen counterweights,
    both computed on the whole machine; overrides : the parameter values to apply
    (:meth:`Machine.with_parameters`); basis_error : the largest difference between the
    basis' prediction of the result and the whole machine's, N or N m; curves: the
    quantities over the turn (:attr:`BalanceBasis.base` keys; N, N mm) ``"before"`` and
    ``"after"``, computed on the whole machine, with ``"phi"`` (rad).

    An ``"infeasible"`` result proposes no counterweight: ``xy``, ``counterweights``,
    ``after`` and ``curves["after"]`` are the machine as the file has it (nothing changed,
    ``overrides`` empty); ``closest`` holds the static moment of least Delta-Q (g cm, deg, with
    its figures), for information only, and ``alternative`` the answer of another criterion
    (the least peak shaking force with the same counterweight), the best that is achievable.
    """

    criterion: str
    status: str
    message: str
    xy: np.ndarray
    counterweights: dict
    counterweights_before: dict
    before: dict
    after: dict
    overrides: dict
    basis_error: float
    rpm: float
    weights: dict = field(default_factory=dict)
    curves: dict = field(default_factory=dict, repr=False)
    closest: dict | None = None
    alternative: BalanceResult | None = field(default=None, repr=False)

    @property
    def proposed(self) -> bool:
        """Whether the result proposes counterweights (every status but ``"infeasible"``)."""
        return self.status != "infeasible"

    def to_json(self) -> dict:
        """The result as the ``sewmech balance --json`` keys: for an infeasible one,
        ``counterweights`` and ``after`` are null, and ``closest`` and ``alternative`` say what
        is reachable instead."""
        out = {"criterion": self.criterion, "status": self.status, "message": self.message,
               "rpm": self.rpm,
               "counterweights": self.counterweights if self.proposed else None,
               "counterweights_before": self.counterweights_before,
               "before": _plain(self.before),
               "after": _plain(self.after) if self.proposed else None,
               "weights": self.weights, "basis_error": self.basis_error}
        if not self.proposed:
            out["closest"] = None if self.closest is None else {
                "counterweights": self.closest["counterweights"],
                "figures": _plain(self.closest["figures"]),
                "note": "the least Delta-Q reachable; not proposed (see message)"}
            alt = self.alternative
            out["alternative"] = None if alt is None else {
                "criterion": alt.criterion, "option": f"--criterion {alt.criterion}",
                "status": alt.status, "message": alt.message,
                "counterweights": alt.counterweights, "after": _plain(alt.after)}
        return out


def _plain(d: dict) -> dict:
    return {k: (None if v is None else float(v)) for k, v in d.items()}


#: the weighted criterion's parts and their default weights
WEIGHTED_PARTS = ("peak_force_N", "rms_force_N", "peak_moment_Nm", "bearings_peak_N",
                  "torque_fluctuation_Nm")


#: how often balance() solves again with the friction of its answer, at most
FRICTION_PASSES = 8


def balance(machine: Machine, criterion: str = "delta-q",
            counterweights: Sequence[str] | None = None, *, rpm: float | None = None,
            step_deg: float = 1.0, moment_point: tuple[float, float] | None = None,
            weights: Mapping[str, float] | None = None,
            basis: BalanceBasis | None = None,
            control_point: str | None = None) -> BalanceResult:
    """Choose the static moments and angles of ``counterweights`` (default: all of the
    machine's) that minimise ``criterion`` at ``rpm``:

    - ``"delta-q"``: the balancing paper's | max|Qx| - max|Qy| | = 0 (Q the shaking force):
      one counterweight, its static moment along its present angle;
    - ``"peak"``, ``"rms"``: the peak or the RMS over the turn of the shaking force's length;
    - ``"moment"``: the peak shaking moment about ``moment_point`` (default the upper shaft);
    - ``"bearings"``: the larger of the peak front and rear bearing reactions of the upper
      shaft (the JB dynamics report's third method; needs ``[shaft]``);
    - ``"torque"``: the fluctuation (max - min) of the driving torque;
    - ``"weighted"``: sum of ``weights[part] * part / part before`` over
      :data:`WEIGHTED_PARTS` (default weight 1 each; bearings only with ``[shaft]``);
    - ``"vibration"``: the larger of the RMS vibration velocities along x and y at the
      housing's ``control_point`` (default its first; needs ``[housing]``);
    - ``"equal-levels"``: the balancing paper's own experimental criterion predicted from the
      model: one counterweight's static moment along its present angle at which the control
      point's x and y levels are equal (:func:`sewmech.design._vibration_criteria.
      level_curves` draws the two against it).

    Each counterweight keeps its radius; its static moment stays within
    ``max_static_moment_gcm`` if its table gives one. ``basis``: a :func:`balance_basis` of the
    same machine, counterweights, speed and grid, to reuse.
    """
    if criterion not in CRITERIA:
        raise OptionError("--criterion", f"unknown criterion {criterion!r}",
                          f"Choose one of {', '.join(CRITERIA)}")
    B = basis if basis is not None else balance_basis(
        machine, counterweights, rpm=rpm, step_deg=step_deg, moment_point=moment_point,
        control_point=control_point)
    if criterion in ("vibration", "equal-levels") and B.housing is None:
        raise OptionError("--criterion", f"machine '{machine.name}' has no [housing] table, so"
                          " its vibration is not known", "Add [housing] (its mass, mounts and"
                          " control points: docs/vibration.md) or choose another criterion")
    if criterion == "bearings" and not B.has_bearings:
        raise OptionError("--criterion", f"machine '{machine.name}' has no [shaft] table, so"
                          " its bearing reactions are not known", "Add [shaft] (the cranks' and"
                          " bearings' planes along the shaft) or choose another criterion")
    w = _weights(weights, B) if criterion == "weighted" else {}

    def solve(B):
        if criterion == "delta-q":
            return _solve_delta_q(B)
        if criterion in ("vibration", "equal-levels"):
            from ._vibration_criteria import solve_equal_levels, solve_vibration

            return (solve_vibration(B) if criterion == "vibration" else
                    solve_equal_levels(B))
        if criterion == "rms":
            return _solve_rms(B)
        if criterion == "weighted":
            return _solve_weighted(B, w)
        return _solve_peak(B, criterion)

    xy, status, message = solve(B)
    both = B.evaluate(np.stack([B.start, xy]))  # the file's and the chosen, on the machine
    exact = {k: v[1] for k, v in both.items()}
    predicted = B.quantities(xy)
    if machine.spec.friction is not None and status != "infeasible":
        # the counterweights change the pair forces and with them the friction, which the
        # linear basis cannot know (the shaking force and moment do not depend on it): solve
        # again with the basis moved by the friction's change at the answer, until the answer
        # stays (the friction of the answer, as it is)
        # (the shift is the friction's change against the frictionless basis B, not against
        # the last shifted one: shifts taken against that would drop the one before and
        # alternate)
        passes = 0
        for passes in range(1, FRICTION_PASSES + 1):
            plain = B.quantities(xy)
            shift = {k: exact[k] - plain[k] for k in exact}
            shifted = replace(B, base={k: B.base[k] + shift[k] for k in exact})
            # from the last answer (the weighted criterion's parts are scaled by the figures
            # at the start, so it keeps its start): where the optimum is flat, a solve from
            # afar may land elsewhere on it with every pass and never settle
            xy2, status, message = solve(shifted if criterion == "weighted" else
                                         replace(shifted, start=xy.copy()))
            moved = float(np.abs(xy2 - xy).max())
            xy = xy2
            exact = {k: v[0] for k, v in B.evaluate(xy[None]).items()}
            predicted = shifted.quantities(xy)
            B_used = shifted
            if moved <= 1e-9 * max(1.0, float(np.abs(xy).max())) or \
                    max(_difference(k, predicted[k], exact[k]) for k in exact) <= 1e-9:
                break
        message += (f"; with the friction of the answer ({passes} pass"
                    f"{'es' if passes != 1 else ''}: the counterweights change the friction)")
        B = B_used
    if status == "optimal" and np.any(np.hypot(xy[:, 0], xy[:, 1]) >= B.s_max * (1 - 1e-9)):
        status = "bounded"
        message += "; a counterweight is at its max_static_moment_gcm"
    before = figures({k: v[0] for k, v in both.items()}, B.levels)
    after = figures(exact, B.levels)
    err = max(_difference(k, predicted[k], exact[k]) for k in exact)
    curves = {"phi": B.phi, "before": {k: v[0] for k, v in both.items()}, "after": exact}
    if criterion == "delta-q" and status != "infeasible" and \
            after["peak_force_N"] > before["peak_force_N"] * (1.0 + 1e-9):
        message += (f"; note: equal peaks here raise the peak shaking force from"
                    f" {float(before['peak_force_N']):.4g} to {float(after['peak_force_N']):.4g}"
                    " N (--criterion peak minimises it)")
    if status != "infeasible":
        return BalanceResult(criterion, status, message, xy, B.describe(xy),
                             B.describe(B.start), before, after, B.design(xy), err, B.rpm, w,
                             curves)
    # nothing to propose: the machine stays as the file has it; the least Delta-Q is kept for
    # information, and the least peak shaking force is what this counterweight can achieve
    closest = {"xy": xy, "counterweights": B.describe(xy), "figures": after}
    if criterion == "equal-levels":  # the least vibration is what it can achieve instead
        alt = balance(machine, "vibration", basis=B)
        message += _unequal_advice(B, closest, alt, before)
    else:
        alt = balance(machine, "peak", basis=B)
        message += _infeasible_advice(B, closest, alt, before)
    return BalanceResult(criterion, status, message, B.start.copy(), B.describe(B.start),
                         B.describe(B.start), before, dict(before), {}, err, B.rpm, w,
                         {"phi": B.phi, "before": curves["before"], "after": curves["before"]},
                         closest, alt)


def _infeasible_advice(B: BalanceBasis, closest: dict, alt: BalanceResult, before: dict
                       ) -> str:
    """What an infeasible Delta-Q says besides: what its closest point would do, the best
    another criterion achieves with the same counterweight, and what to change."""
    (name, cw), = closest["counterweights"].items()
    peak0, peak1 = float(before["peak_force_N"]), float(closest["figures"]["peak_force_N"])
    (_, a), = alt.counterweights.items()
    text = (f". No counterweight is proposed: the least Delta-Q,"
            f" {float(closest['figures']['delta_q_N']):.4g} N with {cw['static_moment_gcm']:.4g}"
            f" g cm, would make the peak shaking force {peak1:.4g} N against {peak0:.4g} N"
            f" now{f' ({peak1 / peak0:.2g} x)' if peak0 > 0 else ''}. The best this counterweight achieves is the least"
            f" peak shaking force, {float(alt.after['peak_force_N']):.4g} N with"
            f" {a['static_moment_gcm']:.4g} g cm at {a['angle_deg']:.4g} deg: use --criterion"
            f" peak (or rms, weighted); or turn '{name}' (its angle_deg) to where Delta-Q has a"
            " root")
    if math.isfinite(B.s_max[0]):
        text += ", or allow it more static moment (max_static_moment_gcm)"
    return text


def _unequal_advice(B: BalanceBasis, closest: dict, alt: BalanceResult, before: dict
                   ) -> str:
    """What an equal-levels balancing without a crossing says besides: how close the levels
    come, and the least vibration the counterweights achieve."""
    (name, cw), = closest["counterweights"].items()
    f = closest["figures"]
    lx, ly = float(f["vibration_x_db"]), float(f["vibration_y_db"])
    worst0 = max(float(before["vibration_x_db"]), float(before["vibration_y_db"]))
    best = max(float(alt.after["vibration_x_db"]), float(alt.after["vibration_y_db"]))
    where = ", ".join(f"{n} {c['static_moment_gcm']:.4g} g cm at {c['angle_deg']:.4g} deg"
                      for n, c in alt.counterweights.items())
    text = (f". No counterweight is proposed: the levels come closest with"
            f" {cw['static_moment_gcm']:.4g} g cm, x {lx:.4g} dB and y {ly:.4g} dB. The least"
            f" larger level the counterweights achieve is {best:.4g} dB against {worst0:.4g} dB"
            f" now ({where}): use --criterion vibration; or turn '{name}' (its angle_deg)")
    if math.isfinite(B.s_max[0]):
        text += ", or allow it more static moment (max_static_moment_gcm)"
    return text


def _weights(weights: Mapping[str, float] | None, B: BalanceBasis) -> dict:
    parts = [p for p in WEIGHTED_PARTS if B.has_bearings or p != "bearings_peak_N"]
    w = {p: 1.0 for p in parts}
    for k, v in (weights or {}).items():
        if k not in parts:
            raise OptionError("--weight", f"unknown part {k!r}", f"Parts: {', '.join(parts)}")
        if not (math.isfinite(v) and v >= 0.0):
            raise OptionError("--weight", f"{k} = {v!r}: a weight is a number >= 0")
        w[k] = float(v)
    if not any(w.values()):
        raise OptionError("--weight", "every weight is 0", "Give at least one a weight > 0")
    return w


def _solve_rms(B: BalanceBasis) -> tuple[np.ndarray, str, str]:
    """Least squares of the shaking force over the turn (with S terms: Gauss-Newton, each step
    the least squares of the expansion at the last answer); with a limit that the answer
    passes, the cutting-plane method on the limited problem."""
    n = len(B.counterweights)
    xy = B.start.copy()
    steps = 0
    for steps in range(1, 101):
        c, L = _linear(B, "F", xy)
        z, *_ = np.linalg.lstsq(L.reshape(-1, 2 * n), -c.reshape(-1), rcond=None)
        new = z.reshape(n, 2)
        moved = np.abs(new - xy).max()
        xy = new
        if moved <= 1e-13 * (1.0 + np.abs(new).max()):
            break
    how = "least squares" if not _s_terms(B, ["F"]) else f"Gauss-Newton, {steps} steps"
    if np.all(np.hypot(xy[:, 0], xy[:, 1]) <= B.s_max):
        return xy, "optimal", f"RMS shaking force over the turn: {how}"
    return _minimise(B, [("rms", ("F",), 1.0)], xy, "RMS shaking force")


#: what each peak criterion minimises: (kind, quantities) of its one part
_PEAKS = {"peak": ("vector", ("F",), "peak shaking force"),
          "moment": ("abs", ("M",), "peak shaking moment"),
          "bearings": ("vector", ("Bf", "Br"), "larger peak bearing reaction"),
          "torque": ("range", ("T",), "torque fluctuation")}


def _solve_peak(B: BalanceBasis, criterion: str) -> tuple[np.ndarray, str, str]:
    kind, keys, what = _PEAKS[criterion]
    if not _depends(B, keys):
        return B.start.copy(), "optimal", (f"{what}: the chosen counterweights do not change it"
                                           " (kept as the file has them)")
    start, _, _ = _solve_rms(B) if "F" in keys else (B.start, None, None)
    return _minimise(B, [(kind, keys, 1.0)], start, what)


def _solve_weighted(B: BalanceBasis, w: dict) -> tuple[np.ndarray, str, str]:
    """Sum of weighted criteria, each divided by its value before (parts that are 0 before,
    such as the moment of a machine that has none, are left out, and so are parts the chosen
    counterweights cannot change, such as the moment about the shaft's axis of counterweights
    on the shaft: a constant does not move the optimum)."""
    before = figures(B.quantities(B.start), B.levels)
    value = {"peak_force_N": before["peak_force_N"], "rms_force_N": before["rms_force_N"],
             "peak_moment_Nm": before["peak_moment_Nm"],
             "torque_fluctuation_Nm": before["torque_fluctuation_Nm"]}
    if B.has_bearings:
        value["bearings_peak_N"] = max(before["bearing_front_peak_N"],
                                       before["bearing_rear_peak_N"])
    scale = max(float(v) for v in value.values())
    kinds = {"peak_force_N": ("vector", ("F",)), "rms_force_N": ("rms", ("F",)),
             "peak_moment_Nm": ("abs", ("M",)), "bearings_peak_N": ("vector", ("Bf", "Br")),
             "torque_fluctuation_Nm": ("range", ("T",))}
    parts, used, left, fixed = [], [], [], []
    for p, wp in w.items():
        v = float(value[p])
        if wp == 0.0:
            continue
        if not v > 1e-12 * scale:
            left.append(p)
            continue
        if not _depends(B, kinds[p][1]):
            fixed.append(p)
            continue
        parts.append((*kinds[p], wp / v))
        used.append(f"{wp:g} x {p} / {v:.6g}")
    if not parts:
        raise OptionError("--weight", "every weighted part is 0 before balancing or does not"
                          " depend on the chosen counterweights", "Nothing to balance by these"
                          " parts: weigh others")
    start, _, _ = _solve_rms(B)
    xy, status, message = _minimise(B, parts, start, "weighted sum")
    message = message.replace("weighted sum", "weighted sum of " + ", ".join(used), 1)
    if left:
        message += f"; left out (0 before): {', '.join(left)}"
    if fixed:
        message += f"; left out (the counterweights do not change them): {', '.join(fixed)}"
    return xy, status, message


def _depends(B: BalanceBasis, keys: Sequence[str]) -> bool:
    """Whether any of the quantities ``keys`` changes with the chosen counterweights (beyond
    the round-off of the quantity itself)."""
    for key in keys:
        floor = 1e-12 * max(float(np.abs(B.base[key]).max()), 1e-300)
        if float(np.abs(B.resp[key]).max()) * _natural(B) > floor:
            return True
    return False


def _solve_delta_q(B: BalanceBasis) -> tuple[np.ndarray, str, str]:
    """The paper's Delta-Q = 0: one counterweight's static moment along its present angle (a
    root of max|Qx| - max|Qy| on the exact basis); the root of least peak force if several."""
    from scipy.optimize import brentq, minimize_scalar

    if len(B.counterweights) != 1:
        raise OptionError("--counterweight", "delta-q chooses the static moment of one"
                          f" counterweight; {len(B.counterweights)} are chosen",
                          "Name one with --counterweight NAME (its angle stays as the file"
                          " gives it), or choose peak, rms or weighted for several")
    from ._vibration_criteria import _direction

    beta, e = _direction(B)  # its present angle (the file's when it weighs nothing now)

    def f(S):
        F = B.quantities((S * e)[None, :])["F"]
        return float(np.abs(F[:, 0]).max() - np.abs(F[:, 1]).max())

    # the scan reaches four times the natural scale (or the limit)
    hi = B.s_max[0] if math.isfinite(B.s_max[0]) else 4.0 * _natural(B)
    grid = np.linspace(0.0, hi, 401)
    F = B.quantities(grid[:, None, None] * e)["F"]  # the scan in one batch
    vals = np.abs(F[..., 0]).max(axis=-1) - np.abs(F[..., 1]).max(axis=-1)
    roots = []
    for k in np.nonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) <= 0)[0]:
        if vals[k] == 0.0:
            roots.append(grid[k])
        elif vals[k + 1] != 0.0:
            roots.append(brentq(f, grid[k], grid[k + 1], xtol=1e-14 * hi, rtol=1e-14))
    where = f"along {math.degrees(beta):.6g} deg"
    if roots:
        best = min(roots, key=lambda s: float(B.criteria((s * e)[None, :])["peak_force_N"]))
        more = f" (the one of least peak force among {len(roots)})" if len(roots) > 1 else ""
        return (best * e)[None, :], "optimal", \
            f"Delta-Q = 0: root of max|Qx| - max|Qy| {where}{more}"
    k = int(np.argmin(np.abs(vals)))
    lo, up = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    s = minimize_scalar(lambda S: abs(f(S)), bounds=(lo, up), method="bounded",
                        options={"xatol": 1e-12 * hi}).x
    limit = "max_static_moment_gcm" if math.isfinite(B.s_max[0]) else "the scanned range"
    return (s * e)[None, :], "infeasible", f"Delta-Q does not reach 0 {where} within {limit}"


# ---- the designer's views: the paper's workflow and the trade-off front -----------------------


def link_static_moment(machine: Machine, link: str) -> tuple[float, float]:
    """The static moment of a link's own masses (its ``[masses]`` table, without the
    counterweights) about its frame's origin: (S g cm, angle deg in the link frame). For the
    upper shaft's crank this is the balancing paper's S_1, the counterweight the machine has."""
    mp = machine.masses.get(link)
    if mp is None:
        return 0.0, 0.0
    m, com = mp.mass, mp.com
    return (float(m * math.hypot(com[0], com[1]) * GCM_PER_KGMM),
            float(math.degrees(math.atan2(com[1], com[0]))))


def paper_workflow(machine: Machine, counterweight: str, *, rpm: float | None = None,
                   step_deg: float = 1.0, factor: float | None = None,
                   insert_depth_mm: float | None = None, wall_mm: float | None = None,
                   basis: BalanceBasis | None = None, result: BalanceResult | None = None
                   ) -> dict:
    """The balancing paper's method on ``counterweight`` (an extra counterweight on the upper
    shaft, usually of static moment 0 in the file): S_add, its static moment from Delta-Q = 0
    along its angle (whatever the file gives it), S_1 the
    static moment the shaft's crank has (:func:`link_static_moment`, all its solids), S_opt =
    |S_1 + S_add| (as vectors: the net static moment of the crank with the extra
    counterweight), and the extra counterweight built ``factor`` times stronger (default: the
    strongest of 3 .. 2.5 that can be built within its ``max_static_moment_gcm``) as a steel
    cup with a lead insert at its radius, clear of the shaft (:func:`counterweight_bore`) by
    ``wall_mm`` (default :data:`~sewmech.design.inserts.WALL_MM`), with the trimming holes
    that bring it back to S_add (:func:`sewmech.design.inserts.build_extra`;
    ``insert_depth_mm`` fixes the hole's depth). ``result``: the :func:`balance` answer of
    ``"delta-q"`` on this counterweight, if already computed.

    Returns a dict (g cm, deg, mm, g) with the :class:`BalanceResult` under ``"result"``;
    ``"build"`` the recipe, or None with ``"build_refused"`` saying why (located, with what to
    change): Delta-Q has no root (``s_add_gcm`` and ``s_opt_gcm`` are then None too), nothing
    is to be added, the shaft's diameter is not known, or no cup within the limits holds the
    margin."""
    from .inserts import WALL_MM, NotBuildable, build_extra

    res = result if result is not None else balance(
        machine, "delta-q", [counterweight], rpm=rpm, step_deg=step_deg, basis=basis)
    cw = res.counterweights[counterweight]
    link = cw["link"]
    s1, a1 = link_static_moment(machine, link)
    out = {"counterweight": counterweight, "link": link, "s1_gcm": s1, "s1_angle_deg": a1,
           "status": res.status, "result": res, "build": None}
    where = f"{machine.file}: [counterweights.{counterweight}]"
    if not res.proposed:
        out.update(s_add_gcm=None, s_add_angle_deg=None, s_opt_gcm=None, s_opt_angle_deg=None)
        out["build_refused"] = (f"{where}: Delta-Q has no root along its angle, so there is no"
                                " S_add and nothing to build")
        return out
    # S_add is the extra counterweight's static moment Delta-Q asks for (>= 0, at its angle),
    # whatever the file gave it: the difference from the file's (1000 g cm in the file, 135
    # proposed) printed as "S_add -865 g cm", a static moment no counterweight has
    add = cw["static_moment_gcm"]
    v1 = s1 * np.exp(1j * math.radians(a1))
    v_opt = v1 + cw["static_moment_gcm"] * np.exp(1j * math.radians(cw["angle_deg"]))
    out.update(s_add_gcm=add, s_add_angle_deg=cw["angle_deg"], s_opt_gcm=float(abs(v_opt)),
               s_opt_angle_deg=float(np.degrees(np.angle(v_opt))))
    if not add > 1e-9 * abs(s1):
        out["build_refused"] = (f"{where}: Delta-Q needs no extra counterweight here (S_add ="
                                " 0): nothing to build")
        return out
    bore, source = counterweight_bore(machine, counterweight)
    if bore is None:
        out["build_refused"] = (f"{where}: the diameter of the shaft it is clamped on is not"
                                " known, so the lead insert's clearance cannot be checked."
                                " Give bore_mm (the shaft's diameter there) in this table")
        return out
    spec = machine.spec.counterweights[counterweight]
    try:
        out["build"] = build_extra(add, cw["radius_mm"], bore_mm=bore,
                                   wall_mm=WALL_MM if wall_mm is None else wall_mm,
                                   depth_mm=insert_depth_mm, factor=factor,
                                   max_s_gcm=spec.max_static_moment_gcm, where=where)
        out["build"]["bore_source"] = source
    except NotBuildable as exc:
        out["build_refused"] = str(exc)
    return out


def counterweight_bore(machine: Machine, counterweight: str) -> tuple[float | None, str]:
    """The diameter (mm) of the shaft a counterweight is clamped on, and where it comes from:
    its table's ``bore_mm``, else the largest solid of its link's ``[masses]`` on the link's
    axis (a cylinder or tube along z through the frame's origin, not a hole) that spans the
    counterweight's plane ``z_mm``; (None, why) when neither gives it."""
    spec = machine.spec.counterweights[counterweight]
    if spec.bore_mm is not None:
        return float(spec.bore_mm), f"bore_mm of [counterweights.{counterweight}]"
    masses = machine.spec.masses.get(spec.link)
    if spec.z_mm is None or masses is None or not masses.solids:
        return None, "no bore_mm, and no solids on the link's axis at z_mm to read it from"
    best = None
    for k, solid in enumerate(masses.solids):
        if solid.type not in ("cylinder", "hollow_cylinder") or solid.hole:
            continue
        ax, base = solid.axis, solid.base
        if ax[0] != 0.0 or ax[1] != 0.0 or ax[2] == 0.0 or base[0] != 0.0 or base[1] != 0.0:
            continue
        z0, z1 = sorted((base[2], base[2] + math.copysign(solid.length, ax[2])))
        if not z0 <= spec.z_mm <= z1:
            continue
        r = solid.radius if solid.type == "cylinder" else solid.r_out
        if best is None or r > best[0]:
            best = (r, k)
    if best is None:
        return None, f"no solid of [masses.{spec.link}] on its axis at z = {spec.z_mm:g} mm"
    return 2.0 * best[0], f"[masses.{spec.link}] solids[{best[1]}] at z = {spec.z_mm:g} mm"


def tradeoff(B: BalanceBasis, n: int = 2048, seed: int = 0, span: float | None = None) -> dict:
    """Designs to choose from: ``n`` sets of static moments spread over the plane of each
    counterweight (a low-discrepancy sample, :func:`spread`, shifted by ``seed``) within
    ``span`` kg mm of 0 (default:
    twice the largest of the file's and the least-RMS answer) and their limits, with every
    balancing figure (computed from the basis, one batch) and which of them are not dominated
    in peak shaking force, peak shaking moment and the larger peak bearing reaction (or the
    torque fluctuation without ``[shaft]``). Returns {"xy": (n, k, 2) kg mm, "figures": dict of
    (n,), "front": (n,) bool, "axes": the three figure names}."""
    k = len(B.counterweights)
    if span is None:
        rms, _, _ = _solve_rms(B)
        span = 2.0 * max(float(np.abs(rms).max()), float(np.abs(B.start).max()), 1e-3)
    z = spread(n, 2 * k, seed) * 2.0 - 1.0
    xy = _within_limits(B, span * z.reshape(n, k, 2))
    fig = B.criteria(xy)
    if B.has_bearings:
        third = np.maximum(fig["bearing_front_peak_N"], fig["bearing_rear_peak_N"])
        axes = ("peak_force_N", "peak_moment_Nm", "bearings_peak_N")
        fig["bearings_peak_N"] = third
    else:
        axes = ("peak_force_N", "peak_moment_Nm", "torque_fluctuation_Nm")
    F = np.column_stack([fig[a] for a in axes])
    return {"xy": xy, "figures": fig, "front": pareto_front(F), "axes": axes}


def spread(n: int, d: int, seed: int = 0) -> np.ndarray:
    """``n`` points in the unit cube of ``d`` dimensions spread evenly (Roberts' R_d sequence:
    x_i = frac(s + i alpha), alpha_j = phi_d^-j with phi_d the root of x^(d+1) = x + 1; ``seed``
    picks the shift s): (n, d). A low-discrepancy sample without importing scipy.stats (about
    1 s), which the report's balancing section would pay in every process."""
    phi = 2.0
    for _ in range(60):  # Newton on x^(d+1) - x - 1 from 2 (converges to the real root > 1)
        phi -= (phi ** (d + 1) - phi - 1.0) / ((d + 1) * phi ** d - 1.0)
    alpha = phi ** -np.arange(1, d + 1)
    shift = np.random.default_rng(seed).random(d)
    return np.mod(shift + np.arange(1, n + 1)[:, None] * alpha[None, :], 1.0)


def pareto_front(F: ArrayLike) -> np.ndarray:
    """Which rows of ``F`` (n, m), all to be minimised, no other row dominates (no worse in
    every column and better in one): (n,) bool."""
    F = np.asarray(F, dtype=float)
    n = len(F)
    keep = np.ones(n, dtype=bool)
    for i in range(n):
        if not keep[i]:
            continue
        dominated = np.all(F <= F[i], axis=1) & np.any(F < F[i], axis=1)
        if dominated.any():
            keep[i] = False
        else:  # i dominates these
            worse = np.all(F[i] <= F, axis=1) & np.any(F[i] < F, axis=1)
            keep[worse] = False
    return keep
