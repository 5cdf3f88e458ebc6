"""CSV tables with a header row: reading with record numbers and typed
columns, writing with exact float round trip, and angle unit conversion.

Conventions of the table files (see docs/project-files.md):

* UTF-8, one record per line, the first non-comment line is the header;
* the delimiter is ``,`` (``;`` or a tab are detected from the header line);
* lines whose first non-blank character is ``#`` and blank lines are skipped;
* empty cells are unknown values (NaN) where a column allows them;
* columns whose name starts with ``_`` or ``est_`` and the columns ``note``
  and ``comment`` are ignored by the readers.

Record numbers are 1-based line numbers in the file, counting the header and
comment lines, so that they match what an editor shows.
"""

from __future__ import annotations

import csv
import difflib
import io
import math
from dataclasses import dataclass
from decimal import Decimal, localcontext
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

from photogram.errors import InputError
from photogram.project.text_input import read_text, suggest
from photogram.project.toml_writer import comment_line

__all__ = ["Table", "read_table", "csv_records", "format_table", "format_float",
           "angle_to_rad", "format_angle", "IGNORED_COLUMNS"]

IGNORED_COLUMNS = ("note", "comment")
_PI = Decimal("3.14159265358979323846264338327950288419716939937510582097494459")
_PER_RAD = {"rad": None, "deg": Decimal(180), "gon": Decimal(200)}


def _ignored(column: str) -> bool:
    return column.startswith(("_", "est_")) or column in IGNORED_COLUMNS


@dataclass
class Table:
    """A CSV table as text cells, with the line number of every record.

    Attributes
    ----------
    path : Path
        The file, as shown in messages.
    header : list of str
        Column names.
    rows : list of list of str
        Cells, stripped of surrounding blanks.
    records : numpy.ndarray
        1-based line number of each row.
    header_line : int
        Line of the header.
    """

    path: Path
    header: list[str]
    rows: list[list[str]]
    records: np.ndarray
    header_line: int

    def __len__(self) -> int:
        return len(self.rows)

    def has(self, column: str) -> bool:
        """Whether the header has ``column``."""
        return column in self.header

    def error(self, row: int | None, what: str, hint: str | None = None) -> InputError:
        """An InputError at record ``row`` (None: at the header)."""
        line = self.header_line if row is None else int(self.records[row])
        return InputError(what, file=self.path, line=line, hint=hint)

    def cells(self, column: str) -> list[str]:
        """The raw cells of ``column`` (empty strings if the column is absent)."""
        if column not in self.header:
            return [""] * len(self.rows)
        j = self.header.index(column)
        return [row[j] for row in self.rows]

    def replace_text(self, column: str, values: list[str]) -> None:
        """Replace the cells of an existing ``column``."""
        j = self.header.index(column)
        for row, value in zip(self.rows, values):
            row[j] = value

    def text(self, column: str, *, required: bool = True) -> list[str]:
        """Text cells; with ``required`` an empty cell is an error."""
        cells = self.cells(column)
        if required:
            for i, cell in enumerate(cells):
                if not cell:
                    raise self.error(i, f"empty cell in column '{column}'",
                                     hint=f"every row needs a value in column '{column}'")
        return cells

    def floats(self, column: str, *, required: bool = False) -> np.ndarray:
        """Finite numbers; empty cells are NaN unless ``required``."""
        cells = self.cells(column)
        if required:
            self.text(column)
        try:
            if "_" in "".join(cells):     # float() reads '1_0' as 10: not in a table
                raise ValueError
            values = np.array([c if c else "nan" for c in cells], dtype=str).astype(float)
        except ValueError:
            values = np.array([self._parse(i, column, c) for i, c in enumerate(cells)])
        bad = np.flatnonzero(~np.isfinite(values) &
                             np.fromiter(map(bool, cells), bool, len(cells)))
        if len(bad):
            i = int(bad[0])
            hint = "leave the cell empty for an unknown value" if not required \
                else "give a finite number"
            raise self.error(i, f"'{cells[i]}' in column '{column}' is not a finite number: "
                                f"NaN and infinity are not allowed", hint=hint)
        return values.reshape(len(cells))

    def angles(self, column: str, unit: str) -> np.ndarray:
        """Angles in ``unit`` converted to radians (exactly rounded)."""
        values = self.floats(column)
        if unit == "rad":
            return values
        cells = self.cells(column)
        return np.array([angle_to_rad(c, unit) if c else math.nan for c in cells], dtype=float)

    def _parse(self, row: int, column: str, cell: str) -> float:
        if not cell:
            return math.nan
        try:
            if "_" in cell:
                raise ValueError(cell)
            return float(cell)
        except ValueError:
            hint = "use a point as decimal separator" if "," in cell else \
                "give a number, or leave the cell empty"
            raise self.error(row, f"'{cell}' in column '{column}' is not a number",
                             hint=hint) from None


def _delimiter(header: str) -> str:
    counts = {d: header.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=lambda d: counts[d])
    return best if counts[best] else ","


def _logical_lines(text: str) -> tuple[list[str], list[int]]:
    kept = [(number, line) for number, line in enumerate(text.splitlines(), 1)
            if (stripped := line.strip()) and stripped[0] != "#"]
    return [line for _, line in kept], [number for number, _ in kept]


def read_table(path: Path, *, required: Iterable[str], optional: Iterable[str] = (),
               what: str = "table") -> Table:
    """Read a CSV table and check its header.

    Parameters
    ----------
    path : Path
        The file.
    required, optional : iterable of str
        Column names; any other column is an error unless ignored (``_x``,
        ``est_x``, ``note``, ``comment``).
    what : str
        What the table is, for messages ("stations table").

    Returns
    -------
    Table

    Raises
    ------
    InputError
        Missing/unreadable/non-UTF-8 file, no header, no rows, unknown,
        duplicate or missing columns, a record with the wrong field count.
    """
    path = Path(path)
    required, optional = list(required), list(optional)
    lines, numbers = _logical_lines(read_text(path, what))
    if not lines:
        raise InputError(f"the {what} is empty (no header row)", file=path, line=1,
                         hint=f"the first line must name the columns: {', '.join(required)}")
    delimiter = _delimiter(lines[0])
    fast = _read_unquoted(lines, numbers, delimiter)
    if fast is not None:
        header, rows, records = fast
        table = Table(path, header, [], np.zeros(0, int), numbers[0])
        _check_header(table, required, optional, what)
        for row, line in zip(rows, records):
            if len(row) != len(header):
                raise _field_count_error(path, line, len(row), len(header))
        if not rows:
            raise _no_rows_error(path, numbers[0], what)
        table.rows, table.records = rows, np.array(records, dtype=int)
        return table
    reader = csv.reader(lines, delimiter=delimiter)
    header = [h.strip() for h in next(csv_records(reader, numbers, path), [])]
    table = Table(path, header, [], np.zeros(0, int), numbers[0])
    _check_header(table, required, optional, what)
    rows, records = [], []
    for row in csv_records(reader, numbers, path):
        line = numbers[reader.line_num - 1]
        if len(row) != len(header):
            raise _field_count_error(path, line, len(row), len(header))
        rows.append([c.strip() for c in row])
        records.append(line)
    if not rows:
        raise _no_rows_error(path, numbers[0], what)
    table.rows, table.records = rows, np.array(records, dtype=int)
    return table


def _field_count_error(path: Path, line: int, n: int, n_header: int) -> InputError:
    """A record whose number of fields is not the header's."""
    return InputError(f"this record has {n} fields but the header has {n_header}",
                      file=path, line=line,
                      hint="every row needs one cell per column; empty cells are allowed")


def _no_rows_error(path: Path, line: int, what: str) -> InputError:
    """A table with a header and nothing below it."""
    return InputError(f"the {what} has a header but no rows", file=path, line=line,
                      hint="add at least one row below the header")

def _read_unquoted(lines: list[str], numbers: list[int], delimiter: str):
    """The fast path of :func:`read_table`: without a quote character every
    logical line is one record, so the records need not be read one by one
    to know their line numbers. Returns (header, rows, line numbers of the
    rows), cells stripped, or None when the text holds a quote or the csv
    module objects (the record-by-record path then finds the same records
    and reports the error at its line)."""
    if any('"' in line for line in lines):
        return None
    try:
        records = list(csv.reader(lines, delimiter=delimiter))
    except csv.Error:
        return None
    if len(records) != len(lines):
        return None
    strip = str.strip
    header = list(map(strip, records[0]))
    rows = [list(map(strip, row)) for row in records[1:]]
    return header, rows, numbers[1:]


def csv_records(reader, numbers: list[int], path: Path):
    """Iterate ``reader``, turning the csv module's errors (a cell longer than
    ``csv.field_size_limit()``, often an unclosed quote) into an InputError
    at the line where the record starts."""
    while True:
        start = numbers[min(reader.line_num, len(numbers) - 1)]
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as exc:
            limit = csv.field_size_limit()
            if "field limit" in str(exc):
                what = (f"a cell of this record is longer than {limit} characters "
                        f"({limit // 1024} KiB), more than a CSV cell may hold")
                hint = "is a quote \" not closed? Otherwise shorten the cell"
            else:
                what, hint = f"this record cannot be read as CSV: {exc}", \
                    "check the quotes of this line"
            raise InputError(what, file=path, line=start, hint=hint) from None
        yield row


def _check_header(table: Table, required: list[str], optional: list[str], what: str) -> None:
    allowed = required + optional
    unknown = [h for h in table.header if h not in allowed and not _ignored(h)]
    seen = set()
    for name in table.header:
        if name in seen:
            raise table.error(None, f"column '{name}' appears twice in the header",
                              hint="rename or remove one of them")
        seen.add(name)
        if not name:
            raise table.error(None, "the header has an empty column name",
                              hint="name every column (or remove trailing delimiters)")
    for name in required:
        if name not in seen:
            close = difflib.get_close_matches(name, unknown, n=1, cutoff=0.5)
            hint = f"required columns: {', '.join(required)}"
            raise table.error(None, f"the {what} has no column '{name}'",
                              hint=hint + (f"; is '{close[0]}' meant to be '{name}'?"
                                           if close else ""))
    if unknown:
        raise table.error(None, f"unknown column '{unknown[0]}' in the {what}",
                          hint=suggest(unknown[0], allowed, noun="columns") +
                          "; columns starting with '_' are ignored")


# --------------------------------------------------------------------------
# numbers and angles as text
# --------------------------------------------------------------------------

def format_float(value: float) -> str:
    """Shortest text that reads back to exactly ``value``; '' for NaN."""
    value = float(value)
    return "" if math.isnan(value) else repr(value)


def angle_to_rad(text: str | float, unit: str) -> float:
    """Convert an angle in ``unit`` to radians, correctly rounded.

    The conversion is done in 50-digit decimal arithmetic, so that
    :func:`format_angle` can always find a text that converts back to the
    same float.
    """
    per_rad = _PER_RAD[unit]
    if per_rad is None:
        return float(text)
    with localcontext() as ctx:
        ctx.prec = 50
        return float(Decimal(str(text).strip()) * _PI / per_rad)


def format_angle(rad: float, unit: str) -> str:
    """Text of an angle in ``unit`` that :func:`angle_to_rad` reads back to
    exactly ``rad`` (the shortest of a few candidates); '' for NaN."""
    rad = float(rad)
    if math.isnan(rad) or unit == "rad":
        return format_float(rad)
    with localcontext() as ctx:
        ctx.prec = 50
        exact = Decimal(rad) * _PER_RAD[unit] / _PI
    candidates = [repr(float(exact))] + [format(exact, f".{d}g") for d in (17, 19, 22, 26)]
    for text in candidates:
        if angle_to_rad(text, unit) == rad:
            return text
    return candidates[-1]


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, (float, np.floating)):
        return format_float(value)
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    return str(value)


def _cells(values) -> list[str]:
    """:func:`_cell` of each value; a float64/float32 array at once (its
    ``tolist`` floats are the values :func:`format_float` formats)."""
    if isinstance(values, np.ndarray) and values.ndim == 1 and \
            values.dtype in (np.float64, np.float32):
        return ["" if v != v else repr(v) for v in values.tolist()]
    return [_cell(v) for v in values]


def format_table(columns: Mapping[str, Iterable], *, comment: str | None = None) -> str:
    """CSV text of ``columns`` (name -> values); floats via repr, NaN empty.

    Values already formatted as strings are written unchanged. If a value of
    the first column starts with ``#`` every cell is quoted, so that the row is
    not read back as a comment. ``comment`` lines (split at ``\\n`` only) have
    their control characters escaped, so a user string in a comment cannot
    start a line of its own.
    """
    names = list(columns)
    data = [_cells(columns[n]) for n in names]
    n_rows = len(data[0]) if data else 0
    quote_all = any(v.startswith("#") for v in data[0]) if data else False
    buf = io.StringIO()
    if comment:                  # one "# " line per "\n"; control characters escaped
        for line in str(comment).split("\n"):
            buf.write(f"# {comment_line(line)}\n")
    writer = csv.writer(buf, lineterminator="\n",
                        quoting=csv.QUOTE_ALL if quote_all else csv.QUOTE_MINIMAL)
    writer.writerow(names)
    writer.writerows([col[i] for col in data] for i in range(n_rows))
    return buf.getvalue()
