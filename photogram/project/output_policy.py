"""Nothing is lost: where a command may write its results.

Rules (docs/reliability.md, "Nothing lost"):

* a results folder that holds the results of an earlier run (its
  ``summary.json``) is never silently replaced: the command stops with one
  line and asks for ``--force`` (replace) or ``--output NEW_FOLDER``;
* a folder that is not empty and holds no photogram results (e.g. a project
  folder given as ``--output``) is not written into without ``--force``;
* an output folder never contains an input file of the run, not even with
  ``--force`` (outputs would overwrite inputs);
* an unfinished run of a resumable command (``photogram montecarlo``: its
  ``samples/``; ``photogram mocap``: its ``.partial/``, both in the staging
  folder) is resumed, not refused;
* a folder whose replacement was interrupted (marked incomplete) is
  replaced without ``--force``.

Results are written into a staging folder and moved into place at the end,
under a lock that keeps a second run out
(:mod:`photogram.project.results_folder`); every file is written atomically
(:mod:`photogram.project.atomic`).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from photogram.errors import InputError
from photogram.project.results_folder import (
    INCOMPLETE, RESUMABLE_STATE, check_not_inputs, staging_path)

__all__ = ["claim_output", "project_inputs", "PARTIAL"]

#: the hidden folder of a resumable run's intermediate results
PARTIAL = RESUMABLE_STATE[0]
_RESUMABLE_STATE = RESUMABLE_STATE


def project_inputs(project) -> list[Path]:
    """The files a project reads: the .prj, its tables, and the files of a
    ``[mocap]`` or ``[track]`` section."""
    out = [Path(project.path)] + [Path(p) for p in project.sources.values() if p]
    ms = getattr(project, "mocap", None)
    if ms is not None:
        for name in ("calibration", "camera_frames", "limb_lengths", "truth", "reference_trc",
                     "rotation_differences", "truth_rotations"):
            value = getattr(ms, name, None)
            if value is not None:
                out.append(Path(value))
        if ms.source.path is not None:
            out.append(Path(ms.source.path))
        out += [Path(p) for p in (ms.source.cameras or {}).values()]
        out += [Path(p) for p in (ms.images or {}).values()]
    ts = getattr(project, "track", None)
    if ts is not None:          # [track]: videos, seed clicks, exposure frames
        out += [Path(p) for p in ts.videos.values()]
        out += [Path(p) for p in (ts.seeds, ts.exposures) if p is not None]
    bs = getattr(project, "board", None)
    if bs is not None:          # [board]: videos or image folders
        out += [Path(p) for p in bs.cameras.values()]
        out += [Path(p) for p in (bs.scene or {}).get("files", [])]
    return out


def _earlier(summary: Path) -> str:
    try:
        data = json.loads(summary.read_text(encoding="utf-8"))
        what = str(data.get("command") or "a run")
    except (OSError, ValueError):
        what = "a run"
    stamp = time.strftime("%Y-%m-%d %H:%M", time.localtime(summary.stat().st_mtime))
    return f"{what} of {stamp}"


def claim_output(folder, *, command: str, inputs=(), force: bool = False,
                 resumable: bool = False) -> str:
    """Check that ``folder`` may receive the results of ``command`` (module
    doc) before any work is done.

    Returns
    -------
    str
        ``"new"`` (absent or empty), ``"replace"`` (earlier results, with
        ``force``; an interrupted replacement), ``"resume"`` (an unfinished
        resumable run).

    Raises
    ------
    InputError
        One line naming the folder and what to do.
    """
    folder = Path(folder).absolute()
    check_not_inputs(folder, inputs)
    staged = resumable and any((staging_path(folder) / name).is_dir()
                               for name in _RESUMABLE_STATE)
    if not folder.exists():
        return "resume" if staged else "new"
    if not folder.is_dir():
        raise InputError("the output folder is a file", file=folder,
                         hint="choose a folder with --output")
    if (folder / INCOMPLETE).is_file():
        return "replace"                  # our own replacement, interrupted
    summary = folder / "summary.json"
    if summary.is_file():
        if force:
            return "resume" if staged else "replace"
        raise InputError(f"holds the results of an earlier run ({_earlier(summary)}); "
                         f"photogram {command} does not replace them silently", file=folder,
                         hint="add --force to replace them, or write a new folder with "
                              "--output NEW_FOLDER")
    if resumable and any((folder / name).is_dir() for name in _RESUMABLE_STATE):
        return "resume"                   # left by a version without staging folders
    if any(folder.iterdir()) and not force:
        raise InputError("the output folder is not empty and holds no photogram results",
                         file=folder, hint="add --force to write into it anyway, or choose "
                                           "another folder with --output")
    return "resume" if staged else "new"
