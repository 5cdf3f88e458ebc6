"""The ``photogram`` command line: argument parsing and dispatch only.

Every subcommand except ``demo`` takes a project path, reads and validates
the project first (so bad input fails the same way everywhere) and then calls
a library function named in :data:`COMMANDS` as ``"module:function"``. The
module is imported lazily; if it (or another photogram module it needs) does
not exist yet, the command reports that its engine is not built yet.

A command function has the signature ``run(project, args) -> int | None``
(``demo``: ``run(args)``), where ``project`` is the validated
:class:`photogram.project.Project` with ``project.output.folder`` already set
from ``--output``, and ``args`` the parsed :class:`argparse.Namespace`.
Registering a new engine is one line in :data:`COMMANDS`.

Exit codes: 0 success, 1 internal error (a bug), 2 user error
(:class:`photogram.errors.PhotogramError`, or an operating-system error such
as a full disk; one line on stderr), 130 interrupted.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
import traceback
import warnings
from dataclasses import dataclass
from pathlib import Path

import photogram
from photogram.errors import NotBuiltError, PhotogramError

__all__ = ["main", "build_parser", "COMMANDS", "Command"]


@dataclass(frozen=True)
class Command:
    """A subcommand: where its function lives and what it needs."""

    target: str                 # "module:function", imported lazily
    engine: str                 # for "the ... is not built yet"
    help: str
    needs_project: bool = True


COMMANDS: dict[str, Command] = {
    "check": Command("photogram_cli.check:run", "the project checker",
                     "read and validate a project and print a summary"),
    "calibrate": Command("photogram.commands.calibrate:run", "the adjustment engine",
                         "bundle adjustment with self-calibration (interior orientation); "
                         "on a board project ([board]) every camera of a rig from a board"),
    "orient": Command("photogram.commands.orient:run", "the adjustment engine",
                      "exterior orientation of the stations with known cameras"),
    "intersect": Command("photogram.commands.intersect:run", "the adjustment engine",
                         "object coordinates of points from oriented stations"),
    "track": Command("photogram.commands.track:run", "the video tracker",
                     "track jumper markers and ski lines in the videos of a jump -> the "
                     "observations of intersect (docs/track.md)"),
    "montecarlo": Command("photogram.commands.montecarlo:run", "the Monte Carlo engine",
                          "precision of the results by Monte Carlo simulation"),
    "simulate": Command("photogram.commands.simulate:run", "the simulator",
                        "synthetic image observations for a planned network",
                        needs_project=False),
    "report": Command("photogram.commands.report:run", "the report generator",
                      "rebuild report.pdf (the accuracy report) of a results folder",
                      needs_project=False),
    "mocap": Command("photogram.commands.mocap:run", "the motion-capture pipeline",
                     "markerless motion capture: track the athlete in every camera, "
                     "reconstruct its joints, metrics (docs/mocap.md)"),
    "measure": Command("photogram.commands.measure:run", "the target measurement",
                       "measure targets in a folder of photographs: detection, subpixel "
                       "centres, codes, numbering -> image_points.csv (docs/measure.md)",
                       needs_project=False),
    "demo": Command("photogram.demo:run", "the demo",
                    "run the built-in demonstration", needs_project=False),
    "import": Command("photogram.commands.convert:run_import", "the importers",
                      "read a DBAT, PhotoModeler, Pose2Sim, OpenCV, COLMAP project or a "
                      "folder of target images into a new project folder",
                      needs_project=False),
    "export": Command("photogram.commands.convert:run_export", "the exporters",
                      "write a results folder as Pose2Sim, OpenCV, COLMAP, PLY, TRC, C3D, "
                      ".mot or CSV", needs_project=False),
}


def _common_options() -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-v", "--verbose", action="count", default=0,
                        help="more messages; on errors also the traceback")
    common.add_argument("-q", "--quiet", action="store_true", help="only errors")
    common.add_argument("--output", metavar="FOLDER", type=Path,
                        help="output folder (default: [output] folder of the project)")
    return common


#: commands that write a results folder (guarded by photogram.project.output_policy)
WRITERS = {"calibrate": False, "orient": False, "intersect": False, "montecarlo": True,
           "mocap": True, "track": False}        # command -> resumable


def _extra_options(name: str, sub: argparse.ArgumentParser) -> None:
    if name in WRITERS:
        sub.add_argument("--force", action="store_true",
                         help="replace the results of an earlier run in the output folder")
    if name in WRITERS and name != "track":
        sub.add_argument("--no-report", action="store_true",
                         help="no report.pdf (build it later with `photogram report FOLDER`)")
    if name == "mocap":
        sub.add_argument("--allow-plugin", action="store_true",
                         help="allow a [mocap.source] of kind \"plugin\" to import and run its "
                              "Python module (code named in the project file; only for "
                              "projects you trust)")
        sub.add_argument("--no-figures", action="store_true",
                         help="no PNG figures in the results folder (batch runs; a report "
                              "then says they were not drawn)")
    if name == "check":
        sub.add_argument("--force", action="store_true",
                         help="with --output: replace existing files")
    if name == "report":
        # optional in the parser, checked by the command (exit 2 with a hint)
        sub.add_argument("folder", nargs="?", type=Path, metavar="RESULTS",
                         help="a results folder (the output folder of calibrate, orient, "
                              "intersect)")
    if name in ("intersect", "report"):
        # checked by the command (one line, exit 2), not by argparse
        sub.add_argument("--units", metavar="UNITS", default=None,
                         help="stick model in the project's units (project) or in deg, m and "
                              "km/h (coach); default: [report] units of the project")
    if name == "simulate":
        # optional in the parser, checked by the command (exit 2 with a hint)
        sub.add_argument("design", nargs="?", type=Path, metavar="DESIGN",
                         help="the network design file (.toml), e.g. "
                              "projects/designs/situation-b.toml")
        sub.add_argument("--force", action="store_true", help="replace existing files")
    if name in ("montecarlo", "simulate"):
        sub.add_argument("--seed", type=int, default=None, help="random seed")
    if name == "montecarlo":
        sub.add_argument("--runs", type=int, default=None,
                         help="number of simulations (default: [montecarlo] runs)")
        sub.add_argument("--workers", type=int, default=None,
                         help="local worker processes (default: [montecarlo] workers, 1)")
        sub.add_argument("--scheduler", metavar="ADDRESS", default=None,
                         help="run on a Dask cluster, e.g. tcp://127.0.0.1:8786")
    if name in ("import", "export"):
        # optional in the parser, checked by the command (exit 2 with a hint)
        sub.add_argument("format", nargs="?", metavar="FORMAT",
                         help="see docs/interoperability.md")
        sub.add_argument("source", nargs="?", type=Path, metavar="SRC" if name == "import"
                         else "RESULTS", help="file or folder to read")
        sub.add_argument("--to", type=Path, metavar="DIR" if name == "import" else "PATH",
                         help="new project folder" if name == "import" else "file to write")
    if name == "import":
        sub.add_argument("--name", help="project name (default: from the source)")
        sub.add_argument("--target", help="images: the target, e.g. chessboard:9x6:0.025")
        sub.add_argument("--model", choices=("opencv", "brown"), default="opencv",
                         help="images: camera model of the calibration project")
        sub.add_argument("--control", type=Path, metavar="FILE",
                         help="pmexport: DBAT control table id,label,x,y,z[,sx,sy,sz]")
        sub.add_argument("--free", metavar="PARAMS",
                         help="pmexport: camera parameters to estimate, 'all' (DBAT's c x0 y0 "
                              "B1 K1 K2 K3 P1 P2) or a list such as c,x0,y0 (default: fixed)")
        sub.add_argument("--image-size", metavar="W,H",
                         help="pmexport: image size in pixels when line 2 lacks it")
    if name == "export":
        sub.add_argument("--force", action="store_true", help="replace existing files")
    if name == "measure":
        # optional in the parser, checked by the command (exit 2 with a hint)
        sub.add_argument("field", nargs="?", type=Path, metavar="FIELD",
                         help="the target-field description (.toml), e.g. "
                              "projects/camcal/sheet.toml")
        sub.add_argument("--images", type=Path, metavar="DIR",
                         help="folder of images (default: images of the field file)")
        sub.add_argument("--force", action="store_true",
                         help="replace the results of an earlier run in the output folder")
        sub.add_argument("--no-eccentricity", action="store_true",
                         help="write the ellipse centres without the eccentricity correction")
        sub.add_argument("--no-report", action="store_true",
                         help="no drawings (images/*.png) and no report.pdf")
        sub.add_argument("--guided", type=Path, metavar="PROJECT",
                         help="after a first measurement (--no-eccentricity): adjust "
                              "PROJECT, predict the missing targets through the adjusted "
                              "cameras, measure them, repeat until nothing new "
                              "(-> results-guided/)")
        sub.add_argument("--serve", type=Path, metavar="PROJECT",
                         help="a local web page to inspect, correct and add the image "
                              "measurements of PROJECT, with epipolar help (docs/measure-serve.md)")
        sub.add_argument("--field", dest="serve_field", type=Path, metavar="FIELD",
                         help="--serve: the target-field description (detector settings, "
                              "eccentricity, images folder)")
        sub.add_argument("--port", type=int, default=0,
                         help="--serve: the port on 127.0.0.1 (default 0: a free one)")
        sub.add_argument("--open-browser", action="store_true",
                         help="--serve: open the page in the default browser")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with one subparser per entry of :data:`COMMANDS`."""
    parser = argparse.ArgumentParser(
        prog="photogram",
        description="Close-range photogrammetry and multi-camera motion capture.")
    parser.add_argument("--version", action="version",
                        version=f"photogram {photogram.__version__}")
    subs = parser.add_subparsers(dest="command", metavar="COMMAND")
    common = _common_options()
    for name, cmd in COMMANDS.items():
        sub = subs.add_parser(name, parents=[common], help=cmd.help, description=cmd.help)
        if cmd.needs_project:
            sub.add_argument("project", type=Path,
                             help="the .prj file (or a folder holding one)")
        _extra_options(name, sub)
    return parser


#: ``photogram measure --serve``: its own function, the same error handling
SERVE = Command("photogram.commands.measure_serve:run", "the measuring page",
                "a local web page over a project's image measurements", needs_project=False)


def load_command(name: str, cmd: Command | None = None):
    """Import the function of subcommand ``name``.

    Raises
    ------
    NotBuiltError
        Its module (or a photogram module it imports) or function is missing.
    PhotogramError
        A third-party package it needs is not installed.
    """
    cmd = cmd or COMMANDS[name]
    module_name, _, attr = cmd.target.partition(":")
    not_built = NotBuiltError(f"photogram {name}: {cmd.engine} is not built yet")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        missing = exc.name or ""
        if missing.split(".")[0] in ("photogram", "photogram_cli"):
            raise not_built from exc
        raise PhotogramError(f"photogram {name}: needs the Python package '{missing}', "
                             f"which is not installed",
                             hint="run `make venv` or `pip install -e .`") from exc
    function = getattr(module, attr, None)
    if function is None:
        raise not_built
    return function


def run_command(args: argparse.Namespace) -> int:
    """Read the project (if any), then call the command's function."""
    cmd = COMMANDS[args.command]
    if getattr(args, "output", None) is not None:
        from photogram.project.limits import check_output_path
        check_output_path(args.output)
    if args.command == "measure" and getattr(args, "serve", None) is not None:
        # the page's run button runs photogram commands as this front end does
        args.run_argv = [sys.executable, "-m", __package__ or "photogram_cli"]
        return int(load_command("measure", SERVE)(args) or 0)
    if not cmd.needs_project:
        return int(load_command(args.command)(args) or 0)
    from photogram.project import read_project

    project = read_project(args.project)
    if args.output is not None and args.command != "check":
        project.output.folder = str(Path(args.output).absolute())
    if args.command not in WRITERS:
        return int(load_command(args.command)(project, args) or 0)
    from photogram.project.limits import check_output_path
    from photogram.project.output_policy import claim_output, project_inputs
    from photogram.project.results_folder import output_lock
    folder = project.output_folder()
    check_output_path(folder, "--output" if args.output is not None else "[output] folder")
    # one run per results folder, from the check to the last file (a second
    # run into the same folder stops with one line)
    with output_lock(folder, command=args.command):
        mode = claim_output(folder, command=args.command, inputs=project_inputs(project),
                            force=args.force, resumable=WRITERS[args.command])
        code = int(load_command(args.command)(project, args) or 0)
        # after the run: an error stays the only line
        if mode == "resume":     # the command itself decided what it could reuse
            logging.getLogger("photogram").info(
                "continued the unfinished run in %s (its finished parts are reused only "
                "where the inputs are unchanged)", folder)
        elif mode != "new":
            logging.getLogger("photogram").info("replaced the earlier run in %s", folder)
        return code


def _setup_logging(args: argparse.Namespace) -> None:
    level = logging.WARNING if args.quiet else \
        logging.DEBUG if args.verbose > 1 else logging.INFO
    logging.basicConfig(level=level, format="%(message)s", stream=sys.stderr)


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _input_of(args: argparse.Namespace) -> str:
    """The input a command was given (for the last-resort messages)."""
    for name in ("project", "folder", "source", "design"):
        value = getattr(args, name, None)
        if value is not None:
            return str(value)
    return f"photogram {args.command}"


def _last_resort(exc: BaseException, args: argparse.Namespace) -> str | None:
    """One line for a failure that bad input causes but that no reader
    caught at its source (docs/reliability.md, issue 16 item 21), or None
    for a bug."""
    if isinstance(exc, MemoryError):
        return (f"{_input_of(args)}: photogram {args.command} ran out of memory reading or "
                f"processing this input (is a file far larger than it should be?)")
    if isinstance(exc, RecursionError):
        return (f"{_input_of(args)}: photogram {args.command}: an input file is nested too "
                f"deeply (damaged or not a photogram file)")
    if isinstance(exc, PermissionError) and exc.filename:
        return (f"{exc.filename}: permission denied (photogram {args.command} needs to read "
                f"the file, or to search and write the folder: check its permissions)")
    return None


_PARSERS: dict = {}


def _parser() -> argparse.ArgumentParser:
    """:func:`build_parser`, built once per content of :data:`COMMANDS`
    (parsing does not change a parser; a program or test that runs many
    commands in one process saves about 4 ms a call)."""
    key = tuple(COMMANDS.items())
    if key not in _PARSERS:
        _PARSERS.clear()
        _PARSERS[key] = build_parser()
    return _PARSERS[key]


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``photogram`` console script; returns the exit code."""
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    verbose = args.verbose
    if not verbose:
        # numeric warnings of a failing network must not add lines to the
        # one-line error; -v shows them
        warnings.simplefilter("ignore", RuntimeWarning)
    try:
        _setup_logging(args)
        return run_command(args)
    except PhotogramError as exc:
        if verbose:
            traceback.print_exc()
        print(exc.one_line(), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"photogram {args.command}: interrupted", file=sys.stderr)
        return 130
    except (MemoryError, RecursionError, OSError) as exc:
        message = _last_resort(exc, args)
        if verbose:
            traceback.print_exc()
        if message is None and isinstance(exc, OSError):
            # a full disk, a lost permission: not a bug, one line
            where = f"{exc.filename}: " if exc.filename else ""
            message = (f"{where}cannot write or read: {exc.strerror or exc} (free disk "
                       f"space or check the permissions, then run the command again; "
                       f"results are only moved into place when complete)")
        print(_one_line(message), file=sys.stderr)
        return 2
    except Exception as exc:  # anything else is a bug
        if verbose:
            traceback.print_exc()
        print(_one_line(f"internal error: {type(exc).__name__}: {exc} "
                        f"(please report; rerun with -v for the traceback)"), file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
