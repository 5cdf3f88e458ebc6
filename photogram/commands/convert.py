"""`photogram import FORMAT SRC --to DIR` and `photogram export FORMAT
RESULTS --to PATH`: the command-line ends of :mod:`photogram.io.formats`."""

from __future__ import annotations

from photogram.errors import InputError

__all__ = ["run_import", "run_export"]


def _need(args, name: str, usage: str):
    value = getattr(args, name, None)
    if value in (None, ""):
        raise InputError(f"missing {name.upper() if name != 'to' else '--to'}",
                         hint=f"usage: {usage}")
    return value


def run_import(args) -> int:
    """Import a foreign project or calibration into a new project folder."""
    from photogram.io.formats import IMPORT_FORMATS, import_project
    usage = f"photogram import {{{','.join(IMPORT_FORMATS)}}} SRC --to DIR"
    fmt = _need(args, "format", usage)
    src = _need(args, "source", usage)
    to = _need(args, "to", usage)
    prj = import_project(fmt, src, to, name=getattr(args, "name", None),
                         target=getattr(args, "target", None),
                         model=getattr(args, "model", None) or "opencv")
    if not getattr(args, "quiet", False):
        print(f"import {fmt}: {src} -> {prj}")
    return 0


def run_export(args) -> int:
    """Export a results folder (or a project) in a foreign format."""
    from photogram.io.formats import EXPORT_FORMATS, export_results
    usage = f"photogram export {{{','.join(EXPORT_FORMATS)}}} RESULTS --to PATH [--force]"
    fmt = _need(args, "format", usage)
    src = _need(args, "source", usage)
    to = _need(args, "to", usage)
    files = export_results(fmt, src, to, force=bool(getattr(args, "force", False)))
    if not getattr(args, "quiet", False):
        shown = ", ".join(str(f) for f in files[:4]) + (" ..." if len(files) > 4 else "")
        print(f"export {fmt}: {src} -> {shown}")
    return 0
