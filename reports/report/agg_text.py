"""A matplotlib backend: Agg with its text laid out and its glyphs rendered once per process.

The report draws dozens of figures whose texts repeat (tick labels, axis labels, the legend
entries of the same configurations); matplotlib's Agg renderer lays out every string with
FreeType again in each figure and renders every glyph again at each place (text is about half
of a figure's drawing time). This backend (``matplotlib.use("module://reports.report.agg_text")``,
done by reports.report.canvas) is Agg whose renderer remembers, for the life of the process:

- the width, height and descent of a string in a font at a dpi;
- the glyphs (font file, glyph index, offset) a string is laid out into;
- the bitmap of a glyph at a sub-pixel offset (an offset by whole pixels moves the bitmap by
  whole pixels: FreeType hints the glyph, then transforms and translates its outline, and
  rasterizes it in its own bounding box), drawn where Agg would draw it.

It calls the same FreeType functions as Agg's renderer with the same arguments, so it writes the
same pixels (tests/reports/report/test_report.py compares a figure drawn both ways). Mathtext, TeX,
rotated text and text drawn without antialiasing go through Agg's own code. With a matplotlib whose
FreeType wrapper lacks the entry points used here, this is plain Agg.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backend_bases import FigureManagerBase
from matplotlib.backends import backend_agg
from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg

try:
    from matplotlib.ft2font import FT2Font, RenderMode

    SUPPORTED = all(hasattr(FT2Font, f) for f in ("_layout", "_render_glyph", "_set_transform"))
except ImportError:  # an older matplotlib: plain Agg
    SUPPORTED = False

#: (string, font properties, dpi, hinting) -> (width, height, descent) in pixels
_METRICS: dict = {}
#: (string, font properties, dpi, hinting, features, language) -> [(font, size, glyph, x, y)]
_LAYOUTS: dict = {}
#: (font file, size, dpi, glyph, hinting, x and y offset in 1/64 px mod 64) ->
#: (bitmap, left and top relative to the whole-pixel part of the offset)
_GLYPHS: dict = {}
#: the glyph transform of horizontal, unslanted, unstretched text (16.16 fixed point)
_IDENTITY = np.array([[0x10000, 0], [0, 0x10000]])
#: the caches are emptied when one holds more entries than this (a bound on memory)
MAX_ENTRIES = 200_000


def _bounded(cache: dict) -> dict:
    if len(cache) > MAX_ENTRIES:
        cache.clear()
    return cache


class RendererCachedText(RendererAgg):
    """Agg's renderer with the string metrics, layouts and glyph bitmaps of horizontal,
    antialiased plain text cached across figures (module docstring)."""

    def get_text_width_height_descent(self, s, prop, ismath):
        if ismath or not SUPPORTED:
            return super().get_text_width_height_descent(s, prop, ismath)
        key = (s, prop.copy(), self.dpi, backend_agg.get_hinting_flag())
        got = _METRICS.get(key)
        if got is None:
            got = super().get_text_width_height_descent(s, prop, ismath)
            _bounded(_METRICS)[key] = got
        return got

    def draw_text(self, gc, x, y, s, prop, angle, ismath=False, mtext=None):
        if ismath or angle != 0 or not gc.get_antialiased() or not SUPPORTED:
            return super().draw_text(gc, x, y, s, prop, angle, ismath=ismath, mtext=mtext)
        flags = backend_agg.get_hinting_flag()
        features = mtext.get_fontfeatures() if mtext is not None else None
        language = mtext.get_language() if mtext is not None else None
        size = prop.get_size_in_points()
        key = (s, prop.copy(), self.dpi, flags, _hashable(features), _hashable(language))
        items = _LAYOUTS.get(key)
        if items is None:
            font = self._prepare_font(prop)
            items = [
                (item.ft_object, item.glyph_index, item.x, item.y)
                for item in font._layout(s, flags=flags, features=features, language=language)
            ]
            _bounded(_LAYOUTS)[key] = items
        height = int(self.height)
        for font, glyph, dx, dy in items:  # dy is upwards, as in RendererAgg
            tx = round(0x40 * (x + dx))
            ty = round(0x40 * (self.height - y + dy))  # FreeType's y is upwards
            gkey = (font.fname, size, self.dpi, glyph, flags, tx & 63, ty & 63)
            got = _GLYPHS.get(gkey)
            if got is None:
                font.set_size(size, self.dpi)
                font._set_transform(_IDENTITY, np.array([tx & 63, ty & 63]))
                bitmap = font._render_glyph(glyph, flags, RenderMode.NORMAL)
                got = (np.array(bitmap.buffer), bitmap.left, bitmap.top)
                _bounded(_GLYPHS)[gkey] = got
            buffer, left, top = got
            self._renderer.draw_text_image(
                buffer, left + (tx >> 6), height - (top + (ty >> 6)) + buffer.shape[0], 0, gc
            )


def _hashable(v):
    if isinstance(v, list):
        return tuple(_hashable(x) for x in v)
    return v


class FigureCanvasCachedText(FigureCanvasAgg):
    """Agg's canvas drawing with :class:`RendererCachedText`."""

    def get_renderer(self):
        w, h = self.get_width_height(physical=True)
        key = w, h, self.figure.dpi
        if self._lastKey != key:
            self.renderer = RendererCachedText(w, h, self.figure.dpi)
            self._lastKey = key
        return self.renderer


FigureCanvas = FigureCanvasCachedText
FigureManager = FigureManagerBase
