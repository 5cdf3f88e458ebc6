"""Every bad-input case fails in read_project with one InputError naming the
file, the line and a fix."""

from __future__ import annotations

import pytest

from photogram.errors import InputError
from photogram.project import read_project

from project_cases import CASES, expected_line, make_project


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_bad_input_is_one_input_error(tmp_path, case):
    prj = make_project(tmp_path, case.project)
    case.edit(prj.parent)
    with pytest.raises(InputError) as info:
        read_project(prj)
    err = info.value
    assert err.file is not None and err.file.endswith(case.file), err.one_line()
    assert err.line == expected_line(prj.parent, case), err.one_line()
    text = err.one_line()
    for word in case.words:
        assert word in text
    assert "\n" not in text
    assert err.hint, "every error says how to fix it"


def test_missing_project_file(tmp_path):
    with pytest.raises(InputError) as info:
        read_project(tmp_path / "nothing.prj")
    assert info.value.one_line().startswith(str(tmp_path / "nothing.prj") + ": project file not found")


def test_folder_with_one_prj_is_accepted(tmp_path):
    prj = make_project(tmp_path)
    assert read_project(prj.parent).name == "lab"


def test_folder_without_prj(tmp_path):
    with pytest.raises(InputError, match="without a .prj file"):
        read_project(tmp_path)


def test_comment_lines_count_in_record_numbers(tmp_path):
    prj = make_project(tmp_path)
    # image_points.csv starts with a comment line: the header is line 2
    table = (prj.parent / "image_points.csv").read_text().splitlines()
    assert table[0].startswith("#") and table[1].startswith("station")
    project = read_project(prj)
    assert project.image_points.record[0] == 3
    assert project.stations.record[0] == 3
    assert project.points.record[0] == 2
