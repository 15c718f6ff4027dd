"""Exact derivatives of the inverse dynamics by the design (issue 32): every pair force, the
driving torque, the shaking force and moment and the bearing reactions against central finite
differences of the whole analysis (friction, springs, process loads and a counterweight
included), the equations the derivative is taken of against the kernel's solution, a batch
against one design at a time, a frictionless machine, and the located error."""

from __future__ import annotations

import math

import numpy as np
import pytest

import sewmech
from sewmech.engine.dynamic_sensitivity import dynamics_sensitivities
from sewmech.engine.dynamics import inverse_dynamics
from sewmech.engine.errors import AnalysisError

PHI = np.radians(np.arange(0.0, 360.0, 7.5))
#: one parameter of every kind: a pin on a crank, a dyad length, a frame point, a cam arc, a
#: loop's term, the counterweight's static moment and angle, the setting input, a crank's
#: phase and its speed ratio, the spring's anchor, a point on a link
KINDS = ("B.u", "take_up.length1", "Lp.x", "feed_cam.arc0.radius", "lift.cam.3.length",
         "extra.static_moment", "extra.angle", "input.regulator", "needle_crank.phase",
         "needle_crank.ratio", "feed_bar.spring_anchor.y", "feed_bar.pin.v")


@pytest.fixture(scope="module")
def jb():
    m = sewmech.load_machine("jb1-3").with_parameters(
        {"extra.static_moment": 0.6, "input.regulator": math.radians(20.0)})
    return m, dynamics_sensitivities(m, PHI)


def _rel(fd, exact, scale):
    return float(np.abs(fd - exact).max()) / scale


def test_the_equations_are_the_kernels(jb):
    """The complex-safe equations the derivative is taken of hold at the kernel's solution (to
    1e-9 of the largest force): they are the same equations."""
    _, ds = jb
    assert ds.residual < 1e-9


@pytest.mark.parametrize("name", KINDS)
def test_every_derivative_against_central_differences(jb, name):
    """d/dp of the pair unknowns, the driving torque, the shaking force and moment and both
    bearings against central differences of the whole analysis (h = 2e-6 of the value and half
    of it, extrapolated), at the
    angles where no process load switches between the three analyses (a load that switches
    makes the forces jump: they have no derivative there); within 1e-6 of each quantity's
    scale."""
    m, ds = jb
    P0 = m.defaults
    j = m.parameter_names.index(name)
    base = ds.result
    best = None
    # central differences at h and h / 2, extrapolated (Richardson), for two steps: the
    # friction's smoothed sign bends the forces sharply where a pair's sliding turns (a small
    # step resolves it), the loop units' Newton solutions carry round-off (a large step
    # drowns it); the step whose two differences agree best is taken (chosen without the
    # exact answer)
    for h in (1e-5 * max(1.0, abs(P0[j])), 2e-6 * max(1.0, abs(P0[j]))):
        same = np.ones(len(PHI), dtype=bool)
        fds = []
        for step in (h, h / 2):
            Pp, Pm = P0.copy(), P0.copy()
            Pp[j] += step
            Pm[j] -= step
            rp, rm = inverse_dynamics(m, PHI, params=Pp), inverse_dynamics(m, PHI, params=Pm)
            same &= np.all((rp.load_on == base.load_on) & (rm.load_on == base.load_on),
                           axis=-1)
            fds.append([(a - b) / (2.0 * step) for a, b in (
                (rp.unknowns, rm.unknowns), (rp.input_torque, rm.input_torque),
                (rp.shaking_force, rm.shaking_force), (rp.shaking_moment, rm.shaking_moment),
                (rp.bearings.front, rm.bearings.front), (rp.bearings.rear, rm.bearings.rear))])
        c, f = fds[0][0], fds[1][0]  # (judged on the pair unknowns)
        spread = float(np.abs(f - c)[same].max()) / max(float(np.abs(f[same]).max()), 1e-12)
        if best is None or spread < best[0]:
            best = (spread, same, fds)
    _, same, fds = best
    assert same.sum() > 0.8 * len(PHI)
    exacts = [(ds.dX[..., j], base.unknowns), (ds.input_torque[..., j], base.input_torque),
              (ds.shaking_force[..., j], base.shaking_force),
              (ds.shaking_moment[..., j], base.shaking_moment),
              (ds.bearings_front[..., j], base.bearings.front),
              (ds.bearings_rear[..., j], base.bearings.rear)]
    for k, ((exact, value), coarse, fine) in enumerate(zip(exacts, *fds, strict=True)):
        fd = (4.0 * fine - coarse) / 3.0
        # the scale: the derivative's own size, or (where it is round-off) the quantity's
        scale = max(float(np.abs(fd[same]).max()), 1e-6 * float(np.abs(value).max()), 1e-12)
        assert _rel(fd[same], exact[same], scale) < 1e-6, (name, k)


def test_a_batch_is_each_design_on_its_own(jb):
    m, _ = jb
    P = m.parameters({"needle_bar.length": np.array([43.0, 45.5])})
    batch = dynamics_sensitivities(m, PHI, params=P)
    for d in range(2):
        one = dynamics_sensitivities(m, PHI, params=P[d])
        for a, b in ((batch.dX[d], one.dX), (batch.input_torque[d], one.input_torque),
                     (batch.bearings_front[d], one.bearings_front)):
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * np.abs(b).max())


def test_without_friction_and_at_another_speed():
    """The frictionless machine (the forces linear in the inertia terms) at 1500 rpm: the
    derivative of the driving torque by the needle-bar link against central differences."""
    from test_dynamics import without_friction

    m = without_friction("jb1-3")
    ds = dynamics_sensitivities(m, PHI, rpm=1500.0)
    assert ds.residual < 1e-9
    j = m.parameter_names.index("needle_bar.length")
    h = 1e-5 * m.defaults[j]
    Pp, Pm = m.defaults.copy(), m.defaults.copy()
    Pp[j] += h
    Pm[j] -= h
    rp = inverse_dynamics(m, PHI, params=Pp, rpm=1500.0)
    rm = inverse_dynamics(m, PHI, params=Pm, rpm=1500.0)
    base = ds.result
    same = np.all((rp.load_on == base.load_on) & (rm.load_on == base.load_on), axis=-1)
    fd = (rp.input_torque - rm.input_torque) / (2.0 * h)
    assert _rel(fd[same], ds.input_torque[same, j], float(np.abs(fd[same]).max())) < 1e-6


def test_a_machine_that_does_not_assemble_is_a_located_error():
    m = sewmech.load_machine("jb1-3")
    with pytest.raises(Exception) as err:
        dynamics_sensitivities(m, PHI, params=m.parameters({"needle_bar.length": 5.0}))
    assert isinstance(err.value, (AnalysisError, sewmech.engine.errors.SewmechError))
    assert "needle_bar" in str(err.value) or "assembl" in str(err.value)


# ---- the compiled derivatives against the complex step through the whole residual -------------


def _machines():
    from test_dynamics import SC_TOML
    from test_physics import JB_PHYSICS, JB_TEXT, SC_LOSSES, with_text

    return {
        "jb1-3 with a counterweight": sewmech.load_machine("jb1-3").with_parameters(
            {"extra.static_moment": 0.6, "input.regulator": math.radians(20.0)}),
        "jb1-3 with torsion and line springs": with_text(JB_TEXT, JB_PHYSICS),
        "jb8-2": sewmech.load_machine("jb8-2"),
        "slider-crank with friction, springs and loads": with_text(SC_TOML, SC_LOSSES),
    }


@pytest.mark.parametrize("which", ["jb1-3 with a counterweight",
                                   "jb1-3 with torsion and line springs", "jb8-2",
                                   "slider-crank with friction, springs and loads"])
def test_the_compiled_derivatives_are_the_complex_step_through_the_whole_residual(which):
    """Every derivative of every quantity by every parameter, from the compiled kernel (each
    term for the parameters that move it, by hand or by the complex step, the block solve)
    against the second implementation: the whole residual in numpy by the complex step, one
    direction per parameter, and a dense solve. The same to 1e-12 of each quantity's largest
    derivative (both are exact: what is left is rounding); the equations at the solution
    vanish in both."""
    from sewmech.engine._dynamic_reference import reference_sensitivities

    m = _machines()[which]
    a = dynamics_sensitivities(m, PHI, rpm=900.0)
    b = reference_sensitivities(m, PHI, rpm=900.0)
    assert a.residual < 1e-9 and b.residual < 1e-9
    for name in ("dX", "input_torque", "shaking_force", "shaking_moment", "bearings_front",
                 "bearings_rear"):
        x, y = getattr(a, name), getattr(b, name)
        if y is None:
            assert x is None
            continue
        scale = float(np.abs(y).max())
        assert scale > 0.0, name
        assert float(np.abs(x - y).max()) <= 1e-12 * scale, (which, name)


def test_the_compiled_derivatives_of_a_batch():
    """Two designs in one call: each design's derivatives equal the reference's."""
    from sewmech.engine._dynamic_reference import reference_sensitivities

    m = sewmech.load_machine("jb1-3")
    P = m.parameters({"take_up.length1": np.array([m.defaults[m.parameter_names.index(
        "take_up.length1")], 1.01 * m.defaults[m.parameter_names.index("take_up.length1")]])})
    a = dynamics_sensitivities(m, PHI, params=P)
    b = reference_sensitivities(m, PHI, params=P)
    for x, y in ((a.dX, b.dX), (a.bearings_rear, b.bearings_rear),
                 (a.input_torque, b.input_torque)):
        assert x.shape == y.shape and x.shape[0] == 2
        assert float(np.abs(x - y).max()) <= 1e-12 * float(np.abs(y).max())
