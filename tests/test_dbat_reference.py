"""Real data: photogram against DBAT's published results and PhotoModeler's.

The data are DBAT's examples (BSD licence, ../shared/data/dbat/LICENSE.txt),
read in place through projects/camcal/*.prj and projects/sxb/sxb.prj. The
reference figures are parsed from the reports beside the data, never retyped
(except PhotoModeler's camera, which is not in the local data; see
PM_CAMERA). The tests skip when the data are absent.

Tolerances: "within x% or half a unit of the last printed digit, whichever is
larger", because a reference printed with 3 significant digits (DBAT's
deviations) is only known to +-0.5 units of its last digit.
"""

from __future__ import annotations

import csv
import json
import math
import re
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest

from photogram.bundle import adjust
from photogram.geometry import camera_model, rescale_parameters
from photogram.project import read_project, read_results
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
DBAT = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "dbat"
CAMCAL = DBAT / "camcal"
SXB = DBAT / "sxb"
PROJECTS = ROOT / "projects"

if not DBAT.is_dir():
    pytest.skip(f"DBAT reference data not found at {DBAT}", allow_module_level=True)

#: Our brown parameters -> the headings of DBAT's report (camera section).
DBAT_NAMES = {"c": "Camera Constant", "x0": "px - principal point x",
              "y0": "py - principal point y", "K1": "K1 - radial distortion 1",
              "K2": "K2 - radial distortion 2", "K3": "K3 - radial distortion 3",
              "P1": "P1 - decentering distortion 1", "P2": "P2 - decentering distortion 2",
              "B1": "as - off-unit aspect parameter"}
EO_NAMES = ("Xc", "Yc", "Zc", "Omega", "Phi", "Kappa")

#: PhotoModeler's own calibration of the C4040Z, which it held fixed in the
#: two "no-orient" runs whose reports are in the local data. The reports do
#: not list it; it is line 4 of the PhotoModeler export of the weighted run
#: in DBAT's repository (niclasborlin/dbat, code/demo/data/weighted/camcal/
#: weighted-bundle-1mm/c4040z-1mm-pmexport.txt): focal, px, py, format width
#: and height (mm), K1, K2, K3, P1, P2. PhotoModeler's signs are those of
#: DBAT's report (DBAT's prob2dbatstruct flips py, K and P between
#: PhotoModeler and its internal model, and its report flips them back).
PM_CAMERA = "7.4693  3.6178  2.6087 7.25320 5.43990 4.981e-3 -9.814e-5 0 -6.587e-5 -2.806e-5"


# --------------------------------------------------------------------------
# the reference files
# --------------------------------------------------------------------------

def printed(text: str) -> tuple[float, float]:
    """A printed number and half a unit of its last digit."""
    d = Decimal(text)
    return float(d), 0.5 * 10.0 ** d.as_tuple().exponent


def close(ours: float, text: str, rel: float) -> bool:
    ref, half = printed(text)
    return abs(ours - ref) <= max(rel * abs(ref), half)


def dbat_report(path: Path) -> dict:
    """The figures of a DBAT report: 'sigma0', 'redundancy', the camera
    section ({heading: {'value': text, 'deviation': text}}), the photos
    ({photo number: {heading: ...}}) and the check-point differences."""
    text = path.read_text(encoding="utf-8")
    out = {"sigma0": re.search(r"^\s*Sigma0:\s+(\S+)", text, re.M).group(1),
           "redundancy": int(re.search(r"^\s*Redundancy\s+(\d+)", text, re.M).group(1)),
           "camera": {}, "photos": {}, "check": {},
           "rms": re.search(r"Overall point RMS:\s+(\S+) pixels", text).group(1),
           "max_residual": re.search(r"Mark point residuals:\s*\n\s*Maximum:\s+(\S+) pixels",
                                     text).group(1)}
    photo, heading = None, None
    for line in text.splitlines():
        s = line.strip()
        if m := re.match(r"Photo (\d+):", s):
            photo = int(m.group(1))
        elif m := re.match(r"(Value|Deviation):\s+(\S+)", s):
            where = out["photos"].setdefault(photo, {}) if photo else out["camera"]
            where.setdefault(heading, {})[m.group(1).lower()] = m.group(2)
        elif s.endswith(":"):
            heading = s[:-1]
        elif s.startswith("Quality"):
            photo = None
    if m := re.search(r"Check measurements.*?Diff.*?\n\s*id,[^\n]*\n(.*?)\n\s*Check point delta",
                      text, re.S):
        for row in m.group(1).splitlines():
            f = [c.strip() for c in row.split(",")]
            out["check"][f[0]] = f[1:4]
    return out


def pm_report(path: Path) -> dict:
    """PhotoModeler's status report: 'last_error' and per photo
    {name: (value, deviation)} for Omega Phi Kappa (deg) and Xc Yc Zc."""
    text = path.read_text(encoding="utf-8")
    out = {"last_error": re.search(r"Last Error:\s+(\S+)", text).group(1), "photos": {}}
    for m in re.finditer(r"Photo (\d+):(.*?)(?=Photo \d+:|\n\s*Quality)", text, re.S):
        out["photos"][int(m.group(1))] = {
            name: re.search(name + r"\s*\n\s*Value:\s*(\S+).*?\n\s*Deviation:\s*\w+:\s*(\S+)",
                            m.group(2), re.S).groups()
            for name in EO_NAMES}
    return out


def pm_points(path: Path) -> dict:
    """PhotoModeler's 3D point table: id -> (xyz, precision); 'fixed' -> NaN."""
    rows = [r for r in csv.reader(path.read_text(encoding="utf-8").splitlines()) if r]
    header = next(r for r in rows if r[0] == "Id")
    col = {h: i for i, h in enumerate(header)}
    out = {}
    for r in rows[rows.index(header) + 1:]:
        xyz = [float(r[col[f"{c} (project units)"]]) for c in "XYZ"]
        prec = [math.nan if r[col[f"{c} Precision"]] == "fixed" else
                float(r[col[f"{c} Precision"]]) for c in "XYZ"]
        out[r[0]] = (np.array(xyz), np.array(prec))
    return out


def dbat_stations(path: Path) -> dict:
    """DBAT's EO listing: id -> (x y z omega phi kappa, their sigmas).

    The header says "Unit: degrees", but DBAT 0.9.2 writes the angles in
    radians and multiplies all six *sigmas* by 180/pi: the angle sigmas are
    in degrees, the position sigmas come out 57.3 times too large (checked
    against the report in test_dbat_station_listing_units)."""
    out = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.strip() and not line.startswith("#"):
            f = [c.strip() for c in line.split(",")]
            values = np.array([float(v) for v in f[2:8]])
            sigmas = np.radians([float(v) for v in f[8:14]])
            out[f[1]] = (values, sigmas)
    return out


def to_mm(values: dict, ps: float) -> dict:
    """Brown parameters (px) -- or their sigmas -- in mm with the pixel
    size ``ps`` (c, x0, y0 times ps; K1 ps^-2, K2 ps^-4, K3 ps^-6; P ps^-1)."""
    model = camera_model("brown")
    names = list(model.parameter_names)
    mm = rescale_parameters(model, np.array([values[n] for n in names]), ps)
    return dict(zip(names, mm))


def pixel_size(report: dict) -> float:
    """DBAT's nominal pixel size: format height / image height."""
    cam = report["camera"]
    return float(cam["Format height"]["value"]) / float(cam["Image height"]["value"])


def residuals_match(result, report: dict) -> bool:
    """DBAT's overall point RMS (of the residual vector lengths) and largest
    residual, in pixels, printed with 3 decimals."""
    v = np.hypot(result.residuals["vx"], result.residuals["vy"])
    return (close(float(np.sqrt(np.mean(v ** 2))), report["rms"], 0.0)
            and close(float(np.max(v)), report["max_residual"], 0.0))


def wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


# --------------------------------------------------------------------------
# runs (each adjustment once per test session)
# --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def camcal():
    return adjust(read_project(PROJECTS / "camcal" / "camcal.prj"))


@pytest.fixture(scope="module")
def camcal_weighted():
    return adjust(read_project(PROJECTS / "camcal" / "camcal-weighted.prj"))


@pytest.fixture(scope="module")
def sxb():
    return adjust(read_project(PROJECTS / "sxb" / "sxb.prj"), fix_interior=True)


def with_pm_camera(prj: Path):
    """The project with PhotoModeler's camera, held fixed (as in PM's runs)."""
    project = read_project(prj)
    f = [float(v) for v in PM_CAMERA.split()]
    ps = f[3] / 2272                            # PM's format width / image width
    assert f[4] / 1704 == pytest.approx(ps, rel=1e-6)      # square pixels
    model = camera_model("brown")
    mm = dict(c=f[0], x0=f[1], y0=f[2], K1=f[5], K2=f[6], K3=f[7], P1=f[8], P2=f[9],
              B1=0.0, B2=0.0)
    px = rescale_parameters(model, np.array([mm[n] for n in model.parameter_names]), 1 / ps)
    for name, value in zip(model.parameter_names, px):
        project.cameras["C4040Z"].parameters[name].value = float(value)
        project.cameras["C4040Z"].parameters[name].free = False
    return project, dict(zip(model.parameter_names, px))


# --------------------------------------------------------------------------
# CAMCAL, DBAT's settings (fixed control)
# --------------------------------------------------------------------------

def camera_check(values: dict, sigmas: dict, report: dict, rel: float = 0.005) -> list[str]:
    """Our camera (px) against DBAT's report (mm); returns the mismatches."""
    ps = pixel_size(report)
    mm = to_mm(values, ps)
    smm = {n: abs(v) for n, v in to_mm(sigmas, ps).items()}
    bad = []
    for name, heading in DBAT_NAMES.items():
        ref = report["camera"][heading]
        if not close(mm[name], ref["value"], rel):
            bad.append(f"{name}: {mm[name]:.7g} vs DBAT {ref['value']}")
        if not close(smm[name], ref["deviation"], rel):
            bad.append(f"sigma {name}: {smm[name]:.4g} vs DBAT {ref['deviation']}")
    return bad


def test_camcal_reproduces_dbat(camcal):
    report = dbat_report(CAMCAL / "dbat-report.txt")
    s = camcal.summary
    assert s["status"] == "converged"
    assert s["redundancy"] == report["redundancy"] == 3725
    assert s["sigma0"] == pytest.approx(printed(report["sigma0"])[0], rel=0.001)
    cam = camcal.project.cameras["C4040Z"]
    values = {n: p.value for n, p in cam.parameters.items()}
    assert camera_check(values, camcal.camera_sigma["C4040Z"], report) == []
    assert s["counts"] == {"observations": 4148, "unknowns": 423, "conditions": 0,
                           "interior": 9, "exterior": 126, "points": 288}
    assert residuals_match(camcal, report)


def test_camcal_through_the_command_line(tmp_path):
    out = tmp_path / "out"
    assert main(["calibrate", "--no-report", str(PROJECTS / "camcal" / "camcal.prj"), "--output",
                 str(out), "-q"]) == 0
    results = read_results(out)
    report = dbat_report(CAMCAL / "dbat-report.txt")
    assert results.summary["redundancy"] == report["redundancy"]
    assert results.summary["sigma0"] == pytest.approx(printed(report["sigma0"])[0], rel=0.001)
    cam = results.cameras["C4040Z"]
    values = {n: p.value for n, p in cam.parameters.items()}
    sigmas = {n: p.sigma_estimated or 0.0 for n, p in cam.parameters.items()}
    assert camera_check(values, sigmas, report) == []
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["command"] == "calibrate"


def test_dbat_station_listing_units():
    """The EO listing's sigmas are the report's deviations times 180/pi."""
    listing = dbat_stations(CAMCAL / "dbat-camera_stations.txt")
    report = dbat_report(CAMCAL / "dbat-report.txt")
    for k, (values, sigmas) in listing.items():
        photo = report["photos"][int(k)]
        for i, name in enumerate(EO_NAMES[:3]):
            assert close(values[i], photo[name]["value"], 1e-6)
            assert close(sigmas[i], photo[name]["deviation"], 0.005), (k, name)
        for i, name in enumerate(EO_NAMES[3:], 3):
            assert close(math.degrees(values[i]), photo[name]["value"], 1e-6), (k, name)
            assert close(math.degrees(sigmas[i]), photo[name]["deviation"], 0.005), (k, name)


def test_camcal_exterior_orientation_matches_dbat(camcal):
    listing = dbat_stations(CAMCAL / "dbat-camera_stations.txt")
    st = camcal.project.stations
    worst = 0.0
    for k, (values, sigmas) in listing.items():
        i = st.names.index(k)
        d = np.hstack([st.position[i] - values[:3], wrap(st.angles[i] - values[3:])])
        ours = camcal.station_sigma[i]
        worst = max(worst, float(np.max(np.abs(d) / sigmas)))
        assert np.all(np.abs(d) <= 0.01 * sigmas), (k, d / sigmas)
        assert np.allclose(ours, sigmas, rtol=0.005), (k, ours / sigmas)
    print(f"CAMCAL EO: max |ours - DBAT| = {worst:.2e} of DBAT's deviation")


# --------------------------------------------------------------------------
# CAMCAL, weighted control, and PhotoModeler
# --------------------------------------------------------------------------

PM_RUNS = {"weighted": ("camcal-weighted.prj", "photomodeler-weighted-no-orient"),
           "fixed": ("camcal.prj", "photomodeler-fixed-no-orient")}


@pytest.mark.parametrize("run", sorted(PM_RUNS))
def test_photomodeler_run_with_its_camera(run):
    """PhotoModeler's own runs, reproduced with PhotoModeler's camera held
    fixed ("Calibration: off" in its reports)."""
    prj, stem = PM_RUNS[run]
    project, _ = with_pm_camera(PROJECTS / "camcal" / prj)
    result = adjust(project, fix_interior=True)
    report = pm_report(CAMCAL / f"{stem}-report.txt")
    s = result.summary
    # PhotoModeler counts control coordinates as observations even when they
    # are fixed: 3 x 4 more than our redundancy in the fixed run.
    extra = 12 if run == "fixed" else 0
    sigma0_pm = s["sigma0"] * math.sqrt(s["redundancy"] / (s["redundancy"] + extra))
    # PM prints 4 digits of Last Error and 5 of its camera: 0.1 %
    assert close(sigma0_pm, report["last_error"], 0.001), (s["sigma0"], sigma0_pm)
    # points: PM's 3D table is in the control frame (its export translates)
    pm = pm_points(CAMCAL / f"{stem}-3dpts.txt")
    pts = result.project.points
    d = np.array([pts.xyz[i] - pm[p][0] for i, p in enumerate(pts.ids)])
    prec = np.array([pm[p][1] for p in pts.ids])
    ours = result.point_sigma
    assert np.nanmax(np.abs(d)) < 5e-6                 # PM prints 1e-6 m
    free = np.isfinite(prec)
    assert np.allclose(ours[free], prec[free], rtol=0.02, atol=1e-6)
    # stations: PM reports them in its internal frame, centred on the sheet
    st = result.project.stations
    pos = np.array([[float(report["photos"][k][n][0]) for n in EO_NAMES[:3]]
                    for k in range(1, 22)])
    ang = np.radians([[float(report["photos"][k][n][0]) for n in EO_NAMES[3:]]
                      for k in range(1, 22)])
    dev = np.array([[float(report["photos"][k][n][1]) for n in EO_NAMES] for k in range(1, 22)])
    order = [st.names.index(str(k)) for k in range(1, 22)]
    shift = np.median(st.position[order] - pos, axis=0)
    assert np.allclose(shift, [0.5, 0.5, 0.0], atol=2e-5)
    dpos = st.position[order] - shift - pos
    dang = wrap(st.angles[order] - ang)
    # PM's camera is printed to 0.1 um: its principal point alone is
    # uncertain by 0.05 um / 7.47 mm = 7 urad in the station angles, 1.4e-5 m
    # at 2 m; twice that is allowed (PM prints 1e-6 m and 1e-6 deg itself)
    assert np.max(np.abs(dang)) < 1.5e-5 and np.max(np.abs(dpos)) < 3e-5
    assert np.all(np.abs(np.hstack([dpos, np.degrees(dang)])) <= 0.1 * dev)
    print(f"PM {run}: sigma0 {s['sigma0']:.5f} (PM convention {sigma0_pm:.5f}, "
          f"Last Error {report['last_error']}); points max |d| {np.nanmax(np.abs(d)):.1e} m; "
          f"EO max |d| {np.max(np.abs(dpos)):.1e} m, {np.max(np.abs(dang)):.1e} rad "
          f"({np.max(np.abs(np.hstack([dpos, np.degrees(dang)])) / dev):.3f} of PM's deviation)")


def test_camcal_weighted_self_calibration(camcal, camcal_weighted):
    """DBAT's settings with weighted control (1 mm), against PhotoModeler's
    weighted run and PhotoModeler's calibration."""
    w, s = camcal_weighted.summary, camcal.summary
    assert w["status"] == "converged" and w["redundancy"] == s["redundancy"] == 3725
    # nested models: the fixed-control solution is feasible here with zero
    # control residuals, so the weighted fit cannot be worse ...
    assert w["sigma0"] < s["sigma0"]
    # ... and PhotoModeler's camera is one possible interior orientation
    project, pm_px = with_pm_camera(PROJECTS / "camcal" / "camcal-weighted.prj")
    pm_run = adjust(project, fix_interior=True).summary
    bound = pm_run["sigma0"] * math.sqrt(pm_run["redundancy"] / w["redundancy"])
    assert w["sigma0"] < bound
    report = pm_report(CAMCAL / "photomodeler-weighted-no-orient-report.txt")
    assert w["sigma0"] < printed(report["last_error"])[0]

    # points: the two solutions share observations and datum; a different
    # camera moves the points by much less than PhotoModeler's 1-sigma
    # precision (about 1 mm, mostly the datum)
    pm = pm_points(CAMCAL / "photomodeler-weighted-no-orient-3dpts.txt")
    pts = camcal_weighted.project.points
    d = np.array([pts.xyz[i] - pm[p][0] for i, p in enumerate(pts.ids)])
    prec = np.array([pm[p][1] for p in pts.ids])
    assert np.all(np.abs(d) < prec)
    # precisions scale with sigma0: ours / PM's = our sigma0 / PM's Last Error
    ratio = camcal_weighted.point_sigma / prec
    expected = w["sigma0"] / printed(report["last_error"])[0]
    assert np.allclose(ratio, expected, rtol=0.01)

    # camera against PhotoModeler's calibration, in pixels (PM's format
    # differs from DBAT's nominal one by 0.04 %). PM's model has no aspect
    # parameter and K3 = 0, so only c, the principal point and the distortion
    # curves are comparable, to about a tenth of a percent and a pixel.
    cam = {n: p.value for n, p in camcal_weighted.project.cameras["C4040Z"].parameters.items()}
    assert cam["c"] == pytest.approx(pm_px["c"], rel=0.002)
    assert abs(cam["x0"] - pm_px["x0"]) < 2.5 and abs(cam["y0"] - pm_px["y0"]) < 2.5
    r = np.linspace(0.0, 2272 / 2, 50)                   # up to the half width

    def radial(p):
        return r * (p["K1"] * r ** 2 + p["K2"] * r ** 4 + p["K3"] * r ** 6)

    assert np.max(np.abs(radial(cam) - radial(pm_px))) < 1.0
    assert np.max(np.abs(radial(pm_px))) > 50.0           # of 55 px distortion
    corners = np.array([[x, y] for x in (-1136, 1136) for y in (-852, 852)], float)

    def tangential(p):
        x, y = corners[:, 0], corners[:, 1]
        r2 = x * x + y * y
        return np.hypot(p["P1"] * (r2 + 2 * x * x) + 2 * p["P2"] * x * y,
                        p["P2"] * (r2 + 2 * y * y) + 2 * p["P1"] * x * y)

    assert np.max(np.abs(tangential(cam) - tangential(pm_px))) < 0.5
    print(f"CAMCAL weighted: sigma0 {w['sigma0']:.6f} (fixed control {s['sigma0']:.6f}, "
          f"PM Last Error {report['last_error']}); points max |d| {np.max(np.abs(d)):.2e} m "
          f"= {np.max(np.abs(d) / prec):.2f} PM sigma; c {cam['c']:.2f} vs PM {pm_px['c']:.2f} px")


# --------------------------------------------------------------------------
# SXB
# --------------------------------------------------------------------------

def test_sxb_reproduces_dbat(sxb):
    report = dbat_report(SXB / "dbat-report.txt")
    s = sxb.summary
    assert s["status"] == "converged"
    assert s["redundancy"] == report["redundancy"] == 1261
    assert s["sigma0"] == pytest.approx(printed(report["sigma0"])[0], rel=0.005)
    assert s["counts"]["interior"] == 0 and s["counts"]["observations"] == 2434
    assert residuals_match(sxb, report)
    # check points: DBAT prints posterior - prior with 3 decimals
    check = s["check_points"]
    assert sorted(check["ids"]) == sorted(report["check"]) == ["351", "410"]
    for pid, d in zip(check["ids"], check["differences"]):
        ref = np.array([float(v) for v in report["check"][pid]])
        assert np.all(np.abs(np.array(d) - ref) <= 0.001), (pid, d, ref)
        print(f"SXB check point {pid}: ours {np.round(d, 4)} m, DBAT {ref} m")


def test_sxb_exterior_orientation_matches_dbat(sxb):
    report = dbat_report(SXB / "dbat-report.txt")
    st = sxb.project.stations
    for k, photo in report["photos"].items():
        i = st.names.index(str(k))
        ours = list(st.position[i]) + list(np.degrees(st.angles[i]))
        ours_sigma = list(sxb.station_sigma[i, :3]) + list(np.degrees(sxb.station_sigma[i, 3:]))
        for j, name in enumerate(EO_NAMES):
            value, dev = photo[name]["value"], photo[name]["deviation"]
            diff = ours[j] - float(value)
            if j >= 3:
                diff = (diff + 180) % 360 - 180
            assert abs(diff) <= max(0.01 * float(dev), printed(value)[1]), (k, name, diff)
            assert close(ours_sigma[j], dev, 0.005), (k, name, ours_sigma[j], dev)
