"""The rig constraint (photogram.adjust.rig_blocks, issue 21 item 2): the
rig image-point block's Jacobians against central differences, and a
simulated rig network (3 cameras rigidly mounted, 8 frames, 0.2 px noise)
adjusted with the constraint against the truth and against the same images
adjusted as free stations."""

import numpy as np
import pytest

from photogram.adjust.dense import dense_cofactors
from photogram.adjust.residual_blocks import ImagePointBlock
from photogram.adjust.rig_blocks import RigImagePointBlock, composed_poses
from photogram.adjust.solver import Problem, SolverOptions, solve
from photogram.adjust.state import Layout, State
from photogram.geometry import opk_to_matrix, rodrigues_to_matrix
from photogram.simulation.network import observe, ring_stations

IO = {"brown": np.array([1420.0, 320.0, 240.0, -5e-8, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
      "opencv": np.array([1000.0, 1001, 640, 360, -0.1, 0.05, 1e-3, -1e-3, 0.01]),
      "opencv_fisheye": np.array([420.0, 421, 640, 360, 0.02, -0.01, 0.001, 0.0])}


def _rig_truth(n_frames=8, seed=0):
    """Frames on a ring at 2 m looking at a 0.5 m target frame; sensor 0 is
    the reference, sensors 1 and 2 sit 0.15-0.16 m beside it, turned by a
    few degrees."""
    rng = np.random.default_rng(seed)
    target = np.array([0.0, 0.0, 0.15])
    X0f, Rf = ring_stations(n_frames, 2.0, 1.0, target, jitter=0.05, rng=rng,
                            rolls=[0, np.pi / 2, np.pi, -np.pi / 2])
    Rs = np.stack([np.eye(3), rodrigues_to_matrix(np.array([0.01, -0.06, 0.02])),
                   rodrigues_to_matrix(np.array([-0.02, 0.05, -0.01]))])
    X0s = np.array([[0.0, 0.0, 0.0], [0.15, 0.01, -0.02], [-0.16, 0.02, 0.01]])
    points = rng.uniform([-0.25, -0.25, 0.0], [0.25, 0.25, 0.3], (60, 3))
    return Rf, X0f, Rs, X0s, points, rng


def _network(sigma=0.2, seed=0):
    Rf, X0f, Rs, X0s, points, rng = _rig_truth(seed=seed)
    F, S = len(Rf), len(Rs)
    frame, sensor = np.repeat(np.arange(F), S), np.tile(np.arange(S), F)   # image -> f, s
    R, X0 = composed_poses(Rf[frame], X0f[frame], Rs[sensor], X0s[sensor])
    net = observe("brown", np.stack([IO["brown"]] * S), sensor, R, X0, points, (640, 480),
                  sigma=sigma, rng=rng)
    return net, (Rf, X0f, Rs, X0s), frame, sensor


def _start(truth, rng, sigma_pos=0.01, sigma_rot=0.01):
    R, X0 = truth
    turn = np.stack([rodrigues_to_matrix(v) for v in rng.normal(0, sigma_rot, (len(R), 3))])
    return turn @ R, X0 + rng.normal(0, sigma_pos, X0.shape)


N_CONTROL = 6


def _point_free(n):
    free = np.ones((n, 3), bool)
    free[:N_CONTROL] = False              # datum: six control points fixed
    return free


def _rig_problem(net, truth, frame, sensor, rng):
    Rf, X0f, Rs, X0s = truth
    F, S, P = len(Rf), len(Rs), len(net.points)
    Rf0, X0f0 = _start((Rf, X0f), rng)
    Rs0, X0s0 = _start((Rs, X0s), rng)
    Rs0[0], X0s0[0] = np.eye(3), 0.0               # the reference sensor: identity
    free_st = np.ones((F + S, 6), bool)
    free_st[F] = False
    free = {"camera": [np.zeros(10, bool)] * S, "station": free_st, "point": _point_free(P)}
    layout = Layout([10] * S, F + S, P, np.zeros(P, bool), free)
    pts0 = net.points + np.where(_point_free(P), rng.normal(0, 0.005, (P, 3)), 0.0)
    state = State(pts0, np.concatenate([Rf0, Rs0]), np.concatenate([X0f0, X0s0]),
                  [IO["brown"].copy() for _ in range(S)])
    img = net.station
    block = RigImagePointBlock(net_model(), np.arange(S), sensor[img], frame[img],
                               F + sensor[img], net.point, net.xy, np.full(len(img), 0.2),
                               layout)
    return Problem(state, layout, [block])


def _free_problem(net, rng):
    n_img, P = len(net.R), len(net.points)
    S = len(net.io)
    R0, X00 = _start((net.R, net.X0), rng)
    free = {"camera": [np.zeros(10, bool)] * S, "station": np.ones((n_img, 6), bool),
            "point": _point_free(P)}
    layout = Layout([10] * S, n_img, P, np.zeros(P, bool), free)
    pts0 = net.points + np.where(_point_free(P), rng.normal(0, 0.005, (P, 3)), 0.0)
    state = State(pts0, R0, X00, [IO["brown"].copy() for _ in range(S)])
    block = ImagePointBlock(net_model(), np.arange(S), net.station_camera[net.station],
                            net.station, net.point, net.xy, np.full(len(net.station), 0.2),
                            layout)
    return Problem(state, layout, [block])


def net_model():
    from photogram.geometry import camera_model
    return camera_model("brown")


def _column_sigmas(problem):
    """A-priori (sigma0 = 1) standard deviations of every column (0: fixed)
    and the cofactors of the free columns with their column numbers."""
    _, _, Q, _ = dense_cofactors(problem)
    cols = np.flatnonzero(problem.layout.free)
    sig = np.zeros(problem.layout.n_columns)
    sig[cols] = np.sqrt(np.diag(Q))
    return sig, Q, cols


@pytest.mark.parametrize("name", sorted(IO))
def test_rig_block_jacobians_match_central_differences(name):
    from photogram.geometry import camera_model
    rng = np.random.default_rng(5)
    model = camera_model(name)
    p = len(IO[name])
    F, S, P, N = 3, 3, 10, 24
    Rf, X0f, Rs, X0s, _, _ = _rig_truth(F, seed=1)
    Rs = Rs @ np.stack([rodrigues_to_matrix(v) for v in rng.normal(0, 0.05, (S, 3))])
    X0s = X0s + rng.normal(0, 0.05, X0s.shape)
    pts = rng.uniform([-0.25, -0.25, 0.0], [0.25, 0.25, 0.3], (P, 3))
    io = [IO[name] * (1 + rng.normal(0, 1e-3, p)) for _ in range(S)]
    layout = Layout([p] * S, F + S, P, np.zeros(P, bool),
                    {"camera": [np.ones(p, bool)] * S, "station": np.ones((F + S, 6), bool),
                     "point": np.ones((P, 3), bool)})
    cam = rng.integers(0, S, N)
    frame = rng.integers(0, F, N)
    block = RigImagePointBlock(model, np.arange(S), cam, frame, F + cam, rng.integers(0, P, N),
                               rng.normal(300, 50, (N, 2)), np.ones(N), layout)
    state = State(pts, np.concatenate([Rf, Rs]), np.concatenate([X0f, X0s]), io)
    e, J = block.evaluate(state)
    assert [j.shape[2] for j in J] == [3, 6, 6, p]
    for slot, cols in enumerate(block.slot_cols):
        for k in range(cols.shape[1]):
            scale = 1e-6 * max(1.0, abs(io[0][k])) if slot == 3 else 1e-6
            num = np.zeros((N, 2))
            for n in range(N):                  # one row at a time (columns shared by rows)
                for sgn in (1, -1):
                    dx = np.zeros(layout.n_columns)
                    dx[cols[n, k]] = sgn * scale
                    en, _ = block.evaluate(state.updated(layout, dx), jacobians=False)
                    num[n] += sgn * en[n] / (2 * scale)
            np.testing.assert_allclose(J[slot][:, :, k], num, rtol=1e-6,
                                       atol=1e-6 * max(1.0, np.abs(J[slot][:, :, k]).max()),
                                       err_msg=f"{name}: slot {slot}, column {k}")


def test_composition_is_colmaps_sensor_from_rig_times_rig_from_world():
    rng = np.random.default_rng(2)
    Rf, Rs = (np.stack([rodrigues_to_matrix(v) for v in rng.normal(0, 1, (4, 3))])
              for _ in range(2))
    X0f, X0s = rng.normal(0, 1, (4, 3)), rng.normal(0, 1, (4, 3))
    R, X0 = composed_poses(Rf, X0f, Rs, X0s)
    X = rng.normal(0, 1, (4, 3))
    # camera coordinates: through the rig, and directly with the composed pose
    via_rig = np.einsum("nij,nj->ni", Rs, np.einsum("nij,nj->ni", Rf, X - X0f) - X0s)
    direct = np.einsum("nij,nj->ni", R, X - X0)
    np.testing.assert_allclose(via_rig, direct, atol=1e-13)


@pytest.fixture(scope="module")
def adjusted():
    net, truth, frame, sensor = _network()
    rng = np.random.default_rng(11)
    rig, free = _rig_problem(net, truth, frame, sensor, rng), _free_problem(net, rng)
    for problem in (rig, free):
        s = solve(problem, SolverOptions(max_iterations=30))
        assert s.status == "converged", s.message
    return net, truth, frame, sensor, rig, free


def test_rig_has_six_unknowns_per_frame_and_per_non_reference_sensor(adjusted):
    net, truth, frame, sensor, rig, free = adjusted
    F, S = len(truth[0]), len(truth[2])
    n_points = 3 * (len(net.points) - N_CONTROL)
    assert rig.layout.n_free == 6 * F + 6 * (S - 1) + n_points
    assert free.layout.n_free == 6 * F * S + n_points
    assert rig.layout.n_free < free.layout.n_free


def test_rig_recovers_sensor_offsets_and_frame_poses_within_their_sigmas(adjusted):
    net, (Rf, X0f, Rs, X0s), frame, sensor, rig, _ = adjusted
    F = len(Rf)
    sig, _, _ = _column_sigmas(rig)
    st = rig.state
    cols = rig.layout.station_cols
    # position errors, and rotation errors as the small angles of R_true^T-free
    # increments (the engine's own parameters: R = expm([d]x) R_true)
    dpos = st.X0 - np.concatenate([X0f, X0s])
    D = st.R @ np.swapaxes(np.concatenate([Rf, Rs]), 1, 2)
    drot = 0.5 * np.stack([D[:, 2, 1] - D[:, 1, 2], D[:, 0, 2] - D[:, 2, 0],
                           D[:, 1, 0] - D[:, 0, 1]], axis=1)
    err = np.hstack([dpos, drot])
    s = sig[cols]
    free = rig.layout.free[cols]
    z = np.abs(err[free]) / s[free]
    assert z.max() < 4.0, z.max()
    # the reference sensor stays the identity
    np.testing.assert_array_equal(st.R[F], np.eye(3))
    np.testing.assert_array_equal(st.X0[F], np.zeros(3))
    # sensor offsets to better than 0.5 mm, frame centres to better than 1 mm
    assert np.abs(dpos[F:]).max() < 5e-4
    assert np.abs(dpos[:F]).max() < 1e-3


def test_composed_poses_are_at_least_as_precise_as_free_stations(adjusted):
    net, truth, frame, sensor, rig, free = adjusted
    F = len(truth[0])
    img = np.arange(len(frame))
    # composed centres X0 = X0_f + R_f^T X0_s (eq. (1)) and their covariance
    # by first-order propagation (Jacobian by central differences through the
    # engine's own update)
    _, Q, cols = _column_sigmas(rig)
    where = {c: i for i, c in enumerate(cols)}
    lay, st = rig.layout, rig.state

    def centres(state):
        return composed_poses(state.R[frame], state.X0[frame], state.R[F + sensor],
                              state.X0[F + sensor])[1]

    A = np.zeros((3 * len(img), len(cols)))
    h = 1e-7
    for c in cols:
        dx = np.zeros(lay.n_columns)
        dx[c] = h
        plus = centres(st.updated(lay, dx))
        dx[c] = -h
        minus = centres(st.updated(lay, dx))
        A[:, where[c]] = ((plus - minus) / (2 * h)).ravel()
    sig_rig = np.sqrt(np.diag(A @ Q @ A.T)).reshape(-1, 3)
    sig_free_cols, _, _ = _column_sigmas(free)
    sig_free = sig_free_cols[free.layout.station_cols[img, :3]]
    assert np.all(sig_rig <= sig_free * (1 + 1e-9))
    ratio = np.median(sig_rig / sig_free)
    assert ratio < 0.9, ratio
    # and the composed poses agree with the free stations within their sigmas
    z = np.abs(centres(st) - free.state.X0) / np.hypot(sig_rig, sig_free)
    assert z.max() < 4.0


def test_composition_jacobian_matches_central_differences():
    from photogram.stats.rig_covariance import composition_jacobian
    rng = np.random.default_rng(8)
    n = 4
    lay = Layout([], 2 * n + n, 0, np.zeros(0, bool),
                 {"camera": [], "station": np.ones((3 * n, 6), bool),
                  "point": np.zeros((0, 3), bool)})
    R = np.stack([rodrigues_to_matrix(v) for v in rng.normal(0, 1, (3 * n, 3))])
    state = State(np.zeros((0, 3)), R, rng.normal(0, 1, (3 * n, 3)), [])
    d, f, s = np.arange(n), n + np.arange(n), 2 * n + np.arange(n)
    lay.derived = (d, f, s)
    state.compose(lay.derived)
    T = composition_jacobian(state.R[f], state.X0[s], state.R[s])
    h = 1e-6
    for j, cols in enumerate(np.concatenate([lay.station_cols[f], lay.station_cols[s]], 1).T):
        out = []
        for sgn in (1, -1):
            dx = np.zeros(lay.n_columns)
            dx[cols] = sgn * h
            st = state.updated(lay, dx)
            # the derived station's increment: dX0 and the small rotation of
            # R_new R_old^T
            D = st.R[d] @ np.swapaxes(state.R[d], 1, 2)
            rot = 0.5 * np.stack([D[:, 2, 1] - D[:, 1, 2], D[:, 0, 2] - D[:, 2, 0],
                                  D[:, 1, 0] - D[:, 0, 1]], axis=1)
            out.append(np.hstack([st.X0[d] - state.X0[d], rot]))
        np.testing.assert_allclose(T[:, :, j], (out[0] - out[1]) / (2 * h), atol=1e-8)


# --------------------------------------------------------------------------
# a project with a rig ([rigs.NAME] and the stations' frame column)

def _rig_project(rigs=True, seed=0):
    from photogram.project.model import Rig
    from photogram.simulation.network import to_project
    net, truth, frame, sensor = _network(seed=seed)
    prj = to_project(net, control=range(N_CONTROL), sigma_image=0.2, camera_names=["A", "B", "C"],
                     perturb_points=0.005, perturb_stations=0.005,
                     rng=np.random.default_rng(seed + 3), name="rig")
    prj.adjustment.datum = "control"
    if rigs:
        prj.rigs = {"head": Rig("head", "A", ["B", "C"])}
        prj.stations.frame = [f"F{f + 1}" for f in frame]
    return prj, truth, frame, sensor


@pytest.fixture(scope="module")
def rig_results():
    from photogram.bundle.run import adjust
    out = {}
    for rigs in (True, False):
        prj, truth, frame, sensor = _rig_project(rigs)
        out[rigs] = adjust(prj)
    return out, truth, frame, sensor


def test_rig_project_has_six_unknowns_per_frame_and_per_other_camera(rig_results):
    res, truth, frame, sensor = rig_results
    F, S = len(truth[0]), len(truth[2])
    assert res[True].summary["status"] == "converged"
    assert res[True].summary["counts"]["exterior"] == 6 * F + 6 * (S - 1)
    assert res[False].summary["counts"]["exterior"] == 6 * F * S
    assert len(res[True].project.stations.position) == F * S
    assert res[True].station_sigma.shape == (F * S, 6)


def test_rig_project_recovers_the_sensor_poses_within_their_sigmas(rig_results):
    res, (Rf, X0f, Rs, X0s), frame, sensor = rig_results
    rows = res[True].summary["rigs"]
    assert [(r["rig"], r["camera"], r["reference"]) for r in rows] == [("head", "B", "A"),
                                                                       ("head", "C", "A")]
    s0 = res[True].summary["sigma0"]
    assert 0.85 < s0 < 1.15
    for j, r in enumerate(rows):
        z = np.abs(np.array(r["position"]) - X0s[j + 1]) / np.array(r["position_sigma"])
        assert z.max() < 4.0, z
        R = opk_to_matrix(np.array(r["angles_rad"]))
        D = R @ Rs[j + 1].T
        rot = 0.5 * np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]])
        # angle sigmas are of omega phi kappa; the small rotation is close to them
        assert np.linalg.norm(rot) < 4.0 * np.linalg.norm(r["angle_sigma_rad"])
    # the results' [rigs] holds the adjusted poses
    X0, _ = res[True].project.rigs["head"].sensors["B"]
    np.testing.assert_array_equal(X0, rows[0]["position"])


def test_rig_project_stations_are_the_composition_and_at_least_as_precise(rig_results):
    from photogram.geometry import opk_to_matrix as opk
    res, (Rf, X0f, Rs, X0s), frame, sensor = rig_results
    st = res[True].project.stations
    R = opk(st.angles)
    ref = np.flatnonzero(sensor == 0)[frame]            # each image's frame station
    rows = {r["camera"]: r for r in res[True].summary["rigs"]}
    for i in np.flatnonzero(sensor > 0):
        r = rows["BC"[sensor[i] - 1]]
        Rc, X0c = composed_poses(R[ref[i]][None], st.position[ref[i]][None],
                                 opk(np.array(r["angles_rad"]))[None],
                                 np.array(r["position"])[None])
        np.testing.assert_allclose(st.position[i], X0c[0], atol=1e-12)
        np.testing.assert_allclose(R[i], Rc[0], atol=1e-12)
    sig_rig, sig_free = res[True].station_sigma, res[False].station_sigma
    assert np.all(sig_rig[:, :3] <= sig_free[:, :3] * 1.02)
    assert np.median(sig_rig[:, :3] / sig_free[:, :3]) < 0.9
    # and the composed poses agree with the truth within their sigmas
    _, X0_true = composed_poses(Rf[frame], X0f[frame], Rs[sensor], X0s[sensor])
    z = np.abs(st.position - X0_true) / sig_rig[:, :3]
    assert z.max() < 4.5


def test_rig_project_file_round_trip_and_errors(tmp_path):
    from photogram.errors import InputError
    from photogram.project import read_project
    from photogram.project.writer import write_project
    prj, *_ = _rig_project()
    prj.rigs["head"].sensors["B"] = (np.array([0.15, 0.01, -0.02]), np.array([0.01, -0.06, 0.02]))
    path = write_project(prj, tmp_path / "rig.prj")
    back = read_project(path)
    rig = back.rigs["head"]
    assert (rig.reference, rig.cameras, rig.fixed) == ("A", ["B", "C"], False)
    np.testing.assert_array_equal(rig.sensors["B"][0], [0.15, 0.01, -0.02])
    np.testing.assert_allclose(rig.sensors["B"][1], [0.01, -0.06, 0.02], rtol=0, atol=1e-15)
    assert back.stations.frame == prj.stations.frame
    text = path.read_text()
    stations = tmp_path / "rig_stations.csv"
    table = stations.read_text()

    def fails(prj_text, csv_text, match):
        path.write_text(prj_text)
        stations.write_text(csv_text)
        with pytest.raises(InputError, match=match):
            read_project(path)

    fails(text.replace('cameras = ["B", "C"]', 'cameras = ["B", "D"]'), table,
          "unknown camera 'D'")
    fails(text.replace("fixed = false", "fixed = true"), table, "C has no pose in sensors")
    lines = table.splitlines()
    two_a = lines[:2] + [lines[2].replace(",B,", ",A,")] + lines[3:]
    fails(text, "\n".join(two_a) + "\n", "frame F1 has two images of camera A")
    no_frame = lines[:2] + [lines[2].rsplit(",", 1)[0] + ","] + lines[3:]
    fails(text, "\n".join(no_frame) + "\n", "names no frame")
    no_ref = [lines[0], lines[1].rsplit(",", 1)[0] + ",F9"] + lines[2:]
    fails(text, "\n".join(no_ref) + "\n", "no image of its rig's reference camera A")


def test_rig_images_cannot_carry_a_dependent_datum():
    from photogram.adjust.build import build_problem
    from photogram.errors import InputError
    prj, *_ = _rig_project()
    prj.adjustment.datum = "dependent"
    prj.adjustment.dependent_station = "S2"            # camera B of frame 1
    with pytest.raises(InputError, match="fixes station.*S2"):
        build_problem(prj)


def test_a_project_without_rigs_builds_the_same_blocks():
    """No rigs: plain image blocks only, no derived stations (the default
    projects' numbers are unchanged: tests/test_examples_unchanged.py)."""
    from photogram.adjust.build import build_problem
    prj, *_ = _rig_project(rigs=False)
    built = build_problem(prj)
    assert built.rigs is None and built.problem.layout.derived is None
    assert all(type(b) is ImagePointBlock for b in built.problem.blocks)
    assert len(built.problem.state.X0) == len(prj.stations)


def test_rigs_csv_holds_the_rig_cameras_with_their_sigmas(rig_results, tmp_path):
    import pandas as pd

    from photogram.project.results import write_results
    res, *_ = rig_results
    r = res[True]
    write_results(tmp_path / "res", r.project, r.summary, station_sigma=r.station_sigma,
                  station_covariance=r.covariances["stations"])
    table = pd.read_csv(tmp_path / "res" / "rigs.csv", comment="#", dtype={"camera": str})
    rows = r.summary["rigs"]
    assert list(table["camera"]) == ["B", "C"] and list(table["reference"]) == ["A", "A"]
    np.testing.assert_array_equal(table[["X0", "Y0", "Z0"]].to_numpy(),
                                  [row["position"] for row in rows])
    np.testing.assert_array_equal(table[["est_sX0", "est_sY0", "est_sZ0"]].to_numpy(),
                                  [row["position_sigma"] for row in rows])
    # angles in the project's unit (degrees)
    np.testing.assert_allclose(np.radians(table[["omega", "phi", "kappa"]].to_numpy()),
                               [row["angles_rad"] for row in rows], rtol=1e-15, atol=1e-17)
    assert not (tmp_path / "res" / "interior.csv").exists()


def test_a_fixed_rig_holds_the_camera_poses():
    """fixed = true with the true poses: 6 unknowns per frame only; the
    cameras' poses come back unchanged with sigma 0."""
    from photogram.bundle.run import adjust
    from photogram.geometry import matrix_to_opk
    prj, (Rf, X0f, Rs, X0s), frame, sensor = _rig_project()
    rig = prj.rigs["head"]
    rig.fixed = True
    rig.sensors = {c: (X0s[j + 1], matrix_to_opk(Rs[j + 1][None])[0]) for j, c in
                   enumerate(rig.cameras)}
    res = adjust(prj)
    assert res.summary["counts"]["exterior"] == 6 * len(Rf)
    for j, row in enumerate(res.summary["rigs"]):
        np.testing.assert_allclose(row["position"], X0s[j + 1], rtol=0, atol=1e-15)
        assert max(row["position_sigma"] + row["angle_sigma_rad"]) == 0.0


def test_more_rig_errors(tmp_path):
    from photogram.errors import InputError
    from photogram.project import read_project
    from photogram.project.writer import write_project
    prj, *_ = _rig_project()
    path = write_project(prj, tmp_path / "rig.prj")
    text = path.read_text()
    two_rigs = text + '\n[rigs.other]\nreference = "B"\ncameras = ["C"]\n'
    path.write_text(two_rigs.replace('cameras = ["B", "C"]', 'cameras = ["B"]'))
    with pytest.raises(InputError, match="camera B is in rigs head and other"):
        read_project(path)
    path.write_text(text.replace('cameras = ["B", "C"]', 'cameras = ["B"]'))
    with pytest.raises(InputError, match="its camera C is in no rig"):
        read_project(path)
