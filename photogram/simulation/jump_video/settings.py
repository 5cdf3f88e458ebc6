"""Settings of the rendered jump videos: the normal and the harsh set.

See :mod:`photogram.simulation.jump_video` for what is simulated.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

__all__ = ["VideoSettings", "harsh_settings", "IMAGE_SIZE", "MARKERS", "SKIS", "STATIONS",
           "VIDEO_SEED"]

#: Image format (width, height) in px, as the field cameras.
IMAGE_SIZE = (640, 480)
#: The jumper's markers: P1 helmet, P2 hip, P3 right binding, P4 left binding.
MARKERS = ("P1", "P2", "P3", "P4")
#: The skis: L1 right, L2 left (index 0 and 1 of ``jump_truth()["ski_tail"]``).
SKIS = ("L1", "L2")
STATIONS = ("S1", "S2", "S3")
VIDEO_SEED = 20251219


@dataclass
class VideoSettings:
    """What the three rendered videos look like.

    Attributes
    ----------
    lead_in, lead_out : int
        Frames before the first and after the last exposure (offset 0). The
        jumper is in the air only during the 24 exposures; the lead frames
        show the arena without the jumper (bystanders keep walking): a
        background model (temporal median) can be learned from them.
    shutter : float
        Exposure time (s). Motion blur is the mean of ``subframes`` renders
        at times spread evenly over the shutter, centred on the frame time.
    subframes : int
        Renders averaged per frame for the motion blur (1: no blur).
    noise : float
        Standard deviation of the additive Gaussian noise (grey levels).
    jpeg_quality : int
        JPEG quality of every frame (0: no compression).
    blur : float
        Gaussian sigma (px) of the optics' defocus blur (0: none).
    gain_jitter : float
        Relative standard deviation of a per-frame brightness factor (auto
        exposure flicker; 0: none).
    offsets : dict
        Station -> frames: that camera's video starts ``offset`` frames late
        (a sync lag): exposure ``e`` is frame ``lead_in + e - offset`` there
        (``e`` from 0). Stations not given have 0.
    occlusions : list
        ``(station, marker, first_exposure, last_exposure)``: the marker is
        not drawn in that station for the exposures first..last (numbered
        from 1 as "001".."024", inclusive), as if hidden behind an arm.
    bystanders : int
        People walking in the background (0, 1 or 2; the walks are fixed:
        far side of the slope, near the images of the flight path in S2 and
        S3). Each has a small bright reflective patch on the jacket,
        marker-like.
    marker_radius : float
        Radius (dm) of the reflective marker balls: 0.5 dm gives discs of
        2.4-2.7 px diameter in S1, 2.5-3.0 px in S2 (50-60 m), 3.1 px in S3
        (80 m, longer lens).
    target_radius : float
        Radius (dm) of the static ball targets of the field.
    click_sigma : float
        Standard deviation (px, each axis) of the simulated seed clicks.
    seed : int
        Seed of every random draw (noise, texture, clicks).
    body : bool
        False draws the jumper as its four markers only, on the static
        scene (tests of the marker discs, debugging a tracker).
    """

    lead_in: int = 12
    lead_out: int = 12
    shutter: float = 1 / 500
    subframes: int = 6
    noise: float = 2.0
    jpeg_quality: int = 92
    blur: float = 0.5
    gain_jitter: float = 0.0
    offsets: dict = field(default_factory=dict)
    occlusions: list = field(default_factory=list)
    bystanders: int = 0
    marker_radius: float = 0.5
    target_radius: float = 1.0
    click_sigma: float = 0.7
    seed: int = VIDEO_SEED
    body: bool = True

    def offset(self, station: str) -> int:
        """Frames by which ``station``'s video starts late."""
        return int(self.offsets.get(station, 0))

    def validate(self) -> None:
        """Raise ValueError on settings that cannot be rendered."""
        if self.lead_in < 0 or self.lead_out < 0:
            raise ValueError("lead_in and lead_out must be >= 0")
        if self.subframes < 1 or self.shutter < 0:
            raise ValueError("subframes must be >= 1 and shutter >= 0")
        for st, off in self.offsets.items():
            if st not in STATIONS:
                raise ValueError(f"offsets: unknown station {st!r}")
            if not -self.lead_in <= int(off) <= self.lead_out:
                raise ValueError(f"offset {off} of {st} must lie in [-lead_in, lead_out] so "
                                 "that every exposure is in its video")
        for st, mk, a, b in self.occlusions:
            if st not in STATIONS or mk not in MARKERS or not 1 <= a <= b:
                raise ValueError(f"occlusion {(st, mk, a, b)!r}: (station, marker, first, last)"
                                 " with exposures numbered from 1")
        if not 0 <= self.bystanders <= 2:
            raise ValueError("bystanders must be 0, 1 or 2")


def harsh_settings(seed: int = VIDEO_SEED + 1) -> VideoSettings:
    """The harsher set the trackers were NOT tuned on.

    Noise 5 grey levels, JPEG quality 60, a 1/200 s shutter (2.5x the blur:
    3-4 px streaks), defocus 0.8 px, a 2 % brightness flicker from frame to
    frame, two bystanders in the background (near
    the jumper's images in S2 and S3) with bright jacket patches, three
    short marker occlusions in S2 (P2 at 006-007, P3 at 012-014, P1 at
    019), and S3's video starting one frame late (a sync lag the tracker
    has to detect or tolerate).
    """
    return replace(VideoSettings(), shutter=1 / 200, subframes=10, noise=5.0, jpeg_quality=60,
                   blur=0.8, gain_jitter=0.02, offsets={"S3": 1},
                   occlusions=[("S2", "P2", 6, 7), ("S2", "P3", 12, 14), ("S2", "P1", 19, 19)],
                   bystanders=2, seed=seed)
