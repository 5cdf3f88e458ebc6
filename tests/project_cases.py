"""Malformed-project cases shared by the reader and CLI tests.

Each case copies tests/data/lab (or field) into a temporary folder, breaks
one thing, and says which file and line the error must name.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

DATA = Path(__file__).parent / "data"


@dataclass
class Case:
    name: str
    edit: Callable[[Path], None]          # gets the project folder
    file: str                              # expected file name in the message
    line: str | int | None                 # text on the expected line, or a number
    words: tuple[str, ...]                 # must appear in the message
    project: str = "lab"


def replace(path: Path, old: str, new: str, count: int = 1) -> None:
    text = path.read_text(encoding="utf-8")
    assert old in text, (old, path)
    path.write_text(text.replace(old, new, count), encoding="utf-8")


def append(path: Path, text: str) -> None:
    with open(path, "a", encoding="utf-8") as handle:
        handle.write(text)


def make_project(tmp_path: Path, name: str = "lab") -> Path:
    """A fresh copy of tests/data/<name>; returns its .prj."""
    folder = tmp_path / name
    shutil.copytree(DATA / name, folder)
    return folder / f"{name}.prj"


def expected_line(folder: Path, case: Case) -> int | None:
    """The line the error must name: a number, or the first (or, for a
    ``(text, k)`` pair, the k-th) line containing a text."""
    if case.line is None or isinstance(case.line, int):
        return case.line
    text, k = case.line if isinstance(case.line, tuple) else (case.line, 0)
    lines = (folder / case.file).read_text(encoding="utf-8", errors="replace").splitlines()
    hits = [i for i, line in enumerate(lines, 1) if text in line]
    assert hits, (text, case.file)
    return hits[k]


def set_cell(file: str, prefix: str, column: int, value: str):
    """Edit: set a cell of the first row starting with ``prefix``."""
    def edit(d: Path) -> None:
        lines = (d / file).read_text(encoding="utf-8").splitlines()
        i = next(i for i, line in enumerate(lines) if line.startswith(prefix))
        cells = lines[i].split(",")
        cells[column] = value
        lines[i] = ",".join(cells)
        (d / file).write_text("\n".join(lines) + "\n", encoding="utf-8")
    return edit


def _e(file, old, new):
    return lambda d: replace(d / file, old, new)


def _nonutf8_csv(d: Path) -> None:
    data = (d / "points.csv").read_bytes().replace(b"2,control", b"2,contr\xf4le")
    (d / "points.csv").write_bytes(data)


def _nonutf8_prj(d: Path) -> None:
    data = (d / "lab.prj").read_bytes().replace(b'name = "lab"', b'name = "l\xe4b"')
    (d / "lab.prj").write_bytes(data)


def _single_ray(d: Path) -> None:
    text = (d / "image_points.csv").read_text()
    kept = [ln for ln in text.splitlines() if not (",18," in ln and not ln.startswith("S2"))]
    (d / "image_points.csv").write_text("\n".join(kept) + "\n")


def _missing(file):
    return lambda d: (d / file).unlink()


def _empty(file, header_only):
    def edit(d):
        lines = (d / file).read_text().splitlines()
        keep = [ln for ln in lines if ln.startswith("#")]
        if header_only:
            keep += [next(ln for ln in lines if not ln.startswith("#"))]
        (d / file).write_text("\n".join(keep) + "\n")
    return edit


CASES = [
    Case("missing table", _missing("stations.csv"), "lab.prj", 'file = "stations.csv"',
         ("stations table", "not found")),
    Case("missing cameras file", _missing("lab_cameras.toml"), "field.prj",
         'from = "lab_cameras.toml"', ("not found",), project="field"),
    Case("toml syntax", _e("lab.prj", "max_iterations = 30", "max_iterations = = 30"),
         "lab.prj", "max_iterations", ("TOML syntax error",)),
    Case("toml unquoted string", _e("lab.prj", 'datum = "control"', "datum = control"),
         "lab.prj", "datum = control", ("TOML syntax error", "quotes")),
    Case("duplicate camera", lambda d: append(d / "lab.prj", '\n[cameras.K1]\nc = 1.0\n'),
         "lab.prj", ("[cameras.K1]", -1), ("TOML syntax error", "twice")),
    Case("unknown section", _e("lab.prj", "[output]", "[outputs]"), "lab.prj", "[outputs]",
         ("unknown section 'outputs'", "did you mean 'output'")),
    Case("unknown key", _e("lab.prj", "tolerance =", "tolerence ="), "lab.prj", "tolerence",
         ("unknown key 'tolerence' in [adjustment]", "did you mean 'tolerance'")),
    Case("wrong type", _e("lab.prj", "max_iterations = 30", 'max_iterations = "30"'),
         "lab.prj", "max_iterations", ("must be an integer", "string")),
    Case("wrong type bool", _e("lab.prj", "variance_components = false",
                               "variance_components = 0"),
         "lab.prj", "variance_components", ("true or false",)),
    Case("unknown length unit", _e("lab.prj", 'length_unit = "m"', 'length_unit = "meter"'),
         "lab.prj", "length_unit", ("unknown length_unit 'meter'", "m, dm, cm, mm")),
    Case("unknown angle unit", _e("lab.prj", 'angle_unit = "deg"', 'angle_unit = "grad"'),
         "lab.prj", "angle_unit", ("unknown angle_unit 'grad'",)),
    Case("unknown rotation direction", _e("lab.prj", '"world_to_camera"', '"world2camera"'),
         "lab.prj", "rotation_direction", ("unknown rotation_direction", "world_to_camera")),
    Case("unknown camera model", _e("lab.prj", 'model = "brown"', 'model = "browne"'),
         "lab.prj", "browne", ("unknown camera model 'browne'", "did you mean 'brown'")),
    Case("unknown parameter", _e("lab.prj", "P1 = 0.0", "p1 = 0.0"), "lab.prj", "p1 = 0.0",
         ("unknown parameter 'p1'", "did you mean 'P1'")),
    Case("unknown parameter key", _e("lab.prj", "K1 = { value = 0.0, free = true }",
                                     "K1 = { value = 0.0, fixed = true }"),
         "lab.prj", "fixed = true", ("unknown key 'fixed'",)),
    Case("missing camera constant", _e("lab.prj", "c  = { value = 1420.0, free = true }\n", ""),
         "lab.prj", "[cameras.K1]", ("camera K1 has no c",)),
    Case("sigma on fixed parameter", _e("lab.prj", "P1 = 0.0", "P1 = { value = 0.0, sigma = 1.0 }"),
         "lab.prj", "P1 =", ("has a sigma but is fixed",)),
    Case("nan in toml", _e("lab.prj", "sigma_image = 0.5", "sigma_image = nan"), "lab.prj",
         "sigma_image", ("finite",)),
    Case("negative sigma in toml", _e("lab.prj", "sigma_image = 0.5", "sigma_image = -0.5"),
         "lab.prj", "sigma_image", ("must be > 0",)),
    Case("image size", _e("lab.prj", "image_size = [1920, 1080]", "image_size = [1920]"),
         "lab.prj", "image_size = [1920]", ("array of 2 integers",)),
    Case("unknown camera of station", _e("stations.csv", "S3,K2", "S3,K3"), "stations.csv",
         "S3,K3", ("unknown camera 'K3'", "station S3")),
    Case("unknown station of observation", _e("image_points.csv", "S2,5,", "S5,5,"),
         "image_points.csv", "S5,5,", ("unknown station 'S5'",)),
    Case("unknown point of observation", _e("image_points.csv", "S2,17,", "S2,71,"),
         "image_points.csv", "S2,71,", ("unknown point '71'", "did you mean")),
    Case("duplicate point id", _e("points.csv", "C2,check", "C1,check"), "points.csv",
         "C1,check,1.7", ("duplicate point id 'C1'", "line 10")),
    Case("duplicate station id", _e("stations.csv", "S4,K2", "S1,K2"), "stations.csv",
         "S1,K2", ("duplicate station id 'S1'",)),
    Case("duplicate observation", lambda d: append(d / "image_points.csv", "S1,5,1.0,2.0,\n"),
         "image_points.csv", "S1,5,1.0,2.0", ("measured twice",)),
    Case("non-numeric cell", _e("points.csv", "2.000,0.000,1.500", "2.000,0.OOO,1.500"),
         "points.csv", "0.OOO", ("'0.OOO' in column 'Y' is not a number",)),
    Case("decimal comma", set_cell("image_points.csv", "S2,5,", 2, '"1016,5"'),
         "image_points.csv", "1016,5", ("not a number", "decimal separator")),
    Case("nan cell", _e("stations.csv", "-0.500,-4.000", "nan,-4.000"), "stations.csv",
         "nan,-4.000", ("'nan' in column 'X0'", "not a finite number")),
    Case("inf cell", set_cell("image_points.csv", "S2,5,", 2, "inf"), "image_points.csv",
         "S2,5,inf", ("'inf'", "not a finite number")),
    Case("empty required cell", set_cell("image_points.csv", "S2,5,", 2, ""), "image_points.csv",
         "S2,5,,", ("empty cell in column 'x'",)),
    Case("missing column", _e("stations.csv", "station,camera", "station,cam"), "stations.csv",
         "station,cam", ("no column 'camera'",)),
    Case("unknown column", _e("points.csv", "Z,sX,", "Z,sx,"), "points.csv",
         "id,kind", ("unknown column 'sx'", "did you mean 'sX'")),
    Case("misspelt required column", _e("points.csv", "id,kind,X", "id,type,X"),
         "points.csv", "id,type", ("has no column 'kind'", "required columns: id, kind")),
    Case("wrong field count", _e("points.csv", "5,control,1.000,0.300,0.750,",
                                 "5,control,1.000,0.300,0.750,0.001,"),
         "points.csv", "5,control", ("has 9 fields but the header has 8",)),
    Case("empty table", _empty("stations.csv", True), "stations.csv", "station,camera",
         ("has a header but no rows",)),
    Case("empty file", _empty("points.csv", False), "points.csv", 1, ("is empty",)),
    Case("tie point in one image", _single_ray, "image_points.csv", "S2,18,",
         ("point 18 is seen in 1 image (station S2)", "at least 2 rays",
          "measure it in another image or remove it")),
    Case("non-utf8 csv", _nonutf8_csv, "points.csv", "2,contr", ("not UTF-8", "0xF4")),
    Case("non-utf8 prj", _nonutf8_prj, "lab.prj", 'name = "l', ("not UTF-8",)),
    Case("unknown kind", _e("points.csv", "C2,check", "C2,chek"), "points.csv", "C2,chek",
         ("unknown point kind 'chek'", "did you mean 'check'")),
    Case("control without coordinates", _e("points.csv", "8,control,1.000,0.000,1.800",
                                           "8,control,,,"),
         "points.csv", "8,control", ("control point 8 has no coordinates",)),
    Case("partial coordinates", _e("points.csv", "8,control,1.000,0.000,1.800",
                                   "8,control,1.000,,1.800"),
         "points.csv", "8,control", ("only some of X, Y, Z",)),
    Case("zero observation sigma",
         lambda d: append(d / "image_points.csv", "S4,C1,10.0,20.0,0\n"),
         "image_points.csv", "S4,C1,10.0,20.0,0", ("sigma must be > 0",)),
    Case("constraint unknown point", _e("lab.prj", 'to = "2"', 'to = "22"'), "lab.prj",
         'to = "22"', ("unknown point '22'", "[[constraints.distance]] #1")),
    Case("constraint csv unknown point", _e("distances.csv", "T1,T4", "T1,T9"),
         "distances.csv", "T1,T9", ("unknown point 'T9'",), project="field"),
    Case("inner constraints unknown point", _e("field.prj", '"T4"]', '"T5"]'), "field.prj",
         "inner_constraints", ("inner_constraints names point T5",), project="field"),
    Case("from unknown camera name",
         _e("field.prj", 'from = "lab_cameras.toml"\n\n', 'from = "lab_cameras.toml"\nname = "K7"\n\n'),
         "field.prj", 'name = "K7"', ("camera K7 is not in lab_cameras.toml",), project="field"),
    Case("from unknown free parameter", _e("field.prj", 'free = ["c"]', 'free = ["f"]'),
         "field.prj", 'free = ["f"]', ("unknown parameter 'f'",), project="field"),
    Case("from image unit mismatch",
         lambda d: (replace(d / "field.prj", 'image_unit = "px"', 'image_unit = "mm"'),
                    replace(d / "lab_cameras.toml", "pixel_size = [0.0055, 0.0055]",
                            "pixel_size = [0.0055, 0.0056]")),
         "field.prj", 'from = "lab_cameras.toml"', ("is in px", "image_unit = mm",
                                                    "square pixel_size"), project="field"),
    Case("mm image unit needs pixel size",
         lambda d: (replace(d / "lab.prj", 'image_unit = "px"', 'image_unit = "mm"'),
                    replace(d / "lab.prj", "pixel_size = [0.0055, 0.0055]\n", ""),
                    replace(d / "lab.prj", 'points = "image_points.csv"',
                            'points = "image_points.csv"\nunit = "px"')),
         "lab.prj", 'unit = "px"', ("camera K1 has no pixel_size",)),
    Case("missing section", _e("lab.prj", '[stations]\nfile = "stations.csv"', ""), "lab.prj",
         None, ("missing section [stations]",)),
]
