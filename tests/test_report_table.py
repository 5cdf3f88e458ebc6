"""The report's own results-table reader (photogram/report/table.py): the
same values as the pandas reader of photogram.project.results_read, the same
one-line errors, and a report built without importing pandas."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.report.table import Table, groups, read_table

ROOT = Path(__file__).resolve().parents[1]


def _write(tmp_path, text, name="t.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_values_as_pandas_reads_them(tmp_path):
    from photogram.project.results_read import read_results_table

    path = _write(tmp_path, "# a comment\nstation,point,x,vx,used,note\n"
                            "S1,007,1.5,,1,\n\nS2,P2,-2e-3,0.25,0,\"a, b\"\n# end\n")
    t = read_table(path, ("station", "point"))
    f = read_results_table(path, ("station", "point"))
    assert t.columns == list(f.columns)
    assert t["point"].tolist() == ["007", "P2"]           # ids stay text
    for c in ("x", "vx", "used"):
        np.testing.assert_array_equal(t[c], f[c].to_numpy(float))
    assert t["note"].tolist() == ["", "a, b"]
    assert len(t) == 2


@pytest.mark.parametrize("text, match, line", [
    ("a,b\n1,2\n3,x7\n", "'x7' in column 'b' is not a number", 3),
    ("# only\n\n", "the table is empty", None),
    ("a,b\n1,2,3\n", "3 cells, the header has 2", 2),
])
def test_damage_is_one_line(tmp_path, text, match, line):
    path = _write(tmp_path, text)
    with pytest.raises(InputError, match=match) as err:
        read_table(path)
    assert str(path.name) in str(err.value)
    if line is not None:
        assert f":{line}" in str(err.value) or f"line {line}" in str(err.value)


def test_not_utf8(tmp_path):
    path = tmp_path / "t.csv"
    path.write_bytes(b"a,b\n\xff\xfe,1\n")
    with pytest.raises(InputError, match="not UTF-8"):
        read_table(path, ("a",))


def test_keyed_lookup_first_row_wins():
    t = Table({"id": np.array(["A", "B", "A"], dtype=object), "X": np.array([1.0, 2, 3])}, "id")
    np.testing.assert_array_equal(t.positions(["B", "A", "C"]), [1, 0, -1])
    assert t.value("A", "X") == 1.0 and t.value("C", "X") is None
    sub = t.take(t["X"] > 1.5)
    assert sub["id"].tolist() == ["B", "A"] and sub.row("A") == 1


def test_groups_in_order_of_first_appearance():
    code, names = groups(np.array(["S2", "S1", "S2", "S10", "S1"], dtype=object))
    assert names == ["S2", "S1", "S10"]
    np.testing.assert_array_equal(code, [0, 1, 0, 2, 1])
    code, names = groups(np.array([], dtype=object))
    assert names == [] and len(code) == 0


@pytest.mark.slow
def test_report_does_not_import_pandas(tmp_path):
    """A calibrate report of the lab data is built in a process that never
    imports pandas (its import was most of CAMCAL's report time)."""
    lab = ROOT / "tests" / "data" / "lab" / "lab.prj"
    if not lab.is_file():
        pytest.skip("tests/data/lab missing")
    code = (
        "import sys\n"
        "from photogram.project.reader import read_project\n"
        "from photogram.commands.bundle import calibrate\n"
        f"calibrate(read_project({str(lab)!r}), output={str(tmp_path / 'r')!r})\n"
        "print('pandas' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "False"
    assert (tmp_path / "r" / "report.pdf").stat().st_size > 10_000


def test_pandas_path_for_large_tables_reads_the_same(tmp_path):
    from photogram.report.table import read_table_pandas

    path = _write(tmp_path, "# c\nstation,point,x,vx,note\nS1,007,1.5,,a\nS2,,2.5,-1e-3,\n")
    a, b = read_table(path, ("station", "point"), "point"), \
        read_table_pandas(path, ("station", "point"), "point")
    assert a.columns == b.columns and a.key == b.key == "point"
    for c in a.columns:
        if a[c].dtype == object:
            assert a[c].tolist() == b[c].tolist()
        else:
            np.testing.assert_array_equal(a[c], b[c])
    bad = _write(tmp_path, "a,b\n1,2\n3,x7\n", "bad.csv")
    with pytest.raises(InputError, match="'x7' in column 'b'"):
        read_table_pandas(bad)


def test_sorted_groups_sort_the_names_as_text():
    from photogram.report.table import sorted_groups

    keys = np.array(["P10", "P2", "P10", "A"], dtype=object)
    code, names = sorted_groups(keys)
    assert names.tolist() == ["A", "P10", "P2"]
    assert [names[c] for c in code] == keys.tolist()


def test_per_image_statistics_equal_a_loop():
    from photogram.report.pages_residuals import _per_image, _stats, _w

    rng = np.random.default_rng(3)
    n = 500
    r = Table({"station": rng.choice(np.array(["S1", "S2", "S3", "S4"], dtype=object), n),
               "vx": rng.normal(size=n), "vy": rng.normal(size=n),
               "wx": np.where(rng.random(n) < 0.1, np.nan, rng.normal(size=n)),
               "wy": rng.normal(size=n),
               "used": rng.random(n) < 0.8})
    r = r.with_column("used", np.where(r["station"] == "S4", False, r["used"]))
    code, names = r.groups("station")
    got = _per_image(r, code, len(names))
    for i, name in enumerate(names):
        g = r.take((r["station"] == name) & r["used"])
        k, sx, sy, sv, mx = _stats(g)
        w = _w(g)
        want = [k, sx, sy, sv, mx, np.nanmax(w) if np.isfinite(w).any() else np.nan]
        np.testing.assert_allclose(got[i], want, rtol=1e-12, equal_nan=True)
    assert got[names.index("S4"), 0] == 0 and np.isnan(got[names.index("S4"), 1])
