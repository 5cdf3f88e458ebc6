"""The stick model of a ski jumper per exposure (docs/stick-model.md).

:func:`stick_model` turns the intersected points P1..P4 and the ski line
directions of every exposure into the jumper frame (O, X', Y', Z'), the angles
alpha, beta, gamma, delta_phi, the ski slope phi, the heading, the height Z0
and the speed v of O, the two ski segments and, given the covariances of the
inputs, the sigma (and covariance) of every parameter. The definitions are
in :mod:`photogram.jump.definitions`, the propagation in
:mod:`photogram.jump.propagate`.

Units: lengths in the project's length unit (``length_unit``), speed in that
unit per second, angles in radians (``to_frame`` converts).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import InputError
from photogram.jump import definitions as defs
from photogram.jump import propagate as prop
from photogram.project.model import LENGTH_UNITS

__all__ = ["StickModel", "stick_model", "ski_segments", "PlaneGround", "ProfileGround",
           "ANGLE_FACTORS"]

#: radians -> unit
ANGLE_FACTORS = {"rad": 1.0, "deg": 180.0 / np.pi, "gon": 200.0 / np.pi}


# ---------------------------------------------------------------------------
# ground for Z0


@dataclass
class PlaneGround:
    """A slope plane through ``point`` with normal ``normal``; Z0 becomes the
    height of O above it: vertical (``vertical=True``, along world Z) or along
    the normal."""

    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    vertical: bool = True

    def height(self, O: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        nrm = np.asarray(self.normal, dtype=float)
        nrm = nrm / np.linalg.norm(nrm)
        if nrm[2] < 0:
            nrm = -nrm
        if self.vertical and nrm[2] < 1e-9:
            raise InputError("a vertical plane has no height above it",
                             hint="give the slope plane's normal, world Z up")
        grad = nrm / nrm[2] if self.vertical else nrm
        h = (O - np.asarray(self.point, dtype=float)) @ grad
        return h, np.broadcast_to(grad, O.shape).copy()


@dataclass
class ProfileGround:
    """A hill profile ``z(x)`` tabulated along world X (increasing ``x``),
    linear in between; Z0 becomes the vertical height ``O_z - z(O_x)`` (NaN
    outside the table)."""

    x: np.ndarray
    z: np.ndarray

    def height(self, O: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(self.x, dtype=float)
        z = np.asarray(self.z, dtype=float)
        if x.ndim != 1 or x.shape != z.shape or x.size < 2 or np.any(np.diff(x) <= 0):
            raise InputError("the ground profile needs >= 2 points with increasing x")
        k = np.clip(np.searchsorted(x, O[:, 0]) - 1, 0, x.size - 2)
        slope = (z[k + 1] - z[k]) / (x[k + 1] - x[k])
        zg = z[k] + slope * (O[:, 0] - x[k])
        outside = (O[:, 0] < x[0]) | (O[:, 0] > x[-1])
        h = np.where(outside, np.nan, O[:, 2] - zg)
        dh = np.stack([-slope, np.zeros_like(slope), np.ones_like(slope)], axis=1)
        return h, dh


# ---------------------------------------------------------------------------
# the model


@dataclass
class StickModel:
    """Stick model of a series of exposures (arrays indexed by exposure).

    Attributes
    ----------
    times, frames : ndarray (n,)
        Exposure times (s) and frame numbers (0 at the first exposure).
    P : ndarray (n, 4, 3)
        P1..P4 as given.
    d1, d2 : ndarray (n, 3)
        Unit ski directions (oriented).
    O, X, Y, Z : ndarray (n, 3)
        Origin and axes of the jumper frame.
    values : dict name -> ndarray (n,)
        Every parameter of :data:`photogram.jump.definitions.PARAMETERS`.
    velocity : ndarray (n, 3)
        Velocity of O the speed ``v`` is the norm of.
    binding_points : ndarray (n, 2, 3)
        The point of each ski line closest to its binding point.
    skis : ndarray (n, 2, 2, 3)
        Ski segments: ``skis[i, k] = (tail, tip)`` of ski k (0 right, 1 left).
    jacobian : ndarray (n, 7, 18)
        d(parameters except v) / d(P1..P4, d1, d2) per exposure.
    cov : ndarray (n, 8, 8) or None
        Covariance of the parameters (order of PARAMETERS), if input
        covariances were given.
    """

    times: np.ndarray
    frames: np.ndarray
    fps: float
    length_unit: str
    P: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    O: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    Z: np.ndarray
    values: dict[str, np.ndarray]
    velocity: np.ndarray
    binding_points: np.ndarray
    skis: np.ndarray
    ski_length: float
    binding_fraction: float
    jacobian: np.ndarray
    jacobian_O: np.ndarray
    cov: np.ndarray | None = None
    speed_pairs: tuple[np.ndarray, np.ndarray] = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.times)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.values[name]

    @property
    def sigma(self) -> dict[str, np.ndarray] | None:
        """Sigma of every parameter (None without input covariances)."""
        if self.cov is None:
            return None
        sd = np.sqrt(np.clip(np.diagonal(self.cov, axis1=1, axis2=2), 0.0, None))
        sd = np.where(np.isnan(np.diagonal(self.cov, axis1=1, axis2=2)), np.nan, sd)
        return {name: sd[:, k] for k, name in enumerate(defs.PARAMETERS)}

    def to_frame(self, angle_unit: str = "rad", exposures=None):
        """One row per exposure: exposure, frame, time, every parameter, its
        sigma (``sigma_<name>``, if known) and O.

        ``angle_unit`` is rad, deg or gon; lengths stay in ``length_unit``
        (``v`` in length unit per second). The units are in ``frame.attrs``.
        ``exposures`` are the exposure ids as the measurements name them
        (``"001"``, ..., as in points3d.csv and lines3d.csv); without them the
        exposures are numbered 0, 1, ... in time order.
        """
        import pandas as pd

        if angle_unit not in ANGLE_FACTORS:
            raise InputError(f"unknown angle unit {angle_unit!r}",
                             hint=f"use one of {', '.join(ANGLE_FACTORS)}")
        f = ANGLE_FACTORS[angle_unit]
        if exposures is None:
            ids = np.arange(len(self))
        else:
            ids = np.array([str(e) for e in exposures], dtype=object)
            if len(ids) != len(self):
                raise InputError(f"{len(ids)} exposure ids for {len(self)} exposures")
        cols = {"exposure": ids, "frame": self.frames, "time": self.times}
        sig = self.sigma
        for name in defs.PARAMETERS:
            k = f if name in defs.ANGLE_PARAMETERS else 1.0
            cols[name] = self.values[name] * k
        if sig is not None:
            for name in defs.PARAMETERS:
                k = f if name in defs.ANGLE_PARAMETERS else 1.0
                cols["sigma_" + name] = sig[name] * k
        for j, c in enumerate("xyz"):
            cols["O_" + c] = self.O[:, j]
        frame = pd.DataFrame(cols)
        frame.attrs.update({"angle_unit": angle_unit, "length_unit": self.length_unit,
                            "fps": self.fps})
        return frame


def _as_array(x, shape_tail: tuple, n: int | None, what: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim != len(shape_tail) + 1 or a.shape[1:] != shape_tail or (n is not None and len(a) != n):
        want = "(n, " + ", ".join(map(str, shape_tail)) + ")"
        raise InputError(f"{what} has shape {a.shape}, expected {want}"
                         + (f" with n = {n}" if n is not None else ""))
    return a


def ski_segments(P3, P4, u1, u2, c1=None, c2=None, *, length: float,
                 binding_fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """Ski segments from the ski lines and the binding points.

    The ski line ``k`` passes through ``c_k`` (default: its binding point)
    with unit direction ``u_k``; its binding point is the point of the line
    closest to P3 (right ski) or P4 (left ski), and the ski of ``length``
    runs from ``binding - f length u`` (tail) to ``binding + (1-f) length u``
    (tip), ``f = binding_fraction``.

    Returns
    -------
    binding_points : ndarray (n, 2, 3)
    skis : ndarray (n, 2, 2, 3)
        ``(tail, tip)`` per ski.
    """
    feet = []
    for Pb, u, c in ((P3, u1, c1), (P4, u2, c2)):
        c = Pb if c is None else c
        t = np.einsum("ni,ni->n", Pb - c, u)
        feet.append(c + t[:, None] * u)
    feet = np.stack(feet, axis=1)
    u = np.stack([u1, u2], axis=1)
    tail = feet - binding_fraction * length * u
    tip = feet + (1.0 - binding_fraction) * length * u
    return feet, np.stack([tail, tip], axis=2)


def stick_model(P, d1, d2, *, fps: float = 30.0, times=None, length_unit: str = "m",
                ski_length: float = 2.63, binding_fraction: float = 0.43,
                c1=None, c2=None, forward=None, ground=None,
                cov_points=None, cov_dirs=None, cov=None) -> StickModel:
    """Stick model parameters of every exposure (vectorized).

    Parameters
    ----------
    P : array_like (n, 4, 3)
        P1 head, P2 hip, P3 right binding, P4 left binding (project length
        unit, world Z up); NaN for a point not measured.
    d1, d2 : array_like (n, 3)
        Directions of the right and left ski lines, from tail to tip (any
        length). See ``forward`` to orient them.
    fps : float
        Frame rate (30 in the paper).
    times : array_like (n,), optional
        Exposure times in s on the ``1/fps`` grid (default ``arange(n)/fps``);
        a missing frame in the times makes the speed of its neighbours NaN.
    length_unit : str
        The project's length unit (m, dm, cm, mm).
    ski_length : float
        Ski length in **metres** (converted to ``length_unit``).
    binding_fraction : float
        Position of the binding from the tail as a fraction of the ski length
        (0.43: an assumption, see docs/stick-model.md).
    c1, c2 : array_like (n, 3), optional
        A point on each ski line (default: the line passes through P3 / P4).
    forward : "flight" or array_like (3,) or (n, 3), optional
        Flip each direction so that it points along ``forward`` ("flight": the
        displacement of O from the first to the last exposure).
    ground : PlaneGround or ProfileGround, optional
        Z0 is the height above it instead of the world Z of O.
    cov_points, cov_dirs, cov :
        Input covariances (:func:`photogram.jump.propagate.input_covariance`);
        without them ``cov`` and ``sigma`` of the model are None.

    Raises
    ------
    InputError
        Bad shapes or options, ski directions pointing against each other.
    """
    P = _as_array(P, (4, 3), None, "P")
    n = len(P)
    d1 = _as_array(d1, (3,), n, "d1")
    d2 = _as_array(d2, (3,), n, "d2")
    if not (np.isfinite(fps) and fps > 0):
        raise InputError(f"fps must be positive, got {fps}")
    if length_unit not in LENGTH_UNITS:
        raise InputError(f"unknown length unit {length_unit!r}",
                         hint=f"use one of {', '.join(LENGTH_UNITS)}")
    if not 0.0 <= binding_fraction <= 1.0:
        raise InputError(f"binding_fraction must be in [0, 1], got {binding_fraction}")
    if not ski_length > 0:
        raise InputError(f"ski_length must be positive, got {ski_length}")
    times = np.arange(n) / fps if times is None else np.asarray(times, dtype=float)
    if times.shape != (n,):
        raise InputError(f"times has shape {times.shape}, expected ({n},)")
    frames = prop.exposure_frames(times, fps)
    O_raw = 0.5 * (P[:, 2] + P[:, 3])
    if forward is not None:
        d1, d2 = _orient(d1, d2, forward, O_raw)
    with np.errstate(invalid="ignore"):
        bad = np.einsum("ni,ni->n", d1, d2) <= 0
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise InputError(f"the ski directions of exposure {k} point against each other",
                         hint="orient d1 and d2 from tail to tip, or pass forward=")

    with np.errstate(divide="ignore", invalid="ignore"):
        q, f = defs.parameters(P, d1, d2, ground=ground)
        names = [p for p in defs.PARAMETERS if p != "v"]
        values = {p: q[p].v for p in names}
        J = np.stack([q[p].J for p in names], axis=1)
        a, b = prop.speed_pairs(frames)
        v, velocity, g = prop.speed(f["O"].v, times, a, b)
        values["v"] = v
        length = ski_length / LENGTH_UNITS[length_unit]
        c1 = None if c1 is None else _as_array(c1, (3,), n, "c1")
        c2 = None if c2 is None else _as_array(c2, (3,), n, "c2")
        feet, skis = ski_segments(P[:, 2], P[:, 3], f["u1"].v, f["u2"].v, c1, c2,
                                  length=length, binding_fraction=binding_fraction)
        C = None
        if cov_points is not None or cov_dirs is not None or cov is not None:
            Cin = prop.input_covariance(n, cov_points, cov_dirs, cov)
            C = prop.propagate(J, f["O"].J, Cin, a, b, g)
    return StickModel(times=times, frames=frames, fps=float(fps), length_unit=length_unit,
                      P=P, d1=f["u1"].v, d2=f["u2"].v, O=f["O"].v, X=f["X"].v,
                      Y=f["Y"].v, Z=f["Z"].v, values=values, velocity=velocity,
                      binding_points=feet, skis=skis, ski_length=length,
                      binding_fraction=binding_fraction, jacobian=J,
                      jacobian_O=f["O"].J, cov=C, speed_pairs=(a, b))


def _orient(d1, d2, forward, O):
    if isinstance(forward, str):
        if forward != "flight":
            raise InputError(f"unknown forward {forward!r}", hint='use "flight" or a vector')
        ok = np.flatnonzero(np.all(np.isfinite(O), axis=1))
        if len(ok) < 2:
            raise InputError('forward="flight" needs O at two exposures at least')
        fwd = np.broadcast_to(O[ok[-1]] - O[ok[0]], d1.shape)
    else:
        fwd = np.broadcast_to(np.asarray(forward, dtype=float), d1.shape)
    out = []
    for d in (d1, d2):
        s = np.where(np.einsum("ni,ni->n", d, fwd) < 0, -1.0, 1.0)
        out.append(d * s[:, None])
    return out[0], out[1]
