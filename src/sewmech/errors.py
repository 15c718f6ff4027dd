"""Errors that say where and what to do."""

from __future__ import annotations


class SewmechError(Exception):
    """Base class of every error sewmech raises on purpose."""


class MachineFileError(SewmechError, ValueError):
    """A machine file is malformed or inconsistent.

    Attributes
    ----------
    file : str
        The file (or ``<string>`` for text loaded from memory).
    table : str
        The TOML table, e.g. ``units[2] "take_up"`` or ``points.D``.
    key : str
        The key inside that table ("" when the table itself is at fault).
    """

    def __init__(self, file: str, table: str, key: str, message: str):
        self.file = file
        self.table = table
        self.key = key
        self.message = message
        where = f"[{table}]" if table else "(top level)"
        if key:
            where += f" {key}"
        super().__init__(f"{file}: {where}: {message}")


class AssemblyError(SewmechError):
    """The mechanism cannot be assembled (or moved through) at some crank angle.

    Attributes
    ----------
    unit : str
        Name of the unit that failed.
    phi_deg : float
        Shaft angle of the failure, degrees, in the machine's angle convention.
    design : tuple[int, ...]
        Index of the failing design in the batch (``()`` for a single design).
    reason : str
        What went wrong.
    """

    def __init__(self, unit: str, phi_deg: float, design: tuple, reason: str, hint: str = ""):
        self.unit = unit
        self.phi_deg = phi_deg
        self.design = design
        self.reason = reason
        at = f"design {design}, " if design else ""
        msg = f"unit '{unit}' at {at}shaft angle phi = {phi_deg:.6g} deg: {reason}"
        if hint:
            msg += f". {hint}"
        super().__init__(msg)


class ConvergenceError(AssemblyError):
    """The loop solver did not converge (names the loop unit, the angle and the residual)."""


def name_index(names: tuple[str, ...], name: str, what: str, owner: str = "") -> int:
    """Position of ``name`` in ``names``; a KeyError that suggests close names otherwise.

    ``what`` names the kind ("point", "link", ...), ``owner`` what was searched (e.g.
    "machine 'jb1-3'"), both for the message.
    """
    try:
        return names.index(name)
    except ValueError:
        import difflib

        close = difflib.get_close_matches(name, names, n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        where = f"{owner} has no" if owner else "no"
        raise KeyError(f"{where} {what} '{name}'{hint}") from None
