"""Exact design sensitivities of positions (issue 17, first part): against closed forms and
against central differences of the kinematics on every shipped machine (every unit type:
cranks driven by the shaft and by a setting, points, RRR, RRP on the frame and in a moving slot,
RPR, loops with vector and cam terms)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import SLIDER_CRANK, fourbar

import sewmech
from sewmech.engine.machine import shipped_machines
from sewmech.engine.sensitivity import sensitivities

PHI = np.radians(np.arange(0.37, 360.0, 17.0))


def richardson(machine, phi, P0, keep, h_rel=3e-4, attrs=("p", "theta", "q"), mask=False):
    """Central differences of p, theta, q by every parameter with Richardson's extrapolation
    ((4 D(h/2) - D(h)) / 3, error O(h^4)): all 4 n designs in one kinematics call. The step is
    not smaller because the loop solver's tolerance (about 1e-10 mm) divided by the step is the
    other error. Parameters not in ``keep`` are not stepped (their column is 0)."""
    n = len(P0)
    h = np.where(keep, h_rel * np.maximum(1.0, np.abs(P0)), 0.0)
    steps = np.concatenate([h, -h, h / 2, -h / 2])
    h = np.where(keep, h, 1.0)
    P = np.tile(P0, (4 * n, 1))
    P[np.arange(4 * n), np.tile(np.arange(n), 4)] += steps
    r = sewmech.kinematics(machine, phi, params=P, on_failure="mask" if mask else "raise")
    out = []
    for arr in (getattr(r, x) for x in attrs):
        a = arr.reshape((4, n) + arr.shape[1:])
        d1 = (a[0] - a[1]) / (2 * h).reshape((n,) + (1,) * (a.ndim - 2))
        d2 = (a[2] - a[3]) / h.reshape((n,) + (1,) * (a.ndim - 2))
        out.append(np.moveaxis((4 * d2 - d1) / 3, 0, -1))  # parameter axis last
    return out


def worst_relative(d, ref, keep) -> float:
    """The largest difference of derivatives ``d`` from ``ref`` (parameter axis last) over
    the parameters ``keep``, each relative to max(1, its largest reference value); 0 for a
    machine without such channels."""
    if ref.size == 0:
        return 0.0
    axes = tuple(range(ref.ndim - 1))
    err = np.abs(d[..., keep] - ref[..., keep]).max(axis=axes)
    return float((err / np.maximum(1.0, np.abs(ref[..., keep]).max(axis=axes))).max())


@pytest.mark.parametrize("name", sorted(shipped_machines()))
def test_sensitivities_equal_central_differences_on_every_shipped_machine(name):
    m = sewmech.load_machine(name)
    if "regulator" in m.spec.inputs:
        # the regulator at its zero mark, inside its range: the file's working setting is the
        # range's end, where a central difference of the setting would step outside it
        m = m.with_parameters({"input.regulator": 0.0})
    S = sensitivities(m, PHI)
    P0 = np.array(m.defaults)
    # the counterweights do not move anything (their parameters' derivatives are 0), and a
    # step below 0 g cm is outside their domain
    keep = np.array([not any(p.startswith(c.name + ".") for c in m.counterweights)
                     for p in m.parameter_names])
    fd = richardson(m, PHI, P0, keep)
    for d, ref, what in ((S.dp, fd[0], "p"), (S.dtheta, fd[1], "theta"), (S.dq, fd[2], "q")):
        assert worst_relative(d, ref, keep) < 1e-6, (name, what)
    # exactly 0: no unit's support holds a counterweight, so nothing is written in its column
    assert np.abs(S.dp[..., ~keep]).max(initial=0.0) == 0.0
    # the rates: velocities, angular velocities and joint rates at the file's speed, and the
    # accelerations (their differences need a longer step: the loop solver's tolerance over
    # the step is amplified by the speed squared; a step that makes the mechanism fail to
    # assemble leaves that parameter out)
    R = sensitivities(m, PHI, rates=True)
    # two steps, each limited by another error (truncation at the long one, the solver's
    # tolerance at the short one): the derivative must meet one of them; a speed ratio is no
    # dimension (its step turns the cams by whole degrees over the march) and stays out
    dims = keep & np.array([not p.endswith(".ratio") for p in m.parameter_names])
    fds = [richardson(m, PHI, P0, dims, h_rel=h, attrs=("a", "epsilon", "q_ddot"), mask=True)
           for h in (3e-4, 3e-3)]
    for k, (d, what) in enumerate(((R.da, "a"), (R.depsilon, "epsilon"), (R.dqdd, "qdd"))):
        if fds[0][k].size == 0:
            continue
        errs = []
        for fd in fds:
            ref = fd[k]
            axes = tuple(range(ref.ndim - 1))
            err = np.abs(d - ref).max(axis=axes) / np.maximum(1.0, np.abs(ref).max(axis=axes))
            errs.append(np.where(np.isfinite(err), err, np.inf))
        worst = np.minimum(*errs)[dims]
        assert np.isfinite(worst).all() and worst.max() < 1e-6, (name, what, worst.max())
    # exact: both kernels take the positions' tangents from the same compiled unit functions
    # (the level is their argument), the same operations in the same order
    assert np.array_equal(R.dp, S.dp)
    fd = richardson(m, PHI, P0, keep, attrs=("v", "omega", "q_dot"))
    for d, ref, what in ((R.dv, fd[0], "v"), (R.domega, fd[1], "omega"), (R.dqd, fd[2], "qd")):
        assert worst_relative(d, ref, keep) < 1e-6, (name, what)


def test_slider_crank_closed_forms():
    """x = r cos(t) + sqrt(l^2 - r^2 sin^2 t) on a guide through the crank's axis:
    dx/dr = cos t - r sin^2 t / sqrt(l^2 - r^2 sin^2 t), dx/dl = l / sqrt(l^2 - r^2 sin^2 t);
    both 1 at the top dead centre, and the stroke 2 r has d/dr = 2, d/dl = 0."""
    r, l = 15.0, 44.0
    m = sewmech.machine_from_toml(SLIDER_CRANK.format(r=r, l=l, e=0.0, alpha=0.0, gx=0.0,
                                                      gy=0.0, branch=1))
    t = np.radians(np.arange(0.0, 360.0, 10.0))
    S = sensitivities(m, t)
    x, dx, unit = S.channel("q_slider")
    names = m.parameter_names
    root = np.sqrt(l * l - r * r * np.sin(t) ** 2)
    assert np.allclose(x, r * np.cos(t) + root, atol=1e-9) and unit == "mm"
    np.testing.assert_allclose(dx[:, names.index("B.u")],
                               np.cos(t) - r * np.sin(t) ** 2 / root, atol=1e-12)
    np.testing.assert_allclose(dx[:, names.index("slider.length")], l / root, atol=1e-12)
    assert dx[0, names.index("B.u")] == pytest.approx(1.0, abs=1e-12)
    assert dx[0, names.index("slider.length")] == pytest.approx(1.0, abs=1e-12)
    bdc = int(np.argmin(np.abs(t - math.pi)))
    stroke = dx[0] - dx[bdc]
    assert stroke[names.index("B.u")] == pytest.approx(2.0, abs=1e-12)
    assert stroke[names.index("slider.length")] == pytest.approx(0.0, abs=1e-12)


def test_four_bar_output_angle_closed_forms():
    """a e^{i t2} + b e^{i t3} = d + c e^{i t4}, differentiated with t2 held: the real part
    after multiplying by e^{-i t3} eliminates dt3, so
    dt4 = Re[(dd + dc e^{i t4} - da e^{i t2} - db e^{i t3}) e^{-i t3}] / (c sin(t4 - t3))."""
    m = fourbar()
    t = np.radians(np.arange(3.0, 360.0, 11.0))
    S = sensitivities(m, t)
    r = S.kin
    t2 = r.link("crank").theta
    t3 = r.link("coupler").theta
    t4 = r.link("rocker").theta
    c = 35.0
    den = c * np.sin(t4 - t3)
    expected = {"B.u": -np.cos(t2 - t3) / den, "dyad.length1": -1.0 / den,
                "dyad.length2": np.cos(t4 - t3) / den, "D.x": np.cos(t3) / den}
    _, d, unit = S.channel("theta_rocker")
    assert unit == "rad"
    for name, ref in expected.items():
        np.testing.assert_allclose(d[:, m.parameter_names.index(name)], ref, rtol=1e-10,
                                   atol=1e-13, err_msg=name)


def test_sensitivity_command_prints_the_issue_keys(tmp_path):
    from typer.testing import CliRunner

    from sewmech.cli import app

    out = CliRunner().invoke(app, ["sensitivity", "jb1-3", "--output", "p_needle.point_y",
                                   "--phi-deg", "30", "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.output)
    assert data["output"] == "p_needle.point_y" and data["phi_deg"] == 30.0
    m = sewmech.load_machine("jb1-3")
    S = sensitivities(m, np.radians([30.0]))
    v, d, _ = S.channel("p_needle.point_y")
    assert data["value"] == pytest.approx(float(v[0]))
    assert set(data["d_dparam"]) == set(m.parameter_names)
    j = m.parameter_names.index("needle_bar.length")
    assert data["d_dparam"]["needle_bar.length"] == pytest.approx(float(d[0, j]))
    acc = CliRunner().invoke(app, ["sensitivity", "jb1-3", "--output", "a_needle.point_y",
                                   "--phi-deg", "30", "--json"])
    assert acc.exit_code == 0, acc.output
    R = sensitivities(m, np.radians([30.0]), rates=True)
    assert json.loads(acc.output)["d_dparam"]["needle_bar.length"] == pytest.approx(
        float(R.channel("a_needle.point_y")[1][0, j]))
    bad = CliRunner().invoke(app, ["sensitivity", "jb1-3", "--output", "j_needle.point_y"])
    assert bad.exit_code == 2 and "not a channel" in bad.output
    bad = CliRunner().invoke(app, ["sensitivity", "jb1-3", "--output", "p_nothing_y"])
    assert bad.exit_code == 2 and "nothing" in bad.output


def test_sensitivity_ranks_by_what_each_tolerance_moves_the_output():
    """Derivatives of different units (mm per mm, mm per rad, mm per 1) were ranked by their
    raw size, so a speed ratio and an angle in radians led the needle's height; and a
    round-off derivative read 6.12323e-17. They are ranked by derivative x tolerance (IT9 on
    lengths, +-0.05 deg on angles, stated in the table), what is no made dimension is listed
    apart, and a derivative at round-off counts as not moving the output."""
    from typer.testing import CliRunner

    from sewmech.cli import app
    from sewmech.design.tolerance_file import it_tolerance_mm

    args = ["sensitivity", "jb1-3", "--output", "p_needle.point_y", "--phi-deg", "30"]
    out = CliRunner().invoke(app, [*args, "--top", "15"], env={"COLUMNS": "200"})
    assert out.exit_code == 0, out.output
    text = out.stdout
    assert "IT9 on lengths, +-0.05 deg on angles" in text
    assert "e-17" not in text and "e-16" not in text
    rows = [[c.strip() for c in line.split("│")[1:-1]] for line in text.splitlines()]
    rows = [r for r in rows if len(r) == 5 and r[0] and r[0] != "parameter"]
    m = sewmech.load_machine("jb1-3")
    S = sensitivities(m, np.radians([30.0]))
    _, d, _ = S.channel("p_needle.point_y")
    effects = []
    for name, tol, effect, deriv, unit in rows:
        j = m.parameter_names.index(name)
        t = (0.5 * it_tolerance_mm(m.defaults[j], 9) if unit == "mm per mm" else
             math.radians(0.05))
        assert tol == (f"+-{t:.3g} mm" if unit == "mm per mm" else "+-0.05 deg")
        assert float(deriv) == pytest.approx(d[0, j], rel=1e-5)
        assert float(effect) == pytest.approx(d[0, j] * t, rel=1e-3)
        effects.append(abs(float(effect)))
    assert effects == sorted(effects, reverse=True)
    assert rows[0][0] == "needle.point.u"  # 1 mm per mm at +-0.0435 mm (IT9 of 119 mm)
    names = [r[0] for r in rows]
    # the crank's phase (10.9 mm per rad) below the needle-bar link (1.05 mm per mm): 0.05 deg
    # of phase moves the point 0.0095 mm, the link's IT9 0.033 mm
    assert names.index("needle_bar.length") < names.index("needle_crank.phase")
    assert "needle_crank.ratio" not in names and "not toleranced" in text
    assert "needle.point.v" not in names  # its derivative is round-off (6e-17 mm per mm)
    assert "117 do not move" in text  # of 126 (4 more: the feed-bar spring's hook and anchor)
    data = json.loads(CliRunner().invoke(app, [*args, "--json"]).stdout)
    assert data["effects"]["needle_bar.length"] == pytest.approx(
        data["d_dparam"]["needle_bar.length"] * data["tolerances"]["needle_bar.length"])
    assert "needle_crank.ratio" not in data["effects"]


def test_sensitivity_ranks_by_the_tolerances_of_a_file(tmp_path):
    """With a tolerance file, its tolerances rank: angles at +-1 deg put the crank's phase and
    the guide's angle (10.86 mm per rad: 0.19 mm) above every length."""
    from typer.testing import CliRunner

    from sewmech.cli import app

    path = tmp_path / "t.toml"
    path.write_text("[defaults]\nit_grade = 9\nangle_deg = 1.0\n")
    out = CliRunner().invoke(app, ["sensitivity", "jb1-3", "--output", "p_needle.point_y",
                                   "--phi-deg", "30", "--tolerances", str(path), "--json"])
    assert out.exit_code == 0, out.output
    effects = json.loads(out.stdout)["effects"]
    top = sorted(effects, key=lambda k: -abs(effects[k]))[:2]
    assert set(top) == {"needle_crank.phase", "needle_bar.guide_angle"}
    assert effects["needle_crank.phase"] == pytest.approx(10.861 * math.radians(1.0), rel=1e-4)


def located_differences_agree(m, f, g, n_params: int, regulator_deg: float = 25.0) -> None:
    """``g`` (a metric's gradient by ``f``) against central differences with Richardson's
    extrapolation of the metric located again on perturbed designs, for the ``n_params``
    parameters that move it most (the setting input aside), to 1e-6."""
    P0 = np.array(m.defaults)
    names = m.parameter_names
    # (a crank's speed ratio is no dimension: the motion it makes repeats on another period,
    # and an event's angle jumps between turns)
    order = [j for j in np.argsort(-np.abs(g.d_dparam))
             if names[j] != "input.regulator" and not names[j].endswith(".ratio")]
    for j in order[:n_params]:
        h = 1e-4 * max(1.0, abs(P0[j]))

        def at(step, j=j):
            P = P0.copy()
            P[j] += step
            return f(m, regulator_deg, params=P).value

        fd = (4 * (at(h / 2) - at(-h / 2)) / h - (at(h) - at(-h)) / (2 * h)) / 3
        assert g.d_dparam[j] == pytest.approx(fd, rel=1e-6, abs=1e-9), (g.metric, names[j])


def test_stitch_length_gradient_against_differences_of_located_events():
    """The stitch length's derivative (events moving with the design) against central
    differences of the stitch length located again on the perturbed designs (Richardson), for
    the parameters that move it most, and by the regulator setting itself."""
    from sewmech.sewing.feed import feed_cycles
    from sewmech.sewing.gradients import stitch_length_gradient

    m = sewmech.load_machine("jb1-3")
    g = stitch_length_gradient(m, 25.0)
    assert g.value == pytest.approx(float(feed_cycles(m, 25.0).stitch_mm), abs=1e-7)
    located_differences_agree(m, stitch_length_gradient, g, 8)
    names = m.parameter_names
    # by the setting: the input's derivative, per rad of regulator
    h = 1e-3  # deg
    fd = (stitch_length_gradient(m, 25.0 + h).value
          - stitch_length_gradient(m, 25.0 - h).value) / math.radians(2 * h)
    assert g.d_dparam[names.index("input.regulator")] == pytest.approx(fd, rel=1e-6)
    # the rise and fall are on the plate
    r = sewmech.kinematics(m, np.radians(list(g.events_deg.values())),
                           inputs={"regulator": math.radians(25.0)})
    plate = m.spec.sewing.plate_y
    assert np.abs(r.point("feed_dog.tip").p[..., 1] - plate).max() < 1e-10


def test_sensitivity_command_for_the_stitch_length():
    from typer.testing import CliRunner

    from sewmech.cli import app

    out = CliRunner().invoke(app, ["sensitivity", "jb1-3", "--output", "stitch_length",
                                   "--input", "regulator=25", "--json"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.output)
    assert data["output"] == "stitch_length" and data["unit"] == "mm"
    assert data["events_deg"]["regulator"] == 25.0
    from sewmech.sewing.gradients import stitch_length_gradient

    g = stitch_length_gradient(sewmech.load_machine("jb1-3"), 25.0)
    assert data["value"] == pytest.approx(g.value)
    assert data["d_dparam"]["feed_cam.arc0.radius"] == pytest.approx(
        g.as_dict()["feed_cam.arc0.radius"])
    bad = CliRunner().invoke(app, ["sensitivity", "bartack-1820", "--output", "stitch_length"])
    assert bad.exit_code == 2 and "stitch length" in bad.output


def test_a_batch_of_designs_equals_each_alone_and_a_huge_one_is_refused():
    from sewmech.engine.errors import AnalysisError

    m = sewmech.load_machine("jb1-3")
    phi = np.radians([10.0, 100.0, 250.0])
    P = m.parameters({"needle_bar.length": np.array([44.0, 45.0, 46.0])})
    S = sensitivities(m, phi, params=P)
    assert S.dp.shape == (3, 3, len(m.point_names), 2, len(m.parameter_names))
    for k in range(3):
        alone = sensitivities(m, phi, params=P[k])
        # exact: every position is a lane of its own, computed by the same instructions
        assert np.array_equal(S.dp[k], alone.dp) and np.array_equal(S.dtheta[k], alone.dtheta)
    with pytest.raises(AnalysisError, match="GiB"):
        sensitivities(m, np.radians(np.arange(0.0, 360.0, 0.1)),
                      params=np.tile(m.defaults, (40, 1)))


@pytest.mark.parametrize("metric", ["feed_lift", "dog_height_at_needle_plate", "needle_top_deg",
                                    "take_up_lag_deg", "needle_descent_at_take_up_top",
                                    "loop_lift", "shuttle_swing_deg"])
def test_metric_gradients_against_differences_of_located_events(metric):
    """The lift (a value at an extremum) and the dog's height when the needle reaches the plate
    (a value at another point's crossing): against central differences of the metric located
    again on perturbed designs (Richardson), for the parameters that move it most."""
    from sewmech.sewing.feed import check_feed
    from sewmech.sewing.gradients import METRICS

    m = sewmech.load_machine("jb1-3")
    f = METRICS[metric]
    g = f(m, 25.0)
    from sewmech.sewing import timing

    if metric == "feed_lift":
        from sewmech.sewing.feed import feed_cycles

        assert g.value == pytest.approx(float(feed_cycles(m, 25.0).lift_mm), abs=1e-6)
    elif metric == "needle_top_deg":
        assert g.value == pytest.approx(timing.needle_stroke(m).top_phi_deg, abs=1e-9)
    elif metric == "take_up_lag_deg":
        assert g.value == pytest.approx(timing.take_up_lag_deg(m), abs=1e-9)
    elif metric == "needle_descent_at_take_up_top":
        assert g.value == pytest.approx(timing.needle_descent_at_take_up_top(m), abs=1e-9)
    elif metric == "loop_lift":
        assert g.value == pytest.approx(timing.loop_lift(m).rise_mm, abs=1e-9)
    elif metric == "shuttle_swing_deg":
        assert g.value == pytest.approx(timing.shuttle_swing(m).swing_deg, abs=1e-9)
    else:  # the check at the longest stitch reads the same quantity
        at30 = f(m, 30.0).value
        check = next(c for c in check_feed(m) if c.name.startswith("dog height"))
        assert at30 == pytest.approx(check.value, abs=1e-6)
    located_differences_agree(m, f, g, 6)
    # the Monte Carlo's batch values (a 5 deg grid) against the located metric, for the
    # nominal and a changed design
    from sewmech.sewing.gradients import metric_values

    P = np.tile(m.defaults, (2, 1))
    j = int(np.argmax(np.abs(g.d_dparam) * (~np.array([n.endswith(".ratio") or n.startswith(
        "input.") for n in m.parameter_names]))))
    P[1, j] += 0.01 * max(1.0, abs(P[1, j]))
    batch = metric_values(m, metric, 25.0, P, step_deg=5.0)
    exact = [f(m, 25.0, params=P[k]).value for k in range(2)]
    np.testing.assert_allclose(batch, exact, atol=3e-4 if metric.endswith("deg") else 2e-5)


def test_the_command_line_offers_every_metric():
    from sewmech.app.cli.accuracy import METRICS as CLI
    from sewmech.sewing.gradients import METRICS

    assert set(CLI) == set(METRICS)


@pytest.mark.parametrize("channels", [["p_needle.point_y"],
                                      ["p_feed_dog.tip_x", "theta_take_up_lever"],
                                      ["q_needle_bar", "omega_big_rod"]])
def test_outputs_solve_only_what_the_channels_need(channels):
    """sensitivities(..., outputs=): the asked channels' values and derivatives (with the
    rates and accelerations) equal those of the whole machine's; only the units they depend on
    are solved (the needle's chain has no loop unit, so no feed point is in its result); a name
    that is not a channel is refused with the way out."""
    m = sewmech.load_machine("jb1-3")
    phi = np.radians([3.0, 91.0, 200.0, 311.0])
    whole = sensitivities(m, phi, rates=True)
    part = sensitivities(m, phi, rates=True, outputs=channels)
    for name in channels:
        head, _, rest = name.partition("_")
        rate = {"p": "v", "theta": "omega", "q": "qd"}.get(head, head)
        for kind in (name, f"{rate}_{rest}"):
            v0, d0, _ = whole.channel(kind)
            v1, d1, _ = part.channel(kind)
            np.testing.assert_array_equal(v1, v0)
            np.testing.assert_allclose(d1, d0, rtol=0, atol=1e-12 * max(1.0, np.abs(d0).max()))
    if channels == ["p_needle.point_y"]:
        assert "feed_dog.tip" not in part.kin.point_names
        assert len(part.kin.point_names) < len(whole.kin.point_names)
    with pytest.raises(KeyError, match="not a channel"):
        sensitivities(m, phi, outputs=["needle.point"])


def test_compact_point_and_dense_forms_agree():
    """The compact form (a channel's derivatives by its support only), one point's block and
    the dense arrays hold the same numbers; every parameter outside a channel's support has a
    zero derivative (checked against central differences above) and the names are the
    machine's."""
    m = sewmech.load_machine("jb1-3")
    phi = np.radians([5.0, 123.0, 250.0])
    S = sensitivities(m, phi, rates=True, outputs=["p_needle.point_y"])
    assert S.parameter_names == m.parameter_names
    i = S.kin.point_names.index("needle.point")
    v, d, sup, unit = S.compact("p_needle.point_y")
    v0, full, _ = S.channel("p_needle.point_y")
    np.testing.assert_array_equal(v, v0)
    assert unit == "mm" and d.shape == (3, len(sup)) and len(sup) < len(m.parameter_names)
    np.testing.assert_array_equal(full[:, sup], d)
    np.testing.assert_array_equal(np.delete(full, sup, axis=-1), 0.0)
    np.testing.assert_array_equal(S.dp[:, i, 1], full)
    for level, dense in enumerate((S.dp, S.dv, S.da)):
        np.testing.assert_array_equal(S.point("needle.point", level), dense[:, i])
