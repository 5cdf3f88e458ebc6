"""``photogram mocap``: project files, the command line, results folder, the
simulated example project and Pose2Sim's demo (read in place when present)."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from photogram.io.trc import read_trc
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.files import read_joints
from photogram.project import read_project
from photogram.simulation.ski.simproject import write_simulated_project
from photogram.simulation.ski.simulate import simulate_session
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
POSE2SIM = ROOT.parent / "shared" / "data" / "pose2sim-demo"


@pytest.fixture(scope="module")
def small_project(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ski")
    sim = simulate_session(seed=5, n_runs=2, frames_per_run=60)
    write_simulated_project(sim, folder, name="ski")
    return folder / "ski.prj", sim


@pytest.mark.filterwarnings("ignore:No analog data")
def test_mocap_command_writes_the_results_folder(small_project, capsys):
    prj, sim = small_project
    assert main(["mocap", "--no-report", str(prj)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("mocap: 120 frames x 6 cameras x 24 joints (ski24)") and "MPJPE" in out
    res = prj.parent / "results"
    for name in ("joints3d.csv", "joints3d.trc", "joints3d.c3d", "metrics.csv",
                 "detections.csv", "reprojection.csv", "bones.csv", "summary.json", "log.txt",
                 "trajectory.png", "angles.png", "reprojection.png", "skeletons.png"):
        assert (res / name).is_file(), name
    s = json.loads((res / "summary.json").read_text())
    assert s["figures"] is True                     # drawn (not --no-figures)
    assert s["counts"] == {"frames": 120, "cameras": 6, "joints": 24,
                           "detections": s["counts"]["detections"], "runs": 2}
    assert s["accuracy"]["mpjpe"] < 0.03 and s["accuracy"]["knee_flexion_mae"] < 3.0
    assert s["reconstruction"]["stages"][-1]["sigma2"] == 400.0   # the default (px^2)
    frames, X = read_joints(res / "joints3d.csv", SKI24)
    assert frames.tolist() == list(range(120))
    assert np.nanmax(np.abs(X - sim.joints)) < 0.3
    trc = read_trc(res / "joints3d.trc", rotate_to_z_up=True)
    assert np.allclose(trc.markers["r_knee"], X[:, SKI24.index("r_knee")], atol=1e-5)
    raw = read_trc(res / "joints3d.trc")            # Y up: (Y, Z, X)
    assert np.allclose(raw.markers["head"][:, 1], X[:, 0, 2], atol=1e-5)
    import c3d
    with open(res / "joints3d.c3d", "rb") as handle:
        frames3d = [p for _, p, _ in c3d.Reader(handle).read_frames()]
    assert len(frames3d) == 120
    assert np.allclose(frames3d[0][0, :3] / 1000, X[0, 0], atol=1e-4)
    metrics = (res / "metrics.csv").read_text().splitlines()
    assert metrics[1].startswith("frame,time,com_x,com_y,com_z,speed,knee_flexion_r")
    assert "reconstruction:" in (res / "log.txt").read_text()


def test_check_reads_a_mocap_project(small_project, capsys):
    prj, _ = small_project
    assert main(["check", str(prj)]) == 0
    p = read_project(prj)
    assert p.mocap.source.kind == "csv" and p.mocap.runs == (60,) and len(p.cameras) == 6


@pytest.mark.parametrize("edit, message", [
    (('skeleton = "ski24"\ncamera_frames', 'skeleton = "ski99"\ncamera_frames'),
     "unknown skeleton 'ski99'"),
    (('path = "detections.csv"', 'path = "nothing.csv"'), "file nothing.csv not found"),
    (("fps = 50", "fps = 50\nfsp = 3"), "unknown key 'fsp'"),
    (('kind = "csv"', 'kind = "cvs"'), "unknown kind 'cvs'"),
    (("[stations]", "[observations]\npoints = 'x.csv'\n\n[stations]"),
     "[observations] has no meaning in a motion-capture project"),
])
def test_bad_input_is_one_line_and_exit_2(small_project, tmp_path, capsys, edit, message):
    prj, _ = small_project
    for f in prj.parent.iterdir():
        if f.is_file():
            shutil.copy(f, tmp_path / f.name)
    (tmp_path / "truth").mkdir()
    shutil.copy(prj.parent / "truth" / "joints3d.csv", tmp_path / "truth" / "joints3d.csv")
    text = (tmp_path / "ski.prj").read_text()
    assert edit[0] in text
    (tmp_path / "ski.prj").write_text(text.replace(edit[0], edit[1], 1))
    assert main(["mocap", "--no-report", str(tmp_path / "ski.prj")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "ski.prj:" in err


def test_example_project_is_reproducible(tmp_path):
    """projects/ski-ptz is exactly what its generator writes."""
    import runpy
    committed = ROOT / "projects" / "ski-ptz"
    runpy.run_path(str(committed / "generate.py"), run_name="gen")["main"](
        ["--out", str(tmp_path), "--no-differences"])
    for f in ("ski-ptz.prj", "stations.csv", "camera_frames.csv", "detections.csv",
              "truth/joints3d.csv", "truth/outliers.csv"):
        assert (tmp_path / f).read_bytes() == (committed / f).read_bytes(), f
    text = (committed / "ski-ptz.prj").read_text()
    assert text.startswith("# SIMULATED data")


@pytest.mark.skipif(not (POSE2SIM / "Calib_qualisys.toml").is_file(),
                    reason="../shared/data/pose2sim-demo is absent")
def test_pose2sim_demo_main_person_and_reference():
    from mocap_fixtures import pose2sim_demo_run
    r = pose2sim_demo_run()                     # run_mocap of demo.prj as shipped
    assert r.observations.shape == (100, 4, 25, 3) and r.skeleton.name == "body25b"
    # the bystanders (left of camera 1, right of camera 2) are never chosen
    assert np.nanmax(r.tracked[0].detected[:, 2]) > 300
    assert np.all(r.tracked[1].detected[:, 0] < 700)
    ref = r.reference
    assert ref["frames"] == 100 and len(ref["joints"]) == 21
    # ours 8.8, 7.7, 6.6 px with the default sigma^2 = 400 px^2 (7.4, 6.8, 5.2
    # with the paper's 100 px^2), Pose2Sim's 11.9, 8.1, 8.8 px (docs/mocap.md 10)
    for cam in ("cam_01", "cam_02", "cam_04"):
        v = ref["reprojection"][cam]
        assert v["ours_median_px"] < 10 and v["reference_median_px"] > v["ours_median_px"]
    assert ref["bone_cv_mean"]["ours"] < 0.10
    assert ref["mpjpe_to_reference"] < 0.05
