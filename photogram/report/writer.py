"""Build the report of a results folder and write report.pdf.

Two ways to draw it: a report whose sections all have native builders
(``native=True`` in :mod:`photogram.report.registry`: the pages of calibrate
and orient) is drawn by the native PDF writer (:mod:`photogram.report.native`,
no matplotlib import: about 0.1 s instead of 2 s for CAMCAL, issue 23); the
others (intersect, Monte Carlo, mocap) and any report with text outside
cp1252 are drawn with matplotlib as described below.

The PDF is reproducible: matplotlib's default style (not the user's
matplotlibrc), no creation date, and nothing in the pages that depends on
the time or the machine, so that the same results folder gives a
byte-identical report.pdf. It is written atomically.

Fonts: the PDF's standard fonts (Helvetica, and Courier for the monospaced
tables; every viewer has them, nothing is embedded), because laying out and
writing text glyph by glyph in embedded DejaVu subsets was half of a
report's CPU time (issue 23). They cover Latin-1 (cp1252) only: a page with
any other character (a Greek project name, say) is written with embedded
Type 3 subsets of DejaVu instead, as before. Minus signs are ASCII hyphens
(``axes.unicode_minus`` off: U+2212 is not in cp1252). PNG pages
(``png_folder``) are rendered by Agg with DejaVu.
"""

from __future__ import annotations

import io
import logging
from contextlib import ExitStack
from pathlib import Path

import photogram
from photogram.errors import InputError
from photogram.project.atomic import atomic_write_bytes
from photogram.report.data import ReportData, load
from photogram.report.layout import Document
from photogram.report.registry import all_native, sections

__all__ = ["write_report", "build_report", "REPORT_NAME", "RC"]

REPORT_NAME = "report.pdf"

RC = {"pdf.fonttype": 3, "pdf.use14corefonts": True, "axes.unicode_minus": False,
      "font.size": 8, "axes.titlesize": 8.5, "axes.labelsize": 8,
      "xtick.labelsize": 7, "ytick.labelsize": 7, "legend.fontsize": 7,
      "axes.titlelocation": "left", "figure.dpi": 100, "image.interpolation": "antialiased",
      "font.monospace": ["DejaVu Sans Mono", "Courier"]}


class _QuietWeight(logging.Filter):
    """Drop matplotlib's note that the standard fonts' weight is "Medium"
    where "normal" was asked for (it picks the right font)."""

    def filter(self, record) -> bool:
        return not str(record.msg).startswith("findfont: Failed to find font weight")


def _style(stack: ExitStack) -> None:
    import matplotlib
    import matplotlib.style

    stack.enter_context(matplotlib.style.context("default"))
    stack.enter_context(matplotlib.rc_context(RC))
    logger, quiet = logging.getLogger("matplotlib.font_manager"), _QuietWeight()
    logger.addFilter(quiet)
    stack.callback(logger.removeFilter, quiet)


def core_fonts_fit(fig) -> bool:
    """True if every text of ``fig`` can be written in the PDF standard
    fonts (cp1252); tick labels are numbers with ASCII minus signs."""
    from matplotlib.text import Text

    for artist in fig.findobj(Text):
        try:
            artist.get_text().encode("cp1252")
        except UnicodeEncodeError:
            return False
    return True


def _header(data) -> str:
    return f"photogram {photogram.__version__} {data.command} report: {data.name}"


def _footer(data) -> str:
    return f"photogram {photogram.__version__} - accuracy report of {data.name} ({data.command})"


def _lay_out(doc, data, secs):
    outline = []
    for sec in secs:
        before = len(doc.pages)
        sec.build(doc, data)
        outline.append((sec.title, len(doc.pages) - before))
    return doc.finish(_footer(data)), outline


def build_report(data: ReportData, secs=None):
    """Lay out the pages of ``data`` with matplotlib; returns ``(figures,
    outline)`` with ``outline`` a list of ``(section title, number of
    pages)``. Call inside the report's style (see :func:`write_report`)."""
    return _lay_out(Document(header=_header(data)), data,
                    sections(data) if secs is None else secs)


def _meta(data) -> dict:
    return {"Title": f"Accuracy report: {data.name} ({data.command})",
            "Author": None, "Subject": "photogrammetric adjustment results",
            "Creator": f"photogram {photogram.__version__}", "CreationDate": None,
            "ModDate": None}


def build_native(data: ReportData, secs=None):
    """Lay out and draw the pages of ``data`` with the native PDF writer;
    returns ``(pdf bytes, outline)``. Raises UnicodeEncodeError for text
    outside cp1252 (the standard fonts' encoding)."""
    from photogram.report.native import NativeDocument

    doc = NativeDocument(header=_header(data), info=_meta(data))
    _, outline = _lay_out(doc, data, sections(data) if secs is None else secs)
    return doc.tobytes(), outline


def _matplotlib_pdf(figures, meta) -> bytes:
    import matplotlib
    from matplotlib.backends.backend_pdf import PdfPages

    buf = io.BytesIO()
    with PdfPages(buf, metadata=meta) as pdf:
        for fig in figures:
            with matplotlib.rc_context({"pdf.use14corefonts": core_fonts_fit(fig)}):
                pdf.savefig(fig)
    return buf.getvalue()


def report_units(data, units=None) -> str:
    """The units of the stick-model pages: ``units``, else summary.json's
    ``report_units``, else the project's ``[report] units``, else "project"."""
    from photogram.project.model import REPORT_UNITS

    project = getattr(getattr(data.project, "report", None), "units", None)
    value = units or data.summary.get("report_units") or project or "project"
    if value in REPORT_UNITS:       # photogram.jump only for the error (its import costs)
        return value
    from photogram.jump.coach import check_units
    return check_units(value)


def write_report(folder: str | Path, *, output: str | Path | None = None,
                 png_folder: str | Path | None = None, dpi: int = 60,
                 outline: list | None = None, units: str | None = None,
                 project=None, tables: dict | None = None) -> Path:
    """Write ``report.pdf`` for the results folder ``folder``.

    Parameters
    ----------
    folder : str or Path
        A results folder written by calibrate, orient or intersect.
    output : str or Path, optional
        Folder to write report.pdf into (default ``folder``).
    png_folder : str or Path, optional
        Also write every page as ``page-NN.png`` there (``dpi``), rendered
        by matplotlib (the matplotlib layout of the same pages, also when
        report.pdf is drawn natively; for a quick look and tests).
    project : Project, optional
        The project the results were computed from, as read from its file
        and not changed since (a command passes the one it has in memory,
        so that it is not read again; see :func:`photogram.report.data.load`).
    tables : dict, optional
        The tables the command has just written into ``folder`` (file name
        -> :class:`~photogram.project.results.WrittenTable`, from
        :func:`~photogram.project.results.write_results`), so that they are
        not parsed again; the report is the same as without them.
    outline : list, optional
        If given, ``(section title, number of pages)`` of every section are
        appended to it.
    units : str, optional
        "project" or "coach" (:mod:`photogram.jump.coach`); default: what
        the command used (summary.json), else the project's ``[report] units``.

    Returns
    -------
    Path
        The report.

    Raises
    ------
    InputError
        ``folder`` is not a results folder (one line naming what is missing).
    """
    data = load(folder, project, tables)
    data.extra["units"] = report_units(data, units)
    target = Path(output) if output is not None else Path(folder)
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the report folder: {exc.strerror}", file=target,
                         hint="check the path and permissions (--output)") from None
    secs = sections(data)
    pdf = None
    if all_native(secs):
        try:
            pdf, contents = build_native(data, secs)
        except UnicodeEncodeError:          # not cp1252: matplotlib with embedded DejaVu
            pdf = None
    if pdf is not None and png_folder is None:
        if outline is not None:
            outline.extend(contents)
        return atomic_write_bytes(target / REPORT_NAME, pdf)
    with ExitStack() as stack:
        _style(stack)
        figures, mpl_contents = build_report(data, secs)
        if pdf is None:
            pdf, contents = _matplotlib_pdf(figures, _meta(data)), mpl_contents
        if png_folder is not None:
            png_folder = Path(png_folder)
            png_folder.mkdir(parents=True, exist_ok=True)
            for i, fig in enumerate(figures, 1):
                fig.savefig(png_folder / f"page-{i:02d}.png", dpi=dpi,
                            metadata={"Software": None})
    if outline is not None:
        outline.extend(contents)
    return atomic_write_bytes(target / REPORT_NAME, pdf)
