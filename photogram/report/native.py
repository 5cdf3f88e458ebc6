"""The report's pages drawn with the native PDF writer
(:mod:`photogram.report.pdf`) instead of matplotlib.

:class:`NativeDocument` is :class:`photogram.report.layout.Document` with
its drawing primitives replaced: the same flow, page breaks, tables and
axes blocks (so a report has the same pages either way), drawn on a
:class:`~photogram.report.pdf.canvas.Canvas` per page; its axes are
:class:`~photogram.report.pdf.axes.Axes` (or
:class:`~photogram.report.pdf.axes3d.Axes3D` for ``projection="3d"``),
drawn when the document is finished. Text is set in the PDF standard fonts
(cp1252); a character outside it raises UnicodeEncodeError, and
:func:`photogram.report.writer.write_report` then writes that report with
matplotlib (embedded DejaVu) instead.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.report.layout import Document, Page
from photogram.report.pdf.axes import Axes
from photogram.report.pdf.axes3d import Axes3D
from photogram.report.pdf.canvas import Canvas, font_name
from photogram.report.pdf.file import PdfFile

__all__ = ["NativeDocument"]

PT = 72.0


@dataclass
class NativeDocument(Document):
    """A report laid out as :class:`~photogram.report.layout.Document` does,
    drawn by the native PDF writer.

    Parameters
    ----------
    header : str
        Left part of the running header of every page.
    info : dict
        The PDF's document information (Title, Creator, ...).
    """

    info: dict = field(default_factory=dict)
    native = True

    def __post_init__(self):
        self.pdf = PdfFile(self.info)

    def _begin_page(self, size) -> Page:
        return Page(Canvas(self.pdf, size[0] * PT, size[1] * PT), self.section, size)

    def _put(self, x, y, text, size, *, bold=False, mono=False, color="black", ha="left",
             page=None):
        page = page or self.page
        text.encode("cp1252")               # UnicodeEncodeError: the matplotlib fallback
        page.figure.text(x * PT, (page.size[1] - y) * PT, text, size,
                         font=font_name(mono, bold), color=color, ha=ha)

    def _rule(self, x0, x1, y, lw, color):
        c, h = self.page.figure, self.page.size[1]
        c.stroke_style(color, lw)
        c.line(x0 * PT, (h - y) * PT, x1 * PT, (h - y) * PT)

    def _add_axes(self, left, top, width, height, projection=None):
        h = self.page.size[1]
        rect = (left * PT, (h - top - height) * PT, width * PT, height * PT)
        ax = (Axes3D if projection == "3d" else Axes)(self.page.figure, rect)
        self.page.axes.append(ax)
        return ax

    def _put_image(self, array, left, top, width, height):
        a = np.asarray(array)
        if a.dtype != np.uint8:
            a = np.round(np.clip(a, 0, 1) * 255).astype(np.uint8)
        if a.ndim == 2:
            a = np.repeat(a[..., None], 3, axis=2)
        alpha = a[..., 3] if a.shape[2] == 4 and (a[..., 3] < 255).any() else None
        h = self.page.size[1]
        self.page.figure.image(a[..., :3], left * PT, (h - top - height) * PT, width * PT,
                               height * PT, alpha, interpolate=True)

    def finish(self, footer: str) -> list:
        """Number the pages, draw the axes and add the pages to the PDF;
        returns the pages (their canvases)."""
        self._footers(footer)
        for page in self.pages:
            for ax in page.axes:
                ax.render()
            page.figure.finish()
        return [p.figure for p in self.pages]

    def tobytes(self) -> bytes:
        """The PDF (after :meth:`finish`)."""
        return self.pdf.tobytes()
