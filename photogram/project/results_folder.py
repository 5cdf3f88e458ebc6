"""A results folder appears complete or not at all; one run writes it at a time.

A command writes its results into a **staging folder**, a hidden sibling of
the results folder (``<parent>/.<name>.incomplete``), and moves them into
place only when everything is written (:func:`staged_results`):

* results folder absent: the staging folder is renamed to it (one atomic
  rename);
* results folder present (``--force``, an empty folder, ``make demo``): it
  is first marked incomplete (``.photogram-incomplete``), the old
  ``summary.json`` is removed (the folder no longer looks complete), the
  entries the earlier run wrote (listed in its ``.photogram-files``) and the
  new run does not are removed, the new entries are moved in one by one
  (``summary.json`` last) and the mark is removed. Files that photogram did
  not write (a user's notes) stay.

An interruption (Ctrl-C, a full disk, a killed process) before that point
leaves the results folder as it was (absent, or the earlier results intact);
the rest of the run is in the staging folder. A rerun replaces a stale
staging folder without ``--force``, or, for a resumable command
(``photogram montecarlo``: ``samples/``; ``photogram mocap``: ``.partial/``),
continues it. The state of an earlier complete run (its ``samples/``) is
hard-linked into the staging folder, so a rerun with ``--force`` and the
same settings reuses its trials as before.

**One run per folder.** :func:`output_lock` takes a lock (the ``filelock``
package) on ``<parent>/.<name>.lock`` for the whole run: a second run into
the same folder, from any process, stops at once with one line. The lock is
re-entrant within a process (the command line takes it before checking the
folder, the command again when it stages its results).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import threading
from pathlib import Path

from photogram.errors import InputError
from photogram.project.atomic import atomic_write_text

__all__ = ["staged_results", "output_lock", "staging_path", "lock_path", "final_folder",
           "INCOMPLETE", "MANIFEST", "RESUMABLE_STATE"]

#: mark of a results folder whose replacement did not finish
INCOMPLETE = ".photogram-incomplete"
#: the entries a run wrote into its results folder (one name a line)
MANIFEST = ".photogram-files"
#: folders of a resumable run's intermediate state (montecarlo, mocap)
RESUMABLE_STATE = (".partial", "samples")
_STAGING_SUFFIX = ".incomplete"

_REGISTRY: dict[str, list] = {}        # lock file -> [FileLock, depth], this process
_REGISTRY_LOCK = threading.Lock()


def staging_path(folder) -> Path:
    """The staging folder of a results folder: ``<parent>/.<name>.incomplete``."""
    folder = Path(folder).absolute()
    return folder.parent / f".{folder.name}{_STAGING_SUFFIX}"


def lock_path(folder) -> Path:
    """The lock file of a results folder: ``<parent>/.<name>.lock``."""
    folder = Path(folder).absolute()
    return folder.parent / f".{folder.name}.lock"


def final_folder(path) -> Path:
    """The results folder a staging folder becomes (``path`` itself if it is
    not a staging folder): what reports and messages show."""
    path = Path(path).absolute()
    name = path.name
    if name.startswith(".") and name.endswith(_STAGING_SUFFIX) and \
            len(name) > len(_STAGING_SUFFIX) + 1:
        return path.parent / name[1:-len(_STAGING_SUFFIX)]
    return path


def _make_folder(path: Path, what: str, named: Path) -> None:
    """Create ``path`` (and its parents), or one line naming ``named``."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create {what}: {exc.strerror}", file=named,
                         hint="check the path and permissions ([output] folder or "
                              "--output)") from None


@contextlib.contextmanager
def output_lock(folder, *, command: str = "this command"):
    """Hold the lock of ``folder`` (module doc) for the ``with`` block.

    Raises
    ------
    InputError
        Another run (another process) holds it, or the lock file cannot be
        created.
    """
    import filelock

    folder = Path(folder).absolute()
    path = lock_path(folder)
    key = str(path)
    _make_folder(path.parent, "the folder of the results", path.parent)
    with _REGISTRY_LOCK:
        entry = _REGISTRY.setdefault(key, [filelock.FileLock(key, thread_local=False), 0])
        try:
            entry[0].acquire(timeout=0)
        except filelock.Timeout:
            if entry[1] == 0:
                del _REGISTRY[key]
            raise InputError(
                f"another photogram run is writing into this folder (its lock {path.name} "
                f"is held); photogram {command} does not mix its results with another run's",
                file=folder, hint="wait until that run has finished, or write a new folder "
                                  "with --output NEW_FOLDER") from None
        except OSError as exc:
            if entry[1] == 0:
                del _REGISTRY[key]
            raise InputError(f"cannot create the lock file: {exc.strerror}", file=path,
                             hint="check that the folder is writable") from None
        entry[1] += 1
    try:
        yield path
    finally:
        with _REGISTRY_LOCK:
            entry[0].release()
            entry[1] -= 1
            if entry[1] == 0:
                del _REGISTRY[key]


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.resolve().relative_to(folder.resolve())
        return True
    except ValueError:
        return False


def check_not_inputs(folder, inputs) -> None:
    """Refuse a results folder that holds an input file of the run.

    Raises
    ------
    InputError
    """
    folder = Path(folder).absolute()
    for p in inputs:
        p = Path(p)
        if p.exists() and _inside(p, folder):
            raise InputError(f"the output folder holds the input {p.name} of this run; "
                             f"photogram never writes over its inputs", file=folder,
                             hint="choose another folder with --output")


class Stage:
    """A staging folder being written; see :func:`staged_results`.

    Attributes
    ----------
    final : Path
        The results folder.
    path : Path
        Where to write (the staging folder).
    """

    def __init__(self, final: Path, resumable: bool):
        self.final, self.path, self.resumable = final, staging_path(final), resumable

    def open(self) -> None:
        """Create the staging folder: continue it (resumable run with
        state), or start it afresh."""
        if self.path.exists() and not (self.resumable and _has_state(self.path)):
            _remove(self.path)
        _make_folder(self.path, "the results folder", self.final)
        if self.resumable and self.final.is_dir():
            for name in RESUMABLE_STATE:       # an earlier run's trials, by hard links
                src, dst = self.final / name, self.path / name
                if src.is_dir() and not dst.exists():
                    shutil.copytree(src, dst, copy_function=_link_or_copy)

    def commit(self) -> Path:
        """Move the staging folder's content into the results folder
        (module doc); returns the results folder."""
        for name in RESUMABLE_STATE[:1]:        # mocap's .partial: only while unfinished
            _remove(self.path / name)
        entries = sorted(p.name for p in self.path.iterdir() if p.name != MANIFEST)
        atomic_write_text(self.path / MANIFEST, "\n".join(entries) + "\n")
        if not self.final.exists():
            os.rename(self.path, self.final)
            return self.final
        if not self.final.is_dir():
            raise InputError("the output folder is a file", file=self.final,
                             hint="choose a folder with --output")
        _merge(self.path, self.final, entries)
        return self.final


@contextlib.contextmanager
def staged_results(folder, *, command: str = "this command", inputs=(),
                   resumable: bool = False):
    """Write a results folder through a staging folder (module doc).

    Parameters
    ----------
    folder : str or Path
        The results folder.
    command : str
        For messages.
    inputs : iterable of path
        The run's input files: none may lie inside ``folder``.
    resumable : bool
        Keep the staging folder after an error if it holds the run's state
        (``samples/``, ``.partial/``, for the rerun to continue), and
        continue one that holds a state.

    Yields
    ------
    Stage
        Write into ``stage.path``; on leaving the block without an error the
        results are moved to ``stage.final``.

    Raises
    ------
    InputError
        The folder holds an input, another run writes it, or it cannot be
        created.
    """
    final = Path(folder).absolute()
    check_not_inputs(final, inputs)
    with output_lock(final, command=command):
        stage = Stage(final, resumable)
        stage.open()
        try:
            yield stage
        except BaseException:
            if not (resumable and _has_state(stage.path)):   # nothing to continue
                _remove(stage.path)
            raise
        stage.commit()


def _has_state(folder: Path) -> bool:
    return any((folder / name).is_dir() for name in RESUMABLE_STATE)


def _link_or_copy(src, dst):
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)
    return dst


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    elif path.exists() or path.is_symlink():
        try:
            path.unlink()
        except OSError:
            pass


def _move(src: Path, dst: Path) -> None:
    if dst.is_dir() and not dst.is_symlink():
        shutil.rmtree(dst)
    os.replace(src, dst)


def _merge(staging: Path, final: Path, entries: list[str]) -> None:
    """Replace the results in an existing folder (module doc)."""
    atomic_write_text(final / INCOMPLETE, "photogram is replacing the results in this "
                                          "folder; if this file stays, that run was "
                                          "interrupted: run the command again\n")
    (final / "summary.json").unlink(missing_ok=True)
    try:
        earlier = (final / MANIFEST).read_text(encoding="utf-8").split("\n")
    except (OSError, UnicodeDecodeError):
        earlier = []
    keep = set(entries) | {MANIFEST, INCOMPLETE}
    for name in earlier:
        if name and name not in keep and "/" not in name and name not in (".", ".."):
            _remove(final / name)
    last = [n for n in entries if n == "summary.json"]
    for name in [n for n in entries if n != "summary.json"] + [MANIFEST] + last:
        _move(staging / name, final / name)
    (final / INCOMPLETE).unlink()
    _remove(staging)
