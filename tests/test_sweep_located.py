"""Issue 34, item 1: a sweep design evaluated at a fraction of the positions with the answers
of the whole grid: the assembly decided on a 10 deg grid (with the 1 deg grid where that
cannot decide) equals the 1 deg grid's answer; the feed metrics located by Newton's method
from predicted events equal their values from each design's whole turn and from an
independent root finder (Brent's method on the kinematics), and are closer to them than the
1 deg grid's interpolated values they replace."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from sewmech import load_machine
from sewmech.design import sweep as sw
from sewmech.design._dynamic_metrics import is_dynamic
from sewmech.design._models import ref_key
from sewmech.design.evaluate import (
    ASSEMBLY_CLEARANCE_MM,
    AssemblyCounts,
    assembles_batch,
    assembles_on_grid,
    metric_batch,
)
from sewmech.design.sweep_file import load_sweep
from sewmech.engine.kinematics import kinematics
from sewmech.sewing.feed import _roles, feed_cycles
from sewmech.sewing.samples import whole_turn_values

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "examples" / "sweeps" / "jb-feed.toml"
FOURBAR = ROOT / "examples" / "machines" / "fourbar-20-80.toml"


@pytest.fixture(scope="module")
def shipped():
    return load_sweep(SHIPPED)


def _perturbed(machine, rel: float, n: int, seed: int) -> np.ndarray:
    """n designs with every dimension (not the speed ratios or the setting inputs) moved by a
    normal relative error of ``rel``."""
    base = np.asarray(machine.defaults, dtype=float)
    scale = np.array([0.0 if ("ratio" in p or p.startswith("input.")) else rel
                      for p in machine.parameter_names])
    rng = np.random.default_rng(seed)
    return base * (1.0 + rng.normal(0.0, 1.0, (n, len(base))) * scale)


def test_the_located_assembly_is_the_whole_grid_s_on_the_shipped_sweep(shipped):
    P = sw.params_of(shipped, sw.sample(shipped, 0, 300))
    counts = AssemblyCounts()
    got = assembles_batch(shipped.machine, P, counts=counts)
    assert np.array_equal(got, assembles_on_grid(shipped.machine, P))
    assert counts.coarse == 300 and counts.whole_grid == 0  # the coarse grid decided all


@pytest.mark.parametrize("name, rel", [("jb1-3", 0.01), ("jb8-2", 0.01),
                                       (str(FOURBAR), 0.08)])
def test_the_located_assembly_is_the_whole_grid_s_on_designs_that_jam(name, rel):
    """Dimensions moved at random: most JB designs jam (their cams' arcs no longer join, and
    where their loop units fail depends on the solver's steps: the whole grid decides those),
    some four-bars cannot close; every answer is the whole grid's, and both ways are taken."""
    m = load_machine(name)
    P = _perturbed(m, rel, 400, seed=3)
    counts = AssemblyCounts()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        got = assembles_batch(m, P, counts=counts)
    want = assembles_on_grid(m, P)
    assert np.array_equal(got, want), np.nonzero(got != want)[0]
    assert counts.coarse + counts.whole_grid == 400
    assert counts.coarse > 0
    if name != str(FOURBAR):
        assert counts.whole_grid > 0 and 0 < want.sum() < 400


def test_a_margin_that_dips_below_the_clearance_between_coarse_angles_goes_to_the_grid():
    """The four-bar's dyad stretched nearly straight at 175 deg (its crank's phase moved 5 deg:
    halfway between two coarse angles), with 0.5 um more and less room than the clearance
    there: at the coarse angles 170 and 180 deg the margin is 0.04 mm, so only the whole
    grid tells the two apart."""
    m = load_machine(FOURBAR)
    names = m.parameter_names
    P = np.tile(np.asarray(m.defaults, dtype=float), (2, 1))
    P[:, names.index("crank.phase")] = math.radians(5.0)
    # |B D| is largest (20 + 80 = 100 mm) where the crank points away from D: phi = 175 deg
    for k, room in enumerate((ASSEMBLY_CLEARANCE_MM + 5e-4, ASSEMBLY_CLEARANCE_MM - 5e-4)):
        P[k, names.index("dyad.length1")] = 50.0
        P[k, names.index("dyad.length2")] = 50.0 + room
    counts = AssemblyCounts()
    got = assembles_batch(m, P, counts=counts)
    assert list(got) == [True, False] == list(assembles_on_grid(m, P))
    assert counts.whole_grid == 2


def _exact_stitch(machine, p: np.ndarray, regulator_deg: float) -> float:
    """The stitch length (mm) by Brent's method on the kinematics: the dog's tip crossing the
    plate going up and going down, bracketed on a 1 deg grid; the loop units solved to 1e-13
    mm (their default 1e-10 moves the tip by up to about 1e-9 mm on these designs)."""
    s = _roles(machine)

    def at(phi):
        r = kinematics(machine, [phi], params=p,
                       inputs={s.regulator: math.radians(regulator_deg)}, tol=1e-13)
        return r.point(s.feed_dog).p[0]

    grid = np.radians(np.arange(361.0))
    y = np.array([at(g)[1] - s.plate_y for g in grid])
    xs = {}
    for i in np.nonzero(np.sign(y[:-1]) != np.sign(y[1:]))[0]:
        root = brentq(lambda g: at(g)[1] - s.plate_y, grid[i], grid[i + 1], xtol=1e-14)
        xs["up" if y[i + 1] > y[i] else "down"] = at(root)[0]
    fwd = 1.0 if s.forward == "+x" else -1.0
    return fwd * (xs["down"] - xs["up"])


def test_located_feed_metrics_are_exact_and_the_feasible_set_is_the_grid_s(shipped):
    """A 1,000-design slice of the shipped sweep: each feed metric located from predicted
    events equals its value located from the design's whole turn to 1e-9 mm; the grid
    evaluation's values (the 1 deg grid's interpolant, its stitch lengths located on the exact
    kinematics by feed_cycles) agree with them to within the interpolant's error, and the
    feasible set is the grid's but for designs within that of a limit. On the three designs
    where the interpolant's stitch length is farthest off, the located values and feed_cycles'
    equal Brent's roots on the kinematics to 1e-9 mm, and the interpolant alone is more than
    1e-7 mm off."""
    n = 1000
    c = sw.evaluate_chunk(shipped, 0, n)
    P = sw.params_of(shipped, sw.sample(shipped, 0, n))
    m = shipped.machine
    kin = [o for o in shipped.spec.outputs if not is_dynamic(o.metric)]
    assert c.counts["feed_located"] + c.counts["feed_whole_turn"] == len(kin) * n
    assert c.counts["feed_located"] >= 0.95 * len(kin) * n  # the predictions do their work
    assert c.counts["feed_checked"] == len(kin) * len(range(0, n, sw.CHECK_EVERY))
    rows = np.arange(0, n, 5)
    old, ok = metric_batch(m, kin, P)
    assert np.array_equal(ok, c.columns["assembles"])
    near_limit = np.zeros(n, dtype=bool)
    for o in kin:
        got = c.columns[o.column]
        reg = o.regulator_deg
        turn = whole_turn_values(m, o.metric, reg, P[rows])
        np.testing.assert_allclose(got[rows], turn, rtol=0, atol=1e-9, err_msg=o.column)
        grid = old[ref_key(o)]
        assert np.nanmax(np.abs(got - grid)) <= 5e-5, o.column
        for lim in (o.min, o.max):
            if lim is not None:
                near_limit |= np.abs(grid - lim) <= 5e-5
    first = kin[0]
    assert first.metric == "stitch_length"
    interp = feed_cycles(m, first.regulator_deg, params=P, on_failure="mask",
                         exact=False).stitch_mm
    worst = np.argsort(-np.abs(c.columns[first.column] - interp))[:3]
    for k in worst:  # the designs where the interpolant alone is farthest off
        exact = _exact_stitch(m, P[k], first.regulator_deg)
        assert abs(c.columns[first.column][k] - exact) <= 1e-9
        assert abs(old[ref_key(first)][k] - exact) <= 1e-9  # (feed_cycles, located)
        assert abs(interp[k] - exact) > 1e-7  # (the interpolant's error is real)
    feasible_grid = ok.copy()
    for o in kin:
        v = old[ref_key(o)]
        with np.errstate(invalid="ignore"):
            feasible_grid &= np.isfinite(v) & (v >= (o.min if o.min is not None else -np.inf)) \
                & (v <= (o.max if o.max is not None else np.inf))
    differ = feasible_grid != c.columns["feasible"]
    assert not (differ & ~near_limit).any()
    assert 0 < c.columns["feasible"].sum() < n  # (the limits select)


def test_a_stitch_the_predictions_miss_is_found_on_the_one_degree_turn(shipped):
    """Design 51266 of the shipped sweep feeds 0.12 mm at regulator 30 deg: its dog is above
    the plate for under 5 deg, so Newton's steps from the predicted events do not settle and a
    5 deg turn would not see the stitch either. The design is located from its 1 deg turn,
    as the grid evaluation saw it, whatever its chunk."""
    from sewmech.sewing.gradients import metric_values

    o = next(o for o in shipped.spec.outputs
             if o.metric == "stitch_length" and o.regulator_deg == 30.0)
    d = 51266
    for a, b in ((d, d + 1), (d - 3, d + 5)):
        P = sw.params_of(shipped, sw.sample(shipped, a, b))
        counts = dict.fromkeys(sw.COUNTS, 0)
        got = sw._feed_values(shipped, o, P, np.ones(len(P), dtype=bool), a, counts)[d - a]
        assert counts["feed_whole_turn"] >= 1
        grid = metric_values(shipped.machine, "stitch_length", 30.0, P[d - a:d - a + 1])[0]
        assert 0.1 < got < 0.15 and abs(got - grid) <= 1e-6
        assert abs(got - whole_turn_values(shipped.machine, "stitch_length", 30.0,
                                           P[d - a:d - a + 1], 1.0)[0]) <= 1e-12


def test_the_units_no_design_of_the_batch_changes_are_checked_once(monkeypatch):
    """A batch that varies the feed's dimensions alone: the conditions of the units no design
    changes (the needle bar's, the take-up's, the hook's) are evaluated for its first design
    only, and the answers are the whole grid's; with the take-up too short to close in every
    design, every design fails, as on the whole grid."""
    from sewmech.design import evaluate as ev
    from sewmech.engine.margins import conditions

    m = load_machine("jb1-3")
    P = np.repeat(m.defaults[None], 6, axis=0)
    P[:, m.parameter_names.index("feed_fork.slot.1.length")] = np.linspace(14.0, 18.0, 6)
    n_cond = len(conditions(m, np.asarray(m.defaults)))
    calls = []
    real = ev._coarse

    def spy(machine, Q, which, looped, *rest):
        calls.append((len(Q), int(which.sum()), len(looped)))
        return real(machine, Q, which, looped, *rest)

    monkeypatch.setattr(ev, "_coarse", spy)
    got = assembles_batch(m, P)
    assert np.array_equal(got, assembles_on_grid(m, P)) and got.all()
    shared = [(w, lp) for n, w, lp in calls if n == 1]
    own = [(w, lp) for n, w, lp in calls if n == 6]
    # (the fork hangs on a loop unit: the points on it, not a closed-form unit's margins,
    # are what the designs change)
    assert shared and own and shared[0][0] + own[0][0] == n_cond and shared[0][0] > 0
    assert own[0][1] > 0
    P[:, m.parameter_names.index("take_up.length1")] *= 0.5
    got = assembles_batch(m, P)
    want = assembles_on_grid(m, P)
    assert np.array_equal(got, want) and not want.any()
