"""Balancing from measured vibration: the crossing of the x and y velocity lines, levels in dB,
and trial-weight balancing by influence coefficients.

The balancing paper in our sources (class 1820 bar-tack semi-automatic) ends with a measurement:
an extra counterweight built 2.5 to 3 times too large is trimmed step by step, the vibration
velocity of a control point on the housing is measured along x and y at each step, and the
static moment where the two are equal (neither direction preferred) is the one to keep. Here the
two velocities are fitted against the static moment, and the crossing comes with a 95 %
confidence interval (Fieller's interval for the root of a fitted line). The level change in dB
between two measurements says what the operator feels.

Trial-weight balancing by influence coefficients is the workshop method for a machine already
built: measure the vibration (amplitude and phase, at one or more places and speeds), add a known
trial mass in each correction plane in turn and measure again; the vibration is linear in the
unbalance, so the correction that cancels it best is a least-squares problem in complex numbers.

Units: static moments g cm (as people weigh and drill them), velocities mm/s, angles deg at the
edges; phasors are complex numbers amplitude * exp(i phase).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..engine.errors import AnalysisError

#: reference vibration velocity for levels in dB, mm/s: 5e-8 m/s, the reference of the GOST
#: vibration standards the balancing paper's measurements follow (ISO 1683 uses 1e-9 m/s;
#: a level change does not depend on it)
V_REF_MM_S = 5e-5

#: the ranges of measured numbers (CSV files and arguments), checked where they enter:
#: a vibration velocity or amplitude, mm/s (a magnitude; 1 m/s is far beyond any machine
#: that still stands, and 0 is a reading at the instrument's floor)
VELOCITY_RANGE_MM_S = (0.0, 1e6)
#: a velocity whose level in dB is taken (``sewmech level-change``), mm/s: one nanometre per
#: second, far below any vibration meter's floor, to a metre per second (a level needs a
#: velocity > 0: the level of 0 is minus infinity)
LEVEL_RANGE_MM_S = (1e-6, 1e6)
#: a static moment (an extra counterweight, a trial mass), g cm: a magnitude (its sign belongs
#: to its angle), up to 10 kg m
STATIC_MOMENT_RANGE_GCM = (0.0, 1e6)
#: a phase or a trial mass's angle, deg: within a turn either way
ANGLE_RANGE_DEG = (-360.0, 360.0)


@dataclass(frozen=True)
class Crossing:
    """Where the x and y vibration velocities are equal, from measurements.

    s_add_gcm : the static moment of the crossing, g cm; ci95_gcm : its 95 % confidence
    interval (low, high), g cm; n_points : measurements used; fit_x, fit_y : each line's
    coefficients (intercept mm/s, slope mm/s per g cm); residual_mm_s : the standard deviation
    of the difference vx - vy about its line, mm/s; v_at_crossing_mm_s : the fitted velocity
    on either axis there; level_change_db : the level of the fitted velocity vector
    sqrt(vx^2 + vy^2) at the crossing against the lowest static moment measured (negative: the
    machine is quieter), None where it is not defined (a fitted velocity vector of zero, or
    of round-off of the velocities measured, at either end: the level of 0 is minus infinity),
    and ``level_change_note`` then says why."""

    s_add_gcm: float
    ci95_gcm: tuple[float, float]
    n_points: int
    fit_x: tuple[float, float]
    fit_y: tuple[float, float]
    residual_mm_s: float
    v_at_crossing_mm_s: float
    s_lowest_gcm: float
    level_change_db: float | None
    level_change_note: str | None = None

    def to_json(self) -> dict:
        out = {"s_add_gcm": self.s_add_gcm, "ci95_gcm": list(self.ci95_gcm),
               "n_points": self.n_points,
               "fit_x": {"intercept_mm_s": self.fit_x[0], "slope_mm_s_per_gcm": self.fit_x[1]},
               "fit_y": {"intercept_mm_s": self.fit_y[0], "slope_mm_s_per_gcm": self.fit_y[1]},
               "residual_mm_s": self.residual_mm_s,
               "v_at_crossing_mm_s": self.v_at_crossing_mm_s,
               "s_lowest_gcm": self.s_lowest_gcm, "level_change_db": self.level_change_db}
        if self.level_change_db is None:
            out["level_change_note"] = self.level_change_note
        return out


def _line(s: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares line v = a + b s: coefficients (a, b), their covariance, residual
    variance (n - 2 degrees of freedom). ``s`` should be of order 1 (:func:`crossing` fits
    against the static moments scaled to -0.5 .. 0.5): numpy's rank cut-off and X^T X are
    not scale-free."""
    X = np.column_stack([np.ones_like(s), s])
    coef, *_ = np.linalg.lstsq(X, v, rcond=None)
    r = v - X @ coef
    dof = len(s) - 2
    var = float(r @ r) / dof if dof > 0 else 0.0
    cov = var * np.linalg.inv(X.T @ X)
    return coef, cov, var


def crossing(s_add_gcm: ArrayLike, vx_mm_s: ArrayLike, vy_mm_s: ArrayLike,
             where: str = "measurements") -> Crossing:
    """The static moment where the vibration velocities on x and y are equal.

    ``s_add_gcm`` (g cm), ``vx_mm_s`` and ``vy_mm_s`` (mm/s): one measurement per entry,
    repeats at the same static moment allowed. Each velocity is fitted by a straight line; the
    crossing is the root of their difference d = vx - vy fitted on the same rows (paired, so
    what the two axes share cancels), and its 95 % interval is Fieller's: the static moments
    where 0 lies within the line's 95 % band, (a + b S)^2 <= t^2 var(a + b S), t from Student's
    distribution with n - 2 degrees of freedom. ``where`` names the data in errors.

    Raises AnalysisError when the data cannot give a crossing: fewer than two measurements on
    either side of it, lines that do not cross within the measured range, or a difference
    whose slope is not significant (the interval would be unbounded)."""
    from scipy.stats import t as student

    s = np.asarray(s_add_gcm, dtype=float)
    vx = np.asarray(vx_mm_s, dtype=float)
    vy = np.asarray(vy_mm_s, dtype=float)
    if not (s.shape == vx.shape == vy.shape and s.ndim == 1):
        raise AnalysisError(where, "the static moments and the two velocities must be columns"
                            " of the same length")
    for name, a in (("s_add_gcm", s), ("vx_mm_s", vx), ("vy_mm_s", vy)):
        bad = np.nonzero(~np.isfinite(a))[0]
        if bad.size:
            raise AnalysisError(where, f"{name} is not a finite number in measurement"
                                f" {bad[0] + 1}", "Give every measurement as a number")
    if np.any(vx < 0) or np.any(vy < 0):
        raise AnalysisError(where, "a vibration velocity is negative",
                            "Give the velocities' magnitudes (RMS or peak), mm/s")
    for name, a, (lo, hi), unit in (("s_add_gcm", s, STATIC_MOMENT_RANGE_GCM, "g cm"),
                                    ("vx_mm_s", vx, VELOCITY_RANGE_MM_S, "mm/s"),
                                    ("vy_mm_s", vy, VELOCITY_RANGE_MM_S, "mm/s")):
        bad = np.nonzero(~((a >= lo) & (a <= hi)))[0]
        if bad.size:
            raise AnalysisError(where, f"{name} is {a[bad[0]]:g} {unit} in measurement"
                                f" {bad[0] + 1}, outside {lo:g} .. {hi:g} {unit}",
                                "Check the value and its unit")
    if np.unique(s).size < 3:
        raise AnalysisError(where, f"{np.unique(s).size} different static moments measured",
                            "Measure at least three (two on each side of the crossing)")
    d = vx - vy
    n = len(s)
    lo_s, hi_s = float(s.min()), float(s.max())
    # the lines are fitted against t = (s - mid) / span, -0.5 .. 0.5, whatever the unit and
    # size of the static moments: fitted against s itself, moments of 1e-20 g cm fell below
    # numpy's rank cut-off ("the lines do not cross") and of 1e-300 g cm made X^T X singular
    # (numpy's bare "Singular matrix")
    mid, span = 0.5 * (lo_s + hi_s), hi_s - lo_s
    t = (s - mid) / span
    coef, cov, var = _line(t, d)
    a, b = coef
    if b == 0.0 or not (-0.5 <= -a / b <= 0.5):
        side = "x" if np.mean(d) > 0 else "y"
        raise AnalysisError(where, f"the x and y lines do not cross within the measured static"
                            f" moments {lo_s:g} .. {hi_s:g} g cm (the {side} velocity is the"
                            " larger throughout)", "Measure further on the side where the"
                            " velocities come closer")
    root_t = -a / b
    root = mid + span * root_t
    below, above = int(np.sum(t < root_t)), int(np.sum(t > root_t))
    if below < 2 or above < 2:
        raise AnalysisError(where, f"{below} measurement(s) below and {above} above the"
                            f" crossing at {root:.4g} g cm", "Measure at least two on each"
                            " side of it")
    tq = float(student.ppf(0.975, n - 2))
    # Fieller: (a + b S)^2 - t^2 (Vaa + 2 S Vab + S^2 Vbb) = 0
    qa = b * b - tq * tq * cov[1, 1]
    qb = 2.0 * (a * b - tq * tq * cov[0, 1])
    qc = a * a - tq * tq * cov[0, 0]
    if qa <= 0.0:
        raise AnalysisError(where, "the difference of the two velocities does not change"
                            " significantly with the static moment (its slope is within its"
                            " own 95 % band): the crossing's interval is unbounded",
                            "Measure over a wider range of static moments or repeat the"
                            " measurements")
    disc = max(qb * qb - 4.0 * qa * qc, 0.0)
    lo = mid + span * (-qb - math.sqrt(disc)) / (2.0 * qa)
    hi = mid + span * (-qb + math.sqrt(disc)) / (2.0 * qa)
    cx, _, _ = _line(t, vx)
    cy, _, _ = _line(t, vy)
    v_cross = float(cx[0] + cx[1] * root_t)
    s0 = lo_s
    v0 = math.hypot(cx[0] - 0.5 * cx[1], cy[0] - 0.5 * cy[1])  # at t = -0.5, s = s0
    v1 = math.hypot(v_cross, float(cy[0] + cy[1] * root_t))
    # each line as intercept (mm/s) and slope (mm/s per g cm) of the static moment itself
    fit_x = (float(cx[0] - cx[1] * mid / span), float(cx[1] / span))
    fit_y = (float(cy[0] - cy[1] * mid / span), float(cy[1] / span))
    if not np.all(np.isfinite([*fit_x, *fit_y, lo, hi])):
        raise AnalysisError(where, f"the static moments measured span only {span:g} g cm: the"
                            " lines' slopes per g cm are beyond floating point",
                            "Give the static moments in g cm (a milligram at 1 cm is 0.001"
                            " g cm)")
    # a level in dB needs a velocity > 0: a fitted velocity vector of zero (or of round-off of
    # the velocities measured) at either end has none, and the change is said to be undefined
    floor = 1e-9 * max(float(np.max(vx)), float(np.max(vy)))
    change, note = None, None
    if v1 <= floor or v0 <= floor:
        at = (f"at the crossing ({root:.4g} g cm)" if v1 <= floor
              else f"at the lowest static moment measured ({s0:g} g cm)")
        note = (f"not defined: the fitted lines give a velocity of 0 mm/s {at}, and a level in"
                " dB needs a velocity > 0 (the level of 0 is minus infinity)")
    else:
        change = level_change_db(v0, v1)
    return Crossing(float(root), (float(lo), float(hi)), n, fit_x, fit_y, math.sqrt(var),
                    v_cross, s0, change, note)


def level_db(v_mm_s: ArrayLike, ref_mm_s: float = V_REF_MM_S) -> np.ndarray:
    """Vibration velocity level, dB: 20 log10(v / ref); ``v_mm_s`` and ``ref_mm_s`` in mm/s
    (default reference 5e-8 m/s)."""
    v = np.asarray(v_mm_s, dtype=float)
    if np.any(v <= 0) or not ref_mm_s > 0:
        raise AnalysisError("level", "velocities and the reference must be > 0 mm/s")
    return 20.0 * np.log10(v / ref_mm_s)


def level_change_db(before_mm_s: float, after_mm_s: float) -> float:
    """Change of the vibration velocity level from ``before`` to ``after`` (mm/s), dB: negative
    when the vibration fell (the paper's 110 -> 105.2 dBA is -4.8 dB, a velocity 0.58 times
    the first)."""
    return float(level_db(after_mm_s) - level_db(before_mm_s))


# ---- influence coefficients ------------------------------------------------------------------


def phasor(amplitude: ArrayLike, phase_deg: ArrayLike) -> np.ndarray:
    """Complex phasors amplitude * exp(i phase) (phase in deg)."""
    return np.asarray(amplitude, dtype=float) * np.exp(1j * np.radians(phase_deg))


@dataclass(frozen=True)
class InfluenceResult:
    """Correction masses from influence coefficients.

    correction_gcm : per plane, the static moment to add, g cm; correction_angle_deg : per
    plane, its angle deg (in the frame the trial masses' angles were given in); coefficients :
    (rows, planes) complex influence coefficients, mm/s per g cm; residual : (rows,) complex
    vibration predicted after the correction, mm/s; before, after : RMS of the vibration
    amplitudes over the rows before and predicted after, mm/s (after is 0 when the
    correction cancels every reading, see ``cancelled``); cancelled : None, or why the
    predicted vibration is nil (as many readings as planes: the correction is fitted to cancel
    them exactly, so what is left is round-off, not a level); level_change_db : the predicted
    change in level, dB, None when cancelled."""

    correction_gcm: np.ndarray
    correction_angle_deg: np.ndarray
    coefficients: np.ndarray
    residual: np.ndarray
    before: float
    after: float
    cancelled: str | None = None

    @property
    def level_change_db(self) -> float | None:
        if self.cancelled is not None or not (self.before > 0 and self.after > 0):
            return None
        return level_change_db(self.before, self.after)

    def to_json(self, planes=None) -> dict:
        names = planes or [f"plane {j + 1}" for j in range(len(self.correction_gcm))]
        out = {"corrections": {n: {"static_moment_gcm": float(s), "angle_deg": float(a)}
                               for n, s, a in zip(names, self.correction_gcm,
                                                  self.correction_angle_deg)},
               "before_rms_mm_s": self.before, "after_rms_mm_s": self.after,
               "level_change_db": self.level_change_db}
        if self.level_change_db is None:
            out["level_change_note"] = self.cancelled or "no vibration before or after"
        return out


#: the least change a trial run must make to the readings, as a fraction of their size (the
#: 2-norm over the rows, for the weakest combination of the trial masses): a vibration meter
#: resolves about 1 % of a reading (or 0.5 deg of phase), so a smaller change does not
#: determine the influence coefficients, and the correction they give (at least 100 times
#: the trial mass) is noise. Balancing practice asks a trial run to change the readings by
#: 10 to 30 % or more.
MIN_TRIAL_EFFECT = 0.01


def influence_balance(baseline: ArrayLike, trials: ArrayLike, trial_gcm: ArrayLike,
                      trial_angle_deg: ArrayLike, names: list[str] | None = None
                      ) -> InfluenceResult:
    """Correction masses from trial runs (the influence-coefficient method).

    baseline : (rows,) complex vibration phasors without trial masses, mm/s (a row is one
    measuring place at one speed, or one repeat); trials : (planes, rows) the same rows measured
    with the trial mass of each plane in turn; trial_gcm, trial_angle_deg : (planes,) each trial
    mass's static moment (g cm) and angle (deg). The vibration is taken as linear in the
    unbalance: V = V_0 + A U with U the complex static moments added, so
    A[:, j] = (V_j - V_0) / U_j, and the correction minimises sum |V_0 + A U|^2 (exact when
    rows = planes and A is regular; least squares over more rows). ``names``: the planes'
    names in messages (default "plane 1", ...).

    Raises AnalysisError when the trial runs do not determine the coefficients: a trial mass
    whose run changes the readings by less than :data:`MIN_TRIAL_EFFECT` of their size, or
    trial runs whose changes do not tell the planes apart (the smallest singular value of the
    changes, against the readings' size, below the same fraction)."""
    V0 = np.asarray(baseline, dtype=complex)
    Vt = np.atleast_2d(np.asarray(trials, dtype=complex))
    Ut = phasor(trial_gcm, trial_angle_deg).reshape(-1)
    for name, a, hi, unit in (("a baseline reading", np.abs(V0), VELOCITY_RANGE_MM_S[1], "mm/s"),
                              ("a trial run's reading", np.abs(Vt), VELOCITY_RANGE_MM_S[1],
                               "mm/s"),
                              ("a trial mass", np.abs(Ut), STATIC_MOMENT_RANGE_GCM[1], "g cm")):
        if not np.all(a <= hi):  # (a NaN fails too)
            raise AnalysisError("influence", f"{name} is not a finite number within"
                                f" {hi:g} {unit}", "Check the value and its unit")
    if V0.ndim != 1 or Vt.shape != (len(Ut), len(V0)):
        raise AnalysisError("influence", f"{len(Ut)} trial masses and {len(V0)} baseline"
                            f" readings need trials of shape ({len(Ut)}, {len(V0)}), got"
                            f" {Vt.shape}")
    if np.any(np.abs(Ut) == 0):
        raise AnalysisError("influence", "a trial mass has a zero static moment",
                            "Give each trial mass's static moment > 0 g cm")
    if len(V0) < len(Ut):
        raise AnalysisError("influence", f"{_count(len(V0), 'reading')} cannot fix"
                            f" {_count(len(Ut), 'plane')}", "Measure at more places or speeds"
                            " than there are planes")
    names = names or [f"plane {j + 1}" for j in range(len(Ut))]
    E = (Vt - V0[None, :]).T  # (rows, planes): what each trial mass changed, mm/s
    size = max(float(np.linalg.norm(V0)), float(np.linalg.norm(Vt, axis=1).max()))
    effect = np.linalg.norm(E, axis=0) / size if size > 0 else np.zeros(len(Ut))
    weak = int(np.argmin(effect))
    if not effect[weak] >= MIN_TRIAL_EFFECT:
        # the trial mass that would change the readings by 10 % (linear in the mass); a
        # change of 1e-4 or less is no measurement of it at all
        bigger = abs(Ut[weak]) * 0.1 / effect[weak] if effect[weak] >= 1e-4 else math.inf
        more = (f" (about {bigger:.3g} g cm)" if bigger <= STATIC_MOMENT_RANGE_GCM[1]
                else "")
        apart = "the trial runs do not tell the planes apart: " if len(Ut) > 1 else ""
        raise AnalysisError("influence", f"{apart}the trial mass of {names[weak]}"
                            f" ({abs(Ut[weak]):g} g cm) changes the readings by"
                            f" {100 * effect[weak]:.2g} % of their size, less than the"
                            f" {100 * MIN_TRIAL_EFFECT:g} % a vibration meter resolves: its"
                            " influence coefficients are not determined, and a correction"
                            f" from them would be at least {1 / MIN_TRIAL_EFFECT:g} times the"
                            " trial mass", f"Repeat that run with a trial mass that changes"
                            f" the readings by 10 % or more{more}, and check that the mass"
                            " was fitted in that plane")
    sv = np.linalg.svd(E, compute_uv=False)
    if len(Ut) > 1 and not sv[-1] >= MIN_TRIAL_EFFECT * size:
        raise AnalysisError("influence", "the trial runs do not tell the planes apart: some"
                            " combination of their trial masses changes the readings by"
                            f" {100 * sv[-1] / size:.2g} % of their size (the influence"
                            " coefficients of the planes are nearly dependent), so the"
                            " correction is not determined", "Measure at another place or"
                            " speed, where the planes act differently, or use larger trial"
                            " masses")
    A = E / Ut[None, :]  # (rows, planes), mm/s per g cm
    U, *_ = np.linalg.lstsq(A, -V0, rcond=None)
    res = V0 + A @ U
    before = float(np.sqrt(np.mean(np.abs(V0) ** 2)))
    after = float(np.sqrt(np.mean(np.abs(res) ** 2)))
    cancelled = None
    if len(V0) == len(Ut):
        cancelled = (f"{_count(len(V0), 'reading')} and {_count(len(Ut), 'plane')}: the"
                     " correction is fitted to cancel every reading, so nothing is left to"
                     " give a level after (measure at more places or speeds for a check)")
    elif after <= 1e-12 * before:  # readings without noise that a correction cancels
        cancelled = ("the correction cancels every reading (what is left is round-off), so"
                     " there is no level after to compare")
    if cancelled is not None:
        after, res = 0.0, np.zeros_like(res)
    return InfluenceResult(np.abs(U), np.degrees(np.angle(U)), A, res, before, after,
                           cancelled)


def _count(n: int, noun: str) -> str:
    """``n`` and ``noun``, in the plural unless n is 1: "1 reading", "3 readings"."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"
