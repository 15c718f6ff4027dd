"""The machine file's physics checked against the compiled machine's names, when it is compiled:
the process loads' conditions (:mod:`sewmech.engine.channels`), the springs and the friction
(:mod:`sewmech.engine.springs`, :mod:`sewmech.engine.friction`). Each mistake is a
:class:`MachineFileError` naming the file, the table and the key.
"""

from __future__ import annotations

import difflib
from collections.abc import Sequence

from .channels import KINDS, THREAD_CHANNELS, channel_examples, resolve_channel
from .errors import MachineFileError
from .spec import LoadSpec, SpringSpec, TorsionSpringSpec


def check_conditions(machine_name: str, file: str, loads: Sequence[LoadSpec], points, links,
                     variables, has_thread: bool) -> None:
    """Raise :class:`MachineFileError` (file, load, ``when``) for a condition that names a
    channel the machine does not have, or asks the rate of a channel that has none here."""
    for k, load in enumerate(loads):
        table = f'loads[{k}] "{load.name}"'
        for j, c in enumerate(load.when):
            ref = resolve_channel(c.channel, points, links, variables, has_thread)
            if ref is None:
                known = [f"p_{p}_{x}" for p in points for x in "xy"] + list(THREAD_CHANNELS)
                close = difflib.get_close_matches(c.channel, known, n=3)
                why = (" (thread channels need a [thread] table)"
                       if c.channel in THREAD_CHANNELS else "")
                raise MachineFileError(file, table, f"when[{j}].channel", f"machine"
                                       f" '{machine_name}' has no channel '{c.channel}'{why}",
                                       f"Did you mean {', '.join(close)}?" if close else
                                       f"Channels look like {channel_examples(points)}")
            if (c.rising or c.falling) and ref.kind != "thread" and KINDS[ref.kind][1] is None:
                raise MachineFileError(file, table, f"when[{j}]", f"'{c.channel}' is an"
                                       " acceleration: sewmech has no rate of it to read",
                                       "Use the velocity's channel with above or below")


def check_springs(machine_name: str, file: str, springs: Sequence[SpringSpec],
                  torsion: Sequence[TorsionSpringSpec], links: Sequence[str],
                  points: Sequence[str], point_links: dict, pairs: Sequence) -> None:
    """Raise :class:`MachineFileError` (file, spring, key) for a spring that names a link or a
    point the machine lacks, an end that is not on its link, both ends on one link, or a
    torsion spring at a pair that is not a revolute pair."""
    seen = set()
    for k, s in enumerate(springs):
        table = f'springs[{k}] "{s.name}"'
        if s.name in seen:
            raise MachineFileError(file, table, "name", f"a second spring named '{s.name}'",
                                   "Give every spring its own name")
        seen.add(s.name)
        for e in range(2):
            link, point = s.links[e], s.points[e]
            if link not in links:
                close = difflib.get_close_matches(link, list(links), n=3)
                raise MachineFileError(file, table, f"links[{e}]", f"machine '{machine_name}'"
                                       f" has no link '{link}'",
                                       f"Did you mean {', '.join(close)}?" if close else
                                       f"Links: {', '.join(links)}")
            if point not in points:
                close = difflib.get_close_matches(point, list(points), n=3)
                raise MachineFileError(file, table, f"points[{e}]", f"machine '{machine_name}'"
                                       f" has no point '{point}'",
                                       f"Did you mean {', '.join(close)}?" if close else
                                       "Name a point of [points] or of a unit")
            if link not in point_links[point]:
                on = [p for p in points if link in point_links.get(p, ())]
                raise MachineFileError(file, table, f"points[{e}]", f"'{point}' is not a point"
                                       f" of '{link}' (it is on:"
                                       f" {', '.join(point_links[point])})",
                                       f"The points of '{link}': {', '.join(on) or 'none'}")
        if s.links[0] == s.links[1]:
            raise MachineFileError(file, table, "links", f"both ends are on '{s.links[0]}': a"
                                   " spring between two points of one link only stresses the"
                                   " link, it puts no force on the mechanism",
                                   "Join two different links (or a link and the frame)")
    revolute = {p.name: p for p in pairs if p.kind == "revolute"}
    for k, s in enumerate(torsion):
        table = f'torsion_springs[{k}] "{s.name}"'
        if s.name in seen:
            raise MachineFileError(file, table, "name", f"a second spring named '{s.name}'",
                                   "Give every spring its own name")
        seen.add(s.name)
        if s.pair not in revolute:
            others = [p.name for p in pairs if p.name == s.pair]
            what = (f"'{s.pair}' is a {next(p.kind for p in pairs if p.name == s.pair)} pair:"
                    " a torsion spring sits at a pin" if others else
                    f"machine '{machine_name}' has no pair '{s.pair}'")
            close = difflib.get_close_matches(s.pair, list(revolute), n=3)
            raise MachineFileError(file, table, "pair", what,
                                   f"Did you mean {', '.join(close)}?" if close else
                                   "`sewmech check MACHINE --pairs` lists the revolute pairs")


def check_friction(machine_name: str, file: str, friction, pairs: Sequence) -> None:
    """Raise :class:`MachineFileError` for a ``[friction.pairs]`` entry naming no pair of the
    machine, or a pin radius given for a pair that has no pin."""
    if friction is None:
        return
    kinds = {p.name: p.kind for p in pairs if p.kind != "driver"}
    for name, pf in friction.pairs.items():
        if name not in kinds:
            close = difflib.get_close_matches(name, list(kinds), n=3)
            raise MachineFileError(file, "friction.pairs", name, f"machine '{machine_name}' has"
                                   f" no pair '{name}'",
                                   f"Did you mean {', '.join(close)}?" if close else
                                   "`sewmech check MACHINE --pairs` lists them")
        if pf.pin_radius_mm is not None and kinds[name] != "revolute":
            raise MachineFileError(file, f"friction.pairs.{name}", "pin_radius_mm", f"'{name}'"
                                   f" is a {kinds[name]} pair, which has no pin",
                                   "Give pin_radius_mm only for revolute pairs")
