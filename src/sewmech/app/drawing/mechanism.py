"""The mechanism drawn at one shaft angle, every named point and every pair labelled: the key to
the names that the force tables, the checks and the machine file use.

Links are drawn as the page draws them (every pair of a link's points joined, a light fill), the
frame's points as ground marks, sliders as a block on their guide's line, the paths of the
needle point, take-up eye, shuttle point and feed dog over the turn dashed. Labels are placed
by :func:`place_labels`: beside their point where there is room, further out with a leader line
where the drawing is crowded, never on top of another label or point when there is room for it.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

#: label font size, pt, and the width of one character of it (DejaVu Sans, on average), pt
FONT_PT = 6.5
CHAR_PT = 0.62 * FONT_PT
LINE_PT = 1.25 * FONT_PT
#: the gap kept around a label and the radius of a point marker, pt
PAD_PT = 1.5
MARK_PT = 2.5
#: how far from its anchor a label may go, pt (in rings of candidate places)
RINGS_PT = (4.0, 10.0, 18.0, 28.0, 40.0, 55.0, 75.0, 100.0, 130.0)
_DIRECTIONS = np.radians(np.arange(0.0, 360.0, 22.5))


def link_points(machine) -> dict[str, list[str]]:
    """The points of each moving link (its pins and named points), the frame left out."""
    links: dict[str, list[str]] = {}
    for pt, owners in machine.point_links.items():
        for link in owners:
            if link != "frame":
                links.setdefault(link, []).append(pt)
    return links


def draw_links(ax, xy: dict[str, np.ndarray], links: dict[str, list[str]], colors=None,
               lw: float = 2.2, fill: bool = True, single_color: str | None = None) -> None:
    """Each link as the page draws it: every pair of its points joined (a link of more than
    four points: from its first point), a light fill when it has three or more."""
    from matplotlib.patches import Polygon

    for j, (link, pts) in enumerate(links.items()):
        q = np.array([xy[p] for p in pts if p in xy and np.all(np.isfinite(xy[p]))])
        if len(q) < 2:
            continue
        col = single_color or (colors[j % len(colors)] if colors else f"C{j % 10}")
        if fill and len(q) >= 3:
            ax.add_patch(Polygon(q, closed=True, facecolor=col, alpha=0.10, lw=0))
        first = len(q) if len(q) <= 4 else 1
        segs = [(q[a], q[b]) for a in range(first) for b in range(a + 1, len(q))]
        for a, b in segs:
            ax.plot([a[0], b[0]], [a[1], b[1]], color=col, lw=lw, solid_capstyle="round",
                    zorder=2)


def _overlap(boxes: np.ndarray, others: np.ndarray) -> np.ndarray:
    """Total overlap area of each of ``boxes`` (k, 4: x0, y0, x1, y1) with ``others`` (m, 4)."""
    if len(others) == 0:
        return np.zeros(len(boxes))
    w = (np.minimum(boxes[:, None, 2], others[None, :, 2])
         - np.maximum(boxes[:, None, 0], others[None, :, 0]))
    h = (np.minimum(boxes[:, None, 3], others[None, :, 3])
         - np.maximum(boxes[:, None, 1], others[None, :, 1]))
    return (np.clip(w, 0.0, None) * np.clip(h, 0.0, None)).sum(axis=1)


def place_labels(anchors, sizes, bounds, prefer=None, marks=None, pad: float = PAD_PT):
    """Boxes for labels of ``sizes`` (n, 2: width, height) beside ``anchors`` (n, 2), all in
    the same units (points of the page), inside ``bounds`` (x0, y0, x1, y1).

    Each label in turn (the most crowded anchors first) takes the first free place on rings of
    growing distance around its anchor (``prefer``: an angle, rad, per label, tried first on
    each ring): free means not overlapping a label placed before it, nor a point of ``marks``
    (m, 2) other than its own anchor (each a square of :data:`MARK_PT`), each box grown by
    ``pad``. Where no place is free, the one with the least overlap. Returns (n, 4) boxes
    x0, y0, x1, y1."""
    anchors = np.asarray(anchors, dtype=float).reshape(-1, 2)
    sizes = np.asarray(sizes, dtype=float).reshape(-1, 2)
    marks = anchors if marks is None else np.asarray(marks, dtype=float).reshape(-1, 2)
    n = len(anchors)
    prefer = np.full(n, np.nan) if prefer is None else np.asarray(prefer, dtype=float)
    mark_boxes = np.hstack([marks - MARK_PT, marks + MARK_PT])
    d = np.linalg.norm(anchors[:, None, :] - anchors[None, :, :], axis=-1)
    order = np.argsort(-(d < 40.0).sum(axis=1), kind="stable")
    rings = np.repeat(np.asarray(RINGS_PT), len(_DIRECTIONS))
    placed = np.zeros((0, 4))
    out = np.zeros((n, 4))
    x0, y0, x1, y1 = bounds
    grow = np.array([-pad, -pad, pad, pad])
    for i in order:
        w, h = sizes[i]
        dirs = _DIRECTIONS
        if np.isfinite(prefer[i]):
            gap = np.abs((dirs - prefer[i] + np.pi) % (2 * np.pi) - np.pi)
            dirs = dirs[np.argsort(gap, kind="stable")]
        t = np.tile(dirs, len(RINGS_PT))
        c, s = np.cos(t), np.sin(t)
        m = np.maximum(np.abs(c), np.abs(s))
        # each candidate box's nearest side is a ring's distance from the anchor along t
        cx = anchors[i, 0] + c * (rings + 0.5 * w * np.abs(c) / m)
        cy = anchors[i, 1] + s * (rings + 0.5 * h * np.abs(s) / m)
        boxes = np.stack([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], axis=1)
        inside = (boxes[:, 0] >= x0) & (boxes[:, 2] <= x1) & (boxes[:, 1] >= y0) & (
            boxes[:, 3] <= y1)
        if not inside.any():  # no place inside the bounds: beside the anchor
            out[i] = [anchors[i, 0] + 4, anchors[i, 1] + 4, anchors[i, 0] + 4 + w,
                      anchors[i, 1] + 4 + h]
        else:
            own = np.all(np.abs(marks - anchors[i]) < 1e-9, axis=1)
            grown = boxes + grow
            cost = _overlap(grown, placed) + _overlap(grown, mark_boxes[~own])
            cost[~inside] = np.inf
            free = np.flatnonzero(cost == 0.0)
            out[i] = boxes[free[0] if free.size else int(np.argmin(cost))]
        placed = np.vstack([placed, out[i]])
    return out


def _labels(machine, xy: dict[str, np.ndarray]) -> list[dict]:
    """Every point and every pair with where its label belongs: (name, kind, links, anchor,
    preferred direction, text). A pin named as its point shares the point's label."""
    pairs = list(machine.pairs)
    rows = []
    for pt in machine.point_names:
        owners = machine.point_links.get(pt, ())
        kind = ("frame point" if tuple(owners) == ("frame",) else
                "pivot" if "frame" in owners else "point")
        rows.append({"name": pt, "kind": kind, "links": ", ".join(owners), "at": pt,
                     "label": True, "prefer": math.nan})
    point_set = set(machine.point_names)
    cams = machine.spec.cams
    for p in pairs:
        links = " -> ".join(p.links)
        if p.name in point_set:  # a pin named as its point: the point's label names it
            rows.append({"name": p.name, "kind": f"{p.kind} pair", "links": links, "at": p.name,
                         "label": False, "prefer": math.nan})
            continue
        at, towards = p.point, p.links[1]
        if p.kind == "driver" or (at is None and p.kind != "cam"):
            shared = [q for q in machine.point_names
                      if set(p.links) <= set(machine.point_links.get(q, ()))]
            at = shared[0] if shared else None
        elif p.kind == "cam":
            cam = next((c for c in cams.values() if c.link == p.links[0]), None)
            at = cam.pivot if cam is not None else None
        if at is None or at not in xy:
            continue
        prefer = math.nan
        other = [xy[q] for q in machine.point_names if q != at and q in xy
                 and towards in machine.point_links.get(q, ())]
        if other:
            v = np.mean(other, axis=0) - xy[at]
            if np.hypot(*v) > 1e-9:
                prefer = math.atan2(v[1], v[0])
        rows.append({"name": p.name, "kind": f"{p.kind} pair", "links": links, "at": at,
                     "label": True, "prefer": prefer})
    return rows


def mechanism_figure(machine, res, k: int, *, title: str, max_height_in: float = 11.0):
    """The labelled drawing of ``machine`` at the angle of index ``k`` of the kinematics
    result ``res`` (every point, every link; its paths over the turn come from the whole
    result). Returns (figure, data): the data has a row for every point and every pair with
    its place at that angle and its label's place, mm."""
    from .figures import subplots

    names = list(res.point_names)
    P = res.p
    xy = {n: P[k, i] for i, n in enumerate(names) if np.all(np.isfinite(P[k, i]))}
    finite = P[np.all(np.isfinite(P), axis=-1)]
    lo, hi = finite.min(axis=0), finite.max(axis=0)
    span = max(float((hi - lo).max()), 1.0)
    margin = 0.16 * span
    lo, hi = lo - margin, hi + margin
    dx, dy = hi - lo
    width_in = 9.0
    frame_w, frame_h = 0.4, 0.5  # inches around the axes (ticks, title)
    s = (width_in - 2 * frame_w) * 72.0 / dx  # pt per mm
    if dy * s / 72.0 + 2 * frame_h > max_height_in:
        s = (max_height_in - 2 * frame_h) * 72.0 / dy
    ax_w, ax_h = dx * s / 72.0, dy * s / 72.0
    fig_w, fig_h = max(ax_w + 2 * frame_w, 5.0), ax_h + 2 * frame_h
    fig, ax = subplots(figsize=(fig_w, fig_h))
    ax.set_position([(fig_w - ax_w) / 2 / fig_w, frame_h / fig_h, ax_w / fig_w, ax_h / fig_h])
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal", adjustable="box")
    ax.grid(True, alpha=0.2)
    ax.tick_params(labelsize=7)
    ax.set_xlabel("x [mm]", fontsize=8)
    ax.set_ylabel("y [mm]", fontsize=8)

    sewing = machine.spec.sewing
    if sewing is not None:
        ax.axhline(sewing.plate_y, color="0.55", lw=0.8, ls="--", zorder=1)
        ax.text(lo[0] + 0.01 * dx, sewing.plate_y, " throat plate", fontsize=6, color="0.4",
                va="bottom")
        for role, col in (("needle_point", "C0"), ("take_up_eye", "C3"), ("feed_dog", "C4"),
                          ("shuttle_point", "C2")):
            name = getattr(sewing, role, None)
            if name in names:
                path = P[:, names.index(name)]
                ax.plot(path[:, 0], path[:, 1], color=col, lw=0.7, ls=(0, (3, 2)), alpha=0.8,
                        zorder=1)
    draw_links(ax, xy, link_points(machine))
    theta = res.theta[k]
    for p in machine.pairs:  # sliders: a block on its guide's line
        if p.kind not in ("prismatic", "slot") or p.point not in xy:
            continue
        a = theta[res.link_names.index(p.line_link)] if p.line_link else 0.0
        a += (machine.defaults[p.line_param] if p.line_param >= 0 else 0.0) + p.extra_angle
        c, s_ = math.cos(a), math.sin(a)
        q = xy[p.point]
        half = 0.06 * span
        ax.plot([q[0] - c * half, q[0] + c * half], [q[1] - s_ * half, q[1] + s_ * half],
                color="0.3", lw=0.8, ls=(0, (2, 2)), zorder=2)
        from matplotlib.patches import Rectangle
        from matplotlib.transforms import Affine2D

        bw, bh = 0.022 * span, 0.012 * span
        block = Rectangle((-bw / 2, -bh / 2), bw, bh, facecolor="#ffd54f", edgecolor="0.2",
                          lw=0.8, zorder=3)
        block.set_transform(Affine2D().rotate(a).translate(*q) + ax.transData)
        ax.add_patch(block)
    fixed = [n for n in names if machine.point_links.get(n, ()) == ("frame",)
             or "frame" in machine.point_links.get(n, ())]
    for n in fixed:
        if n in xy:
            ax.plot(xy[n][0], xy[n][1] - 3.5 / s, marker="^", ms=6, color="0.35", zorder=3,
                    ls="none")
    pts = np.array([xy[n] for n in names if n in xy])
    ax.plot(pts[:, 0], pts[:, 1], "o", ms=3.2, mfc="white", mec="0.1", mew=0.8, zorder=4)

    rows = _labels(machine, xy)
    shown = [r for r in rows if r["label"]]
    to_pt = lambda q: (np.asarray(q) - lo) * s  # noqa: E731 - data mm to points of the axes
    anchors = np.array([to_pt(xy[r["at"]]) for r in shown])
    sizes = np.array([(len(r["name"]) * CHAR_PT + 2.0, LINE_PT + 1.0) for r in shown])
    boxes = place_labels(anchors, sizes, (0.0, 0.0, dx * s, dy * s),
                         prefer=[r["prefer"] for r in shown], marks=to_pt(pts))
    centres = (boxes[:, :2] + boxes[:, 2:]) / 2 / s + lo
    for r, (cx, cy), box, a in zip(shown, centres, boxes, anchors):
        anchor = xy[r["at"]]
        # the box's nearest point to the anchor: a leader line when the label is not beside it
        edge = np.clip(a, box[:2], box[2:])
        if np.hypot(*(edge - a)) > 8.0:
            end = edge / s + lo
            ax.plot([anchor[0], end[0]], [anchor[1], end[1]], color="0.3", lw=0.6,
                    zorder=4.5)
        pair = r["kind"].endswith("pair")
        ax.text(cx, cy, r["name"], fontsize=FONT_PT, ha="center", va="center", zorder=5,
                color="#7a1f1f" if pair else "0.05", style="italic" if pair else "normal",
                bbox={"boxstyle": "square,pad=0.08", "fc": "white", "ec": "none",
                      "alpha": 0.85})
        r["label_x_mm"], r["label_y_mm"] = cx, cy
    ax.set_title(title, fontsize=9)
    data = pd.DataFrame([{"name": r["name"], "kind": r["kind"], "links": r["links"],
                          "at_point": r["at"], "x_mm": xy[r["at"]][0], "y_mm": xy[r["at"]][1],
                          "label_x_mm": r.get("label_x_mm", xy[r["at"]][0]),
                          "label_y_mm": r.get("label_y_mm", xy[r["at"]][1])} for r in rows])
    return fig, data
