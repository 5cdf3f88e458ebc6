"""Spots of reflective markers in small windows (the image fits of
:mod:`photogram.track.bindings`): the white top-hat, windows with their
pixel centres, moments and the single marker's spot (a soft elliptical
disc, :func:`fit_spot_shape`), fitted by a batched Levenberg-Marquardt with
analytic Jacobians; two equal spots in one blob are in
:mod:`photogram.track.two_spots`."""

from __future__ import annotations

import warnings

import numpy as np

from photogram.track.background import frame_gain

# ------------------------------------------------------------------ image fits

def _opening(frame: np.ndarray, size: int) -> np.ndarray:
    """Grey opening ``open(I)`` with a ``size`` square (float32): the frame
    without its bright spots smaller than the square."""
    import cv2
    f = np.asarray(frame, np.float32)
    k = cv2.getStructuringElement(cv2.MORPH_RECT, (size, size))
    return cv2.morphologyEx(f, cv2.MORPH_OPEN, k)


def _tophat(frame: np.ndarray, size: int) -> np.ndarray:
    """White top-hat ``I - open(I)`` with a ``size`` square (float32)."""
    return np.asarray(frame, np.float32) - _opening(frame, size)


def _crop_around(frame, xy, pad: int, pixel_offset: float):
    """The part of ``frame`` within ``pad`` pixels of the points ``xy``
    (n, 2) (image frame) and its origin (2,): image coordinates in the crop
    are those in the frame minus the origin (a top-hat of the crop equals
    the frame's within ``pad - size`` of its border)."""
    H, W = frame.shape[:2]
    ij = np.rint(np.asarray(xy, float).reshape(-1, 2) - pixel_offset).astype(int)
    x0, y0 = np.maximum(ij.min(0) - pad, 0)
    x1, y1 = np.minimum(ij.max(0) + pad + 1, [W, H])
    return frame[y0:y1, x0:x1], np.array([x0, y0], float)


def _behind(frame, background, size, noise):
    """The scene behind the markers of a frame: the grey opening (the frame
    without its small bright spots) where the jumper's body is, the static
    background (scaled by the frame's brightness ratio) where the opening
    shows it, within ``max(4 noise, 10)`` grey levels (the opening of a
    noisy frame is biased low, the temporal median is not)."""
    bg = np.asarray(background, np.float32) * frame_gain(frame, background)
    op = _opening(frame, size)
    return np.where(op >= bg - max(4 * noise, 10.0), bg, op)


def _windows(img: np.ndarray, centres: np.ndarray, half: int, pixel_offset: float):
    """Windows (n, 2h+1, 2h+1) of ``img`` around ``centres`` (n, 2) (image
    frame) and the image-frame coordinates of their pixel centres
    (n, 2h+1, 2h+1) x 2; pixels outside the image are NaN."""
    centres = np.asarray(centres, float).reshape(-1, 2)
    H, W = img.shape
    ij = np.rint(centres - pixel_offset).astype(int)                  # (n, 2) col, row
    r = np.arange(-half, half + 1)
    cols = ij[:, 0, None, None] + r[None, None, :]
    rows = ij[:, 1, None, None] + r[None, :, None]
    cols, rows = np.broadcast_arrays(cols, rows)
    inside = (cols >= 0) & (cols < W) & (rows >= 0) & (rows < H)
    vals = np.where(inside, img[np.clip(rows, 0, H - 1), np.clip(cols, 0, W - 1)], np.nan)
    return vals.astype(float), cols + pixel_offset, rows + pixel_offset


def _gauss(x, y, cx, cy, Sinv):
    """exp(-q/2) of pixel grids (n, h, w) about centres (n,) with inverse
    covariances (n, 3) (a, b, c of [[a, b], [b, c]])."""
    dx, dy = x - cx[:, None, None], y - cy[:, None, None]
    q = Sinv[:, 0, None, None] * dx * dx + 2 * Sinv[:, 1, None, None] * dx * dy \
        + Sinv[:, 2, None, None] * dy * dy
    return np.exp(-0.5 * q)


def _inv_sym(S):
    """Inverse of symmetric 2x2 (n, 3) [sxx, sxy, syy] -> (n, 3)."""
    det = S[:, 0] * S[:, 2] - S[:, 1] ** 2
    return np.column_stack([S[:, 2], -S[:, 1], S[:, 0]]) / det[:, None]


def _gauss_newton(model, p, v, x, y, n_iter=30, damping=1e-3):
    """Batched Levenberg-Marquardt with the model's analytic Jacobian.

    ``model(p, x, y) -> (n, h, w)`` and ``model.jacobian(p, x, y) -> (n, h,
    w, k)``; ``p`` (n, k) start; ``v`` (n, h, w) data (NaN outside the
    image); ``x, y`` (n, h, w) pixel centres. Returns p, J (n, m, k) at the
    solution, residuals (n, m), valid (n, m).
    """
    valid = np.isfinite(v).reshape(len(v), -1)
    data = np.where(np.isfinite(v), v, 0).reshape(len(v), -1)
    lam = np.full(len(p), damping)
    eye = np.eye(p.shape[1])[None]

    def resid(q):
        with np.errstate(all="ignore"):
            r = model(q, x, y).reshape(len(q), -1) - data
        return np.where(valid, r, 0.0)

    def jac(q, r0):
        with np.errstate(all="ignore"):
            J = model.jacobian(q, x, y).reshape(len(q), -1, q.shape[1])
        return np.where(valid[:, :, None], np.nan_to_num(J), 0.0)

    r = resid(p)
    cost = (r ** 2).sum(1)
    done = np.zeros(len(p), bool)
    J = jac(p, r)
    for _ in range(n_iter):
        A = J.transpose(0, 2, 1) @ J
        g = (J.transpose(0, 2, 1) @ r[:, :, None])[:, :, 0]
        D = np.einsum("nii->ni", A)
        Ad = A + lam[:, None, None] * (D[:, :, None] * eye + 1e-9 * eye)
        try:
            step = -np.linalg.solve(Ad, g[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            step = -(np.linalg.pinv(Ad) @ g[:, :, None])[:, :, 0]
        pn = p + step
        rn = resid(pn)
        cn = (rn ** 2).sum(1)
        better = np.isfinite(cn) & (cn < cost) & ~done
        p = np.where(better[:, None], pn, p)
        r = np.where(better[:, None], rn, r)
        # a window is done when its accepted step is below 1e-6 in every
        # parameter or its damping has grown past 1e6 (no step lowers it)
        done |= (better & (np.abs(step) < 1e-6).all(1)) | (~better & (lam * 10.0 > 1e6))
        cost = np.where(better, cn, cost)
        lam = np.where(better, lam * 0.3, lam * 10.0)
        if better.any():
            J = np.where(better[:, None, None], jac(p, r), J)
        if done.all():
            break
    return p, J, r, valid


def _nanmax(v):
    """Largest finite value per window (n, h, w) -> (n,), NaN if none."""
    f = np.isfinite(v).any(axis=(1, 2))
    return np.where(f, np.max(np.where(np.isfinite(v), v, -np.inf), axis=(1, 2)), np.nan)


def _moments(v, x, y):
    """Centroid (n, 2), second moments (n, 3) and border level (n,) of the
    positive part of windows ``v`` less the median of their border."""
    border = np.concatenate([v[:, 0, :], v[:, -1, :], v[:, 1:-1, 0], v[:, 1:-1, -1]], axis=1)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        b = np.nanmedian(border, axis=1)
    w = np.clip(np.nan_to_num(v - b[:, None, None]), 0, None)
    s = w.sum((1, 2))
    s = np.where(s > 0, s, np.nan)
    cx, cy = (w * x).sum((1, 2)) / s, (w * y).sum((1, 2)) / s
    dx, dy = x - cx[:, None, None], y - cy[:, None, None]
    M = np.column_stack([(w * dx * dx).sum((1, 2)), (w * dx * dy).sum((1, 2)),
                         (w * dy * dy).sum((1, 2))]) / s[:, None]
    return np.column_stack([cx, cy]), M, b


def _shape(lx, rho, ly):
    """Covariance (n, 3) from log variances and a correlation (kept in
    (-0.95, 0.95) by tanh)."""
    sx, sy = np.exp(0.5 * lx), np.exp(0.5 * ly)
    return np.column_stack([sx * sx, 0.95 * np.tanh(rho) * sx * sy, sy * sy])


def _profile(x, y, cx, cy, Qinv, w):
    """A soft elliptical disc, 1 inside, 0 outside: ``erfc((rho - 1) / w) / 2``
    with ``rho^2 = (x - c)^T Q^-1 (x - c)`` (pixel grids (n, h, w), centres
    (n,), ``Qinv`` (n, 3), edge widths (n,) in units of the radius)."""
    from scipy.special import erfc
    dx, dy = x - cx[:, None, None], y - cy[:, None, None]
    q = Qinv[:, 0, None, None] * dx * dx + 2 * Qinv[:, 1, None, None] * dx * dy \
        + Qinv[:, 2, None, None] * dy * dy
    return 0.5 * erfc((np.sqrt(q) - 1.0) / w[:, None, None])


def _profile_jacobian(x, y, cx, cy, Qinv, w):
    """:func:`_profile` ``g`` and its partials (n, h, w, 6) by the centre
    (cx, cy), the three entries of ``Qinv`` and the edge width ``w``:
    ``dg/dz = -exp(-z^2) / sqrt(pi)``, ``z = (rho - 1) / w``,
    ``drho/dq = 1 / (2 rho)``, ``dq/dcx = -2 (a dx + b dy)``,
    ``dq/dcy = -2 (b dx + c dy)``, ``dq/d(a, b, c) = (dx^2, 2 dx dy, dy^2)``."""
    from scipy.special import erfc
    dx, dy = x - cx[:, None, None], y - cy[:, None, None]
    a, b, c = (Qinv[:, k, None, None] for k in range(3))
    q = a * dx * dx + 2 * b * dx * dy + c * dy * dy
    rho = np.sqrt(np.maximum(q, 1e-24))
    ww = w[:, None, None]
    z = (rho - 1.0) / ww
    g = 0.5 * erfc(z)
    dg_dq = -np.exp(-z * z) / np.sqrt(np.pi) / ww / (2 * rho)
    J = np.empty(x.shape + (6,))
    J[..., 0] = dg_dq * -2 * (a * dx + b * dy)
    J[..., 1] = dg_dq * -2 * (b * dx + c * dy)
    J[..., 2] = dg_dq * dx * dx
    J[..., 3] = dg_dq * 2 * dx * dy
    J[..., 4] = dg_dq * dy * dy
    J[..., 5] = -np.exp(-z * z) / np.sqrt(np.pi) * -z / ww
    return g, J


def _shape_jacobian(lx, rho, ly):
    """``Qinv`` = inverse of :func:`_shape` (n, 3) and d Qinv / d(lx, rho,
    ly) (n, 3, 3): ``dQinv = -Qinv dS Qinv``."""
    S = _shape(lx, rho, ly)
    Qi = _inv_sym(S)
    sx, sy, th = np.exp(0.5 * lx), np.exp(0.5 * ly), np.tanh(rho)
    dS = np.zeros((len(lx), 3, 3))                       # [entry of S, parameter]
    dS[:, 0, 0] = sx * sx
    dS[:, 1, 0] = 0.5 * S[:, 1]
    dS[:, 1, 1] = 0.95 * (1 - th * th) * sx * sy
    dS[:, 1, 2] = 0.5 * S[:, 1]
    dS[:, 2, 2] = sy * sy

    def full(v):                                          # (n, 3) -> (n, 2, 2)
        return np.stack([np.stack([v[..., 0], v[..., 1]], -1),
                         np.stack([v[..., 1], v[..., 2]], -1)], -2)
    Qm = full(Qi)
    out = np.empty((len(lx), 3, 3))
    for k in range(3):
        D = -Qm @ full(dS[:, :, k]) @ Qm
        out[:, :, k] = np.stack([D[:, 0, 0], D[:, 0, 1], D[:, 1, 1]], -1)
    return Qi, out


def _one_spot(p, x, y):
    Q = _shape(p[:, 4], p[:, 5], p[:, 6])
    return p[:, 0, None, None] * _profile(x, y, p[:, 2], p[:, 3], _inv_sym(Q), np.exp(p[:, 7])) \
        + p[:, 1, None, None]


def _one_spot_jacobian(p, x, y):
    """d :func:`_one_spot` / d(amp, b, cx, cy, lx, rho, ly, log w), analytic."""
    Qi, dQi = _shape_jacobian(p[:, 4], p[:, 5], p[:, 6])
    w = np.exp(p[:, 7])
    g, Jg = _profile_jacobian(x, y, p[:, 2], p[:, 3], Qi, w)
    amp = p[:, 0, None, None, None]
    J = np.empty(x.shape + (8,))
    J[..., 0] = g
    J[..., 1] = 1.0
    J[..., 2:4] = amp * Jg[..., 0:2]
    J[..., 4:7] = amp * np.einsum("nhwe,nek->nhwk", Jg[..., 2:5], dQi)
    J[..., 7] = amp[..., 0] * Jg[..., 5] * w[:, None, None]
    return J


_one_spot.jacobian = _one_spot_jacobian


def fit_spot_shape(image: np.ndarray, centres: np.ndarray, *, half: int = 4,
                   pixel_offset: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """The spot of single markers: a soft elliptical disc over a constant.

    The marker balls image as uniform discs, widened by defocus and
    smeared by motion blur: modelled as ``A erfc((rho - 1) / w) / 2 + b``,
    ``rho`` the elliptical radius of the shape matrix ``Q`` (a circle of
    radius R: ``Q = R^2 I``) and ``w`` the relative edge width.

    Parameters
    ----------
    image : (H, W)
        Grey values above the local background (the white top-hat of the
        frame).
    centres : (n, 2)
        Approximate centres (image frame).
    half : int
        Half side (px) of the fitting window.
    pixel_offset : float
        Image-frame coordinate of the first pixel's centre.

    Returns
    -------
    shape : (n, 4)
        ``qxx, qxy, qyy`` (px^2) of ``Q`` and ``w``; NaN where the fit failed.
    centre : (n, 2)
    """
    return fit_spot_windows(*spot_windows(image, centres, half=half, pixel_offset=pixel_offset))


def spot_windows(image: np.ndarray, centres: np.ndarray, *, half: int = 4,
                 pixel_offset: float = 0.5):
    """The windows :func:`fit_spot_shape` fits: grey values (n, 2h+1,
    2h+1) (NaN outside the image) and the image-frame coordinates x, y of
    their pixel centres (each (n, 2h+1, 2h+1))."""
    return _windows(image, np.asarray(centres, float).reshape(-1, 2), half, pixel_offset)


def fit_spot_windows(v: np.ndarray, x: np.ndarray, y: np.ndarray):
    """:func:`fit_spot_shape` on windows (:func:`spot_windows`; windows of
    several images may be stacked: every window's fit is its own).

    Returns
    -------
    shape : (n, 4)
    centre : (n, 2)
    """
    c, M, b = _moments(v, x, y)
    M = np.clip(M, [0.05, -np.inf, 0.05], None)
    amp = _nanmax(v) - b
    with np.errstate(all="ignore"):
        rho = np.arctanh(np.clip(M[:, 1] / np.sqrt(M[:, 0] * M[:, 2]) / 0.95, -0.9, 0.9))
    # a uniform disc of radius R has variance R^2 / 4 per axis
    p0 = np.column_stack([amp, b, c, np.log(4 * M[:, 0]), rho, np.log(4 * M[:, 2]),
                          np.full(len(v), np.log(0.4))])
    shape = np.full((len(v), 4), np.nan)
    cen = np.full((len(v), 2), np.nan)
    ok = np.isfinite(p0).all(1) & (amp > 0)
    if ok.any():
        p, *_ = _gauss_newton(_one_spot, p0[ok], v[ok], x[ok], y[ok])
        shape[ok] = np.column_stack([_shape(p[:, 4], p[:, 5], p[:, 6]), np.exp(p[:, 7])])
        cen[ok] = p[:, 2:4]
        far = np.hypot(*(cen[ok] - c[ok]).T) > 1.5
        shape[np.nonzero(ok)[0][far]] = np.nan
    return shape, cen
