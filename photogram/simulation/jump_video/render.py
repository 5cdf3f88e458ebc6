"""Rendering the three videos and their truth tables."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from photogram.measure.render import degrade
from photogram.simulation.jump import FPS, N_EXPOSURES
from photogram.simulation.jump_video.actors import (
    MARKER_GREY, PATCH, JumperMotion, Parts, bystander_parts, jumper_parts)
from photogram.simulation.jump_video.raster import Disc, Shape, bounding_box, capsule_outline, paint
from photogram.simulation.jump_video.scene import static_image
from photogram.simulation.jump_video.settings import (
    IMAGE_SIZE, MARKERS, SKIS, STATIONS, VideoSettings)

__all__ = ["JumpVideos", "render_jump_videos", "render_frame", "frame_time", "compress"]


@dataclass
class JumpVideos:
    """Three rendered videos with their truth (module doc of
    :mod:`photogram.simulation.jump_video`)."""

    frames: dict                   # station -> (F, 480, 640) uint8
    fps: float
    exposure_frames: dict          # station -> (n_exposures,) int frame index in its video
    cameras: dict                  # station -> ViewCamera (the truth)
    truth_markers: pd.DataFrame
    truth_skis: pd.DataFrame
    seeds: pd.DataFrame
    truth_targets: pd.DataFrame
    settings: VideoSettings
    offsets: dict = field(default_factory=dict)
    encoded: dict = field(default_factory=dict)   # station -> JPEG bytes per frame (or None)

    @property
    def n_frames(self) -> int:
        """Frames per video (all stations have the same number)."""
        return len(next(iter(self.frames.values())))


def compress(raw: np.ndarray, quality: int) -> tuple[np.ndarray, bytes]:
    """JPEG-compress a uint8 grey frame: (decoded frame, JPEG bytes).
    ``quality`` 0 keeps the frame and encodes it at quality 100 (the bytes
    then only serve the AVI file)."""
    import cv2
    q = int(quality) if quality else 100
    ok, buf = cv2.imencode(".jpg", raw, [cv2.IMWRITE_JPEG_QUALITY, q])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    data = buf.tobytes()
    return (cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE) if quality else raw), data


def _gain(settings: VideoSettings, station_index: int, frame: int) -> float:
    """Brightness factor of one frame: 1 + N(0, gain_jitter) (auto
    exposure flicker), seeded per station and frame."""
    if not settings.gain_jitter:
        return 1.0
    rng = np.random.default_rng([settings.seed, 11, station_index, frame])
    return float(1.0 + rng.normal(0.0, settings.gain_jitter))


def _cameras():
    from photogram.simulation.ski_lines import field_cameras
    return field_cameras()


def drawing_camera(camera):
    """The camera that paints into the pixel grid: image coordinates in the
    project's convention (top-left corner of the image at (0, 0), the first
    pixel's centre at (0.5, 0.5); docs/measure.md, as the lab renderer
    :mod:`photogram.measure.scenes` and ``photogram measure`` use) are 0.5
    px more than the raster's (the first pixel's centre at (0, 0)). The
    principal point moved by -0.5 px moves every projection by exactly
    -0.5 px (the brown correction is relative to the principal point)."""
    from photogram.lines.views import ViewCamera
    io = np.array(camera.io, dtype=float)
    io[1:3] -= 0.5
    return ViewCamera(camera.R, camera.X0, io, camera.model, camera.name)


def frame_time(frame: int, station: str, settings: VideoSettings) -> float:
    """Time (s, 0 at the first exposure) of the middle of ``frame``'s
    shutter in ``station``'s video."""
    return (frame + settings.offset(station) - settings.lead_in) / FPS


def _hidden(settings, station, exposure):
    return {m for st, m, a, b in settings.occlusions
            if st == station and a <= exposure + 1 <= b}


def _part_points(parts: Parts) -> np.ndarray:
    """The 3D points (k, 3) of ``parts`` that :func:`_project_parts` draws."""
    return np.vstack([parts.A, parts.B, parts.disc_centres.reshape(-1, 3)] + parts.solids)


def _project_parts(parts: Parts, camera, discs_grey, xy=None) -> tuple[list, list, float]:
    """Image shapes and discs of 3D parts in one camera, and their mean
    depth (dm); ``xy``: the projections of :func:`_part_points` if already
    computed (:func:`_project_all`)."""
    n = len(parts.A)
    X = _part_points(parts)
    if xy is None:
        xy = camera.project(X)
    depth = -((X - camera.X0) @ camera.R.T)[:, 2]
    f = camera.c / depth
    shapes = [Shape(capsule_outline(xy[i], xy[n + i], parts.rA[i] * f[i],
                                    parts.rB[i] * f[n + i]),
                    parts.grey[i], 0.5 * (depth[i] + depth[n + i])) for i in range(n)]
    k = 2 * n + len(parts.disc_centres)
    for s, g in zip(parts.solids, parts.solid_grey):
        shapes.append(Shape(xy[k:k + len(s)], g, float(depth[k:k + len(s)].mean())))
        k += len(s)
    d0 = 2 * n
    discs = [Disc(xy[d0 + j], parts.disc_radius * f[d0 + j], discs_grey)
             for j in range(len(parts.disc_centres))]
    return shapes, discs, float(depth.mean()) if len(depth) else np.inf


def _project_all(groups, camera) -> list:
    """Per group, the projections of :func:`_project_parts` of each of its
    parts, from one projection of all their points: one distortion
    inversion per frame (Newton, vectorised) instead of one per part list;
    its per-point result is the same to rounding (converged to 1e-12 of the
    principal distance)."""
    points = [_part_points(p) for parts_list, _ in groups for p in parts_list]
    if not points:
        return [[] for _ in groups]
    xy = camera.project(np.vstack(points))
    ends = np.cumsum([len(x) for x in points])[:-1]
    chunks = iter(np.split(xy, ends))
    return [[_project_parts(p, camera, grey, next(chunks)) for p in parts_list]
            for parts_list, grey in groups]


def _sub_times(settings):
    k = settings.subframes
    return (np.arange(k) + 0.5) / k * settings.shutter - settings.shutter / 2


def _groups(station, frame, settings, motion):
    """Per moving group (bystanders, then the jumper), its parts at each
    sub-frame time."""
    t = frame_time(frame, station, settings)
    dts = _sub_times(settings)
    groups = []
    for b in range(settings.bystanders):
        groups.append(([bystander_parts(b, t + dt) for dt in dts], PATCH))
    e = frame + settings.offset(station) - settings.lead_in
    if 0 <= e < len(motion.times):
        hidden = _hidden(settings, station, e)
        parts = []
        for dt in dts:
            P, tail, tip = motion.pose(e, dt)
            parts.append(jumper_parts(P, tail, tip, settings.marker_radius, hidden,
                                      body=settings.body))
        groups.append((parts, MARKER_GREY))
    return groups


def render_frame(station: str, frame: int, settings: VideoSettings, camera, static,
                 motion) -> np.ndarray:
    """The ideal (float, before blur/noise/JPEG) image of one frame: the
    static scene with the moving groups painted far to near, each the mean
    of its sub-frame renders (motion blur)."""
    img = static.copy()
    groups = []
    for proj in _project_all(_groups(station, frame, settings, motion), camera):
        groups.append((np.nanmean([p[2] for p in proj]), [p[:2] for p in proj]))
    for _, proj in sorted(groups, key=lambda g: -g[0]):
        pts = ([s.outline for sh, _ in proj for s in sh]
               + [d.centre[None] + d.radius for _, ds in proj for d in ds]
               + [d.centre[None] - d.radius for _, ds in proj for d in ds])
        box = bounding_box(np.vstack(pts), IMAGE_SIZE) if pts else None
        if box is None:
            continue
        acc = np.zeros((box[3] - box[1], box[2] - box[0]))
        for shapes, discs in proj:
            acc += paint(img, box, shapes, discs)
        img[box[1]:box[3], box[0]:box[2]] = acc / len(proj)
    return img


def _truth_tables(cameras, settings, motion, exposure_frames):
    """Marker and ski truth: images of the true points at mid-shutter."""
    w, h = IMAGE_SIZE
    truth = motion.truth
    n = len(motion.times)
    rows_m, rows_s = [], []
    for st in STATIONS:
        cam = cameras[st]
        xy = cam.project(truth["P"].reshape(-1, 3)).reshape(n, 4, 2)
        tail = cam.project(truth["ski_tail"].reshape(-1, 3)).reshape(n, 2, 2)
        tip = cam.project(truth["ski_tip"].reshape(-1, 3)).reshape(n, 2, 2)
        for e in range(n):
            hidden = _hidden(settings, st, e)
            fr = int(exposure_frames[st][e])
            for m, name in enumerate(MARKERS):
                x, y = xy[e, m]
                inside = 0.0 <= x <= w and 0.0 <= y <= h
                rows_m.append((st, fr, f"{e + 1:03d}", name, x, y,
                               bool(inside and name not in hidden)))
            for s, name in enumerate(SKIS):
                rows_s.append((st, fr, f"{e + 1:03d}", name, *tail[e, s], *tip[e, s]))
    markers = pd.DataFrame(rows_m, columns=["station", "frame", "exposure", "marker", "x", "y",
                                            "visible"])
    skis = pd.DataFrame(rows_s, columns=["station", "frame", "exposure", "ski", "x_tail",
                                         "y_tail", "x_tip", "y_tip"])
    return markers, skis


def _seed_frame(markers):
    """The first video frame number in which every station shows all four
    markers visible (None if there is none)."""
    full = markers.groupby(["frame", "station"]).visible.all().unstack()
    ok = full.notna().all(axis=1) & full.fillna(False).astype(bool).all(axis=1)
    return int(ok[ok].index.min()) if ok.any() else None


def _seeds(markers, settings):
    """One click per marker and station, as a user would give them: all in
    the same frame number of the three videos (:func:`_seed_frame`; with a
    sync lag that frame shows another exposure in the late camera, and the
    click is where the marker is in that frame), the truth plus
    N(0, click_sigma) per axis. Without a common frame: each station's
    first frame with all four visible, else each marker's first visible."""
    rng = np.random.default_rng([settings.seed, 3])
    common = _seed_frame(markers)
    rows = []
    for st in STATIONS:
        m = markers[markers.station == st]
        full = m.groupby("frame").visible.all()
        first = common if common is not None else (full[full].index.min() if full.any()
                                                     else None)
        for name in MARKERS:
            mm = m[(m.marker == name) & m.visible]
            if first is not None:
                mm = mm[mm.frame == first]
            if len(mm) == 0:
                continue
            r = mm.iloc[0]
            dx, dy = rng.normal(0.0, settings.click_sigma, 2)
            rows.append((st, int(r.frame), name, r.x + dx, r.y + dy))
    return pd.DataFrame(rows, columns=["station", "frame", "marker", "x", "y"])


def _targets(cameras):
    from photogram.simulation.jump_video.scene import static_points
    ids, X = static_points()
    rows = []
    for st in STATIONS:
        xy = cameras[st].project(X)
        rows += [(st, i, x, y) for i, (x, y) in zip(ids, xy)]
    return pd.DataFrame(rows, columns=["station", "point", "x", "y"])


def render_jump_videos(settings: VideoSettings | None = None, *, n_exposures: int = N_EXPOSURES,
                       stations=STATIONS, frames=None, ideal: bool = False) -> JumpVideos:
    """Render the jump as three videos with their truth.

    Parameters
    ----------
    settings : VideoSettings, optional
        Default ``VideoSettings()`` (the normal set).
    n_exposures : int
        Exposures of :func:`photogram.simulation.jump.jump_truth` (24; fewer
        gives a different, shorter path: for fast tests only).
    stations : sequence of str
        Stations to render (the truth tables always hold all three).
    frames : sequence of int, optional
        Render only these frame indices (others stay zero): for tests.
    ideal : bool
        Keep the float images without blur, noise and JPEG (``frames``
        then holds float32 arrays): for tests of the geometry.

    Returns
    -------
    JumpVideos
    """
    settings = settings or VideoSettings()
    settings.validate()
    motion = JumperMotion(n_exposures)
    cameras = _cameras()
    n_frames = settings.lead_in + n_exposures + settings.lead_out
    exposure_frames = {st: settings.lead_in + np.arange(n_exposures) - settings.offset(st)
                       for st in STATIONS}
    w, h = IMAGE_SIZE
    out, encoded = {}, {}
    for si, st in enumerate(STATIONS):
        if st not in stations:
            continue
        drawn = drawing_camera(cameras[st])
        static = static_image(drawn, IMAGE_SIZE, target_radius=settings.target_radius,
                              seed=settings.seed)
        video = np.zeros((n_frames, h, w), np.float32 if ideal else np.uint8)
        encoded[st] = [None] * n_frames
        todo = range(n_frames) if frames is None else frames
        for k in todo:
            img = render_frame(st, k, settings, drawn, static, motion)
            if ideal:
                video[k] = img
                continue
            raw = degrade(img * _gain(settings, si, k), blur=settings.blur,
                          noise=settings.noise, seed=[settings.seed, si, k])
            video[k], encoded[st][k] = compress(raw, settings.jpeg_quality)
        out[st] = video
    markers, skis = _truth_tables(cameras, settings, motion, exposure_frames)
    return JumpVideos(frames=out, fps=FPS, exposure_frames=exposure_frames, cameras=cameras,
                      truth_markers=markers, truth_skis=skis, seeds=_seeds(markers, settings),
                      truth_targets=_targets(cameras), settings=settings,
                      offsets={st: settings.offset(st) for st in STATIONS}, encoded=encoded)
