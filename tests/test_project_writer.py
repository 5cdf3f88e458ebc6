"""write_project never overwrites inputs, refuses existing files, and every
write is atomic."""

from __future__ import annotations

import os
import tomllib

import pytest

from photogram.errors import InputError
from photogram.project import atomic, read_project, write_project
from photogram.project.atomic import atomic_write_text
from photogram.project.toml_writer import Inline, dumps

from project_cases import make_project


def test_refuses_to_overwrite_existing_file(tmp_path):
    project = read_project(make_project(tmp_path))
    out = tmp_path / "copy.prj"
    write_project(project, out)
    before = out.read_bytes()
    with pytest.raises(InputError, match="file exists") as info:
        write_project(project, out)
    assert "overwrite=True" in info.value.one_line()
    assert out.read_bytes() == before
    write_project(project, out, overwrite=True)


def test_never_writes_over_its_own_input_files(tmp_path):
    prj = make_project(tmp_path)
    project = read_project(prj)
    before = {p: p.read_bytes() for p in prj.parent.iterdir()}
    with pytest.raises(InputError, match="input file"):
        write_project(project, prj, overwrite=True)
    assert before == {p: p.read_bytes() for p in prj.parent.iterdir()}


def test_never_writes_over_an_input_table(tmp_path):
    prj = make_project(tmp_path)
    project = read_project(prj)
    # a project called "image" would write image_points.csv: the input table
    project_file = prj.parent / "image.prj"
    before = (prj.parent / "image_points.csv").read_bytes()
    with pytest.raises(InputError, match="input file") as info:
        write_project(project, project_file, overwrite=True)
    assert info.value.file.endswith("image_points.csv")
    assert (prj.parent / "image_points.csv").read_bytes() == before
    assert not project_file.exists()


def test_nothing_is_written_when_one_target_exists(tmp_path):
    project = read_project(make_project(tmp_path))
    (tmp_path / "out_points.csv").write_text("keep me")
    with pytest.raises(InputError):
        write_project(project, tmp_path / "out.prj")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lab", "out_points.csv"]


def test_missing_folder(tmp_path):
    project = read_project(make_project(tmp_path))
    with pytest.raises(InputError, match="does not exist"):
        write_project(project, tmp_path / "no" / "x.prj")


def test_atomic_write_failure_midway_leaves_old_file(tmp_path, monkeypatch):
    target = tmp_path / "a.csv"
    target.write_text("old content\n")

    def half_then_fail(handle, data):
        handle.write(data[: len(data) // 2])
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(atomic, "_write_all", half_then_fail)
    with pytest.raises(OSError):
        atomic_write_text(target, "new content " * 1000)
    assert target.read_text() == "old content\n"
    assert os.listdir(tmp_path) == ["a.csv"]


def test_atomic_write_failure_leaves_no_partial_new_file(tmp_path, monkeypatch):
    def fail(*args):
        raise KeyboardInterrupt
    monkeypatch.setattr(atomic.os, "replace", fail)
    with pytest.raises(KeyboardInterrupt):
        atomic_write_text(tmp_path / "b.prj", "x = 1\n")
    assert os.listdir(tmp_path) == []


def test_write_project_failure_midway_leaves_no_project(tmp_path, monkeypatch):
    project = read_project(make_project(tmp_path))
    out = tmp_path / "out"
    out.mkdir()
    calls = []

    def fail_on_third(handle, data):
        calls.append(1)
        if len(calls) == 3:
            raise OSError(5, "I/O error")
        handle.write(data)
    monkeypatch.setattr(atomic, "_write_all", fail_on_third)
    with pytest.raises(OSError):
        write_project(project, out / "x.prj")
    names = sorted(p.name for p in out.iterdir())
    assert "x.prj" not in names and not any(n.endswith(".tmp") for n in names)


def test_atomic_write_into_missing_folder_is_input_error(tmp_path):
    with pytest.raises(InputError, match="cannot write"):
        atomic_write_text(tmp_path / "missing" / "x.txt", "x")


def test_toml_writer_round_trips_through_tomllib():
    doc = {"a": {"name": 'he said "hi"\n\ttab \\ back', "n": 3, "f": 0.1, "big": 1e300,
                 "tiny": 5e-324, "neg": -0.0, "flag": True, "list": [1, 2.5, "x"],
                 "inline": Inline(value=1.5, free=True, sigma=None)},
           "b": {"c": {"d": 1}}, "arr": [{"x": 1}, {"x": 2}],
           "weird key": {"k.e.y": "v", "é": "ü"}}
    text = dumps(doc, header="header line")
    back = tomllib.loads(text)
    assert back["a"]["name"] == doc["a"]["name"]
    assert back["a"]["inline"] == {"value": 1.5, "free": True}
    assert back["a"]["tiny"] == 5e-324 and str(back["a"]["neg"]) == "-0.0"
    assert back["arr"] == [{"x": 1}, {"x": 2}] and back["b"] == {"c": {"d": 1}}
    assert back["weird key"] == {"k.e.y": "v", "é": "ü"}
    assert text.startswith("# header line\n")
