"""Design problems (sewmech.design.problem): a four-bar whose rocker swing has a closed-form
crank length, a constrained one whose optimum sits on its constraint, bad problem files, and
`sewmech optimize`'s JSON keys."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq
from sewmech.cli import app
from typer.testing import CliRunner

import sewmech
from sewmech.design.optimize import optimize
from sewmech.design.problem import Problem, batch_values, load_problem
from sewmech.engine.errors import MachineFileError, OptionError

ROOT = Path(__file__).resolve().parent.parent
SWING = ROOT / "examples" / "problems" / "fourbar-swing.toml"


def closed_form_crank(target: float, b=40.0, c=35.0, d=38.0) -> float:
    """The rocker's extremes are where crank and coupler line up (A to C = b + a or b - a):
    cos t = (d^2 + c^2 - (b +- a)^2) / (2 d c) at the rocker's pivot; the swing is the
    difference of the two angles."""
    def swing(a):
        t1 = math.acos((d * d + c * c - (b + a) ** 2) / (2 * d * c))
        t2 = math.acos((d * d + c * c - (b - a) ** 2) / (2 * d * c))
        return abs(t1 - t2)

    return brentq(lambda a: swing(a) - target, 8.0, 18.0, xtol=1e-14)


@pytest.mark.parametrize("method, tol", [("golden", 1e-5), ("powell", 1e-5), ("cyclic", 1e-5),
                                         ("slsqp", 1e-5), ("de", 1e-6)])
def test_every_method_finds_the_closed_form_crank_length(method, tol):
    spec, m = load_problem(SWING)
    r = optimize(Problem(spec, m), method)
    assert r.status == "success", r.message
    assert r.x[0] == pytest.approx(closed_form_crank(0.9), abs=tol)
    assert r.fun < 1e-10 < r.objective_start


def write(tmp_path, text):
    f = tmp_path / "p.toml"
    f.write_text(text, encoding="utf-8")
    return f


CONSTRAINED = """
[problem]
name = "largest swing with a short crank"
machine = "fourbar-benchmark"
[[variables]]
parameter = "B.u"
lower = 8.0
upper = 18.0
start = 10.0
[objective]
[[objective.parts]]
metric = "range:theta_rocker"
sense = "max"
[[constraints]]
metric = "p_B_x"       # the crank pin at phi = 0 (the crank along +x): the crank's length
phi_deg = 0.0
max = 14.0
"""


@pytest.mark.parametrize("method", ["powell", "cyclic", "slsqp", "de"])
def test_the_optimum_on_a_constraint(tmp_path, method):
    """The swing grows with the crank, so the largest swing with a crank of at most 14 mm is at
    14 mm exactly; the interior penalty approaches it from inside."""
    spec, m = load_problem(write(tmp_path, CONSTRAINED))
    r = optimize(Problem(spec, m), method)
    assert r.status == "success", r.message
    assert r.x[0] == pytest.approx(14.0, abs=2e-4)
    c = r.constraints["p_B_x"]
    assert c["satisfied"] and c["value"] <= 14.0 + 1e-9


@pytest.mark.parametrize("edit, needle", [
    (("B.u", "B.uu"), "Did you mean B.u"),
    (("upper = 18.0", "upper = 5.0"), "lower < upper"),
    (('sense = "max"', 'sense = "most"'), "sense"),
    (("max = 14.0", "mx = 14.0"), "mx"),
    # an unknown metric is located (file, table, key) where it enters, with the known ones it
    # resembles (it was found only when evaluated: no file, table or key)
    (('metric = "p_B_x"', 'metric = "p_B_xx"'),
     "[constraints] 0.metric: unknown metric 'p_B_xx'. Did you mean p_B_x"),
    (('"range:theta_rocker"', '"range:theta_rocke"'),
     ("[objective.parts] 0.metric: 'theta_rocke' is not a channel of 'fourbar-benchmark'. Did"
      " you mean range:theta_rocker")),
    (('"range:theta_rocker"', '"range:omega_rocker"'), "a range is of a position channel"),
    (('"range:theta_rocker"', '"stich_length"'), "Did you mean stitch_length"),
    (('"range:theta_rocker"', '"stitch_length"'), ("[objective.parts] 0.metric: stitch_length"
                                                   " needs a machine with a stitch regulator")),
])
def test_bad_problem_files_are_located(tmp_path, edit, needle):
    with pytest.raises(MachineFileError) as exc:
        load_problem(write(tmp_path, CONSTRAINED.replace(*edit, 1)))
    assert "p.toml" in str(exc.value) and needle in str(exc.value)


def test_unknown_metric_on_the_command_line(tmp_path):
    """`sewmech optimize` with a misspelt metric: one located error line, exit 2, before any
    work; and a feed metric's setting outside the regulator's range is located too."""
    text = SWING.read_text().replace('"range:theta_rocker"', '"range:theta_rockr"')
    path = tmp_path / "p.toml"
    path.write_text(text)
    out = CliRunner().invoke(app, ["optimize", str(path)])
    assert out.exit_code == 2
    assert f"{path}: [objective.parts] 0.metric: 'theta_rockr' is not a channel" in \
        " ".join(out.stderr.split())
    jb = (SWING.parent / "jb13-toward-jb82.toml").read_text()
    path.write_text(jb.replace("regulator_deg = 25.0", "regulator_deg = 45.0", 1))
    with pytest.raises(MachineFileError, match=r"\[objective.parts\] 0.regulator_deg: 45 deg is"
                       r" outside the regulator's range -30 .. 30 deg"):
        load_problem(path)


def test_optimize_says_the_objective_is_normalised_and_shows_its_parts():
    """The feed-lift problem minimises the dog's height at needle entry: the command printed
    "objective -1 -> -2.05" and nothing in mm. It says the objective is normalised and how, and
    shows each part in its own unit at the start and at the answer; the objective is the parts
    divided by their scales (here the part's size at the start)."""
    lift = SWING.parent / "feed-lift.toml"
    out = CliRunner().invoke(app, ["optimize", str(lift), "--method", "slsqp", "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.stdout)
    (part,) = data["objective_parts"]
    assert part["metric"] == "dog_height_at_needle_plate" and part["unit"] == "mm"
    assert part["regulator_deg"] == 30.0 and part["sense"] == "min"
    spec, m = load_problem(lift)
    p = Problem(spec, m)
    start = p.metric(spec.objective.parts[0], p.start)[0]
    assert part["start"] == pytest.approx(start, abs=1e-9) and start < -0.5  # mm, below
    assert part["scale"] == pytest.approx(abs(start), rel=1e-12)
    assert data["objective_start"] == pytest.approx(-1.0, rel=1e-12)
    assert data["objective"] == pytest.approx(part["answer"] / part["scale"], rel=1e-9)
    assert part["answer"] < start - 0.5  # lower by more than half a millimetre
    out = CliRunner().invoke(app, ["optimize", str(lift), "--method", "slsqp"],
                             env={"COLUMNS": "160"})
    assert out.exit_code == 0, out.output
    text = " ".join(out.stdout.split())
    assert "(normalised, dimensionless: the sum of the parts' w ((f - t) / s)^2" in text
    row = next(line for line in out.stdout.splitlines() if "dog_height_at_needle_plate" in line
               and "regulator 30 deg" in line)
    cells = [c.strip() for c in row.split("│")[1:-1]]
    assert cells[2] == "min" and cells[6] == "mm"
    assert float(cells[4]) == pytest.approx(start, abs=1e-5)  # (6 digits of ~1 mm)
    assert float(cells[5]) == pytest.approx(part["answer"], abs=1e-5)
    assert "feed_lift = 1.3 mm met" in out.stdout


def test_a_channel_at_a_regulator_setting(tmp_path):
    """A channel or a range with regulator_deg is read at that setting (it was read at the
    default whatever the file said), by the exact metric and the batch alike; a metric that
    does not depend on the regulator refuses the key."""
    from sewmech.engine.extremes import extremes

    text = (SWING.parent / "feed-lift.toml").read_text()
    text += '\n[[constraints]]\nmetric = "range:p_feed_dog.tip_y"\nregulator_deg = 0.0\nmax = 9.0\n'
    text += '\n[[constraints]]\nmetric = "p_feed_dog.tip_x"\nphi_deg = 100.0\n' \
            'regulator_deg = -20.0\nmax = 90.0\n'
    path = tmp_path / "p.toml"
    path.write_text(text)
    spec, m = load_problem(path)
    p = Problem(spec, m)
    rng_ref, x_ref = spec.constraints[-2], spec.constraints[-1]
    ex = extremes(m, "p_feed_dog.tip_y", inputs={"regulator": 0.0})
    at_zero = ex.maximum.value - ex.minimum.value
    ex30 = extremes(m, "p_feed_dog.tip_y")  # the working setting
    assert abs(at_zero - (ex30.maximum.value - ex30.minimum.value)) > 1e-3
    assert p.metric(rng_ref, p.start)[0] == pytest.approx(at_zero, abs=1e-9)
    k = sewmech.kinematics(m, np.radians([100.0]), inputs={"regulator": math.radians(-20.0)})
    x20 = float(k.point("feed_dog.tip").p[0, 0])
    assert p.metric(x_ref, p.start)[0] == pytest.approx(x20, abs=1e-9)
    vals, _ = batch_values(p, p.start[None, :])
    assert vals[("range:p_feed_dog.tip_y", 0.0, 0.0)][0] == pytest.approx(at_zero, abs=1e-7)
    assert vals[("p_feed_dog.tip_x", -20.0, 100.0)][0] == pytest.approx(x20, abs=1e-9)
    path.write_text(text.replace('metric = "feed_lift"\nregulator_deg = 0.0',
                                 'metric = "loop_lift"\nregulator_deg = 0.0'))
    with pytest.raises(MachineFileError, match=r"\[constraints\] 0.regulator_deg: loop_lift"
                       " does not depend on the regulator"):
        load_problem(path)


def test_golden_refuses_constraints(tmp_path):
    spec, m = load_problem(write(tmp_path, CONSTRAINED))
    with pytest.raises(OptionError, match="golden searches one variable"):
        optimize(Problem(spec, m), "golden")
    with pytest.raises(OptionError, match="unknown method"):
        optimize(Problem(spec, m), "annealing")


def test_optimize_command_prints_the_issue_keys(tmp_path):
    out = CliRunner().invoke(app, ["optimize", str(SWING), "--method", "slsqp", "--json",
                                   "--out", str(tmp_path / "o")])
    assert out.exit_code == 0, out.output
    data = json.loads(out.output)
    for key in ("status", "x", "objective", "objective_start", "constraints", "n_evaluations"):
        assert key in data
    assert data["status"] == "success"
    assert data["x"]["B.u"] == pytest.approx(closed_form_crank(0.9), abs=1e-5)
    assert (tmp_path / "o" / "problem-convergence.png").is_file()
    page = (tmp_path / "o" / "index.html").read_text()
    assert "Metrics before and after" in page and "B.u" in page
    assert (tmp_path / "o" / "problem-mechanism.png").is_file()  # before and after
    assert (tmp_path / "o" / "problem-channel-theta_rocker.csv").is_file()
    bad = CliRunner().invoke(app, ["optimize", str(SWING), "--method", "annealing"])
    assert bad.exit_code == 2 and "--method" in bad.output


def test_the_shipped_feed_lift_problem_by_slsqp():
    """The JB1-3 feed lift: SLSQP with exact gradients meets every constraint and lowers the
    dog further at needle entry. A larger throw lifts the dog higher and drops it lower; a
    smaller radius lowers its whole path: so the throw goes to its bound and the radius comes
    down until the lift meets its band's lower edge."""
    spec, m = load_problem(ROOT / "examples" / "problems" / "feed-lift.toml")
    p = Problem(spec, m)
    r = optimize(p, "slsqp")
    assert r.status == "success", r.message
    assert r.fun < r.objective_start
    assert all(c["satisfied"] for c in r.constraints.values())
    assert r.constraints["feed_lift"]["value"] == pytest.approx(1.3, abs=1e-6)
    assert r.x[0] == pytest.approx(1.8)
    assert r.n_evaluations < 60


def test_the_feed_lift_report_shows_the_dog_before_and_after(tmp_path):
    """sewmech optimize --out writes the problem's page: every metric before and after (the
    answer's equal to the constraints the command reports), and the dog's path at each
    regulator setting the metrics read, whose highest point above the plate is the lift."""
    import numpy as np
    import pandas as pd

    path = ROOT / "examples" / "problems" / "feed-lift.toml"
    out = CliRunner().invoke(app, ["optimize", str(path), "--method", "slsqp", "--json",
                                   "--out", str(tmp_path / "o")])
    assert out.exit_code == 0, out.output
    data = json.loads(out.output)
    o = tmp_path / "o"
    metrics = pd.read_csv(o / "problem-metrics.csv")
    lift = metrics[metrics.metric == "feed_lift"].iloc[0]
    assert lift.answer == pytest.approx(data["constraints"]["feed_lift"]["value"], abs=1e-9)
    for reg in ("0", "30"):
        curves = pd.read_csv(o / f"problem-feed-{reg}.csv")
        assert {"start y above the plate [mm]", "answer y above the plate [mm]"} <= set(curves)
    y = pd.read_csv(o / "problem-feed-0.csv")["answer y above the plate [mm]"].to_numpy()
    assert np.max(y) == pytest.approx(lift.answer, abs=2e-4)  # 1 deg samples of the path
    page = (o / "index.html").read_text()
    assert "The feed dog at regulator 30 deg" in page and "data:image/png;base64" in page


def test_an_answer_always_assembles_over_the_whole_turn(tmp_path):
    """Maximising the swing pushes the crank toward the length where the four-bar stops
    turning over (Grashof: a + 40 <= 35 + 38, a <= 33 mm); the search never returns a design
    beyond it, and says the answer assembles."""
    text = CONSTRAINED.replace("upper = 18.0", "upper = 36.0").split("[[constraints]]")[0]
    spec, m = load_problem(write(tmp_path, text))
    r = optimize(Problem(spec, m), "golden")
    assert r.x[0] <= 33.0
    assert r.constraints["assembles over the whole turn"]["satisfied"]
    assert r.status == "success"


def test_differential_evolution_evaluates_a_population_per_batch_call(tmp_path):
    """batch_values: the metrics of several designs in one call equal each design's exact
    metric; a design that does not assemble is masked (NaN value, never used), and the
    penalised objective gives it 1e12, never NaN."""
    import numpy as np

    from sewmech.design.optimize import _penalised
    from sewmech.design.problem import batch_values

    text = CONSTRAINED.replace("upper = 18.0", "upper = 36.0")
    spec, m = load_problem(write(tmp_path, text))
    p = Problem(spec, m)
    X = np.array([[10.0], [14.0], [35.0]])  # the last is beyond the Grashof limit (33 mm)
    vals, ok = batch_values(p, X)
    assert list(ok) == [True, True, False]
    for k in range(2):
        for ref in [*spec.objective.parts, *spec.constraints]:
            exact, _ = p.metric(ref, X[k])
            got = vals[(ref.metric, ref.regulator_deg, ref.phi_deg)][k]
            assert got == pytest.approx(exact, abs=1e-7), ref.metric
    assert np.isnan(vals[("p_B_x", None, 0.0)][2])
    f = _penalised(p, X)
    assert np.all(np.isfinite(f)) and f[2] == 1e12


def test_values_only_path_equals_the_exact_objective_and_constraints():
    """Problem.batch / Problem.value (what Powell, cyclic search, DE and NSGA-II read): the
    objective and every constraint of the JB1-3 feed-lift problem from the 1 deg grid's
    Hermite events equal the exactly located ones of Problem.objective / constraints; the
    assembly flag equals design_ok; a design counts once however often it is asked for."""
    import numpy as np

    spec, m = load_problem(ROOT / "examples" / "problems" / "feed-lift.toml")
    p = Problem(spec, m)
    X = np.array([p.start, [1.7, 7.5], [1.0, 8.8]])
    f, g, ok = p.batch(X)
    assert g.shape == (3, 5) and p.constraint_scales().shape == (5,)
    for k, x in enumerate(X):
        assert ok[k] == p.design_ok(x)
        assert f[k] == pytest.approx(p.objective(x)[0], abs=1e-6)
        np.testing.assert_allclose(g[k], p.constraints(x)[0], atol=1e-6)
    before = p.evaluations
    fv, gv, okv = p.value(X[1])
    p.value(X[1])
    assert p.evaluations == before  # X[1] was evaluated above
    assert fv == f[1] and okv == ok[1] and np.array_equal(gv, g[1])


def test_a_design_that_fails_between_grid_angles_is_never_feasible(tmp_path):
    """The crank turned 0.5 deg so that the dyad's reach is tightest at phi = 179.5 deg, between
    grid angles, and the links 2e-4 mm too short there: at every whole degree it assembles
    (4e-4 mm to spare at 179 and 180), so a 1 deg grid alone would pass it. The searches'
    check keeps every unit 0.01 mm from failing at the grid angles and refuses it; the answer's
    verdict is the exact proof, which locates the failure; the margin's own closed form
    says the same."""
    import numpy as np

    from sewmech.design.evaluate import ASSEMBLY_CLEARANCE_MM, assembles_batch
    from sewmech.engine.assembly import prove_assembly

    r, ad, l1 = 15.0, 38.0, 30.0
    l2 = ad + r - 2e-4 - l1
    m = sewmech.load_machine("fourbar-benchmark")
    P = m.parameters({"B.u": r, "crank.phase": math.radians(0.5), "dyad.length1": l1,
                      "dyad.length2": l2})
    grid = np.radians(np.arange(360.0)) + math.radians(0.5)
    reach = np.hypot(ad - r * np.cos(grid), r * np.sin(grid))  # |B D| at the grid angles
    assert np.all(l1 + l2 - reach > 1e-4)  # a grid alone passes it ...
    assert l1 + l2 - (ad + r) < 0  # ... but it fails at 179.5 deg
    assert sewmech.kinematics(m, np.radians(np.arange(360.0)), params=P,
                              on_failure="mask").feasible.all()
    assert not assembles_batch(m, P[None, :])[0]
    proof = prove_assembly(m, params=P)
    assert not proof.ok and abs(proof.smallest.phi_deg - 179.5) < 1e-6
    # a design with room to spare passes both
    P2 = m.parameters({"B.u": r, "dyad.length1": l1, "dyad.length2": l2 + 0.1})
    assert assembles_batch(m, P2[None, :])[0] and prove_assembly(m, params=P2).ok
    assert 0 < ASSEMBLY_CLEARANCE_MM <= 0.01
    # a problem's answer reported: not assembled, with where, whatever the grid says
    spec, pm = load_problem(write(tmp_path, CONSTRAINED))
    pm2 = pm.with_parameters({"crank.phase": math.radians(0.5), "dyad.length1": l1,
                              "dyad.length2": l2})
    prob2 = Problem(spec, pm2)
    rep = prob2.report(np.array([r]))
    a = rep["assembles over the whole turn"]
    assert not a["satisfied"] and a["failures"] and a["smallest_margin_mm"] < 0
    assert not prob2.design_ok(np.array([r]))


TWO_PARTS = """
[problem]
name = "swing against crank length"
machine = "fourbar-benchmark"
[[variables]]
parameter = "B.u"
lower = 8.0
upper = 18.0
[objective]
[[objective.parts]]
metric = "range:theta_rocker"
target = 0.9
[[objective.parts]]
metric = "p_B_x"          # the crank's length (the pin at phi = 0): as short as may be
phi_deg = 0.0
sense = "min"
"""


def test_nsga2_front_between_two_objectives(tmp_path):
    """The swing grows with the crank: the front runs from the shortest crank (8 mm) to the
    crank of the exact swing (13.43 mm), every design on it not dominated, each assembling."""
    import numpy as np

    spec, m = load_problem(write(tmp_path, TWO_PARTS))
    r = optimize(Problem(spec, m), "nsga2", seed=3)
    assert r.status == "success", r.message
    X = np.array(r.front["x"])[:, 0]
    F = np.array(r.front["f"])
    a_star = closed_form_crank(0.9)
    assert X.min() < 8.3 and X.max() == pytest.approx(a_star, abs=0.05)
    assert np.all(X <= a_star + 0.05)
    for i in range(len(F)):  # no design of the front dominates another
        dominated = np.all(F <= F[i], axis=1) & np.any(F < F[i], axis=1)
        assert not dominated.any()
    assert 8.0 <= r.x[0] <= a_star + 0.05
    with pytest.raises(OptionError, match="at least two objective parts"):
        optimize(Problem(*load_problem(SWING)), "nsga2")


def test_jb13_toward_jb82_hits_both_targets():
    """The weighted uniform form by SLSQP (as its smooth epigraph problem): two dimensions of
    the JB1-3's feed give the JB8-2's stitch length and dog height at regulator 25 deg, both
    computed from jb8-2.toml."""
    import sewmech
    from sewmech.sewing.gradients import METRICS

    spec, m = load_problem(ROOT / "examples" / "problems" / "jb13-toward-jb82.toml")
    p = Problem(spec, m)
    r = optimize(p, "slsqp")
    assert r.status == "success", r.message
    assert r.fun < 1e-8 < r.objective_start
    jb82 = sewmech.load_machine("jb8-2")
    for part in spec.objective.parts:
        got, _ = p.metric(part, r.x)
        theirs = METRICS[part.metric](jb82, 25.0).value
        assert got == pytest.approx(theirs, abs=1e-4), part.metric


def test_the_take_up_problem_by_slsqp_with_the_thread_figures_exact_derivatives():
    """The take-up problem: the batch values equal the thread balance of each design and the
    start meets the constraints (the penalty methods need that). SLSQP, with the thread
    figures' exact derivatives and the assembly margin as a constraint, meets every
    constraint, keeps the take-up 0.01 mm from full extension, and no feasible design a small
    step away along any variable is better (a brute-force check of the answer)."""
    import numpy as np

    from sewmech.design.evaluate import ASSEMBLY_CLEARANCE_MM
    from sewmech.design.problem import batch_values
    from sewmech.sewing.thread import thread_balance

    spec, m = load_problem(ROOT / "examples" / "problems" / "take-up.toml")
    p = Problem(spec, m)
    X = np.array([p.start, p.start + [0.3, -0.2, 0.4]])
    vals, ok = batch_values(p, X)
    assert ok.all()
    for k in range(2):
        b = thread_balance(m, params=p.params(X[k]))
        assert vals[("thread_min_overfeed", None, 0.0)][k] == pytest.approx(
            b.min_overfeed_while_loop_grows)
    g, _, _ = p.constraints(p.start)
    assert np.all(g > 0)
    r = optimize(p, "slsqp")
    assert r.status == "success", r.message
    assert r.fun < r.objective_start - 5.0  # the least overfeed raised several times over
    margin = r.constraints["assembles over the whole turn"]["smallest_margin_mm"]
    assert margin >= ASSEMBLY_CLEARANCE_MM - 1e-6
    q = Problem(spec, m)
    for j in range(3):
        for step in (-0.01, 0.01):
            x = np.array(r.x, dtype=float)
            x[j] += step
            if not (p.lower[j] <= x[j] <= p.upper[j]):
                continue
            if q.assembly_margin(x)[0] < ASSEMBLY_CLEARANCE_MM or np.any(
                    q.constraints(x)[0] < 0):
                continue
            assert q.objective(x)[0] >= r.fun - 1e-9, (j, step)


def test_the_assembly_margin_and_its_derivative():
    """Problem.assembly_margin: the smallest margin equals the exact proof's (located between
    grid angles), its derivative the central differences of that proof's smallest margin."""
    import numpy as np

    from sewmech.engine.assembly import prove_assembly

    spec, m = load_problem(ROOT / "examples" / "problems" / "take-up.toml")
    p = Problem(spec, m)
    x = np.array([25.6, 19.2, -8.0])
    v, d = p.assembly_margin(x)

    def smallest(xx):
        return min(prove_assembly(m, params=p.params(xx), inputs=i).smallest.value_mm
                   for i in ({"regulator": math.radians(-30)}, {"regulator": math.radians(30)}))

    assert v == pytest.approx(smallest(x), abs=1e-9)
    for j in range(3):
        e = np.zeros(3)
        e[j] = 1e-5
        fd = (smallest(x + e) - smallest(x - e)) / 2e-5
        assert d[j] == pytest.approx(fd, abs=1e-5), j
