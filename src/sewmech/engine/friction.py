"""Friction in the pairs (``[friction]``): Coulomb friction with an optional viscous part.

A revolute pair carries a friction moment mu r |F| about its pin (r: the pin's radius, |F|:
the pin force), a prismatic pair a friction force mu |N| along its guide, a cam or slot contact
mu N along the contact's tangent; each acts against the relative motion of the pair's two links
(the sign smoothed as v / sqrt(v^2 + s^2) below the sliding speed s, ``smooth_mm_s``; a
revolute pair's sliding speed is its relative angular velocity times r), and a viscous part adds
``viscous_N_mm_s`` per unit of relative speed. Friction depends on the pair forces, which
depend on the friction: the force analysis becomes nonlinear. The force kernel
(:func:`sewmech.engine._kernels.force_solve`) solves it at every position by fixed-point
iteration from the frictionless solution (each step a solve with the friction of the last step
as applied forces), accelerated by Anderson's method (each position's next step the combination
of its last four that best cancels their changes), to a change below 1e-10 of each design's
largest force. Friction enters only the right-hand sides (the applied forces), not the matrix,
which depends on the positions alone: the kernel factors each position's equations once and
runs a design's whole iteration with those factors, so that a step costs a back-substitution,
the friction forces and Anderson's update. Where it does not settle the mechanism is
self-locking or near it, and the analysis says where.

mu = 0 everywhere (or no ``[friction]`` table) is the frictionless analysis, exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _kernels as K
from .machine import Machine

#: unknowns per pair kind (as the force analysis lays them out)
N_UNKNOWN = {"revolute": 2, "prismatic": 2, "cam": 1, "slot": 1, "driver": 1}
KIND_CODE = {"revolute": K.PAIR_REVOLUTE, "prismatic": K.PAIR_PRISMATIC, "cam": K.PAIR_CAM,
             "slot": K.PAIR_SLOT}
#: the fixed-point iteration stops when no unknown changes by more than this, relative to
#: its design's largest force, or fails after MAX_STEPS
TOLERANCE = 1e-10
MAX_STEPS = 60
#: the steps Anderson's acceleration combines (:func:`sewmech.engine._kernels._anderson`;
#: at most 3: the kernel's sums are written out for 3)
ANDERSON_DEPTH = 3


@dataclass(frozen=True)
class FrictionTables:
    """The frictional pairs of a machine for the friction kernel
    (:func:`sewmech.engine._kernels.force_solve`): their indices among the machine's pairs, the
    integer rows (kind, first link, second link, first unknown's column) and the values (mu,
    pin radius mm, viscous part, smoothing speed mm/s)."""

    pair_index: tuple[int, ...]
    names: tuple[str, ...]
    ints: np.ndarray
    values: np.ndarray

    @classmethod
    def build(cls, machine: Machine) -> FrictionTables | None:
        f = machine.spec.friction
        if f is None:
            return None
        idx, names, ints, vals = [], [], [], []
        col = 0
        for i, p in enumerate(machine.pairs):
            n_unknown = N_UNKNOWN[p.kind]
            if p.kind != "driver":
                own = f.pairs.get(p.name)
                mu = own.coefficient if own is not None and own.coefficient is not None \
                    else f.coefficient
                r = own.pin_radius_mm if own is not None and own.pin_radius_mm is not None \
                    else f.pin_radius_mm
                visc = own.viscous_N_mm_s if own is not None and \
                    own.viscous_N_mm_s is not None else f.viscous_N_mm_s
                if p.kind != "revolute":
                    r = 0.0
                if (mu > 0.0 and (p.kind != "revolute" or r > 0.0)) or visc > 0.0:
                    idx.append(i)
                    names.append(p.name)
                    ints.append((KIND_CODE[p.kind], machine.link_index(p.links[0]),
                                 machine.link_index(p.links[1]), col))
                    vals.append((mu, r, visc, f.smooth_mm_s))
            col += n_unknown
        if not idx:
            return None
        return cls(tuple(idx), tuple(names), np.asarray(ints, dtype=np.int64).reshape(-1, 4),
                   np.asarray(vals, dtype=float).reshape(-1, 4))

    def __len__(self) -> int:
        return len(self.names)
