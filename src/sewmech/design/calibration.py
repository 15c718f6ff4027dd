"""Calibrating the housing's model from the bench: why theory and measurement disagree.

The balancing paper computed an extra counterweight of 64.1 g cm (Delta-Q = 0) and measured its
best at 143 g cm (the x and y vibration velocities of the control point equal) [Sunkuev-
balancing]. The model predicts both curves, v_x(S_add) and v_y(S_add) (:mod:`sewmech.engine.
housing`, the balancing basis); what it does not know well is the housing's mounts. Here the
mounts' stiffness (one factor on all of them) and damping (the loss factor, or one factor on
the mounts' own damping) — and, if asked, the extra counterweight's angle — are fitted to the
measured curves by least squares on the logarithms of the velocities (relative errors, so that
both axes count alike), with scipy's trust-region reflective method within bounds. The
uncertainty of each fitted value is the square root of the diagonal of s^2 (J^T J)^-1 at the
answer (s^2 the residuals' variance, J their Jacobian in the fitted values' logarithms, so a
value's standard deviation is relative); the calibrated model then gives its own crossing, the
static moment it predicts the bench will find, beside the uncalibrated model's and Delta-Q's.

Units: static moments g cm at the edges (kg mm inside), velocities mm/s, angles deg at the
edges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..engine.errors import AnalysisError, OptionError
from ..engine.machine import Machine

#: the fitted values' bounds: the mounts' stiffness factor, the loss factor (or the damping's
#: factor)
STIFFNESS_FACTOR = (1e-3, 1e3)
LOSS_FACTOR = (1e-4, 2.0)
#: a fitted value whose standard deviation (relative, or in rad for the angle) exceeds this is
#: reported as not determined by the measurements
POORLY = 0.5


@dataclass(frozen=True)
class Calibration:
    """A housing fitted to measured vibration.

    machine : the machine's name; values, std : the fitted values (``stiffness_factor``; ``loss_factor`` or
    ``damping_factor``; ``angle_deg`` if fitted) and their standard deviations; rms_log_error :
    the RMS of log(v_model / v_measured) at the answer (0.1: about 10 %); before_rms_log_error:
    the same of the model as the file has it; crossing_gcm : the calibrated model's equal-levels
    static moment (None if its curves do not cross), model_crossing_gcm the file's model's,
    delta_q_gcm the Delta-Q answer, measured_crossing_gcm the crossing of the measured lines
    (:func:`sewmech.design.vibration.crossing`, None if they give none); curves : S_gcm and the
    measured, model and calibrated velocities for plotting; n_points; status : "fitted",
    "undetermined" (a value's standard deviation above :data:`POORLY`) or "bounded" (a value
    at the end of its range: the mounts alone cannot explain the bench); message."""

    machine: str
    counterweight: str
    control_point: str
    values: dict
    std: dict
    rms_log_error: float
    before_rms_log_error: float
    crossing_gcm: float | None
    model_crossing_gcm: float | None
    delta_q_gcm: float | None
    measured_crossing_gcm: float | None
    n_points: int
    status: str
    message: str
    curves: dict

    def to_json(self) -> dict:
        return {"machine": self.machine, "counterweight": self.counterweight, "control_point": self.control_point,
                "values": self.values, "std": self.std, "rms_log_error": self.rms_log_error,
                "before_rms_log_error": self.before_rms_log_error,
                "crossing_gcm": self.crossing_gcm, "model_crossing_gcm": self.model_crossing_gcm,
                "delta_q_gcm": self.delta_q_gcm,
                "measured_crossing_gcm": self.measured_crossing_gcm,
                "n_points": self.n_points, "status": self.status, "message": self.message}


def _scaled(housing, k: float, d: float, viscous: bool):
    """The housing with its mounts' stiffness times k and its damping: the loss factor d, or
    (mounts with their own damping) their damping times d."""
    if viscous:
        return replace(housing, K=housing.K * k, K_eta=housing.K_eta * k, C=housing.C * d,
                       mount_k=housing.mount_k * k, mount_c=housing.mount_c * d)
    return replace(housing, K=housing.K * k, K_eta=housing.K_eta * k, eta=d,
                   mount_k=housing.mount_k * k)


def calibrate(machine: Machine, s_add_gcm, vx_mm_s, vy_mm_s, *,
              counterweight: str | None = None, control_point: str | None = None,
              fit_angle: bool = False, where: str = "measurements") -> Calibration:
    """Fit the machine's housing (its mounts' stiffness and damping, and the extra
    counterweight's angle if ``fit_angle``) to measured x and y vibration velocities (mm/s) of
    the control point against the extra counterweight's static moment (g cm); see the module
    doc. ``counterweight``: default the one on the upper shaft's crank."""
    from scipy.optimize import least_squares

    from ..engine.housing import vibration
    from .balancing import balance, balance_basis, shaft_counterweight
    from .vibration import crossing

    if machine.spec.housing is None:
        raise AnalysisError(machine.file or machine.name, "the machine has no [housing] table:"
                            " there is no model to calibrate", "Add [housing]"
                            " (docs/vibration.md)")
    name = counterweight or shaft_counterweight(machine)
    if name is None:
        raise OptionError("--counterweight", f"machine '{machine.name}' has no counterweight on"
                          " the upper shaft's crank", "Name the counterweight the measurements"
                          " varied")
    S = np.asarray(s_add_gcm, dtype=float) / 100.0  # kg mm
    vm = np.stack([np.asarray(vx_mm_s, float), np.asarray(vy_mm_s, float)], axis=-1)
    if len(S) < 3:
        raise AnalysisError(where, f"{len(S)} measurement(s): a fit of 2 or 3 values needs"
                            " at least 3", "Measure at more static moments")
    if not (vm > 0).all():
        raise AnalysisError(where, "a velocity of 0: the fit compares logarithms", "Leave out"
                            " readings at the instrument's floor")
    B = balance_basis(machine, [name], control_point=control_point)
    spec = machine.spec.counterweights[name]
    beta0 = math.radians(spec.angle_deg) if spec.by_moment else math.atan2(spec.at_mm[1],
                                                                           spec.at_mm[0])
    viscous = not np.isnan(B.housing.mount_c).all()
    d0 = 1.0 if viscous else B.housing.eta
    h0 = B.housing

    def model(k, d, beta):
        xy = S[:, None] * np.array([math.cos(beta), math.sin(beta)])
        W = B.quantities(xy[:, None, :])["W"]
        return vibration(_scaled(h0, k, d, viscous), W, B.rpm).rms_velocity[:, B.control, :2]

    def residual(z):
        k, d = math.exp(z[0]), math.exp(z[1])
        beta = z[2] if fit_angle else beta0
        return (np.log(model(k, d, beta)) - np.log(vm)).reshape(-1)

    lo = [math.log(STIFFNESS_FACTOR[0]), math.log(LOSS_FACTOR[0])]
    hi = [math.log(STIFFNESS_FACTOR[1]), math.log(LOSS_FACTOR[1] if not viscous else 1e3)]
    z0 = [0.0, math.log(d0)]
    if fit_angle:
        lo.append(beta0 - math.pi)
        hi.append(beta0 + math.pi)
        z0.append(beta0)
    before = float(np.sqrt(np.mean(residual(np.array(z0)) ** 2)))
    best = None
    for k0 in (0.0, math.log(0.3), math.log(3.0)):  # a few starts: the fit has local minima
        start = np.array([k0, *z0[1:]])
        res = least_squares(residual, start, bounds=(lo, hi), method="trf", x_scale="jac",
                            xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=2000)
        if best is None or res.cost < best.cost:
            best = res
    z = best.x
    r = best.fun
    n, p = r.size, z.size
    J = best.jac
    dof = max(n - p, 1)
    s2 = float(r @ r) / dof
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
        std_z = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        std_z = np.full(p, np.nan)
    k, d = math.exp(z[0]), math.exp(z[1])
    beta = float(z[2]) if fit_angle else beta0
    dname = "damping_factor" if viscous else "loss_factor"
    values = {"stiffness_factor": k, dname: d}
    std = {"stiffness_factor": float(k * std_z[0]), dname: float(d * std_z[1])}
    if fit_angle:
        values["angle_deg"] = math.degrees(beta) % 360.0
        std["angle_deg"] = float(math.degrees(std_z[2]))
    # a value the measurements do not pin down: its standard deviation as large as itself
    # (a factor's relative one above POORLY, an angle's above POORLY rad)
    poorly = [n for i, n in enumerate(values) if not np.isfinite(std_z[i])
              or std_z[i] > POORLY]
    bounded = [n for i, n in enumerate(("stiffness_factor", dname))
               if min(z[i] - lo[i], hi[i] - z[i]) < 1e-6]
    # the crossings: the calibrated model, the model as the file has it, Delta-Q, the lines
    cal = replace(B, housing=_scaled(h0, k, d, viscous))
    if fit_angle:  # the calibrated angle is where its crossing is looked for
        cal = replace(cal, start=np.array([[1e-12 * math.cos(beta), 1e-12 * math.sin(beta)]]))

    def cross(basis):
        res = balance(machine, "equal-levels", basis=basis)
        return res.counterweights[name]["static_moment_gcm"] if res.status == "optimal" \
            else None

    try:
        measured = crossing(s_add_gcm, vx_mm_s, vy_mm_s, where=where).s_add_gcm
    except AnalysisError:
        measured = None
    dq = balance(machine, "delta-q", basis=B)
    grid = np.linspace(0.0, max(float(np.max(s_add_gcm)) * 1.2, 1.0), 121) / 100.0
    xy = grid[:, None] * np.array([math.cos(beta), math.sin(beta)])
    W = B.quantities(xy[:, None, :])["W"]
    curves = {"S_gcm": grid * 100.0,
              "model": vibration(h0, W, B.rpm).rms_velocity[:, B.control, :2],
              "calibrated": vibration(cal.housing, W, B.rpm).rms_velocity[:, B.control, :2],
              "measured_S_gcm": np.asarray(s_add_gcm, float), "measured": vm}
    rms = float(np.sqrt(np.mean(r ** 2)))
    status = "bounded" if bounded else "undetermined" if poorly else "fitted"
    msg = (f"fitted {', '.join(values)} by least squares on log velocity ({n} values); RMS"
           f" error {rms:.3g} (was {before:.3g} with the file's mounts)")
    if poorly:
        msg += (f"; {' and '.join(poorly)} not determined by these measurements (standard"
                f" deviation above {POORLY:.0%} of the value{' or 29 deg' * fit_angle}):"
                " measure over a wider range of static moments, or fit fewer values")
    if bounded:
        msg += (f"; {' and '.join(bounded)} at the bound of its range: the housing's model"
                " cannot follow the bench with its mounts alone (look at the mass properties,"
                " the control point and the counterweight's angle)")
    return Calibration(machine.name, name, B.control_name, values, std, rms, before, cross(cal), cross(B),
                       dq.counterweights[name]["static_moment_gcm"] if dq.status == "optimal"
                       else None, measured, len(S), status, msg, curves)
