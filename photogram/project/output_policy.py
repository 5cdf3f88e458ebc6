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
  ``samples/``; ``photogram mocap``: its ``.partial/``) is resumed, not
  refused.

Every file is written atomically (:mod:`photogram.project.atomic`), so an
interrupted run leaves either the old or the new version of a file.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from photogram.errors import InputError

__all__ = ["claim_output", "project_inputs", "PARTIAL"]

#: the hidden folder of a resumable run's intermediate results
PARTIAL = ".partial"
_RESUMABLE_STATE = (PARTIAL, "samples")


def project_inputs(project) -> list[Path]:
    """The files a project reads: the .prj, its tables, and the files of a
    ``[mocap]`` section."""
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
    return out


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.resolve().relative_to(folder.resolve())
        return True
    except ValueError:
        return False


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
        ``force``), ``"resume"`` (an unfinished resumable run).

    Raises
    ------
    InputError
        One line naming the folder and what to do.
    """
    folder = Path(folder).absolute()
    for p in inputs:
        p = Path(p)
        if p.exists() and _inside(p, folder):
            raise InputError(f"the output folder holds the input {p.name} of this run; "
                             f"photogram never writes over its inputs", file=folder,
                             hint="choose another folder with --output")
    if not folder.exists():
        return "new"
    if not folder.is_dir():
        raise InputError("the output folder is a file", file=folder,
                         hint="choose a folder with --output")
    summary = folder / "summary.json"
    if summary.is_file():
        if force:
            return "replace"
        raise InputError(f"holds the results of an earlier run ({_earlier(summary)}); "
                         f"photogram {command} does not replace them silently", file=folder,
                         hint="add --force to replace them, or write a new folder with "
                              "--output NEW_FOLDER")
    if resumable and any((folder / name).is_dir() for name in _RESUMABLE_STATE):
        return "resume"
    if any(folder.iterdir()) and not force:
        raise InputError("the output folder is not empty and holds no photogram results",
                         file=folder, hint="add --force to write into it anyway, or choose "
                                           "another folder with --output")
    return "new"
