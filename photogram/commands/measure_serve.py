"""`photogram measure --serve PROJECT`: the measuring page (photogram.serve,
docs/measure-serve.md); argument handling only."""

from __future__ import annotations

from photogram.errors import InputError

__all__ = ["run"]


def run(args) -> int:
    """Command-line entry (``photogram measure --serve PROJECT [--field FIELD]
    [--images DIR] [--port N] [--open-browser]``)."""
    from photogram.serve import serve
    port = getattr(args, "port", 0) or 0
    if not 0 <= port <= 65535:
        raise InputError(f"--port {port}: give 0 (a free port) or a port 1-65535")
    field = getattr(args, "serve_field", None) or getattr(args, "field", None)
    return serve(args.serve, field=field, images=getattr(args, "images", None), port=port,
                 open_browser=bool(getattr(args, "open_browser", False)),
                 announce=lambda line: print(line, flush=True),
                 run_argv=getattr(args, "run_argv", None))
