"""The command hands its report the tables it has just written.

`photogram calibrate` and `photogram orient` write stations.csv, points.csv
and residuals.csv and then draw report.pdf from the results folder. Parsing
the 34 MB of a 181,000-observation network again (and importing pandas for
it) was about a third of that report (issue 23). The command keeps the
columns it formatted the files from (:class:`photogram.project.results.WrittenTable`)
and hands them over; :func:`table_from_written` turns them into the very
:class:`~photogram.report.table.Table` that reading the file gives, so that
`photogram report FOLDER` later builds a byte-identical report.

Why the values are the same: numbers are written by ``repr`` (the shortest
text that reads back to exactly the same float, `format_float`), integers
as decimal text, NaN as an empty cell; the report's readers parse them
correctly rounded (Python's ``float``; pandas' C parser for large tables,
which in pandas 3.1 has one converter for every precision mode), so the
float parsed is the float written. Ids are written as the strings they are.
Where that chain could break, the file is read instead: a file that is no
longer the one written (its size, inode or modification time changed), a column name with blanks, a text cell holding a
quote, a comma, a ``#`` (a comment to pandas) or a line break, a text
column of other than strings, a number column of text that is not a number
or of booleans, a column the readers keep as text although it is not an id
(``_x``, ``note``, ``comment``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from photogram.report.table import Table, _is_text

__all__ = ["table_from_written", "groups_from_index"]

#: characters that the CSV writer quotes or that a reader treats specially
_SPECIAL = frozenset('",#\n\r')
#: a decimal number as every reader parses it alike (no blanks, no "_", no "nan")
_DECIMAL = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def table_from_written(written, path: Path, text=(), key: str | None = None) -> Table | None:
    """The :class:`Table` that reading ``path`` would give, built from the
    columns it was written from; None where that cannot be guaranteed (the
    caller then reads the file).

    Parameters
    ----------
    written : WrittenTable or None
        Columns and size of the file as written
        (:func:`photogram.project.results.write_results`, ``tables=``).
    path : Path
        The file (still the one written: size ``written.nbytes``, inode and
        modification time ``written.signature``).
    text, key
        As :func:`photogram.report.table.read_table`.
    """
    if written is None or not _unchanged(path, written):
        return None
    text = set(text)
    cols = {}
    for name, values in written.columns.items():
        if not isinstance(name, str) or name != name.strip() or _SPECIAL & set(name):
            return None
        if _is_text(name, text):
            column = _text_column(values) if name in text else None
        else:
            column = _number_column(values)
        if column is None:
            return None
        cols[name] = column
    if len({len(v) for v in cols.values()}) > 1:
        return None
    table = Table(cols, key if key in cols else None)
    for name, (index, ids) in getattr(written, "codes", {}).items():
        seeded = groups_from_index(index, ids) if name in cols else None
        if seeded is not None:
            table.seed_groups(name, *seeded)
    return table


def groups_from_index(index, ids) -> tuple | None:
    """:func:`photogram.report.table.groups` of the column ``ids[index]``,
    from the integer indices (no string hashed per row): the distinct values
    in order of first appearance and each row's position among them. None
    unless the ids are distinct strings and the indices within them (then
    distinct indices are distinct texts)."""
    index = np.asarray(index)
    ids = list(ids)
    if (index.dtype.kind not in "iu" or set(map(type, ids)) - {str}
            or len(set(ids)) != len(ids)):
        return None
    if not len(index):
        return np.zeros(0, dtype=int), []
    if index.min() < 0 or index.max() >= len(ids):
        return None
    distinct, first = np.unique(index, return_index=True)
    order = distinct[np.argsort(first, kind="stable")]      # by first appearance
    rank = np.empty(len(ids), dtype=int)
    rank[order] = np.arange(len(order))
    return rank[index], [ids[i] for i in order.tolist()]


def _unchanged(path: Path, written) -> bool:
    """Whether ``path`` is still the file written: its size, and its inode
    and modification time where the writer noted them."""
    try:
        st = path.stat()
    except OSError:
        return False
    signature = getattr(written, "signature", None)
    return st.st_size == written.nbytes and (
        signature is None or (st.st_ino, st.st_mtime_ns) == tuple(signature))


def _text_column(values) -> np.ndarray | None:
    """An id column as read back (object array of str), or None."""
    cells = values.tolist() if isinstance(values, np.ndarray) else list(values)
    if set(map(type, cells)) - {str}:
        return None
    joined = "".join(cells)
    if any(c in joined for c in _SPECIAL):
        return None
    if isinstance(values, np.ndarray) and values.dtype == object and values.ndim == 1:
        return values.copy()                # the same str objects, a copy of the array
    return np.array(cells, dtype=object).reshape(-1)


def _number_column(values) -> np.ndarray | None:
    """A number column as read back (float array: written by repr, read
    correctly rounded), or None."""
    array = np.asarray(values)
    if array.dtype.kind in "fiu":
        out = array.astype(float).reshape(-1)
        return None if np.isinf(out).any() else out     # "inf": parsers differ
    if array.dtype.kind not in "OU":
        return None
    out = np.empty(array.size)
    for i, value in enumerate(array.reshape(-1).tolist()):
        out[i] = _number(value)
    return None if np.isinf(out).any() else out


def _number(value) -> float:
    """The float a reader parses from the cell written for ``value`` (NaN
    for an empty cell; inf where no exact answer is guaranteed, so that
    the column is read from the file instead)."""
    if value is None:
        return np.nan
    if isinstance(value, str):
        if value == "":
            return np.nan
        return float(value) if _DECIMAL.fullmatch(value) else np.inf
    if isinstance(value, (float, np.floating)):
        return float(value)                 # written by repr: read back exactly
    if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
        return float(str(value))
    return np.inf
