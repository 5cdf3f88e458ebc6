"""A copy of projects/lab with its photographs measured, as `make demo` does
it: `photogram measure frame.toml` (-> results-measure/image_points.csv, the
observations lab.prj reads), optionally followed by `photogram calibrate
lab.prj` (-> results/, whose cameras.toml and covariance.npz the field and
jumps projects read)."""

from __future__ import annotations

import contextlib
import io
import shutil
from pathlib import Path

LAB = Path(__file__).resolve().parents[1] / "projects" / "lab"


def measure_lab(folder: Path) -> Path:
    """Measure the photographs of the lab copy in ``folder`` into its
    results-measure/ (no drawings); returns the image points table."""
    from photogram_cli.main import main
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = main(["measure", str(Path(folder) / "frame.toml"), "-q", "--no-report"])
    if code != 0:
        raise RuntimeError(f"photogram measure {folder}/frame.toml failed ({code})")
    return Path(folder) / "results-measure" / "image_points.csv"


def stage_lab(dest: Path, *, calibrate: bool = False, report: bool = False) -> Path:
    """Copy projects/lab (without results folders) to ``dest`` and measure
    it (and calibrate it; its report.pdf only with ``report``: the report
    costs more CPU than the adjustment); returns ``dest``."""
    dest = Path(dest)
    shutil.copytree(LAB, dest, ignore=shutil.ignore_patterns("results", "results-*", ".*"))
    measure_lab(dest)
    if calibrate:
        from photogram_cli.main import main
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            code = main(["calibrate", str(dest / "lab.prj"), "-q",
                         *([] if report else ["--no-report"])])
        if code != 0:
            raise RuntimeError(f"photogram calibrate {dest}/lab.prj failed ({code})")
    return dest
