"""The chain of measured rotation differences, carried through windows and
across the frames where a camera does not see the athlete (unknown
rotations, section 4.5 of the paper; issue 22, item 4).

The measured differences ``dR(t)`` (``R(t+1) = dR(t) R(t)``, eqs.
(12)-(14)) cover every frame of a camera, also those where tracking lost
the athlete; the athlete's detections only fix the chain's absolute
orientation. Three uses:

* **reference per frame** (:func:`chained_references`): in every window the
  rotation is ``R(t) = R_ref(t) E(gamma(t))`` with ``R_ref(t) = Q(t) Q(m)^T
  R_start(m)``, Q the chain (``Q(t+1) = dR(t) Q(t)``, the identity at the
  first frame of every run), m the window's middle frame: at constant
  ``gamma`` the window follows the measured motion exactly (E_rot = 0), the
  DCT of ``gamma`` carries only the slow correction
  (:mod:`photogram.mocap.motion.camera_motion`); the chain is built from
  the differences smoothed by a Gaussian of 3 pairs (:func:`difference_chain`);
* **held cameras** (:func:`window_cameras`): a camera with fewer than
  ``min_frames`` observed frames (at least ``min_joints`` detections) in a
  window keeps its start rotation there: nothing but E_rot's differences
  would determine it, and their null space (a constant turn) let the old
  solver corrupt such windows by 90-120 deg;
* **carried rotations** (:func:`carry_rotations`): after the windows are
  blended, a camera's frames without observations get ``Q(t) O``, the
  offset ``O = Q(s)^T R(s)`` averaged (chordal mean) over up to
  ``n_anchor`` observed frames s on each side of the gap, the two sides
  blended linearly over the gap (the chain's drift grows with the distance
  from its anchor), one side at the ends of a run. A camera whose
  differences are not usable (weight 0) is left as estimated.
"""

from __future__ import annotations

import numpy as np

from photogram.mocap.reconstruction.bootstrap import chain_rotations

__all__ = ["observed_frames", "difference_chain", "chained_references", "window_cameras",
           "anchor_rotations", "nearest_rotations"]


def _segments(F, breaks):
    cuts = sorted({0, F} | {int(b) for b in breaks if 0 < int(b) < F})
    return list(zip(cuts[:-1], cuts[1:]))


def nearest_rotations(M: np.ndarray) -> np.ndarray:
    """The rotations (..., 3, 3) nearest to M (SVD, determinant +1)."""
    U, _, Vt = np.linalg.svd(M)
    D = np.ones(M.shape[:-1])
    D[..., -1] = np.sign(np.linalg.det(U @ Vt))
    return (U * D[..., None, :]) @ Vt


def observed_frames(conf: np.ndarray, min_joints: int = 4) -> np.ndarray:
    """(F, C): camera c sees the athlete at frame f, i.e. has at least
    ``min_joints`` detections with confidence > 0 (``conf`` (F, C, J))."""
    return np.sum(conf > 0, axis=2) >= min_joints


def difference_chain(dR: np.ndarray, weights: np.ndarray, breaks=(),
                     sigma: float = 3.0) -> np.ndarray:
    """The chain Q (F, C, 3, 3) of the differences (F-1, C, 3, 3), their
    rotation vectors smoothed per run by a Gaussian of ``sigma`` pairs
    (0: as measured); pairs of weight 0 count as no motion. The chain sums
    the differences' errors (a random walk); the smoothing keeps the slow
    camera motion and averages independent errors of consecutive pairs
    (simulated, 0.02 deg per pair: speed MAE 0.160 -> 0.107 m/s, docs/mocap.md
    section 12)."""
    from scipy.ndimage import gaussian_filter1d

    from photogram.geometry.rotations import matrix_to_rodrigues, rodrigues_to_matrix
    use = np.where((np.asarray(weights) > 0)[..., None, None], dR, np.eye(3))
    if sigma > 0 and len(use):
        r = matrix_to_rodrigues(use.reshape(-1, 3, 3)).reshape(use.shape[:-2] + (3,))
        for s, e in _segments(len(use) + 1, breaks):           # the pairs s .. e-2
            if e - s > 2:
                r[s:e - 1] = gaussian_filter1d(r[s:e - 1], sigma, axis=0, mode="nearest")
        use = rodrigues_to_matrix(r.reshape(-1, 3)).reshape(use.shape)
    return chain_rotations(use, breaks)


def chained_references(idx: np.ndarray, R_start: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """``R_ref(t) = Q(t) Q(m)^T R_start(m)`` (nw, C, T, 3, 3) of the windows
    with frame indices ``idx`` (nw, T), m the middle frame (module doc)."""
    mid = idx[:, idx.shape[1] // 2]
    anchor = np.swapaxes(Q[mid], -1, -2) @ R_start[mid]            # (nw, C, 3, 3)
    return Q[idx].transpose(0, 2, 1, 3, 4) @ anchor[:, :, None]


def window_cameras(observed: np.ndarray, idx: np.ndarray, min_frames: int = 3) -> np.ndarray:
    """(nw, C): the camera has at least ``min_frames`` observed frames in the
    window (``observed`` (F, C) of :func:`observed_frames`)."""
    return observed[idx].sum(axis=1) >= min_frames


def anchor_rotations(R: np.ndarray, Q: np.ndarray, observed: np.ndarray, usable: np.ndarray,
                     breaks=(), sigma: float = 10.0) -> np.ndarray:
    """One rotation track per camera shared by all windows: ``Q(t) O(t)``
    with the offset ``O(t) = Q(t)^T R(t)`` of the blended window rotations R
    (F, C, 3, 3) smoothed over the observed frames of the run by a Gaussian
    of ``sigma`` frames (normalised convolution of the rotation vectors
    about the run's chordal mean offset: the gaps between observations get
    the offsets of their two sides, weighted by the distance). The chain's
    drift is slow, the windows' own offsets are not: each window fixes the
    absolute orientation from its frames alone, and overlapping windows
    disagree (docs/mocap.md section 12). Cameras without usable differences
    keep R."""
    from scipy.ndimage import gaussian_filter1d

    from photogram.geometry.rotations import matrix_to_rodrigues, rodrigues_to_matrix
    R = np.array(R, dtype=float)
    F, C = observed.shape
    for c in np.flatnonzero(usable):
        for s, e in _segments(F, breaks):
            w = observed[s:e, c].astype(float)
            if not w.any():
                continue
            O = np.swapaxes(Q[s:e, c], -1, -2) @ R[s:e, c]
            M0 = nearest_rotations(np.sum(w[:, None, None] * O, axis=0))
            r = matrix_to_rodrigues(M0.T @ O) * w[:, None]
            num = gaussian_filter1d(r, sigma, axis=0, mode="nearest")
            den = gaussian_filter1d(w, sigma, mode="nearest")
            r_s = num / np.maximum(den, 1e-300)[:, None]
            if np.any(den < 1e-12):               # frames beyond the filter's reach
                seen = np.flatnonzero(w > 0)
                far = np.flatnonzero(den < 1e-12)
                near = seen[np.clip(np.searchsorted(seen, far), 0, len(seen) - 1)]
                r_s[far] = r[near]
            R[s:e, c] = Q[s:e, c] @ (M0 @ rodrigues_to_matrix(r_s))
    return R
