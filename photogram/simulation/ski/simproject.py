"""Write a simulated skiing session (:mod:`photogram.simulation.ski.simulate`) as a
motion-capture project folder, byte for byte reproducibly.

Files: ``<name>.prj`` (cameras inline, opencv model, nominal principal
distance of the first frame), ``stations.csv`` (one per camera: position
and the angles of the first frame), ``camera_frames.csv`` (omega, phi,
kappa in degrees and fx, fy per camera and frame: the known rotations and
zoom), ``detections.csv`` (frame, camera, joint, x, y, confidence; 0.01 px,
missing detections left out), ``truth/joints3d.csv`` (the true joints),
``truth/outliers.csv`` (which detections are outliers or swapped).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photogram.geometry import matrix_to_opk
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.files import write_joints
from photogram.project.atomic import atomic_write_text
from photogram.simulation.ski.simulate import SkiSimulation

__all__ = ["write_simulated_project", "write_estimate_project"]


def _csv(header, rows, comment):
    lines = [f"# {c}" for c in comment] + [",".join(header)]
    lines += [",".join(r) for r in rows]
    return "\n".join(lines) + "\n"


def _f(x, d):
    return f"{x:.{d}f}"


def camera_sections(cams) -> list[str]:
    """The ``[cameras.NAME]`` sections (opencv model, frame 0's interior
    orientation) of a simulated project file, as lines."""
    lines = []
    for c, cam in enumerate(cams.names):
        io = cams.io[c][0]
        lines += [f"[cameras.{cam}]", 'model = "opencv"',
                  f"image_size = [{int(cams.image_size[c, 0])}, {int(cams.image_size[c, 1])}]",
                  f"fx = {_f(io[0], 2)}", f"fy = {_f(io[1], 2)}", f"cx = {_f(io[2], 2)}",
                  f"cy = {_f(io[3], 2)}", f"k1 = {io[4]:g}", ""]
    return lines


def write_simulated_project(sim: SkiSimulation, folder: Path, name: str = "ski-ptz",
                            command: str = "projects/ski-ptz/generate.py") -> list[Path]:
    folder = Path(folder)
    (folder / "truth").mkdir(parents=True, exist_ok=True)
    cams = sim.cameras
    F, C, J, _ = sim.observations.shape
    seed = sim.info["seed"]
    head = [f"SIMULATED data (photogram.simulation.ski.simulate, seed {seed}): not measured.",
            f"Written by {command}; do not edit by hand: change the generator and run it "
            f"again."]
    angles = np.degrees(matrix_to_opk(cams.R.reshape(-1, 3, 3))).reshape(F, C, 3)
    written = []
    prj = ["# " + head[0], "# " + head[1],
           f"# {sim.info['runs']} giant-slalom run(s) of three turns, {F} frames at "
           f"{sim.fps:g} fps, {C} pan-tilt-zoom cameras with known rotations per frame.",
           f"# Run: photogram mocap projects/{name}/{name}.prj  (see README.md)", "",
           "[project]", f'name = "{name}"', 'length_unit = "m"', 'angle_unit = "deg"',
           'image_unit = "px"', ""]
    prj += camera_sections(cams)
    prj += ["[stations]", 'file = "stations.csv"', "",
            "[mocap]", f"fps = {sim.fps:g}", 'skeleton = "ski24"',
            'camera_frames = "camera_frames.csv"   # rotations and zoom per frame (known)',
            'truth = "truth/joints3d.csv"',
            f"up = [{', '.join(_f(v, 6) for v in sim.slope_normal)}]   # slope normal "
            f"(lean angle)"]
    if sim.breaks:
        prj.append(f"runs = [{', '.join(str(b) for b in sim.breaks)}]   # first frames of "
                   f"runs 2, 3, ...")
    prj += ["", "[mocap.source]", 'kind = "csv"', 'path = "detections.csv"',
            'skeleton = "ski24"', "", "[output]", 'folder = "results"', ""]
    from photogram.project.safe_names import safe_name
    written.append(atomic_write_text(folder / f"{safe_name(name, 'ski')}.prj", "\n".join(prj)))
    rows = [[cam, cam] + [_f(v, 4) for v in cams.X0[c]] + [_f(v, 7) for v in angles[0, c]]
            for c, cam in enumerate(cams.names)]
    written.append(atomic_write_text(folder / "stations.csv", _csv(
        ["station", "camera", "X0", "Y0", "Z0", "omega", "phi", "kappa"], rows,
        head + ["one station per camera: projection centre (m), angles of frame 0 (deg)"])))
    rows = [[str(f), cam] + [_f(v, 7) for v in angles[f, c]]
            + [_f(cams.io[c][f, 0], 3), _f(cams.io[c][f, 1], 3)]
            for f in range(F) for c, cam in enumerate(cams.names)]
    written.append(atomic_write_text(folder / "camera_frames.csv", _csv(
        ["frame", "camera", "omega", "phi", "kappa", "fx", "fy"], rows,
        head + ["known rotations (deg, world to camera) and zoom (px) per camera and frame"])))
    obs = sim.observations
    f_idx, c_idx, j_idx = np.nonzero(np.isfinite(obs[..., 0]))
    o = obs[f_idx, c_idx, j_idx]
    names, joints = np.array(cams.names), np.array(SKI24.joints)
    rows = [[str(f), names[c], joints[j], _f(x, 2), _f(y, 2), _f(p, 3)]
            for f, c, j, (x, y, p) in zip(f_idx, c_idx, j_idx, o)]
    written.append(atomic_write_text(folder / "detections.csv", _csv(
        ["frame", "camera", "joint", "x", "y", "confidence"], rows,
        head + ["2D detections (px) with noise, 5 % outliers, left/right swaps; "
                "truth/outliers.csv says which"])))
    written.append(write_joints(folder / "truth" / "joints3d.csv", np.arange(F),
                                np.arange(F) / sim.fps, sim.joints, SKI24,
                                comment="\n".join(head + ["true joints (m, Z up)"])))
    f_o, c_o, j_o = np.nonzero(sim.outlier)
    rows = [[str(f), names[c], joints[j], "outlier"] for f, c, j in zip(f_o, c_o, j_o)]
    f_s, c_s = np.nonzero(sim.swapped)
    rows += [[str(f), names[c], "", "swapped"] for f, c in zip(f_s, c_s)]
    rows.sort(key=lambda r: (int(r[0]), r[1], r[2]))
    written.append(atomic_write_text(folder / "truth" / "outliers.csv", _csv(
        ["frame", "camera", "joint", "kind"], rows, head)))
    return written


def write_estimate_project(sim: SkiSimulation, folder: Path, name: str = "ski-ptz",
                           command: str = "projects/ski-ptz/generate.py") -> Path:
    """``<name>-estimate.prj``: the project of :func:`write_simulated_project`
    with the rotations unknown (``rotation = "estimate"``): the zoom from
    ``camera_frames.csv`` (its angles are not read), the rotation
    differences from ``rotation_differences.csv`` (measured on rendered
    images), and the known rotations as ``truth_rotations``."""
    from photogram.project.safe_names import safe_name
    stem = safe_name(name, "ski")
    text = (Path(folder) / f"{stem}.prj").read_text(encoding="utf-8")
    text = text.replace(f"# Run: photogram mocap projects/{name}/{name}.prj",
                        f"# Rotations UNKNOWN (estimated). Run: photogram mocap "
                        f"projects/{name}/{name}-estimate.prj")
    text = text.replace(
        'camera_frames = "camera_frames.csv"   # rotations and zoom per frame (known)',
        'rotation = "estimate"                 # rotations unknown: estimated with the poses\n'
        'camera_frames = "camera_frames.csv"   # the zoom per frame (its angles are not read)\n'
        'rotation_differences = "rotation_differences.csv"   # measured on rendered images\n'
        'truth_rotations = "camera_frames.csv" # the true rotations, for the comparison')
    text = text.replace('folder = "results"', 'folder = "results-estimate"')
    return atomic_write_text(Path(folder) / f"{stem}-estimate.prj", text)
