"""Reading the tables and the covariance file of a results folder back, with
every damage a one-line :class:`~photogram.errors.InputError` naming the file
(and the line): text in a number column, a record that does not parse, a
covariance.npz that holds pickled Python objects (never unpickled).
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from photogram.errors import InputError

__all__ = ["read_results_table", "read_covariance", "read_orientation_covariance"]

_DAMAGED = "the file is damaged: run the command again"


def _text_column(name: str, ids) -> bool:
    return name in ids or name.startswith("_") or name in ("note", "comment")


def _data_lines(path: Path) -> list[int]:
    """1-based file lines of the header and the rows as pandas reads them
    (blank lines and lines starting with ``#`` skipped)."""
    numbers = []
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            stripped = line.strip()
            if stripped and not stripped.startswith("#"):
                numbers.append(number)
    return numbers


def read_results_table(path, ids=(), *, text=(), keep_default_na: bool = False):
    """A CSV table of a results folder as a pandas DataFrame.

    Parameters
    ----------
    path : Path
        The file.
    ids : iterable of str
        Columns read as text (ids).
    text : iterable of str
        Further text columns; every other column must hold numbers (or be
        empty), except ignored ones (``_x``, ``note``, ``comment``).
    keep_default_na : bool
        pandas' ``keep_default_na`` (False: only empty cells are missing).

    Raises
    ------
    InputError
        Not UTF-8, a record pandas cannot parse, or a cell of a number column
        that is not a number (naming its line and column).
    """
    import pandas as pd

    path = Path(path)
    ids = tuple(ids)
    try:
        frame = pd.read_csv(path, comment="#", dtype={k: str for k in ids},
                            keep_default_na=keep_default_na, na_values=[""])
    except UnicodeDecodeError as exc:
        raise InputError(f"the file is not UTF-8 text ({exc.reason})", file=path,
                         hint=_DAMAGED) from None
    except pd.errors.EmptyDataError:
        raise InputError("the table is empty (no header row)", file=path,
                         hint=_DAMAGED) from None
    except (pd.errors.ParserError, ValueError, OverflowError) as exc:
        raise InputError(f"cannot read the table: {' '.join(str(exc).split())[:160]}",
                         file=path, hint=_DAMAGED) from None
    for column in frame.columns:
        name = str(column)
        if _text_column(name, ids) or name in text:
            continue
        values = frame[column]
        if values.dtype.kind in "biuf":
            continue
        for i, cell in enumerate(values):
            if isinstance(cell, str):
                try:
                    float(cell)
                    continue
                except ValueError:
                    pass
            elif cell is None or isinstance(cell, (int, float)):
                continue
            lines = _data_lines(path)
            line = lines[i + 1] if i + 1 < len(lines) else None
            shown = str(cell) if len(str(cell)) <= 40 else str(cell)[:37] + "..."
            raise InputError(f"'{shown}' in column '{name}' is not a number", file=path,
                             line=line, hint="a results table holds numbers in this column; "
                                             + _DAMAGED)
    return frame


def read_covariance(path) -> dict:
    """The arrays of a covariance.npz, loaded with ``allow_pickle=False``.

    Raises
    ------
    InputError
        Unreadable, not an .npz file, or holding pickled Python objects
        (which photogram never loads: a pickle can run code).
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if not hasattr(z, "files"):
                raise InputError("not a covariance file (.npz): a single array", file=path,
                                 hint=_DAMAGED)
            return {k: z[k] for k in z.files}
    except InputError:
        raise
    except ValueError as exc:
        if "pickle" in str(exc):
            raise InputError("the covariance file holds pickled Python objects, which "
                             "photogram never loads (np.load with allow_pickle=False)",
                             file=path, hint="a pickle can run code: write the file again "
                                             "with the command that made it") from None
        raise InputError(f"cannot read the covariance file: {exc}", file=path,
                         hint=_DAMAGED) from None
    except (OSError, EOFError, KeyError) as exc:
        raise InputError(f"cannot read the covariance file: {exc}", file=path,
                         hint=_DAMAGED) from None
    except zipfile.BadZipFile as exc:
        raise InputError(f"cannot read the covariance file ({type(exc).__name__}: {exc})",
                         file=path, hint=_DAMAGED) from None


def read_orientation_covariance(folder) -> tuple[list[str], np.ndarray]:
    """``(labels, matrix)`` of a results folder's covariance.npz (see
    :func:`photogram.commands.bundle.run`).

    Raises
    ------
    FileNotFoundError
        There is no covariance.npz.
    InputError
        It cannot be read (:func:`read_covariance`), or ``labels`` and
        ``matrix`` are missing or do not match (n labels, n x n finite).
    """
    path = Path(folder) / "covariance.npz"
    if not path.is_file():
        raise FileNotFoundError(2, "no covariance.npz", str(path))
    z = read_covariance(path)
    labels, matrix = z.get("labels"), z.get("matrix")
    if labels is None or matrix is None:
        raise InputError("the covariance file has no 'labels' and 'matrix'", file=path,
                         hint=_DAMAGED)
    labels = np.asarray(labels).reshape(-1)
    n = len(labels)
    if labels.dtype.kind not in "US" or matrix.shape != (n, n) or \
            matrix.dtype.kind not in "fiu" or not np.all(np.isfinite(matrix)):
        raise InputError(f"the covariance file does not hold {n} labels and a finite "
                         f"{n} x {n} matrix (matrix {matrix.shape}, {matrix.dtype})",
                         file=path, hint=_DAMAGED)
    return [str(x) for x in labels], np.asarray(matrix, dtype=float)
