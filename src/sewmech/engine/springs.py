"""Springs and dampers of the force analysis (``[[springs]]``, ``[[torsion_springs]]``).

A translational spring-damper joins two points, each on a link or on the frame. With L its
length and L0 its free length (mm), its tension (N, positive when it pulls its ends together)
is T = k (L - L0) + c dL/dt; it pulls each end toward the other. Its potential energy is
k (L - L0)^2 / 2 (N mm) and its damper takes c (dL/dt)^2 (N mm/s) out of the machine.

A torsional spring-damper sits at a revolute pair: with theta the pair's relative angle (its
second link's angle less its first's, rad) and theta0 its free angle, its moment on the second
link is M = -(k d + c dtheta/dt), d = theta - theta0 taken in (-pi, pi] (a spring that winds
more than half a turn either way is not one sewmech can read), and -M on the first. Potential
energy k d^2 / 2, damping loss c (dtheta/dt)^2.

Units: k in N/mm (translational) or N mm/rad (torsional; the file gives N mm/deg), c in N s/mm
or N mm s/rad, forces N, moments N mm, energies N mm, powers N mm/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import AnalysisError
from .loads import add_couple, add_point_force
from .machine import Machine

#: how far a torsion spring may be wound from its free angle, rad (170 deg): beyond it the
#: relative angle of its pair is not told apart from one a turn away
WIND_LIMIT = math.radians(170.0)


@dataclass(frozen=True)
class SpringTables:
    """The machine's springs prepared for the force analysis (indices and values in sewmech's
    units; see the module doc)."""

    names: tuple[str, ...]
    ends: tuple[tuple[int, int, int, int], ...]  # translational: link a, point a, link b, point b
    k: np.ndarray  # N/mm
    free: np.ndarray  # mm
    c: np.ndarray  # N s/mm
    torsion_names: tuple[str, ...]
    torsion_links: tuple[tuple[int, int], ...]  # the pair's first and second link
    kt: np.ndarray  # N mm/rad
    free_angle: np.ndarray  # rad
    ct: np.ndarray  # N mm s/rad

    @classmethod
    def build(cls, machine: Machine) -> SpringTables:
        spec = machine.spec
        pairs = {p.name: p for p in machine.pairs}
        ends = tuple((machine.link_index(s.links[0]), machine.point_index(s.points[0]),
                      machine.link_index(s.links[1]), machine.point_index(s.points[1]))
                     for s in spec.springs)
        tl = tuple((machine.link_index(pairs[s.pair].links[0]),
                    machine.link_index(pairs[s.pair].links[1])) for s in spec.torsion_springs)
        deg = 180.0 / math.pi
        return cls(tuple(s.name for s in spec.springs), ends,
                   np.array([s.stiffness_N_per_mm for s in spec.springs]),
                   np.array([s.free_length for s in spec.springs]),
                   np.array([s.damping_N_s_per_mm for s in spec.springs]),
                   tuple(s.name for s in spec.torsion_springs), tl,
                   np.array([s.stiffness_N_mm_per_deg * deg for s in spec.torsion_springs]),
                   np.radians([s.free_angle for s in spec.torsion_springs]),
                   np.array([s.damping_N_mm_s_per_deg * deg for s in spec.torsion_springs]))

    def __len__(self) -> int:
        return len(self.names) + len(self.torsion_names)

    @property
    def all_names(self) -> tuple[str, ...]:
        return self.names + self.torsion_names

    def evaluate(self, a: dict[str, np.ndarray], XB: np.ndarray, out: dict[str, np.ndarray]
                 ) -> None:
        """Add every spring's forces to the generalized forces XB (D, n_phi, n_eq) and fill
        ``out``: ``SF`` (D, n_phi, n_springs) each one's tension (N) or moment on its pair's
        second link (N mm), ``SL`` its length (mm) or relative angle (rad), ``SE`` the
        springs' potential energy (D, n_phi) N mm, ``SER`` its rate and ``SD`` the dampers'
        loss, N mm/s. Translational springs first, then the torsion springs."""
        P, V, TH, OM, GP = a["P"], a["V"], a["TH"], a["OM"], a["GP"]
        SF, SL = out["SF"], out["SL"]
        out["SE"][...] = 0.0
        out["SER"][...] = 0.0
        out["SD"][...] = 0.0
        n = len(self.names)
        for j, (la, pa, lb, pb) in enumerate(self.ends):
            d = P[:, :, pb] - P[:, :, pa]
            L = np.sqrt(np.sum(d * d, axis=-1))
            u = d / L[..., None]
            Ld = np.sum(u * (V[:, :, pb] - V[:, :, pa]), axis=-1)
            stretch = L - self.free[j]
            T = self.k[j] * stretch + self.c[j] * Ld
            SF[:, :, j], SL[:, :, j] = T, L
            F = T[..., None] * u  # on end a, toward b; end b takes -F
            add_point_force(XB, la, P[:, :, pa], F, GP)
            add_point_force(XB, lb, P[:, :, pb], -F, GP)
            out["SE"] += 0.5 * self.k[j] * stretch * stretch
            out["SER"] += self.k[j] * stretch * Ld
            out["SD"] += self.c[j] * Ld * Ld
        for j, (la, lb) in enumerate(self.torsion_links):
            rel = TH[:, :, lb] - TH[:, :, la]
            d = np.mod(rel - self.free_angle[j] + math.pi, 2.0 * math.pi) - math.pi
            if (np.abs(d) > WIND_LIMIT).any():
                k = np.argwhere(np.abs(d) > WIND_LIMIT)[0]
                raise AnalysisError(f"torsion spring '{self.torsion_names[j]}'", "its pair"
                                    " turns more than 170 deg away from its free angle"
                                    f" (position {int(k[1])} of the turn): a pair that turns"
                                    " round is no place for a torsion spring",
                                    "Put it at a pair that rocks, or use a translational"
                                    " spring")
            w = OM[:, :, lb] - OM[:, :, la]
            M = -(self.kt[j] * d + self.ct[j] * w)
            SF[:, :, n + j], SL[:, :, n + j] = M, rel
            add_couple(XB, lb, M)
            add_couple(XB, la, -M)
            out["SE"] += 0.5 * self.kt[j] * d * d
            out["SER"] += self.kt[j] * d * w
            out["SD"] += self.ct[j] * w * w
