"""Orientation pieces shared by a Monte-Carlo chain and its first-order
propagation: rows of the station outputs (X0 Y0 Z0 omega phi kappa) from
rows in the engine's station columns (dX0, delta), and an orientation with
one parameter moved (central differences through the intersect step)."""

from __future__ import annotations

import numpy as np

from photogram.geometry import angle_increment_map, small_rotation

__all__ = ["station_rows", "perturb_orientation"]


def station_rows(bundle, Phi, R):
    """Rows (6 S, M) of X0 and omega-phi-kappa from rows in (dX0, delta)."""
    _, E = angle_increment_map(R)
    rows = []
    for s in range(len(R)):
        cols = bundle.station_cols[s]
        rows.append(Phi[cols[:3]])
        rows.append(E[s] @ Phi[cols[3:]])
    return np.vstack(rows)


def perturb_orientation(io, R, X0, which, h, shape_io):
    """The orientation with parameter ``which`` moved by ``h``: an interior
    parameter (flat index) or ("station", s, q) in (dX0, delta)."""
    io, R, X0 = io.copy(), R.copy(), X0.copy()
    if isinstance(which, tuple):
        _, s, q = which
        if q < 3:
            X0[s, q] += h
        else:
            d = np.zeros(3)
            d[q - 3] = h
            R[s] = small_rotation(d) @ R[s]
    else:
        io.reshape(-1)[which] += h
    return io, R, X0
