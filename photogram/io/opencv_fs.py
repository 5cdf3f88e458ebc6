"""OpenCV FileStorage calibration files (YAML, XML or JSON), read and
written with ``cv2.FileStorage``.

Read (one camera per file, names as OpenCV's samples and common tools write
them; the first present name wins):

==================  ====================================================
intrinsics          ``camera_matrix``, ``cameraMatrix``, ``K``, ``M``, ``mtx``,
                    ``intrinsic``
distortion          ``distortion_coefficients``, ``dist_coeffs``, ``distCoeffs``,
                    ``D``, ``dist`` (4, 5, 8, 12 or 14: with non-zero terms beyond k3
                    the camera is ``opencv_full``)
image size          ``image_width`` + ``image_height``, or ``image_size``/``imageSize``
pose (optional)     ``R`` (3 x 3 matrix or Rodrigues vector) or ``rvec``, with ``T``,
                    ``t`` or ``tvec``: ``x_cv = R X + T``; or OpenCV's calibration
                    sample's ``extrinsic_parameters`` (one row ``rvec, tvec`` per view)
==================  ====================================================

A stereo file (``M1 D1 M2 D2 R T`` of ``cv2.stereoCalibrate``) gives two
cameras: the first at the origin, the second at ``R, T``.

Written: ``camera_matrix``, ``distortion_coefficients`` (1 x 5; 1 x 8, 12
or 14 for ``opencv_full`` cameras),
``image_width``, ``image_height``, ``R`` (3 x 3), ``rvec``, ``T`` (3 x 1)
and ``camera_name`` per file; ``cv2.FileStorage`` writes doubles with 17
significant digits, so the numbers read back exactly. Several stations are
written as one file per station into a folder.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from photogram.errors import InputError
from photogram.io.exchange import View, opencv_camera

__all__ = ["read_opencv", "opencv_project", "format_opencv", "write_opencv"]

_K = ("camera_matrix", "cameraMatrix", "K", "M", "mtx", "intrinsic")
_D = ("distortion_coefficients", "dist_coeffs", "distCoeffs", "D", "dist")
_R = ("R", "rvec", "rotation")
_T = ("T", "t", "tvec", "translation")
EXTENSIONS = (".yml", ".yaml", ".xml", ".json")


def _open(path: Path):
    import cv2
    if not path.is_file():
        raise InputError("OpenCV calibration file not found", file=path)
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except Exception as exc:                       # cv2.error (or SystemError around it)
        cause = exc.__cause__ or exc
        text = str(cause)
        m = re.search(r"\((\d+)\):\s*(.*?)'?\s*$", text.strip())
        line = int(m.group(1)) if m else None
        what = m.group(2).strip(" '") if m else text.strip().splitlines()[-1]
        raise InputError(f"not a valid OpenCV FileStorage file: {what}", file=path, line=line,
                         hint="the file is truncated or damaged") from None
    if not fs.isOpened():
        raise InputError("cannot open as an OpenCV FileStorage file", file=path,
                         hint="YAML (%YAML:1.0 header), XML (<opencv_storage>) or JSON")
    return fs


def _line_of(path: Path, key: str) -> int | None:
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return None
    pat = re.compile(r'^\s*(?:<\s*|")?' + re.escape(key) + r'(?:\s*:|"\s*:|[\s>])')
    for k, ln in enumerate(lines, 1):
        if pat.match(ln):
            return k
    return None


def _node(fs, names):
    for n in names:
        node = fs.getNode(n)
        if not node.empty() and not node.isNone():
            return n, node
    return None, None


def _opencv_matrix(path, key, node) -> np.ndarray:
    """An ``!!opencv-matrix`` node read item by item: ``node.mat()`` trusts
    rows, cols and dt (a negative or huge size makes OpenCV allocate
    gigabytes or corrupt its heap), so they are checked against the data."""
    def fail(what):
        return InputError(f"{key}: {what}", file=path, line=_line_of(path, key),
                          hint="an opencv-matrix has rows, cols (integers), dt (e.g. d) and "
                               "data: a list of rows x cols numbers")
    r, c, dt, data = (node.getNode(k) for k in ("rows", "cols", "dt", "data"))
    if not (r.isInt() and c.isInt()):
        raise fail("rows and cols must be integers")
    if not data.isSeq():
        raise fail("data must be a list of numbers")
    rows, cols = int(r.real()), int(c.real())
    m = re.fullmatch(r"(\d*)([ucwsifdh])", dt.string().strip() if dt.isString() else "d")
    if m is None:
        raise fail(f"unknown dt {dt.string()!r}")
    channels = int(m.group(1) or 1)
    if rows < 0 or cols < 0 or not 1 <= channels <= 4 or data.size() != rows * cols * channels:
        raise fail(f"data has {data.size()} numbers, rows x cols = {rows} x {cols}"
                   + (f" x {channels} channels" if channels != 1 else ""))
    values = []
    for i in range(data.size()):
        item = data.at(i)
        if not (item.isReal() or item.isInt()):
            raise fail(f"data item {i + 1} is not a number")
        values.append(item.real())
    shape = (rows, cols) if channels == 1 else (rows, cols, channels)
    return np.asarray(values, dtype=float).reshape(shape)


def _matrix(path, fs, key, node, shape=None):
    """A numeric node as a float array (matrix, sequence or number)."""
    if node.isMap():
        a = _opencv_matrix(path, key, node)
    elif node.isSeq():
        vals = []
        for i in range(node.size()):
            item = node.at(i)
            if item.isSeq():
                vals.append([item.at(j).real() for j in range(item.size())])
            else:
                vals.append(item.real())
        a = np.asarray(vals, dtype=float)
    elif node.isReal() or node.isInt():
        a = np.asarray([node.real()], dtype=float)
    else:
        raise InputError(f"{key} is not numeric", file=path, line=_line_of(path, key))
    if not np.all(np.isfinite(a)):
        raise InputError(f"{key} holds NaN or infinity", file=path, line=_line_of(path, key))
    if shape is not None and a.size != int(np.prod(shape)):
        raise InputError(f"{key} has {a.size} elements, expected {int(np.prod(shape))}",
                         file=path, line=_line_of(path, key))
    return a if shape is None else a.reshape(shape)


def _camera(path, fs, kname, knode, dnames, size, name):
    K = _matrix(path, fs, kname, knode, (3, 3))
    dname, dnode = _node(fs, dnames)
    dist = np.zeros(5) if dnode is None else _matrix(path, fs, dname, dnode).ravel()
    try:
        opencv_camera(name, K, dist, size)
    except InputError as exc:
        raise InputError(exc.what, file=path, line=_line_of(path, kname), hint=exc.hint) from None
    return K, dist


def _size(path, fs):
    _, w = _node(fs, ("image_width", "imageWidth"))
    _, h = _node(fs, ("image_height", "imageHeight"))
    if w is not None and h is not None:
        return int(round(w.real())), int(round(h.real()))
    sname, s = _node(fs, ("image_size", "imageSize"))
    if s is not None:
        a = _matrix(path, fs, sname, s).ravel()
        if a.size == 2:
            return int(round(a[0])), int(round(a[1]))
    return None


def _rotation(path, fs, rname, rnode) -> np.ndarray:
    from photogram.geometry import rodrigues_to_matrix
    a = _matrix(path, fs, rname, rnode)
    if a.size == 9:
        R = a.reshape(3, 3)
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise InputError(f"{rname} is not a rotation matrix", file=path,
                             line=_line_of(path, rname))
        return R
    if a.size == 3:
        return rodrigues_to_matrix(a.ravel())
    raise InputError(f"{rname} must be a 3 x 3 rotation or a Rodrigues vector", file=path,
                     line=_line_of(path, rname))


def read_opencv(path, name: str | None = None) -> list[View]:
    """The camera(s) of an OpenCV FileStorage calibration file.

    Without a pose the camera is put at the origin (``R = I``, ``T = 0``)
    and marked ``extra["posed"] = False``.

    Raises
    ------
    InputError
        Unreadable file (with the parser's line), no camera matrix, skew,
        unsupported distortion terms, malformed pose.
    """
    path = Path(path)
    fs = _open(path)
    try:
        base = name or (fs.getNode("camera_name").string() or path.stem)
        size = _size(path, fs)
        if not fs.getNode("M1").empty() and not fs.getNode("M2").empty():
            views = []
            for k, cam in enumerate(("1", "2")):
                K, dist = _camera(path, fs, "M" + cam, fs.getNode("M" + cam), ("D" + cam,),
                                  size, f"{base}_{cam}")
                if k == 0:
                    R, t = np.eye(3), np.zeros(3)
                else:
                    rname, rnode = _node(fs, ("R",))
                    tname, tnode = _node(fs, ("T",))
                    if rnode is None or tnode is None:
                        raise InputError("stereo file without R and T", file=path)
                    R = _rotation(path, fs, rname, rnode)
                    t = _matrix(path, fs, tname, tnode, (3,))
                views.append(View(name=f"{base}_{cam}", camera=f"{base}_{cam}", K=K, dist=dist,
                                  R_cv=R, t_cv=t, image_size=size, extra={"posed": True}))
            return views
        kname, knode = _node(fs, _K)
        if knode is None:
            raise InputError("no camera matrix in the file", file=path, line=1,
                             hint=f"expected one of {', '.join(_K)}")
        K, dist = _camera(path, fs, kname, knode, _D, size, base)
        ename, enode = _node(fs, ("extrinsic_parameters",))
        if enode is not None:
            ext = _matrix(path, fs, ename, enode)
            if ext.ndim != 2 or ext.shape[1] != 6:
                raise InputError("extrinsic_parameters must have 6 columns (rvec, tvec)",
                                 file=path, line=_line_of(path, ename))
            from photogram.geometry import rodrigues_to_matrix
            return [View(name=f"{base}_{i + 1}", camera=base, K=K, dist=dist,
                         R_cv=rodrigues_to_matrix(row[:3]), t_cv=row[3:].copy(),
                         image_size=size, extra={"posed": True}) for i, row in enumerate(ext)]
        rname, rnode = _node(fs, _R)
        tname, tnode = _node(fs, _T)
        if (rnode is None) != (tnode is None):
            missing = "a translation (T or tvec)" if tnode is None else "a rotation (R or rvec)"
            raise InputError(f"the pose has no {missing}", file=path,
                             line=_line_of(path, rname or tname))
        posed = rnode is not None
        R = _rotation(path, fs, rname, rnode) if posed else np.eye(3)
        t = _matrix(path, fs, tname, tnode, (3,)) if posed else np.zeros(3)
        return [View(name=base, camera=base, K=K, dist=dist, R_cv=R, t_cv=t, image_size=size,
                     extra={"posed": posed})]
    finally:
        fs.release()


def opencv_project(path, name: str | None = None):
    """Import an OpenCV calibration file as a project (one ``opencv``
    camera; one station per pose; without a pose one station at the origin,
    whose orientation is left unknown)."""
    from photogram.io.pose2sim import views_project
    path = Path(path)
    views = read_opencv(path)
    project = views_project(views, name or path.stem, source=str(path))
    for i, v in enumerate(views):
        if not v.extra.get("posed", True):
            project.stations.position[i] = np.nan
            project.stations.angles[i] = np.nan
    return project


def format_opencv(view: View, extension: str = ".yml") -> str:
    """The FileStorage text of one view (``extension`` picks YAML/XML/JSON)."""
    import cv2
    from photogram.geometry import matrix_to_rodrigues
    if extension not in EXTENSIONS:
        raise InputError(f"unknown FileStorage extension {extension!r}",
                         hint=f"use one of {', '.join(EXTENSIONS)}")
    fs = cv2.FileStorage(extension, cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    fs.write("camera_name", view.name)
    if view.image_size is not None:
        fs.write("image_width", int(view.image_size[0]))
        fs.write("image_height", int(view.image_size[1]))
    fs.write("camera_matrix", np.asarray(view.K, float))
    fs.write("distortion_coefficients", np.asarray(view.dist, float).reshape(1, -1))
    fs.write("R", np.asarray(view.R_cv, float))
    fs.write("rvec", matrix_to_rodrigues(view.R_cv).reshape(3, 1))
    fs.write("T", np.asarray(view.t_cv, float).reshape(3, 1))
    return fs.releaseAndGetString()


def write_opencv(path, views: list[View], *, force: bool = False) -> list[Path]:
    """Write views as FileStorage files (atomically; no replacing unless
    ``force``). One view: ``path`` is the file. Several: ``path`` is a
    folder (created), one ``<station>.yml`` per view (or the extension of
    ``path`` if it has one of .yml/.yaml/.xml/.json)."""
    from photogram.io.exchange import write_new_text
    path = Path(path)
    ext = path.suffix.lower() if path.suffix.lower() in EXTENSIONS else ".yml"
    if len(views) == 1 and path.suffix.lower() in EXTENSIONS:
        return [write_new_text(path, format_opencv(views[0], ext), force)]
    folder = path.with_suffix("") if path.suffix.lower() in EXTENSIONS else path
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    from photogram.project.safe_names import safe_names
    targets = [folder / f"{stem}{ext}"
               for stem in safe_names([v.name for v in views], default="camera")]
    if not force:
        for t in targets:
            if t.exists():
                raise InputError("file exists", file=t, hint="pass --force to replace it")
    for v, t in zip(views, targets):
        out.append(write_new_text(t, format_opencv(v, ext), force))
    return out
