"""The editable observation table and the session of photogram measure
--serve (photogram/serve/table.py, session.py): edits and undo, saving
with numbered backups that are never overwritten, comments and columns
kept, one-line errors for bad input (unreadable image, missing table)."""

from __future__ import annotations

import os

import pytest

from serve_fixtures import Running, lab_copy


@pytest.fixture
def lab(tmp_path):
    from photogram.serve.session import Session
    prj = lab_copy(tmp_path / "lab", oriented=False)
    with Session(prj) as s:
        yield s, prj.parent / "lab_image_points.csv"


def test_edit_undo_save_with_numbered_backups(lab):
    session, table = lab
    original = table.read_text(encoding="utf-8")
    with Running(session) as r:
        add = {"op": "add", "view": "K1a", "point": "NEW1", "x": 100.123456, "y": 50.5,
               "sigma": 0.5, "manual": True}
        status, body = r.request("POST", "/api/edit", add)
        assert status == 200 and body["dirty"] and body["can_undo"]
        new = body["observations"][-1]
        assert new == {"oid": 446, "view": "K1a", "point": "NEW1", "x": 100.1235, "y": 50.5,
                       "sigma": 0.5, "manual": True}
        status, body = r.request("POST", "/api/edit", add)       # the same label again
        assert status == 400 and "NEW1 is already measured in K1a" in body["error"]
        r.request("POST", "/api/edit", {"op": "move", "oid": 5, "x": 10, "y": 20, "sigma": 0.03})
        r.request("POST", "/api/edit", {"op": "relabel", "oid": 6, "point": "T99"})
        r.request("POST", "/api/edit", {"op": "delete", "oid": 7})
        status, body = r.request("POST", "/api/undo")            # the delete
        assert status == 200 and 7 in {o["oid"] for o in body["observations"]}
        status, body = r.request("POST", "/api/save")
        assert status == 200 and body == {"saved": str(table), "backup": str(table) + ".~1~",
                                          "rows": 447}
        assert (table.parent / "lab_image_points.csv.~1~").read_text(encoding="utf-8") == original
        saved = table.read_text(encoding="utf-8").splitlines()
        old = original.splitlines()
        # the two comment lines kept, the columns in their order (sigma and
        # _manual appended), untouched rows unchanged
        assert saved[:2] == old[:2] and saved[2] == "station,point,x,y,sigma,_manual"
        assert saved[3] == old[3] + ",,0"
        station, point = old[3 + 5].split(",")[:2]          # oid 5, moved
        assert saved[3 + 5] == f"{station},{point},10.0000,20.0000,0.0300,0"
        assert saved[3 + 6].split(",")[1] == "T99"
        assert saved[-1] == "K1a,NEW1,100.1235,50.5000,0.5000,1"
        status, body = r.request("GET", "/api/project")
        assert not body["dirty"] and body["observations"][-1]["manual"]
        # a second save: backup 2; an existing higher number is skipped, never overwritten
        (table.parent / "lab_image_points.csv.~7~").write_text("keep", encoding="utf-8")
        status, body = r.request("POST", "/api/save")
        assert body["backup"] == str(table) + ".~8~"
        assert (table.parent / "lab_image_points.csv.~7~").read_text() == "keep"
        assert (table.parent / "lab_image_points.csv.~1~").read_text(encoding="utf-8") == original
    # the saved table is a valid table of the project
    from photogram.project.tables import read_table
    t = read_table(table, required=("station", "point", "x", "y"), optional=("sigma",))
    assert len(t.rows) == 447


def test_undo_nothing_and_bad_edits(lab):
    session, table = lab
    from photogram.serve.table import BadEdit
    with pytest.raises(BadEdit, match="nothing to undo"):
        session.undo()
    with pytest.raises(BadEdit, match="no observation 9999"):
        session.edit({"op": "move", "oid": 9999, "x": 1, "y": 2})
    with pytest.raises(BadEdit, match="label 'a,b' cannot be used"):
        session.edit({"op": "add", "view": "K1a", "point": "a,b", "x": 1, "y": 2})
    with pytest.raises(BadEdit, match="x, y and sigma must be numbers"):
        session.edit({"op": "add", "view": "K1a", "point": "Q", "x": "nan?", "y": 2})
    with pytest.raises(BadEdit, match="no view 'K9z'"):
        session.edit({"op": "add", "view": "K9z", "point": "Q", "x": 1, "y": 2})
    with pytest.raises(BadEdit, match="T02 is already measured in K1a"):
        session.edit({"op": "relabel", "oid": 0, "point": "T02"})
    assert not session.dirty and not session.body()["can_undo"]    # nothing changed


def test_save_writes_atomically_only_the_table(lab, monkeypatch):
    """A failing write leaves the old table (and its backup) in place."""
    session, table = lab
    original = table.read_bytes()
    session.edit({"op": "delete", "oid": 0})
    before = set(os.listdir(table.parent))

    def refuse(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(Exception):
        session.save()
    assert table.read_bytes() == original
    assert set(os.listdir(table.parent)) - before <= {"lab_image_points.csv.~1~"}


def test_unreadable_image_is_a_view_error(tmp_path):
    from photogram.serve.session import Session
    prj = lab_copy(tmp_path / "lab", oriented=False)
    (prj.parent / "images" / "K2b.jpg").write_bytes(b"\xff\xd8 not a jpeg")
    (prj.parent / "images" / "K3c.jpg").unlink()
    s = Session(prj)
    try:
        views = {v["id"]: v for v in s.body()["views"]}
        assert views["K1a"]["ok"] and views["K1a"]["error"] is None
        assert not views["K2b"]["ok"]
        assert views["K2b"]["error"] == (f"cannot read image {prj.parent / 'images' / 'K2b.jpg'}: "
                                         f"truncated JPEG (no end-of-image marker) "
                                         f"(copy the image again)")
        assert views["K3c"]["error"].startswith("no image for station K3c in ")
        assert (views["K2b"]["width"], views["K2b"]["height"]) == (640, 480)   # from the camera
        with Running(s) as r:
            status, body = r.request("GET", f"/api/image?view=K2b&token={r.token}")
            assert status == 404 and body["error"].startswith("cannot read image")
    finally:
        s.close()


def test_bad_field_is_one_line(tmp_path):
    from photogram.errors import InputError
    from photogram.serve.session import Session
    prj = lab_copy(tmp_path / "lab", oriented=False)
    bad = prj.parent / "bad.toml"
    bad.write_text("[field\n", encoding="utf-8")
    with pytest.raises(InputError) as exc:
        Session(prj, field=bad)
    assert "bad.toml" in exc.value.one_line() and "\n" not in exc.value.one_line()
    Session(prj).close()        # the failed session left no lock behind


def test_quoted_cells_survive_a_save(tmp_path):
    """A note column with the delimiter inside quotes is written back quoted
    (the saved table reads as the original); NaN in JSON is null."""
    from photogram.serve.table import EditableTable
    path = tmp_path / "t.csv"
    path.write_text('# c\nstation,point,x,y,note\nK1a,T01,1.5,2.5,"left, top"\n'
                    'K1a,T02,3,4,"say ""hi"""\n', encoding="utf-8")
    t = EditableTable.read(path)
    t.move(1, 5, 6)
    t.save()
    again = EditableTable.read(path)
    assert [r.cells["note"] for r in again.rows] == ["left, top", 'say "hi"']
    assert again.rows[1].cells["x"] == "5.0000"
    from photogram.serve.server import _finite
    assert _finite({"a": [float("nan"), 1.0], "b": float("inf")}) == {"a": [None, 1.0], "b": None}


def test_image_cache_keeps_only_recent_images(lab, monkeypatch):
    """The store keeps decoded images up to its byte budget (a project of
    many large photographs does not fill the memory)."""
    session, _ = lab
    store = session.images
    one = 640 * 480 * 3
    assert len(store._bgr.items) == 9          # the 9 images read at the start (4 MB)
    store._bgr.budget = int(2.5 * one)
    store._bgr.items.clear()
    for v in ("K1a", "K1b", "K1c", "K2a"):
        store.bgr(v)
    assert list(store._bgr.items) == ["K1c", "K2a"]
    first = store.bgr("K1a")               # read again, the same pixels
    assert first.shape == (480, 640, 3) and list(store._bgr.items)[-1] == "K1a"


def test_save_over_a_table_changed_on_disk_keeps_that_version(lab):
    """Another program (photogram measure again) wrote the table while the
    page had it open: the save still writes, the other version is the
    backup and the page is told."""
    session, table = lab
    session.edit({"op": "delete", "oid": 0})
    other = table.read_text(encoding="utf-8").replace("K1a,T02,", "K1a,T02X,")
    table.write_text(other, encoding="utf-8")
    out = session.save()
    assert (table.parent / "lab_image_points.csv.~1~").read_text(encoding="utf-8") == other
    assert session.body()["messages"][-1] == (f"{table} had changed on disk since it was read "
                                              f"(another program wrote it); that version is "
                                              f"kept as {out['backup']}")
    session.save()                 # our own last save is not "another program"
    assert len(session.body()["messages"]) == 1
