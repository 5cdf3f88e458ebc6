#!/usr/bin/env python3
"""Generate the simulated example projects, projects/lab, projects/field
and projects/jumps (with the rendered photographs of the lab frame).

All data are SIMULATED (nothing here was measured): the networks of the
ski-jump paper's laboratory calibration (Fig. 5) and field orientation
(Fig. 7) are built by :mod:`photogram.simulation.designs` with a fixed seed,
and written with :func:`photogram.project.write_project`. Running the script
again gives byte-identical files (``tests/test_designs.py`` checks that the
committed files are exactly what this script writes).

Usage (from the repository root)::

    .venv/bin/python projects/generate.py              # rewrites projects/lab, projects/field
    .venv/bin/python projects/generate.py --out /tmp/x # somewhere else

What is written (``<stem>_*.csv`` is write_project's naming)::

    lab/lab.prj                  free-network self-calibration (datum free + scale bar)
    lab/lab_stations.csv         9 stations, approximate values from a sketch
    lab/lab_points.csv           50 targets, approximate coordinates
    lab/lab_image_points.csv     typed image measurements, sigma 0.33 px (the check
                                 of the measurement; the input of lab-typed.prj)
    lab/lab-typed.prj            the same calibration from the typed measurements
    lab/images/*.jpg             rendered photographs of the true frame (9, 640 x 480,
                                 retro dots and ArUco markers; photogram.measure.scenes)
    lab/frame.toml               their target-field description for photogram measure
                                 (lab.prj reads what it writes, results-measure/)
    lab/truth/*.csv              the true cameras, stations, points, scale bar,
                                 noise-free image coordinates
    field/field.prj              alternative 1: orientation with 15 reference
                                 and 6 tie points; cameras from ../lab/results/cameras.toml
    field/field-alt2.prj         alternative 2: also the helmet at 10 exposures
                                 (shares field_stations.csv)
    field/field_*.csv, field/field-alt2_*.csv
    field/cameras-nominal.toml   the true (nominal) interior orientation, in the
                                 results/cameras.toml schema
    field/truth/*.csv            the true values (alternative 2 covers both)
    jumps/jumps.prj              the intersect step: a jump at 30 fps in the field
                                 stations; cameras from the lab, stations from the
                                 field results
    jumps/jumper_points.csv      exposure, station, point (P1..P4), x, y
    jumps/ski_lines.csv          exposure, station, line (L1, L2), x, y
    jumps/truth/*.csv            the true jumper points, skis and angles

Two things write_project cannot express are done on its output text: the
field projects take their cameras ``from`` the lab results (write_project
writes cameras in full), and field-alt2.prj uses the stations table of
field.prj. Every file gets a comment header saying that it is simulated.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from photogram.geometry import camera_model
from photogram.project import write_project
from photogram.project.atomic import atomic_write_bytes, atomic_write_text
from photogram.project.camera_schema import camera_to_toml
from photogram.project.tables import format_angle, format_table
from photogram.project.toml_writer import dumps
from photogram.simulation import designs
from photogram.simulation.designs import FIELD_SEED, LAB_SEED, field_design, lab_design

HERE = Path(__file__).resolve().parent
LAB_CAMERAS = "../lab/results/cameras.toml"
NOMINAL_CAMERAS = "cameras-nominal.toml"


def _simulated(what: str, seed: int) -> str:
    return (f"SIMULATED data: {what}.\n"
            f"Written by projects/generate.py (seed {seed}); do not edit by hand: "
            f"change the generator and run it again.")


#: What each written file holds (header comment).
DESCRIPTIONS = {
    "lab.prj": "laboratory self-calibration of the cameras K1, K2, K3 on a 3D test frame "
               "(ski-jump paper, Fig. 5)",
    "lab_stations.csv": "lab stations, approximate values from a sketch "
                        "(truth + ~3 cm, ~3 gon)",
    "lab_points.csv": "lab targets, approximate coordinates (truth + ~1 cm)",
    "lab_image_points.csv": "lab image measurements, typed (px; noise N(0, 0.33 px)); "
                            "lab.prj measures its own from images/, this table is the check",
    "lab-typed.prj": "laboratory self-calibration of K1, K2, K3 from the typed image "
                     "measurements (lab_image_points.csv)",
    "frame.toml": "target field of the rendered lab photographs (images/) for "
                  "photogram measure",
    "field.prj": "field orientation of K1, K2, K3 at a K120-like hill (ski-jump paper, "
                 "Fig. 7), alternative 1: reference and tie points",
    "field-alt2.prj": "field orientation of K1, K2, K3 at a K120-like hill (ski-jump "
                      "paper, Fig. 7), alternative 2: also the helmet at 10 exposures",
    "field_stations.csv": "field stations from a map (truth + ~1 dm, ~2 gon); "
                          "used by field.prj and field-alt2.prj",
    "field_points.csv": "surveyed reference points (truth + N(0, 0.12 dm)) and "
                        "tie points (unknown), dm",
    "field_image_points.csv": "field image measurements (px; noise N(0, 0.33 px))",
    "field-alt2_points.csv": "surveyed reference points (truth + N(0, 0.12 dm)), "
                             "tie points and helmet positions (unknown), dm",
    "field-alt2_image_points.csv": "field image measurements with the helmet "
                                   "(px; noise N(0, 0.33 px))",
}


def _comment(text: str) -> str:
    return "".join(f"# {line}\n" if line else "#\n" for line in text.splitlines())


def _strip_writer_header(text: str) -> str:
    """Drop write_project's "# written by photogram <version>" line, so that
    the files do not change with the version number."""
    lines = text.splitlines(keepends=True)
    while lines and lines[0].startswith("# written by photogram"):
        lines.pop(0)
    return "".join(lines)


def _written(project, stem: str) -> dict[str, str]:
    """The texts write_project produces for ``project`` as ``<stem>.prj``."""
    with tempfile.TemporaryDirectory() as tmp:
        write_project(project, Path(tmp) / f"{stem}.prj")
        return {p.name: p.read_text(encoding="utf-8") for p in sorted(Path(tmp).iterdir())}


def _blocks(text: str) -> list[str]:
    return text.split("\n\n")


def _cameras_from(prj: str, path: str, note: str) -> str:
    """Replace every inline ``[cameras.NAME]`` table by ``from = path``."""
    out, first = [], True
    for block in _blocks(prj):
        head = block.lstrip("\n").splitlines()[0] if block.strip() else ""
        if head.startswith("[cameras."):
            comment = _comment(note) if first else ""
            out.append(f"{comment}{head}\nfrom = \"{path}\"")
            first = False
        else:
            out.append(block)
    return "\n\n".join(out)


def _replace_table_file(prj: str, old: str, new: str) -> str:
    target = f'file = "{old}"'
    if target not in prj:
        raise RuntimeError(f"{old} not found in the written .prj")
    return prj.replace(target, f'file = "{new}"')


def _truth_tables(truth: dict, units: tuple[str, str]) -> dict[str, str]:
    """CSV texts of the true values (same columns as the input tables)."""
    angle_unit = units[1]
    st = truth["stations"]
    stations = {"station": st["names"], "camera": st["camera"]}
    for j, c in enumerate(("X0", "Y0", "Z0")):
        stations[c] = st["X0"][:, j]
    for j, c in enumerate(("omega", "phi", "kappa")):
        stations[c] = [format_angle(a, angle_unit) for a in st["angles"][:, j]]
    pts = truth["points"]
    points = {"id": pts["ids"], "kind": pts["kind"]}
    for j, c in enumerate("XYZ"):
        points[c] = pts["xyz"][:, j]
    names = camera_model(designs.MODEL).parameter_names
    cameras = {"camera": list(truth["cameras"])}
    for p in names:
        cameras[p] = [float(truth["cameras"][c][p]) for c in truth["cameras"]]
    xy = np.round(truth["xy_true"], 6)
    image = {"station": [st["names"][i] for i in truth["station"]],
             "point": [pts["ids"][i] for i in truth["point"]],
             "x": xy[:, 0], "y": xy[:, 1]}
    length, angle = units
    tables = {
        "cameras.csv": (cameras, "true interior orientation (px; brown model, "
                                 "docs/camera-models.md)"),
        "stations.csv": (stations, f"true stations ({length}; {angle}, world_to_camera "
                                   f"omega-phi-kappa)"),
        "points.csv": (points, f"true object points ({length})"),
        "image_points.csv": (image, "noise-free image coordinates (px); the measurements "
                                    "are these plus N(0, 0.33 px), rounded to 0.01 px"),
    }
    if truth["distances"]:
        d = truth["distances"]
        tables["distances.csv"] = (
            {"from": [r["from"] for r in d], "to": [r["to"] for r in d],
             "true": [r["true"] for r in d], "value": [r["value"] for r in d],
             "sigma": [r["sigma"] for r in d]},
            f"scale bar: true length and the calibrated value given in the project ({length})")
    return {name: format_table(cols, comment=_simulated(what, truth["seed"]))
            for name, (cols, what) in tables.items()}


def _truth_with_rows(project, truth) -> dict:
    truth = dict(truth)
    truth["points"] = dict(truth["points"], kind=[str(k) for k in project.points.kind])
    truth["station"] = project.image_points.station
    truth["point"] = project.image_points.point
    return truth


def _with_header(text: str, header: str) -> str:
    return _comment(header) + _strip_writer_header(text)


#: the lab's measured observations: photogram measure frame.toml writes them
LAB_MEASURED = "results-measure/image_points.csv"
LAB_JPEG_QUALITY = 92


def _jpeg_with_comment(image: np.ndarray, comment: str) -> bytes:
    """JPEG bytes (quality LAB_JPEG_QUALITY) with a COM segment right after
    the start-of-image marker, so that the file itself says it is simulated."""
    import cv2
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, LAB_JPEG_QUALITY])
    if not ok:  # pragma: no cover - encoding a valid array does not fail
        raise RuntimeError("JPEG encoding failed")
    data = buf.tobytes()
    text = comment.encode("ascii")
    return data[:2] + b"\xff\xfe" + (len(text) + 2).to_bytes(2, "big") + text + data[2:]


def lab_images(truth_folder: Path) -> dict[str, bytes | str]:
    """The rendered photographs of the lab frame (images/*.jpg) and their
    target-field description (frame.toml), from the truth tables the
    generator writes (photogram.measure.scenes: photogram's brown model,
    retro dots of 16 mm on black plates, ArUco DICT_4X4_50 markers of 70 mm
    on nine points spread over the plate and the post tops; 640 x 480, blur
    0.7 px, noise 2, JPEG 92). The description gives the project's
    approximate coordinates (lab_points.csv), never the truth."""
    from photogram.measure.scenes import (_rows, choose_markers, field_description, read_truth,
                                          render_project)
    truth = read_truth(truth_folder)
    markers = choose_markers(truth["points"])
    note = _simulated("photograph of the lab frame rendered from truth/ (K1, K2, K3 at the true "
                      "stations; photogram.measure.scenes)", LAB_SEED).replace("\n", " ")
    files: dict[str, bytes | str] = {}
    for name, img in render_project(truth, markers, seed=LAB_SEED).items():
        files[f"images/{name}.jpg"] = _jpeg_with_comment(img, note)
    folder = Path(truth_folder).parent
    approx = {r["id"]: np.array([float(r["X"]), float(r["Y"]), float(r["Z"])])
              for r in _rows(folder / "lab_points.csv")}
    text = field_description(markers, approx, points_file="lab_points.csv", images="images")
    header = _simulated(DESCRIPTIONS["frame.toml"], LAB_SEED) + (
        "\nRun: photogram measure projects/lab/frame.toml  (writes results-measure/, whose "
        "image_points.csv\nlab.prj calibrates from). See README.md.")
    files["frame.toml"] = _comment(header) + text
    return files


def lab_files() -> dict[str, str]:
    project, truth = lab_design(LAB_SEED)
    files = {}
    for name, text in _written(project, "lab").items():
        if name.endswith(".prj"):
            typed = _with_header(text.replace('folder = "results"', 'folder = "results-typed"'),
                                 _simulated(DESCRIPTIONS["lab-typed.prj"], LAB_SEED)
                                 + "\nRun: photogram calibrate projects/lab/lab-typed.prj  "
                                   "(writes results-typed/). See README.md.")
            files["lab-typed.prj"] = typed
            text = _replace_observations(text, "lab_image_points.csv", LAB_MEASURED)
            header = _simulated(DESCRIPTIONS[name], LAB_SEED) + (
                "\nThe image points are measured from the rendered photographs images/:\n"
                "run photogram measure projects/lab/frame.toml  (writes results-measure/),\n"
                "then photogram calibrate projects/lab/lab.prj  (writes results/, whose "
                "cameras.toml\nthe field projects use). The typed lab_image_points.csv is "
                "the check (lab-typed.prj). See README.md.")
        else:
            header = _simulated(DESCRIPTIONS[name], LAB_SEED)
        files[name] = _with_header(text, header)
    truth = _truth_with_rows(project, truth)
    for name, text in _truth_tables(truth, ("m", "gon")).items():
        files[f"truth/{name}"] = text
    return files


def _replace_observations(prj: str, old: str, new: str) -> str:
    target = f'points = "{old}"'
    if prj.count(target) != 1:
        raise RuntimeError(f"{old} not found once in the written .prj")
    return prj.replace(target, f'points = "{new}"   # written by photogram measure frame.toml')


def field_files() -> dict[str, str]:
    note = (f"interior orientation from the lab calibration, all parameters fixed.\n"
            f"It exists after `photogram calibrate ../lab/lab.prj`; to use the true "
            f"(nominal)\nvalues instead, write from = \"{NOMINAL_CAMERAS}\".")
    files = {}
    p1, t1 = field_design(FIELD_SEED, alternative=1)
    p2, t2 = field_design(FIELD_SEED, alternative=2)
    w1, w2 = _written(p1, "field"), _written(p2, "field-alt2")
    if w1["field_stations.csv"] != w2["field-alt2_stations.csv"]:
        raise RuntimeError("the two field alternatives differ in their stations")
    for name, text in w1.items():
        header = _simulated(DESCRIPTIONS[name], FIELD_SEED)
        if name.endswith(".prj"):
            header += ("\nRun: photogram orient projects/field/field.prj  (after the lab "
                       "calibration). See README.md.")
            text = _cameras_from(text, LAB_CAMERAS, note)
        files[name] = _with_header(text, header)
    for name, text in w2.items():
        if name == "field-alt2_stations.csv":
            continue
        header = _simulated(DESCRIPTIONS[name], FIELD_SEED)
        if name.endswith(".prj"):
            header += ("\nRun: photogram orient projects/field/field-alt2.prj  (after the lab "
                       "calibration). See README.md.")
            text = _cameras_from(text, LAB_CAMERAS, note)
            text = _replace_table_file(text, "field-alt2_stations.csv", "field_stations.csv")
        files[name] = _with_header(text, header)
    cams = {n: camera_to_toml(c) for n, c in p1.cameras.items()}
    files[NOMINAL_CAMERAS] = dumps(
        {"project": {"name": "lab-truth", "length_unit": "m", "angle_unit": "gon",
                     "image_unit": "px"},
         "cameras": cams},
        header=_simulated("the true interior orientation of the simulation, in the "
                          "results/cameras.toml schema", FIELD_SEED)
        + "\nUse it with [cameras.K1] from = \"cameras-nominal.toml\" before the lab "
          "calibration has run.")
    truth = _truth_with_rows(p2, t2)
    for name, text in _truth_tables(truth, ("dm", "gon")).items():
        files[f"truth/{name}"] = text
    return files


JUMPS_PRJ = """[project]
name = "jumps"
length_unit = "dm"
angle_unit = "gon"
image_unit = "px"
rotation = "omega-phi-kappa"
rotation_direction = "world_to_camera"

# interior orientation from the lab calibration, exterior from the field
# orientation (run photogram calibrate and photogram orient first)
[cameras.K1]
from = "../lab/results/cameras.toml"

[cameras.K2]
from = "../lab/results/cameras.toml"

[cameras.K3]
from = "../lab/results/cameras.toml"

[stations]
file = "../field/results/stations.csv"

# jumper points P1 helmet, P2 hip, P3 right and P4 left binding, and points
# measured along the right (L1) and left (L2) ski, per exposure (30 fps)
[observations]
points = "jumper_points.csv"
lines = "ski_lines.csv"

[adjustment]
sigma_image = 0.33

[intersect]
fps = 30
points = ["P1", "P2", "P3", "P4"]
skis = ["L1", "L2"]
ski_length = 2.63                     # m
binding_fraction = 0.43               # binding from the ski tail
orientation = ["../field/results"]    # joint covariance of lab interior + field exterior
swap_skis = false

[output]
folder = "results"
"""


def jumps_files() -> dict[str, str]:
    """The simulated jump: ~14 m of early flight at 30 fps in the field
    stations (photogram.simulation.jump)."""
    from photogram.simulation.jump import JUMP_SEED, jump_project
    project, truth = jump_project(noise=True)
    pts, lines = truth["points_table"], truth["lines_table"]
    header = _simulated("a ski jump (24 exposures at 30 fps) seen by the field stations; "
                        "jumper points and ski lines with noise N(0, 0.33 px)", JUMP_SEED)
    files = {"jumps.prj": _comment(header + "\nRun: photogram intersect projects/jumps/jumps.prj "
                                            "(after calibrate and orient). See README.md.")
             + JUMPS_PRJ}
    rows = ["exposure,station,point,x,y"] + [
        f"{e},{s},{p},{x:.2f},{y:.2f}" for e, s, p, (x, y) in
        zip(pts["exposure"], pts["station"], pts["point"], pts["xy"])]
    files["jumper_points.csv"] = _comment(header) + "\n".join(rows) + "\n"
    rows = ["exposure,station,line,x,y"] + [
        f"{e},{s},{l},{x:.2f},{y:.2f}" for e, s, l, (x, y) in
        zip(lines["exposure"], lines["station"], lines["line"], lines["xy"])]
    files["ski_lines.csv"] = _comment(header) + "\n".join(rows) + "\n"
    th = _comment(_simulated("the TRUE jumper points (dm) the jump was simulated from", JUMP_SEED))
    rows = ["exposure,point,X,Y,Z"]
    for e in range(len(truth["times"])):
        for k, name in enumerate(("P1", "P2", "P3", "P4")):
            X = truth["P"][e, k]
            rows.append(f"{e + 1:03d},{name},{X[0]:.6f},{X[1]:.6f},{X[2]:.6f}")
    files["truth/jumper_points.csv"] = th + "\n".join(rows) + "\n"
    th = _comment(_simulated("the TRUE skis (dm): tail and tip of L1 (right) and L2 (left), "
                             "and the true angles (gon) of the construction", JUMP_SEED))
    rows = ["exposure,line,X_tail,Y_tail,Z_tail,X_tip,Y_tip,Z_tip"]
    for e in range(len(truth["times"])):
        for j, name in enumerate(("L1", "L2")):
            a, b = truth["ski_tail"][e, j], truth["ski_tip"][e, j]
            rows.append(f"{e + 1:03d},{name}," + ",".join(f"{v:.6f}" for v in (*a, *b)))
    files["truth/skis.csv"] = th + "\n".join(rows) + "\n"
    g = 200.0 / np.pi
    rows = ["exposure,alpha,beta,delta_phi"] + [
        f"{e + 1:03d},{truth['legs'][e] * g:.8f},{truth['trunk'][e] * g:.8f},"
        f"{truth['v_angle'][e] * g:.8f}" for e in range(len(truth["times"]))]
    files["truth/angles.csv"] = th + "\n".join(rows) + "\n"
    files.update(_coach_files(truth))
    return files


def _coach_files(truth) -> dict[str, str]:
    """The landing slope as a profile (distance = world X, height = world Z
    of the surface, dm), the true height of O above it per exposure, and
    jumps-coach.prj: jumps.prj with the profile and the coach's units."""
    from photogram.simulation.jump import JUMP_SEED
    X = np.arange(300.0, 801.0, 50.0)
    rows = ["distance,height"] + [f"{x:.1f},{z:.6f}" for x, z in
                                  zip(X, designs.slope_height(X))]
    files = {"landing_profile.csv": _comment(_simulated(
        "the landing slope of the simulated hill along the jump axis (world X, dm): "
        "height = world Z of the surface (dm)", JUMP_SEED)) + "\n".join(rows) + "\n"}
    O = 0.5 * (truth["P"][:, 2] + truth["P"][:, 3])
    H = O[:, 2] - designs.slope_height(O[:, 0])
    rows = ["exposure,H"] + [f"{e + 1:03d},{h:.6f}" for e, h in enumerate(H)]
    files["truth/heights.csv"] = _comment(_simulated(
        "the TRUE height (dm) of O, the midpoint of the bindings, above the landing slope "
        "(vertical)", JUMP_SEED)) + "\n".join(rows) + "\n"
    prj = JUMPS_PRJ.replace('name = "jumps"', 'name = "jumps-coach"').replace(
        'swap_skis = false\n', 'swap_skis = false\n'
        'landing_profile = "landing_profile.csv"   # height of O above the slope: H\n').replace(
        'folder = "results"\n', 'folder = "results-coach"\n\n'
        '# the stick model in deg, m and km/h (report, figures, coach.csv)\n'
        '[report]\nunits = "coach"\n')
    files["jumps-coach.prj"] = _comment(_simulated(
        "the jumps project for a coach: deg, m, km/h and the height above the landing "
        "slope", JUMP_SEED) + "\nRun: photogram intersect projects/jumps/jumps-coach.prj "
        "(after calibrate and orient). See README.md.") + prj
    return files


def generate(out: Path = HERE) -> list[Path]:
    """Write the projects below ``out`` (folders lab/, field/ and jumps/);
    returns the files written."""
    out = Path(out)
    written = []
    for folder, files in (("lab", lab_files()), ("field", field_files()),
                          ("jumps", jumps_files()), ("lab", None)):
        if files is None:                 # the photographs, rendered from the truth just written
            files = lab_images(out / "lab" / "truth")
        for name, text in files.items():
            path = out / folder / name
            path.parent.mkdir(parents=True, exist_ok=True)
            if isinstance(text, bytes):
                atomic_write_bytes(path, text)
            else:
                atomic_write_text(path, text)
            path.chmod(0o644)
            written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE,
                        help="folder to write lab/ and field/ into (default: %(default)s)")
    args = parser.parse_args(argv)
    for path in generate(args.out):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
