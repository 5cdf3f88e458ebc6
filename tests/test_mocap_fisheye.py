"""Fisheye cameras in motion capture: a Pose2Sim/anipose calibration file
with ``fisheye = true`` (as ``photogram calibrate`` writes it for
``model = "opencv_fisheye"``) read into projects and mocap cameras, and a
reconstruction through them (SIMULATED skier, cameras checked against
``cv2.fisheye.projectPoints``)."""

import cv2
import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import camera_model
from photogram.io.exchange import View
from photogram.io.pose2sim import pose2sim_project, read_pose2sim, write_pose2sim
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.files import cameras_from_views
from photogram.mocap.evaluation.metrics import accuracy_3d
from photogram.mocap.reconstruction.cameras import MocapCameras
from photogram.mocap.reconstruction.reconstruct import reconstruct
from photogram.simulation.ski.simulate import simulate_session


def _look_at_cv(C, target):
    """OpenCV world-to-camera rotation of a camera at C looking at target
    (image y down, world Z up)."""
    z = (target - C) / np.linalg.norm(target - C)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return np.array([x, np.cross(z, x), z])


def _fisheye_views(centre, n=4, radius=8.0):
    rng = np.random.default_rng(4)
    views = []
    for i in range(n):
        a = 2 * np.pi * i / n + 0.3
        C = centre + np.array([radius * np.cos(a), radius * np.sin(a), 1.5])
        R = _look_at_cv(C, centre)
        K = np.array([[rng.uniform(480, 520), 0, 640 + rng.uniform(-10, 10)],
                      [0, 0, 360 + rng.uniform(-10, 10)], [0, 0, 1.0]])
        K[1, 1] = K[0, 0] * 1.0005
        dist = np.array([rng.uniform(-0.05, 0.05), rng.uniform(-0.02, 0.02),
                         rng.uniform(-0.005, 0.005), 0.001])
        views.append(View(name=f"fe{i + 1}", camera=f"fe{i + 1}", K=K, dist=dist, R_cv=R,
                          t_cv=-R @ C, image_size=(1280, 720), extra={"fisheye": True}))
    return views


def test_fisheye_calibration_file_round_trip_projects_as_opencv(tmp_path):
    views = _fisheye_views(np.array([0.0, 0.0, 1.0]))
    path = write_pose2sim(tmp_path / "Calib_fisheye.toml", views)
    read = read_pose2sim(path)
    assert [v.extra["fisheye"] for v in read] == [True] * 4
    for v, w in zip(views, read):
        assert np.array_equal(v.dist, w.dist) and np.array_equal(v.K, w.K)
    cams = cameras_from_views(read)
    assert cams.models == ["opencv_fisheye"] * 4
    X = np.random.default_rng(1).uniform(-1.5, 1.5, (1, 40, 3)) + [0, 0, 1.0]
    xy = cams.project(X)                                   # (1, C, J, 2)
    for c, v in enumerate(views):
        ref, _ = cv2.fisheye.projectPoints(X[0][:, None, :], cv2.Rodrigues(v.R_cv)[0], v.t_cv,
                                           v.K, v.dist)
        assert np.abs(xy[0, c] - ref.reshape(-1, 2)).max() < 1e-6
    # the imported project has opencv_fisheye cameras with the file's values
    p = pose2sim_project(path)
    cam = p.cameras["fe2"]
    assert cam.model == "opencv_fisheye"
    names = camera_model("opencv_fisheye").parameter_names
    assert np.allclose([cam.parameters[n].value for n in names],
                       [*views[1].K[[0, 1, 0, 1], [0, 1, 2, 2]], *views[1].dist], rtol=0,
                       atol=1e-15)


def test_fisheye_distortions_must_be_four(tmp_path):
    views = _fisheye_views(np.zeros(3), n=2)
    path = write_pose2sim(tmp_path / "Calib.toml", views)
    text = path.read_text().replace("fisheye = true", "fisheye = 1", 1)
    bad = tmp_path / "Calib_bad.toml"
    bad.write_text(text)
    with pytest.raises(InputError, match="true or false"):
        read_pose2sim(bad)
    lines = path.read_text().splitlines()
    k = next(i for i, s in enumerate(lines) if s.startswith("distortions"))
    lines[k] = "distortions = [ 0.1, 0.0, 0.0, 0.0, 0.0]"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"\[k1, k2, k3, k4\]") as err:
        read_pose2sim(bad)
    assert err.value.line == next(i for i, s in enumerate(lines)
                                  if s.startswith("fisheye")) + 1


@pytest.mark.slow
def test_skier_reconstructed_through_fisheye_cameras():
    """Noise-free detections projected through wide fisheye cameras give
    the same skier as the same cameras made pinhole (the rays are the
    same: the fisheye adds nothing to the reconstruction's own 1.3 cm);
    with 1 px noise within 2.5 cm; the fisheye detections read as pinhole
    cameras (the distortion ignored) are off by more than 10 cm: the model
    is used."""
    sim = simulate_session(seed=3, n_runs=1, frames_per_run=30)
    truth = sim.joints
    centre = np.nanmean(truth.reshape(-1, 3), axis=0)
    cams = cameras_from_views(_fisheye_views(centre))
    pinhole = MocapCameras(cams.names, ["opencv"] * 4,
                           [np.concatenate([p[:, :4], np.zeros((1, 5))], 1) for p in cams.io],
                           cams.X0, cams.R, cams.image_size)

    def detections(c, noise):
        xy = c.project(truth)
        assert np.isfinite(xy).all()
        xy = xy + np.random.default_rng(7).normal(0, noise, xy.shape)
        return np.concatenate([xy, np.full(xy.shape[:-1] + (1,), 0.9)], axis=-1)

    exact = reconstruct(detections(cams, 0.0), cams, SKI24).joints
    same = reconstruct(detections(pinhole, 0.0), pinhole, SKI24).joints
    assert np.nanmax(np.abs(exact - same)) < 1e-5
    noisy = detections(cams, 1.0)
    assert accuracy_3d(reconstruct(noisy, cams, SKI24).joints, truth, SKI24)["mpjpe"] < 0.025
    wrong = reconstruct(noisy, pinhole, SKI24)
    assert accuracy_3d(wrong.joints, truth, SKI24)["mpjpe"] > 0.1
