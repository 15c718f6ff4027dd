"""Independent reference for the run in time: the benchmark four-bar's forward dynamics in Exudyn.

Not a test module itself (pytest collects ``test_*.py`` only): tests/test_running.py imports it
after ``pytest.importorskip("exudyn")``.

The crank-rocker of tests/exudyn_fourbar.py (the same bodies, joints, closed-form initial pose
and Exudyn conventions), but with the crank free: it starts from rest at phi = 0 and is driven
by a constant torque about z (a ``LoadTorqueVector`` on the crank's body) against a viscous
torque -c omega (an ``ObjectConnectorCoordinateSpringDamper`` of stiffness 0 between a ground
coordinate and the crank's rotation coordinate), with gravity along -y. Extra inertia on the
crank (a hand wheel, a motor's rotor through a belt) is added to the crank body's own. The
equations are Exudyn's redundant coordinates with the joints as constraints (index 3), solved
by its generalized-alpha integrator without numerical damping (spectral radius 1: the
trapezoidal rule) at a fixed step; sewmech integrates one coordinate with its reduced inertia.
"""

from __future__ import annotations

import math
import time

import numpy as np

from exudyn_fourbar import LINK_NAMES, fourbar_kinematics, link_com_kinematics


def run_fourbar(links, torque_Nmm, damping_Nmm_s, t_end, h, *, crank_extra_inertia=0.0,
                gravity=True, g=9.81, A=(0.0, 0.0), D=(38.0, 0.0), lengths=(15.0, 40.0, 35.0),
                spectral_radius=0.9):
    """The crank angle phi(t) (rad) and speed omega(t) (rad/s) at t = k h, k = 0 .. t_end / h,
    from rest at phi = 0.

    ``links``: {"crank"|"coupler"|"rocker": (m kg, com_u mm, com_v mm, I_zz kg mm^2)};
    ``torque_Nmm`` the constant driving torque, ``damping_Nmm_s`` c of the viscous torque
    -c omega (N mm per rad/s), ``crank_extra_inertia`` kg mm^2 added to the crank's I_zz.
    Returns {"t", "phi", "omega", "solve_time_s"}."""
    import exudyn as exu
    from exudyn import itemInterface as ii

    mm = 1e-3
    A_si = np.asarray(A, float) * mm
    D_si = np.asarray(D, float) * mm
    a, b, c = (float(x) for x in lengths)
    kin0 = fourbar_kinematics(np.array([0.0]), 0.0, A, D, lengths)
    com0 = link_com_kinematics(kin0, links)

    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddObject(ii.ObjectGround())
    node_ground = mbs.AddNode(ii.NodePointGround())
    bodies, nodes, com_local = {}, {}, {}
    for name in LINK_NAMES:
        m, cu, cv, izz = (float(x) for x in links[name])
        if name == "crank":
            izz += crank_extra_inertia
        k = com0[name]
        G = k["G"][0] * mm
        nd = mbs.AddNode(ii.NodeRigidBody2D(referenceCoordinates=[G[0], G[1], float(k["th"][0])],
                                            initialCoordinates=[0.0, 0.0, 0.0],
                                            initialVelocities=[0.0, 0.0, 0.0]))
        bd = mbs.AddObject(ii.ObjectRigidBody2D(mass=m, inertia=izz * 1e-6, nodeNumber=nd))
        nodes[name], bodies[name] = nd, bd
        com_local[name] = np.array([cu, cv]) * mm
        if gravity and m != 0.0:
            mG = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=bd, localPosition=[0, 0, 0]))
            mbs.AddLoad(ii.LoadForceVector(markerNumber=mG, loadVector=[0.0, -m * g, 0.0]))

    def body_marker(name, u):
        p = np.array([u * mm, 0.0]) - com_local[name]
        return mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=bodies[name],
                                                   localPosition=[p[0], p[1], 0.0]))

    mA0 = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=ground,
                                              localPosition=[A_si[0], A_si[1], 0.0]))
    mD0 = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=ground,
                                              localPosition=[D_si[0], D_si[1], 0.0]))
    mbs.AddObject(ii.RevoluteJoint2D(markerNumbers=[mA0, body_marker("crank", 0.0)]))
    mbs.AddObject(ii.RevoluteJoint2D(markerNumbers=[body_marker("crank", a),
                                                    body_marker("coupler", 0.0)]))
    mbs.AddObject(ii.RevoluteJoint2D(markerNumbers=[body_marker("coupler", b),
                                                    body_marker("rocker", c)]))
    mbs.AddObject(ii.RevoluteJoint2D(markerNumbers=[mD0, body_marker("rocker", 0.0)]))
    # the drive: a constant torque on the crank, and the viscous torque on its rotation
    m_body = mbs.AddMarker(ii.MarkerBodyRigid(bodyNumber=bodies["crank"],
                                              localPosition=[0.0, 0.0, 0.0]))
    mbs.AddLoad(ii.LoadTorqueVector(markerNumber=m_body,
                                    loadVector=[0.0, 0.0, torque_Nmm * mm]))
    m_gc = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=node_ground, coordinate=0))
    m_cc = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=nodes["crank"], coordinate=2))
    mbs.AddObject(ii.CoordinateSpringDamper(markerNumbers=[m_gc, m_cc], stiffness=0.0,
                                            damping=damping_Nmm_s * mm))
    s_q = mbs.AddSensor(ii.SensorNode(nodeNumber=nodes["crank"],
                                      outputVariableType=exu.OutputVariableType.Coordinates,
                                      storeInternal=True, writeToFile=False))
    s_v = mbs.AddSensor(ii.SensorNode(nodeNumber=nodes["crank"],
                                      outputVariableType=exu.OutputVariableType.Coordinates_t,
                                      storeInternal=True, writeToFile=False))
    mbs.Assemble()

    n_steps = int(round(t_end / h))
    ss = exu.SimulationSettings()
    ss.solution.file.write = False
    ss.solution.sensors.writePeriod = h * 0.5  # every step
    ss.solution.solverInformationFileName = ""
    ss.timeIntegration.verboseMode = 0
    ss.timeIntegration.verboseModeFile = 0
    ss.timeIntegration.startTime = 0.0
    ss.timeIntegration.endTime = n_steps * h
    ss.timeIntegration.numberOfSteps = n_steps
    ss.timeIntegration.automaticStepSize = False
    ss.timeIntegration.adaptiveStep = False
    ss.timeIntegration.newton.useModifiedNewton = False
    ss.timeIntegration.newton.relativeTolerance = 1e-13
    ss.timeIntegration.newton.absoluteTolerance = 1e-15
    ss.timeIntegration.generalizedAlpha.spectralRadius = spectral_radius
    ss.show.statistics = False
    ss.show.computationTime = False
    ss.show.globalTimers = False
    t0 = time.perf_counter()
    ok = mbs.SolveDynamic(ss, solverType=exu.DynamicSolverType.GeneralizedAlpha)
    solve_time = time.perf_counter() - t0
    if ok is False:
        raise RuntimeError("Exudyn SolveDynamic failed")
    q = np.asarray(mbs.GetSensorStoredData(s_q))
    v = np.asarray(mbs.GetSensorStoredData(s_v))
    t_k = np.arange(n_steps + 1) * h
    idx = np.searchsorted(q[:, 0], t_k - 0.25 * h)
    idx = np.minimum(idx, len(q) - 1)
    if np.max(np.abs(q[idx, 0] - t_k)) > 1e-3 * h:
        raise RuntimeError("sensor samples do not hit the steps")
    # the crank node's reference angle is 0 (phi = 0 at the start): its coordinate is phi
    return {"t": t_k, "phi": q[idx, 3], "omega": v[idx, 3], "solve_time_s": solve_time}


if __name__ == "__main__":  # the reference's own convergence: halving the step
    from exudyn_fourbar import TEST_LINKS

    for h in (2e-5, 1e-5, 5e-6):
        r = run_fourbar(TEST_LINKS, 50.0, 0.3, 0.3, h, crank_extra_inertia=10.0)
        print(f"h = {h:g}: phi(0.3 s) = {r['phi'][-1]:.12f} rad, omega = {r['omega'][-1]:.10f}"
              f" rad/s ({r['solve_time_s']:.2f} s)")
    print(math.pi)
