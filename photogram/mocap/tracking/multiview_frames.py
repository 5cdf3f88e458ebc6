"""The arrays behind the multi-view choice of the athlete
(:mod:`photogram.mocap.tracking.multiview`): every camera's candidates
padded into arrays, the linear triangulation terms of their rows, the
combinations of one candidate per camera at each level (cameras left out)
and their per-camera reprojection errors, cached per frame."""

from __future__ import annotations

import itertools
import warnings

import numpy as np

# --------------------------------------------------------------------------
# candidates as arrays
# --------------------------------------------------------------------------
def _pad(candidates, F, J, min_conf, min_joints):
    """(F, C, K, J, 3) joints, (F, C, K) rows (-1: padding or too few joints)."""
    C = len(candidates)
    counts = np.zeros((F, C), int)
    for c, det in enumerate(candidates):
        if det is not None and len(det.frames):
            np.add.at(counts[:, c], det.frames[det.frames < F], 1)
    K = max(int(counts.max()) if counts.size else 0, 1)
    joints = np.full((F, C, K, J, 3), np.nan)
    joints[..., 2] = 0.0
    rows = np.full((F, C, K), -1)
    for c, det in enumerate(candidates):
        if det is None or not len(det.frames):
            continue
        order = np.argsort(det.frames, kind="stable")
        fr = det.frames[order]
        keep = fr < F
        order, fr = order[keep], fr[keep]
        first = np.searchsorted(fr, fr)                    # slot within the frame
        slot = np.arange(len(fr)) - first
        joints[fr, c, slot] = det.joints[order]
        rows[fr, c, slot] = order
    conf = np.nan_to_num(joints[..., 2])
    seen = (conf >= min_conf) & np.all(np.isfinite(joints[..., :2]), -1)
    rows[seen.sum(-1) < min_joints] = -1
    return joints, rows, seen


def _rows_terms(cameras, joints, seen, F):
    """Per candidate joint: the DLT matrix A = w s^2 (a1 a1^T + a2 a2^T)
    (F, C, K, J, 3, 3) with the ideal-coordinate rows a1 = t_x R_3 + R_1,
    a2 = t_y R_3 - R_2 (``a (X - X0) = 0``), the ideal coordinates t
    (F, C, K, J, 2) and the pixel scale s (F, C)."""
    _, C, K, J, _ = joints.shape
    xy = np.where(seen[..., None], joints[..., :2], np.nan)
    t = cameras.to_rays(xy.reshape(F, C, K * J, 2)).reshape(F, C, K, J, 2)
    R = cameras.rotations(F)                               # (F, C, 3, 3)
    s = cameras.pixel_scale(F).mean(-1)                    # (F, C)
    ok = seen & np.all(np.isfinite(t), -1)
    t0 = np.where(ok[..., None], t, 0.0)
    r = R[:, :, None, None]                                # (F, C, 1, 1, 3, 3)
    a1 = t0[..., 0:1] * r[..., 2, :] + r[..., 0, :]
    a2 = t0[..., 1:2] * r[..., 2, :] - r[..., 1, :]
    w = np.where(ok, np.nan_to_num(joints[..., 2]), 0.0) * (s ** 2)[:, :, None, None]
    A = w[..., None, None] * (a1[..., :, None] * a1[..., None, :]
                              + a2[..., :, None] * a2[..., None, :])
    return A, np.where(ok[..., None], t, np.nan), s, ok


# --------------------------------------------------------------------------
# combinations of one frame
# --------------------------------------------------------------------------
def _level_combinations(options, level, cap):
    """(M, C) candidate slots (-1: camera off) of the combinations leaving
    ``level`` of the cameras with options out."""
    avail = [c for c, o in enumerate(options) if o]
    C = len(options)
    out = []
    for off in itertools.combinations(avail, level):
        on = [c for c in avail if c not in off]
        lists = [options[c] for c in on]
        n = int(np.prod([len(x) for x in lists]))
        if n > cap:                                        # keep the first (most joints)
            k = max(1, int(cap ** (1.0 / len(lists))))
            lists = [x[:k] for x in lists]
        for combo in itertools.product(*lists):
            row = np.full(C, -1)
            row[on] = combo
            out.append(row)
    return np.array(out, int).reshape(-1, C)


def _nanmedian(a):
    """Median over the last axis ignoring NaN (NaN if none): np.nanmedian
    without its masked-array path, which is slow on many short rows."""
    srt = np.sort(a, axis=-1)                              # NaN last
    n = np.sum(~np.isnan(a), axis=-1)
    lo = np.maximum((n - 1) // 2, 0)[..., None]
    hi = np.maximum(n // 2, 0)[..., None]
    med = 0.5 * (np.take_along_axis(srt, lo, -1) + np.take_along_axis(srt, hi, -1))[..., 0]
    return np.where(n > 0, med, np.nan)


def _solve3(N, r):
    """Batched 3x3 solves (..., 3, 3) x = (..., 3); NaN where singular."""
    det = np.linalg.det(N)
    good = np.abs(det) > 1e-12 * np.maximum(np.einsum("...ii->...", N) ** 3, 1e-300)
    Ns = np.where(good[..., None, None], N, np.eye(3))
    x = np.linalg.solve(Ns, r[..., None])[..., 0]
    return np.where(good[..., None], x, np.nan)


def _evaluate(combos, A, t, ok, s, R, X0, min_joints):
    """Triangulate and score (M, C) combinations of one frame.

    Returns the error per combination (M,) (inf: not judged), per camera
    (M, C) and the roots (M, 3)."""
    M, C = combos.shape
    on = combos >= 0
    slot = np.where(on, combos, 0)
    cam = np.arange(C)[None, :]
    Ac = A[cam, slot] * on[..., None, None, None]          # (M, C, J, 3, 3)
    okc = ok[cam, slot] & on[..., None]                    # (M, C, J)
    tc = t[cam, slot]                                      # (M, C, J, 2)
    rhs_unit = np.einsum("mcjab,cb->mcja", Ac, X0)
    two = okc.sum(1) >= 2                                  # (M, J)
    X = _solve3(Ac.sum(1), rhs_unit.sum(1))                # pass 1: algebraic
    d = np.einsum("cab,mcjb->mcja", R, X[:, None] - X0[None, :, None])[..., 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        wd = 1.0 / np.maximum(d ** 2, 1e-12)               # pass 2: (1 / depth)^2
    wd = np.where(np.isfinite(wd), wd, 0.0)
    X = _solve3((Ac * wd[..., None, None]).sum(1), (rhs_unit * wd[..., None]).sum(1))
    X = np.where(two[..., None], X, np.nan)
    Xc = np.einsum("cab,mcjb->mcja", R, X[:, None] - X0[None, :, None])
    with np.errstate(invalid="ignore", divide="ignore"):
        proj = np.stack([-Xc[..., 0] / Xc[..., 2], Xc[..., 1] / Xc[..., 2]], -1)
        err = np.linalg.norm(proj - tc, axis=-1) * s[None, :, None]
    use = okc & two[:, None, :] & (Xc[..., 2] < 0) & np.isfinite(err)
    e = np.where(use, err, np.nan)
    n = use.sum(-1)
    per_cam = _nanmedian(e)                                # (M, C)
    root = _nanmedian(np.moveaxis(X, 1, -1))               # (M, 3)
    per_cam = np.where(on & (n >= min_joints), per_cam, np.where(on, np.inf, np.nan))
    total = np.where(on.sum(1) >= 2, np.nanmax(np.where(on, per_cam, -np.inf), axis=1), np.inf)
    return total, per_cam, root, X


class _Frames:
    """Lazy, cached combinations per frame and level."""

    def __init__(self, joints, rows, seen, cameras, settings):
        F = joints.shape[0]
        self.st = settings
        self.joints, self.rows = joints, rows
        self.A, self.t, self.s, self.ok = _rows_terms(cameras, joints, seen, F)
        self.R = cameras.rotations(F)
        self.X0 = np.asarray(cameras.X0, float)
        self.nseen = seen.sum(-1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)     # padding: all NaN
            self.t_median = np.nanmedian(self.t, axis=3)         # (F, C, K, 2) ideal
        self.cache = {}

    def options(self, f, pred=None, reach=np.inf):
        """Per camera the candidate slots (most joints first); with a
        predicted root ``pred``, only those whose median joint lies within
        ``reach`` (3D) of it as seen from the camera (a necessary condition
        of the gate that saves the combinations of far candidates)."""
        out = []
        if pred is not None:
            Xc = np.einsum("cab,cb->ca", self.R[f], pred[None] - self.X0)
            with np.errstate(invalid="ignore", divide="ignore"):
                tp = np.stack([-Xc[:, 0] / Xc[:, 2], Xc[:, 1] / Xc[:, 2]], -1)
                allowed = np.where(Xc[:, 2] < 0, reach / np.abs(Xc[:, 2]), -1.0)
        for c in range(self.rows.shape[1]):
            k = np.flatnonzero(self.rows[f, c] >= 0)
            if pred is not None and len(k):
                d = np.linalg.norm(self.t_median[f, c, k] - tp[c], axis=-1)
                k = k[d <= allowed[c]]
            out.append(tuple(k[np.argsort(-self.nseen[f, c, k], kind="stable")]))
        return tuple(out)

    def near(self, f, options, X, reach_px):
        """``options`` kept within ``reach_px`` of the projections of X (J, 3)
        (median over the joints both have)."""
        Xc = np.einsum("cab,cjb->cja", self.R[f], X[None] - self.X0[:, None])
        with np.errstate(invalid="ignore", divide="ignore"):
            tp = np.stack([-Xc[..., 0] / Xc[..., 2], Xc[..., 1] / Xc[..., 2]], -1)  # (C, J, 2)
        out = []
        for c, ks in enumerate(options):
            keep = []
            for k in ks:
                d = np.linalg.norm(self.t[f, c, k] - tp[c], axis=-1) * self.s[f, c]
                d = d[np.isfinite(d)]
                if len(d) and np.median(d) <= reach_px:
                    keep.append(k)
            out.append(tuple(keep))
        return tuple(out)

    @staticmethod
    def levels(options):
        n = sum(1 for o in options if o)
        return range(0, max(n - 1, 0))

    def level(self, f, lv, options):
        key = (f, lv, options)
        if key not in self.cache:
            combos = _level_combinations(options, lv, self.st.max_combinations)
            if len(combos):
                total, per_cam, root, _ = self.evaluate(f, combos)
            else:
                total, per_cam, root = (np.zeros(0), np.zeros((0, len(self.X0))),
                                        np.zeros((0, 3)))
            self.cache[key] = (combos, total, per_cam, root)      # without the points
        return self.cache[key]

    def evaluate(self, f, combos, chunk: int = 2000):
        """:func:`_evaluate` in chunks of ``chunk`` combinations (memory)."""
        parts = [_evaluate(combos[i:i + chunk], self.A[f], self.t[f], self.ok[f], self.s[f],
                           self.R[f], self.X0, self.st.min_joints)
                 for i in range(0, len(combos), chunk)]
        return tuple(np.concatenate(p) for p in zip(*parts))


def _duplicate(ja, jb, limit):
    ok = np.all(np.isfinite(ja[:, :2]), -1) & np.all(np.isfinite(jb[:, :2]), -1)
    if not ok.any():
        return False
    return float(np.median(np.linalg.norm(ja[ok, :2] - jb[ok, :2], axis=-1))) <= limit
