"""Every stitch-formation check of a lockstitch machine, against the published facts of its class.

:func:`check_timing` gathers the checks of the timing (shuttle swing, loop lift, take-up lag
and needle descent, :mod:`sewmech.sewing.timing`) and of the feed (:func:`sewmech.sewing.feed.
check_feed`) that the machine's ``[sewing]`` roles allow; the report and ``sewmech report``
print them. Each is a :class:`~sewmech.sewing.timing.Check`: value, expectation, pass/fail and
source (a key of docs/references.md, :mod:`sewmech.sewing.references`). A machine with masses
and one-sided contacts (a cam under a pad, a roller on a flat) also gets a check per contact
(:func:`check_contacts`): its least force over the turn at the working speed must stay at or
above its ``margin_N``, or the follower leaves its cam.
"""

from __future__ import annotations

from ..engine.machine import Machine
from .feed import check_feed
from .timing import (
    LOOP_LIFT_MM,
    NEEDLE_DESCENT_AT_TAKE_UP_TOP_MM,
    SHUTTLE_SWING_DEG,
    Check,
    loop_lift,
    needle_descent_at_take_up_top,
    roles,
    shuttle_swing,
    take_up_lag_deg,
)


def check_contacts(machine: Machine, params=None, *, opening_speeds: bool = True
                   ) -> list[Check]:
    """A check per one-sided contact of a machine with ``[masses]``: its least force over the
    turn at the working speed and setting, against its ``margin_N`` (N), with the speed above
    which it opens in the expectation (``opening_speeds=False`` leaves that out: the least force
    alone is one force analysis, the opening speed a few dozen)."""
    from ..engine.contacts import contact_margins, one_sided_pairs

    if not machine.spec.masses or not one_sided_pairs(machine):
        return []
    import numpy as np

    P = None if params is None else np.asarray(params, dtype=float)
    out = []
    margins = contact_margins(machine, params=P, opening=opening_speeds)
    for c in margins:
        opens = ("" if not opening_speeds else "; it never opens below"
                 f" {100 * c.rpm:g} rpm" if c.opens_above_rpm is None
                 else f"; it opens above {c.opens_above_rpm:.0f} rpm")
        out.append(Check(f"contact '{c.name}' stays closed at {c.rpm:g} rpm", c.least_force_N,
                         "N", f">= {c.margin_N:g} N over the turn (least at"
                         f" {c.at_phi_deg:.1f} deg{opens})", c.ok,
                         "the force analysis (docs/dynamics.md)"))
    return out


def check_loads_take_energy_out(machine: Machine, params=None) -> list[Check]:
    """A check on a machine with process loads: over a turn at the working speed and setting
    they must take energy out of the machine (a process resists the machine: the presser foot
    gives back what it takes, the fabric and the thread take), or their windows and conditions
    do not follow the process. Tolerance: 1e-6 of the peak motor power (the grid's mean of a
    conservative load's power is not exactly 0)."""
    if not machine.spec.loads:
        return []
    import math

    import numpy as np

    from ..engine.dynamics import inverse_dynamics

    phi = np.radians(np.arange(0.0, 360.0, 0.5))
    r = inverse_dynamics(machine, phi, params=None if params is None else np.asarray(params))
    put_in = float(np.mean(r.external_power)) * 1e-3  # W
    tol = 1e-6 * float(np.abs(r.input_power).max()) * 1e-3
    ok = put_in <= tol
    rpm = r.kin.omega_shaft.reshape(-1)[0] * 30.0 / math.pi
    return [Check(f"process loads take energy out at {rpm:g} rpm", -put_in, "W",
                  ">= 0 (what they take over a turn; below 0 they would drive the machine:"
                  " give them conditions that follow the process)", ok,
                  "the energy balance (docs/dynamics.md)")]


def check_timing(machine: Machine, params=None, *, opening_speeds: bool = True
                 ) -> list[Check]:
    """The stitch-formation checks that the machine's roles allow, as numbers with pass/fail,
    and the one-sided contacts' (:func:`check_contacts`)."""
    s = roles(machine)
    out: list[Check] = []
    if s.shuttle_link is not None:
        sw = shuttle_swing(machine, params).swing_deg
        lo, hi = SHUTTLE_SWING_DEG
        out.append(Check("shuttle swing", sw, "deg", f"{lo:g}-{hi:g}", lo <= sw <= hi,
                         "[EC-household-machine] (JA household oscillating shuttle)"))
    if s.shuttle_point is not None:
        ll = loop_lift(machine, params)
        lo, hi = LOOP_LIFT_MM
        out.append(Check("loop lift when the shuttle point meets the needle", ll.rise_mm, "mm",
                         f"{lo:g}-{hi:g}", lo <= ll.rise_mm <= hi,
                         "[Melnikov-seamstress] (Soviet household machines)"))
        out.append(Check("shuttle point above the needle eye at the meeting",
                         ll.point_above_eye_mm, "mm", "> 0 (point above the eye)",
                         ll.point_above_eye_mm > 0.0, "[NAVEDTRA-14218] (Singer 31-15: 1.6 mm)"))
    if s.take_up_eye is not None:
        lag = take_up_lag_deg(machine, params)
        out.append(Check("take-up eye top after needle top", lag, "deg", "> 0 (lags)", lag > 0.0,
                         "[Thread-holder-timing] (household machines)"))
        d = needle_descent_at_take_up_top(machine, params)
        lo, hi = NEEDLE_DESCENT_AT_TAKE_UP_TOP_MM
        out.append(Check("needle descent when the take-up eye is at its top", d, "mm",
                         f"{lo:g}-{hi:g} (a few mm, about 1/8 in)", lo <= d <= hi,
                         "[Thread-holder-timing] (household machines: about 1/8 in)"))
    if s.feed_dog is not None and s.regulator is not None:
        out += check_feed(machine, params)
    out += check_contacts(machine, params, opening_speeds=opening_speeds)
    out += check_loads_take_energy_out(machine, params)
    return out
