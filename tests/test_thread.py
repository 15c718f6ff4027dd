"""The thread path and the take-up's supply, against geometry computed by hand here."""

import math

import numpy as np
import pytest

import sewmech
from sewmech.errors import MachineFileError
from sewmech.thread import path_length, thread_path


def _over_pin(A, C, B, r):
    """A taut thread from A round a pin (centre C, radius r) to B, the pin bending it: two
    tangents and the arc between the tangent points (the classic belt construction)."""
    A, C, B = (np.asarray(x, float) for x in (A, C, B))
    da, db = np.linalg.norm(A - C), np.linalg.norm(B - C)
    ca, cb = (A - C) / da, (B - C) / db
    between = math.acos(np.clip(ca @ cb, -1, 1))  # angle ACB at the centre
    arc = 2 * math.pi - between - math.acos(r / da) - math.acos(r / db)
    return math.sqrt(da**2 - r**2) + math.sqrt(db**2 - r**2) + r * arc


def test_straight_path_is_the_sum_of_distances():
    pts = np.array([[0, 0], [3, 4], [3, 10], [-5, 10]], float)
    assert path_length(pts, np.zeros(4)) == pytest.approx(5 + 6 + 8, abs=1e-12)


@pytest.mark.parametrize("wrap", [-1, 1])
def test_wrap_over_a_pin(wrap):
    # the thread passes over (cw) a pin at (0, 3), or under its mirror image (ccw)
    A, C, B, r = (-10.0, 0.0), (0.0, 3.0 * -wrap), (10.0, 0.0), 2.0
    expected = _over_pin(A, C, B, r)
    assert path_length([A, C, B], [0.0, wrap * r, 0.0]) == pytest.approx(expected, abs=1e-12)
    # the arc is 55.5 deg here: the hand numbers, once more
    assert expected == pytest.approx(2 * math.sqrt(109 - 4) + 2 * math.radians(55.49), abs=2e-3)


def test_wrap_more_than_half_a_turn():
    # out along y = 0, round the far side of a pin of radius 2 at (0, 2), back along y = 4
    L = path_length([(-10.0, 0.0), (0.0, 2.0), (-10.0, 4.0)], [0.0, 2.0, 0.0])
    assert L == pytest.approx(20.0 + 2 * math.pi, abs=1e-12)
    # wrapped the other way the thread would have to go round almost a whole turn
    L_cw = path_length([(-10.0, 0.0), (0.0, 2.0), (-10.0, 4.0)], [0.0, -2.0, 0.0])
    assert L_cw > L


def test_crossed_tangent_between_opposite_wraps():
    # two pins wrapped in opposite senses: the straight part is the inner tangent,
    # sqrt(D^2 - (r1 + r2)^2); with symmetric points the arcs are equal and computed by hand
    r = 1.0
    pts = [(-10.0, 5.0), (-4.0, 0.0), (4.0, 0.0), (10.0, -5.0)]
    L = path_length(pts, [0.0, -r, r, 0.0])
    D = 8.0
    inner = math.sqrt(D**2 - (2 * r) ** 2)
    # direction of the inner tangent: turned from +x by asin(2r / D) (downwards here)
    ang_in = -math.asin(2 * r / D)
    # end tangent from (-10, 5) to the pin at (-4, 0), thread passing above it (cw)
    v = np.array([6.0, -5.0])
    dA = np.linalg.norm(v)
    tA = math.sqrt(dA**2 - r**2)
    ang_a = math.atan2(v[1], v[0]) + math.asin(r / dA)  # tangent above the pin: turned up
    arc = (ang_a - ang_in) % (2 * math.pi)  # right turn from the end tangent to the inner one
    assert L == pytest.approx(2 * tA + inner + 2 * r * arc, abs=1e-12)


def test_overlapping_guides_are_an_error():
    with pytest.raises(ValueError, match="guides 1 and 2 overlap"):
        path_length([(0, 0), (0, 5), (0, 6), (0, 20)], [0.0, 2.0, -2.0, 0.0])
    with pytest.raises(ValueError, match="point guide"):
        path_length([(0, 0), (5, 0)], [1.0, 0.0])


@pytest.fixture(scope="module")
def jb():
    return sewmech.load_machine("jb1-3")


def test_jb_path_against_its_guides(jb):
    """The machine's path length from the guides' positions, computed here segment by segment."""
    phi = np.radians(np.arange(0.0, 360.0, 7.0))
    tp = thread_path(jb, phi)
    r = sewmech.kinematics(jb, phi)
    T = r.point("thread.tension").p
    P = r.point("thread.check_post").p
    E = r.point("take_up.eye").p
    G = r.point("thread.face_guide").p
    NB = r.point("needle_bar.thread_guide").p
    NE = r.point("needle.eye").p
    dist = lambda a, b: np.linalg.norm(a - b, axis=-1)  # noqa: E731
    tu = np.array([_over_pin(T[k], P[k], E[k], 2.0) for k in range(len(phi))]) + dist(E, G)
    below = dist(G, NB) + dist(NB, NE)
    np.testing.assert_allclose(tp.take_up, tu, atol=1e-10)
    np.testing.assert_allclose(tp.below, below, atol=1e-10)
    np.testing.assert_allclose(tp.total, tu + below, atol=1e-10)
    np.testing.assert_allclose(tp.supply, tu.max() - tu, atol=1e-10)


def test_supply_over_a_cycle(jb):
    """The take-up returns every bit of thread it releases: S(0) = S(360); its stroke is the
    range of its section, and the eye's top is the least supply (the stitch is set there)."""
    phi = np.radians(np.arange(0.0, 361.0, 1.0))
    tp = thread_path(jb, phi)
    assert tp.supply[-1] == pytest.approx(tp.supply[0], abs=1e-9)
    assert float(tp.stroke) == pytest.approx(np.ptp(tp.supply), abs=1e-12)
    assert 80.0 < float(tp.stroke) < 130.0  # household take-ups draw about 100 mm
    eye_top = np.argmax(sewmech.kinematics(jb, phi).point("take_up.eye").p[:, 1])
    assert abs(tp.phi_deg[np.argmin(tp.supply)] - tp.phi_deg[eye_top]) < 12.0


def test_thread_table_errors():
    from sewmech.spec import parse_machine

    base = sewmech.load_machine("jb1-3").file
    text = open(base).read()
    bad = text.replace('{ point = "thread.face_guide" }', '{ point = "thread.face_guid" }')
    with pytest.raises(MachineFileError, match=r"thread.*guides\[3\]\.point.*unknown point"):
        sewmech.machine_from_toml(bad, "jb.toml")
    bad = text.replace("take_up = [0, 3]", "take_up = [0, 1]")
    with pytest.raises(MachineFileError, match="guide 1 .* must be a point guide"):
        parse_machine(bad, "jb.toml")


def test_taut_round_a_circle():
    from sewmech.thread import _taut_round_circle

    # clear of the circle: straight
    assert _taut_round_circle([0, 10], [0, 0], 2.0, [10, 10]) == pytest.approx(10.0)
    # blocked, A and B on opposite sides: round the side where the straight line passes, with
    # the arc between the tangent points = angle ACB - acos(r/|CA|) - acos(r/|CB|)
    for B in ((1.0, -10.0), (-1.0, -10.0)):
        A, C, r = np.array([0.0, 10.0]), np.zeros(2), 2.0
        da, db = np.linalg.norm(A - C), np.linalg.norm(np.subtract(B, C))
        acb = math.acos((A - C) @ np.subtract(B, C) / (da * db))
        expected = (math.sqrt(da**2 - r**2) + math.sqrt(db**2 - r**2)
                    + r * (acb - math.acos(r / da) - math.acos(r / db)))
        assert _taut_round_circle(A, C, r, B) == pytest.approx(expected, abs=1e-12)


def test_consumption_matches_the_industry_formula():
    from sewmech.thread import consumption_per_stitch

    l = np.array([1.0, 2.5, 4.0])
    t = np.array([0.5, 1.0, 6.0])
    c = consumption_per_stitch(l, t)
    # C = 2 + 2 T S inches per inch of seam, T in inches, S stitches per inch: per stitch
    S = 25.4 / l
    per_stitch_mm = (2 + 2 * (t / 25.4) * S) / S * 25.4
    np.testing.assert_allclose(c["total"], per_stitch_mm, rtol=1e-12)
    np.testing.assert_allclose(c["needle"], l + t)
    d = consumption_per_stitch(2.5, 1.0, 0.2)
    assert d["needle"] == pytest.approx(3.5 + 0.1 * math.pi)


def test_balance_parts(jb):
    """Demand parts against the kinematics, computed here; the loop's largest size against the
    estimate from [US-10017890] (half the bobbin case's perimeter plus twice its depth below the
    plate)."""
    from sewmech.thread import thread_balance

    b = thread_balance(jb, step_deg=1.0)
    phi = np.radians(b.phi_deg)
    r = sewmech.kinematics(jb, phi)
    eye = r.point("needle.eye").p
    np.testing.assert_allclose(b.penetration, np.maximum(0.0, -140.0 + 1.0 - eye[:, 1]), atol=1e-12)
    tp = thread_path(jb, phi)
    np.testing.assert_allclose(b.bar, tp.below, atol=1e-12)
    k = int(np.argmin(tp.supply))
    # exactly 0: the demand is counted from its own value at the take-up's top
    assert b.demand[k] == 0.0 and b.take_up_top_deg == b.phi_deg[k]
    np.testing.assert_allclose(b.overfeed, tp.supply - b.demand, atol=1e-12)
    # the loop: none outside seizure .. cast-off; the size of the DOMAIN estimate (which is
    # itself approximate: our legs both follow the case's outline, 13 % more here)
    R, depth = 12.0, 167.5 - 140.0 - 12.0
    estimate = math.pi * R + 2 * depth
    assert 0.8 * estimate < b.loop.max() < 1.2 * estimate
    outside = (b.phi_deg - b.seizure_deg) % 360 > (b.cast_off_deg - b.seizure_deg) % 360 + 1
    assert np.all(b.loop[outside] == 0.0)  # set to 0 there, not computed
    assert b.consumption_mm == pytest.approx(2.5 + 1.0 + 0.1 * math.pi)
    # events on the balance's own grid against the timing module's root finds (Brent)
    from sewmech import timing as T

    assert b.seizure_deg == pytest.approx(T.loop_lift(jb).phi_deg, abs=1e-6)
    assert b.needle_entry_deg == pytest.approx(T.needle_windows(jb)[0].start_deg, abs=1e-6)


def test_thread_checks_from_the_balance(jb):
    """The checks read the balance where the formulation says: the least overfeed between seizure
    and the loop's largest size, the overfeed as the eye enters the fabric, and after cast-off."""
    from sewmech.thread import check_thread, thread_balance

    b = thread_balance(jb)
    c = {x.name: x for x in check_thread(jb, b)}
    loop_on = b.loop > 0
    k_max = int(np.argmax(b.loop))
    grow = ((b.phi_deg - b.seizure_deg) % 360 <= (b.phi_deg[k_max] - b.seizure_deg) % 360)
    assert c["least overfeed while the shuttle enlarges the loop"].value == pytest.approx(
        b.overfeed[grow].min())
    assert np.count_nonzero(~loop_on[grow]) <= 1  # the loop exists all through it (0 at seizure)
    k_e = np.argmin(np.abs((b.phi_deg - b.needle_entry_deg + 180) % 360 - 180))
    assert c["overfeed when the needle enters the fabric"].value == pytest.approx(
        b.overfeed[k_e], abs=0.3)  # within half a degree of the entry
    first_off = (k_max + 1) % len(b.phi_deg)
    assert b.loop[first_off] == 0.0
    assert c["take-up reserve once the loop is cast off"].value == pytest.approx(
        b.overfeed[first_off])


def test_adjustable_take_up_against_single_balances(jb):
    """Each recommended setting, evaluated on its own with thread_balance and check_thread,
    passes every check, with the smallest slack equal to the reported margin; a setting next to
    it has no larger margin."""
    from sewmech.thread import CHECK_SPRING_STROKE_MM, adjust_take_up, check_thread, \
        thread_balance

    adj = jb.spec.thread.adjust
    settings = np.linspace(adj.min, adj.max, 29)
    r = adjust_take_up(jb, adj.parameter, settings, thickness_mm=[0.5, 2.0, 5.0])
    assert np.isfinite(r.best).all()
    assert np.all(np.diff(r.best) != 0)  # the setting follows the fabric

    def slack(t, q):
        p = jb.parameters({adj.parameter: q})
        b = thread_balance(jb, fabric_mm=t, params=p)
        c = {x.name: x for x in check_thread(jb, b)}
        o_e = c["overfeed when the needle enters the fabric"].value
        return b, c, min(c["least overfeed while the shuttle enlarges the loop"].value, o_e,
                         CHECK_SPRING_STROKE_MM - o_e,
                         c["take-up reserve once the loop is cast off"].value - b.consumption_mm)

    for t, q, m in zip(r.thickness_mm, r.best, r.best_margin):
        b, c, s = slack(t, q)
        assert all(x.passed for x in c.values()), (t, q)
        assert s == pytest.approx(m, abs=1e-9)
        j = int(np.nonzero(settings == q)[0][0])
        for k in (j - 1, j + 1):
            if 0 <= k < settings.size:
                try:
                    assert slack(t, settings[k])[2] <= m + 1e-9
                except sewmech.AssemblyError:  # the take-up does not assemble there:
                    assert np.isnan(r.margin[list(r.thickness_mm).index(t), k])  # masked
