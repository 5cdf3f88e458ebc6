"""Nothing is lost (issue 12, item 4): results folders are not silently
replaced, inputs are never written over, an interrupted mocap run resumes."""

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.project.output_policy import PARTIAL, claim_output
from photogram_cli.main import main

from lab_stage import copy_measured_lab

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]


def test_claim_output_rules(tmp_path):
    out = tmp_path / "results"
    assert claim_output(out, command="calibrate") == "new"
    out.mkdir()
    assert claim_output(out, command="calibrate") == "new"             # empty
    (out / "summary.json").write_text(json.dumps({"command": "calibrate"}))
    with pytest.raises(InputError) as e:
        claim_output(out, command="calibrate")
    line = e.value.one_line()
    assert "earlier run (calibrate of" in line and "--force" in line and str(out) in line
    assert claim_output(out, command="calibrate", force=True) == "replace"
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="not empty"):
        claim_output(other, command="orient")
    assert claim_output(other, command="orient", force=True) == "new"
    with pytest.raises(InputError, match="never writes over its inputs"):
        claim_output(other, command="orient", inputs=[other / "notes.txt"], force=True)
    partial = tmp_path / "mc"
    (partial / "samples").mkdir(parents=True)
    assert claim_output(partial, command="montecarlo", resumable=True) == "resume"
    with pytest.raises(InputError):
        claim_output(partial, command="calibrate")


def _digest(folder: Path) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_calibrate_twice_needs_force_and_inputs_stay(tmp_path, capsys):
    prj = copy_measured_lab(tmp_path / "lab")    # copied and measured (its input)
    before = _digest(prj)
    assert main(["calibrate", "--no-report", str(prj / "lab.prj"), "-q"]) == 0
    first = (prj / "results" / "summary.json").read_bytes()
    capsys.readouterr()
    assert main(["calibrate", "--no-report", str(prj / "lab.prj"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "earlier run" in err[0] and "--force" in err[0], err
    assert (prj / "results" / "summary.json").read_bytes() == first      # untouched
    assert main(["calibrate", "--no-report", str(prj / "lab.prj"), "-q", "--force"]) == 0
    # the inputs are byte for byte what they were (beside them: the empty lock
    # file of the results folder, photogram.project.results_folder)
    after = {k: v for k, v in _digest(prj).items() if k.split("/")[0] != "results"}
    assert after.pop(".results.lock") == hashlib.sha256(b"").hexdigest()
    assert after == before
    # results written into the project folder itself would overwrite inputs: refused
    capsys.readouterr()
    assert main(["calibrate", "--no-report", str(prj / "lab.prj"), "-q", "--force", "--output", str(prj)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "never writes over its inputs" in err[0], err
    assert {k: v for k, v in _digest(prj).items()
            if k.split("/")[0] != "results" and k != ".results.lock"} == before


def test_interrupted_mocap_resumes_with_the_next_camera(tmp_path, monkeypatch):
    """An interrupted `photogram mocap` with images keeps every camera's
    rotation differences measured so far and resumes with the next one."""
    from photogram.mocap.motion import homography
    from photogram.simulation.ski.render import render_camera, write_video
    from photogram.simulation.ski.scene import build_scene
    from photogram.simulation.ski.simproject import write_estimate_project, write_simulated_project
    from photogram.simulation.ski.simulate import simulate_session
    # 12 frames (30 before issue 23 item 6): resuming does not depend on the length
    sim = simulate_session(seed=5, n_runs=1, frames_per_run=12)
    write_simulated_project(sim, tmp_path, name="ski")
    prj = write_estimate_project(sim, tmp_path, name="ski")
    (tmp_path / "video").mkdir()
    scene = build_scene(sim, seed=0)
    lines = ["", "[mocap.images]"]
    for c, name in enumerate(sim.cameras.names):
        write_video(tmp_path / "video" / f"{name}.avi", render_camera(scene, sim, c), 50)
        lines.append(f'{name} = "video/{name}.avi"')
    prj.write_text(prj.read_text().replace(
        'rotation_differences = "rotation_differences.csv"   # measured on rendered images\n',
        "") + "\n".join(lines) + "\n")
    real = homography.rotation_differences
    calls = []

    def interrupted(*args, **kw):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*args, **kw)

    monkeypatch.setattr(homography, "rotation_differences", interrupted)
    out = tmp_path / "results-estimate"
    batch = ["mocap", "--no-report", "--no-figures", str(prj), "-q"]
    assert main(batch) != 0                                    # interrupted
    # the unfinished run waits in the staging folder; no results folder yet
    staging = tmp_path / ".results-estimate.incomplete"
    assert sorted(p.name for p in (staging / PARTIAL / "rotation_differences").iterdir()) == \
        ["C1.npz", "C2.npz"]
    assert not out.exists()
    calls.clear()
    monkeypatch.setattr(homography, "rotation_differences", lambda *a, **k: (calls.append(1),
                                                                            real(*a, **k))[1])
    assert main(batch) == 0                                    # resumed, no --force needed
    assert len(calls) == 4                                     # C3..C6 only
    assert not (out / PARTIAL).exists() and not staging.exists()   # cleaned up when complete
    resumed = (out / "rotations.csv").read_text()
    # the same as a run that was never interrupted
    monkeypatch.setattr(homography, "rotation_differences", real)
    assert main([*batch, "--output", str(tmp_path / "clean")]) == 0
    assert (tmp_path / "clean" / "rotations.csv").read_text() == resumed
    summary = json.loads((out / "summary.json").read_text())
    assert np.isfinite(summary["accuracy"]["mpjpe"])
