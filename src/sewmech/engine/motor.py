"""The motor that drives the upper shaft: its torque against its speed, through a belt.

A machine file's ``[motor]`` table (:class:`sewmech.spec.MotorSpec`; docs/running.md) becomes a
:class:`Motor`: the numbers the run in time (:mod:`sewmech.engine.running`) integrates with,
in sewmech's units (torques N mm at the motor's shaft, speeds rad/s, inertias kg mm^2). Four
kinds:

- ``table``: the torque at the motor's shaft against its speed, linear between the points and
  the last piece continued beyond the last speed (a falling curve goes on falling: past its
  no-load speed a motor brakes). The household machine's universal motor is one.
- ``induction``: Kloss's curve T(s) = 2 T_b s s_b / (s^2 + s_b^2) of the slip
  s = (n_s - n) / n_s, through the rated point (``rated_rpm``, ``rated_power_W``) with the
  breakdown torque T_b = ``breakdown_torque_ratio`` times the rated torque T_r; the
  breakdown slip follows, s_b = s_r (k + sqrt(k^2 - 1)) with k = T_b / T_r. Past the
  synchronous speed the slip is negative and the motor brakes.
- ``clutch``: that induction motor, already running at its no-load (synchronous) speed with its
  flywheel, and a dry clutch that passes at most ``clutch_torque_N_mm`` while it slips; when the
  two sides turn together the motor drives the machine directly. To stop, the clutch lets go
  and a brake of ``brake_torque_N_mm`` acts on the machine's side.
- ``servo``: a speed controller holding the working speed, PI with the torque limit
  ``max_torque_N_mm``. Its gains follow from the speed loop's bandwidth f_b (``bandwidth_hz``)
  and the inertia the motor sees, J_m = J_rotor + (J_machine + J_hand_wheel) / i^2:
  k_p = 2 pi f_b J_m, k_i = k_p 2 pi f_b / 4 (the PI's zero a quarter of the crossover), with
  back-calculation against wind-up (tracking time k_p / k_i). To stop, its speed command is 0.

The belt ratio i is the motor's speed over the shaft's: the motor's torque T reaches the shaft
as i T, its rotor's inertia as i^2 J_rotor. The belt itself is rigid and without loss.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import MachineFileError
from .spec import MotorSpec, _Spec, load_toml_model

#: the kinds' codes in the run's kernel
KIND_CODE = {"table": 0, "induction": 1, "clutch": 2, "servo": 3}
#: the servo's speed loop when the file gives no bandwidth_hz, Hz
DEFAULT_BANDWIDTH_HZ = 10.0


def rpm_to_rad_s(rpm: float) -> float:
    return rpm * math.pi / 30.0


@dataclass(frozen=True)
class Motor:
    """A motor ready to run (see the module doc). Torques N mm at the motor's shaft, speeds
    rad/s of the motor, inertias kg mm^2.

    Attributes
    ----------
    spec : MotorSpec
        The ``[motor]`` table it was made from.
    where : str
        The file it came from (errors about the motor name it, with ``[motor]``).
    kind, belt_ratio, rotor_inertia, hand_wheel_inertia
    table_speed, table_torque : the table's points (``table``), rad/s and N mm
    synchronous_speed, rated_torque, breakdown_torque, breakdown_slip : Kloss's curve
        (``induction`` and ``clutch``)
    clutch_torque, brake_torque : ``clutch``
    max_torque, bandwidth_hz : ``servo``
    """

    spec: MotorSpec
    where: str
    kind: str
    belt_ratio: float
    rotor_inertia: float
    hand_wheel_inertia: float
    table_speed: np.ndarray
    table_torque: np.ndarray
    synchronous_speed: float = math.nan
    rated_torque: float = math.nan
    breakdown_torque: float = math.nan
    breakdown_slip: float = math.nan
    clutch_torque: float = math.nan
    brake_torque: float = 0.0
    max_torque: float = math.nan
    bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ

    @property
    def code(self) -> int:
        return KIND_CODE[self.kind]

    def torque(self, speed: np.ndarray) -> np.ndarray:
        """The motor's torque (N mm) at its speed(s) ``speed`` (rad/s) on its curve: the
        table, or Kloss's curve (a clutch motor's motor; a servo has no curve: its torque
        limit at every speed)."""
        w = np.asarray(speed, dtype=float)
        if self.kind == "table":
            return table_torque(self.table_speed, self.table_torque, w)
        if self.kind in ("induction", "clutch"):
            s = (self.synchronous_speed - w) / self.synchronous_speed
            sb = self.breakdown_slip
            return 2.0 * self.breakdown_torque * s * sb / (s * s + sb * sb)
        return np.full_like(w, self.max_torque)

    @property
    def peak_torque(self) -> float:
        """The most torque the motor puts on its shaft, N mm (a clutch motor: the clutch's
        limit, or its motor's breakdown torque if that is less)."""
        if self.kind == "table":
            return float(np.max(self.table_torque))
        if self.kind == "induction":
            return self.breakdown_torque
        if self.kind == "clutch":
            return min(self.clutch_torque, self.breakdown_torque)
        return self.max_torque

    @property
    def free_speed(self) -> float:
        """The motor's speed without load (rad/s): where its curve reaches 0 torque (a table
        that never does: inf; a servo: inf, it holds its command)."""
        if self.kind in ("induction", "clutch"):
            return self.synchronous_speed
        if self.kind == "table":
            n, t = self.table_speed, self.table_torque
            for k in range(1, len(n)):
                if t[k] <= 0.0 < t[k - 1]:
                    return float(n[k - 1] + (n[k] - n[k - 1]) * t[k - 1] / (t[k - 1] - t[k]))
            if t[-1] < t[-2]:  # the last piece continued down to 0
                return float(n[-1] + (n[-1] - n[-2]) * t[-1] / (t[-2] - t[-1]))
        return math.inf

    def describe(self) -> str:
        """One line: what the motor is."""
        i = f", belt ratio {self.belt_ratio:g}"
        if self.kind == "table":
            return (f"table motor ({len(self.table_speed)} points up to"
                    f" {self.table_speed[-1] * 30 / math.pi:g} rpm, starting torque"
                    f" {self.table_torque[0]:g} N mm){i}")
        if self.kind in ("induction", "clutch"):
            s = self.spec
            text = (f"induction motor {s.rated_power_W:g} W at {s.rated_rpm:g} rpm (synchronous"
                    f" {s.synchronous_rpm:g}, breakdown torque {s.breakdown_torque_ratio:g} x"
                    f" {self.rated_torque:.4g} N mm){i}")
            if self.kind == "clutch":
                text = (f"clutch motor: {text}, clutch {self.clutch_torque:g} N mm, brake"
                        f" {self.brake_torque:g} N mm")
            return text
        return (f"servo motor (torque limit {self.max_torque:g} N mm, speed loop"
                f" {self.bandwidth_hz:g} Hz){i}")

    def to_json(self) -> dict:
        """The motor's values as given (SI names), for ``--json``."""
        out = {"kind": self.kind, "belt_ratio": self.belt_ratio,
               "rotor_inertia_kgm2": self.rotor_inertia * 1e-6,
               "hand_wheel_inertia_kgm2": self.hand_wheel_inertia * 1e-6,
               "description": self.describe()}
        if self.kind == "table":
            out["speed_rpm"] = [float(x) for x in self.table_speed * 30 / math.pi]
            out["torque_Nm"] = [float(x) * 1e-3 for x in self.table_torque]
        if self.kind in ("induction", "clutch"):
            s = self.spec
            out.update(synchronous_rpm=s.synchronous_rpm, rated_rpm=s.rated_rpm,
                       rated_power_W=s.rated_power_W, rated_torque_Nm=self.rated_torque * 1e-3,
                       breakdown_torque_Nm=self.breakdown_torque * 1e-3,
                       breakdown_slip=self.breakdown_slip)
        if self.kind == "clutch":
            out.update(clutch_torque_Nm=self.clutch_torque * 1e-3,
                       brake_torque_Nm=self.brake_torque * 1e-3)
        if self.kind == "servo":
            out.update(max_torque_Nm=self.max_torque * 1e-3, bandwidth_hz=self.bandwidth_hz)
        return out


def table_torque(speed: np.ndarray, torque: np.ndarray, w: np.ndarray) -> np.ndarray:
    """A table's torque at speeds ``w``: linear between its points, the last piece continued
    beyond its last speed, its first value below 0."""
    w = np.asarray(w, dtype=float)
    out = np.interp(w, speed, torque)
    beyond = w > speed[-1]
    if beyond.any():
        slope = (torque[-1] - torque[-2]) / (speed[-1] - speed[-2])
        out = np.where(beyond, torque[-1] + slope * (w - speed[-1]), out)
    return out


def motor_from_spec(spec: MotorSpec, where: str = "<motor>") -> Motor:
    """A :class:`Motor` from a validated ``[motor]`` table; ``where`` is its file."""
    common = dict(spec=spec, where=where, kind=spec.kind, belt_ratio=float(spec.belt_ratio),
                  rotor_inertia=float(spec.rotor_inertia_kg_mm2),
                  hand_wheel_inertia=float(spec.hand_wheel_inertia_kg_mm2))
    if spec.kind == "table":
        n = np.array([rpm_to_rad_s(x) for x in spec.speed_rpm])
        t = np.array(spec.torque_N_mm, dtype=float)
        for a in (n, t):
            a.setflags(write=False)
        return Motor(**common, table_speed=n, table_torque=t)
    empty = np.zeros(0)
    empty.setflags(write=False)
    if spec.kind in ("induction", "clutch"):
        ws = rpm_to_rad_s(spec.synchronous_rpm)
        wr = rpm_to_rad_s(spec.rated_rpm)
        tr = spec.rated_power_W * 1e3 / wr  # W = N m/s -> N mm at rad/s
        k = spec.breakdown_torque_ratio
        sr = (ws - wr) / ws
        sb = sr * (k + math.sqrt(k * k - 1.0))
        if sb >= 1.0:
            raise MachineFileError(where, "motor", "breakdown_torque_ratio",
                                   f"is {k:g}: with the rated slip {sr:.3g} Kloss's curve would"
                                   f" break down at a slip of {sb:.3g}, beyond standstill (1)",
                                   "Check the rated speed and the breakdown torque on the"
                                   " motor's plate or data sheet")
        extra = {}
        if spec.kind == "clutch":
            extra = dict(clutch_torque=float(spec.clutch_torque_N_mm),
                         brake_torque=float(spec.brake_torque_N_mm or 0.0))
        return Motor(**common, table_speed=empty, table_torque=empty, synchronous_speed=ws,
                     rated_torque=tr, breakdown_torque=k * tr, breakdown_slip=sb, **extra)
    return Motor(**common, table_speed=empty, table_torque=empty,
                 max_torque=float(spec.max_torque_N_mm),
                 bandwidth_hz=float(spec.bandwidth_hz or DEFAULT_BANDWIDTH_HZ))


class MotorFile(_Spec):
    """A motor file: one ``[motor]`` table (as in machine files), for ``sewmech run --motor``."""

    motor: MotorSpec


def load_motor_file(path: str | Path) -> Motor:
    """A :class:`Motor` from a TOML file that holds a ``[motor]`` table; every problem a
    :class:`~sewmech.errors.MachineFileError` naming the file, the table and the key."""
    spec = load_toml_model(path, MotorFile, "motor file", doc="docs/running.md").motor
    return motor_from_spec(spec, str(path))
