"""Extremes of any channel over the cycle, and dead centres, located to 1e-9 rad of crank angle.

The derivative of a channel with respect to the shaft angle is the kinematics' own analytic rate
evaluated at omega = 1 rad/s (then d/dt = d/dphi): position -> velocity, angle -> angular
velocity, slider displacement -> its rate. Sign changes of that derivative on the grid of the
design's shared evaluation (:mod:`sewmech.engine.evaluation`) bracket every stationary point;
Newton's method on the exact kinematics, kept inside the bracket, refines each.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import MachineFileError
from .evaluation import evaluation
from .kinematics import kinematics
from .machine import Machine
from .results import CHANNEL_KINDS


@dataclass(frozen=True)
class Extremum:
    """A stationary point of a channel over the cycle.

    Attributes
    ----------
    kind : str
        "max" or "min" (local).
    phi : float
        Shaft angle, rad, in [phi0, phi0 + 2 pi).
    value : float
        Channel value there (unit of the channel).
    """

    kind: str
    phi: float
    value: float

    @property
    def phi_deg(self) -> float:
        return math.degrees(self.phi)


@dataclass(frozen=True)
class ExtremesResult:
    """All local extrema of one channel over one revolution, plus the global max and min."""

    channel: str
    unit: str
    extrema: tuple[Extremum, ...]

    @property
    def maximum(self) -> Extremum:
        return max((e for e in self.extrema if e.kind == "max"), key=lambda e: e.value)

    @property
    def minimum(self) -> Extremum:
        return min((e for e in self.extrema if e.kind == "min"), key=lambda e: e.value)


def _derivative_channel(name: str) -> str:
    kind, _, rest = name.partition("_")
    if kind not in CHANNEL_KINDS or CHANNEL_KINDS[kind][2] is None:
        raise ValueError(f"extremes of '{name}' need its derivative, which sewmech does not"
                         " compute (channels of kind a_, epsilon_ and qdd_ have none)")
    return f"{CHANNEL_KINDS[kind][2]}_{rest}"


def extremes(
    machine: Machine,
    channel: str,
    *,
    params=None,
    inputs=None,
    n_grid: int = 720,
    phi0: float = 0.0,
    xtol: float = 1e-12,
) -> ExtremesResult:
    """Local maxima and minima of a channel over one revolution of the shaft.

    Parameters
    ----------
    machine : Machine
    channel : str
        Channel name, e.g. ``"p_needle_y"``, ``"theta_rocker"``, ``"q_needle_bar"``.
    params, inputs
        One design (as for :func:`sewmech.kinematics`); batches are not accepted here.
    n_grid : int
        Grid of the bracketing scan; extrema closer than 2 pi / n_grid may merge.
    phi0 : float
        Start of the revolution scanned, rad (the extrema's angles are in [phi0, phi0 + 2 pi)).
    xtol : float
        Absolute tolerance on the crank angle, rad (default 1e-12; the guarantee is 1e-9).

    Returns
    -------
    ExtremesResult
        Extrema sorted by crank angle; positions where the mechanism fails raise.

    The design's shared :func:`~sewmech.engine.evaluation.evaluation` is read: the zeros of
    the channel's derivative are bracketed on its grid and refined on the exact kinematics.
    """
    deriv = _derivative_channel(channel)
    ev = evaluation(machine, params, inputs, n_grid)
    key = ("extremes", channel, float(phi0), float(xtol))
    if key not in ev.memo:
        _, unit = ev.grid.channel(channel)
        found = []
        for root in ev.roots(deriv, 0.0, phi0=phi0, xtol=xtol):
            r = ev.at([root.phi], **_selection(channel))
            found.append(Extremum("max" if root.direction < 0 else "min", float(root.phi),
                                  float(r.channel(channel)[0][0])))
        ev.memo[key] = ExtremesResult(channel, unit, tuple(found))
    return ev.memo[key]


def _selection(channel: str) -> dict:
    """The outputs a channel needs: an exact evaluation solves only the units behind them."""
    kind, _, rest = channel.partition("_")
    if kind in ("p", "v", "a"):
        return dict(points=[rest.rpartition("_")[0]], links=[], variables=[])
    if kind in ("theta", "omega", "epsilon"):
        return dict(points=[], links=[rest], variables=[])
    return dict(points=[], links=[], variables=[rest])


def dead_centres(machine: Machine, unit: str, **kw) -> ExtremesResult:
    """Dead centres of a unit: where its output stands still (extremes of the output).

    Output of an ``rrp`` or ``rpr`` unit: its slider variable; of an ``rrr`` dyad: the angle of
    its second link (the rocker); of a ``loop``: its first unknown link.
    """
    try:
        ui = machine.unit_names.index(unit)
    except ValueError:
        raise KeyError(f"machine '{machine.name}' has no unit '{unit}'") from None
    spec = machine.spec.units[ui]
    if spec.type in ("rrp", "rpr"):
        ch = f"q_{spec.variable or spec.name}"
    elif spec.type == "rrr":
        ch = f"theta_{spec.links[1]}"
    elif spec.type == "loop" and spec.unknown_links_deg:
        ch = f"theta_{next(iter(spec.unknown_links_deg))}"
    else:
        raise ValueError(f"unit '{unit}' ({spec.type}) has no output that can stand still")
    return extremes(machine, ch, **kw)


@dataclass(frozen=True)
class Crossing:
    """Where a channel passes a level: shaft angle (rad) and direction (+1 rising, -1 falling)."""

    phi: float
    direction: int

    @property
    def phi_deg(self) -> float:
        return math.degrees(self.phi)


def crossings(
    machine: Machine,
    channel: str,
    level: float,
    *,
    params=None,
    inputs=None,
    n_grid: int = 720,
    phi0: float = 0.0,
    xtol: float = 1e-12,
) -> tuple[Crossing, ...]:
    """Shaft angles in [phi0, phi0 + 2 pi) where ``channel`` equals ``level`` (its unit).

    Sign changes of channel - level on the design's shared evaluation bracket each crossing;
    it is refined on the exact kinematics to ``xtol`` rad. Angle channels are compared as
    returned (in (-pi, pi]); use a point or variable channel for levels near the wrap.
    """
    ev = evaluation(machine, params, inputs, n_grid)
    return tuple(Crossing(r.phi, r.direction)
                 for r in ev.roots(channel, level, phi0=phi0, xtol=xtol))


@dataclass(frozen=True)
class ReferenceCheck:
    """Whether the file's angle convention holds: at ``reference_phi_deg`` the reference event
    happens (``[convention] reference_point``/``reference_extreme`` or
    ``reference_link``/``reference_angle_deg``).

    status is "ok", "mismatch" or "unchecked" (the file does not say what makes the event
    checkable); ``found_deg`` is where the event happens (None when unchecked), ``text`` one
    sentence for people.
    """

    status: str
    found_deg: float | None
    text: str


#: how far (deg) the reference event may be from ``reference_phi_deg``
REFERENCE_TOL_DEG = 0.01


def check_reference(machine: Machine, *, params=None) -> ReferenceCheck:
    """Locate the reference event of the file's convention and compare it with
    ``reference_phi_deg`` (to :data:`REFERENCE_TOL_DEG`)."""
    c = machine.spec.convention
    ref = c.reference_phi_deg
    if c.reference_point is not None:
        axis = "y" if c.reference_extreme in ("top", "bottom") else "x"
        res = extremes(machine, f"p_{c.reference_point}_{axis}", params=params)
        big = c.reference_extreme in ("top", "right")
        try:
            found = (res.maximum if big else res.minimum).phi_deg
        except ValueError:  # the point does not move along that axis
            return ReferenceCheck("mismatch", None, f"'{c.reference_point}' has no"
                                  f" {c.reference_extreme} position: it does not move along"
                                  f" {axis}")
        what = f"{c.reference_point} at its {c.reference_extreme}"
    elif c.reference_link is not None:
        r = kinematics(machine, np.radians([ref]), params=params, links=[c.reference_link],
                       points=[], variables=[])
        theta = math.degrees(float(r.link(c.reference_link).theta[0]))
        off = (theta - c.reference_angle_deg + 180.0) % 360.0 - 180.0
        found = ref - off  # exact for a link turning at the shaft's rate
        what = f"link {c.reference_link} at {c.reference_angle_deg:g} deg"
        if abs(off) <= REFERENCE_TOL_DEG:
            return ReferenceCheck("ok", ref, f"{what} at phi = {ref:g} deg: checked")
        return ReferenceCheck("mismatch", found, f"reference_phi_deg = {ref:g} but there the"
                              f" link {c.reference_link} is at {theta % 360.0:.6g} deg, not"
                              f" {c.reference_angle_deg:g} deg")
    else:
        return ReferenceCheck("unchecked", None, "not checked: the file does not say what makes"
                              " the event checkable (add reference_point and reference_extreme,"
                              " or reference_link and reference_angle_deg, to [convention])")
    off = (found - ref + 180.0) % 360.0 - 180.0
    if abs(off) <= REFERENCE_TOL_DEG:
        return ReferenceCheck("ok", found, f"{what} at phi = {found:.6g} deg: checked")
    return ReferenceCheck("mismatch", found, f"reference_phi_deg = {ref:g} but {what} is at"
                          f" phi = {found % 360.0:.6g} deg")


def require_reference(machine: Machine) -> ReferenceCheck:
    """:func:`check_reference`, raising :class:`~sewmech.errors.MachineFileError` at
    ``[convention] reference_phi_deg`` (with the angle or phase change that fixes it) when the
    convention does not hold. ``sewmech check`` and the report call it."""
    ref = check_reference(machine)
    if ref.status != "mismatch":
        return ref
    conv = machine.spec.convention
    if ref.found_deg is not None:
        off = (ref.found_deg - conv.reference_phi_deg + 180.0) % 360.0 - 180.0
        hint = (f"Set reference_phi_deg = {ref.found_deg % 360.0:.6g}, or change the phase_deg"
                f" of every crank on the shaft by {off:+.6g} deg")
    else:
        hint = "Correct [convention]"
    raise MachineFileError(machine.file, "convention", "reference_phi_deg", ref.text, hint)
