"""Design sweeps, the numeric part: the designs of a sweep file (a grid or a seeded random,
Latin-hypercube or Sobol sample) and the evaluation of a chunk of them in batch calls.

A sweep is split into chunks of consecutive designs, design ``i`` always the same whatever the
chunk size or the worker: :func:`sample` draws designs ``start .. stop`` alone (a Sobol sample
fast-forwarded to ``start``, random designs from seeded blocks of :data:`BLOCK`, a Latin
hypercube drawn whole and sliced, a grid by unravelling the index). :func:`evaluate_chunk`
evaluates one chunk: the whole-turn assembly decided on a coarse grid
(:func:`sewmech.design.evaluate.assembles_batch`), the feed metrics located by Newton's method
from the events of the sweep's centre design (:func:`sewmech.sewing.samples.
sample_feed_values`), the other metrics with the batch calls the optimisers use
(:func:`sewmech.design.evaluate.metric_batch`), the force metrics with one
:class:`~sewmech.dynamics.DynamicsPlan` call, the curves with one kinematics call; the answers
are those of the whole 1 deg grid (docs/sweeps.md, "How a design is evaluated"). Running chunks on Dask and writing them is the app's
(:mod:`sewmech.app.sweep_run`); nothing here reads or writes files.

Columns: ``design`` (the index), every parameter in its file unit (mm; deg for an angle, its
column named ``NAME_deg``), ``assembles``
(the mechanism assembles at every whole degree of the turn at both ends of every setting
input, every closed-form unit at least 0.01 mm from failing there, which keeps it assembled
between the degrees too), every output (its unit: mm, deg for ``*_deg`` metrics, N m, N; NaN where the design
cannot be evaluated) and ``feasible`` (it assembles and every output is a number within its
limits). A NaN is never feasible.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .sweep_file import Sweep

#: random designs are drawn in blocks of this many, each from its own seed (seed, block)
BLOCK = 4096


def sample(sweep: Sweep, start: int, stop: int) -> np.ndarray:
    """Designs ``start .. stop - 1`` of the sweep, (stop - start, n_parameters), in the
    parameters' file units (mm, deg)."""
    spec = sweep.spec
    n = sweep.n_designs
    if not 0 <= start <= stop <= n:
        raise ValueError(f"designs {start} .. {stop} are outside the sweep's 0 .. {n}")
    lo = np.array([p.lower for p in spec.parameters])
    hi = np.array([p.upper for p in spec.parameters])
    d = len(lo)
    method, seed = spec.sampling.method, spec.sampling.seed
    if method == "grid":
        shape = tuple(p.points for p in spec.parameters)
        idx = np.unravel_index(np.arange(start, stop, dtype=np.int64), shape)
        return np.column_stack([np.linspace(p.lower, p.upper, p.points)[i]
                                for p, i in zip(spec.parameters, idx)]).reshape(-1, d)
    if method == "sobol":
        from scipy.stats import qmc

        engine = qmc.Sobol(d, scramble=True, rng=np.random.default_rng(seed))
        if start:  # (fast_forward(0) overflows in scipy)
            engine.fast_forward(start)
        with warnings.catch_warnings():  # (balance needs n a power of 2: documented)
            warnings.simplefilter("ignore", UserWarning)
            u = engine.random(stop - start)
    elif method == "lhs":
        u = _latin_hypercube(d, n, seed)[start:stop]
    else:
        u = np.empty((stop - start, d))
        for b in range(start // BLOCK, (stop - 1) // BLOCK + 1 if stop > start else 0):
            block = np.random.default_rng([seed, b]).random((BLOCK, d))
            a0, a1 = max(start, b * BLOCK), min(stop, (b + 1) * BLOCK)
            u[a0 - start:a1 - start] = block[a0 - b * BLOCK:a1 - b * BLOCK]
    return lo + u * (hi - lo)


@functools.lru_cache(maxsize=2)
def _latin_hypercube(d: int, n: int, seed: int) -> np.ndarray:
    from scipy.stats import qmc

    u = qmc.LatinHypercube(d, rng=np.random.default_rng(seed)).random(n)
    u.setflags(write=False)
    return u


def params_of(sweep: Sweep, X: np.ndarray) -> np.ndarray:
    """Parameter vectors (m, n_machine_parameters; internal units) of designs X (file units):
    the machine's values with the sweep's parameters replaced."""
    m = sweep.machine
    P = np.tile(np.asarray(m.defaults, dtype=float), (len(X), 1))
    P[:, sweep.index] = np.asarray(X, dtype=float) * np.asarray(sweep.factor)
    return P


@dataclass
class Chunk:
    """One evaluated chunk: ``columns`` (name -> (m,) array, in :func:`column_units` order),
    ``curves`` (channel -> (m, n_phi) array at the curves' angles) and ``counts``: how the
    designs were evaluated (:data:`COUNTS`: designs whose assembly the coarse grid decided or
    the whole 1 deg grid did; feed-metric values located from predicted events or from a
    whole turn, and how many of those were checks)."""

    start: int
    columns: dict[str, np.ndarray]
    curves: dict[str, np.ndarray]
    counts: dict[str, int] = field(default_factory=dict)


#: what :attr:`Chunk.counts` holds (added over the chunks by the runner)
COUNTS = ("assembly_coarse", "assembly_whole_grid", "feed_located", "feed_whole_turn",
          "feed_checked")
#: every this many-th design of the sweep (by its index) has its located feed metrics
#: compared with their values from its whole turn (:func:`sewmech.sewing.samples.
#: sample_feed_values`; a difference over 1e-9 mm redoes the chunk's designs from their turns)
CHECK_EVERY = 16


def column_units(sweep: Sweep) -> dict[str, str]:
    """Every column of the sweep's table with its unit, in order."""
    from ..sewing.gradients import METRICS
    from . import metrics as km
    from ._dynamic_metrics import is_dynamic
    from ._dynamic_metrics import unit_of as dynamic_unit

    out = {"design": "", **dict(zip(sweep.columns, sweep.units, strict=True)), "assembles": ""}
    ch_units = {"p": "mm", "v": "mm/s", "a": "mm/s^2", "theta": "rad", "omega": "rad/s",
                "epsilon": "rad/s^2"}
    for o in sweep.spec.outputs:
        name = o.metric
        if is_dynamic(name):
            unit = dynamic_unit(name)
        elif name in METRICS:
            unit = "deg" if name.endswith("_deg") else "mm"
        elif km.is_kinematic_family(name) and not name.startswith("range:"):
            unit = km.unit_of(sweep.machine, name)
        else:
            channel = name.split(":", 1)[-1]
            kind = channel.split("_")[0]
            unit = ch_units.get(kind)
            if unit is None:  # a joint variable: its own unit
                var = channel.split("_", 1)[1]
                m = sweep.machine
                unit = m.variable_units[m.variable_names.index(var)]
        out[o.column] = unit
    out["feasible"] = ""
    return out


def curve_phi_deg(sweep: Sweep) -> np.ndarray:
    """The angles of the curves, deg (one turn in the curves' step)."""
    c = sweep.spec.curves
    if c is None:
        return np.zeros(0)
    return np.arange(round(360.0 / c.step_deg)) * c.step_deg


def evaluate_chunk(sweep: Sweep, start: int, stop: int) -> Chunk:
    """Designs ``start .. stop - 1`` evaluated in batch calls (see the module doc)."""
    from ._dynamic_metrics import is_dynamic
    from ._models import ref_key
    from .evaluate import AssemblyCounts, assembles_batch, metric_batch

    spec = sweep.spec
    X = sample(sweep, start, stop)
    P = params_of(sweep, X)
    asm = AssemblyCounts()
    ok = assembles_batch(sweep.machine, P, counts=asm)
    counts = dict.fromkeys(COUNTS, 0)
    counts.update(assembly_coarse=asm.coarse, assembly_whole_grid=asm.whole_grid)
    kin_outputs = [o for o in spec.outputs if not is_dynamic(o.metric)]
    located = [o for o in kin_outputs if _located(sweep, o)]
    values, _ = metric_batch(sweep.machine, [o for o in kin_outputs if o not in located], P, ok)
    for o in located:
        values[ref_key(o)] = _feed_values(sweep, o, P, ok, start, counts)
    dyn = _dynamics(sweep, P, ok) if spec.dynamics is not None else {}
    cols: dict[str, np.ndarray] = {"design": np.arange(start, stop, dtype=np.int64)}
    for j, name in enumerate(sweep.columns):
        cols[name] = X[:, j].copy()
    cols["assembles"] = ok
    feasible = ok.copy()
    for o in spec.outputs:
        v = dyn[o.metric] if is_dynamic(o.metric) else values[ref_key(o)]
        v = np.asarray(v, dtype=float).copy()
        cols[o.column] = v
        with np.errstate(invalid="ignore"):
            feasible &= np.isfinite(v)
            if o.min is not None:
                feasible &= v >= o.min
            if o.max is not None:
                feasible &= v <= o.max
    cols["feasible"] = feasible
    curves = _curves(sweep, P) if spec.curves is not None else {}
    return Chunk(start, cols, curves, counts)


def _located(sweep: Sweep, o) -> bool:
    """Whether output ``o`` is a feed metric whose events are located by Newton's method
    (:mod:`sewmech.sewing.samples`): the stitch length, the lift and the dog's height when the
    needle reaches the plate, at a regulator setting, of a machine with a stitch regulator."""
    from ..sewing.samples import WINDOWED

    s = sweep.machine.spec.sewing
    return (o.metric in WINDOWED and getattr(o, "at", None) is None and s is not None
            and s.regulator is not None)


def _feed_values(sweep: Sweep, o, P: np.ndarray, ok: np.ndarray, start: int,
                 counts: dict) -> np.ndarray:
    """A feed metric (mm) of the designs that assemble, each event located by Newton's method
    from where the sweep's centre design has it moved by the event's derivative, with the
    guards of :func:`sewmech.sewing.samples.sample_feed_values` (a design not located there is
    located from its whole turn, on the 1 deg grid the grid evaluation used where a 5 deg
    turn shows no event, so that an event the grid saw is seen; every :data:`CHECK_EVERY`-th
    design is compared with its value from its whole turn, in the same call); NaN for the
    others."""
    from ..sewing.samples import sample_feed_values

    reg = _regulator_deg(sweep, o)
    out = np.full(len(P), np.nan)
    rows = np.nonzero(ok)[0]
    if rows.size == 0:
        return out
    nominal = _nominal(sweep, o.metric, reg)
    design = start + rows
    check = np.nonzero(design % CHECK_EVERY == 0)[0]
    if nominal is None:  # (the centre's events unknown: every design from its turn)
        from ..sewing.samples import whole_turn_values

        out[rows] = whole_turn_values(sweep.machine, o.metric, reg, P[rows], 1.0)
        counts["feed_whole_turn"] += int(rows.size)
        return out
    grad, base = nominal
    vals, how = sample_feed_values(sweep.machine, o.metric, reg, P[rows], grad, check=check,
                                   base=base, fine_step_deg=1.0)
    out[rows] = vals
    counts["feed_located"] += how["located"]
    counts["feed_whole_turn"] += how["whole_turn"]
    counts["feed_checked"] += how["checked"]
    return out


def _regulator_deg(sweep: Sweep, o) -> float:
    if o.regulator_deg is not None:
        return float(o.regulator_deg)
    m = sweep.machine
    return float(m.spec.inputs[m.spec.sewing.regulator].default_deg)


def _nominal(sweep: Sweep, metric: str, regulator_deg: float):
    """The feed metric's :class:`~sewmech.sewing.gradients.Gradient` (its events and their
    derivatives) at the centre of the sweep's box (or, where that cannot be evaluated, the
    machine file's design), with that design's parameters, kept with the sweep; None where
    neither can be."""
    from ..engine.errors import SewmechError
    from ..sewing.gradients import METRICS

    cache = sweep.__dict__.setdefault("_nominal_feed", {})
    key = (metric, regulator_deg)
    if key not in cache:
        spec = sweep.spec
        centre = params_of(sweep, np.array([[0.5 * (p.lower + p.upper)
                                             for p in spec.parameters]]))[0]
        cache[key] = None
        for base in (centre, np.asarray(sweep.machine.defaults, dtype=float)):
            try:
                cache[key] = (METRICS[metric](sweep.machine, regulator_deg, params=base), base)
                break
            except SewmechError:
                continue
    return cache[key]


def _dynamics(sweep: Sweep, P: np.ndarray, ok: np.ndarray) -> dict[str, np.ndarray]:
    """Every force metric of the sweep's outputs (peak |driving torque| N m, peak |shaking
    force| N, ...: :mod:`sewmech.design._dynamic_metrics`), at the machine's working setting
    and the sweep's speed, the machine's loads and masses, one DynamicsPlan call for the
    designs that assemble; NaN for those that do not or whose force equations are singular
    somewhere."""
    from ._dynamic_metrics import is_dynamic

    names = sorted({o.metric for o in sweep.spec.outputs if is_dynamic(o.metric)})
    out = {n: np.full(len(P), np.nan) for n in names}
    rows = np.nonzero(ok)[0]
    if rows.size == 0 or not names:
        return out
    got = _force_metrics(sweep).values(names, P[rows])
    for n in names:
        out[n][rows] = got[n]
    return out


def _force_metrics(sweep: Sweep):
    fm = getattr(sweep, "_force_metrics", None)
    if fm is None:
        from ._dynamic_metrics import ForceMetrics

        fm = sweep._force_metrics = ForceMetrics(sweep.machine, sweep.spec.dynamics)
    return fm


def _curves(sweep: Sweep, P: np.ndarray) -> dict[str, np.ndarray]:
    """The curves' channels of every design over a turn (NaN where a position does not
    assemble), at the curves' settings."""
    from ..engine.kinematics import kinematics

    c = sweep.spec.curves
    inputs = {n: math.radians(v) for n, v in c.inputs.items()} or None
    r = kinematics(sweep.machine, np.radians(curve_phi_deg(sweep)), params=P, inputs=inputs,
                   on_failure="mask")
    out = {}
    for ch in c.channels:
        v = np.array(r.channel(ch)[0], dtype=float)
        v[~r.feasible.reshape(v.shape)] = np.nan
        out[ch] = v
    return out


class ChunkBounds(Sequence):
    """(start, stop) of every chunk of ``chunk`` designs (the last one may be shorter), as a
    sequence computed on demand: a sweep of 1e10 designs has 4e7 chunks of 250, whose list
    alone would take 4 GB before any work."""

    def __init__(self, n_designs: int, chunk: int):
        if chunk < 1:
            raise ValueError(f"a chunk holds at least one design, got {chunk}")
        self.n_designs, self.chunk = int(n_designs), int(chunk)

    def __len__(self) -> int:
        return -(-self.n_designs // self.chunk)

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        n = len(self)
        if k < 0:
            k += n
        if not 0 <= k < n:
            raise IndexError(f"chunk {k} of {n}")
        a = k * self.chunk
        return (a, min(a + self.chunk, self.n_designs))

    def designs_in(self, chunks) -> int:
        """How many designs the chunks ``chunks`` (indices) hold."""
        return sum(b - a for a, b in (self[k] for k in chunks if 0 <= k < len(self)))


def chunk_bounds(n_designs: int, chunk: int) -> ChunkBounds:
    """(start, stop) of every chunk of ``chunk`` designs (the last one may be shorter)."""
    return ChunkBounds(n_designs, chunk)


# ---- on workers ---------------------------------------------------------------------------------
#: the sweeps this process has built, by the digest of their texts (a worker builds each once)
_BUILT: dict[str, Sweep] = {}


def texts_of(sweep: Sweep) -> tuple[str, str, str, str]:
    """What a worker needs to rebuild the sweep without reading a file: the sweep file's and
    the machine file's names and texts."""
    return (sweep.text, sweep.file, sweep.machine_text, sweep.machine_file)


def evaluate_texts(texts: tuple[str, str, str, str], start: int, stop: int) -> Chunk:
    """:func:`evaluate_chunk` for a sweep given by its texts (:func:`texts_of`), built once per
    process: a Dask task."""
    return evaluate_chunk(sweep_of_texts(texts), start, stop)


def sweep_of_texts(texts: tuple[str, str, str, str]) -> Sweep:
    """The sweep given by its texts (:func:`texts_of`), built once per process."""
    import hashlib

    key = hashlib.sha256("\0".join(texts).encode("utf-8")).hexdigest()
    sweep = _BUILT.get(key)
    if sweep is None:
        sweep = _BUILT[key] = Sweep.from_texts(*texts)
    return sweep


def prepare_worker() -> None:
    """A worker process's start: one thread per kernel call (each Dask thread runs a chunk on
    its core) and the compiled kernels loaded from numba's cache now rather than in the first
    task."""
    from ..engine._threads import set_threads
    from ..engine.kinematics import kinematics
    from ..engine.machine import load_machine

    set_threads(1)
    m = load_machine("fourbar-benchmark")
    kinematics(m, np.radians(np.arange(0.0, 360.0, 30.0)), on_failure="mask")
