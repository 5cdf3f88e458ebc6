"""`photogram measure FIELD --guided PROJECT.prj` on rendered images with
known truth (the scene of tests/test_measure_bundle_guided.py: 9 x 7 dots,
six views, k1 = -0.08, 12 faint dots, a first pass that misses 132
targets), through the command line: the first measurement is the
project's ``results-measure/image_points.csv``; the guided run writes
``results-guided/`` and never the project's own folder; bad input is one
line, exit 2, nothing written."""

import csv
import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from photogram.project.model import TargetSettings
from photogram.project.writer import write_project
from photogram.simulation.network import to_project
from photogram_cli.main import main

from test_measure_bundle_guided import CONTROL, FREE, RADIUS, _scene, _true_ellipse_centres
from test_measure_eccentric_bundle import SIZE

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

FIELD = """[field]
name = "rendered sheet"
images = "images"
polarity = "dark"
diameter = 0.04
min_diameter = 5
max_diameter = 80
min_contrast = 20

# the field needs a code to be a valid description; the guided run uses
# only [field] (images, polarity, channel, contrast, sigma floor)
[[codes.target]]
id = "C1"
bits = "11110000"
xyz = [-0.1, -0.1, 0.0]
"""


@pytest.fixture(scope="module")
def scene():
    return _scene()


def _setup(folder: Path, scene, *, targets: bool = True) -> Path:
    """A field file, the images named like the stations, a project whose
    image points are the first pass in results-measure/ (ellipse centres)."""
    net, images, sigma = scene
    prj = to_project(net, control=CONTROL, free_interior=FREE, sigma_image=0.05,
                     perturb_points=0.001, perturb_stations=0.01, rng=np.random.default_rng(1))
    prj.image_points.sigma = sigma
    P = len(prj.points)
    if targets:
        prj.targets = TargetSettings(ids=list(prj.points.ids), radius=np.full(P, RADIUS),
                                     normals=np.tile([0.0, 0.0, 1.0], (P, 1)))
    folder.mkdir(exist_ok=True)
    path = write_project(prj, folder / "sheet.prj")
    first = folder / "results-measure"
    first.mkdir()
    shutil.move(folder / "sheet_image_points.csv", first / "image_points.csv")
    (first / "summary.json").write_text(json.dumps({"command": "measure",
                                                    "eccentricity_correction": False}))
    path.write_text(path.read_text().replace('points = "sheet_image_points.csv"',
                                             'points = "results-measure/image_points.csv"'))
    (folder / "images").mkdir()
    for name, img in images.items():
        cv2.imwrite(str(folder / "images" / f"{name}.png"), img)
    (folder / "field.toml").write_text(FIELD)
    return path


def _run(capsys, args):
    code = main(["measure", *map(str, args)])
    cap = capsys.readouterr()
    return code, cap.out.strip().splitlines(), cap.err.strip().splitlines()


def _listing(folder: Path):
    return sorted((str(p.relative_to(folder)), p.stat().st_mtime_ns) for p in folder.rglob("*"))


def test_guided_run_through_the_command_line(tmp_path, scene, capsys):
    net = scene[0]
    prj = _setup(tmp_path, scene)
    before = _listing(tmp_path / "results-measure")
    code, out, err = _run(capsys, [tmp_path / "field.toml", "--guided", prj])
    assert code == 0, err
    print(out)
    assert _listing(tmp_path / "results-measure") == before      # the input untouched
    res = tmp_path / "results-guided"
    summary = json.loads((res / "summary.json").read_text())
    rows = list(csv.DictReader(line for line in (res / "image_points.csv").open()
                               if not line.startswith("#")))
    first = list(csv.DictReader(line for line in
                                (tmp_path / "results-measure" / "image_points.csv").open()
                                if not line.startswith("#")))
    n0 = len(first)
    assert summary["observations_before"] == n0 and summary["observations"] == len(rows)
    added = [r["added"] for r in summary["rounds"]]
    removed = sum(r["removed"] for r in summary["rounds"])
    print(f"{n0} -> {len(rows)} observations; rounds {summary['rounds']}")
    assert added[-1] == 0 and len(added) >= 2 and sum(added) - removed == len(rows) - n0
    assert sum(summary["added_per_image"].values()) == len(rows) - n0
    # the first measurement's rows come first, unchanged
    assert [(r["station"], r["point"]) for r in rows[:n0]] == \
        [(r["station"], r["point"]) for r in first]
    # the added rows: every one its own target, none wrong (truth: ellipse centres)
    st = {s: i for i, s in enumerate(["S1", "S2", "S3", "S4", "S5", "S6"])}
    new = rows[n0:]
    s_idx = np.array([st[r["station"]] for r in new])
    p_idx = np.array([int(r["point"][1:]) - 1 for r in new])
    pairs = set(zip(s_idx.tolist(), p_idx.tolist()))
    assert len(pairs) == len(new)
    assert not pairs & {(st[r["station"]], int(r["point"][1:]) - 1) for r in first}
    xy = np.array([[float(r["x"]), float(r["y"])] for r in new])
    err = np.linalg.norm(xy - _true_ellipse_centres(net, s_idx, p_idx), axis=1)
    print(f"added {len(new)}: error RMS {np.sqrt((err ** 2).mean()):.4f} px, max {err.max():.3f}")
    assert len(new) >= 125                 # the library test: 132 of 132 missed targets
    assert err.max() < 0.3 and np.sqrt((err ** 2).mean()) < 0.05
    guided = list(csv.DictReader((res / "guided.csv").open()))
    assert len(guided) == len(new) and {int(g["round"]) for g in guided} <= set(
        range(1, len(added) + 1))
    # a second run into the same folder is refused without --force
    code, _, err = _run(capsys, [tmp_path / "field.toml", "--guided", prj])
    assert code == 2 and len(err) == 1 and "--force" in err[0]


def test_guided_run_bad_input_is_one_line_and_writes_nothing(tmp_path, scene, capsys):
    prj = _setup(tmp_path, scene)
    field = tmp_path / "field.toml"
    first = tmp_path / "results-measure"
    before = _listing(first)
    # the project's own measurement folder is an input
    code, _, err = _run(capsys, [field, "--guided", prj, "--output", first, "--force"])
    assert code == 2 and len(err) == 1 and "image points" in err[0], err
    assert _listing(first) == before
    # a station without an image
    (tmp_path / "images" / "S4.png").rename(tmp_path / "S4.png")
    code, _, err = _run(capsys, [field, "--guided", prj])
    assert code == 2 and len(err) == 1 and "no image for station S4" in err[0], err
    assert not (tmp_path / "results-guided").exists()
    (tmp_path / "S4.png").rename(tmp_path / "images" / "S4.png")
    # a first measurement corrected for eccentricity
    (first / "summary.json").write_text(json.dumps({"eccentricity_correction": True}))
    code, _, err = _run(capsys, [field, "--guided", prj])
    assert code == 2 and len(err) == 1 and "twice" in err[0], err
    assert not (tmp_path / "results-guided").exists()
    # a project without [targets]
    other = _setup(tmp_path / "plain", scene, targets=False)
    code, _, err = _run(capsys, [other.parent / "field.toml", "--guided", other])
    assert code == 2 and len(err) == 1 and "[targets]" in err[0], err
    assert not (other.parent / "results-guided").exists()
