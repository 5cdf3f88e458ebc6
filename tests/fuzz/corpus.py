"""A corpus of malformed project files, tables and importer inputs, built
programmatically from the example projects (projects/) and from files the
exporters write, and a runner that checks the outcome of each case.

Nothing here writes below projects/: :func:`stage` copies the example
projects into a scratch folder once (:func:`staged_base`: once per process);
:class:`Mirror` mirrors that copy once with hard links, and each case puts
its mutated file in place, runs, and puts the link back
(:func:`materialize` still builds one case as a tree of its own). Real
commands write into ``--output``.

A case passes when the command returns 0 or 2, never prints a traceback or
"internal error", and on 2 writes exactly one line to stderr that starts with
the path of an input file of the case (``file:`` or ``file:line:``); when the
error names the mutated file at a row-local mutation, the line is the
mutated one. Cases marked ``expect="error"`` (NaN/inf/text in a numeric
cell, unknown references, duplicate ids, bytes that are not UTF-8) must
return 2.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import shutil
import sys
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[2]
PROJECTS = ROOT / "projects"
SHARED = ROOT.parent / "shared" / "data"

# --------------------------------------------------------------------------
# staging


_SKIP = {"results", "results-estimate", "results-measure", "results-typed"}


def stage(base: Path) -> Path:
    """Copy the example projects (and importer sources) into ``base``;
    returns ``base``. The lab and field results are computed there (the
    jumps and Monte-Carlo projects and the importer sources read them)."""
    base = Path(base)
    if (base / ".staged").is_file():
        return base
    for name in ("lab", "field", "jumps", "designs", "ski-ptz"):
        shutil.copytree(PROJECTS / name, base / name,
                        ignore=lambda folder, names: [n for n in names if n in _SKIP])
    _results(base)
    _trim_mocap(base / "ski-ptz", FRAMES)
    _importer_sources(base / "import")
    (base / ".staged").write_text("ok")
    return base


def _results(base: Path) -> None:
    """The lab and field results the jumps project and the importer sources
    read, computed in the staged copy (a fresh clone has none): the lab's
    photographs measured (its observations), the lab calibrated, the field
    oriented."""
    import contextlib
    import io

    from photogram_cli.main import main
    for command, prj, *more in (("measure", "lab/frame.toml", "--no-report"),
                                ("calibrate", "lab/lab.prj", "--no-report"),
                                ("orient", "field/field.prj", "--no-report")):
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            code = main([command, str(base / prj), "-q", *more])
        if code != 0:
            raise RuntimeError(f"photogram {command} {prj} failed while staging the corpus")


FRAMES = 12     # frames kept of projects/ski-ptz (the reading stage then takes ~0.05 s)


def _trim_mocap(folder: Path, n: int) -> None:
    """Keep the first ``n`` frames of the ski-ptz tables (``n - 1`` frame
    pairs of the rotation differences)."""
    for name, limit in (("detections.csv", n), ("camera_frames.csv", n),
                        ("truth/joints3d.csv", n), ("truth/outliers.csv", n),
                        ("rotation_differences.csv", n - 1)):
        path = folder / name
        if not path.is_file():
            continue
        lines = path.read_text(encoding="utf-8").split("\n")
        head = next(i for i, ln in enumerate(lines) if ln and not ln.startswith("#"))
        lagged = lines[head].rstrip().endswith(",to_frame")    # lagged pairs: both ends kept
        keep = lines[:head + 1] + [ln for ln in lines[head + 1:]
                                   if ln and int(ln.split(",")[0]) < limit
                                   and not (lagged and ln.split(",")[-1].strip()
                                            and int(ln.split(",")[-1]) > n - 1)]
        path.write_text("\n".join(keep) + "\n", encoding="utf-8")


def _importer_sources(folder: Path) -> None:
    """Valid inputs of every importer: written by our exporters from the
    field results, a small BAL problem, DBAT's sxb script (if present) and a
    PhotoModeler export (from DBAT's CAMCAL data, if present)."""
    from photogram.io.formats import export_results
    folder.mkdir(parents=True)
    field_results = folder.parent / "field" / "results"
    (folder / "pose2sim").mkdir()
    export_results("pose2sim", field_results, folder / "pose2sim" / "Calib.toml")
    export_results("colmap", field_results, folder / "colmap")
    from photogram.io.export_source import load_source, views_of
    from photogram.io.opencv_fs import format_opencv
    view = views_of(load_source(field_results).project)[0]
    (folder / "opencv").mkdir()
    (folder / "opencv" / "cam.yml").write_text(format_opencv(view, ".yml"), encoding="utf-8")
    (folder / "bal").mkdir()
    (folder / "bal" / "problem.txt").write_text(BAL_TEXT, encoding="utf-8")
    if (SHARED / "dbat" / "sxb" / "sxb.xml").is_file():
        shutil.copytree(SHARED / "dbat" / "sxb", folder / "dbat", copy_function=_copy_rw)
    if (SHARED / "dbat" / "camcal" / "markpts.txt").is_file():
        sys.path.insert(0, str(ROOT / "tests"))
        try:
            from test_io_dbat_pm import write_pmexport
        finally:
            sys.path.remove(str(ROOT / "tests"))
        (folder / "pmexport").mkdir()
        write_pmexport(folder / "pmexport" / "camcal.txt", n_marks=80)


def _copy_rw(src, dst):
    shutil.copyfile(src, dst)
    return dst


BAL_TEXT = """2 3 6
0 0 -10.5 12.25
1 0 -8.0 11.5
0 1 20.75 -3.5
1 1 22.0 -4.25
0 2 5.5 30.0
1 2 7.25 29.5
0.01
-0.02
0.005
0.1
-0.2
-8.0
500.0
1e-07
2e-13
-0.01
0.03
0.002
0.6
0.1
-8.2
510.0
-1e-07
1e-13
0.12
0.05
0.3
-0.4
0.02
-0.1
0.05
-0.3
0.2
"""


def materialize(base: Path, dest: Path, rel: str, data: bytes | None) -> Path:
    """Build ``dest`` as a mirror of ``base`` in which ``rel`` holds
    ``data``: the project folders and the folders on the way to ``rel`` are
    real (``..`` in a project must lead back into ``dest``), their files hard
    links (copies where links fail), deeper folders symbolic links."""
    target = Path(dest) / rel

    def mirror(src: Path, dst: Path, depth: int) -> None:
        dst.mkdir(parents=True, exist_ok=True)
        for child in src.iterdir():
            out = dst / child.name
            if child.name == ".staged" or out == target:
                continue
            if child.is_dir():
                if depth == 0 or target.is_relative_to(out):
                    mirror(child, out, depth + 1)
                else:
                    out.symlink_to(child, target_is_directory=True)
            else:
                try:
                    os.link(child, out)
                except OSError:
                    shutil.copyfile(child, out)
    mirror(Path(base), Path(dest), 0)
    if data is not None:
        target.write_bytes(data)
    return dest


# --------------------------------------------------------------------------
# cases


@dataclass(frozen=True)
class Case:
    """One malformed input: ``rel`` (the file, relative to the staged
    tree) mutated by ``mutate`` (bytes -> bytes), run as ``runner`` with
    ``args`` (paths relative to the case folder, see :func:`argv`)."""

    id: str
    rel: str
    mutate: Callable[[bytes], bytes] = field(compare=False)
    runner: str                     # "cli" or "mocap-read"
    args: tuple                     # argv with {root} and {out} placeholders
    expect: str = "any"             # "error" or "any"
    line: int | None = None         # the mutated line (1-based), for row-local mutations
    line_alt: int | None = None     # another acceptable line (duplicates)


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


def _join(lines: list[bytes]) -> bytes:
    return b"\n".join(lines)


def _csv_layout(data: bytes):
    """(lines, header index, data row indexes) of a CSV table."""
    lines = _lines(data)
    header = next(i for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith(b"#"))
    rows = [i for i in range(header + 1, len(lines))
            if lines[i].strip() and not lines[i].lstrip().startswith(b"#")]
    return lines, header, rows


def _set_cell(row: int, col: int, value: bytes, sep=b","):
    def f(data: bytes) -> bytes:
        lines = _lines(data)
        cells = lines[row].split(sep)
        cells[col] = value
        lines[row] = sep.join(cells)
        return _join(lines)
    return f


def _truncate(k: int):
    return lambda data: data[:k]


def _insert_line(after: int, text: bytes):
    def f(data: bytes) -> bytes:
        lines = _lines(data)
        lines.insert(after + 1, text)
        return _join(lines)
    return f


def _replace_line(i: int, text: bytes):
    def f(data: bytes) -> bytes:
        lines = _lines(data)
        lines[i] = text
        return _join(lines)
    return f


def _delete_line(i: int):
    def f(data: bytes) -> bytes:
        lines = _lines(data)
        del lines[i]
        return _join(lines)
    return f


def _keep_lines(n: int):
    return lambda data: _join(_lines(data)[:n]) + b"\n"


def _bom(data):
    return b"\xef\xbb\xbf" + data


def _crlf(data):
    return data.replace(b"\r\n", b"\n").replace(b"\n", b"\r\n")


def _whole_file(kind: str):
    return {"bom": _bom, "crlf": _crlf, "empty": lambda d: b"",
            "binary": lambda d: bytes(range(256)) * 4,
            "nul": lambda d: d.replace(b"\n", b"\x00\n", 3)}[kind]


def _is_number(text: bytes) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


NUMERIC_BAD = [b"nan", b"inf", b"-inf", b"1e400", b"abc"]      # each must be an error
NUMERIC_ANY = [b"", b"1e300", b"-1e300", b"0x10", b"1_0"]        # legal or an error
TEXT_ANY = [b"", b"nan", b" ", b"a,b", b'"q"', b"\xc3\xa9t\xc3\xa9"]

UNKNOWN = b"ZZ_UNKNOWN"
MAX_COLUMNS = 8      # cells mutated per row (the joints table has 74 columns)
ID_COLUMNS = ("id", "station", "point", "exposure", "camera", "from", "to")


def truncations(data: bytes) -> list[int]:
    n = len(data)
    return sorted({0, min(20, n - 1), n // 3, n // 2, (2 * n) // 3, n - 1} - {n})


def csv_cases(prefix: str, rel: str, data: bytes, runner: str, args: tuple, *,
              refs: dict[str, str] = (), unique: tuple = (), sep=b",",
              all_rows: bool = False) -> list[Case]:
    """Cases of one CSV table. ``refs``: column -> kind of id it refers to
    (an unknown id there is an error); ``unique``: columns whose combination
    must be unique (a duplicated first row is an error)."""
    lines, h, rows = _csv_layout(data)
    header = [c.strip().decode("utf-8", "replace") for c in lines[h].split(sep)]
    cases = []

    def add(name, mutate, expect="any", line=None, line_alt=None):
        cases.append(Case(f"{prefix}:{name}", rel, mutate, runner, args, expect, line, line_alt))

    for k in truncations(data):
        add(f"truncate@{k}", _truncate(k))
    add("header-only", _keep_lines(h + 1))
    add("comments-only", _keep_lines(h))
    for kind in ("bom", "crlf", "empty", "binary", "nul"):
        add(kind, _whole_file(kind))
    add("tabs", lambda d: d.replace(sep, b"\t"))
    add("semicolons", lambda d: d.replace(sep, b";"))
    if not rows:
        return cases
    targets = [rows[0], rows[-1]] if all_rows else [rows[0]]
    for r in targets:
        cells = lines[r].split(sep)
        where = "first" if r == rows[0] else "last"
        for c, name in enumerate(header[:MAX_COLUMNS]):
            if c >= len(cells):
                continue
            ignored = name.startswith(("_", "est_")) or name in ("note", "comment")
            numeric = _is_number(cells[c].strip()) and not ignored and name not in ID_COLUMNS
            for v in (NUMERIC_BAD + NUMERIC_ANY) if numeric else TEXT_ANY:
                bad = numeric and v in NUMERIC_BAD
                add(f"{where}:{name}={v.decode('utf-8', 'replace')!r}", _set_cell(r, c, v, sep),
                    "error" if bad else "any", r + 1)
            if name in dict(refs):
                add(f"{where}:{name}=unknown", _set_cell(r, c, UNKNOWN, sep), "error", r + 1)
        add(f"{where}:extra-field", _replace_line(r, lines[r] + sep + b"1"), "any", r + 1)
        add(f"{where}:missing-field", _replace_line(r, sep.join(cells[:-1])), "any", r + 1)
        add(f"{where}:non-utf8", _replace_line(r, lines[r] + b"\xff\xfe"), "error", r + 1)
        add(f"{where}:deleted", _delete_line(r))
    if unique:
        add("duplicate-row", _insert_line(rows[0], lines[rows[0]]), "error", rows[0] + 2,
            rows[0] + 1)
    add("unknown-column", _replace_line(h, lines[h] + sep + b"zz_col"))
    add("renamed-column", _replace_line(h, sep.join([b"zz_" + lines[h].split(sep)[0]]
                                                    + lines[h].split(sep)[1:])))
    add("duplicate-column", _replace_line(h, lines[h] + sep + lines[h].split(sep)[-1]))
    add("huge-row", _insert_line(rows[-1], sep.join([b"9" * 400] * len(header))))
    return cases


_KEY = re.compile(rb"^(\s*)([A-Za-z0-9_\-\"\.]+)(\s*=\s*)(.*)$")

TOML_VALUES = [b'"fuzz"', b"nan", b"inf", b"-1", b"1e400", b"[]", b"true",
               b"99999999999999999999999", b'"ZZ_UNKNOWN.csv"']


def toml_cases(prefix: str, rel: str, data: bytes, runner: str, args: tuple,
               values=TOML_VALUES, sections: tuple = ()) -> list[Case]:
    """Cases of one TOML file: every key (once per key name and section
    kind) set to wrong types, NaN/inf, huge and unknown values, deleted,
    renamed; whole-file truncations, bytes that are not UTF-8, BOM, CRLF."""
    lines = _lines(data)
    cases = []

    def add(name, mutate, expect="any", line=None):
        cases.append(Case(f"{prefix}:{name}", rel, mutate, runner, args, expect, line))

    for k in truncations(data):
        add(f"truncate@{k}", _truncate(k))
    for kind in ("bom", "crlf", "empty", "binary", "nul"):
        add(kind, _whole_file(kind))
    add("tabs", lambda d: d.replace(b" = ", b"\t=\t"))
    section, seen = b"", set()
    for i, ln in enumerate(lines):
        s = ln.strip()
        if s.startswith(b"["):
            section = re.sub(rb"\.[^.\]]*\]$", b".*]", s) if s.startswith(b"[cameras.") else s
            if (b"dup", s) not in seen:
                seen.add((b"dup", s))
                add(f"{s.decode()}:duplicate-section", _insert_line(len(lines) - 1, ln))
            continue
        m = _KEY.match(ln)
        if not m or s.startswith(b"#"):
            continue
        key = m.group(2)
        if (section, key) in seen or (sections and not section.startswith(sections)):
            continue
        seen.add((section, key))
        where = f"{section.decode()}{key.decode()}"
        for v in values:
            add(f"{where}={v.decode()}", _replace_line(i, m.group(1) + key + m.group(3) + v),
                "any", i + 1)
        add(f"{where}:deleted", _delete_line(i))
        add(f"{where}:renamed", _replace_line(i, m.group(1) + b"zz_" + key + m.group(3)
                                              + m.group(4)), "any", i + 1)
        add(f"{where}:non-utf8", _replace_line(i, m.group(1) + key + m.group(3) + b'"\xff"'),
            "error", i + 1)
        add(f"{where}:duplicate-key", _insert_line(i, ln), "error", i + 2)
        add(f"{where}:syntax", _replace_line(i, m.group(1) + key + m.group(3)), "error", i + 1)
    add("unknown-section", lambda d: d + b"\n[zz_section]\nx = 1\n")
    return cases


def text_cases(prefix: str, rel: str, data: bytes, runner: str, args: tuple,
               n_lines: int = 4, record_lines: bool = True) -> list[Case]:
    """Cases of a line-based foreign file (whitespace or comma separated):
    truncations, whole-file damage, and at a few lines each token set to
    NaN/inf/text/huge, the line doubled, deleted, or given bytes that are not
    UTF-8."""
    lines = _lines(data)
    cases = []

    def add(name, mutate, expect="any", line=None):
        # structured files (YAML, XML) name the line of the key, not of the value
        cases.append(Case(f"{prefix}:{name}", rel, mutate, runner, args, expect,
                          line if record_lines else None))

    for k in truncations(data):
        add(f"truncate@{k}", _truncate(k))
    for kind in ("bom", "crlf", "empty", "binary", "nul"):
        add(kind, _whole_file(kind))
    body = [i for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith(b"#")]
    picks = sorted({body[int(j * (len(body) - 1) / max(n_lines - 1, 1))]
                    for j in range(n_lines)}) if body else []
    for i in picks:
        tokens = re.split(rb"(\s+|,)", lines[i])
        idx = [j for j, t in enumerate(tokens) if t.strip() and t != b","]
        for j in idx[:6]:
            for v in (b"nan", b"abc", b"1e400", b"-1"):
                new = tokens.copy()
                new[j] = v
                add(f"line{i + 1}:tok{j // 2}={v.decode()}", _replace_line(i, b"".join(new)),
                    "any", i + 1)
        add(f"line{i + 1}:doubled", _insert_line(i, lines[i]))
        add(f"line{i + 1}:deleted", _delete_line(i))
        add(f"line{i + 1}:non-utf8", _replace_line(i, lines[i] + b" \xff"), "any", i + 1)
        add(f"line{i + 1}:cut", _replace_line(i, lines[i][: len(lines[i]) // 2]), "any", i + 1)
    return cases


def _check(prj):
    return ("check", "-q", "{root}/" + prj)


def build_cases(base: Path) -> list[Case]:
    """All corpus cases (``base``: the staged tree of :func:`stage`)."""
    cases: list[Case] = []

    def read(rel):
        return (base / rel).read_bytes()

    # lab: every file through `check`
    lab = _check("lab/lab.prj")
    cases += toml_cases("lab.prj", "lab/lab.prj", read("lab/lab.prj"), "cli", lab)
    cases += csv_cases("lab_stations", "lab/lab_stations.csv", read("lab/lab_stations.csv"),
                       "cli", lab, refs={"camera": "camera"}, unique=("station",), all_rows=True)
    cases += csv_cases("lab_points", "lab/lab_points.csv", read("lab/lab_points.csv"), "cli",
                       lab, unique=("id",), all_rows=True)
    # the typed table is read by lab-typed.prj; lab.prj reads the measured one
    cases += csv_cases("lab_image_points", "lab/lab_image_points.csv",
                       read("lab/lab_image_points.csv"), "cli", _check("lab/lab-typed.prj"),
                       refs={"station": "station", "point": "point"}, unique=("station", "point"),
                       all_rows=True)
    cases += csv_cases("lab_measured_points", "lab/results-measure/image_points.csv",
                       read("lab/results-measure/image_points.csv"), "cli", lab,
                       refs={"station": "station", "point": "point"}, unique=("station", "point"))
    # field: its tables and the lab's cameras.toml it refers to
    field = _check("field/field.prj")
    # ([project] and [output] keys are mutated in lab.prj)
    cases += toml_cases("field.prj", "field/field.prj", read("field/field.prj"), "cli", field,
                        sections=(b"[cameras", b"[stations", b"[points", b"[observations",
                                  b"[adjustment"))
    cases += csv_cases("field_stations", "field/field_stations.csv",
                       read("field/field_stations.csv"), "cli", field, refs={"camera": "camera"},
                       unique=("station",))
    cases += csv_cases("field_points", "field/field_points.csv", read("field/field_points.csv"),
                       "cli", field, unique=("id",))
    cases += csv_cases("field_image_points", "field/field_image_points.csv",
                       read("field/field_image_points.csv"), "cli", field,
                       refs={"station": "station", "point": "point"}, unique=("station", "point"))
    cases += toml_cases("lab/results/cameras.toml", "lab/results/cameras.toml",
                        read("lab/results/cameras.toml"), "cli", field,
                        values=[b'"fuzz"', b"nan", b"1e400", b"[]", b"true", b"-1"])
    # jumps: intersect project, its tables, the field results it reads
    jumps = _check("jumps/jumps.prj")
    cases += toml_cases("jumps.prj", "jumps/jumps.prj", read("jumps/jumps.prj"), "cli", jumps,
                        sections=(b"[cameras", b"[stations", b"[observations", b"[adjustment",
                                  b"[intersect"))
    cases += csv_cases("jumper_points", "jumps/jumper_points.csv",
                       read("jumps/jumper_points.csv"), "cli", jumps,
                       refs={"station": "station"}, unique=("station", "point", "exposure"))
    cases += csv_cases("ski_lines", "jumps/ski_lines.csv", read("jumps/ski_lines.csv"), "cli",
                       jumps, refs={"station": "station"})
    cases += csv_cases("field/results/stations", "field/results/stations.csv",
                       read("field/results/stations.csv"), "cli", jumps,
                       refs={"camera": "camera"}, unique=("station",))
    mc = _check("jumps/montecarlo.prj")
    cases += toml_cases("montecarlo.prj", "jumps/montecarlo.prj", read("jumps/montecarlo.prj"),
                        "cli", mc)
    sa = _check("designs/situation-a.prj")
    cases += toml_cases("situation-a.prj", "designs/situation-a.prj",
                        read("designs/situation-a.prj"), "cli", sa)
    # ski-ptz: the .prj files through `check`, the mocap tables through the
    # mocap command's reading stage
    cases += toml_cases("ski-ptz.prj", "ski-ptz/ski-ptz.prj", read("ski-ptz/ski-ptz.prj"), "cli",
                        _check("ski-ptz/ski-ptz.prj"))
    # the estimate project: only its [mocap] keys (the rest is as in ski-ptz.prj)
    cases += toml_cases("ski-ptz-estimate.prj", "ski-ptz/ski-ptz-estimate.prj",
                        read("ski-ptz/ski-ptz-estimate.prj"), "cli",
                        _check("ski-ptz/ski-ptz-estimate.prj"), sections=(b"[mocap",))
    est = ("{root}/ski-ptz/ski-ptz-estimate.prj",)
    known = ("{root}/ski-ptz/ski-ptz.prj",)
    cases += csv_cases("ski-ptz/stations", "ski-ptz/stations.csv", read("ski-ptz/stations.csv"),
                       "cli", _check("ski-ptz/ski-ptz.prj"), refs={"camera": "camera"},
                       unique=("station",))
    cases += csv_cases("camera_frames", "ski-ptz/camera_frames.csv",
                       read("ski-ptz/camera_frames.csv"), "mocap-read", known,
                       refs={"camera": "camera"}, unique=("frame", "camera"))
    cases += csv_cases("detections", "ski-ptz/detections.csv", read("ski-ptz/detections.csv"),
                       "mocap-read", known, refs={"camera": "camera", "joint": "joint"})
    cases += csv_cases("rotation_differences", "ski-ptz/rotation_differences.csv",
                       read("ski-ptz/rotation_differences.csv"), "mocap-read", est,
                       refs={"camera": "camera"}, unique=("frame", "camera"))
    cases += csv_cases("truth/joints3d", "ski-ptz/truth/joints3d.csv",
                       read("ski-ptz/truth/joints3d.csv"), "mocap-read", known)
    # importers
    imp = base / "import"

    def importer(fmt, src):
        return ("import", fmt, "{root}/import/" + src, "--to", "{out}/imported")
    cases += toml_cases("import-pose2sim", "import/pose2sim/Calib.toml",
                        read("import/pose2sim/Calib.toml"), "cli",
                        importer("pose2sim", "pose2sim/Calib.toml"),
                        values=[b'"fuzz"', b"nan", b"inf", b"[]", b"[1, 2]", b"1e400",
                                b"[[1, 2], [3]]", b"true"])
    cases += text_cases("import-opencv", "import/opencv/cam.yml", read("import/opencv/cam.yml"),
                        "cli", importer("opencv", "opencv/cam.yml"), n_lines=8,
                        record_lines=False)
    for f in ("cameras.txt", "images.txt", "points3D.txt"):
        cases += text_cases(f"import-colmap/{f}", f"import/colmap/{f}",
                            read(f"import/colmap/{f}"), "cli", importer("colmap", "colmap"))
    cases += text_cases("import-bal", "import/bal/problem.txt", read("import/bal/problem.txt"),
                        "cli", importer("bal", "bal/problem.txt"), n_lines=6)
    if (imp / "pmexport").is_dir():
        cases += text_cases("import-pmexport", "import/pmexport/camcal.txt",
                            read("import/pmexport/camcal.txt"), "cli",
                            importer("pmexport", "pmexport/camcal.txt"), n_lines=8)
    if (imp / "dbat").is_dir():
        cases += text_cases("import-dbat/sxb.xml", "import/dbat/sxb.xml",
                            read("import/dbat/sxb.xml"), "cli", importer("dbat", "dbat/sxb.xml"),
                            n_lines=6, record_lines=False)
        for f in ("markpts.txt", "sxb-control.txt", "images.txt"):
            cases += text_cases(f"import-dbat/{f}", f"import/dbat/{f}", read(f"import/dbat/{f}"),
                                "cli", importer("dbat", "dbat/sxb.xml"))
    # the real commands on a representative subset
    cases += real_command_cases(base)
    ids = [c.id for c in cases]
    assert len(ids) == len(set(ids)), [i for i in ids if ids.count(i) > 1][:5]
    return cases


def real_command_cases(base: Path) -> list[Case]:
    """The commands themselves (not only `check`) on a subset of the
    mutations: calibrate, orient, intersect, montecarlo, mocap."""
    def read(rel):
        return (base / rel).read_bytes()
    out = []
    plan = [
        ("calibrate", "lab/lab.prj", ("calibrate", "-q", "{root}/lab/lab.prj", "--output", "{out}")),
        ("orient", "field/field.prj", ("orient", "-q", "{root}/field/field.prj", "--output", "{out}")),
        ("intersect", "jumps/jumps.prj",
         ("intersect", "-q", "{root}/jumps/jumps.prj", "--output", "{out}")),
    ]
    for cmd, prj, args in plan:
        folder = prj.split("/")[0]
        text = (base / prj).read_text(encoding="utf-8")
        tables = sorted(p.name for p in (base / folder).glob("*.csv") if f'"{p.name}"' in text)
        for t in tables:
            for c in csv_cases(f"{cmd}:{t}", f"{folder}/{t}", read(f"{folder}/{t}"), "cli", args):
                if c.id.split(":", 2)[2] in ("truncate@1", "header-only", "non-utf8", "binary",
                                              "first:non-utf8", "first:extra-field"):
                    out.append(c)
                elif c.expect == "error" and re.search(r"first:\w+='(nan|1e400|abc)'", c.id):
                    out.append(c)
        for c in toml_cases(f"{cmd}:{prj}", prj, read(prj), "cli", args):
            if c.id.endswith((":truncate@1", ":binary", ":unknown-section")) or \
                    "sigma_image=nan" in c.id or "length_unit=\"fuzz\"" in c.id:
                out.append(c)
    mc = ("montecarlo", "-q", "{root}/jumps/montecarlo.prj", "--runs", "2", "--workers", "1",
          "--output", "{out}")
    for c in toml_cases("montecarlo:montecarlo.prj", "jumps/montecarlo.prj",
                        read("jumps/montecarlo.prj"), "cli", mc):
        if any(s in c.id for s in ("orient=", "intersect=", "perturb=", "interior_covariance=",
                                   "truth=", "chunk=nan", ":binary")):
            out.append(c)
    mocap = ("mocap", "-q", "{root}/ski-ptz/ski-ptz.prj", "--output", "{out}")
    for rel, keep in (("ski-ptz/detections.csv", ("binary", "first:non-utf8", "first:camera=unknown",
                                                  "header-only")),
                      ("ski-ptz/camera_frames.csv", ("first:camera=unknown", "first:non-utf8",
                                                     "first:omega='nan'"))):
        for c in csv_cases(f"mocap:{rel}", rel, read(rel), "cli", mocap,
                           refs={"camera": "camera"}):
            if c.id.split(":", 2)[2] in keep:
                out.append(c)
    return out


# --------------------------------------------------------------------------
# running


@dataclass
class Outcome:
    rc: int
    out: str
    err: str


def argv(case: Case, root: Path, out: Path) -> list[str]:
    return [a.replace("{root}", str(root)).replace("{out}", str(out)) for a in case.args]


def run_cli(args: list[str]) -> Outcome:
    """``photogram ARGS`` in this process; stdout and stderr captured."""
    from photogram_cli.main import main
    o, e = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(o), contextlib.redirect_stderr(e):
        try:
            rc = main(args)
        except BaseException:            # noqa: BLE001  (SystemExit included)
            traceback.print_exc()
            rc = 1
    return Outcome(rc, o.getvalue(), e.getvalue())


def run_mocap_read(args: list[str]) -> Outcome:
    """The reading stage of ``photogram mocap``: the project, the cameras,
    the detections, the camera frames, the rotation differences and the
    truth table, with the command line's error handling."""
    from photogram.errors import PhotogramError
    o, e = io.StringIO(), io.StringIO()
    rc = 0
    with contextlib.redirect_stdout(o), contextlib.redirect_stderr(e):
        try:
            mocap_read(Path(args[0]))
        except PhotogramError as exc:
            print(exc.one_line(), file=sys.stderr)
            rc = 2
        except BaseException:            # noqa: BLE001
            traceback.print_exc()
            rc = 1
    return Outcome(rc, o.getvalue(), e.getvalue())


def mocap_read(prj: Path):
    from photogram.mocap.files import cameras_from_project, read_camera_frames, read_joints
    from photogram.mocap.motion.rotation_series import read_rotation_differences
    from photogram.mocap.pipeline import _observations
    from photogram.project import read_project
    project = read_project(prj)
    ms = project.mocap
    cameras = cameras_from_project(project)
    source, tracked, obs = _observations(project, cameras)
    first = int(getattr(source, "first_frame", 0))
    F = obs.shape[0]
    estimate = ms.rotation == "estimate"
    if ms.camera_frames is not None:
        cameras = read_camera_frames(ms.camera_frames, cameras, project, first, F,
                                     rotations=not estimate)
    if estimate and ms.rotation_differences is not None:
        read_rotation_differences(ms.rotation_differences, cameras.names, F, first_frame=first)
    if ms.truth is not None:
        read_joints(ms.truth, source.skeleton)


class Mirror:
    """One mirror of the staged tree ``base`` for many cases: every folder
    real, every file a hard link (a copy where links fail). A case replaces
    its one file, runs, and puts the link back; building and deleting a
    mirror per case (about 14 folders and their links) cost more than most
    cases' commands. If a command leaves anything in the tree (it should
    not: real commands write into ``--output``), the mirror is built anew."""

    def __init__(self, base: Path, root: Path):
        self.base, self.root = Path(base), Path(root)
        self._build()

    def _build(self) -> None:
        shutil.rmtree(self.root, ignore_errors=True)
        for folder, dirs, files in os.walk(self.base):
            rel = Path(folder).relative_to(self.base)
            (self.root / rel).mkdir(parents=True, exist_ok=True)
            for name in files:
                if rel == Path(".") and name == ".staged":
                    continue
                _link(Path(folder) / name, self.root / rel / name)
        self._listing = self._list()

    def _list(self) -> list:
        return [(folder, sorted(dirs), sorted(files)) for folder, dirs, files in os.walk(self.root)]

    def run(self, case: Case, out: Path) -> Outcome:
        """Run ``case`` with its mutated file in place; the tree is as
        before afterwards."""
        target = self.root / case.rel
        data = case.mutate((self.base / case.rel).read_bytes())
        target.unlink()
        target.write_bytes(data)
        try:
            args = argv(case, self.root, out)
            return run_cli(args) if case.runner == "cli" else run_mocap_read(args)
        finally:
            target.unlink(missing_ok=True)
            _link(self.base / case.rel, target)
            if self._list() != self._listing:
                self._build()


def _link(src: Path, dst: Path) -> None:
    try:
        os.link(src, dst)
    except OSError:
        shutil.copyfile(src, dst)


_MIRRORS: dict = {}


def mirror_of(base: Path) -> Mirror:
    """The mirror of ``base`` (built once per process, beside ``base``)."""
    base = Path(base)
    if base not in _MIRRORS:
        _MIRRORS[base] = Mirror(base, base.parent / f"{base.name}.mirror")
    return _MIRRORS[base]


def staged_base() -> Path:
    """The example projects staged once per process (:func:`stage`) in a
    temporary folder removed at exit: tests/test_fuzz_corpus.py and
    tests/test_fuzz_hypothesis.py share it (staging costs a measure, a
    calibrate and an orient). The folder is in /dev/shm where there is
    one: the commands' atomic writes still call fsync, which costs the
    cases nothing there (about 0.5 s of system CPU for the corpus on disk);
    durability is tested elsewhere, not by the fuzz cases."""
    if "base" not in _STAGED:
        import atexit
        import tempfile
        top = Path(tempfile.mkdtemp(prefix="fuzz-", dir=_memory_folder()))
        atexit.register(shutil.rmtree, top, ignore_errors=True)
        _STAGED["base"] = stage(top / "base")
    return _STAGED["base"]


def _memory_folder(path="/dev/shm", need=1 << 30):
    """``path`` if it is a writable folder with ``need`` bytes free (a
    container's /dev/shm is often 64 MB, too small for the staged projects
    and the cases' outputs), else None (the default temporary folder)."""
    try:
        st = os.statvfs(path)
    except OSError:
        return None
    free = st.f_bavail * st.f_frsize
    return path if free >= need and os.access(path, os.W_OK | os.X_OK) else None


_STAGED: dict = {}


def run_case(case: Case, base: Path, work: Path | None = None) -> tuple[Outcome, list[str]]:
    """Run ``case`` on the mirror of ``base`` (:class:`Mirror`), its outputs
    in ``work/out``; returns the outcome and the list of problems (empty: the
    case passed). Without ``work``, one folder beside the mirror serves every
    case of the process, its ``out`` removed before each case (a temporary
    folder per case cost as much as the cheapest cases' commands)."""
    m = mirror_of(base)
    if work is None:
        work = m.root.parent / f"{m.root.name}.work"
        work.mkdir(exist_ok=True)
        if (work / "out").exists():
            shutil.rmtree(work / "out")
    out = Path(work) / "out"
    res = m.run(case, out)
    return res, problems(case, res, m.root, out)


def problems(case: Case, res: Outcome, root: Path, out: Path) -> list[str]:
    text = res.out + res.err
    bad = []
    if "Traceback" in text:
        bad.append("traceback")
    if res.rc not in (0, 2):
        bad.append(f"exit code {res.rc}: {res.err.strip().splitlines()[-1:] }")
        return bad
    if res.rc == 0:
        if case.expect == "error":
            bad.append("accepted input that must be an error")
        bad += _nonfinite_outputs(out)
        return bad
    lines = res.err.strip("\n").split("\n")
    if len(lines) != 1 or not lines[0].strip():
        bad.append(f"{len(lines)} lines on stderr: {res.err!r}")
        return bad
    line = lines[0]
    named = None
    # the first prefix ending at ': ' or ':<n>: ' that is a path of the case
    for mm in re.finditer(r"(?::(\d+))?: ", line):
        path = line[:mm.start()]
        if path.startswith(str(root)):
            named = (path, mm.group(1))
            break
    if named is None:
        bad.append(f"the message names no input file of the case: {line}")
        return bad
    path, lineno = named
    mutated = str(root / case.rel)
    if Path(path) == Path(mutated) and case.line is not None:
        # a row-local mutation: the message names its line (an error about
        # something the file lacks, e.g. a missing frame, may name none)
        ok_lines = {str(case.line)} | ({str(case.line_alt)} if case.line_alt else set())
        also = f"line {case.line})" in line        # "duplicate ... (first on line N)"
        # a legal-looking value may be caught where it conflicts, on a
        # neighbouring line (a photo number that the next line must repeat)
        near = case.expect != "error" and lineno is not None and \
            abs(int(lineno) - case.line) <= 2
        if lineno not in ok_lines and not also and not near and \
                (lineno is not None or case.expect == "error"):
            bad.append(f"line {lineno}, expected {case.line}: {line}")
    return bad


def _nonfinite_outputs(out: Path) -> list[str]:
    """summary.json and CSV results written by a successful command must
    hold no NaN or infinity."""
    bad = []
    summary = out / "summary.json"
    if summary.is_file():
        text = summary.read_text()
        if re.search(r"\b(NaN|Infinity)\b", text):
            bad.append("summary.json holds NaN or Infinity")
        json.loads(text)
    return bad
