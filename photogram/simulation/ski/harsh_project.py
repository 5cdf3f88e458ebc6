"""Write the harsh simulated session (:mod:`photogram.simulation.ski.harsh`)
as motion-capture project folders, byte for byte reproducibly. SIMULATED.

Files of the folder: ``<name>.prj`` (known rotations), ``<name>-estimate.prj``
(rotations estimated; ``rotation_differences.csv``), ``stations.csv``,
``camera_frames.csv``, ``detections.csv`` (with a ``person`` column: every
detected person of a camera frame, ids shuffled per frame),
``rotation_differences.csv``, ``truth/joints3d.csv``,
``truth/identity.csv`` (the athlete's person id per camera frame),
``truth/degradations.csv`` (outliers, swapped frames, frames whose athlete
is not detected); and a sub-folder ``two-cameras/`` with the same session
seen by two cameras (``<name>-2cam.prj``, its own stations, camera frames,
detections and identity; the truth joints of the parent folder).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from photogram.geometry import matrix_to_opk
from photogram.mocap.body.skeleton import SKI24
from photogram.mocap.files import write_joints
from photogram.mocap.motion.rotation_series import write_rotation_differences
from photogram.project.atomic import atomic_write_text
from photogram.simulation.ski.harsh import (HarshSimulation, simulated_rotation_differences,
                                            two_cameras)
from photogram.simulation.ski.simproject import _csv, _f, camera_sections

__all__ = ["write_harsh_project", "header"]


def header(sim: HarshSimulation, command: str) -> list[str]:
    return [f"SIMULATED data (photogram.simulation.ski.harsh, harsh setting, seed "
            f"{sim.settings.seed}): not measured.",
            f"Written by {command}; do not edit by hand: change the generator and run it "
            f"again."]


def _prj(sim, name, head, estimate=False, two=False, truth="truth/joints3d.csv"):
    cams = sim.cameras
    F = len(sim.joints)
    stem = f"{name}-2cam" if two else (f"{name}-estimate" if estimate else name)
    where = f"projects/{name}/two-cameras" if two else f"projects/{name}"
    lines = ["# " + head[0], "# " + head[1],
             f"# One giant-slalom run of five turns over a kicker, {F} frames at {sim.fps:g} "
             f"fps, {cams.n_cameras} pan-tilt-zoom cameras, a harsh detector, bystanders.",
             "# " + ("Rotations UNKNOWN (estimated). " if estimate else "")
             + f"Run: photogram mocap {where}/{stem}.prj  (see README.md)", "",
             "[project]", f'name = "{stem}"', 'length_unit = "m"', 'angle_unit = "deg"',
             'image_unit = "px"', ""]
    lines += camera_sections(cams)
    lines += ["[stations]", 'file = "stations.csv"', "",
              "[mocap]", f"fps = {sim.fps:g}", 'skeleton = "ski24"']
    if estimate:
        lines += ['rotation = "estimate"                 # rotations unknown: estimated',
                  'camera_frames = "camera_frames.csv"   # the zoom per frame (its angles '
                  'are not read)',
                  'rotation_differences = "rotation_differences.csv"   # simulated '
                  'measurements',
                  'truth_rotations = "camera_frames.csv" # the true rotations, for the '
                  'comparison']
    else:
        lines.append('camera_frames = "camera_frames.csv"   # rotations and zoom per frame '
                     '(known)')
    lines += [f'truth = "{truth}"',
              f"up = [{', '.join(_f(v, 6) for v in sim.slope_normal)}]   # nominal slope "
              f"normal (lean angle)", "",
              "[mocap.source]", 'kind = "csv"', 'path = "detections.csv"', 'skeleton = "ski24"',
              "", "[output]", f'folder = "{"results-estimate" if estimate else "results"}"', ""]
    return stem, "\n".join(lines)


def _camera_files(sim, folder, head):
    cams = sim.cameras
    F, C = sim.observations.shape[:2]
    angles = np.degrees(matrix_to_opk(cams.R.reshape(-1, 3, 3))).reshape(F, C, 3)
    rows = [[cam, cam] + [_f(v, 4) for v in cams.X0[c]] + [_f(v, 7) for v in angles[0, c]]
            for c, cam in enumerate(cams.names)]
    out = [atomic_write_text(folder / "stations.csv", _csv(
        ["station", "camera", "X0", "Y0", "Z0", "omega", "phi", "kappa"], rows,
        head + ["one station per camera: projection centre (m), angles of frame 0 (deg)"]))]
    rows = [[str(f), cam] + [_f(v, 7) for v in angles[f, c]]
            + [_f(cams.io[c][f, 0], 3), _f(cams.io[c][f, 1], 3)]
            for f in range(F) for c, cam in enumerate(cams.names)]
    out.append(atomic_write_text(folder / "camera_frames.csv", _csv(
        ["frame", "camera", "omega", "phi", "kappa", "fx", "fy"], rows,
        head + ["true rotations (deg, world to camera; mis-levelled bases, lag, jitter) and "
                "zoom (px) per camera and frame"])))
    return out


def _detections(sim, folder, head):
    names, joints = np.array(sim.cameras.names), np.array(SKI24.joints)
    P = sim.people                                        # (P, F, C, J, 3)
    pid = np.moveaxis(sim.person_id, -1, 0)               # (P, F, C)
    k, f, c, j = np.nonzero(np.nan_to_num(P[..., 2]) > 0)
    ids = pid[k, f, c]
    order = np.lexsort((j, ids, c, f))
    o = P[k, f, c, j][order]
    rows = [[str(ff), names[cc], joints[jj], _f(x, 1), _f(y, 1), _f(p, 2), str(ii)]
            for ff, cc, jj, ii, (x, y, p) in zip(f[order], c[order], j[order], ids[order], o)]
    out = [atomic_write_text(folder / "detections.csv", _csv(
        ["frame", "camera", "joint", "x", "y", "confidence", "person"], rows,
        head + ["2D detections (px, 0.1 px) of every person seen; person ids shuffled per camera "
                "frame; truth/identity.csv says which is the athlete"]))]
    (folder / "truth").mkdir(exist_ok=True)
    f, c = np.nonzero(sim.person_id[..., 0] >= 0)
    rows = [[str(ff), names[cc], str(sim.person_id[ff, cc, 0]),
             str(int(np.sum(sim.person_id[ff, cc] >= 0)))] for ff, cc in zip(f, c)]
    out.append(atomic_write_text(folder / "truth" / "identity.csv", _csv(
        ["frame", "camera", "athlete_person", "persons"], rows,
        head + ["the athlete's person id in detections.csv per camera frame (no row: the "
                "athlete is not detected)"])))
    return out


def _lagged_comment(st) -> list[str]:
    """Comment lines of the lagged rows (none without lags)."""
    if not st.dr_lags:
        return []
    lags = ", ".join(str(k) for k in st.dr_lags)
    return [f"lagged pairs frame t -> to_frame = t+k (k = {lags}; R(to_frame) = dR R(t)) "
            f"where the true turn is below {st.dr_lag_max_fraction:g} of the field of view:",
            f"{st.dr_noise_deg:g} deg noise / (1 - turn/fov), zoom scale error "
            f"+-{100 * st.dr_lag_scale:g} % of pan and tilt per camera, more failures near "
            f"the limit (photogram.simulation.ski.harsh_lagged)"]


def write_harsh_project(sim: HarshSimulation, folder: Path, name: str = "ski-ptz-harsh",
                        command: str = "projects/ski-ptz-harsh/generate.py") -> list[Path]:
    """Write the folder (module doc); returns the files written."""
    folder = Path(folder)
    (folder / "truth").mkdir(parents=True, exist_ok=True)
    head = header(sim, command)
    F = len(sim.joints)
    written = []
    for estimate in (False, True):
        stem, text = _prj(sim, name, head, estimate=estimate)
        written.append(atomic_write_text(folder / f"{stem}.prj", text))
    written += _camera_files(sim, folder, head)
    written += _detections(sim, folder, head)
    per = simulated_rotation_differences(sim, sim.settings, sim.settings.seed + 1000)
    written.append(write_rotation_differences(
        folder / "rotation_differences.csv", per, comment="\n".join(head + [
            "rotation differences frame t -> t+1 (rotation vector of dR, R(t+1) = dR R(t), "
            "deg): the truth with 0.03 deg noise,", "2 % failed pairs (ok 0), 1 % wrong "
            "pairs (0.5-3 deg off, ok 1)"] + _lagged_comment(sim.settings))))
    written.append(write_joints(folder / "truth" / "joints3d.csv", np.arange(F),
                                np.arange(F) / sim.fps, sim.joints, SKI24,
                                comment="\n".join(head + ["true joints of the athlete (m, Z up)"])))
    names, joints = np.array(sim.cameras.names), np.array(SKI24.joints)
    f_o, c_o, j_o = np.nonzero(sim.outlier)
    rows = [[str(f), names[c], joints[j], "outlier"] for f, c, j in zip(f_o, c_o, j_o)]
    rows += [[str(f), names[c], "", "swapped"] for f, c in zip(*np.nonzero(sim.swapped))]
    rows += [[str(f), names[c], "", "not detected"] for f, c in zip(*np.nonzero(sim.lost))]
    rows.sort(key=lambda r: (int(r[0]), r[1], r[2], r[3]))
    written.append(atomic_write_text(folder / "truth" / "degradations.csv", _csv(
        ["frame", "camera", "joint", "kind"], rows,
        head + ["the athlete's outliers, swapped camera frames and camera frames without "
                "the athlete's detection"])))
    two = two_cameras(sim)
    sub = folder / "two-cameras"
    (sub / "truth").mkdir(parents=True, exist_ok=True)
    stem, text = _prj(replace(two), name, head, two=True, truth="../truth/joints3d.csv")
    written.append(atomic_write_text(sub / f"{stem}.prj", text))
    written += _camera_files(two, sub, head)
    written += _detections(two, sub, head)
    return written
