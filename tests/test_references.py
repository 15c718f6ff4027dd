"""The published facts sewmech checks against travel with it: docs/references.md, written from
sewmech.sewing.references, and cited by key from the checks, the machine files, the docs and
the page. Nothing a user gets names a file they do not have (notes kept outside the repository
while sewmech was written)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

import sewmech
from sewmech.cli import app
from sewmech.sewing.references import BY_KEY, REFERENCES, cited, keys_in, markdown

ROOT = Path(__file__).resolve().parents[1]
#: names of files outside the repository (assembled so that this file does not match itself)
OUTSIDE = re.compile("|".join([r"DOMAIN(\.md|\s+\d)", r"\bseeds/", r"\bshared/",
                               r"\b(SPEC|STYLE)\.md", r"\.(ru|zh)\.txt\b"]))
TEXT = {".py", ".toml", ".md", ".js", ".html", ".css", ".csv", ".txt", ".cfg"}


def _shipped() -> list[Path]:
    """Every text file a user of sewmech gets or reads: the package (its data included), the
    docs, the README, the examples, studies, benchmarks and tests."""
    files = [ROOT / "README.md", ROOT / "Makefile", ROOT / "pyproject.toml"]
    for folder in ("src/sewmech", "docs", "examples", "studies", "benchmarks", "tests"):
        files += [p for p in (ROOT / folder).rglob("*") if p.suffix in TEXT
                  and "__pycache__" not in p.parts and p.is_file()]
    return [p for p in files if p.exists() and p.resolve() != Path(__file__).resolve()]


def _text(path: Path) -> str:
    return path.read_text(encoding="utf-8", errors="replace")


def test_docs_page_is_written_from_the_list():
    page = ROOT / "docs" / "references.md"
    assert _text(page) == markdown(), (
        "docs/references.md is out of date: python -m sewmech.sewing.references >"
        " docs/references.md")


def test_no_shipped_file_names_a_file_outside_the_repository():
    found = [f"{p.relative_to(ROOT)}:{n}: {line.strip()[:90]}"
             for p in _shipped() for n, line in enumerate(_text(p).splitlines(), 1)
             if OUTSIDE.search(line)]
    assert found == [], "\n".join(found)


def test_every_cited_key_has_an_entry():
    # (the list's own module holds the key pattern; its entries are in docs/references.md)
    own = ROOT / "src/sewmech/sewing/references.py"
    unknown = [f"{p.relative_to(ROOT)}: [{k}]" for p in _shipped() if p != own
               for k in keys_in(_text(p)) if k not in BY_KEY]
    assert unknown == [], "keys without an entry in sewmech.sewing.references:\n" + "\n".join(
        unknown)


def test_every_entry_is_cited_or_background():
    own = {ROOT / "src/sewmech/sewing/references.py", ROOT / "docs/references.md"}
    used = {k for p in _shipped() if p not in own for k in keys_in(_text(p))}
    # a background entry may be cited only from another entry
    used |= {k for r in REFERENCES for f in r.facts for k in keys_in(f.what + f.used)}
    uncited = [r.key for r in REFERENCES if r.key not in used and not r.background]
    assert uncited == []


def test_entries_are_complete():
    assert len(BY_KEY) == len(REFERENCES)  # keys are unique
    for r in REFERENCES:
        assert keys_in(f"[{r.key}]") == [r.key], r.key  # the key has the citation's form
        assert r.source.strip() and r.checked
        assert r.facts or r.background, r.key
        for f in r.facts:
            assert f.value and f.what and f.used, r.key
        assert not r.url or r.url.startswith(("http://", "https://")), r.key


def test_keys_and_what_is_not_a_key():
    text = "see [JB-dynamics] and [ISO-286]; not [estimate], x[k-1], [JB8-2] or [docs](x.md)"
    assert keys_in(text) == ["JB-dynamics", "ISO-286"]
    assert [r.key for r in cited(text + " [JB-dynamics] [No-such-key]")] == ["JB-dynamics",
                                                                              "ISO-286"]


@pytest.mark.parametrize("name", ["jb1-3", "jb8-2"])
def test_every_check_cites_its_sources_by_key(name):
    from sewmech.checks import check_timing
    from sewmech.thread import check_thread

    m = sewmech.load_machine(name)
    checks = check_timing(m) + check_thread(m)
    assert len(checks) == 17
    for c in checks:
        if c.source.startswith(("the force analysis", "the energy balance")):
            # the machine's own dynamics (its one-sided contacts, its loads' energy): checked
            # against its own analysis, which the docs describe, not against a published value
            assert c.source.endswith("(docs/dynamics.md)"), c.source
            continue
        keys = keys_in(c.source)
        assert keys, f"{c.name}: {c.source!r} cites no source"
        assert all(k in BY_KEY for k in keys), c.source
        assert not OUTSIDE.search(c.source)


def test_the_page_gets_each_check_with_its_references():
    from sewmech.app.web.session import check_dict
    from sewmech.checks import check_timing

    c = next(c for c in check_timing(sewmech.load_machine("jb1-3")) if c.name == "shuttle swing")
    d = check_dict(c)
    assert d["source"].startswith("[EC-household-machine]")
    assert d["references"] == [BY_KEY["EC-household-machine"].brief()]
    assert "Encyclopedia of China" in d["references"][0]["source"]


def test_check_command_names_no_file_outside_the_repository():
    out = CliRunner().invoke(app, ["check", "jb1-3", "--parameters"])
    assert out.exit_code == 0, out.output
    assert not OUTSIDE.search(out.output)
