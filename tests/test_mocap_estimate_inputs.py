"""``rotation = "estimate"``: what the project must give and what the 2D
metrics compare (issue 22, item 5).

Stations need only their projection centres (the angles may be absent or
empty and are not used); the detections are compared with the truth
projected through the true cameras (``truth_rotations``), never through the
estimated ones; offsets cannot be estimated without rotations. A short
SIMULATED run (30 frames, seed 5) with the true rotation differences keeps
every reconstruction to a few seconds.
"""

import json

import numpy as np
import pytest

from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.motion.homography import RotationDifferences
from photogram.mocap.motion.rotation_series import write_rotation_differences
from photogram.simulation.ski.simproject import write_estimate_project, write_simulated_project
from photogram.simulation.ski.simulate import simulate_session
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

FRAMES = 30
DETECTION_KEYS = ("pck_detections", "mpjpe_2d_px_detections", "mpjpe_2d_normalized_detections")
REPROJECTED_KEYS = ("pck_reprojected", "mpjpe_2d_px_reprojected",
                    "mpjpe_2d_normalized_reprojected")


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """The project folder (``ski.prj`` known rotations, ``ski-estimate.prj``
    estimated) with the true rotation differences, and the simulation."""
    folder = tmp_path_factory.mktemp("estimate-inputs")
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=FRAMES)
    write_simulated_project(sim, folder, name="ski")
    write_estimate_project(sim, folder, name="ski")
    R = sim.cameras.R
    P = FRAMES - 1
    per = {name: RotationDifferences(R[1:, c] @ np.swapaxes(R[:-1, c], -1, -2),
                                     np.full(P, 100), np.full(P, 120), np.ones(P, bool), 0.0,
                                     FRAMES)
           for c, name in enumerate(sim.cameras.names)}
    write_rotation_differences(folder / "rotation_differences.csv", per)
    return folder, sim


def _variant(folder, name, prj="ski-estimate.prj", edits=(), stations=None):
    """A copy of ``prj`` writing ``results-<name>``, with text ``edits``
    and optionally its own stations table (text)."""
    text = (folder / prj).read_text()
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    text = text.replace('folder = "results-estimate"', f'folder = "results-{name}"')
    text = text.replace('folder = "results"\n', f'folder = "results-{name}"\n')
    if stations is not None:
        (folder / f"stations-{name}.csv").write_text(stations)
        text = text.replace('file = "stations.csv"', f'file = "stations-{name}.csv"')
    path = folder / f"{name}.prj"
    path.write_text(text)
    return path


def _run(folder, name, **kw):
    prj = _variant(folder, name, **kw)
    assert main(["mocap", "--no-report", "--no-figures", str(prj), "-q", "--force"]) == 0
    return folder / f"results-{name}"


def _stations(folder, angles):
    """The stations table with ``angles(row, omega, phi, kappa)`` -> cells
    (None: the angle columns left out)."""
    out = []
    for line in (folder / "stations.csv").read_text().splitlines():
        if line.startswith("#"):
            out.append(line)
            continue
        cells = line.split(",")
        if angles is None:
            out.append(",".join(cells[:5]))
        elif cells[0] == "station":
            out.append(line)
        else:
            out.append(",".join(cells[:5] + angles(cells[0], cells[5:])))
    return "\n".join(out) + "\n"


@pytest.fixture(scope="module")
def runs(simulated):
    """Results folders of the estimate with the stations' true angles, with
    centres only (no angle columns), with zero angles, and with the angles
    of C1 only (the others' cells empty)."""
    folder, _ = simulated
    return {
        "angles": _run(folder, "angles"),
        "centres": _run(folder, "centres", stations=_stations(folder, None)),
        "zero": _run(folder, "zero", stations=_stations(folder, lambda s, a: ["0", "0", "0"])),
        "c1-only": _run(folder, "c1-only", stations=_stations(
            folder, lambda s, a: a if s == "C1" else ["", "", ""])),
    }


def test_centres_only_give_the_result_of_the_angles(runs):
    ref = runs["angles"]
    for name in ("centres", "zero", "c1-only"):
        for table in ("joints3d.csv", "rotations.csv", "metrics.csv"):
            assert (runs[name] / table).read_bytes() == (ref / table).read_bytes(), (name, table)
    # the rotations are estimated, not taken from the stations: close to the truth
    rot = json.loads((ref / "summary.json").read_text())["rotation"]["rotation_errors"]
    assert rot["all"]["median_deg"] < 1.0, rot


def test_given_angles_are_reported_as_not_used(runs):
    def note(name):
        return [ln for ln in (runs[name] / "log.txt").read_text().splitlines()
                if "are not used" in ln]
    assert len(note("angles")) == 1 and "C1, C2, C3, C4, C5, C6" in note("angles")[0]
    assert len(note("c1-only")) == 1 and "station(s) C1 are not used" in note("c1-only")[0]
    assert note("centres") == []


def test_detection_metrics_use_the_true_cameras(simulated, runs):
    folder, sim = simulated
    est = json.loads((runs["angles"] / "summary.json").read_text())["accuracy"]
    known_dir = _run(folder, "known", prj="ski.prj", edits=[(
        "[mocap.source]", "[mocap.tracking]\nmultiview = false\n\n[mocap.source]")])
    known = json.loads((known_dir / "summary.json").read_text())["accuracy"]
    for key in DETECTION_KEYS:                 # the same detections, the same true cameras
        assert est[key] == pytest.approx(known[key], abs=1e-9, rel=0), key
    # and what the simulator's noise-free projections say (detections written to 0.01 px)
    rows = [ln.split(",") for ln in (known_dir / "detections.csv").read_text().splitlines()
            if ln and not ln.startswith("#")]
    col = {k: i for i, k in enumerate(rows[0])}
    rows = rows[1:]
    f = np.array([int(r[col["frame"]]) for r in rows])
    c = np.array([sim.cameras.names.index(r[col["camera"]]) for r in rows])
    j = np.array([SKI24.index(r[col["joint"]]) for r in rows])
    xy = np.array([[float(r[col["x"]]), float(r[col["y"]])] for r in rows])
    expected = np.mean(np.linalg.norm(xy - sim.image_truth[f, c, j], axis=-1))
    assert est["mpjpe_2d_px_detections"] == pytest.approx(expected, abs=0.01)
    assert est["cameras_2d"]["detections"].startswith("true")
    assert est["cameras_2d"]["reprojected"].startswith("estimated")
    assert "cameras_2d" not in known


def test_without_truth_rotations_the_detection_metrics_are_left_out(simulated, runs):
    folder, _ = simulated
    out = _run(folder, "no-truth-rotations", edits=[(
        'truth_rotations = "camera_frames.csv"', '# truth_rotations = "camera_frames.csv"')])
    acc = json.loads((out / "summary.json").read_text())["accuracy"]
    with_truth = json.loads((runs["angles"] / "summary.json").read_text())["accuracy"]
    assert not any(k in acc for k in DETECTION_KEYS), acc
    assert acc["cameras_2d"]["detections"].startswith("not computed")
    for key in REPROJECTED_KEYS:        # the estimated cameras: truth_rotations changes nothing
        assert acc[key] == with_truth[key], key


def _one_line_error(capsys, argv, *parts):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    for part in parts:
        assert part in err[0], (part, err[0])
    return err[0]


@pytest.mark.parametrize("mode", ["estimate", "report"])
def test_estimated_offsets_need_known_rotations(simulated, capsys, mode):
    folder, _ = simulated
    prj = _variant(folder, f"offsets-{mode}", edits=[(
        'rotation = "estimate"', f'rotation = "estimate"\noffsets = "{mode}"')])
    for command in ("check", "mocap"):
        _one_line_error(capsys, [command, str(prj)], f"offsets-{mode}.prj:", f'"{mode}"',
                        'rotation = "estimate"', "offsets = {")


def test_offsets_table_with_estimated_rotations_is_accepted_with_a_warning(simulated):
    folder, _ = simulated
    out = _run(folder, "offsets-table", edits=[(
        'rotation = "estimate"', 'rotation = "estimate"\noffsets = { C2 = 1 }')])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["synchronisation"]["applied"] == {"C2": 1.0}
    assert any(w.startswith("offsets applied to the detections and the zoom only")
               for w in summary["warnings"]), summary["warnings"]


def test_a_station_without_its_centre_is_one_line(simulated, capsys):
    folder, _ = simulated
    text = "\n".join(",".join(ln.split(",")[:2] + ["", "", ""]) if ln.startswith("C3,") else ln
                     for ln in _stations(folder, None).splitlines()) + "\n"
    prj = _variant(folder, "no-centre", stations=text)
    line = 1 + next(k for k, ln in enumerate(text.splitlines()) if ln.startswith("C3,"))
    _one_line_error(capsys, ["mocap", str(prj), "--force"], f"stations-no-centre.csv:{line}:",
                    "station C3 needs its position")


def test_known_rotations_still_need_the_angles(simulated, capsys):
    folder, _ = simulated
    prj = _variant(folder, "known-centres", prj="ski.prj", stations=_stations(folder, None))
    _one_line_error(capsys, ["mocap", str(prj), "--force"], "stations-known-centres.csv:",
                    "station C1 needs its position and angles", 'rotation = "estimate"')
