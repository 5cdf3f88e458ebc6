"""One editing session of ``photogram measure --serve``: the project, its
views, the editable observation tables, the orientation, and the lock that
makes it the only editor of the project.

Everything the HTTP endpoints do is a method here (plain Python, tested
without a server): :meth:`Session.body` is the JSON of ``GET /api/project``
(the contract of docs/measure-serve.md), :meth:`Session.edit`,
:meth:`Session.undo` and :meth:`Session.save` change and write the tables.
Edits are serialised by one lock (the server runs a thread per request).
"""

from __future__ import annotations

import threading
from pathlib import Path

from photogram.errors import InputError
from photogram.serve.results import read_orientation, residual_rows
from photogram.serve.sources import ImageStore, still_views
from photogram.serve.table import BadEdit, EditableTable

__all__ = ["Session", "LINES_OID"]

LINES_OID = 1_000_000        # oids of the lines table start here


class Session:
    """An open project (module doc).

    Parameters
    ----------
    project_path : Path
        The .prj file (or its folder).
    field : Path, optional
        The target-field description (``photogram measure FIELD``): the
        detector's polarity, diameters and contrast, the eccentricity
        correction, and the images folder.
    images : Path, optional
        The folder of the photographs (default: the field's, else
        ``images/`` beside the project).
    lock : bool
        Take the project's editor lock (:meth:`close` releases it).
    run_argv : list of str, optional
        The command line that runs a photogram command (``POST /api/run``;
        given by the command-line layer); None: no run button.

    Raises
    ------
    InputError
        The project, the field or the table cannot be read, or another
        editor holds the lock (one line each).
    """

    def __init__(self, project_path, *, field=None, images=None, lock: bool = True,
                 run_argv=None):
        from photogram.project import read_project
        self.run_argv = list(run_argv) if run_argv else None
        self.project = read_project(project_path)
        self.field = None
        if field is not None:
            from photogram.measure.field import read_field
            self.field = read_field(field)
        self.messages: list[str] = list(self.project.warnings)[:20]
        self._edit_lock = threading.RLock()
        self._edits: list[EditableTable] = []    # the table of each edit, for undo
        self._filelock = None
        points, lines = self._table_paths()
        if lock:            # before reading: no other editor saves in between
            self._lock(points)
        try:
            self.points_table = EditableTable.read(points, "point")
            self.lines_table = (EditableTable.read(lines, "line", first_oid=LINES_OID)
                                if lines is not None else None)
            self.tables = [t for t in (self.points_table, self.lines_table) if t is not None]
            self.views = self._views(images)
            self.images = ImageStore(self.views)
            self.images.check_all()
            self.orientation = read_orientation(self.project)
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ setup
    def _table_paths(self) -> tuple[Path, Path | None]:
        """The points table and the lines table (or None) being edited."""
        src = self.project.sources
        if self.project.track is not None:
            from photogram.serve.video import track_tables
            return track_tables(self.project)
        path = src.get("image_points")
        if path is None:
            raise InputError("the project has no image points table ([observations] points)",
                             file=self.project.path,
                             hint="add [observations] points = \"image_points.csv\"")
        return Path(path), src.get("image_lines")

    def _lock(self, table: Path) -> None:
        import filelock
        path = table.parent / f".{table.name}.lock"     # hidden, as a results folder's lock
        lock = filelock.FileLock(str(path), thread_local=False)
        try:
            lock.acquire(timeout=0)
        except filelock.Timeout:
            raise InputError(f"another photogram measure --serve is editing "
                             f"{table} (lock {path} held)",
                             hint="stop that server first with Ctrl+C in its terminal") from None
        except OSError as exc:
            raise InputError(f"cannot create the lock file {path}: {exc.strerror}",
                             hint="check that the folder is writable") from None
        self._filelock = lock

    def __enter__(self) -> "Session":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Release the editor lock (idempotent)."""
        if self._filelock is not None:
            self._filelock.release()
            self._filelock = None

    def _views(self, images):
        self.exposures = None
        if self.project.track is not None:
            from photogram.serve.video import video_views
            views, self.exposures = video_views(self.project)
            return views
        folder = images
        if folder is None and self.field is not None and self.field.images is not None:
            folder = self.field.images
        if folder is None:
            folder = self.project.folder / "images"
        folder = Path(folder)
        if not folder.is_dir():
            self.messages.append(f"no images folder {folder} (give --images DIR)")
        st = self.project.stations
        sizes = {}
        for name, cam in zip(st.names, st.camera):
            size = self.project.cameras[cam].image_size
            if size is not None:
                sizes[name] = size
        return still_views(st.names, folder, sizes)

    # ------------------------------------------------------------------ access
    def view(self, view_id) -> object:
        """The view with this id (:class:`BadEdit` if none)."""
        for v in self.views:
            if v.id == view_id:
                return v
        raise BadEdit(f"no view {view_id!r} in this project")

    def table_of(self, oid: int) -> EditableTable:
        """The table an oid belongs to."""
        if self.lines_table is not None and int(oid) >= LINES_OID:
            return self.lines_table
        return self.points_table

    @property
    def dirty(self) -> bool:
        return any(t.dirty for t in self.tables)

    def residuals(self) -> tuple[list[dict], list[dict]]:
        """The residual rows of the last adjustment with the oids of their
        observations, and the 20 largest |w| (:func:`residual_rows`; the
        oids looked up in one dict, built in one pass over the table)."""
        oids = {(_view_id(r.cells), r.cells["point"]): r.oid for r in self.points_table.rows}
        return residual_rows(self.orientation, lambda view, point: oids.get((view, point)))

    def _labels(self) -> list[str]:
        """The point ids for the label chooser: the points table's, or the
        markers of a video project."""
        if self.project.track is not None:
            return list(self.project.track.markers)
        return list(self.project.points.ids)

    # ------------------------------------------------------------------ JSON
    def body(self) -> dict:
        """The JSON of ``GET /api/project``."""
        with self._edit_lock:
            pt, lt = self.points_table, self.lines_table
            obs = [_row_json(r, "point") for r in pt.rows]
            lines = [_row_json(r, "line") for r in lt.rows] if lt is not None else []
            residuals, worst = self.residuals()
            return {"name": self.project.name, "project": str(self.project.path),
                    "table": str(pt.path), "lines_table": str(lt.path) if lt else None,
                    "exposures": self.exposures,
                    "views": [v.json() for v in self.views],
                    "oriented": self.orientation.oriented,
                    "orientation_note": self.orientation.note,
                    "points": self._labels(),
                    "observations": obs, "lines": lines,
                    "residuals": residuals, "worst": worst,
                    "dirty": self.dirty,
                    "can_undo": any(t.can_undo for t in self.tables),
                    "messages": list(self.messages)}

    # ------------------------------------------------------------------ edits
    def edit(self, req: dict) -> dict:
        """``POST /api/edit`` (add, move, delete, relabel); returns :meth:`body`.

        Raises
        ------
        BadEdit
            Unknown op, view or oid, a duplicate label, bad numbers.
        """
        op = req.get("op")
        with self._edit_lock:
            if op == "add":
                v = self.view(req.get("view"))
                table = self.lines_table if req.get("line") is not None else self.points_table
                if table is None:
                    raise BadEdit("the project has no image lines table")
                label = req.get("line") if table is not self.points_table else req.get("point")
                table.add(v.station, label, req.get("x"), req.get("y"), req.get("sigma"),
                          manual=bool(req.get("manual")), exposure=v.exposure or "")
                self._edits.append(table)
            elif op in ("move", "delete", "relabel"):
                oid = parse_oid(req.get("oid"))
                table = self.table_of(oid)
                if op == "move":
                    table.move(oid, req.get("x"), req.get("y"), req.get("sigma"),
                               manual=bool(req.get("manual")))
                elif op == "delete":
                    table.delete(oid)
                else:
                    table.relabel(oid, req.get("point") if req.get("point") is not None
                                  else req.get("line"))
                self._edits.append(table)
            else:
                raise BadEdit(f"unknown edit op {op!r}: add, move, delete or relabel")
            return self.body()

    def undo(self) -> dict:
        """``POST /api/undo``: undo the last edit; returns :meth:`body`."""
        with self._edit_lock:
            if not self._edits:
                raise BadEdit("nothing to undo")
            self._edits.pop().undo()
            return self.body()

    def save(self) -> dict:
        """``POST /api/save``: write the edited tables (numbered backup,
        atomic); returns {"saved", "backup", "rows"} of the points table."""
        with self._edit_lock:
            out = None
            for t in self.tables:
                if t is self.points_table or t.dirty:
                    path, backup = t.save()
                    if t.changed_on_disk:
                        self.messages.append(
                            f"{path} had changed on disk since it was read (another program "
                            f"wrote it); that version is kept as {backup}")
                    if t is self.points_table:
                        out = {"saved": str(path), "backup": str(backup) if backup else None,
                               "rows": len(t.rows)}
            return out


def _row_json(row, label: str) -> dict:
    c = row.cells
    out = {"oid": row.oid, "view": _view_id(c), label: c[label],
           "x": _float(c["x"]), "y": _float(c["y"])}
    if label == "point":
        s = _float(c.get("sigma", ""))
        out["sigma"] = s
        out["manual"] = row.manual
    return out


def _view_id(cells: dict) -> str:
    e = cells.get("exposure", "")
    return f"{e}/{cells['station']}" if e else cells["station"]


def _float(text):
    try:
        v = float(text)
    except (TypeError, ValueError):
        return None
    return v if v == v else None


def parse_oid(value) -> int:
    """An oid from a request (:class:`BadEdit` if not an integer)."""
    try:
        return int(value)
    except (TypeError, ValueError):
        raise BadEdit(f"oid must be an integer, not {value!r}") from None
