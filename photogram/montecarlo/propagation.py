"""First-order propagation through a Monte-Carlo chain.

Every random input of a run is a standard normal number times a sigma (the
whitened residuals of the adjustment's observations, and ``z`` of the
interior draw ``io = io_true + L z``). Linearized at the truth, every output
is a linear function of these numbers, ``d out = Phi z``, and its sigma is
the norm of its row of ``Phi``:

* adjustment step: ``dtheta = -Q J^T (eps + Jio L z)`` (Q the cofactors of
  the unknowns, J the whitened Jacobian, Jio its derivative w.r.t. the fixed
  interior orientation);
* intersect step (points, lines, stick model) with the orientation fixed:
  ``d out = G dtheta_orientation + (image noise)`` with ``G`` by central
  differences through the intersect step, and the image part from the
  intersect's own cofactors (points: 3x3 per point, lines: 4x4 per line,
  the stick model by :func:`photogram.jump.propagate.propagate`).

``sigma_prop`` counts only the perturbed kinds and the correlations the chain
creates (the stations of ``orient`` move with the drawn interior
orientation). ``sigma_cmd``, what the commands report, is not modelled here:
the commands' own code computes it at the chain's setup
(:mod:`photogram.montecarlo.reported`).
"""

from __future__ import annotations

import numpy as np

from photogram.jump.definitions import PARAMETERS
from photogram.lines.batch import local_basis_batch
from photogram.montecarlo.orientation import perturb_orientation, station_rows

__all__ = ["propagate"]


def _s_transform(rows, X):
    """Remove a translation and a rotation about Z (least squares over the
    points X (n, 3)) from rows (3 n, M) of point coordinates."""
    n = len(X)
    c = X - X.mean(0)
    T = np.zeros((n, 3, 4))
    T[:, [0, 1, 2], [0, 1, 2]] = 1.0
    T[:, 0, 3], T[:, 1, 3] = -c[:, 1], c[:, 0]
    T = T.reshape(3 * n, 4)
    return rows - T @ np.linalg.solve(T.T @ T, T.T @ rows)


def _stage2_vector(chain, io, R, X0):
    li = chain.intersect
    out = li.solve(io, R, X0, li.inputs_points, li.inputs_lines, chain.X2,
                   (chain.LP2, chain.LD2))
    m = out.model
    v = np.concatenate([out.P.ravel(), np.stack([m.values[q] for q in PARAMETERS], 1).ravel()])
    return v


def _stage2(chain, Phi_theta, thetas):
    """Rows of the intersect outputs: orientation part (Phi) and the image
    variances."""
    b, li = chain.bundle, chain.intersect
    io, R, X0 = b.start.io, b.start.R, b.start.X0
    f0 = _stage2_vector(chain, io, R, X0)
    n2 = len(f0)
    n_angle = chain.outputs.angle[-n2:]
    G = np.zeros((n2, len(thetas)))
    for i, which in enumerate(thetas):
        s = np.linalg.norm(Phi_theta[i])
        if s == 0:
            continue
        h = 1e-3 * s
        fp = _stage2_vector(chain, *perturb_orientation(io, R, X0, which, h, chain.shape_io))
        fm = _stage2_vector(chain, *perturb_orientation(io, R, X0, which, -h, chain.shape_io))
        d = fp - fm
        d[n_angle] = np.angle(np.exp(1j * d[n_angle]))
        G[:, i] = d / (2 * h)
    orient = G @ Phi_theta
    # image noise of the intersect step (at the truth)
    X, covX = li.intersect_points(io, R, X0, li.inputs_points, chain.X2, covariance=True)
    LP, LD, covL, _ = li.intersect_lines(io, R, X0, li.inputs_lines, (chain.LP2, chain.LD2),
                                         covariance=True)
    E = chain.n_exposures
    u, v = local_basis_batch(LD)
    B = np.stack([u, v], -1)                                     # (L, 3, 2)
    cov_d = (B @ covL[:, :2, :2] @ np.swapaxes(B, 1, 2)).reshape(E, 2, 3, 3)
    cov_p = covX[li.jumper_index]                                # (E, 4, 3, 3)
    P = X[li.jumper_index]
    LPe, LDe = LP.reshape(E, 2, 3), LD.reshape(E, 2, 3)
    img_model = li.stick(P, LPe, LDe, cov_points=cov_p, cov_dirs=cov_d)
    var_img = np.concatenate([np.diagonal(cov_p, axis1=2, axis2=3).ravel(),
                              np.diagonal(img_model.cov, axis1=1, axis2=2).ravel()])
    return orient, var_img


def propagate(chain):
    """``(sigma_prop, sigma_cmd)`` for every output of the chain (internal
    units, in the order of ``chain.outputs``); ``sigma_cmd`` is
    :attr:`Chain.sigma_cmd`."""
    b = chain.bundle
    f = chain.perturb
    J, Q, Jio = b.linearize(b.start, b.inputs)
    A = -Q @ J.T                                         # (n, m) per whitened observation
    m = A.shape[1]
    L = chain.io_L
    Aio = -Q @ (J.T @ (Jio @ L)) if L.shape[1] else np.zeros((b.n, 0))
    use = np.isin(b.sources, list(f)).astype(float)
    Phi = np.hstack([A * use[None, :], Aio * ("interior" in f)])
    M = Phi.shape[1]
    K, p = chain.shape_io
    # interior orientation used by the run, all K p parameters
    io_rows = np.zeros((K * p, M))
    if chain.fix_interior:
        io_rows[:, m:] = L * ("interior" in f)
    else:
        free = b.io_free.ravel()
        io_rows[free] = Phi[b.io_cols[b.io_free]]
    rows = [station_rows(b, Phi, b.start.R), io_rows[chain.io_random]]
    if len(chain.collect):
        pr = Phi[b.point_cols[chain.collect].ravel()]
        if chain.settings.align == "plan":
            pr = _s_transform(pr, b.start.X[chain.collect])
        rows.append(pr)
    var = np.concatenate([np.sum(r * r, axis=1) for r in rows])
    if chain.intersect is not None:
        S = len(b.station_names)
        thetas = [int(i) for i in chain.io_random] + [("station", s, q)
                                                       for s in range(S) for q in range(6)]
        st_rows = Phi[b.station_cols.ravel()]
        Phi_theta = np.vstack([io_rows[chain.io_random], st_rows])
        orient, var_img = _stage2(chain, Phi_theta, thetas)
        var2 = np.sum(orient * orient, axis=1) + var_img * ("image" in f)
        var = np.concatenate([var, var2])
    return np.sqrt(var), np.asarray(chain.sigma_cmd, dtype=float)
