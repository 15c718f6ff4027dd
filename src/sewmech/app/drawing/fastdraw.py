"""matplotlib, faster, with the same figures: what :func:`sewmech.app.drawing.figures.render` changes
while it lays a figure out and draws it as PNG and SVG.

A report draws 22 figures, and matplotlib spends much of that time answering the same
questions again for every figure and every format (a font's height, a tick label's extent,
where an axis's ticks go) and reading its font file through a Python file object.
:func:`fast_text` answers the questions from caches the figures share and reads the fonts from
memory, :func:`freeze_ticks` fixes the ticks once the layout is done (and
:func:`reused_tick_updates` then updates each axis's ticks once per format), and :func:`png_bytes`
writes matplotlib's pixels as a PNG without Pillow's search for row filters. The pixels and
the SVG are matplotlib's own (a test compares them with matplotlib's files).
"""

from __future__ import annotations

import contextlib
import functools
import io
import os
import struct
import zlib

import matplotlib

#: a font's height metrics at a resolution, by (font properties, dpi): see fast_text
_HEIGHTS: dict = {}
#: a line of text's (width, height, descent) by (renderer class, text, font properties, dpi,
#: hinting): see fast_text
_EXTENTS: dict = {}


def _dpi(renderer) -> float:
    """The renderer's resolution (the SVG backend's is fixed: 72 dpi)."""
    from matplotlib.backends.backend_svg import FigureCanvasSVG

    return getattr(renderer, "dpi", FigureCanvasSVG.fixed_dpi)


def _font_key(prop, dpi) -> tuple:
    """What decides a text's metrics besides the text: the font properties (as matplotlib's
    own text metrics cache tells them apart), the resolution and the hinting settings."""
    return (tuple(prop.get_family()), prop.get_style(), prop.get_variant(), prop.get_weight(),
            prop.get_stretch(), prop.get_size_in_points(), prop.get_file(),
            prop.get_math_fontfamily(), dpi, matplotlib.rcParams["text.hinting"],
            matplotlib.rcParams["text.hinting_factor"],
            matplotlib.rcParams["text.kerning_factor"])


def _font_height_metrics(renderer, prop):
    """(ascent, descent, line gap) of the font ``prop`` at the renderer's resolution, in
    pixels: what matplotlib's text layout reads from the font's OS/2 (or hhea) table for every
    text it measures or draws, here read once per font, size and resolution. The same
    arithmetic as matplotlib's, so the same numbers."""
    key = _font_key(prop, _dpi(renderer))
    hit = _HEIGHTS.get(key)
    if hit is None:
        from matplotlib.font_manager import fontManager, get_font

        font = get_font(fontManager._find_fonts_by_props(prop))
        hit = (None, None, None)
        for name, gap, ascent, descent in (
                ("OS/2", "sTypoLineGap", "sTypoAscender", "sTypoDescender"),
                ("hhea", "lineGap", "ascent", "descent")):
            table = font.get_sfnt_table(name)
            if table is None:
                continue
            scale = 1 / font.get_sfnt_table("head")["unitsPerEm"] * key[5] * key[8] / 72
            hit = (table[ascent] * scale, -table[descent] * scale, table[gap] * scale)
            break
        _HEIGHTS[key] = hit
    return hit


def _shared_extents(measure):
    """The renderer method ``measure`` (``get_text_width_height_descent``), answering from
    :data:`_EXTENTS` for plain text. matplotlib caches a text's extent per renderer, and every
    figure has renderers of its own, so each figure measured its tick labels, titles and
    legend entries again (1,336 measurements in a report's PNGs, 388 of them different: the
    font is laid out for each, about 0.3 ms). A renderer of the Agg or the SVG backend
    measures a text by its font and resolution alone, so one answer serves every figure.
    Mathematical and TeX text is measured by matplotlib, as before."""
    def get_text_width_height_descent(self, s, prop, ismath):
        if ismath:
            return measure(self, s, prop, ismath)
        key = (type(self), s, _font_key(prop, _dpi(self)))
        hit = _EXTENTS.get(key)
        if hit is None:
            hit = _EXTENTS[key] = measure(self, s, prop, ismath)
        return hit

    get_text_width_height_descent.measure = measure
    return get_text_width_height_descent


#: a font file's bytes, by path: see _fonts_in_memory
_FONT_FILES: dict = {}
#: the renderers' fonts read from memory, by matplotlib's _get_font arguments
_MEMORY_FONTS: dict = {}


class _FontsInMemory:
    """Stands in for matplotlib's ``ft2font`` module while matplotlib opens a font for the
    report's renderers (:func:`_memory_font`): every ``FT2Font`` reads its file from memory.
    Anything else is the module's own."""

    def __getattr__(self, name):
        from matplotlib import ft2font

        return getattr(ft2font, name)

    @staticmethod
    def FT2Font(path, *args, **kwargs):  # the name matplotlib calls
        from matplotlib import ft2font

        try:
            path = os.fspath(path)
        except TypeError:  # not a file name (a later matplotlib's own object): as it was
            return ft2font.FT2Font(path, *args, **kwargs)
        data = _FONT_FILES.get(path)
        if data is None:
            with open(path, "rb") as fh:
                data = _FONT_FILES[path] = fh.read()
        return ft2font.FT2Font(io.BytesIO(data), *args, **kwargs)


def _memory_font(get_font, *args, **kwargs):
    """``get_font(*args, **kwargs)``, matplotlib's own ``font_manager._get_font`` without its
    cache (the font and its fallbacks for a list of files), with the files read from memory;
    one font object per argument set, as matplotlib keeps them, in a cache of its own
    (matplotlib's keeps file-backed ones: a PDF written later embeds its font by file
    name)."""
    key = (args, tuple(sorted(kwargs.items())))
    hit = _MEMORY_FONTS.get(key)
    if hit is None:
        import matplotlib.font_manager as fm

        real = fm.ft2font
        fm.ft2font = _FontsInMemory()
        try:
            hit = _MEMORY_FONTS[key] = get_font(*args, **kwargs)
        finally:
            fm.ft2font = real
    return hit


def _fonts_in_memory(prepare):
    """The method ``prepare(self, font_prop)`` that picks the font a text is measured or drawn
    with (the Agg renderer's ``_prepare_font``, the SVG renderer's ``TextToPath._get_font``),
    with the font read from memory. matplotlib opens a font file through a Python file
    object, and FreeType reads every glyph it lays out or draws through it, a seek and a read
    each: a report made 313,000 system calls on DejaVuSans.ttf. From memory, the same glyphs
    cost less than half the time. The fonts are swapped only while such a method picks one;
    mathematical text and other backends keep matplotlib's."""
    def _prepare_font(self, font_prop):
        import matplotlib.font_manager as fm

        real = fm._get_font
        fm._get_font = functools.partial(_memory_font, real.__wrapped__)
        try:
            return prepare(self, font_prop)
        finally:
            fm._get_font = real

    _prepare_font.prepare = prepare
    return _prepare_font


@contextlib.contextmanager
def fast_text():
    """While a figure is laid out and drawn, the Agg and SVG renderers answer two of
    matplotlib's questions from caches shared by all figures: a font's height metrics
    (:func:`_font_height_metrics`; matplotlib asks the renderer first, where it has that
    method, and otherwise looks the font up and reads its tables again for every text it
    measures: about a tenth of the drawing), and a text's extent (:func:`_shared_extents`);
    and both read their fonts from memory (:func:`_fonts_in_memory`). Removed
    afterwards; a renderer with a height method of its own keeps it. For one figure drawn at
    a time in a process, as matplotlib itself requires (the report's processes, the command
    line): the methods are swapped on the classes, not per figure."""
    from matplotlib.backends.backend_agg import RendererAgg
    from matplotlib.backends.backend_svg import RendererSVG

    added = [cls for cls in (RendererAgg, RendererSVG)
             if not hasattr(cls, "_get_font_height_metrics")]
    for cls in added:
        cls._get_font_height_metrics = _font_height_metrics
    wrapped = [cls for cls in (RendererAgg, RendererSVG)
               if "get_text_width_height_descent" in vars(cls)
               and not hasattr(cls.get_text_width_height_descent, "measure")]
    for cls in wrapped:
        cls.get_text_width_height_descent = _shared_extents(cls.get_text_width_height_descent)
    import matplotlib.font_manager as fm
    from matplotlib.textpath import TextToPath

    memory = [(cls, name) for cls, name in ((RendererAgg, "_prepare_font"),
                                            (TextToPath, "_get_font"))
              if hasattr(getattr(fm, "_get_font", None), "__wrapped__")
              and name in vars(cls) and not hasattr(getattr(cls, name), "prepare")]
    for cls, name in memory:
        setattr(cls, name, _fonts_in_memory(getattr(cls, name)))
    try:
        yield
    finally:
        for cls in added:
            del cls._get_font_height_metrics
        for cls in wrapped:
            cls.get_text_width_height_descent = cls.get_text_width_height_descent.measure
        for cls, name in memory:
            setattr(cls, name, getattr(cls, name).prepare)


def freeze_ticks(fig) -> None:
    """Fix every axis's major ticks and their labels where they are now, so that the two
    formats draw them without asking the locator and the formatter again (each draw did, for
    every axis: about a tenth of the drawing; the files are the same). An axis whose labels
    share an offset (``1e-3`` at its end) keeps its own formatter."""
    from matplotlib.ticker import FixedFormatter, FixedLocator

    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            fmt = axis.get_major_formatter()
            locs = axis.get_majorticklocs()
            labels = fmt.format_ticks(locs)
            if getattr(fmt, "get_offset", lambda: "")():
                continue
            axis.set_major_locator(FixedLocator(locs))
            axis.set_major_formatter(FixedFormatter(labels))



@contextlib.contextmanager
def reused_tick_updates():
    """While a figure whose ticks are fixed (:func:`freeze_ticks`) is drawn: an axis's tick
    update (each tick's position and label, and which ticks are drawn) is done once and reused
    while nothing it reads has changed (the view interval, the locators, the formatters, the
    scale). matplotlib updated an axis's ticks each time it measured the axis, its title's
    clearance or its label's place, and again when it drew it: 2,212 updates a report, 0.67 s
    in one process, with the ticks fixed most of them giving what was there. Polar and other
    special axes update as before."""
    from matplotlib.axis import Axis, XAxis, YAxis

    update = vars(Axis).get("_update_ticks")
    if update is None or hasattr(update, "update"):
        yield
        return
    done: dict = {}

    def _update_ticks(self):
        if type(self) not in (XAxis, YAxis):
            return update(self)
        key = (tuple(self.get_view_interval()), id(self.major.locator), id(self.major.formatter),
               id(self.minor.locator), id(self.minor.formatter), id(self._scale))
        hit = done.get(id(self))
        if hit is None or hit[0] != key:
            hit = done[id(self)] = (key, update(self))
        return list(hit[1])

    _update_ticks.update = update
    Axis._update_ticks = _update_ticks
    try:
        yield
    finally:
        Axis._update_ticks = update

def png_bytes(fig, dpi: float) -> bytes:
    """``fig`` drawn by matplotlib's Agg renderer at ``dpi`` (dots per inch), as a PNG file:
    the pixels and the metadata (the resolution, matplotlib's ``Software`` text) of
    ``fig.savefig(format="png")``, the rows left unfiltered and deflated at zlib level 1.

    Pillow, which matplotlib writes PNGs with, tries all five PNG row filters on every row to
    pick one, and has no option to choose; on a plot's flat colours that search cost more
    than the deflating (38 ms of a 1584 x 1008 figure) and saved under 2 % of the file. Here
    the same file takes 17 ms. Falls back to matplotlib's PNG when its raw image does not
    have the figure's size."""
    import numpy as np

    raw = io.BytesIO()
    fig.savefig(raw, format="raw", dpi=dpi)
    w, h = fig.canvas.get_width_height(physical=True)
    data = raw.getbuffer()
    if len(data) != 4 * w * h:
        png = io.BytesIO()
        fig.savefig(png, format="png", dpi=dpi, pil_kwargs={"compress_level": 1})
        return png.getvalue()
    rows = np.empty((h, 1 + 4 * w), np.uint8)
    rows[:, 0] = 0  # filter type None
    rows[:, 1:] = np.frombuffer(data, np.uint8).reshape(h, 4 * w)
    ppm = int(dpi / 0.0254 + 0.5)  # pixels per metre, as Pillow rounds them
    software = f"Matplotlib version{matplotlib.__version__}, https://matplotlib.org/"
    chunks = (b"IHDR" + struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0),  # 8-bit RGBA
              b"tEXt" + b"Software\0" + software.encode("latin-1"),
              b"pHYs" + struct.pack(">IIB", ppm, ppm, 1),
              b"IDAT" + zlib.compress(rows, 1),
              b"IEND")
    return b"\x89PNG\r\n\x1a\n" + b"".join(
        struct.pack(">I", len(c) - 4) + c + struct.pack(">I", zlib.crc32(c)) for c in chunks)
