"""The one line implementation (photogram.lines.batch): the commands'
per-line functions are batches of one, and a batch of many lines (groups of
different sizes, padded) gives each line's per-line result."""

import numpy as np
import pytest

from photogram.lines import SpaceLine, fit_view_line, intersect_line
from photogram.lines.batch import intersect_lines_batch
from photogram.lines.batch_image import fit_lines_batch, line_layout
from photogram.simulation.ski_lines import field_cameras, measure_segment

CAMS = field_cameras()
CENTRE = np.array([470.0, 7.0, -250.0])


def _lines(n_lines=6, seed=3):
    """Noisy measured points of random lines near CENTRE in every camera,
    with a different number of points per line and view."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n_lines):
        D = rng.normal(size=3)
        D /= np.linalg.norm(D)
        L = SpaceLine(CENTRE + rng.normal(scale=5.0, size=3), D)
        ends = np.array([L.point - 12.0 * D, L.point + 12.0 * D])
        out.append({s: measure_segment(ends, cam, int(rng.integers(4, 18)), sigma=0.3, rng=rng)
                    for s, cam in CAMS.items()})
    return out


def test_a_batch_of_many_lines_gives_the_per_line_results():
    lines = _lines()
    names = list(CAMS)
    xi, J, sig, group = [], [], [], []
    for i, pts in enumerate(lines):
        for j, s in enumerate(names):
            x, Jx = CAMS[s].ideal(pts[s], jacobians=True)
            xi.append(x)
            J.append(Jx)
            sig.append(np.full(len(x), 0.3))
            group.append(np.full(len(x), i * len(names) + j))
    xi, J, sig, group = map(np.concatenate, (xi, J, sig, group))
    # shuffle the groups' order in the input (each group's points stay in order)
    G = len(lines) * len(names)
    perm = np.argsort(np.random.default_rng(0).permutation(G)[group], kind="stable")
    xi, J, sig, group = xi[perm], J[perm], sig[perm], group[perm]
    layout = line_layout(group, G)
    assert not layout[1].all()                          # padded
    l, cov_l, ends = fit_lines_batch(xi, J, sig, group, G, layout=layout)
    assert np.array_equal(l, fit_lines_batch(xi, J, sig, group, G)[0])
    k = len(names)
    R = np.array([[CAMS[s].R for s in names]] * len(lines))
    X0 = np.array([[CAMS[s].X0 for s in names]] * len(lines))
    c = np.array([[CAMS[s].c for s in names]] * len(lines))
    P, D, C, chi2 = intersect_lines_batch(l.reshape(-1, k, 3), cov_l.reshape(-1, k, 3, 3),
                                          ends.reshape(-1, k, 2, 2), R, X0, c, covariance=True)
    for i, pts in enumerate(lines):
        fl = {s: fit_view_line(pts[s], CAMS[s], 0.3) for s in names}
        for j, s in enumerate(names):
            assert np.allclose(l[i * k + j], fl[s].homogeneous, rtol=0, atol=1e-13)
            assert np.allclose(cov_l[i * k + j], fl[s].cov_homogeneous, rtol=1e-12, atol=0)
            assert np.allclose(ends[i * k + j], fl[s].end_points, rtol=0, atol=1e-11)
        ref = intersect_line(fl, CAMS)
        assert np.abs(D[i] - ref.line.direction).max() < 1e-13
        assert np.abs(P[i] - ref.line.point).max() < 1e-10
        assert np.allclose(C[i], ref.line.covariance, rtol=1e-9)
        assert chi2[i] == pytest.approx(ref.chi2, rel=1e-9)
        assert ref.converged and ref.iterations >= 1


def test_each_line_stops_on_its_own():
    """The per-line stopping rule: a line in a batch takes the iterations
    it takes alone."""
    lines = _lines(4, seed=5)
    res = [intersect_line({s: fit_view_line(p[s], CAMS[s], 0.3) for s in CAMS}, CAMS)
           for p in lines]
    its = [r.iterations for r in res]
    from photogram.lines.batch import intersect_lines_full
    names = list(CAMS)
    fl = [[fit_view_line(p[s], CAMS[s], 0.3) for s in names] for p in lines]
    out = intersect_lines_full(
        np.array([[f.homogeneous for f in row] for row in fl]),
        np.array([[f.cov_homogeneous for f in row] for row in fl]),
        np.array([[f.end_points for f in row] for row in fl]),
        np.array([[CAMS[s].R for s in names]] * len(lines)),
        np.array([[CAMS[s].X0 for s in names]] * len(lines)),
        np.array([[CAMS[s].c for s in names]] * len(lines)))
    assert list(out.iterations) == its
    for i, r in enumerate(res):
        assert np.array_equal(out.D[i] / np.linalg.norm(out.D[i]), r.line.direction) or \
            np.abs(out.D[i] - r.line.direction).max() < 1e-15
