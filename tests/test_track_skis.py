"""Ski lines tracked in video frames (photogram.track.skis, issue 19 item 4).

Synthetic frames are drawn here: skis as antialiased dark bars (supersampled
coverage) on bright noisy snow, the body as darker bars (the suit), the
three field views of the simulated jump. The integration test with the
rendered videos of photogram.simulation.jump_video runs when that module is
there.
"""

import numpy as np
import pandas as pd
import pytest

from photogram.track.ski_axes import BarLine, noise_sigma, sample_axis
from photogram.track.ski_edges import fit_ski_pair
from photogram.track.skis import track_skis

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

SNOW, SKI, SUIT = 205.0, 88.0, 35.0


def draw_bar(img, p0, p1, width, grey, ss=4):
    """Paint an antialiased bar p0-p1 of ``width`` px and ``grey`` on img
    (in place): the coverage of each pixel from ss x ss samples."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    H, W = img.shape
    lo = np.maximum(np.floor(np.minimum(p0, p1) - width - 2).astype(int), 0)
    hi = np.minimum(np.ceil(np.maximum(p0, p1) + width + 2).astype(int), [W - 1, H - 1])
    if np.any(hi < lo):
        return
    off = (np.arange(ss) + 0.5) / ss - 0.5
    yy, xx = np.mgrid[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1].astype(float)
    X = xx[..., None, None] + off[None, None, None, :]
    Y = yy[..., None, None] + off[None, None, :, None]
    u = p1 - p0
    L = np.linalg.norm(u)
    u /= L
    t = (X - p0[0]) * u[0] + (Y - p0[1]) * u[1]
    d = -(X - p0[0]) * u[1] + (Y - p0[1]) * u[0]
    cov = ((t >= 0) & (t <= L) & (np.abs(d) <= width / 2)).mean((-1, -2))
    sub = img[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1]
    sub[...] = sub * (1 - cov) + grey * cov


def finish(img, rng, noise=2.0):
    """Light blur (3-tap binomial), noise, 8 bits."""
    k = np.array([0.25, 0.5, 0.25])
    img = np.apply_along_axis(lambda r: np.convolve(r, k, "same"), 1, img)
    img = np.apply_along_axis(lambda c: np.convolve(c, k, "same"), 0, img)
    return np.clip(np.round(img + rng.normal(0, noise, img.shape)), 0, 255).astype(np.uint8)


def median_background(frames):
    """Temporal median of frames (F, H, W) as float: ``np.median(frames,
    axis=0)`` exactly (the mean of the two middle uint8 values is exact in
    float64), by the background's sorting network (0.13 s CPU for 24
    frames with np.median, 0.02 s so)."""
    from photogram.track.background import sorted_images
    frames = np.asarray(frames)
    if frames.dtype != np.uint8 or not 1 <= len(frames) <= 32:
        return np.median(frames, axis=0).astype(float)
    s = sorted_images(frames)
    k = (len(s) - 1) // 2
    return s[k].astype(float) if len(s) % 2 else (s[k].astype(float) + s[k + 1]) / 2


def axis_errors(xy, tail, tip):
    """Direction error (deg) of the principal axis of points xy against the
    segment tail-tip, and the points' distances from it (px)."""
    u = (tip - tail) / np.linalg.norm(tip - tail)
    n = np.array([-u[1], u[0]])
    c = xy - xy.mean(0)
    d = np.linalg.eigh(c.T @ c)[1][:, -1]
    d = d if d @ u > 0 else -d
    ang = np.degrees(np.arctan2(u[0] * d[1] - u[1] * d[0], u @ d))
    return ang, (xy - tail) @ n


# ---------------------------------------------------------------- one image

def _pair_scene(seed=0, body=True):
    rng = np.random.default_rng(seed)
    img = np.full((140, 220), SNOW)
    img += np.linspace(-10, 10, 220)[None, :]                    # a gentle gradient
    bg = img.copy()
    ends = [(np.array([185.0, 70.0]), np.array([40.0, 66.0])),   # tail, tip
            (np.array([187.0, 68.5]), np.array([35.0, 75.0]))]
    if body:                                                     # legs and trunk, darker
        draw_bar(img, (120, 67), (85, 50), 6.0, SUIT)
        draw_bar(img, (85, 50), (55, 40), 7.0, SUIT)
    for tail, tip in ends[::-1]:
        draw_bar(img, tail, tip, 2.6, SKI)
    return finish(img, rng), bg, ends


def _initial(ends, turn_deg=0.6, shift=0.6):
    out = []
    for k, (tail, tip) in enumerate(ends):
        u = (tip - tail) / np.linalg.norm(tip - tail)
        a = np.radians(turn_deg * (1 - 2 * k))
        u = np.array([np.cos(a) * u[0] - np.sin(a) * u[1], np.sin(a) * u[0] + np.cos(a) * u[1]])
        b = tail + 0.43 * (tip - tail) + shift * np.array([-u[1], u[0]])
        L = np.linalg.norm(tip - tail)
        out.append(BarLine(b, u, np.array([-0.43 * L, 0.57 * L]) * 1.05, 2.0, np.nan))
    return out


@pytest.mark.parametrize("body", [False, True])
def test_pair_fit_direction_and_offset(body):
    frame, bg, ends = _pair_scene(1, body)
    sn = noise_sigma(bg - frame)
    fit = fit_ski_pair(frame, bg, _initial(ends), sigma_noise=sn)
    assert fit.ok, fit.reason
    for line, (tail, tip) in zip(fit.lines, ends):
        pts = sample_axis(line, 15, frame.shape)
        ang, dist = axis_errors(pts, tail, tip)
        assert abs(ang) < 0.1                       # the goal, on clean bars
        assert np.abs(dist).max() < 0.15
        assert abs(line.width - 2.6) < 0.6
        assert line.direction @ (tip - tail) > 0    # oriented tail to tip
        # tail to tip order and the ends within a few px
        assert np.linalg.norm(line.tail - tail) < 3 and np.linalg.norm(line.tip - tip) < 3
        assert line.support > 0.15
        assert np.isfinite(line.cov).all() and np.sqrt(line.cov[0, 0]) < np.radians(0.1)


def test_pair_fit_reports_a_missing_ski():
    rng = np.random.default_rng(2)
    bg = np.full((140, 220), SNOW)
    frame = finish(bg.copy(), rng)                   # no skis at all
    fit = fit_ski_pair(frame, bg, _initial(_pair_scene()[2]),
                       sigma_noise=noise_sigma(bg - frame))
    assert not fit.ok
    assert "contrast" in fit.reason


# --------------------------------------------------- three views, sequences

@pytest.fixture(scope="module")
def field():
    from photogram.simulation.jump import jump_truth
    from photogram.simulation.ski_lines import field_cameras
    return field_cameras(), jump_truth()


def _views(field, exposures, *, seed=3, missing=(), marker_swap=(), lost=(), gains=None):
    """Frames (one per exposure), backgrounds, markers and truth of the
    field views. ``missing``: (exposure, station) drawn without skis;
    ``marker_swap``: (exposure, station) with P3/P4 interchanged; ``lost``:
    (exposure, station) with P3 and P4 lost; ``gains``: brightness factor
    per exposure (auto exposure)."""
    cams, T = field
    rng = np.random.default_rng(seed)
    frames, bgs, rows, truth = {}, {}, [], []
    for st, cam in cams.items():
        bg = np.full((480, 640), SNOW) + np.linspace(-8, 8, 640)[None, :]
        F = []
        for i, e in enumerate(exposures):
            img = bg.copy()
            P = cam.project(T["P"][e])
            tail, tip = cam.project(T["ski_tail"][e]), cam.project(T["ski_tip"][e])
            O = (P[2] + P[3]) / 2
            # image points in the project's convention, drawn at raster = image - 0.5
            r = 0.5
            draw_bar(img, O + 0.3 * (P[1] - O) - r, P[1] - r, 5.0, SUIT)   # thighs
            draw_bar(img, P[1] - r, P[0] - r, 6.0, SUIT)
            if (i + 1, st) not in missing:
                for k in (1, 0):
                    draw_bar(img, tail[k] - r, tip[k] - r, 2.6, SKI)
            F.append(finish(img * (1.0 if gains is None else gains[i]), rng))
            for j, m in enumerate(("P1", "P2", "P3", "P4")):
                name = m
                if (i + 1, st) in marker_swap and m in ("P3", "P4"):
                    name = "P4" if m == "P3" else "P3"
                status = "lost" if (i + 1, st) in lost and m in ("P3", "P4") else "ok"
                x, y = P[j] + rng.normal(0, 0.2, 2)
                rows.append((i + 1, st, name, x, y, 0.2, status, ""))
            for k, lab in enumerate(("L1", "L2")):
                truth.append((i + 1, st, lab, tail[k], tip[k]))
        frames[st] = np.array(F)
        bgs[st] = bg
    markers = pd.DataFrame(rows, columns=["exposure", "station", "marker", "x", "y", "sigma",
                                          "status", "reason"])
    return frames, bgs, cams, markers, truth


def _label_errors(result, truth):
    """Per (exposure, station, line) in the table: direction error and RMS
    distance from its own ski's true axis and from the other ski's."""
    t = {(e, st, lab): (a, b) for e, st, lab, a, b in truth}
    out = []
    for (e, st, lab), g in result.table.groupby(["exposure", "station", "line"]):
        xy = g[["x", "y"]].to_numpy()
        other = "L2" if lab == "L1" else "L1"
        ang, d = axis_errors(xy, *t[(e, st, lab)])
        _, d_other = axis_errors(xy, *t[(e, st, other)])
        out.append((e, st, lab, ang, np.sqrt(np.mean(d ** 2)), np.sqrt(np.mean(d_other ** 2)),
                    len(g)))
    return pd.DataFrame(out, columns=["exposure", "station", "line", "angle", "dist",
                                      "dist_other", "n"])


def test_track_three_views(field):
    frames, bgs, cams, markers, truth = _views(field, [0, 1, 2, 3, 4])
    res = track_skis(frames, bgs, cams, markers, np.arange(5))
    assert list(res.table.columns) == ["exposure", "station", "line", "x", "y", "sigma"]
    err = _label_errors(res, truth)
    # every ski found or flagged, never both; 15 points each, tail to tip
    found = set(zip(err.exposure, err.station, err.line))
    flagged = set(zip(res.flags.exposure, res.flags.station, res.flags.line))
    assert not found & flagged and len(found | flagged) == 5 * 3 * 2
    assert len(found) >= 24
    assert (err.n == 15).all()
    # labels right (closer to their own ski), directions within a few tenths
    assert (err.dist < err.dist_other).all()
    assert np.sqrt(np.mean(err.angle ** 2)) < 0.3
    assert err.dist.max() < 1.0
    assert set(res.checks.status) <= {"ok", "swapped", "flagged"}
    assert (res.checks.status != "flagged").sum() >= 3
    assert (res.table.sigma > 0).all()


def test_brightness_changes(field):
    # a +-4 % brightness change per frame (auto exposure) against the median
    # background: the frame's gain is measured and the background scaled
    from photogram.track.background import frame_gain as _frame_gain
    gains = [1.04, 0.96, 1.04, 0.96]
    frames, bgs, cams, markers, truth = _views(field, [6, 7, 8, 9], gains=gains)
    for st in frames:
        g = [_frame_gain(f.astype(float), bgs[st]) for f in frames[st]]
        assert np.allclose(g, gains, atol=0.003)
    res = track_skis(frames, bgs, cams, markers, np.arange(4))
    err = _label_errors(res, truth)
    assert len(err) == 24 and (err.dist < err.dist_other).all()
    assert np.sqrt(np.mean(err.angle ** 2)) < 0.4 and err.dist.max() < 0.5


def test_swapped_binding_markers_are_corrected(field):
    swap = {(e, "S2") for e in range(1, 5)}
    frames, bgs, cams, markers, truth = _views(field, [6, 7, 8, 9], marker_swap=swap)
    # the check corrects the labels the (swapped) binding markers gave
    res = track_skis(frames, bgs, cams, markers, np.arange(4))
    # with trust_bindings the same swap contradicts the bindings: flagged
    # with the reason, the labels left as the bindings say
    trusted = track_skis(frames, bgs, cams, markers, np.arange(4), trust_bindings=True)
    fl = trusted.checks[trusted.checks.detail.str.contains("binding markers of S2 say")]
    assert len(fl) >= 3 and (fl.status == "flagged").all()
    assert (trusted.checks.status != "swapped").all()
    err = _label_errors(res, truth)
    # the table's labels are right in every view after the three-view check
    assert (err.dist < err.dist_other).all()
    checked = res.checks[res.checks.check.isin(["ok", "swapped", "ambiguous"])]
    assert len(checked) >= 3
    # and the swaps in S2 are reported
    swapped = res.checks[res.checks.status == "swapped"]
    assert len(swapped) >= 3
    assert all("S2" in s.split(",") for s in swapped.swapped)


def test_missing_skis_and_markers_are_flagged(field):
    frames, bgs, cams, markers, truth = _views(field, [10, 11, 12],
                                               missing={(2, "S1")}, lost={(3, "S3")})
    res = track_skis(frames, bgs, cams, markers, np.arange(3))
    f = res.flags
    assert set(f[(f.exposure == 2) & (f.station == "S1")].line) == {"L1", "L2"}
    lost = f[(f.exposure == 3) & (f.station == "S3")]
    assert set(lost.line) == {"L1", "L2"} and (lost.reason == "no binding marker").all()
    t = res.table
    assert t[(t.exposure == 2) & (t.station == "S1")].empty
    assert t[(t.exposure == 3) & (t.station == "S3")].empty
    # without three views the label check cannot run: flagged, with the reason
    c = res.checks.set_index("exposure")
    assert c.loc[2, "status"] == "flagged" and "needs 3" in c.loc[2, "detail"]
    # the skis are found again in S1 at exposure 3, or one is flagged for the
    # reason of that view (the skis there overlap: the support of one is
    # 0.14-0.16 depending on where the pixel grid falls and the fit stops)
    back = t[(t.exposure == 3) & (t.station == "S1")]
    assert len(back) in (15, 30)
    if len(back) == 15:
        why = f[(f.exposure == 3) & (f.station == "S1")]
        assert len(why) == 1 and "support" in why.reason.iloc[0]
        assert set(why.line) | set(back.line) == {"L1", "L2"}


# ----------------------------------------------------- the rendered videos

def _rendered(kind):
    from jump_videos import rendered_videos      # rendered once per session
    v = rendered_videos(kind)
    rng = np.random.default_rng(11)
    tm = v.truth_markers
    markers = pd.DataFrame({
        "exposure": tm.exposure, "station": tm.station, "marker": tm.marker,
        "x": tm.x + rng.normal(0, 0.2, len(tm)), "y": tm.y + rng.normal(0, 0.2, len(tm)),
        "sigma": 0.2, "status": np.where(tm.visible, "ok", "lost"), "reason": ""})
    bgs = {}
    for st, F in v.frames.items():
        ef = np.asarray(v.exposure_frames[st])
        lead = np.setdiff1d(np.arange(len(F)), ef)       # the jumper is not there
        bgs[st] = median_background(F[lead])
    res = track_skis(v.frames, bgs, v.cameras, markers, v.exposure_frames)
    ts = v.truth_skis
    truth = [(e, st, lab, np.array([a, b]), np.array([c, d])) for e, st, lab, a, b, c, d in
             zip(ts.exposure, ts.station, ts.ski, ts.x_tail, ts.y_tail, ts.x_tip, ts.y_tip)]
    return res, _label_errors(res, truth)


def test_rendered_normal_videos():
    res, err = _rendered("normal")
    # measured on the normal set (benchmarks/track_skis.py): direction RMS
    # 0.15 deg, max 1.1 deg, 77 % of the skis within 0.1 deg, points 0.06 px
    # RMS from the true axes, 4 of 144 ski images flagged; the 0.1 deg goal
    # is met for most but not all skis (a ski along the suit's edge or
    # behind it is seen over a short length only)
    assert len(err) >= 0.8 * 24 * 3 * 2
    assert len(err) + len(res.flags) == 24 * 3 * 2
    assert (err.dist < err.dist_other).mean() > 0.9
    assert np.sqrt(np.mean(err.angle ** 2)) < 0.3
    assert (err.angle.abs() < 0.1).mean() > 0.6
    assert np.sqrt(np.mean(err.dist ** 2)) < 0.2
    assert (res.checks.status != "flagged").sum() >= 15


def test_rendered_harsh_videos():
    # not tuned on: measured (with the true frame offsets, as here; the true
    # markers + 0.2 px) 113 of 144 ski images, direction RMS 0.50 deg, max
    # 2.1 deg, 95 % nearer their own ski (3 nearer the other and more than
    # 0.5 px off their own), 26 flagged as not decided by the three-view
    # check (the label check scales the point sigmas by its own s0 where no
    # assignment fits them). Before the check's s0, the undecided views'
    # flags and the sequence check: 1.2 deg RMS, max 7 deg, 80 % right.
    # Asserted: every ski image measured or flagged, most measured, labels
    # right, directions within a degree
    res, err = _rendered("harsh")
    assert len(err) + len(res.flags) == 24 * 3 * 2
    assert len(err) >= 0.7 * 24 * 3 * 2
    assert (err.dist < err.dist_other).mean() > 0.9
    assert np.sqrt(np.mean(err.angle ** 2)) < 1.0


def test_bar_model_jacobian_is_analytic_and_matches_finite_differences():
    """The two-bar model's Jacobian (angle, shift, ends of each bar; width,
    grey, blur) against central differences."""
    from photogram.track import ski_edges as se
    rng = np.random.default_rng(0)
    x, y = np.meshgrid(np.arange(24.0), np.arange(30.0))
    x, y = x.ravel(), y.ravel()
    bg = 200 + rng.normal(0, 3, x.shape)
    ref, u0 = np.array([11.0, 15.0]), np.array([0.6, 0.8])
    for th in (np.array([0.05, 1.2, -8, 9, -0.03, -2.1, -7, 10, 2.5, 90, 0.8]),
               np.array([-0.2, 0.3, -12, 4, 0.1, 0.0, -3, 12, 1.2, 120, 1.6])):
        J = se._model_jacobian(th, x, y, bg, ref, u0)
        for k in range(11):
            h = 1e-6 * max(1.0, abs(th[k]))
            e = np.zeros(11)
            e[k] = h
            fd = (se._model(th + e, x, y, bg, ref, u0)
                  - se._model(th - e, x, y, bg, ref, u0)) / (2 * h)
            np.testing.assert_allclose(J[:, k], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_fused_pair_model_equals_the_two_bar_composition():
    """The fused two-bar evaluation (both bars in one array pass, ndtr only
    where it is not saturated) gives eq. (2) composed from each bar's
    eq. (1) coverage, also far beyond the bars' ends and sides; the
    residual object's Jacobian (reusing the terms of the last residual
    evaluation) equals the analytic one at whatever point it is asked."""
    from scipy.special import ndtr
    from photogram.track import ski_edges as se
    rng = np.random.default_rng(1)
    x, y = np.meshgrid(np.arange(-40.0, 60.0), np.arange(-30.0, 50.0))
    x, y = x.ravel(), y.ravel()
    bg = 200 + rng.normal(0, 3, x.shape)
    ref, u0 = np.array([11.0, 15.0]), np.array([0.6, 0.8])
    th = np.array([0.05, 1.2, -8, 9, -0.03, -2.1, -7, 10, 2.5, 90, 0.8])
    w, s = th[8], th[10]

    def coverage(ang, c, a, b):                              # eq. (1), one bar
        u = np.array([u0[0] * np.cos(ang) - u0[1] * np.sin(ang),
                      u0[0] * np.sin(ang) + u0[1] * np.cos(ang)])
        p = ref + c * np.array([-u0[1], u0[0]])
        d = -(x - p[0]) * u[1] + (y - p[1]) * u[0]
        t = (x - p[0]) * u[0] + (y - p[1]) * u[1]
        return ((ndtr((d + w / 2) / s) - ndtr((d - w / 2) / s))
                * (ndtr((t - a) / s) - ndtr((t - b) / s)))

    c1, c2 = coverage(*th[:4]), coverage(*th[4:8])
    expected = (bg - th[9]) * (c1 + c2 - c1 * c2)
    assert (expected == 0).mean() > 0.5                     # most pixels saturated
    np.testing.assert_allclose(se._model(th, x, y, bg, ref, u0), expected, rtol=0, atol=1e-10)
    v = expected + rng.normal(0, 2, x.shape)
    problem = se._PairResiduals(x, y, bg, v, ref, u0)
    other = th + 0.01
    np.testing.assert_allclose(problem.fun(other), se._model(other, x, y, bg, ref, u0) - v,
                               rtol=0, atol=1e-10)
    for at in (other, th):          # the cached point, then a point not evaluated
        np.testing.assert_allclose(problem.jac(at), se._model_jacobian(at, x, y, bg, ref, u0),
                                   rtol=0, atol=1e-12)


def test_robust_lm_matches_scipy_soft_l1_with_bounds():
    """The module's soft-L1 Levenberg-Marquardt reaches scipy's
    least_squares(loss="soft_l1") minimum on a bounded exponential fit with
    outliers, and keeps a parameter on its bound where the bound binds."""
    from scipy.optimize import least_squares
    from photogram.track.ski_edges import robust_lm
    rng = np.random.default_rng(3)
    t = np.linspace(0, 4, 200)
    y = 3.0 * np.exp(-0.7 * t) + 0.5 + rng.normal(0, 0.02, t.size)
    y[::17] += 1.5                                          # outliers

    def fun(p):
        return p[0] * np.exp(-p[1] * t) + p[2] - y

    def jac(p):
        e = np.exp(-p[1] * t)
        return np.column_stack([e, -p[0] * t * e, np.ones_like(t)])

    for upper_c in (np.inf, 0.4):                           # free, then binding
        lo, hi = np.array([0, 0, -1.0]), np.array([10, 5, upper_c])
        ref = least_squares(fun, [1, 1, 0], jac=jac, bounds=(lo, hi), loss="soft_l1",
                            f_scale=0.06, xtol=1e-12, ftol=1e-12, gtol=1e-12)
        res = robust_lm(fun, jac, np.array([1, 1, 0.0]), lo, hi, f_scale=0.06,
                        xtol=1e-10, ftol=1e-14, max_iter=200)
        assert res.status > 0
        np.testing.assert_allclose(res.x, ref.x, atol=2e-5)
        assert np.all(res.x >= lo) and np.all(res.x <= hi)
    assert res.x[2] == 0.4


def test_crop_around_gives_the_frames_tophat():
    """The binding split's top-hat of a crop equals the whole frame's
    top-hat in the crop's fitting windows."""
    from photogram.track.spots import _crop_around
    from photogram.track.spots import _tophat
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 255, (120, 160)).astype(np.uint8)
    xy = np.array([[40.5, 30.5], [47.2, 36.9]])
    crop, origin = _crop_around(frame, xy, 4 + 7 + 1, 0.5)
    full = _tophat(frame, 7)
    part = _tophat(crop, 7)
    x0, y0 = origin.astype(int)
    for c in xy:
        i, j = int(c[0] - 0.5), int(c[1] - 0.5)
        np.testing.assert_array_equal(part[j - 4 - y0:j + 5 - y0, i - 4 - x0:i + 5 - x0],
                                      full[j - 4:j + 5, i - 4:i + 5])


def test_grow_equals_scipy_binary_dilation():
    """The masks' one-pixel growth is scipy.ndimage.binary_dilation with its
    default cross, borders included."""
    from scipy.ndimage import binary_dilation
    from photogram.track.ski_edges import _grow
    rng = np.random.default_rng(0)
    for _ in range(100):
        m = rng.random((rng.integers(1, 30), rng.integers(1, 30))) < rng.random()
        np.testing.assert_array_equal(_grow(m), binary_dilation(m, iterations=1))
