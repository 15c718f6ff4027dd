"""The table of current figures (benchmarks/table.py): built from the results files, met or not
computed from the figure against the target, a results file without its rows named in a
sentence, and BENCHMARKS.md's table the one the committed results files give. No benchmark
runs here."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "benchmarks"


@pytest.fixture(scope="module")
def table():
    sys.path.insert(0, str(BENCH))
    try:
        spec = importlib.util.spec_from_file_location("bench_table", BENCH / "table.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = mod  # (its dataclass looks itself up there)
        spec.loader.exec_module(mod)
        yield mod
    finally:
        sys.path.remove(str(BENCH))
        sys.modules.pop("bench_table", None)


@pytest.fixture(scope="module")
def timing(table):
    return sys.modules["_timing"]


def write(path: Path, data: dict) -> None:
    path.write_text(json.dumps(data), encoding="utf-8")


def test_rows_from_the_results_files(table, timing, tmp_path):
    f = timing.figure
    write(tmp_path / "a.json", {"keep": 1, "date": "2026-11-20", "commit": "abc1234", "figures": [
        f("fast job", 4.0, "ms", target=5.0),
        f("slow job", 6.0, "ms", target=5.0),
        f("against a peer", 10.0, "ms", anchor="peer", anchor_value=35.0, ratio=3.5,
          target=3.0, op=">=", on="ratio"),
        f("costly", 40.0, "ms", anchor="one call", anchor_value=2.0, ratio=20.0,
          ratio_kind="time", target=4.0, on="ratio"),
        f("information", 1.0, "s"),
        f("with a condition", 1.0, "s", target=2.0, condition=("the same answer", False)),
    ]})
    rows, problems = table.load(tmp_path)
    assert problems == []
    assert [r.met for r in rows] == [True, False, True, False, None, False]
    assert {(r.date, r.commit) for r in rows} == {("2026-11-20", "abc1234")}
    text = table.render(rows)
    lines = text.splitlines()
    assert lines[0] == "| job | anchor | sewmech | ratio | target | met | date | commit |"
    assert "| slow job |  | 6 ms |  | <= 5 ms | **MISSED** | 2026-11-20 | abc1234 |" in lines
    assert "| against a peer | peer: 35 ms | 10 ms | 3.5x faster | >= 3x faster | met |" \
        in text
    assert "| 20x the time | <= 4x the time | **MISSED** |" in text
    assert "| information |  | 1 s |  | (information) |  |" in text
    assert "and the same answer (not held) | **MISSED** |" in text
    assert lines[-1] == "5 targets: 2 met, 3 missed; 1 figures for information."


def test_met_is_recomputed_not_copied(table, timing, tmp_path):
    row = timing.figure("claims met", 9.0, "s", target=2.0)
    row["met"] = True  # a hand-edited file
    write(tmp_path / "b.json", {"figures": [row], "date": "2026-11-20", "commit": "abc1234"})
    rows, problems = table.load(tmp_path)
    assert rows[0].met is False
    assert problems == ["b.json: row 1 ('claims met') says met = True but its figure against its"
                        " target gives False (the table shows the latter)"]


def test_a_file_without_its_rows_is_named_not_a_traceback(table, timing, tmp_path):
    write(tmp_path / "old.json", {"best_s": 1.0})
    write(tmp_path / "partial.json", {"figures": [{"job": "no figure", "unit": "s"},
                                                  timing.figure("fine", 1.0, "s")]})
    (tmp_path / "broken.json").write_text("{", encoding="utf-8")
    rows, problems = table.load(tmp_path)
    assert [r.job for r in rows] == ["fine"]
    assert rows[0].date == rows[0].commit == "?"  # not committed: git has no date for it
    assert problems[0].startswith("broken.json: not readable JSON")
    assert problems[1].startswith("old.json: no 'figures' list (the rows of this table): run"
                                  " its benchmark again")
    assert problems[2] == "partial.json: row 1 ('no figure') has no figure"


def test_the_helper_checks_its_arguments(timing):
    with pytest.raises(ValueError, match="op must be one of"):
        timing.figure("x", 1.0, "s", target=1.0, op="=<")
    with pytest.raises(ValueError, match="on must be"):
        timing.figure("x", 1.0, "s", target=1.0, on="anchor")


def test_benchmarks_md_shows_the_committed_results(table):
    """The table at the top of BENCHMARKS.md is what the results files give (run
    ``python benchmarks/table.py --write`` after a benchmark run, as ``make bench`` does)."""
    rows, problems = table.load()
    assert problems == []
    assert rows, "no rows in benchmarks/results/*.json"
    doc = (ROOT / "BENCHMARKS.md").read_text(encoding="utf-8")
    assert table.current_block(doc) == table.render(rows), (
        "BENCHMARKS.md's table of current figures is not the one benchmarks/results/*.json"
        " give: run python benchmarks/table.py --write")
    assert doc[:doc.index(table.START)].count("\n## ") == 1, "the table is the first section"


def test_every_results_file_has_a_benchmark_writing_it():
    """Each results file is written by a bench_*.py through _timing.write_results (so that a
    new benchmark adds its rows the same way)."""
    scripts = {p.name: p.read_text(encoding="utf-8") for p in BENCH.glob("bench_*.py")}
    for path in (BENCH / "results").glob("*.json"):
        writers = [n for n, s in scripts.items() if path.name in s]
        assert writers, f"no bench_*.py names {path.name}"
        assert all("write_results(" in scripts[n] for n in writers), writers


def test_write_results_keeps_the_keys_and_stamps_the_run(table, timing, tmp_path):
    path = tmp_path / "results" / "x.json"
    timing.write_results(path, {"best_s": 1.5, "rows": {"a": 1}},
                         [timing.figure("x", 1.5, "s", target=2.0)])
    data = json.loads(path.read_text(encoding="utf-8"))
    assert data["best_s"] == 1.5 and data["rows"] == {"a": 1}
    assert data["figures"][0]["met"] is True
    assert len(data["date"]) == 10 and data["date"][4] == "-"
    assert data["commit"] is None or data["commit"].rstrip("+").isalnum()
    assert "load_1min" in data
    rows, problems = table.load(path.parent)
    assert problems == [] and rows[0].commit == str(data["commit"])
