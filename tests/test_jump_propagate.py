"""Analytic Jacobians against central finite differences; propagated sigmas
against a Monte Carlo simulation."""

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.jump import PARAMETERS, PlaneGround, ProfileGround, stick_model
from photogram.jump import definitions as defs
from photogram.jump import diff as D
from photogram.jump import propagate as prop
from photogram.jump.synthetic import synthetic_jumper

H = 1e-5          # finite-difference step (inputs of order 1..50)
TOL = 1e-6        # relative error of a Jacobian row


def fd_jacobian(fun, blocks, h=H):
    """Central differences of fun(list of (n,3) blocks) -> (n,) or (n,3),
    with respect to every input column (exposures are independent)."""
    x = np.concatenate(blocks, axis=1)
    k = len(blocks)

    def split(a):
        return [a[:, 3 * j:3 * j + 3] for j in range(k)]

    cols = []
    for c in range(x.shape[1]):
        xp, xm = x.copy(), x.copy()
        xp[:, c] += h
        xm[:, c] -= h
        cols.append((fun(split(xp)) - fun(split(xm))) / (2 * h))
    return np.stack(cols, axis=-1)


def assert_jacobian(J, Jfd, what=""):
    """Every row (exposure, output) within TOL relative to its largest entry."""
    err = np.max(np.abs(J - Jfd), axis=-1)
    scale = np.max(np.abs(Jfd), axis=-1)
    rel = np.where(scale > 0, err / np.where(scale > 0, scale, 1), err)
    assert np.all(np.isfinite(rel)), what
    assert np.max(rel) < TOL, f"{what}: relative error {np.max(rel):.2e}"


RNG = np.random.default_rng(7)
BLOCKS = [RNG.normal(size=(6, 3)) for _ in range(3)]

PRIMITIVES = {
    "add": lambda a, b, c: D.add(a, b),
    "sub": lambda a, b, c: D.sub(a, b),
    "mean": lambda a, b, c: D.mean(a, b),
    "scale": lambda a, b, c: D.scale(a, 2.5),
    "neg": lambda a, b, c: D.neg(a),
    "component": lambda a, b, c: D.component(a, 1),
    "dot": lambda a, b, c: D.dot(a, b),
    "cross": lambda a, b, c: D.cross(a, b),
    "norm": lambda a, b, c: D.norm(a),
    "normalize": lambda a, b, c: D.normalize(a),
    "reject": lambda a, b, c: D.reject(a, D.normalize(b)),
    "reject_nonunit": lambda a, b, c: D.reject(a, b),
    "atan2": lambda a, b, c: D.atan2(D.dot(a, b), D.dot(a, c)),
    "asin": lambda a, b, c: D.asin(D.component(D.normalize(a), 2)),
    "angle": lambda a, b, c: D.angle(a, b),
}


@pytest.mark.parametrize("name", sorted(PRIMITIVES))
def test_primitive_jacobians(name):
    f = PRIMITIVES[name]
    q = f(*D.inputs(BLOCKS))
    Jfd = fd_jacobian(lambda bl: f(*D.inputs(bl)).v, BLOCKS)
    assert q.J.shape == Jfd.shape
    assert_jacobian(q.J, Jfd, name)


def test_normalize_jacobian_is_projector_over_length():
    a = BLOCKS[0]
    u, Jn = D.normalize_jacobian(a)
    assert np.allclose(Jn @ a[:, :, None], 0, atol=1e-14)      # no change along a
    Jfd = fd_jacobian(lambda bl: D.normalize_jacobian(bl[0])[0], [a])
    assert_jacobian(Jn, Jfd, "normalize_jacobian")


@pytest.fixture(scope="module")
def jump():
    return synthetic_jumper(n=12)


def _blocks(s):
    P = s["P"]
    return [P[:, 0], P[:, 1], P[:, 2], P[:, 3], s["d1"], s["d2"]]


def _values(bl, ground=None):
    P = np.stack(bl[:4], axis=1)
    q, _ = defs.parameters(P, bl[4], bl[5], ground=ground)
    return np.stack([q[p].v for p in PARAMETERS if p != "v"], axis=1)


@pytest.mark.parametrize("ground", [None, PlaneGround((0, 0, 30.0), (0.5, 0.1, 0.8)),
                                    PlaneGround((0, 0, 30.0), (0.5, 0.1, 0.8), vertical=False),
                                    ProfileGround(np.array([0.0, 17.3, 60.0]),
                                                  np.array([42.0, 35.0, 10.0]))])
def test_parameter_jacobians_against_finite_differences(jump, ground):
    m = stick_model(jump["P"], jump["d1"], jump["d2"], ground=ground)
    Jfd = fd_jacobian(lambda bl: _values(bl, ground), _blocks(jump))
    assert m.jacobian.shape == (12, 7, 18)
    names = [p for p in PARAMETERS if p != "v"]
    for k, name in enumerate(names):
        assert_jacobian(m.jacobian[:, k], Jfd[:, k], name)


def test_frame_jacobians_against_finite_differences(jump):
    def frame(bl):
        Q = D.inputs(bl)
        return defs.frame(Q[0], Q[2], Q[3], Q[4], Q[5])

    f = frame(_blocks(jump))
    for name in ("O", "X", "Y", "Z", "u1", "u2"):
        Jfd = fd_jacobian(lambda bl: frame(bl)[name].v, _blocks(jump))
        assert_jacobian(f[name].J, Jfd, name)


def test_speed_jacobian_against_finite_differences(jump):
    t = jump["times"]
    O = jump["O"]
    a, b = prop.speed_pairs(np.arange(len(t)))
    v, _, g = prop.speed(O, t, a, b)
    n = len(t)
    for i in (0, 5, n - 1):
        for j, sign in ((b[i], 1.0), (a[i], -1.0)):
            fd = np.zeros(3)
            for c in range(3):
                Op, Om = O.copy(), O.copy()
                Op[j, c] += H
                Om[j, c] -= H
                fd[c] = (prop.speed(Op, t, a, b)[0][i] - prop.speed(Om, t, a, b)[0][i]) / (2 * H)
            assert np.max(np.abs(sign * g[i] - fd)) < TOL * np.max(np.abs(fd))


def test_speed_sigma_closed_form(jump):
    """Bindings independent, isotropic sigma s: var(O) = s^2/2 I, so a central
    difference has sigma s / (2 dt) * ... = s * fps / 2, one-sided s * fps."""
    s = 0.005
    m = stick_model(jump["P"], jump["d1"], jump["d2"],
                    cov_points=np.eye(3) * s ** 2 * np.ones((4, 1, 1)))
    sv = m.sigma["v"]
    assert np.allclose(sv[1:-1], s * 30 / 2)
    assert np.allclose(sv[[0, -1]], s * 30)


def random_spd(rng, n, k, sigma):
    B = rng.normal(size=(n, k, k))
    return sigma ** 2 * (B @ np.swapaxes(B, 1, 2) / k + 0.3 * np.eye(k))


@pytest.mark.slow
def test_propagated_sigmas_match_monte_carlo():
    rng = np.random.default_rng(2024)
    s = synthetic_jumper(n=10)
    n, draws = 10, 4000
    u1, u2 = s["u1"], s["u2"]
    C_pts = random_spd(rng, n, 12, 0.002)                       # full 12x12, in m^2
    sd = 0.004                                                  # rad, rank 2
    C_dir = np.zeros((n, 2, 3, 3))
    for k, u in enumerate((u1, u2)):
        C_dir[:, k] = sd ** 2 * (np.eye(3) - u[:, :, None] * u[:, None, :])
    m = stick_model(s["P"], u1, u2, cov_points=C_pts, cov_dirs=C_dir)

    # draws: all exposures at once, exposures independent
    L = np.linalg.cholesky(C_pts)                               # (n, 12, 12)
    dP = np.einsum("nij,dnj->dni", L, rng.normal(size=(draws, n, 12)))
    P = s["P"][None] + dP.reshape(draws, n, 4, 3)
    dirs = []
    for k, u in enumerate((u1, u2)):
        w, V = np.linalg.eigh(C_dir[:, k])
        Lk = V * np.sqrt(np.clip(w, 0, None))[:, None, :]
        dirs.append(u[None] + np.einsum("nij,dnj->dni", Lk, rng.normal(size=(draws, n, 3))))
    names = [p for p in PARAMETERS if p != "v"]
    vals, O = [], []
    for d0 in range(0, draws, 500):       # 500 draws a pass: 40 instead of 330 MB
        q, f = defs.parameters(P[d0:d0 + 500].reshape(-1, 4, 3),
                               dirs[0][d0:d0 + 500].reshape(-1, 3),
                               dirs[1][d0:d0 + 500].reshape(-1, 3))
        vals.append(np.stack([q[p].v.reshape(-1, n) for p in names], axis=-1))
        O.append(f["O"].v.reshape(-1, n, 3))
    vals, O = np.concatenate(vals), np.concatenate(O)      # (draws, n, 7), (draws, n, 3)
    a, b = m.speed_pairs
    v = np.stack([prop.speed(O[d], m.times, a, b)[0] for d in range(draws)])
    sample = np.concatenate([vals, v[:, :, None]], axis=-1)            # (draws, n, 8)
    C_mc = np.einsum("dni,dnj->nij", sample - sample.mean(0), sample - sample.mean(0)) / (draws - 1)

    s_prop = np.sqrt(np.diagonal(m.cov, axis1=1, axis2=2))
    s_mc = np.sqrt(np.diagonal(C_mc, axis1=1, axis2=2))
    assert np.all(s_prop > 0)
    rel = np.abs(s_mc / s_prop - 1)
    worst = np.unravel_index(np.argmax(rel), rel.shape)
    assert rel.max() < 0.05, f"exposure {worst[0]} {PARAMETERS[worst[1]]}: {rel.max():.3f}"
    # the whole covariance (correlations), scaled by the propagated sigmas
    scaled = (C_mc - m.cov) / (s_prop[:, :, None] * s_prop[:, None, :])
    assert np.max(np.abs(scaled)) < 0.08
    # v at the ends is correlated with its own exposure's parameters
    assert np.max(np.abs(m.cov[0, 7, :7])) > 0 and np.all(m.cov[5, 7, :7] == 0)


def test_input_covariance_shapes():
    n = 3
    rng = np.random.default_rng(1)
    per_point = random_spd(rng, n * 4, 3, 0.01).reshape(n, 4, 3, 3)
    C = prop.input_covariance(n, cov_points=per_point)
    assert C.shape == (n, 18, 18)
    assert np.allclose(C[:, 3:6, 3:6], per_point[:, 1])
    assert np.all(C[:, :3, 3:6] == 0) and np.all(C[:, 12:, :] == 0)
    C1 = prop.input_covariance(n, cov_points=per_point[0])               # broadcast
    assert np.allclose(C1[2], C[0])
    d = random_spd(rng, n, 6, 0.01)
    C2 = prop.input_covariance(n, cov_points=C[:, :12, :12], cov_dirs=d)
    assert np.allclose(C2[:, 12:, 12:], d)
    C3 = prop.input_covariance(n, cov=C2)
    assert np.allclose(C3, C2)
    with pytest.raises(InputError, match="not both"):
        prop.input_covariance(n, cov_points=per_point, cov=C2)
    bad = C2.copy()
    bad[:, 0, 1] += 1.0
    with pytest.raises(InputError, match="symmetric"):
        prop.input_covariance(n, cov=bad)


def test_nan_exposure_gives_nan_sigma():
    s = synthetic_jumper(n=6)
    P = s["P"].copy()
    P[2, 0] = np.nan
    m = stick_model(P, s["d1"], s["d2"], cov_points=np.eye(12) * 1e-4)
    sig = m.sigma
    assert np.isnan(sig["alpha"][2]) and np.isfinite(sig["alpha"][1])
    assert np.isfinite(sig["v"][2])        # from the neighbours' O
