"""The balancing commands: `sewmech balance` (its JSON keys, the library's numbers, the
paper's workflow on the shipped bar-tack machine), `sewmech trial-balance` and
`sewmech influence-balance` (measurement files, their located errors)."""

from __future__ import annotations

import json
import re

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
    build = paper["build"]
    assert build["s_built_gcm"] == pytest.approx(build["factor"] * paper["s_add_gcm"])
    assert 2.5 <= build["factor"] <= 3.0 and build["s_built_gcm"] <= 400.0  # the file's limit


def test_the_balance_table_shows_a_cancelled_figure_as_0_not_its_round_off():
    """Delta-Q = 0 by construction: after the counterweight it is round-off of the forces
    (7e-15 N), which the table shows as 0, and the basis check says it agrees."""
    code, text = run("balance", "bartack-1820", "--step-deg", "4")
    assert code == 0, text
    row = next(line for line in text.splitlines() if line.startswith("\u2502 Delta-Q"))
    cells = [c.strip() for c in row.split("\u2502") if c.strip()]
    assert cells[-2] == "0" and float(cells[-3]) > 10.0, cells
    assert not re.search(r"\de-1\d", text), text
    assert "agrees to round-off" in text


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


def _one_error_line(text: str, where: str) -> None:
    lines = [line for line in text.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"error: {where}"), text


def test_an_infeasible_delta_q_gives_no_counterweight_and_no_recipe(tmp_path):
    """A counterweight along 45 deg on a slider-crank: Delta-Q has no root. The answer is no
    counterweight (JSON: null), the least peak force as what is achievable, and no recipe."""
    from test_balancing import slider_crank_cw_text

    f = write(tmp_path / "sc.toml", slider_crank_cw_text(45.0))
    code, out = run("balance", f, "--criterion", "delta-q", "--json", "--step-deg", "2")
    assert code == 0, out
    data = json.loads(out)
    assert data["status"] == "infeasible"
    assert data["counterweights"] is None and data["after"] is None
    assert data["paper"]["build"] is None and data["paper"]["s_add_gcm"] is None
    alt = data["alternative"]
    assert alt["option"] == "--criterion peak"
    assert alt["after"]["peak_force_N"] < data["before"]["peak_force_N"]
    code, out = run("balance", f, "--criterion", "delta-q", "--step-deg", "2")
    assert code == 0, out
    flat = " ".join(out.split())
    assert "delta-q: infeasible" in flat and "No counterweight is proposed" in flat
    assert "--criterion peak" in flat and "least peak shaking force" in flat
    assert "steel cup" not in flat and "lead insert" not in flat and "built 3 x" not in flat
    assert "no recipe for the built counterweight" in flat and "nothing to build" in flat
    # the report's section: the least peak force shown, delta-q said to propose nothing
    import matplotlib

    matplotlib.use("Agg")
    from sewmech.app.drawing.figures import Figures
    from sewmech.app.report.balancing import balancing_section, section_html

    m = load_machine(str(f))
    sec = balancing_section(Figures(tmp_path, m.name), m, front=False)
    assert sec["main"].criterion == "peak" and sec["main"].proposed
    page = " ".join(section_html(m, sec).split())
    assert "<b>delta-q</b> proposes nothing" in page
    assert "No recipe for the built counterweight" in page and "steel cup" not in page
    assert "delta-q" not in sec["comparison"].columns


def test_the_built_counterweight_of_the_shipped_machines_clears_their_shafts():
    """bartack-1820's recipe had a 30.6 mm hole whose edge was 2.7 mm from the axis of its
    12 mm shaft; now the hole keeps 2 mm of steel to the shaft, the steel cup holds it, and
    the margin comes down to what the file's 400 g cm allows."""
    code, out = run("balance", "bartack-1820", "--json", "--step-deg", "2")
    assert code == 0, out
    b = json.loads(out)["paper"]["build"]
    assert b["bore_mm"] == 12.0 and "solids" in b["bore_source"]
    assert b["hole_edge_mm"] >= 6.0 + 2.0 - 1e-9 and b["clearance_mm"] >= 2.0 - 1e-9
    blk, ins = b["block"], b["insert"]
    assert blk["diameter_mm"] >= ins["diameter_mm"] + 4.0 - 1e-9
    assert blk["length_mm"] >= ins["depth_mm"] + 2.0 - 1e-9
    assert b["s_built_gcm"] <= 400.0 and 2.5 <= b["factor"] <= 3.0
    code, out = run("balance", "jb1-3", "--json", "--step-deg", "2")
    assert code == 0, out
    b = json.loads(out)["paper"]["build"]
    assert b["bore_mm"] == 8.5 and b["clearance_mm"] >= 2.0 - 1e-9
    # a root whose built counterweight exceeds the space: refused, located, with what to do
    code, out = run("balance", "jb1-3", "--set", "extra.angle=90deg", "--step-deg", "2",
                    "--json")
    assert code == 0, out
    paper = json.loads(out)["paper"]
    assert paper["build"] is None
    assert "jb1-3.toml: [counterweights.extra]" in paper["build_refused"]
    assert "max_static_moment_gcm" in paper["build_refused"]


def test_a_counterweight_without_a_known_bore_gets_no_recipe(tmp_path):
    from test_balancing import slider_crank_cw_text

    f = write(tmp_path / "sc.toml", slider_crank_cw_text(180.0))
    code, out = run("balance", f, "--json", "--step-deg", "2")
    assert code == 0, out
    paper = json.loads(out)["paper"]
    assert paper["status"] == "optimal" and paper["build"] is None
    assert "[counterweights.cw]" in paper["build_refused"] and "bore_mm" in paper["build_refused"]
    # with its bore the recipe clears it
    f = write(tmp_path / "sc2.toml", slider_crank_cw_text(180.0, "bore_mm = 6.0\n"))
    code, out = run("balance", f, "--json", "--step-deg", "2")
    assert code == 0, out
    b = json.loads(out)["paper"]["build"]
    assert b["bore_source"].startswith("bore_mm") and b["clearance_mm"] >= 2.0 - 1e-9


def test_enum_options_and_domain_errors_are_one_located_line():
    code, text = run("balance", "bartack-1820", "--criterion", "bogus")
    assert code == 2
    _one_error_line(text, "--criterion")
    assert "delta-q, peak, rms" in text
    code, text = run("balance", "bartack-1820", "--criterion", "pek")
    assert code == 2 and "Did you mean --criterion peak?" in text
    # a counterweight's value out of its domain: what it means and what to give
    code, text = run("balance", "bartack-1820", "--set", "extra.static_moment=-5gcm")
    assert code == 2
    flat = " ".join(text.split())
    assert "[counterweights.extra] static_moment_gcm: is -5 g cm" in flat
    assert "cannot be negative" in flat and "turn it by angle_deg" in flat
    assert "Input should be" not in flat
    code, text = run("balance", "bartack-1820", "--set", "extra.radius=0mm")
    assert code == 2 and "Input should be" not in text and "centre of mass" in text
    # a machine without counterweights: the file is named, not an option that was not given
    code, text = run("balance", "jb8-2")
    assert code == 2 and "has no counterweights" in text
    assert "--counterweight" not in text and "jb8-2.toml" in " ".join(text.split())


def _runs_csv(tmp_path, rng, places=3, lag=False, name="runs.csv"):
    """A trial-run file made from a known linear model: returns (file, unbalance)."""
    A = rng.normal(size=(places, 2)) + 1j * rng.normal(size=(places, 2))
    U = np.array([40.0 * np.exp(1j * np.radians(120.0)), 15.0 * np.exp(1j * np.radians(-30))])
    V0 = A @ U
    sign = -1.0 if lag else 1.0
    rows = ["run,place,amplitude_mm_s,phase_deg,trial_gcm,trial_angle_deg"]

    def row(run, p, v, trial, ang):
        ph = sign * float(np.degrees(np.angle(v)))
        rows.append(f"{run},p{p},{float(abs(v))!r},{ph!r},{trial},{ang}")

    for p in range(places):
        row(0, p, V0[p], 0, 0)
    for j, (t, ang) in enumerate(((30.0, 0.0), (25.0, 90.0))):
        V = V0 + A[:, j] * t * np.exp(1j * np.radians(ang))
        for p in range(places):
            row(j + 1, p, V[p], t, ang)
    return write(tmp_path / name, "\n".join(rows) + "\n"), U


def test_influence_balance_refuses_signed_magnitudes_and_says_its_phase_sense(tmp_path, rng):
    f, _ = _runs_csv(tmp_path, rng)
    lines = f.read_text().splitlines()
    bad = lines.copy()
    cells = bad[3].split(",")
    cells[2] = "-" + cells[2]
    bad[3] = ",".join(cells)
    code, text = run("influence-balance", write(tmp_path / "neg.csv", "\n".join(bad) + "\n"))
    assert code == 2
    _one_error_line(text, "")
    flat = " ".join(text.split())
    assert "neg.csv:4: column amplitude_mm_s" in flat and "is negative" in flat
    assert "add 180 deg to its phase_deg" in flat
    bad = lines.copy()
    cells = bad[5].split(",")
    cells[4] = "-30.0"
    bad[5] = ",".join(cells)
    code, text = run("influence-balance", write(tmp_path / "negt.csv", "\n".join(bad) + "\n"))
    assert code == 2
    flat = " ".join(text.split())
    assert "negt.csv:6: column trial_gcm" in flat and "trial_angle_deg" in flat
    # the phase convention is stated, and a lag (counted against the trial angles) is read
    # with --phase-lag: the same unbalance comes back
    code, text = run("influence-balance", "--help")
    assert "counted in the same sense as trial_angle_deg" in " ".join(text.split())
    g, U = _runs_csv(tmp_path, rng, lag=True, name="lag.csv")
    code, text = run("influence-balance", g, "--phase-lag", "--json")
    assert code == 0, text
    data = json.loads(text)
    for j, u in enumerate(-U):
        c = data["corrections"][f"run {j + 1}"]
        got = c["static_moment_gcm"] * np.exp(1j * np.radians(c["angle_deg"]))
        assert abs(got - u) < 1e-9 * abs(u)
    code, text = run("influence-balance", g, "--json")  # read as the same sense: wrong
    data = json.loads(text)
    c = data["corrections"]["run 1"]
    assert abs(c["static_moment_gcm"] * np.exp(1j * np.radians(c["angle_deg"])) + U[0]) > 1.0


def test_influence_balance_exactly_determined_has_no_level_after(tmp_path, rng):
    """Two readings, two planes: the correction cancels them by construction, so the level
    after is undefined, said in words (JSON: null with the reason), never -300 dB."""
    f, _ = _runs_csv(tmp_path, rng, places=2)
    code, text = run("influence-balance", f, "--json")
    assert code == 0, text
    data = json.loads(text)
    assert data["level_change_db"] is None
    assert "2 readings and 2 planes" in data["level_change_note"]
    assert data["after_rms_mm_s"] == 0.0
    code, text = run("influence-balance", f)
    flat = " ".join(text.split())
    assert "-> 0 mm/s" in flat and "cancel every reading" in flat and " dB" not in flat
    assert "from 2 places and 2 trial runs" in flat
    # noise-free readings over more places cancel too (a round-off residual is no level)
    f, _ = _runs_csv(tmp_path, rng, places=4, name="four.csv")
    data = json.loads(run("influence-balance", f, "--json")[1])
    assert data["level_change_db"] is None and "round-off" in data["level_change_note"]
    # one reading for two planes: the grammar of the refusal
    g = write(tmp_path / "one.csv", "\n".join(
        line for line in f.read_text().splitlines() if not line.split(",")[1:2]
        or line.split(",")[1] in ("place", "p0")) + "\n")
    code, text = run("influence-balance", g)
    assert code == 2 and "1 reading cannot fix 2 planes" in " ".join(text.split())
