"""Two equal spots in one blob (the split of two merged markers in
:mod:`photogram.track.bindings`): on the white top-hat
(:func:`fit_two_spots`) or as opaque discs over the body behind them
(:func:`fit_two_spots_over`), fitted by the batched Levenberg-Marquardt of
:mod:`photogram.track.spots` with analytic Jacobians."""

from __future__ import annotations

import numpy as np

from photogram.track.spots import (_gauss_newton, _inv_sym, _moments, _nanmax, _profile,
                                   _profile_jacobian, _windows)

__all__ = ["fit_two_spots", "fit_two_spots_over"]


def _two_spots(shape):
    Qinv, w = _inv_sym(shape[:, :3]), shape[:, 3]

    def model(p, x, y):
        a, b, cx, cy, dx, dy = p.T
        g1 = _profile(x, y, cx + dx, cy + dy, Qinv, w)
        g2 = _profile(x, y, cx - dx, cy - dy, Qinv, w)
        # opaque discs: the union, not the sum, of the two coverages
        return a[:, None, None] * (g1 + g2 - g1 * g2) + b[:, None, None]

    def jacobian(p, x, y):
        """d model / d(a, b, cx, cy, dx, dy), analytic."""
        a, b, cx, cy, dx, dy = p.T
        g1, J1 = _profile_jacobian(x, y, cx + dx, cy + dy, Qinv, w)
        g2, J2 = _profile_jacobian(x, y, cx - dx, cy - dy, Qinv, w)
        A = a[:, None, None, None]
        h1, h2 = (1 - g2)[..., None] * J1[..., :2], (1 - g1)[..., None] * J2[..., :2]
        J = np.empty(x.shape + (6,))
        J[..., 0] = g1 + g2 - g1 * g2
        J[..., 1] = 1.0
        J[..., 2:4] = A * (h1 + h2)
        J[..., 4:6] = A * (h1 - h2)
        return J

    model.jacobian = jacobian
    return model


def fit_two_spots(image: np.ndarray, centres: np.ndarray, shapes: np.ndarray, *,
                  noise: float | np.ndarray = 1.0, half: int = 4,
                  pixel_offset: float = 0.5, sigma_floor: float = 0.05) -> dict:
    """Two equal spots of a known shape fitted to blobs (module doc, step 3).

    Parameters
    ----------
    image : (H, W)
        Grey values above the local background (white top-hat).
    centres : (n, 2)
        Approximate blob centres (image frame).
    shapes : (n, 4) or (4,)
        The shape of ONE spot (:func:`photogram.track.spots.fit_spot_shape` of single markers).
    noise : float or (n,)
        Pixel noise sigma (grey levels); the fit's residual RMS is used
        where it is larger.
    half : int
        Half side (px) of the fitting window.
    pixel_offset : float
        Image-frame coordinate of the first pixel's centre.
    sigma_floor : float
        Smallest point sigma (px): the model is not the rendered disc.

    Returns
    -------
    dict of arrays
        ``centre`` (n, 2) the midpoint ``c``; ``half_sep`` (n, 2) ``d``
        (sign arbitrary); ``points`` (n, 2, 2) ``c + d`` and ``c - d``;
        ``separation`` (n,) ``2 |d|``; ``sep_sigma`` (n,); ``sigma`` (n,)
        per point (RMS of its x and y sigmas, with the floor);
        ``centre_sigma`` (n,); ``rms`` (n,) residual RMS; ``amplitude``.
    """
    centres = np.asarray(centres, float).reshape(-1, 2)
    n = len(centres)
    S = np.broadcast_to(np.asarray(shapes, float), (n, 4)).copy()
    v, x, y = _windows(image, centres, half, pixel_offset)
    c, M, b = _moments(v, x, y)
    # two equal spots at c +- d: second moments S + d d^T (moment start)
    d0 = _moment_start(M, S)
    amp = _nanmax(v) - b
    p0 = np.column_stack([amp, b, c, d0])
    out = _empty_result(n)
    ok = np.isfinite(p0).all(1) & np.isfinite(S).all(1) & (amp > 0)
    if not ok.any():
        return out
    idx = np.nonzero(ok)[0]
    p, J, r, valid = _gauss_newton(_two_spots(S[ok]), p0[ok], v[ok], x[ok], y[ok])
    return _two_spot_result(out, idx, p, J, r, valid, noise, n, sigma_floor)


def _two_spot_result(out, idx, p, J, r, valid, noise, n, sigma_floor):
    """Fill the result arrays of the windows ``idx`` from a two-spot fit
    (parameters ``p[:, 2:4]`` the midpoint, ``p[:, 4:6]`` the half
    separation; the covariance from ``J`` scaled by the larger of the
    residual RMS and ``noise``)."""
    m = valid.sum(1)
    rms = np.sqrt((r ** 2).sum(1) / np.maximum(m - p.shape[1], 1))
    sn = np.maximum(rms, np.broadcast_to(np.asarray(noise, float), (n,))[idx])
    A = J.transpose(0, 2, 1) @ J
    C = np.linalg.pinv(A) * (sn ** 2)[:, None, None]
    cc, dd = p[:, 2:4], p[:, 4:6]
    # var of c + s d per axis: C_cc + C_dd + 2 s C_cd (the larger of the two points)
    vx = C[:, 2, 2] + C[:, 4, 4] + 2 * np.abs(C[:, 2, 4])
    vy = C[:, 3, 3] + C[:, 5, 5] + 2 * np.abs(C[:, 3, 5])
    dl = np.hypot(dd[:, 0], dd[:, 1])
    u = dd / np.maximum(dl, 1e-9)[:, None]
    var_d = np.einsum("ni,nij,nj->n", u, C[:, 4:6, 4:6], u)
    out["centre"][idx] = cc
    out["half_sep"][idx] = dd
    out["points"][idx] = np.stack([cc + dd, cc - dd], axis=1)
    out["separation"][idx] = 2 * dl
    out["sep_sigma"][idx] = 2 * np.sqrt(np.maximum(var_d, 0))
    out["sigma"][idx] = np.sqrt(0.5 * (vx + vy) + sigma_floor ** 2)
    out["centre_sigma"][idx] = np.sqrt(0.5 * (C[:, 2, 2] + C[:, 3, 3]) + sigma_floor ** 2)
    out["rms"][idx] = rms
    out["amplitude"][idx] = p[:, 0]
    return out


def _empty_result(n):
    return {k: np.full(s, np.nan) for k, s in
            [("centre", (n, 2)), ("half_sep", (n, 2)), ("points", (n, 2, 2)),
             ("separation", n), ("sep_sigma", n), ("sigma", n), ("centre_sigma", n),
             ("rms", n), ("amplitude", n)]}


def _moment_start(M, S):
    """Half separation ``d`` (n, 2) of two equal spots of shape ``S`` whose
    blob has the second moments ``M``: ``M = S / 4 + d d^T`` (a uniform
    disc of shape Q has the second moments Q / 4)."""
    E = M - S[:, :3] / 4
    tr, det = E[:, 0] + E[:, 2], E[:, 0] * E[:, 2] - E[:, 1] ** 2
    lam1 = 0.5 * tr + np.sqrt(np.maximum(0.25 * tr ** 2 - det, 0))
    ang = 0.5 * np.arctan2(2 * E[:, 1], E[:, 0] - E[:, 2])
    dlen = np.sqrt(np.clip(lam1, 0.04, None))
    return np.column_stack([np.cos(ang), np.sin(ang)]) * dlen[:, None]


def _two_spots_over(shape, under):
    """Two opaque discs of grey ``a`` over the scene behind them, ``under``
    (n, h, w) plus an offset ``k``: ``I = a C + (U + k) (1 - C)``,
    ``C = g1 + g2 - g1 g2``."""
    Qinv, w = _inv_sym(shape[:, :3]), shape[:, 3]

    def model(p, x, y):
        a, k, cx, cy, dx, dy = p.T
        g1 = _profile(x, y, cx + dx, cy + dy, Qinv, w)
        g2 = _profile(x, y, cx - dx, cy - dy, Qinv, w)
        C = g1 + g2 - g1 * g2
        return a[:, None, None] * C + (under + k[:, None, None]) * (1 - C)

    def jacobian(p, x, y):
        """d model / d(a, k, cx, cy, dx, dy), analytic."""
        a, k, cx, cy, dx, dy = p.T
        g1, J1 = _profile_jacobian(x, y, cx + dx, cy + dy, Qinv, w)
        g2, J2 = _profile_jacobian(x, y, cx - dx, cy - dy, Qinv, w)
        C = g1 + g2 - g1 * g2
        A = (a[:, None, None] - under - k[:, None, None])[..., None]
        h1, h2 = (1 - g2)[..., None] * J1[..., :2], (1 - g1)[..., None] * J2[..., :2]
        J = np.empty(x.shape + (6,))
        J[..., 0] = C
        J[..., 1] = 1 - C
        J[..., 2:4] = A * (h1 + h2)
        J[..., 4:6] = A * (h1 - h2)
        return J

    model.jacobian = jacobian
    return model


def fit_two_spots_over(frame: np.ndarray, under: np.ndarray, centres: np.ndarray,
                       shapes: np.ndarray, *, noise: float | np.ndarray = 1.0, half: int = 4,
                       pixel_offset: float = 0.5, sigma_floor: float = 0.05) -> dict:
    """Two equal opaque spots fitted in the frame itself, composited over
    what is behind them.

    :func:`fit_two_spots` fits ``a C + b`` to the white top-hat
    ``I - open(I)``: one contrast ``a`` all round. A marker at the edge of
    the dark body against bright snow has the snow's small contrast on one
    side and the body's large one on the other: the binding markers sit on
    the boots at the edge of the skis, and their top-hat centres came out
    0.15 px towards the body (rendered normal set, docs/track.md). Here the
    frame is ``I = a C + (U + k)(1 - C)`` with ``U`` the scene behind the
    markers (``under``: the grey opening ``open(I)``, the frame with its
    small bright spots removed), so each side of a disc counts with its own
    contrast.

    Parameters
    ----------
    frame, under : (H, W)
        The frame and the scene behind its markers (grey levels).
    centres, shapes, noise, half, pixel_offset, sigma_floor
        As :func:`fit_two_spots`.

    Returns
    -------
    dict of arrays
        As :func:`fit_two_spots` (``amplitude``: the markers' grey).
    """
    centres = np.asarray(centres, float).reshape(-1, 2)
    n = len(centres)
    S = np.broadcast_to(np.asarray(shapes, float), (n, 4)).copy()
    v, x, y = _windows(np.asarray(frame, float), centres, half, pixel_offset)
    u, _, _ = _windows(np.asarray(under, float), centres, half, pixel_offset)
    c, M, _ = _moments(v - u, x, y)
    d0 = _moment_start(M, S)
    amp = _nanmax(v)
    p0 = np.column_stack([amp, np.zeros(n), c, d0])
    out = _empty_result(n)
    ok = np.isfinite(p0).all(1) & np.isfinite(S).all(1) & np.isfinite(u).all((1, 2))
    if not ok.any():
        return out
    idx = np.nonzero(ok)[0]
    p, J, r, valid = _gauss_newton(_two_spots_over(S[ok], u[ok]), p0[ok], v[ok], x[ok], y[ok])
    return _two_spot_result(out, idx, p, J, r, valid, noise, n, sigma_floor)
