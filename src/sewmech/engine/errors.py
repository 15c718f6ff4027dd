"""Errors that say where and what to do.

Every error sewmech raises on purpose is a :class:`SewmechError`. Its text reads
``<where>: <what is wrong>. <what to do>``, where *where* is a file with its table and key, a
command-line option, a parameter of a design, an output path, or a unit at a shaft angle. The
command line prints it as ``error: <text>`` and exits with code 2 (docs/errors.md).
"""

from __future__ import annotations


class SewmechError(Exception):
    """Base class of every error sewmech raises on purpose.

    Attributes
    ----------
    where : str
        The location: a file with its table and key, an option, a parameter, a path.
    message : str
        What is wrong.
    hint : str
        What to do about it ("" when the message says it already).
    """

    def __init__(self, where: str, message: str | None = None, hint: str = ""):
        if message is None:  # SewmechError("text"): the text says where itself
            where, message = "", where
        self.where = where
        self.message = message
        self.hint = hint
        super().__init__(_join(where, message, hint))


def _join(where: str, message: str, hint: str) -> str:
    text = f"{where}: {message}" if where else message
    if hint:
        text = (text + " " if text.endswith(("?", "!")) else text.rstrip(".") + ". ") + hint
    return text


class MachineFileError(SewmechError, ValueError):
    """A machine file (or a load file) is malformed or inconsistent.

    Attributes
    ----------
    file : str
        The file (or ``<string>`` for text loaded from memory).
    table : str
        The TOML table, e.g. ``units[2] "take_up"`` or ``points.D``.
    key : str
        The key inside that table ("" when the table itself is at fault).
    """

    def __init__(self, file: str, table: str, key: str, message: str, hint: str = ""):
        self.file = file
        self.table = table
        self.key = key
        if table or key:
            where = f"[{table}]" if table else "(top level)"
            if key:
                where += f" {key}"
            where = f"{file}: {where}"
        else:  # the file as a whole
            where = file
        super().__init__(where, message, hint)


class OptionError(SewmechError, ValueError):
    """A command-line option (or a library argument) has a value sewmech cannot use.

    ``option`` is the option as typed (``--rpm``) or the argument's name (``rpm``).
    """

    def __init__(self, option: str, message: str, hint: str = ""):
        self.option = option
        super().__init__(option, message, hint)


class ParameterError(SewmechError, ValueError):
    """A parameter value of a design is not a finite number inside its domain.

    Attributes
    ----------
    parameter : str
        The parameter's name as ``Machine.parameters`` uses it (``dyad.length1``).
    design : tuple[int, ...]
        Index of the design in the batch (``()`` for a single design).
    value : float
        The offending value, internal units (mm, rad).
    """

    def __init__(self, parameter: str, design: tuple, value: float, message: str,
                 hint: str = ""):
        self.parameter = parameter
        self.design = design
        self.value = value
        at = f" of design {design}" if design else ""
        super().__init__(f"parameter '{parameter}'{at}", message, hint)


class AnalysisError(SewmechError, ValueError):
    """An analysis cannot be done for this machine: what it lacks is named (no masses for the
    speed fluctuation, a motor too weak to carry the cycle, no forces at all)."""


class OutputError(SewmechError, OSError):
    """An output path cannot be written safely (it is a file, not writable, holds files that
    sewmech did not write, or another run is writing into it)."""

    def __init__(self, path: str, message: str, hint: str = ""):
        self.path = path
        super().__init__(path, message, hint)


class AssemblyError(SewmechError):
    """The mechanism cannot be assembled (or moved through) at some crank angle.

    Attributes
    ----------
    unit : str
        Name of the unit that failed.
    phi_deg : float
        Shaft angle of the first failure in march order, degrees, in the machine's convention.
    design : tuple[int, ...]
        Index of the failing design in the batch (``()`` for a single design).
    reason : str
        What went wrong.
    file : str
        The machine file ("" when unknown).
    ranges_deg : list[tuple[float, float]]
        The evaluated shaft angles (deg) over which this unit fails for this design, as closed
        ranges of consecutive evaluated angles.
    """

    def __init__(self, unit: str, phi_deg: float, design: tuple, reason: str, hint: str = "",
                 file: str = "", ranges_deg: list | None = None):
        self.unit = unit
        self.phi_deg = phi_deg
        self.design = design
        self.reason = reason
        self.file = file
        self.ranges_deg = list(ranges_deg or [])
        at = f"design {design}, " if design else ""
        where = f"{file}: " if file else ""
        where += f"unit '{unit}' at {at}shaft angle phi = {phi_deg:.6g} deg"
        message = reason
        if len(self.ranges_deg) > 1 or (self.ranges_deg and
                                        self.ranges_deg[0][0] != self.ranges_deg[0][1]):
            message += f" (fails over phi {format_ranges(self.ranges_deg)} deg)"
        super().__init__(where, message, hint)


class ConvergenceError(AssemblyError):
    """The loop solver did not converge (names the loop unit, the angle and the residual)."""


def format_ranges(ranges: list, limit: int = 4) -> str:
    """[(10, 20), (30, 30)] -> '10..20, 30' (at most ``limit`` ranges, then '...')."""
    parts = [f"{a:g}" if a == b else f"{a:g}..{b:g}" for a, b in ranges[:limit]]
    if len(ranges) > limit:
        parts.append(f"and {len(ranges) - limit} more")
    return ", ".join(parts)


def name_index(names: tuple[str, ...], name: str, what: str, owner: str = "") -> int:
    """Position of ``name`` in ``names``; a KeyError that suggests close names otherwise.

    ``what`` names the kind ("point", "link", ...), ``owner`` what was searched (e.g.
    "machine 'jb1-3'"), both for the message.
    """
    try:
        return names.index(name)
    except ValueError:
        import difflib

        close = difflib.get_close_matches(str(name), names, n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        where = f"{owner} has no" if owner else "no"
        raise KeyError(f"{where} {what} '{name}'{hint}") from None
