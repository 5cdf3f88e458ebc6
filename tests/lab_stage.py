"""A copy of projects/lab with its photographs measured, as `make demo` does
it: `photogram measure frame.toml` (-> results-measure/image_points.csv, the
observations lab.prj reads), optionally followed by `photogram calibrate
lab.prj` (-> results/, whose cameras.toml and covariance.npz the field and
jumps projects read)."""

from __future__ import annotations

import contextlib
import io
import json
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


def stage_lab(dest: Path, *, calibrate: bool = False, report: bool = False,
              measured_copy: bool = False) -> Path:
    """Copy projects/lab (without results folders) to ``dest`` and measure
    it (and calibrate it; its report.pdf only with ``report``: the report
    costs more CPU than the adjustment); returns ``dest``. With
    ``measured_copy`` the measurement is the session's
    (:func:`copy_measured_lab`): for callers that do not test the
    measurement itself."""
    dest = Path(dest)
    if measured_copy:
        copy_measured_lab(dest)
    else:
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


_MEASURED: dict = {}


def copy_measured_lab(dest: Path) -> Path:
    """What :func:`stage_lab` ``(dest)`` gives (a copy of projects/lab with
    its photographs measured), the measurement made once per test session
    and copied: for tests that need the measured lab as their input and do
    not test the measurement (measuring costs ~1.3 s CPU). Its
    ``results-measure/summary.json`` names ``dest``'s frame.toml, as a
    measurement there would; returns ``dest``."""
    if "lab" not in _MEASURED:
        import atexit
        import tempfile
        top = Path(tempfile.mkdtemp(prefix="lab-measured-"))
        atexit.register(shutil.rmtree, top, ignore_errors=True)
        _MEASURED["lab"] = stage_lab(top / "lab")
    dest = Path(dest)
    shutil.copytree(_MEASURED["lab"], dest)
    summary = dest / "results-measure" / "summary.json"
    data = json.loads(summary.read_text(encoding="utf-8"))
    data["field"] = str(dest / "frame.toml")
    summary.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    return dest
