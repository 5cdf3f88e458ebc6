"""A simulated ski jump seen by the three cameras of the field design.

About 20 m of early flight at 30 fps (24 exposures, hill coordinates in dm,
see :mod:`photogram.simulation.designs`): the binding midpoint O flies 2.5-4.5
m above the 35 degree landing slope at ~25 m/s; the skis open in a V, the
jumper leans over them. Jumper points: P1 helmet, P2 hip, P3 right and P4
left binding; ski lines L1 (right) and L2 (left), each measured as points
along the ski in every image. Noise N(0, 0.33 px) on every image coordinate.

Everything is a pure function of its seed (no file I/O here).
"""

from __future__ import annotations

import numpy as np

from photogram.geometry import camera_model
from photogram.simulation.designs import (
    FIELD_SEED, field_design, slope_height, true_cameras)

JUMP_SEED = 20250103
FPS = 30.0
N_EXPOSURES = 24
SKI_LENGTH = 26.3            # dm (2.63 m)
BINDING_FRACTION = 0.43      # binding position from the ski tail
SIGMA_IMAGE = 0.33
POINTS_PER_SKI = 15
JUMPER_POINTS = ("P1", "P2", "P3", "P4")
SKI_LINES = ("L1", "L2")


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _rotate(v, axis, angle):
    """Rodrigues rotation of vectors v (n,3) about unit axes (n,3)."""
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    return v * c + np.cross(axis, v) * s + axis * np.sum(axis * v, -1, keepdims=True) * (1 - c)


def jump_truth(n_exposures=N_EXPOSURES, fps=FPS):
    """True jumper points, ski directions and ski segments per exposure.

    Returns a dict with ``times`` (n,), ``P`` (n,4,3), ``d1``, ``d2`` (n,3)
    unit ski directions (tail to tip), ``ski_tail``/``ski_tip`` (n,2,3), and
    the angles used to build them (radians): attack (skis above the flight
    path), v_angle (between the skis), legs and trunk (above the ski axis).
    """
    t = np.arange(n_exposures) / fps
    s = t / t[-1] if n_exposures > 1 else t
    x = 425.0 + 140.0 * s                                    # ~18 m/s along X over 14 m
    h = 25.0 + 20.0 * np.sin(np.pi * (0.3 + 0.6 * s))        # height above slope
    O = np.stack([x, -5.0 + 6.0 * s, slope_height(x) + h], axis=1)
    vel = np.gradient(O, t, axis=0) if n_exposures > 1 else np.array([[250.0, 0, -175.0]])
    flight = _unit(vel)
    side = _unit(np.cross([0.0, 0.0, 1.0], flight))           # to the jumper's left
    up = np.cross(flight, side)
    attack = np.radians(28.0 + 6.0 * s)                      # skis above the path
    v_angle = np.radians(26.0 + 8.0 * s)
    legs = np.radians(14.0 - 4.0 * s)
    trunk = np.radians(22.0 + 6.0 * s)
    axis_x = _rotate(flight, side, -attack)                  # pitch the ski axis up
    axis_z = _unit(np.cross(axis_x, side))
    if np.any(axis_z[:, 2] < 0):
        axis_z = -axis_z
    d1 = _rotate(axis_x, axis_z, -v_angle / 2)               # right ski
    d2 = _rotate(axis_x, axis_z, v_angle / 2)                # left ski
    right = -_unit(np.cross(axis_z, axis_x))
    P3 = O + 1.2 * right
    P4 = O - 1.2 * right
    leg_dir = _unit(np.cos(legs)[:, None] * axis_x + np.sin(legs)[:, None] * axis_z)
    P2 = O + 9.0 * leg_dir
    trunk_dir = _unit(np.cos(trunk)[:, None] * axis_x + np.sin(trunk)[:, None] * axis_z)
    P1 = P2 + 7.5 * trunk_dir
    P = np.stack([P1, P2, P3, P4], axis=1)
    bindings = np.stack([P3, P4], axis=1)
    dirs = np.stack([d1, d2], axis=1)
    tail = bindings - BINDING_FRACTION * SKI_LENGTH * dirs
    tip = tail + SKI_LENGTH * dirs
    return {"times": t, "fps": fps, "P": P, "d1": d1, "d2": d2, "O": O,
            "ski_tail": tail, "ski_tip": tip, "attack": attack, "v_angle": v_angle,
            "legs": legs, "trunk": trunk, "up": up}


def jump_observations(seed=JUMP_SEED, n_exposures=N_EXPOSURES, fps=FPS, sigma=SIGMA_IMAGE,
                      field_seed=FIELD_SEED):
    """Image observations of the simulated jump in the field stations.

    Returns ``(truth, points, lines, stations)``: ``points`` a dict of columns
    exposure, station, point, x, y (true and noisy); ``lines`` the same with
    ``line`` for points sampled along each projected ski; ``stations`` the
    field truth (names, cameras, X0, angles).
    """
    rng = np.random.default_rng([seed, 1])
    truth = jump_truth(n_exposures, fps)
    _, field = field_design(field_seed)
    st = field["stations"]
    cams = true_cameras()
    model = camera_model("brown")
    n_s = len(st["names"])
    exp_ids = np.array([f"{e + 1:03d}" for e in range(n_exposures)])

    # jumper points: every exposure x station x point
    e, s, p = np.meshgrid(np.arange(n_exposures), np.arange(n_s), np.arange(4), indexing="ij")
    e, s, p = e.ravel(), s.ravel(), p.ravel()
    io = np.stack([cams[c] for c in st["camera"]])[s]
    xy = model.project(truth["P"][e, p], st["angles"][s], st["X0"][s], io)
    points = {"exposure": exp_ids[e], "station": np.array(st["names"])[s],
              "point": np.array(JUMPER_POINTS)[p], "xy_true": xy,
              "xy": xy + rng.normal(0, sigma, xy.shape)}

    # ski lines: points along each ski, spread over its visible length
    k = POINTS_PER_SKI
    e, s, l, j = np.meshgrid(np.arange(n_exposures), np.arange(n_s), np.arange(2), np.arange(k),
                             indexing="ij")
    e, s, l, j = e.ravel(), s.ravel(), l.ravel(), j.ravel()
    frac = 0.05 + 0.9 * (j + rng.uniform(-0.3, 0.3, len(j))) / (k - 1)
    X = truth["ski_tail"][e, l] + frac[:, None] * (truth["ski_tip"][e, l] - truth["ski_tail"][e, l])
    io = np.stack([cams[c] for c in st["camera"]])[s]
    xy = model.project(X, st["angles"][s], st["X0"][s], io)
    lines = {"exposure": exp_ids[e], "station": np.array(st["names"])[s],
             "line": np.array(SKI_LINES)[l], "xy_true": xy,
             "xy": xy + rng.normal(0, sigma, xy.shape), "X_true": X}
    return truth, points, lines, st


def jump_project(seed=JUMP_SEED, noise=True, n_exposures=N_EXPOSURES, fps=FPS):
    """The simulated jump as an in-memory Project with the TRUE orientation
    (field stations, nominal cameras), moving points ``P1@001`` ... and ski
    lines ``L1@001`` ...; ``noise=False`` gives exact image coordinates.

    Returns ``(project, truth)``.
    """
    from photogram.project.model import (
        AdjustmentSettings, ImageLines, ImagePoints, IntersectSettings, Points, Project,
        Stations, Units)
    from photogram.simulation.designs import CAMERAS, _camera
    truth, pts, lines, st = jump_observations(seed, n_exposures, fps)
    key = "xy" if noise else "xy_true"
    names = list(st["names"])
    s_index = {n: i for i, n in enumerate(names)}
    ids = [f"{p}@{e}" for p, e in zip(pts["point"], pts["exposure"])]
    uniq = list(dict.fromkeys(ids))
    p_index = {n: i for i, n in enumerate(uniq)}
    project = Project(
        name="jumps", units=Units(length="dm", angle="gon", image="px"),
        cameras={c: _camera(c, CAMERAS[c]) for c in CAMERAS},
        stations=Stations(names=names, camera=list(st["camera"]), position=st["X0"].copy(),
                          angles=st["angles"].copy(), position_sigma=np.full((3, 3), np.nan),
                          angle_sigma=np.full((3, 3), np.nan)),
        points=Points(ids=uniq, kind=np.full(len(uniq), "tie", dtype=object),
                      xyz=np.full((len(uniq), 3), np.nan), sigma=np.full((len(uniq), 3), np.nan),
                      record=np.zeros(len(uniq), dtype=int)),
        image_points=ImagePoints(station=np.array([s_index[s] for s in pts["station"]]),
                                 point=np.array([p_index[i] for i in ids]), xy=pts[key].copy(),
                                 sigma=np.full(len(ids), np.nan),
                                 record=np.arange(len(ids)) + 2),
        image_lines=ImageLines(station=np.array([s_index[s] for s in lines["station"]]),
                               line=np.array([f"{l}@{e}" for l, e in
                                              zip(lines["line"], lines["exposure"])], dtype=object),
                               xy=lines[key].copy(), sigma=np.full(len(lines["line"]), np.nan),
                               record=np.arange(len(lines["line"])) + 2),
        adjustment=AdjustmentSettings(sigma_image=SIGMA_IMAGE),
        intersect=IntersectSettings(fps=fps, ski_length=SKI_LENGTH / 10.0,
                                    binding_fraction=BINDING_FRACTION))
    truth["points_table"], truth["lines_table"], truth["stations"] = pts, lines, st
    return project, truth
