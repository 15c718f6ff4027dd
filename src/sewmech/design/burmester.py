"""Motion generation (Burmester) and timed path generation of four-bars.

A pose is (x, y, angle): a body's reference point P at (x, y) mm and the body's u axis at
``angle`` rad. A dyad guides the body: its circle point M, fixed on the body (u, v in the
body's frame), moves on a circle about its centre point K on the frame. Two dyads make the
four-bar: the input link K1 -> M1, the coupler M1 -> M2 carrying the body, the output link
K2 -> M2.

- Three poses: any circle point will do (a free choice); its centre is the circumcentre of its
  three positions (:func:`centre_point`).
- Four poses: the circle points lie on Burmester's circle-point curve and their centres on the
  centre-point curve. With the dyad equation W (e^{i beta_j} - 1) + Z (e^{i alpha_j} - 1) =
  delta_j (j = 2..4, alpha_j the body's rotations, delta_j P's displacements from pose 1), the
  compatibility condition sum_j Delta_j e^{i beta_j} = 0 (Delta_1..4 the cofactors of the
  3 x 4 matrix [e^{i beta} - 1, e^{i alpha} - 1, delta] extended by the unit column) is a
  triangle closure: each choice of beta_2 gives two (beta_3, beta_4), each one dyad
  (:func:`burmester_curves`).
- Choosing two dyads: every pair is built and checked for the defects of classical synthesis
  (:func:`choose_pair`): the poses on one assembly branch (the branch defect), the input
  passing through them in order (the order defect), an input that turns fully where one is
  asked for (Grashof), and the least transmission angle over the motion; the pair with the
  largest least transmission angle is taken, the criterion stated.

Timed path generation (:func:`path_start`): the coupler point through points at given input
angles; three of them fix a four-bar exactly once the coupler's and the output's rotations are
chosen (free choices, scanned); that four-bar starts the optimiser (:mod:`sewmech.design.optimize`,
exact gradients) over all the points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .synthesis import TWO_PI, FourBar, SynthesisError, grashof


def _rot(theta) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def pose_points(poses: np.ndarray, m: np.ndarray) -> np.ndarray:
    """The positions (n, 2) of the body point ``m`` (u, v) in each pose of ``poses`` (n, 3)."""
    P = np.asarray(poses, dtype=float)
    c, s = np.cos(P[:, 2]), np.sin(P[:, 2])
    return P[:, :2] + np.stack([c * m[0] - s * m[1], s * m[0] + c * m[1]], axis=-1)


def centre_point(q: np.ndarray, where: str = "poses") -> np.ndarray:
    """The centre (2,) of the circle through the three points ``q`` (3, 2); a located error
    when they are (nearly) on one line (the centre would be at infinity: a slider)."""
    q = np.asarray(q, dtype=float)
    a, b, c = q
    d = 2.0 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    scale = max(np.ptp(q[:, 0]), np.ptp(q[:, 1]), 1e-300)
    if abs(d) <= 1e-9 * scale * scale:
        raise SynthesisError(where, "the circle point's three positions lie on one line (or"
                             " two coincide): its centre is at infinity", "Choose another"
                             " circle point")
    b2, c2 = b - a, c - a
    ux = (c2[1] * (b2 @ b2) - b2[1] * (c2 @ c2)) / d
    uy = (b2[0] * (c2 @ c2) - c2[0] * (b2 @ b2)) / d
    return a + np.array([ux, uy])


def check_poses(poses, n: int, where: str = "poses") -> np.ndarray:
    P = np.asarray(poses, dtype=float)
    if P.shape != (n, 3) or not np.all(np.isfinite(P)):
        raise SynthesisError(where, f"needs {n} poses of three finite numbers (x mm, y mm, angle"
                             f" deg), got {P.shape[0] if P.ndim else 0}", "Give each pose as"
                             " X,Y,ANGLE_DEG")
    for i in range(n):
        for j in range(i):
            same = (np.hypot(*(P[i, :2] - P[j, :2])) < 1e-9 and
                    abs(np.angle(np.exp(1j * (P[i, 2] - P[j, 2])))) < 1e-12)
            if same:
                raise SynthesisError(where, f"poses {j + 1} and {i + 1} coincide", "Give"
                                     " distinct poses: each must move the body")
    return P


@dataclass(frozen=True)
class Dyad:
    """A guiding dyad: centre point K (frame, mm), circle point m (body frame, mm), and its
    circle point's position in pose 1, M1 (mm)."""

    K: np.ndarray
    m: np.ndarray
    M1: np.ndarray


def three_pose_dyad(poses, m, where: str = "--circle-point") -> Dyad:
    """The dyad whose circle point is ``m`` (u, v, body frame, mm) for three poses (3, 3 with
    the angle in rad)."""
    P = check_poses(poses, 3)
    q = pose_points(P, np.asarray(m, dtype=float))
    K = centre_point(q, where)
    return Dyad(K, np.asarray(m, dtype=float), q[0])


@dataclass(frozen=True)
class BurmesterCurves:
    """The centre-point and circle-point curves of four poses, sampled: beta2 (k,) rad, the
    input rotation from pose 1 to 2; centre (k, 2) and circle (k, 2, in the frame, pose 1);
    m (k, 2) the circle points in the body frame; branch (k,) which of the two triangle
    closures; residual (k,) the dyad equation's residual at pose 4 (mm)."""

    beta2: np.ndarray
    centre: np.ndarray
    circle: np.ndarray
    m: np.ndarray
    branch: np.ndarray
    residual: np.ndarray


def burmester_curves(poses, samples: int = 720) -> BurmesterCurves:
    """Burmester's curves of four poses (4, 3; angles rad), one dyad per (beta2, branch)."""
    P = check_poses(poses, 4)
    z = P[:, 0] + 1j * P[:, 1]
    delta = z[1:] - z[0]
    ea = np.exp(1j * (P[1:, 2] - P[0, 2])) - 1.0
    # the 4 x 3 matrix [e^{i beta} ; e^{i alpha} - 1 ; delta] with rows j = 1..4 (j = 1: the
    # trivial row 1, 0, 0 from beta_1 = 0 written as the unit column): sum_j Delta_j e^{i beta_j}
    # = 0 with Delta_j the signed 3 x 3 minors of [ea ; delta] augmented
    A = np.zeros((4, 3), dtype=complex)
    A[:, 0] = 1.0
    A[1:, 1] = ea
    A[1:, 2] = delta
    Dl = np.array([(-1) ** j * np.linalg.det(np.delete(A, j, axis=0)) for j in range(4)])
    # the cofactor form: sum_j Dl_j (e^{i beta_j}) = 0 over the first column [1, e^{ib2}, ...]
    out = {k: [] for k in ("beta2", "centre", "circle", "m", "branch", "residual")}
    R1 = np.array(_rot(P[0, 2]))
    for b2 in np.linspace(0.0, TWO_PI, samples, endpoint=False)[1:]:
        rhs = -(Dl[0] + Dl[1] * np.exp(1j * b2))
        r3, r4 = abs(Dl[2]), abs(Dl[3])
        L = abs(rhs)
        if L == 0.0 or r3 == 0.0 or r4 == 0.0:
            continue
        # u + v = rhs, |u| = r3, |v| = r4: u at the two intersections of two circles
        x = (r3 * r3 - r4 * r4 + L * L) / (2.0 * L)
        h2 = r3 * r3 - x * x
        if h2 < 0.0:
            continue
        e = rhs / L
        for br in (1, -1):
            u = e * (x + 1j * br * math.sqrt(h2))
            b3 = np.angle(u / Dl[2])
            b4 = np.angle((rhs - u) / Dl[3])
            beta = np.array([b2, b3, b4])
            M = np.array([[np.exp(1j * beta[0]) - 1.0, ea[0]], [np.exp(1j * beta[1]) - 1.0,
                                                               ea[1]]])
            if abs(np.linalg.det(M)) < 1e-12:
                continue
            W, Z = np.linalg.solve(M, delta[:2])
            res = abs(W * (np.exp(1j * beta[2]) - 1.0) + Z * ea[2] - delta[2])
            M1 = z[0] - Z
            K = M1 - W
            if abs(W) < 1e-9 or not np.isfinite(K):
                continue
            mloc = R1.T @ np.array([(M1 - z[0]).real, (M1 - z[0]).imag])
            out["beta2"].append(b2)
            out["centre"].append([K.real, K.imag])
            out["circle"].append([M1.real, M1.imag])
            out["m"].append(mloc)
            out["branch"].append(br)
            out["residual"].append(res)
    if not out["beta2"]:
        raise SynthesisError("poses", "the four poses have no Burmester points (no circle point"
                             " moves on a circle through them)", "Change the poses")
    return BurmesterCurves(*(np.array(out[k]) for k in ("beta2", "centre", "circle", "m",
                                                          "branch", "residual")))


@dataclass(frozen=True)
class MotionSynthesis:
    """A four-bar that carries a body through given poses. fourbar : the linkage (its coupler
    point P is the body's reference point); body_offset : body angle minus coupler angle, rad;
    input_deg : the input angle at each pose; ratio : +1 (the input turns counter-clockwise
    through the poses in order) or -1; drive : "shaft" (the input turns fully) or "setting";
    grashof, min_transmission_deg : over the motion; dyads : the two chosen; curves : the
    Burmester curves (four poses) or None; candidates : how many dyad pairs were tried and
    how many were free of defects; notes : the free choices and findings."""

    fourbar: FourBar
    poses: np.ndarray
    body_offset: float
    input_deg: np.ndarray
    ratio: int
    drive: str
    grashof: object
    min_transmission_deg: float
    dyads: tuple[Dyad, Dyad]
    curves: BurmesterCurves | None
    candidates: tuple[int, int]
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def phi_deg(self) -> np.ndarray:
        """The shaft angles (or input settings) at which the machine file is in each pose."""
        if self.drive == "shaft":
            return np.mod(self.ratio * (self.input_deg - self.input_deg[0]), 360.0)
        return self.input_deg


def _pair_checks(K1, m1, K2, m2, poses, need_crank: bool, grid: int = 181):
    """Vectorised over candidate pairs (n,): the four-bar of input dyad (K1, m1) and output
    dyad (K2, m2). Returns a dict of arrays: ok (free of defects), branch, ratio, mu_min (deg),
    crank (the input turns fully), input angles (n, poses)."""
    P = np.asarray(poses, dtype=float)
    n = K1.shape[0]
    c, s = np.cos(P[:, 2]), np.sin(P[:, 2])

    def pts(m):
        return P[None, :, :2] + np.stack([c[None] * m[:, None, 0] - s[None] * m[:, None, 1],
                                          s[None] * m[:, None, 0] + c[None] * m[:, None, 1]],
                                         -1)

    B = pts(m1)
    C = pts(m2)
    a = np.linalg.norm(B[:, 0] - K1, axis=-1)
    b = np.linalg.norm(C[:, 0] - B[:, 0], axis=-1)
    cc = np.linalg.norm(C[:, 0] - K2, axis=-1)
    d = np.linalg.norm(K2 - K1, axis=-1)
    DB = K2[:, None] - B
    CB = C - B
    side = np.sign(DB[..., 0] * CB[..., 1] - DB[..., 1] * CB[..., 0])
    branch_ok = np.all(side == side[:, :1], axis=1) & (side[:, 0] != 0)
    th = np.arctan2(B[..., 1] - K1[:, None, 1], B[..., 0] - K1[:, None, 0])
    rel = np.mod(th - th[:, :1], TWO_PI)
    inc = np.all(np.diff(rel, axis=1) > 1e-9, axis=1)
    rel_neg = np.mod(th[:, :1] - th, TWO_PI)
    dec = np.all(np.diff(rel_neg, axis=1) > 1e-9, axis=1)
    ratio = np.where(inc, 1, np.where(dec, -1, 0))
    sl = np.sort(np.stack([a, b, cc, d], -1), -1)
    grash = sl[:, 0] + sl[:, 3] < sl[:, 1] + sl[:, 2] - 1e-9 * sl[:, 3]
    shortest_in = (np.minimum(a, d) <= np.minimum(b, cc))
    crank = grash & shortest_in
    # the motion: the whole turn for a crank, else from the first pose to the last
    span = np.where(crank, TWO_PI, np.where(ratio > 0, rel[:, -1], rel_neg[:, -1]))
    t = np.linspace(0.0, 1.0, grid)
    ang = th[:, :1] + np.where(ratio[:, None] < 0, -1.0, 1.0) * span[:, None] * t[None]
    Bg = K1[:, None] + a[:, None, None] * np.stack([np.cos(ang), np.sin(ang)], -1)
    dv = K2[:, None] - Bg
    dd2 = np.sum(dv * dv, -1)
    dd = np.sqrt(dd2)
    along = (b[:, None] ** 2 - cc[:, None] ** 2 + dd2) / (2 * dd)
    h2 = b[:, None] ** 2 - along ** 2
    assembles = np.all(h2 > 1e-12 * (b[:, None] ** 2), axis=1)
    br = side[:, 0]
    e = dv / dd[..., None]
    h = br[:, None] * np.sqrt(np.maximum(h2, 0.0))
    Cg = Bg + along[..., None] * e + h[..., None] * np.stack([-e[..., 1], e[..., 0]], -1)
    u = Cg - Bg
    w = Cg - K2[:, None]
    cosm = np.sum(u * w, -1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(w, axis=-1))
    mu = np.degrees(np.arccos(np.clip(cosm, -1, 1)))
    mu_min = np.min(np.minimum(mu, 180 - mu), axis=1)
    ok = branch_ok & (ratio != 0) & assembles & np.all(np.isfinite(K1) & np.isfinite(K2), 1)
    if need_crank:
        ok &= crank
    ok &= (a > 1e-6) & (cc > 1e-6) & (b > 1e-6) & (d > 1e-6)
    return {"ok": ok, "branch": side[:, 0].astype(int), "ratio": ratio, "mu_min": mu_min,
            "crank": crank, "theta2": th, "a": a, "b": b, "c": cc, "d": d, "n": n}


#: the longest link of a chosen four-bar at most this many times its shortest, and every link
#: within this factor of the poses' spread, where any pair allows it (a link of a millimetre
#: beside one of a metre, or a linkage far smaller than its motion, cannot be made)
PROPORTION = 8.0
#: ... and a least transmission angle over the motion of at least this, deg (the usual design
#: rule: below it the coupler pushes the output more along it than round its pivot)
MIN_TRANSMISSION_DEG = 30.0


def choose_pair(dyads_K: np.ndarray, dyads_m: np.ndarray, poses, *, prefer_crank: bool = True,
                max_pairs: int = 40000, where: str = "poses") -> tuple[int, int, dict, tuple]:
    """The best pair (input i, output j) of the candidate dyads (centre points (n, 2), circle
    points (n, 2) in the body frame): free of the branch and order defects, assembling over
    the motion (the whole turn when its input is a crank); preferred in this order: a crank
    input in proportion (links within :data:`PROPORTION` of one another and of the poses'
    spread, a least transmission angle of :data:`MIN_TRANSMISSION_DEG`), a lever input so, a
    crank, a lever; then the largest least transmission angle. Returns (i, j, the checks of
    that pair, (pairs tried, pairs free of defects))."""
    K = np.asarray(dyads_K, dtype=float)
    M = np.asarray(dyads_m, dtype=float)
    n = len(K)
    if n < 2:
        raise SynthesisError(where, "fewer than two dyads to choose from", "Change the poses")
    stride = max(1, int(math.ceil(n * (n - 1) / max_pairs)))
    ii, jj = np.nonzero(~np.eye(n, dtype=bool))
    ii, jj = ii[::stride], jj[::stride]
    far = np.linalg.norm(K[ii] - K[jj], axis=-1) > 1e-6 * (1 + np.abs(K).max())
    ii, jj = ii[far], jj[far]
    best = None
    results = {need: _pair_checks(K[ii], M[ii], K[jj], M[jj], poses, need)
               for need in ((True, False) if prefer_crank else (False,))}
    usable = max(int(r["ok"].sum()) for r in results.values())
    Pp = np.asarray(poses, dtype=float)
    sp = max(float(np.ptp(Pp[:, 0])), float(np.ptp(Pp[:, 1])), 1e-9)
    # preference: a crank input in proportion, a lever in proportion, a crank, a lever
    for sane_only in (True, False):
        for r in results.values():
            L = np.stack([r["a"], r["b"], r["c"], r["d"]], -1)
            sane = ((L.max(-1) <= PROPORTION * L.min(-1)) & (L.min(-1) >= sp / PROPORTION)
                    & (L.max(-1) <= PROPORTION * sp) & (r["mu_min"] >= MIN_TRANSMISSION_DEG))
            pick = r["ok"] & (sane | (not sane_only))
            if pick.any():
                k = int(np.argmax(np.where(pick, r["mu_min"], -1.0)))
                best = (int(ii[k]), int(jj[k]), {key: (v[k] if isinstance(v, np.ndarray)
                                                       else v) for key, v in r.items()})
                break
        if best is not None:
            break
    if best is None:
        raise SynthesisError(where, f"none of the {len(ii)} four-bars built from pairs of the"
                             " dyads reaches the poses in order on one assembly branch"
                             " (every pair has a branch or an order defect, or a dead centre"
                             " between the poses)", "Change the poses, or give other circle"
                             " points")
    return best[0], best[1], best[2], (len(ii), usable)


def _fourbar_of(d1: Dyad, d2: Dyad, poses, branch: int) -> tuple[FourBar, float]:
    """The four-bar of an input dyad d1 and an output dyad d2 with the body's reference point
    as coupler point; and the body angle minus the coupler angle."""
    P = np.asarray(poses, dtype=float)
    B1, C1 = d1.M1, d2.M1
    a = float(np.hypot(*(B1 - d1.K)))
    b = float(np.hypot(*(C1 - B1)))
    c = float(np.hypot(*(C1 - d2.K)))
    th3 = math.atan2(C1[1] - B1[1], C1[0] - B1[0])
    rel = _rot(th3).T @ (P[0, :2] - B1)
    fb = FourBar((float(d1.K[0]), float(d1.K[1])), (float(d2.K[0]), float(d2.K[1])), a, b, c,
                 a, c, int(branch), (float(rel[0]), float(rel[1])))
    return fb, float(P[0, 2] - th3)


def synthesize_motion(poses_deg, circle_points=None, *, samples: int = 720) -> MotionSynthesis:
    """A four-bar that carries a body through three or four poses (x mm, y mm, angle deg).

    Three poses: with ``circle_points`` (two (u, v) in the body frame) those are the dyads;
    without, circle points on a grid over the body's neighbourhood are tried (a free choice,
    stated) and the pair chosen as :func:`choose_pair` says. Four poses: the dyads come from
    Burmester's curves (``samples`` values of beta2) and the pair is chosen the same way.
    """
    P = np.array(poses_deg, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] not in (3, 4):
        raise SynthesisError("--pose", f"motion generation takes three or four poses, got"
                             f" {P.shape[0] if P.ndim == 2 else 0}", "Give --pose X,Y,ANGLE_DEG"
                             " three or four times")
    P[:, 2] = np.radians(P[:, 2])
    n = P.shape[0]
    check_poses(P, n, "--pose")
    spread = max(float(np.ptp(P[:, 0])), float(np.ptp(P[:, 1])), 1e-3)
    curves = None
    notes = []
    if n == 3:
        if circle_points is not None:
            cps = np.asarray(circle_points, dtype=float)
            if cps.shape != (2, 2):
                raise SynthesisError("--circle-point", "give two circle points (u, v)")
            d1 = three_pose_dyad(P, cps[0])
            d2 = three_pose_dyad(P, cps[1])
            k = _pair_checks(d1.K[None], d1.m[None], d2.K[None], d2.m[None], P, False)
            if not k["ok"][0]:
                why = ("its poses lie on different assembly branches (branch defect)"
                       if k["ratio"][0] != 0 else "the input passes the poses out of order"
                       " (order defect)")
                raise SynthesisError("--circle-point", f"the four-bar of these circle points"
                                     f" does not carry the body through the poses: {why}",
                                     "Choose other circle points, or leave them out to let"
                                     " sewmech choose")
            chk = {key: (v[0] if isinstance(v, np.ndarray) else v) for key, v in k.items()}
            tried = (1, 1)
            notes.append("circle points given (the free choice of three-pose synthesis):"
                         f" {tuple(np.round(cps[0], 6))} and {tuple(np.round(cps[1], 6))} mm"
                         " in the body frame")
        else:
            g = np.linspace(-1.5 * spread, 1.5 * spread, 13)
            cand = np.array([(u, v) for u in g for v in g])
            Ks, ms = [], []
            for m in cand:
                try:
                    dy = three_pose_dyad(P, m)
                except SynthesisError:
                    continue
                if np.hypot(*(dy.K - P[0, :2])) < 20 * spread:
                    Ks.append(dy.K)
                    ms.append(m)
            i, j, chk, tried = choose_pair(np.array(Ks), np.array(ms), P, where="--pose")
            d1 = three_pose_dyad(P, ms[i])
            d2 = three_pose_dyad(P, ms[j])
            notes.append(f"circle points chosen (the free choice of three-pose synthesis) from"
                         f" a 13 x 13 grid of +-{1.5 * spread:.4g} mm about the body's"
                         " reference point")
    else:
        curves = burmester_curves(P, samples)
        keep = np.linalg.norm(curves.centre - P[0, :2], axis=-1) < 20 * spread
        Ks, ms = curves.centre[keep], curves.m[keep]
        i, j, chk, tried = choose_pair(Ks, ms, P, where="--pose")
        d1 = Dyad(Ks[i], ms[i], pose_points(P[:1], ms[i])[0])
        d2 = Dyad(Ks[j], ms[j], pose_points(P[:1], ms[j])[0])
        notes.append(f"the dyads are points of Burmester's curves ({samples} values of the"
                     " input's rotation beta2 to pose 2, two closures each)")
    fb, offset = _fourbar_of(d1, d2, P, int(chk["branch"]))
    drive = "shaft" if chk["crank"] else "setting"
    notes.append(f"pair chosen: of {tried[0]} four-bars from pairs of dyads, {tried[1]} are free"
                 " of branch and order defects"
                 + "; preferred: a crank input with the links in proportion (the longest at"
                   f" most {PROPORTION:g} times the shortest, each within {PROPORTION:g} times"
                   f" the poses' spread) and transmitting at least {MIN_TRANSMISSION_DEG:g} deg,"
                   " then a lever so, then a crank, then a lever; of"
                   " those, the largest least transmission angle,"
                   f" {chk['mu_min']:.2f} deg over the motion")
    g = grashof(fb.a, fb.b, fb.c, fb.d)
    notes.append(f"Grashof: {g.text}; the input "
                 + ("turns with the shaft" if drive == "shaft" else
                    "is a lever (a setting input over the poses' range)"))
    th2 = np.degrees(np.asarray(chk["theta2"]))
    return MotionSynthesis(fb, P, offset, th2, int(chk["ratio"]), drive, g,
                           float(chk["mu_min"]), (d1, d2), curves, tried, tuple(notes))


# ---- timed path generation: the exact start ---------------------------------------------------


@dataclass(frozen=True)
class PathStart:
    """A four-bar whose coupler point P passes exactly through three of the path's points at
    their input angles; fourbar (crank A -> B turns with the shaft at phase 0, so the input angle
    is the shaft angle), the three indices, the free choices (coupler and output rotations,
    rad), and the rms distance of P from all the points, mm."""

    fourbar: FourBar
    exact: tuple[int, int, int]
    alpha: tuple[float, float]
    gamma: tuple[float, float]
    rms_mm: float


def path_start(points, phi_deg, *, A=None) -> PathStart:
    """An exact three-point start for timed path generation: the coupler point through points
    ``points`` (n, 2) mm at the input angles ``phi_deg`` (n,), input pivot ``A`` (default: a
    free choice made by the scan). The coupler's rotations alpha_2, alpha_3 and the output's
    gamma_2, gamma_3 between the three exact points are free choices: a grid of them is tried
    and the four-bar (a crank-rocker, on one branch, assembling over the turn) nearest all the
    points kept."""
    Z = np.asarray(points, dtype=float)
    phi = np.radians(np.asarray(phi_deg, dtype=float))
    n = len(Z)
    if Z.shape != (n, 2) or phi.shape != (n,) or n < 3:
        raise SynthesisError("--path", f"needs three or more points with their angles, got {n}",
                             "Give a CSV with columns phi_deg, x_mm, y_mm")
    if not (np.all(np.isfinite(Z)) and np.all(np.isfinite(phi))):
        raise SynthesisError("--path", "a point or angle is not a finite number")
    for i in range(n):
        for j in range(i):
            if abs(np.angle(np.exp(1j * (phi[i] - phi[j])))) < 1e-12:
                raise SynthesisError("--path", f"points {j + 1} and {i + 1} are at the same"
                                     f" input angle {math.degrees(phi[i]):g} deg",
                                     "Give each point its own angle")
    idx = (0, n // 3, (2 * n) // 3) if n > 3 else (0, 1, 2)
    z = Z[list(idx), 0] + 1j * Z[list(idx), 1]
    beta = phi[list(idx)] - phi[idx[0]]
    delta = z[1:] - z[0]
    span = max(np.ptp(Z[:, 0]), np.ptp(Z[:, 1]), 1e-3)
    grid = np.radians(np.arange(-60.0, 61.0, 15.0))
    best = None
    for a2 in grid:
        for a3 in grid:
            ea = np.exp(1j * np.array([a2, a3])) - 1.0
            M = np.array([[np.exp(1j * beta[1]) - 1.0, ea[0]], [np.exp(1j * beta[2]) - 1.0,
                                                                ea[1]]])
            if abs(np.linalg.det(M)) < 1e-12:
                continue
            W, Zv = np.linalg.solve(M, delta)
            Bp = z[0] - Zv
            Ap = Bp - W
            for g2 in grid:
                for g3 in grid:
                    Mg = np.array([[np.exp(1j * g2) - 1.0, ea[0]],
                                   [np.exp(1j * g3) - 1.0, ea[1]]])
                    if abs(np.linalg.det(Mg)) < 1e-12:
                        continue
                    U, S = np.linalg.solve(Mg, delta)
                    Cp = z[0] - S
                    Dp = Cp - U
                    a, b = abs(W), abs(Cp - Bp)
                    c, d = abs(U), abs(Dp - Ap)
                    if min(a, b, c, d) < 1e-3 * span or max(a, b, c, d) > 50 * span:
                        continue
                    g = grashof(a, b, c, d)
                    if g.kind not in ("crank-rocker", "double-crank") or g.change_point:
                        continue
                    side = np.sign(((Dp - Bp).conjugate() * (Cp - Bp)).imag)
                    fb = _path_fourbar(Ap, Bp, Cp, Dp, z[0], phi[idx[0]], int(side or 1))
                    xy = fb.coupler_xy(phi)
                    s = fb.solve(np.linspace(0, TWO_PI, 181))
                    if not np.all(s["ok"]):
                        continue
                    rms = float(np.sqrt(np.mean(np.sum((xy - Z) ** 2, -1))))
                    if np.isfinite(rms) and (best is None or rms < best[0]):
                        best = (rms, fb, (float(a2), float(a3)), (float(g2), float(g3)))
    if best is None:
        raise SynthesisError("--path", "no crank-rocker found through three of the points for"
                             " any of the coupler and output rotations tried", "Check that the"
                             " points and their angles describe a path a four-bar can trace")
    return PathStart(best[1], tuple(int(i) for i in idx), best[2], best[3], best[0])


def _path_fourbar(A, B, C, D, P, phi1: float, branch: int) -> FourBar:
    """The four-bar of complex points A, B, C, D (pose at the input angle phi1) with the crank's
    angle equal to the shaft angle: B sits on the crank's u axis turned by (angle(AB) - phi1)."""
    a = abs(B - A)
    th3 = np.angle(C - B)
    rel = (P - B) * np.exp(-1j * th3)
    phase = float(np.angle(B - A) - phi1)  # the crank's angle is phase + the shaft angle
    return FourBar((float(A.real), float(A.imag)), (float(D.real), float(D.imag)), float(a),
                   float(abs(C - B)), float(abs(D - C)), float(a), float(abs(D - C)), branch,
                   (float(rel.real), float(rel.imag)), phase)


@dataclass(frozen=True)
class PathSynthesis:
    """Timed path generation: the exact three-point start and the optimiser's answer over
    every point. start, answer : the machine texts; start_rms_mm, answer_rms_mm, answer_max_mm :
    the coupler point's distance from the points; variables : name -> (start, answer) in file
    units; result : the optimiser's OptimizeResult; problem_text : the design problem (TOML)
    the optimiser solved, for ``sewmech optimize``."""

    start: PathStart
    start_text: str
    answer_text: str
    start_rms_mm: float
    answer_rms_mm: float
    answer_max_mm: float
    variables: dict
    result: object
    problem_text: str
    notes: tuple[str, ...] = field(default_factory=tuple)


#: the four-bar's parameters the optimiser moves in path generation
PATH_VARIABLES = ("B.u", "dyad.length1", "dyad.length2", "A.x", "A.y", "D.x", "D.y", "P.u",
                  "P.v", "input.phase")


def synthesize_path(points, phi_deg, *, name: str = "path-generator", method: str = "slsqp"
                    ) -> PathSynthesis:
    """A four-bar whose coupler point P passes through ``points`` (n, 2) mm at the shaft angles
    ``phi_deg`` (n,): the exact three-point start (:func:`path_start`), then the design problem
    "P at each point at its angle" (every dimension a variable, within +-50 % of the start's
    lengths and +-one path size of its pivots, the crank's phase +-45 deg) solved by
    ``method`` of :func:`sewmech.design.optimize.optimize` (SLSQP: exact gradients)."""
    from ..engine.kinematics import kinematics
    from ..engine.machine import machine_from_toml
    from .optimize import optimize
    from .problem import Problem, ProblemSpec
    from .synthesis import machine_text

    Z = np.asarray(points, dtype=float)
    phi = np.asarray(phi_deg, dtype=float)
    st = path_start(Z, phi)
    fb = st.fourbar
    notes = [f"exact start through points {', '.join(str(i + 1) for i in st.exact)} with the"
             f" coupler turning {math.degrees(st.alpha[0]):g}, {math.degrees(st.alpha[1]):g}"
             f" deg and the output {math.degrees(st.gamma[0]):g},"
             f" {math.degrees(st.gamma[1]):g} deg between them (free choices, the best of a"
             f" 15 deg grid): rms {st.rms_mm:.4g} mm from all {len(Z)} points"]
    text = machine_text(fb, name=name, title=f"Path generator through {len(Z)} points",
                        notes=["A four-bar whose coupler point P follows a path at given shaft"
                               " angles (sewmech synthesize path)."],
                        phase_deg=math.degrees(fb.phase))
    m = machine_from_toml(text, f"{name}.toml")
    span = max(float(np.ptp(Z[:, 0])), float(np.ptp(Z[:, 1])), 1.0)
    start = {n: float(m.defaults[m.parameter_index(n)]) for n in PATH_VARIABLES}
    start["input.phase"] = math.degrees(start["input.phase"])
    variables = []
    for n, v in start.items():
        if n in ("B.u", "dyad.length1", "dyad.length2"):
            lo, hi = 0.5 * v, 1.5 * v
        elif n == "input.phase":
            lo, hi = v - 45.0, v + 45.0
        else:
            lo, hi = v - span, v + span
        variables.append({"parameter": n, "lower": lo, "upper": hi})
    parts = [{"metric": f"p_P_{c}", "phi_deg": float(a), "target": float(Z[k, i]),
              "scale": 1.0} for k, a in enumerate(phi) for i, c in enumerate("xy")]
    spec = ProblemSpec.model_validate({"problem": {"name": f"{name}: path", "machine": name},
                                       "variables": variables,
                                       "objective": {"form": "weighted_sum", "parts": parts}})
    problem = Problem(spec, m)
    r = optimize(problem, method, tol=1e-12)
    x = {n: float(v) for n, v in zip(problem.names, r.x, strict=True)}
    values = {n: (math.radians(v) if n == "input.phase" else v) for n, v in x.items()}
    m2 = m.with_parameters(values)
    rp = kinematics(m2, np.radians(phi), points=["P"], links=[], variables=[],
                    on_failure="mask").point("P").p
    dist = np.linalg.norm(rp - Z, axis=-1)
    fb2 = FourBar((x["A.x"], x["A.y"]), (x["D.x"], x["D.y"]), x["B.u"], x["dyad.length1"],
                      x["dyad.length2"], x["B.u"], x["dyad.length2"], fb.branch,
                  (x["P.u"], x["P.v"]), math.radians(x["input.phase"]))
    answer_text = machine_text(fb2, name=name, title=f"Path generator through {len(Z)} points"
                               " (optimised)",
                               notes=["A four-bar whose coupler point P follows a path at given"
                                      " shaft angles, optimised from an exact three-point start"
                                      " (sewmech synthesize path)."],
                               phase_deg=x["input.phase"])
    notes.append(f"{method}: objective {r.objective_start:.4g} -> {r.fun:.4g} (sum of squared"
                 f" distances, mm^2) in {r.n_evaluations} designs ({r.status})")
    lines = [f'[problem]\nname = "{name}: path"\nmachine = "{name}.toml"\n']
    for v in variables:
        lines.append(f'[[variables]]\nparameter = "{v["parameter"]}"\nlower = {v["lower"]!r}\n'
                     f'upper = {v["upper"]!r}\n')
    lines.append('[objective]\nform = "weighted_sum"\n')
    for p in parts:
        lines.append(f'[[objective.parts]]\nmetric = "{p["metric"]}"\nphi_deg = {p["phi_deg"]!r}'
                     f'\ntarget = {p["target"]!r}\nscale = 1.0\n')
    return PathSynthesis(st, text, answer_text, st.rms_mm,
                         float(np.sqrt(np.mean(dist ** 2))), float(dist.max()),
                         {n: (start[n], x[n]) for n in start}, r, "\n".join(lines),
                         tuple(notes))
