"""photogram montecarlo: the engine steps against the commands, seeding and
engines (1 and 2 local workers, Dask), resume after an interruption, the
agreement of Monte-Carlo and propagated sigmas, bad input.

The small network (4 stations, 14 points, 6 of them weighted reference
points) keeps every Monte-Carlo run at about a millisecond.
"""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.project import read_project, write_project
from photogram.simulation.network import frame_network, to_project

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


def _network(folder):
    net = frame_network(n_stations=4, n_points=14, sigma=0.3, seed=3)
    project = to_project(net, control=range(6), point_sigma=0.001, sigma_image=0.3,
                         name="net", rng=np.random.default_rng(1))
    project.adjustment.datum = "weighted"
    folder.mkdir(parents=True, exist_ok=True)
    write_project(project, folder / "net.prj")
    return folder / "net.prj"


def _chain_file(folder, body, name="mc.prj"):
    path = folder / name
    path.write_text(textwrap.dedent(f"""\
        [project]
        name = "mc"

        [montecarlo]
        {textwrap.dedent(body).strip()}

        [output]
        folder = "out"
        """).replace("\n        ", "\n"), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def net(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mc")
    _network(folder)
    return folder


def _chain_project(folder, runs=40, chunk=10, extra=""):
    path = _chain_file(folder, f"""
        orient = "net.prj"
        perturb = ["image", "reference"]
        points = ["P*"]
        runs = {runs}
        seed = 7
        chunk = {chunk}
        {extra}
        """)
    return read_project(path)


def _samples(folder):
    import pandas as pd
    return pd.read_csv(folder / "samples.csv")


# ---------------------------------------------------------------------------
# kernels

def test_engine_bundle_reproduces_the_command(net):
    """The Monte-Carlo adjustment step is the engine's problem re-solved
    with new observations: from a perturbed start it reaches what
    ``photogram orient`` reaches, and its cofactors are the engine's."""
    from photogram.bundle import adjust
    from photogram.montecarlo.adjustment import EngineBundle
    from photogram.stats.covariance import cofactors, station_covariances
    from photogram.adjust.build import build_problem
    project = read_project(net / "net.prj")
    result = adjust(project, fix_interior=True)
    eb = EngineBundle(result.project, fix_interior=True)
    inputs = eb.inputs.copy()
    inputs.xy = project.image_points.xy.copy()             # the measured values
    inputs.reference = project.points.xyz[eb.control]      # the given reference values
    start = eb.start.copy()
    start.X0 += 0.01
    state, _ = eb.solve(inputs, start=start)
    assert np.abs(state.X0 - result.project.stations.position).max() < 2e-6   # engine tol
    assert np.abs(state.X[eb.free_points]
                  - result.project.points.xyz[eb.free_points]).max() < 2e-6
    _, Q, _ = eb.linearize(state, inputs)
    built = build_problem(result.project, fix_interior=True)
    S = station_covariances(cofactors(built.problem), built.problem.state.R)
    sig = np.sqrt(np.diag(Q))[eb.station_cols[:, :3]]
    assert np.allclose(sig, np.sqrt(np.diagonal(S, axis1=1, axis2=2))[:, :3], rtol=1e-4)


def test_exact_inputs_give_back_the_truth(net):
    from photogram.bundle import adjust
    from photogram.montecarlo.adjustment import EngineBundle
    result = adjust(read_project(net / "net.prj"), fix_interior=True)
    eb = EngineBundle(result.project, fix_interior=True)
    state, it = eb.solve(eb.inputs)
    assert it <= 2
    assert np.abs(state.X0 - eb.start.X0).max() < 1e-9
    assert np.abs(state.X[eb.free_points] - eb.start.X[eb.free_points]).max() < 1e-9


def _orientation_of(project):
    from types import SimpleNamespace
    from photogram.geometry import camera_model, opk_to_matrix
    models = [camera_model(c.model) for c in project.cameras.values()]
    p = max(m.n_params for m in models)
    io = np.zeros((len(models), p))
    for k, c in enumerate(project.cameras.values()):
        io[k, :len(c.values())] = c.values()
    R, X0 = opk_to_matrix(project.stations.angles), project.stations.position
    start = SimpleNamespace(io=io, R=R, X0=X0)
    return SimpleNamespace(camera_names=list(project.cameras), models=models,
                           station_names=list(project.stations.names), start=start), io, R, X0


def test_intersect_step_reproduces_the_pipeline():
    """Points by the engine problem of photogram intersect, lines by the
    line code of the command (photogram.lines.batch, of which the command's
    per-line functions are batches of one), against the command's functions;
    the lines differ only by the Gauss-Newton tolerance (Monte Carlo 1e-11,
    the command 1e-10) and roundoff."""
    from photogram.jump.pipeline import intersect_points
    from photogram.lines import cameras_from_project, intersect_line_from_points
    from photogram.montecarlo.intersect import IntersectStep
    from photogram.simulation.jump import jump_project
    project, _ = jump_project(n_exposures=4)
    orientation, io, R, X0 = _orientation_of(project)
    step = IntersectStep(project, orientation)
    adjusted, cov, _, _ = intersect_points(project)
    X, covX = step.intersect_points(io, R, X0, step.inputs_points, step.start_points,
                                    covariance=True)
    assert np.abs(X - adjusted.points.xyz).max() < 1e-6
    assert np.allclose(covX, cov, rtol=1e-6)
    P, D, C, chi2 = step.intersect_lines(io, R, X0, step.inputs_lines, covariance=True)
    cams = cameras_from_project(project)
    il = project.image_lines
    for n in (0, 5):                            # L1@001, L2@003
        ski, e = ("L1", "L2")[n % 2], step.exposures[n // 2]
        rows = il.line == f"{ski}@{e}"
        pts = {project.stations.names[s]: il.xy[rows & (il.station == s)]
               for s in np.unique(il.station[rows])}
        ref = intersect_line_from_points(pts, cams, 0.33)
        d = D[n] * np.sign(D[n] @ ref.line.direction)
        assert np.abs(d - ref.line.direction).max() < 1e-11
        assert np.abs(P[n] - ref.line.point).max() < 1e-9
        assert np.allclose(C[n], ref.line.covariance, rtol=1e-9)
        assert chi2[n] == pytest.approx(ref.chi2, rel=1e-10)


def test_seeds_of_a_run_do_not_depend_on_the_number_of_runs():
    from photogram.montecarlo.execute import seeds_for
    a, b = seeds_for(5, 10), seeds_for(5, 1000)
    for i in range(10):
        assert np.array_equal(a[i].generate_state(4), b[i].generate_state(4))


# ---------------------------------------------------------------------------
# agreement with propagation

def test_monte_carlo_sigmas_agree_with_propagated_sigmas(net, tmp_path):
    """N = 500 runs: sigma_mc / sigma has a relative standard error of
    1 / sqrt(2 (N - 1)) = 3.2 %, so 10 % is 3.1 standard errors (two-sided
    probability 0.2 % per quantity, for the fixed seed a deterministic
    check); the median over all 66 quantities is within 3 %. The network is
    well conditioned, so linearization errors are far below that."""
    from photogram.montecarlo import run_montecarlo
    project = _chain_project(net, runs=500, chunk=100)
    _, summary = run_montecarlo(project, output=tmp_path, progress=False)
    import pandas as pd
    table = pd.read_csv(tmp_path / "summary.csv")
    assert summary["failed"] == 0
    assert len(table) == 4 * 6 + 14 * 3                  # stations, points
    assert np.all(np.abs(table.ratio - 1) < 0.10), table[np.abs(table.ratio - 1) >= 0.1]
    assert abs(np.median(table.ratio) - 1) < 0.03
    lo, hi = summary["ratio_band_95"]
    assert lo == pytest.approx(1 - 1.96 / np.sqrt(2 * 499), abs=0.005)
    assert hi == pytest.approx(1 + 1.96 / np.sqrt(2 * 499), abs=0.005)
    assert (tmp_path / "table1.csv").is_file()


# ---------------------------------------------------------------------------
# engines and resume

def test_same_numbers_for_1_and_2_workers_and_dask(net, tmp_path):
    from photogram.montecarlo import run_montecarlo
    project = _chain_project(net)
    run_montecarlo(project, output=tmp_path / "w1", workers=1, progress=False)
    run_montecarlo(project, output=tmp_path / "w2", workers=2, progress=False)
    a, b = _samples(tmp_path / "w1"), _samples(tmp_path / "w2")
    assert a.equals(b)
    assert (tmp_path / "w1" / "samples" / "chunk-00003.csv").read_bytes() == \
        (tmp_path / "w2" / "samples" / "chunk-00003.csv").read_bytes()
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  protocol="tcp://", host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        _, summary = run_montecarlo(project, output=tmp_path / "dask",
                                    scheduler=cluster.scheduler_address, progress=False)
    assert summary["execution"]["engine"] == "dask"
    assert _samples(tmp_path / "dask").equals(a)


def test_interrupted_run_resumes_and_gives_the_same_results(net, tmp_path):
    from photogram.montecarlo import run_montecarlo
    project = _chain_project(net)
    run_montecarlo(project, output=tmp_path / "full", progress=False)
    done = []

    def interrupt(index):
        done.append(index)
        if len(done) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_montecarlo(project, output=tmp_path / "cut", progress=False, on_chunk=interrupt)
    chunks = sorted(p.name for p in (tmp_path / "cut" / "samples").glob("chunk-*.csv"))
    assert chunks == ["chunk-00000.csv", "chunk-00001.csv"]
    assert not (tmp_path / "cut" / "samples.csv").exists()
    seen = []
    _, summary = run_montecarlo(project, output=tmp_path / "cut", progress=False,
                                on_chunk=seen.append)
    assert seen == [2, 3]                        # the finished chunks are not run again
    assert summary["execution"]["runs_resumed"] == 20
    assert _samples(tmp_path / "cut").equals(_samples(tmp_path / "full"))
    # other settings: the old chunks are discarded, not mixed in
    other = _chain_project(net, extra="truth = \"adjusted\"\nalign = \"plan\"")
    _, summary = run_montecarlo(other, output=tmp_path / "cut", progress=False)
    assert summary["execution"]["runs_resumed"] == 0


# ---------------------------------------------------------------------------
# the jump chain (orient -> intersect) on simulated files

def _jump_chain(tmp_path, runs, convert=lambda project: project):
    """Monte Carlo of the simulated field orientation and the 3-exposure
    jump (image and reference perturbed), the cameras converted by
    ``convert``: ``(folder, summary)`` after checking that no run failed and
    the headline has its three groups."""
    from photogram.montecarlo import run_montecarlo
    from photogram.simulation.designs import field_design
    from photogram.simulation.jump import jump_project
    field, _ = field_design()
    write_project(convert(field), tmp_path / "field.prj")
    jumps, _ = jump_project(n_exposures=3)
    write_project(convert(jumps), tmp_path / "jumps.prj")
    path = _chain_file(tmp_path, f"""
        orient = "field.prj"
        intersect = "jumps.prj"
        perturb = ["image", "reference"]
        runs = {runs}
        seed = 3
        """)
    folder, summary = run_montecarlo(read_project(path), progress=False)
    assert summary["failed"] == 0
    assert set(summary["headline"]) == {"station", "jumper", "stick"}
    return folder, summary


def test_orient_intersect_chain_on_the_simulated_jump(tmp_path):
    folder, summary = _jump_chain(tmp_path, runs=30)
    for group in summary["headline"].values():
        assert 0.6 < group["ratio"]["median"] < 1.4          # 30 runs: +-26 % at 2 sigma
    t2 = (folder / "table2.csv").read_text()
    assert "P1.X" in t2 and "delta_phi" in t2


# ---------------------------------------------------------------------------
# bad input

@pytest.mark.parametrize("body, message", [
    ('orient = "net.prj"\nrunz = 10', "unknown key 'runz'"),
    ('orient = "net.prj"\nruns = 0', "runs in [montecarlo] must be at least 1"),
    ('orient = "missing.prj"', "project missing.prj not found"),
    ('runs = 5', "needs exactly one of orient and calibrate"),
    ('orient = "net.prj"\nperturb = ["imgae"]', "unknown perturbation 'imgae'"),
])
def test_bad_montecarlo_section_is_one_line_with_file_and_line(net, tmp_path, body, message,
                                                                capsys):
    from photogram_cli.main import main
    (tmp_path / "net.prj").symlink_to(net / "net.prj")
    for f in net.glob("net_*.csv"):
        (tmp_path / f.name).symlink_to(f)
    path = _chain_file(tmp_path, body)
    with pytest.raises(InputError) as err:
        read_project(path)
    assert message in str(err.value)
    assert err.value.file == str(path) and err.value.line is not None
    assert main(["montecarlo", "--no-report", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{path}:") and message in lines[0]


def test_bad_command_line_values_exit_2(net, capsys):
    from photogram_cli.main import main
    path = _chain_file(net, 'orient = "net.prj"\nruns = 5', name="ok.prj")
    assert main(["montecarlo", "--no-report", str(path), "--runs", "0"]) == 2
    assert "--runs must be at least 1" in capsys.readouterr().err
    assert main(["montecarlo", "--no-report", str(path), "--scheduler", "localhost:1"]) == 2
    assert "tcp://HOST:PORT" in capsys.readouterr().err


def test_command_line_run_writes_the_results(net, tmp_path, capsys):
    from photogram_cli.main import main
    path = _chain_file(net, 'orient = "net.prj"\nruns = 20\nchunk = 5\nseed = 2',
                       name="cli.prj")
    assert main(["montecarlo", "--no-report", str(path), "--output", str(tmp_path), "--seed", "4"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("montecarlo: 20 runs (0 failed)")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["seed"] == 4 and summary["runs"] == 20
    for name in ("summary.csv", "table1.csv", "samples.csv", "log.txt",
                 "samples/chunk-00003.csv"):
        assert (tmp_path / name).is_file()


# ---------------------------------------------------------------------------
# every camera model of the engine (issue 17: Monte Carlo runs the engine)

def _to_opencv(project):
    """The project's cameras in the opencv model (the exact pinhole part of
    brown_to_opencv; distortion starts at 0 and is estimated where free)."""
    from photogram.geometry import brown_to_opencv, camera_model
    from photogram.project.model import Parameter
    names = camera_model("opencv").parameter_names
    for cam in project.cameras.values():
        if cam.model == "opencv":
            continue
        free = [p.free for p in cam.parameters.values()]
        values = brown_to_opencv(cam.values(), strict=False)
        cam.model = "opencv"
        cam.parameters = {n: Parameter(float(v), free=bool(free[min(i, 3)]) if i < 4 else False)
                          for i, (n, v) in enumerate(zip(names, values))}
    return project


def _to_bal(project):
    """The project's cameras in the bal model (f = c, k1 = k2 = 0)."""
    from photogram.geometry import camera_model
    from photogram.project.model import Parameter
    names = camera_model("bal").parameter_names
    for cam in project.cameras.values():
        v = cam.values()
        cam.model = "bal"
        cam.parameters = {n: Parameter(float(x)) for n, x in zip(names, (v[0], 0.0, 0.0))}
    return project


@pytest.mark.parametrize("model", ["opencv", "bal"])
def test_monte_carlo_with_other_camera_models_agrees_with_propagation(net, tmp_path, model):
    """The orient chain of the small network with opencv (bal) cameras: the
    same engine problem, so sigma_mc / sigma_prop is near 1 as with brown."""
    from photogram.montecarlo import run_montecarlo
    convert = {"opencv": _to_opencv, "bal": _to_bal}[model]
    project = convert(read_project(net / "net.prj"))
    folder = tmp_path / "cv"
    folder.mkdir()
    write_project(project, folder / "net.prj")
    assert read_project(folder / "net.prj").cameras[next(iter(project.cameras))].model == model
    chain = _chain_project(folder, runs=300, chunk=100)
    _, summary = run_montecarlo(chain, output=tmp_path / "out", progress=False)
    import pandas as pd
    table = pd.read_csv(tmp_path / "out" / "summary.csv")
    assert summary["failed"] == 0
    assert len(table) == 4 * 6 + 14 * 3
    assert np.all(np.abs(table.ratio - 1) < 0.13), table[np.abs(table.ratio - 1) >= 0.13]
    assert abs(np.median(table.ratio) - 1) < 0.04


def test_orient_intersect_chain_with_opencv_cameras(tmp_path):
    """Field orientation and jump intersection (points by the engine, lines
    by the batch line code) with opencv cameras."""
    _, summary = _jump_chain(tmp_path, runs=60, convert=_to_opencv)
    for group in summary["headline"].values():
        assert 0.7 < group["ratio"]["median"] < 1.3          # 60 runs: +-18 % at 2 sigma
