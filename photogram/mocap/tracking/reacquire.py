"""The athlete's track in one camera that is lost and re-acquired
(docs/mocap.md section 5, "Main person per camera"; issue 22).

Among the candidate detections of one camera
(:class:`~photogram.mocap.tracking.detections.CameraDetections`) the athlete
is the person the sequence follows longest and best, not the largest one
of a frame:

1. **states**: per candidate a robust centre (median of the joints above
   ``min_confidence``), a size (the larger of the 10-90 % spans of x and y:
   insensitive to a wild joint) and a quality ``q`` (the sum of the joint
   confidences over the joint count: mean confidence times the fraction
   seen). With ``image_centre`` given (a **pan-tilt** camera that follows
   the athlete) ``q`` is multiplied by ``exp(-r^2 / (2 * 0.15^2))``, ``r``
   the distance from the image centre over the half diagonal (scale
   :data:`CENTRE_SCALE` = 0.15), and by a motion weight
   ``exp(-m^2 / (2 * 0.05^2))``, ``m`` the image speed of the candidate's
   tracklet over +-5 frames in sizes per frame: the athlete stays near the
   centre and nearly still, a bystander standing still drifts across the
   image as the camera pans, a person beside the athlete stays beside it
   (the product of both weights is at least :data:`WEIGHT_FLOOR` = 0.05: an
   athlete far off the centre still counts when nobody else is there);
2. **tracklets**: candidates are linked frame to frame (gaps of up to
   :data:`LINK_GAP` frames) by an optimal assignment on the distance to the
   constant-velocity prediction (a straight line through the last 5
   centres) and the size ratio; a link needs the centre
   within ``gate`` (0.5) sizes per frame of the prediction and a size ratio
   below :data:`SIZE_RATIO` (2);
3. **chain**: every tracklet is cut where another one starts or ends; the
   athlete is the sequence of such segments, disjoint in time, of the
   largest total quality minus a cost per link (dynamic programming over
   the segments ordered by their first frame): nothing to go on within a
   tracklet; :data:`LINK_COST` (0.2) for a link whose start lies in the gate
   of the previous segment's end (``gate + GATE_GROWTH * (g - 1)`` sizes
   after ``g`` frames, GATE_GROWTH = 0.05, and a ratio of the median sizes
   below :data:`CHAIN_SIZE_RATIO` (1.5) that grows likewise: the longer the
   athlete was lost, the farther it may be found); :data:`REACQUIRE_COST`
   (15 frames of full quality) for a link anywhere else in the image (the
   full-image search: only a tracklet worth more than that is taken); and
   :data:`SWITCH_COST` (50) for leaving a tracklet that goes on for another
   one (an identity switch). The track is therefore re-acquired wherever it
   continues best after a loss, and its seed is the best whole sequence,
   not the largest, surest detection of one frame;
4. **pan-tilt losses**: with ``image_centre`` a segment that *drifts off
   the centre* (median centre weight below :data:`WEIGHT_FLOOR` and median
   motion weight below :data:`DRIFT_WEIGHT` = 0.5) is chained only after a
   gap of at most :data:`LONG_LOSS` (25) frames: it continues a track
   but does not bridge a long loss (a camera looking away from the athlete
   sees a bystander drift across the image, off its centre; an athlete off
   the centre of a lagging camera stays nearly still in the image).

Per frame the chain gives the chosen row (-1: none) and a status:
:data:`TRACKED`, :data:`ACQUIRED` (the first frame of the track, the
first frame after a loss, or a link outside the gate) or :data:`LOST`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from photogram.mocap.tracking.detections import CameraDetections
from photogram.stats.small_samples import median_of_few

__all__ = ["PersonTrack", "follow_person", "candidate_states", "TRACKED", "ACQUIRED", "LOST",
           "LINK_GAP", "SIZE_RATIO", "CHAIN_SIZE_RATIO", "GATE_GROWTH", "LINK_COST",
           "REACQUIRE_COST", "SWITCH_COST",
           "CENTRE_SCALE", "MOTION_FRAMES", "MOTION_SCALE", "WEIGHT_FLOOR", "DRIFT_WEIGHT",
           "LONG_LOSS", "centre_weight"]

#: per-frame status (the codes of :mod:`photogram.mocap.tracking.crop_tracking`)
TRACKED, ACQUIRED, LOST = 0, 1, 2
#: frames a tracklet may skip
LINK_GAP = 2
#: largest size ratio between linked frames of a tracklet
SIZE_RATIO = 2.0
#: largest ratio of the median sizes (5 frames) at a link of the chain
CHAIN_SIZE_RATIO = 1.5
#: growth of the gate (sizes per frame lost) between tracklets of the chain
GATE_GROWTH = 0.05
#: cost of a link in the gate, of one outside it, and of leaving a tracklet
#: that goes on for another one (frames of quality 1)
LINK_COST, REACQUIRE_COST, SWITCH_COST = 0.2, 15.0, 50.0
#: width of the image-centre weight (fraction of the half diagonal)
CENTRE_SCALE = 0.15
#: the smallest pan-tilt weight (a frame far off the centre still counts)
WEIGHT_FLOOR = 0.05
#: frames either side and scale (sizes per frame) of the motion weight
MOTION_FRAMES, MOTION_SCALE = 5, 0.05
#: median motion weight below which a segment off the centre drifts, and the
#: frames lost beyond which such a segment does not re-acquire (step 4)
DRIFT_WEIGHT, LONG_LOSS = 0.5, 25
_VELOCITY_FRAMES = 5        # frames of a tracklet's end its velocity is fitted to
_MAX_EXTRAPOLATION = 10     # frames a velocity is extrapolated over a gap


@dataclass
class PersonTrack:
    """``rows`` (F,) the chosen row of the detections (-1: none), ``status``
    (F,) TRACKED / ACQUIRED / LOST, ``tracklets`` the number of tracklets
    found, ``chain`` the (first, last) frames of the chained tracklets."""

    rows: np.ndarray
    status: np.ndarray
    tracklets: int
    chain: list


def candidate_states(det: CameraDetections, min_confidence: float = 0.1):
    """Per candidate row: centre (n, 2), size (n,), quality (n,) (without
    the pan-tilt weights) and usable (n,) (two joints or more), step 1 of
    the module doc."""
    j = np.asarray(det.joints, float)
    n, J = j.shape[:2]
    conf = np.nan_to_num(j[..., 2])
    ok = np.all(np.isfinite(j[..., :2]), -1) & (conf > min_confidence)
    xy = np.where(ok[..., None], j[..., :2], np.nan)
    centre, (lo, hi) = _median_and_percentiles(xy, ok.sum(1), (10, 90))
    size = np.max(hi - lo, axis=-1) if n else np.zeros(0)
    usable = (ok.sum(1) >= 2) & np.all(np.isfinite(centre), -1) & np.isfinite(size)
    size = np.where(usable, np.maximum(np.nan_to_num(size), 1.0), np.nan)
    quality = np.where(ok, conf, 0.0).sum(1) / max(J, 1)
    return centre, size, np.where(usable, quality, 0.0), usable


def _median_and_percentiles(xy, k, percents):
    """``np.nanmedian(xy, axis=1)`` and ``np.nanpercentile(xy, percents,
    axis=1)`` (linear interpolation) of ``xy`` (n, J, D) with ``k`` (n,)
    finite rows each, bit for bit (the same sums and numpy's ``_lerp``),
    without numpy's loop over the rows (masked arrays, apply_along_axis)."""
    n, J, D = xy.shape
    s = np.sort(xy, axis=1)                                       # NaN last
    k = np.broadcast_to(np.asarray(k)[:, None], (n, D))
    none = k == 0

    def take(i):
        i = np.clip(i, 0, max(J - 1, 0)).astype(np.intp)
        return np.take_along_axis(s, i[:, None, :], axis=1)[:, 0] if J else \
            np.full((n, D), np.nan)

    h = k // 2
    hi = take(h)
    med = np.where(k % 2 == 1, hi, (take(h - 1) + hi) / 2.0)
    med[none] = np.nan
    out = np.empty((len(percents), n, D))
    for m, q in enumerate(np.true_divide(percents, 100)):
        v = (k - 1) * q                                           # virtual index
        below = np.floor(v)
        top = v >= k - 1                                          # numpy: the last value
        a, b = take(np.where(top, k - 1, below)), take(np.where(top, k - 1, below + 1))
        g = v - below
        d = b - a
        out[m] = np.where(g >= 0.5, b - d * (1 - g), a + d * g)
        out[m][none] = np.nan
    return med, out


def centre_weight(centre, image_centre) -> np.ndarray:
    """``exp(-r^2 / (2 CENTRE_SCALE^2))`` per candidate centre (n, 2), ``r``
    the distance from ``image_centre`` over the half diagonal."""
    c0 = np.asarray(image_centre, float)
    r = np.linalg.norm(centre - c0, axis=-1) / max(float(np.linalg.norm(c0)), 1.0)
    return np.exp(-0.5 * (np.nan_to_num(r, nan=1e3) / CENTRE_SCALE) ** 2)


def _tracklets(frames, centre, size, usable, F, gate):
    """Step 2: list of row arrays (in frame order), one per tracklet."""
    by_frame = [[] for _ in range(F)]
    for i in np.flatnonzero(usable):
        if 0 <= frames[i] < F:
            by_frame[int(frames[i])].append(int(i))
    tracks: list[list[int]] = []
    active: list[int] = []                              # tracklets that may continue
    for f in range(F):
        cand = by_frame[f]
        active = [t for t in active if f - frames[tracks[t][-1]] <= LINK_GAP + 1]
        taken = set()
        if active and cand:
            last = np.array([tracks[t][-1] for t in active])
            # the tail is all _end_state reads (not the whole tracklet each frame)
            ends = [_end_state(np.array(tracks[t][-_VELOCITY_FRAMES:]), frames, centre, size,
                               True) for t in active]
            g = (f - frames[last]).astype(float)
            pred = np.array([e[0] + e[2] * gi for e, gi in zip(ends, g)])
            c = np.array(cand)
            d = np.linalg.norm(centre[c][None] - pred[:, None], axis=-1) / (
                gate * g[:, None] * size[last][:, None])
            r = np.abs(np.log(size[c][None] / size[last][:, None])) / np.log(SIZE_RATIO)
            cost = d ** 2 + r ** 2
            feasible = (d <= 1.0) & (r <= 1.0)
            ti, ci = linear_sum_assignment(np.where(feasible, cost, 1e9))
            for a, b in zip(ti, ci):
                if feasible[a, b]:
                    tracks[active[a]].append(c[b])
                    taken.add(c[b])
        for i in cand:
            if i not in taken:
                tracks.append([i])
                active.append(len(tracks) - 1)
    return [np.array(t, int) for t in tracks]


def _end_state(rows, frames, centre, size, tail: bool):
    """Centre, size, velocity (per frame) and frame at one end of a run of
    rows: a least-squares straight line through the centres of its last (or
    first) :data:`_VELOCITY_FRAMES` frames, evaluated at the end (one noisy
    frame does not decide), and their median size."""
    k = rows[-_VELOCITY_FRAMES:] if tail else rows[:_VELOCITY_FRAMES]
    fr = frames[k].astype(float)
    c = centre[k]
    end = -1 if tail else 0
    v, at = np.zeros(2), c[end]
    if len(k) >= 3 and np.ptp(fr) > 0:              # least squares, closed form
        t = fr - fr.mean()
        mean = c.mean(0)
        v = t @ (c - mean) / (t @ t)
        at = mean + v * t[end]
    return at, float(median_of_few(size[k].tolist())), v, int(frames[k[end]])


def _segments(tracks, frames):
    """Every tracklet cut where another one starts or ends (so that the
    chain may leave or join a tracklet there): list of (tracklet, rows)."""
    starts = {int(frames[t[0]]) for t in tracks}
    ends = {int(frames[t[-1]]) + 1 for t in tracks}
    cuts = np.array(sorted(starts | ends))
    out = []
    for k, t in enumerate(tracks):
        fr = frames[t]
        inner = cuts[(cuts > fr[0]) & (cuts <= fr[-1])]
        for part in np.split(t, np.searchsorted(fr, inner)):
            if len(part):
                out.append((k, part))
    return out


def _motion_weight(tracks, frames, centre, size, n):
    """(n,) per row of a tracklet: ``exp(-m^2 / (2 MOTION_SCALE^2))``, ``m``
    the image speed of the tracklet's centre over +-:data:`MOTION_FRAMES`
    frames in sizes per frame (a pan-tilt camera follows the athlete; a
    bystander standing still drifts across the image); 1 where the
    tracklet is shorter than that."""
    w = np.ones(n)
    for t in tracks:
        if len(t) <= MOTION_FRAMES:
            continue
        fr = frames[t].astype(float)
        idx = np.arange(len(t))
        a = np.clip(idx - MOTION_FRAMES, 0, len(t) - 1)
        b = np.clip(idx + MOTION_FRAMES, 0, len(t) - 1)
        m = np.linalg.norm(centre[t[b]] - centre[t[a]], axis=-1) / (
            np.maximum(fr[b] - fr[a], 1.0) * size[t])
        w[t] = np.exp(-0.5 * (m / MOTION_SCALE) ** 2)
    return w


def follow_person(det: CameraDetections, min_confidence: float = 0.1, gate: float = 0.5,
                  image_centre=None) -> PersonTrack:
    """The athlete's track in one camera (module doc).

    Parameters
    ----------
    det : CameraDetections
        All candidates of the camera.
    min_confidence : float
        Joints at or below it are not used.
    gate : float
        Sizes per frame a tracklet's next centre may lie from its prediction.
    image_centre : (2,) array_like, optional
        The image centre (px) of a pan-tilt camera following the athlete.

    Returns
    -------
    PersonTrack
    """
    F = int(det.n_frames)
    rows_out = np.full(F, -1)
    status = np.full(F, LOST)
    frames = np.asarray(det.frames, int)
    centre, size, quality, usable = candidate_states(det, min_confidence)
    tracks = _tracklets(frames, centre, size, usable, F, gate)
    if not tracks:
        return PersonTrack(rows_out, status, 0, [])
    segs = _segments(tracks, frames)
    S = len(segs)
    drifting = np.zeros(S, bool)
    if image_centre is not None:
        on_centre = centre_weight(centre, image_centre)
        still = _motion_weight(tracks, frames, centre, size, len(quality))
        quality = quality * np.maximum(on_centre * still, WEIGHT_FLOOR)
        # step 4: off the centre and drifting across the image
        drifting = np.array([np.median(on_centre[r]) < WEIGHT_FLOOR
                             and np.median(still[r]) < DRIFT_WEIGHT for _, r in segs])
    owner = np.array([k for k, _ in segs])
    start = np.array([frames[r[0]] for _, r in segs])
    end = np.array([frames[r[-1]] for _, r in segs])
    value = np.array([quality[r].sum() for _, r in segs])
    last_frame = np.array([frames[t[-1]] for t in tracks])
    heads = [_end_state(r, frames, centre, size, False) for _, r in segs]
    tails = [_end_state(r, frames, centre, size, True) for _, r in segs]
    c_end = np.array([s[0] for s in tails])
    s_end = np.array([s[1] for s in tails])
    v_end = np.array([s[2] for s in tails])
    best = value.copy()
    prev = np.full(S, -1)
    for j in np.argsort(start, kind="stable"):      # step 3: best chain ending with j
        before = np.flatnonzero(end < start[j])
        if drifting[j]:                             # step 4: no long loss bridged
            before = before[start[j] - end[before] <= LONG_LOSS]
        if not len(before):
            continue
        g = (start[j] - end[before]).astype(float)
        pred = c_end[before] + v_end[before] * np.minimum(g, _MAX_EXTRAPOLATION)[:, None]
        grow = gate + GATE_GROWTH * (g - 1.0)
        d = np.linalg.norm(heads[j][0] - pred, axis=-1) / (grow * s_end[before])
        r = np.abs(np.log(heads[j][1] / s_end[before])) / (
            np.log(CHAIN_SIZE_RATIO) * (1.0 + GATE_GROWTH / gate * (g - 1.0)))
        cost = np.where((d <= 1.0) & (r <= 1.0), LINK_COST, REACQUIRE_COST)
        # leaving a tracklet that goes on for another one: an identity switch
        cost = np.where(last_frame[owner[before]] > end[before], SWITCH_COST, cost)
        cost = np.where(owner[before] == owner[j], 0.0, cost)   # the same tracklet goes on
        gain = best[before] - cost
        k = int(np.argmax(gain))
        if gain[k] > 0:
            best[j] += gain[k]
            prev[j] = before[k]
    chain = []
    t = int(np.argmax(best))
    while t >= 0:
        chain.append(t)
        t = int(prev[t])
    chain.reverse()
    for a, t in zip([-1] + chain[:-1], chain):
        rows = segs[t][1]
        rows_out[frames[rows]] = rows
        first = int(frames[rows[0]])
        if a >= 0 and owner[a] != owner[t] and not _in_gate(tails[a], heads[t], gate,
                                                              first - end[a]):
            status[first] = ACQUIRED                # found again elsewhere: re-acquired
    found = rows_out >= 0
    after_loss = found & ~np.r_[False, found[:-1]]  # first frame found after a loss
    status[found & (status != ACQUIRED)] = TRACKED
    status[after_loss] = ACQUIRED
    return PersonTrack(rows_out, status, len(tracks),
                       [(int(start[t]), int(end[t])) for t in chain])


def _in_gate(tail, head, gate, g):
    """Whether a link between consecutive chained tracklets lies in the gate."""
    c, s, v, _ = tail
    pred = c + v * min(g, _MAX_EXTRAPOLATION)
    grow = gate + GATE_GROWTH * (g - 1.0)
    d = np.linalg.norm(head[0] - pred) / (grow * s)
    r = abs(np.log(head[1] / s)) / (np.log(CHAIN_SIZE_RATIO)
                                    * (1.0 + GATE_GROWTH / gate * (g - 1.0)))
    return bool(d <= 1.0 and r <= 1.0)
