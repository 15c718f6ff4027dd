"""Process loads of the force analysis, evaluated from the motion.

Every applied force acts at a point of a link (or of the frame, where it is only recorded).
The force kernel (:func:`sewmech._kernels.force_solve`) reads them as generalized forces per
link, in the rows of the Newton-Euler equations: the sum of their x and y components (N) and of
their moments about the link's centre of mass (N mm); :func:`add_point_force` and
:func:`add_couple` put one force or couple there (springs and friction use them too).

A process load (``[[loads]]``, :class:`~sewmech.spec.LoadSpec`) acts where its shaft-angle
windows and every clause of its ``when`` hold. A clause reads a channel of the motion: a
kinematics channel (``p_feed_dog.tip_y``: the dog's tip height, mm; ``v_...``, ``theta_...``,
``q_...``; docs/notation.md) or the thread's take-up section ``thread.take_up_mm`` (the length of
the needle thread between the file's ``[thread] take_up`` guides, mm: it grows while the take-up
draws thread back). ``above``/``below`` compare the channel with a value; ``rising``/``falling``
read the sign of its rate; ``within_of_max`` holds where the channel is within that much of its
largest value over the whole turn (found on a 5 deg grid of its own, then on a 0.25 deg grid
around it and refined by a parabola, whatever grid the forces are asked on).

Force laws: ``constant`` (``force_N`` along a fixed direction or the bisector toward points),
``elastic`` (``force_N`` plus ``rate_N_per_mm`` times the travel of its first above/below
channel past the threshold, along the fixed direction), ``resistive`` (``force_N`` against the
point's velocity, along the line ``angle_deg`` if given, with the smooth sign
v / sqrt(v^2 + s^2), s = ``smooth_mm_s``). :class:`LoadTables` prepares the loads of a machine
once for a grid of shaft angles; :meth:`LoadTables.forces` evaluates them for a batch of
designs.

Units: positions mm, velocities mm/s, forces N, moments N mm, power N mm/s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .channels import ChannelRef, channel_values, resolve_channel
from .machine import Machine
from .spec import Condition, LoadSpec

#: the grids on which ``within_of_max`` finds a channel's largest value over the turn: a coarse
#: one over the turn, then a fine one across the coarse steps around its largest value, deg
MAX_COARSE_DEG = 5.0
MAX_GRID_DEG = 0.25


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


def smooth_sign(x: np.ndarray, scale: float) -> np.ndarray:
    """x / sqrt(x^2 + scale^2): the sign of x, smooth where |x| is below ``scale``."""
    return x / np.sqrt(x * x + scale * scale)


@dataclass(frozen=True)
class ThreadSection:
    """The take-up section of the machine's ``[thread]`` path: guide point indices and signed
    radii (mm, + a counter-clockwise wrap)."""

    points: tuple[int, ...]
    rho: np.ndarray

    @classmethod
    def of(cls, machine: Machine) -> ThreadSection | None:
        t = machine.spec.thread
        if t is None:
            return None
        i0, i1 = t.take_up
        guides = t.guides[i0:i1 + 1]
        return cls(tuple(machine.point_index(g.point) for g in guides),
                   np.array([g.radius * (1.0 if g.wrap == "ccw" else -1.0) for g in guides]))

    def length_and_rate(self, P: np.ndarray, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Length (mm) and its rate (mm/s) of the section, (D, n_phi)."""
        from .threadpath import path_length, path_length_gradient

        c = P[:, :, list(self.points)]
        L = path_length(c, self.rho, on_overlap="nan")
        g = path_length_gradient(c, self.rho)
        return L, np.einsum("dkgc,dkgc->dk", g, V[:, :, list(self.points)])


# ---- loads ------------------------------------------------------------------------------------


@dataclass
class LoadTables:
    """The process loads of a machine, prepared for the shaft angles ``phi_deg``: for each
    load its link and point indices, its window mask (n_phi,), its direction (a fixed (cos,
    sin), or None for a bisector toward the ``toward`` points, or for a resistive load without
    a line), its conditions resolved to channels."""

    specs: tuple[LoadSpec, ...]
    links: tuple[int, ...]
    points: tuple[int, ...]
    on: np.ndarray
    direction: tuple[tuple[float, float] | None, ...]
    toward: tuple[tuple[int, ...], ...]
    conditions: tuple[tuple[tuple[ChannelRef, Condition], ...], ...]
    thread: ThreadSection | None
    machine: Machine = field(repr=False)
    phi: np.ndarray = field(repr=False)
    _max_plan: object = field(default=None, repr=False)
    _supports: dict = field(default_factory=dict, repr=False)

    @classmethod
    def build(cls, machine: Machine, loads: Sequence[LoadSpec], phi_deg: np.ndarray
              ) -> LoadTables:
        links, points, on, direction, toward, conds = [], [], [], [], [], []
        masks: dict[tuple, np.ndarray] = {}
        names = (machine.point_names, machine.link_names, machine.variable_names)
        thread = ThreadSection.of(machine)
        for load in loads:
            key = tuple(map(tuple, load.windows_deg))
            if key not in masks:
                masks[key] = in_windows(phi_deg, load.windows_deg).astype(float)
            on.append(masks[key])
            links.append(machine.link_index(load.link))
            points.append(machine.point_index(load.point))
            if load.angle_deg is not None:
                a = math.radians(load.angle_deg)
                direction.append((math.cos(a), math.sin(a)))
                toward.append(())
            else:
                direction.append(None)
                toward.append(tuple(machine.point_index(q) for q in load.toward or ()))
            conds.append(tuple((resolve_channel(c.channel, *names, thread is not None), c)
                               for c in load.when))
        return cls(tuple(loads), tuple(links), tuple(points),
                   np.asarray(on, dtype=float).reshape(len(loads), len(phi_deg)),
                   tuple(direction), tuple(toward), tuple(conds), thread, machine,
                   np.radians(np.asarray(phi_deg, dtype=float)))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(ld.name for ld in self.specs)

    def __len__(self) -> int:
        return len(self.specs)

    @property
    def dissipative(self) -> tuple[bool, ...]:
        """Which loads only ever take energy out (the resistive ones)."""
        return tuple(ld.law == "resistive" for ld in self.specs)

    def _maxima(self, ref: ChannelRef, params: np.ndarray) -> np.ndarray:
        """The channel's largest value over the turn, (D,), for the designs ``params`` (the
        same designs and settings the forces are asked for): found on a 5 deg grid of its own,
        then on a 0.25 deg grid across the steps around it, refined by a parabola through the
        three best (the channels a condition reads are smooth where they peak). Kept per
        design, on the machine (the counterweights, which move nothing, left out of its key)."""
        from .kinematics import KinematicsPlan, kinematics

        P = params.reshape(-1, params.shape[-1])
        out = np.empty(P.shape[0])
        support = self._support(ref)
        todo: dict = {}  # key -> the designs that need it (designs alike in it share it)
        for d in range(P.shape[0]):
            key = (ref.name, P[d, support].tobytes())
            hit = self.machine._condition_maxima.get(key)
            if hit is None:
                todo.setdefault(key, []).append(d)
            else:
                out[d] = hit
        if not todo:
            return out
        todo = [(ds, key) for key, ds in todo.items()]
        if self._max_plan is None:
            n = round(360.0 / MAX_COARSE_DEG)
            self._max_plan = KinematicsPlan(self.machine, np.arange(n) * (2 * math.pi / n),
                                            on_failure="mask")
        plan = self._max_plan
        rows = np.array([ds[0] for ds, _ in todo])
        plan.run(P[rows])
        coarse = channel_values(ref, plan.kernel_arrays(), self.thread)[0]  # (m, n)
        h = math.radians(MAX_COARSE_DEG)
        offsets = np.linspace(-h, h, 2 * round(MAX_COARSE_DEG / MAX_GRID_DEG) + 1)
        ks = np.argmax(np.where(np.isfinite(coarse), coarse, -np.inf), axis=1)
        cache = self.machine._condition_maxima
        for k in np.unique(ks):  # the designs whose coarse peak is at the same angle together
            group = np.nonzero(ks == k)[0]
            r = kinematics(self.machine, k * h + offsets, params=P[rows[group]],
                           on_failure="mask")
            if ref.kind == "thread":
                fine = self.thread.length_and_rate(r.p, r.v)[0]
            else:
                fine = np.asarray(r.channel(ref.name)[0], dtype=float).reshape(len(group), -1)
            fine = np.where(np.isfinite(fine), fine, -np.inf)
            for j, g in enumerate(group):
                f = fine[j]
                i = int(np.argmax(f))
                y1 = f[i]
                peak = y1
                if 0 < i < len(f) - 1:
                    y0, y2 = f[i - 1], f[i + 1]
                    den = y0 - 2.0 * y1 + y2
                    if den < 0.0:
                        peak = max(y1, y1 - 0.125 * (y2 - y0) ** 2 / den)
                ds, key = todo[g]
                out[ds] = peak
                if len(cache) >= 4096:
                    cache.pop(next(iter(cache)))
                cache[key] = peak
        return out

    def _channel(self, ref: ChannelRef, a: dict[str, np.ndarray], params: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray | None]:
        """:func:`channel_values` of the designs of ``a``; a thread channel (a path and its
        gradient at every position) only once for designs whose parameters that move its
        guides are the same (a sweep of the feed's dimensions shares the take-up's thread)."""
        D = a["P"].shape[0]
        if ref.kind != "thread" or D < 2:
            return channel_values(ref, a, self.thread)
        P = np.asarray(params, dtype=float).reshape(D, -1)[:, self._support(ref)]
        _, first, back = np.unique(P, axis=0, return_index=True, return_inverse=True)
        if len(first) == D:
            return channel_values(ref, a, self.thread)
        val, rate = channel_values(ref, {"P": a["P"][first], "V": a["V"][first]}, self.thread)
        back = back.reshape(-1)
        return val[back], (None if rate is None else rate[back])

    def _support(self, ref: ChannelRef) -> np.ndarray:
        """The parameters a channel's values depend on (indices): its largest value is kept
        per their values alone (designs that differ elsewhere, as a sweep's feed dimensions
        for the take-up's thread, share it)."""
        hit = self._supports.get(ref.name)
        if hit is not None:
            return hit
        from .sensitivity import _plan

        m = self.machine
        if ref.kind == "thread":
            names = [f"p_{m.point_names[i]}_x" for i in self.thread.points]
        elif ref.kind in ("p", "v", "a"):
            names = [f"p_{m.point_names[ref.index]}_x"]
        elif ref.kind in ("theta", "omega", "epsilon"):
            names = [f"theta_{m.link_names[ref.index]}"]
        else:
            names = [f"q_{m.variable_names[ref.index]}"]
        plan = _plan(m, names)
        sup: set = set()
        for name in names:
            kind, _, rest = name.partition("_")
            fam = {"p": "p", "theta": "l", "q": "v"}[kind]
            if fam == "p":
                i = m.point_names.index(rest.rpartition("_")[0])
            elif fam == "l":
                i = m.link_names.index(rest)
            else:
                i = m.variable_names.index(rest)
            sup |= {int(j) for j in plan.support[plan.quantity[fam][i]]}
        out = np.array(sorted(sup), dtype=np.int64)
        self._supports[ref.name] = out
        return out

    def masks(self, a: dict[str, np.ndarray], params: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        """(n_loads, D, n_phi): where each load acts (1.0 or 0.0), and the travel of its first
        above/below channel past the threshold (mm or the channel's unit; 0 without one)."""
        D, n_phi = a["P"].shape[:2]
        on = np.empty((len(self), D, n_phi))
        travel = np.zeros((len(self), D, n_phi))
        read: dict[str, tuple] = {}  # each channel read once a call (a thread channel's
        for j in range(len(self)):  # length and rate cost a path and its gradient)
            m = np.broadcast_to(self.on[j] > 0.5, (D, n_phi)).copy()
            first = True
            for ref, c in self.conditions[j]:
                if ref.name not in read:
                    read[ref.name] = self._channel(ref, a, params)
                val, rate = read[ref.name]
                with np.errstate(invalid="ignore"):
                    if c.above is not None:
                        m &= val > c.above
                        if first:
                            travel[j] = np.maximum(val - c.above, 0.0)
                    elif c.below is not None:
                        m &= val < c.below
                        if first:
                            travel[j] = np.maximum(c.below - val, 0.0)
                    elif c.rising:
                        m &= rate > 0.0
                    elif c.falling:
                        m &= rate < 0.0
                    else:
                        top = self._maxima(ref, params)
                        m &= val >= top[:, None] - c.within_of_max
                if c.above is not None or c.below is not None:
                    first = False
            on[j] = m
        return on, travel

    def forces(self, a: dict[str, np.ndarray], params: np.ndarray, LF: np.ndarray,
               LPOW: np.ndarray) -> np.ndarray:
        """Fill LF (D, n_phi, n_loads, 2) with each load's force, N, and LPOW (D, n_phi) with
        their power on the machine, N mm/s, from the kinematics kernel arrays ``a`` (P, V of
        the points: (D, n_phi, n_points, 2), ...) of the designs ``params``; returns where
        each load acts, (n_loads, D, n_phi), 1.0 or 0.0."""
        P, V = a["P"], a["V"]
        LPOW[...] = 0.0
        on, travel = self.masks(a, params)
        for j, spec in enumerate(self.specs):
            pi = self.points[j]
            d = self.direction[j]
            v = V[:, :, pi]
            if spec.law == "resistive":
                if d is not None:  # against the velocity's component along the line
                    u = np.array(d)
                    f = -spec.force_N * smooth_sign(v @ u, spec.smooth_mm_s)
                    F = f[..., None] * u
                else:  # against the velocity
                    speed = np.sqrt(np.sum(v * v, axis=-1))
                    F = -spec.force_N * (v / np.sqrt(speed * speed + spec.smooth_mm_s ** 2
                                                     )[..., None])
            else:
                if d is not None:
                    u = np.array(d)
                else:  # the bisector of the unit vectors toward the given points
                    u = np.zeros(P.shape[:2] + (2,))
                    for q in self.toward[j]:
                        e = P[:, :, q] - P[:, :, pi]
                        u += e / np.sqrt(e[..., :1] ** 2 + e[..., 1:] ** 2)
                    u /= np.sqrt(u[..., :1] ** 2 + u[..., 1:] ** 2)
                f = spec.force_N + (spec.rate_N_per_mm * travel[j]
                                    if spec.law == "elastic" else 0.0)
                F = np.broadcast_to(f, P.shape[:2])[..., None] * u
            LF[:, :, j] = F * on[j][..., None]
            LPOW += LF[:, :, j, 0] * v[..., 0] + LF[:, :, j, 1] * v[..., 1]
        return on

    def generalized(self, P: np.ndarray, GP: np.ndarray, LF: np.ndarray,
                    XB: np.ndarray) -> None:
        """Add the loads' forces LF at their points to the generalized forces XB."""
        for j in range(len(self)):
            add_point_force(XB, self.links[j], P[:, :, self.points[j]], LF[:, :, j], GP)
