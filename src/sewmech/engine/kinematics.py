"""Kinematics of a compiled machine over crank angles and designs.

:func:`kinematics` is the one entry point: it broadcasts designs, builds the march of shaft
angles (continuation for loop units), runs the compiled interpreter once and wraps the arrays in
a :class:`~sewmech.results.KinematicsResult`.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from . import _kernels as K
from ._threads import run_chunks
from .errors import AssemblyError, ConvergenceError, OptionError, ParameterError, SewmechError
from .machine import PARAM_LIMIT, Machine, compile_machine, domain_message, parameter_location
from .margins import describe
from .results import KinematicsResult, mask_runs
from .spec import MachineSpec

_REASONS = {
    K.FAIL_ASSEMBLY: ("cannot be assembled: its closure equations have no real solution (a link"
                      " is too short or too long for the distance it must bridge)",
                      "Check this unit's lengths and the positions of the points it joins"),
    K.FAIL_SINGULAR: ("singular position (a dead centre or toggle): the velocity of this unit is"
                      " not defined here",
                      "Evaluate at angles off the toggle or change the dimensions"),
    K.FAIL_NEWTON: ("the loop solver did not converge", "Check the unit's initial guesses"
                    " (unknown_*) at the assembly angle and the loop terms"),
    K.FAIL_LOST: ("continuation was lost after the loop failed at an earlier angle", ""),
}


# designs x march steps below which the single-threaded kernel is used
_PARALLEL_MIN_WORK = 20_000


def rpm_to_rad_s(rpm: float) -> float:
    """Shaft speed rev/min -> rad/s."""
    return rpm * 2.0 * math.pi / 60.0


def _march(phi: np.ndarray, start: float, max_step: float):
    """Continuation path from the assembly angle through every requested angle (forward).

    Returns (march angles, output row of each march step or -1 for an intermediate step, index
    into phi of the step's shaft speed). Gaps wider than max_step are split evenly.
    """
    if not phi.size:
        empty = np.empty(0, dtype=np.int64)
        return np.empty(0), empty, empty
    offsets = np.mod(phi - start, 2.0 * math.pi)
    order = np.argsort(offsets, kind="stable")
    targets = offsets[order]
    gaps = np.diff(targets, prepend=0.0)
    # steps per requested angle: the gap split into ceil(gap / max_step) equal parts
    n_sub = np.maximum(1, np.ceil(gaps / max_step - 1e-12).astype(np.int64))
    lead = targets[0] > 0.0  # the march starts at the assembly angle itself
    if lead:
        n_sub[0] = max(1, int(n_sub[0]))
    else:
        n_sub[0] = 1
    idx = np.repeat(np.arange(len(targets)), n_sub)  # the requested angle each step leads to
    first = np.cumsum(n_sub) - n_sub  # position of each group's first step
    k = np.arange(idx.size) - first[idx] + 1  # 1 .. n_sub within a group
    prev = np.where(idx > 0, targets[np.maximum(idx - 1, 0)], 0.0)
    march = start + prev + gaps[idx] * k / n_sub[idx]
    store = np.where(k == n_sub[idx], order[idx], -1).astype(np.int64)
    where = order[idx].astype(np.int64)
    if lead:
        march = np.concatenate([[start], march])
        store = np.concatenate([[-1], store])
        where = np.concatenate([[order[0]], where])
    return march, store, where


#: the fastest shaft speed sewmech accepts, rev/min (household machines run at 1000-1500,
#: industrial ones up to about 10,000)
MAX_RPM = 1e5
#: the slowest: a turn in 1000 minutes, slower than any hand turns a hand wheel. Below it the
#: squares of the speed (accelerations, kinetic energy) leave the floating-point range long
#: before the speed itself does (at 1e-165 rpm the continuation of the loop units failed, at
#: 5e-324 rpm the reduced inertia was 0 / 0)
MIN_RPM = 1e-3


def check_speed(name: str, rpm: float) -> float:
    """``rpm`` as a float, or an :class:`OptionError` unless it is a finite speed in
    MIN_RPM .. MAX_RPM rev/min."""
    try:
        value = float(rpm)
    except (TypeError, ValueError):
        raise OptionError(name, f"must be a number of rev/min, got {rpm!r}") from None
    if not MIN_RPM <= value <= MAX_RPM:  # (a NaN fails too)
        raise OptionError(name, f"must be a shaft speed in {MIN_RPM:g} .. {MAX_RPM:g} rev/min,"
                          f" got {value:g}", "Give the working speed, e.g. 1000")
    return value


def check_finite(name: str, values: np.ndarray, unit: str, *, limit: float) -> None:
    """An :class:`OptionError` unless every value is finite and within +-limit."""
    values = np.asarray(values, dtype=float)
    bad = ~(np.abs(values) <= limit)
    if bad.any():
        k = np.unravel_index(int(np.argmax(bad)), values.shape) if values.ndim else ()
        at = f"[{', '.join(map(str, k))}]" if k else ""
        raise OptionError(name, f"{name}{at} is {float(values[k])!r}: every value must be a"
                          f" finite number within +-{limit:g} {unit}")


@functools.cache
def _memory_bytes() -> float:
    """Physical memory of this computer, bytes (inf where it cannot be read; read once)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return math.inf


def kernel_input(a: np.ndarray) -> np.ndarray:
    """An input array as the kernels take it: C-contiguous and read-only, whether or not the
    caller's array is writable (the machine's tables are not), so that numba compiles each
    kernel for one array type instead of one per combination (20 s each for the interpreter)."""
    a = np.ascontiguousarray(a)
    if a.flags.writeable:
        a = a.view()
        a.flags.writeable = False
    return a


def kernel_params(P: np.ndarray) -> np.ndarray:
    """Designs ``P`` (batch + (n_parameters,)) as the kernels take them: (n_design,
    n_parameters), C-contiguous and read-only (see :func:`kernel_input`)."""
    return kernel_input(P.reshape(-1, P.shape[-1]))


class KinematicsPlan:
    """A kinematics call prepared once and run for many designs: the fast path for loops.

    Everything that does not depend on the design is done here once: argument checks, the
    continuation march, cos and sin of the march angles, the output selection and the pruned
    program. Each call then fills preallocated arrays in one compiled call and returns a
    :class:`KinematicsResult` that *views those arrays*: it stays valid until the plan's next
    call with the same batch shape, which overwrites it (``result.copy()`` is not needed for
    :func:`kinematics`, which uses a fresh plan per call). Use it where one machine is
    evaluated over and over, e.g. in an optimisation loop::

        plan = KinematicsPlan(m, phi, points=["P"], links=[])
        for x in candidates:
            p = plan(m.parameters({"coupler.length": x})).point("P").p   # (n_phi, 2) mm

    Parameters are those of :func:`kinematics` (which see); ``params`` and ``inputs`` are given
    per call. ``extra_points`` = (rows of (link index, origin point index or -1 for the frame
    origin), rows of (u, v) mm in the link frame) adds points that are not in the machine file,
    e.g. the links' centres of mass: after each call ``extra_motion`` holds their position,
    velocity and acceleration, batch + (n_phi, n_extra, 2) each (mm, mm/s, mm/s^2).
    ``start_phi`` (rad): where the loop units' continuation starts from their initial values
    (default: the file's ``assembly_phi_deg``); given a known solution at that angle as the
    initial values, a nearby angle is reached in one step (:mod:`sewmech.engine.evaluation`).
    """

    def __init__(
        self,
        machine: Machine,
        phi: ArrayLike,
        *,
        rpm: float | None = None,
        omega: ArrayLike | None = None,
        epsilon: ArrayLike = 0.0,
        on_failure: Literal["raise", "mask"] = "raise",
        points: Sequence[str] | None = None,
        links: Sequence[str] | None = None,
        variables: Sequence[str] | None = None,
        max_step_deg: float = 5.0,
        tol: float = 1e-10,
        max_iter: int = 25,
        extra_points: tuple[np.ndarray, np.ndarray] | None = None,
        start_phi: float | None = None,
    ):
        if on_failure not in ("raise", "mask"):
            raise OptionError("on_failure", f"must be 'raise' or 'mask', got {on_failure!r}")
        phi = np.array(phi, dtype=float, ndmin=1)  # a private copy: the result freezes it
        if phi.ndim != 1:
            raise OptionError("phi", f"must be one-dimensional (n_phi,), got shape {phi.shape}")
        check_finite("phi", phi, "rad", limit=PARAM_LIMIT)
        n_phi = phi.shape[0]
        if omega is None:
            if rpm is not None:
                check_speed("rpm", rpm)
            omega = rpm_to_rad_s(machine.rpm if rpm is None else rpm)
        omega_arr = np.empty(n_phi)
        omega_arr[...] = omega
        check_finite("omega", omega_arr, "rad/s", limit=rpm_to_rad_s(MAX_RPM))
        eps_arr = np.empty(n_phi)
        eps_arr[...] = epsilon
        check_finite("epsilon", eps_arr, "rad/s^2", limit=1e9)
        for name, value, lo, hi in (("max_step_deg", max_step_deg, 1e-3, 90.0),
                                    ("tol", tol, 1e-15, 1.0), ("max_iter", max_iter, 1, 1000)):
            if not lo <= value <= hi:  # (a NaN fails too)
                raise OptionError(name, f"must be in {lo:g} .. {hi:g}, got {value!r}")
        if machine.has_loops:
            start = machine.assembly_phi if start_phi is None else float(start_phi)
            march, store, where = _march(phi, start, math.radians(max_step_deg))
            march_omega, march_eps = omega_arr[where], eps_arr[where]
        else:
            march, store = phi, np.arange(n_phi, dtype=np.int64)
            march_omega, march_eps = omega_arr, eps_arr
        (self._pt_names, pt_sel, self._lk_names, lk_sel, self._var_names, var_sel, need_th,
         rows) = machine.selection(points, links, variables)
        program = machine.program if len(rows) == len(machine.program) else machine.program[rows]
        for a in (phi, omega_arr, eps_arr):
            a.setflags(write=False)
        self.machine = machine
        self.phi = phi
        self.omega = omega_arr
        self.epsilon = eps_arr
        self.on_failure = on_failure
        self._store = store
        self._rows = rows
        self._var_units = tuple(machine.variable_units[i] for i in var_sel)
        # the kernel's arguments before the design and after it (see _kernels.evaluate_program)
        self._head = (kernel_input(program),)
        tail = (machine.parameter_lo, machine.parameter_hi, march, np.cos(march),
                np.sin(march), store, march_omega, march_eps,
                machine.groups, machine.unknowns, machine.terms, machine.cams, machine.arcs,
                len(machine.point_names), len(machine.link_names), len(machine.variable_names),
                float(tol), int(max_iter), need_th, pt_sel, lk_sel, var_sel)
        self._tail = tuple(kernel_input(x) if isinstance(x, np.ndarray) else x for x in tail)
        self._n_march = march.shape[0]
        if extra_points is None:
            extra_points = (np.empty((0, 2), dtype=np.int64), np.empty((0, 2)))
        self._extra = (kernel_input(np.asarray(extra_points[0], dtype=np.int64)),
                       kernel_input(np.asarray(extra_points[1], dtype=float)))
        self._sizes = (len(pt_sel), len(lk_sel), len(var_sel), machine.groups.shape[0],
                       self._extra[0].shape[0])
        self._live: tuple | None = None  # (batch, buffers, result) of the last batch shape
        self.extra_motion: tuple[np.ndarray, ...] = ()

    @property
    def n_phi(self) -> int:
        return self.phi.shape[0]

    @property
    def any_failed(self) -> bool:
        """Whether the last call had positions that could not be assembled."""
        return self._dirty

    def kernel_arrays(self) -> dict[str, np.ndarray]:
        """The last call's arrays as the kernels use them, (n_design, n_phi, ...): P, V, A of
        the selected points, TH, OM, EP of the links, S, SD, SDD of the variables, GP, GV, GA
        of the extra points, and feasible."""
        if self._live is None:
            raise RuntimeError("the plan has not been run yet")
        return self._live[1][3]

    def designs(self, params, inputs=None) -> np.ndarray:
        """The parameter vectors a call evaluates, batch + (n_parameters,), checked."""
        machine = self.machine
        if params is None and not inputs:
            return machine.defaults
        if params is None:
            return machine.parameters(inputs=inputs)
        P0 = np.asarray(params, dtype=float)
        if P0.shape[-1:] != machine.defaults.shape:
            raise ValueError(f"params must have shape batch + ({machine.defaults.size},),"
                             f" got {P0.shape}")
        if inputs:
            extra = machine.parameters(inputs=inputs)
            P0 = np.broadcast_to(P0, np.broadcast_shapes(P0.shape, extra.shape)).copy()
            for name in inputs:
                i = machine.parameter_index(f"input.{name}")
                P0[..., i] = extra[..., i]
        return P0

    def _buffers(self, batch: tuple[int, ...], keep: bool = True):
        """Output arrays and the result that views them, for a batch shape (kept for reuse
        unless ``keep`` is False)."""
        if keep and self._live is not None and self._live[0] == batch:
            return self._live[1], self._live[2]
        n_design = int(np.prod(batch, dtype=np.int64))
        n_phi = self.n_phi
        n_pt, n_l, n_v, n_g, n_ex = self._sizes
        need = 8 * n_design * n_phi * (6 * n_pt + 3 * n_l + 3 * n_v + 6 * n_ex + 2 * n_g + 5)
        have = _memory_bytes()
        if need > 0.8 * have:
            raise OptionError("params", f"the outputs of {n_design} designs at {n_phi} angles"
                              f" need {need / 2**30:.1f} GiB, more than this computer's"
                              f" {have / 2**30:.1f} GiB of memory allow",
                              "Evaluate the designs in chunks, or select fewer points, links"
                              " and variables")
        P, V, A = (np.empty((n_design, n_phi, n_pt, 2)) for _ in range(3))
        TH, OM, EP = (np.empty((n_design, n_phi, n_l)) for _ in range(3))
        S, SD, SDD = (np.empty((n_design, n_phi, n_v)) for _ in range(3))
        fail_unit = np.empty((n_design, n_phi), dtype=np.int64)
        fail_code = np.empty((n_design, n_phi), dtype=np.int64)
        loop_res = np.empty((n_design, n_phi, n_g))
        loop_worst = np.zeros((n_design, n_phi, n_g), dtype=np.int64)
        feasible = np.empty((n_design, n_phi), dtype=bool)
        failure_unit = np.empty((n_design, n_phi), dtype=np.int64)
        extra = tuple(np.empty((n_design, n_phi, n_ex, 2)) for _ in range(3))
        out = (P, V, A, TH, OM, EP, S, SD, SDD, fail_unit, fail_code, loop_res, loop_worst,
               *self._extra, *extra)
        m = self.machine

        def shape(x, tail=()):
            return x.reshape(batch + (n_phi,) + tail)

        result = KinematicsResult(
            machine=m.name, phi=self.phi, omega_shaft=self.omega, epsilon_shaft=self.epsilon,
            point_names=self._pt_names, link_names=self._lk_names,
            variable_names=self._var_names, variable_units=self._var_units,
            unit_names=m.unit_names,
            p=shape(P, (n_pt, 2)), v=shape(V, (n_pt, 2)), a=shape(A, (n_pt, 2)),
            theta=shape(TH, (n_l,)), omega=shape(OM, (n_l,)), epsilon=shape(EP, (n_l,)),
            q=shape(S, (n_v,)), q_dot=shape(SD, (n_v,)), q_ddot=shape(SDD, (n_v,)),
            feasible=shape(feasible), failure_unit=shape(failure_unit),
            loop_residual=shape(loop_res, (n_g,)), branches=dict(m.branches),
            failure_code=shape(fail_code))
        named = dict(zip(("P", "V", "A", "TH", "OM", "EP", "S", "SD", "SDD"), out[:9]),
                     GP=extra[0], GV=extra[1], GA=extra[2], feasible=feasible)
        buffers = (out, feasible, failure_unit, named)
        if keep:
            self.extra_motion = tuple(x.reshape(batch + (n_phi, n_ex, 2)) for x in extra)
            self._live = (batch, buffers, result)
            self._dirty = True  # feasible and failure_unit are not filled yet
        return buffers, result

    def __call__(self, params: ArrayLike | None = None, *,
                 inputs: Mapping[str, ArrayLike] | None = None) -> KinematicsResult:
        """Evaluate designs (see :func:`kinematics` for ``params`` and ``inputs``).

        The returned result views the plan's arrays: the next call with the same batch shape
        overwrites it.
        """
        return self.run(self.designs(params, inputs))

    def run(self, P0: np.ndarray, *, fresh: bool = False) -> KinematicsResult:
        """Evaluate the designs ``P0`` (batch + (n_parameters,)) from :meth:`designs`.
        ``fresh``: into new arrays, which no later call overwrites (what :func:`kinematics`
        returns)."""
        batch = P0.shape[:-1]
        flat = kernel_params(P0)
        (out, feasible, failure_unit, _), result = self._buffers(batch, keep=not fresh)
        if fresh:
            self._dirty = True  # the new arrays are not filled yet
        loop_res = out[11]
        if loop_res.size:
            loop_res.fill(np.nan)  # NaN where a loop unit was not solved
        n_design = flat.shape[0]
        args = self._head + (flat,) + self._tail + out
        if n_design >= 4 and n_design * self._n_march >= _PARALLEL_MIN_WORK:
            # threads pay some tens of microseconds to start; worth it for big batches
            n_failed = run_chunks(K.evaluate_program, n_design, args)
        else:
            n_failed = K.evaluate_program(0, n_design, *args)
        if not n_failed:
            if self._dirty:  # the last call's failures are still marked
                feasible.fill(True)
                failure_unit.fill(-1)
                self._dirty = False
            return result
        self._dirty = True
        fail_unit, fail_code = out[9], out[10]
        np.less(fail_unit, 0, out=feasible)
        machine = self.machine
        # fail_unit holds rows of the evaluated program (a parameter's index for FAIL_PARAM):
        # back to the machine's rows, then to units
        bad_param = fail_code == K.FAIL_PARAM
        row = np.where((fail_unit >= 0) & ~bad_param,
                       self._rows[np.clip(fail_unit, 0, max(len(self._rows) - 1, 0))], -1)
        if self.on_failure == "raise":
            _raise_first(machine, self.phi, self._store, batch, row, fail_unit, fail_code,
                         loop_res, out[12], flat)
        failure_unit[...] = machine.unit_of_row[row]  # fixed points belong to no unit: -1
        if bad_param.any():
            owner = np.asarray(machine.parameter_owner + (-1,), dtype=np.int64)
            failure_unit[bad_param] = owner[fail_unit[bad_param]]
        return result


def kinematics(
    machine: Machine,
    phi: ArrayLike,
    *,
    params: ArrayLike | None = None,
    inputs: Mapping[str, ArrayLike] | None = None,
    rpm: float | None = None,
    omega: ArrayLike | None = None,
    epsilon: ArrayLike = 0.0,
    on_failure: Literal["raise", "mask"] = "raise",
    points: Sequence[str] | None = None,
    links: Sequence[str] | None = None,
    variables: Sequence[str] | None = None,
    max_step_deg: float = 5.0,
    tol: float = 1e-10,
    max_iter: int = 25,
) -> KinematicsResult:
    """Positions, velocities and accelerations of every point, link and joint variable.

    Parameters
    ----------
    machine : Machine
        A compiled machine (:func:`sewmech.load_machine`).
    phi : array_like, shape (n_phi,)
        Upper-shaft angles, rad, in the machine's angle convention.
    params : array_like, shape batch + (n_parameters,), optional
        Parameter vectors of a batch of designs (:meth:`Machine.parameters`); default: the file.
    inputs : mapping name -> array_like, optional
        Setting inputs (e.g. ``{"regulator": 0.1}``), rad; broadcast against ``params``' batch.
    rpm : float, optional
        Constant shaft speed, rev/min (default: the machine file's ``[speed] rpm``).
    omega : array_like, shape () or (n_phi,), optional
        Shaft angular velocity, rad/s, constant or prescribed per angle omega(phi); overrides rpm.
    epsilon : array_like, shape () or (n_phi,)
        Shaft angular acceleration, rad/s^2, per angle (default 0: constant speed).
    on_failure : {"raise", "mask"}
        "raise": an :class:`AssemblyError` names the unit and the crank angle of the first
        failure. "mask": return with ``feasible`` False (and NaN values) where it failed.
    points, links, variables : sequence of str, optional
        Return only these (default: all). Only the units these outputs depend on are solved, so
        large sweeps that need a few channels save the memory and time of the rest.
    max_step_deg : float
        Largest continuation step of the loop solver, degrees.
    tol : float
        Loop-closure tolerance of the Newton iteration, mm (max-norm of the residual).
    max_iter : int
        Newton iterations per continuation step (four times as many at assembly).

    Returns
    -------
    KinematicsResult

    See Also
    --------
    KinematicsPlan : the same call prepared once, for loops over many designs.
    """
    # the plan of a call like an earlier one is kept with the machine (its checks, march and
    # selection are done once); each call still returns arrays of its own
    phi_arr = np.asarray(phi, dtype=float)
    key = (phi_arr.shape, phi_arr.tobytes(), rpm, _key(omega), _key(epsilon), on_failure,
           _key(points), _key(links), _key(variables), max_step_deg, tol, max_iter)
    plans = machine._plans
    plan = plans.pop(key, None)
    if plan is None:
        plan = KinematicsPlan(machine, phi_arr, rpm=rpm, omega=omega, epsilon=epsilon,
                              on_failure=on_failure, points=points, links=links,
                              variables=variables, max_step_deg=max_step_deg, tol=tol,
                              max_iter=max_iter)
        while len(plans) >= _KEEP_PLANS:
            plans.pop(next(iter(plans)))
    plans[key] = plan
    return plan.run(plan.designs(params, inputs), fresh=True)


#: one-off calls whose plans each machine keeps
_KEEP_PLANS = 16


def _key(x):
    """A hashable stand-in for an argument of kinematics()."""
    if x is None or isinstance(x, (int, float, str)):
        return x
    if isinstance(x, (list, tuple)) and all(isinstance(v, str) for v in x):
        return tuple(x)  # names (points, links, variables): as np.ndim would, 20 times faster
    if isinstance(x, np.ndarray) or np.ndim(x):
        a = np.asarray(x)
        return (a.shape, a.dtype.str, a.tobytes()) if a.dtype != object else tuple(a.tolist())
    return ("scalar", float(x)) if np.isscalar(x) else tuple(x)


def _raise_first(machine, phi, store, batch, row, fail_unit, fail_code, loop_res, loop_worst,
                 params):
    """Raise the error of the first failure in march order (later ones may be "lost")."""
    order = store[store >= 0]
    phi_deg = np.degrees(phi)
    for d in range(fail_code.shape[0]):
        failed = order[fail_code[d, order] != K.FAIL_NONE]
        if not failed.size:
            continue
        i = int(failed[0])
        code = int(fail_code[d, i])
        design = tuple(int(x) for x in np.unravel_index(d, batch)) if batch else ()
        if code == K.FAIL_PARAM:
            j = int(fail_unit[d, i])
            raise _parameter_error(machine, j, design, float(params[d, j]))
        r = int(row[d, i])
        ui = machine.kernel_unit_of_row[r]
        unit = machine.unit_names[ui] if ui >= 0 else "?"
        reason, hint = _REASONS[code]
        # the evaluated angles (in increasing order) at which this unit fails for this design
        same = np.zeros(phi.shape[0], dtype=bool)
        same[order] = (row[d, order] == r) & (fail_code[d, order] != K.FAIL_NONE)
        ranges = angle_ranges(phi_deg, same)
        if code == K.FAIL_ASSEMBLY:
            def at_failure(c, x=float(phi[i]), p=params[d]):
                r = kinematics(machine, np.array([x]), params=p, points=c.points,
                               links=c.links, variables=(), omega=1.0, on_failure="mask")
                return r if r.all_feasible else None

            why = describe(machine, ui, params[d], at_failure)
            if why:
                reason = f"cannot be assembled: {why}"
        if code in (K.FAIL_ASSEMBLY, K.FAIL_SINGULAR):
            hint = _branch_hint(machine, ui, hint, phi, params[d])
        if code in (K.FAIL_NEWTON, K.FAIL_SINGULAR) and machine.unit_types[ui] == "loop":
            g = int(machine.program[r, 1])
            spec = machine.spec.units[ui]
            loop = spec.loops[int(loop_worst[d, i, g])].name
            res = loop_res[d, i, g]
            reason = (f"{reason} in loop '{loop}' (residual {res:.3g} mm)"
                      if code == K.FAIL_NEWTON else
                      f"{reason} (loop Jacobian singular near loop '{loop}')")
            raise ConvergenceError(unit, float(phi_deg[i]), design, reason, hint,
                                   file=machine.file, ranges_deg=ranges)
        raise AssemblyError(unit, float(phi_deg[i]), design, reason, hint, file=machine.file,
                            ranges_deg=ranges)


def angle_ranges(phi_deg: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """Ranges (first, last angle, deg) of the masked angles, consecutive in increasing order."""
    order = np.argsort(phi_deg, kind="stable")
    return [(round(float(phi_deg[order[a]]), 6), round(float(phi_deg[order[b]]), 6))
            for a, b in mask_runs(mask[order])]


def check_design(machine: Machine, params: ArrayLike) -> None:
    """A :class:`ParameterError` for the first parameter of the first design (params: batch +
    (n_parameters,)) outside its domain (``Machine.parameter_lo``/``parameter_hi``)."""
    P = np.asarray(params, dtype=float)
    bad = ~((P >= machine.parameter_lo) & (P <= machine.parameter_hi))
    if bad.any():
        flat = bad.reshape(-1, bad.shape[-1])
        d = int(np.flatnonzero(flat.any(axis=1))[0])
        j = int(np.flatnonzero(flat[d])[0])
        design = tuple(int(x) for x in np.unravel_index(d, P.shape[:-1])) if P.ndim > 1 else ()
        raise _parameter_error(machine, j, design, float(P.reshape(-1, P.shape[-1])[d, j]))


def _parameter_error(machine: Machine, j: int, design: tuple, value: float) -> ParameterError:
    """A parameter outside its domain, located in the machine file where it comes from."""
    name = machine.parameter_names[j]
    msg, hint = domain_message(name, value, machine.parameter_units[j],
                               float(machine.parameter_lo[j]), float(machine.parameter_hi[j]))
    src = machine.parameter_sources[j] if machine.parameter_sources else None
    if src is not None and not name.startswith("input."):
        table, key = parameter_location(machine.spec, src)
        hint += f" (the parameter of {machine.file}: [{table}] {key})"
    return ParameterError(name, design, value, msg, hint)


def _branch_hint(machine: Machine, ui: int, hint: str, phi: np.ndarray,
                 params: np.ndarray) -> str:
    """Name the closed-form units upstream of unit ``ui`` whose assembly branch decides where
    its inputs are; if flipping one of them makes this design assemble at every angle asked
    for, say so."""
    up = [k for k in machine.upstream_units(ui) if machine.unit_names[k] in machine.branches]
    if not up:
        return hint
    for k in up:  # try the other branch of each (a few compiled calls, only on failure)
        raw = machine.spec.model_dump()
        raw["units"][k]["branch"] = -raw["units"][k]["branch"]
        try:
            other = compile_machine(MachineSpec.model_validate(raw), machine.file)
            ok = kinematics(other, phi, params=params, on_failure="mask").all_feasible
        except (SewmechError, ValueError):
            ok = False
        if ok:
            name = machine.unit_names[k]
            return (f"{hint}. With branch = {-machine.branches[name]:+d} in unit '{name}' (its"
                    " other assembly) the machine assembles at every angle asked for")
    listed = ", ".join(f"'{n}' (branch {machine.branches[n]:+d})"
                       for n in (machine.unit_names[k] for k in up))
    return (f"{hint}. Its inputs depend on the branch of {listed}; the other branch of each"
            " does not help either")
