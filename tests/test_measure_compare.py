"""photogram.measure.compare: a measured table against a reference (the
check `make demo` prints for the lab). Synthetic tables with known
differences: matched, missing, extra, z against both sigmas, swapped labels
found as wrong labels, an unreadable table one line."""

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.measure.compare import compare_tables


def _write(path, rows, sigma=True):
    head = "station,point,x,y" + (",sigma" if sigma else "")
    lines = ["# a comment", head] + [",".join(str(v) for v in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture
def tables(tmp_path):
    rng = np.random.default_rng(5)
    truth = {(f"S{s}", f"P{p:02d}"): (50.0 + 40 * p, 30.0 + 25 * s)
             for s in range(3) for p in range(10)}
    meas = []
    for (s, p), (x, y) in truth.items():
        if (s, p) == ("S0", "P09"):
            continue                                       # one not measured
        dx, dy = rng.normal(0, 0.05, 2)
        meas.append((s, p, x + dx, y + dy, 0.05))
    meas.append(("S1", "EXTRA", 10.0, 10.0, 0.05))         # one not in the reference
    ref = [(s, p, x, y) for (s, p), (x, y) in truth.items()]
    return tmp_path, meas, ref


def test_agreeing_tables(tables):
    tmp, meas, ref = tables
    c = compare_tables(_write(tmp / "m.csv", meas), _write(tmp / "r.csv", ref, sigma=False))
    assert (c.n_measured, c.n_reference, c.matched) == (30, 30, 29)
    assert c.missing == [("S0", "P09")] and c.extra == [("S1", "EXTRA")]
    assert c.wrong == [] and c.beyond == []
    assert 0.5 < c.mean_z2 < 1.6 and c.rms < 0.15
    assert "29 of 30 found" in c.line() and "0 more than 3 px off" in c.line()


def test_swapped_labels_are_wrong_labels(tables):
    tmp, meas, ref = tables
    i = next(k for k, r in enumerate(meas) if r[:2] == ("S2", "P03"))
    j = next(k for k, r in enumerate(meas) if r[:2] == ("S2", "P04"))
    meas[i], meas[j] = (meas[i][0], "P04", *meas[i][2:]), (meas[j][0], "P03", *meas[j][2:])
    c = compare_tables(_write(tmp / "m.csv", meas), _write(tmp / "r.csv", ref, sigma=False))
    assert sorted(w[:2] for w in c.wrong) == [("S2", "P03"), ("S2", "P04")]
    assert len(c.beyond) == 2 and c.max_z > 100


def test_reference_sigma_enters_z(tables):
    tmp, meas, ref = tables
    meas = [(s, p, x + 0.3, y, sg) for s, p, x, y, sg in meas]   # a 0.3 px offset in x
    m, r = _write(tmp / "m.csv", meas), _write(tmp / "r.csv", ref, sigma=False)
    alone = compare_tables(m, r)
    both = compare_tables(m, r, sigma_reference=0.33)
    assert alone.mean_z2 > 10 and len(alone.beyond) > 0 and alone.wrong == []
    assert both.mean_z2 < 1 and both.beyond == []


def test_not_a_table_is_one_input_error(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    with pytest.raises(InputError) as err:
        compare_tables(bad, bad)
    assert "not an image points table" in str(err.value) and "\n" not in str(err.value)
