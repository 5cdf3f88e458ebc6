"""photogram montecarlo gives honest, current numbers (issue 16, items 1, 3,
17 and the Monte-Carlo/simulate part of 21).

* Finished runs are reused only when every input file (by content), every
  setting the runs depend on and the program are the same; ``--force`` and
  ``make demo`` replacing its results always compute again.
* ``sigma_cmd`` is what ``photogram orient`` and ``photogram intersect``
  write for the same inputs.
* A project file cannot name a Dask cluster.
* Absurd run or exposure counts are refused at once with one line.
"""

from __future__ import annotations

import json
import logging
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from photogram.errors import InputError
from photogram.project import read_project
from test_montecarlo import _network

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]


def _chain(folder, runs=40, chunk=10, seed=7, extra=""):
    path = folder / "mc.prj"
    path.write_text(textwrap.dedent(f"""\
        [project]
        name = "mc"

        [montecarlo]
        orient = "net.prj"
        perturb = ["image", "reference"]
        points = ["P*"]
        runs = {runs}
        seed = {seed}
        chunk = {chunk}
        {extra}

        [output]
        folder = "out"
        """), encoding="utf-8")
    return path


@pytest.fixture
def net(tmp_path):
    """A fresh copy of the small network (the tests edit its files)."""
    _network(tmp_path / "net")
    return tmp_path / "net"


def _run(path, output, **kw):
    from photogram.montecarlo import run_montecarlo
    return run_montecarlo(read_project(path), output=output, progress=False, **kw)


def _samples(folder):
    return pd.read_csv(folder / "samples.csv")


def _edit_control_point(net, delta=0.002):
    """Move reference point P1 by ``delta`` in X (2 of its sigmas)."""
    path = net / "net_points.csv"
    lines = path.read_text(encoding="utf-8").splitlines()
    cells = lines[1].split(",")
    assert cells[0] == "P1" and cells[1] == "control"
    cells[2] = repr(float(cells[2]) + delta)
    lines[1] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _edit_sigma_image(net, value="0.6"):
    path = net / "net.prj"
    text = path.read_text(encoding="utf-8")
    assert "sigma_image = 0.3\n" in text
    path.write_text(text.replace("sigma_image = 0.3\n", f"sigma_image = {value}\n"),
                    encoding="utf-8")


def _fresh(net, tmp_path, name):
    """The samples of an uninterrupted run of the current inputs in a new folder."""
    _run(net / "mc.prj", tmp_path / name)
    return _samples(tmp_path / name)


# ---------------------------------------------------------------------------
# item 1: resume only with the same inputs

@pytest.mark.parametrize("edit, changed", [(_edit_control_point, "net_points.csv"),
                                           (_edit_sigma_image, "net.prj")])
def test_an_edited_input_file_means_recompute_not_resume(net, tmp_path, caplog, edit,
                                                         changed):
    """Editing a control coordinate (points table) or sigma_image (project
    file) between two starts: the second computes all 40 runs again (none
    resumed), says why in one line naming the file, and its samples are
    bit-identical to a fresh run of the edited inputs, not to the old ones."""
    _chain(net)
    out = tmp_path / "out"
    _run(net / "mc.prj", out)
    old = _samples(out)
    edit(net)
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="photogram"):
        _, summary = _run(net / "mc.prj", out)
    assert summary["execution"]["runs_resumed"] == 0
    assert summary["execution"]["runs_computed"] == 40
    why = [r.getMessage() for r in caplog.records if "computing all 40 runs again" in
           r.getMessage()]
    assert len(why) == 1 and f"{changed} changed" in why[0], why
    assert not any("resuming" in r.getMessage() for r in caplog.records)
    new = _samples(out)
    assert new.equals(_fresh(net, tmp_path, "fresh"))
    assert not new.equals(old)


def test_interrupted_run_with_edited_input_never_mixes_chunks(net, tmp_path):
    """kill mid-run (2 of 4 chunks written), edit a control coordinate, and
    add a chunk of the old inputs as a still-running old process would: the
    rerun reuses none of them and equals a fresh run of the edited inputs.
    A chunk of the old inputs slipped in later is not read either."""
    _chain(net)
    out = tmp_path / "out"
    _run(net / "mc.prj", tmp_path / "old")                   # a complete run, old inputs
    done = []

    def interrupt(index):
        done.append(index)
        if len(done) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _run(net / "mc.prj", out, on_chunk=interrupt)
    _edit_control_point(net)
    shutil.copy(tmp_path / "old" / "samples" / "chunk-00003.csv", out / "samples")
    seen = []
    _run(net / "mc.prj", out, on_chunk=seen.append)
    assert sorted(seen) == [0, 1, 2, 3]                      # everything computed again
    fresh = _fresh(net, tmp_path, "fresh")
    assert _samples(out).equals(fresh)
    # an old chunk written after the manifest of the new inputs
    shutil.copy(tmp_path / "old" / "samples" / "chunk-00002.csv", out / "samples")
    seen = []
    _run(net / "mc.prj", out, on_chunk=seen.append)
    assert seen == [2]
    assert _samples(out).equals(fresh)


def test_unchanged_inputs_still_resume_and_more_runs_reuse_the_done_ones(net, tmp_path):
    """The manifest does not break resuming: same inputs -> the finished
    chunks are reused, bit-identical; raising runs reuses them too."""
    _chain(net)
    out = tmp_path / "out"
    _run(net / "mc.prj", out)
    _, summary = _run(net / "mc.prj", out)
    assert summary["execution"]["runs_resumed"] == 40
    _, summary = _run(net / "mc.prj", out, runs=60)
    assert summary["execution"]["runs_resumed"] == 40
    assert summary["execution"]["runs_computed"] == 20
    manifest = json.loads((out / "samples" / "manifest.json").read_text())
    assert {Path(p).name for p in manifest["files"]} == {
        "net.prj", "net_stations.csv", "net_points.csv", "net_image_points.csv"}


def test_force_on_the_command_line_always_recomputes(net, tmp_path, caplog):
    from photogram_cli.main import main
    path = _chain(net)
    out = tmp_path / "out"
    assert main(["montecarlo", "--no-report", str(path), "--output", str(out), "-q"]) == 0
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="photogram"):
        assert main(["montecarlo", "--no-report", str(path), "--output", str(out), "-q", "--force"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["execution"]["runs_resumed"] == 0
    assert summary["execution"]["runs_computed"] == 40
    assert any("computing all 40 runs again (--force)" in r.getMessage()
               for r in caplog.records)


def test_demo_replacing_its_monte_carlo_results_computes_them_again(net, tmp_path,
                                                                    monkeypatch, capsys):
    """make demo says "replacing the earlier results": then no run may be
    resumed from the earlier samples."""
    import photogram.demo as demo
    path = _chain(net, runs=40)
    monkeypatch.setattr(demo, "ROOT", tmp_path)
    monkeypatch.setattr(demo, "PROJECTS", tmp_path)
    monkeypatch.setattr(demo, "steps", lambda: [("montecarlo", demo._montecarlo, path, None)])
    demo.run()
    first = json.loads((net / "out" / "summary.json").read_text())
    assert first["execution"]["runs_computed"] == 200
    demo.run()
    assert "replacing the earlier results" in capsys.readouterr().out
    second = json.loads((net / "out" / "summary.json").read_text())
    assert second["execution"]["runs_resumed"] == 0
    assert second["execution"]["runs_computed"] == 200


# ---------------------------------------------------------------------------
# item 17: no cluster address from a project file

def test_a_project_file_cannot_name_a_dask_cluster(net, tmp_path, capsys, monkeypatch):
    from photogram_cli.main import main
    import photogram.montecarlo.execute as execute
    contacted = []
    monkeypatch.setattr(execute, "_dask", lambda *a, **k: contacted.append(a) or iter(()))
    path = _chain(net, extra='scheduler = "tcp://127.0.0.1:9"')
    with pytest.raises(InputError) as err:
        read_project(path)
    assert err.value.file == str(path)
    assert err.value.line == path.read_text().splitlines().index(
        'scheduler = "tcp://127.0.0.1:9"') + 1
    assert main(["montecarlo", "--no-report", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{path}:") and "--scheduler" in lines[0]
    assert contacted == [] and not (net / "out").exists()


# ---------------------------------------------------------------------------
# item 21: absurd counts are refused before anything is allocated

def _cli(*args, timeout=120):
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "photogram_cli", *map(str, args)],
                       capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stderr.strip().splitlines(), time.perf_counter() - t0


def _in_process(capsys, *args):
    """The command's entry point in this process: (exit code, stderr lines)."""
    from photogram_cli.main import main
    capsys.readouterr()
    code = main(list(map(str, args)))
    return code, capsys.readouterr().err.strip().splitlines()


def test_a_billion_runs_or_exposures_are_refused_at_once(net, tmp_path, capsys):
    """The first in a real process (its exit code and its one line on
    stderr), the other two through the same entry point in this process."""
    path = _chain(net)
    rc, err, seconds = _cli("montecarlo", path, "--runs", 10 ** 9, "--output", tmp_path / "a")
    assert rc == 2 and len(err) == 1 and "--runs must be at most 100000" in err[0], err
    path = _chain(net, runs=10 ** 9)
    rc, err = _in_process(capsys, "montecarlo", path, "--output", tmp_path / "b")
    assert rc == 2 and len(err) == 1 and err[0].startswith(f"{path}:")
    assert "runs in [montecarlo] must be at most 100000" in err[0]
    design = tmp_path / "big.toml"
    text = (ROOT / "projects" / "designs" / "situation-b.toml").read_text(encoding="utf-8")
    assert "\nexposures = 24" in text
    design.write_text(text.replace("\nexposures = 24", "\nexposures = 1000000000"),
                      encoding="utf-8")
    rc, err = _in_process(capsys, "simulate", design, "--output", tmp_path / "sim")
    assert rc == 2 and len(err) == 1 and err[0].startswith(f"{design}:")
    assert "exposures in [jumper] must be at most 1000" in err[0]
    assert not (tmp_path / "sim").exists()


# ---------------------------------------------------------------------------
# item 3: sigma_cmd is what the commands write now

@pytest.fixture(scope="module")
def demo_chain(tmp_path_factory, example_steps):
    """lab, field and jumps as calibrate, orient and intersect leave them (a
    copy of the session's example runs, conftest.py ``example_steps``:
    `photogram calibrate|orient|intersect --no-report -q` on copies of the
    examples), then a short Monte Carlo as a user runs it."""
    from photogram_cli.main import main
    example_steps.results("intersect jumps")
    root = example_steps.copy(("lab", "field", "jumps"), tmp_path_factory.mktemp("demo"))
    assert main(["montecarlo", "--no-report", str(root / "jumps" / "montecarlo.prj"), "-q",
                 "--runs", "20", "--workers", "1", "--output", str(root / "mc")]) == 0
    return root


def test_sigma_cmd_is_what_orient_and_intersect_write(demo_chain):
    """Every station, jumper-point and stick-model sigma_cmd equals the
    sigma in field/results/stations.csv, jumps/results/points3d.csv and
    jumps/results/exposures.csv (summary.csv has 6 digits)."""
    root = demo_chain
    s = pd.read_csv(root / "mc" / "summary.csv").set_index("quantity")
    st = pd.read_csv(root / "field" / "results" / "stations.csv")
    want, got = [], []
    for _, r in st.iterrows():
        for q in ("X0", "Y0", "Z0", "omega", "phi", "kappa"):
            want.append(r[f"est_s{q}"])
            got.append(s.loc[f"{r.station}.{q}", "sigma_cmd"])
    assert len(want) == 18
    pts = pd.read_csv(root / "jumps" / "results" / "points3d.csv", dtype={"exposure": str})
    for _, r in pts.iterrows():
        for a in "XYZ":
            want.append(r[f"s{a}"])
            got.append(s.loc[f"{r.point}@{r.exposure}.{a}", "sigma_cmd"])
    assert len(want) == 18 + 24 * 4 * 3
    ex = pd.read_csv(root / "jumps" / "results" / "exposures.csv")
    names = [q.split("@")[1] for q in s.index if q.startswith("alpha@")]
    assert len(names) == len(ex) == 24
    for e, (_, r) in zip(names, ex.iterrows()):
        for q in ("alpha", "beta", "gamma", "delta_phi", "phi", "heading", "Z0", "v"):
            want.append(r[f"sigma_{q}"])
            got.append(s.loc[f"{q}@{e}", "sigma_cmd"])
    np.testing.assert_allclose(got, want, rtol=2e-5)
    # the headline ratio compares with those: the jumper points' ratio_cmd is
    # close to 1 now (it was 0.07-0.13 against the stale sigmas)
    head = json.loads((root / "mc" / "summary.json").read_text())["headline"]
    assert 0.7 < head["jumper"]["ratio_cmd"]["median"] < 1.3
