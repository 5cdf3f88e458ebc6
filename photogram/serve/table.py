"""The editable observation table of ``photogram measure --serve``.

A points table (``station, point, x, y`` [, ``sigma``, ``exposure``, ...])
or a lines table (``station, line, x, y`` ...) read once, edited in memory
(add, move, delete, relabel) with an undo stack, and written back on save:

* the comment lines before the header and the order of the columns are
  kept (comment lines between the rows are not; the backup has them);
  rows that were not edited keep their cells as read (a cell holding the
  delimiter or a quote is quoted as in RFC 4180); the
  coordinates of edited rows are written with 4 decimals, as
  ``photogram measure`` writes them;
* a manual observation (kept as clicked, not refined) is flagged in the
  column ``_manual`` (appended when first needed; the project readers
  ignore columns starting with ``_``, docs/project-files.md);
* before the file is replaced, the previous version is kept as a numbered
  backup ``NAME.~N~`` with ``N`` one more than the largest existing number,
  so no backup is ever overwritten (the numbered backups of GNU ``cp
  --backup=numbered`` and Emacs' ``version-control``);
* the new file is written atomically (:mod:`photogram.project.atomic`), in
  the table's own folder only.

Every row has an ``oid`` (observation id), an integer that stays with it
for the life of the server (the page addresses observations by it).
"""

from __future__ import annotations

import copy
import glob
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from photogram.errors import InputError
from photogram.montecarlo.manifest import file_digest
from photogram.project.atomic import atomic_write_text
from photogram.project.tables import read_table

__all__ = ["Row", "EditableTable", "next_backup", "BadEdit"]

_BACKUP = re.compile(r"\.~(\d+)~$")
_ID = re.compile(r"^[^,;\t\"#\s][^,;\t\"]*$")


class BadEdit(ValueError):
    """An edit the table refuses (a duplicate label, an unknown oid): the
    message is one line for the page (HTTP 400)."""


@dataclass
class Row:
    """One observation: its cells by column name, and its flags."""

    oid: int
    cells: dict[str, str]
    manual: bool = False
    edited: bool = False


@dataclass
class EditableTable:
    """An observation table being edited (module doc).

    Attributes
    ----------
    path : Path
        The table file.
    label : str
        The label column: ``point`` or ``line``.
    comments : list of str
        The comment lines before the header (kept on save).
    header : list of str
        The columns in file order.
    delimiter : str
    rows : list of Row
    """

    path: Path
    label: str
    comments: list[str]
    header: list[str]
    delimiter: str
    rows: list[Row]
    _undo: list = field(default_factory=list)
    _next: int = 0
    dirty: bool = False
    signature: str = ""          # sha256 of the file as read or last saved
    changed_on_disk: bool = False   # the last save found another program's version

    @classmethod
    def read(cls, path, label: str = "point", first_oid: int = 0) -> "EditableTable":
        """Read ``path`` (station, LABEL, x, y required; a one-line
        :class:`InputError` when it is missing or malformed)."""
        path = Path(path)
        optional = ("sigma", "exposure", "group")
        table = read_table(path, required=("station", label, "x", "y"), optional=optional,
                           what="image points table" if label == "point" else "image lines table")
        text = path.read_text(encoding="utf-8")
        comments = []
        for line in text.splitlines():
            if line.strip() and not line.strip().startswith("#"):
                break
            comments.append(line)
        delim = next((d for d in (",", ";", "\t") if d in text.splitlines()[table.header_line - 1]),
                     ",")
        rows = []
        for i, cells in enumerate(table.rows):
            c = dict(zip(table.header, cells))
            manual = c.get("_manual", "").strip().lower() in ("1", "true", "yes")
            rows.append(Row(first_oid + i, c, manual))
        return cls(path, label, comments, list(table.header), delim, rows,
                   _next=first_oid + len(rows), signature=file_digest(path))

    # ------------------------------------------------------------------ access
    def find(self, oid: int) -> Row:
        """The row with ``oid`` (:class:`BadEdit` if none)."""
        for row in self.rows:
            if row.oid == oid:
                return row
        raise BadEdit(f"no observation {oid} in {self.path.name} (deleted or undone?)")

    def key(self, row: Row) -> tuple:
        """(exposure, station, label) of a row."""
        return (row.cells.get("exposure", ""), row.cells["station"], row.cells[self.label])

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    # ------------------------------------------------------------------ edits
    def _push(self) -> None:
        self._undo.append((copy.deepcopy(self.rows), self.dirty))
        self.dirty = True

    def undo(self) -> None:
        """Undo the last edit (:class:`BadEdit` if there is none)."""
        if not self._undo:
            raise BadEdit("nothing to undo")
        self.rows, self.dirty = self._undo.pop()

    def add(self, station: str, label: str, x: float, y: float, sigma=None, *,
            manual: bool = False, exposure: str = "") -> Row:
        """Add an observation; a label already measured in that view (and
        exposure) is refused, as is a label that cannot be a table cell."""
        check_label(label, self.label)
        if self.label != "line" and any(self.key(r) == (exposure, station, label)
                                        for r in self.rows):
            raise BadEdit(f"{self.label} {label} is already measured in {station}: "
                          f"move or delete that observation instead")
        xy = _parse_xy(x, y, sigma)
        cells = {h: "" for h in self.header}
        cells.update(station=station, **{self.label: label})
        if exposure:
            cells["exposure"] = exposure
        self._push()
        row = Row(self._next, cells, manual, edited=True)
        self._next += 1
        _set_xy(row, xy)
        self.rows.append(row)
        return row

    def move(self, oid: int, x: float, y: float, sigma=None, *, manual: bool = False) -> Row:
        """Move an observation (new centre and sigma)."""
        self.find(oid)
        xy = _parse_xy(x, y, sigma)
        self._push()
        row = self.find(oid)
        row.manual, row.edited = manual, True
        _set_xy(row, xy)
        return row

    def delete(self, oid: int) -> None:
        """Delete an observation."""
        self.find(oid)
        self._push()
        self.rows = [r for r in self.rows if r.oid != oid]

    def relabel(self, oid: int, label: str) -> Row:
        """Give an observation another label (refused if the view has it)."""
        check_label(label, self.label)
        row = self.find(oid)
        if self.label != "line":
            exp, st, _ = self.key(row)
            if any(self.key(r) == (exp, st, label) and r.oid != oid for r in self.rows):
                raise BadEdit(f"{self.label} {label} is already measured in {st}")
        self._push()
        row = self.find(oid)
        row.cells[self.label], row.edited = label, True
        return row

    # ------------------------------------------------------------------ save
    def text(self) -> str:
        """The file text of the current rows (module doc)."""
        header = list(self.header)
        if any("sigma" in r.cells and r.cells["sigma"] for r in self.rows) and \
                "sigma" not in header:
            header.append("sigma")
        if any(r.manual for r in self.rows) and "_manual" not in header:
            header.append("_manual")
        d = self.delimiter
        lines = list(self.comments) + [d.join(_quoted(h, d) for h in header)]
        for r in self.rows:
            cells = dict(r.cells)
            if "_manual" in header:
                cells["_manual"] = "1" if r.manual else ("0" if r.edited else
                                                         cells.get("_manual", "") or "0")
            lines.append(d.join(_quoted(cells.get(h, ""), d) for h in header))
        return "\n".join(lines) + "\n"

    def save(self) -> tuple[Path, Path | None]:
        """Keep the old file as ``NAME.~N~`` and write the new one
        atomically; returns (saved path, backup path or None). If another
        program wrote the file since it was read (``photogram measure``
        again), ``changed_on_disk`` is set: its version is the backup."""
        backup = None
        self.changed_on_disk = self.path.is_file() and file_digest(self.path) != self.signature
        if self.path.is_file():
            backup = next_backup(self.path)
            try:
                os.link(self.path, backup)
            except OSError:
                with open(backup, "xb") as f:
                    f.write(self.path.read_bytes())
        atomic_write_text(self.path, self.text())
        self.signature = file_digest(self.path)
        self.dirty = False
        for r in self.rows:
            r.edited = False
        return self.path, backup


def _quoted(cell: str, delimiter: str) -> str:
    """A cell as CSV text: quoted (RFC 4180) if it holds the delimiter, a
    quote or a line break."""
    if delimiter in cell or '"' in cell or "\n" in cell or "\r" in cell:
        return '"' + cell.replace('"', '""') + '"'
    return cell


def next_backup(path) -> Path:
    """``NAME.~N~`` beside ``path``, N = 1 + the largest existing N (GNU
    numbered backups; never an existing file)."""
    path = Path(path)
    largest = 0
    for p in path.parent.glob(glob.escape(path.name) + ".~*~"):
        m = _BACKUP.search(p.name)
        if m and p.name[:m.start()] == path.name:
            largest = max(largest, int(m.group(1)))
    return path.with_name(f"{path.name}.~{largest + 1}~")


def check_label(label, what: str = "point") -> None:
    """A label must be a non-empty table cell without a delimiter or quote."""
    if not isinstance(label, str) or not _ID.match(label) or len(label) > 64:
        raise BadEdit(f"{what} label {label!r} cannot be used: give a non-empty name without "
                      f"commas, semicolons, tabs or quotes (at most 64 characters)")


def _parse_xy(x, y, sigma) -> tuple:
    """(x, y, sigma or None) as floats (:class:`BadEdit` if not numbers in range)."""
    try:
        x, y = float(x), float(y)
        s = None if sigma is None else float(sigma)
    except (TypeError, ValueError):
        raise BadEdit("x, y and sigma must be numbers") from None
    if not (abs(x) < 1e6 and abs(y) < 1e6) or (s is not None and not 0 < s < 1e3):
        raise BadEdit(f"coordinates ({x}, {y}) or sigma {s} out of range")
    return x, y, s


def _set_xy(row: Row, xy: tuple) -> None:
    x, y, s = xy
    row.cells["x"], row.cells["y"] = f"{x:.4f}", f"{y:.4f}"
    if s is not None:
        row.cells["sigma"] = f"{s:.4f}"


def missing_table(path, what: str) -> InputError:
    """The one-line error of a table that does not exist."""
    return InputError(f"the {what} does not exist", file=path,
                      hint="measure first (photogram measure FIELD) or create it with the "
                           "header station,point,x,y")
