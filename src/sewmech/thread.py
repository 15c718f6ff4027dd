"""The needle thread: its path through the guides, the take-up's supply.

A thread path is an ordered list of guides from the tension discs to the needle eye. Each guide
is a point (a hole or an eye: the thread passes through it) or a pin of radius r (the thread
wraps it, counter-clockwise or clockwise as seen from the hand-wheel end). Between guides the
thread runs straight, along the common tangent of the two guides' circles; on a pin it follows
the arc between its incoming and outgoing tangent points. Guides may move (the take-up eye, the
needle-bar thread guide, the needle eye): the path is evaluated from the kinematics at every
shaft angle, for one design or a batch.

Geometry. Give every guide a signed radius rho (+r: the thread turns left, counter-clockwise,
round it; -r: right; 0: a point). The thread leaves guide 1 towards guide 2 along the unit
vector u with tangent points t_k = c_k + rho_k R(u), R(u) the right normal of u. Requiring
t2 - t1 parallel to u gives, with d = c2 - c1, b = rho1 - rho2 and a = sqrt(|d|^2 - b^2):
u = (a d + b J d) / |d|^2 (J: rotation by +90 deg) and a straight length a. On a pin the thread
turns from u_in to u_out through the angle measured in its wrap direction, in [0, 2 pi).
A pin holds the thread on its given side at every angle (as a hook or an eye would); place the
guides so that the thread bends round each pin the same way all through the cycle (a wrap that
jumps towards 360 deg means it does not).

The take-up's supply is S(phi) = max L_tu - L_tu(phi), L_tu the length of the take-up section
of the path (from ``take_up[0]`` to ``take_up[1]``): the thread the take-up has released
towards the needle (DOMAIN.md 2.3). Lengths in mm, angles rad inside, degrees at the edges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from .kinematics import kinematics
from .machine import Machine


def path_length(centres: ArrayLike, rho: ArrayLike) -> np.ndarray:
    """Length (mm) of a thread through guides with centres (..., n, 2) and signed radii (n,).

    The first and last guides must be points (rho = 0). Raises ValueError where two guides'
    circles overlap so that no common tangent exists (reported with the guide pair).
    """
    c = np.asarray(centres, dtype=float)
    rho = np.asarray(rho, dtype=float)
    n = c.shape[-2]
    if rho.shape != (n,):
        raise ValueError(f"rho must have shape ({n},), got {rho.shape}")
    if rho[0] != 0.0 or rho[-1] != 0.0:
        raise ValueError("the thread path must start and end at a point guide (radius 0)")
    d = c[..., 1:, :] - c[..., :-1, :]
    dd = np.einsum("...i,...i->...", d, d)
    b = rho[:-1] - rho[1:]
    a2 = dd - b * b
    if np.any(a2 < 0.0):
        k = int(np.nonzero(np.any(a2.reshape(-1, n - 1) < 0.0, axis=0))[0][0])
        raise ValueError(f"thread guides {k} and {k + 1} overlap: no common tangent (their"
                         " distance is less than the difference of their signed radii)")
    a = np.sqrt(a2)
    jd = np.stack([-d[..., 1], d[..., 0]], axis=-1)
    u = (a[..., None] * d + b[..., None] * jd) / dd[..., None]
    total = a.sum(axis=-1)
    pins = np.nonzero(rho[1:-1] != 0.0)[0] + 1
    if pins.size:
        u_in = u[..., pins - 1, :]
        u_out = u[..., pins, :]
        cross = u_in[..., 0] * u_out[..., 1] - u_in[..., 1] * u_out[..., 0]
        dot = np.einsum("...i,...i->...", u_in, u_out)
        turn = np.arctan2(cross, dot)  # left turn positive
        wrap = np.mod(np.sign(rho[pins]) * turn, 2.0 * math.pi)
        total = total + (np.abs(rho[pins]) * wrap).sum(axis=-1)
    return total


@dataclass(frozen=True)
class ThreadPath:
    """Thread lengths over the shaft cycle (batch + (n_phi,) arrays, mm).

    total: the whole path; take_up: its take-up section; supply: max(take_up) - take_up, the
    thread released towards the needle; below: the part after the take-up section (to the
    needle eye).
    """

    phi_deg: np.ndarray
    total: np.ndarray = field(repr=False)
    take_up: np.ndarray = field(repr=False)
    supply: np.ndarray = field(repr=False)
    below: np.ndarray = field(repr=False)

    @property
    def stroke(self) -> np.ndarray:
        """The take-up's thread stroke: peak-to-peak of its section, mm."""
        return np.ptp(self.take_up, axis=-1)


def _thread_spec(machine: Machine):
    t = machine.spec.thread
    if t is None:
        raise ValueError(f"machine '{machine.name}' ({machine.file}) has no [thread] table: list"
                         " the thread guides (docs/machine-files.md)")
    return t


def guide_radii(machine: Machine) -> np.ndarray:
    """Signed radii of the file's thread guides (mm; + counter-clockwise wrap)."""
    t = _thread_spec(machine)
    return np.array([g.radius * (1.0 if g.wrap == "ccw" else -1.0) for g in t.guides])


def thread_path(machine: Machine, phi: ArrayLike, *, params=None, inputs=None,
                on_failure: str = "raise") -> ThreadPath:
    """Lengths of the machine's thread path at shaft angles ``phi`` (rad) for one design or a
    batch (``params``). The supply is taken over the given angles: pass a full cycle."""
    t = _thread_spec(machine)
    names = [g.point for g in t.guides]
    unique = list(dict.fromkeys(names))
    r = kinematics(machine, phi, params=params, inputs=inputs, points=unique, links=[],
                   variables=[], on_failure=on_failure)
    pos = np.stack([r.point(nm).p for nm in names], axis=-2)  # batch + (n_phi, n_guides, 2)
    rho = guide_radii(machine)
    i0, i1 = t.take_up
    total = path_length(pos, rho)
    tu = path_length(pos[..., i0:i1 + 1, :], rho[i0:i1 + 1])
    below = path_length(pos[..., i1:, :], rho[i1:])
    return ThreadPath(np.degrees(np.asarray(phi, dtype=float)), total, tu,
                      tu.max(axis=-1, keepdims=True) - tu, below)
