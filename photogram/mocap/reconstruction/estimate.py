"""Poses and camera rotations together: motion capture from pan-tilt cameras
with unknown orientation (section 4.5 of the paper).

Known: the cameras' projection centres and interior orientation (zoom per
frame); unknown: their rotations. Measured from the images: the rotation
differences between consecutive frames (:mod:`photogram.mocap.motion.homography`,
eqs. (12)-(13)). Steps:

1. **bootstrap** (:mod:`photogram.mocap.reconstruction.bootstrap`): 25 rounds of pose-only
   reconstruction with cameras aimed at the pose;
2. **joint optimisation** (:mod:`photogram.mocap.reconstruction.joint`,
   :mod:`photogram.mocap.reconstruction.joint_solver`): pose coefficients (N_Pi = 11) and
   camera Euler angles as inverse DCTs (N_Gamma = 11 per camera and axis)
   over windows, the energy of part 1 plus E_rot of eq. (14) with
   lambda_rep = 500, lambda_limbs = 1, lambda_rot = 10000 (the paper's
   values; residual units in docs/mocap.md), by Levenberg-Marquardt on the
   dense per-window model (the paper ran 1500 L-BFGS iterations; the
   Gauss-Newton model reaches the minimum in tens);
   With measured differences every window's rotation follows their chain
   per frame, ``R(t) = Q(t) Q(m)^T R(m) E(gamma(t))``, and a camera without
   athlete detections in a window is held there
   (:mod:`photogram.mocap.reconstruction.rotation_chain`);
3. windows blended as in part 1 (poses) and rotation matrices blended with
   the same weights and projected to the nearest rotation;
4. with measured differences: one rotation track per camera and run, the
   chain ``Q(t)`` times its offset ``Q(t)^T R(t)`` smoothed over the
   observed frames (Gaussian, sigma 10 frames; the frames without observations
   get the offsets of both sides of their gap), and the poses of every
   window solved again on these cameras (the last stage of part 1,
   warm-started): independent windows fix the absolute orientation each
   from their own frames and disagree in the overlaps (p95 23 cm on the
   simulated run of benchmarks/mocap_seams.py, 5.6 cm after), which the
   blend turned into jumps of the centre of mass (docs/mocap.md section 12);
5. with measured differences and ``chain_offsets`` (default): before the
   poses are solved again, the offsets ``Q(t)^T R(t)`` are fitted over the
   whole run with a random-walk prior from the differences' own error and a
   shift of the athlete per frame
   (:mod:`photogram.mocap.reconstruction.chain_offsets`): the windows fix
   the offsets each from their own frames, where a shift of the whole
   athlete with every camera turned along costs almost nothing.

Ablations (Table 2 of the paper): ``pose_basis = "free"`` (a position per
joint and frame: Ours-A, Ours-B), ``rotation_basis = "free"`` (angles per
frame) and ``rotation_prior = False`` (no E_rot: rotations optimised
freely, Ours-B).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace

import numpy as np

from photogram.errors import InputError
from photogram.mocap.body.skeleton import Skeleton
from photogram.mocap.motion.camera_motion import euler_from_matrices
from photogram.mocap.reconstruction.blas import one_blas_thread
from photogram.mocap.reconstruction.bootstrap import bootstrap_poses
from photogram.mocap.reconstruction.cameras import MocapCameras
from photogram.mocap.reconstruction.chain_links import lagged_noise
from photogram.mocap.reconstruction.chain_offsets import refine_chain_offsets
from photogram.mocap.reconstruction.dct import blend_weights, dct_basis
from photogram.mocap.reconstruction.joint import JointBatch
from photogram.mocap.reconstruction.joint_solver import solve_joint, solve_joint_lbfgs
from photogram.mocap.reconstruction.reconstruct import (Reconstruction, ReconstructionSettings,
                                                        _batches, _blend, _given_lengths, _support,
                                                        limb_lengths, window_disagreement)
from photogram.mocap.reconstruction.rotation_chain import (anchor_rotations, chained_references,
                                                           difference_chain, observed_frames,
                                                           window_cameras)
from photogram.mocap.reconstruction.solvers import solve_gauss_newton

__all__ = ["ESTIMATE_DEFAULTS", "ABLATIONS", "estimate_settings", "EstimatedRotations",
           "estimate_poses_and_rotations"]

log = logging.getLogger(__name__)

#: the paper's values for unknown rotations (section 4.5)
ESTIMATE_DEFAULTS = {"n_dct": 11, "lambda_rep": 500.0, "lambda_limbs": 1.0}
#: Table 2 of the paper: (pose_basis, rotation_basis, rotation_prior)
ABLATIONS = {"ours": ("dct", "dct", True), "ours-a": ("free", "dct", True),
             "ours-b": ("free", "dct", False), "no-erot": ("dct", "dct", False)}


def estimate_settings(**overrides) -> ReconstructionSettings:
    """ReconstructionSettings with the defaults of the unknown-rotation case
    (a ``cutoff_hz`` given replaces the default count ``n_dct`` = 11)."""
    defaults = dict(ESTIMATE_DEFAULTS)
    if overrides.get("cutoff_hz") is not None:
        defaults.pop("n_dct")
    return ReconstructionSettings(**{**defaults, "rotation": "estimate", **overrides})


@dataclass
class EstimatedRotations(Reconstruction):
    """A :class:`Reconstruction` plus the estimated rotations ``R`` (F, C, 3,
    3) (world to camera, photogrammetric), the bootstrap's rotations and the
    mean change of the pose centre per bootstrap round."""

    R: np.ndarray | None = None
    R_bootstrap: np.ndarray | None = None
    bootstrap_history: list = field(default_factory=list)


def _orthonormal(M):
    U, _, Vt = np.linalg.svd(M)
    D = np.ones(M.shape[:-1])
    D[..., -1] = np.sign(np.linalg.det(U @ Vt))
    return (U * D[..., None, :]) @ Vt


def _blend_rotations(batches, Rw, F, overlap):
    """Weighted mean of the window rotations (nw, C, T, 3, 3) per frame,
    projected to the nearest rotation."""
    C = Rw[0].shape[1]
    acc = np.zeros((F, C, 3, 3))
    for (ws, idx, b), R in zip(batches, Rw):
        w = blend_weights(idx.shape[1], overlap)
        np.add.at(acc, idx, w[None, :, None, None, None] * R.transpose(0, 2, 1, 3, 4))
    return _orthonormal(acc)


def _free_points(b):
    """The batch with the identity as pose basis: a free position per joint
    and frame (ablation Ours-A/B); every observed joint uses all frames."""
    T = b.B.shape[0]
    n = np.where(b.n_coef > 0, T, 0)
    return replace(b, B=np.eye(T), n_coef=n)


def _window_rotation_data(idx, R_boot, dR, dR_weight, BG, Q=None):
    """R_ref, start coefficients g, measured differences and weights of the
    windows with frame indices ``idx`` (nw, T); with the chain ``Q`` (F, C,
    3, 3) R_ref is chained per frame (:mod:`photogram.mocap.reconstruction.rotation_chain`)."""
    nw, T = idx.shape
    Rw = R_boot[idx].transpose(0, 2, 1, 3, 4)                        # (nw, C, T, 3, 3)
    if Q is None:
        R_ref = R_boot[idx[:, T // 2]]                              # (nw, C, 3, 3)
        gam = euler_from_matrices(np.swapaxes(R_ref, -1, -2)[:, :, None] @ Rw)
    else:
        R_ref = chained_references(idx, R_boot, Q)                  # (nw, C, T, 3, 3)
        gam = euler_from_matrices(np.swapaxes(R_ref, -1, -2) @ Rw)
    g = np.einsum("wcta,tk->wcak", gam, BG)
    if dR is None:
        C = R_boot.shape[1]
        return R_ref, g, np.broadcast_to(np.eye(3), (nw, C, T - 1, 3, 3)).copy(), \
            np.zeros((nw, C, T - 1))
    pairs = idx[:, :-1]
    return (R_ref, g, dR[pairs].transpose(0, 2, 1, 3, 4),
            dR_weight[pairs].transpose(0, 2, 1))


def _pair_sigma(s, difference_sigma, C):
    """Error per pair and axis (rad) of every camera's differences."""
    if s.chain_sigma_deg > 0:
        return np.full(C, np.radians(s.chain_sigma_deg))
    if difference_sigma is None:
        return np.full(C, np.radians(0.05))
    return np.asarray(difference_sigma, float)


def _with_noise(lagged, Q, sigma_pair):
    """The lagged differences with their estimated error per pair (rad),
    those of cameras without an estimate left out; None without any."""
    if lagged is None or not len(lagged[0]):
        return None
    cam, a, b, dR = (np.asarray(v) for v in lagged[:4])
    sig = lagged_noise(Q, (cam, a, b, dR), sigma_pair)[cam]
    keep = np.isfinite(sig)
    return cam[keep], a[keep], b[keep], dR[keep], sig[keep]


def _pose_on_anchor(batches, coeffs, R, X0, lengths, s, F, J):
    """The poses of every window again, the cameras held on the shared
    rotation track R (F, C, 3, 3) (the last stage of part 1, warm-started):
    every window then sees the same cameras and the blended trajectory is
    continuous (module doc); returns X, views and the stage's record."""
    E, iterations = 0.0, 0
    L = np.nan_to_num(lengths)
    lam_limbs = s.lambda_limbs / s.limb_unit ** 2
    for (ws, idx, b), a in zip(batches, coeffs):
        b.R = np.ascontiguousarray(R[idx].transpose(0, 2, 3, 4, 1))      # (nw, C, 3, 3, T)
        b.RX0 = np.einsum("wcabt,cb->wcat", b.R, X0)
        use = b.with_limb_mask(b.limb_mask * np.isfinite(lengths))
        a[...], e, it = solve_gauss_newton(use, a, s.sigma2, L, s.lambda_rep, lam_limbs,
                                           s.max_iterations, s.tolerance,
                                           step_tol=s.step_tol)
        E += float(np.sum(e))
        iterations = max(iterations, it)
    X, views = _blend(batches, coeffs, F, J, s.overlap)
    return X, views, {"step": "anchored poses", "sigma2": s.sigma2, "energy": E,
                      "iterations": iterations}


@one_blas_thread
def estimate_poses_and_rotations(observations, cameras: MocapCameras, skeleton: Skeleton,
                                 rotation_differences=None, difference_weights=None,
                                 settings: ReconstructionSettings | None = None,
                                 breaks=(), difference_sigma=None,
                                 lagged=None, chain=None) -> EstimatedRotations:
    """Reconstruct poses and camera rotations (module doc).

    Parameters
    ----------
    observations : (F, C, J, 3)
        As for :func:`photogram.mocap.reconstruction.reconstruct.reconstruct`.
    cameras : MocapCameras
        Projection centres and interior orientation (per frame); their
        rotations are not used.
    rotation_differences : (F-1, C, 3, 3) or None
        Measured ``dR`` with ``R(t+1) = dR(t) R(t)`` (None: no E_rot).
    difference_weights : (F-1, C) or None
        0 for pairs without a measurement (default: all 1).
    settings : ReconstructionSettings
        :func:`estimate_settings` by default.
    difference_sigma : (C,) or None
        Error of the measured differences per pair and axis (rad), e.g.
        :func:`photogram.mocap.reconstruction.chain_offsets.difference_noise`
        of the raw measurements; ``settings.chain_sigma_deg`` wins when > 0,
        0.05 deg where neither is known.
    lagged : tuple or None
        Differences measured over more than one frame, (camera (M,), first
        frame (M,), second frame (M,), dR (M, 3, 3)) with ``R(second) = dR
        R(first)`` (frames of ``observations``); their error is estimated
        against the chain (:func:`photogram.mocap.reconstruction.chain_offsets.lagged_noise`).
    chain : (F-1, C, 3, 3) or None
        The differences for the chain of the offsets stage: outliers removed
        but not smoothed
        (:func:`photogram.mocap.motion.unknown_rotations.chain_differences`);
        None: ``rotation_differences`` (as given, not smoothed again).
    """
    s = settings or estimate_settings()
    obs = np.asarray(observations, dtype=float)
    F, C, J, _ = obs.shape
    if obs.shape[1] != cameras.n_cameras or obs.shape[2] != skeleton.n_joints:
        raise InputError(f"observations must be (frames, {cameras.n_cameras} cameras, "
                         f"{skeleton.n_joints} joints, 3), got {obs.shape}")
    dR = None if rotation_differences is None else np.asarray(rotation_differences, float)
    if dR is not None and dR.shape != (F - 1, C, 3, 3):
        raise InputError(f"rotation differences must be ({F - 1}, {C}, 3, 3), got {dR.shape}")
    weights = np.ones((max(F - 1, 0), C)) if difference_weights is None \
        else np.asarray(difference_weights, float)
    lambda_rot = s.lambda_rot if (s.rotation_prior and dR is not None) else 0.0
    t0 = time.perf_counter()
    if s.pose_basis not in ("dct", "free") or s.rotation_basis not in ("dct", "free"):
        raise InputError(f"pose_basis and rotation_basis must be dct or free, not "
                         f"{s.pose_basis!r}, {s.rotation_basis!r}")
    cams = replace(cameras, R=np.broadcast_to(np.eye(3), (1, C, 3, 3)).copy())
    if s.pose_basis == "free":
        windows, batches = _batches(obs, cams, skeleton,
                                    replace(s, n_dct=s.window, cutoff_hz=None), breaks)
        batches = [(ws, idx, _free_points(b)) for ws, idx, b in batches]
    else:
        windows, batches = _batches(obs, cams, skeleton, s, breaks)

    def blend(coeffs):
        return _blend(batches, coeffs, F, J, s.overlap)[0]

    conf = np.where(np.isfinite(obs[..., 2]) & np.all(np.isfinite(obs[..., :2]), -1),
                    obs[..., 2], 0.0)
    conf = np.where(conf > s.min_confidence, conf, 0.0)
    xy = np.where((conf > 0)[..., None], obs[..., :2], np.nan)
    t_obs = cams.to_rays(xy)
    coeffs, R_boot, history = bootstrap_poses(
        batches, blend, cams, t_obs, conf, s, s.bootstrap_iterations, log=log,
        dR=dR if lambda_rot else None, breaks=breaks)
    t_boot = time.perf_counter() - t0
    given = _given_lengths(skeleton, s.limb_lengths) if s.limb_lengths else None
    lengths = given if given is not None else limb_lengths(blend(coeffs), skeleton,
                                                           s.symmetric_limbs)
    lam_limbs = s.lambda_limbs / s.limb_unit ** 2
    L = np.nan_to_num(lengths)
    observed = observed_frames(conf)
    Q = difference_chain(dR, weights, breaks) if lambda_rot else None
    energy, iterations, Rw, stages = 0.0, 0, [], []
    for b, (ws, idx, batch) in enumerate(batches):
        T = idx.shape[1]
        BG = np.eye(T) if s.rotation_basis == "free" else dct_basis(T, s.n_rotation_dct)
        R_ref, g, dRw, wts = _window_rotation_data(idx, R_boot, dR, weights, BG, Q)
        obs_batch = batch.with_limb_mask(batch.limb_mask * np.isfinite(lengths))
        jb = JointBatch(obs_batch, cameras.X0, R_ref, dRw, wts, BG,
                        camera_free=window_cameras(observed, idx))
        if s.solver == "lbfgs":       # the paper's, for comparison (1500 iterations)
            a, g, E, it = solve_joint_lbfgs(jb, coeffs[b], g, s.sigma2, L, s.lambda_rep,
                                            lam_limbs, lambda_rot, 15 * s.max_iterations)
        else:
            a, g, E, it = solve_joint(jb, coeffs[b], g, s.sigma2, L, s.lambda_rep, lam_limbs,
                                      lambda_rot, s.max_iterations, s.tolerance,
                                      step_tol=s.step_tol)
        coeffs[b] = a
        Rw.append(jb.rotations(g)[2])
        energy += float(np.sum(E))
        iterations = max(iterations, it)
    X, views = _blend(batches, coeffs, F, J, s.overlap)
    R = _blend_rotations(batches, Rw, F, s.overlap)
    t_joint = time.perf_counter() - t0 - t_boot
    joint_coeffs = [a.copy() for a in coeffs]
    carried = np.zeros((F, C), bool)
    anchored = stages_offsets = None
    if Q is not None:       # one rotation track per camera, the poses again on it
        usable = np.any(weights > 0, axis=0)
        R = anchor_rotations(R, Q, observed, usable, breaks)
        carried = ~observed & usable[None, :]
        if s.chain_offsets:     # the offsets over the whole run (module doc, step 5)
            t2 = time.perf_counter()
            sig = _pair_sigma(s, difference_sigma, C)
            Qc = difference_chain(dR if chain is None else np.asarray(chain, float), weights,
                                  breaks, sigma=0.0)          # not smoothed (chain_differences)
            R, offsets = refine_chain_offsets(
                X, R, Qc, t_obs, conf,
                cameras.pixel_scale(F), cameras.X0,
                np.flatnonzero(usable), breaks, s.offset_knot_frames, sig, s.sigma2,
                lagged=_with_noise(lagged, Qc, sig))
            stages_offsets = dict(step="chain offsets", seconds=time.perf_counter() - t2,
                                  **offsets)
        X, views, anchored = _pose_on_anchor(batches, coeffs, R, cameras.X0, lengths, s, F, J)
    n_views = np.sum(np.isfinite(obs[..., 0]) & (np.nan_to_num(obs[..., 2]) >
                                                  s.min_confidence), axis=1)
    X[(views == 0) | (_support(n_views, s.support_frames) < 2)] = np.nan
    valid = np.isfinite(X).all(axis=-1)
    seconds = time.perf_counter() - t0
    stages.append({"step": "bootstrap", "rounds": s.bootstrap_iterations,
                   "seconds": t_boot, "last_change_m": history[-1] if history else None})
    stages.append({"step": "joint", "sigma2": s.sigma2, "lambda_rot": lambda_rot,
                   "energy": energy, "iterations": iterations, "seconds": t_joint,
                   "seam_disagreement_m": window_disagreement(batches, joint_coeffs, F, J,
                                                              valid),
                   "chained_camera_frames": carried.sum(axis=0).tolist()})
    if anchored is not None:
        anchored.update(seconds=seconds - t_boot - t_joint,
                        seam_disagreement_m=window_disagreement(batches, coeffs, F, J, valid))
        if stages_offsets is not None:
            stages.append(stages_offsets)
        stages.append(anchored)
    return EstimatedRotations(joints=X, n_views=n_views, limb_lengths=lengths, energy=energy,
                              iterations=iterations, seconds=seconds,
                              solver="joint-lbfgs" if s.solver == "lbfgs" else "joint-lm",
                              n_windows=len(windows), stages=stages, R=R, R_bootstrap=R_boot,
                              bootstrap_history=history)
