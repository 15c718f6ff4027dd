"""The events' root finder on a few intervals (Python floats, engine._events._root_of_one) gives
the array path's bits: the page's turn locates its feed and thread events one or two intervals
at a time."""

from __future__ import annotations

import math

import numpy as np

from sewmech.engine import _events as E


def test_few_intervals_give_the_array_paths_bits():
    rng = np.random.default_rng(34)
    bisected = 0
    for trial in range(3000):
        k = int(rng.integers(1, E._FEW + 1))
        y0 = rng.normal(size=k) * 10.0 ** rng.uniform(-6, 3)
        y1 = -np.sign(y0) * np.abs(rng.normal(size=k)) * 10.0 ** rng.uniform(-6, 3)
        if trial % 7 == 0:
            y0[0] = 0.0
        if trial % 11 == 0:
            y1[-1] = 0.0
        m0, m1 = (rng.normal(size=k) * 10.0 ** rng.uniform(-3, 5) for _ in range(2))
        h = 2.0 * math.pi / float(rng.choice([180, 360, 720]))
        with np.errstate(all="ignore"):
            few = E.herm_root(y0, y1, m0, m1, h)
            arrays = E._herm_root_arrays(y0, y1, m0, m1, h)
            # the rows Newton did not settle (the bisection's)
            t = arrays
            bisected += int(np.sum(np.abs(E.herm(y0, y1, m0, m1, h, t))
                                   > 1e-12 * np.maximum(abs(y0), abs(y1))))
        assert np.array_equal(few, arrays) and np.array_equal(np.signbit(few),
                                                              np.signbit(arrays)), trial
    assert bisected > 0  # the bisection was compared too
    # more intervals, or not finite values: the array path itself
    y = np.linspace(-1.0, 1.0, E._FEW + 1)
    assert np.array_equal(E.herm_root(y, -y, y, y, 0.1), E._herm_root_arrays(y, -y, y, y, 0.1))
    args = (*(np.array(a) for a in ([1.0, np.nan], [-1.0, 1.0], [0.0, 0.0], [0.0, 0.0])), 0.1)
    with np.errstate(all="ignore"):
        assert np.array_equal(E.herm_root(*args), E._herm_root_arrays(*args), equal_nan=True)
