"""Property-based fuzzing (hypothesis): arbitrary and almost-valid text and
bytes as a .prj, as each table of the lab project, as the mocap tables and
as every importer's input. Property: the command either succeeds (exit 0)
or fails with exit code 2 and one line on stderr naming an input file;
never a traceback or another exit code.

Derandomized and with fixed example counts, so that CI runs the same
examples every time (benchmarks/fuzz.py counts them)."""

from __future__ import annotations

import os
from collections import Counter

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzz.corpus import Case, run_case, staged_base
import pytest

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


def _n(examples: int) -> int:
    """The examples of a property: a third in `make test` (about 15 s), all
    with PHOTOGRAM_FUZZ_FULL=1 (benchmarks/fuzz.py counts its own)."""
    return examples if os.environ.get("PHOTOGRAM_FUZZ_FULL") else max(10, examples // 3)


SETTINGS = dict(deadline=None, derandomize=True, database=None,
                suppress_health_check=list(HealthCheck))
#: outcomes of every example run (benchmarks/fuzz.py reads them)
STATS: Counter = Counter()

_BASE = staged_base()        # shared with tests/test_fuzz_corpus.py


def _lines(rel: str) -> list[str]:
    return (_BASE / rel).read_text(encoding="utf-8").split("\n")


def check(rel: str, data: bytes, args: tuple, runner: str = "cli") -> None:
    """Run one example: ``rel`` replaced by ``data``."""
    case = Case("hypothesis", rel, lambda _: data, runner, args)
    res, bad = run_case(case, _BASE)          # its own empty output folder
    STATS["examples"] += 1
    STATS[f"exit{res.rc}"] += 1
    if "Traceback" in res.out + res.err:
        STATS["tracebacks"] += 1
    assert not bad, f"{bad}\ninput {data[:300]!r}\nstderr: {res.err[-3000:]}"


LAB = ("check", "-q", "{root}/lab/lab.prj")
FIELD = ("check", "-q", "{root}/field/field.prj")

# values a cell or a TOML value may take: numbers of every kind, ids, junk
NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(min_value=-10**30, max_value=10**30).map(str),
    st.sampled_from(["nan", "inf", "-inf", "1e400", "-1e400", "0x10", "1_0", "", " ", "1,5",
                     "1e-400", "+.5", "5.", "1e", "--1", "NaN", "Infinity"]))
IDS = st.one_of(st.sampled_from(["T01", "K1", "K1a", "SB1", "ZZ", "", "nan", "#x", '"q"']),
                st.text(max_size=6))
CELL = st.one_of(NUMBERS, IDS, st.text(max_size=10))
TOML_VALUE = st.one_of(
    NUMBERS.filter(lambda s: s.strip() != ""),
    st.text(max_size=12).map(lambda s: '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'),
    st.sampled_from(["true", "[]", "{}", "[1, 2]", '["a", 1]', "{ value = nan, free = true }",
                     '"gon"', '"deg"', '"furlong"', '"control"', '"ZZ.csv"', "[0, 0]",
                     "[640, 480, 3]", "-0.0", "1979-05-27"]),
    st.text(max_size=12))


def _toml_edits(rel: str):
    """An almost-valid TOML file: 1-3 lines of ``rel`` with their value
    replaced, deleted or doubled."""
    lines = _lines(rel)
    keys = [i for i, ln in enumerate(lines) if "=" in ln and not ln.lstrip().startswith("#")]
    edit = st.tuples(st.sampled_from(keys), st.sampled_from(["value", "delete", "double"]),
                     TOML_VALUE)

    def apply(edits):
        out = list(lines)
        for i, op, value in sorted(edits, reverse=True):
            if op == "value":
                out[i] = out[i].split("=", 1)[0] + "= " + value
            elif op == "delete":
                del out[i]
            else:
                out.insert(i, out[i])
        return "\n".join(out).encode("utf-8", "surrogatepass")
    return st.lists(edit, min_size=1, max_size=3).map(apply)


def _csv_edits(rel: str):
    """An almost-valid CSV table: cells of a few rows replaced, rows cut,
    doubled or deleted, the header edited."""
    lines = _lines(rel)
    body = [i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("#")]
    header, rows = body[0], body[1:]
    edit = st.tuples(st.sampled_from([header] + rows[:40]),
                     st.sampled_from(["cell", "cell", "cut", "double", "delete"]),
                     st.integers(0, 12), CELL)

    def apply(edits):
        out = list(lines)
        for i, op, col, value in sorted(edits, reverse=True):
            cells = out[i].split(",")
            if op == "cell":
                cells[col % len(cells)] = value
                out[i] = ",".join(cells)
            elif op == "cut":
                out[i] = out[i][: col * len(out[i]) // 12]
            elif op == "double":
                out.insert(i, out[i])
            else:
                del out[i]
        return "\n".join(out).encode("utf-8", "surrogatepass")
    return st.lists(edit, min_size=1, max_size=4).map(apply)


def _tokens(rel: str):
    """An almost-valid line-based foreign file: tokens replaced, lines cut."""
    lines = _lines(rel)
    body = [i for i, ln in enumerate(lines) if ln.strip()]
    edit = st.tuples(st.sampled_from(body), st.integers(0, 30), CELL)

    def apply(edits):
        out = list(lines)
        for i, k, value in edits:
            parts = out[i].split()
            if parts:
                parts[k % len(parts)] = value
            out[i] = " ".join(parts)
        return "\n".join(out).encode("utf-8", "surrogatepass")
    return st.lists(edit, min_size=1, max_size=4).map(apply)


def _text(max_size=400):
    return st.text(max_size=max_size).map(lambda s: s.encode("utf-8", "surrogatepass"))


# -- the project file ---------------------------------------------------------

@settings(max_examples=_n(200), **SETTINGS)
@given(st.one_of(st.binary(max_size=400), _text()))
def test_prj_arbitrary(data):
    check("lab/lab.prj", data, LAB)


@settings(max_examples=_n(450), **SETTINGS)
@given(_toml_edits("lab/lab.prj"))
def test_prj_almost_valid(data):
    check("lab/lab.prj", data, LAB)


@settings(max_examples=_n(180), **SETTINGS)
@given(_toml_edits("lab/results/cameras.toml"))
def test_cameras_toml_almost_valid(data):
    check("lab/results/cameras.toml", data, FIELD)


@settings(max_examples=_n(100), **SETTINGS)
@given(_toml_edits("ski-ptz/ski-ptz.prj"))
def test_mocap_prj_almost_valid(data):
    check("ski-ptz/ski-ptz.prj", data, ("check", "-q", "{root}/ski-ptz/ski-ptz.prj"))


# -- the tables ---------------------------------------------------------------

TABLES = ["lab/lab_stations.csv", "lab/lab_points.csv", "lab/lab_image_points.csv"]


@settings(max_examples=_n(250), **SETTINGS)
@given(st.sampled_from(TABLES), st.one_of(st.binary(max_size=300), _text(300)))
def test_table_arbitrary(rel, data):
    check(rel, data, LAB)


@settings(max_examples=_n(500), **SETTINGS)
@given(st.data())
def test_table_almost_valid(data):
    rel = data.draw(st.sampled_from(TABLES))
    check(rel, data.draw(_csv_edits(rel)), LAB)


@settings(max_examples=_n(100), **SETTINGS)
@given(st.data())
def test_jumps_tables_almost_valid(data):
    rel = data.draw(st.sampled_from(["jumps/jumper_points.csv", "field/results/stations.csv"]))
    check(rel, data.draw(_csv_edits(rel)), ("check", "-q", "{root}/jumps/jumps.prj"))


@settings(max_examples=_n(40), **SETTINGS)
@given(st.data())
def test_mocap_tables_almost_valid(data):
    rel = data.draw(st.sampled_from(["ski-ptz/camera_frames.csv",
                                     "ski-ptz/rotation_differences.csv"]))
    check(rel, data.draw(_csv_edits(rel)), ("{root}/ski-ptz/ski-ptz-estimate.prj",),
          runner="mocap-read")


# -- the importers --------------------------------------------------------------

IMPORTS = {
    "pose2sim": ("import/pose2sim/Calib.toml", "pose2sim/Calib.toml"),
    "opencv": ("import/opencv/cam.yml", "opencv/cam.yml"),
    "colmap": ("import/colmap/images.txt", "colmap"),
    "colmap-cameras": ("import/colmap/cameras.txt", "colmap"),
    "bal": ("import/bal/problem.txt", "bal/problem.txt"),
}
if (_BASE / "import" / "pmexport").is_dir():
    IMPORTS["pmexport"] = ("import/pmexport/camcal.txt", "pmexport/camcal.txt")
if (_BASE / "import" / "dbat").is_dir():
    IMPORTS["dbat"] = ("import/dbat/sxb.xml", "dbat/sxb.xml")


def _import_args(key):
    rel, src = IMPORTS[key]
    fmt = key.split("-")[0]
    return rel, ("import", fmt, "{root}/import/" + src, "--to", "{out}/imported")


@settings(max_examples=_n(250), **SETTINGS)
@given(st.sampled_from(sorted(IMPORTS)), st.one_of(st.binary(max_size=300), _text(300)))
def test_importer_arbitrary(key, data):
    rel, args = _import_args(key)
    check(rel, data, args)


@settings(max_examples=_n(450), **SETTINGS)
@given(st.data())
def test_importer_almost_valid(data):
    key = data.draw(st.sampled_from(sorted(IMPORTS)))
    rel, args = _import_args(key)
    edits = _toml_edits(rel) if rel.endswith(".toml") else _tokens(rel)
    check(rel, data.draw(edits), args)
