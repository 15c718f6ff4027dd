"""Applied forces of the force analysis: process loads, evaluated from the motion.

Every applied force acts at a point of a link (or of the frame, where it is only recorded).
The force kernel (:func:`sewmech._kernels.force_solve`) reads them as generalized forces per
link, in the rows of the Newton-Euler equations: the sum of their x and y components (N) and of
their moments about the link's centre of mass (N mm); :func:`add_point_force` puts one force
there.

A process load (``[[loads]]``, :class:`~sewmech.spec.LoadSpec`) acts inside its shaft-angle
windows, along a fixed direction or along the bisector of the unit vectors from its point
toward other points (a thread over the point to two guides). :class:`LoadTables` prepares the
loads of a machine once for a grid of shaft angles; :meth:`LoadTables.forces` evaluates them
for a batch of designs.

Units: positions mm, velocities mm/s, forces N, moments N mm, power N mm/s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .machine import Machine
from .spec import LoadSpec


def in_windows(phi_deg: np.ndarray, windows: Sequence[tuple[float, float]]) -> np.ndarray:
    """Mask of shaft angles (deg) inside any of the windows [start, end] (deg); a window with
    end < start wraps through 360; a window of 360 deg or more is the whole cycle."""
    a = np.mod(phi_deg, 360.0)
    out = np.zeros(np.shape(phi_deg), dtype=bool)
    for w0, w1 in windows:
        if w1 - w0 >= 360.0:
            return np.ones(np.shape(phi_deg), dtype=bool)
        s, e = w0 % 360.0, w1 % 360.0
        tol = 1e-9
        out |= ((a >= s - tol) & (a <= e + tol)) if s <= e else ((a >= s - tol) | (a <= e + tol))
    return out


def add_point_force(XB: np.ndarray, link: int, at: np.ndarray, F: np.ndarray,
                    com: np.ndarray) -> None:
    """Add a force ``F`` (..., 2) N acting at ``at`` (..., 2) mm on link ``link`` to the
    generalized forces ``XB`` (..., n_eq) (nothing for the frame, link 0); ``com`` (...,
    n_links, 2): the links' centres of mass, mm."""
    if link == 0:
        return
    r = 3 * (link - 1)
    XB[..., r] += F[..., 0]
    XB[..., r + 1] += F[..., 1]
    dx = at - com[..., link, :]
    XB[..., r + 2] += dx[..., 0] * F[..., 1] - dx[..., 1] * F[..., 0]


def add_couple(XB: np.ndarray, link: int, M: np.ndarray) -> None:
    """Add a couple ``M`` (...) N mm on link ``link`` to ``XB`` (nothing for the frame)."""
    if link:
        XB[..., 3 * (link - 1) + 2] += M


@dataclass(frozen=True)
class LoadTables:
    """The process loads of a machine, prepared for the shaft angles ``phi_deg``.

    links, points: (n_loads,) link and point indices; on: (n_loads, n_phi) 1.0 inside the
    windows; force_N: (n_loads,); direction: (n_loads, 2) the fixed direction (cos, sin), or
    None rows for loads along a bisector, whose ``toward`` point indices are in ``toward``."""

    names: tuple[str, ...]
    links: tuple[int, ...]
    points: tuple[int, ...]
    force_N: np.ndarray
    on: np.ndarray
    direction: tuple[tuple[float, float] | None, ...]
    toward: tuple[tuple[int, ...], ...]

    @classmethod
    def build(cls, machine: Machine, loads: Sequence[LoadSpec], phi_deg: np.ndarray
              ) -> LoadTables:
        names, links, points, force, on, direction, toward = [], [], [], [], [], [], []
        masks: dict[tuple, np.ndarray] = {}
        for load in loads:
            key = tuple(map(tuple, load.windows_deg))
            if key not in masks:
                masks[key] = in_windows(phi_deg, load.windows_deg).astype(float)
            names.append(load.name)
            on.append(masks[key])
            links.append(machine.link_index(load.link))
            points.append(machine.point_index(load.point))
            force.append(load.force_N)
            if load.angle_deg is not None:
                a = math.radians(load.angle_deg)
                direction.append((math.cos(a), math.sin(a)))
                toward.append(())
            else:
                direction.append(None)
                toward.append(tuple(machine.point_index(q) for q in load.toward))
        return cls(tuple(names), tuple(links), tuple(points), np.asarray(force, dtype=float),
                   np.asarray(on, dtype=float).reshape(len(loads), len(phi_deg)),
                   tuple(direction), tuple(toward))

    def __len__(self) -> int:
        return len(self.names)

    def forces(self, P: np.ndarray, V: np.ndarray, LF: np.ndarray, LPOW: np.ndarray) -> None:
        """Fill LF (D, n_phi, n_loads, 2) with each load's force, N, and LPOW (D, n_phi) with
        their power on the machine, N mm/s, from the points' positions P and velocities V
        (D, n_phi, n_points, 2)."""
        LPOW[...] = 0.0
        for j in range(len(self)):
            pi = self.points[j]
            d = self.direction[j]
            if d is not None:
                u = np.array(d)
            else:  # the bisector of the unit vectors toward the given points
                u = np.zeros(P.shape[:2] + (2,))
                for q in self.toward[j]:
                    e = P[:, :, q] - P[:, :, pi]
                    u += e / np.sqrt(e[..., :1] ** 2 + e[..., 1:] ** 2)
                u /= np.sqrt(u[..., :1] ** 2 + u[..., 1:] ** 2)
            f = self.force_N[j] * self.on[j]
            LF[:, :, j] = f[:, None] * u
            LPOW += LF[:, :, j, 0] * V[:, :, pi, 0] + LF[:, :, j, 1] * V[:, :, pi, 1]

    def generalized(self, P: np.ndarray, GP: np.ndarray, LF: np.ndarray,
                    XB: np.ndarray) -> None:
        """Add the loads' forces LF at their points to the generalized forces XB."""
        for j in range(len(self)):
            add_point_force(XB, self.links[j], P[:, :, self.points[j]], LF[:, :, j], GP)
