"""The registry of report sections.

A section is a group of pages: a name, a title, a test whether it applies to
a results folder (``applies(data) -> bool``) and a builder that lays its
pages out (``build(doc, data)``, see :class:`photogram.report.layout.Document`).
Sections are registered with :func:`section` when their module is imported
and built in the order of ``order``; the modules are listed in
:data:`MODULES`.

A later command adds its pages by writing a module with one or more
``@section(...)`` builders that apply when its output files exist, and
adding the module to :data:`MODULES` (see photogram/report/hooks.py for the
Monte Carlo and motion-capture entries, and docs/report.md).

A section registered with ``native=True`` can also be laid out by
:class:`photogram.report.native.NativeDocument` (the PDF writer without
matplotlib); a report whose applicable sections are all native is written
that way (:func:`all_native`), any other with matplotlib.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Callable

__all__ = ["Section", "SECTIONS", "MODULES", "INPUT_ONLY", "section", "sections",
           "all_native"]

#: page modules, imported by :func:`sections`
MODULES = ("photogram.report.pages_summary", "photogram.report.pages_cameras",
           "photogram.report.pages_stations", "photogram.report.pages_measurement",
           "photogram.report.pages_residuals",
           "photogram.report.pages_points", "photogram.report.pages_geometry",
           "photogram.report.pages_network", "photogram.report.pages_inputs",
           "photogram.report.pages_intersect", "photogram.report.hooks",
           "photogram.report.pages_montecarlo", "photogram.report.pages_mocap")

#: sections left out of a command's report because that command estimates
#: nothing they show: the intersect step holds cameras and stations fixed
#: (the reports of calibrate and orient have their pages); its report shows
#: them once, on one page ("inputs", photogram/report/pages_inputs.py)
INPUT_ONLY = {"intersect": ("cameras", "stations")}


@dataclass(frozen=True)
class Section:
    name: str
    title: str
    order: float
    applies: Callable
    build: Callable
    native: bool = False


SECTIONS: dict[str, Section] = {}


def section(name: str, title: str, order: float, applies: Callable | None = None, *,
            native: bool = False):
    """Decorator registering ``build(doc, data)`` as the section ``name``
    (a later registration under the same name replaces an earlier one);
    ``native``: the builder also draws on the native document (it uses only
    what :class:`photogram.report.native.NativeDocument` and its axes offer)."""
    def register(build):
        SECTIONS[name] = Section(name, title, order, applies or (lambda data: True), build,
                                 native)
        return build
    return register


def sections(data=None) -> list[Section]:
    """The registered sections in order; with ``data`` only those that
    apply to it."""
    for module in MODULES:
        importlib.import_module(module)
    out = sorted(SECTIONS.values(), key=lambda s: (s.order, s.name))
    if data is None:
        return out
    skip = INPUT_ONLY.get(data.command, ())
    return [s for s in out if s.name not in skip and s.applies(data)]


def all_native(secs) -> bool:
    """Whether every section of ``secs`` has a native builder."""
    return all(s.native for s in secs)
