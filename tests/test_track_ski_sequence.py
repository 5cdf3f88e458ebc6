"""The ski lines of one view as a sequence (photogram.track.ski_sequence)
and the label decisions of photogram.track.skis that use the three-view
check."""

from types import SimpleNamespace

import numpy as np
import pandas as pd

from photogram.track.ski_edges import BarLine
from photogram.track.ski_sequence import axis_directions, sequence_check
from photogram.track.ski_views import _oriented_flips, _separation


def _axes(angles, lengths, sigma, station="S1", line="L1", n=15):
    rows = []
    for i, (a, L) in enumerate(zip(angles, lengths)):
        t = np.linspace(-L / 2, L / 2, n)
        u = np.array([np.cos(a), np.sin(a)])
        xy = np.array([300.0, 200.0]) + t[:, None] * u
        for x, y in xy:
            rows.append((f"{i + 1:03d}", station, line, x, y, sigma))
    return pd.DataFrame(rows, columns=["exposure", "station", "line", "x", "y", "sigma"])


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
    n = 20
    tc = np.linspace(-30, 30, 15)
    s_angle = 0.2 / np.sqrt((tc ** 2).sum())
    names = [f"{i + 1:03d}" for i in range(n)]
    a1 = 0.3 + 0.004 * np.arange(n)
    a2 = a1 + np.radians(4.0)
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
