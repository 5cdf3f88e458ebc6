"""Propagation of the orientation's uncertainty into intersected points
(and the directions of intersected lines, :func:`line_direction_sensitivity`).

A point intersected with fixed orientation theta (interior and exterior
parameters) is ``X(theta) = argmin sum |r(X, theta)|^2``. Its sensitivity is
``dX/dtheta = -A^-1 J_X^T W J_theta`` with ``A = J_X^T W J_X`` (the implicit
function theorem on the normal equations), so the orientation contributes

    Sigma_X += (dX/dtheta) Sigma_theta (dX/dtheta)^T

to the covariance from the image noise (ski-jump paper, section 4, step 3:
"with the covariance of the orientation"). Computed for all points at once;
the result is the joint covariance of all points, because points of different
exposures share the same orientation errors.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry import matrix_to_opk

STATION_PARAMETERS = ("X0", "Y0", "Z0", "omega", "phi", "kappa")


def orientation_sensitivity(problem, project, camera_names, labels):
    """``dX/dtheta`` (3 n_points, n_theta) for the points of ``problem``.

    Parameters
    ----------
    problem : Problem
        Points free, orientation fixed, at its solution.
    project : Project
        For station and camera names.
    camera_names : list of str
        Cameras in the order of ``problem.state.io``.
    labels : list of str
        Parameter labels of the orientation covariance
        (``"K1.c"``, ``"S1.X0"``, ``"S1.omega"``, ...; see covariance.npz).
    """
    index = {lab: i for i, lab in enumerate(labels)}
    n_theta = len(labels)
    n_p = len(problem.state.points)
    sens = np.zeros((n_p, 3, n_theta))
    A = np.zeros((n_p, 3, 3))
    st_names = project.stations.names
    for k, blk in enumerate(problem.blocks):
        if blk.name != "image points":
            continue
        w = problem.weights(k)                                   # (N, 2)
        io = np.stack([problem.state.io[c] for c in blk.cameras])[blk.camera]
        R = problem.state.R[blk.station]
        _, jac = blk.model.residuals(blk.xy, problem.state.points[blk.point], matrix_to_opk(R),
                                     problem.state.X0[blk.station], io)
        JX = jac["X"] * w[:, :, None]
        A += _sum_by(blk.point, np.matmul(np.swapaxes(JX, 1, 2), JX), n_p)
        cam_name = [camera_names[c] for c in blk.cameras]
        params = list(project.cameras[cam_name[0]].parameters)
        cols_io = np.array([[index.get(f"{cam_name[c]}.{p}", -1) for p in params]
                            for c in range(len(cam_name))])[blk.camera]
        cols_st = np.array([[index.get(f"{s}.{p}", -1) for p in STATION_PARAMETERS]
                            for s in st_names])[blk.station]
        J_theta = np.concatenate([jac["io"], jac["X0"], jac["angles"]], axis=2) * w[:, :, None]
        cols = np.concatenate([cols_io, cols_st], axis=1)
        prod = np.matmul(np.swapaxes(JX, 1, 2), J_theta)          # (N, 3, q)
        ok = cols >= 0
        rows = np.repeat(blk.point, cols.shape[1]).reshape(cols.shape)
        for a in range(3):
            np.add.at(sens[:, a, :], (rows[ok], cols[ok]), prod[:, a, :][ok])
    Ainv = np.linalg.inv(A)
    return -np.matmul(Ainv, sens).reshape(3 * n_p, n_theta)


def line_direction_sensitivity(problem, project, camera_names, labels, lines,
                               half_length: float = 1.0):
    """``dd/dtheta`` (n_lines, 3, n_theta) of 3D lines intersected from image
    lines (points measured along them) with the orientation fixed: how the
    unit direction ``d`` of each line moves with the orientation while the
    measured image lines stay.

    Each line is represented by two of its points ``X_+- = c +- h d``; a
    point on the line projects onto every view's image line, one condition
    ``n_v^T r_v(X, theta) = 0`` per view (``n_v`` the normal of the
    projected line in the image, ``r_v`` the image-point model of the
    problem). By the implicit function theorem on the weighted normal
    equations, as for the points (module doc),
    ``dX/dtheta = -A^+ sum_v w_v a_v (n_v^T J_theta,v)``,
    ``a_v = J_X,v^T n_v``, ``A = sum_v w_v a_v a_v^T`` (rank 2: the
    pseudo-inverse leaves the position along the line, which the image
    lines do not fix), and ``dd/dtheta = (I - d d^T)(dX_+ - dX_-) / 2h``.
    With two views this is exact (two planes meet in the line); with more,
    the views are weighted by ``w_v`` (e.g. the number of points over their
    variance) where the line intersection weights them by each image line's
    full covariance: a close approximation.

    Parameters
    ----------
    problem : Problem
        The intersection problem (the stations and cameras at the
        orientation used; its image-point block gives the model).
    project : Project
        For station and camera names.
    camera_names : list of str
        Cameras in the order of ``problem.state.io``.
    labels : list of str
        Parameter labels of the orientation covariance.
    lines : sequence of (stations, c, d, w)
        Per line the station indices of its views, a point ``c`` (3,) and
        unit direction ``d`` (3,) of the intersected line, and the views'
        weights ``w``.
    half_length : float
        ``h`` (object units; the result does not depend on it).
    """
    index = {lab: i for i, lab in enumerate(labels)}
    n_theta = len(labels)
    out = np.zeros((len(lines), 3, n_theta))
    blocks = [b for b in problem.blocks if b.name == "image points"]
    if not blocks or not len(lines):
        return out
    st_names = project.stations.names
    # one virtual observation per line, view and end
    obs = [(i, k, int(s), w) for i, (sts, c, d, ws) in enumerate(lines)
           for s, w in zip(sts, ws) for k in (-1.0, 1.0)]
    if not obs:
        return out
    li, ends, st, wv = (np.array(v) for v in zip(*obs))
    c = np.array([lines[i][1] for i in li], float)
    d = np.array([lines[i][2] for i in li], float)
    X = c + (ends * half_length)[:, None] * d
    a = np.zeros((len(st), 3))
    b = np.zeros((len(st), n_theta))
    for blk in blocks:
        # the block's camera of each of its stations (a block per camera model)
        cam_of_station = {}
        for s_, k_ in zip(blk.station, blk.camera):
            cam_of_station.setdefault(int(s_), int(k_))
        sel = np.nonzero([int(s_) in cam_of_station for s_ in st])[0]
        if not len(sel):
            continue
        a[sel], b[sel] = _line_conditions(problem, project, camera_names, blk, index, n_theta,
                                          st_names, X[sel], st[sel], cam_of_station)
    dX = {}
    for key in set(zip(li.tolist(), ends.tolist())):
        m = (li == key[0]) & (ends == key[1])
        A = (wv[m, None, None] * a[m, :, None] * a[m, None, :]).sum(0)
        B = (wv[m, None, None] * a[m, :, None] * b[m, None, :]).sum(0)
        dX[key] = -np.linalg.pinv(A, rcond=1e-10) @ B
    for i, (_, _, d_i, _) in enumerate(lines):
        if (i, 1.0) not in dX:
            continue
        d_i = np.asarray(d_i, float)
        P = np.eye(3) - np.outer(d_i, d_i)
        out[i] = P @ (dX[(i, 1.0)] - dX[(i, -1.0)]) / (2 * half_length)
    return out


def _line_conditions(problem, project, camera_names, blk, index, n_theta, st_names, X, st,
                     cam_of_station):
    """Per virtual observation (pairs of a line's two ends in one view, in
    that order): ``a = J_X^T n`` (N, 3) and ``n^T J_theta`` (N, n_theta) in
    the orientation's columns, ``n`` the image normal of the projected line
    in the residual's frame (:func:`line_direction_sensitivity`)."""
    cam = np.array([cam_of_station[int(s_)] for s_ in st])
    io = np.stack([problem.state.io[blk.cameras[k]] for k in cam])
    angles, X0 = matrix_to_opk(problem.state.R[st]), problem.state.X0[st]
    # the residual is correct(xy) - ideal(X): its corrections and their
    # interior Jacobian are taken at the measured position of each point
    xy = blk.model.project(X, angles, X0, io)
    _, jac = blk.model.residuals(xy, X, angles, X0, io)
    # the image line in the residual's frame: correct(xy_-) - ideal(X_+) =
    # ideal(X_-) - ideal(X_+), the two ends' difference
    pair = np.arange(0, len(st), 2)
    u = -blk.model.residuals(xy[pair], X[pair + 1], angles[pair], X0[pair], io[pair],
                             jacobians=False)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    n = np.repeat(np.column_stack([-u[:, 1], u[:, 0]]), 2, axis=0)       # (N, 2)
    a = np.einsum("ni,nij->nj", n, jac["X"])                              # (N, 3)
    cam_name = [camera_names[k] for k in blk.cameras]
    params = list(project.cameras[cam_name[0]].parameters)
    cols_io = np.array([[index.get(f"{cam_name[k]}.{p}", -1) for p in params]
                        for k in range(len(cam_name))])[cam]
    cols_st = np.array([[index.get(f"{s}.{p}", -1) for p in STATION_PARAMETERS]
                        for s in st_names])[st]
    J_theta = np.concatenate([jac["io"], jac["X0"], jac["angles"]], axis=2)
    b_local = np.einsum("ni,nij->nj", n, J_theta)
    cols = np.concatenate([cols_io, cols_st], axis=1)
    b = np.zeros((len(st), n_theta))
    ok = cols >= 0
    rows = np.repeat(np.arange(len(st)), cols.shape[1]).reshape(cols.shape)
    np.add.at(b, (rows[ok], cols[ok]), b_local[ok])
    return a, b


def _sum_by(index, values, n):
    out = np.zeros((n,) + values.shape[1:])
    np.add.at(out, index, values)
    return out


def propagate_orientation(sensitivity, covariance):
    """Joint covariance (3 n_points, 3 n_points) that the orientation
    covariance adds to the points."""
    return sensitivity @ covariance @ sensitivity.T


def combine_covariance_blocks(labels, blocks):
    """One covariance over the union of several labelled covariance blocks
    (the folders of ``[intersect] orientation``: a lab's interior, a field's
    joint interior-exterior covariance).

    Parameters
    ----------
    labels : sequence of sequence of str
        The parameter labels of each block, in the order of its rows.
    blocks : sequence of ndarray
        The square covariance matrices.

    Returns
    -------
    (list of str, ndarray)
        The union of the labels (first appearance order) and the combined
        matrix; a later block overrides an earlier one where they share
        parameters, and parameters with zero variance (held fixed in that
        block) are not copied.
    """
    union = list(dict.fromkeys(x for lab in labels for x in lab))
    index = {x: i for i, x in enumerate(union)}
    total = np.zeros((len(union), len(union)))
    for lab, mat in zip(labels, blocks):
        mat = np.asarray(mat, dtype=float)
        ix = np.array([index[x] for x in lab], dtype=int)
        keep = np.diag(mat) > 0
        total[np.ix_(ix[keep], ix[keep])] = mat[np.ix_(keep, keep)]
    return union, total
