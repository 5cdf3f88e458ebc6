"""The covariance of an orientation computed with a calibrated camera.

``photogram orient`` holds the interior orientation fixed at the lab values,
but those values carry the lab's covariance. The stations then absorb part
of an interior error (a wrong c moves a station along its line of sight), so
the honest covariance of the orientation is that of the adjustment in which
the interior parameters are observed with their lab covariance (a weighted
prior with the full matrix, correlations included), evaluated at the
fixed-interior solution: to first order it equals
``Sigma_x + D Sigma_io D^T`` with the sensitivity ``D = dx/dio`` of the
fixed-interior estimate, and it carries the interior-exterior
cross-covariances that make later errors cancel (an interior error and the
station shift it causes largely cancel in an intersected point).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.stats.covariance import cofactors


def calibration_covariance(project):
    """The covariance of the interior orientation of the project's cameras
    from the covariance.npz beside the cameras file they were taken from
    (``from = ".../results/cameras.toml"``), or None.

    Returns ``(labels, matrix, folder)`` restricted to parameters with a
    non-zero variance.
    """
    from photogram.project.results_read import read_orientation_covariance
    folders = {c.source for c in project.cameras.values() if c.source}
    if len(folders) != 1:
        return None
    cams_file = Path(next(iter(folders)))
    if not cams_file.is_absolute():
        cams_file = project.folder / cams_file
    folder = cams_file.parent
    if not (folder / "covariance.npz").is_file():
        return None
    labels, matrix = read_orientation_covariance(folder)
    wanted = {f"{n}.{p}" for n, c in project.cameras.items() for p in c.parameters}
    keep = [i for i, lab in enumerate(labels) if lab in wanted and matrix[i, i] > 0]
    if not keep:
        return None
    return [labels[i] for i in keep], matrix[np.ix_(keep, keep)], folder


def interior_sensitivity(problem, camera_names, project, labels):
    """``D = dx_station / d io`` (6 n_stations, len(labels)) of the
    estimate with the interior orientation held fixed:
    ``D = -Q_(st, x) J_x^T W J_io`` over all unknowns x (stations and
    points), from the cofactors of the fixed-interior problem."""
    cof = cofactors(problem)
    lay = problem.layout
    n_s, n_p = len(problem.state.X0), len(problem.state.points)
    col_of = {lab: i for i, lab in enumerate(labels)}
    n_io = len(labels)
    N_st = np.zeros((n_s, 6, n_io))
    N_pt = np.zeros((n_p, 3, n_io))
    _, Js = problem.evaluate(problem.state)          # whitened, masked by the free flags
    for k, blk in enumerate(problem.blocks):
        if blk.name != "image points":
            continue
        e, raw = blk.evaluate(problem.state)         # unmasked: the fixed interior too
        w = problem.weights(k)[:, :, None]
        J_io = raw[2] * w
        cam = camera_names[blk.cameras[0]]
        params = list(project.cameras[cam].parameters)
        cols = np.array([col_of.get(f"{cam}.{p}", -1) for p in params])
        ok = cols >= 0
        if not ok.any():
            continue
        J_io = J_io[:, :, ok]
        prod_pt = np.matmul(np.swapaxes(Js[k][0], 1, 2), J_io)      # (N, 3, q)
        prod_st = np.matmul(np.swapaxes(Js[k][1], 1, 2), J_io)      # (N, 6, q)
        add_pt = np.zeros((n_p, 3, ok.sum()))
        add_st = np.zeros((n_s, 6, ok.sum()))
        np.add.at(add_pt, blk.point, prod_pt)
        np.add.at(add_st, blk.station, prod_st)
        N_pt[:, :, cols[ok]] += add_pt
        N_st[:, :, cols[ok]] += add_st
    # D = -(Q N)[stations], N the stacked N_st and N_pt: the station block of
    # Q_cc times N_st plus the cross cofactors times N_pt (point by point)
    st_cols = lay.station_cols.ravel()                                # (6 n_s,)
    D = -(cof.Qcc[np.ix_(st_cols, st_cols)] @ N_st.reshape(6 * n_s, n_io))
    elim = ~lay.reduced_points
    if elim.all():
        D -= cof.ce_times(N_pt)[st_cols]
    else:                     # coupled points are reduced unknowns: Q_cc
        pc = lay.point_cols[~elim].ravel()
        D -= cof.Qcc[np.ix_(st_cols, pc)] @ N_pt[~elim].reshape(-1, n_io)
        if elim.any():
            D -= cof.ce_times(N_pt[elim])[st_cols]
    return D, cof


def station_rotation_to_angles(problem):
    """Block-diagonal (6 n_s, 6 n_s) map from (dX0, delta) to (dX0, d opk)."""
    from photogram.geometry import angle_increment_map
    _, E = angle_increment_map(problem.state.R)
    n_s = len(E)
    T = np.zeros((6 * n_s, 6 * n_s))
    for s in range(n_s):
        T[6 * s:6 * s + 3, 6 * s:6 * s + 3] = np.eye(3)
        T[6 * s + 3:6 * s + 6, 6 * s + 3:6 * s + 6] = E[s]
    return T
