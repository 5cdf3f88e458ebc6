"""Page layout of the report: a flowing A4 document of matplotlib figures.

A :class:`Document` keeps a cursor on the current page; headings, text,
tables and blocks of axes are placed one below the other, and a new page is
started (with the section's title marked "continued" and a table's header
repeated) when the next item does not fit. Tables are monospaced text, one
text object per row, so that the PDF's text layer reads row by row and every
column lines up; a table wider than the page is set in a smaller font. A
figure can float at the right margin (:meth:`Document.float_right`) while
narrow text and tables continue at its left.

All sizes are in inches. Figures are plain :class:`matplotlib.figure.Figure`
objects (no pyplot, no global state); :mod:`photogram.report.writer` saves
them. Everything drawn goes through a few primitives (``_begin_page``,
``_put``, ``_rule``, ``_add_axes``, ``image``, ``finish``) that
:class:`photogram.report.native.NativeDocument` overrides to draw the same
layout with the native PDF writer (:mod:`photogram.report.pdf`), without
matplotlib; matplotlib is imported only when a matplotlib page is made.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass, field

__all__ = ["Document", "PORTRAIT", "LANDSCAPE", "MONO", "char_width", "decorate",
           "equal_limits"]

PORTRAIT = (8.27, 11.69)          # A4, inches
LANDSCAPE = (11.69, 8.27)
MARGIN_X, MARGIN_TOP, MARGIN_BOTTOM = 0.6, 0.75, 0.65
MONO = "monospace"               # DejaVu Sans Mono; Courier in the PDF (writer.RC)
_MONO_ADVANCE = 0.602             # advance of DejaVu Sans Mono, in em
_SANS_ADVANCE = 0.56              # generous mean advance of DejaVu Sans, in em
_LINE = 1.38                      # line height in font sizes
# Text is set on its baseline, a fixed distance below the cursor (the top of
# DejaVu's "l", as matplotlib's va="top" put it): the PDF standard fonts
# measure each string's own ink, so va="top" would move every line by its
# tallest glyph ("^", "|") and the rows of a table would not be evenly spaced.
_ASCENT, _DESCENT = 0.76, 0.236   # in em


def ascent(size: float) -> float:
    """Distance (inches) from the top of a ``size`` pt line to its baseline."""
    return size * _ASCENT / 72.0


def char_width(size: float, mono: bool = True) -> float:
    """Width (inches) of one character of a ``size`` pt font."""
    return size * (_MONO_ADVANCE if mono else _SANS_ADVANCE) / 72.0


def line_height(size: float) -> float:
    return size * _LINE / 72.0


def decorate(ax, title: str | None = None, xlabel: str | None = None,
             ylabel: str | None = None, *, xpad: float = 0.3, ypad: float = 0.48,
             size: float | None = None) -> None:
    """Title and axis labels at fixed distances (inches) from the axes.

    matplotlib places them by measuring every tick label on every draw,
    which is most of the time a report takes; fixed places are as good here
    because the layout leaves that much room (``pad_left``/``pad_bottom``
    of :meth:`Document.axes`)."""
    if getattr(ax, "native", False):
        ax.decorate(title, xlabel, ylabel, xpad=xpad, ypad=ypad, size=size)
        return
    fig = ax.figure
    ax.apply_aspect()
    pos = ax.get_position()
    w_in, h_in = pos.width * fig.get_figwidth(), pos.height * fig.get_figheight()
    if title:
        size = size or 8.5
        ax.text(0.0, 1.0 + (0.07 + size * _DESCENT / 72.0) / h_in, title,
                transform=ax.transAxes, ha="left", va="baseline", size=size)
    if xlabel:
        ax.set_xlabel(xlabel)
        ax.xaxis.set_label_coords(0.5, -xpad / h_in)
    if ylabel:
        ax.set_ylabel(ylabel)
        ax.yaxis.set_label_coords(-ypad / w_in, 0.5)


def equal_limits(ax, lo, hi) -> None:
    """Limits around the box ``lo``..``hi`` (x, y) with equal scales on both
    axes, widened to the shape of the axes (no matplotlib aspect warning)."""
    if getattr(ax, "native", False):
        ratio = ax.height_in / ax.width_in
    else:
        fig = ax.figure
        pos = ax.get_position()
        ratio = (pos.height * fig.get_figheight()) / (pos.width * fig.get_figwidth())
    (x0, y0), (x1, y1) = lo, hi
    w, h = max(x1 - x0, 1e-12), max(y1 - y0, 1e-12)
    if h / w < ratio:
        h = w * ratio
    else:
        w = h / ratio
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    ax.set_xlim(cx - w / 2, cx + w / 2)
    ax.set_ylim(cy - h / 2, cy + h / 2)


@dataclass
class Page:
    figure: object            # matplotlib Figure, or the native page's canvas
    section: str
    size: tuple
    axes: list = field(default_factory=list)   # native axes, drawn at finish


@dataclass
class Document:
    """The pages of a report being laid out.

    Parameters
    ----------
    header : str
        Left part of the running header of every page.
    """

    header: str
    pages: list = field(default_factory=list)
    section: str = ""
    _y: float = 0.0               # cursor, inches from the top of the page
    _float_bottom: float = 0.0    # bottom of a figure floating at the right
    _float_width: float = 0.0     # its width, with the gap to the text

    # ------------------------------------------------------------------ pages
    @property
    def page(self) -> Page:
        return self.pages[-1]

    @property
    def width(self) -> float:
        """Usable width of the current page (inches)."""
        return self.page.size[0] - 2 * MARGIN_X

    @property
    def free_width(self) -> float:
        """Width left of a floating figure at the cursor (inches)."""
        return self.width - (self._float_width if self._y < self._float_bottom else 0.0)

    @property
    def remaining(self) -> float:
        """Height left on the current page (inches)."""
        return self.page.size[1] - MARGIN_BOTTOM - self._y

    def start_section(self, title: str, *, landscape: bool = False, intro: str = "",
                      heading: bool = True) -> None:
        """A new page headed ``title``; ``intro`` is a short paragraph below."""
        self.section = title
        self._new_page(landscape, continued=False)
        if heading:
            self.heading(title, size=13)
        if intro:
            self.text(intro, size=8.5, color="0.25")
            self.space(0.05)

    def new_page(self, *, landscape: bool | None = None) -> None:
        """Continue the current section on a new page."""
        if landscape is None:
            landscape = self.page.size[0] > self.page.size[1]
        self._new_page(landscape, continued=True)

    def _new_page(self, landscape: bool, continued: bool) -> None:
        size = LANDSCAPE if landscape else PORTRAIT
        self.pages.append(self._begin_page(size))
        self._y = MARGIN_TOP
        self._float_bottom = 0.0
        self._put(MARGIN_X, 0.4, self.header, 7.5, color="0.35")
        self._put(size[0] - MARGIN_X, 0.4, self.section, 7.5, color="0.35", ha="right")
        self._rule(MARGIN_X, size[0] - MARGIN_X, 0.47, lw=0.5, color="0.6")
        if continued:
            self.heading(f"{self.section} (continued)", size=10, color="0.3")

    def ensure(self, height: float) -> None:
        """Start a new page unless ``height`` inches still fit."""
        if height > self.remaining and self._y > MARGIN_TOP + 0.5:
            self.new_page()

    # ------------------------------------------------- drawing primitives
    def _begin_page(self, size) -> Page:
        """A new empty page of ``size`` (inches)."""
        from matplotlib.figure import Figure

        return Page(Figure(figsize=size), self.section, size)

    def _put(self, x: float, y: float, text: str, size: float, *, bold: bool = False,
             mono: bool = False, color="black", ha: str = "left", page=None) -> None:
        """``text`` with its baseline ``y`` inches from the top of ``page``
        (default: the current page)."""
        page = page or self.page
        page.figure.text(x / page.size[0], 1.0 - y / page.size[1], text, size=size,
                         va="baseline", ha=ha, color=color, family=MONO if mono else None,
                         weight="bold" if bold else "normal")

    def _rule(self, x0: float, x1: float, y: float, lw: float, color) -> None:
        """A horizontal line ``y`` inches from the top."""
        from matplotlib.lines import Line2D

        self.page.figure.add_artist(Line2D([self._fx(x0), self._fx(x1)], [self._fy(y)] * 2,
                                           lw=lw, color=color))

    def _add_axes(self, left: float, top: float, width: float, height: float,
                  projection=None):
        """Axes with the box ``left``, ``top`` (inches from the page's left and
        top) ``width`` x ``height``."""
        return self.page.figure.add_axes([self._fx(left), self._fy(top + height),
                                          width / self.page.size[0],
                                          height / self.page.size[1]], projection=projection)

    # --------------------------------------------------------------- helpers
    def _fy(self, y_in: float) -> float:
        return 1.0 - y_in / self.page.size[1]

    def _fx(self, x_in: float) -> float:
        return x_in / self.page.size[0]

    def space(self, height: float) -> None:
        self._y += height

    # ------------------------------------------------------------------ text
    def heading(self, text: str, size: float = 10.5, color: str = "black") -> None:
        self.ensure(line_height(size) * 2.5)
        self._y += 0.35 * line_height(size)
        self._put(MARGIN_X, self._y + ascent(size), text, size, bold=True, color=color)
        self._y += line_height(size) * 1.15

    def text(self, text: str, size: float = 8.5, mono: bool = False,
             color: str = "black", indent: float = 0.0, hanging: str = "") -> None:
        """A paragraph, wrapped to the page width (blank lines are kept)."""
        width = int((self.free_width - indent) / char_width(size, mono))
        lines = []
        for para in str(text).split("\n"):
            lines += textwrap.wrap(para, width, break_long_words=True,
                                   subsequent_indent=hanging) or [""]
        for line in lines:
            self.ensure(line_height(size))
            self._put(MARGIN_X + indent, self._y + ascent(size), line, size, mono=mono,
                      color=color)
            self._y += line_height(size)
        self._y += 0.3 * line_height(size)

    def bullets(self, items, size: float = 8.5, empty: str = "none") -> None:
        for item in items or [empty]:
            self.text("- " + str(item), size=size, hanging="  ")

    # ---------------------------------------------------------------- tables
    def table(self, header, rows, *, align: str | None = None, size: float = 8.0,
              title: str | None = None, note: str | None = None) -> None:
        """A table of strings; ``align`` one letter per column, ``l`` or
        ``r`` (default: first column left, others right). Flows over pages,
        repeating the header."""
        header = [str(h) for h in header]
        rows = [[str(c) for c in r] for r in rows]
        n = len(header)
        align = align or "l" + "r" * (n - 1)
        widths = [max([len(header[j])] + [len(r[j]) for r in rows]) for j in range(n)]
        total = sum(widths) + 2 * (n - 1)
        if total * char_width(size) > self.free_width:
            self.clear_float()
        size = min(size, max(5.0, self.width / (total * char_width(1.0))))
        room = int(self.width / char_width(size)) - 2 * (n - 1)
        if sum(widths) > room:                # too wide even in 5 pt: cut the widest cells
            cap = max(4, room // n)
            widths = [min(w, cap) for w in widths]

            def cut(text, w):
                return text if len(text) <= w else text[:w - 1] + "~"

            header = [cut(h, w) for h, w in zip(header, widths)]
            rows = [[cut(c, w) for c, w in zip(r, widths)] for r in rows]
            total = sum(widths) + 2 * (n - 1)

        def fmt(cells):
            return "  ".join(c.ljust(w) if a == "l" else c.rjust(w)
                             for c, w, a in zip(cells, widths, align)).rstrip()

        lh = line_height(size)
        if title:
            self.ensure(line_height(9) * 1.5 + 3 * lh)
            self.subheading(title)
        head = fmt(header)
        rule_w = total * char_width(size)

        def put_header():
            self._put_mono(head, size, weight="bold")
            self._rule(MARGIN_X, MARGIN_X + rule_w, self._y - 0.15 * lh, lw=0.5, color="0.4")
            self._y += 0.15 * lh

        self.ensure(3 * lh)
        put_header()
        for row in rows:
            if lh > self.remaining:
                self.new_page()
                put_header()
            self._put_mono(fmt(row), size)
        if not rows:
            self._put_mono("(none)", size, color="0.4")
        self._y += 0.5 * lh
        if note:
            self.text(note, size=7.5, color="0.3")

    def _put_mono(self, line: str, size: float, weight="normal", color="black") -> None:
        self._put(MARGIN_X, self._y + ascent(size), line, size, mono=True,
                  bold=weight == "bold", color=color)
        self._y += line_height(size)

    def pairs(self, items, *, size: float = 8.0, title: str | None = None) -> None:
        """A two-column list ``name  value``; long values wrap under
        themselves."""
        items = [(str(k), str(v)) for k, v in items]
        if title:
            self.subheading(title)
        key_w = max([len(k) for k, _ in items] + [1]) + 2
        width = max(20, int(self.free_width / char_width(size)) - key_w)
        for key, value in items:
            lines = textwrap.wrap(value, width, break_long_words=True) or [""]
            for i, line in enumerate(lines):
                if line_height(size) > self.remaining:
                    self.new_page()
                self._put_mono((key if i == 0 else "").ljust(key_w) + line, size)
        self._y += 0.5 * line_height(size)

    def subheading(self, text: str, size: float = 9.0) -> None:
        self.ensure(line_height(size) * 4)
        self._y += 0.2 * line_height(size)
        self._put(MARGIN_X, self._y + ascent(size), text, size, bold=True)
        self._y += line_height(size) * 1.2

    # ------------------------------------------------------------------ axes
    def axes(self, height: float, ncols: int = 1, *, pad_left: float = 0.75,
             pad_right: float = 0.2, pad_bottom: float = 0.5, pad_top: float = 0.3,
             gap: float = 0.0, projection=None, widths=None):
        """A block ``height`` inches high (including room for labels) with
        ``ncols`` axes side by side; returns the list of axes."""
        self.clear_float()
        self.ensure(height)
        top, bottom = self._y + pad_top, self._y + height - pad_bottom
        widths = widths or [1.0] * ncols
        cell = (self.width - gap * (ncols - 1)) / sum(widths)
        axes, x = [], MARGIN_X
        for w in widths:
            left, right = x + pad_left, x + w * cell - pad_right
            axes.append(self._add_axes(left, top, right - left, bottom - top, projection))
            x += w * cell + gap
        self._y += height
        return axes

    def float_right(self, width: float, height: float, *, pad_left: float = 0.55,
                    pad_bottom: float = 0.5, pad_top: float = 0.3):
        """Axes in a block ``width`` x ``height`` inches at the right margin,
        from the cursor down, with text and tables continuing at its left
        (they must be narrow enough); :meth:`clear_float` moves the cursor
        below it. Returns the axes."""
        self.ensure(height)
        w = self.page.size[0]
        left = w - MARGIN_X - width + pad_left
        ax = self._add_axes(left, self._y + pad_top, width - pad_left,
                            height - pad_top - pad_bottom)
        self._float_bottom = self._y + height
        self._float_width = width + 0.15
        return ax

    def clear_float(self) -> None:
        self._y = max(self._y, self._float_bottom)
        self._float_bottom = 0.0

    def image(self, array, height: float) -> None:
        """An RGB(A) image array, fitted into the page width and ``height``."""
        h, w = array.shape[:2]
        self.ensure(height)
        height = min(height, self.remaining)
        disp_w = min(self.width, height * w / h)
        disp_h = disp_w * h / w
        x0 = MARGIN_X + (self.width - disp_w) / 2
        self._put_image(array, x0, self._y, disp_w, disp_h)
        self._y += disp_h + 0.1

    def _put_image(self, array, left, top, width, height) -> None:
        ax = self._add_axes(left, top, width, height)
        ax.imshow(array, interpolation="antialiased")
        ax.set_axis_off()

    # ---------------------------------------------------------------- finish
    def _footers(self, footer: str) -> None:
        n = len(self.pages)
        for i, page in enumerate(self.pages, 1):
            w, h = page.size
            self._put(MARGIN_X, h - 0.35, footer, 7, color="0.35", page=page)
            self._put(w - MARGIN_X, h - 0.35, f"page {i} of {n}", 7, color="0.35", ha="right",
                      page=page)

    def finish(self, footer: str) -> list:
        """Number the pages and return the figures."""
        self._footers(footer)
        return [p.figure for p in self.pages]
