"""Block solvers of the force kernel, written by :mod:`sewmech.engine._blockgen` (do not edit).

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

CHUNK = 64
_U = np.uint64


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def block_qr_1(W, off, F, foff, B, X, start, nk, worst):
    wo = _U(off * CHUNK)
    fo = _U(foff * CHUNK)
    bo = _U(start * CHUNK)
    for kk in range(_U(nk)):
        a0_0 = W[wo + _U(0) + kk]
        b0 = B[bo + _U(0) + kk]
        sc = abs(a0_0)
        # column 0
        n2 = a0_0 * a0_0
        al = -math.copysign(math.sqrt(n2), a0_0)
        v0 = a0_0 - al
        vn2 = n2 - a0_0 * a0_0 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = abs(al)
        s = tau * (v0 * b0)
        b0 -= s * v0
        F[fo + _U(64) + kk] = v0
        F[fo + _U(128) + kk] = tau
        a0_0 = al
        # the factors, kept for other right-hand sides
        F[fo + _U(0) + kk] = a0_0
        # back substitution with R
        x0 = b0 / a0_0
        X[bo + _U(0) + kk] = x0
        worst[kk] = min(worst[kk], amin / sc if sc > 0.0 else 0.0)  # a zero block: singular


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def block_qr_2(W, off, F, foff, B, X, start, nk, worst):
    wo = _U(off * CHUNK)
    fo = _U(foff * CHUNK)
    bo = _U(start * CHUNK)
    for kk in range(_U(nk)):
        a0_0 = W[wo + _U(0) + kk]
        a0_1 = W[wo + _U(64) + kk]
        a1_0 = W[wo + _U(128) + kk]
        a1_1 = W[wo + _U(192) + kk]
        b0 = B[bo + _U(0) + kk]
        b1 = B[bo + _U(64) + kk]
        sc = abs(a0_0)
        sc = max(sc, abs(a0_1))
        sc = max(sc, abs(a1_0))
        sc = max(sc, abs(a1_1))
        # column 0: the reflector I - tau v v^T, v = (a0_0 - alpha, a1_0, ...)
        n2 = a0_0 * a0_0 + a1_0 * a1_0
        al = -math.copysign(math.sqrt(n2), a0_0)
        v0 = a0_0 - al
        vn2 = n2 - a0_0 * a0_0 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = abs(al)
        s = tau * (v0 * a0_1 + a1_0 * a1_1)
        a0_1 -= s * v0
        a1_1 -= s * a1_0
        s = tau * (v0 * b0 + a1_0 * b1)
        b0 -= s * v0
        b1 -= s * a1_0
        F[fo + _U(256) + kk] = v0
        F[fo + _U(384) + kk] = tau
        a0_0 = al
        # column 1
        n2 = a1_1 * a1_1
        al = -math.copysign(math.sqrt(n2), a1_1)
        v0 = a1_1 - al
        vn2 = n2 - a1_1 * a1_1 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * b1)
        b1 -= s * v0
        F[fo + _U(320) + kk] = v0
        F[fo + _U(448) + kk] = tau
        a1_1 = al
        # the factors, kept for other right-hand sides
        F[fo + _U(0) + kk] = a0_0
        F[fo + _U(64) + kk] = a0_1
        F[fo + _U(128) + kk] = a1_0
        F[fo + _U(192) + kk] = a1_1
        # back substitution with R
        x1 = b1 / a1_1
        X[bo + _U(64) + kk] = x1
        x0 = (b0 - a0_1 * x1) / a0_0
        X[bo + _U(0) + kk] = x0
        worst[kk] = min(worst[kk], amin / sc if sc > 0.0 else 0.0)  # a zero block: singular


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def block_qr_3(W, off, F, foff, B, X, start, nk, worst):
    wo = _U(off * CHUNK)
    fo = _U(foff * CHUNK)
    bo = _U(start * CHUNK)
    for kk in range(_U(nk)):
        a0_0 = W[wo + _U(0) + kk]
        a0_1 = W[wo + _U(64) + kk]
        a0_2 = W[wo + _U(128) + kk]
        a1_0 = W[wo + _U(192) + kk]
        a1_1 = W[wo + _U(256) + kk]
        a1_2 = W[wo + _U(320) + kk]
        a2_0 = W[wo + _U(384) + kk]
        a2_1 = W[wo + _U(448) + kk]
        a2_2 = W[wo + _U(512) + kk]
        b0 = B[bo + _U(0) + kk]
        b1 = B[bo + _U(64) + kk]
        b2 = B[bo + _U(128) + kk]
        sc = abs(a0_0)
        sc = max(sc, abs(a0_1))
        sc = max(sc, abs(a0_2))
        sc = max(sc, abs(a1_0))
        sc = max(sc, abs(a1_1))
        sc = max(sc, abs(a1_2))
        sc = max(sc, abs(a2_0))
        sc = max(sc, abs(a2_1))
        sc = max(sc, abs(a2_2))
        # column 0: the reflector I - tau v v^T, v = (a0_0 - alpha, a1_0, ...)
        n2 = a0_0 * a0_0 + a1_0 * a1_0 + a2_0 * a2_0
        al = -math.copysign(math.sqrt(n2), a0_0)
        v0 = a0_0 - al
        vn2 = n2 - a0_0 * a0_0 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = abs(al)
        s = tau * (v0 * a0_1 + a1_0 * a1_1 + a2_0 * a2_1)
        a0_1 -= s * v0
        a1_1 -= s * a1_0
        a2_1 -= s * a2_0
        s = tau * (v0 * a0_2 + a1_0 * a1_2 + a2_0 * a2_2)
        a0_2 -= s * v0
        a1_2 -= s * a1_0
        a2_2 -= s * a2_0
        s = tau * (v0 * b0 + a1_0 * b1 + a2_0 * b2)
        b0 -= s * v0
        b1 -= s * a1_0
        b2 -= s * a2_0
        F[fo + _U(576) + kk] = v0
        F[fo + _U(768) + kk] = tau
        a0_0 = al
        # column 1: the reflector I - tau v v^T, v = (a1_1 - alpha, a2_1, ...)
        n2 = a1_1 * a1_1 + a2_1 * a2_1
        al = -math.copysign(math.sqrt(n2), a1_1)
        v0 = a1_1 - al
        vn2 = n2 - a1_1 * a1_1 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * a1_2 + a2_1 * a2_2)
        a1_2 -= s * v0
        a2_2 -= s * a2_1
        s = tau * (v0 * b1 + a2_1 * b2)
        b1 -= s * v0
        b2 -= s * a2_1
        F[fo + _U(640) + kk] = v0
        F[fo + _U(832) + kk] = tau
        a1_1 = al
        # column 2
        n2 = a2_2 * a2_2
        al = -math.copysign(math.sqrt(n2), a2_2)
        v0 = a2_2 - al
        vn2 = n2 - a2_2 * a2_2 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * b2)
        b2 -= s * v0
        F[fo + _U(704) + kk] = v0
        F[fo + _U(896) + kk] = tau
        a2_2 = al
        # the factors, kept for other right-hand sides
        F[fo + _U(0) + kk] = a0_0
        F[fo + _U(64) + kk] = a0_1
        F[fo + _U(128) + kk] = a0_2
        F[fo + _U(192) + kk] = a1_0
        F[fo + _U(256) + kk] = a1_1
        F[fo + _U(320) + kk] = a1_2
        F[fo + _U(384) + kk] = a2_0
        F[fo + _U(448) + kk] = a2_1
        F[fo + _U(512) + kk] = a2_2
        # back substitution with R
        x2 = b2 / a2_2
        X[bo + _U(128) + kk] = x2
        x1 = (b1 - a1_2 * x2) / a1_1
        X[bo + _U(64) + kk] = x1
        x0 = (b0 - a0_1 * x1 - a0_2 * x2) / a0_0
        X[bo + _U(0) + kk] = x0
        worst[kk] = min(worst[kk], amin / sc if sc > 0.0 else 0.0)  # a zero block: singular


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def block_qr_4(W, off, F, foff, B, X, start, nk, worst):
    wo = _U(off * CHUNK)
    fo = _U(foff * CHUNK)
    bo = _U(start * CHUNK)
    for kk in range(_U(nk)):
        a0_0 = W[wo + _U(0) + kk]
        a0_1 = W[wo + _U(64) + kk]
        a0_2 = W[wo + _U(128) + kk]
        a0_3 = W[wo + _U(192) + kk]
        a1_0 = W[wo + _U(256) + kk]
        a1_1 = W[wo + _U(320) + kk]
        a1_2 = W[wo + _U(384) + kk]
        a1_3 = W[wo + _U(448) + kk]
        a2_0 = W[wo + _U(512) + kk]
        a2_1 = W[wo + _U(576) + kk]
        a2_2 = W[wo + _U(640) + kk]
        a2_3 = W[wo + _U(704) + kk]
        a3_0 = W[wo + _U(768) + kk]
        a3_1 = W[wo + _U(832) + kk]
        a3_2 = W[wo + _U(896) + kk]
        a3_3 = W[wo + _U(960) + kk]
        b0 = B[bo + _U(0) + kk]
        b1 = B[bo + _U(64) + kk]
        b2 = B[bo + _U(128) + kk]
        b3 = B[bo + _U(192) + kk]
        sc = abs(a0_0)
        sc = max(sc, abs(a0_1))
        sc = max(sc, abs(a0_2))
        sc = max(sc, abs(a0_3))
        sc = max(sc, abs(a1_0))
        sc = max(sc, abs(a1_1))
        sc = max(sc, abs(a1_2))
        sc = max(sc, abs(a1_3))
        sc = max(sc, abs(a2_0))
        sc = max(sc, abs(a2_1))
        sc = max(sc, abs(a2_2))
        sc = max(sc, abs(a2_3))
        sc = max(sc, abs(a3_0))
        sc = max(sc, abs(a3_1))
        sc = max(sc, abs(a3_2))
        sc = max(sc, abs(a3_3))
        # column 0: the reflector I - tau v v^T, v = (a0_0 - alpha, a1_0, ...)
        n2 = a0_0 * a0_0 + a1_0 * a1_0 + a2_0 * a2_0 + a3_0 * a3_0
        al = -math.copysign(math.sqrt(n2), a0_0)
        v0 = a0_0 - al
        vn2 = n2 - a0_0 * a0_0 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = abs(al)
        s = tau * (v0 * a0_1 + a1_0 * a1_1 + a2_0 * a2_1 + a3_0 * a3_1)
        a0_1 -= s * v0
        a1_1 -= s * a1_0
        a2_1 -= s * a2_0
        a3_1 -= s * a3_0
        s = tau * (v0 * a0_2 + a1_0 * a1_2 + a2_0 * a2_2 + a3_0 * a3_2)
        a0_2 -= s * v0
        a1_2 -= s * a1_0
        a2_2 -= s * a2_0
        a3_2 -= s * a3_0
        s = tau * (v0 * a0_3 + a1_0 * a1_3 + a2_0 * a2_3 + a3_0 * a3_3)
        a0_3 -= s * v0
        a1_3 -= s * a1_0
        a2_3 -= s * a2_0
        a3_3 -= s * a3_0
        s = tau * (v0 * b0 + a1_0 * b1 + a2_0 * b2 + a3_0 * b3)
        b0 -= s * v0
        b1 -= s * a1_0
        b2 -= s * a2_0
        b3 -= s * a3_0
        F[fo + _U(1024) + kk] = v0
        F[fo + _U(1280) + kk] = tau
        a0_0 = al
        # column 1: the reflector I - tau v v^T, v = (a1_1 - alpha, a2_1, ...)
        n2 = a1_1 * a1_1 + a2_1 * a2_1 + a3_1 * a3_1
        al = -math.copysign(math.sqrt(n2), a1_1)
        v0 = a1_1 - al
        vn2 = n2 - a1_1 * a1_1 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * a1_2 + a2_1 * a2_2 + a3_1 * a3_2)
        a1_2 -= s * v0
        a2_2 -= s * a2_1
        a3_2 -= s * a3_1
        s = tau * (v0 * a1_3 + a2_1 * a2_3 + a3_1 * a3_3)
        a1_3 -= s * v0
        a2_3 -= s * a2_1
        a3_3 -= s * a3_1
        s = tau * (v0 * b1 + a2_1 * b2 + a3_1 * b3)
        b1 -= s * v0
        b2 -= s * a2_1
        b3 -= s * a3_1
        F[fo + _U(1088) + kk] = v0
        F[fo + _U(1344) + kk] = tau
        a1_1 = al
        # column 2: the reflector I - tau v v^T, v = (a2_2 - alpha, a3_2, ...)
        n2 = a2_2 * a2_2 + a3_2 * a3_2
        al = -math.copysign(math.sqrt(n2), a2_2)
        v0 = a2_2 - al
        vn2 = n2 - a2_2 * a2_2 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * a2_3 + a3_2 * a3_3)
        a2_3 -= s * v0
        a3_3 -= s * a3_2
        s = tau * (v0 * b2 + a3_2 * b3)
        b2 -= s * v0
        b3 -= s * a3_2
        F[fo + _U(1152) + kk] = v0
        F[fo + _U(1408) + kk] = tau
        a2_2 = al
        # column 3
        n2 = a3_3 * a3_3
        al = -math.copysign(math.sqrt(n2), a3_3)
        v0 = a3_3 - al
        vn2 = n2 - a3_3 * a3_3 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * b3)
        b3 -= s * v0
        F[fo + _U(1216) + kk] = v0
        F[fo + _U(1472) + kk] = tau
        a3_3 = al
        # the factors, kept for other right-hand sides
        F[fo + _U(0) + kk] = a0_0
        F[fo + _U(64) + kk] = a0_1
        F[fo + _U(128) + kk] = a0_2
        F[fo + _U(192) + kk] = a0_3
        F[fo + _U(256) + kk] = a1_0
        F[fo + _U(320) + kk] = a1_1
        F[fo + _U(384) + kk] = a1_2
        F[fo + _U(448) + kk] = a1_3
        F[fo + _U(512) + kk] = a2_0
        F[fo + _U(576) + kk] = a2_1
        F[fo + _U(640) + kk] = a2_2
        F[fo + _U(704) + kk] = a2_3
        F[fo + _U(768) + kk] = a3_0
        F[fo + _U(832) + kk] = a3_1
        F[fo + _U(896) + kk] = a3_2
        F[fo + _U(960) + kk] = a3_3
        # back substitution with R
        x3 = b3 / a3_3
        X[bo + _U(192) + kk] = x3
        x2 = (b2 - a2_3 * x3) / a2_2
        X[bo + _U(128) + kk] = x2
        x1 = (b1 - a1_2 * x2 - a1_3 * x3) / a1_1
        X[bo + _U(64) + kk] = x1
        x0 = (b0 - a0_1 * x1 - a0_2 * x2 - a0_3 * x3) / a0_0
        X[bo + _U(0) + kk] = x0
        worst[kk] = min(worst[kk], amin / sc if sc > 0.0 else 0.0)  # a zero block: singular


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def block_qr_5(W, off, F, foff, B, X, start, nk, worst):
    wo = _U(off * CHUNK)
    fo = _U(foff * CHUNK)
    bo = _U(start * CHUNK)
    for kk in range(_U(nk)):
        a0_0 = W[wo + _U(0) + kk]
        a0_1 = W[wo + _U(64) + kk]
        a0_2 = W[wo + _U(128) + kk]
        a0_3 = W[wo + _U(192) + kk]
        a0_4 = W[wo + _U(256) + kk]
        a1_0 = W[wo + _U(320) + kk]
        a1_1 = W[wo + _U(384) + kk]
        a1_2 = W[wo + _U(448) + kk]
        a1_3 = W[wo + _U(512) + kk]
        a1_4 = W[wo + _U(576) + kk]
        a2_0 = W[wo + _U(640) + kk]
        a2_1 = W[wo + _U(704) + kk]
        a2_2 = W[wo + _U(768) + kk]
        a2_3 = W[wo + _U(832) + kk]
        a2_4 = W[wo + _U(896) + kk]
        a3_0 = W[wo + _U(960) + kk]
        a3_1 = W[wo + _U(1024) + kk]
        a3_2 = W[wo + _U(1088) + kk]
        a3_3 = W[wo + _U(1152) + kk]
        a3_4 = W[wo + _U(1216) + kk]
        a4_0 = W[wo + _U(1280) + kk]
        a4_1 = W[wo + _U(1344) + kk]
        a4_2 = W[wo + _U(1408) + kk]
        a4_3 = W[wo + _U(1472) + kk]
        a4_4 = W[wo + _U(1536) + kk]
        b0 = B[bo + _U(0) + kk]
        b1 = B[bo + _U(64) + kk]
        b2 = B[bo + _U(128) + kk]
        b3 = B[bo + _U(192) + kk]
        b4 = B[bo + _U(256) + kk]
        sc = abs(a0_0)
        sc = max(sc, abs(a0_1))
        sc = max(sc, abs(a0_2))
        sc = max(sc, abs(a0_3))
        sc = max(sc, abs(a0_4))
        sc = max(sc, abs(a1_0))
        sc = max(sc, abs(a1_1))
        sc = max(sc, abs(a1_2))
        sc = max(sc, abs(a1_3))
        sc = max(sc, abs(a1_4))
        sc = max(sc, abs(a2_0))
        sc = max(sc, abs(a2_1))
        sc = max(sc, abs(a2_2))
        sc = max(sc, abs(a2_3))
        sc = max(sc, abs(a2_4))
        sc = max(sc, abs(a3_0))
        sc = max(sc, abs(a3_1))
        sc = max(sc, abs(a3_2))
        sc = max(sc, abs(a3_3))
        sc = max(sc, abs(a3_4))
        sc = max(sc, abs(a4_0))
        sc = max(sc, abs(a4_1))
        sc = max(sc, abs(a4_2))
        sc = max(sc, abs(a4_3))
        sc = max(sc, abs(a4_4))
        # column 0: the reflector I - tau v v^T, v = (a0_0 - alpha, a1_0, ...)
        n2 = a0_0 * a0_0 + a1_0 * a1_0 + a2_0 * a2_0 + a3_0 * a3_0 + a4_0 * a4_0
        al = -math.copysign(math.sqrt(n2), a0_0)
        v0 = a0_0 - al
        vn2 = n2 - a0_0 * a0_0 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = abs(al)
        s = tau * (v0 * a0_1 + a1_0 * a1_1 + a2_0 * a2_1 + a3_0 * a3_1 + a4_0 * a4_1)
        a0_1 -= s * v0
        a1_1 -= s * a1_0
        a2_1 -= s * a2_0
        a3_1 -= s * a3_0
        a4_1 -= s * a4_0
        s = tau * (v0 * a0_2 + a1_0 * a1_2 + a2_0 * a2_2 + a3_0 * a3_2 + a4_0 * a4_2)
        a0_2 -= s * v0
        a1_2 -= s * a1_0
        a2_2 -= s * a2_0
        a3_2 -= s * a3_0
        a4_2 -= s * a4_0
        s = tau * (v0 * a0_3 + a1_0 * a1_3 + a2_0 * a2_3 + a3_0 * a3_3 + a4_0 * a4_3)
        a0_3 -= s * v0
        a1_3 -= s * a1_0
        a2_3 -= s * a2_0
        a3_3 -= s * a3_0
        a4_3 -= s * a4_0
        s = tau * (v0 * a0_4 + a1_0 * a1_4 + a2_0 * a2_4 + a3_0 * a3_4 + a4_0 * a4_4)
        a0_4 -= s * v0
        a1_4 -= s * a1_0
        a2_4 -= s * a2_0
        a3_4 -= s * a3_0
        a4_4 -= s * a4_0
        s = tau * (v0 * b0 + a1_0 * b1 + a2_0 * b2 + a3_0 * b3 + a4_0 * b4)
        b0 -= s * v0
        b1 -= s * a1_0
        b2 -= s * a2_0
        b3 -= s * a3_0
        b4 -= s * a4_0
        F[fo + _U(1600) + kk] = v0
        F[fo + _U(1920) + kk] = tau
        a0_0 = al
        # column 1: the reflector I - tau v v^T, v = (a1_1 - alpha, a2_1, ...)
        n2 = a1_1 * a1_1 + a2_1 * a2_1 + a3_1 * a3_1 + a4_1 * a4_1
        al = -math.copysign(math.sqrt(n2), a1_1)
        v0 = a1_1 - al
        vn2 = n2 - a1_1 * a1_1 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * a1_2 + a2_1 * a2_2 + a3_1 * a3_2 + a4_1 * a4_2)
        a1_2 -= s * v0
        a2_2 -= s * a2_1
        a3_2 -= s * a3_1
        a4_2 -= s * a4_1
        s = tau * (v0 * a1_3 + a2_1 * a2_3 + a3_1 * a3_3 + a4_1 * a4_3)
        a1_3 -= s * v0
        a2_3 -= s * a2_1
        a3_3 -= s * a3_1
        a4_3 -= s * a4_1
        s = tau * (v0 * a1_4 + a2_1 * a2_4 + a3_1 * a3_4 + a4_1 * a4_4)
        a1_4 -= s * v0
        a2_4 -= s * a2_1
        a3_4 -= s * a3_1
        a4_4 -= s * a4_1
        s = tau * (v0 * b1 + a2_1 * b2 + a3_1 * b3 + a4_1 * b4)
        b1 -= s * v0
        b2 -= s * a2_1
        b3 -= s * a3_1
        b4 -= s * a4_1
        F[fo + _U(1664) + kk] = v0
        F[fo + _U(1984) + kk] = tau
        a1_1 = al
        # column 2: the reflector I - tau v v^T, v = (a2_2 - alpha, a3_2, ...)
        n2 = a2_2 * a2_2 + a3_2 * a3_2 + a4_2 * a4_2
        al = -math.copysign(math.sqrt(n2), a2_2)
        v0 = a2_2 - al
        vn2 = n2 - a2_2 * a2_2 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * a2_3 + a3_2 * a3_3 + a4_2 * a4_3)
        a2_3 -= s * v0
        a3_3 -= s * a3_2
        a4_3 -= s * a4_2
        s = tau * (v0 * a2_4 + a3_2 * a3_4 + a4_2 * a4_4)
        a2_4 -= s * v0
        a3_4 -= s * a3_2
        a4_4 -= s * a4_2
        s = tau * (v0 * b2 + a3_2 * b3 + a4_2 * b4)
        b2 -= s * v0
        b3 -= s * a3_2
        b4 -= s * a4_2
        F[fo + _U(1728) + kk] = v0
        F[fo + _U(2048) + kk] = tau
        a2_2 = al
        # column 3: the reflector I - tau v v^T, v = (a3_3 - alpha, a4_3, ...)
        n2 = a3_3 * a3_3 + a4_3 * a4_3
        al = -math.copysign(math.sqrt(n2), a3_3)
        v0 = a3_3 - al
        vn2 = n2 - a3_3 * a3_3 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * a3_4 + a4_3 * a4_4)
        a3_4 -= s * v0
        a4_4 -= s * a4_3
        s = tau * (v0 * b3 + a4_3 * b4)
        b3 -= s * v0
        b4 -= s * a4_3
        F[fo + _U(1792) + kk] = v0
        F[fo + _U(2112) + kk] = tau
        a3_3 = al
        # column 4
        n2 = a4_4 * a4_4
        al = -math.copysign(math.sqrt(n2), a4_4)
        v0 = a4_4 - al
        vn2 = n2 - a4_4 * a4_4 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * b4)
        b4 -= s * v0
        F[fo + _U(1856) + kk] = v0
        F[fo + _U(2176) + kk] = tau
        a4_4 = al
        # the factors, kept for other right-hand sides
        F[fo + _U(0) + kk] = a0_0
        F[fo + _U(64) + kk] = a0_1
        F[fo + _U(128) + kk] = a0_2
        F[fo + _U(192) + kk] = a0_3
        F[fo + _U(256) + kk] = a0_4
        F[fo + _U(320) + kk] = a1_0
        F[fo + _U(384) + kk] = a1_1
        F[fo + _U(448) + kk] = a1_2
        F[fo + _U(512) + kk] = a1_3
        F[fo + _U(576) + kk] = a1_4
        F[fo + _U(640) + kk] = a2_0
        F[fo + _U(704) + kk] = a2_1
        F[fo + _U(768) + kk] = a2_2
        F[fo + _U(832) + kk] = a2_3
        F[fo + _U(896) + kk] = a2_4
        F[fo + _U(960) + kk] = a3_0
        F[fo + _U(1024) + kk] = a3_1
        F[fo + _U(1088) + kk] = a3_2
        F[fo + _U(1152) + kk] = a3_3
        F[fo + _U(1216) + kk] = a3_4
        F[fo + _U(1280) + kk] = a4_0
        F[fo + _U(1344) + kk] = a4_1
        F[fo + _U(1408) + kk] = a4_2
        F[fo + _U(1472) + kk] = a4_3
        F[fo + _U(1536) + kk] = a4_4
        # back substitution with R
        x4 = b4 / a4_4
        X[bo + _U(256) + kk] = x4
        x3 = (b3 - a3_4 * x4) / a3_3
        X[bo + _U(192) + kk] = x3
        x2 = (b2 - a2_3 * x3 - a2_4 * x4) / a2_2
        X[bo + _U(128) + kk] = x2
        x1 = (b1 - a1_2 * x2 - a1_3 * x3 - a1_4 * x4) / a1_1
        X[bo + _U(64) + kk] = x1
        x0 = (b0 - a0_1 * x1 - a0_2 * x2 - a0_3 * x3 - a0_4 * x4) / a0_0
        X[bo + _U(0) + kk] = x0
        worst[kk] = min(worst[kk], amin / sc if sc > 0.0 else 0.0)  # a zero block: singular


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def block_qr_6(W, off, F, foff, B, X, start, nk, worst):
    wo = _U(off * CHUNK)
    fo = _U(foff * CHUNK)
    bo = _U(start * CHUNK)
    for kk in range(_U(nk)):
        a0_0 = W[wo + _U(0) + kk]
        a0_1 = W[wo + _U(64) + kk]
        a0_2 = W[wo + _U(128) + kk]
        a0_3 = W[wo + _U(192) + kk]
        a0_4 = W[wo + _U(256) + kk]
        a0_5 = W[wo + _U(320) + kk]
        a1_0 = W[wo + _U(384) + kk]
        a1_1 = W[wo + _U(448) + kk]
        a1_2 = W[wo + _U(512) + kk]
        a1_3 = W[wo + _U(576) + kk]
        a1_4 = W[wo + _U(640) + kk]
        a1_5 = W[wo + _U(704) + kk]
        a2_0 = W[wo + _U(768) + kk]
        a2_1 = W[wo + _U(832) + kk]
        a2_2 = W[wo + _U(896) + kk]
        a2_3 = W[wo + _U(960) + kk]
        a2_4 = W[wo + _U(1024) + kk]
        a2_5 = W[wo + _U(1088) + kk]
        a3_0 = W[wo + _U(1152) + kk]
        a3_1 = W[wo + _U(1216) + kk]
        a3_2 = W[wo + _U(1280) + kk]
        a3_3 = W[wo + _U(1344) + kk]
        a3_4 = W[wo + _U(1408) + kk]
        a3_5 = W[wo + _U(1472) + kk]
        a4_0 = W[wo + _U(1536) + kk]
        a4_1 = W[wo + _U(1600) + kk]
        a4_2 = W[wo + _U(1664) + kk]
        a4_3 = W[wo + _U(1728) + kk]
        a4_4 = W[wo + _U(1792) + kk]
        a4_5 = W[wo + _U(1856) + kk]
        a5_0 = W[wo + _U(1920) + kk]
        a5_1 = W[wo + _U(1984) + kk]
        a5_2 = W[wo + _U(2048) + kk]
        a5_3 = W[wo + _U(2112) + kk]
        a5_4 = W[wo + _U(2176) + kk]
        a5_5 = W[wo + _U(2240) + kk]
        b0 = B[bo + _U(0) + kk]
        b1 = B[bo + _U(64) + kk]
        b2 = B[bo + _U(128) + kk]
        b3 = B[bo + _U(192) + kk]
        b4 = B[bo + _U(256) + kk]
        b5 = B[bo + _U(320) + kk]
        sc = abs(a0_0)
        sc = max(sc, abs(a0_1))
        sc = max(sc, abs(a0_2))
        sc = max(sc, abs(a0_3))
        sc = max(sc, abs(a0_4))
        sc = max(sc, abs(a0_5))
        sc = max(sc, abs(a1_0))
        sc = max(sc, abs(a1_1))
        sc = max(sc, abs(a1_2))
        sc = max(sc, abs(a1_3))
        sc = max(sc, abs(a1_4))
        sc = max(sc, abs(a1_5))
        sc = max(sc, abs(a2_0))
        sc = max(sc, abs(a2_1))
        sc = max(sc, abs(a2_2))
        sc = max(sc, abs(a2_3))
        sc = max(sc, abs(a2_4))
        sc = max(sc, abs(a2_5))
        sc = max(sc, abs(a3_0))
        sc = max(sc, abs(a3_1))
        sc = max(sc, abs(a3_2))
        sc = max(sc, abs(a3_3))
        sc = max(sc, abs(a3_4))
        sc = max(sc, abs(a3_5))
        sc = max(sc, abs(a4_0))
        sc = max(sc, abs(a4_1))
        sc = max(sc, abs(a4_2))
        sc = max(sc, abs(a4_3))
        sc = max(sc, abs(a4_4))
        sc = max(sc, abs(a4_5))
        sc = max(sc, abs(a5_0))
        sc = max(sc, abs(a5_1))
        sc = max(sc, abs(a5_2))
        sc = max(sc, abs(a5_3))
        sc = max(sc, abs(a5_4))
        sc = max(sc, abs(a5_5))
        # column 0: the reflector I - tau v v^T, v = (a0_0 - alpha, a1_0, ...)
        n2 = a0_0 * a0_0 + a1_0 * a1_0 + a2_0 * a2_0 + a3_0 * a3_0 + a4_0 * a4_0 + a5_0 * a5_0
        al = -math.copysign(math.sqrt(n2), a0_0)
        v0 = a0_0 - al
        vn2 = n2 - a0_0 * a0_0 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = abs(al)
        s = tau * (v0 * a0_1 + a1_0 * a1_1 + a2_0 * a2_1 + a3_0 * a3_1 + a4_0 * a4_1 + a5_0 * a5_1)
        a0_1 -= s * v0
        a1_1 -= s * a1_0
        a2_1 -= s * a2_0
        a3_1 -= s * a3_0
        a4_1 -= s * a4_0
        a5_1 -= s * a5_0
        s = tau * (v0 * a0_2 + a1_0 * a1_2 + a2_0 * a2_2 + a3_0 * a3_2 + a4_0 * a4_2 + a5_0 * a5_2)
        a0_2 -= s * v0
        a1_2 -= s * a1_0
        a2_2 -= s * a2_0
        a3_2 -= s * a3_0
        a4_2 -= s * a4_0
        a5_2 -= s * a5_0
        s = tau * (v0 * a0_3 + a1_0 * a1_3 + a2_0 * a2_3 + a3_0 * a3_3 + a4_0 * a4_3 + a5_0 * a5_3)
        a0_3 -= s * v0
        a1_3 -= s * a1_0
        a2_3 -= s * a2_0
        a3_3 -= s * a3_0
        a4_3 -= s * a4_0
        a5_3 -= s * a5_0
        s = tau * (v0 * a0_4 + a1_0 * a1_4 + a2_0 * a2_4 + a3_0 * a3_4 + a4_0 * a4_4 + a5_0 * a5_4)
        a0_4 -= s * v0
        a1_4 -= s * a1_0
        a2_4 -= s * a2_0
        a3_4 -= s * a3_0
        a4_4 -= s * a4_0
        a5_4 -= s * a5_0
        s = tau * (v0 * a0_5 + a1_0 * a1_5 + a2_0 * a2_5 + a3_0 * a3_5 + a4_0 * a4_5 + a5_0 * a5_5)
        a0_5 -= s * v0
        a1_5 -= s * a1_0
        a2_5 -= s * a2_0
        a3_5 -= s * a3_0
        a4_5 -= s * a4_0
        a5_5 -= s * a5_0
        s = tau * (v0 * b0 + a1_0 * b1 + a2_0 * b2 + a3_0 * b3 + a4_0 * b4 + a5_0 * b5)
        b0 -= s * v0
        b1 -= s * a1_0
        b2 -= s * a2_0
        b3 -= s * a3_0
        b4 -= s * a4_0
        b5 -= s * a5_0
        F[fo + _U(2304) + kk] = v0
        F[fo + _U(2688) + kk] = tau
        a0_0 = al
        # column 1: the reflector I - tau v v^T, v = (a1_1 - alpha, a2_1, ...)
        n2 = a1_1 * a1_1 + a2_1 * a2_1 + a3_1 * a3_1 + a4_1 * a4_1 + a5_1 * a5_1
        al = -math.copysign(math.sqrt(n2), a1_1)
        v0 = a1_1 - al
        vn2 = n2 - a1_1 * a1_1 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * a1_2 + a2_1 * a2_2 + a3_1 * a3_2 + a4_1 * a4_2 + a5_1 * a5_2)
        a1_2 -= s * v0
        a2_2 -= s * a2_1
        a3_2 -= s * a3_1
        a4_2 -= s * a4_1
        a5_2 -= s * a5_1
        s = tau * (v0 * a1_3 + a2_1 * a2_3 + a3_1 * a3_3 + a4_1 * a4_3 + a5_1 * a5_3)
        a1_3 -= s * v0
        a2_3 -= s * a2_1
        a3_3 -= s * a3_1
        a4_3 -= s * a4_1
        a5_3 -= s * a5_1
        s = tau * (v0 * a1_4 + a2_1 * a2_4 + a3_1 * a3_4 + a4_1 * a4_4 + a5_1 * a5_4)
        a1_4 -= s * v0
        a2_4 -= s * a2_1
        a3_4 -= s * a3_1
        a4_4 -= s * a4_1
        a5_4 -= s * a5_1
        s = tau * (v0 * a1_5 + a2_1 * a2_5 + a3_1 * a3_5 + a4_1 * a4_5 + a5_1 * a5_5)
        a1_5 -= s * v0
        a2_5 -= s * a2_1
        a3_5 -= s * a3_1
        a4_5 -= s * a4_1
        a5_5 -= s * a5_1
        s = tau * (v0 * b1 + a2_1 * b2 + a3_1 * b3 + a4_1 * b4 + a5_1 * b5)
        b1 -= s * v0
        b2 -= s * a2_1
        b3 -= s * a3_1
        b4 -= s * a4_1
        b5 -= s * a5_1
        F[fo + _U(2368) + kk] = v0
        F[fo + _U(2752) + kk] = tau
        a1_1 = al
        # column 2: the reflector I - tau v v^T, v = (a2_2 - alpha, a3_2, ...)
        n2 = a2_2 * a2_2 + a3_2 * a3_2 + a4_2 * a4_2 + a5_2 * a5_2
        al = -math.copysign(math.sqrt(n2), a2_2)
        v0 = a2_2 - al
        vn2 = n2 - a2_2 * a2_2 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * a2_3 + a3_2 * a3_3 + a4_2 * a4_3 + a5_2 * a5_3)
        a2_3 -= s * v0
        a3_3 -= s * a3_2
        a4_3 -= s * a4_2
        a5_3 -= s * a5_2
        s = tau * (v0 * a2_4 + a3_2 * a3_4 + a4_2 * a4_4 + a5_2 * a5_4)
        a2_4 -= s * v0
        a3_4 -= s * a3_2
        a4_4 -= s * a4_2
        a5_4 -= s * a5_2
        s = tau * (v0 * a2_5 + a3_2 * a3_5 + a4_2 * a4_5 + a5_2 * a5_5)
        a2_5 -= s * v0
        a3_5 -= s * a3_2
        a4_5 -= s * a4_2
        a5_5 -= s * a5_2
        s = tau * (v0 * b2 + a3_2 * b3 + a4_2 * b4 + a5_2 * b5)
        b2 -= s * v0
        b3 -= s * a3_2
        b4 -= s * a4_2
        b5 -= s * a5_2
        F[fo + _U(2432) + kk] = v0
        F[fo + _U(2816) + kk] = tau
        a2_2 = al
        # column 3: the reflector I - tau v v^T, v = (a3_3 - alpha, a4_3, ...)
        n2 = a3_3 * a3_3 + a4_3 * a4_3 + a5_3 * a5_3
        al = -math.copysign(math.sqrt(n2), a3_3)
        v0 = a3_3 - al
        vn2 = n2 - a3_3 * a3_3 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * a3_4 + a4_3 * a4_4 + a5_3 * a5_4)
        a3_4 -= s * v0
        a4_4 -= s * a4_3
        a5_4 -= s * a5_3
        s = tau * (v0 * a3_5 + a4_3 * a4_5 + a5_3 * a5_5)
        a3_5 -= s * v0
        a4_5 -= s * a4_3
        a5_5 -= s * a5_3
        s = tau * (v0 * b3 + a4_3 * b4 + a5_3 * b5)
        b3 -= s * v0
        b4 -= s * a4_3
        b5 -= s * a5_3
        F[fo + _U(2496) + kk] = v0
        F[fo + _U(2880) + kk] = tau
        a3_3 = al
        # column 4: the reflector I - tau v v^T, v = (a4_4 - alpha, a5_4, ...)
        n2 = a4_4 * a4_4 + a5_4 * a5_4
        al = -math.copysign(math.sqrt(n2), a4_4)
        v0 = a4_4 - al
        vn2 = n2 - a4_4 * a4_4 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * a4_5 + a5_4 * a5_5)
        a4_5 -= s * v0
        a5_5 -= s * a5_4
        s = tau * (v0 * b4 + a5_4 * b5)
        b4 -= s * v0
        b5 -= s * a5_4
        F[fo + _U(2560) + kk] = v0
        F[fo + _U(2944) + kk] = tau
        a4_4 = al
        # column 5
        n2 = a5_5 * a5_5
        al = -math.copysign(math.sqrt(n2), a5_5)
        v0 = a5_5 - al
        vn2 = n2 - a5_5 * a5_5 + v0 * v0
        tau = 2.0 / vn2 if vn2 > 0.0 else 0.0
        amin = min(amin, abs(al))
        s = tau * (v0 * b5)
        b5 -= s * v0
        F[fo + _U(2624) + kk] = v0
        F[fo + _U(3008) + kk] = tau
        a5_5 = al
        # the factors, kept for other right-hand sides
        F[fo + _U(0) + kk] = a0_0
        F[fo + _U(64) + kk] = a0_1
        F[fo + _U(128) + kk] = a0_2
        F[fo + _U(192) + kk] = a0_3
        F[fo + _U(256) + kk] = a0_4
        F[fo + _U(320) + kk] = a0_5
        F[fo + _U(384) + kk] = a1_0
        F[fo + _U(448) + kk] = a1_1
        F[fo + _U(512) + kk] = a1_2
        F[fo + _U(576) + kk] = a1_3
        F[fo + _U(640) + kk] = a1_4
        F[fo + _U(704) + kk] = a1_5
        F[fo + _U(768) + kk] = a2_0
        F[fo + _U(832) + kk] = a2_1
        F[fo + _U(896) + kk] = a2_2
        F[fo + _U(960) + kk] = a2_3
        F[fo + _U(1024) + kk] = a2_4
        F[fo + _U(1088) + kk] = a2_5
        F[fo + _U(1152) + kk] = a3_0
        F[fo + _U(1216) + kk] = a3_1
        F[fo + _U(1280) + kk] = a3_2
        F[fo + _U(1344) + kk] = a3_3
        F[fo + _U(1408) + kk] = a3_4
        F[fo + _U(1472) + kk] = a3_5
        F[fo + _U(1536) + kk] = a4_0
        F[fo + _U(1600) + kk] = a4_1
        F[fo + _U(1664) + kk] = a4_2
        F[fo + _U(1728) + kk] = a4_3
        F[fo + _U(1792) + kk] = a4_4
        F[fo + _U(1856) + kk] = a4_5
        F[fo + _U(1920) + kk] = a5_0
        F[fo + _U(1984) + kk] = a5_1
        F[fo + _U(2048) + kk] = a5_2
        F[fo + _U(2112) + kk] = a5_3
        F[fo + _U(2176) + kk] = a5_4
        F[fo + _U(2240) + kk] = a5_5
        # back substitution with R
        x5 = b5 / a5_5
        X[bo + _U(320) + kk] = x5
        x4 = (b4 - a4_5 * x5) / a4_4
        X[bo + _U(256) + kk] = x4
        x3 = (b3 - a3_4 * x4 - a3_5 * x5) / a3_3
        X[bo + _U(192) + kk] = x3
        x2 = (b2 - a2_3 * x3 - a2_4 * x4 - a2_5 * x5) / a2_2
        X[bo + _U(128) + kk] = x2
        x1 = (b1 - a1_2 * x2 - a1_3 * x3 - a1_4 * x4 - a1_5 * x5) / a1_1
        X[bo + _U(64) + kk] = x1
        x0 = (b0 - a0_1 * x1 - a0_2 * x2 - a0_3 * x3 - a0_4 * x4 - a0_5 * x5) / a0_0
        X[bo + _U(0) + kk] = x0
        worst[kk] = min(worst[kk], amin / sc if sc > 0.0 else 0.0)  # a zero block: singular


MAX_BLOCK = 6


@njit(cache=True, error_model="numpy", fastmath={"contract"})
def block_qr(n, W, off, F, foff, B, X, start, nk, worst):
    """Solve an n x n block with its written solver and keep its factors (see the
    module doc).

    False when n > MAX_BLOCK: the caller solves the block itself."""
    if n == 1:
        block_qr_1(W, off, F, foff, B, X, start, nk, worst)
    elif n == 2:
        block_qr_2(W, off, F, foff, B, X, start, nk, worst)
    elif n == 3:
        block_qr_3(W, off, F, foff, B, X, start, nk, worst)
    elif n == 4:
        block_qr_4(W, off, F, foff, B, X, start, nk, worst)
    elif n == 5:
        block_qr_5(W, off, F, foff, B, X, start, nk, worst)
    elif n == 6:
        block_qr_6(W, off, F, foff, B, X, start, nk, worst)
    else:
        return False
    return True
