"""Bootstrap of poses and camera rotations when the rotations are unknown
(section 4.5 of the paper, "initialization").

Only the positions (and interior orientation) of the cameras are known.
Pose only, repeated ``iterations`` (25) times:

1. every camera looks at the mean of the current pose estimate of the frame
   (``P(t)``, at the start the centre of the cameras), with the global z
   axis up (no roll), and is then panned and tilted by the athlete's offset
   in its image: the rotation is turned so that the ray through the median
   of the athlete's detections passes through ``P(t)``;
2. the pose is reconstructed with these cameras held fixed (the solver of
   part 1, :func:`photogram.mocap.reconstruction.solvers.solve_gauss_newton`, a few
   iterations per round, warm-started), the robust scale continued from
   ``gnc_start`` down to ``sigma2`` over the first four fifths of the
   rounds;
3. ``P(t)`` is the mean of the reconstructed joints of the frame.

Step 1 makes every camera's ray through the athlete pass through ``P``, so
what moves ``P`` is the athlete's apparent size: a skeleton of one size must
appear as large as it does in every camera, which only fits at the right
distances from the known projection centres. The rounds converge slowly
(hence 25); the joint optimisation (:mod:`photogram.mocap.reconstruction.estimate`) refines
everything.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry.aiming import look_at
from photogram.mocap.reconstruction.cameras import MocapCameras
from photogram.mocap.reconstruction.solvers import solve_gauss_newton

__all__ = ["aim_cameras", "athlete_directions", "bootstrap_poses", "apparent_size",
           "size_trilateration", "chain_rotations", "procrustes_cameras",
           "triangulate_directions", "level_start", "fill_path"]


def athlete_directions(t_obs: np.ndarray, conf: np.ndarray) -> np.ndarray:
    """Unit direction (F, C, 3) to the athlete in every camera frame: the
    median of the ideal coordinates (F, C, J, 2) of the detections with
    ``conf`` > 0, as the camera vector ``(t_x, -t_y, -1)`` (the
    photogrammetric camera looks along -z); NaN without detections."""
    t = np.where((conf > 0)[..., None], t_obs, np.nan)
    with np.errstate(all="ignore"):
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            m = np.nanmedian(t, axis=2)                            # (F, C, 2)
    d = np.stack([m[..., 0], -m[..., 1], -np.ones(m.shape[:-1])], -1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _turn(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotations (n, 3, 3) taking unit vectors a to b (n, 3)."""
    v = np.cross(a, b)
    c = np.sum(a * b, axis=-1)
    K = np.zeros(a.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    K = K - np.swapaxes(K, -1, -2)
    f = 1.0 / (1.0 + np.maximum(c, -1.0 + 1e-12))
    return np.eye(3) + K + (K @ K) * f[..., None, None]


def aim_cameras(X0: np.ndarray, target: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """World-to-camera rotations (F, C, 3, 3): cameras at X0 (C, 3) looking at
    ``target`` (F, 3) with z up, turned so that the camera direction
    ``direction`` (F, C, 3) (NaN: not turned) points at the target."""
    F, C = direction.shape[:2]
    L = look_at(np.repeat(X0[None], F, 0).reshape(-1, 3),
                np.repeat(target[:, None], C, 1).reshape(-1, 3)).reshape(F, C, 3, 3)
    d = np.nan_to_num(direction.reshape(-1, 3), nan=0.0)
    bad = ~np.all(np.isfinite(direction.reshape(-1, 3)), axis=1)
    d[bad] = (0.0, 0.0, -1.0)
    T = _turn(np.tile([0.0, 0.0, -1.0], (len(d), 1)), d).reshape(F, C, 3, 3)
    return T @ L


def _mean_pose(X: np.ndarray, previous: np.ndarray) -> np.ndarray:
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        P = np.nanmean(X, axis=1)
    ok = np.all(np.isfinite(P), axis=1)
    return np.where(ok[:, None], P, previous)


def apparent_size(t_obs: np.ndarray, conf: np.ndarray) -> np.ndarray:
    """Angular size (F, C) of the athlete: the root median square distance of
    the detections (ideal coordinates, radians) from their median; NaN with
    fewer than 4 detections."""
    import warnings
    t = np.where((conf > 0)[..., None], t_obs, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        m = np.nanmedian(t, axis=2, keepdims=True)
        size = np.sqrt(np.nanmedian(np.sum((t - m) ** 2, axis=-1), axis=2))
    size[np.sum(conf > 0, axis=2) < 4] = np.nan
    return size


def _variance(logd, L, o, n):
    """``sum_c (o (v_c - mean))^2`` over the cameras of ``v = (logd + L) o``
    (logd (N, C), L and o (f, C); mean ``sum_c v_c / n``): (f, N). Below 8
    cameras one (f, N) plane per camera, added in numpy's order for a sum
    over a short last axis (one after the other): the same bits as the sum
    over the last axis of the (f, N, C) array, in a third of the time."""
    C = logd.shape[1]
    if C >= 8:                      # numpy sums 8 or more terms pairwise
        v = (logd[None] + L[:, None, :]) * o[:, None, :]                  # (f, N, C)
        mean = v.sum(-1) / n
        return np.sum(((v - mean[..., None]) * o[:, None, :]) ** 2, -1)
    lt = np.ascontiguousarray(logd.T)
    v = [(lt[c][None] + L[:, c, None]) * o[:, c, None] for c in range(C)]   # (f, N) each
    total = v[0].copy()
    for c in range(1, C):
        total += v[c]
    mean = total / n
    var = ((v[0] - mean) * o[:, 0, None]) ** 2
    for c in range(1, C):
        var += ((v[c] - mean) * o[:, c, None]) ** 2
    return var


def size_trilateration(X0: np.ndarray, size: np.ndarray, extent: float = 2.0,
                       step: float = 1.0, smooth: int = 9) -> np.ndarray:
    """Positions (F, 3) where the athlete's angular size ``size`` (F, C) is
    consistent with one physical size: ``|P - X0_c| size_c`` equal for all
    cameras, i.e. the smallest variance over the cameras of ``log(|P - X0_c|
    size_c)`` (scale-free). P is searched on a grid of ``step`` in the plane
    of the cameras (fitted to X0; skiers move on the slope a little below
    the cameras) over ``extent`` times the cameras' spread, then smoothed
    over the frames by a running median of ``smooth`` frames. Frames seen by
    fewer than three cameras stay at the centre of the cameras.

    The cost is flat along some directions (near one end of a ring of
    cameras a point 10 m off costs a variance of 1e-5), so this is only a
    start for :func:`photogram.mocap.reconstruction.bearings.bearing_adjustment`, which
    fixes the path from the bearings of a whole segment."""
    from scipy.ndimage import median_filter
    F, C = size.shape
    centre = X0.mean(axis=0)
    _, _, Vt = np.linalg.svd(X0 - centre)
    e1, e2 = Vt[0], Vt[1]
    half = extent * np.max(np.linalg.norm(X0 - centre, axis=1))
    g = np.arange(-half, half + step, step)
    G = centre + g[:, None, None] * e1 + g[None, :, None] * e2            # (n, n, 3)
    G = G.reshape(-1, 3)
    logd = np.log(np.linalg.norm(G[:, None, :] - X0[None], axis=-1))     # (N, C)
    ok = np.isfinite(size) & (size > 0)
    ls = np.where(ok, np.log(np.where(ok, size, 1.0)), 0.0)
    P = np.repeat(centre[None], F, 0)
    n = np.maximum(ok.sum(axis=1), 1)
    # chunks of frames with (f, N, C) temporaries of at most ~32 MB each: a
    # fine grid (N ~ 10^6 points) in chunks of 64 frames took 2 GB
    f = int(min(64, max(1, 2 ** 25 // (8 * G.shape[0] * C))))
    for s0 in range(0, F, f):
        o, L = ok[s0:s0 + f], ls[s0:s0 + f]
        var = _variance(logd, L, o, n[s0:s0 + f, None])
        P[s0:s0 + f] = G[np.argmin(var, axis=1)]
    if smooth > 1:
        P = median_filter(P, size=(smooth, 1), mode="nearest")
    P[ok.sum(axis=1) < 3] = centre
    return P


def chain_rotations(dR: np.ndarray, breaks=()) -> np.ndarray:
    """``Q(t)`` (F, C, 3, 3) with ``Q(t+1) = dR(t) Q(t)`` and ``Q = I`` at the
    first frame of every segment (``breaks``)."""
    F = dR.shape[0] + 1
    C = dR.shape[1]
    Q = np.empty((F, C, 3, 3))
    Q[0] = np.eye(3)
    starts = set(int(b) for b in breaks)
    for t in range(1, F):                      # a loop over frames, over all cameras at once
        Q[t] = np.eye(3) if t in starts else dR[t - 1] @ Q[t - 1]
    return Q


def _segments(F, breaks):
    cuts = sorted({0, F} | {int(b) for b in breaks if 0 < int(b) < F})
    return list(zip(cuts[:-1], cuts[1:]))


def procrustes_cameras(X0, P, directions, Q, breaks=()) -> np.ndarray:
    """Rotations ``R(t) = Q(t) R0`` (F, C, 3, 3) with one ``R0`` per camera
    and segment that best turns the directions to ``P`` (F, 3) into the
    observed camera directions ``directions`` (F, C, 3): Wahba's problem,
    solved by SVD (frames without a direction are left out)."""
    F, C = directions.shape[:2]
    v = P[:, None, :] - X0[None]
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    b = np.einsum("fcba,fcb->fca", Q, directions)                 # Q^T d
    ok = np.all(np.isfinite(b), axis=-1)
    b = np.where(ok[..., None], b, 0.0)
    R = np.empty((F, C, 3, 3))
    for s, e in _segments(F, breaks):
        M = np.einsum("fca,fcb->cab", b[s:e], v[s:e])
        U, _, Vt = np.linalg.svd(M)
        D = np.ones((C, 3))
        D[:, 2] = np.sign(np.linalg.det(U @ Vt))
        R0 = (U * D[:, None, :]) @ Vt
        R[s:e] = Q[s:e] @ R0[None]
    return R


def level_start(X0, P, directions, Q, breaks=()) -> np.ndarray:
    """Rotations ``Q(t) R0`` with ``R0`` the chordal mean over the segment of
    ``Q(t)^T A(t)``, A the cameras aimed at P with the z axis up
    (:func:`aim_cameras`): level cameras (not the upside-down mirror a
    free Procrustes fit may give)."""
    A = aim_cameras(X0, P, directions)
    F, C = A.shape[:2]
    R = np.empty((F, C, 3, 3))
    for s, e in _segments(F, breaks):
        M = np.einsum("fcba,fcbd->cad", Q[s:e], A[s:e])
        U, _, Vt = np.linalg.svd(M)
        D = np.ones((C, 3))
        D[:, 2] = np.sign(np.linalg.det(U @ Vt))
        R[s:e] = Q[s:e] @ ((U * D[:, None, :]) @ Vt)[None]
    return R


def triangulate_directions(X0, R, directions, min_eig: float = 0.01):
    """Least-squares intersection (F, 3) of the rays from X0 (C, 3) along the
    world directions ``R^T d`` (NaN directions left out), and whether it is
    determined (F,): at least two rays whose normal matrix ``sum(I - u u^T)``
    has its smallest eigenvalue above ``min_eig`` (rays at least ~6 deg
    apart)."""
    u = np.einsum("fcba,fcb->fca", R, directions)
    ok = np.all(np.isfinite(u), axis=-1)
    u = np.where(ok[..., None], u, 0.0)
    Pm = (np.eye(3) - u[..., :, None] * u[..., None, :]) * ok[..., None, None]
    A = Pm.sum(axis=1)
    good = (ok.sum(axis=1) >= 2) & (np.linalg.eigvalsh(A)[:, 0] > min_eig)
    rhs = np.einsum("fcab,cb->fa", Pm, X0)
    return np.linalg.solve(A + 1e-9 * np.eye(3), rhs[..., None])[..., 0], good


def fill_path(P, good, breaks=()) -> np.ndarray:
    """P (F, 3) with the frames that are not ``good`` interpolated linearly
    from the good ones of their segment (constant beyond the ends; the
    centre of the segment's good frames if none is good... kept as is)."""
    P = P.copy()
    F = len(P)
    for s, e in _segments(F, breaks):
        g = np.flatnonzero(good[s:e])
        if len(g) == 0 or len(g) == e - s:
            continue
        t = np.arange(e - s)
        for k in range(3):
            P[s:e, k] = np.interp(t, g, P[s:e, k][g])
    return P


def _joint_directions(t_obs, conf):
    d = np.stack([t_obs[..., 0], -t_obs[..., 1], -np.ones(t_obs.shape[:-1])], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return np.where((conf > 0)[..., None], d, np.nan)


def procrustes_joints(X0, X, joint_dirs, conf, Q, breaks=()) -> np.ndarray:
    """Like :func:`procrustes_cameras` with every detected joint: directions
    from X0 to the joints X (F, J, 3) against the observed directions
    ``joint_dirs`` (F, C, J, 3), weighted by the confidences (F, C, J)."""
    F, C = joint_dirs.shape[:2]
    v = X[:, None] - X0[None, :, None]                               # (F, C, J, 3)
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    b = np.einsum("fcba,fcjb->fcja", Q, joint_dirs)
    w = np.where(np.all(np.isfinite(b), -1) & np.all(np.isfinite(v), -1), conf, 0.0)
    b, v = np.nan_to_num(b), np.nan_to_num(v)
    R = np.empty((F, C, 3, 3))
    for s, e in _segments(F, breaks):
        M = np.einsum("fcj,fcja,fcjb->cab", w[s:e], b[s:e], v[s:e])
        U, _, Vt = np.linalg.svd(M)
        D = np.ones((C, 3))
        D[:, 2] = np.sign(np.linalg.det(U @ Vt))
        R[s:e] = Q[s:e] @ ((U * D[:, None, :]) @ Vt)[None]
    return R


def bootstrap_poses(batches, blend, cameras: MocapCameras, t_obs, conf, settings,
                    iterations: int = 25, inner_iterations: int = 5, log=None,
                    dR=None, breaks=()):
    """Run the bootstrap (module doc).

    Parameters
    ----------
    batches : list of (windows, frame index (nw, T), WindowBatch)
        From :func:`photogram.mocap.reconstruction.reconstruct._batches`; their rotations
        are overwritten.
    blend : callable(coefficients) -> (F, J, 3)
        Blends window coefficients into a sequence.
    t_obs, conf : (F, C, J, 2), (F, C, J)
        Ideal coordinates and confidences of the detections.
    settings : ReconstructionSettings
        ``gnc_start``, ``sigma2``, ``lambda_rep``.
    dR : (F-1, C, 3, 3) or None
        Measured rotation differences. Without them every round aims the
        cameras at the pose (:func:`aim_cameras`, the paper's bootstrap);
        with them the cameras are ``Q(t) R0`` and ``R0`` is fitted to the
        athlete's path first (:func:`photogram.mocap.reconstruction.bearings.bearing_adjustment`
        from :func:`size_trilateration`) and to the reconstructed joints in
        every round (:func:`procrustes_joints`).

    Returns
    -------
    coeffs : list of (nw, J, 3, K)
    R : (F, C, 3, 3)
        The rotations of the last round, fitted to the final poses.
    history : list of float
        Mean displacement of the pose centre per round (m), for the log.
    """
    from photogram.mocap.reconstruction.bearings import bearing_adjustment
    directions = athlete_directions(t_obs, conf)
    F = directions.shape[0]
    X0 = cameras.X0
    P = size_trilateration(X0, apparent_size(t_obs, conf))
    Q = None if dR is None else chain_rotations(dR, breaks)
    jd = _joint_directions(t_obs, conf)
    if Q is not None:
        R = level_start(X0, P, directions, Q, breaks)
        for s, e in _segments(F, breaks):
            _, R0, _ = bearing_adjustment(X0, Q[s:e], directions[s:e], P[s:e],
                                          np.linalg.inv(Q[s]) @ R[s])
            R[s:e] = Q[s:e] @ R0[None]
        P_tri, good = triangulate_directions(X0, R, directions)
        P = fill_path(P_tri, good, breaks)
    else:
        R = aim_cameras(X0, P, directions)
    coeffs = []
    for ws, idx, b in batches:
        nw, T, C, J, K = b.shape
        a = np.zeros((nw, J, 3, K))
        a[:, :, :, 0] = (P[idx].mean(axis=1) * np.sqrt(T))[:, None, :]
        coeffs.append(a)
    stages = settings.stages()
    cool = max(1, int(round(0.8 * iterations)))
    history = []
    for n in range(iterations):
        sigma2 = stages[min(n * len(stages) // cool, len(stages) - 1)]
        for (ws, idx, b), a in zip(batches, coeffs):
            b.R = np.ascontiguousarray(R[idx].transpose(0, 2, 3, 4, 1))      # (nw,C,3,3,T)
            b.RX0 = np.einsum("wcabt,cb->wcat", b.R, X0)
            a[...] = solve_gauss_newton(b, a, sigma2, np.zeros(len(b.limbs)),
                                        settings.lambda_rep, 0.0, inner_iterations, 1e-6,
                                        second_order=False)[0]
        X = blend(coeffs)
        P_new = _mean_pose(X, P)
        history.append(float(np.mean(np.linalg.norm(P_new - P, axis=1))))
        if log is not None:
            log.debug("bootstrap round %d: sigma2 %g, mean change of the pose centre %.3f m",
                      n + 1, sigma2, history[-1])
        P = P_new
        R = aim_cameras(X0, P, directions) if Q is None else \
            procrustes_joints(X0, X, jd, conf, Q, breaks)
    return coeffs, R, history
