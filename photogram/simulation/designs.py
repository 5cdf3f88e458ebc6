"""The two example networks of the ski-jump paper, simulated with known truth.

* :func:`lab_design`: the laboratory self-calibration of the three cameras
  K1, K2, K3 on a 3D test frame (the paper's Fig. 5);
* :func:`field_design`: the orientation of the same three cameras at a
  K120-like jumping hill (the paper's Fig. 7), alternative 1 (reference and
  tie points only) or alternative 2 (plus the helmet positions of one jump).

Both are pure functions of a seed: no file I/O (``projects/generate.py``
writes them). Each returns ``(project, truth)``: the
:class:`~photogram.project.model.Project` as a user would give it
(observations with noise, approximate values, a-priori sigmas) and a dict
with the true values it was simulated from.

Every simulated number is rounded to a sensible number of decimals (image
coordinates to 0.01 px, the truth to 0.01 mm and 1e-6 gon, approximations
to what a sketch or a map gives) *before* it is used, so that the files
hold exactly the values of the simulation and the generated files do not
depend on the last bits of the floating-point library. The random draws come
from separate streams ``np.random.default_rng([seed, stream])``, one per
kind of quantity, so that adding or removing something (the helmet points of
alternative 2) leaves all other values unchanged.

Conventions as in :mod:`photogram.project.model`: angles in radians
(world-to-camera omega-phi-kappa), image y down, cameras looking along -z.
"""

from __future__ import annotations

import numpy as np

from photogram.geometry import camera_model, matrix_to_opk, opk_to_matrix
from photogram.project.model import (
    AdjustmentSettings, Camera, DistanceConstraint, ImagePoints, OutputSettings,
    Parameter, Points, Project, Stations, Units)
from photogram.project.tables import angle_to_rad
from photogram.simulation.network import look_at, observe, roll

__all__ = ["CAMERAS", "NOMINAL_C", "IMAGE_SIZE", "PIXEL_SIZE", "SIGMA_IMAGE",
           "LAB_FREE", "LAB_SEED", "FIELD_SEED", "lab_design", "field_design",
           "true_cameras", "slope_height"]

MODEL = "brown"
PARAMETERS = camera_model(MODEL).parameter_names

#: True interior orientation of the three cameras (px; parameters not given
#: are 0). c near the paper's 1420 / 1422 / 2493 px, principal points a few
#: px off the centre of the 640 x 480 format, a small barrel-type radial
#: distortion (about 3 px of correction in the corners of K1 and K2).
CAMERAS: dict[str, dict[str, float]] = {
    "K1": {"c": 1420.0, "x0": 323.4, "y0": 237.2, "K1": -5.2e-08, "K2": 3.0e-14},
    "K2": {"c": 1422.0, "x0": 317.1, "y0": 243.8, "K1": -4.7e-08, "K2": 0.0},
    "K3": {"c": 2493.0, "x0": 321.8, "y0": 238.6, "K1": -2.1e-08, "K2": 0.0},
}
#: Start values of c for the self-calibration: the nominal focal lengths
#: (14 mm and 25 mm lenses) over the nominal pixel size.
NOMINAL_C = {"K1": 1400.0, "K2": 1400.0, "K3": 2500.0}
IMAGE_SIZE = (640, 480)
PIXEL_SIZE = (0.01, 0.01)         # mm per px: a 6.4 x 4.8 mm (1/2") sensor
SIGMA_IMAGE = 0.33                # px, the paper's image sigma
LAB_FREE = ("c", "x0", "y0", "K1", "K2")
MARGIN = 4.0                      # px: targets closer to the border are not measured
LAB_SEED = 20250101
FIELD_SEED = 20250102

# random streams: np.random.default_rng([seed, stream])
_TRUTH_POINTS, _TRUTH_STATIONS, _IMAGE_NOISE, _APPROX_POINTS, _APPROX_STATIONS, \
    _SCALE_BAR, _SURVEY, _HELMET_NOISE = range(8)


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------

def _rng(seed: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), stream])


def _gon(values, decimals: int) -> np.ndarray:
    """Radians of angles given in gon, rounded to ``decimals`` in gon and
    converted exactly as the project reader converts the text."""
    gon = np.round(np.asarray(values, float) * 200.0 / np.pi, decimals)
    return np.array([angle_to_rad(f"{v:.{decimals}f}", "gon") for v in gon.ravel()]
                    ).reshape(gon.shape)


def true_cameras() -> dict[str, np.ndarray]:
    """The true interior orientation per camera, in model order."""
    return {name: np.array([vals.get(p, 0.0) for p in PARAMETERS], float)
            for name, vals in CAMERAS.items()}


def _camera(name: str, values: dict, free=()) -> Camera:
    params = {p: Parameter(float(values.get(p, 0.0)), free=p in free) for p in PARAMETERS}
    return Camera(name=name, model=MODEL, parameters=params, image_size=IMAGE_SIZE,
                  pixel_size=PIXEL_SIZE)


def _simulate(stations_cam, R, X0, points, seed, stream):
    """Exact image coordinates of every visible point (at least MARGIN px
    inside the format, in front of the camera) and the measured ones (noise
    N(0, SIGMA_IMAGE), rounded to 0.01 px)."""
    io = np.array([true_cameras()[c] for c in CAMERAS])
    cam_index = np.array([list(CAMERAS).index(c) for c in stations_cam])
    net = observe(MODEL, io, cam_index, R, X0, points, IMAGE_SIZE, sigma=0.0, margin=MARGIN)
    noise = _rng(seed, stream).normal(0.0, SIGMA_IMAGE, net.xy_true.shape)
    return net.station, net.point, net.xy_true, np.round(net.xy_true + noise, 2)


def _rays(point_idx, n_points) -> np.ndarray:
    return np.bincount(point_idx, minlength=n_points)


def _truth_stations(names, cams, X0, angles):
    return {"names": list(names), "camera": list(cams), "X0": X0, "angles": angles,
            "R": opk_to_matrix(angles)}


# ---------------------------------------------------------------------------
# the laboratory calibration (Fig. 5)
# ---------------------------------------------------------------------------

#: Frame centre (m) the lab stations look at.
LAB_CENTRE = np.array([0.25, 0.25, 0.15])
#: (station, camera, azimuth deg, elevation deg, distance m, roll deg)
LAB_STATIONS = (
    ("K1a", "K1", 0.0, 35.0, 2.0, 0.0),
    ("K1b", "K1", 120.0, 45.0, 2.0, 90.0),
    ("K1c", "K1", 240.0, 30.0, 2.0, 270.0),
    ("K2a", "K2", 60.0, 30.0, 2.0, 0.0),
    ("K2b", "K2", 180.0, 40.0, 2.0, 90.0),
    ("K2c", "K2", 300.0, 50.0, 2.0, 270.0),
    ("K3a", "K3", 30.0, 40.0, 4.0, 0.0),
    ("K3b", "K3", 150.0, 30.0, 4.0, 90.0),
    ("K3c", "K3", 270.0, 45.0, 4.0, 270.0),
)
SCALE_BAR = ("SB1", "SB2")
SCALE_BAR_LENGTH = 0.5            # m, nominal
SCALE_BAR_SIGMA = 1e-4            # m (0.1 mm)


def _lab_points(rng) -> tuple[list[str], np.ndarray]:
    """48 targets on a 0.5 x 0.5 x 0.3 m frame and the two ends of a scale bar.

    A 5 x 5 grid on the base plate (spacing 0.125 m, placed to +-1 cm), four
    corner posts with targets at 0.1/0.2/0.3 m, four mid-edge posts with
    targets at 0.075/0.225 m, a centre post with targets at 0.1/0.2/0.3 m,
    and a 0.5 m scale bar across the plate on 4 cm high supports.
    """
    g = np.linspace(0.0, 0.5, 5)
    base = np.array([[x, y, 0.0] for y in g for x in g])
    base[:, :2] += rng.uniform(-0.01, 0.01, (25, 2))
    base[:, :2] = np.clip(base[:, :2], 0.0, 0.5)
    posts = []
    for x, y in ((0.03, 0.03), (0.47, 0.03), (0.47, 0.47), (0.03, 0.47)):
        posts += [[x, y, z] for z in (0.1, 0.2, 0.3)]
    for x, y in ((0.25, 0.03), (0.47, 0.25), (0.25, 0.47), (0.03, 0.25)):
        posts += [[x, y, z] for z in (0.075, 0.225)]
    posts += [[0.27, 0.27, z] for z in (0.1, 0.2, 0.3)]
    posts = np.array(posts) + rng.normal(0.0, 0.002, (len(posts), 3))
    frame = np.vstack([base, posts])
    half = SCALE_BAR_LENGTH / 2 * np.array([1.0, -1.0, 0.0]) / np.sqrt(2.0)
    mid = np.array([0.25, 0.25, 0.04])
    pts = np.round(np.vstack([frame, mid - half, mid + half]), 5)
    ids = [f"T{i + 1:02d}" for i in range(len(frame))] + list(SCALE_BAR)
    return ids, pts


def _lab_stations(rng):
    names, cams, X0, R = [], [], [], []
    for name, cam, az, el, dist, kappa in LAB_STATIONS:
        a, e = np.radians(az), np.radians(el)
        direction = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
        x0 = LAB_CENTRE + dist * direction + rng.normal(0.0, 0.05, 3)
        aim = LAB_CENTRE + rng.normal(0.0, 0.02, 3)
        r = roll(look_at(x0, aim), np.radians(kappa + rng.normal(0.0, 1.0)))
        names.append(name)
        cams.append(cam)
        X0.append(x0)
        R.append(r[0])
    X0 = np.round(np.array(X0), 5)
    angles = _gon(matrix_to_opk(np.array(R)), 6)
    return names, cams, X0, angles


def lab_design(seed: int = LAB_SEED) -> tuple[Project, dict]:
    """The laboratory self-calibration network of the paper's Fig. 5.

    A 0.5 x 0.5 x 0.3 m test frame of 48 targets plus a 0.5 m scale bar
    (``SB1``-``SB2``, sigma 0.1 mm), all of unknown coordinates (free
    network: inner constraints over all points, the scale from the bar),
    photographed in 9 images: 3 per camera from different directions with
    rolls of 0, 90 and 270 degrees; K1 and K2 at 2 m, K3 at 4 m from the
    frame centre. Image sigma 0.33 px. The interior parameters c, x0, y0,
    K1, K2 of every camera are free and start from nominal values.

    Approximate values as from a rough sketch: stations the truth plus
    N(0, 3 cm) and N(0, 3 gon) (rounded to 1 cm and 0.1 gon), points the
    truth plus N(0, 1 cm) (rounded to 1 mm).

    Returns
    -------
    project : Project
    truth : dict
        ``points`` (ids, xyz), ``stations`` (names, camera, X0, angles, R),
        ``cameras`` (name -> dict of parameters), ``distances`` (a, b, true
        length, given value, sigma), ``xy_true`` (exact image coordinates,
        row-aligned with ``project.image_points``), ``seed``, ``sigma_image``.
    """
    ids, pts = _lab_points(_rng(seed, _TRUTH_POINTS))
    names, cams, X0, angles = _lab_stations(_rng(seed, _TRUTH_STATIONS))
    R = opk_to_matrix(angles)
    st, pt, xy_true, xy = _simulate(cams, R, X0, pts, seed, _IMAGE_NOISE)
    rays = _rays(pt, len(pts))
    if rays.min() < 3:
        raise RuntimeError(f"lab design: point {ids[int(rays.argmin())]} has "
                           f"{rays.min()} rays")
    rng = _rng(seed, _APPROX_STATIONS)
    approx_X0 = np.round(X0 + rng.normal(0.0, 0.03, X0.shape), 2)
    approx_angles = _gon(angles + rng.normal(0.0, 3.0, angles.shape) * np.pi / 200, 1)
    approx_pts = np.round(pts + _rng(seed, _APPROX_POINTS).normal(0.0, 0.01, pts.shape), 3)
    ia, ib = ids.index(SCALE_BAR[0]), ids.index(SCALE_BAR[1])
    true_length = float(np.linalg.norm(pts[ia] - pts[ib]))
    given_length = float(np.round(
        true_length + _rng(seed, _SCALE_BAR).normal(0.0, SCALE_BAR_SIGMA), 5))

    cameras = {c: _camera(c, {"c": NOMINAL_C[c], "x0": IMAGE_SIZE[0] / 2,
                              "y0": IMAGE_SIZE[1] / 2}, free=LAB_FREE) for c in CAMERAS}
    n_s, n_p, n_o = len(names), len(ids), len(st)
    project = Project(
        name="lab", units=Units(length="m", angle="gon", image="px"),
        cameras=cameras,
        stations=Stations(names=names, camera=cams, position=approx_X0, angles=approx_angles,
                          position_sigma=np.full((n_s, 3), np.nan),
                          angle_sigma=np.full((n_s, 3), np.nan),
                          record=np.arange(n_s) + 2),
        points=Points(ids=ids, kind=np.array(["tie"] * n_p, dtype=object), xyz=approx_pts,
                      sigma=np.full((n_p, 3), np.nan), record=np.arange(n_p) + 2),
        image_points=ImagePoints(station=st, point=pt, xy=xy, sigma=np.full(n_o, np.nan),
                                 record=np.arange(n_o) + 2),
        distances=[DistanceConstraint(SCALE_BAR[0], SCALE_BAR[1], given_length,
                                      SCALE_BAR_SIGMA)],
        adjustment=AdjustmentSettings(datum="free", sigma_image=SIGMA_IMAGE),
        output=OutputSettings(folder="results"))
    truth = {
        "seed": seed, "sigma_image": SIGMA_IMAGE,
        "points": {"ids": ids, "xyz": pts},
        "stations": _truth_stations(names, cams, X0, angles),
        "cameras": {c: dict(zip(PARAMETERS, v)) for c, v in true_cameras().items()},
        "distances": [{"from": SCALE_BAR[0], "to": SCALE_BAR[1], "true": true_length,
                       "value": given_length, "sigma": SCALE_BAR_SIGMA}],
        "xy_true": xy_true,
    }
    return project, truth


# ---------------------------------------------------------------------------
# the field orientation (Fig. 7)
# ---------------------------------------------------------------------------
# Hill coordinates in dm: X horizontal down the hill from the take-off edge,
# Y horizontal to the left (looking down the hill), Z up from the take-off
# edge. The landing slope falls at 35 degrees through (X, Z) = (400, -250).

SLOPE_DEG = 35.0
SLOPE_X, SLOPE_Z = 400.0, -250.0
#: (station, camera, X0, aim point, roll gon): K1 up the hill and K2 down
#: the hill about 55 m from the flight path, K3 on a tower about 80 m away,
#: all on the same side of the landing slope; each looks at the middle of
#: its part of the zone, turned a little about its axis (tripods are not
#: levelled exactly).
FIELD_STATIONS = (
    ("S1", "K1", (300.0, 500.0, -150.0), (499.0, -10.0, -286.0), -3.0),
    ("S2", "K2", (670.0, 490.0, -345.0), (462.0, -7.0, -280.0), -2.0),
    ("S3", "K3", (478.0, 800.0, -200.0), (481.0, -15.0, -292.0), 5.0),
)
CONTROL_SIGMA = 0.12              # dm, each axis
N_HELMET = 10


def slope_height(X) -> np.ndarray:
    """Z (dm) of the landing slope's surface at horizontal distance X (dm)."""
    return SLOPE_Z - np.tan(np.radians(SLOPE_DEG)) * (np.asarray(X, float) - SLOPE_X)


def _on_slope(x, y, h):
    return [x, y, float(slope_height(x)) + h]


def _field_points(rng):
    """15 reference points, 6 tie points and the helmet at 10 exposures.

    Reference (control): M1-M6 markers on the snow (two rows, 6 m either side
    of the centre line), P1-P6 tops of poles 2-3.5 m high along the edges of
    the slope, F1-F3 targets in the surroundings (floodlight masts on the far
    side, a fence on the near side). Tie: T1-T3 the feet of three poles,
    T4-T6 distance markers on the centre line. Helmet: H01-H10 along a
    flight path 2-5 m above the slope.
    """
    control = {
        "M1": _on_slope(415, -60, 0.0), "M2": _on_slope(480, -60, 0.0),
        "M3": _on_slope(545, -60, 0.0), "M4": _on_slope(420, 60, 0.0),
        "M5": _on_slope(485, 60, 0.0), "M6": _on_slope(545, 60, 0.0),
        "P1": _on_slope(410, -120, 25.0), "P2": _on_slope(480, -120, 35.0),
        "P3": _on_slope(550, -120, 30.0), "P4": _on_slope(410, 120, 30.0),
        "P5": _on_slope(480, 120, 20.0), "P6": _on_slope(550, 120, 35.0),
        "F1": _on_slope(440, -200, 50.0), "F2": _on_slope(520, -200, 70.0),
        "F3": _on_slope(480, 170, 12.0),
    }
    tie = {
        "T1": _on_slope(410, -120, 0.0), "T2": _on_slope(480, 120, 0.0),
        "T3": _on_slope(550, -120, 0.0),
        "T4": _on_slope(430, 0, 0.0), "T5": _on_slope(480, 0, 0.0),
        "T6": _on_slope(530, 0, 0.0),
    }
    static = np.array(list(control.values()) + list(tie.values()))
    static[:, :2] += rng.uniform(-2.0, 2.0, (len(static), 2))   # placed by hand
    static[:, 2] += rng.normal(0.0, 0.3, len(static))            # snow surface
    # helmet: ~20 m of flight along the centre line (about 11 exposures per s at 25 m/s)
    t = np.linspace(0.05, 0.95, N_HELMET)
    hx = 400.0 + 180.0 * t
    helmet = np.stack([hx, 5.0 + 8.0 * t, slope_height(hx) + 20.0 + 30.0 * np.sin(np.pi * t)],
                      axis=1)
    helmet += rng.normal(0.0, 0.5, helmet.shape)
    ids_c, ids_t = list(control), list(tie)
    ids_h = [f"H{i + 1:02d}" for i in range(N_HELMET)]
    return ids_c, ids_t, ids_h, np.round(static, 3), np.round(helmet, 3)


def _field_stations(rng):
    names = [s[0] for s in FIELD_STATIONS]
    cams = [s[1] for s in FIELD_STATIONS]
    X0 = np.array([s[2] for s in FIELD_STATIONS], float) + rng.normal(0.0, 0.5, (3, 3))
    aim = np.array([s[3] for s in FIELD_STATIONS], float) + rng.normal(0.0, 2.0, (3, 3))
    R = roll(look_at(X0, aim), np.array([s[4] for s in FIELD_STATIONS]) * np.pi / 200)
    return names, cams, np.round(X0, 3), _gon(matrix_to_opk(R), 6)


def field_design(seed: int = FIELD_SEED, alternative: int = 1) -> tuple[Project, dict]:
    """The field network of the paper's Fig. 7 at a K120-like hill (dm).

    Three stations, one per camera (K1, K2 about 55 m and K3 about 80 m from
    the flight path, all on the same side of the landing slope), look at a
    flight zone about 20 m long where the jumper flies 2-5 m above a 35
    degree slope. 15 surveyed reference points (kind control, sigma 0.12 dm
    per axis: ``datum = "weighted"``) and 6 tie points are seen in all three
    images; alternative 2 adds the helmet at 10 exposures of one jump as tie
    points (``H01``-``H10``). Interior orientation: the true (lab) values,
    held fixed. Image sigma 0.33 px.

    Given values: reference coordinates the truth plus N(0, 0.12 dm) (the
    survey, rounded to 0.01 dm); stations from a map, the truth plus
    N(0, 1 dm) (rounded to 0.1 dm) and N(0, 2 gon) (rounded to 0.1 gon); tie
    and helmet points without approximations.

    Returns
    -------
    project : Project
    truth : dict
        As :func:`lab_design` (``distances`` empty).
    """
    if alternative not in (1, 2):
        raise ValueError(f"alternative must be 1 or 2, got {alternative!r}")
    ids_c, ids_t, ids_h, static, helmet = _field_points(_rng(seed, _TRUTH_POINTS))
    names, cams, X0, angles = _field_stations(_rng(seed, _TRUTH_STATIONS))
    R = opk_to_matrix(angles)
    n_static = len(static)
    st, pt, xy_true, xy = _simulate(cams, R, X0, static, seed, _IMAGE_NOISE)
    if len(st) != 3 * n_static:
        raise RuntimeError("field design: a reference or tie point is not seen in all images")
    ids = ids_c + ids_t
    pts = static
    if alternative == 2:
        hs, hp, h_true, h_xy = _simulate(cams, R, X0, helmet, seed, _HELMET_NOISE)
        if len(hs) != 3 * len(helmet):
            raise RuntimeError("field design: a helmet position is not seen in all images")
        st = np.concatenate([st, hs])
        pt = np.concatenate([pt, hp + n_static])
        xy_true, xy = np.vstack([xy_true, h_true]), np.vstack([xy, h_xy])
        order = np.lexsort((pt, st))
        st, pt, xy_true, xy = st[order], pt[order], xy_true[order], xy[order]
        ids = ids + ids_h
        pts = np.vstack([static, helmet])
    n_c, n_p, n_o = len(ids_c), len(ids), len(st)
    kind = np.array(["control"] * n_c + ["tie"] * (n_p - n_c), dtype=object)
    xyz = np.full((n_p, 3), np.nan)
    xyz[:n_c] = np.round(pts[:n_c] + _rng(seed, _SURVEY).normal(0.0, CONTROL_SIGMA, (n_c, 3)),
                         2)
    sigma = np.full((n_p, 3), np.nan)
    sigma[:n_c] = CONTROL_SIGMA
    rng = _rng(seed, _APPROX_STATIONS)
    approx_X0 = np.round(X0 + rng.normal(0.0, 1.0, X0.shape), 1)
    approx_angles = _gon(angles + rng.normal(0.0, 2.0, angles.shape) * np.pi / 200, 1)
    name = "field" if alternative == 1 else "field-alt2"
    project = Project(
        name=name, units=Units(length="dm", angle="gon", image="px"),
        cameras={c: _camera(c, CAMERAS[c]) for c in CAMERAS},
        stations=Stations(names=names, camera=cams, position=approx_X0, angles=approx_angles,
                          position_sigma=np.full((3, 3), np.nan),
                          angle_sigma=np.full((3, 3), np.nan), record=np.arange(3) + 2),
        points=Points(ids=ids, kind=kind, xyz=xyz, sigma=sigma, record=np.arange(n_p) + 2),
        image_points=ImagePoints(station=st, point=pt, xy=xy, sigma=np.full(n_o, np.nan),
                                 record=np.arange(n_o) + 2),
        adjustment=AdjustmentSettings(datum="weighted", sigma_image=SIGMA_IMAGE),
        output=OutputSettings(folder="results" if alternative == 1 else "results-alt2"))
    truth = {
        "seed": seed, "sigma_image": SIGMA_IMAGE, "alternative": alternative,
        "points": {"ids": ids, "xyz": pts},
        "stations": _truth_stations(names, cams, X0, angles),
        "cameras": {c: dict(zip(PARAMETERS, v)) for c, v in true_cameras().items()},
        "distances": [],
        "xy_true": xy_true,
    }
    return project, truth
