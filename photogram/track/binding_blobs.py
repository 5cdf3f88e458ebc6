"""The binding pair's blob in the images (steps 1-3 of
:mod:`photogram.track.bindings`, module doc): the candidates of a view that
may be the blob (:func:`blob_candidates`), the spot of a single marker per
station and exposure fitted to the ok single markers (:func:`spot_shapes`,
:func:`shape_near`), and the two-spot fit of a located blob with its
outcome (:func:`split_blob`). The spot models and their fits are in
:mod:`photogram.track.spots` and :mod:`photogram.track.two_spots`."""

from __future__ import annotations

import numpy as np

from photogram.track.markers import detect_markers
from photogram.track.spots import (_behind, _crop_around, _tophat, fit_spot_windows,
                                   spot_windows)
from photogram.track.two_spots import fit_two_spots, fit_two_spots_over

__all__ = []


def _as_background(b, frame):
    """(median (H, W) float, noise (H, W) float, Background or None)."""
    from photogram.track.background import Background
    if isinstance(b, Background):
        return b.median, b.noise, b
    med = np.asarray(b, np.float32)
    d = np.asarray(frame, np.float32) - med
    level = max(1.4826 * float(np.median(np.abs(d - np.median(d)))), 0.5)
    noise = np.full(med.shape, level, np.float32)
    return med, noise, Background(med, noise, level, 1)



def blob_candidates(cand, taken, min_flux):
    """The marker candidates ``cand`` (Candidates) of one view that may be
    the pair's blob (module doc, step 1): not on the ok single markers
    ``taken`` (n, 2) of the image (None: none) and, where some candidate is
    on one, at least ``min_flux`` of the flux and peak of those; (m, 2)."""
    c = cand.xy
    if taken is not None and len(c):
        dd = np.hypot(c[:, None, 0] - taken[None, :, 0], c[:, None, 1] - taken[None, :, 1])
        # as bright as a single marker of this image (the pair's blob
        # is one or two markers; gaps of snow and edges are fainter)
        mine = dd.min(1) <= 1.0
        keep = (dd > 2.0).all(1)
        if mine.any():
            keep &= (cand.flux >= min_flux * np.median(cand.flux[mine])) \
                & (cand.peak >= min_flux * np.median(cand.peak[mine]))
        c = c[keep]
    return c


def spot_shapes(frames, sing_ok, stations, when, eidx, *, half, tophat, pixel_offset):
    """The spot of a single marker (module doc, step 2) fitted in every
    exposure frame to the ok single markers ``sing_ok`` (rows of the marker
    table): per station (exposure indices (n,) by ``eidx``, shapes (n, 4))
    of the fits that succeeded; ``when[exposure][station]`` the frame."""
    shape_at = {}
    for s in stations:
        pos, wins = [], []
        for e, g in sing_ok[sing_ok.station == s].groupby("exposure"):
            f = when[e][s]
            if not 0 <= f < len(frames[s]):
                continue
            xy = g[["x", "y"]].to_numpy(float)
            crop, origin = _crop_around(frames[s][f], xy, half + tophat + 1, pixel_offset)
            wins.append(spot_windows(_tophat(crop, tophat), xy - origin, half=half,
                                     pixel_offset=pixel_offset))
            pos += [eidx[e]] * len(xy)
        # all windows of the station in one batched fit (each window's fit
        # is its own: the same shapes as one fit per exposure)
        sh = fit_spot_windows(*(np.concatenate(a) for a in zip(*wins)))[0] if wins \
            else np.zeros((0, 4))
        good = np.isfinite(sh).all(1)
        shape_at[s] = (np.asarray(pos, int)[good], sh[good].reshape(-1, 4))
    return shape_at


def shape_near(shape_at, i, window):
    """The spot's shape at exposure index ``i``: the median of the station's
    shapes ``shape_at`` within ``window`` exposures (NaN without any)."""
    near = np.abs(shape_at[0] - i) <= window
    return np.median(shape_at[1][near], axis=0) if near.any() \
        else np.full(4, np.nan)


def split_blob(fr, noise, med, centre, shape, *, spot_model, half, tophat, pixel_offset,
               sigma_floor, min_snr):
    """Two spots of ``shape`` fitted to the blob at ``centre`` (2,) of frame
    ``fr`` (module doc, step 3; ``noise`` and ``med`` the background's noise
    and median images; ``spot_model`` as
    :func:`photogram.track.bindings.split_merged_bindings`).

    Returns
    -------
    fit : dict
        Of :func:`photogram.track.two_spots.fit_two_spots` (or ``_over``),
        one blob, in frame coordinates.
    c : ndarray (2,)
        The blob's centre (``centre`` where the fit failed).
    csig : float
        Its sigma (NaN where the fit failed).
    measurable : bool
        The separation is above ``min_snr`` of its sigmas.
    outcome : str
        ``"split"``, or why not.
    """
    ij = np.clip(np.rint(centre - pixel_offset).astype(int), 0,
                 [fr.shape[1] - 1, fr.shape[0] - 1])
    sn = float(noise[ij[1], ij[0]])
    if spot_model == "composite":
        fit = fit_two_spots_over(fr, _behind(fr, med, tophat, sn), centre[None], shape,
                                 noise=sn, half=half,
                                 pixel_offset=pixel_offset, sigma_floor=sigma_floor)
    else:
        crop, origin = _crop_around(fr, centre[None], half + tophat + 1, pixel_offset)
        fit = fit_two_spots(_tophat(crop, tophat), (centre - origin)[None], shape,
                            noise=sn, half=half, pixel_offset=pixel_offset,
                            sigma_floor=sigma_floor)
        for k in ("centre", "points"):
            fit[k] = fit[k] + origin
    sep, ssig = fit["separation"][0], fit["sep_sigma"][0]
    measurable = np.isfinite(sep) and sep > min_snr * ssig
    c = fit["centre"][0]
    if not np.isfinite(c).all() or np.hypot(*(c - centre)) > 2.0:
        c, csig = centre, np.nan
        outcome = "fit failed"
        measurable = False
    else:
        csig = fit["centre_sigma"][0]
        outcome = "split" if measurable else \
            f"separation not measurable ({sep:.2f} px, sigma {ssig:.2f})"
    return fit, c, csig, measurable, outcome


def view_candidates(e, stations, when, frames, backgrounds, row, pair, singles_at, candidates,
                    *, k_sigma, pixel_offset, min_flux):
    """Per view, the candidates for the pair's blob at exposure ``e`` (module
    doc, step 1): the midpoint of the two bindings where both are ok, else
    the marker candidates (``candidates[station][frame]``, or detected
    again) kept by :func:`blob_candidates`; none where the frame is not in
    the video.

    Returns
    -------
    per_view : list of ndarray (m, 2)
        In ``stations`` order.
    imgs : dict station -> (frame, noise, median)
        The frame and its background's noise and median images.
    """
    per_view, imgs = [], {}
    right_m, left_m = pair
    for s in stations:
        f = when[e][s]
        if not 0 <= f < len(frames[s]):
            per_view.append(np.zeros((0, 2)))
            continue
        fr = frames[s][f]
        med, noise, bg = _as_background(backgrounds[s], fr)
        imgs[s] = (fr, noise, med)
        a, b = row(e, s, right_m), row(e, s, left_m)
        if a is not None and b is not None and a.status == "ok" and b.status == "ok":
            per_view.append(np.array([[(a.x + b.x) / 2, (a.y + b.y) / 2]]))
            continue
        cand = candidates[s][f] if candidates is not None else \
            detect_markers(fr, bg, k=k_sigma, pixel_offset=pixel_offset)
        per_view.append(blob_candidates(cand, singles_at.get((e, s)), min_flux))
    return per_view, imgs
