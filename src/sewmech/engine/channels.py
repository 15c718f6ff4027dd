"""Channels of the motion that process loads' conditions read (docs/machine-files.md).

A channel is a kinematics channel (``p_POINT_x``, ``v_...``, ``theta_LINK``, ``q_VARIABLE``,
...: docs/notation.md) or a thread channel (``thread.take_up_mm``: the length of the needle
thread between the ``[thread] take_up`` guides). :func:`resolve_channel` turns a name into
indices once; :func:`channel_values` reads a channel and its rate from the kinematics kernel's
arrays. Units: the channel's own (mm, rad, their rates).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .spec import FRAME

#: the thread channels a condition may read (with a ``[thread]`` table)
THREAD_CHANNELS = ("thread.take_up_mm",)
#: channel kind -> (kernel array of its value, of its rate)
KINDS = {"p": ("P", "V"), "v": ("V", "A"), "a": ("A", None), "theta": ("TH", "OM"),
          "omega": ("OM", "EP"), "epsilon": ("EP", None), "q": ("S", "SD"), "qd": ("SD", "SDD"),
          "qdd": ("SDD", None)}

@dataclass(frozen=True)
class ChannelRef:
    """A channel resolved to kernel arrays: ``kind`` (p, v, ..., or thread), the index of its
    point, link or variable, and its component (0 x, 1 y) for point channels."""

    name: str
    kind: str
    index: int = -1
    comp: int = 0


def resolve_channel(name: str, points: Sequence[str], links: Sequence[str],
                    variables: Sequence[str], has_thread: bool) -> ChannelRef | None:
    """The channel ``name`` of a machine with these points, links and joint variables, or
    None if it has no such channel."""
    if name in THREAD_CHANNELS:
        return ChannelRef(name, "thread") if has_thread else None
    kind, _, rest = name.partition("_")
    if kind not in KINDS or not rest:
        return None
    if kind in ("p", "v", "a"):
        pt, _, comp = rest.rpartition("_")
        if comp not in ("x", "y") or pt not in points:
            return None
        return ChannelRef(name, kind, list(points).index(pt), "xy".index(comp))
    if kind in ("theta", "omega", "epsilon"):
        if rest not in links or rest == FRAME:
            return None
        return ChannelRef(name, kind, list(links).index(rest))
    if rest not in variables:
        return None
    return ChannelRef(name, kind, list(variables).index(rest))


def channel_examples(points: Sequence[str]) -> str:
    ex = [f"p_{p}_y" for p in list(points)[:2]]
    return ", ".join(ex + ["theta_LINK", "q_VARIABLE", *THREAD_CHANNELS])


def channel_values(ref: ChannelRef, a: dict[str, np.ndarray], thread=None
                   ) -> tuple[np.ndarray, np.ndarray | None]:
    """A channel's values and rates (D, n_phi) from the kinematics kernel arrays ``a`` (the
    rate None where sewmech has none); ``thread``: a :class:`ThreadSection` for thread
    channels."""
    if ref.kind == "thread":
        return thread.length_and_rate(a["P"], a["V"])
    val, rate = KINDS[ref.kind]
    point = ref.kind in ("p", "v", "a")

    def get(key: str) -> np.ndarray:
        return a[key][:, :, ref.index, ref.comp] if point else a[key][:, :, ref.index]

    return get(val), (get(rate) if rate is not None else None)


