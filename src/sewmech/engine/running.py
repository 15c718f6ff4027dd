"""The machine run in time: start-up from rest, the steady state, the stop (issue 31).

A machine is one degree of freedom, the upper shaft's angle phi. Its equation of motion is the
inverse dynamics read the other way round: the torque the machine asks at the shaft,

    tau(phi, w, e) = J(phi) e + J'(phi) w^2 / 2 + N(phi, w, e),

(J the reduced inertia, w the shaft's speed, e its acceleration; N everything else: weights,
springs, process loads, friction, dampers), equals what the motor puts on it through the belt
less what the motor's rotor and the hand wheel take:

    (J + J_hw + i^2 J_rotor) e + J' w^2 / 2 + N(phi, w, e) = i T_motor(i w).

:func:`run` integrates it in time with a :class:`~sewmech.engine.motor.Motor`.

**The tables.** The right-hand side must be cheap, and the force analysis is not (with friction
about 50 us a position for JB1-3), so it is tabulated once (:func:`run_tables`): J and J' exactly
from the kinematics on a fine grid (``fine`` times the force grid), and N from the whole force
analysis (:class:`~sewmech.dynamics.DynamicsPlan`, friction, springs, loads and all) on a grid of
shaft angles (``step_deg``) at a few speeds and accelerations. N's speed dependence is
interpolated by a monotone cubic over speeds from rest to ``w_top`` (exact where N is linear in
w: a machine without friction, whose dampers and viscous friction give b w; the weights,
springs and loads' part does not change with speed). Only Coulomb friction makes N depend on
the acceleration (its pair forces carry the inertia forces); that part is tabulated at four
accelerations (+-E, +-E/4) and four speeds and interpolated linearly (at rest it is 0: the
smooth sign of friction vanishes with the sliding speed). docs/running.md says how well this
reproduces the force analysis (tests/test_running.py measures it along the run).

**The integration.** Dormand-Prince 5(4) with error control (compiled, ``_running``), stepping at
most ``max_dphi`` of shaft angle, with events located on the steps: each full turn, the clutch
taking hold and slipping, a stall, the stop. The run starts at rest at ``phi0`` (default the
convention's reference angle, e.g. the needle at its top), runs until the turn's mean speed
stays (two successive turns within ``steady_tol``; or for ``run_time`` s), takes the last full
turn as the steady state, and then stops at the same angle: the motor switched off (table,
induction), its command 0 (servo), or declutched and braked (clutch), until the shaft is below
1 % of the working speed.

**The speed fluctuation** of the steady turn, delta_run = (w_max - w_min) / w_mean, is compared
with the energy method's (:func:`sewmech.dynamics.speed_fluctuation` at the run's mean speed,
with the hand wheel and the motor's rotor as its flywheel): they agree when the fluctuation is
small and the motor's torque does not change within the turn; a motor whose torque falls
steeply with speed (an induction motor's slip region, a servo) damps the fluctuation, and the
run then says by how much.

Units inside: mm, kg, s, N, rad; torques N mm, inertias kg mm^2, powers N mm/s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from . import _running as RK
from .errors import AnalysisError, MachineFileError, OptionError
from .kinematics import check_speed, rpm_to_rad_s
from .machine import Machine
from .motor import Motor, motor_from_spec
from .spec import LoadSpec

#: the force analysis' speeds for the tables, as fractions of w_top (the first: nearly at rest,
#: the limit of the smooth signs and the rates' signs from above)
SPEED_FRACTIONS = (1e-6, 0.0025, 0.0075, 0.025, 0.075, 0.2, 0.35, 0.5, 0.65, 0.8, 1.0)
#: the speeds (indices into SPEED_FRACTIONS) at which friction's acceleration part is tabulated
ACCEL_SPEEDS = (3, 5, 7, 10)
#: its accelerations, as fractions of E
ACCEL_FRACTIONS = (-1.0, -0.25, 0.25, 1.0)
#: the run is stopped when the shaft is below this fraction of the working speed
STOP_FRACTION = 0.01
#: samples of the steady turn (shaft angle), for its fluctuation and the figure
STEADY_SAMPLES = 720
#: the integration's relative tolerance
RTOL = 1e-10


@dataclass(frozen=True)
class RunTables:
    """What the run's right-hand side interpolates (see the module doc), for one design at one
    setting. Arrays: ``J``, ``dJ``, ``d2J`` (fine grid of ``n_fine`` angles from 0, kg mm^2 and
    its derivatives per rad), ``speeds`` (rad/s), ``N0`` (n_speeds, n_phi, N mm: N at e = 0),
    ``N0_w`` (its slopes in w), ``accel_speeds`` (rad/s, from 0), ``accelerations`` (rad/s^2,
    with 0), ``dN_e`` (n_accel_speeds, n_accelerations, n_phi: friction's part that comes with
    e, N mm). ``friction``: whether the machine has Coulomb friction (else N does not depend on
    e and the acceleration axis is just 0)."""

    machine: Machine = field(repr=False)
    step_deg: float
    w_top: float
    e_max: float
    friction: bool
    J: np.ndarray = field(repr=False)
    dJ: np.ndarray = field(repr=False)
    d2J: np.ndarray = field(repr=False)
    speeds: np.ndarray = field(repr=False)
    N0: np.ndarray = field(repr=False)
    N0_w: np.ndarray = field(repr=False)
    accel_speeds: np.ndarray = field(repr=False)
    accelerations: np.ndarray = field(repr=False)
    dN_e: np.ndarray = field(repr=False)
    positions: int = 0  # positions of the force analysis the tables took

    @property
    def arrays(self) -> tuple:
        """The kernels' table arguments: JG, DJG, D2JG, WN, N0, N0W, WM, EA, DT."""
        return (self.J, self.dJ, self.d2J, self.speeds, self.N0, self.N0_w, self.accel_speeds,
                self.accelerations, self.dN_e)

    def demand(self, phi: ArrayLike, omega: ArrayLike, epsilon: ArrayLike) -> np.ndarray:
        """The tables' torque at the shaft (N mm) in states (phi rad, omega rad/s, epsilon
        rad/s^2): J e + J' w^2 / 2 + N(phi, w, e), what the force analysis' ``input_torque``
        gives in the same state."""
        phi, omega, epsilon = np.broadcast_arrays(*(np.asarray(x, dtype=float).ravel()
                                                    for x in (phi, omega, epsilon)))
        out = np.empty(phi.shape[0])
        RK.demand(np.ascontiguousarray(phi), np.ascontiguousarray(omega),
                  np.ascontiguousarray(epsilon), *self.arrays, out)
        return out

    def inertia(self, phi: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """J(phi) (kg mm^2) and J'(phi) (kg mm^2/rad) as the run interpolates them."""
        phi = np.asarray(phi, dtype=float).ravel()
        out = np.array([RK.inertia_at(float(p), self.J, self.dJ, self.d2J) for p in phi])
        return out[:, 0], out[:, 1]


def has_coulomb_friction(machine: Machine) -> bool:
    """Whether any pair of the machine has Coulomb friction (a coefficient above 0)."""
    fr = machine.spec.friction
    if fr is None:
        return False
    return fr.coefficient > 0.0 or any((p.coefficient or 0.0) > 0.0 for p in fr.pairs.values())


def _pchip_slopes(x: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Fritsch and Carlson's slopes of the monotone cubic through (x, Y[k]) along axis 0 (as
    scipy's PchipInterpolator); exact for data linear in x."""
    n = x.shape[0]
    D = np.zeros_like(Y)
    if n < 2:
        return D
    h = np.diff(x)[:, None]
    m = np.diff(Y, axis=0) / h
    if n == 2:
        D[0] = D[1] = m[0]
        return D
    w1 = 2 * h[1:] + h[:-1]
    w2 = h[1:] + 2 * h[:-1]
    same = (np.sign(m[:-1]) == np.sign(m[1:])) & (m[:-1] != 0) & (m[1:] != 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        inner = (w1 + w2) / (w1 / m[:-1] + w2 / m[1:])
    D[1:-1] = np.where(same, inner, 0.0)

    def end(h0, h1, m0, m1):
        d = ((2 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
        d = np.where(np.sign(d) != np.sign(m0), 0.0, d)
        return np.where((np.sign(m0) != np.sign(m1)) & (np.abs(d) > 3 * np.abs(m0)), 3 * m0, d)

    D[0] = end(h[0], h[1], m[0], m[1])
    D[-1] = end(h[-1], h[-2], m[-1], m[-2])
    return D


def run_tables(machine: Machine, *, w_top: float, e_max: float | None = None,
               inputs: Mapping[str, ArrayLike] | None = None,
               loads: Sequence[LoadSpec] | None = None, gravity: bool = True,
               step_deg: float = 1.0, fine: int = 4, e_scale=None) -> RunTables:
    """The tables of the run for speeds up to ``w_top`` (rad/s) and accelerations up to
    ``e_max`` (rad/s^2; default from ``e_scale(N0_max, dJ_max, J_min)``, a function giving it
    from the tables at rest), on a grid of ``step_deg`` (which must divide 360) and J on one
    ``fine`` times finer. ``inputs``, ``loads`` and ``gravity`` as for the force analysis."""
    from .dynamics import DynamicsPlan

    n = int(round(360.0 / step_deg))
    if not (0.05 <= step_deg <= 10.0 and math.isclose(n * step_deg, 360.0, rel_tol=1e-9)):
        raise OptionError("step_deg", f"must divide 360 and be in 0.05 .. 10 deg, got"
                          f" {step_deg!r}", "Give e.g. 1 or 0.5")
    n_fine = n * int(fine)
    phi_fine = np.linspace(0.0, 2 * math.pi, n_fine, endpoint=False)
    unit = DynamicsPlan(machine, phi_fine, omega=1.0, epsilon=0.0, gravity=False, loads=[],
                        friction=False)(inputs=inputs)
    J = np.array(unit.reduced_inertia, dtype=float)  # kg mm^2
    dJ = 2e3 * np.array(unit.kinetic_energy_rate, dtype=float)  # d(2T)/dphi at w = 1: J'
    if not (J > 0).all():
        raise AnalysisError(machine.file, "the reduced inertia J(phi) is zero somewhere (no"
                            " [masses], or none that the shaft moves there): the machine's"
                            " motion in time cannot be computed", "Add [masses.LINK] tables"
                            " (docs/machine-files.md)")
    h_fine = 2 * math.pi / n_fine
    d2J = (np.roll(dJ, -1) - np.roll(dJ, 1)) / (2 * h_fine)
    phi = phi_fine[::fine]
    Jc, dJc = J[::fine], dJ[::fine]
    speeds = w_top * np.asarray(SPEED_FRACTIONS)
    friction = has_coulomb_friction(machine)

    def torques(ws, es):
        ws, es = np.asarray(ws, float), np.asarray(es, float)
        plan = DynamicsPlan(machine, np.tile(phi, ws.size), omega=np.repeat(ws, n),
                            epsilon=np.repeat(es, n), gravity=gravity, loads=loads)
        tau = np.array(plan(inputs=inputs).input_torque).reshape(ws.size, n)
        return tau - 1e-3 * (Jc * es[:, None] + 0.5 * dJc * ws[:, None] ** 2)

    N0 = torques(speeds, np.zeros_like(speeds))
    positions = N0.size
    if e_max is None:
        e_max = e_scale(float(np.abs(N0).max()), float(np.abs(dJ).max()), float(J.min()))
    if friction:
        idx = list(ACCEL_SPEEDS)
        es = e_max * np.asarray(ACCEL_FRACTIONS)
        ws = speeds[idx]
        N = torques(np.repeat(ws, es.size), np.tile(es, ws.size)).reshape(len(idx), es.size, n)
        positions += N.size
        k0 = int(np.searchsorted(es, 0.0))
        accelerations = np.insert(es, k0, 0.0)
        dN = np.zeros((len(idx) + 1, accelerations.size, n))  # row 0: at rest, 0
        dN[1:, :k0] = N[:, :k0] - N0[idx, None]
        dN[1:, k0 + 1:] = N[:, k0:] - N0[idx, None]
        accel_speeds = np.concatenate([[0.0], ws])
    else:
        accelerations, accel_speeds, dN = np.zeros(1), np.zeros(1), np.zeros((1, 1, n))
    out = RunTables(machine, float(step_deg), float(w_top), float(e_max), friction,
                    *(np.ascontiguousarray(a, dtype=float) for a in (
                        J, dJ, d2J, speeds, N0, _pchip_slopes(speeds, N0), accel_speeds,
                        accelerations, dN)), positions=positions)
    for a in out.arrays:
        a.setflags(write=False)
    return out


# ---- the motor in the kernel ----------------------------------------------------------------------


def servo_gains(motor: Motor, machine_inertia: float) -> tuple[float, float, float]:
    """(k_p N mm s, k_i N mm, tracking time s) of a servo motor's PI speed loop for the
    machine's mean inertia at the shaft (kg mm^2; see :mod:`sewmech.engine.motor`)."""
    i = motor.belt_ratio
    wb = 2 * math.pi * motor.bandwidth_hz
    jm = motor.rotor_inertia + (machine_inertia + motor.hand_wheel_inertia) / (i * i)
    kp = 1e-3 * wb * jm
    ki = kp * wb / 4.0
    return kp, ki, kp / ki


def _motor_params(motor: Motor, w_target: float, machine_inertia: float) -> tuple:
    """The kernel's motor arguments (MP, TW, TT)."""
    i = motor.belt_ratio
    MP = np.zeros(15)
    MP[0] = motor.code
    MP[1] = i
    MP[2] = motor.hand_wheel_inertia
    MP[3] = motor.rotor_inertia
    if motor.kind in ("induction", "clutch"):
        MP[4], MP[5], MP[6] = motor.synchronous_speed, motor.breakdown_slip, motor.breakdown_torque
    if motor.kind == "clutch":
        MP[7], MP[8] = motor.clutch_torque, motor.brake_torque
    if motor.kind == "servo":
        kp, ki, tt = servo_gains(motor, machine_inertia)
        MP[9], MP[10], MP[11], MP[12], MP[13] = motor.max_torque, kp, ki, i * w_target, tt
    MP[14] = 1e-3 * w_target  # the brake's smooth sign
    if motor.kind == "table":
        TW, TT = np.array(motor.table_speed), np.array(motor.table_torque)
    else:
        TW, TT = np.zeros(2), np.zeros(2)
    return MP, np.ascontiguousarray(TW), np.ascontiguousarray(TT)


# ---- the result ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SteadyRun:
    """The steady state: the last full turn of the run before the stop.

    Attributes
    ----------
    t_start, t_end : s, the turn's beginning and end
    mean_speed : rad/s, the mean over the turn's shaft angle (as the energy method's)
    phi : rad, (STEADY_SAMPLES,) the turn's angles from its start
    omega : rad/s, the speed at them
    delta : (w_max - w_min) / w_mean over the turn
    settled : whether the turn's mean stayed within ``steady_tol`` of the one before (False: the
        run's time ran out first; ``change`` says how far it was)
    change : the relative change of the turn's duration from the turn before
    """

    t_start: float
    t_end: float
    mean_speed: float
    phi: np.ndarray = field(repr=False)
    omega: np.ndarray = field(repr=False)
    delta: float
    settled: bool
    change: float

    @property
    def mean_rpm(self) -> float:
        return self.mean_speed * 30.0 / math.pi


@dataclass(frozen=True)
class RunResult:
    """The machine run in time (see the module doc). Arrays over the samples ``time`` (s):

    Attributes
    ----------
    phi : rad, the shaft's angle (counted on over the turns)
    omega : rad/s, its speed; ``epsilon`` rad/s^2 its acceleration
    motor_speed : rad/s, the motor's (i omega while the belt and clutch hold)
    motor_torque : N mm, the motor's torque on its own shaft (a clutch motor: its motor's)
    belt_torque : N mm, the torque the belt puts on the machine's shaft
    demand : N mm, the machine's torque at the shaft as the tables give it (J e + J' w^2 / 2
        + N), the hand wheel and the motor not included
    phase : 0 start-up and steady running, 1 the stop
    time_to_speed : s, when the shaft first reaches the working speed (None: never)
    steady : SteadyRun
    stop_start, time_to_stop : s, when the stop begins and how long it takes (None: it did not
        end within the run's time: nothing takes the energy out)
    energy : the energy method's SpeedFluctuation at the steady mean speed
    events : (time s, what) of the clutch taking hold or slipping
    """

    machine: Machine = field(repr=False)
    motor: Motor = field(repr=False)
    rpm: float
    phi0: float
    time: np.ndarray = field(repr=False)
    phi: np.ndarray = field(repr=False)
    omega: np.ndarray = field(repr=False)
    epsilon: np.ndarray = field(repr=False)
    motor_speed: np.ndarray = field(repr=False)
    motor_torque: np.ndarray = field(repr=False)
    belt_torque: np.ndarray = field(repr=False)
    demand: np.ndarray = field(repr=False)
    phase: np.ndarray = field(repr=False)
    time_to_speed: float | None
    steady: SteadyRun
    stop_start: float
    time_to_stop: float | None
    energy: object = field(repr=False)
    tables: RunTables = field(repr=False)
    events: tuple = ()
    steps: int = 0
    segments: tuple = field(default=(), repr=False)

    @property
    def motor_power(self) -> np.ndarray:
        """The motor's power on its shaft, N mm/s (mW)."""
        return self.motor_torque * self.motor_speed

    @property
    def rpm_curve(self) -> np.ndarray:
        return self.omega * 30.0 / math.pi

    @property
    def delta_run(self) -> float:
        return self.steady.delta

    @property
    def delta_energy(self) -> float:
        return float(self.energy.delta)

    def state_at(self, t: ArrayLike) -> np.ndarray:
        """The state (phi, omega, servo integral, motor speed) at times ``t`` (s) from the
        integration's steps (cubic Hermite between them: the steps' own accuracy)."""
        return _dense(self.segments, np.asarray(t, dtype=float))[0]


def _dense(segments, t: np.ndarray):
    """States at times t from the stored segments: (Y (n, 4), mode (n,), sign (n,))."""
    t = np.atleast_1d(t)
    Y = np.empty((t.size, 4))
    modes = np.empty(t.size, dtype=np.int64)
    signs = np.empty(t.size)
    starts = np.array([s[0][0] for s in segments])
    which = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(segments) - 1)
    for j in np.unique(which):
        T, Yj, F, mode, sign = segments[j]
        sel = which == j
        tt = np.clip(t[sel], T[0], T[-1])
        k = np.clip(np.searchsorted(T, tt, side="right") - 1, 0, len(T) - 2) if len(T) > 1 \
            else np.zeros(tt.size, dtype=np.int64)
        if len(T) == 1:
            Y[sel] = Yj[0]
        else:
            h = (T[k + 1] - T[k])[:, None]
            f = ((tt - T[k]) / h[:, 0])[:, None]
            f2, f3 = f * f, f * f * f
            Y[sel] = ((2 * f3 - 3 * f2 + 1) * Yj[k] + (f3 - 2 * f2 + f) * h * F[k]
                      + (-2 * f3 + 3 * f2) * Yj[k + 1] + (f3 - f2) * h * F[k + 1])
        modes[sel] = mode
        signs[sel] = sign
    return Y, modes, signs


# ---- the run ------------------------------------------------------------------------------------


def machine_motor(machine: Machine) -> Motor:
    """The machine file's ``[motor]``, or a located error if it has none."""
    if machine.spec.motor is None:
        raise MachineFileError(machine.file, "", "", "has no [motor] table: the run in time"
                               " needs the motor that drives the shaft", "Add one"
                               " (docs/running.md), or give a motor file (sewmech run --motor"
                               " FILE)")
    return motor_from_spec(machine.spec.motor, machine.file)


def _top_speed(motor: Motor, w_target: float) -> float:
    """The fastest shaft speed the tables should cover at first (rad/s)."""
    if motor.kind == "servo":
        return 1.3 * w_target
    free = motor.free_speed / motor.belt_ratio
    if not math.isfinite(free):
        return 2.0 * w_target
    return float(min(max(1.25 * w_target, 1.05 * free), 4.0 * w_target))


def run(machine: Machine, *, motor: Motor | None = None, rpm: float | None = None,
        inputs: Mapping[str, ArrayLike] | None = None, loads: Sequence[LoadSpec] | None = None,
        gravity: bool = True, phi0: float | None = None, run_time: float | None = None,
        stop: bool = True, max_time: float = 30.0, steady_tol: float = 1e-6,
        step_deg: float = 1.0, max_dphi: float | None = None, sample_dt: float | None = None,
        energy_method: bool = True, tables: RunTables | None = None) -> RunResult:
    """Start the machine from rest with its motor, run it to its steady state, and stop it.

    Parameters
    ----------
    machine : Machine
    motor : Motor, optional
        Default: the machine file's ``[motor]`` (:func:`machine_motor`).
    rpm : float, optional
        The working speed, rev/min (default the file's ``[speed]``): the speed whose reaching is
        timed, and a servo's command.
    inputs, loads, gravity
        As for :func:`sewmech.dynamics.inverse_dynamics` (the setting inputs, the process loads,
        the weights).
    phi0 : float, optional
        The shaft's angle at rest before the start, rad (default the convention's reference
        angle).
    run_time : float, optional
        Run the motor this long (s) instead of until the steady state.
    stop : bool
        Stop the machine after the steady state (default True).
    max_time : float
        The most time (s) the start-up and the steady state may take, and the stop.
    steady_tol : float
        The steady state: two successive turns whose durations differ by less than this
        fraction.
    step_deg : float
        The force analysis' grid of the tables, deg.
    max_dphi : float, optional
        The largest shaft angle a step may advance, rad (default two grid steps).
    sample_dt : float, optional
        The samples' spacing, s (default 1/72 of a turn at the working speed).
    energy_method : bool
        Also compute the energy method's speed fluctuation at the steady speed.
    tables : RunTables, optional
        Tables made before (:func:`run_tables`) for this machine and setting.

    Returns
    -------
    RunResult

    Raises
    ------
    MachineFileError
        ``[motor]`` (where the motor came from): the motor cannot start the machine, it stalls,
        or it cannot bring the machine to the working speed (said with the speed it reaches).
    """
    motor = machine_motor(machine) if motor is None else motor
    rpm = machine.rpm if rpm is None else check_speed("rpm", rpm)
    w_t = rpm_to_rad_s(rpm)
    for name, value, lo in (("max_time", max_time, 1e-6), ("steady_tol", steady_tol, 1e-14)):
        if not lo <= value <= 1e6:
            raise OptionError(name, f"must be in {lo:g} .. 1e6, got {value!r}")
    if run_time is not None and not 0.0 < run_time <= 1e6:
        raise OptionError("run_time", f"must be a time in s above 0, got {run_time!r}")
    if phi0 is None:
        phi0 = math.radians(machine.spec.convention.reference_phi_deg)
    phi0 = float(phi0) % (2 * math.pi)
    i = motor.belt_ratio
    turn = 2 * math.pi / w_t

    def scale_e(n_max, dj_max, j_min, w_top):
        a_min = 1e-3 * (j_min + motor.hand_wheel_inertia)  # a slipping clutch: the machine alone
        drive = i * motor.peak_torque
        return (drive + n_max + 0.5e-3 * dj_max * w_top ** 2) / a_min

    w_top = _top_speed(motor, w_t)
    for _attempt in range(4):
        if tables is None:
            tables = run_tables(machine, w_top=w_top, inputs=inputs, loads=loads,
                                gravity=gravity, step_deg=step_deg,
                                e_scale=lambda n, d, j, w=w_top: scale_e(n, d, j, w))
        res = _integrate(machine, motor, tables, w_t, phi0, run_time, stop, max_time,
                         steady_tol, max_dphi, turn)
        w_max = max(float(np.max(s[1][:, 1])) for s in res["segments"])
        e_max = res["e_max"]
        if w_max <= 1.02 * tables.w_top and (not tables.friction
                                             or e_max <= 1.05 * tables.e_max):
            break
        w_top = max(tables.w_top, 1.25 * w_max)  # the run left its tables: make them wider
        tables = None
    return _result(machine, motor, tables, res, rpm, phi0, sample_dt or turn / 72.0, inputs,
                   loads, gravity, energy_method)


def _integrate(machine, motor, tables, w_t, phi0, run_time, stop, max_time, steady_tol,
               max_dphi, turn) -> dict:
    """The run's segments from rest to the stop (see :func:`run`)."""
    i = motor.belt_ratio
    MP, TW, TT = _motor_params(motor, w_t, float(tables.J.mean()))
    arrays = tables.arrays
    ATOL = np.array([1e-10, 1e-10 * w_t, 1e-10 * max(i * motor.peak_torque, 1.0),
                     1e-10 * i * w_t])
    dphi = 2 * math.radians(tables.step_deg) if max_dphi is None else float(max_dphi)
    w_floor = 0.02 * w_t
    w_stop = STOP_FRACTION * w_t
    clutch = motor.kind == "clutch"
    mode = RK.SLIP if clutch else RK.RUN
    sign = 1.0
    y = np.array([phi0, 0.0, 0.0, motor.synchronous_speed if clutch else 0.0])
    where = (motor.where, "motor", "")
    # can it start? the acceleration at rest
    info = np.empty((1, 6))
    RK.evaluate(y[None, :], np.array([mode]), np.array([sign]), MP, TW, TT, *arrays, info)
    if not info[0, 0] > 0.0:
        raise MachineFileError(*where, f"the motor cannot start the machine at phi ="
                               f" {math.degrees(phi0):.4g} deg: it puts {info[0, 2]:.4g} N mm"
                               f" on the shaft, which asks {info[0, 3]:.4g} N mm there at rest",
                               "Give a motor with more starting torque or a larger belt ratio")
    cap = 20000
    T, Y, F = np.empty(cap), np.empty((cap, 4)), np.empty((cap, 4))
    segments, events, durations = [], [], []
    t, h = 0.0, 1e-4 * turn
    phi_end = phi0 + 2 * math.pi
    turn_start = 0.0
    time_to_speed = None
    steady_at = None  # (t_start, t_end, settled, change) of the steady turn
    stop_start = None
    time_to_stop = None
    e_seen = 0.0
    t_limit = max_time if run_time is None else run_time
    steps = 0
    while True:
        phase_stop = stop_start is not None
        t_end = (stop_start + max_time) if phase_stop else t_limit
        n, code, h = RK.segment(t, y, h, t_end, phi_end, mode, sign, w_stop, RTOL, ATOL, dphi,
                                w_floor, MP, TW, TT, *arrays, T, Y, F)
        steps += n - 1
        seg = (T[:n].copy(), Y[:n].copy(), F[:n].copy(), mode, sign)
        segments.append(seg)
        e_seen = max(e_seen, float(np.abs(seg[2][:, 1]).max()))
        if time_to_speed is None and not phase_stop:
            k = np.flatnonzero(seg[1][:, 1] >= w_t)
            if k.size:
                time_to_speed = _crossing(seg, int(k[0]), w_t)
        t, y = float(T[n - 1]), Y[n - 1].copy()
        if code == RK.FULL:
            continue
        if code == RK.TINY_STEP:
            raise AnalysisError(machine.file, f"the run's integration could not go on at t ="
                                f" {t:.6g} s (phi = {math.degrees(y[0]):.6g} deg, {y[1] * 30 / math.pi:.6g}"
                                " rpm): its step fell below what floating point resolves",
                                "Report it with the machine file; a coarser step_deg may help")
        if code == RK.STALLED:
            best = max(float(s[1][:, 1].max()) for s in segments)
            raise MachineFileError(*where, f"the motor stalls: the shaft comes to rest at phi ="
                                   f" {math.degrees(y[0]) % 360:.4g} deg after {t:.4g} s, having"
                                   f" reached {best * 30 / math.pi:.4g} rpm (working speed"
                                   f" {w_t * 30 / math.pi:g} rpm)", "Give a stronger motor or a"
                                   " larger belt ratio")
        if code == RK.LOCKED:
            events.append((t, "the clutch takes hold"))
            mode = RK.RUN
            y[3] = i * y[1]
            continue
        if code == RK.SLIPS:
            info = np.empty((1, 6))
            RK.evaluate(y[None, :], np.array([mode]), np.array([sign]), MP, TW, TT, *arrays,
                        info)
            sign = 1.0 if info[0, 5] > 0 else -1.0
            events.append((t, "the clutch slips"))
            mode = RK.SLIP
            continue
        if code == RK.STOPPED:
            time_to_stop = t - stop_start
            break
        if phase_stop:  # AT_PHI while stopping: go on; AT_TIME: it did not stop in max_time
            if code == RK.AT_PHI:
                phi_end += 2 * math.pi
                continue
            break
        if code == RK.AT_PHI:
            durations.append(t - turn_start)
            turn_start = t
            phi_end += 2 * math.pi
            if run_time is not None or len(durations) < 3:
                continue
            d = durations
            change = max(abs(d[-1] - d[-2]) / d[-1], abs(d[-2] - d[-3]) / d[-2])
            if change > steady_tol:
                continue
            steady_at = (t - d[-1], t, True, change)
            if time_to_speed is None:
                break  # settled below the working speed (said by _result)
        else:  # AT_TIME: the run's time is out
            d = durations
            if not d:
                raise MachineFileError(*where, f"the machine does not complete a turn in"
                                       f" {t_limit:g} s (it reaches"
                                       f" {y[1] * 30 / math.pi:.4g} rpm)", "Give a stronger"
                                       " motor, a larger belt ratio or a longer time")
            change = abs(d[-1] - d[-2]) / d[-1] if len(d) >= 2 else math.inf
            steady_at = (turn_start - d[-1], turn_start, run_time is not None, change)
        # the steady turn is found: the stop begins (at the start's angle after a settled turn)
        if not stop:
            break
        stop_start = t
        mode = RK.FREE if clutch else RK.STOP
        if clutch:
            events.append((t, "the clutch lets go and the brake acts"))
    return dict(segments=segments, events=events, durations=durations,
                time_to_speed=time_to_speed, steady_at=steady_at, stop_start=stop_start,
                time_to_stop=time_to_stop, e_max=e_seen, steps=steps, MP=(MP, TW, TT),
                where=where, w_t=w_t)


def _crossing(seg, k: int, w: float) -> float:
    """The time the speed crosses w upwards just before row k of a segment (k > 0)."""
    T, Y, F = seg[0], seg[1], seg[2]
    if k == 0:
        return float(T[0])
    lo, hi = 0.0, 1.0
    h = T[k] - T[k - 1]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        f2, f3 = mid * mid, mid ** 3
        v = ((2 * f3 - 3 * f2 + 1) * Y[k - 1, 1] + (f3 - 2 * f2 + mid) * h * F[k - 1, 1]
             + (-2 * f3 + 3 * f2) * Y[k, 1] + (f3 - f2) * h * F[k, 1])
        lo, hi = (lo, mid) if v >= w else (mid, hi)
    return float(T[k - 1] + hi * h)


def _steady(segments, t0: float, t1: float, phi_start: float) -> tuple[np.ndarray, np.ndarray]:
    """The steady turn sampled at STEADY_SAMPLES shaft angles from its start: (phi rel, w)."""
    tt = np.linspace(t0, t1, 40 * STEADY_SAMPLES + 1)
    Y = _dense(segments, tt)[0]
    target = phi_start + np.arange(STEADY_SAMPLES) * 2 * math.pi / STEADY_SAMPLES
    # phi(t) rises: the times of the target angles, refined by a Newton step on the dense
    # output (phi' = w)
    ts = np.interp(target, Y[:, 0], tt)
    for _ in range(3):
        Ys = _dense(segments, ts)[0]
        ts = ts - (Ys[:, 0] - target) / Ys[:, 1]
    Ys = _dense(segments, ts)[0]
    return target - phi_start, Ys[:, 1]


def _result(machine, motor, tables, res, rpm, phi0, dt, inputs, loads, gravity,
            energy_method) -> RunResult:
    segments = res["segments"]
    t_final = float(segments[-1][0][-1])
    n = int(min(max(t_final / dt, 200), 50000))
    time = np.linspace(0.0, t_final, n + 1)
    Y, modes, signs = _dense(segments, time)
    MP, TW, TT = res["MP"]
    info = np.empty((time.size, 6))
    RK.evaluate(Y, modes, signs, MP, TW, TT, *tables.arrays, info)
    w_t = res["w_t"]
    t0, t1, settled, change = res["steady_at"] if res["steady_at"] is not None else (
        None, None, False, math.inf)
    if t0 is None:  # it settled below the working speed
        d = res["durations"]
        t1 = float(sum(d)) if d else t_final
        t0 = t1 - d[-1]
    phi_start = float(_dense(segments, np.array([t0]))[0][0, 0])
    sphi, som = _steady(segments, t0, t1, phi_start)
    mean = float(som.mean())
    steady = SteadyRun(t0, t1, mean, sphi, som, float((som.max() - som.min()) / mean),
                       bool(settled), float(change))
    where = res["where"]
    reached = res["time_to_speed"]
    if motor.kind == "servo":
        short = 2 * math.pi / (t1 - t0) < w_t * (1 - 1e-3)
    else:
        short = reached is None
    if short:
        how = (f"it settles at {steady.mean_rpm:.4g} rpm" if settled else
               f"in {t1:.4g} s it reaches {steady.mean_rpm:.4g} rpm (mean of its last turn)"
               f" and has not settled")
        raise MachineFileError(*where, f"the motor cannot bring the machine to its working"
                               f" speed of {w_t * 30 / math.pi:g} rpm: {how}", "Give a"
                               " stronger or faster motor or a larger belt ratio"
                               " (docs/running.md)")
    energy = None
    if energy_method:
        from .dynamics import speed_fluctuation

        flywheel = motor.hand_wheel_inertia + motor.rotor_inertia * motor.belt_ratio ** 2
        energy = speed_fluctuation(machine, rpm=steady.mean_rpm, flywheel=flywheel,
                                   n_phi=STEADY_SAMPLES, inputs=inputs, loads=loads,
                                   gravity=gravity)
    stop_start = res["stop_start"]
    phase = np.zeros(time.size, dtype=np.int64)
    if stop_start is not None:
        phase[time >= stop_start] = 1
    demand = tables.demand(Y[:, 0], Y[:, 1], info[:, 0])
    return RunResult(
        machine=machine, motor=motor, rpm=float(rpm), phi0=float(phi0), time=time, phi=Y[:, 0],
        omega=Y[:, 1], epsilon=info[:, 0].copy(), motor_speed=info[:, 4].copy(),
        motor_torque=info[:, 1].copy(), belt_torque=info[:, 2].copy(), demand=demand,
        phase=phase, time_to_speed=reached, steady=steady,
        stop_start=float(stop_start) if stop_start is not None else t_final,
        time_to_stop=res["time_to_stop"], energy=energy, tables=tables,
        events=tuple(res["events"]), steps=res["steps"], segments=tuple(segments))
