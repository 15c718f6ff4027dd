"""The housing on its mounts: what the operator feels (docs/vibration.md).

The housing (head, arm and bed, ``[housing]``) is a rigid body with six degrees of freedom, held
by elastic mounts, and excited by every force the mechanisms put on it over one turn: each frame
pair's force at its point, in the plane (z) of its mechanism; the upper shaft's two bearings in
3-D at their own z (their forces carry the cranks on the shaft); each spring anchored to the
frame; the couples at the frame's pairs (a guide's couple, friction at a pin) and the drivers'
reactions (the motor, mounted on the housing, and the setting inputs' holders). At a constant
shaft speed the excitation is periodic: its Fourier series over the turn gives one complex
6 x 6 solve per harmonic, for every design of a batch at once:

    (K (1 + i eta) + i n Omega C - (n Omega)^2 M) Q_n = W_n,

with q = (u_x, u_y, u_z, theta_x, theta_y, theta_z) the housing's small displacement at the
frame's origin (mm) and rotation (rad), M its mass matrix about the origin, K and C the mounts'
stiffness and damping (a mount without damping gets the housing's loss factor eta as
structural damping) and W_n the harmonic of the excitation wrench (force N and moment about the
origin N mm). A point p of the housing moves by u + theta x p; its velocity's harmonics give its
spectrum, its RMS velocity along each axis and its level in dB re 5e-8 m/s (the balancing
paper's reference [Sunkuev-balancing]). The mounts' forces are what the table feels.

Units: mm, kg, s, N, rad; inertia kg mm^2; stiffness N/mm (N mm/rad for rotations); damping
N s/mm; velocities mm/s; frequencies Hz at the edges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .errors import AnalysisError, MachineFileError
from .machine import Machine
from .spec import FRAME, SHAFT

#: the reference of vibration velocity levels, mm/s (5e-8 m/s, [Sunkuev-balancing])
V_REF_MM_S = 5e-5
#: mass and inertia in kg and kg mm^2 times accelerations in mm/s^2 give 1e3 N and N mm
_ACC = 1e-3
AXES = ("x", "y", "z")


def skew(p: np.ndarray) -> np.ndarray:
    """[p]x: the matrix of p x (.), (..., 3, 3)."""
    p = np.asarray(p, dtype=float)
    z = np.zeros(p.shape[:-1])
    return np.stack([np.stack([z, -p[..., 2], p[..., 1]], -1),
                     np.stack([p[..., 2], z, -p[..., 0]], -1),
                     np.stack([-p[..., 1], p[..., 0], z], -1)], -2)


def point_map(p: np.ndarray) -> np.ndarray:
    """T (..., 3, 6): the displacement of the housing's point p for its motion q: u + theta x p
    = u - [p]x theta."""
    p = np.asarray(p, dtype=float)
    eye = np.broadcast_to(np.eye(3), p.shape[:-1] + (3, 3))
    return np.concatenate([eye, -skew(p)], axis=-1)


@dataclass(frozen=True)
class Housing:
    """The housing of a machine as the vibration analysis uses it (see the module doc).

    M : (6, 6) mass matrix about the frame's origin (kg, kg mm, kg mm^2); K (6, 6) the mounts'
    stiffness (N/mm, N, N mm/rad); C (6, 6) their viscous damping (N s/mm ...); K_eta (6, 6)
    the stiffness of the mounts that take the loss factor ``eta`` instead; mounts' names,
    points (n, 3) mm, stiffness and damping (n, 3); control points' names and points (n, 3)."""

    mass_kg: float
    com_mm: np.ndarray
    M: np.ndarray
    K: np.ndarray
    C: np.ndarray
    K_eta: np.ndarray
    eta: float
    mount_names: tuple[str, ...]
    mount_at: np.ndarray
    mount_k: np.ndarray
    mount_c: np.ndarray  # NaN rows: structural damping
    control_names: tuple[str, ...]
    control_at: np.ndarray
    planes: dict = field(default_factory=dict)
    default_plane: float = 0.0

    @classmethod
    def of(cls, machine: Machine) -> Housing:
        """The machine's ``[housing]`` (an AnalysisError naming the file if it has none)."""
        h = machine.spec.housing
        if h is None:
            raise AnalysisError(machine.file or f"machine '{machine.name}'", "the machine has"
                                " no [housing] table: its vibration is not known", "Add"
                                " [housing] (its mass, mounts and control points:"
                                " docs/vibration.md)")
        known = [p.name for p in machine.pairs if FRAME in p.links and p.kind != "driver"]
        known += [sp.name for sp in machine.spec.springs if FRAME in sp.links]
        for name in h.planes_mm:
            if name not in known:
                raise MachineFileError(machine.file or machine.name, "housing", "planes_mm",
                                       f"'{name}' is not a pair with the frame nor a spring"
                                       " anchored to it", "Name one of: "
                                       + ", ".join(known))
        return build_housing(machine.name, machine.file, h)

    # ---- the free housing ----------------------------------------------------------------
    def modes(self) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequencies (Hz, ascending, (6,)) and mode shapes ((6, 6), column k the
        mode of frequency k, scaled to a largest component of 1) of the undamped housing:
        K phi = omega^2 M phi."""
        from scipy.linalg import eigh

        w2, vec = eigh(self.K + self.K_eta, _ACC * self.M)
        f = np.sqrt(np.maximum(w2, 0.0)) / (2.0 * math.pi)
        k = np.argmax(np.abs(vec), axis=0)
        vec = vec / vec[k, np.arange(6)]
        return f, vec

    def impedance(self, w: np.ndarray) -> np.ndarray:
        """Z(w) (..., 6, 6) complex: K + i eta K_eta + i w C - w^2 M, w in rad/s (...)."""
        w = np.asarray(w, dtype=float)[..., None, None]
        return (self.K + self.K_eta * (1.0 + 1j * self.eta) + 1j * w * self.C
                - _ACC * w * w * self.M)


def build_housing(name: str, file: str, h) -> Housing:
    """The :class:`Housing` of a validated ``[housing]`` table (located MachineFileErrors: a
    mount or control point outside the housing, mounts that leave it free to move)."""
    from .mass import from_spec

    mp = from_spec(h.mass)
    if not np.isfinite(mp.inertia).all():
        raise MachineFileError(file, "housing.mass", "inertia", "the housing needs its full"
                               " inertia tensor", "Give inertia = [[Ixx, Ixy, Ixz], ...] or solids")
    c = np.asarray(mp.com, dtype=float)
    Tc = point_map(c)
    M = mp.mass * Tc.T @ Tc
    M[3:, 3:] += mp.inertia
    at = np.array([m.at_mm for m in h.mounts], dtype=float)
    k = np.array([m.stiffness_N_per_mm for m in h.mounts], dtype=float)
    cc = np.array([m.damping_N_s_per_mm if m.damping_N_s_per_mm is not None else
                   (np.nan, np.nan, np.nan) for m in h.mounts], dtype=float)
    K = np.zeros((6, 6))
    K_eta = np.zeros((6, 6))
    C = np.zeros((6, 6))
    for j in range(len(h.mounts)):
        T = point_map(at[j])
        Km = T.T @ np.diag(k[j]) @ T
        if np.isnan(cc[j]).any():
            K_eta += Km
        else:
            K += Km
            C += T.T @ np.diag(cc[j]) @ T
    control = np.array(list(h.control_points.values()), dtype=float).reshape(-1, 3)
    if h.bounds_mm is not None:
        lo = np.array([b[0] for b in h.bounds_mm])
        hi = np.array([b[1] for b in h.bounds_mm])
        for what, names, pts in (("mounts", [m.name for m in h.mounts], at),
                                 ("control_points", list(h.control_points), control)):
            for nm, p in zip(names, pts, strict=True):
                out = (p < lo - 1e-9) | (p > hi + 1e-9)
                if out.any():
                    ax = AXES[int(np.argmax(out))]
                    key = (f"{nm}" if what == "control_points" else f"{nm}.at_mm")
                    raise MachineFileError(file, f"housing.{what}", key, f"{p.tolist()} mm is"
                                           f" not on the housing: its {ax} is outside"
                                           f" bounds_mm {h.bounds_mm[AXES.index(ax)]}",
                                           "Give a point of the housing (inside bounds_mm)")
    # the mounts must hold the housing in every direction
    Ks = K + K_eta
    w, v = np.linalg.eigh(Ks)
    scale = max(float(np.abs(Ks).max()), 1e-300)
    if not (w > 1e-12 * scale).all():
        free = v[:, int(np.argmin(w))]
        j = int(np.argmax(np.abs(free)))
        what = (f"along {AXES[j]}" if j < 3 else f"about the {AXES[j - 3]} axis")
        raise MachineFileError(file, "housing", "mounts", f"the mounts leave the housing free"
                               f" to move {what} (no stiffness holds it there)", "Give the"
                               " mounts stiffness in that direction, or more mounts, apart")
    return Housing(mp.mass, c, M, K, C, K_eta, float(h.loss_factor),
                   tuple(m.name for m in h.mounts), at, k, cc, tuple(h.control_points),
                   control, dict(h.planes_mm), float(h.default_plane_mm))


# ---- the excitation -----------------------------------------------------------------------------


def excitation(machine: Machine, housing: Housing, res) -> np.ndarray:
    """The wrench the mechanisms put on the housing over the turn, batch + (n_phi, 6): force
    (N, x y z) and moment about the frame's origin (N mm, x y z), from a
    :class:`~sewmech.dynamics.DynamicsResult` (see the module doc for what it holds)."""
    shape = res.kin.theta.shape[:-1]
    W = np.zeros(shape + (6,))
    shaft = machine.spec.shaft
    on_shaft = set(shaft.links) if shaft is not None else set()

    def add(F2, p2, z):
        """A planar force F2 (..., 2) at p2 (..., 2) in the plane z: F = (fx, fy, 0) and its
        moment p x F, p = (px, py, z), written out as np.cross computes it (the same
        products and differences: the same bits, without its reshaping of 3-vectors)."""
        fx, fy = F2[..., 0], F2[..., 1]
        p2 = np.broadcast_to(p2, F2.shape)
        px, py, z = p2[..., 0], p2[..., 1], float(z)
        W[..., 0] += fx
        W[..., 1] += fy
        W[..., 2] += 0.0
        W[..., 3] += py * 0.0 - z * fy
        W[..., 4] += z * fx - px * 0.0
        W[..., 5] += px * fy - py * fx

    reactions = res.frame_reactions
    points = res.frame_reaction_points
    for name, F in reactions.items():
        pair = next((p for p in res.pairs if p.name == name), None)
        if pair is not None and on_shaft and FRAME in pair.links and (
                pair.links[1] in on_shaft or pair.links[0] in on_shaft):
            continue  # the shaft's cranks act through its bearings (below)
        add(F, points[name], housing.planes.get(name, housing.default_plane))
    for name, M in res.frame_couples.items():
        pair = next((p for p in res.pairs if p.name == name), None)
        if pair is not None and on_shaft and pair.kind == "revolute" and (
                pair.links[1] in on_shaft or pair.links[0] in on_shaft):
            continue  # friction at the shaft's journals: the bearings' (below)
        W[..., 5] += M
    if shaft is not None:
        br = res.bearings
        axis = _shaft_axis(machine)
        for B, z in ((br.front, br.z_front), (br.rear, br.z_rear)):
            add(-B, axis, z)
        # friction at the journals: its moment acts on the housing about the shaft's axis
        fr = res._friction_at_pairs
        for pair in res.pairs:
            if pair.kind == "revolute" and pair.name in fr and FRAME in pair.links and (
                    pair.links[1] in on_shaft or pair.links[0] in on_shaft):
                W[..., 5] += (-1.0 if pair.links[0] == FRAME else 1.0) * fr[pair.name]
    # the drivers' reactions: the motor on the housing, the setting inputs' holders
    for c, pair in res._columns.values():
        if pair.kind == "driver":
            W[..., 5] -= res.unknowns[..., c]
    return W


def _shaft_axis(machine: Machine) -> np.ndarray:
    for u in machine.spec.units:
        if u.type == "crank" and u.input == SHAFT and (u.link or u.name) in \
                machine.spec.shaft.links:
            p = machine.spec.points[u.pivot]
            return np.array([p.x, p.y])
    return np.zeros(2)


# ---- the response -------------------------------------------------------------------------------


@dataclass(frozen=True)
class HousingVibration:
    """The housing's steady periodic vibration at a shaft speed, for a batch of designs.

    harmonics: (n_h,) the harmonic orders n (>= 1) of the shaft speed, frequency_hz their
    frequencies; Q (batch, n_h, 6) the housing's displacement harmonics (mm, rad; complex
    amplitudes of e^{i n Omega t}, a real signal's being 2 Re); control_v (batch, n_h, n_c, 3)
    the control points' velocity harmonics (mm/s); mount_f (batch, n_h, n_m, 3) the mounts'
    force harmonics on the table (N)."""

    housing: Housing
    rpm: float
    harmonics: np.ndarray
    frequency_hz: np.ndarray
    Q: np.ndarray = field(repr=False)
    control_v: np.ndarray = field(repr=False)
    mount_f: np.ndarray = field(repr=False)

    @property
    def rms_velocity(self) -> np.ndarray:
        """RMS velocity of each control point along x, y, z, mm/s, batch + (n_c, 3)."""
        return np.sqrt(2.0 * np.sum(np.abs(self.control_v) ** 2, axis=-3))

    @property
    def level_db(self) -> np.ndarray:
        """The RMS velocities as levels, dB re 5e-8 m/s, batch + (n_c, 3)."""
        with np.errstate(divide="ignore"):
            return 20.0 * np.log10(self.rms_velocity / V_REF_MM_S)

    @property
    def spectrum(self) -> np.ndarray:
        """Each harmonic's RMS velocity at each control point along each axis, mm/s,
        batch + (n_h, n_c, 3)."""
        return np.sqrt(2.0) * np.abs(self.control_v)

    @property
    def mount_rms(self) -> np.ndarray:
        """RMS force of each mount on the table along x, y, z (the turn's mean left out), N,
        batch + (n_m, 3)."""
        return np.sqrt(2.0 * np.sum(np.abs(self.mount_f) ** 2, axis=-3))

    def control(self, name: str) -> int:
        try:
            return self.housing.control_names.index(name)
        except ValueError:
            raise KeyError(f"no control point '{name}'; the housing's:"
                           f" {', '.join(self.housing.control_names)}") from None

    def velocity_in_time(self, n_t: int = 360) -> np.ndarray:
        """The control points' velocities over one turn, batch + (n_t, n_c, 3), mm/s."""
        phi = np.arange(n_t) * (2.0 * math.pi / n_t)
        e = np.exp(1j * np.outer(phi, self.harmonics))  # (n_t, n_h)
        return 2.0 * np.real(np.einsum("th,...hcx->...tcx", e, self.control_v))


def vibration(housing: Housing, wrench: np.ndarray, rpm: float) -> HousingVibration:
    """The housing's steady vibration under the periodic ``wrench`` (batch + (n_phi, 6), on a
    whole turn in equal steps, :func:`excitation`) at ``rpm``: every harmonic the grid holds
    (up to n_phi / 2, the last one's Nyquist share halved), one complex 6 x 6 solve each."""
    W = np.asarray(wrench, dtype=float)
    n_phi = W.shape[-2]
    F = np.fft.rfft(W, axis=-2) / n_phi  # e^{-i n phi_k}: W(t) = sum_n F_n e^{i n Omega t}
    n = np.arange(F.shape[-2])
    if n_phi % 2 == 0:  # the Nyquist harmonic appears once in rfft: its share is half
        F[..., -1, :] *= 0.5
    F, n = F[..., 1:, :], n[1:]
    omega = rpm * math.pi / 30.0
    w = n * omega
    Z = housing.impedance(w)  # (n_h, 6, 6)
    Q = np.linalg.solve(Z, F[..., None])[..., 0]  # batch + (n_h, 6)
    V = 1j * w[:, None] * Q
    Tc = point_map(housing.control_at)  # (n_c, 3, 6)
    control_v = np.einsum("cxk,...hk->...hcx", Tc, V)
    Tm = point_map(housing.mount_at)  # (n_m, 3, 6)
    d = np.einsum("mxk,...hk->...hmx", Tm, Q)
    c = np.where(np.isnan(housing.mount_c), 0.0, housing.mount_c)
    structural = np.isnan(housing.mount_c)
    kk = housing.mount_k * np.where(structural, 1.0 + 1j * housing.eta, 1.0)
    mount_f = (kk + 1j * w[:, None, None] * c) * d
    return HousingVibration(housing, float(rpm), n, w / (2.0 * math.pi), Q, control_v,
                            mount_f)


def housing_vibration(machine: Machine, phi_step_deg: float = 2.0, *, rpm: float | None = None,
                      inputs=None, params=None, loads=None, gravity: bool = True
                      ) -> HousingVibration:
    """The machine's housing vibration at ``rpm`` (default: the file's) and setting
    ``inputs`` (rad; default: the working setting), from its inverse dynamics on a whole turn
    in steps of ``phi_step_deg`` (harmonics up to 180 / step)."""
    from .dynamics import inverse_dynamics

    housing = Housing.of(machine)
    n = round(360.0 / phi_step_deg)
    if n < 8 or abs(n * phi_step_deg - 360.0) > 1e-9:
        raise ValueError(f"phi_step_deg must divide 360 into at least 8 steps, got"
                         f" {phi_step_deg}")
    phi = np.arange(n) * (2.0 * math.pi / n)
    r = inverse_dynamics(machine, phi, rpm=rpm, inputs=inputs, params=params, loads=loads,
                         gravity=gravity)
    rpm = float(r.kin.omega_shaft.reshape(-1)[0] * 30.0 / math.pi)
    return vibration(housing, excitation(machine, housing, r), rpm)
