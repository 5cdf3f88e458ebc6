"""File names from user-given names (cameras, stations, points, projects).

A name in a project file or on the command line is text chosen by whoever
wrote the project: ``"../../../../x"``, ``"C1/evil"``, a NUL byte, 5000
characters, ``"CON"``. Whenever such a name becomes a file or folder name it
goes through :func:`safe_name` (one name) or :func:`safe_names` (the names of
one folder, kept distinct), and the joined path through :func:`inside`, so
that every file photogram writes stays inside its folder.

Rules of :func:`safe_name`:

* characters other than ASCII letters, digits, ``_``, ``-`` and ``.`` become
  ``_`` (runs of them one ``_``): no path separators, no NUL or control
  characters, no spaces;
* leading and trailing ``.``, ``_`` and ``-`` are removed (no ``..``, no hidden
  files, nothing that looks like a command-line option);
* Windows device names (``CON``, ``NUL``, ``COM1``, ...) get ``_`` after them
  (``nul.txt`` becomes ``nul_.txt``);
* an empty result becomes ``default``;
* a name longer than ``max_length`` characters is cut and ends with ``-``
  and 8 hex digits of the SHA-1 of the original name, so two long names
  sharing a prefix stay different.

A name that is already safe is returned unchanged (``"C1"`` stays ``"C1"``), so
file names of ordinary projects do not change. :func:`safe_names` also makes
the names of one folder distinct (including case-insensitively, as on macOS
and Windows): a name whose safe form collides with another gets the hash
suffix.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

from photogram.errors import InputError

__all__ = ["safe_name", "safe_names", "inside", "MAX_LENGTH"]

#: longest file-name component produced (well below the 255 bytes of most file systems)
MAX_LENGTH = 100
_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]+")
_RESERVED = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(1, 10)),
             *(f"LPT{i}" for i in range(1, 10))}


def _digest(name: str) -> str:
    return hashlib.sha1(str(name).encode("utf-8", "surrogatepass")).hexdigest()[:8]


def safe_name(name, default: str = "unnamed", max_length: int = MAX_LENGTH) -> str:
    """A file-name component (no folder) made from a user-given ``name``.

    Parameters
    ----------
    name : str or object
        The name as given (converted with ``str``).
    default : str
        What an empty or all-unsafe name becomes.
    max_length : int
        The longest result (at least 16).

    Returns
    -------
    str
        Only ``[A-Za-z0-9_.-]``, not starting or ending with ``.``, ``_`` or
        ``-``, never ``.`` or ``..``, at most ``max_length`` characters
        (module doc). Safe names are returned unchanged.
    """
    text = str(name)
    s = _UNSAFE.sub("_", text).strip("._-") or default
    stem, dot, rest = s.partition(".")
    if stem.upper() in _RESERVED:                 # "nul.txt" -> "nul_.txt"
        s = stem + "_" + dot + rest
    if len(s) > max_length:
        s = s[:max(max_length - 9, 1)].rstrip("._-") + "-" + _digest(text)
    return s


def safe_names(names, default: str = "unnamed", max_length: int = MAX_LENGTH) -> list[str]:
    """:func:`safe_name` of each of ``names``, made distinct.

    Names that stay unchanged keep their form; a name whose safe form
    collides (also ignoring case) with another's gets ``-`` and 8 hex digits
    of its SHA-1, so different names never share a file.

    Raises
    ------
    ValueError
        ``names`` holds the same name twice (a caller's bug: the names of
        one folder are unique by construction).
    """
    names = [str(n) for n in names]
    if len(set(names)) != len(names):
        raise ValueError("safe_names: duplicate names")
    out = [safe_name(n, default, max_length) for n in names]
    taken = {}
    for s in out:
        taken[s.lower()] = taken.get(s.lower(), 0) + 1
    for i, (n, s) in enumerate(zip(names, out)):
        if taken[s.lower()] > 1 and s != n:
            out[i] = s[:max(max_length - 9, 1)] + "-" + _digest(n)
    # unchanged names that still collide case-insensitively (e.g. "C1" and "c1")
    seen = set()
    for i, (n, s) in enumerate(zip(names, out)):
        if s.lower() in seen:
            out[i] = s[:max(max_length - 9, 1)] + "-" + _digest(n)
        seen.add(out[i].lower())
    return out


def inside(folder, name: str, suffix: str = "", what: str = "name") -> Path:
    """``folder / (safe_name(name) + suffix)``, checked to lie in ``folder``.

    The check is a second line of defence: the safe name cannot leave the
    folder, and the resolved path (symbolic links followed) must too.

    Raises
    ------
    InputError
        The resolved path is not inside ``folder`` (e.g. a symbolic link in
        the folder pointing elsewhere).
    """
    folder = Path(folder)
    path = folder / (safe_name(name) + suffix)
    root = folder.resolve()
    if path.resolve().parent != root:
        raise InputError(f"the file for {what} {name!r} would be written outside the folder "
                         f"({path.resolve()})", file=folder,
                         hint="remove the symbolic link, or write into another folder")
    return path
