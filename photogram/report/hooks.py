"""Hooks for the commands being built: Monte Carlo and motion capture.

Each is a registered section that applies to a results folder whose
summary.json says ``"command": "montecarlo"`` (or ``"mocap"``), that has a
``"montecarlo"`` / ``"mocap"`` entry in summary.json, or that holds files
named ``montecarlo*`` / ``mocap*`` (.csv, .json, .png). Both commands now
have their own pages (photogram/report/pages_montecarlo.py, pages_mocap.py),
registered under the same names, which replace these; the generic view
remains the pattern for a command without pages. It shows what it finds: the summary's
numbers, the first rows of their tables (Monte Carlo: table1.csv,
table2.csv; mocap: metrics.csv, reprojection.csv, bones.csv; and the
prefixed CSV files), the prefixed JSON files and PNG figures.

To give a command proper pages, register a builder under the same section
name in a module of :data:`photogram.report.registry.MODULES` listed after
this one (a later registration replaces this one), e.g.::

    @section("montecarlo", "Monte Carlo", 90, applies=lambda d: d.has("montecarlo.csv"))
    def build(doc, data): ...
"""

from __future__ import annotations

import json

import numpy as np

from photogram.report.numbers import num
from photogram.report.registry import section

_SUFFIXES = (".csv", ".json", ".png")


def files(data, prefix: str):
    """Files of the results folder whose name starts with ``prefix``."""
    return sorted(p for p in data.folder.iterdir()
                  if p.is_file() and p.name.startswith(prefix) and p.suffix in _SUFFIXES)


def _flat(value, key=""):
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _flat(v, f"{key}.{k}" if key else str(k))
    elif isinstance(value, (int, float, str, bool)) or value is None:
        yield key, value
    elif isinstance(value, list) and len(value) <= 8 and all(
            isinstance(v, (int, float, str)) for v in value):
        yield key, ", ".join(num(v, 4) if isinstance(v, float) else str(v) for v in value)


def _cell(v):
    return num(v, 4) if isinstance(v, float) else str(v)


def generic(doc, data, title: str, prefix: str, intro: str, extra=()) -> None:
    """The outputs of a command the report has no pages for yet: its entry
    of summary.json (or the whole summary if the folder is its own), the
    first rows of its CSV files (``prefix*`` and ``extra``), its JSON files
    and PNG figures."""
    doc.start_section(title, intro=intro)
    entry = data.summary.get(prefix) or (data.summary if data.command == prefix else None)
    if entry:
        doc.pairs([(k, _cell(v)) for k, v in list(_flat(entry))[:50]], title="summary.json",
                  size=7.5)
    paths = [data.folder / f for f in extra if data.has(f)] + files(data, prefix)
    for path in paths:
        if path.suffix == ".csv":
            import pandas as pd

            frame = pd.read_csv(path, comment="#")
            cols = list(frame.columns)[:9]
            doc.table(cols, [[_cell(v) for v in row] for row in
                             frame[cols].head(40).itertuples(index=False)],
                      title=f"{path.name}: {len(frame)} rows, {len(frame.columns)} columns",
                      size=7,
                      note="(first 40 rows and 9 columns)" if frame.shape[0] > 40
                      or frame.shape[1] > 9 else None)
        elif path.suffix == ".json":
            try:
                content = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError, RecursionError):
                continue
            doc.pairs([(k, num(v, 5) if isinstance(v, float) else str(v))
                       for k, v in list(_flat(content))[:40]], title=path.name)
        else:
            from photogram.report.data import read_image

            doc.subheading(path.name)
            doc.image(read_image(path), min(6.0, doc.remaining - 0.1))


@section("montecarlo", "Monte Carlo", 90,
         applies=lambda d: d.command == "montecarlo" or bool(files(d, "montecarlo"))
         or "montecarlo" in d.summary)
def build_montecarlo(doc, data):
    generic(doc, data, "Monte Carlo", "montecarlo", extra=("table1.csv", "table2.csv"), intro=(
        "Outputs of photogram montecarlo found in the results folder (generic view until "
        "the Monte Carlo pages are defined): the spread of the results over simulated "
        "measurement noise, to compare with the propagated sigmas of the other pages."))


@section("mocap", "Motion capture", 95,
         applies=lambda d: d.command == "mocap" or bool(files(d, "mocap"))
         or "mocap" in d.summary)
def build_mocap(doc, data):
    generic(doc, data, "Motion capture", "mocap",
            extra=("metrics.csv", "reprojection.csv", "bones.csv"), intro=(
        "Outputs of photogram mocap found in the results folder (generic view until the "
        "motion-capture pages are defined)."))
