"""CSV tables, the camera schema and the project checks."""

from __future__ import annotations

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.project import camera_models, invert_opk, parameter_names, read_project
from photogram.project.camera_schema import FALLBACK_PARAMETERS
from photogram.project.tables import read_table
from photogram.project.validate import TomlSource

from project_cases import make_project, replace


def _table(tmp_path, text, **kw):
    path = tmp_path / "t.csv"
    path.write_bytes(text.encode("utf-8"))
    return read_table(path, required=("id",), optional=("x", "y"), **kw)


def test_semicolon_tab_bom_comments_and_ignored_columns(tmp_path):
    t = _table(tmp_path, "\ufeff# comment\n\nid;x;_note;est_sx\n# c\nA; 1.5 ;hi;2\n")
    assert t.header == ["id", "x", "_note", "est_sx"]
    assert t.records.tolist() == [5] and t.floats("x").tolist() == [1.5]
    t = _table(tmp_path, "id\tx\nB\t2\n")
    assert t.text("id") == ["B"]
    assert np.isnan(t.floats("y")).all()


def test_quoted_cells_and_ids_keep_their_text(tmp_path):
    t = _table(tmp_path, 'id,x\n"007",1\n"a,b",2\n')
    assert t.text("id") == ["007", "a,b"]


def test_duplicate_and_empty_column_names(tmp_path):
    with pytest.raises(InputError, match="appears twice"):
        _table(tmp_path, "id,x,x\n1,2,3\n")
    with pytest.raises(InputError, match="empty column name"):
        _table(tmp_path, "id,x,\n1,2,\n")


def test_fallback_parameter_names_match_the_geometry_table():
    assert parameter_names("brown") == ("c", "x0", "y0", "K1", "K2", "K3", "P1", "P2",
                                        "B1", "B2")
    assert parameter_names("opencv") == ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    assert set(camera_models()) >= set(FALLBACK_PARAMETERS)
    assert parameter_names("nope") is None


def test_invert_opk_is_an_involution():
    rng = np.random.default_rng(3)
    angles = rng.uniform(-1.5, 1.5, (50, 3))
    np.testing.assert_allclose(invert_opk(invert_opk(angles)), angles, atol=1e-12)
    assert np.isnan(invert_opk([np.nan, 0, 0])).all()


def test_opencv_camera(tmp_path):
    prj = make_project(tmp_path)
    replace(prj, '[cameras.K2]\nmodel = "brown"', '[cameras.K2]\nmodel = "opencv"')
    replace(prj, 'c  = { value = 1400.0, free = true, sigma = 20.0 }\n'
                 'x0 = { value = 960.0, free = true }\ny0 = { value = 540.0, free = true }\n'
                 'K1 = { value = 0.0, free = true }',
            "fx = 1400.0\nfy = 1400.0\ncx = 960.0\ncy = 540.0\nk1 = { value = 0.0, free = true }")
    cam = read_project(prj).cameras["K2"]
    assert list(cam.parameters) == list(parameter_names("opencv"))
    assert cam.free_mask().tolist() == [False] * 4 + [True] + [False] * 4


def test_camera_defaults_are_zero_and_fixed(tmp_path):
    cam = read_project(make_project(tmp_path)).cameras["K1"]
    assert cam.parameters["B2"].value == 0.0 and not cam.parameters["B2"].free


def test_line_index_finds_keys_inline_tables_and_arrays(tmp_path):
    path = tmp_path / "x.toml"
    path.write_text('[a]\nk = 1\n[cameras."K 1"]\nc = { value = 1, free = true }\n'
                    '[[c.d]]\nx = 1\n[[c.d]]\nx = 2\n')
    src = TomlSource.load(path)
    assert src.line_of(("a", "k")) == 2
    assert src.line_of(("cameras", "K 1", "c", "free")) == 4
    assert src.line_of(("c", "d", 1, "x")) == 8
    assert src.line_of(("a", "missing")) == 1


def test_warnings_for_unused_things_and_points_outside_the_image(tmp_path):
    prj = make_project(tmp_path)
    with open(prj.parent / "stations.csv", "a") as f:
        f.write("S9,K1,,,,,,\n")
    with open(prj.parent / "image_points.csv", "a") as f:
        f.write("S4,C1,-5.0,20.0,\n")
    warnings = read_project(prj).warnings
    assert any("1 station(s) have no observations: S9" in w for w in warnings)
    assert any("1 image point(s) lie outside the image format" in w for w in warnings)


def test_check_point_needs_two_rays(tmp_path):
    prj = make_project(tmp_path)
    lines = (prj.parent / "image_points.csv").read_text().splitlines()
    kept = [ln for ln in lines if ",C2," not in ln or ln.startswith("S3")]
    (prj.parent / "image_points.csv").write_text("\n".join(kept) + "\n")
    with pytest.raises(InputError, match="a check point needs at least 2 rays"):
        read_project(prj)


def test_sigma_without_value_is_an_error(tmp_path):
    prj = make_project(tmp_path)
    replace(prj.parent / "points.csv", "17,tie,,,,,,", "17,tie,,,,0.1,0.1,0.1")
    with pytest.raises(InputError, match="without its value") as info:
        read_project(prj)
    assert info.value.line == 12
