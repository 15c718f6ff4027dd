"""Writes :mod:`sewmech._blocks`: the force kernel's block solvers, one per block size.

The force kernel (:func:`sewmech._kernels.force_solve`) solves the Newton-Euler equations of
every position block by block. A generic loop over a block's rows and columns runs many short
loops over positions, whose start-up costs more than their arithmetic. For the block sizes that
machines have (the JB machines' largest is 6), this module writes the Householder QR of an n x n
block as straight-line code on scalars inside one loop over positions, which the compiler turns
into four positions per AVX2 instruction.

Two details make that loop vectorise. The scratch arrays are flat with a fixed pitch (the
positions of one entry are contiguous, entry e starts at e * CHUNK), so the compiler sees that
entries never overlap and needs no run-time overlap checks; and the indices are unsigned, so
numba emits no negative-index wrap-around, which would hide the access pattern.

Run ``python -m sewmech.engine._blockgen`` after changing this file; a test checks that the written
module is up to date.
"""

from __future__ import annotations

from pathlib import Path

#: block sizes with a written solver; larger blocks use the generic loop of the force kernel
MAX_BLOCK = 6
#: positions per chunk of the force kernel, the pitch of its scratch arrays
CHUNK = 64

_HEAD = f'''"""Block solvers of the force kernel, written by :mod:`sewmech.engine._blockgen` (do not edit).

``block_qr_N(W, off, F, foff, B, X, start, nk, worst)`` solves, at positions 0 <= kk < nk, one
N x N block of the force equations by Householder QR (stable without pivoting, so that every
position runs the same instructions). The arrays are flat with pitch CHUNK (entry e of position
kk at e * CHUNK + kk): the block's entries are W's entries off, off + 1, ... (row-major), its
right-hand sides B's entries start, start + 1, ... (overwritten), and its unknowns go to X's
entries start, start + 1, .... ``worst[kk]`` is lowered to the smallest |R_jj| relative to the
block's largest entry (0: singular). The factors go to F's entries foff, ... (N * (N + 2) of
them: R on and above the diagonal and the reflectors' vectors below it, row-major, then each
reflector's first entry v0 and its tau), with which the force kernel solves the block again for
other right-hand sides (the steps of the friction iteration) without factoring it again.
"""

import math

import numpy as np
from numba import njit

CHUNK = {CHUNK}
_U = np.uint64'''


def _at(array: str, base: str, entry: int) -> str:
    """The element of a flat scratch array at entry ``entry`` of the position whose entry 0 is
    at ``base`` (a loop variable), the entry's offset a module constant (``_E<entry>``): a
    constant is typed once per function, while ``_U(offset)`` at every access cost numba's
    compiler a call and an addition to type each time (0.5 s of the install's compile)."""
    return f"{array}[{base}]" if entry == 0 else f"{array}[{base} + _E{entry}]"


def _solver(n: int) -> str:
    """Source of the solver for an n x n block."""
    lines = ["", "",
             '@njit(cache=True, error_model="numpy", fastmath={"contract"}, no_cpython_wrapper=True)',
             f"def block_qr_{n}(W, off, F, foff, B, X, start, nk, worst):",
             "    wo = _U(off * CHUNK)",
             "    fo = _U(foff * CHUNK)",
             "    bo = _U(start * CHUNK)",
             "    for kk in range(_U(nk)):",
             "        w = wo + kk",
             "        f = fo + kk",
             "        x = bo + kk"]
    body: list[str] = []
    b = body.append
    for i in range(n):
        for j in range(n):
            b(f"a{i}_{j} = {_at('W', 'w', i * n + j)}")
    for i in range(n):
        b(f"b{i} = {_at('B', 'x', i)}")
    # the block's largest entry, the scale of the pivot check
    b("sc = abs(a0_0)")
    for i in range(n):
        for j in range(n):
            if i or j:
                b(f"sc = max(sc, abs(a{i}_{j}))")
    for j in range(n):
        b(f"# column {j}: the reflector I - tau v v^T, v = (a{j}_{j} - alpha, a{j + 1}_{j}, ...)"
          if j < n - 1 else f"# column {j}")
        b("n2 = " + " + ".join(f"a{i}_{j} * a{i}_{j}" for i in range(j, n)))
        b(f"al = -math.copysign(math.sqrt(n2), a{j}_{j})")
        b(f"v0 = a{j}_{j} - al")
        b(f"vn2 = n2 - a{j}_{j} * a{j}_{j} + v0 * v0")
        b("tau = 2.0 / vn2 if vn2 > 0.0 else 0.0")
        b("amin = abs(al)" if j == 0 else "amin = min(amin, abs(al))")
        vec = ["v0"] + [f"a{i}_{j}" for i in range(j + 1, n)]
        for c in [*range(j + 1, n), None]:  # the later columns, then the right-hand side
            col = [f"a{i}_{c}" if c is not None else f"b{i}" for i in range(j, n)]
            b("s = tau * (" + " + ".join(f"{v} * {x}" for v, x in zip(vec, col)) + ")")
            for v, x in zip(vec, col):
                b(f"{x} -= s * {v}")
        b(f"{_at('F', 'f', n * n + j)} = v0")
        b(f"{_at('F', 'f', n * n + n + j)} = tau")
        b(f"a{j}_{j} = al")
    b("# the factors, kept for other right-hand sides")
    for i in range(n):
        for j in range(n):
            b(f"{_at('F', 'f', i * n + j)} = a{i}_{j}")
    b("# back substitution with R")
    for j in range(n - 1, -1, -1):
        terms = "".join(f" - a{j}_{c} * x{c}" for c in range(j + 1, n))
        b(f"x{j} = {f'(b{j}{terms})' if terms else f'b{j}'} / a{j}_{j}")
        b(f"{_at('X', 'x', j)} = x{j}")
    b("worst[kk] = min(worst[kk], amin / sc if sc > 0.0 else 0.0)  # a zero block: singular")
    lines.extend("        " + line for line in body)
    return "\n".join(lines)


def source(max_block: int = MAX_BLOCK) -> str:
    """The whole module :mod:`sewmech._blocks`."""
    parts = [_HEAD, "# the entries' offsets in the flat scratch (see _at in the writer)"]
    parts.extend(f"_E{e} = _U({e} * CHUNK)" for e in range(1, max_block * (max_block + 2)))
    parts.extend(_solver(n) for n in range(1, max_block + 1))
    lines = ["", "", f"MAX_BLOCK = {max_block}", "", "",
             '@njit(cache=True, error_model="numpy", fastmath={"contract"})',
             "def block_qr(n, W, off, F, foff, B, X, start, nk, worst):",
             '    """Solve an n x n block with its written solver and keep its factors (see the',
             "    module doc).",
             "",
             '    False when n > MAX_BLOCK: the caller solves the block itself."""']
    for n in range(1, max_block + 1):
        lines.append(f"    {'if' if n == 1 else 'elif'} n == {n}:")
        lines.append(f"        block_qr_{n}(W, off, F, foff, B, X, start, nk, worst)")
    lines += ["    else:", "        return False", "    return True", ""]
    parts.append("\n".join(lines))
    return "\n".join(parts)


def main() -> None:
    path = Path(__file__).with_name("_blocks.py")
    path.write_text(source())
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
