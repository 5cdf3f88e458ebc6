"""Numbering the targets of a 3D field (a test frame) from its coded targets.

With six or more coded targets (ring codes or ArUco markers) decoded in an
image, not all in one plane, the direct linear transformation
(:func:`photogram.init.dlt.dlt`, Abdel-Aziz & Karara 1971; Hartley &
Zisserman alg. 7.1) gives the image's projection matrix from their
approximate 3D coordinates; it predicts every uncoded target of the field's
table. A prediction takes the nearest plain detection within ``gate``
times the distance to the nearest *other* prediction (so that two targets
that appear close together in this view cannot swap), if the second
nearest detection is at least twice as far and the detection's nearest
prediction is this target (mutual), one-to-one; the
projection matrix is computed again from everything numbered and the
prediction repeated until the numbering no longer changes. Targets behind
the camera or outside the image are not predicted.

Lens distortion is not in the DLT: the iteration absorbs what it can and
the gate keeps the numbering safe where it cannot (a target far from its
prediction stays unnumbered, never mislabelled).
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError
from photogram.init.dlt import dlt
from photogram.measure.label import Numbering, nearest_claim_wins

__all__ = ["number_space"]


def _project(P, X):
    h = np.column_stack([X, np.ones(len(X))]) @ P.T
    with np.errstate(divide="ignore", invalid="ignore"):
        return h[:, :2] / h[:, 2:3], h[:, 2]


def number_space(xy: np.ndarray, code_label: np.ndarray, code_ids: list[str],
                 code_XYZ: np.ndarray, ids: list[str], XYZ: np.ndarray,
                 image_size: tuple[int, int], *, gate: float = 0.35, max_iter: int = 20,
                 image: str = "") -> Numbering:
    """Number the detections of one image of a 3D field (module doc).

    Parameters
    ----------
    xy : (n, 2) detections (px); code_label : (n,) code id, "" plain, None rejected
    code_ids, code_XYZ : the coded targets and their approximate coordinates (k, 3)
    ids, XYZ : the uncoded targets (m, 3)
    image_size : (w, h)

    Returns
    -------
    Numbering
        ``homography`` holds the (3, 4) projection matrix.
    """
    from scipy.spatial import cKDTree
    n = len(xy)
    labels = np.full(n, "", dtype=object)
    problems: list[str] = []
    conflicts: list[str] = []
    pos = {c: k for k, c in enumerate(code_ids)}
    seen: dict[str, list[int]] = {}
    for i, lab in enumerate(code_label):
        if lab:
            seen.setdefault(lab, []).append(i)
    for cid, idx in seen.items():
        if len(idx) > 1:
            problems.append(f"{image}: code {cid} decoded {len(idx)} times; none of them used")
        elif cid in pos:
            labels[idx[0]] = cid
    have = [c for c in code_ids if c in labels]
    if len(have) < 6:
        problems.append(f"{image}: {len(have)} coded target(s) decoded; a 3D field needs at "
                        f"least 6 (not in one plane) to number the rest")
        return Numbering(labels, None, problems)
    cidx = np.array([np.nonzero(labels == c)[0][0] for c in have])
    cX = code_XYZ[[pos[c] for c in have]]
    # codes that disagree with the field: the largest consensus of projections
    # from 6-code subsets (a subset close to degenerate predicts wildly and
    # finds no consensus, so approximate coordinates do not raise false alarms)
    keep = np.ones(len(have), bool)
    pair = np.linalg.norm(xy[cidx][:, None] - xy[cidx][None], axis=2)
    scale = np.median(pair[np.triu_indices(len(cidx), 1)])
    thr = max(10.0, 0.1 * scale)
    if len(have) >= 7:
        import itertools
        combos = list(itertools.combinations(range(len(have)), 6))
        if len(combos) > 300:
            pick = np.random.default_rng(0).choice(len(combos), 300, replace=False)
            combos = [combos[i] for i in pick]
        best = (0, np.inf, None)
        for sub in combos:
            try:
                Pk = dlt(cX[list(sub)], xy[cidx[list(sub)]])
            except GeometryError:
                continue
            r = np.linalg.norm(_project(Pk, cX)[0] - xy[cidx], axis=1)
            inl = r < thr
            score = (int(inl.sum()), float(np.median(r[inl])) if inl.any() else np.inf)
            if score[0] > best[0] or (score[0] == best[0] and score[1] < best[1]):
                best = (score[0], score[1], r)
        if best[2] is not None and best[0] >= 6:
            for k in np.nonzero(best[2] >= thr)[0]:
                conflicts.append(f"{image}: code {have[k]} is {best[2][k]:.1f} px from the "
                                 f"projection of the other codes: it disagrees with the field")
                keep[k] = False
    if conflicts:
        for k in np.nonzero(~keep)[0]:
            labels[cidx[k]] = ""
        return Numbering(labels, None, problems, 0, conflicts)
    try:
        P = dlt(cX, xy[cidx])
    except GeometryError as exc:
        problems.append(f"{image}: the coded targets give no projection: {exc.what}")
        return Numbering(labels, None, problems)
    pc, _ = _project(P, cX)
    plain = np.nonzero(code_label == "")[0]
    if len(plain) == 0 or len(XYZ) == 0:
        return Numbering(labels, P, problems, 0, conflicts)
    tree = cKDTree(xy[plain])
    w, h = image_size
    assign = np.full(len(XYZ), -1)
    it = 0
    for it in range(1, max_iter + 1):
        p, depth = _project(P, XYZ)
        allp = np.vstack([p, pc])
        ok = np.isfinite(p).all(axis=1) & (depth > 0) & (p[:, 0] > -5) & (p[:, 1] > -5) \
            & (p[:, 0] < w + 5) & (p[:, 1] < h + 5)
        # distance of each prediction to the nearest other one (codes included)
        dd = np.linalg.norm(p[:, None] - allp[None], axis=2)
        dd[np.arange(len(p)), np.arange(len(p))] = np.inf
        sep = dd.min(axis=1)
        dk, jk = tree.query(np.where(ok[:, None], p, 1e12), k=2)
        d, j = dk[:, 0], jk[:, 0]
        # unambiguous: the nearest dot within the gate, the second nearest at
        # least twice as far, and the dot's nearest prediction is this target
        second = dk[:, 1] if len(plain) > 1 else np.full(len(d), np.inf)
        jj = plain[np.minimum(j, len(plain) - 1)]
        back = cKDTree(np.where(ok[:, None], p, 1e12)).query(xy[jj], k=1)[1]
        new = np.where(ok & (d < gate * sep) & (second > 2 * d) & (back == np.arange(len(p))),
                       jj, -1)
        new = nearest_claim_wins(new, d)   # one-to-one: the nearer claim wins
        if np.array_equal(new, assign):
            break
        assign = new
        sel = assign >= 0
        try:
            P = dlt(np.vstack([XYZ[sel], cX]), np.vstack([xy[assign[sel]], xy[cidx]]))
        except GeometryError:
            break
        pc, _ = _project(P, cX)
    for g in np.nonzero(assign >= 0)[0]:
        labels[assign[g]] = ids[g]
    return Numbering(labels, P, problems, it, conflicts)
