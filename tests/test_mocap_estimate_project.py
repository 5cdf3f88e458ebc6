"""``photogram mocap`` with ``rotation = "estimate"`` (issue 9): rotations from
rendered videos read with OpenCV, a camera without background features
reported, the estimated rotations written, and the project errors."""

import json
from pathlib import Path

import numpy as np
import pytest

from photogram.mocap.motion.rotation_series import read_rotation_differences
from photogram.simulation.ski.render import render_camera, write_video
from photogram.simulation.ski.scene import build_scene
from photogram.simulation.ski.simproject import write_estimate_project, write_simulated_project
from photogram.simulation.ski.simulate import simulate_session
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

FRAMES = 30
FEATURELESS = 1          # camera C2 films uniform snow and sky


@pytest.fixture(scope="module")
def video_project(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ski-estimate")
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=FRAMES)
    write_simulated_project(sim, folder, name="ski")
    prj = write_estimate_project(sim, folder, name="ski")
    (folder / "video").mkdir()
    textured, blank = build_scene(sim, seed=0), build_scene(sim, seed=0, texture=False)
    lines = ["", "[mocap.images]"]
    for c, name in enumerate(sim.cameras.names):
        scene = blank if c == FEATURELESS else textured
        write_video(folder / "video" / f"{name}.avi", render_camera(scene, sim, c), 50)
        lines.append(f'{name} = "video/{name}.avi"')
    text = prj.read_text().replace(
        'rotation_differences = "rotation_differences.csv"   # measured on rendered images\n',
        "")
    prj.write_text(text + "\n".join(lines) + "\n")
    return prj, sim


def test_estimate_from_videos_reports_the_featureless_camera(video_project):
    prj, sim = video_project
    assert main(["mocap", "--no-report", "--no-figures", str(prj), "-q"]) == 0
    out = prj.parent / "results-estimate"
    summary = json.loads((out / "summary.json").read_text())
    rot = summary["rotation"]
    assert rot["cameras"]["C2"]["used"] is False
    assert all(rot["cameras"][n]["used"] for n in ("C1", "C3", "C4", "C5", "C6"))
    assert any("camera C2" in w and "background inliers" in w for w in summary["warnings"])
    # the rotations of the cameras with measured differences are close to the truth
    errs = rot["rotation_errors"]
    for name in ("C1", "C3", "C4", "C5", "C6"):
        assert errs[name]["median_deg"] < 0.5, (name, errs[name])
    assert summary["accuracy"]["mpjpe"] < 0.3
    assert summary["accuracy"]["mpjpe_hip"] < 0.05
    # the measured differences and the rotations are written
    per = read_rotation_differences(out / "rotation_differences.csv", sim.cameras.names, FRAMES)
    assert per["C1"].failed == 0 and per["C2"].failed == per["C2"].pairs
    rows = (out / "rotations.csv").read_text().splitlines()
    assert rows[1].startswith("frame,camera,omega,phi,kappa")
    assert len(rows) == 2 + FRAMES * 6


def test_estimated_rotations_feed_back_as_known(video_project, tmp_path):
    prj, sim = video_project
    out = prj.parent / "results-estimate"
    if not (out / "rotations.csv").is_file():
        main(["mocap", "--no-report", "--no-figures", str(prj), "-q"])
    known = prj.parent / "known.prj"
    text = (prj.parent / "ski.prj").read_text().replace(
        'camera_frames = "camera_frames.csv"', 'camera_frames = "results-estimate/rotations.csv"')
    known.write_text(text.replace('folder = "results"', 'folder = "results-known"'))
    assert main(["mocap", "--no-report", "--no-figures", str(known), "-q"]) == 0
    summary = json.loads((prj.parent / "results-known" / "summary.json").read_text())
    assert summary["accuracy"]["mpjpe"] < 0.3


@pytest.mark.parametrize("edit, message", [
    (('rotation = "estimate"', 'rotation = "guess"'), "rotation"),
    (('rotation_differences = "rotation_differences.csv"   # measured on rendered images\n',
      ''), "needs the camera images or measured rotation differences"),
    (('[mocap.source]', '[mocap.homography]\nn_feature = 10\n\n[mocap.source]'), "n_feature"),
    (('[mocap.source]', '[mocap.reconstruction]\npose_basis = "spline"\n\n[mocap.source]'),
     "pose_basis"),
])
def test_estimate_project_errors_are_one_line(tmp_path, capsys, edit, message):
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=30)
    write_simulated_project(sim, tmp_path, name="ski")
    prj = write_estimate_project(sim, tmp_path, name="ski")
    (tmp_path / "rotation_differences.csv").write_text(
        "frame,camera,rx,ry,rz,inliers,matches,ok\n")
    prj.write_text(prj.read_text().replace(*edit))
    assert main(["check", str(prj)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and "ski-estimate.prj" in err[0], err


def test_malformed_rotation_differences_is_one_line(tmp_path, capsys):
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=30)
    write_simulated_project(sim, tmp_path, name="ski")
    prj = write_estimate_project(sim, tmp_path, name="ski")
    (tmp_path / "rotation_differences.csv").write_text(
        "frame,camera,rx,ry,rz,inliers,matches,ok\n0,C1,0.1,zero,0,40,50,1\n")
    assert main(["mocap", "--no-report", str(prj)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rotation_differences.csv:2" in err[0], err


def test_example_rotation_differences_are_what_photogram_measures():
    """projects/ski-ptz/rotation_differences.csv: re-measured on the first 30
    rendered frames of C1, and close to the true differences."""
    from photogram.geometry.rotations import matrix_to_rodrigues
    from photogram.mocap.motion.homography import rotation_differences
    from photogram.mocap.motion.rotation_series import rotation_difference_errors
    from photogram.simulation.ski.simimages import detection_boxes
    root = Path(__file__).resolve().parents[1] / "projects" / "ski-ptz"
    from mocap_fixtures import ski_session      # seed 8 and its scene (texture seed 0), shared
    sim, scene = ski_session()
    per = read_rotation_differences(root / "rotation_differences.csv", sim.cameras.names, 279)
    rd = rotation_differences(render_camera(scene, sim, 0, frames=range(30)),
                              "opencv", sim.cameras.io[0][:30], image_scale=0.5,
                              boxes=detection_boxes(sim.observations, 0)[:30])
    a = np.degrees(matrix_to_rodrigues(rd.dR))
    b = np.degrees(matrix_to_rodrigues(per["C1"].dR[:29]))
    assert np.max(np.abs(a - b)) < 1e-6
    for c, name in enumerate(sim.cameras.names):
        err = rotation_difference_errors(per[name].dR, sim.cameras.R[:, c])
        assert err["angle"]["median"] < 0.02, (name, err)
