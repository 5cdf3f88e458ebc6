"""Guided measurement: measure where the layout says a target must be.

After the numbering of an image (:mod:`photogram.measure.label`) the
plane's homography predicts every target of the field that was not found,
**as an ellipse**: the image of the circle of the field's diameter
(``C' = H^-T C H^-1``). The subpixel edge fit of
:func:`photogram.measure.centre.edge_ellipse` is started from that ellipse,
without any segmentation, so a target is also measured when its blob
merged with a neighbour (a small coded target's dot with its ring in an
oblique view), was split by noise or fell below the threshold. A guided
measurement is kept when

* the fit converged with a small residual and enough contrast,
* its centre is within ``gate`` times the local spacing of the prediction
  and its axes within a factor 0.6-1.6 of the predicted ones,
* no accepted detection lies on it already, and
* for a coded target, its ring does not decode to anything else (the
  right code, or an unreadable ring).

The homography is fitted again with the new points and the prediction
repeated (the "predict again to add what was missed" of the issue, here
per image with the plane homography; a prediction from a bundle
adjustment of all images is the next step, docs/measure.md).
"""

from __future__ import annotations

import numpy as np

from photogram.measure.centre import edge_ellipse
from photogram.measure.codes import decode_rings, ring_profiles
from photogram.measure.detect import Detections
from photogram.measure.ellipse import conic_axes, conic_centre, conic_from_matrix

__all__ = ["circle_images", "guided_measure"]


def circle_images(H: np.ndarray, XY: np.ndarray, radius: float):
    """Image ellipses of circles in a plane: centres (n, 2), semi-axes
    (n, 2, major first), angles (n,) of the major axis; NaN where the
    image is no ellipse (the circle crosses the vanishing line)."""
    Hi = np.linalg.inv(H)
    n = len(XY)
    c = np.full((n, 2), np.nan)
    ax = np.full((n, 2), np.nan)
    ang = np.full(n, np.nan)
    for k, (X, Y) in enumerate(np.asarray(XY, float)):
        C = np.array([[1, 0, -X], [0, 1, -Y], [-X, -Y, X * X + Y * Y - radius * radius]])
        conic = conic_from_matrix(Hi.T @ C @ Hi)
        try:
            c[k] = conic_centre(conic)
        except np.linalg.LinAlgError:
            continue
        A, B, th = conic_axes(conic)
        ax[k] = A, B
        ang[k] = th
    return c, ax, ang


def _append(det: Detections, fit: dict, idx: np.ndarray) -> Detections:
    cat = np.concatenate
    extra = dict(det.extra)
    extra["background"] = cat([det.extra["background"], fit["background"][idx]])
    extra["guided"] = cat([det.extra.get("guided", np.zeros(len(det), bool)),
                           np.ones(len(idx), bool)])
    if "marker" in extra:
        extra["marker"] = cat([extra["marker"], np.zeros(len(idx), bool)])
    return Detections(cat([det.xy, fit["xy"][idx]]),
                      cat([det.xy_centroid, np.full((len(idx), 2), np.nan)]),
                      cat([det.axes, fit["axes"][idx]]), cat([det.angle, fit["angle"][idx]]),
                      cat([det.contrast, fit["contrast"][idx]]),
                      cat([det.residual, fit["residual"][idx]]),
                      cat([det.sigma, fit["sigma"][idx]]), cat([det.n_edge, fit["n_edge"][idx]]),
                      det.rejected_xy, det.rejected_reason, det.image_size, extra)


def guided_measure(t: np.ndarray, det: Detections, labels: np.ndarray, code_label: np.ndarray,
                   H: np.ndarray, fld, *, gate: float = 0.3, max_residual: float = 0.5,
                   rounds: int = 2):
    """Add guided measurements of the field's missing targets (module doc).

    Parameters
    ----------
    t : image with bright targets (float32)
    det, labels, code_label : the detections of the image, their numbers
        ("" none) and decoded codes
    H : plane -> image homography of the numbering
    fld : the :class:`~photogram.measure.field.TargetField`

    Returns
    -------
    det, labels, code_label, H : extended (new detections appended) and the
        homography fitted to all numbered targets
    """
    import cv2
    ids, XY = fld.layout(markers=False)          # circles only: markers are not guided
    all_ids, all_XY = fld.layout()
    pos = {k: i for i, k in enumerate(all_ids)}
    code_ids = {c.id for c in fld.codes}
    h, w = t.shape
    r = fld.diameter / 2
    for _ in range(rounds):
        have = {v for v in labels if v}
        miss = np.array([i for i, k in enumerate(ids) if k not in have], int)
        if len(miss) == 0:
            break
        c, ax, ang = circle_images(H, XY[miss], r)
        q = np.column_stack([XY[miss], np.ones(len(miss))]) @ H.T
        qx = np.column_stack([XY[miss] + [fld.spacing or 4 * r, 0], np.ones(len(miss))]) @ H.T
        local = np.linalg.norm(qx[:, :2] / qx[:, 2:] - q[:, :2] / q[:, 2:], axis=1)
        reach = np.where([ids[i] in code_ids for i in miss], 4.5, 1.6) * ax[:, 0]
        ok = (np.isfinite(c).all(axis=1) & np.isfinite(ax).all(axis=1)
              & (2 * ax[:, 0] >= fld.min_diameter) & (2 * ax[:, 0] <= fld.max_diameter)
              & (c[:, 0] - reach > 1) & (c[:, 1] - reach > 1)
              & (c[:, 0] + reach < w - 2) & (c[:, 1] + reach < h - 2))
        if len(det):
            near = np.linalg.norm(c[:, None] - det.xy[None], axis=2).min(axis=1)
            ok &= ~(near < np.maximum(ax[:, 1], 1.0))       # something is measured there
        sel = np.nonzero(ok)[0]
        if len(sel) == 0:
            break
        fit = edge_ellipse(t, c[sel], ax[sel, 0], ax[sel, 1], ang[sel])
        good = (fit["ok_edge"] & fit["ok_fit"] & (fit["residual"] <= max_residual)
                & (fit["contrast"] >= fld.min_contrast))
        with np.errstate(invalid="ignore"):
            good &= np.linalg.norm(fit["xy"] - c[sel], axis=1) <= gate * local[sel]
            ratio = fit["axes"] / ax[sel]
            good &= np.all((ratio > 0.6) & (ratio < 1.6), axis=1)
        new_codes = np.full(len(sel), "", dtype=object)
        is_code = np.array([ids[miss[i]] in code_ids for i in sel], bool)
        if (good & is_code).any():
            k = np.nonzero(good & is_code)[0]
            ring, inside, valid = ring_profiles(t, fit["xy"][k], fit["axes"][k], fit["angle"][k],
                                                fit["background"][k], fit["contrast"][k],
                                                radii=fld.code_radii)
            lab, _ = decode_rings(ring, inside, valid, fld.codes)
            for kk, lb in zip(k, lab):
                want = ids[miss[sel[kk]]]
                if lb is None or lb == want:
                    new_codes[kk] = want
                else:
                    good[kk] = False
        idx = np.nonzero(good)[0]
        if len(idx) == 0:
            break
        det = _append(det, fit, idx)
        labels = np.concatenate([labels, np.array([ids[miss[sel[i]]] for i in idx], object)])
        code_label = np.concatenate([code_label, new_codes[idx]])
        num = np.array([bool(v) and v in pos for v in labels])
        P = all_XY[[pos[v] for v in labels[num]]]
        H2, _ = cv2.findHomography(P.astype(np.float64), det.xy[num].astype(np.float64), 0)
        if H2 is not None:
            H = H2
    return det, labels, code_label, H
