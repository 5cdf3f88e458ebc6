"""3D reconstruction of a sequence from multi-view 2D detections (sections
4.3-4.4 of the paper, with known camera rotations).

Every joint coordinate is an inverse DCT plus a linear trend per window
(:func:`photogram.mocap.reconstruction.dct.trend_basis`: without the trend
every window's ends bend flat and overlapping windows disagree) whose DCT
terms are chosen by a cut-off
frequency, ``cutoff_hz`` (default 12 Hz: ``floor(2 T fc / fps) + 1``
coefficients in a window of T frames, 25 over 50 frames at 50 fps, the
paper's N_Pi), or by an explicit count ``n_dct`` (which then wins; the
project file refuses both); the coefficients minimise the energy of
:mod:`photogram.mocap.reconstruction.energy` (robust confidence-weighted reprojection term,
lambda_rep = 80, sigma^2 = 100 px^2; limb-length prior, lambda_limbs = 1).
All joints start at the centre of the cameras (the mean projection centre),
as in the paper. The solvers are in :mod:`photogram.mocap.reconstruction.solvers`:
``"gauss-newton"`` (default; IRLS Gauss-Newton / Levenberg-Marquardt with
preconditioned conjugate gradients) and ``"lbfgs"`` (the paper's L-BFGS).

Continuation (graduated non-convexity; both solvers): from the centre of
the cameras every detection is hundreds of pixels off and the Geman-McClure
function would treat all of them as outliers, so the robust scale starts at
``sigma^2 = gnc_start`` (1e6 px^2) and is divided by ten per stage down to
the paper's 100 px^2. The stages with sigma^2 >= 1e4 px^2 only place the
athlete roughly and use at most 10 coefficients and every third frame. The
limb lengths, when not given, are estimated before the last stage as the
medians of the reconstructed lengths over the joint-frames two cameras
detect (left and right averaged), and the limb prior (given or estimated
lengths) is active in the last stage only.
The energy reported is that of the last stage: the paper's energy.

Partly observed joints: restricted to the frames a joint is detected in, the
DCT basis is nearly degenerate when the gap is contiguous (condition number
7.5e6 for 25 coefficients on the first 40 of 50 frames, 5e8 for 10 on the
first 20): the trajectory in the gap is an extrapolation that the energy
hardly constrains, and the solvers creep along it for ever. Such a joint
uses the most leading coefficients for which that condition number stays
below 100 (scattered single missing frames keep all 25); the others stay
zero. A joint-frame that fewer than two cameras observe (detected, in
front, fitted within ``inlier_sigmas`` sqrt(sigma2) px) is a gap
(:mod:`photogram.mocap.reconstruction.observability`): NaN in the joints,
its reason in ``Reconstruction.gaps`` (``support_frames`` may bridge short
runs; default 0, none).
"""

from __future__ import annotations

import logging
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from photogram.errors import InputError
from photogram.mocap.body.skeleton import Skeleton
from photogram.mocap.reconstruction.blas import one_blas_thread
from photogram.mocap.reconstruction.cameras import MocapCameras
from photogram.mocap.reconstruction.dct import (blend_weights, coefficients_for_cutoff,
                                                plan_windows, trend_basis)
from photogram.mocap.reconstruction.energy import WindowBatch
from photogram.mocap.reconstruction.observability import (Gaps, bridge_short_runs, find_gaps,
                                                          observing_cameras)
from photogram.mocap.reconstruction.solvers import solve_gauss_newton, solve_lbfgs

__all__ = ["ReconstructionSettings", "Reconstruction", "reconstruct", "limb_lengths",
           "window_disagreement",
           "SOLVERS", "DEFAULT_CUTOFF_HZ"]

log = logging.getLogger(__name__)
SOLVERS = ("gauss-newton", "lbfgs")
MAX_CONDITION = 100.0    # of the DCT basis on the frames a joint is detected in
#: default DCT cut-off (Hz): 25 coefficients over 50 frames at 50 fps (the paper's N_Pi for
#: skiing); the smoothing proper is the Butterworth post-filter at 6 Hz
#: (:mod:`photogram.mocap.reconstruction.filtering`), which unlike a lower DCT cut-off
#: keeps the fast translation of a skier at the ends of the windows (docs/mocap.md)
DEFAULT_CUTOFF_HZ = 12.0
#: default robust scale sigma^2 (px^2) of the Geman-McClure reprojection norm
#: rho = e^2 / (e^2 + sigma^2) (docs/mocap.md section 6); the paper's is 100 px^2
#: (``PAPER_SIGMA2``, still reachable: ``[mocap.reconstruction] sigma2 = 100``). 400 px^2
#: fits Pose2Sim's real demo better (mean reprojection error, jerk, bone lengths), the
#: simulated skiing about as well (mixed), but lets one camera with a static bias of
#: 10-30 px into the joints more (benchmarks/mocap_smoothness.py, docs/mocap.md sections 6, 10)
DEFAULT_SIGMA2 = 400.0
PAPER_SIGMA2 = 100.0


@dataclass
class ReconstructionSettings:
    """Settings of :func:`reconstruct` (defaults: the paper's values, except the
    DCT cut-off and ``sigma2``, see ``DEFAULT_CUTOFF_HZ`` and ``DEFAULT_SIGMA2``)."""

    n_dct: int | None = None        # explicit coefficients per window (wins over cutoff_hz)
    cutoff_hz: float | None = None  # DCT cut-off (Hz); None: DEFAULT_CUTOFF_HZ unless n_dct
    fps: float = 50.0               # frame rate of the observations (for cutoff_hz)
    window: int = 50
    overlap: int = 10
    sigma2: float = DEFAULT_SIGMA2  # px^2; the paper's: PAPER_SIGMA2 = 100
    lambda_rep: float = 80.0
    lambda_limbs: float = 1.0
    limb_unit: float = 0.01         # limb residuals in this length (cm of a project in m)
    solver: str = "gauss-newton"
    gnc_start: float = 1e6          # sigma^2 of the first continuation stage (px^2)
    max_iterations: int = 100       # per stage (Gauss-Newton) / per stage x 20 (L-BFGS)
    tolerance: float = 1e-9         # relative energy decrease that ends the last stage
    limb_lengths: dict | None = None   # {(a, b): length}; None: estimate
    symmetric_limbs: bool = True
    min_confidence: float = 0.0
    support_frames: int = 0         # bridge gaps (< 2 cameras) of at most this many frames
    inlier_sigmas: float = 3.0      # a camera counts where its error <= this x sqrt(sigma2)
    step_tol: float = 1e-5          # converged when no determined position moves more (m)
    # unknown camera rotations (photogram.mocap.reconstruction.estimate; estimate_settings())
    rotation: str = "known"         # or "estimate"
    n_rotation_dct: int = 11        # N_Gamma: DCT coefficients per camera and angle
    lambda_rot: float = 1e4         # weight of E_rot, eq. (14) (residuals in degrees)
    bootstrap_iterations: int = 25
    pose_basis: str = "dct"         # or "free" (ablation: a position per joint and frame)
    rotation_basis: str = "dct"     # or "free" (ablation: angles per frame)
    rotation_prior: bool = True     # False: no E_rot (ablation)
    chain_offsets: bool = True      # fit the chain's offsets over the whole run (chain_offsets)
    offset_knot_frames: int = 2     # knots of the offset tracks every this many frames
    chain_sigma_deg: float = 0.0    # error of the differences per pair and axis; 0: measured

    def __post_init__(self):
        if self.n_dct is not None and self.cutoff_hz is not None:
            raise InputError(f"give either n_dct ({self.n_dct}) or cutoff_hz "
                             f"({self.cutoff_hz}) for the reconstruction, not both",
                             hint="cutoff_hz = 12 keeps the DCT terms up to 12 Hz; n_dct a count")
        if self.n_dct is not None and self.n_dct < 1:
            raise InputError(f"n_dct must be at least 1, not {self.n_dct}")
        if self.cutoff_hz is not None and not 0 < self.cutoff_hz < self.fps / 2:
            raise InputError(f"cutoff_hz must be in (0, fps/2 = {self.fps / 2:g}) Hz, not "
                             f"{self.cutoff_hz}")

    @property
    def inlier_px(self) -> float | None:
        """Largest reprojection error (px) of a detection that counts for
        a joint-frame's determination (None: any; ``inlier_sigmas`` 0)."""
        return float(self.inlier_sigmas) * float(np.sqrt(self.sigma2)) \
            if self.inlier_sigmas > 0 else None

    @property
    def cutoff(self) -> float | None:
        """The DCT cut-off in Hz in use (None when ``n_dct`` counts)."""
        if self.n_dct is not None:
            return None
        return DEFAULT_CUTOFF_HZ if self.cutoff_hz is None else float(self.cutoff_hz)

    def coefficients(self, length: int) -> int:
        """DCT coefficients of a window of ``length`` frames: ``n_dct``
        (at most ``length``), else the count of the cut-off,
        :func:`~photogram.mocap.reconstruction.dct.coefficients_for_cutoff`."""
        if self.n_dct is not None:
            return min(int(self.n_dct), int(length))
        return coefficients_for_cutoff(int(length), self.cutoff, self.fps)

    def stages(self) -> list[float]:
        s, out = float(self.gnc_start), []
        while s > self.sigma2 * 1.0001:
            out.append(s)
            s /= 10.0
        return out + [float(self.sigma2)]


@dataclass
class Reconstruction:
    """Result of :func:`reconstruct`: joints (F, J, 3), NaN at the gaps
    (joint-frames fewer than two cameras observe, unless ``support_frames``
    bridges them: the trajectory there is an extrapolation), ``gaps`` their
    reasons (:class:`~photogram.mocap.reconstruction.observability.Gaps`);
    ``n_views`` (F, J) detections per frame."""

    joints: np.ndarray
    n_views: np.ndarray
    limb_lengths: np.ndarray
    energy: float
    iterations: int
    seconds: float
    solver: str
    n_windows: int
    stages: list = field(default_factory=list)
    unfiltered: np.ndarray | None = None    # the joints before a post-filter (pipeline)
    gaps: Gaps | None = None                # the undetermined joint-frames and why


# --------------------------------------------------------------------------
def limb_lengths(X: np.ndarray, skeleton: Skeleton, symmetric: bool = True) -> np.ndarray:
    """Median length of every limb over the frames of X (F, J, 3) (NaN-aware);
    with ``symmetric`` the left and right limbs get their mean."""
    L = skeleton.limb_indices()
    d = np.linalg.norm(X[:, L[:, 0]] - X[:, L[:, 1]], axis=-1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)        # limbs never seen
        med = np.nanmedian(d, axis=0) if len(d) else np.full(len(L), np.nan)
    if symmetric:
        perm = skeleton.swap_permutation()
        key = {tuple(sorted(p)): k for k, p in enumerate(L.tolist())}
        out = med.copy()
        for k, (a, b) in enumerate(L):
            m = key.get(tuple(sorted((perm[a], perm[b]))))
            if m is not None and m != k and np.isfinite(med[m]) and np.isfinite(med[k]):
                out[k] = 0.5 * (med[k] + med[m])
        med = out
    return med


def _given_lengths(skeleton: Skeleton, given: dict) -> np.ndarray:
    out = np.full(len(skeleton.limbs), np.nan)
    for k, (a, b) in enumerate(skeleton.limbs):
        v = given.get((a, b), given.get((b, a)))
        if v is not None:
            out[k] = float(v)
    return out


def _batches(obs, cameras: MocapCameras, skeleton: Skeleton, settings, breaks):
    """Gather the windows into batches of equal length, laid out (nw, C, J, T)."""
    F, C, J, _ = obs.shape
    conf = np.where(np.isfinite(obs[..., 2]) & np.all(np.isfinite(obs[..., :2]), -1),
                    obs[..., 2], 0.0)
    conf = np.where(conf > settings.min_confidence, conf, 0.0)
    xy = np.where((conf > 0)[..., None], obs[..., :2], np.nan)
    t_obs = np.nan_to_num(cameras.to_rays(xy)).transpose(1, 2, 0, 3)     # (C, J, F, 2)
    conf = conf.transpose(1, 2, 0)                                         # (C, J, F)
    scale = cameras.pixel_scale(F).transpose(1, 2, 0)                      # (C, 2, F)
    R = cameras.rotations(F).transpose(1, 2, 3, 0)                         # (C, 3, 3, F)
    RX0 = np.einsum("cabf,cb->caf", R, cameras.X0)
    windows = plan_windows(F, settings.window, settings.overlap, settings.coefficients,
                           breaks)
    determined = _determined(obs, settings, breaks)   # the convergence test watches these
    limbs = skeleton.limb_indices()
    groups: dict[tuple, list] = {}
    for w in windows:
        groups.setdefault((w.length, w.n_coefficients), []).append(w)
    out = []
    for (T, K), ws in groups.items():
        idx = np.array([np.arange(w.start, w.stop) for w in ws])       # (nw, T)
        c = np.ascontiguousarray(conf[:, :, idx].transpose(2, 0, 1, 3))   # (nw, C, J, T)
        B = trend_basis(T, K)
        n_coef = _coefficients(np.any(c > 0, axis=1), B)              # (nw, J)
        support = determined[idx]                                      # (nw, T, J)
        observed = n_coef > 0
        mask = observed[:, limbs[:, 0]] & observed[:, limbs[:, 1]] if len(limbs) \
            else np.zeros((len(ws), 0), bool)
        t = t_obs[:, :, idx].transpose(2, 0, 1, 3, 4)                  # (nw, C, J, T, 2)
        sc = scale[:, :, idx].transpose(2, 0, 1, 3)                    # (nw, C, 2, T)
        batch = WindowBatch(
            tx=np.ascontiguousarray(t[..., 0]), ty=np.ascontiguousarray(t[..., 1]), conf=c,
            sx=np.ascontiguousarray(sc[:, :, 0:1]), sy=np.ascontiguousarray(sc[:, :, 1:2]),
            R=np.ascontiguousarray(R[..., idx].transpose(3, 0, 1, 2, 4)),
            RX0=np.ascontiguousarray(RX0[..., idx].transpose(2, 0, 1, 3)),
            B=B, limbs=limbs, limb_mask=mask.astype(float), n_coef=n_coef,
            support=np.ascontiguousarray(support.transpose(0, 2, 1)))
        out.append((ws, idx, batch))
    return windows, out


def _determined(obs, settings, breaks) -> np.ndarray:
    """(F, J) the joint-frames two cameras detect (short runs bridged by
    ``support_frames``), before any reconstruction."""
    views = np.count_nonzero(observing_cameras(obs, settings.min_confidence), axis=1)
    return bridge_short_runs(views >= 2, settings.support_frames, breaks)


def _coefficients(seen: np.ndarray, B: np.ndarray, max_cond: float | None = None):
    """Coefficients (nw, J) each joint may use: all K when it is detected in
    every frame of the window, else the most leading ones for which the
    basis on its frames ``seen`` (nw, J, T) has a condition number <=
    ``max_cond`` (0 when never detected)."""
    max_cond = MAX_CONDITION if max_cond is None else max_cond
    T, K = B.shape
    n = np.where(seen.all(axis=-1), K, 0)
    part = np.flatnonzero((~seen.all(axis=-1) & seen.any(axis=-1)).ravel())
    if len(part):
        m = seen.reshape(-1, T)[part].astype(float)
        G = np.einsum("nt,tk,tl->nkl", m, B, B)
        best = np.ones(len(part), int)
        for k in range(2, K + 1):
            ev = np.linalg.eigvalsh(G[:, :k, :k])
            ok = ev[:, 0] > ev[:, -1] / max_cond ** 2
            best = np.where(ok & (best == k - 1), k, best)
        n.reshape(-1)[part] = best
    return n


def _stage_plan(s: ReconstructionSettings):
    """(sigma^2, coefficients, frame step) of every continuation stage: the
    stages with sigma^2 >= 1e4 px^2 only place the athlete roughly, so they
    use at most 10 coefficients and every third frame; the others all of
    each window's coefficients (``None``)."""
    out = []
    for sigma2 in s.stages():
        coarse = sigma2 >= 1e4 - 1e-9 and sigma2 > s.sigma2
        out.append((sigma2, 10 if coarse else None, 3 if coarse else 1))
    return out


@one_blas_thread
def reconstruct(observations: np.ndarray, cameras: MocapCameras, skeleton: Skeleton,
                settings: ReconstructionSettings | None = None, breaks=()) -> Reconstruction:
    """Reconstruct the joints of a sequence.

    Parameters
    ----------
    observations : (F, C, J, 3)
        x, y (px, full image) and confidence of joint j in camera c at frame
        f; NaN or confidence 0: no detection.
    cameras : MocapCameras
        With rotations (and interior orientation) per frame or fixed.
    skeleton : Skeleton
        The joints of ``observations`` (J = skeleton.n_joints) and the limbs.
    settings : ReconstructionSettings
    breaks : frames where an independent segment starts (windows never cross).
    """
    s = settings or ReconstructionSettings()
    if s.solver not in SOLVERS:
        raise InputError(f"unknown solver {s.solver!r}", hint="use " + " or ".join(SOLVERS))
    obs = np.asarray(observations, dtype=float)
    if obs.ndim != 4 or obs.shape[1] != cameras.n_cameras or obs.shape[2] != skeleton.n_joints \
            or obs.shape[3] != 3:
        raise InputError(f"observations must be (frames, {cameras.n_cameras} cameras, "
                         f"{skeleton.n_joints} joints, 3), got {obs.shape}")
    t0 = time.perf_counter()
    F, J = obs.shape[0], skeleton.n_joints
    windows, batches = _batches(obs, cameras, skeleton, s, breaks)
    determined = _determined(obs, s, breaks)
    given = _given_lengths(skeleton, s.limb_lengths) if s.limb_lengths else None
    centre = cameras.centre()
    coeffs = []
    for ws, idx, batch in batches:
        nw, T, C, J, K = batch.shape
        a = np.zeros((nw, J, 3, K))
        a[:, :, :, 0] = centre * np.sqrt(T)          # constant trajectory at the centre
        coeffs.append(a)
    solver = solve_gauss_newton if s.solver == "gauss-newton" else solve_lbfgs
    stages, iterations = [], 0
    plan = _stage_plan(s)
    n_max = max(w.n_coefficients for w in windows)      # DCT terms (the basis adds a trend)
    lengths = given if given is not None else np.full(len(skeleton.limbs), np.nan)
    for n, (sigma2, k, step) in enumerate(plan):
        last = n == len(plan) - 1
        if last and given is None and len(skeleton.limbs):
            X, _ = _blend(batches, coeffs, F, J, s.overlap)
            X[~determined] = np.nan               # lengths from what two cameras see
            lengths = limb_lengths(X, skeleton, s.symmetric_limbs)
        lam = s.lambda_limbs / s.limb_unit ** 2 if last else 0.0
        L = np.nan_to_num(lengths)
        stage_E, stage_it = 0.0, 0
        for b, (ws, idx, batch) in enumerate(batches):
            use = batch.subsample(step)
            if lam:
                use = use.with_limb_mask(batch.limb_mask * np.isfinite(lengths))
            kk = min(k or batch.B.shape[1], use.B.shape[0], batch.B.shape[1])
            a, E, it = solver(use, coeffs[b][..., :kk].copy(), sigma2, L, s.lambda_rep, lam,
                              s.max_iterations, s.tolerance if last else 1e-4,
                              second_order=last, step_tol=s.step_tol if last else 0.0)
            coeffs[b][..., :kk] = a
            stage_E += float(np.sum(E))
            stage_it = max(stage_it, it)
        iterations += stage_it
        stages.append({"sigma2": sigma2, "coefficients": min(k or n_max, n_max),
                       "linear_trend": True,
                       "cutoff_hz": s.cutoff if k is None else None, "frame_step": step,
                       "lambda_limbs": lam, "energy": stage_E, "iterations": stage_it,
                       "seconds": time.perf_counter() - t0})
        log.debug("stage sigma2=%g k=%d step=%d energy=%.6g iterations=%d %.2fs", sigma2,
                  stages[-1]["coefficients"], step, stage_E, stage_it, time.perf_counter() - t0)
    X, views = _blend(batches, coeffs, F, J, s.overlap)
    n_views = np.sum(np.isfinite(obs[..., 0]) & (np.nan_to_num(obs[..., 2]) >
                                                  s.min_confidence), axis=1)
    X[views == 0] = np.nan
    gaps = find_gaps(obs, s.min_confidence, s.support_frames, breaks, cameras, X,
                     max_error_px=s.inlier_px)
    X[gaps.mask] = np.nan
    stages[-1]["seam_disagreement_m"] = window_disagreement(batches, coeffs, F, J,
                                                            np.isfinite(X).all(axis=-1))
    return Reconstruction(joints=X, n_views=n_views, limb_lengths=lengths,
                          energy=stages[-1]["energy"], iterations=iterations,
                          seconds=time.perf_counter() - t0, solver=s.solver,
                          n_windows=len(windows), stages=stages, gaps=gaps)


def _support(n_views: np.ndarray, h: int) -> np.ndarray:
    """Detections of every joint within +-h frames (F, J) (the rule of
    :mod:`photogram.mocap.reconstruction.estimate`'s own mask; the pipeline
    applies :func:`~photogram.mocap.reconstruction.observability.find_gaps`
    after it)."""
    c = np.concatenate([np.zeros((1, n_views.shape[1])), np.cumsum(n_views, axis=0)])
    F = len(n_views)
    lo = np.clip(np.arange(F) - h, 0, F)
    hi = np.clip(np.arange(F) + h + 1, 0, F)
    return c[hi] - c[lo]


def _blend(batches, coeffs, F, J, overlap):
    """Blend the window trajectories (dct module doc); ``views`` counts the
    windows in which each (frame, joint) is observed."""
    acc = np.zeros((F, J, 3))
    wsum = np.zeros((F, J))
    views = np.zeros((F, J))
    for (ws, idx, batch), a in zip(batches, coeffs):
        X = batch.positions(a).transpose(0, 3, 1, 2)              # (nw, T, J, 3)
        w = blend_weights(idx.shape[1], overlap)[None, :, None] * batch.observed[:, None, :]
        np.add.at(acc, idx, w[..., None] * X)
        np.add.at(wsum, idx, w)
        np.add.at(views, idx, np.broadcast_to(batch.observed[:, None, :], w.shape))
    with np.errstate(invalid="ignore", divide="ignore"):
        X = acc / wsum[..., None]
    return X, views


def window_disagreement(batches, coeffs, F, J, valid=None) -> dict:
    """How far overlapping windows' solutions are apart before blending:
    ``|X_a(t) - X_b(t)|`` of the joints observed in both windows of an
    overlap (twice the spread about their mean where three overlap), over
    the frames and joints ``valid`` (F, J) (default all): median, 95th
    percentile and maximum (m; None without overlaps). Independent window
    solutions that disagree are blended into a trajectory that changes
    faster in the overlap than the motion (docs/mocap.md section 6)."""
    s1 = np.zeros((F, J, 3))
    s2 = np.zeros((F, J))
    n = np.zeros((F, J))
    for (ws, idx, batch), a in zip(batches, coeffs):
        X = batch.positions(a).transpose(0, 3, 1, 2)              # (nw, T, J, 3)
        m = np.broadcast_to(batch.observed[:, None, :], X.shape[:3]).astype(float)
        np.add.at(s1, idx, m[..., None] * X)
        np.add.at(s2, idx, m * np.sum(X * X, axis=-1))
        np.add.at(n, idx, m)
    use = (n >= 2) & (True if valid is None else valid)
    if not use.any():
        return {"median": None, "p95": None, "max": None}
    mean = s1[use] / n[use, None]
    d = 2.0 * np.sqrt(np.maximum(s2[use] / n[use] - np.sum(mean * mean, axis=-1), 0.0))
    return {"median": float(np.median(d)), "p95": float(np.percentile(d, 95)),
            "max": float(d.max())}
