"""A light table for the report: the CSV tables of a results folder read
into numpy columns, without pandas (whose import alone cost CAMCAL's report
0.23 s CPU, more than the rest of the command's own imports).

The checks are those of :func:`photogram.project.results_read.read_results_table`
(a one-line :class:`~photogram.errors.InputError` naming the file and line):
text that is not UTF-8, a table without a header, a record with more cells
than the header, text in a number column.
"""

from __future__ import annotations

import csv
import io
from itertools import repeat
from pathlib import Path

import numpy as np

from photogram.errors import InputError

__all__ = ["Table", "read_table"]

_DAMAGED = "the file is damaged: run the command again"


class Table:
    """Named numpy columns of equal length, optionally keyed by an id column.

    Parameters
    ----------
    columns : dict of str -> array
        Number columns as float arrays, text columns as object arrays of str.
    key : str, optional
        The id column rows are looked up by (:meth:`positions`).
    """

    def __init__(self, columns: dict, key: str | None = None):
        self._cols = {str(k): np.asarray(v) for k, v in columns.items()}
        lengths = {len(v) for v in self._cols.values()}
        if len(lengths) > 1:
            raise ValueError(f"columns of unequal length: {sorted(lengths)}")
        self._n = lengths.pop() if lengths else 0
        self.key = key
        self._index = None

    # ---------------------------------------------------------------- access
    @property
    def columns(self) -> list[str]:
        return list(self._cols)

    def __len__(self) -> int:
        return self._n

    def __contains__(self, name) -> bool:
        return name in self._cols

    def __getitem__(self, name: str) -> np.ndarray:
        return self._cols[name]

    def get(self, name: str, default=None):
        return self._cols.get(name, default)

    def groups(self, name: str) -> tuple[np.ndarray, list]:
        """:func:`groups` of column ``name`` (computed once per table)."""
        cache = self.__dict__.setdefault("_groups", {})
        if name not in cache:
            cache[name] = groups(self._cols[name])
        return cache[name]

    def numbers(self, names) -> np.ndarray:
        """``(n, len(names))`` float array of the number columns ``names``."""
        if not len(names):
            return np.zeros((self._n, 0))
        return np.column_stack([self._cols[c].astype(float) for c in names])

    def with_column(self, name: str, values) -> "Table":
        cols = dict(self._cols)
        cols[name] = np.asarray(values)
        out = Table(cols, self.key)
        kept = {k: v for k, v in self.__dict__.get("_groups", {}).items() if k != name}
        if kept:                            # the groups of the other columns still hold
            out.__dict__["_groups"] = kept
        return out

    def seed_groups(self, name: str, codes, names) -> None:
        """Set what :meth:`groups` returns for column ``name`` (when the
        caller has it without hashing the column; it must be what
        :func:`groups` would compute)."""
        self.__dict__.setdefault("_groups", {})[name] = (codes, names)

    def take(self, rows) -> "Table":
        """The rows selected by a boolean mask or an integer index array."""
        return Table({k: v[rows] for k, v in self._cols.items()}, self.key)

    # ------------------------------------------------------------------ keys
    @property
    def ids(self) -> np.ndarray:
        """The key column (object array of str)."""
        return self._cols[self.key]

    def _lookup(self) -> dict:
        if self._index is None:
            ids = self.ids.tolist()
            # the first row of a duplicated id wins
            self._index = {k: i for i, k in reversed(list(enumerate(ids)))}
        return self._index

    def positions(self, ids) -> np.ndarray:
        """Row of each of ``ids`` (int array, -1 where the id is absent)."""
        index = self._lookup()
        ids = ids.tolist() if isinstance(ids, np.ndarray) else list(ids)
        return np.fromiter(map(index.get, ids, repeat(-1, len(ids))), dtype=int, count=len(ids))

    def row(self, key) -> int | None:
        """Row of one id, or None."""
        return self._lookup().get(key)

    def value(self, key, name: str, default=None):
        """The cell of row ``key`` (an id) and column ``name`` (``default``
        when either is absent)."""
        i = self.row(key)
        if i is None or name not in self._cols:
            return default
        return self._cols[name][i]


def groups(keys) -> tuple[np.ndarray, list]:
    """``(codes, names)``: the distinct values of ``keys`` (as text) in order
    of first appearance and each row's position among them (a hash per
    row, not a sort of 181,000 strings)."""
    keys = list(map(str, keys.tolist() if isinstance(keys, np.ndarray) else keys))
    index = {k: i for i, k in enumerate(dict.fromkeys(keys))}
    codes = np.fromiter(map(index.__getitem__, keys), dtype=int, count=len(keys))
    return codes, list(index)


def sorted_groups(keys) -> tuple[np.ndarray, np.ndarray]:
    """``(codes, names)`` as :func:`groups`, the names sorted (as text)."""
    codes, names = groups(keys)
    names = np.array(names, dtype=object)
    order = np.argsort(names.astype(str), kind="stable")
    rank = np.empty(len(order), dtype=int)
    rank[order] = np.arange(len(order))
    return rank[codes], names[order]


def sorted_subgroups(codes, names) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sorted_groups` of some rows of a column, from that column's
    :func:`groups` ``(codes, names)`` restricted to the rows (``codes`` of
    those rows only): the same result, without hashing the rows' text again
    (a table's groups are cached; issue 23)."""
    codes = np.asarray(codes, dtype=int)
    present = np.zeros(len(names), bool)
    present[codes] = True
    kept = np.flatnonzero(present)
    sub = np.array(names, dtype=object)[kept]
    order = np.argsort(sub.astype(str), kind="stable")
    rank = np.full(len(names), -1, dtype=int)
    rank[kept[order]] = np.arange(len(kept))
    return rank[codes], sub[order]


# ------------------------------------------------------------------ reading


def _rows(path: Path) -> tuple[list[str], list[list[str]], list[int]]:
    """Header, records and the 1-based file line of every record (blank
    lines and lines starting with ``#`` skipped, as the results tables are
    read elsewhere)."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"the file is not UTF-8 text ({exc.reason})", file=path,
                         hint=_DAMAGED) from None
    lines = text.splitlines()
    if "#" in text or not all(map(str.strip, lines)):   # a comment or a blank line
        numbers = [n for n, line in enumerate(lines, 1)
                   if line.strip() and not line.lstrip().startswith("#")]
        lines = [lines[n - 1] for n in numbers]
    else:                                   # no comment, no blank line: every line counts
        numbers = list(range(1, len(lines) + 1))
    if not lines:
        raise InputError("the table is empty (no header row)", file=path, hint=_DAMAGED)
    try:
        if '"' in text:
            records = list(csv.reader(io.StringIO("\n".join(lines))))
        else:                               # no quoted cells: a plain split
            records = [line.split(",") for line in lines]
    except csv.Error as exc:
        raise InputError(f"cannot read the table: {exc}", file=path, hint=_DAMAGED) from None
    if len(records) != len(lines):      # a quoted cell over several lines
        raise InputError("cannot read the table: a quoted cell spans lines", file=path,
                         hint=_DAMAGED)
    header = [h.strip() for h in records[0]]
    width = len(header)
    body = records[1:]
    lengths = set(map(len, body))
    if lengths and max(lengths) > width:
        for rec, number in zip(body, numbers[1:]):
            if len(rec) > width:
                raise InputError(f"cannot read the table: {len(rec)} cells, the header has "
                                 f"{width}", file=path, line=number, hint=_DAMAGED)
    if lengths - {width}:
        body = [rec + [""] * (width - len(rec)) for rec in body]
    return header, body, numbers[1:]


def _is_text(name: str, text) -> bool:
    return name in text or name.startswith("_") or name in ("note", "comment")


def _number_column(path, name, cells, numbers) -> np.ndarray:
    cells = np.array(cells, dtype=object)
    cells[cells == ""] = "nan"
    try:
        return cells.astype(float)          # float() accepts surrounding blanks
    except ValueError:
        pass
    cells = np.array([c.strip() or "nan" for c in cells], dtype=object)
    try:
        return cells.astype(float)
    except ValueError:
        for cell, line in zip(cells, numbers):
            try:
                float(cell)
            except ValueError:
                shown = cell if len(cell) <= 40 else cell[:37] + "..."
                raise InputError(f"'{shown}' in column '{name}' is not a number", file=path,
                                 line=line, hint="a results table holds numbers in this "
                                                 "column; " + _DAMAGED) from None
        raise


#: above this many bytes of tables in a results folder, pandas' C parser reads
#: them (its import, about 0.23 s CPU, is then cheaper than parsing in Python:
#: 1.7 s against 0.14 s for 181,000 residuals)
PANDAS_BYTES = 4_000_000


def read_table_pandas(path, text=(), key: str | None = None) -> Table:
    """:func:`read_table` through :func:`photogram.project.results_read.read_results_table`
    (pandas; the same checks), for large tables."""
    from photogram.project.results_read import read_results_table

    text = tuple(text)
    frame = read_results_table(path, text)
    cols = {}
    for name in frame.columns:
        values = frame[name]
        name = str(name)
        if _is_text(name, set(text)):
            cells = values.to_numpy(dtype=object).reshape(-1)
            cells[values.isna().to_numpy()] = ""
            cols[name] = cells
        else:
            cols[name] = values.to_numpy(dtype=float, na_value=np.nan)
    return Table(cols, key if key in cols else None)


def read_table(path, text=(), key: str | None = None) -> Table:
    """A CSV table of a results folder as a :class:`Table`.

    Parameters
    ----------
    path : Path
        The file.
    text : iterable of str
        Text columns (ids, kinds); every other column must hold numbers (or
        be empty: NaN), except ignored ones (``_x``, ``note``, ``comment``),
        which are kept as text.
    key : str, optional
        The id column of the table (:meth:`Table.positions`).

    Raises
    ------
    InputError
        Not UTF-8, no header, a record with more cells than the header, a
        cell of a number column that is not a number (naming its line).
    """
    path = Path(path)
    header, body, numbers = _rows(path)
    text = set(text)
    cols = {}
    columns = list(zip(*body)) if body else [()] * len(header)
    for name, cells in zip(header, columns):
        if _is_text(name, text):
            cols[name] = np.array(cells, dtype=object).reshape(-1)
        else:
            cols[name] = _number_column(path, name, cells, numbers)
    return Table(cols, key if key in cols else None)
