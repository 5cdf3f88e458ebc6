"""``photogram measure --serve PROJECT``: a local web page to inspect,
correct and add image measurements, with epipolar help (issue 24;
docs/measure-serve.md).

Modules: :mod:`~photogram.serve.session` (the project being edited, its
lock), :mod:`~photogram.serve.table` (the editable table, undo, numbered
backups, atomic save), :mod:`~photogram.serve.sources` (images and video
frames), :mod:`~photogram.serve.results` (orientation, sigma0 and residuals
of the results folder), :mod:`~photogram.serve.refine` (the subpixel
detector at a click), :mod:`~photogram.serve.epipolar` (epipolar curves,
predicted points and ski lines), :mod:`~photogram.serve.run` (orient,
calibrate, intersect in a subprocess), :mod:`~photogram.serve.server` and
:mod:`~photogram.serve.api` (HTTP, standard library only).
"""

from __future__ import annotations

import contextlib

__all__ = ["serve"]


@contextlib.contextmanager
def _stop_on_sigterm():
    """SIGTERM (a service manager, ``kill``) stops the server as Ctrl+C
    does (exit 0, lock released); only in the main thread, restored after."""
    import signal
    import threading
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum, frame):
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def serve(project, *, field=None, images=None, port: int = 0, open_browser: bool = False,
          announce=print, run_argv=None) -> int:
    """Serve the page for ``project`` until interrupted (Ctrl+C or SIGTERM);
    returns 0.

    Parameters
    ----------
    project : Path
        The .prj file (or its folder).
    field, images : Path, optional
        See :class:`photogram.serve.session.Session`.
    port : int
        0: a free port chosen by the operating system.
    open_browser : bool
        Open the URL in the default browser.
    announce : callable
        Receives the one line with the URL.
    run_argv : list of str, optional
        How to run a photogram command (the run button), e.g.
        ``[sys.executable, "-m", FRONT_END]``; None: the button answers 400.

    Raises
    ------
    InputError
        Bad input or another editor on the project (one line).
    """
    from photogram.serve.server import make_server
    from photogram.serve.session import Session
    session = Session(project, field=field, images=images, run_argv=run_argv)
    try:
        server = make_server(session, port)
        try:
            announce(f"measure --serve: {server.url} (Ctrl+C to stop)")
            if open_browser:
                import webbrowser
                webbrowser.open(server.url)
            with _stop_on_sigterm():
                try:
                    server.serve_forever()
                except KeyboardInterrupt:
                    pass
        finally:
            server.server_close()
            if session.dirty:
                import logging
                logging.getLogger("photogram").warning(
                    "measure --serve: stopped with unsaved edits; %s holds the last save",
                    session.points_table.path)
    finally:
        session.close()
    return 0
