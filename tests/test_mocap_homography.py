"""Camera rotation differences from images (photogram.mocap.motion.homography and
rotation_series) on rendered simulated frames, filtering, checks, files and
video input (photogram.mocap.motion.video)."""

import cv2
import numpy as np
import pytest

from photogram.errors import GeometryError, InputError
from photogram.geometry import rodrigues_to_matrix
from photogram.mocap.motion.homography import RotationDifferences, rotation_differences
from photogram.mocap.motion.rotation_series import (check_rotation_differences,
                                                    filter_rotation_differences,
                                                    read_rotation_differences,
                                                    rotation_difference_errors,
                                                    write_rotation_differences)
from photogram.mocap.motion.video import count_frames, read_frames
from photogram.simulation.ski.render import build_scene, render_camera, write_video

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

FRAMES = list(range(100, 130))          # 30 frames (mocap_fixtures.RENDER_FRAMES)
WIDE, ZOOMED = 2, 0                     # C3 (f ~ 4000 px) and C1 (f ~ 13000 px)


@pytest.fixture(scope="module")
def sim():
    # shared with test_mocap_lagged_differences (tests/mocap_fixtures.py): the
    # same session, scene, frames and measurements, rendered and measured once
    from mocap_fixtures import ski_session
    return ski_session()[0]


@pytest.fixture(scope="module")
def boxes(sim):
    from mocap_fixtures import ski_boxes
    return ski_boxes()


@pytest.fixture(scope="module")
def images(sim):
    from mocap_fixtures import release_images, ski_images
    yield ski_images()
    release_images("test_mocap_homography")


def _estimate(sim, images, boxes, cam, **kw):
    from mocap_fixtures import ski_measured
    return ski_measured(cam, **kw)


@pytest.mark.parametrize("cam", [WIDE, ZOOMED])
def test_rotation_differences_match_the_truth(sim, images, boxes, cam):
    rd = _estimate(sim, images, boxes, cam)
    assert rd.frames == 30 and rd.pairs == 29 and rd.failed == 0
    assert rd.median_inliers > 150
    err = rotation_difference_errors(rd.dR, sim.cameras.R[FRAMES, cam])
    # measured: pan/tilt 0.0002-0.0015 deg, roll 0.005-0.007 deg (narrow views)
    assert err["x"]["median"] < 0.005 and err["y"]["median"] < 0.005
    assert err["z"]["median"] < 0.02 and err["angle"]["p95"] < 0.05
    # the true differences are 0.1-0.5 deg: the estimate is not trivially identity
    still = rotation_difference_errors(np.repeat(np.eye(3)[None], 29, 0),
                                       sim.cameras.R[FRAMES, cam])
    assert still["angle"]["median"] > 0.05
    assert "0 failed" in check_rotation_differences(rd, "C3")


def test_the_homography_projection_of_eq13_is_worse_on_narrow_views(sim, images, boxes):
    rd = _estimate(sim, images, boxes, ZOOMED, method="homography")
    err = rotation_difference_errors(rd.dR, sim.cameras.R[FRAMES, ZOOMED])
    assert err["angle"]["median"] > 0.05      # ~0.5 deg: the perspective terms are weak


def test_featureless_camera_is_reported_by_name(sim, boxes):
    blank = build_scene(sim, texture=False)
    frames = list(range(0, 279, 40))
    imgs = render_camera(blank, sim, 4, frames)
    rd = rotation_differences(imgs, "opencv", sim.cameras.io[4][frames], 0.5, boxes[frames, 4])
    assert rd.failed == rd.pairs and np.all(np.isnan(rd.dR))
    with pytest.raises(GeometryError, match=r"camera C5: 6 of 6 frame pairs have fewer than 30"):
        check_rotation_differences(rd, "C5")
    with pytest.raises(GeometryError):
        filter_rotation_differences(rd.dR, rd.ok)


def test_filter_removes_outliers_and_fills_failed_pairs():
    rng = np.random.default_rng(1)
    n = 200
    t = np.arange(n)
    truth = np.radians(np.stack([0.3 * np.sin(t / 30), 0.2 * np.cos(t / 45), 0.01 + 0 * t], -1))
    raw = truth + np.radians(rng.normal(0, 0.002, (n, 3)))
    spikes = rng.choice(n, 12, replace=False)
    raw[spikes] += np.radians(rng.choice([-2.0, 2.0], (12, 3)))
    ok = np.ones(n, bool)
    ok[[5, 6, 7, 90, 150]] = False
    dR = rodrigues_to_matrix(raw)
    dR[~ok] = np.nan
    R = np.empty((n + 1, 3, 3))                 # rotations whose differences are the truth
    R[0] = np.eye(3)
    for k in range(n):
        R[k + 1] = rodrigues_to_matrix(truth[k]) @ R[k]
    before = rotation_difference_errors(dR, R)
    out = filter_rotation_differences(dR, ok)
    after = rotation_difference_errors(out, R)
    assert after["n"] == n and np.all(np.isfinite(out))
    assert before["angle"]["p95"] > 1.0            # spikes of ~3.5 deg
    assert after["angle"]["p95"] < 0.01 and after["angle"]["median"] < 0.005
    # a break: segments are filtered apart, the crossing pair is left as it is
    seg = filter_rotation_differences(dR, ok, breaks=[100])
    assert np.array_equal(seg[99], dR[99])
    assert np.allclose(seg[:99], filter_rotation_differences(dR[:99], ok[:99]))


def _rd(n=6, fail=2):
    r = np.radians(np.column_stack([np.linspace(0, 0.3, n), np.full(n, 0.1), np.zeros(n)]))
    dR = rodrigues_to_matrix(r)
    ok = np.ones(n, bool)
    ok[fail] = False
    dR[fail] = np.nan
    return RotationDifferences(dR, np.arange(n) + 40, np.arange(n) + 50, ok, 0.1, n + 1)


def test_rotation_files_round_trip_and_bad_rows(tmp_path):
    path = tmp_path / "rotations.csv"
    cams = {"C1": _rd(), "C2": _rd(fail=4)}
    write_rotation_differences(path, cams)
    back = read_rotation_differences(path, ["C1", "C2"], 7)
    for name, rd in cams.items():
        good = rd.ok
        assert np.allclose(back[name].dR[good], rd.dR[good], atol=1e-10)
        assert np.all(np.isnan(back[name].dR[~good]))
        assert np.array_equal(back[name].ok, rd.ok)
        assert np.array_equal(back[name].inliers, rd.inliers)
    lines = path.read_text().splitlines()
    lines[3] = lines[3].replace(",C1,", ",C1,x")
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"rotations\.csv:4: malformed"):
        read_rotation_differences(path, ["C1", "C2"], 7)
    with pytest.raises(InputError, match="unknown camera 'C2'"):
        write_rotation_differences(path, cams)
        read_rotation_differences(path, ["C1"], 7)
    with pytest.raises(InputError, match="lacks"):
        read_rotation_differences(path, ["C1", "C2"], 9)
    with pytest.raises(InputError, match="no such file"):
        read_rotation_differences(tmp_path / "missing.csv", ["C1"], 7)


def test_video_round_trip(tmp_path, images):
    frames = images[WIDE][:5]
    path = tmp_path / "c3.avi"
    assert write_video(path, frames, 50.0) == 5
    assert count_frames(path) == 5
    back = list(read_frames(path))
    assert len(back) == 5 and back[0].shape == frames[0].shape
    for a, b in zip(frames, back):
        assert np.abs(a.astype(int) - b.astype(int)).mean() < 6      # MJPG is lossy
    assert [f.shape for f in read_frames(path, [1, 3])] == [frames[0].shape] * 2
    assert not list(tmp_path.glob(".*"))                               # no temporary left
    folder = tmp_path / "images"
    folder.mkdir()
    for k, img in enumerate(frames):
        cv2.imwrite(str(folder / f"f{k + 8}.png"), img)                # f8 ... f12
    assert count_frames(folder) == 5
    back = list(read_frames(folder))
    assert all(np.array_equal(a, b) for a, b in zip(frames, back))     # f8 before f10


def test_bad_video_input(tmp_path):
    with pytest.raises(InputError, match="no such video file or image folder") as e:
        list(read_frames(tmp_path / "nothing.mp4"))
    assert "nothing.mp4" in str(e.value)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="holds no images"):
        count_frames(empty)
    junk = tmp_path / "junk.mp4"
    junk.write_bytes(b"not a video")
    with pytest.raises(InputError, match="cannot read this video"):
        list(read_frames(junk))
    (empty / "a.png").write_bytes(b"not an image")
    with pytest.raises(InputError, match=r"a\.png: OpenCV cannot read this image"):
        list(read_frames(empty))
    with pytest.raises(InputError, match="no images to write"):
        write_video(tmp_path / "x.avi", [], 25)
