"""Mass properties against numerical integration written here (Gauss-Legendre quadrature over
each solid's own coordinates), not against the closed forms the package uses."""

import math

import numpy as np
import pytest

from sewmech import mass as M

RHO = 7850.0  # kg/m^3
RHO_MM = RHO * 1e-9  # kg/mm^3


def _gl(n, a, b):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (b - a) * x + 0.5 * (b + a), 0.5 * (b - a) * w


def _integrate(points, weights):
    """mass, com, inertia about the com of point samples with volume weights (density RHO)."""
    dm = RHO_MM * weights
    m = dm.sum()
    com = (points * dm[:, None]).sum(0) / m
    r = points - com
    r2 = (r * r).sum(1)
    inertia = (dm[:, None, None] * (r2[:, None, None] * np.eye(3) - r[:, :, None] * r[:, None, :])).sum(0)
    return m, com, inertia


def _revolution(r_of_z, z0, z1, r_in=0.0, n=40):
    """Quadrature points of a solid of revolution about z: radius r_in..r_of_z(z), z0..z1."""
    zs, wz = _gl(n, z0, z1)
    th, wt = _gl(n, 0.0, 2 * math.pi)
    pts, ws = [], []
    for z, w1 in zip(zs, wz):
        rs, wr = _gl(n, r_in, r_of_z(z))
        for r, w2 in zip(rs, wr):
            for t, w3 in zip(th, wt):
                pts.append((r * math.cos(t), r * math.sin(t), z))
                ws.append(w1 * w2 * w3 * r)
    return np.array(pts), np.array(ws)


def _same(mp, ref, rtol=1e-9):
    m, com, inertia = ref
    assert mp.mass == pytest.approx(m, rel=rtol)
    np.testing.assert_allclose(mp.com, com, atol=1e-9 * max(1.0, np.abs(com).max()))
    np.testing.assert_allclose(mp.inertia, inertia, atol=rtol * np.abs(inertia).max())


def test_cylinder_and_tube():
    _same(M.cylinder(6.0, 40.0, RHO), _integrate(*_revolution(lambda z: 6.0, 0, 40)))
    _same(M.hollow_cylinder(10.0, 6.0, 25.0, RHO),
          _integrate(*_revolution(lambda z: 10.0, 0, 25, r_in=6.0)))


@pytest.mark.parametrize("r1,r2,h", [(10.0, 4.0, 30.0), (3.0, 9.0, 12.0), (8.0, 0.0, 20.0),
                                     (5.0, 5.0, 10.0)])
def test_frustum_and_cone(r1, r2, h):
    ref = _integrate(*_revolution(lambda z: r1 + (r2 - r1) * z / h, 0, h))
    _same(M.frustum(r1, r2, h, RHO), ref)
    if r2 == 0.0:
        _same(M.cone(r1, h, RHO), ref)


def test_box_turned_has_products_of_inertia():
    a, b, c = 30.0, 12.0, 5.0
    xs, wx = _gl(6, -a / 2, a / 2)
    ys, wy = _gl(6, -b / 2, b / 2)
    zs, wz = _gl(6, -c / 2, c / 2)
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    W = (wx[:, None, None] * wy[None, :, None] * wz[None, None, :]).ravel()
    P = np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1)
    ang = math.radians(30.0)
    R = np.array([[math.cos(ang), -math.sin(ang), 0], [math.sin(ang), math.cos(ang), 0],
                  [0, 0, 1]])
    t = np.array([5.0, -3.0, 2.0])
    mp = M.box(a, b, c, RHO, center=t, rotation=R)
    _same(mp, _integrate(P @ R.T + t, W))
    assert abs(mp.inertia[0, 1]) > 1e-3 * mp.inertia[2, 2]  # the turn makes I_xy appear


def test_sphere():
    n = 30
    rs, wr = _gl(n, 0, 7.0)
    th, wt = _gl(n, 0, math.pi)
    ph, wp = _gl(n, 0, 2 * math.pi)
    R, T, F = np.meshgrid(rs, th, ph, indexing="ij")
    W = (wr[:, None, None] * wt[None, :, None] * wp[None, None, :] * R**2 * np.sin(T)).ravel()
    P = np.stack([(R * np.sin(T) * np.cos(F)).ravel(), (R * np.sin(T) * np.sin(F)).ravel(),
                  (R * np.cos(T)).ravel()], 1) + np.array([1.0, 2.0, 3.0])
    _same(M.sphere(7.0, RHO, center=(1, 2, 3)), _integrate(P, W))


def test_axis_and_placement():
    """A cylinder along +x starting at (10, 0, 0) equals the z cylinder turned and moved."""
    c = M.cylinder(4.0, 50.0, RHO, base=(10.0, 0.0, 0.0), axis=(1.0, 0.0, 0.0))
    pts, w = _revolution(lambda z: 4.0, 0, 50)
    pts = pts[:, [2, 1, 0]] * np.array([1.0, 1.0, -1.0]) + np.array([10.0, 0.0, 0.0])
    _same(c, _integrate(pts, w))


def test_holes_and_composition():
    """A crank: a disc with a bored hub hole and a counterweight bump, from solids and holes,
    against the quadrature of the same body assembled here point by point."""
    disc = M.cylinder(20.0, 8.0, RHO)
    bore = M.cylinder(4.0, 8.0, RHO, hole=True)
    pin = M.cylinder(3.0, 12.0, RHO, base=(12.0, 0.0, 8.0))
    body = M.compose([disc, bore, pin])
    p1, w1 = _revolution(lambda z: 20.0, 0, 8, r_in=4.0)
    p2, w2 = _revolution(lambda z: 3.0, 0, 12)
    p2 = p2 + np.array([12.0, 0.0, 8.0])
    _same(body, _integrate(np.vstack([p1, p2]), np.concatenate([w1, w2])))
    # a tube is a cylinder less its bore
    _same(M.compose([M.cylinder(10.0, 25.0, RHO), M.cylinder(6.0, 25.0, RHO, hole=True)]),
          (lambda t: (t.mass, t.com, t.inertia))(M.hollow_cylinder(10.0, 6.0, 25.0, RHO)))
    # the parallel-axis rule: about a point, against the quadrature directly
    m, com, _ = _integrate(np.vstack([p1, p2]), np.concatenate([w1, w2]))
    q = np.array([0.0, 0.0, 0.0])
    r = np.vstack([p1, p2]) - q
    dm = RHO_MM * np.concatenate([w1, w2])
    I_q = (dm[:, None, None] * ((r * r).sum(1)[:, None, None] * np.eye(3)
                                - r[:, :, None] * r[:, None, :])).sum(0)
    np.testing.assert_allclose(body.about(q), I_q, rtol=1e-9, atol=1e-9 * np.abs(I_q).max())
    assert body.planar[0] == pytest.approx(m) and np.allclose(body.planar[1], com[:2])


def test_bad_input():
    with pytest.raises(ValueError, match="radius must be positive"):
        M.cylinder(0.0, 5.0, RHO)
    with pytest.raises(ValueError, match="r_in must be"):
        M.hollow_cylinder(5.0, 6.0, 5.0, RHO)
    with pytest.raises(ValueError, match="holes remove more"):
        M.compose([M.sphere(2.0, RHO), M.sphere(3.0, RHO, hole=True)])
    assert M.MATERIALS["steel"] == 7850.0


import sewmech  # noqa: E402

FOURBAR = sewmech.shipped_machines()["fourbar-benchmark"].read_text()


def test_masses_in_a_machine_file():
    text = FOURBAR + """
[masses.crank]
material = "steel"
solids = [
  { type = "box", size = [25.0, 8.0, 5.0], center = [7.5, 0.0, 0.0] },
  { type = "cylinder", radius = 2.0, length = 5.0, base = [15.0, 0.0, -2.5], hole = true },
]

[masses.coupler]
mass = 0.035
com = [20.0, 1.5]
inertia_zz = 6.1
"""
    m = sewmech.machine_from_toml(text, "fb.toml")
    crank = m.masses["crank"]
    ref = M.compose([M.box(25.0, 8.0, 5.0, 7850.0, center=(7.5, 0, 0)),
                     M.cylinder(2.0, 5.0, 7850.0, base=(15.0, 0, -2.5), hole=True)])
    assert crank.mass == pytest.approx(ref.mass) and np.allclose(crank.inertia, ref.inertia)
    assert crank.mass == pytest.approx(7850e-9 * (25 * 8 * 5 - math.pi * 4 * 5))
    c = m.masses["coupler"]
    assert c.planar == (0.035, pytest.approx(np.array([20.0, 1.5])), 6.1)
    assert np.isnan(c.inertia[0, 0])  # measured planar values: the rest is unknown


@pytest.mark.parametrize("table,match", [
    ('[masses.crnk]\nmass = 1.0\ncom = [0.0, 0.0]\ninertia_zz = 1.0\n',
     r"masses\.crnk.*not a moving link.*crank"),
    ('[masses.crank]\nmass = 1.0\ncom = [0.0, 0.0]\n', "exactly one of inertia_zz, inertia"),
    ('[masses.crank]\nmaterial = "unobtainium"\nsolids = [ { type = "sphere", radius = 1.0 } ]\n',
     "unknown material"),
    ('[masses.crank]\ndensity = 7850.0\nsolids = [ { type = "sphere", radius = 1.0 },'
     ' { type = "sphere", radius = 2.0, hole = true } ]\n',
     r"solids: solids\[1\] \(a sphere hole\): 8\d % of it lies outside the material"),
])
def test_mass_table_errors(table, match):
    from sewmech.errors import MachineFileError

    with pytest.raises(MachineFileError, match=match):
        sewmech.machine_from_toml(FOURBAR + "\n" + table, "fb.toml")


def test_compose_refuses_holes_heavier_than_the_solids():
    with pytest.raises(ValueError, match="holes remove more"):
        M.compose([M.sphere(1.0, 7850.0), M.sphere(2.0, 7850.0, hole=True)])


def test_a_solid_can_have_its_own_material():
    from sewmech.mass import MATERIALS, from_spec
    from sewmech.spec import MassSpec

    spec = MassSpec(material="steel", solids=[
        {"type": "cylinder", "radius": 4.0, "length": 100.0},
        {"type": "cylinder", "radius": 20.0, "length": 10.0, "base": [0.0, 0.0, 100.0],
         "material": "cast_iron"}])
    mp = from_spec(spec)
    expect = (MATERIALS["steel"] * math.pi * 16.0 * 100.0
              + MATERIALS["cast_iron"] * math.pi * 400.0 * 10.0) * 1e-9
    assert math.isclose(mp.mass, expect, rel_tol=1e-12)
    with pytest.raises(ValueError, match="solids\\[0\\]: unknown material 'brass2'"):
        MassSpec(material="steel", solids=[{"type": "sphere", "radius": 1.0,
                                            "material": "brass2"}])
