"""The part of the camera models shared by all of them, and the registry.

Conventions (docs/camera-models.md):

* Camera frame: photogrammetric, x right, y up, the camera looks along -z;
  ``Xc = R (X - X0)`` with R the world-to-camera matrix of omega-phi-kappa.
* Image coordinates: x right, y **down** (pixel column/row, or mm from the
  top-left corner). The collinearity equations (ski-jump paper, appendix A,
  eq. (A1), written for a y-down image)::

      xbar = x - x0 = -c Xc_x / Xc_z
      ybar = y - y0 = +c Xc_y / Xc_z

  i.e. the image frame is the camera frame turned 180 deg about x. The
  OpenCV camera frame is ``diag(1,-1,-1) Xc``: ``R_cv = diag(1,-1,-1) R``,
  ``t_cv = -R_cv X0``.

A camera model is an object with ``name``, ``parameter_names``,
``parameter_dims`` (power of the image length unit of every parameter, used
by :func:`rescale_parameters`), ``default_parameters``, ``project`` and
``residuals``. Every function works on n observations at once; ``io`` is the
(n, p) array of interior parameters of each observation (a single (p,) row is
broadcast), ``angles`` and ``X0`` are (n, 3) (or (3,)), ``X`` is (n, 3).

Jacobian dictionaries have the keys ``"io"`` (n, 2, p), ``"angles"``,
``"X0"``, ``"X"`` and ``"rotation"`` (all (n, 2, 3)); ``"rotation"`` is with
respect to an incremental rotation ``delta`` with
``R = small_rotation(delta) @ R0`` at ``delta = 0``.
"""

from __future__ import annotations

import numpy as np

from photogram.errors import GeometryError, InputError
from photogram.geometry.rotations import matrix_to_opk, opk_derivatives, opk_to_matrix

FLIP_YZ = np.diag([1.0, -1.0, -1.0])

CAMERA_MODELS: dict[str, "CameraModel"] = {}


# --------------------------------------------------------------------------
# registry
# --------------------------------------------------------------------------
def register_model(cls):
    """Class decorator: instantiate ``cls`` and add it to CAMERA_MODELS."""
    CAMERA_MODELS[cls.name] = cls()
    return cls


def camera_model(name: str) -> "CameraModel":
    """The camera model called ``name``.

    Raises
    ------
    InputError
        For an unknown name; the message lists the known models.
    """
    try:
        return CAMERA_MODELS[name]
    except (KeyError, TypeError):
        raise InputError(f"unknown camera model {name!r}",
                         hint="known models: " + ", ".join(sorted(CAMERA_MODELS))) from None


def rescale_parameters(model, params, factor: float) -> np.ndarray:
    """Change the image length unit of a parameter array.

    Every parameter is multiplied by ``factor ** dim`` with ``dim`` from
    ``model.parameter_dims``. ``factor`` is new units per old unit: from mm
    to px it is ``1 / pixel_size`` (e.g. DBAT's mm values to px:
    ``rescale_parameters("brown", p_mm, 1 / 0.0031911)``).
    """
    model = camera_model(model) if isinstance(model, str) else model
    dims = np.asarray(model.parameter_dims, dtype=float)
    return np.asarray(params, dtype=float) * float(factor) ** dims


# --------------------------------------------------------------------------
# shared geometry
# --------------------------------------------------------------------------
def broadcast_observations(X, angles, X0, io, n_params):
    """Broadcast inputs to n observations: X (n,3), angles (n,3), X0 (n,3),
    io (n,p). Raises InputError on inconsistent shapes."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    n = X.shape[0]
    try:
        angles = np.broadcast_to(np.asarray(angles, dtype=float), (n, 3))
        X0 = np.broadcast_to(np.asarray(X0, dtype=float), (n, 3))
        io = np.broadcast_to(np.asarray(io, dtype=float), (n, n_params))
    except ValueError:
        raise InputError("observation arrays have inconsistent shapes",
                         hint=f"X is {X.shape}; angles and X0 must be (n,3) or (3,), "
                              f"io (n,{n_params}) or ({n_params},)") from None
    if X.shape != (n, 3):
        raise InputError(f"object points must be (n,3), got {X.shape}")
    return X, angles, X0, io


def camera_frame(X, angles, X0):
    """Camera coordinates ``Xc = R (X - X0)`` (collinearity, ski-jump paper
    appendix A) with ``R = opk_to_matrix(angles)``.

    Returns
    -------
    Xc : (n, 3)
    R : (n, 3, 3)
    d : (n, 3), ``X - X0``
    """
    R = opk_to_matrix(angles)
    d = X - X0
    return np.einsum("nij,nj->ni", R, d), R, d


def ideal_projection(Xc, c, jacobians=False):
    """Pinhole projection relative to the principal point, y down.

    ``xbar = -c Xc_x / Xc_z``, ``ybar = c Xc_y / Xc_z`` (ski-jump paper,
    appendix A, eq. (A1) adapted to a y-down image).

    Parameters
    ----------
    Xc : (n, 3) camera coordinates.
    c : (n,) or scalar principal distance.
    jacobians : bool
        Also return the partials.

    Returns
    -------
    xy : (n, 2)
    J_xc : (n, 2, 3), only with ``jacobians=True``
        ``d xy / d Xc = [[-c/Z, 0, c X/Z^2], [0, c/Z, -c Y/Z^2]]``.
    J_c : (n, 2), only with ``jacobians=True``
        ``d xy / d c = xy / c`` (the projection with c = 1).
    """
    Xc = np.asarray(Xc, dtype=float)
    c = np.broadcast_to(np.asarray(c, dtype=float), Xc.shape[:1])
    iz = 1.0 / Xc[:, 2]
    t = np.stack([-Xc[:, 0] * iz, Xc[:, 1] * iz], -1)     # c = 1 projection
    xy = c[:, None] * t
    if not jacobians:
        return xy
    J = np.zeros(Xc.shape[:1] + (2, 3))
    J[:, 0, 0] = -c * iz
    J[:, 0, 2] = c * Xc[:, 0] * iz * iz
    J[:, 1, 1] = c * iz
    J[:, 1, 2] = -c * Xc[:, 1] * iz * iz
    return xy, J, t


def pose_jacobians(J_xc, R, d, angles, Xc, stations=True):
    """Chain ``d out / d Xc`` (n, 2, 3) to the exterior parameters.

    ``dXc/dX = R``, ``dXc/dX0 = -R``, ``dXc/d angle_k = dR/d angle_k (X-X0)``
    and, for ``R = expm([delta]x) R0`` at 0, ``dXc/d delta = -[Xc]x``.
    With ``angles=None`` the omega-phi-kappa partials are not computed (the
    rotation-matrix path of the engine, which only needs ``"rotation"``);
    with ``stations=False`` only ``"X"`` (the others None).
    """
    JX = J_xc @ R
    if not stations:          # the caller holds the stations fixed: X only
        return {"X": JX, "X0": None, "rotation": None}
    # -J [Xc]x: row i is Xc x J_i (written out: np.cross is slow on small
    # arrays, same products and differences)
    a, b = Xc[:, None, :], J_xc
    rot = np.empty(np.broadcast_shapes(a.shape, b.shape))
    rot[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    rot[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    rot[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    out = {"X": JX, "X0": -JX, "rotation": rot}
    if angles is not None:
        dRd = np.einsum("nijk,nj->nik", opk_derivatives(angles), d)
        out["angles"] = J_xc @ dRd
    return out


def rotation_observations(X, R, X0, io, n_params):
    """Broadcast the inputs of the rotation-matrix path: X (n,3), R
    (n,3,3), X0 (n,3), io (n,p); returns them with ``Xc = R (X - X0)`` and
    ``d = X - X0``."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    n = X.shape[0]
    try:
        R, X0, io = (a if a.shape == shape else np.broadcast_to(a, shape)
                     for a, shape in ((np.asarray(R, dtype=float), (n, 3, 3)),
                                      (np.asarray(X0, dtype=float), (n, 3)),
                                      (np.asarray(io, dtype=float), (n, n_params))))
    except ValueError:
        raise InputError("observation arrays have inconsistent shapes",
                         hint=f"X is {X.shape}; R must be (n,3,3) or (3,3), X0 (n,3) "
                              f"or (3,), io (n,{n_params}) or ({n_params},)") from None
    d = X - X0
    Xc = np.einsum("nij,nj->ni", R, d)
    return X, R, X0, io, Xc, d


def solve2(A, b):
    """Solve the 2x2 systems ``A x = b`` for (n,2,2) A and (n,2,...) b by
    Cramer's rule (vectorised, no per-observation loop)."""
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    inv = np.stack([np.stack([A[:, 1, 1], -A[:, 0, 1]], -1),
                    np.stack([-A[:, 1, 0], A[:, 0, 0]], -1)], -2) / det[:, None, None]
    return np.einsum("nij,nj...->ni...", inv, b)


def newton_invert(fun, target, start, scale, tol=1e-12, max_iter=50):
    """Solve ``fun(z) = target`` for z (n,2) by Newton's method.

    ``fun(z)`` returns ``(value (n,2), jacobian (n,2,2))``. Iterates until
    every step is below ``tol * scale`` (relative; Newton's quadratic
    convergence leaves an error of order the square of the last step, i.e.
    at rounding level), then takes one more step.

    Raises
    ------
    GeometryError
        If some points do not converge (the distortion is not invertible
        there, typically far outside the image format).
    """
    z = np.array(start, dtype=float)
    scale = np.broadcast_to(np.asarray(scale, dtype=float), z.shape[:1])
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for _ in range(max_iter):
            value, jac = fun(z)
            step = solve2(jac, target - value)
            z = z + step
            done = np.all(np.abs(step) <= tol * scale[:, None], axis=1)
            if np.all(done):
                value, jac = fun(z)
                return z + solve2(jac, target - value)
    bad = int(np.count_nonzero(~done | ~np.isfinite(z).all(axis=1)))
    raise GeometryError(f"distortion inversion did not converge for {bad} of "
                        f"{len(z)} points",
                        hint="the points are probably far outside the image format, "
                             "where the distortion polynomial is not invertible")


def opencv_pose(R, X0):
    """OpenCV extrinsics from ours: ``R_cv = diag(1,-1,-1) R``,
    ``t_cv = -R_cv X0`` (shapes (...,3,3), (...,3))."""
    R_cv = FLIP_YZ @ np.asarray(R, dtype=float)
    return R_cv, -np.einsum("...ij,...j->...i", R_cv, np.asarray(X0, dtype=float))


def photogrammetric_pose(R_cv, t_cv):
    """Inverse of :func:`opencv_pose`: ``R = diag(1,-1,-1) R_cv``,
    ``X0 = -R_cv^T t_cv``."""
    R_cv = np.asarray(R_cv, dtype=float)
    X0 = -np.einsum("...ji,...j->...i", R_cv, np.asarray(t_cv, dtype=float))
    return FLIP_YZ @ R_cv, X0


# --------------------------------------------------------------------------
# base class
# --------------------------------------------------------------------------
class CameraModel:
    """Interface of a camera model (see the module docstring).

    Subclasses set ``name``, ``parameter_names``, ``parameter_dims`` and
    implement ``default_parameters``, ``project``, ``residuals``,
    ``distortion``, ``image_to_ray`` and ``ray_to_image``.
    """

    name: str = ""
    parameter_names: tuple[str, ...] = ()
    parameter_dims: tuple[int, ...] = ()

    def __repr__(self) -> str:
        return f"<camera model {self.name!r}: {', '.join(self.parameter_names)}>"

    @property
    def n_params(self) -> int:
        return len(self.parameter_names)

    def index(self, name: str) -> int:
        """Column of parameter ``name`` in io."""
        try:
            return self.parameter_names.index(name)
        except ValueError:
            raise InputError(f"camera model {self.name!r} has no parameter {name!r}",
                             hint="its parameters: " + ", ".join(self.parameter_names)) from None

    def default_parameters(self, principal_distance, image_size):
        """Initial parameter array (principal point at the format centre)."""
        raise NotImplementedError

    def project(self, X, angles, X0, io, jacobians=False):
        """Measured image coordinates (n, 2) [, Jacobian dict]."""
        raise NotImplementedError

    def residuals(self, xy_obs, X, angles, X0, io, jacobians=True):
        """Residuals (n, 2) of the model's own formulation [, Jacobian dict]."""
        raise NotImplementedError

    def residuals_rotation(self, xy_obs, X, R, X0, io, jacobians=True):
        """:meth:`residuals` with the world-to-camera matrices R (n, 3, 3)
        instead of omega-phi-kappa angles (the engine's state holds R).

        The Jacobian dict has the keys ``"io"``, ``"X0"``, ``"X"`` and
        ``"rotation"`` (no ``"angles"``). This generic version goes through
        the angles; the models override it with a direct one.
        """
        angles = matrix_to_opk(np.asarray(R, dtype=float))
        if not jacobians:
            return self.residuals(xy_obs, X, angles, X0, io, jacobians=False)
        r, jac = self.residuals(xy_obs, X, angles, X0, io)
        jac.pop("angles", None)
        return r, jac

    def image_to_ray(self, xy, io):
        """Normalised ideal coordinates (ideal projection with c = 1)."""
        raise NotImplementedError

    def ray_to_image(self, t, io):
        """Measured coordinates of normalised ideal coordinates."""
        raise NotImplementedError

    def _prepare(self, X, angles, X0, io):
        X, angles, X0, io = broadcast_observations(X, angles, X0, io, self.n_params)
        Xc, R, d = camera_frame(X, angles, X0)
        return X, angles, X0, io, Xc, R, d

    @staticmethod
    def rays_to_points(t):
        """Camera-frame points (R = I, X0 = 0) whose ideal projection with
        c = 1 is ``t`` (n,2): ``X = (t_x, -t_y, -1)``."""
        t = np.asarray(t, dtype=float)
        return np.stack([t[:, 0], -t[:, 1], -np.ones(len(t))], -1)
