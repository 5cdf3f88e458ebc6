"""The whole measurement of a rendered coded sheet (known truth): detection,
ring codes, numbering by homography, guided measurement, eccentricity
correction; and the ring decoder against corrupted profiles (every code
decoded or rejected, never mis-decoded)."""

import numpy as np
import pytest

from photogram.measure.codes import RingCode, decode_rings
from photogram.measure.field import read_field
from photogram.measure.pipeline import PIXEL_OFFSET, measure_image
from photogram.measure.render import field_scene

from pathlib import Path

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

SHEET = Path(__file__).resolve().parents[1] / "projects" / "camcal" / "sheet.toml"

VIEWS = {
    "front": {},
    "oblique": dict(eye=(-0.8, -1.0, 1.4), code_rotation=30),
    # harsher than anything the detector was tuned on: more blur, noise,
    # JPEG 50, uneven light, smaller and more foreshortened targets
    "harsh": dict(eye=(1.3, -0.8, 1.3), f=600.0, blur=1.2, noise=5.0, jpeg=50, gradient=0.5,
                  seed=3, code_rotation=100),
}


@pytest.fixture(scope="module")
def field():
    fld = read_field(SHEET)
    fld.min_diameter = 4.0          # the rendered targets are small
    return fld


@pytest.fixture(scope="module")
def rendered(field):
    return {name: field_scene(field, **kw) for name, kw in VIEWS.items()}


@pytest.mark.parametrize("name", list(VIEWS))
def test_rendered_sheet_numbered_without_a_wrong_label(field, rendered, name):
    img, truth, cam = rendered[name]
    res = measure_image(img, field, name)
    lab = res.numbering.labels
    numbered = [i for i, v in enumerate(lab) if v]
    err = np.array([res.xy[i] - PIXEL_OFFSET - truth[lab[i]] for i in numbered])
    dist = np.hypot(*err.T)
    assert dist.max() < 1.0                      # no label on a wrong target
    assert len(numbered) == len(truth) == 100    # every target, each once
    assert len({lab[i] for i in numbered}) == 100
    assert sorted(v for v in res.code_label if v) == ["1001", "1002", "1003", "1004"]
    diam = 2 * res.detections.axes[numbered, 0]
    big = diam >= 10
    rms_big = float(np.sqrt((err[big] ** 2).sum(axis=1).mean()))
    rms_all = float(np.sqrt((err ** 2).sum(axis=1).mean()))
    print(f"{name}: {big.sum()} targets >= 10 px: RMS {rms_big:.4f} px; all {len(err)} "
          f"({diam.min():.1f}-{diam.max():.1f} px): {rms_all:.4f} px; "
          f"guided {int(res.detections.extra.get('guided', np.zeros(1)).sum())}")
    assert big.sum() >= 20
    assert rms_big <= 0.05                       # the goal, eccentricity corrected
    assert res.numbering.conflicts == []


def test_eccentricity_correction_matters_on_the_oblique_view(field, rendered):
    img, truth, cam = rendered["oblique"]
    on = measure_image(img, field, "on")
    off = measure_image(img, field, "off", eccentricity_correction=False)

    def rms(res):
        lab = res.numbering.labels
        e = np.array([res.xy[i] - PIXEL_OFFSET - truth[v] for i, v in enumerate(lab) if v])
        return float(np.sqrt((e ** 2).sum(axis=1).mean()))

    print(f"oblique: with the correction {rms(on):.4f} px, without {rms(off):.4f} px")
    assert rms(on) < 0.7 * rms(off)


def test_swapped_codes_are_a_conflict(field):
    img, truth, cam = field_scene(field, swap=("1001", "1004"), size=(640, 480), f=560.0)
    res = measure_image(img, field, "swapped")
    assert res.numbering.conflicts and "mirrored" in res.numbering.conflicts[0]
    assert sum(1 for v in res.numbering.labels if v and v.startswith("D")) == 0


def test_ring_decoder_never_mis_decodes():
    codes = [RingCode("1001", "11111000"), RingCode("1002", "11001100"),
             RingCode("1003", "10010100"), RingCode("1004", "10101010")]
    rng = np.random.default_rng(5)
    n = 360
    profiles, truth = [], []
    for c in codes:
        base = c.template(n)
        for shift in range(0, 360, 7):
            p = np.roll(base, shift)
            kind = shift % 4
            if kind == 1:                       # random flips
                p = p ^ (rng.random(n) < rng.uniform(0, 0.15))
            elif kind == 2:                     # arcs grown or shrunk (blur, threshold)
                k = int(rng.integers(-15, 16))
                p = np.convolve(np.r_[p[-25:], p, p[:25]].astype(float),
                                np.ones(2 * abs(k) + 1), "same")[25:-25]
                p = p > 0 if k > 0 else p >= (2 * abs(k) + 1) - 1e-9
            elif kind == 3:                     # a part of the ring hidden (ink or paper)
                a = int(rng.integers(0, n))
                p = p.copy()
                p[np.arange(a, a + int(rng.integers(20, 70))) % n] = rng.random() < 0.5
            profiles.append(p)
            truth.append(c.id)
    ring = np.array(profiles)
    lab, score = decode_rings(ring, np.zeros(len(ring)), np.ones(len(ring), bool), codes)
    wrong = [(t, v) for t, v in zip(truth, lab) if v not in (t, None)]
    decoded = sum(1 for t, v in zip(truth, lab) if v == t)
    print(f"{len(ring)} corrupted profiles: {decoded} decoded, "
          f"{sum(1 for v in lab if v is None)} rejected, {len(wrong)} wrong")
    assert wrong == []
    assert decoded >= 0.5 * len(ring)
