"""CAD files out (issue 33): DXF through ezdxf and SVG from the same geometry, read back and
compared with the design: every cam arc (centre, radius, end angles) against the cam's own
construction (sewmech.cams) turned by its link's angle, every path point against the
kinematics engine, the feed cam's pitch curve against the fork face the engine's loop solves,
ezdxf's audit, the units and layers of the header, the title block; the command and its
located errors."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import ezdxf
import numpy as np
import pytest
from typer.testing import CliRunner

import sewmech
from sewmech.app.drawing.cad import machine_drawing
from sewmech.app.files.cad import svg_text, write_dxf, write_svg
from sewmech.cams import constant_width_arcs
from sewmech.cli import app

PHI = 30.0
TOL = 1e-9


@pytest.fixture(scope="module")
def jb():
    return sewmech.load_machine("jb1-3")


@pytest.fixture(scope="module")
def dxf_doc(jb, tmp_path_factory):
    path = tmp_path_factory.mktemp("cad") / "jb1-3.dxf"
    write_dxf(machine_drawing(jb, phi_deg=PHI, version=sewmech.__version__), path)
    return ezdxf.readfile(path)


def _by_layer(doc, kind, layer):
    return [e for e in doc.modelspace().query(kind) if e.dxf.layer == layer]


def test_audit_units_layers(dxf_doc, jb):
    auditor = dxf_doc.audit()
    assert not auditor.has_errors and not auditor.has_fixes
    assert dxf_doc.header["$INSUNITS"] == 4 and dxf_doc.header["$MEASUREMENT"] == 1
    layers = {layer.dxf.name for layer in dxf_doc.layers}
    assert "cam-feed_cam" in layers and "cam-lift_cam" in layers
    for link in ("needle_crank", "needle_link", "take_up_lever", "feed_fork", "feed_bar"):
        assert link in layers
    for role in ("needle.eye", "take_up.eye", "feed_dog.tip"):
        assert f"path-{role}" in layers


def test_feed_cam_arcs_equal_the_design(dxf_doc, jb):
    """The six arcs against the constant-width construction (width 20, stroke 7, dwell 60 deg
    from the file) turned by the cam's angle, phase + phi: centre, radius, both end angles."""
    cam = jb.spec.cams["feed_cam"].constant_width
    arcs = constant_width_arcs(cam.width, cam.stroke, math.radians(cam.dwell_deg),
                               math.radians(cam.orientation_deg))
    th = math.radians(22.973 + PHI)  # the feed_cam crank: phase_deg + phi
    got = _by_layer(dxf_doc, "ARC", "cam-feed_cam")
    assert len(got) == 6
    axis = np.array([jb.spec.points["O"].x, jb.spec.points["O"].y])
    c, s = math.cos(th), math.sin(th)
    for k in range(6):
        u, v = arcs["cx"][k], arcs["cy"][k]
        centre = axis + [c * u - s * v, s * u + c * v]
        start = math.degrees(arcs["normal_from"][k] + th) % 360.0
        end = math.degrees(arcs["normal_to"][k] + th) % 360.0
        match = [a for a in got if abs(a.dxf.radius - arcs["radius"][k]) < TOL
                 and np.hypot(*(np.array(a.dxf.center)[:2] - centre)) < TOL]
        assert len(match) >= 1, f"arc {k} not in the file"
        a = match[0]
        assert abs(a.dxf.start_angle - start) < TOL and abs(a.dxf.end_angle - end) < TOL
        assert a.dxf.center[2] == 0.0
    # each arc's centre as a point on the cam's layer
    points = [np.array(p.dxf.location)[:2] for p in _by_layer(dxf_doc, "POINT", "cam-feed_cam")]
    assert len(points) == 6
    # the profile is closed: each arc ends where the next begins (tangent continuity)
    ends = [(np.array(a.dxf.center)[:2] + a.dxf.radius * np.array(
        [math.cos(math.radians(a.dxf.end_angle)), math.sin(math.radians(a.dxf.end_angle))]))
        for a in got]
    starts = [(np.array(a.dxf.center)[:2] + a.dxf.radius * np.array(
        [math.cos(math.radians(a.dxf.start_angle)), math.sin(math.radians(a.dxf.start_angle))]))
        for a in got]
    for e in ends:
        assert min(np.hypot(*(e - s_)) for s_ in starts) < 1e-9


def test_lift_cam_circle_against_the_engine(dxf_doc, jb):
    r = sewmech.kinematics(jb, [math.radians(PHI)], points=["O2"], links=["rocking_shaft"])
    th = r.link("rocking_shaft").theta[0]
    pivot = r.point("O2").p[0]
    centre = pivot + 1.3 * np.array([math.cos(th), math.sin(th)])
    circles = [e for e in _by_layer(dxf_doc, "CIRCLE", "cam-lift_cam")
               if abs(e.dxf.radius - 8.0) < TOL]
    assert len(circles) == 1
    assert np.hypot(*(np.array(circles[0].dxf.center)[:2] - centre)) < TOL


def test_paths_equal_the_engine(dxf_doc, jb):
    turn = np.radians(np.arange(0.0, 360.0, 1.0))
    r = sewmech.kinematics(jb, turn, points=["needle.eye", "take_up.eye", "feed_dog.tip"])
    for role in ("needle.eye", "take_up.eye", "feed_dog.tip"):
        (pl,) = _by_layer(dxf_doc, "LWPOLYLINE", f"path-{role}")
        pts = np.array([(x, y) for x, y, *_ in pl.get_points()])
        assert pl.closed and pts.shape == (360, 2)
        assert np.abs(pts - r.point(role).p).max() < TOL


def test_link_outlines_and_joints(dxf_doc, jb):
    """Each link's joints are holes at their engine positions; its outline keeps
    link_radius from every joint (arcs about them)."""
    r = sewmech.kinematics(jb, [math.radians(PHI)])
    xy = {n: r.p[0, i] for i, n in enumerate(r.point_names)}
    holes = [np.array(c.dxf.center)[:2] for c in _by_layer(dxf_doc, "CIRCLE", "joints")]
    for p, owners in jb.point_links.items():
        if len(owners) > 1 and set(owners) - {"frame"}:
            assert min(np.hypot(*(h - xy[p])) for h in holes) < TOL, p
    arcs = _by_layer(dxf_doc, "ARC", "needle_link")
    centres = [np.array(a.dxf.center)[:2] for a in arcs]
    for p in ("B", "C"):
        assert min(np.hypot(*(c - xy[p])) for c in centres) < TOL


def test_feed_cam_pitch_curve_lies_on_the_fork_face(jb, tmp_path):
    """The pitch curve (the foot of the perpendicular from the cam axis to the fork face,
    relative to the cam), turned back to each shaft angle, lies on the face the engine's loop
    places 10 mm beside the fork's axis."""
    path = tmp_path / "cam.dxf"
    write_dxf(machine_drawing(jb, phi_deg=0.0, part="feed_cam"), path)
    doc = ezdxf.readfile(path)
    (pl,) = _by_layer(doc, "LWPOLYLINE", "cam-feed_cam")
    pts = np.array([(x, y) for x, y, *_ in pl.get_points()])
    turn = np.radians(np.arange(0.0, 360.0, 1.0))
    r = sewmech.kinematics(jb, turn, points=["O", "feed_fork.pin"], links=["feed_cam",
                                                                          "feed_fork"])
    th_cam = r.link("feed_cam").theta
    axis = r.point("O").p[0]
    assert len(pts) == len(turn)
    for k in range(len(turn)):
        rot = th_cam[k] - th_cam[0]
        v = pts[k] - axis
        q = axis + [math.cos(rot) * v[0] - math.sin(rot) * v[1],
                 math.sin(rot) * v[0] + math.cos(rot) * v[1]]
        thf = r.link("feed_fork").theta[k]
        n = np.array([math.cos(thf + math.pi / 2), math.sin(thf + math.pi / 2)])
        assert abs((q - r.point("feed_fork.pin").p[k]) @ n - 10.0) < 1e-8
    # a part's drawing: the cam and the title block only
    layers = {e.dxf.layer for e in doc.modelspace()}
    assert layers == {"cam-feed_cam", "title"}


def test_svg_says_what_the_dxf_says(jb, dxf_doc):
    d = machine_drawing(jb, phi_deg=PHI)
    root = ET.fromstring(svg_text(d))
    ns = {"s": "http://www.w3.org/2000/svg"}
    groups = {g.get("id"): g for g in root.findall("s:g", ns)}
    assert "cam-feed_cam" in groups and "title" in groups
    assert root.get("width").endswith("mm")
    arcs_svg = [p for p in groups["cam-feed_cam"].findall("s:path", ns) if " A " in p.get("d")]
    assert len(arcs_svg) == len(_by_layer(dxf_doc, "ARC", "cam-feed_cam")) == 6
    for p in arcs_svg:  # each arc's end points on its circle (y up: the SVG's y is -y)
        tok = p.get("d").split()
        x0, y0, rad = float(tok[1]), -float(tok[2]), float(tok[4])
        x1, y1 = float(tok[9]), -float(tok[10])
        fits = [a for a in _by_layer(dxf_doc, "ARC", "cam-feed_cam")
                if abs(a.dxf.radius - rad) < TOL and
                abs(np.hypot(x0 - a.dxf.center[0], y0 - a.dxf.center[1]) - rad) < 1e-9 and
                abs(np.hypot(x1 - a.dxf.center[0], y1 - a.dxf.center[1]) - rad) < 1e-9]
        assert fits
    text = " ".join(t.text for t in root.iter("{http://www.w3.org/2000/svg}text"))
    assert "jb1-3" in text and "phi = 30 deg" in text and "mm" in text


def test_title_block(dxf_doc):
    texts = [t.dxf.text for t in _by_layer(dxf_doc, "TEXT", "title")]
    assert texts[0] == "jb1-3"
    assert any("phi = 30 deg" in t and "mm" in t for t in texts)
    assert any(t.startswith("input regulator = 30 deg") for t in texts)
    assert any(t.startswith("drawn by sewmech") for t in texts)


def test_design_values_in_the_title(jb, tmp_path):
    m = jb.with_parameters({"needle_bar.length": 45.0})
    write_svg(machine_drawing(m, phi_deg=0.0), tmp_path / "x.svg")
    assert "needle_bar.length = 45" in (tmp_path / "x.svg").read_text()


# ---- the command ------------------------------------------------------------------------------


def test_export_command(tmp_path):
    out = tmp_path / "drw"
    r = CliRunner().invoke(app, ["export", "jb1-3", "--format", "dxf", "--format", "svg",
                                 "--phi-deg", "30", "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert (out / "jb1-3-phi30.dxf").is_file() and (out / "jb1-3-phi30.svg").is_file()
    doc = ezdxf.readfile(out / "jb1-3-phi30.dxf")
    assert not doc.audit().has_errors


def test_export_errors_keep_the_users_files(tmp_path):
    mine = tmp_path / "drawing.dxf"
    mine.write_text("mine")
    run = CliRunner().invoke
    r = run(app, ["export", "jb1-3", "--out", str(mine)])
    assert r.exit_code == 2 and "error: --out" in r.output and mine.read_text() == "mine"
    r = run(app, ["export", "jb1-3", "--part", "feedcam", "--out", str(tmp_path / "a")])
    assert r.exit_code == 2 and "Did you mean feed_cam" in r.output
    assert not (tmp_path / "a").exists()
    r = run(app, ["export", "jb1-3", "--format", "dwg", "--out", str(tmp_path / "b")])
    assert r.exit_code == 2 and "error: --format" in r.output
    r = run(app, ["export", "fourbar-benchmark", "--phi-deg", "nan", "--out",
                  str(tmp_path / "c")])
    assert r.exit_code == 2 and "--phi-deg" in r.output


def test_optimize_out_writes_the_answers_drawing(tmp_path):
    import json

    out = tmp_path / "opt"
    from pathlib import Path

    problem = Path(__file__).resolve().parents[1] / "examples" / "problems" / "fourbar-swing.toml"
    r = CliRunner().invoke(app, ["optimize", str(problem), "--method", "slsqp", "--out",
                                 str(out)])
    assert r.exit_code == 0, r.output
    crank = json.loads((out / "optimize.json").read_text())["x"]["B.u"]
    doc = ezdxf.readfile(out / "answer.dxf")
    assert not doc.audit().has_errors
    centres = [np.array(a.dxf.center)[:2] for a in _by_layer(doc, "ARC", "crank")]
    assert len(centres) == 2  # the crank's outline round A and B
    assert abs(np.hypot(*(centres[0] - centres[1])) - crank) < TOL
    assert (out / "answer.svg").is_file()
    assert 'href="answer.dxf"' in (out / "index.html").read_text()


def test_the_pages_drawing_is_the_commands(tmp_path):
    """POST /api/sessions/TOKEN/drawing.dxf: the page's design at the page's angle, the same
    file as sewmech export with those values; a bad angle is a located 400."""
    import io

    from serve_helpers import call, running_server

    with running_server() as url:
        status, body = call(f"{url}/api/sessions", {"machine": "jb1-3"})
        assert status == 200
        token = body["session"]
        values = {"needle_bar.length": 45.5, "input.regulator": 12.0}
        status, text = call(f"{url}/api/sessions/{token}/drawing.dxf",
                            {"set": values, "phi_deg": 30})
        assert status == 200 and "AC1024" in text  # R2010
        status, svg = call(f"{url}/api/sessions/{token}/drawing.svg", {"set": values,
                                                                       "phi_deg": 30})
        assert status == 200 and svg.lstrip().startswith("<?xml")
        status, err = call(f"{url}/api/sessions/{token}/drawing.dxf", {"phi_deg": "x"})
        assert status == 400 and err["error"]["where"] == "phi_deg"
    page = ezdxf.read(io.StringIO(text))
    assert not page.audit().has_errors
    m = sewmech.load_machine("jb1-3").with_parameters({"needle_bar.length": 45.5})
    cli = ezdxf.read(io.StringIO(_export_dxf_text(m)))

    def geometry(doc):
        out = []
        for e in doc.modelspace():
            if e.dxftype() == "ARC":
                out.append(("ARC", e.dxf.layer, *np.round(e.dxf.center, 9), round(e.dxf.radius, 9),
                            round(e.dxf.start_angle, 9), round(e.dxf.end_angle, 9)))
            elif e.dxftype() == "LWPOLYLINE":
                out.append(("LW", e.dxf.layer, *np.round(np.array(list(e.get_points()))[:, :2],
                                                         9).ravel()))
        return sorted(map(str, out))

    assert geometry(page) == geometry(cli)
    texts = [t.dxf.text for t in page.modelspace().query("TEXT")]
    assert "input regulator = 12 deg" in texts
    assert any("needle_bar.length = 45.5" in t for t in texts)


def _export_dxf_text(m) -> str:
    """The DXF text sewmech export writes for ``m`` at 30 deg with the regulator at 12 deg."""
    import io

    from sewmech.app.files.cad import dxf_document

    d = machine_drawing(m, phi_deg=30.0, inputs={"regulator": math.radians(12.0)})
    buf = io.StringIO()
    dxf_document(d).write(buf)
    return buf.getvalue()
