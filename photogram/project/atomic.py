"""Atomic file writes: a file is either the old one or the complete new one.

The text goes to a temporary file in the same folder, is flushed and
fsync'ed, and then renamed over the target with :func:`os.replace` (atomic on
POSIX and Windows). On any failure the temporary file is removed and the
target is left untouched.

File modes: :func:`tempfile.mkstemp` creates its file with mode 0600 (only the
owner may read it). The temporary file is given the mode any other new file
would get, ``0666 & ~umask`` (a replaced file keeps its own mode, as when an
editor saves it), before it is renamed into place (:func:`give_file_mode`).
"""

from __future__ import annotations

import os
import stat
import tempfile
import threading
from pathlib import Path

from photogram.errors import InputError

__all__ = ["atomic_write_text", "atomic_write_bytes", "same_file", "give_file_mode",
           "current_umask"]

_UMASK_LOCK = threading.Lock()


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (the folder must exist).

    Parameters
    ----------
    path : str or Path
        Target file; replaced if it exists.
    data : bytes
        The complete content.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        The folder does not exist or is not writable.
    """
    path = Path(path)
    folder = path.parent
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise InputError(f"cannot write into {folder}: {exc.strerror}", file=path,
                         hint="check that the folder exists and is writable") from None
    try:
        give_file_mode(tmp, path, fd=fd)
        with os.fdopen(fd, "wb") as handle:
            _write_all(handle, data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        _remove(tmp)
        if isinstance(exc, OSError) and exc.filename is None:
            exc.filename = str(path)          # a full disk names the file it hit
        raise
    _sync_folder(folder)
    return path


def current_umask() -> int:
    """The process's umask (read from /proc where possible: setting it to
    read it is not thread-safe)."""
    try:
        with open("/proc/self/status", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    with _UMASK_LOCK:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def give_file_mode(tmp: str | Path, target: str | Path, *, fd: int | None = None) -> None:
    """Give the temporary file ``tmp`` (made by :func:`tempfile.mkstemp`,
    mode 0600) the mode ``target`` will have: the mode of the file it
    replaces, else ``0666 & ~umask`` like any newly created file.

    Parameters
    ----------
    tmp : str or Path
        The temporary file.
    target : str or Path
        The file it will be renamed to.
    fd : int, optional
        An open descriptor of ``tmp`` (then ``fchmod`` is used).
    """
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except OSError:
        mode = 0o666 & ~current_umask()
    try:
        if fd is not None and hasattr(os, "fchmod"):
            os.fchmod(fd, mode)
        else:
            os.chmod(tmp, mode)
    except OSError:                 # e.g. a file system without modes: keep what we have
        pass


def _write_all(handle, data: bytes) -> None:
    """Write in chunks (a seam for tests that simulate a failure mid-write)."""
    step = 1 << 20
    for start in range(0, len(data), step):
        handle.write(data[start:start + step])


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` as UTF-8 with ``\\n`` line ends, atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def _remove(tmp: str) -> None:
    try:
        os.unlink(tmp)
    except OSError:
        pass


def _sync_folder(folder: Path) -> None:
    """fsync the folder so that the rename itself is durable (POSIX only)."""
    if os.name != "posix":
        return
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def same_file(a: str | Path, b: str | Path) -> bool:
    """Whether two paths name the same file (existing or not)."""
    a, b = Path(a), Path(b)
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return a.resolve() == b.resolve()
