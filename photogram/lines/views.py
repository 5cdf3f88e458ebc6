"""Oriented views for line photogrammetry: a station's exterior orientation
with its camera, ideal (corrected) image coordinates, and image lines fitted
in them.

Conventions (docs/camera-models.md): ``Xc = R (X - X0)``, camera looking
along -z, image y down; ideal coordinates relative to the principal point

    x̄ = -c Xc_x / Xc_z,   ȳ = +c Xc_y / Xc_z.

In homogeneous form ``(x̄, ȳ, 1) ~ P X~`` with the ideal projection matrix

    P = diag(-c, c, 1) R [I | -X0]                                     (3 x 4)

so the plane through the projection centre and an ideal image line ``l`` is
``pi = P^T l`` (Hartley & Zisserman 2003, result 8.2): its normal is
``R^T diag(-c, c, 1) l`` and it contains ``X0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.errors import InputError
from photogram.geometry import camera_model, opk_to_matrix
from photogram.init.intersection import project_ideal, ray_directions
from photogram.lines.batch_image import across_sigma
from photogram.lines.image_line import ImageLine, fit_image_line

__all__ = ["ViewCamera", "ideal_coordinates", "fit_view_line", "cameras_from_project",
           "lines_from_project"]


@dataclass
class ViewCamera:
    """An oriented view: world-to-camera ``R`` (3, 3), projection centre
    ``X0`` (3,), interior orientation ``io`` in the order of ``model``.

    ``name`` is the station name used in messages.
    """

    R: np.ndarray
    X0: np.ndarray
    io: np.ndarray
    model: str = "brown"
    name: str = ""

    def __post_init__(self):
        self.R = np.asarray(self.R, dtype=float).reshape(3, 3)
        self.X0 = np.asarray(self.X0, dtype=float).reshape(3)
        self.io = np.asarray(self.io, dtype=float).reshape(-1)
        m = camera_model(self.model)
        if len(self.io) != m.n_params:
            raise InputError(f"view {self.name}: io has {len(self.io)} values, "
                             f"model {self.model!r} needs {m.n_params}",
                             hint="order: " + ", ".join(m.parameter_names))

    @classmethod
    def from_angles(cls, angles, X0, io, model: str = "brown", name: str = "") -> "ViewCamera":
        """From omega-phi-kappa (radians, world-to-camera)."""
        return cls(opk_to_matrix(np.asarray(angles, dtype=float)), X0, io, model, name)

    @property
    def c(self) -> float:
        """Principal distance of the ideal coordinates: the model's first
        parameter (brown ``c``, opencv ``fx``), as photogram.init.ideal."""
        return float(self.io[0])

    @property
    def matrix(self) -> np.ndarray:
        """Ideal projection matrix ``diag(-c, c, 1) R [I | -X0]`` (3, 4)."""
        K = np.diag([-self.c, self.c, 1.0]) @ self.R
        return np.hstack([K, -(K @ self.X0)[:, None]])

    def ideal(self, xy, jacobians: bool = False):
        """Ideal image coordinates relative to the principal point, y down,
        of measured coordinates (n, 2): the camera model's correction
        (brown: ``correct``; others ``c * image_to_ray``).

        With ``jacobians`` also ``d ideal / d xy`` (n, 2, 2).
        """
        return ideal_coordinates(self.model, xy, self.io, jacobians=jacobians)

    def measured(self, xy_ideal) -> np.ndarray:
        """Measured (distorted) coordinates of ideal ones (n, 2)."""
        t = np.atleast_2d(np.asarray(xy_ideal, dtype=float)) / self.c
        return camera_model(self.model).ray_to_image(t, self.io)

    def project_ideal(self, X) -> np.ndarray:
        """Ideal image coordinates (n, 2) of object points (n, 3)."""
        return project_ideal(np.atleast_2d(X), self.R, self.X0, self.c)

    def project(self, X) -> np.ndarray:
        """Measured image coordinates (n, 2) of object points (n, 3)."""
        return self.measured(self.project_ideal(X))

    def rays(self, xy_ideal) -> np.ndarray:
        """Unit world directions (n, 3) of the rays of ideal image points."""
        xy = np.atleast_2d(np.asarray(xy_ideal, dtype=float))
        return ray_directions(xy, self.R, self.c)

    def plane(self, l) -> np.ndarray:
        """Plane ``pi = P^T l`` (4,) through ``X0`` and the ideal image line
        ``l`` (3,), scaled to a unit normal: ``pi . (X, 1)`` is the signed
        distance of X from the plane."""
        pi = self.matrix.T @ np.asarray(l, dtype=float)
        return pi / np.linalg.norm(pi[:3])


def ideal_coordinates(model, xy, io, jacobians: bool = False):
    """Ideal image coordinates relative to the principal point, y down, of
    measured coordinates xy (n, 2) with the interior orientation ``io`` (p,)
    or per row (n, p) of camera model ``model`` (a name): brown's
    ``correct``, other models ``c * image_to_ray`` with ``c = io[0]`` (the
    principal distance of the ideal frame). With ``jacobians`` also
    ``d ideal / d xy`` (n, 2, 2). The one implementation of
    :meth:`ViewCamera.ideal` and of the batch line code
    (:mod:`photogram.lines.batch`)."""
    m = camera_model(model)
    xy = np.atleast_2d(np.asarray(xy, dtype=float))
    io = np.broadcast_to(np.asarray(io, dtype=float), (len(xy), m.n_params))
    if model == "brown":
        out = m.correct(xy, io, jacobians="xy" if jacobians else False)
        return (out[0], out[1]["xy"]) if jacobians else out
    c = io[:, :1]
    t = m.image_to_ray(xy, io)
    if not jacobians:
        return c * t
    if model == "opencv":
        _, part = m.distortion(t[:, 0], t[:, 1], io)
        dxy_dt = (part["xy"] + np.eye(2)) * io[:, :2, None]
        return c * t, c[:, :, None] * np.linalg.inv(dxy_dt)
    h = 1e-4
    J = np.stack([(m.image_to_ray(xy + h * e, io) - m.image_to_ray(xy - h * e, io))
                  / (2 * h) for e in np.eye(2)], -1)
    return c * t, c[:, :, None] * J


def fit_view_line(xy, camera: ViewCamera, sigma=1.0, *, label: str | None = None,
                  **kwargs) -> ImageLine:
    """Fit an image line in ideal coordinates (appendix C.2, step A).

    The measured points are corrected with the camera model first (the
    object line images as a straight line only without distortion); the
    a-priori sigma of each point across the line follows from the correction
    Jacobian ``J``: ``sigma_i |J_i^T n|`` (n from the principal axis of the
    corrected points). Then :func:`fit_image_line` (eq. (C11)) in the ideal
    frame.

    Parameters
    ----------
    xy : array_like (n, 2)
        Measured image coordinates.
    camera : ViewCamera
    sigma : float or array_like (n,)
        A-priori sigma of the measured coordinates (image units).
    label : str, optional
        Line name for messages.
    **kwargs
        Passed to :func:`fit_image_line`.

    Returns
    -------
    ImageLine
        With ``frame = "ideal"`` and ``station = camera.name``.
    """
    xy = np.asarray(xy, dtype=float)
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise InputError(f"line {label} in {camera.name}: points must be (n, 2), "
                         f"got {xy.shape}")
    xi, J = camera.ideal(xy, jacobians=True)
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), (len(xy),))
    # the sigma across the line of the corrected points, with the normal of
    # the principal axis (the unweighted solution) of the corrected points
    if len(xi) >= 2 and np.isfinite(xi).all():
        sig = across_sigma(xi[:, None], J[:, None], sig[:, None],
                           np.ones((len(xi), 1), dtype=bool))[:, 0]
    line = fit_image_line(xi, sig, frame="ideal", station=camera.name, label=label, **kwargs)
    return line


def cameras_from_project(project) -> dict[str, ViewCamera]:
    """A :class:`ViewCamera` per station of a Project, from the stations'
    position/angles (the orientation: use an adjusted project) and the
    parameter values of their cameras."""
    st = project.stations
    out = {}
    for i, name in enumerate(st.names):
        cam = project.cameras[st.camera[i]]
        out[name] = ViewCamera.from_angles(st.angles[i], st.position[i], cam.values(),
                                           cam.model, name)
    return out


def lines_from_project(project) -> dict[str, dict[str, np.ndarray]]:
    """The image line measurements of a Project as
    ``{station: {line label: xy (n, 2)}}``."""
    il = project.image_lines
    names = project.stations.names
    out: dict[str, dict[str, np.ndarray]] = {}
    for s in np.unique(il.station):
        rows = il.station == s
        labels = il.line[rows]
        out[names[int(s)]] = {str(lab): il.xy[rows][labels == lab]
                              for lab in dict.fromkeys(labels.tolist())}
    return out
