"""The two skis of one image: a joint fit of two blurred dark bars in a band
around their predicted lines (issue 19, item 4).

Skis are long thin dark bars (1-5 px wide, 50-100 px long) on bright snow.
Seen from the side the two skis of a V nearly coincide in the image: their
axes cross near the bindings, the tips are 2-15 px apart. Edge detectors
(Canny + Hough, OpenCV's line-segment detector) merge the two skis' edges
with each other and with the suit's (benchmarks/track_skis.py: LSD in the
same bands 2.2 deg RMS against 0.15 deg here, normal rendered set); we
therefore fit both bars at once to the image, with the model

    C_k(p) = [Phi((d_k + w/2) / s) - Phi((d_k - w/2) / s)]
             [Phi((t_k - a_k) / s) - Phi((t_k - b_k) / s)]              (1)
    B(p) - I(p) = (B(p) - G) (C_1 + C_2 - C_1 C_2)                      (2)

per pixel ``p`` of the band: ``I`` the frame, ``B`` the background,
``d_k``, ``t_k`` the signed distance across and the position along the axis
of ski ``k`` (angle and shift per ski), ``a_k, b_k`` its ends; shared by
both skis (the same skis at about the same distance) the width ``w``, the
grey ``G`` and the blur ``s`` (the Gaussian edge of an antialiased, slightly
blurred bar). Eq. (2) composes two opaque bars over the background (their
union: no double darkening where they overlap), so the contrast follows the
background (snow, sky, a pole behind). The ski axis is the middle line
between the two long edges of eq. (1): the edges are fitted together, not
detected one by one.

Left out of the fit: the suit (pixels darker than the ski grey ``G``), dark
pixels away from both predicted axes (a suit lighter than the skis), pixels
darker than the fitted model (re-fitted up to ``iterations`` times), bright
pixels (reflective markers) and given discs (the marker positions), each
with a one-pixel margin. Least squares with a soft-L1 loss
(:func:`robust_lm`, in :mod:`photogram.track.lm`); the covariance of each axis' angle and
shift from the Gauss-Newton normal matrix, scaled by the robust residual
variance.

The axes (:class:`photogram.track.ski_axes.BarLine`) become image lines
measured by points (:func:`photogram.track.ski_axes.sample_axis`); eq.
(C11) of the ski-jump paper is then fitted to these points by
:func:`photogram.lines.views.fit_view_line`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photogram.track.lm import LMResult, robust_lm  # noqa: F401  (re-exported)
from photogram.track.ski_axes import BarLine, _sample
from photogram.track.ski_bars import (  # noqa: F401  (_model, _model_jacobian for the tests)
    _BLUR, _G, _PER_SKI, _W, _model, _model_jacobian, _PairResiduals, _PairTerms, _xy1)

__all__ = ["PairFit", "best_split", "fit_ski_pair", "robust_lm", "LMResult"]


@dataclass
class PairFit:
    """Result of :func:`fit_ski_pair`: the two axes (in the order of the
    initial lines), the RMS residual, the share of masked pixels and a
    success flag with its reason."""

    lines: list
    rms: float
    masked: float
    ok: bool
    reason: str = ""
    n_pixels: int = 0


def _grow(mask):
    """``mask`` grown by one pixel (4-neighbours): scipy.ndimage's
    ``binary_dilation(mask, iterations=1)`` with its default cross, without
    its per-call overhead (these masks are a few thousand pixels)."""
    out = mask.copy()
    out[1:] |= mask[:-1]
    out[:-1] |= mask[1:]
    out[:, 1:] |= mask[:, :-1]
    out[:, :-1] |= mask[:, 1:]
    return out


# the solver's relative cost change to stop at (robust_lm's ftol); the fits
# whose masks are then changed only decide which pixels the next one uses
# and stop at _FTOL_MASK, the fit on the final mask at _FTOL
_FTOL, _FTOL_MASK = 1e-6, 1e-4


def _to_bar(theta, k, ref, u0, cov):
    ang, c, a, b = theta[k * _PER_SKI:(k + 1) * _PER_SKI]
    ca, sa = np.cos(ang), np.sin(ang)
    u = np.array([u0[0] * ca - u0[1] * sa, u0[0] * sa + u0[1] * ca])
    n0 = np.array([-u0[1], u0[0]])
    p = ref + c * n0
    # (angle, shift along n0 at ref) -> (angle, shift across the axis at p):
    # p does not move with the angle; a shift c along n0 is c cos(ang) across
    i = k * _PER_SKI
    C = cov[np.ix_([i, i + 1], [i, i + 1])] if cov is not None else np.full((2, 2), np.nan)
    J = np.array([[1.0, 0.0], [0.0, ca]])
    return BarLine(p, u, np.array([a, b]), float(theta[_W]), float(theta[_G]), J @ C @ J.T)


@dataclass
class _Window:
    """Pixels of the band around two predicted axes (bounding box arrays)."""

    xx: np.ndarray
    yy: np.ndarray
    img: np.ndarray          # background - frame
    bg: np.ndarray
    frame: np.ndarray
    band: np.ndarray         # usable pixels of the box
    ref: np.ndarray
    u0: np.ndarray
    G0: float                # the skis' grey from their tail halves
    bg_median: float         # median background of the band

    def suit(self, G, level):
        """The suit: darker than the ski (grey ``G``) by ``level`` or a
        quarter of the ski's contrast, grown by one pixel."""
        margin_g = max(level, 0.25 * (self.bg_median - G))
        return _grow(self.band & (self.frame < G - margin_g))


def _window(frame, background, initial, margin, exclude, mask_level, sigma_noise,
            body_gap=None):
    bgi = np.asarray(background, dtype=float)
    frame = np.asarray(frame, dtype=float)
    H, W = frame.shape
    l1, l2 = initial
    ref = (l1.point + l2.point) / 2
    u0 = l1.direction + l2.direction
    u0 = u0 / np.linalg.norm(u0)
    # band: pixels near either predicted axis, between the ends (+margin)
    ends = np.array([l.point + e * l.direction for l in initial for e in l.ends])
    lo = np.maximum(np.floor(ends.min(0) - margin).astype(int), 0)
    hi = np.minimum(np.ceil(ends.max(0) + margin).astype(int), [W - 1, H - 1])
    if np.any(hi - lo < 3):
        return None
    yy, xx = np.mgrid[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1].astype(float)
    band = np.zeros(xx.shape, bool)
    for l in initial:
        rel = np.stack([xx - l.point[0], yy - l.point[1]], -1)
        t = rel @ l.direction
        d = rel @ l.normal
        band |= (np.abs(d) <= margin) & (t >= l.ends[0] - margin) & (t <= l.ends[1] + margin)
    fr = frame[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1]
    bgw = bgi[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1]
    img = bgw - fr
    # the body, whatever its grey: dark pixels away from both predicted axes
    # (by more than half a width + body_gap), grown by one pixel
    if body_gap is not None:
        near = np.zeros(xx.shape, bool)
        for l in initial:
            rel = np.stack([xx - l.point[0], yy - l.point[1]], -1)
            near |= np.abs(rel @ l.normal) <= l.width / 2 + body_gap
        level = max(mask_level * sigma_noise, 0.3 * np.percentile(img[band], 95))
        band &= ~_grow(band & (img > level) & ~near)
    # bright things (reflective markers, patches) and the given discs
    band &= ~_grow(img < -mask_level * sigma_noise)
    for c, r in exclude:
        band &= (xx - c[0]) ** 2 + (yy - c[1]) ** 2 > r * r
    tails = [l.point + np.linspace(l.ends[0], 0.0, 12)[:, None] * l.direction
             for l in initial]
    G0 = float(np.median(_sample(frame, np.concatenate(tails))))
    return _Window(xx, yy, img, bgw, fr, band, ref, u0, G0, float(np.median(bgw[band])))


def _axes_parameters(lines, ref, u0):
    """Angle, shift along the reference normal and ends of each axis
    relative to (ref, u0): the first 8 parameters of the model."""
    n0 = np.array([-u0[1], u0[0]])
    out = []
    for l in lines:
        ang = np.arctan2(u0[0] * l.direction[1] - u0[1] * l.direction[0], u0 @ l.direction)
        # the axis meets the line ref + c n0 at c (the new point on the axis)
        c = ((l.point - ref) @ l.normal) / (n0 @ l.normal)
        shift = (l.point - (ref + c * n0)) @ l.direction
        out += [ang, c, l.ends[0] + shift, l.ends[1] + shift]
    return np.array(out)


def best_split(frame, background, initial, *, sigma_noise: float, span_deg: float = 8.0,
               step_deg: float = 1.0, width: float = 1.5, blur: float = 0.7,
               mask_level: float = 4.0, exclude=()):
    """The two axes' directions by a grid search: each predicted axis is
    turned about its point by -span..span (deg) and every pair scored by
    the soft-L1 cost of eq. (2) with a fixed width, blur and grey (from the
    tails). For the first exposure, where the two skis are not yet told
    apart. Returns the turned pair (list of BarLine)."""
    margin = span_deg / 57.3 * max(l.length for l in initial) / 2 + 4
    win = _window(frame, background, initial, margin, exclude, mask_level, sigma_noise)
    if win is None:
        return list(initial)
    use = win.band & ~win.suit(win.G0, mask_level * sigma_noise)
    x, y, v, bv = win.xx[use], win.yy[use], win.img[use], win.bg[use]
    turns = np.arange(-span_deg, span_deg + 1e-9, step_deg)
    cand = [[BarLine(l.point, _turn(l.direction, t), l.ends, width, win.G0) for t in turns]
            for l in initial]
    # eq. (1) of the k-th turn of both axes at once: (turns, 2, n)
    X3 = _xy1(x, y)
    cov = np.stack([_PairTerms(np.r_[_axes_parameters([c1, c2], win.ref, win.u0),
                                     width, win.G0, blur], X3, win.ref, win.u0).C
                    for c1, c2 in zip(*cand)])
    c1, c2 = cov[:, 0, None, :], cov[None, :, 1, :]
    r = (bv - win.G0) * (c1 + c2 - c1 * c2) - v
    z2 = (r / (3 * sigma_noise)) ** 2
    cost = (np.sqrt(1 + z2) - 1).sum(-1)
    i, j = np.unravel_index(np.argmin(cost), cost.shape)
    return [cand[0][i], cand[1][j]]


def _turn(u, deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([c * u[0] - s * u[1], s * u[0] + c * u[1]])


def fit_ski_pair(frame, background, initial, *, sigma_noise: float, margin: float = 5.0,
                 mask_level: float = 4.0, iterations: int = 3, blur: float = 0.7,
                 body_gap: float | None = 2.5, max_turn_deg: float = 3.0,
                 max_shift: float = 4.0, exclude=()) -> PairFit:
    """Fit two dark bars (eqs. (1), (2) of the module docstring) in a band
    around two predicted axes.

    Parameters
    ----------
    frame : ndarray (H, W)
        The image.
    background : ndarray (H, W)
        Its background (nothing moving): ``D = background - frame``.
    initial : pair of BarLine
        Predicted axes with ends and widths (``contrast``: the ski's grey,
        may be nan: taken from the image).
    sigma_noise : float
        Image noise (grey levels), :func:`photogram.track.ski_axes.noise_sigma`.
    margin : float
        Half-width of the band around the predicted axes and the margin
        beyond their ends (px).
    mask_level : float
        Pixels darker than the model by more than this many noise sigmas
        (and by a fifth of the ski contrast) are masked, with a one-pixel
        margin, and the fit repeated up to ``iterations`` times (a fit whose
        mask then changes stops at a relative cost change of 1e-4, the fit
        on the final mask at 1e-6); so are
        pixels darker than the ski grey (the suit) and brighter than the
        background by this many sigmas (markers).
    blur : float
        Initial edge blur (px).
    body_gap : float or None
        Dark pixels farther than half a ski width plus this from both
        predicted axes are the body (a suit lighter than the skis is not
        caught by the grey rule): masked with a one-pixel margin. None:
        off.
    max_turn_deg, max_shift : float
        Bounds of each axis' turn (deg) and shift (px) from its prediction.
    exclude : iterable of (xy, radius)
        Discs of pixels left out (e.g. the binding markers drawn over the
        skis).

    Returns
    -------
    PairFit
    """
    win = _window(frame, background, initial, margin, exclude, mask_level, sigma_noise,
                  body_gap)
    if win is None:
        return PairFit(list(initial), np.nan, 1.0, False, "outside the image")
    xx, yy, img, bgw, fr, band = win.xx, win.yy, win.img, win.bg, win.frame, win.band
    ref, u0 = win.ref, win.u0
    theta0 = _axes_parameters(initial, ref, u0)
    G = np.nanmean([l.contrast for l in initial]) if np.isfinite(
        [l.contrast for l in initial]).any() else win.G0
    w = np.mean([l.width for l in initial])
    theta0 = np.concatenate([theta0, [np.clip(w, 1.0, 12.0), np.clip(G, 1.0, 254.0), blur]])
    # bounds: turn, shift and ends near the prediction; the grey within half
    # the predicted contrast (else the fit may take the suit for a ski)
    da, dc = np.radians(max_turn_deg), max_shift
    de = np.array([0.25 * l.length + 3.0 for l in initial])
    contrast = max(win.bg_median - theta0[_G], 5 * sigma_noise)
    lower = np.array([-da, -dc, -de[0], -de[0], -da, -dc, -de[1], -de[1],
                      0.3, -0.5 * contrast, 0.3])
    upper = np.array([da, dc, de[0], de[0], da, dc, de[1], de[1],
                      15.0, 0.5 * contrast, 3.0])
    lower[:_G + 1] += theta0[:_G + 1]
    upper[:_G + 1] += theta0[:_G + 1]
    lower[_W] = 0.3
    upper[_W] = 15.0
    theta0 = np.clip(theta0, lower + 1e-9, upper - 1e-9)

    def suit(G):
        return win.suit(G, mask_level * sigma_noise)

    use = band & ~suit(theta0[_G])
    theta = theta0
    res = None
    for it in range(iterations):
        x, y, v, bv = xx[use], yy[use], img[use], bgw[use]
        if len(v) < 20:
            return PairFit(list(initial), np.nan, 1.0, False, "no pixels left in the band")
        problem = _PairResiduals(x, y, bv, v, ref, u0)
        last = it == iterations - 1
        res = robust_lm(problem.fun, problem.jac, theta, lower, upper, f_scale=3 * sigma_noise,
                        max_iter=60, xtol=1e-5, ftol=_FTOL if last else _FTOL_MASK)
        theta = res.x
        A = np.median(bgw[use]) - theta[_G]
        dark = np.zeros_like(band)
        dark[band] = (img[band] - _model(theta, xx[band], yy[band], bgw[band], ref, u0)
                      > max(mask_level * sigma_noise, 0.2 * A))
        new = band & ~_grow(dark) & ~suit(theta[_G])
        if np.array_equal(new, use):
            if not last and _FTOL_MASK > _FTOL:
                # the mask is final: converge fully from here
                res = robust_lm(problem.fun, problem.jac, theta, lower, upper,
                                f_scale=3 * sigma_noise, max_iter=60, xtol=1e-5, ftol=_FTOL)
                theta = res.x
            break
        use = new
    # covariance of the parameters (Gauss-Newton, unit weights scaled by the
    # robust residual variance of the used pixels)
    r = res.fun
    s2 = (1.4826 * np.median(np.abs(r))) ** 2 + 1e-12
    J = res.jac
    try:
        cov = s2 * np.linalg.pinv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = None
    lines = [_to_bar(theta, k, ref, u0, cov) for k in (0, 1)]
    # support: area of each bar in used pixels, not covered by the other
    x, y = xx[use], yy[use]
    cs = _PairTerms(theta, _xy1(x, y), ref, u0).C
    for k, l in enumerate(lines):
        area = max(theta[_W], 1.0) * max(l.length, 1.0)
        l.support = float(np.sum(cs[k] * (1 - cs[1 - k])) / area)
    rms = float(np.sqrt(np.mean(r ** 2)))
    masked = float(1.0 - use.sum() / max(band.sum(), 1))
    ok, reason = True, ""
    bmed = np.median(bgw[use])
    for k, l in enumerate(lines):
        if bmed - l.contrast < 5 * sigma_noise:
            ok, reason = False, (f"ski {k + 1}: contrast {bmed - l.contrast:.3g} below 5 "
                                 "noise sigmas")
        elif l.length < 5:
            ok, reason = False, f"ski {k + 1}: {l.length:.3g} px long"
    if ok and res.status < 0:
        ok, reason = False, f"fit failed ({res.message})"
    return PairFit(lines, rms, masked, ok, reason, int(use.sum()))
