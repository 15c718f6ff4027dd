"""The page's answers as JSON text, their arrays written by numpy (issue 34, item 4).

A turn carries about 17,000 numbers; Python's JSON writer spends about 300 ns on each float
(its shortest repr), a third of a turn's whole time. Every array of an answer is rounded to
``DECIMALS`` decimals anyway, so each is a whole number ``q`` of millionths: all of a turn's
arrays are written here at once, as those integers' digits with the decimal point put in
(trailing zeros after the first decimal left out), by array arithmetic on a table of bytes.
The text reads back, in JavaScript or Python, as exactly the floats the plain writer gives
(``json.dumps`` of ``np.round(a, DECIMALS).tolist()``): both are the float nearest to
``q / 10**DECIMALS`` (``tests/test_serve_encode.py`` compares them).

An answer is a tree of dicts, lists, strings, numbers, None and :class:`Arr` (an array the
page receives as nested lists, NaN and infinity as ``null``). :func:`plain` turns the arrays
into lists (what :meth:`Session.turn` returns), :func:`dumps` writes the JSON bytes.
"""

from __future__ import annotations

import json
import secrets

import numpy as np

#: decimals kept in the answers' arrays (mm, N: 1e-6 is far below anything drawn or printed)
DECIMALS = 6
#: the largest magnitude written by the fast path: its millionths are exact integers in a
#: float (2**53 is about 9e15); larger values (none in a sane machine) take json's own path
_FAST_LIMIT = 1e9

_SCALE = 10.0 ** DECIMALS


class NotJSON(ValueError):
    """A float outside an :class:`Arr` that JSON cannot hold (NaN, infinity): a bug."""


class Arr:
    """An array of an answer: written as nested lists, rounded to ``DECIMALS`` decimals, NaN
    and infinity as null."""

    __slots__ = ("a",)

    def __init__(self, a):
        self.a = np.asarray(a, dtype=float)

    def tolist(self) -> list:
        a = self.a
        ok = np.isfinite(a)
        r = np.round(a, DECIMALS)
        if ok.all():
            return r.tolist()
        return np.where(ok, r, None).tolist()


def plain(obj):
    """The answer with its arrays as lists (what json.loads of :func:`dumps` gives)."""
    if isinstance(obj, Arr):
        return obj.tolist()
    if isinstance(obj, dict):
        return {k: plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [plain(v) for v in obj]
    return obj


def _words(texts: list[bytes]) -> np.ndarray:
    """Texts of 4 bytes each as uint32 words (their bytes in memory in the given order)."""
    return np.frombuffer(b"".join(texts), dtype=np.uint32)


#: 0000 .. 9999
_DIGITS4 = _words([f"{i:04d}".encode() for i in range(10_000)])
#: " .00" .. " .99": the point and the first two decimals
_POINT2 = _words([f" .{i:02d}".encode() for i in range(100)])
_SIGN = _words([b"  [-"])[0]
_CLOSE = _words([b"],  "])[0]
#: the masks of the bytes kept of those two words: a row's "[" and the sign (index
#: 2 * opens + negative); its "]" and the comma (index closes)
_SIGN_KEEP = _words([b"\x00\x00\x00\x00", b"\x00\x00\x00\x01", b"\x00\x00\x01\x00",
                     b"\x00\x00\x01\x01"])
_CLOSE_KEEP = _words([b"\x00\x01\x00\x00", b"\x01\x01\x00\x00"])
#: the masks of a word's bytes kept: its last k (a number's leading digits), its first k
_LAST = _words([bytes(4 - k) + b"\x01" * k for k in range(5)])
_FIRST = _words([b"\x01" * k + bytes(4 - k) for k in range(5)])
#: the powers of ten that add a whole digit: 10, 100, ..., 10**9 (a value just below
#: :data:`_FAST_LIMIT` may round up to it)
_TENS = 10 ** np.arange(1, 10, dtype=np.int64)
_KEPT: np.ndarray | None = None
assert DECIMALS == 6  # the decimals' words below: " .dd" and "dddd"


def _kept() -> np.ndarray:
    """The decimals written of each ``q mod 10**DECIMALS``: up to its last non-zero digit, at
    least one (a table of 10**DECIMALS bytes, made once)."""
    global _KEPT
    if _KEPT is None:
        f = np.arange(10 ** DECIMALS)
        kept = np.full(f.size, DECIMALS, dtype=np.int8)
        for k in range(1, DECIMALS):
            kept[f % 10 ** k == 0] = DECIMALS - k
        kept[0] = 1
        _KEPT = kept
    return _KEPT


def _digits(values: np.ndarray, opens: np.ndarray, closes: np.ndarray) -> tuple[bytes,
                                                                                np.ndarray]:
    """Finite values below :data:`_FAST_LIMIT` written as ``"<number>,"`` one after the other,
    with a "[" before the numbers that ``opens`` marks and a "]" after those ``closes`` marks
    (the rows of a table): (the bytes, the offset of each number's text and the end).

    Each number is a row of 4-byte words, "  [-", its whole part's digits in groups of four,
    " .dd", "dddd", "],  ", with a mask of the bytes kept: the "[" and "]" where marked, the
    sign if negative, the whole part from its first digit, the decimals to their last non-zero
    one (at least one), the comma."""
    qf = np.rint(values * _SCALE)           # np.round's own steps: multiply, round half even
    neg = np.signbit(qf)                     # -0.0 stays "-0" (a negative zero, as repr)
    u = np.abs(qf).astype(np.int64)
    whole, frac = np.divmod(u, np.int64(10 ** DECIMALS))
    width = 1 + np.searchsorted(_TENS, whole, side="right")  # digits of the whole part
    groups = (int(width.max()) + 3) // 4 if whole.size else 1
    n = values.size
    words = np.empty((n, groups + 4), dtype=np.uint32)
    keep = np.empty((n, groups + 4), dtype=np.uint32)
    words[:, 0] = _SIGN
    keep[:, 0] = _SIGN_KEEP[neg + 2 * opens]
    rest = whole
    for g in range(groups, 0, -1):
        rest, low = np.divmod(rest, 10_000)
        words[:, g] = _DIGITS4[low]
        keep[:, g] = _LAST[np.clip(width - 4 * (groups - g), 0, 4)]
    kept = _kept()[frac]
    hi, lo = np.divmod(frac, 10_000)
    words[:, groups + 1] = _POINT2[hi]
    keep[:, groups + 1] = _FIRST[2 + np.minimum(kept, 2)] & _LAST[3]
    words[:, groups + 2] = _DIGITS4[lo]
    keep[:, groups + 2] = _FIRST[np.maximum(kept - 2, 0)]
    words[:, groups + 3] = _CLOSE
    keep[:, groups + 3] = _CLOSE_KEEP[closes.astype(np.intp)]
    text = words.view(np.uint8)[keep.view(bool)].tobytes()
    ends = np.empty(n + 1, dtype=np.int64)
    ends[0] = 0
    np.cumsum(width + kept + 2 + neg + opens + closes, out=ends[1:])
    return text, ends


def dumps(obj) -> bytes:
    """The answer as compact JSON bytes (ASCII), its :class:`Arr` arrays written at once.
    :class:`NotJSON` for a float that JSON cannot hold (NaN, infinity) outside an
    :class:`Arr`.

    The tree is written by json itself with each array as a placeholder string, a random
    token of this call and the array's number (no string of the answer can be it), which the
    arrays' text then replaces."""
    arrays: list[Arr] = []
    token = secrets.token_hex(12)

    def placeholder(x):
        if not isinstance(x, Arr):
            raise TypeError(f"Object of type {type(x).__name__} is not JSON serializable")
        arrays.append(x)
        return f"{token}{len(arrays) - 1}"

    try:
        tree = json.dumps(obj, separators=(",", ":"), allow_nan=False, default=placeholder)
    except ValueError as exc:
        raise NotJSON(str(exc)) from None
    if not arrays:
        return tree.encode()
    written = _arrays(arrays)
    parts = tree.split(f'"{token}')
    out = [parts[0].encode()]
    for part in parts[1:]:
        k, rest = part.split('"', 1)
        out += [written[int(k)], rest.encode()]
    return b"".join(out)


def _arrays(arrays: list[Arr]) -> list[bytes]:
    """The JSON text of each array: the finite ones of at most two axes below
    :data:`_FAST_LIMIT` at once (:func:`_digits`), the others (none in a sane answer) by json."""
    flat = np.concatenate([x.a.ravel() for x in arrays])
    if np.abs(flat).max(initial=0.0) < _FAST_LIMIT:  # (False with a NaN)
        fast = [x.a.size > 0 and x.a.ndim <= 2 for x in arrays]
    else:  # the arrays that hold one, each by json
        fast = [x.a.size > 0 and x.a.ndim <= 2 and bool(np.all(np.abs(x.a) < _FAST_LIMIT))
                for x in arrays]
    use = [x for x, f in zip(arrays, fast, strict=True) if f]
    text = b""
    if use:
        flat = np.concatenate([x.a.ravel() for x in use]) if len(use) < len(arrays) else flat
        opens = np.zeros(flat.size, dtype=bool)
        closes = np.zeros(flat.size, dtype=bool)
        i = 0
        for x in use:
            if x.a.ndim == 2:  # rows of a table: [[a,b],[c,d]]
                k = x.a.shape[1]
                opens[i:i + x.a.size:k] = True
                closes[i + k - 1:i + x.a.size:k] = True
            i += x.a.size
        text, ends = _digits(flat, opens, closes)
    out, i = [], 0
    for x, f in zip(arrays, fast, strict=True):
        if f:
            body = text[ends[i]:ends[i + x.a.size] - 1]  # without the last comma
            out.append(body if x.a.ndim == 0 else b"[" + body + b"]")
            i += x.a.size
        else:
            out.append(json.dumps(x.tolist(), separators=(",", ":")).encode())
    return out
