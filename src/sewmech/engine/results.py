"""Result objects of the kinematics: frozen, named, with an explicit feasibility mask.

Array convention (docs/notation.md): leading batch axes for designs, then the crank-angle axis,
then coordinates. Nothing is squeezed: a single design has batch shape ``()``, and the phi axis
is always present.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import name_index

# channel prefix -> (array attribute, unit, derivative prefix wrt phi at omega = 1 rad/s)
CHANNEL_KINDS = {
    "p": ("p", "mm", "v"),
    "v": ("v", "mm/s", "a"),
    "a": ("a", "mm/s^2", None),
    "theta": ("theta", "rad", "omega"),
    "omega": ("omega", "rad/s", "epsilon"),
    "epsilon": ("epsilon", "rad/s^2", None),
    "q": ("q", None, "qd"),
    "qd": ("q_dot", None, "qdd"),
    "qdd": ("q_ddot", None, None),
}


def mask_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of every run of consecutive True values of a 1-D mask."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(m[1:] != m[:-1])
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2])]


#: failure codes of the kernels (sewmech._kernels.FAIL_*): (word, explanation)
FAILURE_REASONS = {
    0: ("", ""),
    1: ("assembly", "the closure equations have no real solution: a link is too short or too"
                    " long for the distance it must bridge"),
    2: ("singular", "a dead centre or toggle: the velocity is not defined"),
    3: ("newton", "the loop solver did not converge"),
    4: ("lost", "the loop's continuation was lost after it failed at an earlier angle"),
    5: ("parameter", "a parameter of the design is not finite or outside its domain"),
}


@dataclass(frozen=True)
class PointMotion:
    """Position (mm), velocity (mm/s), acceleration (mm/s^2) of one point; (..., n_phi, 2)."""

    p: np.ndarray
    v: np.ndarray
    a: np.ndarray


@dataclass(frozen=True)
class LinkMotion:
    """Angle (rad), angular velocity (rad/s), angular acceleration (rad/s^2); (..., n_phi)."""

    theta: np.ndarray
    omega: np.ndarray
    epsilon: np.ndarray


@dataclass(frozen=True)
class VariableMotion:
    """A joint variable (slider displacement in mm, or a free angle in rad) and its rates."""

    q: np.ndarray
    q_dot: np.ndarray
    q_ddot: np.ndarray
    unit: str


@dataclass(frozen=True, eq=False)
class KinematicsResult:
    """Motion of every point, link and joint variable of a machine over crank angles.

    Attributes
    ----------
    machine : str
        Machine name.
    phi : ndarray, shape (n_phi,)
        Upper-shaft angle, rad, in the machine's angle convention.
    omega_shaft, epsilon_shaft : ndarray, shape (n_phi,)
        Shaft speed (rad/s) and angular acceleration (rad/s^2) used.
    p, v, a : ndarray, shape batch + (n_phi, n_points, 2)
        Point positions (mm), velocities (mm/s), accelerations (mm/s^2).
    theta, omega, epsilon : ndarray, shape batch + (n_phi, n_links)
        Link angles (rad), angular velocities (rad/s), accelerations (rad/s^2). Link 0 = frame.
    q, q_dot, q_ddot : ndarray, shape batch + (n_phi, n_variables)
        Joint variables (slider displacements mm, free angles rad) and time derivatives.
    feasible : ndarray of bool, shape batch + (n_phi,)
        False where some unit could not be assembled; only there are the values NaN.
    failure_unit : ndarray of int, shape batch + (n_phi,)
        Index into ``unit_names`` of the unit that failed, -1 where feasible (and where a
        parameter of a frame point or a setting input is outside its domain); names in
        :attr:`failure_units`, reasons in :attr:`failure_reasons`, a table in
        :meth:`failures`.
    failure_code : ndarray of int, shape batch + (n_phi,)
        Why it failed (:data:`FAILURE_REASONS`), 0 where feasible.
    loop_residual : ndarray, shape batch + (n_phi, n_loop_units)
        Max-norm of the loop-closure residual (mm) of each loop unit after Newton; NaN for a
        loop unit that the requested outputs did not need (it was not solved).
    branches : dict[str, int]
        Assembly branch of each closed-form unit, as stated in the machine file.
    """

    machine: str
    phi: np.ndarray
    omega_shaft: np.ndarray
    epsilon_shaft: np.ndarray
    point_names: tuple[str, ...]
    link_names: tuple[str, ...]
    variable_names: tuple[str, ...]
    variable_units: tuple[str, ...]
    unit_names: tuple[str, ...]
    p: np.ndarray = field(repr=False)
    v: np.ndarray = field(repr=False)
    a: np.ndarray = field(repr=False)
    theta: np.ndarray = field(repr=False)
    omega: np.ndarray = field(repr=False)
    epsilon: np.ndarray = field(repr=False)
    q: np.ndarray = field(repr=False)
    q_dot: np.ndarray = field(repr=False)
    q_ddot: np.ndarray = field(repr=False)
    feasible: np.ndarray = field(repr=False)
    failure_unit: np.ndarray = field(repr=False)
    loop_residual: np.ndarray = field(repr=False)
    branches: dict[str, int] = field(default_factory=dict)
    failure_code: np.ndarray = field(default=None, repr=False)

    def __post_init__(self):
        if self.failure_code is None:
            object.__setattr__(self, "failure_code",
                               np.where(self.feasible, 0, 1).astype(np.int64))
        for name in ("phi", "omega_shaft", "epsilon_shaft", "p", "v", "a", "theta", "omega",
                     "epsilon", "q", "q_dot", "q_ddot", "feasible", "failure_unit",
                     "loop_residual", "failure_code"):
            getattr(self, name).setflags(write=False)

    # ---- failures -----------------------------------------------------------------------------
    @property
    def failure_units(self) -> np.ndarray:
        """Name of the unit that failed at each position (object array, batch + (n_phi,));
        "" where feasible, "(parameters)" where a frame point's or setting input's value is
        outside its domain."""
        names = np.asarray(self.unit_names + ("",), dtype=object)
        out = names[np.where(self.failure_unit >= 0, self.failure_unit, len(self.unit_names))]
        out[(self.failure_unit < 0) & ~self.feasible] = "(parameters)"
        return out

    @property
    def failure_reasons(self) -> np.ndarray:
        """Why each position failed, as a word (object array, batch + (n_phi,)); "" where
        feasible (see :data:`FAILURE_REASONS`)."""
        words = np.asarray([FAILURE_REASONS[k][0] for k in sorted(FAILURE_REASONS)],
                           dtype=object)
        return words[self.failure_code]

    def failures(self):
        """A DataFrame with one row per failing design, unit and reason: the design index
        (batches), the unit, the reason, its explanation, and the ranges of shaft angles (deg)
        where it fails, e.g. "120..145, 300"."""
        import pandas as pd

        from .errors import format_ranges

        rows = []
        batch = self.batch_shape
        n_design = int(np.prod(batch, dtype=np.int64))
        feasible = self.feasible.reshape(n_design, self.phi.shape[0])
        units = self.failure_units.reshape(feasible.shape)
        codes = self.failure_code.reshape(feasible.shape)
        order = np.argsort(self.phi_deg, kind="stable")
        phi = self.phi_deg[order]
        for d in np.flatnonzero(~feasible.all(axis=1)):
            for unit, code in sorted({(units[d, i], int(codes[d, i]))
                                      for i in np.flatnonzero(~feasible[d])}):
                mask = ((units[d] == unit) & (codes[d] == code))[order]
                runs = [(round(float(phi[a]), 6), round(float(phi[b]), 6))
                        for a, b in mask_runs(mask)]
                row = {"design": tuple(int(x) for x in np.unravel_index(d, batch))} \
                    if batch else {}
                row.update(unit=unit, reason=FAILURE_REASONS[code][0],
                           explanation=FAILURE_REASONS[code][1],
                           phi_deg=format_ranges(runs, limit=len(runs)))
                rows.append(row)
        cols = (["design"] if batch else []) + ["unit", "reason", "explanation", "phi_deg"]
        return pd.DataFrame(rows, columns=cols)

    # ---- shapes -------------------------------------------------------------------------------
    @property
    def batch_shape(self) -> tuple[int, ...]:
        return self.feasible.shape[:-1]

    @property
    def phi_deg(self) -> np.ndarray:
        """Shaft angle in degrees (for display), to 1e-9 deg: the angles people give in
        degrees come back as they gave them (``degrees(radians(30))`` is 29.999999999999996)."""
        return np.round(np.degrees(self.phi), 9) + 0.0  # (+ 0.0: no -0.0)

    @property
    def all_feasible(self) -> bool:
        return bool(self.feasible.all())

    # ---- named access -------------------------------------------------------------------------
    def point(self, name: str) -> PointMotion:
        i = name_index(self.point_names, name, "point")
        return PointMotion(self.p[..., i, :], self.v[..., i, :], self.a[..., i, :])

    def link(self, name: str) -> LinkMotion:
        i = name_index(self.link_names, name, "link")
        return LinkMotion(self.theta[..., i], self.omega[..., i], self.epsilon[..., i])

    def variable(self, name: str) -> VariableMotion:
        i = name_index(self.variable_names, name, "joint variable")
        return VariableMotion(self.q[..., i], self.q_dot[..., i], self.q_ddot[..., i],
                              self.variable_units[i])

    def channel_names(self) -> list[str]:
        """All channel names: ``p_B_x``, ``v_B_y``, ``theta_L``, ``q_V`` ... (see notation)."""
        names = []
        for kind in ("p", "v", "a"):
            for pt in self.point_names:
                names += [f"{kind}_{pt}_x", f"{kind}_{pt}_y"]
        for kind in ("theta", "omega", "epsilon"):
            names += [f"{kind}_{lk}" for lk in self.link_names if lk != "frame"]
        for kind in ("q", "qd", "qdd"):
            names += [f"{kind}_{var}" for var in self.variable_names]
        return names

    def channel(self, name: str) -> tuple[np.ndarray, str]:
        """One channel by name: (values with shape batch + (n_phi,), unit)."""
        kind, _, rest = name.partition("_")
        if kind not in CHANNEL_KINDS or not rest:
            raise KeyError(f"unknown channel '{name}'; channels look like p_B_x, v_B_y, a_B_x,"
                           " theta_L, omega_L, epsilon_L, q_V, qd_V, qdd_V")
        attr, unit, _ = CHANNEL_KINDS[kind]
        if kind in ("p", "v", "a"):
            pt, _, comp = rest.rpartition("_")
            if comp not in ("x", "y"):
                raise KeyError(f"channel '{name}': a point channel ends in _x or _y")
            i = name_index(self.point_names, pt, "point")
            return getattr(self, attr)[..., i, "xy".index(comp)], unit
        if kind in ("theta", "omega", "epsilon"):
            i = name_index(self.link_names, rest, "link")
            return getattr(self, attr)[..., i], unit
        i = name_index(self.variable_names, rest, "joint variable")
        base = self.variable_units[i]
        unit = {"q": base, "qd": f"{base}/s", "qdd": f"{base}/s^2"}[kind]
        return getattr(self, attr)[..., i], unit

    def channels(self) -> dict[str, tuple[np.ndarray, str]]:
        return {n: self.channel(n) for n in self.channel_names()}

    # ---- export ---------------------------------------------------------------------------------
    def to_pandas(self):
        """A DataFrame with one row per (design, phi) and one column per channel.

        Column names carry their unit (``p_B_x_mm``, ``omega_L_rad_s``); the first columns are
        the design index (batches only), ``phi_deg`` and ``feasible``.
        """
        import pandas as pd

        n_phi = self.phi.shape[0]
        n_design = int(np.prod(self.batch_shape, dtype=int))
        cols: dict[str, np.ndarray] = {}
        if self.batch_shape:
            cols["design"] = np.repeat(np.arange(n_design), n_phi)
        cols["phi_deg"] = np.tile(self.phi_deg, n_design)
        cols["feasible"] = self.feasible.reshape(-1)
        for name, (values, unit) in self.channels().items():
            cols[f"{name}_{unit_suffix(unit)}"] = values.reshape(-1)
        return pd.DataFrame(cols)


def unit_suffix(unit: str) -> str:
    """'mm/s^2' -> 'mm_s2' for column names."""
    return unit.replace("/", "_").replace("^", "")


