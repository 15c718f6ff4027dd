"""Fault injection: real `report`, `optimize --out` and `sweep` processes killed outright
(SIGKILL: nothing of Python runs any more) at a dozen points of their work each.

After every kill: no process of the command's group is left (the figure workers and Dask's
worker processes end with it), and the output directory is as the killed run found it (apart
from sewmech's own lock and staging, which the next run recovers; a sweep keeps the chunks it
finished). The same command run again then succeeds and leaves a complete result: for the
staged commands the same files as an uninterrupted run, for the sweep the same values, design
by design, as a sweep that was never interrupted.

Kill points are drawn from a seeded generator over each command's measured duration, so every
run of the suite kills at points spread over the whole of the work (imports, computing,
drawing, writing, moving into place).
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
KILLS = 12
#: every this many kills, the command is also run to the end and its result checked
COMPLETE_EVERY = 4
OWN = (".sewmech.lock", ".sewmech-staging-")

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not hasattr(os, "killpg"), reason="needs process groups")]


def _cli() -> list[str]:
    exe = Path(sys.executable).with_name("sewmech")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "sewmech"]


def _state(root: Path) -> dict:
    """The directory as a user sees it: every file (sewmech's lock and staging left out) with
    its content hash."""
    out = {}
    if not root.exists():
        return out
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root)
        if rel.parts[0].startswith(OWN):
            continue
        out[str(rel)] = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
    return out


def _gone(pgid: int, timeout: float = 10.0) -> bool:
    deadline = time.time() + timeout
    while time.time() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def _run(args: list[str], cwd: Path) -> tuple[float, subprocess.CompletedProcess]:
    t = time.perf_counter()
    out = subprocess.run(_cli() + args, cwd=cwd, capture_output=True, text=True, timeout=600)
    return time.perf_counter() - t, out


def _kill_at(args: list[str], cwd: Path, after_s: float) -> int | None:
    """Start the command in a group of its own, SIGKILL it after ``after_s``; returns its exit
    code if it finished first, else None. Asserts that no process of the group is left."""
    p = subprocess.Popen(_cli() + args, cwd=cwd, stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        rc = p.wait(timeout=after_s)
    except subprocess.TimeoutExpired:
        os.kill(p.pid, signal.SIGKILL)
        p.wait(timeout=30)
        rc = None
    alive = not _gone(p.pid)
    if alive:
        os.killpg(p.pid, signal.SIGKILL)
    assert not alive, f"a process of {args[0]} outlived it (killed after {after_s:.2f} s)"
    return rc


def _kill_points(duration: float, seed: int, kills: int = KILLS) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.sort(rng.uniform(0.05, 1.05, kills)) * duration


def _check_complete(d: Path, reference: dict) -> None:
    manifest = json.loads((d / ".sewmech-manifest.json").read_text())["files"]
    assert sorted(manifest) == sorted(reference), "the result is not complete"
    for name, rec in manifest.items():
        assert (d / name).stat().st_size == rec["size"], name
    assert not [n for n in os.listdir(d) if n.startswith(".sewmech-staging-")]


@pytest.mark.parametrize("name, args, seed, kills", [
    # the report (8 s a run) at half the kill points: the moment that matters most, the
    # moves into place, is killed deterministically below (test_a_run_killed_while_...)
    ("report", ["report", "jb1-3", "--step-deg", "5"], 29, KILLS // 2),
    ("optimize", ["optimize", str(ROOT / "examples/problems/fourbar-swing.toml"),
                  "--method", "slsqp"], 30, KILLS),
], ids=["report", "optimize"])
def test_a_staged_command_killed_anywhere_leaves_its_directory_and_recovers(tmp_path, name,
                                                                           args, seed, kills):
    d = tmp_path / "out"
    cmd = args + ["--out", str(d)]
    duration, first = _run(cmd, tmp_path)
    assert first.returncode == 0, first.stderr
    reference = {n: None for n in json.loads(
        (d / ".sewmech-manifest.json").read_text())["files"]}
    for i, t in enumerate(_kill_points(duration, seed, kills)):
        before = _state(d)
        rc = _kill_at(cmd, tmp_path, t)
        assert rc in (None, 0), (t, rc)
        if rc is None and _state(d) != before:
            # killed after its result was moved into place (its figures' files differ from
            # run to run): then the whole new result is there, never a part of it
            assert t > 0.5 * duration, f"{name} killed after {t:.2f} s changed the result"
            _check_complete(d, reference)
        if (i + 1) % COMPLETE_EVERY == 0 and i + 1 < kills:  # (the last run follows)
            _, again = _run(cmd, tmp_path)
            assert again.returncode == 0, (t, again.stderr)
            assert "Traceback" not in again.stderr
            _check_complete(d, reference)
    _, last = _run(cmd, tmp_path)
    assert last.returncode == 0, last.stderr
    _check_complete(d, reference)


def _sweep_values(d: Path):
    import pandas as pd

    parts = [pd.read_parquet(p) for p in sorted((d / "chunks").glob("*.parquet"))]
    return pd.concat(parts, ignore_index=True) if parts else None


def test_a_sweep_killed_anywhere_resumes_to_the_same_values(tmp_path):
    sweep = str(ROOT / "examples/sweeps/jb-feed-small.toml")
    common = ["sweep", sweep, "--workers", "0", "--chunk", "2"]
    duration, ref = _run(common + ["--out", str(tmp_path / "ref")], tmp_path)
    assert ref.returncode == 0, ref.stderr
    d = tmp_path / "out"
    cmd = common + ["--out", str(d)]
    for t in _kill_points(duration, 31):
        done = {p.name: p.read_bytes() for p in (d / "chunks").glob("*.parquet")} \
            if (d / "chunks").exists() else {}
        rc = _kill_at(cmd, tmp_path, t)
        assert rc in (None, 0), (t, rc)
        if d.exists():  # no reader sees a half-written chunk; a finished chunk stays as it was
            for name, data in done.items():
                assert (d / "chunks" / name).read_bytes() == data, name
            _sweep_values(d)
        if rc == 0:
            break
    _, last = _run(cmd, tmp_path)
    assert last.returncode == 0, last.stderr
    got, want = _sweep_values(d), _sweep_values(tmp_path / "ref")
    assert list(got.columns) == list(want.columns) and len(got) == len(want)
    import pandas as pd

    pd.testing.assert_frame_equal(got, want)  # the same compiled code on the same designs


#: writes three files through output_dir, the moves into place wrapped so that the process
#: kills itself (SIGKILL) just before or just after its K-th move; K = 0 runs to the end, and
#: tag "fail" raises before anything is staged (a run that ends in an error)
_MOVER = """
import os, signal, sys
from sewmech.app.files import outdir
root, tag, k, when = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
real, calls = outdir.move_no_replace, [0]
def move(src, dst):
    calls[0] += 1
    if calls[0] == k and when == "before":
        os.kill(os.getpid(), signal.SIGKILL)
    real(src, dst)
    if calls[0] == k and when == "after":
        os.kill(os.getpid(), signal.SIGKILL)
outdir.move_no_replace = move
names = ("a.csv", "b.csv", "c.csv") + (("d.csv",) if tag == "old" else ())
with outdir.output_dir(root, command="t") as d:
    if tag == "fail":
        raise SystemExit(3)
    for n in names:
        (d / n).write_text(n + " " + tag + "\\n", encoding="utf-8")
"""


def _mover(root: Path, tag: str, k: int = 0, when: str = "before") -> int:
    return subprocess.run([sys.executable, "-c", _MOVER, str(root), tag, str(k), when],
                          capture_output=True, text=True, timeout=120).returncode


@pytest.mark.parametrize("k, when", [(1, "before"), (2, "before"), (1, "after"), (2, "after"),
                                     (3, "after")])
def test_a_run_killed_while_it_moves_its_files_in_is_rolled_back(tmp_path, k, when):
    """A run killed between its moves into place (old file set aside, new one not yet in; some
    new files in, others not; every new file in, the stale d.csv not yet dropped and the
    manifest not yet written): the next run puts the directory back as the killed run found
    it (the previous files, each exactly sewmech's own again) before it does anything, and a
    run after it completes. The killed run's previous files were lost: the next run removed
    the staging directory that held them."""
    from sewmech.app.files import outdir

    root = tmp_path / "out"
    assert _mover(root, "old") == 0
    before = _state(root)
    assert sorted(before) == [".sewmech-manifest.json", "a.csv", "b.csv", "c.csv", "d.csv"]
    assert _mover(root, "new", k, when) == -signal.SIGKILL
    assert _state(root) != before or when == "before"  # (killed in the middle of it)
    # a command's check before its work takes the killed run's new files for sewmech's own
    # (they are rolled back under the lock), not for the user's
    outdir.preflight(root, command="t")
    assert _mover(root, "fail") == 3  # a run that ends in an error: it recovers, commits nothing
    assert _state(root) == before
    assert not [e for e in os.listdir(root) if e.startswith(".sewmech-staging-")]
    outdir.preflight(root, command="t")  # every file sewmech's own, unchanged: not refused
    assert _mover(root, "new") == 0
    after = _state(root)
    assert sorted(after) == [".sewmech-manifest.json", "a.csv", "b.csv", "c.csv"]
    assert (root / "a.csv").read_text(encoding="utf-8") == "a.csv new\n"
