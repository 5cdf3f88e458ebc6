"""Accuracy reports: report.pdf of a results folder.

:func:`write_report` reads a results folder (summary.json, cameras.toml,
stations.csv, points.csv, residuals.csv, covariance.npz, and the intersect
outputs exposures.csv, points3d.csv, lines3d.csv, stick.png) and writes
``report.pdf`` into it, atomically and byte-identical for the same input.
Every command calls it at the end; ``photogram report FOLDER`` rebuilds it.

The pages are groups ("sections") registered in :mod:`photogram.report.registry`
by the ``pages_*`` modules, each applying only when its data exist; see
docs/report.md for what each page shows and how to read it.
"""

from photogram.report.data import ReportData, load
from photogram.report.registry import SECTIONS, Section, section, sections
from photogram.report.writer import REPORT_NAME, build_report, write_report

__all__ = ["write_report", "build_report", "load", "ReportData", "REPORT_NAME",
           "Section", "SECTIONS", "section", "sections"]
