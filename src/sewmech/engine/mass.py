"""Mass properties of machine parts from elementary solids.

A part is built from solids in the part's own frame (x, y, z in mm): solid and hollow
cylinders, cones, frustums, boxes, spheres, each placed by a position and an axis (or a rotation),
and holes as negative solids. ``compose`` adds them with the parallel-axis rule in tensor form,
I_O = I_C + m (|d|^2 E - d d^T) ([Meriam-Kraige]).

Units: lengths mm, mass kg, inertia kg mm^2, densities kg/m^3 at the edges (``density``
arguments), converted inside. The inertia tensor is the full 3 x 3 matrix about the centre of
mass with the products of inertia as off-diagonal terms: I = integral (|r|^2 E - r r^T) dm,
so I[0, 1] = -integral x y dm.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

#: typical densities, kg/m^3 [estimates: handbook values for plain carbon steel, grey cast iron,
#: aluminium alloy, brass, cast lead (the balancing paper's counterweight inserts)]
MATERIALS = {"steel": 7850.0, "cast_iron": 7200.0, "aluminium": 2700.0, "brass": 8500.0,
             "lead": 11340.0}

_KG_PER_M3_TO_KG_PER_MM3 = 1e-9


@dataclass(frozen=True)
class MassProperties:
    """Mass (kg), centre of mass (mm, part frame) and inertia tensor about it (kg mm^2).

    A negative mass is a hole: composing it subtracts the material.
    """

    mass: float
    com: np.ndarray = field(repr=True)
    inertia: np.ndarray = field(repr=True)

    def about(self, point: ArrayLike) -> np.ndarray:
        """Inertia tensor about ``point`` (mm), same axes (parallel-axis rule), kg mm^2."""
        d = self.com - np.asarray(point, dtype=float)
        return self.inertia + self.mass * (float(d @ d) * np.eye(3) - np.outer(d, d))

    def moved(self, rotation: ArrayLike | None = None,
              translation: ArrayLike = (0.0, 0.0, 0.0)) -> MassProperties:
        """The same body turned by ``rotation`` (3 x 3, about the frame origin) and then shifted
        by ``translation`` (mm)."""
        R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
        return MassProperties(self.mass, R @ self.com + np.asarray(translation, dtype=float),
                              R @ self.inertia @ R.T)

    @property
    def planar(self) -> tuple[float, np.ndarray, float]:
        """(mass kg, centre of mass (x, y) mm, I_zz about it kg mm^2): what a planar link needs
        when its plane is the xy plane of the part frame."""
        return self.mass, self.com[:2].copy(), float(self.inertia[2, 2])

    @property
    def principal(self) -> tuple[np.ndarray, np.ndarray]:
        """Principal moments (ascending, kg mm^2) and axes (columns)."""
        w, v = np.linalg.eigh(self.inertia)
        return w, v


def compose(parts: Iterable[MassProperties]) -> MassProperties:
    """One body from several (holes are parts with negative mass)."""
    parts = list(parts)
    if not parts:
        raise ValueError("compose() needs at least one part")
    m = sum(p.mass for p in parts)
    if not m > 0.0:
        raise ValueError(f"the composed mass is {m:.6g} kg: the holes remove more than the"
                         " solids hold")
    com = sum(p.mass * p.com for p in parts) / m
    inertia = sum(p.about(com) for p in parts)
    return MassProperties(float(m), com, inertia)


def _rotation_z_to(axis: ArrayLike) -> np.ndarray:
    """A rotation that takes +z to the unit vector of ``axis`` (axisymmetric solids: the turn
    about the axis does not matter)."""
    a = np.asarray(axis, dtype=float)
    n = np.linalg.norm(a)
    if not n > 0.0:
        raise ValueError(f"axis must be a non-zero vector, got {axis!r}")
    a = a / n
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, a)
    s = np.linalg.norm(v)
    c = float(z @ a)
    if s < 1e-15:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = v / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def _positive(**values):
    for name, v in values.items():
        if not v > 0.0:
            raise ValueError(f"{name} must be positive (mm or kg/m^3), got {v!r}")


def _axisymmetric(m, zc, izz, ixx, base, axis, hole) -> MassProperties:
    """A solid of revolution about local z with its centroid at local z = zc."""
    sign = -1.0 if hole else 1.0
    local = MassProperties(sign * m, np.array([0.0, 0.0, zc]),
                           sign * np.diag([ixx, ixx, izz]))
    return local.moved(_rotation_z_to(axis), base)


def cylinder(radius: float, length: float, density: float, *, base: ArrayLike = (0, 0, 0),
             axis: ArrayLike = (0, 0, 1), hole: bool = False) -> MassProperties:
    """Solid cylinder; ``base`` is the centre of one end face, ``axis`` points to the other."""
    _positive(radius=radius, length=length, density=density)
    m = density * _KG_PER_M3_TO_KG_PER_MM3 * math.pi * radius**2 * length
    return _axisymmetric(m, length / 2, m * radius**2 / 2, m * (3 * radius**2 + length**2) / 12,
                         base, axis, hole)


def hollow_cylinder(r_out: float, r_in: float, length: float, density: float, *,
                    base: ArrayLike = (0, 0, 0), axis: ArrayLike = (0, 0, 1),
                    hole: bool = False) -> MassProperties:
    """Tube (bush, hub) of outer and inner radius."""
    _positive(r_out=r_out, length=length, density=density)
    if not 0.0 <= r_in < r_out:
        raise ValueError(f"r_in must be in [0, r_out), got r_in={r_in}, r_out={r_out}")
    m = density * _KG_PER_M3_TO_KG_PER_MM3 * math.pi * (r_out**2 - r_in**2) * length
    s = r_out**2 + r_in**2
    return _axisymmetric(m, length / 2, m * s / 2, m * (3 * s + length**2) / 12, base, axis,
                         hole)


def frustum(r1: float, r2: float, height: float, density: float, *,
            base: ArrayLike = (0, 0, 0), axis: ArrayLike = (0, 0, 1),
            hole: bool = False) -> MassProperties:
    """Truncated cone: radius r1 at ``base``, r2 at ``height`` along ``axis`` (r2 = 0: a cone)."""
    _positive(r1=r1, height=height, density=density)
    if r2 < 0.0:
        raise ValueError(f"r2 must be >= 0, got {r2}")
    q = r1**2 + r1 * r2 + r2**2
    m = density * _KG_PER_M3_TO_KG_PER_MM3 * math.pi * height * q / 3
    zc = height * (r1**2 + 2 * r1 * r2 + 3 * r2**2) / (4 * q)
    # I_zz = (3m/10)(r1^5 - r2^5)/(r1^3 - r2^3), written without the 0/0 at r1 = r2
    izz = 0.3 * m * (r1**4 + r1**3 * r2 + r1**2 * r2**2 + r1 * r2**3 + r2**4) / q
    ixx = 3 * m * (4 * r1**6 + 8 * r1**5 * r2 + 12 * r1**4 * r2**2 + 12 * r1**3 * r2**3
                   + 12 * r1**2 * r2**4 + 8 * r1 * r2**5 + 4 * r2**6
                   + height**2 * (r1**4 + 4 * r1**3 * r2 + 10 * r1**2 * r2**2 + 4 * r1 * r2**3
                                  + r2**4)) / (80 * q**2)
    return _axisymmetric(m, zc, izz, ixx, base, axis, hole)


def cone(radius: float, height: float, density: float, *, base: ArrayLike = (0, 0, 0),
         axis: ArrayLike = (0, 0, 1), hole: bool = False) -> MassProperties:
    """Solid cone: base circle at ``base``, apex ``height`` along ``axis``."""
    return frustum(radius, 0.0, height, density, base=base, axis=axis, hole=hole)


def box(a: float, b: float, c: float, density: float, *, center: ArrayLike = (0, 0, 0),
        rotation: ArrayLike | None = None, hole: bool = False) -> MassProperties:
    """Rectangular block, edges a, b, c along the (rotated) x, y, z axes, centred at ``center``."""
    _positive(a=a, b=b, c=c, density=density)
    m = density * _KG_PER_M3_TO_KG_PER_MM3 * a * b * c
    sign = -1.0 if hole else 1.0
    local = MassProperties(sign * m, np.zeros(3),
                           sign * m / 12 * np.diag([b**2 + c**2, a**2 + c**2, a**2 + b**2]))
    return local.moved(rotation, center)


def sphere(radius: float, density: float, *, center: ArrayLike = (0, 0, 0),
           hole: bool = False) -> MassProperties:
    """Solid sphere."""
    _positive(radius=radius, density=density)
    m = density * _KG_PER_M3_TO_KG_PER_MM3 * 4 / 3 * math.pi * radius**3
    sign = -1.0 if hole else 1.0
    return MassProperties(sign * m, np.asarray(center, dtype=float),
                          sign * 0.4 * m * radius**2 * np.eye(3))


def point_mass(mass: float, at: Sequence[float]) -> MassProperties:
    """A concentrated mass (kg) at a point (mm): a pin, a screw, a counterweight insert."""
    _positive(mass=mass)
    return MassProperties(float(mass), np.asarray(at, dtype=float), np.zeros((3, 3)))


def check_inertia(inertia: np.ndarray, what: str = "inertia") -> None:
    """Raise ValueError unless a 3 x 3 inertia tensor (kg mm^2) is physical: symmetric,
    positive semi-definite, its principal moments meeting the triangle inequalities
    (I1 <= I2 + I3 and its permutations: no body has more inertia about one axis than about the
    two others together)."""
    inertia = np.asarray(inertia, dtype=float)
    if not np.isfinite(inertia).all():
        raise ValueError(f"{what} has entries that are not finite numbers")
    scale = max(float(np.abs(inertia).max()), 1e-300)
    if not np.allclose(inertia, inertia.T, rtol=0.0, atol=1e-9 * scale):
        raise ValueError(f"{what} must be a symmetric 3 x 3 tensor (I[i][j] = I[j][i])")
    w = np.linalg.eigvalsh(inertia)
    tol = 1e-9 * scale
    if w[0] < -tol:
        raise ValueError(f"{what} is not positive semi-definite: a principal moment is"
                         f" {w[0]:.6g} kg mm^2 (the kinetic energy would be negative); check"
                         " the signs of the products of inertia and the moments")
    if w[2] > w[0] + w[1] + tol:
        raise ValueError(f"{what}: the principal moments {w[0]:.6g}, {w[1]:.6g}, {w[2]:.6g}"
                         " kg mm^2 break the triangle inequality (the largest must not exceed"
                         " the sum of the other two): no real body has them")


def _volume_points(s, n: int = 9) -> np.ndarray:
    """Points (mm, part frame) spread through the volume of a solid spec: an n x n x n grid
    over its bounding box in its own frame, kept where they lie inside it."""
    if s.type == "point":
        return np.asarray([s.at], dtype=float)
    g = (np.arange(n) + 0.5) / n
    u, v, w = (x.ravel() for x in np.meshgrid(g, g, g, indexing="ij"))
    if s.type == "sphere":
        local = (np.stack([u, v, w], axis=1) * 2 - 1) * s.radius
        pts = np.asarray(s.center, dtype=float) + local
    elif s.type == "box":
        a = math.radians(s.angle_deg)
        R = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0],
                      [0.0, 0.0, 1.0]])
        local = (np.stack([u, v, w], axis=1) - 0.5) * np.asarray(s.size)
        pts = np.asarray(s.center, dtype=float) + local @ R.T
    else:
        r = {"cylinder": lambda: s.radius, "hollow_cylinder": lambda: s.r_out}.get(
            s.type, lambda: max(s.r1, s.r2))()
        h = s.length if s.type in ("cylinder", "hollow_cylinder") else s.height
        local = np.stack([(2 * u - 1) * r, (2 * v - 1) * r, w * h], axis=1)
        pts = np.asarray(s.base, dtype=float) + local @ _rotation_z_to(s.axis).T
    return pts[_inside(s, pts, 0.0)]


def _inside(s, pts: np.ndarray, tol: float) -> np.ndarray:
    """Which points (mm, part frame) lie in the material of a solid spec (within ``tol``)."""
    if s.type == "point":
        return np.zeros(len(pts), dtype=bool)
    if s.type == "sphere":
        return np.linalg.norm(pts - np.asarray(s.center), axis=1) <= s.radius + tol
    if s.type == "box":
        a = math.radians(s.angle_deg)
        R = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0],
                      [0.0, 0.0, 1.0]])
        local = (pts - np.asarray(s.center)) @ R
        return (np.abs(local) <= np.asarray(s.size) / 2 + tol).all(axis=1)
    local = (pts - np.asarray(s.base, dtype=float)) @ _rotation_z_to(s.axis)
    t = local[:, 2]
    rho = np.hypot(local[:, 0], local[:, 1])
    if s.type == "cylinder":
        h, r_out, r_in = s.length, np.full(len(pts), s.radius), 0.0
    elif s.type == "hollow_cylinder":
        h, r_out, r_in = s.length, np.full(len(pts), s.r_out), s.r_in
    else:
        h = s.height
        r_out = s.r1 + (s.r2 - s.r1) * np.clip(t / h, 0.0, 1.0)
        r_in = 0.0
    return (t >= -tol) & (t <= h + tol) & (rho <= r_out + tol) & (rho >= r_in - tol)


#: the largest share of a hole's volume that may lie outside the solids it is cut from: elementary
#: solids approximate real parts (a box cut in a ring overshoots its curved faces a little)
HOLE_OUTSIDE_SHARE = 0.05


def check_holes(solids) -> None:
    """Raise ValueError (naming ``solids[k]``) if more than :data:`HOLE_OUTSIDE_SHARE` of a
    hole's volume lies outside the material of the solids that are not holes (sampled on a grid
    through the hole): subtracting it would remove material that is not there."""
    full = [s for s in solids if not s.hole]
    for k, s in enumerate(solids):
        if not s.hole:
            continue
        pts = _volume_points(s)
        inside = np.zeros(len(pts), dtype=bool)
        tol = 1e-9 * (1.0 + float(np.abs(pts).max())) if len(pts) else 0.0
        for f in full:
            inside |= _inside(f, pts, tol)
        share = 1.0 - float(inside.mean()) if len(pts) else 0.0
        if share > HOLE_OUTSIDE_SHARE:
            p = pts[~inside][0]
            raise ValueError(f"solids[{k}] (a {s.type} hole): {100 * share:.0f} % of it lies"
                             f" outside the material (e.g. the point ({p[0]:.4g}, {p[1]:.4g},"
                             f" {p[2]:.4g}) mm is in none of the solids); a hole must lie inside"
                             " the solids it is cut from: move it, make it smaller, or add the"
                             " solid it is cut from")


def from_spec(spec) -> MassProperties:
    """Mass properties of one ``[masses.LINK]`` table (:class:`sewmech.spec.MassSpec`).

    Measured values with only ``inertia_zz`` give a planar body: its I_xx, I_yy and products
    with z are unknown (NaN), which the planar analyses never read.
    """
    if spec.mass is not None:
        com = np.zeros(3)
        com[: len(spec.com)] = spec.com
        if spec.inertia is not None:
            inertia = np.asarray(spec.inertia, dtype=float)
            check_inertia(inertia)
        else:
            inertia = np.full((3, 3), np.nan)
            inertia[2, 2] = spec.inertia_zz
            inertia[0, 1] = inertia[1, 0] = np.nan
        return MassProperties(float(spec.mass), com, inertia)
    check_holes(spec.solids)
    link_rho = spec.density if spec.density is not None else MATERIALS[spec.material]
    parts = []
    for s in spec.solids:
        rho = (s.density if s.density is not None else
               MATERIALS[s.material] if s.material is not None else link_rho)
        if s.type == "cylinder":
            parts.append(cylinder(s.radius, s.length, rho, base=s.base, axis=s.axis, hole=s.hole))
        elif s.type == "hollow_cylinder":
            parts.append(hollow_cylinder(s.r_out, s.r_in, s.length, rho, base=s.base,
                                         axis=s.axis, hole=s.hole))
        elif s.type in ("frustum", "cone"):
            parts.append(frustum(s.r1, s.r2, s.height, rho, base=s.base, axis=s.axis,
                                 hole=s.hole))
        elif s.type == "box":
            a = math.radians(s.angle_deg)
            R = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0],
                          [0.0, 0.0, 1.0]])
            parts.append(box(*s.size, rho, center=s.center, rotation=R, hole=s.hole))
        elif s.type == "sphere":
            parts.append(sphere(s.radius, rho, center=s.center, hole=s.hole))
        else:
            p = point_mass(s.mass, s.at)
            parts.append(MassProperties(-p.mass, p.com, -p.inertia) if s.hole else p)
    body = compose(parts)
    check_inertia(body.inertia, "the composed inertia")
    return body
