"""Guided measurement over all images of a 3D field: predict again from the
network and number what the first pass missed.

The per-image numbering (:mod:`photogram.measure.space`) predicts from the
field's *approximate* coordinates, a centimetre off on a sketched frame,
i.e. several pixels: it numbers only what is unambiguous. This step
improves the predictions from the images themselves, by alternating
(the classical "resection - intersection" iteration, Luhmann et al. sec.
4.4.3, here with linear methods):

1. **intersection**: every target numbered in two or more images is
   triangulated linearly from the images' projection matrices (Hartley &
   Zisserman alg. 12.1, DLT triangulation); observations more than
   ``max(2 px, 4 x median)`` from their reprojection are dropped (a label
   on the wrong blob cannot survive this) and the point is triangulated
   again;
2. **resection**: each image's projection matrix by DLT from all its
   numbered targets with the new coordinates;
3. **numbering again** in every image with the new predictions and a gate
   of ``max(3 px, 4 x`` the image's reprojection RMS), with the same rules
   as the first pass (nearest plain detection, the second nearest twice as
   far, mutual, one-to-one).

An image with only four or five codes (too few for its own DLT) is
resected by PnP (``cv2.solvePnP``) with the interior orientation of each
resected image in turn, keeping the one whose predictions meet the most
detections. Three rounds, and a last intersection that only removes labels
that do not fit. The DLT has no lens distortion: the gate stays a few pixels
wide to leave room for it (the bundle adjustment that follows models it).
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError
from photogram.init.dlt import dlt

__all__ = ["refine_space", "triangulate"]


def triangulate(Ps: list[np.ndarray], xy: np.ndarray) -> np.ndarray:
    """Linear (DLT) triangulation of one point from k >= 2 views."""
    A = []
    for P, (x, y) in zip(Ps, xy):
        A.append(x * P[2] - P[0])
        A.append(y * P[2] - P[1])
    _, _, vt = np.linalg.svd(np.array(A))
    X = vt[-1]
    return X[:3] / X[3]


def _project(P, X):
    h = np.column_stack([X, np.ones(len(X))]) @ P.T
    with np.errstate(divide="ignore", invalid="ignore"):
        return h[:, :2] / h[:, 2:3], h[:, 2]


def _renumber(res, P, ids, XYZ, code_ids, gate_px):
    from scipy.spatial import cKDTree
    det = res.detections
    labels = res.numbering.labels
    plain = np.array([i for i in range(len(det)) if res.code_label[i] == ""], int)
    if len(plain) == 0:
        return
    p, depth = _project(P, XYZ)
    w, h = det.image_size
    ok = np.isfinite(p).all(axis=1) & (depth > 0) & (p[:, 0] > 0) & (p[:, 1] > 0) \
        & (p[:, 0] < w) & (p[:, 1] < h)
    pp = np.where(ok[:, None], p, 1e12)
    tree = cKDTree(det.xy[plain])
    dk, jk = tree.query(pp, k=min(2, len(plain)))
    dk = dk.reshape(len(pp), -1)
    jk = jk.reshape(len(pp), -1)
    d = dk[:, 0]
    second = dk[:, 1] if dk.shape[1] > 1 else np.full(len(d), np.inf)
    jj = plain[np.minimum(jk[:, 0], len(plain) - 1)]
    back = cKDTree(pp).query(det.xy[jj], k=1)[1]
    take = ok & (d < gate_px) & (second > 2 * d) & (back == np.arange(len(p)))
    new = np.array([v if v in code_ids else "" for v in labels], dtype=object)
    used = set()
    for g in np.argsort(d):
        if take[g] and jj[g] not in used:
            used.add(jj[g])
            new[jj[g]] = ids[g]
    res.numbering.labels = new


def _pnp(res, lab_pos, X, Ks, code_set, ids_t, X_t):
    """Projection matrix of an image with 4-5 coded targets: PnP with the
    interior orientation of each already resected image, keeping the one
    whose predictions meet the most detections within 3 px."""
    import cv2
    lab = res.numbering.labels
    sel = [i for i, v in enumerate(lab) if v in lab_pos]
    if len(sel) < 4:
        return None
    obj = X[[lab_pos[lab[i]] for i in sel]].astype(np.float64)
    img = res.detections.xy[sel].astype(np.float64)
    from scipy.spatial import cKDTree
    tree = cKDTree(res.detections.xy)
    best, best_n = None, -1
    for K in Ks:
        ok, rvec, tvec = cv2.solvePnP(obj, img, K, None, flags=cv2.SOLVEPNP_EPNP)
        if not ok:
            continue
        ok, rvec, tvec = cv2.solvePnP(obj, img, K, None, rvec, tvec, True,
                                      cv2.SOLVEPNP_ITERATIVE)
        R, _ = cv2.Rodrigues(rvec)
        P = K @ np.column_stack([R, tvec.ravel()])
        p, depth = _project(P, X_t)
        good = np.isfinite(p).all(axis=1) & (depth > 0)
        n = int((tree.query(np.where(good[:, None], p, 1e12), k=1)[0] < 3.0).sum())
        if n > best_n:
            best, best_n = P, n
    return best


def refine_space(results: list, fld, rounds: int = 3) -> None:
    """Renumber the images of a 3D field from the network (module doc); in place."""
    import cv2
    code_ids, code_XYZ = fld.coded3()
    ids = list(code_ids) + list(fld.target_ids)
    X = np.vstack([code_XYZ, fld.target_xyz])
    pos = {k: i for i, k in enumerate(ids)}
    code_set = set(code_ids)
    for rnd in range(rounds + 1):
        # resection of every image from its numbered targets
        Ps, rms = {}, {}
        for res in results:
            lab = res.numbering.labels
            sel = [i for i, v in enumerate(lab) if v in pos]
            if len(sel) < 6:
                continue
            XX = X[[pos[lab[i]] for i in sel]]
            try:
                P = dlt(XX, res.detections.xy[sel])
            except GeometryError:
                continue
            r = np.linalg.norm(_project(P, XX)[0] - res.detections.xy[sel], axis=1)
            Ps[res.name] = P
            rms[res.name] = float(np.sqrt(np.mean(r ** 2)))
        # intersection of every target numbered in two or more images
        obs: dict[str, list] = {}
        for res in results:
            if res.name not in Ps:
                continue
            for i, v in enumerate(res.numbering.labels):
                if v in pos:
                    obs.setdefault(v, []).append((res, i))
        for v, lst in obs.items():
            if len(lst) < 2 or v in code_set and len(lst) < 3:
                continue
            Pl = [Ps[r.name] for r, _ in lst]
            xy = np.array([r.detections.xy[i] for r, i in lst])
            Xv = triangulate(Pl, xy)
            e = np.array([np.linalg.norm(_project(P, Xv[None])[0][0] - q) for P, q in zip(Pl, xy)])
            bad = e > max(2.0, 4 * np.median(e))
            for (r, i), b in zip(lst, bad):
                if b and v not in code_set:
                    r.numbering.labels[i] = ""             # a label on the wrong blob
            if (~bad).sum() >= 2:
                Xv = triangulate([P for P, b in zip(Pl, bad) if not b], xy[~bad])
            X[pos[v]] = Xv
        if rnd == rounds:
            break                          # the last pass only checks the labels
        # number again from the refined network
        Ks = []
        for P in Ps.values():
            K = cv2.decomposeProjectionMatrix(P)[0]
            Ks.append(K / K[2, 2])
        for res in results:
            if res.name in Ps:
                sel = [i for i, v in enumerate(res.numbering.labels) if v in pos]
                XX = X[[pos[res.numbering.labels[i]] for i in sel]]
                try:
                    P = dlt(XX, res.detections.xy[sel])
                except GeometryError:
                    continue
                gate = max(3.0, 4 * rms[res.name])
            else:
                P = _pnp(res, pos, X, Ks, code_set, fld.target_ids, X[len(code_ids):])
                if P is None:
                    continue
                gate = 3.0
                res.numbering.problems = [
                    p for p in res.numbering.problems if "needs at least 6" not in p] + \
                    ([] if rnd else [f"{res.name}: too few codes for its own DLT; numbered "
                                     f"through the network (PnP)"])
            _renumber(res, P, fld.target_ids, X[len(code_ids):], code_set, gate)
