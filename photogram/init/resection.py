"""Space resection: the exterior orientation of one image from known object
points and known interior orientation.

* :func:`resection_direct` — closed-form candidates: Grunert's three-point
  solution (P3P) and, for planar point sets, the decomposition of the
  plane-to-image homography.
* :func:`resect` — picks the candidate that reprojects all points best.
* :func:`refine_resection` — Gauss-Newton least squares with the full camera
  model (distortion included) of :mod:`photogram.geometry`.

The closed-form candidates are computed in :mod:`photogram.init.resection_start`,
the least squares in :mod:`photogram.init.resection_refine`; this module
chooses among the candidates and re-exports both.

Conventions (:mod:`photogram.project.model`): ``Xc = R (X - X0)``, camera
frame x right, y up, looking along -z (points in front have ``Xc_z < 0``);
image coordinates x right, y down; ideal collinearity
``x - x0 = -c Xc_x / Xc_z``, ``y - y0 = c Xc_y / Xc_z``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.errors import GeometryError
from photogram.geometry.rotations import matrix_to_opk
from photogram.init.rays import bearings
from photogram.init.resection_refine import ResectionResult, refine_resection
from photogram.init.resection_start import _check_input, project_ideal, resection_direct

__all__ = ["resection_direct", "resect", "refine_resection", "ResectionResult",
           "PoseEstimate", "bearings", "project_ideal"]


@dataclass
class PoseEstimate:
    """An approximate exterior orientation.

    ``R`` world-to-camera rotation, ``X0`` projection centre, ``rms``
    reprojection RMS over all points (image units, per coordinate),
    ``candidates`` the number of distinct candidates considered.
    """

    R: np.ndarray
    X0: np.ndarray
    rms: float
    candidates: int

    @property
    def angles(self) -> np.ndarray:
        """Omega-phi-kappa of ``R`` (radians)."""
        return matrix_to_opk(self.R)


def resect(X, xy_ideal, c, x0=0.0, y0=0.0) -> PoseEstimate:
    """Space resection with known interior orientation: the best closed-form
    candidate.

    All candidates of :func:`resection_direct` are scored by the RMS of the
    ideal reprojection residuals over all points (candidates putting a point
    behind the camera, ``Xc_z >= 0``, are discarded); the smallest wins. With
    exactly 3 points the choice is only possible if there is one candidate.

    Parameters
    ----------
    X, xy_ideal, c, x0, y0 :
        As in :func:`resection_direct`.

    Returns
    -------
    PoseEstimate

    Raises
    ------
    GeometryError
        As :func:`resection_direct`; also when no candidate puts all points
        in front of the camera, or when 3 points leave several candidates.
    """
    X, xy = _check_input(X, xy_ideal, 3, "space resection")
    cands = resection_direct(X, xy, c, x0, y0)
    if not cands:
        raise GeometryError(
            "space resection found no real solution",
            hint="check the principal distance and the point correspondences")
    Rs = np.stack([R for R, _ in cands])
    X0s = np.stack([X0 for _, X0 in cands])
    Xc = np.einsum("kij,knj->kni", Rs, X[None] - X0s[:, None])      # (k, n, 3)
    front = (Xc[..., 2] < 0).all(axis=1)
    if not front.any():
        raise GeometryError(
            "space resection: no solution has all points in front of the camera",
            hint="check the point correspondences and the image y axis (down)")
    with np.errstate(divide="ignore", invalid="ignore"):
        proj = np.stack([x0 - c * Xc[..., 0] / Xc[..., 2],
                         y0 + c * Xc[..., 1] / Xc[..., 2]], axis=-1)
    rms = np.sqrt(np.mean((proj - xy) ** 2, axis=(1, 2)))
    rms[~front] = np.inf
    order = np.argsort(rms)
    best = order[0]
    # distinct candidates (the same pose found from several triples counts once)
    distinct = [order[0]]
    for k in order[1:]:
        if np.isfinite(rms[k]) and not any(
                np.allclose(Rs[k], Rs[j], atol=1e-6) and
                np.allclose(X0s[k], X0s[j], atol=1e-6 * (1 + np.abs(X0s[j]).max()))
                for j in distinct):
            distinct.append(k)
    if len(X) == 3 and len(distinct) > 1:
        raise GeometryError(
            f"space resection from 3 points is ambiguous ({len(distinct)} solutions)",
            hint="add a 4th point, or pick a solution from resection_direct() "
                 "with an approximate camera position")
    return PoseEstimate(R=Rs[best], X0=X0s[best], rms=float(rms[best]),
                        candidates=len(distinct))
