"""The athlete chosen by multi-view consistency (docs/mocap.md section 5).

The per-camera tracking (:mod:`photogram.mocap.tracking.athlete`) picks the
largest, surest person of each view; a bystander nearer to one camera than
the athlete can win there. Here the choice is made across the cameras, as
Pose2Sim's ``personAssociation`` (single-person mode,
``best_persons_and_cameras_combination``) does:

1. **combinations** (per frame): one candidate per camera; every joint is
   triangulated by a linear DLT weighted by its confidence (joints below
   ``association_confidence`` left out; a second pass weights each ray by
   ``(f / depth)^2`` so that the algebraic residual is a pixel residual) and
   reprojected; the error of a camera is the **median** over its joints
   seen by at least two cameras of the combination (px; robust to a swapped
   or wild joint), the error of the combination the **largest** camera error.
2. **levels**: all cameras first; if no combination is consistent (error <=
   ``association_px``) or none lies in the temporal gate (step 3), one camera
   is left out (every choice of one), then two, ... down to two cameras
   (Pose2Sim's loop with ``nb_cams_off``); at the first level with a gated,
   consistent combination the one with the smallest error is taken. The
   cameras left out are flagged *inconsistent* for that frame.
3. **temporal continuity** (as the per-camera tracking, in 3D): per run,
   the frame whose best consistent combination has the most cameras (then
   the smallest error; :data:`SEED_FRAMES` evenly spaced frames searched)
   seeds the track, which is followed forwards and backwards;
   in every frame only combinations whose **root** (median of the
   triangulated joints) lies within ``gate * H * g`` of the constant-velocity
   prediction count (``H`` the seed's size: the largest distance between two
   of its joints; ``g`` frames since the last chosen frame). A frame without
   such a combination is left out entirely (flagged), the prediction goes on.
   In a crowded frame (more than :data:`CROWDED` combinations) only the
   candidates near the last skeleton, moved by the root's velocity, are
   combined.
4. **ambiguity**: a camera of the chosen combination where another candidate
   (not a duplicate of the chosen one: median joint distance above an
   eighth of the threshold) fits the same other cameras, in the gate, nearly
   as well (its camera error within ``ambiguity_ratio`` = 3 times the chosen
   one's, or below a quarter of the threshold) is left out (flagged
   *ambiguous*): never a guess.

A bystander seen by one or two cameras is therefore taken only if it is
consistent with the athlete's 3D skeleton in those cameras, which a
different person is not. A run where fewer than half of the camera-frames
with a candidate are used (:attr:`Association.undecided_runs`) says more
about the cameras than about the people: the caller keeps the per-camera
choice there.

The cameras are duck-typed (``to_rays``, ``rotations``, ``pixel_scale``,
``X0``: a :class:`photogram.mocap.reconstruction.cameras.MocapCameras`; this
package does not import the reconstruction).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.mocap.tracking.detections import CameraDetections
from photogram.mocap.tracking.multiview_frames import _Frames, _duplicate, _pad

__all__ = ["AssociationSettings", "Association", "associate", "settings_from_tracking",
           "tracked_candidates", "describe", "USED", "INCONSISTENT", "AMBIGUOUS",
           "NO_CANDIDATE", "UNDECIDED", "CROWDED", "SEED_FRAMES"]

#: combinations of all cameras above which a frame is crowded: only the
#: candidates near the predicted skeleton are combined
CROWDED = 64
#: frames of a run searched for the seed (evenly spaced)
SEED_FRAMES = 12
#: per frame and camera: what the association did with the camera
USED, INCONSISTENT, AMBIGUOUS, NO_CANDIDATE, UNDECIDED = 0, 1, 2, 3, 4


@dataclass
class AssociationSettings:
    """``association_px``: largest per-camera median reprojection error (px)
    of a consistent combination; ``association_confidence``: joints below
    it are not used for the choice (Pose2Sim's
    ``likelihood_threshold_association``, 0.3); ``gate``: the temporal gate
    in body sizes per frame; ``ambiguity_ratio``: a rival candidate whose
    camera error is within this factor of the chosen one's (or below a
    quarter of ``association_px``) makes the camera ambiguous;
    ``min_joints``: joints a camera must see (with another camera of the
    combination) to be judged; ``max_combinations``:
    per frame and level (more: the candidates with the most confident joints
    are kept)."""

    association_px: float = 40.0
    association_confidence: float = 0.3
    gate: float = 0.5
    ambiguity_ratio: float = 3.0
    min_joints: int = 4
    max_combinations: int = 5000


@dataclass
class Association:
    """Per frame and camera (F, C): ``rows`` the chosen candidate's row of
    the camera's detections (-1: none), ``status`` (:data:`USED`,
    :data:`INCONSISTENT`, :data:`AMBIGUOUS`, :data:`NO_CANDIDATE`,
    :data:`UNDECIDED`), ``error_px`` the camera's median reprojection error
    in the chosen combination; ``root`` (F, 3) the chosen combination's root
    (NaN: frame left out); per run, ``seeds`` the seed frame (-1: none)
    and ``sizes`` H."""

    rows: np.ndarray
    status: np.ndarray
    error_px: np.ndarray
    root: np.ndarray
    seeds: list
    sizes: list
    settings: AssociationSettings = field(default_factory=AssociationSettings)
    runs: list = field(default_factory=list)

    @property
    def undecided_runs(self) -> list:
        """(first, end) of the runs without any consistent combination (no
        seed: wrong cameras, or never two cameras at once) or where fewer
        than half of the camera-frames with a candidate are used."""
        return [(lo, hi) for (lo, hi), s in zip(self.runs, self.seeds)
                if s < 0 or not self._mostly_used(lo, hi)]

    def _mostly_used(self, lo, hi) -> bool:
        """At least half of the camera-frames with a candidate are used;
        otherwise the cameras do not fit the detections (a calibration in
        the wrong unit, frames numbered differently), not a person problem."""
        st = self.status[lo:hi]
        with_candidate = np.sum(st != NO_CANDIDATE)
        return bool(with_candidate and np.sum(st == USED) >= 0.5 * with_candidate)

    def joints(self, candidates: list) -> np.ndarray:
        """(F, C, J, 3) joints of the chosen candidates (NaN, 0: none)."""
        F, C = self.rows.shape
        J = next(d.skeleton.n_joints for d in candidates if d is not None)
        out = np.full((F, C, J, 3), np.nan)
        out[..., 2] = 0.0
        for c, det in enumerate(candidates):
            take = self.rows[:, c] >= 0
            if det is not None and take.any():
                out[take, c] = det.joints[self.rows[take, c]]
        return out

    def report(self, names, per_camera_rows=None) -> dict:
        """Per camera: frames used, frames where another row than the
        per-camera choice was taken, frames left out (inconsistent,
        ambiguous, frame undecided) although the camera had a candidate."""
        out = {}
        for c, name in enumerate(names):
            st, rows = self.status[:, c], self.rows[:, c]
            d = {"used": int(np.sum(st == USED)),
                 "inconsistent": int(np.sum(st == INCONSISTENT)),
                 "ambiguous": int(np.sum(st == AMBIGUOUS)),
                 "undecided": int(np.sum(st == UNDECIDED)),
                 "no_candidate": int(np.sum(st == NO_CANDIDATE))}
            if per_camera_rows is not None and per_camera_rows[c] is not None:
                pc = np.asarray(per_camera_rows[c])
                d["other_person"] = int(np.sum((rows >= 0) & (pc >= 0) & (rows != pc)))
                d["per_camera_left_out"] = int(np.sum((rows < 0) & (pc >= 0)))
                d["gained"] = int(np.sum((rows >= 0) & (pc < 0)))
            e = self.error_px[:, c][st == USED]
            d["median_error_px"] = float(np.median(e)) if len(e) else None
            out[name] = d
        return out


def _choose(frames: _Frames, f, pred, radius, size=0.0, skeleton=None, reach_px=np.inf):
    """The chosen combination of frame f within ``radius`` of ``pred``
    (None: no gate): (slots (C,), per-camera errors (C,), root (3,),
    ambiguous cameras) or None. In a crowded frame (more than
    :data:`CROWDED` combinations of all cameras) only the candidates within
    ``reach_px`` (median over the joints) of the predicted ``skeleton()``
    (J, 3) are combined."""
    st = frames.st
    thr = st.association_px
    options = frames.options(f, pred, radius + size)
    if skeleton is not None and np.prod([max(len(o), 1) for o in options]) > CROWDED:
        options = frames.near(f, options, skeleton(), reach_px)
    for lv in frames.levels(options):
        combos, total, per_cam, root = frames.level(f, lv, options)
        good = total <= thr
        if pred is not None:
            good &= np.linalg.norm(root - pred, axis=-1) <= radius
        if not good.any():
            continue
        idx = np.flatnonzero(good)
        best = idx[np.argmin(total[idx])]
        combo = combos[best].copy()
        ambiguous = []
        for c in np.flatnonzero(combo >= 0):
            same = np.all((combos[idx] == combo) | (np.arange(len(combo)) == c), axis=1)
            close = per_cam[idx, c] <= max(st.ambiguity_ratio * per_cam[best, c], 0.25 * thr)
            rivals = combos[idx][same & close & (combos[idx, c] != combo[c]), c]
            ja = frames.joints[f, c, combo[c]]
            if any(not _duplicate(ja, frames.joints[f, c, k], thr / 8) for k in rivals):
                ambiguous.append(int(c))
        return combo, per_cam[best], root[best], ambiguous
    return None


def _size(X):
    P = X[np.all(np.isfinite(X), -1)]
    if len(P) < 2:
        return np.nan
    return float(np.max(np.linalg.norm(P[:, None] - P[None], axis=-1)))


def associate(candidates: list, cameras, n_frames: int,
              settings: AssociationSettings | None = None, breaks=()) -> Association:
    """Choose the athlete's candidate per frame and camera (module doc).

    Parameters
    ----------
    candidates : list of CameraDetections or None
        Per camera (in the order of ``cameras``), all candidate detections.
    cameras : MocapCameras
        Calibrated cameras (rotations per frame if they move), ``n_frames``
        frames.
    n_frames : int
    settings : AssociationSettings, optional
    breaks : sequence of int
        First frames of independent runs (each is seeded and tracked alone).

    Returns
    -------
    Association
    """
    st = settings or AssociationSettings()
    F, C = int(n_frames), len(candidates)
    J = next((d.skeleton.n_joints for d in candidates if d is not None), 0)
    rows_out = np.full((F, C), -1)
    status = np.full((F, C), NO_CANDIDATE)
    error = np.full((F, C), np.nan)
    roots = np.full((F, 3), np.nan)
    if F == 0 or J == 0:
        return Association(rows_out, status, error, roots, [], [], st)
    joints, rows, seen = _pad(candidates, F, J, st.association_confidence, st.min_joints)
    frames = _Frames(joints, rows, seen, cameras, st)
    has = (rows >= 0).any(-1)                              # (F, C)
    cuts = [0] + sorted(int(b) for b in breaks if 0 < b < F) + [F]
    seeds, sizes = [], []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        seed, size = _track_segment(frames, lo, hi, has, rows, rows_out, status, error, roots)
        seeds.append(seed)
        sizes.append(size)
    return Association(rows_out, status, error, roots, seeds, sizes, st,
                       list(zip(cuts[:-1], cuts[1:])))


def _track_segment(frames, lo, hi, has, rows, rows_out, status, error, roots):
    """Seed and track frames lo..hi-1 (one run); fills the output arrays."""
    st = frames.st
    C = rows.shape[1]
    # seed: most cameras, then smallest error, without a gate
    best_key, seed = None, -1
    for f in range(lo, hi, max(1, (hi - lo) // SEED_FRAMES)):
        ch = _choose(frames, f, None, np.inf)
        if ch is not None:
            key = (-int(np.sum(ch[0] >= 0)), float(np.nanmax(ch[1][ch[0] >= 0])))
            if best_key is None or key < best_key:
                best_key, seed = key, f
    if seed < 0:
        status[lo:hi][has[lo:hi]] = UNDECIDED
        return -1, np.nan
    seed_combo = _choose(frames, seed, None, np.inf)[0]
    size = _size(frames.evaluate(seed, seed_combo[None])[3][0])
    if not np.isfinite(size) or size <= 0:
        size = 1.0
    for order in (range(seed, hi), range(seed - 1, lo - 1, -1)):
        track = []                                     # (frame, root, combo) accepted
        if order.start != seed:
            track = [(seed, roots[seed], seed_combo)]
        for f in order:
            pred, radius, skeleton, reach = None, np.inf, None, np.inf
            if track:
                lf, lr, lc = track[-1]
                g = abs(f - lf)
                v = np.zeros(3)
                if len(track) > 1 and abs(lf - track[-2][0]) <= 5:
                    v = (lr - track[-2][1]) / abs(lf - track[-2][0])
                pred, radius = lr + v * g, st.gate * size * g

                def skeleton(lf=lf, lc=lc, shift=v * g):   # the last skeleton, moved
                    return frames.evaluate(lf, lc[None])[3][0] + shift
                reach = 3.0 * st.association_px * g
            ch = _choose(frames, f, pred, radius, size, skeleton, reach)
            if ch is None:
                status[f, has[f]] = UNDECIDED
                continue
            combo, per_cam, root, ambiguous = ch
            roots[f] = root
            track.append((f, root, combo))
            for c in range(C):
                if combo[c] >= 0 and c not in ambiguous:
                    rows_out[f, c] = rows[f, c, combo[c]]
                    status[f, c] = USED
                    error[f, c] = per_cam[c]
                elif combo[c] >= 0:
                    status[f, c] = AMBIGUOUS
                elif has[f, c]:
                    status[f, c] = INCONSISTENT
            if np.sum(status[f] == USED) < 2:              # ambiguity left one camera
                rows_out[f] = -1
                status[f, status[f] == USED] = AMBIGUOUS
                roots[f] = np.nan
    return seed, size


def settings_from_tracking(tracking) -> AssociationSettings:
    """The association settings of ``[mocap.tracking]`` (a TrackingSettings)."""
    return AssociationSettings(association_px=tracking.association_px,
                               association_confidence=tracking.association_confidence,
                               gate=tracking.gate)


def tracked_candidates(tracked, skeleton) -> tuple[CameraDetections, np.ndarray]:
    """One candidate per frame (the tracked athlete of an image detector,
    a TrackedCamera) and the rows of the per-camera choice (F,)."""
    j = np.asarray(tracked.joints, float)
    F = len(j)
    have = np.flatnonzero((np.nan_to_num(j[..., 2]) > 0).any(-1))
    det = CameraDetections.from_joints(tracked.camera, skeleton, have, j[have], F)
    rows = np.full(F, -1)
    rows[have] = np.arange(len(have))
    return det, rows


def describe(report: dict) -> list[str]:
    """One log line per camera of :meth:`Association.report`."""
    out = []
    for name, d in report.items():
        err = d.get("median_error_px")
        out.append(f"camera {name}: multi-view choice in {d['used']} frames (median "
                   f"{'-' if err is None else f'{err:.1f}'} px), another person than the "
                   f"per-camera choice in {d.get('other_person', 0)}, left out as inconsistent "
                   f"in {d['inconsistent']}, ambiguous in {d['ambiguous']}, frame undecided in "
                   f"{d['undecided']}")
    return out
