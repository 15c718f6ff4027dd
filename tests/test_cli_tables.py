"""What a newcomer reads first on the command line: tables written to a pipe or a file are
never cut, in a terminal they fit and still cut no value, every number says its unit, a
point unit's wrong origin names the points it may take, the documentation's small machine
file passes `sewmech check`, and `sewmech serve` ends normally on Ctrl-C."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest
from sewmech.cli import app
from typer.testing import CliRunner

import sewmech
from conftest import BENCH, FOURBAR_LOOP
from sewmech.app.cli import common
from sewmech.engine.machine import shipped_machines

ROOT = Path(__file__).resolve().parent.parent
runner = CliRunner()


def _cli() -> list[str]:
    exe = Path(sys.executable).with_name("sewmech")
    return [str(exe)] if exe.exists() else [sys.executable, "-c",
                                            "from sewmech.cli import main; main()"]


def _cells(out: str, column: int) -> list[str]:
    """The text of one column of every body row of the rich tables in ``out``."""
    rows = [line.split("│") for line in out.splitlines() if line.startswith("│")]
    return [r[column + 1].strip() for r in rows if len(r) > column + 1]


# ---- a pipe or a file: no width limit --------------------------------------------------------

def test_tables_written_to_a_pipe_are_never_cut():
    res = runner.invoke(app, ["feed", "jb1-3"])  # (the runner's output is not a terminal)
    assert res.exit_code == 0, res.output
    assert "…" not in res.output
    header = next(line for line in res.output.splitlines() if "regulator_deg" in line)
    for col in ("regulator_deg", "stitch_mm", "lift_mm", "rise_deg", "top_deg",
                "mid_feed_deg", "fall_deg"):
        assert re.search(rf"┃ +{col} +┃", header), (col, header)
    res = runner.invoke(app, ["machines"])
    assert res.exit_code == 0 and "…" not in res.output
    assert _cells(res.output, 3) == [str(p) for _, p in sorted(shipped_machines().items())]


def test_a_table_piped_from_the_command_is_whole():
    """The real process with its stdout a pipe (and stdin whatever the test runner has)."""
    p = subprocess.run(_cli() + ["machines"], capture_output=True, text=True, timeout=120,
                       check=False, env={**os.environ, "COLUMNS": "60"})  # (does not count)
    assert p.returncode == 0, p.stderr
    assert "…" not in p.stdout
    for path in shipped_machines().values():
        assert str(path) in p.stdout


def test_in_a_terminal_tables_fit_and_paths_fold_whole(monkeypatch):
    monkeypatch.setattr(common.console, "_force_terminal", True)
    monkeypatch.setattr(common.console, "_width", 80)
    monkeypatch.setattr(common.console, "_color_system", None)
    assert common.console.is_terminal and common.console.width == 80
    res = runner.invoke(app, ["machines"])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert max(len(line) for line in lines) <= 80
    assert "…" not in res.output
    # a path too long for its column goes on to the next lines, whole
    text = "".join(_cells(res.output, 3))
    for path in shipped_machines().values():
        assert str(path) in text


# ---- units -----------------------------------------------------------------------------------

def test_the_margin_table_of_check_says_its_units():
    res = runner.invoke(app, ["check", "jb1-3"])
    assert res.exit_code == 0, res.output
    header = next(line for line in res.output.splitlines() if "condition" in line)
    assert "margin [mm]" in header and "at phi [deg]" in header
    # a setting is shown as written, its table name too ([thread.adjust] is not markup)
    assert "Q.y = 22 ([thread.adjust] max)" in res.output


def test_the_feed_marks_say_their_units():
    res = runner.invoke(app, ["feed", "jb1-3"])
    assert "stitch [mm]" in res.output and "regulator [deg]" in res.output


# ---- a point unit's origin -------------------------------------------------------------------

FOURBAR = (ROOT / "src" / "sewmech" / "data" / "machines" / "fourbar-benchmark.toml").read_text(
    encoding="utf-8")


def test_a_wrong_origin_names_the_points_it_may_take(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(FOURBAR.replace('link = "coupler"\norigin = "B"',
                                   'link = "coupler"\norigin = "D"'), encoding="utf-8")
    res = runner.invoke(app, ["check", str(bad)])
    assert res.exit_code == 2
    line = " ".join(res.output.split())
    assert '[units[2] "coupler_point"] origin:' in line
    assert "origin 'D' is not a point of link 'coupler' ('D' is on frame, rocker)" in line
    assert "the points of 'coupler' solved above this unit are: B, C" in line
    assert "Set origin to one of them, or link to a link 'D' is on" in line
    # the same mistake on a loop unit's link that has no point yet: what to do instead
    text = FOURBAR_LOOP.format(**BENCH, assembly=0.0, g_coupler=60.0, g_rocker=100.0) + (
        '[[units]]\ntype = "point"\nname = "cp"\nlink = "coupler"\norigin = "B"\n'
        'points = { P = [30.0, 10.0] }\n')
    with pytest.raises(sewmech.MachineFileError) as exc:
        sewmech.machine_from_toml(text, "loop.toml")
    msg = str(exc.value)
    assert "origin 'B' is not a point of link 'coupler' ('B' is on crank)" in msg
    assert "no point of 'coupler' is solved above this unit" in msg
    assert "joints" in msg  # the loop unit's joints put its points on its links


def test_a_load_on_the_wrong_link_names_the_points_of_that_link(tmp_path):
    loads = tmp_path / "loads.toml"
    loads.write_text('[[loads]]\nname = "pull"\nlink = "take_up_lever"\npoint = "needle.eye"\n'
                     'force_N = 3.0\nangle_deg = -90.0\n', encoding="utf-8")
    res = runner.invoke(app, ["dynamics", "jb1-3", "--loads", str(loads)])
    assert res.exit_code == 2
    line = " ".join(res.output.split())
    assert "the points of 'take_up_lever' are: T, R, take_up.eye" in line


# ---- the documentation's machine file --------------------------------------------------------

def _doc_machine() -> str:
    doc = (ROOT / "docs" / "machine-files.md").read_text(encoding="utf-8")
    section = doc.split("## A complete small machine file", 1)[1]
    return section.split("```toml\n", 1)[1].split("```", 1)[0]


def test_the_small_machine_file_of_the_docs_is_complete(tmp_path):
    text = _doc_machine()
    path = tmp_path / "small-machine.toml"
    path.write_text(text, encoding="utf-8")
    res = runner.invoke(app, ["check", str(path)])
    assert res.exit_code == 0, res.output
    assert "small-machine: valid" in res.output and "checked" in res.output
    m = sewmech.load_machine(path)
    assert m.spec.sewing is not None and m.spec.masses  # the roles and the masses are there
    res = runner.invoke(app, ["dynamics", str(path)])
    assert res.exit_code == 0, res.output
    # every table it has is one this page explains
    doc = (ROOT / "docs" / "machine-files.md").read_text(encoding="utf-8")
    for table in re.findall(r"^\[+([a-z_]+)", text, flags=re.MULTILINE):
        assert f"[{table}" in doc.split("## Every table", 1)[1], table


# ---- serve: Ctrl-C is its normal end ---------------------------------------------------------

@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_serve_stopped_by_its_documented_stop_ends_normally(tmp_path, sig):
    p = subprocess.Popen(_cli() + ["serve", "fourbar-benchmark", "--port", "0"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        first = p.stdout.readline()
        url = re.search(r"http://\S+/", first).group(0)
        deadline = time.monotonic() + 60
        while True:  # the page answers: the server runs
            try:
                with urllib.request.urlopen(url + "api/machines", timeout=5) as r:
                    assert r.status == 200
                break
            except OSError:
                assert time.monotonic() < deadline, "the server never answered"
                time.sleep(0.1)
        p.send_signal(sig)
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    assert p.returncode == 0, err
    assert "error" not in err and "Traceback" not in err
    assert out.strip().splitlines()[-1] == "sewmech: the page's server stopped"
