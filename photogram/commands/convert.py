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
                         model=getattr(args, "model", None) or "opencv",
                         control=getattr(args, "control", None),
                         free=_free(getattr(args, "free", None)),
                         image_size=_size(getattr(args, "image_size", None)))
    if not getattr(args, "quiet", False):
        print(f"import {fmt}: {src} -> {prj}")
    return 0


def _free(text):
    """``--free all`` or ``--free c,x0,y0``."""
    if text is None:
        return None
    words = [w.strip() for w in str(text).split(",") if w.strip()]
    return "all" if words == ["all"] else words


def _size(text):
    """``--image-size 2272,1704`` -> (2272, 1704)."""
    if text is None:
        return None
    try:
        w, h = (int(v) for v in str(text).replace("x", ",").split(","))
    except ValueError:
        raise InputError(f"--image-size {text!r} is not WIDTH,HEIGHT in pixels",
                         hint="e.g. --image-size 2272,1704") from None
    if w <= 0 or h <= 0:
        raise InputError(f"--image-size {text!r} must be positive")
    return w, h


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
