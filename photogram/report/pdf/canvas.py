"""Drawing on one PDF page: text in the standard fonts, lines, polylines,
many segments or markers as one vectorized path, rectangles, fills,
images, colours, line widths, dashes, opacity and clipping.

Coordinates are PDF points (1/72 inch) from the bottom-left corner of the
page. Numeric path data is formatted by one ``%`` over a whole array
(:func:`fmt_points`), never point by point in Python.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from photogram.report.pdf.colors import rgb
from photogram.report.pdf.file import pdf_string
from photogram.report.pdf.fontdata import WIDTHS

__all__ = ["Canvas", "text_width", "fmt_points", "font_name", "MARKERS"]

_RESOURCE = {"Helvetica": "F1", "Helvetica-Bold": "F2", "Courier": "F3", "Courier-Bold": "F4"}
_TABLES = {name: np.array(WIDTHS[base], float)
           for name, base in (("Helvetica", "Helvetica"), ("Helvetica-Bold", "Helvetica-Bold"),
                              ("Courier", "Courier"), ("Courier-Bold", "Courier"))}
#: the same widths as Python lists (a short label is summed faster without numpy)
_WIDTH_LISTS = {name: table.tolist() for name, table in _TABLES.items()}


def font_name(mono: bool = False, bold: bool = False) -> str:
    """The standard font of a text: Helvetica or Courier, bold or not."""
    return ("Courier" if mono else "Helvetica") + ("-Bold" if bold else "")


def text_width(text: str, size: float, font: str = "Helvetica") -> float:
    """Advance width (points) of ``text`` set in ``font`` at ``size`` pt
    (Adobe AFM widths, cp1252 codes; other characters count as a digit)."""
    return _advance(text, font) * size / 1000.0


@lru_cache(maxsize=4096)
def _advance(text: str, font: str) -> float:
    """Advance width of ``text`` in thousandths of the font size (cached:
    tick labels and table cells repeat)."""
    widths = _WIDTH_LISTS[font]
    return float(sum(map(widths.__getitem__, text.encode("cp1252", errors="replace"))))


#: layers with more elements than this are written with 0.1 pt instead of
#: 0.01 pt resolution (a third fewer digits to format and compress)
DENSE = 2500


def fmt_points(template: str, values) -> str:
    """``template`` repeated once per row of ``values`` (n, k), filled with
    the row's numbers: one ``%`` formatting over the whole array. More than
    :data:`DENSE` rows are written to 0.1 pt ("%.2f" becomes "%.1f")."""
    values = np.asarray(values, float)
    if values.size == 0:
        return ""
    if len(values) > DENSE:
        template = template.replace("%.2f", "%.1f")
    return (template * len(values)) % tuple(values.ravel().tolist())


def _c(x: float) -> str:
    return f"{x:.3f}".rstrip("0").rstrip(".") or "0"


@lru_cache(maxsize=4096)
def _literal(text: str) -> str:
    """:func:`pdf_string` of ``text`` as str (cached: tick labels repeat)."""
    return pdf_string(text).decode("latin-1")


@lru_cache(maxsize=64)
def _font_op(font: str, size: float) -> str:
    return f" BT /{_RESOURCE[font]} {_c(size)} Tf"


@lru_cache(maxsize=1024)
def _stroke_op(color, lw, dash, cap) -> str:
    """Colour, width, cap, join and dash operators of a stroke (cached: a
    report strokes in a few styles)."""
    r, g, b = rgb(color)
    return (f"{_c(r)} {_c(g)} {_c(b)} RG {_c(lw)} w {cap} J 1 j "
            + (f"[{' '.join(_c(d) for d in dash)}] 0 d " if dash else "[] 0 d "))


@lru_cache(maxsize=256)
def _fill_op(color) -> str:
    """``r g b rg`` of a colour (cached: a page sets hundreds of texts in a
    few colours)."""
    r, g, b = rgb(color)
    return f"{_c(r)} {_c(g)} {_c(b)} rg"


#: marker outlines in units of the marker size (points), as
#: (vertices (k, 2), closed, filled); circles are Bezier curves (see _circle)
MARKERS = {
    "^": (np.array([[0, 0.577], [-0.5, -0.289], [0.5, -0.289]]), True, True),
    "s": (np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]), True, True),
    "+": (np.array([[-0.5, 0], [0.5, 0], [0, -0.5], [0, 0.5]]), False, False),
    "x": (np.array([[-0.5, -0.5], [0.5, 0.5], [-0.5, 0.5], [0.5, -0.5]]), False, False),
}
_K = 0.5523


def _circle_offsets() -> np.ndarray:
    """The 13 points of a unit circle drawn as four cubic Bezier curves."""
    k = _K
    return np.array([[1, 0], [1, k], [k, 1], [0, 1], [-k, 1], [-1, k], [-1, 0],
                     [-1, -k], [-k, -1], [0, -1], [k, -1], [1, -k], [1, 0]], float)


CIRCLE = _circle_offsets()
_CIRCLE_TEMPLATE = "%.2f %.2f m " + "%.2f %.2f %.2f %.2f %.2f %.2f c " * 4 + "h\n"


class Canvas:
    """The content stream of one page being drawn.

    Parameters
    ----------
    pdf : PdfFile
        The file the page belongs to (images and opacity states are
        registered there).
    width, height : float
        Page size in points.
    """

    def __init__(self, pdf, width: float, height: float):
        self.pdf, self.width, self.height = pdf, width, height
        self._ops: list[str] = []
        self.images: dict[str, int] = {}
        self._opacity = [1.0]                # current opacity, per saved state
        self._stroke_rgb, self._edge = "0 0 0", 0.0

    # -------------------------------------------------------------- state
    def raw(self, op: str) -> None:
        self._ops.append(op)

    def save(self) -> None:
        self._ops.append("q\n")
        self._opacity.append(self._opacity[-1])

    def restore(self) -> None:
        self._ops.append("Q\n")
        self._opacity.pop()

    def stroke_style(self, color="black", lw: float = 1.0, dash=None, cap: int = 0,
                     alpha: float | None = None) -> None:
        self._edge = lw
        try:
            style = _stroke_op(color, lw, tuple(dash) if dash else None, cap)
        except TypeError:                   # an unhashable colour (an array)
            style = _stroke_op(tuple(rgb(color)), lw, tuple(dash) if dash else None, cap)
        self._ops.append(style + self._alpha(alpha) + "\n")

    def fill_style(self, color="black", alpha: float | None = None) -> None:
        r, g, b = rgb(color)
        self._stroke_rgb = f"{_c(r)} {_c(g)} {_c(b)}"        # round-cap discs (markers)
        self._ops.append(f"{_c(r)} {_c(g)} {_c(b)} rg " + self._alpha(alpha) + "\n")

    def _alpha(self, alpha) -> str:
        """The operator setting the opacity to ``alpha`` (None: opaque),
        empty when it is already so."""
        alpha = 1.0 if alpha is None else float(alpha)
        if alpha == self._opacity[-1]:
            return ""
        self._opacity[-1] = alpha
        return f"/{self.pdf.alpha_state(alpha)} gs"

    def clip_rect(self, x: float, y: float, w: float, h: float) -> None:
        """Clip what follows (until :meth:`restore`) to a rectangle."""
        self._ops.append(f"{x:.2f} {y:.2f} {w:.2f} {h:.2f} re W n\n")

    # --------------------------------------------------------------- text
    def text(self, x: float, y: float, text: str, size: float, *, font: str = "Helvetica",
             color="black", ha: str = "left", angle: float = 0.0) -> None:
        """``text`` with its baseline at ``y``; ``ha`` left, center or right
        of ``x`` (along the baseline when rotated by ``angle`` degrees)."""
        if not text:
            return
        shift = 0.0 if ha == "left" else _advance(text, font) * size / 1000.0 * (
            0.5 if ha == "center" else 1.0)
        fill = _fill_op(color) if isinstance(color, str) else _fill_op(tuple(rgb(color)))
        if angle:
            a = np.radians(angle)
            c, s = np.cos(a), np.sin(a)
            x0, y0 = x - shift * c, y - shift * s
            pos = f"{c:.4f} {s:.4f} {-s:.4f} {c:.4f} {x0:.2f} {y0:.2f} Tm"
        else:
            pos = f"1 0 0 1 {x - shift:.2f} {y:.2f} Tm"
        self._ops.append((self._alpha(None) if self._opacity[-1] != 1.0 else "")
                         + _font_op(font, size) + f" {fill} {pos} " + _literal(text)
                         + " Tj ET\n")

    # -------------------------------------------------------------- paths
    def line(self, x0, y0, x1, y1) -> None:
        self._ops.append(f"{x0:.2f} {y0:.2f} m {x1:.2f} {y1:.2f} l S\n")

    def polyline(self, xy, close: bool = False, fill: bool = False, stroke: bool = True) -> None:
        """One path through the points ``xy`` (n, 2); NaN rows break it."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        ok = np.all(np.isfinite(xy), axis=1)
        if ok.sum() < 2 and not fill:
            return
        # a point after a gap (or the first) starts a new subpath
        start = ok & ~np.concatenate([[False], ok[:-1]])
        template = "".join(np.where(start, "%.2f %.2f m ", "%.2f %.2f l ")[ok].tolist())
        body = (template % tuple(xy[ok].ravel().tolist())).rstrip()
        self._ops.append(body + (" h" if close else "") + " "
                         + ("B" if fill and stroke else "f" if fill else "S") + "\n")

    def segments(self, a, b, each: bool = False) -> None:
        """The segments ``a[i] -> b[i]`` (n, 2) as one stroked path, or with
        ``each`` stroked one by one (so that translucent lines darken where
        they cross, as a matplotlib LineCollection; still one formatting)."""
        a, b = np.asarray(a, float).reshape(-1, 2), np.asarray(b, float).reshape(-1, 2)
        ok = np.all(np.isfinite(a) & np.isfinite(b), axis=1)
        if each:
            self._ops.append(fmt_points("%.2f %.2f m %.2f %.2f l S\n",
                                        np.hstack([a[ok], b[ok]])))
            return
        self._ops.append(fmt_points("%.2f %.2f m %.2f %.2f l\n",
                                    np.hstack([a[ok], b[ok]])) + "S\n")

    def rect(self, x, y, w, h, fill: bool = False, stroke: bool = True) -> None:
        self._ops.append(f"{x:.2f} {y:.2f} {w:.2f} {h:.2f} re "
                         + ("B" if fill and stroke else "f" if fill else "S") + "\n")

    def rects(self, xywh, fill: bool = True, stroke: bool = False) -> None:
        """Many rectangles (n, 4: x, y, w, h) as one path."""
        self._ops.append(fmt_points("%.2f %.2f %.2f %.2f re\n", xywh)
                         + ("B" if fill and stroke else "f" if fill else "S") + "\n")

    def markers(self, xy, marker: str, size: float, *, filled: bool = True) -> None:
        """Markers at ``xy`` (n, 2) points, ``size`` points across, as one path
        (fill and stroke in the current colours)."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        if not len(xy):
            return
        if marker in ("o", ".") and filled:
            # a filled disc is a zero-length line with round caps, as wide as
            # the disc plus its edge: 4 numbers a marker instead of 26
            self._ops.append(f"q {_c(size + self._edge)} w 1 J "
                             + self._stroke_rgb + " RG\n"
                             + fmt_points("%.2f %.2f m %.2f %.2f l\n", np.hstack([xy, xy]))
                             + "S Q\n")
            return
        if marker in ("o", "."):
            pts = xy[:, None, :] + 0.5 * size * CIRCLE[None]
            self._ops.append(fmt_points(_CIRCLE_TEMPLATE, pts.reshape(len(xy), -1)) + "S\n")
            return
        verts, closed, fill = MARKERS[marker]
        pts = (xy[:, None, :] + size * verts[None]).reshape(len(xy), -1)
        if closed:
            tpl = "%.2f %.2f m " + "%.2f %.2f l " * (len(verts) - 1) + "h\n"
            self._ops.append(fmt_points(tpl, pts) + ("B\n" if fill and filled else "S\n"))
        else:                                  # pairs of strokes (+, x)
            self._ops.append(fmt_points("%.2f %.2f m %.2f %.2f l %.2f %.2f m %.2f %.2f l\n",
                                        pts) + "S\n")

    def beziers(self, pts13) -> None:
        """Closed curves of four cubic Beziers each, ``pts13`` (n, 13, 2) as
        :data:`CIRCLE` (ellipses), stroked as one path."""
        pts13 = np.asarray(pts13, float)
        pts13 = pts13[np.all(np.isfinite(pts13), axis=(1, 2))]
        self._ops.append(fmt_points(_CIRCLE_TEMPLATE, pts13.reshape(len(pts13), -1)) + "S\n")

    # -------------------------------------------------------------- images
    def image(self, rgb_array, x, y, w, h, alpha=None, interpolate: bool = False) -> None:
        """An RGB uint8 image (rows from the top) into the rectangle
        ``x, y, w, h`` (points); ``alpha`` an optional (h, w) uint8 mask."""
        obj = self.pdf.image(rgb_array, alpha, interpolate)
        name = f"Im{obj}"
        self.images[name] = obj
        self._ops.append(self._alpha(None)
                         + f" q {w:.3f} 0 0 {h:.3f} {x:.3f} {y:.3f} cm /{name} Do Q\n")

    # --------------------------------------------------------------- output
    def content(self) -> bytes:
        return "".join(self._ops).encode("latin-1")

    def finish(self) -> None:
        """Add the page to the file."""
        self.pdf.add_page(self.width, self.height, self.content(), self.images)
