"""Reading the user's text files and wording hints.

:func:`read_text` / :func:`decode_utf8` turn unreadable or non-UTF-8 files
into one :class:`~photogram.errors.InputError` at the line of the first bad
byte; :func:`suggest` words the "did you mean" hint of a misspelt name;
:data:`DOCS` is the format reference that hints point at.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Iterable

from photogram.errors import InputError

__all__ = ["read_text", "decode_utf8", "suggest", "DOCS"]

DOCS = "docs/project-files.md"


def read_text(path: Path, what: str = "file") -> str:
    """Read a UTF-8 text file (an optional BOM is dropped).

    Raises
    ------
    InputError
        The file is missing, a folder, unreadable or not UTF-8; for bad bytes
        the line of the first one is given.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{what} not found", file=path,
                         hint="check the path and the spelling") from None
    except IsADirectoryError:
        raise InputError(f"{what} is a folder, not a file", file=path,
                         hint="give the path of the file itself") from None
    except PermissionError:
        raise InputError(f"cannot read {what}: permission denied", file=path,
                         hint=f"photogram needs read permission on the file and execute "
                              f"(search) permission on its folder {path.parent}") from None
    except OSError as exc:
        raise InputError(f"cannot read {what}: {exc.strerror}", file=path,
                         hint="check the file permissions") from None
    return decode_utf8(data, path)


def decode_utf8(data: bytes, path: Path | str) -> str:
    """Decode ``data`` as UTF-8 or raise an InputError at the bad line."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError(
            f"the file is not UTF-8 text: byte 0x{data[exc.start]:02X} cannot be decoded",
            file=path, line=line,
            hint="save it as UTF-8, e.g. as 'CSV UTF-8' in Excel",
        ) from None
    return text.removeprefix("\ufeff")


def suggest(word: str, options: Iterable[str], *, noun: str = "allowed") -> str:
    """A hint naming the closest option (difflib) and listing all options."""
    options = [str(o) for o in options]
    lower = {o.lower(): o for o in options}
    close = [lower[word.lower()]] if word.lower() in lower else \
        difflib.get_close_matches(word, options, n=1, cutoff=0.6)
    listing = f"{noun}: {', '.join(options)}" if len(options) <= 20 else \
        f"{len(options)} {noun}, e.g. {', '.join(options[:5])}"
    return (f"did you mean '{close[0]}'? " if close else "") + listing
