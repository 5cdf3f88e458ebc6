"""Multi-camera calibration from a waved ChArUco board (issue 20, item 1):
aniposelib's CameraGroup.calibrate_rows and photogram's calibrate_rig (if
present) on the same detections of a rendered set with known truth
(photogram.simulation.board_rig), normal and harsh.

The set: 6 cameras (1280 x 720, 2-4 m from the volume's centre:
``board_rig.USABLE_DISTANCE``; ``--size 1920x1080 --distance 2,6`` for the
issue's 2-6 m, where the 8 cm squares are still decoded), 100 board poses
(pose 0 flat on the floor; a minute of waving sampled every 0.5 s),
target charuco:7x5:0.08:0.06:DICT_5X5_100, detected in every image with
``photogram.io.targets.detect``.

Figures per camera, after a similarity transform (Umeyama 1991, from the
camera centres) of each method's world frame onto the truth: centre error
(mm), rotation error (deg), focal length error (%); per method: the mean
reprojection error (px) of the corners seen by >= 2 cameras, triangulated
(linear, undistorted rays) with that method's cameras, and the wall time.
photogram's cameras are also compared without alignment, in the floor
frame (the board frame of pose 0), where it reports them.

aniposelib (``pip install aniposelib`` or ``.[bench-rig]``): its cameras
have one focal length and k1 free (principal point at
``cv2.initCameraMatrix2D``'s), its world frame is its first camera's, its
unit the board's (m); its bundle adjustment subsamples points with
``np.random`` (seeded here).

Run: .venv/bin/python benchmarks/board_rig.py [--cameras 6] [--poses 100]
     [--size 1280x720] [--distance 2,4]
     [--sets normal,harsh] [--write FOLDER]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import time

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np

from photogram.io.targets import parse_target
from photogram.simulation import board_rig as br


def umeyama(src, dst):
    """Similarity ``dst ~ s Q src + T`` by least squares (Umeyama 1991, eq.
    40-42)."""
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    U, S, Vt = np.linalg.svd(b.T @ a / len(src))
    D = np.eye(3)
    D[2, 2] = np.sign(np.linalg.det(U @ Vt))
    Q = U @ D @ Vt
    s = np.trace(np.diag(S) @ D) / (a ** 2).sum(1).mean()
    return s, Q, md - s * Q @ ms


def angle_deg(R):
    return math.degrees(math.acos(np.clip((np.trace(R) - 1) / 2, -1, 1)))


def triangulated_error(cams, detections):
    """Mean reprojection error (px) of the corners seen by >= 2 cameras,
    triangulated linearly from undistorted rays: ``cams`` {name: (K, dist,
    R, t)}."""
    import cv2
    obs = {}
    for name, frames in detections.items():
        K, dist, R, t = cams[name]
        for k, (ids, xy) in frames.items():
            xn = cv2.undistortPoints(xy.reshape(-1, 1, 2), K, dist,
                                     criteria=(3, 50, 1e-10)).reshape(-1, 2)
            for i, x, u in zip(ids, xn, xy):
                obs.setdefault((k, int(i)), []).append((name, x, u))
    errs = []
    for views in obs.values():
        if len(views) < 2:
            continue
        A = []
        for name, x, _ in views:
            _, _, R, t = cams[name]
            P = np.column_stack([R, t])
            A += [x[0] * P[2] - P[0], x[1] * P[2] - P[1]]
        X = np.linalg.svd(np.array(A))[2][-1]
        if abs(X[3]) < 1e-12:
            continue
        X = X[:3] / X[3]
        for name, _, u in views:
            K, dist, R, t = cams[name]
            p = cv2.projectPoints(X.reshape(1, 3), cv2.Rodrigues(R)[0], t, K, dist)[0]
            errs.append(np.linalg.norm(p.ravel() - u))
    return float(np.mean(errs)) if errs else math.nan


def compare(cameras, est, floor=None):
    """Per camera (centre mm, rotation deg, focal %) after the similarity
    from ``est`` centres to the truth; with ``floor`` = (R0, t0), also
    without alignment, the truth moved into the floor frame."""
    C_true = np.array([c.centre for c in cameras])
    C_est = np.array([-est[c.name][2].T @ est[c.name][3] for c in cameras])
    s, Q, T = umeyama(C_est, C_true)
    rows = []
    for c, ce in zip(cameras, C_est):
        K, _, R, _ = est[c.name]
        row = dict(centre=1000 * np.linalg.norm(s * Q @ ce + T - c.centre),
                   rot=angle_deg(R @ Q.T @ c.R.T),
                   focal=100 * (K[0, 0] / c.K[0, 0] - 1))
        if floor is not None:
            R0, t0 = floor                   # X_world = R0 X_floor + t0
            R_f, C_f = c.R @ R0, R0.T @ (c.centre - t0)
            row["centre_floor"] = 1000 * np.linalg.norm(ce - C_f)
            row["rot_floor"] = angle_deg(R @ R_f.T)
        rows.append(row)
    return rows, s


def run_anipose(cameras, detections, target, seed=0):
    from aniposelib.boards import CharucoBoard
    from aniposelib.cameras import CameraGroup
    bits = int(target.dictionary.split("_")[1][0])
    size = int(target.dictionary.split("_")[2])
    board = CharucoBoard(target.cols, target.rows, square_length=target.size,
                         marker_length=target.marker, marker_bits=bits, dict_size=size)
    group = CameraGroup.from_names([c.name for c in cameras])
    rows = []
    for cam, c in zip(group.cameras, cameras):
        cam.set_size(c.image_size)
        rows.append([{"framenum": k, "corners": xy.reshape(-1, 1, 2).astype(np.float32),
                      "ids": ids.reshape(-1, 1).astype(np.int32)}
                     for k, (ids, xy) in sorted(detections[c.name].items())])
    np.random.seed(seed)
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        error = group.calibrate_rows(rows, board, init_intrinsics=True, init_extrinsics=True,
                                     verbose=False)
    wall = time.perf_counter() - t0
    est = {}
    for cam, c in zip(group.cameras, cameras):
        import cv2
        est[c.name] = (np.asarray(cam.get_camera_matrix(), float),
                       np.asarray(cam.get_distortions(), float).ravel(),
                       cv2.Rodrigues(np.asarray(cam.get_rotation(), float))[0],
                       np.asarray(cam.get_translation(), float).ravel())
    return est, wall, float(error)


SIGMAS = {}           # camera -> photogram's (centre sigma mm, rotation sigma deg)


def run_photogram(cameras, detections, target):
    try:
        from photogram.rig import calibrate_rig
    except ImportError:
        print("photogram rig: not available")
        return None, math.nan
    sizes = {c.name: c.image_size for c in cameras}
    floor = 0 if any(0 in d for d in detections.values()) else None
    t0 = time.perf_counter()
    # the rendered lenses have k3 (fix_k3=False); the floor pose is pose 0
    result = calibrate_rig(detections, sizes, target, floor_frame=floor, fix_k3=False)
    print(f"photogram: sigma0 {result.sigma0:.3f}, views left out "
          f"{len(result.summary['rejected_views'])}, corners left out "
          f"{result.summary['rejected_corners']}, floor frame "
          f"{result.floor_frame if floor is not None else 'not detected: none'}")
    wall = time.perf_counter() - t0
    for c in cameras:                      # photogram's own sigmas, for the floor frame
        rc = result.cameras[c.name]
        SIGMAS[c.name] = (1000 * rc.centre_sigma,
                          math.sqrt(sum(rc.sigmas[k] ** 2 for k in ("rx", "ry", "rz"))))
    est = {c.name: (np.asarray(result.cameras[c.name].K, float),
                    np.asarray(result.cameras[c.name].dist, float).ravel(),
                    np.asarray(result.cameras[c.name].R, float),
                    np.asarray(result.cameras[c.name].t, float).ravel()) for c in cameras}
    return est, wall


def render_and_detect(name, args, target):
    settings = br.normal_settings(seed=args.seed) if name == "normal" else \
        br.harsh_settings(seed=args.seed + 1)
    w, h = (int(v) for v in args.size.split("x"))
    distance = tuple(float(v) for v in args.distance.split(",")) if args.distance else \
        br.USABLE_DISTANCE
    cameras = br.rig_cameras(args.cameras, seed=args.seed, image_size=(w, h), distance=distance)
    poses = br.board_poses(args.poses, seed=args.seed, cameras=cameras, target=target,
                           partly_outside=settings.partly_outside)
    t0 = time.perf_counter()
    images = br.render_rig(cameras, poses, target, settings)
    t_render = time.perf_counter() - t0
    if args.write:
        br.write_rig_set(f"{args.write}/{name}", cameras, poses, target, settings,
                         images=images)
    t0 = time.perf_counter()
    detections, err = br.detect_rig(cameras, images, target), []
    for c in cameras:
        for k, (ids, xy_det) in detections[c.name].items():
            xy, _ = br.true_corners(c, poses[k], target)
            err.append(np.linalg.norm(xy_det - xy[ids], axis=1))
    t_detect = time.perf_counter() - t0
    seen = np.zeros(len(poses), int)
    for frames in detections.values():
        for k in frames:
            seen[k] += 1
    err = np.concatenate(err)
    print(f"\n== {name}: {args.cameras} cameras, {args.poses} poses; render {t_render:.0f} s, "
          f"detect {t_detect:.0f} s")
    print(f"views with the board detected: {sum(len(f) for f in detections.values())} of "
          f"{args.cameras * args.poses}; poses seen by >= 2 cameras: {np.mean(seen >= 2):.0%}; "
          f"floor pose (0) in {seen[0]} cameras")
    print(f"detected corners vs truth: {len(err)} corners, RMS {np.sqrt(np.mean(err ** 2)):.3f} "
          f"px, median {np.median(err):.3f} px, > 1 px: {np.mean(err > 1):.1%}")
    return cameras, poses, detections


def report(label, cameras, est, detections, wall, floor=None):
    rows, s = compare(cameras, est, floor)
    cams = {c.name: est[c.name] for c in cameras}
    rep = triangulated_error(cams, detections)
    print(f"{label}: wall {wall:.1f} s, reprojection (triangulated) {rep:.3f} px, "
          f"similarity scale {s:.4f}")
    for c, r in zip(cameras, rows):
        extra = (f"  | floor frame: {r['centre_floor']:7.1f} mm {r['rot_floor']:6.3f} deg"
                 if "centre_floor" in r else "")
        if "centre_floor" in r and c.name in SIGMAS and label == "photogram":
            extra += (f"  (sigmas {SIGMAS[c.name][0]:.1f} mm {SIGMAS[c.name][1]:.3f} deg)")
        dist = np.linalg.norm(c.centre - br.VOLUME_CENTRE)
        print(f"  {c.name} ({dist:.1f} m): centre {r['centre']:7.1f} mm  rotation {r['rot']:6.3f} deg  "
              f"focal {r['focal']:+6.2f} %{extra}")
    out = dict(centre_mm=np.mean([r["centre"] for r in rows]),
               deg=np.mean([r["rot"] for r in rows]),
               focal_pct=np.mean([abs(r["focal"]) for r in rows]), px=rep, s=wall)
    if floor is not None:
        out["floor_mm"] = np.mean([r["centre_floor"] for r in rows])
        out["floor_deg"] = np.mean([r["rot_floor"] for r in rows])
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cameras", type=int, default=6)
    ap.add_argument("--poses", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--size", default="1280x720", help="image size WxH (px)")
    ap.add_argument("--distance", default=None,
                    help="camera distances from the volume's centre, MIN,MAX (m); "
                         "default: the board's usable range at 1280 x 720, 2,4")
    ap.add_argument("--sets", default="normal,harsh")
    ap.add_argument("--write", default=None, help="also write the rendered sets here")
    args = ap.parse_args()
    target = parse_target(br.TARGET_SPEC)
    result = {}
    for name in args.sets.split(","):
        cameras, poses, detections = render_and_detect(name, args, target)
        a, p = {}, {}
        try:
            est, wall, err = run_anipose(cameras, detections, target, seed=args.seed)
            print(f"aniposelib's own final error: {err:.3f} px")
            a = report("aniposelib", cameras, est, detections, wall)
        except ImportError:
            print("aniposelib: not installed (pip install aniposelib)")
        except Exception as exc:            # its failure is a result: reported, nan
            print(f"aniposelib: failed ({type(exc).__name__}: {exc})")
        try:
            est, wall = run_photogram(cameras, detections, target)
            if est is not None:
                p = report("photogram", cameras, est, detections, wall,
                           br.floor_frame(poses) if any(0 in d for d in detections.values())
                           else None)
        except Exception as exc:
            print(f"photogram rig: failed ({type(exc).__name__}: {exc})")
        for tag, figures, keys in (("anipose", a, ()),
                                   ("photogram", p, ("floor_mm", "floor_deg"))):
            for key in ("centre_mm", "deg", "focal_pct", "px", "s") + keys:
                result[f"{name}_{tag}_{key}"] = figures.get(key, math.nan)
    print("RESULT " + " ".join(f"{k}={v:.4g}" for k, v in result.items()))


if __name__ == "__main__":
    main()
