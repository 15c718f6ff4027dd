"""Calibrating the housing from the bench (issue 31): a bench made by the model itself with
known mounts (and a known counterweight angle) is recovered; the calibrated crossing is the
crossing of the calibrated curves found by root-finding; the shipped example is answered
honestly; the command's options are located when wrong."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import brentq

from sewmech.design.balancing import balance_basis
from sewmech.design.calibration import _scaled, calibrate
from sewmech.engine.housing import vibration
from sewmech.engine.machine import load_machine
from test_balancing_cli import run

S_GCM = np.repeat([85.0, 105.0, 125.0, 145.0, 165.0, 185.0, 205.6], 3)


@pytest.fixture(scope="module")
def bartack():
    m = load_machine("bartack-1820")
    return m, balance_basis(m, ["extra"])


def bench(basis, s_gcm, k, eta, angle_deg=180.0):
    """The model's x and y RMS velocities (mm/s) at the control point with the mounts'
    stiffness times k and loss factor eta, the extra counterweight at angle_deg."""
    b = math.radians(angle_deg)
    xy = (np.asarray(s_gcm) / 100.0)[:, None] * np.array([math.cos(b), math.sin(b)])
    W = basis.quantities(xy[:, None, :])["W"]
    v = vibration(_scaled(basis.housing, k, eta, False), W, basis.rpm).rms_velocity
    return v[:, basis.control, 0], v[:, basis.control, 1]


def test_a_bench_made_by_the_model_gives_back_its_mounts(bartack):
    """No noise: the fit returns the bench's stiffness factor and loss factor to 1e-6 and an
    RMS error of round-off; its crossing is where the calibrated curves cross (brentq on
    v_x - v_y of the same model, an independent root)."""
    m, B = bartack
    vx, vy = bench(B, S_GCM, 0.7, 0.3)
    c = calibrate(m, S_GCM, vx, vy)
    assert c.status == "fitted", c.message
    assert c.values["stiffness_factor"] == pytest.approx(0.7, rel=1e-6)
    assert c.values["loss_factor"] == pytest.approx(0.3, rel=1e-6)
    assert c.rms_log_error < 1e-8 and c.before_rms_log_error > 0.1

    def gap(s):
        x, y = bench(B, [s], 0.7, 0.3)
        return x[0] - y[0]

    s = np.linspace(1.0, 400.0, 400)
    x, y = bench(B, s, 0.7, 0.3)
    sign = np.nonzero(np.diff(np.sign(x - y)))[0]
    roots = [brentq(gap, s[i], s[i + 1], xtol=1e-10) for i in sign]
    assert roots and min(abs(r - c.crossing_gcm) for r in roots) < 1e-3 * c.crossing_gcm
    # the model as the file has it crosses elsewhere, and the curves for the plot are the
    # calibrated model's
    assert abs(c.model_crossing_gcm - c.crossing_gcm) > 1.0
    xg, yg = bench(B, c.curves["S_gcm"], 0.7, 0.3)
    np.testing.assert_allclose(c.curves["calibrated"][:, 0], xg, rtol=1e-6)
    np.testing.assert_allclose(c.curves["calibrated"][:, 1], yg, rtol=1e-6)


def test_noise_stays_within_the_reported_uncertainty(bartack):
    """5 % log-normal noise: each fitted value within three of its standard deviations of the
    bench's, and the standard deviation about what the noise gives (not zero, not huge)."""
    m, B = bartack
    vx, vy = bench(B, S_GCM, 1.1, 0.2)
    rng = np.random.default_rng(31)
    vx = vx * np.exp(rng.normal(0.0, 0.05, vx.size))
    vy = vy * np.exp(rng.normal(0.0, 0.05, vy.size))
    c = calibrate(m, S_GCM, vx, vy)
    assert c.status == "fitted", c.message
    for name, true in (("stiffness_factor", 1.1), ("loss_factor", 0.2)):
        assert abs(c.values[name] - true) < 3.0 * c.std[name], (name, c.values, c.std)
        assert 1e-4 * true < c.std[name] < 0.5 * true
    assert c.rms_log_error == pytest.approx(0.05, rel=0.4)


def test_the_counterweights_angle_is_fitted_when_asked(bartack):
    """A bench whose extra counterweight sits at 165 deg (not the file's 180): fitting the
    angle finds it, and without it the fit is worse."""
    m, B = bartack
    vx, vy = bench(B, S_GCM, 1.2, 0.2, angle_deg=165.0)
    c = calibrate(m, S_GCM, vx, vy, fit_angle=True)
    assert c.values["angle_deg"] == pytest.approx(165.0, abs=1e-4)
    assert c.values["stiffness_factor"] == pytest.approx(1.2, rel=1e-5)
    assert c.rms_log_error < 1e-7
    fixed = calibrate(m, S_GCM, vx, vy)
    assert fixed.rms_log_error > 100 * c.rms_log_error


def test_the_shipped_example_is_answered_honestly():
    """The synthetic example's straight lines are not the model's curves: the command fits what
    it can, says which value ran to its bound or is not determined, and still gives every
    crossing; --out writes the calibration's plot and curves."""
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent / "examples" / "measurements"
    code, text = run("trial-balance", root / "bartack-1820-vibration.csv", "--calibrate",
                     "bartack-1820", "--json")
    assert code == 0, text
    data = json.loads(text)
    cal = data["calibration"]
    assert cal["rms_log_error"] < cal["before_rms_log_error"]
    assert cal["status"] in ("bounded", "undetermined")
    assert "at the bound" in cal["message"] or "not determined" in cal["message"]
    for key in ("crossing_gcm", "model_crossing_gcm", "delta_q_gcm", "measured_crossing_gcm"):
        assert cal[key] is not None and 50.0 < cal[key] < 250.0, key
    assert cal["measured_crossing_gcm"] == pytest.approx(data["s_add_gcm"], rel=1e-12)


def test_calibration_options_are_located(tmp_path):
    from pathlib import Path

    csv = Path(__file__).resolve().parent.parent / "examples" / "measurements" \
        / "bartack-1820-vibration.csv"
    code, text = run("trial-balance", csv, "--fit-angle")
    assert code == 2 and "--fit-angle" in text and "--calibrate" in text
    code, text = run("trial-balance", csv, "--calibrate", "embroidery-131")
    assert code == 2 and "--calibrate" in text and "[housing]" in text
    code, text = run("trial-balance", csv, "--calibrate", "bartack-1820", "--counterweight",
                     "nope")
    assert code == 2 and "--counterweight" in text and "extra" in text
    code, text = run("trial-balance", csv, "--calibrate", "bartack-1820", "--control-point",
                     "elbow")
    assert code == 2 and "--control-point" in text and "hands" in text
    few = tmp_path / "few.csv"
    few.write_text("s_add_gcm,vx_mm_s,vy_mm_s\n100,5,6\n150,6,5\n", encoding="utf-8")
    code, text = run("trial-balance", few, "--calibrate", "bartack-1820")
    assert code == 2 and "few.csv" in text and "at least 3" in text
    assert "Traceback" not in text


def test_the_scaled_housing_scales_what_it_says(bartack):
    """_scaled multiplies the mounts' stiffness (and the structural part with it) and sets the
    loss factor; the mass is untouched."""
    _, B = bartack
    h = _scaled(B.housing, 2.0, 0.4, False)
    np.testing.assert_allclose(h.K, 2.0 * B.housing.K)
    np.testing.assert_allclose(h.M, B.housing.M)
    assert h.eta == 0.4
    assert replace(h, eta=B.housing.eta).eta == B.housing.eta
