"""Tolerance analysis (issue 17): the ISO 286 table against its formula, RSS against Monte
Carlo, worst case as a bound, allocation against a numerical optimiser, and tolerance files'
errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import fourbar
from typer.testing import CliRunner

import sewmech
from sewmech.cli import app
from sewmech.design.tolerance_file import (IT_RANGES_MM, IT_TABLE_UM, ToleranceSpec,
                                           it_tolerance_mm, load_tolerance_file, tolerances_of)
from sewmech.design.tolerances import allocate, tolerance_analysis
from sewmech.engine.errors import MachineFileError

runner = CliRunner()


def test_it_table_follows_its_formula():
    """ISO 286-1: IT = k i with i = 0.45 D^(1/3) + 0.001 D (um, D the geometric mean of the size
    range, mm) and k = 7, 10, 16, 25, 40, 64, 100, 160, 250 for IT5 .. IT13; the table rounds
    (the first range, below 3 mm, most)."""
    k = {5: 7, 6: 10, 7: 16, 8: 25, 9: 40, 10: 64, 11: 100, 12: 160, 13: 250}
    lows = (1,) + IT_RANGES_MM[:-1]
    for grade, row in IT_TABLE_UM.items():
        for lo, hi, v in zip(lows, IT_RANGES_MM, row):
            D = math.sqrt(lo * hi)
            i = 0.45 * D ** (1 / 3) + 0.001 * D
            assert abs(k[grade] * i - v) / v < (0.14 if hi == 3 else 0.10), (grade, hi)
    assert it_tolerance_mm(25.0, 7) == pytest.approx(0.021)
    assert it_tolerance_mm(-167.5, 9) == pytest.approx(0.100)  # a coordinate: its magnitude


def test_rss_agrees_with_monte_carlo_and_worst_case_bounds_every_sample():
    m = fourbar()
    spec = ToleranceSpec.model_validate({"defaults": {"it_grade": 7, "angle_deg": 0.05}})
    r = tolerance_analysis(m, "theta_rocker", spec, phi_deg=40.0, samples=40_000, seed=3)
    # normal dimensions at sigma = t / 3: the metric's std is RSS / 3 to first order; the
    # sampling error of a std from n samples is about 1 / sqrt(2 n) = 0.35 %
    assert r.monte_carlo["std"] == pytest.approx(r.rss / 3.0, rel=0.02)
    assert r.monte_carlo["assembled"] == 40_000
    assert sum(r.contributions.values()) == pytest.approx(1.0)
    uni = ToleranceSpec.model_validate({"defaults": {"it_grade": 7, "angle_deg": 0.05,
                                                     "distribution": "uniform"}})
    u = tolerance_analysis(m, "theta_rocker", uni, phi_deg=40.0, samples=20_000, seed=4)
    # the linear worst case bounds every sample (second-order terms are ~1e-6 of it here)
    assert max(abs(u.monte_carlo["min"]), abs(u.monte_carlo["max"])) <= u.worst_case * 1.001
    # and uniform dimensions have std t / sqrt(3): the metric's is RSS / sqrt(3)
    assert u.monte_carlo["std"] == pytest.approx(u.rss / math.sqrt(3.0), rel=0.02)


@pytest.mark.parametrize("distribution, divisor", [("normal", 3.0),
                                                   ("uniform", math.sqrt(3.0))])
def test_standard_deviation_against_a_closed_form(distribution, divisor):
    """The crank pin's x, A.x + B.u cos(phi) - B.v sin(phi), is linear in the three dimensions
    that move it: its standard deviation is sqrt(sum (d_j t_j)^2) / 3 for normal dimensions at
    sigma = t / 3 and / sqrt(3) for uniform ones over +-t (a uniform distribution of half-width
    t has standard deviation t / sqrt(3)); the Monte Carlo's agrees to its sampling error
    (about 1 / sqrt(2 n) = 0.35 %), and the worst case bounds every sample."""
    m = fourbar()
    t = {"A.x": 0.05, "B.u": 0.03, "B.v": 0.02}
    spec = ToleranceSpec.model_validate({"defaults": {"it_grade": 5,
                                                      "distribution": distribution},
                                         "parameters": t})
    phi = math.radians(40.0)
    d = {"A.x": 1.0, "B.u": math.cos(phi), "B.v": -math.sin(phi)}
    rss = math.sqrt(sum((d[k] * t[k]) ** 2 for k in t))
    r = tolerance_analysis(m, "p_B_x", spec, phi_deg=40.0, samples=40_000, seed=5)
    assert r.rss == pytest.approx(rss, rel=1e-12)
    assert r.worst_case == pytest.approx(sum(abs(d[k]) * t[k] for k in t), rel=1e-12)
    assert r.sigma == pytest.approx(rss / divisor, rel=1e-12)
    assert r.to_json()["sigma"] == r.sigma
    assert r.monte_carlo["std"] == pytest.approx(rss / divisor, rel=0.02)
    assert max(-r.monte_carlo["min"], r.monte_carlo["max"]) <= r.worst_case * (1 + 1e-9)
    # brute force: the same designs drawn here, the pin placed by its closed form
    rng = np.random.default_rng(6)
    n = 200_000
    if distribution == "normal":
        dev = {k: rng.standard_normal(n) * v / 3.0 for k, v in t.items()}
    else:
        dev = {k: rng.uniform(-v, v, n) for k, v in t.items()}
    x = dev["A.x"] + (15.0 + dev["B.u"]) * math.cos(phi) - dev["B.v"] * math.sin(phi)
    assert np.std(x) == pytest.approx(rss / divisor, rel=0.01)


def test_tolerance_command_compares_the_monte_carlo_with_the_right_sigma(tmp_path):
    """The console line compared uniform dimensions' Monte Carlo with "RSS / 3"; their standard
    deviation is RSS / sqrt(3)."""
    path = tmp_path / "u.toml"
    path.write_text('[defaults]\nit_grade = 9\ndistribution = "uniform"\n')
    args = ["tolerance", "jb1-3", "--output", "p_needle.point_y", "--phi-deg", "30",
            "--samples", "4000", "--tolerances", str(path)]
    out = runner.invoke(app, [*args, "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.stdout)
    assert data["sigma"] == pytest.approx(data["rss"] / math.sqrt(3.0), rel=1e-12)
    assert data["monte_carlo"]["std"] == pytest.approx(data["sigma"], rel=0.05)
    out = runner.invoke(app, args, env={"COLUMNS": "200"})
    assert out.exit_code == 0, out.output
    assert f"(RSS / sqrt(3) = {data['sigma']:.4g} mm" in out.stdout
    assert "RSS / 3 " not in out.stdout


@pytest.mark.parametrize("distribution", ["normal", "uniform"])
def test_allocation_is_the_least_cost_within_the_band(distribution):
    """The closed forms against SLSQP on min sum b_j / t_j subject to the band."""
    from scipy.optimize import minimize

    m = fourbar()
    rng = np.random.default_rng(7)
    n = len(m.parameter_names)
    d = rng.normal(size=n)
    b = rng.uniform(0.5, 2.0, size=n)
    on = np.ones(n, dtype=bool)
    band = 0.05
    alloc, rule = allocate(m, d, b, on, band, distribution)
    t = np.array([alloc[p] for p in m.parameter_names])
    if distribution == "normal":
        assert rule == "RSS" and math.sqrt(np.sum((d * t) ** 2)) == pytest.approx(band)

        def con(x):
            return band ** 2 - np.sum((d * x) ** 2)
    else:
        assert rule == "worst case" and np.sum(np.abs(d) * t) == pytest.approx(band)

        def con(x):
            return band - np.sum(np.abs(d) * x)
    # in logarithms of the tolerances, which keeps the problem well scaled
    ref = minimize(lambda y: np.sum(b * np.exp(-y)), np.log(t * 0.5), method="SLSQP",
                   constraints=[{"type": "ineq", "fun": lambda y: con(np.exp(y))}],
                   options={"ftol": 1e-12, "maxiter": 1000})
    assert ref.success, ref.message
    assert np.sum(b / t) == pytest.approx(ref.fun, rel=1e-6)
    np.testing.assert_allclose(t, np.exp(ref.x), rtol=1e-3)


@pytest.mark.parametrize("text, needle", [
    ('[parameters]\n"dyad.lenght1" = 0.01\n', "Did you mean dyad.length1"),
    ('[parameters]\n"dyad.length1" = -0.01\n', "finite number >= 0"),
    ('[defaults]\nit_grade = 4\n', "IT4 is not tabulated"),
    ('[defaults]\ndistribution = "triangle"\n', "distribution"),
    ('[defaults]\nit_grade = "7"\n', "it_grade"),
    ('[defaultz]\nit_grade = 7\n', "defaultz"),
    ('[parameters\n', "not valid TOML"),
])
def test_bad_tolerance_files_are_located(tmp_path, text, needle):
    f = tmp_path / "tol.toml"
    f.write_text(text, encoding="utf-8")
    with pytest.raises(MachineFileError) as exc:
        tolerances_of(fourbar(), load_tolerance_file(f), str(f))
    assert "tol.toml" in str(exc.value) and needle in str(exc.value)


def test_tolerance_file_values_in_mm_and_deg(tmp_path):
    f = tmp_path / "tol.toml"
    f.write_text('[defaults]\nit_grade = 8\nexclude = ["A.x"]\n[parameters]\n'
                 '"dyad.length1" = 0.01\n"crank.phase" = 0.5\n', encoding="utf-8")
    m = fourbar()
    t = tolerances_of(m, load_tolerance_file(f))
    names = m.parameter_names
    assert t[names.index("dyad.length1")] == 0.01
    assert t[names.index("crank.phase")] == pytest.approx(math.radians(0.5))
    assert t[names.index("A.x")] == 0.0  # held exact
    assert t[names.index("dyad.length2")] == pytest.approx(0.5 * it_tolerance_mm(35.0, 8))
    assert t[names.index("crank.ratio")] == 0.0  # a ratio is not toleranced by default


def test_tolerance_command_prints_the_issue_keys(tmp_path):
    out = runner.invoke(app, ["tolerance", "jb1-3", "--output", "stitch_length",
                              "--regulator-deg", "25", "--samples", "400", "--band", "0.05",
                              "--json", "--out", str(tmp_path / "t")])
    assert out.exit_code == 0, out.output
    data = json.loads(out.output)
    for key in ("worst_case", "rss", "monte_carlo", "contributions", "allocation"):
        assert key in data
    assert {"std", "p99"} <= set(data["monte_carlo"])
    assert data["rss"] <= data["worst_case"]
    names = {p.name for p in (tmp_path / "t").iterdir()}
    assert "jb1-3-tolerance-stitch_length-distribution.png" in names
    assert "jb1-3-tolerance-stitch_length-pareto.png" in names
    bad = runner.invoke(app, ["tolerance", "jb1-3", "--output", "stitch_length", "--samples",
                              "5"])
    assert bad.exit_code == 2 and "--samples" in bad.output
    bad = runner.invoke(app, ["tolerance", "jb1-3", "--output", "stitch_length",
                              "--regulator-deg", "45"])
    assert bad.exit_code == 2 and "regulator" in bad.output


def test_tolerance_as_the_readme_writes_it_analyses_the_working_setting():
    """`sewmech tolerance jb1-3 --output stitch_length` analysed the regulator's zero mark (a
    9e-7 mm stitch, tolerances allocated for it, no word); it analyses the machine's working
    setting, the longest forward stitch."""
    from sewmech.sewing.gradients import stitch_length_gradient

    out = runner.invoke(app, ["tolerance", "jb1-3", "--output", "stitch_length", "--samples",
                              "200", "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.stdout)
    g = stitch_length_gradient(sewmech.load_machine("jb1-3"), 30.0)
    assert data["value"] == pytest.approx(g.value, abs=1e-9) and 4.0 < data["value"] < 4.2


@pytest.mark.parametrize("argv, option, give", [
    (["tolerance", "jb1-3", "--output", "stitch_length", "--regulator-deg", "0"],
     "--regulator-deg", "--regulator-deg 30"),
    (["sensitivity", "jb1-3", "--output", "stitch_length", "--input", "regulator=0"],
     "--input", "--input regulator=30"),
    (["tolerance", "jb8-2", "--output", "stitch_length", "--regulator-deg", "0"],
     "--regulator-deg", "--regulator-deg 28"),
])
def test_a_stitch_of_round_off_is_refused(argv, option, give):
    """At the zero mark the stitch is round-off (9e-7 mm): its tolerances and derivatives
    belong to no stitch. The command refuses it in one located line that names the metric, the
    setting and the option to give, with the working setting as the suggestion."""
    out = runner.invoke(app, argv)
    assert out.exit_code == 2
    text = " ".join(out.stderr.split())
    assert text.startswith(f"error: {option}: stitch_length at regulator 0 deg is")
    assert "round-off of no stitch" in text and f"e.g. {give} (the machine's working" in text
    assert "Traceback" not in out.output


def test_the_library_refuses_a_stitch_of_round_off(tmp_path):
    """tolerance_analysis and metric_gradient refuse the zero mark's stitch and name their
    argument; a machine whose own working setting is the zero mark is told the forward end
    and that its default_deg should be its working setting. A short but real stitch passes."""
    from sewmech.design.tolerances import metric_gradient
    from sewmech.engine.errors import OptionError

    m = sewmech.load_machine("jb1-3")
    with pytest.raises(OptionError, match=r"^regulator_deg: stitch_length at regulator 0 deg"
                       r".*e\.g\. regulator_deg=30 \(the machine's working setting\)"):
        tolerance_analysis(m, "stitch_length", regulator_deg=0.0, samples=100)
    with pytest.raises(OptionError, match="round-off of no stitch"):
        metric_gradient(m, "stitch_length", regulator_deg=0.0)
    value, _, _ = metric_gradient(m, "stitch_length", regulator_deg=0.05)  # 6 micrometres
    assert 1e-3 < value < 1e-2
    # the lift and the dog's height are no degenerate metrics at the zero mark
    assert metric_gradient(m, "feed_lift", regulator_deg=0.0)[0] > 1.0
    text = Path(m.file).read_text().replace("default_deg = 30.0 ", "default_deg = 0.0 ", 1)
    path = tmp_path / "zero.toml"
    path.write_text(text)
    out = runner.invoke(app, ["tolerance", str(path), "--output", "stitch_length"])
    assert out.exit_code == 2
    text = " ".join(out.stderr.split())
    assert "stitch_length at regulator 0 deg" in text and "--regulator-deg 30 (the forward end" \
        in text and "[inputs.regulator] default_deg should be its working setting" in text
