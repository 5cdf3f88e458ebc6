"""COLMAP's camera models, binary files and rigs.

The models here are written by a minimal writer of this file that follows
COLMAP's struct layout (src/colmap/scene/reconstruction_io_binary.cc) and
text layout, with 2D points made by an independent transcription of
COLMAP's projection (src/colmap/sensor/models.h), so that photogram's
reader is checked against COLMAP's definitions, not against itself.
"""

from __future__ import annotations

import logging
import struct
from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.geometry import camera_model, quaternion_to_matrix, rodrigues_to_matrix
from photogram.io.colmap import (colmap_project, colmap_records, read_colmap, read_records,
                                 write_records)
from photogram.io.colmap_cameras import model_to_colmap
from photogram.io.exchange import View
from photogram.io.formats import export_results, import_project

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

IDS = {"SIMPLE_PINHOLE": 0, "PINHOLE": 1, "SIMPLE_RADIAL": 2, "RADIAL": 3, "OPENCV": 4,
       "OPENCV_FISHEYE": 5, "FULL_OPENCV": 6, "SIMPLE_RADIAL_FISHEYE": 8, "RADIAL_FISHEYE": 9}
#: generic parameters of every model (COLMAP's pixel frame, centre of pixel 0 at 0.5)
PARAMS = {
    "SIMPLE_PINHOLE": [1500.5, 960.25, 540.75],
    "PINHOLE": [1500.5, 1498.25, 960.25, 540.75],
    "SIMPLE_RADIAL": [1500.5, 960.25, 540.75, -0.07],
    "RADIAL": [1500.5, 960.25, 540.75, -0.07, 0.021],
    "OPENCV": [1500.5, 1498.25, 960.25, 540.75, -0.07, 0.021, 3e-4, -2e-4],
    "FULL_OPENCV": [1500.5, 1498.25, 960.25, 540.75, -0.07, 0.021, 3e-4, -2e-4, 0.004,
                    0.05, -0.01, 0.002],
    "OPENCV_FISHEYE": [700.5, 699.25, 960.25, 540.75, 0.05, -0.02, 0.004, -0.001],
    "SIMPLE_RADIAL_FISHEYE": [700.5, 960.25, 540.75, 0.05],
    "RADIAL_FISHEYE": [700.5, 960.25, 540.75, 0.05, -0.02],
}
PHOTOGRAM = {"SIMPLE_PINHOLE": "opencv", "PINHOLE": "opencv", "SIMPLE_RADIAL": "opencv",
             "RADIAL": "opencv", "OPENCV": "opencv", "FULL_OPENCV": "opencv_full",
             "OPENCV_FISHEYE": "opencv_fisheye", "SIMPLE_RADIAL_FISHEYE": "opencv_fisheye",
             "RADIAL_FISHEYE": "opencv_fisheye"}


# --------------------------------------------------------------------------
# COLMAP's projection, transcribed from models.h (World/CamToImg, Distortion)

def colmap_pixels(model, p, Xc):
    """Pixels (COLMAP's frame) of camera-frame points Xc (n,3), z > 0."""
    u, v = Xc[:, 0] / Xc[:, 2], Xc[:, 1] / Xc[:, 2]
    p = list(p)
    if model in ("SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL", "SIMPLE_RADIAL_FISHEYE",
                 "RADIAL_FISHEYE"):
        f, cx, cy, *k = p
        fx = fy = f
    else:
        fx, fy, cx, cy, *k = p
    if model in ("SIMPLE_PINHOLE", "PINHOLE"):
        du = dv = 0.0
    elif model in ("SIMPLE_RADIAL", "RADIAL"):
        k1, k2 = (k + [0.0])[:2]
        r2 = u * u + v * v
        radial = k1 * r2 + k2 * r2 * r2
        du, dv = u * radial, v * radial
    elif model in ("OPENCV", "FULL_OPENCV"):
        k1, k2, p1, p2, k3, k4, k5, k6 = (k + [0.0] * 4)[:8]
        u2, v2, uv = u * u, v * v, u * v
        r2 = u2 + v2
        r4, r6 = r2 * r2, r2 * r2 * r2
        radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6)
        du = u * radial + 2 * p1 * uv + p2 * (r2 + 2 * u2) - u
        dv = v * radial + 2 * p2 * uv + p1 * (r2 + 2 * v2) - v
    else:
        k1, k2, k3, k4 = (k + [0.0] * 3)[:4]
        r = np.sqrt(u * u + v * v)
        th = np.arctan(r)
        t2 = th * th
        thd = th * (1 + k1 * t2 + k2 * t2 ** 2 + k3 * t2 ** 3 + k4 * t2 ** 4)
        du, dv = u * thd / r - u, v * thd / r - v
    return np.stack([fx * (u + du) + cx, fy * (v + dv) + cy], -1)


# --------------------------------------------------------------------------
# an independent minimal writer of COLMAP's files


def write_bin(folder: Path, cameras, images, points, rigs=None, frames=None):
    """cameras: [(id, model, w, h, params)]; images: [(id, q, t, cam, name,
    [(x, y, pid)])]; points: [(id, xyz, rgb, err, [(img, idx)])]; rigs:
    [(id, (type, id), [(type, id, q, t)])]; frames: [(id, rig, q, t,
    [(type, sid, did)])]."""
    folder.mkdir(parents=True, exist_ok=True)
    b = struct.pack("<Q", len(cameras))
    for cid, model, w, h, params in cameras:
        b += struct.pack("<IiQQ", cid, IDS[model], w, h) + struct.pack(f"<{len(params)}d",
                                                                        *params)
    (folder / "cameras.bin").write_bytes(b)
    b = struct.pack("<Q", len(images))
    for iid, q, t, cam, name, pts in images:
        b += struct.pack("<I4d3dI", iid, *q, *t, cam) + name.encode() + b"\x00"
        b += struct.pack("<Q", len(pts))
        for x, y, pid in pts:
            b += struct.pack("<ddQ", x, y, 2 ** 64 - 1 if pid < 0 else pid)
    (folder / "images.bin").write_bytes(b)
    b = struct.pack("<Q", len(points))
    for pid, xyz, rgb, err, track in points:
        b += struct.pack("<Q3d3Bd", pid, *xyz, *rgb, err) + struct.pack("<Q", len(track))
        for a, c in track:
            b += struct.pack("<II", a, c)
    (folder / "points3D.bin").write_bytes(b)
    if rigs is not None:
        types = {"CAMERA": 0, "IMU": 1}
        b = struct.pack("<Q", len(rigs))
        for rid, ref, sensors in rigs:
            b += struct.pack("<II", rid, len(sensors) + 1) + struct.pack("<iI", types[ref[0]],
                                                                        ref[1])
            for kind, sid, q, t in sensors:
                b += struct.pack("<iIB", types[kind], sid, q is not None)
                if q is not None:
                    b += struct.pack("<7d", *q, *t)
        (folder / "rigs.bin").write_bytes(b)
        b = struct.pack("<Q", len(frames))
        for fid, rid, q, t, data in frames:
            b += struct.pack("<II7dI", fid, rid, *q, *t, len(data))
            for kind, sid, did in data:
                b += struct.pack("<iIQ", types[kind], sid, did)
        (folder / "frames.bin").write_bytes(b)


def write_txt(folder: Path, cameras, images, points, rigs=None, frames=None):
    """The same as text, numbers as COLMAP writes them (precision 17; sensor
    types by name, as COLMAP's operator<< of SensorType)."""
    folder.mkdir(parents=True, exist_ok=True)
    g = "{:.17g}".format
    if rigs is not None:
        lines = ["# Rig calib list"]
        for rid, ref, sensors in rigs:
            f = [str(rid), str(len(sensors) + 1), ref[0], str(ref[1])]
            for kind, sid, q, t in sensors:
                f += [kind, str(sid)] + (["1"] + [g(c) for c in (*q, *t)] if q else ["0"])
            lines.append(" ".join(f))
        (folder / "rigs.txt").write_text("\n".join(lines) + "\n")
        lines = ["# Frame list"]
        for fid, rid, q, t, data in frames:
            lines.append(" ".join([str(fid), str(rid)] + [g(c) for c in (*q, *t)] +
                                  [str(len(data))] + [f"{k} {a} {b}" for k, a, b in data]))
        (folder / "frames.txt").write_text("\n".join(lines) + "\n")
    (folder / "cameras.txt").write_text("# Camera list\n" + "".join(
        f"{cid} {model} {w} {h} " + " ".join(map(g, params)) + "\n"
        for cid, model, w, h, params in cameras))
    lines = ["# Image list"]
    for iid, q, t, cam, name, pts in images:
        lines.append(" ".join([str(iid)] + [g(c) for c in (*q, *t)] + [str(cam), name]))
        lines.append(" ".join(f"{g(x)} {g(y)} {pid}" for x, y, pid in pts))
    (folder / "images.txt").write_text("\n".join(lines) + "\n")
    (folder / "points3D.txt").write_text("# 3D point list\n" + "".join(
        " ".join([str(pid)] + [g(c) for c in xyz] + [str(c) for c in rgb] + [g(err)] +
                 [f"{a} {c}" for a, c in track]) + "\n"
        for pid, xyz, rgb, err, track in points))


def quat(R):
    from photogram.geometry import matrix_to_quaternion
    return tuple(float(c) for c in matrix_to_quaternion(R))


def scene(model, n_images=4, n_points=30, seed=7):
    """Cameras, images and points of one camera of ``model`` (2D points by
    colmap_pixels; the fisheye models see a wider field)."""
    rng = np.random.default_rng(seed)
    wide = "FISHEYE" in model
    X = rng.uniform([-2, -2, -1], [2, 2, 1], (n_points, 3)) * (2.0 if wide else 0.6)
    images, tracks = [], {i: [] for i in range(n_points)}
    for k in range(n_images):
        R = rodrigues_to_matrix(np.array([0.05 * k, 0.1 - 0.05 * k, 0.02]))
        t = np.array([0.1 * k, -0.2, 5.0])
        xy = colmap_pixels(model, PARAMS[model], X @ R.T + t)
        pts = []
        for i in range(n_points):
            if (i + k) % 7 == 0:
                continue
            tracks[i].append((10 + k, len(pts)))
            pts.append((float(xy[i, 0]), float(xy[i, 1]), 100 + i))
        pts.append((5.5, 6.5, -1))                       # a feature without a 3D point
        images.append((10 + k, quat(R), tuple(t), 3, f"img_{k}.jpg", pts))
    points = [(100 + i, tuple(X[i]), (10, 20, 30), 0.25, tracks[i]) for i in range(n_points)]
    return [(3, model, 1920, 1080, PARAMS[model])], images, points


def read_bin_cameras(path: Path):
    """cameras.bin by struct, independently of photogram."""
    data = path.read_bytes()
    (n,), pos, out = struct.unpack_from("<Q", data), 8, {}
    nparams = {0: 3, 1: 4, 2: 4, 3: 5, 4: 8, 5: 8, 6: 12, 8: 4, 9: 5}
    names = {v: k for k, v in IDS.items()}
    for _ in range(n):
        cid, mid, w, h = struct.unpack_from("<IiQQ", data, pos)
        pos += 24
        out[cid] = (names[mid], w, h, struct.unpack_from(f"<{nparams[mid]}d", data, pos))
        pos += 8 * nparams[mid]
    assert pos == len(data)
    return out


def residuals(prj):
    ip = prj.image_points
    out = []
    for name, cam in prj.cameras.items():
        sel = np.array([prj.stations.camera[s] == name for s in ip.station])
        st = ip.station[sel]
        out.append(camera_model(cam.model).residuals(
            ip.xy[sel], prj.points.xyz[ip.point[sel]], prj.stations.angles[st],
            prj.stations.position[st], cam.values(), jacobians=False))
    return np.concatenate(out)


# --------------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["bin", "txt"])
@pytest.mark.parametrize("model", list(PARAMS))
def test_import_reproduces_colmaps_projection(tmp_path, model, fmt):
    """Every COLMAP model, binary and text: the imported camera (photogram's
    model, principal point -0.5 px) reproduces the 2D points that COLMAP's
    own formulas make, to 1e-9 px."""
    cams, images, points = scene(model)
    (write_bin if fmt == "bin" else write_txt)(tmp_path / "m", cams, images, points)
    prj = colmap_project(tmp_path / "m")
    cam = prj.cameras["3"]
    assert cam.model == PHOTOGRAM[model]
    assert np.abs(residuals(prj)).max() < 1e-9
    p = PARAMS[model]
    assert cam.parameters["fx"].value == p[0]
    assert cam.parameters["cx"].value == p[2 if model in ("PINHOLE", "OPENCV", "FULL_OPENCV",
                                                          "OPENCV_FISHEYE") else 1] - 0.5
    assert len(prj.stations) == 4 and len(prj.points) == 30
    # one focal length f: the camera says fy = fx (parameter sharing), so a
    # self-calibration keeps COLMAP's model
    single_f = ("SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL", "SIMPLE_RADIAL_FISHEYE",
                "RADIAL_FISHEYE")
    assert cam.ties == ({"fy": "fx"} if model in single_f else {})


@pytest.mark.parametrize("src", ["bin", "txt"])
@pytest.mark.parametrize("out", ["colmap", "colmap-bin"])
@pytest.mark.parametrize("model", list(PARAMS))
def test_round_trip_is_exact_and_keeps_the_model(tmp_path, model, out, src):
    """COLMAP binary or text -> photogram project -> COLMAP (text or
    binary) -> the same COLMAP model and parameters (1e-12 relative; the
    0.5 px shift is the only arithmetic), poses and points."""
    cams, images, points = scene(model)
    (write_bin if src == "bin" else write_txt)(tmp_path / "m", cams, images, points)
    prj = import_project("colmap", tmp_path / "m", tmp_path / "imp")
    from photogram.project import read_project
    assert read_project(prj).cameras["3"].ties == \
        colmap_project(tmp_path / "m").cameras["3"].ties          # the .prj keeps the tie
    export_results(out, prj, tmp_path / "back")
    ext = ".bin" if out == "colmap-bin" else ".txt"
    assert (tmp_path / "back" / ("cameras" + ext)).is_file()
    if out == "colmap-bin":
        back_cam = read_bin_cameras(tmp_path / "back" / "cameras.bin")[3]
        assert back_cam[:3] == (model, 1920, 1080)
        assert np.allclose(back_cam[3], PARAMS[model], rtol=1e-12, atol=0)
    else:
        f = (tmp_path / "back" / "cameras.txt").read_text().splitlines()[-1].split()
        assert f[:4] == ["3", model, "1920", "1080"]
        assert np.allclose([float(v) for v in f[4:]], PARAMS[model], rtol=1e-12, atol=0)
    a, b = read_colmap(tmp_path / "m"), read_colmap(tmp_path / "back")
    assert b.binary == (out == "colmap-bin")
    for u, v in zip(a.views, b.views):
        assert u.name == v.name
        assert np.allclose(u.R_cv, v.R_cv, rtol=0, atol=1e-14)
        assert np.allclose(u.t_cv, v.t_cv, rtol=1e-12, atol=1e-14)
        assert np.allclose(u.K, v.K, rtol=1e-12, atol=0)
        assert np.allclose(u.dist, v.dist, rtol=1e-12, atol=0)
    assert a.point_ids == b.point_ids and np.allclose(a.xyz, b.xyz, rtol=1e-12, atol=0)
    ka = sorted(zip(a.obs_image, a.obs_point, map(tuple, a.obs_xy)))
    kb = sorted(zip(b.obs_image, b.obs_point, map(tuple, b.obs_xy)))
    assert [k[:2] for k in ka] == [k[:2] for k in kb]
    assert np.allclose([k[2] for k in ka], [k[2] for k in kb], rtol=1e-12, atol=1e-12)


def test_records_round_trip_text_and_binary(tmp_path):
    """read -> write (text, binary) -> read gives the same records, rigs and
    frames included (text numbers by repr: exact)."""
    cams, images, points, rigs, frames = rig_scene()
    write_bin(tmp_path / "m", cams, images, points, rigs, frames)
    rec, _ = read_records(tmp_path / "m")
    for binary_files in (False, True):
        out = tmp_path / f"w{binary_files}"
        write_records(out, rec, binary_files=binary_files)
        back, is_bin = read_records(out)
        assert is_bin == binary_files
        for cid in rec.cameras:
            assert back.cameras[cid].model == rec.cameras[cid].model
            assert np.array_equal(back.cameras[cid].params, rec.cameras[cid].params)
        for u, v in zip(rec.images, back.images):
            assert (u.image_id, u.camera_id, u.name) == (v.image_id, v.camera_id, v.name)
            assert np.array_equal(u.q, v.q) and np.array_equal(u.t, v.t)
            assert np.array_equal(u.xy, v.xy) and np.array_equal(u.point3d, v.point3d)
        assert np.array_equal(rec.points.xyz, back.points.xyz)
        assert all(np.array_equal(a, b) for a, b in zip(rec.points.tracks, back.points.tracks))
        assert [(r.rig_id, r.ref) for r in rec.rigs] == [(r.rig_id, r.ref) for r in back.rigs]
        for r, s in zip(rec.rigs, back.rigs):
            for a, b in zip(r.sensors, s.sensors):
                assert a[:2] == b[:2] and np.array_equal(a[2], b[2]) and np.array_equal(a[3],
                                                                                         b[3])
        for f, g in zip(rec.frames, back.frames):
            assert (f.frame_id, f.rig_id, f.data) == (g.frame_id, g.rig_id, g.data)
            assert np.array_equal(f.q, g.q) and np.array_equal(f.t, g.t)


# --------------------------------------------------------------------------
# rigs

def rig_scene():
    """Two cameras on a rig (camera 2 at 0.3 m to the right, turned 10 deg
    about y), three frames; images.bin holds placeholder identity poses,
    which COLMAP ignores when frames exist."""
    rng = np.random.default_rng(3)
    X = rng.uniform([-1, -1, -0.5], [1, 1, 0.5], (25, 3))
    Rs = rodrigues_to_matrix(np.array([0.0, np.radians(10), 0.0]))
    ts = np.array([-0.3, 0.0, 0.02])
    cams = [(1, "OPENCV", 1920, 1080, PARAMS["OPENCV"]),
            (2, "SIMPLE_RADIAL", 1920, 1080, PARAMS["SIMPLE_RADIAL"])]
    images, frames, tracks = [], [], {i: [] for i in range(len(X))}
    for k in range(3):
        Rr = rodrigues_to_matrix(np.array([0.03 * k, -0.05 * k, 0.01]))
        tr = np.array([0.2 * k - 0.15, 0.1, 4.0])
        frames.append((k + 1, 1, quat(Rr), tuple(tr), [("CAMERA", 1, 2 * k + 1),
                                                       ("CAMERA", 2, 2 * k + 2)]))
        for cam, (R, t) in ((1, (Rr, tr)), (2, (Rs @ Rr, Rs @ tr + ts))):
            model = cams[cam - 1][1]
            xy = colmap_pixels(model, PARAMS[model], X @ R.T + t)
            iid = 2 * k + cam
            pts = []
            for i in range(len(X)):
                tracks[i].append((iid, len(pts)))
                pts.append((float(xy[i, 0]), float(xy[i, 1]), 500 + i))
            images.append((iid, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), cam,
                           f"rig1/cam{cam}/{k:04d}.png", pts))
    points = [(500 + i, tuple(X[i]), (1, 2, 3), 0.1, tracks[i]) for i in range(len(X))]
    rigs = [(1, ("CAMERA", 1), [("CAMERA", 2, quat(Rs), tuple(ts))])]
    return cams, images, points, rigs, frames


def test_rig_frames_give_the_image_poses(tmp_path, caplog):
    """Image poses are sensor_from_rig * rig_from_world (the placeholder
    poses of images.bin are ignored, as COLMAP does); the import keeps every
    image as a station reproducing COLMAP's pixels to 1e-9 px, and the rig
    as a project rig with the stations' frames."""
    write_bin(tmp_path / "m", *rig_scene())
    with caplog.at_level(logging.WARNING, logger="photogram"):
        prj = colmap_project(tmp_path / "m")
    assert "rig" not in caplog.text
    assert len(prj.stations) == 6 and set(prj.cameras) == {"1", "2"}
    rig = prj.rigs["1"]
    assert (rig.reference, rig.cameras, rig.fixed) == ("1", ["2"], False)
    assert prj.stations.frame == ["1", "1", "2", "2", "3", "3"]
    assert np.abs(residuals(prj)).max() < 1e-9
    model = read_colmap(tmp_path / "m")
    assert [(v.extra["rig"], v.extra["frame"]) for v in model.views[:2]] == [(1, 1), (1, 1)]


def test_rigs_text_equal_rigs_binary(tmp_path):
    """rigs.txt / frames.txt as COLMAP writes them give the poses of the
    binary files (to the 17 digits of the text)."""
    data = rig_scene()
    write_bin(tmp_path / "b", *data)
    write_txt(tmp_path / "t", *data)
    a, b = read_colmap(tmp_path / "b"), read_colmap(tmp_path / "t")
    assert not b.binary and len(b.records.rigs) == 1 and len(b.records.frames) == 3
    for u, v in zip(a.views, b.views):
        assert np.allclose(u.R_cv, v.R_cv, rtol=0, atol=1e-15)
        assert np.allclose(u.t_cv, v.t_cv, rtol=1e-15, atol=1e-15)
    assert np.abs(residuals(colmap_project(tmp_path / "t"))).max() < 1e-9


def test_malformed_rigs_text(tmp_path):
    write_txt(tmp_path / "t", *rig_scene())
    f = tmp_path / "t" / "rigs.txt"
    text = f.read_text()
    f.write_text(text.replace("1 2 CAMERA 1 CAMERA 2 1", "1 2 CAMERA 1 LIDAR 2 1"))
    with pytest.raises(InputError, match="sensor type 'LIDAR'") as err:
        read_colmap(tmp_path / "t")
    assert err.value.file == str(f) and err.value.line == 2
    f.write_text(text.replace("1 2 CAMERA 1 CAMERA 2 1", "1 3 CAMERA 1 CAMERA 2 1"))
    with pytest.raises(InputError, match="ends before its NUM_SENSORS") as err:
        read_colmap(tmp_path / "t")
    assert err.value.file == str(f) and err.value.line == 2
    g = tmp_path / "t" / "frames.txt"
    f.write_text(f.read_text().replace("1 3 CAMERA", "1 2 CAMERA"))
    g.write_text(g.read_text().replace(" 2 CAMERA 1 1 CAMERA 2 2", " 2 CAMERA 1 1 CAMERA 2"))
    with pytest.raises(InputError, match="NUM_DATA_IDS is 2 but 5 values") as err:
        read_colmap(tmp_path / "t")
    assert err.value.line == 2


def test_rig_errors_name_the_file(tmp_path):
    cams, images, points, rigs, frames = rig_scene()
    frames[2] = (3, 1, frames[2][2], frames[2][3], frames[2][4][:1])   # image 6 in no frame
    write_bin(tmp_path / "m", cams, images, points, rigs, frames)
    with pytest.raises(InputError, match="image 6 .* is in no frame") as err:
        read_colmap(tmp_path / "m")
    assert err.value.file.endswith("frames.bin")


# --------------------------------------------------------------------------
# export: the smallest exact model; refits between models


@pytest.mark.parametrize("model,values,expect", [
    ("opencv", [1500.0, 1500.0, 960.0, 540.0, 0, 0, 0, 0, 0], "SIMPLE_PINHOLE"),
    ("opencv", [1500.0, 1499.0, 960.0, 540.0, 0, 0, 0, 0, 0], "PINHOLE"),
    ("opencv", [1500.0, 1500.0, 960.0, 540.0, -0.1, 0, 0, 0, 0], "SIMPLE_RADIAL"),
    ("opencv", [1500.0, 1500.0, 960.0, 540.0, -0.1, 0.02, 0, 0, 0], "RADIAL"),
    ("opencv", [1500.0, 1500.0, 960.0, 540.0, -0.1, 0.02, 1e-4, 0, 0], "OPENCV"),
    ("opencv", [1500.0, 1500.0, 960.0, 540.0, -0.1, 0.02, 0, 0, 0.003], "FULL_OPENCV"),
    ("opencv_full", [1500.0, 1500.0, 960.0, 540.0, -0.1] + [0] * 13, "SIMPLE_RADIAL"),
    ("opencv_full", [1500.0, 1500.0, 960.0, 540.0, -0.1, 0, 0, 0, 0, 0.01] + [0] * 8,
     "FULL_OPENCV"),
    ("opencv_fisheye", [700.0, 700.0, 960.0, 540.0, 0.05, 0, 0, 0], "SIMPLE_RADIAL_FISHEYE"),
    ("opencv_fisheye", [700.0, 700.0, 960.0, 540.0, 0.05, -0.01, 0, 0], "RADIAL_FISHEYE"),
    ("opencv_fisheye", [700.0, 701.0, 960.0, 540.0, 0.05, 0, 0, 0], "OPENCV_FISHEYE"),
])
def test_export_picks_the_smallest_exact_model(tmp_path, model, values, expect):
    """The COLMAP model written is the smallest that holds the camera; read
    back (refitted into the model COLMAP's maps to), the camera projects
    the same points to 1e-9 px."""
    colmap, params = model_to_colmap(model, values, 0.5)
    assert colmap == expect
    from photogram.io.colmap_cameras import view_intrinsics
    K, dist, fisheye = view_intrinsics(model, values)
    view = View(name="a", camera="1", K=K, dist=dist, R_cv=np.eye(3), t_cv=np.zeros(3),
                image_size=(1920, 1080), extra={"fisheye": fisheye})
    rng = np.random.default_rng(2)
    X = np.column_stack([rng.uniform(-1, 1, (40, 2)), rng.uniform(3, 6, 40)])
    write_records(tmp_path / "c", colmap_records([view], [str(i) for i in range(40)], X,
                                                 [(0, i, 0.0, 0.0) for i in range(40)]),
                  binary_files=True)
    back = colmap_project(tmp_path / "c")
    cam = back.cameras["1"]
    angles, X0 = back.stations.angles[0], back.stations.position[0]
    xy_a = camera_model(model).project(X * [1, -1, -1], np.zeros(3), np.zeros(3), values)
    xy_b = camera_model(cam.model).project(X, angles, X0, cam.values())
    assert np.abs(xy_a - xy_b).max() < 1e-9


def test_thin_prism_or_tilt_have_no_colmap_model():
    values = [1500.0, 1500.0, 960.0, 540.0, -0.1] + [0] * 7 + [1e-3] + [0] * 5
    with pytest.raises(InputError, match="no COLMAP camera model holds"):
        model_to_colmap("opencv_full", values, 0.5, name="cam")


def test_export_of_a_fisheye_project_writes_opencv_fisheye(tmp_path):
    cams, images, points = scene("OPENCV_FISHEYE")
    write_txt(tmp_path / "m", cams, images, points)
    prj = import_project("colmap", tmp_path / "m", tmp_path / "imp")
    export_results("colmap-bin", prj, tmp_path / "b")
    assert read_bin_cameras(tmp_path / "b" / "cameras.bin")[3][0] == "OPENCV_FISHEYE"


# --------------------------------------------------------------------------
# malformed binary files


def test_truncated_binary_names_file_and_record(tmp_path):
    write_bin(tmp_path / "m", *scene("OPENCV"))
    f = tmp_path / "m" / "images.bin"
    f.write_bytes(f.read_bytes()[:700])
    with pytest.raises(InputError, match=r"record \d+ \(byte \d+\).*truncated") as err:
        read_colmap(tmp_path / "m")
    assert err.value.file == str(f)


def test_unknown_model_id_and_trailing_bytes(tmp_path):
    cams, images, points = scene("OPENCV")
    write_bin(tmp_path / "m", cams, images, points)
    f = tmp_path / "m" / "cameras.bin"
    data = bytearray(f.read_bytes())
    data[12:16] = struct.pack("<i", 7)            # FOV: not supported
    f.write_bytes(bytes(data))
    with pytest.raises(InputError, match="camera model id 7 is not supported"):
        read_colmap(tmp_path / "m")
    write_bin(tmp_path / "n", cams, images, points)
    g = tmp_path / "n" / "points3D.bin"
    g.write_bytes(g.read_bytes() + b"\x00\x01")
    with pytest.raises(InputError, match="2 bytes after the last record"):
        read_colmap(tmp_path / "n")


def test_binary_is_preferred_when_both_are_there(tmp_path):
    cams, images, points = scene("RADIAL")
    write_bin(tmp_path / "m", cams, images, points)
    write_txt(tmp_path / "m", [(3, "PINHOLE", 1920, 1080, PARAMS["PINHOLE"])], images, points)
    assert read_colmap(tmp_path / "m").views[0].extra["colmap_model"] == "RADIAL"


def test_rational_camera_through_orient_and_back(tmp_path):
    """A FULL_OPENCV (rational) model imports as an opencv_full camera, the
    engine adjusts it (sigma0 at rounding level on exact data), and the
    results export as COLMAP binary with the same FULL_OPENCV camera."""
    import json

    from photogram_cli.main import main
    write_bin(tmp_path / "m", *scene("FULL_OPENCV"))
    prj = import_project("colmap", tmp_path / "m", tmp_path / "imp")
    assert main(["orient", "--no-report", "-q", str(prj), "--output", str(tmp_path / "out")]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["sigma0"] < 1e-9
    assert main(["export", "-q", "colmap-bin", str(tmp_path / "out"), "--to",
                 str(tmp_path / "back")]) == 0
    model, w, h, params = read_bin_cameras(tmp_path / "back" / "cameras.bin")[3]
    assert model == "FULL_OPENCV" and np.allclose(params, PARAMS["FULL_OPENCV"], rtol=1e-12)


def test_unknown_point_names_the_points_line(tmp_path):
    cams, images, points = scene("PINHOLE")
    write_txt(tmp_path / "t", cams, images, points[1:])       # point 100 missing
    with pytest.raises(InputError, match="POINT3D_ID 100 of image img_1.jpg") as err:
        read_colmap(tmp_path / "t")
    assert err.value.file.endswith("images.txt") and err.value.line == 5
    write_bin(tmp_path / "b", cams, images, points[1:])
    with pytest.raises(InputError, match=r"record 2: POINT3D_ID 100"):
        read_colmap(tmp_path / "b")


@pytest.mark.parametrize("name", ["cameras.bin", "images.bin", "points3D.bin", "rigs.bin",
                                  "frames.bin"])
def test_damaged_binary_files_give_one_line_errors(tmp_path, name):
    """Every truncation and a sample of byte flips of each binary file end
    in an InputError or a model, never in another exception."""
    write_bin(tmp_path / "m", *rig_scene())
    f = tmp_path / "m" / name
    data = f.read_bytes()
    rng = np.random.default_rng(5)
    cases = [data[:k] for k in range(0, len(data), max(1, len(data) // 60))]
    for _ in range(60):
        b = bytearray(data)
        b[int(rng.integers(len(b)))] ^= 1 << int(rng.integers(8))
        cases.append(bytes(b))
    for case in cases:
        f.write_bytes(case)
        try:
            read_colmap(tmp_path / "m")
        except InputError as err:
            assert err.file is not None and "\n" not in str(err)


def test_ids_outside_colmaps_integer_types_are_renumbered():
    K = np.array([[1500.0, 0, 960], [0, 1500.0, 540], [0, 0, 1]])
    views = [View(name=n, camera=c, K=K, dist=np.zeros(5), R_cv=np.eye(3), t_cv=np.zeros(3),
                  image_size=(1920, 1080)) for n, c in (("a", "99999999999"), ("b", "-1"))]
    rec = colmap_records(views, ["18446744073709551615", "5"], np.ones((2, 3)),
                         [(0, 0, 1.0, 2.0), (1, 1, 3.0, 4.0)])
    assert sorted(rec.cameras) == [1, 2] and list(rec.points.ids) == [1, 2]
    from photogram.io.colmap_binary import format_binary
    assert set(format_binary(rec)) == {"cameras.bin", "images.bin", "points3D.bin"}


def test_ids_given_twice(tmp_path):
    cams, images, points = scene("PINHOLE")
    write_txt(tmp_path / "t", cams, images, points + [points[3]])
    with pytest.raises(InputError, match="POINT3D_ID 103 is given twice") as err:
        read_colmap(tmp_path / "t")
    assert err.value.line == 32
    write_bin(tmp_path / "b", cams, images + [images[1][:4] + ("other.jpg", [])], points)
    with pytest.raises(InputError, match="record 5: IMAGE_ID 11 is given twice"):
        read_colmap(tmp_path / "b")


def test_sparse_folder_names_its_models(tmp_path):
    write_bin(tmp_path / "sparse" / "0", *scene("PINHOLE"))
    with pytest.raises(InputError, match="no cameras.txt here") as err:
        read_colmap(tmp_path / "sparse")
    assert "give one of: 0" in str(err.value)


def _same_pose(q, t, q2, t2):
    """Two COLMAP poses agree to 1e-12 (a quaternion and its negative are
    one rotation)."""
    q, q2 = np.asarray(q, float), np.asarray(q2, float)
    q2 = q2 if q @ q2 >= 0 else -q2
    return np.allclose(q, q2, rtol=0, atol=1e-12) and np.allclose(t, t2, rtol=0, atol=1e-12)


def _rig_records_by_name(rec):
    """Rigs as {rig_id: (ref camera, [(camera, q, t)])} and frames as
    {frame_id: (rig_id, q, t, sorted image NAMEs)}."""
    names = {im.image_id: im.name for im in rec.images}
    rigs = {r.rig_id: (r.ref, [(s[1], s[2], s[3]) for s in r.sensors]) for r in rec.rigs}
    frames = {f.frame_id: (f.rig_id, f.q, f.t, sorted(names[d] for _, _, d in f.data))
              for f in rec.frames}
    return rigs, frames


def _check_rigs_equal(a, b):
    ra, fa = _rig_records_by_name(a)
    rb, fb = _rig_records_by_name(b)
    assert ra.keys() == rb.keys() and fa.keys() == fb.keys()
    for k in ra:
        assert ra[k][0] == rb[k][0]
        for (ca, qa, ta), (cb, qb, tb) in zip(ra[k][1], rb[k][1]):
            assert ca == cb and (qa is None) == (qb is None)
            assert qa is None or _same_pose(qa, ta, qb, tb)
    for k in fa:
        assert fa[k][0] == fb[k][0] and fa[k][3] == fb[k][3]
        assert _same_pose(fa[k][1], fa[k][2], fb[k][1], fb[k][2])


@pytest.mark.parametrize("src", ["bin", "txt"])
@pytest.mark.parametrize("out", ["colmap", "colmap-bin"])
def test_rigs_and_frames_round_trip_exactly(tmp_path, out, src):
    """COLMAP (rigs, frames) -> photogram project (.prj with [rigs.1] and
    the stations' frame column) -> COLMAP: the same rigs, sensor poses,
    frames, frame poses (1e-12) and image poses."""
    (write_bin if src == "bin" else write_txt)(tmp_path / "m", *rig_scene())
    prj = import_project("colmap", tmp_path / "m", tmp_path / "imp")
    from photogram.project import read_project
    project = read_project(prj)
    assert list(project.rigs) == ["1"] and project.stations.frames()[:2] == ["1", "1"]
    export_results(out, prj, tmp_path / "back")
    a, _ = read_records(tmp_path / "m")
    b, is_bin = read_records(tmp_path / "back")
    assert is_bin == (out == "colmap-bin") and len(b.rigs) == 1 and len(b.frames) == 3
    _check_rigs_equal(a, b)
    for u, v in zip(read_colmap(tmp_path / "m").views, read_colmap(tmp_path / "back").views):
        assert u.name == v.name
        assert np.allclose(u.R_cv, v.R_cv, rtol=0, atol=1e-14)
        assert np.allclose(u.t_cv, v.t_cv, rtol=0, atol=1e-13)


def test_a_sensor_without_pose_round_trips_as_unknown(tmp_path):
    """HAS_POSE 0 (a sensor to be calibrated): the image poses come from
    images.*, the project rig has no pose for the camera, and the export
    writes HAS_POSE 0 again."""
    cams, images, points, rigs, frames = rig_scene()
    rigs = [(1, ("CAMERA", 1), [("CAMERA", 2, None, None)])]
    write_txt(tmp_path / "m", cams, images, points, rigs, frames)
    prj = import_project("colmap", tmp_path / "m", tmp_path / "imp")
    from photogram.project import read_project
    assert read_project(prj).rigs["1"].sensors == {}
    export_results("colmap", prj, tmp_path / "back")
    a, _ = read_records(tmp_path / "m")
    b, _ = read_records(tmp_path / "back")
    assert b.rigs[0].sensors[0][2:] == (None, None)
    _check_rigs_equal(a, b)


def test_rigs_survive_an_adjustment_and_the_export_of_its_results(tmp_path):
    """COLMAP rig -> project -> photogram's adjustment with the rig (6
    unknowns per frame + 6 for the second camera) -> export of the results
    folder: the same rigs and frames (noise-free: to 1e-12)."""
    import json

    from photogram_cli.main import main
    write_bin(tmp_path / "m", *rig_scene())
    prj = import_project("colmap", tmp_path / "m", tmp_path / "imp")
    assert main(["calibrate", "--no-report", str(prj)]) == 0
    res = prj.parent / "results"
    summary = json.loads((res / "summary.json").read_text())
    assert summary["counts"]["exterior"] == 6 * 3 + 6
    assert (res / "rigs.csv").is_file()
    written = export_results("colmap-bin", res, tmp_path / "back")
    assert {p.name for p in written} >= {"rigs.bin", "frames.bin"}
    a, _ = read_records(tmp_path / "m")
    b, _ = read_records(tmp_path / "back")
    _check_rigs_equal(a, b)
