"""A small native PDF writer for the accuracy report (issue 23, item 1).

The report's pages are drawn without matplotlib (whose import alone costs
more CPU than the whole report may): :mod:`.file` writes the PDF objects
(pages, the standard fonts in WinAnsiEncoding, Flate streams, RGB image
XObjects, cross-reference table), :mod:`.canvas` draws on one page (text,
lines, vectorized paths and markers, images, clipping), :mod:`.axes` is a
small plot axes on a canvas (data -> page transform, nice ticks, grid,
labels, legend, log y, images with a colour map, arrows) and :mod:`.axes3d`
an orthographic 3D view. :mod:`photogram.report.native` lays the report's
pages out with them (the same API as :class:`photogram.report.layout.Document`).
"""

from photogram.report.pdf.canvas import Canvas, text_width
from photogram.report.pdf.file import PdfFile

__all__ = ["PdfFile", "Canvas", "text_width"]
