"""Workshop drawings as files: DXF (through ezdxf) and SVG, both from one
:class:`~sewmech.app.drawing.cad.Drawing`, so the two say the same.

DXF: release R2010, units mm in the header ($INSUNITS 4, $MEASUREMENT 1), a layer per link, per
cam (``cam-NAME``), per path (``path-POINT``), and ``joints``, ``frame``, ``title``; lines,
true arcs and circles, points (the arcs' centres), light-weight polylines, text. Every
coordinate is written with all the digits a float has, so a reader gets the design back
exactly. SVG: the same entities as paths (arcs as SVG arcs), y pointing up as in the machine's
frame, one group a layer (its id the layer's name), the title block as text.
"""

from __future__ import annotations

import html
import math
from pathlib import Path

from ..drawing.cad import Arc, Circle, Drawing, Line, Point, Polyline, Text

#: how the title block sits under the drawing: its text lines' spacing in text heights
LINE_SPACING = 1.6


def title_block(d: Drawing, text_height: float) -> list:
    """The title block's entities: a frame and the title lines, under the drawing's bounds."""
    x0, y0, x1, y1 = d.bounds()
    n = len(d.title)
    h = text_height
    width = max(x1 - x0, max((len(t) for t in d.title), default=10) * 0.75 * h + 2 * h)
    height = (n * LINE_SPACING + 1.0) * h
    top = y0 - 2.0 * h
    bottom = top - height
    out = [Polyline(((x0, bottom), (x0 + width, bottom), (x0 + width, top), (x0, top)), True,
                    "title")]
    for k, line in enumerate(d.title):
        out.append(Text((x0 + h, top - (k + 1) * LINE_SPACING * h), h if k else 1.2 * h, line,
                        "title"))
    return out


def text_height_for(d: Drawing) -> float:
    """The title block's text height, mm: 2.5 % of the drawing's size, within 0.8 .. 5."""
    x0, y0, x1, y1 = d.bounds()
    return min(max(0.025 * max(x1 - x0, y1 - y0), 0.8), 5.0)


def _entities(d: Drawing, text_height: float | None) -> list:
    return list(d.entities) + title_block(d, text_height or text_height_for(d))


def dxf_document(d: Drawing, text_height: float | None = None):
    """The ezdxf document of ``d`` (with its title block; text ``text_height`` mm, default
    :func:`text_height_for`)."""
    import ezdxf
    from ezdxf import units

    doc = ezdxf.new("R2010", setup=True)
    doc.units = units.MM
    doc.header["$INSUNITS"] = units.MM
    doc.header["$MEASUREMENT"] = 1
    doc.header["$LUNITS"] = 2  # decimal
    msp = doc.modelspace()
    for name, color in {**d.layers, "title": 7}.items():
        if name not in doc.layers:
            doc.layers.add(name, color=color)
    for e in _entities(d, text_height):
        a = {"layer": e.layer}
        if isinstance(e, Line):
            msp.add_line(e.p0, e.p1, dxfattribs=a)
        elif isinstance(e, Arc):
            msp.add_arc(e.centre, e.radius, e.start_deg, e.end_deg, dxfattribs=a)
        elif isinstance(e, Circle):
            msp.add_circle(e.centre, e.radius, dxfattribs=a)
        elif isinstance(e, Point):
            msp.add_point(e.p, dxfattribs=a)
        elif isinstance(e, Polyline):
            msp.add_lwpolyline(e.points, close=e.closed, dxfattribs=a)
        elif isinstance(e, Text):
            msp.add_text(e.text, height=e.height, dxfattribs={**a, "insert": e.p})
    return doc


def write_dxf(d: Drawing, path: Path, text_height: float | None = None) -> Path:
    from .io import atomic_write

    doc = dxf_document(d, text_height)
    with atomic_write(path, "w", encoding="utf-8") as fh:
        doc.write(fh)
    return Path(path)


def _n(x: float) -> str:
    return repr(float(x))


def svg_text(d: Drawing, text_height: float | None = None) -> str:
    """The SVG document of ``d``: mm units (the viewBox in mm, width and height in mm), y up."""
    text_height = text_height or text_height_for(d)
    ents = _entities(d, text_height)
    tmp = Drawing(entities=[e for e in ents if not isinstance(e, Text)])
    x0, y0, x1, y1 = tmp.bounds()
    pad = 2.0 * text_height
    x0, y0, x1, y1 = x0 - pad, y0 - pad, x1 + pad, y1 + pad
    w, h = x1 - x0, y1 - y0
    groups: dict[str, list[str]] = {}
    stroke = max(0.0015 * max(w, h), 0.05)
    for e in ents:
        g = groups.setdefault(e.layer, [])
        if isinstance(e, Line):
            g.append(f'<path d="M {_n(e.p0[0])} {_n(-e.p0[1])} L {_n(e.p1[0])} {_n(-e.p1[1])}"/>')
        elif isinstance(e, Arc):
            a0, a1 = math.radians(e.start_deg), math.radians(e.end_deg)
            span = (e.end_deg - e.start_deg) % 360.0
            sx, sy = e.centre[0] + e.radius * math.cos(a0), e.centre[1] + e.radius * math.sin(a0)
            ex, ey = e.centre[0] + e.radius * math.cos(a1), e.centre[1] + e.radius * math.sin(a1)
            g.append(f'<path d="M {_n(sx)} {_n(-sy)} A {_n(e.radius)} {_n(e.radius)} 0'
                     f' {1 if span > 180.0 else 0} 0 {_n(ex)} {_n(-ey)}"/>')
        elif isinstance(e, Circle):
            g.append(f'<circle cx="{_n(e.centre[0])}" cy="{_n(-e.centre[1])}"'
                     f' r="{_n(e.radius)}"/>')
        elif isinstance(e, Point):
            g.append(f'<circle class="point" cx="{_n(e.p[0])}" cy="{_n(-e.p[1])}"'
                     f' r="{_n(2 * stroke)}"/>')
        elif isinstance(e, Polyline):
            pts = " ".join(f"{_n(x)},{_n(-y)}" for x, y in e.points)
            tag = "polygon" if e.closed else "polyline"
            g.append(f'<{tag} points="{pts}"/>')
        elif isinstance(e, Text):
            g.append(f'<text x="{_n(e.p[0])}" y="{_n(-e.p[1])}" font-size="{_n(e.height)}"'
                     f' font-family="sans-serif" stroke="none" fill="black">'
                     f"{html.escape(e.text)}</text>")
    colours = ["#000000", "#cc0000", "#b8860b", "#008000", "#008b8b", "#0000cc", "#8b008b"]
    body = []
    for layer, items in groups.items():
        col = colours[d.layers.get(layer, 7) % len(colours)] if layer != "title" else "#000000"
        body.append(f'<g id="{html.escape(layer, quote=True)}" stroke="{col}">\n'
                    + "\n".join(items) + "\n</g>")
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<svg xmlns="http://www.w3.org/2000/svg" width="{_n(w)}mm" height="{_n(h)}mm"'
            f' viewBox="{_n(x0)} {_n(-y1)} {_n(w)} {_n(h)}">\n'
            f"<title>{html.escape(d.title[0] if d.title else d.machine)}</title>\n"
            f'<style>path,circle,polyline,polygon{{fill:none;stroke-width:{_n(stroke)}}}'
            f" circle.point{{fill:currentColor}}</style>\n" + "\n".join(body) + "\n</svg>\n")


def write_svg(d: Drawing, path: Path, text_height: float | None = None) -> Path:
    from .io import atomic_write

    with atomic_write(path, "w", encoding="utf-8") as fh:
        fh.write(svg_text(d, text_height))
    return Path(path)
