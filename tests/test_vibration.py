"""Balancing from measurements and the built counterweight: synthetic data with a known answer.

- the crossing of two measured lines: exact for noise-free lines, and its 95 % interval covers
  the true crossing in about 95 % of noisy repeats (a coverage check of Fieller's interval);
- malformed measurement files get located errors;
- influence coefficients recover a known unbalance from a linear model of the machine;
- the lead insert's static moment against its volume, density and radius written out, and the
  part around it against its own geometry: it clears the shaft by the stated wall, holds the
  lead, and weighs what the built static moment needs; a part that no cup can be is refused.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sewmech.design.inserts import build_extra, insert, trim_hole
from sewmech.design.vibration import crossing, influence_balance, level_change_db, level_db, phasor
from sewmech.engine.errors import AnalysisError, OptionError

S = np.repeat(np.array([0.0, 40.0, 80.0, 120.0, 160.0, 205.6]), 3)  # g cm, three repeats


def lines(s, noise=0.0, rng=None, cross=143.0):
    """vx falls and vy rises with the static moment; they meet at ``cross`` g cm."""
    vx = 9.0 - 0.03 * (s - cross)
    vy = 9.0 + 0.02 * (s - cross)
    if noise:
        vx = vx + rng.normal(scale=noise, size=s.shape)
        vy = vy + rng.normal(scale=noise, size=s.shape)
    return vx, vy


def test_noise_free_lines_cross_where_they_were_made_to():
    vx, vy = lines(S)
    c = crossing(S, vx, vy)
    assert c.s_add_gcm == pytest.approx(143.0, rel=1e-12)
    # the interval is as wide as the round-off of the fitted lines (its width goes with the
    # square root of their residual variance, which may be exactly zero): it holds the crossing
    # up to that round-off, a few ulps of 143 on either side
    lo, hi = c.ci95_gcm
    assert lo <= hi
    assert lo - 1e-9 * 143.0 <= 143.0 <= hi + 1e-9 * 143.0
    assert hi - lo < 1e-4
    assert c.n_points == len(S)
    assert c.fit_x[1] == pytest.approx(-0.03) and c.fit_y[1] == pytest.approx(0.02)
    # the level at the crossing against no extra counterweight, written out
    v0 = math.hypot(9.0 + 0.03 * 143.0, 9.0 - 0.02 * 143.0)
    v1 = math.hypot(9.0, 9.0)
    assert c.level_change_db == pytest.approx(20.0 * math.log10(v1 / v0), rel=1e-12)


def test_the_95_percent_interval_covers_the_crossing_about_95_percent_of_the_time(rng):
    hits, n = 0, 400
    for _ in range(n):
        vx, vy = lines(S, noise=0.4, rng=rng)
        lo, hi = crossing(S, vx, vy).ci95_gcm
        hits += lo <= 143.0 <= hi
    # binomial: 95 % of 400 is 380 +- 4.4 (one standard deviation)
    assert 364 <= hits <= 395


def test_levels_in_db():
    assert level_change_db(1.0, 0.5) == pytest.approx(-6.0206, abs=1e-4)
    # the paper's 110 -> 105.2 dBA: the velocity fell to 10^(-4.8 / 20) = 0.575 of the first
    v0 = 5e-5 * 10 ** (110.0 / 20.0)
    assert float(level_db(v0)) == pytest.approx(110.0)
    assert level_change_db(v0, v0 * 10 ** (-4.8 / 20.0)) == pytest.approx(-4.8)


@pytest.mark.parametrize("s, vx, vy, needle", [
    (np.array([0.0, 50.0]), np.array([1.0, 2.0]), np.array([2.0, 1.0]), "at least three"),
    (S, S * 0 + 5.0, S * 0 + 1.0, "do not cross"),
    (np.array([0.0, 10.0, 20.0, 30.0, 40.0]), np.array([5.0, 4.0, 3.0, 2.0, 1.0]),
     np.array([4.5, 4.5, 4.5, 4.5, 4.5]), "1 measurement\\(s\\) below and"),
    (S, np.where(S > 100, np.nan, 1.0), S * 0 + 1.0, "not a finite number in measurement"),
])
def test_data_that_cannot_give_a_crossing_is_refused_with_the_reason(s, vx, vy, needle):
    with pytest.raises(AnalysisError, match=needle):
        crossing(s, vx, vy, where="run.csv")


def test_influence_coefficients_recover_a_known_unbalance(rng):
    # a machine whose vibration at 4 rows (2 places x 2 speeds) is linear in 2 planes' masses
    A = rng.normal(size=(4, 2)) + 1j * rng.normal(size=(4, 2))  # mm/s per g cm
    U_true = phasor([60.0, 25.0], [200.0, 35.0])  # the unbalance, g cm
    V0 = A @ U_true
    trial = phasor([30.0, 30.0], [0.0, 90.0])
    trials = np.stack([V0 + A[:, j] * trial[j] for j in range(2)])
    res = influence_balance(V0, trials, [30.0, 30.0], [0.0, 90.0])
    corr = res.correction_gcm * np.exp(1j * np.radians(res.correction_angle_deg))
    assert np.allclose(corr, -U_true, rtol=1e-12)
    assert res.after < 1e-9 * res.before
    # with noise: least squares over more rows than planes, near the truth
    V0n = V0 + 0.01 * (rng.normal(size=4) + 1j * rng.normal(size=4))
    res = influence_balance(V0n, trials, [30.0, 30.0], [0.0, 90.0])
    corr = res.correction_gcm * np.exp(1j * np.radians(res.correction_angle_deg))
    assert np.abs(corr + U_true).max() < 1.0
    with pytest.raises(AnalysisError, match="do not tell the planes apart"):
        influence_balance(V0, np.stack([V0, V0]), [30.0, 30.0], [0.0, 90.0])


def test_lead_insert_static_moment_from_its_volume():
    ins = insert(100.0, 30.0, depth_mm=30.0)
    vol = math.pi * ins.diameter_mm ** 2 / 4.0 * 30.0  # mm^3
    # (11.34 - 7.85) g/cm^3 = 3.49e-3 g/mm^3; g mm / 10 = g cm
    assert (11.34e-3 - 7.85e-3) * vol * 30.0 / 10.0 == pytest.approx(100.0, rel=1e-12)
    assert ins.mass_g == pytest.approx(11.34e-3 * vol)
    same = insert(100.0, 30.0, diameter_mm=ins.diameter_mm)
    assert same.depth_mm == pytest.approx(30.0)
    d = trim_hole(50.0, 15.0, 10.0)
    assert 11.34e-3 * math.pi * d * d / 4.0 * 10.0 * 15.0 / 10.0 == pytest.approx(50.0)
    b = build_extra(64.1, 20.0, bore_mm=8.0, depth_mm=10.0, factor=3.0)
    assert b["s_built_gcm"] == pytest.approx(192.3)
    ins = b["insert"]
    # the lead drilled out completely removes the whole margin, 2 x 64.1 g cm
    lead_s = 11.34e-3 * math.pi * ins["diameter_mm"] ** 2 / 4.0 * 10.0 * 20.0 / 10.0
    assert lead_s == pytest.approx(2.0 * 64.1, rel=1e-12)
    # block + insert make the built static moment
    assert b["body_s_gcm"] + ins["s_gcm"] == pytest.approx(192.3)
    assert b["body_mass_g"] * 20.0 / 10.0 == pytest.approx(b["body_s_gcm"])
    # trimming to S_add: the hole into the lead is the insert itself (it holds the margin
    # exactly); a hole into steel must be wider, by the root of the densities
    assert b["trim_diameter_mm"] == pytest.approx(ins["diameter_mm"])
    assert b["trim_diameter_body_mm"] ** 2 * 7850.0 == pytest.approx(
        b["trim_diameter_mm"] ** 2 * 11340.0)
    assert b["hole_edge_mm"] == pytest.approx(20.0 - ins["diameter_mm"] / 2.0)
    with pytest.raises(OptionError, match="margin"):
        build_extra(64.1, 15.0, bore_mm=8.0, depth_mm=10.0, factor=5.0)
    with pytest.raises(OptionError, match="not denser"):
        insert(10.0, 15.0, depth_mm=5.0, filler="aluminium")
    # a hole wider than twice its radius would cross the axis
    with pytest.raises(OptionError, match="cross the axis"):
        insert(100.0, 15.0, depth_mm=2.0)


def _check_cup(b, s_add, radius, bore, wall):
    """Everything a recipe claims, from its own dimensions: the hole clears the bore by the
    wall, the cup holds the hole with that wall round it and under it and clears the shaft,
    and the steel and lead at the radius make the built static moment."""
    ins, blk = b["insert"], b["block"]
    d, h, D, T = ins["diameter_mm"], ins["depth_mm"], blk["diameter_mm"], blk["length_mm"]
    tol = 1e-9 * radius
    assert b["hole_edge_mm"] == pytest.approx(radius - d / 2.0, abs=tol)
    assert radius - d / 2.0 >= bore / 2.0 + wall - tol  # clear of the shaft's bore
    assert b["clearance_mm"] >= wall - tol
    assert radius - D / 2.0 >= bore / 2.0 - tol  # the cup itself clears the shaft
    assert (D - d) / 2.0 >= wall - tol and T - h >= wall - tol  # the walls round the lead
    steel_g = 7.85e-3 * math.pi / 4.0 * (D * D * T - d * d * h)
    lead_g = 11.34e-3 * math.pi / 4.0 * d * d * h
    assert steel_g == pytest.approx(blk["steel_g"], rel=1e-9)
    assert lead_g == pytest.approx(ins["mass_g"], rel=1e-9)
    # g x mm / 10 = g cm: the part as built, and with its lead drilled out, S_add
    assert (steel_g + lead_g) * radius / 10.0 == pytest.approx(b["s_built_gcm"], rel=1e-9)
    assert steel_g * radius / 10.0 == pytest.approx(s_add, rel=1e-9)
    assert 2.5 <= b["factor"] <= 3.0


@pytest.mark.parametrize("s_add, radius, bore", [
    (135.0, 18.0, 12.0),   # bartack-1820's S_add on its 12 mm main shaft (the issue's 2.7 mm)
    (83.15, 18.0, 8.5),    # jb1-3's on its 8.5 mm upper shaft
    (64.1, 15.0, 12.0),    # the paper's S_add on a tight radius
    (20.0, 15.0, 10.0),    # a small counterweight (far out, it would be too light to hold its lead)
])
def test_the_built_counterweight_clears_the_shaft_and_holds_its_lead(s_add, radius, bore):
    b = build_extra(s_add, radius, bore_mm=bore)
    _check_cup(b, s_add, radius, bore, 2.0)
    assert b["wall_mm"] == 2.0 and b["bore_mm"] == bore


def test_the_built_counterweight_over_random_inputs(rng):
    """Either a recipe that passes every check of its own geometry, or a located refusal
    that says what to change; never a hole in the shaft."""
    from sewmech.design.inserts import NotBuildable

    built = refused = 0
    for _ in range(300):
        s_add = float(rng.uniform(5.0, 400.0))
        bore = float(rng.uniform(5.0, 20.0))
        radius = bore / 2.0 + float(rng.uniform(2.5, 30.0))
        wall = float(rng.uniform(0.5, 3.0))
        limit = float(rng.uniform(2.0, 4.0) * s_add) if rng.random() < 0.5 else None
        try:
            b = build_extra(s_add, radius, bore_mm=bore, wall_mm=wall, max_s_gcm=limit,
                            where="[counterweights.x]")
        except NotBuildable as exc:
            refused += 1
            assert exc.where == "[counterweights.x]" and exc.hint
            continue
        built += 1
        _check_cup(b, s_add, radius, bore, wall)
        if limit is not None:
            assert b["s_built_gcm"] <= limit * (1.0 + 1e-12)
    assert built > 50 and refused > 10  # both sides were tried


def test_a_counterweight_that_cannot_be_built_is_refused_with_what_to_change():
    from sewmech.design.inserts import NotBuildable

    # the old recipe's own example: 64.1 g cm at 15 mm with a 10 mm deep hole wants a hole
    # 31 mm across, which crosses the shaft; the radii that hold it are named
    with pytest.raises(NotBuildable, match="no lead-insert counterweight.*can be built") as exc:
        build_extra(64.1, 15.0, bore_mm=10.0, depth_mm=10.0, factor=3.0, where="cw")
    assert "radius_mm between" in exc.value.hint
    # no room outside the shaft for a hole and its walls
    with pytest.raises(NotBuildable, match="no room"):
        build_extra(64.1, 7.0, bore_mm=12.0)
    # the space's limit below even the paper's least margin
    with pytest.raises(NotBuildable, match="space allows") as exc:
        build_extra(135.0, 18.0, bore_mm=12.0, max_s_gcm=300.0)
    assert "max_static_moment_gcm" in exc.value.hint
    # the margin comes down from 3 x to what fits under the limit, and says so
    b = build_extra(135.0, 18.0, bore_mm=12.0, max_s_gcm=400.0)
    assert b["factor"] == pytest.approx(2.9) and "400 g cm" in b["factor_note"]
