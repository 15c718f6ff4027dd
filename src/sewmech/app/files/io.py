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
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np

from ...engine.results import KinematicsResult
from .outdir import file_mode


@contextlib.contextmanager
def atomic_write(path: str | Path, mode: str = "w", encoding: str | None = "utf-8") -> Iterator:
    """Open a temporary file beside ``path``; on success rename it over ``path``.

    On an exception the temporary file is removed and ``path`` is left as it was. The file gets
    the mode the umask gives (0644 under umask 022). Commands write through
    :func:`sewmech.outdir.output_dir`, which decides whether ``path`` may be replaced at all.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, file_mode())  # mkstemp makes 0600: the umask decides, as for open()
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


def dump_json(data, fh, *, indent: int | None = None) -> None:
    """``data`` as JSON into the open text file ``fh``: strict JSON, which has no NaN or
    infinity. Every command gives an undefined figure as null with a note that says why, at
    its source; a NaN or an infinity that still reaches this point is a bug in sewmech, and
    is raised as one (a RuntimeError naming where it is) rather than written as the bare
    ``NaN`` that JSON readers refuse."""
    try:
        text = json.dumps(data, indent=indent, allow_nan=False)
    except ValueError:
        raise RuntimeError(f"a non-finite number at {_non_finite_path(data)} was about to be"
                           " written as JSON") from None
    fh.write(text)


def _non_finite_path(data, path: str = "") -> str:
    """Where the first NaN or infinity in ``data`` is (``objective_parts[0].start``), or ""."""
    if isinstance(data, float):
        return "" if math.isfinite(data) else (path or "the top level")
    if isinstance(data, dict):
        items = ((f"{path}.{k}" if path else str(k), v) for k, v in data.items())
    elif isinstance(data, list | tuple):
        items = ((f"{path}[{k}]", v) for k, v in enumerate(data))
    else:
        return ""
    for where, v in items:
        hit = _non_finite_path(v, where)
        if hit:
            return hit
    return ""


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
        dump_json(kinematics_to_dict(result), fh, indent=1)
    return path


def write_kinematics_csv(result: KinematicsResult, path: str | Path) -> Path:
    """Write :meth:`KinematicsResult.to_pandas` as CSV, atomically."""
    path = Path(path)
    df = result.to_pandas()
    with atomic_write(path) as fh:
        df.to_csv(fh, index=False, float_format="%.10g")
    return path


#: the unknowns of each pair kind, with their units (see sewmech.machine.Pair)
_PAIR_LABELS = {"revolute": ("Fx_N", "Fy_N"), "prismatic": ("N_N", "M_Nmm"), "cam": ("N_N",),
                "slot": ("N_N",), "driver": ("torque_Nmm",)}


def full_turn(phi_deg) -> bool:
    """Whether the angles (deg) are a whole turn in equal steps (the grid of `--step-deg`),
    on which a turn's mean is the grid's mean."""
    a = np.asarray(phi_deg, dtype=float)
    if a.size < 4:
        return False
    step = 360.0 / a.size
    return bool(np.allclose(np.diff(a), step, rtol=0, atol=1e-6 * step))


def turn_means(res) -> dict:
    """Means over the turn (W) of the motor's power, the friction loss, the dampers' loss and
    the loads' dissipation (minus their mean power: positive when they take energy out); None
    each unless the result's angles are a whole turn in equal steps."""
    if not full_turn(res.phi_deg):
        return {k: None for k in ("mean_input_power_W", "friction_loss_W", "damping_loss_W",
                                  "load_dissipation_W")}
    return {"mean_input_power_W": _clean(float(np.mean(res.input_power)) * 1e-3),
            "friction_loss_W": _clean(float(np.mean(res.friction_power)) * 1e-3),
            "damping_loss_W": _clean(float(np.mean(res.damping_power)) * 1e-3),
            "load_dissipation_W": _clean(-float(np.mean(res.external_power)) * 1e-3)}


def dynamics_to_dict(res, contacts=None) -> dict:
    """A JSON-ready dict of a single-design :class:`sewmech.dynamics.DynamicsResult`: per
    position the driving torque, energies, powers, shaking force and moment and the upper
    shaft's bearing reactions (SI units, named in the keys; null where not defined), and every
    pair's unknowns per position (``pairs``: kind, links, components with units, values);
    the turn's means of the motor's power and the losses (null unless the angles are a whole
    turn in equal steps), the springs' and the friction's figures, where each load acts, and
    ``contacts`` (:func:`sewmech.engine.contacts.contact_margins`' entries, if given)."""
    if res.kin.batch_shape:
        raise ValueError("dynamics_to_dict takes one design (batch shape ()), got batch shape"
                         f" {res.kin.batch_shape}")
    try:
        br, why = res.bearings, None
    except ValueError as exc:  # no [shaft] table, or planar-only shaft masses: say why
        br, why = None, str(exc)
    rows = []
    for k, phi in enumerate(res.phi_deg.tolist()):
        rows.append({
            "phi_deg": phi,
            "input_torque_Nm": _clean(float(res.input_torque[k]) * 1e-3),
            "input_power_W": _clean(float(res.input_power[k]) * 1e-3),
            "kinetic_energy_J": _clean(float(res.kinetic_energy[k]) * 1e-3),
            "potential_energy_J": _clean(float(res.potential_energy[k]) * 1e-3),
            "external_power_W": _clean(float(res.external_power[k]) * 1e-3),
            "reduced_inertia_kgm2": _clean(float(res.reduced_inertia[k]) * 1e-6),
            "shaking_force_N": [_clean(float(x)) for x in res.shaking_force[k]],
            "shaking_moment_Nm": _clean(float(res.shaking_moment[k]) * 1e-3),
            "bearing_front_N": None if br is None else [_clean(float(x)) for x in br.front[k]],
            "bearing_rear_N": None if br is None else [_clean(float(x)) for x in br.rear[k]],
            "friction_power_W": _clean(float(res.friction_power[k]) * 1e-3),
            "damping_power_W": _clean(float(res.damping_power[k]) * 1e-3),
            "loads_acting": [res.load_names[j] for j in range(len(res.load_names))
                             if res.load_on is not None and res.load_on[k, j] > 0.5],
        })
    sp = res.springs
    springs = {} if sp is None else {
        name: {"kind": "translational" if j < sp.n_translational else "torsional",
               "unit": "N" if j < sp.n_translational else "N m",
               "values": [_clean(float(v) * (1.0 if j < sp.n_translational else 1e-3))
                          for v in sp.force[:, j]]}
        for j, name in enumerate(sp.names)}
    fr = res.friction
    friction = {} if fr is None else {
        name: {"power_W": [_clean(float(v) * 1e-3) for v in fr.power[:, j]]}
        for j, name in enumerate(fr.pairs)}
    out = {
        "machine": res.machine.name,
        "rpm": round(float(res.kin.omega_shaft[0] * 60 / (2 * math.pi)), 9),
        "gravity": res.gravity,
        "loads": list(res.load_names),
        "settings_deg": {name: round(math.degrees(float(res.params[
            res.machine.parameter_index(f"input.{name}")])), 9) for name in res.machine.spec.inputs},
        "conventions": {
            "input_torque_Nm": "torque of the motor on the upper shaft, counter-clockwise +",
            "external_power_W": "power of the process loads on the machine (gravity excluded:"
                                " it is in potential_energy_J)",
            "shaking_force_N": "-sum m a_G of the moving links: what the frame feels",
            "shaking_moment_Nm": "-sum (I alpha + r_G x m a_G) about the frame origin",
            "reduced_inertia_kgm2": "J(phi) = 2 T / omega^2; null where the shaft is at rest"
                                    " (omega = 0: a motion at rest has no velocity ratios)",
            "bearing_front_N": "force of the front bearing on the upper shaft (x, y)",
            "bearing_rear_N": "force of the rear bearing on the upper shaft (x, y)"
                              + (f"; null here: {why}" if why else ""),
            "mean_input_power_W": "the motor's mean power over the turn; it equals"
                                  " friction_loss_W + damping_loss_W + load_dissipation_W"
                                  " (null unless the angles are a whole turn in equal steps)",
            "load_dissipation_W": "minus the loads' mean power: what they take out of the"
                                  " machine (negative: they would drive it)",
            "contacts": "one-sided contacts at this speed: least force over the turn and where,"
                        " and the speed above which each opens (null: it never opens below"
                        " 100 x this speed)",
            "springs": "tension (N, + pulling its ends together) or moment on the pair's second"
                       " link (N m) over the turn",
        },
        "positions": rows,
        "pairs": {pair.name: {"kind": pair.kind, "links": list(pair.links),
                              "point": pair.point,
                              "components": list(_PAIR_LABELS[pair.kind]),
                              "values": [[_clean(float(v)) for v in row]
                                         for row in res.pair(pair.name)]}
                  for pair in res.pairs},
    }
    out.update(turn_means(res))
    out["contacts"] = None if contacts is None else [c.to_json() for c in contacts]
    out["springs"] = springs
    out["friction"] = friction
    return out


def write_dynamics_csv(res, out_dir: str | Path) -> list[Path]:
    """Two CSV files (atomically): MACHINE-dynamics.csv with the per-position figures of
    :func:`dynamics_to_dict` and MACHINE-pair-forces.csv with every pair's unknowns (N, N mm)."""
    import pandas as pd

    out_dir = Path(out_dir)
    data = dynamics_to_dict(res)
    flat = []
    for r in data["positions"]:
        row = {}
        for key, value in r.items():
            if key == "loads_acting":
                row[key] = "; ".join(value)
            elif isinstance(value, list):
                row[key.replace("_N", "_x_N")] = value[0]
                row[key.replace("_N", "_y_N")] = value[1]
            elif value is None and key.startswith("bearing"):
                continue
            else:
                row[key] = value
        flat.append(row)
    main = out_dir / f"{res.machine.name}-dynamics.csv"
    with atomic_write(main) as fh:
        pd.DataFrame(flat).to_csv(fh, index=False, float_format="%.10g")
    pairs = out_dir / f"{res.machine.name}-pair-forces.csv"
    with atomic_write(pairs) as fh:
        pair_forces_frame(res).to_csv(fh, index=False, float_format="%.10g")
    return [main, pairs]


def pair_forces_frame(res):
    """Every pair's unknowns per position of a single-design dynamics result, one column each:
    ``PAIR.Fx_N``/``Fy_N`` (revolute), ``N_N``/``M_Nmm`` (prismatic), ``N_N`` (cam, slot),
    ``torque_Nmm`` (driver); the action of the pair's first link on its second."""
    import pandas as pd

    cols = {"phi_deg": res.phi_deg}
    for pair in res.pairs:
        x = res.pair(pair.name)
        for j, label in enumerate(_PAIR_LABELS[pair.kind]):
            cols[f"{pair.name}.{label}"] = x[:, j]
    return pd.DataFrame(cols)


#: the largest CSV file of measurements sewmech reads, bytes (a few hundred lines are usual)
MAX_CSV_BYTES = 64 * 2**20


def read_csv_columns(path: str | Path, numbers: Sequence[str], texts: Sequence[str] = (),
                     *, what: str = "measurements",
                     nonnegative: Mapping[str, str] | None = None,
                     ranges: Mapping[str, tuple[float, float, str]] | None = None,
                     labels: Mapping[str, tuple[str, str, str]] | None = None
                     ) -> dict[str, np.ndarray]:
    """The columns ``numbers`` (as floats) and ``texts`` (as strings) of a CSV file with a
    header line; other columns are ignored, blank lines and lines starting with ``#`` skipped.
    ``nonnegative``: number columns that must be >= 0, each with what to do instead (a
    magnitude's sign belongs to an angle); ``ranges``: number columns that must lie in
    (lo, hi, unit), a range a measurement can have; ``labels``: text columns whose every cell
    must match a regular expression, each with (the pattern, what it is, what to do otherwise).

    Raises AnalysisError naming the file, and the line and column of a bad value, when a column
    is missing or named twice in the header, a number is not a finite number (or negative where
    it may not be, or outside its range), a text cell is empty (or does not match its label's
    pattern), or there are no data lines."""
    import csv
    import re

    from ...engine.errors import AnalysisError
    from ...engine.paths import not_regular, user_path

    path = user_path(path)
    where = str(path)
    try:
        why = not_regular(path)
        if why is not None:
            raise AnalysisError(where, why, f"Give the CSV file of the {what}")
        if path.stat().st_size > MAX_CSV_BYTES:
            raise AnalysisError(where, f"is {path.stat().st_size / 2**20:.0f} MiB; a file of"
                                f" {what} is at most {MAX_CSV_BYTES // 2**20} MiB of text",
                                f"Check that this is the CSV file of the {what}")
        with open(path, encoding="utf-8-sig", newline="") as fh:
            lines = [(k, row) for k, row in enumerate(csv.reader(fh), start=1)
                     if row and any(c.strip() for c in row)
                     and not row[0].lstrip().startswith("#")]
    except UnicodeDecodeError as exc:
        raise AnalysisError(where, f"is not UTF-8 text ({exc.reason})", "Save it as UTF-8"
                            " (a spreadsheet's 'CSV UTF-8')") from None
    except csv.Error as exc:
        raise AnalysisError(where, f"is not a CSV file sewmech can read ({exc})",
                            "Save it as plain comma-separated text") from None
    except OSError as exc:
        raise AnalysisError(where, f"cannot be read ({exc.strerror or exc})",
                            "Check the path and its permissions") from None
    if not lines:
        raise AnalysisError(where, "is empty", f"Write a header line ({', '.join(numbers)})"
                            f" and one line per measurement")
    head_line, header = lines[0]
    header = [c.strip() for c in header]
    missing = [c for c in (*numbers, *texts) if c not in header]
    if missing:
        raise AnalysisError(f"{where}:{head_line}", f"missing column(s) {', '.join(missing)}"
                            f" (the header has {', '.join(header) or 'nothing'})",
                            f"The header must name {', '.join((*numbers, *texts))}")
    twice = [c for c in (*numbers, *texts) if header.count(c) > 1]
    if twice:  # which one would be read is anybody's guess
        raise AnalysisError(f"{where}:{head_line}", f"the header names column(s)"
                            f" {', '.join(twice)} more than once", "Name each column once")
    if len(lines) < 2:
        raise AnalysisError(where, "has a header but no measurements", "Add one line each")
    idx = {c: header.index(c) for c in (*numbers, *texts)}
    out: dict[str, list] = {c: [] for c in idx}
    for k, row in lines[1:]:
        for c, j in idx.items():
            cell = row[j].strip() if j < len(row) else ""
            if c in texts:
                if not cell:
                    raise AnalysisError(f"{where}:{k}", f"column {c} is empty",
                                        f"Give each line its {c}")
                if labels and c in labels and not re.fullmatch(labels[c][0], cell):
                    raise AnalysisError(f"{where}:{k}", f"column {c}: {cell!r} is not"
                                        f" {labels[c][1]}", labels[c][2])
                out[c].append(cell)
                continue
            try:
                v = float(cell)
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                raise AnalysisError(f"{where}:{k}", f"column {c}: {cell!r} is not a number",
                                    "Give a finite number (a dot for decimals)")
            if nonnegative and c in nonnegative and v < 0.0:
                raise AnalysisError(f"{where}:{k}", f"column {c}: {cell} is negative",
                                    nonnegative[c])
            if ranges and c in ranges and not ranges[c][0] <= v <= ranges[c][1]:
                lo, hi, unit = ranges[c]
                raise AnalysisError(f"{where}:{k}", f"column {c}: {cell} is outside {lo:g} .."
                                    f" {hi:g} {unit}, the range a measurement of it can have",
                                    "Check the value and its unit (docs/balancing.md)")
            out[c].append(v)
    return {c: np.array(v, dtype=float if c in numbers else object) for c, v in out.items()}
