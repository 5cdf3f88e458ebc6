"""Exceptions a user can cause, each carrying where and how to fix it.

Anything raised that is *not* a :class:`PhotogramError` is a bug. The command
line turns a :class:`PhotogramError` into one line on stderr and exit code 2.
"""

from __future__ import annotations

from pathlib import Path


class PhotogramError(Exception):
    """Base class of every error the user can cause.

    Parameters
    ----------
    what : str
        What is wrong, in one sentence.
    file : str or Path, optional
        The file the problem is in.
    line : int, optional
        1-based line number in ``file`` (or record number for tables, counting
        the header as line 1, so that it matches what an editor shows).
    hint : str, optional
        How to fix it.
    """

    def __init__(self, what: str, file: str | Path | None = None,
                 line: int | None = None, hint: str | None = None):
        self.what = what
        self.file = None if file is None else str(file)
        self.line = line
        self.hint = hint
        super().__init__(self.one_line())

    def one_line(self) -> str:
        """The message as one line: ``file:line: what (hint)``."""
        where = ""
        if self.file is not None:
            where = self.file + (f":{self.line}" if self.line is not None else "") + ": "
        text = where + self.what
        if self.hint:
            text += f" ({self.hint})"
        return " ".join(text.split())


class InputError(PhotogramError):
    """A project file, table or argument is malformed or inconsistent."""


class NotBuiltError(PhotogramError):
    """A command whose engine is not built yet."""


class GeometryError(PhotogramError):
    """A configuration that admits no (unique) solution: coplanar points for a
    DLT, a zero baseline, parallel rays, a datum defect, divergence."""
