"""The report's section "Vibration and running": what the operator feels and what the motor
sees. The housing's natural frequencies and mode shapes, the control points' levels and spectra
as the file has the machine and balanced on the vibration, the levels over the range of shaft
speeds (the resonances a run-up passes through); the run in time where the machine has a motor
(docs/vibration.md, docs/running.md)."""

from __future__ import annotations

import html
import math

import numpy as np
import pandas as pd

from ...engine.dynamics import inverse_dynamics
from ...engine.housing import Housing, excitation, housing_vibration, vibration
from ...engine.machine import Machine

#: the shaft-angle step of the section's Fourier series, deg (harmonics up to 90; the command and the page use the same)
STEP_DEG = 2.0
#: the speed range of the levels-against-speed figure, as fractions of the working speed
SPEED_RANGE = (0.2, 1.5)
N_SPEEDS = 27
#: the shaft-angle step of the levels-against-speed figure, deg (harmonics up to 45)
SWEEP_STEP_DEG = 4.0
DOF = ("ux", "uy", "uz", "rx", "ry", "rz")


def _mode_name(shape: np.ndarray) -> str:
    """The motion a mode shape is mostly (its largest component, rotations at 100 mm)."""
    w = np.abs(shape) * np.array([1, 1, 1, 100, 100, 100])
    j = int(np.argmax(w))
    return ("sliding along " + "xyz"[j]) if j < 3 else ("turning about " + "xyz"[j - 3])


def _balanced(machine: Machine):
    """The counterweights chosen on the vibration (the least larger x or y level at the first
    control point; the shaft's counterweight if there is one), or None without counterweights
    or when nothing is proposed."""
    from ...design.balancing import balance, shaft_counterweight

    if not machine.counterweights:
        return None
    shaft = shaft_counterweight(machine)
    res = balance(machine, "vibration", [shaft] if shaft else None)
    return res if res.proposed else None


def vibration_section(figs, machine: Machine, balanced=None) -> dict:
    """Add the housing's figures to ``figs``; return ``html`` (the section's heading, text and
    tables) and ``table`` (its key figures: levels before and after, natural frequencies).
    ``balanced``: the balancing section's answer on the vibration criterion, if it has one
    (else balanced here when the machine has counterweights)."""
    from ..drawing.figures import subplots, table_html

    h = Housing.of(machine)
    rpm = machine.rpm
    n_shaft = rpm / 60.0
    f, shapes = h.modes()
    if balanced is not None:
        bal = balanced if balanced.proposed else None
    else:
        bal = _balanced(machine)
    designs = [("as the file has it", {})]
    if bal is not None:
        designs.append((f"balanced on the vibration ({bal.status})", bal.overrides))
    P = None  # one design as the file has it, or it and the balanced one
    if bal is not None:
        names = list(machine.parameter_names)
        P = machine.parameters({k: np.array([machine.defaults[names.index(k)], x])
                                for k, x in bal.overrides.items()})
    v = housing_vibration(machine, STEP_DEG, params=P)
    lv = v.level_db.reshape(-1, len(h.control_names), 3)
    rms = v.rms_velocity.reshape(-1, len(h.control_names), 3)
    spec = v.spectrum.reshape((-1,) + v.spectrum.shape[-3:])
    cw = ""
    if bal is not None:
        cw = ", ".join(f"{html.escape(n)} {c['static_moment_gcm']:.4g} g cm at"
                       f" {c['angle_deg']:.4g} deg" for n, c in bal.counterweights.items())

    # ---- the spectrum at the first control point --------------------------------------------
    cp = h.control_names[0]
    fig, axs = subplots(1, 3, figsize=(12, 3.8), sharey=True, constrained_layout=True)
    top = min(len(v.harmonics), 12)
    with np.errstate(divide="ignore"):
        db = 20.0 * np.log10(np.maximum(spec[:, :top, 0, :], 1e-300) / 5e-5)
    floor = max(float(np.max(lv[:, 0, :])) - 60.0, 0.0)
    data = {"harmonic": v.harmonics[:top], "frequency_hz": v.frequency_hz[:top]}
    for j, (ax, axis) in enumerate(zip(axs, "xyz", strict=True)):
        for k, (label, _) in enumerate(designs):
            off = (k - (len(designs) - 1) / 2) * 0.35
            ax.bar(v.harmonics[:top] + off, np.maximum(db[k, :, j], floor) - floor,
                   bottom=floor, width=0.35, color=f"C{k}",
                   label=f"{label}: {lv[k, 0, j]:.1f} dB")
            data[f"{axis}_db_{'before' if k == 0 else 'after'}"] = db[k, :, j]
        for fk in f:
            if fk / n_shaft <= top + 0.5:
                ax.axvline(fk / n_shaft, color="0.5", ls=":", lw=0.9)
        ax.set_xlabel(f"harmonic of the shaft speed ({n_shaft:.3g} Hz each)")
        ax.set_title(f"along {axis}", fontsize=10)
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    axs[0].set_ylabel("level of each harmonic [dB re 5e-8 m/s]")
    fig.suptitle(f"{machine.name}: vibration of the housing at '{cp}', {rpm:g} rpm")
    figs.add(fig, "vib-spectrum", f"Vibration at the control point '{cp}'",
             "The level of each harmonic of the shaft speed in the RMS vibration velocity of"
             f" the housing's control point '{cp}' along x, y and z, predicted by the housing's"
             " model (a rigid body on its mounts, excited by every force of the mechanisms;"
             " docs/vibration.md), as the file has the machine"
             + (f" and balanced on the vibration ({cw})" if bal is not None else "")
             + "; the legend gives each axis's overall level. Dotted: the housing's natural"
             " frequencies in shaft orders (a mode near a harmonic amplifies it).",
             pd.DataFrame(data))

    # ---- levels against the shaft speed ------------------------------------------------------
    speeds = rpm * np.linspace(*SPEED_RANGE, N_SPEEDS)
    n_phi = round(360.0 / SWEEP_STEP_DEG)
    phi = np.arange(n_phi) * (2.0 * math.pi / n_phi)
    sweep = np.empty((N_SPEEDS, len(designs), 3))
    for i, n in enumerate(speeds):
        r = inverse_dynamics(machine, phi, rpm=float(n), params=P)
        vv = vibration(h, excitation(machine, h, r), float(n))
        sweep[i] = vv.level_db.reshape(len(designs), -1, 3)[:, 0, :]
    fig, ax = subplots(figsize=(9, 4.2), constrained_layout=True)
    sdata = {"rpm": speeds}
    for j, axis in enumerate("xyz"):
        for k, (label, _) in enumerate(designs):
            ax.plot(speeds, sweep[:, k, j], color=f"C{j}", ls="-" if k == 0 else "--",
                    label=f"{axis}, {label}")
            sdata[f"{axis}_db_{'before' if k == 0 else 'after'}"] = sweep[:, k, j]
    for fk in f:
        if speeds[0] <= fk * 60.0 <= speeds[-1]:
            ax.axvline(fk * 60.0, color="0.5", ls=":", lw=0.9)
    ax.axvline(rpm, color="k", lw=0.9)
    ax.set_xlabel("shaft speed [rpm] (solid black: the working speed; dotted: a natural"
                  " frequency at the first harmonic)")
    ax.set_ylabel(f"level at '{cp}' [dB re 5e-8 m/s]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title(f"{machine.name}: the control point's levels over the speeds a run-up passes",
                 fontsize=10)
    figs.add(fig, "vib-speed", "Vibration levels against the shaft speed",
             f"The levels at '{cp}' along x, y and z from {speeds[0]:.0f} to {speeds[-1]:.0f}"
             " rpm (the steady vibration at each speed, on a 4 deg grid of the turn: the"
             " inertia forces of the mechanisms grow with its square, the housing answers"
             " through its modes), as the file has the machine"
             + (" (solid) and balanced on the vibration (dashed)" if bal is not None else "")
             + ". A run-up passes through every speed below the working one; where a natural"
             " frequency meets the first harmonic the level peaks.", pd.DataFrame(sdata))

    # ---- tables -----------------------------------------------------------------------------
    rows = []
    for k, (label, _) in enumerate(designs):
        for i, name in enumerate(h.control_names):
            rows.append({"machine": label, "control point": name,
                         **{f"{a} [dB]": lv[k, i, j] for j, a in enumerate("xyz")},
                         **{f"{a} [mm/s]": rms[k, i, j] for j, a in enumerate("xyz")}})
    levels = pd.DataFrame(rows)
    modes = pd.DataFrame({"mode": np.arange(1, 7), "frequency [Hz]": f,
                          "shaft orders": f / n_shaft,
                          "mostly": [_mode_name(shapes[:, k]) for k in range(6)],
                          **{d: shapes[j] for j, d in enumerate(DOF)}})
    shown_modes = modes.copy()
    for d in DOF:
        shown_modes[d] = np.round(modes[d].to_numpy(), 3) + 0.0  # (+ 0.0: no -0)
    key = [(f"level at '{cp}' along {a}, as the file has it", lv[0, 0, j], "dB re 5e-8 m/s")
           for j, a in enumerate("xyz")]
    if bal is not None:
        key += [(f"level at '{cp}' along {a}, balanced on the vibration", lv[1, 0, j],
                 "dB re 5e-8 m/s") for j, a in enumerate("xyz")]
    key += [(f"natural frequency {k + 1} ({_mode_name(shapes[:, k])})", f[k], "Hz")
            for k in range(6)]
    nearest = int(np.argmin(np.abs(f / n_shaft - 1.0)))
    warn = ""
    if abs(f[nearest] / n_shaft - 1.0) < 0.2:
        warn = (f" Mode {nearest + 1} ({_mode_name(shapes[:, nearest])}, {f[nearest]:.3g} Hz)"
                f" lies within {abs(f[nearest] / n_shaft - 1.0):.0%} of the working speed's"
                " first harmonic: the housing runs near resonance, and its mounts decide its"
                " levels more than any counterweight.")
    text = (f'<h2 id="vibration">Vibration and running</h2><p>The housing of {machine.name}'
            f" ({h.mass_kg:.3g} kg on {len(h.mount_names)} mounts) as a rigid body excited by"
            f" every force the mechanisms put on it at {rpm:g} rpm: its vibration velocity at"
            " the control points where the operator's hands rest, in dB re 5e-8 m/s as the"
            " balancing paper measures it (docs/vibration.md)"
            + (f"; balanced on the vibration: {cw}" if bal is not None else "")
            + f".{html.escape(warn)}</p>" + table_html(levels)
            + "<h3>Natural frequencies and mode shapes</h3><p>Each mode's frequency, in shaft"
            " orders at the working speed, and its shape: the housing's displacement at the"
            " frame's origin (ux, uy, uz mm) and rotation (rx, ry, rz rad), scaled to a largest"
            " of 1; components below 0.001 of the largest shown as 0, all of them in the"
            " CSV).</p>" + table_html(shown_modes))
    return {"html": text, "table": pd.DataFrame(key, columns=["figure", "value", "unit"]),
            "levels": levels, "modes": modes}
