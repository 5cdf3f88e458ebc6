"""The ski lines of one view as a sequence (photogram.track.ski_sequence)
and the label decisions of photogram.track.skis that use the three-view
check."""

from types import SimpleNamespace

import numpy as np
import pandas as pd

from photogram.track.ski_axes import BarLine
from photogram.track.ski_sequence import axis_directions, sequence_check
from photogram.track.ski_views import _oriented_flips, _Seen, _separation, coincide_confirmed


def _axes(angles, lengths, sigma, station="S1", line="L1", n=15):
    rows = []
    for i, (a, L) in enumerate(zip(angles, lengths)):
        t = np.linspace(-L / 2, L / 2, n)
        u = np.array([np.cos(a), np.sin(a)])
        xy = np.array([300.0, 200.0]) + t[:, None] * u
        for x, y in xy:
            rows.append((f"{i + 1:03d}", station, line, x, y, sigma))
    return pd.DataFrame(rows, columns=["exposure", "station", "line", "x", "y", "sigma"])


def _two_skis(n=20):
    """20 exposures of two skis whose image directions differ by 4 deg (the
    V), axes of 15 samples at 0.2 px: ``n``, the direction sigma of one
    axis, the exposure names and the two skis' angles."""
    tc = np.linspace(-30, 30, 15)
    s_angle = 0.2 / np.sqrt((tc ** 2).sum())
    names = [f"{i + 1:03d}" for i in range(n)]
    a1 = 0.3 + 0.004 * np.arange(n)
    return n, s_angle, names, a1, a1 + np.radians(4.0)


def test_axis_directions_angle_sigma_and_length():
    t = _axes([0.3], [60.0], 0.2)
    d = axis_directions(t).iloc[0]
    assert abs(d.angle - 0.3) < 1e-12 and abs(d.length - 60.0) < 1e-9
    tc = np.linspace(-30, 30, 15)
    assert abs(d.sigma_angle - 0.2 / np.sqrt((tc ** 2).sum())) < 1e-12


def test_sequence_scales_sigmas_by_the_scatter_and_flags_outliers_and_short_axes():
    rng = np.random.default_rng(5)
    n = 24
    tc = np.linspace(-30, 30, 15)
    s_angle = 0.2 / np.sqrt((tc ** 2).sum())               # claimed direction sigma
    true = 0.2 + 0.01 * np.arange(n) - 2e-4 * np.arange(n) ** 2
    noisy = true + rng.normal(0, 3 * s_angle, n)           # three times the claimed sigma
    noisy[7] += 40 * s_angle                               # an outlier
    lengths = np.full(n, 60.0)
    lengths[15] = 20.0                                     # a piece of the ski
    t = _axes(noisy, lengths, 0.2)
    out, flags, factors, _ = sequence_check(t, [f"{i + 1:03d}" for i in range(n)])
    f = factors.iloc[0]
    assert 2.0 < f.s0 < 4.5 and f.scale == f.s0 and f.outliers == 1
    reasons = {e: r for e, _, _, r in flags}
    assert set(reasons) == {"008", "016"}
    assert "off the sequence" in reasons["008"] and "long" in reasons["016"]
    assert set(out.exposure) == {f"{i + 1:03d}" for i in range(n)} - {"008", "016"}
    np.testing.assert_allclose(out.sigma, 0.2 * f.s0)
    # a sequence within its sigmas is never scaled down
    t = _axes(true + rng.normal(0, 0.3 * s_angle, n), np.full(n, 60.0), 0.2)
    out, flags, factors, _ = sequence_check(t, [f"{i + 1:03d}" for i in range(n)])
    assert not flags and factors.iloc[0].scale == 1.0 and (out.sigma == 0.2).all()


def _line(p, u, ends=(-30.0, 30.0)):
    u = np.asarray(u, float) / np.linalg.norm(u)
    return BarLine(np.asarray(p, float), u, np.array(ends), 1.5, 100.0)


def test_separation_of_two_axes():
    a = _line([0, 0], [1, 0])
    b = _line([0, 0.5], [1, 0.1])                          # b's tip 3.49 px off a
    assert abs(_separation([a, b]) - (0.5 + 30 * 0.1 / np.hypot(1, 0.1))) < 1e-12
    assert _separation(None) == 0.0


def test_flips_oriented_by_the_labelled_views():
    views = {"S1": SimpleNamespace(labelled=True), "S2": SimpleNamespace(labelled=False),
             "S3": SimpleNamespace(labelled=False)}
    # the check interchanges S1, the only labelled view: the unlabelled S2
    # and S3 are interchanged instead
    res = SimpleNamespace(status="swapped", swapped=["S1"], stations=["S1", "S2", "S3"])
    assert _oriented_flips(res, views) == ["S2", "S3"]
    res = SimpleNamespace(status="swapped", swapped=["S2"], stations=["S1", "S2", "S3"])
    assert _oriented_flips(res, views) == ["S2"]
    res = SimpleNamespace(status="ok", swapped=[], stations=["S1", "S2", "S3"])
    assert _oriented_flips(res, views) == []


def test_pending_views_are_decided_by_the_two_sequences_or_flagged():
    """Two skis whose image directions differ by 4 deg (the V): a view whose
    labels are open is taken as labelled, interchanged where its axes fit
    the other ski's sequence, and flagged where the two directions are too
    close to tell."""
    rng = np.random.default_rng(2)
    n, s_angle, names, a1, a2 = _two_skis()
    t1 = _axes(a1 + rng.normal(0, s_angle, n), np.full(n, 60.0), 0.2, line="L1")
    t2 = _axes(a2 + rng.normal(0, s_angle, n), np.full(n, 60.0), 0.2, line="L2")
    t = pd.concat([t1, t2], ignore_index=True)
    # exposure 006 labelled the wrong way round, 012 the right way
    swap = t.exposure == "006"
    t.loc[swap, "line"] = t.loc[swap, "line"].map({"L1": "L2", "L2": "L1"})
    pending = {("006", "S1"): "test", ("012", "S1"): "test"}
    out, flags, factors, decided = sequence_check(t, names, pending=pending)
    assert decided == {("006", "S1"): "interchanged", ("012", "S1"): "as labelled"}
    assert not flags
    d = axis_directions(out).set_index(["exposure", "line"])
    assert abs(d.loc[("006", "L1"), "angle"] - a1[5]) < 5 * s_angle
    assert abs(d.loc[("006", "L2"), "angle"] - a2[5]) < 5 * s_angle
    # directions 0.01 deg apart: not told apart, flagged and left out
    t2 = _axes(a1 + np.radians(0.01) + rng.normal(0, s_angle, n), np.full(n, 60.0), 0.2,
               line="L2")
    t = pd.concat([t1, t2], ignore_index=True)
    out, flags, factors, decided = sequence_check(t, names, pending={("009", "S1"): "test"})
    assert not decided and {f[0] for f in flags} == {"009"}
    assert "do not tell them apart" in flags[0][3]
    assert "009" not in set(out.exposure)


def test_an_axis_its_own_direction_does_not_identify_is_flagged():
    """A pending view whose pair assignment is clear from one axis alone:
    its other axis runs between the two skis' directions (a fit from one
    ski onto the other) and is flagged, not labelled by its partner; the
    clear axis keeps its label (harsh set, exposure 011 in S2)."""
    rng = np.random.default_rng(3)
    n, s_angle, names, a1, a2 = _two_skis()
    a2_bad = a2.copy()
    a2_bad[10] = 0.5 * (a1[10] + a2[10])          # exposure 011: halfway between
    t1 = _axes(a1 + rng.normal(0, s_angle, n), np.full(n, 60.0), 0.2, line="L1")
    t2 = _axes(a2_bad + rng.normal(0, s_angle, n), np.full(n, 60.0), 0.2, line="L2")
    # its sigma that of a poor fit: 2 deg, each sequence 1 sigma away
    t2.loc[t2.exposure == "011", "sigma"] = 0.2 * np.radians(2.0) / s_angle
    t = pd.concat([t1, t2], ignore_index=True)
    out, flags, factors, decided = sequence_check(t, names, pending={("011", "S1"): "test"})
    assert decided == {("011", "S1"): "as labelled"}
    assert [(f[0], f[1], f[2]) for f in flags] == [("011", "S1", "L2")]
    assert "not this axis on its own" in flags[0][3]
    kept = out[out.exposure == "011"]
    assert set(kept.line) == {"L1"}
    d = axis_directions(kept)
    assert abs(d.angle.iloc[0] - a1[10]) < 5 * s_angle


def _ski_views(shift, sigma=0.1):
    """Three views (opencv model, 6 m away) of two parallel skis 0.5 m long,
    the second ``shift`` from the first; S2's measured pair is the first ski
    twice (a pair fit on one ski). Returns (views, cameras, how far the
    second ski's true image in S2 is from the first's chord, px)."""
    from photogram.lines.views import ViewCamera
    from photogram.simulation.network import look_at
    X0 = np.array([[6.0, 0.0, 2.0], [0.0, 6.0, 2.5], [-6.0, 1.0, 1.5]])
    R = look_at(X0, np.zeros(3))
    io = np.array([1400.0, 1410.0, 320.0, 240.0, -0.12, 0.03, 5e-4, -3e-4, 0.0])
    cams = {f"S{i + 1}": ViewCamera(R[i], X0[i], io, "opencv", f"S{i + 1}") for i in range(3)}
    d = np.array([0.3, 0.8, -0.5]) / np.linalg.norm([0.3, 0.8, -0.5])
    t = np.linspace(-0.25, 0.25, 15)[:, None]
    skis = {"L1": t * d, "L2": t * d + shift}
    views, gap = {}, 0.0
    for s, cam in cams.items():
        pts = {lab: cam.project(X) for lab, X in skis.items()}
        if s == "S2":
            a, b = pts["L1"], pts["L2"]
            u = (a[-1] - a[0]) / np.linalg.norm(a[-1] - a[0])
            gap = float(np.abs((b - a[0]) @ np.array([u[1], -u[0]])).max())
            pts["L2"] = pts["L1"].copy()
        views[s] = _Seen(pts=pts, sig={"L1": sigma, "L2": sigma})
    return views, cams, gap


def test_coincidence_needs_the_decided_views():
    """An undecided view whose fitted skis coincide (one ski fitted twice)
    keeps its labels only where the views the check decided show the skis
    coincide there too (harsh set, exposures 015-017 in S2)."""
    res = SimpleNamespace(stations=["S1", "S2", "S3"], undecided=["S2"],
                          costs={"as measured": 1.0, "swap S2": 1.2, "swap S1": 900.0,
                                 "swap S3": 800.0})
    labels = ["L1", "L2"]
    # the second ski 3 cm away across S2's view: about 7 px apart in S2
    across = np.cross([0.3, 0.8, -0.5], [0.0, 6.0, 2.5])
    views, cams, gap = _ski_views(0.03 * across / np.linalg.norm(across))
    assert 5 < gap < 10
    assert not coincide_confirmed(res, views, "S2", cams, labels, coincide_px=1.0)
    # the second ski 3 cm along S2's line of sight: one image line in S2
    along = np.array([0.0, 6.0, 2.5]) / np.linalg.norm([0.0, 6.0, 2.5])
    views, cams, gap = _ski_views(0.03 * along)
    assert gap < 0.1
    assert coincide_confirmed(res, views, "S2", cams, labels, coincide_px=1.0)
    # with 0.2 px points the gap transferred from two views has a sigma of
    # 0.33 px: 0 + 3.09 sigma is above 1 px, coincidence not shown
    assert not coincide_confirmed(res, _ski_views(0.03 * along, sigma=0.2)[0], "S2", cams,
                                  labels, coincide_px=1.0)
    # the same labels interchanged in S3 by the check: still the two skis
    swapped = {"S1": views["S1"], "S2": views["S2"],
               "S3": _Seen(pts={"L1": views["S3"].pts["L2"], "L2": views["S3"].pts["L1"]},
                           sig=views["S3"].sig)}
    res_s3 = SimpleNamespace(**{**vars(res), "costs": {"as measured": 900.0, "swap S3": 1.0,
                                                       "swap S2": 800.0, "swap S1": 1.2}})
    assert coincide_confirmed(res_s3, swapped, "S2", cams, labels, coincide_px=1.0)
    # one decided view besides it is no evidence
    res_one = SimpleNamespace(**{**vars(res), "undecided": ["S2", "S3"]})
    assert not coincide_confirmed(res_one, views, "S2", cams, labels, coincide_px=1.0)

