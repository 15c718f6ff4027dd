"""The balancing commands: `sewmech balance` (its JSON keys, the library's numbers, the
paper's workflow on the shipped bar-tack machine), `sewmech trial-balance` and
`sewmech influence-balance` (measurement files, their located errors)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from sewmech.cli import app
from typer.testing import CliRunner

from sewmech.design.balancing import balance
from sewmech.design.vibration import crossing
from sewmech.engine.machine import load_machine

runner = CliRunner()


def run(*args):
    out = runner.invoke(app, [str(a) for a in args])
    return out.exit_code, out.output


def test_balance_json_has_the_issue_keys_and_the_library_numbers():
    code, text = run("balance", "bartack-1820", "--json", "--step-deg", "2")
    assert code == 0, text
    data = json.loads(text)
    assert data["criterion"] == "delta-q" and data["status"] == "optimal"
    cw = data["counterweights"]["extra"]
    for key in ("static_moment_gcm", "angle_deg", "mass_g"):
        assert key in cw
    for side in ("before", "after"):
        for key in ("delta_q_N", "peak_force_N", "rms_force_N", "peak_moment_Nm",
                    "bearing_front_peak_N", "bearing_rear_peak_N"):
            assert isinstance(data[side][key], float), (side, key)
    lib = balance(load_machine("bartack-1820"), "delta-q", ["extra"], step_deg=2.0)
    assert cw["static_moment_gcm"] == pytest.approx(
        lib.counterweights["extra"]["static_moment_gcm"], rel=1e-12)
    assert data["after"]["delta_q_N"] < 1e-9 * data["before"]["peak_force_N"]
    # the paper's workflow: S_add, the crank's own S_1 and the built counterweight
    paper = data["paper"]
    assert paper["s_add_gcm"] == pytest.approx(cw["static_moment_gcm"])
    assert paper["build"]["s_built_gcm"] == pytest.approx(3.0 * paper["s_add_gcm"])


def test_balance_writes_its_figures_and_refuses_bad_options(tmp_path):
    code, text = run("balance", "bartack-1820", "--criterion", "rms", "--step-deg", "4",
                     "--out", tmp_path / "b")
    assert code == 0, text
    names = {p.name for p in (tmp_path / "b").iterdir()}
    for stem in ("bal-components", "bal-hodograph", "bal-bearings", "bal-front"):
        assert f"bartack-1820-{stem}.png" in names and f"bartack-1820-{stem}.csv" in names
    data = json.loads((tmp_path / "b" / "bartack-1820-balance.json").read_text())
    assert data["criterion"] == "rms"
    code, text = run("balance", "bartack-1820", "--counterweight", "nothing")
    assert code == 2 and "--counterweight" in text and "extra" in text
    code, text = run("balance", "bartack-1820", "--weight", "peak_force_N=2")
    assert code == 2 and "only the weighted criterion" in text
    code, text = run("balance", "bartack-1820", "--criterion", "weighted", "--weight", "peak=2")
    assert code == 2 and "unknown part" in text
    code, text = run("balance", "fourbar-benchmark")
    assert code == 2 and "has no counterweights" in text


def write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


def test_trial_balance_reads_the_measurements(tmp_path, rng):
    s = np.repeat([0.0, 50.0, 100.0, 150.0, 205.6], 2)
    vx = 9.0 - 0.03 * (s - 143.0) + rng.normal(scale=0.1, size=s.size)
    vy = 9.0 + 0.02 * (s - 143.0) + rng.normal(scale=0.1, size=s.size)
    lines = ["s_add_gcm,vx_mm_s,vy_mm_s,note"] + [f"{a},{b},{c},run" for a, b, c in
                                                  zip(s, vx, vy)]
    f = write(tmp_path / "v.csv", "\n".join(lines) + "\n")
    code, text = run("trial-balance", f, "--json")
    assert code == 0, text
    data = json.loads(text)
    ref = crossing(s, vx, vy)
    assert data["s_add_gcm"] == pytest.approx(ref.s_add_gcm, rel=1e-12)
    assert data["ci95_gcm"] == pytest.approx(list(ref.ci95_gcm), rel=1e-12)
    assert data["n_points"] == 10
    assert data["ci95_gcm"][0] < 143.0 < data["ci95_gcm"][1]
    code, text = run("trial-balance", f, "--out", tmp_path / "o")
    assert code == 0, text
    assert (tmp_path / "o" / "trial-balance.png").is_file()


@pytest.mark.parametrize("body, needle", [
    ("s_add_gcm,vx_mm_s\n0,1\n", "missing column(s) vy_mm_s"),
    ("s_add_gcm,vx_mm_s,vy_mm_s\n0,1,2\n50,abc,2\n", "v.csv:3: column vx_mm_s: 'abc' is not"),
    ("s_add_gcm,vx_mm_s,vy_mm_s\n0,5,1\n50,5,1\n100,5,1\n", "do not cross"),
    ("s_add_gcm,vx_mm_s,vy_mm_s\n0,5,4.5\n10,4,4.5\n20,3,4.5\n30,2,4.5\n",
     "below and"),
    ("", "is empty"),
])
def test_malformed_measurement_files_get_located_errors(tmp_path, body, needle):
    f = write(tmp_path / "v.csv", body)
    code, text = run("trial-balance", f)
    assert code == 2, text
    assert "v.csv" in text and needle in " ".join(text.split())


def test_influence_balance_from_a_csv(tmp_path, rng):
    A = rng.normal(size=(3, 2)) + 1j * rng.normal(size=(3, 2))
    U = np.array([40.0 * np.exp(1j * np.radians(120.0)), 15.0 * np.exp(1j * np.radians(-30))])
    V0 = A @ U
    trial = [30.0, 30.0]
    rows = ["run,place,amplitude_mm_s,phase_deg,trial_gcm,trial_angle_deg"]
    for p in range(3):
        rows.append(f"0,p{p},{float(abs(V0[p]))!r},{float(np.degrees(np.angle(V0[p])))!r},0,0")
    for j in range(2):
        V = V0 + A[:, j] * trial[j]
        for p in range(3):
            rows.append(f"{j + 1},p{p},{float(abs(V[p]))!r},{float(np.degrees(np.angle(V[p])))!r},30,0")
    f = write(tmp_path / "runs.csv", "\n".join(rows) + "\n")
    code, text = run("influence-balance", f, "--json")
    assert code == 0, text
    data = json.loads(text)
    got = [data["corrections"][f"run {j + 1}"] for j in range(2)]
    for g, u in zip(got, -U):
        assert g["static_moment_gcm"] == pytest.approx(abs(u), rel=1e-9)
        assert np.cos(np.radians(g["angle_deg"]) - np.angle(u)) == pytest.approx(1.0)
    assert data["after_rms_mm_s"] < 1e-9 * data["before_rms_mm_s"]
    bad = write(tmp_path / "bad.csv", "\n".join(rows[:-1]) + "\n")
    code, text = run("influence-balance", bad)
    assert code == 2 and "not measured: run 2 place p2" in text


def test_the_shipped_example_measurements():
    """examples/measurements: synthetic data made with a crossing at 143 g cm and a known
    unbalance (60 g cm at 200 deg, 25 g cm at 35 deg); the commands find them within noise."""
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent / "examples" / "measurements"
    code, text = run("trial-balance", root / "bartack-1820-vibration.csv", "--json")
    assert code == 0, text
    data = json.loads(text)
    assert data["ci95_gcm"][0] < 143.0 < data["ci95_gcm"][1] and data["n_points"] == 21
    code, text = run("influence-balance", root / "trial-runs.csv", "--json")
    assert code == 0, text
    c = json.loads(text)["corrections"]
    assert abs(c["run 1"]["static_moment_gcm"] - 60.0) < 3.0
    assert abs(c["run 2"]["static_moment_gcm"] - 25.0) < 3.0
    assert abs((c["run 1"]["angle_deg"] - 20.0 + 180.0) % 360.0 - 180.0) < 5.0
    assert abs((c["run 2"]["angle_deg"] + 145.0 + 180.0) % 360.0 - 180.0) < 5.0


def test_level_change_and_the_moment_point():
    code, text = run("level-change", "1.0", "0.5", "--json")
    assert code == 0, text
    data = json.loads(text)
    assert data["level_change_db"] == pytest.approx(20.0 * np.log10(0.5))
    assert data["before_db"] == pytest.approx(20.0 * np.log10(1.0 / 5e-5))
    code, text = run("level-change", "0", "1")
    assert code == 2 and "BEFORE" in text
    # the moment about a named point: the command's answer is the library's
    code, text = run("balance", "bartack-1820", "--criterion", "moment", "--moment-point-mm",
                     "0,-150", "--step-deg", "4", "--json")
    assert code == 0, text
    data = json.loads(text)
    lib = balance(load_machine("bartack-1820"), "moment", step_deg=4.0,
                  moment_point=(0.0, -150.0))
    assert data["after"]["peak_moment_Nm"] == pytest.approx(lib.after["peak_moment_Nm"],
                                                            rel=1e-9)
    assert data["after"]["peak_moment_Nm"] < data["before"]["peak_moment_Nm"]
    code, text = run("balance", "bartack-1820", "--moment-point-mm", "1,2,3")
    assert code == 2 and "--moment-point-mm" in text
