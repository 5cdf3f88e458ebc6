"""photogram.track.tracks (and tracks2d, sync, rays): the marker table from
synchronized videos. Synthetic videos drawn here (tests/track_scenes.py:
Gaussian markers moving with the simulated jump over a textured arena seen
by the three true field views), and the rendered jump videos when the
renderer is there (issue 19). The goals: every ok row right (no wrong
label in any exposure), centres to 0.2 px RMS, lost or ambiguous markers
flagged instead of guessed."""

import numpy as np
import pandas as pd
import pytest

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

pytest.importorskip("cv2")

from track_scenes import blob_image, jump_markers, render_views  # noqa: E402

from photogram.errors import InputError  # noqa: E402
from photogram.lines.views import ViewCamera  # noqa: E402
from photogram.simulation.ski_lines import field_cameras  # noqa: E402
from photogram.track.tracks import COLUMNS, track_markers  # noqa: E402
from photogram.track.tracks2d import TrackSettings  # noqa: E402

MARKERS = ["P1", "P2", "P3", "P4"]
T = 40
EXPO = {f"{k + 1:03d}": 8 + k for k in range(24)}        # reference frames 8..31
OFFSETS = {"S1": 0, "S2": 2, "S3": -1}                    # frames started late


def _seeds(truth, offsets, frame=6, click=0.6, markers=MARKERS):
    rng = np.random.default_rng(4)
    rows = []
    for st, tr in truth.items():
        f = frame - offsets.get(st, 0)
        for i, m in enumerate(markers):
            rows.append((st, f, m, *(tr[f, i] + rng.normal(0, click / np.sqrt(2), 2))))
    return pd.DataFrame(rows, columns=["station", "frame", "marker", "x", "y"])


def _evaluate(table, truth, offsets, wrong_px=1.0):
    """Errors of the ok rows; rows that are wrong (off by more than wrong_px,
    or a hidden marker reported)."""
    errs, wrong = [], []
    for r in table.itertuples():
        f = EXPO[r.exposure] - offsets[r.station]
        t = truth[r.station][f, MARKERS.index(r.marker)]
        if r.status == "ok":
            e = np.hypot(r.x - t[0], r.y - t[1]) if np.isfinite(t).all() else np.inf
            errs.append(e)
            if e > wrong_px:
                wrong.append(r)
    return np.array(errs), wrong


@pytest.fixture(scope="module")
def cams():
    return field_cameras()


@pytest.fixture(scope="module")
def separate(cams):
    """Bindings moved apart (every marker its own blob), P1 hidden in S2 for
    three frames, S2 two frames late, S3 one frame early."""
    X = jump_markers(T, separate_bindings=True)
    vis = {"S2": np.ones((T, 4), bool)}
    vis["S2"][18:21, 0] = False
    frames, truth = render_views(cams, X, visible=vis, offsets=OFFSETS)
    return X, frames, truth


@pytest.fixture(scope="module")
def separate_backgrounds(separate):
    """The backgrounds of the ``separate`` frames, as ``track_markers``
    estimates them when not given (shared by the tests that track those
    frames unchanged; ~0.2 s CPU per call)."""
    from photogram.track.background import estimate_background
    return {n: estimate_background(F) for n, F in separate[1].items()}


@pytest.fixture(scope="module")
def separate_result(cams, separate):
    _, frames, truth = separate
    return track_markers(frames, cams, _seeds(truth, OFFSETS), MARKERS, EXPO)


def test_precondition_bindings_are_apart(cams, separate):
    X = separate[0]
    for cam in cams.values():
        q = np.stack([cam.project(X[:, k]) for k in range(4)], 1)
        d = np.linalg.norm(q[:, :, None] - q[:, None], axis=3)
        d[:, range(4), range(4)] = np.inf
        assert d.min() > 5.0


def test_table_has_exactly_the_columns_and_rows(separate_result):
    tab = separate_result.table
    assert list(tab.columns) == COLUMNS
    assert len(tab) == 24 * 3 * 4
    assert list(dict.fromkeys(tab.exposure)) == list(EXPO)
    assert set(tab.status) <= {"ok", "lost", "ambiguous"}
    bad = tab.status != "ok"
    assert tab.loc[bad, ["x", "y", "sigma"]].isna().all().all()
    assert tab.loc[~bad, ["x", "y", "sigma"]].notna().all().all()
    assert (tab.reason.str.len() > 0).all()


def test_sync_offsets_are_estimated(separate_result):
    assert separate_result.offsets == OFFSETS
    assert all(separate_result.sync.clear.values())


def test_separate_markers_are_tracked_right(separate_result, separate):
    _, _, truth = separate
    tab = separate_result.table
    errs, wrong = _evaluate(tab, truth, OFFSETS)
    assert not wrong
    assert np.sqrt(np.mean(errs ** 2)) < 0.1
    # P1 hidden in S2 at instants 18..20 (exposures 011-013): flagged, not guessed
    hidden = tab[(tab.station == "S2") & (tab.marker == "P1")
                 & tab.exposure.isin(["011", "012", "013"])]
    assert (hidden.status != "ok").all()
    assert (hidden.status == "lost").sum() >= 2
    # and tracked again after the occlusion
    after = tab[(tab.station == "S2") & (tab.marker == "P1") & (tab.exposure >= "015")]
    assert (after.status == "ok").mean() > 0.9
    # nearly everything else ok
    assert (tab.status == "ok").sum() >= len(tab) - 3 - 6


def test_merged_bindings_are_flagged_never_guessed(cams):
    """The true jump: P3 and P4 image 0.6-3 px apart (one blob or two
    touching ones): their rows are ambiguous, P1 and P2 ok."""
    X = jump_markers(T)
    frames, truth = render_views(cams, X, offsets=OFFSETS, seed=7)
    res = track_markers(frames, cams, _seeds(truth, OFFSETS), MARKERS, EXPO,
                        offsets=OFFSETS)
    tab = res.table
    errs, wrong = _evaluate(tab, truth, OFFSETS)
    assert not wrong
    bind = tab[tab.marker.isin(["P3", "P4"])]
    assert (bind.status != "ok").all()
    assert (bind.status == "ambiguous").mean() > 0.5
    head = tab[tab.marker.isin(["P1", "P2"])]
    assert (head.status == "ok").mean() > 0.95


def test_a_distractor_in_the_gate_makes_it_ambiguous(cams, separate):
    """A second bright spot 2 px from P2 in S1 for three frames: P2 is
    ambiguous there (two blobs in the gate), right elsewhere."""
    X, frames, truth = separate
    fr = {k: v.copy() for k, v in frames.items()}
    for f in (20, 21, 22):
        img = fr["S1"][f].astype(np.float32)
        img += blob_image(img.shape, truth["S1"][f, 1:2] + [2.0, 0.0], 150.0)
        fr["S1"][f] = np.clip(img, 0, 255).astype(np.uint8)
    res = track_markers(fr, cams, _seeds(truth, OFFSETS), MARKERS, EXPO, offsets=OFFSETS)
    tab = res.table
    _, wrong = _evaluate(tab, truth, OFFSETS)
    assert not wrong
    hit = tab[(tab.station == "S1") & (tab.marker == "P2")
              & tab.exposure.isin(["013", "014", "015"])]
    assert (hit.status == "ambiguous").all()


def test_perturbed_orientation_gives_no_wrong_label(cams, separate, separate_backgrounds):
    """An estimated orientation (angles off by 0.03 gon, centres by 0.5 dm):
    the checks use its tolerance, labels stay right."""
    from photogram.geometry import matrix_to_opk
    rng = np.random.default_rng(2)
    est = {n: ViewCamera.from_angles(matrix_to_opk(c.R) + rng.normal(0, 0.03 * np.pi / 200, 3),
                                     c.X0 + rng.normal(0, 0.5, 3), c.io, c.model, n)
           for n, c in cams.items()}
    _, frames, truth = separate
    res = track_markers(frames, est, _seeds(truth, OFFSETS), MARKERS, EXPO,
                        backgrounds=separate_backgrounds)
    assert res.offsets == OFFSETS
    errs, wrong = _evaluate(res.table, truth, OFFSETS)
    assert not wrong
    assert (res.table.status == "ok").mean() > 0.9


def _perturbed(cams, gon, dm, seed=2):
    from photogram.geometry import matrix_to_opk
    rng = np.random.default_rng(seed)
    return {n: ViewCamera.from_angles(matrix_to_opk(c.R) + rng.normal(0, gon * np.pi / 200, 3),
                                      c.X0 + rng.normal(0, dm, 3), c.io, c.model, n)
            for n, c in cams.items()}


def test_poor_orientation_bias_is_compensated_and_sync_refused(cams, separate,
                                                              separate_backgrounds):
    """Angles 0.3 gon off (reprojections several px off): with the offsets
    given, the systematic error is estimated and the labels stay right;
    asked to estimate the offsets, the tracker refuses instead of guessing."""
    _, frames, truth = separate
    est = _perturbed(cams, 0.3, 1.0, seed=3)
    X = separate[0]
    off = max(np.hypot(*(est[n].project(X[15]) - cams[n].project(X[15])).T).max()
              for n in cams)
    assert off > 3.0                       # the orientation error is real
    res = track_markers(frames, est, _seeds(truth, OFFSETS), MARKERS, EXPO, offsets=OFFSETS,
                        backgrounds=separate_backgrounds)
    _, wrong = _evaluate(res.table, truth, OFFSETS)
    assert not wrong
    assert (res.table.status == "ok").mean() > 0.9
    with pytest.raises(InputError, match="sync offset of camera S[23] is not clear"):
        track_markers(frames, est, _seeds(truth, OFFSETS), MARKERS, EXPO,
                      backgrounds=separate_backgrounds)


def test_seed_far_from_any_marker_is_named_and_the_rest_goes_on(cams, separate,
                                                               separate_backgrounds):
    """A click 25 px off its marker is not used: the marker goes without a
    seed in that camera (found again from the other cameras' 3D track, or
    flagged), the reason names station, frame and marker, nothing is
    wrong; the other markers are tracked as before."""
    _, frames, truth = separate
    seeds = _seeds(truth, OFFSETS)
    k = seeds.index[(seeds.station == "S2") & (seeds.marker == "P2")][0]
    seeds.loc[k, "x"] += 25.0
    res = track_markers(frames, cams, seeds, MARKERS, EXPO, offsets=OFFSETS,
                        backgrounds=separate_backgrounds)
    assert len(res.notes) == 1 and "seed of P2 in S2 frame 4" in res.notes[0]
    assert "not used" in res.notes[0] and "\n" not in res.notes[0]
    _, wrong = _evaluate(res.table, truth, OFFSETS)
    assert not wrong
    others = res.table[res.table.marker != "P2"]
    assert (others.status == "ok").mean() > 0.9


def test_blank_camera_is_named(cams, separate):
    _, frames, truth = separate
    fr = dict(frames)
    rng = np.random.default_rng(0)
    blank = np.empty_like(frames["S3"])
    for k in range(len(blank)):     # frame by frame: the same draws as in one call, ~0.2 GB less
        blank[k] = np.clip(rng.normal(120, 2, blank.shape[1:]), 0, 255)
    fr["S3"] = blank
    with pytest.raises(InputError, match="camera S3 sees none of the markers") as e:
        track_markers(fr, cams, _seeds(truth, OFFSETS), MARKERS, EXPO, offsets=OFFSETS)
    assert "\n" not in str(e.value)


def test_bad_tables_are_input_errors(cams, separate):
    _, frames, truth = separate
    seeds = _seeds(truth, OFFSETS)
    with pytest.raises(InputError, match="unknown station S9"):
        track_markers(frames, cams, seeds.replace({"station": {"S3": "S9"}}), MARKERS, EXPO)
    with pytest.raises(InputError, match="two seed clicks for P1 in S1"):
        track_markers(frames, cams, pd.concat([seeds, seeds.iloc[:1]]), MARKERS, EXPO)
    with pytest.raises(InputError, match="exposure, frame"):
        track_markers(frames, cams, seeds, MARKERS, pd.DataFrame({"e": [1]}))


# ----------------------------------------------------------------------------
# the rendered jump videos (photogram.simulation.jump_video, colleague's branch)

def _rendered(kind):
    from jump_videos import rendered_videos      # rendered once per session
    return rendered_videos(kind)


def _run_rendered(kind):
    """track_markers on the ``kind`` set: its frames, cameras and seeds,
    MARKERS, the 24 exposures as frames of S1 (the first camera), the
    offsets estimated, default settings (the renderer paints in the
    project's frame, top-left corner at (0, 0)); computed once per session
    by tests/jump_videos.py, which test_track_bindings shares."""
    from jump_videos import MARKERS as SHARED, tracked_markers
    assert list(SHARED) == MARKERS
    v = _rendered(kind)
    assert next(iter(v.frames)) == "S1" and len(v.exposure_frames["S1"]) == 24
    res = tracked_markers(kind)[1]
    t = v.truth_markers.set_index(["exposure", "station", "marker"])
    m = res.table.join(t[["x", "y", "visible"]], on=["exposure", "station", "marker"],
                       rsuffix="_true")
    ok = m[m.status == "ok"]
    err = np.hypot(ok.x - ok.x_true, ok.y - ok.y_true)
    wrong = (err > 1.0) | (ok.visible.astype(str) != "True")
    return res, m, err, wrong


def test_rendered_normal_meets_the_goals():
    res, m, err, wrong = _run_rendered("normal")
    assert wrong.sum() == 0
    assert np.sqrt(np.mean(err ** 2)) <= 0.2
    vis = m.visible.astype(str) == "True"
    head = m[vis & m.marker.isin(["P1", "P2"])]
    assert (head.status == "ok").mean() > 0.9
    assert all(v == 0 for v in res.offsets.values())


@pytest.mark.xfail(strict=True, reason=(
    "harsh set (not tuned on), measured 2026-12-02: 2 wrong labels of 137 ok rows (the "
    "marker tracker alone). S2's seed of P3 (frame 12) is 5.8 px from every blob and is "
    "not used; the seed of P4 in the same frame snaps to a blob 5.3 px from the true "
    "marker (within the 5 px seed radius) and is tracked wrongly at 001 and 006 (P3/P4 "
    "are ambiguous in the other views, so no 3D check can catch it here; the binding "
    "split after it flags 006, photogram track keeps 001 wrong). S2's P1 re-acquired 7 "
    "px off at 020 after its occlusion at 019 is now flagged by the left-out residual. "
    "Centres of the right ones 0.19 px RMS, S3's lag of 1 frame found. docs/track.md "
    "section 4."))
def test_rendered_harsh_reported_with_a_looser_bound():
    """Not tuned on: no wrong label allowed still, the centres to 0.3 px."""
    res, m, err, wrong = _run_rendered("harsh")
    print("harsh:", res.offsets, m.status.value_counts().to_dict(),
          "rms", float(np.sqrt(np.mean(err[~wrong] ** 2))), "wrong", int(wrong.sum()))
    assert wrong.sum() == 0
    assert np.sqrt(np.mean(err ** 2)) <= 0.3
    assert res.offsets["S3"] == 1


def test_markers_found_at_their_3d_prediction_are_right():
    """The harsh set (not tuned on) loses markers in some views that the
    3D search (``tracks3d.fill_3d``: the marker's triangulated track
    projected into the view, one blob inside the gate) finds again: 5 rows,
    measured 2026-12-03 (the normal set needs none). Each must be the true
    marker: within 1 px of the rendered truth. Projections handed to the
    wrong markers find none of them."""
    res, m, err, wrong = _run_rendered("harsh")
    ok = m[m.status == "ok"]
    found = ok.reason.astype(str).str.contains("at the 3D prediction").to_numpy()
    assert found.sum() >= 3, ok.reason.value_counts().to_dict()
    assert not wrong.to_numpy()[found].any()
    assert np.all(err.to_numpy()[found] < 1.0)


def test_scatter_sigma_measures_the_track_noise():
    from photogram.track.tracks2d import scatter_sigma
    t = np.arange(300, dtype=float) / 5
    xy = np.column_stack([400 - 18 * t + 0.02 * t ** 2, 80 + 9 * t + 0.15 * t ** 2])
    ok = np.ones(300, bool)
    ok[[10, 11, 30]] = False                       # gaps are fine
    assert scatter_sigma(xy, ok) < 1e-6            # a smooth track has none
    rng = np.random.default_rng(1)
    noisy = xy + rng.normal(0, 0.2, xy.shape)
    assert scatter_sigma(noisy, ok) == pytest.approx(0.2, rel=0.15)
    assert np.isnan(scatter_sigma(noisy, np.arange(300) < 5))


def test_left_out_residuals_show_a_wrong_view_that_the_joint_residuals_hide():
    """Three field cameras on one side of the hill: a point 5 px off in one
    view along the direction the others see worst leaves joint residuals
    below 3 px; the residual against the other two views' point shows the
    5 px whole."""
    from photogram.simulation.ski_lines import field_cameras
    from photogram.track.rays import reprojection_residuals, triangulate
    from photogram.track.tracks3d import left_out_residuals
    from photogram.simulation.jump import jump_truth
    cams = list(field_cameras().values())
    X = np.asarray(jump_truth()["P"])[[3, 15], 1]           # the hip at two exposures
    xy = np.stack([c.project(X) for c in cams])            # (3, 2, 2)
    assert ((xy > 0) & (xy < [640, 480])).all()
    # the direction in view 1 along which the other two views' point moves
    # least per pixel: the epipolar direction of the point of views 0 and 2
    Xa = X + np.array([1.0, 0.0, 0.0])
    step = cams[1].project(Xa) - xy[1]
    e = step / np.linalg.norm(step, axis=1, keepdims=True)
    bad = xy.copy()
    bad[1] += 5.0 * e
    lo = left_out_residuals(cams, bad)
    np.testing.assert_allclose(lo[1], 5.0, atol=1e-6)
    Xj, _ = triangulate(cams, bad)
    joint = reprojection_residuals(cams, Xj, bad)
    assert np.nanmax(joint) < 3.0                          # the check's tolerance
    assert np.isnan(left_out_residuals(cams[:2], bad[:2])).all()
