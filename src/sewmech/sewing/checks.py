"""Every stitch-formation check of a lockstitch machine, against the published facts of its class.

:func:`check_timing` gathers the checks of the timing (shuttle swing, loop lift, take-up lag
and needle descent, :mod:`sewmech.sewing.timing`) and of the feed (:func:`sewmech.sewing.feed.
check_feed`) that the machine's ``[sewing]`` roles allow; the report and ``sewmech report``
print them. Each is a :class:`~sewmech.sewing.timing.Check`: value, expectation, pass/fail and
source (a key of docs/references.md, :mod:`sewmech.sewing.references`).
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


def check_timing(machine: Machine, params=None) -> list[Check]:
    """The stitch-formation checks that the machine's roles allow, as numbers with pass/fail."""
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
    return out
