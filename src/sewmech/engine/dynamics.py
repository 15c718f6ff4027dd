"""Inverse dynamics of a whole machine: forces in every pair, driving torque, frame reactions.

The method is the JB dynamics report's matrix-vector force analysis: for every moving link the
Newton-Euler equations (two force equations and the moment equation about its centre of mass)
are written with the unknown pair forces, stacked into one square linear system per position,
and solved. Here every position of every design is one such system, assembled and solved in
one compiled call; the system is first put in block upper-triangular form from its sparsity
(:func:`force_structure`), so that a position costs a few small eliminations (the Assur groups,
in effect) instead of one of the whole system. :class:`DynamicsPlan` prepares all of this once
for loops over designs; :func:`inverse_dynamics` is a one-off plan.

Pairs (:class:`sewmech.machine.Pair`) come from the machine file: every pin shared by two links
is a revolute pair, every slider unit a prismatic pair, every crank a driver; the cam contacts
and pins-in-slots of loop units are declared in their ``contacts``. A pair's unknowns are the
action of its first link on its second.

Units: inputs and internal arrays in mm, kg, s, rad; forces N, moments and torques N mm,
energies N mm (= mJ), powers N mm/s (= mW), inertias kg mm^2. The ``*_Nm``, ``*_J`` and ``*_W``
names of the JSON output are SI.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from functools import cached_property, lru_cache

import numpy as np
from numpy.typing import ArrayLike

from . import _kernels as K
from ._blocks import MAX_BLOCK
from ._threads import run_chunks
from .counterweights import CounterweightMotion, counterweight_values
from .errors import AnalysisError, OptionError, SewmechError
from .friction import ANDERSON_DEPTH, MAX_STEPS, TOLERANCE, FrictionTables
from .kinematics import KinematicsPlan, check_speed, kernel_input, kernel_params
from .loads import LoadTables, in_windows  # noqa: F401  (in_windows: sewmech.dynamics.in_windows)
from .machine import Machine, Pair
from .mass import MassProperties
from .results import KinematicsResult
from .spec import FRAME, SHAFT, LoadSpec
from .springs import SpringTables

#: standard gravity, m/s^2 (acts along -y of the machine frame)
GRAVITY = 9.80665

#: unknowns per pair kind
_N_UNKNOWN = {"revolute": 2, "prismatic": 2, "cam": 1, "slot": 1, "driver": 1}


def _machine_where(machine) -> str:
    """The machine and its file, for an error's *where*: ``machine 'x' (path/x.toml)``."""
    file = getattr(machine, "file", "")
    return f"machine '{machine.name}' ({file})" if file else f"machine '{machine.name}'"


class SingularForceSystem(SewmechError):
    """The equilibrium equations have no unique solution at some position."""


@dataclass(frozen=True)
class LinkMasses:
    """Mass properties of the moving links in their own frames (planar part).

    Arrays have shape ``(..., n_links)`` over the machine's links (index 0, the frame, is
    unused); leading axes broadcast against the design batch.

    Attributes
    ----------
    mass : kg
    com_u, com_v : mm, centre of mass in the link frame (origin ``origins[i]``, u along the
        link angle, v to its left)
    inertia : kg mm^2, I_zz about the centre of mass
    origins : point index of each link's frame origin (-1: none, the link is massless)
    """

    mass: np.ndarray
    com_u: np.ndarray
    com_v: np.ndarray
    inertia: np.ndarray
    origins: np.ndarray


def link_masses(machine: Machine,
                overrides: Mapping[str, MassProperties] | None = None) -> LinkMasses:
    """Planar mass properties of every link from the machine file's ``[masses]`` (links without
    one are massless), with ``overrides`` (link -> :class:`MassProperties` in the link frame)."""
    if not overrides:
        return _file_masses(machine)
    return _link_masses(machine, overrides)


@lru_cache(maxsize=64)
def _file_masses(machine: Machine) -> LinkMasses:
    out = _link_masses(machine, None)
    for a in (out.mass, out.com_u, out.com_v, out.inertia, out.origins):
        a.setflags(write=False)
    return out


def _link_masses(machine: Machine, overrides) -> LinkMasses:
    n = len(machine.link_names)
    m, cu, cv, inertia = (np.zeros(n) for _ in range(4))
    origins = np.full(n, -1, dtype=np.int64)
    table = dict(machine.masses)
    for name, mp in (overrides or {}).items():
        machine.link_index(name)
        table[name] = mp
    for name, mp in table.items():
        i = machine.link_index(name)
        origin = machine.mass_origins.get(name) or _first_point(machine, name)
        if origin is None:
            raise ValueError(f"link '{name}' has no points: its mass needs a frame origin")
        mass, com, izz = mp.planar
        m[i], cu[i], cv[i], inertia[i] = mass, com[0], com[1], izz
        origins[i] = machine.point_index(origin)
    for i, name in enumerate(machine.link_names):
        if origins[i] < 0 and i > 0:  # massless: take moments about one of its points anyway
            p = _first_point(machine, name)
            origins[i] = machine.point_index(p) if p is not None else -1
    return LinkMasses(m, cu, cv, inertia, origins)


def _first_point(machine: Machine, link: str) -> str | None:
    for p in machine.point_names:
        if link in machine.point_links[p]:
            return p
    return None


# ---- loads -------------------------------------------------------------------------------------


# ---- the force analysis --------------------------------------------------------------------------


@dataclass(frozen=True)
class SpringForces:
    """The springs' forces over the turn (``[[springs]]`` then ``[[torsion_springs]]``).

    ``force``: batch + (n_phi, n_springs), a translational spring's tension (N, positive when
    it pulls its ends together) or a torsion spring's moment on its pair's second link
    (N mm); ``length``: its length (mm) or the pair's relative angle (rad); ``energy``: their
    potential energy, N mm, batch + (n_phi,); ``energy_rate``: its rate and ``damping_power``
    the dampers' loss (>= 0), N mm/s. The first ``n_translational`` are translational."""

    names: tuple[str, ...]
    n_translational: int
    force: np.ndarray = field(repr=False)
    length: np.ndarray = field(repr=False)
    energy: np.ndarray = field(repr=False)
    energy_rate: np.ndarray = field(repr=False)
    damping_power: np.ndarray = field(repr=False)

    def of(self, name: str) -> np.ndarray:
        """One spring's force (N) or moment (N mm), batch + (n_phi,)."""
        return self.force[..., self.names.index(name)]


@dataclass(frozen=True)
class FrictionForces:
    """Friction in the pairs over the turn (``[friction]``): ``force`` batch + (n_phi, n_fr),
    each frictional pair's friction moment (N mm, revolute) or force (N, along the contact's
    tangent) on its second link; ``power`` the power it takes out of the machine (N mm/s,
    >= 0)."""

    pairs: tuple[str, ...]
    force: np.ndarray = field(repr=False)
    power: np.ndarray = field(repr=False)

    @property
    def total_power(self) -> np.ndarray:
        """The friction loss of all pairs, N mm/s, batch + (n_phi,)."""
        return self.power.sum(axis=-1)


@dataclass(frozen=True, eq=False)
class DynamicsResult:
    """Forces and energies of a machine over crank angles (see the module doc for units).

    Array convention: batch axes, then the crank-angle axis, then components.

    Attributes
    ----------
    kin : KinematicsResult
        The motion the forces were solved for.
    pairs : tuple[Pair, ...]
        The pairs in unknown order.
    unknowns : ndarray, batch + (n_phi, n_unknowns)
        Every pair's unknowns (N, or N mm for couples and torques), pair after pair.
    gravity : bool
    load_names : tuple[str, ...]
    load_force : ndarray, batch + (n_phi, n_loads, 2)
        Each load's force, N (zero outside its windows).
    load_power : ndarray, batch + (n_phi,)
        Power of the loads on the machine, N mm/s.
    mass : LinkMasses
    params : ndarray, batch + (n_parameters,)
        The designs' parameter vectors.
    com_p, com_v, com_a : ndarray, batch + (n_phi, n_links, 2)
        Centre of mass of each link (its ``[masses]`` without counterweights): mm, mm/s,
        mm/s^2.
    counterweights : CounterweightMotion or None
        The machine's ``[counterweights]`` (point masses on links, per design): their masses
        and motion; the forces, the shaking, the energies and the bearing reactions include
        them.
    load_on : ndarray, batch + (n_phi, n_loads)
        1 where each load acts (its windows and conditions hold), else 0.
    load_dissipative : tuple[bool, ...]
        Which loads are resistive (take energy out wherever they act).
    springs : SpringForces
        The springs' forces, energy and damping loss (empty without springs).
    friction : FrictionForces or None
        Friction in the pairs (None without ``[friction]``).
    """

    machine: Machine = field(repr=False)
    kin: KinematicsResult = field(repr=False)
    pairs: tuple[Pair, ...]
    unknowns: np.ndarray = field(repr=False)
    gravity: bool
    load_names: tuple[str, ...]
    load_force: np.ndarray = field(repr=False)
    load_power: np.ndarray = field(repr=False)
    mass: LinkMasses = field(repr=False)
    com_p: np.ndarray = field(repr=False)
    com_v: np.ndarray = field(repr=False)
    com_a: np.ndarray = field(repr=False)
    params: np.ndarray = field(repr=False)
    mass_props: dict = field(default_factory=dict, repr=False)
    load_links: tuple[int, ...] = ()
    counterweights: CounterweightMotion | None = field(default=None, repr=False)
    load_on: np.ndarray | None = field(default=None, repr=False)
    load_dissipative: tuple[bool, ...] = ()
    springs: SpringForces | None = field(default=None, repr=False)
    friction: FrictionForces | None = field(default=None, repr=False)

    # ---- pairs
    @cached_property
    def _columns(self) -> dict[str, tuple[int, Pair]]:
        out, c = {}, 0
        for pair in self.pairs:
            out[pair.name] = (c, pair)
            c += _N_UNKNOWN[pair.kind]
        return out

    @property
    def phi(self) -> np.ndarray:
        return self.kin.phi

    @property
    def phi_deg(self) -> np.ndarray:
        return self.kin.phi_deg

    @property
    def pair_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.pairs)

    def pair(self, name: str) -> np.ndarray:
        """The unknowns of one pair, batch + (n_phi, k): revolute (Fx, Fy) N; prismatic (N in N,
        M in N mm); cam and slot (N,) N; driver (torque N mm,). Action of ``links[0]`` on
        ``links[1]``."""
        try:
            c, pair = self._columns[name]
        except KeyError:
            import difflib

            close = difflib.get_close_matches(name, list(self._columns), n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            raise KeyError(f"no pair '{name}'{hint}") from None
        return self.unknowns[..., c:c + _N_UNKNOWN[pair.kind]]

    def force(self, name: str) -> np.ndarray:
        """The force vector (N) of a pair on its second link, batch + (n_phi, 2)."""
        c, pair = self._columns[name]
        x = self.unknowns[..., c:c + _N_UNKNOWN[pair.kind]]
        if pair.kind == "revolute":
            return x
        if pair.kind == "driver":
            raise ValueError(f"pair '{name}' is a driver: it transmits a torque, not a force")
        return x[..., :1] * self._geometry[1][..., self.pairs.index(pair), :]

    def total_force(self, name: str) -> np.ndarray:
        """The force (N) of a pair on its second link, the friction along a sliding pair's
        tangent included (:meth:`force` is its normal force alone), batch + (n_phi, 2)."""
        F = self.force(name)
        fr = self._friction_at_pairs
        c, pair = self._columns[name]
        if name in fr and pair.kind != "revolute":
            n = self._geometry[1][..., self.pairs.index(pair), :]
            t = np.stack([n[..., 1], -n[..., 0]], axis=-1)  # the friction kernel's tangent
            F = F + fr[name][..., None] * t
        return F

    def magnitude(self, name: str) -> np.ndarray:
        """|force| (N) of a pair, or |torque| (N mm) of a driver, batch + (n_phi,)."""
        c, pair = self._columns[name]
        if pair.kind == "driver":
            return np.abs(self.unknowns[..., c])
        return np.linalg.norm(self.force(name), axis=-1)

    @cached_property
    def _geometry(self) -> tuple[np.ndarray, np.ndarray]:
        return pair_geometry(self.machine, self.kin, self.params)

    # ---- driving
    @cached_property
    def input_torque(self) -> np.ndarray:
        """Torque on the upper shaft from the motor, N mm, batch + (n_phi,): the sum of the
        shaft-driven cranks' torques, each times its speed ratio (equal power)."""
        P = self.kin.p.shape[:-2]
        tau = np.zeros(P)
        params = self.params
        for c, pair in self._columns.values():
            if pair.kind == "driver" and pair.input == SHAFT:
                tau = tau + self.unknowns[..., c] * params[..., None, pair.ratio_param]
        return tau

    @cached_property
    def setting_torques(self) -> dict[str, np.ndarray]:
        """Torque (N mm) that holds each setting input (e.g. the stitch regulator)."""
        return {pair.input: self.unknowns[..., c] for c, pair in self._columns.values()
                if pair.kind == "driver" and pair.input != SHAFT}

    @property
    def input_power(self) -> np.ndarray:
        """Power the motor puts into the shaft, N mm/s."""
        return self.input_torque * self.kin.omega_shaft

    # ---- the frame
    @cached_property
    def frame_reactions(self) -> dict[str, np.ndarray]:
        """Force (N) on the frame at each of its pairs (revolute, prismatic, cam, slot), the
        friction along a sliding pair's tangent included, and of each spring anchored to it
        (by the spring's name); where each acts: :attr:`frame_reaction_points`."""
        out = {}
        for name, (c, pair) in self._columns.items():
            if pair.kind == "driver":
                continue
            if FRAME not in pair.links:
                continue
            F = self.total_force(name)
            out[name] = -F if pair.links[0] == FRAME else F
        for spring, (end, F) in self._frame_springs.items():
            out[spring] = F
        return out

    @cached_property
    def frame_reaction_points(self) -> dict[str, np.ndarray]:
        """Where each force of :attr:`frame_reactions` acts on the frame, mm, batch + (n_phi,
        2): a pair's point (a cam's contact), a spring's anchor."""
        points, _ = self._geometry
        out = {}
        for name in self.frame_reactions:
            if name in self._frame_springs:
                out[name] = self.kin.point(self._frame_springs[name][0]).p
            else:
                out[name] = points[..., self.pair_names.index(name), :]
        return out

    @cached_property
    def _frame_springs(self) -> dict[str, tuple[str, np.ndarray]]:
        """The translational springs anchored to the frame: name -> (anchor point, force on
        the frame N)."""
        out = {}
        sp = self.springs
        if sp is None:
            return out
        for j, spec in enumerate(self.machine.spec.springs):
            if FRAME not in spec.links:
                continue
            e = spec.links.index(FRAME)
            pa = self.kin.point(spec.points[0]).p
            pb = self.kin.point(spec.points[1]).p
            d = pb - pa
            u = d / np.linalg.norm(d, axis=-1, keepdims=True)
            T = sp.force[..., j][..., None]
            out[spec.name] = (spec.points[e], T * u if e == 0 else -T * u)
        return out

    @cached_property
    def _friction_at_pairs(self) -> dict[str, np.ndarray]:
        if self.friction is None:
            return {}
        return {name: self.friction.force[..., j] for j, name in enumerate(self.friction.pairs)}

    @cached_property
    def frame_couples(self) -> dict[str, np.ndarray]:
        """Couples (N mm) on the frame at its pairs: a guide's couple, the friction moment at
        a pin with the frame, a torsion spring's at such a pin (by the spring's name)."""
        out = {}
        fr = self._friction_at_pairs
        for name, (c, pair) in self._columns.items():
            if pair.kind == "driver" or FRAME not in pair.links:
                continue
            sign = -1.0 if pair.links[0] == FRAME else 1.0  # on the frame: minus its action
            M = np.zeros(self.kin.phi.shape if not self.kin.batch_shape else
                         self.kin.batch_shape + self.kin.phi.shape)
            if pair.kind == "prismatic":
                M = M + sign * self.unknowns[..., c + 1]
            if pair.kind == "revolute" and name in fr:
                M = M + sign * fr[name]
            if pair.kind == "prismatic" or name in fr:
                out[name] = M
        sp = self.springs
        if sp is not None:
            n = sp.n_translational
            for j, spec in enumerate(self.machine.spec.torsion_springs):
                pair = self.pairs[self.pair_names.index(spec.pair)]
                if FRAME in pair.links:  # its moment on the pair's second link; the first's
                    M = sp.force[..., n + j]
                    out[spec.name] = -M if pair.links[0] == FRAME else M
        return out

    @cached_property
    def shaking_force(self) -> np.ndarray:
        """Shaking force, N, batch + (n_phi, 2): the resultant of the links' inertia forces,
        -sum m a_G (counterweights included), which the frame (and through it the table)
        feels."""
        out = -np.einsum("...l,...lc->...c", self._m, self.com_a) * 1e-3
        if self.counterweights is not None:
            out += self.counterweights.inertia_force()
        return out

    @cached_property
    def shaking_moment(self) -> np.ndarray:
        """Shaking moment about the frame origin, N mm, batch + (n_phi,): -sum (I alpha +
        r_G x m a_G), the motor's reaction on its mount included."""
        g, a = self.com_p, self.com_a
        cross = g[..., 0] * a[..., 1] - g[..., 1] * a[..., 0]
        out = -(np.einsum("...l,...l->...", self._m, cross)
                + np.einsum("...l,...l->...", self._I, self.kin.epsilon)) * 1e-3
        if self.counterweights is not None:
            out += self.counterweights.moment_of_inertia_forces()
        return out

    # ---- energy
    @cached_property
    def _m(self) -> np.ndarray:
        return np.broadcast_to(self.mass.mass, self.kin.theta.shape)

    @cached_property
    def _I(self) -> np.ndarray:
        return np.broadcast_to(self.mass.inertia, self.kin.theta.shape)

    @cached_property
    def kinetic_energy(self) -> np.ndarray:
        """Kinetic energy of the machine, N mm (= mJ), batch + (n_phi,)."""
        v2 = np.sum(self.com_v ** 2, axis=-1)
        out = 0.5e-3 * (np.sum(self._m * v2, axis=-1)
                        + np.sum(self._I * self.kin.omega ** 2, axis=-1))
        if self.counterweights is not None:
            out += self.counterweights.kinetic_energy()
        return out

    @cached_property
    def kinetic_energy_rate(self) -> np.ndarray:
        """dT/dt from the motion alone (sum m v.a + I omega alpha), N mm/s."""
        va = np.sum(self.com_v * self.com_a, axis=-1)
        out = 1e-3 * (np.sum(self._m * va, axis=-1)
                      + np.sum(self._I * self.kin.omega * self.kin.epsilon, axis=-1))
        if self.counterweights is not None:
            out += self.counterweights.kinetic_energy_rate()
        return out

    @cached_property
    def potential_energy(self) -> np.ndarray:
        """Potential energy of gravity (above y = 0 of the frame) and of the springs, N mm."""
        out = np.zeros_like(self.kinetic_energy)
        if self.gravity:
            out += GRAVITY * np.sum(self._m * self.com_p[..., 1], axis=-1)
            if self.counterweights is not None:
                out += GRAVITY * self.counterweights.weight_height()
        if self.springs is not None and self.springs.names:
            out += self.springs.energy
        return out

    @cached_property
    def potential_energy_rate(self) -> np.ndarray:
        """dV/dt (gravity and springs), N mm/s."""
        out = np.zeros_like(self.kinetic_energy)
        if self.gravity:
            out += GRAVITY * np.sum(self._m * self.com_v[..., 1], axis=-1)
            if self.counterweights is not None:
                out += GRAVITY * self.counterweights.weight_rate()
        if self.springs is not None and self.springs.names:
            out += self.springs.energy_rate
        return out

    @property
    def external_power(self) -> np.ndarray:
        """Power of the applied loads on the machine, N mm/s (gravity not included: it is in
        the potential energy)."""
        return self.load_power

    @cached_property
    def friction_power(self) -> np.ndarray:
        """Power friction takes out of the machine (all pairs), N mm/s, >= 0."""
        if self.friction is None:
            return np.zeros_like(self.kinetic_energy)
        return self.friction.total_power

    @cached_property
    def damping_power(self) -> np.ndarray:
        """Power the springs' dampers take out of the machine, N mm/s, >= 0."""
        if self.springs is None or not self.springs.names:
            return np.zeros_like(self.kinetic_energy)
        return self.springs.damping_power

    @cached_property
    def power_balance(self) -> np.ndarray:
        """P_in - dT/dt - dV/dt + P_loads - P_friction - P_damping, N mm/s: zero to round-off
        (every term computed on its own: the motor's torque from the force solve, the rest from
        the motion and the applied forces)."""
        return (self.input_power - self.kinetic_energy_rate - self.potential_energy_rate
                + self.external_power - self.friction_power - self.damping_power)

    @cached_property
    def bearings(self) -> BearingReactions:
        """The upper shaft's front and rear bearing reactions (:func:`bearing_reactions`)."""
        return bearing_reactions(self)

    @cached_property
    def reduced_inertia(self) -> np.ndarray:
        """Equivalent moment of inertia at the upper shaft, J(phi) = 2 T / omega^2, kg mm^2:
        from the velocities divided by the shaft speed first (the motion's ratios, which do
        not depend on it), so that a slow shaft's squares never leave the floating-point
        range. NaN where the shaft is at rest (omega = 0, or below 1e-290 rad/s, where the
        velocities themselves underflow: a motion at rest has no ratios)."""
        w = np.asarray(self.kin.omega_shaft, dtype=float)
        moving = np.abs(w) >= 1e-290
        inv = np.divide(1.0, w, out=np.zeros_like(w), where=moving)
        v2 = np.sum((self.com_v * inv[:, None, None]) ** 2, axis=-1)
        two_t = 1e-3 * (np.sum(self._m * v2, axis=-1)
                        + np.sum(self._I * (self.kin.omega * inv[:, None]) ** 2, axis=-1))
        if self.counterweights is not None:  # (N mm per (rad/s)^2, as 2 T / omega^2)
            cw = self.counterweights
            two_t = two_t + 1e-3 * np.einsum(
                "...c,...kc->...k", cw.mass, np.sum((cw.v * inv[:, None, None]) ** 2,
                                                    axis=-1))
        return np.where(moving, 1e3 * two_t, np.nan)



@dataclass(frozen=True)
class BearingReactions:
    """Reactions of the upper shaft's bearings (the force each bearing puts on the shaft), N,
    batch + (n_phi, 2); ``inertia_couple`` is dH/dt of the shaft about its axis point (x, y
    components, N mm), the part that products of inertia add."""

    front: np.ndarray
    rear: np.ndarray
    z_front: float
    z_rear: float
    inertia_couple: np.ndarray


def bearing_reactions(res: DynamicsResult) -> BearingReactions:
    """The upper shaft in 3-D: its parts turn about z; the pairs of each crank act in that
    crank's plane (``[shaft] links``), gravity at each part's centre of mass; the two bearings
    (``[shaft] bearings``) carry what is left. Moments about the axis point: the x and y
    components of dH/dt = (J_xz alpha - J_yz omega^2, J_yz alpha + J_xz omega^2) with the
    products of inertia J_xz, J_yz of the turning parts about that point.
    """
    kin = res.kin
    cw = res.counterweights
    return shaft_bearings(
        res.machine, res.pairs, res.gravity, res.mass_props, res.load_links,
        res.total_force, lambda k: res.load_force[..., k, :],
        lambda li: (kin.theta[..., li], kin.omega[..., li], kin.epsilon[..., li],
                    res.com_a[..., li, :]),
        None if cw is None else (cw.names, cw.links, cw.z,
                                 lambda k: (cw.mass[..., k, None], cw.a[..., k, :])),
        kin.theta.shape[:-1], np.result_type(kin.theta, res.com_a))


def shaft_pairs(shaft, pairs, lname: str):
    """The pairs a crank of the upper shaft (link ``lname``) sums for its bearings, with the
    sign of their force on it: those with a link that is neither the frame (the frame's share
    is the bearings' job) nor the shaft itself."""
    for pair in pairs:
        if pair.kind == "driver" or lname not in pair.links or FRAME in pair.links:
            continue
        if pair.links[0] in shaft.links and pair.links[1] in shaft.links:
            continue
        yield pair, (1.0 if pair.links[1] == lname else -1.0)


def shaft_mass(mass_props: dict, lname: str):
    """The mass properties of a part of the upper shaft (None: massless); the bearings need
    its products of inertia."""
    mp = mass_props.get(lname)
    if mp is not None and not np.isfinite(mp.inertia).all():
        raise ValueError(f"link '{lname}' turns with the upper shaft but its [masses] table"
                         " gives only inertia_zz: the bearing reactions need its products"
                         " of inertia (give the full inertia tensor or solids)")
    return mp


def shaft_bearings(machine: Machine, pairs, gravity: bool, mass_props: dict, load_links,
                   total_force, load_force, link_motion, counterweights, bshape: tuple,
                   dtype) -> BearingReactions:
    """:func:`bearing_reactions` from what it reads, each asked for when needed:
    ``total_force(pair name)`` (.., 2) N, ``load_force(k)`` (.., 2) N, ``link_motion(link
    index)`` (theta, omega, epsilon, centre-of-mass acceleration) of a shaft link, and
    ``counterweights`` (names, links, z, ``k -> (mass (.., 1), acceleration (.., 2))``) or
    None; arrays of shape ``bshape`` (+ components) and type ``dtype`` (complex for the
    complex step of :mod:`sewmech.engine.dynamic_sensitivity`)."""
    shaft = machine.spec.shaft
    if shaft is None:
        raise ValueError(f"machine '{machine.name}' has no [shaft] table: give the z of its"
                         " cranks' planes and of its two bearings")
    names = machine.link_names
    dt = dtype
    S = np.zeros(bshape + (2,), dtype=dt)  # sum of forces from outside the shaft (not the
    Mx = np.zeros(bshape, dtype=dt)  # bearings), their moments about the axis point, N mm
    My = np.zeros(bshape, dtype=dt)
    dHx = np.zeros(bshape, dtype=dt)
    dHy = np.zeros(bshape, dtype=dt)
    mass_S = np.zeros(bshape + (2,), dtype=dt)
    for lname, z in shaft.links.items():
        li = names.index(lname)
        # pairs of this crank with links that are not the frame (the frame's share is the
        # bearings' job) and not the shaft itself
        for pair, sign in shaft_pairs(shaft, pairs, lname):
            F = total_force(pair.name) * sign
            S += F
            Mx += -z * F[..., 1]
            My += z * F[..., 0]
        for k, li_load in enumerate(load_links):
            if li_load == li:
                F = load_force(k)
                S += F
                Mx += -z * F[..., 1]
                My += z * F[..., 0]
        mp = shaft_mass(mass_props, lname)
        if mp is None:
            continue
        th, w, e, a = link_motion(li)
        c, s = np.cos(th), np.sin(th)
        J = mp.about(np.zeros(3))  # about the axis point at z = 0
        zc = mp.com[2]
        jxz = c * J[0, 2] - s * J[1, 2]
        jyz = s * J[0, 2] + c * J[1, 2]
        dHx += 1e-3 * (jxz * e - jyz * w * w)
        dHy += 1e-3 * (jyz * e + jxz * w * w)
        m = mp.mass
        mass_S += 1e-3 * m * a
        if gravity:
            S[..., 1] -= m * GRAVITY
            Mx += zc * m * GRAVITY
    if counterweights is not None:
        cw_names, cw_links, cw_z, cw_of = counterweights
        for k in range(len(cw_names)):
            if names[cw_links[k]] not in shaft.links:
                continue
            m, a = cw_of(k)  # a point mass at plane z
            z = cw_z[k]
            mass_S += 1e-3 * m[..., None] * a
            dHx += -1e-3 * z * m * a[..., 1]  # dH/dt = r x m a, about the axis point
            dHy += 1e-3 * z * m * a[..., 0]
            if gravity:
                S[..., 1] -= m * GRAVITY
                Mx += z * m * GRAVITY
    # bearings: B_f + B_r + S = sum m a ; z x B terms + M = dH/dt
    need = mass_S - S
    zf, zr = shaft.bearings["front"], shaft.bearings["rear"]
    Mx_need = dHx - Mx
    My_need = dHy - My
    bfy = (Mx_need + zr * need[..., 1]) / (zr - zf)
    bfx = (My_need - zr * need[..., 0]) / (zf - zr)
    front = np.stack([bfx, bfy], axis=-1)
    rear = need - front
    return BearingReactions(front, rear, zf, zr, np.stack([dHx, dHy], axis=-1))


def _flat(kin: KinematicsResult, a: np.ndarray) -> np.ndarray:
    """batch + (n_phi, ...) -> (n_designs, n_phi, ...), contiguous and read-only, for the
    kernels."""
    n_d = int(np.prod(kin.batch_shape, dtype=np.int64))
    return kernel_input(a.reshape((n_d, kin.phi.shape[0]) + a.shape[len(kin.batch_shape) + 1:]))


def pair_geometry(machine: Machine, kin: KinematicsResult,
                  params: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Where each pair's force acts (mm) and the direction of its single force (unit vector;
    revolute: (1, 0); drivers: zeros), batch + (n_phi, n_pairs, 2) each; the geometry the
    force solve itself uses."""
    table, angles, cam_rows = _pair_table(machine)
    batch, n_phi = kin.batch_shape, kin.phi.shape[0]
    P = np.broadcast_to(machine.defaults if params is None else params,
                        batch + machine.defaults.shape)
    n_d = int(np.prod(batch, dtype=np.int64))
    X = np.zeros((n_d, n_phi, len(machine.pairs), 2))
    N = np.zeros_like(X)
    K.pair_geometry(*(kernel_input(x) for x in (table, angles, cam_rows, machine.terms)),
                    kernel_params(P), _flat(kin, kin.p),
                    _flat(kin, kin.theta), _flat(kin, kin.q), X, N)
    shape = batch + (n_phi, len(machine.pairs), 2)
    return X.reshape(shape), N.reshape(shape)


def force_system(machine: Machine) -> str:
    """One line on the machine's force analysis: pairs, unknowns against equations, masses,
    loads and whether the upper shaft's bearings can be computed."""
    n_eq = 3 * (len(machine.link_names) - 1)
    n_unk = sum(_N_UNKNOWN[p.kind] for p in machine.pairs)
    kinds = ", ".join(f"{sum(1 for p in machine.pairs if p.kind == k)} {k}"
                      for k in _N_UNKNOWN if any(p.kind == k for p in machine.pairs))
    state = ("ready" if n_unk == n_eq else
             "NOT READY: declare the missing cam/slot contacts or pins")
    return (f"{len(machine.pairs)} pairs ({kinds}): {n_unk} unknowns for {n_eq} equations,"
            f" {state}; masses for {len(machine.masses)} of {len(machine.link_names) - 1} links;"
            f" {len(machine.spec.loads)} loads; bearings"
            f" {'from [shaft]' if machine.spec.shaft is not None else 'not computed (no [shaft])'}")


@dataclass(frozen=True)
class ForceStructure:
    """The sparsity of a machine's force equations, put in block upper-triangular form once.

    Rows are the equations (3 per moving link: x, y, moment), columns the pairs' unknowns. A
    perfect matching of rows to columns and the strongly connected components of the matched
    graph (the Dulmage-Mendelsohn decomposition) give blocks that can be solved one after the
    other, last first: for a chain of Assur groups these are the groups themselves (the
    four-bar's 9 x 9 system is a 6 x 6 block for the dyad and a 3 x 3 block for the crank), so
    each position costs a few small eliminations instead of one of the whole system.
    """

    table: np.ndarray  # the pairs as the kernel's integer table (_kernels.PAIR_COLS)
    angles: np.ndarray  # fixed line angle of each pair, rad
    cam_rows: np.ndarray  # loop-term rows of the cam pairs
    pattern: np.ndarray  # (n_eq, n_eq) bool: the structural non-zeros
    blk_ptr: np.ndarray  # block b has rows rperm[blk_ptr[b]:blk_ptr[b + 1]]
    rperm: np.ndarray
    cperm: np.ndarray  # the unknowns solved by each block, in the same slots
    cpl_ptr: np.ndarray  # coupling entries of block b: cpl_ptr[b]:cpl_ptr[b + 1]
    cpl_row: np.ndarray  # row within the block
    cpl_col: np.ndarray  # unknown of a later block
    blk_off: np.ndarray  # block b's entries (row-major) start at this slot
    pslot: np.ndarray  # (n_pairs, 14): the slot of every matrix entry of every pair
    n_slots: int  # the blocks' entries, then the coupling entries

    @property
    def block_sizes(self) -> tuple[int, ...]:
        return tuple(int(x) for x in np.diff(self.blk_ptr))


@lru_cache(maxsize=64)
def force_structure(machine: Machine) -> ForceStructure:
    """The block structure of the machine's force equations (:class:`ForceStructure`).

    Raises
    ------
    SingularForceSystem
        The pairs do not give as many unknowns as equations, or some links' equations cannot
        be matched with unknowns of their own (the system is singular at every position).
    """
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components, maximum_bipartite_matching

    names = machine.link_names
    n_links = len(names)
    n_eq = 3 * (n_links - 1)
    pairs = machine.pairs
    n_unk = sum(_N_UNKNOWN[p.kind] for p in pairs)
    if n_unk != n_eq:
        kinds = {k: sum(1 for p in pairs if p.kind == k) for k in _N_UNKNOWN}
        raise SingularForceSystem(
            f"{_machine_where(machine)}: {n_links - 1} moving links give {n_eq} equilibrium"
            f" equations but the pairs give {n_unk} unknowns ({kinds}); declare the cam and"
            " slot contacts of loop units (units[].contacts) and pin shared points"
            " (point units' pins)")
    table, angles, cam_rows = _pair_table(machine)
    pattern = np.zeros((n_eq, n_eq), dtype=bool)
    for kind, la, lb, col in table[:, [0, 1, 2, 7]]:
        if kind == K.PAIR_DRIVER:
            pattern[3 * (lb - 1) + 2, col] = True
            continue
        nf = 2 if kind == K.PAIR_REVOLUTE else 1
        for link in (la, lb):
            if link:
                pattern[3 * (link - 1):3 * link, col:col + nf] = True
                if kind == K.PAIR_PRISMATIC:
                    pattern[3 * (link - 1) + 2, col + 1] = True
    match = maximum_bipartite_matching(csr_matrix(pattern), perm_type="column")
    if (match < 0).any():
        lame = sorted({names[1 + int(r) // 3] for r in np.flatnonzero(match < 0)})
        raise SingularForceSystem(
            f"{_machine_where(machine)}: the equations of link(s) {', '.join(lame)} cannot be"
            " balanced by the pairs' unknowns (the force system is singular at every"
            " position); check which links the pairs, pins and contacts join")
    row_of_col = np.empty(n_eq, dtype=np.int64)
    row_of_col[match] = np.arange(n_eq)
    rows, cols = np.nonzero(pattern)
    graph = csr_matrix((np.ones(rows.size), (rows, row_of_col[cols])), shape=(n_eq, n_eq))
    n_comp, label = connected_components(graph, directed=True, connection="strong")
    # components in topological order: a component's rows use unknowns of later ones only
    succ = [set() for _ in range(n_comp)]
    for r, c in zip(rows, row_of_col[cols]):
        if label[r] != label[c]:
            succ[label[r]].add(label[c])
    indeg = np.zeros(n_comp, dtype=np.int64)
    for s_ in succ:
        for c in s_:
            indeg[c] += 1
    order, ready = [], [c for c in range(n_comp) if indeg[c] == 0]
    while ready:
        c = ready.pop()
        order.append(c)
        for t in succ[c]:
            indeg[t] -= 1
            if indeg[t] == 0:
                ready.append(t)
    rank = np.empty(n_comp, dtype=np.int64)
    rank[order] = np.arange(n_comp)
    rperm = np.argsort(rank[label], kind="stable").astype(np.int64)
    cperm = match[rperm].astype(np.int64)
    blk_ptr = np.concatenate([[0], np.cumsum(np.bincount(rank[label], minlength=n_comp))])
    cpl_ptr, cpl_row, cpl_col = [0], [], []
    block_of_col = np.empty(n_eq, dtype=np.int64)
    block_of_col[cperm] = np.repeat(np.arange(n_comp), np.diff(blk_ptr))
    for blk in range(n_comp):
        for i, r in enumerate(rperm[blk_ptr[blk]:blk_ptr[blk + 1]]):
            for c in np.flatnonzero(pattern[r]):
                if block_of_col[c] != blk:
                    assert block_of_col[c] > blk, "not block upper-triangular"
                    cpl_row.append(i)
                    cpl_col.append(int(c))
        cpl_ptr.append(len(cpl_row))
    # where each entry lives in the kernel's slot array: blocks row-major, then couplings
    sizes = np.diff(blk_ptr)
    blk_off = np.concatenate([[0], np.cumsum(sizes ** 2)]).astype(np.int64)
    slot = np.full((n_eq, n_eq), -1, dtype=np.int64)
    for blk in range(n_comp):
        r0, nb = blk_ptr[blk], sizes[blk]
        rr, cc = rperm[r0:r0 + nb], cperm[r0:r0 + nb]
        slot[np.ix_(rr, cc)] = blk_off[blk] + np.arange(nb * nb).reshape(nb, nb)
    for blk in range(n_comp):
        for c in range(cpl_ptr[blk], cpl_ptr[blk + 1]):
            slot[rperm[blk_ptr[blk] + cpl_row[c]], cpl_col[c]] = blk_off[-1] + c
    pslot = np.full((len(table), 14), -1, dtype=np.int64)
    for i, (kind, la, lb, col) in enumerate(table[:, [0, 1, 2, 7]]):
        if kind == K.PAIR_DRIVER:
            pslot[i, 0] = slot[3 * (lb - 1) + 2, col]
            continue
        for side, link in enumerate((lb, la)):
            if not link:
                continue
            for j in range(2 if kind == K.PAIR_REVOLUTE else 1):
                for comp in range(3):
                    pslot[i, 6 * j + 3 * side + comp] = slot[3 * (link - 1) + comp, col + j]
            if kind == K.PAIR_PRISMATIC:
                pslot[i, 12 + side] = slot[3 * (link - 1) + 2, col + 1]
    assert (slot[pattern] >= 0).all()
    out = ForceStructure(table, angles, cam_rows, pattern, blk_ptr.astype(np.int64), rperm,
                         cperm, np.asarray(cpl_ptr, dtype=np.int64),
                         np.asarray(cpl_row, dtype=np.int64), np.asarray(cpl_col, dtype=np.int64),
                         blk_off, pslot, int(blk_off[-1] + len(cpl_col)))
    for a in (out.pattern, out.blk_ptr, out.rperm, out.cperm, out.cpl_ptr, out.cpl_row,
              out.cpl_col, out.blk_off, out.pslot):
        a.setflags(write=False)
    return out


#: a DynamicsResult's own fields; anything else in its __dict__ is a cached derived quantity
_RESULT_FIELDS = frozenset(f.name for f in fields(DynamicsResult))
_N_RESULT_FIELDS = len(_RESULT_FIELDS)


class DynamicsPlan:
    """An inverse-dynamics call prepared once and run for many designs: the fast path for loops
    (balancing and optimisation call it thousands of times).

    Prepared once: the kinematics (:class:`~sewmech.kinematics.KinematicsPlan`, which also
    moves every link's centre of mass), the pair table and the block structure of the force
    equations (:func:`force_structure`), the link masses and the loads with their windows. A
    call is then two compiled calls (motion, then loads and forces) into reused arrays. Calls
    with the same batch shape return the same :class:`DynamicsResult` object, which views those
    arrays: each call overwrites it (its copy of the designs included) and drops the derived
    quantities (energies, reactions, ...) it had cached. :func:`inverse_dynamics` is a one-off
    plan.

    Parameters are those of :func:`inverse_dynamics` (which see); ``params`` and ``inputs`` are
    given per call. ``on_failure="mask"`` (as for the kinematics) gives NaN forces at the
    positions that cannot be assembled instead of raising (design sweeps). ``friction=False``
    leaves the file's ``[friction]`` out: the forces are then linear in the masses and the
    applied forces (the balancing basis' responses).
    """

    def __init__(
        self,
        machine: Machine,
        phi: ArrayLike,
        *,
        rpm: float | None = None,
        omega: ArrayLike | None = None,
        epsilon: ArrayLike = 0.0,
        gravity: bool = True,
        loads: Sequence[LoadSpec] | None = None,
        masses: Mapping[str, MassProperties] | None = None,
        on_failure: str = "raise",
        friction: bool = True,
    ):
        self.machine = machine
        self.structure = force_structure(machine)
        self.gravity = bool(gravity)
        self.masses = lm = link_masses(machine, masses)
        self.mass_props = {**machine.masses, **(masses or {})}
        self.loads = tuple(machine.spec.loads if loads is None else loads)
        if loads is not None:
            machine.check_loads(list(self.loads))
        n_links = len(machine.link_names)
        links = np.arange(n_links, dtype=np.int64)
        rows, local = [np.stack([links, lm.origins], axis=1)], [np.stack([lm.com_u, lm.com_v],
                                                                          axis=1)]
        # counterweights: the motion of the points (0, 0), (1, 0), (0, 1) of each one's link
        # frame, from which every point mass on it follows linearly (see _counterweights)
        self.counterweights = machine.counterweights
        self._cw_links = sorted({c.link_index for c in self.counterweights})
        for li in self._cw_links:
            origin = next(c.origin for c in self.counterweights if c.link_index == li)
            rows.append(np.array([[li, machine.point_index(origin)]] * 3, dtype=np.int64))
            local.append(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
        self.kin_plan = KinematicsPlan(
            machine, phi, rpm=rpm, omega=omega, epsilon=epsilon, on_failure=on_failure,
            extra_points=(np.concatenate(rows), np.concatenate(local)))
        self._loads = LoadTables.build(machine, self.loads, np.degrees(self.kin_plan.phi))
        self._load_links = self._loads.links
        self._springs = SpringTables.build(machine)
        self._friction = FrictionTables.build(machine) if friction else None
        self._live: tuple | None = None
        #: blocks of up to this many unknowns go to the written solvers of ``_blocks``, larger
        #: ones to the force kernel's generic loop (0: all of them; the tests compare the two)
        self._max_written = MAX_BLOCK

    def __call__(self, params: ArrayLike | None = None, *,
                 inputs: Mapping[str, ArrayLike] | None = None) -> DynamicsResult:
        """Forces for designs (see :func:`inverse_dynamics` for ``params`` and ``inputs``).

        The returned result views the plan's arrays: the next call with the same batch shape
        overwrites it (copy the arrays you want to keep).
        """
        kp = self.kin_plan
        P = kp.designs(params, inputs)
        kin = kp.run(P)
        a = kp.kernel_arrays()
        live = self._live
        if live is None or live[0] is not a:  # a new batch shape: new arrays and result
            live = self._live = self._prepare(kin, a)
        _, solve, head, tail, res, cw, out, fric, frictionless = live
        self._applied(a, P, out)
        kp_params = kernel_params(P)
        # friction is solved by the same kernel call (it keeps each position's factors for its
        # steps), after the counterweights' solves where counterweights have mass: then the
        # kernel is called a second time with their part
        cw_mass = cw is not None and bool(counterweight_values(
            self.counterweights, P.reshape(len(out["X"]), -1))[0].any())
        one_pass = fric is frictionless or not cw_mass
        if solve(*head, kp_params, *tail, *(fric if one_pass else frictionless),
                 self._max_written):  # some pivots ~ zero
            self._raise_singular(kin, a["feasible"], out["MINPIV"])
        if cw is not None:
            cw_part = None if one_pass else -out["X"].copy()
            self._counterweights(P, solve, head, tail, cw)
            if cw_part is not None:
                cw_part += out["X"]
                solve(*head, kp_params, *tail, *fric[:6], cw_part, *fric[7:],
                      self._max_written)
        if fric is not frictionless:
            self._check_settled(kin, out["SETTLE"])
        if kp.any_failed:  # some positions could not be assembled (on_failure="mask")
            feasible = a["feasible"]
            for key in ("LF", "LPOW", "X", "MINPIV", "SF", "SL", "SE", "SER", "SD", "FF",
                        "FP", "LON"):
                if key in out:
                    out[key][~feasible] = np.nan
        np.copyto(res.params, P)
        cached = res.__dict__
        if len(cached) > _N_RESULT_FIELDS:  # the last call's derived quantities are stale
            for key in [k for k in cached if k not in _RESULT_FIELDS]:
                del cached[key]
        return res

    def _prepare(self, kin: KinematicsResult, a: dict[str, np.ndarray]) -> tuple:
        """Output arrays, the force kernel's arguments and the result that views the outputs,
        for the kinematics plan's arrays ``a`` (one batch shape)."""
        kp, st, lm, machine = self.kin_plan, self.structure, self.masses, self.machine
        batch, n_phi = kin.batch_shape, kp.n_phi
        n_d = math.prod(batch)
        n_eq = st.pattern.shape[0]
        LF = np.empty((n_d, n_phi, len(self._loads), 2))
        LPOW, MINPIV = np.empty((n_d, n_phi)), np.empty((n_d, n_phi))
        X = np.empty((n_d, n_phi, n_eq))
        XB = np.zeros((n_d, n_phi, n_eq))
        n_sp, fr = len(self._springs), self._friction
        springs = dict(SF=np.empty((n_d, n_phi, n_sp)), SL=np.empty((n_d, n_phi, n_sp)),
                       SE=np.zeros((n_d, n_phi)), SER=np.zeros((n_d, n_phi)),
                       SD=np.zeros((n_d, n_phi)))
        friction = {} if fr is None else dict(
            FF=np.zeros((n_d, n_phi, len(fr))), FP=np.zeros((n_d, n_phi, len(fr))),
            SETTLE=np.zeros((n_d, 2)))
        LON = np.empty((n_d, n_phi, len(self._loads)))
        if n_d >= 4 and n_d * n_phi >= 20000:  # big batches: chunks of designs on threads
            def solve(*args, n_d=n_d):
                return run_chunks(K.force_solve, n_d, args)
        else:
            def solve(*args, n_d=n_d):
                return K.force_solve(0, n_d, *args)
        # inputs read-only (one array type per argument: numba compiles the kernel once)
        head = tuple(kernel_input(x) for x in (st.table, st.angles, st.cam_rows, machine.terms))
        tail = (a["P"], a["EP"], a["S"], a["TH"], a["GP"], a["GA"],
                *(kernel_input(x) for x in (lm.mass, lm.inertia)),
                GRAVITY if self.gravity else 0.0, XB,
                *(kernel_input(x) for x in (st.blk_ptr, st.blk_off, st.rperm, st.cperm,
                                            st.cpl_ptr, st.cpl_row, st.cpl_col, st.pslot)),
                st.n_slots, X, MINPIV)
        out = {"LF": LF, "LPOW": LPOW, "X": X, "XB": XB, "MINPIV": MINPIV, "LON": LON,
               **springs, **friction}
        # the force kernel's friction arguments (fr_int, fr_f, fr_pair, OM, GV, feasible, CW,
        # FF, FP, SETTLE, max_steps, tol, depth): the same array types with and without
        # friction (one compiled kernel); no rows, no steps: the frictionless analysis
        motion = (a["OM"], a["GV"], a["feasible"])
        frictionless = (kernel_input(np.zeros((0, 4), dtype=np.int64)),
                        kernel_input(np.zeros((0, 4))), kernel_input(np.zeros(0, dtype=np.int64)),
                        *motion, np.zeros((0, 0, 0)), np.zeros((0, 0, 0)), np.zeros((0, 0, 0)),
                        np.zeros((0, 2)), 0, TOLERANCE, ANDERSON_DEPTH)
        fric = frictionless if fr is None else (
            kernel_input(fr.ints), kernel_input(fr.values),
            kernel_input(np.asarray(fr.pair_index, dtype=np.int64)), *motion,
            np.zeros((0, 0, 0)), friction["FF"], friction["FP"], friction["SETTLE"], MAX_STEPS,
            TOLERANCE, ANDERSON_DEPTH)
        self._frictionless = frictionless

        def shape(x):
            return x.reshape(batch + x.shape[1:])

        n_links = len(machine.link_names)
        gp, gv, ga = (x[..., :n_links, :] for x in kp.extra_motion)
        cw = motion = None
        if self.counterweights:
            cw, motion = self._prepare_counterweights(a, tail, batch, n_eq)
        res = DynamicsResult(
            machine=machine, kin=kin, pairs=machine.pairs, unknowns=shape(X),
            gravity=self.gravity, load_names=tuple(ld.name for ld in self.loads),
            load_force=shape(LF), load_power=shape(LPOW), mass=lm, com_p=gp, com_v=gv,
            com_a=ga, params=np.empty(batch + (machine.defaults.size,)),
            mass_props=self.mass_props, load_links=self._load_links, counterweights=motion,
            load_on=shape(LON), load_dissipative=self._loads.dissipative,
            springs=SpringForces(self._springs.all_names, len(self._springs.names),
                                 shape(springs["SF"]), shape(springs["SL"]),
                                 shape(springs["SE"]), shape(springs["SER"]),
                                 shape(springs["SD"])),
            friction=None if fr is None else FrictionForces(
                fr.names, shape(friction["FF"]), shape(friction["FP"])))
        return a, solve, head, tail, res, cw, out, fric, frictionless

    def _applied(self, a: dict[str, np.ndarray], P: np.ndarray,
                 out: dict[str, np.ndarray]) -> None:
        """The applied forces of this call's motion that do not depend on the pair forces:
        the loads' forces, power and where they act (out's LF, LPOW, LON), the springs'
        (SF, SL, SE, SER, SD), all as generalized forces (XB)."""
        XB = out["XB"]
        XB[...] = 0.0
        loads = self._loads
        if len(loads):
            on = loads.forces(a, P, out["LF"], out["LPOW"])
            out["LON"][...] = np.moveaxis(on, 0, -1)
            loads.generalized(a["P"], a["GP"], out["LF"], XB)
        else:
            out["LPOW"][...] = 0.0
        if len(self._springs):
            self._springs.evaluate(a, XB, out)

    def _check_settled(self, kin, settle) -> None:
        """Raise where the force kernel's friction iteration did not settle (``settle`` (n_d,
        2): per design the change left relative to its largest force and the position where,
        -1 when it settled): at the first such design."""
        bad = np.flatnonzero(settle[:, 1] >= 0)
        if not len(bad):
            return
        d = int(bad[0])
        change, k = settle[d, 0], int(settle[d, 1])
        batch = kin.batch_shape
        design = tuple(int(i) for i in np.unravel_index(d, batch)) if batch else ()
        at = f"design {design}, " if design else ""
        raise AnalysisError(
            f"{_machine_where(self.machine)} at {at}phi = {float(kin.phi_deg[k]):.6g}"
            " deg", f"the force analysis with friction did not settle in {MAX_STEPS} steps"
            f" (a change of {change:.2g} of the largest force remained): the friction may"
            " lock the mechanism there", "Lower the friction coefficients or pin radii"
            " ([friction]), or check the pairs' geometry near this angle")

    # ---- counterweights -----------------------------------------------------------------------
    # The forces are linear in the loads a point mass m at r = (u, v) of link L's frame puts on
    # L: its inertia force and weight (linear in m and m r) and their moment about the frame's
    # origin (linear in m r, and m |r|^2 times the link's angular acceleration). So with X_0,
    # X_u, X_v the machine's answer to 1 kg at (0, 0), (1, 0), (0, 1) of that frame alone (no
    # loads, no other mass; gravity as asked) and X_I its answer to 1 kg mm^2 of moment of
    # inertia on L alone, the mass adds
    #     m X_0 + m u (X_u - X_0 - X_I) + m v (X_v - X_0 - X_I) + m (u^2 + v^2) X_I.
    # Four solves per link with counterweights give it for every design, whatever its
    # counterweights.
    def _prepare_counterweights(self, a, tail, batch, n_eq):
        """Arrays of the counterweight solves and the result's CounterweightMotion."""
        n_links = len(self.machine.link_names)
        n_d, n_phi = a["GP"].shape[:2]
        n_cw = len(self.counterweights)
        units = [np.zeros(n_links) for _ in self._cw_links]
        for e, li in zip(units, self._cw_links):
            e[li] = 1.0
        units = [kernel_input(e) for e in units]
        nothing = kernel_input(np.zeros(n_links))
        scratch = dict(
            GP=np.zeros((n_d, n_phi, n_links, 2)), GA=np.zeros((n_d, n_phi, n_links, 2)),
            unit=units, nothing=nothing,
            # no applied forces; writable like the machine's own XB, so that the force kernel is
            # compiled for one array type (a read-only one here cost a second 15 s compile)
            XB=np.zeros((n_d, n_phi, n_eq)),
            MINPIV=np.empty((n_d, n_phi)),
            X=np.empty((len(self._cw_links), 4, n_d, n_phi, n_eq)),
            cp=np.empty((n_d, n_phi, n_cw, 2)), cv=np.empty((n_d, n_phi, n_cw, 2)),
            ca=np.empty((n_d, n_phi, n_cw, 2)), mass=np.empty((n_d, n_cw)))
        shape = batch
        motion = CounterweightMotion(
            names=tuple(c.name for c in self.counterweights),
            links=np.array([c.link_index for c in self.counterweights], dtype=np.int64),
            z=np.array([c.z for c in self.counterweights]),
            mass=scratch["mass"].reshape(shape + (n_cw,)),
            p=scratch["cp"].reshape(shape + (n_phi, n_cw, 2)),
            v=scratch["cv"].reshape(shape + (n_phi, n_cw, 2)),
            a=scratch["ca"].reshape(shape + (n_phi, n_cw, 2)))
        return scratch, motion

    def _counterweights(self, P, solve, head, tail, cw) -> None:
        """Add the counterweights of designs ``P`` to the unknowns ``tail``'s X holds, and
        fill their motion."""
        n_links = len(self.machine.link_names)
        a = self.kin_plan.kernel_arrays()
        n_d = a["GP"].shape[0]
        m, u, v = counterweight_values(self.counterweights, P.reshape(n_d, -1))
        cw["mass"][...] = m
        X = tail[-2]  # (X, MINPIV)
        for j, li in enumerate(self._cw_links):
            base = n_links + 3 * j  # the three frame points of this link among the extras
            on = [k for k, c in enumerate(self.counterweights) if c.link_index == li]
            if m[:, on].any():  # (a link whose counterweights all weigh 0 adds nothing)
                self._counterweight_solves(P, solve, head, tail, cw, j, li, base)
            X0, Xu, Xv, XI = cw["X"][j]
            for k in on:
                if m[:, k].any():
                    mk, mu, mv, mr2 = (x[:, k, None, None] for x in (m, m * u, m * v,
                                                                      m * (u * u + v * v)))
                    X += mk * X0 + mu * Xu + mv * Xv + mr2 * XI
                for out, key in ((cw["cp"], "GP"), (cw["cv"], "GV"), (cw["ca"], "GA")):
                    g = a[key][:, :, base:base + 3]
                    out[:, :, k] = (g[:, :, 0] + u[:, k, None, None] * (g[:, :, 1] - g[:, :, 0])
                                    + v[:, k, None, None] * (g[:, :, 2] - g[:, :, 0]))

    def _counterweight_solves(self, P, solve, head, tail, cw, j, li, base) -> None:
        """The machine's answers to 1 kg at (0, 0), (1, 0), (0, 1) of link ``li``'s frame and
        to 1 kg mm^2 on it, as X_0, X_u - X_0 - X_I, X_v - X_0 - X_I, X_I in cw["X"][j]."""
        a = self.kin_plan.kernel_arrays()
        # tail: P, EP, S, TH, GP, GA, mass, inertia, gravity, XB, (8 block arrays), n_slots,
        # X, MINPIV
        state, gravity, rest = tail[:4], tail[8], tail[10:-2]
        for b in range(4):  # 1 kg at each point; then 1 kg mm^2 (at any point: a couple)
            cw["GP"][:, :, li] = a["GP"][:, :, base + min(b, 2)]
            cw["GA"][:, :, li] = a["GA"][:, :, base + min(b, 2)]
            mass, inertia = (cw["unit"][j], cw["nothing"]) if b < 3 else \
                (cw["nothing"], cw["unit"][j])
            solve(*head, kernel_params(P), *state, cw["GP"], cw["GA"], mass, inertia, gravity,
                  cw["XB"], *rest, cw["X"][j, b], cw["MINPIV"], *self._frictionless,
                  self._max_written)
        X0, Xu, Xv, XI = cw["X"][j]
        Xu -= X0 + XI
        Xv -= X0 + XI

    def _raise_singular(self, kin: KinematicsResult, feasible: np.ndarray,
                        minpiv: np.ndarray) -> None:
        """Raise SingularForceSystem at the first assembled position with a zero pivot."""
        bad = feasible & ~(minpiv > K.PIVOT_MIN)
        if not bad.any():  # only positions that did not assemble (masked)
            return
        d, k = np.argwhere(bad)[0]
        batch = kin.batch_shape
        design = tuple(int(i) for i in np.unravel_index(d, batch)) if batch else ()
        at = f"design {design}, " if design else ""
        raise SingularForceSystem(
            f"{_machine_where(self.machine)} at {at}phi = {float(kin.phi_deg[k]):.6g} deg: the"
            " equilibrium equations are singular (a mechanism at a dead centre with respect"
            " to its driver, or a pair whose line passes through its link's pivot); step"
            " around this angle")


def inverse_dynamics(
    machine: Machine,
    phi: ArrayLike,
    *,
    params: ArrayLike | None = None,
    inputs: Mapping[str, ArrayLike] | None = None,
    rpm: float | None = None,
    omega: ArrayLike | None = None,
    epsilon: ArrayLike = 0.0,
    gravity: bool = True,
    loads: Sequence[LoadSpec] | None = None,
    masses: Mapping[str, MassProperties] | None = None,
) -> DynamicsResult:
    """Forces in every pair, the driving torque and the frame reactions over crank angles.

    Parameters
    ----------
    machine : Machine
    phi : array_like, shape (n_phi,)
        Upper-shaft angles, rad.
    params, inputs, rpm, omega, epsilon
        As :func:`sewmech.kinematics.kinematics` (designs, settings, the shaft's speed in
        rev/min or rad/s and its acceleration in rad/s^2).
    gravity : bool
        Weight of the links along -y (9.80665 m/s^2).
    loads : sequence of LoadSpec, optional
        Process loads; default: the machine file's ``[[loads]]``. ``[]`` for none.
    masses : mapping link -> MassProperties, optional
        Replace or add link mass properties (link frame, mm, kg, kg mm^2).

    Returns
    -------
    DynamicsResult

    Raises
    ------
    SingularForceSystem
        The machine's pairs do not give as many unknowns as equations, or the equations are
        singular at some position (a dead centre of a mechanism with a driver).

    See Also
    --------
    DynamicsPlan : the same call prepared once, for loops over many designs.
    """
    plan = DynamicsPlan(machine, phi, rpm=rpm, omega=omega, epsilon=epsilon, gravity=gravity,
                        loads=loads, masses=masses)
    return plan(params, inputs=inputs)


_KIND_CODE = {"revolute": K.PAIR_REVOLUTE, "prismatic": K.PAIR_PRISMATIC, "cam": K.PAIR_CAM,
              "slot": K.PAIR_SLOT, "driver": K.PAIR_DRIVER}


@lru_cache(maxsize=64)
def _pair_table(machine: Machine) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The machine's pairs as the kernel's integer table (see ``_kernels.PAIR_COLS``), their
    fixed line angles (rad) and the cam pairs' loop-term rows."""
    names = machine.link_names
    rows, angles, cam_rows = [], [], []
    col = 0
    for pair in machine.pairs:
        row = [_KIND_CODE[pair.kind], names.index(pair.links[0]), names.index(pair.links[1]),
               machine.point_index(pair.point) if pair.point else -1,
               names.index(pair.line_link) if pair.line_link else -1,
               machine.variable_index(pair.line_var) if pair.line_var else -1,
               pair.line_param, col, 0, len(cam_rows), len(pair.terms)]
        if pair.kind == "cam":
            row[8] = int(machine.terms[pair.cam_term, 2])
            cam_rows.extend(pair.terms)
        rows.append(row)
        angles.append(pair.extra_angle)
        col += _N_UNKNOWN[pair.kind]
    table = np.asarray(rows, dtype=np.int64).reshape(-1, K.PAIR_COLS)
    out = (table, np.asarray(angles, dtype=float), np.asarray(cam_rows, dtype=np.int64))
    for a in out:
        a.setflags(write=False)
    return out


# ---- the shaft's speed over the cycle --------------------------------------------------------------


@dataclass(frozen=True)
class SpeedFluctuation:
    """Steady running with a constant motor torque and a flywheel (one machine, one cycle).

    Attributes
    ----------
    phi : rad, (n_phi,)
    omega : rad/s, the shaft's speed omega(phi)
    epsilon : rad/s^2, its acceleration omega d omega / d phi
    motor_torque : N mm, the constant motor torque (the cycle mean of the load torque)
    load_torque : N mm, the torque the weights and process loads ask of the shaft at rest
    reduced_inertia : kg mm^2, J(phi) of the mechanisms plus the flywheel
    delta : coefficient of speed fluctuation (omega_max - omega_min) / omega_mean
    """

    phi: np.ndarray
    omega: np.ndarray
    epsilon: np.ndarray
    motor_torque: float
    load_torque: np.ndarray
    reduced_inertia: np.ndarray
    flywheel: float
    delta: float


def speed_fluctuation(machine: Machine, *, rpm: float | None = None, flywheel: float = 0.0,
                      n_phi: int = 720, inputs: Mapping[str, ArrayLike] | None = None,
                      loads: Sequence[LoadSpec] | None = None, gravity: bool = True,
                      masses: Mapping[str, MassProperties] | None = None) -> SpeedFluctuation:
    """omega(phi) of the upper shaft under a constant motor torque (beyond the JB report).

    The machine is one degree of freedom: d/dphi (J(phi) omega^2 / 2) = M - Q(phi), where
    J(phi) is the reduced inertia (mechanisms plus ``flywheel``, kg mm^2), M the motor torque
    and Q(phi) the torque everything but the inertia asks at the shaft (weights, springs and
    process loads by virtual work; friction and dampers by the power they take), taken on the
    motion at the nominal speed: friction, dampers and resistive loads depend on it, and the
    fluctuation is small. A steady cycle needs M = mean Q; the energy integral then gives
    omega(phi), scaled so that its mean over the cycle is ``rpm``.
    """
    if not 0.0 <= flywheel <= 1e12:  # (a NaN fails too)
        raise OptionError("flywheel", f"must be a moment of inertia in 0 .. 1e12 kg mm^2, got"
                          f" {flywheel!r}", "Give the flywheel's inertia about the shaft")
    if rpm is not None:
        rpm = check_speed("rpm", rpm)
    if not 8 <= n_phi <= 100_000:
        raise OptionError("n_phi", f"must be in 8 .. 100000 positions, got {n_phi!r}")
    phi = np.linspace(0.0, 2 * math.pi, n_phi, endpoint=False)
    w_nom = (machine.rpm if rpm is None else rpm) * 2 * math.pi / 60
    unit = inverse_dynamics(machine, phi, omega=1.0, inputs=inputs, loads=loads,
                            gravity=gravity, masses=masses)  # omega = 1 rad/s: rates = d/dphi
    J = unit.reduced_inertia + flywheel  # kg mm^2
    if not (J > 0).all():
        raise AnalysisError(machine.file, "the reduced inertia J(phi) is zero (no [masses] and"
                           " no flywheel): the speed cannot be computed", "Add [masses.LINK]"
                           " tables or give a flywheel")
    nominal = inverse_dynamics(machine, phi, omega=w_nom, inputs=inputs, loads=loads,
                               gravity=gravity, masses=masses)
    Q = (nominal.potential_energy_rate - nominal.external_power + nominal.friction_power
         + nominal.damping_power) / w_nom  # N mm per rad
    M = float(Q.mean())
    # work of M - Q from phi = 0, by the trapezoidal rule on the periodic grid (closed cycle)
    h = 2 * math.pi / n_phi
    f = M - Q
    W = np.concatenate([[0.0], np.cumsum(0.5 * h * (f[:-1] + f[1:]))])  # N mm

    def omega_for(w0):  # 1/2 J w^2 = 1/2 J0 w0^2 + W, in kg mm^2/s^2 (W in N mm = 1e3 kg mm^2/s^2)
        return np.sqrt(np.maximum(J[0] * w0 ** 2 + 2e3 * W, 0.0) / J)

    from scipy.optimize import brentq

    def excess(w0):  # the mean speed over the nominal one: rises with the speed at phi = 0
        return omega_for(w0).mean() - w_nom

    if excess(0.0) >= 0.0:  # from rest at phi = 0 the work of the loads alone is too fast
        raise AnalysisError(machine.file, f"no steady cycle at {w_nom * 30 / math.pi:g} rpm:"
                           " the work of the weights and process loads over the turn moves"
                           " the machine's reduced inertia (least J"
                           f" {J.min():.3g} kg mm^2) faster than that even from rest",
                           "Give the links' [masses] (a crank's inertia too), add a flywheel"
                           " or raise the speed")
    hi = 10.0 * w_nom
    while excess(hi) < 0.0:  # the mean grows like w0 sqrt(J0 / J): a bracket is near
        hi *= 10.0
    w0 = brentq(excess, 0.0, hi, xtol=1e-12)
    om = omega_for(w0)
    if not (J[0] * w0 ** 2 + 2e3 * W > 0).all():
        raise AnalysisError(machine.file, "the shaft stops within the cycle: the motor torque"
                           " cannot carry the machine at this speed", "Add a flywheel or raise"
                           " the speed")
    # epsilon = omega domega/dphi = (M - Q - 1/2 J' omega^2) / J, J' from the motion (exact)
    dJ = 2e3 * unit.kinetic_energy_rate  # d(2T)/dphi at unit speed = dJ/dphi, kg mm^2 / rad
    eps = (1e3 * f - 0.5 * dJ * om ** 2) / J
    return SpeedFluctuation(phi, om, eps, M, Q, J, flywheel,
                            float((om.max() - om.min()) / om.mean()))
