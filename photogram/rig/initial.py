"""Start values of a multi-camera rig calibrated from a board.

1. Intrinsics and the board's pose in every camera's frames: OpenCV's
   ``calibrateCamera`` (Zhang's method: homographies, closed form, then its
   own Levenberg-Marquardt) on each camera's detections alone.
2. The cameras' relative poses: for every pair of cameras that see the
   board in the same frame, ``T_ij = T_ib T_jb^-1`` (``T_cb`` board to
   camera, OpenCV convention ``x = R X + t``); the pairs' estimates are
   averaged (chordal mean of the rotations, median of the translations)
   and chained along a spanning tree of the camera graph that prefers the
   pairs with the most shared frames (as aniposelib and caliscope do).
3. Every board pose in the world from the camera that sees it with the
   most corners.

All transforms are 4 x 4 homogeneous matrices in OpenCV's convention.
"""

from __future__ import annotations

import collections
import copy
import hashlib

import numpy as np

from photogram.errors import InputError

__all__ = ["camera_intrinsics", "chordal_mean", "relative_poses", "spanning_tree",
           "initial_rig", "planar_view_ok"]


def _T(R, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.ravel(t)
    return T


def _inv(T) -> np.ndarray:
    R, t = T[:3, :3], T[:3, 3]
    return _T(R.T, -R.T @ t)


def chordal_mean(Rs) -> np.ndarray:
    """The rotation nearest (Frobenius) to the mean of rotation matrices
    (the chordal L2 mean; Hartley et al. 2013, "Rotation averaging")."""
    M = np.sum(np.asarray(Rs, dtype=float), axis=0)
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def planar_view_ok(board_points, xy, min_ratio: float = 0.05) -> bool:
    """Whether a view of a planar board can start a calibration: its
    corners are not (nearly) on one line of the board (the smaller singular
    value of the centred board coordinates at least ``min_ratio`` of the
    larger) and their homography exists (``cv2.findHomography``). A view
    failing either makes ``cv2.calibrateCamera``'s ``initIntrinsicParams2D``
    stop with an assertion (seen on rendered harsh sets: ChArUco corners
    decoded along one row)."""
    import cv2
    P = np.asarray(board_points, float)[:, :2]
    s = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
    if len(P) < 4 or s[0] <= 0 or s[1] < min_ratio * s[0]:
        return False
    H, _ = cv2.findHomography(P.astype(np.float64), np.asarray(xy, np.float64).reshape(-1, 2))
    return H is not None and bool(np.all(np.isfinite(H)))


def camera_intrinsics(frames: dict, board_points: np.ndarray, image_size, *,
                      fix_k3: bool = True, name: str = "camera", fisheye: bool = False):
    """OpenCV's calibration of one camera from its own detections
    (``cv2.calibrateCamera``, or ``cv2.fisheye.calibrate`` for the fisheye
    model: then ``dist`` holds k1..k4).

    Parameters
    ----------
    frames : dict frame -> (ids (n,), xy (n, 2))
    board_points : (m, 3) the board's points in its frame (ids index rows)
    image_size : (w, h)

    Returns
    -------
    K : (3, 3), dist : (5,), poses : dict frame -> T_cb (4, 4), rms : float
    """
    import cv2
    keys = [f for f, (ids, xy) in frames.items()
            if len(ids) >= 6 and planar_view_ok(board_points[ids], xy)]
    if len(keys) < 3:
        raise InputError(f"camera {name}: the board is seen in {len(keys)} frame(s) with at "
                         "least 6 corners; a calibration needs 3 or more",
                         hint="film the board closer to this camera, at several tilts")
    obj = [board_points[frames[f][0]].astype(np.float32) for f in keys]
    img = [frames[f][1].astype(np.float32).reshape(-1, 1, 2) for f in keys]
    size = tuple(int(v) for v in image_size)
    if fisheye:
        rms, K, dist, rvecs, tvecs = _fisheye_start(obj, img, size, name)
    else:
        rms, K, dist, rvecs, tvecs = _pinhole_start(obj, img, size, name, fix_k3)
    poses = {}
    for f, r, t in zip(keys, rvecs, tvecs):
        poses[f] = _T(cv2.Rodrigues(np.asarray(r, float))[0], np.asarray(t, float))
    n = 4 if fisheye else 5
    return K, np.asarray(dist, float).ravel()[:n], poses, float(rms)


#: Focal lengths (in image widths) from which :func:`_pinhole_start` also
#: starts OpenCV's calibration, beside OpenCV's own start.
FOCAL_STARTS = (0.5, 0.7, 1.0, 1.4, 2.0)


#: The last few :func:`_pinhole_start` results by their exact inputs (the
#: six OpenCV calibrations are most of a rig calibration's CPU; the same
#: camera's detections come back unchanged when a calibration is run again
#: with one camera's views changed, or with other scene points).
_STARTS: collections.OrderedDict = collections.OrderedDict()
_STARTS_SIZE = 16


def _start_key(obj, img, size, fix_k3) -> tuple:
    """The exact inputs of :func:`_pinhole_start` as a hashable key (a
    SHA-1 of every array's dtype, shape and bytes)."""
    h = hashlib.sha1()
    for a in (*obj, *img):
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest(), len(obj), tuple(size), bool(fix_k3)


def _pinhole_start(obj, img, size, name, fix_k3):
    """``cv2.calibrateCamera`` from OpenCV's own start (``initCameraMatrix2D``
    from the views' homographies) and from the focal lengths
    :data:`FOCAL_STARTS` with the principal point at the centre; the
    solution of least RMS. OpenCV's start alone can end in a local minimum
    when the views are small and near fronto-parallel (seen on a rendered
    harsh set at 1920 x 1080: a camera at 3.7 m got f 21 % off with 1.7 px
    RMS, where a start at 0.7 image widths gives 0.13 px and 0.7 %).

    OpenCV is deterministic: a result is kept for the same inputs
    (``_STARTS``, the last ``_STARTS_SIZE``) and returned as a copy."""
    key = _start_key(obj, img, size, fix_k3)
    if key in _STARTS:
        _STARTS.move_to_end(key)
    else:
        _STARTS[key] = _pinhole_starts(obj, img, size, name, fix_k3)
        while len(_STARTS) > _STARTS_SIZE:
            _STARTS.popitem(last=False)
    return copy.deepcopy(_STARTS[key])


def _pinhole_starts(obj, img, size, name, fix_k3):
    """:func:`_pinhole_start` computed."""
    import cv2
    flags = cv2.CALIB_FIX_K3 if fix_k3 else 0
    w, h = size
    best, last_error = None, None
    for scale in (None,) + FOCAL_STARTS:
        if scale is None:
            K0, extra = None, 0
        else:
            K0 = np.array([[scale * w, 0.0, (w - 1) / 2], [0.0, scale * w, (h - 1) / 2],
                           [0.0, 0.0, 1.0]])
            extra = cv2.CALIB_USE_INTRINSIC_GUESS
        try:
            out = cv2.calibrateCamera(obj, img, size, K0, None, flags=flags | extra)
        except cv2.error as exc:
            last_error = exc
            continue
        if np.isfinite(out[0]) and (best is None or out[0] < best[0]):
            best = out
    if best is None:
        raise InputError(f"camera {name}: OpenCV's calibration gives no start "
                         f"({str(last_error).strip().splitlines()[-1]})",
                         hint="more board views at several tilts, each with corners "
                              "over the whole board")
    return best


def _fisheye_start(obj, img, size, name):
    """``cv2.fisheye.calibrate`` (skew fixed, extrinsics recomputed per
    iteration) from the pinhole start of ``initCameraMatrix2D``."""
    import cv2
    K0 = cv2.initCameraMatrix2D(obj, img, size)
    flags = (cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
             | cv2.fisheye.CALIB_USE_INTRINSIC_GUESS)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-10)
    try:
        rms, K, D, rvecs, tvecs = cv2.fisheye.calibrate(
            [o.reshape(-1, 1, 3).astype(np.float64) for o in obj],
            [x.reshape(-1, 1, 2).astype(np.float64) for x in img], size, K0, np.zeros(4),
            flags=flags, criteria=crit)
    except cv2.error as exc:
        raise InputError(f"camera {name}: OpenCV's fisheye calibration gives no start "
                         f"({str(exc).strip().splitlines()[-1]})",
                         hint="more board views at several tilts, or model = \"opencv\" for "
                              "a lens of moderate field of view") from None
    return rms, K, D, rvecs, tvecs


def relative_poses(poses: dict) -> dict:
    """Pairwise camera poses from shared frames.

    Parameters
    ----------
    poses : dict camera -> dict frame -> T_cb

    Returns
    -------
    dict (i, j) -> (T_ij (4, 4) mapping camera j's frame to camera i's,
    number of shared frames)
    """
    names = list(poses)
    out = {}
    for a, i in enumerate(names):
        for j in names[a + 1:]:
            shared = sorted(set(poses[i]) & set(poses[j]))
            if not shared:
                continue
            Ts = [poses[i][f] @ _inv(poses[j][f]) for f in shared]
            T = _robust_mean(Ts)
            out[(i, j)] = (T, len(shared))
            out[(j, i)] = (_inv(T), len(shared))
    return out


def _angle_deg(Ra, Rb) -> float:
    c = (np.trace(Ra.T @ Rb) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _robust_mean(Ts, max_deg: float = 3.0):
    """Mean of rigid transforms: the chordal mean of the rotations and the
    median of the translations, then again over those within ``max_deg``
    and 5 % of the translation's length of it (a board numbered the other
    way round in one camera gives a frame 180 degrees off)."""
    Rs = np.array([T[:3, :3] for T in Ts])
    ts = np.array([T[:3, 3] for T in Ts])
    R, t = chordal_mean(Rs), np.median(ts, axis=0)
    ok = np.array([_angle_deg(R, Ri) < max_deg and np.linalg.norm(ti - t)
                   < 0.05 * max(np.linalg.norm(t), 1e-12) for Ri, ti in zip(Rs, ts)])
    if ok.sum() >= max(1, len(Ts) // 2) and not ok.all():
        R, t = chordal_mean(Rs[ok]), np.median(ts[ok], axis=0)
    return _T(R, t)


def spanning_tree(names, pairs: dict, reference):
    """Camera -> (parent, T_child_parent): a maximum spanning tree of the
    camera graph weighted by shared frames (Prim's algorithm from
    ``reference``). Raises InputError naming the cameras that share no
    frame with the rest."""
    tree = {reference: (None, np.eye(4))}
    while len(tree) < len(names):
        best = None
        for (i, j), (T, n) in pairs.items():
            if j in tree and i not in tree and (best is None or n > best[2]):
                best = (i, j, n, T)
        if best is None:
            lost = [c for c in names if c not in tree]
            raise InputError(f"camera(s) {', '.join(lost)} never see the board in the same "
                             f"frame as camera {reference} or the cameras linked to it",
                             hint="wave the board where these cameras and the others see it "
                                  "at the same time")
        i, j, _, T = best
        tree[i] = (j, T)
    return tree


def initial_rig(detections: dict, board_points: np.ndarray, image_sizes: dict, *,
                fix_k3: bool = True, reference=None, fisheye: bool = False):
    """Start values of every camera and board pose (module doc).

    Returns
    -------
    dict with ``K`` {camera: (3, 3)}, ``dist`` {camera: (5,)}, ``T_cw``
    {camera: world-to-camera (4, 4)} with the world = the reference
    camera's frame, ``T_wb`` {frame: board-to-world (4, 4)}, ``rms``
    {camera: OpenCV's RMS}, ``reference``.
    """
    names = list(detections)
    K, dist, poses, rms = {}, {}, {}, {}
    for c in names:
        K[c], dist[c], poses[c], rms[c] = camera_intrinsics(
            detections[c], board_points, image_sizes[c], fix_k3=fix_k3, name=c,
            fisheye=fisheye)
    if reference is None:        # the camera that shares the most frames
        count = {c: sum(len(set(poses[c]) & set(poses[d])) for d in names if d != c)
                 for c in names}
        reference = max(names, key=lambda c: count[c])
    pairs = relative_poses(poses)
    tree = spanning_tree(names, pairs, reference)
    T_cw = {}

    def world_to(c):
        if c not in T_cw:
            parent, T = tree[c]
            T_cw[c] = np.eye(4) if parent is None else T @ world_to(parent)
        return T_cw[c]
    for c in names:
        world_to(c)
    T_wb = {}
    frames = sorted({f for c in names for f in poses[c]})
    for f in frames:
        # the camera whose board pose agrees with the most others (then the
        # most corners): a view numbered the other way round is outvoted
        seen = [c for c in names if f in poses[c]]
        cand = {c: _inv(T_cw[c]) @ poses[c][f] for c in seen}
        votes = {c: sum(_angle_deg(cand[c][:3, :3], cand[d][:3, :3]) < 5.0 for d in seen)
                 for c in seen}
        c = max(seen, key=lambda c: (votes[c], len(detections[c][f][0])))
        T_wb[f] = cand[c]
    return {"K": K, "dist": dist, "T_cw": T_cw, "T_wb": T_wb, "rms": rms,
            "reference": reference}
