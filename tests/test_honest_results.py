"""Honest outputs (issue 16, items 2, 16, 20): sigmas of camera-to-world
angles propagated through the conversion, result files with the umask's
mode, user strings escaped in the headers of TOML, CSV and TRC files."""

from __future__ import annotations

import os
import stat
import tomllib

import numpy as np
import pytest

from photogram.project import read_project, read_results, write_results
from photogram.project.atomic import atomic_write_text
from photogram.project.results import RESULT_FILES

from project_cases import DATA


# ---------------------------------------------------------------- item 16


@pytest.fixture
def umask():
    """Set the process umask for one test, restore it afterwards."""
    old = os.umask(0o022)
    yield lambda mask: os.umask(mask)
    os.umask(old)


def _mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.mark.parametrize("mask", [0o022, 0o027, 0o002])
def test_result_files_get_the_umask_mode_not_0600(tmp_path, umask, mask):
    umask(mask)
    project = read_project(DATA / "lab" / "lab.prj")
    folder = write_results(tmp_path / "results", project, {"status": "converged"})
    for name in RESULT_FILES:
        assert _mode(folder / name) == 0o666 & ~mask, name
    # a replaced file keeps the mode its owner gave it, as after an editor's save
    os.chmod(folder / "log.txt", 0o600)
    atomic_write_text(folder / "log.txt", "again\n")
    assert _mode(folder / "log.txt") == 0o600
    assert (folder / "log.txt").read_text() == "again\n"


# ---------------------------------------------------------------- item 20

HOSTILE = 'lab\nsecond line\r\x07 "quoted" \\ \u2028end'


def test_project_name_with_line_break_is_escaped_in_cameras_toml(tmp_path):
    """A project name with line breaks and control characters stays on its
    comment line of results/cameras.toml, which reads back (TOML forbids
    control characters in comments), with the name intact."""
    project = read_project(DATA / "lab" / "lab.prj")
    project.name = HOSTILE
    folder = write_results(tmp_path / "results", project, {"status": "converged"})
    text = (folder / "cameras.toml").read_text(encoding="utf-8")
    head = text.split("\n[", 1)[0].rstrip("\n").split("\n")
    assert len(head) == 2 and all(line.startswith("# ") for line in head), head
    assert head[0].endswith(r'from "lab\nsecond line\r\u0007 \"quoted\" \\ \u2028end"')
    doc = tomllib.loads(text)
    assert doc["project"]["name"] == HOSTILE
    back = read_results(folder)                      # the command re-reads its output
    assert set(back.cameras) == set(project.cameras)
    assert back.summary["project"]["name"] == HOSTILE


def test_comment_lines_of_csv_and_toml_escape_control_characters():
    from photogram.project.tables import format_table
    from photogram.project.toml_writer import dumps
    csv = format_table({"a": [1.0]}, comment="made from \x1b[31m" + HOSTILE)
    lines = csv.split("\n")
    # one comment line per "\n" of the comment; nothing else ends a line
    assert lines[0] == r"# made from \u001B[31mlab" and lines[1].startswith("# second line")
    assert lines[2] == "a" and len(csv.splitlines()) == 4
    toml = dumps({"x": {"y": 1}}, header="a\x00b", comments={("x",): "c\rd"})
    assert toml.splitlines()[0] == r"# a\u0000b" and r"# c\u000Dd" in toml
    assert tomllib.loads(toml) == {"x": {"y": 1}}


def test_trc_header_escapes_marker_and_file_names(tmp_path):
    from photogram.io.trc import read_trc, write_trc
    t = np.arange(3) / 50.0
    xyz = np.arange(9.0).reshape(3, 3)
    names = {"head\tleft": xyz, "knee\nR": xyz + 1, "plain": xyz + 2}
    path = write_trc(tmp_path / "jump\t1.trc", t, names, rotate_to_y_up=False)
    lines = path.read_text().split("\n")
    assert lines[0].split("\t") == ["PathFileType", "4", "(X/Y/Z)", r'"jump\t1.trc"']
    header = lines[3].split("\t")
    assert header == ["Frame#", "Time", r'"head\tleft"', "", "", r'"knee\nR"', "", "",
                      "plain", "", ""]
    back = read_trc(path)
    assert list(back.markers) == [r'"head\tleft"', r'"knee\nR"', "plain"]
    np.testing.assert_array_equal(back.markers["plain"], xyz + 2)
    np.testing.assert_array_equal(back.markers[r'"knee\nR"'], xyz + 1)
