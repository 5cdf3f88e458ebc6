"""Numbering the targets of a planar field from its coded targets.

In one image the decoded coded targets give the plane-to-image mapping:
a homography from four or more codes (an affinity from three; direct
linear solution, Hartley & Zisserman, *Multiple View Geometry*, 2nd ed.,
alg. 4.2 with normalisation, via ``cv2.findHomography``). It predicts every
uncoded target of the layout; a prediction takes the nearest plain dot
within a gate of ``gate`` times the local grid spacing in the image (the
distance between the predictions of neighbouring nodes), one-to-one (a
dot claimed by two nodes goes to the nearer, and the other node stays
empty). The homography is then fitted again by least squares to every
numbered dot and the prediction repeated until the numbering no longer
changes, so that lens distortion and the approximate start are absorbed
step by step (the gate stays small compared with half the spacing, which
is what keeps a dot from being given its neighbour's number).

**Consistency.** Codes that disagree with the layout are caught: a code
id decoded twice in one image is dropped (both, a *problem*); the
homography of the codes must keep the sheet's handedness (a sheet is seen
from its front: plane X right / Y up maps to image x right / y down with a
negative Jacobian determinant; two codes swapped on the sheet or in the
description give a mirrored mapping, a *conflict*); and after the numbering
each code's residual from the homography of the grid dots alone must be
within the gate (otherwise a *conflict*). Conflicts stop the command.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Numbering", "number_plane"]

log = logging.getLogger("photogram")


@dataclass
class Numbering:
    """Labels of the detections of one image."""

    labels: np.ndarray                 # (n,) object: point id or "" (unnumbered)
    homography: np.ndarray | None      # plane (X, Y) -> image px
    problems: list[str] = field(default_factory=list)
    iterations: int = 0
    conflicts: list[str] = field(default_factory=list)


def _predict(H, XY):
    p = np.column_stack([XY, np.ones(len(XY))]) @ H.T
    return p[:, :2] / p[:, 2:3]


def _fit(XY, xy):
    import cv2
    if len(XY) >= 4:
        H, _ = cv2.findHomography(XY.astype(np.float64), xy.astype(np.float64), 0)
        if H is not None:
            return H
    if len(XY) >= 3:
        A, _ = cv2.estimateAffine2D(XY.astype(np.float64), xy.astype(np.float64),
                                    method=cv2.LMEDS) if len(XY) > 3 else \
            (cv2.getAffineTransform(XY[:3].astype(np.float32), xy[:3].astype(np.float32)), None)
        if A is not None:
            return np.vstack([A, [0.0, 0.0, 1.0]])
    return None


def number_plane(xy: np.ndarray, code_label: np.ndarray, code_ids: list[str],
                 code_XY: np.ndarray, grid_ids: list[str], grid_XY: np.ndarray,
                 spacing: float, *, gate: float = 0.3, max_iter: int = 20,
                 image: str = "") -> Numbering:
    """Number the dots of one image (module doc).

    Parameters
    ----------
    xy : (n, 2)            dot centres in the image (px)
    code_label : (n,)      decoded code id, "" for a plain dot, None for a rejected ring
    code_ids, code_XY      the field's codes and their plane coordinates (k, 2)
    grid_ids, grid_XY      the uncoded layout (m, 2)
    spacing : float        grid spacing (object units), the scale of the gate
    gate : float           gate radius as a fraction of the local spacing in the image
    image : str            the image's name for messages

    Returns
    -------
    Numbering
    """
    from scipy.spatial import cKDTree
    n = len(xy)
    labels = np.full(n, "", dtype=object)
    problems = []
    code_pos = {c: k for k, c in enumerate(code_ids)}
    found = {}
    for i, lab in enumerate(code_label):
        if lab:
            found.setdefault(lab, []).append(i)
    for cid, idx in found.items():
        if len(idx) > 1:
            problems.append(f"{image}: code {cid} decoded {len(idx)} times; none of them used")
            continue
        if cid in code_pos:
            labels[idx[0]] = cid
    have = [c for c in code_ids if c in labels]
    if len(have) < 3:
        problems.append(f"{image}: {len(have)} coded target(s) decoded; at least 3 are needed "
                        f"to number the grid")
        return Numbering(labels, None, problems)
    cidx = np.array([np.nonzero(labels == c)[0][0] for c in have])
    cXY = code_XY[[code_pos[c] for c in have]]
    H = _fit(cXY, xy[cidx])
    conflicts = []
    if H is not None:
        m = cXY.mean(axis=0)
        J = np.column_stack([(_predict(H, [m + [1e-3 * spacing, 0]]) - _predict(H, [m]))[0],
                             (_predict(H, [m + [0, 1e-3 * spacing]]) - _predict(H, [m]))[0]])
        if np.linalg.det(J) > 0:
            conflicts.append(f"{image}: the codes {', '.join(have)} are seen mirrored: they "
                             f"disagree with the layout of the target field")
            return Numbering(labels, None, problems, 0, conflicts)
    if H is None or len(grid_XY) == 0:
        return Numbering(labels, H, problems, 0, conflicts)
    plain = np.nonzero(code_label == "")[0]
    if len(plain) == 0:
        return Numbering(labels, H, problems, 0, conflicts)
    tree = cKDTree(xy[plain])
    assign = np.full(len(grid_XY), -1)
    it = 0
    for it in range(1, max_iter + 1):
        P = _predict(H, grid_XY)
        Px = _predict(H, grid_XY + [spacing, 0.0])
        Py = _predict(H, grid_XY + [0.0, spacing])
        local = np.minimum(np.linalg.norm(Px - P, axis=1), np.linalg.norm(Py - P, axis=1))
        ok = np.isfinite(P).all(axis=1)
        d, j = tree.query(np.where(ok[:, None], P, 1e12), k=1)
        new = np.where(ok & (d < gate * local), plain[np.minimum(j, len(plain) - 1)], -1)
        new = nearest_claim_wins(new, d)   # a dot claimed twice goes to the nearer node
        if np.array_equal(new, assign):
            break
        assign = new
        sel = assign >= 0
        XY = np.vstack([grid_XY[sel], cXY])
        H2 = _fit(XY, np.vstack([xy[assign[sel]], xy[cidx]]))
        if H2 is None:
            break
        H = H2
    sel = assign >= 0
    for g in np.nonzero(sel)[0]:
        labels[assign[g]] = grid_ids[g]
    # codes against the homography of the grid dots alone
    if sel.sum() >= 8:
        Hg = _fit(grid_XY[sel], xy[assign[sel]])
        if Hg is not None:
            P = _predict(Hg, cXY)
            Px = _predict(Hg, cXY + [spacing, 0.0])
            local = np.linalg.norm(Px - P, axis=1)
            bad = np.linalg.norm(P - xy[cidx], axis=1) > gate * local
            for k in np.nonzero(bad)[0]:
                conflicts.append(f"{image}: code {have[k]} is "
                                 f"{np.linalg.norm(P[k] - xy[cidx[k]]):.1f} px from where the "
                                 f"grid puts it: it disagrees with the layout")
                labels[cidx[k]] = ""
    return Numbering(labels, H, problems, it, conflicts)


def nearest_claim_wins(claims, distance):
    """One-to-one assignment: where several predictions claim the same
    detection, only the nearest keeps it.

    Parameters
    ----------
    claims : ndarray (n,) of int
        The detection each prediction claims (-1: none).
    distance : ndarray (n,)
        The distance of each prediction to its detection.

    Returns
    -------
    ndarray (n,) of int
        ``claims`` with every claim but the nearest of each detection set to
        -1.
    """
    claims = np.asarray(claims).copy()
    order = np.argsort(distance, kind="stable")
    order = order[claims[order] >= 0]
    _, first = np.unique(claims[order], return_index=True)
    keep = np.zeros(len(claims), dtype=bool)
    keep[order[first]] = True
    claims[~keep] = -1
    return claims
