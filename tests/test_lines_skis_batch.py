"""The ski label check scores its label assignments and computes its
transfers with all lines of an exposure in one batch
(:func:`photogram.lines.skis._batch`); the result is the same, to the last
bit, as one :func:`photogram.lines.intersect_line` per line (the path it
falls back to when a normal matrix is singular). SIMULATED exposures."""

import numpy as np
import pytest

import photogram.lines.skis as skis
from photogram.lines import check_ski_labels, swap_labels
from photogram.simulation.ski_lines import field_cameras, measure_segment, ski_pair

CAMS = field_cameras()
SIGMA = 0.33


def _exposure(centre, rng, roll=20.0, n=15, sigma=SIGMA):
    left, right = ski_pair(centre, roll_deg=roll)
    return {s: {"L1": measure_segment(left, cam, n, sigma, rng),
                "L2": measure_segment(right, cam, n, sigma, rng)} for s, cam in CAMS.items()}


def _as_tuple(check):
    rows = [(t.station, t.label, t.from_stations, t.angle_deg, t.distances.tolist(), t.chi2)
            for t in check.transfer + check.transfer_fixed]
    return (check.status, check.swapped, check.undecided, check.costs, check.message, rows)


def _cases():
    rng = np.random.default_rng(23)
    out = []
    for roll, sigma in ((20.0, SIGMA), (-20.0, SIGMA), (2.0, SIGMA), (20.0, 8.0)):
        lines = _exposure([480.0, 8.0, -262.0], rng, roll=roll, sigma=sigma)
        out += [lines, swap_labels(lines, "S2")]
    return out


@pytest.mark.parametrize("case", range(8))
def test_batch_equals_one_line_at_a_time(case, monkeypatch):
    lines = _cases()[case]
    batch = check_ski_labels(lines, CAMS, SIGMA, exposure="e")
    monkeypatch.setattr(skis, "_batch", lambda groups, cameras: None)
    one = check_ski_labels(lines, CAMS, SIGMA, exposure="e")
    assert repr(_as_tuple(batch)) == repr(_as_tuple(one))     # every float to the last bit
    assert batch.transfer                                       # the transfers were compared


def test_the_cases_cover_every_status():
    statuses = {check_ski_labels(c, CAMS, SIGMA).status for c in _cases()}
    assert {"ok", "swapped"} <= statuses and statuses & {"ambiguous", "inconsistent"}
