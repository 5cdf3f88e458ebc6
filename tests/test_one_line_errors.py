"""Issue 16, item 21: hostile inputs that ended as "internal error ... (please
report)" with exit 1 now end as one line on stderr naming the file and what
is wrong, exit 2, no traceback; the size-based ones are refused before
anything big is allocated (docs/reliability.md, "Issue 16, item 21").

Every test goes through the command line (``photogram_cli.main.main``).
"""

from __future__ import annotations

import bz2
import errno
import gzip
import json
import os
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

import photogram
from photogram_cli.main import main

from project_cases import make_project

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

DATA = Path(__file__).parent / "data"
PROJECTS = Path(photogram.__file__).resolve().parents[1] / "projects"
MIB = 1 << 20


def _one_line(capsys) -> str:
    """The single line on stderr (asserting there is exactly one)."""
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "internal error" not in err, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    return lines[0]


def _png(path: Path, width: int, height: int) -> Path:
    """A tiny PNG whose IHDR claims ``width`` x ``height`` (nothing allocated)."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + \
            struct.pack(">I", zlib.crc32(kind + data))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) +
                     chunk(b"IDAT", zlib.compress(b"")) + chunk(b"IEND", b""))
    return path


# --------------------------------------------------------------------------
# TOML nested 100,000 deep
# --------------------------------------------------------------------------

@pytest.mark.parametrize("value", ["[" * 100_000 + "]" * 100_000,
                                   "{a = " * 100_000 + "1" + "}" * 100_000],
                         ids=["arrays", "inline-tables"])
def test_toml_nested_100000_deep(tmp_path, capsys, value):
    prj = make_project(tmp_path)
    text = prj.read_text()
    line = text.count("\n") + 3
    prj.write_text(text + "\n[intersect]\nfps = " + value + "\n")
    assert main(["check", str(prj)]) == 2
    assert _one_line(capsys) == (
        f"{prj}:{line}: arrays or tables nested more than 100 levels deep (photogram reads "
        f"TOML nested at most 100 levels; the file is damaged or not a photogram file)")


def test_toml_nesting_limit_ignores_brackets_in_strings_and_comments(tmp_path, capsys):
    """100 levels are read; brackets in strings and comments do not count."""
    prj = make_project(tmp_path)
    deep = "[" * 100 + "]" * 100
    prj.write_text(prj.read_text() + f'\n# {"[" * 300}\n[intersect]\n'
                   f'x = "{"{" * 300}"\ny = """{"[" * 300}"""\nz = {deep}\n')
    assert main(["check", str(prj)]) == 2        # read, then: x is an unknown key
    assert "unknown key 'x' in [intersect]" in _one_line(capsys)


def test_toml_nested_in_a_real_process(tmp_path):
    """The real console process: one line, exit 2 (no RecursionError)."""
    prj = make_project(tmp_path)
    prj.write_text("a = " + "[" * 100_000 + "]" * 100_000 + "\n")
    proc = subprocess.run([sys.executable, "-m", "photogram_cli", "check", str(prj)],
                          capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONWARNINGS="ignore"))
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.splitlines() == [
        f"{prj}:1: arrays or tables nested more than 100 levels deep (photogram reads TOML "
        f"nested at most 100 levels; the file is damaged or not a photogram file)"]


# --------------------------------------------------------------------------
# a CSV cell over 128 KiB
# --------------------------------------------------------------------------

@pytest.mark.parametrize("quoted", [False, True], ids=["plain", "quoted"])
def test_csv_cell_over_128_kib(tmp_path, capsys, quoted):
    prj = make_project(tmp_path)
    points = prj.parent / "points.csv"
    lines = points.read_text().splitlines()
    big = "x" * (128 * 1024 + 1)
    lines[2] = (f'"{big}"' if quoted else big) + lines[2][1:]
    points.write_text("\n".join(lines) + "\n")
    assert main(["check", str(prj)]) == 2
    assert _one_line(capsys) == (
        f"{points}:3: a cell of this record is longer than 131072 characters (128 KiB), more "
        f"than a CSV cell may hold (is a quote \" not closed? Otherwise shorten the cell)")


def test_csv_unclosed_quote_names_the_line_where_it_opens(tmp_path, capsys):
    """An unclosed quote makes the rest of a long file one cell: the line of
    the quote is named."""
    prj = make_project(tmp_path)
    points = prj.parent / "points.csv"
    lines = points.read_text().splitlines()
    lines[3] = '"' + lines[3]
    lines += [f"T{i},tie,1,2,3,,," for i in range(8000)]
    points.write_text("\n".join(lines) + "\n")
    assert main(["check", str(prj)]) == 2
    assert _one_line(capsys).startswith(f"{points}:4: a cell of this record is longer than "
                                        f"131072 characters")


def test_csv_cell_over_128_kib_in_the_rotation_differences(tmp_path, capsys):
    """The mocap rotation-differences table has its own CSV reader."""
    folder = tmp_path / "ski"
    shutil.copytree(PROJECTS / "ski-ptz", folder, ignore=shutil.ignore_patterns("results*"))
    table = folder / "rotation_differences.csv"
    lines = table.read_text().splitlines()
    k = [i for i, line in enumerate(lines) if not line.startswith("#")][3]
    row = lines[k].split(",")
    row[2] = "1" * (128 * 1024 + 1)
    lines[k] = ",".join(row)
    table.write_text("\n".join(lines) + "\n")
    assert main(["mocap", "--no-report", "-q", str(folder / "ski-ptz-estimate.prj"),
                 "--output", str(tmp_path / "out")]) == 2
    assert _one_line(capsys).startswith(f"{table}:{k + 1}: a cell of this record is longer "
                                        f"than 131072 characters (128 KiB)")


# --------------------------------------------------------------------------
# a project folder without execute permission
# --------------------------------------------------------------------------

def _deny_inside(monkeypatch, folder: Path):
    """Make every stat/open of a path inside ``folder`` fail as it does when
    the folder lacks execute (search) permission (works as root too)."""
    real_stat, real_open = os.stat, os.open

    def denied(path):
        p = Path(os.fsdecode(path)) if not isinstance(path, int) else None
        return p is not None and p.parent == folder

    def stat(path, *args, **kw):
        if denied(path):
            raise PermissionError(errno.EACCES, "Permission denied", os.fsdecode(path))
        return real_stat(path, *args, **kw)

    def open_(path, *args, **kw):
        if denied(path):
            raise PermissionError(errno.EACCES, "Permission denied", os.fsdecode(path))
        return real_open(path, *args, **kw)

    monkeypatch.setattr(os, "stat", stat)
    monkeypatch.setattr(os, "open", open_)


@pytest.mark.parametrize("command", ["check", "calibrate"])
def test_project_folder_without_execute_permission(tmp_path, capsys, monkeypatch, command):
    prj = make_project(tmp_path)
    _deny_inside(monkeypatch, prj.parent)
    assert main([command, str(prj)]) == 2
    folder = prj.parent
    assert _one_line(capsys) == (
        f"{prj}: permission denied: the project cannot be read (photogram needs read and "
        f"execute (search) permission on the folder {folder}: e.g. chmod u+rx {folder})")


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0,
                    reason="as root the permission check is moot")
def test_project_folder_without_execute_permission_real(tmp_path, capsys):
    prj = make_project(tmp_path)
    prj.parent.chmod(0o600)
    try:
        assert main(["check", str(prj)]) == 2
        assert "permission denied" in _one_line(capsys)
    finally:
        prj.parent.chmod(0o700)


def test_permission_error_anywhere_is_one_line(tmp_path, capsys, monkeypatch):
    """Last resort: a PermissionError no reader converted names its file."""
    import photogram.project as project_pkg

    def read_project(path):
        raise PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "x.csv"))

    monkeypatch.setattr(project_pkg, "read_project", read_project)
    assert main(["check", str(tmp_path / "p.prj")]) == 2
    assert _one_line(capsys).startswith(f"{tmp_path / 'x.csv'}: permission denied")


# --------------------------------------------------------------------------
# --output pointing at a symlink loop
# --------------------------------------------------------------------------

def _loop(tmp_path: Path) -> Path:
    a, b = tmp_path / "loopA", tmp_path / "loopB"
    a.symlink_to(b)
    b.symlink_to(a)
    return a


@pytest.mark.parametrize("command,sub", [("calibrate", ""), ("intersect", "x"),
                                         ("check", ""), ("mocap", "")])
def test_output_symlink_loop(tmp_path, capsys, command, sub):
    prj = make_project(tmp_path)
    out = _loop(tmp_path) / sub if sub else _loop(tmp_path)
    assert main([command, str(prj), "--output", str(out)]) == 2
    assert _one_line(capsys) == (f"{out}: --output: a loop of symbolic links, not a folder "
                                 f"(give a real folder; check the links with ls -l)")


def test_output_folder_of_the_project_file_is_a_symlink_loop(tmp_path, capsys):
    prj = make_project(tmp_path)
    _loop(prj.parent)
    prj.write_text(prj.read_text().replace('folder = "results"', 'folder = "loopA"'))
    assert main(["calibrate", "--no-report", str(prj)]) == 2
    assert _one_line(capsys).startswith(f"{prj.parent / 'loopA'}: [output] folder: a loop of "
                                        f"symbolic links")


def test_report_output_symlink_loop(results, tmp_path, capsys):
    out = _loop(tmp_path)
    assert main(["report", str(results), "--output", str(out)]) == 2
    assert _one_line(capsys).startswith(f"{out}: --output: a loop of symbolic links")


# --------------------------------------------------------------------------
# photogram report: residuals.csv, summary.json, covariance.npz
# --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """A calibrate results folder of tests/data/lab."""
    folder = tmp_path_factory.mktemp("item21") / "results"
    assert main(["calibrate", "--no-report", "-q", str(DATA / "lab" / "lab.prj"), "--output", str(folder)]) == 0
    return folder


@pytest.fixture
def damaged(results, tmp_path):
    folder = tmp_path / "results"
    shutil.copytree(results, folder)
    return folder


def test_report_text_in_a_number_column_of_residuals(damaged, capsys):
    path = damaged / "residuals.csv"
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    row = lines[3].split(",")
    row[header.index("vx")] = "abc"
    lines[3] = ",".join(row)
    path.write_text("\n".join(lines) + "\n")
    assert main(["report", str(damaged)]) == 2
    assert _one_line(capsys) == (
        f"{path}:4: 'abc' in column 'vx' is not a number (a results table holds numbers in "
        f"this column; the file is damaged: run the command again)")


def test_report_residuals_that_do_not_parse(damaged, capsys):
    path = damaged / "residuals.csv"
    path.write_text(path.read_text() + "a,b,c,d,e,f,g,h,i,j,k,l,m,n\n")
    line = len(path.read_text().splitlines())
    header = len(path.read_text().splitlines()[0].split(","))
    assert main(["report", str(damaged)]) == 2
    assert _one_line(capsys).startswith(
        f"{path}:{line}: cannot read the table: 14 cells, the header has {header} "
        "(the file is damaged: run the command again)")


@pytest.mark.parametrize("content,what", [
    (b"[1, 2]", "summary.json holds an array, not a JSON object"),
    (b"null", "summary.json holds null, not a JSON object"),
    (b"1e999999", "summary.json holds a number, not a JSON object"),
    (b'"text"', "summary.json holds a string, not a JSON object"),
    (b'{"redundancy": ' + b"9" * 5000 + b"}",
     "not valid JSON: Exceeds the limit (4300 digits) for integer string conversion: "
     "value has 5000 digits"),
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00", "the file is not UTF-8 text: byte 0x89"),
], ids=["array", "null", "huge-number", "string", "5000-digits", "binary"])
def test_report_binary_or_wrong_summary_json(damaged, capsys, content, what):
    path = damaged / "summary.json"
    path.write_bytes(content)
    assert main(["report", str(damaged)]) == 2
    line = _one_line(capsys)
    assert line.startswith(f"{path}") and what in line, line


def test_report_summary_json_over_the_size_limit(damaged, capsys, monkeypatch):
    import photogram.project.limits as limits
    monkeypatch.setattr(limits, "MAX_JSON_BYTES", 1000)
    path = damaged / "summary.json"
    path.write_text(json.dumps({"command": "calibrate", "pad": "x" * 3000}))
    assert main(["report", str(damaged)]) == 2
    assert _one_line(capsys).startswith(f"{path}: summary.json is 0 MiB, more than photogram "
                                        f"reads (0 MiB)")


@pytest.mark.parametrize("text", ["[" * 100_000 + "]" * 100_000,
                                  '{"a": ' * 100_000 + "1" + "}" * 100_000],
                         ids=["arrays", "objects"])
def test_report_deeply_nested_summary_json(damaged, capsys, text):
    path = damaged / "summary.json"
    path.write_text(text)
    assert main(["report", str(damaged)]) == 2
    assert _one_line(capsys) == (
        f"{path}:1: arrays or tables nested more than 100 levels deep (photogram reads JSON "
        f"nested at most 100 levels; the file is damaged or not a photogram file)")


class _Trap:
    """Unpickling this object creates the file ``marker``: proof that a
    pickle was (not) loaded."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _pickled_covariance(path: Path, marker: Path) -> None:
    trap = np.empty(1, dtype=object)
    trap[0] = _Trap(marker)
    np.savez(path, labels=trap, matrix=np.eye(1))


PICKLED = ("the covariance file holds pickled Python objects, which photogram never loads "
           "(np.load with allow_pickle=False) (a pickle can run code: write the file again "
           "with the command that made it)")


def test_report_pickled_covariance(damaged, capsys, tmp_path):
    marker = tmp_path / "unpickled"
    _pickled_covariance(damaged / "covariance.npz", marker)
    assert main(["report", str(damaged)]) == 2
    assert _one_line(capsys) == f"{damaged / 'covariance.npz'}: {PICKLED}"
    assert not marker.exists()


def test_orient_with_a_pickled_covariance_beside_the_cameras(tmp_path, capsys):
    """orient reads the calibration's covariance.npz beside the cameras file."""
    prj = make_project(tmp_path, "field")
    marker = tmp_path / "unpickled"
    _pickled_covariance(prj.parent / "covariance.npz", marker)
    assert main(["orient", "--no-report", "-q", str(prj)]) == 2
    assert _one_line(capsys) == f"{prj.parent / 'covariance.npz'}: {PICKLED}"
    assert not marker.exists()


def test_covariance_with_mismatched_arrays(tmp_path, capsys):
    prj = make_project(tmp_path, "field")
    np.savez(prj.parent / "covariance.npz", labels=np.array(["K1.c", "K1.x0"]),
             matrix=np.eye(3))
    assert main(["orient", "--no-report", "-q", str(prj)]) == 2
    assert _one_line(capsys).startswith(
        f"{prj.parent / 'covariance.npz'}: the covariance file does not hold 2 labels and a "
        f"finite 2 x 2 matrix")


# --------------------------------------------------------------------------
# a 40000 x 40000 PNG
# --------------------------------------------------------------------------

BIG = ("the image is 40000 x 40000 pixels, more than photogram reads (250 megapixels) "
       "(scale it down, or check that the file is not damaged)")


def test_import_images_40000_square_png(tmp_path, capsys):
    png = _png(tmp_path / "images" / "a.png", 40000, 40000)
    assert main(["import", "images", str(png.parent), "--target", "chessboard:9x6:0.025",
                 "--to", str(tmp_path / "out")]) == 2
    assert _one_line(capsys) == f"{png}: {BIG}"


def test_import_images_under_opencv_limit_but_over_ours(tmp_path, capsys):
    """16000 x 16000 (256 Mpx) OpenCV would decode; refused from its header."""
    png = _png(tmp_path / "images" / "a.png", 16000, 16000)
    assert main(["import", "images", str(png.parent), "--target", "chessboard:9x6:0.025",
                 "--to", str(tmp_path / "out")]) == 2
    assert _one_line(capsys).startswith(f"{png}: the image is 16000 x 16000 pixels")


def test_mocap_image_folder_with_a_40000_square_png(tmp_path, capsys):
    folder = tmp_path / "ski"
    shutil.copytree(PROJECTS / "ski-ptz", folder, ignore=shutil.ignore_patterns("results*"))
    png = _png(folder / "frames" / "C1" / "0001.png", 40000, 40000)
    prj = folder / "ski-ptz-estimate.prj"
    text = "".join(line for line in prj.read_text().splitlines(keepends=True)
                   if not line.startswith("rotation_differences ="))
    text += "\n[mocap.images]\n" + "".join(f'C{i} = "frames/C1"\n' for i in range(1, 7))
    prj.write_text(text)
    assert main(["mocap", "--no-report", "-q", str(prj), "--output", str(tmp_path / "out")]) == 2
    assert _one_line(capsys) == f"{png}: {BIG}"


def test_image_headers_are_read_without_decoding(tmp_path):
    """The sizes of PNG, JPEG, BMP, TIFF and PNM headers."""
    from photogram.project.limits import image_size
    files = {
        "a.png": _png(tmp_path / "a.png", 40000, 30000).read_bytes(),
        "a.jpg": b"\xff\xd8\xff\xe0\x00\x10JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00"
                 b"\xff\xc0\x00\x11\x08" + struct.pack(">HH", 30000, 40000) + b"\x03" + b"\0" * 9,
        "a.bmp": b"BM" + b"\0" * 16 + struct.pack("<ii", 40000, -30000) + b"\0" * 30,
        "a.tif": b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", 2)
                 + struct.pack("<HHII", 256, 4, 1, 40000)
                 + struct.pack("<HHIHH", 257, 3, 1, 30000, 0),
        "a.pgm": b"P5\n# comment\n40000 30000\n255\n",
    }
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
        assert image_size(tmp_path / name) == (40000, 30000), name


# --------------------------------------------------------------------------
# a BAL .bz2 that inflates to gigabytes
# --------------------------------------------------------------------------

def _bomb(path: Path, mib: int) -> Path:
    """A compressed file of ``mib`` MiB of '0' (streams of 16 MiB repeated:
    a few KB on disk)."""
    block = b"0" * (16 * MIB)
    one = bz2.compress(block) if path.suffix == ".bz2" else gzip.compress(block)
    path.write_bytes(one * (mib // 16))
    return path


def test_bal_bz2_that_inflates_to_gigabytes(tmp_path, capsys):
    """4 GiB of text in 11.5 KB: refused at the real limit (256 MiB) while
    streaming, without holding it."""
    bomb = _bomb(tmp_path / "problem.txt.bz2", 4096)
    assert bomb.stat().st_size < 20_000
    assert main(["import", "bal", str(bomb), "--to", str(tmp_path / "out")]) == 2
    assert _one_line(capsys) == (
        f"{bomb}: the BAL file inflates to more than photogram reads (256 MiB) (a damaged or "
        f"hostile archive, or a problem too big for photogram: split it or use a smaller one)")


@pytest.mark.parametrize("name", ["problem.txt.gz", "problem.txt"])
def test_bal_gz_or_plain_over_the_limit(tmp_path, capsys, monkeypatch, name):
    import photogram.project.limits as limits
    monkeypatch.setattr(limits, "MAX_DECOMPRESSED_BYTES", 8 * MIB)
    path = tmp_path / name
    if name.endswith(".gz"):
        _bomb(path, 32)
    else:
        path.write_bytes(b"1 1 1\n" + b"0 " * (5 * MIB))
    assert main(["import", "bal", str(path), "--to", str(tmp_path / "out")]) == 2
    line = _one_line(capsys)
    assert line.startswith(f"{path}: the BAL file ") and "more than photogram reads (8 MiB)" \
        in line, line


def test_decompression_is_measured_while_streaming(tmp_path):
    """The measuring pass holds at most one chunk: peak memory stays below
    half the limit (the inflated data is never held)."""
    import tracemalloc

    from photogram.errors import InputError
    from photogram.project.limits import read_maybe_compressed
    bomb = _bomb(tmp_path / "b.bz2", 64)
    tracemalloc.start()
    try:
        with pytest.raises(InputError, match="inflates to more than"):
            read_maybe_compressed(bomb, limit=16 * MIB, what="BAL file")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 8 * MIB
    small = tmp_path / "s.bz2"
    small.write_bytes(bz2.compress(b"1 2 3\n"))
    assert read_maybe_compressed(small, limit=6) == b"1 2 3\n"


# --------------------------------------------------------------------------
# the last resort in the command line
# --------------------------------------------------------------------------

@pytest.mark.parametrize("error,words", [
    (MemoryError, "ran out of memory reading or processing this input"),
    (RecursionError, "an input file is nested too deeply"),
])
def test_memory_and_recursion_errors_are_one_line_naming_the_input(tmp_path, capsys,
                                                                   monkeypatch, error, words):
    import photogram.project as project_pkg

    def read_project(path):
        raise error()

    monkeypatch.setattr(project_pkg, "read_project", read_project)
    prj = tmp_path / "p.prj"
    assert main(["calibrate", "--no-report", str(prj)]) == 2
    line = _one_line(capsys)
    assert line.startswith(f"{prj}: photogram calibrate") and words in line, line


class _HugeVideo:
    """A stand-in for cv2.VideoCapture of a video whose frames are 40000 x
    40000: decoding a frame fails as it would for lack of memory."""

    def __init__(self, path):
        self.path = path

    def isOpened(self):
        return True

    def get(self, prop):
        import cv2
        return {cv2.CAP_PROP_FRAME_WIDTH: 40000.0, cv2.CAP_PROP_FRAME_HEIGHT: 40000.0,
                cv2.CAP_PROP_FRAME_COUNT: 279.0, cv2.CAP_PROP_FPS: 50.0}.get(prop, 0.0)

    def read(self):
        raise MemoryError("cannot allocate a 40000 x 40000 frame")

    grab = read

    def release(self):
        pass


def test_mocap_video_with_40000_square_frames(tmp_path, capsys, monkeypatch):
    import cv2
    folder = tmp_path / "ski"
    shutil.copytree(PROJECTS / "ski-ptz", folder, ignore=shutil.ignore_patterns("results*"))
    video = folder / "C1.avi"
    video.write_bytes(b"RIFF")
    prj = folder / "ski-ptz-estimate.prj"
    text = "".join(line for line in prj.read_text().splitlines(keepends=True)
                   if not line.startswith("rotation_differences ="))
    text += "\n[mocap.images]\n" + "".join(f'C{i} = "C1.avi"\n' for i in range(1, 7))
    prj.write_text(text)
    monkeypatch.setattr(cv2, "VideoCapture", _HugeVideo)
    assert main(["mocap", "--no-report", "-q", str(prj), "--output", str(tmp_path / "out")]) == 2
    assert _one_line(capsys) == (
        f"{video}: the video frame is 40000 x 40000 pixels, more than photogram reads "
        f"(250 megapixels) (scale it down, or check that the file is not damaged)")
