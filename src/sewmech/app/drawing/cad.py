"""A machine as a workshop drawing: the geometry of every link, joint, cam and path at one shaft
angle, as lines, true arcs, circles, points, polylines and text on named layers, ready for the
writers of :mod:`sewmech.app.files.cad` (DXF through ezdxf, SVG), which write the same
geometry.

What is drawn (mm, the machine's frame: x right, y up):

- every moving link on a layer of its name: its outline, the convex hull of its points grown by
  :attr:`CadStyle.link_radius` (straight edges and a true arc round each corner point), and its
  joints as holes (circles) on the layer ``joints``; the frame's pivots on ``frame``;
- every cam on a layer ``cam-NAME`` (the feed cam's is ``cam-feed_cam``): each circular arc of
  its profile as a true arc at the cam's position, each arc's centre as a point with a centre
  mark (two short lines), the bore on its shaft (a circle), and the
  follower's pitch curve: the path of the follower's trace point relative to the cam, turned
  with the cam to the drawing's angle. For a roller follower (a loop term's ``offset`` r > 0)
  the trace point is the roller's centre, and the pitch curve is the profile's arcs with radii
  R + r about the same centres (true arcs). For a flat face (offset 0) the trace point is the
  foot of the perpendicular from the cam's axis to the face, (h(n) + 0) n with h the profile's
  support function and n the face's normal relative to the cam, at the normals the face takes
  over a turn (a polyline);
- the paths over a turn of the needle eye, the take-up eye, the feed dog's tip and the shuttle
  point (the ``[sewing]`` roles; for a machine without them, every point that belongs to one
  link only) as polylines on layers ``path-POINT``;
- a title block on ``title``: the machine, its title, the values changed from its file, the
  shaft angle and the setting inputs, the scale (1:1, mm) and sewmech's version.

Angles of arcs are degrees counter-clockwise from +x, from start to end (DXF's convention).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Line:
    p0: tuple[float, float]
    p1: tuple[float, float]
    layer: str


@dataclass(frozen=True)
class Arc:
    """A circular arc counter-clockwise from ``start_deg`` to ``end_deg`` about ``centre``."""

    centre: tuple[float, float]
    radius: float
    start_deg: float
    end_deg: float
    layer: str


@dataclass(frozen=True)
class Circle:
    centre: tuple[float, float]
    radius: float
    layer: str


@dataclass(frozen=True)
class Point:
    p: tuple[float, float]
    layer: str


@dataclass(frozen=True)
class Polyline:
    points: tuple[tuple[float, float], ...]
    closed: bool
    layer: str


@dataclass(frozen=True)
class Text:
    p: tuple[float, float]
    height: float
    text: str
    layer: str


@dataclass(frozen=True)
class CadStyle:
    """Sizes of what is drawn, mm: link_radius (the outline's half width round each point),
    hole_radius (a joint's hole), text_height (the title block's text)."""

    link_radius: float
    hole_radius: float
    text_height: float


@dataclass
class Drawing:
    """The entities of a drawing, its layers (name -> a colour index 1..255, DXF's ACI) in the
    order they were made, and its title block's lines."""

    entities: list = field(default_factory=list)
    layers: dict = field(default_factory=dict)
    title: list = field(default_factory=list)
    machine: str = ""
    phi_deg: float = 0.0

    def layer(self, name: str) -> str:
        if name not in self.layers:
            self.layers[name] = 1 + len(self.layers) % 7
        return name

    def add(self, entity) -> None:
        self.layer(entity.layer)
        self.entities.append(entity)

    def bounds(self) -> tuple[float, float, float, float]:
        xs, ys = [], []
        for e in self.entities:
            if isinstance(e, Line):
                xs += [e.p0[0], e.p1[0]]
                ys += [e.p0[1], e.p1[1]]
            elif isinstance(e, (Arc, Circle)):
                xs += [e.centre[0] - e.radius, e.centre[0] + e.radius]
                ys += [e.centre[1] - e.radius, e.centre[1] + e.radius]
            elif isinstance(e, Point):
                xs.append(e.p[0])
                ys.append(e.p[1])
            elif isinstance(e, Polyline):
                xs += [p[0] for p in e.points]
                ys += [p[1] for p in e.points]
        return (min(xs), min(ys), max(xs), max(ys)) if xs else (0.0, 0.0, 1.0, 1.0)


def _pt(v) -> tuple[float, float]:
    return (float(v[0]), float(v[1]))


def _hull(points: np.ndarray) -> np.ndarray:
    """The convex hull's vertices, counter-clockwise (Andrew's monotone chain); collinear and
    repeated points dropped."""
    pts = sorted({(round(float(x), 9), round(float(y), 9)): (float(x), float(y))
                  for x, y in points}.values())
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-12:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-12:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def rounded_hull(points: np.ndarray, r: float, layer: str) -> list:
    """The outline of the points' convex hull grown by ``r``: an edge offset outward by r for
    each hull edge and a true arc of radius r round each hull vertex (a circle for one point,
    the slot shape for two)."""
    h = _hull(points)
    if len(h) == 1:
        return [Circle(_pt(h[0]), r, layer)]
    out = []
    n = len(h)
    for i in range(n):
        a, b = h[i], h[(i + 1) % n]
        d = (b - a) / np.hypot(*(b - a))
        nrm = np.array([d[1], -d[0]])  # outward for a counter-clockwise hull
        out.append(Line(_pt(a + r * nrm), _pt(b + r * nrm), layer))
    for i in range(n):
        prev, cur, nxt = h[i - 1], h[i], h[(i + 1) % n]
        d0 = (cur - prev) / np.hypot(*(cur - prev))
        d1 = (nxt - cur) / np.hypot(*(nxt - cur))
        a0 = math.degrees(math.atan2(-d0[0], d0[1]))  # outward normals of the two edges
        a1 = math.degrees(math.atan2(-d1[0], d1[1]))
        out.append(Arc(_pt(cur), r, a0 % 360.0, a1 % 360.0, layer))
    return out


def default_style(machine, xy: np.ndarray) -> CadStyle:
    finite = xy[np.all(np.isfinite(xy), axis=-1)]
    span = float(np.ptp(finite, axis=0).max()) if len(finite) else 100.0
    r = min(max(0.012 * span, 1.0), 6.0)
    return CadStyle(link_radius=r, hole_radius=0.4 * r, text_height=max(0.012 * span, 2.5))


def _cam_terms(machine) -> dict:
    """cam name -> [(normal link, normal_deg, offset)] of the loop terms that touch it."""
    out: dict = {}
    for u in machine.spec.units:
        for loop in getattr(u, "loops", None) or ():
            for t in loop.terms:
                if t.cam is not None and t.normal_link is not None:
                    out.setdefault(t.cam, []).append((t.normal_link, t.normal_deg, t.offset))
    return out


def cam_arcs(machine, params: np.ndarray, name: str) -> dict:
    """The arcs of cam ``name`` in its own frame for the design ``params``: cx, cy, radius,
    normal_from, normal_to (n,), mm and rad."""
    keys = ("cx", "cy", "radius", "normal_from", "normal_to")
    k = 0
    rows = {key: [] for key in keys}
    while f"{name}.arc{k}.cx" in machine.parameter_names:
        for key in keys:
            rows[key].append(params[machine.parameter_index(f"{name}.arc{k}.{key}")])
        k += 1
    return {key: np.array(v, dtype=float) for key, v in rows.items()}


def machine_drawing(machine, *, phi_deg: float = 0.0, params=None, inputs=None,
                    part: str | None = None, style: CadStyle | None = None,
                    version: str = "", changes: dict | None = None) -> Drawing:
    """The drawing of ``machine`` (design ``params``, setting ``inputs`` rad) at the shaft angle
    ``phi_deg``. ``part``: a link or a cam: only it (its outline, joints, cam and pitch curve)
    and the title block. ``changes``: values changed from the file (internal units) for the
    title block, besides the machine's own (``--set``)."""
    from ...engine.cams import support
    from ...engine.kinematics import kinematics
    from .mechanism import link_points

    P = machine.defaults if params is None else np.asarray(params, dtype=float)
    phi = math.radians(phi_deg)
    turn = np.radians(np.arange(0.0, 360.0, 1.0))
    grid = np.concatenate([[phi], turn])
    r = kinematics(machine, grid, params=P, inputs=inputs, on_failure="mask")
    if not r.feasible[0]:
        from ...engine.errors import OptionError

        raise OptionError("--phi-deg", f"{machine.name} cannot be assembled at phi ="
                          f" {phi_deg:g} deg", "Give an angle where it assembles")
    names = list(r.point_names)
    xy = {n: r.p[0, i] for i, n in enumerate(names)}
    style = style or default_style(machine, r.p[0])
    d = Drawing(machine=machine.name, phi_deg=phi_deg)
    cams = machine.spec.cams
    if part is not None:
        known = set(machine.link_names) | set(cams)
        if part not in known:
            import difflib

            from ...engine.errors import OptionError

            near = difflib.get_close_matches(part, sorted(known), n=3)
            raise OptionError("--part", f"'{part}' is no link or cam of {machine.name}",
                              f"Did you mean {', '.join(near)}?" if near else
                              f"Links and cams: {', '.join(sorted(known))}")
    links = link_points(machine)
    theta = {n: r.theta[0, i] for i, n in enumerate(r.link_names)}

    def wanted(link: str) -> bool:
        return part is None or part == link

    cam_links = {c.link: c.pivot for c in cams.values()}
    for link, pts in links.items():
        if not wanted(link):
            continue
        if cam_links.get(link) is not None and set(pts) <= {cam_links[link]}:
            continue  # a cam's own link: the cam is its outline (below)
        q = np.array([xy[p] for p in pts])
        for e in rounded_hull(q, style.link_radius, d.layer(link)):
            d.add(e)
        for p in pts:
            if len(machine.point_links.get(p, ())) > 1:
                d.add(Circle(_pt(xy[p]), style.hole_radius, "joints"))
    if part is None:
        for p, owners in machine.point_links.items():
            if "frame" in owners and p in xy:
                d.add(Circle(_pt(xy[p]), style.hole_radius, "frame"))
                if len(owners) > 1:  # a pivot: a cross
                    h = 2.0 * style.hole_radius
                    d.add(Line(_pt(xy[p] - [h, 0]), _pt(xy[p] + [h, 0]), "frame"))
                    d.add(Line(_pt(xy[p] - [0, h]), _pt(xy[p] + [0, h]), "frame"))
    terms = _cam_terms(machine)
    for name, cam in cams.items():
        if part is not None and part not in (name, cam.link):
            continue
        layer = d.layer(f"cam-{name}")
        arcs = cam_arcs(machine, P, name)
        th = theta.get(cam.link, 0.0)
        origin = xy[cam.pivot]
        c, s = math.cos(th), math.sin(th)

        def to_frame(u, v, origin=origin, c=c, s=s):
            return (float(origin[0] + c * u - s * v), float(origin[1] + s * u + c * v))

        for cx, cy, R, n0, n1 in zip(arcs["cx"], arcs["cy"], arcs["radius"],
                                     arcs["normal_from"], arcs["normal_to"], strict=True):
            centre = to_frame(cx, cy)
            if n1 - n0 >= 2 * math.pi - 1e-12:
                d.add(Circle(centre, float(R), layer))
            else:
                d.add(Arc(centre, float(R), math.degrees(n0 + th) % 360.0,
                          math.degrees(n1 + th) % 360.0, layer))
            d.add(Point(centre, layer))
            m_ = 0.5 * style.hole_radius  # a centre mark
            d.add(Line((centre[0] - m_, centre[1]), (centre[0] + m_, centre[1]), layer))
            d.add(Line((centre[0], centre[1] - m_), (centre[0], centre[1] + m_), layer))
        d.add(Circle(_pt(origin), style.hole_radius, layer))  # the cam's bore on its shaft
        for normal_link, normal_deg, offset in terms.get(name, ()):
            if offset > 0.0:  # a roller: its centre's path, the arcs grown by r
                for cx, cy, R, n0, n1 in zip(arcs["cx"], arcs["cy"], arcs["radius"],
                                             arcs["normal_from"], arcs["normal_to"],
                                             strict=True):
                    centre = to_frame(cx, cy)
                    if n1 - n0 >= 2 * math.pi - 1e-12:
                        d.add(Circle(centre, float(R + offset), layer))
                    else:
                        d.add(Arc(centre, float(R + offset), math.degrees(n0 + th) % 360.0,
                                  math.degrees(n1 + th) % 360.0, layer))
                continue
            # a flat face: the foot of the perpendicular from the axis, (h(n)) n, at the
            # normals (relative to the cam) the face takes over the turn
            i_n = r.link_names.index(normal_link)
            i_c = r.link_names.index(cam.link)
            rel = r.theta[1:, i_n] + math.radians(normal_deg) - r.theta[1:, i_c]
            ok = np.isfinite(rel)
            rel = rel[ok]
            h = support(arcs, rel)
            pts = [to_frame(hh * math.cos(a), hh * math.sin(a)) for hh, a in zip(h, rel,
                                                                                  strict=True)]
            closed = bool(np.ptp(np.unwrap(rel)) >= 2 * math.pi - 0.05)
            d.add(Polyline(tuple(pts), closed, layer))
    if part is None:
        for p in _path_points(machine, names):
            path = r.p[1:, names.index(p)]
            path = path[np.all(np.isfinite(path), axis=-1)]
            if len(path) > 1 and np.ptp(path, axis=0).max() > 1e-9:
                d.add(Polyline(tuple(_pt(q) for q in path), True, f"path-{p}"))
    d.title = title_lines(machine, phi_deg, inputs, part, version, P, changes)
    return d


def _path_points(machine, names) -> list[str]:
    s = machine.spec.sewing
    if s is not None:
        roles = [getattr(s, k, None) for k in ("needle_eye", "take_up_eye", "feed_dog",
                                               "shuttle_point")]
        return [p for p in roles if p in names]
    return [p for p in names if len(machine.point_links.get(p, ())) == 1
            and machine.point_links[p] != ("frame",)]


def title_lines(machine, phi_deg: float, inputs, part, version: str, params=None,
                changes: dict | None = None) -> list[str]:
    """The title block's lines: the machine (and part), its title, the angle and scale, every
    setting input, the values changed from its file (mm, rad as the parameters), sewmech."""
    lines = [f"{machine.name}" + (f": {part}" if part else ""),
             machine.spec.machine.title or "",
             f"shaft angle phi = {phi_deg:g} deg; scale 1:1, mm"]
    settings = dict(inputs or {})
    for name in machine.spec.inputs:
        v = settings.get(name)
        if v is None:
            P = machine.defaults if params is None else params
            v = float(P[machine.parameter_index(f"input.{name}")])
        lines.append(f"input {name} = {math.degrees(v):.6g} deg")
    changed = {**machine.changes, **(changes or {})}
    if changed:
        lines.append("design values changed from the file: " + ", ".join(
            f"{k} = {v:.6g}" for k, v in changed.items()))
    lines.append(f"drawn by sewmech {version}".rstrip())
    return [ln for ln in lines if ln]
