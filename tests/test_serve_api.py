"""The page's JSON API against a real server: its numbers are the library's, its errors are
located JSON (never a traceback), a bad request does not stop it, and two pages do not share
their edits."""

from __future__ import annotations

import math
import subprocess
import sys
import threading

import numpy as np
import pytest
from sewmech.dynamics import inverse_dynamics
from sewmech.feed import feed_cycles
from sewmech.thread import thread_balance

import sewmech
from serve_helpers import call, running_server

CLI = "from sewmech.app.cli import main; main()"
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


@pytest.fixture(scope="module")
def url():
    import sewmech.web  # noqa: F401  (the short name, as test_layers imports it, first)

    with running_server() as u:
        yield u


@pytest.fixture(scope="module")
def jb(url):
    status, body = call(f"{url}/api/sessions", {"machine": "jb1-3"})
    assert status == 200, body
    return body


@pytest.fixture(scope="module")
def machine():
    return sewmech.load_machine("jb1-3")


def _turn(url, token, values):
    return call(f"{url}/api/sessions/{token}/turn", {"set": values})


def _params(m, regulator_deg=None, **dims):
    """A design as the page sets it: the regulator at the file's setting unless given (deg)."""
    return m.parameters(dims, inputs=None if regulator_deg is None else
                        {"regulator": math.radians(regulator_deg)})


def test_machines_and_the_parameter_table(url, jb):
    status, body = call(f"{url}/api/machines")
    assert status == 200 and body["initial"] == "jb1-3"
    assert {"jb1-3", "jb8-2"} <= {m["name"] for m in body["machines"]}
    params = {p["name"]: p for p in jb["machine"]["parameters"]}
    reg = params["input.regulator"]
    assert (reg["unit"], reg["lo"], reg["hi"], reg["main"]) == ("deg", -30.0, 30.0, True)
    assert params["needle_bar.length"]["unit"] == "mm" and params["needle_bar.length"]["main"]
    assert params["feed_cam.stroke"]["value"] == 7.0  # a cam through its design values
    m = sewmech.load_machine("jb1-3")
    settable = {n for n, s in zip(m.parameter_names, m.parameter_sources) if s is not None}
    assert settable <= set(params)  # every parameter a designer can set is reachable


def test_a_turn_is_the_librarys_turn(url, jb, machine):
    token = jb["session"]
    status, t = _turn(url, token, {"input.regulator": 20.0, "needle_bar.length": 45.0})
    assert status == 200, t
    m = machine
    P = _params(m, 20.0, **{"needle_bar.length": 45.0})
    phi = np.radians(np.asarray(t["phi_deg"]))
    assert np.allclose(np.diff(t["phi_deg"]), 2.0) and len(phi) == 180
    r = sewmech.kinematics(m, phi, params=P)
    for name in ("needle.point", "take_up.eye", "feed_dog.tip", "C", "R"):
        p = r.point(name).p
        assert np.allclose(t["points"][name]["x"], p[:, 0], atol=2e-6)
        assert np.allclose(t["points"][name]["y"], p[:, 1], atol=2e-6)
    c = feed_cycles(m, 20.0, params=P)
    assert t["feed"]["stitch_mm"] == pytest.approx(float(c.stitch_mm), abs=1e-6)
    assert t["feed"]["lift_mm"] == pytest.approx(float(c.lift_mm), abs=1e-6)
    d = inverse_dynamics(m, phi, params=P)
    assert np.allclose(t["dynamics"]["torque_Nmm"], d.input_torque, atol=2e-6)
    assert np.allclose(t["dynamics"]["shaking_force_N"], d.shaking_force, atol=2e-6)
    # the turn's means: the mean torque, and the friction loss (W) the library gives
    assert t["dynamics"]["mean_torque_Nmm"] == pytest.approx(float(d.input_torque.mean()),
                                                             rel=1e-9)
    assert t["dynamics"]["friction_loss_W"] == pytest.approx(
        float(d.friction_power.mean()) * 1e-3, rel=1e-9)
    assert t["dynamics"]["friction_loss_W"] > 1.0
    # the housing's levels at its control points: the library's on the page's turn
    from sewmech.engine.housing import housing_vibration

    hv = housing_vibration(m, 2.0, params=P)
    for j, ax in enumerate("xyz"):
        assert t["dynamics"]["vibration"]["hands"]["level_db"][ax] == pytest.approx(
            float(hv.level_db[0, j]), abs=2e-6)
        assert t["dynamics"]["vibration"]["hands"]["rms_velocity_mm_s"][ax] == pytest.approx(
            float(hv.rms_velocity[0, j]), rel=1e-6)
    b = thread_balance(m, stitch_mm=abs(float(c.stitch_mm)), params=P)
    assert np.allclose(t["thread"]["overfeed_mm"], b.overfeed, atol=2e-6)
    needle = r.point("needle.point")
    assert np.allclose(t["motion"]["needle_point"]["vy_mm_s"], needle.v[:, 1], atol=1e-5)
    # the regulator moves the stitch: the number the page shows follows the setting; the page
    # opens at the machine's working setting (the longest forward stitch), not on a zero stitch
    status, t0 = _turn(url, token, {"input.regulator": 0.0})
    assert abs(t0["feed"]["stitch_mm"]) < 0.01 and t["feed"]["stitch_mm"] > 2.0
    status, tw = _turn(url, token, {})
    assert tw["feed"]["stitch_mm"] == pytest.approx(float(feed_cycles(m, 30.0).stitch_mm),
                                                    abs=1e-6)
    assert tw["feed"]["stitch_mm"] > 4.0


def test_checks_are_the_librarys_checks(url, jb, machine):
    from sewmech.checks import check_timing

    status, body = call(f"{url}/api/sessions/{jb['session']}/checks",
                        {"set": {"needle_bar.length": 45.0}})
    assert status == 200, body
    P = _params(machine, **{"needle_bar.length": 45.0})
    direct = check_timing(machine, P)
    assert [c["check"] for c in body["checks"]] == [c.name for c in direct]
    for got, want in zip(body["checks"], direct):
        assert got["value"] == pytest.approx(want.value, abs=1e-6)
        assert got["passed"] is bool(want.passed)
    # shown at the precision of its quantity, as the report shows it: the zero mark's stitch
    # (round-off of a 4 mm stroke, about 1e-6 mm) reads 0, a real value with its digits
    shown = {c["check"]: c["shown"] for c in body["checks"]}
    zero = [c for c in direct if "zero mark" in c.name and c.unit == "mm" and abs(c.value) < 1e-3]
    assert zero and all(shown[c.name] == "0" for c in zero)
    assert all("e-" not in v for v in shown.values())
    real = next(c for c in direct if c.unit == "mm" and abs(c.value) > 1.0)
    assert float(shown[real.name]) == pytest.approx(real.value, abs=1e-4)
    events = {e["event"]: e["value"] for e in body["events"]}
    assert events["needle top dead centre"] == pytest.approx(
        sewmech.timing.needle_stroke(machine, P).top_phi_deg, abs=1e-6)


def test_a_design_that_does_not_assemble_says_where_and_why(url, jb):
    status, body = _turn(url, jb["session"], {"take_up.length2": 2.0})
    assert status == 422
    e = body["error"]
    assert e["kind"] == "AssemblyError" and "take_up" in e["where"] and e["what"]
    status, body = _turn(url, jb["session"], {"input.regulator": 45.0})  # outside -30..30
    assert status == 422 and body["error"]["where"] and "range" in body["error"]["what"]
    status, body = _turn(url, jb["session"], {"needle_bar.lenght": 45.0})
    assert status == 422 and "not a parameter" in body["error"]["what"]
    status, body = _turn(url, jb["session"], {"needle_bar.length": "45"})
    assert status == 422 and "finite number" in body["error"]["what"]
    status, body = call(f"{url}/api/sessions/{jb['session']}/turn", raw=b"{not json")
    assert status == 400 and body["error"]["where"] == "request"
    # a cam's design values that make no cam: located at the cam's parameter
    status, body = _turn(url, jb["session"], {"feed_cam.dwell": 500.0})
    assert status == 422 and body["error"]["where"] == "parameter 'feed_cam.dwell'"
    # a value the file's rules refuse (a crank that does not turn): the checks say so, located
    status, body = call(f"{url}/api/sessions/{jb['session']}/checks",
                        {"set": {"needle_crank.ratio": 0.0}})
    assert status == 422 and 'units[0] "needle_crank"' in body["error"]["where"]
    # the server keeps serving, the session too
    status, body = _turn(url, jb["session"], {})
    assert status == 200 and body["feed"]["stitch_mm"] is not None


@pytest.mark.parametrize("raw, located", [
    (b"[machine]\nname = 3\n", "[machine] name"),
    (b"[machine\n", "not valid TOML"),
    (b"\xff\xfe[machine]", "not UTF-8"),
    (b"a = 1\0", "binary"),
])
def test_a_bad_upload_gets_its_located_error(url, raw, located):
    status, body = call(f"{url}/api/upload?name=../../etc/my.toml", raw=raw)
    assert status == 422, body
    e = body["error"]
    assert located in e["where"] + " " + e["what"]
    assert e["where"].startswith("my.toml")  # the name is a label only: no path of it is kept
    assert "Traceback" not in str(body)
    status, _ = call(f"{url}/api/machines")
    assert status == 200


def test_uploads_and_requests_have_size_limits(url):
    import http.client
    import json

    from sewmech.spec import MAX_FILE_BYTES

    # the length is refused from the header, before any of the body is read
    host, port = url.split("//")[1].split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=30)
    conn.putrequest("POST", "/api/upload?name=big.toml")
    conn.putheader("Content-Length", str(MAX_FILE_BYTES + 1))
    conn.endheaders()
    r = conn.getresponse()
    body = json.loads(r.read())
    conn.close()
    assert r.status == 413 and body["error"]["where"] == "machine file"
    status, body = call(f"{url}/api/sessions", {"machine": "x" * 300_000})
    assert status == 413


def test_an_uploaded_file_opens_and_a_name_never_becomes_a_path(url):
    text = sewmech.machine.shipped_machines()["fourbar-benchmark"].read_text()
    status, body = call(f"{url}/api/upload?name=mine.toml", raw=text.encode())
    assert status == 200 and body["machine"]["file"] == "mine.toml"
    status, t = _turn(url, body["session"], {})
    assert status == 200 and t["dynamics"] is None or "torque_Nmm" in t["dynamics"]
    for name in ("/etc/passwd", "../jb1-3", "jb1-3.toml"):
        status, body = call(f"{url}/api/sessions", {"machine": name})
        assert status == 404 and "not a machine this server offers" in body["error"]["what"]
    status, body = call(f"{url}/api/sessions/nosuchtoken/turn", {"set": {}})
    assert status == 404 and body["error"]["hint"]


def test_two_pages_do_not_see_each_others_edits(url, machine):
    a = call(f"{url}/api/sessions", {"machine": "jb1-3"})[1]["session"]
    b = call(f"{url}/api/sessions", {"machine": "jb1-3"})[1]["session"]
    out = {}

    def run(token, values, key):
        for _ in range(5):
            out[key] = _turn(url, token, values)[1]

    ta = threading.Thread(target=run, args=(a, {"input.regulator": 25.0}, "a"))
    tb = threading.Thread(target=run, args=(b, {"input.regulator": -10.0,
                                                "needle_bar.length": 46.0}, "b"))
    ta.start(), tb.start(), ta.join(), tb.join()
    want_a = float(feed_cycles(machine, 25.0).stitch_mm)
    want_b = float(feed_cycles(machine, -10.0, params=_params(
        machine, -10.0, **{"needle_bar.length": 46.0})).stitch_mm)
    assert out["a"]["feed"]["stitch_mm"] == pytest.approx(want_a, abs=1e-6)
    assert out["b"]["feed"]["stitch_mm"] == pytest.approx(want_b, abs=1e-6)
    # a's export carries a's values only
    text = call(f"{url}/api/sessions/{a}/export.toml", {"set": {"input.regulator": 25.0}})[1]
    assert "default_deg = 25.0" in text and "length = 46.0" not in text


def test_the_export_is_the_files_text_with_the_new_values_and_loads_back(url, jb, machine):
    values = {"needle_bar.length": 45.5, "feed_cam.stroke": 7.2, "input.regulator": 12.0,
              "needle_crank.phase": 2.0, "extra.static_moment": 50.0}
    status, text = call(f"{url}/api/sessions/{jb['session']}/export.toml", {"set": values})
    assert status == 200
    shipped = sewmech.machine.shipped_machines()["jb1-3"].read_text()
    assert text.count("\n") == shipped.count("\n")  # the file's own text: comments kept
    assert "# JB1-3 household lockstitch machine" in text
    back = sewmech.machine_from_toml(text)
    want = machine.parameters({"needle_bar.length": 45.5, "feed_cam.stroke": 7.2,
                               "needle_crank.phase": math.radians(2.0),
                               "extra.static_moment": 50.0 / 100.0},
                              inputs={"regulator": math.radians(12.0)})
    assert np.allclose(back.defaults, want, rtol=1e-12, atol=1e-12)
    status, csv = call(f"{url}/api/sessions/{jb['session']}/curves.csv", {"set": values})
    assert status == 200
    lines = csv.splitlines()
    assert lines[0].startswith("phi_deg,") and "torque_Nmm" in lines[0] and len(lines) == 181


def test_sewmech_serve_prints_its_url_and_serves(tmp_path):
    mine = tmp_path / "mine.toml"
    mine.write_text(sewmech.machine.shipped_machines()["jb8-2"].read_text())
    proc = subprocess.Popen([sys.executable, "-c", CLI, "serve", str(mine), "--port",
                             "0"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        line = proc.stdout.readline()
        assert "http://127.0.0.1:" in line, line
        base = line.split("http://")[1].split("/")[0]
        status, body = call(f"http://{base}/api/machines")
        assert status == 200 and body["initial"] == "jb8-2 (mine.toml)"
        assert "jb1-3" in {m["name"] for m in body["machines"]}
        status, body = call(f"http://{base}/api/sessions", {"machine": body["initial"]})
        assert status == 200 and body["machine"]["file"] == "mine.toml"
        status, page = call(f"http://{base}/")
        assert status == 200 and page.lower().startswith("<!doctype html")
    finally:
        proc.terminate()
        proc.wait(20)
    bad = tmp_path / "bad.toml"
    bad.write_text("[machine]\nname = 3\n")
    r = subprocess.run([sys.executable, "-c", CLI, "serve", str(bad), "--port",
                        "0"], check=False, capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "[machine] name" in r.stderr
