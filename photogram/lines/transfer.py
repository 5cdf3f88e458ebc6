"""Line transfer between views (into a third view).

**Transfer.** A line measured in two oriented views a and b is the
intersection of their planes (step B with two views, space_line.py);
projected into a third view c it predicts the line there. This is the
trifocal line transfer of Hartley & Zisserman (2003, sec. 15.1.1,
``l_i = l'_j l''_k T_i^{jk}``, with the tensor of eq. (17.12) built from the
three projection matrices); :func:`trifocal_tensor` and
:func:`transfer_line_trifocal` give that form, and the tests check that both
agree. Our form also propagates the covariance of the two measured lines.

The left/right ski check built on it is in :mod:`photogram.lines.skis`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.lines.image_line import ImageLine, line_angle, normalize_line
from photogram.lines.plucker import project_line
from photogram.lines.space_line import LineIntersection, intersect_line

__all__ = ["TransferredLine", "LineComparison", "transfer_line", "trifocal_tensor",
           "transfer_line_trifocal", "compare_lines"]


@dataclass(eq=False)
class TransferredLine:
    """A line predicted in a view: homogeneous ideal line ``l`` (3,)
    (``l1^2 + l2^2 = 1``), its covariance (3, 3), and the 3D line it came
    from."""

    l: np.ndarray
    covariance: np.ndarray
    space_line: LineIntersection
    station: str = ""


@dataclass
class LineComparison:
    """A predicted line against a measured one.

    ``angle`` (radians) between them, ``distances`` (2,) of the measured
    segment's end points from the predicted line (image units), ``chi2`` of
    those distances with the propagated covariance of both lines (2 dof).
    """

    angle: float
    distances: np.ndarray
    chi2: float


# ---------------------------------------------------------------------------
# transfer


def transfer_line(line_a: ImageLine, cam_a, line_b: ImageLine, cam_b, cam_c, *,
                  label: str | None = None,
                  min_plane_angle_deg: float = 1.0) -> TransferredLine:
    """Transfer lines measured in views a and b into view c.

    The 3D line is the intersection of the two planes (eqs. (C13)-(C14)
    with two views), projected into c with
    :func:`~photogram.lines.plucker.project_line`; the covariance is
    propagated from the two image lines.

    Raises
    ------
    GeometryError
        If the planes of a and b (nearly) coincide: the line is parallel to
        the baseline a-b or in one of its epipolar planes.
    """
    names = [cam_a.name or "a", cam_b.name or "b"]
    if names[0] == names[1]:
        names = [names[0] + " (a)", names[1] + " (b)"]
    X = intersect_line(dict(zip(names, (line_a, line_b))), dict(zip(names, (cam_a, cam_b))),
                       label=label, min_plane_angle_deg=min_plane_angle_deg)
    l, G = project_line(X.line, cam_c, jacobian=True)
    return TransferredLine(l, G @ X.line.covariance @ G.T, X, cam_c.name)


def trifocal_tensor(cam1, cam2, cam3) -> np.ndarray:
    """Trifocal tensor (3, 3, 3) of three views in ideal coordinates,
    Hartley & Zisserman (2003) eq. (17.12):
    ``T_i^{qr} = (-1)^(i+1) det[~a^i; b^q; c^r]`` with ``~a^i`` the first
    projection matrix without row i, ``b^q``, ``c^r`` rows of the others."""
    A, B, C = cam1.matrix, cam2.matrix, cam3.matrix
    T = np.empty((3, 3, 3))
    for i in range(3):
        ai = np.delete(A, i, axis=0)
        for q in range(3):
            for r in range(3):
                T[i, q, r] = (-1) ** i * np.linalg.det(np.vstack([ai, B[q], C[r]]))
    return T


def transfer_line_trifocal(T, l2, l3) -> np.ndarray:
    """Line in view 1 from lines in views 2 and 3: ``l_i = l2_j l3_k T_i^{jk}``
    (H&Z eq. 15.1), normalised (sign arbitrary)."""
    return normalize_line(np.einsum("ijk,j,k->i", T, np.asarray(l2, float),
                                    np.asarray(l3, float)))


def compare_lines(l, measured: ImageLine, cov_l=None) -> LineComparison:
    """Compare a predicted line ``l`` (homogeneous, ideal) with a measured
    one: angle, distances of the measured end points from ``l`` and their
    chi-square (covariance of ``l`` plus that of the measured line)."""
    l = normalize_line(l)
    E = np.column_stack([measured.end_points, np.ones(2)])
    d = E @ l
    C = E @ measured.cov_homogeneous @ E.T
    if cov_l is not None:
        C = C + E @ cov_l @ E.T
    chi2 = float(d @ np.linalg.solve(C, d))
    return LineComparison(line_angle(l, measured.homogeneous), d, chi2)
