"""Observation sources: where the 2D detections come from (pluggable).

=============  ===============================================  =================
kind           what                                             module
=============  ===============================================  =================
``openpose``   OpenPose / Pose2Sim JSON folders, one per camera  :mod:`.openpose`
``csv``        one long CSV table of detections                  :mod:`.csv`
``mediapipe``  mediapipe 0.10.21 pose on image crops (optional)  :mod:`.mediapipe`
``plugin``     a user network ``"module:function"`` on crops     :mod:`.plugin`
=============  ===============================================  =================

:func:`open_source` builds one from ``[mocap.source]``; every source gives,
per camera, the tracked athlete (:meth:`ObservationSource.track`).

May import :mod:`photogram.mocap.tracking` (the candidate detections, the
tracking) and :mod:`photogram.mocap.body`; never the reconstruction, the
motion, the evaluation or the project glue (docs/mocap.md, "Package
layout").
"""

from __future__ import annotations

from pathlib import Path

from photogram.errors import InputError
from photogram.mocap.body.skeleton import SKELETONS, get_skeleton
from photogram.mocap.sources.base import ImageDetector, ObservationSource

__all__ = ["ObservationSource", "ImageDetector", "ImageSource", "open_source"]


class ImageSource(ObservationSource):
    """An image detector run on the images of every camera (crop tracking)."""

    def __init__(self, kind: str, detector: ImageDetector, images: dict):
        self.kind = kind
        self.detector = detector
        self.skeleton = detector.skeleton
        self.images = images
        self.cameras = list(images)

    def track(self, camera, settings=None, wide=False):
        from photogram.mocap.tracking.crop_tracking import track_images
        return track_images(self.images[camera], self.detector, camera, settings, wide)


def _camera_paths(src, camera_names, error) -> dict[str, Path]:
    """Camera -> folder/file: explicit ``cameras``, else the entries of
    ``path`` (sub-folders, or files for videos) in name order."""
    if src.cameras:
        unknown = [c for c in src.cameras if c not in camera_names]
        if unknown:
            raise error(("source", "cameras"), f"unknown camera {unknown[0]} in "
                        f"[mocap.source.cameras]", hint="cameras: " + ", ".join(camera_names))
        return {c: src.cameras[c] for c in camera_names if c in src.cameras}
    entries = sorted(p for p in Path(src.path).iterdir() if not p.name.startswith("."))
    if len(entries) != len(camera_names):
        raise error(("source", "path"), f"{src.path} holds {len(entries)} entries for "
                    f"{len(camera_names)} cameras",
                    hint="map them explicitly: cameras = { cam1 = \"folder1\", ... }")
    return dict(zip(camera_names, entries))


def open_source(settings, camera_names: list[str], folder: Path, *,
                allow_plugin: bool = False) -> ObservationSource:
    """The source of ``[mocap.source]`` (``settings``: MocapSettings).

    A source of kind ``plugin`` imports the project's module only with
    ``allow_plugin`` (the ``--allow-plugin`` opt-in); without it an
    InputError at the line of ``network``.
    """
    src = settings.source
    err = settings.error
    if src.kind == "plugin" and not allow_plugin:
        from photogram.mocap.sources.plugin import refuse_plugin
        exc = refuse_plugin(src.network)
        raise err(("source", "network"), exc.what, hint=exc.hint)

    def skeleton(default):
        name = src.skeleton or default
        if name is None:
            raise err(("source",), f"[mocap.source] of kind {src.kind} needs skeleton = ...",
                      hint="one of " + ", ".join(SKELETONS))
        try:
            return get_skeleton(name)
        except InputError as exc:
            raise err(("source", "skeleton"), exc.what, hint=exc.hint) from None

    if src.kind == "openpose":
        from photogram.mocap.sources.openpose import OpenPoseSource
        return OpenPoseSource(_camera_paths(src, camera_names, err), skeleton("body25"))
    if src.kind == "csv":
        from photogram.mocap.sources.csv import CsvSource
        return CsvSource(src.path, skeleton(settings.skeleton), camera_names)
    from photogram.mocap.sources.images import ImageSequence
    images = {c: ImageSequence(p) for c, p in _camera_paths(src, camera_names, err).items()}
    from photogram.mocap.sources.images import check_frame_rates
    check_frame_rates(images, settings.fps, err)
    if src.kind == "mediapipe":
        from photogram.mocap.sources.mediapipe import MediapipeDetector
        return ImageSource("mediapipe", MediapipeDetector(), images)
    from photogram.mocap.sources.plugin import PluginDetector, load_function
    try:
        function = load_function(src.network, folder, allow=True)
    except InputError as exc:
        raise err(("source", "network"), exc.what, hint=exc.hint) from None
    return ImageSource("plugin", PluginDetector(function, skeleton(None), src.network), images)
