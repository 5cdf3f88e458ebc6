"""The command hands its report the tables it wrote (issue 23, item 1):
the handed-over tables equal what reading the files gives (the small-table
reader and pandas' reader alike), the report is byte for byte the one
`photogram report FOLDER` rebuilds, and where equality cannot be
guaranteed the file is read instead."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import photogram.report.data as report_data
from photogram.commands.bundle import calibrate
from photogram.project.atomic import atomic_write_text
from photogram.project.reader import read_project
from photogram.project.results import WrittenTable
from photogram.project.tables import format_table
from photogram.project.writer import write_project
from photogram.report import write_report
from photogram.report.handover import table_from_written
from photogram.report.table import read_table, read_table_pandas
from photogram.simulation.network import to_project, wall_network

SPECS = {"stations.csv": (("station", "camera"), "station"),
         "points.csv": (("id", "kind"), "id"),
         "residuals.csv": (("station", "point", "line"), None)}


@pytest.fixture(scope="module")
def wall(tmp_path_factory):
    """A small SIMULATED wall network (12 stations, 300 points), calibrated
    with its report; the tables the command handed over, recorded."""
    tmp = tmp_path_factory.mktemp("handover")
    net = wall_network(n_stations=12, n_points=300, rays=5, seed=3)
    prj = to_project(net, control=range(8), perturb_points=0.05, perturb_stations=0.005,
                     sigma_image=0.5, rng=np.random.default_rng(3), name="wall")
    prj.adjustment.datum = "control"
    project = read_project(write_project(prj, tmp / "wall.prj"))
    handed = {}
    original = report_data.table_from_written

    def spy(written, path, text=(), key=None):
        handed[path.name] = (written, original(written, path, text, key))
        return handed[path.name][1]

    report_data.table_from_written = spy
    try:
        calibrate(project, output=tmp / "results")
    finally:
        report_data.table_from_written = original
    return tmp / "results", handed


def _assert_same_table(a, b):
    assert a.columns == b.columns and a.key == b.key and len(a) == len(b)
    for name in a.columns:
        x, y = a[name], b[name]
        assert x.dtype == y.dtype, name
        if x.dtype.kind == "f":
            assert np.array_equal(x, y, equal_nan=True), name
            assert np.array_equal(np.signbit(x), np.signbit(y)), name
        else:
            assert x.tolist() == y.tolist(), name


def test_the_command_hands_over_every_table(wall):
    _, handed = wall
    assert sorted(handed) == sorted(SPECS)
    for name, (written, table) in handed.items():
        assert isinstance(written, WrittenTable), name
        assert table is not None, f"{name} was read from the file"


@pytest.mark.parametrize("reader", [read_table, read_table_pandas])
def test_handed_tables_equal_the_files_as_read(wall, reader):
    folder, handed = wall
    for name, (text, key) in SPECS.items():
        _assert_same_table(handed[name][1], reader(folder / name, text, key=key))


def test_the_report_is_the_one_rebuilt_from_the_files(wall):
    folder, _ = wall
    written = (folder / "report.pdf").read_bytes()
    write_report(folder)                # no project, no tables: everything read back
    assert (folder / "report.pdf").read_bytes() == written


def test_the_rebuild_through_pandas_is_the_same_report(wall, monkeypatch):
    folder, _ = wall
    written = (folder / "report.pdf").read_bytes()
    monkeypatch.setattr(report_data, "PANDAS_BYTES", 0)   # as for a large folder
    write_report(folder)
    assert (folder / "report.pdf").read_bytes() == written


def _written(tmp_path, columns, name="t.csv"):
    """The table written as write_results writes it (atomically, a new
    file), with its WrittenTable."""
    text = format_table(columns)
    path = tmp_path / name
    atomic_write_text(path, text)
    st = path.stat()
    return WrittenTable(columns, len(text.encode("utf-8")), (st.st_ino, st.st_mtime_ns)), path


def test_numbers_ids_and_empty_cells_read_back_exactly(tmp_path):
    rng = np.random.default_rng(0)
    values = rng.normal(size=50) * 10.0 ** rng.integers(-12, 12, 50)
    values[[3, 7]] = np.nan
    values[9] = -0.0
    cols = {"id": np.array([f"P{i}" for i in range(50)], dtype=object), "x": values,
            "n": np.arange(50) - 25, "s": [f"{v:.6g}" for v in rng.normal(size=50)]}
    written, path = _written(tmp_path, cols)
    table = table_from_written(written, path, ("id",), key="id")
    assert table is not None
    _assert_same_table(table, read_table(path, ("id",), key="id"))
    _assert_same_table(table, read_table_pandas(path, ("id",), key="id"))


@pytest.mark.parametrize("cols", [
    {"id": ["P#1", "P2"], "x": [1.0, 2.0]},         # '#' starts a comment for pandas
    {"id": ['P"1', "P2"], "x": [1.0, 2.0]},         # quoted by the writer
    {"id": ["P,1", "P2"], "x": [1.0, 2.0]},
    {"id": ["P1", 2], "x": [1.0, 2.0]},             # an id that is not a string
    {"id": ["P1", "P2"], "x": [1.0, np.inf]},       # 'inf': the readers differ
    {"id": ["P1", "P2"], "x": np.array([True, False])},
    {"id": ["P1", "P2"], "x": ["1.5", "nan"]},      # text that is no plain number
    {"id": ["P1", "P2"], "x": ["1.5", " 2"]},
    {"id": ["P1", "P2"], "note": ["a", "b"]},       # kept as text, not an id
    {"id": ["P1", "P2"], " x": [1.0, 2.0]},          # a blank in a column name
])
def test_what_is_not_sure_to_read_back_the_same_is_read_from_the_file(tmp_path, cols):
    written, path = _written(tmp_path, cols)
    assert table_from_written(written, path, ("id",), key="id") is None


def test_a_file_changed_since_it_was_written_is_read(tmp_path):
    written, path = _written(tmp_path, {"id": ["P1", "P2"], "x": [1.0, 2.0]})
    assert table_from_written(written, path, ("id",), key="id") is not None
    # replaced by a table of the same size (a new file, as every writer here makes)
    _, same_size = _written(tmp_path, {"id": ["P1", "P2"], "x": [1.0, 2.5]}, "u.csv")
    assert same_size.stat().st_size == written.nbytes
    same_size.replace(path)
    assert table_from_written(written, path, ("id",), key="id") is None
    # longer
    path.write_text("id,x\nP1,1.0\nP2,2.25\n", encoding="utf-8")
    assert table_from_written(written, path, ("id",), key="id") is None
    path.unlink()
    assert table_from_written(written, path, ("id",), key="id") is None
    assert table_from_written(None, Path("nowhere.csv")) is None


def test_handed_residuals_carry_the_groups_of_their_ids(wall):
    from photogram.report.table import groups
    _, handed = wall
    table = handed["residuals.csv"][1]
    seeded = table.__dict__.get("_groups", {})
    assert sorted(seeded) == ["point", "station"]
    for name, (codes, names) in seeded.items():
        want_codes, want_names = groups(table[name])
        assert np.array_equal(codes, want_codes) and codes.dtype == want_codes.dtype
        assert names == want_names
    # the report's residuals (with their "used" column) keep them
    assert table.with_column("used", np.ones(len(table), bool)).groups("point") is \
        seeded["point"]


def test_groups_from_indices_equal_groups_of_the_text():
    from photogram.report.handover import groups_from_index
    from photogram.report.table import groups
    rng = np.random.default_rng(4)
    ids = [f"P{i}" for i in rng.permutation(500)]
    for n in (0, 1, 7, 2000):
        index = rng.integers(0, 300, n)            # not every id used, in random order
        codes, names = groups_from_index(index, ids)
        want_codes, want_names = groups(np.array(ids, dtype=object)[index])
        assert np.array_equal(codes, want_codes) and names == want_names
    assert groups_from_index(np.array([0, 1]), ["a", "a"]) is None       # ids not distinct
    assert groups_from_index(np.array([0, -1]), ["a", "b"]) is None      # -1 would wrap
    assert groups_from_index(np.array([0, 2]), ["a", "b"]) is None
    assert groups_from_index(np.array([0.0, 1.0]), ["a", "b"]) is None
