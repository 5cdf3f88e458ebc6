"""`photogram report RESULTS`: rebuild report.pdf of a results folder.

Every command writes its report at the end; this rebuilds it from the saved
results (e.g. after an update of photogram, or into another folder with
``--output``). Byte-identical to the command's report for the same results.
"""

from __future__ import annotations

from photogram.errors import InputError
from photogram.report import write_report


def run(args):
    """Command-line entry: ``args.folder`` (the results folder), optional
    ``args.output``; prints one line."""
    if getattr(args, "folder", None) is None:
        raise InputError("photogram report: which results folder?",
                         hint="give it, e.g. photogram report projects/lab/results")
    outline = []
    path = write_report(args.folder, output=getattr(args, "output", None), outline=outline,
                        units=getattr(args, "units", None))
    if not getattr(args, "quiet", False):
        pages = sum(n for _, n in outline)
        print(f"report: {pages} pages ({', '.join(t for t, _ in outline)}) in {path}")
    return 0
