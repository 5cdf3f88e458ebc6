"""3D lines: point + unit direction, Plücker coordinates and a minimal
4-parameter local update.

A line is stored as a reference point ``P`` on it and a unit direction
``D``; its Plücker coordinates are ``(d, m) = (D, P x D)`` with ``d . m = 0``
(Hartley & Zisserman 2003, sec. 3.2.2; Pottmann & Wallner 2001). Estimation
uses the standard minimal update in the local frame of the line
(e.g. Förstner & Wrobel 2016, sec. 10.5 "reduced coordinates"): with an
orthonormal basis ``(u, v)`` perpendicular to ``D``,

    D' = normalize(D + alpha u + beta v),   P' = P + gamma u + delta v,

``(alpha, beta)`` small rotations (radians) and ``(gamma, delta)`` shifts
across the line at ``P``. The basis is a smooth function of ``D`` built from
the world axis least aligned with it, so no direction is special. A line's
4x4 covariance refers to these parameters at its own ``P``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.errors import GeometryError

__all__ = ["SpaceLine", "line_from_points", "line_from_plucker", "closest_point",
           "point_on_line", "distance_point_line", "project_line", "project_line_batch",
           "local_basis", "cross"]


def cross(a, b) -> np.ndarray:
    """Cross product of (..., 3) arrays (faster than ``np.cross`` for the
    small arrays used here)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.ndim == 1 and b.ndim == 1:
        a1, a2, a3 = a.tolist()
        b1, b2, b3 = b.tolist()
        return np.array([a2 * b3 - a3 * b2, a3 * b1 - a1 * b3, a1 * b2 - a2 * b1])
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def local_basis(D) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal ``(u, v)`` with ``u, v, D`` right-handed, from the world
    axis least aligned with the unit vector ``D``."""
    D = np.asarray(D, dtype=float)
    e = np.zeros(3)
    e[int(np.argmin(np.abs(D)))] = 1.0
    u = cross(e, D)
    u /= np.sqrt(u @ u)
    return u, cross(D, u)


@dataclass(eq=False)
class SpaceLine:
    """A 3D line ``X(t) = point + t direction`` (|direction| = 1).

    ``covariance`` (4, 4), if known, is that of the local parameters
    ``(alpha, beta, gamma, delta)`` at ``point`` in :attr:`basis`.
    """

    point: np.ndarray
    direction: np.ndarray
    covariance: np.ndarray | None = None
    label: str | None = None

    def __post_init__(self):
        self.point = np.asarray(self.point, dtype=float).reshape(3)
        D = np.asarray(self.direction, dtype=float).reshape(3)
        n = np.sqrt(D @ D)
        if not np.isfinite(n) or n == 0:
            raise GeometryError("3D line with a zero or non-finite direction")
        self.direction = D / n
        self._basis = None

    @property
    def basis(self) -> tuple[np.ndarray, np.ndarray]:
        """``(u, v)``, the frame of the local parameters (:func:`local_basis`)."""
        if self._basis is None:
            self._basis = local_basis(self.direction)
        return self._basis

    # -- Plücker ------------------------------------------------------------
    @property
    def moment(self) -> np.ndarray:
        """``m = P x D``."""
        return cross(self.point, self.direction)

    @property
    def plucker(self) -> np.ndarray:
        """``(d, m)`` (6,), ``d`` unit, ``d . m = 0``."""
        return np.concatenate([self.direction, self.moment])

    def plucker_jacobian(self) -> np.ndarray:
        """d(d, m)/d(alpha, beta, gamma, delta) (6, 4) at the line."""
        u, v = self.basis
        J = np.zeros((6, 4))
        J[:3, 0], J[:3, 1] = u, v
        J[3:, 0], J[3:, 1] = cross(self.point, u), cross(self.point, v)
        J[3:, 2], J[3:, 3] = cross(u, self.direction), cross(v, self.direction)
        return J

    @property
    def covariance_plucker(self) -> np.ndarray:
        """Covariance (6, 6) of :attr:`plucker` (rank 4)."""
        J = self.plucker_jacobian()
        return J @ self.covariance @ J.T

    # -- local update -------------------------------------------------------
    def update(self, delta) -> "SpaceLine":
        """The line moved by the local parameters ``delta`` (4,)."""
        a, b, g, h = np.asarray(delta, dtype=float)
        u, v = self.basis
        return SpaceLine(self.point + g * u + h * v, self.direction + a * u + b * v,
                         label=self.label)

    def local_error(self, other: "SpaceLine") -> np.ndarray:
        """The ``delta`` with ``self.update(delta) == other`` (exactly):
        ``alpha = u . D'/(D . D')``, ..., and the shifts of ``other``'s point
        in the plane through ``point`` perpendicular to ``direction``."""
        u, v = self.basis
        D, Do = self.direction, other.direction
        c = D @ Do
        if abs(c) < 1e-12:
            raise GeometryError("the two lines are perpendicular: no local error")
        t = (self.point - other.point) @ D / c
        Q = other.point + t * Do - self.point
        return np.array([u @ Do / c, v @ Do / c, u @ Q, v @ Q])

    def recentred(self, X) -> "SpaceLine":
        """The same line with its point moved to the point closest to X,
        the covariance transported there."""
        t = float((np.asarray(X, dtype=float) - self.point) @ self.direction)
        out = SpaceLine(self.point + t * self.direction, self.direction, label=self.label)
        if self.covariance is not None:
            # same basis (same D); gamma' = gamma + t alpha, delta' = delta + t beta
            T = np.eye(4)
            T[2, 0] = T[3, 1] = t
            out.covariance = T @ self.covariance @ T.T
        return out

    def point_covariance(self, t) -> np.ndarray:
        """Covariance (3, 3) of the point at ``t`` (its across-line part)."""
        u, v = self.basis
        J = np.stack([t * u, t * v, u, v], axis=1)
        return J @ self.covariance @ J.T

    @property
    def sigma_angle(self) -> float:
        """RMS standard deviation of the direction (radians)."""
        return float(np.sqrt(np.trace(self.covariance[:2, :2]) / 2))

    @property
    def sigma_position(self) -> float:
        """RMS standard deviation across the line at ``point``."""
        return float(np.sqrt(np.trace(self.covariance[2:, 2:]) / 2))


def line_from_points(X1, X2, label: str | None = None) -> SpaceLine:
    """The line through X1 and X2; ``point = X1``, ``direction`` towards X2
    (so ``point_on_line(L, |X2 - X1|) = X2``)."""
    X1, X2 = np.asarray(X1, dtype=float), np.asarray(X2, dtype=float)
    if np.linalg.norm(X2 - X1) == 0:
        raise GeometryError("line_from_points: the two points coincide")
    return SpaceLine(X1, X2 - X1, label=label)


def line_from_plucker(d, m, label: str | None = None) -> SpaceLine:
    """Line of Plücker coordinates ``(d, m)`` (``d . m = 0``); its point is
    the point closest to the origin, ``d x m / |d|^2``."""
    d, m = np.asarray(d, dtype=float), np.asarray(m, dtype=float)
    dd = d @ d
    if dd == 0:
        raise GeometryError("Plücker coordinates with d = 0 (line at infinity)")
    return SpaceLine(cross(d, m) / dd, d, label=label)


def closest_point(line: SpaceLine, X) -> np.ndarray:
    """Points on the line closest to X (..., 3)."""
    X = np.asarray(X, dtype=float)
    t = (X - line.point) @ line.direction
    return line.point + t[..., None] * line.direction


def point_on_line(line: SpaceLine, t) -> np.ndarray:
    """``point + t direction`` for scalar or array ``t``."""
    t = np.asarray(t, dtype=float)
    return line.point + t[..., None] * line.direction


def distance_point_line(line: SpaceLine, X) -> np.ndarray:
    """Distances of points X (..., 3) from the line."""
    X = np.asarray(X, dtype=float)
    return np.linalg.norm(cross(X - line.point, line.direction), axis=-1)


def project_line(line: SpaceLine, camera, jacobian: bool = False):
    """Homogeneous ideal image line of a 3D line (eq. (C13) read backwards).

    The plane through the projection centre and the line has the normal
    ``N = (P - X0) x D``; in the camera frame ``R N``, and with
    ``pi = P_cam^T l`` (views.py) the image line is
    ``l ~ diag(-1/c, 1/c, 1) R N``. It is normalised (``l1^2 + l2^2 = 1``,
    ``l . (x̄, ȳ, 1)`` the signed distance in image units, coordinates
    relative to the principal point) and oriented so that the image of
    ``direction`` runs along ``(l2, -l1)``.

    Parameters
    ----------
    line : SpaceLine
    camera : ViewCamera
    jacobian : bool
        Also return ``dl / d(alpha, beta, gamma, delta)`` (3, 4).

    Returns
    -------
    l : ndarray (3,)
    J : ndarray (3, 4), only with ``jacobian``
    """
    l, J = project_line_batch(line, camera.R[None], camera.X0[None], np.array([camera.c]),
                              names=[camera.name])
    return (l[0], J[0]) if jacobian else l[0]


def project_line_batch(line: SpaceLine, R, X0, c, names=None):
    """:func:`project_line` into k views at once: ``R`` (k, 3, 3), ``X0``
    (k, 3), ``c`` (k,). Returns ``l`` (k, 3) and ``dl/d delta`` (k, 3, 4)."""
    u, v = line.basis
    D = line.direction
    r = line.point - X0                                        # (k, 3)
    Kp = np.stack([-1.0 / c, 1.0 / c, np.ones_like(c)], -1)    # (k, 3)
    h = Kp * np.einsum("kij,kj->ki", R, cross(r, D))
    rho = np.hypot(h[:, 0], h[:, 1])
    bad = rho <= 1e-14 * np.linalg.norm(h, axis=1)
    if bad.any():
        k = int(np.nonzero(bad)[0][0])
        name = names[k] if names is not None and names[k] else "the view"
        raise GeometryError(
            f"the 3D line{' ' + line.label if line.label else ''} passes through the "
            f"projection centre of {name}: it images as a point",
            hint="measure it in views that see it as a line")
    l = h / rho[:, None]
    # orientation: the image of P + s D moves along (l2, -l1)
    Xc = np.einsum("kij,kj->ki", R, r)
    dXc = R @ D
    dx = np.stack([-c * (dXc[:, 0] * Xc[:, 2] - Xc[:, 0] * dXc[:, 2]),
                   c * (dXc[:, 1] * Xc[:, 2] - Xc[:, 1] * dXc[:, 2])], -1)
    sign = np.where(dx[:, 0] * l[:, 1] - dx[:, 1] * l[:, 0] < 0, -1.0, 1.0)
    l = sign[:, None] * l
    dN = np.stack([cross(r, u), cross(r, v),
                   np.broadcast_to(cross(u, D), r.shape),
                   np.broadcast_to(cross(v, D), r.shape)], axis=-1)   # (k, 3, 4)
    dh = Kp[:, :, None] * (R @ dN)
    nt = l.copy()
    nt[:, 2] = 0.0
    P = np.eye(3) - l[:, :, None] * nt[:, None, :]
    J = (sign / rho)[:, None, None] * (P @ dh)
    return l, J
