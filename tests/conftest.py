"""Shared machine texts for the tests: small mechanisms whose closed forms the tests write out."""

import numpy as np
import pytest

import sewmech

FOURBAR = """
[machine]
name = "fourbar"
[convention]
reference_event = "crank along +x"
reference_phi_deg = 0.0
[points.A]
x = {ax}
y = {ay}
[points.D]
x = {dx}
y = {dy}
[[units]]
type = "crank"
name = "crank"
pivot = "A"
phase_deg = {phase}
points = {{ B = [{ab}, 0.0] }}
[[units]]
type = "rrr"
name = "dyad"
joints = ["B", "D"]
new = "C"
links = ["coupler", "rocker"]
lengths = [{bc}, {cd}]
branch = {branch}
[[units]]
type = "point"
name = "cp"
link = "coupler"
origin = "B"
points = {{ P = [{pu}, {pv}] }}
"""

FOURBAR_LOOP = """
[machine]
name = "fourbar-loop"
[convention]
reference_event = "crank along +x"
reference_phi_deg = 0.0
assembly_phi_deg = {assembly}
[points.A]
x = {ax}
y = {ay}
[points.D]
x = {dx}
y = {dy}
[[units]]
type = "crank"
name = "crank"
pivot = "A"
phase_deg = {phase}
points = {{ B = [{ab}, 0.0] }}
[[units]]
type = "loop"
name = "fourbar"
unknown_links_deg = {{ coupler = {g_coupler}, rocker = {g_rocker} }}
loops = [ {{ name = "ABCD", terms = [ {{point = "B"}}, {{link = "coupler", length = {bc}}},
          {{link = "rocker", length = {cd}, sign = -1}}, {{point = "D", sign = -1}} ] }} ]
"""

SLIDER_CRANK = """
[machine]
name = "slider-crank"
[convention]
reference_event = "crank along +x"
reference_phi_deg = 0.0
[points.O]
x = 0.0
y = 0.0
[points.G]
x = {gx}
y = {gy}
[[units]]
type = "crank"
name = "crank"
pivot = "O"
points = {{ B = [{r}, 0.0] }}
[[units]]
type = "rrp"
name = "slider"
pin = "B"
rod = "rod"
length = {l}
new = "C"
slider = "block"
guide_point = "G"
guide_angle_deg = {alpha}
offset = {e}
branch = {branch}
"""

BENCH = dict(ax=0.0, ay=0.0, dx=38.0, dy=0.0, phase=0.0, ab=15.0, bc=40.0, cd=35.0, branch=1,
             pu=30.0, pv=10.0)


def fourbar(**kw) -> sewmech.Machine:
    return sewmech.machine_from_toml(FOURBAR.format(**{**BENCH, **kw}))


def slider_crank(r=15.0, l=44.0, e=0.0, alpha=90.0, gx=0.0, gy=0.0, branch=1):
    return sewmech.machine_from_toml(SLIDER_CRANK.format(r=r, l=l, e=e, alpha=alpha, gx=gx,
                                                         gy=gy, branch=branch))


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


PHI = np.radians(np.arange(0.0, 360.0, 3.0))
