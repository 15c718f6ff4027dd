"""``sewmech vibration``: the housing's vibration at its control points, its modes and the
forces its mounts pass to the table (docs/vibration.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from .common import DEFAULT_MACHINE, SET_HELP, _load, _rpm, _settings, command, console, print_json

#: the shaft-angle step of the vibration's Fourier series, deg (harmonics up to 90)
STEP_DEG = 2.0
DOF = ("ux", "uy", "uz", "rx", "ry", "rz")


def vibration_to_dict(v, control: str | None = None) -> dict:
    """A JSON-ready dict of a one-design :class:`~sewmech.engine.housing.HousingVibration`:
    ``control_points`` (name -> ``level_db`` and ``rms_velocity_mm_s``, each with x, y, z),
    ``modes`` (six: ``frequency_hz`` and the mode ``shape`` with its six components: ux, uy,
    uz mm, rx, ry, rz rad, scaled to a largest of 1), ``mounts`` (name -> ``rms_force_N`` x,
    y, z on the table), ``spectrum`` (per control point and axis the harmonics' RMS
    velocities, mm/s, at ``frequency_hz``)."""
    h = v.housing
    f, shapes = h.modes()
    rms, lv, spec = v.rms_velocity, v.level_db, v.spectrum
    out = {
        "rpm": v.rpm,
        "reference": "5e-8 m/s (dB of RMS velocity)",
        "control_points": {name: {
            "level_db": {ax: float(lv[i, j]) for j, ax in enumerate("xyz")},
            "rms_velocity_mm_s": {ax: float(rms[i, j]) for j, ax in enumerate("xyz")}}
            for i, name in enumerate(h.control_names)},
        "modes": [{"frequency_hz": float(f[k]),
                   "shape": {d: float(shapes[j, k]) for j, d in enumerate(DOF)}}
                  for k in range(6)],
        "mounts": {name: {"rms_force_N": {ax: float(v.mount_rms[i, j])
                                          for j, ax in enumerate("xyz")}}
                   for i, name in enumerate(h.mount_names)},
        "spectrum": {"harmonic": v.harmonics.tolist(), "frequency_hz": v.frequency_hz.tolist(),
                     **{name: {ax: spec[:, i, j].tolist() for j, ax in enumerate("xyz")}
                        for i, name in enumerate(h.control_names)}},
    }
    if control is not None:
        out["control_point"] = control
    return out


def _mode_name(shape: np.ndarray) -> str:
    """The motion a mode shape is mostly (its largest component, rotations at 100 mm)."""
    w = np.abs(shape) * np.array([1, 1, 1, 100, 100, 100])
    j = int(np.argmax(w))
    return ("sliding along " + "xyz"[j]) if j < 3 else ("turning about " + "xyz"[j - 3])


@command("vibration")
def vibration_cmd(
    machine: str = typer.Argument(DEFAULT_MACHINE, help="shipped machine name or TOML file"),
    rpm: float = typer.Option(None, help="shaft speed, rev/min (default: the file's)"),
    inputs: list[str] = typer.Option(None, "--input", help="a setting input NAME=DEG, e.g."
                                     " regulator=30; repeatable (default: the file's)"),
    as_json: bool = typer.Option(False, "--json", help="print the levels, modes and mount"
                                 " forces as JSON"),
    out: Path = typer.Option(None, help="also write the spectra, the velocities over a turn"
                             " and the mode shapes (CSV) and figures here"),
    sets: list[str] = typer.Option(None, "--set", help=SET_HELP),
):
    """The housing's vibration: RMS velocity and level (dB re 5e-8 m/s) at its control points,
    its natural frequencies and mode shapes, the forces its mounts pass to the table."""
    from ...engine.housing import Housing, housing_vibration

    m = _load(machine, sets)
    Housing.of(m)  # a machine without [housing]: one located line before any work
    settings = _settings(m, inputs)
    rpm = _rpm(rpm)
    if out is not None:
        from ..files.outdir import preflight

        preflight(out, command="vibration")
    v = housing_vibration(m, STEP_DEG, rpm=rpm, inputs=settings or None)
    data = vibration_to_dict(v)
    if as_json:
        print_json(data)
        if out is None:
            return
    else:
        _print(m, v, data)
    if out is not None:
        from ..files.outdir import output_dir

        with output_dir(out, command="vibration") as root:
            written = _write(m, v, root)
        if not as_json:
            for name in written:
                console.print(f"written: {escape(str(out / name))}")


def _print(m, v, data) -> None:
    h = v.housing
    t = Table(title=f"{m.name}: housing vibration at {v.rpm:g} rpm (RMS velocity; level dB re"
                    " 5e-8 m/s)")
    for col in ("control point", "x mm/s", "y mm/s", "z mm/s", "x dB", "y dB", "z dB"):
        t.add_column(col, justify="left" if col == "control point" else "right")
    for name, cp in data["control_points"].items():
        r, lv = cp["rms_velocity_mm_s"], cp["level_db"]
        t.add_row(escape(name), *(f"{r[a]:.3g}" for a in "xyz"),
                  *(f"{lv[a]:.1f}" for a in "xyz"))
    console.print(t)
    f, shapes = h.modes()
    mt = Table(title="natural frequencies of the housing on its mounts")
    for col in ("mode", "frequency, Hz", "mostly", "x shaft orders"):
        mt.add_column(col, justify="right" if col != "mostly" else "left")
    for k in range(6):
        mt.add_row(str(k + 1), f"{f[k]:.2f}", _mode_name(shapes[:, k]),
                   f"{f[k] / (v.rpm / 60.0):.2f}")
    console.print(mt)
    ft = Table(title="forces of the mounts on the table (RMS, N)")
    for col in ("mount", "x", "y", "z"):
        ft.add_column(col, justify="left" if col == "mount" else "right")
    for name, mnt in data["mounts"].items():
        ft.add_row(escape(name), *(f"{mnt['rms_force_N'][a]:.3g}" for a in "xyz"))
    console.print(ft)


def _write(m, v, root: Path) -> list[str]:
    """The spectra, the velocities over a turn, the modes and the levels as CSV, and the
    figures (PNG, SVG) of the spectra and the velocity hodographs, into ``root``."""
    import pandas as pd

    from ..drawing.figures import save_figure, subplots
    from ..files.io import atomic_write, dump_json

    h = v.housing
    names = []
    spec = v.spectrum
    rows = {"harmonic": v.harmonics, "frequency_hz": v.frequency_hz}
    for i, cp in enumerate(h.control_names):
        for j, ax in enumerate("xyz"):
            rows[f"{cp}_{ax}_rms_mm_s"] = spec[:, i, j]
    stem = f"{m.name}-vibration"
    with atomic_write(root / f"{stem}-spectrum.csv") as fh:
        pd.DataFrame(rows).to_csv(fh, index=False, float_format="%.10g")
    names.append(f"{stem}-spectrum.csv")
    vt = v.velocity_in_time(360)
    t_rows = {"phi_deg": np.arange(360.0)}
    for i, cp in enumerate(h.control_names):
        for j, ax in enumerate("xyz"):
            t_rows[f"{cp}_v{ax}_mm_s"] = vt[:, i, j]
    with atomic_write(root / f"{stem}-velocity.csv") as fh:
        pd.DataFrame(t_rows).to_csv(fh, index=False, float_format="%.10g")
    names.append(f"{stem}-velocity.csv")
    f, shapes = h.modes()
    with atomic_write(root / f"{stem}-modes.csv") as fh:
        pd.DataFrame({"mode": np.arange(1, 7), "frequency_hz": f,
                      **{d: shapes[j] for j, d in enumerate(DOF)}}).to_csv(
            fh, index=False, float_format="%.10g")
    names.append(f"{stem}-modes.csv")
    with atomic_write(root / f"{stem}.json") as fh:
        dump_json(vibration_to_dict(v), fh, indent=1)
    names.append(f"{stem}.json")
    fig, axs = subplots(len(h.control_names), 2, figsize=(10, 3.8 * len(h.control_names)),
                        constrained_layout=True, squeeze=False)
    for i, cp in enumerate(h.control_names):
        ax = axs[i, 0]
        width = 0.27
        for j, axis in enumerate("xyz"):
            ax.bar(v.harmonics + (j - 1) * width, spec[:, i, j], width=width,
                   label=f"{axis}: {v.level_db[i, j]:.1f} dB")
        ax.set_xlim(0.3, min(len(v.harmonics), 12) + 0.7)
        ax.set_xlabel(f"harmonic of the shaft speed ({v.rpm / 60:.3g} Hz each)")
        ax.set_ylabel("RMS velocity [mm/s]")
        ax.set_title(f"control point '{cp}': spectrum")
        ax.legend(fontsize=7)
        ax.grid(True, axis="y", alpha=0.3)
        ax = axs[i, 1]
        ax.plot(vt[:, i, 0], vt[:, i, 1], lw=1.4)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("vx [mm/s]")
        ax.set_ylabel("vy [mm/s]")
        ax.set_title("velocity over a turn (x, y)")
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"{m.name}: housing vibration at {v.rpm:g} rpm")
    save_figure(fig, root, f"{stem}")
    names += [f"{stem}.png", f"{stem}.svg"]
    return names
