"""The JSON endpoints of ``photogram measure --serve`` (the contract of
docs/measure-serve.md): each a function ``(session, query, body)`` that
returns a JSON-able dict, or ``(bytes, content type)`` for an image. Bad
requests raise :class:`~photogram.serve.server.ApiError` or
:class:`~photogram.serve.table.BadEdit` (HTTP 400 with one line).
"""

from __future__ import annotations

from photogram.errors import PhotogramError
from photogram.serve.table import BadEdit

__all__ = ["ROUTES", "ApiError"]


class ApiError(Exception):
    """An error answered as JSON ``{"error": message}`` with an HTTP status."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


def _number(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise BadEdit(f"{name} must be a number, not {value!r}") from None
    if v != v or abs(v) > 1e7:
        raise BadEdit(f"{name} out of range: {value!r}")
    return v


def project(session, query, body):
    """GET /api/project."""
    return session.body()


def image(session, query, body):
    """GET /api/image?view=ID: PNG of the full-resolution image (404 if
    unreadable)."""
    view = session.view(query.get("view"))
    try:
        return session.images.png(view.id), "image/png"
    except PhotogramError as exc:
        raise ApiError(404, exc.one_line()) from None


def edit(session, query, body):
    """POST /api/edit."""
    return session.edit(body)


def undo(session, query, body):
    """POST /api/undo."""
    return session.undo()


def save(session, query, body):
    """POST /api/save."""
    return session.save()


def refine(session, query, body):
    """POST /api/refine {"view", "x", "y", "point"}."""
    from photogram.serve.refine import refine_click
    view = session.view(body.get("view"))
    x, y = _number(body.get("x"), "x"), _number(body.get("y"), "y")
    return refine_click(session, view, x, y, body.get("point"))


def epipolar(session, query, body):
    """GET /api/epipolar?view=ID&x=..&y=.. | ?oid=N | ?view=ID&point=P."""
    from photogram.serve.epipolar import epipolar_help
    if query.get("oid") is not None:
        from photogram.serve.session import parse_oid
        return epipolar_help(session, oid=parse_oid(query["oid"]))
    view = session.view(query.get("view"))
    if query.get("x") is not None or query.get("y") is not None:
        xy = (_number(query.get("x"), "x"), _number(query.get("y"), "y"))
        return epipolar_help(session, view=view, xy=xy, point=query.get("point"))
    if query.get("point"):
        return epipolar_help(session, view=view, point=query["point"])
    raise BadEdit("give oid, or view with x and y, or view with point")


def predict_line(session, query, body):
    """GET /api/predict_line?exposure=E&line=L."""
    from photogram.serve.epipolar import predicted_line
    if not query.get("line"):
        raise BadEdit("give line=NAME")
    return predicted_line(session, query.get("exposure") or "", query["line"])


def run(session, query, body):
    """POST /api/run {"command"}."""
    from photogram.serve.run import run_command
    return run_command(session, body.get("command"))


ROUTES = {("GET", "/api/project"): project, ("GET", "/api/image"): image,
          ("POST", "/api/edit"): edit, ("POST", "/api/undo"): undo,
          ("POST", "/api/save"): save, ("POST", "/api/refine"): refine,
          ("GET", "/api/epipolar"): epipolar, ("GET", "/api/predict_line"): predict_line,
          ("POST", "/api/run"): run}
