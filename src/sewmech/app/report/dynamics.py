"""The report's dynamics section: driving torque, energies and speed fluctuation, shaking force
and moment, upper-shaft bearings, pair forces, force transmission (pressure angles, regulator
torque, needle force). Run at the working speed and, as the JB dynamics report does, at the
longest forward stitch (the hardest case for the feed)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

from ...engine.dynamics import inverse_dynamics, speed_fluctuation
from ...engine.machine import Machine
from ...sewing import feed as FD
from ...sewing.transmission import needle_force, pressure_angles, regulator_torques
from ..files.io import pair_forces_frame
from .page import arc_cam_note

#: shaft torque for the needle-force view, N mm [estimate: a household machine's motor of about
#: 70 W at 1000 r/min of the shaft after the belt gives about 0.67 N m; 0.5 N m is a margin]
NEEDLE_VIEW_TORQUE_NMM = 500.0
#: needle penetration resistance of thick material, N [estimate: several layers of denim with a
#: size 100-110 needle take some 5-10 N]
PENETRATION_RESISTANCE_N = 8.0


def dynamics_section(figs, machine: Machine, variants: Sequence[Machine] = (), *,
                     inputs: dict[str, float] | None = None, rpm: float | None = None,
                     loads=None, gravity: bool = True) -> pd.DataFrame:
    """Add the dynamics figures to ``figs`` (:class:`~sewmech.app.drawing.figures.Figures`); return the key figures.

    inputs: setting inputs, rad (default: the stitch regulator at its longest forward stitch);
    rpm: shaft speed (default: the file's); loads: process loads (default: the file's);
    gravity: the links' weights.
    """
    from ..drawing.figures import subplots

    s = machine.spec.sewing
    settings = dict(inputs or {})
    if not settings and s is not None and s.regulator is not None:
        settings = {s.regulator: math.radians(FD.regulator_range_deg(machine)[1])}
    phi_deg = np.arange(0.0, 360.0, 1.0)
    phi = np.radians(phi_deg)
    rpm = machine.rpm if rpm is None else rpm
    common = {"inputs": settings, "gravity": gravity}
    full = inverse_dynamics(machine, phi, rpm=rpm, loads=loads, **common)
    noload = inverse_dynamics(machine, phi, rpm=rpm, loads=[], **common)
    rest = inverse_dynamics(machine, phi, omega=1e-6, loads=loads, **common)
    at = "".join(f", {k} at {math.degrees(v):g} deg" for k, v in settings.items())
    rows = []
    kinks = arc_cam_note(machine)

    # ---- driving torque -------------------------------------------------------------------------
    fig, ax = subplots(figsize=(9, 4), constrained_layout=True)
    ax.plot(phi_deg, full.input_torque * 1e-3, lw=1.6, label="with the process loads")
    ax.plot(phi_deg, noload.input_torque * 1e-3, lw=1.2, ls="--", label="no load")
    ax.plot(phi_deg, rest.input_torque * 1e-3, lw=1.0, ls=":", label="at rest (loads, weights)")
    for k, name in enumerate(full.load_names):
        on = full.load_on[:, k] > 0.5  # its windows and its conditions on the motion
        ax.fill_between(phi_deg, 0, 1, where=on, transform=ax.get_xaxis_transform(),
                        color=f"C{k + 3}", alpha=0.12, step="mid", label=name)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("shaft angle phi [deg]")
    ax.set_ylabel("driving torque [N m]")
    ax.set_xticks(np.arange(0, 361, 30))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title(f"{machine.name}: torque on the upper shaft at {rpm:g} rpm{at}")
    figs.add(fig, "dyn-torque", "Driving torque",
             "The motor's torque on the upper shaft over one revolution with the process loads"
             " of the machine file (shaded: where each acts, its windows and its conditions on"
             " the motion), without them (the no-load torque at working speed: inertia, weights,"
             " springs and friction), and at rest (what the weights, springs and loads alone"
             " ask)." + kinks,
             pd.DataFrame({"phi_deg": phi_deg, "torque_Nm": full.input_torque * 1e-3,
                           "no_load_torque_Nm": noload.input_torque * 1e-3,
                           "static_torque_Nm": rest.input_torque * 1e-3}))
    tq = full.input_torque * 1e-3
    rows += [("peak driving torque", float(np.abs(tq).max()), "N m"),
             ("RMS driving torque", float(np.sqrt(np.mean(tq ** 2))), "N m"),
             ("mean driving torque (with loads)", float(tq.mean()), "N m"),
             ("mean no-load torque at working speed (friction)",
              float(noload.input_torque.mean() * 1e-3), "N m"),
             ("peak no-load torque at working speed",
              float(np.abs(noload.input_torque).max() * 1e-3), "N m"),
             ("peak power", float(np.abs(full.input_power).max() * 1e-3), "W"),
             ("mean power with loads", float(full.input_power.mean() * 1e-3), "W"),
             ("friction loss (mean)", float(full.friction_power.mean() * 1e-3), "W"),
             ("dampers' loss (mean)", float(full.damping_power.mean() * 1e-3), "W"),
             ("loads' dissipation (mean)", float(-full.external_power.mean() * 1e-3), "W")]
    rows += _physics_figure(figs, machine, full, settings, rpm, loads, gravity, phi_deg)

    # ---- energy, reduced inertia, speed fluctuation -------------------------------------------
    sf = speed_fluctuation(machine, rpm=rpm, n_phi=720, loads=loads, **common)
    fig, axs = subplots(3, 1, figsize=(9, 7.5), sharex=True, constrained_layout=True)
    axs[0].plot(phi_deg, full.kinetic_energy * 1e-3, label="kinetic T")
    axs[0].plot(phi_deg, (full.potential_energy - full.potential_energy.mean()) * 1e-3,
                label="potential V (about its mean)")
    axs[0].set_ylabel("energy [J]")
    axs[1].plot(phi_deg, full.reduced_inertia * 1e-6 * 1e4, color="C2")
    axs[1].set_ylabel("J(phi) [kg cm^2]")
    sphi = np.degrees(sf.phi)
    axs[2].plot(sphi, sf.omega * 60 / (2 * math.pi), color="C3")
    axs[2].set_ylabel("shaft speed [rpm]")
    axs[2].set_xlabel("shaft angle phi [deg]")
    axs[2].set_xticks(np.arange(0, 361, 30))
    for a in axs:
        a.grid(True, alpha=0.3)
    axs[0].legend(fontsize=7)
    fig.suptitle(f"{machine.name}: energies, reduced inertia and speed under a constant motor"
                 f" torque ({sf.motor_torque * 1e-3:.3g} N m), mean {rpm:g} rpm")
    figs.add(fig, "dyn-energy", "Energy, reduced inertia, speed fluctuation",
             "Kinetic and potential energy, the equivalent moment of inertia at the upper shaft"
             " J(phi) = 2T/omega^2 (hand wheel included), and the shaft speed over the cycle"
             " when a constant motor torque carries the weights and process loads (steady"
             f" cycle): coefficient of speed fluctuation {sf.delta:.4f}.",
             pd.DataFrame({"phi_deg": phi_deg, "kinetic_J": full.kinetic_energy * 1e-3,
                           "potential_J": full.potential_energy * 1e-3,
                           "J_kgm2": full.reduced_inertia * 1e-6,
                           "omega_rad_s": np.interp(phi_deg, sphi, sf.omega)}))
    rows += [("reduced inertia J min", float(full.reduced_inertia.min() * 1e-6), "kg m^2"),
             ("reduced inertia J max", float(full.reduced_inertia.max() * 1e-6), "kg m^2"),
             ("coefficient of speed fluctuation", sf.delta, "1")]

    # ---- shaking force and moment ---------------------------------------------------------------
    F = full.shaking_force
    fig, axs = subplots(1, 2, figsize=(10, 4.6), constrained_layout=True)
    axs[0].plot(F[:, 0], F[:, 1], lw=1.4)
    for k in range(0, 360, 30):
        axs[0].plot(F[k, 0], F[k, 1], "o", ms=3, color="C1")
        axs[0].annotate(f"{k}", F[k], textcoords="offset points", xytext=(3, 2), fontsize=7)
    axs[0].plot(0, 0, "k+")
    axs[0].set_aspect("equal", adjustable="datalim")
    axs[0].set_xlabel("Fx [N]")
    axs[0].set_ylabel("Fy [N]")
    axs[0].set_title("shaking force hodograph (labels: phi deg)")
    axs[1].plot(phi_deg, full.shaking_moment * 1e-3, color="C2")
    axs[1].set_xlabel("shaft angle phi [deg]")
    axs[1].set_ylabel("shaking moment [N m]")
    axs[1].set_xticks(np.arange(0, 361, 60))
    axs[1].set_title("shaking moment about the upper-shaft axis")
    for a in axs:
        a.grid(True, alpha=0.3)
    figs.add(fig, "dyn-shaking", "Shaking force and moment",
             "The resultant of the links' inertia forces (-sum m a_G) that the frame passes to"
             " the table, and its moment about the upper-shaft axis (the motor's reaction"
             " included)." + kinks,
             pd.DataFrame({"phi_deg": phi_deg, "Fx_N": F[:, 0], "Fy_N": F[:, 1],
                           "M_Nm": full.shaking_moment * 1e-3}))
    rows += [("peak shaking force", float(np.linalg.norm(F, axis=-1).max()), "N"),
             ("peak shaking moment", float(np.abs(full.shaking_moment).max() * 1e-3), "N m")]

    # ---- upper-shaft bearings -------------------------------------------------------------------
    if machine.spec.shaft is not None:
        br = full.bearings
        fig, axs = subplots(1, 2, figsize=(10, 4.8), constrained_layout=True,
                                subplot_kw={"projection": "polar"})
        data = {"phi_deg": phi_deg}
        for a, (label, B, z) in zip(axs, (("front", br.front, br.z_front),
                                          ("rear", br.rear, br.z_rear))):
            ang = np.arctan2(B[:, 1], B[:, 0])
            mag = np.linalg.norm(B, axis=-1)
            a.plot(np.append(ang, ang[0]), np.append(mag, mag[0]), lw=1.4)
            for k in range(0, 360, 30):
                a.annotate(f"{k}", (ang[k], mag[k]), fontsize=6)
            a.set_title(f"{label} bearing (z = {z:g} mm), N")
            data[f"{label}_x_N"], data[f"{label}_y_N"] = B[:, 0], B[:, 1]
            rows.append((f"peak {label} bearing reaction", float(mag.max()), "N"))
        fig.suptitle(f"{machine.name}: reactions of the upper shaft's bearings (polar, labels:"
                     " phi deg)")
        figs.add(fig, "dyn-bearings", "Upper-shaft bearing reactions",
                 "The force each bearing puts on the upper shaft, as polar diagrams (direction"
                 " in the machine frame, magnitude in N): the cranks' pair forces act in their"
                 " own planes along the shaft, and the turning parts' products of inertia add a"
                 " couple." + kinks, pd.DataFrame(data))

    # ---- pair forces --------------------------------------------------------------------------
    peak = []
    for pair in full.pairs:
        mag = full.magnitude(pair.name)
        k = int(np.argmax(mag))
        unit = "N m" if pair.kind == "driver" else "N"
        scale = 1e-3 if pair.kind == "driver" else 1.0
        peak.append({"pair": pair.name, "kind": pair.kind, "links": " -> ".join(pair.links),
                     "peak": float(mag[k] * scale), "unit": unit, "at_phi_deg": phi_deg[k],
                     "mean": float(mag.mean() * scale)})
    peak_df = pd.DataFrame(peak)
    forces = peak_df[peak_df.unit == "N"].sort_values("peak")
    fig, ax = subplots(figsize=(9, 0.28 * len(forces) + 1.2), constrained_layout=True)
    ax.barh(forces.pair, forces.peak, color="C0", label="peak")
    ax.barh(forces.pair, forces["mean"], color="C1", alpha=0.7, label="mean")
    ax.set_xlabel("force [N]")
    ax.legend(fontsize=7)
    ax.grid(True, axis="x", alpha=0.3)
    ax.set_title(f"{machine.name}: pair forces over the cycle")
    figs.add(fig, "dyn-pairs", "Forces in the pairs",
             "Largest and mean force in every pair over the cycle (revolute: |F|; slider: the"
             " normal force; cam and slot: the contact force). Per-angle values of every"
             " component are in the CSV.", pair_forces_frame(full), table=peak_df.round(4))

    # ---- force transmission ---------------------------------------------------------------------
    pa = pressure_angles(machine, phi, inputs=settings)
    fig, ax = subplots(figsize=(9, 4.2), constrained_layout=True)
    for name, a in pa.angles.items():
        ax.plot(phi_deg, a, lw=1.2, label=name)
    ax.axhline(45.0, color="k", lw=0.8, ls="--")
    ax.set_ylim(0, 90)
    ax.set_xlabel("shaft angle phi [deg]")
    ax.set_ylabel("pressure angle [deg]")
    ax.set_xticks(np.arange(0, 361, 30))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title(f"{machine.name}: pressure angles (0: the force all drives)")
    worst = pd.DataFrame([{"mechanism": n, "worst_deg": a, "at_phi_deg": p, "measured": pa.what[n]}
                          for n, a, p in pa.worst()])
    figs.add(fig, "dyn-pressure", "Force transmission: pressure angles",
             "Angle between the force a mechanism passes on and the motion it drives (dashed:"
             " 45 deg, the usual limit for linkages).",
             pd.DataFrame({"phi_deg": phi_deg, **pa.angles}), table=worst.round(2))

    if s is not None and s.regulator is not None:
        fig, ax = subplots(figsize=(9, 4), constrained_layout=True)
        data = {"phi_deg": np.arange(0.0, 360.0, 5.0)}
        table = []
        for k, mm in enumerate([machine] + list(variants)):
            lo, hi = FD.regulator_range_deg(mm)
            for j, setting in enumerate((lo, 0.0, hi)):
                tau = regulator_torques(mm, [setting], rpm=rpm)[setting] * 1e-3
                ax.plot(data["phi_deg"], tau, color=f"C{k}", ls=("-", ":", "--")[j], lw=1.2,
                        label=f"{mm.name}, regulator {setting:+g} deg")
                data[f"{mm.name}_{setting:+g}deg_Nm"] = tau
                table.append({"machine": mm.name, "regulator_deg": setting,
                              "peak_holding_torque_Nm": float(np.abs(tau).max()),
                              "mean_Nm": float(tau.mean())})
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_xlabel("shaft angle phi [deg]")
        ax.set_ylabel("torque on the regulator [N m]")
        ax.set_xticks(np.arange(0, 361, 30))
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
        ax.set_title("what must hold the stitch setting")
        figs.add(fig, "dyn-regulator", "Torque on the stitch regulator",
                 "The torque that the feed mechanism's forces put on the regulator slot over"
                 " the cycle, at reverse, zero and forward settings, for this machine and its"
                 " variants (regulator designs compared): the detent or friction must exceed"
                 " its peak." + kinks, pd.DataFrame(data), table=pd.DataFrame(table).round(5))
        rows.append(("peak torque on the regulator (forward)",
                     float(np.abs(full.setting_torques[s.regulator]).max() * 1e-3), "N m"))

    if s is not None:
        nf = needle_force(machine, NEEDLE_VIEW_TORQUE_NMM, rpm=rpm)
        fig, ax = subplots(figsize=(7, 4), constrained_layout=True)
        order = np.argsort(nf.depth)
        ax.plot(nf.depth[order], nf.force[order], lw=1.6, label=f"available at"
                f" {NEEDLE_VIEW_TORQUE_NMM * 1e-3:g} N m on the shaft")
        ax.axhline(PENETRATION_RESISTANCE_N, color="C3", ls="--",
                   label=f"penetration resistance {PENETRATION_RESISTANCE_N:g} N")
        ax.set_xlabel("needle point below the plate top [mm]")
        ax.set_ylabel("needle force [N]")
        ax.set_ylim(0, max(4 * PENETRATION_RESISTANCE_N, 1.0))
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
        ax.set_title(f"{machine.name}: sewing thick material")
        short = nf.depth[nf.force < PENETRATION_RESISTANCE_N]
        limit = float(short.min()) if short.size else float(nf.depth.max())
        figs.add(fig, "dyn-needle", "Needle force through thick material",
                 "The force the needle can push with along its descent below the plate when"
                 f" the shaft gives {NEEDLE_VIEW_TORQUE_NMM * 1e-3:g} N m (less the no-load"
                 " torque at working speed), by virtual work; it falls towards bottom dead"
                 f" centre. Against {PENETRATION_RESISTANCE_N:g} N of resistance the needle"
                 f" gets {limit:.2f} mm deep [torque and resistance are estimates].",
                 pd.DataFrame({"phi_deg": nf.phi_deg, "depth_mm": nf.depth, "force_N": nf.force}))
        rows.append((f"needle depth reached against {PENETRATION_RESISTANCE_N:g} N", limit, "mm"))
    return pd.DataFrame(rows, columns=["quantity", "value", "unit"])


def _physics_figure(figs, machine: Machine, full, settings, rpm, loads, gravity,
                    phi_deg) -> list[tuple]:
    """The machine's own physics: the friction each pair takes, the springs' forces and the
    one-sided contacts' forces with their margins and opening speeds (a figure when the
    machine has any of them); returns its key-figure rows."""
    from ...engine.contacts import contact_margins
    from ..drawing.figures import subplots

    contacts = contact_margins(machine, rpm=rpm, inputs=settings, loads=loads, gravity=gravity)
    fr, sp = full.friction, full.springs
    panels = [p for p, have in (("friction", fr is not None), ("springs", bool(sp and sp.names)),
                                ("contacts", bool(contacts))) if have]
    rows = []
    for c in contacts:
        rows.append((f"least force in the one-sided contact {c.name} (at phi"
                     f" {c.at_phi_deg:.1f} deg; margin {c.margin_N:g} N:"
                     f" {'holds' if c.ok else 'FAILS'})", c.least_force_N, "N"))
        rows.append((f"speed above which {c.name} opens", c.opens_above_rpm
                     if c.opens_above_rpm is not None else float("nan"), "rpm"))
    if not panels:
        return rows
    fig, axs = subplots(len(panels), 1, figsize=(9, 3.2 * len(panels) + 0.6),
                        constrained_layout=True, squeeze=False)
    data = {"phi_deg": phi_deg}
    for ax, panel in zip(axs[:, 0], panels):
        if panel == "friction":
            loss = fr.power.mean(axis=0) * 1e-3
            order = np.argsort(loss)
            ax.barh([fr.pairs[i] for i in order], loss[order], color="C3")
            ax.set_xlabel("friction loss, mean over the turn [W]")
            ax.set_title(f"friction in the pairs: {loss.sum():.3g} W in all")
            ax.tick_params(axis="y", labelsize=7)
            for j, name in enumerate(fr.pairs):
                data[f"friction_W: {name}"] = fr.power[:, j] * 1e-3
        elif panel == "springs":
            for j, name in enumerate(sp.names):
                torsion = j >= sp.n_translational
                ax.plot(phi_deg, sp.force[:, j] * (1e-3 if torsion else 1.0),
                        label=f"{name} [{'N m' if torsion else 'N'}]")
                data[f"spring: {name}"] = sp.force[:, j] * (1e-3 if torsion else 1.0)
            ax.set_ylabel("spring force")
            ax.set_xlabel("shaft angle phi [deg]")
            ax.legend(fontsize=7)
        else:
            for j, c in enumerate(contacts):
                n = full.pair(c.name)[..., 0]
                opens = ("never below 100 x" if c.opens_above_rpm is None
                         else f"opens above {c.opens_above_rpm:.0f} rpm")
                ax.plot(phi_deg, n, color=f"C{j}", label=f"{c.name} ({opens})")
                ax.axhline(c.margin_N, color=f"C{j}", lw=0.8, ls="--")
                ax.plot([c.at_phi_deg], [c.least_force_N], "o", color=f"C{j}", ms=4)
                data[f"contact_N: {c.name}"] = n
            ax.axhline(0.0, color="k", lw=0.6)
            ax.set_ylabel("contact force [N]")
            ax.set_xlabel("shaft angle phi [deg]")
            ax.set_title("one-sided contacts (dashed: the margin each must keep)")
            ax.legend(fontsize=7)
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"{machine.name}: friction, springs and contacts at {rpm:g} rpm")
    figs.add(fig, "dyn-physics", "Friction, springs and one-sided contacts",
             "The machine's own physics (docs/dynamics.md): the power friction takes in each"
             " pair (mean over the turn), the springs' forces, and the force in every one-sided"
             " contact with the margin it must keep; the speed above which each contact opens"
             " is found on the whole analysis (the inertia forces grow with the square of the"
             " speed, springs, weights and loads do not).", pd.DataFrame(data))
    return rows
