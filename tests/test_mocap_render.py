"""Rendered images of the simulated ski runs (photogram.simulation.ski.render):
determinism, the skier where the camera model puts it, the background of
consecutive frames related by the true rotation homography, the exact lens
inversion."""

import cv2
import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import camera_model
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.motion.lens import pixel_rays, scaled_parameters, undistort_radius
from photogram.simulation.ski.render import build_scene, ideal_offsets, render_frame
from photogram.simulation.ski.simulate import simulate_session

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

SIZE = (960, 540)
FLIP = np.diag([1.0, -1.0, -1.0])


@pytest.fixture(scope="module")
def sim():
    return simulate_session(seed=8, n_runs=1)


@pytest.fixture(scope="module")
def scene(sim):
    return build_scene(sim, seed=3)


def test_render_is_deterministic_with_the_right_size(sim, scene):
    a = render_frame(scene, sim, 2, 40, SIZE)
    b = render_frame(scene, sim, 2, 40, SIZE)
    c = render_frame(build_scene(sim, seed=3), sim, 2, 40, SIZE)
    assert a.shape == (540, 960, 3) and a.dtype == np.uint8
    assert np.array_equal(a, b) and np.array_equal(a, c)
    assert a.std() > 10                      # not blank
    other = render_frame(build_scene(sim, seed=4), sim, 2, 40, SIZE)
    assert not np.array_equal(a, other)      # the seed matters


def test_skier_is_drawn_where_the_camera_model_projects_the_joints(sim, scene):
    cam, frame = 0, 120
    with_skier = render_frame(scene, sim, cam, frame, SIZE).astype(int)
    without = render_frame(scene, sim, cam, frame, SIZE, skier=False).astype(int)
    xy = sim.cameras.select_frames([frame]).project(sim.joints[frame:frame + 1])[0, cam]
    small = 0.5 * (xy + 0.5) - 0.5
    diff = np.abs(with_skier - without).sum(-1)
    for name in ("r_hip", "l_hip", "r_knee", "l_knee", "neck", "r_shoulder"):
        x, y = np.rint(small[SKI24.index(name)]).astype(int)
        assert diff[y, x] > 30, name
    # nothing changes far from the athlete
    x0, y0 = np.nanmin(small, 0).astype(int) - 40
    x1, y1 = np.nanmax(small, 0).astype(int) + 40
    outside = np.ones(diff.shape, bool)
    outside[max(y0, 0):y1, max(x0, 0):x1] = False
    assert diff[outside].max() == 0


def _warp_previous(prev, sim, cam, t):
    """Frame t resampled on the pixels of frame t+1 through the true rotation
    (exact lens model both ways); NaN-free mask of the valid pixels."""
    io0 = scaled_parameters(sim.cameras.io[cam][t], (1920, 1080), SIZE)
    io1 = scaled_parameters(sim.cameras.io[cam][t + 1], (1920, 1080), SIZE)
    R0, R1 = FLIP @ sim.cameras.R[t, cam], FLIP @ sim.cameras.R[t + 1, cam]
    H, W = SIZE[1], SIZE[0]
    yy, xx = np.mgrid[0:H, 0:W]
    t1 = pixel_rays(io1, np.column_stack([xx.ravel(), yy.ravel()]).astype(float))
    rays = np.column_stack([t1, np.ones(len(t1))]) @ (R0 @ R1.T).T      # frame t's camera
    t0 = rays[:, :2] / rays[:, 2:]
    xy0 = camera_model("opencv").ray_to_image(t0, io0).reshape(H, W, 2).astype(np.float32)
    warped = cv2.remap(prev, xy0[..., 0], xy0[..., 1], cv2.INTER_LINEAR)
    valid = ((xy0[..., 0] > 1) & (xy0[..., 0] < W - 2) & (xy0[..., 1] > 1)
             & (xy0[..., 1] < H - 2))
    return warped, valid


@pytest.mark.parametrize("cam,t", [(2, 60), (0, 150)])      # wide and zoomed
def test_background_moves_by_the_true_rotation_homography(sim, scene, cam, t):
    a = render_frame(scene, sim, cam, t, SIZE, skier=False)
    b = render_frame(scene, sim, cam, t + 1, SIZE, skier=False)
    warped, valid = _warp_previous(a, sim, cam, t)
    err = np.abs(warped.astype(int) - b.astype(int)).mean(-1)[valid].mean()
    still = np.abs(a.astype(int) - b.astype(int)).mean()
    assert err < 1.5, err                          # resampling only
    assert still > 4 * err                         # the camera did turn
    # a rotation wrong by 0.02 deg about the vertical is visible
    sim_bad = simulate_session(seed=8, n_runs=1)
    turn = cv2.Rodrigues(np.array([0.0, np.radians(0.02), 0.0]))[0]
    sim_bad.cameras.R[t, cam] = turn @ sim_bad.cameras.R[t, cam]
    bad, valid = _warp_previous(a, sim_bad, cam, t)
    err_bad = np.abs(bad.astype(int) - b.astype(int)).mean(-1)[valid].mean()
    assert err_bad > 1.3 * err


def test_radial_distortion_is_inverted_exactly():
    rd = np.linspace(0.0, 0.9, 2001)
    for k1, k2, k3 in [(-0.01, 0.0, 0.0), (0.08, -0.02, 0.004), (-0.2, 0.05, 0.0)]:
        ru = undistort_radius(rd, k1, k2, k3)
        r2 = ru * ru
        assert np.max(np.abs(ru * (1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3) - rd)) < 1e-12
    io = np.array([1100.0, 1090.0, 470.3, 268.9, -0.04, 0.01, 0.0, 0.0, 0.002])
    xy = np.random.default_rng(0).uniform([0, 0], [960, 540], (500, 2))
    exact = camera_model("opencv").image_to_ray(xy, io)
    assert np.max(np.abs(pixel_rays(io, xy) - exact)) < 1e-9
    # the renderer's per-pixel rays (interpolated correction): below 1e-3 px
    q = ideal_offsets(io, SIZE).astype(float)
    ij = np.rint(xy).astype(int).clip(0, [959, 539])
    t = pixel_rays(io, ij.astype(float))
    assert np.max(np.abs(q[ij[:, 1], ij[:, 0]] - t * io[:2])) < 1e-3
    with pytest.raises(InputError, match="radial"):
        pixel_rays(np.r_[io[:6], 0.001, 0.0, io[8]], xy)
