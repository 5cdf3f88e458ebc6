"""The AICON 3D Studio / Australis-type camera model in forward form.

The distortion is *added* to the projected (ideal) image coordinates
(docs/camera-models.md, section 5.3):

1. ideal image coordinates relative to the principal point, in the y-up
   frame of the image plane (Luhmann et al., Close-Range Photogrammetry
   and 3D Imaging, section 3.3: x' right, y' up)::

       u = xs = -c Xc_x / Xc_z,    v = ys_up = -c Xc_y / Xc_z

   (photogram's y-down ideal coordinate is ``-v``, ski-jump paper,
   appendix A, eq. (A1));
2. radial distortion balanced at the radius r0 (Luhmann et al., the
   balanced form of the radial distortion ``dr = A1 r (r^2 - r0^2) +
   A2 r (r^4 - r0^4) + A3 r (r^6 - r0^6)``), with ``r^2 = u^2 + v^2`` and
   ``g = dr / r``::

       g = A1 (r^2 - r0^2) + A2 (r^4 - r0^4) + A3 (r^6 - r0^6)

3. the corrections (radial, decentring B1 B2 as Brown (1971), affinity
   and shear C1 C2, which act on x only)::

       du = u g + B1 (r^2 + 2 u^2) + 2 B2 u v + C1 u + C2 v
       dv = v g + B2 (r^2 + 2 v^2) + 2 B1 u v

4. measured coordinates in photogram's image frame (y down)::

       x = xh + u + du,    y = yh - (v + dv)

``r0`` is the balancing radius, a constant of the camera (not estimated:
the project reader refuses ``free = true`` for it); ``r0 = 0`` is the
unbalanced polynomial. All lengths in the project's image unit (mm or
px). The residual is ``r = xy_obs - project(...)``.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry.camera import newton_invert, register_model
from photogram.geometry.forward_model import ForwardModel

__all__ = ["AiconModel"]


@register_model
class AiconModel(ForwardModel):
    """Forward AICON / Australis-type model with balanced radial distortion.

    ``parameter_names = ("c", "xh", "yh", "A1", "A2", "A3", "B1", "B2",
    "C1", "C2", "r0")``; xh, yh is the principal point in photogram's image
    frame (from the top-left corner, y down), r0 the balancing radius.
    """

    name = "aicon"
    parameter_names = ("c", "xh", "yh", "A1", "A2", "A3", "B1", "B2", "C1", "C2", "r0")
    parameter_dims = (1, 1, 1, -2, -4, -6, -1, -1, 0, 0, 1)
    #: constants of the camera, never estimated (the project reader refuses
    #: them free)
    constant_parameters = ("r0",)

    def default_parameters(self, principal_distance, image_size):
        """c = principal_distance, principal point at the format centre,
        no distortion, r0 = 0 (unbalanced)."""
        w, h = image_size
        p = np.zeros(self.n_params)
        p[:3] = principal_distance, w / 2.0, h / 2.0
        return p

    # ------------------------------------------------------------------
    def distortion(self, xs, ys, io):
        """Distortion ``d = (x - xh, y - yh) - (xs, ys)`` of ideal image
        coordinates (xs, ys) relative to the principal point, **y down**
        (steps 2-4).

        Returns
        -------
        d : (n, 2)
        partials : dict
            ``"xy"`` dd/d(xs, ys) (n,2,2); ``"io"`` dd/d io (n,2,p) (zero
            for c, xh, yh, which do not enter).
        """
        xs = np.atleast_1d(np.asarray(xs, dtype=float))
        ys = np.atleast_1d(np.asarray(ys, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(xs), self.n_params))
        n = len(xs)
        A1, A2, A3, B1, B2, C1, C2, r0 = (io[:, i] for i in range(3, 11))
        u, v = xs, -ys
        r2, R2 = u * u + v * v, r0 * r0
        g = A1 * (r2 - R2) + A2 * (r2 * r2 - R2 * R2) + A3 * (r2 ** 3 - R2 ** 3)
        gp = A1 + r2 * (2.0 * A2 + 3.0 * r2 * A3)                  # dg/d(r2)
        du = u * g + B1 * (r2 + 2 * u * u) + 2 * B2 * u * v + C1 * u + C2 * v
        dv = v * g + B2 * (r2 + 2 * v * v) + 2 * B1 * u * v
        # d(du, dv)/d(u, v)
        a = g + 2 * u * u * gp + 6 * B1 * u + 2 * B2 * v + C1
        b = 2 * u * v * gp + 2 * B1 * v + 2 * B2 * u + C2
        e = 2 * u * v * gp + 2 * B2 * u + 2 * B1 * v
        f = g + 2 * v * v * gp + 6 * B2 * v + 2 * B1 * u
        # d(du, -dv)/d(xs, ys) = [[a, b], [-e, -f]] diag(1, -1)
        dxy = np.empty((n, 2, 2))
        dxy[:, 0, 0], dxy[:, 0, 1] = a, -b
        dxy[:, 1, 0], dxy[:, 1, 1] = -e, f
        dio = np.zeros((n, 2, self.n_params))
        for col, s in ((3, r2 - R2), (4, r2 * r2 - R2 * R2), (5, r2 ** 3 - R2 ** 3)):
            dio[:, 0, col], dio[:, 1, col] = u * s, -v * s
        dio[:, 0, 6], dio[:, 1, 6] = r2 + 2 * u * u, -2 * u * v
        dio[:, 0, 7], dio[:, 1, 7] = 2 * u * v, -(r2 + 2 * v * v)
        dio[:, 0, 8] = u
        dio[:, 0, 9] = v
        g_r0 = -2.0 * r0 * (A1 + R2 * (2.0 * A2 + 3.0 * R2 * A3))   # dg/d r0
        dio[:, 0, 10], dio[:, 1, 10] = u * g_r0, -v * g_r0
        return np.stack([du, -dv], -1), {"xy": dxy, "io": dio}

    def _forward(self, t, io):
        """Image coordinates of normalised coordinates t (ideal projection
        with c = 1, y down) with d/dt (n,2,2) and d/d io (n,2,p)."""
        c = io[:, 0:1]
        xs = c * t
        d, part = self.distortion(xs[:, 0], xs[:, 1], io)
        xy = io[:, 1:3] + xs + d
        M = part["xy"] + np.eye(2)                     # d xy / d xs
        dio = part["io"]
        dio[:, :, 0] = np.einsum("nij,nj->ni", M, t)   # d xs / d c = t
        dio[:, 0, 1] = 1.0
        dio[:, 1, 2] = 1.0
        return xy, M * c[:, :, None], dio

    def image_to_ray(self, xy, io):
        """Normalised coordinates of image points (Newton's method on
        ``_forward``, converged to 1e-12 relative)."""
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        io = np.broadcast_to(np.asarray(io, dtype=float), (len(xy), self.n_params))
        start = (xy - io[:, 1:3]) / io[:, 0:1]

        def fun(t):
            value, dt, _ = self._forward(t, io)
            return value, dt

        return newton_invert(fun, xy, start, np.maximum(1.0, np.abs(start).max(axis=1)))
