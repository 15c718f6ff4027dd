"""The install: the lock holds every dependency pyproject.toml asks for, at a version it allows,
with hashes; the Makefile installs from it; the metadata builds without deprecation boxes."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from packaging.markers import default_environment
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[1]


def _project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]


def _lock() -> dict[str, list[tuple[str, str]]]:
    """name -> [(version, marker)] of requirements.lock (a universal lock may pin a package
    twice, once per range of Python versions)."""
    pins: dict[str, list[tuple[str, str]]] = {}
    text = (ROOT / "requirements.lock").read_text(encoding="utf-8")
    for m in re.finditer(r"^([A-Za-z0-9_.\-]+)==([^\s;\\]+)\s*(?:;\s*([^\\\n]+?))?\s*\\?$", text,
                         re.M):
        pins.setdefault(canonicalize_name(m[1]), []).append((m[2], (m[3] or "").strip()))
    return pins


def test_the_lock_pins_every_dependency_at_an_allowed_version_with_hashes():
    project, pins = _project(), _lock()
    wanted = list(project["dependencies"])
    for extra in ("test", "bench", "dev"):
        wanted += project["optional-dependencies"][extra]
    wanted += ["setuptools>=77", "wheel"]  # the build tools (make lock gives them)
    env = default_environment()
    for text in wanted:
        req = Requirement(text)
        versions = [v for v, marker in pins.get(canonicalize_name(req.name), [])
                    if not marker or Requirement(f"x; {marker}").marker.evaluate(env)]
        assert len(versions) == 1, f"{req.name}: pinned {versions} for this Python in the lock"
        assert req.specifier.contains(versions[0], prereleases=True), (
            f"{req.name}=={versions[0]} in requirements.lock is outside {req.specifier}:"
            " run make lock")
    text = (ROOT / "requirements.lock").read_text(encoding="utf-8")
    blocks = re.split(r"\n(?=\w)", text.split("\n", 2)[2])  # one block a pinned package
    assert all("--hash=sha256:" in b for b in blocks if "==" in b)


def test_make_installs_from_the_lock_and_checks_its_hashes():
    make = (ROOT / "Makefile").read_text(encoding="utf-8")
    assert re.search(r"pip install .*--require-hashes.*-r \$\(LOCK\)", make)
    assert "test-latest:" in make and "lock:" in make
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert "make test" in ci


def test_the_license_is_an_spdx_string():
    # a table ({ text = "MIT" }) makes setuptools print a deprecation box on every install
    assert _project()["license"] == "MIT"
