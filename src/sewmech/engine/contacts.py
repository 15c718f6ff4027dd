"""One-sided contacts: the least force each keeps over the turn, and the speed at which it opens.

A one-sided contact (a cam under a pad, a roller on one flat face: ``one_sided = true`` in a loop
unit's ``contacts``) can only push. Its force N must stay above its ``margin_N`` over the whole
turn at the working speed, or the follower leaves its cam and the motion the kinematics assumes
is not the machine's. :func:`contact_margins` gives, for every one-sided contact, its least
force over the turn and where, and the speed at which it first opens (N reaches 0).

The opening speed: at a constant shaft speed omega the accelerations grow with omega^2, the
velocities with omega; gravity, springs and position-dependent loads do not change. So at each
shaft angle N = a + b omega + c omega^2 exactly for a machine without friction and without
velocity-dependent loads (b from dampers alone), and nearly so with them. The coefficients are
fitted per angle from three speeds (once, 1.5 and twice the working speed); the least speed at
which some angle's N reaches 0 is then bracketed and found by Brent's method on the full
analysis (friction, the loads' smooth signs and all), the least force over the turn on a grid of
``n_phi`` angles, looked for again on a fine grid across the steps around the grid's least.

Units: forces N, speeds rev/min (``*_rpm``), angles deg at the edges.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .kinematics import MIN_RPM
from .machine import Machine

#: the fastest speed sewmech looks for an opening at, as a multiple of the working speed
OPENING_SEARCH_FACTOR = 100.0


@dataclass(frozen=True)
class ContactMargin:
    """A one-sided contact at the working speed: its least force (N) over the turn and the
    shaft angle where (deg), its margin, whether the least force keeps it (``ok``), and the
    speed above which it opens (rev/min; None: not below ``OPENING_SEARCH_FACTOR`` times the
    working speed, nor below 100,000 rpm)."""

    name: str
    margin_N: float
    least_force_N: float
    at_phi_deg: float
    opens_above_rpm: float | None
    rpm: float

    @property
    def ok(self) -> bool:
        return self.least_force_N >= self.margin_N

    def to_json(self) -> dict:
        return {"pair": self.name, "least_force_N": self.least_force_N,
                "at_phi_deg": self.at_phi_deg, "margin_N": self.margin_N, "ok": self.ok,
                "opens_above_rpm": self.opens_above_rpm}


def one_sided_pairs(machine: Machine) -> list:
    return [p for p in machine.pairs if p.one_sided]


def _margin_of(machine: Machine, name: str) -> float:
    for u in machine.spec.units:
        for c in getattr(u, "contacts", ()) or ():
            pname = f"{u.name}.{c.cam}" if hasattr(c, "cam") else f"{c.slot}.slot"
            if pname == name:
                return c.margin_N
    return 1.0


#: the least force of a contact is looked for again on this many angles across the grid
#: steps on both sides of the grid's least (a load that starts or stops there makes the force
#: jump, so no curve is fitted through the grid values)
LOCAL_POINTS = 81


def _least(force_at, values: np.ndarray, phi_deg: np.ndarray) -> tuple[float, float]:
    """Least value of a periodic sampled curve and its angle (deg): the grid's least, looked
    for again by evaluating ``force_at(phi_deg array)`` on LOCAL_POINTS angles across the two
    grid steps around it."""
    n = values.shape[0]
    k = int(np.nanargmin(values))
    h = 360.0 / n
    local = phi_deg[k] + np.linspace(-h, h, LOCAL_POINTS)
    fine = force_at(np.mod(local, 360.0))
    j = int(np.nanargmin(fine))
    if fine[j] < values[k]:
        return float(fine[j]), float(local[j] % 360.0)
    return float(values[k]), float(phi_deg[k])


def contact_margins(machine: Machine, *, rpm: float | None = None,
                    inputs: Mapping[str, float] | None = None, params=None, loads=None,
                    gravity: bool = True, n_phi: int = 360, opening: bool = True
                    ) -> list[ContactMargin]:
    """Every one-sided contact's least force over the turn at ``rpm`` (default: the machine
    file's working speed) and setting ``inputs`` (rad; default: the working setting), and the
    speed above which it opens (see the module doc). One design (``params``); ``loads`` and
    ``gravity`` as for :func:`~sewmech.dynamics.inverse_dynamics`. ``opening=False``: the
    least forces alone (one force analysis; ``opens_above_rpm`` None)."""
    from .dynamics import DynamicsPlan

    pairs = one_sided_pairs(machine)
    if not pairs:
        return []
    rpm0 = float(machine.spec.speed.rpm if rpm is None else rpm)
    phi = np.arange(n_phi) * (2.0 * math.pi / n_phi)
    phi_deg = np.degrees(phi)
    plans: dict[float, DynamicsPlan] = {}

    def forces(r: float) -> np.ndarray:
        """(n_phi, n_pairs): the contact forces at r rev/min."""
        plan = plans.get(r)
        if plan is None:
            plan = plans[r] = DynamicsPlan(machine, phi, rpm=r, loads=loads, gravity=gravity)
        res = plan(params, inputs=inputs)
        return np.stack([np.asarray(res.pair(p.name))[..., 0].reshape(-1) for p in pairs],
                        axis=-1)

    f1 = forces(rpm0)
    out = []

    def local(j: int):
        def force_at(deg: np.ndarray) -> np.ndarray:
            plan = DynamicsPlan(machine, np.radians(deg), rpm=rpm0, loads=loads,
                                gravity=gravity)
            return np.asarray(plan(params, inputs=inputs).pair(pairs[j].name))[..., 0]
        return force_at

    if not opening:
        for j, p in enumerate(pairs):
            least, at = _least(local(j), f1[:, j], phi_deg)
            out.append(ContactMargin(p.name, _margin_of(machine, p.name), least, at, None,
                                     rpm0))
        return out
    speeds = (rpm0, 1.5 * rpm0, 2.0 * rpm0)  # (none below the working speed: it may be the
    # slowest sewmech takes)
    fit = [f1 if s == rpm0 else forces(s) for s in speeds]
    w = np.array([s * math.pi / 30.0 for s in speeds])
    V = np.stack([np.ones(3), w, w * w], axis=1)
    coef = np.linalg.solve(V, np.stack(fit, axis=0).reshape(3, -1)).reshape(3, n_phi, -1)
    top = min(OPENING_SEARCH_FACTOR * rpm0, 1e5)
    for j, p in enumerate(pairs):
        least, at = _least(local(j), f1[:, j], phi_deg)
        opens = None
        guess = _first_root(coef[:, :, j], top * math.pi / 30.0)
        def least_at(r: float, j: int = j) -> float:
            return float(forces(r)[:, j].min())

        if least <= 0.0:
            opens = _bisect_down(least_at, rpm0)
        elif guess is not None:
            opens = _refine(least_at, rpm0, guess * 30.0 / math.pi, top)
        out.append(ContactMargin(p.name, _margin_of(machine, p.name), least, at, opens, rpm0))
    return out


def _first_root(c: np.ndarray, w_top: float) -> float | None:
    """The least omega in (0, w_top] at which a + b w + c w^2 reaches 0 at some angle (c: (3,
    n_phi)), or None."""
    a, b, q = c
    best = math.inf
    for ai, bi, qi in zip(a, b, q, strict=True):
        if ai <= 0.0:
            return 0.0
        if abs(qi) < 1e-300:
            roots = [-ai / bi] if bi != 0.0 else []
        else:
            disc = bi * bi - 4.0 * qi * ai
            if disc < 0.0:
                continue
            s = math.sqrt(disc)
            roots = [(-bi - s) / (2.0 * qi), (-bi + s) / (2.0 * qi)]
        for r in roots:
            if 0.0 < r < best:
                best = r
    return best if best <= w_top else None


def _refine(g, rpm0: float, guess: float, top: float) -> float | None:
    """The least speed above rpm0 where g (the least force over the turn) reaches 0, near
    ``guess``: bracketed by stepping, then Brent's method."""
    from scipy.optimize import brentq

    lo = rpm0
    hi = max(guess, rpm0 * 1.001)
    while g(hi) > 0.0:
        lo, hi = hi, hi * 1.25
        if hi > top:
            return None
    # the fit may overshoot: come down while the force at the lower end is still <= 0
    while g(lo) <= 0.0 and lo * 0.8 >= MIN_RPM:
        hi, lo = lo, lo * 0.8
    return float(brentq(g, lo, hi, xtol=1e-9 * hi, rtol=1e-12))


def _bisect_down(g, rpm0: float) -> float | None:
    """A contact already open at rpm0: the speed below it where it closes again (g > 0), or
    None if it is open down to a crawl (gravity or a load alone opens it)."""
    from scipy.optimize import brentq

    hi, lo = rpm0, rpm0
    while g(lo) <= 0.0:
        hi, lo = lo, lo * 0.5
        if lo < max(1e-3 * rpm0, MIN_RPM):
            return None
    return float(brentq(g, lo, hi, xtol=1e-9 * hi, rtol=1e-12))
