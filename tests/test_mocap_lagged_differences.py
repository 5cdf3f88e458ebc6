"""Lagged rotation differences (frames t and t+k, k > 1): the data, the
``to_frame`` column of rotation_differences.csv, their measurement on
rendered SIMULATED frames, and the arrays the solver takes."""

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import rodrigues_to_matrix
from photogram.mocap.motion.homography import LaggedDifferences, RotationDifferences
from photogram.mocap.motion.rotation_series import (read_rotation_differences,
                                                    write_rotation_differences)

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


def _rd(n=30, lags=(10, 25), seed=0, fail=3):
    """Consecutive differences of a random pan (n frames) and exact lagged ones."""
    rng = np.random.default_rng(seed)
    dR = rodrigues_to_matrix(rng.normal(0, 0.01, (n - 1, 3)))
    R = [np.eye(3)]
    for d in dR:
        R.append(d @ R[-1])
    R = np.array(R)
    first = np.concatenate([np.arange(0, n - k) for k in lags])
    second = np.concatenate([np.arange(k, n) for k in lags])
    lag = R[second] @ np.swapaxes(R[first], -1, -2)
    ok = np.ones(len(first), bool)
    ok[fail] = False
    lag[fail] = np.nan
    lagged = LaggedDifferences(first, second, lag, np.full(len(first), 90),
                               np.full(len(first), 120), ok)
    okc = np.ones(n - 1, bool)
    return RotationDifferences(dR, np.full(n - 1, 300), np.full(n - 1, 400), okc, 0.0, n,
                               lagged), R


def test_positional_construction_keeps_working():
    rd = RotationDifferences(np.zeros((2, 3, 3)), np.zeros(2), np.zeros(2),
                             np.ones(2, bool), 0.0, 3)
    assert rd.lagged is None
    assert len(LaggedDifferences.empty()) == 0


def test_round_trip_with_lagged_pairs(tmp_path):
    rd, R = _rd()
    plain, _ = _rd(seed=1)
    plain.lagged = None
    path = write_rotation_differences(tmp_path / "r.csv", {"C1": rd, "C2": plain},
                                      first_frame=5, comment="test")
    text = path.read_text().splitlines()
    assert text[1] == "frame,camera,rx,ry,rz,inliers,matches,ok,to_frame"
    assert text[2].startswith("5,C1,") and text[2].endswith(",6")
    back = read_rotation_differences(path, ["C1", "C2"], 30, first_frame=5)
    assert back["C2"].lagged is None
    np.testing.assert_allclose(back["C2"].dR, plain.dR, atol=1e-10)
    lg, orig = back["C1"].lagged, rd.lagged
    order = np.lexsort((orig.second, orig.first))
    for key in ("first", "second", "inliers", "matches", "ok"):
        np.testing.assert_array_equal(getattr(lg, key), getattr(orig, key)[order])
    np.testing.assert_allclose(lg.dR, orig.dR[order], atol=1e-10)   # NaN where failed
    good = lg.ok
    true = R[lg.second] @ np.swapaxes(R[lg.first], -1, -2)
    np.testing.assert_allclose(lg.dR[good], true[good], atol=1e-10)
    assert np.isnan(lg.dR[~good]).all() and (~good).sum() == 1


def test_files_without_lagged_pairs_keep_eight_columns(tmp_path):
    rd, _ = _rd()
    rd.lagged = None
    a = write_rotation_differences(tmp_path / "a.csv", {"C1": rd}).read_bytes()
    rd.lagged = LaggedDifferences.empty()
    b = write_rotation_differences(tmp_path / "b.csv", {"C1": rd}).read_bytes()
    assert a == b and a.startswith(b"frame,camera,rx,ry,rz,inliers,matches,ok\n")
    assert b",to_frame" not in a
    back = read_rotation_differences(tmp_path / "a.csv", ["C1"], 30)
    assert back["C1"].lagged is None
    np.testing.assert_allclose(back["C1"].dR, rd.dR, atol=1e-10)


def _table(tmp_path, rows, n=4):
    head = "frame,camera,rx,ry,rz,inliers,matches,ok,to_frame\n"
    body = "".join(f"{t},C1,0.1,0,0,50,60,1,{t + 1}\n" for t in range(n - 1))
    p = tmp_path / "rotations.csv"
    p.write_text(head + body + "".join(r + "\n" for r in rows))
    return p


def test_nine_columns_with_empty_to_frame_are_consecutive(tmp_path):
    p = tmp_path / "rotations.csv"
    p.write_text("frame,camera,rx,ry,rz,inliers,matches,ok,to_frame\n"
                 "0,C1,0.1,0,0,50,60,1,\n1,C1,0.1,0,0,50,60,1,2\n0,C1,0.2,0,0,40,60,1,2\n")
    back = read_rotation_differences(p, ["C1"], 3)["C1"]
    assert back.pairs == 2 and back.lagged.first.tolist() == [0]
    assert back.lagged.second.tolist() == [2] and back.lagged.inliers.tolist() == [40]


@pytest.mark.parametrize("row, message", [
    ("0,C1,0.2,0,0,50,60,1,4", r"rotations\.csv:5: to_frame 4 outside 1\.\.3"),
    ("2,C1,0.2,0,0,50,60,1,2", r"rotations\.csv:5: to_frame 2 outside 3\.\.3"),
    ("1,C1,0.2,0,0,50,60,1,0", r"rotations\.csv:5: to_frame 0 outside 2\.\.3"),
    ("0,C1,0.2,0,0,50,60,1,x", r"rotations\.csv:5: malformed number"),
    ("0,C1,0.2,0,0,50,60,1", r"rotations\.csv:5: 8 fields, expected 9"),
    ("0,C1,0.2,0,0,50,60,1,1", r"rotations\.csv:5: duplicate frame 0 of camera C1"),
])
def test_bad_rows(tmp_path, row, message):
    with pytest.raises(InputError, match=message) as e:
        read_rotation_differences(_table(tmp_path, [row]), ["C1"], 4)
    assert "\n" not in str(e.value)


def test_duplicate_lagged_pair(tmp_path):
    p = _table(tmp_path, ["0,C1,0.2,0,0,50,60,1,2", "0,C1,0.2,0,0,50,60,1,3",
                          "0,C1,0.3,0,0,50,60,1,2"])
    with pytest.raises(InputError, match=r"rotations\.csv:7: duplicate frames 0-2 of camera "
                                         r"C1 \(first on line 5\)"):
        read_rotation_differences(p, ["C1"], 4)


def test_bad_header(tmp_path):
    p = tmp_path / "rotations.csv"
    p.write_text("frame,camera,rx,ry,rz,inliers,matches,ok,to\n0,C1,0,0,0,1,1,1,1\n")
    with pytest.raises(InputError, match=r"rotations\.csv:1: expected the columns"):
        read_rotation_differences(p, ["C1"], 2)


# -- measured on rendered SIMULATED frames ----------------------------------
FRAMES = list(range(100, 130))          # 30 frames (as tests/test_mocap_homography.py)
WIDE, ZOOMED = 2, 0


@pytest.fixture(scope="module")
def rendered():
    # the frames of test_mocap_homography, rendered once (tests/mocap_fixtures.py)
    from mocap_fixtures import release_images, ski_boxes, ski_images, ski_session
    yield ski_session()[0], ski_boxes(), ski_images()
    release_images("test_mocap_lagged_differences")


def _measure(rendered, cam, **kw):
    from mocap_fixtures import ski_measured
    return ski_measured(cam, **kw)          # memoised per camera and settings


def _angles(R, first, second):
    """Angle (deg) of R(second) R(first)^T, and of est (n,3,3) against it."""
    from photogram.geometry import matrix_to_rodrigues
    true = R[second] @ np.swapaxes(R[first], -1, -2)
    return true, np.degrees(np.linalg.norm(matrix_to_rodrigues(true), axis=1))


def _errors(est, true):
    from photogram.geometry import matrix_to_rodrigues
    return np.degrees(np.linalg.norm(matrix_to_rodrigues(est @ np.swapaxes(true, -1, -2)),
                                     axis=1))


@pytest.mark.parametrize("cam", [WIDE, ZOOMED])
def test_lagged_pairs_match_the_truth(rendered, cam):
    sim = rendered[0]
    rd = _measure(rendered, cam)
    R = sim.cameras.R[FRAMES, cam]
    lg = rd.lagged
    assert set(np.unique(lg.second - lg.first)) <= {10, 25} and np.any(lg.second - lg.first == 10)
    assert lg.ok.all() and np.all(lg.inliers >= 30)
    true, angle = _angles(R, lg.first, lg.second)
    assert np.median(angle) > 1.5            # 2-5 deg: far from the identity
    e_lag = _errors(lg.dR, true)
    steps = np.arange(rd.pairs)
    e_one = _errors(rd.dR, _angles(R, steps, steps + 1)[0])
    # measured (seed 8): consecutive median 0.005 deg, lagged 0.010-0.011 deg
    assert np.median(e_lag) < 3 * np.median(e_one) and np.median(e_lag) < 0.02
    assert np.percentile(e_lag, 95) < 0.1


@pytest.mark.parametrize("cam", [WIDE, ZOOMED])
def test_pairs_beyond_the_overlap_limit_are_not_attempted(rendered, cam):
    from photogram.mocap.motion.homography import horizontal_fov, pinhole_matrices
    sim, _, images = rendered
    R = sim.cameras.R[FRAMES, cam]
    K = pinhole_matrices("opencv", sim.cameras.io[cam][FRAMES], 0.5)
    fov = np.degrees([horizontal_fov(k, images[cam][0].shape[1]) for k in K])
    for fraction in (0.5, 0.2):
        lg = _measure(rendered, cam, max_lag_fraction=fraction).lagged
        first = np.concatenate([np.arange(30 - k) for k in (10, 25)])
        second = np.concatenate([np.arange(k, 30) for k in (10, 25)])
        _, angle = _angles(R, first, second)
        limit = fraction * np.minimum(fov[first], fov[second])
        tried = {(a, b) for a, b in zip(lg.first.tolist(), lg.second.tolist())}
        # the prediction (chained measured differences) is within 0.05 deg of the truth
        inside = {(a, b) for a, b, x, y in zip(first, second, angle, limit) if x < y - 0.05}
        outside = {(a, b) for a, b, x, y in zip(first, second, angle, limit) if x > y + 0.05}
        assert inside <= tried and not (outside & tried)
        if cam == ZOOMED and fraction == 0.5:
            assert len(outside) >= 5             # lag 25 of the zoomed camera: 4-6 deg turns
        if fraction == 0.2:
            assert len(outside) > 0


def test_no_lags_gives_none(rendered):
    rd = _measure(rendered, WIDE, lags=())
    assert rd.lagged is None
    twice = _measure(rendered, WIDE, lags=(10, 10)).lagged
    assert len(twice) == len(set(zip(twice.first.tolist(), twice.second.tolist()))) > 0
    with pytest.raises(InputError, match="lag must be an integer of at least 2"):
        _measure(rendered, WIDE, lags=(1, 10))


# -- through the pipeline's measurement: table, images cache, solver arrays --
def _cameras(names):
    from photogram.mocap.reconstruction.cameras import MocapCameras
    C = len(names)
    return MocapCameras(list(names), ["opencv"] * C,
                        [np.array([1000., 1000, 4, 4, 0, 0, 0, 0, 0])] * C,
                        np.zeros((C, 3)), np.repeat(np.eye(3)[None], C, 0), np.full((C, 2), 8.0))


def test_lagged_pairs_flow_from_the_table(tmp_path):
    import types

    from photogram.mocap.motion.unknown_rotations import lagged_arrays, measure_differences
    rd, R = _rd()
    plain, _ = _rd(seed=1)
    plain.lagged = None
    path = write_rotation_differences(tmp_path / "r.csv", {"C1": plain, "C2": rd},
                                      first_frame=3)
    ms = types.SimpleNamespace(homography={}, rotation_differences=path, images=None)
    warnings = []
    _, weights, per = measure_differences(ms, _cameras(["C1", "C2"]), [None, None], (0, 30), 3,
                                          warnings)
    assert not warnings and per["C1"].lagged is None
    assert len(per["C2"].lagged) == len(rd.lagged)
    cam, first, second, dR = lagged_arrays(per, ["C1", "C2"], {})
    assert np.all(cam == 1) and len(cam) == rd.lagged.ok.sum()     # the failed pair left out
    np.testing.assert_allclose(dR, R[second] @ np.swapaxes(R[first], -1, -2), atol=1e-9)
    # the camera order of the solver is the index
    cam, *_ = lagged_arrays(per, ["C2", "C1"], {})
    assert np.all(cam == 0)


def test_lagged_arrays_keeps_confident_pairs_only():
    from photogram.mocap.motion.unknown_rotations import lagged_arrays
    rd, _ = _rd()                                    # consecutive inliers 300, lagged 90
    cam, first, second, dR = lagged_arrays({"A": rd}, ["A"], {})
    assert len(cam) == rd.lagged.ok.sum()            # 90 >= 0.3 * 300
    few = rd.lagged.inliers.copy()
    few[::2] = 80                                    # below 0.3 * 300 = 90
    rd.lagged.inliers = few
    cam, first, second, dR = lagged_arrays({"A": rd}, ["A"], {})
    keep = rd.lagged.ok & (few >= 90)
    assert np.array_equal(first, rd.lagged.first[keep])
    assert np.array_equal(second, rd.lagged.second[keep])
    cam, *_ = lagged_arrays({"A": rd}, ["A"], {"min_inlier_fraction": 0.0})
    assert len(cam) == rd.lagged.ok.sum()
    rd.ok[:10] = False                               # 10 of 29 failed: the camera is out
    assert len(lagged_arrays({"A": rd}, ["A"], {})[0]) == 0
    empty = lagged_arrays({}, ["A"], {})
    assert [a.shape for a in empty] == [(0,), (0,), (0,), (0, 3, 3)]
    assert empty[0].dtype.kind == "i"


def test_the_images_cache_keeps_the_lagged_pairs(tmp_path, monkeypatch):
    import types

    from photogram.mocap.motion import homography, video
    from photogram.mocap.motion.homography import HomographySettings
    from photogram.mocap.motion.unknown_rotations import _from_images
    rd, _ = _rd()
    plain, _ = _rd(seed=1)
    plain.lagged = None
    made = {"A": rd, "B": plain}
    (tmp_path / "A.avi").write_bytes(b"not read")
    (tmp_path / "B.avi").write_bytes(b"not read")
    monkeypatch.setattr(video, "read_frames",
                        lambda path, frames=None: (np.zeros((8, 8, 3), np.uint8) for _ in frames))
    order = iter(["A", "B"])
    monkeypatch.setattr(homography, "rotation_differences", lambda *a, **k: made[next(order)])
    ms = types.SimpleNamespace(images={n: tmp_path / f"{n}.avi" for n in made})
    cache = tmp_path / "cache"
    out = _from_images(ms, _cameras(["A", "B"]), [None, None], (0, 30), HomographySettings(),
                       cache=cache)
    assert out["A"] is rd
    monkeypatch.setattr(homography, "rotation_differences",
                        lambda *a, **k: pytest.fail("measured again"))
    again = _from_images(ms, _cameras(["A", "B"]), [None, None], (0, 30), HomographySettings(),
                         cache=cache)
    assert again["B"].lagged is None
    lg = again["A"].lagged
    for key in ("first", "second", "inliers", "matches", "ok"):
        np.testing.assert_array_equal(getattr(lg, key), getattr(rd.lagged, key))
    np.testing.assert_array_equal(lg.dR, rd.lagged.dR)


@pytest.mark.parametrize("block, expect", [
    ("lags = []\nmax_lag_fraction = 0.3", {"lags": (), "max_lag_fraction": 0.3}),
    ("lags = [5, 12]", {"lags": (5, 12)}),
    ("lags = [1, 10]", "lags in [mocap.homography] must list frame distances of at least 2"),
    ("lags = 10", "lags in [mocap.homography] must list frame distances of at least 2"),
    ("max_lag_fraction = 0", "max_lag_fraction"),
])
def test_project_homography_lags(tmp_path, capsys, block, expect):
    from photogram.project import read_project
    from photogram.simulation.ski.simproject import (write_estimate_project,
                                                     write_simulated_project)
    from photogram.simulation.ski.simulate import simulate_session
    from photogram_cli.main import main
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=30)
    write_simulated_project(sim, tmp_path, name="ski")
    prj = write_estimate_project(sim, tmp_path, name="ski")
    (tmp_path / "rotation_differences.csv").write_text(
        "frame,camera,rx,ry,rz,inliers,matches,ok\n")
    prj.write_text(prj.read_text().replace(
        "[mocap.source]", f"[mocap.homography]\n{block}\n\n[mocap.source]"))
    if isinstance(expect, dict):
        assert read_project(prj).mocap.homography == expect
        return
    assert main(["check", str(prj)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expect in err[0] and "ski-estimate.prj" in err[0], err


# -- the SIMULATED harsh setting's lagged pairs ---------------------------------
@pytest.fixture(scope="module")
def harsh():
    from photogram.simulation.ski.harsh import simulate_harsh
    return simulate_harsh(seed=23)


def test_simulated_lagged_pairs_follow_the_noise_model(harsh):
    from dataclasses import replace

    from photogram.geometry import matrix_to_rodrigues
    from photogram.simulation.ski.harsh import simulated_rotation_differences
    from photogram.simulation.ski.harsh_lagged import fields_of_view
    st = harsh.settings
    per = simulated_rotation_differences(harsh, st, 5)
    off = simulated_rotation_differences(harsh, replace(st, dr_lags=()), 5)
    R = harsh.cameras.R
    slopes, attempted, failed = [], 0, 0
    for c, (name, rd) in enumerate(per.items()):
        # the consecutive pairs do not depend on the lagged ones (own random stream)
        np.testing.assert_array_equal(rd.dR, off[name].dR)
        np.testing.assert_array_equal(rd.inliers, off[name].inliers)
        assert off[name].lagged is None
        lg = rd.lagged
        assert set(np.unique(lg.second - lg.first)) == {10, 25}
        true = R[lg.second, c] @ np.swapaxes(R[lg.first, c], -1, -2)
        rv = matrix_to_rodrigues(true)
        fov = fields_of_view(harsh.cameras.io[c], harsh.cameras.image_size[c][0])
        u = np.linalg.norm(rv, axis=1) / np.minimum(fov[lg.first], fov[lg.second])
        assert u.max() < 0.5                         # only overlapping views
        n_all = sum(len(R) - k for k in (10, 25))
        attempted += len(lg)
        failed += np.count_nonzero(~lg.ok)
        good = lg.ok & (lg.inliers >= 40)            # not the wrong pairs
        e = matrix_to_rodrigues(lg.dR[good] @ np.swapaxes(true[good], -1, -2))
        # the scale error: pan and tilt errors proportional to the turn, one sign
        x, y = rv[good, :2].ravel(), e[:, :2].ravel()
        slopes.append(np.dot(x, y) / np.dot(x, x))
        assert np.degrees(np.median(np.abs(e[:, 2]))) < 0.05      # roll: noise only
        assert len(lg) <= n_all
    slopes = np.array(slopes)
    assert np.all(np.abs(np.abs(slopes) - 0.003) < 0.0015), slopes
    assert 0.03 < failed / attempted < 0.2           # 2 % plus more near the limit
