"""Readers of DBAT's image-point and control-point tables and camera XML."""

from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import camera_model, rescale_parameters
from photogram.io.dbat import (load_dbat_project, read_camera_xml, read_control_points,
                               read_image_points)

DBAT = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "dbat"
CAMCAL = DBAT / "camcal"
SXB = DBAT / "sxb"

CAMERA_XML = """<?xml version="1.0" encoding="UTF-8"?>
<document dbat_camera_version="1.0">
  <cameras>
    <camera>
      <id>1</id>
      <name>Test camera (C4040Z-like)</name>
      <unit>mm</unit>
      <sensor>auto,5.43764</sensor>
      <image>2272,1704</image>
      <aspect>1</aspect>
      <focal>7.5</focal>
      <model>3</model>
      <cc>0,0</cc>
      <pp>0,0</pp>
      <K>0,0,0</K>
      <P>0,0</P>
    </camera>
  </cameras>
</document>
"""


def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


# -------------------------------------------------------------- image points --

def test_image_points_default_format(tmp_path):
    p = write(tmp_path, "markpts.txt", "# Mark points\n# Format: im, id, x, y, sxy\n"
              " 1,    2, 1429.1871, 1456.4278, 0.1\n\n"
              " 1, 1001, 1813.4284, 1266.2367, 0.2  # a control point\n"
              "10,    2,  100.5,     200.25,   0.1\n")
    ip = read_image_points(p)
    assert ip.image == ["1", "1", "10"] and ip.point == ["2", "1001", "2"]
    assert np.allclose(ip.xy[0], [1429.1871, 1456.4278])
    assert np.allclose(ip.sxy, [0.1, 0.2, 0.1])
    assert list(ip.line) == [3, 5, 6]


def test_image_points_other_format_and_default_sigma(tmp_path):
    p = write(tmp_path, "m.txt", "# id, image, x, y\n317, 1, 5007.6667, 7275.6667\n"
              "333, 2, 2158.25, 1135.5\n")
    ip = read_image_points(p, "id,im,x,y", sxy=0.5)
    assert ip.image == ["1", "2"] and ip.point == ["317", "333"]
    assert np.all(ip.sxy == 0.5)
    assert np.isnan(read_image_points(p, "id,im,x,y").sxy).all()


@pytest.mark.parametrize("text,fmt,match,line", [
    ("1, 2, 3.0, abc, 0.1\n", "im,id,x,y,sxy", "y is not a number", 1),
    ("# c\n1, 2, 3.0\n", "im,id,x,y,sxy", "expected 5 columns", 2),
    ("1, 2, 3.0, 4.0, -0.1\n", "im,id,x,y,sxy", "sigma must be positive", 1),
    ("# nothing\n", "im,id,x,y,sxy", "no image points", None),
    ("1, 2, 3.0, 4.0\n", "im,x,y", "has no column 'id'", None),
])
def test_image_points_errors(tmp_path, text, fmt, match, line):
    p = write(tmp_path, "bad.txt", text)
    with pytest.raises(InputError, match=match) as e:
        read_image_points(p, fmt)
    assert e.value.file == str(p)
    assert e.value.line == line


# ------------------------------------------------------------ control points --

def test_control_points_all_layouts(tmp_path):
    p = write(tmp_path, "c.txt", "# Id,label,X,Y,Z\n1001,CP1,0,1,0\n"
              "1002,CP2,1,1,0,0.001\n317, B2.16, 999604.580, 112344.443, 139.453, "
              "0.02, 0.02, 0.04\n")
    cp = read_control_points(p)
    assert cp.ids == ["1001", "1002", "317"] and cp.labels == ["CP1", "CP2", "B2.16"]
    assert np.allclose(cp.xyz[2], [999604.580, 112344.443, 139.453])
    assert np.allclose(cp.sigma, [[0, 0, 0], [0.001] * 3, [0.02, 0.02, 0.04]])


@pytest.mark.parametrize("text,match", [
    ("1,a,0,1\n", "5, 6 or 8 columns"),
    ("1,a,0,1,2,3,4\n", "5, 6 or 8 columns"),
    ("1,a,0,x,2\n", "y is not a number"),
    ("1,a,0,1,2\n1,b,0,0,0\n", "duplicate control point 1"),
    ("1,a,0,1,2,-1\n", "must not be negative"),
])
def test_control_points_errors(tmp_path, text, match):
    with pytest.raises(InputError, match=match):
        read_control_points(write(tmp_path, "c.txt", text))


# ---------------------------------------------------------------- camera XML --

def test_camera_xml_defaults(tmp_path):
    cam, = read_camera_xml(write(tmp_path, "cam.xml", CAMERA_XML))
    h = 5.43764
    assert cam.sensor == pytest.approx((h * 2272 / 1704, h))
    assert cam.image == (2272, 1704)
    assert cam.cc == 7.5                                   # cc 0: the focal length
    assert cam.pp == pytest.approx((h * 2272 / 1704 / 2, h / 2))   # pp 0: the centre
    assert cam.pixel_size[0] == pytest.approx(h / 1704)
    assert cam.model == 3 and cam.K == (0, 0, 0)


def test_camera_xml_explicit_values_to_pixels(tmp_path):
    xml = CAMERA_XML.replace("<cc>0,0</cc>", "<cc>7.457</cc>").replace(
        "<pp>0,0</pp>", "<pp>3.61546,2.61329</pp>").replace(
        "<K>0,0,0</K>", "<K>0.00458861,-4.51351e-05,-2.05253e-06</K>").replace(
        "<P>0,0</P>", "<P>-6.12803e-05,-4.41171e-05</P>")
    xmlp = write(tmp_path, "cam.xml", xml)
    mark = write(tmp_path, "m.txt", "1,1,0,0,0.1\n2,1,1,1,0.1\n")
    project = load_dbat_project(mark, None, xmlp)
    cam = project.cameras["Test_camera_C4040Z-like"]
    p = 5.43764 / 1704
    want = rescale_parameters("brown", [7.457, 3.61546, 2.61329, 0.00458861, -4.51351e-05,
                                        -2.05253e-06, -6.12803e-05, -4.41171e-05, 0, 0], 1 / p)
    assert np.allclose(cam.values(), want, rtol=1e-12)
    assert cam.values()[0] == pytest.approx(7.457 / p)
    assert list(cam.parameters) == list(camera_model("brown").parameter_names)
    assert cam.pixel_size == pytest.approx((p, p)) and cam.image_size == (2272, 1704)


@pytest.mark.parametrize("text,match", [
    ("<document><cameras/></document>", "no <camera>"),
    ("<document><camera><image>10,10</image><sensor>1,1</sensor></camera></document>",
     "no <focal>"),
    ("<document><camera><image>10</image><focal>1</focal></camera></document>",
     "width,height"),
    ("<document><camera>", "cannot read camera XML"),
])
def test_camera_xml_errors(tmp_path, text, match):
    with pytest.raises(InputError, match=match):
        read_camera_xml(write(tmp_path, "cam.xml", text))


# ------------------------------------------------------------------- project --

def test_load_project_small(tmp_path):
    mark = write(tmp_path, "m.txt", "# im,id,x,y,sxy\n10,5,100,200,0.2\n2,5,110,210,0.1\n"
                 "2,1001,300,300,0.1\n10,7,1,2,0.1\n")
    ctrl = write(tmp_path, "c.txt", "1001,A,0,1,0\n1002,B,1,1,0,0.01\n")
    xmlp = write(tmp_path, "cam.xml", CAMERA_XML)
    p = load_dbat_project(mark, ctrl, xmlp, name="small", check_ids=["1002"])
    assert p.name == "small"
    assert p.stations.names == ["2", "10"]                 # numeric order
    assert p.points.ids == ["5", "7", "1001", "1002"]
    assert list(p.points.kind) == ["tie", "tie", "control", "check"]
    assert np.isnan(p.points.xyz[:2]).all() and np.allclose(p.points.xyz[2], [0, 1, 0])
    assert np.allclose(p.points.sigma[2:], [[0, 0, 0], [0.01] * 3])
    assert list(p.image_points.station) == [1, 0, 0, 1]
    assert list(p.image_points.point) == [0, 0, 2, 1]
    assert list(p.image_points.record) == [2, 3, 4, 5]
    assert p.units.image == "px" and p.units.length == "m"
    assert p.adjustment.sigma_image == pytest.approx(0.1)
    assert p.adjustment.datum == "control"
    assert np.isnan(p.stations.position).all() and np.isnan(p.stations.angles).all()
    cam = p.cameras[p.stations.camera[0]]
    assert cam.model == "brown"
    assert cam.parameters["x0"].value == 1136.0 and cam.parameters["y0"].value == 852.0


def test_load_project_duplicate_measurement(tmp_path):
    mark = write(tmp_path, "m.txt", "1,5,100,200,0.2\n1,5,110,210,0.1\n")
    with pytest.raises(InputError, match="measured twice") as e:
        load_dbat_project(mark, None, write(tmp_path, "cam.xml", CAMERA_XML))
    assert e.value.line == 1


# ----------------------------------------------------------------- real data --

@pytest.mark.skipif(not (CAMCAL / "markpts.txt").exists(), reason="DBAT data not available")
def test_camcal():
    p = load_dbat_project(CAMCAL / "markpts.txt", CAMCAL / "camcal-fixed.txt",
                          CAMCAL / "c4040z.xml")
    assert len(p.stations) == 21 and p.stations.names[0] == "1"
    assert len(p.image_points) == 2074
    assert len(p.points) == 100
    ctrl = p.points.kind == "control"
    assert [p.points.ids[i] for i in np.nonzero(ctrl)[0]] == ["1001", "1002", "1003", "1004"]
    assert np.array_equal(np.sort(p.points.xyz[ctrl], axis=0),
                          [[0, 0, 0], [0, 0, 0], [1, 1, 0], [1, 1, 0]])
    assert np.all(p.points.sigma[ctrl] == 0)               # fixed control
    cam = next(iter(p.cameras.values()))
    assert cam.parameters["c"].value == pytest.approx(7.5 / (5.43764 / 1704))   # 2350.3 px
    assert (cam.parameters["x0"].value, cam.parameters["y0"].value) == (1136.0, 852.0)
    assert np.all(p.image_points.sigma == 0.1)
    assert np.bincount(p.image_points.point).min() >= 2


@pytest.mark.skipif(not (SXB / "markpts.txt").exists(), reason="DBAT data not available")
def test_sxb_script_camera_and_formats():
    p = load_dbat_project(SXB / "markpts.txt", SXB / "sxb-control.txt", SXB / "sxb.xml",
                          name="sxb", image_format="id,im,x,y", sxy=0.5,
                          check_ids=["351", "410"])
    assert len(p.stations) == 5
    cam = next(iter(p.cameras.values()))
    px = 53.148 / 8858
    assert cam.pixel_size == pytest.approx((px, 77.976 / 12996))
    assert cam.parameters["c"].value == pytest.approx(123.9392 / px)
    assert cam.parameters["x0"].value == pytest.approx(26.5770 / px)
    assert cam.parameters["y0"].value == pytest.approx(38.8110 / (77.976 / 12996))
    kinds = dict(zip(p.points.ids, p.points.kind))
    assert kinds["351"] == kinds["410"] == "check" and kinds["317"] == "control"
    assert np.allclose(p.points.sigma[p.points.ids.index("317")], [0.02, 0.02, 0.04])
    assert np.all(p.image_points.sigma == 0.5)
