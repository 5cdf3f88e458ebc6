"""Speed-ups of the report (issue 23, round 5) give the same numbers bit
for bit as the straightforward code they replaced."""

import numpy as np
import pytest

from photogram.report.shapes import ray_counts


def _ray_counts_reference(a, b, extent, shape):
    """The (n, 2) formulation of :func:`ray_counts` before round 5, in one chunk."""
    a, b = np.asarray(a, float).reshape(-1, 2), np.asarray(b, float).reshape(-1, 2)
    rows, cols = int(shape[0]), int(shape[1])
    x0, x1, y0, y1 = (float(v) for v in extent)
    scale = np.array([cols / (x1 - x0), rows / (y1 - y0)])
    pa, pb = (a - [x0, y0]) * scale, (b - [x0, y0]) * scale
    ok = np.all(np.isfinite(pa) & np.isfinite(pb), axis=1)
    pa, pb = pa[ok], pb[ok]
    length = np.abs(pb - pa).max(axis=1)
    n = np.ceil(length).astype(np.int64) + 1
    seg = np.repeat(np.arange(len(n)), n)
    k = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    L = length[seg]
    t = np.minimum(k, L) / np.maximum(L, 1e-300)
    ij = np.floor(pa[seg] + t[:, None] * (pb[seg] - pa[seg])).astype(np.int64)
    last = np.zeros(len(k), bool)
    last[np.cumsum(n) - 1] = True
    again = np.zeros(len(k), bool)
    again[1:] = last[1:] & (k[1:] > 0) & np.all(ij[1:] == ij[:-1], axis=1)
    inside = ((ij[:, 0] >= 0) & (ij[:, 0] < cols) & (ij[:, 1] >= 0) & (ij[:, 1] < rows)
              & ~again)
    return np.bincount(ij[inside, 1] * cols + ij[inside, 0],
                       minlength=rows * cols).reshape(rows, cols)


@pytest.mark.parametrize("seed", range(40))
def test_ray_counts_match_reference(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 60))
    a = rng.normal(size=(n, 2)) * rng.uniform(0.1, 3)
    b = a + rng.normal(size=(n, 2)) * rng.choice([0.0, 0.01, 1.0, 5.0])
    if seed % 5 == 0:
        a[0] = np.nan
    shape = (int(rng.integers(1, 40)), int(rng.integers(1, 40)))
    extent = (-1.5, 1.2, -1.1, 1.7)
    want = _ray_counts_reference(a, b, extent, shape)
    for chunk in (1, int(rng.integers(2, 300)), 1_000_000):
        np.testing.assert_array_equal(ray_counts(a, b, extent, shape, chunk=chunk), want)


def test_ray_counts_reference_is_not_trivial():
    # a horizontal segment across a 10 x 5 grid: one count in each column of row 2
    got = _ray_counts_reference([[0.05, 2.5]], [[9.95, 2.5]], (0, 10, 0, 5), (5, 10))
    assert got[2].tolist() == [1] * 10 and got.sum() == 10


def _raster_reference(centre, u, v, idx, t, x0, y0, k):
    """The (n, 2) pixel expression of raster_ellipses before round 5."""
    px = (centre[idx] + u[idx] * np.cos(t)[:, None] + v[idx] * np.sin(t)[:, None]
          - [x0, y0]) * k
    return np.floor(px[:, 0]).astype(np.int64), np.floor(px[:, 1]).astype(np.int64)


@pytest.mark.parametrize("seed", range(10))
def test_ellipse_pixels_match_reference(seed):
    from photogram.report.pdf.artists import _pixel

    rng = np.random.default_rng(seed)
    n = 50
    centre, u, v = (rng.normal(size=(n, 2)) * s for s in (100.0, 5.0, 3.0))
    idx = rng.integers(0, n, 4000)
    t = rng.uniform(0, 2 * np.pi, 4000)
    x0, y0, k = rng.normal() * 10, rng.normal() * 10, 150 / 72
    want = _raster_reference(centre, u, v, idx, t, x0, y0, k)
    cos, sin = np.cos(t), np.sin(t)
    for j, origin in ((0, x0), (1, y0)):
        got = _pixel(centre[:, j], u[:, j], v[:, j], idx, cos, sin, origin, k)
        np.testing.assert_array_equal(got, want[j])


def _hull_reference(xy):
    """convex_hull before round 5: np.unique first, the extremes filter after."""
    from photogram.report.shapes import _inside_extremes, _monotone_chain

    pts = np.unique(np.asarray(xy, float).reshape(-1, 2), axis=0)
    if len(pts) < 3:
        return pts
    if len(pts) > 32:
        pts = pts[~_inside_extremes(pts)]
    return _monotone_chain(pts)


@pytest.mark.parametrize("seed", range(30))
def test_convex_hull_matches_reference(seed):
    from photogram.report.shapes import convex_hull

    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    if seed % 3 == 0:            # integer pixels: repeated points, ties at the extremes
        xy = rng.integers(0, 12, size=(n, 2)).astype(float)
    elif seed % 3 == 1:          # a few distinct points repeated many times
        base = rng.normal(size=(int(rng.integers(1, 6)), 2))
        xy = base[rng.integers(0, len(base), n)]
        xy = np.vstack([xy, rng.normal(size=(int(rng.integers(0, 4)), 2))])
    else:
        xy = rng.normal(size=(n, 2)) * [3000, 2000]
    np.testing.assert_array_equal(convex_hull(xy), _hull_reference(xy))


@pytest.mark.parametrize("blank", ["", "   ", "\t", " \r"])
def test_read_table_skips_blank_lines_without_comments(tmp_path, blank):
    # no "#" in the file: the blank-line test alone picks the filtering path
    from photogram.report.table import read_table

    path = tmp_path / "t.csv"
    path.write_text(f"id,x\nA,1.5\n{blank}\nB,2.5\n", encoding="utf-8", newline="")
    t = read_table(path, ("id",), key="id")
    assert t["id"].tolist() == ["A", "B"]
    assert t["x"].tolist() == [1.5, 2.5]


@pytest.mark.parametrize("seed", range(20))
def test_sorted_subgroups_match_sorted_groups(seed):
    from photogram.report.table import groups, sorted_groups, sorted_subgroups

    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 300))
    pool = np.array([str(k) for k in rng.integers(0, 60, 40)] + ["P10", "P9", "a", "10"],
                    dtype=object)
    keys = pool[rng.integers(0, len(pool), n)]
    rows = rng.random(n) < rng.uniform(0, 1)
    codes, names = groups(keys)
    got_codes, got_names = sorted_subgroups(codes[rows], names)
    want_codes, want_names = sorted_groups(keys[rows])
    assert got_names.tolist() == want_names.tolist()
    np.testing.assert_array_equal(got_codes, want_codes)
