"""Line transfer into a third view and the left/right ski label check."""

import numpy as np
import pytest

from photogram.errors import GeometryError, InputError
from photogram.lines import (
    SpaceLine, check_ski_labels, check_ski_sequence, compare_lines, fit_view_line,
    line_angle, line_planes, plane_angles, point_on_line, project_line, swap_labels, transfer_line,
    transfer_line_trifocal, trifocal_tensor)
from photogram.simulation.ski_lines import field_cameras, flight_positions, measure_segment, ski_pair

# in `make test-fast` again since the ski check's batch (1.2 s CPU for the module, was 2.8 s)

CAMS = field_cameras()
SIGMA = 0.33


def _exposure(centre, rng, roll=20.0, n=15):
    left, right = ski_pair(centre, roll_deg=roll)
    return {s: {"L1": measure_segment(left, cam, n, SIGMA, rng),
                "L2": measure_segment(right, cam, n, SIGMA, rng)} for s, cam in CAMS.items()}


def _same(a, b):
    return a.keys() == b.keys() and all(
        a[s].keys() == b[s].keys() and all(np.array_equal(a[s][k], b[s][k]) for k in a[s])
        for s in a)


# ---------------------------------------------------------------------------
# transfer


@pytest.mark.parametrize("D", [[0.0, 0.0, 1.0], [0.3, 1.0, 0.1], [1.0, -0.3, 0.2],
                               [0.94, 0.17, -0.34]])
def test_transfer_equals_trifocal_transfer_and_the_projection(D):
    """Noise-free: the transferred line is the projection of the true line
    and equals H&Z's trifocal transfer. Along the flight (the last
    direction, a ski) the line is nearly parallel to the plane of the three
    projection centres, and the pair S1-S3 is refused (planes at 0.5 deg)."""
    truth = SpaceLine([480.0, 8.0, -262.0], D)
    ends = np.array([point_on_line(truth, -12.0), point_on_line(truth, 12.0)])
    lines = {s: fit_view_line(measure_segment(ends, cam), cam, SIGMA, label="L1")
             for s, cam in CAMS.items()}
    angles = np.degrees(plane_angles(line_planes(lines, CAMS)))
    names = list(CAMS)
    for c, (a, b) in (("S1", ("S2", "S3")), ("S2", ("S1", "S3")), ("S3", ("S1", "S2"))):
        if angles[names.index(a), names.index(b)] < 1.0:
            with pytest.raises(GeometryError, match=f"{a} and {b}"):
                transfer_line(lines[a], CAMS[a], lines[b], CAMS[b], CAMS[c], label="L1")
            continue
        tr = transfer_line(lines[a], CAMS[a], lines[b], CAMS[b], CAMS[c], label="L1")
        l_true = project_line(truth, CAMS[c])
        l_true *= np.sign(l_true @ tr.l)
        np.testing.assert_allclose(tr.l, l_true, atol=1e-8 * (1 + abs(l_true[2])))
        T = trifocal_tensor(CAMS[c], CAMS[a], CAMS[b])
        l_tri = transfer_line_trifocal(T, lines[a].homogeneous, lines[b].homogeneous)
        assert line_angle(l_tri, tr.l) < 1e-9
        assert abs(abs(l_tri[2]) - abs(tr.l[2])) < 1e-6
        cmp = compare_lines(tr.l, lines[c], tr.covariance)
        assert cmp.angle < 1e-9 and np.abs(cmp.distances).max() < 1e-7 and cmp.chi2 < 1e-9
        assert tr.covariance.shape == (3, 3) and tr.space_line.redundancy == 0
    if D == [0.94, 0.17, -0.34]:
        assert angles[0, 2] < 1.0


def test_transfer_of_a_line_along_the_baseline_is_refused():
    S1, S2 = CAMS["S1"].X0, CAMS["S2"].X0
    truth = SpaceLine([480.0, 8.0, -262.0], S2 - S1)
    ends = np.array([point_on_line(truth, -12.0), point_on_line(truth, 12.0)])
    lines = {s: fit_view_line(measure_segment(ends, cam), cam) for s, cam in CAMS.items()}
    with pytest.raises(GeometryError, match="S1 and S2"):
        transfer_line(lines["S1"], CAMS["S1"], lines["S2"], CAMS["S2"], CAMS["S3"])


def test_transfer_chi_square_with_noise():
    """The measured line in the third view agrees with the transferred one
    within the propagated covariance (mean chi2 of the two end-point
    distances ~2)."""
    rng = np.random.default_rng(5)
    left, _ = ski_pair(flight_positions()[4], roll_deg=20.0)
    chis = []
    for _ in range(60):
        lines = {s: fit_view_line(measure_segment(left, cam, 15, SIGMA, rng), cam, SIGMA)
                 for s, cam in CAMS.items()}
        tr = transfer_line(lines["S1"], CAMS["S1"], lines["S3"], CAMS["S3"], CAMS["S2"])
        chis.append(compare_lines(tr.l, lines["S2"], tr.covariance).chi2)
    assert 2 - 2.576 * np.sqrt(4 / 60) < np.mean(chis) < 2 + 2.576 * np.sqrt(4 / 60)


# ---------------------------------------------------------------------------
# ski labels


@pytest.mark.parametrize("roll", [20.0, -20.0])
def test_swapped_ski_is_detected_and_fixed_without_false_alarms(roll):
    rng = np.random.default_rng(20250104)
    for i, centre in enumerate(flight_positions()[::2 if roll > 0 else 3]):
        lbv = _exposure(centre, rng, roll)
        ok = check_ski_labels(lbv, CAMS, SIGMA, exposure=i)
        assert ok.status == "ok" and ok.swapped == [], ok.message
        assert ok.costs["as measured"] < ok.threshold
        assert all(t.chi2 < 30 for t in ok.transfer)
        for station in CAMS:
            wrong = swap_labels(lbv, station)
            r = check_ski_labels(wrong, CAMS, SIGMA, exposure=i, fix=True)
            assert r.status == "swapped" and r.swapped == [station], r.message
            assert f"interchanged in {station}" in r.message and f"exposure {i}" in r.message
            assert _same(r.corrected, lbv)
            assert _same(swap_labels(wrong, r), lbv)
            assert max(t.chi2 for t in r.transfer) > 100
            assert max(t.chi2 for t in r.transfer_fixed) < 30


def test_ski_seen_edge_on_is_ambiguous_not_a_false_alarm():
    """With the V of the skis in a plane through S2 (roll 0), S2 cannot
    separate them: a swap there is undecidable, and a swap in S1 leaves S1
    and S3 disagreeing without a majority."""
    rng = np.random.default_rng(3)
    lbv = _exposure(flight_positions()[3], rng, roll=0.0)
    r = check_ski_labels(lbv, CAMS, SIGMA)
    assert r.status == "ambiguous" and r.undecided == ["S2"] and r.swapped == []
    r = check_ski_labels(swap_labels(lbv, "S2"), CAMS, SIGMA)
    assert r.status == "ambiguous" and r.swapped == []
    r = check_ski_labels(swap_labels(lbv, "S1"), CAMS, SIGMA, fix=True)
    assert r.status == "ambiguous" and r.swapped == [] and "no majority" in r.message
    assert _same(r.corrected, swap_labels(lbv, "S1"))        # nothing changed


def test_sequence_inconsistent_and_errors():
    rng = np.random.default_rng(9)
    seq = {f"E{i}": _exposure(c, rng) for i, c in enumerate(flight_positions()[:3])}
    seq["E1"] = swap_labels(seq["E1"], "S3")
    res = check_ski_sequence(seq, CAMS, SIGMA)
    assert [res[e].status for e in seq] == ["ok", "swapped", "ok"]
    assert res["E1"].swapped == ["S3"] and res["E1"].exposure == "E1"
    # sigma far too small: nothing fits
    assert check_ski_labels(seq["E0"], CAMS, 0.01).status == "inconsistent"
    # two images always agree
    two = {s: seq["E0"][s] for s in ("S1", "S3")}
    with pytest.raises(GeometryError, match="measured in 2 images"):
        check_ski_labels(two, CAMS, SIGMA, exposure="E0")
    # a station without one ski is skipped
    part = dict(seq["E0"])
    part["S4"] = {"L1": part["S1"]["L1"]}
    assert check_ski_labels(part, CAMS, SIGMA).skipped == ["S4"]
    three = {s: dict(v, L3=v["L1"]) for s, v in seq["E0"].items()}
    with pytest.raises(InputError, match="two ski labels"):
        check_ski_labels(three, CAMS, SIGMA)
    with pytest.raises(InputError, match="unknown station"):
        swap_labels(seq["E0"], "S7")


def test_project_tables_feed_the_check():
    """Cameras and ski measurements taken from a Project (the field design
    with its true orientation and an image-lines table)."""
    from photogram.lines import cameras_from_project, lines_from_project
    from photogram.project.model import ImageLines
    from photogram.simulation.designs import field_design
    project, truth = field_design()
    project.stations.position = truth["stations"]["X0"].copy()
    project.stations.angles = truth["stations"]["angles"].copy()
    cams = cameras_from_project(project)
    for s in CAMS:
        np.testing.assert_allclose(cams[s].R, CAMS[s].R, atol=1e-12)
        np.testing.assert_allclose(cams[s].io, CAMS[s].io)
    lbv = _exposure(flight_positions()[2], np.random.default_rng(4))
    st, lab, xy = [], [], []
    for i, s in enumerate(project.stations.names):
        for name in ("L1", "L2"):
            st += [i] * len(lbv[s][name])
            lab += [name] * len(lbv[s][name])
            xy.append(lbv[s][name])
    project.image_lines = ImageLines(station=np.array(st), line=np.array(lab, dtype=object),
                                     xy=np.vstack(xy), sigma=np.full(len(st), np.nan),
                                     record=np.arange(len(st)) + 2)
    table = lines_from_project(project)
    assert _same(table, lbv)
    assert check_ski_labels(table, cams, SIGMA).status == "ok"
