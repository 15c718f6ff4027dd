"""The run in time for the report's "Vibration and running" section (and ``sewmech run --out``):
the run-up curve from rest through the steady state to the stop, the motor's torque and power,
and the steady turn's speed against the energy method's (:mod:`sewmech.engine.running`)."""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ...engine.machine import Machine
from ...engine.running import RunResult, run
from ..drawing.figures import table_html


def running_left_out(machine: Machine) -> str | None:
    """Why the machine cannot be run in time (the sentence for the section's place), or None."""
    file = Path(machine.file).name
    if machine.spec.motor is None:
        return (f"Left out because {file} has no [motor] table: the run in time needs the motor"
                " that drives the shaft (docs/running.md).")
    if not machine.spec.masses:
        return (f"Left out because {file} has no [masses] tables: the run in time needs the"
                " machine's inertia (docs/machine-files.md).")
    return None


def running_section(figs, machine: Machine, *, result: RunResult | None = None,
                    inputs: Mapping[str, float] | None = None, rpm: float | None = None,
                    loads: Sequence | None = None, gravity: bool = True) -> dict:
    """Add the run's figures to ``figs`` (:class:`~sewmech.app.drawing.figures.Figures`): the
    run-up curve, the motor's torque and power, the steady turn against the energy method;
    return ``html`` (the part's heading, text and key-figure table, for the "Vibration and
    running" section), ``table`` (the key figures: quantity, value, unit) and ``result`` (the
    :class:`~sewmech.engine.running.RunResult`). A machine without a ``[motor]`` or
    ``[masses]`` cannot run: :func:`running_left_out` says why (ask it first).

    result: a run made already (:func:`sewmech.engine.running.run`); else the machine is run
    with its ``[motor]`` at ``inputs`` (rad; default the file's settings), ``rpm`` (default the
    file's), ``loads`` (default the file's) and ``gravity``.
    """
    from ..drawing.figures import subplots

    r = result if result is not None else run(machine, rpm=rpm, inputs=inputs, loads=loads,
                                              gravity=gravity)
    mo = r.motor
    t = r.time
    rpm_t = r.rpm
    s = r.steady
    stop = r.phase == 1

    # ---- the run-up curve ------------------------------------------------------------------------
    fig, ax = subplots(figsize=(9, 4.2), constrained_layout=True)
    ax.plot(t, r.rpm_curve, lw=1.2, color="C0", label="shaft speed")
    ax.axhline(rpm_t, color="k", lw=0.8, ls="--", label=f"working speed {rpm_t:g} rpm")
    if r.time_to_speed is not None:
        ax.axvline(r.time_to_speed, color="C2", lw=0.9, ls=":")
        ax.annotate(f"working speed after {r.time_to_speed:.3g} s", (r.time_to_speed, rpm_t),
                    textcoords="offset points", xytext=(6, -16), fontsize=8, color="C2")
    ax.axvspan(s.t_start, s.t_end, color="C1", alpha=0.15,
               label=f"steady turn: {s.mean_rpm:.5g} rpm, delta {s.delta:.3g}")
    if stop.any():
        ax.axvline(r.stop_start, color="C3", lw=0.9, ls=":")
        end = (f"stops in {r.time_to_stop:.3g} s" if r.time_to_stop is not None
               else "does not stop in the time given")
        how = {"clutch": "declutched and braked", "servo": "commanded to 0"}.get(mo.kind,
                                                                             "motor off")
        ax.annotate(f"{how}: {end}", (r.stop_start, 0.5 * rpm_t), textcoords="offset points",
                    xytext=(6, 0), fontsize=8, color="C3")
    for when, what in r.events:
        ax.axvline(when, color="0.5", lw=0.6, ls="-.")
        ax.annotate(what, (when, 0.15 * rpm_t), rotation=90, fontsize=7, color="0.4",
                    textcoords="offset points", xytext=(2, 0))
    ax.set_xlabel("time [s]")
    ax.set_ylabel("shaft speed [rpm]")
    ax.set_ylim(bottom=0.0)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="lower right" if not stop.any() else "center right")
    ax.set_title(f"{machine.name}: run-up from rest, steady running and stop ({mo.kind} motor)")
    figs.add(fig, "run-up", "Run-up curve",
             f"The upper shaft's speed from rest to the steady state and through the stop, with"
             f" its motor ({mo.describe()}) and the hand wheel; shaded: the steady turn whose"
             " speed fluctuation is given. The speed ripples within each turn: the machine's"
             " reduced inertia and its loads change with the shaft angle. Computed by"
             " integrating the machine's equation of motion in time with tables of its whole"
             " force analysis (docs/running.md).",
             pd.DataFrame({"time_s": t, "phi_rad": r.phi, "shaft_rpm": r.rpm_curve,
                           "stopping": stop}))

    # ---- the motor's torque and power ---------------------------------------------------------
    fig, axs = subplots(2, 1, figsize=(9, 5.6), sharex=True, constrained_layout=True)
    axs[0].plot(t, r.motor_torque * 1e-3, lw=1.0, label="motor's torque (its shaft)")
    axs[0].plot(t, r.belt_torque * 1e-3 / mo.belt_ratio, lw=0.8, alpha=0.8,
                label="through the belt, per belt ratio")
    axs[0].set_ylabel("torque [N m]")
    axs[1].plot(t, r.motor_power * 1e-3, lw=1.0, color="C3")
    axs[1].set_ylabel("motor power [W]")
    axs[1].set_xlabel("time [s]")
    for a in axs:
        a.grid(True, alpha=0.3)
        a.axhline(0.0, color="k", lw=0.5)
    axs[0].legend(fontsize=7, loc="upper right")
    fig.suptitle(f"{machine.name}: the motor's torque and power (belt ratio"
                 f" {mo.belt_ratio:g})")
    figs.add(fig, "run-motor", "Motor torque and power",
             "The motor's torque on its own shaft and its power over the run; the torque the"
             " belt passes to the machine (divided by the belt ratio, to compare) differs from"
             " it by what the rotor's own inertia takes. High at the start, where the motor"
             " accelerates the machine and its own rotor; in the steady state it carries the"
             " friction and the loads; 0 once the motor is off (a servo brakes).",
             pd.DataFrame({"time_s": t, "motor_rpm": r.motor_speed * 30 / math.pi,
                           "motor_torque_Nm": r.motor_torque * 1e-3,
                           "belt_torque_Nm": r.belt_torque * 1e-3,
                           "motor_power_W": r.motor_power * 1e-3}))

    # ---- the steady turn against the energy method --------------------------------------------
    phi_deg = np.degrees(s.phi)
    start_deg = math.degrees(r.phi0)
    fig, ax = subplots(figsize=(9, 4), constrained_layout=True)
    at = (phi_deg + start_deg) % 360.0
    order = np.argsort(at)
    ax.plot(at[order], s.omega[order] * 30 / math.pi, lw=1.6,
            label=f"run in time: delta {s.delta:.4g}")
    data = {"phi_deg": at[order], "run_rpm": s.omega[order] * 30 / math.pi}
    delta_e = None
    if r.energy is not None:
        sf = r.energy
        ax.plot(np.degrees(sf.phi), sf.omega * 30 / math.pi, lw=1.0, ls="--",
                label=f"energy method (constant motor torque): delta {sf.delta:.4g}")
        data["energy_method_rpm"] = np.interp(at[order], np.degrees(sf.phi),
                                              sf.omega * 30 / math.pi, period=360.0)
        delta_e = float(sf.delta)
    ax.set_xlabel("shaft angle phi [deg]")
    ax.set_ylabel("shaft speed [rpm]")
    ax.set_xticks(np.arange(0, 361, 30))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"{machine.name}: the steady turn at {s.mean_rpm:.5g} rpm")
    figs.add(fig, "run-steady", "Steady turn: speed over the shaft angle",
             "The shaft's speed over the last full turn before the stop, from the run in time,"
             " and from the energy method (the same mean speed, the hand wheel and the motor's"
             " rotor as its flywheel, a constant motor torque). They agree when the fluctuation"
             " is small and the motor's torque does not change within the turn; a motor whose"
             " torque falls with its speed damps the fluctuation.", pd.DataFrame(data))

    rows = [("working speed", rpm_t, "rpm"),
            ("time to reach the working speed",
             r.time_to_speed if r.time_to_speed is not None else math.nan, "s"),
            ("steady speed (mean over the turn)", s.mean_rpm, "rpm"),
            ("steady state settled", float(s.settled), "1"),
            ("coefficient of speed fluctuation, run in time (delta_run)", s.delta, "1"),
            ("coefficient of speed fluctuation, energy method (delta_energy)",
             delta_e if delta_e is not None else math.nan, "1"),
            ("largest motor torque", float(np.abs(r.motor_torque).max() * 1e-3), "N m"),
            ("largest motor power", float(np.abs(r.motor_power).max() * 1e-3), "W"),
            ("mean motor power in the steady turn", _steady_power(r) * 1e-3, "W"),
            ("time to stop (below 1 % of the working speed)",
             r.time_to_stop if r.time_to_stop is not None else math.nan, "s")]
    key = pd.DataFrame(rows, columns=["quantity", "value", "unit"])
    return {"html": running_html(machine, key, r), "table": key, "result": r}


def _steady_power(r: RunResult) -> float:
    """The motor's mean power (N mm/s) over the steady turn: its work over the turn's time."""
    s = r.steady
    sel = (r.time >= s.t_start) & (r.time <= s.t_end)
    if sel.sum() < 2:
        return math.nan
    p, tt = r.motor_power[sel], r.time[sel]
    return float(np.sum(0.5 * (p[1:] + p[:-1]) * np.diff(tt)) / (tt[-1] - tt[0]))


def running_html(machine: Machine, key: pd.DataFrame, result: RunResult | None = None) -> str:
    """The section's opening paragraph and its key figures (HTML), for the report."""
    motor = html.escape(result.motor.describe()) if result is not None else "its [motor]"
    return (f"<h3 id=\"running\">Running: start-up, steady state, stop</h3><p>The machine run in"
            f" time with {motor}: from rest at the convention's angle to its steady speed, then"
            " stopped. The speed fluctuation of the steady turn is compared with the energy"
            " method's (docs/running.md).</p>" + table_html(key))
