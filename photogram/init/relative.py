"""Relative orientation of a stereo pair.

Frames (see :mod:`photogram.project.model`): ``Xc = R (X - X0)``, the
photogrammetric camera frame (x right, y up, looking along -z), image
coordinates with y down. The model frame of a relative orientation is the
camera frame of the left image: ``R1 = I``, ``X0_1 = 0``; the right station
has ``R2`` and ``X0_2 = b`` with the baseline scaled to ``|b_x| = 1``
("dependent" relative orientation).

Coplanarity condition. With the image rays in the model frame

    p1 = (x̄1, -ȳ1, -c1),   p2 = R2^T (x̄2, -ȳ2, -c2)

the rays and the baseline are coplanar, ``b · (p1 × p2) = 0``, i.e.

    p2_cam^T E p1 = 0,   E = R2 [b]x                                     (1)

(``p2_cam = R2 p2``). In the computer-vision camera frame (y down, z
forward: ``Xcv = D Xc``, ``D = diag(1, -1, -1)``) the normalized image
coordinates are simply ``(x̄/c, ȳ/c)``, the rotation ``R_cv = D R2 D`` and
the translation ``t_cv = -D R2 b``, so the essential matrix of the
computer-vision literature, ``E_cv = [t_cv]x R_cv``, is ``-D R2 [b]x D``.

The closed-form starts (normalized 8-point and 5-point essential matrix,
homography of a planar scene, chirality) are in
:mod:`photogram.init.relative_start`; the refinement of each start (the
bundle adjustment of the pair by variable projection, with the model points
as unknowns) in :mod:`photogram.init.relative_refine`. This module tries
every start, chooses the best distinct solution, tests for a zero baseline
and ambiguity, and re-exports the closed-form functions.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from photogram.errors import GeometryError
from photogram.geometry.rotations import matrix_to_opk
from photogram.init.rays import bearings, max_intersection_angles
from photogram.init.relative_refine import _precision, _refine, _same
from photogram.init.relative_start import (  # noqa: F401  (FLIP and the closed forms: re-exports)
    FLIP, _distinct, _starts, decompose_essential, eight_point, essential_candidates,
    homography_candidates, rotation_only_fit, sampson_errors,
)

__all__ = ["RelativeOrientationResult", "relative_orientation", "essential_candidates",
           "homography_candidates", "eight_point", "decompose_essential", "sampson_errors",
           "rotation_only_fit"]


@dataclass
class RelativeOrientationResult:
    """A relatively oriented stereo pair (model frame = left camera frame).

    Attributes
    ----------
    R2 : ndarray (3, 3)
        World(model)-to-camera rotation of the right station.
    angles2 : ndarray (3,)
        Its omega-phi-kappa (radians).
    X0_2 : ndarray (3,)
        Right projection centre = baseline ``b``, scaled so that
        ``|b[fixed_component]| = 1`` (normally ``|b_x| = 1``).
    X : ndarray (n, 3)
        Model points.
    residuals1, residuals2 : ndarray (n, 2)
        Image residuals ``observed - computed`` in the left and right image.
    sigma0 : float
        A-posteriori sigma of an image coordinate,
        ``sqrt(v^T v / (4n - 3n - 5))`` (NaN for n = 5).
    covariance : ndarray (5, 5)
        Of ``(δx, δy, δz, b_j, b_k)`` (rotation increment, radians; the two
        free baseline components), scaled by ``sigma_image^2`` if given, else
        by ``sigma0^2``.
    sigma_X : ndarray (n, 3)
        Standard deviations of the model points (same scale).
    max_angle : ndarray (n,)
        Intersection angle of each point's two rays (radians).
    fixed_component : int
        Baseline component held at ±1 (0 = x).
    rotation_only_rms : float
        RMS image residual (image units) of the best pure-rotation fit, the
        parallax left for the baseline to explain.
    iterations : int
    converged : bool
    ambiguous : bool
        True when the solution may not be unique: only 5 points, or another
        candidate fitting as well (e.g. a planar scene).
    candidates : int
        Number of distinct refined candidates with all points in front.
    alternatives : list of (R2, X0_2, sigma0)
        The other distinct candidates that fit (almost) as well as the
        chosen one (see ``ambiguous``), best first.
    notes : list of str
    """

    R2: np.ndarray
    angles2: np.ndarray
    X0_2: np.ndarray
    X: np.ndarray
    residuals1: np.ndarray
    residuals2: np.ndarray
    sigma0: float
    covariance: np.ndarray
    sigma_X: np.ndarray
    max_angle: np.ndarray
    fixed_component: int
    rotation_only_rms: float
    iterations: int
    converged: bool
    ambiguous: bool
    candidates: int
    alternatives: list = field(default_factory=list)
    notes: list = field(default_factory=list)

    @property
    def baseline(self) -> np.ndarray:
        """Alias of ``X0_2``."""
        return self.X0_2


def relative_orientation(xy1_ideal, xy2_ideal, c1, c2, *, x0y0_1=None, x0y0_2=None,
                         sigma_image: float | None = None, fixed_component: int | None = 0,
                         parallax_factor: float = 3.0, max_iterations: int = 100,
                         tol: float = 1e-12, warn: bool = True) -> RelativeOrientationResult:
    """Relative orientation of a stereo pair from homologous image points.

    Closed-form start from the essential matrix (normalized 8-point or
    5-point algorithm, see :func:`essential_candidates`), disambiguated by
    chirality; then least squares of the image residuals of both images
    with the model points as unknowns (the coplanarity condition (1) in its
    Gauss-Helmert form), with the left camera at ``(I, 0)`` and the baseline
    component ``b_x`` held at ±1. Every candidate with all points in front
    of both cameras is refined; the smallest sum of squared residuals wins.

    Parameters
    ----------
    xy1_ideal, xy2_ideal : array_like (n, 2)
        Ideal (distortion-free) image coordinates of the same n >= 5 points
        in the left and right image, reduced to the principal point unless
        ``x0y0_1`` / ``x0y0_2`` are given.
    c1, c2 : float
        Principal distances (image units).
    x0y0_1, x0y0_2 : array_like (2,), optional
        Principal points to subtract.
    sigma_image : float, optional
        A-priori sigma of an image coordinate: scales the covariance and is
        the noise level of the zero-baseline test.
    fixed_component : int or None
        Baseline component held at ±1 (0: ``b_x``, the classical dependent
        relative orientation). ``None`` or a component that is less than a
        fifth of the baseline length (e.g. ``b_x`` of a vertical baseline)
        selects the largest component instead (noted in ``notes``).
    parallax_factor : float
        Zero-baseline test: the pair is rejected when the best pure
        rotation explains the images to within ``parallax_factor`` times
        the noise (``sigma_image``, or the relative orientation's own
        ``sigma0``).
    max_iterations, tol :
        Iteration control of the refinement.
    warn : bool
        Emit :class:`UserWarning` when the solution may be ambiguous.

    Returns
    -------
    RelativeOrientationResult

    Raises
    ------
    GeometryError
        Fewer than 5 points; non-finite input; zero baseline (pure rotation
        between the images, no parallax); no candidate with the points in
        front of both cameras.

    Warns
    -----
    UserWarning
        With exactly 5 points (up to 10 solutions of which chirality may not
        single out one) or when two distinct solutions fit equally well
        (e.g. a planar scene).
    """
    xy1 = np.asarray(xy1_ideal, dtype=float)
    xy2 = np.asarray(xy2_ideal, dtype=float)
    if xy1.ndim != 2 or xy1.shape[1:] != (2,) or xy1.shape != xy2.shape:
        raise GeometryError(
            f"relative orientation needs two (n, 2) arrays of homologous image points, "
            f"got {xy1.shape} and {xy2.shape}")
    n = len(xy1)
    if n < 5:
        raise GeometryError(
            f"relative orientation needs at least 5 homologous points, got {n}",
            hint="a relative orientation has 5 unknowns; measure 6 or more "
                 "points common to both images (8 or more for a unique linear start)")
    if x0y0_1 is not None:
        xy1 = xy1 - np.asarray(x0y0_1, dtype=float)
    if x0y0_2 is not None:
        xy2 = xy2 - np.asarray(x0y0_2, dtype=float)
    c1, c2 = float(c1), float(c2)
    if not (np.isfinite(xy1).all() and np.isfinite(xy2).all()):
        raise GeometryError("relative orientation: image coordinates contain NaN or inf")
    if not (c1 > 0 and c2 > 0):
        raise GeometryError(f"relative orientation: principal distances must be positive, "
                            f"got {c1:g} and {c2:g}")
    notes: list[str] = []
    c_mean = 0.5 * (c1 + c2)

    # zero baseline: a pure rotation explains everything
    _, rms_rot = rotation_only_fit(xy1, xy2, c1, c2)
    floor = 1e-9 * c_mean
    if sigma_image is not None:
        floor = max(floor, parallax_factor * float(sigma_image))
    if rms_rot <= floor:
        raise GeometryError(
            f"relative orientation: zero baseline; a pure rotation fits the "
            f"{n} points to {rms_rot:.3g} (image units), there is no parallax",
            hint="the two images were taken from (nearly) the same position; "
                 "use a pair with a wider baseline")

    thr = 3.0 * float(sigma_image) / c_mean if sigma_image is not None else 1e-3
    starts = _starts(xy1, xy2, c1, c2, thr)

    # a few iterations for every start, then only the distinct ones to the end
    short = []
    for R2, b, X in _distinct(starts):             # loop over candidate solutions
        bad = ~np.isfinite(X).all(1)
        if bad.any():
            X[bad] = -np.array([0.0, 0.0, 1.0]) * 10.0 * np.linalg.norm(b)
        short.append(_refine(xy1, xy2, c1, c2, R2, b, X, fixed_component,
                             min(3, max_iterations), tol))
    short.sort(key=lambda f: (f.behind > 0, f.cost))
    s2_short = float(sigma_image) ** 2 if sigma_image is not None else \
        (short[0].cost / (n - 5) if n > 5 else 0.0)
    floor = 1e-20 * c_mean ** 2 * n
    kept: list = []
    for f in short:
        # only starts that may end as (distinct) equally good solutions go on:
        # not in the same basin as a kept one (10 sigma), and with a sum of
        # squares already within the tie margin of the best start
        if kept and (f.cost - short[0].cost > 9.0 * s2_short + floor or f.behind):
            continue
        if not any(_same(f, g, s2_short, floor, tol=0.05, k=10.0) for g in kept):
            kept.append(f)
    fits = []
    for j, st in enumerate([(f.R2, f.b, f.X) for f in kept]):
        # the most promising start gets the full budget, the others (which
        # only matter if they reach an equally good, distinct solution) 20
        budget = max_iterations if j == 0 else min(max_iterations, 20)
        f = _refine(xy1, xy2, c1, c2, *st, fixed_component, budget, tol)
        fits.append((f, f.k_fixed))
    dof = n - 5
    finite = [fk for fk in fits if np.isfinite(fk[0].cost)]
    if finite and sigma_image is None and dof > 0:
        # zero baseline, judged against the noise level the data show
        s_best = float(np.sqrt(min(f.cost for f, _ in finite) / dof))
        if rms_rot <= parallax_factor * s_best:
            raise GeometryError(
                f"relative orientation: zero baseline; a pure rotation fits the "
                f"{n} points to {rms_rot:.3g} (image units), not much worse than the "
                f"relative orientation ({s_best:.3g}): no usable parallax",
                hint="the two images were taken from (nearly) the same position; "
                     "use a pair with a wider baseline")
    good = [(f, k) for f, k in finite if f.behind == 0]
    if not good:
        worst = sorted(finite, key=lambda fk: (fk[0].behind, fk[0].cost))[:1]
        if not worst or worst[0][0].behind > max(1, n // 10):
            raise GeometryError(
                f"relative orientation: no solution puts the {n} points in front of both "
                f"cameras",
                hint="check the point correspondences, the principal distances and the "
                     "image y axis (down)")
        good = worst
        notes.append(f"{good[0][0].behind} point(s) behind a camera after refinement")
    good.sort(key=lambda fk: fk[0].cost)
    fit, k_fixed = good[0]
    # other solutions that fit as well
    # an alternative "fits as well" when it converged to a solution that is
    # distinct from the best one by more than 5 sigma (Mahalanobis distance
    # with the best one's normal matrix) and its sum of squares exceeds the
    # best one's by less than a 3-sigma margin
    s2 = float(sigma_image) ** 2 if sigma_image is not None else \
        (fit.cost / dof if dof > 0 else 0.0)
    floor = 1e-20 * c_mean ** 2 * n
    distinct_good = [good[0]]
    for f, k in good[1:]:
        if f.converged and not any(_same(f, g, s2, floor) for g, _ in distinct_good):
            distinct_good.append((f, k))
    tie = [f for f, _ in distinct_good[1:] if f.cost - fit.cost <= 9.0 * s2 + floor]
    sigma0 = float(np.sqrt(fit.cost / dof)) if dof > 0 else float("nan")
    if fit.k_fixed != fixed_component:
        notes.append(f"baseline component {'xyz'[fit.k_fixed]} held at ±1 "
                     f"(b_{'xyz'[fixed_component] if fixed_component is not None else 'x'}"
                     f" is small)")
    ambiguous = False
    if n == 5:
        ambiguous = True
        notes.append("5 points: the relative orientation may be ambiguous "
                     "(up to 10 solutions); measure more points")
    if tie:
        ambiguous = True
        notes.append(f"{len(tie) + 1} distinct solutions fit equally well "
                     "(critical configuration, e.g. all points on a plane)")
    if ambiguous and warn:
        warnings.warn("relative orientation may be ambiguous: " + "; ".join(
            m for m in notes if "ambig" in m or "distinct" in m), UserWarning, stacklevel=2)

    scale2 = float(sigma_image) ** 2 if sigma_image is not None else \
        (sigma0 ** 2 if np.isfinite(sigma0) else np.nan)
    cov, sigma_X = _precision(fit, scale2, n)
    angles2 = np.asarray(matrix_to_opk(fit.R2), dtype=float)
    d1 = bearings(xy1, c1)
    d2 = bearings(xy2, c2) @ fit.R2                           # R2^T d2 (rows)
    ang = max_intersection_angles(np.repeat(np.arange(n), 2),
                                  np.stack([d1, d2], axis=1).reshape(-1, 3), n)
    return RelativeOrientationResult(
        R2=fit.R2, angles2=angles2, X0_2=fit.b, X=fit.X, residuals1=fit.r1,
        residuals2=fit.r2, sigma0=sigma0, covariance=cov, sigma_X=sigma_X,
        max_angle=ang, fixed_component=k_fixed, rotation_only_rms=rms_rot,
        iterations=fit.iterations, converged=fit.converged, ambiguous=ambiguous,
        candidates=len(distinct_good),
        alternatives=[(f.R2, f.b, float(np.sqrt(f.cost / dof)) if dof > 0 else float("nan"))
                      for f in tie], notes=notes)
