"""[targets] and the points table's diameter, nX nY nZ (circular targets
measured as ellipse centres): off by default, per point or by default,
split into eccentric image-point blocks, bad input as one InputError."""

import numpy as np
import pytest

from photogram.adjust.build import build_problem
from photogram.adjust.eccentric_blocks import EccentricImagePointBlock
from photogram.errors import InputError
from photogram.init.chain import approximate
from photogram.project import read_project
from photogram_cli.main import main

from project_cases import append, make_project


def _with_columns(prj, cells):
    """Add diameter, nX, nY, nZ to points.csv: ``cells`` id -> "d,nx,ny,nz"."""
    path = prj.parent / "points.csv"
    lines = path.read_text(encoding="utf-8").splitlines()
    out = []
    for line in lines:
        if line.startswith("id,"):
            out.append(line + ",diameter,nX,nY,nZ")
        elif line and not line.startswith("#"):
            out.append(line + "," + cells.get(line.split(",")[0], ",,,"))
        else:
            out.append(line)
    path.write_text("\n".join(out) + "\n", encoding="utf-8")


def _blocks(project):
    return build_problem(approximate(project)[0]).problem.blocks


def test_off_by_default(tmp_path):
    prj = read_project(make_project(tmp_path))
    assert prj.targets is None
    assert not any(isinstance(b, EccentricImagePointBlock) for b in _blocks(prj))


def test_section_defaults_apply_to_every_point(tmp_path):
    path = make_project(tmp_path)
    append(path, '\n[targets]\ndiameter = 0.02\nnormal = [0, -2, 0]\n')
    prj = read_project(path)
    assert np.allclose(prj.targets.radius, 0.01)
    assert np.allclose(prj.targets.normals, [0, -1, 0])
    blocks = _blocks(prj)
    ecc = [b for b in blocks if isinstance(b, EccentricImagePointBlock)]
    images = [b for b in blocks if b.name == "image points"]
    assert ecc and len(ecc) == len(images)          # every observation a target
    rows = np.sort(np.concatenate([b.rows for b in images]))
    assert np.array_equal(rows, np.arange(len(prj.image_points)))


def test_point_columns_and_switch(tmp_path):
    path = make_project(tmp_path)
    _with_columns(path, {"1": "0.03,0,0,1", "2": "0.05,,,", "C1": "0,,,"})
    append(path, '\n[targets]\nnormal = [0, 1, 0]\n')
    prj = read_project(path)
    r, n = prj.targets.for_points(["1", "2", "C1", "3"])
    assert np.allclose(r[:2], [0.015, 0.025]) and np.isnan(r[2:]).all()
    assert np.allclose(n[:2], [[0, 0, 1], [0, 1, 0]])
    blocks = _blocks(prj)
    eb = [b for b in blocks if isinstance(b, EccentricImagePointBlock)]
    ecc = np.concatenate([b.point[b.radius > 0] for b in eb])
    ids = np.array(prj.points.ids)[np.unique(ecc)]
    assert set(ids) == {"1", "2"}
    for b in eb:                                   # radius per observation, by point
        pid = np.array(prj.points.ids)[b.point]
        assert np.allclose(b.radius, np.select([pid == "1", pid == "2"], [0.015, 0.025], 0.0))
    images = [b for b in blocks if b.name == "image points"]
    assert sum(len(b) for b in images) == len(prj.image_points)
    replace_switch = path.read_text().replace("[targets]\n", "[targets]\neccentricity = false\n")
    path.write_text(replace_switch)
    assert not any(isinstance(b, EccentricImagePointBlock) for b in _blocks(read_project(path)))


def test_diameter_column_alone_switches_it_on(tmp_path):
    path = make_project(tmp_path)
    _with_columns(path, {"1": "0.03,0,0,1"})
    assert read_project(path).targets.for_points(["1"])[0][0] == 0.015


@pytest.mark.parametrize("cells,section,words,line", [
    ({"5": "0.03,,,"}, "", ("point 5", "without a normal", "nX nY nZ"), "5,control"),
    ({"5": "-1,0,0,1"}, "", ("point 5", "negative diameter"), "5,control"),
    ({"5": "0.03,0,1,"}, "", ("only some of nX, nY, nZ",), "5,control"),
    ({}, "\n[targets]\ndiameter = 0.02\nnormal = [0, 0, 0]\n", ("normal", "not all zero"),
     "normal = [0, 0, 0]"),
    ({}, "\n[targets]\ndiameter = 0.02\n", ("point 1", "without a normal"), "1,control"),
    ({}, "\n[targets]\ndiamter = 0.02\n", ("diamter",), "diamter"),
])
def test_bad_input(tmp_path, capsys, cells, section, words, line):
    path = make_project(tmp_path)
    if cells:
        _with_columns(path, cells)
    if section:
        append(path, section)
    with pytest.raises(InputError) as exc:
        read_project(path)
    msg = exc.value.one_line()
    assert all(w in msg for w in words), msg
    name = "points.csv" if line[0].isdigit() else "lab.prj"
    assert exc.value.file.endswith(name)
    lines = (path.parent / name).read_text().splitlines()
    assert exc.value.line == next(i for i, t in enumerate(lines, 1) if t.startswith(line))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words[0] in err[0]


def test_written_project_keeps_the_targets(tmp_path):
    from photogram.project.writer import write_project
    path = make_project(tmp_path)
    _with_columns(path, {"1": "0.03,0,0,1", "2": "0.05,0,1,0"})
    append(path, '\n[targets]\neccentricity = false\n')
    prj = read_project(path)
    (tmp_path / "copy").mkdir()
    out = write_project(prj, tmp_path / "copy" / "copy.prj")
    back = read_project(out)
    assert back.targets.eccentricity is False
    for ids in (["1", "2"], ["3"]):
        a, b = prj.targets.for_points(ids), back.targets.for_points(ids)
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])


@pytest.mark.slow
def test_calibrate_command_with_targets(tmp_path, capsys):
    """End to end through the command: exit 0, residuals in the order of
    the image points table although the observations were split into
    eccentric and plain blocks."""
    import csv
    import json
    path = make_project(tmp_path)
    _with_columns(path, {"1": "0.03,0,-1,0", "5": "0.03,0,-1,0", "C1": "0.03,0,-1,0"})
    assert main(["calibrate", "--no-report", str(path)]) == 0
    res = path.parent / "results"
    assert json.loads((res / "summary.json").read_text())["status"] == "converged"
    with open(res / "residuals.csv", encoding="utf-8") as f:
        got = [(r["station"], r["point"]) for r in csv.DictReader(f)]
    with open(path.parent / "image_points.csv", encoding="utf-8") as f:
        want = [(r["station"], r["point"])
                for r in csv.DictReader(line for line in f if not line.startswith("#"))]
    assert got == want
