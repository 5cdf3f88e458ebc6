"""The lab chain with the eccentricity inside the adjustment and guided
measurement from the bundle, on the rendered lab photographs (projects/lab,
truth in projects/lab/truth/):

1. ``photogram measure frame.toml --no-eccentricity`` writes ellipse
   centres and ``targets.toml`` (the field's diameter and normal);
2. a copy of lab.prj with that ``[targets]`` (the ArUco markers given
   diameter 0 in the points table) calibrates with the correction on;
3. ``photogram measure frame.toml --guided lab-targets.prj`` adds
   observations, none wrong, into results-guided/ (lab.prj's own
   results-measure/ untouched)."""

import json
import tomllib

import numpy as np
import pytest

from lab_stage import LAB
from photogram.bundle import adjust
from photogram.measure.compare import compare_tables
from photogram.measure.field import read_field
from photogram.measure.scenes import _rows
from photogram.project import read_project
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    import shutil
    dest = tmp_path_factory.mktemp("targets") / "lab"
    shutil.copytree(LAB, dest, ignore=shutil.ignore_patterns("results", "results-*", ".*"))
    assert main(["measure", str(dest / "frame.toml"), "--no-eccentricity", "--no-report",
                 "-q"]) == 0
    snippet = (dest / "results-measure" / "targets.toml").read_text()
    markers = set(read_field(dest / "frame.toml").marker_xyz)
    lines = []
    for line in (dest / "lab_points.csv").read_text().splitlines():
        if line.startswith("#"):
            lines.append(line)
        elif line.startswith("id,"):
            lines.append(line + ",diameter")
        else:                                   # markers 0, dots: the [targets] default
            lines.append(line + ("," + ("0" if line.split(",")[0] in markers else "")))
    (dest / "lab_points.csv").write_text("\n".join(lines) + "\n")
    text = (dest / "lab.prj").read_text().replace('folder = "results"',
                                                  'folder = "results-targets"')
    (dest / "lab-targets.prj").write_text(text + "\n" + snippet)
    return dest


def test_no_eccentricity_writes_targets_toml(lab):
    out = lab / "results-measure"
    doc = tomllib.loads((out / "targets.toml").read_text())
    assert doc == {"targets": {"diameter": 0.016, "normal": [0, 0, 1]}}
    text = (out / "targets.toml").read_text()
    for m in read_field(lab / "frame.toml").marker_xyz:
        assert m in text                               # named: not circles
    assert json.loads((out / "summary.json").read_text())["eccentricity_correction"] is False


def test_with_eccentricity_no_targets_toml(tmp_path):
    import shutil
    dest = tmp_path / "lab"
    shutil.copytree(LAB, dest, ignore=shutil.ignore_patterns("results", "results-*", ".*"))
    assert main(["measure", str(dest / "frame.toml"), "--no-report", "-q"]) == 0
    out = dest / "results-measure"
    assert not (out / "targets.toml").exists()
    assert json.loads((out / "summary.json").read_text())["eccentricity_correction"] is True


def test_project_with_the_snippet_calibrates_with_the_correction(lab):
    prj = read_project(lab / "lab-targets.prj")
    radius, normal = prj.targets.for_points(prj.points.ids)
    markers = set(read_field(lab / "frame.toml").marker_xyz)
    is_marker = np.array([p in markers for p in prj.points.ids])
    assert prj.targets.eccentricity
    assert np.allclose(radius[~is_marker], 0.008) and np.isnan(radius[is_marker]).all()
    assert np.allclose(normal[~is_marker], [0, 0, 1])
    assert main(["calibrate", str(lab / "lab-targets.prj"), "--no-report", "-q"]) == 0
    assert (lab / "results-targets" / "summary.json").is_file()
    with_ = adjust(prj)
    without = adjust(read_project(lab / "lab.prj"))
    true = {r["camera"]: r for r in _rows(LAB / "truth" / "cameras.csv")}
    moved = []
    for cam in ("K1", "K2", "K3"):
        for p in ("c", "x0", "y0"):
            v = with_.project.cameras[cam].parameters[p].value
            s = with_.camera_sigma[cam][p]
            assert abs(v - float(true[cam][p])) < 3 * s
            moved.append(abs(v - without.project.cameras[cam].parameters[p].value))
    assert with_.summary["status"] == "converged"
    assert max(moved) > 0.005                          # the correction is applied


def test_guided_run_on_the_lab(lab):
    truth = LAB / "truth" / "image_points.csv"
    first = compare_tables(lab / "results-measure" / "image_points.csv", truth)
    before = sorted(p.stat().st_mtime_ns for p in (lab / "results-measure").iterdir())
    assert main(["measure", str(lab / "frame.toml"), "--guided",
                 str(lab / "lab-targets.prj"), "-q"]) == 0
    assert sorted(p.stat().st_mtime_ns for p in (lab / "results-measure").iterdir()) == before
    out = lab / "results-guided"
    c = compare_tables(out / "image_points.csv", truth)
    summary = json.loads((out / "summary.json").read_text())
    print(f"first {first.matched}/{first.n_reference} RMS {first.rms:.4f}; guided "
          f"{c.matched}/{c.n_reference} RMS {c.rms:.4f}, rounds {summary['rounds']}")
    assert c.n_measured == summary["observations"] == c.matched        # all true targets
    assert c.matched >= first.matched + 10 and not c.wrong and not c.extra
    tr = {(r["station"], r["point"]): (float(r["x"]), float(r["y"])) for r in _rows(truth)}
    err = [np.hypot(float(r["x"]) - tr[r["station"], r["point"]][0],
                    float(r["y"]) - tr[r["station"], r["point"]][1])
           for r in _rows(out / "guided.csv")]
    assert len(err) == c.matched - first.matched and max(err) < 0.15
    assert c.rms < 0.04
    # lab.prj reads results-measure/: the guided run never writes there
    code = main(["measure", str(lab / "frame.toml"), "--guided", str(lab / "lab-targets.prj"),
                 "--output", str(lab / "results-measure"), "--force", "-q"])
    assert code == 2
    assert sorted(p.stat().st_mtime_ns for p in (lab / "results-measure").iterdir()) == before
