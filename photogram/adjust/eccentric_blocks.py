"""Image points of circular targets measured as ellipse centres.

:class:`EccentricImagePointBlock` is the collinearity residual of
:class:`~photogram.adjust.residual_blocks.ImagePointBlock` with the object
point ``X`` replaced by ``X_e = X + delta(X, n, r, R, X0)``, the object
point whose projection is the centre of the imaged ellipse
(:mod:`photogram.geometry.circle`, eq. (1)). The measured ellipse centre is
compared with the predicted ellipse centre instead of the projection of
the circle's centre, so the eccentricity of the projected circle is
corrected inside the adjustment (Ahn et al. 1999; Luhmann et al. sec.
3.6.1.2).

The Jacobian is complete, nothing neglected: with ``J_X`` the model's
derivative by the object point and ``D_*`` those of ``X_e``,

* point:    ``J_X D_X``
* station:  ``[J_X0 + J_X D_X0, J_rot + J_X D_rot]``
* interior: the model's own (``delta`` does not depend on it).

The only approximation is the model's: with lens distortion the ellipse
centre is taken as the distorted image of the pinhole ellipse centre
(first order; the distortion is locally affine over one target).
"""

from __future__ import annotations

import numpy as np

from photogram.adjust.residual_blocks import ImagePointBlock
from photogram.geometry import matrix_to_opk
from photogram.geometry.circle import ellipse_centre_point

__all__ = ["EccentricImagePointBlock", "with_ellipse_centres"]


class EccentricImagePointBlock(ImagePointBlock):
    """Image points of circular targets of known radius and normal.

    Parameters
    ----------
    radius : (N,) circle radius per observation (object units)
    normal : (N, 3) target-plane normal per observation
    others : as :class:`ImagePointBlock`
    """

    eccentric = True          # same name as ImagePointBlock: snooping, robust, stats treat it alike

    def __init__(self, model, cameras, camera, station, point, xy, sigma, layout,
                 radius, normal, labels=None):
        super().__init__(model, cameras, camera, station, point, xy, sigma, layout, labels)
        self.radius = np.broadcast_to(np.asarray(radius, float), (len(self.point),)).copy()
        self.normal = np.broadcast_to(np.asarray(normal, float), (len(self.point), 3)).copy()

    def eccentricity(self, state) -> np.ndarray:
        """Predicted ellipse centre minus the projection of the circle's
        centre (N, 2), image unit, at ``state``."""
        io = np.stack([state.io[k] for k in self.cameras])[self.camera]
        R, X0 = state.R[self.station], state.X0[self.station]
        X = state.points[self.point]
        Xe = ellipse_centre_point(X, self.normal, self.radius, R, X0)
        ang = matrix_to_opk(R)
        return (self.model.project(Xe, ang, X0, io)
                - self.model.project(X, ang, X0, io))

    def evaluate(self, state, jacobians=True):
        io = np.stack([state.io[k] for k in self.cameras])[self.camera]
        R, X0 = state.R[self.station], state.X0[self.station]
        X = state.points[self.point]
        if not jacobians:
            Xe = ellipse_centre_point(X, self.normal, self.radius, R, X0)
            return self.model.residuals_rotation(self.xy, Xe, R, X0, io, jacobians=False), None
        Xe, D = ellipse_centre_point(X, self.normal, self.radius, R, X0, jacobians=True)
        e, jac = self.model.residuals_rotation(self.xy, Xe, R, X0, io)
        JX = jac["X"]
        station = np.concatenate([jac["X0"] + JX @ D["X0"],
                                  jac["rotation"] + JX @ D["rotation"]], axis=2)
        return e, [JX @ D["X"], station, jac["io"]]


def with_ellipse_centres(blocks, radius, normal, layout):
    """Replace every :class:`ImagePointBlock` of ``blocks`` that observes a
    circular target (finite ``radius[point] > 0``) by an
    :class:`EccentricImagePointBlock` with the same observations, order,
    group, labels and rows; the other points of the block get radius 0
    (``delta = 0``, the plain collinearity residual). ``radius`` (n_p,),
    ``normal`` (n_p, 3) per object point."""
    radius = np.asarray(radius, float)
    target = np.isfinite(radius) & (radius > 0)
    r = np.where(target, radius, 0.0)
    nv = np.where(target[:, None], np.asarray(normal, float), [0.0, 0.0, 1.0])
    out = []
    for blk in blocks:
        if type(blk) is not ImagePointBlock or not target[blk.point].any():
            out.append(blk)
            continue
        new = EccentricImagePointBlock(blk.model, blk.cameras, blk.camera, blk.station,
                                       blk.point, blk.xy, blk.sigma[:, 0], layout,
                                       r[blk.point], nv[blk.point], labels=blk.labels)
        new.group = blk.group
        if hasattr(blk, "rows"):
            new.rows = blk.rows
        out.append(new)
    return out
