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
