"""Extremes to 1e-9 rad against closed forms; io round trips and atomicity; the CLI."""

import json
import math

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

import sewmech
from conftest import PHI, fourbar, slider_crank
from sewmech.cli import app
from sewmech.extremes import dead_centres, extremes
from sewmech.io import atomic_write, write_kinematics_csv, write_kinematics_json


def test_offset_slider_crank_dead_centres_closed_form():
    """Dead centres of an offset slider-crank: crank and rod collinear, so the crank angle is
    asin(e / (l + r)) (extended) and pi + asin(e / (l - r)) (folded), horizontal guide."""
    r, l, e = 15.0, 44.0, 5.0
    m = slider_crank(r=r, l=l, e=e, alpha=0.0)
    res = dead_centres(m, "slider")
    assert len(res.extrema) == 2
    far = math.asin(e / (l + r))
    near = math.pi + math.asin(e / (l - r))
    assert abs(res.maximum.phi - far) < 1e-9
    assert abs(res.minimum.phi - near) < 1e-9
    assert res.maximum.value == pytest.approx(math.sqrt((l + r) ** 2 - e * e), abs=1e-12)
    assert res.minimum.value == pytest.approx(math.sqrt((l - r) ** 2 - e * e), abs=1e-12)


def test_rocker_extremes_are_toggle_positions():
    """A crank-rocker's rocker stands still when crank and coupler are collinear: there
    |A C| = BC +/- AB, independent of the package's solver."""
    m = fourbar()
    res = dead_centres(m, "dyad")
    assert {e.kind for e in res.extrema} == {"max", "min"} and len(res.extrema) == 2
    for ex in res.extrema:
        r = sewmech.kinematics(m, np.array([ex.phi]))
        ac = np.hypot(*r.point("C").p[0])
        assert min(abs(ac - 55.0), abs(ac - 25.0)) < 1e-7  # 1e-9 rad of crank -> ~1e-7 mm


def test_extremes_of_a_point_channel_and_bad_channel():
    m = fourbar()
    res = extremes(m, "p_P_y")
    g = sewmech.kinematics(m, np.radians(np.arange(0, 360, 0.01))).point("P").p[:, 1]
    assert res.maximum.value >= g.max() - 1e-12 and res.maximum.value - g.max() < 1e-6
    with pytest.raises(ValueError, match="derivative"):
        extremes(m, "a_P_y")


def test_csv_and_json_round_trip(tmp_path):
    r = sewmech.kinematics(fourbar(), PHI)
    csv = write_kinematics_csv(r, tmp_path / "k.csv")
    df = pd.read_csv(csv)
    np.testing.assert_allclose(df["p_C_x_mm"], r.point("C").p[:, 0], rtol=1e-9)
    np.testing.assert_allclose(df["phi_deg"], np.degrees(PHI), rtol=1e-12)
    js = json.loads(write_kinematics_json(r, tmp_path / "k.json").read_text())
    assert js["channels"]["omega_rocker"]["unit"] == "rad/s"
    np.testing.assert_allclose(js["channels"]["omega_rocker"]["values"], r.link("rocker").omega)


def test_atomic_write_leaves_nothing_half_written(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_write(target) as fh:
            fh.write("half")
            raise RuntimeError("disk full")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


def test_json_has_null_for_infeasible(tmp_path):
    m = fourbar()
    params = m.parameters({"dyad.length1": np.array([40.0, 5.0]),
                           "dyad.length2": np.array([35.0, 5.0])})
    r = sewmech.kinematics(m, PHI, params=params, on_failure="mask")
    js = json.loads(write_kinematics_json(r, tmp_path / "k.json").read_text())
    assert js["feasible"][1][0] is False and js["channels"]["p_C_x"]["values"][1][0] is None


runner = CliRunner()


def test_cli_machines_check_kinematics(tmp_path):
    out = runner.invoke(app, ["machines"])
    assert out.exit_code == 0 and "jb1-3" in out.stdout
    out = runner.invoke(app, ["check", "jb1-3"])
    assert out.exit_code == 0 and "assembles" in out.stdout
    assert "force analysis" in out.stdout
    from sewmech.dynamics import force_system

    line = force_system(sewmech.load_machine("jb1-3"))
    assert "48 unknowns for 48 equations, ready" in line and "bearings from [shaft]" in line
    path = sewmech.load_machine("jb1-3").file
    text = open(path).read().replace('contacts = [ { cam = "cam", one_sided = true } ]\n', "")
    short = force_system(sewmech.machine_from_toml(text))
    assert "47 unknowns for 48 equations, NOT READY" in short
    out = runner.invoke(app, ["kinematics", "jb1-3", "--json", "--step-deg", "10"])
    data = json.loads(out.stdout)
    assert len(data["phi_deg"]) == 36 and "p_take_up.eye_y" in data["channels"]
    # the angles come back as given, not as their round trip through radians (29.999999999999996)
    assert data["phi_deg"] == [10.0 * k for k in range(36)]
    out = runner.invoke(app, ["kinematics", "jb1-3", "--out", str(tmp_path), "--format", "json"])
    assert out.exit_code == 0 and (tmp_path / "jb1-3-kinematics.json").exists()


def test_report_garbage_left_to_the_process_end_when_asked():
    """write_report(collect_garbage=False) (what the `sewmech` process uses): the collector's
    settings come back, and what the report made is frozen (kept, never collected) instead of
    unfrozen; with True (the default) the caller's state comes back exactly."""
    import subprocess
    import sys

    code = (
        "import gc\n"
        "from sewmech.app.report.build import _few_collections\n"
        "before = gc.get_threshold(); n0 = gc.get_freeze_count()\n"
        "with _few_collections(True):\n"
        "    assert gc.get_threshold()[0] == 0 and gc.get_freeze_count() > 0\n"
        "assert (gc.get_threshold(), gc.get_freeze_count()) == (before, n0)\n"
        "with _few_collections(False):\n"
        "    cycle = []; cycle.append(cycle); cycle = None\n"
        "assert gc.get_threshold() == before and gc.get_freeze_count() > 0\n"
        "assert gc.collect() == 0  # the cycle is kept: frozen, not walked\n"
        "print('ok')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=False)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr


def test_sewmech_process_keeps_freed_memory_in_the_heap():
    """A `sewmech report` process's malloc settings (glibc): an 8 MiB array comes from the
    heap, not from a mapping of its own (and what is freed at the heap's top is kept)."""
    import ctypes
    import subprocess
    import sys

    if not hasattr(ctypes.CDLL(None), "mallinfo2"):
        pytest.skip("not glibc (2.33 or later)")
    code = (
        "import ctypes, sys, numpy as np\n"
        "class Info(ctypes.Structure):\n"
        "    _fields_ = [(n, ctypes.c_size_t) for n in ('arena', 'ordblks', 'smblks',"
        " 'hblks', 'hblkhd', 'usmblks', 'fsmblks', 'uordblks', 'fordblks', 'keepcost')]\n"
        "libc = ctypes.CDLL(None); libc.mallinfo2.restype = Info\n"
        "if sys.argv[1] == '1':\n"
        "    from sewmech.app.cli.analysis import _keep_freed_memory; _keep_freed_memory()\n"
        "a = np.ones(1 << 20)\n"
        "print(libc.mallinfo2().hblkhd / 2**20)\n")
    mapped = [float(subprocess.run([sys.executable, "-c", code, flag], capture_output=True,
                                   text=True, check=True).stdout) for flag in ("0", "1")]
    assert mapped[0] >= 8 > mapped[1]  # MiB in mappings of their own: before, after


def test_cli_check_reports_file_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[machine]\nname = 'x'\n[convention]\nreference_event='top'\n"
                   "reference_phi_deg=0\n[points.A]\nx=0\ny=0\nz=1\n"
                   "[[units]]\ntype='crank'\nname='c'\npivot='A'\n")
    out = runner.invoke(app, ["check", str(bad)])
    assert out.exit_code == 2
    assert "bad.toml" in out.stderr and "points.A" in out.stderr and "unknown key 'z'" in out.stderr


def test_cli_report_writes_page_figures_and_tables(tmp_path):
    import gc
    import sys

    out_dir = tmp_path / "rep"
    before = (gc.get_threshold(), gc.get_freeze_count(), gc.isenabled())
    had_pyplot = "matplotlib.pyplot" in sys.modules  # (another test may have loaded it)
    out = runner.invoke(app, ["report", "jb1-3", "--out", str(out_dir), "--step-deg", "2"])
    assert out.exit_code == 0, out.stdout
    # the collector is as it was (it is off and everything loaded frozen while a report is
    # built), and drawing the report's figures needed no pyplot
    assert (gc.get_threshold(), gc.get_freeze_count(), gc.isenabled()) == before
    assert had_pyplot or "matplotlib.pyplot" not in sys.modules
    page = (out_dir / "index.html").read_text()
    checks = pd.read_csv(out_dir / "jb1-3-checks.csv")
    # 11 of the timing and the feed, 2 one-sided contacts, the process loads' energy
    assert f"All {len(checks)} checks pass" in page and len(checks) == 14
    figures = ("mechanism", "motion", "eye-path", "timing-diagram", "feed-trajectories", "stitch-curve",
               "feed-sensitivity", "thread-balance", "take-up-adjustment", "thread-consumption",
               "dyn-torque", "dyn-physics", "dyn-energy", "dyn-shaking", "dyn-bearings",
               "dyn-pairs",
               "dyn-pressure", "dyn-regulator", "dyn-needle", "bal-components", "bal-hodograph",
               "bal-bearings", "bal-levels", "bal-front", "vib-spectrum", "vib-speed",
               "accuracy-stitch", "comparison")
    assert page.count("data:image/png;base64,") == len(figures)
    assert "jb1-3 against jb8-2" in page  # the file's variant, side by side
    for fig in figures:
        for ext in ("png", "svg", "csv"):
            assert (out_dir / f"jb1-3-{fig}.{ext}").stat().st_size > 500, (fig, ext)
    timing = pd.read_csv(out_dir / "jb1-3-timing-diagram.csv")
    assert timing["phi_deg"].iloc[-1] == 360.0 and len(timing) == 181
    # the figure data are the kinematics at those angles
    r = sewmech.kinematics(sewmech.load_machine("jb1-3"), np.radians(timing["phi_deg"]))
    np.testing.assert_allclose(timing["needle_point_y_mm"], r.point("needle.point").p[:, 1],
                               rtol=1e-9)
    assert set(checks["result"]) == {"pass"}
    marks = pd.read_csv(out_dir / "jb1-3-scale-marks.csv")
    assert list(marks["stitch_mm"]) == [k * 0.5 for k in range(-8, 9)]
    assert (out_dir / "jb1-3.toml").exists()  # the machine data travel with the report
    # the balancing section shows the library's answer for the extra counterweight
    from sewmech.design.balancing import balance

    bal = pd.read_csv(out_dir / "jb1-3-bal-components.csv")
    lib = balance(sewmech.load_machine("jb1-3"), "delta-q", ["extra"])
    np.testing.assert_allclose(bal["Qx_after_N"], lib.curves["after"]["F"][:, 0], rtol=1e-9,
                               atol=1e-9)
    assert 'id="balancing"' in page and "The balancing paper's method" in page
    # the accuracy section: the stitch length's exact derivative at the longest stitch
    from sewmech.design.tolerance_file import ToleranceSpec, tolerances_of
    from sewmech.sewing.gradients import stitch_length_gradient

    acc = pd.read_csv(out_dir / "jb1-3-accuracy.csv").set_index("metric")
    m13 = sewmech.load_machine("jb1-3")
    g = stitch_length_gradient(m13, 30.0)
    tol = tolerances_of(m13, ToleranceSpec.model_validate({"defaults": {"it_grade": 9}}))
    assert acc.loc["stitch_length", "value"] == pytest.approx(g.value, abs=1e-9)
    assert acc.loc["stitch_length", "RSS +-"] == pytest.approx(
        float(np.sqrt(np.sum((g.d_dparam * tol) ** 2))), rel=1e-9)
    # the dynamics figures are the library's numbers at the longest forward stitch
    from sewmech.dynamics import inverse_dynamics

    torque = pd.read_csv(out_dir / "jb1-3-dyn-torque.csv")
    d = inverse_dynamics(sewmech.load_machine("jb1-3"), np.radians(torque["phi_deg"]),
                         inputs={"regulator": math.radians(30.0)})
    np.testing.assert_allclose(torque["torque_Nm"], d.input_torque * 1e-3, rtol=1e-9,
                               atol=1e-12)
    key = pd.read_csv(out_dir / "jb1-3-dynamics-key-figures.csv").set_index("quantity")
    assert math.isclose(key.loc["peak driving torque", "value"],
                        np.abs(d.input_torque).max() * 1e-3, rel_tol=1e-9)
    assert 'id="dynamics"' in page
    # demo is the same job on the default machine
    assert runner.invoke(app, ["demo", "--out", str(tmp_path / "demo")]).exit_code == 0
    assert (tmp_path / "demo" / "index.html").exists()


def test_cli_report_failure_leaves_previous_report(tmp_path):
    out_dir = tmp_path / "rep"
    out_dir.mkdir()
    (out_dir / "index.html").write_text("previous")
    out = runner.invoke(app, ["report", "fourbar-benchmark", "--out", str(out_dir)])
    assert out.exit_code == 2
    assert "[sewing]" in out.stderr and "fourbar-benchmark" in out.stderr
    assert (out_dir / "index.html").read_text() == "previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rep"]  # no staging left behind


def test_cli_feed_json_and_kinematics_input():
    out = runner.invoke(app, ["feed", "jb1-3", "--json"])
    assert out.exit_code == 0, out.stderr
    data = json.loads(out.stdout)  # strict JSON: no NaN
    assert [k["stitch_mm"] for k in data["scale_marks"]] == [k * 0.5 for k in range(-8, 9)]
    zero = data["settings"][1]
    assert zero["regulator_deg"] == 0.0 and abs(zero["stitch_mm"]) < 0.01
    assert zero["mid_feed_deg"] is None  # no feed, no feed timing
    assert data["feed_cam_phase_for_mid_feed_at_top_deg"] == pytest.approx(22.973, abs=1e-3)
    # kinematics at a regulator setting equals the API's
    out = runner.invoke(app, ["kinematics", "jb1-3", "--step-deg", "30", "--input",
                              "regulator=20", "--json"])
    assert out.exit_code == 0, out.stderr
    got = json.loads(out.stdout)
    m = sewmech.load_machine("jb1-3")
    r = sewmech.kinematics(m, np.radians(np.arange(0, 360, 30.0)),
                           inputs={"regulator": np.radians(20.0)})
    key = next(k for k in got["channels"] if "feed_dog.tip" in k and k.startswith("p_"))
    np.testing.assert_allclose(np.asarray(got["channels"][key]["values"]),
                               r.channel(key)[0], rtol=1e-12)
    bad = runner.invoke(app, ["kinematics", "jb1-3", "--input", "reg=20"])
    assert bad.exit_code == 2 and "no input 'reg'" in bad.stderr


def test_figures_with_their_ticks_fixed_draw_the_same(tmp_path):
    """render() fixes each axis's ticks and labels after the layout (so that the PNG and the SVG
    do not ask the locators and formatters again) and answers the fonts' height metrics from
    a cache: its PNG is byte for byte the one the same figure gives without either, its SVG
    the same but for matplotlib's random ids, for linear, logarithmic, offset (1e-3 at the
    axis end) and polar axes, and the axis with an offset keeps its formatter; the renderers
    are left as they were."""
    import io
    import re

    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_agg import RendererAgg

    from sewmech.app.drawing.figures import PNG_DPI, render

    def figure():
        fig = plt.figure(figsize=(6, 4), layout="constrained")
        a = fig.add_subplot(2, 2, 1)
        a.plot(np.linspace(0, 7, 50), np.sin(np.linspace(0, 7, 50)), label="sin")
        a.set_aspect("equal", adjustable="datalim")  # its view changes while it is drawn
        a.annotate("top", (1.6, 1.0), textcoords="offset points", xytext=(4, 2), fontsize=7)
        a.legend(fontsize=7)
        a.set_title("a title over the axis")
        b = fig.add_subplot(2, 2, 2)
        b.semilogy(np.arange(1, 20), np.exp(np.arange(1, 20)))
        cloud = b.scatter(np.arange(1, 20), np.exp(np.arange(1, 20)), c=np.arange(19), s=6,
                          rasterized=True)  # a raster inside the SVG
        fig.colorbar(cloud, ax=b, label="k")
        c = fig.add_subplot(2, 2, 3)
        c.plot([0, 1, 2], [1000.001, 1000.002, 1000.0015])  # an offset on y
        d = fig.add_subplot(2, 2, 4, projection="polar")
        d.plot(np.linspace(0, 6, 30), np.linspace(1, 2, 30))
        return fig

    from matplotlib.backends.backend_svg import RendererSVG

    from sewmech.app.drawing import fastdraw

    render(figure(), tmp_path, "warm")  # fills the caches the figures share
    assert fastdraw._EXTENTS and fastdraw._HEIGHTS
    fig = figure()
    png = render(fig, tmp_path, "fixed")  # every text measured from the caches
    assert (tmp_path / "fixed.svg").stat().st_size > 0
    from matplotlib.ticker import FixedFormatter, FixedLocator

    assert not hasattr(RendererAgg, "_get_font_height_metrics")
    for cls in (RendererAgg, RendererSVG):  # matplotlib's own measurement is back
        assert not hasattr(cls.get_text_width_height_descent, "measure")
    # and its own fonts: the ones read from memory stay in sewmech's cache, so a PDF (which
    # embeds a font by its file) is written as before
    from matplotlib.font_manager import findfont, get_font
    from matplotlib.textpath import TextToPath

    assert fastdraw._MEMORY_FONTS and fastdraw._FONT_FILES
    assert not hasattr(RendererAgg._prepare_font, "prepare")
    from matplotlib.axis import Axis

    assert not hasattr(Axis._update_ticks, "update")  # the axes update their ticks again
    assert not hasattr(TextToPath._get_font, "prepare")
    assert "DejaVuSans.ttf" in str(get_font(findfont("DejaVu Sans")).fname)
    pdf = io.BytesIO()
    fig.savefig(pdf, format="pdf")
    assert b"DejaVuSans" in pdf.getvalue()
    assert isinstance(fig.axes[0].xaxis.get_major_locator(), FixedLocator)
    assert isinstance(fig.axes[0].yaxis.get_major_formatter(), FixedFormatter)
    assert not isinstance(fig.axes[3].yaxis.get_major_formatter(), FixedFormatter)  # offset
    ref = figure()
    ref.set_dpi(PNG_DPI)
    ref.get_layout_engine().execute(ref)
    ref.set_layout_engine(None)
    buf = io.BytesIO()
    ref.savefig(buf, format="png", dpi=PNG_DPI)
    # sewmech writes the PNG itself (rows unfiltered, zlib level 1): matplotlib's pixels,
    # resolution and Software text, decoded by Pillow
    from PIL import Image

    mine, theirs = Image.open(io.BytesIO(png)), Image.open(buf)
    assert (mine.mode, mine.size) == (theirs.mode, theirs.size) == ("RGBA", (720, 480))
    assert np.array_equal(np.asarray(mine), np.asarray(theirs))
    assert mine.info["Software"] == theirs.info["Software"]
    assert np.allclose(mine.info["dpi"], theirs.info["dpi"]) and png != buf.getvalue()
    # the SVG too, but for the ids matplotlib draws at random and the date
    svg = io.BytesIO()
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        ref.savefig(svg, format="svg")

    def norm(text):
        text = re.sub(r'(id="|#|url\(#)[A-Za-z0-9_]+', r"\1X", text)
        return re.sub(r"<dc:date>.*?</dc:date>", "", text)

    mine = norm((tmp_path / "fixed.svg").read_text())
    assert mine == norm(svg.getvalue().decode()) and "<text" in mine
    plt.close("all")


def test_reused_tick_updates_follow_the_axis():
    """A reused tick update is done again when what it reads changes: the view, the locator."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import FixedLocator

    from sewmech.app.drawing.fastdraw import reused_tick_updates

    ax = Figure().add_subplot()
    ax.set_xlim(0, 10)
    ax.xaxis.set_major_locator(FixedLocator([0, 2, 4, 6, 8, 10]))
    with reused_tick_updates():
        assert [t.get_loc() for t in ax.xaxis._update_ticks()] == [0, 2, 4, 6, 8, 10]
        ax.set_xlim(0, 5)
        assert [t.get_loc() for t in ax.xaxis._update_ticks()] == [0, 2, 4]
        ax.xaxis.set_major_locator(FixedLocator([1, 3]))
        assert [t.get_loc() for t in ax.xaxis._update_ticks()] == [1, 3]


def _rows(text: str, label: str) -> list[list[str]]:
    """The cells of a channel's rows in a printed table (its own row and those that follow
    with an empty first cell)."""
    rows, on = [], False
    for line in text.splitlines():
        cells = [c.strip() for c in line.split("│")[1:-1]]
        if not cells:
            continue
        if cells[0] == label:
            on = True
        elif cells[0]:
            on = False
        if on:
            rows.append(cells)
    return rows


def test_kinematics_at_one_angle_shows_the_values_there():
    """--phi-deg 225 printed 0 and "(constant)" for every rate and acceleration (a range of one
    value has no spread): one angle, or a few, are a table of the values at each angle."""
    m = sewmech.load_machine("jb1-3")
    out = runner.invoke(app, ["kinematics", "jb1-3", "--phi-deg", "225"],
                        env={"COLUMNS": "140"})
    assert out.exit_code == 0, out.stderr
    assert "(constant)" not in out.stdout
    r = sewmech.kinematics(m, np.radians([225.0]))
    (row,) = _rows(out.stdout, "needle.point.y")
    assert row[1:3] == ["mm", "225"]
    p, v, a = (float(c) for c in row[3:6])
    pm = r.point("needle.point")
    assert p == pytest.approx(pm.p[0, 1], rel=1e-6)
    assert v == pytest.approx(pm.v[0, 1], rel=1e-3) and abs(v) > 100.0  # mm/s at 1000 rpm
    assert a == pytest.approx(pm.a[0, 1], rel=1e-3) and abs(a) > 1e3
    # a frame point: its place, no rate
    assert _rows(out.stdout, "O2.x")[0][3:6] == ["-16.25", "0", "0"]
    # a few angles: a row each
    out = runner.invoke(app, ["kinematics", "jb1-3", "--phi-deg", "0", "--phi-deg", "90",
                              "--phi-deg", "225"], env={"COLUMNS": "140"})
    assert out.exit_code == 0, out.stderr
    rows = _rows(out.stdout, "needle.point.y")
    r = sewmech.kinematics(m, np.radians([0.0, 90.0, 225.0]))
    assert [c[2] for c in rows] == ["0", "90", "225"]
    np.testing.assert_allclose([float(c[4]) for c in rows], r.point("needle.point").v[:, 1],
                               rtol=1e-3, atol=1e-6 * 1000.0)


def test_kinematics_summary_calls_constant_only_what_does_not_move():
    """The whole turn's summary: a channel is constant only when its position, its rate and its
    acceleration are all round-off; a crank pin's x at 90 and 270 deg has the same value (0)
    at both but moves, and is not called constant."""
    from rich.console import Console

    from sewmech.app.cli.analysis import _summary

    m = fourbar()
    r = sewmech.kinematics(m, np.radians([90.0, 270.0]))
    assert np.ptp(r.point("B").p[:, 0]) < 1e-12 and np.abs(r.point("B").v[:, 0]).min() > 1.0
    con = Console(width=200, record=True)
    con.print(_summary(r))
    text = con.export_text()
    (row,) = _rows(text, "B.x")
    assert "(constant)" not in row and float(row[4]) > 1.0
    (row,) = _rows(text, "A.x")  # the frame pivot
    assert row[3:6] == ["(constant)", "0", "0"]
