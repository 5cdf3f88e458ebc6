"""Bundle Adjustment in the Large (BAL) problem files (Agarwal, Snavely,
Seitz, Szeliski 2010): reading, writing, Ceres' residuals and cost.
The translation into an engine problem, its solution and cofactors are
:mod:`photogram.bundle.bal` (io is below the engine).

File layout (plain text, usually bz2-compressed)::

    n_cameras n_points n_observations
    camera point x y                       (n_observations lines)
    9 numbers per camera                   (Rodrigues rotation r, translation t, f, k1, k2)
    3 numbers per point                    (X, Y, Z)

Projection (the BAL convention, as in Ceres' ``SnavelyReprojectionError``)::

    P = R(r) X + t,   p = -P / P_z,   x = f (1 + k1 |p|^2 + k2 |p|^4) p

with image coordinates relative to the image centre, **y up**; the camera
looks along -z. Ceres' residual is ``predicted - observed`` and its cost
``0.5 sum r^2`` (unit weights).

In the engine (photogram's conventions, docs/camera-models.md) the same
camera is ``R = R(r)``, ``X0 = -R^T t`` (``Xc = R (X - X0) = P``) with the
``bal`` camera model (parameters f, k1, k2; :mod:`photogram.geometry.bal_model`)
and image coordinates **y down**: the loader turns ``(x, y)`` into
``(x, -y)``. The cost is unchanged. Every BAL camera has its own f, k1, k2, so
the engine problem has one camera (interior orientation) per station.

Observations whose point lies behind its camera at the start (P_z >= 0;
problem-49-7776 has 31) are dropped by default (``behind="drop"``), as the
Ceres figure of COLMAP's bundle adjuster treats them (COLMAP scores a point
behind the camera as zero); ``behind="keep"`` keeps them and computes their
cost by the formula above, as Ceres' own BAL example does.
"""

from __future__ import annotations

import bz2
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.geometry import rodrigues_to_matrix
from photogram.project.limits import read_maybe_compressed

__all__ = ["BALProblem", "read_bal", "write_bal", "bal_residuals", "bal_cost",
           "behind_camera"]


@dataclass
class BALProblem:
    """A BAL problem in its own conventions (y up, Rodrigues rotations)."""

    cameras: np.ndarray       # (n_c, 9): r (3), t (3), f, k1, k2
    points: np.ndarray        # (n_p, 3)
    camera: np.ndarray        # (N,) camera index of every observation
    point: np.ndarray         # (N,) point index
    xy: np.ndarray            # (N, 2) observed, BAL image frame (y up)
    name: str = ""

    @property
    def n_cameras(self) -> int:
        return len(self.cameras)

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_observations(self) -> int:
        return len(self.camera)

    def copy(self) -> "BALProblem":
        return BALProblem(self.cameras.copy(), self.points.copy(), self.camera.copy(),
                          self.point.copy(), self.xy.copy(), self.name)

    def subset(self, keep) -> "BALProblem":
        """The problem with only the observations ``keep`` (bool or index)."""
        keep = np.asarray(keep)
        idx = np.flatnonzero(keep) if keep.dtype == bool else keep
        return BALProblem(self.cameras.copy(), self.points.copy(), self.camera[idx],
                          self.point[idx], self.xy[idx], self.name)


def _open_text(path: Path) -> str:
    """The text of a plain, .bz2 or .gz BAL file; a file that is (or
    inflates to) more than MAX_DECOMPRESSED_BYTES is refused while streaming,
    before it is held in memory."""
    raw = read_maybe_compressed(path, what="BAL file")
    return raw.decode("ascii")


def _is_float(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _token_line(text: str, k: int) -> int:
    """1-based line of the ``k``-th whitespace-separated token of ``text``."""
    seen = 0
    for number, line in enumerate(text.splitlines(), 1):
        seen += len(line.split())
        if seen > k:
            return number
    return number


def read_bal(path) -> BALProblem:
    """Read a BAL problem file (plain, .bz2 or .gz).

    Raises
    ------
    InputError
        When the file is missing, truncated or its indices are out of range.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"BAL file {path} not found", file=path)
    try:
        text = _open_text(path)
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"cannot read BAL file {path}: {exc}", file=path) from None
    tokens = text.split()
    try:
        n_c, n_p, n_o = (int(t) for t in tokens[:3])
        if len(tokens) < 3 or min(n_c, n_p, n_o) < 0:
            raise ValueError
    except ValueError:
        raise InputError("BAL header must be 'n_cameras n_points n_observations'",
                         file=path, line=1, hint="three counts >= 0") from None
    need = 3 + 4 * n_o + 9 * n_c + 3 * n_p
    if len(tokens) < need:
        raise InputError(f"BAL file is truncated: {len(tokens)} numbers, {need} expected",
                         file=path, hint="the header counts do not match the contents")
    try:
        values = np.array(tokens[3:need], dtype=float)
    except ValueError:
        k = next(k for k, t in enumerate(tokens[3:need], 3) if not _is_float(t))
        raise InputError(f"BAL file contains a non-numeric entry {tokens[k]!r}", file=path,
                         line=_token_line(text, k), hint="every entry is a number") from None
    finite = np.isfinite(values)
    if not finite.all():
        k = 3 + int(np.flatnonzero(~finite)[0])
        raise InputError(f"BAL entry {tokens[k]!r} is not a finite number", file=path,
                         line=_token_line(text, k), hint="NaN and infinity are not allowed")
    obs = values[:4 * n_o].reshape(n_o, 4)
    cams = values[4 * n_o:4 * n_o + 9 * n_c].reshape(n_c, 9)
    pts = values[4 * n_o + 9 * n_c:].reshape(n_p, 3)
    bad = np.any(obs[:, :2] != np.round(obs[:, :2]), axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"BAL observation {i}: camera and point indices must be integers",
                         file=path, line=i + 2, hint="camera point x y")
    cam_idx = obs[:, 0].astype(np.int64)
    pt_idx = obs[:, 1].astype(np.int64)
    bad = (cam_idx < 0) | (cam_idx >= n_c) | (pt_idx < 0) | (pt_idx >= n_p)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"BAL observation {i} refers to camera {cam_idx[i]} / point "
                         f"{pt_idx[i]} outside the header counts", file=path, line=i + 2)
    name = path.name
    for suffix in (".bz2", ".gz", ".txt"):
        name = name.removesuffix(suffix)
    return BALProblem(cams, pts, cam_idx, pt_idx, obs[:, 2:4].copy(), name)


def write_bal(path, bal: BALProblem) -> None:
    """Write a BAL file (bz2-compressed when the name ends in .bz2)."""
    path = Path(path)
    lines = [f"{bal.n_cameras} {bal.n_points} {bal.n_observations}"]
    lines += [f"{c} {p} {x:.17g} {y:.17g}"
              for c, p, (x, y) in zip(bal.camera, bal.point, bal.xy)]
    lines += [f"{v:.17g}" for v in bal.cameras.ravel()]
    lines += [f"{v:.17g}" for v in bal.points.ravel()]
    data = ("\n".join(lines) + "\n").encode("ascii")
    if path.suffix == ".bz2":
        data = bz2.compress(data)
    path.write_bytes(data)


def _camera_points(bal: BALProblem):
    cam = bal.cameras[bal.camera]
    R = rodrigues_to_matrix(bal.cameras[:, :3])[bal.camera]
    P = np.einsum("nij,nj->ni", R, bal.points[bal.point]) + cam[:, 3:6]
    return P, cam


def bal_residuals(bal: BALProblem) -> np.ndarray:
    """Ceres' residuals ``predicted - observed`` (N, 2), BAL image frame."""
    P, cam = _camera_points(bal)
    p = -P[:, :2] / P[:, 2:3]
    r2 = np.sum(p * p, axis=1)
    d = 1.0 + r2 * (cam[:, 7] + r2 * cam[:, 8])
    return cam[:, 6:7] * d[:, None] * p - bal.xy


def bal_cost(bal: BALProblem) -> float:
    """``0.5 sum r^2`` over all observations (Ceres' cost)."""
    r = bal_residuals(bal)
    return 0.5 * float(np.sum(r * r))


def behind_camera(bal: BALProblem) -> np.ndarray:
    """(N,) bool: the observation's point is behind its camera (P_z >= 0)."""
    P, _ = _camera_points(bal)
    return P[:, 2] >= 0.0
