"""Issue 16, item 7: data snooping tests the reference (control)
coordinates of the weighted datum in the same w-test as the image points,
each with its own redundancy number, and names the coordinate. A 25-sigma
error in the Z of control point M3 used to be blamed on M3's three good
rays (all rejected) while the bad coordinate stayed."""

import copy

import numpy as np

from field_copy import field_copy
from photogram.adjust.build import build_problem
from photogram.adjust.solver import solve
from photogram.bundle import adjust
from photogram.project import read_project
from photogram.stats.reliability import data_snooping, normalized_residuals, redundancy_numbers

M3 = "M3,control,544.55,-61.81,-351.2,"
M3_BAD = "M3,control,544.55,-61.81,-348.2,"      # Z + 3.0 dm = 25 sigma (sZ 0.12 dm)


def _bad_z(text):
    assert M3 in text
    return text.replace(M3, M3_BAD)


def _project(tmp_path, bad=True):
    prj = field_copy(tmp_path, adjustment={"snooping_alpha": "0.001"},
                     **({"field_points.csv": _bad_z} if bad else {}))
    return read_project(prj)


def test_snooping_names_the_wrong_control_coordinate(tmp_path):
    project = _project(tmp_path)
    res = adjust(project, fix_interior=True)
    rejected = res.summary["snooping"]["rejected"]
    assert [(r["block"], r["label"]) for r in rejected] == [("control coordinates", "M3 Z")]
    assert rejected[0]["coordinate"] == "Z" and rejected[0]["w"] > 10
    assert any("reference coordinate(s) M3 Z" in w for w in res.summary["warnings"])
    # the images determine M3's Z again: it comes back to the surveyed truth
    # (the value before the error), within 3 of its sigmas
    i = project.points.ids.index("M3")
    z_true = float(M3.split(",")[4])
    assert abs(res.project.points.xyz[i, 2] - z_true) < 3 * res.point_sigma[i, 2]
    assert abs(res.project.points.xyz[i, 2] - (z_true + 3.0)) > 2.5


def test_control_w_is_residual_over_sigma_sqrt_redundancy(tmp_path):
    """The control coordinates' w-test statistics use their own redundancy
    numbers: w = v / (sigma sqrt(r)); all redundancy numbers add up to the
    redundancy."""
    from photogram.bundle import approximate_if_needed
    project = approximate_if_needed(_project(tmp_path), {})
    p = build_problem(project, fix_interior=True).problem
    solve(p)
    red = redundancy_numbers(p)
    assert abs(sum(float(r.sum()) for r in red) - p.redundancy()) < 1e-6
    k = next(k for k, b in enumerate(p.blocks) if b.name == "control coordinates")
    blk = p.blocks[k]
    v = p.state.points[blk.point] - blk.xyz
    w = normalized_residuals(p, red)[k]
    np.testing.assert_allclose(w, v / (blk.sigma * np.sqrt(red[k])), rtol=1e-12)
    assert 0.05 < red[k].min() and red[k].max() < 1
    # the largest |w| of the whole adjustment is M3's Z
    i = blk.labels.index("M3")
    assert abs(w[i, 2]) == max(float(np.abs(x).max()) for x in normalized_residuals(p, red))
    q = copy.deepcopy(p)
    r = data_snooping(q, 0.001)
    assert [x["label"] for x in r.rejected] == ["M3 Z"]
    assert not q.coordinate_active[k][i, 2] and q.coordinate_active[k][i, :2].all()
    assert q.redundancy() == p.redundancy() - 1


def test_clean_field_rejects_nothing(tmp_path):
    res = adjust(_project(tmp_path, bad=False), fix_interior=True)
    assert res.summary["snooping"]["rejected"] == []


def test_a_blunder_in_a_ray_of_a_control_point_is_still_the_ray(tmp_path):
    """A 29.9-sigma blunder in ray S2/P1 of control point P1 pulls P1, so
    P1's reference Y shows the largest single |w| (7.7 against 7.6); the
    ray's 2D statistic (chi-square, 2 degrees of freedom: 8.6 as a one-
    coordinate |w|) explains it better, and the ray is rejected, not P1 Y
    (benchmarks/blunders.py, field, 1 %, seed 11)."""
    from photogram.bundle import approximate_if_needed
    bad = lambda t: t.replace("S2,P1,315.48,174.33", "S2,P1,323.49,168.56")  # noqa: E731
    project = approximate_if_needed(read_project(field_copy(
        tmp_path, **{"field_image_points.csv": bad})), {})
    p = build_problem(project, fix_interior=True).problem
    solve(p)
    r = data_snooping(p, 0.001, scale="aposteriori", per_round="point", readmit=True,
                      swap_rays=4)
    assert [x["label"] for x in r.rejected] == ["S2/P1"]
