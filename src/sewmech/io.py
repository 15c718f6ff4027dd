"""Writing results: CSV and JSON, always atomically (temporary file + rename).

A reader never sees a half-written file: every writer goes through :func:`atomic_write`, which
writes next to the target and renames only after the data are complete and flushed.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .results import KinematicsResult


@contextlib.contextmanager
def atomic_write(path: str | Path, mode: str = "w", encoding: str | None = "utf-8") -> Iterator:
    """Open a temporary file beside ``path``; on success rename it over ``path``.

    On an exception the temporary file is removed and ``path`` is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        kwargs = {"encoding": encoding, "newline": ""} if "b" not in mode else {}
        with os.fdopen(fd, mode, **kwargs) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _clean(x):
    """JSON has no NaN: write null for infeasible entries."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def kinematics_to_dict(result: KinematicsResult) -> dict:
    """A JSON-ready dict: ``phi_deg``, ``feasible`` and every channel with its unit."""
    def listify(a):
        return [_clean(v) for v in np.asarray(a, dtype=float).ravel().tolist()] if a.ndim <= 1 \
            else [listify(x) for x in a]

    return {
        "machine": result.machine,
        "units": {"length": "mm", "angle": "rad", "time": "s"},
        "batch_shape": list(result.batch_shape),
        "phi_deg": listify(result.phi_deg),
        "feasible": np.asarray(result.feasible).tolist(),
        "branches": result.branches,
        "channels": {name: {"unit": unit, "values": listify(values)}
                     for name, (values, unit) in result.channels().items()},
    }


def write_kinematics_json(result: KinematicsResult, path: str | Path) -> Path:
    """Write :func:`kinematics_to_dict` as JSON, atomically."""
    path = Path(path)
    with atomic_write(path) as fh:
        json.dump(kinematics_to_dict(result), fh, indent=1)
    return path


def write_kinematics_csv(result: KinematicsResult, path: str | Path) -> Path:
    """Write :meth:`KinematicsResult.to_pandas` as CSV, atomically."""
    path = Path(path)
    df = result.to_pandas()
    with atomic_write(path) as fh:
        df.to_csv(fh, index=False, float_format="%.10g")
    return path
