"""A kernel compiled on its first use says so on stderr, once, before it compiles (issue 34, 3);
the install's warm-up lists its own steps and compiles only the everyday kernels."""

from __future__ import annotations

import numba

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
