"""The page's fast JSON writer (sewmech.app.web.encode): its text reads back as exactly the
floats json.dumps writes of the same answer with its arrays rounded as lists, for the values a
turn has and the edges of the digit tables (signs, zeros, carries, rounding ties, large
values, NaN and infinity, tables of rows)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from sewmech.app.web.encode import Arr, NotJSON, dumps, plain


def _same(a, b) -> bool:
    """Equal as JSON values, floats bit for bit (a negative zero is one) and of the same type."""
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(map(_same, a, b))
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, float):
        return type(b) is float and a == b and math.copysign(1, a) == math.copysign(1, b)
    return type(a) is type(b) and a == b


def _values():
    rng = np.random.default_rng(34)
    v = np.concatenate([rng.uniform(-100, 100, 3000), rng.normal(0, 1e-5, 500),
                        rng.uniform(-5e8, 5e8, 500), 10.0 ** rng.uniform(-7, 9, 500),
                        [0.0, -0.0, -1e-9, 1e-7, 5e-7, -5e-7, 1.5e-6, 2.5e-6, 12.5, 100.0,
                         999999.9999995, 1e8, -0.1, 0.1, 1 / 3, 999999999.9999, 9999.99999999,
                         # rounded up to a whole digit more (10 digits, the most below 1e9)
                         999999999.9999996, -999999999.9999997, 99999.9999996]])
    return np.concatenate([v, np.round(v, 3), np.round(v, 1), np.round(v, 0), -v])


def test_arrays_read_back_as_the_plain_writers_floats():
    v = _values()
    answer = {"a": Arr(v), "rows": Arr(v[:400].reshape(-1, 2)), "row": Arr(v[:3][None, :]),
              "column": Arr(v[:3][:, None]), "scalar": Arr(2.5), "empty": Arr([]),
              "gaps": Arr([1.0, np.nan, -np.inf, 2.0]), "big": Arr([1e12, -3.0]),
              "deep": Arr(np.ones((2, 2, 2))), "text": "x\u00e9\"\\ \ud800", "none": None,
              "flag": True, "n": 3, "f": 1.25, "list": [Arr([1.0]), {"k": Arr([-0.0])}]}
    fast = json.loads(dumps(answer))
    assert _same(fast, json.loads(json.dumps(plain(answer))))
    assert fast["gaps"] == [1.0, None, None, 2.0]
    # a gap in an array beside empty ones, first and last
    for gaps in ({"e": Arr([]), "n": Arr([np.nan]), "z": Arr(np.zeros((0, 2)))},
                 {"n": Arr([np.nan, 1.0]), "e": Arr([]), "x": Arr([2.0, -0.5])}):
        assert _same(json.loads(dumps(gaps)), json.loads(json.dumps(plain(gaps))))
    assert _same(fast["a"], np.round(v, 6).tolist())


def test_a_turn_is_written_as_the_plain_writer_writes_it():
    from sewmech.app.web.session import Session, shipped_texts

    file, text = shipped_texts()["jb1-3"]
    s = Session.from_text(text, file)
    for values in ({}, {"input.regulator": -12.3, "needle_bar.length": 44.25}):
        assert _same(json.loads(s.turn_json(values)), json.loads(json.dumps(s.turn(values))))


def test_what_json_refuses_is_refused():
    with pytest.raises(NotJSON):
        dumps({"x": float("nan"), "a": Arr([1.0])})
    with pytest.raises(TypeError):
        dumps({"x": object()})
    assert json.loads(dumps({1: Arr([1.0])})) == {"1": [1.0]}  # as json writes a key
