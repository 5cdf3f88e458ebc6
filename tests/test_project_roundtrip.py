"""read_project(write_project(read_project(p))) reproduces every value."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from photogram.project import read_project, write_project
from photogram.project.tables import angle_to_rad, format_angle

from project_cases import DATA, make_project, replace


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind == "f" or b.dtype.kind == "f":
        return a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    return a.tolist() == b.tolist()


def assert_same_project(a, b, *, angle_atol=0.0):
    assert (a.name, a.units, a.rotation, a.rotation_direction) == \
        (b.name, b.units, b.rotation, b.rotation_direction)
    assert a.cameras.keys() == b.cameras.keys()
    for name in a.cameras:
        ca, cb = a.cameras[name], b.cameras[name]
        assert (ca.model, ca.parameters, ca.image_size, ca.pixel_size) == \
            (cb.model, cb.parameters, cb.image_size, cb.pixel_size)
    for attr in ("names", "camera", "position", "position_sigma", "angle_sigma"):
        assert _same(getattr(a.stations, attr), getattr(b.stations, attr)), attr
    if angle_atol:
        np.testing.assert_allclose(b.stations.angles, a.stations.angles, rtol=0, atol=angle_atol)
    else:
        assert _same(a.stations.angles, b.stations.angles)
    for attr in ("ids", "kind", "xyz", "sigma"):
        assert _same(getattr(a.points, attr), getattr(b.points, attr)), attr
    for table in ("image_points", "image_lines"):
        ta, tb = getattr(a, table), getattr(b, table)
        for attr in ("station", "xy", "sigma") + (("point",) if table == "image_points"
                                                  else ("line",)):
            assert _same(getattr(ta, attr), getattr(tb, attr)), (table, attr)
    assert a.distances == b.distances and a.verticals == b.verticals
    assert a.adjustment == b.adjustment and a.output == b.output


def test_lab_round_trip_is_exact(tmp_path):
    first = read_project(DATA / "lab" / "lab.prj")
    second = read_project(write_project(first, tmp_path / "copy.prj"))
    assert_same_project(first, second)
    third = read_project(write_project(second, tmp_path / "again.prj"))
    assert_same_project(first, third)
    assert (tmp_path / "copy.prj").read_text().count('angle_unit = "deg"') == 1


def test_field_round_trip_gon_camera_to_world(tmp_path):
    first = read_project(DATA / "field" / "field.prj")
    second = read_project(write_project(first, tmp_path / "copy.prj"))
    assert second.units.angle == "gon" and second.rotation_direction == "camera_to_world"
    # the inversion camera-to-world <-> world-to-camera uses trigonometry:
    # exact where a neighbouring float exists, else within a few 1e-16 rad
    assert_same_project(first, second, angle_atol=1e-14)
    assert second.cameras["K2"].parameters["c"].sigma == 0.44
    assert "taken from lab_cameras.toml" in (tmp_path / "copy.prj").read_text()


def test_round_trip_exact_for_awkward_values(tmp_path):
    project = read_project(DATA / "lab" / "lab.prj")
    rng = np.random.default_rng(1)
    project.units.angle = "gon"
    project.stations.angles = rng.uniform(-np.pi, np.pi, project.stations.angles.shape)
    project.stations.angle_sigma = rng.uniform(0, 1e-3, (len(project.stations), 3))
    project.stations.position = rng.normal(0, 1e3, (len(project.stations), 3)) / 3
    project.stations.position_sigma[:] = np.nan
    project.stations.position_sigma[0] = [1e-300, 0.1, 0.0]
    project.points.xyz[-1] = [math.pi, -0.0, 1e22]
    project.image_points.xy *= 1 / 3
    project.image_points.sigma[:] = 0.1 + 1 / 7
    project.cameras["K1"].parameters["K1"].value = 1.234567890123e-9
    project.points.ids[-1] = "#19"  # must not become a comment line
    second = read_project(write_project(project, tmp_path / "x.prj"))
    assert_same_project(project, second)


def test_units_survive(tmp_path):
    prj = make_project(tmp_path)
    for key, value in (("length_unit", "mm"), ("angle_unit", "rad")):
        replace(prj, f'{key} = "{"m" if key == "length_unit" else "deg"}"', f'{key} = "{value}"')
    first = read_project(prj)
    second = read_project(write_project(first, tmp_path / "copy.prj"))
    assert second.units.length == "mm" and second.units.angle == "rad"
    assert_same_project(first, second)


def test_mm_image_unit_converts_pixel_observations(tmp_path):
    prj = make_project(tmp_path)
    replace(prj, 'image_unit = "px"', 'image_unit = "mm"')
    replace(prj, 'points = "image_points.csv"', 'points = "image_points.csv"\nunit = "px"')
    mm = read_project(prj)
    px = read_project(DATA / "lab" / "lab.prj")
    np.testing.assert_allclose(mm.image_points.xy, px.image_points.xy * 0.0055, rtol=1e-15)
    finite = np.isfinite(px.image_points.sigma)
    np.testing.assert_allclose(mm.image_points.sigma[finite],
                               px.image_points.sigma[finite] * 0.0055, rtol=1e-15)
    second = read_project(write_project(mm, tmp_path / "copy.prj"))
    assert second.units.image == "mm"
    assert_same_project(mm, second)


def test_angles_are_radians_world_to_camera():
    lab = read_project(DATA / "lab" / "lab.prj")
    np.testing.assert_allclose(lab.stations.angles[0], np.radians([84.2894, -20.4625, -2.0022]),
                               rtol=0, atol=1e-15)
    field = read_project(DATA / "field" / "field.prj")
    from photogram.project.camera_schema import opk_to_matrix
    c2w = np.array([-76.26124, 0.0, 21.13956]) * np.pi / 200
    np.testing.assert_allclose(opk_to_matrix(field.stations.angles[0]),
                               opk_to_matrix(c2w).T, atol=1e-14)
    np.testing.assert_allclose(field.stations.angle_sigma[0], [0.5 * np.pi / 200] * 3,
                               rtol=1e-15)


def test_ids_are_strings_and_observations_indices():
    lab = read_project(DATA / "lab" / "lab.prj")
    assert lab.points.ids[:3] == ["1", "2", "3"]
    assert lab.image_points.station.dtype.kind == "i"
    assert lab.points.ids[lab.image_points.point[0]] == "1"
    assert lab.stations.names[lab.image_points.station[-1]] == "S4"


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=-10.0, max_value=10.0, allow_nan=False) |
       st.floats(min_value=-1e-200, max_value=1e-200, allow_nan=False),
       st.sampled_from(["deg", "gon", "rad"]))
def test_angle_text_round_trip_exact(rad, unit):
    assert angle_to_rad(format_angle(rad, unit), unit) == rad


def test_typical_angles_stay_short():
    assert format_angle(angle_to_rad("12.5", "deg"), "deg") == "12.5"
    assert format_angle(angle_to_rad("-199.99999", "gon"), "gon") == "-199.99999"


def test_written_project_points_at_its_own_tables(tmp_path):
    first = read_project(DATA / "field" / "field.prj")
    out = write_project(first, tmp_path / "f.prj")
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["f.prj", "f_image_lines.csv", "f_image_points.csv", "f_points.csv",
                     "f_stations.csv"]
    assert read_project(out).sources["stations"] == tmp_path / "f_stations.csv"


@pytest.mark.parametrize("name", ["lab", "field"])
def test_reading_does_not_modify_fixture(name):
    before = {p: p.read_bytes() for p in (DATA / name).iterdir()}
    read_project(DATA / name)
    assert before == {p: p.read_bytes() for p in (DATA / name).iterdir()}


def test_cameras_from_a_px_file_are_converted_to_mm(tmp_path):
    prj = make_project(tmp_path, "field")
    replace(prj, 'image_unit = "px"', 'image_unit = "mm"')
    replace(prj, 'lines = "image_lines.csv"', 'lines = "image_lines.csv"\nunit = "px"')
    mm = read_project(prj)
    px = read_project(DATA / "field" / "field.prj")
    for name in ("K1", "K2"):
        a, b = mm.cameras[name].parameters, px.cameras[name].parameters
        assert a["c"].value == pytest.approx(b["c"].value * 0.0055, rel=1e-15)
        assert a["K1"].sigma_estimated == pytest.approx(b["K1"].sigma_estimated / 0.0055**2)
    assert mm.cameras["K2"].parameters["c"].sigma == pytest.approx(0.44 * 0.0055)
    np.testing.assert_allclose(mm.image_lines.xy, px.image_lines.xy * 0.0055, rtol=1e-15)
    second = read_project(write_project(mm, tmp_path / "copy.prj"))
    assert_same_project(mm, second, angle_atol=1e-14)


def test_principal_point_defaults_to_the_format_centre(tmp_path):
    prj = make_project(tmp_path)
    replace(prj, "x0 = { value = 960.0, free = true }\ny0 = { value = 540.0, free = true }\n"
                 "K1 = { value = 0.0, free = true }\n\n[stations]", "\n[stations]")
    k2 = read_project(prj).cameras["K2"].parameters
    assert (k2["x0"].value, k2["y0"].value, k2["x0"].free) == (960.0, 540.0, False)
