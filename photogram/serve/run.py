"""The "run" button of ``photogram measure --serve``: ``photogram
calibrate``, ``orient`` or ``intersect`` on the saved project, in a
subprocess (``PHOTOGRAM COMMAND PROJECT --force --no-report --quiet``, a
timeout of :data:`TIMEOUT` s), then the results folder read again
(orientation, sigma0, worst residuals). ``PHOTOGRAM`` is the command line
that started the server, as the command-line layer gives it
(``session.run_argv``: the same interpreter running the same front end;
the library does not name the front end, docs/index.md).

A subprocess rather than a call: the command runs exactly as on the
command line (its own results-folder lock, its own error handling and exit
code), a crash or a long run does not take the server with it, and the
layers stay clean (``photogram.serve`` does not import the commands).
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from photogram.serve.results import read_orientation
from photogram.serve.table import BadEdit

__all__ = ["run_command", "COMMANDS", "TIMEOUT"]

COMMANDS = ("calibrate", "orient", "intersect")
TIMEOUT = 600.0


class NotSaved(BadEdit):
    """The project has unsaved edits (HTTP 409)."""

    status = 409


def _env() -> dict:
    """The environment of the subprocess: this process's, with the folder
    of the photogram package first on PYTHONPATH (the same code runs)."""
    import photogram
    env = dict(os.environ)
    top = str(Path(photogram.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join([top] + [p for p in env.get("PYTHONPATH", "").split(
        os.pathsep) if p and p != top])
    env["PYTHONIOENCODING"] = "utf-8"
    return env


def run_command(session, command, timeout: float = TIMEOUT) -> dict:
    """``POST /api/run``: run ``command`` on the project (module doc).

    Raises
    ------
    BadEdit
        Not one of :data:`COMMANDS`.
    NotSaved
        The tables have unsaved edits (save first).
    """
    if command not in COMMANDS:
        raise BadEdit(f"cannot run {command!r}: choose {', '.join(COMMANDS)}")
    if session.dirty:
        raise NotSaved("save the observations first: the command reads the saved table")
    prefix = getattr(session, "run_argv", None)
    if not prefix:
        raise BadEdit("running commands needs the server started by photogram measure --serve")
    args = [*prefix, command, str(session.project.path), "--force", "--no-report", "--quiet"]
    try:
        proc = subprocess.run(args, capture_output=True, text=True, timeout=timeout,
                              env=_env(), cwd=str(session.project.folder), stdin=subprocess.DEVNULL)
        rc, err = proc.returncode, proc.stderr
    except subprocess.TimeoutExpired:
        rc, err = -1, f"photogram {command} did not finish within {timeout:.0f} s (stopped)"
    lines = [line.strip() for line in (err or "").splitlines() if line.strip()]
    session.orientation = read_orientation(session.project)
    _, worst = session.residuals()
    return {"rc": rc, "sigma0": session.orientation.sigma0, "worst": worst,
            "message": lines[-1] if lines else "", "project": session.body()}
