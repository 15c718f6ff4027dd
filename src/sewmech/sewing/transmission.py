"""Force transmission (the JB dynamics report's 传力特性): pressure angles of every mechanism,
the torque on the stitch regulator, and the needle force for sewing thick material.

Angles are returned in degrees (they are read, not computed with); forces N, torques N mm.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..engine.dynamics import DynamicsResult, _first_point, inverse_dynamics, pair_geometry
from ..engine.kinematics import kinematics
from ..engine.machine import Machine


@dataclass(frozen=True)
class PressureAngles:
    """Pressure angle (deg, 0 = all of the force drives, 90 = none) of each mechanism over the
    cycle: ``angles[name]`` has shape (n_phi,); NaN where the driven point stands still."""

    phi_deg: np.ndarray
    angles: dict[str, np.ndarray]
    what: dict[str, str]

    def worst(self) -> list[tuple[str, float, float]]:
        """(name, largest pressure angle deg, at phi deg) of each mechanism, worst first."""
        out = []
        for name, a in self.angles.items():
            if np.isfinite(a).any():
                k = int(np.nanargmax(a))
                out.append((name, float(a[k]), float(self.phi_deg[k])))
        return sorted(out, key=lambda t: -t[1])


def _fold(angle: np.ndarray) -> np.ndarray:
    """An angle between two lines (rad) -> the acute angle, deg in [0, 90]."""
    return np.degrees(np.abs(np.arcsin(np.abs(np.sin(angle)))))


def _between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Acute angle (deg) between the lines of two vectors (..., 2); NaN for a zero vector."""
    nu = np.linalg.norm(u, axis=-1)
    nv = np.linalg.norm(v, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.abs(np.sum(u * v, axis=-1)) / (nu * nv)
        out = np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))
    scale = np.nanmax(nv) if np.isfinite(nv).any() else 1.0
    return np.where(nv > 1e-9 * max(scale, 1e-300), out, np.nan)


def pressure_angles(machine: Machine, phi: ArrayLike, *,
                    inputs: Mapping[str, ArrayLike] | None = None,
                    params: ArrayLike | None = None) -> PressureAngles:
    """Pressure angles of every dyad, slider and cam/slot contact of a machine (one design:
    ``params``, default the file's).

    - RRR dyad: the force comes along the first link (a two-force member) and the new joint
      moves square to the second link: 90 deg minus the transmission angle between them.
    - slider (RRP): the force along the rod against the guide direction.
    - cam contacts: the force along the contact normal against the velocity of the follower's
      material point at the contact; slot contacts (a pin or roller pushing the sides of a
      slot or a flat): the same against the slotted link's point (NaN where it stands still,
      as a stitch regulator's slot does).
    """
    kin = kinematics(machine, phi, params=params, inputs=inputs, omega=1.0)
    if params is None:
        P = machine.defaults if not inputs else machine.parameters(inputs=inputs)
    else:
        P = machine.parameters(inputs=inputs, base=params) if inputs else np.asarray(params)
    out: dict[str, np.ndarray] = {}
    what: dict[str, str] = {}
    for u in machine.spec.units:
        if u.type == "rrr":
            d = kin.link(u.links[0]).theta - kin.link(u.links[1]).theta
            out[u.name] = 90.0 - _fold(d)
            what[u.name] = f"90 deg - angle between {u.links[0]} and {u.links[1]} at {u.new}"
        elif u.type == "rrp":
            d = kin.link(u.rod).theta - kin.link(u.slider).theta
            out[u.name] = _fold(d)
            what[u.name] = f"{u.rod} against the guide of {u.slider}"
    X_all, N_all = pair_geometry(machine, kin, P)
    for i, pair in enumerate(machine.pairs):
        if pair.kind not in ("cam", "slot"):
            continue
        n, X = N_all[:, i], X_all[:, i]
        driven = pair.links[1] if pair.kind == "cam" else pair.links[0]
        mo = kin.point(_first_point(machine, driven))
        w = kin.link(driven).omega
        r = X - mo.p
        v = mo.v + w[..., None] * np.stack([-r[..., 1], r[..., 0]], axis=-1)
        out[pair.name] = _between(n, v)
        what[pair.name] = f"contact normal against the motion of {driven}"
        if not np.isfinite(out[pair.name]).any():
            del out[pair.name], what[pair.name]  # a guide that does not move: nothing driven
    return PressureAngles(kin.phi_deg, out, what)


@dataclass(frozen=True)
class NeedleForce:
    """Needle force the shaft can give along the stroke (quasi-static, beyond inertia).

    Attributes
    ----------
    phi_deg : (n,) shaft angles of the descent, deg
    depth : (n,) mm below the throat plate's top of the needle point (positive: below)
    force : (n,) N, the force the needle can push with: (torque - no-load torque) / (-dy/dphi)
    torque : N mm, the shaft torque assumed
    """

    phi_deg: np.ndarray
    depth: np.ndarray
    force: np.ndarray
    torque: float


def needle_force(machine: Machine, torque_Nmm: float, *, rpm: float | None = None,
                 n_phi: int = 720) -> NeedleForce:
    """The needle's available force through the fabric for a given shaft torque (N mm).

    At each angle of the needle's descent, the torque that is left after the no-load driving
    torque at ``rpm`` (inertia, weights; no process loads) pushes the needle with
    F = (M - M_0) / (-dy/dphi) (virtual work; dy/dphi in mm/rad). Only angles where the needle
    point is at or below the plate's top are returned.
    """
    sew = machine.spec.sewing
    if sew is None:
        raise ValueError(f"machine '{machine.name}' has no [sewing] table (needle point, plate)")
    phi = np.linspace(0.0, 2 * math.pi, n_phi, endpoint=False)
    res = inverse_dynamics(machine, phi, rpm=rpm, loads=[])
    needle = res.kin.point(sew.needle_point)
    dy = needle.v[:, 1] / res.kin.omega_shaft  # mm/rad
    y = needle.p[:, 1]
    down = (dy < 0) & (y <= sew.plate_y)
    with np.errstate(divide="ignore"):
        force = (torque_Nmm - res.input_torque) / (-dy)
    return NeedleForce(res.phi_deg[down], sew.plate_y - y[down], force[down], torque_Nmm)


def regulator_torques(machine: Machine, settings_deg: Sequence[float], *,
                      rpm: float | None = None, n_phi: int = 72) -> dict[float, np.ndarray]:
    """Torque (N mm) that holds the stitch regulator, over the cycle, at each setting (deg)."""
    sew = machine.spec.sewing
    if sew is None or sew.regulator is None:
        raise ValueError(f"machine '{machine.name}' names no stitch regulator ([sewing])")
    phi = np.linspace(0.0, 2 * math.pi, n_phi, endpoint=False)
    P = machine.parameters(inputs={sew.regulator: np.radians(settings_deg)})
    res: DynamicsResult = inverse_dynamics(machine, phi, params=P, rpm=rpm)
    tau = res.setting_torques[sew.regulator]
    return {float(s): tau[k] for k, s in enumerate(settings_deg)}


__all__ = ["NeedleForce", "PressureAngles", "needle_force", "pressure_angles",
           "regulator_torques"]
