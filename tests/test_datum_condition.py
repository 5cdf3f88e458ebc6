"""Issue 16, item 9: inner constraints on points that barely fix the datum
(3 nearly collinear points) are refused, or warned about, with the points
named; they used to end "converged" above the true minimum of the cost."""

import numpy as np
import pytest

from photogram.bundle import adjust
from photogram.errors import GeometryError
from photogram.simulation.network import observe, ring_stations, to_project


def _network(offset):
    """A frame network whose points P1, P2, P3 lie on a 0.35 m line, P2
    ``offset`` metres off it."""
    rng = np.random.default_rng(3)
    pts = rng.uniform([-0.25, -0.25, 0.0], [0.25, 0.25, 0.3], (40, 3))
    d = pts[2] - pts[0]
    pts[1] = 0.5 * (pts[0] + pts[2]) + offset * np.cross(d, [0, 0, 1]) / np.linalg.norm(
        np.cross(d, [0, 0, 1]))
    X0, R = ring_stations(8, 2.0, 1.0, np.array([0, 0, 0.15]), jitter=0.05, rng=rng,
                          rolls=[0, np.pi / 2, np.pi, -np.pi / 2])
    io = np.array([1420.0, 320.0, 240.0, -5e-8, 0, 0, 0, 0, 0, 0])
    return observe("brown", io, np.zeros(8, int), R, X0, pts, (640, 480), sigma=0.3, rng=rng)


def _adjust(net, chosen):
    prj = to_project(net, perturb_points=0.01, perturb_stations=0.02,
                     rng=np.random.default_rng(1))
    prj.adjustment.datum = "free"
    prj.adjustment.inner_constraints = chosen
    prj.adjustment.max_iterations = 100
    return adjust(prj)


def test_condition_of_point_sets():
    """Analytic cases: collinear points cannot fix the rotation about their
    line (condition 0, the rotation named); a regular tetrahedron fixes
    all 7 motions well; the condition does not depend on position or size."""
    from photogram.adjust.datum import _point_motions, inner_constraint_condition
    line = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]])
    c, weakest = inner_constraint_condition(line)
    assert c < 1e-12 and weakest == ["rotation about X"]
    tetra = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1.0]])
    c1, _ = inner_constraint_condition(tetra)
    c2, _ = inner_constraint_condition(1000 + 0.01 * tetra)
    assert c1 > 0.3 and abs(c1 - c2) < 1e-9
    # condition = smallest / largest singular value of the motions (by hand)
    tri = np.array([[0, 0, 0], [1, 0, 0], [0.5, 0.01, 0]])
    centre = tri.mean(0)
    size = np.sqrt(np.mean(np.sum((tri - centre) ** 2, 1)))
    sv = np.linalg.svd(_point_motions(tri, centre, size).reshape(-1, 7), compute_uv=False)
    assert inner_constraint_condition(tri)[0] == pytest.approx(sv[-1] / sv[0], rel=1e-12)


def test_nearly_collinear_inner_constraints_are_refused():
    net = _network(1e-3)                    # 1 mm off a 0.35 m line
    with pytest.raises(GeometryError, match=r"inner constraints on point\(s\) P1, P2, P3 "
                                            r"barely fix the datum"):
        _adjust(net, ["P1", "P2", "P3"])


def test_weak_inner_constraints_warn_and_reach_the_minimum():
    net = _network(5e-3)                    # 5 mm off: weak, still solvable
    weak = _adjust(net, ["P1", "P2", "P3"])
    assert any("P1, P2, P3 barely fix the datum" in w for w in weak.summary["warnings"])
    full = _adjust(net, None)               # all points: the same minimum
    assert not any("barely fix" in w for w in full.summary["warnings"])
    assert weak.summary["final_cost"] == pytest.approx(full.summary["final_cost"], rel=1e-7)


def test_thresholds_are_ordered():
    from photogram.adjust.datum import DATUM_REFUSE, DATUM_WARN
    assert 0 < DATUM_REFUSE < DATUM_WARN < 0.3
