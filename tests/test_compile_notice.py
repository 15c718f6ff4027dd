"""A kernel compiled on its first use says so on stderr, once, before it compiles (issue 34, 3);
the install's warm-up lists its own steps and compiles only the everyday kernels."""

from __future__ import annotations

import platform
import subprocess
import sys

import numba
import pytest

from sewmech.engine import _compiling, warm


def _kernel():
    @numba.njit(cache=False)
    def fresh_kernel(x):  # a new function: numba compiles it on its first call
        return x + 1.0

    return fresh_kernel


def test_a_first_compile_is_announced_once(monkeypatch, capsys):
    _compiling.install()
    k = _kernel()
    key = (k.py_func.__module__, "fresh_kernel")
    monkeypatch.setattr(_compiling, "FAMILIES", {key: ("the test's kernel", 7)})
    monkeypatch.setattr(_compiling, "_said", set())
    assert k(1.0) == 2.0
    k(2)  # a second specialisation of the same kernel: no second line
    _kernel()(1.0)  # nor the same function compiled again in this process
    err = capsys.readouterr().err
    assert err.count("sewmech: compiling the test's kernel once (about 7 s of CPU") == 1
    assert err.strip().endswith("...")


def test_the_warm_up_and_a_loaded_kernel_say_nothing(monkeypatch, capsys):
    _compiling.install()
    k = _kernel()
    monkeypatch.setattr(_compiling, "FAMILIES",
                        {(k.py_func.__module__, None): ("the test's kernel", 7)})
    monkeypatch.setattr(_compiling, "_said", set())
    monkeypatch.setattr(_compiling, "quiet", True)
    k(1.0)
    assert capsys.readouterr().err == ""


def test_the_install_compiles_the_everyday_kernels_and_leaves_the_rest():
    install = [step for _, step, at_install in warm.STEPS if at_install]
    later = [step for _, step, at_install in warm.STEPS if not at_install]
    assert install[:2] == ["kinematics", "dynamics"]
    assert set(later) == {"sensitivities", "force_tangents", "run"}
    assert warm.main(["--bogus"]) == 2


def _kernel_seeing_gc(module: str, seen: list):
    """A fresh kernel, defined as if in ``module``, that records at its compile (typing) time
    whether the garbage collector runs."""
    import gc

    from numba.extending import overload

    def probe():
        pass

    @overload(probe)
    def _probe():
        seen.append(gc.isenabled())
        return lambda: None

    def kernel(x):
        probe()
        return x + 1.0

    kernel.__module__ = module
    return numba.njit(cache=False)(kernel)


def test_the_collector_pauses_while_a_sewmech_kernel_compiles_and_only_then():
    import gc

    _compiling.install()
    assert gc.isenabled()
    seen: list[bool] = []
    assert _kernel_seeing_gc("sewmech.engine._a_test_kernel", seen)(1.0) == 2.0
    assert seen == [False]  # paused while the compile ran
    assert gc.isenabled()  # and back on after it
    seen.clear()
    assert _kernel_seeing_gc("someone_elses_module", seen)(1.0) == 2.0
    assert seen == [True]  # another package's kernel compiles as numba would compile it
    gc.disable()  # a collector the caller had turned off stays off
    try:
        seen.clear()
        _kernel_seeing_gc("sewmech.engine._a_test_kernel", seen)(1.0)
        assert seen == [False] and not gc.isenabled()
    finally:
        gc.enable()


def test_roomy_calls_from_a_frame_with_room_for_a_compile():
    import sys

    def inner(a, b=0):
        caller = sys._getframe(1).f_code  # the frame roomy called from
        return a + b, caller.co_stacksize

    total, stack = _compiling.roomy(inner, 2, b=3)
    assert total == 5
    assert stack >= _compiling._ROOM_SLOTS  # 8 bytes a slot: half a megabyte

    def fails():
        raise KeyError("x")

    try:
        _compiling.roomy(fails)
    except KeyError:
        pass
    else:
        raise AssertionError("roomy swallowed the exception")


_REUSE = """
import ctypes, resource, sys
from sewmech.engine import warm
if sys.argv[1] == "keep":
    assert warm.keep_freed_memory()
libc = ctypes.CDLL(None)
libc.malloc.restype = ctypes.c_void_p
libc.malloc.argtypes = (ctypes.c_size_t,)
libc.free.argtypes = (ctypes.c_void_p,)
n = 8 << 20
for k in range(2):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    p = libc.malloc(n)
    ctypes.memset(p, 1, n)
    libc.free(p)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                    reason="glibc's malloc settings")
def test_the_install_keeps_freed_memory_for_its_next_allocations():
    """8 MB freed and allocated again: by default glibc returns it to the system and faults
    its 2,048 pages in again; after keep_freed_memory it reuses them."""

    def faults(mode: str) -> int:
        out = subprocess.run([sys.executable, "-c", _REUSE, mode], capture_output=True,
                             text=True, check=True)
        return int(out.stdout.split()[-1])

    assert faults("default") > 1000
    assert faults("keep") < 200
