"""Independent reference for the planar inverse dynamics of a four-bar, computed with Exudyn.

Not a test module itself (pytest collects ``test_*.py`` only): the dynamics test and the
benchmark import it after ``pytest.importorskip("exudyn")``.

Model
-----
Crank-rocker A-B-C-D with frame pivots A and D, crank AB, coupler BC, rocker CD; the
assembly branch puts C to the left of the direction B -> D (at phi = 0, B = A + (AB, 0) and
C has y > 0 for the default data).  The crank angle is prescribed, phi = omega * t
(counter-clockwise positive, phi = 0: B on +x of A).

Each link is one ``ObjectRigidBody2D`` on a ``NodeRigidBody2D`` placed at its centre of mass
and rotated with the link frame (u along A->B, B->C, D->C; v = u turned +90 deg); the joints
are ``RevoluteJoint2D`` (ObjectJointRevolute2D) between ``MarkerBodyPosition`` markers; the
crank angle is prescribed by a ``CoordinateConstraint`` (ObjectConnectorCoordinate) between a
ground coordinate and the crank's rotation coordinate, with ``offsetUserFunction`` = omega*t
(and ``offsetUserFunction_t`` = omega for index-2 solvers).  The Exudyn model is built in SI
units (m, kg, kg*m^2, N, N*m); inputs and outputs are converted at the interface.

Exudyn conventions (determined with a hanging-pendulum probe solved both with SolveStatic
and SolveDynamic, and confirmed by the Newton-Euler self-check below):
* In the DYNAMIC solvers (GeneralizedAlpha, TrapezoidalIndex2) the equations read
  M q'' + ... + C_q^T lambda = f, with C = (marker 1 quantity) - (marker 0 quantity).  Hence
  ``RevoluteJoint2D`` ([m0, m1], C = p1 - p0) reports as ``OutputVariableType.Force`` the two
  Lagrange multipliers = the force ON MARKER 0's body FROM marker 1's body, global x, y (the
  third component is 0); the force on marker 1's body is minus that.
  ``CoordinateConstraint`` ([m0, m1], C = k*v1 - v0 - offset) reports lambda = minus the
  generalised force on the marker-1 coordinate.
* SURPRISE: the STATIC solver (SolveStatic) reports the OPPOSITE sign for the same
  configuration (lambda = force on marker 1's body), so the sign below is only valid for
  SolveDynamic.
Here every joint has marker 1 on the body whose force the interface reports
(A: [ground, crank], B: [crank, coupler], C: [coupler, rocker], D: [ground, rocker]) and the
drive has marker 1 = crank rotation coordinate, so all outputs are -lambda.
"""

from __future__ import annotations

import math
import time

import numpy as np

G_SI = 9.81  # m/s^2, along -y when gravity=True

LINK_NAMES = ("crank", "coupler", "rocker")


# --------------------------------------------------------------------------------------------
# closed-form kinematics (mm, rad, s), independent of sewmech and of Exudyn
# --------------------------------------------------------------------------------------------
def _rot(th):
    c, s = np.cos(th), np.sin(th)
    return np.array([[c, -s], [s, c]]) if np.ndim(th) == 0 else np.stack(
        [np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def _perp(v):
    """Vector(s) turned +90 degrees."""
    v = np.asarray(v, float)
    return np.stack([-v[..., 1], v[..., 0]], -1)


def _cross(r, f):
    return r[..., 0] * f[..., 1] - r[..., 1] * f[..., 0]


def fourbar_kinematics(phi, omega, A=(0.0, 0.0), D=(38.0, 0.0), lengths=(15.0, 40.0, 35.0)):
    """Positions, angles, angular velocities and accelerations at crank angles ``phi``
    (crank at constant ``omega``, rad/s).  Lengths in mm.  Returns a dict of arrays:
    B, C (n, 2) mm; th2, th3, th4 (link angles of u axes); w2, w3, w4 (rad/s);
    al2, al3, al4 (rad/s^2)."""
    phi = np.atleast_1d(np.asarray(phi, float))
    A = np.asarray(A, float)
    D = np.asarray(D, float)
    a, b, c = lengths
    e2 = np.stack([np.cos(phi), np.sin(phi)], -1)
    B = A + a * e2
    d = D - B
    L = np.linalg.norm(d, axis=-1)
    x = (b * b - c * c + L * L) / (2 * L)
    h2 = b * b - x * x
    if np.any(h2 < 0):
        raise ValueError("four-bar cannot be assembled at some crank angle")
    h = np.sqrt(h2)
    ed = d / L[:, None]
    C = B + x[:, None] * ed + h[:, None] * _perp(ed)  # C to the left of B -> D
    th2 = phi
    th3 = np.arctan2(C[:, 1] - B[:, 1], C[:, 0] - B[:, 0])
    th4 = np.arctan2(C[:, 1] - D[1], C[:, 0] - D[0])
    e3 = np.stack([np.cos(th3), np.sin(th3)], -1)
    e4 = np.stack([np.cos(th4), np.sin(th4)], -1)
    # loop: A + a e2 + b e3 = D + c e4  ->  b w3 e3p - c w4 e4p = -a w2 e2p
    w2 = np.full_like(phi, omega)
    M = np.stack([b * _perp(e3), -c * _perp(e4)], -1)  # (n, 2, 2), columns: w3, w4
    rhs = -a * w2[:, None] * _perp(e2)
    w34 = np.linalg.solve(M, rhs[..., None])[..., 0]
    w3, w4 = w34[:, 0], w34[:, 1]
    al2 = np.zeros_like(phi)
    # b al3 e3p - c al4 e4p = a w2^2 e2 + b w3^2 e3 - c w4^2 e4 - a al2 e2p
    rhs = (a * w2[:, None] ** 2 * e2 + b * w3[:, None] ** 2 * e3 - c * w4[:, None] ** 2 * e4
           - a * al2[:, None] * _perp(e2))
    al34 = np.linalg.solve(M, rhs[..., None])[..., 0]
    return dict(phi=phi, A=np.broadcast_to(A, B.shape), B=B, C=C,
                D=np.broadcast_to(D, B.shape),
                th2=th2, th3=th3, th4=th4, w2=w2, w3=w3, w4=w4,
                al2=al2, al3=al34[:, 0], al4=al34[:, 1])


def link_com_kinematics(kin, links):
    """Per link: origin, angle, omega, alpha, and COM position / velocity / acceleration (mm)."""
    out = {}
    origins = {"crank": ("A", "B", "th2", "w2", "al2"),
               "coupler": ("B", "C", "th3", "w3", "al3"),
               "rocker": ("D", "C", "th4", "w4", "al4")}
    # velocity / acceleration of the link origins: A, D fixed; B on the crank
    vB = kin["w2"][:, None] * _perp(kin["B"] - kin["A"])
    aB = (kin["al2"][:, None] * _perp(kin["B"] - kin["A"])
          - kin["w2"][:, None] ** 2 * (kin["B"] - kin["A"]))
    zero = np.zeros_like(vB)
    vel0 = {"A": (zero, zero), "B": (vB, aB), "D": (zero, zero)}
    for name, (o, _, th, w, al) in origins.items():
        m, cu, cv, I = links[name]
        r = np.einsum("nij,j->ni", _rot(kin[th]), np.array([cu, cv], float))
        P0 = kin[o]
        v0, a0 = vel0[o]
        wv, alv = kin[w][:, None], kin[al][:, None]
        out[name] = dict(m=m, I=I, th=kin[th], w=kin[w], al=kin[al], G=P0 + r,
                         vG=v0 + wv * _perp(r), aG=a0 + alv * _perp(r) - wv ** 2 * r)
    return out


# --------------------------------------------------------------------------------------------
# Exudyn model
# --------------------------------------------------------------------------------------------
def solve_fourbar(links, rpm=1000.0, n_per_rev=360, gravity=False,
                  A=(0.0, 0.0), D=(38.0, 0.0), lengths=(15.0, 40.0, 35.0),
                  *, g=G_SI, substeps=16, startup_revs=1, solver="GeneralizedAlpha",
                  spectral_radius=0.6):
    """Inverse dynamics of the crank-rocker with Exudyn; see the module docstring.

    ``links``: {"crank"|"coupler"|"rocker": (m kg, com_u mm, com_v mm, I_zz kg*mm^2 about COM)}.
    Returns numpy arrays over one revolution (after ``startup_revs`` revolutions of start-up)
    at phi_k = 2*pi*k/n_per_rev: "phi" (rad), "torque_Nmm", "F_A", "F_B", "F_C", "F_D" (N,
    shape (n, 2), conventions as in the task: force on crank from frame, on coupler from crank,
    on rocker from coupler, on rocker from frame), and "solve_time_s" (wall time of
    SolveDynamic only).  ``g``: gravity in m/s^2 along -y when ``gravity`` (default 9.81; note
    sewmech.dynamics.GRAVITY is 9.80665, pass ``g=9.80665`` for a like-for-like comparison).
    ``substeps`` time steps per output angle; ``solver`` is
    "GeneralizedAlpha" (index 3, numerical damping ``spectral_radius``) or "TrapezoidalIndex2".
    """
    import exudyn as exu
    from exudyn import itemInterface as ii

    missing = set(LINK_NAMES) - set(links)
    if missing:
        raise ValueError(f"missing link data: {sorted(missing)}")
    n = int(n_per_rev)
    if not (rpm > 0 and n >= 1 and substeps >= 1 and startup_revs >= 1):
        raise ValueError("need rpm > 0, n_per_rev >= 1, substeps >= 1, startup_revs >= 1")
    omega = 2.0 * math.pi * rpm / 60.0  # rad/s
    T_rev = 2.0 * math.pi / omega
    dt_out = T_rev / n
    h = dt_out / substeps
    n_steps = (startup_revs + 1) * n * substeps

    mm = 1e-3
    A_si = np.asarray(A, float) * mm
    D_si = np.asarray(D, float) * mm
    a, b, c = (float(x) for x in lengths)

    # initial pose and (consistent) velocities at t = 0, phi = 0 from the closed form
    kin0 = fourbar_kinematics(np.array([0.0]), omega, A, D, lengths)
    com0 = link_com_kinematics(kin0, links)

    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddObject(ii.ObjectGround())
    node_ground = mbs.AddNode(ii.NodePointGround())

    bodies, nodes, com_local = {}, {}, {}
    for name in LINK_NAMES:
        m, cu, cv, I = (float(x) for x in links[name])
        k = com0[name]
        G = k["G"][0] * mm
        nd = mbs.AddNode(ii.NodeRigidBody2D(
            referenceCoordinates=[G[0], G[1], float(k["th"][0])],
            initialCoordinates=[0.0, 0.0, 0.0],
            initialVelocities=[k["vG"][0, 0] * mm, k["vG"][0, 1] * mm, float(k["w"][0])]))
        bd = mbs.AddObject(ii.ObjectRigidBody2D(mass=m, inertia=I * 1e-6, nodeNumber=nd))
        nodes[name], bodies[name] = nd, bd
        com_local[name] = np.array([cu, cv]) * mm
        if gravity and m != 0.0:
            mG = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=bd, localPosition=[0, 0, 0]))
            mbs.AddLoad(ii.LoadForceVector(markerNumber=mG, loadVector=[0.0, -m * g, 0.0]))

    def body_marker(name, u):
        """Marker at link-frame point (u, 0) mm; body frame origin is the COM."""
        p = np.array([u * mm, 0.0]) - com_local[name]
        return mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=bodies[name],
                                                   localPosition=[p[0], p[1], 0.0]))

    mA0 = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=ground,
                                              localPosition=[A_si[0], A_si[1], 0.0]))
    mD0 = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=ground,
                                              localPosition=[D_si[0], D_si[1], 0.0]))
    joints = {
        # marker 1 = body ON which the reported force acts (reported as -lambda, see top)
        "F_A": mbs.AddObject(ii.RevoluteJoint2D(markerNumbers=[mA0, body_marker("crank", 0.0)])),
        "F_B": mbs.AddObject(ii.RevoluteJoint2D(markerNumbers=[body_marker("crank", a),
                                                               body_marker("coupler", 0.0)])),
        "F_C": mbs.AddObject(ii.RevoluteJoint2D(markerNumbers=[body_marker("coupler", b),
                                                               body_marker("rocker", c)])),
        "F_D": mbs.AddObject(ii.RevoluteJoint2D(markerNumbers=[mD0, body_marker("rocker", 0.0)])),
    }

    # prescribed crank angle: (rotation coordinate of crank node) - 0 - omega*t = 0;
    # the node's reference angle is 0 (= phi at t = 0), so its coordinate is phi itself
    m_gc = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=node_ground, coordinate=0))
    m_cc = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=nodes["crank"], coordinate=2))

    def uf_offset(mbs_, t, itemNumber, lOffset):
        return omega * t

    def uf_offset_t(mbs_, t, itemNumber, lOffset):
        return omega

    drive = mbs.AddObject(ii.CoordinateConstraint(markerNumbers=[m_gc, m_cc],
                                                  offsetUserFunction=uf_offset,
                                                  offsetUserFunction_t=uf_offset_t))

    ovt = exu.OutputVariableType.Force
    sensors = {key: mbs.AddSensor(ii.SensorObject(objectNumber=obj, outputVariableType=ovt,
                                                  storeInternal=True, writeToFile=False))
               for key, obj in joints.items()}
    sensors["torque"] = mbs.AddSensor(ii.SensorObject(objectNumber=drive, outputVariableType=ovt,
                                                      storeInternal=True, writeToFile=False))
    mbs.Assemble()

    ss = exu.SimulationSettings()
    ss.solution.file.write = False
    ss.solution.sensors.writePeriod = h * 0.5  # every step; the samples are picked by time
    ss.solution.solverInformationFileName = ""
    ss.timeIntegration.verboseMode = 0
    ss.timeIntegration.verboseModeFile = 0
    ss.timeIntegration.startTime = 0.0
    ss.timeIntegration.endTime = n_steps * h
    ss.timeIntegration.numberOfSteps = n_steps
    ss.timeIntegration.automaticStepSize = False
    ss.timeIntegration.adaptiveStep = False
    ss.timeIntegration.newton.useModifiedNewton = False
    ss.timeIntegration.newton.relativeTolerance = 1e-12
    ss.timeIntegration.newton.absoluteTolerance = 1e-14
    if solver == "GeneralizedAlpha":
        ss.timeIntegration.generalizedAlpha.spectralRadius = spectral_radius
        stype = exu.DynamicSolverType.GeneralizedAlpha
    elif solver == "TrapezoidalIndex2":
        stype = exu.DynamicSolverType.TrapezoidalIndex2
    else:
        raise ValueError(f"unknown solver {solver!r}")
    ss.show.statistics = False
    ss.show.computationTime = False
    ss.show.globalTimers = False

    t0 = time.perf_counter()
    ok = mbs.SolveDynamic(ss, solverType=stype)
    solve_time = time.perf_counter() - t0
    if ok is False:
        raise RuntimeError("Exudyn SolveDynamic failed")

    # pick the samples of the last revolution at t_k = startup_revs*T + k*dt_out
    t_k = startup_revs * T_rev + np.arange(n) * dt_out
    data = {key: np.asarray(mbs.GetSensorStoredData(s)) for key, s in sensors.items()}
    times = data["torque"][:, 0]
    idx = np.searchsorted(times, t_k - 0.25 * h)
    if np.any(idx >= len(times)) or np.max(np.abs(times[idx] - t_k)) > 1e-3 * h:
        raise RuntimeError("sensor samples do not hit the output angles")
    phi = (2.0 * math.pi * np.arange(n) / n)
    out = {"phi": phi,
           # dynamic-solver sign: generalised force on the marker-1 coordinate = -lambda
           "torque_Nmm": -data["torque"][idx, 1] * 1e3}
    for key in joints:
        out[key] = -data[key][idx, 1:3]  # force on marker 1's body = -lambda
    out["solve_time_s"] = solve_time
    return out


# --------------------------------------------------------------------------------------------
# self-checks
# --------------------------------------------------------------------------------------------
def newton_euler_residuals(res, links, rpm=1000.0, gravity=False,
                           A=(0.0, 0.0), D=(38.0, 0.0), lengths=(15.0, 40.0, 35.0), g=G_SI):
    """Relative residuals of Newton's and Euler's laws per link, with the closed-form
    kinematics (SI internally).  Returns {link: (force_residual, moment_residual)} (max over
    samples, relative to the largest force / moment magnitude involved) and the power-balance
    residual under key "power"."""
    omega = 2.0 * math.pi * rpm / 60.0
    kin = fourbar_kinematics(res["phi"], omega, A, D, lengths)
    com = link_com_kinematics(kin, links)
    mm = 1e-3
    gv = np.array([0.0, -g]) if gravity else np.zeros(2)
    FA, FB, FC, FD = res["F_A"], res["F_B"], res["F_C"], res["F_D"]
    T = res["torque_Nmm"] * mm  # N*m
    P = {k: kin[k] * mm for k in "ABCD"}
    out = {}

    def check(name, forces, torque):
        k = com[name]
        m, I = k["m"], k["I"] * 1e-6
        G, aG = k["G"] * mm, k["aG"] * mm
        Fsum = sum(F for F, _ in forces) + m * gv
        Msum = sum(_cross(p - G, F) for F, p in forces) + torque
        r_f = Fsum - m * aG
        r_m = Msum - I * k["al"]
        f_scale = max(max(np.abs(F).max() for F, _ in forces), np.abs(m * aG).max(), 1e-30)
        m_scale = max(max(np.abs(_cross(p - G, F)).max() for F, p in forces),
                      np.abs(torque).max(), np.abs(I * k["al"]).max(), 1e-30)
        out[name] = (np.abs(r_f).max() / f_scale, np.abs(r_m).max() / m_scale)

    check("crank", [(FA, P["A"]), (-FB, P["B"])], T)
    check("coupler", [(FB, P["B"]), (-FC, P["C"])], 0.0)
    check("rocker", [(FC, P["C"]), (FD, P["D"])], 0.0)
    # power balance: T*omega = dE/dt
    dE = 0.0
    for name in LINK_NAMES:
        k = com[name]
        m, I = k["m"], k["I"] * 1e-6
        vG, aG = k["vG"] * mm, k["aG"] * mm
        dE = dE + m * np.sum(vG * aG, -1) + I * k["w"] * k["al"] - m * np.sum(gv * vG, -1)
    p_in = T * omega
    out["power"] = np.abs(p_in - dE).max() / max(np.abs(p_in).max(), np.abs(dE).max())
    return out


def closed_form_inverse_dynamics(phi, links, rpm=1000.0, gravity=False,
                                 A=(0.0, 0.0), D=(38.0, 0.0), lengths=(15.0, 40.0, 35.0),
                                 g=G_SI):
    """Exact inverse dynamics from the closed-form kinematics: solves the 9 x 9 linear
    Newton-Euler system per sample for F_A, F_B, F_C, F_D, torque (same conventions and units as
    ``solve_fourbar``).  Used by the self-check to measure Exudyn's discretisation error."""
    omega = 2.0 * math.pi * rpm / 60.0
    phi = np.atleast_1d(np.asarray(phi, float))
    kin = fourbar_kinematics(phi, omega, A, D, lengths)
    com = link_com_kinematics(kin, links)
    mm = 1e-3
    gv = np.array([0.0, -g]) if gravity else np.zeros(2)
    # per link: [(joint index 0..3 = A,B,C,D, sign, point)], has driving torque
    layout = [("crank", [(0, 1.0, "A"), (1, -1.0, "B")], True),
              ("coupler", [(1, 1.0, "B"), (2, -1.0, "C")], False),
              ("rocker", [(2, 1.0, "C"), (3, 1.0, "D")], False)]
    sol = np.empty((len(phi), 9))
    for k in range(len(phi)):
        M = np.zeros((9, 9))
        r = np.zeros(9)
        for row, (name, terms, driven) in zip((0, 3, 6), layout):
            c = com[name]
            G = c["G"][k] * mm
            for j, sgn, p in terms:
                rp = kin[p][k] * mm - G
                M[row:row + 2, 2 * j:2 * j + 2] += sgn * np.eye(2)
                M[row + 2, 2 * j:2 * j + 2] += sgn * np.array([-rp[1], rp[0]])  # rp x F
            if driven:
                M[row + 2, 8] = 1.0
            r[row:row + 2] = c["m"] * (c["aG"][k] * mm - gv)
            r[row + 2] = c["I"] * 1e-6 * c["al"][k]
        sol[k] = np.linalg.solve(M, r)
    return {"phi": phi, "F_A": sol[:, 0:2], "F_B": sol[:, 2:4], "F_C": sol[:, 4:6],
            "F_D": sol[:, 6:8], "torque_Nmm": sol[:, 8] * 1e3}


TEST_LINKS = {"crank": (0.05, 7.5, 0.0, 1.2),
              "coupler": (0.08, 20.0, 2.0, 12.0),
              "rocker": (0.07, 17.5, -1.0, 8.0)}


if __name__ == "__main__":
    import exudyn as exu

    print("exudyn", exu.__version__)
    kin = fourbar_kinematics(np.array([0.0]), 1.0)
    print("C at phi=0:", kin["C"][0], "(y must be > 0)")
    ok = True
    for gravity in (False, True):
        res = solve_fourbar(TEST_LINKS, rpm=1000.0, n_per_rev=360, gravity=gravity)
        r = newton_euler_residuals(res, TEST_LINKS, rpm=1000.0, gravity=gravity)
        print(f"\ngravity={gravity}: solve_time_s = {res['solve_time_s']:.3f}")
        for name in LINK_NAMES:
            print(f"  {name:8s} force residual {r[name][0]:.2e}   moment residual {r[name][1]:.2e}")
            ok &= r[name][0] < 1e-5 and r[name][1] < 1e-5
        print(f"  power balance residual {r['power']:.2e}")
        ok &= r["power"] < 1e-5
        ex = closed_form_inverse_dynamics(res["phi"], TEST_LINKS, rpm=1000.0, gravity=gravity)
        errs = {k: np.abs(res[k] - ex[k]).max() / np.abs(ex[k]).max()
                for k in ("torque_Nmm", "F_A", "F_B", "F_C", "F_D")}
        print("  max rel. error vs closed-form inverse dynamics: "
              + ", ".join(f"{k} {v:.2e}" for k, v in errs.items()))
        ok &= max(errs.values()) < 1e-5
        print(f"  torque range [{res['torque_Nmm'].min():.4f}, {res['torque_Nmm'].max():.4f}] N*mm,"
              f" |F_A| max {np.linalg.norm(res['F_A'], axis=1).max():.4f} N")
        print("  phi=0: torque %.6f N*mm, F_A %s, F_B %s, F_C %s, F_D %s" % (
            res["torque_Nmm"][0], res["F_A"][0], res["F_B"][0], res["F_C"][0], res["F_D"][0]))
    print("\nALL SELF-CHECKS PASSED" if ok else "\nSELF-CHECK FAILED")
