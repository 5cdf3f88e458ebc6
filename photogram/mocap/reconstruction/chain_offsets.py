"""One slowly varying offset per camera between the chain of measured
rotation differences and the camera's rotation, fitted over the whole run
together with a shift of the athlete per frame (unknown rotations, section
4.5 of the paper; issue 22).

The rotation of a pan-tilt camera is ``R(t) = Q(t) O(t)``: ``Q`` the chain
of its measured differences (``Q(t+1) = dR(t) Q(t)``, eqs. (12)-(14),
:func:`photogram.mocap.reconstruction.rotation_chain.difference_chain`),
``O`` the offset that the athlete's detections must fix. With exact
differences ``O`` is one constant rotation per camera and run, and 450
frames of a skier crossing 150 m of slope determine it well; the windows of
the joint optimisation (:mod:`photogram.mocap.reconstruction.estimate`)
each fix it from their own 40-odd frames instead, where a shift of the whole
athlete with every camera turned along with it costs almost nothing (the
harsh simulator: 0.6 deg median rotation error, also with *exact*
differences). Here the offset is a track of rotations at knots every
``knot_frames`` frames, geodesically interpolated, with a random-walk prior
between knots whose variance is what the chain's errors allow
(``sigma^2`` per pair, ``sigma`` the differences' error per pair and axis):
the maximum a-posteriori offsets given the detections (robust: the
Geman-McClure ``rho = e^2 / (e^2 + sigma2)`` that part 1 uses as its
reading of eqs. (7)-(9), with the reconstruction's ``sigma2``; graduated,
100, 10 and 1 times ``sigma2``) and the chain. The detections' noise is
their robust residual scale times :func:`correlation_inflation` (their
errors are correlated over frames; counted as independent, hundreds of
frames would overrule the chain).
The athlete's joints ``X(t)`` of the reconstruction are held except for a
shift ``delta(t)`` per frame, the mode the windows cannot see; the shift is
eliminated per frame (Schur complement, 3 x 3 blocks) and the offsets
solved by Levenberg-Marquardt on the reduced system (C x knots x 3
unknowns). The poses are then solved again on the new rotations by the
caller.

Residuals (pixels): ``r = s * (t(p) - t_obs)`` with ``p = R(t) (X + delta
- X0)`` in the camera frame (world-to-camera ``R``, the camera looking
along -z), ideal coordinates ``t(p) = (-p_x/p_z, p_y/p_z)``
(:mod:`photogram.mocap.reconstruction.cameras`) and ``s`` the model's pixels
per ideal unit. Derivatives (right perturbation ``O <- O Exp(theta)``):
``dp/d delta = R``, ``dp/d theta = -R [X + delta - X0]_x``; with the knot
weights ``1 - a``, ``a`` of the frame between its two knots
(:func:`observation_jacobians`, checked against finite differences in
tests/test_mocap_chain_offsets.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import spsolve

from photogram.geometry.rotations import matrix_to_rodrigues, rodrigues_to_matrix, skew
from photogram.mocap.reconstruction.chain_links import (ChainLinks, correlation_inflation,
                                                        observation_joints)

__all__ = ["OffsetTrack", "offset_knots", "interpolate_offsets", "observation_jacobians",
           "refine_chain_offsets"]


@dataclass
class OffsetTrack:
    """Knots of the offset tracks: ``frame`` (K,), ``camera`` (K,), ``O``
    (K, 3, 3); per camera frame ``knot`` (F, C, 2) the two knots around it
    (-1: not refined) and ``alpha`` (F, C) the weight of the second."""
    frame: np.ndarray
    camera: np.ndarray
    O: np.ndarray
    knot: np.ndarray
    alpha: np.ndarray


def offset_knots(F: int, cameras, breaks=(), knot_frames: int = 10, n_cameras=None):
    """Knot frames of every refined camera and run segment (the first and
    last frame of a segment are knots, the rest spaced ``knot_frames``);
    returns frame (K,), camera (K,), knot (F, C, 2), alpha (F, C)."""
    C = n_cameras if n_cameras is not None else (max(cameras) + 1 if len(cameras) else 0)
    cuts = sorted({0, F} | {int(b) for b in breaks if 0 < int(b) < F})
    frames, cams = [], []
    knot = np.full((F, C, 2), -1, dtype=int)
    alpha = np.zeros((F, C))
    for c in cameras:
        for s, e in zip(cuts[:-1], cuts[1:]):
            n = max(1, int(np.ceil((e - 1 - s) / knot_frames)))
            kf = np.unique(np.round(np.linspace(s, e - 1, n + 1)).astype(int))
            first = len(frames)
            frames.extend(kf.tolist())
            cams.extend([c] * len(kf))
            t = np.arange(s, e)
            if len(kf) == 1:
                knot[t, c] = first
                continue
            i = np.clip(np.searchsorted(kf, t, side="right") - 1, 0, len(kf) - 2)
            knot[t, c, 0] = first + i
            knot[t, c, 1] = first + i + 1
            alpha[t, c] = (t - kf[i]) / (kf[i + 1] - kf[i])
    return np.asarray(frames, int), np.asarray(cams, int), knot, alpha


def interpolate_offsets(track: OffsetTrack) -> np.ndarray:
    """``O(t)`` (F, C, 3, 3) of the refined camera frames (geodesic
    interpolation between their two knots); identity elsewhere."""
    F, C = track.alpha.shape
    out = np.broadcast_to(np.eye(3), (F, C, 3, 3)).copy()
    ok = track.knot[..., 0] >= 0
    k0, k1 = track.knot[ok, 0], track.knot[ok, 1]
    O0, O1 = track.O[k0], track.O[k1]
    d = matrix_to_rodrigues(np.swapaxes(O0, -1, -2) @ O1)
    out[ok] = O0 @ rodrigues_to_matrix(track.alpha[ok][:, None] * d)
    return out


def observation_jacobians(R, v, t_obs, scale):
    """Residuals and Jacobians of joint observations (module doc).

    Parameters
    ----------
    R : (N, 3, 3) world-to-camera rotations
    v : (N, 3) ``X + delta - X0``
    t_obs : (N, 2) observed ideal coordinates
    scale : (N, 2) pixels per ideal unit

    Returns
    -------
    r : (N, 2) residuals in pixels
    J_delta : (N, 2, 3) d r / d delta
    J_theta : (N, 2, 3) d r / d theta (right perturbation of R)
    front : (N,) bool, the point is in front of the camera (p_z < 0)
    """
    p = np.einsum("nab,nb->na", R, v)
    z = np.where(p[:, 2] < 0, p[:, 2], -1.0)
    t = np.stack([-p[:, 0] / z, p[:, 1] / z], axis=1)
    r = scale * (t - t_obs)
    dt = np.zeros((len(p), 2, 3))                 # d t / d p
    dt[:, 0, 0] = -1.0 / z
    dt[:, 0, 2] = p[:, 0] / z ** 2
    dt[:, 1, 1] = 1.0 / z
    dt[:, 1, 2] = -p[:, 1] / z ** 2
    dt *= scale[:, :, None]
    J_delta = dt @ R
    J_theta = -J_delta @ skew(v)
    return r, J_delta, J_theta, p[:, 2] < 0


def _terms(R, X, delta, t_obs, conf, scale, X0, sigma2, noise2):
    F, C, J = conf.shape
    f, c, j = np.nonzero(conf > 0)
    v = X[f, j] + delta[f] - X0[c]
    r, Jd, Jt, front = observation_jacobians(R[f, c], v, t_obs[f, c, j], scale[f, c])
    e2 = np.sum(r ** 2, axis=1)
    # Geman-McClure: cost (sigma2 / noise2) e2 / (e2 + sigma2) ~ e2 / noise2 near 0
    cost = float(np.sum(conf[f, c, j] * front * sigma2 / noise2 * e2 / (e2 + sigma2)))
    w = conf[f, c, j] * front * sigma2 ** 2 / noise2 / (e2 + sigma2) ** 2
    return cost, (f, c, r, Jd, Jt, w)


def _solve_stage(track, delta, rotations, links, Xf, tob, use, scale, X0,
                 sigma2, noise2, max_iterations, tolerance):
    """Levenberg-Marquardt on the offsets' knots (the athlete's shift per
    frame eliminated, module doc) at one robust scale; returns the track,
    the shift, the cost and the iterations."""
    F, C, J = use.shape
    frames, cams, knot, alpha = track.frame, track.camera, track.knot, track.alpha
    K = len(frames)

    def total(tr, dl):
        cost = _terms(rotations(tr), Xf, dl, tob, use, scale, X0, sigma2, noise2)[0]
        return cost + float(np.sum(np.sum(links.residuals(tr) ** 2, axis=1) / links.var))

    cost = total(track, delta)
    mu, its = 1e-3, 0
    fl, ll = np.nonzero(knot.reshape(F, -1) >= 0)          # refined (frame, slot)
    for it in range(max_iterations):
        Rt = rotations(track)
        _, (f, c, r, Jd, Jt, w) = _terms(Rt, Xf, delta, tob, use, scale, X0, sigma2, noise2)
        A, gd, B, Dl, g, loc = _normal_blocks(f, c, r, Jd, Jt, w, knot, alpha, K)
        Ai = np.linalg.inv(A)
        AiB = np.einsum("fab,fblc->falc", Ai, B)
        S_loc = Dl - np.einsum("falc,fame->flcme", B, AiB)
        rhs_loc = -np.einsum("falc,fa->flc", AiB, gd)       # - B^T A^-1 g_delta
        rhs = -g.copy()
        fi, li, mi = np.nonzero((loc[:, :, None] >= 0) & (loc[:, None, :] >= 0))
        np.add.at(rhs, loc[fl, ll], -rhs_loc[fl, ll])
        # the chain's links between knots: r0 + sum_i coef_i theta_knot_i
        r0 = links.residuals(track)
        iv = 1.0 / links.var
        rows, cols, vals = [loc[fi, li]], [loc[fi, mi]], [S_loc[fi, li, :, mi, :]]
        for i in range(links.knots.shape[1]):
            np.add.at(rhs, links.knots[:, i], -(links.coefs[:, i] * iv)[:, None] * r0)
            for k in range(links.knots.shape[1]):
                rows.append(links.knots[:, i])
                cols.append(links.knots[:, k])
                vals.append((links.coefs[:, i] * links.coefs[:, k] * iv)[:, None, None]
                            * np.eye(3))
        Hm = _block_matrix(np.concatenate(rows), np.concatenate(cols), np.concatenate(vals), K)
        diag = sparse.diags(Hm.diagonal() + 1e-12, format="csc")
        improved = False
        for _ in range(10):
            dth = spsolve(Hm + mu * diag, rhs.reshape(-1)).reshape(K, 3)
            if not np.all(np.isfinite(dth)):
                mu *= 10
                continue
            # back-substitution: A ddelta = -g_delta - B theta
            Bth = np.zeros((F, 3))
            np.add.at(Bth, fl, np.einsum("nac,nc->na", B[fl, :, ll, :], dth[loc[fl, ll]]))
            ddl = np.einsum("fab,fb->fa", Ai, -gd - Bth)
            trial = OffsetTrack(frames, cams, track.O @ rodrigues_to_matrix(dth), knot, alpha)
            new = total(trial, delta + ddl)
            if new < cost:
                change = (cost - new) / max(cost, 1e-300)
                track, delta, cost = trial, delta + ddl, new
                mu = max(mu / 3, 1e-9)
                improved = True
                break
            mu *= 10
        its = it + 1
        if not improved or change < tolerance:
            break
    return track, delta, cost, its


def _block_matrix(rows, cols, blocks, K):
    """Sparse (3K, 3K) matrix summing the 3 x 3 ``blocks`` (n, 3, 3) at
    block positions (``rows``, ``cols``) (duplicates added)."""
    a, b = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
    r = (3 * rows[:, None, None] + a).ravel()
    c = (3 * cols[:, None, None] + b).ravel()
    return sparse.coo_matrix((blocks.ravel(), (r, c)), shape=(3 * K, 3 * K)).tocsc()


def _normal_blocks(f, c, r, Jd, Jt, w, knot, alpha, K):
    """Blocks of the Gauss-Newton normal equations: per frame ``A`` (F, 3,
    3) and ``gd`` (F, 3) of the shift, ``B`` (F, 3, L, 3) shift x offset
    and ``Dl`` (F, L, 3, L, 3) offset x offset in the frame's L = 2C local
    slots (camera c's knots before and after the frame: slots 2c, 2c+1,
    weights 1 - a, a), ``g`` (K, 3) of the knots and ``loc`` (F, L) the
    knot of every slot (-1: held). Observations come sorted by (frame,
    camera) (``np.nonzero`` order) and are summed per camera frame first."""
    F, C = knot.shape[:2]
    L = 2 * C
    cf = f * C + c
    starts = np.flatnonzero(np.r_[True, cf[1:] != cf[:-1]])
    gf, gc = f[starts], c[starts]
    wJd = Jd * w[:, None, None]
    sums = [np.add.reduceat(x, starts, axis=0) for x in (
        np.einsum("nia,nib->nab", wJd, Jd), np.einsum("nia,ni->na", wJd, r),
        np.einsum("nia,nib->nab", wJd, Jt), np.einsum("nia,nib->nab", Jt * w[:, None, None], Jt),
        np.einsum("nia,ni->na", Jt * w[:, None, None], r))]
    dd, dr, dt, tt, tr = sums
    A = np.zeros((F, 3, 3))
    np.add.at(A, gf, dd)
    A += np.eye(3) * 1e-6                               # frames without detections
    gd = np.zeros((F, 3))
    np.add.at(gd, gf, dr)
    loc = knot.reshape(F, L)
    refined = loc[gf, 2 * gc] >= 0
    a = alpha[gf, gc]
    B = np.zeros((F, 3, L, 3))
    Dl = np.zeros((F, L, 3, L, 3))
    g = np.zeros((K, 3))
    wts = (1.0 - a, a)
    for s1 in (0, 1):
        B[gf[refined], :, 2 * gc[refined] + s1] = (wts[s1][:, None, None] * dt)[refined]
        np.add.at(g, loc[gf[refined], 2 * gc[refined] + s1], (wts[s1][:, None] * tr)[refined])
        for s2 in (0, 1):
            Dl[gf[refined], 2 * gc[refined] + s1, :, 2 * gc[refined] + s2] = \
                ((wts[s1] * wts[s2])[:, None, None] * tt)[refined]
    return A, gd, B, Dl, g, loc


def refine_chain_offsets(X, R, Q, t_obs, conf, scale, X0, cameras, breaks=(),
                         knot_frames: int = 2, sigma_pair=None, sigma2: float = 400.0,
                         max_iterations: int = 30, tolerance: float = 1e-6, lagged=None):
    """The offsets ``O(t)`` of every camera in ``cameras`` (module doc).

    Parameters
    ----------
    X : (F, J, 3) joints of the reconstruction (NaN: not reconstructed)
    R : (F, C, 3, 3) its rotations (start values; other cameras held)
    Q : (F, C, 3, 3) chain of the measured differences
    t_obs : (F, C, J, 2) observed ideal coordinates
    conf : (F, C, J) confidences (0: not used)
    scale : (F, C, 2) pixels per ideal unit
    X0 : (C, 3) projection centres
    cameras : indices of the cameras to refine (usable differences)
    sigma_pair : (C,) error of the differences per pair and axis (rad)
    sigma2 : robust scale (px^2) of rho
    lagged : optional measured differences over more than one frame, a
        tuple (camera (M,), first (M,), second (M,), dR (M, 3, 3), sigma
        (M,) rad per axis) with ``R(second) = dR R(first)``

    Returns
    -------
    R : (F, C, 3, 3) the rotations ``Q(t) O(t)`` (held cameras unchanged)
    info : dict (iterations, cost before and after, per-camera offset change in deg)
    """
    F, C, J = conf.shape
    cameras = [int(c) for c in cameras]
    use = np.where(np.isfinite(X).all(-1)[:, None, :] & np.isfinite(t_obs).all(-1), conf, 0.0)
    use = np.where(np.isfinite(scale).all(-1)[..., None], use, 0.0)
    Xf = np.nan_to_num(X)
    tob = np.nan_to_num(t_obs)
    info = {"iterations": 0, "cameras": [int(c) for c in cameras]}
    if not cameras or not use.any():
        return R, info
    frames, cams, knot, alpha = offset_knots(F, cameras, breaks, knot_frames, C)
    O = np.swapaxes(Q[frames, cams], -1, -2) @ R[frames, cams]
    track = OffsetTrack(frames, cams, O, knot, alpha)
    Rf = R.copy()
    held = np.ones(C, bool)
    held[cameras] = False
    sig = np.full(C, np.radians(0.05)) if sigma_pair is None else np.asarray(sigma_pair, float)
    sig = np.where(np.isfinite(sig) & (sig > 0), sig, np.radians(0.05))
    links = ChainLinks(track, Q, sig, lagged, interpolate_offsets)
    delta = np.zeros((F, 3))
    O_start = track.O.copy()

    def rotations(tr):
        out = Q @ interpolate_offsets(tr)
        return np.where(held[None, :, None, None], Rf, out)

    info["stages"] = []
    for s2 in (100.0 * sigma2, 10.0 * sigma2, sigma2):     # graduated non-convexity
        # the detections' noise: robust scale of the residuals (Rayleigh median)
        _, (f, c, r, *_rest) = _terms(rotations(track), Xf, delta, tob, use, scale, X0, s2, 1.0)
        e = np.sqrt(np.sum(r ** 2, axis=1))
        noise2 = float(max(np.median(e) / 1.1774, 1.0) ** 2)
        inflation = correlation_inflation(r, f, c, observation_joints(use), e < 3.0 * np.sqrt(noise2),
                                          (F, C, J), 2 * knot_frames)
        noise2 *= inflation
        track, delta, cost, its = _solve_stage(
            track, delta, rotations, links, Xf, tob, use, scale, X0, s2, noise2,
            max_iterations, tolerance)
        info["stages"].append({"sigma2": s2, "inflation": inflation,
                               "detection_sigma_px": float(np.sqrt(noise2 / inflation)),
                               "iterations": its, "cost": cost})
        info["iterations"] += its
    info["cost_end"] = cost
    moved = np.degrees(np.linalg.norm(matrix_to_rodrigues(
        np.swapaxes(O_start, -1, -2) @ track.O), axis=-1))
    info["offset_change_deg"] = {int(cc): float(np.max(moved[cams == cc])) for cc in cameras}
    info["shift_m_median"] = float(np.median(np.linalg.norm(delta, axis=1)))
    return rotations(track), info
