"""Observation features of the reader: per-camera image sigma, variance
groups, and exposures (moving points measured at many instants)."""

import numpy as np
import pytest

from photogram.adjust.build import build_problem
from photogram.errors import InputError
from photogram.project import read_project

from photogram.init.chain import approximate
from project_cases import append, make_project, replace


def add_column(path, name, value=lambda k: ""):
    """Add a column to a CSV table (comment lines kept)."""
    lines = path.read_text().splitlines()
    out, k, seen_header = [], 0, False
    for row in lines:
        if not row or row.startswith("#"):
            out.append(row)
        elif not seen_header:
            out.append(row + "," + name)
            seen_header = True
        else:
            out.append(row + "," + value(k))
            k += 1
    path.write_text("\n".join(out) + "\n")


def test_sigma_image_per_camera_reaches_the_blocks(tmp_path):
    prj_path = make_project(tmp_path)
    replace(prj_path, "sigma_image = 0.5", "sigma_image = { K1 = 0.3, K2 = 0.7 }")
    prj, _ = approximate(read_project(prj_path))
    assert prj.adjustment.sigma_image == {"K1": 0.3, "K2": 0.7}
    built = build_problem(prj)
    sig = {}
    for b in built.problem.blocks:
        if b.name == "image points":
            default = np.isnan(prj.image_points.sigma[b.rows])    # no sigma of its own
            sig[b.group] = np.unique(b.sigma[default, 0]).tolist()
    assert sig == {"image K1": [0.3], "image K2": [0.7]}


def test_sigma_image_for_an_unknown_camera_is_one_line_error(tmp_path):
    prj_path = make_project(tmp_path)
    replace(prj_path, "sigma_image = 0.5", "sigma_image = { K1 = 0.3, K9 = 0.7 }")
    with pytest.raises(InputError, match="sigma_image names unknown camera 'K9'") as e:
        read_project(prj_path)
    assert e.value.line is not None


def test_group_column_makes_variance_groups(tmp_path):
    prj_path = make_project(tmp_path)
    add_column(prj_path.parent / "image_points.csv", "group",
               lambda k: "manual" if k % 2 else "auto")
    prj, _ = approximate(read_project(prj_path))
    built = build_problem(prj)
    groups = {b.group for b in built.problem.blocks if b.name == "image points"}
    assert groups == {"image auto", "image manual"}


def test_exposure_column_creates_moving_points(tmp_path):
    prj_path = make_project(tmp_path)
    obs = prj_path.parent / "image_points.csv"
    text = obs.read_text()
    add_column(obs, "exposure")
    rows = [r for r in text.splitlines() if r.startswith("S1,5,") or r.startswith("S2,5,")]
    assert len(rows) == 2
    append(obs, "".join(r.replace(",5,", ",H,") + ",007\n" for r in rows))
    prj = read_project(prj_path)
    i = prj.points.index()["H@007"]
    assert prj.points.kind[i] == "tie" and np.all(np.isnan(prj.points.xyz[i]))
    assert np.count_nonzero(prj.image_points.point == i) == 2


def test_moving_point_seen_once_is_rejected(tmp_path):
    prj_path = make_project(tmp_path)
    obs = prj_path.parent / "image_points.csv"
    text = obs.read_text()
    add_column(obs, "exposure")
    row = next(r for r in text.splitlines() if r.startswith("S1,5,"))
    append(obs, row.replace(",5,", ",H,") + ",007\n")
    with pytest.raises(InputError, match="H@007"):
        read_project(prj_path)
