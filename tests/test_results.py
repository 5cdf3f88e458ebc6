"""The results folder: written atomically, JSON without NaN, read back, and
its cameras.toml taken by a later project with from = ...."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from photogram.errors import InputError
from photogram.project import read_project, read_results, write_results
from photogram.project.results import RESULT_FILES

from project_cases import DATA, make_project, replace

SUMMARY = {"status": "converged", "iterations": 4, "sigma0": 0.93, "redundancy": 57,
           "timings": {"total_s": 0.12}, "extra": {"nan": float("nan"), "inf": np.inf,
                                                    "arr": np.array([1.0, np.nan])}}


def _write(folder, project, **kw):
    n, m = len(project.stations), len(project.points)
    point_sigma = np.full((m, 3), 0.0004)
    point_sigma[0] = np.nan
    obs = project.image_points
    residuals = pd.DataFrame({"station": obs.station, "point": obs.point,
                              "x": obs.xy[:, 0], "y": obs.xy[:, 1],
                              "vx": np.linspace(-1, 1, len(obs)), "vy": np.nan})
    cam_sigma = {"K1": {"c": 0.41, "x0": 0.35, "K3": np.nan}, "K2": np.full(10, 0.5)}
    return write_results(folder, project, SUMMARY, camera_sigma=cam_sigma,
                         station_sigma=np.full((n, 6), 1e-4), point_sigma=point_sigma,
                         residuals=residuals, log_text="iteration 1\n", **kw)


def test_results_folder_files_and_json_without_nan(tmp_path):
    project = read_project(DATA / "lab" / "lab.prj")
    folder = _write(tmp_path / "results" / "deep", project)
    assert sorted(p.name for p in folder.iterdir()) == sorted(RESULT_FILES)
    text = (folder / "summary.json").read_text()

    def no_constants(name):
        raise AssertionError(f"JSON contains {name}")
    summary = json.loads(text, parse_constant=no_constants)
    for key in ("status", "iterations", "sigma0", "redundancy", "counts", "timings",
                "warnings", "project", "software_version"):
        assert key in summary
    assert summary["extra"] == {"nan": None, "inf": None, "arr": [1.0, None]}
    assert summary["counts"]["points_by_kind"] == {"control": 8, "check": 2, "tie": 3}
    assert summary["project"]["rotation_direction"] == "world_to_camera"


def test_read_results_parses_back(tmp_path):
    project = read_project(DATA / "lab" / "lab.prj")
    res = read_results(_write(tmp_path / "r", project))
    assert res.summary["status"] == "converged" and res.summary["sigma0"] == 0.93
    assert res.image_unit == "px"
    assert res.cameras["K1"].parameters["c"].sigma_estimated == 0.41
    assert res.cameras["K1"].parameters["K3"].sigma_estimated is None
    assert res.cameras["K2"].parameters["B2"].sigma_estimated == 0.5
    assert list(res.stations["station"]) == project.stations.names
    assert np.allclose(res.stations["omega"], np.degrees(project.stations.angles[:, 0]))
    assert np.allclose(res.stations["est_somega"], np.degrees(1e-4))
    assert res.points["id"].tolist() == project.points.ids
    assert math.isnan(res.points["est_sX"][0]) and res.points["est_sX"][1] == 0.0004
    assert res.residuals["station"].iloc[0] == "S1" and res.residuals["point"].iloc[0] == "1"
    assert len(res.residuals) == len(project.image_points)
    assert res.log == "iteration 1\n"


def test_results_tables_are_valid_input_tables(tmp_path):
    prj = make_project(tmp_path)
    folder = _write(prj.parent / "results", read_project(prj))
    for name in ("stations", "points"):
        replace(prj, f'file = "{name}.csv"', f'file = "results/{name}.csv"')
    again = read_project(prj)
    assert again.stations.names == ["S1", "S2", "S3", "S4"]
    assert (folder / "points.csv").read_text().splitlines()[0] == \
        "id,kind,X,Y,Z,sX,sY,sZ,est_sX,est_sY,est_sZ"


def test_field_takes_interior_orientation_from_lab_results(tmp_path):
    lab_prj = make_project(tmp_path, "lab")
    field_prj = make_project(tmp_path, "field")
    lab = read_project(lab_prj)
    lab.cameras["K1"].parameters["c"].value = 1421.25  # "estimated"
    _write(lab.output_folder(), lab)
    replace(field_prj, 'from = "lab_cameras.toml"\n\n[cameras.K2]',
            'from = "../lab/results/cameras.toml"\n\n[cameras.K2]')
    replace(field_prj, 'from = "lab_cameras.toml"\nfree = ["c"]',
            'from = "../lab/results/cameras.toml"\nname = "K2"\nfree = ["c", "x0"]')
    field = read_project(field_prj)
    k1, k2 = field.cameras["K1"], field.cameras["K2"]
    assert k1.parameters["c"].value == 1421.25 and not k1.free_mask().any()
    assert k1.source == "../lab/results/cameras.toml"
    assert k2.free_mask().sum() == 2
    assert k2.parameters["c"].sigma == 0.5 and k2.parameters["x0"].sigma == 0.5


def test_results_never_overwrite_project_inputs(tmp_path):
    prj = make_project(tmp_path)
    project = read_project(prj)
    before = (prj.parent / "stations.csv").read_bytes()
    with pytest.raises(InputError, match="input file"):
        write_results(prj.parent, project, SUMMARY)
    assert (prj.parent / "stations.csv").read_bytes() == before


def test_results_minimal_arguments(tmp_path):
    project = read_project(DATA / "field" / "field.prj")
    res = read_results(write_results(tmp_path / "r", project, {"status": "failed"}))
    assert res.summary["sigma0"] is None and res.summary["iterations"] is None
    assert len(res.residuals) == 0
    assert res.stations["omega"].tolist() == pytest.approx(
        pd.read_csv(DATA / "field" / "stations.csv")["omega"].tolist(), abs=1e-9)


def test_read_results_missing_folder(tmp_path):
    with pytest.raises(InputError, match="no results here"):
        read_results(tmp_path)


def test_read_results_damaged_json(tmp_path):
    project = read_project(DATA / "lab" / "lab.prj")
    folder = write_results(tmp_path / "r", project, SUMMARY)
    (folder / "summary.json").write_text('{\n  "status": ,\n}')
    with pytest.raises(InputError) as info:
        read_results(folder)
    assert info.value.line == 2 and "not valid JSON" in info.value.what
