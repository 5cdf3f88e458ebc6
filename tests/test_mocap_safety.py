"""Issue 16, items 18 and 22: a project's plugin module is imported only with
``--allow-plugin`` (and the import is announced); mocap errors are one line."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.mocap.sources.plugin import load_function
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

MODULE = "untrusted_net_i16"          # a name no other test imports

NETWORK = '''
from pathlib import Path
import numpy as np

Path(__file__).with_name("IMPORTED").write_text("the module's code ran")


def detect(image):
    ys, xs = np.nonzero(image[..., 0] > 128)
    if len(xs) == 0:
        return None
    j = np.zeros((17, 3))
    j[:, 0] = np.linspace(xs.min(), xs.max(), 17)
    j[:, 1] = np.linspace(ys.min(), ys.max(), 17)
    j[:, 2] = 0.9
    return j
'''


def _plugin_project(folder: Path) -> Path:
    import cv2
    (folder / f"{MODULE}.py").write_text(NETWORK)
    for cam in ("A", "B"):
        (folder / cam).mkdir()
        for f in range(6):
            img = np.zeros((120, 160, 3), np.uint8)
            x = 40 + 4 * f + (10 if cam == "B" else 0)
            img[30:90, x:x + 20] = 255
            cv2.imwrite(str(folder / cam / f"{f:03d}.png"), img)
    (folder / "stations.csv").write_text(
        "station,camera,X0,Y0,Z0,omega,phi,kappa\nA,A,0,-10,1,90,0,0\nB,B,3,-10,1,90,10,0\n")
    cams = "".join(f'[cameras.{c}]\nmodel = "opencv"\nimage_size = [160, 120]\nfx = 200.0\n'
                   f'fy = 200.0\ncx = 80.0\ncy = 60.0\n\n' for c in "AB")
    prj = folder / "p.prj"
    prj.write_text('[project]\nname = "p"\n\n' + cams + '[stations]\nfile = "stations.csv"\n\n'
                   '[mocap]\nfps = 25\n\n[mocap.source]\nkind = "plugin"\n'
                   f'network = "{MODULE}:detect"\nskeleton = "coco17"\n'
                   'cameras = { A = "A", B = "B" }\n\n'
                   '[mocap.tracking]\ncrop_size = 64\nsigma_centre = 2\nsigma_side = 4\n')
    return prj


def test_plugin_module_is_not_imported_without_allow_plugin(tmp_path, capsys, caplog):
    """A downloaded project with ``kind = "plugin"`` must not run its module:
    exit 2, one line at the line of ``network`` naming the module and the
    opt-in; the module's code has not run and no results are written. With
    ``--allow-plugin`` it runs, and which module (from which file) is logged
    before the import."""
    prj = _plugin_project(tmp_path)
    marker = tmp_path / "IMPORTED"
    sys.modules.pop(MODULE, None)
    assert main(["mocap", "--no-report", str(prj)]) == 2
    out, err = capsys.readouterr()
    assert err.splitlines() == [err.strip()]
    line = prj.read_text().splitlines().index(f'network = "{MODULE}:detect"') + 1
    assert err.startswith(f"{prj}:{line}: network '{MODULE}:detect'")
    assert f"module '{MODULE}'" in err and "--allow-plugin" in err
    assert not marker.exists() and MODULE not in sys.modules
    assert not (tmp_path / "results").exists()
    # the library refuses as well, whoever calls it
    with pytest.raises(InputError, match="--allow-plugin"):
        load_function(f"{MODULE}:detect", tmp_path)
    assert not marker.exists()
    with pytest.raises(InputError, match="not of the form"):     # not a TypeError
        load_function(f".{MODULE}:detect", tmp_path, allow=True)
    # with the opt-in: imported, announced with its file
    caplog.set_level(logging.INFO)
    assert main(["mocap", "--no-report", "--no-figures", "-q", "--allow-plugin", str(prj)]) == 0
    assert marker.exists()
    notices = [r.getMessage() for r in caplog.records if "importing module" in r.getMessage()]
    assert len(notices) == 1 and str(tmp_path / f"{MODULE}.py") in notices[0]
    assert (tmp_path / "results" / "summary.json").is_file()
    sys.modules.pop(MODULE, None)


def _run(*args, cwd):
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    return subprocess.run([sys.executable, "-m", "photogram_cli", *args], cwd=cwd,
                          capture_output=True, text=True, env=env, timeout=300)


def test_mocap_errors_are_one_line_in_a_real_process(tmp_path):
    """No progress line before the error: the project reads fine, the error
    comes from the pipeline (today's main printed ``photogram mocap ...``
    first), also over an earlier run with --force (``replacing the earlier
    run ...``); a successful run still shows its progress."""
    from photogram.simulation.ski.simproject import write_simulated_project
    from photogram.simulation.ski.simulate import simulate_session
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=20)
    write_simulated_project(sim, tmp_path / "p", name="ski")
    prj = tmp_path / "p" / "ski.prj"
    ok = _run("mocap", "--no-report", "--no-figures", "p/ski.prj", cwd=tmp_path)
    assert ok.returncode == 0, ok.stderr
    assert "reconstruction:" in ok.stderr                  # progress of a good run is shown
    text = prj.read_text()
    text = text.replace("fps = 50\n", "fps = 50\nframes = [500, 600]\n")
    prj.write_text(text)
    line = text.splitlines().index("frames = [500, 600]") + 1
    for extra in (("--force",), ("--output", "new")):
        proc = _run("mocap", "p/ski.prj", *extra, cwd=tmp_path)
        assert proc.returncode == 2
        assert proc.stderr.splitlines() == [
            f"p/ski.prj:{line}: frames [500, 600] select nothing of frames 0..19"], proc.stderr
        assert proc.stdout == ""
