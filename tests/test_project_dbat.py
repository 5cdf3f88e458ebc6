"""Reading DBAT projects through a .prj: DBAT tables, cameras from DBAT XML,
stations and tie points implied by the observations (docs/project-files.md,
"Reading DBAT projects")."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.io.dbat import load_dbat_project
from photogram.project import read_project, write_project

from project_cases import make_project

ROOT = Path(__file__).resolve().parents[1]
DBAT = ROOT.parent / "shared" / "data" / "dbat"

CAMERA_XML = """<?xml version="1.0" encoding="UTF-8"?>
<document dbat_camera_version="1.0">
  <cameras>
    <camera>
      <id>1</id>
      <name>Test camera</name>
      <unit>mm</unit>
      <sensor>auto,5.43764</sensor>
      <image>2272,1704</image>
      <focal>7.5</focal>
      <model>3</model>
      <K>0,0,0</K>
      <P>0,0</P>
    </camera>
  </cameras>
</document>
"""

MARKPTS = """# Format: image id, point id, x, y, sxy
1, 1001, 100.0, 200.0, 0.1
1, 1002, 900.0, 210.0, 0.1
1,   17, 500.0, 800.0, 0.2
2, 1001, 120.0, 190.0, 0.1
2, 1002, 910.0, 230.0, 0.1

2,   17, 480.0, 790.0, 0.2   # end-of-line comment
2, 1003, 300.0, 300.0, 0.1
1, 1003, 310.0, 290.0, 0.1
"""

CONTROL = """# Id,label,X,Y,Z
1001,CP1,0,1,0
1002,CP2,1,1,0
1003,CP3,0,0,0
"""

PRJ = """[project]
name = "small"

[cameras.cam]
from_dbat = "cam.xml"
free = ["c", "x0", "y0"]

[stations]
from_observations = true

[points]
file = "control.txt"
format = "dbat"
columns = "id,label,x,y,z"
check = ["1003"]

[observations]
points = { file = "markpts.txt", format = "dbat", columns = "im,id,x,y,sxy" }
"""


def small(tmp_path: Path, prj: str = PRJ, **files) -> Path:
    """A small DBAT project in tmp_path; ``files`` replace or add files."""
    texts = {"cam.xml": CAMERA_XML, "markpts.txt": MARKPTS, "control.txt": CONTROL}
    texts.update(files)
    for name, text in texts.items():
        (tmp_path / name).write_text(text, encoding="utf-8")
    path = tmp_path / "small.prj"
    path.write_text(prj, encoding="utf-8")
    return path


def error(path: Path) -> InputError:
    with pytest.raises(InputError) as info:
        read_project(path)
    message = str(info.value)
    assert "\n" not in message and message == info.value.one_line()
    return info.value


def line_of(path: Path, text: str) -> int:
    lines = path.read_text(encoding="utf-8").splitlines()
    return next(i for i, line in enumerate(lines, 1) if text in line)


# ------------------------------------------------------------------ reading --

def test_small_dbat_project(tmp_path):
    p = read_project(small(tmp_path))
    assert p.stations.names == ["1", "2"] and p.stations.camera == ["cam", "cam"]
    assert np.all(np.isnan(p.stations.position)) and np.all(np.isnan(p.stations.angles))
    assert p.points.ids == ["1001", "1002", "1003", "17"]
    assert list(p.points.kind) == ["control", "control", "check", "tie"]
    assert np.allclose(p.points.xyz[:3], [[0, 1, 0], [1, 1, 0], [0, 0, 0]])
    assert np.all(np.isnan(p.points.xyz[3])) and np.all(p.points.sigma[:3] == 0)
    obs = p.image_points
    assert len(obs) == 8
    assert [p.stations.names[s] for s in obs.station] == ["1", "1", "1", "2", "2", "2", "2",
                                                          "1"]
    assert [p.points.ids[i] for i in obs.point] == ["1001", "1002", "17", "1001", "1002",
                                                    "17", "1003", "1003"]
    assert np.allclose(obs.xy[2], [500.0, 800.0]) and np.allclose(obs.sigma[2], 0.2)
    assert list(obs.record) == [2, 3, 4, 5, 6, 8, 9, 10]
    assert p.sources["image_points"] == tmp_path / "markpts.txt"
    assert p.sources["points"] == tmp_path / "control.txt"
    cam = p.cameras["cam"]
    assert cam.model == "brown" and cam.image_size == (2272, 1704)
    assert [n for n, par in cam.parameters.items() if par.free] == ["c", "x0", "y0"]
    ps = 5.43764 / 1704
    assert cam.parameters["c"].value == pytest.approx(7.5 / ps)
    assert cam.parameters["x0"].value == pytest.approx(1136.0)
    assert cam.parameters["y0"].value == pytest.approx(852.0)
    assert p.warnings == []


def test_same_project_as_load_dbat_project(tmp_path):
    p = read_project(small(tmp_path))
    q = load_dbat_project(tmp_path / "markpts.txt", tmp_path / "control.txt",
                          tmp_path / "cam.xml", check_ids=["1003"])
    assert np.allclose(p.cameras["cam"].values(), next(iter(q.cameras.values())).values())
    assert p.stations.names == q.stations.names
    assert sorted(p.points.ids) == sorted(q.points.ids)
    key_p = {(p.stations.names[s], p.points.ids[i]): tuple(xy)
             for s, i, xy in zip(p.image_points.station, p.image_points.point, p.image_points.xy)}
    key_q = {(q.stations.names[s], q.points.ids[i]): tuple(xy)
             for s, i, xy in zip(q.image_points.station, q.image_points.point, q.image_points.xy)}
    assert key_p == key_q


def test_two_tables_with_their_own_sigma(tmp_path):
    prj = PRJ.replace(
        'points = { file = "markpts.txt", format = "dbat", columns = "im,id,x,y,sxy" }\n',
        "unit = \"px\"\n\n"
        "[[observations.points]]\nfile = \"a.txt\"\nformat = \"dbat\"\ncolumns = \"id,im,x,y\"\n"
        "sxy = 0.5\n\n"
        "[[observations.points]]\nfile = \"b.txt\"\nformat = \"dbat\"\ncolumns = \"id,im,x,y\"\n"
        "sxy = 1.0\n")
    path = small(tmp_path, prj,
                 **{"a.txt": "# id, im, x, y\n1001, 1, 100, 200\n1001, 2, 120, 190\n"
                             "1002, 1, 900, 210\n1002, 2, 910, 230\n1003, 2, 300, 300\n"
                             "1003, 1, 310, 290\n",
                    "b.txt": "# id, im, x, y\n17, 1, 500, 800\n17, 2, 480, 790\n"})
    p = read_project(path)
    assert p.stations.names == ["1", "2"]
    assert np.allclose(p.image_points.sigma, [0.5] * 6 + [1.0] * 2)
    assert p.sources["image_points"].name == "a.txt"
    assert p.sources["image_points:1"].name == "b.txt"
    assert list(p.image_points.record) == [2, 3, 4, 5, 6, 7, 2, 3]


def test_weighted_control_and_sigma_columns(tmp_path):
    prj = PRJ.replace('columns = "id,label,x,y,z"', 'columns = "id,label,x,y,z,sx,sy,sz"')
    path = small(tmp_path, prj, **{"control.txt": "1001,CP1,0,1,0,0.02,0.02,0.04\n"
                                                  "1002,CP2,1,1,0,0.02,0.02,0.04\n"
                                                  "1003,CP3,0,0,0,0.02,0.02,0.04\n"})
    p = read_project(path)
    assert np.allclose(p.points.sigma[:3], [[0.02, 0.02, 0.04]] * 3)
    assert np.all(np.isnan(p.points.sigma[3]))


def test_image_unit_mm_converts_tables_and_camera(tmp_path):
    prj = PRJ.replace('name = "small"', 'name = "small"\nimage_unit = "mm"')
    p = read_project(small(tmp_path, prj))
    ps = 5.43764 / 1704
    assert np.allclose(p.image_points.xy[0], [100.0 * ps, 200.0 * ps])
    assert np.allclose(p.image_points.sigma[0], 0.1 * ps)
    assert p.cameras["cam"].parameters["c"].value == pytest.approx(7.5)
    assert p.cameras["cam"].parameters["y0"].value == pytest.approx(5.43764 / 2)


def test_stations_table_with_dbat_observations(tmp_path):
    prj = PRJ.replace("from_observations = true", 'file = "stations.csv"')
    path = small(tmp_path, prj, **{"stations.csv": "station,camera,X0,Y0,Z0\n"
                                                   "1,cam,0,0,2\n2,cam,1,0,2\n"})
    p = read_project(path)
    assert p.stations.names == ["1", "2"] and np.allclose(p.stations.position[1], [1, 0, 2])


def test_csv_inline_table_is_the_plain_path(tmp_path):
    prj = make_project(tmp_path)
    before = read_project(prj)
    text = prj.read_text(encoding="utf-8")
    prj.write_text(text.replace('points = "image_points.csv"',
                                'points = { file = "image_points.csv", format = "csv" }'),
                   encoding="utf-8")
    after = read_project(prj)
    assert np.array_equal(before.image_points.xy, after.image_points.xy)
    assert np.array_equal(before.image_points.station, after.image_points.station)
    assert np.array_equal(before.image_points.point, after.image_points.point)
    assert np.array_equal(before.image_points.record, after.image_points.record)


def test_a_dbat_project_can_be_written_as_csv(tmp_path):
    p = read_project(small(tmp_path))
    (tmp_path / "copy").mkdir()
    out = write_project(p, tmp_path / "copy" / "copy.prj")
    q = read_project(out)
    assert q.stations.names == p.stations.names and q.points.ids == p.points.ids
    assert np.allclose(q.image_points.xy, p.image_points.xy)
    assert np.allclose(q.cameras["cam"].values(), p.cameras["cam"].values())


# ------------------------------------------------------------------- errors --

def test_unknown_format_names_prj_file_and_line(tmp_path):
    path = small(tmp_path, PRJ.replace('format = "dbat", columns = "im', 'format = "dbta", '
                                                                          'columns = "im'))
    e = error(path)
    assert e.file == str(path) and e.line == line_of(path, 'format = "dbta"')
    assert "unknown format 'dbta'" in e.what and "did you mean 'dbat'" in e.hint


def test_unknown_points_format(tmp_path):
    path = small(tmp_path, PRJ.replace('format = "dbat"\ncolumns', 'format = "DBAT"\ncolumns'))
    e = error(path)
    assert e.line == line_of(path, 'format = "DBAT"') and "unknown format" in e.what


def test_unknown_format_in_array_of_tables(tmp_path):
    prj = PRJ.replace(
        'points = { file = "markpts.txt", format = "dbat", columns = "im,id,x,y,sxy" }\n',
        '\n[[observations.points]]\nfile = "markpts.txt"\nformat = "dbat"\n\n'
        '[[observations.points]]\nfile = "markpts.txt"\nformat = "photomodeler"\n')
    path = small(tmp_path, prj)
    e = error(path)
    assert e.line == line_of(path, '"photomodeler"') and "#2" in e.what


def test_bad_row_in_a_dbat_table_names_its_line(tmp_path):
    path = small(tmp_path, **{"markpts.txt": MARKPTS.replace("910.0", "9l0.0")})
    e = error(path)
    assert e.file == str(tmp_path / "markpts.txt") and e.line == 6


def test_duplicate_across_tables_names_the_second(tmp_path):
    prj = PRJ.replace(
        'points = { file = "markpts.txt", format = "dbat", columns = "im,id,x,y,sxy" }\n',
        '\n[[observations.points]]\nfile = "markpts.txt"\nformat = "dbat"\n\n'
        '[[observations.points]]\nfile = "more.txt"\nformat = "dbat"\n')
    path = small(tmp_path, prj, **{"more.txt": "# more\n2, 18, 1.0, 2.0, 0.1\n"
                                               "2, 1002, 910.0, 230.0, 0.1\n"})
    e = error(path)
    assert e.file == str(tmp_path / "more.txt") and e.line == 3
    assert "measured twice" in e.what and "markpts.txt:6" in e.what


def test_single_ray_tie_point_in_second_table(tmp_path):
    prj = PRJ.replace(
        'points = { file = "markpts.txt", format = "dbat", columns = "im,id,x,y,sxy" }\n',
        '\n[[observations.points]]\nfile = "markpts.txt"\nformat = "dbat"\n\n'
        '[[observations.points]]\nfile = "more.txt"\nformat = "dbat"\n')
    path = small(tmp_path, prj, **{"more.txt": "# more\n\n2, 18, 1.0, 2.0, 0.1\n"})
    e = error(path)
    assert e.file == str(tmp_path / "more.txt") and e.line == 3 and "1 image" in e.what


def test_image_columns_without_ids(tmp_path):
    path = small(tmp_path, PRJ.replace('columns = "im,id,x,y,sxy"', 'columns = "im,x,y,sxy"'))
    e = error(path)
    assert e.line == line_of(path, "markpts.txt") and "has no id" in e.what


def test_sxy_twice(tmp_path):
    path = small(tmp_path, PRJ.replace('columns = "im,id,x,y,sxy" }',
                                       'columns = "im,id,x,y,sxy", sxy = 0.5 }'))
    assert "both as a column and as a key" in error(path).what


def test_dbat_keys_on_a_csv_table(tmp_path):
    path = small(tmp_path, PRJ.replace('format = "dbat", columns', 'columns'))
    e = error(path)
    assert 'only used with format = "dbat"' in e.what


def test_unsupported_control_columns(tmp_path):
    path = small(tmp_path, PRJ.replace('columns = "id,label,x,y,z"', 'columns = "id,x,y,z"'))
    e = error(path)
    assert e.line == line_of(path, 'columns = "id,x,y,z"') and "id,label,x,y,z" in e.hint


def test_control_columns_disagree_with_file(tmp_path):
    path = small(tmp_path, **{"control.txt": CONTROL.replace("1002,CP2,1,1,0",
                                                             "1002,CP2,1,1,0,0.01")})
    e = error(path)
    assert e.file == str(tmp_path / "control.txt") and e.line == 3


def test_check_point_not_in_control_file(tmp_path):
    path = small(tmp_path, PRJ.replace('check = ["1003"]', 'check = ["1030"]'))
    e = error(path)
    assert e.line == line_of(path, "check =") and "did you mean '1003'" in e.hint


def test_unknown_point_with_csv_points_table(tmp_path):
    prj = PRJ.replace('file = "control.txt"\nformat = "dbat"\ncolumns = "id,label,x,y,z"\n'
                      'check = ["1003"]', 'file = "points.csv"')
    path = small(tmp_path, prj, **{"points.csv": "id,kind,X,Y,Z\n1001,control,0,1,0\n"
                                                 "1002,control,1,1,0\n1003,check,0,0,0\n"})
    e = error(path)
    assert e.file == str(tmp_path / "markpts.txt") and e.line == 4 and "'17'" in e.what


def test_stations_need_a_camera_when_there_are_several(tmp_path):
    prj = PRJ.replace("[stations]", '[cameras.other]\nfrom_dbat = "cam.xml"\n\n[stations]')
    e = error(small(tmp_path, prj))
    assert "add camera" in e.hint


def test_stations_unknown_camera(tmp_path):
    path = small(tmp_path, PRJ.replace("from_observations = true",
                                       'from_observations = true\ncamera = "cma"'))
    e = error(path)
    assert e.line == line_of(path, 'camera = "cma"') and "did you mean 'cam'" in e.hint


def test_stations_file_and_from_observations(tmp_path):
    path = small(tmp_path, PRJ.replace("from_observations = true",
                                       'from_observations = true\nfile = "s.csv"'))
    assert "both file and from_observations" in error(path).what


def test_camera_key_without_from_observations(tmp_path):
    path = small(tmp_path, PRJ.replace("from_observations = true",
                                       'file = "s.csv"\ncamera = "cam"'))
    assert "only used with from_observations" in error(path).what


def test_typo_in_stations_key(tmp_path):
    e = error(small(tmp_path, PRJ.replace("from_observations", "from_observation")))
    assert "did you mean 'from_observations'" in e.hint


def test_dbat_camera_errors(tmp_path):
    path = small(tmp_path, PRJ.replace('free = ["c", "x0", "y0"]', 'free = ["c", "f"]'))
    e = error(path)
    assert e.line == line_of(path, "free =") and "unknown parameter 'f'" in e.what
    path = small(tmp_path, PRJ.replace('from_dbat = "cam.xml"', 'from_dbat = "nocam.xml"'))
    e = error(path)
    assert e.line == line_of(path, "from_dbat") and "not found" in e.what
    two = CAMERA_XML.replace("  </cameras>", CAMERA_XML.split("<cameras>")[1].split(
        "</cameras>")[0].replace("<id>1</id>", "<id>2</id>").replace(
        "Test camera", "Second") + "  </cameras>")
    path = small(tmp_path, **{"cam.xml": two})
    assert "holds 2 cameras" in error(path).what
    path = small(tmp_path, PRJ.replace('from_dbat = "cam.xml"',
                                       'from_dbat = "cam.xml"\ncamera = "Second"'),
                 **{"cam.xml": two})
    assert read_project(path).cameras["cam"].parameters["c"].free
    path = small(tmp_path, PRJ.replace('from_dbat = "cam.xml"',
                                       'from_dbat = "cam.xml"\nmodel = "brown"'))
    assert "unknown key 'model'" in error(path).what


# ------------------------------------------------------- the real projects --

needs_data = pytest.mark.skipif(not DBAT.is_dir(), reason=f"DBAT data not found at {DBAT}")


@needs_data
def test_camcal_prj_matches_load_dbat_project():
    p = read_project(ROOT / "projects" / "camcal" / "camcal.prj")
    q = load_dbat_project(DBAT / "camcal" / "markpts.txt", DBAT / "camcal" / "camcal-fixed.txt",
                          DBAT / "camcal" / "c4040z.xml")
    assert np.array_equal(p.cameras["C4040Z"].values(), next(iter(q.cameras.values())).values())
    assert len(p.stations) == 21 and len(p.points) == 100 and len(p.image_points) == 2074
    assert [n for n, par in p.cameras["C4040Z"].parameters.items() if par.free] == \
        ["c", "x0", "y0", "K1", "K2", "K3", "P1", "P2", "B1"]
    assert np.all(p.image_points.sigma == 0.1)


@needs_data
def test_sxb_prj_reads_both_tables_and_check_points():
    p = read_project(ROOT / "projects" / "sxb" / "sxb.prj")
    assert len(p.stations) == 5 and len(p.image_points) == 1196
    kinds = dict(zip(p.points.ids, p.points.kind))
    assert kinds["351"] == kinds["410"] == "check"
    assert sum(k == "control" for k in kinds.values()) == 14
    assert sorted(set(p.image_points.sigma)) == [0.5, 1.0]
    assert not any(par.free for par in p.cameras["aerial"].parameters.values())
