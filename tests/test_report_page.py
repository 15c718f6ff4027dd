"""The report as a reader meets it: a contents list whose links land, a labelled drawing of the
mechanism that names every point and pair the tables use, numbers at the precision of their
quantity (never round-off, never True/False), a section that is left out saying why, the
circular-arc cams' kinks explained where they show, and every source key resolved."""

from __future__ import annotations

import html
import re

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

import sewmech
from sewmech.cli import app
from sewmech.sewing.references import BY_KEY, keys_in

from test_references import OUTSIDE

runner = CliRunner()
#: the shipped machines with [sewing] roles, and the step of their reports here (the
#: convention's angle, 90 deg, is on each grid)
REPORTS = {"jb1-3": "2", "jb8-2": "2", "bartack-1820": "5"}


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """name -> (output directory, page text, command output)."""
    out = {}
    for name, step in REPORTS.items():
        d = tmp_path_factory.mktemp(name) / "rep"
        res = runner.invoke(app, ["report", name, "--out", str(d), "--step-deg", step])
        assert res.exit_code == 0, res.output
        out[name] = (d, (d / "index.html").read_text(encoding="utf-8"), res.output)
    return out


def _ids(page: str) -> list[str]:
    return re.findall(r'\sid="([^"]+)"', page)


def _tables(page: str) -> str:
    return "".join(re.findall(r"<table.*?</table>", page, re.S))


def _rows(page: str, table_class: str | None = None) -> list[list[str]]:
    tables = re.findall(r"<table[^>]*>.*?</table>", page, re.S)
    if table_class:
        tables = [t for t in tables if table_class in t.split(">", 1)[0]]
    rows = []
    for t in tables:
        for tr in re.findall(r"<tr>(.*?)</tr>", t, re.S):
            rows.append([html.unescape(re.sub(r"<[^>]+>", "", c)).strip()
                         for c in re.findall(r"<td[^>]*>(.*?)</td>", tr, re.S)])
    return rows


@pytest.mark.parametrize("name", REPORTS)
def test_contents_list_links_to_every_section(reports, name):
    _, page, _ = reports[name]
    nav = re.search(r'<nav id="contents">(.*?)</nav>', page, re.S)
    assert nav, "no contents list"
    links = re.findall(r'href="#([^"]+)"', nav.group(1))
    ids = _ids(page)
    assert len(ids) == len(set(ids)), "ids are not unique"
    assert set(links) <= set(ids), f"links to nothing: {set(links) - set(ids)}"
    sections = re.findall(r'<h2 id="([^"]+)">', page)
    assert set(sections) <= set(links)  # every section is in the contents
    figures = re.findall(r'<figure id="([^"]+)">', page)
    assert set(figures) <= set(links)  # and every figure, under its section
    assert "mechanism" in links and links.index("checks") > links.index("mechanism")


@pytest.mark.parametrize("name", REPORTS)
def test_the_mechanism_is_drawn_with_every_name(reports, name):
    d, page, _ = reports[name]
    assert '<figure id="mechanism">' in page
    assert page.index('<figure id="mechanism">') < page.index('<h2 id="checks">')
    assert (d / f"{name}-mechanism.png").stat().st_size > 20_000
    assert (d / f"{name}-mechanism.svg").stat().st_size > 20_000
    data = pd.read_csv(d / f"{name}-mechanism.csv")
    m = sewmech.load_machine(name)
    names = set(data["name"])
    assert set(m.point_names) <= names
    assert {p.name for p in m.pairs} <= names
    # at the stated angle: the convention's, every point where the kinematics puts it
    caption = re.search(r'<figure id="mechanism">.*?<figcaption>(.*?)</figcaption>', page,
                        re.S).group(1)
    assert "at phi = 90 deg (needle bar at its top dead centre)" in caption
    r = sewmech.kinematics(m, np.radians([90.0]))
    pts = data[data["kind"].isin(["point", "pivot", "frame point"])].set_index("name")
    for i, pt in enumerate(r.point_names):
        assert pts.loc[pt, "x_mm"] == pytest.approx(r.p[0, i, 0], abs=1e-6)
        assert pts.loc[pt, "y_mm"] == pytest.approx(r.p[0, i, 1], abs=1e-6)
    # the drawing's text (SVG keeps text as text) has every point's and pair's name: a pin
    # named as its point shares the point's label
    svg = (d / f"{name}-mechanism.svg").read_text(encoding="utf-8")
    texts = {html.unescape(t) for t in re.findall(r">([^<>]*)</text>", svg)}
    assert names <= texts, names - texts


def test_the_pairs_of_the_force_table_are_in_the_drawing(reports):
    d, page, _ = reports["jb1-3"]
    drawn = set(pd.read_csv(d / "jb1-3-mechanism.csv")["name"])
    table = {r[0] for r in _rows(page) if len(r) == 7 and r[1] in ("revolute", "prismatic",
                                                                  "slot", "cam", "driver")}
    assert len(table) == 28 and {"E", "D", "K", "Lp", "feed_fork.cam"} <= table
    assert table <= drawn


@pytest.mark.parametrize("name", REPORTS)
def test_tables_show_no_round_off_and_no_flags_as_python_writes_them(reports, name):
    d, page, _ = reports[name]
    tables = _tables(page)
    bad = re.findall(r">\s*(True|False|nan|NaN|-0(?:\.0+)?|[-0-9.]+e-(?:1\d|0[5-9]))\s*<",
                     tables)
    assert bad == [], bad
    # a real small number keeps its digits: nothing below 1e-4 was made up either way
    if name != "bartack-1820":
        checks = {r[0]: r[1] for r in _rows(page, "checks")}
        assert checks["stitch at the regulator's zero mark"] == "0"
        sens = [r for r in _rows(page) if r and r[0] == "feed cam width (fork gap)"]
        assert sens and all(c in ("0", "yes") for c in sens[0][1:]), sens
        # the zero mark's curve is named as a zero, in the data and in the legend
        header = (d / f"{name}-feed-trajectories.csv").read_text().splitlines()[0]
        assert "x_mm_reg_0deg" in header and "-0.0" not in header


def test_a_section_left_out_says_why(reports):
    _, page82, _ = reports["jb8-2"]
    assert ('<h2 id="balancing">Balancing</h2><p class="sub left-out">Left out because'
            " jb8-2.toml has no [counterweights] table") in page82
    assert re.search(r'<a href="#balancing">Balancing</a> \(left out\)', page82)
    _, page13, _ = reports["jb1-3"]
    assert "Left out because" not in page13  # jb1-3 has every section
    _, bartack, _ = reports["bartack-1820"]
    for section in ("feed", "thread", "accuracy"):
        assert re.search(rf'<h2 id="{section}">[^<]*</h2><p class="sub left-out">Left out'
                         " because", bartack), section


def test_captions_explain_the_cams_kinks(reports):
    _, page, _ = reports["jb1-3"]
    for fig in ("dyn-torque", "dyn-shaking", "dyn-bearings", "dyn-regulator", "bal-components"):
        caption = re.search(rf'<figure id="{fig}">.*?<figcaption>(.*?)</figcaption>', page,
                            re.S).group(1)
        assert "the circular-arc cam (feed_cam)" in caption, fig  # one arc: no jump
        assert caption.count("where two arcs meet") == 1
    _, bartack, _ = reports["bartack-1820"]  # no cams: nothing to explain
    assert "circular-arc cam" not in bartack


@pytest.mark.parametrize("name", REPORTS)
def test_every_key_resolves_and_no_file_outside_is_named(reports, name):
    d, page, output = reports[name]
    keys = keys_in(page)
    assert keys and set(keys) <= set(BY_KEY)
    for k in keys:
        assert f'<dt id="ref-{k}">' in page, k
    assert '<h2 id="references">References</h2>' in page
    for text in [page, output] + [p.read_text(encoding="utf-8") for p in d.glob("*.csv")]:
        assert not OUTSIDE.search(text)


def test_place_labels_keeps_labels_apart():
    from sewmech.app.drawing.mechanism import place_labels

    rng = np.random.default_rng(1)
    # twenty labels on five crowded points in a roomy drawing: none overlaps another
    anchors = np.repeat(rng.uniform(200, 300, (5, 2)), 4, axis=0)
    sizes = np.column_stack([rng.uniform(10, 60, 20), np.full(20, 9.0)])
    boxes = place_labels(anchors, sizes, (0, 0, 500, 500))
    assert np.allclose(boxes[:, 2:] - boxes[:, :2], sizes)
    for i in range(20):
        for j in range(i):
            w = min(boxes[i, 2], boxes[j, 2]) - max(boxes[i, 0], boxes[j, 0])
            h = min(boxes[i, 3], boxes[j, 3]) - max(boxes[i, 1], boxes[j, 1])
            assert w <= 0 or h <= 0, (i, j)
    assert np.all(boxes[:, :2] >= 0) and np.all(boxes[:, 2:] <= 500)
    # a lone label sits beside its point, towards the side asked for
    box = place_labels([[100.0, 100.0]], [[30.0, 8.0]], (0, 0, 500, 500), prefer=[np.pi])[0]
    assert box[2] <= 100.0 and abs((box[1] + box[3]) / 2 - 100.0) < 1e-9
    assert 100.0 - box[2] < 10.0


def test_the_drawing_is_the_turn_of_the_motion_diagrams(reports):
    """The mechanism is drawn from the report's own kinematics (no call of its own)."""
    d, _, _ = reports["jb1-3"]
    motion = pd.read_csv(d / "jb1-3-motion.csv")
    data = pd.read_csv(d / "jb1-3-mechanism.csv").set_index("name")
    k = int(np.flatnonzero(motion["phi_deg"] == 90.0)[0])
    y = motion["needle.point height y [mm]"].iloc[k]
    assert data.loc["needle.point", "y_mm"] == pytest.approx(y, abs=1e-9)


def test_the_vibration_section_is_the_librarys(reports):
    """The section "Vibration and running": its levels are housing_vibration's at the working
    setting (as the file has it, and with the counterweights the vibration criterion chose),
    its modes the housing's; a machine without counterweights gets the section on its own."""
    from sewmech.design.balancing import balance
    from sewmech.engine.housing import Housing, housing_vibration

    d, page, _ = reports["jb1-3"]
    assert '<h2 id="vibration">Vibration and running</h2>' in page
    m = sewmech.load_machine("jb1-3")
    levels = pd.read_csv(d / "jb1-3-vibration-levels.csv")
    as_file = levels[levels["machine"] == "as the file has it"].iloc[0]
    v = housing_vibration(m, 2.0)
    for j, ax in enumerate("xyz"):
        assert as_file[f"{ax} [dB]"] == pytest.approx(float(v.level_db[0, j]), abs=1e-6)
    res = balance(m, "vibration")
    balanced = levels[levels["machine"] != "as the file has it"].iloc[0]
    v2 = housing_vibration(m.with_parameters(res.overrides), 2.0)
    for j, ax in enumerate("xyz"):
        assert balanced[f"{ax} [dB]"] == pytest.approx(float(v2.level_db[0, j]), abs=1e-6)
    assert max(balanced["x [dB]"], balanced["y [dB]"]) <= max(as_file["x [dB]"],
                                                              as_file["y [dB]"]) + 1e-9
    modes = pd.read_csv(d / "jb1-3-housing-modes.csv")
    f, _ = Housing.of(m).modes()
    np.testing.assert_allclose(modes["frequency [Hz]"], f, rtol=1e-9)
    for stem in ("vib-spectrum", "vib-speed"):
        assert (d / f"jb1-3-{stem}.png").stat().st_size > 5000
    speed = pd.read_csv(d / "jb1-3-vib-speed.csv")
    k = int(np.argmin(np.abs(speed["rpm"] - m.rpm)))
    assert speed["rpm"][k] == pytest.approx(m.rpm)  # the working speed is on the sweep's grid
    assert speed["x_db_before"][k] == pytest.approx(float(v.level_db[0, 0]), abs=0.2)
    _, page82, _ = reports["jb8-2"]
    assert '<h2 id="vibration">Vibration and running</h2><p>' in page82
