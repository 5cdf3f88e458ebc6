"""``photogram mocap PROJECT``: markerless multi-camera motion capture.

The project is a .prj with a ``[mocap]`` section (docs/mocap.md), read and
validated by the common reader. The command tracks the athlete in every
camera, reconstructs the joints (DCT trajectories, robust reprojection
energy, limb prior), computes the metrics and writes the results folder
(:mod:`photogram.mocap.outputs`).
"""

from __future__ import annotations

import io
import logging
import time
from pathlib import Path

from photogram.errors import InputError

__all__ = ["run", "mocap"]


class _Tee(logging.Handler):
    """Every record of photogram.mocap into log.txt; those at or above the
    caller's level also to the usual handlers: at once when ``live`` (``-v``)
    or when the record is marked ``immediate`` (the plugin-import notice),
    otherwise held back and passed on by :meth:`pass_on` once the run has
    succeeded, so that a failing run prints its error as the only line."""

    def __init__(self, stream, threshold: int, live: bool = False):
        super().__init__(logging.DEBUG)
        self.stream, self.threshold, self.live = stream, threshold, live
        self.held = []
        self.setFormatter(logging.Formatter("%(message)s"))

    def emit(self, record):
        self.stream.write(self.format(record) + "\n")
        if record.levelno >= self.threshold:
            if self.live or getattr(record, "immediate", False):
                logging.getLogger().handle(record)
            else:
                self.held.append(record)

    def pass_on(self):
        """Pass the held records on (the run succeeded)."""
        held, self.held = self.held, []
        for record in held:
            logging.getLogger().handle(record)


def mocap(project, output: str | Path | None = None, *, allow_plugin: bool = False,
          live: bool = False, report: bool = True, figures: bool = True):
    """Run the pipeline on ``project`` and write its results folder.

    Parameters
    ----------
    project : Project
        A project with a ``[mocap]`` section.
    output : str or Path, optional
        The results folder (default: ``[output] folder``).
    allow_plugin : bool
        The user's opt-in (``--allow-plugin``) to import the Python module of
        a ``plugin`` source; without it such a project is refused.
    live : bool
        Progress messages at once (``-v``); otherwise they are held back and
        shown when the run has succeeded (a failing run: one error line).
    report : bool
        Write report.pdf (``--no-report``: not; `photogram report` builds it
        later from the folder).
    figures : bool
        Draw the PNG figures of the results folder (``--no-figures``: not,
        for batch runs; summary.json says ``"figures": false`` and the
        report's Run table says they were not drawn).

    Returns
    -------
    (Path, MocapResult)
    """
    if getattr(project, "mocap", None) is None:
        raise InputError("this project has no [mocap] section", file=project.path,
                         hint="a motion-capture project needs [mocap] and [mocap.source]; "
                              "see docs/mocap.md")
    source = project.mocap.source
    if source.kind == "plugin" and not allow_plugin:       # before anything is done
        from photogram.mocap.sources.plugin import refuse_plugin
        exc = refuse_plugin(source.network)
        raise project.mocap.error(("source", "network"), exc.what, hint=exc.hint)
    if output is not None:                # the resumable state goes there too
        project.output.folder = str(Path(output).absolute())
    from photogram.project.output_policy import project_inputs
    from photogram.project.results_folder import staged_results
    final = project.output_folder()
    # the run (and its resumable .partial/) lives in the staging folder until
    # its results are complete (photogram.project.results_folder)
    with staged_results(final, command="mocap", resumable=True,
                        inputs=project_inputs(project)) as stage:
        project.output.folder = str(stage.path)
        try:
            result, tee = _run_into(project, stage.path, allow_plugin, live, report,
                                    figures)
        finally:
            project.output.folder = str(final)
    tee.pass_on()                         # the progress messages, now that nothing failed
    return final, result


def _run_into(project, folder, allow_plugin: bool, live: bool, report: bool = True,
              figures: bool = True):
    """The pipeline, its results files and report in ``folder``; returns the
    result and the handler holding the progress messages back."""
    from photogram.mocap.outputs import write_outputs
    from photogram.mocap.pipeline import run_mocap
    stream = io.StringIO()
    logger = logging.getLogger("photogram.mocap")
    tee = _Tee(stream, logger.getEffectiveLevel(), live)
    saved = logger.level, logger.propagate
    logger.addHandler(tee)
    logger.setLevel(logging.DEBUG)
    logger.propagate = False
    t0 = time.perf_counter()
    try:
        logger.info("photogram mocap %s", project.path)
        result = run_mocap(project, allow_plugin=allow_plugin)
        logger.info("done in %.1f s", time.perf_counter() - t0)
    finally:
        logger.removeHandler(tee)
        logger.setLevel(saved[0])
        logger.propagate = saved[1]
    write_outputs(result, project, folder, stream.getvalue(), figures=figures)
    if report:                            # report.pdf, as every command (not with --no-report)
        from photogram.report import write_report
        write_report(folder)
    import shutil

    from photogram.project.output_policy import PARTIAL
    shutil.rmtree(folder / PARTIAL, ignore_errors=True)   # the run is complete
    return result, tee


def run(project, args=None) -> int:
    """Command-line entry: run, write, print one line."""
    folder, result = mocap(project, allow_plugin=bool(getattr(args, "allow_plugin", False)),
                           live=bool(getattr(args, "verbose", 0)),
                           report=not getattr(args, "no_report", False),
                           figures=not getattr(args, "no_figures", False))
    if not getattr(args, "quiet", False):
        rec = result.reconstruction
        rp = [v["median_px"] for v in result.reprojection.values() if v["median_px"] is not None]
        text = (f"mocap: {len(result.frames)} frames x {result.cameras.n_cameras} cameras x "
                f"{result.skeleton.n_joints} joints ({result.skeleton.name}), {rec.solver} "
                f"{rec.seconds:.1f} s, median reprojection error "
                f"{min(rp):.1f}-{max(rp):.1f} px" if rp else "")
        if result.accuracy is not None:
            text += f", MPJPE {100 * result.accuracy['mpjpe']:.1f} cm vs truth"
        if project.warnings:
            text += f", {len(project.warnings)} warning(s) in summary.json"
        print(f"{text}; results in {folder}")
    return 0
