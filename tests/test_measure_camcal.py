"""`photogram measure` on real photographs: DBAT's CAMCAL (21 images of the
PhotoModeler calibration sheet), against PhotoModeler's measurement of the
same images (markpts.txt) and DBAT's calibration from it (dbat-report.txt).

Ids: ours come from the sheet layout (projects/camcal/sheet.toml: grid dots
``D{row}{col}``, codes 1001-1004); they are mapped to PhotoModeler's by
position (within 3 px) and the mapping must be one-to-one over all images.
Centres are compared without the eccentricity correction (PhotoModeler's
are ellipse centres too: the correction makes the agreement worse,
docs/measure.md). Figures in docs/measure.md and docs/benchmarks.md.

The camera constant misses DBAT's by 1.7 of DBAT's deviations (strict
xfail). The tests at the end record the evidence for the cause: our centres
and PhotoModeler's differ by a radial scale; every colour channel shows it
and red and blue more than green (lateral chromatic aberration), so no
channel or mix of them reproduces PhotoModeler's; PhotoModeler's centres
are not eccentricity-corrected; and re-encoding these JPEGs changes the
green channel's radial scale by as much as the whole difference.
"""

import json
import re
from pathlib import Path

import cv2

import numpy as np
import pytest

from photogram.bundle import adjust
from photogram.project import read_project
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
CAMCAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "dbat" / "camcal"
SHEET = ROOT / "projects" / "camcal" / "sheet.toml"

if not (CAMCAL / "images").is_dir():
    pytest.skip(f"CAMCAL images not found at {CAMCAL}", allow_module_level=True)

#: DBAT's report (mm) converted with its nominal pixel size p = 5.43764 / 1704 mm
P = 5.43764 / 1704
DBAT = {"c": (7.457 / P, 0.00105 / P), "x0": (3.61546 / P, 0.00082 / P),
        "y0": (2.61329 / P, 0.00098 / P), "K1": (0.00458861 * P ** 2, 2.21e-05 * P ** 2)}
DBAT_SIGMA0_PX = 0.16148


def _read_obs(path):
    rows = [ln.split(",") for ln in path.read_text().splitlines()
            if ln and not ln.startswith("#")][1:]
    return [(r[0], r[1], float(r[2]), float(r[3]), float(r[4])) for r in rows]


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    out = tmp_path_factory.mktemp("camcal") / "measured"
    # no report.pdf: the tests read the tables and summary.json
    assert main(["measure", str(SHEET), "--output", str(out), "--no-eccentricity", "-q",
                 "--no-report"]) == 0
    return out


@pytest.fixture(scope="module")
def comparison(measured):
    obs = _read_obs(measured / "image_points.csv")
    stations = sorted({o[0] for o in obs})
    assert len(stations) == 21
    ref = np.loadtxt(CAMCAL / "markpts.txt", delimiter=",")
    pairs, residuals, found = {}, [], 0
    for k, st in enumerate(stations, 1):          # image ids 1..21 = P8250021..41
        mine = [o for o in obs if o[0] == st]
        xy = np.array([[o[2], o[3]] for o in mine])
        r = ref[ref[:, 0] == k]
        d = np.linalg.norm(r[:, None, 2:4] - xy[None], axis=2)
        j = d.argmin(axis=1)
        ok = d.min(axis=1) < 3.0
        found += int(ok.sum())
        for row, jj in zip(r[ok], j[ok]):
            pairs.setdefault(mine[jj][1], set()).add(int(row[1]))
        residuals.append(xy[j[ok]] - r[ok, 2:4])
    return {"obs": obs, "n_ref": len(ref), "found": found, "pairs": pairs,
            "residuals": np.vstack(residuals)}


def test_found_with_a_one_to_one_mapping(comparison, measured):
    c = comparison
    print(f"found {c['found']} of {c['n_ref']} ({100 * c['found'] / c['n_ref']:.2f} %), "
          f"{len(c['obs'])} observations written")
    assert c["found"] >= 0.98 * c["n_ref"]
    # one-to-one: each of our ids is one PhotoModeler id and vice versa
    assert all(len(v) == 1 for v in c["pairs"].values())
    inverse = {}
    for ours, theirs in c["pairs"].items():
        inverse.setdefault(next(iter(theirs)), set()).add(ours)
    assert all(len(v) == 1 for v in inverse.values())
    assert len(c["pairs"]) == 100
    # the codes are the sheet's own numbers: decoded, never mis-decoded
    for code in ("1001", "1002", "1003", "1004"):
        assert c["pairs"][code] == {int(code)}
    summary = json.loads((measured / "summary.json").read_text())
    assert summary["totals"]["codes"] == 84               # 4 codes x 21 images
    assert summary["problems"] == []


def test_centres_agree_with_photomodeler(comparison):
    r = comparison["residuals"]
    offset = r.mean(axis=0)
    rms = float(np.sqrt(((r - offset) ** 2).sum(axis=1).mean()))
    per_axis = np.sqrt(((r - offset) ** 2).mean(axis=0))
    print(f"offset {offset[0]:+.4f} {offset[1]:+.4f} px (after the +0.5 px corner convention), "
          f"RMS {rms:.4f} px (x {per_axis[0]:.4f}, y {per_axis[1]:.4f})")
    # PhotoModeler's image frame has the image corner at (0, 0) as ours: what
    # remains of the offset is small
    assert np.all(np.abs(offset) < 0.1)
    assert rms <= 0.10                     # measured 0.081; issue goal 0.15


@pytest.fixture(scope="module")
def calibration(measured, tmp_path_factory):
    folder = tmp_path_factory.mktemp("camcal-prj")
    text = (ROOT / "projects" / "camcal" / "camcal-measured.prj").read_text()
    text = text.replace("../../../shared/data", str(CAMCAL.parents[1]))
    text = text.replace('"results-measure/image_points.csv"',
                        json.dumps(str(measured / "image_points.csv")))
    text = re.sub(r'folder = "results-measured"', f'folder = "{folder / "out"}"', text)
    (folder / "camcal-measured.prj").write_text(text)
    return adjust(read_project(folder / "camcal-measured.prj"))


def test_calibrate_on_the_measured_project(calibration):
    s = calibration.summary
    cam = calibration.project.cameras["C4040Z"]
    dev = {k: (cam.parameters[k].value - v) / sd for k, (v, sd) in DBAT.items()}
    print(f"sigma0 {s['sigma0']:.4f}, in px {s['sigma0_image']:.4f} (DBAT 0.1615); "
          + ", ".join(f"{k} {d:+.2f} sd" for k, d in dev.items()))
    assert s["status"] == "converged"
    assert s["sigma0_image"] <= DBAT_SIGMA0_PX
    for k in ("x0", "y0", "K1"):
        assert abs(dev[k]) <= 1.0, k


@pytest.mark.xfail(strict=True, reason="c comes out 1.7 DBAT deviations above DBAT's: "
                   "our centres and PhotoModeler's differ by a radial scale of 1e-4 (0.7 sd of "
                   "c) and by a further pattern worth 1 sd; the green channel of these "
                   "recompressed JPEGs carries lateral chromatic aberration through JPEG's "
                   "chroma, and re-encoding alone moves c by 0.7-1.2 sd (docs/measure.md)")
def test_camera_constant_within_one_deviation_of_dbat(calibration):
    cam = calibration.project.cameras["C4040Z"]
    v, sd = DBAT["c"]
    assert abs(cam.parameters["c"].value - v) <= sd


def _radial_scale(folder):
    """Least squares ``ours - PhotoModeler = offset + s (x_pm - centre)`` over
    all matched observations (centre of the image 1136, 852): ``s``."""
    obs = _read_obs(Path(folder) / "image_points.csv")
    ref = np.loadtxt(CAMCAL / "markpts.txt", delimiter=",")
    d, q = [], []
    for k, st in enumerate(sorted({o[0] for o in obs}), 1):
        xy = np.array([[o[2], o[3]] for o in obs if o[0] == st])
        r = ref[ref[:, 0] == k]
        dist = np.linalg.norm(r[:, None, 2:4] - xy[None], axis=2)
        ok = dist.min(axis=1) < 3.0
        d.append(xy[dist.argmin(axis=1)[ok]] - r[ok, 2:4])
        q.append(r[ok, 2:4] - [1136.0, 852.0])
    d, q = np.vstack(d), np.vstack(q)
    A = np.zeros((2 * len(d), 3))
    A[0::2, 0] = A[1::2, 1] = 1
    A[:, 2] = q.ravel()
    sol = np.linalg.lstsq(A, d.ravel(), rcond=None)[0]
    return float(sol[2]), d


def _measure(tmp, name, channel="green", images=None, eccentricity=False):
    sheet = tmp / f"sheet-{name}.toml"
    sheet.write_text(re.sub(r'(?m)^channel = .*$', f'channel = "{channel}"', SHEET.read_text()))
    out = tmp / name
    args = ["measure", str(sheet), "--images", str(images or CAMCAL / "images"),
            "--output", str(out), "--no-report", "-q"]
    assert main(args + ([] if eccentricity else ["--no-eccentricity"])) == 0
    return out


@pytest.fixture(scope="module")
def scales(measured, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("camcal-channels")
    s = {"green": _radial_scale(measured)[0]}
    for ch in ("red", "blue", "gray"):
        s[ch] = _radial_scale(_measure(tmp, ch, ch))[0]
    print("radial scale against PhotoModeler: " + ", ".join(f"{k} {v * 1e5:+.1f}e-5"
                                                             for k, v in s.items()))
    return s


def test_lateral_chromatic_aberration_no_channel_reproduces_photomodeler(scales):
    # our green centres lie radially outside PhotoModeler's (0.1 px at the corners)
    assert 5e-5 < scales["green"] < 1.5e-4              # measured 9.8e-5
    # lateral chromatic aberration: red and blue images are larger than green
    assert scales["red"] - scales["green"] > 3e-4       # measured 4.9e-4
    assert scales["blue"] - scales["green"] > 1.5e-4    # measured 2.9e-4
    # grey (0.299 R + 0.587 G + 0.114 B) is their mix
    mix = 0.299 * scales["red"] + 0.587 * scales["green"] + 0.114 * scales["blue"]
    assert abs(scales["gray"] - mix) < 3e-5
    # every channel is radially outside PhotoModeler's: no non-negative mix
    # of the channels of these images gives PhotoModeler's scale
    assert min(scales.values()) == scales["green"] > 0


def test_photomodeler_centres_are_not_eccentricity_corrected(measured, tmp_path_factory):
    """Regress our - PhotoModeler on (offset, radial scale, our eccentricity
    correction): PhotoModeler's centres contain none of the correction."""
    corrected = _measure(tmp_path_factory.mktemp("camcal-ecc"), "ecc", eccentricity=True)
    _, d0 = _radial_scale(measured)
    _, d1 = _radial_scale(corrected)
    corr = d1 - d0                                      # the correction applied
    assert np.sqrt((corr ** 2).sum(axis=1).mean()) > 0.04      # measured 0.063 px RMS
    ref = np.loadtxt(CAMCAL / "markpts.txt", delimiter=",")
    # (same matching order in both runs: PhotoModeler's rows, image by image)
    assert len(d0) == len(d1) == len(ref)
    q = ref[:, 2:4] - [1136.0, 852.0]
    A = np.zeros((2 * len(d0), 4))
    A[0::2, 0] = A[1::2, 1] = 1
    A[:, 2] = q.ravel()
    A[:, 3] = corr.ravel()
    alpha = np.linalg.lstsq(A, d0.ravel(), rcond=None)[0][3]
    print(f"fraction of the eccentricity correction in PhotoModeler's centres: {alpha:+.3f}")
    assert abs(alpha) < 0.2                             # measured +0.04


def test_jpeg_reencoding_moves_the_green_radial_scale(scales, tmp_path_factory):
    """The green channel of a JPEG is luminance plus 2x-subsampled, quantised
    chroma, and the chroma carries the lateral chromatic aberration: re-encoding
    these images (quality 30) moves the green centres' radial scale by about
    as much as the whole difference to PhotoModeler's."""
    tmp = tmp_path_factory.mktemp("camcal-q30")
    images = tmp / "images"
    images.mkdir()
    for f in sorted((CAMCAL / "images").glob("*.JPG")):
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        assert cv2.imwrite(str(images / f.name), img, [cv2.IMWRITE_JPEG_QUALITY, 30])
    s30 = _radial_scale(_measure(tmp, "q30", images=images))[0]
    print(f"green radial scale: {scales['green'] * 1e5:+.1f}e-5, re-encoded at quality 30 "
          f"{s30 * 1e5:+.1f}e-5")
    assert abs(s30 - scales["green"]) > 4e-5            # measured 7.7e-5 (OpenCV, quality 30)


def test_epipolar_curves_of_measure_serve_on_the_real_photographs(calibration):
    """Real data for ``photogram measure --serve``'s epipolar help
    (photogram/serve/epipolar.py): with the calibrated C4040Z (DBAT's
    camera model, whose distortion must be inverted to draw a curve, and
    strong radial distortion), the curve of a target of one photograph
    passes near the same target's measurement in every other photograph,
    as far as the two measurements' residuals allow (sigma0 0.15 px)."""
    from photogram.lines.views import cameras_from_project
    from photogram.serve.epipolar import image_of_ray
    pr = calibration.project
    cams = cameras_from_project(pr)
    names = pr.stations.names
    width, height = pr.cameras["C4040Z"].image_size
    ip = pr.image_points
    obs = {(names[s], pr.points.ids[p]): xy for s, p, xy in zip(ip.station, ip.point, ip.xy)}
    src = names[0]
    labels = sorted(p for s, p in obs if s == src)[::9]            # 11 targets
    dist = []
    for label in labels:
        cam = cams[src]
        d = cam.rays(cam.ideal(obs[(src, label)][None]))[0]
        for other in names[1:]:
            if (other, label) not in obs:
                continue
            curve = np.array(image_of_ray(cams[other], cam.X0, d, width, height))
            assert len(curve) >= 20
            x = obs[(other, label)]
            a, b = curve[:-1], curve[1:]
            t = np.clip(((x - a) * (b - a)).sum(1) / ((b - a) ** 2).sum(1), 0, 1)
            dist.append(np.min(np.hypot(*(a + t[:, None] * (b - a) - x).T)))
    dist = np.array(dist)
    print(f"CAMCAL epipolar curves: {len(dist)} pairs, distance to the measured target "
          f"median {np.median(dist):.3f} px, max {dist.max():.3f} px")
    assert len(dist) >= 150
    assert np.median(dist) < 0.3 and dist.max() < 1.5
