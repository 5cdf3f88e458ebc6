"""The one-step 3D line (ski-jump paper, appendix C.2, eq. (C15)).

One equation per measured (corrected) image point: its orthogonal distance
from the projected 3D line ``l_j(L)`` (:func:`~photogram.lines.plucker.project_line`)

    e_i = l_j(L) . (x̄_i, ȳ_i, 1),    weight sigma_i^-2                  (C15)

(equivalently: the ray of the point and the 3D line are coplanar), solved by
Gauss-Newton on the same 4 parameters, started from step B. To first order
both estimators are the same (the fitted line is a sufficient statistic of
its points), which the tests confirm.
"""

from __future__ import annotations

import numpy as np

from photogram.lines.plucker import SpaceLine, project_line_batch
from photogram.lines.space_line import (LineIntersection, _check_count, _recentre, _scale,
                                        _sigma_of, _solve, _Views, intersect_line)
from photogram.lines.views import fit_view_line

__all__ = ["intersect_line_one_step"]


def intersect_line_one_step(points_by_view, cameras, sigma=1.0, *, label: str | None = None,
                            initial: SpaceLine | LineIntersection | None = None,
                            min_plane_angle_deg: float = 1.0, max_iterations: int = 50,
                            tol: float = 1e-10) -> LineIntersection:
    """3D line directly from the measured points, eq. (C15).

    One equation per point: its orthogonal distance (ideal image
    coordinates) from the projected 3D line, weighted with the point's
    a-priori sigma across the line (propagated through the distortion
    correction). Gauss-Newton on the 4 line parameters from ``initial``
    (default: step A + B, :func:`intersect_line`; pass that function's
    result to reuse its fitted image lines and checks).

    Parameters
    ----------
    points_by_view : dict {station: array (n_j, 2)}
        Measured image coordinates of points along the line.
    cameras : dict {station: ViewCamera}
    sigma : float, array or dict {station: float or array}
        A-priori sigma of the measured coordinates (image units).
    label, initial, min_plane_angle_deg, max_iterations, tol :
        As :func:`intersect_line`.

    Returns
    -------
    LineIntersection
        ``residuals[station]`` are the distances of all points (n_j,).
    """
    _check_count(points_by_view, label)
    names = list(points_by_view)
    if isinstance(initial, LineIntersection) and initial.image_lines:
        step_b = initial                 # reuse its fitted lines and checks
        lines = initial.image_lines
        names = [n for n in names if n in lines]
    else:
        lines = {n: fit_view_line(points_by_view[n], cameras[n],
                                  _sigma_of(sigma, n, len(points_by_view[n])), label=label)
                 for n in names}
        step_b = intersect_line(lines, cameras, label=label,
                                min_plane_angle_deg=min_plane_angle_deg)
    if initial is None or isinstance(initial, LineIntersection):
        L = step_b.line
    else:
        L = initial
    L = SpaceLine(L.point, L.direction, label=label)
    cams = [cameras[n] for n in names]
    views = _Views(names, [lines[n] for n in names], cams)
    xi, Jc, sig, vi = [], [], [], []
    for j, (n, cam) in enumerate(zip(names, cams)):
        xy = np.asarray(points_by_view[n], dtype=float)
        x, J = cam.ideal(xy, jacobians=True)
        xi.append(x)
        Jc.append(J)
        sig.append(_sigma_of(sigma, n, len(xy)))
        vi.append(np.full(len(xy), j))
    Xt = np.column_stack([np.vstack(xi), np.ones(sum(len(x) for x in xi))])
    Jc, sig, vi = np.concatenate(Jc), np.concatenate(sig), np.concatenate(vi)
    splits = np.cumsum([len(x) for x in xi])[:-1]

    def system(L):
        l, G = project_line_batch(L, views.R, views.X0, views.c, names=names)
        e = (Xt * l[vi]).sum(1)                                          # (C15)
        A = np.einsum("mi,miq->mq", Xt, G[vi])
        sn = sig * np.linalg.norm(np.einsum("mji,mj->mi", Jc, l[vi, :2]), axis=1)
        w = 1.0 / sn ** 2
        return A.T @ (w[:, None] * A), A.T @ (w * e), float(w @ (e * e)), e

    what = f"line {label}" if label else "line"
    scale = _scale(L, cams)
    converged, it = False, 0
    for it in range(1, max_iterations + 1):
        N, g, _, _ = system(L)
        step = -_solve(N, g, what)
        L = L.update(step)
        if np.abs(step[:2]).max() <= tol and np.abs(step[2:]).max() <= tol * scale:
            converged = True
            break
    L = _recentre(L, views.extent(L))
    N, _, chi2, e = system(L)
    L.covariance = np.linalg.inv(N)
    r = len(Xt) - 4
    return LineIntersection(
        line=L, label=label, stations=names, method="one-step", chi2=chi2, redundancy=r,
        sigma0=float(np.sqrt(chi2 / r)) if r > 0 else float("nan"),
        residuals=dict(zip(names, np.split(e, splits))),
        plane_angles=step_b.plane_angles, best_pair=step_b.best_pair,
        extent=views.extent(L), iterations=it, converged=converged, image_lines=lines)
