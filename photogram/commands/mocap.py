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
    caller's level also to the usual handlers."""

    def __init__(self, stream, threshold: int):
        super().__init__(logging.DEBUG)
        self.stream, self.threshold = stream, threshold
        self.setFormatter(logging.Formatter("%(message)s"))

    def emit(self, record):
        self.stream.write(self.format(record) + "\n")
        if record.levelno >= self.threshold:
            logging.getLogger().handle(record)


def mocap(project, output: str | Path | None = None):
    """Run the pipeline on ``project`` and write its results folder.

    Returns
    -------
    (Path, MocapResult)
    """
    if getattr(project, "mocap", None) is None:
        raise InputError("this project has no [mocap] section", file=project.path,
                         hint="a motion-capture project needs [mocap] and [mocap.source]; "
                              "see docs/mocap.md")
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
            result = _run_into(project, stage.path)
        finally:
            project.output.folder = str(final)
    return final, result


def _run_into(project, folder):
    """The pipeline, its results files and report in ``folder``."""
    from photogram.mocap.outputs import write_outputs
    from photogram.mocap.pipeline import run_mocap
    stream = io.StringIO()
    logger = logging.getLogger("photogram.mocap")
    tee = _Tee(stream, logger.getEffectiveLevel())
    saved = logger.level, logger.propagate
    logger.addHandler(tee)
    logger.setLevel(logging.DEBUG)
    logger.propagate = False
    t0 = time.perf_counter()
    try:
        logger.info("photogram mocap %s", project.path)
        result = run_mocap(project)
        logger.info("done in %.1f s", time.perf_counter() - t0)
    finally:
        logger.removeHandler(tee)
        logger.setLevel(saved[0])
        logger.propagate = saved[1]
    write_outputs(result, project, folder, stream.getvalue())
    from photogram.report import write_report
    write_report(folder)                  # report.pdf, as every command
    import shutil

    from photogram.project.output_policy import PARTIAL
    shutil.rmtree(folder / PARTIAL, ignore_errors=True)   # the run is complete
    return result


def run(project, args=None) -> int:
    """Command-line entry: run, write, print one line."""
    folder, result = mocap(project)
    if not getattr(args, "quiet", False):
        rec = result.reconstruction
        rp = [v["median_px"] for v in result.reprojection.values() if v["median_px"] is not None]
        text = (f"mocap: {len(result.frames)} frames x {result.cameras.n_cameras} cameras x "
                f"{result.skeleton.n_joints} joints ({result.skeleton.name}), {rec.solver} "
                f"{rec.seconds:.1f} s, median reprojection error "
                f"{min(rp):.1f}-{max(rp):.1f} px" if rp else "")
        if result.accuracy is not None:
            text += f", MPJPE {100 * result.accuracy['mpjpe']:.1f} cm vs truth"
        print(f"{text}; results in {folder}")
    return 0
