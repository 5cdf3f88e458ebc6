"""2D tracks of the markers in one camera, from one seed click per marker.

From the seed frame the tracker runs forwards to the last frame, then
backwards to the first. In every frame, for all markers at once:

1. **Prediction** from the marker's last (up to 5) positions in this
   direction: a least-squares polynomial in time, quadratic from 4
   positions (constant image acceleration: a ballistic flight is a parabola
   in the image up to perspective), linear from 2-3, constant from 1.
   Right after the seed the velocity is unknown: the jumper's markers move
   together, so the common displacement is found by voting (every
   candidate within ``max_speed`` of a seed proposes a displacement; the
   one that brings most seeds onto a candidate within ``vote_tol`` wins;
   a tie is no decision). The backward pass starts with the velocity of
   the forward pass.
2. **Gating**: candidates within ``gate + gate_growth * (frames since the
   last detection - 1)`` px of the prediction (Blackman & Popoli,
   *Design and Analysis of Modern Tracking Systems*, 1999, ch. 6: a
   validation gate that grows while the track coasts).
3. **Decision**, never a guess:

   - no candidate in the gate, or only ones fainter than ``low_flux``
     times the marker's typical flux: ``lost`` (the marker coasts on its
     prediction, for at most ``max_coast`` frames);
   - a second candidate in the gate nearly as close as the best one
     (closer than ``clear_ratio`` times and ``clear_margin`` px beyond
     the best distance): ``ambiguous``;
   - the best candidate is also the best of another marker (two markers
     merged into one blob), or much brighter than the marker so far
     (``merge_flux``), or elongated (``max_elongation``): ``ambiguous``
     (the blob, or the flux-weighted centre of the blobs in the gate,
     still carries the prediction on: two markers that image as one blob
     or as a pair of blobs stay tracked as a group, never labelled);
   - another blob of at least ``neighbour_flux`` times its flux within
     ``min_separation`` px of the chosen one (2-4 px discs that close
     overlap and pull each other's centres by tenths of a pixel):
     ``ambiguous``;
   - otherwise ``ok``.

Statuses per frame and marker: 0 ok, 1 lost, 2 ambiguous, with a reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import InputError
from photogram.stats.small_samples import median_of_few
from photogram.track.markers import Candidates

__all__ = ["TrackSettings", "Track2D", "track_station", "neighbour_distance", "OK", "LOST",
           "AMBIGUOUS", "STATUS", "scatter_sigma"]

OK, LOST, AMBIGUOUS = 0, 1, 2
STATUS = ("ok", "lost", "ambiguous")


@dataclass
class TrackSettings:
    """Tuning of the tracker (px unless noted); the defaults were set on
    the normal rendered set (benchmarks/track.py), never on the harsh one."""

    seed_radius: float = 5.0       # a seed click must be this close to a blob
    max_speed: float = 45.0        # px/frame: the search right after a seed
    vote_tol: float = 2.0          # px: a displaced seed meets a candidate
    gate: float = 4.0              # validation gate around the prediction
    gate_growth: float = 2.0       # px per frame the marker coasted
    max_coast: int = 5             # frames predicted without a blob, then lost for good
    clear_ratio: float = 2.0       # a second blob within ratio x best distance ...
    clear_margin: float = 2.0      # ... or best + margin px makes it ambiguous
    min_separation: float = 4.0    # px: a blob this close to another one is not ok ...
    neighbour_flux: float = 0.25   # ... if the other has this fraction of its flux
    merge_flux: float = 1.6        # flux / the marker's flux above: merged blobs
    low_flux: float = 0.4          # below: partly hidden
    max_elongation: float = 1.8    # RMS radius ratio above: merged blobs
    epipolar_tol: float = 3.0      # px: residual of a correct correspondence (less the bias)
    fill_gate: float = 2.0         # px: search radius at the 3D prediction (less the bias)
    ballistic_window: int = 6      # frames each side for the 3D prediction through gaps
    k_sigma: float = 5.0           # candidate threshold (DoG noise sigmas)
    max_offset: int = 10           # frames: sync offsets searched
    sync_tol: float = 1.0          # px: largest median epipolar distance of a sync offset
    pixel_offset: float = 0.5      # image frame: 0.5 photogram's (corner), 0 OpenCV's


@dataclass
class Track2D:
    """Per frame (F) and marker (M) of one camera: ``xy`` (F, M, 2) px,
    ``sigma`` (F, M), ``status`` (F, M) int8 (:data:`STATUS`), ``reason``
    (F, M) str, ``cand`` (F, M) the candidate index (-1 none), ``flux``
    (M,) the typical flux of each marker; ``notes`` what the user should
    know (a seed click that was not used)."""

    xy: np.ndarray
    sigma: np.ndarray
    status: np.ndarray
    reason: np.ndarray
    cand: np.ndarray
    flux: np.ndarray
    notes: list = field(default_factory=list)


def _predict(hist: list, t: int) -> np.ndarray:
    ts = np.array([h[0] for h in hist], float)
    ps = np.array([h[1] for h in hist])
    if len(hist) == 1:
        return ps[0]
    deg = 2 if len(hist) >= 4 else 1
    tt = ts - t
    V = np.vander(tt, deg + 1)
    coef, *_ = np.linalg.lstsq(V, ps, rcond=None)
    return coef[-1]                                   # the value at tt = 0


def neighbour_distance(c: Candidates, j: int, min_flux: float) -> float:
    """Distance (px) from candidate ``j`` to the nearest other candidate with
    at least ``min_flux`` times its flux (inf if none): a fainter one pulls
    the Gaussian-weighted centre by less than its flux ratio times its
    weight, negligible below a quarter of the flux at 3-4 px."""
    d = np.hypot(*(c.xy - c.xy[j]).T)
    d[j] = np.inf
    d[c.flux < min_flux * c.flux[j]] = np.inf
    return float(d.min(initial=np.inf))


def _vote(p0: np.ndarray, cand: Candidates, dt: int, s: TrackSettings):
    """Common displacement per frame of seeds ``p0`` (k, 2) onto ``cand``:
    (2,) or None when no clear winner."""
    if not len(cand):
        return None
    disp = (cand.xy[None, :, :] - p0[:, None, :]).reshape(-1, 2)
    disp = disp[np.hypot(*disp.T) <= s.max_speed * abs(dt)]
    if not len(disp):
        return None
    moved = p0[None, :, :] + disp[:, None, :]                            # (h, k, 2)
    dd = np.linalg.norm(moved[:, :, None, :] - cand.xy[None, None], axis=3)
    support = (dd.min(axis=2) < s.vote_tol).sum(axis=1)
    best = support.max()
    top = disp[support == best]
    # hypotheses within vote_tol of each other are one displacement
    if np.hypot(*(top - top[0]).T).max() > 2 * s.vote_tol:
        return None
    if best < min(2, len(p0)):
        return None
    return top.mean(axis=0) / dt


def track_station(cands: list[Candidates], seeds: dict, markers: list[str],
                  station: str = "", settings: TrackSettings | None = None) -> Track2D:
    """2D tracks of the markers in one camera (module doc).

    Parameters
    ----------
    cands : list of Candidates, one per frame
    seeds : dict marker -> (frame, (x, y))
        One click per marker (photogram image frame, px); markers without a
        seed stay ``lost`` ("no seed in this camera").
    markers : list of str
    station : str
        For the messages.

    Returns
    -------
    Track2D

    Raises
    ------
    InputError
        A seed more than ``seed_radius`` px from every candidate of its
        frame (naming station, frame, marker); when that holds for every
        seed of the camera, naming the camera (it sees no marker: a wrong
        or blank video).
    """
    s = settings or TrackSettings()
    F, M = len(cands), len(markers)
    xy = np.full((F, M, 2), np.nan)
    sig = np.full((F, M), np.nan)
    status = np.full((F, M), LOST, np.int8)
    reason = np.full((F, M), "no seed in this camera", dtype=object)
    cidx = np.full((F, M), -1, int)
    flux = np.full(M, np.nan)
    snapped, failed = {}, []
    for m, (f, p) in seeds.items():
        if m not in markers:
            raise InputError(f"seed for unknown marker {m!r} in {station}",
                             hint="markers: " + ", ".join(markers))
        if not 0 <= f < F:
            raise InputError(f"seed of {m} in {station}: frame {f} is not in the video "
                             f"(0..{F - 1})", hint="click in a frame of the video")
        c = cands[f]
        d = np.hypot(*(c.xy - np.asarray(p, float)).T) if len(c) else np.array([np.inf])
        j = int(np.argmin(d))
        if d[j] > s.seed_radius:
            near = "no bright blob in this frame" if not np.isfinite(d[j]) \
                else f"the nearest bright blob is {d[j]:.1f} px away"
            failed.append((m, f, InputError(
                f"seed of {m} in {station} frame {f} at ({p[0]:.1f}, {p[1]:.1f}): {near} "
                f"(more than {s.seed_radius:g} px)",
                hint="click on the marker itself in a frame where it is visible")))
            continue
        snapped[markers.index(m)] = (f, j)
    if failed and not snapped:
        frames_ = sorted({f for f, _ in seeds.values()})
        raise InputError(f"camera {station} sees none of the markers at its seed clicks "
                         f"(frame {', '.join(map(str, frames_))}): no bright new spot within "
                         f"{s.seed_radius:g} px of any",
                         hint="check that the video is the right one and not blank, that "
                              "the seeds' frames are this camera's, or leave the camera out")
    # a seed that misses while others of the camera hit: that marker goes
    # without a seed in this camera (lost here unless the 3D prediction from
    # the other cameras finds it); the reason at the seed's frame says why
    notes = []
    for m, f, err in failed:
        notes.append(f"{err.args[0]}: not used, {m} has no seed in {station}")
    for i in range(M):
        if i not in snapped:
            continue
        f, j = snapped[i]
        shared = [k for k, (g, jj) in snapped.items() if g == f and jj == j and k != i]
        c = cands[f]
        xy[f, i], sig[f, i], cidx[f, i] = c.xy[j], c.sigma[j], j
        dn = neighbour_distance(c, j, s.neighbour_flux)
        if shared:
            status[f, i] = AMBIGUOUS
            reason[f, i] = "seed on one blob with " + ", ".join(markers[k] for k in shared)
            flux[i] = c.flux[j] / (len(shared) + 1)
        elif dn < s.min_separation:
            status[f, i] = AMBIGUOUS
            reason[f, i] = f"seed on a blob {dn:.1f} px from another one"
            flux[i] = c.flux[j]
        else:
            status[f, i], reason[f, i] = OK, "seed"
            flux[i] = c.flux[j]
    for direction in (1, -1):
        _pass(cands, snapped, markers, direction, s, xy, sig, status, reason, cidx, flux)
    return Track2D(xy, sig, status, reason, cidx, flux, notes)


def _pass(cands, snapped, markers, direction, s, xy, sig, status, reason, cidx, flux):
    F, M = len(cands), len(markers)
    hist = {}
    fluxes = {i: [flux[i]] for i in snapped}
    for i, (f, j) in snapped.items():
        h = [(f, xy[f, i])]
        if direction < 0 and f + 1 < F and status[f + 1, i] != LOST:
            h = [(f + 1, xy[f + 1, i])] + h          # the forward pass's velocity
        hist[i] = h
    active = set(snapped)
    first = min(f for f, _ in snapped.values()) if snapped else F
    last = max(f for f, _ in snapped.values()) if snapped else -1
    frames = range(first + 1, F) if direction > 0 else range(last - 1, -1, -1)
    for t in frames:
        live = [i for i in sorted(active) if (t - snapped[i][0]) * direction > 0]
        if not live:
            continue
        c = cands[t]
        pred, gate = {}, {}
        fresh = [i for i in live if len(hist[i]) == 1]
        v = None
        if fresh:
            dt = t - hist[fresh[0]][-1][0]
            p0 = np.array([hist[i][-1][1] for i in fresh])
            v = _vote(p0, c, dt, s)
        for i in live:
            tl = hist[i][-1][0]
            coast = abs(t - tl) - 1
            if len(hist[i]) == 1:
                if v is None:
                    status[t, i], reason[t, i] = LOST, "no common motion found after the seed"
                    continue
                pred[i] = hist[i][-1][1] + v * (t - tl)
            else:
                pred[i] = _predict(hist[i][-5:], t)
            gate[i] = s.gate + s.gate_growth * coast
        if not pred:
            continue
        ids = list(pred)
        P = np.array([pred[i] for i in ids])
        D = np.linalg.norm(P[:, None, :] - c.xy[None], axis=2) if len(c) \
            else np.zeros((len(ids), 0))
        best = np.full(len(ids), -1)
        for a, i in enumerate(ids):
            inside = np.nonzero(D[a] < gate[i])[0]
            # blobs far fainter than the marker are not it (not even partly)
            bright = inside[c.flux[inside] >= s.low_flux * median_of_few(fluxes[i][-10:])]
            if not len(bright):
                status[t, i] = LOST
                reason[t, i] = (f"no blob within {gate[i]:.1f} px of the prediction"
                                if not len(inside) else
                                f"only faint blobs within {gate[i]:.1f} px of the prediction")
                continue
            inside = bright
            order = inside[np.argsort(D[a, inside])]
            d1 = D[a, order[0]]
            if len(order) > 1 and D[a, order[1]] < max(s.clear_ratio * d1, d1 + s.clear_margin):
                status[t, i] = AMBIGUOUS
                reason[t, i] = (f"{len(order)} blobs within {gate[i]:.1f} px of the "
                                f"prediction ({d1:.1f} and {D[a, order[1]]:.1f} px)")
                # the group carries the prediction on (its flux-weighted centre)
                wf = c.flux[order]
                hist[i].append((t, (wf[:, None] * c.xy[order]).sum(0) / wf.sum()))
                continue
            best[a] = order[0]
        for a, i in enumerate(ids):
            j = best[a]
            if j < 0:
                continue
            others = [markers[ids[b]] for b in range(len(ids)) if b != a and best[b] == j]
            xy[t, i], sig[t, i], cidx[t, i] = c.xy[j], c.sigma[j], j
            ratio = c.flux[j] / median_of_few(fluxes[i][-10:])
            dn = neighbour_distance(c, j, s.neighbour_flux)
            if others:
                status[t, i] = AMBIGUOUS
                reason[t, i] = "one blob with " + ", ".join(others) + " (merged)"
            elif dn < s.min_separation:
                status[t, i] = AMBIGUOUS
                reason[t, i] = (f"another blob {dn:.1f} px away: the centres of "
                                "overlapping blobs are off")
            elif ratio > s.merge_flux or c.elongation[j] > s.max_elongation:
                status[t, i] = AMBIGUOUS
                reason[t, i] = (f"blob {ratio:.1f}x the marker's flux, elongation "
                                f"{c.elongation[j]:.1f} (merged?)")
            else:
                status[t, i], reason[t, i] = OK, "tracked"
                fluxes[i].append(c.flux[j])
            # the blob carries the prediction on, whatever the status
            hist[i].append((t, c.xy[j]))
        for i in live:
            if abs(t - hist[i][-1][0]) > s.max_coast:
                active.discard(i)
                for u in (range(t + 1, F) if direction > 0 else range(t - 1, -1, -1)):
                    status[u, i] = LOST
                    reason[u, i] = f"track ended: no blob for {s.max_coast} frames"
    for i in snapped:
        flux[i] = np.median(fluxes[i])



def scatter_sigma(xy: np.ndarray, ok: np.ndarray, half: int = 3,
                  min_points: int = 8) -> float:
    """Empirical sigma (px, per coordinate) of a marker's track: the robust
    scatter of its ok positions about a quadratic in time through its
    neighbours within ``half`` frames (leave-one-out prediction residuals,
    ``1.4826 MAD``, divided by ``sqrt(1 + h)`` with ``h`` the variance
    factor of the prediction). The flight and the body's motion are smooth
    over a quarter of a second; what is left is the measurement's own
    noise, JPEG and motion blur included, that the propagated noise sigma
    of :func:`photogram.track.markers.detect_markers` does not know. NaN
    with fewer than ``min_points`` usable positions.

    Parameters
    ----------
    xy : (F, 2)
    ok : (F,) bool
    """
    t_ok = np.nonzero(ok)[0]
    res, fac = [], []
    for t in t_ok:
        nb = t_ok[(np.abs(t_ok - t) <= half) & (t_ok != t)]
        if len(nb) < 4 or not ((nb < t).any() and (nb > t).any()):
            continue
        V = np.vander((nb - t).astype(float), 3)
        coef, *_ = np.linalg.lstsq(V, xy[nb], rcond=None)
        res.append(xy[t] - coef[-1])
        fac.append(1.0 + np.linalg.inv(V.T @ V)[-1, -1])
    if len(res) < min_points:
        return float("nan")
    r = np.asarray(res) / np.sqrt(np.asarray(fac))[:, None]
    return float(1.4826 * np.median(np.abs(r - np.median(r, axis=0))))
