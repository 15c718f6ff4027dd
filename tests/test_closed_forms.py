"""The engine against closed forms written here, independent of the package."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sewmech
from conftest import BENCH, PHI, fourbar, slider_crank


def freudenstein_theta4(theta2, a, b, c, d, branch):
    """Output angle of a four-bar from Freudenstein's equation, ground on the x axis.

    K1 cos t4 - K2 cos t2 + K3 = cos(t2 - t4), K1 = d/a, K2 = d/c, K3 = (a^2-b^2+c^2+d^2)/(2ac),
    solved by the half-angle substitution.
    """
    K1, K2, K3 = d / a, d / c, (a * a - b * b + c * c + d * d) / (2 * a * c)
    A = math.cos(theta2) - K1 - K2 * math.cos(theta2) + K3
    B = -2.0 * math.sin(theta2)
    C = K1 - (K2 + 1.0) * math.cos(theta2) + K3
    disc = math.sqrt(B * B - 4 * A * C)
    return [2.0 * math.atan((-B + s * disc) / (2.0 * A)) for s in (1, -1)]


def angle_diff(a, b):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))


def test_fourbar_rocker_angle_matches_freudenstein():
    m = fourbar()
    r = sewmech.kinematics(m, PHI)
    th4 = r.link("rocker").theta
    for i, t2 in enumerate(PHI):
        cands = freudenstein_theta4(t2, 15.0, 40.0, 35.0, 38.0, 1)
        # one of the two Freudenstein roots is the assembly with C to the left of B->D
        assert min(angle_diff(th4[i], c) for c in cands) < 1e-11


def test_coupler_point_closed_form():
    m = fourbar()
    r = sewmech.kinematics(m, PHI)
    B = 15.0 * np.stack([np.cos(PHI), np.sin(PHI)], -1)
    D = np.array([38.0, 0.0])
    d = D - B
    dd = np.hypot(d[:, 0], d[:, 1])
    a = (40.0**2 - 35.0**2 + dd**2) / (2 * dd)
    h = np.sqrt(40.0**2 - a**2)
    e = d / dd[:, None]
    n = np.stack([-e[:, 1], e[:, 0]], -1)
    C = B + a[:, None] * e + h[:, None] * n
    u = (C - B) / 40.0
    un = np.stack([-u[:, 1], u[:, 0]], -1)
    P = B + 30.0 * u + 10.0 * un
    np.testing.assert_allclose(r.point("C").p, C, atol=1e-12)
    np.testing.assert_allclose(r.point("P").p, P, atol=1e-12)


@given(r=st.floats(5, 30), lam=st.floats(0.1, 0.6), e=st.floats(-0.5, 0.5))
@settings(max_examples=40, deadline=None)
def test_slider_crank_displacement(r, lam, e):
    """Offset slider-crank: x = r cos t + sqrt(l^2 - (r sin t - e)^2) along a horizontal guide."""
    l = r / lam
    e_mm = e * (l - r)
    m = slider_crank(r=r, l=l, e=e_mm, alpha=0.0)
    res = sewmech.kinematics(m, PHI)
    x = r * np.cos(PHI) + np.sqrt(l**2 - (r * np.sin(PHI) - e_mm) ** 2)
    np.testing.assert_allclose(res.variable("slider").q, x, rtol=0, atol=1e-10 * l)
    np.testing.assert_allclose(res.point("C").p[:, 1], e_mm, atol=1e-10 * l)


def test_needle_bar_rise_after_bottom_dead_centre():
    """Needle-bar rise after BDC for the crank above the bar (the sewing-machine inversion).

    With the pin at its lowest point at BDC and the rod hanging down to the bar, a crank turn of
    delta lifts the pin r(1 - cos delta) and tilts the rod, which lifts the bar a further
    l[1 - sqrt(1 - (r/l)^2 sin^2 delta)]. (The textbook form has a minus sign there:
    the piston-above-crank inversion; for the needle bar the sign is plus.)
    """
    r, l = 15.35, 44.0
    m = slider_crank(r=r, l=l, alpha=90.0, branch=-1)
    res = sewmech.kinematics(m, PHI)
    y = res.variable("slider").q
    delta = PHI - math.radians(270.0)  # BDC: crank pin straight down
    h = r * (1 - np.cos(delta)) + l * (1 - np.sqrt(1 - (r / l) ** 2 * np.sin(delta) ** 2))
    np.testing.assert_allclose(y - (-r - l), h, atol=1e-10)
