"""The athlete lost and re-acquired, and bystanders nearer to the cameras
(issue 22, item 1): the per-camera track
(photogram.mocap.tracking.reacquire.follow_person, with the image centre of
the pan-tilt cameras) against the previous per-camera choice (seed by
size x confidence, followed by the candidate inside the last good box: kept
below as ``previous_select_person``), and the multi-view choice
(photogram.mocap.tracking.multiview, known rotations) after the losses.

SIMULATED (photogram.simulation.ski.simulate, 450 frames at 50 fps, six
pan-tilt-zoom cameras) plus composed people (photogram.mocap.tracking.crowd,
person 0 the athlete):

* normal (seed 8): C1 loses the athlete in frames 100-194 (95 frames, no
  detection) and finds it again 250 px off (the camera lagged); a real 3D
  person standing still half way from the athlete's position of frame 147
  to C1 (twice the athlete's size there, confidence 0.97; seen while C1
  pans past it); a 1.5x larger copy of the athlete 300 px beside it in C2
  (confidence 0.95).
* harsh (seed 31, not tuned on): as normal, plus C4 whose detections jump
  700 px out in frames 250-309, C3 that loses the athlete in 30-89 and
  finds it 300 px off, a second person standing still 0.6 of the way to C3
  (frame 60), a walking 1.6x copy crossing the athlete in C5 (-400..+400
  px), and a 1.3x copy 250 px beside it in C6 all along.

The harsh scene is also run on ten more simulations (seeds 40-49) and ten
held-out ones (seeds 60-69), per-camera tracks only. Design choices made
after looking at these data (disclosed): the cost of leaving a tracklet
that goes on (SWITCH_COST), after a first run of the harsh setting where
the walking copy in C5 took 113 camera-frames; the line through the last
five centres for the prediction and the ends of the tracklets, after seeds
40-49 missed 38 frames of C3 in seed 46 (one noisy centre broke the
athlete's tracklet). Seeds 60-69 were first run after both.

Per setting: camera-frames where a bystander was chosen (previous
per-camera choice, new per-camera track, multi-view choice); athlete
camera-frames (usable detections) not tracked; lost runs and re-acquisitions
against the constructed truth.

Run: .venv/bin/python benchmarks/mocap_reacquire.py
"""

from __future__ import annotations

import sys
import time

import numpy as np

from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.tracking import multiview as mv
from photogram.mocap.tracking.crowd import compose, copied_bystander, projected_bystander
from photogram.mocap.tracking.detections import boxes_from_joints
from photogram.mocap.tracking.reacquire import ACQUIRED, follow_person
from photogram.simulation.ski.simulate import simulate_session

F = 450
CENTRE = (960.0, 540.0)


def previous_select_person(det, min_confidence=0.1):
    """The per-camera choice before issue 22 (for comparison only)."""
    chosen = np.full(det.n_frames, -1)
    conf = np.where(det.joints[..., 2] > min_confidence, det.joints[..., 2], np.nan)
    with np.errstate(invalid="ignore"), __import__("warnings").catch_warnings():
        __import__("warnings").simplefilter("ignore", RuntimeWarning)
        mean_conf = np.nan_to_num(np.nanmean(conf, axis=1))
    boxes = boxes_from_joints(det.joints, min_confidence)
    area = np.nan_to_num((boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1]))
    score = mean_conf * np.sqrt(np.maximum(area, 0))
    ok = np.all(np.isfinite(boxes), axis=1)
    by_frame = {}
    for i in np.flatnonzero(ok):
        by_frame.setdefault(int(det.frames[i]), []).append(int(i))
    seed = int(np.flatnonzero(ok)[np.argmax(score[ok])])
    chosen[det.frames[seed]] = seed
    for order in (range(det.frames[seed] + 1, det.n_frames), range(det.frames[seed] - 1, -1, -1)):
        last = boxes[seed]
        for f in order:
            best, best_d = -1, np.inf
            for i in by_frame.get(f, ()):
                c = 0.5 * (boxes[i, :2] + boxes[i, 2:])
                if last[0] <= c[0] <= last[2] and last[1] <= c[1] <= last[3]:
                    d = float(np.hypot(*(c - 0.5 * (last[:2] + last[2:]))))
                    if d < best_d:
                        best, best_d = i, d
            if best >= 0:
                chosen[f] = best
                last = boxes[best]
    return chosen


def _still(sim, frame, camera, towards):
    mid = sim.joints[frame]
    X = np.repeat(mid[None], F, 0) + towards * (sim.cameras.X0[camera] - mid.mean(0))
    out = projected_bystander(sim.cameras, X, 0.97)
    xy = out[..., :2]
    inside = (xy[..., 0] > 0) & (xy[..., 0] < 1920) & (xy[..., 1] > 0) & (xy[..., 1] < 1080)
    out[~inside] = (np.nan, np.nan, 0.0)
    return out


def scene(sim, harsh, shift=True):
    """Detections per camera and the athlete's truth: (dets, obs, losses)
    with losses {camera: [(first, end)]}; ``shift``: the athlete found
    again off its last position (a per-camera effect that the 3D geometry
    of the simulation does not have: False for the multi-view choice)."""
    k = 1.0 if shift else 0.0
    obs = sim.observations.copy()
    losses = {0: [(100, 195)]}
    obs[100:195, 0] = (np.nan, np.nan, 0.0)
    obs[195:, 0, :, :2] += k * np.array([250.0, 80.0])
    people = [_still(sim, 147, 0, 0.5)]
    bys = [(1, copied_bystander(sim.observations[:, 1], 50, 1.5, (300.0, 0.0)))]
    if harsh:
        losses[2] = [(30, 90)]
        obs[30:90, 2] = (np.nan, np.nan, 0.0)
        obs[90:, 2, :, :2] += k * np.array([-300.0, 40.0])
        losses[3] = [(250, 310)]
        obs[250:310, 3, :, :2] += (700.0, -200.0)
        people.append(_still(sim, 60, 2, 0.6))
        walk = np.stack([np.linspace(-400, 400, F), np.zeros(F)], -1)
        bys += [(4, copied_bystander(sim.observations[:, 4], 70, 1.6, walk)),
                (5, copied_bystander(sim.observations[:, 5], 30, 1.3, (-250.0, 30.0)))]
    for p in people:
        bys += [(c, p[:, c]) for c in range(6) if (p[:, c, :, 2] > 0).any()]
    return compose(obs, SKI24, sim.cameras.names, bys), obs, losses


def _usable(obs_c, lost):
    ok = (np.nan_to_num(obs_c[..., 2]) > 0.1).sum(-1) >= 2
    for lo, hi in lost:
        ok[lo:hi] = False
    return ok


def run(seed, harsh):
    sim = simulate_session(seed=seed, frames_per_run=F)
    dets, obs, losses = scene(sim, harsh)
    out = {"previous": 0, "track": 0, "multiview": 0, "missed": 0, "previous_missed": 0,
           "reacquired_right": 0, "reacquisitions_expected": 0, "lost_frames": 0,
           "lost_expected": 0}
    t0 = time.perf_counter()
    for c, d in enumerate(dets):
        truth = _usable(obs[:, c], losses.get(c, []))
        old = previous_select_person(d)
        tr = follow_person(d, image_centre=CENTRE)
        for key, rows in (("previous", old), ("track", tr.rows)):
            ch = rows >= 0
            out[key] += int(np.sum(d.person[rows[ch]] > 0))
        athlete = lambda rows: (rows >= 0) & (d.person[np.maximum(rows, 0)] == 0)  # noqa: E731
        out["missed"] += int(np.sum(truth & ~athlete(tr.rows)))
        out["previous_missed"] += int(np.sum(truth & ~athlete(old)))
        out["lost_frames"] += int(np.sum(tr.rows < 0))
        out["lost_expected"] += int(np.sum(~truth))
        for lo, hi in losses.get(c, []):
            out["reacquisitions_expected"] += 1
            out["reacquired_right"] += int(tr.status[hi] == ACQUIRED and athlete(tr.rows)[hi])
    seconds_track = time.perf_counter() - t0
    dets, _, _ = scene(sim, harsh, shift=False)
    a = mv.associate(dets, sim.cameras, F)
    for c, d in enumerate(dets):
        out["multiview"] += int(np.sum((a.rows[:, c] >= 0)
                                       & (d.person[np.maximum(a.rows[:, c], 0)] > 0)))
    back = [hi for c, ls in losses.items() for _, hi in ls]
    out["multiview_back_used"] = int(sum(a.status[hi, c] == mv.USED
                                         for c, ls in losses.items() for _, hi in ls))
    out["present"] = int(sum(_usable(obs[:, c], losses.get(c, [])).sum() for c in range(6)))
    name = "harsh" if harsh else "normal"
    print(f"{name} (seed {seed}, {F} frames, 6 cameras, {out['present']} athlete camera-frames):"
          f" bystander camera-frames chosen: previous per-camera {out['previous']}, new "
          f"per-camera track {out['track']}, multi-view {out['multiview']}; athlete camera-frames"
          f" missed: previous {out['previous_missed']}, new {out['missed']}; lost frames "
          f"{out['lost_frames']} (truth {out['lost_expected']}); re-acquired in the first frame "
          f"back {out['reacquired_right']} of {out['reacquisitions_expected']} losses (multi-view:"
          f" {out['multiview_back_used']} of {len(back)}); per-camera tracks "
          f"{seconds_track:.2f} s")
    return out


def sweep(seeds):
    """The harsh scene on other simulations (per-camera tracks only)."""
    taken, missed = [], []
    for seed in seeds:
        sim = simulate_session(seed=seed, frames_per_run=F)
        dets, obs, losses = scene(sim, True)
        t, m = 0, 0
        for c, d in enumerate(dets):
            tr = follow_person(d, image_centre=CENTRE)
            ch = tr.rows >= 0
            t += int(np.sum(d.person[tr.rows[ch]] > 0))
            m += int(np.sum(_usable(obs[:, c], losses.get(c, []))
                            & ~(ch & (d.person[np.maximum(tr.rows, 0)] == 0))))
        taken.append(t)
        missed.append(m)
    print(f"harsh scene on seeds {seeds[0]}-{seeds[-1]} (per-camera tracks): bystander "
          f"camera-frames {taken}, athlete camera-frames missed {missed}")
    return sum(taken), sum(missed)


def main() -> int:
    t0 = time.perf_counter()
    n = run(8, False)
    h = run(31, True)
    sweep_taken, sweep_missed = sweep(list(range(40, 50)))
    held_taken, held_missed = sweep(list(range(60, 70)))
    print(f"total {time.perf_counter() - t0:.0f} s")
    print(f"RESULT normal_bystander_previous={n['previous']} normal_bystander_track={n['track']} "
          f"normal_bystander_multiview={n['multiview']} normal_missed_previous="
          f"{n['previous_missed']} normal_missed={n['missed']} normal_reacquired="
          f"{n['reacquired_right']}/{n['reacquisitions_expected']} "
          f"harsh_bystander_previous={h['previous']} harsh_bystander_track={h['track']} "
          f"harsh_bystander_multiview={h['multiview']} harsh_missed_previous="
          f"{h['previous_missed']} harsh_missed={h['missed']} harsh_reacquired="
          f"{h['reacquired_right']}/{h['reacquisitions_expected']} "
          f"harsh_multiview_back={h['multiview_back_used']}/{h['reacquisitions_expected']} "
          f"sweep_bystander_track={sweep_taken} sweep_missed={sweep_missed} "
          f"heldout_bystander_track={held_taken} heldout_missed={held_missed}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
