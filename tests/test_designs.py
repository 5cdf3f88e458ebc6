"""The example projects projects/lab and projects/field: the designs of
photogram.simulation.designs, the files projects/generate.py writes from
them (committed, byte for byte reproducible) and reading them back."""

from __future__ import annotations

import csv
import importlib.util
import shutil
from pathlib import Path

import numpy as np
import pytest

from photogram.geometry import camera_model
from photogram.project import read_project
from photogram.simulation import designs
from photogram.simulation.designs import (
    CAMERAS, CONTROL_SIGMA, FIELD_SEED, IMAGE_SIZE, LAB_SEED, SIGMA_IMAGE, field_design,
    lab_design, slope_height)

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

PROJECTS = Path(__file__).resolve().parents[1] / "projects"
LAB_PRJ = PROJECTS / "lab" / "lab-typed.prj"      # the typed observations of the design
LAB_MEASURED_PRJ = PROJECTS / "lab" / "lab.prj"   # the same, measured from images/
FIELD = PROJECTS / "field"
LAB_CAMERAS = "../lab/results/cameras.toml"


def _generator():
    spec = importlib.util.spec_from_file_location("projects_generate",
                                                  PROJECTS / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    out = tmp_path_factory.mktemp("generated")
    return out, _generator().generate(out)


@pytest.fixture(scope="module")
def lab():
    return lab_design(LAB_SEED)


@pytest.fixture(scope="module")
def field():
    return {alt: field_design(FIELD_SEED, alternative=alt) for alt in (1, 2)}


def _nominal_field(tmp_path: Path) -> Path:
    """A copy of projects/field whose projects take the nominal cameras."""
    folder = tmp_path / "field"
    shutil.copytree(FIELD, folder, ignore=shutil.ignore_patterns("results*"))
    for prj in ("field.prj", "field-alt2.prj"):
        path = folder / prj
        text = path.read_text(encoding="utf-8")
        assert text.count(f'from = "{LAB_CAMERAS}"') == 3
        path.write_text(text.replace(LAB_CAMERAS, "cameras-nominal.toml"), encoding="utf-8")
    return folder


def _read_csv(path: Path) -> list[dict]:
    lines = [ln for ln in path.read_text(encoding="utf-8").splitlines()
             if ln.strip() and not ln.lstrip().startswith("#")]
    return list(csv.DictReader(lines))


# ---------------------------------------------------------------------------
# the generator and the committed files
# ---------------------------------------------------------------------------

def test_regenerating_reproduces_the_committed_files_byte_for_byte(generated):
    out, paths = generated
    assert paths
    for path in paths:
        rel = path.relative_to(out)
        committed = PROJECTS / rel
        assert committed.is_file(), f"projects/{rel} missing: run projects/generate.py"
        if path.suffix == ".jpg" and committed.read_bytes() != path.read_bytes():
            # another JPEG encoder or floating-point rounding: the same picture
            assert _same_picture(committed, path), \
                f"projects/{rel} differs from the generator's output: run projects/generate.py"
            continue
        assert committed.read_bytes() == path.read_bytes(), \
            f"projects/{rel} differs from the generator's output: run projects/generate.py"


def _same_picture(a: Path, b: Path) -> bool:
    import cv2
    ia, ib = (cv2.imread(str(p), cv2.IMREAD_GRAYSCALE).astype(int) for p in (a, b))
    if ia.shape != ib.shape:
        return False
    d = np.abs(ia - ib)
    return d.mean() < 0.05 and np.mean(d > 1) < 1e-3


def test_lab_photographs_are_small_and_say_they_are_simulated():
    images = sorted((PROJECTS / "lab" / "images").glob("*.jpg"))
    names = [p.stem for p in images]
    stations = [r["station"] for r in _read_csv(PROJECTS / "lab" / "lab_stations.csv")]
    assert names == sorted(stations)                       # one photograph per station
    assert sum(p.stat().st_size for p in images) < 1_000_000
    for p in images:
        data = p.read_bytes()
        assert data[:4] == b"\xff\xd8\xff\xfe" and b"SIMULATED data" in data[:400], p.name


def test_lab_prj_calibrates_from_the_measurement_and_lab_typed_from_the_table():
    measured = LAB_MEASURED_PRJ.read_text(encoding="utf-8")
    typed = LAB_PRJ.read_text(encoding="utf-8")
    assert 'points = "results-measure/image_points.csv"' in measured
    assert 'folder = "results"' in measured
    assert 'points = "lab_image_points.csv"' in typed and 'folder = "results-typed"' in typed
    body = [ln for ln in measured.splitlines() if not ln.startswith("#")
            and not ln.startswith("points =") and not ln.startswith("folder =")]
    assert body == [ln for ln in typed.splitlines() if not ln.startswith("#")
                    and not ln.startswith("points =") and not ln.startswith("folder =")]


def test_no_stale_generated_files_are_committed(generated):
    out, paths = generated
    made = {p.relative_to(out) for p in paths}
    for folder in ("lab", "field"):
        for path in (PROJECTS / folder).rglob("*"):
            rel = path.relative_to(PROJECTS)
            # results folders and hidden files (the lock file a results folder
            # leaves beside it, .gitignore'd) are not committed
            if path.is_file() and path.name != "README.md" \
                    and not rel.parts[1].startswith(("results", ".")):
                assert rel in made, f"projects/{rel} is not written by the generator"


def test_generator_is_deterministic(tmp_path, generated):
    out, paths = generated
    again = _generator().generate(tmp_path)
    assert [p.relative_to(tmp_path) for p in again] == [p.relative_to(out) for p in paths]
    for a, b in zip(again, paths):
        assert a.read_bytes() == b.read_bytes()


def test_every_file_says_it_is_simulated(generated):
    _, paths = generated
    for path in paths:
        if path.suffix == ".jpg":                   # a JPEG comment segment
            assert b"SIMULATED data" in path.read_bytes()[:400], path.name
            continue
        assert path.read_text(encoding="utf-8").startswith("# SIMULATED data"), path.name


# ---------------------------------------------------------------------------
# the lab project
# ---------------------------------------------------------------------------

def test_lab_project_reads_back_with_the_design_values(lab):
    design, truth = lab
    prj = read_project(LAB_PRJ)
    assert prj.name == "lab"
    assert (prj.units.length, prj.units.angle, prj.units.image) == ("m", "gon", "px")
    assert prj.rotation_direction == "world_to_camera"
    assert prj.adjustment.datum == "free" and prj.adjustment.inner_constraints is None
    assert prj.adjustment.sigma_image == SIGMA_IMAGE
    assert prj.output.folder == "results-typed"
    assert prj.warnings == []
    # exactly the values of the design (bit for bit)
    assert prj.stations.names == design.stations.names
    assert np.array_equal(prj.stations.position, design.stations.position)
    assert np.array_equal(prj.stations.angles, design.stations.angles)
    assert prj.points.ids == design.points.ids
    assert np.array_equal(prj.points.xyz, design.points.xyz)
    assert np.array_equal(prj.image_points.xy, design.image_points.xy)
    assert np.array_equal(prj.image_points.station, design.image_points.station)
    assert np.array_equal(prj.image_points.point, design.image_points.point)


def test_lab_counts_and_cameras():
    prj = read_project(LAB_PRJ)
    assert list(prj.cameras) == ["K1", "K2", "K3"]
    assert len(prj.stations) == 9
    assert [prj.stations.camera.count(c) for c in ("K1", "K2", "K3")] == [3, 3, 3]
    assert 40 <= len(prj.points) <= 60
    assert set(prj.points.kind) == {"tie"}
    assert np.all(np.isfinite(prj.points.xyz)) and np.all(np.isfinite(prj.stations.position))
    assert len(prj.image_points) == 446
    for cam in prj.cameras.values():
        assert cam.image_size == IMAGE_SIZE
        free = [p for p, par in cam.parameters.items() if par.free]
        assert free == ["c", "x0", "y0", "K1", "K2"]
        assert all(par.value == 0.0 for p, par in cam.parameters.items() if not par.free)
    # one scale bar: with the inner constraints over all points, 6 conditions
    assert len(prj.distances) == 1
    d = prj.distances[0]
    assert (d.point_a, d.point_b, d.sigma) == ("SB1", "SB2", 1e-4)


def test_lab_geometry(lab):
    design, truth = lab
    X0 = truth["stations"]["X0"]
    dist = np.linalg.norm(X0 - designs.LAB_CENTRE, axis=1)
    cams = np.array(truth["stations"]["camera"])
    assert np.all(np.abs(dist[cams != "K3"] - 2.0) < 0.15)
    assert np.all(np.abs(dist[cams == "K3"] - 4.0) < 0.15)
    pts = truth["points"]["xyz"]
    assert np.all(pts.min(0) >= -1e-9)
    assert np.all(pts.max(0) <= [0.5, 0.5, 0.31])
    # roll diversity: per camera, the image x axes differ by about 90 degrees
    R = truth["stations"]["R"]
    for cam in CAMERAS:
        i = np.flatnonzero(cams == cam)
        up = R[i][:, 1, 2]                    # world Z in camera y: 1 upright, 0 turned
        assert np.sum(np.abs(up) > 0.3) == 1 and np.sum(np.abs(up) < 0.3) == 2, up


def test_lab_approximations_are_rough_but_close(lab):
    design, truth = lab
    d_pos = design.stations.position - truth["stations"]["X0"]
    assert 0.005 < np.abs(d_pos).max() < 0.15
    d_ang = np.degrees(design.stations.angles - truth["stations"]["angles"]) / 0.9
    assert 0.5 < np.abs(d_ang).max() < 12.0                       # gon
    d_pts = design.points.xyz - truth["points"]["xyz"]
    assert 0.003 < d_pts.std() < 0.02


# ---------------------------------------------------------------------------
# the field projects
# ---------------------------------------------------------------------------

def test_field_prj_takes_the_cameras_from_the_lab_results():
    for prj in ("field.prj", "field-alt2.prj"):
        text = (FIELD / prj).read_text(encoding="utf-8")
        for cam in ("K1", "K2", "K3"):
            assert f'[cameras.{cam}]\nfrom = "{LAB_CAMERAS}"' in text
    alt2 = (FIELD / "field-alt2.prj").read_text(encoding="utf-8")
    assert 'file = "field_stations.csv"' in alt2
    assert not (FIELD / "field-alt2_stations.csv").exists()


@pytest.mark.parametrize("alternative", [1, 2])
def test_field_project_reads_back(tmp_path, field, alternative):
    design, truth = field[alternative]
    folder = _nominal_field(tmp_path)
    name = "field.prj" if alternative == 1 else "field-alt2.prj"
    prj = read_project(folder / name)
    assert prj.warnings == []
    assert (prj.units.length, prj.units.angle, prj.units.image) == ("dm", "gon", "px")
    assert prj.adjustment.datum == "weighted"
    assert prj.adjustment.sigma_image == SIGMA_IMAGE
    assert prj.output.folder == ("results" if alternative == 1 else "results-alt2")
    # cameras: the nominal (true) values, all fixed
    true_io = designs.true_cameras()
    for cname, cam in prj.cameras.items():
        assert np.array_equal(cam.values(), true_io[cname])
        assert not cam.free_mask().any()
    # stations: one per camera, approximate values given
    assert prj.stations.names == ["S1", "S2", "S3"]
    assert prj.stations.camera == ["K1", "K2", "K3"]
    assert np.array_equal(prj.stations.position, design.stations.position)
    assert np.array_equal(prj.stations.angles, design.stations.angles)
    # points
    kinds = list(prj.points.kind)
    helmets = [i for i in prj.points.ids if i.startswith("H")]
    assert kinds.count("control") == 15
    assert kinds.count("tie") == 6 + (10 if alternative == 2 else 0)
    assert len(helmets) == (10 if alternative == 2 else 0)
    control = np.array(kinds) == "control"
    assert np.all(prj.points.sigma[control] == CONTROL_SIGMA)
    assert np.all(np.isnan(prj.points.xyz[~control]))
    assert np.array_equal(prj.points.xyz[control], design.points.xyz[control])
    # every point in all three images
    assert len(prj.image_points) == 3 * len(prj.points)
    assert np.all(np.bincount(prj.image_points.point, minlength=len(prj.points)) == 3)
    assert np.array_equal(prj.image_points.xy, design.image_points.xy)


def test_field_alternatives_share_all_but_the_helmet(field):
    (p1, t1), (p2, t2) = field[1], field[2]
    n = len(p1.points)
    assert p2.points.ids[:n] == p1.points.ids
    assert np.array_equal(p2.points.xyz[:n], p1.points.xyz[:n], equal_nan=True)
    static = p2.image_points.point < n
    assert np.array_equal(p2.image_points.xy[static], p1.image_points.xy)
    assert np.array_equal(p2.stations.position, p1.stations.position)
    assert np.array_equal(p2.stations.angles, p1.stations.angles)


def test_field_geometry(field):
    _, truth = field[2]
    X0 = truth["stations"]["X0"]
    ids = truth["points"]["ids"]
    pts = truth["points"]["xyz"]
    helmet = pts[[i.startswith("H") for i in ids]]
    # cameras 40-80 m (400-800 dm) from the flight path, all on one side
    dist = np.linalg.norm(helmet[None] - X0[:, None], axis=2).mean(axis=1)
    assert np.all((dist > 400) & (dist < 850)), dist
    assert np.all(X0[:, 1] > 300)
    # the helmet flies 2-5 m above the slope along a path of about 20 m
    above = helmet[:, 2] - slope_height(helmet[:, 0])
    assert np.all((above > 19) & (above < 52))
    path = np.sum(np.linalg.norm(np.diff(helmet, axis=0), axis=1))
    assert 170 < path < 230
    # reference points at different heights above the snow
    control = pts[:15]
    h = control[:, 2] - slope_height(control[:, 0])
    assert h.min() < 1 and h.max() > 50


def test_field_control_is_the_truth_plus_survey_noise(field):
    design, truth = field[1]
    control = np.asarray(design.points.kind) == "control"
    d = design.points.xyz[control] - truth["points"]["xyz"][control]
    assert 0.05 < d.std() < 0.2 and np.abs(d).max() < 5 * CONTROL_SIGMA
    d_pos = design.stations.position - truth["stations"]["X0"]
    assert np.abs(d_pos).max() < 5.0
    d_gon = (design.stations.angles - truth["stations"]["angles"]) * 200 / np.pi
    assert 0.3 < np.abs(d_gon).max() < 10.0


# ---------------------------------------------------------------------------
# observations and truth
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("which", ["lab", "field1", "field2"])
def test_observations_inside_the_format_and_consistent_with_the_truth(which, lab, field):
    design, truth = lab if which == "lab" else field[int(which[-1])]
    obs = design.image_points
    w, h = IMAGE_SIZE
    assert np.all((obs.xy >= 0) & (obs.xy <= [w, h]))
    assert np.all(np.bincount(obs.point, minlength=len(design.points)) >= 2)
    # the exact projections of the truth, with noise of the stated sigma
    model = camera_model("brown")
    io = designs.true_cameras()
    st = truth["stations"]
    cams = np.array([io[st["camera"][s]] for s in obs.station])
    xy = model.project(truth["points"]["xyz"][obs.point], st["angles"][obs.station],
                       st["X0"][obs.station], cams)
    np.testing.assert_allclose(xy, truth["xy_true"], atol=1e-6)
    noise = obs.xy - truth["xy_true"]
    assert abs(noise.std() / SIGMA_IMAGE - 1) < 0.2
    # in front of the cameras
    Xc = np.einsum("nij,nj->ni", st["R"][obs.station],
                   truth["points"]["xyz"][obs.point] - st["X0"][obs.station])
    assert np.all(Xc[:, 2] < 0)


def test_truth_tables_hold_the_design_truth(lab, field):
    for folder, (design, truth) in (("lab", lab), ("field", field[2])):
        rows = _read_csv(PROJECTS / folder / "truth" / "points.csv")
        assert [r["id"] for r in rows] == truth["points"]["ids"]
        xyz = np.array([[float(r[c]) for c in "XYZ"] for r in rows])
        assert np.array_equal(xyz, truth["points"]["xyz"])
        rows = _read_csv(PROJECTS / folder / "truth" / "stations.csv")
        assert np.array_equal(np.array([[float(r[c]) for c in ("X0", "Y0", "Z0")]
                                        for r in rows]), truth["stations"]["X0"])
        gon = np.array([[float(r[c]) for c in ("omega", "phi", "kappa")] for r in rows])
        np.testing.assert_allclose(gon * np.pi / 200, truth["stations"]["angles"],
                                   rtol=0, atol=1e-15)
        rows = _read_csv(PROJECTS / folder / "truth" / "cameras.csv")
        for r in rows:
            assert float(r["c"]) == CAMERAS[r["camera"]]["c"]
    rows = _read_csv(PROJECTS / "lab" / "truth" / "distances.csv")
    assert len(rows) == 1 and float(rows[0]["value"]) == lab[0].distances[0].value
    assert abs(float(rows[0]["true"]) - float(rows[0]["value"])) < 5e-4


def test_designs_are_pure_functions_of_the_seed():
    a, _ = lab_design(3)
    b, _ = lab_design(3)
    c, _ = lab_design(4)
    assert np.array_equal(a.image_points.xy, b.image_points.xy)
    assert not np.array_equal(a.points.xyz, c.points.xyz)
    with pytest.raises(ValueError):
        field_design(FIELD_SEED, alternative=3)


def test_lab_network_self_calibrates(lab):
    """The free-network self-calibration converges from the given values and
    recovers the cameras within their standard deviations (what README.md
    tells the user to expect)."""
    from photogram.adjust.build import build_problem
    from photogram.adjust.solver import solve
    from photogram.stats.covariance import camera_covariances, cofactors

    design, truth = lab
    built = build_problem(design)
    summary = solve(built.problem)
    assert summary.status == "converged"
    assert summary.n_conditions == 6
    assert abs(summary.sigma0 - 1.0) < 0.1
    cof = cofactors(built.problem)
    for k, name in enumerate(built.camera_names):
        sd = np.sqrt(np.diag(camera_covariances(cof, summary.sigma0 ** 2)[k]))[:3]
        true = np.array([truth["cameras"][name][p] for p in ("c", "x0", "y0")])
        assert np.all(np.abs(built.problem.state.io[k][:3] - true) < 4 * sd)
