"""Propagation of the orientation's uncertainty into intersected points.

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
