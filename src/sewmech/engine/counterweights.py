"""Counterweights: point masses added to moving links (``[counterweights.NAME]``).

A counterweight is given by its mass at a point of its link's frame, or by its static moment
S = m r at an angle and a radius (the balancing paper's way: the inertia force of a
counterweight on a crank depends on S alone). Either way its values are parameters of the
machine, so that designs in a batch can differ in them; :func:`counterweight_values` turns a
batch of parameter vectors into mass and position.

Units: mass kg, positions mm, static moment kg mm (1 kg mm = 100 g cm), angles rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

#: 1 kg mm of static moment in g cm
GCM_PER_KGMM = 100.0


@dataclass(frozen=True)
class Counterweight:
    """A compiled counterweight.

    name : its table name; link : the link it is on (``link_index`` into the link names);
    origin : the point at the origin of the link frame; z : its axial plane, mm (NaN: not
    given); by_moment : given as static moment, angle and radius (else mass and (u, v));
    params : indices of its three parameters (mass kg, u mm, v mm; or static moment kg mm,
    angle rad, radius mm).
    """

    name: str
    link: str
    link_index: int
    origin: str
    z: float
    by_moment: bool
    params: tuple[int, int, int]


#: parameter names and units of each way of giving a counterweight
PARAMETERS = {False: (("mass", "kg"), ("u", "mm"), ("v", "mm")),
              True: (("static_moment", "kg mm"), ("angle", "rad"), ("radius", "mm"))}


def counterweight_values(counterweights: tuple[Counterweight, ...], params: ArrayLike
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mass (kg) and link-frame position u, v (mm) of each counterweight for parameter vectors
    ``params`` (batch + (n_parameters,)); each result has shape batch + (n_counterweights,)."""
    P = np.asarray(params, dtype=float)
    n = len(counterweights)
    m, u, v = (np.empty(P.shape[:-1] + (n,)) for _ in range(3))
    for k, cw in enumerate(counterweights):
        a, b, c = (P[..., i] for i in cw.params)
        if cw.by_moment:  # S, angle, radius
            m[..., k] = a / c
            u[..., k] = c * np.cos(b)
            v[..., k] = c * np.sin(b)
        else:
            m[..., k], u[..., k], v[..., k] = a, b, c
    return m, u, v


def static_moment(mass: ArrayLike, u: ArrayLike, v: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(S kg mm, angle rad in (-pi, pi]) of point masses ``mass`` (kg) at (u, v) (mm)."""
    m = np.asarray(mass, dtype=float)
    return m * np.hypot(u, v), np.arctan2(v, u)


def describe(cw: Counterweight, mass: float, u: float, v: float) -> dict:
    """One counterweight in the units people use: static moment g cm, angle deg, mass g,
    radius and u, v mm."""
    S, ang = static_moment(mass, u, v)
    return {"link": cw.link, "static_moment_gcm": float(S) * GCM_PER_KGMM,
            "angle_deg": math.degrees(float(ang)) + 0.0,  # (+ 0.0: never "-0 deg")
            "mass_g": 1e3 * float(mass),
            "radius_mm": float(math.hypot(u, v)), "u_mm": float(u), "v_mm": float(v)}


@dataclass(frozen=True, eq=False)
class CounterweightMotion:
    """The counterweights of a dynamics result (:class:`sewmech.dynamics.DynamicsResult`).

    names; links : link index of each (n_cw,); z : axial plane of each, mm (NaN: not given);
    mass : kg, batch + (n_cw,); p, v, a : position, velocity, acceleration of each,
    batch + (n_phi, n_cw, 2), mm, mm/s, mm/s^2.
    """

    names: tuple[str, ...]
    links: np.ndarray
    z: np.ndarray
    mass: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray

    def inertia_force(self) -> np.ndarray:
        """Sum of the counterweights' inertia forces -m a, N, batch + (n_phi, 2)."""
        return -1e-3 * np.einsum("...c,...kcx->...kx", self.mass, self.a)

    def moment_of_inertia_forces(self) -> np.ndarray:
        """Sum of the moments of the inertia forces about the frame origin, -m (p x a), N mm,
        batch + (n_phi,)."""
        cross = self.p[..., 0] * self.a[..., 1] - self.p[..., 1] * self.a[..., 0]
        return -1e-3 * np.einsum("...c,...kc->...k", self.mass, cross)

    def kinetic_energy(self) -> np.ndarray:
        """1/2 sum m |v|^2, N mm, batch + (n_phi,)."""
        return 0.5e-3 * np.einsum("...c,...kc->...k", self.mass, np.sum(self.v ** 2, axis=-1))

    def kinetic_energy_rate(self) -> np.ndarray:
        """sum m v.a, N mm/s, batch + (n_phi,)."""
        return 1e-3 * np.einsum("...c,...kc->...k", self.mass,
                                np.sum(self.v * self.a, axis=-1))

    def weight_height(self) -> np.ndarray:
        """sum m y, kg mm, batch + (n_phi,) (times g: potential energy in N mm)."""
        return np.einsum("...c,...kc->...k", self.mass, self.p[..., 1])

    def weight_rate(self) -> np.ndarray:
        """sum m v_y, kg mm/s, batch + (n_phi,)."""
        return np.einsum("...c,...kc->...k", self.mass, self.v[..., 1])
