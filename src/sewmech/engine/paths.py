"""Paths a person gives sewmech: ``~`` expanded, and only regular files read.

A path's ``~user`` whose user does not exist, or a ``~`` without a home directory, is an
:class:`~sewmech.engine.errors.OptionError` at the path (Python's own expansion raises a bare
RuntimeError). A file sewmech reads must be a regular file: a named pipe would block the
command for ever, a device would be read without end, a socket cannot be read at all.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from .errors import OptionError


def user_path(path: str | os.PathLike, where: str | None = None) -> Path:
    """``path`` with a leading ``~`` or ``~user`` expanded. ``where``: the option or argument
    the path came from, for the error (default: the path itself)."""
    p = Path(path)
    try:
        return p.expanduser()
    except RuntimeError:
        head = str(p).split(os.sep, 1)[0]
        raise OptionError(where or str(p), f"{head!r}: there is no such user, or no home"
                          " directory to put for it", "Write the path without ~, or with an"
                          " existing user's (~ alone for your own)") from None


def not_regular(path: Path) -> str | None:
    """Why ``path`` (which exists) is not a file sewmech can read, or None if it is a regular
    file (or a symbolic link to one). Raises OSError if it cannot be examined."""
    mode = os.stat(path).st_mode
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "is a directory"
    if stat.S_ISFIFO(mode):
        return "is a named pipe, not a file (reading it would wait for a writer)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "is a device, not a file"
    if stat.S_ISSOCK(mode):
        return "is a socket, not a file"
    return "is not a regular file"
