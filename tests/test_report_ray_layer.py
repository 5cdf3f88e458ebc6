"""The stacked-ray image of the network page (photogram.report.shapes.ray_counts,
ray_layer) against a plain per-segment walk and against its definition."""

import numpy as np
from photogram.report.shapes import ray_counts, ray_layer


def _walk(a, b, extent, shape):
    """Reference: each segment walked one pixel step at a time in a loop."""
    rows, cols = shape
    x0, x1, y0, y1 = extent
    out = np.zeros(shape, int)
    for p, q in zip(a, b):
        pa = (p - [x0, y0]) * [cols / (x1 - x0), rows / (y1 - y0)]
        pb = (q - [x0, y0]) * [cols / (x1 - x0), rows / (y1 - y0)]
        L = np.abs(pb - pa).max()
        seen = []
        for k in range(int(np.ceil(L)) + 1):
            x, y = pa + (min(k, L) / L) * (pb - pa)
            seen.append((int(np.floor(y)), int(np.floor(x))))
        if len(seen) > 1 and seen[-1] == seen[-2]:
            seen.pop()                          # the end, in the pixel of the step before
        for i, j in seen:
            if 0 <= i < rows and 0 <= j < cols:
                out[i, j] += 1
    return out


def test_counts_equal_a_plain_walk_in_small_chunks():
    rng = np.random.default_rng(3)
    a, b = rng.uniform(-2, 12, (300, 2)), rng.uniform(-2, 12, (300, 2))
    extent, shape = (0.0, 10.0, 0.0, 8.0), (40, 50)
    got = ray_counts(a, b, extent, shape, chunk=97)
    np.testing.assert_array_equal(got, _walk(a, b, extent, shape))


def test_a_horizontal_segment_counts_once_per_pixel_it_crosses():
    c = ray_counts([[0.05, 2.5]], [[9.95, 2.5]], (0, 10, 0, 5), (5, 10))
    assert c[2].tolist() == [1] * 10            # row of y = 2.5, every column once
    assert c.sum() == 10


def test_layer_opacity_is_that_of_stacked_lines():
    from matplotlib.figure import Figure
    fig = Figure(figsize=(2, 1))
    ax = fig.add_axes([0, 0, 1, 1])
    ax.set_xlim(0, 10)
    ax.set_ylim(0, 5)
    a = np.tile([[0.05, 2.5]], (3, 1))
    b = np.tile([[9.95, 2.5]], (3, 1))
    im = ray_layer(ax, a, b, "red", 0.15, dpi=5)          # 10 x 5 pixels
    rgba = im.get_array()
    assert rgba.shape == (5, 10, 4)
    np.testing.assert_allclose(rgba[2, :, 3], 1 - 0.85 ** 3, rtol=1e-12)
    np.testing.assert_array_equal(rgba[0, :, 3], 0.0)
    np.testing.assert_allclose(rgba[2, 0, :3], [1.0, 0.0, 0.0])
