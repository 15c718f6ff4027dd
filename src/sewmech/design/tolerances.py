"""Tolerance analysis: how far a sewing metric strays when every dimension is made within its
tolerance, which dimensions matter, and the widest tolerances that keep a metric in a band.

The JB kinematics report states its aim as reasonable dimensions and accuracy requirements;
this module answers the second half from the exact derivatives of the metrics
(:mod:`sewmech.sewing.gradients`, :mod:`sewmech.engine.sensitivity`):

- **worst case**: sum_j |d_j| t_j (every dimension at the unlucky end of its tolerance);
- **RSS**: sqrt(sum_j (d_j t_j)^2), the band at the same confidence as the tolerances (3
  standard deviations for normally distributed dimensions);
- **Monte Carlo**: the metric computed again on a batch of designs drawn within the
  tolerances (normal with sigma = t / 3, or uniform over +-t), in one batch call, nonlinear
  effects included;
- **contributions**: each dimension's share of the RSS variance, (d_j t_j)^2 / RSS^2;
- **allocation**: the tolerances of least cost sum_j b_j / t_j (the cost model: halving a
  tolerance doubles its cost) that keep the metric within +-B: by RSS
  t_j = B (b_j / d_j^2)^(1/3) / sqrt(sum_k d_k^2 (b_k / d_k^2)^(2/3)), by worst case
  t_j = B sqrt(b_j / |d_j|) / sum_k sqrt(b_k |d_k|) (Lagrange's conditions, closed forms).

Units: tolerances and deviations in internal units (mm, rad), metrics in their own (mm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..engine.errors import OptionError
from ..engine.machine import Machine
from ..engine.sensitivity import sensitivities
from ..sewing.gradients import METRICS, Gradient, metric_values, require_a_stitch
from ..sewing.samples import WINDOWED, sample_feed_values
from .tolerance_file import ToleranceSpec, costs_of, tolerances_of


@dataclass(frozen=True)
class ToleranceResult:
    """What :func:`tolerance_analysis` found. ``deviations`` holds the Monte Carlo samples'
    deviations from the nominal value (for plots); ``allocation`` the allocated tolerances
    (parameter -> +- internal units) when a band was given."""

    metric: str
    unit: str
    value: float
    distribution: str
    names: tuple[str, ...]
    units: tuple[str, ...]
    tolerance: np.ndarray
    derivative: np.ndarray
    worst_case: float
    rss: float
    monte_carlo: dict
    contributions: dict
    deviations: np.ndarray = field(repr=False)
    allocation: dict | None = None
    allocation_rule: str | None = None
    band: float | None = None

    @property
    def sigma_divisor(self) -> tuple[float, str]:
        """What divides the RSS to give the metric's standard deviation to first order, and its
        name: 3 for normal dimensions (a tolerance is 3 sigma), sqrt(3) for uniform ones (the
        standard deviation of a uniform distribution over +-t is t / sqrt(3))."""
        return (3.0, "3") if self.distribution == "normal" else (math.sqrt(3.0), "sqrt(3)")

    @property
    def sigma(self) -> float:
        """The metric's standard deviation to first order, RSS / :attr:`sigma_divisor`: what the
        Monte Carlo's ``std`` should come close to where the metric is near linear."""
        return self.rss / self.sigma_divisor[0]

    def to_json(self) -> dict:
        return {"metric": self.metric, "unit": self.unit, "value": self.value,
                "distribution": self.distribution, "worst_case": self.worst_case,
                "rss": self.rss, "sigma": self.sigma, "monte_carlo": self.monte_carlo,
                "contributions": self.contributions,
                "tolerances": {n: float(t) for n, t in zip(self.names, self.tolerance)},
                "derivatives": {n: float(d) for n, d in zip(self.names, self.derivative)},
                "band": self.band, "allocation": self.allocation,
                "allocation_rule": self.allocation_rule}


#: the half-width of an allocation band, in the output's unit (mm, deg or rad): a nanometre
#: (or 1e-6 deg) to a metre, beyond which no dimension of a sewing machine is allocated
BAND_RANGE = (1e-6, 1e3)

#: the metrics read off the feed (they need a regulator setting)
FEED = ("stitch_length", "feed_lift", "dog_height_at_needle_plate")


def metric_gradient(machine: Machine, metric: str, *, regulator_deg: float | None = None,
                    phi_deg: float = 0.0, at: str | None = None
                    ) -> tuple[float, np.ndarray, str]:
    """A metric (a key of :data:`sewmech.sewing.gradients.METRICS`, a metric over the turn or
    a transmission angle of :mod:`sewmech.design.metrics`, a force metric with its exact
    derivative) or a channel at ``phi_deg`` or at the event ``at``: its value, its derivatives
    by every parameter and its unit. A metric that is degenerate at the setting (a stitch of
    round-off length at the zero mark) is refused
    (:func:`sewmech.sewing.gradients.require_a_stitch`), as is a value-only metric (the force
    metrics until their exact derivatives land, the cam pressure angle)."""
    value, d, unit, _ = _gradient(machine, metric, regulator_deg, phi_deg, at=at)
    return value, d, unit


def is_family_metric(metric: str) -> bool:
    """A metric of :mod:`sewmech.design.metrics` or of the force analysis (a name with its
    family: ``max:p_C_y``, ``transmission_angle_min:dyad``, ``peak_torque``)."""
    from . import metrics as km
    from ._dynamic_metrics import is_dynamic

    return km.is_kinematic_family(metric) or is_dynamic(metric)


def family_ref(machine: Machine, metric: str, regulator_deg: float | None, phi_deg: float,
               at: str | None, option: str = "--output"):
    """A metric reference (as a problem file's) for a family metric or a channel at an event,
    checked against the machine: an OptionError at ``option`` (or ``--at``) otherwise."""
    from ..engine.kinematics import kinematics
    from . import metrics as km
    from ._dynamic_metrics import check_name as check_dynamic
    from ._models import MetricRef

    channels = kinematics(machine, [0.0], on_failure="mask").channel_names()
    try:
        if at is not None:
            if metric not in channels:
                raise km.MetricNameError(f"{metric}: only a channel is read at an event",
                                         "Give a channel, or leave out --at")
            km.check_event(machine, at, channels)
            km.check_read_at_event(metric)
        elif not (km.check_name(machine, metric, channels) or check_dynamic(machine, metric)):
            raise km.MetricNameError(f"unknown metric '{metric}'")
    except km.MetricNameError as exc:
        raise OptionError("--at" if at is not None else option, exc.what, exc.hint) from None
    return MetricRef(metric=metric, regulator_deg=regulator_deg, phi_deg=phi_deg, at=at)


def _gradient(machine: Machine, metric: str, regulator_deg: float | None, phi_deg: float,
              option: str = "regulator_deg", give: str = "regulator_deg={deg:g}",
              working_deg: float | None = None, at: str | None = None
              ) -> tuple[float, np.ndarray, str, Gradient | None]:
    """:func:`metric_gradient` and the metric's :class:`Gradient` (its events; None for a
    channel or a family metric); ``option``, ``give`` and ``working_deg`` name the setting in
    a refusal (:func:`~sewmech.sewing.gradients.require_a_stitch`)."""
    if at is not None or is_family_metric(metric):
        from .evaluate import metric_value
        from .problem import metric_unit

        ref = family_ref(machine, metric, regulator_deg, phi_deg, at)
        mv = metric_value(machine, ref, np.asarray(machine.defaults, dtype=float))
        if mv.d is None:
            raise OptionError("--output", f"{metric} has no exact derivative yet (value only:"
                              " the force metrics' derivatives come with the derivative of the"
                              " force solve)", "Choose a kinematic metric or a channel")
        return mv.value, mv.d, metric_unit(machine, metric), None
    if metric in METRICS:
        reg = _setting(machine, regulator_deg) if metric in FEED else None
        g = METRICS[metric](machine, reg)
        if reg is not None:
            require_a_stitch(machine, metric, g.value, reg, option=option, give=give,
                             working_deg=working_deg)
        return g.value, g.d_dparam, g.unit, g
    inputs = _inputs(machine, regulator_deg)
    try:
        S = sensitivities(machine, np.radians([phi_deg]), inputs=inputs, outputs=[metric])
        v, d, unit = S.channel(metric)
    except KeyError as exc:
        raise OptionError("--output", exc.args[0], "Metrics: " + ", ".join(METRICS)) from None
    return float(v[0]), d[0], unit, None


def _setting(machine: Machine, regulator_deg: float | None) -> float:
    s = machine.spec.sewing
    if s is None or s.regulator is None:
        raise OptionError("--output", f"machine '{machine.name}' has no stitch regulator in"
                          " its [sewing] table", "Choose a position channel")
    return machine.spec.inputs[s.regulator].default_deg if regulator_deg is None \
        else float(regulator_deg)


def _inputs(machine: Machine, regulator_deg: float | None):
    s = machine.spec.sewing
    if regulator_deg is None or s is None or s.regulator is None:
        return None
    return {s.regulator: math.radians(regulator_deg)}


#: the shaft-angle grid of the Monte Carlo's other metrics, deg: their events on it are within
#: 1.5e-5 mm of the located ones on JB1-3 (docs/accuracy.md), and the nominal design is computed
#: on the same grid, so that the deviations keep no bias of it
MC_STEP_DEG = 5.0


def sample_values(machine: Machine, metric: str, P: np.ndarray, *,
                  regulator_deg: float | None = None, phi_deg: float = 0.0,
                  nominal: Gradient | None = None, at: str | None = None
                  ) -> tuple[np.ndarray, dict]:
    """The metric for a batch of designs ``P`` (n, n_params; row 0 the nominal design) and
    how it was evaluated. The feed metrics, given their ``nominal`` :class:`Gradient`, in
    windows around its events (:mod:`sewmech.sewing.samples`); the other sewing metrics in one
    batch call on a ``MC_STEP_DEG`` grid; a metric over the turn or a transmission angle on its
    batches' 1 deg grid (:mod:`sewmech.design.metrics`); a channel at ``phi_deg`` or at the
    event ``at``."""
    if at is not None or is_family_metric(metric):
        from ._dynamic_metrics import is_dynamic
        from ._models import ref_key
        from .evaluate import metric_batch

        ref = family_ref(machine, metric, regulator_deg, phi_deg, at)
        vals, _ = metric_batch(machine, [ref], P, np.ones(len(P), dtype=bool))
        return vals[ref_key(ref)], {"grid_deg": 2.0 if is_dynamic(metric) else 1.0}
    if metric in WINDOWED and nominal is not None:
        return sample_feed_values(machine, metric, _setting(machine, regulator_deg), P, nominal)
    if metric in METRICS:
        return metric_values(machine, metric, _setting(machine, regulator_deg) if metric in FEED
                             else None, P, step_deg=MC_STEP_DEG), {"grid_deg": MC_STEP_DEG}
    from ..engine.kinematics import kinematics

    r = kinematics(machine, np.radians([phi_deg]), params=P,
                   inputs=_inputs(machine, regulator_deg), on_failure="mask")
    return r.channel(metric)[0][..., 0], {}


def tolerance_analysis(machine: Machine, metric: str, spec: ToleranceSpec | None = None, *,
                       regulator_deg: float | None = None, phi_deg: float = 0.0,
                       samples: int = 10_000, seed: int = 0, band: float | None = None,
                       where: str = "tolerances", option: str = "regulator_deg",
                       give: str = "regulator_deg={deg:g}",
                       working_deg: float | None = None, at: str | None = None
                       ) -> ToleranceResult:
    """Worst case, RSS, Monte Carlo (``samples`` designs, ``seed``), contributions and, with
    ``band`` (+- in the metric's unit), the allocated tolerances, for ``metric`` under the
    tolerances of ``spec`` (default: IT9 on every length, see
    :func:`sewmech.design.tolerance_file.tolerances_of`), at ``regulator_deg`` (default: the
    machine's working setting). A metric that is degenerate at the setting (a stitch of
    round-off length) is refused, naming ``option`` and a setting in ``give``'s form (the
    working setting ``working_deg``, default the machine file's)."""
    if not (isinstance(samples, int) and 100 <= samples <= 1_000_000):
        raise OptionError("--samples", f"must be a whole number in 100 .. 1000000, got"
                          f" {samples!r}", "Give e.g. --samples 10000")
    if band is not None and not BAND_RANGE[0] <= band <= BAND_RANGE[1]:  # (a NaN fails too)
        raise OptionError("--band", f"must be in {BAND_RANGE[0]:g} .. {BAND_RANGE[1]:g} (the"
                          f" output's unit: mm, deg or rad), got {band!r}",
                          "Give the half-width of the band the output must stay in, e.g."
                          " --band 0.05")
    from .optimize import check_seed

    check_seed(seed)
    tol = tolerances_of(machine, spec, where)
    dist = (spec or ToleranceSpec()).defaults.distribution
    value, d, unit, nominal = _gradient(machine, metric, regulator_deg, phi_deg, option, give,
                                        working_deg, at)
    on = tol > 0
    contrib = (d * tol) ** 2
    rss = float(np.sqrt(contrib.sum()))
    worst = float(np.sum(np.abs(d) * tol))
    names = tuple(n for n, o in zip(machine.parameter_names, on) if o)
    units = tuple(u for u, o in zip(machine.parameter_units, on) if o)
    shares = {machine.parameter_names[j]: float(contrib[j] / rss ** 2)
              for j in np.argsort(-contrib) if on[j] and rss > 0}
    # Monte Carlo: deviations within the tolerances, one batch call
    rng = np.random.default_rng(seed)
    t = tol[on]
    if dist == "normal":
        dev = rng.standard_normal(size=(samples, t.size))
        dev *= t / 3.0
    else:
        dev = rng.random(size=(samples, t.size))
        dev *= 2.0 * t
        dev -= t
    # row 0: the nominal design (at the setting), evaluated the same way
    base = machine.parameters(inputs=_inputs(machine, regulator_deg)) \
        if _inputs(machine, regulator_deg) else np.asarray(machine.defaults, dtype=float)
    P = np.empty((samples + 1, base.size))
    P[:] = base
    P[1:, np.flatnonzero(on)] += dev
    vals, how = sample_values(machine, metric, P, regulator_deg=regulator_deg,
                              phi_deg=phi_deg, nominal=nominal, at=at)
    ok = np.isfinite(vals[1:])
    dv = vals[1:][ok] - vals[0]
    n_ok = int(ok.sum())

    def stat(f, need: int) -> float | None:  # None where too few designs give the metric
        return float(f(dv)) if n_ok >= need else None

    mc = {"n": int(samples), "assembled": n_ok, "mean": stat(np.mean, 1),
          "std": stat(lambda a: np.std(a, ddof=1), 2),
          "p99": stat(lambda a: np.quantile(np.abs(a), 0.99), 1),
          "min": stat(np.min, 1), "max": stat(np.max, 1), "seed": int(seed),
          "evaluation": how}
    if n_ok < 2:  # JSON has no NaN: null, and why beside it
        mc["note"] = (f"{'no design' if n_ok == 0 else 'only one design'} of the {samples}"
                      " drawn assembles and gives the metric, so the figures that need"
                      f" {'one' if n_ok == 0 else 'two'} are not defined (the tolerances are"
                      " wider than the mechanism can be made within)")
    alloc = rule = None
    if band is not None:
        alloc, rule = allocate(machine, d, costs_of(machine, spec), on, band, dist)
    return ToleranceResult(metric, unit, value, dist, names, units, t, d[on], worst, rss, mc,
                           shares, dv, alloc, rule, band)


def allocate(machine: Machine, d: np.ndarray, b: np.ndarray, on: np.ndarray, band: float,
             distribution: str) -> tuple[dict, str]:
    """The tolerances (+-, internal units) of least cost sum b_j / t_j over the parameters
    ``on`` that keep the metric within +-``band``: by RSS for normally distributed
    dimensions, by worst case for uniform ones. Parameters that do not move the metric are
    left out (any tolerance serves)."""
    # a derivative at round-off of the largest one does not move the metric
    act = on & (np.abs(d) > 1e-9 * np.abs(d).max()) & (b > 0.0)
    out = {}
    if distribution == "normal":
        w = (b[act] / d[act] ** 2) ** (1.0 / 3.0)
        t = band * w / math.sqrt(float(np.sum(d[act] ** 2 * w ** 2)))
        rule = "RSS"
    else:
        w = np.sqrt(b[act] / np.abs(d[act]))
        t = band * w / float(np.sum(np.sqrt(b[act] * np.abs(d[act]))))
        rule = "worst case"
    for j, tj in zip(np.nonzero(act)[0], t):
        out[machine.parameter_names[j]] = float(tj)
    return out, rule
