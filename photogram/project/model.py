"""The in-memory project model: cameras, stations, points, observations,
constraints and settings.

Tables are column arrays (numpy), so that every later layer works on all
observations at once. Internal units are the project's own length unit and
image unit; angles are always **radians** in memory (the readers and writers
convert from and to the unit named in ``[project]``). Unknown values are NaN.

Conventions (see docs/camera-models.md):

* Rotations are omega-phi-kappa, stored as the angles of the
  **world-to-camera** matrix R (``Xc = R (X - X0)``); the camera frame is the
  photogrammetric one (x right, y up, camera looking along -z).
* Image coordinates have x to the right and y **down** (pixel columns and
  rows; or millimetres from the top-left corner of the format).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

LENGTH_UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001}
ANGLE_UNITS = ("rad", "deg", "gon")
IMAGE_UNITS = ("px", "mm")
POINT_KINDS = ("control", "check", "tie")
DATUMS = ("control", "weighted", "free", "dependent")
#: [adjustment] dependent_coordinate (datum = "dependent", DBAT's ref_base)
DEPENDENT_COORDINATES = ("longest", "x", "y", "z")
ROTATIONS = ("omega-phi-kappa",)           # as written in [project] rotation
ROTATION_DIRECTIONS = ("world_to_camera", "camera_to_world")
DAMPINGS = ("none", "lm", "armijo")
#: [adjustment] robust ("none": off): the one list of losses the reader accepts,
#: photogram.stats.robust implements and docs/project-files.md names
ROBUST_FUNCTIONS = ("huber", "cauchy", "soft_l1", "tukey")


@dataclass
class Parameter:
    """One interior-orientation parameter.

    ``sigma`` is an a-priori standard deviation: a free parameter with a sigma
    is a weighted (prior) observation of ``value``. ``sigma_estimated`` is the
    a-posteriori sigma of an earlier adjustment (results/cameras.toml); it is
    carried along for information and never used as a weight.
    """

    value: float
    free: bool = False
    sigma: float | None = None
    sigma_estimated: float | None = None


@dataclass
class Camera:
    """A physical camera (interior orientation), shared by its stations.

    ``parameters`` holds every parameter of ``model`` (see
    :func:`photogram.geometry.camera_model`), in the model's order.
    """

    name: str
    model: str = "brown"
    parameters: dict[str, Parameter] = field(default_factory=dict)
    image_size: tuple[int, int] | None = None      # width, height in px
    pixel_size: tuple[float, float] | None = None  # mm per px (x, y)
    source: str | None = None                      # file it was taken from
    # parameter sharing (docs/project-files.md, "Parameter sharing"); empty:
    # every parameter is one value for all stations of this camera
    per_station: tuple[str, ...] = ()              # one value per station of the camera
    ties: dict[str, str] = field(default_factory=dict)    # parameter -> the one it equals
    shared: dict[str, str] = field(default_factory=dict)  # parameter -> group across cameras
    # estimated per-station values (results): parameter -> {station: value}
    station_values: dict[str, dict[str, float]] = field(default_factory=dict)

    def shares(self) -> bool:
        """Whether any parameter is not simply one value for the camera."""
        return bool(self.per_station or self.ties or self.shared)

    def values(self) -> np.ndarray:
        """Parameter values as an array, in model order."""
        return np.array([p.value for p in self.parameters.values()], dtype=float)

    def free_mask(self) -> np.ndarray:
        """Boolean mask of free parameters, in model order."""
        return np.array([p.free for p in self.parameters.values()], dtype=bool)


@dataclass
class Units:
    length: str = "m"
    angle: str = "deg"
    image: str = "px"


@dataclass
class Stations:
    """Camera stations (exposures). Row i is station ``names[i]``.

    ``position``/``angles`` are approximate exterior orientations (NaN where
    unknown); ``position_sigma``/``angle_sigma`` are a-priori sigmas that make
    them weighted observations (NaN: no prior). Angles in radians.
    ``record`` is the 1-based line of each station in its source file.
    """

    names: list[str] = field(default_factory=list)
    camera: list[str] = field(default_factory=list)
    position: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    angles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    position_sigma: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    angle_sigma: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    record: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    # the rig frame (exposure) of each station ("" none); empty list: no frames
    frame: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.names)

    def index(self) -> dict[str, int]:
        return {n: i for i, n in enumerate(self.names)}

    def frames(self) -> list[str]:
        """The frame of every station ("" where none)."""
        return list(self.frame) if len(self.frame) == len(self.names) else [""] * len(self.names)


@dataclass
class Rig:
    """Cameras rigidly mounted together (COLMAP's rig, ``[rigs.NAME]``).

    ``reference`` is the camera whose frame is the rig's (its pose in the
    rig is the identity); ``cameras`` the others. ``sensors`` holds the
    pose of each other camera in the rig (``sensor_from_rig``) as the
    (position (3,), angles (3,) radians world-to-camera sense) of a
    station whose "world" is the rig frame; a camera without one has an
    unknown pose. ``fixed``: the sensor poses are held at their values.
    """

    name: str
    reference: str
    cameras: list[str] = field(default_factory=list)
    fixed: bool = False
    sensors: dict = field(default_factory=dict)     # camera -> (position, angles)
    line: int | None = None


@dataclass
class Points:
    """Object points. ``kind`` is control, check or tie; ``xyz`` NaN where
    unknown; ``sigma`` the a-priori sigma of reference coordinates (NaN: none,
    0: fixed); ``record`` the 1-based line in the source file (empty if the
    points were not read from a file)."""

    ids: list[str] = field(default_factory=list)
    kind: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=object))
    xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    sigma: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    record: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    # circular targets (optional columns diameter, nX nY nZ): NaN = not given
    diameter: np.ndarray | None = None
    normal: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.ids)

    def index(self) -> dict[str, int]:
        return {n: i for i, n in enumerate(self.ids)}


@dataclass
class ImagePoints:
    """Image point observations, one row per measurement.

    ``station``/``point`` are integer indices into :class:`Stations` and
    :class:`Points`; ``xy`` in the project's image unit; ``sigma`` per
    observation (NaN: the default from ``[adjustment]``); ``record`` the
    1-based line in the source file (for messages).
    """

    station: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    point: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    sigma: np.ndarray = field(default_factory=lambda: np.zeros(0))
    record: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    group: np.ndarray | None = None   # variance-component group per row ("" = per camera)

    def __len__(self) -> int:
        return len(self.station)


@dataclass
class ImageLines:
    """Points measured along image lines (e.g. skis): one row per point."""

    station: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    line: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=object))
    xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    sigma: np.ndarray = field(default_factory=lambda: np.zeros(0))
    record: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    def __len__(self) -> int:
        return len(self.station)


@dataclass
class DistanceConstraint:
    """A measured distance between two object points (scale bar, rod)."""

    point_a: str
    point_b: str
    value: float
    sigma: float


@dataclass
class VerticalConstraint:
    """Two points on a vertical rod (eq. (3) of the ski-jump paper): the
    horizontal offsets of ``top`` from ``bottom`` are observed as zero with
    ``sigma`` as a slope ratio (e.g. 0.01 for 1:100)."""

    top: str
    bottom: str
    sigma: float


@dataclass
class AdjustmentSettings:
    datum: str = "control"
    max_iterations: int = 50
    tolerance: float = 1e-8
    sigma_image: float | dict = 1.0   # default a-priori image sigma (image unit), or per camera
    sigma_control: float | None = None  # default sigma of control coords
    damping: str = "lm"               # "none" | "lm" | "armijo"
    robust: str | None = None         # None | "huber" | "cauchy" ...
    variance_components: bool = False
    snooping_alpha: float | None = None
    inner_constraints: list[str] | None = None  # point ids; None: all points
    dependent_station: str | None = None  # datum = "dependent": base station (None: first)
    dependent_coordinate: str = "longest"  # ... and the coordinate of the scale


@dataclass
class TargetSettings:
    """``[targets]``: circular targets measured as ellipse centres; the
    adjustment predicts the imaged ellipse centre (docs/adjustment.md,
    "Eccentricity of circular targets"). ``radius`` and ``normal`` per
    point (NaN: not a circular target), resolved from the points table's
    ``diameter``, ``nX nY nZ`` and the section's defaults."""

    eccentricity: bool = True
    diameter: float | None = None       # default diameter, object units
    normal: tuple | None = None         # default target normal
    ids: list | None = None             # point ids the arrays below follow
    radius: np.ndarray | None = None    # per point, NaN: not a circular target
    normals: np.ndarray | None = None   # (., 3) unit normals

    def for_points(self, ids) -> tuple[np.ndarray, np.ndarray]:
        """Radius (n,) and unit normal (n, 3) of the points ``ids`` (NaN
        for points that are not circular targets or unknown here)."""
        where = {p: i for i, p in enumerate(self.ids or [])}
        j = np.array([where.get(p, -1) for p in ids], dtype=int)
        ok = j >= 0
        r = np.full(len(j), np.nan)
        nv = np.full((len(j), 3), np.nan)
        if self.radius is not None:
            r[ok] = self.radius[j[ok]]
            nv[ok] = self.normals[j[ok]]
        return r, nv


@dataclass
class IntersectSettings:
    """``[intersect]``: the ski-jump intersection step (photogram intersect).

    ``points`` are the jumper points P1 (helmet), P2 (hip), P3 (right
    binding), P4 (left binding); ``skis`` the right and left ski lines;
    ``orientation`` earlier results folders whose covariance.npz files are
    propagated into the points (e.g. the lab's for the interior and the
    field's for the exterior orientation; None: image noise only);
    ``ski_length`` in metres.
    """

    fps: float = 30.0
    points: tuple = ("P1", "P2", "P3", "P4")
    skis: tuple = ("L1", "L2")
    ski_length: float = 2.63
    binding_fraction: float = 0.43
    orientation: list | None = None
    swap_skis: bool = False
    landing_profile: str | None = None       # CSV (distance, height) along world X


#: ``[report] units``: "project" (the project's units) or "coach" (deg, m,
#: km/h in the stick-model tables, figures and coach.csv)
REPORT_UNITS = ("project", "coach")


@dataclass
class ReportSettings:
    """``[report]``: how the reports show the results (``units``, one of
    :data:`REPORT_UNITS`)."""

    units: str = "project"


@dataclass
class OutputSettings:
    folder: str = "results"


PERTURBATIONS = ("image", "reference", "interior", "constraints")
TRUTHS = ("adjusted", "simulation")


@dataclass
class MonteCarloSettings:
    """``[montecarlo]``: the chain a Monte-Carlo simulation repeats
    (``photogram montecarlo``, docs/montecarlo.md).

    Exactly one of ``orient`` (bundle with the interior orientation held
    fixed) and ``calibrate`` (interior parameters free as that project says)
    names the adjustment step; ``intersect`` optionally the intersect step
    that takes its orientation. Paths are absolute (resolved against the
    .prj folder by the reader). ``perturb`` lists what is drawn per run:
    image coordinates, reference coordinates, the interior orientation
    (from ``interior_covariance``, a results folder with covariance.npz;
    default: the folder of the cameras file of the adjustment step) and
    constraint observations (distances, verticality). ``truth`` is the
    adjusted solution or the simulation truth (``truth/`` beside each
    project, as ``photogram simulate`` and projects/generate.py write it).
    ``points`` are ids (``*`` wildcards) of adjustment points to collect
    (e.g. helmet tie points); ``align`` removes from them a translation and
    a rotation about the vertical per run (``"none"`` or ``"plan"``) before
    their scatter is taken. ``scheduler`` is the address of a Dask
    cluster (``tcp://host:port``; None: local processes); it is set only
    from the command line (``--scheduler``), never from a project file.
    """

    orient: str | None = None
    calibrate: str | None = None
    intersect: str | None = None
    perturb: tuple = ("image", "reference")
    interior_covariance: str | None = None
    truth: str = "adjusted"
    points: tuple = ()
    align: str = "none"
    runs: int = 1000
    seed: int = 0
    chunk: int = 50
    workers: int = 1
    scheduler: str | None = None


@dataclass
class Project:
    """A whole photogrammetric project, as read from a .prj file."""

    name: str = "project"
    path: Path | None = None
    units: Units = field(default_factory=Units)
    rotation: str = "opk"
    rotation_direction: str = "world_to_camera"
    cameras: dict[str, Camera] = field(default_factory=dict)
    stations: Stations = field(default_factory=Stations)
    points: Points = field(default_factory=Points)
    image_points: ImagePoints = field(default_factory=ImagePoints)
    image_lines: ImageLines = field(default_factory=ImageLines)
    distances: list[DistanceConstraint] = field(default_factory=list)
    verticals: list[VerticalConstraint] = field(default_factory=list)
    adjustment: AdjustmentSettings = field(default_factory=AdjustmentSettings)
    output: OutputSettings = field(default_factory=OutputSettings)
    report: ReportSettings = field(default_factory=ReportSettings)
    intersect: IntersectSettings = field(default_factory=IntersectSettings)
    montecarlo: MonteCarloSettings | None = None
    targets: TargetSettings | None = None   # [targets]: None = no eccentricity correction
    mocap: object | None = None        # MocapSettings (photogram.project.reader_mocap)
    track: object | None = None        # TrackSettings (photogram.project.reader_track)
    board: object | None = None        # BoardSettings (photogram.project.reader_board)
    rigs: dict[str, Rig] = field(default_factory=dict)   # [rigs.NAME]
    sources: dict[str, Path] = field(default_factory=dict)  # table -> file
    warnings: list[str] = field(default_factory=list)  # found by the reader

    @property
    def folder(self) -> Path:
        """Folder the project's relative paths are resolved against."""
        return self.path.parent if self.path is not None else Path.cwd()

    def output_folder(self) -> Path:
        out = Path(self.output.folder)
        return out if out.is_absolute() else self.folder / out
