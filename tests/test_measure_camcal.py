"""`photogram measure` on real photographs: DBAT's CAMCAL (21 images of the
PhotoModeler calibration sheet), against PhotoModeler's measurement of the
same images (markpts.txt) and DBAT's calibration from it (dbat-report.txt).

Ids: ours come from the sheet layout (projects/camcal/sheet.toml: grid dots
``D{row}{col}``, codes 1001-1004); they are mapped to PhotoModeler's by
position (within 3 px) and the mapping must be one-to-one over all images.
Centres are compared without the eccentricity correction (PhotoModeler's
are ellipse centres too: the correction makes the agreement worse,
docs/measure.md). Figures in docs/measure.md and docs/benchmarks.md.
"""

import json
import re
from pathlib import Path

import numpy as np
import pytest

from photogram.commands.bundle import adjust
from photogram.project import read_project
from photogram_cli.main import main

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
    assert main(["measure", str(SHEET), "--output", str(out), "--no-eccentricity", "-q"]) == 0
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


@pytest.mark.xfail(strict=True, reason="c comes out 1.7 DBAT deviations above DBAT's "
                   "(a radial scale of 9e-5 between our centres and PhotoModeler's on these "
                   "recompressed JPEGs; docs/measure.md): the issue's 1-sd goal is not met")
def test_camera_constant_within_one_deviation_of_dbat(calibration):
    cam = calibration.project.cameras["C4040Z"]
    v, sd = DBAT["c"]
    assert abs(cam.parameters["c"].value - v) <= sd
