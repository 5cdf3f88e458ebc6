"""DBAT XML scripts and PhotoModeler text exports into photogram projects."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import camera_model
from photogram.io.dbat_script import dbat_script_project
from photogram.io.formats import import_project
from photogram.io.pmexport import pmexport_project, read_pmexport
from photogram.project import read_project

from io_fixtures import SHARED

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

DBAT = SHARED / "dbat"
ROOT = Path(__file__).resolve().parents[1]


def need_dbat():
    if not DBAT.is_dir():
        pytest.skip(f"DBAT reference data not found at {DBAT}")


def observations(p):
    return sorted((p.stations.names[s], p.points.ids[q], x, y, sg) for s, q, (x, y), sg in
                  zip(p.image_points.station, p.image_points.point, p.image_points.xy,
                      p.image_points.sigma))


def points(p):
    xyz = np.nan_to_num(p.points.xyz, nan=-999.0)
    sig = np.nan_to_num(p.points.sigma, nan=-999.0)
    return sorted((i, str(k), tuple(x), tuple(s)) for i, k, x, s in
                  zip(p.points.ids, p.points.kind, xyz, sig))


@pytest.mark.parametrize("script,reference", [("camcal/camcaldemo.xml", "camcal/camcal.prj"),
                                              ("sxb/sxb.xml", "sxb/sxb.prj")])
def test_dbat_script_import_equals_the_hand_written_project(tmp_path, script, reference):
    """Importing DBAT's script gives the same project as the hand-written
    .prj that reads DBAT's tables in place (projects/camcal, projects/sxb):
    camera values and free flags, control/check/tie points with sigmas,
    every observation with its sigma, datum and sigma_image."""
    need_dbat()
    prj = import_project("dbat", DBAT / script, tmp_path / "imp")
    a, b = read_project(prj), read_project(ROOT / "projects" / reference)
    (ca,), (cb,) = a.cameras.values(), b.cameras.values()
    assert np.array_equal(ca.values(), cb.values())
    assert np.array_equal(ca.free_mask(), cb.free_mask())
    assert ca.image_size == cb.image_size and ca.pixel_size == cb.pixel_size
    assert observations(a) == observations(b)
    assert points(a) == points(b)
    assert a.adjustment.datum == b.adjustment.datum
    assert a.adjustment.sigma_image == b.adjustment.sigma_image
    assert sorted(a.stations.names) == sorted(b.stations.names)


def test_imported_sxb_adjusts_like_dbat(tmp_path):
    """The imported SXB block reproduces DBAT's sigma0 1.1786 and redundancy
    1261 (dbat-report.txt); CAMCAL's import equals projects/camcal, whose
    reproduction of DBAT is tests/test_dbat_reference.py."""
    need_dbat()
    from photogram.bundle import adjust
    prj = import_project("dbat", DBAT / "sxb" / "sxb.xml", tmp_path / "imp")
    s = adjust(read_project(prj)).summary
    assert s["status"] == "converged" and s["redundancy"] == 1261
    assert round(s["sigma0"], 4) == 1.1786


def test_dbat_script_errors(tmp_path):
    need_dbat()
    import shutil
    for f in (DBAT / "sxb").iterdir():
        shutil.copy(f, tmp_path / f.name)      # DBAT's tables beside the edited script
    text = (DBAT / "sxb" / "sxb.xml").read_text(encoding="utf-8")
    bad = tmp_path / "sxb.xml"
    bad.write_text(text.replace("</ctrl_pts>", "</ctrl_ptz>"), encoding="utf-8")
    with pytest.raises(InputError) as err:
        dbat_script_project(bad)
    assert err.value.file == str(bad) and err.value.line == text.splitlines().index(
        "    </ctrl_pts>") + 1
    bad.write_text(text.replace("measurements/markpts.txt", "measurements/nothere.txt"),
                   encoding="utf-8")
    with pytest.raises(InputError, match="nothere.txt not found") as err:
        dbat_script_project(bad)
    assert err.value.line == next(k for k, ln in enumerate(text.splitlines(), 1)
                                  if "markpts.txt" in ln)
    (tmp_path / "c.xml").write_text((DBAT / "camcal" / "c4040z.xml").read_text())
    with pytest.raises(InputError, match="not a DBAT script"):
        dbat_script_project(tmp_path / "c.xml")


# --------------------------------------------------------------------------
# PhotoModeler export (no real file in our data: written from the
# documented layout with the real CAMCAL measurements and DBAT's result)

W, H = 2272, 1704
PH = 5.43764 / H                                       # DBAT's nominal pixel (mm)
IO = {"c": 7.457, "px": 3.61546, "py": 2.61329, "K1": 0.00458861, "K2": -4.51351e-05,
      "K3": -2.05253e-06, "P1": -6.12803e-05, "P2": -4.41171e-05, "as": 0.000389598}


def write_pmexport(path: Path, n_marks: int | None = None) -> Path:
    """A PhotoModeler export of the CAMCAL network: DBAT's interior
    orientation (mm; aspect as a wider format, pw = (1 + as) ph), DBAT's
    stations (angles in degrees, written kappa phi omega), PhotoModeler's
    object points and the measured marks (px)."""
    cam = DBAT / "camcal"
    st = np.genfromtxt(cam / "dbat-camera_stations.txt", delimiter=",", comments="#",
                       usecols=range(8))
    marks = np.genfromtxt(cam / "markpts.txt", delimiter=",", comments="#")
    pts = {}
    for row in csv.reader((cam / "photomodeler-fixed-no-orient-3dpts.txt").read_text()
                          .splitlines()):
        if len(row) > 5 and row[0].strip().isdigit():
            pts[int(row[0])] = [float(v) for v in row[3:6]]
    ctrl = {1001: (0, 1, 0), 1002: (1, 1, 0), 1003: (0, 0, 0), 1004: (1, 0, 0)}
    pw = PH * (1 + IO["as"])
    xs, ys, xp = W * pw, H * PH, IO["px"] * (1 + IO["as"])     # xp in physical mm
    camera = (f"{IO['c']} {xp!r} {IO['py']} {xs!r} {ys!r} {IO['K1']} {IO['K2']} {IO['K3']} "
              f"{IO['P1']} {IO['P2']}")
    lines = ["CAMCAL as a PhotoModeler export", f"0.0001 20 {W} {H}",
             "0.0003 0.001 0.001 1 1 1 1 1 1", camera, "0 0 0 0 0 0 0 0 0 0"]
    for i, r in enumerate(st):
        om, ph, ka = (float(v) for v in np.degrees(r[5:8]))
        x, y, z = (float(v) for v in r[2:5])
        lines += [f"{i} C:\\images\\P82500{21 + i}.JPG", f"{i} {x!r} {y!r} {z!r} {ka!r} {ph!r} "
                  f"{om!r}", f"{i} 0.001 0.001 0.001 0.01 0.01 0.01", f"{i}", f"{i} {camera}",
                  f"{i} 0 0 0 0 0 0 0 0 0 0"]
    lines.append("")
    lines += [f"{k} {v[0]} {v[1]} {v[2]} 0 0 0" for k, v in ctrl.items()] + [""]
    lines += [f"{k} {v[0]} {v[1]} {v[2]} 0 0 0" for k, v in pts.items()] + [""]
    rows = marks if n_marks is None else marks[:n_marks]
    lines += [f"{int(m[0]) - 1} {int(m[1])} {float(m[2])!r} {float(m[3])!r} 0.1 0.1"
              for m in rows]                   # sigmas in px, as PhotoModeler writes them
    path.write_text("\n".join(lines) + "\n")
    return path


def test_pmexport_reproduces_the_camcal_measurements(tmp_path):
    """Read through the documented conventions (angles kappa-phi-omega in
    degrees, pp and distortion as DBAT reports them, pixel aspect from the
    format), the CAMCAL measurements are reproduced at DBAT's noise level:
    RMS 0.159 px (docs/camera-models.md, 4.4)."""
    need_dbat()
    p = pmexport_project(write_pmexport(tmp_path / "camcal.txt"))
    cam = p.cameras["pm"]
    assert p.adjustment.datum == "control" and np.isclose(p.adjustment.sigma_image, 0.1)
    assert np.isclose(cam.parameters["B1"].value, IO["as"])
    assert np.isclose(cam.parameters["c"].value * PH, IO["c"])
    ip = p.image_points
    assert len(ip) == 2074 and len(p.stations) == 21
    r = camera_model("brown").residuals(ip.xy, p.points.xyz[ip.point],
                                        p.stations.angles[ip.station],
                                        p.stations.position[ip.station], cam.values(),
                                        jacobians=False)
    rms = np.sqrt(np.mean(r ** 2))
    assert 0.15 < rms < 0.17 and np.all(np.abs(r.mean(axis=0)) < 0.02)
    prj = import_project("pmexport", tmp_path / "camcal.txt", tmp_path / "imp")
    assert len(read_project(prj).image_points) == 2074


@pytest.mark.parametrize("edit,line,words", [
    (lambda ls: ls[:3], 3, "5 lines"),
    (lambda ls: ls[:8], 8, "truncated"),
    (lambda ls: ls[:6] + [ls[6].replace(" 0.4", " x0.4", 1)] + ls[7:], 7, "not a number"),
    (lambda ls: ls[:4] + ["7.457 3.6 2.6"] + ls[5:], 5, "expected 10"),
])
def test_pmexport_malformed(tmp_path, edit, line, words):
    need_dbat()
    good = write_pmexport(tmp_path / "good.txt", n_marks=50).read_text().splitlines()
    lines = edit(good)
    if words == "expected 10":                 # the camera line is the 4th
        lines = good[:3] + ["7.457 3.6 2.6"] + good[4:]
        line = 4
    bad = tmp_path / "bad.txt"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as err:
        read_pmexport(bad)
    assert err.value.file == str(bad) and err.value.line == line and words in str(err.value)


# --------------------------------------------------------------------------
# BAL (read by the engine's photogram.io.bal)


def test_bal_import_keeps_the_cost(tmp_path):
    """The imported BAL problem has Ceres' cost at the start: photogram's
    ``bal`` camera model on the project's stations and points reproduces
    BAL's residuals (y flipped)."""
    src = SHARED / "bal" / "problem-49-7776-pre.txt.bz2"
    if not src.is_file():
        pytest.skip(f"BAL data not found at {src}")
    from photogram.io.bal import bal_residuals, read_bal
    p = read_project(import_project("bal", src, tmp_path / "bal"))
    assert (len(p.stations), len(p.points), len(p.image_points)) == (49, 7776, 31843)
    ip = p.image_points
    io = np.array([p.cameras[c].values() for c in p.stations.camera])[ip.station]
    r = camera_model("bal").residuals(ip.xy, p.points.xyz[ip.point],
                                      p.stations.angles[ip.station],
                                      p.stations.position[ip.station], io, jacobians=False)
    ref = 0.5 * np.sum(bal_residuals(read_bal(src)) ** 2)
    assert np.isclose(0.5 * np.sum(r ** 2), ref, rtol=1e-12)
