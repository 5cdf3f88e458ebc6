"""The HTTP server of ``photogram measure --serve``.

Built on the standard library's :class:`http.server.ThreadingHTTPServer`:
the page needs a handful of JSON endpoints and static files for one user
on one machine, which the standard library serves without adding a
dependency (a web framework would bring its own release cycle and
security advisories for no feature used here). One thread per request;
the session serialises edits with its own lock.

Security (docs/measure-serve.md):

* bound to 127.0.0.1 only;
* every ``/api/`` request must carry the random token of the printed URL,
  as the header ``X-Photogram-Token`` (or ``?token=`` for images), compared
  in constant time; otherwise 403;
* the ``Host`` header must be ``127.0.0.1:PORT`` or ``localhost:PORT``
  (a DNS-rebinding page from elsewhere gets 403);
* no file name from a request is used as a path: views are ids from the
  server's list, static files a fixed set read from the package.

Errors are JSON ``{"error": one line}`` with status 400/403/404/409; the
server logs one line per error, never a traceback to the client.
"""

from __future__ import annotations

import hmac
import json
import logging
import math
import secrets
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

from photogram.errors import PhotogramError
from photogram.serve.api import ROUTES, ApiError
from photogram.serve.table import BadEdit

__all__ = ["make_server", "Handler", "STATIC"]

log = logging.getLogger("photogram")

STATIC = Path(__file__).resolve().parent / "static"
_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
          ".css": "text/css; charset=utf-8", ".svg": "image/svg+xml", ".png": "image/png",
          ".ico": "image/x-icon"}
_MAX_BODY = 1 << 20


def static_files() -> dict[str, Path]:
    """The files served under /static/ (and / = index.html): the package's
    static folder, by name, read when the server starts."""
    if not STATIC.is_dir():
        return {}
    return {p.name: p for p in STATIC.iterdir() if p.is_file() and p.suffix in _TYPES}


def _finite(obj):
    """``obj`` with NaN and infinities as null (JSON has no NaN)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


class Handler(BaseHTTPRequestHandler):
    """Request handler: checks, routing, JSON answers (module doc)."""

    server_version = "photogram-serve"
    sys_version = ""
    protocol_version = "HTTP/1.1"

    # -------------------------------------------------------------- plumbing
    def log_message(self, format, *args):          # noqa: A002 (the base class's name)
        log.debug("measure --serve: " + format, *args)

    def _send(self, status: int, body: bytes, ctype: str, extra: dict | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        for k, v in (extra or {}).items():
            self.send_header(k, v)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, status: int, obj) -> None:
        self._send(status, json.dumps(_finite(obj), allow_nan=False).encode("utf-8"),
                   "application/json; charset=utf-8")

    def _error(self, status: int, message: str) -> None:
        message = " ".join(str(message).split())
        log.warning("measure --serve: %s %s -> %d %s", self.command,
                    urlsplit(self.path).path, status, message)
        self._json(status, {"error": message})

    def _host_ok(self) -> bool:
        port = self.server.server_address[1]
        return self.headers.get("Host", "") in (f"127.0.0.1:{port}", f"localhost:{port}")

    def _token_ok(self, query: dict) -> bool:
        given = self.headers.get("X-Photogram-Token") or (query.get("token") or [""])[0]
        return hmac.compare_digest(given.encode("utf-8", "replace"),
                                   self.server.token.encode("utf-8"))

    def _raw(self) -> bytes:
        """The request body (read before any check, so the connection stays
        in step)."""
        try:
            n = int(self.headers.get("Content-Length") or 0)
        except ValueError:
            raise ApiError(400, "bad Content-Length") from None
        if n > _MAX_BODY:
            self.close_connection = True
            raise ApiError(400, "request body too large")
        return self.rfile.read(n) if n > 0 else b""

    @staticmethod
    def _parse(raw: bytes) -> dict:
        raw = raw or b"{}"
        try:
            data = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, ValueError):
            raise ApiError(400, "the request body is not JSON") from None
        if not isinstance(data, dict):
            raise ApiError(400, "the request body must be a JSON object")
        return data

    # -------------------------------------------------------------- dispatch
    def do_GET(self):
        self._dispatch("GET")

    def do_POST(self):
        self._dispatch("POST")

    def _dispatch(self, method: str) -> None:
        url = urlsplit(self.path)
        query = parse_qs(url.query)
        try:
            raw = self._raw() if method == "POST" else b""
            if not self._host_ok():
                raise ApiError(403, "wrong Host header (only 127.0.0.1 or localhost)")
            if not url.path.startswith("/api/"):
                if method != "GET":
                    raise ApiError(404, f"no such page {url.path}")
                return self._static(url.path)
            if not self._token_ok(query):
                raise ApiError(403, "missing or wrong token: open the URL that "
                                    "photogram measure --serve printed")
            body = self._parse(raw) if method == "POST" else {}
            route = self.server.routes.get((method, url.path))
            if route is None:
                raise ApiError(404, f"no endpoint {method} {url.path}")
            result = route(self.server.session, {k: v[0] for k, v in query.items()}, body)
            if isinstance(result, tuple):       # (bytes, content type)
                return self._send(200, result[0], result[1])
            return self._json(200, result)
        except ApiError as exc:
            return self._error(exc.status, str(exc))
        except BadEdit as exc:          # (NotSaved: 409)
            return self._error(getattr(exc, "status", 400), str(exc))
        except PhotogramError as exc:
            return self._error(400, exc.one_line())
        except Exception as exc:       # a bug: one line to the log and the client
            log.exception("measure --serve: internal error")
            return self._error(500, f"internal error: {type(exc).__name__}: {exc}")

    def _static(self, path: str) -> None:
        files = self.server.static
        name = "index.html" if path in ("/", "/index.html") else \
            path[len("/static/"):] if path.startswith("/static/") else None
        if name is None or name not in files:
            raise ApiError(404, f"no such page {path}")
        p = files[name]
        self._send(200, p.read_bytes(), _TYPES[p.suffix])


def make_server(session, port: int = 0, token: str | None = None):
    """A :class:`ThreadingHTTPServer` on 127.0.0.1:``port`` (0: a free port)
    over ``session``, with the API routes; ``server.token`` is the token
    (random unless given), ``server.url`` the URL to open."""
    server = ThreadingHTTPServer(("127.0.0.1", int(port)), Handler)
    server.daemon_threads = True
    server.session = session
    server.token = token or secrets.token_urlsafe(24)
    server.routes = ROUTES
    server.static = static_files()
    server.url = f"http://127.0.0.1:{server.server_address[1]}/?token={server.token}"
    return server
