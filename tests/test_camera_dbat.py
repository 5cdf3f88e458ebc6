"""The brown model is DBAT's lens distortion model 3.

1. A literal transcription of DBAT's residual (res_euler_brown_1.m, which
   brown_euler_cam4.m calls for model 3, with DBAT's internal signs) equals
   ours up to the documented sign of the residual: v = (-r_x, r_y).
2. With DBAT's published CAMCAL result (dbat-report.txt,
   dbat-camera_stations.txt) and PhotoModeler's object points the image
   residuals are at DBAT's noise level, with no systematic offset.
"""

import csv
from pathlib import Path

import numpy as np
import pytest

from photogram.geometry import camera_model, rescale_parameters

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "dbat" / "camcal"

# DBAT 0.9.2.0, camcaldemo, fixed control (dbat-report.txt): cc, px, py, K1,
# K2, K3, P1, P2, as, sk in mm; DBAT's nominal pixel size (pixel height).
DBAT_IO = np.array([7.457, 3.61546, 2.61329, 0.00458861, -4.51351e-05, -2.05253e-06,
                    -6.12803e-05, -4.41171e-05, 0.000389598, 0.0])
PIXEL = 5.43764 / 1704


def dbat_res_euler_brown_1(Q, q0, ang, f, u, sz, u0, K, P, b):
    """DBAT's model-3 residual, transcribed (2-by-N arrays as in MATLAB):

    lhs = eulerpinhole2(Q, q0, ang, -f)
    rhs = brown_dist(affine2(xlat2(aniscale2(scale2(u,sz),[1;-1]),-u0),b),-K,-P)
    v = lhs - rhs
    """
    def r(axis, a):
        c, s = np.cos(a), np.sin(a)
        m = {1: [[1, 0, 0], [0, c, -s], [0, s, c]], 2: [[c, 0, s], [0, 1, 0], [-s, 0, c]],
             3: [[c, -s, 0], [s, c, 0], [0, 0, 1]]}[axis]
        return np.array(m)

    M = r(1, ang[0]) @ r(2, ang[1]) @ r(3, ang[2])          # eulerrotmat(ang,123,false)
    W = M.T @ (Q - q0[:, None])                               # world2cam(P,p0,M')
    lhs = -f * W[:2] / W[2]                                   # f*pinhole(.) with -f
    s = sz * u                                                # scale2
    s = np.diag([1.0, -1.0]) @ s                              # aniscale2 [1;-1]
    x = s - u0[:, None]                                       # xlat2(.,-u0)
    a = np.array([[1 + b[0], b[1]], [0, 1]]) @ x              # affine2
    r2 = np.sum(a ** 2, 0)                                    # brown_dist(a,-K,-P)
    rad = a * ((-K[0]) * r2 + (-K[1]) * r2 ** 2 + (-K[2]) * r2 ** 3)
    p = -np.asarray(P)
    tang = p[:, None] * r2 + 2 * (p @ a) * a                  # tang_scale
    return lhs - (a + rad + tang)


def test_transcribed_dbat_residual_equals_ours():
    rng = np.random.default_rng(3)
    io = DBAT_IO.copy()
    io[9] = 2e-4                                              # exercise the skew too
    n = 60
    ang = np.array([0.5, -0.1, 2.9])
    q0 = np.array([0.5, -0.5, 1.5])
    Q = np.stack([rng.uniform(-0.2, 1.2, n), rng.uniform(-0.2, 1.2, n),
                  rng.uniform(-0.05, 0.05, n)])
    u = rng.uniform([0, 0], [2272, 1704], (n, 2)).T          # pixels, y down
    # DBAT's internal values: reported py, K and P with flipped signs
    # (bundle_result_file.m: "Flip signs of py": IOdata([3,6:end],:) negated).
    u0_int = np.array([io[1], -io[2]])
    K_int, P_int = -io[3:6], -io[6:8]
    v = dbat_res_euler_brown_1(Q, q0, ang, io[0], u, PIXEL, u0_int, K_int, P_int, io[8:10])
    r = camera_model("brown").residuals(u.T * PIXEL, Q.T, ang, q0, io, jacobians=False)
    assert np.allclose(v[0], -r[:, 0], atol=1e-13)
    assert np.allclose(v[1], r[:, 1], atol=1e-13)


def load_camcal():
    if not DATA.is_dir():
        pytest.skip(f"DBAT reference data not found at {DATA}")
    stations = np.genfromtxt(DATA / "dbat-camera_stations.txt", delimiter=",",
                             comments="#", usecols=range(8))
    marks = np.genfromtxt(DATA / "markpts.txt", delimiter=",", comments="#")
    points = {1001: (0, 1, 0), 1002: (1, 1, 0), 1003: (0, 0, 0), 1004: (1, 0, 0)}
    lines = (DATA / "photomodeler-fixed-no-orient-3dpts.txt").read_text().splitlines()
    for row in csv.reader(lines):
        if len(row) > 5 and row[0].strip().isdigit():
            points.setdefault(int(row[0]), tuple(float(v) for v in row[3:6]))
    keep = np.array([int(p) in points for p in marks[:, 1]])
    marks = marks[keep]
    X = np.array([points[int(p)] for p in marks[:, 1]], dtype=float)
    eo = stations[marks[:, 0].astype(int) - 1]
    # the stations file says "Unit: degrees" but holds radians
    return marks[:, 2:4], X, eo[:, 5:8], eo[:, 2:5]


def test_dbat_camcal_result_reproduces_measurements():
    xy, X, angles, X0 = load_camcal()
    brown = camera_model("brown")
    r = brown.residuals(xy * PIXEL, X, angles, X0, DBAT_IO, jacobians=False) / PIXEL
    assert len(r) > 2000
    rms = np.sqrt(np.mean(r ** 2))
    assert rms < 0.2                       # DBAT: sigma0 0.16 px (sxy = 0.1 px)
    assert np.all(np.abs(r.mean(axis=0)) < 0.02)
    # the same in pixels, and through the forward projection
    io_px = rescale_parameters("brown", DBAT_IO, 1 / PIXEL)
    r_px = brown.residuals(xy, X, angles, X0, io_px, jacobians=False)
    assert np.allclose(r_px, r, atol=1e-9)
    proj = brown.project(X, angles, X0, io_px)
    assert np.sqrt(np.mean((proj - xy) ** 2)) < 0.2


def test_dbat_signs_matter():
    """Flipping the sign convention of K or applying the aspect before the
    principal point (res_euler_brown_3 order) is clearly worse."""
    xy, X, angles, X0 = load_camcal()
    brown = camera_model("brown")

    def rms(io):
        r = brown.residuals(xy * PIXEL, X, angles, X0, io, jacobians=False) / PIXEL
        return np.sqrt(np.mean(r ** 2))

    flipped = DBAT_IO.copy()
    flipped[3:6] *= -1
    assert rms(flipped) > 10 * rms(DBAT_IO)
    shifted = DBAT_IO.copy()
    shifted[1] *= 1 + DBAT_IO[8]           # px referred to the unscaled x axis
    assert rms(shifted) > 1.5 * rms(DBAT_IO)
