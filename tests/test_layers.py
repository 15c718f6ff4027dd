"""The package's layers import downward only, without cycles, and the numeric layers import no
plotting or command-line library (docs/architecture.md)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import sewmech

ROOT = Path(sewmech.__file__).resolve().parent
#: the layers from the bottom up; a module may import its own layer and the ones below
LAYERS = ("engine", "sewing", "design", "app")
#: what the numeric layers must never import
APP_ONLY = ("matplotlib", "typer", "rich", "click")


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT).with_suffix("")
        parts = ("sewmech",) + rel.parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _imports(name: str, path: Path) -> list[tuple[str, int]]:
    """Every module an import statement of the file names (at any depth: imports inside
    functions count), with its line."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            found.append((mod, node.lineno))
            # `from . import feed`: the names may be modules themselves
            found += [(f"{mod}.{a.name}", node.lineno) for a in node.names]
    return found


def _layer(module: str) -> int | None:
    parts = module.split(".")
    if len(parts) > 1 and parts[0] == "sewmech" and parts[1] in LAYERS:
        return LAYERS.index(parts[1])
    return None


MODULES = _modules()


def test_every_module_lives_in_a_layer():
    loose = [m for m in MODULES if m.count(".") == 1 and m.split(".")[1] not in LAYERS
             and m != "sewmech.data"]
    assert loose == [], f"modules outside the layers: {loose}"


@pytest.mark.parametrize("name", [m for m in MODULES if _layer(m) is not None])
def test_imports_run_downward(name):
    own = _layer(name)
    for mod, line in _imports(name, MODULES[name]):
        other = _layer(mod)
        assert other is None or other <= own, (
            f"{MODULES[name].relative_to(ROOT.parent)}:{line} imports {mod}: layer"
            f" {LAYERS[other]} is above {LAYERS[own]}")
        if own < LAYERS.index("app"):
            assert mod.split(".")[0] not in APP_ONLY, (
                f"{name}:{line} imports {mod}: numeric code imports no plotting or CLI")


def test_no_import_cycles():
    graph = {name: {mod for mod, _ in _imports(name, path) if mod in MODULES and mod != name
                    and _layer(mod) is not None}
             for name, path in MODULES.items() if _layer(name) is not None}
    state: dict[str, int] = {}

    def visit(node, trail):
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycle = trail[trail.index(nxt):] + [nxt]
                raise AssertionError("import cycle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt, trail + [nxt])
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])


def test_short_module_names_are_the_layers_modules():
    import importlib

    for short, where in sewmech.MODULES.items():
        assert importlib.import_module(f"sewmech.{short}") is importlib.import_module(
            f"sewmech.{where}")
    # the names the README uses, and the functions that share a module's name
    from sewmech.dynamics import inverse_dynamics  # noqa: F401
    from sewmech.timing import check_timing

    assert check_timing is sewmech.checks.check_timing
    assert callable(sewmech.kinematics) and sewmech.kinematics.__module__ == (
        "sewmech.engine.kinematics")
    assert sewmech.errors.SewmechError is sewmech.SewmechError


def test_the_application_layer_is_in_rooms():
    """app/ holds folders of one kind each (the command line, the report, the page, figures,
    files), the sweep runner and how numbers are shown; a new command or report section goes
    into its room."""
    rooms = {"cli", "report", "web", "drawing", "files"}
    loose = sorted(p.name for p in (ROOT / "app").glob("*.py")
                   if p.name not in ("__init__.py", "sweep_run.py", "display.py"))
    assert loose == [], f"modules loose in app/ (put them in a room: {sorted(rooms)})"
    assert {p.name for p in (ROOT / "app").iterdir() if p.is_dir()} - {"__pycache__"} == rooms


def test_the_checker_sees_an_upward_import(tmp_path):
    # the test itself: an engine module importing the app must be caught
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from ..app import cli\n")
    found = _imports("sewmech.engine.bad", bad)
    assert ("sewmech.app.cli", 2) in found and _layer("sewmech.app.cli") > _layer(
        "sewmech.engine.bad")


def test_starting_a_command_imports_no_plotting_tables_or_optimisers():
    """Every command imports sewmech's numeric layers and its command line; the heavy libraries
    (matplotlib, pandas, scipy.optimize: about 0.8 s together) come only with the functions
    that use them."""
    import subprocess
    import sys

    code = ("import importlib, pkgutil, sys, sewmech\n"
            "for layer in ('engine', 'sewing', 'design'):\n"
            "    pkg = importlib.import_module('sewmech.' + layer)\n"
            "    for m in pkgutil.iter_modules(pkg.__path__):\n"
            "        if m.name != '_blockgen':  # (a script that writes _blocks.py)\n"
            "            importlib.import_module(f'sewmech.{layer}.{m.name}')\n"
            "import sewmech.app.cli\n"
            "print(sorted(m for m in ('matplotlib', 'pandas', 'scipy.optimize')"
            " if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"


def test_a_short_name_leaves_the_module_its_own_spec():
    """Importing a module by its short name does not give it the alias's spec: its __spec__
    keeps its real name, and a package's files stay reachable through importlib.resources."""
    import importlib.resources

    import sewmech

    for short, where in sewmech.MODULES.items():
        module = importlib.import_module(f"sewmech.{short}")
        assert module.__spec__.name == f"sewmech.{where}", short
    assert importlib.resources.files("sewmech.app.web").joinpath("static").is_dir()
