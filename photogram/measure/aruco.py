"""ArUco markers as coded targets (OpenCV's aruco module).

A square marker carries its id in its bit pattern; OpenCV finds the
markers (``cv2.aruco.ArucoDetector``, corners refined to subpixel with
``CORNER_REFINE_SUBPIX``) and photogram uses each marker as **one point,
its centre**: the intersection of the diagonals of its four corners. OpenCV's
corner refinement is not enough for that (on rendered truth its corners
were off by 0.2-1.9 px in oblique views), so the corners are measured again
(:func:`refine_quads`): subpixel edge points across each of the four sides
of the marker's black border (mid-level crossing between paper and border,
as for the circles), a straight line fitted to each side (total least
squares, outlying points dropped), corners where adjacent lines meet. The
centre of a square is the intersection of its diagonals and a homography
maps lines to lines, so the image of the centre is exactly the
intersection of the imaged diagonals: no eccentricity, unlike a circle
(lens distortion over the marker aside).

In the target-field description::

    [aruco]
    dictionary = "DICT_4X4_50"   # any cv2.aruco.DICT_*
    sigma = 0.05                 # px, centre sigma written for a marker

    [[aruco.marker]]
    id = 7                       # the marker's id in the dictionary
    point = "M7"                 # its point id (default "M{id}")
    xyz = [0.0, 0.5, 0.0]        # object coordinates of its centre

Markers of the dictionary that are not in the description are counted and
ignored; a marker id seen twice in one image is dropped (both).
"""

from __future__ import annotations

import numpy as np

__all__ = ["detect_markers", "diagonal_centre", "inside_quads", "refine_quads"]


def diagonal_centre(corners: np.ndarray) -> np.ndarray:
    """Intersection of the diagonals (0-2, 1-3) of quadrilaterals (n, 4, 2)."""
    c = np.asarray(corners, float)
    h = np.concatenate([c, np.ones(c.shape[:2] + (1,))], axis=2)
    d1 = np.cross(h[:, 0], h[:, 2])
    d2 = np.cross(h[:, 1], h[:, 3])
    p = np.cross(d1, d2)
    return p[:, :2] / p[:, 2:3]


def detect_markers(gray: np.ndarray, dictionary: str):
    """ArUco markers in an image.

    Returns
    -------
    ids : (n,) int, corners : (n, 4, 2) px (OpenCV frame, pixel centres at
    integers), centres : (n, 2) the diagonal intersections
    """
    import cv2
    dic = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    params.cornerRefinementWinSize = 5
    params.cornerRefinementMaxIterations = 100
    params.cornerRefinementMinAccuracy = 0.001
    detector = cv2.aruco.ArucoDetector(dic, params)
    corners, ids, _ = detector.detectMarkers(np.ascontiguousarray(gray))
    if ids is None or len(ids) == 0:
        return np.zeros(0, int), np.zeros((0, 4, 2)), np.zeros((0, 2))
    quads = np.array([q.reshape(4, 2) for q in corners], float)
    quads = refine_quads(gray, quads, dic.markerSize + 2)
    quads = refine_quads(gray, quads, dic.markerSize + 2, min_half=1.8)   # closer window
    return ids.ravel().astype(int), quads, diagonal_centre(quads)


def _line(p):
    """Total-least-squares line (a, b, c), a x + b y + c = 0, |(a, b)| = 1."""
    m = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - m)
    n = vt[1]
    return np.array([n[0], n[1], -n @ m])


def refine_quads(gray: np.ndarray, quads: np.ndarray, cells: int, k: int = 24,
                 m: int = 33, min_half: float = 2.5) -> np.ndarray:
    """Corners of markers from lines fitted to subpixel edge points of their sides.

    Parameters
    ----------
    gray : the image (marker border dark on light paper)
    quads : (n, 4, 2) approximate corners (OpenCV's order, around the marker)
    cells : cells across a marker (bits + 2 border cells)
    k : edge points per side (between 15 % and 85 % of the side)
    m : samples per profile, across +- 0.45 of a border cell (at least
        ``min_half`` px; a second pass with a smaller window follows the first)

    Returns
    -------
    (n, 4, 2) refined corners; a marker whose sides cannot be measured
    keeps OpenCV's corners.
    """
    import cv2
    quads = np.asarray(quads, float)
    n = len(quads)
    if n == 0:
        return quads
    img = np.asarray(gray, np.float32)
    a = quads
    b = np.roll(quads, -1, axis=1)                       # side i: corner i -> i + 1
    side = b - a
    length = np.linalg.norm(side, axis=2)
    u = side / length[..., None]
    centre = quads.mean(axis=1)
    normal = np.stack([u[..., 1], -u[..., 0]], axis=2)
    mid = 0.5 * (a + b)
    flip = ((mid - centre[:, None]) * normal).sum(axis=2) < 0
    normal[flip] *= -1                                    # pointing out of the marker
    half = np.maximum(min_half, 0.45 * length / cells)    # (n, 4)
    f = np.linspace(0.15, 0.85, k)
    s = np.linspace(-1, 1, m)
    base = a[:, :, None, :] + f[None, None, :, None] * side[:, :, None, :]     # (n,4,k,2)
    off = half[:, :, None, None] * s[None, None, None, :]                     # (n,4,1,m)
    P = base[:, :, :, None, :] + off[..., None] * normal[:, :, None, None, :]  # (n,4,k,m,2)
    prof = cv2.remap(img, P[..., 0].reshape(-1, m).astype(np.float32),
                     P[..., 1].reshape(-1, m).astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE).reshape(n, 4, k, m).astype(float)
    inner = np.median(prof[..., :3].mean(axis=-1), axis=2)       # the black border
    outer = np.median(prof[..., -3:].mean(axis=-1), axis=2)      # the paper
    level = 0.5 * (inner + outer)[..., None, None]
    above = prof > level
    up = ~above[..., :-1] & above[..., 1:]                        # dark -> light going out
    has = up.any(axis=-1)
    j = np.argmax(up, axis=-1)
    p0 = np.take_along_axis(prof, j[..., None], -1)[..., 0]
    p1 = np.take_along_axis(prof, j[..., None] + 1, -1)[..., 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (level[..., 0] - p0) / (p1 - p0)
    step = 2 * half[..., None] / (m - 1)
    d = -half[..., None] + (j + np.nan_to_num(t)) * step                      # (n,4,k)
    pts = base + d[..., None] * normal[:, :, None, :]
    out = quads.copy()
    for i in range(n):
        if (outer[i] - inner[i] < 10).any():
            continue
        lines = []
        for e in range(4):
            q = pts[i, e][has[i, e]]
            if len(q) < k // 2:
                break
            ln = _line(q)
            r = q @ ln[:2] + ln[2]
            keep = np.abs(r) <= max(0.3, 3.5 * 1.4826 * np.median(np.abs(r)))
            lines.append(_line(q[keep]) if keep.sum() >= k // 3 else ln)
        if len(lines) < 4:
            continue
        new = np.empty((4, 2))
        for c in range(4):
            p = np.cross(lines[c - 1], lines[c])              # corner c: sides c-1 and c
            new[c] = p[:2] / p[2]
        if np.linalg.norm(new - quads[i], axis=1).max() < 0.3 * length[i].mean():
            out[i] = new
    return out


def inside_quads(xy: np.ndarray, quads: np.ndarray, grow: float = 1.15) -> np.ndarray:
    """Which points lie inside any of the quadrilaterals (grown about their
    centres by ``grow``): dots found on a marker's cells are not targets."""
    import cv2
    out = np.zeros(len(xy), bool)
    for q in quads:
        c = q.mean(axis=0)
        g = (c + grow * (q - c)).astype(np.float32)
        for i, p in enumerate(xy):
            if not out[i] and cv2.pointPolygonTest(g, (float(p[0]), float(p[1])), False) >= 0:
                out[i] = True
    return out
