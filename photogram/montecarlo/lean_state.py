"""State, per-run observations and the small residual helpers of the lean
Monte-Carlo bundle adjustment (:mod:`photogram.montecarlo.bundle`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.geometry import matrix_to_opk
from photogram.geometry.camera import ideal_projection


@dataclass
class BundleState:
    """Values of all unknowns (and of the fixed interior orientation)."""

    io: np.ndarray        # (K, p)
    R: np.ndarray         # (S, 3, 3)
    X0: np.ndarray        # (S, 3)
    X: np.ndarray         # (P, 3)

    def copy(self) -> "BundleState":
        return BundleState(self.io.copy(), self.R.copy(), self.X0.copy(), self.X.copy())

    @property
    def angles(self) -> np.ndarray:
        return matrix_to_opk(self.R)


@dataclass
class BundleInputs:
    """The observations of one run (same shapes as in the project)."""

    xy: np.ndarray                 # (N, 2) image coordinates
    reference: np.ndarray          # (n_c, 3) reference coordinates of the control points
    station_prior: np.ndarray      # (S, 6) prior X0 Y0 Z0 omega phi kappa (radians)
    interior_prior: np.ndarray     # (n_ip,) prior values of weighted interior parameters
    distances: np.ndarray          # (n_d,)
    verticals: np.ndarray          # (n_v, 2) observed slopes (0 for a vertical rod)

    def copy(self) -> "BundleInputs":
        return BundleInputs(*(np.array(a, dtype=float, copy=True) for a in (
            self.xy, self.reference, self.station_prior, self.interior_prior,
            self.distances, self.verticals)))


def correct_brown(model, xy, io, jacobians=False):
    """Corrected coordinates ``C`` of measured ``xy`` (and ``dC/dio``)."""
    if jacobians:
        C, jac = model.correct(xy, io, jacobians=True)
        return C, jac["io"]
    return model.correct(xy, io)


def image_residuals(C, X, R, X0, c):
    """``C - ideal`` and the Jacobian of ``ideal`` w.r.t. Xc, with Xc."""
    Xc = np.einsum("nij,nj->ni", R, X - X0)
    ideal, J_xc, t = ideal_projection(Xc, c, jacobians=True)
    return C - ideal, J_xc, Xc, t
